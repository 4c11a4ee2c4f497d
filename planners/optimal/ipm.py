"""TOPP3-SOCP's problem, solved by a primal-dual interior-point method on banded Newton systems:
the engine's solver (topp3.Piece._socp), in place of copp-py's Clarabel call.

The problem is COPP's (Wang et al., IJMTM 215 (2026) 104355), as copp-py 0.2.3 builds it for
Clarabel (its topp3_socp.rs, clarabel_constraints.rs and constraints.rs, read, not copied): on a
window of stations k = 0 … n (s_k), a_k = ṡ² and b_k = s̈ with the ends held (a rest end: a = b = 0
and the first moving station tied to it by copp's constant-jerk block, a_1 = 1.5·(s_1 − s_0)·b_1),
b linear between stations (a_{k+1} − a_k = Δs_k·(b_k + b_{k+1})), and minimise Σ w_k/√a_k (COPP's
chord weights, its time):

- first order: 0 ≤ a_k ≤ amax_k (the joints' velocity limits and the feed caps), and a ≥ 0 inside
  every cell too (its slope rows at both ends);
- second order: rows ca·a_k + cb·b_k ≤ r (the joints' accelerations, the midpoint caps);
- third order at both ends of every cell, c = (b_{k+1} − b_k)/Δs: rows
  ca·a + cb·b + cc·c + cd ≤ J/√a, J/√a replaced by its tangent at a_lin (copp's linearisation,
  floored at LIN_FLOOR);
- at a rest end, the moving station's a held within the bounds copp derives from the jerk at the
  rest end itself and from every row at the station (stationary_bounds).

Clarabel solves it as a conic program: one sparse KKT system of every row and cone, factored by
QDLDL and refined at each iteration (what that costs: docs/TUNING.md).  Here the objective is kept as it is (separable, convex in a > 0) and every
row couples two neighbouring stations, so with the unknowns ordered station by station the
reduced Newton system [∇²f + Gᵀ(Z/S)G, Eᵀ; E, 0] is banded (half-bandwidth 5) and LAPACK's
banded LU (dgbtrf) factors it in O(n).  Rows that couple many stations (`optimal`'s window reads
of a G1 join: Rows.add_linear) would widen that band over the whole piece: with them the system
is factored by SuperLU in the same order (_Sparse).  Mehrotra's predictor-corrector (Nocedal & Wright,
Numerical Optimization, 2nd ed., §14.2, for the inequalities; the objective's Hessian is
diagonal) with one step length for primal and dual.  A piece's next linearisation starts from the
last one's iterate (warm_start), on the same band layout.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import scipy.sparse as sp
from scipy.linalg import lapack
from scipy.sparse.linalg import splu

# copp's floor of a_lin in the jerk rows' tangent and the stationary bounds (its
# a_linearization_floor)
LIN_FLOOR = 1e-10
EPS = np.finfo(float).eps
# the stopping test: residuals of the dual, the equalities and the inequalities relative to their
# scale, and the duality gap relative to the objective
TOL = 1e-9
MAX_ITER = 120
# ... or, where the residuals stop falling for STALL_ITER iterations, the best iterate if its
# residual is below ALMOST_TOL (Clarabel's reduced tolerances are 5e-5 … 1e-4)
STALL_ITER = 5
ALMOST_TOL = 1e-6
STEP_TO_BOUNDARY = 0.99
# the start: the linearisation's a (b = 0), each slack at least START_SLACK·(1 + |h|), centred at
# μ = START_MU (the fewest iterations of the starts tried: docs/TUNING.md)
START_SLACK = 0.1
START_MU = 1e-3
# a warm start (warm_start): slacks at least WARM_SLACK of their row's size, multipliers at
# least WARM_MU over their slack, pushed that far inside so the next linearisation's moved rows
# do not start at their boundary (the settings tried: docs/TUNING.md)
WARM_SLACK = 1e-2
WARM_MU = 1e-4
# the band's diagonal regularisation (+ on the primal unknowns, − on the equalities' multipliers):
# keeps the LU defined where a station's rows are all inactive
REGULARISATION = 1e-11
# rows wider than this many unknowns: the Newton system is factored as a sparse matrix (_Sparse)
BAND_SPAN = 24
# ... and the rows of more than this many unknowns are summed into it as dense blocks
WIDE_ROW = 8
# refinement steps of the corrector's Newton solve, until its residual is below REFINE_TOL of its
# right side (the predictor's only sets the centring)
REFINE_STEPS = 1
REFINE_TOL = 1e-12


class NoSolution(RuntimeError):
    """The interior-point method stopped without a solution (infeasible rows, or no progress)."""


class Rows:
    """A piece's constraint set in COPP's form, as arrays over its stations ``s``: the joints'
    derivatives d1, d2, d3 (n × 3) and symmetric limits v, a, j (n × 3), the first-order cap (n),
    and rows added at stations (add_2nd, add_3rd)."""

    def __init__(self, s, d1, d2, d3, v, a, j, cap):
        self.s = np.asarray(s, float)
        self.joints = (d1, d2, d3, v, a, j, np.asarray(cap, float))
        with np.errstate(divide="ignore"):
            vel = np.where(d1 != 0, (v / np.where(d1 != 0, np.abs(d1), 1.0)) ** 2, np.inf)
        self.amax = np.minimum(np.min(vel, axis=1), cap)
        k = np.arange(len(self.s))
        r2, r3 = [], []
        for m in range(d1.shape[1]):
            for sg in (1.0, -1.0):
                r2.append((k, sg * d2[:, m], sg * d1[:, m], a[:, m]))
                r3.append((k, sg * d3[:, m], sg * 3 * d2[:, m], sg * d1[:, m], np.zeros(len(k)), j[:, m]))
        self._r2, self._r3 = r2, r3
        self.linear = []        # add_linear's blocks
        self._joint_rows = (len(r2), len(r3))       # the rows added after them: add_2nd, add_3rd
        self._sorted = None

    def add_2nd(self, ca, cb, rhs, start):
        """Rows ca·a + cb·b ≤ rhs at stations start, start + 1, …"""
        ca = np.ravel(ca)
        self._r2.append((start + np.arange(len(ca)), ca, np.ravel(cb), np.ravel(rhs)))
        self._sorted = None

    def add_3rd(self, ca, cb, cc, cd, jmax, station):
        """Rows ca·a + cb·b + cc·c + cd ≤ jmax/√a at one station."""
        ca = np.ravel(ca)
        jmax = np.broadcast_to(np.ravel(jmax), ca.shape)
        self._r3.append((np.full(len(ca), station), ca, np.ravel(cb), np.ravel(cc), np.ravel(cd), jmax))
        self._sorted = None

    def add_linear(self, cols, vals, rhs):
        """Rows vals·x[cols] ≤ rhs over the unknowns x = (a_0, b_0, a_1, b_1, …): ``cols`` (w), ``vals``
        (m × w), ``rhs`` (m).  A window solve holds the blocks whose unknowns all lie inside it;
        copp-py's Robot has no such rows (copp_robot leaves them out)."""
        self.linear.append((np.asarray(cols, np.int64), np.asarray(vals, float), np.asarray(rhs, float)))

    def copp_robot(self):
        """The same rows as a copp-py Robot: for Clarabel where the IPM has no solution, and TOPP2-RA."""
        import copp_py as copp
        d1, d2, d3, v, a, j, cap = self.joints
        n = len(self.s)
        rob = copp.Robot(d1.shape[1], capacity=n)
        rob.append_s(self.s)
        rob.set_q(np.zeros_like(d1), d1, d2, 0, dddq=d3)
        rob.add_velocity_limits(v, -v, start_idx_s=0, length=n)
        rob.add_acceleration_limits(a, -a, start_idx_s=0, length=n)
        rob.add_jerk_limits(j, -j, start_idx_s=0, length=n)
        rob.constraints.add_constraint_1st(cap[:, None], 0)
        n2, n3 = self._joint_rows
        for k, ca, cb, rhs in self._r2[n2:]:
            if len(k):
                rob.constraints.add_constraint_2nd(ca[:, None], cb[:, None], rhs[:, None], int(k[0]))
        for k, ca, cb, cc, cd, jm in self._r3[n3:]:
            if len(k):
                rob.constraints.add_constraint_3rd(ca[None, :], cb[None, :], cc[None, :], cd[None, :],
                                                   np.array(jm, float)[None, :], int(k[0]))
        return rob

    def rows(self):
        """(2nd-order rows, 3rd-order rows) as column arrays sorted by station, finite rows only."""
        if self._sorted is None:
            out = []
            for parts in (self._r2, self._r3):
                cols = [np.concatenate(c) for c in zip(*parts)]
                keep = np.isfinite(cols[-1])
                order = np.argsort(cols[0][keep], kind="stable")
                out.append([c[keep][order] for c in cols])
            self._sorted = tuple(out)
        return self._sorted


