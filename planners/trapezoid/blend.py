"""LinuxCNC 2.9's blend arcs, one corner at a time, for the queue model (planners.trapezoid.queue).

Follows tp.c ``tpCreateLineLineBlend`` / ``tpCreateLineArcBlend`` / ``tpCreateArcLineBlend``
(source read at LinuxCNC commit f1270d6ed7): blendmath.c ``blendInit3FromLineLine``,
``blendParamKinematics``, ``blendComputeParameters``, ``blendFindPoints3`` and
``blendCheckConsume``; ``blendInit3FromLineArc`` / ``blendInit3FromArcLine`` and
``blendLineArcPostProcess`` / ``blendArcLinePostProcess`` for a line↔arc corner.
Each function returns a :class:`Blend` (or None: no blend arc, LinuxCNC then chooses a
parabolic or tangent junction) without changing the segments; planners.trapezoid.queue connects it.
Arc↔arc corners follow ``tpCreateArcArcBlend`` (``blendInit3FromArcArc``,
``blendArcArcPostProcess``). Not followed: blendmath.c ``checkTangentAngle`` (exact circles
pass it) and helices (no blend arc: LinuxCNC's coplanarity test refuses nearly all of them).
"""
from __future__ import annotations

import math

import numpy as np

from planners.paths.base import cross3, norm3
from planners.paths.spiral import approximating_circle, tangent_blend_on_spiral
from planners.trapezoid.rules import ACC_RATIO_NORMAL, GAP_CYCLES

BLEND_DIST_FRACTION = 0.5                     # tc_types.h: a blend takes at most half a segment
ANGLE_EPS = 1e-6                              # tp_types.h TP_ANGLE_EPSILON
MIN_ARC_LENGTH = 1e-6                         # tp_types.h TP_MIN_ARC_LENGTH


def _plane_bound(binormal, bound: float) -> float:
    """blendmath.c calculateInscribedDiameter with one bound on every axis: the largest
    magnitude of a vector in the plane ⊥ ``binormal`` keeping each axis within ``bound``."""
    scale = max(math.sqrt(max(1.0 - float(b) * float(b), 0.0)) for b in binormal)
    return bound / max(scale, 1e-300)


def _unit(v):
    v = np.asarray(v, float)
    return v / norm3(v)


def arc_tangent(g, at_end: bool):
    """Unit tangent of a planar arc at its start or end (direction of travel)."""
    if g.spiral:
        return g.tangent_out() if at_end else g.tangent_in()
    p = g.end if at_end else g.start
    return _unit(cross3(g.normal, p - g.center))


class Blend:
    """A blend arc as LinuxCNC makes it: from ``start`` about ``center`` (unit ``binormal``)
    through ``angle`` at radius ``radius``; ``trim1`` of the previous segment (mm of a line,
    radians of a circle) and ``trim2`` of the next; max velocity ``v_plan``, requested
    ``v_req``, plane acceleration bound ``a_max``; ``consume``: the previous line's rest
    (``line_length`` mm) becomes the start of the blend segment."""

    __slots__ = ("start", "center", "binormal", "angle", "radius", "trim1", "trim2", "v_plan",
                 "v_req", "a_max", "consume", "line_length")


def _tolerance(prev, tc) -> float:
    """tc.c tcFindBlendTolerance: G64 P (no P: a quarter of the segment), at most a quarter of
    either segment."""
    t1 = prev.tol if prev.tol > 0 else 0.25 * prev.nominal
    t2 = tc.tol if tc.tol > 0 else 0.25 * tc.nominal
    return min(t1, t2, 0.25 * prev.nominal, 0.25 * tc.nominal)


def _kinematics(theta, binormal, prev, tc, lines: bool, v_axis, a_axis):
    """blendParamKinematics: (a_max, v_req, v_goal) of the blend plane; two lines may go at
    the "altitude" speed of their velocity triangle."""
    phi = math.pi - 2.0 * theta
    a_max = _plane_bound(binormal, a_axis)
    v_req = max(min(prev.reqvel, prev.maxvel), min(tc.reqvel, tc.maxvel))   # tcGetMaxTargetVel, scale 1
    v_alt = 0.0
    if lines:
        c = math.cos(min(phi, math.pi * 0.49))
        vm1, vm2 = min(prev.maxvel, tc.maxvel / c), min(tc.maxvel, prev.maxvel / c)
        base = norm3(tc.u * vm2 - prev.u * vm1)
        v_alt = vm1 * vm2 * math.sin(phi) / base if base > 0 else 0.0
    return a_max, v_req, min(v_req, max(v_alt, _plane_bound(binormal, v_axis)))


