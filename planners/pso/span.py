"""A piece's feed spline as one piece of `Profile.from_pieces`: s(t) by inverting the exact time
map t(x) = ∫ dx/ṡ, ṡ, s̈, s⃛ from the spline (feed.py), so the samples at T carry no
interpolation error of their own.

The time map is integrated by Gauss–Legendre on each station interval.  At both ends ṡ → 0
as x^{2/3}; there x = h·ν³ from the rest end makes the integrand 3hν²/ṡ smooth, so the same rule
holds and Newton's method in ν converges where it would stall in x."""
from __future__ import annotations

import numpy as np

GAUSS_X, GAUSS_W = np.polynomial.legendre.leggauss(8)
NEWTON_STEPS = 8


class FeedSpan:
    """The spline with coefficients ``c`` on ``feed``'s piece (rest-to-rest piece ``group``),
    stretched uniformly in time by ``lam``."""

    def __init__(self, feed, c, group: int):
        self.feed, self.group, self.lam = feed, group, 1.0
        self.s0, self.tu = feed.piece.s0, feed.piece.tu
        spl = feed.spline(np.asarray(c, float))
        self._w, self._w1, self._w2 = spl, spl.derivative(1), spl.derivative(2)
        x = feed.x
        self.x, self.h0, self.h1 = x, x[1] - x[0], x[-1] - x[-2]
        n = len(x)
        dt = np.empty(n - 1)
        dt[1:-1] = self._integral(x[1:-2], x[2:-1])
        dt[0] = self._end_integral(np.ones(1), start=True)[0]
        dt[-1] = self._end_integral(np.ones(1), start=False)[0]
        self.tx = np.concatenate([[0.0], np.cumsum(dt)])

    @property
    def duration(self):
        return float(self.tx[-1]) * self.tu * self.lam

    def _sd(self, x):
        return np.cbrt(np.maximum(self._w(x), 0.0)) ** 2

    def _integral(self, a, b):
        """∫_a^b dx/ṡ per pair (interior: ṡ > 0 on [a, b])."""
        mid, half = (a + b) / 2, (b - a) / 2
        pts = mid[:, None] + half[:, None] * GAUSS_X[None, :]
        return half * (GAUSS_W[None, :] / self._sd(pts)).sum(axis=1)

    def _end_integral(self, nu, start: bool):
        """∫ dx/ṡ from the rest end to x = h·ν³ from it, per ν ∈ [0, 1]."""
        h, end = (self.h0, self.x[0]) if start else (self.h1, self.x[-1])
        pts = nu[:, None] * (GAUSS_X[None, :] + 1) / 2                # ν′ ∈ [0, ν]
        xx = end + h * pts ** 3 if start else end - h * pts ** 3
        f = 3 * h * pts ** 2 / np.maximum(self._sd(xx), 1e-300)
        return nu / 2 * (f * GAUSS_W[None, :]).sum(axis=1)

    def at(self, tt):
        """(s − s0, ṡ, s̈, s⃛) at local times tt."""
        tu = self.tu * self.lam
        u = np.clip(np.asarray(tt, float) / tu, 0.0, self.tx[-1])
        n = len(self.x)
        k = np.clip(np.searchsorted(self.tx, u, side="right") - 1, 0, n - 2)
        x = np.empty_like(u)
        first, last = k == 0, k == n - 2
        mid = ~(first | last)
        # interior: Newton on t_k + ∫_{x_k}^x dx/ṡ = u from the linear guess, kept in the interval
        if mid.any():
            km, um = k[mid], u[mid]
            xa, xb = self.x[km], self.x[km + 1]
            xm = xa + (xb - xa) * (um - self.tx[km]) / (self.tx[km + 1] - self.tx[km])
            for _ in range(NEWTON_STEPS):
                xm = np.clip(xm - (self.tx[km] + self._integral(xa, xm) - um) * self._sd(xm), xa, xb)
            x[mid] = xm
        for sel, start in ((first, True), (last, False)):
            if sel.any():
                # time from the rest end: u (start) or t_end − u (stop), solved for ν in [0, 1]
                target = u[sel] if start else self.tx[-1] - u[sel]
                span = self.tx[1] if start else self.tx[-1] - self.tx[-2]
                nu = np.cbrt(np.clip(target / span, 0.0, 1.0))       # t ∝ ν near rest
                h, end = (self.h0, self.x[0]) if start else (self.h1, self.x[-1])
                for _ in range(NEWTON_STEPS):
                    xx = end + h * nu ** 3 if start else end - h * nu ** 3
                    dtdnu = 3 * h * nu ** 2 / np.maximum(self._sd(xx), 1e-300)
                    step = (self._end_integral(nu, start) - target) / np.where(dtdnu > 0, dtdnu, np.inf)
                    nu = np.clip(nu - step, 0.0, 1.0)
                x[sel] = end + h * nu ** 3 if start else end - h * nu ** 3
        w = np.maximum(self._w(x), 0.0)
        w1, w2 = self._w1(x), self._w2(x)
        cb = np.cbrt(w)
        sd, sdd, sddd = cb * cb, (2.0 / 3.0) * cb * w1, (2.0 / 9.0) * w1 * w1 + (2.0 / 3.0) * w * w2
        return x, sd / tu, sdd / tu ** 2, sddd / tu ** 3

    def a_at_stations(self):
        """ṡ² (scaled) at the piece's stations: the reference the polish is linearised around."""
        return self._sd(self.x) ** 2
