"""User FMUs in the chain (issue 22): a Drive written in Python and packaged with pythonfmu (not
our C FMU framework; FMI 2.0) or pythonfmu3 (FMI 3.0) replaces ours; on the ideal chain each
drive's position equals the exact first-order-lag recursion computed here in numpy from the
targets the bus delivered. A wrong FMU is refused in one line naming the FMU, the variable and
what was expected."""
from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from harness.cli import main as cli

HERE = Path(__file__).resolve().parent
LINE = {"type": "nurbs", "units": "mm", "degree": 1, "knots": [0, 0, 1, 1],
        "control_points": [[-50, 0, -400], [50, 0, -400]], "weights": [1, 1]}
TAU = 0.002        # lag_drive.py's default time constant


def build(src: Path, out: Path, tool: str = "pythonfmu") -> Path:
    exe = Path(sys.executable).with_name(tool)
    r = subprocess.run([str(exe), "build", "-f", str(src), "-d", str(out)], capture_output=True, text=True,
                       cwd=out, timeout=300)
    assert r.returncode == 0, r.stderr
    (fmu,) = out.glob("*.fmu")
    return fmu


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict:
    tmp = tmp_path_factory.mktemp("userfmu")
    (tmp / "good").mkdir()
    (tmp / "bad").mkdir()
    good = build(HERE / "fmus" / "lag_drive.py", tmp / "good")
    # the same Drive with its position an input: a wrong causality
    bad_src = tmp / "bad" / "bad_drive.py"
    bad_src.write_text((HERE / "fmus" / "lag_drive.py").read_text().replace("class LagDrive", "class BadDrive")
                       .replace('for name in ("position", "velocity"', 'self.register_variable(Real("position", '
                                'causality=Fmi2Causality.input))\n        for name in ("velocity"'))
    bad = build(bad_src, tmp / "bad")
    (tmp / "good3").mkdir()
    (tmp / "bad3").mkdir()
    good3 = build(HERE / "fmus" / "lag_drive3.py", tmp / "good3", "pythonfmu3")
    bad3_src = tmp / "bad3" / "bad_drive3.py"      # FMI 3.0, its fault an Int32: a wrong type
    bad3_src.write_text((HERE / "fmus" / "lag_drive3.py").read_text().replace("class LagDrive3", "class BadDrive3")
                        .replace('self.register_variable(Boolean("fault"', 'self.register_variable(Int32("fault"')
                        .replace("import Boolean,", "import Boolean, Int32,").replace("self.fault = False", "self.fault = 0"))
    bad3 = build(bad3_src, tmp / "bad3", "pythonfmu3")
    (tmp / "line.json").write_text(json.dumps(LINE))
    return {"good": good, "bad": bad, "good3": good3, "bad3": bad3, "line": tmp / "line.json", "tmp": tmp}


def lag_recursion(tgt: np.ndarray, T: float) -> np.ndarray:
    """The positions of an exact first-order lag (τ = TAU) under Gauss–Seidel stepping: during
    step i the drive holds the target the bus output in that step."""
    a = math.exp(-T / TAU)
    r = np.empty_like(tgt)
    r[0] = tgt[0]
    for i in range(len(tgt) - 1):
        r[i + 1] = tgt[i + 1] + (r[i] - tgt[i + 1]) * a
    return r


def test_pythonfmu_drive_replaces_ours_and_matches_the_lag_recursion(fmus, tmp_path):
    import planners
    from harness.cosim.run import cosimulate
    from kins import load_machine
    from planners.paths import load_path
    m = load_machine("keops")
    prof = planners.plan("scurve", load_path(fmus["line"]), m)
    res = cosimulate(m, prof, tmp_path, ideal=True, fmus={"Drive": fmus["good"]})
    worst = 0.0
    for k in (1, 2, 3):
        tgt, p = res[f"ethercat.q{k}_target"], res[f"drive{k}.position"]
        assert np.array_equal(tgt, res[f"kinematics.q{k}_cmd"])          # ideal bus: target = command
        assert np.max(np.abs(lag_recursion(tgt, m.servo_period_s) - p)) <= 1e-12
        worst = max(worst, np.max(np.abs(tgt - p)) * 1e3)
    assert "resources/LagDrive.fmu" in (tmp_path / "SystemStructure.ssd").read_text()

    # the same through `pkmbench run` with a suite's [fmus]: the summary's following error
    suite = tmp_path / "s.toml"
    suite.write_text(f'[[run]]\nmachine = "keops"\npath = "{fmus["line"]}"\nplanners = ["scurve"]\n'
                     f'[fmus]\nDrive = "{fmus["good"]}"\n')
    assert cli(["run", str(suite), "--ideal", "--no-recordings", "--out", str(tmp_path / "run")]) == 0
    s = json.loads((tmp_path / "run/summary.json").read_text())
    assert s["fmus"] == {"Drive": str(fmus["good"])}
    assert s["planners"]["scurve"]["max_following_error_um"] == pytest.approx(worst, rel=1e-12)
    assert worst > 100          # a 2 ms lag at these speeds: far from our ideal drive's zero


