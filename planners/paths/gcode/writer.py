"""A segment path written back as G-code (G21 G90; G1 lines, G2/G3 arcs), as a CAM post would."""
from __future__ import annotations

import math
from pathlib import Path as FsPath

import numpy as np

from planners.paths.gcode.reader import GCodeError
from planners.paths.segments import SegmentPath


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
