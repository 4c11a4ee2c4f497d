"""`pkmbench run`: co-simulate planners on a machine × toolpath (or a suite) and compare."""
from __future__ import annotations

# Local imports: every command module is imported to build the parser; a command loads what it
# needs when it runs (`pkmbench --help` and the other commands stay fast)

import sys
from pathlib import Path

from harness.cli import CliError, add_gcode_arguments, add_timeout_argument, gcode_setup, parse_start
from harness.outdir import output_dir
from kins.resources import run_dir, suite_run_dir

JITTER_PRESETS = ("none", "linuxcnc_rt_preempt", "tuned_rt")


def add_arguments(p):
    p.add_argument("suite", nargs="?", help="a suite file (benchmarks/suites/*.toml) instead of --machine/--path")
    p.add_argument("--machine", help="machine id (benchmarks/machines/) or .toml file")
    p.add_argument("--path", help="toolpath id (benchmarks/paths/) or .json/.ngc file")
    p.add_argument("--planners", default="trapezoid,scurve,scurve_joint,pso,toppra,optimal",
                   help="comma-separated planners (default: %(default)s)")
    p.add_argument("--out", default=None, help="output folder (default: results/<machine>_<path> or results/<suite>)")
    p.add_argument("--seed", type=int, default=0, help="seed of the EtherCAT jitter draws and of a stochastic planner (pso) without a seed option, 0 <= SEED < 2**64 (default: 0)")
    p.add_argument("--jitter", default=None, help=f"EtherCAT preset: {', '.join(JITTER_PRESETS)} (default: the machine file's)")
    p.add_argument("--ideal", action="store_true", help="ideal chain: no jitter, no delay, ideal drives")
    p.add_argument("--engine", choices=("native", "python"), default="native", help="co-simulation master")
    p.add_argument("--jacobi", action="store_true", help="Jacobi instead of Gauss–Seidel")
    p.add_argument("--no-recordings", action="store_true", help="skip run.mcap and run.rrd")
    p.add_argument("--fmu", action="append", metavar="BLOCK=FILE.fmu",
                   help="a user FMU in place of ours: BLOCK one of Interpolator, Kinematics, EtherCAT, Drive "
                        "(repeatable; a suite's [fmus] table does the same; interface: harness/cosim/blocks.py)")
    add_gcode_arguments(p)
    add_timeout_argument(p)
    p.add_argument("--max-feed", action="store_true",
                   help="run G-code at F_max, ignoring its F words (planner-only comparisons; "
                        "summary.json's 'feed' says so); a suite's [[run]] takes max_feed = true")


