"""An RS274NGC interpreter that reads G-code as LinuxCNC 2.9 reads it.

tokens (a line → a block) → expr (expressions and functions) → params (numbered and named
parameters) → owords (sub/call/if/while/do/repeat structure) → modal (the modal state) →
interp (execution order of a block), with codes (words, G/M codes and their groups), offsets
(coordinate systems, G10/G28/G92), motion (end points, arcs, probing), cycles (canned cycles)
and flow (O-word control) →
canon (canonical moves in machine mm).
``linuxcnc.py`` runs LinuxCNC's own interpreter, the reference of the tests.
"""
from planners.paths.gcode.rs274.canon import CanonEvent, CanonMove, CanonProgram
from planners.paths.gcode.rs274.errors import RS274Error
from planners.paths.gcode.rs274.interp import Interpreter, interpret

__all__ = ["CanonEvent", "CanonMove", "CanonProgram", "Interpreter", "RS274Error", "interpret"]
