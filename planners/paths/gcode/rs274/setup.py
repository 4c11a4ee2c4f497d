"""What a LinuxCNC machine holds before a program starts: its tool table, its parameter (var)
file and the work offsets a user sets — so a CAM program written with its origin on the stock
can be placed in a PKM's workspace without editing it.

- Tool table (``--tool-table FILE``), LinuxCNC's ``.tbl``: one tool a line, words ``T`` (tool
  number), ``P`` (pocket), offsets ``X Y Z A B C U V W``, ``D`` (diameter), ``I J`` (lathe
  angles), ``Q`` (orientation), then ``;comment`` (tooldata_common.cc ``tooldata_read_entry``).
  T, M6 and G43 H read it; lengths in mm (the machine's units).
- Parameter file (``--var-file FILE``), LinuxCNC's ``.var``: lines ``number value`` in
  increasing order (rs274ngc_pre.cc ``Interp::restore_parameters``; G28 #5161…, G30 #5181…,
  G92 #5211… applied when #5210 = 1, G54…G59.3 #5221…/#5241…/…/#5381… with their XY rotation
  #5230…, the active system #5220). Lengths in mm.
- ``--offset CODE=X,Y,Z`` (repeatable, after the var file): sets the X, Y, Z of G54…G59.3 (the
  origin of that system), G92 (and #5210 = 1, so it is in force from the start, as a persistent
  G92 is), G28 or G30 (the stored positions). It does not select a system: #5220 does (G54 when
  nothing sets it), or the program's own G54…G59.3.

LinuxCNC skips a malformed tool-table line and a var-file line it cannot scan; here both are
refused naming the file and the line (an offset silently dropped would move the whole program).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from planners.paths.gcode.rs274.errors import RS274Error
from planners.paths.gcode.rs274.params import MAX_PARAMETER

# G code → first parameter of its X, Y, Z (LinuxCNC's parameter map)
SYSTEMS = {"G54": 1, "G55": 2, "G56": 3, "G57": 4, "G58": 5, "G59": 6, "G59.1": 7, "G59.2": 8, "G59.3": 9}
OFFSET_BASES = {code: 5201 + 20 * idx for code, idx in SYSTEMS.items()} | {"G92": 5211, "G28": 5161, "G30": 5181}
OFFSET_CODES = tuple(OFFSET_BASES)
_TOOL_WORDS = {"T": int, "P": int, "Q": int} | {c: float for c in "XYZABCUVWDIJ"}
# lengths among the tool words (scaled with the machine's units), the others are angles/integers
_TOOL_LENGTHS = "XYZUVWD"


def _length_parameter(n: int) -> bool:
    """A parameter that holds a length: X, Y, Z, U, V, W of G28, G30, G92 and the nine systems
    (A, B, C and the rotation are angles, #5210 and #5220 a flag and an index)."""
    for base in (5161, 5181, 5211) + tuple(5201 + 20 * i for i in range(1, 10)):
        if base <= n < base + 9:
            return (n - base) in (0, 1, 2, 6, 7, 8)
    return False


@dataclass(frozen=True)
class Setup:
    """Tools (number → {"P": pocket, "X"/"Y"/"Z"/"D"…: mm, "comment"}) and the parameters the
    interpreter starts with (number → value, lengths in mm), with where each came from."""
    tools: dict = field(default_factory=dict)
    params: dict = field(default_factory=dict)
    sources: tuple = ()                 # ("tool table", file), ("var file", file), ("offset", spec)

    def __bool__(self) -> bool:
        return bool(self.tools or self.params)

    # ------------------------------------------------------------------ the interpreter's start
    def apply(self, interp) -> None:
        """Set an Interpreter's tools, parameters, active system and G92 offset, as LinuxCNC's
        Interp::init does after reading the var file (no canon call: nothing to flush yet)."""
        if self.tools:
            interp.tools = {n: {k: v for k, v in t.items() if k in "XYZD"} for n, t in self.tools.items()}
        for n, v in sorted(self.params.items()):
            interp.params.set(n, v)
        idx = int(round(interp.params.get(5220)))
        code = next(c for c, i in SYSTEMS.items() if i == idx)
        interp.m.coord = float(code[1:])
        interp.m.coord_index = idx
        interp.g5x = [interp.params.get(5201 + 20 * idx + i) for i in range(3)]
        interp.rot = interp.params.get(5210 + 20 * idx)
        if interp.params.get(5210) == 1.0:
            interp.g92 = [interp.params.get(5211 + i) for i in range(3)]

    # ------------------------------------------------------------------ files for LinuxCNC
    def var_text(self, mm_per_unit: float = 1.0) -> str:
        """The parameters as a LinuxCNC var file, lengths divided by ``mm_per_unit`` (25.4 for
        LinuxCNC's standalone interpreters, whose machine units are inches)."""
        rows = []
        for n, v in sorted(self.params.items()):
            rows.append(f"{n}\t{v / mm_per_unit if _length_parameter(n) else v!r}\n")
        return "".join(rows)

    def tool_table_text(self, mm_per_unit: float = 1.0) -> str:
        """The tools as a LinuxCNC .tbl, lengths divided by ``mm_per_unit``."""
        rows = []
        for n, t in sorted(self.tools.items()):
            words = [f"T{n}", f"P{t.get('P', n)}"]
            words += [f"{k}{t[k] / mm_per_unit if k in _TOOL_LENGTHS else t[k]!r}"
                      for k in "XYZABCUVWDIJQ" if k in t]
            rows.append(" ".join(words) + (f" ;{t['comment']}" if t.get("comment") else " ;") + "\n")
        return "".join(rows)


def _read(file, what: str) -> str:
    try:
        data = Path(file).read_bytes()
    except OSError as e:
        raise RS274Error(str(file), 0, f"cannot read {what}: {e.strerror}") from None
    return data.decode("utf-8", errors="replace")


def read_tool_table(file) -> dict:
    """A LinuxCNC tool table: tool number → {"P": pocket, "X": mm, …, "comment": text}."""
    src = str(file)
    tools: dict[int, dict] = {}
    for ln, raw in enumerate(_read(file, "tool table").splitlines(), start=1):
        body, _, comment = raw.partition(";")
        words = body.split()
        if not words:
            continue
        t: dict = {}
        for w in words:
            letter, text = w[0].upper(), w[1:]
            kind = _TOOL_WORDS.get(letter)
            if kind is None:
                raise RS274Error(src, ln, f"tool table: unknown word {w!r} (valid: T P X Y Z A B C U V W D I J Q, "
                                          f"then ;comment)")
            if letter in t:
                raise RS274Error(src, ln, f"tool table: {letter} given twice")
            try:
                v = kind(text)
            except ValueError:
                v = None
            if v is None or not math.isfinite(v):
                what = "an integer" if kind is int else "a number"
                raise RS274Error(src, ln, f"tool table: {w!r}: {letter} needs {what}")
            t[letter] = v
        if "T" not in t:
            raise RS274Error(src, ln, "tool table: no T word (the tool number)")
        n = t.pop("T")
        if n < 0:
            raise RS274Error(src, ln, f"tool table: T{n}: tool numbers are ≥ 0")
        if n in tools:
            raise RS274Error(src, ln, f"tool table: tool T{n} is listed twice")
        if comment.strip():
            t["comment"] = comment.strip()
        tools[n] = t
    return tools


def read_var_file(file) -> dict:
    """A LinuxCNC parameter file: number → value (lengths in mm)."""
    src = str(file)
    params: dict[int, float] = {}
    last = 0
    for ln, raw in enumerate(_read(file, "parameter file").splitlines(), start=1):
        words = raw.split()
        if not words:
            continue
        try:
            n, v = int(words[0]), float(words[1]) if len(words) > 1 else None
        except ValueError:
            n = v = None
        if n is None or v is None or not math.isfinite(v):
            raise RS274Error(src, ln, f"parameter file: expected 'number value', got {raw.strip()!r}")
        if not 1 <= n <= MAX_PARAMETER:
            raise RS274Error(src, ln, f"parameter file: #{n} out of range (#1 … #{MAX_PARAMETER})")
        if n <= last:
            # Interp::restore_parameters: "Parameter file out of order"
            raise RS274Error(src, ln, f"parameter file: #{n} after #{last}: the numbers must increase")
        last = n
        params[n] = v
    _check_index(params, src)
    return params


def _check_index(params: dict, src: str) -> None:
    idx = params.get(5220, 1.0)
    if idx not in SYSTEMS.values():
        raise RS274Error(src, 0, f"#5220 = {idx:g}: the active coordinate system must be 1 … 9 (G54 … G59.3)")


def parse_offset(spec: str) -> tuple[str, list[float]]:
    """'G54=X,Y,Z' → ("G54", [x, y, z]); ValueError naming the spec otherwise."""
    code, eq, rest = spec.partition("=")
    code = code.strip().upper()
    if code.endswith(".0"):
        code = code[:-2]
    if not eq or code not in OFFSET_BASES:
        raise ValueError(f"--offset {spec}: expected CODE=X,Y,Z with CODE one of {', '.join(OFFSET_CODES)}")
    try:
        xyz = [float(v) for v in rest.split(",")]
    except ValueError:
        xyz = []
    if len(xyz) != 3 or not all(map(math.isfinite, xyz)):
        raise ValueError(f"--offset {spec}: expected X,Y,Z in mm (three finite numbers) after '='")
    return code, xyz


def make_setup(tool_table=None, var_file=None, offsets=()) -> Setup:
    """The Setup of a tool table file, a var file and ``--offset`` specs (applied in that order);
    RS274Error for a bad file (file and line), ValueError for a bad spec."""
    tools = read_tool_table(tool_table) if tool_table else {}
    params = read_var_file(var_file) if var_file else {}
    sources = ((("tool table", str(tool_table)),) if tool_table else ()) + \
              ((("var file", str(var_file)),) if var_file else ())
    for spec in offsets:
        code, xyz = parse_offset(spec)
        base = OFFSET_BASES[code]
        for i, v in enumerate(xyz):
            params[base + i] = v
        if code == "G92":
            params[5210] = 1.0
        sources += (("offset", spec),)
    return Setup(tools, params, sources)
