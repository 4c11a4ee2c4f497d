"""Canned cycles, probing and the rules of a line, against LinuxCNC 2.9's own interpreter: its
`gcode` module (the moves, full precision: ≤ 1e-9 mm), `rs274 -g` (the order of moves, dwells
and spindle calls) and the errors both give. Skips when LinuxCNC is not installed
(`make linuxcnc`)."""
import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest

import planners
from kins import load_machine
from planners.linuxcnc import runner
from planners.paths import resolve_path
from planners.paths.gcode import EmptyProgram, GCodeError, parse_gcode, program_path
from planners.paths.gcode.rs274 import RS274Error, interpret
from planners.paths.gcode.rs274.interp import Interpreter
from planners.paths.gcode.rs274.reference import (available, compare, linuxcnc_moves, linuxcnc_rows, rs274_sequence,
                                                  sequence)

WHY = available()
needs_linuxcnc = pytest.mark.skipif(WHY is not None, reason=str(WHY))
ROOT = Path(__file__).resolve().parents[1]
CYCLE_PROGRAMS = sorted((ROOT / "tests/gcode").glob("cycles_*.ngc"))


def ours(file, **kw):
    return interpret(Path(file).read_text(), str(file), **kw)


def write(tmp_path, text, name="t.ngc"):
    f = tmp_path / name
    f.write_text(text)
    return f


# ---------------------------------------------------------------- canned cycles
@needs_linuxcnc
@pytest.mark.parametrize("file", CYCLE_PROGRAMS, ids=lambda p: p.name)
def test_cycles_move_as_linuxcnc(file):
    # every cycle in the plane of the file, G98/G99, L repeats, G91, modal re-use: the same
    # canonical moves (kind, end, line) as LinuxCNC's interpreter
    ref, end = linuxcnc_moves(file)
    assert end["error"] is None
    cp = ours(file)
    assert compare(cp.moves, ref, 1e-9) is None
    assert len(cp.moves) >= 50


@needs_linuxcnc
@pytest.mark.parametrize("file", CYCLE_PROGRAMS, ids=lambda p: p.name)
def test_cycles_dwell_and_spindle_calls_in_linuxcnc_order(file):
    # G82/G89 dwell, G84 stop/reverse/dwell/stop/forward, G86 stop and restart, G87 orient,
    # G88 program stop: where LinuxCNC's canon calls them among the moves (its queue waits there)
    seq = sequence(ours(file))
    assert seq == rs274_sequence(file)
    if "inch" not in file.name:
        assert ("m", 0) in seq and ("m", 19) in seq and any(s[0] == "dwell" for s in seq if isinstance(s, tuple))


def test_g81_closed_form():
    # G99 G81 from Z10: rapid over the hole, down to R, feed to Z, rapid back to R; G98 back to
    # the initial level (CYCLE_MACRO: a later block goes to the clearance level at the next hole
    # first, straight from R); G91: X from the current point, R from the initial level, Z from R
    cp = interpret("G21 G0 X0 Y0 Z10\nF60\nG81 X1 Y2 Z-1 R2\nG98 X3\nG91 G81 X1 Y0 Z-2 R-5 L2\nM2\n", "g81.ngc")
    ends = [(mv.kind, tuple(round(v, 12) for v in mv.end)) for mv in cp.moves[1:]]
    assert ends == [("rapid", (1, 2, 10)), ("rapid", (1, 2, 2)), ("feed", (1, 2, -1)), ("rapid", (1, 2, 2)),
                    ("rapid", (3, 2, 10)), ("rapid", (3, 2, 2)), ("feed", (3, 2, -1)), ("rapid", (3, 2, 10)),
                    ("rapid", (4, 2, 10)), ("rapid", (4, 2, 5)), ("feed", (4, 2, 3)), ("rapid", (4, 2, 10)),
                    ("rapid", (5, 2, 10)), ("rapid", (5, 2, 5)), ("feed", (5, 2, 3)), ("rapid", (5, 2, 10))]
    assert all(mv.path_mode == ("exact", "path") for mv in cp.moves[1:])    # cycles run in G61


