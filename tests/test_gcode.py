"""planners.paths.gcode: every supported word, modal state, arcs, blending modes and every error."""
import math

import numpy as np
import pytest

from planners.paths.gcode import EmptyProgram, GCodeError, parse_gcode, program_path, read_gcode
from planners.paths import Arc, Line, PathError, load_path

START = "G90 G21 G17\nG0 X0 Y0 Z0\n"


def prog(body, start=START):
    return parse_gcode(start + body, "t.ngc")


def ends(p):
    return np.array([m.segment.end for m in p.moves])


def test_g0_g1_modal_absolute_incremental_and_feed():
    p = prog("G1 X10 F600\nY5\nG91 X-2 Y-1 Z3\nG90 G0 X1\n")
    assert np.allclose(ends(p), [[10, 0, 0], [10, 5, 0], [8, 4, 3], [1, 4, 3]])
    assert [m.line for m in p.moves] == [3, 4, 5, 6]                  # file line numbers
    assert [m.rapid for m in p.moves] == [False, False, False, True]
    assert p.moves[0].feed_mm_s == pytest.approx(10.0) and p.moves[3].feed_mm_s is None
    assert np.allclose(p.start, [0, 0, 0])
    assert p.notes[0][0] == 2 and "start point" in p.notes[0][1]


def test_inches_n_numbers_comments_percent():
    text = "%\nN5 G20 G90 (inch) ; trailing\nN10 G0 X0 Y0 Z0\nN20 G1 X1 F10 (ten ipm)\n%\n"
    p = parse_gcode(text, "t.ngc")
    assert np.allclose(p.moves[0].segment.end, [25.4, 0, 0])
    assert p.moves[0].feed_mm_s == pytest.approx(10 * 25.4 / 60)
    assert p.moves[0].line == 4


def test_percent_lines_bound_the_program_as_linuxcnc_reads_them():
    # the first non-blank line '%' opens it, the next lone '%' ends it (a G1 after is never
    # read); a '%' on any other line, or with a comment, is an error of that line
    p = parse_gcode("\n%\nG21 G0 X0 Y0 Z0\nG1 X1 F60\n  %\nG1 X5\n", "t.ngc")
    assert ends(p).tolist() == [[1.0, 0.0, 0.0]] and p.moves[0].line == 4
    for text, line in (("G21 G0 X0 Y0 Z0\n%\nG1 X1 F60\nM2\n", 2),
                       ("%\nG21 G0 X0 Y0 Z0\n% (end)\nG1 X1 F60\n", 3),
                       ("% (start)\nG21 G0 X0 Y0 Z0\nG1 X1 F60\n%\n", 1)):
        with pytest.raises(GCodeError, match="'%' here") as e:
            parse_gcode(text, "t.ngc")
        assert e.value.line == line


def test_subroutine_file_lone_percent_lines_are_skipped(tmp_path):
    (tmp_path / "sq.ngc").write_text("%\no<sq> sub\nG1 X#1 F60\no<sq> endsub\nM2\n%\n")
    p = parse_gcode("G21 G0 X0 Y0 Z0\no<sq> call [3]\nM2\n", "t.ngc", subroutine_path=[tmp_path])
    assert ends(p).tolist() == [[3.0, 0.0, 0.0]]


def test_m_codes_are_recorded_with_their_line_and_m30_ends():
    # (was: S/T/M/G40/G80 "ignored with a note"; the interpreter now records M codes as events
    # at the move index where LinuxCNC would stop for them)
    p = prog("S1000 T1 M3 G40 G80\nG1 X1 F60\nM30\nG1 X5\n")
    # S is SET_SPINDLE_SPEED, a message to motion (as rs274 prints it, before M3's)
    assert [(e.kind, e.value, e.line, e.index) for e in p.events] == [("speed", 1000, 3, 0), ("m", 3, 3, 0),
                                                                     ("m", 30, 5, 1)]
    assert "M30: end of program" in " ".join(n for _, n in p.notes)
    assert len(p.moves) == 1


