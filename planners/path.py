"""Toolpaths: one geometry, parametrised by arc length s (mm), shared by every planner.

Two kinds (the path-file contract of DESIGN.md / Interpolator.fmu):

* :class:`NurbsPath` — a NURBS curve, evaluated with scipy's B-splines in homogeneous
  coordinates (w·P, w). Its arc length is tabulated with Gauss–Legendre quadrature on
  sub-intervals of every knot span and inverted by Newton's method, so ``point(s)`` is on
  the curve at arc length s to ≲ 1e-12 mm (the contract asks ≤ 1e-9 mm).
* :class:`SegmentPath` — lines and circular/helical arcs (from G-code, from G64 corner
  blending, or a NURBS cut into G1 lines). Exact closed forms.

Every path gives ``length``, ``point(s)``, ``derivs(s)`` (P, P′, P″, P‴ with respect to arc
length), ``curvature(s)``, ``corners()`` (arc lengths where the tangent is discontinuous:
the exact-stop points), ``bounds()`` and ``to_file(file)``. :func:`load_path` reads .json
(nurbs | segments) and .ngc files; :func:`resolve_path` finds a standard path by name in
``benchmarks/paths/``.
"""
from __future__ import annotations

import json
import math
from pathlib import Path as FsPath

import numpy as np
from scipy.interpolate import BSpline

PATH_DIR = FsPath(__file__).resolve().parent.parent / "benchmarks" / "paths"

S_TOL = 1e-9            # mm: arc lengths this far outside [0, L] are clipped, beyond → error
CONTIG_TOL = 1e-9       # mm: consecutive segments must join this closely (file contract)
END_TOL = 1e-6          # mm: an arc's redundant "end" must agree this closely
CORNER_ANGLE = 1e-6     # rad: a tangent turn larger than this is a corner (exact stop)
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(16)
_SUBDIV = 64            # Gauss–Legendre sub-intervals per knot span (Hermite first guess → 2 Newton steps)
_CHUNK = 65536          # arc lengths per block when a segment path evaluates many at once


class PathError(ValueError):
    """A toolpath is malformed or a query is outside it; the message names file and problem."""



def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b of two 3-vectors (np.cross costs ~15 µs a call; paths build one per segment)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])

def _vec3(v, what: str, where: str) -> np.ndarray:
    a = np.asarray(v, float)
    # math.isfinite on three floats: np.isfinite(a).all() costs ~3 µs, paths build 10⁵ of these
    if a.shape != (3,) or not (math.isfinite(a[0]) and math.isfinite(a[1]) and math.isfinite(a[2])):
        raise PathError(f"{where}: {what} must be 3 finite numbers [x, y, z], got {v!r}")
    return a


def norm3(v) -> float:
    """|v| of one 3-vector (np.linalg.norm costs ~3 µs a call)."""
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


