"""planners.trapezoid.queue / tp_blend / tp_plan (LinuxCNC 2.9's motion queue) against closed forms.

The numbers come from tp.c / blendmath.c / tc.c read at LinuxCNC f1270d6ed7 and worked out by
hand here; where the real LinuxCNC was run on the same program its figure is in the comment
(benchmarks/oracle/README.md has the rest).
"""
import math

import numpy as np
import pytest

from kins import load_machine
from planners import plan
from planners.trapezoid import queue as Q
from planners.paths.gcode import parse_gcode, program_path

# kossel-like: 1 ms period, 20 mm/s and 500 mm/s² on every axis, F_max 20 mm/s; a corner in
# the XY plane has a_max = 500 (blendmath.c calculateInscribedDiameter), a_n = 500·√0.75
KOSSEL = Q.Limits(1e-3, 20.0, 500.0, 20.0)
A_N = 500.0 * math.sqrt(0.75)


def queue(text, lim=KOSSEL):
    runs, _ = Q.build(parse_gcode(text).moves, lim)
    return [tc for r in runs for tc in r]


def corner(L, F, p=""):
    """Two lines of L mm at a 90° corner in XY, F mm/min, G64 [P…]."""
    return f"G21 G90 G17 G64 {p}\nG0 X0 Y0 Z0\nG1 X{L} F{F}\nY{L}\nM2\n"


def test_long_lines_take_the_parabolic_blend_radius():
    # blendComputeParameters: long lines at 10 mm/s, v_plan = F; the "equivalent parabolic
    # blend" at half the acceleration lasts v/(a/2) and covers s = 2v²/a: R = s/φ = 4v²/(π·a)
    v = 10.0
    line1, blend, line2 = queue(corner(40, 600))
    R = 4 * v * v / (math.pi * 500.0)
    assert R > v * v / A_N
    assert blend.kind == "blend" and blend.arc.radius == pytest.approx(R, rel=1e-12)
    assert blend.maxvel == pytest.approx(v, rel=1e-15)
    assert line1.target == pytest.approx(40.0 - R, rel=1e-12)          # d = R at 90°
    # into the arc tangent; the last G64 move stays PARABOLIC (half acceleration)
    assert (line1.term, blend.term, line2.term) == (Q.TANGENT, Q.TANGENT, Q.PARABOLIC)


def test_short_lines_are_room_limited():
    # 1 mm lines at 20 mm/s: half a line (0.5 mm) is the room; the arc's speed is what its
    # radius allows at the normal acceleration, √(a_n·R) ≈ 14.7 mm/s
    _, blend, _ = queue(corner(1, 1200))
    assert blend.arc.radius == pytest.approx(0.5, rel=1e-12)
    assert blend.maxvel == pytest.approx(math.sqrt(A_N * 0.5), rel=1e-12)


def test_blend_within_the_g64_p_tolerance():
    p = 0.01
    _, blend, _ = queue(corner(40, 600, "P0.01"))
    R = p / (math.sqrt(2) - 1)
    assert blend.arc.radius == pytest.approx(R, rel=1e-9)
    # the arc's middle is R(√2 − 1) = P from the corner (40, 0)
    mid = blend.arc.eval(np.array([blend.arc.length / 2]), 0)[0][0]
    assert np.linalg.norm(mid - [40, 0, 0]) == pytest.approx(p, rel=1e-9)
    assert blend.maxvel == pytest.approx(math.sqrt(A_N * R), rel=1e-9)


