"""trapezoid on a G-code program: LinuxCNC's motion queue (planners.trapezoid.queue) run cycle by cycle
(planners.trapezoid.cycle), and the geometry the tool follows.

The geometry is the queue's segments laid end to end (lines, circles, blend arcs with the
line they consumed); a parabolic blend (tp.c ``tpDoParabolicBlending``) moves the tool by the
sum of two segments' displacements, off both: there the geometry is the polyline through the
positions of the blend's periods, as LinuxCNC commands them.
"""
from __future__ import annotations

import math

import numpy as np

from planners.trapezoid import queue as Q
from planners.linuxcnc import IO_CYCLE_S, TASK_CYCLE_S  # the sim config's cycles
from planners.paths.base import norm3
from planners.paths.gcode.reader import is_sync
from planners.paths.segments import Arc, Line
from planners.trapezoid.cycle import simulate

TINY = 1e-9                  # mm: a piece or polyline step shorter than this is dropped


def queue_arrays(runs, lim: Q.Limits):
    """Per segment of the flattened runs: (segments, L, target speed, acceleration, final
    speed, {i: blend speed} of the parabolic junctions, the segments ending at rest, run-end
    indices). A run's last segment ends at rest: the queue drains there."""
    tcs = [tc for r in runs for tc in r]
    ends = set(np.cumsum([len(r) for r in runs]) - 1)
    L = [tc.target for tc in tcs]
    vt = [min(tc.reqvel, tc.maxvel, lim.feed_max) for tc in tcs]     # tpGetRealTargetVel
    acc = [Q.tangential_acc(tc) for tc in tcs]
    vf, blends, stops = [0.0] * len(tcs), {}, []
    for i, tc in enumerate(tcs):
        if i in ends or tc.term in (Q.STOP, Q.EXACT):
            stops.append(i)
        elif tc.term == Q.TANGENT:                   # tpGetRealFinalVel
            vf[i] = min(tc.finalvel, vt[i], vt[i + 1])
        else:
            blends[i] = Q.blend_velocities(tc, tcs[i + 1])[0]
    return tcs, L, vt, acc, vf, blends, stops, sorted(ends)


def pieces(tc) -> list:
    """The geometry of a queued segment, its lengths summing to tc.target."""
    if tc.kind == "line":
        return [Line.exact(tc.start, tc.end, tc.u, tc.line)] if tc.target > TINY else []
    if tc.kind == "circle":
        return [tc.arc]
    out = []
    if tc.line_length > TINY:
        a = tc.arc.start
        out.append(Line.exact(a - tc.line_length * tc.u, a, tc.u, tc.line))
    return out + [tc.arc]


def cut(segs, a: float, b: float) -> list:
    """The part of segments laid end to end between arc lengths a ≤ b."""
    out, s0 = [], 0.0
    for g in segs:
        lo, hi = max(a - s0, 0.0), min(b - s0, g.length)
        if hi - lo > TINY:
            out.append(g if (lo == 0.0 and hi == g.length) else _sub(g, lo, hi))
        s0 += g.length
    return out


def _sub(g, lo: float, hi: float):
    """Segment g from arc length lo to hi."""
    if g.kind == "line":
        return Line.exact(g.start + lo * g.direction, g.start + hi * g.direction, g.direction, g.line)
    h = Arc.__new__(Arc)
    h.normal, h.line, h.spiral = g.normal, g.line, 0.0
    if g.spiral:
        # a spiral's angle is not proportional to its length: the angles at lo and hi; the rest
        # keeps the same dr/dφ and rise per radian
        p0, p1 = (float(x) for x in g._measure.phi_of(np.array([lo, hi])))
        f0, f1 = p0 / g.angle, p1 / g.angle
        h.start = g.planar_point(p0) + f0 * g.rise * g.normal
        h.spiral = g.spiral * (f1 - f0)
    else:
        f0, f1 = lo / g.length, hi / g.length
        h.start = _arc_at(g, f0 * g.angle)
    h.center = g.center + f0 * g.rise * g.normal
    h.angle, h.rise = (f1 - f0) * g.angle, (f1 - f0) * g.rise
    h._derive()
    return h


def _arc_at(g, phi: float):
    return g.center + math.cos(phi) * g.a + math.sin(phi) * g.b + (phi / g.angle) * g.rise * g.normal


