"""S-curve feed planning with the feed limiting function (FLF) — `scurve` and `scurve_joint`.

Erwinski, Wawrzak, Paprocki, "Multi-criteria… feedrate planning", IEEE TII 18(11) 2022 and
Erwinski et al., NU·ROBOTI·FTS 2022 (shared/SOURCES.md §A, §D):

1. FLF(s) = min(F_max, F_clim, F_alim, F_jlim) with F_clim = (2/T)√(ρ² − (ρ − ε)²),
   F_alim = √(A/κ), F_jlim = ∛(J/κ²).
2. Critical points: the path ends and exact-stop corners (feed 0) and the FLF local minima
   (a sample lower than 5 neighbours on each side, refined by a golden-section search); a
   minimum next to a stop or another critical point is dropped only where the feed could not
   rise above it over the distance between them (near-cusps µm apart are kept).
3. Between critical points one jerk-limited 1-D profile (v0, a = 0) → (v1, a = 0) over the arc
   length of the segment: computed by ruckig (time-optimal with target velocity) rather than
   hand-written seven-phase formulas; its peak feed is lowered by bisection (≤ 30 iterations
   or Δ < 0.001 mm/s, TII 2022) until it stays under the FLF.
4. Forward/backward consistency: the feed at each critical point is lowered until every
   segment can change between its end feeds within its length.
5. Axis-limit repair: a segment whose axes break a limit gets its J, then its A, lowered
   (a one-dimensional search for the largest value without violation, as TII 2022's golden
   section; stop at a relative width of 1 %; the search starts at 5 % or, on a segment too
   short to have a profile there, at the lowest value that has one); if lowering A and J
   cannot fix it (a violation caused by the feed itself, e.g. v or centripetal terms), its
   end and peak feeds are scaled down.  Added for feasibility at T (issue 19): the check
   reads the jerk a G1 join's acceleration jump shows at T next to the join (a segment
   broken by that alone gets its join feeds lowered), both one-sided values at every jerk
   switch, and the table rows of refined cells (lobe tips); the tables are refined at
   curvature peaks and NURBS knots.  `scurve` checks the Cartesian axes — the paper's
   method, which lets the joints of a delta break their limits; `scurve_joint` checks the
   joints through the IK and adds the joint-velocity cap V_joint / max|q′(s)| to the FLF:
   the conservative fix a user would try.
6. The profile is sampled at exact multiples of T (segments join with a = 0 and the last
   sample lands on s = L at rest) and read at T as the metric reads it; the segments under a
   difference above a limit get checks tightened by that excess and are planned again.

The 1-D pieces (a ruckig segment, reachable feeds) are planners.scurve.pieces; the segment
checks, run for all the segments of a round at once, planners.scurve.batch (the peak fit and
the repair are generators whose tests scurve_batch.drive runs in lockstep).
Size: ~490 lines: the FLF, the critical points, the peak fit and the repair loop of one
method (TII 2022), kept together.
"""
from __future__ import annotations

import math
import time

import numpy as np

from planners.constraints import (PathTable, PlanningError, check_limits, check_path,
                          chord_feed_cap, cross_norm, corner_list, ik_along, joint_derivs, second_derivative_jumps)
from planners.feed import feed_ceiling
from planners.profile import Profile
from planners.verify import ORDERS, windows_above
from planners.scurve.batch import Checker, Joined, drive
from planners.scurve.pieces import Segment, no_profile, reachable, solver

MIN_NEIGHBOURS = 5          # TII 2022: a minimum is lower than 5 neighbours each side
PEAK_BISECTION_ITERS = 30   # TII 2022: ≤ 30 iterations or Δ < 0.001 mm/s
PEAK_BISECTION_TOL = 1e-3   # mm/s
REPAIR_MIN_FACTOR = 0.05    # the lowest A or J factor the repair tries (TII 2022)
# plans again after a reading at T above a limit, at most (meander_lcnc's U-turns needed 5:
# joint jerk 1.013 at T after 4)
AT_T_REPLANS = 8


# -- the feed limiting function ----------------------------------------------------
def flf(path, limits, T, s, *, joint_machine=None):
    """FLF at arc lengths s (mm/s).  With ``joint_machine`` adds V_joint / max|q′(s)|."""
    s = np.asarray(s, float)
    kappa = np.abs(np.asarray(path.curvature(s), float))
    q1 = joint_derivs(joint_machine, path, s)[1] if joint_machine is not None else None
    # the programmed F of a G-code path caps the FLF too (planners.feed)
    return np.minimum(flf_of(kappa, q1, limits, T), feed_ceiling(path, s, limits.feed_max))


