"""LinuxCNC 2.9's per-cycle motion update (tp.c ``tpRunCycle``), on a list of segments.

Each period (tp.c ``tpCalculateTrapezoidalAccel``, ``tcUpdateDistFromAccel``): the largest new
speed that can still stop at the segment's final speed, v = −a·dt/2 + √(v_f² + a(2·dx − v·dt)
+ (a·dt/2)²), capped at the segment's target speed, the acceleration clamped to ±a, the
distance advanced by the trapezoidal rule. A cycle that passes a segment end is split
(``tpHandleSplitCycle``): the time τ to the end is solved exactly and the rest of the period
runs on the next segment.

:func:`simulate`'s options, each LinuxCNC's: ``blends`` = {i: blend speed} for the parabolic
junctions i → i+1 (tp.c ``tpHandleRegularCycle``, ``tcIsBlending``, ``tpDoParabolicBlending``):
once segment i is on its final deceleration (to rest at its end) below its blend speed,
i+1 starts moving too, both at their own (halved) accelerations; the tool is at the sum of
both displacements (``trace`` = [(cycle k, i, x, x2, v, v2)] of those periods). ``stops``:
the segments that end at rest (TC_TERM_COND_STOP / EXACT): the next one starts on the next
period (tpCheckEndCondition removes a segment in the period it arrives). ``ramps``: per
segment its look-ahead final speed if it may ramp (tangent, not a rapid), else None: one that
would last less than 1/ARC_BLEND_RAMP_FREQ from its first full period on accelerates evenly
to its final speed instead (``tpActivateSegment``, ``tpCalculateRampAccel``).
"""
from __future__ import annotations

import math

import numpy as np

from planners.errors import PlanningError

MAX_CYCLES = 20_000_000
VEL_EPS = 1e-8               # tp_types.h TP_VEL_EPSILON


def simulate(L, vmax, amax, vf, T: float, length: float, blends=None, stops=(), ramps=None,
             min_run: int | None = None):
    """(s, sd, excess, trace) at every period (s, sd: arrays); s = the segments' lengths before
    the current one plus its progress (clipped to ``length``); ``excess``: the largest clipped
    speed excess at a segment end (mm/s, diagnostics). blends, stops, ramps: see the module's
    doc; without them the loop is the plain one. ``min_run`` (default MIN_RUN): the fewest
    periods at cruise speed or at full acceleration run as one numpy pass (:func:`_cruise`,
    :func:`_accelerate`), the same numbers as the loop's; more than the periods there are: the
    loop runs every one."""
    # plain floats in the per-cycle loop: a 10⁵-line program runs ~2·10⁶ passes; the
    # segment's values are read once per segment, and min()/max() are written as conditionals
    # that return what the builtins return (first argument on a tie, so a zero's sign stays)
    min_run = MIN_RUN if min_run is None else min_run
    blends, stops, n = blends or {}, set(stops), len(L)
    s_out, v_out, trace = [0.0], [0.0], []
    done_s, done_v = [], []            # arrays of the periods before s_out's (the numpy runs)
    i, x, v, base, excess = 0, 0.0, 0.0, 0.0, 0.0
    sqrt = math.sqrt
    a, Li, vfi, vmi = amax[0], L[0], vf[0], vmax[0]
    vf2 = vfi ** 2
    end = Li - 1e-12
    vb, x2, v2, blending = blends.get(0), 0.0, 0.0, False
    active, ramp = -1, False
    acc, k, try_run = 0.0, 0, True
    while k < MAX_CYCLES:
        t_left = T
        if ramps is not None and active != i:
            active, ramp = i, _ramps(ramps[i], Li - x, v, vmi)
        # a run of periods at the cruise speed or at full acceleration (most of a CAM
        # program's periods) in one numpy pass: each period's test as the loop below makes it
        if try_run and not blending and not ramp and a > 0 and vmi > 0 and (acc == 0.0 and v == vmi or acc == a):
            m = min(_run_estimate(acc == a, Li - x, v, vmi, vf2, a, T), MAX_CYCLES - k - 1)
            if m >= min_run:
                xs, vs = (_accelerate if acc == a else _cruise)(x, v, m, Li, end, vmi, vf2, a, T)
                # a run cut short: its next period is another kind, the loop's
                try_run = len(xs) == m
                if len(xs):
                    if s_out:
                        done_s.append(np.array(s_out))
                        done_v.append(np.array(v_out))
                        s_out, v_out = [], []
                    pos = base + xs
                    # min(length, pos) of each: pos grows, so only if the last one passes length
                    done_s.append(np.minimum(pos, length) if length < base + float(xs[-1]) else pos)
                    done_v.append(vs)
                    x, v = float(xs[-1]), float(vs[-1])
                    k += len(xs)
                    continue
        try_run = True
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
            if ramp and active == i and vfi >= VEL_EPS:
                acc = _ramp_acc(v, vfi, dx)
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
                if vb is not None and t_left == T:
                    # tcIsBlending: on the final deceleration (the speed is the stopping
                    # curve's, not a cap) and below the blend speed; latched
                    v_des = -half + sqrt(disc) if disc > half * half else -half
                    blending = blending or (abs(v_des - v) < VEL_EPS and acc < 0 and v < vb)
                    if blending:
                        x2, v2 = _next_step(x2, v2, L[i + 1], vmax[i + 1], amax[i + 1], T)
                break
            tau = _arrival(v, acc, dx, t_left)
            v_end = v + acc * tau
            if i == n - 1:
                s_out.append(length)
                v_out.append(0.0)
                return (np.concatenate(done_s + [np.array(s_out)]), np.concatenate(done_v + [np.array(v_out)]),
                        excess, trace)
            if v_end - vfi > excess:
                excess = v_end - vfi
            base += Li
            i += 1
            if vb is not None:
                # a parabolic end: the next segment moves on from where the blend took it, this
                # period counted (tpHandleSplitCycle gives it no extra time)
                x, v = _next_step(x2, v2, L[i], vmax[i], amax[i], T) if blending else (x2, v2)
                t_left, x2, v2, blending = 0.0, 0.0, 0.0, False
            else:
                v = vfi if vfi < v_end else v_end
                x = 0.0
                t_left = 0.0 if i - 1 in stops else t_left - tau
            a, Li, vfi, vmi = amax[i], L[i], vf[i], vmax[i]
            vf2 = vfi ** 2
            end = Li - 1e-12
            vb = blends.get(i)
        k += 1
        pos = base + x
        s_out.append(length if length < pos else pos)
        v_out.append(v)
        if blending:
            trace.append((k, i, x, x2, v, v2))
    raise PlanningError(f"trapezoid: no arrival after {MAX_CYCLES} cycles (a limit too small?)")


