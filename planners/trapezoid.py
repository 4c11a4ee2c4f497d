"""Planner 1: ``trapezoid`` — LinuxCNC 2.9 trajectory planner, type 0 (no jerk limit).

What LinuxCNC would do with the toolpath, cycle by cycle (``src/emc/tp/`` of LinuxCNC 2.9):

* Geometry as LinuxCNC gets it: lines and arcs. A NURBS is first cut into G1 lines within
  the chord tolerance (as a CAM post does; :func:`planners.paths.lines.cut_into_lines`) and its
  corners are then blended under ``G64 P<tolerance>`` by tangent arcs
  (:func:`planners.paths.blend.blend_corners`; blendmath.c). A G-code path is re-blended
  from its program as LinuxCNC blends it: G64 arcs sized to the speed (the moves' feeds, the
  axis limits: ``blendComputeParameters``), line↔arc corners too (``tpCreateLineArcBlend``);
  the arc runs at most at its v_plan. Other segment paths are used as given.
* Segment limits (tc.c ``tcGetTangentialMaxAccel``, ``tcUpdateArcLimits``; blendmath.c
  ``pmCircleActualMaxVel``): LinuxCNC limits only the Cartesian axes and the feed. A line's
  acceleration/velocity is the largest keeping every axis within its limit along the line's
  direction; a G2/G3 arc's tangential acceleration gets √(1 − (v²/ρ / a)²) of the plane's
  bound a, v its machine speed (``tcUpdateCircleAccRatio``), a blend arc's
  ``BLEND_ACC_RATIO_TANGENTIAL`` = 0.5; the speed is capped at √(0.866·a·ρ)
  (``BLEND_ACC_RATIO_NORMAL``).
* Look-ahead (tp.c ``tpRunOptimization`` / ``tpComputeOptimalVelocity``): backward pass
  v_start = √(v_final² + 2·a·L), so every segment can stop where the path demands; a
  tangent-discontinuous junction (exact stop, or a corner with no blend) ends at rest.
  Differences from LinuxCNC: the whole path is looked ahead (LinuxCNC stops after
  TP_LOOKAHEAD_DEPTH segments, which matters only for very short segments), no "kink"
  velocity at small tangent breaks. The programmed F caps each move (planners.feed;
  ``--max-feed`` runs at F_max).
* Per-cycle update (tp.c ``tpCalculateTrapezoidalAccel``, ``tcUpdateDistFromAccel``,
  ``tpHandleSplitCycle``): the largest new speed that can still stop at the segment's final
  speed, v = −a·dt/2 + √(v_f² + a(2·dx − v·dt) + (a·dt/2)²), capped at the segment's
  velocity, the acceleration clamped to ±a, the distance advanced by the trapezoidal
  rule; a cycle that passes the segment end carries the rest into the next segment.
* Queue syncs (a G-code path): motion rests after the move for a dwell's P and for the
  mean wait of LinuxCNC's io task at coolant M codes (:func:`queue_waits`).

The profile lives on the geometry it planned on (``profile.path``: the G1 lines and blend
arcs); ``profile.info["geometry_deviation_mm"]`` bounds its distance from the original path
(chord deviation + largest blend deviation).
"""
from __future__ import annotations

import math

import numpy as np

from planners.constraints import check_limits, check_path_in_workspace
from planners.errors import PlanningError
from planners.paths.blend import blend_corners
from planners.paths.lines import cut_into_lines
from planners.paths import NurbsPath, Path, SegmentPath
from planners.feed import segment_feeds
from planners.profile import Profile

ACC_RATIO_TANGENTIAL = 0.5                               # blendmath.h
ACC_RATIO_NORMAL = math.sqrt(1 - ACC_RATIO_TANGENTIAL**2)  # ≈ 0.866
MAX_CYCLES = 20_000_000


