"""planners.trapezoid.planner (LinuxCNC type 0) against closed forms and the independent metrics."""
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from planners.verify import command_metrics
from kins import load_machine
from planners import PlanningError, get_planner, plan
from planners.paths import Arc, Line, SegmentPath, resolve_path


@pytest.fixture(scope="module")
def keops():
    return load_machine("keops")


def x_line(D, z=-400.0):
    return SegmentPath([Line([-D / 2, 0, z], [D / 2, 0, z])])


@pytest.mark.parametrize("D", [200.0, 100.0, 50.0, 3.0])
def test_straight_line_closed_form(keops, D):
    v, a = keops.limits.cartesian.v, keops.limits.cartesian.a
    t_exact = D / v + v / a if D >= v * v / a else 2 * math.sqrt(D / a)
    pr = plan("trapezoid", x_line(D), keops)
    assert abs(pr.execution_time_s - t_exact) <= pr.T
    assert pr.s[0] == 0 and pr.s[-1] == D
    assert pr.sd[0] == pr.sd[-1] == 0 and pr.sdd[0] == pr.sdd[-1] == 0
    assert pr.sd.max() <= v * (1 + 1e-12)
    assert np.abs(pr.sdd).max() <= a * (1 + 1e-9)


def test_profile_integrals_consistent(keops):
    pr = plan("trapezoid", resolve_path("helix"), keops)
    # LinuxCNC advances by the trapezoidal rule: Δs = (v_k + v_{k+1})·T/2 except on the last step
    ds = np.diff(pr.s)[:-1]
    assert np.abs(ds - 0.5 * (pr.sd[:-2] + pr.sd[1:-1]) * pr.T).max() < 1e-9
    assert np.allclose(np.diff(pr.sd)[:-1] / pr.T, pr.sdd[1:-1])
    assert np.allclose(np.diff(pr.sdd) / pr.T, pr.sddd[1:])
    assert (np.diff(pr.s) >= 0).all()


def test_helix_speed_capped_alike_on_a_segment_path_and_in_linuxcncs_queue(keops, tmp_path):
    # LinuxCNC caps a G2/G3 twice: ARC_FEED's planar speed √(a_n·r) stretched over the helix
    # (= √(a_n·(r + (h/θ)²/r))) and, once finalized, pmCircleEffectiveMinRadius r + h²/r (whole
    # rise h): on 3 turns the first binds; the segment-path planner and the queue replica (a
    # program with a line after the helix, so it is finalized) agree
    from planners.paths.gcode import load_gcode_path
    r, theta, rise = 5.0, 6 * math.pi, 10.0
    cap = math.sqrt(0.866025403784 * keops.limits.cartesian.a * (r + (rise / theta) ** 2 / r))
    assert cap < 0.5 * keops.limits.cartesian.v           # the cap, not the machine speed, binds
    arc = Arc([r, 0.0, -405.0], [0.0, 0.0, -405.0], [0.0, 0.0, 1.0], theta, rise=rise)
    pr = plan("trapezoid", SegmentPath([arc, Line([r, 0, -395.0], [r, 0, -365.0])]), keops)
    assert pr.sd[pr.s < arc.length - 1e-6].max() == pytest.approx(cap, rel=1e-6)
    ngc = tmp_path / "helix.ngc"
    ngc.write_text(f"G21 G90 G64\nG0 X{r} Y0 Z-405\nG3 X{r} Y0 Z-395 I{-r} J0 P3 F60000\nG1 Z-365\nM2\n")
    prog = plan("trapezoid", load_gcode_path(ngc), keops, programmed_feed=False)
    assert prog.sd[prog.s < arc.length - 1e-6].max() == pytest.approx(cap, rel=1e-6)


def test_arc_speed_radius_is_the_smaller_of_linuxcncs_two_rules():
    from planners.trapezoid.rules import arc_speed_radius, effective_min_radius
    r, h = 20.0, 10.0
    for theta in (0.5, 1.0, 3.0, 20.0):
        stretched, whole = r + (h / theta) ** 2 / r, r + h ** 2 / r
        assert effective_min_radius(r, theta, h, 0.0) == pytest.approx(whole, rel=1e-15)
        assert arc_speed_radius(r, theta, h, 0.0) == pytest.approx(min(stretched, whole), rel=1e-15)
    # a spiral: (r² + k²)^1.5 / (r² + 2k²), k = dr/dφ, the radius of curvature of r(φ) = r + kφ
    k = 2.0
    assert effective_min_radius(r, 1.0, 0.0, k) == pytest.approx((r * r + k * k) ** 1.5 / (r * r + 2 * k * k))


