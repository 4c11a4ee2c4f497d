"""Coordinate systems and offsets, mixed into the Interpreter: program ↔ machine coordinates,
G54-G59.3 (interp_convert.cc's convert_coordinate_system), G43/G43.1/G49
(convert_tool_length_offset), M70-M73's modal state, and the non-modal G10 L2/L20 (convert_setup),
G92 family (convert_axis_offsets) and G28/G30 (convert_home)."""
from __future__ import annotations

import math

from planners.paths.gcode.rs274.codes import AXES, MM_PER_INCH
from planners.paths.gcode.rs274.errors import LineError


class Offsets:
    """Uses the Interpreter's pos, m (modal state), params, g5x, rot, g92, tlo, tool, tools."""

    # ------------------------------------------------------------------ coordinates
    def unit(self) -> float:
        return MM_PER_INCH if self.m.units == 20 else 1.0

    # emccanon.cc rotate_and_offset_pos: G92 first, then the XY rotation, then G5x and the tool
    # offset (unoffset_and_unrotate_pos the reverse)
    def to_machine(self, p):
        o, g, t_ = self.g5x, self.g92, self.tlo
        x, y, z = p[0] + g[0], p[1] + g[1], p[2] + g[2]
        if self.rot:
            t = math.radians(self.rot)
            c, s = math.cos(t), math.sin(t)
            x, y = x * c - y * s, x * s + y * c
        return [x + o[0] + t_[0], y + o[1] + t_[1], z + o[2] + t_[2]]

    def to_program(self, q):
        o, g, t_ = self.g5x, self.g92, self.tlo
        x, y, z = q[0] - o[0] - t_[0], q[1] - o[1] - t_[1], q[2] - o[2] - t_[2]
        if self.rot:
            t = math.radians(-self.rot)
            c, s = math.cos(t), math.sin(t)
            x, y = x * c - y * s, x * s + y * c
        return [x - g[0], y - g[1], z - g[2]]

    # ------------------------------------------------------------------ modal state
    def save_modal(self):
        return self.m.copy()

    def restore_modal(self, saved):
        coord = saved.coord
        self.m = saved.copy()
        self.m.motion = self.m.motion           # (motion mode is part of the saved state too)
        if coord != self.active_coord:
            self.select_coord(int(coord * 10))

    @property
    def active_coord(self):
        return self.m.coord

    def select_coord(self, g: int) -> None:
        self.flush()                     # emccanon.cc: offsets end a G64 Q chain
        idx = {540: 1, 550: 2, 560: 3, 570: 4, 580: 5, 590: 6, 591: 7, 592: 8, 593: 9}[g]
        self.m.coord = g / 10
        self.m.coord_index = idx
        self.params.set(5220, float(idx))
        base = 5201 + 20 * idx
        self.g5x = [self.params.get(base + i) for i in range(3)]
        self.rot = self.params.get(5210 + 20 * idx)

    def tool_length(self, g: int, w) -> None:
        self.flush()                     # emccanon.cc: offsets end a G64 Q chain
        if g == 490:
            self.tlo = [0.0, 0.0, 0.0]
        elif g == 430:
            h = int(w["h"]) if "h" in w else self.tool
            self.check_tool(h, f"G43 H{h}")
            t = self.tools.get(h, {})
            self.tlo = [t.get("X", 0.0), t.get("Y", 0.0), t.get("Z", 0.0)]
        else:                                     # G43.1: dynamic offset from the axis words
            u = self.unit()
            self.tlo = [w.get(a, 0.0) * u for a in AXES]
            for a in AXES:
                w.pop(a, None)

    def check_tool(self, n: int, word: str) -> None:
        """LinuxCNC's "Requested tool N not found in the tool table" (T, M61 Q, G43 H), when a
        table is given; tool 0 is "no tool"."""
        if self.tools and n != 0 and n not in self.tools:
            raise LineError(f"{word}: tool {n} is not in the tool table")

    # ------------------------------------------------------------------ non-modal G codes
    def nonmodal(self, g: int, w, axes) -> None:
        if "@" in axes:
            raise LineError(f"polar coordinates (@ ^) with G{g / 10:g}")
        u = self.unit()
        prog = self.to_program(self.pos)
        if g == 100:
            self._g10(w, axes, u)
        elif g in (920, 921, 922, 923):
            self._g92(g, w, axes, u)
        elif g in (281, 301):                       # store the current (machine) position
            base = 5161 if g == 281 else 5181
            for i in range(3):
                self.params.set(base + i, self.pos[i])
        else:
            self._home(g, w, axes, u, prog)

    def _g10(self, w, axes, u) -> None:
        """G10 L2 (set a system's origin) and L20 (so that the current point reads the words)."""
        self.flush()                     # emccanon.cc: offsets end a G64 Q chain
        lnum = w.get("l")
        if lnum not in (2.0, 20.0):
            raise LineError(f"G10 L{lnum if lnum is None else f'{lnum:g}'} is not supported (G10 L2/L20 only)")
        p = int(w.get("p", 0))
        if not 0 <= p <= 9:
            raise LineError(f"G10 P{p}: coordinate system must be 0 … 9")
        idx = p or self.m.coord_index
        base = 5201 + 20 * idx
        if lnum == 2.0:
            for a in axes:
                self.params.set(base + AXES.index(a), w[a] * u)
            if "r" in w:
                self.params.set(5210 + 20 * idx, w["r"])
        else:
            if "r" in w:
                raise LineError("R not allowed in G10 L20")
            if self.params.get(5210 + 20 * idx):
                raise LineError("G10 L20 on a rotated coordinate system is not supported")
            for a in axes:
                i = AXES.index(a)
                self.params.set(base + i, self.pos[i] - self.g92[i] - self.tlo[i] - w[a] * u)
        if idx == self.m.coord_index:
            self.select_coord(int(self.m.coord * 10))

    def _g92(self, g: int, w, axes, u) -> None:
        """G92 (set the offset), G92.1 (clear it and its parameters), G92.2 (clear it),
        G92.3 (restore it from the parameters)."""
        self.flush()                     # emccanon.cc: offsets end a G64 Q chain
        if g == 920:
            if not axes:
                raise LineError("G92 needs at least one axis word")
            for a in axes:
                i = AXES.index(a)
                self.g92[i] = self.pos[i] - self.g5x[i] - self.tlo[i] - w[a] * u
            if self.rot and ("x" in w or "y" in w):
                raise LineError("G92 with an XY rotation in force is not supported")
            for i in range(3):
                self.params.set(5211 + i, self.g92[i])
            self.params.set(5210, 1.0)
        elif g in (921, 922):
            self.g92 = [0.0, 0.0, 0.0]
            if g == 921:
                for i in range(3):
                    self.params.set(5211 + i, 0.0)
                self.params.set(5210, 0.0)
        else:
            self.g92 = [self.params.get(5211 + i) for i in range(3)]

    def _home(self, g: int, w, axes, u, prog) -> None:
        """G28 / G30: via an intermediate point to the stored one."""
        base = 5161 if g == 280 else 5181
        # interp_convert.cc's convert_home: always a traverse to the intermediate point
        # (the current point when no axis word is given), then to the stored point
        mid = list(prog)
        for a in axes:
            i = AXES.index(a)
            mid[i] = w[a] * u if self.m.absolute else prog[i] + w[a] * u
        self.emit("rapid", self.to_machine(mid) if axes else list(self.pos))
        end = list(self.pos)
        for i, a in enumerate(AXES):
            if not axes or a in axes:
                end[i] = self.params.get(base + i)
        self.emit("rapid", end)
