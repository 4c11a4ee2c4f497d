"""Spiral arcs (LinuxCNC's G2/G3 whose end radius differs: the centre kept, the radius linear in
the swept angle): points, arc length and its inverse against the closed form of the
Archimedean spiral's length, derivatives, blends, the path file, and a plain arc unchanged."""
import json
import math

import numpy as np
import pytest

from planners.paths import Arc, Line, SegmentPath, load_path
from planners.paths.gcode import parse_gcode


def closed_length(r0: float, k: float, m: float, phi):
    """∫₀^φ √((r0 + kψ)² + k² + m²) dψ = [F(ρ)]/k with F(ρ) = ½(ρ√(ρ² + c²) + c²·asinh(ρ/c)),
    c² = k² + m² (the planar Archimedean spiral's length when m = 0, plus a linear rise)."""
    c2 = k * k + m * m
    F = lambda rho: 0.5 * (rho * np.sqrt(rho * rho + c2) + c2 * np.arcsinh(rho / math.sqrt(c2)))  # noqa: E731
    return (F(r0 + k * np.asarray(phi, float)) - F(r0)) / k


def polar(P, c, start, turn: float):
    """(sweep angle from start, in the sense of ``turn``; distance from c) of points P (XY)."""
    a0 = math.atan2(start[1] - c[1], start[0] - c[0])
    ang = np.unwrap(np.concatenate([[0.0], np.arctan2(P[:, 1] - c[1], P[:, 0] - c[0]) - a0]))[1:]
    return turn * ang, np.hypot(P[:, 0] - c[0], P[:, 1] - c[1])


G2_14UM = "G21 G90 G17\nG0 X10 Y0 Z0\nG2 X20.014 Y0 I5 J0 F600\n"    # r0 = 5, r1 = 5.014


def test_reader_keeps_linuxcncs_centre_and_the_radius_is_linear_in_the_angle():
    arc = parse_gcode(G2_14UM, "t.ngc").moves[0].segment
    assert arc.center.tolist() == [15.0, 0.0, 0.0]                # I5 J0 from X10 Y0: not moved
    assert arc.radius == 5.0 and arc.spiral == pytest.approx(0.014, abs=1e-14)
    assert arc.normal.tolist() == [0, 0, -1] and arc.angle == pytest.approx(math.pi, abs=1e-15)
    path = SegmentPath([arc])
    assert np.abs(path.point(0.0) - [10, 0, 0]).max() == 0
    assert np.abs(path.point(path.length) - [20.014, 0, 0]).max() <= 1e-12
    # every point: radius r0 + (r1 − r0)·φ/θ at its own polar angle φ (G2: clockwise)
    P = path.point(np.linspace(0, path.length, 4001))
    phi, rad = polar(P, arc.center, arc.start, -1.0)
    assert np.abs(rad - (5.0 + 0.014 * phi / math.pi)).max() <= 1e-12
    # at mid-angle the radius is the mean of the two, 5.007
    mid = arc.at_angle(np.array([math.pi / 2]), 0)[0][0]
    assert np.abs(mid - [15.0, 5.007, 0.0]).max() <= 1e-12


def test_small_spiral_of_a_ccw_quarter_and_a_helix_in_g18():
    p = parse_gcode("G21 G90\nG0 X0 Y0 Z0\nG1 X10 F600\nG3 X0 Y10.001 I-10 J0\n"
                    "G18 G2 X0 Z10.004 Y13 I0 K5\n", "t.ngc")
    q, h = p.moves[1].segment, p.moves[2].segment
    assert q.center.tolist() == [0, 0, 0] and q.spiral == pytest.approx(0.001, abs=1e-12)
    assert np.abs(q.end - [0, 10.001, 0]).max() <= 1e-12
    # G18 (Z, X; G2 about −Y) from (0, 10.001, 0): centre Z 0 + K5, radius 5 → 5.004, Y rises 2.999
    assert h.center.tolist() == [0.0, 10.001, 5.0] and h.normal.tolist() == [0, -1, 0]
    assert h.spiral == pytest.approx(0.004, abs=1e-12) and h.rise == pytest.approx(-2.999, abs=1e-12)
    assert np.abs(h.end - [0, 13, 10.004]).max() <= 1e-12
    assert np.abs(SegmentPath([h]).point(h.length) - [0, 13, 10.004]).max() <= 1e-12


