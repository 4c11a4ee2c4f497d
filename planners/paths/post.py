"""The CAM post step: a curve written as a CAM post gives it to LinuxCNC — G1 lines within the
chord tolerance, their corners blended under ``G64 P<tolerance>`` (the trapezoid's and the
``linuxcnc`` planner's geometry of a NURBS)."""
from __future__ import annotations

from planners.paths.base import Path, PathError
from planners.paths.blend import blend_corners
from planners.paths.lines import cut_into_lines
from planners.paths.nurbs import NurbsPath
from planners.paths.segments import SegmentPath


def prepare_geometry(path: Path, chord_tol: float, blend_tol: float | None):
    """(segment path planned on, info) — a NURBS cut into G1 lines and blended, as a CAM post
    would give it to LinuxCNC; a segment path as it is (a G-code program is planned by
    planners.trapezoid.program instead)."""
    if isinstance(path, SegmentPath):
        return path, {"geometry_deviation_mm": 0.0, "chord_deviation_mm": 0.0,
                      "blend_deviation_mm": 0.0, "segments": len(path.segments)}
    if not isinstance(path, NurbsPath):
        raise PathError(f"cannot write a {type(path).__name__} as G1 lines")
    poly, chord_dev = cut_into_lines(path, chord_tol)
    n = len(poly.segments)
    tol = [blend_tol] * (n - 1)
    segs, done = blend_corners(poly.segments, tol)
    blend_dev = max((d for _, d in done), default=0.0)
    planned = SegmentPath(segs, f"{path.source} (G1 lines, G64 P{blend_tol:g})" if blend_tol
                          else f"{path.source} (G1 lines, G61)")
    return planned, {"geometry_deviation_mm": chord_dev + blend_dev, "chord_deviation_mm": chord_dev,
                     "blend_deviation_mm": blend_dev, "g1_lines": n, "segments": len(segs),
                     "blends": len(done)}
