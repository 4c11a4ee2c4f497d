"""Kossel thesis (Wąsowski, NCU Toruń 2024): Fig. 29, the servo-thread latency histogram
(EtherCAT.fmu preset `linuxcnc_rt_preempt`: nearly all cycles within ±20 µs, worst ±400 µs), and
Figs. 41–43, the velocity-loop responses to trapezoidal velocity targets (10 mm/s over 500 ms,
20 mm/s over 300 ms, 30 mm/s over 200 ms, 500 mm/s²; thesis: no overshoot, ~20 ms lag), and
Figs. 44–46, the tuning moves +20 mm at 10 mm/s, ±2.5 mm at 10 mm/s, +1 mm at 20 mm/s with
500 mm/s² through Drive.fmu with the tuned gains (thesis: maximum following error ≈ 23 µm)."""
from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from harness.cosim.drive_params import drive_start_values, ethercat_start_values
from harness.cosim.fmu_driver import SteppedFmu
from harness.cosim.system import FMU_DIR
from harness.report.figures import pyplot, save

VELOCITY_TARGETS = (("fig41", 10.0, 0.5), ("fig42", 20.0, 0.3), ("fig43", 30.0, 0.2))
MOVES = (("fig44", 20.0, 10.0, False), ("fig45", 2.5, 10.0, True), ("fig46", 1.0, 20.0, False))


def trapezoid(distance, v, a, T, tail=0.3):
    """Positions of a trapezoidal move sampled at T (closed form), plus a settle tail."""
    ta = v / a
    if a * ta * ta > distance:
        ta = np.sqrt(distance / a)
        v = a * ta
    tc = (distance - a * ta * ta) / v
    tt = 2 * ta + tc
    t = np.arange(1, int(round((tt + tail) / T)) + 1) * T
    x = np.where(t < ta, 0.5 * a * t ** 2,
                 np.where(t < ta + tc, 0.5 * a * ta ** 2 + v * (t - ta),
                          np.where(t < tt, distance - 0.5 * a * np.clip(tt - t, 0, None) ** 2,
                                   distance)))
    return x, tt


def latency(out: Path, cycles: int = 1_000_000, seed: int = 1) -> dict:

    T = 1e-3
    with tempfile.TemporaryDirectory() as d:
        hist = Path(d) / "lateness.csv"
        start = {**ethercat_start_values("kossel", histogram_out=str(hist), seed=seed), "preset": "linuxcnc_rt_preempt"}
        bus = SteppedFmu(FMU_DIR / "EtherCAT.fmu", start, T, "ethercat")
        bus.fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=cycles * T)   # k cycles per step
        bus.close()                                                                       # writes the histogram
        rows = [ln for ln in hist.read_text().splitlines() if ln[:1].isdigit() or ln[:1] == "-"]
        data = np.array([[float(x) for x in ln.split(",")] for ln in rows])   # comments/header skipped
    lo, hi, count = data[:, 0], data[:, 1], data[:, 2]
    mid = 0.5 * (lo + hi)
    within = count[(lo >= -20) & (hi <= 20)].sum() / count.sum()
    worst = float(np.abs(lo[count > 0]).max())   # |lateness| in the outermost non-empty 1 µs bin
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8, 3.6))
    nz = count > 0
    ax.bar(mid[nz], count[nz], width=(hi - lo)[nz], color="tab:blue", label="linuxcnc_rt_preempt (EtherCAT.fmu)")
    ax.set(yscale="log", xlabel="servo-thread lateness (µs)", ylabel="cycles",
           title=f"Fig. 29 — latency histogram, {cycles:,} cycles at 1 ms: {100 * within:.2f} % within ±20 µs, worst {worst:.0f} µs")
    for x in (-20, 20):
        ax.axvline(x, color="k", ls="--", lw=1)
    ax.legend(fontsize=8)
    fig.tight_layout()
    save(fig, out, "kossel_fig29_latency", {"bin_lo_us": lo, "bin_hi_us": hi, "count": count})
    return {"cycles": cycles, "within_20us": float(within), "worst_us": worst}


def _drive_trace(start: dict, x0: float, targets, T: float, outputs) -> list[np.ndarray]:
    """Drive.fmu at rest at x0, then fed one CSP target per period: each output's trace."""
    sim = SteppedFmu(FMU_DIR / "Drive.fmu", {**start, "target": x0}, T, "drive")
    out = sim.run([{"target": float(x)} for x in targets], outputs)
    sim.close()
    return [out[n] for n in outputs]


