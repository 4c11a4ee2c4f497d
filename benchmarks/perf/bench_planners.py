"""Benchmark of the issue-5B planners: scurve, scurve_joint, toppra, optimal, pso.

Prints, for each standard path on its machine, every planner's execution time, planning
time and peak ratios (joints and Cartesian axes, measured by planners.verify on the IK'd
trajectory at the servo period), plus the anchors of the issue:
  scurve planning time on bird ≤ 0.3 s (TII 2022: 0.41–0.61 s, C++ on an i5-6600);
  pso time to reach 1.03·T_optimal ≤ 10 s (2016 PSO: 90 s); optimal ≤ 60 s.
Not a test: numbers only.  Usage:
  .venv/bin/python benchmarks/perf/bench_planners.py [path[:machine] ...] [--pso-iterations N]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path as FsPath

sys.path.insert(0, str(FsPath(__file__).resolve().parents[2]))

from planners.verify import command_metrics  # noqa: E402
from kins import load_machine  # noqa: E402
from planners import PlanningError, plan  # noqa: E402
from planners.paths import resolve_path  # noqa: E402

CASES = [("bird", "keops"), ("bird_flat", "keops"), ("flower", "keops"), ("helix", "keops"),
         ("bird_kossel", "kossel"), ("test_part.ngc", "kossel")]
ORDER = ["scurve", "scurve_joint", "toppra", "optimal", "pso"]


def fmt(r: dict) -> str:
    return "/".join(f"{r[k]:.3f}" for k in ("velocity", "acceleration", "jerk"))


def run_case(path_name: str, machine_name: str, pso_iterations: int) -> dict:
    m = load_machine(machine_name)
    try:
        path = resolve_path(path_name)
    except Exception as e:          # a path not (yet) in benchmarks/paths
        print(f"\n## {path_name} on {machine_name}: skipped ({e})")
        return {}
    print(f"\n## {path_name} on {machine_name}  (length {path.length:.1f} mm, "
          f"T = {m.servo_period_s * 1e6:.0f} µs, corners {len(path.corners())})")
    print(f"{'planner':13s} {'exec s':>9s} {'plan s':>8s}  {'joint v/a/j':>19s}  "
          f"{'cart v/a/j':>19s} {'feed':>6s} feasible")
    out = {}
    for name in ORDER:
        opts = {}
        if name == "pso":
            opts = {} if pso_iterations is None else {"iterations": pso_iterations}
            if "optimal" in out:
                opts["target_time_s"] = 1.03 * out["optimal"]["exec"]
        t0 = time.perf_counter()
        try:
            p = plan(name, path, m, **opts)
        except PlanningError as e:
            print(f"{name:13s} failed: {e}")
            continue
        wall = time.perf_counter() - t0
        r = command_metrics(m, path.point(p.s), p.T, p.s)
        out[name] = {"exec": p.execution_time_s, "plan": wall, "info": p.info}
        print(f"{name:13s} {p.execution_time_s:9.4f} {wall:8.3f}  {fmt(r['joint_peak_ratio']):>19s}  "
              f"{fmt(r['cartesian_peak_ratio']):>19s} {r['cartesian_peak_ratio']['feed']:6.3f} "
              f"{r['feasible']}")
    if {"toppra", "optimal", "pso", "scurve_joint"} <= out.keys():
        t = {k: v["exec"] for k, v in out.items()}
        info = out["pso"]["info"]
        ttt = info.get("time_to_target_s")
        print(f"T_toppra {t['toppra']:.4f} ≤ T_optimal {t['optimal']:.4f} ≤ T_pso {t['pso']:.4f}: "
              f"{t['toppra'] <= t['optimal'] <= t['pso']};  T_pso/T_optimal = {t['pso'] / t['optimal']:.4f} "
              f"(target ≤ 1.03);  T_pso < T_scurve_joint ({t['scurve_joint']:.4f}): {t['pso'] < t['scurve_joint']}")
        print(f"pso: {info['iterations_run']} iterations, stopped by {info['stopped_by']}; swarm alone "
              f"{info['swarm_time_s']:.4f} s, polished {t['pso']:.4f} s; time to reach "
              f"1.03·T_optimal: {'%.2f s' % ttt if ttt is not None else 'not reached'}")
        print(f"optimal: planning {out['optimal']['plan']:.2f} s (anchor ≤ 60 s), IPOPT {out['optimal']['info']['ipopt']}")
    if "scurve" in out:
        print(f"scurve planning time {out['scurve']['plan']:.3f} s (anchor ≤ 0.3 s; TII 2022 C++ 0.41–0.61 s)")
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cases", nargs="*", help="path[:machine] (default: the standard set)")
    ap.add_argument("--pso-iterations", type=int, default=None, help="default: the planner's")
    a = ap.parse_args(argv)
    cases = [tuple(c.split(":")) if ":" in c else (c, "keops") for c in a.cases] or CASES
    for path_name, machine_name in cases:
        run_case(path_name, machine_name, a.pso_iterations)


if __name__ == "__main__":
    main()
