"""The RS274NGC interpreter: blocks → canonical moves, following LinuxCNC 2.9's rs274ngc.

Per block, the order of execution is rs274ngc's execute_block/convert_* order (LinuxCNC's
documented table): O-word control, parameter settings (after the whole line is read, so
``#1=2 #2=#1`` sees the old #1), the comment ((MSG,…), (ABORT,…)), F (in the units before the
line's G20/G21), S, T, M6/M61, M3-5, M70-73, M7-9, other M codes, G4, plane, units, cutter
compensation (G40 only), tool length offset, coordinate system, path control, distance modes,
retract mode, the non-modal G10/G28/G30/G92/G53, motion (canned cycles: cycles.py), then
M0/M1/M2/M30/M60.

This module holds that order (``execute`` and its steps), the parameters and the run loop; the
word and code checks are in codes.py, offsets and coordinate systems in offsets.py, motion and
arcs in motion.py, O-word control flow in flow.py.
"""
from __future__ import annotations

import math
from pathlib import Path as FsPath

from planners.paths.gcode.rs274 import expr as X
from planners.paths.gcode.rs274.canon import CanonEvent, CanonMove, CanonProgram
from planners.paths.gcode.rs274.codes import (AXES, MM_PER_INCH, check_axis_words, check_other_codes, g_groups, m_groups,
                                  read_words)
from planners.paths.gcode.rs274.cycles import CYCLES, Cycles
from planners.paths.gcode.rs274.errors import LineError, RS274Error
from planners.paths.gcode.rs274.flow import Flow, Frame
from planners.paths.gcode.rs274.modal import Modal
from planners.paths.gcode.rs274.motion import Motion
from planners.paths.gcode.rs274.offsets import Offsets
from planners.paths.gcode.rs274.owords import SourceFile
from planners.paths.gcode.rs274.params import Parameters

DEFAULT_MAX_LOOPS = 1_000_000


