"""The RS274NGC interpreter: blocks → canonical moves, following LinuxCNC 2.9's rs274ngc.

Per block, the order of execution is rs274ngc's execute_block/convert_* order: O-word control,
parameter settings (after the whole line is read, so ``#1=2 #2=#1`` sees the old #1), F, S, T,
M6/M61, M3-5, M7-9, M70-73, other M codes, G4, plane, units, cutter compensation (G40 only),
tool length offset, coordinate system, path control, distance modes, retract mode, the
non-modal G10/G28/G30/G92/G53, motion, then M0/M1/M2/M30/M60.
"""
from __future__ import annotations

import math
from pathlib import Path as FsPath

from planners.rs274 import expr as X
from planners.rs274.canon import CanonEvent, CanonMove, CanonProgram
from planners.rs274.errors import LineError, RS274Error
from planners.rs274.modal import Modal
from planners.rs274.owords import SourceFile
from planners.rs274.params import Parameters

MM_PER_INCH = 25.4
# interp_internal.hh: R-form reach tolerance and the spiral tolerance of I/J/K arcs (mm)
RADIUS_TOLERANCE_MM = 0.00005 * MM_PER_INCH
CENTER_ARC_RADIUS_TOLERANCE_MM = 2 * 0.01 * math.sqrt(2)
CENTER_ARC_RADIUS_TOLERANCE_INCH = 2 * 0.001 * math.sqrt(2)
SPIRAL_RELATIVE_TOLERANCE = 0.001
TINY = 1e-12
MAX_CALL_DEPTH = 50
DEFAULT_MAX_LOOPS = 1_000_000

# G codes (×10, as interp_read.cc's read_g) → modal group
G_GROUP = {0: 1, 10: 1, 20: 1, 30: 1, 800: 1,
           40: 0, 100: 0, 280: 0, 281: 0, 300: 0, 301: 0, 530: 0, 920: 0, 921: 0, 922: 0, 923: 0,
           170: 2, 180: 2, 190: 2, 900: 3, 910: 3, 901: 4, 911: 4, 930: 5, 940: 5, 950: 5,
           200: 6, 210: 6, 400: 7, 430: 8, 431: 8, 490: 8, 980: 10, 990: 10,
           540: 12, 550: 12, 560: 12, 570: 12, 580: 12, 590: 12, 591: 12, 592: 12, 593: 12,
           610: 13, 611: 13, 640: 13, 970: 14, 80: 15}
UNSUPPORTED_G = {
    50: "G5 (cubic spline)", 51: "G5.1 (quadratic spline)", 52: "G5.2 (NURBS)", 70: "G7 (lathe diameter mode)",
    330: "G33 (spindle-synchronised motion)", 331: "G33.1 (rigid tapping)", 382: "G38.2 (probing)",
    383: "G38.3 (probing)", 384: "G38.4 (probing)", 385: "G38.5 (probing)", 730: "G73 (canned cycle)",
    740: "G74 (canned cycle)", 760: "G76 (threading cycle)", 810: "G81 (canned cycle)", 820: "G82 (canned cycle)",
    830: "G83 (canned cycle)", 840: "G84 (canned cycle)", 850: "G85 (canned cycle)", 860: "G86 (canned cycle)",
    870: "G87 (canned cycle)", 880: "G88 (canned cycle)", 890: "G89 (canned cycle)",
    410: "G41 (cutter radius compensation)", 420: "G42 (cutter radius compensation)",
    411: "G41.1 (cutter radius compensation)", 421: "G42.1 (cutter radius compensation)",
    432: "G43.2 (additional tool length offset)", 171: "G17.1 (UV plane)", 181: "G18.1 (WU plane)",
    191: "G19.1 (VW plane)", 930: "G93 (inverse-time feed)", 950: "G95 (feed per revolution)",
    960: "G96 (constant surface speed)", 520: "G52 (local offset)", 700: "G70 (lathe finishing cycle)",
    710: "G71 (lathe roughing cycle)", 720: "G72 (lathe facing cycle)", 150: "G15 (polar coordinates)",
    160: "G16 (polar coordinates)",
}
# interp_internal.hh: a line may carry one M code of each group
M_GROUP = {0: 4, 1: 4, 2: 4, 30: 4, 60: 4, 6: 6, 61: 6, 3: 7, 4: 7, 5: 7, 7: 8, 8: 8, 9: 8,
           48: 9, 49: 9, 50: 9, 51: 9, 52: 9, 53: 9, 70: 10, 71: 10, 72: 10, 73: 10,
           62: 5, 63: 5, 64: 5, 65: 5, 66: 5, 67: 5, 68: 5}