def test_line_arc_blends_follow_blendmath():
    # G64 P0.01 at 20 mm/s, benchmarks/oracle/programs/spiral_arcs.ngc's first corners.
    # arc → line: not convex (the line leaves the circle outwards), θ is half the 90°
    # interior angle, the radius the tolerance's P/(√2 − 1) as between lines. line → arc:
    # convex, φ2_max = min(π/3, π/4), θ = π/4 − φ2_max/4 = 3π/16, R = P·sinθ/(1 − sinθ).
    # The real LinuxCNC passes them at 3.231 and 2.323 mm/s (√(a_n·R) = 3.233 and 2.327)
    p = 0.01
    tcs = queue("G21 G90 G17 G64 P0.01\nG0 X5 Y0 Z0\nG3 X-5 Y0 I-5 J0 F1200\nG1 X-6\nG3 X6 Y0 I6 J0\nM2\n")
    assert [tc.kind for tc in tcs] == ["circle", "blend", "line", "blend", "circle"]
    R1 = p / (math.sqrt(2) - 1)
    th = 3 * math.pi / 16
    R2 = p * math.sin(th) / (1 - math.sin(th))
    blends = [tcs[1], tcs[3]]
    assert [b.arc.radius for b in blends] == [pytest.approx(R1, rel=1e-9), pytest.approx(R2, rel=1e-9)]
    assert [b.maxvel for b in blends] == [pytest.approx(math.sqrt(A_N * R1), rel=1e-9),
                                          pytest.approx(math.sqrt(A_N * R2), rel=1e-9)]
    # the circles keep their centres and radii, shortened by the trim angles
    assert tcs[0].arc.radius == pytest.approx(5.0) and tcs[-1].arc.radius == pytest.approx(6.0)
    assert tcs[0].arc.angle < math.pi and tcs[-1].arc.angle < math.pi


def test_clamp_by_length_one_period():
    # tc.c tcClampVelocityByLength: v ≤ L/T; again when the length is final (tcFinalizeLength)
    tc = Q.TC("line", 1, False, 0.15, 300.0, 300.0, 5000.0, Q.PARABOLIC, 0.0)
    Q.clamp_by_length(tc, 1e-3)
    assert tc.maxvel == pytest.approx(150.0, rel=1e-15)
    tc.target = 0.1
    Q.finalize(tc, 1e-3)
    assert tc.finalized and tc.maxvel == pytest.approx(100.0, rel=1e-15)


def test_many_tiny_collinear_moves_last_a_period_each(tmp_path):
    # 400 collinear moves of 5 µm at F1200: no corner (tpSetupTangent: a straight junction is
    # TANGENT, no blend arc), and each segment's max velocity is what lasts 1.02 periods
    # (tpComputeOptimalVelocity: L/(1.02·T) = 4.902 mm/s, below the 20 mm/s of F); the first
    # (never the later one of a look-ahead pair) and the last (never final) keep L/T
    # (tcClampVelocityByLength)
    text = "G21 G90 G64\nG0 X0 Y0 Z-250\nF1200\n" + "".join(f"G1 X{0.005 * (k + 1):.3f}\n" for k in range(400)) + "M2\n"
    tcs = queue(text)
    assert len(tcs) == 400 and all(tc.term == Q.TANGENT for tc in tcs[:-1])
    v = 0.005 / (1.02e-3)
    assert [tc.maxvel for tc in tcs[1:-1]] == [pytest.approx(v, rel=1e-12)] * 398
    assert [tcs[0].maxvel, tcs[-1].maxvel] == [pytest.approx(5.0, rel=1e-12)] * 2
    pr = plan("trapezoid", program_path(parse_gcode(text)), load_machine("kossel"))
    assert pr.sd.max() == pytest.approx(v, rel=1e-9)
    # 2 mm at 4.902 mm/s, plus the ramps (≈ v/a at 500 mm/s², the last move at 250: < 0.02 s)
    assert abs(pr.execution_time_s - 2.0 / v) < 0.02


