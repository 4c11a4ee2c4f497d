"""G1 joins: where they fall among a particle's samples, the time stretch their jerk asks for,
and the feed a cut piece passes them at."""
from __future__ import annotations

import math

import numpy as np

from ..constraints import JUMP_READ_FACTOR


def first_at_or_after(s, points):
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


def join_stretch(read, cont, Jm):
    """Smallest λ ≥ 0 with read/λ² + cont/λ³ ≤ Jm (elementwise): a G1 join's T-reading of the
    jump of q″ scales with ṡ², so as 1/λ², the continuous jerk as 1/λ³.  λ is the positive root
    of Jm·λ³ − read·λ − cont, found by Newton from the upper bound √(read/Jm) + ∛(cont/Jm)
    (the cubic is convex and increasing beyond its root, so the iterates fall monotonically)."""
    x = np.sqrt(read / Jm) + np.cbrt(cont / Jm)
    for _ in range(8):
        x = x - (Jm * x ** 3 - read * x - cont) / np.maximum(3 * Jm * x ** 2 - read, 1e-300)
    return x


def join_feed(table, sj, dq2, limits, margin, T, cap):
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

