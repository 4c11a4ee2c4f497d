"""pkmbench check: crafted programs for every finding and compile error, exit codes, JSON."""
import json

import numpy as np
import pytest

from harness.cli import main
from harness.gcode_check import check_program
from kins import load_machine

KEOPS, KOSSEL, PN101 = load_machine("keops"), load_machine("kossel"), load_machine("pn101")


def prog(tmp_path, text, name="p.ngc"):
    f = tmp_path / name
    f.write_text(text)
    return f


def test_clean_program_exits_0(tmp_path, capsys):
    f = prog(tmp_path, "G21 G90 G61\nG1 X0 Y0 Z-400 F600\nG1 X10\nG1 Y10\nG1 X0\nG1 Y0\nM2\n")
    rep = check_program(f, KEOPS, "scurve_joint")
    assert rep.exit_code == 0 and rep.findings == [] and rep.stats["samples"] > 100
    assert main(["check", str(f), "--machine", "keops", "--planner", "scurve_joint"]) == 0
    assert "clean" in capsys.readouterr().out


@pytest.mark.parametrize("text,line,message", [
    ("G1 X0 Y0 Z-400 F600\nG1 X10 Q5\n", 2, "unsupported word Q5"),
    ("G1 X0 Y0 Z-400 F600\nG0 G1 X10\n", 2, "same modal group"),
    ("G1 X0 Y0 Z-400 F600\nG1 X1.2.3\n", 2, "cannot read"),
    ("G1 X0 Y0 Z-400 F600\nG2 X10 Y0 I3 J0\n", 2, "differs from radius to start"),
    ("G0 X0 Y0 Z-400\nG1 X10\n", 2, "feed move with no feed rate: give F"),
    ("G1 X0 Y0 Z-400 F600\nG1 X10 X11\n", 2, "X word given twice"),
])
def test_compile_errors_exit_2_with_line(tmp_path, capsys, text, line, message):
    f = prog(tmp_path, text)
    rep = check_program(f, KEOPS)
    assert rep.invalid and rep.exit_code == 2
    assert rep.findings[0].lines == [line] and message in rep.findings[0].message
    assert main(["check", str(f), "--machine", "keops"]) == 2
    assert f"p.ngc:{line}: error:" in capsys.readouterr().out


def test_g91_relative_moves_are_accumulated(tmp_path):
    f = prog(tmp_path, "G90 G61 G1 X0 Y0 Z-400 F600\nG91\nG1 X10\nG1 X10\nG1 Y-5\n")
    rep = check_program(f, KEOPS, "scurve_joint")
    assert rep.exit_code == 0
    assert rep.stats["length_mm"] == pytest.approx(25.0)


def test_n_numbers_not_increasing_is_a_warning(tmp_path):
    f = prog(tmp_path, "N10 G1 X0 Y0 Z-400 F600\nN20 G1 X5\nN15 G1 X10\n")
    rep = check_program(f, KEOPS, "scurve_joint")
    w = [x for x in rep.findings if x.severity == "warning"]
    assert len(w) == 1 and w[0].lines == [3] and "N15 does not increase (line 2 has N20)" in w[0].message
    assert rep.exit_code == 0


def test_stroke_exceeded_names_line_joint_and_amount(tmp_path):
    f = prog(tmp_path, "G1 X0 Y0 Z-400 F600\nG1 X20\nG1 Z-800\n")
    rep = check_program(f, KEOPS)
    stroke = [x for x in rep.findings if x.kind == "stroke"]
    assert rep.exit_code == 1 and [x.lines[0] for x in stroke] == [3]
    worst = stroke[0]
    # the worst point is the end (20, 0, -800): its largest joint, by the closed form of kins
    q_end, _ = KEOPS._ik(np.array([[20.0, 0.0, -800.0]]))
    q1 = q_end.max()
    assert worst.value == pytest.approx(q1, abs=1e-6) and worst.limit == 580
    assert f"beyond its stroke limit 580 mm by {q1 - 580:.4g} mm" in worst.message
    assert rep.stats["dynamics"].startswith("skipped")


def test_unreachable_point(tmp_path):
    f = prog(tmp_path, "G1 X0 Y0 Z-200 F600\nG1 X170\n")
    rep = check_program(f, KOSSEL)
    un = [x for x in rep.findings if x.kind == "unreachable"]
    assert un and un[0].lines == [2] and "cannot reach" in un[0].message


def test_singularity_proximity(tmp_path):
    # pn101: Y + d → 0 makes legs 1 and 2 insensitive to y (cond(J) → ∞); d = -350
    f = prog(tmp_path, "G1 X0 Y0 Z0 F600\nG1 Y349.9\n")
    rep = check_program(f, PN101)
    sing = [x for x in rep.findings if x.kind == "singularity"]
    assert sing and sing[0].lines == [2] and sing[0].value > PN101.cond_max
    assert any(x.kind == "box" and x.lines == [2] for x in rep.findings)


def test_joint_velocity_violation_of_a_cartesian_plan(tmp_path):
    # kossel: a diagonal move at the Cartesian limit drives a joint faster than 20 mm/s
    f = prog(tmp_path, "G1 X-40 Y-40 Z-250 F1200\nG1 X40 Y40 Z-250\n")
    rep = check_program(f, KOSSEL, "scurve")
    v = [x for x in rep.findings if x.kind == "joint_velocity"]
    assert v and v[0].lines == [2] and v[0].value > 20.0 and v[0].limit == 20.0
    assert not [x for x in rep.findings if x.kind == "cartesian_velocity"]


def test_json_report_and_usage_errors(tmp_path, capsys):
    f = prog(tmp_path, "G1 X0 Y0 Z-400 F600\nG1 Z-800\n")
    assert main(["check", str(f), "--machine", "keops", "--json"]) == 1
    d = json.loads(capsys.readouterr().out)
    assert d["exit_code"] == 1 and d["findings"][0]["lines"] == [2]
    assert main(["check", str(tmp_path / "none.ngc"), "--machine", "keops"]) == 2
    assert "none.ngc: no such file" in capsys.readouterr().err
    assert main(["check", str(f), "--machine", "keops", "--planner", "magic"]) == 2
    assert "unknown planner 'magic'; valid: trapezoid" in capsys.readouterr().err


def test_gcode_reader_fuzz_short():
    from tests.fuzz_gcode import fuzz
    counts = fuzz(3000, seed=1)
    assert counts["GCodeError"] > 500 and counts["parsed"] > 50   # both paths really exercised