def test_a_short_line_between_two_blends_is_consumed():
    # linuxcnc_delta-like limits (1 ms, 300 mm/s, 5000 mm/s²), F18000, G64 P0.05: 90° corners
    # A (10 mm) → B (0.3 mm) → C (10 mm). Each blend is tolerance-limited: R = d = P/(√2 − 1)
    # = 0.1207 mm at v_plan = √(a_n·R) = 22.9 mm/s. B keeps 0.3 − 2R = 0.0586 mm, which takes
    # 2.6 ms < ARC_BLEND_GAP_CYCLES (4) periods at 22.9 mm/s: blendCheckConsume pops B and the
    # second blend segment starts with it (spherical_arc.c arcPoint's line part)
    lim = Q.Limits(1e-3, 300.0, 5000.0, 300.0)
    tcs = queue("G21 G90 G17 G64 P0.05\nG0 X0 Y0 Z0\nG1 X10 F18000\nY0.3\nX0\nM2\n", lim)
    assert [tc.kind for tc in tcs] == ["line", "blend", "blend", "line"]
    R = 0.05 / (math.sqrt(2) - 1)
    b2 = tcs[2]
    assert b2.line_length == pytest.approx(0.3 - 2 * R, rel=1e-9)
    assert b2.target == pytest.approx(R * math.pi / 2 + 0.3 - 2 * R, rel=1e-9)
    assert b2.maxvel == pytest.approx(math.sqrt(5000.0 * math.sqrt(0.75) * R), rel=1e-9)
    # the geometry is contiguous: line, arc, the consumed piece of B, arc, line
    pr = plan("trapezoid", program_path(parse_gcode("G21 G90 G17 G64 P0.05\nG0 X0 Y0 Z0\nG1 X10 F18000\n"
                                                    "Y0.3\nX0\nM2\n")), load_machine("linuxcnc_delta"))
    assert [g.kind for g in pr.path.segments] == ["line", "arc", "line", "arc", "line"]
    assert pr.info["consumed_lines"] == 1


SQUARE = "G21 G90 G17 {mode}\nG0 X-10 Y-10 Z-250\nG1 X10 F1200\nG1 Y10\nG1 X-10\nM2\n"


def test_g61_exact_path_keeps_the_kink_acceleration_reduction():
    # G61 (TC_TERM_COND_EXACT): tpSetupTangent sets the kink properties of a 90° corner
    # (acceleration reduced by ARC_BLEND_KINK_RATIO = 0.1 on both segments), no blend is
    # made, and tpChooseBestBlend leaves EXACT as it is: each 20 mm line runs rest to rest at
    # 0.9·500 = 450 mm/s², 3·(20/20 + 20/450) = 3.133 s (LinuxCNC: 3.135 s). G61.1 (STOP) stops
    # before any of that: 3·(1 + 20/500) = 3.120 s (LinuxCNC: 3.120 s)
    kossel = load_machine("kossel")
    g61 = plan("trapezoid", program_path(parse_gcode(SQUARE.format(mode="G61"))), kossel)
    g611 = plan("trapezoid", program_path(parse_gcode(SQUARE.format(mode="G61.1"))), kossel)
    assert abs(g61.execution_time_s - 3 * (1 + 20 / 450)) <= 3 * g61.T
    assert abs(g611.execution_time_s - 3 * (1 + 20 / 500)) <= 3 * g611.T
    assert np.abs(np.diff(g61.sd)).max() / g61.T == pytest.approx(450.0, rel=1e-9)
    assert g61.info["exact_stops"] == g611.info["exact_stops"] == 2


def test_g61_runs_through_collinear_moves():
    # G61 is exact *path*: two collinear 0.4 mm moves are TANGENT (tpSetupTangent). The last
    # move is never finalized, so the first ends at √(a·L₂) = 14.1 mm/s (it could stop within
    # half of the last: tpCalculateOptimizationInitialVel); each move peaks at
    # √((2aL + v_f²)/2) = 17.3 mm/s: 2·(17.3 + (17.3 − 14.1))/500 = 0.082 s (LinuxCNC: 0.083 s).
    # G61.1 stops between them: 2·2·√(0.4/500) = 0.113 s
    text = "G21 G90 G17 {mode}\nG0 X-0.4 Y0 Z-250\nG1 X0 F1200\nG1 X0.4\nM2\n"
    kossel = load_machine("kossel")
    vf, vp = math.sqrt(500 * 0.4), math.sqrt((2 * 500 * 0.4 + 500 * 0.4) / 2)
    t = plan("trapezoid", program_path(parse_gcode(text.format(mode="G61"))), kossel).execution_time_s
    assert abs(t - 2 * (vp + vp - vf) / 500) <= 2e-3
    t = plan("trapezoid", program_path(parse_gcode(text.format(mode="G61.1"))), kossel).execution_time_s
    assert abs(t - 4 * math.sqrt(0.4 / 500)) <= 2e-3