def point(segs, x: float):
    """(point, unit tangent) at arc length x along segments laid end to end."""
    s0 = 0.0
    for g in segs:
        if x <= s0 + g.length or g is segs[-1]:
            t = min(max(x - s0, 0.0), g.length)
            if g.kind == "line":
                return g.start + t * g.direction, g.direction
            if g.spiral:
                P, d = (v[0] for v in g.eval(np.array([t]), 1))
                return P, d / norm3(d)
            d = g._tangent(t / g.length * g.angle)
            return _arc_at(g, t / g.length * g.angle), d / norm3(d)
        s0 += g.length
    raise ValueError("point of an empty segment list")


def run_program(prog, lim: Q.Limits):
    """(geometry, s, sd, {move index: arc length where its queue run ends}, info) of a
    program as LinuxCNC's tp runs it (a queue sync's wait goes at its run's end)."""
    runs, ends = Q.build(prog.moves, lim)
    tcs, L, vt, acc, vf, blends, stops, run_ends = queue_arrays(runs, lim)
    cum = np.concatenate([[0.0], np.cumsum(L)])
    ramps = [tc.finalvel if tc.term == Q.TANGENT and not tc.rapid else None for tc in tcs]
    s, sd, excess, trace = simulate(L, vt, acc, vf, lim.T, float(cum[-1]), blends, stops, ramps)
    geometry, s, sd, tc_start = blended_geometry([pieces(tc) for tc in tcs], s, sd, trace, cum)
    info = {"queue_segments": len(tcs), "blend_arcs": sum(tc.kind == "blend" for tc in tcs),
            "consumed_lines": sum(tc.kind == "blend" and tc.line_length > 0 for tc in tcs),
            "parabolic_blends": len(blends), "exact_stops": len(stops) - len(run_ends),
            "tangent_kinks": sum(tc.term == Q.TANGENT and tc.kind != "blend" and tc.kink_red > 0 for tc in tcs),
            "length_clamped": sum(tc.clamped and tc.maxvel < min(tc.reqvel, lim.feed_max) for tc in tcs),
            "boundary_speed_excess_mm_s": float(excess)}
    run_end_s = {ends[r]: float(tc_start[i + 1]) for r, i in enumerate(run_ends)}
    return geometry, s, sd, run_end_s, info


def blended_geometry(segs_of, s, sd, trace, cum):
    """(geometry, s, sd, start of each segment's kept part in the new s): the segments' pieces
    end to end (``cum``: where each segment starts in the simulated s), each parabolic blend's
    periods (``trace``) as a polyline: a segment is kept from where the blend into it ended to
    where the blend out of it began (its first and last samples on its own)."""
    blend = {k: (i, x, x2, v, v2) for k, i, x, x2, v, v2 in trace}
    n = len(segs_of)
    idx = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, n - 1)
    reg = np.ones(len(s), bool)
    reg[list(blend)] = False
    # a segment's progress grows with time: its first and last samples on its own
    ri, rx = idx[reg], (s - cum[idx])[reg]
    k0, k1 = np.searchsorted(ri, np.arange(n), "left"), np.searchsorted(ri, np.arange(n), "right") - 1
    lo = np.where(k0 < len(ri), rx[np.minimum(k0, len(ri) - 1)], np.inf)
    hi = np.where(k1 >= 0, rx[np.maximum(k1, 0)], 0.0)
    into = {blend[k][0] + 1 for k in blend}
    out_of = {blend[k][0] for k in blend}
    # Python floats in the per-segment loop (numpy scalars cost several times more an operation)
    lo_, hi_, cum_ = lo.tolist(), hi.tolist(), cum.tolist()
    a = [lo_[i] if i in into else 0.0 for i in range(n)]
    b = [hi_[i] if i in out_of else cum_[i + 1] - cum_[i] for i in range(n)]
    geometry, start, s_new, sd_new = [], [], s.copy(), sd.copy()
    length = 0.0
    # the trace's periods blend by blend: (period k, x, x2, v, v2) columns of each blend's rows
    ks = sorted(blend)
    rows = np.array([(k,) + blend[k][1:] for k in ks]).reshape(-1, 5)
    of = np.array([blend[k][0] for k in ks], int)
    cuts = np.searchsorted(of, np.arange(n + 1))
    for i in range(n):
        start.append(length)
        part = cut(segs_of[i], a[i], b[i])
        geometry += part
        length += sum(g.length for g in part)
        if i in out_of:
            last = point(segs_of[i], b[i])[0]
            k, x, x2, v, v2 = rows[cuts[i]:cuts[i + 1]].T
            k = k.astype(int)
            P1, T1 = points(segs_of[i], x)
            P2, T2 = points(segs_of[i + 1], x2)
            P = P1 + P2 - point(segs_of[i + 1], 0.0)[0]
            length, last, s_new[k] = _steps(geometry, last, P, length, segs_of[i][-1].line)
            sd_new[k] = _norms(v[:, None] * T1 + v2[:, None] * T2)
            length, _ = _step(geometry, last, point(segs_of[i + 1], a[i + 1])[0], length, segs_of[i][-1].line)
    start = np.array(start + [length])
    # within its segment's kept part (a piece under TINY was dropped from it)
    ir = idx[reg]
    s_new[reg] = np.minimum(start[ir] + (s[reg] - cum[ir]) - np.array(a)[ir], start[ir + 1])
    s_new[-1] = length
    return geometry, np.minimum(s_new, length), sd_new, start