class Path:
    """Base class: a curve from s = 0 to s = length (mm)."""

    kind = "abstract"
    length: float
    source: str

    # -- subclasses -------------------------------------------------------------------
    def _derivs(self, s: np.ndarray, order: int) -> list[np.ndarray]:
        raise NotImplementedError

    def corners(self) -> np.ndarray:
        raise NotImplementedError

    def to_dict(self) -> dict:
        raise NotImplementedError

    # -- public -------------------------------------------------------------------------
    def _check_s(self, s) -> tuple[np.ndarray, bool]:
        a = np.asarray(s, float)
        scalar = a.ndim == 0
        a = np.atleast_1d(a).ravel()
        if not np.isfinite(a).all():
            i = int(np.argmax(~np.isfinite(a)))
            raise PathError(f"{self.source}: arc length #{i} is {a[i]} (not finite)")
        if len(a) and (a.min() < -S_TOL or a.max() > self.length + S_TOL):
            i = int(np.argmax((a < -S_TOL) | (a > self.length + S_TOL)))
            raise PathError(f"{self.source}: arc length #{i} = {a[i]:.12g} mm is outside "
                            f"the path [0, {self.length:.12g}] mm")
        return np.clip(a, 0.0, self.length), scalar

    def point(self, s) -> np.ndarray:
        """Points (N, 3) at arc lengths s (mm); a scalar s gives shape (3,)."""
        a, scalar = self._check_s(s)
        P = self._derivs(a, 0)[0]
        return P[0] if scalar else P

    def derivs(self, s) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(P, dP/ds, d²P/ds², d³P/ds³) at arc lengths s, each (N, 3).

        At a corner the outgoing (right-hand) values are returned, at s = length the
        incoming ones.
        """
        a, _ = self._check_s(s)
        return tuple(self._derivs(a, 3))

    def tangent(self, s) -> np.ndarray:
        a, _ = self._check_s(s)
        return self._derivs(a, 1)[1]

    def curvature(self, s) -> np.ndarray:
        """κ(s) = |d²P/ds²| (1/mm), shape (N,)."""
        a, _ = self._check_s(s)
        return np.linalg.norm(self._derivs(a, 2)[2], axis=1)

    def sample(self, ds: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
        """(s, P) on a uniform grid of step ≤ ds that includes both ends."""
        n = max(2, int(np.ceil(self.length / ds)) + 1)
        s = np.linspace(0.0, self.length, n)
        return s, self.point(s)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(min xyz, max xyz) of the path, from dense sampling (step ≤ 0.05 mm) and corners."""
        s, P = self.sample(min(0.05, self.length / 16))
        return P.min(axis=0), P.max(axis=0)

    def to_file(self, file) -> None:
        """Write the path file (JSON, 17 significant digits) that Interpolator.fmu reads."""
        with open(file, "w") as f:
            json.dump(self.to_dict(), f, indent=1)
            f.write("\n")

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.source!r} length={self.length:.6g} mm>"


# ======================================================================================
# NURBS
# ======================================================================================
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


# ======================================================================================
# Lines, arcs, helices
# ======================================================================================
class Line:
    kind = "line"

    def __init__(self, start, end, line: int | None = None, where: str = "<segment>", direction=None):
        self.start = _vec3(start, "line start", where)
        self.end = _vec3(end, "line end", where)
        self.line = line
        self.length = norm3(self.end - self.start)
        if not self.length > CONTIG_TOL:
            raise PathError(f"{where}: zero-length line at {self.start.tolist()}")
        self.direction = (self.end - self.start) / self.length
        if direction is not None:
            # A known exact direction (e.g. a line trimmed by corner blends): for a very short
            # line, the direction of end − start would carry the rounding of both ends.
            d = np.asarray(direction, float)
            d = d / norm3(d)
            if norm3(self.start + self.length * d - self.end) > END_TOL:
                raise PathError(f"{where}: line direction {d.tolist()} does not lead from start to end")
            self.direction = d

    @classmethod
    def exact(cls, start, end, direction, line: int | None = None) -> "Line":
        """A line from geometry a planner computed (a blend's trimmed line, keeping its
        original direction): no re-validation (see Arc.exact)."""
        g = cls.__new__(cls)
        g.start, g.end, g.line, g.direction = start, end, line, direction
        g.length = norm3(end - start)
        return g

    def tangent_in(self):
        return self.direction

    def tangent_out(self):
        return self.direction

    def to_dict(self) -> dict:
        d = {"type": "line", "start": self.start.tolist(), "end": self.end.tolist()}
        if self.line is not None:
            d["line"] = int(self.line)
        return d


