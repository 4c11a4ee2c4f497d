"""Expressions: ``[…]`` with binary operators and functions, as rs274ngc's read_real_expression.

An expression is parsed once into a tree of tuples (floats stay floats) and evaluated each time
its line runs (a line inside a loop is parsed once). Precedence as interp_read.cc's
``precedence()``: ``**`` > ``* / MOD`` > ``+ -`` > ``EQ NE GT GE LT LE`` > ``AND OR XOR``,
left to right within one level.
"""
from __future__ import annotations

import math

from planners.paths.gcode.rs274.errors import LineError

TOLERANCE_EQUAL = 1e-6     # interp_internal.hh: EQ/NE/GE/LE compare within this

_BINOPS = [("**", 6), ("*", 5), ("/", 5), ("mod", 5), ("+", 4), ("-", 4),
           ("eq", 3), ("ne", 3), ("gt", 3), ("ge", 3), ("lt", 3), ("le", 3),
           ("and", 2), ("xor", 2), ("or", 2)]
_FUNCS = ("abs", "acos", "asin", "atan", "cos", "exp", "fix", "fup", "round", "ln", "sin",
          "sqrt", "tan", "exists")
MAX_DEPTH = 50              # nesting of brackets / parameters: beyond it a clear error


class Reader:
    """Cursor over one line's text: spaces removed and lower-cased outside comments."""

    __slots__ = ("s", "i", "depth")

    def __init__(self, s: str, i: int = 0):
        self.s, self.i, self.depth = s, i, 0

    def peek(self) -> str:
        return self.s[self.i] if self.i < len(self.s) else ""

    def fail(self, what: str):
        near = self.s[self.i:self.i + 12] or "end of line"
        raise LineError(f"cannot read '{near}': {what}")

    def number(self) -> float:
        s, i = self.s, self.i
        j = i
        if j < len(s) and s[j] in "+-":
            j += 1
        k = j
        while k < len(s) and (s[k].isdigit() or s[k] == "."):
            k += 1
        txt = s[i:k]
        if k == j or txt.count(".") > 1 or s[j:k] == ".":
            self.fail("bad number")
        self.i = k
        return float(txt)

    def value(self):
        """read_real_value: a number, [expression], #parameter, a function, or a signed one."""
        self.depth += 1
        if self.depth > MAX_DEPTH:
            self.fail(f"expression nested deeper than {MAX_DEPTH}")
        try:
            c = self.peek()
            if c == "[":
                return self.expression()
            if c == "#":
                return self.parameter()
            if c.isalpha():
                return self.function()
            if c in "+-" and self.i + 1 < len(self.s) and self.s[self.i + 1] in "[#abcdefghijklmnopqrstuvwxyz":
                self.i += 1
                v = self.value()
                if c == "+":
                    return v
                return -v if isinstance(v, float) else ("neg", v)
            if c == "" :
                self.fail("missing value")
            return self.number()
        finally:
            self.depth -= 1

    def parameter(self):
        """#n, #[expr], ##n, #<name>: ('par', index-node) or ('npar', name)."""
        self.i += 1                                   # '#'
        if self.peek() == "<":
            j = self.s.find(">", self.i)
            if j < 0:
                self.fail("named parameter without closing '>'")
            name = self.s[self.i + 1:j]
            if not name:
                self.fail("empty parameter name")
            self.i = j + 1
            return ("npar", name)
        return ("par", self.value())

    def function(self):
        s, i = self.s, self.i
        for f in _FUNCS:
            if s.startswith(f, i):
                self.i = i + len(f)
                if self.peek() != "[":
                    self.fail(f"function {f.upper()} needs '['")
                if f == "exists":
                    self.i += 1
                    if self.peek() != "#":
                        self.fail("EXISTS needs a #<name> parameter")
                    p = self.parameter()
                    if p[0] != "npar" or self.peek() != "]":
                        self.fail("EXISTS needs one #<name> parameter")
                    self.i += 1
                    return ("exists", p[1])
                a = self.expression()
                if f == "atan":
                    if self.peek() != "/":
                        self.fail("ATAN needs the form ATAN[y]/[x]")
                    self.i += 1
                    if self.peek() != "[":
                        self.fail("ATAN needs the form ATAN[y]/[x]")
                    return ("atan", a, self.expression())
                return ("fn", f, a)
        self.fail("unknown word or function")

    def expression(self):
        """[a op b op c …]: operands and operators, then a precedence tree."""
        self.i += 1                                   # '['
        operands, ops = [self.value()], []
        while True:
            c = self.peek()
            if c == "]":
                self.i += 1
                break
            if c == "":
                self.fail("expression without closing ']'")
            for name, prec in _BINOPS:
                if self.s.startswith(name, self.i):
                    self.i += len(name)
                    ops.append((name, prec))
                    break
            else:
                self.fail("unknown operator")
            operands.append(self.value())
        # shunting by precedence, left to right within a level
        out, stack = [operands[0]], []
        for (op, prec), rhs in zip(ops, operands[1:]):
            while stack and stack[-1][1] >= prec:
                o = stack.pop()[0]
                b, a = out.pop(), out.pop()
                out.append(_fold(o, a, b))
            stack.append((op, prec))
            out.append(rhs)
        while stack:
            o = stack.pop()[0]
            b, a = out.pop(), out.pop()
            out.append(_fold(o, a, b))
        return out[0]


