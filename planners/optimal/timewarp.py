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
feet).  Each bump adds δ_i·π·τ, a whole number of periods T: the samples after it keep their
phase against the profile and read as they did, so a round of bumps moves only the reads under
them (a uniform stretch moves every later sample, and new windows read above: 24 rounds of it
took cam_dense_keops's need from 1.014 to 1.022).
"""
from __future__ import annotations

import math

import numpy as np

# a bump's influence is cut at this many τ: sech(30) ≈ 2e-13, and the offset's tail
# 2τδ·e^{-30} ≈ 1e-13·τδ s of time moves no sample by more than ~1e-13 mm
REACH = 30.0
NEWTON_ITERATIONS = 60


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


def bump_width(limits) -> float:
    """τ (s) of the bumps for joint limits (v, a, j): the smallest with the first-order terms of
    a varying λ at most half of the relief it buys, t_u/τ + V/(3Jτ²) ≤ 1/2 for the jerk
    (t_u = A/J) and V/(2Aτ) ≤ 1/2 for the acceleration, where a joint is at V, A and J at once
    (the worst case; elsewhere there is more room)."""
    V, A, J = limits.v, limits.a, limits.j
    tu = A / J
    return max(tu + math.sqrt(tu * tu + 2 * V / (3 * J)), V / A)


class Local:
    """A piece of `Profile.from_pieces` (``duration``, ``s0``, ``at``) run on the stretched time
    t' of the module docstring: ``at(t')`` evaluates the piece at t(t') and turns its ṡ, s̈, s⃛
    by the chain rule."""

    def __init__(self, span, tau: float):
        self.span, self.tau, self.s0 = span, float(tau), span.s0
        self.c, self.d = np.zeros(0), np.zeros(0)

    def add(self, c, delta) -> None:
        """Bumps of heights ``delta`` centred at the piece's own times ``c`` (s)."""
        c = np.concatenate([self.c, np.atleast_1d(np.asarray(c, float))])
        d = np.concatenate([self.d, np.atleast_1d(np.asarray(delta, float))])
        order = np.argsort(c, kind="stable")
        self.c, self.d = c[order], d[order]

    @property
    def added_s(self) -> float:
        """The time the bumps add (s)."""
        return float(np.sum(self.d)) * math.pi * self.tau

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
        lo = np.searchsorted(ts, self.c - REACH * self.tau, side="left")
        hi = np.searchsorted(ts, self.c + REACH * self.tau, side="right")
        past = np.zeros(n + 1)
        np.add.at(past, hi, math.pi * self.tau * self.d)
        off += np.cumsum(past)[:-1]
        for c, d, a, b in zip(self.c, self.d, lo, hi):
            if b <= a:
                continue
            x = (ts[a:b] - c) / self.tau
            sech, th = 1.0 / np.cosh(x), np.tanh(x)
            off[a:b] += self.tau * d * (2 * np.arctan(np.tanh(x / 2)) + math.pi / 2)
            lam[a:b] += d * sech
            lt[a:b] -= d * sech * th / self.tau
            ltt[a:b] += d * sech * (th * th - sech * sech) / self.tau ** 2
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


def bumps_for(span: Local, t_local, need, T: float, extra: float):
    """(centres, heights) of one round's bumps on ``span``: its reads above (stretched times
    ``t_local`` in the piece, stretch needs ``need`` > 1) grouped into cells of τ, one bump per
    cell at its worst read, of height need·(1 + extra) − 1 rounded up so that it adds a whole
    number of periods T."""
    t0 = span.original(np.asarray(t_local, float))
    cell = np.floor(t0 / span.tau).astype(np.int64)
    centres, heights = [], []
    for k in np.unique(cell):
        m = cell == k
        i = int(np.argmax(np.where(m, need, -np.inf)))
        periods = math.ceil((need[i] * (1 + extra) - 1) * math.pi * span.tau / T)
        centres.append(t0[i])
        heights.append(max(periods, 1) * T / (math.pi * span.tau))
    return np.array(centres), np.array(heights)