UNSUPPORTED_M = {19: "M19 (spindle orient)", 98: "M98 (Fanuc subroutine call)", 99: "M99 (Fanuc return)"}
PLANES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}   # (first, second, normal) axis indices
AXES = "xyz"
_ROTARY = "abcuvw"


class Frame:
    __slots__ = ("src", "pc", "named", "saved_numbered", "label", "m73", "call_line", "repeat")

    def __init__(self, src, pc, label=None, call_line=0):
        self.src, self.pc, self.label, self.call_line = src, pc, label, call_line
        self.named: dict[str, float] = {}
        self.saved_numbered = None
        self.m73 = None
        self.repeat: dict[int, int] = {}


class Interpreter:
    """Run one program. ``start``: the machine position before it (mm); ``tools``: tool number
    → {"Z": length offset mm, …}; ``subroutine_path``: folders searched for ``name.ngc`` when
    ``O<name> call`` names no subroutine of the file; ``block_delete``: skip '/' lines."""

    def __init__(self, start=(0.0, 0.0, 0.0), tools=None, subroutine_path=(), block_delete=False,
                 max_loops: int = DEFAULT_MAX_LOOPS):
        self.pos = [float(v) for v in start]      # machine position (mm)
        self.tools = tools or {}
        self.sub_path = [FsPath(p) for p in subroutine_path]
        self.block_delete = block_delete
        self.max_loops = max_loops
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

    # ------------------------------------------------------------------ coordinates
    def unit(self) -> float:
        return MM_PER_INCH if self.m.units == 20 else 1.0

    def to_machine(self, p):
        x, y, z = p
        if self.rot:
            t = math.radians(self.rot)
            c, s = math.cos(t), math.sin(t)
            x, y = x * c - y * s, x * s + y * c
        o, g, t_ = self.g5x, self.g92, self.tlo
        return [x + o[0] + g[0] + t_[0], y + o[1] + g[1] + t_[1], z + o[2] + g[2] + t_[2]]

    def to_program(self, q):
        o, g, t_ = self.g5x, self.g92, self.tlo
        x, y, z = q[0] - o[0] - g[0] - t_[0], q[1] - o[1] - g[1] - t_[1], q[2] - o[2] - g[2] - t_[2]
        if self.rot:
            t = math.radians(-self.rot)
            c, s = math.cos(t), math.sin(t)
            x, y = x * c - y * s, x * s + y * c
        return [x, y, z]

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
    def source(self, name: str, text: str | None = None) -> SourceFile:
        f = self._files.get(name)
        if f is None:
            f = SourceFile(name, text if text is not None else _read_text(name))
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
        main = self.source(source, text)
        self.out = CanonProgram(source, tuple(self.pos))
        self.frames = [Frame(main, 0)]
        self.cur_line = 0
        while not self.ended:
            fr = self.frames[-1]
            src = fr.src
            if fr.pc >= len(src.blocks):
                if len(self.frames) > 1:
                    raise RS274Error(src.name, fr.call_line, f"O<{fr.label}>: the file ends inside the subroutine")
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

    # ------------------------------------------------------------------ O-words
    def _loop(self):
        self.loops += 1
        if self.loops > self.max_loops:
            raise LineError(f"more than {self.max_loops} loop iterations (an endless loop?): stopped")

    def control(self, b, fr: Frame, pc: int) -> None:
        src, k = fr.src, b.okey
        if k == "sub":                 # reached in the flow of the program: skip its body
            fr.pc = src.jump[pc]
        elif k == "call":
            label = b.olabel if isinstance(b.olabel, str) else f"{self.evaluate(b.olabel, fr):g}"
            args = [self.evaluate(a, fr) for a in b.oargs]
            if len(args) > 30:
                raise LineError("more than 30 subroutine arguments")
            if len(self.frames) >= MAX_CALL_DEPTH:
                raise LineError(f"subroutine calls nested deeper than {MAX_CALL_DEPTH}")
            f, at = self.find_sub(label, fr, pc + 1)
            new = Frame(f, at + 1, label, pc + 1)
            new.saved_numbered = self.params.save_locals()
            for i, v in enumerate(args, start=1):
                self.params.set(i, v)
            for i in range(len(args) + 1, 31):
                self.params.set(i, 0.0)
            self.frames.append(new)
            self.value_returned = 0.0
        elif k in ("return", "endsub"):
            if len(self.frames) == 1:
                if k == "return":
                    raise LineError("O return outside a subroutine")
                return
            if b.oargs:
                self.value = self.evaluate(b.oargs[0], fr)
                self.value_returned = 1.0
            done = self.frames.pop()
            self.params.restore_locals(done.saved_numbered)
            if done.m73 is not None:                  # M73: restore the modal state on return
                self.restore_modal(done.m73)
        elif k in ("if", "elseif"):
            if k == "elseif" and src.taken.get(src.chain_head[pc]):
                fr.pc = src.jump[pc]                   # an earlier branch ran: go to endif
                return
            cond = self.evaluate(b.oargs[0], fr)
            src.taken[src.chain_head[pc]] = cond != 0.0
            if cond == 0.0:
                fr.pc = src.next_branch[pc]
        elif k == "else":
            if src.taken.get(src.chain_head[pc]):
                fr.pc = src.jump[pc]
        elif k == "endif":
            pass
        elif k == "while":
            if pc in src.do_of:                       # the closing "while" of a do … while
                if self.evaluate(b.oargs[0], fr) != 0.0:
                    self._loop()
                    fr.pc = src.do_of[pc] + 1
            elif self.evaluate(b.oargs[0], fr) == 0.0:
                fr.pc = src.jump[pc]
        elif k == "endwhile":
            self._loop()
            fr.pc = src.jump[pc]                      # back to the while (re-tests)
        elif k == "do":
            pass
        elif k == "repeat":
            n = self.evaluate(b.oargs[0], fr)
            fr.repeat[pc] = int(n)
            if fr.repeat[pc] <= 0:
                fr.pc = src.jump[pc]
        elif k == "endrepeat":
            start = src.jump[pc]
            fr.repeat[start] -= 1
            if fr.repeat[start] > 0:
                self._loop()
                fr.pc = start + 1
        elif k == "break":
            fr.pc = src.loop_exit[src.jump[pc]]
        elif k == "continue":
            loop = src.jump[pc]
            kind = src.blocks[loop].okey
            if kind == "repeat":
                fr.pc = src.loop_exit[loop] - 1      # the endrepeat: counts down, maybe loops
            elif kind == "do":
                fr.pc = src.loop_exit[loop] - 1      # the closing while
            else:
                self._loop()
                fr.pc = loop

    # ------------------------------------------------------------------ one block
    def execute(self, b, fr: Frame) -> None:
        m = self.m
        fast = b.fast
        if fast is not None:
            # the common CAM line (constant X/Y/Z/I/J/K/R/F words, at most a G0-G3): same
            # semantics as the general path below, without its per-group bookkeeping
            motion, w = fast
            if "f" in w:
                f = w["f"]
                if f < 0:
                    raise LineError(f"negative feed rate F{f:g}")
                m.feed = f * (MM_PER_INCH if m.units == 20 else 1.0)
            if motion is not None:
                m.motion = motion
            mm = m.motion
            axes = [a for a in AXES if a in w]
            self._arc_done = False
            if motion is not None or axes:
                if mm is None or mm == 800:
                    if axes:
                        raise LineError("axis words with no motion mode in force (G0/G1/G2/G3)")
                else:
                    self.motion(mm, dict(w), axes, False)
            for letter in w:
                if letter in "ijkr" and not self._arc_done:
                    raise LineError(f"{letter.upper()} word with no code on the line that uses it")
            return
        if b.comment is not None:
            c = b.comment.strip()
            if c[:4].lower() in ("msg,", "debu", "prin"):
                self.event("message", c)
        if not b.words and not b.assigns:
            return
        ev = self.evaluate
        w: dict[str, float] = {}
        gs: list[int] = []
        ms: list[int] = []
        for letter, node in b.words:
            v = node if isinstance(node, float) else ev(node, fr)
            if not math.isfinite(v):
                raise LineError(f"{letter.upper()} value is not finite")
            if letter == "g":
                g10 = round(v * 10)
                if abs(v * 10 - g10) > 1e-6:
                    raise LineError(f"G{v:g}: G codes have at most one decimal")
                gs.append(g10)
            elif letter == "m":
                if abs(v - round(v)) > 1e-6:
                    raise LineError(f"M{v:g}: M codes are integers")
                ms.append(int(round(v)))
            else:
                if letter in w:
                    raise LineError(f"{letter.upper()} word given twice on one line")
                w[letter] = v
        if b.assigns:
            vals = [(t, ev(node, fr)) for t, node in b.assigns]
        # -- modal groups ----------------------------------------------------------
        groups: dict[int, int] = {}
        for g in gs:
            if g in UNSUPPORTED_G:
                raise LineError(f"{UNSUPPORTED_G[g]} is not supported")
            grp = G_GROUP.get(g)
            if grp is None:
                raise LineError(f"unknown or unsupported G code G{g / 10:g}")
            if grp in groups:
                # interp_read.cc read_g: G80 beside another motion code yields to it
                if grp == 1 and 800 in (g, groups[1]):
                    groups[1] = groups[1] if g == 800 else g
                    continue
                raise LineError(f"G{groups[grp] / 10:g} and G{g / 10:g} are in the same modal group")
            groups[grp] = g
        mgroups: dict[int, int] = {}
        for mc in ms:
            if mc in UNSUPPORTED_M:
                raise LineError(f"{UNSUPPORTED_M[mc]} is not supported")
            grp = M_GROUP.get(mc, 11 if 100 <= mc <= 199 else None)
            if grp is None:
                raise LineError(f"unknown M code M{mc}")
            if grp in mgroups and not (grp == 8 and {mc, mgroups[grp]} == {7, 8}):
                raise LineError(f"M{mgroups[grp]} and M{mc} are in the same modal group")
            mgroups[grp] = mc
        for letter in w:
            if letter in _ROTARY:
                raise LineError(f"{letter.upper()} axis word: rotary/extra axes are not supported (X, Y, Z only)")
        if b.assigns:
            for t, v in vals:
                self.assign(t, v, fr)
        # -- F S T ------------------------------------------------------------------
        u = MM_PER_INCH if groups.get(6, m.units * 10) == 200 else 1.0
        if "f" in w:
            if w["f"] < 0:
                raise LineError(f"negative feed rate F{w['f']:g}")
            m.feed = w["f"] * u
        if "s" in w:
            if w["s"] < 0:
                raise LineError(f"negative spindle speed S{w['s']:g}")
            m.speed = w["s"]
        if "t" in w:
            if w["t"] < 0 or w["t"] != int(w["t"]):
                raise LineError(f"T{w['t']:g}: tool numbers are integers ≥ 0")
            m.selected_tool = int(w["t"])
        mg = mgroups
        if 6 in mg:
            if mg[6] == 6:
                self.tool = m.selected_tool
                self.event("tool", self.tool)
            else:                                     # M61 Q: set the tool number, no change
                if "q" not in w or w["q"] < 0:
                    raise LineError("M61 needs Q ≥ 0 (the tool number)")
                self.tool = int(w["q"])
            self.params.set(5400, float(self.tool))
        if 7 in mg:
            m.spindle = mg[7]
        if 8 in mg:
            m.coolant = mg[8]
        if 10 in mg:
            c = mg[10]
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
        for grp in (5, 9, 11):
            if grp in mg:
                self.event("m", mg[grp])
        for grp in (6, 7, 8, 10):
            if grp in mg:
                self.event("m", mg[grp])
        # -- G codes, in execution order --------------------------------------------
        g0 = groups.get(0)
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
                q = w.get("q", 0.0) * self.unit()
                if p < 0 or q < 0:
                    raise LineError("G64 P and Q must be ≥ 0")
                m.path = ("blend", p, q)
            else:
                m.path = ("exact",)
        if 3 in groups:
            m.absolute = groups[3] == 900
        if 4 in groups:
            m.ijk_absolute = groups[4] == 901
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
        if motion is not None:
            m.motion = motion
        if not axes_used and (motion not in (None, 800) or axes):
            mm = m.motion
            if mm is None or mm == 800:
                if axes:
                    raise LineError("axis words with no motion mode in force (G0/G1/G2/G3)")
            else:
                self.motion(mm, w, axes, g0 == 530)
        elif g0 == 530 and not axes_used:
            raise LineError("G53 needs a G0 or G1 move")
        # interp_check.cc's check_other_codes: a word no code on the line uses is an error
        used = set("xyzfstgmn@^")
        if g0 == 40:
            used.add("p")
        if g0 == 100:
            used |= set("lpr")
        if groups.get(13) == 640:
            used |= set("pq")
        if 8 in groups:
            used.add("h")
        if 6 in mg and mg[6] == 61:
            used.add("q")
        if 5 in mg or 9 in mg:
            used |= set("pqle")
        if self._arc_done:
            used |= set("ijkrp")
        for letter in w:
            if letter not in used:
                raise LineError(f"{letter.upper()} word with no code on the line that uses it")
        for grp in (4,):
            if grp in mg:
                c = mg[grp]
                self.event("m", c)
                if c in (2, 30):
                    self.ended = True
                    self.out.notes.append((self.cur_line, f"M{c}: end of program"))

    def event(self, kind, value):
        fr = self.frames[-1]
        self.out.events.append(CanonEvent(kind, self.cur_line, fr.src.name, value, len(self.out.moves)))

    # ------------------------------------------------------------------ modal helpers
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
        idx = {540: 1, 550: 2, 560: 3, 570: 4, 580: 5, 590: 6, 591: 7, 592: 8, 593: 9}[g]
        self.m.coord = g / 10
        self.m.coord_index = idx
        self.params.set(5220, float(idx))
        base = 5201 + 20 * idx
        self.g5x = [self.params.get(base + i) for i in range(3)]
        self.rot = self.params.get(5210 + 20 * idx)

    def tool_length(self, g: int, w) -> None:
        if g == 490:
            self.tlo = [0.0, 0.0, 0.0]
        elif g == 430:
            h = int(w["h"]) if "h" in w else self.tool
            if self.tools and h != 0 and h not in self.tools:
                raise LineError(f"G43 H{h}: tool {h} is not in the tool table")
            t = self.tools.get(h, {})
            self.tlo = [t.get("X", 0.0), t.get("Y", 0.0), t.get("Z", 0.0)]
        else:                                     # G43.1: dynamic offset from the axis words
            u = self.unit()
            self.tlo = [w.get(a, 0.0) * u for a in AXES]
            for a in AXES:
                w.pop(a, None)

    def nonmodal(self, g: int, w, axes) -> None:
        if "@" in axes:
            raise LineError(f"polar coordinates (@ ^) with G{g / 10:g}")
        u = self.unit()
        prog = self.to_program(self.pos)
        if g == 100:
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
        elif g == 920:
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
        elif g == 923:
            self.g92 = [self.params.get(5211 + i) for i in range(3)]
        elif g in (281, 301):                       # store the current (machine) position
            base = 5161 if g == 281 else 5181
            for i in range(3):
                self.params.set(base + i, self.pos[i])
        else:                                       # G28 / G30: via an intermediate point
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

    def emit(self, kind, end, **kw):
        m = self.m
        fr = self.frames[-1]
        self.out.moves.append(CanonMove(kind, self.cur_line, fr.src.name, tuple(self.pos), tuple(end),
                                        None if kind == "rapid" else m.feed, m.path, **kw))
        self.pos = list(end)

    # ------------------------------------------------------------------ motion
    def polar(self, w, prog, endp, axes) -> None:
        # as interp_find.cc's find_ends: @ (distance) and ^ (angle, degrees) about the origin,
        # or, in G91, added to the current point's distance and angle
        if "x" in axes or "y" in axes:
            raise LineError("X or Y words with polar coordinates (@ ^)")
        px, py = prog[0], prog[1]
        u = self.unit()
        if self.m.absolute:
            if "@" in w and "^" in w:
                px, py = w["@"] * u * math.cos(math.radians(w["^"])), w["@"] * u * math.sin(math.radians(w["^"]))
            elif "@" in w:
                if px == 0 and py == 0:
                    raise LineError("polar @ at the origin needs an angle ^")
                t = math.atan2(py, px)
                px, py = w["@"] * u * math.cos(t), w["@"] * u * math.sin(t)
            else:
                r = math.hypot(py, px)
                px, py = r * math.cos(math.radians(w["^"])), r * math.sin(math.radians(w["^"]))
        else:
            if px == 0 and py == 0:
                raise LineError("incremental polar motion at the origin is indeterminate")
            if "@" in w:
                t = math.atan2(py, px)
                r = math.hypot(py, px) + w["@"] * u
                px, py = r * math.cos(t), r * math.sin(t)
            if "^" in w:
                t = math.atan2(py, px) + math.radians(w["^"])
                r = math.hypot(py, px)
                px, py = r * math.cos(t), r * math.sin(t)
        endp[0], endp[1] = px, py

    def motion(self, mm: int, w, axes, g53: bool) -> None:
        m = self.m
        u = self.unit()
        prog = self.to_program(self.pos)
        axes = [a for a in axes if a != "@"]
        if g53:
            if mm not in (0, 10):
                raise LineError("G53 needs a G0 or G1 move")
            if not m.absolute:
                raise LineError("G53 with G91 (incremental) in force")
            end = list(self.pos)
            for a in axes:
                end[AXES.index(a)] = w[a] * u
        else:
            endp = list(prog)
            for a in axes:
                i = AXES.index(a)
                endp[i] = w[a] * u if m.absolute else prog[i] + w[a] * u
        if "@" in w or "^" in w:
            if g53:
                raise LineError("polar coordinates (@ ^) with G53")
            self.polar(w, prog, endp, axes)
        if mm in (0, 10):
            for letter in "ijkr":
                if letter in w:
                    raise LineError(f"{letter.upper()} word on a G{mm // 10} (straight) move")
            if mm == 10 and not m.feed:
                raise LineError("G1 feed move with a zero feed rate: give F")
            self.emit("rapid" if mm == 0 else "feed", end if g53 else self.to_machine(endp))
            return
        # G2 / G3: as interp_convert.cc's convert_arc2 and interp_arc.cc's arc_data_ijk/arc_data_r
        if not m.feed:
            raise LineError(f"G{mm // 10} arc with a zero feed rate: give F")
        i1, i2, ia = PLANES[m.plane]
        letters = "ijk"
        allowed = {letters[i1], letters[i2]}
        offs = [c for c in "ijk" if c in w]
        bad = [c for c in offs if c not in allowed]
        if bad:
            raise LineError(f"{bad[0].upper()} word for an arc in the G{m.plane} plane")
        if self.rot and m.plane != 17:
            raise LineError("G18/G19 arc with an XY rotation in force is not supported")
        turns = 1
        if "p" in w:
            turns = int(round(w["p"]))
            if abs(w["p"] - turns) > 1e-6 or turns < 1:
                raise LineError(f"arc P{w['p']:g} (turns) must be an integer ≥ 1")
        s1, s2 = prog[i1], prog[i2]
        e1, e2 = endp[i1], endp[i2]
        if "r" in w:
            if offs:
                raise LineError("R and I/J/K given together: use one arc form")
            if e1 == s1 and e2 == s2:
                raise LineError("R-form arc whose end is its start: a full circle needs I/J/K")
            r = w["r"] * u
            ar = abs(r)
            mid1, mid2 = (e1 + s1) / 2.0, (e2 + s2) / 2.0
            half = math.hypot(mid1 - e1, mid2 - e2)
            if half - ar > RADIUS_TOLERANCE_MM * (1 if u == 1.0 else 1) and half - ar > (
                    RADIUS_TOLERANCE_MM if u == 1.0 else 0.00005 * MM_PER_INCH):
                raise LineError(f"arc radius R{abs(w['r']):g} is too small to reach the end point")
            if ar == 0.0 or half / ar > 1 - TINY:
                half = ar
            if (mm == 20 and r > 0) or (mm == 30 and r < 0):
                theta = math.atan2(e2 - s2, e1 - s1) - math.pi / 2
            else:
                theta = math.atan2(e2 - s2, e1 - s1) + math.pi / 2
            off = ar * math.cos(math.asin(half / ar)) if ar else 0.0
            c1, c2 = mid1 + off * math.cos(theta), mid2 + off * math.sin(theta)
        else:
            if not offs:
                raise LineError(f"G{mm // 10} arc needs I/J/K (centre) or R")
            o = {c: w[c] * u for c in offs}
            a1, a2 = o.get(letters[i1], 0.0), o.get(letters[i2], 0.0)
            if m.ijk_absolute:
                c1, c2 = a1, a2
            else:
                c1, c2 = s1 + a1, s2 + a2
            r1 = math.hypot(c1 - s1, c2 - s2)
            r2 = math.hypot(c1 - e1, c2 - e2)
            rtol = RADIUS_TOLERANCE_MM
            if r1 < rtol or r2 < rtol:
                raise LineError(f"zero-radius arc (radius to start {r1:.6g} mm, to end {r2:.6g} mm)")
            err = abs(r1 - r2)
            tol = CENTER_ARC_RADIUS_TOLERANCE_MM if m.units == 21 else CENTER_ARC_RADIUS_TOLERANCE_INCH * MM_PER_INCH
            if err > tol * 100.0 or (err / max(r1, r2) > SPIRAL_RELATIVE_TOLERANCE and err > tol):
                raise LineError(f"arc radius to end ({r2:.6g} mm) differs from radius to start ({r1:.6g} mm) "
                                f"by {err:.3g} mm (LinuxCNC accepts {tol:.3g} mm or 0.1 %)")
        cen = list(prog)
        cen[i1], cen[i2] = c1, c2
        turn = -turns if mm == 20 else turns
        self.emit("arc", self.to_machine(endp), center=tuple(self.to_machine(cen)), plane=m.plane, turn=turn)
        self._arc_done = True


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
