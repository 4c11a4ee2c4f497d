"""Drive.fmu (issue 4): CSP cascade servo, motor models, encoder, CiA 402 fault reaction.

Every expected value is independent of the model: closed forms (steady following error
v/Kp of a P position loop over a velocity loop with integral action), the data sheet
quantities (encoder increment, peak force), the thesis's measured following error.
"""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract
from fmpy.validation import validate_fmu

from harness.report.figures.kossel_thesis import trapezoid
from tests.fmu_util import SteppedFmu
from harness.cosim.drive_params import drive_start_values, nanotec_gains_to_si

ROOT = Path(__file__).resolve().parent.parent
FMU = ROOT / "fmus" / "build" / "Drive.fmu"


@pytest.fixture(scope="module")
def unzipped(tmp_path_factory):
    if not FMU.exists():
        subprocess.run([sys.executable, str(ROOT / "fmus" / "build.py")], check=True)
    return extract(str(FMU), unzipdir=str(tmp_path_factory.mktemp("drive")))


class Sim(SteppedFmu):
    """One drive FMU stepped from Python (tests/fmu_util.SteppedFmu)."""

    def __init__(self, unzipdir, start, step):
        super().__init__(unzipdir, start, step, "drive")

    def run(self, targets, names=("position", "following_error", "force", "state", "fault"),
            sync_ok=None):
        inputs = [{"target": tgt} if sync_ok is None else {"target": tgt, "sync_ok": sync_ok[k]}
                  for k, tgt in enumerate(targets)]
        return super().run(inputs, names)



def keops(**over):
    start = drive_start_values("keops")
    start.update(over)
    return start


def test_validation_clean():
    assert validate_fmu(str(FMU)) == []


def test_fmpy_simulate_standalone():
    from fmpy import simulate_fmu
    res = simulate_fmu(str(FMU), stop_time=0.01, output_interval=250e-6)
    assert len(res) > 10 and np.all(np.isfinite(res["position"]))


def test_ideal_drive_follows_target_exactly(unzipped):
    sim = Sim(unzipped, {"ideal": True}, 250e-6)
    q = 100.0 + np.cumsum(np.linspace(0, 0.3, 400))
    out = sim.run(q)
    sim.close()
    assert np.array_equal(out["position"], q)
    assert np.all(out["following_error"] == 0)


def ramp(v, T, n, x0=100.0):
    return x0 + v * T * np.arange(1, n + 1)


def no_disturbance(**over):
    """keops drive without quantisation, friction or saturation: the linear closed forms hold."""
    start = dict(encoder_resolution_mm=0.0, coulomb_N=0.0, viscous_N_s_per_m=10.0,
                 current_max_A=1e3, voltage_max_V=1e5, following_error_max_mm=0.0)
    start.update(over)
    return keops(**start)


def test_full_velocity_feedforward_ramp_has_zero_following_error(unzipped):
    T, v = 250e-6, 200.0                           # mm/s
    sim = Sim(unzipped, {**no_disturbance(vff=1.0), "target": 100.0}, T)
    out = sim.run(ramp(v, T, 4000))                # 1 s
    sim.close()
    fe = out["following_error"][-400:]             # last 0.1 s
    assert np.max(np.abs(fe)) < 1e-6               # mm: ~zero (nm level)


@pytest.mark.parametrize("kp", [50.0, 100.0])
def test_no_feedforward_ramp_settles_at_v_over_kp(unzipped, kp):
    T, v = 250e-6, 200.0
    sim = Sim(unzipped, {**no_disturbance(vff=0.0, kp_pos=kp), "target": 100.0}, T)
    out = sim.run(ramp(v, T, 8000))                # 2 s
    sim.close()
    fe = out["following_error"][-400:]
    assert np.allclose(fe, v / kp, rtol=1e-4)      # 4 mm at kp = 50 s^-1, 2 mm at 100 s^-1


def test_keops_encoder_steps_are_one_micrometre(unzipped):
    T = 250e-6
    sim = Sim(unzipped, {**keops(), "target": 100.0}, T)
    out = sim.run(ramp(2.0, T, 4000))              # 2 mm/s: 2 µm per 1 ms
    sim.close()
    pos = out["position"]
    counts = pos / 0.001
    assert np.allclose(counts, np.round(counts), atol=1e-6)
    steps = np.diff(pos)
    assert np.isclose(np.min(np.abs(steps[steps != 0])), 0.001, rtol=1e-6)


