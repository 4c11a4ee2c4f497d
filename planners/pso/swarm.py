"""One particle swarm per problem, all advanced together so the best total is known at every
iteration; per rest-to-rest piece the option (whole or cut) with the smaller best total counts."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

W, C1, C2 = 0.7298, 1.49618, 1.49618        # Clerc–Kennedy constriction coefficients


@dataclass
class Particles:
    X: np.ndarray          # positions (P, n)
    V: np.ndarray          # velocities
    P: np.ndarray          # each particle's best position
    fP: np.ndarray         # and its objective
    g: np.ndarray          # the swarm's best position
    fg: float              # and its objective
    vmax: np.ndarray       # the velocity bound per coefficient


class Progress:
    """The best total over time (``history``) and when it first reached ``target`` (seconds
    since t0), for the benchmark."""

    def __init__(self, t0, target):
        self.t0, self.target = t0, target
        self.history, self.time_to_target = [], None

    def reached(self, total):
        if self.target and self.time_to_target is None and total <= self.target:
            self.time_to_target = time.perf_counter() - self.t0

    def record(self, total):
        self.history.append((time.perf_counter() - self.t0, total))
        if self.target and self.time_to_target is None and total <= self.target:
            self.time_to_target = self.history[-1][0]


class Swarm:
    """Particles around each problem's start (its fitted seed made feasible; None where there is
    none), drawn from ``rng`` in problem order."""

    def __init__(self, probs, X0, tags, rng, particles, spread, margin):
        self.probs, self.tags, self.rng, self.margin = probs, tags, rng, margin
        self.states = [self._spawn(pr, x0, particles, spread) for pr, x0 in zip(probs, X0)]

    def _spawn(self, pr, x0, particles, spread):
        x0 = pr.start(x0, self.margin)             # the seed, made to meet every limit
        if x0 is None:
            return None
        n = len(x0)
        X = x0[None, :] * (1 + spread * self.rng.standard_normal((particles, n)))
        X[0] = x0
        X = np.maximum(X, 0.0)
        span = np.maximum(x0, 1e-3 * x0.max())
        Vel = 0.05 * span[None, :] * self.rng.standard_normal((particles, n))
        f = pr.objective(X, self.margin)
        best = int(np.argmin(f))
        return Particles(X, Vel, X.copy(), f.copy(), X[best].copy(), float(f[best]), 0.2 * span)

    def best_options(self):
        """{piece: (option, its time)}: per piece the option with the smaller best total."""
        tot = {}
        for (g, opt), sw in zip(self.tags, self.states):
            tot[(g, opt)] = tot.get((g, opt), 0.0) + (sw.fg if sw is not None else math.inf)
        out = {}
        for (g, opt), v in tot.items():
            if g not in out or v < out[g][1]:
                out[g] = (opt, v)
        return out

    def total(self):
        return sum(v for _, v in self.best_options().values())

    def chosen(self):
        """[(index, problem, particles, piece)] of the options best_options() picks."""
        pick = self.best_options()
        return [(k, pr, sw, g) for k, (pr, sw, (g, opt)) in enumerate(zip(self.probs, self.states, self.tags))
                if sw is not None and pick[g][0] == opt]

    def run(self, iterations, progress, time_budget_s=None):
        """Advance every swarm ``iterations`` times (or until ``time_budget_s`` since progress.t0
        has passed): what stopped it."""
        live = [(pr, sw) for pr, sw in zip(self.probs, self.states) if sw is not None]
        for _ in range(iterations):
            if time_budget_s is not None and time.perf_counter() - progress.t0 > time_budget_s:
                return "time budget"
            for pr, sw in live:
                self._step(pr, sw)
            progress.record(self.total())
        return "iterations"

    def _step(self, pr, sw):
        X, V = sw.X, sw.V
        r1, r2 = self.rng.random(X.shape), self.rng.random(X.shape)
        V = W * V + C1 * r1 * (sw.P - X) + C2 * r2 * (sw.g[None, :] - X)
        V = np.clip(V, -sw.vmax, sw.vmax)
        X = np.maximum(X + V, 0.0)
        f = pr.objective(X, self.margin)
        imp = f < sw.fP
        sw.P[imp], sw.fP[imp] = X[imp], f[imp]
        b = int(np.argmin(sw.fP))
        if sw.fP[b] < sw.fg:
            sw.g, sw.fg = sw.P[b].copy(), float(sw.fP[b])
        sw.X, sw.V = X, V