def flf_of(kappa, q1, limits, T):
    """FLF from the curvature κ and (optionally) q′ at the same points."""
    kappa = np.abs(np.asarray(kappa, float))
    A, J = limits.cartesian.a, limits.cartesian.j
    eps = limits.chord_error_mm
    fc = chord_feed_cap(kappa, eps, T)
    with np.errstate(divide="ignore", invalid="ignore"):
        fa = np.sqrt(A / kappa)
        fj = np.cbrt(J / (kappa * kappa))
    F = np.minimum.reduce([np.full(kappa.shape, limits.feed_max), fc, fa, fj])
    if q1 is not None:
        with np.errstate(divide="ignore"):
            F = np.minimum(F, limits.joint.v / np.abs(q1).max(axis=-1))
    return F


class _Planner:
    def __init__(self, path, machine, limits, joint: bool, margin: float, grid_mm: float):
        self.path, self.machine, self.limits, self.joint = path, machine, limits, joint
        self.T = machine.servo_period_s
        self.otg, self.inp, self.traj = solver()
        lim = limits.joint if joint else limits.cartesian
        # plan the check against slightly tightened limits: the metrics read jerk as a third
        # difference at T, which can exceed the continuous peak by a fraction of a percent
        self.check = type(lim)(lim.v * (1 - margin), lim.a * (1 - margin), lim.j * (1 - margin))
        self.table = PathTable(path, machine if joint else None, ds=grid_mm, fit_scale=True,
                               refine=True)
        if not joint:      # the Cartesian planner does not need the IK, but the path must be reachable
            ik_along(machine, self.table.s, self.table.cart[0])
        self.grid = self.table.s
        self.F = self.F_grid()
        # Δx″ per checked axis at each join of the path's pieces (the table holds a join twice,
        # one-sided): a feed v there jumps the acceleration by Δx″v², which the check at T reads
        # as a jerk of up to JUMP_READ_FACTOR·Δx″v²/T on top of the continuous one
        first = self.table.offset[1:]
        X2 = (self.table.joint if joint else self.table.cart)[2]
        self.joins = self.table.edges[1:-1]
        self.join_d2 = X2[first] - X2[first - 1]
        # rows of the table's refined cells (lobe tips, knots): a q‴ peak there can be narrower
        # than a period's travel, so the segment checks sample these rows too
        g, piece = self.table.s, np.repeat(np.arange(len(self.table.counts)), self.table.counts)
        fine = (np.diff(g) < 0.999 * self.table.hs[piece[:-1]]) & (piece[1:] == piece[:-1])
        self.fine_s = np.unique(np.concatenate([g[:-1][fine], g[1:][fine]]))
        self._passes = None             # consistent()'s inputs and passes of the last round
        self.tight = None               # per segment, factors on its [v, a, j] check ratios (tighten)

    def F_at(self, s):
        """FLF at s from the tables (κ = |P′ × P″| for an arc-length parametrisation)."""
        s = np.atleast_1d(np.asarray(s, float))
        return np.minimum(self._flf_tables(s), feed_ceiling(self.path, s, self.limits.feed_max))

    def _flf_tables(self, s):
        """F_at without the programmed feed's cap."""
        P1, P2, _ = self.table.cartesian(s)
        q1 = self.table.joints(s)[0] if self.joint else None
        return flf_of(cross_norm(P1, P2), q1, self.limits, self.T)

    def F_grid(self):
        """F_at(self.grid), taking the table's rows themselves where the grid's Hermite weight w
        is 0 or 1: there the interpolation gives that row's (or the next row's) x′ and x″ plus
        zero terms, the same values (the sign of a zero aside, which κ and |q′| do not see)."""
        tab, g = self.table, self.grid
        i, w, _ = tab._locate(g)
        tabs = [tab.cart] + ([tab.joint] if self.joint else [])
        if not all(np.isfinite(x).all() for t in tabs for x in t[1:]):     # 0 · inf would be NaN
            return self.F_at(g)
        at_row = (w == 0) | (w == 1)
        row = np.where(w == 0, i, i + 1)[at_row]
        kappa = cross_norm(tab.cart[1][row], tab.cart[2][row])
        q1 = tab.joint[1][row] if self.joint else None
        F = np.empty(len(g))
        F[at_row] = flf_of(kappa, q1, self.limits, self.T)
        F[~at_row] = self._flf_tables(g[~at_row])
        return np.minimum(F, feed_ceiling(self.path, g, self.limits.feed_max))

    # -- critical points ----------------------------------------------------------
    def critical_points(self):
        L, g, F = self.path.length, self.grid, self.F
        corners = corner_list(self.path)
        pts = {0.0: 0.0, L: 0.0}
        for c in corners:
            pts[c] = 0.0
        n = len(F)
        m = MIN_NEIGHBOURS
        Fp = np.concatenate([np.full(m, np.inf), F, np.full(m, np.inf)])
        is_min = np.ones(n, bool)
        # strictly lower by more than rounding: on an arc the FLF is a plateau whose last-digit
        # noise would otherwise make minima everywhere (its ends are critical points below)
        Fs = F * (1 + 1e-9)
        for k in range(1, m + 1):
            is_min &= (Fs < Fp[m - k:m - k + n]) & (Fs < Fp[m + k:m + k + n])
        h = float(self.table.hs.max())
        cs = np.array(sorted(pts))
        # nearest critical point of each minimum: its two neighbours in the sorted cs (a scan
        # of all of cs per minimum was quadratic in the corner count)
        mins = np.nonzero(is_min)[0]
        j = np.searchsorted(cs, g[mins])
        near = np.minimum(np.abs(cs[np.maximum(j - 1, 0)] - g[mins]), np.abs(cs[np.minimum(j, len(cs) - 1)] - g[mins]))
        # nearer: a corner's own dip, which its stop covers, unless the feed the profile can
        # reach from that stop within the distance rises above the dip (a near-cusp a few µm
        # from the path's start: one segment across it was held to the dip's feed throughout)
        c = self.limits.cartesian
        apart = near >= 2 * m * h
        for k in np.nonzero(~apart)[0].tolist():
            apart[k] = reachable(0.0, float(near[k]), c.a, c.j, self.limits.feed_max) > F[mins[k]]
        mins = mins[apart]
        if len(mins):
            x, fx = self.minimise_F(g[np.maximum(mins - 1, 0)], g[np.minimum(mins + 1, n - 1)])
            lower = fx <= F[mins]
            for s_min, f_min in zip(np.where(lower, x, g[mins]).tolist(), np.where(lower, fx, F[mins]).tolist()):
                pts[s_min] = f_min
        for sj, vj in self.second_derivative_jumps(cs):
            pts[sj] = min(pts.get(sj, np.inf), vj)
        # every join of the path's segments (the table's edges): the lower one-sided FLF there
        # (a short blend arc is a plateau of the FLF, which has no strict minimum)
        # The table holds each edge twice: the last row of the piece before and the first of the
        # piece after (a search of the grid per edge was quadratic in the segment count).
        first = self.table.offset[1:]
        for b, f in zip(self.table.edges[1:-1].tolist(), np.minimum(F[first - 1], F[first]).tolist()):
            if b not in pts:
                pts[b] = f
        s = np.array(sorted(pts))
        # merge points closer than 1 µm (a knot that is also an FLF minimum), keeping the lower
        # feed; but never two joins: a piece shorter than 1 µm (a G64 blend of radius 0.2 µm at
        # a reversal) inside a segment let it accelerate there, where the jerk κ²ṡ³ broke the
        # limit at any feed the FLF allows, and the repair could only slow the whole segment.
        # Nor two points whose feeds differ by more than the feed can change over the gap: the
        # higher would not be covered (a near-cusp's double dip 0.5 µm apart, 0.10 and 0.11
        # mm/s, held the segment after it to 0.11 mm/s over 0.4 mm)
        joins = set(self.table.edges.tolist())
        keep = [0]
        for k in range(1, len(s)):
            a, b = pts[s[keep[-1]]], pts[s[k]]
            gap = s[k] - s[keep[-1]]
            if (gap < 1e-3 and not (s[k] in joins and s[keep[-1]] in joins)
                    and reachable(min(a, b), gap, c.a, c.j, max(a, b)) < max(a, b)):
                pts[s[keep[-1]]] = min(pts[s[keep[-1]]], pts[s[k]])
                if k == len(s) - 1:
                    keep[-1] = k
                    pts[s[k]] = 0.0
            else:
                keep.append(k)
        s = s[keep]
        v = np.array([pts[x] for x in s])
        v[0] = v[-1] = 0.0
        return s, v

    def minimise_F(self, lo, hi, xtol: float = 1e-6):
        """(s, FLF) of the FLF's minimum in each bracket [lo, hi], by golden-section search on
        all brackets at once, to xtol: the joint velocity cap of scurve_joint has a minimum on
        most lines of a CAM program, and a scalar search per minimum pays a Python call per
        evaluation (docs/TUNING.md)."""
        r = (math.sqrt(5.0) - 1.0) / 2.0
        a, b = np.asarray(lo, float).copy(), np.asarray(hi, float).copy()
        c, d = b - r * (b - a), a + r * (b - a)
        fc, fd = self.F_at(c), self.F_at(d)
        width = float((b - a).max())
        steps = math.ceil(math.log(xtol / width) / math.log(r)) if width > xtol else 0
        for _ in range(steps):
            # left: the minimum is in [a, d], the old c becomes d; else in [c, b], the old d becomes c
            left = fc <= fd
            a, b = np.where(left, a, c), np.where(left, d, b)
            new = np.where(left, b - r * (b - a), a + r * (b - a))
            fn = self.F_at(new)
            c, fc, d, fd = (np.where(left, new, d), np.where(left, fn, fd),
                            np.where(left, c, new), np.where(left, fc, fn))
        pick = fc <= fd
        return np.where(pick, c, d), np.where(pick, fc, fd)

    def second_derivative_jumps(self, corners):
        """G1 joins where P″ jumps: critical points with the feed that keeps the jerk read at
        T within 0.4 of the checked limit (see constraints.second_derivative_jumps)."""
        jumps = second_derivative_jumps(self.path, self.table, self.machine if self.joint else None, corners)
        # the FLF at every join in one np.interp (one call per join was most of this on a CAM program)
        Fj = np.interp([sj for sj, _ in jumps], self.grid, self.F).tolist() if jumps else []
        out = []
        for (sj, jump), fj in zip(jumps, Fj):
            vj = math.sqrt(0.4 * self.check.j * self.T / jump) if jump > 0 else self.limits.feed_max
            out.append((sj, min(vj, fj)))
        return out

    # -- segments -----------------------------------------------------------------
    def consistent(self, v_c, Ls, A, J):
        """The feeds v_c at the critical points lowered until every segment can change between
        its end feeds within its length: a backward, then a forward pass of reachable()."""
        # Each repair round changes a few segments: an entry whose inputs (its segment, v_c and
        # the feed it is reached from) are those of the last call keeps its last value, so a
        # round costs the stretches that changed, not the whole path again (10⁵ segments)
        n = len(Ls)
        Lr = Ls * (1 - 1e-9)
        last = self._passes
        if last is None or len(last[0]) != n + 1:
            last = (np.full(n + 1, np.nan),) + (np.full(n, np.nan),) * 3 + (np.full(n + 1, np.nan),) * 2
        pvc, pL, pA, pJ, pb, pf = last
        seg = (Lr != pL) | (A != pA) | (J != pJ)
        vc, L_, A_, J_ = v_c.tolist(), Lr.tolist(), A.tolist(), J.tolist()
        b = pb.tolist()
        b[n] = vc[n]

        def back(i):
            r = reachable(b[i + 1], L_[i], A_[i], J_[i], vc[i])
            r = r if r < vc[i] else vc[i]            # min(v_c[i], r)
            changed, b[i] = r != b[i], r
            return changed

        _sweep(np.nonzero(seg | (v_c[:n] != pvc[:n]))[0][::-1].tolist(), b[n] != pb[n], n - 1, -1, back)
        b_new = np.array(b)
        f = pf.tolist()
        f[0] = b[0]

        def fwd(i):
            r = reachable(f[i], L_[i], A_[i], J_[i], b[i + 1])
            r = r if r < b[i + 1] else b[i + 1]
            changed, f[i + 1] = r != f[i + 1], r
            return changed

        _sweep(np.nonzero(seg | (b_new[1:] != pb[1:]))[0].tolist(), f[0] != pf[0], 0, n, fwd)
        self._passes = (v_c.copy(), Lr, A.copy(), J.copy(), b_new, np.array(f))
        return np.array(f)

    def fit_peak(self, seg: Segment, vcap: float, fmax: float):
        """Largest peak feed ≤ vcap whose profile stays under the FLF (bisection); ``fmax`` is
        the FLF's largest value over the segment. A generator for scurve_batch.drive: it yields
        ("flf", seg) per test of the feed against the FLF and returns whether ruckig fitted."""
        bounds = self.first_fit(seg, vcap, fmax)
        if bounds is None:
            return False
        if bounds[0] == bounds[1] or (yield "flf", seg):
            return True
        return (yield from self.bisect_peak(seg, *bounds))

    def first_fit(self, seg: Segment, vcap: float, fmax: float):
        """fit_peak's first fit, at the highest peak the cap and the FLF allow: the bounds
        (lo, hi) of its bisection, or None if ruckig finds no profile."""
        lo = max(seg.v0, seg.v1, 1e-6)
        hi = max(lo, min(vcap, fmax))
        seg.vpeak = hi
        return (lo, hi) if seg.compute(self.otg, self.inp, self.traj) else None

    def bisect_peak(self, seg: Segment, lo: float, hi: float):
        """fit_peak's bisection, after the fit at ``hi`` went over the FLF (a generator, as fit_peak)."""
        good, kept = lo, None
        for _ in range(PEAK_BISECTION_ITERS):
            if hi - good < PEAK_BISECTION_TOL:
                break
            mid = 0.5 * (good + hi)
            seg.vpeak = mid
            if seg.compute(self.otg, self.inp, self.traj) and (yield "flf", seg):
                good, kept = mid, seg.state()
            else:
                hi = mid
        if kept is not None:
            # the fit at ``good`` was made in the loop (ruckig is deterministic): keep it
            seg.restore(kept)
            return True
        seg.vpeak = good
        return seg.compute(self.otg, self.inp, self.traj)

    def ratios(self, seg: Segment, reads: bool = True) -> np.ndarray:
        """Peak [v, a, j] ratios of the checked axes over the segment (against the check limits),
        with the reads at T of the joins at its ends (scurve_batch.Checker) unless ``reads`` is off."""
        c = Checker(self).check([seg])[0]
        return c.r if reads else c.r0

    def join_feed_factors(self, chk, i) -> list[float]:
        """Per end, the factor on its feed that brings the join's read plus the continuous jerk
        next to it within the limit (the read scales as v²; the continuous jerk is kept, which
        errs low), in [0.49, 0.98]: for a segment that violates only through its joins' reads.
        None where that would take more than halving the feed (the continuous jerk next to the
        join leaves no room: the segment's J has to come down, as for any other violation)."""
        f = [1.0, 1.0]
        jlim = self.check.j if self.tight is None else self.check.j / self.tight[i, 2]
        for end, read, jmax, jmin in chk.reads:
            # per axis √(room / |read|), where the continuous jerk of the read's sign next to the
            # join leaves this much room (plain floats: numpy's call overhead was most of it)
            need = math.nan
            for r, hi, lo in zip(read.tolist(), jmax.tolist(), jmin.tolist()):
                room = max(jlim - (hi if r > 0 else -lo), 0.0)
                x = math.sqrt(room / abs(r)) if r != 0 else (math.inf if room > 0 else math.nan)
                if x < need or need != need:          # the smallest, NaN ignored (np.nanmin)
                    need = x
            if need < 0.5:            # the continuous jerk fills the limit: lower J instead
                return None
            f[end] = min(f[end], min(0.98 * need, 0.98))
        return f

    def seg_ok(self, seg, i, vcap, known=None):
        """Fit segment i's peak, then check it: a generator returning its Check (None: no fit).
        ``known``: (a fitted profile, its Check): a check depends on the profile alone, so a fit
        to that same profile takes that Check (a repair's first tests at J or A × 0.05 often
        fit the round's profile again: a cruise, or a change that A and J do not limit)."""
        if not (yield from self.fit_peak(seg, vcap, self.fmax[i])):
            return None
        if known is not None and seg.prof == known[0]:
            return known[1]
        return (yield "check", seg)

    def fit_new(self, new, fresh, caps, checker):
        """seg_ok of the segments ``fresh`` (segment numbers ``new``, caps ``caps``), its first fits
        and tests run for all at once: most pass the FLF at the first fit, and a generator per
        segment through scurve_batch.drive cost more than its tests on a 10⁵-line program."""
        out = [None] * len(fresh)
        bounds = [self.first_fit(seg, c, self.fmax[i]) for i, seg, c in zip(new, fresh, caps)]
        ready = [k for k, b in enumerate(bounds) if b is not None and b[0] == b[1]]
        test = [k for k, b in enumerate(bounds) if b is not None and b[0] != b[1]]
        slow = []
        if test:
            under = checker.under_flf([fresh[k] for k in test]).tolist()
            ready = sorted(ready + [k for k, u in zip(test, under) if u])
            slow = [k for k, u in zip(test, under) if not u]
        if ready:
            for k, c in zip(ready, checker.check([fresh[k] for k in ready])):
                out[k] = c
        # those over the FLF: fit_peak's bisection, then the check
        for k, c in zip(slow, drive([self._bisect_check(fresh[k], *bounds[k]) for k in slow], checker)):
            out[k] = c
        return out

    def _bisect_check(self, seg, lo, hi):
        """seg_ok after a first fit over the FLF (a generator for scurve_batch.drive)."""
        if not (yield from self.bisect_peak(seg, lo, hi)):
            return None
        return (yield "check", seg)

    def lowest_factor(self, seg: Segment, attr: str, full: float) -> float:
        """The lowest factor ≥ REPAIR_MIN_FACTOR on the segment's ``attr`` (A or J, at ``full``)
        at which it has a profile between its end feeds. TII 2022's search starts at the
        smallest factor; a short segment has no profile there, although a J a little lower
        would fix it: a repair that gave up on J scaled its feeds instead, round after round,
        and a jerk at J does not scale with the feed (docs/TUNING.md)."""
        def none_at(f):
            setattr(seg, attr, full * f)
            return no_profile(seg.v0, seg.v1, seg.L, seg.A, seg.J)

        lo, hi = REPAIR_MIN_FACTOR, 1.0
        if not none_at(lo):
            setattr(seg, attr, full)
            return lo
        # no profile at lo; one at 1 (the round's fit): the smallest A or J of a profile,
        # to 1e-4, a little above it (no_profile is a bound: ruckig may still find none there)
        while hi - lo > 1e-4:
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if none_at(mid) else (lo, mid)
        setattr(seg, attr, full)
        return min(hi * 1.001, 1.0)

    def repair(self, i, seg, chk, v, v_c, A, J, vcap):
        """One round's repair of segment i (its Check ``chk``) that broke a limit: its join feeds
        (a violation through the joins' reads only), else TII 2022's J, then A, then its feeds;
        updates the arrays in place. A generator for scurve_batch.drive."""
        f = self.join_feed_factors(chk, i) if chk.ok0 else None
        if f is not None:
            # only the joins' reads at T break the limit: lower the feed at those joins
            v_c[i] = min(v_c[i], v[i] * f[0])
            v_c[i + 1] = min(v_c[i + 1], v[i + 1] * f[1])
            return
        fitted = seg.state()
        passed = {}         # (A, J) → the fit that passed its check there

        def ok(f, attr, full):
            setattr(seg, attr, full * f)
            # no profile at all (most tests at × 0.05): the fit would fail before any request
            # (it would set vpeak, which every later use sets again or restores first)
            if no_profile(seg.v0, seg.v1, seg.L, seg.A, seg.J):
                return False
            c = yield from self.seg_ok(seg, i, vcap[i], (fitted[3], chk))
            if c is not None and c.ok:
                passed[seg.A, seg.J] = seg.state()
                return True
            return False

        # TII 2022 axis repair: lower J, then A, to the largest value without violation
        for attr in ("J", "A"):
            full = getattr(seg, attr)
            low = self.lowest_factor(seg, attr, full)
            if low < 0.99 and (yield from ok(low, attr, full)):
                lo, hi = low, 1.0
                while hi - lo > 0.01:
                    mid = 0.5 * (lo + hi)
                    lo, hi = (mid, hi) if (yield from ok(mid, attr, full)) else (lo, mid)
                setattr(seg, attr, full * lo)
                break
            setattr(seg, attr, full)
        A[i], J[i] = seg.A, seg.J
        seg.A, seg.J = A[i], J[i]
        if (seg.A, seg.J) in passed:
            # the A, J found passed their test: its fit and check would be the same again
            seg.restore(passed[seg.A, seg.J])
            return
        if (seg.A, seg.J) == (fitted[0], fitted[1]):
            # neither lowered: the refit at the same A, J is the round's fit (ruckig is deterministic)
            seg.restore(fitted)
            r = chk.r
        else:
            c = yield from self.seg_ok(seg, i, vcap[i])
            if c is not None and c.ok:
                return
            r = (c if c is not None else (yield "check", seg)).r
        # a violation of the feed itself: scale the segment's feeds down
        # a cruise at constant feed has zero a and j ratios: they bound nothing (the
        # same inf numpy's 0 ** -0.5 gave, without its divide-by-zero warning)
        bounds = (1 / r[0] if r[0] > 0 else math.inf, r[1] ** -0.5 if r[1] > 0 else math.inf,
                  r[2] ** (-1 / 3) if r[2] > 0 else math.inf)
        f = float(min(max(0.98 * min(bounds), 0.3), 0.95))
        vcap[i] = max(seg.vpeak, seg.v0, seg.v1) * f
        v_c[i] = min(v_c[i], v[i] * f)
        v_c[i + 1] = min(v_c[i + 1], v[i + 1] * f)

    def run(self):
        """Plan the segments: (segments, info). The rounds' state is kept for :meth:`tighten`."""
        s_c, v_c = self.critical_points()
        self.s_c, self.Ls = s_c, np.diff(s_c)
        nseg = len(self.Ls)
        # the FLF's largest value over each segment (the ceiling of its peak feed)
        i0, i1 = np.searchsorted(self.grid, s_c[:-1]), np.searchsorted(self.grid, s_c[:-1] + self.Ls)
        self.fmax = [float(self.F[a:b + 1].max()) for a, b in zip(i0.tolist(), i1.tolist())]
        # the s-curve's own A, J: the Cartesian limits, tightened by the margin where those
        # are the checked limits (an axis-aligned stretch reads s⃛ = J on one axis)
        c = self.limits.cartesian
        shrink = 1.0 if self.joint else self.check.a / c.a
        self.v_c = v_c
        self.A = np.full(nseg, c.a * shrink)
        self.J = np.full(nseg, c.j * shrink)
        self.vcap = np.full(nseg, self.limits.feed_max)
        self.repairs = self.rounds = 0
        self.checker = Checker(self)
        # a segment whose end feeds, A, J and cap are those of the last round keeps its fit and
        # check; the others are fitted and checked together
        self.got, self.r = [None] * nseg, np.zeros((nseg, 3))
        self.last = np.full((5, nseg), np.nan)
        return self._rounds()

    def _rounds(self, max_rounds: int = 60):
        """Repair rounds until every segment passes its check: (segments, info)."""
        s_c, Ls, v_c, A, J, vcap, got, r = self.s_c, self.Ls, self.v_c, self.A, self.J, self.vcap, self.got, self.r
        for _ in range(max_rounds):
            self.rounds += 1
            v = self.consistent(v_c, Ls, A, J)
            now = np.array([v[:-1], v[1:], A, J, vcap])
            new = np.nonzero((now != self.last).any(axis=0))[0].tolist()
            self.last = now
            # plain floats (the same values): numpy scalars cost ~3× in the per-fit arithmetic;
            # those of the new segments only (after the first round, a fraction of them)
            at = np.array(new, np.intp)
            cl = vcap[at].tolist()
            fresh = [Segment(*x) for x in zip(*(y[at].tolist() for y in (s_c, Ls, v[:-1], v[1:], A, J)), cl)]
            checks = self.fit_new(new, fresh, cl, self.checker)
            for i, seg, chk in zip(new, fresh, checks):
                if chk is None:
                    raise PlanningError(
                        f"scurve: ruckig found no profile for segment {i} (s = {s_c[i]:.6g}…"
                        f"{s_c[i + 1]:.6g} mm, {v[i]:.6g} → {v[i + 1]:.6g} mm/s)")
                got[i] = (seg, chk)
                r[i] = chk.r
            bad = np.nonzero((r > 1.0).any(axis=1))[0].tolist()
            if not bad:
                return [g[0] for g in got], {"rounds": self.rounds, "repairs": self.repairs, "segments": len(Ls),
                                             "critical_points_mm": s_c.tolist()}
            self.repairs += len(bad)
            drive([self.repair(i, got[i][0], got[i][1], v, v_c, A, J, vcap) for i in bad], self.checker)
        raise PlanningError(f"scurve: axis-limit repair did not converge in {self.rounds} rounds "
                            f"({len(bad)} segment(s) still violate)")

    def over_at_T(self, prof, segs) -> np.ndarray:
        """Per segment, the largest [v, a, j] ratio the metric reads at T (planners.verify: a
        difference at T, over each window that reaches into the segment) where above 1, else 1.
        The segment checks read the continuous derivatives; where the curvature changes within
        a few periods' travel a third difference at T reads more than they do, beyond the
        checks' margin."""
        T, lim = self.T, self.limits.joint if self.joint else self.limits.cartesian
        X = prof.points()
        X = self.machine.ik(X) if self.joint else X
        starts = np.concatenate([[0.0], np.cumsum([g.duration for g in segs])])
        over = np.ones((len(segs), 3))
        above = windows_above(X, T, lim)
        for k, order in enumerate(ORDERS):
            n = np.array([i for o, i, _ in above if o == order], dtype=np.intp)
            r = np.array([r for o, _, r in above if o == order])
            # difference n of order k + 1 reads the samples n … n + k + 1: every segment of them
            for o in range(k + 2):
                seg = np.clip(np.searchsorted(starts, (n + o) * T, side="right") - 1, 0, len(segs) - 1)
                np.maximum.at(over[:, k], seg, r)
        return over

    def tighten(self, over):
        """Tighten the checks of the segments that ``over`` (:meth:`over_at_T`) finds above the
        limits at T by what they read there, and plan again: (segments, info)."""
        if self.tight is None:
            self.tight = np.ones((len(self.Ls), 3))
        hit = np.nonzero((over > 1.0).any(axis=1))[0]
        # the reading at T taken to scale with the continuous peak the check sees (r, with
        # the tightening so far): the check must bring that peak down by the excess at T. A
        # segment's own peak below half the limit is not what makes a window read above it
        peak = np.maximum(self.r[hit], 0.5)
        self.tight[hit] *= np.where(over[hit] > 1.0, over[hit] / peak * (1 + 1e-3), 1.0)
        self.last[:, hit] = np.nan          # checked again, under the tightened limits
        return self._rounds()


