"""`pkmbench plan`: plan feed profiles only (no co-simulation), write them, print their metrics."""
from __future__ import annotations

# Local imports: every command module is imported to build the parser; a command loads what it
# needs when it runs (`pkmbench --help` and the other commands stay fast)

from harness.cli import CliError, add_gcode_arguments, add_timeout_argument, gcode_setup, parse_start
from harness.outdir import output_dir


def add_arguments(p):
    p.add_argument("--list", action="store_true",
                   help="list every planner (built-in, installed plug-in) with its source and guarantees, then exit")
    p.add_argument("--machine", help="machine id or .toml file")
    p.add_argument("--path", help="toolpath id or .json/.ngc file")
    p.add_argument("--planners", default="scurve",
                   help="comma-separated planners: names of --list or module:function (default: %(default)s)")
    add_gcode_arguments(p)
    add_timeout_argument(p)
    p.add_argument("--max-feed", action="store_true", help="run G-code at F_max, ignoring its F words")
    p.add_argument("--out", default=None, help="folder for NAME/profile.csv, NAME/path.json, NAME/metrics.json (default: print only)")


def _setup_option(args) -> dict:
    setup = gcode_setup(args)
    return {"setup": setup} if setup else {}


def list_planners() -> int:
    from planners import registry
    for name in registry.names():
        d = registry.describe(name)
        g = d["guarantees"]
        keeps = "; ".join(f"{k}: {', '.join(v)}" for k, v in g.items()) if g else "—"
        line = f"{name:16s} {d['source']}" + (f" {d['version']}" if d["version"] and d["version"] not in d["source"] else "")
        stoch = f"\n{'':16s} stochastic: its result depends on its seed (reports run it over seeds)" \
            if d.get("stochastic") else ""
        print(f"{line}\n{'':16s} keeps: {keeps}{stoch}" + (f"\n{'':16s} BROKEN: {d['error']}" if "error" in d else ""))
    return 0


def main(args) -> int:
    import planners
    if args.list:
        return list_planners()
    if not (args.machine and args.path):
        raise CliError("give --machine and --path (or --list)")
    from planners.verify import command_metrics
    from kins import load_machine
    from harness.cosim.record import write_json
    from kins.machine import MachineFileError
    from planners.paths import PathError, resolve_path

    try:
        m = load_machine(args.machine)
        path = resolve_path(args.path, home=m.home, start=parse_start(args.start), reader=args.reader,
                            **_setup_option(args))
    except (MachineFileError, PathError) as e:
        raise CliError(str(e)) from None
    from harness.cosim.run import feed_summary, planner_folder
    from planners.feed import use_max_feed
    use_max_feed(path, args.max_feed)
    names = [n.strip() for n in args.planners.split(",") if n.strip()]
    bad = [n for n in names if not planners.registry.known(n)]
    if bad:
        raise CliError(planners.registry.unknown_message(bad))
    folders = {planner_folder(n) for n in names}
    if len(folders) < len(set(names)):
        raise CliError(f"planners {', '.join(names)}: two would share an output folder; plan them apart")
    out = output_dir(args.out) if args.out else None
    failed = 0
    print(f"feed: {feed_summary(path)}")
    print(f"{m.name} / {args.path}: {'planner':14s} {'exec s':>9s} {'plan s':>8s} {'joint v/a/j':>22s} {'feasible':>9s}")
    for name in names:
        try:
            prof = planners.plan_in_time(args.planner_timeout, name, path, m)
            met = command_metrics(m, prof.points(), m.servo_period_s, prof.s)
        except Exception as e:    # a planner's failure, whatever it raised, is its row
            print(f"  {name:14s} failed: {e}")
            failed += 1
            continue
        j = met["joint_peak_ratio"]
        print(f"  {name:14s} {prof.execution_time_s:9.4f} {prof.planning_time_s:8.3f} "
              f"{j['velocity']:6.3f} {j['acceleration']:6.3f} {j['jerk']:7.3f} {'yes' if met['feasible'] else 'NO':>9s}")
        if out:
            d = out / planner_folder(name)
            d.mkdir(parents=True, exist_ok=True)
            prof.save_csv(d / "profile.csv")
            prof.path.to_file(d / "path.json")
            write_json(d / "metrics.json", met)
    return 1 if failed else 0
