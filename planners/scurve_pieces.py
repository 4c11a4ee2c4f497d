"""The 1-D pieces of the s-curve (planners.scurve): how far a jerk-limited feed change needs,
the largest feed reachable in a length, the sample times of a profile's phases, and one ruckig
profile between two critical points (`Segment`)."""
from __future__ import annotations

import math

import numpy as np
from ruckig import Result


def min_distance(v0, v1, A, J):
    """Shortest arc length in which the feed can change from v0 to v1 (a = 0 at both ends)."""
    dv = abs(v1 - v0)
    if dv <= A * A / J:
        return (v0 + v1) * math.sqrt(dv / J)
    return 0.5 * (v0 + v1) * (dv / A + A / J)


def reachable(v0, L, A, J, vmax):
    """Largest v1 ≤ vmax that can be reached from v0 (either way) within L."""
    if min_distance(v0, vmax, A, J) <= L:
        return vmax
    lo, hi = v0, vmax
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if min_distance(v0, mid, A, J) <= L:
            lo = mid
        else:
            hi = mid
    return lo


def phase_samples(tcum, T):
    """np.linspace(a, b, min(4000, max(16, ⌈(b − a)/T⌉))) of every phase [a, b] with b > a,
    concatenated: the same values as numpy's linspace (k·step + a, the end set to b; k/div·Δ
    + a where the step underflows), without a Python call per phase."""
    a, b = tcum[:-1], tcum[1:]
    keep = b > a
    a, b = a[keep], b[keep]
    n = np.minimum(4000, np.maximum(16, np.ceil((b - a) / T))).astype(np.int64)
    first = np.cumsum(n) - n
    ph = np.repeat(np.arange(len(n)), n)
    k = (np.arange(int(n.sum())) - first[ph]).astype(float)
    delta, div = b - a, (n - 1).astype(float)
    step = delta / div
    y = np.where(step[ph] == 0, k / div[ph] * delta[ph], k * step[ph]) + a[ph]
    y[first + n - 1] = b
    return y


class Segment:
    """One ruckig profile between two critical points, as arrays of its seven phases."""

    __slots__ = ("s0", "L", "v0", "v1", "A", "J", "vpeak", "tcum", "j", "a", "v", "p", "duration")

    def __init__(self, s0, L, v0, v1, A, J, vpeak):
        self.s0, self.L, self.v0, self.v1, self.A, self.J, self.vpeak = s0, L, v0, v1, A, J, vpeak
        self.duration = None

    def compute(self, otg, inp, traj) -> bool:
        inp.current_position = [0.0]
        inp.current_velocity = [self.v0]
        inp.current_acceleration = [0.0]
        inp.target_position = [self.L]
        inp.target_velocity = [self.v1]
        inp.target_acceleration = [0.0]
        inp.min_velocity = [0.0]
        inp.max_acceleration = [self.A]
        inp.max_jerk = [self.J]
        # a segment that needs all its length to reach v1 = its peak (the consistency pass
        # allows it to within 1e-9 of L) has no profile in ruckig with the peak at exactly v1
        # 1e-9 above it has one, whose peak is v1
        for widen in (1.0, 1.0 + 1e-9):
            inp.max_velocity = [max(self.vpeak, self.v0, self.v1) * widen]
            try:
                res = otg.calculate(inp, traj)
            except Exception:  # ruckig.RuckigError: no profile for these inputs
                continue
            if res in (Result.Working, Result.Finished):
                break
        else:
            return False
        prof = traj.profiles[0][0]
        self.tcum = np.concatenate([[0.0], np.cumsum(prof.t)])
        self.j, self.a = np.array(prof.j), np.array(prof.a)
        self.v, self.p = np.array(prof.v), np.array(prof.p)
        self.duration = float(traj.duration)
        return True

    def state(self):
        """(A, J, vpeak and the fitted profile), for :meth:`restore`."""
        return (self.A, self.J, self.vpeak, self.tcum, self.j, self.a, self.v, self.p, self.duration)

    def restore(self, state):
        (self.A, self.J, self.vpeak, self.tcum, self.j, self.a, self.v, self.p, self.duration) = state

    def at(self, tt):
        """(p, v, a, j) at local times tt (clipped to the segment)."""
        # np.minimum/np.maximum: np.clip's Python wrapper cost more than the arithmetic here
        tt = np.minimum(np.maximum(np.asarray(tt, float), 0.0), self.duration)
        k = np.minimum(np.maximum(np.searchsorted(self.tcum, tt, side="right") - 1, 0), 6)
        dt = tt - self.tcum[k]
        j = self.j[k]
        a = self.a[k] + j * dt
        v = self.v[k] + self.a[k] * dt + j * dt * dt / 2
        p = self.p[k] + self.v[k] * dt + self.a[k] * dt * dt / 2 + j * dt ** 3 / 6
        return p, v, a, j
