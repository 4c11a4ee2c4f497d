"""A curve cut into G1 lines within a chord tolerance, as a CAM post does (the geometry
`trapezoid` plans a NURBS on, blended then by planners.paths.blend)."""
from __future__ import annotations

import math

import numpy as np

from planners.paths.base import Path, PathError
from planners.paths.segments import Line, SegmentPath


def cut_into_lines(path: Path, chord_tol: float, grid_mm: float = 0.05):
    """G1 lines through points of ``path`` with chord deviation ≤ chord_tol (as a CAM post).

    Vertices include every corner. Step from the local curvature, ℓ = √(8·ε/κ_max), then
    each chord is checked at 17 interior points (midpoint included) and halved until within tolerance.
    Returns (SegmentPath of lines, measured largest deviation in mm).
    """
    if not chord_tol > 0:
        raise PathError(f"{path.source}: chord tolerance {chord_tol} must be > 0")
    L = path.length
    bounds = np.concatenate([[0.0], path.corners(), [L]])
    n = max(2, int(math.ceil(L / grid_mm)) + 1)
    sg = np.linspace(0.0, L, n)
    kg = path.curvature(sg)
    verts = [0.0]
    for a, b in zip(bounds[:-1], bounds[1:]):
        s = a
        while b - s > 1e-12:
            k0 = kg[min(np.searchsorted(sg, s), n - 1)]
            step = math.sqrt(8 * 0.95 * chord_tol / k0) if k0 > 0 else b - s
            for _ in range(3):          # curvature may rise within the step: re-check
                lo, hi = np.searchsorted(sg, s) - 1, np.searchsorted(sg, s + step) + 1
                kmax = kg[max(lo, 0):min(hi + 1, n)].max()
                step = min(step, math.sqrt(8 * 0.95 * chord_tol / kmax) if kmax > 0 else step)
            if s + step >= b - 1e-9:
                s = b
            elif s + 1.5 * step > b:
                s = 0.5 * (s + b)         # no sliver before a corner: split the rest evenly
            else:
                s += step
            verts.append(s)
    sv = np.array(verts)
    for _ in range(20):
        dev = _chord_deviation(path, sv)
        bad = dev > chord_tol
        if not bad.any():
            break
        mids = 0.5 * (sv[:-1] + sv[1:])[bad]
        sv = np.sort(np.concatenate([sv, mids]))
    P = path.point(sv)
    lines = [Line(P[i], P[i + 1], None, f"{path.source}: chord {i}") for i in range(len(P) - 1)]
    out = SegmentPath(lines, f"{path.source} (G1 lines, chord ≤ {chord_tol:g} mm)")
    return out, float(dev.max())


def _chord_deviation(path: Path, sv: np.ndarray) -> np.ndarray:
    """Largest distance of the curve from each chord, from 17 interior points per chord."""
    t = np.linspace(0.0, 1.0, 19)[1:-1]          # 17 points, the midpoint among them
    s = (sv[:-1, None] + (sv[1:] - sv[:-1])[:, None] * t[None, :]).ravel()
    Q = path.point(s).reshape(len(sv) - 1, len(t), 3)
    A, B = path.point(sv[:-1]), path.point(sv[1:])
    u = B - A
    uu = np.maximum(np.sum(u * u, axis=1), 1e-300)
    w = Q - A[:, None, :]
    lam = np.clip(np.sum(w * u[:, None, :], axis=2) / uu[:, None], 0.0, 1.0)
    d = np.linalg.norm(w - lam[..., None] * u[:, None, :], axis=2)
    return d.max(axis=1)
