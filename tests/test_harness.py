"""Harness end to end on a short path: ideal chain exactness, masters agree, determinism,
recordings read back, SSP round trip and the fmpy.ssp cross-check, bad input."""
import json
import zipfile
from pathlib import Path

import numpy as np
import pytest

import planners
from harness.cosim.master import CoSimError, simulate
from harness.cosim.record import read_command_csv, read_mcap
from harness.cosim.run import RECORD, RunError, cosimulate, run_case
from harness.cosim.system import FILE_PARAMS, FMU_DIR, SystemError_, chain, read_ssp, write_ssp
from kins import load_machine
from planners.paths import Line, SegmentPath

pytestmark = pytest.mark.skipif(not (FMU_DIR / "Interpolator.fmu").exists() or not (FMU_DIR / "Drive.fmu").exists()
                                or not (FMU_DIR / "EtherCAT.fmu").exists(), reason="FMUs not built (make fmus)")


@pytest.fixture(scope="module")
def keops():
    return load_machine("keops")


@pytest.fixture(scope="module")
def short_profile(keops):
    path = SegmentPath([Line([-20.0, 0.0, -400.0], [20.0, 10.0, -400.0])], source="short line")
    return planners.plan("scurve", path, keops)


def test_ideal_chain_reproduces_the_command_exactly(keops, short_profile, tmp_path):
    res = cosimulate(keops, short_profile, tmp_path, ideal=True)
    n = len(short_profile.s)
    P = np.column_stack([res[f"interpolator.{a}"] for a in "xyz"])[:n]
    np.testing.assert_allclose(P, short_profile.path.point(short_profile.s), atol=1e-9)
    Q_cmd = np.column_stack([res[f"kinematics.q{k}_cmd"] for k in (1, 2, 3)])
    Q_act = np.column_stack([res[f"drive{k}.position"] for k in (1, 2, 3)])
    assert np.array_equal(Q_act, Q_cmd)                      # ideal bus and drives: exact
    np.testing.assert_allclose(Q_cmd[:n], keops.ik(P), atol=1e-9)


def test_native_and_python_masters_agree(keops, short_profile, tmp_path):
    system = chain(keops, tmp_path / "p.json", tmp_path / "p.csv", 0.05, seed=3, jitter="tuned_rt")
    short_profile.path.to_file(tmp_path / "p.json")
    short_profile.save_csv(tmp_path / "p.csv")
    for jacobi in (False, True):
        a = simulate(system, RECORD, engine="native", jacobi=jacobi)
        b = simulate(system, RECORD, engine="python", jacobi=jacobi)
        assert a.data.shape == b.data.shape == (201, len(RECORD))
        np.testing.assert_allclose(a.data, b.data, rtol=0, atol=1e-12)
    # and the drives really moved (the test is not comparing two constants)
    assert np.ptp(a["drive1.position"]) > 1.0


def test_ssp_round_trip(keops, short_profile, tmp_path):
    system = chain(keops, tmp_path / "p.json", tmp_path / "p.csv", 0.01, seed=7)
    back = read_ssp(write_ssp(system, tmp_path))
    assert [c.name for c in back.components] == [c.name for c in system.components]
    for a, b in zip(system.components, back.components):
        assert a.start == b.start                  # file parameters back to absolute paths
        assert b.fmu == tmp_path / "resources" / a.fmu.name and b.fmu.read_bytes() == a.fmu.read_bytes()
    assert [(c.src, c.src_var, c.dst, c.dst_var) for c in back.connections] == \
           [(c.src, c.src_var, c.dst, c.dst_var) for c in system.connections]
    assert back.step_size == system.step_size and back.stop_time == system.stop_time


