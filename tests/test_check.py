"""pkmbench check: crafted programs for every finding and compile error, exit codes, JSON."""
import json

import numpy as np
import pytest

from harness.cli import main
from harness.check import check_program
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
    ("G1 X0 Y0 Z-400 F600\nG1 X10 Q5\n", 2, "Q word with no code on the line that uses it"),
    ("G1 X0 Y0 Z-400 F600\nG0 G1 X10\n", 2, "same modal group"),
    ("G1 X0 Y0 Z-400 F600\nG1 X1.2.3\n", 2, "cannot read"),
    ("G1 X0 Y0 Z-400 F600\nG2 X10 Y0 I3 J0\n", 2, "differs from radius to start"),
    ("G0 X0 Y0 Z-400\nG1 X10\n", 2, "zero feed rate: give F"),
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


def excursions(tmp_path, n):
    """kossel, G61: from X45 out to X55 (beyond the ±50 mm box) and back on even k, to X49
    (inside) and back on odd k. Excursion k is on lines 3 + 2k and 4 + 2k."""
    body = ["G21 G90 G61", "G1 X45 Y0 Z-250 F1200"]
    for k in range(n):
        body += ["G1 X55" if k % 2 == 0 else "G1 X49", "G1 X45"]
    return prog(tmp_path, "\n".join(body) + "\n")


def test_box_findings_are_exactly_the_lines_that_leave_it(tmp_path):
    f = excursions(tmp_path, 120)
    rep = check_program(f, KOSSEL)
    box = sorted(x.lines[0] for x in rep.findings if x.kind == "box")
    assert box == sorted(ln for k in range(0, 120, 2) for ln in (3 + 2 * k, 4 + 2 * k))   # 120 lines
    assert not [x for x in rep.findings if x.kind in ("unreachable", "stroke")]


def test_text_report_summary_cap_and_all(tmp_path, capsys):
    f = excursions(tmp_path, 120)
    rep = check_program(f, KOSSEL)
    assert main(["check", str(f), "--machine", "kossel"]) == 1
    out = capsys.readouterr().out.splitlines()
    n_err = sum(x.severity == "error" for x in rep.findings)
    assert out[1] == f"  {n_err} error(s), 0 warning(s) on {len({ln for x in rep.findings for ln in x.lines})} line(s)"
    # summary before the findings: one row per kind, box with its 120 findings on 120 lines
    box_row = [ln for ln in out if ln.split()[:2] == ["box", "error"]]
    assert len(box_row) == 1 and " 120 on 120 line(s), worst 5 mm" in box_row[0]   # X55: 5 mm out
    assert out.index(box_row[0]) < min(i for i, ln in enumerate(out) if ln.startswith(f"  {f}:"))
    entries = [ln for ln in out if ln.startswith(f"  {f}:")]
    assert len(entries) == 50
    # an excursion's two box lines (out and back) are consecutive: one entry "3-4", 60 in all
    assert sum(e.startswith(f"  {f}:{3 + 4 * k}-{4 + 4 * k}: error: 2 lines") for e in entries for k in range(60)) \
        == sum(": error: 2 lines" in e for e in entries) > 0
    more = out[-1]
    assert more.startswith("  … ") and "--all prints every one" in more
    n_more, n_more_entries = int(more.split()[1]), int(more.split()[5])
    n_entries = 60 + (len(rep.findings) - 120)          # box runs + every other finding alone
    assert n_more_entries == n_entries - 50
    shown = sum(2 if ": error: 2 lines" in e else 1 for e in entries)
    assert shown + n_more == len(rep.findings)
    assert main(["check", str(f), "--machine", "kossel", "--all"]) == 1
    every = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith(f"  {f}:")]
    assert len(every) == len(rep.findings)
    assert sum(": error: outside the workspace box" in ln for ln in every) == 120


