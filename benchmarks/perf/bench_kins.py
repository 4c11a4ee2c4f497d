"""IK / FK throughput of kins for 10⁶ points per machine, on one core.

Run: .venv/bin/python benchmarks/perf/bench_kins.py   (target: ≥ 5·10⁶ IK points/s)
Prints a table and returns the numbers (used by benchmarks/perf/run_all.py).
"""
from __future__ import annotations

import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")      # one core, as the target says
import numpy as np  # noqa: E402

from kins import available_machines, load_machine  # noqa: E402

N = 1_000_000


def _best_of(fn, repeat=5):
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> dict:
    rng = np.random.default_rng(0)
    out = {}
    print(f"{'machine':16s} {'IK Mpts/s':>10s} {'FK Mpts/s':>10s} {'J Mpts/s':>10s}")
    for name in available_machines():
        m = load_machine(name)
        lo, hi = m.workspace_min, m.workspace_max
        mid, half = (lo + hi) / 2, (hi - lo) / 4            # inner half of the box: all reachable
        P = mid + half * rng.uniform(-1, 1, (N, 3))
        Q = m.ik(P)
        t_ik = _best_of(lambda: m.ik(P))
        t_fk = _best_of(lambda: m.fk(Q))
        t_j = _best_of(lambda: m.jacobian(P), 3)
        out[name] = {"ik_points_per_s": N / t_ik, "fk_points_per_s": N / t_fk, "jacobian_points_per_s": N / t_j}
        print(f"{name:16s} {N / t_ik / 1e6:10.2f} {N / t_fk / 1e6:10.2f} {N / t_j / 1e6:10.2f}")
    return out


if __name__ == "__main__":
    main()