@pytest.mark.parametrize("r0, spiral, theta, rise", [
    (5.0, 0.014, math.pi, 0.0),             # the reader's example
    (5.0, 2.0, 3 * math.pi, 0.0),           # a coarse spiral: 1.5 turns, r 5 → 7
    (0.00127, 0.028, 20 * math.pi, 0.0),    # LinuxCNC's worst: r0 at its radius tolerance, 10 turns
    (2.0, -0.5, 2.5, -4.0),                 # spiralling in while rising
])
def test_length_and_inverse_against_the_closed_form(r0, spiral, theta, rise):
    arc = Arc([r0, 0, 0], [0, 0, 0], [0, 0, 1], theta, rise, spiral=spiral)
    k, m = spiral / theta, rise / theta
    L = float(closed_length(r0, k, m, theta))
    assert arc.length == pytest.approx(L, rel=1e-13, abs=1e-15)
    # s → point: the arc length to each point's polar angle, by the closed form, is s
    s = np.linspace(0, arc.length, 2001)
    P = SegmentPath([arc]).point(s)
    phi, rad = polar(P, [0, 0], [r0, 0], 1.0)
    assert np.abs(closed_length(r0, k, m, phi) - s).max() <= 1e-9
    assert np.abs(rad - (r0 + k * phi)).max() <= 1e-12
    assert np.abs(P[:, 2] - m * phi).max() <= 1e-12


def test_length_equals_a_dense_polyline_richardson_extrapolated():
    arc = Arc([10, 0, 0], [15, 0, 0], [0, 0, -1], math.pi, spiral=0.014)
    path = SegmentPath([arc])
    poly = [np.linalg.norm(np.diff(path.point(np.linspace(0, arc.length, n)), axis=0), axis=1).sum()
            for n in (20001, 40001)]
    assert 4 * poly[1] - poly[0] == pytest.approx(3 * arc.length, abs=3e-10)     # chord error ∝ h²


def test_derivatives_and_curvature():
    arc = Arc([2, 0, 0], [0, 0, 0], [0, 0, 1], 4.0, rise=1.5, spiral=0.6)
    path = SegmentPath([Line([2, -3, 0], [2, 0, 0]), arc])
    s = path.seg_start[1] + np.linspace(0.01, arc.length - 0.01, 37)
    D = path.derivs(s)
    h = 1e-4
    for d in range(3):
        fd = (path.derivs(s + h)[d] - path.derivs(s - h)[d]) / (2 * h)
        assert np.abs(fd - D[d + 1]).max() <= 2e-7
    assert np.abs(np.linalg.norm(D[1], axis=1) - 1).max() <= 1e-14
    # planar curvature of an Archimedean spiral (ρ² + 2k²)/(ρ² + k²)^1.5, on the flat one
    flat = SegmentPath([Arc([2, 0, 0], [0, 0, 0], [0, 0, 1], 4.0, spiral=0.6)])
    t = np.linspace(0, flat.length, 50)
    phi, rho = polar(flat.point(t), [0, 0], [2, 0], 1.0)
    k = 0.6 / 4.0
    assert np.abs(flat.curvature(t) - (rho**2 + 2 * k * k) / (rho**2 + k * k) ** 1.5).max() <= 1e-12
    # the line along +Y meets the spiral at a corner: its tangent (k, r0, m)/|·| leaves the
    # circle's tangent +Y by acos(r0/√(r0² + k² + m²))
    assert path.corners().tolist() == [3.0]
    f = math.sqrt(4 + 0.15**2 + (1.5 / 4) ** 2)
    assert np.abs(arc.tangent_in() - [0.15 / f, 2 / f, 1.5 / 4 / f]).max() <= 1e-15


def test_plain_arc_is_bit_for_bit_the_circle_formula():
    # spiral 0 takes the old code: the same bits as the closed form written out as before
    c, n, th, h = np.array([1.0, 2.0, 3.0]), np.array([0.0, 0.0, 1.0]), 2.2, -0.7
    arc = Arc([4.0, 2.0, 3.0], c, n, th, h)
    assert arc.spiral == 0.0 and "spiral" not in arc.to_dict()
    assert arc.length == th * math.hypot(3.0, h / th)
    path = SegmentPath([arc])
    s = np.linspace(0, arc.length, 101)
    k = th / arc.length
    phi = (s * k)[:, None]
    a, b, hn = arc.a, arc.b, (h / th) * n
    P = c + (np.cos(phi) * a + np.sin(phi) * b + phi * hn)
    d1 = k * (-np.sin(phi) * a + np.cos(phi) * b + hn)
    d2 = k**2 * (-np.cos(phi) * a - np.sin(phi) * b)
    got = path.derivs(s)
    assert np.array_equal(got[0], P) and np.array_equal(got[1], d1) and np.array_equal(got[2], d2)
    assert np.array_equal(arc.eval(s, 0)[0], c + np.cos(phi) * a + np.sin(phi) * b + phi * hn)


