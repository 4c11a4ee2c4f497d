"""LinuxCNC's own interpreter as a reference and as an optional front end (``--reader linuxcnc``).

LinuxCNC's ``gcode`` Python module (Debian ``linuxcnc-uspace``, the same librs274 that the
``rs274`` program and AXIS's preview run) calls back for every canonical command with full
double precision; ``rs274`` itself prints only 4 decimals. This file runs under the
*system* Python that has that module (``/usr/bin/python3 -m`` is not needed: it is run as a
script and imports nothing of pkmbench), and prints one JSON object per canonical move in
machine coordinates (mm), converted as LinuxCNC's canon does (emccanon.cc
rotate_and_offset_pos): add the G92 offset, rotate X/Y by the XY rotation, then add the G5x
and tool offsets. The interpreter calls back in inches (gcodemodule
reports every length in inches), so lengths are multiplied by 25.4.

    /usr/bin/python3 planners/paths/gcode/rs274/linuxcnc.py PROGRAM.ngc [--tool-table FILE] [--var-file FILE] [--start X,Y,Z]

(``--tool-table`` in mm; ``--var-file`` as the module reads it, in its machine units: inches.)
      → {"kind": "rapid"|"feed"|"arc"|"dwell"|"mcode"|..., "line": N, ...} per line, then
        {"kind": "end", "result": CODE, "line": N, "error": TEXT|null}
"""
import json
import math
import os
import sys
import tempfile

IN = 25.4


def _tool_table(file):
    """LinuxCNC .tbl: ``T1 P1 Z0.5 D3 ;comment`` — tool number → Z offset (mm)."""
    tools = {}
    if not file:
        return tools
    with open(file, encoding="latin-1") as f:
        for raw in f:
            body = raw.split(";")[0].split()
            words = {w[0].upper(): w[1:] for w in body if w}
            if "T" in words:
                tools[int(words["T"])] = {k: float(v) for k, v in words.items() if k in "XYZD"}
    return tools


class Canon:
    def __init__(self, tools, var_file):
        self.parameter_file = var_file
        self.tools = tools
        self.out = []
        self.line = 0
        self.g5x = [0.0] * 3
        self.g92 = [0.0] * 3
        self.tlo = [0.0] * 3
        self.rot = 0.0
        self.plane = 1

    # --- queries the interpreter makes -------------------------------------------------
    def get_external_angular_units(self): return 1.0
    def get_external_length_units(self): return 1.0 / IN
    def get_axis_mask(self): return 7                  # X, Y, Z
    def get_block_delete(self): return 0
    def check_abort(self): return False

    def get_tool(self, n):
        t = self.tools.get(n, {})
        # (toolno, x y z a b c u v w offsets, diameter, frontangle, backangle, orientation), inch
        return (n, t.get("X", 0.0) / IN, t.get("Y", 0.0) / IN, t.get("Z", 0.0) / IN, 0, 0, 0, 0, 0, 0,
                t.get("D", 0.0) / IN, 0, 0, 0)

    # --- state -------------------------------------------------------------------------
    def next_line(self, lc): self.line = lc.sequence_number
    def set_g5x_offset(self, idx, x, y, z, *rest): self.g5x = [x * IN, y * IN, z * IN]
    def set_g92_offset(self, x, y, z, *rest): self.g92 = [x * IN, y * IN, z * IN]
    def set_xy_rotation(self, r): self.rot = r
    def tool_offset(self, x, y, z, *rest): self.tlo = [x * IN, y * IN, z * IN]
    def set_plane(self, p): self.plane = p

    def _machine(self, x, y, z):
        # emccanon.cc rotate_and_offset_pos: G92, the XY rotation, then G5x and the tool offset
        x, y, z = x * IN + self.g92[0], y * IN + self.g92[1], z * IN + self.g92[2]
        if self.rot:
            t = math.radians(self.rot)
            c, s = math.cos(t), math.sin(t)
            x, y = x * c - y * s, x * s + y * c
        return [x + self.g5x[0] + self.tlo[0], y + self.g5x[1] + self.tlo[1], z + self.g5x[2] + self.tlo[2]]

    # --- motion ------------------------------------------------------------------------
    def straight_traverse(self, x, y, z, *rest):
        self.out.append({"kind": "rapid", "line": self.line, "end": self._machine(x, y, z)})

    def straight_feed(self, x, y, z, *rest):
        self.out.append({"kind": "feed", "line": self.line, "end": self._machine(x, y, z)})

    def straight_probe(self, x, y, z, *rest):
        self.out.append({"kind": "probe", "line": self.line, "end": self._machine(x, y, z)})

    def rigid_tap(self, x, y, z, *rest):
        self.out.append({"kind": "rigid_tap", "line": self.line})

    def arc_feed(self, fe, se, fa, sa, rot, ae, *rest):
        # plane 1 = XY (first X, second Y, axis Z), 2 = YZ (Y, Z; X), 3 = XZ (Z, X; Y)
        if self.plane == 1:
            end, cen = (fe, se, ae), (fa, sa, 0.0)
        elif self.plane == 2:
            end, cen = (ae, fe, se), (0.0, fa, sa)
        else:
            end, cen = (se, ae, fe), (sa, 0.0, fa)
        c = self._machine(*cen)
        axis = {1: 2, 2: 0, 3: 1}[self.plane]
        c[axis] = None
        self.out.append({"kind": "arc", "line": self.line, "end": self._machine(*end), "center": c,
                         "rotation": rot, "plane": {1: 17, 2: 19, 3: 18}[self.plane]})

    def dwell(self, t):
        self.out.append({"kind": "dwell", "line": self.line, "seconds": t})

    def message(self, text):
        self.out.append({"kind": "message", "line": self.line, "text": text})

    def set_feed_rate(self, f):
        self.out.append({"kind": "feed_rate", "line": self.line, "mm_per_min": f * IN})

    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        return lambda *a: None


def run(program, tool_table=None, start=None, var_file=None):
    """``start`` (x, y, z mm): the machine position before the program. The module always starts
    at 0: a G53 G0 there first (its move is the first one printed, "line" 0) and G80, the
    interpreter's initial motion mode, again."""
    import gcode
    with tempfile.TemporaryDirectory() as d:
        var = os.path.join(d, "pkmbench.var")
        with open(var, "w") as f:       # a copy: LinuxCNC writes its parameters back to the file
            if var_file:
                with open(var_file) as g:
                    f.write(g.read())
        c = Canon(_tool_table(tool_table), var)
        # G21: the machine works in mm (as an INI with LINEAR_UNITS = mm)
        init = ["G21"] + ([] if start is None else ["G53 G0 X%r Y%r Z%r" % tuple(start), "G80"])
        result, last = gcode.parse(program, c, init)
        err = None if result <= gcode.MIN_ERROR else gcode.strerror(result)
    return c.out, {"kind": "end", "result": result, "line": last, "error": err}


if __name__ == "__main__":
    args = sys.argv[1:]
    tbl = None
    if "--tool-table" in args:
        i = args.index("--tool-table")
        tbl = args[i + 1]
        del args[i:i + 2]
    var_file = None
    if "--var-file" in args:
        i = args.index("--var-file")
        var_file = args[i + 1]
        del args[i:i + 2]
    start = None
    if "--start" in args:
        i = args.index("--start")
        start = [float(v) for v in args[i + 1].split(",")]
        del args[i:i + 2]
    moves, end = run(args[0], tbl, start, var_file)
    w = sys.stdout.write
    for m in moves:
        w(json.dumps(m) + "\n")
    w(json.dumps(end) + "\n")