@dataclasses.dataclass
class Solution:
    a: np.ndarray
    b: np.ndarray
    num_stationary: tuple
    iterations: int
    objective: float
    start: "Start | None" = None


@dataclasses.dataclass
class Start:
    """A solve's Newton system's pattern and last iterate (x, slacks s, multipliers z, y), for
    the next solve of the same rows (``solve(start=…)``): the next linearisation of a piece."""
    band: "_Band"
    x: np.ndarray
    s: np.ndarray
    z: np.ndarray
    y: np.ndarray


def anchor_bounds(c, jmax, distance):
    """copp's bounds on the moving station's a from the jerk at the rest end itself, ``distance``
    away: there the constant-jerk block has √a·c = a_1^(3/2)/(4.5·D²), which each row's q′ term
    (``c``, its rhs ``jmax``) bounds; (lo, hi), or None where a row cannot hold."""
    hi, lo = np.inf, 0.0
    factor = 4.5 ** (1 / 3) * distance ** (2 / 3)
    for cf, r in zip(c, jmax):
        if r == np.inf:
            continue
        if not (np.isfinite(r) and np.isfinite(cf)) or (cf == 0.0 and r < 0.0) or (cf > 0.0 and r < 0.0):
            return None
        if cf == 0.0 or (cf < 0.0 and r >= 0.0):
            continue
        bound = (np.cbrt(abs(r)) / np.cbrt(abs(cf)) * factor) ** 2
        if cf > 0.0:
            hi = min(hi, bound)
        else:
            lo = max(lo, bound)
    # a hair inside, as copp does (64 ulp)
    inset = 64 * EPS
    h_in = max(np.nextafter(hi * (1 - inset), -np.inf), 0.0) if np.isfinite(hi) and hi > 0 else hi
    l_in = np.nextafter(lo * (1 + inset), np.inf) if np.isfinite(lo) and lo > 0 else lo
    return (l_in, h_in) if l_in <= h_in else (lo, hi)