def _sweep(dirty, carry, start, stop, update):
    """Run update(i) for i from start towards stop (exclusive) where the inputs of i changed:
    i in ``dirty`` (in sweep order), or the previous entry's output changed (``carry`` for
    the first); update returns whether its output changed. The rest keep their last values."""
    step = 1 if stop > start else -1
    i, k = start, 0
    while i != stop:
        if not carry:
            # skip to the next dirty entry not yet passed
            while k < len(dirty) and (dirty[k] - i) * step < 0:
                k += 1
            if k == len(dirty):
                return
            i = dirty[k]
        carry = update(i)
        i += step


def sample(segs, path, T, planner, info) -> Profile:
    """Join the segments and sample s(t) at exact multiples of T, ending at s = L at rest."""
    joined = Joined(segs)
    prof = Profile.from_pieces(planner, T, [joined], path, info)
    # times where the jerk changes (phase ends), for planners that start from this profile (pso)
    sw, rest = joined.switch_times()
    prof.info.update(jerk_switch_times_s=[0.0] + sw, rest_times_s=rest + [joined.duration])
    return prof


def _plan(path, machine, limits, joint: bool, margin: float, grid_mm: float) -> Profile:
    t0 = time.perf_counter()
    name = "scurve_joint" if joint else "scurve"
    limits = machine.limits if limits is None else limits
    check_limits(limits, name)
    check_path(path, name)
    pl = _Planner(path, machine, limits, joint, margin, grid_mm)
    segs, info = pl.run()
    prof = sample(segs, path, pl.T, name, info)
    # the metric reads the profile at T: segments that break a limit there are planned again
    # under tightened checks (a few times; a profile still above is returned as it is, and
    # the metrics say so)
    replans = 0
    while replans < AT_T_REPLANS:
        over = pl.over_at_T(prof, segs)
        if not (over > 1.0).any():
            break
        segs, info = pl.tighten(over)
        prof = sample(segs, path, pl.T, name, info)
        replans += 1
    prof.info["replans_at_T"] = replans
    prof.planning_time_s = time.perf_counter() - t0
    return prof


def plan(path, machine, limits=None, *, margin: float = 0.005, grid_mm: float = 0.05) -> Profile:
    """`scurve`: FLF s-curve with the Cartesian axis-limit repair of TII 2022."""
    return _plan(path, machine, limits, False, margin, grid_mm)


def plan_joint(path, machine, limits=None, *, margin: float = 0.005, grid_mm: float = 0.05) -> Profile:
    """`scurve_joint`: the same, repairing against the joint limits through the IK."""
    return _plan(path, machine, limits, True, margin, grid_mm)
