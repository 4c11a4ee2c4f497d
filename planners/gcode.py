"""RS274/NGC subset reader: G-code → line/arc segments, each tagged with its source line.

Supported (LinuxCNC semantics): G0 G1 G2 G3 (I/J/K offsets — always incremental — or R,
full circles, helices, P = number of turns), G17/G18/G19, G20/G21, G90/G91, G61/G61.1/G64 P,
F (units per minute), N numbers, ``( … )`` and ``;`` comments, ``%`` lines. Modal words are
kept from line to line. G40, G80, M codes, S and T are accepted and ignored with a note;
M2/M30 end the program. Unknown words, a letter given twice, two G words of one modal
group, R together with I/J/K, a feed move without F, an arc whose end radius disagrees
with its start radius, and zero-length moves are errors (:class:`GCodeError`, carrying the
file, the line number and the message).

Start point: the program does not know where the tool is, so the first motion must be an
absolute (G90) G0/G1 giving X, Y and Z; it positions the tool (no segment is made, a note
says so) unless a ``start`` point is passed.

Corners: the path-control mode in force when a move is read governs the corner at its end
(LinuxCNC's term_cond): G61/G61.1 → exact stop; G64 P p → blended within p mm;
G64 without P (or P0) → LinuxCNC's "best possible speed": blended with no tolerance other
than the room available (half of each adjoining segment). Blending is done by
:mod:`planners.blend`, the one module all planners share. The default mode is G64 (as in
LinuxCNC).
"""
from __future__ import annotations

import gc
import math
import re
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path as FsPath

import numpy as np

from planners.path import Arc, Line, PathError, SegmentPath

INCH_MM = 25.4
ARC_RADIUS_ABS_TOL = 0.002     # mm (LinuxCNC rs274ngc: radius mismatch tolerances, abs …
ARC_RADIUS_REL_TOL = 0.001     # … and relative; an arc is rejected if it breaks both)
ZERO_MOVE_MM = 1e-9

_WORD = re.compile(r"([A-Za-z])\s*([+-]?\s*(?:\d+\.?\d*|\.\d+))")
# a line made of words and blanks only (the common case): read with one findall
_WORD_ALL = re.compile(r"(([A-Za-z])\s*([+-]?\s*(?:\d+\.?\d*|\.\d+)))")
_LINE = re.compile(r"(?:\s*[A-Za-z]\s*[+-]?\s*(?:\d+\.?\d*|\.\d+))*\s*")
_GROUPS = {  # modal groups of the G words we accept
    0.0: "motion", 1.0: "motion", 2.0: "motion", 3.0: "motion", 80.0: "motion",
    17.0: "plane", 18.0: "plane", 19.0: "plane",
    20.0: "units", 21.0: "units",
    90.0: "distance", 91.0: "distance",
    61.0: "path", 61.1: "path", 64.0: "path",
    40.0: "cutter",
}
# plane → (first in-plane axis, second in-plane axis, normal axis); right-handed, so
# G3 turns counter-clockwise about +normal (RS274/NGC: G18 is viewed from +Y: Z then X).
_PLANES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}
_OFFSET_LETTER = {0: "I", 1: "J", 2: "K"}


class GCodeError(PathError):
    """A G-code problem: ``file``, ``line`` (1-based) and ``message``."""

    def __init__(self, file: str, line: int, message: str):
        super().__init__(f"{file}:{line}: {message}")
        self.file, self.line, self.message = file, line, message


@dataclass
class Move:
    segment: Line | Arc
    line: int                      # source line number (1-based)
    rapid: bool                    # G0
    feed_mm_s: float | None        # programmed feed (None for G0)
    blend_mm: float | None         # corner at the END: None = exact stop, inf = no tolerance


@dataclass
class GCodeProgram:
    source: str
    start: np.ndarray
    moves: list[Move] = field(default_factory=list)
    notes: list[tuple[int, str]] = field(default_factory=list)

    def segments(self):
        return [m.segment for m in self.moves]

    def blend_tolerances(self):
        """Tolerance of each corner between consecutive moves (None = exact stop)."""
        return [m.blend_mm for m in self.moves[:-1]]


def _strip_comments(text: str, src: str, ln: int) -> str:
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


def _words(body: str, src: str, ln: int) -> list[tuple[str, float, str]]:
    if _LINE.fullmatch(body):
        return [(L.upper(), float(v.replace(" ", "")), w) for w, L, v in _WORD_ALL.findall(body)]
    words, pos = [], 0
    for m in _WORD.finditer(body):
        gap = body[pos:m.start()]
        if gap.strip():
            raise GCodeError(src, ln, f"cannot read {gap.strip()!r}")
        words.append((m.group(1).upper(), float(m.group(2).replace(" ", "")), m.group(0).strip()))
        pos = m.end()
    rest = body[pos:]
    if rest.strip():
        raise GCodeError(src, ln, f"cannot read {rest.strip()!r}")
    return words