def test_a_line_into_a_helix_is_a_parabolic_blend():
    # the line and the helix of benchmarks/oracle/programs/delta_star.ngc: not coplanar, no
    # blend arc (tpCreateLineArcBlend), and tpChooseBestBlend takes the parabolic blend over
    # the kink. Both segments move at once (tpDoParabolicBlending): the speed dips but never
    # stops (LinuxCNC: 44.5 mm/s at the bottom, from 100)
    text = ("G21 G90 G17 G64\nG0 X0 Y50 Z0\nG1 X0 Y20 Z-10 F6000\nG2 X0 Y20 Z-20 I0 J-20\nM2\n")
    pr = plan("trapezoid", program_path(parse_gcode(text)), load_machine("linuxcnc_delta"))
    assert pr.info["parabolic_blends"] == 1 and pr.info["exact_stops"] == 0
    k = int(np.argmin(np.abs(pr.s - 31.6228)))                     # the junction: √(30² + 10²)
    assert pr.sd[k - 100:k + 100].min() == pytest.approx(44.5, rel=0.05)


def test_circle_tangential_acceleration_share_as_tc_update_circle_acc_ratio():
    # tc.c tcUpdateCircleAccRatio / blendmath.c pmCircleActualMaxVel: a G2/G3 arc of radius
    # 10 whose machine speed is 20 mm/s needs v²/ρ = 40 mm/s² of the 500 normally, and gets
    # √(1 − (40/500)²) of 500 tangentially once final; the last move (never final) keeps 0.5.
    # All junctions are tangent (G61 exact path runs through them)
    tcs = queue("G21 G90 G17 G61\nG0 X-10 Y-10 Z-250\nG1 X10 F900\n"
                "G3 X10 Y10 I0 J10\nG1 X-10\nG3 X-10 Y-10 I0 J-10\nM2\n")
    assert [tc.kind for tc in tcs] == ["line", "circle", "line", "circle"]
    assert all(tc.term == Q.TANGENT for tc in tcs[:-1])
    assert Q.tangential_acc(tcs[1]) == pytest.approx(500.0 * math.sqrt(1 - (40.0 / 500.0) ** 2), rel=1e-9)
    assert Q.tangential_acc(tcs[3]) == pytest.approx(250.0, rel=1e-9)
    assert tcs[1].maxvel == tcs[3].maxvel == pytest.approx(20.0)


@pytest.mark.parametrize("machine,text", [
    ("linuxcnc_delta", "G21 G90 G17 G64\nG0 X0 Y50 Z0\nG1 X0 Y20 Z-10 F6000\nG2 X0 Y20 Z-20 I0 J-20\nM2\n"),
    ("kossel", "G21 G90 G17 G64 P0.01\nG0 X0 Y0 Z-250\nF1200\n"
               + "".join(f"G1 X{0.3 * (k + 1):.3f} Y{0.2 * (k % 2):.3f}\n" for k in range(60)) + "M2\n")])
def test_program_profiles_are_valid_on_their_contiguous_geometry(machine, text):
    # the queue's segments (a parabolic blend's polyline, consumed lines) laid end to end:
    # SegmentPath refuses a gap; the profile runs forwards from rest to rest on it, and its
    # path is where the tool is at each period: the period's chord is the speed's integral
    m = load_machine(machine)
    pr = plan("trapezoid", program_path(parse_gcode(text)), m)
    pr.validate()
    assert (np.diff(pr.s) >= 0).all() and pr.sd[0] == pr.sd[-1] == 0.0
    P = pr.path.point(pr.s)
    chord = np.linalg.norm(np.diff(P, axis=0), axis=1)
    assert (chord <= np.diff(pr.s) + 1e-9).all()          # a chord is never longer than its arc
    assert np.abs(np.diff(pr.s) - 0.5 * (pr.sd[:-1] + pr.sd[1:]) * pr.T).max() < 0.05 * m.limits.feed_max * pr.T


