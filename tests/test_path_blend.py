"""planners.paths.blend: G64 corner arcs against closed forms; NURBS → G1 lines within the chord tolerance."""
import math

import numpy as np
import pytest

from planners.paths.blend import blend_corners
from planners.paths.lines import cut_into_lines
from planners.paths import Arc, Line, NurbsPath, SegmentPath


def corner(L1=10.0, L2=10.0):
    return [Line([0, 0, 0], [L1, 0, 0]), Line([L1, 0, 0], [L1, L2, 0])]


def test_right_angle_within_tolerance():
    p_tol = 0.1
    segs, done = blend_corners(corner(), [p_tol])
    path = SegmentPath(segs)
    R = p_tol / (math.sqrt(2) - 1)                 # e = R(sec(δ/2) − 1), δ = 90°
    arc = [g for g in segs if g.kind == "arc"][0]
    assert arc.radius == pytest.approx(R, rel=1e-12)
    assert arc.angle == pytest.approx(math.pi / 2)
    assert np.allclose(arc.center, [10 - R, R, 0])
    assert path.length == pytest.approx(20 - 2 * R + R * math.pi / 2, rel=1e-12)
    assert len(path.corners()) == 0                # G1-continuous
    s, P = path.sample(1e-4)
    assert np.linalg.norm(P - [10, 0, 0], axis=1).min() == pytest.approx(p_tol, abs=1e-8)
    assert done == [(0, pytest.approx(p_tol))]
    k = path.curvature(path.seg_start[1] + arc.length / 2)
    assert k == pytest.approx(1 / R)


def test_room_limited_blend_uses_half_the_shorter_line():
    segs, done = blend_corners(corner(10.0, 4.0), [math.inf])   # G64 without P
    arc = [g for g in segs if g.kind == "arc"][0]
    assert arc.radius == pytest.approx(2.0)                      # d = R·tan(45°) = 4/2
    assert done[0][1] == pytest.approx(2.0 * (math.sqrt(2) - 1))
    assert segs[-1].length == pytest.approx(2.0)                 # half of the 4 mm line is left


def test_exact_stop_collinear_reversal_and_arc_corners_are_kept():
    segs, done = blend_corners(corner(), [None])
    assert done == [] and len(SegmentPath(segs).corners()) == 1
    straight = [Line([0, 0, 0], [1, 0, 0]), Line([1, 0, 0], [3, 0, 0])]
    assert blend_corners(straight, [0.1])[1] == []
    back = [Line([0, 0, 0], [1, 0, 0]), Line([1, 0, 0], [0.5, 0, 0])]
    assert blend_corners(back, [0.1])[1] == []
    arc = Arc([1, 0, 0], [1, 1, 0], [0, 0, 1], math.pi / 2)      # starts heading +x… then turns
    with_arc = [Line([1, -1, 0], [1, 0, 0]), arc]                  # line heads +y: 90° corner
    segs, done = blend_corners(with_arc, [0.1])
    assert done == [] and len(SegmentPath(segs).corners()) == 1


def test_consecutive_blends_never_overlap():
    # a zig-zag of 1 mm lines with G64 (no tolerance): every line is shared by two blends
    pts = [[i, (i % 2) * 1.0, 0] for i in range(8)]
    lines = [Line(a, b) for a, b in zip(pts[:-1], pts[1:])]
    segs, done = blend_corners(lines, [math.inf] * (len(lines) - 1))
    path = SegmentPath(segs)                       # would raise if not contiguous
    assert len(done) == len(lines) - 1 and len(path.corners()) == 0
    assert all(g.length > 0 for g in segs)


def test_cut_circle_into_lines():
    R, W = 30.0, math.sqrt(0.5)
    P = [[R, 0], [R, R], [0, R], [-R, R], [-R, 0], [-R, -R], [0, -R], [R, -R], [R, 0]]
    circle = NurbsPath(2, [0, 0, 0, .25, .25, .5, .5, .75, .75, 1, 1, 1],
                       [[x, y, 0] for x, y in P], [1, W, 1, W, 1, W, 1, W, 1])
    tol = 1e-3
    poly, dev = cut_into_lines(circle, tol)
    # sagitta of a chord ℓ on radius R: R(1 − cos(ℓ/2R)); check every chord independently
    chords = np.array([g.length for g in poly.segments])
    sag = R * (1 - np.cos(np.arcsin(chords / (2 * R))))
    assert sag.max() <= tol and dev <= tol
    assert dev == pytest.approx(sag.max(), rel=1e-3)
    n_min = math.ceil(2 * math.pi / (2 * math.acos(1 - tol / R)))   # fewest chords possible
    assert n_min <= len(chords) <= 1.2 * n_min
    # the vertices are on the circle
    V = np.array([g.start for g in poly.segments])
    assert np.abs(np.linalg.norm(V[:, :2], axis=1) - R).max() < 1e-9