def stationary_bounds(k, end, ds, a_lin_k, amax, r2, r3):
    """copp's bounds (amin, amax) on a at the moving station k next to the rest end at station
    ``end``, ``ds`` away (signed: negative at the stop), where b = a/(1.5·ds) and c = a/(4.5·ds²):
    the rest end's jerk (anchor_bounds), then each row at k, linear in a there, from above or
    below."""
    st, ca, cb, cc, cd, jm = r3
    at_end = st == end
    anchor = anchor_bounds(cc[at_end], jm[at_end], abs(ds))
    if anchor is None:
        return np.inf, -np.inf
    lo, hi = anchor
    hi = min(hi, amax)
    h = 1.0 / np.sqrt(max(a_lin_k, LIN_FLOOR))
    st2, ca2, cb2, r = r2
    sel = st2 == k
    coef = ca2[sel] + cb2[sel] / (1.5 * ds)
    hi = min(hi, np.min(r[sel][coef > EPS] / coef[coef > EPS], initial=np.inf))
    lo = max(lo, np.max(r[sel][coef < -EPS] / coef[coef < -EPS], initial=0.0))
    sel = st == k
    coef = ca[sel] + cb[sel] / (1.5 * ds) + cc[sel] / (4.5 * ds * ds) + 0.5 * jm[sel] * h ** 3
    rhs = 1.5 * jm[sel] * h - cd[sel]
    hi = min(hi, np.min(rhs[coef > EPS] / coef[coef > EPS], initial=np.inf))
    lo = max(lo, np.max(rhs[coef < -EPS] / coef[coef < -EPS], initial=0.0))
    return lo, hi


