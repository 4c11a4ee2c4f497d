"""Spiral arcs: LinuxCNC's G2/G3 whose radius to the end differs from the radius to the start.

LinuxCNC keeps the programmed centre and moves on an Archimedean spiral (posemath
``pmCircleInit``: ``spiral`` = r_end − r_start; ``pmCirclePoint``: radius r0 + spiral·φ/θ), with
any helical rise linear in φ as for a circle. With k = spiral/θ and m = rise/θ,

    P(φ) = c + (r0 + k·φ)·u(φ) + m·φ·n,   u = cos φ·â + sin φ·b̂,   φ ∈ [0, θ]

and |dP/dφ| = √((r0 + kφ)² + k² + m²), so the arc length s(φ) is ∫₀^φ of that. Here it is
integrated by Gauss–Legendre (8 points) on panels of at most 0.5 rad, and s → φ is Newton on
the same integral from the panel below s. Accuracy: the integrand's singularities lie at
φ = (−r0 ± i·√(k² + m²))/k, at least 1 rad off the real axis (√(k² + m²) ≥ |k|), so on a panel of
half-width ≤ 0.25 rad the rule errs by < 1e-14 relative (Bernstein ellipse ρ ≥ 8, error ~ρ⁻¹⁶);
the inverse stops at |s(φ) − s| ≤ 1e-12 mm per mm of length above 1 mm. The Interpolator FMU
(fmus/Interpolator/spiral.c) runs the same rule on the same panels.

LinuxCNC's tp maps progress to angle with a quadratic fit of s(φ) instead (blendmath.c
``findSpiralArcLengthFit``): the same points, reached at slightly different times; here the
path is parametrised by its true arc length, as every path is.
"""
from __future__ import annotations

import math

import numpy as np

from planners.paths.base import cross3

PANEL_RAD = 0.5
# 8-point Gauss–Legendre nodes on [−1, 1] and weights (numpy.polynomial.legendre.leggauss(8)),
# written out so that the FMU's C code uses the same digits
GL_X = np.array([-0.9602898564975362, -0.7966664774136267, -0.525532409916329, -0.18343464249564978,
                 0.18343464249564978, 0.525532409916329, 0.7966664774136267, 0.9602898564975362])
GL_W = np.array([0.10122853629037706, 0.22238103445337443, 0.3137066458778869, 0.36268378337836166,
                 0.36268378337836166, 0.3137066458778869, 0.22238103445337443, 0.10122853629037706])
NEWTON_TOL = 1e-12          # mm per mm of length (at least 1 mm): |s(φ) − s| of the inverse
NEWTON_MAX = 30


