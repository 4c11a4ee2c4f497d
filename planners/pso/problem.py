"""The two kinds of search problem behind one protocol: a whole rest-to-rest piece (one time
stretch, `PieceProblem`) and the part of a piece between two of its G1 joins (fixed end feeds,
`SubPiece`).  The swarm, the polish and plan() see only `Problem`."""
from __future__ import annotations

from typing import Protocol

import numpy as np
from scipy.interpolate import BSpline

from ..constraints import JUMP_READ_FACTOR
from .basis import Shape
from .join import first_at_or_after, join_stretch
from .result import SplinePiece
from .tuning import (DEGREE, FLAT_END_SPAN, PENALTY_POWER, POLISH_MAX_SPANS, POLISH_REFINE,
                     POLISH_SAMPLES_PER_SPAN)


class Problem(Protocol):
    """One (sub-)piece searched over the free coefficients X (P particles × n) of its feed."""

    K: int                  # control points
    polishable: bool        # False: the polish leaves the swarm's best as it is

    def needs(self, X, margin, each=False):
        """(N, extra): N (P, rows) the limit ratio of each sample (and join) as a time stretch
        reads it; extra what `lp` needs besides."""

    def objective(self, X, margin):
        """(P,) what the swarm minimises (its time, a violation penalised)."""

    def start(self, x0, margin):
        """The fitted seed x0 made to meet every limit, or None."""

    def refined(self, x):
        """(a finer problem, x on it) for the polish."""

    def lp(self, N, extra, act, h, rho):
        """The polish's LP at x from `needs` at x and at x + h·eᵢ (rows act): (cost c over
        (δ, slack), b_ub of A_ub = [∇N | −1], the slack's bounds, the LP's forecast of the
        objective from its solution)."""

    def piece(self, x, f, group):
        """The `SplinePiece` of coefficients x (objective f) in rest-to-rest piece ``group``."""


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


class PieceProblem:
    """A whole rest-to-rest piece: its feed shape (`Shape`) scaled in time to the smallest λ at
    which every limit holds; the objective is that λ, the piece's time."""

    def __init__(self, table, s0, s1, limits, T, joins, K, M, cap_grid, cap_vals, density=None,
                 inner=None, sparse=False):
        self.table, self.s0, self.s1, self.L = table, s0, s1, s1 - s0
        self.limits, self.lim, self.T, self.all_joins = limits, limits.joint, T, joins
        self.shape = Shape(K, M, density, inner=inner, sparse=sparse)
        self.joins = [(sj, d) for sj, d in joins if s0 + 1e-6 < sj < s1 - 1e-6]
        # one-sided joint derivatives at each join (q″ jumps there)
        self.join_derivs = [table.joints(np.array([sj - 1e-9, sj + 1e-9])) for sj, _ in self.joins]
        self.cap_grid, self.cap_vals = cap_grid, cap_vals
        self.K = self.shape.K
        # the polish's forward differences evaluate K + 1 particles at every sample (K ~ the
        # seed's jerk phases over the bound), and its finer uniform spline could not hold the seed
        self.polishable = not sparse

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
        first = first_at_or_after(s, [sj for sj, _ in self.joins])
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
        fine = PieceProblem(self.table, self.s0, self.s1, self.limits, self.T, self.all_joins, 0,
                             max(sh.M, POLISH_SAMPLES_PER_SPAN * (len(inner) - 1)), self.cap_grid, self.cap_vals,
                             inner=inner)
        v = BSpline(sh.knots, sh.full(x[None, :])[0], sh.degree)(fine.shape.tau)
        return fine, fine.shape.fit(fine.shape.tau, v)

    def start(self, x0, margin):
        """The fitted seed stretched to meet every limit (or None)."""
        lam0 = self.objective(x0[None, :], margin)[0]
        return x0 / lam0 if np.isfinite(lam0) else None

    def lp(self, N, extra, act, h, rho):
        """min t s.t. Nᵢ + ∇Nᵢ·δ ≤ t: the piece's time is max N, a minimax."""
        c = np.zeros(len(N))
        c[-1] = 1.0
        return c, -N[0, act], (None, None), lambda z: z[-1]

    def piece(self, x, f, group):
        return SplinePiece(f, self.shape.full(x[None, :])[0], self.shape.knots, self.shape.degree,
                           self.s0, self.L, group)


class SubPiece:
    """The part of a piece between two of its G1 joins (or a join and a rest end), with its end
    feeds fixed: 0 at a rest end, JOIN_FEED_FRACTION of `join_feed` at a join, with s̈ = 0 at
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
        self.polishable = True

    def full(self, X):
        C = np.empty((X.shape[0], self.K))
        C[:, :self.pin0], C[:, -self.pin1:] = self.va, self.vb
        C[:, self.free] = np.maximum(X, 1e-6)
        return C

    def duration(self, X):
        return self.L / (self.full(X) @ self.I1)

    def needs(self, X, margin, each=False):
        """((P, M + ends) limit ratio of each sample and join end, as a time stretch would read
        it, duration) per particle (``each``: see local_need)."""
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
        return np.concatenate(cols, axis=1), d[:, 0]

    def ratio(self, X, margin):
        """(duration, worst limit ratio as a time stretch would read it) per particle."""
        N, d = self.needs(X, margin)
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
        fine = SubPiece(self.table, self.a, self.b, self.va, self.vb, self.ends, self.limits, self.T,
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

    def lp(self, N, d, act, h, rho):
        """min ∇d·δ + w·σ s.t. Nᵢ + ∇Nᵢ·δ ≤ 1 + σ, σ ≥ 0 (d the duration; σ an elastic slack for
        a start that breaks a limit)."""
        n = len(N) - 1
        c = np.concatenate([(d[1:] - d[0]) / h, [100.0 * d[0] / rho]])
        return c, 1.0 - N[0, act], (0.0, None), lambda z: d[0] + c[:n] @ z[:n]

    def piece(self, x, f, group):
        return SplinePiece(float(self.duration(x[None, :])[0]), self.full(x[None, :])[0], self.knots,
                           DEGREE, self.a, self.L, group)