def test_user_m_code_takes_p_and_q():
    # interp_check.cc: P and Q are a user M code's (M100–M199) arguments, not stray words
    p = prog("M101 P1 Q2.5\nG1 X1 F60\n")
    assert [(e.kind, e.value, e.line) for e in p.events] == [("m", 101, 3)] and len(p.moves) == 1
    with pytest.raises(GCodeError, match="Q word with no code"):
        prog("M5 Q2\n")


def test_zero_length_move_is_dropped_but_its_m_code_counts():
    # (was an error; LinuxCNC's canon drops it — the thesis part's "N70 Z-240 M09")
    p = prog("G1 X1 F60\nN70 X1 M09\nG1 X2\n")
    assert [m.line for m in p.moves] == [3, 5]
    assert [(e.value, e.line, e.index) for e in p.events] == [(9, 4, 1)]
    assert any(ln == 4 and "zero-length move dropped" in n for ln, n in p.notes)


def test_arc_ij_quarter_and_full_circle_and_helix():
    p = prog("G1 X10 F600\nG3 X0 Y10 I-10 J0\nG2 X0 Y10 I0 J-10 Z5\n")
    q = p.moves[1].segment
    assert q.angle == pytest.approx(math.pi / 2) and np.allclose(q.normal, [0, 0, 1])
    assert np.allclose(q.center, [0, 0, 0]) and q.radius == pytest.approx(10)
    full = p.moves[2].segment                                          # G2 full turn rising 5
    assert full.angle == pytest.approx(2 * math.pi) and np.allclose(full.normal, [0, 0, -1])
    assert full.rise == pytest.approx(-5.0)                            # rise along n = −z
    assert np.allclose(full.end, [0, 10, 5])
    assert full.length == pytest.approx(math.hypot(2 * math.pi * 10, 5))


def test_arc_r_form_short_and_long_way_and_turns():
    p = prog("G1 X10 F600\nG2 X0 Y-10 R10\nG2 X10 Y0 R-10\nG3 X10 Y0 I-10 J0 P2\n")
    a1, a2, a3 = (m.segment for m in p.moves[1:])
    assert a1.angle == pytest.approx(math.pi / 2) and np.allclose(a1.center, [0, 0, 0], atol=1e-12)
    assert a2.angle == pytest.approx(3 * math.pi / 2)                 # R < 0: the long way
    assert np.allclose(a2.center, [0, 0, 0], atol=1e-12)
    assert a3.angle == pytest.approx(4 * math.pi)                     # P2: two full turns


@pytest.mark.parametrize("plane, words, normal, center", [
    ("G18", "G3 X0 Z-10 I-10 K0", [0, 1, 0], [0, 0, 0]),   # ZX plane, ccw about +Y: +X → −Z
    ("G19", "G3 Y0 Z10 J-10 K0", [1, 0, 0], [0, 0, 0]),    # YZ plane, ccw about +X
])
def test_planes(plane, words, normal, center):
    first = "G1 X10 F600" if plane == "G18" else "G1 Y10 F600"
    p = prog(f"{first}\n{plane} {words}\n")
    a = p.moves[1].segment
    assert np.allclose(a.normal, normal) and np.allclose(a.center, center)
    assert a.angle == pytest.approx(math.pi / 2)
    mid = a.eval(np.array([a.length / 2]), 0)[0][0]
    r = 10 / math.sqrt(2)
    assert np.allclose(mid, [r, 0, -r] if plane == "G18" else [0, r, r])


def test_small_radius_mismatch_is_a_spiral_about_the_programmed_centre():
    # as LinuxCNC: the centre stays at I/J, the radius goes 10 → 10.001 (tests/test_spiral.py)
    p = prog("G1 X10 F600\nG3 X0 Y10.001 I-10 J0\n")
    a = p.moves[1].segment
    assert a.center.tolist() == [0, 0, 0] and a.spiral == pytest.approx(0.001, abs=1e-12)
    assert np.allclose(a.end, [0, 10.001, 0], atol=1e-12)