# Periods below which a run stays in the loop (a numpy pass costs as much as a few dozen loop
# periods; docs/TUNING.md, issue 33)
MIN_RUN = 16
MAX_RUN = 1 << 15           # periods per numpy pass: its arrays stay in cache


def _run_estimate(accelerating: bool, dx: float, v: float, vmax: float, vf2: float, a: float, T: float) -> int:
    """Periods (a slight over-estimate) before a run at cruise speed (or, ``accelerating``,
    at full acceleration) ends: where the stopping curve to the final speed √vf2 takes over,
    or (accelerating) where vmax is reached or half the distance left is covered."""
    if accelerating:
        to_vmax = (vmax - v) / (a * T)
        to_half = (math.sqrt(v * v + a * dx) - v) / (a * T)      # v·t + a·t²/2 = dx/2
        m = min(to_vmax, to_half)
    else:
        m = (dx - (vmax * vmax - vf2) / (2 * a)) / (vmax * T)
    return min(int(m) + 2, MAX_RUN) if m > 0 else 0


def _cruise(x: float, v: float, m: int, Li: float, end: float, vmax: float, vf2: float, a: float, T: float):
    """The first of up to ``m`` periods at cruise speed v = vmax from progress x that the loop
    of :func:`simulate` would run the same way: (progress, speed) after each (empty if the
    first is not one). Every operation as the loop's, in its order (the same floats)."""
    disp = 0.5 * (v + v) * T
    xs = np.empty(m + 1)
    xs.fill(disp)
    xs[0] = x
    np.add.accumulate(xs, out=xs)         # sequential sums: x += disp period by period
    half = 0.5 * a * T
    sqrt = math.sqrt

    def cruises(j: int) -> bool:
        # the stopping curve allows at least vmax (capped to it: acceleration 0), short of the end
        x = float(xs[j])
        disc = vf2 + a * (2 * (Li - x) - v * T) + half * half
        return disc > 0 and -half + sqrt(disc) >= vmax and x + disp < end

    c = _leading(cruises, m)
    vs = np.empty(c)
    vs.fill(v)
    return xs[1:c + 1], vs


