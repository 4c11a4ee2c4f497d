"""Compare the interpreter with LinuxCNC's own (planners/paths/gcode/rs274/linuxcnc.py under the system
Python that has LinuxCNC's ``gcode`` module): the tests' reference, and ``--reader linuxcnc``."""
from __future__ import annotations

import functools
import json
import os
import re
import math
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
SYSTEM_PYTHON = "/usr/bin/python3"


@functools.lru_cache(maxsize=1)
def available() -> str | None:
    """None when LinuxCNC's interpreter can run here, else why not (asked once per process:
    --reader linuxcnc asks on every program)."""
    if shutil.which("rs274") is None:
        return "LinuxCNC's rs274 is not on PATH (make linuxcnc installs linuxcnc-uspace)"
    try:
        r = subprocess.run([SYSTEM_PYTHON, "-c", "import gcode"], capture_output=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return f"{SYSTEM_PYTHON} cannot run"
    if r.returncode:
        return f"LinuxCNC's gcode Python module does not import under {SYSTEM_PYTHON}"
    return None


def linuxcnc_rows(file, tool_table=None, timeout=120, setup=None):
    """Every row linuxcnc.py prints (moves, feed rates, dwells, messages, the end), or None
    when LinuxCNC's gcode module crashed; and the other lines of its output ((PRINT,…)).
    ``setup`` (planners.paths.gcode.rs274.setup.Setup): its tool table and var file, given to
    LinuxCNC in its standalone interpreters' machine units (inches) so that both read the same mm."""
    cmd = [SYSTEM_PYTHON, str(HERE / "linuxcnc.py"), str(file)]
    with tempfile.TemporaryDirectory() as d:
        if setup is not None:
            tool_table = None
            if setup.tools:
                cmd += ["--tool-table", str(_write(Path(d) / "mm.tbl", setup.tool_table_text()))]
            cmd += ["--var-file", str(_write(Path(d) / "in.var", setup.var_text(25.4)))]
        elif tool_table:
            cmd += ["--tool-table", str(tool_table)]
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    if r.returncode < 0:
        return None, []
    lines = r.stdout.splitlines()
    rows = [json.loads(x) for x in lines if x.startswith("{")]
    if not rows or rows[-1].get("kind") != "end":
        raise RuntimeError(f"LinuxCNC's interpreter failed on {file}: {r.stderr[-500:]}")
    return rows, [x for x in lines if not x.startswith("{")]


def linuxcnc_moves(file, tool_table=None, timeout=120, setup=None):
    """(moves, end) of LinuxCNC's interpreter: dicts as linuxcnc.py prints them, each feed move
    with the feed rate (mm/min) in force; ``setup`` as linuxcnc_rows."""
    rows, _ = linuxcnc_rows(file, tool_table, timeout, setup)
    if rows is None:
        # the gcode module crashes on tool changes without a running LinuxCNC (its tool
        # data lives in LinuxCNC's shared memory): fall back to rs274's text output
        return rs274_moves(file, tool_table, timeout, setup)
    return _with_feeds(rows[:-1]), rows[-1]


def _with_feeds(rows):
    """The motion rows, each feed move with the feed rate (mm/min) set before it; a probe move
    is a straight feed (that stops early where a probe trips: never here)."""
    out, feed = [], 0.0
    for m in rows:
        if m["kind"] == "feed_rate":
            feed = m["mm_per_min"]
        elif m["kind"] == "rapid":
            out.append(m)
        elif m["kind"] in ("feed", "arc", "probe"):
            out.append(dict(m, kind="arc" if m["kind"] == "arc" else "feed", feed=feed))
    return out


_CALL = re.compile(r"^\s*\d+\s+N\S*\s+([A-Z_0-9]+)\((.*)\)\s*$")
RS274_DECIMALS_TOL = 0.5e-4 * 25.4 + 1e-9   # rs274 prints 4 decimals (in inches for G20)


def rs274_moves(file, tool_table=None, timeout=120, setup=None):
    """LinuxCNC's ``rs274`` program: canonical calls as text with 4 decimals and no source line
    numbers ("line" is None); same dicts as linuxcnc_moves, plus "decimals": 4. ``setup``: as
    linuxcnc_moves (rs274's machine units are inches: the files are written in inches)."""
    with tempfile.TemporaryDirectory() as d:
        var = []
        if setup is not None:
            var = ["-v", str(_write(Path(d) / "in.var", setup.var_text(25.4)))]
            if setup.tools:
                tool_table = _write(Path(d) / "in.tbl", setup.tool_table_text(25.4))
        r = run_rs274(["-g", "-t", str(tool_table or zero_tool_table(Path(d))), *var, str(file)], timeout)
    unit, g5x, g92, tlo, rot, plane, feed = 1.0, [0.0] * 3, [0.0] * 3, [0.0] * 3, 0.0, 17, 0.0
    out = []

    def mach(x, y, z):
        # emccanon.cc rotate_and_offset_pos: G92, the XY rotation, then G5x and the tool offset
        x, y, z = x + g92[0], y + g92[1], z + g92[2]
        if rot:
            c, s = math.cos(math.radians(rot)), math.sin(math.radians(rot))
            x, y = x * c - y * s, x * s + y * c
        return [(v + g5x[i] + tlo[i]) * unit for i, v in enumerate((x, y, z))]

    for row in r.stdout.splitlines():
        m = _CALL.match(row)
        if not m:
            continue
        name, a = m.group(1), [x for x in re.split(r"[,\s]+", m.group(2).strip()) if x]
        num = lambda k: float(a[k])
        if name == "USE_LENGTH_UNITS":
            unit = 25.4 if "INCH" in a[0] else (10.0 if "CM" in a[0] else 1.0)
        elif name == "SET_G5X_OFFSET":
            g5x = [num(1), num(2), num(3)]
        elif name == "SET_G92_OFFSET":
            g92 = [num(0), num(1), num(2)]
        elif name == "USE_TOOL_LENGTH_OFFSET":
            tlo = [num(0), num(1), num(2)]
        elif name == "SET_XY_ROTATION":
            rot = num(0)
        elif name == "SET_FEED_RATE":
            feed = num(0) * unit
        elif name == "SELECT_PLANE":
            plane = {"CANON_PLANE_XY": 17, "CANON_PLANE_YZ": 19, "CANON_PLANE_XZ": 18}[a[0]]
        elif name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "STRAIGHT_PROBE"):
            out.append({"kind": "rapid" if name == "STRAIGHT_TRAVERSE" else "feed", "line": None,
                        "end": mach(num(0), num(1), num(2))} | ({} if name == "STRAIGHT_TRAVERSE" else {"feed": feed}))
        elif name == "ARC_FEED":
            fe, se, fa, sa, rt, ae = num(0), num(1), num(2), num(3), int(a[4]), num(5)
            if plane == 17:
                end, cen, ax = (fe, se, ae), (fa, sa, 0.0), 2
            elif plane == 19:
                end, cen, ax = (ae, fe, se), (0.0, fa, sa), 0
            else:
                end, cen, ax = (se, ae, fe), (sa, 0.0, fa), 1
            c = mach(*cen)
            c[ax] = None
            out.append({"kind": "arc", "line": None, "end": mach(*end), "center": c, "rotation": rt,
                        "plane": plane, "feed": feed})
    # rs274 prints (on stderr) the error's text, then the line it refused
    err = [x for x in (r.stdout + r.stderr).splitlines() if x and not _CALL.match(x) and not x.startswith("executing")]
    if r.returncode < 0:
        err = [f"rs274 died of signal {-r.returncode}"] + err
    return out, {"kind": "end", "result": r.returncode, "line": None, "decimals": 4,
                 "error": None if r.returncode == 0 else (" / ".join(err) if err else f"rs274 exited {r.returncode}")}