class Interpreter(Offsets, Motion, Flow, Cycles):
    """Run one program. ``start``: the machine position before it (mm); ``tools``: tool number
    → {"Z": length offset mm, …}; ``subroutine_path``: folders searched for ``name.ngc`` when
    ``O<name> call`` names no subroutine of the file; ``block_delete``: skip '/' lines;
    ``probe_surface``: what a G38.x probe touches (motion.py: a height z = c in machine mm, or
    a function f(x, y) → z; the probe is in contact at or below it), None: nothing; ``setup``: a
    tool table, var file and offsets the machine holds at the start (setup.py)."""

    def __init__(self, start=(0.0, 0.0, 0.0), tools=None, subroutine_path=(), block_delete=False,
                 max_loops: int = DEFAULT_MAX_LOOPS, probe_surface=None, setup=None):
        self.pos = [float(v) for v in start]      # machine position (mm)
        self.tools = tools or {}
        self.sub_path = [FsPath(p) for p in subroutine_path]
        self.block_delete = block_delete
        self.max_loops = max_loops
        self.probe_surface = probe_surface
        self.params = Parameters()
        self.m = Modal()
        self.g5x = [0.0, 0.0, 0.0]
        self.rot = 0.0                              # XY rotation of the active system (deg)
        self.g92 = [0.0, 0.0, 0.0]
        self.tlo = [0.0, 0.0, 0.0]
        self.tool = 0
        self.loops = 0
        self.ended = False
        self.value = 0.0
        self.value_returned = 0.0
        self._files: dict[str, SourceFile] = {}
        if setup:
            setup.apply(self)

    # ------------------------------------------------------------------ parameters
    def read_param(self, n: float) -> float:
        if abs(n - round(n)) > 1e-6:
            raise LineError(f"parameter number #{n:g} is not an integer")
        n = int(round(n))
        if 5420 <= n <= 5422:                          # current position, program units
            return self.to_program(self.pos)[n - 5420] / self.unit()
        if n == 5400:
            return float(self.tool)
        return self.params.get(n)

    def read_named(self, name: str, frame: Frame) -> float:
        if name.startswith("_"):
            v = self.params.named_global.get(name)
            if v is not None:
                return v
            v = self.predefined(name)
            if v is None:
                raise LineError(f"named parameter #<{name}> is not defined")
            return v
        v = frame.named.get(name)
        if v is None:
            raise LineError(f"named parameter #<{name}> is not defined")
        return v

    def predefined(self, name: str):
        # the read-only #<_…> parameters of LinuxCNC's interp (a subset; others are refused)
        m = self.m
        if name in ("_x", "_y", "_z"):
            return self.to_program(self.pos)["_x _y _z".split().index(name)] / self.unit()
        return {"_line": float(self.cur_line), "_metric": float(m.units == 21), "_imperial": float(m.units == 20),
                "_absolute": float(m.absolute), "_incremental": float(not m.absolute),
                "_feed": m.feed / self.unit() if m.feed else 0.0, "_motion_mode": float(m.motion or 800) / 10,
                "_plane": float(m.plane) * 10, "_value": self.value, "_value_returned": self.value_returned,
                "_current_tool": float(self.tool), "_coord_system": float(m.coord) * 10 / 10,
                "_task": 0.0, "_ccomp": 400.0, "_ijk_absolute_mode": float(m.ijk_absolute),
                "_rpm": m.speed, "_call_level": float(len(self.frames) - 1)}.get(name)

    def evaluate(self, node, frame: Frame) -> float:
        if isinstance(node, float):
            return node
        k = node[0]
        if k == "bin":
            return X.binary(node[1], self.evaluate(node[2], frame), self.evaluate(node[3], frame))
        if k == "par":
            return self.read_param(self.evaluate(node[1], frame))
        if k == "npar":
            return self.read_named(node[1], frame)
        if k == "neg":
            return -self.evaluate(node[1], frame)
        if k == "fn":
            return X.unary(node[1], self.evaluate(node[2], frame))
        if k == "atan":
            return math.degrees(math.atan2(self.evaluate(node[1], frame), self.evaluate(node[2], frame)))
        if k == "exists":
            n = node[1]
            if n.startswith("_"):
                return float(n in self.params.named_global or self.predefined(n) is not None)
            return float(n in frame.named)
        raise LineError(f"bad expression node {k}")

    def assign(self, target, value: float, frame: Frame) -> None:
        if target[0] == "npar":
            name = target[1]
            if name.startswith("_"):
                if self.predefined(name) is not None and name not in self.params.named_global:
                    raise LineError(f"#<{name}> is read-only")
                self.params.named_global[name] = value
            else:
                frame.named[name] = value
            return
        n = self.evaluate(target[1], frame)
        if abs(n - round(n)) > 1e-6:
            raise LineError(f"parameter number #{n:g} is not an integer")
        if 5400 <= round(n) <= 5429:          # tool and current position: LinuxCNC's read-only ones
            raise LineError(f"parameter #{round(n)} is read-only")
        self.params.set(int(round(n)), value)

    # ------------------------------------------------------------------ files
    def source(self, name: str, text: str | None = None, main: bool = False) -> SourceFile:
        f = self._files.get(name)
        if f is None:
            f = SourceFile(name, text if text is not None else _read_text(name), main)
            self._files[name] = f
        return f

    def find_sub(self, label: str, frame: Frame, line: int):
        for f in [frame.src, self.frames[0].src] + list(self._files.values()):
            if label in f.subs:
                return f, f.subs[label][0]
        for d in self.sub_path:
            cand = d / f"{label}.ngc"
            if cand.is_file():
                f = self.source(str(cand))
                if label not in f.subs:
                    raise LineError(f"{cand} does not define O<{label}> sub")
                return f, f.subs[label][0]
        where = f" (searched {', '.join(map(str, self.sub_path))})" if self.sub_path else ""
        raise LineError(f"O<{label}> call: no such subroutine in the file{where}")

    # ------------------------------------------------------------------ run
    def run(self, text: str, source: str = "<gcode>") -> CanonProgram:
        main = self.source(source, text, main=True)
        self.out = CanonProgram(source, tuple(self.pos))
        self.frames = [Frame(main, 0)]
        self.cur_line = 0
        while not self.ended:
            fr = self.frames[-1]
            src = fr.src
            if fr.pc >= len(src.blocks):
                if len(self.frames) > 1:
                    raise RS274Error(src.name, fr.call_line, f"O<{fr.label}>: the file ends inside the subroutine")
                if src.unclosed_percent:
                    # interp_read.cc read_text: the end of the file before M2/M30 or a closing '%'
                    raise RS274Error(src.name, len(src.blocks) + 1, "File ended with no percent sign: the "
                                     "program opens with '%' and has no closing '%' (nor M2/M30 before the end)")
                break
            pc = fr.pc
            fr.pc += 1
            blk = src.blocks[pc]
            if blk is None:
                continue
            self.cur_line = pc + 1
            try:
                if isinstance(blk, LineError):
                    raise blk
                if blk.delete and self.block_delete:
                    continue
                if blk.okey is not None:
                    self.control(blk, fr, pc)
                else:
                    self.execute(blk, fr)
            except LineError as e:
                raise RS274Error(src.name, pc + 1, str(e)) from None
            except RecursionError:
                raise RS274Error(src.name, pc + 1, "expression nested too deeply") from None
        self.out.end_line = self.cur_line
        return self.out

    # ------------------------------------------------------------------ one block
    def execute(self, b, fr: Frame) -> None:
        if b.fast is not None:
            self._execute_fast(b.fast)
            return
        # the modal state as the line began: an M72 on the line replaces self.m, and the G
        # codes of the line still set this object (as the interpreter always did; issue 18
        # keeps behaviour)
        m = self.m
        if not b.words and not b.assigns:
            if b.comment is not None:
                self.comment(b.comment, fr)
            return
        w, gs, ms = read_words(b.words, self.evaluate, fr)
        if b.assigns:
            vals = [(t, self.evaluate(node, fr)) for t, node in b.assigns]
        groups = g_groups(gs)
        mg = m_groups(ms)
        check_axis_words(w)
        if b.assigns:
            for t, v in vals:
                self.assign(t, v, fr)
        # rs274ngc_pre.cc execute: the line's parameter settings, then execute_block: its
        # comment first
        if b.comment is not None:
            self.comment(b.comment, fr)
        self._feed_speed_tool(w, groups)
        self._m_codes(mg, w, fr)
        g0 = groups.get(0)
        self._g_modes(m, g0, groups, w)
        ran = self._g_motion(m, g0, groups, w)
        check_other_codes(w, g0, groups, mg, self._arc_done, ran)
        if 4 in mg:
            self._program_stop(mg[4])

    def comment(self, text: str, fr: Frame) -> None:
        """interp_convert.cc's convert_comment, first in a block: (MSG,…) is a message,
        (DEBUG,…) one with its parameters expanded (while #5599 > 0), (PRINT,…) is printed by
        LinuxCNC (here a message too, so a report shows it), (ABORT,…) stops the program with
        its expanded text as the error."""
        c = text.lstrip()
        low = c[:6].lower()
        if low.startswith("msg,"):
            self.event("message", c[4:])
        elif low.startswith("debug,"):
            if self.params.num[5599] > 0:
                self.event("message", self.expand_comment(c[6:], fr))
        elif low.startswith("print,"):
            self.event("message", self.expand_comment(c[6:], fr))
        elif low.startswith("abort,"):
            raise LineError(f"(ABORT) {self.expand_comment(c[6:], fr)}")

    def expand_comment(self, text: str, fr: Frame) -> str:
        """interp_convert.cc's convert_param_comment: #n and #<name> replaced by their values
        in the format last set by %d (integer), %f (4 decimals) or %.Nf (default %lf: 6
        decimals); an unknown parameter reads ######."""
        out, fmt, i = [], "%f", 0
        while i < len(text):
            c = text[i]
            if c == "%" and text[i + 1:i + 2] == "d":
                fmt, i = "%.0f", i + 2
            elif c == "%" and text[i + 1:i + 2] == "f":
                fmt, i = "%.4f", i + 2
            elif c == "%" and text[i + 1:i + 2] == ".":
                if text[i + 2:i + 3].isdigit() and text[i + 3:i + 4] == "f":
                    fmt, i = f"%.{text[i + 2]}f", i + 4
                else:                     # not a format: LinuxCNC keeps the '.', not the '%'
                    out.append(".")
                    i += 2
            elif c == "#" and text[i + 1:i + 2].isdigit():
                j = i + 1
                while j < len(text) and text[j].isdigit():
                    j += 1
                try:
                    out.append(fmt % _plain(self.read_param(float(text[i + 1:j]))))
                except LineError:         # out of range
                    out.append("######")
                i = j
            elif c == "#" and text[i + 1:i + 2] == "<":
                j = text.find(">", i + 2)
                if j < 0:
                    raise LineError("named parameter not terminated in a comment")
                name = "".join(text[i + 2:j].split()).lower()
                try:
                    out.append(fmt % _plain(self.read_named(name, fr)))
                except LineError:
                    out.append("######")
                i = j + 1
            else:
                out.append(c)
                i += 1
        return "".join(out)

    def _execute_fast(self, fast) -> None:
        """The common CAM line (constant X/Y/Z/I/J/K/R/F words, at most a G0-G3): same
        semantics as the general path of execute, without its per-group bookkeeping."""
        m = self.m
        motion, w = fast
        if "f" in w:
            f = w["f"]
            if f < 0:
                raise LineError(f"negative feed rate F{f:g}")
            m.feed = f * (MM_PER_INCH if m.units == 20 else 1.0)
            self.flush()
        if motion is not None:
            m.motion = motion
        mm = m.motion
        axes = [a for a in AXES if a in w]
        self._arc_done = False
        if mm in CYCLES:
            if axes:                              # the cycle again at these axis words
                self.cycle(mm, mm, w)
                check_other_codes(w, None, {}, {}, False, mm)
                return
        elif motion is not None or axes:
            self.cycle_il = None                  # convert_motion: a motion other than a cycle
            if mm is None or mm == 800:
                if axes:
                    raise LineError("axis words with no motion mode in force (G0/G1/G2/G3)")
            else:
                self.motion(mm, dict(w), axes, False)
        for letter in w:
            if letter in "ijkr" and not self._arc_done:
                raise LineError(f"{letter.upper()} word with no code on the line that uses it")

    def _feed_speed_tool(self, w, groups) -> None:
        """F, S and T. F is set before the line's G20/G21 (LinuxCNC's order of execution), so
        it is in the units in force before the line: after G21, ``G20 F6`` is 6 mm/min (the
        canon converts F when it is set; a later unit change keeps the rate)."""
        m = self.m
        u = MM_PER_INCH if m.units == 20 else 1.0
        if "f" in w:
            if w["f"] < 0:
                raise LineError(f"negative feed rate F{w['f']:g}")
            m.feed = w["f"] * u
            self.flush()
        if "s" in w:
            if w["s"] < 0:
                raise LineError(f"negative spindle speed S{w['s']:g}")
            m.speed = w["s"]
            self.flush()
            self.event("speed", w["s"])               # SET_SPINDLE_SPEED: a message to motion
        if "t" in w:
            if w["t"] < 0 or w["t"] != int(w["t"]):
                raise LineError(f"T{w['t']:g}: tool numbers are integers ≥ 0")
            self.check_tool(int(w["t"]), f"T{int(w['t'])}")
            m.selected_tool = int(w["t"])

    def _m_codes(self, mg, w, fr: Frame) -> None:
        """M6/M61 (tool change), M3-5 (spindle), M70-73 (modal state), M7-9 (coolant), then
        the events of the M codes other than the program stops."""
        m = self.m
        if 6 in mg:
            if mg[6] == 6:
                self.tool = m.selected_tool
                self.event("tool", self.tool)
            else:                                     # M61 Q: set the tool number, no change
                if "q" not in w or w["q"] < 0:
                    raise LineError("M61 needs Q ≥ 0 (the tool number)")
                self.check_tool(int(w["q"]), f"M61 Q{int(w['q'])}")
                self.tool = int(w["q"])
            self.params.set(5400, float(self.tool))
        if 7 in mg:
            m.spindle = mg[7]
        if 10 in mg:                                  # M70-M73 before M7-M9 (LinuxCNC's order)
            self._modal_state(mg[10], fr)
            m = self.m
        if 8 in mg:
            m.coolant = mg[8]
        for grp in (5, 9, 11):
            if grp in mg:
                self.event("m", mg[grp])
        for grp in (6, 7, 8, 10):
            if grp in mg:
                self.event("m", mg[grp])

    def _modal_state(self, c: int, fr: Frame) -> None:
        """M70 save, M71 forget, M72 restore the modal state; M73: restore it on return."""
        if c == 70:
            self.saved_modal = self.save_modal()
        elif c == 71:
            self.saved_modal = None
        elif c == 72:
            if getattr(self, "saved_modal", None) is None:
                raise LineError("M72: no modal state saved by M70")
            self.restore_modal(self.saved_modal)
        else:
            if len(self.frames) == 1:
                raise LineError("M73 outside a subroutine")
            fr.m73 = self.save_modal()

    def _g_modes(self, m, g0, groups, w) -> None:
        """G4 dwell, then the modal G codes before motion: plane, units, tool length offset,
        coordinate system, path control, distance modes (set in ``m``)."""
        if g0 == 40:
            if "p" not in w or w["p"] < 0:
                raise LineError("G4 dwell needs P ≥ 0 (seconds)")
            self.event("dwell", w["p"])
        if 2 in groups:
            m.plane = groups[2] // 10
        if 6 in groups:
            m.units = groups[6] // 10
        if 8 in groups:
            self.tool_length(groups[8], w)
        if 12 in groups:
            self.select_coord(groups[12])
        if 13 in groups:
            g = groups[13]
            if g == 640:
                p = w.get("p", 0.0) * self.unit()
                # interp_convert.cc convert_control_mode: without Q the naive-CAM tolerance is P
                q = w.get("q", w.get("p", 0.0)) * self.unit()
                if p < 0 or q < 0:
                    raise LineError("G64 P and Q must be ≥ 0")
                m.path = ("blend", p, q)
            else:
                # G61 exact path (LinuxCNC's TC_TERM_COND_EXACT: a tangent junction runs
                # through), G61.1 exact stop (TC_TERM_COND_STOP)
                m.path = ("exact", "path" if g == 610 else "stop")
            self.flush()
        if 3 in groups:
            m.absolute = groups[3] == 900
        if 4 in groups:
            m.ijk_absolute = groups[4] == 901
        if 10 in groups:
            m.retract = groups[10] // 10

    def _g_motion(self, m, g0, groups, w) -> int | None:
        """The non-modal G10/G28/G30/G92 (they take the axis words), else the motion of the
        line in the motion mode of ``m`` (G53: in machine coordinates). Returns the canned
        cycle the line ran, if any (check_other_codes allows its words)."""
        motion = groups.get(1)
        self._arc_done = False
        axes = [a for a in AXES if a in w]
        if "@" in w or "^" in w:
            axes.append("@")
        if g0 in (100, 280, 281, 300, 301, 920, 921, 922, 923):
            self.nonmodal(g0, w, axes)
            axes_used = True
        else:
            axes_used = False
        prev = m.motion
        if motion is not None:
            m.motion = motion
        ran = None                                # LinuxCNC's motion_to_be
        if not axes_used and (motion not in (None, 800) or axes):
            mm = m.motion
            if mm is None or mm == 800:
                if axes:
                    raise LineError("axis words with no motion mode in force (G0/G1/G2/G3)")
            elif not axes and mm not in (0, 10, 20, 30):
                # interp_internal.cc enhance_block: a cycle or probe code needs an axis word
                raise LineError(f"All axes missing with motion code G{mm / 10:g}")
            elif mm in CYCLES:
                if g0 == 530:
                    raise LineError("G53 needs a G0 or G1 move")
                ran = mm
                self.cycle(mm, prev, w)
            else:
                self.motion(mm, w, axes, g0 == 530)
        elif g0 == 530 and not axes_used:
            raise LineError("G53 needs a G0 or G1 move")
        if motion is not None and motion not in CYCLES or ran is None and axes and not axes_used:
            self.cycle_il = None                  # convert_motion: a motion other than a cycle
        return ran

    def _program_stop(self, c: int) -> None:
        """M0/M1/M2/M30/M60, last on the line; M2 and M30 end the program."""
        self.event("m", c)
        if c in (2, 30):
            self.ended = True
            self.out.notes.append((self.cur_line, f"M{c}: end of program"))

    # ------------------------------------------------------------------ canonical output
    def flush(self) -> None:
        """A canon call that ends a G64 Q chain (see CanonProgram.flushes)."""
        self.out.flushes.append(len(self.out.moves))

    def event(self, kind, value):
        fr = self.frames[-1]
        self.out.events.append(CanonEvent(kind, self.cur_line, fr.src.name, value, len(self.out.moves)))

    def emit(self, kind, end, **kw):
        m = self.m
        fr = self.frames[-1]
        self.out.moves.append(CanonMove(kind, self.cur_line, fr.src.name, tuple(self.pos), tuple(end),
                                        None if kind == "rapid" else m.feed, m.path, **kw))
        self.pos = list(end)



def _plain(v: float) -> float:
    """convert_param_comment prints a value within TOLERANCE_EQUAL (1e-4) of 0 as 0."""
    return 0.0 if abs(v) < 1e-4 else v


def _read_text(name: str) -> str:
    try:
        data = FsPath(name).read_bytes()
    except OSError as e:
        raise RS274Error(name, 0, f"cannot read G-code file: {e.strerror}") from None
    if b"\0" in data:
        raise RS274Error(name, data[:data.index(b"\0")].count(b"\n") + 1, "not a text file (NUL byte)")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")       # CAM posts write Latin-1 comments; LinuxCNC reads them


def interpret(text: str, source: str = "<gcode>", **options) -> CanonProgram:
    """Run a program's text; options as :class:`Interpreter`."""
    return Interpreter(**options).run(text, source)
