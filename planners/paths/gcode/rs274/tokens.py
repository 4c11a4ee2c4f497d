"""Tokeniser: one source line → a parsed block (read once; run as often as control flow says).

As rs274ngc's close_and_downcase/read_text: comments ``( … )`` (no nesting) and ``;`` are
taken out, spaces and tabs are removed everywhere else (so ``X1 0.5`` is X10.5) and letters
are lower-cased. A leading ``/`` marks a block-delete line; ``N…`` may start the line; an
O-word line is a control statement; every other line is words (letter + value) and parameter
settings ``#n=value`` / ``#<name>=value``.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

from planners.paths.gcode.rs274.errors import LineError
from planners.paths.gcode.rs274.expr import Reader

# the common CAM line: an optional leading N, then words of the letters in LETTERS (no O,
# @ or ^) with plain numbers; the letters are checked here rather than word by word after it
_SIMPLE = re.compile(r"(?:n[+-]?(?:\d+\.?\d*|\.\d+))?(?:[abcdfghijklmpqrstuvwxyz][+-]?(?:\d+\.?\d*|\.\d+))*")
_SIMPLE_WORD = re.compile(r"([a-z])([+-]?(?:\d+\.?\d*|\.\d+))")
LETTERS = set("abcdfghijklmnpqrstuvwxyz@^")   # @ ^: polar distance and angle
_OKEYS = ("sub", "endsub", "call", "return", "if", "elseif", "else", "endif", "while", "endwhile",
          "do", "repeat", "endrepeat", "break", "continue")


@dataclass(slots=True)
class Block:
    delete: bool = False                  # leading '/'
    words: list = field(default_factory=list)        # (letter, value-node)
    assigns: list = field(default_factory=list)      # (param-node, value-node)
    okey: str | None = None               # O-word keyword
    olabel: object = None                 # O label: str name, or a value-node
    oargs: list = field(default_factory=list)        # call arguments / the condition
    comment: str | None = None            # the last comment's text (for MSG/DEBUG notes)
    fast: tuple | None = None             # (motion G×10 or None, {letter: value}): a plain line


def strip_comments(raw: str) -> tuple[str, str | None]:
    """The line without comments, spaces and case; and its last comment."""
    if "(" not in raw and ";" not in raw and ")" not in raw:
        return "".join(raw.split()).lower(), None
    out, i, comment = [], 0, None
    while i < len(raw):
        c = raw[i]
        if c == "(":
            j = raw.find(")", i + 1)
            if j < 0:
                raise LineError("unclosed comment '('")
            if "(" in raw[i + 1:j]:
                raise LineError("nested comment '(' inside '( … )'")
            comment = raw[i + 1:j]
            i = j + 1
        elif c == ";":
            break                   # read_semicolon: the rest of the line, never a (MSG,…)
        elif c == ")":
            raise LineError("')' without '('")
        else:
            if not c.isspace():
                out.append(c)
            i += 1
    return "".join(out).lower(), comment


def percent_lines(lines: list[str]) -> list[str]:
    """The lines of a main program that LinuxCNC reads (rs274ngc_pre.cc Interp::open,
    interp_read.cc read_text): when its first non-blank line is a lone '%', the program ends
    at the next lone '%' and what follows is never read; both '%' lines become blank."""
    return percent_bounds(lines)[0]


def percent_bounds(lines: list[str]) -> tuple[list[str], bool]:
    """percent_lines, and whether the program opens with '%' and never closes it (LinuxCNC's
    "File ended with no percent sign" when it runs to the end of the file)."""
    first = next((i for i, raw in enumerate(lines) if raw.strip()), None)
    if first is None or lines[first].strip() != "%":
        return lines, False
    out = lines[:first] + [""]
    for raw in lines[first + 1:]:
        # read_text compares after removing trailing white space, then spaces and tabs
        if raw.rstrip().replace(" ", "").replace("\t", "") == "%":
            return out + [""], False
        out.append(raw)
    return out, True


LINELEN = 255           # linuxcnc.h: read_text's fgets buffer; a line filling it is refused


def too_long(raw: str) -> bool:
    """interp_read.cc read_text: fgets reads at most LINELEN − 1 bytes, and a line (with its
    newline) that fills them is "Command too long": 252 characters and a newline are the most."""
    return len(raw) >= LINELEN - 1 - 2 and len(raw.encode("utf-8", "replace")) >= LINELEN - 1


def tokenise(raw: str) -> Block | None:
    """A parsed block, or None for a line with nothing to do (blank, comment)."""
    s, comment = strip_comments(raw)
    if not s:
        return Block(comment=comment) if comment is not None else None
    if s == "%":
        # the opening and closing '%' of a program are gone (percent_lines); any other '%'
        # line, or one with a comment, stops LinuxCNC: "Bad character '%' used"
        raise LineError("'%' here: only a lone '%' as the first line opens a program, and the "
                        "next lone '%' ends it")
    delete = s[0] == "/"
    if delete:
        s = s[1:]
    if _SIMPLE.fullmatch(s):                 # the common CAM line: words with plain numbers
        words = [(letter, float(v)) for letter, v in _SIMPLE_WORD.findall(s) if letter != "n"]
        # every field given: the default factories' empty lists cost ~8 % of this function
        return Block(delete=delete, words=words, assigns=[], okey=None, olabel=None, oargs=[], comment=comment,
                     fast=None if comment is not None or delete else _fast_of(words))
    b = Block(delete=delete, comment=comment)
    r = Reader(s)
    if r.peek() == "n":                       # N number: first on the line, then ignored
        r.i += 1
        j = r.i
        while r.peek().isdigit() or r.peek() == ".":
            r.i += 1
        if r.i == j:
            r.fail("N needs a number")
    if r.peek() == "o":
        _oword(r, b)
        return b
    while r.i < len(s):
        c = r.peek()
        if c == "#":
            p = r.parameter()
            if r.peek() != "=":
                r.fail("a parameter on its own: expected '=' to set it")
            r.i += 1
            b.assigns.append((p, r.value()))
        elif c in LETTERS:
            if c == "n":
                r.fail("N word not at the start of the line")
            r.i += 1
            if r.i >= len(s):
                r.fail(f"{c.upper()} word without a value")
            b.words.append((c, r.value()))
        elif c == "o":
            r.fail("O-word not at the start of the line")
        else:
            r.fail("unexpected character")
    return b


def _oword(r: Reader, b: Block) -> None:
    r.i += 1
    if r.peek() == "<":
        j = r.s.find(">", r.i)
        if j < 0:
            r.fail("O-word name without closing '>'")
        b.olabel = r.s[r.i + 1:j]
        r.i = j + 1
    else:
        v = r.value()
        b.olabel = v if not isinstance(v, float) else f"{v:g}"
    for k in _OKEYS:
        if r.s.startswith(k, r.i) and not (k == "else" and r.s.startswith("elseif", r.i)) \
                and not (k == "endsub" and False):
            # longest keyword first matters for else/elseif, end*/… handled by the order
            b.okey = k
            r.i += len(k)
            break
    else:
        r.fail("unknown O-word keyword (sub, call, if, while, do, repeat, …)")
    if b.okey == "call":
        while r.peek() == "[":
            b.oargs.append(r.expression())
    elif b.okey in ("if", "elseif", "while", "repeat"):
        if r.peek() != "[":
            r.fail(f"O {b.okey} needs a [condition]")
        b.oargs.append(r.expression())
    elif b.okey in ("return", "endsub") and r.peek() == "[":
        b.oargs.append(r.expression())
    if r.i < len(r.s):
        r.fail(f"unexpected text after O {b.okey}")


_FAST_G = {0.0: 0, 1.0: 10, 2.0: 20, 3.0: 30}


def _fast_of(words: list) -> tuple | None:
    """Block.fast of a line of ``words`` without comment or '/': (motion, {letter: value}) when
    they are constant X Y Z I J K R F words and at most one G0/G1/G2/G3, else None."""
    w, motion = {}, None
    for letter, v in words:
        if letter == "g":
            if motion is not None or v not in _FAST_G:
                return None
            motion = _FAST_G[v]
        elif letter in "xyzijkrf" and letter not in w:
            w[letter] = v
        else:
            return None
    return motion, w