def test_kossel_encoder_steps_are_16000_per_rev(unzipped):
    T = 1e-3
    sim = Sim(unzipped, {**drive_start_values("kossel"), "target": 10.0}, T)
    out = sim.run(ramp(1.0, T, 500, x0=10.0))
    sim.close()
    inc = 31.416 / 16000                           # 1.9635 µm
    counts = out["position"] / inc
    assert np.allclose(counts, np.round(counts), atol=1e-6)
    steps = np.diff(out["position"])
    assert np.isclose(np.min(np.abs(steps[steps != 0])), inc, rtol=1e-6)


def test_saturation_caps_the_force(unzipped):
    T = 250e-6
    start = keops(following_error_max_mm=0.0)      # no following-error fault here
    peak = 480.0                                   # keops.toml force_peak_N
    sim = Sim(unzipped, {**start, "target": 100.0}, T)
    out = sim.run(np.full(800, 110.0))             # a 10 mm step
    sim.close()
    force = np.abs(out["force"])
    assert force.max() <= peak * 1.02              # current PI overshoot stays small
    assert force.max() >= peak * 0.95              # and the cap is actually reached
    assert abs(out["position"][-1] - 110.0) < 0.01  # and it still gets there


def test_following_error_over_limit_faults_and_quick_stops(unzipped):
    T = 250e-6
    sim = Sim(unzipped, {**keops(following_error_max_mm=1.0), "target": 100.0}, T)
    out = sim.run(np.r_[np.full(100, 100.0), np.full(400, 150.0)])   # a 50 mm jump: FE ≫ 1 mm
    sim.close()
    assert np.all(out["state"][:100] == 4) and not out["fault"][:100].any()  # operation enabled
    assert out["fault"][100] and out["state"][100] == 6      # fault reaction in the jump's cycle
    assert out["fault"][-1] and out["state"][-1] == 7        # CiA 402 fault
    assert abs(out["position"][-1] - 100.0) < 1.0            # stopped, did not chase the target


def test_sync_error_quick_stops_on_the_fast_ramp(unzipped):
    T, v = 250e-6, 100.0
    decel = 50000.0                                # keops.toml quickstop_decel_mm_s2
    sim = Sim(unzipped, {**no_disturbance(vel_filter_tau_s=0.0), "target": 100.0}, T)
    n = 2000
    sync = np.ones(n, dtype=bool)
    sync[1000:] = False
    out = sim.run(ramp(v, T, n), names=("position", "state", "fault"), sync_ok=sync)
    sim.close()
    assert np.all(out["state"][:1000] == 4)
    assert out["state"][1000] == 6                 # fault reaction active: ramping down
    assert out["state"][-1] == 7
    # stopping distance of the ramp v²/2a (closed form), the loop follows within a few µm
    x_fault = 100.0 + v * T * 1000
    assert out["position"][-1] == pytest.approx(x_fault + v * v / (2 * decel), abs=0.01)


@pytest.mark.parametrize("bad, word", [
    ({"kp_pos": 0.0}, "kp_pos"), ({"kp_vel": -1.0}, "kp_vel"), ({"kp_cur": 0.0}, "kp_cur"),
    ({"motor": "brushed"}, "motor"), ({"inner_period_s": 0.0}, "inner"),
    ({"interpolation": "quintic"}, "interpolation"),
])
def test_bad_parameters_fail_initialisation_with_a_message(unzipped, bad, word):
    msgs = init_failure_messages(unzipped, keops(**bad))
    assert any(word in m for m in msgs), msgs


def init_failure_messages(unzipped, start):
    """Initialise an instance that must fail; return what its logger said."""
    try:
        Sim(unzipped, start, 250e-6)
    except Exception:
        return Sim.last_messages
    raise AssertionError(f"initialisation accepted {start}")


def test_step_not_a_multiple_of_inner_period_is_an_error(unzipped):
    sim = Sim(unzipped, keops(), 300e-6)
    with pytest.raises(Exception):
        sim.run([100.0])
    assert any("multiple" in m for m in sim.messages)


