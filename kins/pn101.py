"""LOLA pn101: vertical 3-axis PKM with three parallel sliders along x.

Source: Dimić, Milutinović, Živanović, Mitrović, ICPE-S 2018, eqs (5)–(11). Frames {B}
(base) and {P} (platform) stay parallel; X = x_T − x_TP, Y = y_T − y_TP, Z = z_T − z_TP.
  IK  p₁ = X + c₄ − √(c₁² − (Y + d)² − (Z + z_p2)²)     (the printed "p₁² = …" of eq (8))
      p₂ = X      − √(c₂² − (Y + d)² − (Z + z_p2)²)
      p₃ = X + x_p3 − √(c₃² − (Z + z_p3 − z_o3)²)
  FK  eq (9) X from p₁, p₂; eq (10) Z from p₃ (lower branch); eq (11) Y (branch Y + d < 0).
Legs 1 and 2 share the same (Y, Z) offsets, so c₁ ≠ c₂ is what lets them tell X from
(Y, Z): with c₁ = c₂ the mechanism is singular everywhere. No parameter values are
published; the machine file's values are assumed.
"""
from __future__ import annotations

import numpy as np

from .machine import Kinematics


class Pn101(Kinematics):
    family = "pn101"
    GEOMETRY_KEYS = ("c1", "c2", "c3", "c4", "d", "z_p2", "x_p3", "z_p3", "y_o3", "z_o3",
                     "x_TP", "y_TP", "z_TP")

    def __post_init__(self):
        g = {k: float(v) for k, v in self.params.items()}
        self.g = g
        self.tool = np.array([g["x_TP"], g["y_TP"], g["z_TP"]])
        if g["c1"] == g["c2"]:
            from .machine import MachineFileError   # local: kins.machine imports this module
            raise MachineFileError(f"{self.source}: [kinematics] c1 = c2 makes pn101 singular everywhere")

    def _local(self, P):
        return (P - self.tool).T  # X, Y, Z rows

    def _ik(self, P):
        g = self.g
        X, Y, Z = self._local(P)
        r12 = (Y + g["d"]) ** 2 + (Z + g["z_p2"]) ** 2
        rad = np.stack([g["c1"] ** 2 - r12, g["c2"] ** 2 - r12,
                        g["c3"] ** 2 - (Z + g["z_p3"] - g["z_o3"]) ** 2], axis=1)
        # Y + d ≥ 0 is the other assembly branch of legs 1, 2 (eq 11): treat as unreachable.
        rad[:, 0] = np.where(Y + g["d"] > 0, -np.abs(rad[:, 0]) - (Y + g["d"]) ** 2, rad[:, 0])
        rad[:, 1] = np.where(Y + g["d"] > 0, -np.abs(rad[:, 1]) - (Y + g["d"]) ** 2, rad[:, 1])
        root = np.sqrt(np.maximum(rad, 0.0))
        Q = np.stack([X + g["c4"] - root[:, 0], X - root[:, 1], X + g["x_p3"] - root[:, 2]], axis=1)
        return Q, rad

    def _fk(self, Q):
        g = self.g
        p1, p2, p3 = Q.T
        X = (p2 ** 2 + g["c1"] ** 2 - g["c2"] ** 2 - (p1 - g["c4"]) ** 2) / (2.0 * (p2 - p1 + g["c4"]))
        rz = g["c3"] ** 2 - (p3 - (X + g["x_p3"])) ** 2
        Z = g["z_o3"] - g["z_p3"] - np.sqrt(np.maximum(rz, 0.0))
        ry = g["c2"] ** 2 - (p2 - X) ** 2 - (Z + g["z_p2"]) ** 2
        Y = -g["d"] - np.sqrt(np.maximum(ry, 0.0))
        return np.stack([X, Y, Z], axis=1) + self.tool, np.minimum(rz, ry)

    def _jacobian(self, P):
        g = self.g
        X, Y, Z = self._local(P)
        r12 = (Y + g["d"]) ** 2 + (Z + g["z_p2"]) ** 2
        s1, s2 = np.sqrt(g["c1"] ** 2 - r12), np.sqrt(g["c2"] ** 2 - r12)
        z3 = Z + g["z_p3"] - g["z_o3"]
        s3 = np.sqrt(g["c3"] ** 2 - z3 ** 2)
        J = np.zeros((len(P), 3, 3))
        J[:, :, 0] = 1.0
        J[:, 0, 1], J[:, 0, 2] = (Y + g["d"]) / s1, (Z + g["z_p2"]) / s1
        J[:, 1, 1], J[:, 1, 2] = (Y + g["d"]) / s2, (Z + g["z_p2"]) / s2
        J[:, 2, 2] = z3 / s3
        return J

    def joint_points(self, P):
        g = self.g
        P2 = np.atleast_2d(np.asarray(P, float))
        Q = self.ik(P2)
        n = len(P2)
        op = P2 - self.tool                                    # platform origin O_P in {B}
        plat = np.array([[g["c4"], g["d"], g["z_p2"]], [0.0, 0.0, g["z_p2"]], [g["x_p3"], 0.0, g["z_p3"]]])
        effector = op[:, None, :] + plat[None]
        base = np.array([[0.0, 0.0, 0.0], [0.0, -g["d"], 0.0], [0.0, -g["y_o3"], g["z_o3"]]])
        carriage = np.broadcast_to(base[None], (n, 3, 3)).copy()
        carriage[:, :, 0] += Q
        # Leg 3 is planar in x-z (eq 7 has no y term): its rod length is measured in x-z.
        carriage[:, 2, 1] = effector[:, 2, 1]
        return carriage, effector