def test_a_short_tangent_segment_ramps_evenly_to_its_final_speed():
    # tp.c tpActivateSegment / tpCalculateRampAccel: a tangent segment that lasts less than
    # 1/ARC_BLEND_RAMP_FREQ (10 ms) from its first full period on accelerates at the constant
    # (v_f² − v²)/(2·dx) that reaches its final speed at its end, not at the limit (500 mm/s²)
    from planners.trapezoid.cycle import simulate
    L, T = [5.0, 0.05, 5.0], 1e-3
    runs = [simulate(L, [19.0, 20.0, 20.0], [500.0] * 3, [19.0, 20.0, 0.0], T, sum(L), ramps=r)
            for r in (None, [None, 20.0, None])]
    for (s, sd, _, _), ramp in zip(runs, (False, True)):
        s, sd = np.array(s), np.array(sd)
        k = int(np.nonzero(s > 5.0)[0][0])              # the first sample on the short segment
        v, dx = sd[k], 5.05 - s[k]
        assert 2 * dx / (v + 20.0) < 0.01
        expected = (20.0 ** 2 - v ** 2) / (2 * dx) if ramp else 500.0
        assert (sd[k + 1] - sd[k]) / T == pytest.approx(expected, rel=1e-9)


def test_arc_bounds_are_emccanon_arc_feed_closed_forms():
    """emccanon.cc ARC_FEED in closed form: a flat half circle of r = 10 mm under a = 5000 mm/s²
    runs within √(a·√3/2·r) = 208.1 mm/s and gets a = π r / (π r / a) = 5000 mm/s²; a helix
    of 3.5 turns (r = 6.657 mm, 16 mm rise) gets that planar bound stretched by its length
    over its planar length, not the tp's r + h²/r with the whole rise (45 mm: 442 mm/s)."""
    from planners.paths import Arc
    lim = Q.Limits(1e-3, 300.0, 5000.0, 300.0)
    half = Arc([10, 0, 0], [0, 0, 0], [0, 0, 1], math.pi)
    v, a = Q.arc_feed_limits(half, lim)
    assert v == pytest.approx(math.sqrt(5000 * math.sqrt(3) / 2 * 10), rel=1e-12) and a == pytest.approx(5000, rel=1e-12)
    r, turns, rise = 6.6573, 3.5, 16.0
    helix = Arc([r, 0, 0], [0, 0, 0], [0, 0, 1], 2 * math.pi * turns, rise)
    v, _ = Q.arc_feed_limits(helix, lim)
    planar = 2 * math.pi * turns * r
    assert v == pytest.approx(math.sqrt(5000 * math.sqrt(3) / 2 * r) * math.hypot(planar, rise) / planar, rel=1e-12)


def _cam_text(n_lines: int, cycles: bool) -> str:
    import importlib.util
    from pathlib import Path
    spec = importlib.util.spec_from_file_location(
        "cam_program", Path(__file__).resolve().parents[1] / "benchmarks" / "perf" / "cam_program.py")
    cam = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(cam)
    return cam.make_cam_program(n_lines, seed=5, cycles=cycles)


@pytest.mark.parametrize("text", [
    "cam",
    # a line into a helix, a spiral, rapids, G61 exact stops and a G61.1 stop between blends
    "G21 G90 G17 G64 P0.05\nG0 X0 Y0 Z-250\nG1 X30 F1500\nG3 X30 Y20 Z-245 I0 J10\nG2 X20 Y10 I-5 J-5\n"
    "G0 X-20\nG61\nG1 Y-20 F900\nX0\nG61.1\nG1 X10 F3000\nG64\nY0\nX20 Y0.2\nM2\n"])
def test_runs_of_periods_are_the_per_period_loop_bit_for_bit(monkeypatch, text):
    # planners.trapezoid.cycle runs cruise and full-acceleration periods as numpy passes: the
    # same floats as the loop taking every period itself (min_run beyond any run), blends,
    # exact stops, ramps and the parabolic blends' trace included
    from planners.trapezoid import cycle
    from planners.trapezoid.program import queue_arrays
    text = _cam_text(400, cycles=True) if text == "cam" else text
    runs, _ = Q.build(parse_gcode(text).moves, KOSSEL)
    tcs, L, vt, acc, vf, blends, stops, _ = queue_arrays(runs, KOSSEL)
    ramps = [tc.finalvel if tc.term == Q.TANGENT and not tc.rapid else None for tc in tcs]
    args = (L, vt, acc, vf, KOSSEL.T, float(np.sum(L)), blends, stops, ramps)
    in_runs = []
    for name in ("_cruise", "_accelerate"):
        f = getattr(cycle, name)
        monkeypatch.setattr(cycle, name, lambda *a, f=f: in_runs.append(len((r := f(*a))[0])) or r)
    s, sd, excess, trace = cycle.simulate(*args)
    s0, sd0, excess0, trace0 = cycle.simulate(*args, min_run=len(s) + 1)
    assert s.tobytes() == s0.tobytes() and sd.tobytes() == sd0.tobytes()
    assert excess == excess0 and trace == trace0
    # what the case is there for: the CAM program's parabolic blends, the other's stops
    assert len(trace) > 0 if text.startswith("%") else len(stops) > 3
    assert sum(in_runs) > len(s) / 2              # most periods ran in numpy passes


