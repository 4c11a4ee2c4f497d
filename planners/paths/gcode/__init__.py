"""G-code (RS274/NGC subset): :mod:`.reader` turns a program into line/arc segments tagged with
their source lines, and writes a path back as G-code."""
from planners.paths.gcode.reader import (GCodeError, GCodeProgram, load_gcode_path, parse_gcode,
                                         program_path, read_gcode, strip_comments, write_gcode)

__all__ = ["GCodeError", "GCodeProgram", "load_gcode_path", "parse_gcode", "program_path",
           "read_gcode", "strip_comments", "write_gcode"]