def test_blending_modes():
    body = "G1 X10 F600\nY10\nG61\nX0\nY0\n"
    p = prog("G64 P0.1\n" + body)
    assert [m.blend_mm for m in p.moves] == [0.1, 0.1, None, None]
    path = program_path(p)
    # the first corner (10,0) is blended within 0.1 mm; (10,10) was programmed under G64 P0.1
    # too; the G61 corner (0,10) stays an exact stop.
    assert len(path.corners()) == 1
    assert np.allclose(path.point(path.corners()), [[0, 10, 0]])
    d = np.linalg.norm(path.sample(0.001)[1] - [10, 0, 0], axis=1).min()
    assert d == pytest.approx(0.1, abs=1e-6)
    assert math.isinf(prog("G64\n" + body).moves[0].blend_mm)
    assert math.isinf(prog("G64 P0\n" + body).moves[0].blend_mm)
    assert prog("G61.1\n" + body).moves[0].blend_mm is None


def test_start_option_and_file(tmp_path):
    p = parse_gcode("G1 X1 F60\n", "s.ngc", start=[0, 0, -200])
    assert np.allclose(p.moves[0].segment.start, [0, 0, -200])
    f = tmp_path / "a.ngc"
    f.write_text(START + "G1 X5 F60\nG1 Y5\n")
    path = load_path(f)
    assert path.length == pytest.approx(10 - 2 * 2.5 + 2.5 * math.pi / 2)   # G64 default: room-limited blend
    assert list(path.line_at([0.1, path.length])) == [3, 4]


@pytest.mark.parametrize("body, line, words", [
    ("G1 X1 F60\nG41 D1\n", 4, "G41 (cutter radius compensation) is not supported"),
    ("G1 X1 F60\nA5\n", 4, "A axis word"),
    ("G1 X1 X2 F60\n", 3, "X word given twice"),
    ("G0 G1 X1 F60\n", 3, "are in the same modal group"),
    ("G17 G18\n", 3, "are in the same modal group"),
    ("G20 G21\n", 3, "are in the same modal group"),
    ("G90 G91\n", 3, "are in the same modal group"),
    ("G61 G64\n", 3, "are in the same modal group"),
    ("G1 X1\n", 3, "zero feed rate: give F"),
    ("G2 X1 Y1 I1\n", 3, "zero feed rate: give F"),
    ("G1 X1 F-1\n", 3, "negative feed rate F-1"),
    ("G1 X1 I1 F60\n", 3, "I word on a G1"),
    ("G2 X2 Y0 I1 R1 F60\n", 3, "R and I/J/K"),
    ("G2 X2 Y0 F60\n", 3, "needs I/J/K"),
    ("G2 X2 Y0 K1 F60\n", 3, "K word for an arc in the G17 plane"),
    ("G2 X10 Y0 I1 J0 F60\n", 3, "radius to end"),
    ("G2 X10 Y0 R2 F60\n", 3, "too small"),
    ("G2 X0 Y0 R2 F60\n", 3, "full circle needs I/J/K"),
    ("G2 X0 Y0 I1 P1.5 F60\n", 3, "(turns) must be an integer"),
    ("G1 X1 F60 P2\n", 3, "P word with no code on the line that uses it"),
    ("G64 P-1\n", 3, "G64 P and Q must be"),
    ("G1 X1 F60 (open\n", 3, "unclosed comment"),
    ("G1 X1 F60 (a (b) c)\n", 3, "nested comment"),
    ("G1 X1 F60 )\n", 3, "')' without '('"),
    ("G1 X1 F60 #1\n", 3, "a parameter on its own"),
    ("I5\n", 3, "I word with no code on the line that uses it"),
    ("G1 X1 N7 F60\n", 3, "N word not at the start of the line"),
])
def test_errors_name_file_and_line(body, line, words):
    with pytest.raises(GCodeError) as e:
        prog(body)
    assert e.value.file == "t.ngc" and e.value.line == line
    assert words in e.value.message and str(e.value).startswith(f"t.ngc:{line}: ")