class Arc:
    """Circle or helix: c + Rot(n, φ)(start − c) + (φ/θ)·h·n, φ ∈ [0, θ] (contract)."""

    kind = "arc"

    def __init__(self, start, center, normal, angle: float, rise: float = 0.0,
                 line: int | None = None, where: str = "<segment>", end=None):
        self.start = _vec3(start, "arc start", where)
        self.center = _vec3(center, "arc center", where)
        n = _vec3(normal, "arc normal", where)
        nn = norm3(n)
        if not nn > 0:
            raise PathError(f"{where}: arc normal is the zero vector")
        if abs(nn - 1.0) > 1e-6:
            raise PathError(f"{where}: arc normal {n.tolist()} is not a unit vector (|n| = {nn:.9g})")
        self.normal = n / nn
        try:
            self.angle = float(angle)
            self.rise = float(rise)
        except (TypeError, ValueError):
            raise PathError(f"{where}: arc angle and rise must be numbers") from None
        if not (np.isfinite(self.angle) and self.angle > 0):
            raise PathError(f"{where}: arc angle θ = {angle!r} must be > 0 (radians)")
        if not np.isfinite(self.rise):
            raise PathError(f"{where}: arc rise h = {rise!r} is not finite")
        self.line = line
        off = self._derive()
        if abs(off) > END_TOL:
            raise PathError(f"{where}: arc center is {off:.6g} mm off the plane through start ⟂ normal")
        if not self.radius > CONTIG_TOL:
            raise PathError(f"{where}: arc radius is zero (center = start)")
        if end is not None:
            e = _vec3(end, "arc end", where)
            if norm3(e - self.end) > END_TOL:
                raise PathError(f"{where}: arc end {e.tolist()} disagrees with start/center/normal/angle/rise "
                                f"(computed {self.end.tolist()}, off by {norm3(e - self.end):.3g} mm)")

    @classmethod
    def exact(cls, start, center, normal, angle: float, line: int | None = None) -> "Arc":
        """A circular arc from geometry a planner computed (a G64 blend): no re-validation,
        which costs more than the arc itself when a program has 10⁵ corners."""
        g = cls.__new__(cls)
        g.start, g.center, g.normal, g.angle, g.rise, g.line = start, center, normal, angle, 0.0, line
        g._derive()
        return g

    @classmethod
    def from_parts(cls, start, center, normal, angle: float, line, a, b, radius: float, length: float,
                   end) -> "Arc":
        """A circular arc whose derived values (what _derive computes) the caller computed
        for many arcs at once (planners.blend)."""
        g = cls.__new__(cls)
        g.start, g.center, g.normal, g.angle, g.rise, g.line = start, center, normal, angle, 0.0, line
        g.a, g.b, g.radius, g.length, g.end = a, b, radius, length, end
        return g

    def _derive(self) -> float:
        """In-plane basis a, b, radius, length and end; returns the centre's offset from the plane."""
        a = self.start - self.center
        nv = self.normal
        off = float(a[0] * nv[0] + a[1] * nv[1] + a[2] * nv[2])
        self.a = a - off * nv
        self.b = cross3(nv, self.a)
        self.radius = norm3(self.a)
        self.length = float(self.angle * math.hypot(self.radius, self.rise / self.angle))
        # eval() at φ = θ for one point, without arrays
        self.end = self.center + math.cos(self.angle) * self.a + math.sin(self.angle) * self.b + self.rise * nv
        return off

    def eval(self, t: np.ndarray, order: int) -> list[np.ndarray]:
        """Point and s-derivatives at arc length t from the arc start."""
        k = self.angle / self.length                # dφ/ds
        phi = (t * k)[:, None]
        c, s_ = np.cos(phi), np.sin(phi)
        hn = (self.rise / self.angle) * self.normal
        out = [self.center + c * self.a + s_ * self.b + phi * hn]
        if order >= 1:
            out.append(k * (-s_ * self.a + c * self.b + hn))
        if order >= 2:
            out.append(k**2 * (-c * self.a - s_ * self.b))
        if order >= 3:
            out.append(k**3 * (s_ * self.a - c * self.b))
        return out

    def _tangent(self, phi: float) -> np.ndarray:
        """dP/ds at sweep φ: the first derivative of eval() for one point, without arrays."""
        k = self.angle / self.length
        hn = (self.rise / self.angle) * self.normal
        return k * (-math.sin(phi) * self.a + math.cos(phi) * self.b + hn)

    def tangent_in(self):
        return self._tangent(0.0)

    def tangent_out(self):
        return self._tangent(self.angle)

    def to_dict(self) -> dict:
        d = {"type": "arc", "start": self.start.tolist(), "center": self.center.tolist(),
             "normal": self.normal.tolist(), "angle": self.angle, "rise": self.rise,
             "end": self.end.tolist()}
        if self.line is not None:
            d["line"] = int(self.line)
        return d