def _steps(geometry: list, last, P: np.ndarray, length: float, line):
    """_step to each row of P in turn: (length, last, the length after each step)."""
    D = P - np.concatenate([last[None], P[:-1]])
    d = _norms(D)
    if not (d > TINY).all():          # a step dropped: the next one starts where it was
        lengths = np.empty(len(P))
        for r, p in enumerate(P):
            length, last = _step(geometry, last, p, length, line)
            lengths[r] = length
        return length, last, lengths
    U = D / d[:, None]
    geometry += [Line.exact(s, e, u, line) for s, e, u in zip(np.concatenate([last[None], P[:-1]]), P, U)]
    lengths = np.cumsum(np.r_[length, d])[1:]     # sequential sums, as length + d step by step
    return float(lengths[-1]), P[-1], lengths


def _norms(V: np.ndarray) -> np.ndarray:
    """norm3 of each row of V (n, 3), its operations in its order."""
    x, y, z = V.T
    return np.sqrt(x * x + y * y + z * z)


def points(segs, xs: np.ndarray):
    """:func:`point` at each arc length of ``xs``: (points (n, 3), unit tangents (n, 3)), the
    same numbers (a circle's sine and cosine by math, as point's; a spiral by point itself)."""
    P, U = np.empty((len(xs), 3)), np.empty((len(xs), 3))
    free = np.ones(len(xs), bool)
    s0 = 0.0
    for g in segs:
        on = free & (xs <= s0 + g.length) if g is not segs[-1] else free.copy()
        free &= ~on
        if not on.any():
            s0 += g.length
            continue
        t = xs[on] - s0
        t = np.where(0.0 > t, 0.0, t)                 # min(max(t, 0.0), g.length) as point's
        t = np.where(g.length < t, g.length, t)
        if g.kind == "line":
            P[on], U[on] = g.start + t[:, None] * g.direction, g.direction
        elif g.spiral:
            P[on], U[on] = zip(*(point([g], x) for x in t.tolist()))
        else:
            phi = t / g.length * g.angle
            c = np.array([math.cos(f) for f in phi.tolist()])[:, None]
            sn = np.array([math.sin(f) for f in phi.tolist()])[:, None]
            P[on] = g.center + c * g.a + sn * g.b + ((phi / g.angle) * g.rise)[:, None] * g.normal
            d = (g.angle / g.length) * (-sn * g.a + c * g.b + (g.rise / g.angle) * g.normal)   # Arc._tangent
            U[on] = d / _norms(d)[:, None]
        s0 += g.length
    return P, U


def _step(geometry: list, last, p, length: float, line):
    """A polyline step from ``last`` to ``p`` (none if shorter than TINY): (length, last)."""
    d = norm3(p - last)
    if d <= TINY:
        return length, last
    geometry.append(Line.exact(last, p, (p - last) / d, line))
    return length + d, p


# M codes that are commands to LinuxCNC's io task: M7 mist on, M8 flood on, M9 both off; M6 is
# two, EMC_TOOL_START_CHANGE and EMC_TOOL_LOAD (interp_convert.cc convert_tool_change:
# START_CHANGE, then emccanon.cc CHANGE_TOOL)
IO_COMMANDS = {7: 1, 8: 1, 9: 2, 6: 2}
# M codes whose commands task hands to motion: spindle on/off (M3, M4, M5), M6's spindle stop
# (convert_tool_change: STOP_SPINDLE_TURNING), an orient (M19), an output set now (M64, M65:
# EMC_MOTION_SET_DOUT) and a program stop's pause and its resume (M0, M1: emcTrajPause,
# emcTrajResume); an S word is one more (SET_SPINDLE_SPEED)
MOTION_MESSAGES = {3: 1, 4: 1, 5: 1, 6: 1, 19: 1, 64: 1, 65: 1, 0: 2, 1: 2}