def test_g83_pecks_back_to_r_then_to_just_above_the_bottom():
    # G83 Q1 from R2 to Z-1.5: pecks to 1, 0, −1, each then rapid out to R and back to 0.254 mm
    # (G83_RAPID_DELTA 0.010 in) above the last depth; G73 only backs off those 0.254 mm
    cp = interpret("G21 G0 X0 Y0 Z2\nF60\nG83 Z-1.5 R2 Q1\nG73 Z-1.5 R2 Q1\nM2\n", "g83.ngc")
    z = [(mv.kind[0], round(mv.end[2], 9)) for mv in cp.moves[1:]]
    d = 0.254
    assert z[:12] == [("r", 2), ("f", 1), ("r", 2), ("r", 1 + d), ("f", 0), ("r", 2), ("r", d),
                      ("f", -1), ("r", 2), ("r", -1 + d), ("f", -1.5), ("r", 2)]
    assert z[12:] == [("r", 2), ("f", 1), ("r", 1 + d), ("f", 0), ("r", d), ("f", -1), ("r", -1 + d),
                      ("f", -1.5), ("r", 2)]


CYCLE_ERRORS = {   # line 3 of "G21 G0 X0 Y0 Z5 / F100 / …": LinuxCNC's error and the words ours has
    "G81 X1 Y1 Z-1": ("R clearance plane unspecified in cycle", "G81"),
    "G81 X1 Y1 Z1 R0": ("R less than z in cycle in xy plane", "G81"),
    "G18 G81 X1 Y1 R0": ("R less than y in cycle in xz plane", "G81"),
    "G83 X1 Z-1 R1 Q0": ("Negative or zero q value used", "G83"),
    "G73 X1 Z-1 R1 Q-2": ("Negative or zero q value used", "G73"),
    "G73 X1 Z-1 R1 Q-1": ("Q word missing with g73", "G73"),     # −1 is rs274ngc's "no Q"
    "G83 X1 Z-1 R1": ("Q word missing with g83", "G83"),
    "G82 X1 Z-1 R1": ("Dwell time p word missing with g82", "G82"),
    "G81 X1 Z-1 R1 L0": ("Cannot do zero repeats of cycle", "G81"),
    "G81 X1 R1": ("Z value unspecified in xy plane canned cycle", "G81"),
    "G19 G81 Y1 R1": ("X value unspecified in yz plane canned cycle", "G81"),
    "G86 X1 Z-1 R1 P1": ("Spindle not turning in g86", "G86"),
    "G84 X1 Z-1 R1": ("Spindle not turning in G84", "G84"),
    "G87 X1 Z-1 R1 I1 J1": ("K word missing with g87", "G87"),
    "G81 Z-1 R1 Q1": ("Q word with no", "Q word"),
    "G81 R1": ("All axes missing with motion code", "G81"),
    "F0 G81 X1 Z-1 R1": ("Cannot feed with zero feed rate", "G81"),
}


@needs_linuxcnc
@pytest.mark.parametrize("text", sorted(CYCLE_ERRORS))
def test_cycle_errors_are_linuxcncs_naming_the_cycle_and_line(text, tmp_path):
    body = f"G21 G0 X0 Y0 Z5\nF100\n{text}\nM2\n"
    _, end = linuxcnc_moves(write(tmp_path, body))
    theirs, word = CYCLE_ERRORS[text]
    assert end["error"] is not None and theirs.lower() in end["error"].lower()
    with pytest.raises(RS274Error) as e:
        interpret(body, "c.ngc")
    assert e.value.line == 3
    assert theirs.lower() in e.value.message.lower() and word in e.value.message


