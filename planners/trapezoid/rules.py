"""LinuxCNC 2.9's tp constants and its arc rule, written once for the queue, the blends and the
planner of plain segment paths (sources: tp_types.h, blendmath.h, initraj.cc defaults of [TRAJ],
blendmath.c ``pmCircleEffectiveMinRadius``, tc.c ``tcUpdateCircleAccRatio``)."""
from __future__ import annotations

import math

import numpy as np

KINK_RATIO = 0.1            # [TRAJ] ARC_BLEND_KINK_RATIO default (initraj.cc)
GAP_CYCLES = 4              # [TRAJ] ARC_BLEND_GAP_CYCLES default
OPT_DEPTH = 50              # [TRAJ] ARC_BLEND_OPTIMIZATION_DEPTH default
OPT_CUTOFF = 4              # tp_types.h TP_OPTIMIZATION_CUTOFF
MIN_SEGMENT_CYCLES = 1.02   # tp_types.h TP_MIN_SEGMENT_CYCLES
ACC_RATIO_TANGENTIAL = 0.5                                  # blendmath.h BLEND_ACC_RATIO_TANGENTIAL
ACC_RATIO_NORMAL = math.sqrt(1.0 - ACC_RATIO_TANGENTIAL ** 2)  # blendmath.h BLEND_ACC_RATIO_NORMAL ≈ 0.866
SHARP_CORNER = (math.pi * 2.0 / 180.0) ** 2   # tpSetupTangent: anti-parallel within 2°


def _spiral_radius(radius, k):
    """The Archimedean spiral's radius of curvature (r² + k²)^1.5 / (r² + 2k²) at radius r,
    k = dr/dφ; a circle keeps its radius exactly (the spiral form gives it to rounding only)."""
    spiral_r = (radius * radius + k * k) ** 1.5 / (radius * radius + 2 * k * k)
    return np.where(k != 0, spiral_r, radius) if isinstance(k, np.ndarray) else (spiral_r if k else radius)


def arc_speed_radius(radius, angle, rise, spiral):
    """The radius ρ whose speed cap √(a_n·ρ) an arc of a segment path gets, as LinuxCNC caps a
    G2/G3 twice: emccanon.cc ARC_FEED's planar speed stretched over the helix (ρ = r_s +
    (h/θ)²/r_s, the rise per radian) and, once finalized, pmCircleEffectiveMinRadius (the whole
    rise); the smaller binds (ARC_FEED's for a helix over 1 rad)."""
    r_s = _spiral_radius(radius, spiral / angle)
    stretched = r_s + (rise / angle) ** 2 / r_s
    return np.minimum(stretched, effective_min_radius(radius, angle, rise, spiral))


def effective_min_radius(radius, angle, rise, spiral):
    """blendmath.c pmCircleEffectiveMinRadius: the Archimedean spiral's radius of curvature
    (r² + k²)^1.5 / (r² + 2k²) at the start radius r, k = dr/dφ, then r_s + h²/r_s with h the
    helix's *whole* rise (a helix's curvature radius would take the rise per radian; LinuxCNC's
    rule is what its tp runs, so it is followed). Floats or numpy arrays alike."""
    r_s = _spiral_radius(radius, spiral / angle)
    return r_s + rise * rise / r_s
