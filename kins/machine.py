"""Machine description and the kinematics interface shared by every PKM family.

A machine file (``benchmarks/machines/<id>.toml``) gives the geometry, joint strokes,
limits, servo period and workspace box. :func:`load_machine` validates it and returns
the kinematics object of its family (``kins.keops``, ``kins.lineardelta``, ``kins.pn101``).

Every family implements three vectorised primitives on (N, 3) arrays:
  ``_ik(P) -> (Q, reach)``  joint positions and the radicand under the root of each leg
                            (reach < 0: the rod cannot reach the point),
  ``_fk(Q) -> (P, reach)``  closed-form forward kinematics,
  ``_jacobian(P)``          dq/dp, shape (N, 3, 3).
The base class adds shape handling, stroke/reach checks, errors and findings.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from kins.resources import MACHINE_DIR


class MachineFileError(ValueError):
    """A machine file is missing, malformed, or has an invalid value."""


class WorkspaceError(ValueError):
    """A Cartesian point (or joint vector) lies outside the machine's workspace."""

    def __init__(self, message: str, index: int, joint: int | None, excess_mm: float):
        super().__init__(message)
        self.index = index
        self.joint = joint
        self.excess_mm = excess_mm


@dataclass(frozen=True)
class Limits:
    """Velocity, acceleration, jerk limits (mm/s, mm/s², mm/s³), same for each axis."""

    v: float
    a: float
    j: float

    def as_array(self) -> np.ndarray:
        return np.array([self.v, self.a, self.j])


@dataclass(frozen=True)
class MachineLimits:
    joint: Limits
    cartesian: Limits
    feed_max: float          # F_max, mm/s (the programmed feed ceiling)
    chord_error_mm: float    # ε of the chord-error feed cap

    def joint_scaled(self, factor: float) -> "MachineLimits":
        """These limits with the joint v, a and j each × ``factor`` (a planner's margin or slack)."""
        J = self.joint
        return replace(self, joint=Limits(J.v * factor, J.a * factor, J.j * factor))


@dataclass(frozen=True)
class Finding:
    """One workspace/singularity problem found by :meth:`Kinematics.check`."""

    index: int          # point index in the array given to check()
    kind: str           # "unreachable" | "stroke" | "singularity" | "box"
    joint: int | None   # 1-based joint number, None for Cartesian findings
    value: float        # the offending value (mm, or condition number)
    limit: float        # the limit it broke
    message: str