def test_points_are_point_bit_for_bit():
    # planners.trapezoid.program.points (a blend's periods at once) against point, one arc
    # length at a time, on a line, a circle, a helix and a spiral laid end to end, at and
    # between their joins, before 0 and past the end
    from planners.paths import Arc, Line
    from planners.trapezoid.program import point, points
    line = Line([0.0, 0.0, -250.0], [10.0, 0.0, -250.0])
    circle = Arc([10.0, 0.0, -250.0], [10.0, 5.0, -250.0], [0, 0, 1], 2.0)
    helix = Arc(circle.end, circle.end + np.array([-3.0, 1.0, 0.0]), [0, 0, 1], 4.0, rise=2.5)
    spiral = Arc(helix.end, helix.end + np.array([2.0, 2.0, 0.0]), [0, 0, -1], 3.0, spiral=1.5)
    segs = [line, circle, helix, spiral]
    joins = np.cumsum([g.length for g in segs])
    xs = np.concatenate([[-1e-9, 0.0], joins, joins - 1e-13, joins + 1e-13,
                         np.random.default_rng(2).uniform(0, joins[-1] + 1.0, 300)])
    P, U = points(segs, xs)
    for x, p, u in zip(xs.tolist(), P, U):
        p0, u0 = point(segs, x)
        assert p.tobytes() == np.asarray(p0, float).tobytes() and u.tobytes() == np.asarray(u0, float).tobytes()


def test_a_sync_drains_the_queue_before_a_rapid_feed_change():
    # G1, G4 P0, G0: the dwell waits for the queue to drain (emctaskmain.cc: EMC_TRAJ_DELAY waits
    # for motion), so the G1 is the last segment queued while it runs and keeps G64's PARABOLIC
    # term: half the acceleration, both ways (tc.c tcGetOverallMaxAccel). tp.c handleModeChange
    # would make it STOP only if the G0 were queued behind it (tcqLast): it never is. Before,
    # the G1 ran at the full 500 mm/s² (D1MiniGSR_front.ngc: 6 ms lost per pass in LinuxCNC).
    text = "G21 G90 G64\nG0 X0 Y0 Z-250\nG1 X10 F600\nG4 P0\nG0 X20\nM2\n"
    p = program_path(parse_gcode(text))
    assert [m.stop for m in p.program.moves] == ["sync", "end"]
    runs, _ = Q.build(p.program.moves, KOSSEL)
    assert [[tc.term for tc in r] for r in runs] == [[Q.PARABOLIC], [Q.PARABOLIC]]
    pr = plan("trapezoid", p, load_machine("kossel"))
    # 10 mm at 10 mm/s with a/2 = 250 both ways, then 10 mm at 20 mm/s with 250 both ways; the
    # dwell's rest is the period the G1 ends in
    t = (10 / 10 + 10 / 250) + (10 / 20 + 20 / 250)
    assert abs(pr.execution_time_s - t) <= 3 * pr.T


def _tool_program(tmp_path, text):
    from planners.paths.gcode import read_gcode
    from planners.paths.gcode.rs274.setup import make_setup
    (tmp_path / "t.tbl").write_text("T1 P1 Z0 D1 ;\nT2 P2 Z0 D2 ;\n")
    f = tmp_path / "tool.ngc"
    f.write_text(text)
    return program_path(read_gcode(f, setup=make_setup(tmp_path / "t.tbl", None, [])))


