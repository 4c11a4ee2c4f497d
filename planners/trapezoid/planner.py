"""Planner 1: ``trapezoid`` — LinuxCNC 2.9 trajectory planner, type 0 (no jerk limit).

What LinuxCNC would do with the toolpath, cycle by cycle (``src/emc/tp/`` of LinuxCNC 2.9):

* A G-code program runs as LinuxCNC's tp queues it (planners.trapezoid.queue, planners.trapezoid.blend,
  planners.trapezoid.program): one move at a time, each corner a blend arc sized to the speed (which
  may take a short previous line into itself), a parabolic blend or a near-tangent "kink",
  whichever ``tpChooseBestBlend`` finds fastest; every segment lasts at least a servo period
  (``tcClampVelocityByLength``); the look-ahead is tp.c's, 50 segments deep; a parabolic
  blend moves two segments at once; a tangent segment shorter than 10 ms ramps evenly to its
  final speed (``tpCalculateRampAccel``); an exact stop costs the rest of its period. Queue syncs:
  motion rests after the move for a dwell's P, the mean wait of LinuxCNC's io task at coolant M
  codes and tool changes, and task's own cycles and messages to motion (tp_plan.move_waits).
  The programmed F caps each move (``--max-feed`` runs at F_max).
* A NURBS is first cut into G1 lines within the chord tolerance (as a CAM post does;
  :func:`planners.paths.lines.cut_into_lines`) and its corners blended under
  ``G64 P<tolerance>`` by the largest tangent arcs (:func:`planners.paths.blend.blend_corners`);
  other segment paths are used as given. There (below) a line's acceleration/velocity is the
  largest keeping every axis within its limit along the line's direction; an arc's
  tangential acceleration gets √(1 − (v²/ρ / a)²) of the plane's bound a, v its machine
  speed (tc.c ``tcUpdateCircleAccRatio``), the last one 0.5; its speed is capped at
  √(0.866·a·ρ) (``BLEND_ACC_RATIO_NORMAL``). The look-ahead is the whole path: v_start =
  √(v_final² + 2·a·L) backwards, a tangent-discontinuous junction ends at rest.
* Per-cycle update, both (planners.trapezoid.cycle: tp.c ``tpCalculateTrapezoidalAccel``,
  ``tcUpdateDistFromAccel``, ``tpHandleSplitCycle``): the largest new speed that can still
  stop at the segment's final speed, v = −a·dt/2 + √(v_f² + a(2·dx − v·dt) + (a·dt/2)²),
  capped at the segment's velocity, the acceleration clamped to ±a, the distance advanced
  by the trapezoidal rule; a cycle that passes the segment end carries the rest into the
  next segment.

The profile lives on the geometry it planned on (``profile.path``: the G1 lines and blend
arcs; a parabolic blend's polyline); ``profile.info["geometry_deviation_mm"]`` bounds its
distance from the original NURBS (chord deviation + largest blend deviation).
"""
from __future__ import annotations

import math

import numpy as np

from planners.constraints import check_limits, check_path_in_workspace
from planners.errors import PlanningError
from planners.paths import Path, PathError, SegmentPath
from planners.paths.post import prepare_geometry
from planners.profile import Profile
from planners.trapezoid import program as tp_plan
from planners.trapezoid import queue as tp_queue
from planners.trapezoid import cycle as tp_run
from planners.trapezoid.rules import ACC_RATIO_NORMAL, ACC_RATIO_TANGENTIAL, arc_speed_radius



