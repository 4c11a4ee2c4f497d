"""LinuxCNC 2.9's motion queue: the segments its trajectory planner builds from a program.

One G-code move at a time, as tp.c ``tpAddLine`` / ``tpAddCircle`` add them (source read at
LinuxCNC commit f1270d6ed7, src/emc/tp/; the numbers are its defaults: [TRAJ]
ARC_BLEND_KINK_RATIO 0.1, ARC_BLEND_GAP_CYCLES 4, ARC_BLEND_OPTIMIZATION_DEPTH 50,
MAX_FEED_OVERRIDE 1, initraj.cc):

* a new segment's max velocity is capped so that it lasts a servo period
  (tc.c ``tcClampVelocityByLength``: v ≤ length / T), again when its length is final
  (``tcFinalizeLength``), and by the look-ahead to length / (1.02 T)
  (``tpComputeOptimalVelocity``, TP_MIN_SEGMENT_CYCLES);
* each corner (``tpHandleBlendArc``): a near-tangent junction whose "kink" needs little
  acceleration is run through as is, the segments' acceleration reduced by the kink's share
  (``tpSetupTangent``, tc.c ``tcSetKinkProperties``); otherwise a blend arc is made
  (blendmath.c; planners.trapezoid.blend) and ``tpChooseBestBlend`` keeps the fastest of the blend
  arc (its max velocity), the tangent kink (its kink velocity) and a parabolic blend (half
  its blend velocity, ``estimateParabolicBlendPerformance``);
* a blend arc whose previous line would be left shorter than ``GAP_CYCLES`` periods at the
  arc's speed takes that line into itself (``blendCheckConsume``: the line is popped and the
  arc segment starts with it, spherical_arc.c ``arcPoint``'s line part);
* the rising-tide look-ahead runs after every new segment over the last ``OPT_DEPTH``
  segments (``tpRunOptimization``, lazy: it stops after ``OPT_CUTOFF`` segments at their
  peak); the last segment, whose length may still change, is planned to stop in itself.

The queue is built as if the whole program were queued before motion starts. LinuxCNC's task
sends a move per servo period or so, ahead of motion on the programs measured; where motion
catches up with the queue (the first moves of a program) LinuxCNC's look-ahead is shorter
than modelled here, and a move arriving while its predecessor is past half-way gets no blend
(tpHandleBlendArc): neither is modelled.
"""
from __future__ import annotations

import math

import numpy as np

from planners.paths.base import norm3
from planners.paths.segments import Arc
from planners.trapezoid import blend as tp_blend
from planners.trapezoid.rules import (ACC_RATIO_NORMAL, ACC_RATIO_TANGENTIAL, KINK_RATIO, MIN_SEGMENT_CYCLES,
                                      OPT_CUTOFF, OPT_DEPTH, SHARP_CORNER, effective_min_radius)


STOP, EXACT, PARABOLIC, TANGENT = "stop", "exact", "parabolic", "tangent"


class TC:
    """One queued segment (tc_types.h TC_STRUCT: the fields this model needs).

    kind: "line" (G0/G1), "circle" (G2/G3) or "blend" (a blend arc, TC_SPHERICAL).
    geometry: a line's start/end/u, a circle's ``arc`` (planners.paths Arc), a blend's ``arc``
    and ``line_length`` (the consumed line before it, along ``u``)."""

    __slots__ = ("kind", "line", "rapid", "start", "end", "u", "arc", "line_length", "target",
                 "nominal", "maxvel", "reqvel", "maxaccel", "term", "blend_prev", "kink_vel",
                 "kink_red", "kink_red_prev", "acc_ratio", "finalized", "tol", "finalvel",
                 "at_max", "clamped")

    def __init__(self, kind, line, rapid, target, maxvel, reqvel, maxaccel, term, tol):
        self.kind, self.line, self.rapid = kind, line, rapid
        self.start = self.end = self.u = self.arc = None
        self.line_length = 0.0
        self.target = self.nominal = target
        self.maxvel, self.reqvel, self.maxaccel = maxvel, reqvel, maxaccel
        self.term, self.tol = term, tol
        self.blend_prev = False
        self.kink_vel, self.kink_red, self.kink_red_prev = -1.0, 0.0, 0.0     # tcInitKinkProperties
        self.acc_ratio = ACC_RATIO_TANGENTIAL                                       # tcInit
        self.finalized = False
        self.finalvel = 0.0
        self.at_max = False
        self.clamped = False            # the max velocity was cut by the length (diagnostics)

    def tangent_in(self):
        return self.u if self.kind == "line" else self.arc.tangent_in()

    def tangent_out(self):
        return self.u if self.kind == "line" else self.arc.tangent_out()


