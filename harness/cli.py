"""The `pkmbench` command line. Each command is a module ``harness.cmd_<name>`` with
``add_arguments(parser)`` and ``main(args) -> int``; a command whose module is not there yet
says so instead of failing obscurely.
"""
from __future__ import annotations

import argparse
import importlib
import sys

# name → (module, one-line help, issue that builds it)
COMMANDS = {
    "run": ("harness.cmd_run", "co-simulate a suite or machine × path × planners and compare", 6),
    "plan": ("harness.cmd_plan", "plan a feed profile only (no co-simulation)", 6),
    "check": ("harness.cmd_check", "offline G-code checker for a PKM (workspace, singularities, joint limits)", 7),
    "sweep": ("harness.cmd_sweep", "run a suite on Dask (in-process, or --scheduler ADDRESS)", 9),
    "report": ("harness.cmd_report", "Markdown/HTML comparison of a sweep", 9),
    "figures": ("harness.cmd_figures", "reproduce the published figures", 8),
    "ci": ("harness.cmd_ci", "nightly performance CI against a committed baseline", 9),
    "history": ("harness.cmd_history", "plot the CI history trend", 9),
    "kins-demo": ("harness.cmd_kins_demo", "workspace and joint-range plots for every machine", 2),
}


class CliError(Exception):
    """A user-facing error: printed as one line, exit code 2."""


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="pkmbench", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    modules = {}
    for name, (modname, help_, issue) in COMMANDS.items():
        try:
            mod = importlib.import_module(modname)
        except ModuleNotFoundError as e:
            if e.name != modname:
                raise
            mod = None
        p = sub.add_parser(name, help=help_ if mod else f"{help_} (coming soon: issue {issue})",
                           description=help_)
        if mod:
            mod.add_arguments(p)
        modules[name] = mod
    args = parser.parse_args(argv)
    if not args.command:
        parser.print_help()
        return 2
    mod = modules[args.command]
    if mod is None:
        print(f"pkmbench {args.command}: coming soon (issue {COMMANDS[args.command][2]})", file=sys.stderr)
        return 2
    try:
        return int(mod.main(args) or 0)
    except CliError as e:
        print(f"pkmbench {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"pkmbench {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    # `python -m harness.cli`: this file runs as __main__, but the commands raise the CliError
    # of the module harness.cli, so run that module's main
    from harness.cli import main as _main
    sys.exit(_main())
