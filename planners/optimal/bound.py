"""A lower bound on the minimum time of the continuous problem (`optimal`'s info["lower_bound_s"]).

The problem: rest to rest on each piece (exact-stop corners), for every s the joint limits
|q′ṡ| ≤ V, |q″ṡ² + q′s̈| ≤ A, the jerk ≤ J, and ṡ ≤ min(F_max, the programmed F, the chord cap).
Dropping constraints can only make the minimum smaller, so the minimum of what is left bounds
every feasible profile from below.  What is kept:

* the feed ceiling ṡ ≤ min(F_max, F) (planners.feed; the chord cap and the jerk are dropped);
* the velocity limit of the joint that moves fastest per mm, ṡ ≤ V / max_i |q′_i(s)|;
* the acceleration of that joint from and to rest: with a = ṡ², da/ds = 2s̈ and
  |q′_i| s̈ ≤ A + |q″_i| a for every joint i, so on an interval where max_i |q′_i| ≥ m₁ and
  max_i |q″_i| ≤ M₂, da/ds ≤ 2(A + M₂a)/m₁; by the comparison theorem a(s) stays below the
  solution of the equality, (a₀ + A/M₂)·exp(2M₂Δs/m₁) − A/M₂, forward from rest at the piece's
  start and backward from rest at its end.

Per station interval [s_k, s_k+1] of length h, the time is at least h / (the ceilings' largest
value there) and at least ∫ ds / √a under either growth (in closed form); T ≥ their sum.  The worst case uses q′, q″, q‴ from the
path's exact derivatives (constraints.joint_derivs: the path's P′, P″, P‴ through the IK) at
both ends and the midpoint: with M₃ = 2 × the largest |q‴| sampled there, M₂ = the largest |q″|
sampled + M₃h/4 and m₁ = the smallest max_i |q′_i| sampled − M₂h/4 (a function whose derivative
is ≤ D moves ≤ Dh/4 between samples h/2 apart).  This holds if |q‴| on the interval stays
below twice its largest sample: stations ≤ BOUND_GRID_MM apart and ≤ BOUND_RADII curvature
radii apart make an interval much shorter than the scale on which q‴ changes.  Where the
interval's m₁ is not positive the velocity and acceleration rows are left out (only the feed
ceiling bounds it).  Unlike the SOCP's station relaxation (the limits held at its stations
only, solved by linearisations: a bound of that transcription, which the converged optimum
can undercut), nothing here depends on a grid's luck: a finer grid only tightens it.
"""
from __future__ import annotations

import math

import numpy as np

from planners.constraints import PathTable, joint_derivs, rest_pieces
from planners.feed import feed_ceiling
from planners.optimal.topp3 import grid_of

# stations of the bound: ≤ BOUND_GRID_MM apart and ≤ BOUND_RADII curvature radii apart
BOUND_GRID_MM = 0.1
BOUND_RADII = 0.1
# the largest |q‴| on an interval is taken as this many times its largest sample there
Q3_SAFETY = 2.0


def _growth(a0, h, A, M2, m1):
    """a at the end of an interval of length h from a0 under da/ds = 2(A + M₂a)/m₁ (Python
    floats: the recursion is sequential, one interval at a time)."""
    if M2 <= 0:
        return a0 + 2 * A * h / m1
    e = 2 * M2 * h / m1
    return math.inf if e > 700 else (a0 + A / M2) * math.exp(e) - A / M2


def _time_under_growth(a0, h, A, M2, m1):
    """∫₀ʰ dx / √a(x) with a(x) the growth from a0 (_growth): in closed form, (m₁/A)(√a(h) − √a0)
    where M₂ = 0, else (2/(k√C))·(atan √(a(h)/C) − atan √(a0/C)) with C = A/M₂, k = 2M₂/m₁."""
    end = _growth(a0, h, A, M2, m1)
    if M2 <= 0:
        return m1 / A * (math.sqrt(end) - math.sqrt(a0))
    C, k = A / M2, 2 * M2 / m1
    top = math.pi / 2 if end == math.inf else math.atan(math.sqrt(end / C))
    return 2 / (k * math.sqrt(C)) * (top - math.atan(math.sqrt(a0 / C)))


def lower_bound(path, machine, limits) -> float:
    """A lower bound (s) on the execution time of any profile of ``path`` within ``limits``
    (module docstring)."""
    table = PathTable(path, machine)
    V, A = limits.joint.v, limits.joint.a
    total = 0.0
    for s0, s1 in rest_pieces(path):
        x = grid_of(path, table, [], s0, s1, BOUND_GRID_MM, BOUND_RADII)
        h = np.diff(x)
        mid = (x[:-1] + x[1:]) / 2
        pts = np.clip(np.concatenate([x, mid]), s0 + 1e-9, s1 - 1e-9)     # one-sided at the corners
        _, D1, D2, D3 = joint_derivs(machine, path, pts, fit_scale=True)
        n = len(x)
        g1, g2, g3 = (np.abs(D).max(axis=1) for D in (D1, D2, D3))

        def worst(g, fn):            # over the interval's two ends and its midpoint
            return fn(fn(g[:n - 1], g[1:n]), g[n:])
        M3 = Q3_SAFETY * worst(g3, np.maximum)
        M2 = worst(g2, np.maximum) + M3 * h / 4
        m1 = worst(g1, np.minimum) - M2 * h / 4
        feed = feed_ceiling(path, pts, limits.feed_max)
        cap2 = worst(np.asarray(feed, float), np.maximum) ** 2
        ok = m1 > 0
        vel2 = np.where(ok, (V / np.where(ok, m1, 1.0)) ** 2, np.inf)
        ceiling = np.minimum(cap2, vel2)
        hl, M2l, m1l, okl, cl = h.tolist(), M2.tolist(), m1.tolist(), ok.tolist(), ceiling.tolist()
        fwd = [0.0] * n                     # bounds of a at the stations, forward from rest
        for k in range(n - 1):
            grow = _growth(fwd[k], hl[k], A, M2l[k], m1l[k]) if okl[k] else math.inf
            fwd[k + 1] = min(grow, cl[k])
        back = 0.0                          # the bound of a backward from rest at the end
        for k in range(n - 2, -1, -1):
            hk = hl[k]
            # a below its ceiling and below the growth from either end: the time over the
            # interval is at least the time under each of them
            dt = hk / math.sqrt(cl[k])
            if okl[k]:
                dt = max(dt, _time_under_growth(fwd[k], hk, A, M2l[k], m1l[k]),
                         _time_under_growth(back, hk, A, M2l[k], m1l[k]))
                back = min(_growth(back, hk, A, M2l[k], m1l[k]), cl[k])
            else:
                back = cl[k]
            total += dt
    return total