def prepare_geometry(path: Path, chord_tol: float, blend_tol: float | None, limits=None,
                     programmed_feed: bool = True):
    """(segment path planned on, info) — the path as LinuxCNC would receive it.

    A G-code path with ``limits`` is re-blended from its program with LinuxCNC's speed-sized
    blend arcs (planners.paths.gcode.program_path; the feeds the path runs at)."""
    if isinstance(path, SegmentPath) and path.program is not None and limits is not None:
        from planners.paths.gcode import program_path
        programmed = programmed_feed and path.feed_mode != "max"
        sized = program_path(path.program, (limits.cartesian.v, limits.cartesian.a, limits.feed_max, programmed))
        sized.feed_mode = path.feed_mode
        return sized, {"geometry_deviation_mm": 0.0, "chord_deviation_mm": 0.0,
                       "blend_deviation_mm": 0.0, "segments": len(sized.segments),
                       "blends": "speed-sized (LinuxCNC blendComputeParameters)"}
    if isinstance(path, SegmentPath):
        return path, {"geometry_deviation_mm": 0.0, "chord_deviation_mm": 0.0,
                      "blend_deviation_mm": 0.0, "segments": len(path.segments)}
    if not isinstance(path, NurbsPath):
        raise PlanningError(f"trapezoid: cannot plan on a {type(path).__name__}")
    poly, chord_dev = cut_into_lines(path, chord_tol)
    n = len(poly.segments)
    tol = [blend_tol] * (n - 1)
    segs, done = blend_corners(poly.segments, tol)
    blend_dev = max((d for _, d in done), default=0.0)
    planned = SegmentPath(segs, f"{path.source} (G1 lines, G64 P{blend_tol:g})" if blend_tol
                          else f"{path.source} (G1 lines, G61)")
    return planned, {"geometry_deviation_mm": chord_dev + blend_dev, "chord_deviation_mm": chord_dev,
                     "blend_deviation_mm": blend_dev, "g1_lines": n, "segments": len(segs),
                     "blends": len(done)}


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
        rho = r + (rise / ang) ** 2 / r     # helix radius of curvature
        k = np.array([g.spiral for g in A]) / ang
        if k.any():
            # a spiral: blendmath.c pmCircleEffectiveMinRadius, the Archimedean spiral's radius of
            # curvature (r² + k²)^1.5 / (r² + 2k²) at the start radius r, k = dr/dφ
            sp = k != 0
            r_sp = (r[sp] ** 2 + k[sp] ** 2) ** 1.5 / (r[sp] ** 2 + 2 * k[sp] ** 2)
            rho[sp] = r_sp + (rise[sp] / ang[sp]) ** 2 / r_sp
        # a speed-sized blend arc also has LinuxCNC's v_plan as its maxvel (tpCreateLineLineBlend)
        cap = np.array([getattr(g, "v_cap", None) or math.inf for g in A])
        blend = np.isfinite(cap)
        v_machine = np.minimum(feed_max, v_axis / scale)
        vmax[arc] = np.minimum.reduce([v_machine, np.sqrt(ACC_RATIO_NORMAL * a_plane * rho), cap])
        # a G2/G3 arc (TC_CIRCULAR) gets the tangential share its machine speed leaves
        # (tc.c tcUpdateCircleAccRatio, blendmath.c pmCircleActualMaxVel): √(1 − (v²/ρ / a)²),
        # 0.5 when v²/ρ exceeds a_n; a blend arc (TC_SPHERICAL) keeps 0.5
        a_n_v = v_machine ** 2 / rho
        ratio = np.where(a_n_v > ACC_RATIO_NORMAL * a_plane, ACC_RATIO_TANGENTIAL,
                         np.sqrt(np.maximum(1.0 - (a_n_v / a_plane) ** 2, 0.0)))
        # ... once finalized (tcFinalizeLength), i.e. when the next move is queued: the last
        # move before a queue sync or the program end never is, and keeps 0.5
        last = np.array(_ends_queue(path, np.nonzero(arc)[0].tolist()), bool)
        amax[arc] = np.where(blend | last, ACC_RATIO_TANGENTIAL, ratio) * a_plane
    return vmax, amax


def _ends_queue(path: SegmentPath, ks) -> list[bool]:
    """For each segment k in ``ks``: is it the last of a G-code move after which the motion
    queue drains (an M-code sync, a dwell, the program end), nothing queued behind it?"""
    prog, segs = path.program, path.segments
    if prog is None:
        return [k == len(segs) - 1 for k in ks]
    stop = {m.line: m.stop for m in prog.moves}
    return [not (k + 1 < len(segs) and segs[k + 1].line == segs[k].line)
            and stop.get(segs[k].line) in ("sync", "end") for k in ks]


