"""ruckig_path: one jerk-limited ruckig trajectory of the arc length (see README.md)."""
from __future__ import annotations

import math

import numpy as np

MARGIN = 0.9       # on the sampled curvature bound: κ between samples may be a little higher

# the limits this planner keeps by construction (pkmbench's Planner protocol)
guarantees = {"cartesian": ["velocity", "acceleration", "feed"]}


def _piece(a: float, b: float, v: float, acc: float, jerk: float):
    """A rest-to-rest ruckig trajectory of s from a to b."""
    from ruckig import InputParameter, Result, Ruckig, Trajectory
    otg, inp, traj = Ruckig(1), InputParameter(1), Trajectory(1)
    inp.current_position, inp.target_position = [a], [b]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [v], [acc], [jerk]
    if otg.calculate(inp, traj) != Result.Working:
        raise RuntimeError(f"ruckig found no trajectory from s = {a} to {b} mm at v = {v} mm/s")
    return traj


def plan(path, machine, limits=None, *, ds_mm: float = 0.05, feed_mm_s: float | None = None, **options):
    """``feed_mm_s``: a speed cap below F_max (a suite's [planner_options.ruckig_path])."""
    from planners.profile import Profile      # the host's type, imported when pkmbench calls us

    lim = limits or machine.limits
    c = lim.cartesian
    T = machine.servo_period_s
    L = float(path.length)
    # a corner (tangent jump) has no finite curvature bound: stop there, rest to rest per piece;
    # so at the joins of a line/arc path (the example stays simple: it stops at each)
    joins = path.segment_joins()           # line/arc pieces: curvature jumps there too
    cuts = list(np.atleast_1d(path.corners())) + (list(joins) if joins is not None else [])
    corners = sorted({float(x) for x in cuts if 0.0 < x < L})
    bounds = [0.0] + corners + [L]
    pieces, t0, info = [], 0.0, []
    for a, b in zip(bounds[:-1], bounds[1:]):
        n = max(2, int(math.ceil((b - a) / ds_mm)) + 1)
        inner = np.linspace(a, b, n)[1:-1] if n > 2 else np.array([(a + b) / 2])
        kappa = float(np.max(path.curvature(inner)))
        v = min(lim.feed_max, c.v, feed_mm_s or math.inf)
        if kappa > 0:
            v = min(v, MARGIN * math.sqrt(c.a / (2.0 * kappa)))
        traj = _piece(a, b, v, c.a / 2, c.j / 2)
        pieces.append((t0, traj, b))
        info.append({"s_end": b, "v_mm_s": v, "kappa_max_per_mm": kappa})
        t0 += traj.duration
    n = int(math.ceil(t0 / T - 1e-12))
    s = np.empty(n + 1)
    k = 0
    for i in range(n + 1):
        t = i * T
        while k < len(pieces) - 1 and t >= pieces[k + 1][0]:
            k += 1
        start, traj, _ = pieces[k]
        s[i] = traj.at_time(min(t - start, traj.duration))[0][0]
    s = np.clip(s, 0.0, L)
    s[0], s[-1] = 0.0, L                     # rest to rest, exactly at the ends
    s = np.maximum.accumulate(s)             # ruckig's round-off must not run backwards
    return Profile.from_s("ruckig_path", T, s, path, info={"pieces": info, "duration_s": t0})


plan.guarantees = guarantees
