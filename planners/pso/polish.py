"""Polish (a memetic step, after the swarm).  A swarm finds the basin — which pieces to cut, the
shape of each stretch — but converges slowly in it (docs/TUNING.md).  So its best particle on each
(sub-)piece is re-expressed on a finer spline (`refined`) and improved by sequential linear
programming (`polish`): per step the limit ratio of every joint at every sample is linearised and
an LP in a trust region takes the step.  A step is kept only if the swarm's own objective falls,
so the polish can only improve on the swarm."""
from __future__ import annotations

import math

import numpy as np

from .problem import Problem
from .tuning import POLISH_ACTIVE, POLISH_ITERATIONS, POLISH_ROWS_PER_COEFF


def polish_best(swarm, steps, margin, progress):
    """Polish the swarm's best on every (sub-)piece of the chosen options, in place (a polished
    problem replaces its coarse one where it is faster): [[piece, swarm's, polished objective,
    steps]].  The best total after each (sub-)piece's polish is offered to ``progress``: when
    it first reaches the target is known to the piece, not only after the last one."""
    polished = []
    total = progress.history[-1][1]
    for k, pr, sw, g in swarm.chosen():
        if not pr.polishable:
            continue
        fine, x = pr.refined(sw.g)
        x, f, its = polish(fine, x, margin, steps)
        polished.append([g, round(sw.fg, 6), round(f, 6), its])
        if f < sw.fg:
            swarm.probs[k], sw.g, sw.fg = fine, x, f
        total = swarm.total()
        progress.reached(total)
    progress.record(total)
    return polished


def polish(pr: Problem, x, margin, iterations=None):
    """Sequential linear programming from the swarm's best x on one (sub-)piece: (x, objective,
    steps taken).  Each step linearises the stretch N(x) of every joint's v, a, j and the feed at
    every sample (forward differences: n + 1 particles evaluated at once) and solves an LP in a
    box trust region (the problem's `lp`: a minimax for a whole piece, the duration with an elastic
    slack for a sub-piece).  Only the rows above POLISH_ACTIVE × the worst enter
    the LP, at most POLISH_ROWS_PER_COEFF per coefficient.  A step is kept if it lowers the
    swarm's own objective (so the polish can only improve on the swarm); the box then doubles if
    the LP predicted at least half the gain, and shrinks ×0.4 after a step that did not help.
    Stops when five steps gained less than 1e-5 relative."""
    from scipy.optimize import linprog
    iterations = POLISH_ITERATIONS if iterations is None else iterations
    x = np.asarray(x, float)
    n = len(x)
    f = float(pr.objective(x[None, :], margin)[0])
    if not math.isfinite(f):
        return x, f, 0
    rho, seen = 0.05 * x.max(), [f]
    for _ in range(iterations):
        if len(seen) > 5 and seen[-6] - f < 1e-5 * f or rho < 1e-9 * x.max():
            break
        h = 1e-5 * x.max()
        Xs = np.vstack([x, x + h * np.eye(n)])
        N, extra = pr.needs(Xs, margin, each=True)
        G = (N[1:] - N[0]) / h                                   # (n, rows)
        act = N[0] >= POLISH_ACTIVE * N[0].max()
        if act.sum() > POLISH_ROWS_PER_COEFF * n:                # the LP's cost grows with its rows
            act = N[0] >= np.partition(N[0], -POLISH_ROWS_PER_COEFF * n)[-POLISH_ROWS_PER_COEFF * n]
        box = [(max(-rho, 1e-6 - xi), rho) for xi in x]
        A = np.hstack([G[:, act].T, -np.ones((int(act.sum()), 1))])
        c, b_ub, slack, forecast = pr.lp(N, extra, act, h, rho)
        res = linprog(c, A_ub=A, b_ub=b_ub, bounds=box + [slack], method="highs")
        xn = x + res.x[:n] if res.status == 0 else x
        fn = float(pr.objective(xn[None, :], margin)[0]) if res.status == 0 else math.inf
        if fn < f:
            pred = forecast(res.x)                                   # the LP's own forecast
            good = (f - fn) >= 0.5 * (f - pred)
            x, f, rho = xn, fn, min((2.0 if good else 1.0) * rho, 0.3 * xn.max())
        else:
            rho *= 0.4
        seen.append(f)
    return x, f, len(seen) - 1