def parse_gcode(text: str, source: str = "<gcode>", start=None, home=None) -> GCodeProgram:
    """Read G-code text into moves (lines/arcs in mm, absolute, each with its line number).

    ``home``: where the tool is before a program whose only motion is its positioning move;
    that move is then the program (from ``home``), instead of leaving nothing to plan.
    """
    pos = None if start is None else np.asarray(start, float).copy()
    prog = GCodeProgram(source, None if pos is None else pos.copy())
    motion = None            # modal state, LinuxCNC defaults: G17 G21 G90 G64, no motion mode
    plane, unit, absolute = 17, 1.0, True
    blend: float | None = math.inf
    feed = None              # mm/s
    ended = False
    positioning = None       # (line, motion, feed, blend) of the move that set the start point
    for ln, raw in enumerate(text.splitlines(), start=1):
        body = _strip_comments(raw, source, ln).strip()
        if not body or body == "%":
            continue
        if ended:
            prog.notes.append((ln, "after M2/M30: ignored"))
            continue
        words = _words(body, source, ln)
        seen: dict[str, tuple[float, str]] = {}
        gwords: dict[str, float] = {}
        mwords: list[float] = []
        for letter, val, txt in words:
            if letter == "G":
                g = round(val, 1)
                if g not in _GROUPS:
                    raise GCodeError(source, ln, f"unsupported G code {txt}")
                grp = _GROUPS[g]
                if grp in gwords:
                    raise GCodeError(source, ln, f"G{gwords[grp]:g} and {txt} are in the same modal group ({grp})")
                gwords[grp] = g
            elif letter == "M":
                mwords.append(val)
            elif letter in "NXYZIJKRFPST":
                if letter in seen:
                    raise GCodeError(source, ln, f"{letter} word given twice ({seen[letter][1]} and {txt})")
                seen[letter] = (val, txt)
            else:
                raise GCodeError(source, ln, f"unsupported word {txt}")
        if "N" in seen and words[0][0] != "N":
            raise GCodeError(source, ln, f"line number {seen['N'][1]} must come first on the line")
        # -- ignored words ------------------------------------------------------------
        for letter in "ST":
            if letter in seen:
                prog.notes.append((ln, f"{seen[letter][1]} ignored (no spindle/tool in this benchmark)"))
        if "cutter" in gwords:
            prog.notes.append((ln, "G40 ignored (no cutter compensation)"))
        for mv in mwords:
            if mv in (2.0, 30.0):
                ended = True
                prog.notes.append((ln, f"M{mv:g}: end of program"))
            else:
                prog.notes.append((ln, f"M{mv:g} ignored"))
        # -- modal state ----------------------------------------------------------------
        if "units" in gwords:
            unit = INCH_MM if gwords["units"] == 20.0 else 1.0
        if "plane" in gwords:
            plane = int(gwords["plane"])
        if "distance" in gwords:
            absolute = gwords["distance"] == 90.0
        p_used = False
        if "path" in gwords:
            if gwords["path"] == 64.0:
                if "P" in seen:
                    p = seen["P"][0] * unit
                    if p < 0:
                        raise GCodeError(source, ln, f"G64 P must be ≥ 0, got {seen['P'][1]}")
                    blend = math.inf if p == 0 else p
                    p_used = True
                else:
                    blend = math.inf
            else:
                blend = None
        if "F" in seen:
            f = seen["F"][0]
            if not f > 0:
                raise GCodeError(source, ln, f"feed rate {seen['F'][1]} must be > 0")
            feed = f * unit / 60.0
        if "motion" in gwords:
            if gwords["motion"] == 80.0:
                prog.notes.append((ln, "G80 ignored (no canned cycles)"))
                motion = None
            else:
                motion = int(gwords["motion"])
        axes = [k for k in "XYZ" if k in seen]
        offs = [k for k in "IJK" if k in seen]
        if not axes:
            if offs or "R" in seen:
                raise GCodeError(source, ln, f"{(offs + ['R'])[0]} word without an axis word (X/Y/Z) to move to")
            if "P" in seen and not p_used:
                raise GCodeError(source, ln, f"{seen['P'][1]} has nothing to apply to (G64 P or G2/G3 P)")
            continue
        if motion is None:
            raise GCodeError(source, ln, "axis words with no motion mode in force (G0/G1/G2/G3)")
        if motion in (0, 1) and (offs or "R" in seen):
            raise GCodeError(source, ln, f"{(offs + ['R'])[0]} word on a G{motion} (straight) move")
        if "P" in seen and not p_used and motion not in (2, 3):
            raise GCodeError(source, ln, f"{seen['P'][1]} has nothing to apply to (G64 P or G2/G3 P)")
        # -- target -----------------------------------------------------------------
        if pos is None:
            if not absolute or motion not in (0, 1) or len(axes) < 3:
                raise GCodeError(source, ln, "the first move must be an absolute (G90) G0/G1 with X, Y and Z "
                                             "(it sets the start point) — or pass start=")
            pos = np.array([seen[k][0] * unit for k in "XYZ"])
            prog.start = pos.copy()
            prog.notes.append((ln, f"start point {pos.tolist()} (positioning move, no segment)"))
            positioning = (ln, motion, feed, blend)
            continue
        target = pos.copy()
        for k in axes:
            i = "XYZ".index(k)
            target[i] = seen[k][0] * unit if absolute else pos[i] + seen[k][0] * unit
        if motion in (0, 1):
            if np.linalg.norm(target - pos) <= ZERO_MOVE_MM:
                raise GCodeError(source, ln, f"zero-length move to {target.tolist()} (already there)")
            if motion == 1 and feed is None:
                raise GCodeError(source, ln, "G1 feed move with no feed rate: give F")
            seg = Line(pos, target, ln, f"{source}:{ln}")
        else:
            if feed is None:
                raise GCodeError(source, ln, f"G{motion} feed move with no feed rate: give F")
            seg = _arc(source, ln, motion, plane, pos, target, seen, unit)
        prog.moves.append(Move(seg, ln, motion == 0, None if motion == 0 else feed, blend))
        pos = seg.end.copy() if motion in (2, 3) else target
    if not prog.moves and positioning is not None:
        ln, motion, feed, blend = positioning
        if home is None:
            raise GCodeError(source, ln, "the program's only move positions the tool: nothing to plan "
                                         "without the point it starts from (pass home=)")
        home = np.asarray(home, float)
        if np.linalg.norm(prog.start - home) <= ZERO_MOVE_MM:
            raise GCodeError(source, ln, f"the program's only move goes to {home.tolist()}, where the tool "
                                         "already is: nothing to plan")
        target, prog.start = prog.start, home.copy()
        prog.notes.append((ln, f"the only move: planned from home {home.tolist()}"))
        prog.moves.append(Move(Line(home, target, ln, f"{source}:{ln}"), ln, motion == 0,
                               None if motion == 0 else feed, blend))
    if not prog.moves:
        raise GCodeError(source, 0, "empty path: the program has no feed or rapid moves")
    return prog