def overall_acc(tc: TC) -> float:
    """tc.c tcGetOverallMaxAccel: less the kink's share; half under a parabolic blend."""
    a = tc.maxaccel * (1.0 - max(tc.kink_red, tc.kink_red_prev))
    if tc.blend_prev or tc.term == PARABOLIC:
        a *= 0.5
    return a


def tangential_acc(tc: TC) -> float:
    """tc.c tcGetTangentialMaxAccel: a circle or blend arc keeps its tangential share."""
    a = overall_acc(tc)
    return a * tc.acc_ratio if tc.kind != "line" else a


def max_target_vel(tc: TC) -> float:
    """tc.c tcGetMaxTargetVel at feed scale 1: the requested speed within the segment's max."""
    return min(tc.reqvel, tc.maxvel)


def clamp_by_length(tc: TC, T: float, cycles: float = 1.0) -> None:
    """tc.c tcClampVelocityByLength: at most one segment length per servo period (per
    ``cycles`` periods: tpComputeOptimalVelocity's 1.02)."""
    v = tc.target / (T * cycles)
    if v < tc.maxvel:
        tc.maxvel, tc.clamped = v, True


def set_term(prev: TC | None, tc: TC | None, term: str) -> None:
    """tc.c tcSetTermCond: the next segment is flagged as parabolic-blended into or not."""
    if tc is not None:
        tc.blend_prev = term == PARABOLIC
    if prev is not None:
        prev.term = term


def remove_kink(prev: TC, tc: TC) -> None:
    """tc.c tcRemoveKinkProperties."""
    prev.kink_vel, prev.kink_red = -1.0, 0.0
    tc.kink_red_prev = 0.0


def finalize(tc: TC | None, T: float) -> None:
    """tc.c tcFinalizeLength: the length is final: clamp again; a circle gets its speed and
    tangential share from its curvature (tcUpdateCircleAccRatio, pmCircleActualMaxVel)."""
    if tc is None or tc.finalized:
        return
    clamp_by_length(tc, T)
    if tc.kind == "circle":
        a = overall_acc(tc)
        g = tc.arc
        rho = effective_min_radius(g.radius, g.angle, g.rise, g.spiral)
        a_n = tc.maxvel ** 2 / rho
        if a_n > ACC_RATIO_NORMAL * a:
            tc.maxvel, tc.acc_ratio = math.sqrt(ACC_RATIO_NORMAL * a * rho), ACC_RATIO_TANGENTIAL
        else:
            tc.acc_ratio = math.sqrt(1.0 - (a_n / a) ** 2)
    tc.finalized = True


def setup_tangent(prev: TC, tc: TC, T: float, a_axis: float) -> str:
    """tp.c tpSetupTangent: "fail" (exact stop or a reversal: no blend), "ok" (run through the
    kink: TANGENT, acceleration reduced by its share) or "no_action" (a blend is tried; the
    kink velocity stays for tpChooseBestBlend)."""
    if prev.term == STOP:
        return "fail"
    t1, t2 = prev.tangent_out(), tc.tangent_in()
    s = t1 + t2
    if float(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]) < SHARP_CORNER:
        set_term(prev, tc, STOP)
        return "fail"
    v_max = min(max_target_vel(prev), max_target_vel(tc))
    # stop on the one segment and start on the other within a period (plus tc's own acceleration)
    a_inst = v_max / T + tc.maxaccel
    scale = a_inst * float(np.abs(t2 - t1).max()) / a_axis            # findAccelScale, equal bounds
    if prev.kind == "circle" or tc.kind == "circle":
        scale /= ACC_RATIO_TANGENTIAL
    if scale < KINK_RATIO:
        set_term(prev, tc, TANGENT)
        _set_kink(prev, tc, v_max, scale)
        return "ok"
    _set_kink(prev, tc, v_max * KINK_RATIO / scale, KINK_RATIO)
    return "no_action"


