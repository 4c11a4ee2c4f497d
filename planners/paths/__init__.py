"""Toolpaths: the geometry every planner plans along, parametrised by arc length s (mm).

- :mod:`.base` — the :class:`Path` interface and :class:`PathError`;
- :mod:`.nurbs` — NURBS curves; :mod:`.segments` — lines and circular/helical/spiral arcs
  (:mod:`.spiral`: a spiral's arc length);
- :mod:`.blend` — G64 corner blending and cutting a curve into G1 lines;
- :mod:`.gcode` — the RS274/NGC reader (and writer);
- :mod:`.io` — path files (.json, .ngc) and the standard paths by name.
"""
from planners.paths.base import Path, PathError
from planners.paths.io import load_path, path_from_dict, resolve_path, standard_paths
from planners.paths.nurbs import NurbsPath
from planners.paths.segments import Arc, Line, SegmentPath

__all__ = ["Path", "PathError", "NurbsPath", "SegmentPath", "Line", "Arc",
           "load_path", "path_from_dict", "resolve_path", "standard_paths"]
