"""A cooperative particle swarm over one piece's feed spline (CPSO-S_K: van den Bergh &
Engelbrecht, IEEE Trans. Evol. Comput. 8(3), 2004): the free coefficients are cut into blocks
of BLOCK, and each block of a particle is judged in the context of the swarm's best
(every other coefficient at its best value).

Why blocks: a coefficient moves the feed over 4 knot spans only, so the time and the limits a
block changes are those of the stations under its support; judging blocks, not whole
particles, lets an improvement in one place count although others got worse in the same
particle, and one swarm over hundreds of coefficients does not converge otherwise.  Blocks of
one colour (every other block) share no station, so all of them are judged in one pass over
the piece; the two colours take turns.  The cut moves by one coefficient each iteration, so
neighbouring coefficients are also improved together.

A particle is the logarithm of the coefficients (the feed is positive, and steps are
relative).  A block's objective on its stations: the time there if every station is within the
limits, else a constant above any time plus the worst need (feasibility first: Deb, Comput.
Methods Appl. Mech. Eng. 186, 2000), so the context stays feasible.  After each iteration the
context is pushed to the limits (feed.FeedSpline.push), which the particles then search around."""
from __future__ import annotations

import numpy as np

W, C1, C2 = 0.7298, 1.49618, 1.49618        # Clerc–Kennedy constriction coefficients
BLOCK = 4                                   # ≥ 4: same-colour supports then leave a knot span between them
VMAX = 0.2                                  # largest step of a log-coefficient per iteration
INFEASIBLE = 1e30


class BlockSwarm:
    """The swarm of one piece, around the feasible coefficients ``c`` (feed.FeedSpline);
    ``rng`` draws every random number, in a fixed order."""

    def __init__(self, feed, c, rng, particles: int, spread: float, push: int = 1):
        self.feed, self.rng, self.P, self.push = feed, rng, particles, push
        self.c = np.array(c, float)
        self.free = np.arange(1, feed.K - 1)
        base = np.log(self.c[self.free])
        self.X = base[None, :] + spread * rng.standard_normal((particles, len(self.free)))
        self.X[0] = base
        self.V = 0.1 * VMAX * rng.standard_normal(self.X.shape)
        self.Pb = self.X.copy()
        self.iteration = 0

    def _blocks(self, colour: int):
        """(blocks (nb, BLOCK) of positions in ``free``, −1 = padding) of one colour under this
        iteration's cut."""
        n, off = len(self.free), self.iteration % BLOCK
        cuts = ([np.arange(0, off)] if off else []) + [np.arange(i, min(i + BLOCK, n)) for i in range(off, n, BLOCK)]
        mine = cuts[colour::2]
        idx = np.full((len(mine), BLOCK), -1)
        for b, ks in enumerate(mine):
            idx[b, :len(ks)] = ks
        return idx

    def _judge(self, idx, Xs):
        """Objective (nb, columns) of each block of each of the position sets Xs (list of (P, n)),
        and of the context as the last column."""
        feed, free = self.feed, self.free
        valid = idx >= 0
        cols = sum(len(X) for X in Xs)
        C = np.repeat(self.c[:, None], cols + 1, axis=1)
        at = idx[valid]
        C[free[at], :cols] = np.exp(np.vstack(Xs)[:, at]).T
        dt, need = feed.reads(C)
        lo, hi = feed.sup_lo[free[idx[:, 0]]], feed.sup_hi[free[idx.max(axis=1)]]    # padding is last
        cum = np.vstack([np.zeros((1, cols + 1)), np.cumsum(dt, axis=0)])
        time = cum[hi] - cum[lo]
        # even rows: the max over [lo, hi] (a zero row past the end keeps hi + 1 a valid index)
        need = np.vstack([need, np.zeros((1, cols + 1))])
        worst = np.maximum.reduceat(need, np.ravel(np.column_stack([lo, hi + 1])), axis=0)[::2]
        return np.where(worst <= 1.0, time, INFEASIBLE + worst)

    def step(self):
        """One iteration: per colour, each block of each particle and of its best is judged; the
        better replaces the best's block, the best block of all enters the context."""
        P = self.P
        for colour in range(2):
            idx = self._blocks(colour)
            if not len(idx):
                continue
            f = self._judge(idx, [self.X, self.Pb])
            fX, fP, f_ctx = f[:, :P], f[:, P:2 * P], f[:, 2 * P]
            valid = idx >= 0
            for b in range(len(idx)):
                at = idx[b][valid[b]]
                better = fX[b] < fP[b]
                self.Pb[np.ix_(better, at)] = self.X[np.ix_(better, at)]
                k = int(np.argmin(fX[b]))
                if fX[b, k] < f_ctx[b]:
                    self.c[self.free[at]] = np.exp(self.X[k, at])
        g = np.log(self.c[self.free])[None, :]
        r1, r2 = self.rng.random(self.X.shape), self.rng.random(self.X.shape)
        self.V = np.clip(W * self.V + C1 * r1 * (self.Pb - self.X) + C2 * r2 * (g - self.X), -VMAX, VMAX)
        self.X = self.X + self.V
        if self.push:
            self.c = self.feed.push(self.c, self.push)
        self.iteration += 1