def compute_parameters(theta, tol, L1, L2, a_max, v_goal):
    """blendmath.c blendComputeParameters: (R_plan, d_plan, v_plan), or None when the arc
    would be below TP_POS_EPSILON / TP_MIN_ARC_LENGTH. The radius is the smaller of what the
    room and tolerance allow and what the corner speed needs (the equivalent parabolic blend)."""
    phi = math.pi - 2.0 * theta
    a_n = a_max * ACC_RATIO_NORMAL
    d_tol = math.cos(theta) * tol / (1.0 - math.sin(theta))
    d_geom = min(L1, L2, d_tol)
    R_geom = math.tan(theta) * d_geom
    v_plan = min(math.sqrt(a_n * R_geom), v_goal)
    a_par = 0.5 * a_max
    s_blend = min(math.sqrt(2.0 * a_par * d_geom), v_plan) / a_par * v_plan
    R_plan = max(v_plan * v_plan / a_n, min(s_blend / phi, R_geom))
    if R_plan < 1e-12 or R_plan * phi < MIN_ARC_LENGTH:
        return None
    return R_plan, R_plan / math.tan(theta), v_plan


def line_line(prev, tc, T: float, v_axis: float, a_axis: float):
    """The blend arc between two lines (tpCreateLineLineBlend), or None."""
    u1, u2 = prev.u, tc.u
    dot = max(-1.0, min(1.0, float(u1[0] * u2[0] + u1[1] * u2[1] + u1[2] * u2[2])))
    theta = math.acos(-dot) / 2.0
    if math.pi / 2.0 - theta < ANGLE_EPS or theta < ANGLE_EPS:
        return None                                      # blendGeom3Init: tangent or a reversal
    bn = cross3(u1, u2)
    bn = bn / norm3(bn)
    a_max, v_req, v_goal = _kinematics(theta, bn, prev, tc, True, v_axis, a_axis)
    L1 = min(prev.target, prev.nominal * BLEND_DIST_FRACTION)
    L2 = tc.target * BLEND_DIST_FRACTION
    p = compute_parameters(theta, _tolerance(prev, tc), L1, L2, a_max, v_goal)
    if p is None:
        return None
    R, d, v_plan = p
    b = Blend()
    P = tc.start
    # m ⟂ u1 in the plane, towards u2; the centre R along it from the tangent point on u1
    m = u2 - dot * u1
    m = m / norm3(m)
    b.start = P - d * u1
    b.center = b.start + R * m
    b.binormal, b.angle, b.radius = bn, math.pi - 2.0 * theta, R
    b.trim1 = b.trim2 = d
    b.v_plan, b.v_req, b.a_max = v_plan, v_req, a_max
    _check_consume(b, prev, prev.target - d, T)
    return b


def _check_consume(b: Blend, prev, rest: float, T: float) -> None:
    """blendmath.c blendCheckConsume: a previous line left shorter than GAP_CYCLES periods at
    the blend's speed is taken into the blend segment, unless a parabolic blend ends in it
    (tc.c tcCanConsume; its synced I/O and spindle-at-speed conditions are not modelled)."""
    b.consume = prev.kind == "line" and not prev.blend_prev and rest / b.v_plan < GAP_CYCLES * T
    b.line_length = rest if b.consume else 0.0