def test_path_file_spiral_field_round_trip(tmp_path):
    arc = Arc([10, 0, 0], [15, 0, 0], [0, 0, -1], math.pi, spiral=0.014)
    path = SegmentPath([Line([0, 0, 0], [10, 0, 0]), arc, Line(arc.end, [30, 0, 0])])
    path.to_file(tmp_path / "p.json")
    doc = json.loads((tmp_path / "p.json").read_text())
    assert doc["segments"][1]["spiral"] == arc.spiral and "spiral" not in doc["segments"][0]
    back = load_path(tmp_path / "p.json")
    s = np.linspace(0, path.length, 501)
    assert np.array_equal(back.point(s), path.point(s))
    del doc["segments"][1]["spiral"]          # absent: a circle, whose end then disagrees
    (tmp_path / "q.json").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="arc end .* disagrees"):
        load_path(tmp_path / "q.json")
    doc["segments"][1]["spiral"] = -5.0
    (tmp_path / "q.json").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=r"end radius r0 \+ spiral = 5 \+ -5 mm must be > 0"):
        load_path(tmp_path / "q.json")


def test_line_spiral_blends_are_tangent_circles_within_the_tolerance():
    # line → spiral (G3, r 5 → 5.02 about the programmed centre) → line under G64 P0.01, as
    # trapezoid queues it (planners.trapezoid.queue): each corner gets a blend arc that leaves the line
    # tangentially and meets the trimmed spiral on it and tangent to it
    from planners.trapezoid import queue as Q
    text = ("G21 G90 G17 G64 P0.01\nG0 X-10 Y-3 Z-250\nG1 X0 Y0 F1200\n"
            "G3 X5.02 Y5 I0 J5\nG1 X15\nM2\n")
    runs, _ = Q.build(parse_gcode(text).moves, Q.Limits(1e-3, 20.0, 500.0, 20.0))
    tcs = [tc for r in runs for tc in r]
    kinds = [tc.kind for tc in tcs]
    assert kinds.count("blend") == 2 and kinds.count("circle") == 1
    k = kinds.index("circle")
    spiral = tcs[k].arc
    assert spiral.center.tolist() == [0.0, 5.0, -250.0]
    assert spiral.spiral / spiral.angle == pytest.approx(0.02 / (math.pi / 2), rel=1e-12)
    before, after = tcs[k - 1].arc, tcs[k + 1].arc
    assert np.abs(before.end - spiral.start).max() <= 1e-9
    assert np.abs(before.tangent_out() - spiral.tangent_in()).max() <= 1e-9
    assert np.abs(after.start - spiral.end).max() <= 1e-9
    assert np.abs(after.tangent_in() - spiral.tangent_out()).max() <= 1e-9
    for b in (before, after):   # the corner within P of the blend circle (tp_blend's deviation check)
        corner = np.array([0.0, 0.0, -250.0]) if b is before else np.array([5.02, 5.0, -250.0])
        assert 0 < np.linalg.norm(corner - b.center) - b.radius <= 0.01 + 1e-12


def test_trapezoid_caps_a_spiral_by_its_radius_of_curvature_at_the_start():
    # LinuxCNC's pmCircleEffectiveMinRadius: the spiral's own radius of curvature at the start
    # radius, i.e. 1/κ(0) of the path; the arc's speed cap is √(a_n·ρ) below the machine's
    from planners.trapezoid.planner import segment_limits
    from planners.trapezoid.rules import ACC_RATIO_NORMAL
    arc = Arc([0.5, 0, 0], [0, 0, 0], [0, 0, 1], 2.0, spiral=0.4)
    path = SegmentPath([arc])
    vmax, _ = segment_limits(path, 1000.0, 100.0, 1000.0)
    rho = 1.0 / float(path.curvature([0.0])[0])
    assert rho != pytest.approx(0.5, rel=1e-3)                 # not the circle's radius
    assert vmax[0] == pytest.approx(math.sqrt(ACC_RATIO_NORMAL * 100.0 * rho), rel=1e-12)
