"""--reader linuxcnc (planners.paths.gcode.rs274.linuxcnc_reader): LinuxCNC's own interpreter as front end.
The two readers must give the same program, move for move: the geometry to 1e-9 mm (LinuxCNC's
module reports inches), the same lines, feeds, blend tolerances, G64 Q joins, stops and events.
Skips where LinuxCNC is not installed (make linuxcnc)."""
import math
from pathlib import Path

import numpy as np
import pytest

from planners.paths.gcode import GCodeError, read_gcode
from planners.paths.gcode.rs274.reference import available

WHY = available()
pytestmark = pytest.mark.skipif(WHY is not None, reason=str(WHY))
ROOT = Path(__file__).resolve().parents[1]
PROGRAMS = ([ROOT / "benchmarks/paths/test_part.ngc"] + sorted((ROOT / "benchmarks/oracle/programs").glob("*.ngc"))
            + sorted((ROOT / "benchmarks/paths/corpus").glob("*.ngc"))
            + sorted((ROOT / "benchmarks/paths/programs/linuxcnc/circular-arcs/quick-tests").glob("*.ngc"))[::4])
HOME = (0.0, 0.0, -200.0)


def same_program(a, b):
    assert len(a.moves) == len(b.moves)
    for x, y in zip(a.moves, b.moves):
        for p, q in ((x.segment.start, y.segment.start), (x.segment.end, y.segment.end)):
            assert np.abs(np.asarray(p) - np.asarray(q)).max() <= 1e-9, (x.line, p, q)
        assert (x.line, x.rapid, x.blend_mm, x.stop, x.segment.kind) == (y.line, y.rapid, y.blend_mm, y.stop, y.segment.kind)
        assert (x.feed_mm_s is None) == (y.feed_mm_s is None)
        if x.feed_mm_s is not None:
            assert y.feed_mm_s == pytest.approx(x.feed_mm_s, rel=1e-12)
    # M2 and M30 are one canon call (PROGRAM_END): the same stop
    ev = lambda p: [(e.kind, 2 if e.value == 30 else e.value, e.index) for e in p.events]  # noqa: E731
    assert ev(a) == ev(b)


@pytest.mark.parametrize("file", PROGRAMS, ids=lambda p: p.name)
def test_both_readers_give_the_same_program(file):
    same_program(read_gcode(file, home=HOME), read_gcode(file, home=HOME, reader="linuxcnc"))


def test_start_and_home_rules_are_the_built_in_readers(tmp_path):
    f = tmp_path / "one.ngc"
    f.write_text("G21 G91\nG1 X10 Y5 F600\nG1 Z-3\nM2\n")       # relative: runs from where the tool is
    for kw in ({"home": HOME}, {"start": (1.0, 2.0, -250.0)}):
        a, b = read_gcode(f, **kw), read_gcode(f, reader="linuxcnc", **kw)
        same_program(a, b)
    assert read_gcode(f, start=(1.0, 2.0, -250.0), reader="linuxcnc").moves[-1].segment.end == pytest.approx([11, 7, -253])
    with pytest.raises(GCodeError, match="the first move must be an absolute"):
        read_gcode(f, reader="linuxcnc")


def test_a_program_linuxcnc_refuses_names_its_line(tmp_path):
    f = tmp_path / "bad.ngc"
    f.write_text("G21 G90\nG0 X0 Y0 Z-200\nG1 X[1/0] F100\nM2\n")
    with pytest.raises(GCodeError) as e:
        read_gcode(f, reader="linuxcnc")
    assert e.value.line == 3 and "LinuxCNC" in e.value.message


SPIRALS = ("G21 G90 G17 G61\nG0 X10 Y0 Z-200\nG2 X20.014 Y0 I5 J0 F600\n"          # r 5 → 5.014
           "G3 X30 Y0 I5 J0.3\nG20 G1 X1.3\nG2 X1.4 Y-.1 I.0503535 J-.05\nM2\n")    # inches, as arc-with-spiral.ngc


def test_spiral_arcs_keep_linuxcncs_centre_in_both_readers(tmp_path):
    """An I/J arc whose end radius differs: LinuxCNC's gcode module gives its centre and end
    (ARC_FEED); both readers keep that centre, and the segment's radius is r0 + (r1 − r0)·φ/θ at
    each point's angle φ, to 1e-9 mm."""
    from planners.paths.gcode.rs274.reference import linuxcnc_moves
    f = tmp_path / "spirals.ngc"
    f.write_text(SPIRALS)
    ref = [m for m in linuxcnc_moves(f)[0] if m["kind"] == "arc"]
    ours, theirs = read_gcode(f, home=HOME), read_gcode(f, home=HOME, reader="linuxcnc")
    same_program(ours, theirs)
    arcs = [[m.segment for m in p.moves if m.segment.kind == "arc"] for p in (ours, theirs)]
    assert len(ref) == len(arcs[0]) == len(arcs[1]) == 3
    for r, a, b in zip(ref, *arcs):
        assert np.abs(a.center[:2] - r["center"][:2]).max() <= 1e-9
        assert abs(a.spiral - b.spiral) <= 1e-9 and np.abs(a.center - b.center).max() <= 1e-9
        r0 = float(np.hypot(*(a.start - a.center)[:2]))
        r1 = float(np.hypot(*(np.asarray(r["end"]) - a.center)[:2]))
        assert abs(r1 - r0) > 1e-3 and a.spiral == pytest.approx(r1 - r0, abs=1e-12)
        P = a.eval(np.linspace(0, a.length, 1001), 0)[0] - a.center
        turn = float(a.normal[2])                      # +1: G3, −1: G2
        a0 = math.atan2(*(a.start - a.center)[1::-1])
        phi = turn * np.unwrap(np.arctan2(P[:, 1], P[:, 0]) - a0)
        assert np.abs(np.hypot(P[:, 0], P[:, 1]) - (r0 + (r1 - r0) * phi / a.angle)).max() <= 1e-9
        assert np.abs(a.end - r["end"]).max() <= 1e-9
