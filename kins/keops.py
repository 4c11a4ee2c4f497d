"""KEOPS tri-pyramid Delta: three linear axes inclined at α, 120° apart.

Source: Erwinski, Karasek, Živanović, Dimić, Slavković, NU·ROBOTI·FTS 2022, eqs (1)–(25),
with the consistent forms of DESIGN.md: w = p + dᵢ, Eᵢ = aᵢ·w, Fᵢ = |w|² − L²,
qᵢ = Eᵢ − √(Eᵢ² − Fᵢ) (the paper prints "+ L²" in F and garbles the rotation of d).
q = 0 at the top of each axis; the carriage moves down-and-inward along aᵢ.
"""
from __future__ import annotations

import numpy as np

from .machine import Kinematics, three_sphere_lower


def _rot_z(deg: float) -> np.ndarray:
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


class Keops(Kinematics):
    family = "keops"
    GEOMETRY_KEYS = ("alpha_deg", "L", "x_ref", "y_ref", "eo")

    def __post_init__(self):
        g = self.params
        a = np.radians(g["alpha_deg"])
        a1 = np.array([-np.cos(a), 0.0, -np.sin(a)])
        d1 = np.array([-(g["x_ref"] - g["eo"]), 0.0, g["y_ref"]])
        rots = [_rot_z(0.0), _rot_z(120.0), _rot_z(240.0)]
        self.axes = np.stack([R @ a1 for R in rots])             # aᵢ, (3, 3)
        self.offsets = np.stack([R @ d1 for R in rots])          # dᵢ (z stays y_ref)
        # Carriage joint point at q = 0 and effector joint offset, for drawing / rod test.
        self.carriage0 = np.stack([R @ np.array([g["x_ref"], 0.0, -g["y_ref"]]) for R in rots])
        self.effector_offsets = np.stack([R @ np.array([g["eo"], 0.0, 0.0]) for R in rots])
        self.L = float(g["L"])

    def _ik(self, P):
        W = P[:, None, :] + self.offsets[None]                   # (N, 3 legs, 3)
        E = np.einsum("nkj,kj->nk", W, self.axes)
        F = np.einsum("nkj,nkj->nk", W, W) - self.L ** 2
        D = E * E - F
        return E - np.sqrt(np.maximum(D, 0.0)), D

    def _fk(self, Q):
        # Rod i is a sphere of radius L about cᵢ = qᵢ aᵢ − dᵢ (from |p + dᵢ − qᵢ aᵢ| = L).
        C = Q[:, :, None] * self.axes[None] - self.offsets[None]
        return three_sphere_lower(C, self.L)

    def _jacobian(self, P):
        W = P[:, None, :] + self.offsets[None]
        E = np.einsum("nkj,kj->nk", W, self.axes)
        F = np.einsum("nkj,nkj->nk", W, W) - self.L ** 2
        root = np.sqrt(E * E - F)
        # ∂q/∂p = a − (E a − w)/√(E² − F)
        return self.axes[None] - (E[:, :, None] * self.axes[None] - W) / root[:, :, None]

    def joint_points(self, P):
        P2 = np.atleast_2d(np.asarray(P, float))
        Q = self.ik(P2)
        carriage = self.carriage0[None] + Q[:, :, None] * self.axes[None]
        effector = P2[:, None, :] + self.effector_offsets[None]
        return carriage, effector
