"""NURBS toolpaths (the path-file contract of DESIGN.md / Interpolator.fmu).

A NURBS curve is evaluated with scipy's B-splines in homogeneous coordinates (w·P, w). Its arc
length is tabulated with Gauss–Legendre quadrature on sub-intervals of every knot span and
inverted by Newton's method, so ``point(s)`` is on the curve at arc length s to ≲ 1e-12 mm
(the contract asks ≤ 1e-9 mm).
"""
from __future__ import annotations

import numpy as np

from planners.paths.base import CORNER_ANGLE, Path, PathError

_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(16)
_SUBDIV = 64            # Gauss–Legendre sub-intervals per knot span (Hermite first guess → 2 Newton steps)


class NurbsPath(Path):
    """A NURBS curve: degree p, clamped knots, control points (n, 3), weights > 0."""

    kind = "nurbs"

    def __init__(self, degree: int, knots, control_points, weights=None, source: str = "<nurbs>"):
        self.source = source
        where = source
        try:
            p = int(degree)
        except (TypeError, ValueError):
            raise PathError(f"{where}: degree must be an integer, got {degree!r}") from None
        if p != degree or p < 1:
            raise PathError(f"{where}: degree must be an integer ≥ 1, got {degree!r}")
        try:
            Pc = np.asarray(control_points, float)
            U = np.asarray(knots, float)
            w = np.ones(len(Pc)) if weights is None else np.asarray(weights, float)
        except (TypeError, ValueError) as e:
            raise PathError(f"{where}: knots, control_points and weights must be numbers ({e})") from None
        n = len(Pc)
        if Pc.ndim != 2 or Pc.shape[1] != 3 or n == 0:
            raise PathError(f"{where}: control_points must be a list of [x, y, z], got shape {Pc.shape}")
        if n < p + 1:
            raise PathError(f"{where}: {n} control points is too few for degree {p} (need ≥ {p + 1})")
        if U.ndim != 1 or len(U) != n + p + 1:
            raise PathError(f"{where}: {len(U)} knots, expected len(control_points) + degree + 1 = {n + p + 1}")
        if w.ndim != 1 or len(w) != n:
            raise PathError(f"{where}: {len(w)} weights for {n} control points")
        for name, arr in (("control_points", Pc), ("knots", U), ("weights", w)):
            if not np.isfinite(arr).all():
                raise PathError(f"{where}: {name} contain a non-finite value")
        if (w <= 0).any():
            i = int(np.argmax(w <= 0))
            raise PathError(f"{where}: weight #{i} = {w[i]} must be > 0")
        if (np.diff(U) < 0).any():
            i = int(np.argmax(np.diff(U) < 0))
            raise PathError(f"{where}: knots must be non-decreasing (knot #{i + 1} = {U[i + 1]} < {U[i]})")
        if not (np.all(U[:p + 1] == U[0]) and np.all(U[-p - 1:] == U[-1])):
            raise PathError(f"{where}: knots must be clamped (first and last knot repeated degree + 1 = {p + 1} times)")
        if not U[-1] > U[0]:
            raise PathError(f"{where}: empty path (all knots equal)")
        mult = np.unique(U[p + 1:n], return_counts=True)[1] if n > p + 1 else np.zeros(0, int)
        if len(mult) and mult.max() > p:
            raise PathError(f"{where}: an interior knot is repeated {mult.max()} times (> degree {p}): the curve breaks")
        self.degree, self.knots, self.control_points, self.weights = p, U, Pc, w
        H = np.column_stack([Pc * w[:, None], w])          # homogeneous control points
        # Derivatives by BSpline.__call__(u, nu): evaluated span by span, so they also work
        # at knots repeated ``degree`` times (BSpline.derivative() refuses those).
        # imported here: scipy.interpolate takes 0.5 s to import, and G-code never needs it
        from scipy.interpolate import BSpline
        self._H = BSpline(U, H, p, extrapolate=True)
        self._build_table()

    @classmethod
    def from_dict(cls, d: dict, source: str = "<nurbs>") -> "NurbsPath":
        for key in ("degree", "knots", "control_points"):
            if key not in d:
                raise PathError(f"{source}: NURBS path lacks '{key}'")
        if d.get("units", "mm") != "mm":
            raise PathError(f"{source}: units must be 'mm', got {d.get('units')!r}")
        return cls(d["degree"], d["knots"], d["control_points"], d.get("weights"), source)

    def to_dict(self) -> dict:
        return {"type": "nurbs", "units": "mm", "degree": self.degree,
                "knots": [float(x) for x in self.knots],
                "control_points": [[float(x) for x in P] for P in self.control_points],
                "weights": [float(x) for x in self.weights]}

    # -- parametric evaluation -----------------------------------------------------
    def _hom(self, u: np.ndarray, k: int) -> np.ndarray:
        # k-th u-derivative of the homogeneous curve; u is kept inside the knot range, where
        # extrapolate=True only serves u = u_max (evaluated on the last span, not NaN).
        if k > self.degree:
            return np.zeros((len(u), 4))
        return self._H(np.clip(u, self.knots[0], self.knots[-1]), nu=k)

    def eval_u(self, u, order: int = 0) -> list[np.ndarray]:
        """C(u) and its u-derivatives up to ``order`` (≤ 3), each (N, 3): quotient rule on A/W."""
        u = np.atleast_1d(np.asarray(u, float))
        Hs = [self._hom(u, k) for k in range(order + 1)]
        A = [h[:, :3] for h in Hs]
        W = [h[:, 3:] for h in Hs]
        C = [A[0] / W[0]]
        if order >= 1:
            C.append((A[1] - C[0] * W[1]) / W[0])
        if order >= 2:
            C.append((A[2] - 2 * C[1] * W[1] - C[0] * W[2]) / W[0])
        if order >= 3:
            C.append((A[3] - 3 * C[2] * W[1] - 3 * C[1] * W[2] - C[0] * W[3]) / W[0])
        return C

    def _speed(self, u: np.ndarray) -> np.ndarray:
        return np.linalg.norm(self.eval_u(u, 1)[1], axis=1)

    def _build_table(self) -> None:
        """Arc length at the ends of ``_SUBDIV`` sub-intervals of each non-empty knot span."""
        spans = np.unique(self.knots)
        edges = np.concatenate([np.linspace(a, b, _SUBDIV + 1)[:-1] for a, b in zip(spans[:-1], spans[1:])]
                               + [spans[-1:]])
        a, b = edges[:-1], edges[1:]
        nodes = 0.5 * (a + b)[:, None] + 0.5 * (b - a)[:, None] * _GL_NODES[None, :]
        sp = self._speed(nodes.ravel()).reshape(nodes.shape)
        # A zero parametric speed is a cusp: the arc-length map is not invertible there.
        scale = float(np.ptp(self.control_points, axis=0).max()) or 1.0
        if not np.isfinite(sp).all() or sp.min() <= 1e-9 * scale:
            i = np.unravel_index(int(np.argmin(np.where(np.isfinite(sp), sp, -1))), sp.shape)
            raise PathError(f"{self.source}: the NURBS has (nearly) zero parametric speed near "
                            f"u = {nodes[i]:.6g} (coincident control points?): not a regular curve")
        seg = 0.5 * (b - a) * (sp @ _GL_WEIGHTS)
        # du/ds = 1/σ at both ends of each sub-interval (taken just inside it, so a corner
        # knot gives the one-sided value) for the cubic Hermite first guess of u(s).
        eps = 1e-9 * (b - a)
        self._dus_a = 1.0 / self._speed(a + eps)
        self._dus_b = 1.0 / self._speed(b - eps)
        self._u_edges = edges
        self._s_edges = np.concatenate([[0.0], np.cumsum(seg)])
        self.length = float(self._s_edges[-1])
        if not self.length > 0:
            raise PathError(f"{self.source}: empty path (length 0)")

    def _arc(self, u0: np.ndarray, u: np.ndarray) -> np.ndarray:
        """∫_{u0}^{u} |C′| du by 16-point Gauss–Legendre (u within one sub-interval)."""
        h = 0.5 * (u - u0)
        nodes = (0.5 * (u + u0))[:, None] + h[:, None] * _GL_NODES[None, :]
        sp = self._speed(nodes.ravel()).reshape(nodes.shape)
        return h * (sp @ _GL_WEIGHTS)

    def u_of_s(self, s) -> np.ndarray:
        """Parameter u at arc lengths s ∈ [0, L] (Newton on the Gauss–Legendre arc length)."""
        s = np.atleast_1d(np.asarray(s, float))
        j = np.clip(np.searchsorted(self._s_edges, s, side="right") - 1, 0, len(self._u_edges) - 2)
        ua, ub = self._u_edges[j], self._u_edges[j + 1]
        sa, sb = self._s_edges[j], self._s_edges[j + 1]
        h = sb - sa
        x = np.clip((s - sa) / h, 0.0, 1.0)
        x2, x3 = x * x, x * x * x
        u = ((2 * x3 - 3 * x2 + 1) * ua + (x3 - 2 * x2 + x) * h * self._dus_a[j]
             + (-2 * x3 + 3 * x2) * ub + (x3 - x2) * h * self._dus_b[j])
        u = np.clip(u, ua, ub)
        tol = 1e-11 + 8 * np.finfo(float).eps * self.length    # mm, ≪ the 1e-9 contract
        for _ in range(12):
            f = sa + self._arc(ua, u) - s
            if np.abs(f).max(initial=0.0) <= tol:
                break
            u = np.clip(u - f / self._speed(u), ua, ub)
        return u

    def _derivs(self, s: np.ndarray, order: int) -> list[np.ndarray]:
        u = self.u_of_s(s)
        C = self.eval_u(u, order)
        out = [C[0]]
        if order == 0:
            return out
        # Chain rule for d/ds = u′ d/du with σ = |C′|: u′ = 1/σ, u″ = −(C′·C″)/σ⁴,
        # u‴ = −(C″·C″ + C′·C‴)/σ⁵ + 4(C′·C″)²/σ⁷.
        sig = np.linalg.norm(C[1], axis=1)[:, None]
        u1 = 1.0 / sig
        out.append(C[1] * u1)
        if order >= 2:
            d12 = np.sum(C[1] * C[2], axis=1)[:, None]
            u2 = -d12 / sig**4
            out.append(C[2] * u1**2 + C[1] * u2)
        if order >= 3:
            d22 = np.sum(C[2] * C[2], axis=1)[:, None]
            d13 = np.sum(C[1] * C[3], axis=1)[:, None]
            u3 = -(d22 + d13) / sig**5 + 4 * d12**2 / sig**7
            out.append(C[3] * u1**3 + 3 * C[2] * u1 * u2 + C[1] * u3)
        return out

    def s_of_u(self, u) -> np.ndarray:
        """Arc length at parameters u."""
        u = np.atleast_1d(np.asarray(u, float))
        j = np.clip(np.searchsorted(self._u_edges, u, side="right") - 1, 0, len(self._u_edges) - 2)
        return self._s_edges[j] + self._arc(self._u_edges[j], u)

    def corners(self) -> np.ndarray:
        """Arc lengths of interior knots (multiplicity = degree) where the tangent turns."""
        p, U = self.degree, self.knots
        vals, mult = np.unique(U, return_counts=True)
        out = []
        for u, m in zip(vals[1:-1], mult[1:-1]):
            if m < p:
                continue           # C^(p−m) ≥ C¹ there: tangent continuous
            eps = 1e-9 * (U[-1] - U[0])
            left = self.eval_u(np.array([u - eps]), 1)[1][0]
            right = self.eval_u(np.array([u]), 1)[1][0]
            c = np.dot(left, right) / (np.linalg.norm(left) * np.linalg.norm(right))
            if np.arccos(np.clip(c, -1.0, 1.0)) > CORNER_ANGLE:
                out.append(float(self.s_of_u(np.array([u]))[0]))
        return np.array(out)
