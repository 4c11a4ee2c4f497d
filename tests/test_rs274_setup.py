"""Tool tables, var files and --offset (planners/paths/gcode/rs274/setup.py): the interpreter
started with them gives LinuxCNC's canonical moves (its own interpreter, given the same files);
malformed files are refused naming the file and line; the CLI and suites take them."""
import json
from pathlib import Path

import pytest

from planners.paths.gcode.rs274 import RS274Error, interpret
from planners.paths.gcode.rs274.reference import (RS274_DECIMALS_TOL, available, compare, linuxcnc_moves,
                                                  rs274_moves)
from planners.paths.gcode.rs274.setup import make_setup, parse_offset, read_tool_table, read_var_file

WHY = available()
needs_linuxcnc = pytest.mark.skipif(WHY is not None, reason=str(WHY))

TBL = "T1 P1 Z10 D3 ;flat 3 mm\nt2 p5 z-2.5 x1 d6.35\n\n;a comment line\nT7 P2 Z33.125 ;\n"
VAR = ("5161\t1\n5162\t2\n5163\t3\n5181\t4\n5182\t-4\n5183\t12\n5210\t1\n5211\t0.5\n5212\t0\n5213\t0.25\n"
       "5220\t2\n5221\t10\n5222\t20\n5223\t30\n5230\t15\n5241\t-5\n5242\t-6\n5243\t-7\n5250\t-10\n"
       "5261\t100\n5262\t0\n5263\t-300\n")
PROGRAM = ("G21 G0 X0 Y0 Z0\nG1 X1 F100\nG2 X3 Y2 R2\nG0 X3\nG54 G0 X4\nG3 X2 Y5 R30\nG92.1\nG0 X0\n"
           "G92.3\nG0 X1 Y1\nG56 G1 X2 Y2 Z2\nG28\nG30 Z1\nM2\n")
# M6 and G43 on separate lines: after M6 LinuxCNC re-reads the position, which its standalone
# interpreters (rs274, the gcode module) take from their last program point, not from the machine
TOOLS = "G21 G0 X0 Y0 Z0\nT2 M6\nG43\nG0 X2\nG43 H7\nG1 X3 F100\nT1 M6\nG43\nG0 Y1\nG49\nG0 Z0\nM2\n"


@pytest.fixture
def files(tmp_path):
    (tmp_path / "t.tbl").write_text(TBL)
    (tmp_path / "v.var").write_text(VAR)
    (tmp_path / "p.ngc").write_text(PROGRAM)
    (tmp_path / "tools.ngc").write_text(TOOLS)
    return tmp_path


def test_tool_table_reads_linuxcnc_format(files):
    t = read_tool_table(files / "t.tbl")
    assert sorted(t) == [1, 2, 7]
    assert t[1] == {"P": 1, "Z": 10.0, "D": 3.0, "comment": "flat 3 mm"}
    assert t[2] == {"P": 5, "Z": -2.5, "X": 1.0, "D": 6.35}
    assert t[7]["Z"] == 33.125


def test_var_file_and_offsets(files):
    p = read_var_file(files / "v.var")
    assert p[5220] == 2 and p[5241] == -5 and p[5230] == 15
    s = make_setup(None, files / "v.var", ["G55=1,2,3", "g59.3=0,0,-1", "G92=0,0,0"])
    assert [s.params[5241 + i] for i in range(3)] == [1, 2, 3]
    assert [s.params[5381 + i] for i in range(3)] == [0, 0, -1]
    assert s.params[5210] == 1 and s.params[5213] == 0
    assert parse_offset("G54=0,0,-300") == ("G54", [0.0, 0.0, -300.0])


def _same(file, setup):
    ref, end = linuxcnc_moves(file, setup=setup)
    assert end["error"] is None, end
    ours = interpret(Path(file).read_text(), str(file), setup=setup).moves
    d = compare(ours, ref, RS274_DECIMALS_TOL if end.get("decimals") else 1e-9)
    assert d is None, d
    return ours, end


