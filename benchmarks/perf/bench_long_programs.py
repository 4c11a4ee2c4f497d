"""Program-length kossel G-code (issue 17, defect 6): generator and planner benchmark.

A CAM-like program inside the kossel workspace (benchmarks/machines/kossel.toml: X/Y ±50 mm,
Z −345…−125 mm; the features stay within 42 mm of the axis and between Z −290 and −235 mm,
where every joint is inside its −280…25 mm stroke): features one after another, each

* a rapid above its start, a plunge (G1), then a wavy closed contour of short G1 chords
  (0.3–0.8 mm, as a CAM post cuts a freeform curve), or an Archimedean spiral pocket of
  short chords — both under G64 P0.01, so every chord corner becomes a blend arc (a G1 join);
* a full circle (G2/G3) at the end of some contours: a corner touching an arc is an exact stop;
* a rapid retract.

The program is a function of (seed, feature count) only.  ``--seconds S`` picks the feature
count: the trapezoid plan of a short calibration program gives seconds per feature, and the
count is rounded from S over that, then rescaled once by the time of that program (the
trapezoid time of the written program is printed).

    python benchmarks/perf/bench_long_programs.py write --seconds 60 --out /tmp/long60.ngc
    python benchmarks/perf/bench_long_programs.py plan --path /tmp/long60.ngc --planners pso

``plan`` runs one planner per process (run it under /usr/bin/time -v for the peak RSS) and
prints planning time, execution time, feasibility and the fallback the planner reports.
Not a test: numbers only.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path as FsPath

import numpy as np

sys.path.insert(0, str(FsPath(__file__).resolve().parents[2]))

SAFE_Z = -235.0            # rapids run here: above every cut
R_MAX = 42.0               # no point farther from the axis (lineardelta: joints in stroke)
CALIBRATION_FEATURES = 12


def _num(x: float) -> str:
    s = f"{x:.4f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def _contour(rng, lines):
    """A wavy closed curve r(θ) = r0·(1 + a·sin(kθ + φ)) of short chords; maybe a circle after."""
    r0 = rng.uniform(5.0, 15.0)
    a, k, phi = rng.uniform(0.05, 0.25), int(rng.integers(2, 7)), rng.uniform(0, 2 * np.pi)
    cx, cy = rng.uniform(-1, 1, 2) * (R_MAX - r0 * (1 + a))
    z = rng.uniform(-290.0, -245.0)
    # chord lengths 0.3–0.8 mm, as a CAM post cutting the curve within its tolerance
    n = int(2 * np.pi * r0 / rng.uniform(0.3, 0.8))
    th = np.linspace(0.0, 2 * np.pi, n + 1)
    r = r0 * (1 + a * np.sin(k * th + phi))
    x, y = cx + r * np.cos(th), cy + r * np.sin(th)
    lines.append(f"G0 X{_num(x[0])} Y{_num(y[0])} Z{_num(SAFE_Z)}")
    lines.append(f"G1 Z{_num(z)} F300")
    for i in range(1, n + 1):
        lines.append(f"G1 X{_num(x[i])} Y{_num(y[i])}" + (" F1200" if i == 1 else ""))
    if rng.random() < 0.5:
        # a full circle about the contour's centre, reached by a short G1 (exact stops at both
        # ends of the arc: a line-arc corner is not blended)
        rc = 0.5 * r0
        lines.append(f"G1 X{_num(cx + rc)} Y{_num(cy)}")
        lines.append(f"G{2 if rng.random() < 0.5 else 3} X{_num(cx + rc)} Y{_num(cy)} I{_num(-rc)} J0")
    lines.append(f"G0 Z{_num(SAFE_Z)}")


def _spiral(rng, lines):
    """An Archimedean spiral pocket r = r_in + p·θ/2π of short chords (one long G64 piece)."""
    r_out = rng.uniform(6.0, 12.0)
    p = rng.uniform(1.5, 3.0)
    cx, cy = rng.uniform(-1, 1, 2) * (R_MAX - r_out)
    z = rng.uniform(-290.0, -245.0)
    r_in = 2.0
    th_end = 2 * np.pi * (r_out - r_in) / p
    pts = [(r_in, 0.0)]
    th = 0.0
    while th < th_end:
        r = r_in + p * th / (2 * np.pi)
        th = min(th + rng.uniform(0.3, 0.8) / r, th_end)
        pts.append((r_in + p * th / (2 * np.pi), th))
    x = np.array([cx + r * math.cos(t) for r, t in pts])
    y = np.array([cy + r * math.sin(t) for r, t in pts])
    lines.append(f"G0 X{_num(x[0])} Y{_num(y[0])} Z{_num(SAFE_Z)}")
    lines.append(f"G1 Z{_num(z)} F300")
    for i in range(1, len(x)):
        lines.append(f"G1 X{_num(x[i])} Y{_num(y[i])}" + (" F1200" if i == 1 else ""))
    lines.append(f"G0 Z{_num(SAFE_Z)}")


def program(seed: int, features: int) -> str:
    """The G-code text: ``features`` features (3 in 10 a spiral pocket), from ``seed``."""
    rng = np.random.default_rng(seed)
    lines = ["%", f"( pkmbench bench_long_programs: seed {seed}, {features} features, kossel )",
             "G21 G90 G17 G64 P0.01", f"G0 X0 Y0 Z{_num(SAFE_Z)}"]
    for _ in range(features):
        (_spiral if rng.random() < 0.3 else _contour)(rng, lines)
    lines += ["M2", "%", ""]
    return "\n".join(lines)


def trapezoid_time(text: str) -> float:
    from kins import load_machine
    from planners import plan
    from planners.paths.gcode import parse_gcode, program_path
    path = program_path(parse_gcode(text, "<bench_long_programs>"))
    return plan("trapezoid", path, load_machine("kossel")).execution_time_s


def features_for(seconds: float, seed: int) -> int:
    """Feature count whose trapezoid plan lasts about ``seconds`` (from a calibration program)."""
    per = trapezoid_time(program(seed, CALIBRATION_FEATURES)) / CALIBRATION_FEATURES
    n = max(1, int(round(seconds / per)))
    # one rescale on the program itself: features differ in size, so a short calibration
    # program misses a long one's time by ~15 %
    return max(1, int(round(n * seconds / trapezoid_time(program(seed, n)))))


def cmd_write(a) -> int:
    n = a.features if a.features else features_for(a.seconds, a.seed)
    text = program(a.seed, n)
    FsPath(a.out).write_text(text)
    segs = sum(1 for ln in text.splitlines() if ln.startswith(("G1", "G2", "G3")))
    print(f"{a.out}: seed {a.seed}, {n} features, {segs} G1/G2/G3 moves, "
          f"trapezoid plan {trapezoid_time(text):.3f} s")
    return 0


def cmd_plan(a) -> int:
    from planners.verify import command_metrics
    from kins import load_machine
    from planners import PlanningError, plan
    from planners.paths import resolve_path
    m = load_machine("kossel")
    path = resolve_path(a.path)
    for name in a.planners.split(","):
        t0 = time.perf_counter()
        try:
            prof = plan(name, path, m)
        except PlanningError as e:
            print(f"{name}: PlanningError after {time.perf_counter() - t0:.1f} s: {e}")
            continue
        wall = time.perf_counter() - t0
        met = command_metrics(m, path.point(prof.s), prof.T, prof.s)
        fb = prof.info.get("fallback") or "none"
        print(json.dumps({"planner": name, "planning_s": round(wall, 2),
                          "execution_s": round(prof.execution_time_s, 4),
                          "feasible": bool(met["feasible"]), "fallback": fb}))
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    w = sub.add_parser("write", help="write a program")
    w.add_argument("--seconds", type=float, default=60.0, help="trapezoid plan time wanted")
    w.add_argument("--features", type=int, default=0, help="feature count (overrides --seconds)")
    w.add_argument("--seed", type=int, default=17)
    w.add_argument("--out", required=True)
    p = sub.add_parser("plan", help="plan a program with some planners and print the figures")
    p.add_argument("--path", required=True)
    p.add_argument("--planners", default="pso")
    a = ap.parse_args(argv)
    return cmd_write(a) if a.cmd == "write" else cmd_plan(a)


if __name__ == "__main__":
    sys.exit(main())