def segment_from_dict(d: dict, where: str):
    if not isinstance(d, dict) or "type" not in d:
        raise PathError(f"{where}: a segment must be an object with a 'type'")
    line = d.get("line")
    try:
        if d["type"] == "line":
            return Line(d["start"], d["end"], line, where)
        if d["type"] == "arc":
            return Arc(d["start"], d["center"], d["normal"], d["angle"], d.get("rise", 0.0),
                       line, where, end=d.get("end"))
    except KeyError as e:
        raise PathError(f"{where}: {d['type']} segment lacks {e}") from None
    raise PathError(f"{where}: unknown segment type {d['type']!r} (line | arc)")


class SegmentPath(Path):
    """Consecutive lines and arcs; s runs from 0 at the first start to the total length."""

    kind = "segments"

    def __init__(self, segments, source: str = "<segments>"):
        self.source = source
        segs = list(segments)
        if not segs:
            raise PathError(f"{source}: empty path (no segments)")
        starts_all = np.array([g.start for g in segs])
        if len(segs) > 1:
            starts = starts_all[1:]
            gaps = np.linalg.norm(starts - np.array([g.end for g in segs[:-1]]), axis=1)
            bad = np.nonzero(gaps > CONTIG_TOL * np.maximum(1.0, np.abs(starts).max(axis=1)))[0]
            if len(bad):
                i, gap = int(bad[0]) + 1, float(gaps[bad[0]])
                ln = f" (G-code line {segs[i].line})" if segs[i].line is not None else ""
                raise PathError(f"{source}: segment #{i}{ln} starts {gap:.3g} mm away from the end "
                                f"of segment #{i - 1}: segments must be contiguous")
        self.segments = segs
        lens = np.array([g.length for g in segs])
        self.seg_start = np.concatenate([[0.0], np.cumsum(lens)])
        self.length = float(self.seg_start[-1])
        # Vectorised tables (lines use a = direction, arcs the circle frame; zeros elsewhere).
        n = len(segs)
        self._is_arc = np.array([g.kind == "arc" for g in segs])
        arcs = [g for g in segs if g.kind == "arc"]
        ia, il = np.nonzero(self._is_arc)[0], np.nonzero(~self._is_arc)[0]
        self._origin = starts_all.copy()
        self._dir, self._a, self._b, self._hn = (np.zeros((n, 3)) for _ in range(4))
        self._k = np.zeros(n)
        if len(il):
            self._dir[il] = np.array([segs[i].direction for i in il.tolist()])
        if arcs:
            self._origin[ia] = np.array([g.center for g in arcs])
            self._a[ia] = np.array([g.a for g in arcs])
            self._b[ia] = np.array([g.b for g in arcs])
            self._hn[ia] = np.array([(g.rise / g.angle) * g.normal for g in arcs])
            self._k[ia] = [g.angle / g.length for g in arcs]
        self._lens = lens
        assert len(self._k) == n

    @classmethod
    def from_dict(cls, d: dict, source: str = "<segments>") -> "SegmentPath":
        if d.get("units", "mm") != "mm":
            raise PathError(f"{source}: units must be 'mm', got {d.get('units')!r}")
        segs = d.get("segments")
        if not isinstance(segs, list):
            raise PathError(f"{source}: a segments path needs a list 'segments'")
        return cls([segment_from_dict(g, f"{source}: segment #{i}") for i, g in enumerate(segs)], source)

    def to_dict(self) -> dict:
        return {"type": "segments", "units": "mm", "segments": [g.to_dict() for g in self.segments]}

    def segment_index(self, s: np.ndarray) -> np.ndarray:
        """Index of the segment holding each s (a junction belongs to the outgoing segment)."""
        return np.clip(np.searchsorted(self.seg_start, s, side="right") - 1, 0, len(self.segments) - 1)

    def _derivs(self, s: np.ndarray, order: int) -> list[np.ndarray]:
        if len(s) > _CHUNK:
            # ~15 temporaries of (N, 3) each: a 10⁶-sample profile in one go peaked at ~0.5 GB;
            # element-wise, so chunks give the same bits
            parts = [self._derivs(s[k:k + _CHUNK], order) for k in range(0, len(s), _CHUNK)]
            return [np.concatenate([p[d] for p in parts]) for d in range(order + 1)]
        i = self.segment_index(s)
        t = np.minimum(s - self.seg_start[i], self._lens[i])[:, None]
        arc = self._is_arc[i][:, None]
        k = self._k[i][:, None]
        phi = t * k
        c, sn = np.cos(phi), np.sin(phi)
        a, b, hn = self._a[i], self._b[i], self._hn[i]
        d = self._dir[i]
        P = self._origin[i] + np.where(arc, c * a + sn * b + phi * hn, t * d)
        out = [P]
        if order >= 1:
            out.append(np.where(arc, k * (-sn * a + c * b + hn), d))
        if order >= 2:
            out.append(np.where(arc, k**2 * (-c * a - sn * b), 0.0))
        if order >= 3:
            out.append(np.where(arc, k**3 * (sn * a - c * b), 0.0))
        return out

    def corners(self) -> np.ndarray:
        # segments are immutable: the tangent breaks are computed once, all joins at a time
        if getattr(self, "_corners", None) is None:
            if len(self.segments) < 2:
                self._corners = np.array([])
            else:
                # unit tangents from the struct-of-arrays tables: a line's direction; an arc's
                # k·(b + hn) at φ = 0 and k·(−sin θ·a + cos θ·b + hn) at φ = θ
                th = np.array([g.angle if g.kind == "arc" else 0.0 for g in self.segments])[:, None]
                arc, k = self._is_arc[:, None], self._k[:, None]
                t_in = np.where(arc, k * (self._b + self._hn), self._dir)
                t_out = np.where(arc, k * (-np.sin(th) * self._a + np.cos(th) * self._b + self._hn), self._dir)
                t0, t1 = t_out[:-1], t_in[1:]
                c = np.einsum("ij,ij->i", t0, t1) / (np.linalg.norm(t0, axis=1) * np.linalg.norm(t1, axis=1))
                sharp = np.arccos(np.clip(c, -1.0, 1.0)) > CORNER_ANGLE
                self._corners = np.asarray(self.seg_start[1:len(self.segments)][sharp], float)
        return self._corners.copy()

    def line_at(self, s) -> np.ndarray:
        """G-code line number (or −1) of the segment at each arc length (for messages)."""
        a, _ = self._check_s(s)
        lines = np.array([-1 if g.line is None else g.line for g in self.segments])
        return lines[self.segment_index(a)]


