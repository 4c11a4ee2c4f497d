"""Sweep two planners × two seeds on a short line (planning only, no FMUs), then write the
Markdown/HTML report of the sweep: results/examples/05/report/report.md."""
import json
import tempfile
from pathlib import Path

from harness.report.sweep_report import write_report
from harness.sweep import expand, run_sweep
from kins.resources import RESULTS

out = RESULTS / "examples" / "05"
with tempfile.TemporaryDirectory() as d:
    line = Path(d) / "line.json"
    line.write_text(json.dumps({"type": "nurbs", "units": "mm", "degree": 1, "knots": [0, 0, 1, 1],
                                "control_points": [[-50, 0, -400], [50, 0, -400]], "weights": [1, 1]}))
    suite = {"run": [{"machine": "keops", "path": str(line), "planners": ["trapezoid", "scurve"]}],
             "sweep": {"seeds": [0, 1]}}
    res = run_sweep(expand(suite), out, task_fn="harness.sweep.tasks:plan_task", workers=0, progress=False)
print(f"{res.ok} tasks ok, {res.failed} failed, {res.skipped} already done")
tables, runs = write_report(out, out / "report")
print(f"report: {tables} table(s), {runs} runs → {out / 'report' / 'report.md'}")
