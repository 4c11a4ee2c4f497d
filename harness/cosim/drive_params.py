"""Machine-file values → start values of Drive.fmu and EtherCAT.fmu (issue 4).

    from harness.cosim.drive_params import drive_start_values, ethercat_start_values
    drive = drive_start_values("kossel")          # {FMU variable name: value}
    bus = ethercat_start_values("kossel", histogram_out="out/lateness.csv")

Both read the ``[drive]`` and ``[ethercat]`` sections of ``benchmarks/machines/<id>.toml``.
A machine either gives SI gains (``[drive.gains]``, keops) or the Nanotec C5-E internal
gains of object 3210h as the Kossel thesis lists them (``[drive.nanotec_gains]``, Table 4).

Nanotec 3210h → SI (``nanotec_gains_to_si``). The public C5-E manual lists the
objects but not their physical units, so the units below are ASSUMED; each is chosen as
a round decimal unit and checked against what the thesis observed (shared/SOURCES.md §C):

=================  =================================  =====================  =====================
3210h entry        assumed unit                       tuned value (Table 4)  SI
=================  =================================  =====================  =====================
position P (:01)   0.01 s⁻¹ (mm/s per mm)             1500                   kp_pos = 15 s⁻¹
velocity P (:03)   0.1 mA per rev/s                   22000                  2.2 A/(rev/s) = 70.0 A·s/m
velocity I (:04)   10 mA per rev (per rev/s · s)      1600                   16 A/rev = 509 A/m (Ti = 137.5 ms)
current P (:05/7)  50 µV/A                            120000                 kp_cur = 6 V/A
current I (:06/8)  1 V/(A·s)                          5000                   ki_cur = 5000 V/(A·s)
VFF / AFF (:0B/C)  per mille                          1000 / 0               1.0 / 0.0
=================  =================================  =====================  =====================

rev → m through the feed constant 6092h (31.416 mm/rev). Checks: the current PI's zero
kp/ki = 1.2 ms sits at the winding's L/R (1.5 ms, assumed motor data), as a tuned PI
should; the thesis heard the current loop get noisy from P ≈ 280 000, which is 14 V/A here,
where kp·Ts/L = 0.73 at Ts = 62.5 µs — close to the discrete loop's limit. With these units,
the assumed carriage mass (0.25 kg) and friction (2 N·s/m, 1 N), the three tuning moves of
the thesis (+20 mm at 10 mm/s, ±2.5 mm at 10 mm/s, +1 mm at 20 mm/s, 500 mm/s²) give a
maximum following error of about 25 µm (thesis: 23 µm); tests/test_fmu_drive_kossel.py
checks it. Not reproduced: the velocity-loop instability the thesis saw above P = 28 000
(the model stays stable there; the real C5-E likely runs a slower velocity loop).
Position I (3210h:02) is not modelled and must be 0.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from harness.seed import fmu_seed
from kins.resources import REPO
from kins import load_machine
from kins.machine import Kinematics, MachineFileError

# assumed units of Nanotec 3210h (see the module docstring)
NANOTEC_POSITION_P_PER_S = 0.01
NANOTEC_VELOCITY_P_A_PER_REV_S = 1e-4
NANOTEC_VELOCITY_I_A_PER_REV = 1e-2
NANOTEC_CURRENT_P_V_PER_A = 5e-5
NANOTEC_CURRENT_I_V_PER_A_S = 1.0


def nanotec_gains_to_si(gains: dict[str, float], feed_mm_per_rev: float,
                        where: str = "[drive.nanotec_gains]") -> dict[str, float]:
    """Nanotec C5-E 3210h gains (internal units) → the SI gain parameters of Drive.fmu."""
    need = ("position_p", "velocity_p", "velocity_i", "current_p", "current_i")
    for key in need:
        if key not in gains:
            raise MachineFileError(f"{where}: missing '{key}'")
        if not isinstance(gains[key], (int, float)) or gains[key] < 0:
            raise MachineFileError(f"{where}: '{key}' = {gains[key]!r} must be a number >= 0")
    for key in ("position_p", "velocity_p", "current_p"):
        if gains[key] <= 0:
            raise MachineFileError(f"{where}: '{key}' = {gains[key]} must be > 0")
    if gains.get("position_i", 0) != 0:
        raise MachineFileError(f"{where}: position_i = {gains['position_i']} is not modelled; set 0")
    if not feed_mm_per_rev > 0:
        raise MachineFileError(f"{where}: feed constant {feed_mm_per_rev} mm/rev must be > 0")
    feed_m = feed_mm_per_rev * 1e-3
    return {
        "kp_pos": gains["position_p"] * NANOTEC_POSITION_P_PER_S,
        "kp_vel": gains["velocity_p"] * NANOTEC_VELOCITY_P_A_PER_REV_S / feed_m,
        "ki_vel": gains["velocity_i"] * NANOTEC_VELOCITY_I_A_PER_REV / feed_m,
        "kp_cur": gains["current_p"] * NANOTEC_CURRENT_P_V_PER_A,
        "ki_cur": gains["current_i"] * NANOTEC_CURRENT_I_V_PER_A_S,
        "vff": gains.get("velocity_ff_permille", 1000) / 1000.0,
        "aff": gains.get("acceleration_ff_permille", 0) / 1000.0,
    }


def _machine(machine: str | Path | Kinematics) -> Kinematics:
    return machine if isinstance(machine, Kinematics) else load_machine(machine)


def _section(m: Kinematics, name: str) -> dict[str, Any]:
    sec = m.raw.get(name)
    if not isinstance(sec, dict):
        raise MachineFileError(f"machine '{m.name}': no [{name}] section")
    return sec


# machine-file key → Drive.fmu parameter (same unit)
_DRIVE_KEYS = {
    "inner_period_s": "inner_period_s", "interpolation": "interpolation",
    "mass_kg": "mass_kg", "force_constant_N_per_A": "force_constant_N_per_A",
    "torque_constant_Nm_per_A": "torque_constant_Nm_per_A",
    "rotor_inertia_kgm2": "rotor_inertia_kgm2", "pulley_mm_per_rev": "pulley_mm_per_rev",
    "encoder_increments_per_rev": "encoder_increments_per_rev",
    "encoder_resolution_mm": "encoder_resolution_mm",
    "resistance_ohm": "resistance_ohm", "inductance_H": "inductance_H",
    "viscous_N_s_per_m": "viscous_N_s_per_m", "coulomb_N": "coulomb_N",
    "current_max_A": "current_max_A", "voltage_max_V": "voltage_max_V",
    "vel_filter_tau_s": "vel_filter_tau_s", "following_error_max_mm": "following_error_max_mm",
    "quickstop_decel_mm_s2": "quickstop_decel_mm_s2",
}
_SI_GAIN_KEYS = {
    "kp_pos_per_s": "kp_pos", "kp_vel_A_s_per_m": "kp_vel", "ki_vel_A_per_m": "ki_vel",
    "kp_cur_V_per_A": "kp_cur", "ki_cur_V_per_A_s": "ki_cur",
    "velocity_ff": "vff", "acceleration_ff": "aff",
}


def drive_start_values(machine: str | Path | Kinematics) -> dict[str, Any]:
    """Start values for one Drive.fmu instance (all three axes of a machine are alike)."""
    m = _machine(machine)
    sec = _section(m, "drive")
    where = f"machine '{m.name}' [drive]"
    out: dict[str, Any] = {"ideal": bool(sec.get("ideal", False))}
    if out["ideal"]:
        return out
    if "motor" not in sec:
        raise MachineFileError(f"{where}: missing 'motor' (linear | stepper_belt)")
    out["motor"] = sec["motor"]
    for key, var in _DRIVE_KEYS.items():
        if key in sec:
            out[var] = sec[key]
    if sec["motor"] == "linear":
        # the current limit follows from the peak force
        if "force_peak_N" in sec and "force_constant_N_per_A" in sec:
            out["current_max_A"] = sec["force_peak_N"] / sec["force_constant_N_per_A"]
    if "nanotec_gains" in sec:
        out.update(nanotec_gains_to_si(sec["nanotec_gains"], sec.get("pulley_mm_per_rev", 0.0),
                                       f"{where} nanotec_gains"))
    elif "gains" in sec:
        for key, var in _SI_GAIN_KEYS.items():
            if key in sec["gains"]:
                out[var] = sec["gains"][key]
    else:
        raise MachineFileError(f"{where}: needs [drive.gains] (SI) or [drive.nanotec_gains]")
    return out


def encoder_increment_mm(machine: str | Path | Kinematics) -> float | None:
    """One encoder increment of the machine's drives in mm (None for ideal drives): the
    resolution of every measured position, so of the following and contour errors too."""
    m = _machine(machine)
    sec = _section(m, "drive")
    if sec.get("ideal", False):
        return None
    if "encoder_resolution_mm" in sec:
        return float(sec["encoder_resolution_mm"])
    if "encoder_increments_per_rev" in sec and "pulley_mm_per_rev" in sec:
        return float(sec["pulley_mm_per_rev"]) / float(sec["encoder_increments_per_rev"])
    return None


_ECAT_KEYS = ("preset", "distribution", "sigma_s", "tail_probability", "tail_scale_s",
              "tail_shape", "cap_s", "startup_lateness_s", "histogram_file", "sync0_shift_s",
              "frame_bytes", "slaves", "forward_delay_s", "on_lost", "extrapolate_cycles",
              "loss_probability", "delay_cycles", "sync_error_limit", "seed",
              "forced_late_cycles", "histogram_bin_s")


def ethercat_start_values(machine: str | Path | Kinematics, *, histogram_out: str = "",
                          seed: int | None = None) -> dict[str, Any]:
    """Start values for EtherCAT.fmu; the cycle defaults to the machine's servo period.
    A relative histogram_file is taken relative to the repository root."""
    m = _machine(machine)
    sec = _section(m, "ethercat")
    out: dict[str, Any] = {"cycle_s": sec.get("cycle_s", m.servo_period_s)}
    for key in _ECAT_KEYS:
        if key in sec:
            out[key] = sec[key]
    if out.get("histogram_file"):
        p = Path(out["histogram_file"])
        if not p.is_absolute():
            p = REPO / p
        out["histogram_file"] = str(p)
    if seed is not None:
        out["seed"] = seed
    if "seed" in out:   # the FMU's 32-bit Integer (harness/seed.py)
        out["seed"] = fmu_seed(out["seed"], f"machine '{m.name}' [ethercat] seed" if seed is None else "seed")
    if histogram_out:
        out["histogram_out"] = str(histogram_out)
    return out
