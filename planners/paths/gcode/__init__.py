"""G-code: :mod:`.reader` turns a program into line/arc segments tagged with their source lines
(through the RS274NGC interpreter, planners.paths.gcode.rs274, and LinuxCNC's canon steps, :mod:`.naivecam`);
:mod:`.writer` writes a path back as G-code."""
from planners.paths.gcode.reader import (EmptyProgram, GCodeError, GCodeProgram, load_gcode_path, parse_gcode,
                                         program_path, read_gcode, strip_comments)
from planners.paths.gcode.writer import write_gcode

__all__ = ["EmptyProgram", "GCodeError", "GCodeProgram", "load_gcode_path", "parse_gcode", "program_path",
           "read_gcode", "strip_comments", "write_gcode"]