def moves(out: Path) -> dict:

    T, a, x0 = 1e-3, 500.0, 50.0
    start = drive_start_values("kossel")
    plt = pyplot()
    result = {}
    for name, distance, v, back in MOVES:
        x, tt = trapezoid(distance, v, a, T)
        if back:                       # ±2.5 mm: out and straight back
            xb, _ = trapezoid(distance, v, a, T)
            x = np.concatenate([x[: int(round(tt / T))], distance - xb])
        pos, fe = _drive_trace(start, x0, x0 + x, T, ("position", "following_error"))
        t = np.arange(1, len(x) + 1) * T
        fe_um = fe * 1e3
        label = f"{'±' if back else '+'}{distance:g} mm at {v:g} mm/s"
        result[name] = {"move": label, "max_following_error_um": float(np.abs(fe_um).max())}
        fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
        a1.plot(t, x0 + x, "k--", lw=1, label="target (CSP)")
        a1.plot(t, pos, lw=1, label="position (Drive.fmu, tuned gains)")
        a1.set(ylabel="position (mm)", title=f"Fig. {name[3:]} — {label}, 500 mm/s²")
        a1.legend(fontsize=8)
        a2.plot(t, fe_um, lw=1, color="tab:red", label="following error")
        a2.set(xlabel="time (s)", ylabel="following error (µm)")
        a2.legend(fontsize=8)
        fig.tight_layout()
        save(fig, out, f"kossel_{name}_move", {"t_s": t, "target_mm": x0 + x, "position_mm": pos, "following_error_um": fe_um})
    return result


def _crossing(t, v, level):
    """First time v rises through level (linear between samples)."""
    k = int(np.argmax(v >= level))
    return float(t[k - 1] + (level - v[k - 1]) / (v[k] - v[k - 1]) * (t[k] - t[k - 1]))


def velocity_responses(out: Path) -> dict:
    """Figs. 41–43. The thesis tuned the velocity loop in velocity mode, before the position loop:
    we emulate that in CSP with the position gain at ~0 (1e-6 s⁻¹; the FMU needs > 0), so the
    velocity loop's setpoint is the feed-forward of the target's velocity. The target velocity is
    one trapezoid of the period's length (ramps at 500 mm/s²) out and one back, then a rest."""

    T, a, x0 = 1e-3, 500.0, 50.0
    start = {**drive_start_values("kossel"), "kp_pos": 1e-6, "following_error_max_mm": 0.0}
    plt = pyplot()
    result = {}
    for name, V, period in VELOCITY_TARGETS:
        distance = V * (period - V / a)          # a velocity trapezoid lasting exactly `period`
        out_, _ = trapezoid(distance, V, a, T, tail=0.0)
        back, _ = trapezoid(distance, V, a, T, tail=0.15)
        x = np.concatenate([out_, distance - back])
        reported, load = _drive_trace(start, x0, x0 + x, T, ("velocity", "load_position"))
        t = np.arange(1, len(x) + 1) * T
        v_target = np.diff(np.concatenate([[0.0], x])) / T            # mean over each cycle
        v_carriage = np.diff(np.concatenate([[x0], load])) / T        # true carriage, mean over each cycle
        # metrics on a 5 ms moving mean: the 1 ms samples carry the stepper/encoder ripple, which
        # the thesis's oscilloscope traces smooth too; the ripple is reported on its own
        w = 5
        smooth = np.convolve(v_carriage, np.ones(w) / w, mode="same")
        half = len(out_)
        lag_ms = 1e3 * (_crossing(t[:half], smooth[:half], V / 2) - _crossing(t[:half], v_target[:half], V / 2))
        overshoot = 100 * (np.abs(smooth).max() / V - 1)
        hold = (t > V / a + 0.02) & (t < period - V / a - 0.01)
        ripple = float(np.ptp(v_carriage[hold]))
        result[name] = {"target": f"{V:g} mm/s, period {1e3 * period:g} ms", "lag_ms": float(lag_ms),
                        "overshoot_pct": float(overshoot), "ripple_mm_s": ripple}
        fig, ax = plt.subplots(figsize=(8, 3.8))
        ax.plot(t, reported, lw=0.6, color="tab:gray", alpha=0.7, label="velocity actual 606Ch (encoder, filtered)")
        ax.plot(t, v_carriage, lw=1.2, color="tab:blue", label="carriage velocity (Drive.fmu, tuned velocity loop)")
        ax.plot(t, v_target, "k--", lw=1, label="velocity target (trapezoid, 500 mm/s²)")
        for y in (V, -V):
            ax.axhline(y, color="tab:red", ls="--", lw=0.7)
        ax.set(xlabel="time (s)", ylabel="velocity (mm/s)")
        ax.set_title(f"Fig. {name[3:]} — velocity response, {V:g} mm/s, period {1e3 * period:g} ms: "
                     f"lag {lag_ms:.1f} ms, overshoot {overshoot:.1f} % (5 ms mean)", fontsize=9)
        ax.legend(fontsize=8, loc="upper right")
        fig.tight_layout()
        save(fig, out, f"kossel_{name}_velocity", {"t_s": t, "target_velocity_mm_s": v_target,
                                                   "carriage_velocity_mm_s": v_carriage,
                                                   "reported_velocity_mm_s": reported})
    return result
