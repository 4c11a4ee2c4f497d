"""The one constraint set of the planners, and the joint and Cartesian derivatives it needs.

Constraints (shared by scurve_joint, pso, toppra and optimal; scurve and trapezoid use the
Cartesian part): joint v/a/j limits, F_max, the chord-error feed cap (:func:`chord_feed_cap`),
and at a G1 join, where q″ jumps, the jerk that jump reads as at T (:data:`JUMP_READ_FACTOR`,
:func:`join_jumps`). The limits themselves are checked once (:func:`check_limits`), the path
against the workspace by :func:`check_path_in_workspace` (the machine's findings) or
:func:`ik_along` (IK of given points). The check of a sampled profile at T is
:mod:`planners.verify`.


Every planner that limits the joints of a PKM needs q(s) and its arc-length derivatives
q′, q″, q‴ (the chain rule then gives joint velocity, acceleration and jerk for any
s(t)).  kins gives the IK and the Jacobian but no higher derivatives, so we differentiate
the IK numerically — but not along the path itself (that would smear the derivatives over
an exact-stop corner): at each s we take the path's own one-sided derivatives
(P, P′, P″, P‴ from ``path.derivs``), build the local cubic X(h) = P + P′h + P″h²/2 + P‴h³/6
and difference q(X(h)) on a 5-point stencil in h.  X(h) agrees with the path to third order,
so these are the derivatives of q(s) at s, with O(h²) truncation (h = 0.02 mm → ~1e-4
relative on q‴ at 1 mm radius, round-off ~1e-8).

Size: ~440 lines: the constraint set, the derivatives it is read from and their tables belong
together (every planner imports them as one); the table's refinement is the part to split off
if it grows.
"""
from __future__ import annotations

import math

import numpy as np

from kins import WorkspaceError
from planners.errors import PlanningError
from planners.feed import feed_ceiling

STENCIL_H_MM = 0.02
# A jump Δq″ of the joint acceleration at speed ṡ reads, as a third difference at T, as at
# most 0.75·Δq″·ṡ²/T (the cumulative mass of the two-period hat kernel of a second
# difference moves by ≤ 3/4 in one period); it adds to the continuous jerk at the join.
JUMP_READ_FACTOR = 0.75
# ... and a third difference centred d periods from the jump reads it too, for d < READ_REACH
READ_REACH = 1.5
# PathTable(refine=True): a cell is at most this many curvature radii wide (q‴ is interpolated
# linearly, its relative error ~ (h/ρ)²/8 = 0.1 %), and never split below REFINE_MIN_MM
REFINE_RADII = 0.1
REFINE_MIN_MM = 1e-5


def third_difference_weight(u: float) -> float:
    """The weight of a jump of the second derivative at u periods into a third difference's
    window [0, 3] (the quadratic B-spline: 0.75 at the centre, JUMP_READ_FACTOR)."""
    u = min(max(u, 0.0), 3.0)
    return u * u / 2 if u < 1 else (-2 * u * u + 6 * u - 3) / 2 if u < 2 else (3 - u) ** 2 / 2


def second_derivative_kernel(tau, T: float):
    """G(τ) = [Λ(τ/T − ½) − Λ(τ/T + ½)]/T² (Λ the unit hat): a third difference at period T
    centred c reads ∫q̈(t)·G(t − c)dt, the kernel of third_difference_weight integrated by parts
    onto the second derivative."""
    hat = lambda u: np.maximum(1 - np.abs(u), 0.0)
    return (hat(tau / T - 0.5) - hat(tau / T + 0.5)) / (T * T)


def join_read_weight(d: float) -> float:
    """The read of a G1 join's jump (κṡ², κ = JUMP_READ_FACTOR·Δq″/T) by the third difference
    centred d periods from it, as a fraction of the read at the join: 1 − 4d²/3 to d = ½, then
    2(1.5 − d)²/3, 0 from READ_REACH on."""
    return third_difference_weight(READ_REACH - abs(d)) / third_difference_weight(READ_REACH)