def test_fmi3_drive_replaces_ours_in_both_masters(fmus, tmp_path):
    """The FMI 3.0 Drive (pythonfmu3) through the whole chain, beside our FMI 2.0 blocks: the same
    closed form in the Python master (fmpy's calls) and the native one (native_master.c calls
    fmi3DoStep, fmi3GetFloat64, … itself), the two agreeing to 1e-12 on every recorded signal."""
    import planners
    from fmpy import read_model_description
    from harness.cosim.run import cosimulate
    from kins import load_machine
    from planners.paths import load_path
    assert read_model_description(str(fmus["good3"])).fmiVersion == "3.0"
    m = load_machine("keops")
    prof = planners.plan("scurve", load_path(fmus["line"]), m)
    res = {}
    for e in ("python", "native"):
        (tmp_path / e).mkdir()
        res[e] = cosimulate(m, prof, tmp_path / e, ideal=True, engine=e, fmus={"Drive": fmus["good3"]})
    worst = 0.0
    for k in (1, 2, 3):
        tgt, p = res["python"][f"ethercat.q{k}_target"], res["python"][f"drive{k}.position"]
        assert np.array_equal(tgt, res["python"][f"kinematics.q{k}_cmd"])
        assert np.max(np.abs(lag_recursion(tgt, m.servo_period_s) - p)) <= 1e-12
        worst = max(worst, np.max(np.abs(tgt - p)) * 1e3)
    py, nat = res["python"], res["native"]
    assert py.columns == nat.columns and py.data.shape == nat.data.shape and len(py.t) > 100
    assert np.max(np.abs(py.data - nat.data)) <= 1e-12
    assert np.any(nat["drive1.following_error"] != 0) and not np.any(nat["drive1.fault"])
    ssd = (tmp_path / "native/SystemStructure.ssd").read_text()
    assert "resources/LagDrive3.fmu" in ssd and "Float64" not in ssd        # SSP's own types on the connectors

    argv = ["run", "--machine", "keops", "--path", str(fmus["line"]), "--planners", "scurve", "--ideal",
            "--no-recordings", "--fmu", f"Drive={fmus['good3']}"]
    for engine in ("python", "native"):
        assert cli(argv + ["--engine", engine, "--out", str(tmp_path / f"run-{engine}")]) == 0
        s = json.loads((tmp_path / f"run-{engine}/summary.json").read_text())
        assert s["planners"]["scurve"]["max_following_error_um"] == pytest.approx(worst, rel=1e-12)
    assert worst > 100


