"""The SSP a run writes, run in another master (issue 22): OSP libcosim loads the run folder's
SystemStructure.ssd unchanged and its run equals the harness's Jacobi run of that SSP, signal
by signal — on the ideal chain and on the real one (jittered bus, drive models).

libcosim initialises the FMUs its own way (all in Initialization Mode, values passed along the
connections, then all leave it), so this also checks that our FMUs' outputs follow their inputs
in Initialization Mode (fmus/common/fmi2_cosim.c); before, libcosim's drives started at 0 mm.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from harness.cli import main as cli
from harness.cosim.master import _free, _Instance, simulate
from harness.cosim.record import read_command_csv
from harness.cosim.run import RECORD
from harness.cosim.system import FMU_DIR, Component, read_ssp

pytest.importorskip("libcosimpy")
pytestmark = pytest.mark.skipif(not all((FMU_DIR / f"{n}.fmu").exists()
                                        for n in ("Interpolator", "Kinematics", "EtherCAT", "Drive")),
                                reason="FMUs not built (make fmus)")

LINE = str(Path(__file__).parent / "data" / "short_line.json")     # (-20, 0, -400) → (20, 10, -400)
# the joints' commands and positions: what must agree exactly; the rest to 1e-9 or 1e-12 relative
EXACT = [f"interpolator.{a}" for a in "xyz"] + [f"kinematics.q{k}_cmd" for k in (1, 2, 3)] + \
        [f"ethercat.q{k}_target" for k in (1, 2, 3)] + [f"drive{k}.position" for k in (1, 2, 3)]


def _run(tmp_path, *flags) -> Path:
    out = tmp_path / "run"
    assert cli(["run", "--machine", "keops", "--path", LINE, "--planners", "scurve", "--jacobi",
                "--no-recordings", "--out", str(out), *flags]) == 0
    return out / "scurve" / "SystemStructure.ssd"


@pytest.mark.parametrize("flags", [("--ideal",), ()], ids=["ideal", "real"])
def test_libcosim_runs_the_ssp_as_the_harness_does(tmp_path, flags, monkeypatch):
    from harness.cosim.libcosim import simulate_libcosim
    ssd = _run(tmp_path, *flags)
    (tmp_path / "cwd").mkdir()
    monkeypatch.chdir(tmp_path / "cwd")
    theirs = simulate_libcosim(ssd, RECORD)
    assert not list((tmp_path / "cwd").iterdir())        # the FMUs' files (lateness.csv) went to the SSP's folder
    ours = simulate(read_ssp(ssd), RECORD, jacobi=True)
    n = len(theirs.t)
    assert n > 500 and np.array_equal(theirs.t, ours.t[1:])
    # the Interpolator got its files: it starts at the path's start, not at its built-in default path
    np.testing.assert_allclose([theirs[f"interpolator.{a}"][0] for a in "xyz"], [-20.0, 0.0, -400.0], atol=1e-6)
    # the commanded joints are those the run wrote (command.csv: t, x, y, z, q1, q2, q3)
    C = read_command_csv(ssd.parent / "command.csv")
    m = len(C) - 1
    np.testing.assert_array_equal(np.column_stack([theirs[f"kinematics.q{k}_cmd"] for k in (1, 2, 3)])[:m], C[1:, 4:])
    for name in RECORD:
        a, b = theirs[name], ours[name][1:]
        if name in EXACT:
            assert np.max(np.abs(a - b)) <= 1e-9, name
        else:
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-9, err_msg=name)
    assert np.ptp(theirs["drive3.position"]) > 1.0                      # the drives moved
    lateness = theirs["ethercat.lateness"]
    assert (np.ptp(lateness) > 0) == (not flags)                         # a jittered bus only on the real chain
    follow = np.abs(theirs["drive1.following_error"]).max()
    assert (follow > 1e-3) == (not flags)                                # drive models only on the real chain


def test_outputs_follow_inputs_in_initialization_mode():
    """What libcosim's initialisation needs: the FMUs' outputs, read in Initialization Mode,
    follow the inputs set there (before: start values until fmi2ExitInitializationMode)."""
    from harness.cosim.system import kinematics_start
    from kins import load_machine
    keops = load_machine("keops")
    p = np.array([10.0, -5.0, -420.0])
    logs: list[str] = []
    kin = _Instance(Component("kinematics", FMU_DIR / "Kinematics.fmu", kinematics_start(keops)), 0.0, logs)
    ideal = _Instance(Component("ideal", FMU_DIR / "Drive.fmu", {"ideal": True}), 0.0, logs)
    drive = _Instance(Component("drive", FMU_DIR / "Drive.fmu", {}), 0.0, logs)   # the default motor model
    insts = (kin, ideal, drive)
    try:
        for inst in insts:
            inst.fmu.enterInitializationMode()
        for a, x in zip("xyz", p):
            kin.set(f"{a}_cmd", x)
        q = [kin.get(f"q{k}_cmd") for k in (1, 2, 3)]
        np.testing.assert_allclose(q, keops.ik(p[None, :])[0], rtol=0, atol=1e-9)
        count = drive.get("encoder_resolution_mm")
        for target in q[:2]:                        # a drive starts at its target, and follows a later one
            for d in (ideal, drive):
                d.set("target", target)
            assert ideal.get("position") == target
            assert abs(drive.get("position") - target) <= count / 2 + 1e-12   # the encoder's reading
        for inst in insts:
            inst.fmu.exitInitializationMode()
        assert [kin.get(f"q{k}_cmd") for k in (1, 2, 3)] == q
        assert ideal.get("position") == q[1]
    finally:
        _free(insts)
    assert not [m for m in logs if "ERROR" in m]
