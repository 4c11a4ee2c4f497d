"""G-code → line/arc segments, each tagged with its source line.

The program runs through :mod:`planners.paths.gcode.rs274`, an RS274NGC interpreter with LinuxCNC 2.9's
semantics (expressions, parameters, O-words, work offsets, G92, tool length offsets, G28/G30,
G53, polar @ ^, M70–M73, canned cycles, probing, …; what it does not support is refused naming
the construct and the line). Its canonical moves (machine coordinates, mm) become Line/Arc segments here;
zero-length moves are dropped as LinuxCNC's canon drops them. Errors are
:class:`GCodeError` (file, line, message). See :func:`parse_gcode` for the start point.

Corners: the path-control mode in force when a move is read governs the corner at its end
(LinuxCNC's term_cond): G61/G61.1 → exact stop; G64 P p → blended within p mm;
G64 without P (or P0) → LinuxCNC's "best possible speed": blended with no tolerance other
than the room available (half of each adjoining segment); the ``trapezoid`` planner re-blends
the program as LinuxCNC's tp does instead (planners.trapezoid.queue). G64 … Q q joins runs of short moves that stay within q
of one line into that line first, as LinuxCNC's canon does (:mod:`.naivecam`). Blending is done by
:mod:`planners.paths.blend`, the one module all planners share. The default mode is G64 (as in
LinuxCNC).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path as FsPath

import numpy as np

from planners.paths.base import PathError, gc_paused
from planners.paths.blend import blend_corners
from planners.paths.gcode.naivecam import join_moves
from planners.paths.gcode.rs274 import RS274Error, interpret
from planners.paths.gcode.rs274.linuxcnc_reader import linuxcnc_canon
from planners.paths.segments import Arc, Line, SegmentPath

INCH_MM = 25.4
ZERO_MOVE_MM = 1e-9

# plane → (first in-plane axis, second in-plane axis, normal axis); right-handed, so
# G3 turns counter-clockwise about +normal (RS274/NGC: G18 is viewed from +Y: Z then X).
_PLANES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}


class GCodeError(PathError):
    """A G-code problem: ``file``, ``line`` (1-based) and ``message``."""

    def __init__(self, file: str, line: int, message: str):
        super().__init__(f"{file}:{line}: {message}")
        self.file, self.line, self.message = file, line, message


class EmptyProgram(GCodeError):
    """A program that makes no move (a subroutine library, a setup file): nothing to plan; the
    checker reads it as nothing to check."""


@dataclass
class Move:
    segment: Line | Arc
    line: int                      # source line number (1-based)
    rapid: bool                    # G0
    feed_mm_s: float | None        # programmed feed (None for G0)
    blend_mm: float | None         # corner at the END: None = exact stop, inf = no tolerance
    # LinuxCNC stops at the end of this move although G64 is in force: "sync" (an M code, a
    # dwell or a tool change follows: task waits for the motion queue to drain), "mode" (rapid ↔
    # feed: tp.c handleModeChange never blends them) or "end"; None otherwise
    stop: str | None = None
    parabolic_end: bool = False    # G64 end with nothing to blend with (tc.c: half acceleration)
    # the path-control mode in force (planners.paths.gcode.rs274 CanonMove.path_mode), kept when
    # ``blend_mm`` becomes None at a stop: LinuxCNC's term_cond and tolerance of the move
    path_mode: tuple = ("exact", "stop")


# M codes that only change the interpreter's state (M70–M73 save/restore modal state): no sync
_STATELESS_M = {70, 71, 72, 73}


# M codes task does not wait for motion at: the stateless ones, the program end, and M62/M63,
# which set an output with the next move (emccanon.cc SET_MOTION_OUTPUT_BIT: EMC_MOTION_SET_DOUT,
# now = 0); M64/M65 set it now and wait
_NO_SYNC_M = _STATELESS_M | {2, 30, 62, 63}


def is_sync(e) -> bool:
    """Whether LinuxCNC's task waits for the motion queue to drain before event ``e``
    (emctaskmain.cc emcTaskCheckPreconditions: WAITING_FOR_MOTION_AND_IO for a dwell, a spindle
    speed, spindle, coolant or tool message, a program stop, a probe, an operator message;
    WAITING_FOR_MOTION for an output set now)."""
    return e.kind in ("dwell", "tool", "probe", "speed", "message") or \
        (e.kind == "m" and e.value not in _NO_SYNC_M)


@dataclass
class GCodeProgram:
    source: str
    start: np.ndarray
    moves: list[Move] = field(default_factory=list)
    notes: list[tuple[int, str]] = field(default_factory=list)
    events: list = field(default_factory=list)   # rs274 CanonEvent: M codes, dwells, tool changes (line, index)
    setup: object = None           # rs274 Setup: tool table, var file, offsets it was read with

    def segments(self):
        return [m.segment for m in self.moves]

    def blend_tolerances(self):
        """Tolerance of each corner between consecutive moves (None = exact stop)."""
        return [m.blend_mm for m in self.moves[:-1]]


def strip_comments(text: str, src: str, ln: int) -> str:
    if "(" not in text and ")" not in text and ";" not in text:
        return text                     # most lines of a CAM program: nothing to strip
    out, i = [], 0
    while i < len(text):
        c = text[i]
        if c == "(":
            j = text.find(")", i + 1)
            if j < 0:
                raise GCodeError(src, ln, "unclosed comment '('")
            if "(" in text[i + 1:j]:
                raise GCodeError(src, ln, "nested comment '(' inside '( … )'")
            i = j + 1
            out.append(" ")
        elif c == ";":
            break
        elif c == ")":
            raise GCodeError(src, ln, "')' without '('")
        else:
            out.append(c)
            i += 1
    return "".join(out)


READERS = ("pkmbench", "linuxcnc")


def parse_gcode(text: str, source: str = "<gcode>", start=None, home=None, *, tools=None,
                subroutine_path=(), block_delete: bool = False, max_loops: int | None = None,
                reader: str = "pkmbench", probe_surface=None, setup=None) -> GCodeProgram:
    """Read G-code text into moves (lines/arcs in mm, machine coordinates, each with its line).

    The text runs through the RS274NGC interpreter (:mod:`planners.paths.gcode.rs274`, LinuxCNC's semantics);
    its canonical moves become segments here. Start point:

    - ``start`` given: LinuxCNC's rule: the tool is there, every move is a segment from it;
    - else, when the first move gives X, Y and Z absolutely, it positions the tool (no segment:
      the standard paths' convention, so they plan as before); a program whose only move is
      that one is planned from ``home``;
    - else the program starts from ``home`` (the machine's position), as LinuxCNC would.

    Zero-length moves are dropped (a note; an M code on their line still counts: ``events``).
    A program with no move at all raises :class:`EmptyProgram`. ``probe_surface``: what G38.x
    probes touch (a height in machine mm, or a function f(x, y) → z; see rs274's Interpreter).
    ``reader="linuxcnc"``: LinuxCNC's own interpreter reads the file ``source`` instead
    (planners.paths.gcode.rs274.linuxcnc_reader; ``text`` is not used, nor tools, subroutine path, block delete).
    ``setup``: the machine's tool table, var file and work offsets at the start
    (planners.paths.gcode.rs274.setup.Setup; kept on the program for the ``linuxcnc`` planner).
    """
    opts = dict(tools=tools, subroutine_path=subroutine_path, block_delete=block_delete, probe_surface=probe_surface,
                setup=setup)
    if max_loops is not None:
        opts["max_loops"] = max_loops
    if reader == "linuxcnc":
        if setup:
            raise GCodeError(source, 0, "--reader linuxcnc does not take a tool table, var file or offset; "
                                        "use the built-in reader (it is checked against LinuxCNC's with them)")
        try:
            cp, positioning = linuxcnc_canon(source, start, home)
        except RS274Error as e:
            raise GCodeError(e.file, _refused_line(e, text, source, start, home, opts), e.message) from None
    elif reader == "pkmbench":
        cp, positioning = _interpret(text, source, start, home, opts)
    else:
        raise GCodeError(source, 0, f"unknown G-code reader {reader!r}; valid: {', '.join(READERS)}")
    # G64 Q: runs of short moves joined into lines, as LinuxCNC's canon joins them
    canon, canon_events = join_moves(cp.moves, cp.events, _STATELESS_M, cp.flushes)
    prog = GCodeProgram(source, None, setup=setup or None)
    prog.notes += cp.notes
    first = 0
    if positioning and canon:
        m0 = canon[0]
        prog.start = np.array(m0.end, float)
        prog.notes.append((m0.line, f"start point {prog.start.tolist()} (positioning move, no segment)"))
        first = 1
    else:
        prog.start = np.array(cp.start, float)
    made = _segments(prog, canon, first)
    # an event's index: the segments before it (LinuxCNC stops there for an M code)
    prog.events = [replace(e, index=made[e.index]) for e in canon_events]
    if not prog.moves and positioning and canon:
        _only_move_from_home(prog, canon[0], home)
    if not prog.moves:
        raise EmptyProgram(source, 0, "nothing to plan: the program makes no move (a subroutine library "
                                      "or a setup file?)")
    for e in prog.events:
        syncs = is_sync(e)
        # a sync outranks a rapid <-> feed stop: the queue drains there before the next move
        # comes, so tp.c never sees the mode change (handleModeChange) while the move runs
        if syncs and 0 < e.index <= len(prog.moves) and prog.moves[e.index - 1].stop in (None, "mode"):
            _stop(prog.moves[e.index - 1], "sync")
    if prog.moves[-1].stop is None:
        _stop(prog.moves[-1], "end")
    return prog


def _refused_line(e, text: str, source: str, start, home, opts) -> int:
    """The line of a refusal by LinuxCNC's interpreter: its gcode module names the line after a
    read error (gcodemodule.cc error_line_offset), so the line our interpreter refuses, if it
    refuses the program too, else LinuxCNC's."""
    try:
        _interpret(text, source, start, home, opts)
    except GCodeError as ours:
        return ours.line
    return e.line


def _interpret(text: str, source: str, start, home, opts):
    """(canonical program, positioning?): the interpreter's run from ``start``; without one, from
    an unknown point (NaN) that the first move must set (positioning), else again from ``home``."""
    positioning = start is None
    at = start if start is not None else (math.nan,) * 3     # unknown: NaN marks it
    try:
        cp = interpret(text, source, start=at, **opts)
        if positioning and cp.moves and not (cp.moves[0].kind in ("rapid", "feed")
                                             and all(map(math.isfinite, cp.moves[0].end))):
            if home is None:
                ln = cp.moves[0].line
                raise GCodeError(source, ln, "the first move must be an absolute (G90) G0/G1 with X, Y and Z "
                                             "(it sets the start point) — or pass start= (the machine's position)")
            positioning = False
            cp = interpret(text, source, start=tuple(np.asarray(home, float)), **opts)
    except RS274Error as e:
        raise GCodeError(e.file, e.line, e.message) from None
    return cp, positioning


def _blend_of(path_mode) -> float | None:
    """A move's corner tolerance from its path mode: G61 → None, G64 P0 → inf, G64 P p → p."""
    return None if path_mode[0] == "exact" else (math.inf if path_mode[1] == 0 else path_mode[1])


def _segments(prog: GCodeProgram, canon: list, first: int) -> list[int]:
    """The canonical moves from ``first`` on as prog.moves (zero-length ones dropped, a rapid↔feed
    change an exact stop); returns the number of moves made before each canonical move."""
    pos = prog.start.copy()
    made = [0] * (len(canon) + 1)
    for k, cm in enumerate(canon[first:], start=first):
        made[k] = len(prog.moves)
        # math on the three floats: numpy's per-call overhead was most of this loop (10⁵ moves)
        if not all(map(math.isfinite, cm.end)):
            raise GCodeError(cm.file, cm.line, "the position is unknown here (pass start=, the machine's position)")
        end = np.array(cm.end, float)
        ln = cm.line
        feed = None if cm.kind == "rapid" else cm.feed_mm_min / 60.0
        if cm.kind == "arc":
            seg = _arc(cm, pos, end)
        else:
            if math.dist(cm.end, pos) <= ZERO_MOVE_MM:
                prog.notes.append((ln, "zero-length move dropped (as LinuxCNC's canon drops it)"))
                continue
            seg = Line(pos, end, ln, f"{cm.file}:{ln}")
        if prog.moves and prog.moves[-1].rapid != (cm.kind == "rapid") and prog.moves[-1].stop is None:
            prog.moves[-1].stop = "mode"      # tp.c handleModeChange: exact stop, full acceleration
            prog.moves[-1].blend_mm = None
        prog.moves.append(Move(seg, ln, cm.kind == "rapid", feed, _blend_of(cm.path_mode), path_mode=cm.path_mode))
        # after an arc, the next segment starts where the arc's geometry ends (within ~1e-15
        # of the programmed end): segments chain exactly, and the standard paths plan as before
        pos = seg.end.copy() if cm.kind == "arc" else end
    made[len(canon)] = len(prog.moves)
    return made


def _only_move_from_home(prog: GCodeProgram, m0, home) -> None:
    """A program whose only move positions the tool: that move, planned from ``home``."""
    source = prog.source
    if home is None:
        raise GCodeError(source, m0.line, "the program's only move positions the tool: nothing to plan "
                                          "without the point it starts from (pass home=)")
    home = np.asarray(home, float)
    if np.linalg.norm(prog.start - home) <= ZERO_MOVE_MM:
        raise GCodeError(source, m0.line, f"the program's only move goes to {home.tolist()}, where the tool "
                                          "already is: nothing to plan")
    target, prog.start = prog.start, home.copy()
    prog.notes.append((m0.line, f"the only move: planned from home {home.tolist()}"))
    prog.moves.append(Move(Line(home, target, m0.line, f"{source}:{m0.line}"), m0.line, m0.kind == "rapid",
                           None if m0.kind == "rapid" else m0.feed_mm_min / 60.0, _blend_of(m0.path_mode),
                           path_mode=m0.path_mode))


def _stop(move: Move, why: str) -> None:
    """The motion queue ends after ``move`` (a sync or the program end): under G64 LinuxCNC
    leaves its term_cond PARABOLIC, so it runs at half acceleration (tc.c
    tcGetOverallMaxAccel) and stops at its end."""
    move.parabolic_end = move.path_mode[0] == "blend"
    move.stop = why
    move.blend_mm = None


def _arc(cm, pos, end) -> Arc:
    """An ARC_FEED as a segment. LinuxCNC keeps the programmed centre and, when the radius to
    the end differs from the radius to the start (within interp_arc.cc's tolerance), moves on a
    spiral whose radius changes linearly with the angle (posemath pmCircleInit/pmCirclePoint):
    so does the segment (Arc's ``spiral`` = r_end − r_start). A difference of 1e-12 mm or less
    is rounding: a circle."""
    src, ln = cm.file, cm.line
    i1, i2, iax = _PLANES[cm.plane]
    axis = np.zeros(3)
    axis[iax] = 1.0
    n = axis if cm.turn > 0 else -axis
    c = np.array(cm.center, float)
    st2, en2 = np.array([pos[i1], pos[i2]]), np.array([end[i1], end[i2]])
    c2 = np.array([c[i1], c[i2]])
    r0, r1 = np.linalg.norm(st2 - c2), np.linalg.norm(en2 - c2)
    spiral = float(r1 - r0) if abs(r1 - r0) > 1e-12 else 0.0
    a2, b2 = st2 - c2, en2 - c2
    s = 1.0 if cm.turn > 0 else -1.0       # counter-clockwise angle about n
    cross = a2[0] * b2[1] - a2[1] * b2[0]
    theta = math.atan2(s * cross, float(np.dot(a2, b2)))
    if theta <= 1e-12:
        theta += 2 * math.pi                # end = start: full circle
    theta += 2 * math.pi * (abs(cm.turn) - 1)
    center = pos.copy()
    center[i1], center[i2] = c2
    rise = float((end[iax] - pos[iax]) * n[iax])
    try:
        return Arc(pos, center, n, theta, rise, ln, f"{src}:{ln}", spiral=spiral)
    except PathError as e:
        raise GCodeError(src, ln, str(e)) from None


def read_gcode(file, start=None, home=None, **options) -> GCodeProgram:
    file = FsPath(file)
    try:
        data = file.read_bytes()
    except OSError as e:
        raise GCodeError(str(file), 0, f"cannot read G-code file: {e.strerror}") from None
    if b"\0" in data:
        raise GCodeError(str(file), data[:data.index(b"\0")].count(b"\n") + 1, "not a text file (NUL byte)")
    try:
        text = data.decode("utf-8")
        latin1 = False
    except UnicodeDecodeError:
        # CAM posts and old editors write Latin-1 comments (é, °, µ); LinuxCNC reads them:
        # every byte is a Latin-1 character, and the G-code words themselves are ASCII
        text, latin1 = data.decode("latin-1"), True
    with gc_paused():
        prog = parse_gcode(text, str(file), start, home, **options)
    if latin1:
        prog.notes.insert(0, (0, "not UTF-8: read as Latin-1"))
    return prog


def program_path(prog: GCodeProgram, *, deferred: bool = False) -> SegmentPath:
    """The blended path of a program (G61 corners kept sharp, G64 corners rounded: the
    largest arc its tolerance and half of each line allow).

    ``deferred``: blend on the first use of the geometry (``program`` and ``source`` are there
    at once): a planner that re-blends the program as LinuxCNC does (trapezoid) never pays
    for these blends, seconds on a 10⁵-line program."""
    if deferred:
        return _DeferredProgramPath(prog)
    with gc_paused():
        return SegmentPath(_blended_segments(prog), prog.source, program=prog)


def _blended_segments(prog: GCodeProgram) -> list:
    return blend_corners(prog.segments(), prog.blend_tolerances())[0]


class _DeferredProgramPath(SegmentPath):
    """program_path(prog), built when an attribute of the geometry is first read."""

    def __init__(self, prog: GCodeProgram):
        self.program, self.source, self._pending = prog, prog.source, True

    def __getattr__(self, name):
        # only reached for an attribute not set yet, i.e. one that SegmentPath.__init__ sets
        d = self.__dict__
        if name.startswith("__") or not d.get("_pending"):
            raise AttributeError(f"{type(self).__name__} has no attribute {name!r}")
        d["_pending"] = False
        try:
            with gc_paused():
                SegmentPath.__init__(self, _blended_segments(self.program), self.source, program=self.program)
        except BaseException:
            d["_pending"] = True           # a blend error is raised again on the next read
            raise
        return getattr(self, name)


def load_gcode_path(file, start=None, **options) -> SegmentPath:
    """The blended path of a G-code file (options: home, tools, subroutine_path, block_delete)."""
    return program_path(read_gcode(file, start, **options))