def solve(rows: Rows, a_lin, lo=0, a_ends=(0.0, 0.0), b_ends=(0.0, 0.0), stationary=(1, 1),
          start: Start | None = None) -> Solution:
    """TOPP3-SOCP on stations lo … lo + len(a_lin) − 1 of ``rows``, linearised around a_lin, its
    ends at (a_ends, b_ends); ``stationary``: (start, end) 1 where that end is a rest (copp's
    num_stationary_max: used where the end's a and b are 0).  ``start``: an earlier solution's
    (Solution.start) where its rows had the same pattern: its Newton system's layout is reused and
    its iterate starts this solve (warm_start); otherwise the cold start."""
    a_lin = np.asarray(a_lin, float)
    n = len(a_lin) - 1
    if n < 2:
        raise NoSolution(f"a window of {n + 1} stations")
    if np.isscalar(stationary):
        stationary = (stationary, stationary)
    ns = tuple(int(m) if ae == 0.0 and be == 0.0 else 0 for m, ae, be in zip(stationary, a_ends, b_ends))
    if max(ns) > 1:
        raise ValueError("more than one stationary station")
    s = rows.s[lo:lo + n + 1]
    ds = np.diff(s)
    r2_all, r3_all = rows.rows()
    r2 = _window(r2_all, lo, n)
    r3 = _window(r3_all, lo, n)
    amax = rows.amax[lo:lo + n + 1]
    h = 1.0 / np.sqrt(np.maximum(a_lin, LIN_FLOOR))
    p = _Problem(2 * (n + 1))
    # the ends: held (a rest end at 0, its b at 0)
    fixed = {0: a_ends[0], 1: b_ends[0], 2 * n: a_ends[1], 2 * n + 1: b_ends[1]}
    # equalities: copp's constant-jerk block at a rest end, then b linear between stations
    if ns[0]:
        p.eq([(2, 1.0), (3, -1.5 * ds[0])], 0.0)
    if ns[1]:
        p.eq([(2 * n - 2, 1.0), (2 * n - 1, 1.5 * ds[-1])], 0.0)
    k = np.arange(ns[0], n - ns[1])
    p.eq_rows([(2 * k, 1.0), (2 * k + 2, -1.0), (2 * k + 1, ds[k]), (2 * k + 3, ds[k])], np.zeros(len(k)))
    # first order
    for side, kk, end, d in ((0, 1, 0, ds[0]), (1, n - 1, n, -ds[-1])):
        if ns[side]:
            amin_k, amax_k = stationary_bounds(kk, end, d, a_lin[kk], amax[kk], r2, r3)
            if amax_k < amin_k:
                raise NoSolution(f"the rest end's bounds cross at station {lo + kk}")
            if np.isfinite(amax_k):
                p.le_rows([(np.array([2 * kk]), 1.0)], np.array([amax_k]))
            p.le_rows([(np.array([2 * kk]), -1.0)], np.array([-amin_k]))
    k = np.arange(ns[0] + 1, n - ns[1])
    p.le_rows([(2 * k, -1.0)], np.zeros(len(k)))
    # a(x) = a_k + 2b_k·x + c·x² ≥ 0 inside each cell too (copp-py 0.2's interval rows): its
    # slope at x = 0 and at the far end, 2a_k + Δs·b_k ≥ 0 and 2a_k + 2Δs·b_k + Δs·b_k+1 ≥ 0
    k = np.arange(ns[0], n - ns[1])
    p.le_rows([(2 * k, -2.0), (2 * k + 1, -ds[k])], np.zeros(len(k)))
    p.le_rows([(2 * k, -2.0), (2 * k + 1, -2 * ds[k]), (2 * k + 3, -ds[k])], np.zeros(len(k)))
    k = np.arange(ns[0] + 1, n - ns[1])
    fin = np.isfinite(amax[k])
    p.le_rows([(2 * k[fin], 1.0)], amax[k[fin]])
    # second order
    st, ca, cb, r = r2
    sel = (st >= ns[0] + 1) & (st < n - ns[1])
    k = st[sel]
    p.le_rows([(2 * k, ca[sel]), (2 * k + 1, cb[sel])], r[sel])
    # third order, the jerk bound J/√a by its tangent at a_lin: (ca + J·h³/2)·a + … ≤ 1.5·J·h − cd
    st, ca, cb, cc, cd, jm = r3
    ca_lin = ca + 0.5 * jm * h[st] ** 3
    rhs = 1.5 * jm * h[st] - cd
    left = (st > ns[0]) & (st <= n - ns[1])        # the cell k − 1 … k
    k = st[left]
    inv = 1.0 / ds[k - 1]
    p.le_rows([(2 * k, ca_lin[left]), (2 * k - 1, -cc[left] * inv), (2 * k + 1, cb[left] + cc[left] * inv)],
              rhs[left])
    right = (st >= ns[0]) & (st < n - ns[1])       # the cell k … k + 1
    k = st[right]
    inv = 1.0 / ds[k]
    p.le_rows([(2 * k, ca_lin[right]), (2 * k + 1, cb[right] - cc[right] * inv), (2 * k + 3, cc[right] * inv)],
              rhs[right])
    # add_linear's blocks inside the window
    for cols, vals, rhs in rows.linear:
        if cols.min() >= 2 * lo and cols.max() <= 2 * (lo + n) + 1:
            p.le_rows([(np.full(len(rhs), c - 2 * lo), vals[:, j]) for j, c in enumerate(cols)], rhs)
    # objective Σ w_k/√a_k over k = 1 … n − 1 (copp's get_weight_a_topp3)
    w = np.zeros(n + 1)
    w[1:n] = 0.5 * (s[2:] - s[:-2])
    if ns[0]:
        w[1] = 0.5 * (5 * s[1] + s[2] - 6 * s[0])
    if ns[1]:
        w[n - 1] = 0.5 * (6 * s[n] - 5 * s[n - 1] - s[n - 2])
    x, its, f, last = p.solve(fixed, w, a_lin, f"stations {lo}…{lo + n}", start)
    a, b = x[0::2].copy(), x[1::2].copy()
    if ns[0]:
        a[0] = b[0] = 0.0
        b[1] = a[1] / (1.5 * ds[0])
    if ns[1]:
        a[n] = b[n] = 0.0
        b[n - 1] = -a[n - 1] / (1.5 * ds[-1])
    return Solution(a, b, ns, its, f, last)


