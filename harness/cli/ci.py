"""`pkmbench ci`: run the nightly suite, compare every metric with the committed baseline.

    pkmbench ci --suite benchmarks/suites/nightly.toml --baseline results/baseline.json
    pkmbench ci ... --update-baseline        # accept the current numbers as the new baseline

Writes OUT/junit.xml and OUT/summary.md (OUT = results/ci by default), appends the run's rows
(kind 'ci', with the metrics out of tolerance in ``regressions``) to the results store
(harness.store; `pkmbench history` and `pkmbench query` read it). Exit 0 on pass, 1 on a
regression (each named with its run, metric, values and tolerance), 2 on a user error.
"""
from __future__ import annotations

# Local imports: every command module is imported to build the parser; a command loads what it
# needs when it runs (`pkmbench --help` and the other commands stay fast)

import os
import shutil
import sys
import time
from pathlib import Path

from harness.cli import CliError, add_timeout_argument
from harness.outdir import output_dir, output_file
from kins.resources import BASELINE, CI_DIR, SUITE_DIR, repo_relative


def add_arguments(p) -> None:
    p.add_argument("--suite", default=None, help="suite file (default: benchmarks/suites/nightly.toml of the checkout)")
    p.add_argument("--baseline", default=str(BASELINE), help="baseline file (default: %(default)s)")
    p.add_argument("--update-baseline", action="store_true",
                   help="write the current numbers as the baseline instead of comparing")
    p.add_argument("--no-timing", action="store_true",
                   help="compare every metric but planning time (a check that the numbers reproduce, "
                        "on a machine that is not the nightly runner)")
    p.add_argument("--out", default=str(CI_DIR), help="folder for junit.xml, summary.md and the run (default: %(default)s)")
    p.add_argument("--junit", help="JUnit XML file (default OUT/junit.xml)")
    p.add_argument("--markdown", help="Markdown summary file (default OUT/summary.md)")
    p.add_argument("--store", default=None,
                   help="results store folder the run is appended to (default: $PKMBENCH_STORE or results/store; "
                        "'none' = do not append, as for corpus and sweep)")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                   help="local worker processes (0 = serial, no Dask)")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="run on an existing dask cluster")
    p.add_argument("--task", default=None, metavar="MODULE:FUNCTION", help="task function (see sweep)")
    p.add_argument("--fmu", action="append", metavar="BLOCK=FILE.fmu",
                   help="a user FMU in place of ours, as for run (repeatable; wins over the suite's [fmus])")
    add_timeout_argument(p)


def main(args) -> int:
    from harness.ci import baseline as ci
    from harness.store import ResultStore, StoreError

    suite_file, task_fn, baseline_file = _inputs(args)
    try:
        baseline = None if args.update_baseline else ci.load_baseline(baseline_file)
    except ci.BaselineError as e:
        raise CliError(str(e)) from None
    tasks, tolerances = _load_tasks(args, suite_file, task_fn)
    junit, mdfile, out = _check_outputs(args, baseline_file)
    run_dir, reference_s, entries, errors, wall_s = _run_suite(args, tasks, task_fn, out)
    from harness.sweep import code_version
    version = code_version()
    if args.update_baseline:
        checks, passed = _update_baseline(args, baseline_file, task_fn, version, reference_s, entries,
                                          errors, tolerances, wall_s)
    else:
        if baseline.get("task_fn") and baseline["task_fn"] != task_fn:
            print(f"ci: note: the baseline was made with task {baseline['task_fn']}, this run uses {task_fn}")
        checks = ci.compare(baseline, entries, errors, tolerances)
        passed = all(c.ok for c in checks)

    md = ci.markdown_summary(checks, reference_s=reference_s, baseline_file=str(baseline_file),
                             suite_file=args.suite, wall_s=wall_s, tolerances=tolerances)
    for f, text in ((junit, ci.junit_xml(checks, wall_s)), (mdfile, md)):
        f.write_text(text)
    rows = _store_rows(run_dir, entries, checks)
    info = {"mode": "update-baseline" if args.update_baseline else "check", "passed": passed,
            "reference_s": reference_s, "wall_s": wall_s, "baseline": str(baseline_file),
            "checks": len(checks), "task_fn": task_fn}
    from harness.sweep import user_fmus_info
    info |= user_fmus_info(tasks) or {}         # only with user FMUs: the other runs' info as it was
    try:
        if args.store != "none":
            with ResultStore(args.store) as st:
                run_id = st.append(rows, kind="ci", suite=args.suite, code_version=version, run_info=info)
                store_dir = st.folder
    except StoreError as e:
        raise CliError(f"{e} (junit {junit} and summary {mdfile} are written)") from None
    if not args.update_baseline:
        # the head and the regressions table of the summary: the metric is named on stdout
        print(md.split("## Tolerances")[0].rstrip())
    stored = f"results store {store_dir} run {run_id}" if args.store != "none" else "no results store (--store none)"
    print(f"ci: JUnit {junit}, summary {mdfile}, {stored}")
    return 0 if passed else 1