def test_start_errors_and_empty_program(tmp_path):
    with pytest.raises(GCodeError, match="first move must be an absolute"):
        parse_gcode("G1 X1 Y1 F60\n", "a.ngc")
    with pytest.raises(GCodeError, match="no motion mode"):
        parse_gcode("X1 Y2 Z3\n", "a.ngc")
    with pytest.raises(EmptyProgram, match="nothing to plan: the program makes no move"):
        parse_gcode("G21\n(no motion)\nM2\n", "a.ngc")
    # a positioning move alone is a move (test_one_move_program_is_a_move_from_home)
    with pytest.raises(GCodeError, match="only move positions the tool"):
        parse_gcode("G21\nG0 X0 Y0 Z0\nM2\n", "a.ngc")
    with pytest.raises(GCodeError, match="cannot read G-code file"):
        read_gcode(tmp_path / "missing.ngc")
    assert issubclass(GCodeError, PathError)


def test_standard_test_part():
    p = read_gcode(__import__("kins.resources").resources.PATH_DIR / "test_part.ngc")
    kinds = [m.segment.kind for m in p.moves]
    assert kinds.count("arc") == 2 and len(p.moves) == 25
    circ = [m.segment for m in p.moves if m.segment.kind == "arc"]
    assert all(c.radius == pytest.approx(12.5) and c.angle == pytest.approx(2 * math.pi) for c in circ)


def test_write_read_round_trip(tmp_path):
    from planners.paths.gcode import write_gcode
    from planners.paths import resolve_path
    from kins.resources import PATH_DIR
    from planners.paths import SegmentPath
    # the part's programmed moves, unblended (its blend arcs lie in tilted planes: G-code
    # cannot express those), written under G61 and read back
    part = SegmentPath(read_gcode(PATH_DIR / "test_part.ngc").segments())
    f = tmp_path / "rt.ngc"
    write_gcode(part, f, 20.0, blend_mm=None, comment="round trip (G61)")
    back = load_path(f)
    assert len(back.segments) == len(part.segments)
    assert back.length == pytest.approx(part.length, abs=1e-4)
    s = np.linspace(0, part.length, 2001)
    assert np.abs(back.point(s * back.length / part.length) - part.point(s)).max() < 1e-4
    assert np.allclose(back.corners(), part.corners(), atol=1e-4)
    vertical = SegmentPath([Line([0, 0, 0], [10, 0, 0]),
                            Arc([10, 0, 0], [10, 0, 5], [0, 1, 0], math.pi / 2)])   # G18 arc
    write_gcode(vertical, f, 10.0)
    v = load_path(f)
    assert np.allclose(v.segments[-1].end, vertical.segments[-1].end, atol=1e-6)
    tilted = SegmentPath([Arc([1, 0, 0], [0, 0, 0], [0, 0.6, 0.8], 1.0)])
    with pytest.raises(GCodeError, match="not a coordinate axis"):
        write_gcode(tilted, f, 10.0)
    helix = resolve_path("helix")                        # 3 turns: written with P3
    write_gcode(helix, f, 100.0)
    h = load_path(f)
    assert h.segments[0].angle == pytest.approx(6 * math.pi) and h.length == pytest.approx(helix.length, rel=1e-9)


