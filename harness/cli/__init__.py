"""The `pkmbench` command line. Each command is a thin module ``harness.cli.<name>`` with
``add_arguments(parser)`` and ``main(args) -> int`` that parses, calls the library
(harness.cosim, harness.sweep, harness.ci, harness.report, harness.check, planners) and
prints.
"""
from __future__ import annotations

import argparse
import contextlib
import importlib
import math
import os
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
    "store": ("harness.cli.store", "the results store's files: `store check` lists those it skips"),
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
    """--start, --reader, --tool-table, --var-file, --offset: how a G-code program is read and
    where it is placed (run, plan, check)."""
    p.add_argument("--start", default=None, metavar="X,Y,Z", help=START_HELP)
    p.add_argument("--reader", choices=("pkmbench", "linuxcnc"), default="pkmbench", help=READER_HELP)
    p.add_argument("--tool-table", default=None, metavar="FILE",
                   help="G-code: LinuxCNC tool table (.tbl: T P X Y Z D … ;comment, mm) for T, M6, G43 H")
    p.add_argument("--var-file", default=None, metavar="FILE",
                   help="G-code: LinuxCNC parameter file (.var: 'number value' lines, mm): work offsets "
                        "G54…G59.3 (#5221…), G92 (#5211…, in force when #5210 = 1), G28/G30 (#5161…, #5181…), "
                        "the active system #5220")
    p.add_argument("--offset", action="append", default=[], metavar="CODE=X,Y,Z",
                   help="G-code: set a work offset before the program (mm; repeatable, after --var-file): "
                        "CODE one of G54…G59.3 (origin of that system; G54 is active unless #5220 says "
                        "otherwise), G92 (in force from the start), G28, G30 (stored positions). "
                        "E.g. --offset G54=0,0,-300 puts a program's origin at z = -300 mm")


def gcode_setup(args):
    """The rs274 Setup of --tool-table, --var-file and --offset (None when none is given);
    CliError naming the file and line, or the spec."""
    tbl, var, offsets = (getattr(args, k, None) for k in ("tool_table", "var_file", "offset"))
    if not (tbl or var or offsets):
        return None
    # loaded only when a setup is given: every command's parser imports this package
    from planners.paths.gcode.rs274 import RS274Error
    from planners.paths.gcode.rs274.setup import make_setup  # (the same reason)
    try:
        return make_setup(tbl, var, offsets or ())
    except (RS274Error, ValueError) as e:
        raise CliError(str(e)) from None


def planner_timeout_s(text: str) -> float:
    """--planner-timeout S: a finite number of seconds > 0 (argparse's type: a bad one is exit 2)."""
    try:
        x = float(text)
    except ValueError:
        x = math.nan
    if not (math.isfinite(x) and x > 0):
        raise argparse.ArgumentTypeError(f"{text!r}: expected a number of seconds > 0")
    return x


def add_timeout_argument(p) -> None:
    """--planner-timeout (run, plan, sweep, ci)."""
    p.add_argument("--planner-timeout", type=planner_timeout_s, default=None, metavar="S",
                   help="stop a planner after S seconds of planning: its row is an error naming the "
                        "timeout, the other planners run (planned in a child process; a suite's "
                        "planner_timeout_s does the same; default: no limit)")


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


def warn_skipped(command: str, store) -> None:
    """One line on stderr per file a results store skipped (harness.store.ResultStore.skipped)."""
    for f, why in store.skipped:
        print(f"pkmbench {command}: warning: skipped {f}: {why} (`pkmbench store check` lists them)",
              file=sys.stderr)


@contextlib.contextmanager
def stdout_to_stderr():
    """What is printed in the body (a plug-in's print(), a C library's write to fd 1) goes to
    stderr: stdout stays for a command's machine-readable output (check --json)."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        os.dup2(2, 1)
        with contextlib.redirect_stdout(sys.stderr):
            yield
    finally:
        sys.stderr.flush()
        os.dup2(saved, 1)
        os.close(saved)


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
    except BrokenPipeError:
        # the reader of stdout (head, less) left: stdout to /dev/null, or the interpreter's own
        # flush at exit fails again with a second message
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        print(f"pkmbench {args.command}: error: output closed before it was all written (broken pipe)",
              file=sys.stderr)
        return 2
    except OSError as e:   # a file the command reads or writes: too long a name, no space, no access, …
        where = f"{shorten(e.filename)}: " if e.filename else ""
        print(f"pkmbench {args.command}: error: {where}{e.strerror or e}", file=sys.stderr)
        return 2


def shorten(name, keep: int = 80) -> str:
    """A file name for a one-line message: a name of thousands of characters shows its ends."""
    name = str(name)
    return name if len(name) <= keep else f"{name[:keep // 2]}…{name[-keep // 2:]} ({len(name)} characters)"