def test_run_is_deterministic_and_recordings_read_back(tmp_path):
    outs = []
    for k in range(2):
        out = tmp_path / f"run{k}"
        s = run_case("keops", str(Path(__file__).parent / "data" / "short_line.json"), ["scurve", "trapezoid"],
                     out, seed=5, recordings=(k == 0))
        assert set(s["planners"]) == {"scurve", "trapezoid"}
        outs.append(out)
    a, b = outs
    assert (a / "summary.json").read_bytes() == (b / "summary.json").read_bytes()
    for p in ("scurve", "trapezoid"):
        assert (a / p / "command.csv").read_bytes() == (b / p / "command.csv").read_bytes()
    summary = json.loads((a / "summary.json").read_text())
    m = summary["planners"]["scurve"]
    assert m["feasible"] is True and 0 < m["max_following_error_um"] < 1000
    assert "NaN" not in (a / "summary.json").read_text()
    # the mcap read back equals the CSV
    cmd = read_command_csv(a / "scurve" / "command.csv")
    mc = read_mcap(a / "scurve" / "run.mcap")
    n = len(cmd)
    for k, col in enumerate("xyz", start=1):
        np.testing.assert_array_equal(mc["/command"][col][:n], cmd[:, k])
    np.testing.assert_array_equal(mc["/joints/command"]["q1"][:n], cmd[:, 4])
    # the rrd read back with the rerun SDK: the joint velocity, acceleration and jerk at every
    # difference of the command, the toolpath once
    from rerun.chunk import RrdReader
    rows: dict[str, int] = {}
    for chunk in RrdReader(str(a / "scurve" / "run.rrd")).stream():
        rows[str(chunk.entity_path)] = rows.get(str(chunk.entity_path), 0) + chunk.num_rows
    for k, order in enumerate(("velocity", "acceleration", "jerk"), start=1):
        assert rows[f"/joints/{order}/q1"] == n - k
    assert rows["/machine/toolpath"] == 1


def test_fmu_error_names_fmu_time_and_log(keops, tmp_path):
    # a straight line that leaves the workspace: the Kinematics FMU must stop the run
    path = SegmentPath([Line([0.0, 0.0, -400.0], [0.0, 0.0, -800.0])], source="down")
    profile = planners.profile.Profile.from_s("line", keops.servo_period_s,
                                              np.linspace(0, 400.0, 2001), path)
    with pytest.raises(CoSimError, match=r"kinematics failed at t = [0-9.]+ s: .*stroke|kinematics failed at t = .*reach"):
        cosimulate(keops, profile, tmp_path, ideal=True)


def test_missing_and_corrupt_fmu(keops, tmp_path, monkeypatch):
    import harness.cosim.system as S
    monkeypatch.setattr(S, "FMU_DIR", tmp_path)
    with pytest.raises(SystemError_, match=r"Interpolator.fmu is missing: build the FMUs with 'make fmus'"):
        chain(keops, tmp_path / "a", tmp_path / "b", 0.01)
    bad = tmp_path / "Bad.fmu"
    bad.write_bytes(b"not a zip")
    from harness.cosim.master import extract
    with pytest.raises(SystemError_, match=r"Bad.fmu: not a valid FMU \(corrupt zip\)"):
        extract(bad)


def test_bad_run_arguments(tmp_path):
    with pytest.raises(RunError, match="unknown machine 'hexa'; valid: keops"):
        run_case("hexa", "bird", ["scurve"], tmp_path)
    with pytest.raises(RunError, match="unknown planner\\(s\\) fastest; valid: trapezoid"):
        run_case("keops", "bird", ["fastest"], tmp_path)
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        import os
        if os.access(ro, os.W_OK):   # root ignores permissions: make the path a file instead
            ro.chmod(0o700)
            ro.rmdir()
            ro.write_text("a file")
        with pytest.raises(RunError, match="cannot (write to|create) output folder .*ro/out"):
            run_case("keops", "bird", ["scurve"], ro / "out")
    finally:
        if ro.is_dir():
            ro.chmod(0o700)


def test_cli_errors(tmp_path, capsys):
    from harness.cli import main
    assert main(["run", "--machine", "keops", "--path", "bird", "--jitter", "wild", "--out", str(tmp_path)]) == 2
    assert "unknown jitter preset 'wild'; valid: none, linuxcnc_rt_preempt, tuned_rt" in capsys.readouterr().err
    suite = tmp_path / "s.toml"
    suite.write_text('[[run]]\nmachine = "keops"\npaht = "bird"\nplanners = ["scurve"]\n')
    assert main(["run", str(suite), "--out", str(tmp_path / "o")]) == 2
    assert "s.toml:line 3: [[run]] #1: unknown key 'paht'" in capsys.readouterr().err
    assert not (tmp_path / "o" / "summary.json").exists()