def line_arc(prev, tc, T: float, v_axis: float, a_axis: float, line_first: bool):
    """The blend arc between a line and a planar circle in either order, or None.

    tp.c tpCreateLineArcBlend / tpCreateArcLineBlend: blendInit3FromLineArc / …ArcLine
    (convexity, φ_max, the reduced θ and the room on the circle), blendComputeParameters, then
    blendLineArcPostProcess / blendArcLinePostProcess (the arc of radius R_plan tangent to
    both, the tolerance re-checked; the trim angle on the circle at most φ_max)."""
    line, circ = (prev, tc) if line_first else (tc, prev)
    g = circ.arc
    if g.rise != 0.0:
        return None                                   # a helix: no blend arc here
    if line_first:
        u1, u2, P = line.u, arc_tangent(g, False), line.end
    else:
        u1, u2, P = arc_tangent(g, True), line.u, line.start
    theta_tan = 0.5 * math.acos(max(-1.0, min(1.0, -float(np.dot(u1, u2)))))
    if math.pi / 2 - theta_tan < ANGLE_EPS or theta_tan < ANGLE_EPS:
        return None                                   # blendGeom3Init: tangent, or a reversal
    bn = _unit(cross3(u1, u2))
    if abs(abs(float(np.dot(bn, g.normal))) - 1.0) > 1e-9:
        return None                                   # not coplanar: no blend arc
    # a spiral is sized on LinuxCNC's circle through P (blendmath.c findSpiralApproximation)
    C, r = approximating_circle(g, not line_first) if g.spiral else (g.center, g.radius)
    if line_first:   # arcConvexTest(center2, P, u_tan1, reverse), φ2_max = min(angle/3, …)
        convex = not (float(np.dot(P - C, u1)) < 0)
        phi_max = min(g.angle / 3.0, theta_tan if convex else math.pi / 2)
    else:            # arcConvexTest(center1, P, u_tan2), φ1_max = min(2·angle/3, …)
        convex = float(np.dot(P - C, u2)) < 0
        phi_max = min(g.angle * 2.0 / 3.0, theta_tan if convex else math.pi / 2)
    theta = min(theta_tan, theta_tan - phi_max / 4.0) if convex else theta_tan
    L_arc = math.sin(phi_max / 4.0) * r if convex else phi_max * r
    # the line: what is left of it before the corner, at most half; after it, half of it
    L_line = min(line.target, BLEND_DIST_FRACTION * line.nominal) if line_first else 0.5 * line.nominal
    a_max, v_req, v_goal = _kinematics(theta, bn, prev, tc, False, v_axis, a_axis)
    tol = _tolerance(prev, tc)
    p = compute_parameters(theta, tol, *((L_line, L_arc) if line_first else (L_arc, L_line)), a_max, v_goal)
    if p is None:
        return None
    R, _, v_plan = p
    res = _line_arc_points(line.u, P, C, r + (-R if convex else R), R, bn, g, line_first)
    if res is None:
        return None
    x, centre, trim = res
    if g.spiral:
        # the exact circle of radius R tangent to the spiral, from LinuxCNC's trim
        exact = tangent_blend_on_spiral(g, P, _unit(cross3(bn, line.u)), bn, R, trim, not line_first)
        if exact is None:
            return None
        trim, centre = exact
        x = float(np.dot(centre - P, line.u))
        if (x > 0) if line_first else (x < 0):
            return None
    if norm3(centre - P) - R > tol or trim > phi_max or trim >= g.angle or abs(x) >= L_line:
        return None
    if line_first:
        t1, t2 = line.end - abs(x) * line.u, _arc_point(g, trim)
    else:
        t1, t2 = _arc_point(g, g.angle - trim), line.start + abs(x) * line.u
    r1, r2 = t1 - centre, t2 - centre
    ang = math.atan2(float(np.dot(cross3(r1, r2), bn)), float(np.dot(r1, r2)))
    if not ang > 0:
        return None
    b = Blend()
    b.start, b.center, b.binormal, b.angle, b.radius = t1, centre, bn, ang, norm3(r1)
    b.trim1, b.trim2 = (abs(x), trim) if line_first else (trim, abs(x))
    b.v_plan, b.v_req, b.a_max = v_plan, v_req, a_max
    if line_first:
        _check_consume(b, prev, prev.target - abs(x), T)
    else:
        b.consume, b.line_length = False, 0.0
    return b


def _line_arc_points(u, P, C, d: float, R: float, bn, g, line_first: bool):
    """blendLineArcPostProcess / blendArcLinePostProcess: (x, centre, trim angle): the blend
    centre R from the line on the turn's side (x along the line from P) and d from the circle's
    centre C, the smaller root; None if there is none or its tangent point is off the line."""
    n = _unit(cross3(bn, u))
    rc = C - P
    c_u, c_n = float(np.dot(rc, u)), float(np.dot(rc, n))
    k = c_u * c_u + (R - c_n) ** 2 - d * d             # x² − 2·c_u·x + k = 0
    disc = c_u * c_u - k
    if disc < 0:
        return None
    x = min((c_u + math.sqrt(disc), c_u - math.sqrt(disc)), key=abs)
    if (x > 0) if line_first else (x < 0):
        return None                                   # the tangent point must lie on the line
    centre = P + x * u + R * n
    trim = math.acos(max(-1.0, min(1.0, float(np.dot(_unit(P - C), _unit(centre - C))))))
    return x, centre, trim


def _arc_point(g, phi: float):
    """The point of a planar arc (or spiral) at angle φ from its start."""
    return g.planar_point(phi)


