"""``--reader linuxcnc``: a program read by LinuxCNC's own interpreter instead of ours.

Two runs of LinuxCNC 2.9's librs274 (Debian ``linuxcnc-uspace``) give the canonical program:

- the ``gcode`` Python module (linuxcnc.py under the system Python) gives the geometry at full
  precision with each move's line and feed; it starts at the machine position, set with
  ``G53 G0`` before the program (its move is dropped);
- the ``rs274`` program gives what that module does not call back: the path-control mode at
  each move (SET_MOTION_CONTROL_MODE, SET_NAIVECAM_TOLERANCE), the canon calls that end a G64 Q
  chain, and the M codes, dwells, tool changes and messages between moves (4 decimals suffice:
  P and Q only).

The two are matched move by move. The result is a :class:`CanonProgram`, as our interpreter's,
so everything after it (G64 Q joining, segments, stops) is shared.
"""
from __future__ import annotations

import json
import math
import re
import subprocess
import tempfile
from pathlib import Path

from planners.paths.gcode.rs274.canon import CanonEvent, CanonMove, CanonProgram
from planners.paths.gcode.rs274.errors import RS274Error
from planners.paths.gcode.rs274.reference import HERE, SYSTEM_PYTHON, available, run_rs274, zero_tool_table

_CALL = re.compile(r"^\s*\d+\s+N\S*\s+([A-Z_0-9]+)\((.*)\)\s*$")
_MOTION = ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "ARC_FEED")
# canon calls that end a G64 Q chain (emccanon.cc flush_segments) without being an event here
_FLUSH = ("SET_FEED_RATE", "SET_SPINDLE_SPEED", "SET_MOTION_CONTROL_MODE", "SET_G5X_OFFSET",
          "SET_G92_OFFSET", "USE_TOOL_LENGTH_OFFSET")
# canon call → (event kind, value) as planners.paths.gcode.rs274 records the M code, dwell, tool or message
_EVENTS = {"START_SPINDLE_CLOCKWISE": ("m", 3), "START_SPINDLE_COUNTERCLOCKWISE": ("m", 4),
           "STOP_SPINDLE_TURNING": ("m", 5), "MIST_ON": ("m", 7), "FLOOD_ON": ("m", 8),
           "FLOOD_OFF": ("m", 9), "PROGRAM_STOP": ("m", 0), "OPTIONAL_PROGRAM_STOP": ("m", 1),
           "PROGRAM_END": ("m", 2), "CHANGE_TOOL": ("m", 6), "SELECT_TOOL": ("tool", None),
           "SET_MOTION_OUTPUT_BIT": ("m", 62), "CLEAR_MOTION_OUTPUT_BIT": ("m", 63),
           "SET_AUX_OUTPUT_BIT": ("m", 64), "CLEAR_AUX_OUTPUT_BIT": ("m", 65),
           "ORIENT_SPINDLE": ("m", 19), "DWELL": ("dwell", None), "MESSAGE": ("message", None),
           "SET_SPINDLE_SPEED": ("speed", None)}


def linuxcnc_canon(file, start=None, home=None, tool_table=None, timeout: float = 300) -> tuple[CanonProgram, bool]:
    """(canonical program, positioning?) of ``file`` as LinuxCNC reads it. The start rule is
    parse_gcode's: ``start`` given → the program runs from it; else a first move that sets X, Y
    and Z absolutely positions the tool (found by running from two different points), else the
    program runs from ``home``. RS274Error naming the file and line if LinuxCNC refuses it."""
    why = available()
    if why is not None:
        raise RS274Error(str(file), 0, f"--reader linuxcnc: {why}")
    src = str(file)
    positioning = False
    if start is None:
        a, last = _module_moves(src, (0.0, 0.0, 0.0), tool_table, timeout)
        b, _ = _module_moves(src, (1.25, -0.75, 0.5), tool_table, timeout)
        positioning = bool(a) and a[0]["kind"] in ("rapid", "feed") and a[0]["end"] == b[0]["end"]
        if positioning:
            moves, at = a, (math.nan,) * 3
        elif home is None:
            raise RS274Error(src, a[0]["line"] if a else 0,
                             "the first move must be an absolute (G90) G0/G1 with X, Y and Z "
                             "(it sets the start point) — or pass start= (the machine's position)")
        else:
            at = tuple(float(v) for v in home)
            moves, last = _module_moves(src, at, tool_table, timeout)
    else:
        at = tuple(float(v) for v in start)
        moves, last = _module_moves(src, at, tool_table, timeout)
    modes, flushes, events = _rs274_stream(src, tool_table, timeout)
    if len(modes) != len(moves):
        raise RS274Error(src, 0, f"--reader linuxcnc: the gcode module gave {len(moves)} moves, rs274 "
                                 f"{len(modes)}: cannot match them")
    return _program(src, at, moves, modes, flushes, events, last), positioning