def station_grid(edges, grid_mm: float, s0: float, s1: float) -> np.ndarray:
    """Stations of a rest-to-rest piece [s0, s1]: ≤ grid_mm apart (≥ 19 intervals a piece),
    uniform between consecutive ``edges`` (its ends, segment joins, G1 joins: each on the grid)
    with ≥ 4 intervals between two (a 0.04 mm G64 blend arc is resolved, not stepped over)."""
    step = min(grid_mm, (s1 - s0) / 19)
    parts = [np.linspace(a, b, max(5, int(math.ceil((b - a) / step - 1e-9)) + 1))[:-1]
             for a, b in zip(edges[:-1], edges[1:])]
    return np.concatenate(parts + [[s1]])


def curvature_splits(h, kappa, radii: float, min_mm: float, most: int, mask=None):
    """(the cells of widths h wider than ``radii`` curvature radii at either end (curvatures
    ``kappa`` at the cell ends) and than ``min_mm``, the parts to split each into, ≤ ``most``);
    ``mask`` selects the cells that may be split."""
    k = np.ceil(h * np.maximum(kappa[:-1], kappa[1:]) / radii)
    ok = (k > 1) & (h > min_mm)
    need = np.nonzero(ok if mask is None else mask & ok)[0]
    return need, np.minimum(k[need], most).astype(np.int64)


def check_limits(limits, planner: str = "planner") -> None:
    """Raise PlanningError unless every limit is a finite number > 0."""
    vals = {f"{group} limit {k}": getattr(getattr(limits, group), k)
            for group in ("joint", "cartesian") for k in ("v", "a", "j")}
    vals |= {"limit feed_max": limits.feed_max, "limit chord_error_mm": limits.chord_error_mm}
    for name, v in vals.items():
        try:
            ok = v > 0 and v < float("inf")
        except TypeError:      # a string or None in a hand-made Limits
            ok = False
        if not ok:
            raise PlanningError(f"{planner}: {name} = {v!r} must be a finite number > 0")


def check_path(path, who: str) -> None:
    L = path.length
    if not np.isfinite(L) or L <= 0:
        raise PlanningError(f"{who}: path has length {L!r}; need a non-empty path")


def check_path_in_workspace(path, machine, step_mm: float = 0.5) -> None:
    """Raise PlanningError naming the first path point (arc length, G-code line, xyz and the
    joint or box side) that ``machine.check`` flags — out of reach, beyond a joint stroke,
    outside the workspace box or near a singularity — sampling the path every ≤ step_mm."""
    s, P = path.sample(step_mm)
    findings = machine.check(P)
    if not findings:
        return
    f = findings[0]
    ln = int(path.line_at(s[f.index])[0])
    where = f" (G-code line {ln})" if ln >= 0 else ""
    joint = f" [joint {f.joint}]" if f.joint is not None else ""
    raise PlanningError(f"{path.source}: the path leaves the workspace of {machine.name} at "
                        f"s = {s[f.index]:.6g} mm{where}{joint}: {f.message}")


def ik_along(machine, s, P) -> np.ndarray:
    """IK of path points P at arc lengths s; PlanningError naming the arc length, the point and
    the joint (the kins message) if one is out of reach (reach and stroke only: for the
    workspace box and singularities see check_path_in_workspace)."""
    try:
        return machine.ik(P)
    except WorkspaceError as e:
        raise PlanningError(f"path point at s = {s[e.index]:.6g} mm leaves the workspace: {e}") from None


def cartesian_derivs(path, s):
    """(P, P′, P″, P‴) at arc lengths s, each (N, 3)."""
    P, P1, P2, P3 = path.derivs(np.asarray(s, float))
    return np.asarray(P, float), np.asarray(P1, float), np.asarray(P2, float), np.asarray(P3, float)