@pytest.mark.parametrize("block, which, message", [
    ("Drive", "bad3", "Drive FMU BadDrive3.fmu: variable 'fault' is output Int32, expected output Boolean"),
    ("Kinematics", "good3", "Kinematics FMU LagDrive3.fmu: no variable 'x_cmd' (the Kinematics interface needs input Real)"),
    ("Drive", "ours:Interpolator", "Drive FMU Interpolator.fmu: no variable 'target' (the Drive interface needs input Real)"),
    ("Drive", "bad", "Drive FMU BadDrive.fmu: variable 'position' is input Real, expected output Real"),
    ("Kinematics", "good", "Kinematics FMU LagDrive.fmu: no variable 'x_cmd' (the Kinematics interface needs input Real)"),
    ("Bus", "good", "unknown block 'Bus' for a user FMU; valid: Interpolator, Kinematics, EtherCAT, Drive"),
])
def test_wrong_fmu_is_refused_naming_the_variable(fmus, tmp_path, capsys, block, which, message):
    from kins.resources import FMU_DIR
    f = FMU_DIR / "Interpolator.fmu" if which == "ours:Interpolator" else fmus[which]
    argv = ["run", "--machine", "keops", "--path", str(fmus["line"]), "--planners", "scurve", "--ideal",
            "--no-recordings", "--out", str(tmp_path / "run"), "--fmu", f"{block}={f}"]
    assert cli(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == f"pkmbench run: error: {message}" and "Traceback" not in "".join(err)
    assert not (tmp_path / "run/summary.json").exists()


def test_sweep_and_ci_run_a_suites_user_fmu_as_run_does(fmus, tmp_path):
    """A suite's [fmus] Drive (a path relative to the suite file) in `sweep` (on a Dask worker
    process, which gets the FMU as bytes) and `ci`: the metrics of `run` with that Drive, bit
    for bit; the rows name the FMU by file, content hash and source."""
    import hashlib

    from harness.store import ResultStore
    from harness.sweep import TaskTable, task_key, tasks_from_suite_file
    shutil.copy(fmus["good"], tmp_path / "LagDrive.fmu")
    runs = f'[[run]]\nmachine = "keops"\npath = "{fmus["line"]}"\nplanners = ["scurve"]\n'
    suite = tmp_path / "s.toml"
    suite.write_text(runs + '[fmus]\nDrive = "LagDrive.fmu"\n')
    assert cli(["run", str(suite), "--jitter", "none", "--no-recordings", "--out", str(tmp_path / "run")]) == 0
    want = json.loads((tmp_path / "run/summary.json").read_text())["planners"]["scurve"]
    assert want["max_following_error_um"] > 100          # the 2 ms lag's, not our drive's

    assert cli(["sweep", str(suite), "--workers", "1", "--out", str(tmp_path / "sw"),
                "--store", str(tmp_path / "store"), "--no-progress"]) == 0
    row, = TaskTable(tmp_path / "sw/results.sqlite").to_rows()
    assert row["worker"].rsplit(":", 1)[1] != str(__import__("os").getpid())   # another process
    assert {k: v for k, v in row["metrics"].items() if k != "planning_time_s"} == want
    sha = hashlib.sha256(fmus["good"].read_bytes()).hexdigest()
    named = {"Drive": {"file": "LagDrive.fmu", "sha256": sha, "source": str(tmp_path / "LagDrive.fmu")}}
    assert row["task"]["fmus"] == named
    ran = json.loads((tmp_path / "sw" / row["run_dir"] / "summary.json").read_text())["fmus"]["Drive"]
    assert ran.endswith(f"/user/{sha[:16]}/LagDrive.fmu")
    with ResultStore(tmp_path / "store") as st:
        _, ((info,),) = st.query("SELECT run_info FROM results")
    assert json.loads(info) == {"fmus": named}
    ours = tmp_path / "ours.toml"
    ours.write_text(runs)
    (t_user,), (t_ours,) = tasks_from_suite_file(suite), tasks_from_suite_file(ours)
    assert "fmus" not in t_ours and task_key(t_user, "v") != task_key(t_ours, "v")

    assert cli(["ci", "--suite", str(suite), "--baseline", str(tmp_path / "baseline.json"), "--out",
                str(tmp_path / "ci"), "--workers", "0", "--store", str(tmp_path / "store"), "--update-baseline"]) == 0
    from harness.sweep import flatten
    entry = json.loads((tmp_path / "baseline.json").read_text())["entries"]["keops/line/scurve/seed0/none/base"]
    assert {k: entry[k] for k in flatten(want)} == flatten(want)
    with ResultStore(tmp_path / "store") as st:
        _, ((info,),) = st.query("SELECT run_info FROM results WHERE kind = 'ci'")
    assert json.loads(info)["fmus"] == named


@pytest.mark.parametrize("command", ["sweep", "ci"])
def test_sweep_and_ci_refuse_a_wrong_fmu_before_any_task(fmus, tmp_path, capsys, command):
    suite = tmp_path / "s.toml"
    suite.write_text(f'[[run]]\nmachine = "keops"\npath = "{fmus["line"]}"\nplanners = ["scurve"]\n'
                     f'[fmus]\nDrive = "{fmus["good"]}"\n')
    argv = ([command, str(suite)] if command == "sweep" else [command, "--suite", str(suite), "--baseline",
                                                               str(tmp_path / "b.json"), "--update-baseline"])
    assert cli(argv + ["--out", str(tmp_path / "o"), "--store", str(tmp_path / "st"), "--fmu",
                       f"Drive={fmus['bad']}"]) == 2            # --fmu wins over the suite's [fmus]
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == (f"pkmbench {command}: error: Drive FMU BadDrive.fmu: variable 'position' is input Real, "
                       f"expected output Real")
    assert not (tmp_path / "o").exists() and not (tmp_path / "st").exists()


@pytest.mark.parametrize("command", ["run", "sweep"])
def test_a_malformed_fmus_table_is_refused_naming_the_suite(tmp_path, capsys, command):
    suite = tmp_path / "s.toml"
    suite.write_text('[[run]]\nmachine = "keops"\npath = "bird"\nplanners = ["scurve"]\n[fmus]\nDrive = 3\n')
    assert cli([command, str(suite), "--out", str(tmp_path / "o")]) == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        f"pkmbench {command}: error: {suite}: [fmus] must map a block name to an .fmu file name")
    assert not (tmp_path / "o").exists()
