"""Measure how far a suite's numbers move when numpy runs other SIMD code paths.

Two x86-64 machines of one kind differ in their SIMD (AVX2, AVX-512): numpy dispatches its
transcendental ufuncs (exp, log, power, arctan2, cbrt, arccos, …) to per-ISA kernels whose
last bits differ. ``NPY_DISABLE_CPU_FEATURES`` makes one machine take another's code path, so
the spread between machines can be measured on one.

    python benchmarks/repro/cross_cpu.py [SUITE] [--out DIR] [--workers N]

runs the suite (planning + co-simulation, as `pkmbench sweep`) once per CPU-feature setting
and writes DIR/spread.json and DIR/spread.md: per metric the largest difference from the
native run, and per metric rule of the CI contract (harness.ci.baseline) whether it held, with
the margin. docs/REPRODUCIBILITY.md quotes its output.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

from harness.sweep import TaskTable, flatten, task_label  # noqa: E402
from harness.ci import baseline as ci  # noqa: E402

# numpy ≥ 2.4 dispatch targets on x86-64 (numpy._core._multiarray_umath.__cpu_dispatch__):
# disabling a level falls back to the one below it.
SETTINGS = {
    "native": "",
    "no-avx512": "X86_V4 AVX512_ICL AVX512_SPR",
    "x86-64-v2": "X86_V3 X86_V4 AVX512_ICL AVX512_SPR",
}


def run_suite(suite: Path, out: Path, setting: str, workers: int, reuse: bool) -> Path:
    env = dict(os.environ, NPY_DISABLE_CPU_FEATURES=SETTINGS[setting])
    folder = out / setting
    if reuse and (folder / "results.sqlite").exists():
        return folder / "results.sqlite"
    cmd = [sys.executable, "-m", "harness.cli", "sweep", str(suite), "--out", str(folder),
           "--workers", str(workers), "--force", "--no-progress"]
    print(f"[{setting}] {' '.join(cmd[2:])}", flush=True)
    subprocess.run(cmd, env=env, cwd=REPO, check=False)
    return folder / "results.sqlite"


def entries(store: Path) -> dict:
    with TaskTable(store) as s:
        return {task_label(r["task"]): flatten(r["metrics"]) for r in s.to_rows() if r["status"] == "ok"}


def spread(reference: dict, other: dict) -> list[dict]:
    rows = []
    for label in sorted(set(reference) & set(other)):
        a, b = reference[label], other[label]
        for metric in sorted(set(a) & set(b)):
            x, y = a[metric], b[metric]
            if metric in ("planning_time_s",) or not isinstance(x, (int, float)):
                continue
            rule = ci.rule_for(metric, ci.DEFAULT_TOLERANCES, label)
            ok, _ = ci.compare_value(metric, x, y, ci.resolve_rule(rule, label))
            rows.append({"entry": label, "metric": metric, "native": x, "other": y,
                         "abs": abs(float(y) - float(x)), "rule": ci.describe(rule), "within": ok})
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("suite", nargs="?", default=str(REPO / "benchmarks/suites/nightly.toml"))
    ap.add_argument("--out", default=str(REPO / "results/cross_cpu"))
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--reuse", action="store_true", help="compare the runs already in --out (no new runs)")
    args = ap.parse_args(argv)
    out = Path(args.out)
    stores = {s: run_suite(Path(args.suite), out, s, args.workers, args.reuse) for s in SETTINGS}
    ref = entries(stores["native"])
    report = {}
    md = ["| setting | metric | entry | native | other | |Δ| | contract | holds |", "|---|---|---|---|---|---|---|---|"]
    for s in list(SETTINGS)[1:]:
        rows = spread(ref, entries(stores[s]))
        report[s] = rows
        worst: dict[str, dict] = {}
        for r in rows:
            if r["abs"] > 0 and (r["metric"] not in worst or r["abs"] > worst[r["metric"]]["abs"]):
                worst[r["metric"]] = r
        for m, r in sorted(worst.items()):
            md.append(f"| {s} | `{m}` | {r['entry']} | {r['native']:.10g} | {r['other']:.10g} | "
                      f"{r['abs']:.3g} | {r['rule']} | {'yes' if r['within'] else '**no**'} |")
        n_same = sum(r["abs"] == 0 for r in rows)
        md.append(f"| {s} | ({n_same} of {len(rows)} metrics identical to the last bit) | | | | | | |")
    (out / "spread.json").write_text(json.dumps(report, indent=1, sort_keys=True) + "\n")
    (out / "spread.md").write_text("\n".join(md) + "\n")
    print("\n".join(md))
    bad = [r for rows in report.values() for r in rows if not r["within"]]
    print(f"{len(bad)} metric(s) outside the contract")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