@needs_linuxcnc
def test_var_file_gives_linuxcncs_moves(files):
    """#5220 = 2 starts in G55 with its rotation, #5210 = 1 puts the stored G92 in force, G28 and
    G30 go to the stored points: the gcode module's moves to 1e-9 mm."""
    ours, end = _same(files / "p.ngc", make_setup(None, files / "v.var"))
    assert "decimals" not in end                       # the full-precision module, not rs274's text
    assert len(ours) == 13                             # 11 motion lines, G28 and G30 two moves each
    # the first move, G0 X0 Y0 Z0 in G55 (-5,-6,-7) rotated -10° with G92 (0.5, 0, 0.25) first
    import math
    c, s = math.cos(math.radians(-10)), math.sin(math.radians(-10))
    assert ours[0].end == pytest.approx((0.5 * c - 5, 0.5 * s - 6, 0.25 - 7), abs=1e-12)
    assert ours[-3].end == pytest.approx((1, 2, 3), abs=1e-12)      # G28: the stored machine point
    assert ours[-1].end[2] == pytest.approx(12, abs=1e-12)          # G30 Z: the stored Z only


@needs_linuxcnc
def test_offsets_give_linuxcncs_moves(files):
    _same(files / "p.ngc", make_setup(None, None, ["G54=10,-20,-300", "G55=1,2,3", "G56=0,0,5",
                                                 "G92=1,1,1", "G28=0,0,-100", "G30=5,5,5"]))


@needs_linuxcnc
def test_tool_table_gives_linuxcncs_moves(files):
    """T, M6, G43 and G43 H from the table (rs274 -t, the table written in its inches)."""
    setup = make_setup(files / "t.tbl", files / "v.var")
    ours, _ = _same(files / "tools.ngc", setup)
    ref, _ = rs274_moves(files / "tools.ngc", setup=setup)
    assert compare(ours, ref, RS274_DECIMALS_TOL) is None
    # a tool length offset moves no axis (the program's Z shifts): the machine stays at G55's
    # Z -7 + G92's 0.25 until G0 Z0 without an offset; tool 2's X offset 1 likewise
    assert [m.end[2] for m in ours] == pytest.approx([-6.75] * 5, abs=1e-12)


@needs_linuxcnc
@pytest.mark.parametrize("line", ["T5", "T1 M6\nG43 H9", "M61 Q9"])
def test_tool_not_in_the_table_is_refused_as_linuxcnc_does(files, line):
    f = files / "bad.ngc"
    f.write_text(f"G21 G0 X0 Y0 Z0\n{line}\nG0 X1\nM2\n")
    setup = make_setup(files / "t.tbl")
    _, end = rs274_moves(f, setup=setup)
    assert end["result"] != 0 and end["error"]          # "Requested tool N not found in the tool table"
    with pytest.raises(RS274Error) as e:
        interpret(f.read_text(), str(f), setup=setup)
    assert e.value.line == line.count("\n") + 2 and "not in the tool table" in e.value.message


@pytest.mark.parametrize("kind,text,line,what", [
    ("tbl", "T1 P1 Z1\nT2 P2 K5\n", 2, "unknown word 'K5'"),
    ("tbl", "T1 P1 Z1\n\nT2 P2 Zabc\n", 3, "'Zabc': Z needs a number"),
    ("tbl", "P2 Z1\n", 1, "no T word"),
    ("tbl", "T1 P1\nT1 P2\n", 2, "listed twice"),
    ("tbl", "T1.5 P1\n", 1, "T needs an integer"),
    ("var", "5221 1\n5220 2\n", 2, "must increase"),
    ("var", "5221 1\n5222 x\n", 2, "expected 'number value'"),
    ("var", "5221\n", 1, "expected 'number value'"),
    ("var", "9999 1\n", 1, "out of range"),
    ("var", "5221 nan\n", 1, "expected 'number value'"),
    ("var", "5220 12\n", 0, "#5220 = 12"),
])
def test_malformed_files_are_refused_naming_file_and_line(tmp_path, kind, text, line, what):
    f = tmp_path / f"x.{kind}"
    f.write_text(text)
    with pytest.raises(RS274Error) as e:
        make_setup(f if kind == "tbl" else None, f if kind == "var" else None)
    assert e.value.file == str(f) and e.value.line == line and what in e.value.message
    assert str(e.value).startswith(f"{f}:{line}: ")


@pytest.mark.parametrize("spec", ["G53=0,0,0", "G54=1,2", "G54:1,2,3", "G54=1,2,inf", "X=1,2,3"])
def test_bad_offset_spec_is_refused(spec):
    with pytest.raises(ValueError, match="--offset"):
        parse_offset(spec)