def _set_kink(prev: TC, tc: TC, kink_vel: float, reduce: float) -> None:
    """tc.c tcSetKinkProperties."""
    prev.kink_vel = kink_vel
    prev.kink_red = max(reduce, prev.kink_red)
    tc.kink_red_prev = max(reduce, tc.kink_red_prev)


def choose_best(prev: TC, tc: TC, blend: TC | None) -> str | None:
    """tp.c tpChooseBestBlend: the fastest of a parabolic blend (half its net velocity, as it
    halves both segments' acceleration), the tangent kink and the blend arc (first on a tie)."""
    if prev.term in (EXACT, STOP):
        return None
    perf = [parabolic_velocity(prev, tc) / 2.0, prev.kink_vel, blend.maxvel if blend is not None else 0.0]
    best = max(range(3), key=lambda k: (perf[k], -k))
    if best == 0:
        remove_kink(prev, tc)
        set_term(prev, tc, PARABOLIC)
        return PARABOLIC
    if best == 1:
        set_term(prev, tc, TANGENT)
        return TANGENT
    remove_kink(prev, tc)
    return "arc"


def _accel_dirs(prev: TC, tc: TC):
    """tc.c tcGetEndAccelUnitVector(prev) / tcGetStartAccelUnitVector(tc): a line's direction;
    a circle's in-plane tangent, at its start turned towards the centre by (v/2)²/r."""
    if prev.kind == "line":
        d1 = prev.u
    else:
        g = prev.arc
        d1 = np.cross(g.normal, g.end - g.center)
        d1 = d1 / norm3(d1)
    if tc.kind == "line":
        return d1, tc.u
    g = tc.arc
    r = g.start - g.center
    tan = np.cross(g.normal, r)
    tan = tan / norm3(tan) * overall_acc(tc)
    perp = -r / norm3(r) * (0.5 * tc.reqvel) ** 2 / g.radius
    d2 = tan + perp
    return d1, d2 / norm3(d2)


def parabolic_velocity(prev: TC, tc: TC) -> float:
    """tp.c estimateParabolicBlendPerformance: the net speed along a parabolic blend between
    prev and tc at their largest target speeds."""
    vb1, vb2, theta = blend_velocities(prev, tc)
    return math.sin(theta) * (vb1 + vb2) / 2.0


def blend_velocities(prev: TC, tc: TC):
    """tp.c tpComputeBlendVelocity (feed scale 1): each segment's speed in a parabolic blend
    and θ, half the angle between their accelerations at the junction."""
    acc1, acc2 = tangential_acc(prev), tangential_acc(tc)
    # tpCalculateTriangleVel: a segment not final yet may lose half its length to a blend
    tri1 = math.sqrt(acc1 * (prev.target if prev.finalized else prev.target / 2.0))
    tri2 = math.sqrt(acc2 * (tc.target if tc.finalized else tc.target / 2.0))
    v1, v2 = min(tri1, max_target_vel(prev)), min(tri2, max_target_vel(tc))
    if not (v1 > 0 and v2 > 0 and acc1 > 0 and acc2 > 0):
        return 0.0, 0.0, 0.0
    t_blend = min(min(prev.target / v1, tc.target / v2), max(v1 / acc1, v2 / acc2))
    vb1, vb2 = min(v1, t_blend * acc1), min(v2, t_blend * acc2)
    d1, d2 = _accel_dirs(prev, tc)
    dot = max(-1.0, min(1.0, float(np.dot(d1, d2))))
    theta = math.acos(-dot) / 2.0
    if prev.tol > 0 and math.cos(theta) > math.cos(math.pi / 2.0 - 1e-3):
        v_tol = 2.0 * math.sqrt(acc1 * prev.tol / math.cos(theta))
        vb1, vb2 = min(vb1, v_tol), min(vb2, v_tol)
    return vb1, vb2, theta