def _progress(k, n, name):
    bar = "#" * (20 * k // max(n, 1))
    sys.stderr.write(f"\r  [{bar:<20s}] {k}/{n} {name:<14s}")
    sys.stderr.flush()


def cases_of(args) -> tuple[list[tuple], Path]:
    """(machine, path, planners, planner options, max_feed, G-code setup) of each run, and the
    output folder."""
    if args.suite:
        from harness.sweep.suite import SuiteError, load_suite, suite_runs
        from harness.sweep.suite import gcode_setup as run_setup
        try:
            suite = load_suite(args.suite)
            runs = suite_runs(suite, args.suite)
        except SuiteError as e:
            raise CliError(str(e)) from None
        if gcode_setup(args):
            raise CliError("--tool-table, --var-file and --offset are for --machine/--path; a suite's "
                           "[[run]] takes tool_table, var_file and offset")
        try:
            cases = [(m, p, list(planners), suite.get("planner_options", {}), max_feed or args.max_feed,
                      run_setup(gcode))
                     for machines, paths, planners, max_feed, gcode in runs for m in machines for p in paths]
        except SuiteError as e:
            raise CliError(str(e)) from None
        return cases, Path(args.out or suite_run_dir(args.suite))
    if not (args.machine and args.path):
        raise CliError("give a suite file, or --machine and --path")
    planners = [p.strip() for p in args.planners.split(",") if p.strip()]
    out = Path(args.out) if args.out else run_dir(args.machine, args.path)
    return [(args.machine, args.path, planners, {}, args.max_feed, gcode_setup(args))], out


def table(summary: dict) -> str:
    cols = ("exec s", "joint v", "joint a", "joint j", "cart a", "feasible", "follow µm", "contour µm")
    lines = [f"{summary['machine']} / {summary['path']}  (T = {summary['servo_period_s'] * 1e6:g} µs, "
             f"feed: {summary.get('feed', '?')})",
             f"  {'planner':14s}" + "".join(f"{c:>11s}" for c in cols)]
    for name, m in summary["planners"].items():
        if "error" in m:
            lines.append(f"  {name:14s}  {m['error']}")
            continue
        j, c = m["joint_peak_ratio"], m["cartesian_peak_ratio"]
        f = lambda v, fmt="{:.3f}": ("—" if v is None else fmt.format(v))  # noqa: E731
        vals = [f(m["execution_time_s"], "{:.4f}"), f(j["velocity"]), f(j["acceleration"]), f(j["jerk"]),
                f(c["acceleration"]), "yes" if m["feasible"] else "NO",
                f(m["max_following_error_um"], "{:.1f}"), f(m["max_contour_error_um"], "{:.1f}")]
        lines.append(f"  {name:14s}" + "".join(f"{v:>11s}" for v in vals))
    return "\n".join(lines)


def _written(odir: Path, summary: dict) -> str:
    """The per-planner files this run wrote (a failed planner or --no-recordings writes fewer)."""
    from harness.cosim.run import planner_folder     # the co-simulation stack loads only when a run runs
    names = [f for f in ("command.csv", "run.mcap", "run.rrd")
             if any((odir / planner_folder(p) / f).exists() for p in summary["planners"])]
    hints = [h for f, h in (("run.rrd", "open the .rrd with 'rerun'"), ("run.mcap", "the .mcap with Foxglove"))
             if f in names]
    return (f"; per planner: {', '.join(names)}" if names else "") + (f" ({', '.join(hints)})" if hints else "")


def main(args) -> int:
    from harness.cosim.run import RunError, run_case
    from harness.seed import SeedError, check_seed

    if args.jitter and args.jitter not in JITTER_PRESETS:
        raise CliError(f"unknown jitter preset '{args.jitter}'; valid: {', '.join(JITTER_PRESETS)}")
    try:
        check_seed(args.seed, "--seed")
    except SeedError as e:
        raise CliError(str(e)) from None
    from harness.cosim.blocks import command_fmus
    from harness.cosim.system import SystemError_
    from harness.sweep.suite import SuiteError, load_suite
    try:
        suite = load_suite(args.suite) if args.suite else None
        fmus = command_fmus(args.fmu, suite, args.suite)
    except (SystemError_, SuiteError) as e:
        raise CliError(str(e)) from None
    start = parse_start(args.start)
    cases, out = cases_of(args)
    # --planner-timeout wins over the suite's planner_timeout_s
    timeout = args.planner_timeout if args.planner_timeout is not None else (suite or {}).get("planner_timeout_s")
    output_dir(out)
    failed = 0
    for machine, path, planners, opts, max_feed, setup in cases:
        odir = out if len(cases) == 1 else out / f"{Path(machine).stem}_{Path(path).stem}"
        print(f"pkmbench run: {machine} / {path}: {', '.join(planners)} → {odir}", file=sys.stderr)
        try:
            summary = run_case(machine, path, planners, odir, seed=args.seed, jitter=args.jitter, ideal=args.ideal,
                               engine=args.engine, jacobi=args.jacobi, planner_options=opts,
                               recordings=not args.no_recordings, progress=_progress, max_feed=max_feed,
                               fmus=fmus or None, start=start, reader=args.reader, planner_timeout_s=timeout,
                               setup=setup)
        except RunError as e:
            raise CliError(str(e)) from None
        sys.stderr.write("\r" + " " * 60 + "\r")
        print(table(summary))
        failed += sum("error" in m for m in summary["planners"].values())
        print(f"  results: {odir}/summary.json{_written(odir, summary)}\n")
    return 1 if failed else 0