def test_latin1_comment_is_read_like_utf8(tmp_path):
    # "(pièce à 90°)" written by a Latin-1 editor: é, à, ° are single bytes that are not UTF-8
    body = "G21 G90 G61 (pi{e}ce {a} 90{d})\nG0 X0 Y0 Z0\nG1 X10 F600 ; r{e}glage\nG1 Y5\n"
    f_latin, f_utf = tmp_path / "l.ngc", tmp_path / "u.ngc"
    f_latin.write_bytes(body.format(e="\xe9", a="\xe0", d="\xb0").encode("latin-1"))
    f_utf.write_text(body.format(e="é", a="à", d="°"), encoding="utf-8")
    pl, pu = read_gcode(f_latin), read_gcode(f_utf)
    assert np.array_equal(ends(pl), ends(pu)) and [m.line for m in pl.moves] == [3, 4]
    assert "Latin-1" in pl.notes[0][1] and not any("Latin-1" in n for _, n in pu.notes)


def test_non_ascii_outside_a_comment_and_nul_name_their_line(tmp_path):
    f = tmp_path / "x.ngc"
    f.write_bytes(b"G0 X0 Y0 Z0\nG1 X\xe9 F600\n")
    with pytest.raises(GCodeError) as e:
        read_gcode(f)
    assert e.value.line == 2 and "cannot read" in e.value.message
    f.write_bytes(b"G0 X0 Y0 Z0\nG1 X1 F600\n\x00\x01")
    with pytest.raises(GCodeError) as e:
        read_gcode(f)
    assert e.value.line == 3 and "not a text file" in e.value.message


def test_one_move_program_is_a_move_from_home():
    text = "G21 G90\nG1 X3 Y4 Z-12 F600\nM2\n"
    p = parse_gcode(text, "t.ngc", home=[0.0, 0.0, 0.0])
    assert len(p.moves) == 1 and p.moves[0].line == 2 and not p.moves[0].rapid
    assert p.moves[0].segment.length == pytest.approx(13.0)            # 3-4-12 → 13
    assert np.allclose(p.start, 0.0) and np.allclose(p.moves[0].segment.end, [3, 4, -12])
    assert p.moves[0].feed_mm_s == pytest.approx(10.0)
    assert program_path(p).length == pytest.approx(13.0)
    # without a home the reader says what is missing, on the move's line (not "no moves")
    with pytest.raises(GCodeError) as e:
        parse_gcode(text, "t.ngc")
    assert e.value.line == 2 and "only move positions the tool" in e.value.message
    with pytest.raises(GCodeError) as e:
        parse_gcode(text, "t.ngc", home=[3, 4, -12])
    assert e.value.line == 2 and "already is" in e.value.message
    # a program with two moves is read as before: home does not change it
    two = "G0 X0 Y0 Z0\nG1 X1 F60\n"
    assert np.array_equal(ends(parse_gcode(two, "t", home=[5, 5, 5])), ends(parse_gcode(two, "t")))


def test_programmed_feeds_are_each_moves_f_capped_by_f_max_and_follow_the_feed_mode():
    """planners.feed.segment_feeds, kept on the path (toppra asked for it per piece, 10³ times
    on a long program): F per segment, rapids at F_max, a new F_max or the --max-feed mark
    read anew, and the kept array cannot be changed by a caller."""
    from planners.feed import feed_ceiling, segment_feeds, use_max_feed
    path = program_path(parse_gcode("G21 G90 G61\nG0 X0 Y0 Z-400\nG1 X10 F600\nG1 Y10 F1200\nG0 X0\n"))
    f = segment_feeds(path, 50.0)
    assert f.tolist() == [10.0, 20.0, 50.0] and segment_feeds(path, 50.0) is f
    assert segment_feeds(path, 15.0).tolist() == [10.0, 15.0, 15.0]
    assert feed_ceiling(path, [5.0, 15.0, 25.0], 15.0).tolist() == [10.0, 15.0, 15.0]
    with pytest.raises(ValueError):
        segment_feeds(path, 15.0)[0] = 1.0
    assert segment_feeds(use_max_feed(path), 50.0) is None
    assert segment_feeds(use_max_feed(path, False), 50.0).tolist() == [10.0, 20.0, 50.0]