def _window(cols, lo, n):
    st = cols[0]
    i0, i1 = np.searchsorted(st, [lo, lo + n + 1])
    return [st[i0:i1] - lo] + [c[i0:i1] for c in cols[1:]]


class _Problem:
    """Rows over x = (a_0, b_0, …, a_n, b_n), assembled, then solved with some unknowns held."""

    def __init__(self, nx):
        self.nx = nx
        self.le, self.eqs = [], []

    def le_rows(self, terms, rhs):
        """Rows Σ v·x[c] ≤ rhs, one per entry of rhs, ``terms`` [(columns, values)]."""
        self.le.append((len(rhs), terms, rhs))

    def eq_rows(self, terms, rhs):
        """Rows Σ v·x[c] = rhs."""
        self.eqs.append((len(rhs), terms, rhs))

    def eq(self, terms, rhs):
        self.eqs.append((1, [(np.array([c]), v) for c, v in terms], np.array([rhs], float)))

    @staticmethod
    def _matrix(blocks, nx):
        rows, cols, vals, rhs, m = [], [], [], [], 0
        for cnt, terms, r in blocks:
            if cnt == 0:
                continue
            idx = m + np.arange(cnt)
            for c, v in terms:
                rows.append(idx)
                cols.append(np.broadcast_to(c, (cnt,)))
                vals.append(np.broadcast_to(np.asarray(v, float), (cnt,)))
            rhs.append(np.asarray(r, float))
            m += cnt
        if m == 0:
            return sp.csr_matrix((0, nx)), np.zeros(0)
        M = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(m, nx))
        return M, np.concatenate(rhs)

    def solve(self, fixed, w, a_lin, where, start=None):
        G, h = self._matrix(self.le, self.nx)
        E, e = self._matrix(self.eqs, self.nx)
        held = np.zeros(self.nx, bool)
        xh = np.zeros(self.nx)
        for c, v in fixed.items():
            held[c], xh[c] = True, v
        free = np.nonzero(~held)[0]
        h = h - G @ xh
        e = e - E @ xh
        G, E = G[:, free].tocsr(), E[:, free].tocsr()
        # rows left without a free unknown: constants, which must hold
        for M, r, name in ((G, h, "inequality"), (E, e, "equality")):
            empty = np.diff(M.indptr) == 0
            bad = empty & ((r < -1e-9 * (1 + np.abs(r))) if name == "inequality" else (np.abs(r) > 1e-9))
            if bad.any():
                raise NoSolution(f"a held end breaks an {name} row ({where})")
        keep = np.diff(G.indptr) > 0
        G, h = G[keep], h[keep]
        keep = np.diff(E.indptr) > 0
        E, e = E[keep], e[keep]
        # each row scaled to unit largest coefficient (the solution is the same; the steps are
        # not dominated by the jerk rows' J·h³ next to a rest)
        G, h = _scaled(G, h)
        E, e = _scaled(E, e)
        station = free // 2
        is_a = (free % 2) == 0
        wf = np.where(is_a, w[station], 0.0)
        x0 = np.where(is_a, np.maximum(a_lin[station], 0.0), 0.0)
        if start is not None and start.band.matches(G, E):
            start.band.load(G, E)
            band = start.band
        elif _span(G) > BAND_SPAN:
            band, start = _Sparse(G, E, station), None
        else:
            band, start = _Band(G, E, station), None
        x, its, f, last = _ipm(G, h, E, e, wf, is_a, x0, band, where, start)
        out = xh.copy()
        out[free] = x
        return out, its, f, last


def _scaled(M, r):
    """Each row over its largest |coefficient|, its pattern kept (explicit zeros too: a warm start
    compares patterns).  Every row has a coefficient (_Problem.solve drops the others)."""
    if M.shape[0] == 0:
        return M, r
    big = np.maximum(np.maximum.reduceat(np.abs(M.data), M.indptr[:-1]), 1e-300)
    M = M.copy()
    M.data *= np.repeat(1.0 / big, np.diff(M.indptr))
    return M, r / big