def optimize(queue: list, T: float) -> None:
    """tp.c tpRunOptimization (TP_OPTIMIZATION_LAZY) with tpComputeOptimalVelocity: from the
    newest segment back, each final speed is what the next one can still stop from, within
    both max velocities and a tangent kink's velocity; through one non-tangent junction at most."""
    n = len(queue)
    hit_peaks, non_tangent = 0, False
    for x in range(1, OPT_DEPTH + 2):
        if n - x - 1 < 0:
            return
        tc, prev = queue[n - x], queue[n - x - 1]
        if prev.term != TANGENT:
            if non_tangent:
                return
            non_tangent = True
            continue
        if not tc.finalized:
            # tpCalculateOptimizationInitialVel: tc may still lose half of itself; plan to stop in it
            v = min(math.sqrt(tangential_acc(tc) * tc.target), max_target_vel(tc))
            prev.finalvel = min(prev.maxvel, v)
            if prev.kink_vel >= 0:
                prev.finalvel = min(prev.finalvel, prev.kink_vel)
            tc.finalvel = 0.0
        else:
            vs_back = math.sqrt(tc.finalvel ** 2 + 2.0 * tangential_acc(tc) * tc.target)
            limit = min(tc.maxvel, prev.maxvel if prev.kink_vel < 0 else min(prev.maxvel, prev.kink_vel))
            if vs_back >= limit:
                vs_back = limit
                prev.at_max = True
            prev.finalvel = vs_back
            clamp_by_length(tc, T, MIN_SEGMENT_CYCLES)
        if tc.at_max:
            hit_peaks += 1
        if hit_peaks > OPT_CUTOFF:
            return


class Limits:
    """What the queue model needs of the machine: servo period T, the X/Y/Z axis velocity and
    acceleration bound (equal on every axis here), the max feed (LinuxCNC's vLimit) and
    whether the programmed F counts (else every move runs at the max feed)."""

    def __init__(self, T: float, v_axis: float, a_axis: float, feed_max: float, programmed: bool = True):
        self.T, self.v_axis, self.a_axis, self.feed_max = float(T), float(v_axis), float(a_axis), float(feed_max)
        self.programmed = programmed


def move_tc(m, lim: Limits) -> TC:
    """The segment tpAddLine / tpAddCircle makes of a program move (planners.paths.gcode Move):
    its max velocity and acceleration as LinuxCNC's canon gives them along the move (the
    fastest axis at its bound; a circle: the bound of its plane), clamped to one period."""
    g = m.segment
    req = lim.feed_max if (m.rapid or not lim.programmed or m.feed_mm_s is None) else min(lim.feed_max, m.feed_mm_s)
    if g.kind == "line":
        worst = float(np.abs(g.direction).max())
        v_max, a_max = lim.v_axis / worst, lim.a_axis / worst
    else:
        v_max, a_max = arc_feed_limits(g, lim)
    # emccanon.cc SET_MOTION_CONTROL_MODE: G64 → PARABOLIC (tolerance P, 0 = none), G61 →
    # EXACT, G61.1 → STOP; a rapid ↔ feed change makes it STOP when the next move comes
    mode = m.path_mode
    blend = mode[0] == "blend"
    term = PARABOLIC if blend else (EXACT if mode[1] == "path" else STOP)
    tc = TC("line" if g.kind == "line" else "circle", m.line, m.rapid, g.length,
            min(lim.feed_max, v_max), min(req, v_max), a_max, term, float(mode[1]) if blend else 0.0)
    if g.kind == "line":
        tc.start, tc.end, tc.u = g.start, g.end, g.direction
    else:
        tc.arc = g
    clamp_by_length(tc, lim.T)
    return tc


def arc_feed_limits(g, lim: Limits) -> tuple[float, float]:
    """(max velocity, max acceleration) of an arc as emccanon.cc ARC_FEED gives them: the planar
    speed within √(a·√3/2 · r_eff) (the centripetal bound, r_eff = √(dr² + r_min²)) and the
    axis bound, stretched over the helix; the acceleration from the time the chord's axes and
    the spiral's length need at the axis bound."""
    r_min = min(g.radius, g.radius + g.spiral)
    r_eff = math.hypot(g.spiral / g.angle, r_min)
    v_planar = min(math.sqrt(lim.a_axis * math.sqrt(3.0) / 2.0 * r_eff), lim.v_axis)
    chord = float(np.abs(g.end - g.start).max())            # getStraightVelocity/-Acceleration
    spiral_length = math.hypot(r_min * g.angle, g.spiral)
    total = math.hypot(spiral_length, float(np.dot(g.end - g.start, g.normal)))
    v_max = total / max(chord / lim.v_axis, spiral_length / v_planar)
    a_max = total / max(chord / lim.a_axis, spiral_length / lim.a_axis)
    return v_max, a_max


