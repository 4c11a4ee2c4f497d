"""The suite's own performance benchmarks: one command, one file (results/perf.json).

    .venv/bin/python benchmarks/perf/run_all.py            # = make perf
    .venv/bin/python benchmarks/perf/run_all.py --only kins sweep

Every ``benchmarks/perf/bench_<area>.py`` exposing ``main() -> dict`` is run in turn (in the
order below, then any others found); an expected one that is not written yet is skipped with
a note, and one that fails is recorded with its error while the others still run.
results/perf.json: {"host": {...}, "utc": ..., "benchmarks": {area: {...} | {"skipped": why} |
{"error": msg}}, "wall_s": {area: s}}.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import sys
import time
import traceback
from datetime import datetime, timezone
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
# area → what it measures (issue 9's list); files are bench_<area>.py
EXPECTED = {
    "kins": "kins IK/FK/Jacobian throughput, points/s",
    "harness": "harness real-time factor; naive fmpy loop / harness / C master ratios",
    "planners": "planning time per planner × path",
    "fmus": "FMU per-step cost (doStep µs) per FMU",
    "sweep": "sweep speed-up, 2 workers over 1",
    "corpus": "planning time per planner over the toolpath corpus (median, worst)",
}


def _load(file: Path):
    spec = importlib.util.spec_from_file_location(f"pkmbench_perf_{file.stem}", file)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _json_safe(x):
    if isinstance(x, dict):
        return {str(k): _json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_safe(v) for v in x]
    if hasattr(x, "item"):                        # numpy scalars
        return x.item()
    return x


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", nargs="*", metavar="AREA", help="run only these areas")
    ap.add_argument("--out", default=str(REPO / "results" / "perf.json"))
    args = ap.parse_args(argv)
    found = {f.stem.removeprefix("bench_"): f for f in sorted(HERE.glob("bench_*.py"))}
    order = list(EXPECTED) + sorted(set(found) - set(EXPECTED))
    if args.only:
        unknown = set(args.only) - set(order)
        if unknown:
            print(f"run_all: unknown area(s) {', '.join(sorted(unknown))}; known: {', '.join(order)}",
                  file=sys.stderr)
            return 2
        order = [a for a in order if a in args.only]
    results, walls = {}, {}
    for area in order:
        if area not in found:
            note = f"benchmarks/perf/bench_{area}.py not written yet ({EXPECTED[area]})"
            print(f"== {area}: skipped — {note}")
            results[area] = {"skipped": note}
            continue
        print(f"== {area}: {found[area].relative_to(REPO)}", flush=True)
        t0 = time.perf_counter()
        try:
            mod = _load(found[area])
            if not callable(getattr(mod, "main", None)):
                raise TypeError(f"{found[area].name} has no main() -> dict")
            results[area] = _json_safe(mod.main())
        except Exception as e:                       # one broken benchmark must not hide the rest
            traceback.print_exc()
            results[area] = {"error": f"{type(e).__name__}: {e}"}
        walls[area] = time.perf_counter() - t0
    doc = {"utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
           "host": {"node": platform.node(), "machine": platform.machine(), "cpus": os.cpu_count(),
                    "python": platform.python_version(), "load_average": os.getloadavg()},
           "benchmarks": results, "wall_s": walls}
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=1, sort_keys=True, allow_nan=False) + "\n")
    bad = [a for a, r in results.items() if isinstance(r, dict) and "error" in r]
    print(f"perf: {len(results) - len(bad)} ok / {len(bad)} failed → {out}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