def segment_limits(path: SegmentPath, v_axis: float, a_axis: float, feed_max: float):
    """Per segment: (velocity cap, tangential acceleration limit), mm/s and mm/s²."""
    segs = path.segments
    arc = np.array([g.kind == "arc" for g in segs])
    # a line: the axis that moves fastest sees |u_k| of the feed and of the acceleration
    worst = np.abs(np.array([g.direction if g.kind == "line" else (1.0, 0.0, 0.0) for g in segs])).max(axis=1)
    vmax = np.minimum(feed_max, v_axis / worst)
    amax = a_axis / worst
    if arc.any():
        # an arc: a bound of any vector in its plane (plus the helix axis if it rises):
        # axis k sees at most |a|·√(u_k² + v_k² (+ n_k²))
        A = [g for g in segs if g.kind == "arc"]
        r = np.array([g.radius for g in A])
        u, v = np.array([g.a for g in A]) / r[:, None], np.array([g.b for g in A]) / r[:, None]
        rise = np.array([g.rise for g in A])
        n = np.array([g.normal for g in A]) * (rise != 0)[:, None]
        scale = np.sqrt(u ** 2 + v ** 2 + n ** 2).max(axis=1)
        a_plane = a_axis / scale
        ang = np.array([g.angle for g in A])
        rho = arc_speed_radius(r, ang, rise, np.array([g.spiral for g in A]))
        v_machine = np.minimum(feed_max, v_axis / scale)
        vmax[arc] = np.minimum(v_machine, np.sqrt(ACC_RATIO_NORMAL * a_plane * rho))
        # an arc gets the tangential share its machine speed leaves (tc.c
        # tcUpdateCircleAccRatio, blendmath.c pmCircleActualMaxVel): √(1 − (v²/ρ / a)²),
        # 0.5 when v²/ρ exceeds a_n
        a_n_v = v_machine ** 2 / rho
        ratio = np.where(a_n_v > ACC_RATIO_NORMAL * a_plane, ACC_RATIO_TANGENTIAL,
                         np.sqrt(np.maximum(1.0 - (a_n_v / a_plane) ** 2, 0.0)))
        # ... once finalized (tcFinalizeLength), i.e. when the next move is queued: the last
        # segment never is, and keeps 0.5
        last = np.nonzero(arc)[0] == len(segs) - 1
        amax[arc] = np.where(last, ACC_RATIO_TANGENTIAL, ratio) * a_plane
    return vmax, amax


def final_velocities(path: SegmentPath, vmax: np.ndarray, amax: np.ndarray, stops=()) -> np.ndarray:
    """Backward look-ahead: the speed at the end of each segment (0 at corners, after the
    segments in ``stops`` and at the end)."""
    n = len(path.segments)
    corner_idx = set(np.searchsorted(path.seg_start, path.corners()).tolist())
    corner_idx.update(i + 1 for i in stops)
    # plain floats in the loop: numpy scalar arithmetic is ~5× slower, and a 10⁵-line
    # program runs this 10⁵ times (IEEE results are the same)
    vm, am = vmax.tolist(), amax.tolist()
    length = [g.length for g in path.segments]
    vf = [0.0] * n
    for i in range(n - 2, -1, -1):
        if i + 1 in corner_idx:
            continue                                  # exact stop at a tangent break
        vs_next = math.sqrt(vf[i + 1] ** 2 + 2 * am[i + 1] * length[i + 1])
        vf[i] = min(vs_next, vm[i], vm[i + 1])
    return np.array(vf)


def simulate(path: SegmentPath, vmax, amax, vf, T: float):
    """Cycle-by-cycle LinuxCNC update on the path's segments (planners.trapezoid.cycle.simulate):
    (s, sd, excess) at every period."""
    s, sd, excess, _ = tp_run.simulate([g.length for g in path.segments], np.asarray(vmax).tolist(),
                                       np.asarray(amax).tolist(), np.asarray(vf).tolist(), T, path.length)
    return s, sd, excess