def program_stops(path: SegmentPath):
    """(segments after which LinuxCNC stops, segments at half acceleration) from the G-code
    moves' ``stop``/``parabolic_end`` (planners.paths.gcode): an M-code queue sync or a rapid ↔ feed
    change stops motion even between collinear moves; the move before a sync or the program
    end keeps term_cond PARABOLIC under G64, i.e. half acceleration (tc.c
    ``tcGetOverallMaxAccel``). Blend arcs (LinuxCNC's own segments) keep full acceleration."""
    prog = path.program
    segs = path.segments
    if prog is None:
        return [], np.zeros(len(segs), bool)
    by_line = {m.line: m for m in prog.moves}
    stops, half = [], np.zeros(len(segs), bool)
    for i, g in enumerate(segs):
        m = by_line.get(g.line)
        if m is None or g.kind != m.segment.kind:
            continue
        if m.stop and (i + 1 == len(segs) or segs[i + 1].line != g.line):
            stops.append(i)
        half[i] = m.parabolic_end
    return stops, half


IO_CYCLE_S = 0.100          # [EMCIO] CYCLE_TIME of the LinuxCNC sim config (planners/linuxcnc/runner.py)
# coolant M codes are commands to LinuxCNC's io task: M7 mist on, M8 flood on, M9 both off
IO_COMMANDS = {7: 1, 8: 1, 9: 2}


def queue_waits(path: SegmentPath) -> dict:
    """{segment index: seconds at rest after it} for a G-code path's queue syncs.

    A dwell waits its P. A coolant M code is a command to the io task, which looks at its
    command buffer once per io cycle (ioControl.cc main loop, esleep(emc_io_cycle_time)) and
    then sleeps a full cycle: the first command waits on average half a cycle (a random
    phase: LinuxCNC's own spread run to run), each further one a whole cycle. The mean is
    used (same inputs, same outputs). Other M codes (spindle, M62–M65 …) go to motion: no wait."""
    prog = path.program
    if prog is None:
        return {}
    last_seg = {}
    for k, g in enumerate(path.segments):
        last_seg[g.line] = k
    per_move: dict[int, list] = {}
    for e in prog.events:
        if 0 < e.index <= len(prog.moves):
            per_move.setdefault(e.index - 1, []).append(e)
    waits = {}
    for mi, evs in per_move.items():
        n_io = sum(IO_COMMANDS.get(e.value, 0) for e in evs if e.kind == "m")
        dwell = sum(float(e.value) for e in evs if e.kind == "dwell")
        w = dwell + (0.5 * IO_CYCLE_S + (n_io - 1) * IO_CYCLE_S if n_io else 0.0)
        k = last_seg.get(prog.moves[mi].line)
        if w > 0 and k is not None and k < len(path.segments) - 1:
            waits[k] = waits.get(k, 0.0) + w
    return waits


