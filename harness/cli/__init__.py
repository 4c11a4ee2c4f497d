"""The `pkmbench` command line. Each command is a thin module ``harness.cli.<name>`` with
``add_arguments(parser)`` and ``main(args) -> int`` that parses, calls the library
(harness.cosim, harness.sweep, harness.ci, harness.report, harness.check, planners) and
prints.
"""
from __future__ import annotations

import argparse
import importlib
import math
import sys

from harness.outdir import OutDirError
from harness.provenance import git_commit, package_version

DESCRIPTION = ("pkmbench: co-simulate feedrate planners on parallel-kinematics machines through FMI "
               "co-simulation FMUs (interpolator, kinematics, EtherCAT, drives) and compare their "
               "execution time, joint-limit ratios and following/contour errors.")

# name → (module, one-line help)
COMMANDS = {
    "run": ("harness.cli.run", "co-simulate a suite or machine × path × planners and compare"),
    "plan": ("harness.cli.plan", "plan a feed profile only (no co-simulation)"),
    "check": ("harness.cli.check", "offline G-code checker for a PKM (workspace, singularities, joint limits)"),
    "sweep": ("harness.cli.sweep", "run a suite on Dask (in-process, or --scheduler ADDRESS)"),
    "report": ("harness.cli.report", "Markdown/HTML comparison of a sweep"),
    "figures": ("harness.cli.figures", "reproduce the published figures"),
    "ci": ("harness.cli.ci", "nightly performance CI against a committed baseline"),
    "history": ("harness.cli.history", "plot the CI history trend (the ci runs of the results store)"),
    "query": ("harness.cli.query", "SQL over the results store (sweeps, corpus, ci)"),
    "corpus": ("harness.cli.corpus", "every planner on every corpus path: table and performance profile"),
    "kins-demo": ("harness.cli.kins_demo", "workspace and joint-range plots for every machine"),
}


class CliError(Exception):
    """A user-facing error: printed as one line, exit code 2."""


START_HELP = ("G-code: the machine position before the program (mm); every move, the first included, "
              "is then planned from it, as LinuxCNC runs it (default: a first absolute G0/G1 with X, Y "
              "and Z positions the tool, else the machine's home)")


READER_HELP = ("G-code reader: pkmbench (the built-in RS274NGC interpreter) or linuxcnc (LinuxCNC's own, "
               "from linuxcnc-uspace: make linuxcnc) (default: %(default)s)")


def add_gcode_arguments(p) -> None:
    """--start and --reader: how a G-code program is read (run, plan, check)."""
    p.add_argument("--start", default=None, metavar="X,Y,Z", help=START_HELP)
    p.add_argument("--reader", choices=("pkmbench", "linuxcnc"), default="pkmbench", help=READER_HELP)


def parse_start(text: str | None) -> list[float] | None:
    """--start X,Y,Z → [x, y, z] (mm), None when not given; CliError naming the value otherwise."""
    if text is None:
        return None
    try:
        xyz = [float(v) for v in text.split(",")]
    except ValueError:
        xyz = []
    if len(xyz) != 3 or not all(map(math.isfinite, xyz)):
        raise CliError(f"--start {text}: expected X,Y,Z in mm (three finite numbers)")
    return xyz


def version_string() -> str:
    """'pkmbench VERSION (git COMMIT)': the installed package's version and, in a git checkout,
    the commit of this code (``+dirty`` when tracked files differ from it)."""
    commit = git_commit(12, dirty=True)
    return f"pkmbench {package_version() or '(not installed)'}" + (f" (git {commit})" if commit else "")


class _Version(argparse.Action):
    """--version, computed only when asked (it runs git)."""

    def __init__(self, option_strings, dest, **kwargs):
        super().__init__(option_strings, dest, nargs=0, help="print the version and git commit, then exit")

    def __call__(self, parser, namespace, values, option_string=None):
        print(version_string())
        parser.exit()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="pkmbench", description=DESCRIPTION)
    parser.add_argument("--version", action=_Version)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    modules = {}
    for name, (modname, help_) in COMMANDS.items():
        mod = importlib.import_module(modname)
        mod.add_arguments(sub.add_parser(name, help=help_, description=help_))
        modules[name] = mod
    args = parser.parse_args(argv)
    if not args.command:
        parser.print_help()
        return 2
    mod = modules[args.command]
    try:
        return int(mod.main(args) or 0)
    except (CliError, OutDirError) as e:
        print(f"pkmbench {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"pkmbench {args.command}: interrupted", file=sys.stderr)
        return 130