def _inputs(args) -> tuple[Path, str, Path]:
    """The suite file, the task function (checked to resolve) and the baseline file."""
    from harness.sweep import DEFAULT_TASK
    if args.suite is None:           # recorded as the checkout-relative name, read from the checkout
        args.suite = repo_relative(SUITE_DIR / "nightly.toml")
        suite_file = SUITE_DIR / "nightly.toml"
    else:
        suite_file = Path(args.suite)
    task_fn = args.task or DEFAULT_TASK
    return suite_file, task_fn, Path(args.baseline)


def _load_tasks(args, suite_file: Path, task_fn: str):
    """The suite's tasks and its tolerances (without planning time under --no-timing)."""
    from harness.ci import baseline as ci
    from harness.sweep import SuiteError, SweepError, expand, load_suite, resolve_task_fn
    from harness.sweep.suite import with_user_fmus
    try:
        resolve_task_fn(task_fn)
    except SweepError as e:
        raise CliError(str(e)) from None
    try:
        suite = load_suite(suite_file)
        tasks = with_user_fmus(expand(suite, src=args.suite, base=Path.cwd()), suite, suite_file, args.fmu)
        if args.planner_timeout is not None:     # wins over the suite's planner_timeout_s
            tasks = [t | {"planner_timeout_s": args.planner_timeout} for t in tasks]
        tolerances = ci.tolerances_from_suite(suite)
        if args.no_timing:
            tolerances = ci.without_timing(tolerances)
    except SuiteError as e:
        raise CliError(str(e)) from None
    return tasks, tolerances


def _check_outputs(args, baseline_file: Path):
    """Every file this command writes, checked before the suite runs for minutes: the JUnit
    and summary files, the output folder, the results store, the baseline under --update."""
    from harness.store import ResultStore, StoreError
    out = output_dir(args.out)
    junit = output_file(args.junit or out / "junit.xml", "JUnit file")
    mdfile = output_file(args.markdown or out / "summary.md", "summary file")
    try:
        if args.store != "none":
            ResultStore(args.store).close()      # a store that cannot be read fails now, not after the suite
    except StoreError as e:
        raise CliError(str(e)) from None
    if args.update_baseline:
        output_file(baseline_file, "baseline file")
    return junit, mdfile, out


def _run_suite(args, tasks, task_fn: str, out: Path):
    """Run every task afresh (timed against the reference workload, best of before and
    after) in OUT/run; the run folder, the reference time, the metrics, the errors, the wall
    time."""
    from harness.ci import baseline as ci
    from harness.sweep import SweepError, TaskTable, run_sweep
    t0 = time.perf_counter()
    reference_s = ci.reference_workload_s()
    run_dir = out / "run"
    shutil.rmtree(run_dir, ignore_errors=True)            # CI measures afresh: nothing skipped
    try:
        repeat = ci.CI_REPEAT_NO_TIMING if args.no_timing and not args.update_baseline else ci.CI_REPEAT
        tasks = [t | {"ci_inner_task": task_fn, "ci_repeat": repeat} for t in tasks]
        run_sweep(tasks, run_dir, task_fn="harness.ci.baseline:reference_timed_task", workers=args.workers,
                  scheduler=args.scheduler, force=True, progress=sys.stderr.isatty())
    except SweepError as e:
        raise CliError(str(e)) from None
    reference_s = min(reference_s, ci.reference_workload_s())   # best of before and after
    with TaskTable(run_dir / "results.sqlite") as store:
        entries, errors = ci.entries_from_rows(store.to_rows(), reference_s)
    wall_s = time.perf_counter() - t0
    return run_dir, reference_s, entries, errors, wall_s


def _update_baseline(args, baseline_file: Path, task_fn: str, version: str, reference_s: float, entries,
                     errors, tolerances, wall_s: float):
    """--update-baseline: write the baseline if every task ran (else name the failures and
    keep the old one); the checks of the run against itself, and whether it passed."""
    from harness.ci import baseline as ci
    if errors:
        for label, err in sorted(errors.items()):
            print(f"FAILED {label}: {err}")
        print(f"ci: {len(errors)} task(s) failed; baseline NOT updated")
        return ci.compare({"entries": entries}, entries, errors, tolerances), False
    doc = ci.write_baseline(baseline_file, suite=args.suite, task_fn=task_fn, code_version=version,
                            reference_s=reference_s, entries=entries)
    checks = ci.compare(doc, entries, errors, tolerances)
    print(f"ci: baseline {baseline_file} written: {len(entries)} runs, "
          f"{sum(len(v) for v in entries.values())} metrics, {wall_s:.1f} s")
    return checks, True


def _store_rows(run_dir: Path, entries, checks) -> list:
    """The results-store rows of the run, each with its metrics out of tolerance."""
    from harness.store import make_row
    from harness.sweep import TaskTable, task_label
    regressions: dict[str, list[str]] = {}
    for c in checks:
        if not c.ok:
            regressions.setdefault(c.entry, []).append(c.metric)
    rows = []
    with TaskTable(run_dir / "results.sqlite") as store:
        for r in store.to_rows():
            label = task_label(r["task"])
            rows.append(make_row(entry=label, machine=r["machine"], path=r["path"], planner=r["planner"],
                                 seed=r["seed"], preset=r["preset"], variation=r["variation"],
                                 status=r["status"], error=r["error"], metrics=entries.get(label),
                                 regressions=regressions.get(label, ()),
                                 run_dir=str(run_dir / r["run_dir"]) if r["run_dir"] else None))
    return rows