def test_sweep_default_task_is_the_full_cosimulation(tmp_path):
    """A sweep's default task runs the FMU chain: drive following error and SSP files exist,
    and a preset that the EtherCAT FMU does not know fails that task only."""
    import sqlite3

    from harness.sweep import run_sweep
    from harness.sweep.suite import expand

    line = str(Path(__file__).parent / "data" / "short_line.json")
    suite = {"run": [{"machine": "keops", "path": line, "planners": ["scurve"]}],
             "sweep": {"seeds": [0], "presets": ["tuned_rt", "wobbly"]}}
    res = run_sweep(expand(suite), tmp_path, workers=0, progress=False)
    assert (res.total, res.ok, res.failed) == (2, 1, 1)
    assert "wobbly" in res.failures[0][0] or "wobbly" in res.failures[0][1]
    rows = sqlite3.connect(tmp_path / "results.sqlite").execute("select * from results").fetchall()
    assert rows
    assert list(tmp_path.rglob("SystemStructure.ssd"))
    summaries = [json.loads(p.read_text()) for p in tmp_path.rglob("summary.json")]
    m = [s["planners"]["scurve"] for s in summaries if "scurve" in s["planners"]][0]
    assert 0 < m["max_following_error_um"] < 1000 and m["feasible"] is True


def test_fmpy_ssp_reproduces_the_jacobi_run(keops, short_profile, tmp_path, monkeypatch):
    """FMPy's own SSP master, on the SSP the harness writes, gives the harness's Jacobi run.

    fmpy's read_ssd parses each component's parameter binding; its simulate_ssp applies one
    parameter set with names qualified by the component, built here from what read_ssd parsed.
    Two gaps in fmpy.ssp are bridged here, not in the harness: it cannot set String parameters
    (the Interpolator's files, named relative to the SSP's folder) or Boolean values read from
    an SSP, and it starts every connector at 0.0 — so the runs agree once the four-stage pipeline has filled (an ideal
    chain, where a 0 mm start target does not fault a drive). fmpy logs row i after step i.
    """
    import fmpy.ssp.simulation as S
    from fmpy.ssp.ssd import Parameter, ParameterSet, read_ssd

    short_profile.path.to_file(tmp_path / "p.json")
    short_profile.save_csv(tmp_path / "p.csv")
    system = chain(keops, tmp_path / "p.json", tmp_path / "p.csv", 0.05, ideal=True)
    ssd = write_ssp(system, tmp_path)          # the folder as an .ssp: its FMUs are in resources/
    ssp = tmp_path / "chain.ssp"
    with zipfile.ZipFile(ssp, "w") as z:
        z.write(ssd, "SystemStructure.ssd")
        for f in (tmp_path / "resources").iterdir():
            z.write(f, f"resources/{f.name}")
    plain = S.set_value

    def set_value(component, name, value):
        v = component.variables[name]
        if v.type == "String":               # file names in the .ssv are relative to its folder
            component.fmu.setString([v.valueReference], [str(tmp_path / value) if name in FILE_PARAMS else str(value)])
        elif v.type == "Boolean" and isinstance(value, str):
            component.fmu.setBoolean([v.valueReference], [value == "true"])
        else:
            plain(component, name, value)

    monkeypatch.setattr(S, "set_value", set_value)
    bound = ParameterSet(name="start values")
    for comp in read_ssd(str(ssp), validate=True).system.elements:
        for b in comp.parameterBindings:
            for pset in b.parameterValues:
                bound.parameters += [Parameter(name=f"{comp.name}.{p.name}", type=p.type, value=p.value)
                                     for p in pset.parameters]
    assert len(bound.parameters) == sum(len(c.start) for c in system.components)
    theirs = S.simulate_ssp(str(ssp), stop_time=0.05, step_size=keops.servo_period_s, parameter_set=bound)
    ours = simulate(read_ssp(ssd), RECORD, jacobi=True)
    fill = 5
    for name in ("interpolator.x", "kinematics.q1_cmd", "ethercat.q2_target", "drive3.position"):
        a = ours[name][1 + fill:]
        b = theirs[name][fill:len(a) + fill]
        assert len(b) > 150
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-9, err_msg=name)
    assert np.ptp(ours["drive3.position"]) > 1.0
