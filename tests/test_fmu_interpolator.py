"""Interpolator.fmu against the Python paths: exact circle, 1 nm on NURBS, exact lines/arcs;
bad files fail initialisation with a message naming the file and the problem; a fuzz run."""
import json
import random

import numpy as np
import pytest

import planners
from harness.cosim.system import FMU_DIR
from kins import load_machine
from planners.paths import Arc, Line, NurbsPath, SegmentPath, resolve_path
from planners.profile import Profile
from tests.fmu_util import Fmu

pytestmark = pytest.mark.skipif(not (FMU_DIR / "Interpolator.fmu").exists(), reason="make fmus")
KEOPS = load_machine("keops")
T = KEOPS.servo_period_s


def replay(path, profile, tmp_path):
    """Run the FMU over the whole profile; returns (N, 4) rows x, y, z, s."""
    path.to_file(tmp_path / "p.json")
    profile.save_csv(tmp_path / "p.csv")
    f = Fmu("Interpolator", {"path_file": str(tmp_path / "p.json"), "profile_file": str(tmp_path / "p.csv"), "T": T})
    assert f.init(), f.logs
    rows = [f.get("x", "y", "z", "s")]
    for k in range(len(profile.s) - 1):
        assert f.step(k * T, T)
        rows.append(f.get("x", "y", "z", "s"))
    assert f.get("done") == [1.0]
    f.close()
    return np.array(rows)


def test_exact_rational_circle(tmp_path):
    w = np.sqrt(0.5)
    r = 30.0
    cps = [[r, 0, -400], [r, r, -400], [0, r, -400], [-r, r, -400], [-r, 0, -400]]
    path = NurbsPath(2, [0, 0, 0, 1, 1, 2, 2, 2], cps, [1, w, 1, w, 1])
    prof = planners.plan("scurve", path, KEOPS)
    out = replay(path, prof, tmp_path)
    rad = np.hypot(out[:, 0], out[:, 1])
    assert np.abs(rad - r).max() <= 1e-9
    # travelled arc length = the profile's s: the angle swept is s / r exactly
    ang = np.unwrap(np.arctan2(out[:, 1], out[:, 0]))
    assert np.abs(ang * r - prof.s).max() <= 1e-6          # ≤ 1 nm
    np.testing.assert_array_equal(out[:, 3], prof.s)


def test_cubic_nurbs_with_50_control_points_within_1_nm(tmp_path):
    rng = np.random.default_rng(4)
    n = 50
    cps = np.column_stack([np.linspace(-80, 80, n), 40 * np.sin(np.linspace(0, 6, n)) + rng.uniform(-5, 5, n),
                           np.full(n, -400.0)])
    knots = np.concatenate([[0] * 4, np.linspace(0, 1, n - 2)[1:-1], [1] * 4])
    path = NurbsPath(3, knots, cps, rng.uniform(0.5, 2.0, n))
    prof = planners.plan("scurve", path, KEOPS)
    out = replay(path, prof, tmp_path)
    assert np.abs(out[:, :3] - path.point(prof.s)).max() <= 1e-6


def test_bird_within_1_nm(tmp_path):
    path = resolve_path("bird")
    prof = planners.plan("scurve", path, KEOPS)
    out = replay(path, prof, tmp_path)
    assert np.abs(out[:, :3] - path.point(prof.s)).max() <= 1e-6


def test_lines_and_arcs_exact(tmp_path):
    path = SegmentPath([Line([0, 0, -400], [10, 0, -400]),
                        Arc([10, 0, -400], [10, 5, -400], [0, 0, 1], np.pi, rise=-2.0),
                        Line([10, 10, -402], [0, 10, -402])])
    prof = planners.plan("trapezoid", path, KEOPS)
    out = replay(path, prof, tmp_path)
    assert np.abs(out[:, :3] - path.point(prof.s)).max() <= 1e-12


def test_spiral_arcs_as_the_python_path(tmp_path):
    # LinuxCNC's spiral arcs (radius linear in the angle): out, and in while rising 3 turns
    path = SegmentPath([Line([0, 0, -400], [10, 0, -400]),
                        Arc([10, 0, -400], [15, 0, -400], [0, 0, -1], np.pi, spiral=0.014),
                        Arc([20.014, 0, -400], [25, 0, -400], [0, 0, 1], 6 * np.pi, rise=-2.0, spiral=-0.02)])
    prof = planners.plan("trapezoid", path, KEOPS)
    out = replay(path, prof, tmp_path)
    assert np.abs(out[:, :3] - path.point(prof.s)).max() <= 1e-9
    # and on the spiral itself: the radius about (15, 0) at each point's angle is 5 + 0.014·φ/π
    on = (prof.s > 10) & (prof.s < path.seg_start[2])
    x, y = out[on, 0] - 15, out[on, 1]
    phi = np.arctan2(y, -x) % (2 * np.pi)            # clockwise from the start at (10, 0)
    assert np.abs(np.hypot(x, y) - (5 + 0.014 * phi / np.pi)).max() <= 1e-9