def _run_program(path: SegmentPath, limits, T: float, programmed_feed: bool):
    """(geometry, s, sd, info) of a G-code program as LinuxCNC's tp queues and runs it
    (planners.trapezoid.program), with the rests at its queue syncs."""
    prog = path.program
    programmed = programmed_feed and path.feed_mode != "max"
    lim = tp_queue.Limits(T, limits.cartesian.v, limits.cartesian.a, limits.feed_max, programmed)
    geometry, s, sd, run_end_s, info = tp_plan.run_program(prog, lim)
    planned = SegmentPath(geometry, f"{prog.source} (LinuxCNC tp queue)", program=prog)
    planned.feed_mode = path.feed_mode
    waits = tp_plan.move_waits(prog, T)
    s, sd = tp_plan.insert_waits(s, sd, [(run_end_s[k], w) for k, w in waits.items()], T)
    # the queue's arc length and the path's sum the same lengths in another order: they part
    # by rounding (> 1e-9 mm on a 1.6·10⁵ mm program), so end exactly at the path's
    np.minimum(s, planned.length, out=s)
    s[-1] = planned.length
    info.update({"geometry_deviation_mm": 0.0, "segments": len(geometry),
                 "blends": "LinuxCNC tp queue (planners.trapezoid.queue)",
                 "lookahead": f"{tp_queue.OPT_DEPTH} segments", "programmed_feed": programmed,
                 "queue_waits_s": {int(k): float(w) for k, w in waits.items()}})
    return planned, s, sd, info


def plan(path: Path, machine, limits=None, *, blend_tolerance_mm: float | None = None,
         chord_tolerance_mm: float | None = None, programmed_feed: bool = True,
         check_workspace_step_mm: float = 0.5) -> Profile:
    """LinuxCNC-style trapezoidal profile.

    ``chord_tolerance_mm`` (default: the machine's chord error) is used to cut a NURBS into
    G1 lines; ``blend_tolerance_mm`` is its G64 P (default: the same value; 0 → G61, exact
    stops at every vertex). ``programmed_feed``: for a G-code path, cap each move at its
    programmed F as LinuxCNC does (the default; False, or a path marked by
    ``planners.feed.use_max_feed``, runs it at F_max).
    """
    limits = limits or machine.limits
    check_limits(limits, "trapezoid")
    T = float(machine.servo_period_s)
    if not (T > 0 and math.isfinite(T)):
        raise PlanningError(f"trapezoid: servo period {machine.servo_period_s!r} s of {machine.name} must be > 0")
    chord = limits.chord_error_mm if chord_tolerance_mm is None else chord_tolerance_mm
    blend = chord if blend_tolerance_mm is None else blend_tolerance_mm
    if not chord > 0:
        raise PlanningError(f"trapezoid: chord tolerance {chord} mm must be > 0")
    if blend < 0:
        raise PlanningError(f"trapezoid: blend tolerance {blend} mm must be ≥ 0")
    if isinstance(path, SegmentPath) and path.program is not None:
        planned, s, sd, info = _run_program(path, limits, T, programmed_feed)
        check_path_in_workspace(planned, machine, check_workspace_step_mm)
    else:
        try:
            planned, info = prepare_geometry(path, chord, blend if blend > 0 else None)
        except PathError as e:
            raise PlanningError(f"trapezoid: {e}") from None
        check_path_in_workspace(planned if isinstance(path, SegmentPath) else path, machine,
                                check_workspace_step_mm)
        vmax, amax = segment_limits(planned, limits.cartesian.v, limits.cartesian.a, limits.feed_max)
        vf = final_velocities(planned, vmax, amax)
        s, sd, excess = simulate(planned, vmax, amax, vf, T)
        info.update({"corners": int(len(planned.corners())), "lookahead": "whole path",
                     "programmed_feed": False, "boundary_speed_excess_mm_s": float(excess)})
    # s̈ as the mean acceleration of each period (the split cycles make it a mix of two
    # segments' accelerations); s⃛ its difference. Rest at the end: both 0 there.
    sdd = np.zeros_like(sd)
    sdd[1:] = np.diff(sd) / T
    sdd[-1] = 0.0
    sddd = np.zeros_like(sdd)
    sddd[1:] = np.diff(sdd) / T
    info["acc_ratio_tangential"] = ACC_RATIO_TANGENTIAL
    return Profile("trapezoid", T, s, sd, sdd, sddd, planned, info=info)
