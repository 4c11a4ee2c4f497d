"""`pkmbench report SWEEP_DIR`: Markdown and HTML comparison of a sweep, with plots
(harness/report/sweep_report.py).

    pkmbench report results/sweeps/nightly            # → SWEEP_DIR/report/report.md, report.html, *.png
"""
from __future__ import annotations

from pathlib import Path

from harness.cli import CliError
from harness.outdir import output_dir


def add_arguments(p) -> None:
    p.add_argument("sweep", help="a sweep folder (holding results.sqlite), e.g. results/sweeps/<suite>")
    p.add_argument("--out", help="report folder (default SWEEP/report)")
    p.add_argument("--reference", default="optimal",
                   help="planner whose execution time is the denominator of the ratio column")


def main(args) -> int:
    from harness.report.sweep_report import ReportError, write_report
    sweep = Path(args.sweep)
    if not (sweep / "results.sqlite").exists():      # before the report folder is made in it
        raise CliError(f"{sweep}: not a sweep folder (no results.sqlite); run `pkmbench sweep` first")
    out = output_dir(args.out or sweep / "report", "report folder")
    try:
        tables, runs = write_report(sweep, out, args.reference)
    except ReportError as e:
        raise CliError(str(e)) from None
    print(f"report: {tables} tables, {runs} runs → {out}/report.md, {out}/report.html")
    return 0