def _arc(src, ln, motion, plane, pos, target, seen, unit) -> Arc:
    i1, i2, iax = _PLANES[plane]
    axis = np.zeros(3)
    axis[iax] = 1.0
    n = axis if motion == 3 else -axis
    offs = [k for k in "IJK" if k in seen]
    allowed = {_OFFSET_LETTER[i1], _OFFSET_LETTER[i2]}
    wrong = [k for k in offs if k not in allowed]
    if wrong:
        raise GCodeError(src, ln, f"{wrong[0]} offset is not in the G{plane} plane (use {' and '.join(sorted(allowed))})")
    if "R" in seen and offs:
        raise GCodeError(src, ln, "R and I/J/K given together: use one arc form")
    st2 = np.array([pos[i1], pos[i2]])
    en2 = np.array([target[i1], target[i2]])
    chord = en2 - st2
    d = float(np.linalg.norm(chord))
    if "R" in seen:
        r = seen["R"][0] * unit
        if d <= ZERO_MOVE_MM:
            raise GCodeError(src, ln, "R-form arc with end = start: a full circle needs I/J/K")
        if abs(r) < d / 2 - ARC_RADIUS_ABS_TOL:
            raise GCodeError(src, ln, f"arc radius R{abs(r):g} mm is too small for the chord of {d:.6g} mm")
        h = math.sqrt(max(r * r - d * d / 4, 0.0))
        u = chord / d
        left = np.array([-u[1], u[0]])      # axis × u in the (first, second) plane axes
        sign = (1.0 if motion == 3 else -1.0) * (1.0 if r > 0 else -1.0)
        c2 = st2 + chord / 2 + sign * h * left
    elif offs:
        off = np.zeros(3)
        for k in offs:
            off["IJK".index(k)] = seen[k][0] * unit
        c2 = st2 + np.array([off[i1], off[i2]])
        r0, r1 = np.linalg.norm(st2 - c2), np.linalg.norm(en2 - c2)
        if abs(r1 - r0) > ARC_RADIUS_ABS_TOL and abs(r1 - r0) > ARC_RADIUS_REL_TOL * r0:
            raise GCodeError(src, ln, f"arc radius to end ({r1:.6g} mm) differs from radius to start "
                                      f"({r0:.6g} mm) by {abs(r1 - r0):.3g} mm")
        if d > ZERO_MOVE_MM:
            # Small mismatch: move the centre onto the chord's perpendicular bisector so the
            # arc ends exactly at the programmed point (the segment file needs contiguity).
            u = chord / d
            m = st2 + chord / 2
            perp = np.array([-u[1], u[0]])
            c2 = m + np.dot(c2 - m, perp) * perp
    else:
        raise GCodeError(src, ln, f"G{motion} arc needs I/J/K (centre offset) or R")
    a2, b2 = st2 - c2, en2 - c2
    if np.linalg.norm(a2) <= ZERO_MOVE_MM:
        raise GCodeError(src, ln, "arc radius is zero (centre at the start point)")
    s = 1.0 if motion == 3 else -1.0       # counter-clockwise angle about n
    cross = a2[0] * b2[1] - a2[1] * b2[0]
    theta = math.atan2(s * cross, float(np.dot(a2, b2)))
    if theta <= 1e-12:
        theta += 2 * math.pi                # end = start: full circle
    if "P" in seen:
        turns = seen["P"][0]
        if turns != int(turns) or turns < 1:
            raise GCodeError(src, ln, f"arc P (turns) must be an integer ≥ 1, got {seen['P'][1]}")
        theta += 2 * math.pi * (int(turns) - 1)
    center = pos.copy()
    center[i1], center[i2] = c2
    rise = float((target[iax] - pos[iax]) * n[iax])
    try:
        return Arc(pos, center, n, theta, rise, ln, f"{src}:{ln}")
    except PathError as e:
        raise GCodeError(src, ln, str(e)) from None