def _fold(op, a, b):
    if isinstance(a, float) and isinstance(b, float):
        return binary(op, a, b)
    return ("bin", op, a, b)


def binary(op: str, a: float, b: float) -> float:
    # as interp_execute.cc's execute_binary1/2
    if op == "+":
        return a + b
    if op == "-":
        return a - b
    if op == "*":
        return a * b
    if op == "/":
        if b == 0.0:
            raise LineError("division by zero in an expression")
        return a / b
    if op == "mod":
        if b == 0.0:
            raise LineError("MOD by zero in an expression")
        r = math.fmod(a, b)
        return r + abs(b) if r < 0.0 else r
    if op == "**":
        if a < 0.0 and b != math.floor(b):
            raise LineError("negative number raised to a non-integer power")
        if a == 0.0 and b < 0.0:
            raise LineError("zero raised to a negative power")
        try:
            return math.pow(a, b)
        except OverflowError:
            raise LineError("power overflows") from None
    if op == "eq":
        return 1.0 if abs(a - b) < TOLERANCE_EQUAL else 0.0
    if op == "ne":
        return 1.0 if abs(a - b) >= TOLERANCE_EQUAL else 0.0
    if op == "le":
        return 1.0 if abs(a - b) < TOLERANCE_EQUAL or a <= b else 0.0
    if op == "ge":
        return 1.0 if abs(a - b) < TOLERANCE_EQUAL or a >= b else 0.0
    if op == "gt":
        return 1.0 if a > b else 0.0
    if op == "lt":
        return 1.0 if a < b else 0.0
    if op == "and":
        return 0.0 if a == 0.0 or b == 0.0 else 1.0
    if op == "or":
        return 1.0 if a != 0.0 or b != 0.0 else 0.0
    if op == "xor":
        return 1.0 if (a == 0.0) != (b == 0.0) else 0.0
    raise LineError(f"unknown operator {op}")


def unary(f: str, v: float) -> float:
    # as interp_execute.cc's execute_unary: angles in degrees
    if f == "abs":
        return abs(v)
    if f == "acos":
        if not -1.0 <= v <= 1.0:
            raise LineError(f"ACOS argument {v:g} out of range [-1, 1]")
        return math.degrees(math.acos(v))
    if f == "asin":
        if not -1.0 <= v <= 1.0:
            raise LineError(f"ASIN argument {v:g} out of range [-1, 1]")
        return math.degrees(math.asin(v))
    if f == "cos":
        return math.cos(math.radians(v))
    if f == "sin":
        return math.sin(math.radians(v))
    if f == "tan":
        return math.tan(math.radians(v))
    if f == "exp":
        try:
            return math.exp(v)
        except OverflowError:
            raise LineError(f"EXP[{v:g}] overflows") from None
    if f == "ln":
        if v <= 0.0:
            raise LineError(f"LN of a number ≤ 0 ({v:g})")
        return math.log(v)
    if f == "sqrt":
        if v < 0.0:
            raise LineError(f"SQRT of a negative number ({v:g})")
        return math.sqrt(v)
    if not math.isfinite(v):
        raise LineError(f"{f.upper()} of a non-finite number")
    if f == "fix":
        return float(math.floor(v))
    if f == "fup":
        return float(math.ceil(v))
    if f == "round":
        return float(int(v + (-0.5 if v < 0.0 else 0.5)))
    raise LineError(f"unknown function {f.upper()}")