def joint_derivs(machine, path, s, h: float = STENCIL_H_MM, cart=None, fit_scale: bool = False):
    """(q, q′, q″, q‴) at arc lengths s, each (N, 3): joint positions and their derivatives
    with respect to arc length.  Raises PlanningError naming the first point that leaves the
    workspace (the kins message names the point and the joint).

    On a curve tighter than the stencil the cubic X(±2h) leaves the path (a G64 blend of
    radius 0.06 µm put it kilometres off, out of reach) and q‴'s truncation error ~(h/ℓ)²/4
    grows with the curve's length scale ℓ = min(1/|P″|, 1/√|P‴|).  A row whose stencil leaves
    the reach retries at h ≤ ℓ/10, then at a quarter of its step; ``fit_scale`` bounds h by
    ℓ/10 everywhere (the s-curve's tables; not the default: optimal's IPOPT on kossel/
    bird_kossel fails on tables that differ from today's in the last bit, a defect of its own)."""
    s = np.asarray(s, float)
    P, P1, P2, P3 = cart if cart is not None else cartesian_derivs(path, s)
    Q0 = ik_along(machine, s, P)
    with np.errstate(divide="ignore"):
        ell = 0.1 * np.minimum(1 / np.linalg.norm(P2, axis=1), 1 / np.sqrt(np.linalg.norm(P3, axis=1)))
    # one step for all rows unless a row needs its own: the float h keeps the default results
    # bit-identical to a scalar stencil (numpy's h ** 3 of an array rounds differently)
    hs = np.minimum(h, ell) if fit_scale else np.full(len(s), float(h))
    q1, q2, q3 = (np.empty_like(Q0) for _ in range(3))
    todo = np.arange(len(s))
    for _ in range(5):
        step = float(h) if (hs[todo] == h).all() else hs[todo][:, None]
        Q, ok = _stencil(machine, P[todo], P1[todo], P2[todo], P3[todo], step)
        rows = todo[ok]
        hh = step if isinstance(step, float) else step[ok]
        Qm2, Qm1, Qp1, Qp2 = (Q[k][ok] for k in (-2, -1, 1, 2))
        q1[rows] = (-Qp2 + 8 * Qp1 - 8 * Qm1 + Qm2) / (12 * hh)
        q2[rows] = (-Qp2 + 16 * Qp1 - 30 * Q0[rows] + 16 * Qm1 - Qm2) / (12 * hh * hh)
        q3[rows] = (Qp2 - 2 * Qp1 + 2 * Qm1 - Qm2) / (2 * hh ** 3)
        todo = todo[~ok]
        if len(todo) == 0:
            return Q0, q1, q2, q3
        hs[todo] = np.where(ell[todo] < hs[todo], ell[todo], hs[todo] / 4)
    i = int(todo[0])
    raise PlanningError(f"path point at s = {s[i]:.6g} mm {P[i]} is at the edge of reach "
                        f"(a joint-derivative stencil of ±{2 * hs[i]:.3g} mm leaves it)")


def _stencil(machine, P, P1, P2, P3, h):
    """IK of the local cubic X(kh), k = ±1, ±2 (h a float or one per row, (n, 1)):
    ({k: q}, rows whose four points are in reach)."""
    Q, ok = {}, np.ones(len(P), bool)
    for k in (-2, -1, 1, 2):
        d = k * h
        X = P + P1 * d + P2 * (d * d / 2) + P3 * (d * d * d / 6)
        Q[k], reach = machine._ik(X)  # stencil points are ≤ 2h off the path: no stroke check
        ok &= ~(reach < 0).any(axis=1)
    return Q, ok


def time_derivs(D1, D2, D3, sd, sdd, sddd):
    """Velocity, acceleration, jerk in time of x(s(t)) from x′, x″, x‴ (N, k) and ṡ, s̈, s⃛ (N,).

    ẋ = x′ṡ,  ẍ = x″ṡ² + x′s̈,  x⃛ = x‴ṡ³ + 3x″ṡs̈ + x′s⃛.  Broadcasts over leading axes.
    """
    sd, sdd, sddd = (np.asarray(x, float)[..., None] for x in (sd, sdd, sddd))
    v = D1 * sd
    a = D2 * sd * sd + D1 * sdd
    j = D3 * sd ** 3 + 3 * D2 * sd * sdd + D1 * sddd
    return v, a, j