# ======================================================================================
# Files
# ======================================================================================
def path_from_dict(d: dict, source: str = "<path>") -> Path:
    if not isinstance(d, dict):
        raise PathError(f"{source}: a path file must hold a JSON object")
    kind = d.get("type")
    if kind == "nurbs":
        return NurbsPath.from_dict(d, source)
    if kind == "segments":
        return SegmentPath.from_dict(d, source)
    raise PathError(f"{source}: unknown path type {kind!r} (expected 'nurbs' or 'segments')")


def load_path(file, **gcode_options) -> Path:
    """Read a path file: .json (nurbs | segments) or .ngc (G-code, corners blended per G61/G64)."""
    file = FsPath(file)
    if file.suffix.lower() in (".ngc", ".nc", ".gcode"):
        from planners.gcode import load_gcode_path
        return load_gcode_path(file, **gcode_options)
    try:
        text = file.read_text()
    except OSError as e:
        raise PathError(f"{file}: cannot read path file: {e.strerror}") from None
    try:
        d = json.loads(text)
    except json.JSONDecodeError as e:
        raise PathError(f"{file}: line {e.lineno}: invalid JSON: {e.msg}") from None
    return path_from_dict(d, str(file))


def standard_paths() -> list[str]:
    return sorted({p.stem if p.suffix == ".json" else p.name for p in PATH_DIR.glob("*")
                   if p.suffix in (".json", ".ngc")})


def resolve_path(name_or_file, **gcode_options) -> Path:
    """A path object from a file name or a standard name (``benchmarks/paths/<name>.(json|ngc)``)."""
    if isinstance(name_or_file, Path):
        return name_or_file
    f = FsPath(name_or_file)
    if f.is_file():
        return load_path(f, **gcode_options)
    for cand in (PATH_DIR / f.name, PATH_DIR / f"{f.name}.json", PATH_DIR / f"{f.name}.ngc"):
        if cand.is_file():
            return load_path(cand, **gcode_options)
    raise PathError(f"{name_or_file}: no such path file, and not a standard path "
                    f"(standard: {', '.join(standard_paths()) or 'none'})")
