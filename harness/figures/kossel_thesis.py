"""Kossel thesis (Wąsowski, NCU Toruń 2024): Fig. 29, the servo-thread latency histogram
(EtherCAT.fmu preset `linuxcnc_rt_preempt`: nearly all cycles within ±20 µs, worst ±400 µs), and
Figs. 44–46, the tuning moves +20 mm at 10 mm/s, ±2.5 mm at 10 mm/s, +1 mm at 20 mm/s with
500 mm/s² through Drive.fmu with the tuned gains (thesis: maximum following error ≈ 23 µm)."""
from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from harness.figures import pyplot, save
from harness.fmu_driver import SteppedFmu
from harness.system import FMU_DIR

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
    from harness.drive_params import ethercat_start_values

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


def moves(out: Path) -> dict:
    from harness.drive_params import drive_start_values

    T, a, x0 = 1e-3, 500.0, 50.0
    start = drive_start_values("kossel")
    plt = pyplot()
    result = {}
    for name, distance, v, back in MOVES:
        x, tt = trapezoid(distance, v, a, T)
        if back:                       # ±2.5 mm: out and straight back
            xb, _ = trapezoid(distance, v, a, T)
            x = np.concatenate([x[: int(round(tt / T))], distance - xb])
        sim = SteppedFmu(FMU_DIR / "Drive.fmu", {**start, "target": x0}, T, "drive")
        pos, fe = [], []
        for k, tgt in enumerate(x0 + x):
            sim.set({"target": float(tgt)})
            sim.fmu.doStep(currentCommunicationPoint=k * T, communicationStepSize=T)
            pos.append(sim.get("position"))
            fe.append(sim.get("following_error"))
        sim.close()
        t = np.arange(1, len(x) + 1) * T
        pos, fe_um = np.array(pos), np.array(fe) * 1e3
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