def peak_ratios(v, a, j, lim) -> np.ndarray:
    """[v, a, j] peak |value| / limit (over all leading axes) for a kins Limits."""
    return np.array([np.abs(v).max() / lim.v, np.abs(a).max() / lim.a, np.abs(j).max() / lim.j])


def feed_cap(path, s, limits, T: float, kappa=None) -> np.ndarray:
    """min(F_max, F, F_clim) along s: the programmed feed ceiling (planners.feed) and the chord-error cap
    F_clim = (2/T)√(ρ² − (ρ − ε)²) of Erwinski et al., TII 2022 (the chord of one period
    deviates ≤ ε from an arc of radius ρ)."""
    kappa = np.asarray(path.curvature(s) if kappa is None else kappa, float)
    return np.minimum(feed_ceiling(path, s, limits.feed_max), chord_feed_cap(kappa, limits.chord_error_mm, T))


def chord_feed_cap(kappa, eps: float, T: float) -> np.ndarray:
    """F_clim = (2/T)√(ρ² − (ρ − ε)²) at curvatures κ ≥ 0 (ρ = 1/κ; straight: inf): the feed at
    which the chord of one period deviates ε from an arc of radius ρ (TII 2022)."""
    kappa = np.asarray(kappa, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = np.where(kappa > 0, 1.0 / np.maximum(kappa, 1e-300), np.inf)
        # ρ² − (ρ − ε)² = 2ρε − ε² (no inf − inf on straight parts); ρ ≤ ε: any chord is within
        # ε, the cap is the diameter per period
        return np.where(rho > eps, (2.0 / T) * np.sqrt(np.maximum(2 * rho * eps - eps * eps, 0.0)), 2 * rho / T)


def cross_norm(P1, P2) -> np.ndarray:
    """|P1 × P2| per row of (…, 3) arrays (κ of an arc-length parametrisation from P′, P″):
    np.linalg.norm(np.cross(P1, P2), axis=-1)'s operations, in its order, on the columns (numpy
    ran those of (N, 3) arrays in inner loops of 3: 3× the time on a 10⁶-row table)."""
    a0, a1, a2 = P1[..., 0], P1[..., 1], P1[..., 2]
    b0, b1, b2 = P2[..., 0], P2[..., 1], P2[..., 2]
    c0, c1, c2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
    return np.sqrt(c0 * c0 + c1 * c1 + c2 * c2)


def table_feed_cap(path, table, limits, T: float) -> np.ndarray:
    """min(F_max, F_clim) on a PathTable's grid (κ = |P′ × P″| of the arc-length parametrisation)."""
    kappa = cross_norm(table.cart[1], table.cart[2])
    return feed_cap(path, table.s, limits, T, kappa=kappa)


def join_jumps(path, table, machine):
    """[(s, Δq″ per joint)] at the G1 joins where q″ jumps (second_derivative_jumps). The stencil
    is fitted to the curve: next to a µm blend the fixed 0.02 mm one reads Δq″ far from J(P)·ΔP″,
    too high or too low (docs/TUNING.md, twenty-third session)."""
    out = []
    for sj, _ in second_derivative_jumps(path, table, machine, corner_list(path)):
        q2 = joint_derivs(machine, path, np.array([sj - 1e-7, sj + 1e-7]), fit_scale=True)[2]
        out.append((sj, np.abs(q2[1] - q2[0])))
    return out


def linspaces(a, b, n) -> np.ndarray:
    """np.linspace(a[k], b[k], n[k]) for every k (n ≥ 2), concatenated: numpy's values (k·step
    + a, the end set to b; k/div·Δ + a where the step underflows) without a call per interval."""
    a, b, n = np.asarray(a, float), np.asarray(b, float), np.asarray(n, np.int64)
    first = np.cumsum(n) - n
    ph = np.repeat(np.arange(len(n)), n)
    k = (np.arange(int(n.sum())) - first[ph]).astype(float)
    delta, div = b - a, (n - 1).astype(float)
    step = delta / div
    y = np.where(step[ph] == 0, k / div[ph] * delta[ph], k * step[ph]) + a[ph]
    y[first + n - 1] = b
    return y


class PathTable:
    """Derivative tables on an arc-length grid, for fast repeated checks.

    Evaluating a NURBS at arc length needs a Newton inversion per call; planners that check
    limits thousands of times (s-curve repair, PSO swarms, IPOPT) read these tables instead.
    The grid is uniform within each piece between exact-stop corners, and holds each corner
    twice (its value from the left and from the right), so no interpolation blends the two
    sides of a corner.  x′ and x″ are interpolated by cubic Hermite with the next derivative
    as slope (O(h⁴)), x‴ linearly (O(h²)), for the Cartesian axes and, with a machine, the
    joints (`joint` is None without one).  ``fit_scale``: the joint stencil bounded by the
    curve's length scale (:func:`joint_derivs`), here and in the join jumps read with this table.
    ``refine`` (the s-curve's tables): cells split to ≤ REFINE_RADII curvature radii and rows
    either side of a NURBS's knots (not the default: optimal on keops/bird ran > 10 min on it).
    """

    def __init__(self, path, machine=None, ds: float = 0.05, min_points: int = 2001,
                 fit_scale: bool = False, refine: bool = False):
        L = float(path.length)
        self.length, self.fit_scale, self.refined = L, fit_scale, refine
        # pieces between the path's joins (segment ends of a line/arc path, corners): a
        # derivative that jumps at a join is never blended, and a segment shorter than ds
        # still gets points of its own (a 0.04 mm G64 blend arc)
        self.edges = np.array([0.0] + breakpoints(path) + [L])
        per_mm = max(1.0 / ds, (min_points - 1) / L)
        a, b = self.edges[:-1], self.edges[1:]
        self.counts = np.maximum(8, np.ceil((b - a) * per_mm).astype(np.int64) + 1)
        self.s = linspaces(a, b, self.counts)
        self.offset = np.cumsum(self.counts) - self.counts
        self.hs = self.s[self.offset + 1] - self.s[self.offset]
        if refine:
            inner = self._refine(path)
        else:
            # evaluate one-sidedly: the end points of each piece a hair inside it
            piece = np.repeat(np.arange(len(self.counts)), self.counts)
            inner = np.clip(self.s, (a + 1e-9)[piece], (b - 1e-9)[piece])
            self.cart = cartesian_derivs(path, inner)
        self.joint = (joint_derivs(machine, path, inner, cart=self.cart, fit_scale=fit_scale)
                      if machine is not None else None)

    def _refine(self, path):
        """Add rows 1e-7 mm either side of a NURBS's knots (P‴ jumps there, which interpolation
        across a knot smears) and split every cell wider than REFINE_RADII curvature radii at its
        ends until none is (a lobe tip narrower than the base spacing is a curvature peak the
        interpolated tables would miss). A path with no cell to split keeps the uniform grid bit
        for bit (optimal warm-starts from scurve_joint, and its IPOPT run is sensitive to that start).
        Sets s, offset, counts, cart, refined; returns the rows' one-sided evaluation points."""
        S, piece = self.s, np.repeat(np.arange(len(self.counts)), self.counts)
        inner = lambda S, piece: np.clip(S, self.edges[piece] + 1e-9, self.edges[piece + 1] - 1e-9)
        cart = cartesian_derivs(path, inner(S, piece))
        self.refined, self.cart = len(self._cells_to_split(S, piece, cart)[0]) > 0, cart
        if not self.refined:
            return inner(S, piece)
        sk = interior_knots(path)
        if len(sk):
            sk = np.concatenate([sk - 1e-7, sk + 1e-7])
            pk = np.clip(np.searchsorted(self.edges, sk, side="right") - 1, 0, len(self.counts) - 1)
            keep = (sk > self.edges[pk] + 1e-9) & (sk < self.edges[pk + 1] - 1e-9)
            S, piece, cart = self._add_rows(path, S, piece, cart, sk[keep], pk[keep], inner)
        for _ in range(12):
            need, k, h = self._cells_to_split(S, piece, cart)
            if len(need) == 0:
                break
            cell = np.repeat(need, k - 1)           # k − 1 new rows per cell at fractions i/k
            frac = (np.arange(len(cell)) - np.repeat(np.cumsum(k - 1) - (k - 1), k - 1) + 1) / np.repeat(k, k - 1)
            S, piece, cart = self._add_rows(path, S, piece, cart, S[cell] + h[cell] * frac, piece[cell], inner)
        self.s, self.cart, self.row_piece = S, cart, piece
        self.counts = np.bincount(piece, minlength=len(self.counts))
        self.offset = np.concatenate([[0], np.cumsum(self.counts)[:-1]])
        return inner(S, piece)

    @staticmethod
    def _cells_to_split(S, piece, cart):
        """(cells wider than REFINE_RADII curvature radii at their ends, the parts to split
        each into (≤ 64), all cell widths)."""
        h = np.diff(S)
        need, parts = curvature_splits(h, cross_norm(cart[1], cart[2]), REFINE_RADII, REFINE_MIN_MM, 64,
                                       piece[1:] == piece[:-1])
        return need, parts, h

    @staticmethod
    def _add_rows(path, S, piece, cart, s_new, p_new, inner):
        """The grid with rows s_new (of pieces p_new) added, sorted within their pieces."""
        c_new = cartesian_derivs(path, inner(s_new, p_new))
        if (np.diff(piece) >= 0).all() and (np.diff(S) >= 0).all() and np.isfinite(s_new).all():
            # the rows are in (piece, s) order and s never decreases: the new rows, put in that
            # order, go after the rows of their piece at or before them, where np.lexsort of all
            # rows puts them (a sort of the 10⁶ rows and their tables per call cost ~0.2 s)
            order = np.lexsort((s_new, p_new))
            s_new, p_new = s_new[order], p_new[order]
            pos = np.clip(np.searchsorted(S, s_new, side="right"),
                          np.searchsorted(piece, p_new, side="left"), np.searchsorted(piece, p_new, side="right"))
            return (np.insert(S, pos, s_new), np.insert(piece, pos, p_new),
                    tuple(np.insert(a, pos, b[order], axis=0) for a, b in zip(cart, c_new)))
        S, piece = np.concatenate([S, s_new]), np.concatenate([piece, p_new])
        order = np.lexsort((S, piece))
        return S[order], piece[order], tuple(np.concatenate([a, b])[order] for a, b in zip(cart, c_new))

    @staticmethod
    def _interp(tab, i, w, h):
        X, X1, X2, X3 = tab
        w, h = w[..., None], h[..., None]
        # each power, weight·h and row gather once (the s-curve's limit checks call this 10⁵
        # times): the same operations in the same order as the terms written out
        w2, w3 = w ** 2, w ** 3
        h00, h10 = 2 * w3 - 3 * w2 + 1, w3 - 2 * w2 + w
        h01, h11 = -2 * w3 + 3 * w2, w3 - w2
        h10h, h11h = h10 * h, h11 * h
        j = i + 1
        A1, B1, A2, B2, A3, B3 = X1[i], X1[j], X2[i], X2[j], X3[i], X3[j]
        d1 = h00 * A1 + h10h * A2 + h01 * B1 + h11h * B2
        d2 = h00 * A2 + h10h * A3 + h01 * B2 + h11h * B3
        d3 = (1 - w) * A3 + w * B3
        return d1, d2, d3

    def _locate(self, s, search=None):
        """(row i, weight w, spacing h): s lies between rows i and i+1 of its piece.
        A corner itself counts to the piece after it (callers stay inside pieces).
        ``search(a, s)``: np.searchsorted(a, s, side="right") by another way (the s-curve's
        checks search windows of the grid: scurve_batch)."""
        search = search or (lambda a, x: np.searchsorted(a, x, side="right"))
        s = np.clip(np.asarray(s, float), 0.0, self.length)
        if self.refined:
            # the sorted grid holds each join twice: the last row ≤ s, kept inside s's piece,
            # which is the row's own (a piece's rows run from its start to its end, and at a
            # join the second row starts the next piece, as the search of the edges has it)
            r = search(self.s, s) - 1
            p = self.row_piece[r]
            i = np.clip(r, self.offset[p], self.offset[p] + self.counts[p] - 2)
            h = self.s[i + 1] - self.s[i]
            return i, (s - self.s[i]) / h, h
        p = np.clip(search(self.edges, s) - 1, 0, len(self.hs) - 1)
        h = self.hs[p]
        x = (s - self.edges[p]) / h
        k = np.clip(x.astype(np.int64), 0, self.counts[p] - 2)
        return self.offset[p] + k, x - k, h

    def cartesian(self, s):
        """(P′, P″, P‴) at s; any shape of s, results with a trailing axis of 3."""
        i, w, h = self._locate(s)
        return self._interp(self.cart, i, w, h)

    def joints(self, s):
        """(q′, q″, q‴) at s."""
        i, w, h = self._locate(s)
        return self._interp(self.joint, i, w, h)

    def joint_positions(self, s):
        """q(s) by linear interpolation (for plotting and toppra's order-0 calls only)."""
        i, w, h = self._locate(s)
        Q = self.joint[0]
        return (1 - w)[..., None] * Q[i] + w[..., None] * Q[i + 1]


def second_derivative_jumps(path, table: PathTable, machine=None, corners=()):
    """[(s, jump)]: points where the path is tangent-continuous but P″ jumps (a G1 join of two
    curves, a NURBS's knot of a quadratic or a multiple knot), sorted, and the size of the jump
    max|Δx″| of the checked coordinates (the joints through the IK with a machine, else the
    Cartesian axes).

    No feed-limiting function of the sources covers these: a nonzero feed ṡ there makes the
    acceleration jump by Δx″·ṡ², which a drive reads at period T as a jerk ≈ Δx″·ṡ²/T, so
    every jerk-limited planner caps the feed there at √(c·J·T/max|Δx″|).
    """
    corners = np.asarray(list(corners), float)
    if path.segment_joins() is not None:
        # joins are known: compare the one-sided values there (no search needed)
        known = np.array(breakpoints(path))
        if len(corners) and len(known):
            # distance to the nearest corner from its two sorted neighbours (a scan of every
            # corner per join was quadratic on a CAM program)
            cs = np.sort(corners)
            j = np.searchsorted(cs, known)
            near = np.minimum(np.abs(cs[np.maximum(j - 1, 0)] - known), np.abs(cs[np.minimum(j, len(cs) - 1)] - known))
            known = known[near >= 1e-9]
        if len(known) == 0:
            return []
        lo = hi = known
        cand = np.arange(len(known))
        d = np.zeros(len(known))
    else:
        g = table.s
        P2 = table.cart[2]
        d = np.linalg.norm(np.diff(P2, axis=0), axis=1)
        base = np.median(d) + 1e-12
        dn = np.maximum(np.concatenate([[0.0], d[:-1]]), np.concatenate([d[1:], [0.0]]))
        # a jump stands out from both neighbouring cells; a steep but smooth stretch does not
        cand = np.nonzero((d > 50 * base) & (d > 1e-3) & (d > 4 * dn))[0]
        if len(corners):
            cand = np.array([i for i in cand if np.min(np.abs(corners - g[i])) >= 1e-3], int)
        lo, hi = g[cand], g[cand + 1]
        m, rows = 64, np.arange(len(cand))
        for _ in range(3 if len(cand) else 0):   # 64-way refinements: cell / 2.6e5 ≈ 2e-7 mm
            sub = lo[:, None] + (hi - lo)[:, None] * np.linspace(0, 1, m)[None, :]
            Q2 = cartesian_derivs(path, sub.ravel())[2].reshape(len(cand), m, 3)
            k = np.linalg.norm(np.diff(Q2, axis=1), axis=2).argmax(axis=1)
            lo, hi = sub[rows, k], sub[rows, k + 1]
        d = d[cand]
        # a NURBS's knots are where P″ can jump (every knot of a quadratic one): those the cell
        # search missed (a jump below 50 × the median cell change) are read where they are
        sk = knot_jumps_cartesian(path, corners)
        if len(sk):
            mid = 0.5 * (lo + hi)
            sk = sk[[len(mid) == 0 or np.min(np.abs(mid - x)) > 1e-6 for x in sk]]
            lo, hi = np.concatenate([lo, sk]), np.concatenate([hi, sk])
            d = np.concatenate([d, np.zeros(len(sk))])
        if len(lo) == 0:
            return []
        cand = np.arange(len(lo))
    # one-sided values 1e-7 mm either side, within the path (a jump found in its last cell)
    pairs = np.clip(np.column_stack([lo - 1e-7, hi + 1e-7]).ravel(), 0.0, path.length)
    cart = cartesian_derivs(path, pairs)
    D = (joint_derivs(machine, path, pairs, cart=cart, fit_scale=table.fit_scale)
         if machine is not None else cart)
    cjump = np.linalg.norm(cart[2][1::2] - cart[2][0::2], axis=1)
    jump = np.abs(D[2][1::2] - D[2][0::2]).max(axis=1)
    # keep real jumps (a smooth stretch's change over 2e-7 mm is tiny; a C² knot has none)
    return sorted((float(0.5 * (lo[n] + hi[n])), float(jump[n])) for n in cand
                  if cjump[n] >= max(0.25 * d[n], 1e-6))


def knot_jumps_cartesian(path, corners=(), continuous: float = 1e3) -> np.ndarray:
    """Arc lengths of a NURBS's interior knots (not corners) where P″ jumps: by more than
    ``continuous`` × what P‴ moves it across the two sides 1e-7 mm apart (a C² knot moves it
    by that much; a steep but continuous P″ near a cusp does not pass 10³ of it)."""
    sk = interior_knots(path)
    if len(corners) and len(sk):
        cs = np.asarray(corners, float)
        sk = sk[np.abs(sk[:, None] - cs[None, :]).min(axis=1) >= 1e-3]
    sk = sk[(sk > 1e-7) & (sk < path.length - 1e-7)]
    if len(sk) == 0:
        return sk
    n = len(sk)
    _, _, P2, P3 = cartesian_derivs(path, np.concatenate([sk - 1e-7, sk + 1e-7]))
    jump = np.linalg.norm(P2[n:] - P2[:n], axis=1)
    steep = np.maximum(np.linalg.norm(P3[n:], axis=1), np.linalg.norm(P3[:n], axis=1)) * 2e-7
    return sk[(jump > continuous * steep) & (jump >= 1e-6)]


def interior_knots(path) -> np.ndarray:
    """Arc lengths of a NURBS's distinct interior knots (where its polynomial pieces meet);
    empty for any other path."""
    U = getattr(path, "knots", None)
    if U is None or not hasattr(path, "s_of_u"):
        return np.zeros(0)
    u = np.unique(np.asarray(U, float))[1:-1]
    return np.asarray(path.s_of_u(u), float) if len(u) else np.zeros(0)


def breakpoints(path) -> list[float]:
    """Interior arc lengths where the path's pieces join: the segment boundaries of a
    line/arc path (its curvature jumps there) and the corners.  A NURBS's derivatives jump
    only at its corners (multiple knots, found by `corners()`); elsewhere they are searched."""
    L = path.length
    joins = path.segment_joins()
    out = [] if joins is None else [float(x) for x in np.asarray(joins)]
    out += corner_list(path)
    out = sorted(x for x in out if 1e-9 < x < L - 1e-9)
    merged = []
    for x in out:
        if not merged or x - merged[-1] > 1e-9:
            merged.append(x)
    return merged


def corner_list(path):
    """The path's exact-stop corners strictly inside it (1 nm from the ends)."""
    L = path.length
    return [float(c) for c in path.corners() if 1e-9 < c < L - 1e-9]


def rest_pieces(path):
    """[(s0, s1)] between the path ends and its exact-stop corners: the rest-to-rest pieces
    (ṡ = s̈ = 0 at both ends, so planners solve them independently)."""
    edges = [0.0] + corner_list(path) + [path.length]
    return list(zip(edges[:-1], edges[1:]))