def run_rs274(args, timeout):
    """``rs274 ARGS`` (stdin closed) in a HOME of its own: LinuxCNC 2.9 keeps the tool data in a
    memory map of $HOME/.tool.mmap (tooldata_mmap.cc, tool_mmap_creator) that each rs274
    truncates when it starts, so two at once under one HOME crash each other with SIGBUS (as
    two test workers did)."""
    with tempfile.TemporaryDirectory(prefix="pkmbench-rs274-") as home:
        return subprocess.run(["rs274", *args], capture_output=True, text=True, timeout=timeout,
                              stdin=subprocess.DEVNULL, env=dict(os.environ, HOME=home))


def zero_tool_table(d: Path) -> Path:
    """rs274's built-in table has tool 1 at Z 0.511 in; ours is empty (offsets 0): a table of
    tools 1…999 with zero offsets, in ``d``, so that both read the same program."""
    return _write(d / "zero.tbl", "".join(f"T{t} P{t} Z0\n" for t in range(1, 1000)))


def _write(f: Path, text: str) -> Path:
    f.write_text(text)
    return f


# canon calls → the interpreter's events (interp_cycles.cc's spindle calls and dwells; the
# program stop of G88): the order of motion and these is where LinuxCNC's queue waits
_SEQUENCE_CALLS = {"STRAIGHT_TRAVERSE": "rapid", "STRAIGHT_FEED": "feed", "STRAIGHT_PROBE": "feed", "ARC_FEED": "arc",
                   "STOP_SPINDLE_TURNING": ("m", 5), "START_SPINDLE_CLOCKWISE": ("m", 3),
                   "START_SPINDLE_COUNTERCLOCKWISE": ("m", 4), "ORIENT_SPINDLE": ("m", 19),
                   "PROGRAM_STOP": ("m", 0), "PROGRAM_END": ("m", 2)}


