"""Generate the standard NURBS/segment paths of benchmarks/paths/ (deterministic; re-run to rebuild).

    .venv/bin/python benchmarks/paths/make_paths.py

The KEOPS paper's "bird" curve is not published: `bird` is our own design with the same
character — sharp corners (exact stops) and several curvature peaks (feed minima) in a
160 × 160 mm square around the keops workspace centre (0, 0, −400). Every path is checked
to fit its machine by tests/test_paths_fit.py.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent

# Bird outline, anchors (x, y) mm, walked once round from the beak tip. "sharp" anchors join
# their Bézier pieces with a tangent break (an exact stop); smooth anchors give the tangent.
BIRD = [  # (point, tangent direction or None for a sharp corner)
    ((78.0, 18.0), None),            # beak tip (start and end)
    ((42.0, 52.0), (-1.0, 0.05)),    # crown of the head
    ((18.0, 36.0), (-0.6, -1.0)),    # nape
    ((-6.0, 78.0), None),            # raised wing tip
    ((-38.0, 24.0), (-1.0, -0.15)),  # back
    ((-78.0, 46.0), None),           # upper tail tip
    ((-56.0, 4.0), None),            # tail notch
    ((-78.0, -42.0), None),          # lower tail tip
    ((-12.0, -78.0), (1.0, 0.0)),    # belly
    ((44.0, -30.0), (0.7, 1.0)),     # breast
    ((52.0, 6.0), None),             # throat (beak root)
    ((78.0, 18.0), None),            # back to the beak tip
]
# Bulge of the pieces next to sharp anchors: the inner handles are the chord/3 turned by
# this angle (rad), so no piece is a straight line and curvature varies along each.
BULGE = [0.35, 0.0, -0.5, 0.45, 0.3, -0.4, 0.4, 0.3, 0.0, 0.2, -0.6]
WEIGHTS = [1.0, 1.4, 0.8, 1.0, 1.2, 1.0, 1.0, 0.8, 1.3, 1.0, 1.0]   # of the 2 inner points of each piece


def rot(v, a):
    c, s = math.cos(a), math.sin(a)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def bezier_chain(anchors, bulge, weights, scale, center, z, slope=(0.0, 0.0)):
    """Cubic Bézier pieces joined with knots of multiplicity 3 (C0 knots: corners allowed),
    on the plane z + slope·(x, y) through the centre (a NURBS maps onto a plane exactly)."""
    pts, w = [], []
    n = len(anchors) - 1
    for i in range(n):
        (A, ta), (B, tb) = anchors[i], anchors[i + 1]
        A, B = np.array(A), np.array(B)
        chord = B - A
        L = np.linalg.norm(chord)
        hA = (np.array(ta) / np.linalg.norm(ta) * L / 3) if ta is not None else rot(chord / 3, bulge[i])
        hB = (np.array(tb) / np.linalg.norm(tb) * L / 3) if tb is not None else rot(chord / 3, -bulge[i])
        ctrl = [A, A + hA, B - hB] if i < n - 1 else [A, A + hA, B - hB, B]
        pts += ctrl
        w += [1.0, weights[i], weights[i]] + ([1.0] if i == n - 1 else [])
    P = [[center[0] + scale * p[0], center[1] + scale * p[1], z + scale * (slope[0] * p[0] + slope[1] * p[1])]
         for p in pts]
    knots = [0.0] * 4 + [float(k) for k in range(1, n) for _ in range(3)] + [float(n)] * 4
    knots = [k / n for k in knots]
    return {"type": "nurbs", "units": "mm", "degree": 3, "knots": knots,
            "control_points": P, "weights": w}


def flower(petals=5, r_out=72.0, r_in=22.0, per_petal=6, z=-400.0):
    """A closed cubic NURBS with petals; clamped, starting and ending at a petal tip."""
    N = petals * per_petal
    P, w = [], []
    for j in range(N + 1):
        phi = 2 * math.pi * j / N
        r = r_in + (r_out - r_in) * (0.5 + 0.5 * math.cos(petals * phi)) ** 1.5
        P.append([r * math.cos(phi), r * math.sin(phi), z])
        w.append(1.0 if j % per_petal else 1.5)      # heavier at the petal tips
    n, p = len(P), 3
    inner = [k / (n - p) for k in range(1, n - p)]
    knots = [0.0] * (p + 1) + inner + [1.0] * (p + 1)
    return {"type": "nurbs", "units": "mm", "degree": 3, "knots": knots,
            "control_points": P, "weights": w}


def helix(radius=50.0, turns=3.0, z0=-450.0, z1=-350.0):
    """A helix about the vertical axis through the keops centre, as one arc segment (exact)."""
    theta = 2 * math.pi * turns
    start = [radius, 0.0, z0]
    end = [radius * math.cos(theta), radius * math.sin(theta), z1]
    return {"type": "segments", "units": "mm", "segments": [
        {"type": "arc", "start": start, "center": [0.0, 0.0, z0], "normal": [0.0, 0.0, 1.0],
         "angle": theta, "rise": z1 - z0, "end": end}]}


def write(name, d):
    with open(HERE / name, "w") as f:
        json.dump(d, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    # anchors span ±78 mm: scale to the 160 × 160 mm square (keops) / 80 × 80 mm (kossel).
    # `bird` lies on a plane through the keops centre (0, 0, −400) falling 0.5 mm per mm along
    # x and y (z from −320 to −480): each keops joint's Jacobian row points 45° down its rail,
    # so accelerations with a z part add up in a joint — Cartesian limits equal to the joint
    # limits then break the joints by ~17 % (the KEOPS paper's "significant" violation).  Flat
    # at z = −400 (`bird_flat`) the rows' xy parts are only ≈ 0.7 long and the joints stay
    # below their limits (a ≈ 0.88): the contrast case.
    write("bird.json", bezier_chain(BIRD, BULGE, WEIGHTS, 80.0 / 78.0, (0.0, 0.0), -400.0, (-0.5, -0.5)))
    write("bird_flat.json", bezier_chain(BIRD, BULGE, WEIGHTS, 80.0 / 78.0, (0.0, 0.0), -400.0))
    # kossel: ±40 mm fits its ±50 mm box; z = −250 keeps the joints below their 25 mm top.
    write("bird_kossel.json", bezier_chain(BIRD, BULGE, WEIGHTS, 40.0 / 78.0, (0.0, 0.0), -250.0))
    write("flower.json", flower())
    write("helix.json", helix())