from hypothesis import given, settings, strategies as st  # noqa: E402


@settings(max_examples=30, deadline=None, derandomize=True)
@given(st.lists(st.tuples(st.floats(-50, 50), st.floats(-50, 50), st.floats(-20, 20)),
                min_size=3, max_size=12),
       st.sampled_from([0.001, 0.05, 1.0, math.inf]))
def test_blended_polylines_are_contiguous_g1_and_within_tolerance(pts, tol):
    P = [np.array(pts[0], float)]
    for q in pts[1:]:
        if np.linalg.norm(np.array(q) - P[-1]) > 0.01:
            P.append(np.array(q, float))
    if len(P) < 3:
        return
    lines = [Line(a, b) for a, b in zip(P[:-1], P[1:])]
    segs, done = blend_corners(lines, [tol] * (len(lines) - 1))
    path = SegmentPath(segs)                                   # contiguity is checked here
    original = SegmentPath(lines)
    assert path.length <= original.length + 1e-9              # an arc is shorter than its corner
    arcs = [g for g in segs if g.kind == "arc"]
    assert len(arcs) == len(done)
    for arc, (i, dev) in zip(arcs, done):                      # each blend within its tolerance
        assert dev <= tol * (1 + 1e-9)
        # the arc's middle is R(sec(θ/2) − 1) from the corner it replaces
        mid = arc.eval(np.array([arc.length / 2]), 0)[0][0]
        # (a nearly straight corner's arc has R ~ 10⁷ mm: its points carry R·ε of rounding; one
        # run of the fast tier read 1.08e-9 mm there, a re-run passed)
        assert np.linalg.norm(mid - lines[i].end) == pytest.approx(
            dev, rel=1e-6, abs=1e-9 + 8 * np.finfo(float).eps * arc.radius)
        # tangent to both lines
        assert np.allclose(arc.tangent_in(), lines[i].direction, atol=1e-9)
        assert np.allclose(arc.tangent_out(), lines[i + 1].direction, atol=1e-9)
    # every remaining corner is one that could not be blended (reversal)
    turns = [math.acos(np.clip(lines[i].direction @ lines[i + 1].direction, -1, 1))
             for i in range(len(lines) - 1)]
    kept = sum(1 for t in turns if t >= math.pi - 1e-6)
    assert len(path.corners()) == kept


def test_blend_arcs_built_column_wise_equal_arc_exact(tmp_path):
    """blend_corners derives every arc's frame, radius, length and end for all corners at
    once: each equals, bit for bit, what Arc.exact (one arc at a time) derives from the same
    start, centre, normal and angle; trimmed lines keep their direction."""
    from planners.paths.gcode import load_gcode_path
    f = tmp_path / "p.ngc"
    f.write_text("G21 G90 G64 P0.05\nG0 X0 Y0 Z-250\nF600\n"
                 + "".join(f"G1 X{(k + 1) * 0.7:.3f} Y{0.3 * (k % 3):.3f} Z{-250 + 0.1 * (k % 2):.3f}\n"
                           for k in range(40)) + "M2\n")
    path = load_gcode_path(f)
    arcs = [g for g in path.segments if g.kind == "arc"]
    assert len(arcs) > 20
    for g in arcs:
        ref = Arc.exact(g.start, g.center, g.normal, g.angle, g.line)
        for attr in ("a", "b", "end"):
            assert np.array_equal(getattr(g, attr), getattr(ref, attr))
        assert g.radius == ref.radius and g.length == ref.length
    for g in path.segments:
        if g.kind == "line":
            assert np.abs(g.start + g.length * g.direction - g.end).max() < 1e-12