def rs274_sequence(file, timeout=120):
    """The moves, dwells ("dwell", s) and spindle/stop calls ("m", n) of ``rs274 -g FILE`` in
    their order, up to PROGRAM_END (which it includes)."""
    r = run_rs274(["-g", str(file)], timeout)
    out = []
    for row in r.stdout.splitlines():
        m = _CALL.match(row)
        if not m:
            continue
        name = m.group(1)
        if name == "DWELL":
            out.append(("dwell", round(float(m.group(2)), 4)))
        elif name in _SEQUENCE_CALLS:
            if name == "PROGRAM_END":
                if out and out[-1] == ("m", 5):
                    out.pop()                 # convert_stop's own spindle stop for M2/M30
                out.append(("m", 2))
                break
            out.append(_SEQUENCE_CALLS[name])
    return out


def sequence(program, kinds=("dwell", "m")) -> list:
    """The same for our canonical program: moves and the events of ``kinds`` in order (M codes
    0, 2, 3, 4, 5, 19 only: the spindle and stop calls rs274_sequence lists)."""
    out, ev = [], [e for e in program.events if e.kind in kinds and (e.kind != "m" or e.value in (0, 2, 3, 4, 5, 19))]
    k = 0
    for i, mv in enumerate(program.moves + [None]):
        while k < len(ev) and ev[k].index == i:
            e = ev[k]
            out.append(("dwell", round(float(e.value), 4)) if e.kind == "dwell" else ("m", e.value))
            k += 1
        if mv is not None:
            out.append(mv.kind)
    return out


def compare(ours, ref, tol=1e-9, feeds: bool = False):
    """First difference between our canonical moves and LinuxCNC's, or None (ends, arc centres,
    turns, kinds, lines; ``feeds``: also the feed rate of each feed move, to 1e-9 relative, or to
    rs274's 4 decimals in its units when ``tol`` is rs274's)."""
    if len(ours) != len(ref):
        n = min(len(ours), len(ref))
        for i in range(n):
            d = _diff(ours[i], ref[i], tol, feeds)
            if d:
                return f"move {i}: {d}"
        return f"{len(ours)} moves, LinuxCNC has {len(ref)}"
    for i, (a, b) in enumerate(zip(ours, ref)):
        d = _diff(a, b, tol, feeds)
        if d:
            return f"move {i}: {d}"
    return None


def _diff(a, b, tol, feeds=False):
    if a.kind != b["kind"]:
        return f"line {a.line}: {a.kind}, LinuxCNC line {b['line']}: {b['kind']}"
    if feeds and a.kind != "rapid":
        f_tol = tol if tol > 1e-9 else 1e-9 * max(1.0, abs(b["feed"]))
        if not abs(a.feed_mm_min - b["feed"]) <= f_tol:
            return f"line {a.line}: feed {a.feed_mm_min:.9g} mm/min, LinuxCNC {b['feed']:.9g} mm/min"
    e = max(abs(x - y) for x, y in zip(a.end, b["end"]))
    if not e <= tol:
        return f"line {a.line}: end {a.end} vs {b['end']} ({e:.3g} mm)"
    if a.kind == "arc":
        c = max(abs(x - y) for x, y in zip(a.center, b["center"]) if y is not None)
        if not c <= tol:
            return f"line {a.line}: centre {a.center} vs {b['center']} ({c:.3g} mm)"
        if a.turn != b["rotation"] or a.plane != b["plane"]:
            return f"line {a.line}: turn/plane {a.turn}/{a.plane} vs {b['rotation']}/{b['plane']}"
    if b["line"] is not None and a.line != b["line"]:
        return f"line {a.line} vs LinuxCNC line {b['line']}"
    return None


if __name__ == "__main__":
    # python -m planners.paths.gcode.rs274.reference FILE…: compare each, one line per program
    from planners.paths.gcode.rs274 import RS274Error, interpret
    from planners.paths.gcode.rs274.interp import _read_text
    for f in sys.argv[1:]:
        try:
            ref, end = linuxcnc_moves(f)
        except Exception as e:
            print(f"REF! {f}: {e}")
            continue
        try:
            ours = interpret(_read_text(f), f).moves
            d = compare(ours, ref, RS274_DECIMALS_TOL if end.get("decimals") else 1e-9)
            print(f"{'OK  ' if d is None else 'DIFF'} {f}: {d or len(ours)} {'' if end['error'] is None else '(LinuxCNC: ' + end['error'] + ')'}")
        except RS274Error as e:
            print(f"ERR  {f}: {e.message} (line {e.line}) / LinuxCNC: {end['error']} ({len(ref)} moves)")