def test_same_inputs_same_outputs_and_fmu_state_round_trip(unzipped):
    T = 1e-3
    q = 10.0 + np.cumsum(np.r_[np.linspace(0, 0.02, 200), np.full(200, 0.02)])
    sim = Sim(unzipped, {**drive_start_values("kossel"), "target": 10.0}, T)
    first = sim.run(q[:200])
    state = sim.fmu.getFMUState()
    t_saved = sim.t
    tail = sim.run(q[200:])
    sim.fmu.setFMUState(state)
    sim.t = t_saved
    again = sim.run(q[200:])
    sim.fmu.freeFMUState(state)
    sim.close()
    other = Sim(unzipped, {**drive_start_values("kossel"), "target": 10.0}, T)
    rerun = other.run(q)
    other.close()
    for n in tail:
        assert np.array_equal(tail[n], again[n])
        assert np.array_equal(np.r_[first[n], tail[n]], rerun[n])


def test_cubic_interpolation_also_tracks_a_ramp(unzipped):
    T, v = 250e-6, 200.0
    sim = Sim(unzipped, {**no_disturbance(interpolation="cubic"), "target": 100.0}, T)
    out = sim.run(ramp(v, T, 4000))
    sim.close()
    assert np.max(np.abs(out["following_error"][-400:])) < 1e-6


# ---- the Kossel thesis (shared/SOURCES.md §C): tuned cascade, three trapezoidal moves ----

def test_nanotec_conversion_of_table4():
    si = nanotec_gains_to_si({"position_p": 1500, "position_i": 0, "velocity_p": 22000,
                              "velocity_i": 1600, "current_p": 120000, "current_i": 5000,
                              "velocity_ff_permille": 1000, "acceleration_ff_permille": 0},
                             31.416)
    assert si["kp_pos"] == pytest.approx(15.0)
    assert si["kp_vel"] == pytest.approx(2.2 / 0.031416)
    assert si["ki_vel"] == pytest.approx(16.0 / 0.031416)
    assert si["kp_cur"] == pytest.approx(6.0) and si["ki_cur"] == pytest.approx(5000.0)
    assert si["vff"] == 1.0 and si["aff"] == 0.0


def test_kossel_thesis_moves_following_error_about_23_um(unzipped):
    T, a = 1e-3, 500.0
    start = drive_start_values("kossel")
    inc = 31.416 / 16000
    worst = 0.0
    for distance, v, back in ((20.0, 10.0, False), (2.5, 10.0, True), (1.0, 20.0, False)):
        x, tt = trapezoid(distance, v, a, T, tail=0.3)
        if back:                                   # ±2.5 mm: out and straight back
            xb, _ = trapezoid(distance, v, a, T, tail=0.3)
            x = np.concatenate([x[: int(round(tt / T))], distance - xb])
        x0 = 50.0
        sim = Sim(unzipped, {**start, "target": x0}, T)
        out = sim.run(x0 + x, names=("position", "load_position", "following_error"))
        sim.close()
        fe_um = np.abs(out["following_error"]) * 1e3
        worst = max(worst, fe_um.max())
        end = x0 + (0.0 if back else distance)
        # true load position: no overshoot beyond one encoder increment (the loop only sees
        # the quantised position, so it cannot hold the load closer than that)
        overshoot = out["load_position"].max() - end if not back else end - out["load_position"].min()
        assert overshoot <= inc
        assert abs(out["position"][-1] - end) < 3 * inc
    assert 15.0 <= worst <= 35.0                   # thesis: about 23 µm


def test_drive_params_for_every_machine_initialise(unzipped):
    from kins import available_machines
    for name in available_machines():
        start = drive_start_values(name)
        sim = Sim(unzipped, {**start, "target": 12.5}, 1e-3)
        out = sim.run([12.5, 12.5])
        sim.close()
        assert np.all(np.isfinite(out["position"])), name


def test_nanotec_conversion_rejects_what_it_cannot_model():
    from kins import MachineFileError
    gains = {"position_p": 1500, "position_i": 10, "velocity_p": 22000, "velocity_i": 1600,
             "current_p": 120000, "current_i": 5000}
    with pytest.raises(MachineFileError, match="position_i"):
        nanotec_gains_to_si(gains, 31.416)
    with pytest.raises(MachineFileError, match="velocity_p"):
        nanotec_gains_to_si({**gains, "position_i": 0, "velocity_p": 0}, 31.416)