def test_cycle_events_make_the_reader_stop():
    # the dwell of G82 and the spindle calls of G86: LinuxCNC's queue waits there (exact stops)
    p = parse_gcode("G21 G0 X0 Y0 Z5\nF100 S1000 M3\nG82 X1 Z-1 R1 P0.5\nG86 X2 Z-1 R1 P0\nM2\n", "c.ngc")
    # G82: rapid over the hole, to R, feed down | dwell | rapid out; G86: rapid over the hole
    # (at R already), feed down | dwell, M5 | rapid out | M3
    assert [(e.kind, e.value, e.index) for e in p.events if e.kind == "dwell" or e.value in (3, 5)] == \
        [("m", 3, 0), ("dwell", 0.5, 3), ("dwell", 0.0, 6), ("m", 5, 6), ("m", 3, 7)]
    assert len(p.moves) == 7 and all(p.moves[i].stop is not None for i in (2, 5, 6))


# ---------------------------------------------------------------- probing
@needs_linuxcnc
def test_g38_3_without_a_surface_moves_to_its_end_as_linuxcnc(tmp_path):
    # nothing to touch: G38.3 runs to its end; #5061-#5063 read that end (program
    # coordinates: G92 here) and #5070 0, as the gcode module sets them
    f = write(tmp_path, "G21 G0 X1 Y2 Z3\nG92 X0\nG38.3 Z-5 F10\nG0 X[#5061+1] Y#5062 Z[#5063+#5070+1]\n"
                        "G38.3 X5\nG0 Y#5061\nM2\n")
    ref, end = linuxcnc_moves(f)
    assert end["error"] is None
    assert compare(ours(f).moves, ref, 1e-9) is None


@pytest.mark.parametrize("g, words", [("G38.2", "G38.2 move finished without making contact"),
                                      ("G38.4", "Probe is already clear when starting G38.4 or G38.5 move")])
def test_g38_2_and_g38_4_without_contact_are_motions_errors(g, words):
    # motion's control.c / command.c: G38.2 runs to its end and stops with the error; G38.4
    # with the probe already clear is refused before it moves
    with pytest.raises(RS274Error) as e:
        interpret(f"G21 G0 X0 Y0 Z5\n{g} Z-5 F10\nM2\n", "p.ngc")
    assert e.value.line == 2 and e.value.message == words


def test_g38_5_with_the_probe_clear_stops_at_once():
    # control.c: G38.5 seeks "clear"; a clear probe trips it on the first servo cycle
    cp = interpret("G21 G0 X0 Y0 Z5\nG38.5 Z-5 F10\nG0 X#5070 Z#5063\nM2\n", "p.ngc")
    assert cp.moves[1].end == (0.0, 0.0, 5.0) and cp.moves[2].end == (1.0, 0.0, 5.0)


def test_probe_on_a_plane_stops_at_contact_and_sets_5061_in_program_units():
    # under G55 (origin at Z-10) in inches, a plane at machine z = −12.7 mm: contact where the
    # straight line from (0, 0, 1 in) to (1, 0, −1 in) crosses it (closed form)
    text = ("G20 G10 L2 P2 X0 Y0 Z[-10/25.4]\nG55 G0 X0 Y0 Z1\nG38.2 X1 Z-1 F10\n"
            "G10 L2 P3 X#5061 Y#5062 Z#5063\nG56 G0 Z#5070\nM2\n")
    cp = interpret(text, "p.ngc", probe_surface=-12.7)
    z0, z1 = -10 + 25.4, -10 - 25.4                  # machine z of the move's ends
    t = (-12.7 - z0) / (z1 - z0)
    hit = (25.4 * t, 0.0, -12.7)
    assert all(abs(a - b) < 1e-9 for a, b in zip(cp.moves[1].end, hit))
    it = Interpreter(probe_surface=-12.7)
    it.run(text, "p.ngc")
    prog_in = [hit[0] / 25.4, 0.0, (hit[2] + 10) / 25.4]     # G55 program coordinates, inches
    assert all(abs(it.params.get(5061 + i) - prog_in[i]) < 1e-12 for i in range(3))
    assert it.params.get(5070) == 1.0
    # G56 (P3) origin = #5061-#5063 as machine offsets (G10 L2 takes program units): Z1 in above
    assert abs(cp.moves[2].end[2] - (prog_in[2] * 25.4 + 25.4)) < 1e-9


