"""pkmbench kinematics library: IK, FK, Jacobian, workspace and singularity checks.

    from kins import load_machine
    m = load_machine("keops")
    q = m.ik([0, 0, -400])          # ≈ [245.1, 245.1, 245.1] mm
"""
from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np

from .keops import Keops
from .lineardelta import LinearDelta
from .machine import (MACHINE_DIR, Finding, Kinematics, Limits, MachineFileError,
                      MachineLimits, WorkspaceError)
from .pn101 import Pn101

FAMILIES: dict[str, type[Kinematics]] = {k.family: k for k in (Keops, LinearDelta, Pn101)}

__all__ = ["load_machine", "machine_from_dict", "available_machines", "Kinematics", "Limits", "MachineLimits",
           "Finding", "WorkspaceError", "MachineFileError", "FAMILIES"]


def available_machines() -> list[str]:
    return sorted(p.stem for p in MACHINE_DIR.glob("*.toml"))


def load_machine(name_or_path: str | Path) -> Kinematics:
    """Load a machine by id (``benchmarks/machines/<id>.toml``) or by file path."""
    p = Path(name_or_path)
    if p.suffix != ".toml":
        p = MACHINE_DIR / f"{name_or_path}.toml"
        if not p.exists():
            raise MachineFileError(f"unknown machine '{name_or_path}'; valid: "
                                   f"{', '.join(available_machines())}")
    if not p.exists():
        raise MachineFileError(f"{p}: no such machine file")
    try:
        raw = tomllib.loads(p.read_text())
    except tomllib.TOMLDecodeError as e:
        raise MachineFileError(f"{p}: not valid TOML: {e}") from None
    return machine_from_dict(raw, str(p))


def _get(d: dict, key: str, src: str, section: str):
    if key not in d:
        raise MachineFileError(f"{src}: missing key '{key}' in [{section}]")
    return d[key]


def _positive(d: dict, key: str, src: str, section: str, allow_zero=False) -> float:
    v = _get(d, key, src, section)
    if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
        raise MachineFileError(f"{src}: [{section}] {key} = {v!r} is not a finite number")
    if v < 0 or (v == 0 and not allow_zero):
        raise MachineFileError(f"{src}: [{section}] {key} = {v} must be {'≥' if allow_zero else '>'} 0")
    return float(v)


def _number(d: dict, key: str, src: str, section: str) -> float:
    v = _get(d, key, src, section)
    if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
        raise MachineFileError(f"{src}: [{section}] {key} = {v!r} is not a finite number")
    return float(v)


def _limits(d: dict, src: str, section: str) -> Limits:
    return Limits(*(_positive(d, k, src, section) for k in ("v", "a", "j")))


# Geometry keys that are lengths (must be > 0); the others are signed offsets.
_LENGTHS = {"L", "R", "x_ref", "c1", "c2", "c3"}


def machine_from_dict(raw: dict, src: str) -> Kinematics:
    """A machine from the parsed contents of a machine file (``src`` names it in errors): what
    load_machine does after reading the file, and what a sweep does with a varied copy."""
    name = _get(raw, "name", src, "top level")
    kin = _get(raw, "kinematics", src, "top level")
    family = _get(kin, "type", src, "kinematics")
    if family not in FAMILIES:
        raise MachineFileError(f"{src}: [kinematics] type = '{family}' is unknown; "
                               f"valid: {', '.join(sorted(FAMILIES))}")
    cls = FAMILIES[family]
    params = {}
    for k in cls.GEOMETRY_KEYS:
        params[k] = (_positive(kin, k, src, "kinematics") if k in _LENGTHS
                     else _number(kin, k, src, "kinematics"))
    lim = _get(raw, "limits", src, "top level")
    limits = MachineLimits(
        joint=_limits(_get(lim, "joint", src, "limits"), src, "limits.joint"),
        cartesian=_limits(_get(lim, "cartesian", src, "limits"), src, "limits.cartesian"),
        feed_max=_positive(lim, "feed_max", src, "limits"),
        chord_error_mm=_positive(lim, "chord_error_mm", src, "limits"),
    )
    ws = _get(raw, "workspace", src, "top level")
    box = {}
    for ax in ("x", "y", "z"):
        v = _get(ws, ax, src, "workspace")
        if not (isinstance(v, list) and len(v) == 2 and v[0] < v[1]):
            raise MachineFileError(f"{src}: [workspace] {ax} must be [min, max] with min < max, got {v!r}")
        box[ax] = v
    home = np.array(_get(ws, "home", src, "workspace"), dtype=float)
    q_min = _number(kin, "q_min", src, "kinematics")
    q_max = _number(kin, "q_max", src, "kinematics")
    if not q_min < q_max:
        raise MachineFileError(f"{src}: [kinematics] q_min = {q_min} must be < q_max = {q_max}")
    return cls(
        name=str(name), source=src,
        servo_period_s=_positive(raw, "servo_period_s", src, "top level"),
        limits=limits, q_min=q_min, q_max=q_max,
        workspace_min=np.array([box[a][0] for a in "xyz"], float),
        workspace_max=np.array([box[a][1] for a in "xyz"], float),
        home=home, cond_max=_positive(kin, "cond_max", src, "kinematics"),
        params=params, raw=raw,
    )