GOOD_NURBS = {"type": "nurbs", "units": "mm", "degree": 2, "knots": [0, 0, 0, 1, 1, 1],
              "control_points": [[0, 0, -400], [10, 10, -400], [20, 0, -400]], "weights": [1, 1, 1]}


def _init_with(tmp_path, path_text, profile_text=None):
    (tmp_path / "p.json").write_text(path_text)
    if profile_text is None:
        profile_text = "t,s,sd,sdd,sddd\n0,0,0,0,0\n0.00025,0.001,4,0,0\n"
    (tmp_path / "p.csv").write_text(profile_text)
    f = Fmu("Interpolator", {"path_file": str(tmp_path / "p.json"), "profile_file": str(tmp_path / "p.csv"), "T": T})
    ok = f.init()
    logs = list(f.logs)
    f.close()
    return ok, " | ".join(logs)


@pytest.mark.parametrize("change,message", [
    ({"knots": [0, 0, 1, 0.5, 1, 1]}, "knots are not non-decreasing: knots[3]"),
    ({"knots": [0, 0, 0, 1, 1]}, "'knots' has 5 values; 3 control points of degree 2 need 6"),
    ({"weights": [1, 0, 1]}, "weights[1] = 0 must be > 0"),
    ({"weights": [1, 1]}, "'weights' has 2 numbers, expected 3"),
    ({"type": "bezier"}, 'unknown path type "bezier"'),
    ({"control_points": [[0, 0, -400], [10, 10], [20, 0, -400]]}, "control_points[1]' has 2 numbers, expected 3"),
])
def test_bad_path_files(tmp_path, change, message):
    ok, log = _init_with(tmp_path, json.dumps({**GOOD_NURBS, **change}))
    assert not ok and "p.json" in log and message in log


@pytest.mark.parametrize("spiral, message", [
    ('"x"', "segments[0].spiral must be a number (mm)"),
    ("-1.5", "segments[0]: end radius 1 + spiral -1.5 mm must be > 0"),
    ("0.1", "segments[0]: end disagrees with start/center/angle/rise/spiral"),
])
def test_bad_spiral_fields(tmp_path, spiral, message):
    arc = ('{"type": "segments", "segments": [{"type": "arc", "start": [1, 0, -400], "center": [0, 0, -400], '
           '"normal": [0, 0, 1], "angle": 1.0, "spiral": %s, "end": [0.5403023058681398, 0.8414709848078965, -400]}]}')
    ok, log = _init_with(tmp_path, arc % spiral)
    assert not ok and "p.json" in log and message in log, log


def test_bad_profile_and_missing_files(tmp_path):
    good = json.dumps(GOOD_NURBS)
    ok, log = _init_with(tmp_path, good, "t,s,sd,sdd,sddd\n0,0,0,0,0\n0.00025,0.5,1,0,0\n0.0005,0.4,0,0,0\n")
    assert not ok and "p.csv:4: the profile runs backwards" in log
    ok, log = _init_with(tmp_path, good, "t,s\n0,0\n")
    assert not ok and "p.csv:1: header must be 't,s,sd,sdd,sddd'" in log
    ok, log = _init_with(tmp_path, good, "t,s,sd,sdd,sddd\n0,0,0,0,0\n0.001,0.1,0,0,0\n")
    assert not ok and "must be at 0.00025" in log
    ok, log = _init_with(tmp_path, good, "t,s,sd,sdd,sddd\n0,0,0,0,0\n0.00025,1e9,0,0,0\n")
    assert not ok and "beyond the path length" in log
    ok, log = _init_with(tmp_path, '{"type": "nurbs", "degree": 2,')
    assert not ok and "p.json: malformed JSON at byte" in log
    f = Fmu("Interpolator", {"path_file": str(tmp_path / "nope.json")})
    assert not f.init() and any("nope.json: cannot open" in line for line in f.logs)
    f.close()


def mutate(text: str, rng: random.Random) -> str:
    b = bytearray(text.encode())
    for _ in range(rng.randint(1, 6)):
        op = rng.random()
        i = rng.randrange(len(b) + 1)
        if op < 0.4 and b:
            del b[min(i, len(b) - 1)]
        elif op < 0.8:
            b.insert(i, rng.choice(b'{}[],:"-0123456789.eE \n\x00nultrfas'))
        elif b:
            j = rng.randrange(len(b))
            b[min(i, len(b) - 1)], b[j] = b[j], b[min(i, len(b) - 1)]
    return b.decode(errors="replace")


