"""`pso` — feed profile optimised by particle swarm (Erwinski, Szczepanski, Tarczewski,
IOP Conf. Ser. MSE 1140, 2021; extended to a delta's joints as planned in Erwinski et al.,
NU·ROBOTI·FTS 2022, shared/SOURCES.md §A).

Shared constraint set with `toppra` and `optimal`: joint v, a, j limits, F_max and the
chord-error feed cap (plus, at a G1 join, the jerk its jump of q″ reads as at T added to the
continuous jerk, bounded as in `optimal`).

Parametrisation.  The path is split at exact-stop corners; on each piece the feed is a
quadratic B-spline ṡ(τ) = Σ cₖBₖ(τ) over normalised time τ ∈ [0, 1] (so s⃛ is piecewise constant,
the class of the s-curve), with c₀ = c₁ = c_{K−2} = c_{K−1} = 0 so the piece starts and ends at
rest with s̈ = 0, and s(τ) = L·∫ṡ/∫₀¹ṡ (exact antiderivative), so every particle reaches the end
of the piece.  Knots: the seed's jerk switch times (then the seed is represented exactly and
the swarm starts from it) plus, with ``extra_knots``, knots at quantiles of the seed's jerk
activity (dense at the FLF minima and G1 joins); ``exact_knots=False`` uses the quantile
knots only.  (A B-spline over arc length, as in the 2021 paper for a Cartesian machine,
cannot leave rest with finite jerk — near rest ṡ ∝ s^{2/3} — hence normalised time.)

A piece with G1 joins (at most MAX_JOINS_CUT) is also searched cut at them (`_SubPiece`):
each join passed at a fixed feed with s̈ = s⃛ = 0, each sub-piece a feed spline of its own with
those ends, in its own normalised time.  The feed must dip at a join (bird: to 57–207 mm/s
from ~850 mm/s between them); a whole-piece spline spends its few control points on that dip
and one time stretch couples all of it, while the cut search shapes each dip-to-dip stretch on
its own.  Per piece the faster of the two is kept (measured on bird and bird_kossel:
docs/TUNING.md).

Objective.  Stretching time by λ divides joint velocity by λ, acceleration by λ², jerk by
λ³ and the feed by λ.  So each whole piece's shape is scaled to the smallest λ at which every
limit holds (the exact penalty for violations: time grows with the violation), and the
objective is the execution time λ.  Every evaluated particle is thus feasible on its
samples; the swarm only searches shapes.  A sub-piece's ends are fixed, so its objective is
its duration × max(1, worst ratio)^PENALTY_POWER instead.  The whole swarm is evaluated at
once (particles × samples arrays).  After the search the best profile is sampled at T and
checked with the independent metrics; a discretisation excess is removed by a further small
stretch of the whole piece (with its join feeds).  The seed is returned where it is faster and
feasible; where it is faster but breaks a limit at T, its fit is stretched at T the same way
and each rest-to-rest piece takes the shorter of that and the swarm's.

Polish (a memetic step, after the swarm).  A swarm finds the basin — which pieces to cut,
the shape of each stretch — but converges slowly in it (docs/TUNING.md).  So its best
particle on each (sub-)piece is re-expressed on a finer spline (`refined`) and improved by
sequential linear programming (`polish`): per step the limit ratio of every joint at every sample
is linearised and an LP in a trust region takes the step.  A step is kept only if the swarm's own
objective falls, so the polish can only improve on the swarm.
``polish_steps=0`` returns the swarm alone.  The swarm runs 20 iterations by default (why:
docs/TUNING.md).

Seeded: the swarm starts around the `scurve_joint` profile (its feed fitted by least
squares), ``seed`` drives all random numbers and the iteration count ends the search, so the
same inputs give the same profile on any machine.  An optional wall-clock ``time_budget_s``
(off by default: it would make the result depend on the machine's speed) is reported in
``info['stopped_by']`` when it ends the search.

Size: this module (~730 lines) and its plan() (~215 lines) are over the project's 400/80-line
guides on purpose this time: another branch is changing its internals for memory on long
programs (issue 18 left them alone; its split into a pso/ package is a later step).
"""
from __future__ import annotations

import math
import time

import numpy as np
from scipy import sparse as sp
from scipy.interpolate import BSpline
from scipy.linalg import LinAlgError, solveh_banded

from .constraints import (JUMP_READ_FACTOR, PathTable, PlanningError, check_limits, check_path,
                          join_jumps, rest_pieces, table_feed_cap)
from .profile import Profile

DEGREE = 2                   # ṡ quadratic per knot span ⇒ s⃛ piecewise constant, as in an s-curve
MIN_KNOT_GAP_T = 2           # seed switch times < 2 servo periods apart share a knot (see _seed_window)
# A piece with G1 joins is cut there into sub-pieces (see _SubPiece).  Their join feed, as a
# fraction of the largest feed at which the join, passed with s̈ = s⃛ = 0, meets every limit
# (_join_feed; the optimum passes bird's joins at 0.99–1.0 of it).  s⃛ = 0 holds over a first
# and last knot span of FLAT_END_SPAN (normalised time) at a join end.  On bird (150 iterations):
# flat span 0.003 / 0.01 / 0.03 with fraction 0.97 gave 1.878 / 1.888 / 1.915 s, 0.01 with 0.99
# 1.967 s; without flat ends (s⃛ free at the join, so the fraction must leave room for the
# continuous jerk) 0.65 gave 1.921 s; with every piece cut 0.6–0.7 1.884–1.888 s, 0.8 1.899 s,
# 0.95 1.943 s.
JOIN_FEED_FRACTION = 0.97
FLAT_END_SPAN = 0.003
# control points per sub-piece: bird (as above) gave 2.056 s with 8, 1.888 s with 10 and 2.128 s
# with 16 (150 iterations: more dimensions converge slower); shared by time, 100 in all, 1.927 s
SUBPIECE_CONTROL_POINTS = 10
# a sub-piece's fitness is its duration × max(1, worst limit ratio)^PENALTY_POWER: its ends are
# fixed, so a violation cannot be removed by a time stretch of the sub-piece alone
PENALTY_POWER = 4
# a piece with more joins is searched whole only: each sub-piece is a swarm of its own, and
# kossel's test_part (8–10 joins a piece, at G64 blends of 0.04 mm) took 100 s instead of 28 s
# for sub-pieces that lost to the whole pieces anyway (bird: ≤ 2 joins a piece)
MAX_JOINS_CUT = 6
# samples per sub-piece (at least one per 8 servo periods of the seed's time there): on bird
# 400 gave 1.919 s in 30 s, 200 1.921 s in 26 s, 100 1.924 s in 19 s
SUBPIECE_SAMPLES = 200
# The polish after the swarm (see `polish`): SLP steps at most, the refinement of each piece's
# spline, at most this many spans a whole piece, samples per span (16: with 6 a span, flower's
# polished profile read 1.1× its jerk limit at T between the samples), the share of the worst
# stretch above which a row enters the LP and at most this many rows per coefficient (all rows
# above 0.7: flower 1.2745 s in 13 s; 20 a coefficient: 1.273 s in 8 s; 5: 1.420 s; a threshold
# of 0.95 instead: 1.438 s).  On bird (20 or 40 swarm iterations, then these): 1.7805 s; with whole
# pieces at 60 spans flower got 1.299 s, at 90 1.275 s.
POLISH_ITERATIONS = 40
POLISH_REFINE = 3
POLISH_MAX_SPANS = 90
POLISH_SAMPLES_PER_SPAN = 16
POLISH_ACTIVE = 0.7
POLISH_ROWS_PER_COEFF = 20
# Size bound of a piece (issue 17): the seed's switch times as knots give a piece as many control
# points as its seed has jerk phases, and the dense (samples × control points) basis and seed fit
# grow with the square of its length (a 44 s kossel piece: 1685 knots, 44 000 seed samples,
# 2.5 GB).  Above BASIS_MAX_ELEMENTS (2.5 × test_part's largest, 19 505 × 99) a piece keeps those
# knots but holds its basis sparse (`_sparse_basis`, a banded seed fit) and is not polished; the
# profile's info['fallback'] lists those pieces.  Under the bound the dense arrays are kept.
BASIS_MAX_ELEMENTS = 5_000_000


