"""Co-simulation speed on the keops bird chain, side by side in one run:
  naive   — the plain-Python reference master (fmpy FMU2Slave calls every step)
  harness — the default native master (C stepping loop, routing, recording)
  minimal — the same C loop with no connections and no recording: only the FMUs' fmi2DoStep,
            i.e. a minimal C master stepping the same FMUs (model compute included)
Prints the ratios and the real-time factor; main() -> dict for run_all.py.
    .venv/bin/python benchmarks/perf/bench_harness.py
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import planners
from harness.cosim.master import simulate
from harness.cosim.run import RECORD
from harness.cosim.system import System, chain
from kins import load_machine

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_kins import _best_of  # noqa: E402  (best-of-n wall time, shared by the benchmarks)


def main() -> dict:
    m = load_machine("keops")
    profile = planners.plan("scurve", "bird", m)
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        profile.path.to_file(d / "path.json")
        profile.save_csv(d / "profile.csv")
        n = len(profile.s) - 1
        system = chain(m, d / "path.json", d / "profile.csv", n * m.servo_period_s)
        bare = System(system.components, [], system.step_size, system.stop_time)
        sim_s = n * m.servo_period_s
        t_naive = _best_of(lambda: simulate(system, RECORD, engine="python"), 1)
        t_native = _best_of(lambda: simulate(system, RECORD, engine="native"), 3)
        t_min = _best_of(lambda: simulate(bare, [], engine="native"), 3)
        # instantiation/initialisation is common to all three: time it alone and subtract
        short = System(system.components, system.connections, system.step_size, system.step_size)
        t_init = _best_of(lambda: simulate(short, RECORD, engine="native"), 3)
    steps = n
    out = {
        "simulated_s": sim_s, "steps": steps, "init_s": t_init,
        "naive_us_per_step": (t_naive - t_init) / steps * 1e6,
        "harness_us_per_step": (t_native - t_init) / steps * 1e6,
        "minimal_us_per_step": (t_min - t_init) / steps * 1e6,
    }
    out["naive_over_harness"] = out["naive_us_per_step"] / out["harness_us_per_step"]
    out["harness_over_minimal"] = out["harness_us_per_step"] / out["minimal_us_per_step"]
    out["real_time_factor"] = sim_s / t_native
    print(f"keops bird chain (6 FMUs, T = 250 µs, {steps} steps = {sim_s:.3f} s simulated; init {t_init * 1e3:.1f} ms)")
    print(f"  naive Python master  {out['naive_us_per_step']:8.2f} µs/step")
    print(f"  harness (native)     {out['harness_us_per_step']:8.2f} µs/step")
    print(f"  minimal C loop       {out['minimal_us_per_step']:8.2f} µs/step")
    print(f"  naive / harness = {out['naive_over_harness']:.1f}×   harness / minimal = {out['harness_over_minimal']:.2f}× "
          f"(target ≤ 3×)   real-time factor {out['real_time_factor']:.0f}× (target ≥ 50×)")
    return out


if __name__ == "__main__":
    main()
