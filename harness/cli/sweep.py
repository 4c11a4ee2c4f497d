"""`pkmbench sweep SUITE.toml`: every task of a suite on Dask, resumable.

    pkmbench sweep benchmarks/suites/nightly.toml                  # in-process cluster, 2 workers
    pkmbench sweep S.toml --workers 4 --out results/sweeps/mine
    pkmbench sweep S.toml --scheduler tcp://10.0.0.5:8786          # an existing cluster
    pkmbench sweep S.toml --fmu Drive=mydrive.fmu                  # a user FMU (or the suite's [fmus])

Exit 0 when every task succeeded, 1 when some failed (they are listed), 2 on a user error.
"""
from __future__ import annotations

# Local imports: every command module is imported to build the parser; a command loads what it
# needs when it runs (`pkmbench --help` and the other commands stay fast)

import os

import sys

from harness.cli import CliError, add_timeout_argument
from harness.outdir import output_dir, run_lock
from kins.resources import sweep_dir


def add_arguments(p) -> None:
    p.add_argument("suite", help="suite file (benchmarks/suites/*.toml) with optional [sweep] axes")
    p.add_argument("--out", help="sweep folder (results.sqlite + runs/); default results/sweeps/<suite> of the checkout")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                   help="local worker processes (default: the number of cores; 0 = no Dask, serial)")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="use an existing dask cluster")
    p.add_argument("--threads", action="store_true",
                   help="local workers as threads of this process instead of processes")
    p.add_argument("--task", default=None, metavar="MODULE:FUNCTION",
                   help="task function (default: harness.sweep.tasks:default_task, the full co-simulation)")
    p.add_argument("--fmu", action="append", metavar="BLOCK=FILE.fmu",
                   help="a user FMU in place of ours, as for run (repeatable; wins over the suite's [fmus])")
    p.add_argument("--force", action="store_true", help="re-run tasks that are already done")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--store", default=None,
                   help="results store folder the finished tasks are appended to, each once, those of an "
                        "interrupted sweep when it is resumed (default: $PKMBENCH_STORE or results/store; "
                        "'none' = do not append)")
    add_timeout_argument(p)


def main(args) -> int:
    from harness.sweep import (DEFAULT_TASK, SuiteError, SweepError, run_sweep,
                               tasks_from_suite_file, user_fmus_info)
    if args.workers < 0:
        raise CliError(f"--workers {args.workers}: must be ≥ 0")
    try:
        tasks = tasks_from_suite_file(args.suite, args.fmu)
    except SuiteError as e:
        raise CliError(str(e)) from None
    if args.planner_timeout is not None:     # wins over the suite's planner_timeout_s
        tasks = [t | {"planner_timeout_s": args.planner_timeout} for t in tasks]
    out = output_dir(args.out or sweep_dir(args.suite), "sweep folder")
    print(f"sweep {args.suite}: {len(tasks)} tasks → {out}", file=sys.stderr, flush=True)
    with run_lock(out):        # a second sweep into the folder is refused: else tasks run twice
        try:
            res = run_sweep(tasks, out, task_fn=args.task or DEFAULT_TASK, workers=args.workers,
                            scheduler=args.scheduler, processes=not args.threads, force=args.force,
                            progress=not args.no_progress)
        except SweepError as e:
            raise CliError(str(e)) from None
        if args.store != "none":
            from harness.store import StoreError
            from harness.sweep.to_store import append_unstored
            try:
                append_unstored(out / "results.sqlite", kind="sweep", suite=str(args.suite), store=args.store,
                                code_version=res.code_version, run_info=user_fmus_info(tasks))
            except StoreError as e:
                raise CliError(f"{e} (the sweep's results are in {out}/results.sqlite)") from None
    print(f"sweep {args.suite}: {res.total} tasks — {res.ok} run, {res.skipped} already done, "
          f"{res.failed} failed — {res.wall_s:.1f} s → {out}/results.sqlite")
    for label, err in res.failures:
        print(f"  FAILED {label}: {err}")
    return 1 if res.failed else 0
