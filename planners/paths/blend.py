"""G64 corner blending, the geometry every planner shares.

Corner blending follows the idea of LinuxCNC 2.9's tangent-arc blends
(``src/emc/tp/blendmath.c``: ``blendInit3FromLineLine``, ``blendFindPoints3``, …): the
corner between two lines is replaced by the circular arc tangent to both, as large as
the tolerance allows, but using at most half of each adjoining line so that neighbouring
blends never overlap. The blended path is then tangent-continuous there. What is *not*
blended (documented limits): corners touching an arc segment (kept as exact stops, as
LinuxCNC does when a blend arc does not fit), and near-reversals (turn > π − 1e-6 rad).

With ``speed`` (a :class:`BlendSpeed`: the moves' feeds and the machine's axis limits) the
arc is sized to the speed as LinuxCNC 2.9's tp sizes it (blendmath.c
``blendInit3FromLineLine``, ``blendParamKinematics``, ``blendComputeParameters``; tc.c
``tcFindBlendTolerance``; :func:`speed_blends`) instead of "as large as fits": at most a quarter of each line as
tolerance, half of each line as room, and a radius only as large as the corner speed needs.
Such an arc carries ``v_cap`` (LinuxCNC's blend maxvel v_plan). With ``speed``, line↔arc
corners are blended too (:func:`line_arc_blend`; arc↔arc corners and helices stay exact stops); a
spiral arc is sized on LinuxCNC's approximating circle, its blend being the exact tangent circle of
that radius (planners.paths.spiral.tangent_blend_on_spiral).

Size: ~420 lines: the line–line blends (column-wise over 10⁵ corners), LinuxCNC's line↔arc
blends and the assembly of the trimmed segments share one set of trim tables.
"""
from __future__ import annotations

import math

import numpy as np

from planners.paths.base import CORNER_ANGLE, PathError, cross3, norm3
from planners.paths.segments import Arc, Line
from planners.paths.spiral import approximating_circle, tangent_blend_on_spiral

REVERSAL_ANGLE = math.pi - 1e-6


class BlendSpeed:
    """What LinuxCNC's blend sizing needs: per segment the requested speed (min(F, F_max);
    rapids F_max) and the line's own velocity limit (tc->maxvel), and the X/Y/Z axis
    velocity and acceleration limits (equal on every axis here)."""

    def __init__(self, req, maxvel, v_axis: float, a_axis: float):
        self.req, self.maxvel = list(req), list(maxvel)
        self.v_axis, self.a_axis = float(v_axis), float(a_axis)


def _plane_bound(binormal, bound: float) -> float:
    """blendmath.c calculateInscribedDiameter with one bound on every axis: the largest
    magnitude of a vector in the plane ⊥ ``binormal`` keeping each axis within ``bound``."""
    scale = max(math.sqrt(max(1.0 - float(b) * float(b), 0.0)) for b in binormal)
    return bound / max(scale, 1e-300)


