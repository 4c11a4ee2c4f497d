"""The 1-D pieces of the s-curve (planners.scurve.planner): how far a jerk-limited feed change needs,
the largest feed reachable in a length, and one ruckig profile between two critical points
(`Segment`)."""
from __future__ import annotations

import math
import struct
from array import array

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Trajectory

_OK = (Result.Working, Result.Finished)
_PROF = struct.Struct("43d")      # Segment.prof


def min_distance(v0, v1, A, J):
    """Shortest arc length in which the feed can change from v0 to v1 (a = 0 at both ends)."""
    dv = abs(v1 - v0)
    if dv <= A * A / J:
        return (v0 + v1) * math.sqrt(dv / J)
    return 0.5 * (v0 + v1) * (dv / A + A / J)


# ruckig accepts a profile whose end is within 1e-8 of the target position and velocity
# (profile.hpp: p_precision, v_precision): the end feed is read as anywhere within _V_TOL of v1
_V_TOL = 2e-8
# a length within this of the shortest change still has a profile (ruckig's and the
# distance's rounding: relative, then absolute mm)
_L_REL, _L_ABS = 1e-6, 1e-7


def no_profile(v0, v1, L, A, J) -> bool:
    """True where no feed change v0 → v1 (a = 0 at both ends, feed ≥ 0) fits in L, so ruckig
    has none: L is below the shortest such change, within ruckig's tolerances. The shortest is
    the direct change (min_distance: it has the largest |a| at every feed) or one that first
    slows to 0 (shorter for a change of several times v0): a profile that slows to some feed
    in between is split there into two changes, whose summed min_distance is concave in that
    feed, so it is shortest at an end."""
    bound = L * (1 + _L_REL) + _L_ABS
    if min_distance(v0, v1, A, J) <= bound or abs(v1 - v0) <= _V_TOL:
        return False
    # min_distance from v0 is concave on each side of it: over the end feeds ruckig accepts it
    # is shortest at one of their two ends (the change through 0 at the lower)
    via0 = min_distance(v0, 0.0, A, J)
    for x in (max(v1 - _V_TOL, 0.0), v1 + _V_TOL):
        if min(min_distance(v0, x, A, J), via0 + min_distance(0.0, x, A, J)) <= bound:
            return False
    return True


def reachable(v0, L, A, J, vmax):
    """Largest v1 ≤ vmax that can be reached from v0 (either way) within L."""
    if min_distance(v0, vmax, A, J) <= L:
        return vmax
    # bisection on min_distance(v0, mid, A, J) ≤ L, written out (the same operations): a
    # repair round calls this ~10⁴ times on a long program
    lo, hi = v0, vmax
    knee = A * A / J
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if mid == lo or mid == hi:      # converged: every further step repeats this one
            break
        dv = abs(mid - v0)
        d = (v0 + mid) * math.sqrt(dv / J) if dv <= knee else 0.5 * (v0 + mid) * (dv / A + A / J)
        if d <= L:
            lo = mid
        else:
            hi = mid
    return lo


def solver():
    """(Ruckig, InputParameter, Trajectory) for :meth:`Segment.compute`: one axis from position 0
    at a = 0 to a = 0, never backwards (min velocity 0); compute sets the rest per segment (the
    fixed inputs are set once: a segment check fits ~10⁵ profiles on a long program)."""
    inp = InputParameter(1)
    inp.current_position = [0.0]
    inp.current_acceleration = [0.0]
    inp.target_acceleration = [0.0]
    inp.min_velocity = [0.0]
    return Ruckig(1), inp, Trajectory(1)


class Segment:
    """One ruckig profile between two critical points. ``prof`` holds s0, L, v0, v1, the duration,
    the seven phases' durations and jerks and the eight boundary states a, v, p (ruckig's) as
    one buffer of 43 doubles: the checks stack many segments' buffers into one array
    (planners.scurve.batch) at the cost of a copy."""

    __slots__ = ("s0", "L", "v0", "v1", "A", "J", "vpeak", "prof", "duration")
    HEAD, T, J_, A_, V_, P_ = slice(0, 5), slice(5, 12), slice(12, 19), slice(19, 27), slice(27, 35), slice(35, 43)

    def __init__(self, s0, L, v0, v1, A, J, vpeak):
        self.s0, self.L, self.v0, self.v1, self.A, self.J, self.vpeak = s0, L, v0, v1, A, J, vpeak
        self.duration = None

    def compute(self, otg, inp, traj) -> bool:
        """Fit the profile with the solver of :func:`solver`; False if ruckig finds none."""
        # ruckig's failure (an exception that formats its input) costs ~20 µs, and the repair's
        # tests at J or A × 0.05 often fail
        if no_profile(self.v0, self.v1, self.L, self.A, self.J):
            return False
        inp.current_velocity = [self.v0]
        inp.target_position = [self.L]
        inp.target_velocity = [self.v1]
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
            if res in _OK:
                break
        else:
            return False
        prof = traj.profiles[0][0]
        self.duration = float(traj.duration)
        # packed, then read as doubles: the same values, faster than an array from a list
        self.prof = array("d", _PROF.pack(self.s0, self.L, self.v0, self.v1, self.duration,
                                          *prof.t, *prof.j, *prof.a, *prof.v, *prof.p))
        return True

    @property
    def tcum(self):
        """Start times of the phases and the end of the last (8)."""
        return np.concatenate([[0.0], np.cumsum(self.prof[Segment.T])])

    def state(self):
        """(A, J, vpeak and the fitted profile), for :meth:`restore`."""
        return (self.A, self.J, self.vpeak, self.prof, self.duration)

    def restore(self, state):
        self.A, self.J, self.vpeak, self.prof, self.duration = state

    def at(self, tt):
        """(p, v, a, j) at local times tt (clipped to the segment)."""
        # np.minimum/np.maximum: np.clip's Python wrapper cost more than the arithmetic here
        tcum = self.tcum
        tt = np.minimum(np.maximum(np.asarray(tt, float), 0.0), self.duration)
        k = np.minimum(np.maximum(np.searchsorted(tcum, tt, side="right") - 1, 0), 6)
        dt = tt - tcum[k]
        jk, ak, vk, pk = (np.asarray(self.prof[x])[k] for x in (Segment.J_, Segment.A_, Segment.V_, Segment.P_))
        a = ak + jk * dt
        v = vk + ak * dt + jk * dt * dt / 2
        p = pk + vk * dt + ak * dt * dt / 2 + jk * dt ** 3 / 6
        return p, v, a, jk
