"""planners.paths: NURBS and segment paths against closed forms and an independent quadrature."""
import json
import math

import numpy as np
import pytest
from scipy.integrate import quad

from planners.paths import (Arc, Line, NurbsPath, PathError, SegmentPath, load_path,
                           resolve_path, standard_paths)

R = 30.0
W = math.sqrt(0.5)


def quarter_circle(z=-400.0):
    # rational quadratic Bézier: exact quarter circle of radius R about the origin
    return NurbsPath(2, [0, 0, 0, 1, 1, 1], [[R, 0, z], [R, R, z], [0, R, z]], [1, W, 1])


def full_circle(z=0.0):
    # the classic 9-point degree-2 NURBS circle (knots of multiplicity 2, still G1)
    P = [[R, 0], [R, R], [0, R], [-R, R], [-R, 0], [-R, -R], [0, -R], [R, -R], [R, 0]]
    w = [1, W, 1, W, 1, W, 1, W, 1]
    U = [0, 0, 0, .25, .25, .5, .5, .75, .75, 1, 1, 1]
    return NurbsPath(2, U, [[x, y, z] for x, y in P], w)


def test_quarter_circle_closed_forms():
    p = quarter_circle()
    assert p.length == pytest.approx(math.pi * R / 2, abs=1e-11)
    s = np.linspace(0, p.length, 1001)
    P, d1, d2, d3 = p.derivs(s)
    phi = s / R
    exact = np.column_stack([R * np.cos(phi), R * np.sin(phi), np.full_like(phi, -400.0)])
    assert np.abs(P - exact).max() < 1e-9
    t = np.column_stack([-np.sin(phi), np.cos(phi), 0 * phi])
    assert np.abs(d1 - t).max() < 1e-9
    assert np.abs(d2 - (-exact + [0, 0, -400]) / R**2).max() < 1e-9
    assert np.abs(d3 - (-t / R**2)).max() < 1e-9
    assert np.abs(p.curvature(s) - 1 / R).max() < 1e-10
    assert len(p.corners()) == 0


def test_full_circle_has_no_corner_and_exact_length():
    p = full_circle()
    assert p.length == pytest.approx(2 * math.pi * R, abs=1e-10)
    assert len(p.corners()) == 0
    s = np.linspace(0, p.length, 777)
    assert np.abs(np.linalg.norm(p.point(s)[:, :2], axis=1) - R).max() < 1e-9
    assert np.abs(p.point(s)[:, 0] - R * np.cos(s / R)).max() < 1e-9


def test_bird_arc_length_matches_independent_quadrature():
    p = resolve_path("bird")
    rng = np.random.default_rng(5)
    s = np.sort(rng.uniform(0, p.length, 12))
    u = p.u_of_s(s)
    spans = np.unique(p.knots)
    for si, ui in zip(s, u):
        total = 0.0
        for a, b in zip(spans[:-1], spans[1:]):
            hi = min(b, ui)
            if hi <= a:
                break
            total += quad(lambda x: p._speed(np.array([x]))[0], a, hi, epsabs=1e-12, epsrel=1e-13, limit=200)[0]
        assert total == pytest.approx(si, abs=1e-9)
    # and the curve points agree with a direct evaluation at those u
    assert np.abs(p.point(s) - p.eval_u(u)[0]).max() < 1e-12


def test_bird_derivatives_by_finite_differences_and_unit_speed():
    p = resolve_path("bird")
    c = p.corners()
    assert len(c) == 5
    s = np.linspace(1.0, p.length - 1.0, 300)
    s = s[np.min(np.abs(s[:, None] - c[None, :]), axis=1) > 0.01]
    P, d1, d2, d3 = p.derivs(s)
    h = 1e-4
    assert np.abs(np.linalg.norm(d1, axis=1) - 1).max() < 1e-12
    assert np.abs(np.sum(d1 * d2, axis=1)).max() < 1e-9            # P′ ⟂ P″ on arc length
    assert np.abs((p.point(s + h) - p.point(s - h)) / (2 * h) - d1).max() < 1e-6
    assert np.abs((p.derivs(s + h)[1] - p.derivs(s - h)[1]) / (2 * h) - d2).max() < 1e-5
    assert np.abs((p.derivs(s + h)[2] - p.derivs(s - h)[2]) / (2 * h) - d3).max() < 1e-3


def test_bird_corners_are_tangent_breaks():
    p = resolve_path("bird")
    for sc in p.corners():
        before = p.point(sc) - p.point(sc - 1e-3)
        after = p.point(sc + 1e-3) - p.point(sc)
        cosang = before @ after / np.linalg.norm(before) / np.linalg.norm(after)
        assert cosang < math.cos(0.1)


def test_helix_segment_closed_form():
    r, h, theta, z0 = 50.0, 100.0, 6 * math.pi, -450.0
    arc = Arc([r, 0, z0], [0, 0, z0], [0, 0, 1], theta, h)
    p = SegmentPath([arc])
    assert p.length == pytest.approx(math.hypot(r * theta, h), rel=1e-15)
    s = np.linspace(0, p.length, 501)
    phi = s / p.length * theta
    exact = np.column_stack([r * np.cos(phi), r * np.sin(phi), z0 + h * phi / theta])
    assert np.abs(p.point(s) - exact).max() < 1e-9
    # helix curvature r / (r² + c²), c = h/θ
    c = h / theta
    assert np.abs(p.curvature(s) - r / (r**2 + c**2)).max() < 1e-12
    helix = resolve_path("helix")
    assert helix.length == pytest.approx(p.length, rel=1e-15)