def _sparse_basis(knots, p, tau):
    """CSR design matrices at τ of the degree-p B-splines on ``knots`` (M, K), of their first
    and second derivatives, and of the antiderivative (M, K + 1, degree p + 1 on the knots with
    one more at each end), with the weights wₖ = ∫₀¹Bₖ = (t_{k+p+1} − t_k)/(p + 1): the
    antiderivative of Σcₖ Bₖ has the coefficients 0, w₀c₀, w₀c₀ + w₁c₁, …  Each row holds at
    most p + 2 nonzeros, so memory grows with M + K, not M·K as the dense arrays do."""
    K = len(knots) - p - 1

    def diff(t, q, n):
        # (n − 1, n): coefficients of the derivative of a degree-q spline on t (knots t[1:−1])
        h = t[q + 1:n + q] - t[1:n]
        g = np.where(h > 0, q / np.where(h > 0, h, 1.0), 0.0)
        return sp.diags([-g, g], [0, 1], shape=(n - 1, n), format="csr")

    d1 = diff(knots, p, K)
    B = BSpline.design_matrix(tau, knots, p)
    B1 = BSpline.design_matrix(tau, knots[1:-1], p - 1) @ d1
    B2 = BSpline.design_matrix(tau, knots[2:-2], p - 2) @ (diff(knots[1:-1], p - 1, K - 1) @ d1)
    A = BSpline.design_matrix(tau, np.concatenate([knots[:1], knots, knots[-1:]]), p + 1)
    w = (knots[p + 1:] - knots[:K]) / (p + 1)
    return B.tocsr(), B1.tocsr(), B2.tocsr(), A.tocsr(), w