def test_probe_on_a_function_surface_finds_the_first_contact():
    # a sloped plane given as a function: z = −2 + 0.5·x; a probe fed from (0, 0, 5) to (8, 0, −5)
    # meets it where 5 − 10t/1 = −2 + 0.5·8t → t = 7/14
    f = lambda x, y: -2 + 0.5 * x
    cp = interpret("G21 G0 X0 Y0 Z5\nG38.3 X8 Z-5 F100\nM2\n", "p.ngc", probe_surface=f)
    assert all(abs(a - b) < 1e-9 for a, b in zip(cp.moves[1].end, (4.0, 0.0, 0.0)))
    # G38.4 from inside the surface: stops where it leaves it (z above −2 + 0.5·x again)
    cp = interpret("G21 G0 X0 Y0 Z-5\nG38.4 Z5 F100\nM2\n", "p.ngc", probe_surface=f)
    assert abs(cp.moves[1].end[2] - -2.0) < 1e-9


def test_probe_program_plans_with_a_surface():
    # the reader stops at the probe (LinuxCNC's interpreter waits for it) and plans the rest
    text = "G21 G0 X0 Y0 Z5\nG38.2 Z-10 F50\nG0 Z[#5063+2]\nG1 X5 F300\nM2\n"
    with pytest.raises(GCodeError, match="without making contact") as e:
        parse_gcode(text, "p.ngc")
    assert e.value.line == 2
    p = parse_gcode(text, "p.ngc", probe_surface=1.5)
    assert [round(m.segment.end[2], 12) for m in p.moves] == [1.5, 3.5, 3.5]
    assert p.moves[0].stop is not None


# ---------------------------------------------------------------- the rules of a line
@needs_linuxcnc
def test_f_is_set_before_the_units_of_its_line(tmp_path):
    # LinuxCNC's order of execution: F, then G20/G21. After G21, "G20 F6" is 6 mm/min, and
    # "G21 F6" after G20 is 6 in/min; the rate stays through a later unit change
    f = write(tmp_path, "G21 G0 X0 Y0 Z0\nG20 F6\nG1 X1\nG21 F6\nG1 X2\nG20\nG1 X3\nM2\n")
    rows, _ = linuxcnc_rows(f)
    theirs = [r["mm_per_min"] for r in rows if r["kind"] == "feed_rate"]
    assert theirs[:2] == pytest.approx([6.0, 6 * 25.4], rel=1e-12)
    feeds = [mv.feed_mm_min for mv in ours(f).moves[1:]]
    assert feeds == pytest.approx([6.0, 6 * 25.4, 6 * 25.4], rel=1e-12)


@needs_linuxcnc
def test_order_of_execution_within_a_block_as_rs274(tmp_path):
    # comment, F, S, M3, dwell G4, then motion, then M0 on one line; G98 before the cycle of
    # its line; M5 before the motion of its line
    f = write(tmp_path, "G21 G0 X0 Y0 Z5\nS100 M3 G4 P0.5 G1 X1 F10 M0\nM5 G0 X2\nG98 G81 X3 Z-1 R1 M3\nM2\n")
    assert sequence(ours(f)) == rs274_sequence(f)


@needs_linuxcnc
@pytest.mark.parametrize("n, ok", [(252, True), (253, False)])
def test_255_character_buffer_as_linuxcnc(n, ok, tmp_path):
    # linuxcnc.h LINELEN 255: a line of 253 characters and its newline fill fgets' buffer
    line = "G1 X1 F100 (" + "c" * (n - 13) + ")"
    assert len(line) == n
    f = write(tmp_path, f"G21 G0 X0 Y0 Z0\n{line}\nM2\n")
    _, end = linuxcnc_moves(f)
    assert (end["error"] is None) == ok
    if ok:
        assert len(ours(f).moves) == 2
    else:
        assert end["error"] == "Command too long"
        with pytest.raises(RS274Error, match="Command too long") as e:
            ours(f)
        assert e.value.line == 2


