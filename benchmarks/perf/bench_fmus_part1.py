"""Speed of Interpolator.fmu and Kinematics.fmu per step, timed in C (issue 3).

Uses the C driver of bench_fmus_part2 (dlopen the FMU's library, fmi2DoStep in a loop).
Interpolator: a cubic NURBS with 60 control points, s-curve profile at T = 250 µs, every
step a new arc length (the profile is never exhausted). Kinematics: keops IK + FK per step.
Targets: Interpolator ≤ 2 µs/step (anchor: RK2 interpolator 4.25 µs on an i5-6600, TII 2022),
Kinematics ≤ 0.5 µs per IK+FK step.     usage: .venv/bin/python benchmarks/perf/bench_fmus_part1.py
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_fmus_part2 import build_driver, time_fmu  # noqa: E402


def main() -> dict:
    import planners
    from kins import load_machine
    from planners.paths import NurbsPath

    m = load_machine("keops")
    n = 60
    t = np.linspace(0, 2 * np.pi, n)
    cps = np.column_stack([70 * np.cos(t), 50 * np.sin(2 * t), np.full(n, -400.0)])
    knots = np.concatenate([[0] * 4, np.linspace(0, 1, n - 2)[1:-1], [1] * 4])
    path = NurbsPath(3, knots, cps, np.linspace(0.7, 1.3, n))
    prof = planners.plan("scurve", path, m)
    steps = len(prof.s) - 1
    out = {}
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        path.to_file(d / "p.json")
        prof.save_csv(d / "p.csv")
        exe = build_driver(d)
        ns = time_fmu(exe, "Interpolator", m.servo_period_s, steps, {},
                      {"path_file": str(d / "p.json"), "profile_file": str(d / "p.csv")}, d)
        out["interpolator_us_per_step"] = ns / 1e3
        ns = time_fmu(exe, "Kinematics", m.servo_period_s, 1_000_000, {"x_cmd": 10.0, "y_cmd": 5.0}, {}, d)
        out["kinematics_us_per_step"] = ns / 1e3
    print(f"Interpolator  {out['interpolator_us_per_step']:.3f} µs/step  ({n}-point cubic NURBS, {steps} steps; target ≤ 2 µs)")
    print(f"Kinematics    {out['kinematics_us_per_step']:.3f} µs/step  (keops IK + FK + cond(J); target ≤ 0.5 µs)")
    return out


if __name__ == "__main__":
    main()