def arc_arc(prev, tc, T: float, v_axis: float, a_axis: float):
    """The blend arc between two coplanar circles (tpCreateArcArcBlend), or None."""
    g1, g2 = prev.arc, tc.arc
    if g1.spiral or g2.spiral:
        return None         # not modelled: a spiral↔arc corner is left to tpChooseBestBlend's others
    if g1.rise != 0.0 or g2.rise != 0.0 or abs(abs(float(np.dot(g1.normal, g2.normal))) - 1.0) > 1e-12:
        return None
    u1, u2, P = arc_tangent(g1, True), arc_tangent(g2, False), g2.start
    dot = max(-1.0, min(1.0, float(np.dot(u1, u2))))
    theta_tan = math.acos(-dot) / 2.0
    if math.pi / 2.0 - theta_tan < ANGLE_EPS or theta_tan < ANGLE_EPS:
        return None
    bn = cross3(u1, u2)
    bn = bn / norm3(bn)
    if any(abs(abs(float(np.dot(bn, g.normal))) - 1.0) > 1e-12 for g in (g1, g2)):
        return None                                       # not coplanar: no blend arc
    normal = (u2 - u1) / norm3(u2 - u1)
    C1, C2 = g1.center, g2.center
    r1, r2 = norm3(P - C1), norm3(P - C2)
    convex1 = float(np.dot(P - C1, u2)) < 0                # arcConvexTest(center1, P, u_tan2)
    convex2 = not float(np.dot(P - C2, u1)) < 0           # arcConvexTest(center2, P, u_tan1, reverse)
    phi1_max = min(g1.angle * 2.0 / 3.0, theta_tan if convex1 else math.pi / 2.0)
    phi2_max = min(g2.angle / 3.0, theta_tan if convex2 else math.pi / 2.0)
    theta = theta_tan
    if convex1:
        theta = min(theta, theta_tan - phi1_max / 4.0)
    if convex2:
        theta = min(theta, theta_tan - phi2_max / 4.0)
    if theta < math.pi / 12.0:
        return None                                       # too tight an arc
    L1 = math.sin(phi1_max / 4.0) * r1 if convex1 else phi1_max * r1
    L2 = math.sin(phi2_max / 4.0) * r2 if convex2 else phi2_max * r2
    a_max, v_req, v_goal = _kinematics(theta, bn, prev, tc, False, v_axis, a_axis)
    tol = _tolerance(prev, tc)
    p = compute_parameters(theta, tol, L1, L2, a_max, v_goal)
    if p is None:
        return None
    R, _, v_plan = p
    centre = _arc_arc_centre(P, C1, C2, r1 + (-R if convex1 else R), r2 + (-R if convex2 else R), bn, normal)
    if centre is None or norm3(centre - P) - R > tol:
        return None
    trim1, trim2 = _trim_angle(P, centre, C1), _trim_angle(P, centre, C2)
    if trim1 > phi1_max or trim2 > phi2_max:
        return None
    t1, t2 = _arc_point(g1, g1.angle - trim1), _arc_point(g2, trim2)
    cos_a = float(np.dot(t1 - centre, t2 - centre)) / (norm3(t1 - centre) * norm3(t2 - centre))
    ang = math.acos(max(-1.0, min(1.0, cos_a)))           # arcInitFromPoints
    if ang < ANGLE_EPS:
        return None
    b = Blend()
    b.start, b.center, b.binormal, b.angle, b.radius = t1, centre, bn, ang, norm3(t1 - centre)
    b.trim1, b.trim2, b.v_plan, b.v_req, b.a_max = trim1, trim2, v_plan, v_req, a_max
    b.consume, b.line_length = False, 0.0
    return b


def _arc_arc_centre(P, C1, C2, d1: float, d2: float, bn, normal):
    """blendArcArcPostProcess: the blend centre at d1 from C1 and d2 from C2, on the side
    nearer P (None if the circles give no such point)."""
    c2x = norm3(C2 - C1)
    if not c2x > 0:
        return None
    cx = (-d1 * d1 + d2 * d2 - c2x * c2x) / (-2.0 * c2x)
    if d1 * d1 - cx * cx < 0:
        return None
    cy = math.sqrt(d1 * d1 - cx * cx)
    uc = (C2 - C1) / c2x
    nc = cross3(bn, uc)
    if float(np.dot(normal, nc)) < 0:
        nc = -nc
    nc = nc / norm3(nc)
    base = C1 - P + cx * uc
    if norm3(base - cy * nc) < norm3(base + cy * nc):
        cy = -cy
    return C1 + cx * uc + cy * nc


def _trim_angle(P, centre, C) -> float:
    """blendmath.c findTrimAngle: the angle at C from P to the blend centre."""
    a, b = (P - C) / norm3(P - C), (centre - C) / norm3(centre - C)
    return math.acos(max(-1.0, min(1.0, float(np.dot(a, b)))))
