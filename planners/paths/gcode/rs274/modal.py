"""Modal state: what M70/M73 save and M72 restores (LinuxCNC's list: units, distance modes,
plane, feed mode, path control with P/Q, coordinate system, retract mode, spindle, coolant,
F and S), plus the motion mode. Defaults are LinuxCNC's at program start: G17 G21 G90 G91.1
G94 G64 G54 G99, no motion mode (the gcode module's start state)."""
from __future__ import annotations

from dataclasses import dataclass, replace


@dataclass(slots=True)
class Modal:
    motion: int | None = None           # G code ×10: 0, 10, 20, 30, 800
    plane: int = 17
    units: int = 21
    absolute: bool = True
    ijk_absolute: bool = False
    path: tuple = ("blend", 0.0, 0.0)   # G64 (no P: best possible speed)
    coord: float = 54.0
    coord_index: int = 1
    retract: int = 99                   # G99: rs274ngc leaves retract_mode zero, R_PLANE
    feed: float = 0.0                   # mm/min
    speed: float = 0.0
    spindle: int = 5
    coolant: int = 9
    selected_tool: int = 0

    def copy(self) -> "Modal":
        return replace(self)