@needs_linuxcnc
@pytest.mark.parametrize("text, error", [
    ("%\nG21 G0 X0 Y0 Z0\nG1 X1 F100\n", "File ended with no percent sign"),
    ("%\nG21 G0 X0 Y0 Z0\nG1 X1 F100\nM2\n", None),                      # M2 ends it first
    ("%\nG21 G0 X0 Y0 Z0\nG1 X1 F100\n%\nG1 X9\n", None)])              # closed: the rest unread
def test_percent_delimiters_as_linuxcnc(text, error, tmp_path):
    f = write(tmp_path, text)
    ref, end = linuxcnc_moves(f)
    assert end["error"] == error
    if error is None:
        assert compare(ours(f).moves, ref, 1e-9) is None
    else:
        with pytest.raises(RS274Error, match=error) as e:
            ours(f)
        assert e.value.line == end["line"] == 4


@needs_linuxcnc
def test_abort_msg_debug_print_as_linuxcnc(tmp_path):
    f = write(tmp_path, "G21 G0 X0 Y0 Z0\n#1=2.5 #<v>=-3\n(MSG, hello world )\n"
                        "G1 X1 F100 (DEBUG, x=#1 y=#<v> %d#1 %.2f#<v> #5599 #<nope> #9)\n(PRINT,at #<_x>)\n"
                        "#5599=0\n(DEBUG, hidden)\n(ABORT, stop %f#1 here)\nG1 X5\nM2\n")
    rows, printed = linuxcnc_rows(f)
    theirs = [(r["line"], r["text"]) for r in rows if r["kind"] == "message"]
    it = Interpreter()
    with pytest.raises(RS274Error) as e:
        it.run(f.read_text(), str(f))
    assert e.value.line == rows[-1]["line"] == 8 and e.value.message.endswith(rows[-1]["error"])
    mine = [(ev.line, ev.value) for ev in it.out.events if ev.kind == "message"]
    assert [m for m in mine if m[0] != 5] == theirs and len(theirs) == 2
    assert (5, printed[0]) in mine                       # (PRINT,…): LinuxCNC prints it
    assert len(it.out.moves) == 2                        # nothing after the ABORT runs


@needs_linuxcnc
@pytest.mark.parametrize("depth, ok", [(9, True), (10, False)])
def test_call_depth_limit_as_linuxcnc(depth, ok, tmp_path):
    # INTERP_SUB_ROUTINE_LEVELS 10: the main program is level 0
    text = ("o<d> sub\no1 if [#1 gt 1]\no<d> call [#1-1]\no1 endif\nG1 X#1 F100\no<d> endsub\n"
            f"G21 G0 X0 Y0 Z0\no<d> call [{depth}]\nM2\n")
    f = write(tmp_path, text)
    ref, end = linuxcnc_moves(f)
    if ok:
        assert end["error"] is None and compare(ours(f).moves, ref, 1e-9) is None
    else:
        assert end["error"] == "Too many subroutine levels"
        with pytest.raises(RS274Error, match="Too many subroutine levels") as e:
            ours(f)
        assert e.value.line == 3


def test_a_subroutine_that_calls_itself_twice_ends_with_an_error():
    text = "o<r> sub\no<r> call\no<r> call\no<r> endsub\nG21 G0 X0 Y0 Z0\no<r> call\nM2\n"
    with pytest.raises(RS274Error, match="Too many subroutine levels") as e:
        interpret(text, "r.ngc")
    assert e.value.line == 2


# ---------------------------------------------------------------- nothing to check
LIBRARY = "o<lib> sub\nG1 X#1 F100\no<lib> endsub\nM2\n"


