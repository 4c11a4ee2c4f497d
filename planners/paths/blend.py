"""G64 corner blending, the geometry every planner shares.

Corner blending follows the idea of LinuxCNC 2.9's tangent-arc blends
(``src/emc/tp/blendmath.c``: ``blendInit3FromLineLine``, ``blendFindPoints3``, …): the
corner between two lines is replaced by the circular arc tangent to both, as large as
the tolerance allows, but using at most half of each adjoining line so that neighbouring
blends never overlap. The blended path is then tangent-continuous there. What is *not*
blended (documented limits): corners touching an arc segment (kept as exact stops), and
near-reversals (turn > π − 1e-6 rad).

LinuxCNC's own blends, sized to the speed one corner at a time as its tp queues the moves
(and line↔arc, arc↔arc corners), are the ``trapezoid`` planner's: planners.trapezoid.blend.
"""
from __future__ import annotations

import math

import numpy as np

from planners.paths.base import CORNER_ANGLE, PathError
from planners.paths.segments import Arc, Line

REVERSAL_ANGLE = math.pi - 1e-6


def _norms(V: np.ndarray) -> np.ndarray:
    """norm3 of each row: √(x·x + y·y + z·z), summed in that order."""
    return np.sqrt(V[:, 0] * V[:, 0] + V[:, 1] * V[:, 1] + V[:, 2] * V[:, 2])


