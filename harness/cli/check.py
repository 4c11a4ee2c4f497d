"""`pkmbench check PROGRAM.ngc --machine M`: the offline G-code checker (exit 0 clean,
1 findings, 2 invalid program)."""
from __future__ import annotations

# Local imports: every command module is imported to build the parser; a command loads what it
# needs when it runs (`pkmbench --help` and the other commands stay fast)

import contextlib

from harness.cli import CliError, add_gcode_arguments, gcode_setup, parse_start, stdout_to_stderr


def add_arguments(p):
    p.add_argument("program", help="G-code program (.ngc)")
    p.add_argument("--machine", required=True, help="machine id or .toml file")
    p.add_argument("--planner", default="trapezoid", help="planner that runs it (default: %(default)s)")
    add_gcode_arguments(p)
    p.add_argument("--json", action="store_true", help="machine-readable report (every finding)")
    p.add_argument("--all", action="store_true",
                   help="print every finding (default: a summary and the 50 worst entries)")


def main(args) -> int:
    from harness.check import TEXT_LIMIT, CheckError, as_text, check_program
    from kins import load_machine
    from kins.machine import MachineFileError

    try:
        # --json: stdout holds the report alone (a plug-in planner's prints go to stderr)
        with stdout_to_stderr() if args.json else contextlib.nullcontext():
            m = load_machine(args.machine)
            rep = check_program(args.program, m, args.planner, start=parse_start(args.start), reader=args.reader,
                                setup=gcode_setup(args))
    except (MachineFileError, CheckError) as e:
        raise CliError(str(e)) from None
    print(rep.to_json() if args.json else as_text(rep, None if args.all else TEXT_LIMIT))
    return rep.exit_code