def test_bird_cartesian_limits_and_geometry(keops):
    bird = resolve_path("bird")
    pr = plan("trapezoid", bird, keops)
    m = command_metrics(keops, pr.path.point(pr.s), pr.T, pr.s)
    c = m["cartesian_peak_ratio"]
    # LinuxCNC limits Cartesian velocity/acceleration only: no jerk limit (it breaks it)
    assert c["velocity"] <= 1 + 1e-6 and c["feed"] <= 1 + 1e-6
    assert c["acceleration"] <= 1 + 1e-6
    assert c["jerk"] > 1
    info = pr.info
    assert info["chord_deviation_mm"] <= keops.limits.chord_error_mm
    assert info["blend_deviation_mm"] <= keops.limits.chord_error_mm * (1 + 1e-9)
    # the planned geometry stays within the claimed deviation of the NURBS
    s, P = pr.path.sample(0.05)
    # nearest NURBS point of each planned point: start at the same arc length, then project
    # (Newton on the foot point: σ ← σ + (P − C(σ))·C′(σ))
    sig = np.clip(s * bird.length / pr.path.length, 0, bird.length)
    for _ in range(4):
        C, d1 = bird.derivs(sig)[:2]
        sig = np.clip(sig + np.sum((P - C) * d1, axis=1), 0, bird.length)
    dist = np.linalg.norm(P - bird.point(sig), axis=1)
    assert dist.max() <= info["geometry_deviation_mm"] * (1 + 1e-6)
    assert dist.max() > 0.5 * keops.limits.chord_error_mm        # the bound is not slack
    assert pr.path.length == pytest.approx(bird.length, abs=0.05)
    assert 1.0 < pr.execution_time_s < 3.0


def test_exact_stop_corner_and_gcode_program(keops):
    # two G61 lines with a right angle: the profile passes the corner at rest
    p = SegmentPath([Line([0, 0, -400], [50, 0, -400]), Line([50, 0, -400], [50, 50, -400])])
    pr = plan("trapezoid", p, keops)
    k = int(np.argmin(np.abs(pr.s - 50.0)))
    assert pr.sd[k] <= keops.limits.cartesian.a * pr.T * 1.01
    m = command_metrics(keops, pr.path.point(pr.s), pr.T, pr.s)
    assert m["cartesian_peak_ratio"]["acceleration"] <= 1.0 + 1e-6


def test_registry_and_bad_input(keops):
    assert get_planner("trapezoid").__module__ == "planners.trapezoid.planner"
    with pytest.raises(PlanningError, match="unknown planner.*nope; valid: trapezoid, scurve"):
        get_planner("nope")
    bad = replace(keops.limits, cartesian=replace(keops.limits.cartesian, a=0.0))
    with pytest.raises(PlanningError, match="cartesian limit a = 0.0 must be"):
        plan("trapezoid", x_line(10.0), keops, bad)
    with pytest.raises(PlanningError, match="feed_max"):
        plan("trapezoid", x_line(10.0), keops, replace(keops.limits, feed_max=-1.0))
    import copy
    zero_T = copy.copy(keops)
    zero_T.servo_period_s = 0.0
    with pytest.raises(PlanningError, match="servo period 0.0 s of keops must be > 0"):
        plan("trapezoid", x_line(10.0), zero_T)
    with pytest.raises(PlanningError, match="chord tolerance"):
        plan("trapezoid", resolve_path("bird"), keops, chord_tolerance_mm=0.0)
    # kossel: inside its box, but joint 2 passes its 25 mm top near z = −153 at x = y = −45
    kossel = load_machine("kossel")
    high = SegmentPath([Line([-45, -45, -200], [-45, -45, -130])], "high.json")
    with pytest.raises(PlanningError) as e:
        plan("trapezoid", high, kossel)
    msg = str(e.value)
    assert msg.startswith("high.json: the path leaves the workspace of kossel at s = 47")
    assert "[joint 2]" in msg and "(-45, -45, -153)" in msg and "stroke limit 25 mm" in msg
    wide = SegmentPath([Line([0, 0, -400], [150, 0, -400])], "wide.json")
    with pytest.raises(PlanningError, match=r"s = 100\.5 mm: point #201 \(100\.5, 0, -400\): outside the workspace box"):
        plan("trapezoid", wide, keops)


def test_deterministic_and_gcode_part_on_kossel(tmp_path):
    kossel = load_machine("kossel")
    part = resolve_path("test_part.ngc")
    a = plan("trapezoid", part, kossel)
    b = plan("trapezoid", part, kossel)
    fa, fb = tmp_path / "a.csv", tmp_path / "b.csv"
    a.save_csv(fa)
    b.save_csv(fb)
    assert fa.read_bytes() == fb.read_bytes()
    # each full circle's end: to the 3D line down a parabolic blend (not coplanar, no blend
    # arc: tpChooseBestBlend), to the G0 up an exact stop (tp.c handleModeChange); the
    # line → circle corners are blended (tpCreateLineArcBlend); the feed never above F_max
    assert (a.info["parabolic_blends"], a.info["exact_stops"]) == (1, 1)
    assert a.sd.max() <= kossel.limits.feed_max * (1 + 1e-12)
    # lower bound: length at F_max; upper: plus a full stop-and-go per corner and per blend
    L = part.length
    assert L / 20.0 < a.execution_time_s < L / 20.0 + 45 * 2 * 20.0 / 500.0