def test_clockwise_arc_and_line_path_and_corners():
    # G2-like: normal −z, quarter turn from (10,0) about origin goes to (0,−10)
    arc = Arc([10, 0, 0], [0, 0, 0], [0, 0, -1], math.pi / 2, 0.0)
    assert np.allclose(arc.end, [0, -10, 0], atol=1e-12)
    line = Line([0, -10, 0], [-20, -10, 0])     # tangent to the arc end (−x): no corner
    line2 = Line([-20, -10, 0], [-20, 10, 0])   # 90° corner
    p = SegmentPath([arc, line, line2])
    assert np.allclose(p.corners(), [arc.length + 20.0])
    assert np.allclose(p.point(arc.length + 5.0), [-5, -10, 0])
    assert p.point(arc.length / 2) == pytest.approx([10 * W, -10 * W, 0], abs=1e-12)


def test_roundtrip_files_are_exact(tmp_path):
    for name in ("bird", "helix"):
        p = resolve_path(name)
        f = tmp_path / f"{name}.json"
        p.to_file(f)
        q = load_path(f)
        s = np.linspace(0, p.length, 333)
        assert q.length == p.length
        assert np.array_equal(q.point(s), p.point(s))


def nurbs_dict(**kw):
    d = {"type": "nurbs", "units": "mm", "degree": 2, "knots": [0, 0, 0, 1, 1, 1],
         "control_points": [[0, 0, 0], [1, 1, 0], [2, 0, 0]], "weights": [1, 1, 1]}
    d.update(kw)
    return d


@pytest.mark.parametrize("change, words", [
    ({"knots": [0, 0, 1, 1, 1]}, "knots, expected"),
    ({"knots": [0, 0, 0.5, 1, 1, 1]}, "clamped"),
    ({"knots": [0, 0, 0, 1, 0.5, 1]}, "non-decreasing"),
    ({"weights": [1, 0, 1]}, "weight #1"),
    ({"weights": [1, 1]}, "2 weights"),
    ({"control_points": [[0, 0], [1, 1], [2, 0]]}, "[x, y, z]"),
    ({"units": "inch"}, "units"),
    ({"degree": 0}, "degree"),
    ({"knots": [0, 0, 0, 0, 0, 0]}, "empty path"),
    ({"control_points": [[0, 0, 0], [0, 0, 0], [0, 0, 0]]}, "zero parametric speed"),
    ({"type": "spline"}, "unknown path type"),
])
def test_bad_nurbs_files_are_named(tmp_path, change, words):
    f = tmp_path / "bad.json"
    f.write_text(json.dumps(nurbs_dict(**change)))
    with pytest.raises(PathError, match=None) as e:
        load_path(f)
    assert str(f) in str(e.value) and words in str(e.value)


def test_bad_segments_and_queries(tmp_path):
    with pytest.raises(PathError, match="empty path"):
        SegmentPath([])
    with pytest.raises(PathError, match="zero-length line"):
        Line([1, 2, 3], [1, 2, 3])
    with pytest.raises(PathError, match="contiguous"):
        SegmentPath([Line([0, 0, 0], [1, 0, 0]), Line([1, 0.1, 0], [2, 0, 0])])
    with pytest.raises(PathError, match="disagrees"):
        Arc([1, 0, 0], [0, 0, 0], [0, 0, 1], math.pi, 0.0, end=[0, 1, 0])
    with pytest.raises(PathError, match="angle"):
        Arc([1, 0, 0], [0, 0, 0], [0, 0, 1], -1.0)
    f = tmp_path / "x.json"
    f.write_text("{not json")
    with pytest.raises(PathError, match="line 1: invalid JSON"):
        load_path(f)
    p = quarter_circle()
    with pytest.raises(PathError, match="outside the path"):
        p.point([0.0, p.length + 1e-6])
    with pytest.raises(PathError, match="not finite"):
        p.point([np.nan])
    assert p.point(p.length + 1e-10) == pytest.approx([0, R, -400], abs=1e-9)
    with pytest.raises(PathError, match="standard: .*bird"):
        resolve_path("no_such_path")
    assert {"bird", "flower", "helix", "test_part.ngc"} <= set(standard_paths())


def test_segment_path_many_points_in_blocks_equal_small_calls():
    """A large query is evaluated in blocks (memory); the values are those of small calls."""
    from planners.paths.segments import _CHUNK
    path = resolve_path("test_part")
    s = np.linspace(0.0, path.length, 2 * _CHUNK + 123)
    big = path.derivs(s)
    for lo in (0, _CHUNK - 5, 2 * _CHUNK):
        small = path.derivs(s[lo:lo + 50])
        for d in range(4):
            assert np.array_equal(big[d][lo:lo + 50], small[d])


def test_a_remembered_evaluation_is_the_evaluation_and_a_copy():
    import pickle
    p = quarter_circle()
    s = np.linspace(0, p.length, 501)
    first = p.derivs(s)
    first[1][:] = 0.0                           # a caller's scribble does not reach the memo
    again = p.derivs(s)
    fresh = NurbsPath(p.degree, p.knots, p.control_points, p.weights).derivs(s)
    for a, b in zip(again, fresh):
        assert np.array_equal(a, b)
    assert np.array_equal(p.point(s), fresh[0])
    # another set of arc lengths is evaluated, not looked up; a pickled path is keyed anew
    assert not np.array_equal(p.derivs(s[::-1])[0], fresh[0])
    q = pickle.loads(pickle.dumps(p))
    assert q.__dict__["_memo_token"] is not p.__dict__["_memo_token"]
    assert np.array_equal(q.derivs(s)[2], fresh[2])
    # another path at the same arc lengths is its own
    other = quarter_circle(z=-390.0)
    assert np.allclose(other.point(s)[:, 2], -390.0, rtol=0, atol=1e-9)