def speed_blends(U1, U2, n1, n2, tol, v1, v2, mv1, mv2, v_axis: float, a_axis: float):
    """LinuxCNC's line–line blend arcs, one row per corner: (R, d, deviation, turn φ, v_plan).

    Follows blendmath.c blendInit3FromLineLine / blendParamKinematics / blendComputeParameters
    (planner type 0, feed override scale 1), column-wise (a CAM program has 10⁵ corners).
    U1, U2: unit directions in/out; n1, n2: the lines' lengths; tol: G64 P (inf: none, a
    quarter of a line); v1, v2: requested speeds; mv1, mv2: the lines' own velocity limits.
    θ is half the interior angle, φ = π − 2θ the turn. The room on each line is half of it:
    LinuxCNC's min(what is left of the previous line, half its length) is always the half,
    since the blend before took at most the other half.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        # tangent (θ = π/2) and reversed (θ = 0) corners give inf/nan here: blend_corners
        # skips them before reading their row
        return _speed_blends(U1, U2, n1, n2, tol, v1, v2, mv1, mv2, v_axis, a_axis)


def _speed_blends(U1, U2, n1, n2, tol, v1, v2, mv1, mv2, v_axis, a_axis):
    dot = np.einsum("ij,ij->i", U1, U2)
    theta = 0.5 * np.arccos(np.clip(-dot, -1.0, 1.0))
    phi = np.pi - 2.0 * theta
    # tc.c tcFindBlendTolerance: no P → a quarter of the line; never more than a quarter of either
    fin = np.isfinite(tol)
    T = np.minimum.reduce([np.where(fin, tol, 0.25 * n1), np.where(fin, tol, 0.25 * n2), 0.25 * n1, 0.25 * n2])
    bn = _cross(U1, U2)
    bn /= _norms(bn)[:, None]
    # blendmath.c calculateInscribedDiameter with one bound on every axis
    scale = np.sqrt(np.maximum(1.0 - bn * bn, 0.0)).max(axis=1)
    a_max = a_axis / scale
    a_n = a_max * math.sqrt(1.0 - 0.25)                  # BLEND_ACC_RATIO_NORMAL
    v_goal = np.maximum(np.minimum(v1, mv1), np.minimum(v2, mv2))   # tcGetMaxTargetVel, scale 1
    # blendParamKinematics: the "altitude" speed of the velocity triangle (lines only)
    c = np.cos(np.minimum(phi, np.pi * 0.49))
    vm1, vm2 = np.minimum(mv1, mv2 / c), np.minimum(mv2, mv1 / c)
    base = _norms(U2 * vm2[:, None] - U1 * vm1[:, None])
    v_alt = np.where(base > 0, vm1 * vm2 * np.sin(phi) / np.where(base > 0, base, 1.0), 0.0)
    v_goal = np.minimum(v_goal, np.maximum(v_alt, v_axis / scale))
    # blendComputeParameters
    d_tol = np.cos(theta) * T / (1.0 - np.sin(theta))
    d_geom = np.minimum.reduce([0.5 * n1, 0.5 * n2, d_tol])
    R_geom = np.tan(theta) * d_geom
    v_plan = np.minimum(np.sqrt(a_n * R_geom), v_goal)
    a_par = 0.5 * a_max
    s_blend = np.minimum(np.sqrt(2.0 * a_par * d_geom), v_plan) / a_par * v_plan
    R_blend = np.minimum(s_blend / phi, R_geom)
    R = np.maximum(v_plan * v_plan / a_n, R_blend)
    d = R / np.tan(theta)
    dev = R / np.sin(theta) - R                          # centre to corner minus the radius
    return R, d, dev, phi, v_plan


def _blend_params(theta: float, binormal, L1, L2, nominal1, nominal2, tol, v1: float, v2: float,
                  v_axis: float, a_axis: float):
    """(R_plan, v_plan, tolerance) of blendParamKinematics + blendComputeParameters for a half
    interior angle θ with an arc on one side (no altitude speed); v1, v2: each move's
    tcGetMaxTargetVel. speed_blends does the same steps for two lines, column-wise."""
    phi = math.pi - 2.0 * theta
    T1 = tol if math.isfinite(tol) else 0.25 * nominal1
    T2 = tol if math.isfinite(tol) else 0.25 * nominal2
    T = min(T1, T2, 0.25 * nominal1, 0.25 * nominal2)
    a_max = _plane_bound(binormal, a_axis)
    a_n = a_max * math.sqrt(1.0 - 0.25)
    v_goal = min(max(v1, v2), _plane_bound(binormal, v_axis))
    d_tol = math.cos(theta) * T / (1.0 - math.sin(theta))
    d_geom = min(L1, L2, d_tol)
    R_geom = math.tan(theta) * d_geom
    v_plan = min(math.sqrt(a_n * R_geom), v_goal)
    a_par = 0.5 * a_max
    s_blend = min(math.sqrt(2.0 * a_par * d_geom), v_plan) / a_par * v_plan
    R_blend = min(s_blend / phi, R_geom)
    return max(v_plan * v_plan / a_n, R_blend), v_plan, T


def _unit(v):
    v = np.asarray(v, float)
    return v / norm3(v)


def arc_tangent(g, at_end: bool):
    """Unit tangent of a planar arc at its start or end (direction of travel)."""
    if g.spiral:
        return g.tangent_out() if at_end else g.tangent_in()
    p = g.end if at_end else g.start
    return _unit(cross3(g.normal, p - g.center))


def line_arc_blend(line, arc, line_room: float, arc_angle: float, line_first: bool, tol: float,
                   v_line: float, v_arc: float, v_axis: float, a_axis: float):
    """LinuxCNC's blend arc between a line and a planar circular arc, or None (no blend).

    blendmath.c blendInit3FromLineArc / blendInit3FromArcLine (convexity, φ_max, the reduced
    θ and the room on the circle), blendComputeParameters, then blendLineArcPostProcess /
    blendArcLinePostProcess (the arc of radius R_plan tangent to both, the tolerance
    re-checked; tp.c: the trim angle on the circle at most φ_max). ``line_room``: what is
    left of the line before the corner (LinuxCNC's target); ``arc`` as it is left (trimmed).
    Returns (R, line trim, arc trim angle, blend centre, binormal, v_plan, deviation).
    """
    if arc.rise != 0.0:
        return None                                   # a helix: not handled here, exact stop
    if line_first:
        u1, u2, P = line.direction, arc_tangent(arc, False), line.end
    else:
        u1, u2, P = arc_tangent(arc, True), line.direction, line.start
    dot = float(np.dot(u1, u2))
    theta_tan = 0.5 * math.acos(max(-1.0, min(1.0, -dot)))
    if math.pi / 2 - theta_tan < 1e-6 or theta_tan < 1e-6:
        return None                                   # blendGeom3Init: tangent, or a reversal
    binormal = _unit(cross3(u1, u2))
    if abs(abs(float(np.dot(binormal, arc.normal))) - 1.0) > 1e-9:
        return None                                   # tp.c: not coplanar → no arc blend
    # a spiral is sized on LinuxCNC's circle through P (findSpiralApproximation)
    C, r = approximating_circle(arc, not line_first) if arc.spiral else (arc.center, arc.radius)
    if line_first:   # arcConvexTest(center2, P, u_tan1, reverse), φ2_max = min(angle/3, …)
        convex = not (float(np.dot(P - C, u1)) < 0)
        phi_max = min(arc_angle / 3.0, theta_tan if convex else math.pi / 2)
    else:            # arcConvexTest(center1, P, u_tan2), φ1_max = min(2·angle/3, …)
        convex = float(np.dot(P - C, u2)) < 0
        phi_max = min(arc_angle * 2.0 / 3.0, theta_tan if convex else math.pi / 2)
    theta = min(theta_tan, theta_tan - phi_max / 4.0) if convex else theta_tan
    L_arc = math.sin(phi_max / 4.0) * r if convex else phi_max * r
    L_line = min(line_room, 0.5 * line.length) if line_first else 0.5 * line.length
    L1, L2 = (L_line, L_arc) if line_first else (L_arc, L_line)
    n1, n2 = (line.length, arc.length) if line_first else (arc.length, line.length)
    v1, v2 = (v_line, v_arc) if line_first else (v_arc, v_line)
    R, v_plan, T = _blend_params(theta, binormal, L1, L2, n1, n2, tol, v1, v2, v_axis, a_axis)
    if not (R >= 1e-12 and R * (math.pi - 2 * theta) >= 1e-6):
        return None
    # the centre: R from the line on the turn's side (x along the line from P), r ∓ R from C
    d = (-R if convex else R) + r
    u = line.direction
    n = _unit(cross3(binormal, u))
    rc = C - P
    c_u, c_n = float(np.dot(rc, u)), float(np.dot(rc, n))
    k = c_u * c_u + (R - c_n) ** 2 - d * d             # x² − 2·c_u·x + k = 0
    disc = c_u * c_u - k
    if disc < 0:
        return None
    x = min((c_u + math.sqrt(disc), c_u - math.sqrt(disc)), key=abs)   # LinuxCNC: the smaller |root|
    if (x > 0) if line_first else (x < 0):
        return None                                   # the tangent point must lie on the line
    centre = P + x * u + R * n
    trim = math.acos(max(-1.0, min(1.0, float(np.dot(_unit(P - C), _unit(centre - C))))))
    if arc.spiral:
        exact = tangent_blend_on_spiral(arc, P, n, binormal, R, trim, not line_first)
        if exact is None:
            return None
        trim, centre = exact
        x = float(np.dot(centre - P, u))
        if (x > 0) if line_first else (x < 0):
            return None
    dev = norm3(centre - P) - R
    if dev > T:
        return None
    if trim > phi_max or trim >= arc_angle or abs(x) >= L_line:
        return None
    return R, abs(x), trim, centre, binormal, v_plan, dev


def _norms(V: np.ndarray) -> np.ndarray:
    """norm3 of each row: √(x·x + y·y + z·z), summed in that order."""
    return np.sqrt(V[:, 0] * V[:, 0] + V[:, 1] * V[:, 1] + V[:, 2] * V[:, 2])


def _cross(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """cross3 of each row pair."""
    return np.column_stack([A[:, 1] * B[:, 2] - A[:, 2] * B[:, 1], A[:, 2] * B[:, 0] - A[:, 0] * B[:, 2],
                            A[:, 0] * B[:, 1] - A[:, 1] * B[:, 0]])


def blend_corners(segments, tolerances, speed: BlendSpeed | None = None):
    """Round the line–line corners whose tolerance is not None.

    ``tolerances[i]`` governs the corner between segments i and i+1: None → exact stop,
    a number p > 0 → an arc within p mm of the corner, inf → an arc limited only by room
    (with ``speed``: sized to the speed as LinuxCNC does, see the module's doc).
    Returns (new segments, list of (corner index, deviation mm) for each blended corner).
    """
    segs = list(segments)
    if len(tolerances) != max(len(segs) - 1, 0):
        raise PathError(f"blend: {len(tolerances)} corner tolerances for {len(segs)} segments")
    trim_start = np.zeros(len(segs))
    trim_end = np.zeros(len(segs))
    is_line = np.array([g.kind == "line" for g in segs])
    # every line–line corner at once (a CAM program has 10⁵ of them): they are independent,
    # each takes at most half of each line, and the line↔arc corners never take more either
    cand = np.array([i for i, tol in enumerate(tolerances) if tol is not None and is_line[i] and is_line[i + 1]],
                    dtype=np.int64)
    arcs, done = {}, []
    if len(cand):
        U = np.array([g.direction if g.kind == "line" else (0.0, 0.0, 0.0) for g in segs])
        L = np.array([g.length for g in segs])
        tolc = np.array([tolerances[i] for i in cand.tolist()], float)
        if not (tolc > 0).all():
            i = int(cand[np.argmin(tolc > 0)])
            raise PathError(f"blend: corner {i} tolerance {tolerances[i]} must be > 0 (or None for an exact stop)")
        turns = np.arctan2(np.linalg.norm(np.cross(U[cand], U[cand + 1]), axis=1),
                           np.einsum("ij,ij->i", U[cand], U[cand + 1]))
        sized = _speed_line_corners if speed is not None else _room_line_corners
        idx, R, d, angle, v_plan, dev = sized(U, L, cand, tolc, turns, speed)
        trim_end[idx] = d
        trim_start[idx + 1] = d
        arcs = dict(zip(idx.tolist(), zip(R.tolist(), d.tolist(), angle.tolist(), v_plan)))
        done = list(zip(idx.tolist(), dev.tolist()))
    trim_start, trim_end = trim_start.tolist(), trim_end.tolist()
    # with speed sizing, line↔arc corners are blended too (tp.c tpCreateLineArcBlend /
    # tpCreateArcLineBlend), in program order
    mixed = [] if speed is None else [i for i, tol in enumerate(tolerances)
                                      if tol is not None and is_line[i] != is_line[i + 1]]
    arc_trim, mixed_built = _line_arc_corners(segs, tolerances, mixed, speed, trim_start, trim_end, done)
    out = _assemble(segs, trim_start, trim_end, arcs, arc_trim, mixed_built)
    done.sort(key=lambda x: x[0])
    return out, done


def _speed_line_corners(U, L, c, tolc, turns, sp: BlendSpeed):
    """The line–line corners sized to the speed (speed_blends): (corner indices, R, d, turn,
    v_plan, deviation) of those that get an arc."""
    req, mv = np.array(sp.req, float), np.array(sp.maxvel, float)
    R, d, dev, phi, vp = speed_blends(U[c], U[c + 1], L[c], L[c + 1], tolc,
                                      req[c], req[c + 1], mv[c], mv[c + 1], sp.v_axis, sp.a_axis)
    # blendComputeParameters aborts an arc below TP_POS_EPSILON / TP_MIN_ARC_LENGTH
    with np.errstate(invalid="ignore"):
        ok = ((turns > CORNER_ANGLE) & (turns < REVERSAL_ANGLE) & (R >= 1e-12) & (R * phi >= 1e-6)
              & (R > 0) & (d > 0))
    return c[ok], R[ok], d[ok], phi[ok], vp[ok].tolist(), dev[ok]


def _room_line_corners(U, L, c, tolc, turns, _speed=None):
    """The line–line corners rounded as large as the tolerance and half of each line allow.

    The arc of a turn δ touches the lines at d = R·tan(δ/2) from the corner and passes it at
    R·(1/cos(δ/2) − 1): R is the smaller of the room's (d = half the shorter line) and the
    tolerance's. δ = atan2(|u1 × u2|, u1 · u2), not acos(u1 · u2): acos loses the angle of a
    nearly straight corner to rounding (~1e-8 rad), and R·δ then puts the arc's end 1e-7 mm off
    its line. The angles by ``math``, one corner at a time: numpy's SIMD kernels round them
    differently per CPU."""
    keep = (turns > CORNER_ANGLE) & (turns < REVERSAL_ANGLE)
    c, tol = c[keep], tolc[keep]
    U1, U2 = U[c], U[c + 1]
    sin_n = _norms(_cross(U1, U2)).tolist()
    cos_n = (U1[:, 0] * U2[:, 0] + U1[:, 1] * U2[:, 1] + U1[:, 2] * U2[:, 2]).tolist()
    delta = [math.atan2(y, x) for y, x in zip(sin_n, cos_n)]
    tan_h = np.array([math.tan(0.5 * x) for x in delta])
    sec_m1 = 1.0 / np.array([math.cos(0.5 * x) for x in delta]) - 1.0
    room = 0.5 * np.minimum(L[c], L[c + 1])
    with np.errstate(divide="ignore"):
        R_tol = np.where(np.isfinite(tol), tol / sec_m1, math.inf)
    R = np.minimum(room / tan_h, R_tol)
    d, dev = R * tan_h, R * sec_m1
    ok = (R > 0) & (d > 0)
    return c[ok], R[ok], d[ok], np.array(delta)[ok], [None] * int(ok.sum()), dev[ok]


def _line_arc_corners(segs, tolerances, mixed, sp: BlendSpeed, trim_start, trim_end, done):
    """The line↔arc corners ``mixed`` (ascending), sized to the speed (line_arc_blend): trims the
    lines in ``trim_start``/``trim_end`` and appends (corner, deviation) to ``done``; returns
    ({arc index: [angle cut at its start, at its end]}, {corner: blend arc})."""
    arc_trim, built = {}, {}
    for i in mixed:
        a, b, tol = segs[i], segs[i + 1], tolerances[i]
        if not tol > 0:
            raise PathError(f"blend: corner {i} tolerance {tol} must be > 0 (or None for an exact stop)")
        line_first = a.kind == "line"
        line, arc = (a, b) if line_first else (b, a)
        ta = arc_trim.setdefault(i + 1 if line_first else i, [0.0, 0.0])
        room = a.length - trim_start[i] if line_first else line.length
        k_line, k_arc = (i, i + 1) if line_first else (i + 1, i)
        res = line_arc_blend(line, arc, room, arc.angle - ta[0] - ta[1], line_first, tol,
                             min(sp.req[k_line], sp.maxvel[k_line]), min(sp.req[k_arc], sp.maxvel[k_arc]),
                             sp.v_axis, sp.a_axis)
        if res is None:
            continue
        R, dL, trim, centre, bn, v_plan, dev = res
        if line_first:
            t1, t2 = line.end - dL * line.direction, _arc_point(arc, trim)
        else:
            t1, t2 = _arc_point(arc, arc.angle - trim), line.start + dL * line.direction
        r1, r2 = t1 - centre, t2 - centre
        ang = math.atan2(float(np.dot(cross3(r1, r2), bn)), float(np.dot(r1, r2)))
        if not ang > 0:
            continue
        if line_first:
            trim_end[i], ta[0] = dL, trim
        else:
            trim_start[i + 1], ta[1] = dL, trim
        g = Arc.exact(t1, centre, bn, ang, segs[i + 1].line)
        g.v_cap = v_plan                  # tpInitBlendArcFromPrev: maxvel = v_plan
        built[i] = g
        done.append((i, dev))
    return arc_trim, built


def _line_line_arcs(segs, arcs):
    """{corner: blend Arc} from {corner: (R, d, turn, v_plan)}: each arc from C − d·u1 to
    C + d·u2 of its corner C, column-wise (the same element-wise operations in the same order
    as one 3-vector at a time: 10⁵ corners cost seconds so)."""
    built = {}
    if not arcs:
        return built
    ai = sorted(arcs)
    R = np.array([arcs[i][0] for i in ai])[:, None]
    d = np.array([arcs[i][1] for i in ai])[:, None]
    delta = [arcs[i][2] for i in ai]
    U1 = np.array([segs[i].direction for i in ai])
    U2 = np.array([segs[i + 1].direction for i in ai])
    m = U2 - np.array([math.cos(x) for x in delta])[:, None] * U1
    m /= _norms(m)[:, None]
    n = _cross(U1, U2)
    n /= _norms(n)[:, None]
    # n exactly ⟂ m: on a nearly straight corner both carry ~1e-10 rounding, and the arc
    # projects start − centre (= −R·m, R up to 10⁴ mm) onto n's plane, moving it 1e-6 mm
    n = n - (n[:, 0] * m[:, 0] + n[:, 1] * m[:, 1] + n[:, 2] * m[:, 2])[:, None] * m
    n /= _norms(n)[:, None]
    t1 = np.array([segs[i].end for i in ai]) - d * U1
    C = t1 + R * m
    # Arc._derive's in-plane basis, radius, length and end, column-wise (rise = 0)
    a = t1 - C
    off = a[:, 0] * n[:, 0] + a[:, 1] * n[:, 1] + a[:, 2] * n[:, 2]
    a = a - off[:, None] * n
    b = _cross(n, a)
    radius = _norms(a).tolist()
    length = [float(th * math.hypot(r, 0.0 / th)) for th, r in zip(delta, radius)]
    end = (C + np.array([math.cos(x) for x in delta])[:, None] * a
           + np.array([math.sin(x) for x in delta])[:, None] * b + 0.0 * n)
    for k, i in enumerate(ai):
        built[i] = Arc.from_parts(t1[k], C[k], n[k], delta[k], segs[i + 1].line,
                                  a[k], b[k], radius[k], length[k], end[k])
        if arcs[i][3] is not None:
            built[i].v_cap = arcs[i][3]     # tp.c tpCreateLineLineBlend: maxvel = v_plan
    return built


def _assemble(segs, trim_start, trim_end, arcs, arc_trim, mixed_built):
    """The blended segment list: trimmed lines (keeping their original direction, so a short
    leftover never gets a direction of rounding noise, i.e. a false corner), trimmed arcs and
    the blend arcs, in path order."""
    lines = [i for i, g in enumerate(segs) if g.kind == "line"]
    trimmed = {}
    if lines:
        li = np.array(lines)
        D = np.array([segs[i].direction for i in lines])
        ts, te = np.array(trim_start)[li][:, None], np.array(trim_end)[li][:, None]
        S = np.array([segs[i].start for i in lines]) + ts * D
        E = np.array([segs[i].end for i in lines]) - te * D
        lens = [segs[i].length - trim_start[i] - trim_end[i] for i in lines]
        trimmed = {i: (S[k], E[k], D[k], lens[k]) for k, i in enumerate(lines)}
    built = _line_line_arcs(segs, arcs)
    out = []
    for i, g in enumerate(segs):
        if g.kind == "line":
            st, en, u, left = trimmed[i]
            if left > 1e-9:
                out.append(Line.exact(st, en, u, g.line))
        elif i in arc_trim and (arc_trim[i][0] > 0 or arc_trim[i][1] > 0):
            t0, t1 = arc_trim[i]
            left = g.angle - t0 - t1
            out.append(Arc.exact(_arc_point(g, t0), g.center, g.normal, left, g.line,
                                 spiral=g.spiral * (left / g.angle)))     # the same dr/dφ
        else:
            out.append(g)
        if i in built:
            out.append(built[i])
        if i in mixed_built:
            out.append(mixed_built[i])
    return out


def _arc_point(g, phi: float):
    """The point of a planar arc at angle φ from its start."""
    return g.planar_point(phi)
