"""The feed of one rest-to-rest piece as a cubic B-spline over arc length, and what it reads at
the piece's stations.

In scaled time (t_u = A/J of the joints, as the TOPP3 engine's Piece) the spline is
w(x) = ṡ^{3/2} over x = s − s0 ∈ [0, L], so that

    ṡ = w^{2/3},   s̈ = ⅔ w^{1/3} w′,   s⃛ = ṡ·ds̈/dx = (2/9) w′² + ⅔ w w″:

finite jerk everywhere, also at rest, where w = 0 and the piece leaves with s ∝ t³ (a constant
jerk start has w linear in x).  A spline of ṡ itself over arc length cannot leave rest with
finite jerk (near rest ṡ ∝ s^{2/3}).  The coefficients at both ends are 0; the others are the
search's variables, c > 0.

Knots are placed by the path's limits, not by any profile's switch times: at equal steps of
the time of the jerk-free time-optimal profile (TOPP2-RA on the same stations), KNOT_STEP_TU
jerk time scales apart, so they are dense where the limits hold the feed low (lobes, joins,
the workspace edge) and sparse on fast stretches, and their number grows with the piece's
duration under its limits, not with its segment count.  Where a G1 join's read or a near-cusp's
curvature dips the feed more than those steps resolve, knots are graded toward it
(_graded_at_dips).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import BSpline
from scipy.signal import find_peaks
from scipy import sparse
from scipy.sparse.linalg import lsqr, spsolve

from planners.verify import FEASIBLE_TOL

# one knot per this many t_u of TOPP2-RA's time (a jerk-limited rise from 0 to A takes 1 t_u)
KNOT_STEP_TU = 0.25
MIN_SPANS = 4
# knots at least this many station intervals apart: a coefficient whose support held fewer
# stations would be free between them
MIN_SPAN_STATIONS = 3
TINY = 1e-12
# knots are graded toward a join or a local minimum where the feed TOPP2-RA allows is below this
# fraction of the feed at the even knots either side (µm blends read 0.001–0.11, a NURBS's
# joins 0.59–0.82)
FEED_DIP = 0.5
# the start (start_within): uniform stretches to reach the limits, then sweeps of the climb back
# toward the target, each raise the largest of these fractions of a coefficient's log-ratio to it,
# in groups of neighbours from the widest power of two the piece holds down to one (coarse to
# fine: climbed in groups of 1–4 only, neighbours that reach a target which reads a few % above
# a limit leave a coefficient between them that can no longer rise, a valley 5 × below the
# target: docs/TUNING.md)
UNIFORM_ROUNDS = 20
# a group of g is started at every (g / CLIMB_OFFSETS)-th coefficient, not at each: a pass reads
# every station whatever g, and starts at each would make a sweep cost K passes
CLIMB_OFFSETS = 8
CLIMB_SWEEPS = 40
CLIMB_FRACTIONS = np.array([1.0, 0.5, 0.25, 0.125, 0.0625])
CHUNK = 1024              # stations a pass of reads() (its temporaries stay in cache)
# the relative raises a push tries on each coefficient, largest first, and the sizes of the
# groups of neighbours it raises together: with groups of 1–4 only, the swarm stalled within 1 %
# of its seed where the jerk holds the feed over many knots (cusp_epitrochoid_keops 1.37 ×
# T_ref; with 8 and 16 1.21 ×: docs/TUNING.md).  Widest first, as the start's climb: single
# coefficients raised first to their stations' limits hold the wider groups after them
# (cusp_trochoid_lcnc's first piece, pushes alone: 4.5 % slower narrow-first, docs/TUNING.md)
PUSH_STEPS = np.array([0.5, 0.2, 0.08, 0.03, 0.01, 0.003, 0.001])
PUSH_GROUPS = (16, 8, 4, 2, 1)
# before those greedy raises, an even round: every group raised by this one small step where
# its stations allow.  Greedy alone, a pass's first groups rise by up to 1.5 × and take the
# jerk their neighbours need to rise with them: cusp_trochoid_lcnc's rise after its first tip
# locked at ~60 mm/s on 7 of 10 seeds, where `optimal` runs 78–97 mm/s (docs/TUNING.md)
PUSH_EVEN = np.array([0.03])
# a coefficient below NOTCH × the smaller of its neighbours is a notch, and a push first tries to
# raise it to these fractions of that neighbour: relative raises (PUSH_STEPS, the swarm's
# log-steps) take dozens of feasible steps out of one, and the feed crawls there (docs/TUNING.md)
NOTCH = 0.1
NOTCH_FILL = np.array([1.0, 0.5, 0.25, 0.1, 0.03])
# a valley of the coefficients (a local minimum and the stretch around it below the lower of
# the highest coefficients either side before a deeper minimum) whose floor is below VALLEY of
# that level is filled toward it by the largest fraction of VALLEY_FILL the stations allow
# (_fill_valleys): where the jerk holds both flanks, raising groups of ≤ 16 neighbours alike, by
# a ramp or a half sine bends the flanks more, and a valley spanning more knots stays
VALLEY = 0.9
VALLEY_FILL = np.array([1.0, 0.5, 0.25, 0.125, 0.0625, 0.03, 0.01])


def interval_time(dx, sd0, sd1):
    """Time over an interval with w = ṡ^{3/2} linear between its ends: ∫dx/w^{2/3} =
    3Δx/(ṡ0 + √(ṡ0ṡ1) + ṡ1), exact at a rest end (w linear: 3Δx/ṡ1); the arithmetic mean of ṡ
    would let a feed that dips to near 0 at a station (a G1 join) pass it in no time."""
    return 3.0 * dx / np.maximum(sd0 + np.sqrt(sd0 * sd1) + sd1, TINY)


def jerk_free_a(piece):
    """ṡ² at the piece's stations of the jerk-free time-optimal profile (TOPP2-RA), within its
    feed caps."""
    return np.maximum(np.minimum(piece.topp2_ra(), piece.cap2), 0.0)


class FeedSpline:
    """The spline's knots and basis on one topp3.Piece's stations, and the reads of any set of
    coefficient columns there (joint v, a, j, the feed cap, the G1 joins' rows)."""

    def __init__(self, piece, margin: float, inner=None, a_ra=None):
        self.piece, self.margin = piece, margin
        self.x = piece.grid - piece.s0
        self.dx = np.diff(self.x)
        self.L = float(self.x[-1])
        self.a_ra = jerk_free_a(piece) if a_ra is None else a_ra
        self.t_ra = self.station_times(np.sqrt(self.a_ra))
        if inner is None:
            m = max(MIN_SPANS, int(math.ceil(self.t_ra[-1] / KNOT_STEP_TU)))
            even = np.interp(np.linspace(0.0, self.t_ra[-1], m + 1)[1:-1], self.t_ra, self.x)
            inner = self._on_stations(np.sort(np.concatenate([even, self._graded_at_dips(piece.joins, even)])))
        self.knots = np.concatenate([[0.0] * 4, inner, [self.L] * 4])
        self.K = len(self.knots) - 4
        self.bases = self._bases()
        # w at the middle of every interval: the feed caps are read there too, where a spline
        # held to a cap at the stations bulges above it (docs/TUNING.md)
        self.mid_basis = sparse.csr_matrix(BSpline.design_matrix((self.x[:-1] + self.x[1:]) / 2, self.knots, 3))
        self.chunks = [(lo, min(lo + CHUNK, len(self.x))) for lo in range(0, len(self.x), CHUNK)]
        self.chunk_bases = [[B[lo:hi] for B in self.bases] for lo, hi in self.chunks]
        # per coefficient: the first and last station under its support [t_k, t_{k+4}]
        self.sup_lo = np.searchsorted(self.x, self.knots[:self.K], side="left")
        self.sup_hi = np.searchsorted(self.x, self.knots[4:self.K + 4], side="right") - 1
        d1, d2, d3 = piece.deriv[1:]
        self.d1, self.d2, self.d3 = d1, d2, d3
        self.d2x3 = 3 * d2
        self.v_abs = np.abs(d1).max(axis=1)
        self.lims = [lim * (1 - margin) for lim in piece.lims]
        # the feed caps (F_max, the chord-error cap) bind ṡ itself, read exactly at the stations
        # and their middles: no margin, or a path at F_max is slower than its seed, which cruises
        # at F_max itself
        self.cap2 = piece.cap2
        self.joins = piece.joins
        # a join's read at T as rows: at the join either side, and (graded stations) weighted
        # at the stations within READ_REACH periods' travel of it (topp3.Piece.join_reads)
        self.join_reads = piece.join_reads
        self._join_rows()
        # per station the fraction of each limit (v, a, j, feed) it is held to: 1 until the
        # samples at T read the limit above 1 over the station (tighten)
        self.factor = np.ones((len(self.x), 4))
        self._limits()

    def _graded_at_dips(self, joins, even):
        """Knots at each station where the feed dips (TOPP2-RA's below FEED_DIP × the larger at the
        even knots either side: a G1 join's read, a near-cusp's curvature peak) over a stretch
        narrower than the even knots' spacing there, and h·2^k either side (h: MIN_SPAN_STATIONS
        station intervals there), out to half that spacing: such a dip is a few µm wide,
        TOPP2-RA passes it in almost no time, so the even steps of its time put no knot there,
        and a spline fitted to a feed that dips between knots rings.  (Graded at joins that do
        not dip, or at a lobe's dip as wide as the spacing, the knots only held the swarm:
        docs/TUNING.md.)"""
        out = []
        bounds = np.concatenate([[0.0], even, [self.L]])
        sd = np.sqrt(self.a_ra)
        # the candidates: the joins and every strict local minimum of the feed inside the piece
        inner = np.nonzero((sd[1:-1] < sd[:-2]) & (sd[1:-1] <= sd[2:]))[0] + 1
        for i in np.union1d(np.array([j[0] for j in joins], np.intp), inner).tolist():
            xj = self.x[i]
            k = int(np.searchsorted(bounds, xj))
            left, right = np.searchsorted(self.x, [bounds[max(k - 1, 0)], bounds[min(k, len(bounds) - 1)]])
            if sd[i] >= FEED_DIP * max(sd[left], sd[min(right, len(sd) - 1)]):
                continue
            spacing = bounds[min(k, len(bounds) - 1)] - bounds[max(k - 1, 0)]
            if self._dip_width(sd, i, spacing) >= spacing:
                continue            # as wide as the even knots' spacing: they follow it
            room = 0.5 * spacing
            h = MIN_SPAN_STATIONS * max(self.dx[max(i - 1, 0)], self.dx[min(i, len(self.dx) - 1)])
            off = h * 2.0 ** np.arange(max(int(math.log2(max(room, h) / h)), 0) + 1)
            off = off[off < room]
            out += [[xj], xj - off, xj + off]
        return np.concatenate(out) if out else np.empty(0)

    def _dip_width(self, sd, i, upto):
        """Length of the stretch around station i where the feed stays below its value there
        / FEED_DIP (the dip), looked for up to ``upto`` either side."""
        x, top = self.x, sd[i] / FEED_DIP
        lo, hi = np.searchsorted(x, [x[i] - upto, x[i] + upto])
        hi = min(hi, len(x) - 1)
        left = np.nonzero(sd[lo:i + 1] >= top)[0]
        right = np.nonzero(sd[i:hi + 1] >= top)[0]
        a = x[lo + left[-1]] if len(left) else x[i] - upto
        b = x[i + right[0]] if len(right) else x[i] + upto
        return b - a

    def _on_stations(self, want):
        """The wanted inner knots moved to stations, ≥ MIN_SPAN_STATIONS intervals apart and from
        the ends."""
        n, out, last = len(self.x), [], 0
        for i in np.searchsorted(self.x, want):
            i = max(int(i), last + MIN_SPAN_STATIONS)
            if i > n - 1 - MIN_SPAN_STATIONS:
                break
            out.append(i)
            last = i
        return self.x[out]

    def refined(self, c):
        """(a FeedSpline with a knot added halfway in TOPP2-RA's time between each two, where a
        station lies ≥ MIN_SPAN_STATIONS from both, its coefficients for the same w): the old
        knots stay, so the same spline is in the new space (knot insertion, Boehm, Computer-Aided
        Design 12(4), 1980), found by least squares at the stations.  Its factors are this one's."""
        old = self.knots[3:self.K + 1]                    # 0, the inner knots, L
        idx = np.searchsorted(self.x, old)
        t_mid = (self.t_ra[idx[:-1]] + self.t_ra[idx[1:]]) / 2
        mid = np.searchsorted(self.t_ra, t_mid)
        keep = (mid - idx[:-1] >= MIN_SPAN_STATIONS) & (idx[1:] - mid >= MIN_SPAN_STATIONS)
        inner = np.sort(np.concatenate([old[1:-1], self.x[mid[keep]]]))
        fine = FeedSpline(self.piece, self.margin, inner, self.a_ra)
        fine.factor = self.factor.copy()
        fine._limits()
        w = self.bases[0] @ np.asarray(c, float)
        B = fine.bases[0].tocsc()[:, 1:-1]
        inside = spsolve((B.T @ B).tocsc(), B.T @ w)
        return fine, np.concatenate([[0.0], np.maximum(inside, TINY), [0.0]])

    def station_times(self, sd):
        """Scaled time at each station of a feed sd (0 at both ends)."""
        return np.concatenate([[0.0], np.cumsum(interval_time(self.dx, sd[:-1], sd[1:]))])

    def spline(self, c) -> BSpline:
        return BSpline(self.knots, c, 3, extrapolate=False)

    def _bases(self):
        """Sparse (n, K) matrices taking coefficients to w, w′, w″ at the stations: a cubic's
        derivative is the quadratic spline on the inner knots with coefficients
        3(c_{i+1} − c_i)/(t_{i+4} − t_{i+1}), its second the linear one likewise (de Boor)."""
        t, x, K = self.knots, self.x, self.K
        B0 = BSpline.design_matrix(x, t, 3)

        def diff(knots, k, n):          # (n − 1, n): the derivative's coefficients
            h = (knots[k + 1:n + k] - knots[1:n]) / k
            return sparse.diags([-1 / h, 1 / h], [0, 1], shape=(n - 1, n))

        D1 = diff(t, 3, K)
        D2 = diff(t[1:-1], 2, K - 1)
        B1 = BSpline.design_matrix(x, t[1:-1], 2) @ D1
        B2 = BSpline.design_matrix(x, t[2:-2], 1) @ D2 @ D1
        return [sparse.csr_matrix(B) for B in (B0, B1, B2)]

    def motion(self, C, bases=None):
        """ṡ, s̈, s⃛ (scaled) at the stations (the rows of ``bases``, all where None) of coefficient
        columns C (K, P)."""
        w, w1, w2 = (B @ C for B in (self.bases if bases is None else bases))
        w = np.maximum(w, 0.0)
        cb = np.cbrt(w)
        return cb * cb, (2.0 / 3.0) * cb * w1, (2.0 / 9.0) * w1 * w1 + (2.0 / 3.0) * w * w2

    def reads(self, C):
        """(interval times (n − 1, P), per-station need (n, P)): the need is the time stretch that
        would bring the station within every limit (held to 1 − margin and to the station's
        factors): max of v/V, √(a/A), ∛(j/J), ṡ/cap, and at a G1 join ∛(max(|j|, |j + κṡ²|)/J)
        (κ signed) for either side's derivatives.  In chunks of CHUNK stations (their temporaries stay small)."""
        C = np.asarray(C, float)
        if C.ndim == 1:
            C = C[:, None]
        n, P = len(self.x), C.shape[1]
        sd_all, need = np.empty((n, P)), np.empty((n, P))
        for k, (lo, hi) in enumerate(self.chunks):
            sd, sdd, sddd = self.motion(C, self.chunk_bases[k])
            sd_all[lo:hi] = sd
            sd2 = sd * sd
            sd3 = sd2 * sd
            # in place (the push reads ~1000 column sets a sweep): the same operations in the
            # same order as |d2ṡ² + d1s̈| and |d3ṡ³ + 3d2ṡs̈ + d1s⃛| per joint
            qa, qj, t, u = (np.empty_like(sd) for _ in range(4))
            for m in range(3):
                d1, d2, d3 = self.d1[lo:hi, m:m + 1], self.d2[lo:hi, m:m + 1], self.d3[lo:hi, m:m + 1]
                a = qa if m == 0 else t
                np.multiply(d2, sd2, out=a)
                a += np.multiply(d1, sdd, out=u)
                np.abs(a, out=a)
                if m:
                    np.maximum(qa, a, out=qa)
                j = qj if m == 0 else t
                np.multiply(d3, sd3, out=j)
                np.multiply(self.d2x3[lo:hi, m:m + 1], sd, out=u)
                u *= sdd
                j += u
                j += np.multiply(d1, sddd, out=u)
                np.abs(j, out=j)
                if m:
                    np.maximum(qj, j, out=qj)
            qa *= self.q_a[lo:hi]
            qj *= self.q_j[lo:hi]
            out = need[lo:hi]
            np.multiply(self.q_vf[lo:hi], sd, out=out)
            np.maximum(out, np.sqrt(qa, out=qa), out=out)
            np.maximum(out, np.cbrt(qj, out=qj), out=out)
        w_mid = np.maximum(self.mid_basis @ C, 0.0)
        cb = np.cbrt(w_mid, out=w_mid)
        np.maximum(need[:-1], np.multiply(cb, cb, out=cb) * self.q_feed_mid, out=need[:-1])
        if len(self.jr_at):
            sd, sdd, sddd = (x[:, None, :] for x in self.motion(C, self.jr_bases))     # (R, 1, P)
            jerk = self.jr_d3 * sd ** 3 + 3 * self.jr_d2 * sd * sdd + self.jr_d1 * sddd    # (R, 3, P)
            # the read signed (topp3._join_rows): |jerk| ≤ J and |jerk + κṡ²| ≤ J
            read = np.maximum(np.abs(jerk), np.abs(jerk + self.jr_kappa * sd * sd)).max(axis=1)
            np.maximum.at(need, self.jr_at, np.cbrt(read * self.q_j[self.jr_at]))
        return interval_time(self.dx[:, None], sd_all[:-1], sd_all[1:]), need

    def _join_rows(self):
        """The join reads as one row per station and side: the station (R,), q′, q″, q‴ and κ
        (R, 3, 1), and the bases' rows there, so reads() takes them all in one product."""
        rows = [(i, D1[side], D2[side], D3[side], kappa) for i, D1, D2, D3, kappa in self.join_reads
                for side in range(len(D1))]
        self.jr_at = np.array([r[0] for r in rows], np.intp)
        self.jr_d1, self.jr_d2, self.jr_d3, self.jr_kappa = (
            np.array([r[m] for r in rows], float).reshape(len(rows), 3, 1) for m in range(1, 5))
        self.jr_bases = [sparse.csr_matrix(B[self.jr_at]) for B in self.bases]

    def _limits(self):
        """Per station the reciprocal limits (n, 1) under the factors: v, feed, a, j."""
        V, A, J = self.lims
        f = self.factor
        self.q_v = (self.v_abs / (V * f[:, 0]))[:, None]
        self.q_feed = (1.0 / np.sqrt(self.cap2 * f[:, 3] ** 2))[:, None]
        self.q_a = (1.0 / (A * f[:, 1]))[:, None]
        self.q_j = (1.0 / (J * f[:, 2]))[:, None]
        # max(q_v·ṡ, q_feed·ṡ) = max(q_v, q_feed)·ṡ exactly (ṡ ≥ 0, rounding is monotone)
        self.q_vf = np.maximum(self.q_v, self.q_feed)
        # an interval's middle under the higher cap of its two stations: a G1 join's cap holds at
        # its station only (topp3.Piece.cap2), F_max and the chord-error cap vary slowly
        self.q_feed_mid = np.minimum(self.q_feed[:-1], self.q_feed[1:])

    def tighten(self, col: int, s_lo: float, s_hi: float, ratio: float, extra: float) -> None:
        """Limit ``col`` (topp3.LIMIT_COLUMNS) at the stations under [s_lo, s_hi] (path s) and two
        either side held to its present fraction / (ratio·(1 + extra)): the samples at T read it
        ``ratio`` × the limit there."""
        x = self.x + self.piece.s0
        i0 = max(int(np.searchsorted(x, s_lo, side="right")) - 2, 0)
        i1 = min(int(np.searchsorted(x, s_hi, side="left")) + 2, len(x))
        self.factor[i0:i1, col] /= ratio * (1 + extra)
        self._limits()

    def fit(self, sd_target):
        """Coefficients whose ṡ is close to sd_target (scaled) at the stations: least squares on
        w = ṡ^{3/2}, the ends 0, every other coefficient > 0."""
        w = np.maximum(sd_target, 0.0) ** 1.5
        B = self.bases[0].tocsc()[:, 1:-1]
        c = lsqr(B, w, atol=1e-12, btol=1e-12, iter_lim=20 * self.K)[0]
        return np.concatenate([[0.0], np.maximum(c, 1e-6 * max(float(w.max()), TINY)), [0.0]])

    def time(self, c) -> float:
        return float(self.reads(c)[0].sum())

    def within(self, c) -> bool:
        return bool(self.reads(c)[1].max() <= 1 + FEASIBLE_TOL)

    def start_within(self, target):
        """A version of ``target`` within the limits at the stations that lies below it by the
        least the climb finds, or None: the target uniformly stretched until within (a G1 join's
        read κṡ² shrinks slower than the stretch: repeated, at most UNIFORM_ROUNDS), then each
        coefficient raised back toward the target by the largest of CLIMB_FRACTIONS of their
        log-ratio that keeps the stations under its support within, in groups of g neighbours
        (_climb_groups, widest first), until a sweep moves nothing or CLIMB_SWEEPS.  Where the
        target holds the limits it is returned; elsewhere only the stretches that break them stay
        slower, by as much as their neighbours' limits require.  Deterministic."""
        target = np.asarray(target, float)
        c = target
        for _ in range(UNIFORM_ROUNDS):
            if self.reads(c)[1].max() <= 1.0:
                break
            c = self.scaled_within(c)
        if self.reads(c)[1].max() > 1.0:
            return None
        if c is target:
            return target.copy()
        c = c.copy()

        def toward(c, rows, ks):
            return np.maximum(target[rows] / np.maximum(c[rows], TINY), 1.0)[:, None] ** CLIMB_FRACTIONS[None, :]

        for _ in range(CLIMB_SWEEPS):
            before = c.copy()
            for g in self._climb_groups():
                self._raise(c, g, toward, CLIMB_FRACTIONS, max(g // CLIMB_OFFSETS, 1))
            if np.array_equal(c, before):
                break
        return c

    def _climb_groups(self):
        """The group sizes of the climb: the powers of two up to the free coefficients' count,
        widest first."""
        return [1 << k for k in range(int(math.log2(max(self.K - 2, 1))), -1, -1)]

    def _raise(self, c, g, factors, gain, stride: int = 1):
        """c (in place) with its free coefficients in groups of g neighbours raised by one column
        of ``factors(c, rows, ks)`` (rows: the groups' coefficients, ks: each one's place in its
        group; (rows, columns) ≥ 1): per group the column of largest ``gain`` that keeps the
        stations under the group's supports within the limits (none where none does).  Groups
        g + 3 apart have supports that share at most a knot, where the other's w, w′, w″ are 0:
        a pass raises every (g + 3)-th group at once, and the passes start groups at every
        ``stride``-th coefficient."""
        period = g + 3
        for r in range(0, period, stride):
            firsts = np.arange(1 + r, self.K - 1, period)
            if not len(firsts):
                continue
            at = firsts[:, None] + np.arange(g)[None, :]          # (groups, g)
            inside = at <= self.K - 2
            C = np.repeat(c[:, None], len(gain), axis=1)
            rows, ks = at[inside], np.broadcast_to(np.arange(g), at.shape)[inside]
            C[rows] *= factors(c, rows, ks)
            last = np.minimum(firsts + g - 1, self.K - 2)
            need = np.vstack([self.reads(C)[1], np.zeros((1, len(gain)))])
            lo, hi = self.sup_lo[firsts], self.sup_hi[last]
            worst = np.maximum.reduceat(need, np.ravel(np.column_stack([lo, hi + 1])), axis=0)[::2]
            score = np.where(worst <= 1.0, gain[None, :], -1.0)
            best = np.argmax(score, axis=1)
            move = score[np.arange(len(firsts)), best] > 0
            sel = move[:, None] & inside
            c[at[sel]] = C[at[sel], np.broadcast_to(best[:, None], at.shape)[sel]]

    def push(self, c, sweeps: int = 1, groups=PUSH_GROUPS):
        """c with its free coefficients raised, g neighbours at a time for each g of ``groups``:
        first all by the even step PUSH_EVEN, then each by the largest of PUSH_STEPS, where that
        keeps the stations under their support within the limits (none where none does;
        _raise): w grows with every coefficient (the basis is ≥ 0), so a raise never costs time.
        Neighbours are raised alike, or by a ramp rising or falling across them (the jerk at a
        group's edge limits a raise alike where the feed climbs or falls there), or, in groups
        of more than 4, by a half sine (the middle most, the edges least: where the jerk holds
        the feed, a stretch rises only as a whole and smoothly); of the feasible raises, the one
        largest in sum.  Deterministic."""
        c = self._fill_valleys(self._fill_notches(np.array(c, float)))
        for _ in range(sweeps):
            for steps in (PUSH_EVEN, PUSH_STEPS):
                for g in groups:
                    shapes = [np.ones(g)] + ([np.arange(1, g + 1) / g, np.arange(g, 0, -1) / g] if g > 1 else []) \
                        + ([np.sin(np.pi * (np.arange(g) + 0.5) / g)] if g > 4 else [])
                    up = np.concatenate([1.0 + np.outer(steps, sh) for sh in shapes])    # (columns, g)
                    self._raise(c, g, lambda c, rows, ks: up[:, ks].T, (up - 1).sum(axis=1))
        return c

    def _fill_notches(self, c):
        """c (in place) with each notch (a free coefficient below NOTCH × its smaller neighbour)
        raised to the largest of NOTCH_FILL × that neighbour that keeps its stations within the
        limits (_raise; none where none does)."""
        inner = c[1:-1]
        neighbour = np.minimum(c[:-2], c[2:])
        notch = np.zeros(len(c), bool)
        notch[1:-1] = inner < NOTCH * neighbour
        if notch.any():
            def factors(c, rows, ks):
                want = np.minimum(c[rows - 1], c[rows + 1])[:, None] * NOTCH_FILL[None, :]
                up = np.maximum(want / np.maximum(c[rows], TINY)[:, None], 1.0)
                return np.where(notch[rows][:, None], up, 1.0)
            self._raise(c, 1, factors, NOTCH_FILL)
        return c

    def _fill_valleys(self, c):
        """c (in place) with each valley (VALLEY) raised toward its level by the largest fraction
        of VALLEY_FILL of (level − c)₊ that keeps the stations under it within the limits: the
        floor most, the rims not at all, so the flanks flatten.  Deepest first; valleys whose
        raised coefficients lie ≥ 4 apart (supports sharing at most a knot) in one pass."""
        inner = c[1:-1]
        minima, props = find_peaks(-inner, prominence=0.0)
        if not len(minima):
            return c
        level = np.minimum(inner[props["left_bases"]], inner[props["right_bases"]])
        deep = inner[minima] < VALLEY * level
        bases = zip(minima, props["left_bases"], props["right_bases"], level, deep)
        # (depth, first and last coefficient, level), the deepest first
        todo = sorted((float(inner[m] / lv), int(a) + 1, int(b) + 1, float(lv)) for m, a, b, lv, d in bases if d)
        while todo:
            batch, rest, taken = [], [], []
            for v in todo:
                _, a, b, _ = v
                if all(b + 4 <= a2 or b2 + 4 <= a for a2, b2 in taken):
                    batch.append(v)
                    taken.append((a, b))
                else:
                    rest.append(v)
            C = np.repeat(c[:, None], len(VALLEY_FILL), axis=1)
            for _, a, b, lv in batch:
                up = np.maximum(lv - c[a:b + 1], 0.0)
                C[a:b + 1] += up[:, None] * VALLEY_FILL[None, :]
            need = self.reads(C)[1]
            for _, a, b, _ in batch:
                worst = need[self.sup_lo[a]:self.sup_hi[b] + 1].max(axis=0)
                ok = np.flatnonzero(worst <= 1.0)
                if len(ok):
                    c[a:b + 1] = C[a:b + 1, ok[0]]
            todo = rest
        return c

    def scaled_within(self, c):
        """c scaled as a whole (a uniform time stretch) until every station is within its limits."""
        return np.asarray(c, float) / max(float(self.reads(c)[1].max()), 1.0) ** 1.5 / (1 + 1e-9)
