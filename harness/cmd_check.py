"""`pkmbench check PROGRAM.ngc --machine M`: the offline G-code checker (exit 0 clean,
1 findings, 2 invalid program)."""
from __future__ import annotations

from harness.cli import CliError


def add_arguments(p):
    p.add_argument("program", help="G-code program (.ngc)")
    p.add_argument("--machine", required=True, help="machine id or .toml file")
    p.add_argument("--planner", default="trapezoid", help="planner that runs it (default: %(default)s)")
    p.add_argument("--json", action="store_true", help="machine-readable report")


def main(args) -> int:
    from harness.gcode_check import CheckError, check_program
    from kins import load_machine
    from kins.machine import MachineFileError

    try:
        m = load_machine(args.machine)
        rep = check_program(args.program, m, args.planner)
    except (MachineFileError, CheckError) as e:
        raise CliError(str(e)) from None
    print(rep.to_json() if args.json else rep.text())
    return rep.exit_code