def test_program_without_motion_is_nothing_to_plan():
    with pytest.raises(EmptyProgram, match="nothing to plan"):
        parse_gcode(LIBRARY, "lib.ngc")


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "harness.cli", *args], capture_output=True, text=True, cwd=ROOT,
                          timeout=600)


def test_check_says_nothing_to_check_and_plan_refuses(tmp_path):
    f = write(tmp_path, LIBRARY, "lib.ngc")
    r = _cli("check", str(f), "--machine", "kossel")
    assert r.returncode == 0 and "nothing to check: the program makes no move" in r.stdout
    r = _cli("check", str(f), "--machine", "kossel", "--json")
    d = json.loads(r.stdout)
    assert r.returncode == 0 and d["valid"] and d["stats"]["moves"] == 0
    r = _cli("plan", "--machine", "kossel", "--path", str(f))
    assert r.returncode == 2 and "nothing to plan" in r.stderr and "Traceback" not in r.stderr


def test_check_reports_messages_as_info(tmp_path):
    f = write(tmp_path, "G21 G0 X0 Y0 Z-200\n(MSG, insert the probe)\nG1 X1 F300\nM2\n", "m.ngc")
    r = _cli("check", str(f), "--machine", "kossel", "--json")
    d = json.loads(r.stdout)
    msgs = [x for x in d["findings"] if x["kind"] == "message"]
    assert msgs == [{"kind": "message", "severity": "info", "lines": [2], "value": None, "limit": None, "unit": "",
                     "message": " insert the probe"}]
    assert d["warnings"] == sum(x["severity"] == "warning" for x in d["findings"])
    r = _cli("check", str(f), "--machine", "kossel")
    assert f"{f}:2: message:  insert the probe" in r.stdout


@needs_linuxcnc
def test_parameters_then_comment_then_modal_restore_before_coolant(tmp_path):
    # rs274ngc_pre.cc: a line's #-settings are stored before execute_block runs its comment;
    # M72 restores the state saved by M70 before the M8 of its line (LinuxCNC drops the rest
    # of a line with M72 and a move: not a case here)
    f = write(tmp_path, "G21 G0 X0 Y0 Z0 F100\n#1=7 (DEBUG,#1)\nM70\nG91\nM72\nG1 X1\nM2\n")
    rows, _ = linuxcnc_rows(f)
    cp = ours(f)
    assert [(e.line, e.value) for e in cp.events if e.kind == "message"] == \
        [(r["line"], r["text"]) for r in rows if r["kind"] == "message"] == [(2, "7.000000")]
    assert compare(cp.moves, [r for r in rows if r["kind"] in ("rapid", "feed")], 1e-9) is None
    it = Interpreter()
    it.run("M7\nM70\nM9\nM72 M8\nM2\n", "c.ngc")
    assert it.m.coolant == 8


@needs_linuxcnc
@pytest.mark.parametrize("text", ["G38.2 F10", "G38.3 F10", "G82 R1 P1"])
def test_probe_and_cycle_codes_without_axes_as_linuxcnc(text, tmp_path):
    f = write(tmp_path, f"G21 G0 X0 Y0 Z0\n{text}\nM2\n")
    _, end = linuxcnc_moves(f)
    assert end["error"] == "All axes missing with motion code"
    with pytest.raises(RS274Error, match="All axes missing with motion code") as e:
        ours(f)
    assert e.value.line == 2


@needs_linuxcnc
def test_benchmark_cam_program_with_drilling_reads_as_linuxcnc(tmp_path):
    # benchmarks/perf/cam_program.py's cycles variant (the 10⁵-line check benchmark's program):
    # drilling patterns of one cycle block and X Y lines between raster rows (a benchmark
    # script, not a package: loaded from its file)
    spec = importlib.util.spec_from_file_location("cam_program", ROOT / "benchmarks" / "perf" / "cam_program.py")
    cam = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(cam)
    f = tmp_path / "camc.ngc"
    text = cam.make_cam_program(7000, seed=2, cycles=True, file=f)
    assert all(g in text for g in ("G81", "G83", "G73"))
    ref, end = linuxcnc_moves(f)
    assert end["error"] is None
    assert compare(ours(f).moves, ref, 1e-9) is None


