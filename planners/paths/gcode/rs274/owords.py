"""O-word structure of one file, found once: subroutines, if/elseif/else/endif chains, loops
(while/endwhile, do/while, repeat/endrepeat) and where break/continue go. Labels match by
O number or name, as rs274ngc's control blocks do."""
from __future__ import annotations

from planners.paths.gcode.rs274.errors import LineError, RS274Error
from planners.paths.gcode.rs274.tokens import LINELEN, percent_bounds, too_long, tokenise


class SourceFile:
    """``main``: the program itself, whose '%' lines LinuxCNC reads as its bounds; a
    subroutine file's lone '%' lines are skipped (as before: LinuxCNC's handling of them
    depends on the main program and is not modelled)."""

    def __init__(self, name: str, text: str, main: bool = False):
        self.name = name
        self.blocks = []
        # with its line end: LinuxCNC counts it against LINELEN
        ends = text.splitlines(keepends=True)
        lines = text.splitlines()
        self.unclosed_percent = False
        if main:
            lines, self.unclosed_percent = percent_bounds(lines)
        else:
            lines = ["" if raw.strip() == "%" else raw for raw in lines]
        for raw, whole in zip(lines, ends):
            try:
                if len(whole) >= LINELEN - 3 and too_long(whole):
                    raise LineError(f"Command too long: a line of {len(whole.rstrip(chr(10) + chr(13)))} characters "
                                    f"(LinuxCNC reads at most {LINELEN - 3} and the line end)")
                self.blocks.append(tokenise(raw))
            except LineError as e:          # raised when (if) the line runs
                self.blocks.append(e)
        self.subs: dict[str, tuple[int, int]] = {}
        self.jump: dict[int, int] = {}
        self.next_branch: dict[int, int] = {}
        self.chain_head: dict[int, int] = {}
        self.do_of: dict[int, int] = {}
        self.loop_exit: dict[int, int] = {}
        self.taken: dict[int, bool] = {}
        self._scan()

    def _err(self, pc, msg):
        raise RS274Error(self.name, pc + 1, msg)

    def _scan(self):
        stack: list[tuple[str, str, int, list]] = []
        for pc, b in enumerate(self.blocks):
            if b is None or isinstance(b, LineError) or b.okey is None:
                continue
            k = b.okey
            lab = b.olabel if isinstance(b.olabel, str) else None
            if lab is None and k != "call":
                self._err(pc, f"O {k}: the label must be a number or <name>, not an expression")
            if k in ("sub", "if", "while", "do", "repeat"):
                if k == "while" and stack and stack[-1][0] == "do" and stack[-1][1] == lab:
                    do = stack.pop()[2]
                    self.do_of[pc] = do
                    self.loop_exit[do] = pc + 1
                    continue
                if k == "sub" and any(s[0] == "sub" for s in stack):
                    self._err(pc, f"O<{lab}> sub inside another subroutine")
                stack.append((k, lab, pc, [pc]))
            elif k in ("elseif", "else"):
                if not stack or stack[-1][0] != "if" or stack[-1][1] != lab:
                    self._err(pc, f"O{lab} {k} without a matching O{lab} if")
                stack[-1][3].append(pc)
            elif k in ("endsub", "endif", "endwhile", "endrepeat"):
                want = {"endsub": "sub", "endif": "if", "endwhile": "while", "endrepeat": "repeat"}[k]
                if not stack or stack[-1][0] != want or stack[-1][1] != lab:
                    self._err(pc, f"O{lab} {k} without a matching O{lab} {want}")
                _, _, start, chain = stack.pop()
                if want == "sub":
                    if lab in self.subs:
                        self._err(pc, f"O<{lab}> sub defined twice")
                    self.subs[lab] = (start, pc)
                    self.jump[start] = pc + 1
                elif want == "if":
                    chain.append(pc)
                    for a, nxt in zip(chain, chain[1:]):
                        self.next_branch[a] = nxt + (0 if self.blocks[nxt].okey == "elseif" else 1)
                        self.chain_head[a] = start
                        self.jump[a] = pc + 1
                    for a in chain:
                        self.chain_head[a] = start
                        self.jump[a] = pc + 1
                else:
                    self.jump[start] = pc + 1
                    self.jump[pc] = start
                    self.loop_exit[start] = pc + 1
            elif k in ("break", "continue"):
                for s in reversed(stack):
                    if s[0] in ("while", "do", "repeat") and s[1] == lab:
                        self.jump[pc] = s[2]
                        break
                else:
                    self._err(pc, f"O{lab} {k} outside an O{lab} loop")
            elif k == "return":
                if not any(s[0] == "sub" for s in stack):
                    pass                                  # checked when it runs
        if stack:
            k, lab, pc, _ = stack[-1]
            self._err(pc, f"O{lab} {k} is never closed")