class _Band:
    """The reduced Newton system [H + Gᵀ·diag(σ)·G, Eᵀ; E, 0] in LAPACK's band storage: the
    unknowns ordered station by station (each equality's multiplier after the first station it
    touches), Gᵀ·diag(σ)·G's upper triangle assembled as one sparse product with σ and mirrored.
    Built for a pattern of G and E (``matches``), loaded with their values (``load``): a piece's
    linearisations share one."""

    def __init__(self, G, E, station):
        nv, ne = G.shape[1], E.shape[0]
        self.nv, self.N = nv, nv + ne
        self.pattern = _pattern(G, E)
        order = _station_order(E, station)
        self.pos = np.empty(self.N, int)
        self.pos[order] = np.arange(self.N)
        # every pair of a row's entries, each once (the product is symmetric): the term
        # G[r,u]·σ_r·G[r,v] lands at the stored entry (pos of u's column, pos of v's column), u's
        # at or above v's
        m, cnt = G.shape[0], np.diff(G.indptr)
        iu, iv, pr = [], [], []
        for c in np.unique(cnt):
            rows = np.flatnonzero(cnt == c)
            a, b = np.triu_indices(c)
            iu.append((G.indptr[rows][:, None] + a).ravel())
            iv.append((G.indptr[rows][:, None] + b).ravel())
            pr.append(np.repeat(rows, len(a)))
        iu, iv, pr = (np.concatenate(x) if x else np.zeros(0, int) for x in (iu, iv, pr))
        pi, pj = self.pos[G.indices[iu]], self.pos[G.indices[iv]]
        if np.any((pi == pj) & (iu != iv)):
            raise ValueError("a row of G holds a column twice")
        swap = pi > pj
        pi, pj, iu, iv = np.where(swap, pj, pi), np.where(swap, pi, pj), np.where(swap, iv, iu), np.where(swap, iu, iv)
        er = np.repeat(np.arange(ne), np.diff(E.indptr))
        ei, ej = self.pos[nv + er], self.pos[E.indices]
        diag = self.pos[np.arange(nv)]
        self.k = int(max(np.max(pj - pi, initial=0), np.max(np.abs(ei - ej), initial=0), 1))
        ld = self.ld = 3 * self.k + 1
        flat = lambda i, j: (2 * self.k + i - j) + j * ld          # dgbtrf's layout (Fortran order), kl = ku = k
        # the product as a sparse matrix (stored entry × row of G), its terms ordered by entry, then
        # row: the upper triangle and the diagonal; the lower is their mirror (the same sums)
        at = flat(pi, pj)
        order = np.argsort(at * np.int64(max(m, 1)) + pr)
        at, pr = at[order], pr[order]
        starts = np.flatnonzero(np.r_[True, at[1:] != at[:-1]]) if len(at) else np.zeros(0, int)
        self.used = at[starts]
        self.M = sp.csr_matrix((np.zeros(len(at)), pr, np.r_[starts, len(at)]), shape=(len(starts), m))
        self.iu, self.iv = iu[order], iv[order]
        j = self.used // ld
        i = self.used - j * ld - 2 * self.k + j
        self.off = i != j
        self.mirror = flat(j[self.off], i[self.off])
        self.e_flat = (flat(ei, ej), flat(ej, ei))
        self.diag = flat(diag, diag)
        self.ydiag = flat(self.pos[nv:], self.pos[nv:])
        self.load(G, E)

    def matches(self, G, E) -> bool:
        return all(np.array_equal(p, q) for p, q in zip(self.pattern, _pattern(G, E)))

    def load(self, G, E):
        """G's and E's values (on this band's pattern)."""
        self.M.data = G.data[self.iu] * G.data[self.iv]
        self.base = np.zeros(self.ld * self.N)
        # each of E's entries has a stored entry of its own, and its mirror another
        self.base[self.e_flat[0]] = E.data
        self.base[self.e_flat[1]] = E.data
        self.base[self.diag] += REGULARISATION
        self.base[self.ydiag] -= REGULARISATION

    def factor(self, sigma, hdiag):
        ab = self.base.copy()
        prod = self.M @ sigma
        ab[self.used] += prod
        ab[self.mirror] += prod[self.off]
        ab[self.diag] += hdiag
        lu, piv, info = lapack.dgbtrf(ab.reshape((self.ld, self.N), order="F"), self.k, self.k, overwrite_ab=True)
        if info < 0:
            raise ValueError(f"dgbtrf: argument {-info}")
        return lu, piv, info

    def solve(self, fac, rx, ry):
        lu, piv, info = fac
        if info > 0:
            raise NoSolution("singular Newton system")
        rhs = np.empty(self.N)
        rhs[self.pos[:self.nv]] = rx
        rhs[self.pos[self.nv:]] = ry
        sol, _ = lapack.dgbtrs(lu, self.k, self.k, rhs, piv)
        return sol[self.pos[:self.nv]], sol[self.pos[self.nv:]]


def _station_order(E, station):
    """The Newton system's unknowns (x, then E's multipliers) station by station, each equality's
    multiplier after the first station it touches."""
    nv, ne = len(station), E.shape[0]
    first = np.minimum.reduceat(E.indices, E.indptr[:-1]) if ne else np.zeros(0, int)
    key = np.concatenate([station * 4.0 + (np.arange(nv) % 2), station[first] * 4.0 + 2 + np.arange(ne) / (ne + 1.0)])
    return np.argsort(key, kind="stable")