@contextmanager
def _gc_paused():
    """Pause the cyclic garbage collector while 10⁵ segment objects are built: its full
    passes over the growing object graph cost ~30 % of reading and blending a 10⁵-line
    program. Nothing is freed later than it would be but cycles (collected on resuming)."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


def read_gcode(file, start=None, home=None) -> GCodeProgram:
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
    with _gc_paused():
        prog = parse_gcode(text, str(file), start, home)
    if latin1:
        prog.notes.insert(0, (0, "not UTF-8: read as Latin-1"))
    return prog


def program_path(prog: GCodeProgram) -> SegmentPath:
    """The blended path of a program (G61 corners kept sharp, G64 corners rounded)."""
    from planners.blend import blend_corners
    with _gc_paused():
        segs, _ = blend_corners(prog.segments(), prog.blend_tolerances())
        path = SegmentPath(segs, prog.source)
    path.program = prog
    return path


def load_gcode_path(file, start=None) -> SegmentPath:
    return program_path(read_gcode(file, start))


def _num(x: float) -> str:
    s = f"{x:.6f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def write_gcode(path: SegmentPath, file, feed_mm_s: float, blend_mm: float | None = None,
                comment: str | None = None) -> None:
    """Write a segment path as G-code (G21 G90; G1 lines, G2/G3 arcs in the G17/G18/G19 planes).

    Coordinates get 6 decimals (1 nm), as a CAM post would; ``blend_mm`` → ``G64 P…``
    (None → G61). Arcs about an axis other than ±x, ±y, ±z are not expressible → GCodeError.
    """
    out = ["%"]
    if comment:
        out.append(f"( {comment.replace('(', '[').replace(')', ']')} )")
    mode = "G61" if blend_mm is None else (f"G64 P{_num(blend_mm)}" if math.isfinite(blend_mm) else "G64")
    out.append(f"G21 G90 G17 {mode}")
    p0 = path.segments[0].start
    out.append(f"G0 X{_num(p0[0])} Y{_num(p0[1])} Z{_num(p0[2])}")
    feed = f" F{_num(feed_mm_s * 60.0)}"
    for i, g in enumerate(path.segments):
        e = g.end
        if g.kind == "line":
            out.append(f"G1 X{_num(e[0])} Y{_num(e[1])} Z{_num(e[2])}{feed}")
        else:
            ax = int(np.argmax(np.abs(g.normal)))
            if abs(abs(g.normal[ax]) - 1.0) > 1e-12:
                raise GCodeError(str(file), i + 1, f"segment #{i}: arc axis {g.normal.tolist()} is "
                                                   "not a coordinate axis (G17/G18/G19 only)")
            plane_word = {2: "G17", 1: "G18", 0: "G19"}[ax]
            word = "G3" if g.normal[ax] > 0 else "G2"
            off = g.center - g.start
            offs = " ".join(f"{'IJK'[k]}{_num(off[k])}" for k in range(3) if k != ax)
            turns = int(math.ceil(g.angle / (2 * math.pi) - 1e-9)) if g.angle > 2 * math.pi + 1e-9 else 1
            p = f" P{turns}" if turns > 1 else ""
            out.append(f"{plane_word} {word} X{_num(e[0])} Y{_num(e[1])} Z{_num(e[2])} {offs}{p}{feed}")
        feed = ""
    out += ["M2", "%", ""]
    FsPath(file).write_text("\n".join(out))