def _module_moves(src: str, start, tool_table, timeout) -> tuple[list[dict], int]:
    """(the moves of LinuxCNC's gcode module from ``start`` (its G53 G0 dropped), each with the
    feed in force (mm/min); the program's last line)."""
    cmd = [SYSTEM_PYTHON, str(HERE / "linuxcnc.py"), src, "--start", ",".join(repr(v) for v in start)]
    if tool_table:
        cmd += ["--tool-table", str(tool_table)]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    if r.returncode < 0:
        raise RS274Error(src, 0, "--reader linuxcnc: LinuxCNC's gcode module crashed (it does on a tool "
                                 "change without a running LinuxCNC): read this program with the built-in reader")
    rows = [json.loads(x) for x in r.stdout.splitlines() if x.startswith("{")]
    if not rows or rows[-1].get("kind") != "end":
        raise RS274Error(src, 0, f"--reader linuxcnc: LinuxCNC's interpreter failed: {r.stderr.strip()[-300:]}")
    end = rows[-1]
    if end["error"] is not None:
        raise RS274Error(src, int(end["line"] or 0), f"LinuxCNC: {end['error']}")
    feed, out = 0.0, []
    for row in rows[1:-1]:                  # rows[0]: the G53 G0 to the start
        if row["kind"] == "feed_rate":
            feed = row["mm_per_min"]
        elif row["kind"] in ("rapid", "feed", "arc"):
            out.append(dict(row, feed=feed))
        elif row["kind"] in ("probe", "rigid_tap"):
            raise RS274Error(src, row["line"], f"{row['kind']} moves are not supported")
    return out, int(end["line"] or 0)


def _rs274_stream(src: str, tool_table, timeout):
    """From ``rs274``'s canon calls: the path mode at each move, the moves emitted before each
    chain-ending call, and the events (kind, value, moves before it)."""
    with tempfile.TemporaryDirectory() as d:
        r = run_rs274(["-g", "-t", str(tool_table or zero_tool_table(Path(d))), src], timeout)
    if r.returncode < 0:
        raise RS274Error(src, 0, f"--reader linuxcnc: LinuxCNC's rs274 died of signal {-r.returncode}")
    unit, mode, q = 1.0, "blend", 0.0
    p = 0.0
    modes, flushes, events = [], [], []
    for row in r.stdout.splitlines():
        m = _CALL.match(row)
        if not m:
            continue
        name, args = m.group(1), [x for x in re.split(r"[,\s]+", m.group(2).strip()) if x]
        n = len(modes)
        if name == "USE_LENGTH_UNITS":
            unit = 25.4 if "INCH" in args[0] else (10.0 if "CM" in args[0] else 1.0)
        elif name == "SET_MOTION_CONTROL_MODE":
            mode = {"CANON_CONTINUOUS": "blend", "CANON_EXACT_PATH": "path"}.get(args[0], "stop")
            p = float(args[1]) * unit if len(args) > 1 else 0.0
        elif name == "SET_NAIVECAM_TOLERANCE":
            q = float(args[0]) * unit
        elif name in _MOTION:
            modes.append(("blend", p, q) if mode == "blend" else ("exact", mode))
        elif name in _EVENTS:
            kind, value = _EVENTS[name]
            if name == "PROGRAM_END" and events and events[-1][:2] == ("m", 5) and events[-1][2] == n:
                events.pop()                  # M2/M30 stop the spindle just before: part of the end
            if name == "FLOOD_OFF" and events and events[-1][:2] == ("m", 7.5) and events[-1][2] == n:
                events.pop()                 # M9 is MIST_OFF then FLOOD_OFF: one M9
            value = {"dwell": lambda: float(args[0]), "tool": lambda: int(args[0]), "speed": lambda: float(args[1]),
                     "message": lambda: m.group(2).strip().strip('"').strip()}.get(kind, lambda: value)()
            events.append((kind, value, n))
        elif name == "MIST_OFF":
            events.append(("m", 7.5, n))     # completed by the FLOOD_OFF that follows (M9)
        if name in _FLUSH:
            flushes.append(n)
    return modes, flushes, [(k, 9 if v == 7.5 else v, n) for k, v, n in events]


def _program(src: str, at, moves, modes, flushes, events, last: int) -> CanonProgram:
    cp = CanonProgram(src, at)
    pos = at
    for row, mode in zip(moves, modes):
        kind, end = row["kind"], tuple(row["end"])
        kw = {}
        if kind == "arc":
            axis = {17: 2, 18: 1, 19: 0}[row["plane"]]
            c = list(row["center"])
            c[axis] = pos[axis]               # the centre's coordinate along the normal: the start's
            kw = {"center": tuple(c), "plane": row["plane"], "turn": int(row["rotation"])}
        cp.moves.append(CanonMove(kind, int(row["line"]), src, tuple(pos), end,
                                  None if kind == "rapid" else row["feed"], mode, **kw))
        pos = end
    for kind, value, n in events:            # LinuxCNC gives no line: the next move's
        line = cp.moves[n].line if n < len(cp.moves) else last
        cp.events.append(CanonEvent(kind, line, src, value, n))
    cp.flushes = flushes
    cp.end_line = last
    return cp
