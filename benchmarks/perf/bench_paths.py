"""Toolpath and trapezoid benchmarks: NURBS arc-length evaluation, G-code reading, planning time.

    .venv/bin/python benchmarks/perf/bench_paths.py

Prints numbers (not a test): points/s of NurbsPath.point / derivs on bird, the time to read
and blend test_part.ngc, the time to cut bird into G1 lines and blend them, and the
trapezoid planner's planning and execution times on the standard paths.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402

from kins import load_machine  # noqa: E402
from planners import plan  # noqa: E402
from planners.paths.blend import blend_corners  # noqa: E402
from planners.paths.lines import cut_into_lines  # noqa: E402
from planners.paths import resolve_path  # noqa: E402


def best_of(fn, n=3):
    best = float("inf")
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> dict:
    out = {}
    bird = resolve_path("bird")
    s = np.linspace(0.0, bird.length, 100_001)
    t = best_of(lambda: bird.point(s))
    out["nurbs_point_per_s"] = len(s) / t
    t = best_of(lambda: bird.derivs(s))
    out["nurbs_derivs_per_s"] = len(s) / t
    out["nurbs_load_s"] = best_of(lambda: resolve_path("bird"))
    out["gcode_read_blend_test_part_s"] = best_of(lambda: resolve_path("test_part.ngc"))
    eps = load_machine("keops").limits.chord_error_mm
    poly = [None]

    def cut():
        poly[0] = cut_into_lines(bird, eps)[0]
    out["bird_cut_into_g1_s"] = best_of(cut)
    out["bird_g1_lines"] = len(poly[0].segments)
    out["bird_blend_s"] = best_of(lambda: blend_corners(poly[0].segments, [eps] * (len(poly[0].segments) - 1)))
    for name, machine in (("bird", "keops"), ("flower", "keops"), ("helix", "keops"),
                          ("test_part.ngc", "kossel")):
        m = load_machine(machine)
        path = resolve_path(name)
        runs = [plan("trapezoid", path, m) for _ in range(3)]
        key = name.replace(".ngc", "")
        out[f"trapezoid_{key}_planning_s"] = min(r.planning_time_s for r in runs)
        out[f"trapezoid_{key}_execution_s"] = runs[0].execution_time_s
    return out


if __name__ == "__main__":
    for k, v in main().items():
        print(f"{k:40s} {v:.6g}")