def test_json_is_complete_and_valid_is_false_beside_errors(tmp_path, capsys):
    f = excursions(tmp_path, 120)
    rep = check_program(f, KOSSEL)
    assert main(["check", str(f), "--machine", "kossel", "--json"]) == 1
    d = json.loads(capsys.readouterr().out)
    assert d["parsed"] is True and d["valid"] is False and d["exit_code"] == 1
    assert len(d["findings"]) == len(rep.findings) and d["errors"] == len(rep.findings)
    assert sum(x["kind"] == "box" for x in d["findings"]) == 120
    assert {r["kind"]: r["count"] for r in d["summary"]}["box"] == 120
    clean = prog(tmp_path, "G21 G90 G61\nG1 X0 Y0 Z-400 F600\nG1 X10\n", "c.ngc")
    assert main(["check", str(clean), "--machine", "keops", "--planner", "scurve_joint", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["parsed"] is True and d["valid"] is True and d["errors"] == 0 and d["findings"] == []
    bad = prog(tmp_path, "G1 X0 Y0 Z-400 F600\nG1 X10 Q5\n", "b.ngc")
    assert main(["check", str(bad), "--machine", "keops", "--json"]) == 2
    d = json.loads(capsys.readouterr().out)
    assert d["parsed"] is False and d["valid"] is False and d["exit_code"] == 2


def test_one_move_program_is_checked_from_home(tmp_path):
    # kossel home (0, 0, -200): the only move goes to (30, 40, -250), 50√2 mm away
    f = prog(tmp_path, "G21 G90\nG1 X30 Y40 Z-250 F600\nM2\n")
    rep = check_program(f, KOSSEL, "scurve_joint")
    assert not rep.invalid and rep.stats["moves"] == 1
    assert rep.stats["length_mm"] == pytest.approx(50 * 2 ** 0.5)
    assert rep.stats["samples"] > 1000          # ≥ 70.7 mm at ≤ 20 mm/s: > 3.5 s at 1 ms


def test_dynamics_findings_read_the_metrics_differences(tmp_path):
    """check takes its differences one order at a time: each finding's value is the worst
    |difference| of its line from planners.verify.differences on the same samples."""
    import planners
    from planners import verify as M
    from planners.paths.gcode import program_path, read_gcode
    m = load_machine("kossel")
    f = tmp_path / "p.ngc"
    f.write_text("G21 G90 G64 P0.01\nG0 X0 Y0 Z-250\nF6000\nG1 X30 Y0\nG1 X30 Y20\nG1 X0 Y20\nG1 X0 Y0\nM2\n")
    rep = check_program(f, m, "trapezoid")
    prof = planners.plan("trapezoid", program_path(read_gcode(f, home=m.home)), m)
    Q = m.ik(prof.path.point(prof.s))
    lines = prof.path.line_at(prof.s)
    found = [x for x in rep.findings if x.kind.startswith("joint_")]
    assert found
    for x in found:
        order = x.kind[len("joint_"):]
        D = M.differences(Q, m.servo_period_s)[order]
        # each window on the line of its last sample (the rest after the end: the last line)
        last = M.window_sample(np.arange(len(D)), len(Q), M.ORDERS.index(order) + 1)
        worst = np.abs(D).max(axis=1)[lines[last] == x.lines[0]]
        assert x.value == worst.max()


def test_trapezoid_check_builds_only_the_blends_it_runs(tmp_path, monkeypatch):
    # trapezoid re-blends a program as LinuxCNC's tp queues it (planners.trapezoid.queue): the check
    # must not build the standard blends too, and its geometry is that of the path that ran
    import planners.paths.gcode.reader as reader
    calls = []
    real = reader.blend_corners
    monkeypatch.setattr(reader, "blend_corners", lambda *a, **k: calls.append(1) or real(*a, **k))
    f = prog(tmp_path, "G21 G90 G64 P0.05\nG1 X0 Y0 Z-400 F3000\nG1 X20\nG1 Y20\nG1 X0\nM2\n")
    rep = check_program(f, KEOPS, "trapezoid")
    assert calls == []
    from planners.paths.gcode import program_path, read_gcode
    from planners import plan
    ran = plan("trapezoid", program_path(read_gcode(f, home=KEOPS.home), deferred=True), KEOPS)
    assert rep.stats["length_mm"] == ran.path.length < 60.0     # three 20 mm lines minus two blends
    # every other planner gets the standard blends, built once
    rep = check_program(f, KEOPS, "scurve")
    assert calls == [1] and rep.stats["length_mm"] == program_path(read_gcode(f, home=KEOPS.home)).length


def test_deferred_program_path_blends_on_first_read(tmp_path):
    from planners.paths.gcode import program_path, read_gcode
    f = prog(tmp_path, "G21 G90 G64 P0.1\nG1 X0 Y0 Z-400 F600\nG1 X10\nG2 X20 Y0 I5 J0\nG1 Y10\nM2\n")
    p = read_gcode(f)
    lazy = program_path(p, deferred=True)
    assert lazy.program is p and "segments" not in vars(lazy)  # nothing built by reading these
    eager = program_path(p)
    assert lazy.length == eager.length and len(lazy.segments) == len(eager.segments)
    s = np.linspace(0.0, eager.length, 101)
    assert np.array_equal(lazy.point(s), eager.point(s)) and np.array_equal(lazy.corners(), eager.corners())


def test_start_gives_the_machine_position_before_the_program(tmp_path, capsys):
    # LinuxCNC's rule with --start: the only move is a segment from the given point
    f = prog(tmp_path, "G21 G90\nG1 X30 Y40 Z-250 F600\nM2\n")
    rep = check_program(f, KOSSEL, "trapezoid", start=(0.0, 0.0, -250.0))
    assert rep.stats["length_mm"] == pytest.approx(50.0)
    assert main(["check", str(f), "--machine", "kossel", "--start", "0,0,-250", "--json"]) == rep.exit_code
    assert json.loads(capsys.readouterr().out)["stats"]["length_mm"] == pytest.approx(50.0)
    assert main(["check", str(f), "--machine", "kossel", "--start", "0,0"]) == 2
    assert "--start 0,0: expected X,Y,Z in mm" in capsys.readouterr().err


def test_a_velocity_finding_names_the_feed_that_keeps_it_within(tmp_path):
    # joint velocity = |q′(s)|·feed: the feed the finding names (speed × limit / value) is exact,
    # so the line programmed at that feed has no joint velocity finding left
    import re
    f = prog(tmp_path, "G1 X-40 Y-40 Z-250 F1200\nG1 X40 Y40 Z-250\n")
    v = [x for x in check_program(f, KOSSEL, "trapezoid").findings if x.kind == "joint_velocity"]
    assert v and "(F1200 programmed)" in v[0].message
    at, keep = map(float, re.search(r"at ([\d.]+) mm/s .*≤ ([\d.]+) mm/s keeps it within", v[0].message).groups())
    assert at == pytest.approx(20.0, rel=1e-3) and keep <= at * 20.0 / v[0].value * (1 + 1e-9)
    f2 = prog(tmp_path, f"G1 X-40 Y-40 Z-250 F{60 * keep * 0.999:.4f}\nG1 X40 Y40 Z-250\n", "p2.ngc")
    assert not [x for x in check_program(f2, KOSSEL, "trapezoid").findings if x.kind == "joint_velocity"]