def move_waits(prog, T: float) -> dict:
    """{move index: seconds at rest after it} for a program's queue syncs (servo period ``T``).

    A dwell waits its P. An io command (coolant, tool change) waits for LinuxCNC's io task,
    which looks at its command buffer once per io cycle (ioControl.cc main loop,
    esleep(emc_io_cycle_time)) and then sleeps a full cycle; task sends the next one only when
    the last is done (taskclass.cc sendCommand): the first command waits on average half a
    cycle (a random phase: LinuxCNC's own spread run to run), each further one a whole cycle.
    A tool change to another tool keeps io busy one cycle more: EMC_TOOL_LOAD raises
    iocontrol.0.tool-change and reports RCS_EXEC; the looped-back tool-changed is read at the
    top of the next cycle (read_tool_inputs), only then RCS_DONE. Same tool: no handshake
    (the EMC_TOOL_LOAD case). So M6: 0.5 + 1 + 1 = 2.5 cycles. A T word's EMC_TOOL_PREPARE
    waits for io only, not motion (emctaskmain.cc emcTaskCheckPreconditions): it goes out while
    the move before still runs and is taken as done by its end (not so after a move shorter than
    two io cycles, or one the naive-CAM join holds back). The mean is used (same inputs,
    same outputs).

    Task's own time at every sync comes on top: it sees the queue drained at its next cycle
    (WAITING_FOR_MOTION_AND_IO), and each message it then sends to motion — the next move, a
    spindle speed or spindle command, a pause and its resume — waits for the servo thread to take
    it (usrmotintf.cc usrmotWriteEmcmotCommand polls for the echo): one task cycle and one servo
    period, one servo period more per message to motion, half a task cycle more per dwell with
    P > 0 (its timeout is polled once a task cycle: emcTaskExecute WAITING_FOR_DELAY). An M0/M1
    program stop lasts as long as the operator and adds only its two messages (the oracle's
    runner leaves its pause out). Nothing waits after the last move (the span measured ends there)."""
    per_move: dict[int, list] = {}
    for e in prog.events:
        if 0 < e.index <= len(prog.moves):
            per_move.setdefault(e.index - 1, []).append(e)
    # the tool in the spindle after each tool change (io starts with none: tool 0)
    handshake, spindle = set(), 0
    for e in prog.events:
        if e.kind == "tool":
            if e.value != spindle:
                handshake.add(id(e))
            spindle = e.value
    waits = {}
    for mi, evs in per_move.items():
        if mi == len(prog.moves) - 1 or not any(is_sync(e) for e in evs):
            continue
        n_io = sum(IO_COMMANDS.get(e.value, 0) for e in evs if e.kind == "m")
        n_hs = sum(id(e) in handshake for e in evs)
        dwells = [float(e.value) for e in evs if e.kind == "dwell"]
        io = 0.5 * IO_CYCLE_S + (n_io - 1 + n_hs) * IO_CYCLE_S if n_io else 0.0
        n_motion = sum(MOTION_MESSAGES.get(e.value, 0) for e in evs if e.kind == "m") + \
            sum(e.kind == "speed" for e in evs)
        task = TASK_CYCLE_S + (1 + n_motion) * T + 0.5 * TASK_CYCLE_S * sum(d > 0 for d in dwells)
        waits[mi] = sum(dwells) + io + task
    return waits


def insert_waits(s: np.ndarray, sd: np.ndarray, at: list, T: float):
    """s, sd with round(wait/T) samples at rest at each (arc length, wait) of ``at``, in order
    (the profile reaches the stop, stays, then runs on as simulated)."""
    if not at:
        return s, sd
    parts_s, parts_v, j0 = [], [], 0
    for pos, w in sorted(at):
        j = int(np.searchsorted(s, pos - 1e-9))
        n = int(round(w / T))
        parts_s += [s[j0:j], np.full(n, pos)]
        parts_v += [sd[j0:j], np.zeros(n)]
        j0 = j
    parts_s.append(s[j0:])
    parts_v.append(sd[j0:])
    return np.concatenate(parts_s), np.concatenate(parts_v)
