"""Kinematics.fmu equals kins to 1e-9 mm over every machine's workspace; workspace errors."""
import numpy as np
import pytest
from fmpy.validation import validate_fmu

from harness.cosim.system import FMU_DIR, kinematics_start
from kins import load_machine
from tests.fmu_util import Fmu
from tests.test_kins import workspace_grid

pytestmark = pytest.mark.skipif(not (FMU_DIR / "Kinematics.fmu").exists(), reason="make fmus")


@pytest.mark.parametrize("name", ["Kinematics", "Interpolator"])
def test_fmpy_validation_is_clean(name):
    assert validate_fmu(str(FMU_DIR / f"{name}.fmu")) == []


@pytest.mark.parametrize("name", ["keops", "kossel", "linuxcnc_delta", "pn101"])
def test_fmu_equals_kins_on_workspace_grid(name):
    m = load_machine(name)
    P = workspace_grid(m, 7)
    Q = m.ik(P)
    f = Fmu("Kinematics", {**kinematics_start(m), "x_cmd": P[0, 0], "y_cmd": P[0, 1], "z_cmd": P[0, 2]})
    assert f.init()
    q_fmu, p_fmu, c_fmu = np.empty_like(P), np.empty_like(P), np.empty(len(P))
    for i, (p, q) in enumerate(zip(P, Q)):
        f.set(x_cmd=p[0], y_cmd=p[1], z_cmd=p[2], q1_act=q[0], q2_act=q[1], q3_act=q[2])
        q_fmu[i] = f.get("q1_cmd", "q2_cmd", "q3_cmd")
        p_fmu[i] = f.get("x_act", "y_act", "z_act")
        c_fmu[i] = f.get("cond_J")[0]
    f.close()
    assert np.abs(q_fmu - Q).max() < 1e-9
    assert np.abs(p_fmu - P).max() < 1e-9
    np.testing.assert_allclose(c_fmu, m.condition_number(P), rtol=1e-6)


def test_outside_workspace_is_an_error_with_time_and_point():
    m = load_machine("keops")
    f = Fmu("Kinematics", kinematics_start(m))
    assert f.init()
    assert f.step(0.0, 250e-6)
    f.set(z_cmd=-800.0)                       # joint 1 at ≈ 636 mm > 580
    assert not f.step(250e-6, 250e-6)
    assert any("t = 0.0005 s" in line and "beyond its stroke" in line and "-800" in line for line in f.logs)
    f.close()


def test_flag_only_mode_holds_outputs():
    m = load_machine("keops")
    f = Fmu("Kinematics", {**kinematics_start(m), "stop_on_workspace_error": False})
    assert f.init()
    q0 = f.get("q1_cmd")[0]
    f.set(z_cmd=-800.0)
    assert f.step(0.0, 250e-6)
    assert f.get("workspace_ok") == [0.0] and f.get("q1_cmd")[0] == q0
    f.close()


def test_bad_parameters_fail_initialisation_with_a_message():
    f = Fmu("Kinematics", {"machine": "hexapod"})
    assert not f.init()
    assert any("machine = 'hexapod' is unknown; valid: keops, lineardelta, pn101" in line for line in f.logs)
    f.close()
    f = Fmu("Kinematics", {"L": -1.0})
    assert not f.init()
    assert any("L = -1 must be > 0" in line for line in f.logs)
    f.close()