def test_trapezoid_plans_the_drilling_program_to_its_end(tmp_path):
    # the profile ends exactly at the planned path's length (they summed the same lengths in
    # another order and parted by rounding: 1.6e-12 mm here, over 1e-9 on the 10⁵-line program)
    spec = importlib.util.spec_from_file_location("cam_program", ROOT / "benchmarks" / "perf" / "cam_program.py")
    cam = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(cam)
    cam.make_cam_program(4000, seed=2, cycles=True, file=tmp_path / "camc.ngc")
    prof = planners.plan("trapezoid", resolve_path(str(tmp_path / "camc.ngc")), load_machine("kossel"))
    assert prof.s[-1] == prof.path.length and "G81" in (tmp_path / "camc.ngc").read_text()


@pytest.mark.parametrize("text", ["G81 X1 Z-1 R1 L100000", "G83 X1 Z-1 R1 Q0.00001"])
def test_endless_cycles_stop_with_a_clear_error(text):
    with pytest.raises(RS274Error, match="limit of 1000 loop iterations") as e:
        interpret(f"G21 G0 X0 Y0 Z5\nF100\n{text}\nM2\n", "c.ngc", max_loops=1000)
    assert e.value.line == 3


@needs_linuxcnc
def test_debug_formats_as_linuxcnc(tmp_path):
    # convert_param_comment: '%.' not followed by a format keeps the '.', an unknown '%x' both,
    # #5420 is the current X, a parameter out of range reads ######
    f = write(tmp_path, "G21 G0 X1 Y0 Z0\n(DEBUG,a%.x b%.5 c%q #5420 #99999 %.3f#5421)\nM2\n")
    rows, _ = linuxcnc_rows(f)
    theirs = [(r["line"], r["text"]) for r in rows if r["kind"] == "message"]
    assert [(e.line, e.value) for e in ours(f).events if e.kind == "message"] == theirs
    assert theirs == [(2, "a.x b.5 c%q 1.000000 ###### 0.000")]


# ---------------------------------------------------------------- the real LinuxCNC (slow)
@pytest.mark.slow
@pytest.mark.realtime
@pytest.mark.parametrize("name, text, closed_form_s", [
    # after G21, "G20 F6" is 6 mm/min: 0.254 mm at 0.1 mm/s (the ramps at 250 mm/s² add 0.4 ms)
    ("f6", "G21 G90 G64\nG0 X0 Y0 Z-200\nG20 F6\nG1 X0.01\nM2\n", 2.54),
    # G81 twice (G99) and a G83 (G98, Q4), with the spindle on: the cycles' moves and stops
    ("drill", "G21 G90 G64\nG0 X0 Y0 Z-200\nF600 S1000 M3\nG99 G81 X5 Y0 Z-210 R-198\nX10\n"
              "G98 G83 X15 Z-212 R-198 Q4\nG80\nG0 X0 Y0\nM2\n", None)])
def test_trapezoid_runs_units_and_cycles_as_the_real_linuxcnc(name, text, closed_form_s, tmp_path):
    if runner.missing():
        pytest.skip(f"LinuxCNC absent: {runner.missing()}")
    f = write(tmp_path, text, f"{name}.ngc")
    path = program_path(parse_gcode(text, str(f)))
    m = load_machine("kossel")
    real = planners.plan("linuxcnc", path, m).execution_time_s
    ours_s = planners.plan("trapezoid", path, m).execution_time_s
    assert abs(ours_s / real - 1) <= 0.002
    if closed_form_s is not None:
        assert abs(real - closed_form_s) <= 0.002