def build(moves, lim: Limits):
    """(runs, ends): the program's segments, one list per stretch the motion queue holds
    between drains (a queue sync: M code, dwell, tool change; the program end), and the index
    of each run's last move."""
    runs, ends, queue = [], [], []
    for k, m in enumerate(moves):
        tc = move_tc(m, lim)
        prev = queue[-1] if queue else None
        consumed = False
        if prev is not None:
            if prev.rapid != tc.rapid:
                set_term(prev, tc, STOP)            # tp.c handleModeChange: never blend G0 ↔ G1
            consumed = handle_blend(queue, prev, tc, lim)
        if not consumed:
            finalize(prev, lim.T)
        queue.append(tc)
        optimize(queue, lim.T)
        if m.stop in ("sync", "end"):
            runs.append(queue)
            ends.append(k)
            queue = []
    if queue:
        runs.append(queue)
        ends.append(len(moves) - 1)
    return runs, ends


def handle_blend(queue: list, prev: TC, tc: TC, lim: Limits) -> bool:
    """tp.c tpHandleBlendArc: the junction prev → tc; True if a blend arc consumed prev."""
    if setup_tangent(prev, tc, lim.T, lim.a_axis) != "no_action":
        return False
    b = None
    if prev.term == PARABOLIC:                      # tpCheckBlendArcType
        if prev.kind == "line" and tc.kind == "line":
            b = tp_blend.line_line(prev, tc, lim.T, lim.v_axis, lim.a_axis)
        elif prev.kind != tc.kind:
            b = tp_blend.line_arc(prev, tc, lim.T, lim.v_axis, lim.a_axis, prev.kind == "line")
        else:
            b = tp_blend.arc_arc(prev, tc, lim.T, lim.v_axis, lim.a_axis)
    if b is not None:
        blend = blend_tc(b, prev, tc, lim.T)
        if choose_best(prev, tc, blend) == "arc":
            connect(queue, prev, tc, b)
            queue.append(blend)
            return b.consume
    choose_best(prev, tc, None)
    return False


def blend_tc(b, prev: TC, tc: TC, T: float) -> TC:
    """tp.c tpInitBlendArcFromPrev: the blend arc's segment, max velocity v_plan, final."""
    blend = TC("blend", prev.line, prev.rapid, b.radius * b.angle + b.line_length, b.v_plan, b.v_req,
               b.a_max, TANGENT, tc.tol)
    blend.arc = Arc.exact(b.start, b.center, b.binormal, b.angle, prev.line)
    blend.line_length = b.line_length
    blend.u = prev.tangent_out()
    finalize(blend, T)
    return blend


def connect(queue: list, prev: TC, tc: TC, b) -> None:
    """tc.c tcConnectBlendArc (and the line↔arc variants): trim both segments to the blend
    arc, or pop a consumed previous line; the junctions into and out of the arc are tangent."""
    if b.consume:
        queue.pop()
    elif prev.kind == "line":
        prev.end = prev.end - b.trim1 * prev.u
        prev.target = norm3(prev.end - prev.start)
    else:
        g = prev.arc
        prev.arc = Arc.exact(g.start, g.center, g.normal, g.angle - b.trim1, g.line,
                             spiral=g.spiral * ((g.angle - b.trim1) / g.angle))     # the same dr/dφ
        prev.target = prev.arc.length
    set_term(None if b.consume else prev, tc, TANGENT)
    if tc.kind == "line":
        tc.start = tc.start + b.trim2 * tc.u
        tc.target = norm3(tc.end - tc.start)
    else:
        g = tc.arc
        tc.arc = Arc.exact(g.planar_point(b.trim2), g.center, g.normal, g.angle - b.trim2, g.line,
                           spiral=g.spiral * ((g.angle - b.trim2) / g.angle))
        tc.target = tc.arc.length
