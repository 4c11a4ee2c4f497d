"""G64 Q (planners.paths.gcode.naivecam): LinuxCNC's canon joins runs of short G1 moves.
Reference: emccanon.cc see_segment / linkable / flush_segments / chord_deviation (2.9)."""
import math

import pytest

from planners.paths.gcode import read_gcode


def program(tmp_path, body, q=0.005, head="G21 G90 G17"):
    f = tmp_path / "q.ngc"
    f.write_text(f"{head} G64 P0.01 Q{q:g}\nG0 X0 Y0 Z-250\nF1200\n{body}M2\n")
    return read_gcode(f)


def jittered(n, step=0.1, jitter=0.001):
    return "".join(f"G1 X{step * k:.4f} Y{jitter * (-1) ** k:.4f}\n" for k in range(1, n + 1))


def test_a_line_within_q_is_joined_into_chains_of_101_points(tmp_path):
    # every point is within 2 µm of any chord: only linkable()'s cap of 100 chained points ends
    # a chain, so 300 moves are 101 + 101 + 98 points
    p = program(tmp_path, jittered(300))
    assert len(p.moves) == 3
    ends = [m.segment.end[0] for m in p.moves]
    assert ends == pytest.approx([10.1, 20.2, 30.0])
    # the joined line takes the last point's line number (flush_segments: pos.line_no)
    assert [m.line for m in p.moves] == [3 + 101, 3 + 202, 3 + 300]


def test_q0_and_g61_join_nothing(tmp_path):
    assert len(program(tmp_path, jittered(50), q=0).moves) == 50
    f = tmp_path / "g61.ngc"
    f.write_text("G21 G90 G61\nG0 X0 Y0 Z-250\nF1200\n" + jittered(50) + "M2\n")
    assert len(read_gcode(f).moves) == 50


def test_a_point_farther_than_q_ends_the_chain(tmp_path):
    # (0,0) → … → (2, 0) then a step 6 µm off the line from the chain's start: not linkable
    body = jittered(20, jitter=0.0) + "G1 X2.1 Y0.006\nG1 X2.2 Y0.012\n"
    p = program(tmp_path, body)
    assert [c for m in p.moves for c in m.segment.end[:2]] == pytest.approx([2.0, 0.0, 2.2, 0.012])


def test_an_m_code_or_a_new_feed_ends_the_chain_and_keeps_its_place(tmp_path):
    p = program(tmp_path, jittered(10) + "M8\n" + "".join(f"G1 X{1 + 0.1 * k:.4f}\n" for k in range(1, 6))
                + "G1 X1.6 F600\nG1 X1.7\n")
    assert len(p.moves) == 3 and p.moves[0].segment.end[0] == pytest.approx(1.0)
    m8 = [e for e in p.events if e.kind == "m" and e.value == 8]
    assert m8[0].index == 1                  # after the first joined line, as LinuxCNC's queue
    assert p.moves[1].segment.end[0] == pytest.approx(1.5) and p.moves[2].feed_mm_s == pytest.approx(10.0)


def test_a_flat_xy_arc_becomes_two_lines_through_its_midpoint(tmp_path):
    # r = 10, θ = 0.04 rad: sagitta 10·(1 − cos 0.02) = 2.0 µm < Q → midpoint and end points
    th = 0.04
    ex, ey = 10 * math.sin(th), 10 - 10 * math.cos(th)
    p = program(tmp_path, f"G1 X0 Y0 Z-250\nG3 X{ex:.6f} Y{ey:.6f} I0 J10\nG1 X{ex + 5:.6f} Y{ey:.6f}\n")
    kinds = [m.segment.kind for m in p.moves]
    assert "arc" not in kinds
    mid = (10 * math.sin(th / 2), 10 - 10 * math.cos(th / 2))
    # both points join one chain: the arc is one line from its start to its end here
    assert tuple(p.moves[0].segment.end[:2]) == pytest.approx((ex, ey), abs=1e-6)
    assert math.hypot(*mid) > 0 and len(p.moves) == 2
    # a larger arc (sagitta 0.5 mm) stays an arc
    q = program(tmp_path, "G1 X0 Y0 Z-250\nG3 X10 Y10 I0 J10\n")
    assert [m.segment.kind for m in q.moves] == ["arc"]


def test_an_f_or_g64_word_ends_the_chain_even_unchanged_but_a_comment_does_not(tmp_path):
    # rs274 enqueues SET_FEED_RATE for every F word and SET_MOTION_CONTROL_MODE for every G64
    # (both flush_segments() in emccanon.cc); COMMENT and SELECT_PLANE do not flush
    line = "".join(f"G1 X{0.1 * k:.4f}\n" for k in range(1, 11))
    more = "".join(f"G1 X{1 + 0.1 * k:.4f}\n" for k in range(1, 11))
    assert len(program(tmp_path, line + "(a comment)\nG17\n" + more).moves) == 1
    assert len(program(tmp_path, line + "F1200\n" + more).moves) == 2
    assert len(program(tmp_path, line + "G64 P0.01 Q0.005\n" + more).moves) == 2
    assert len(program(tmp_path, line + "S1000\n" + more).moves) == 2


def test_the_positioning_first_move_is_never_joined(tmp_path):
    # without start=, a first absolute G1 only positions the tool (its start is unknown): the
    # chain starts after it, so the first segment is the next move, not a join through it
    f = tmp_path / "pos.ngc"
    f.write_text("G21 G90 G64 P0.01\nG1 X-20 Y-20 Z-250 F1200\nX20\nY20\nM2\n")
    p = read_gcode(f)
    assert [m.segment.start[:2].tolist() for m in p.moves] == [[-20.0, -20.0], [20.0, -20.0]]