def _accelerate(x: float, v: float, m: int, Li: float, end: float, vmax: float, vf2: float, a: float, T: float):
    """As :func:`_cruise`, periods at full acceleration a from (x, v): the speed the stopping
    curve allows, capped to vmax, at least a·T above v."""
    vs = np.empty(m + 1)
    vs.fill(a * T)
    vs[0] = v
    np.add.accumulate(vs, out=vs)         # v_new = v + acc·T, acc = a
    xs = np.empty(m + 1)
    xs[0] = x
    np.multiply(vs[:-1] + vs[1:], 0.5, out=xs[1:])
    xs[1:] *= T                           # disp = 0.5·(v + v_new)·T
    np.add.accumulate(xs, out=xs)
    half = 0.5 * a * T
    sqrt = math.sqrt

    def accelerates(j: int) -> bool:
        x, v, v_next = float(xs[j]), float(vs[j]), float(vs[j + 1])
        disc = vf2 + a * (2 * (Li - x) - v * T) + half * half
        if not disc > 0:
            return False
        v_new = -half + sqrt(disc)
        v_new = 0.0 if 0.0 > v_new else v_new
        v_new = vmax if vmax < v_new else v_new
        return (v_new - v) / T >= a and x + 0.5 * (v + v_next) * T < end

    c = _leading(accelerates, m)
    return xs[1:c + 1], vs[1:c + 1]


def _leading(holds, m: int) -> int:
    """How many of holds(0), …, holds(m − 1) hold before the first that does not, for a
    ``holds`` true then false (a run's test is monotone: as the progress and the speed grow,
    the stopping curve's speed falls and the end nears). The estimate of m ends the run near
    m, so the last periods are tried first."""
    lo, hi = 0, m                     # holds(lo − 1) (or lo = 0), not holds(hi) (or hi = m)
    for j in range(m - 1, max(m - 4, 0) - 1, -1):
        if holds(j):
            return j + 1
        hi = j
    while lo < hi:
        mid = (lo + hi) // 2
        if holds(mid):
            lo = mid + 1
        else:
            hi = mid
    return lo


RAMP_S = 1.0 / 100.0        # 1 / [TRAJ] ARC_BLEND_RAMP_FREQ default (initraj.cc)


def _ramps(finalvel, dx: float, v: float, vmax: float) -> bool:
    """tp.c tpActivateSegment: a tangent segment ramps if it would last less than RAMP_S."""
    if finalvel is None or dx == 0:
        return False
    den = v + min(finalvel, vmax)
    return den > 0 and 2.0 * dx / den < RAMP_S


def _ramp_acc(v: float, vf: float, dx: float) -> float:
    """tp.c tpCalculateRampAccel: the constant acceleration that reaches vf at the end."""
    v_avg = (v + vf) / 2.0
    dt = max(dx / v_avg, 1e-16) if v_avg > VEL_EPS else 1e-16
    return (vf - v) / dt


def _arrival(v: float, acc: float, dx: float, t_left: float) -> float:
    """τ in [0, t_left] at which a segment's end, dx ahead, is reached under the cycle's
    constant acceleration: v·τ + acc·τ²/2 = dx."""
    if abs(acc) * t_left < 1e-12 * (1.0 if 1.0 > v else v):
        tau = dx / v if v > 0 else t_left
    else:
        r = v * v + 2 * acc * dx
        tau = (-v + math.sqrt(0.0 if 0.0 > r else r)) / acc
    if 0.0 > tau:
        tau = 0.0
    if t_left < tau:
        tau = t_left
    return tau


def _next_step(x: float, v: float, L: float, vmax: float, a: float, T: float):
    """One period of the next segment during a parabolic blend (tpUpdateBlend →
    tpUpdateCycle(nexttc, NULL): no segment after it, so its final speed is 0); its progress
    is held at its end (tcUpdateDistFromAccel)."""
    half = 0.5 * a * T
    disc = a * (2 * (L - x) - v * T) + half * half
    v_new = -half + math.sqrt(disc) if disc > half * half else -half
    v_new = min(max(v_new, -vmax), vmax)                  # saturate(maxnewvel, target)
    acc = min(max((v_new - v) / T, -a), a)
    v_next = v + acc * T
    if v_next < 0.0:
        return (L if L - x < v * T else x), 0.0
    return min(x + 0.5 * (v + v_next) * T, L), v_next