def fuzz(n: int, tmp_path, seed: int = 0) -> dict:
    """n mutated path/profile files through initialisation: each must succeed or fail with a
    logged message; a crash would take the process down. Returns counts."""
    rng = random.Random(seed)
    seg = json.dumps({"type": "segments", "segments": [
        {"type": "line", "start": [0, 0, -400], "end": [1, 0, -400]},
        {"type": "arc", "start": [1, 0, -400], "center": [1, 1, -400], "normal": [0, 0, 1],
         "angle": 1.0, "rise": 0.0, "end": [1 + np.sin(1.0), 1 - np.cos(1.0), -400]}]})
    spiral = json.dumps({"type": "segments", "segments": [
        {"type": "arc", "start": [1, 0, -400], "center": [0, 0, -400], "normal": [0, 0, 1], "angle": 1.0,
         "spiral": 0.01, "end": [1.01 * np.cos(1.0), 1.01 * np.sin(1.0), -400]}]})
    seeds = [json.dumps(GOOD_NURBS), seg, spiral]
    prof = "t,s,sd,sdd,sddd\n0,0,0,0,0\n0.00025,0.001,4,0,0\n0.0005,0.002,4,0,0\n"
    counts = {"ok": 0, "error": 0}
    for k in range(n):
        if k % 2:
            ok, log = _init_with(tmp_path, mutate(rng.choice(seeds), rng))
        else:
            ok, log = _init_with(tmp_path, seeds[0], mutate(prof, rng))
        assert ok or log, "an initialisation failed without a logged reason"
        counts["ok" if ok else "error"] += 1
    return counts


def test_fuzz_short(tmp_path):
    counts = fuzz(300, tmp_path)
    assert counts["error"] > 100 and counts["ok"] > 0    # the mutations really hit the parsers


def test_build_sources_rebuild_with_fmpy_compile(tmp_path, monkeypatch):
    """The sources/ of a built FMU rebuild with fmpy's own build (CMake) and still simulate."""
    import shutil
    import zipfile
    from fmpy import simulate_fmu
    from fmpy.build import build_platform_binary

    import os
    import sys
    # fmpy runs `cmake`: the pinned one is installed in the venv with fmpy
    monkeypatch.setenv("PATH", os.path.dirname(sys.executable) + os.pathsep + os.environ["PATH"])
    assert shutil.which("cmake"), "cmake (a dependency of fmpy) is not installed"
    unzip = tmp_path / "k"
    with zipfile.ZipFile(FMU_DIR / "Kinematics.fmu") as z:
        z.extractall(unzip)
    so = unzip / "binaries/linux64/Kinematics.so"
    so.unlink()
    (tmp_path / "build").mkdir()
    build_platform_binary(unzip, build_dir=tmp_path / "build")
    assert so.exists()
    r = simulate_fmu(str(unzip), stop_time=0.001, output=["q1_cmd"])
    assert abs(r["q1_cmd"][-1] - KEOPS.ik([0, 0, -400.0])[0]) < 1e-9


if __name__ == "__main__":   # the long fuzz run: python tests/test_fmu_interpolator.py [N] [SEED]
    import sys
    import tempfile
    from pathlib import Path
    with tempfile.TemporaryDirectory() as d:
        print(fuzz(int(sys.argv[1]) if len(sys.argv) > 1 else 100_000, Path(d),
                   int(sys.argv[2]) if len(sys.argv) > 2 else 0))


@pytest.mark.parametrize("gap, accepted", [(3e-9, True), (1e-6, False)])
def test_segment_gap_tolerance_is_the_python_contract(tmp_path, gap, accepted):
    """Consecutive segments may be 1e-9 mm per unit of the largest coordinate apart, as in
    planners/path.py: at |z| = 400 a 3e-9 mm gap (rounding of a near-straight G64 blend of
    R = 2400 mm on bird) is accepted by both, 1e-6 mm refused by both, naming the segment."""
    a, b = [0.0, 0.0, -400.0], [10.0, 0.0, -400.0]
    c = [10.0, 0.0 + gap, -400.0]
    doc = {"type": "segments", "units": "mm", "segments": [
        {"type": "line", "start": a, "end": b}, {"type": "line", "start": c, "end": [10.0, 10.0, -400.0]}]}
    ok, log = _init_with(tmp_path, json.dumps(doc))
    assert ok == accepted, log
    if not accepted:
        assert "segments[1] starts" in log and "away from the end of segments[0]" in log
    from planners.paths import PathError, SegmentPath as SP
    if accepted:
        SP([Line(a, b), Line(c, [10.0, 10.0, -400.0])])
    else:
        with pytest.raises(PathError, match="segment #1 starts"):
            SP([Line(a, b), Line(c, [10.0, 10.0, -400.0])])