def _cross(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """cross3 of each row pair."""
    return np.column_stack([A[:, 1] * B[:, 2] - A[:, 2] * B[:, 1], A[:, 2] * B[:, 0] - A[:, 0] * B[:, 2],
                            A[:, 0] * B[:, 1] - A[:, 1] * B[:, 0]])


def blend_corners(segments, tolerances):
    """Round the line–line corners whose tolerance is not None.

    ``tolerances[i]`` governs the corner between segments i and i+1: None → exact stop,
    a number p > 0 → an arc within p mm of the corner, inf → an arc limited only by room.
    Returns (new segments, list of (corner index, deviation mm) for each blended corner).
    """
    segs = list(segments)
    if len(tolerances) != max(len(segs) - 1, 0):
        raise PathError(f"blend: {len(tolerances)} corner tolerances for {len(segs)} segments")
    trim_start = np.zeros(len(segs))
    trim_end = np.zeros(len(segs))
    is_line = np.array([g.kind == "line" for g in segs])
    # every line–line corner at once (a CAM program has 10⁵ of them): they are independent,
    # each takes at most half of each line
    cand = np.array([i for i, tol in enumerate(tolerances) if tol is not None and is_line[i] and is_line[i + 1]],
                    dtype=np.int64)
    arcs, done = {}, []
    if len(cand):
        U = np.array([g.direction if g.kind == "line" else (0.0, 0.0, 0.0) for g in segs])
        L = np.array([g.length for g in segs])
        tolc = np.array([tolerances[i] for i in cand.tolist()], float)
        if not (tolc > 0).all():
            i = int(cand[np.argmin(tolc > 0)])
            raise PathError(f"blend: corner {i} tolerance {tolerances[i]} must be > 0 (or None for an exact stop)")
        turns = np.arctan2(np.linalg.norm(np.cross(U[cand], U[cand + 1]), axis=1),
                           np.einsum("ij,ij->i", U[cand], U[cand + 1]))
        idx, R, d, angle, dev = _room_line_corners(U, L, cand, tolc, turns)
        trim_end[idx] = d
        trim_start[idx + 1] = d
        arcs = dict(zip(idx.tolist(), zip(R.tolist(), d.tolist(), angle.tolist())))
        done = list(zip(idx.tolist(), dev.tolist()))
    out = _assemble(segs, trim_start.tolist(), trim_end.tolist(), arcs)
    return out, done


def _room_line_corners(U, L, c, tolc, turns):
    """The line–line corners rounded as large as the tolerance and half of each line allow.

    The arc of a turn δ touches the lines at d = R·tan(δ/2) from the corner and passes it at
    R·(1/cos(δ/2) − 1): R is the smaller of the room's (d = half the shorter line) and the
    tolerance's. δ = atan2(|u1 × u2|, u1 · u2), not acos(u1 · u2): acos loses the angle of a
    nearly straight corner to rounding (~1e-8 rad), and R·δ then puts the arc's end 1e-7 mm off
    its line. The angles by ``math``, one corner at a time: numpy's SIMD kernels round them
    differently per CPU."""
    keep = (turns > CORNER_ANGLE) & (turns < REVERSAL_ANGLE)
    c, tol = c[keep], tolc[keep]
    U1, U2 = U[c], U[c + 1]
    sin_n = _norms(_cross(U1, U2)).tolist()
    cos_n = (U1[:, 0] * U2[:, 0] + U1[:, 1] * U2[:, 1] + U1[:, 2] * U2[:, 2]).tolist()
    delta = [math.atan2(y, x) for y, x in zip(sin_n, cos_n)]
    tan_h = np.array([math.tan(0.5 * x) for x in delta])
    sec_m1 = 1.0 / np.array([math.cos(0.5 * x) for x in delta]) - 1.0
    room = 0.5 * np.minimum(L[c], L[c + 1])
    with np.errstate(divide="ignore"):
        R_tol = np.where(np.isfinite(tol), tol / sec_m1, math.inf)
    R = np.minimum(room / tan_h, R_tol)
    d, dev = R * tan_h, R * sec_m1
    ok = (R > 0) & (d > 0)
    return c[ok], R[ok], d[ok], np.array(delta)[ok], dev[ok]


def _line_line_arcs(segs, arcs):
    """{corner: blend Arc} from {corner: (R, d, turn)}: each arc from C − d·u1 to
    C + d·u2 of its corner C, column-wise (the same element-wise operations in the same order
    as one 3-vector at a time: 10⁵ corners cost seconds so)."""
    built = {}
    if not arcs:
        return built
    ai = sorted(arcs)
    R = np.array([arcs[i][0] for i in ai])[:, None]
    d = np.array([arcs[i][1] for i in ai])[:, None]
    delta = [arcs[i][2] for i in ai]
    U1 = np.array([segs[i].direction for i in ai])
    U2 = np.array([segs[i + 1].direction for i in ai])
    m = U2 - np.array([math.cos(x) for x in delta])[:, None] * U1
    m /= _norms(m)[:, None]
    n = _cross(U1, U2)
    n /= _norms(n)[:, None]
    # n exactly ⟂ m: on a nearly straight corner both carry ~1e-10 rounding, and the arc
    # projects start − centre (= −R·m, R up to 10⁴ mm) onto n's plane, moving it 1e-6 mm
    n = n - (n[:, 0] * m[:, 0] + n[:, 1] * m[:, 1] + n[:, 2] * m[:, 2])[:, None] * m
    n /= _norms(n)[:, None]
    t1 = np.array([segs[i].end for i in ai]) - d * U1
    C = t1 + R * m
    # Arc._derive's in-plane basis, radius, length and end, column-wise (rise = 0)
    a = t1 - C
    off = a[:, 0] * n[:, 0] + a[:, 1] * n[:, 1] + a[:, 2] * n[:, 2]
    a = a - off[:, None] * n
    b = _cross(n, a)
    radius = _norms(a).tolist()
    length = [float(th * math.hypot(r, 0.0 / th)) for th, r in zip(delta, radius)]
    end = (C + np.array([math.cos(x) for x in delta])[:, None] * a
           + np.array([math.sin(x) for x in delta])[:, None] * b + 0.0 * n)
    for k, i in enumerate(ai):
        built[i] = Arc.from_parts(t1[k], C[k], n[k], delta[k], segs[i + 1].line,
                                  a[k], b[k], radius[k], length[k], end[k])
    return built


def _assemble(segs, trim_start, trim_end, arcs):
    """The blended segment list: trimmed lines (keeping their original direction, so a short
    leftover never gets a direction of rounding noise, i.e. a false corner), the arcs and
    the blend arcs, in path order."""
    lines = [i for i, g in enumerate(segs) if g.kind == "line"]
    trimmed = {}
    if lines:
        li = np.array(lines)
        D = np.array([segs[i].direction for i in lines])
        ts, te = np.array(trim_start)[li][:, None], np.array(trim_end)[li][:, None]
        S = np.array([segs[i].start for i in lines]) + ts * D
        E = np.array([segs[i].end for i in lines]) - te * D
        lens = [segs[i].length - trim_start[i] - trim_end[i] for i in lines]
        trimmed = {i: (S[k], E[k], D[k], lens[k]) for k, i in enumerate(lines)}
    built = _line_line_arcs(segs, arcs)
    out = []
    for i, g in enumerate(segs):
        if g.kind == "line":
            st, en, u, left = trimmed[i]
            if left > 1e-9:
                out.append(Line.exact(st, en, u, g.line))
        else:
            out.append(g)
        if i in built:
            out.append(built[i])
    return out