def insert_waits(path: SegmentPath, s: np.ndarray, sd: np.ndarray, waits: dict, T: float):
    """s, sd with round(wait/T) samples at rest at the end of each segment in ``waits``
    (the profile reaches the stop, stays, then runs on as simulated)."""
    if not waits:
        return s, sd
    ends = {k: float(path.seg_start[k]) + path.segments[k].length for k in waits}
    parts_s, parts_v, j0 = [], [], 0
    for k in sorted(waits):
        j = int(np.searchsorted(s, ends[k] - 1e-9))
        n = int(round(waits[k] / T))
        parts_s += [s[j0:j], np.full(n, ends[k])]
        parts_v += [sd[j0:j], np.zeros(n)]
        j0 = j
    parts_s.append(s[j0:])
    parts_v.append(sd[j0:])
    return np.concatenate(parts_s), np.concatenate(parts_v)


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
    """Cycle-by-cycle LinuxCNC update: (s, sd, sdd, excess) at every period.

    A cycle that reaches a segment end is split (tp.c ``tpHandleSplitCycle``): the time τ
    to the end under the cycle's constant acceleration is solved exactly, the next segment
    starts at the speed reached there (never above the look-ahead's final speed), and the
    rest of the period runs on the next segment with its own update.
    ``excess`` is the largest clipped speed excess at a segment end (mm/s, diagnostics).
    """
    # plain floats in the per-cycle loop (see final_velocities). A 10⁵-line program runs
    # ~2·10⁶ passes: the segment's values are read once per segment, and min()/max() are
    # written as conditionals that return what the builtins return (first argument on a tie,
    # so the sign of a zero is kept): the same IEEE operations, about half the time.
    L = [g.length for g in path.segments]
    vmax, amax, vf = np.asarray(vmax).tolist(), np.asarray(amax).tolist(), np.asarray(vf).tolist()
    n = len(L)
    s_out, v_out = [0.0], [0.0]
    i, x, v = 0, 0.0, 0.0
    base = 0.0
    excess = 0.0
    sqrt = math.sqrt
    length = path.length
    a, Li, vfi, vmi = amax[0], L[0], vf[0], vmax[0]
    vf2 = vfi ** 2
    end = Li - 1e-12
    for _ in range(MAX_CYCLES):
        t_left = T
        while t_left > 0.0:
            dx = Li - x
            half = 0.5 * a * t_left
            disc = vf2 + a * (2 * dx - v * t_left) + half * half
            v_new = -half + sqrt(disc) if disc > 0 else 0.0
            if 0.0 > v_new:                              # max(v_new, 0.0)
                v_new = 0.0
            if vmi < v_new:                              # min(…, vmax[i])
                v_new = vmi
            acc = (v_new - v) / t_left
            if -a > acc:                                 # min(max(acc, −a), a)
                acc = -a
            if a < acc:
                acc = a
            v_new = v + acc * t_left
            if 0.0 > v_new:
                v_new = 0.0
            disp = 0.5 * (v + v_new) * t_left
            if x + disp < end:
                x += disp
                v = v_new
                break
            # The end of segment i is reached within this cycle at τ: v·τ + acc·τ²/2 = dx.
            if abs(acc) * t_left < 1e-12 * (1.0 if 1.0 > v else v):
                tau = dx / v if v > 0 else t_left
            else:
                r = v * v + 2 * acc * dx
                tau = (-v + sqrt(0.0 if 0.0 > r else r)) / acc
            if 0.0 > tau:
                tau = 0.0
            if t_left < tau:
                tau = t_left
            v_end = v + acc * tau
            if i == n - 1:
                s_out.append(length)
                v_out.append(0.0)
                return np.array(s_out), np.array(v_out), excess
            if v_end - vfi > excess:
                excess = v_end - vfi
            v = vfi if vfi < v_end else v_end
            base += Li
            x = 0.0
            i += 1
            a, Li, vfi, vmi = amax[i], L[i], vf[i], vmax[i]
            vf2 = vfi ** 2
            end = Li - 1e-12
            t_left -= tau
        pos = base + x
        s_out.append(length if length < pos else pos)
        v_out.append(v)
    raise PlanningError(f"trapezoid: no arrival after {MAX_CYCLES} cycles (a limit too small?)")


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
    planned, info = prepare_geometry(path, chord, blend if blend > 0 else None, limits, programmed_feed)
    # the workspace of the path that runs: a program's speed-sized blends (so a G-code path's
    # own blends are never built, see planners.paths.gcode.program_path), else the given curve
    check_path_in_workspace(planned if isinstance(path, SegmentPath) else path, machine, check_workspace_step_mm)
    vmax, amax = segment_limits(planned, limits.cartesian.v, limits.cartesian.a, limits.feed_max)
    feeds = segment_feeds(planned, limits.feed_max) if programmed_feed else None
    if feeds is not None:
        vmax = np.minimum(vmax, feeds)
    stops, half = program_stops(planned)
    amax = np.where(half, 0.5 * amax, amax)
    vf = final_velocities(planned, vmax, amax, stops)
    s, sd, excess = simulate(planned, vmax, amax, vf, T)
    waits = queue_waits(planned)
    s, sd = insert_waits(planned, s, sd, waits, T)
    # s̈ as the mean acceleration of each period (the split cycles make it a mix of two
    # segments' accelerations); s⃛ its difference. Rest at the end: both 0 there.
    sdd = np.zeros_like(sd)
    sdd[1:] = np.diff(sd) / T
    sdd[-1] = 0.0
    sddd = np.zeros_like(sdd)
    sddd[1:] = np.diff(sdd) / T
    info.update({"corners": int(len(planned.corners())), "lookahead": "whole path",
                 "programmed_feed": feeds is not None,
                 "queue_waits_s": {int(k): float(w) for k, w in waits.items()},
                 "boundary_speed_excess_mm_s": float(excess),
                 "acc_ratio_tangential": ACC_RATIO_TANGENTIAL})
    return Profile("trapezoid", T, s, sd, sdd, sddd, planned, info=info)
