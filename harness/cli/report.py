"""`pkmbench report SWEEP_DIR`: a comparison of a sweep a person opens: report.html, one
self-contained interactive file (tables, performance profile, feed and joint ratios along the
path, the nightly trend of the results store; harness/report/html_report.py), and report.md
with PNGs (harness/report/sweep_report.py).

    pkmbench report results/sweeps/nightly            # → SWEEP_DIR/report/report.html, report.md, *.png
"""
from __future__ import annotations

# Local imports: every command module is imported to build the parser; a command loads what it
# needs when it runs (`pkmbench --help` and the other commands stay fast)

from pathlib import Path

from harness.cli import CliError
from harness.outdir import output_dir


def add_arguments(p) -> None:
    p.add_argument("sweep", help="a sweep folder (holding results.sqlite), e.g. results/sweeps/<suite>")
    p.add_argument("--out", help="report folder (default SWEEP/report)")
    p.add_argument("--reference", default="optimal",
                   help="planner whose execution time is the denominator of the ratio column")
    p.add_argument("--store", default=None,
                   help="results store whose ci runs make the nightly trend (default: $PKMBENCH_STORE or results/store)")


def main(args) -> int:
    from harness.report.sweep_report import ReportError, write_report
    from harness.store import StoreError
    from harness.sweep import TaskTable, TaskTableError
    sweep = Path(args.sweep)
    # the sweep's table checked before the report folder is made in it: no empty report/ is left
    if not (sweep / "results.sqlite").is_file():
        raise CliError(f"{sweep}: not a sweep folder (no results.sqlite); run `pkmbench sweep` first")
    try:
        with TaskTable(sweep / "results.sqlite") as st:
            if not st.db.execute("SELECT count(*) FROM results").fetchone()[0]:
                raise CliError(f"{sweep / 'results.sqlite'}: the sweep has no results")
    except TaskTableError as e:
        raise CliError(str(e)) from None
    out = output_dir(args.out or sweep / "report", "report folder")
    try:
        tables, runs = write_report(sweep, out, args.reference, args.store)
    except (ReportError, StoreError) as e:
        raise CliError(str(e)) from None
    print(f"report: {tables} tables, {runs} runs → {out}/report.html (open it in a browser), {out}/report.md")
    return 0
