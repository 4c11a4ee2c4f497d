"""O-word control flow, mixed into the Interpreter: as interp_o_word.cc's
convert_control_functions, where a sub/call/return/if/while/do/repeat/break/continue block sends
the program counter of the current frame (the jump targets are found once by owords.SourceFile)."""
from __future__ import annotations

from planners.paths.gcode.rs274.errors import LineError

# interp_internal.hh INTERP_SUB_ROUTINE_LEVELS: the main program is level 0, a call that would
# reach level 10 is "Too many subroutine levels" (interp_o_word.cc execute_call)
MAX_CALL_DEPTH = 10


class Frame:
    """One level of the call stack: the file and the next block to run, the subroutine's named
    locals, the caller's saved #1 … #30, the M73 state to restore, the repeat counts."""
    __slots__ = ("src", "pc", "named", "saved_numbered", "label", "m73", "call_line", "repeat")

    def __init__(self, src, pc, label=None, call_line=0):
        self.src, self.pc, self.label, self.call_line = src, pc, label, call_line
        self.named: dict[str, float] = {}
        self.saved_numbered = None
        self.m73 = None
        self.repeat: dict[int, int] = {}


class Flow:
    """Uses the Interpreter's frames, params, evaluate, find_sub and restore_modal."""

    def _loop(self):
        self.loops += 1
        if self.loops > self.max_loops:
            raise LineError(f"more than {self.max_loops} loop iterations (an endless loop?): stopped")

    def control(self, b, fr: Frame, pc: int) -> None:
        k = b.okey
        if k == "sub":                 # reached in the flow of the program: skip its body
            fr.pc = fr.src.jump[pc]
        elif k == "call":
            self._o_call(b, fr, pc)
        elif k in ("return", "endsub"):
            self._o_return(b, fr, k)
        elif k in ("if", "elseif", "else", "endif"):
            self._o_branch(b, fr, pc, k)
        else:
            self._o_loop(b, fr, pc, k)

    def _o_call(self, b, fr, pc: int) -> None:
        """A new frame: positional arguments in #1 … #30, the caller's locals saved."""
        label = b.olabel if isinstance(b.olabel, str) else f"{self.evaluate(b.olabel, fr):g}"
        args = [self.evaluate(a, fr) for a in b.oargs]
        if len(args) > 30:
            raise LineError("more than 30 subroutine arguments")
        if len(self.frames) >= MAX_CALL_DEPTH:
            raise LineError(f"Too many subroutine levels: O<{label}> call would nest {MAX_CALL_DEPTH} "
                            f"deep (LinuxCNC allows {MAX_CALL_DEPTH - 1})")
        f, at = self.find_sub(label, fr, pc + 1)
        new = Frame(f, at + 1, label, pc + 1)
        new.saved_numbered = self.params.save_locals()
        for i, v in enumerate(args, start=1):
            self.params.set(i, v)
        for i in range(len(args) + 1, 31):
            self.params.set(i, 0.0)
        self.frames.append(new)
        self.value_returned = 0.0

    def _o_return(self, b, fr, k: str) -> None:
        """return/endsub: the value, the caller's locals and (after M73) its modal state back."""
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

    def _o_branch(self, b, fr, pc: int, k: str) -> None:
        """if/elseif/else/endif: the first true branch of a chain runs, then on to endif."""
        src = fr.src
        if k in ("if", "elseif"):
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

    def _o_loop(self, b, fr, pc: int, k: str) -> None:
        """while/endwhile, do … while, repeat/endrepeat, break and continue; each turn back
        counts against max_loops."""
        src = fr.src
        if k == "while":
            if pc in src.do_of:                       # the closing "while" of a do … while
                if self.evaluate(b.oargs[0], fr) != 0.0:
                    self._loop()
                    fr.pc = src.do_of[pc] + 1
            elif self.evaluate(b.oargs[0], fr) == 0.0:
                fr.pc = src.jump[pc]
        elif k == "endwhile":
            self._loop()
            fr.pc = src.jump[pc]                      # back to the while (re-tests)
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