@dataclass
class Kinematics:
    """Base of every kinematics family. Subclasses set ``family`` and the primitives."""

    name: str
    source: str                       # the file it came from (for messages)
    servo_period_s: float
    limits: MachineLimits
    q_min: float
    q_max: float
    workspace_min: np.ndarray         # Cartesian box, mm
    workspace_max: np.ndarray
    home: np.ndarray                  # workspace centre used by the benchmarks
    cond_max: float                   # singularity-proximity threshold on cond(J)
    params: dict                      # geometry of the family, as in the file
    raw: dict = field(repr=False, default_factory=dict)  # the whole file (drive, bus, …)

    family = "abstract"
    GEOMETRY_KEYS: tuple[str, ...] = ()

    def __post_init__(self):
        """Subclasses derive their geometry from ``params`` here."""

    # -- primitives (subclasses) -------------------------------------------------
    def _ik(self, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def _fk(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def _jacobian(self, P: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def joint_points(self, P) -> tuple[np.ndarray, np.ndarray]:
        """(carriage joint points, effector joint points), each (N, 3, 3) [point, leg, xyz].

        The rod of leg i joins the two; its length is constant (test invariant).
        """
        raise NotImplementedError

    # -- public API ----------------------------------------------------------------
    def ik(self, P):
        """Joint positions (mm) of Cartesian points P, shape (N, 3) or (3,).

        Raises :class:`WorkspaceError` naming the first point a rod cannot reach or
        whose joint leaves its stroke.
        """
        P2, single = _as_points(P, "P")
        Q, reach = self._ik(P2)
        bad = reach < 0
        if bad.any():
            i, k = _first(bad)
            raise WorkspaceError(
                f"{self.name}: point #{i} {_fmt(P2[i])} mm is out of reach of rod {k + 1} "
                f"(radicand {reach[i, k]:.6g} mm² < 0)", i, k + 1, float(np.sqrt(-reach[i, k])))
        self._raise_on_stroke(Q, P2)
        return Q[0] if single else Q

    def fk(self, Q):
        """Cartesian points (mm) of joint positions Q, shape (N, 3) or (3,); closed form."""
        Q2, single = _as_points(Q, "Q")
        P, reach = self._fk(Q2)
        bad = reach < 0
        if bad.any():
            i = int(np.argmax(bad))
            raise WorkspaceError(
                f"{self.name}: joint vector #{i} {_fmt(Q2[i])} mm has no assembly "
                f"(radicand {reach[i]:.6g} < 0)", i, None, float(np.sqrt(-reach[i])))
        return P[0] if single else P

    def jacobian(self, P):
        """dq/dp at P: shape (N, 3, 3) (or (3, 3) for one point); row i = joint i."""
        P2, single = _as_points(P, "P")
        J = self._jacobian(P2)
        return J[0] if single else J

    def condition_number(self, P) -> np.ndarray:
        """2-norm condition number of the Jacobian; inf where a rod cannot reach."""
        P2, single = _as_points(P, "P")
        _, reach = self._ik(P2)
        c = np.full(len(P2), np.inf)
        ok = (reach >= 0).all(axis=1)
        if ok.any():
            with np.errstate(divide="ignore", invalid="ignore"):
                c[ok] = np.linalg.cond(self._jacobian(P2[ok]))
        c[~np.isfinite(c)] = np.inf
        return c[0] if single else c

    def _condition_above(self, P, ok) -> np.ndarray:
        """condition_number(P) at the points ``ok`` where it may exceed cond_max, 0 elsewhere:
        cond = σ₁/σ₃ = σ₁²σ₂/|det J| ≤ ‖J‖_F³/|det J|, so the SVD, the costly part of a check
        of a long path, only runs where that bound is not clearly below cond_max (docs/TUNING.md,
        issue 33)."""
        c = np.zeros(len(P))
        at = np.nonzero(ok)[0]
        if not len(at):
            return c
        J = self._jacobian(P[at])
        with np.errstate(all="ignore"):
            bound_ok = (J * J).sum(axis=(1, 2)) ** 1.5 <= 0.999 * self.cond_max * np.abs(np.linalg.det(J))
        may = at[~bound_ok]
        if len(may):
            c[may] = self.condition_number(P[may])
        return c

    def check(self, P) -> list[Finding]:
        """All workspace and singularity findings for points P (no exception)."""
        P2, _ = _as_points(P, "P")
        Q, reach = self._ik(P2)
        out: list[Finding] = []
        for i, k in zip(*np.nonzero(reach < 0)):
            out.append(Finding(int(i), "unreachable", int(k) + 1, float(np.sqrt(-reach[i, k])), 0.0,
                               f"point #{i} {_fmt(P2[i])}: rod {k + 1} cannot reach it "
                               f"(short by ≈{np.sqrt(-reach[i, k]):.4g} mm)"))
        reachable = (reach >= 0).all(axis=1)
        lo, hi = Q < self.q_min, Q > self.q_max
        for i, k in zip(*np.nonzero((lo | hi) & reachable[:, None])):
            lim = self.q_min if lo[i, k] else self.q_max
            out.append(Finding(int(i), "stroke", int(k) + 1, float(Q[i, k]), lim,
                               f"point #{i} {_fmt(P2[i])}: joint {k + 1} at {Q[i, k]:.6g} mm is "
                               f"beyond its stroke limit {lim:g} mm by {abs(Q[i, k] - lim):.4g} mm"))
        cond = self._condition_above(P2, reachable)
        for i in np.nonzero(reachable & (cond > self.cond_max))[0]:
            out.append(Finding(int(i), "singularity", None, float(cond[i]), self.cond_max,
                               f"point #{i} {_fmt(P2[i])}: Jacobian condition number "
                               f"{cond[i]:.4g} > {self.cond_max:g} (near a singularity)"))
        outside = (P2 < self.workspace_min - 1e-9) | (P2 > self.workspace_max + 1e-9)
        for i in np.nonzero(outside.any(axis=1))[0]:
            out.append(Finding(int(i), "box", None, 0.0, 0.0,
                               f"point #{i} {_fmt(P2[i])}: outside the workspace box "
                               f"{_fmt(self.workspace_min)}…{_fmt(self.workspace_max)} mm"))
        out.sort(key=lambda f: (f.index, f.kind))
        return out

    # -- helpers -------------------------------------------------------------------
    def _raise_on_stroke(self, Q: np.ndarray, P: np.ndarray) -> None:
        lo, hi = Q < self.q_min - 1e-9, Q > self.q_max + 1e-9
        if lo.any() or hi.any():
            i, k = _first(lo | hi)
            lim = self.q_min if lo[i, k] else self.q_max
            raise WorkspaceError(
                f"{self.name}: point #{i} {_fmt(P[i])} mm puts joint {k + 1} at {Q[i, k]:.6g} mm, "
                f"beyond its stroke limit {lim:g} mm by {abs(Q[i, k] - lim):.4g} mm",
                i, k + 1, float(abs(Q[i, k] - lim)))


def _as_points(A, what: str) -> tuple[np.ndarray, bool]:
    A = np.asarray(A, dtype=float)
    single = A.ndim == 1
    A2 = A.reshape(1, -1) if single else A
    if A2.ndim != 2 or A2.shape[1] != 3:
        raise ValueError(f"{what} must have shape (N, 3) or (3,), got {np.shape(A)}")
    if not np.isfinite(A2).all():
        i = int(np.argmax(~np.isfinite(A2).all(axis=1)))
        raise ValueError(f"{what}[{i}] = {A2[i]} is not finite")
    return A2, single


def _first(mask: np.ndarray) -> tuple[int, int]:
    flat = int(np.argmax(mask.reshape(-1)))
    return divmod(flat, mask.shape[1])


def _fmt(p) -> str:
    return "(" + ", ".join(f"{v:.6g}" for v in p) + ")"


def three_sphere_lower(C: np.ndarray, L: float) -> tuple[np.ndarray, np.ndarray]:
    """Intersection of three spheres of equal radius L centred at C (N, 3 centres, 3),
    the solution with the smaller z (effector below the carriages). Returns (P, radicand).

    Trilateration in the frame of the centres: e_x along C1→C2, e_y in their plane,
    e_z = e_x × e_y. Equal radii make the in-plane coordinates the circumcentre.
    """
    c1, c2, c3 = C[:, 0], C[:, 1], C[:, 2]
    d12 = c2 - c1
    d = np.linalg.norm(d12, axis=1)
    ex = d12 / d[:, None]
    d13 = c3 - c1
    i = np.einsum("ij,ij->i", ex, d13)
    ey_raw = d13 - i[:, None] * ex
    jn = np.linalg.norm(ey_raw, axis=1)
    ey = ey_raw / jn[:, None]
    ez = np.cross(ex, ey)
    x = d / 2.0                                        # equal radii
    y = (i * i + jn * jn - 2.0 * i * x) / (2.0 * jn)
    rad = L * L - x * x - y * y
    z = np.sqrt(np.maximum(rad, 0.0))
    base = c1 + x[:, None] * ex + y[:, None] * ey
    # pick the root below the plane of the centres
    sgn = np.where(ez[:, 2] > 0, -1.0, 1.0)
    return base + (sgn * z)[:, None] * ez, rad
