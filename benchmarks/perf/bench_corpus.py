"""Planning time per planner over the toolpath corpus (issue 19): median and worst seconds.

    PYTHONPATH=. .venv/bin/python benchmarks/perf/bench_corpus.py [--planners a,b] [--paths GLOB]

``main()`` (run_all.py) times the fast planners on every corpus path (pso and optimal take
minutes per path: pass --planners for them). Wall times on a shared machine: compare runs on
the same host only.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

DEFAULT = ("trapezoid", "scurve", "scurve_joint", "toppra")


def main(planners=DEFAULT, paths=None) -> dict:
    from harness.corpus.analysis import summary
    from harness.corpus.run import load_manifest, run_corpus, select
    sel = [(e, list(planners)) for e in select(load_manifest(), paths)]
    S = summary(run_corpus(sel))
    return {k: {"paths": s["paths"], "profiles": s["profiles"], "plan_median_s": round(s["plan_median_s"], 4),
                "plan_worst_s": round(s["plan_worst_s"], 4)} for k, s in S.items()}


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--planners", default=",".join(DEFAULT))
    ap.add_argument("--paths", default=None)
    a = ap.parse_args()
    print(json.dumps(main(a.planners.split(","), a.paths), indent=1))
