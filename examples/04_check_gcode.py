"""Check a G-code program on the Kossel before running it: a program that leaves the workspace
gets findings with their line numbers."""
import tempfile
from pathlib import Path

from harness.check import as_text, check_program
from kins import load_machine

program = """G21 G90 G61
G1 X0 Y0 Z-300 F600
G1 X40
G1 X90 (beyond the Kossel's X limit)
G1 X0 Y0
M2
"""
with tempfile.TemporaryDirectory() as d:
    f = Path(d) / "demo.ngc"
    f.write_text(program)
    report = check_program(f, load_machine("kossel"), "trapezoid")
    print(as_text(report))