def test_programmed_feed_option(keops, tmp_path):
    f = tmp_path / "f.ngc"
    f.write_text("G21 G90 G61\nG0 X-50 Y0 Z-400\nG1 X0 F6000\nG1 X50 F30000\n")
    path = resolve_path(str(f))
    fast = plan("trapezoid", path, keops, programmed_feed=False)
    slow = plan("trapezoid", path, keops)            # the programmed F is the default
    # at F_max (1000 mm/s) the look-ahead binds: the last move is never final, so the first
    # ends at √(a·L) (it could stop within half of the last, tp.c
    # tpCalculateOptimizationInitialVel) and the second peaks at √((2aL + a·L)/2) = 866 mm/s
    a = keops.limits.cartesian.a
    assert fast.sd.max() == pytest.approx(math.sqrt(1.5 * a * 50.0), abs=a * fast.T)
    from planners.feed import use_max_feed           # the suite's --max-feed mark: F_max
    assert plan("trapezoid", use_max_feed(resolve_path(str(f))), keops).execution_time_s == fast.execution_time_s
    # first move capped at F6000 = 100 mm/s, the second at F30000 = 500 mm/s (< F_max)
    first = slow.s <= 50.0
    assert slow.sd[first].max() == pytest.approx(100.0)
    assert slow.sd.max() == pytest.approx(500.0)
    # collinear moves: no stop between them (G61 is exact path: tpSetupTangent makes the
    # straight junction TANGENT). Closed form: 0→100 in 100/a, cruise, 100→500 on the second
    # move, cruise, 500→0.
    d_up1, d_up2, d_down = 100**2 / (2 * a), (500**2 - 100**2) / (2 * a), 500**2 / (2 * a)
    t = (100 / a + (50 - d_up1) / 100 + 400 / a + (50 - d_up2 - d_down) / 500 + 500 / a)
    assert abs(slow.execution_time_s - t) <= 2 * slow.T


def _simulate_reference(path, vmax, amax, vf, T):
    """The per-cycle loop as first written (min/max builtins, values read per pass): the
    reference the faster trapezoid.simulate must reproduce bit for bit."""
    from planners.trapezoid.cycle import MAX_CYCLES
    L = [g.length for g in path.segments]
    vmax, amax, vf = np.asarray(vmax).tolist(), np.asarray(amax).tolist(), np.asarray(vf).tolist()
    n = len(L)
    s_out, v_out = [0.0], [0.0]
    i, x, v, base, excess = 0, 0.0, 0.0, 0.0, 0.0
    for _ in range(MAX_CYCLES):
        t_left = T
        while t_left > 0.0:
            a = amax[i]
            dx = L[i] - x
            half = 0.5 * a * t_left
            disc = vf[i] ** 2 + a * (2 * dx - v * t_left) + half * half
            v_new = -half + math.sqrt(disc) if disc > 0 else 0.0
            v_new = min(max(v_new, 0.0), vmax[i])
            acc = min(max((v_new - v) / t_left, -a), a)
            v_new = max(v + acc * t_left, 0.0)
            disp = 0.5 * (v + v_new) * t_left
            if x + disp < L[i] - 1e-12:
                x += disp
                v = v_new
                break
            if abs(acc) * t_left < 1e-12 * max(v, 1.0):
                tau = dx / v if v > 0 else t_left
            else:
                tau = (-v + math.sqrt(max(v * v + 2 * acc * dx, 0.0))) / acc
            tau = min(max(tau, 0.0), t_left)
            v_end = v + acc * tau
            if i == n - 1:
                return np.array(s_out + [path.length]), np.array(v_out + [0.0]), excess
            excess = max(excess, v_end - vf[i])
            v = min(v_end, vf[i])
            base += L[i]
            x = 0.0
            i += 1
            t_left -= tau
        s_out.append(min(base + x, path.length))
        v_out.append(v)
    raise AssertionError("no arrival")


@pytest.mark.parametrize("machine,name", [("kossel", "test_part"), ("keops", "bird"), ("keops", "helix"),
                                          ("kossel", "cam")])
def test_simulate_equals_the_reference_loop_bit_for_bit(tmp_path, machine, name):
    import importlib.util
    from planners.paths.post import prepare_geometry
    from planners.trapezoid.planner import final_velocities, segment_limits, simulate
    m = load_machine(machine)
    if name == "cam":
        spec = importlib.util.spec_from_file_location(
            "cam_program", Path(__file__).resolve().parents[1] / "benchmarks" / "perf" / "cam_program.py")
        cam = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(cam)
        cam.make_cam_program(300, seed=3, file=tmp_path / "cam.ngc")
        path = resolve_path(str(tmp_path / "cam.ngc"))
    else:
        path = resolve_path(name)
    lim = m.limits
    planned, _ = prepare_geometry(path, lim.chord_error_mm, lim.chord_error_mm)
    vmax, amax = segment_limits(planned, lim.cartesian.v, lim.cartesian.a, lim.feed_max)
    vf = final_velocities(planned, vmax, amax)
    s, sd, ex = simulate(planned, vmax, amax, vf, m.servo_period_s)
    s0, sd0, ex0 = _simulate_reference(planned, vmax, amax, vf, m.servo_period_s)
    assert len(s) > 100
    assert np.array_equal(s, s0) and np.array_equal(sd, sd0) and ex == ex0
