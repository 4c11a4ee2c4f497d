"""Path files: read .json (nurbs | segments) and .ngc (G-code) toolpaths, find the standard
ones by name in ``benchmarks/paths/``.
"""
from __future__ import annotations

import json
from pathlib import Path as FsPath

from kins.resources import PATH_DIR
from planners.paths.base import Path, PathError
from planners.paths.gcode.reader import load_gcode_path
from planners.paths.nurbs import NurbsPath
from planners.paths.segments import SegmentPath

def path_from_dict(d: dict, source: str = "<path>") -> Path:
    if not isinstance(d, dict):
        raise PathError(f"{source}: a path file must hold a JSON object")
    kind = d.get("type")
    if kind == "nurbs":
        return NurbsPath.from_dict(d, source)
    if kind == "segments":
        return SegmentPath.from_dict(d, source)
    raise PathError(f"{source}: unknown path type {kind!r} (expected 'nurbs' or 'segments')")


def load_path(file, **gcode_options) -> Path:
    """Read a path file: .json (nurbs | segments) or .ngc (G-code, corners blended per G61/G64)."""
    file = FsPath(file)
    if file.suffix.lower() in (".ngc", ".nc", ".gcode"):
        return load_gcode_path(file, **gcode_options)
    try:
        text = file.read_text()
    except OSError as e:
        raise PathError(f"{file}: cannot read path file: {e.strerror}") from None
    try:
        d = json.loads(text)
    except json.JSONDecodeError as e:
        raise PathError(f"{file}: line {e.lineno}: invalid JSON: {e.msg}") from None
    return path_from_dict(d, str(file))


def standard_paths() -> list[str]:
    return sorted({p.stem if p.suffix == ".json" else p.name for p in PATH_DIR.glob("*")
                   if p.suffix in (".json", ".ngc")})


def resolve_path(name_or_file, **gcode_options) -> Path:
    """A path object from a file name or a standard name (``benchmarks/paths/<name>.(json|ngc)``)."""
    if isinstance(name_or_file, Path):
        return name_or_file
    f = FsPath(name_or_file)
    if f.is_file():
        return load_path(f, **gcode_options)
    for cand in (PATH_DIR / f.name, PATH_DIR / f"{f.name}.json", PATH_DIR / f"{f.name}.ngc"):
        if cand.is_file():
            return load_path(cand, **gcode_options)
    raise PathError(f"{name_or_file}: no such path file, and not a standard path "
                    f"(standard: {', '.join(standard_paths()) or 'none'})")