class SpiralMeasure:
    """Arc length s(φ) of one spiral arc and its inverse φ(s) (see the module's doc)."""

    def __init__(self, r0: float, k: float, m: float, theta: float):
        self.r0, self.k, self.c2, self.theta = r0, k, k * k + m * m, theta
        n = max(1, math.ceil(theta / PANEL_RAD))
        self.edges = np.arange(n + 1) * (theta / n)
        self.edges[-1] = theta
        self.S = np.concatenate([[0.0], np.cumsum(self._quad(self.edges[:-1], self.edges[1:]))])
        self.length = float(self.S[-1])

    def speed(self, phi: np.ndarray) -> np.ndarray:
        """|dP/dφ| = ds/dφ."""
        rho = self.r0 + self.k * phi
        return np.sqrt(rho * rho + self.c2)

    def _quad(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """∫ₐᵇ speed dφ, a and b in one panel."""
        mid, half = 0.5 * (a + b), 0.5 * (b - a)
        return half * (self.speed(mid[:, None] + half[:, None] * GL_X) @ GL_W)

    def _panel(self, phi: np.ndarray) -> np.ndarray:
        n = len(self.edges) - 1
        return np.clip((phi * (n / self.theta)).astype(np.int64), 0, n - 1)

    def s_of(self, phi) -> np.ndarray:
        phi = np.asarray(phi, float)
        j = self._panel(phi)
        return self.S[j] + self._quad(self.edges[j], phi)

    def phi_of(self, s) -> np.ndarray:
        """φ(s) for s in [0, length]: Newton on s(φ) − s within the panel holding s."""
        s = np.asarray(s, float)
        n = len(self.edges) - 1
        j = np.clip(np.searchsorted(self.S, s, side="right") - 1, 0, n - 1)
        lo, hi, S0 = self.edges[j], self.edges[j + 1], self.S[j]
        phi = lo + (hi - lo) * (s - S0) / (self.S[j + 1] - S0)      # s(φ) is nearly linear
        tol = NEWTON_TOL * max(1.0, self.length)
        for _ in range(NEWTON_MAX):
            f = S0 + self._quad(lo, phi) - s
            if not len(f) or np.abs(f).max() <= tol:
                break
            phi = np.clip(phi - f / self.speed(phi), lo, hi)
        return phi


def spiral_derivs(phi: np.ndarray, r0: float, k: float, m: float, frame, order: int) -> list[np.ndarray]:
    """P and its arc-length derivatives at sweep angles φ (N,): ``frame`` = (c, â, b̂, n).

    With ρ = r0 + kφ, f = |dP/dφ| = √(ρ² + k² + m²): P_φ = k·u + ρ·v + m·n, P_φφ = 2k·v − ρ·u,
    P_φφφ = −3k·u − ρ·v (v = du/dφ); φ' = 1/f, φ'' = −ρk/f⁴, φ''' = k²(4ρ² − f²)/f⁷; then the
    chain rule: P' = P_φ·φ', P'' = P_φφ·φ'² + P_φ·φ'', P''' = P_φφφ·φ'³ + 3·P_φφ·φ'·φ'' + P_φ·φ'''.
    """
    c, ah, bh, n = frame
    p = phi[:, None]
    cs, sn = np.cos(p), np.sin(p)
    u, v = cs * ah + sn * bh, -sn * ah + cs * bh
    rho = r0 + k * p
    out = [c + rho * u + (m * p) * n]
    if order < 1:
        return out
    f2 = rho * rho + (k * k + m * m)
    f = np.sqrt(f2)
    d1 = k * u + rho * v + m * n
    out.append(d1 / f)
    if order >= 2:
        d2 = 2.0 * k * v - rho * u
        p1, p2 = 1.0 / f, -rho * k / (f2 * f2)
        out.append(d2 * (p1 * p1) + d1 * p2)
        if order >= 3:
            d3 = -3.0 * k * u - rho * v
            p3 = k * k * (4.0 * rho * rho - f2) / (f2 * f2 * f2 * f)
            out.append(d3 * (p1 * p1 * p1) + 3.0 * d2 * (p1 * p2) + d1 * p3)
    return out


def approximating_circle(arc, at_end: bool):
    """(centre, radius) of LinuxCNC's circle for a spiral at its start or end, the corner point P
    (blendmath.c findSpiralApproximation): the centre moved along the unit tangent at P by
    spiral/θ, the radius its distance to P. LinuxCNC sizes a line↔arc blend on it."""
    P = arc.end if at_end else arc.start
    T = arc.tangent_out() if at_end else arc.tangent_in()
    C = arc.center + (arc.spiral / arc.angle) * T
    d = P - C
    return C, math.sqrt(float(d @ d))


def tangent_blend_on_spiral(arc, P, n, bn, R: float, trim0: float, from_end: bool):
    """(trim angle, centre) of the circle of radius R tangent to the spiral ``arc`` and to the
    line through P with in-plane normal n (the centre at P + x·u + R·n), or None. LinuxCNC
    places its blend with the approximating circle and joins the gap it leaves to the spiral
    with a slightly spiral blend arc (spherical_arc.c arcInitFromPoints); here the blend is the
    exact tangent circle of the same radius, found by Newton from LinuxCNC's trim ``trim0``
    (measured from the end when ``from_end``), so the path stays tangent-continuous."""
    phi, sign = trim0, (-1.0 if from_end else 1.0)
    tol = 1e-13 * max(1.0, R)
    for _ in range(NEWTON_MAX):
        sweep = arc.angle - phi if from_end else phi
        Q, T, K = (v[0] for v in arc.at_angle(np.array([sweep]), 2))
        centre = Q + R * cross3(bn, T)          # the circle about bn through Q, tangent there
        g = float((centre - P) @ n) - R
        if abs(g) <= tol:
            return (phi, centre) if 0.0 < phi < arc.angle else None
        dg = float((T + R * cross3(bn, K)) @ n) * arc.ds_dphi(sweep) * sign
        if not dg:
            return None
        phi -= g / dg
    return None
