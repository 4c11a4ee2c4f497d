"""Linear delta (Kossel, LinuxCNC's simulated delta): three vertical towers.

Convention of LinuxCNC ``lineardeltakins``: towers A = (0, R), B = (−R·sin 60°, −R·cos 60°),
C = (R·sin 60°, −R·cos 60°); R is the effective radius (tower minus effector offset), so the
rod joins the carriage (Xᵢ, Yᵢ, qᵢ) to the effector point itself:
qᵢ = z + √(L² − (Xᵢ − x)² − (Yᵢ − y)²).
"""
from __future__ import annotations

import numpy as np

from .machine import Kinematics, three_sphere_lower


_BLOCK = 1 << 14          # points per block of _ik


class LinearDelta(Kinematics):
    family = "lineardelta"
    GEOMETRY_KEYS = ("L", "R")

    def __post_init__(self):
        R = float(self.params["R"])
        s60, c60 = np.sin(np.radians(60.0)), np.cos(np.radians(60.0))
        self.towers = np.array([[0.0, R], [-R * s60, -R * c60], [R * s60, -R * c60]])
        self.L = float(self.params["L"])

    def _ik(self, P):
        # per tower on contiguous columns (the same operations): numpy runs (N, 3) arithmetic
        # in inner loops of 3, and a check reads the IK of 10⁶ samples; in blocks of points,
        # so that the temporaries stay in cache instead of being 10⁶-element arrays each
        Q, rad = np.empty((len(P), 3)), np.empty((len(P), 3))
        towers = self.towers.tolist()
        for a in range(0, len(P), _BLOCK):
            b = a + _BLOCK
            x, y, z = (np.ascontiguousarray(P[a:b, c]) for c in range(3))
            for k, (tx, ty) in enumerate(towers):
                dx, dy = tx - x, ty - y
                rad[a:b, k] = r = self.L ** 2 - dx * dx - dy * dy
                Q[a:b, k] = z + np.sqrt(np.maximum(r, 0.0))
        return Q, rad

    def _fk(self, Q):
        C = np.empty((len(Q), 3, 3))
        C[:, :, 0:2] = self.towers[None]
        C[:, :, 2] = Q
        return three_sphere_lower(C, self.L)

    def _jacobian(self, P):
        dx = self.towers[None, :, 0] - P[:, 0:1]
        dy = self.towers[None, :, 1] - P[:, 1:2]
        root = np.sqrt(self.L ** 2 - dx * dx - dy * dy)
        J = np.empty((len(P), 3, 3))
        J[:, :, 0] = dx / root
        J[:, :, 1] = dy / root
        J[:, :, 2] = 1.0
        return J

    def joint_points(self, P):
        P2 = np.atleast_2d(np.asarray(P, float))
        Q = self.ik(P2)
        carriage = np.concatenate([np.broadcast_to(self.towers[None], (len(P2), 3, 2)),
                                   Q[:, :, None]], axis=2)
        effector = np.broadcast_to(P2[:, None, :], (len(P2), 3, 3)).copy()
        return carriage, effector