def test_a_tool_change_waits_two_and_a_half_io_cycles(tmp_path):
    # M6 is two io commands (interp_convert.cc convert_tool_change: START_CHANGE, then
    # emccanon.cc CHANGE_TOOL's EMC_TOOL_LOAD); the first meets the free-running io cycle at a
    # random phase (mean ½ cycle), the second waits a cycle (taskclass.cc sendCommand), and a new
    # tool keeps io busy one cycle more (ioControl.cc read_tool_inputs): 2.5 × 0.1 s. The same
    # tool again: no handshake (EMC_TOOL_LOAD), 1.5 cycles. Tool 1 → 2: 2.5 cycles; coolant
    # on the same stop continues the chain (M8: one more command). A T's EMC_TOOL_PREPARE waits
    # for io only, not motion: it goes out while the 0.5 s move before still runs, done by its end
    from planners.trapezoid.program import move_waits
    text = ("G21 G90 G64\nG0 X0 Y0 Z-250\nT1\nG1 X5 F600\nM6\nG1 X10\nT1 M6\nG1 X15\nT2 M6\n"
            "G1 X20\nT1\nM6 M8\nG1 X25\nM2\n")
    p = _tool_program(tmp_path, text)
    # each stop also takes task's time: a cycle, a period, a period for M6's spindle stop
    task = 0.001 + 2 * 0.001
    assert move_waits(p.program, 0.001) == {0: pytest.approx(0.25 + task), 1: pytest.approx(0.15 + task),
                                            2: pytest.approx(0.25 + task), 3: pytest.approx(0.35 + task)}
    pr = plan("trapezoid", p, load_machine("kossel"))
    assert np.count_nonzero(pr.sd[1:-1] == 0.0) * pr.T == pytest.approx(1.0 + 4 * task + 4 * pr.T, abs=pr.T / 2)


def test_task_time_at_a_sync_is_a_cycle_a_period_and_a_period_per_message_to_motion(tmp_path):
    # emctaskmain.cc: task sees the drained queue at its next cycle; every message it then hands
    # to motion (the next move, SET_SPINDLE_SPEED, spindle on/off, a pause and its resume) waits
    # a servo period for the echo (usrmotintf.cc usrmotWriteEmcmotCommand); a dwell's timeout is
    # polled once a cycle (half a cycle more on average). Here the period T = 2 ms ≠ the cycle.
    from planners.trapezoid.program import move_waits
    text = ("G21 G90 G64\nG0 X0 Y0 Z-250\nG1 X1 F600\nG4 P0\nG1 X2\nS1000\nG1 X3\nM5\nM3 S900\n"
            "G1 X4\n(MSG,hello)\nG1 X5\nG4 P0.5\nG1 X6\nM0\nG1 X7\nM70\nG1 X8\nM2\n")
    p = _tool_program(tmp_path, text)
    T, c = 0.002, 0.001
    assert move_waits(p.program, T) == {
        0: pytest.approx(c + T), 1: pytest.approx(c + 2 * T), 2: pytest.approx(c + 4 * T),
        3: pytest.approx(c + T), 4: pytest.approx(0.5 + 1.5 * c + T), 5: pytest.approx(c + 3 * T)}
    # and every one of them stops the move before it (M70 only saves the modal state)
    assert [m.stop for m in p.program.moves[:-1]] == ["sync"] * 6 + [None]


def test_an_output_set_with_motion_is_no_sync_one_set_now_is(tmp_path):
    # M62/M63 ride with the next move (EMC_MOTION_SET_DOUT, now = 0: emcTaskCheckPreconditions
    # DONE); M64/M65 set the pin now and wait for motion, one message to motion. Against the real
    # LinuxCNC (60 of each between 10 mm moves at F1200): M62/M63 32.981 s, trapezoid 32.980;
    # M64/M65 35.579 s, trapezoid 35.560
    from planners.trapezoid.program import move_waits
    text = "G21 G90 G64\nG0 X0 Y0 Z-250\nG1 X1 F600\nM62 P0\nG1 X2\nM63 P0\nG1 X3\nM64 P0\nG1 X4\nM65 P0\nG1 X5\nM2\n"
    p = _tool_program(tmp_path, text)
    assert [m.stop for m in p.program.moves[:-1]] == [None, None, "sync", "sync"]
    assert move_waits(p.program, 0.001) == {2: pytest.approx(0.003), 3: pytest.approx(0.003)}