# ------------------------------------------------------------------ CLI and suites
CAM = ("(origin on the stock top, as CAM writes it)\nG21 G90 G17\nG0 X0 Y0 Z5\nG1 Z-1 F300\nG1 X20 F600\n"
       "G2 X20 Y20 I0 J10\nG1 X0\nG1 Y0\nG0 Z5\nM2\n")


def _cli(*argv):
    from harness.cli import main
    return main([str(a) for a in argv])


def test_check_places_a_cam_program_with_offset(tmp_path, capsys):
    f = tmp_path / "cam.ngc"
    f.write_text(CAM)
    # at the stock origin (z ≈ 0) the kossel's joints are beyond their stroke (its Z range is
    # -345 … -125 mm); placed 250 mm down, only its jerk findings remain
    assert _cli("check", f, "--machine", "kossel", "--json") == 1
    rep = json.loads(capsys.readouterr().out)
    assert any(x["kind"] == "stroke" for x in rep["findings"])
    assert _cli("check", f, "--machine", "kossel", "--json", "--offset", "G54=-10,-10,-250") == 1
    rep = json.loads(capsys.readouterr().out)
    assert rep["parsed"] and {x["kind"] for x in rep["findings"]} == {"joint_jerk", "cartesian_jerk"}


def test_plan_with_var_file_equals_plan_with_offset(tmp_path, capsys):
    f = tmp_path / "cam.ngc"
    f.write_text(CAM)
    (tmp_path / "v.var").write_text("5220 3\n5261 -10\n5262 -10\n5263 -250\n")
    outs = []
    for extra in (["--var-file", tmp_path / "v.var"], ["--offset", "G56=-10,-10,-250", "--var-file",
                                                        tmp_path / "v.var"]):
        assert _cli("plan", "--machine", "kossel", "--path", f, "--planners", "trapezoid", *extra) == 0
        row = [x for x in capsys.readouterr().out.splitlines() if "trapezoid" in x][0].split()
        outs.append(row[:2] + row[3:])                  # all but the planning time
    assert outs[0] == outs[1] and float(outs[0][1]) > 0


@pytest.mark.parametrize("argv,what", [
    (["--offset", "G54=1,2"], "--offset G54=1,2"),
    (["--var-file", "VAR"], "VAR:1: parameter file"),
    (["--tool-table", "NOPE"], "cannot read tool table"),
])
def test_cli_refuses_bad_setup_in_one_line(tmp_path, capsys, argv, what):
    f = tmp_path / "cam.ngc"
    f.write_text(CAM)
    (tmp_path / "VAR").write_text("5221 one\n")
    argv = [str(tmp_path / a) if a in ("VAR", "NOPE") else a for a in argv]
    what = what.replace("VAR", str(tmp_path / "VAR"))
    assert _cli("check", f, "--machine", "kossel", *argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and what in err


def test_suite_takes_gcode_setup_and_refuses_unknown_keys(tmp_path):
    from harness.sweep.suite import SuiteError, expand, gcode_setup, load_suite, suite_runs, task_key
    f = tmp_path / "cam.ngc"
    f.write_text(CAM)
    (tmp_path / "t.tbl").write_text(TBL)
    suite = tmp_path / "s.toml"
    suite.write_text(f'[[run]]\nmachine = "kossel"\npath = "{f}"\nplanners = ["trapezoid"]\n'
                     f'tool_table = "t.tbl"\noffset = ["G54=-10,-10,-250"]\n')
    runs = suite_runs(load_suite(suite), str(suite))
    g = runs[0][4]
    assert g["tool_table"] == tmp_path / "t.tbl" and g["offset"] == ["G54=-10,-10,-250"]
    assert gcode_setup(g).params[5223] == -250
    tasks = expand(load_suite(suite), str(suite))
    assert tasks[0]["gcode_setup"] == {"tool_table": TBL, "offset": ["G54=-10,-10,-250"]}
    plain = dict(tasks[0])
    del plain["gcode_setup"]
    assert task_key(tasks[0], "v") != task_key(plain, "v")
    suite.write_text(suite.read_text() + "var = \"x.var\"\n")
    with pytest.raises(SuiteError, match=r"s.toml:line 7: \[\[run\]\] #1: unknown key 'var'"):
        load_suite(suite)
    suite.write_text(suite.read_text().replace('var = "x.var"', 'offset = ["G54=1"]').replace(
        'offset = ["G54=-10,-10,-250"]\n', ""))
    with pytest.raises(SuiteError, match="--offset G54=1"):
        load_suite(suite)