class _Shape:
    """B-spline basis over τ ∈ [0, 1] sampled at M points (and its antiderivative)."""

    def __init__(self, K: int, M: int, density=None, degree: int = DEGREE, inner=None,
                 sparse: bool = False):
        """``density``: (τ grid, weights) — knots and samples at its quantiles (uniform if
        None); ``inner``: explicit knots in [0, 1] (then K follows from them); ``sparse``: the
        basis as CSR matrices (see `_sparse_basis`), for a piece over BASIS_MAX_ELEMENTS."""
        self.degree = p = degree
        if inner is not None:
            if density is not None and K > 0:      # add K knots at the density's quantiles
                g, wts = density
                cum = np.concatenate([[0.0], np.cumsum(0.5 * (wts[1:] + wts[:-1]) * np.diff(g))])
                inner = np.concatenate([inner, np.interp(np.linspace(0, 1, K + 2)[1:-1], cum / cum[-1], g)])
            inner = np.unique(np.concatenate([[0.0], np.clip(inner, 0, 1), [1.0]]))
            inner = inner[np.concatenate([[True], np.diff(inner) > 1e-9])]
            K = len(inner) + p - 1
            mids = 0.5 * (inner[1:] + inner[:-1])
            self.tau = np.unique(np.concatenate([np.linspace(0, 1, M), inner, mids]))
        self.K, self.M = K, M
        if inner is not None:
            pass
        elif density is None:
            inner, self.tau = np.linspace(0, 1, K - 2), np.linspace(0, 1, M)
        else:
            g, wts = density
            cum = np.concatenate([[0.0], np.cumsum(0.5 * (wts[1:] + wts[:-1]) * np.diff(g))])
            cum /= cum[-1]
            inner = np.interp(np.linspace(0, 1, K - 2), cum, g)
            inner[0], inner[-1] = 0.0, 1.0
            self.tau = np.unique(np.concatenate([np.interp(np.linspace(0, 1, M // 2), cum, g),
                                                 np.linspace(0, 1, M - M // 2)]))
        if len(inner) != K - p + 1:
            inner = np.interp(np.linspace(0, 1, K - p + 1), np.linspace(0, 1, len(inner)), inner)
        self.knots = np.concatenate([[0] * p, inner, [1] * p])
        self.free = np.arange(2, K - 2)
        self.sparse = sparse
        if sparse:
            self.B, self.B1, self.B2, self.A, self.w = _sparse_basis(self.knots, p, self.tau)
            return
        eye = np.eye(K)
        basis = [BSpline(self.knots, eye[k], self.degree) for k in range(K)]
        self.B = np.stack([b(self.tau) for b in basis], 1)               # (M, K)
        self.B1 = np.stack([b.derivative(1)(self.tau) for b in basis], 1)
        self.B2 = np.stack([b.derivative(2)(self.tau) for b in basis], 1)
        anti = [b.antiderivative(1) for b in basis]
        self.I = np.stack([a(self.tau) - a(0.0) for a in anti], 1)        # ∫₀^τ Bₖ

    def full(self, X):
        """Control points (P, K) from free coefficients (P, K−4), ends pinned at rest."""
        C = np.zeros((X.shape[0], self.K))
        C[:, self.free] = np.maximum(X, 0.0)
        return C

    def eval(self, C):
        """(∫₀¹ṡ dτ (P,), ∫₀^τ ṡ, ṡ, ṡ′, ṡ″ (P, M) each) of control points C (P, K)."""
        if not self.sparse:
            return C @ self.I[-1], C @ self.I.T, C @ self.B.T, C @ self.B1.T, C @ self.B2.T
        # the antiderivative's coefficients: running sums of wₖcₖ from 0 (see _sparse_basis)
        anti = np.concatenate([np.zeros((C.shape[0], 1)), np.cumsum(C * self.w, axis=1)], axis=1)
        return (C @ self.w, (self.A @ anti.T).T, (self.B @ C.T).T, (self.B1 @ C.T).T,
                (self.B2 @ C.T).T)

    def fit(self, tau, v):
        """Least-squares free coefficients of a sampled feed v(τ)."""
        if self.sparse:
            # normal equations of a B-spline basis are banded (half-bandwidth = degree): a
            # banded Cholesky solve, O(samples + K) memory where lstsq needs samples × K
            B = BSpline.design_matrix(tau, self.knots, self.degree).tocsc()[:, self.free]
            N, rhs, p = (B.T @ B).todia(), B.T @ v, self.degree
            ab = np.zeros((p + 1, len(self.free)))
            for d in range(p + 1):
                ab[p - d, d:] = N.diagonal(d)
            try:
                x = solveh_banded(ab, rhs)
            except LinAlgError:
                # a span without samples (seed switch times closer than its sampling) leaves
                # the fit singular there; a tiny ridge picks the small-norm coefficients
                ab[p] += 1e-12 * ab[p].max()
                x = solveh_banded(ab, rhs)
            return np.maximum(x, 1e-6 * max(v.max(), 1e-9))
        eye = np.eye(self.K)
        B = np.stack([BSpline(self.knots, eye[k], self.degree)(tau) for k in range(self.K)], 1)
        x, *_ = np.linalg.lstsq(B[:, self.free], v, rcond=None)
        return np.maximum(x, 1e-6 * max(v.max(), 1e-9))


def _first_at_or_after(s, points):
    """(P, J) index of each row's first sample ≥ each point, 0 where none is (np.argmax of
    s ≥ point, as the join terms had it), clipped to [1, M − 1].  By a search in each row's
    running maximum: O(P·J·log M), where a (P, M) comparison per join made a piece's evaluation
    quadratic in its length (a 44 s kossel piece: 800 joins × 8900 samples × 40 particles)."""
    out = np.zeros((s.shape[0], len(points)), dtype=np.intp)
    if len(points):
        top = np.maximum.accumulate(s, axis=1)
        for r in range(s.shape[0]):
            i = np.searchsorted(top[r], points, side="left")
            out[r] = np.where(i < s.shape[1], i, 0)
    return np.clip(out, 1, s.shape[1] - 1)


def local_need(table, s, v, a, j, lim, m, cap_grid, cap_vals, each=False):
    """(P, M) time stretch each sample alone asks for: the λ at which its joint velocity,
    acceleration and jerk (÷ λ, λ², λ³) and its feed (÷ λ) meet the limits tightened by m.
    ``each``: (P, M·10) instead, every joint's v, a, j and the feed apart (the polish's LP needs
    each smooth piece of the maximum: at a tie of two joints the maximum's slope is one-sided)."""
    d1, d2, d3 = table.joints(s)                                  # (P, M, 3) each
    v3, a3, j3 = v[..., None], a[..., None], j[..., None]
    cap = np.interp(s, cap_grid, cap_vals)
    parts = [np.abs(d1 * v3) / (lim.v * m),
             np.sqrt(np.abs(d2 * v3 ** 2 + d1 * a3) / (lim.a * m)),
             np.cbrt(np.abs(d3 * v3 ** 3 + 3 * d2 * v3 * a3 + d1 * j3) / (lim.j * m)),
             (v / (cap * m))[..., None]]
    if each:
        return np.concatenate(parts, axis=2).reshape(s.shape[0], -1)
    return np.maximum.reduce([x.max(axis=2) for x in parts])


class _PieceProblem:
    def __init__(self, table, s0, s1, limits, T, joins, K, M, cap_grid, cap_vals, density=None,
                 inner=None, sparse=False):
        self.table, self.s0, self.s1, self.L = table, s0, s1, s1 - s0
        self.limits, self.lim, self.T, self.all_joins = limits, limits.joint, T, joins
        self.shape = _Shape(K, M, density, inner=inner, sparse=sparse)
        self.joins = [(sj, d) for sj, d in joins if s0 + 1e-6 < sj < s1 - 1e-6]
        # one-sided joint derivatives at each join (q″ jumps there)
        self.join_derivs = [table.joints(np.array([sj - 1e-9, sj + 1e-9])) for sj, _ in self.joins]
        self.cap_grid, self.cap_vals = cap_grid, cap_vals

    def needs(self, X, margin, each=False):
        """(P, M + joins) time stretch each sample (and each join) alone asks for, and the
        profile arrays at λ = 1: the piece's λ is the row maximum (``each``: see local_need)."""
        sh = self.shape
        C = sh.full(X)
        area, S, V, A, J = sh.eval(C)                        # area: ∫₀¹ ṡ dτ per particle
        bad = area <= 1e-12
        area = np.where(bad, 1.0, area)
        k = (self.L / area)[:, None]
        s = self.s0 + k * S                                  # (P, M), exact
        v, a, j = k * V, k * A, k * J
        s = np.clip(s, self.s0 + 1e-9, self.s1 - 1e-9)
        m = 1 - margin
        cols = [local_need(self.table, s, v, a, j, self.lim, m, self.cap_grid, self.cap_vals, each)]
        rows = np.arange(len(v))
        Jm = self.lim.j * m
        first = _first_at_or_after(s, [sj for sj, _ in self.joins])
        for (sj, dq2), (D1, D2, D3), i in zip(self.joins, self.join_derivs, first.T):
            # the join as `optimal` bounds it: its T-reading 0.75·Δq″·ṡ²/T plus the continuous
            # jerk on either side within the jerk limit.  ṡ, s̈, s⃛ at the join are interpolated
            # between the samples around it: the sample after a 0.04 mm blend arc may already be
            # far up the next line's ramp
            sa, sb = s[rows, i - 1], s[rows, i]
            f = np.clip((sj - sa) / np.maximum(sb - sa, 1e-12), 0.0, 1.0)
            vj, aj, jj = ((1 - f) * x[rows, i - 1] + f * x[rows, i] for x in (v, a, j))
            read = JUMP_READ_FACTOR * dq2[None, :] * vj[:, None] ** 2 / self.T        # (P, 3)
            for d1, d2, d3 in zip(D1, D2, D3):                                       # each side
                cont = np.abs(d3 * vj[:, None] ** 3 + 3 * d2 * (vj * aj)[:, None] + d1 * jj[:, None])
                stretch = join_stretch(read, cont, Jm)
                cols.append(stretch if each else stretch.max(axis=1)[:, None])
        N = np.concatenate(cols, axis=1)
        N[bad | ~np.isfinite(N).all(axis=1)] = np.inf
        return N, (s, v, a, j)

    def scale(self, X, margin):
        """(λ, profile arrays at λ = 1) for each particle: λ = the smallest time stretch at
        which the particle meets every limit (tightened by ``margin``)."""
        N, arrays = self.needs(X, margin)
        return N.max(axis=1), arrays

    def objective(self, X, margin):
        return self.scale(X, margin)[0]

    def refined(self, x):
        """(finer problem, x on it) for the polish: POLISH_REFINE × the spans, uniform in time (the
        seed's switch times can lie a servo period apart: a linear model of the cube-root jerk
        ratio across such a span held for steps a thousand times too small), at most
        POLISH_MAX_SPANS, POLISH_SAMPLES_PER_SPAN samples each; x by least squares."""
        sh = self.shape
        n = min(POLISH_REFINE * (len(np.unique(sh.knots)) - 1), POLISH_MAX_SPANS)
        inner = np.linspace(0.0, 1.0, n + 1)
        fine = _PieceProblem(self.table, self.s0, self.s1, self.limits, self.T, self.all_joins, 0,
                             max(sh.M, POLISH_SAMPLES_PER_SPAN * (len(inner) - 1)), self.cap_grid, self.cap_vals,
                             inner=inner)
        v = BSpline(sh.knots, sh.full(x[None, :])[0], sh.degree)(fine.shape.tau)
        return fine, fine.shape.fit(fine.shape.tau, v)

    def start(self, x0, margin):
        """The fitted seed stretched to meet every limit (or None)."""
        lam0 = self.objective(x0[None, :], margin)[0]
        return x0 / lam0 if np.isfinite(lam0) else None


class _SubPiece:
    """The part of a piece between two of its G1 joins (or a join and a rest end), with its end
    feeds fixed: 0 at a rest end, JOIN_FEED_FRACTION of `_join_feed` at a join, with s̈ = 0 at
    both ends (and s⃛ = 0 at a join), so sub-pieces chain with ṡ and s̈ continuous.  The feed
    ṡ(τ) is a quadratic B-spline over normalised time τ ∈ [0, 1] in mm/s; the duration follows
    from the arc length, d = L/∫₀¹ṡ dτ (then s̈ = ṡ′/d, s⃛ = ṡ″/d²).  Cut this way each swarm shapes
    one feed dip only, and a join's dip needs no knots of its own."""

    def __init__(self, table, a, b, va, vb, ends, limits, T, K, M, cap_grid, cap_vals):
        self.table, self.a, self.b, self.L, self.va, self.vb = table, a, b, b - a, va, vb
        self.ends = ends                        # [(end index 0 | -1, Δq″, one-sided d1, d2, d3)]
        self.limits, self.lim, self.T, self.spans = limits, limits.joint, T, K - 2
        # at a join end three equal control points: s̈ = s⃛ = 0 over a short first (last) span,
        # so the join's jerk is its T-reading alone; K − 4 free coefficients either way
        a0, a1 = (FLAT_END_SPAN if va > 0 else 0.0), (1 - FLAT_END_SPAN if vb > 0 else 1.0)
        inner = np.concatenate([[0.0] if va > 0 else [], np.linspace(a0, a1, K - 1),
                                [1.0] if vb > 0 else []])
        self.pin0, self.pin1 = (3 if va > 0 else 2), (3 if vb > 0 else 2)
        K = len(inner) + 1
        self.knots = np.concatenate([[0.0, 0.0], inner, [1.0, 1.0]])
        self.K = K
        self.tau = np.linspace(0, 1, M)
        eye = np.eye(K)
        basis = [BSpline(self.knots, eye[k], DEGREE) for k in range(K)]
        self.B = np.stack([bs(self.tau) for bs in basis], 1)
        self.B1 = np.stack([bs.derivative(1)(self.tau) for bs in basis], 1)
        self.B2 = np.stack([bs.derivative(2)(self.tau) for bs in basis], 1)
        self.I1 = np.array([bs.antiderivative(1)(1.0) - bs.antiderivative(1)(0.0) for bs in basis])
        self.I = np.stack([bs.antiderivative(1)(self.tau) - bs.antiderivative(1)(0.0) for bs in basis], 1)
        self.free = np.arange(self.pin0, K - self.pin1)
        self.cap_grid, self.cap_vals = cap_grid, cap_vals

    def full(self, X):
        C = np.empty((X.shape[0], self.K))
        C[:, :self.pin0], C[:, -self.pin1:] = self.va, self.vb
        C[:, self.free] = np.maximum(X, 1e-6)
        return C

    def duration(self, X):
        return self.L / (self.full(X) @ self.I1)

    def needs(self, X, margin, each=False):
        """(duration, (P, M + ends) limit ratio of each sample and join end, as a time stretch
        would read it) per particle (``each``: see local_need)."""
        C = self.full(X)
        d = self.duration(X)[:, None]
        s = np.clip(self.a + d * (C @ self.I.T), self.a + 1e-9, self.b - 1e-9)
        v, acc, jr = C @ self.B.T, (C @ self.B1.T) / d, (C @ self.B2.T) / d ** 2
        m = 1 - margin
        cols = [local_need(self.table, s, v, acc, jr, self.lim, m, self.cap_grid, self.cap_vals, each)]
        for i, dq2, e1, e2, e3 in self.ends:
            # the join as `optimal` bounds it, on this side: T-reading + continuous jerk
            vj, aj, jj = v[:, i], acc[:, i], jr[:, i]
            read = JUMP_READ_FACTOR * dq2[None, :] * vj[:, None] ** 2 / self.T
            cont = np.abs(e3 * vj[:, None] ** 3 + 3 * e2 * (vj * aj)[:, None] + e1 * jj[:, None])
            ratio = (read + cont) / (self.lim.j * m)
            cols.append(ratio if each else ratio.max(axis=1)[:, None])
        return d[:, 0], np.concatenate(cols, axis=1)

    def ratio(self, X, margin):
        """(duration, worst limit ratio as a time stretch would read it) per particle."""
        d, N = self.needs(X, margin)
        return d, N.max(axis=1)

    def objective(self, X, margin):
        d, need = self.ratio(X, margin)
        return np.where(np.isfinite(need), d * np.maximum(1.0, need) ** PENALTY_POWER, np.inf)

    def fit(self, prof):
        """Free coefficients of the profile's feed over this sub-piece, in its own time, with
        the fixed ends."""
        i = np.nonzero((prof.s >= self.a) & (prof.s <= self.b))[0]
        if len(i) < 4:
            return np.full(len(self.free), max(self.va, self.vb, 1e-3))
        tt = (prof.t[i] - prof.t[i[0]]) / max(prof.t[i[-1]] - prof.t[i[0]], 1e-12)
        return self.fit_feed(tt, prof.sd[i])

    def fit_feed(self, tt, v):
        """Least-squares free coefficients of a feed v sampled at normalised times tt."""
        eye = np.eye(self.K)
        B = np.stack([BSpline(self.knots, eye[k], DEGREE)(tt) for k in range(self.K)], 1)
        rhs = v - B[:, :self.pin0].sum(1) * self.va - B[:, -self.pin1:].sum(1) * self.vb
        x, *_ = np.linalg.lstsq(B[:, self.free], rhs, rcond=None)
        return np.maximum(x, 1e-3)

    def refined(self, x):
        """(finer sub-piece, x on it) for the polish: each span split in POLISH_REFINE, so the
        old knots are a subset and the feed is the same curve (knot insertion, done here by
        least squares on the finer samples)."""
        n = self.spans * POLISH_REFINE
        fine = _SubPiece(self.table, self.a, self.b, self.va, self.vb, self.ends, self.limits, self.T,
                         n + 2, max(len(self.tau), POLISH_SAMPLES_PER_SPAN * n), self.cap_grid,
                         self.cap_vals)
        v = BSpline(self.knots, self.full(x[None, :])[0], DEGREE)(fine.tau)
        return fine, fine.fit_feed(fine.tau, v)

    def start(self, x0, margin):
        """The fitted seed, its feed lowered until it meets every limit (or None)."""
        for _ in range(60):
            if self.ratio(x0[None, :], margin)[1][0] <= 1.0:
                return x0
            x0 = 0.9 * x0
        return None


def polish(pr, x, margin, iterations=None):
    """Sequential linear programming from the swarm's best x on one (sub-)piece: (x, objective,
    steps taken).  Each step linearises the stretch N(x) of every joint's v, a, j and the feed at
    every sample (forward differences: n + 1 particles evaluated at once) and solves an LP in a
    box trust region —
    whole piece: min t s.t. Nᵢ + ∇Nᵢ·δ ≤ t (its time is max N, a minimax);
    sub-piece:   min ∇d·δ + w·σ s.t. Nᵢ + ∇Nᵢ·δ ≤ 1 + σ, σ ≥ 0 (d its duration; σ an elastic
    slack for a start that breaks a limit).  Only the rows above POLISH_ACTIVE × the worst enter
    the LP, at most POLISH_ROWS_PER_COEFF per coefficient.  A step is kept if it lowers the
    swarm's own objective (so the polish can only improve on the swarm); the box then doubles if
    the LP predicted at least half the gain, and shrinks ×0.4 after a step that did not help.
    Stops when five steps gained less than 1e-5 relative."""
    from scipy.optimize import linprog
    iterations = POLISH_ITERATIONS if iterations is None else iterations
    sub = isinstance(pr, _SubPiece)
    x = np.asarray(x, float)
    n = len(x)
    f = float(pr.objective(x[None, :], margin)[0])
    if not math.isfinite(f):
        return x, f, 0
    rho, seen = 0.05 * x.max(), [f]
    for _ in range(iterations):
        if len(seen) > 5 and seen[-6] - f < 1e-5 * f or rho < 1e-9 * x.max():
            break
        h = 1e-5 * x.max()
        Xs = np.vstack([x, x + h * np.eye(n)])
        if sub:
            d, N = pr.needs(Xs, margin, each=True)
        else:
            N, _ = pr.needs(Xs, margin, each=True)
        G = (N[1:] - N[0]) / h                                   # (n, rows)
        act = N[0] >= POLISH_ACTIVE * N[0].max()
        if act.sum() > POLISH_ROWS_PER_COEFF * n:                # the LP's cost grows with its rows
            act = N[0] >= np.partition(N[0], -POLISH_ROWS_PER_COEFF * n)[-POLISH_ROWS_PER_COEFF * n]
        box = [(max(-rho, 1e-6 - xi), rho) for xi in x]
        A = np.hstack([G[:, act].T, -np.ones((int(act.sum()), 1))])
        if sub:
            c = np.concatenate([(d[1:] - d[0]) / h, [100.0 * d[0] / rho]])
            res = linprog(c, A_ub=A, b_ub=1.0 - N[0, act], bounds=box + [(0.0, None)], method="highs")
        else:
            c = np.zeros(n + 1)
            c[-1] = 1.0
            res = linprog(c, A_ub=A, b_ub=-N[0, act], bounds=box + [(None, None)], method="highs")
        xn = x + res.x[:n] if res.status == 0 else x
        fn = float(pr.objective(xn[None, :], margin)[0]) if res.status == 0 else math.inf
        if fn < f:
            pred = (d[0] + c[:n] @ res.x[:n]) if sub else res.x[-1]     # the LP's own forecast
            good = (f - fn) >= 0.5 * (f - pred)
            x, f, rho = xn, fn, min((2.0 if good else 1.0) * rho, 0.3 * xn.max())
        else:
            rho *= 0.4
        seen.append(f)
    return x, f, len(seen) - 1


def _join_feed(table, sj, dq2, limits, margin, T, cap):
    """The largest feed at which a join passed with s̈ = s⃛ = 0 meets every limit: its T-reading
    of the q″ jump within the jerk limit, and on either side the joint velocity, the centripetal
    joint acceleration q″ṡ², the jerk q‴ṡ³ and the feed cap (kossel's bird: F_max rules)."""
    m, lim = 1 - margin, limits.joint
    d1, d2, d3 = table.joints(np.array([sj - 1e-9, sj + 1e-9]))
    tiny = 1e-300
    return float(min(math.sqrt(lim.j * m * T / (JUMP_READ_FACTOR * max(float(dq2.max()), tiny))),
                     lim.v * m / max(float(np.abs(d1).max()), tiny),
                     math.sqrt(lim.a * m / max(float(np.abs(d2).max()), tiny)),
                     math.cbrt(lim.j * m / max(float(np.abs(d3).max()), tiny)),
                     m * float(np.interp(sj, table.s, cap))))


def join_stretch(read, cont, Jm):
    """Smallest λ ≥ 0 with read/λ² + cont/λ³ ≤ Jm (elementwise): a G1 join's T-reading of the
    jump of q″ scales with ṡ², so as 1/λ², the continuous jerk as 1/λ³.  λ is the positive root
    of Jm·λ³ − read·λ − cont, found by Newton from the upper bound √(read/Jm) + ∛(cont/Jm)
    (the cubic is convex and increasing beyond its root, so the iterates fall monotonically)."""
    x = np.sqrt(read / Jm) + np.cbrt(cont / Jm)
    for _ in range(8):
        x = x - (Jm * x ** 3 - read * x - cont) / np.maximum(3 * Jm * x ** 2 - read, 1e-300)
    return x


def _seed_window(prof, s0, s1):
    """(τ, ṡ, s⃛, duration, switch τ) of a profile on piece [s0, s1], τ normalised to [0, 1].

    The piece starts and ends at rest between two samples; with the seed's jerk switch times
    (scurve's info) its ends are exact, else the sample just outside is taken."""
    t = prof.t
    idx = np.nonzero((prof.s >= s0 - 1e-9) & (prof.s <= s1 + 1e-9))[0]
    i0, i1 = max(idx[0] - 1, 0), min(idx[-1] + 1, len(t) - 1)
    t0, t1 = t[i0], t[i1]
    sw = np.asarray(prof.info.get("jerk_switch_times_s", []), float)
    rest = np.asarray(prof.info.get("rest_times_s", []), float)
    if len(sw) and len(rest):
        # the rest moments (path start, corners, end) nearest to where s crosses s0 and s1
        t0 = rest[np.argmin(np.abs(rest - np.interp(s0, prof.s, t)))]
        t1 = rest[np.argmin(np.abs(rest - np.interp(s1, prof.s, t)))]
    else:
        sw = np.zeros(0)
    D = t1 - t0
    inside = (t >= t0) & (t <= t1)
    tau = np.concatenate([[0.0], (t[inside] - t0) / D, [1.0]])
    vv = np.concatenate([[0.0], prof.sd[inside], [0.0]])
    jj = np.concatenate([[0.0], prof.sddd[inside], [0.0]])
    knots = None
    if len(sw):
        # switch times closer than ~2 servo periods (a jerk phase the s-curve's bisection left
        # almost empty) become one knot: a knot span holding no seed sample leaves the
        # least-squares fit undetermined there, and its jerk exploded (×2000 on bird)
        kept = []
        for ts in sw[(sw > t0 + 1e-9) & (sw < t1 - 1e-9)]:
            if not kept or ts - kept[-1] >= MIN_KNOT_GAP_T * prof.T:
                kept.append(ts)
        knots = (np.array(kept) - t0) / D
    return tau, vv, jj, D, knots


def knot_density(tau, jerk):
    """Half the knots uniform in time, half where the seed's jerk is busy (its transitions:
    the feed dips at the FLF minima and G1 joins need the resolution)."""
    aj = np.abs(jerk)
    w = np.convolve(aj, np.ones(9) / 9, mode="same")
    area = np.trapezoid(w, tau) if hasattr(np, "trapezoid") else np.trapz(w, tau)
    return tau, 1.0 + (w / area if area > 0 else 0.0)


def _stretch_at_T(pieces, groups, T, path, machine, limits, info):
    """(profile, its metrics) of the pieces sampled at T, each group (a rest-to-rest piece)
    stretched, up to 8 times, by the worst need of the samples whose time falls in it; profile
    None if still infeasible.  Mutates the pieces' λ."""
    from planners.verify import command_metrics, stretch_need
    for _ in range(8):
        prof = _sample(pieces, T, path, info)
        r = command_metrics(machine, path.point(prof.s), T, prof.s)
        if r["feasible"] and r["cartesian_peak_ratio"]["feed"] <= 1 + 1e-6:
            return prof, r
        need = stretch_need(machine.ik(path.point(prof.s)), prof.s, T, limits)
        starts = np.concatenate([[0.0], np.cumsum([p["lam"] for p in pieces])])
        k = np.clip(np.searchsorted(starts, prof.t, side="right") - 1, 0, len(pieces) - 1)
        grp = np.array([p["group"] for p in pieces])[k]
        for g in range(groups):
            # a whole rest-to-rest piece is stretched (its sub-pieces' join feeds scale with it),
            # by the worst need of the samples whose time falls in it
            near = grp == g
            worst = float(need[near].max()) if near.any() else 0.0
            if worst > 1.0:
                for p in pieces:
                    if p["group"] == g:
                        p["lam"] *= worst * (1 + 1e-4)
    return None, r


def _sample(pieces, T, path, info) -> Profile:
    """Evaluate each piece's B-spline exactly at multiples of T and join them."""
    starts = np.concatenate([[0.0], np.cumsum([p["lam"] for p in pieces])])
    total = float(starts[-1])
    N = max(1, int(math.ceil(total / T - 1e-9)))
    t = np.arange(N + 1) * T
    s = np.empty(N + 1)
    sd, sdd, sddd = np.zeros(N + 1), np.zeros(N + 1), np.zeros(N + 1)
    k = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(pieces) - 1)
    for i, p in enumerate(pieces):
        mk = k == i
        if not mk.any():
            continue
        lam, C, knots, s0, L = p["lam"], p["C"], p["knots"], p["s0"], p["L"]
        spl = BSpline(knots, C, p["degree"])
        anti = spl.antiderivative(1)
        area = anti(1.0) - anti(0.0)
        tau = np.clip((t[mk] - starts[i]) / lam, 0.0, 1.0)
        kk = L / area
        s[mk] = s0 + kk * (anti(tau) - anti(0.0))
        sd[mk] = kk * spl(tau) / lam
        sdd[mk] = kk * spl.derivative(1)(tau) / lam ** 2
        sddd[mk] = kk * spl.derivative(2)(tau) / lam ** 3
    L = path.length
    s = np.minimum(np.maximum.accumulate(s), L)
    s[0], s[-1] = 0.0, L
    sd[-1] = sdd[-1] = sddd[-1] = 0.0
    return Profile("pso", T, s, sd, sdd, sddd, path, info=dict(info, continuous_time_s=total))


def plan(path, machine, limits=None, *, seed: int = 0, particles: int = 40, iterations: int = 20,
         control_points: int = 60, samples: int = 400, margin: float = 0.005,
         time_budget_s: float | None = None, seed_profile=None, target_time_s: float | None = None,
         exact_knots: bool = True, extra_knots: float = 0.5, spread: float = 0.05,
         polish_steps: int | None = None) -> Profile:
    """PSO-optimised feed.  ``control_points``: total over the pieces (≥ 8 each, shared in
    proportion to the seed's time on each); ``polish_steps``: SLP steps per piece after the
    swarm (POLISH_ITERATIONS if None, 0: none); ``target_time_s``: record when the best total
    (swarm, then polished) first reaches it (``info['time_to_target_s']``), for the benchmark."""
    from planners.verify import command_metrics, stretch_need
    from .scurve import plan_joint

    t0 = time.perf_counter()
    polish_steps = POLISH_ITERATIONS if polish_steps is None else polish_steps
    limits = machine.limits if limits is None else limits
    check_limits(limits, "pso")
    check_path(path, "pso")
    if particles < 2 or iterations < 0:
        raise PlanningError(f"pso: need ≥ 2 particles and ≥ 0 iterations (got {particles}, {iterations})")
    T = machine.servo_period_s
    rng = np.random.default_rng(seed)
    table = PathTable(path, machine)
    cap = table_feed_cap(path, table, limits, T)
    joins = join_jumps(path, table, machine)
    seed_prof = plan_joint(path, machine, limits) if seed_profile is None else seed_profile
    pcs = rest_pieces(path)
    # control points in proportion to the seed's time on each piece
    tp = np.array([max(np.count_nonzero((seed_prof.s > a) & (seed_prof.s < b)), 1) for a, b in pcs], float)
    Ks = np.maximum(8, np.round(control_points * tp / tp.sum()).astype(int))

    # each piece is searched whole (one time stretch, knots at the seed's switches) and, if it
    # has G1 joins, also cut at them (_SubPiece); the better of the two is kept per piece:
    # cut wins on keops' bird (swarm alone: 1.878 s against 2.132 s), whole on kossel's
    # bird_kossel, whose seconds-long sub-pieces 10 uniform control points cannot shape
    probs, X0, tags = [], [], []                 # tags: (piece, "whole" | "cut")
    seed_pieces = []                             # the seed's fit per piece, in _sample's form
    fallback = []                                # pieces over the size bound (BASIS_MAX_ELEMENTS)
    for g, ((s0, s1), K) in enumerate(zip(pcs, Ks)):
        tau, vv, jj, D, knots = _seed_window(seed_prof, s0, s1)
        # with the seed's jerk switch times as knots a quadratic B-spline holds the s-curve
        # exactly: the swarm starts from the seed itself
        # samples at least every 8 servo periods of the seed's time on the piece (a 17 s piece
        # of kossel's test_part would get one per 42 ms, coarser than its feed dips)
        M = max(samples, int(math.ceil(D / (8 * T))))
        exact = knots is not None and exact_knots
        over = exact and (M + 2 * len(knots) + len(tau)) * (len(knots) + K) > BASIS_MAX_ELEMENTS
        pr = _PieceProblem(table, s0, s1, limits, T, joins, int(K * extra_knots) if exact else int(K), M,
                           table.s, cap, knot_density(tau, jj), inner=knots if exact else None,
                           sparse=over)
        if over:
            fallback.append({"piece": g, "s_mm": [round(float(s0), 6), round(float(s1), 6)],
                             "seed_knots": len(knots), "control_points": int(pr.shape.K),
                             "samples": int(len(pr.shape.tau)), "polish": "skipped"})
        probs.append(pr)
        X0.append(pr.shape.fit(tau, vv))
        tags.append((g, "whole"))
        if seed_pieces is not None and exact:
            seed_pieces.append({"lam": D, "lam0": D, "C": pr.shape.full(X0[-1][None, :])[0],
                                "knots": pr.shape.knots, "degree": pr.shape.degree, "s0": s0, "L": s1 - s0,
                                "group": g})
        else:
            seed_pieces = None                   # not every piece has the seed's switch times
        inside = [(sj, d) for sj, d in joins if s0 + 1e-6 < sj < s1 - 1e-6]
        if not inside or len(inside) > MAX_JOINS_CUT:
            continue
        bnd = [s0] + [sj for sj, _ in inside] + [s1]
        vs = [0.0] + [JOIN_FEED_FRACTION * _join_feed(table, sj, d, limits, margin, T, cap)
                      for sj, d in inside] + [0.0]
        for k in range(len(bnd) - 1):
            ends = []
            if k > 0:
                e = table.joints(np.array([bnd[k] + 1e-9]))
                ends.append((0, inside[k - 1][1], e[0][0], e[1][0], e[2][0]))
            if k < len(bnd) - 2:
                e = table.joints(np.array([bnd[k + 1] - 1e-9]))
                ends.append((-1, inside[k][1], e[0][0], e[1][0], e[2][0]))
            tk = np.interp([bnd[k], bnd[k + 1]], seed_prof.s, seed_prof.t)
            M = max(SUBPIECE_SAMPLES, int(math.ceil((tk[1] - tk[0]) / (8 * T))))
            pr = _SubPiece(table, bnd[k], bnd[k + 1], vs[k], vs[k + 1], ends, limits, T,
                           SUBPIECE_CONTROL_POINTS, M, table.s, cap)
            probs.append(pr)
            X0.append(pr.fit(seed_prof))
            tags.append((g, "cut"))

    # one swarm per (sub-)piece, all advanced together so the total best is known at every iteration
    w, c1, c2 = 0.7298, 1.49618, 1.49618        # Clerc–Kennedy constriction coefficients
    swarm = []
    for pr, x0 in zip(probs, X0):
        x0 = pr.start(x0, margin)                  # the seed, made to meet every limit
        if x0 is None:
            swarm.append(None)
            continue
        n = len(x0)
        X = x0[None, :] * (1 + spread * rng.standard_normal((particles, n)))
        X[0] = x0
        X = np.maximum(X, 0.0)
        span = np.maximum(x0, 1e-3 * x0.max())
        Vel = 0.05 * span[None, :] * rng.standard_normal((particles, n))
        f = pr.objective(X, margin)
        best = int(np.argmin(f))
        swarm.append({"X": X, "V": Vel, "P": X.copy(), "fP": f.copy(), "g": X[best].copy(),
                      "fg": float(f[best]), "vmax": 0.2 * span})

    def best_options():
        """{piece: (option, its time)}: per piece the option with the smaller best total."""
        tot = {}
        for (g, opt), sw in zip(tags, swarm):
            tot[(g, opt)] = tot.get((g, opt), 0.0) + (sw["fg"] if sw is not None else math.inf)
        out = {}
        for (g, opt), v in tot.items():
            if g not in out or v < out[g][1]:
                out[g] = (opt, v)
        return out

    chosen = best_options()
    bad = [g for g, (_, v) in chosen.items() if not math.isfinite(v)]
    if bad:
        raise PlanningError(f"pso: no feasible particle on piece(s) {bad} (s = "
                            f"{', '.join(f'{pcs[i][0]:.6g}…{pcs[i][1]:.6g}' for i in bad)} mm)")
    history = [(time.perf_counter() - t0, sum(v for _, v in chosen.values()))]
    time_to_target = history[0][0] if target_time_s and history[0][1] <= target_time_s else None
    stopped_by = "iterations"
    live = [(pr, sw) for pr, sw in zip(probs, swarm) if sw is not None]
    for it in range(iterations):
        if time_budget_s is not None and time.perf_counter() - t0 > time_budget_s:
            stopped_by = "time budget"
            break
        for pr, sw in live:
            X, V = sw["X"], sw["V"]
            r1, r2 = rng.random(X.shape), rng.random(X.shape)
            V = w * V + c1 * r1 * (sw["P"] - X) + c2 * r2 * (sw["g"][None, :] - X)
            V = np.clip(V, -sw["vmax"], sw["vmax"])
            X = np.maximum(X + V, 0.0)
            f = pr.objective(X, margin)
            imp = f < sw["fP"]
            sw["P"][imp], sw["fP"][imp] = X[imp], f[imp]
            b = int(np.argmin(sw["fP"]))
            if sw["fP"][b] < sw["fg"]:
                sw["g"], sw["fg"] = sw["P"][b].copy(), float(sw["fP"][b])
            sw["X"], sw["V"] = X, V
        total = sum(v for _, v in best_options().values())
        history.append((time.perf_counter() - t0, total))
        if target_time_s and time_to_target is None and total <= target_time_s:
            time_to_target = history[-1][0]

    swarm_total = history[-1][1]
    polished = []
    if polish_steps > 0:
        # the swarm finds the shape (which option, which basin); a few SLP steps on a finer
        # spline converge it (bird: 1.87 s after 800 iterations of the swarm alone, 1.7805 s
        # after 20 and the polish)
        chosen, total = best_options(), swarm_total
        for k, (pr, sw, (g, opt)) in enumerate(zip(probs, swarm, tags)):
            if sw is None or chosen[g][0] != opt:
                continue
            if isinstance(pr, _PieceProblem) and pr.shape.sparse:
                # over the size bound: the polish's forward differences evaluate K + 1 particles
                # at every sample (K ~ the seed's jerk phases), and its finer uniform spline of
                # at most POLISH_MAX_SPANS spans could not hold the seed; the swarm's best stays
                continue
            fine, x = pr.refined(sw["g"])
            x, f, its = polish(fine, x, margin, polish_steps)
            polished.append([g, round(sw["fg"], 6), round(f, 6), its])
            if f < sw["fg"]:
                probs[k], sw["g"], sw["fg"] = fine, x, f
            # the best total after each (sub-)piece's polish: when it first reaches the target
            # is known to the piece, not only after the last one
            total = sum(v for _, v in best_options().values())
            if target_time_s and time_to_target is None and total <= target_time_s:
                time_to_target = time.perf_counter() - t0
        history.append((time.perf_counter() - t0, total))

    chosen = best_options()
    pieces = []
    for pr, sw, (g, opt) in zip(probs, swarm, tags):
        if chosen[g][0] != opt:
            continue
        if isinstance(pr, _SubPiece):
            lam = float(pr.duration(sw["g"][None, :])[0])
            pieces.append({"lam": lam, "C": pr.full(sw["g"][None, :])[0], "knots": pr.knots,
                           "degree": DEGREE, "s0": pr.a, "L": pr.L, "group": g})
        else:
            pieces.append({"lam": sw["fg"], "C": pr.shape.full(sw["g"][None, :])[0],
                           "knots": pr.shape.knots, "degree": pr.shape.degree, "s0": pr.s0,
                           "L": pr.L, "group": g})
        pieces[-1]["lam0"] = pieces[-1]["lam"]
    info = {"seed": seed, "particles": particles, "iterations_run": len(history) - 1,
            "stopped_by": stopped_by,
            "control_points": [int(pr.K if isinstance(pr, _SubPiece) else pr.shape.K)
                               for pr, (g, opt) in zip(probs, tags) if chosen[g][0] == opt],
            "searched_as": [chosen[g][0] for g in range(len(pcs))],
            "seed_time_s": float(seed_prof.execution_time_s),
            "history": [[round(history[i][0], 4), float(history[i][1])]        # ~50 and the last
                        for i in sorted(set(range(0, len(history), max(1, len(history) // 50)))
                                        | {len(history) - 1})],
            "swarm_time_s": float(swarm_total), "polish": polished,
            **({"fallback": {"reason": f"piece over the size bound of {BASIS_MAX_ELEMENTS} basis elements: "
                                       "sparse basis at the seed's switch times, no polish",
                             "pieces": fallback}} if fallback else {}),
            "time_to_target_s": time_to_target}
    # check at T with the independent metrics; stretch the pieces whose samples at T read
    # above a limit (the swarm saw only its own samples) by just that excess
    prof, r = _stretch_at_T(pieces, len(pcs), T, path, machine, limits, info)
    if prof is None:
        raise PlanningError(f"pso: best particle breaks a joint limit at T: {r['joint_peak_ratio']}")
    first = {}
    for p in pieces:
        first.setdefault(p["group"], p)
    prof.info["t_check_stretch"] = [round(p["lam"] / p["lam0"], 6) for p in first.values()]
    prof.info["returned"] = "swarm best"
    # the best feasible profile known: the swarm's, or its seed where the swarm did not beat it
    # (the swarm's constraint set carries a margin the seed's own check does not: on paths
    # where the feed limit rules, as kossel's, the stretched seed ends a few ms slower)
    if seed_prof.execution_time_s < prof.execution_time_s:
        rs = command_metrics(machine, path.point(seed_prof.s), T, seed_prof.s)
        if rs["feasible"] and rs["cartesian_peak_ratio"]["feed"] <= 1 + 1e-6:
            prof = Profile("pso", T, seed_prof.s, seed_prof.sd, seed_prof.sdd, seed_prof.sddd, path,
                           info=dict(prof.info, continuous_time_s=seed_prof.info.get("continuous_time_s"),
                                     returned=f"seed ({seed_prof.planner}): the swarm's best was "
                                              f"{prof.execution_time_s:.6g} s"))
        elif seed_pieces:
            # the seed breaks a limit at T (on CAM-like kossel programs scurve_joint reads up to
            # 1.10 × the jerk limit), while the swarm's start, its fit stretched to the swarm's
            # stricter sample model (the continuous jerk on 0.04 mm blend arcs, the joins' T
            # reading, the margin), can be slower still: the seed's fit stretched at T by just
            # its excess per piece is feasible too.  Per rest-to-rest piece the shorter of the
            # two is kept (the fit misses the seed where switch times closer than
            # MIN_KNOT_GAP_T share a knot, and reads higher there), checked at T once more
            sp_prof, _ = _stretch_at_T(seed_pieces, len(pcs), T, path, machine, limits, info)
            if sp_prof is not None:
                dur = {}
                for name, pp in (("swarm", pieces), ("seed", seed_pieces)):
                    for q in pp:
                        dur[name, q["group"]] = dur.get((name, q["group"]), 0.0) + q["lam"]
                pick = ["seed" if dur["seed", g] < dur["swarm", g] else "swarm" for g in range(len(pcs))]
                mixed = [dict(q) for q in pieces if pick[q["group"]] == "swarm"] + \
                        [dict(q) for q in seed_pieces if pick[q["group"]] == "seed"]
                mixed.sort(key=lambda q: q["s0"])
                mx_prof, _ = _stretch_at_T(mixed, len(pcs), T, path, machine, limits, info)
                if mx_prof is not None and mx_prof.execution_time_s < prof.execution_time_s:
                    first = {}
                    for q in mixed:
                        first.setdefault(q["group"], q)
                    mx_prof.info.update(
                        t_check_stretch=[round(q["lam"] / q["lam0"], 6) for q in first.values()],
                        pieces_from=pick,
                        returned=f"per piece the swarm's best or the seed ({seed_prof.planner}) fitted "
                                 f"on its switch times, each stretched at T (the seed read "
                                 f"{max(rs['joint_peak_ratio'].values()):.4g} × a joint limit): "
                                 f"the swarm's best alone was {prof.execution_time_s:.6g} s")
                    prof = mx_prof
    prof.planning_time_s = time.perf_counter() - t0
    return prof
