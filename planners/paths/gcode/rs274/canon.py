"""Canonical commands: what the interpreter hands to motion (as rs274ngc's canon calls).

Positions are machine coordinates in mm (work offsets, G92, the tool length offset and the XY
rotation applied, as LinuxCNC's canon and AXIS's glcanon do). Zero-length moves are kept
here, as the interpreter emits them; the motion layer (planners.paths.gcode) drops them.
"""
from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(slots=True)
class CanonMove:
    kind: str                   # "rapid" | "feed" | "arc"
    line: int                   # source line (1-based) in ``file``
    file: str
    start: tuple                # (x, y, z) mm
    end: tuple
    feed_mm_min: float | None   # programmed feed (None for rapids)
    path_mode: tuple            # ("exact", "path" | "stop") | ("blend", p_mm, q_mm): G61 / G61.1 / G64 P Q
    center: tuple | None = None  # arc: centre (the coordinate along the normal = start's)
    plane: int = 17             # arc: 17 | 18 | 19
    turn: int = 0               # arc: ARC_FEED's rotation: −1 = one CW turn part, +1 CCW, ±n …


@dataclass(slots=True)
class CanonEvent:
    kind: str                   # "m" (M code), "dwell", "tool", "message", "probe", "speed" (S)
    line: int
    file: str
    value: object               # the M number, the dwell in s, the tool number, the text
    index: int                  # number of moves emitted before it: it happens there


@dataclass
class CanonProgram:
    source: str
    start: tuple
    moves: list[CanonMove] = field(default_factory=list)
    events: list[CanonEvent] = field(default_factory=list)
    notes: list[tuple[int, str]] = field(default_factory=list)
    # moves emitted before each canon call that flushes LinuxCNC's G64 Q chain (an F, S or G64
    # word, a work or tool offset: emccanon.cc SET_FEED_RATE, SET_SPINDLE_SPEED, …)
    flushes: list[int] = field(default_factory=list)
    end_line: int = 0
