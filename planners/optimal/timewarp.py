"""Time stretches of a planned profile, uniform and local: the last resort of a planner whose
samples at T still read a limit above 1 in a few windows after its own repairs (topp3's rounds).

A uniform stretch t → λt slows a whole rest-to-rest piece by its worst read: on a G64 program
of 600 joins in one piece, a jerk read of 1.04 at one join cost 1.7–2.2 % of the piece's time
(docs/TUNING.md).  Here the time is stretched only around the reads:

    dt'/dt = λ(t) = 1 + Σ_i δ_i·sech((t − c_i)/τ)

(t the piece's own time, t' the stretched one).  Why sech: |λ_t| ≤ (λ − 1)/τ and
|λ_tt| ≤ (λ − 1)/τ² everywhere, down to the bumps' tails, so the terms a varying λ adds,
3q̈·λ_t + q̇·λ_tt to the jerk and q̇·λ_t to the acceleration (to first order in δ), stay within
a fixed fraction of the relief 3(λ − 1)·q⃛ and 2(λ − 1)·q̈ it buys where a joint is at its limit
(bump_width: at most half of it; a bump of compact support has an unbounded λ_t/(λ − 1) at its
feet).  The terms grow with the joints' speed q̇, so a bump where they are slow (a G1 join's
corner) may be narrower than one sized for V, and costs less (local_widths).  Each bump adds
δ_i·π·τ_i, a whole number of periods T: the samples after it keep their phase against the
profile and read as they did, so a round of bumps moves only the reads under them (a uniform
stretch moves every later sample, and new windows read above: 24 rounds of it took
cam_dense_keops's need from 1.014 to 1.022).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import maximum_filter1d

# a bump's influence is cut at this many τ: sech(30) ≈ 2e-13, and the offset's tail
# 2τδ·e^{-30} ≈ 1e-13·τδ s of time moves no sample by more than ~1e-13 mm
REACH = 30.0
NEWTON_ITERATIONS = 60
# a bump's width is set by the joints' speed within this many of the widest bumps (bump_width at
# V) of its centre, times a margin: its terms fall off as sech, and the stretch only slows the
# joints, but a bump's rounds move the samples, so the speed it was sized on is not exact
WIDTH_REACH = 2.0
WIDTH_SPEED_MARGIN = 1.25


class Uniform:
    """A piece of `Profile.from_pieces` run λ times slower: t → λt scales ṡ by 1/λ, s̈ by 1/λ²,
    s⃛ by 1/λ³."""

    def __init__(self, span, lam: float = 1.0):
        self.span, self.lam, self.s0 = span, float(lam), span.s0

    @property
    def duration(self) -> float:
        return self.span.duration * self.lam

    def at(self, tp):
        s, sd, sdd, sddd = self.span.at(np.asarray(tp, float) / self.lam)
        return s, sd / self.lam, sdd / self.lam ** 2, sddd / self.lam ** 3


def bump_width(limits, speed=None):
    """τ (s) of the bumps for joint limits (v, a, j): the smallest with the first-order terms of
    a varying λ at most half of the relief it buys, t_u/τ + v/(3Jτ²) ≤ 1/2 for the jerk
    (t_u = A/J) and v/(2Aτ) ≤ 1/2 for the acceleration, where a joint is at speed v, A and J at
    once (the worst case; elsewhere there is more room): v = V, or ``speed`` (a number or an
    array, capped at V), the fastest a joint moves under the bump."""
    V, A, J = limits.v, limits.a, limits.j
    v = V if speed is None else np.minimum(speed, V)
    tu = A / J
    tau = np.maximum(tu + np.sqrt(tu * tu + 2 * v / (3 * J)), v / A)
    return float(tau) if np.ndim(tau) == 0 else tau


def local_widths(Q, T: float, limits, samples):
    """τ (s) of a bump at each of ``samples`` (indices into joint samples Q (N, 3) at T): by the
    fastest joint speed within WIDTH_REACH widest bumps of it, × WIDTH_SPEED_MARGIN.  Where the
    joints are slow (a G1 join's read at a corner, a near-cusp) a bump may be narrower than one
    sized for V, and costs less: its height adds δ·π·τ."""
    widest = bump_width(limits)
    speed = np.zeros(len(Q))
    if len(Q) > 1:
        speed[1:] = np.abs(np.diff(Q, axis=0)).max(axis=1) / T
        speed[0] = speed[1]
    reach = int(math.ceil(WIDTH_REACH * widest / T))
    around = maximum_filter1d(speed, size=2 * reach + 1, mode="nearest")
    return np.minimum(bump_width(limits, WIDTH_SPEED_MARGIN * around[samples]), widest)


class Local:
    """A piece of `Profile.from_pieces` (``duration``, ``s0``, ``at``) run on the stretched time
    t' of the module docstring: ``at(t')`` evaluates the piece at t(t') and turns its ṡ, s̈, s⃛
    by the chain rule."""

    def __init__(self, span, tau: float):
        self.span, self.tau, self.s0 = span, float(tau), span.s0
        self.c, self.d, self.w = np.zeros(0), np.zeros(0), np.zeros(0)

    def add(self, c, delta, width=None) -> None:
        """Bumps of heights ``delta`` centred at the piece's own times ``c`` (s), each ``width``
        wide (τ, s; the span's τ where None)."""
        c = np.atleast_1d(np.asarray(c, float))
        w = np.broadcast_to(self.tau if width is None else np.asarray(width, float), c.shape)
        c = np.concatenate([self.c, c])
        d = np.concatenate([self.d, np.atleast_1d(np.asarray(delta, float))])
        w = np.concatenate([self.w, w])
        order = np.argsort(c, kind="stable")
        self.c, self.d, self.w = c[order], d[order], w[order]

    @property
    def added_s(self) -> float:
        """The time the bumps add (s)."""
        return float(np.sum(self.d * self.w)) * math.pi

    @property
    def duration(self) -> float:
        return self.span.duration + self.added_s

    def _terms(self, t):
        """(t' − t, λ, λ_t, λ_tt) at the piece's own times t: each bump over its REACH only, its
        whole πτδ added to every later time (a running sum)."""
        n = len(t)
        order = np.argsort(t, kind="stable")
        ts = t[order]
        off, lam, lt, ltt = np.zeros(n), np.ones(n), np.zeros(n), np.zeros(n)
        lo = np.searchsorted(ts, self.c - REACH * self.w, side="left")
        hi = np.searchsorted(ts, self.c + REACH * self.w, side="right")
        past = np.zeros(n + 1)
        np.add.at(past, hi, math.pi * self.w * self.d)
        off += np.cumsum(past)[:-1]
        for c, d, tau, a, b in zip(self.c, self.d, self.w, lo, hi):
            if b <= a:
                continue
            x = (ts[a:b] - c) / tau
            sech, th = 1.0 / np.cosh(x), np.tanh(x)
            off[a:b] += tau * d * (2 * np.arctan(np.tanh(x / 2)) + math.pi / 2)
            lam[a:b] += d * sech
            lt[a:b] -= d * sech * th / tau
            ltt[a:b] += d * sech * (th * th - sech * sech) / tau ** 2
        out = [np.empty(n) for _ in range(4)]
        for o, v in zip(out, (off, lam, lt, ltt)):
            o[order] = v
        return out

    def original(self, tp):
        """The piece's own times t of stretched times t' (Newton: t + offset(t) is increasing
        with slope λ ≥ 1)."""
        tp = np.asarray(tp, float)
        if len(self.c) == 0:
            return tp
        t = tp.copy()
        for _ in range(NEWTON_ITERATIONS):
            off, lam, _, _ = self._terms(t)
            step = (t + off - tp) / lam
            t -= step
            if np.max(np.abs(step), initial=0.0) <= 4 * np.spacing(max(1.0, self.duration)):
                return t
        raise ArithmeticError(f"the stretched time's inverse did not converge in {NEWTON_ITERATIONS} steps")

    def at(self, tp):
        t = self.original(tp)
        s, sd, sdd, sddd = self.span.at(t)
        if len(self.c) == 0:
            return s, sd, sdd, sddd
        _, lam, lt, ltt = self._terms(t)
        p1 = 1.0 / lam                                  # dt/dt' and its derivatives in t'
        p2 = -lt / lam ** 3
        p3 = (3 * lt * lt - lam * ltt) / lam ** 5
        return s, sd * p1, sdd * p1 ** 2 + sd * p2, sddd * p1 ** 3 + 3 * sdd * p1 * p2 + sd * p3


def bumps_for(span: Local, t_local, need, T: float, extra: float, widths=None):
    """(centres, heights, widths) of one round's bumps on ``span``: its reads above (stretched
    times ``t_local`` in the piece, stretch needs ``need`` > 1; ``widths``: a bump's τ at each,
    the span's where None) grouped into cells of the span's τ, one bump per cell at its worst
    read, as wide as the widest read of its cell wants, of height need·(1 + extra) − 1 rounded
    up so that it adds a whole number of periods T."""
    t0 = span.original(np.asarray(t_local, float))
    widths = np.full(len(t0), span.tau) if widths is None else np.asarray(widths, float)
    cell = np.floor(t0 / span.tau).astype(np.int64)
    centres, heights, taus = [], [], []
    for k in np.unique(cell):
        m = cell == k
        i = int(np.argmax(np.where(m, need, -np.inf)))
        tau = float(widths[m].max())
        periods = math.ceil((need[i] * (1 + extra) - 1) * math.pi * tau / T)
        centres.append(t0[i])
        heights.append(max(periods, 1) * T / (math.pi * tau))
        taus.append(tau)
    return np.array(centres), np.array(heights), np.array(taus)