def _span(G) -> int:
    """The widest row of G, in columns (unknowns are ordered station by station)."""
    if G.shape[0] == 0 or G.nnz == 0:
        return 0
    nz = np.diff(G.indptr) > 0
    lo = np.minimum.reduceat(G.indices, G.indptr[:-1][nz])
    hi = np.maximum.reduceat(G.indices, G.indptr[:-1][nz])
    return int(np.max(hi - lo))


class _Sparse:
    """The reduced Newton system of _Band, factored by SuperLU (scipy.sparse.linalg.splu) in the
    stations' order, for rows wider than BAND_SPAN columns (the G1 joins' window reads,
    topp3.Piece._window_reads): dgbtrf's cost grows with the square of the widest row over the
    whole piece, a sparse LU's only where the wide rows are.  The wide rows come in blocks on
    one set of columns (a join's), whose share of Gᵀ·diag(σ)·G is a dense product Vᵀ·diag(σ)·V."""

    def __init__(self, G, E, station):
        self.nv, self.N = G.shape[1], G.shape[1] + E.shape[0]
        self.pattern = _pattern(G, E)
        self.order = _station_order(E, station)
        self.pos = np.empty(self.N, int)          # an unknown's place in that order
        self.pos[self.order] = np.arange(self.N)
        cnt = np.diff(G.indptr)
        wide = np.flatnonzero(cnt > WIDE_ROW)
        groups = {}
        for r in wide:
            groups.setdefault(G.indices[G.indptr[r]:G.indptr[r + 1]].tobytes(), []).append(r)
        self.blocks = [(np.array(rs), G.indices[G.indptr[rs[0]]:G.indptr[rs[0] + 1]].copy()) for rs in groups.values()]
        self.narrow = np.flatnonzero(cnt <= WIDE_ROW)
        self.reg = np.r_[np.full(self.nv, REGULARISATION), np.full(self.N - self.nv, -REGULARISATION)]
        self.load(G, E)

    def matches(self, G, E) -> bool:
        return all(np.array_equal(p, q) for p, q in zip(self.pattern, _pattern(G, E)))

    def load(self, G, E):
        """G's and E's values (on this pattern)."""
        self.Gn = G[self.narrow]
        self.Gnt = self.Gn.T.tocsr()
        self.V = [G[rs][:, cols].toarray() for rs, cols in self.blocks]
        o = self.order
        self.EK = sp.bmat([[None, E.T], [E, None]], format="csr")[o][:, o].tocsc()

    def factor(self, sigma, hdiag):
        H = (self.Gnt @ sp.diags(sigma[self.narrow]) @ self.Gn).tocoo()
        ri, ci, dv = [H.row, np.arange(self.N)], [H.col, np.arange(self.N)], [H.data, self.reg + np.r_[hdiag, np.zeros(self.N - self.nv)]]
        for (rs, cols), V in zip(self.blocks, self.V):
            ri.append(np.repeat(cols, len(cols)))
            ci.append(np.tile(cols, len(cols)))
            dv.append(((V.T * sigma[rs]) @ V).ravel())
        K = sp.csc_matrix((np.concatenate(dv), (self.pos[np.concatenate(ri)], self.pos[np.concatenate(ci)])),
                          shape=(self.N, self.N)) + self.EK
        try:
            # in the stations' order the fill stays within each row's reach; the diagonal pivots
            # of the regularised quasi-definite system
            return splu(K, permc_spec="NATURAL", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        except RuntimeError:        # exactly singular
            return None

    def solve(self, fac, rx, ry):
        if fac is None:
            raise NoSolution("singular Newton system")
        rhs = np.r_[rx, ry]
        sol = np.empty(self.N)
        sol[self.order] = fac.solve(rhs[self.order])
        return sol[:self.nv], sol[self.nv:]


def warm_start(start, G, h):
    """The iterate a solve starts from at an earlier solution of rows of the same pattern (x, s,
    z, y): its x and y; each slack h − G·x where that is at least WARM_SLACK·(1 + |h|), and each
    multiplier at least WARM_MU over its slack."""
    x, y = start.x.copy(), start.y.copy()
    s = np.maximum(h - G @ x, WARM_SLACK * (1.0 + np.abs(h)))
    z = np.maximum(start.z, WARM_MU / s)
    return x, s, z, y


def _pattern(G, E):
    return G.shape, G.indptr, G.indices, E.shape, E.indptr, E.indices


def _ipm(G, h, E, e, w, is_a, x0, band, where, start=None):
    """min Σ w·a^(−½) s.t. G·x ≤ h, E·x = e, from ``start`` (warm_start) or x0: (x, iterations,
    objective, Start)."""
    Gt, Et = G.T.tocsr(), E.T.tocsr()
    m = G.shape[0]
    ia = np.nonzero(is_a)[0]
    wa = w[ia]
    pos_w = wa > 0
    if start is not None:
        x, s, z, y = warm_start(start, G, h)
    else:
        x = x0.copy()
        scale = max(float(np.max(x[ia], initial=0.0)), 1.0)
        x[ia] = np.maximum(x[ia], 1e-2 * scale)
        # slacks at least START_SLACK of their row's size, centred at START_MU (the rows are scaled)
        s = np.maximum(h - G @ x, START_SLACK * (1.0 + np.abs(h)))
        z = START_MU / s
        y = np.zeros(E.shape[0])
    hscale = 1.0 + float(np.max(np.abs(h), initial=0.0))
    escale = 1.0 + float(np.max(np.abs(e), initial=0.0))

    def step(v, dv):
        """The largest α with v + α·dv ≥ 0 (v > 0)."""
        r = float(np.max(-dv / v, initial=0.0))
        return 1.0 / r if r > 0 else np.inf

    best = None
    for it in range(MAX_ITER):
        a = x[ia]
        grad = np.zeros_like(x)
        hd = np.zeros_like(x)
        aw = a[pos_w]
        grad[ia[pos_w]] = -0.5 * wa[pos_w] * aw ** -1.5
        hd[ia[pos_w]] = 0.75 * wa[pos_w] * aw ** -2.5
        f = float(np.sum(wa[pos_w] / np.sqrt(aw)))
        gz, ey = Gt @ z, Et @ y
        rd = grad + gz + ey
        re = E @ x - e
        ri = G @ x + s - h
        mu = float(s @ z) / max(m, 1)
        # the dual residual against its terms' size (its round-off floor: Gᵀz sums large z)
        dscale = 1.0 + max(float(np.max(np.abs(v), initial=0.0)) for v in (grad, gz, ey))
        res = max(float(np.max(np.abs(rd), initial=0.0)) / dscale,
                  float(np.max(np.abs(re), initial=0.0)) / escale,
                  float(np.max(np.abs(ri), initial=0.0)) / hscale,
                  mu * m / (1.0 + f))
        if res < TOL:
            return x, it, f, Start(band, x, s, z, y)
        if best is None or res < best[0]:
            best = (res, it, f, Start(band, x, s, z, y))     # the steps make new arrays
        elif it - best[1] >= STALL_ITER and best[0] < ALMOST_TOL:
            # no progress for STALL_ITER iterations: the best iterate, where it is close enough
            # (Clarabel's AlmostSolved, which copp accepts)
            return best[3].x, it, best[2], best[3]
        sig = z / s
        fac = band.factor(sig, hd)

        def direction(rc, refine):
            rx, ry = -rd - Gt @ ((z * ri - rc) / s), -re
            dx, dy = band.solve(fac, rx, ry)
            gdx = None
            for _ in range(refine):
                # the band's LU against the system itself: σ spans ~20 decades near the end
                gdx = G @ dx
                ex = rx - (hd * dx + Gt @ (sig * gdx) + Et @ dy)
                ey = ry - E @ dx
                if max(float(np.max(np.abs(ex), initial=0.0)), float(np.max(np.abs(ey), initial=0.0))) <= \
                        REFINE_TOL * (1.0 + max(float(np.max(np.abs(rx), initial=0.0)), float(np.max(np.abs(ry), initial=0.0)))):
                    break
                cx, cy = band.solve(fac, ex, ey)
                dx, dy, gdx = dx + cx, dy + cy, None
            ds = -ri - (G @ dx if gdx is None else gdx)
            return dx, dy, ds, (-rc - z * ds) / s

        dx, dy, ds, dz = direction(s * z, 0)
        al = min(1.0, step(s, ds), step(z, dz), step(a[pos_w], dx[ia][pos_w]))
        mu_aff = float((s + al * ds) @ (z + al * dz)) / max(m, 1)
        sigma = (mu_aff / mu) ** 3
        dx, dy, ds, dz = direction(s * z + ds * dz - sigma * mu, REFINE_STEPS)
        al = min(1.0, STEP_TO_BOUNDARY * min(step(s, ds), step(z, dz), step(a[pos_w], dx[ia][pos_w])))
        if not np.isfinite(al) or al < 1e-10:
            raise NoSolution(f"the interior-point steps stalled at iteration {it} ({where})")
        x, y, s, z = x + al * dx, y + al * dy, s + al * ds, z + al * dz
    raise NoSolution(f"no convergence in {MAX_ITER} interior-point iterations ({where})")
