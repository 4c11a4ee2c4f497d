"""`pso` — feed profile optimised by particle swarm (Erwinski, Szczepanski, Tarczewski,
IOP Conf. Ser. MSE 1140, 2021; extended to a delta's joints as planned in Erwinski et al.,
NU·ROBOTI·FTS 2022, shared/SOURCES.md §A).

Shared constraint set with `toppra` and `optimal`: joint v, a, j limits, F_max and the
chord-error feed cap (plus, at a G1 join, the jerk its jump of q″ reads as at T added to the
continuous jerk, bounded as in `optimal`).

Parametrisation.  The path is split at exact-stop corners; on each piece the feed is a
quadratic B-spline ṡ(τ) = Σ cₖBₖ(τ) over normalised time τ ∈ [0, 1] (so s⃛ is piecewise constant,
the class of the s-curve), with c₀ = c₁ = c_{K−2} = c_{K−1} = 0 so the piece starts and ends at
rest with s̈ = 0, and s(τ) = L·∫ṡ/∫₀¹ṡ (exact antiderivative), so every particle reaches the end
of the piece.  Knots: the seed's jerk switch times (then the seed is represented exactly and
the swarm starts from it) plus, with ``extra_knots``, knots at quantiles of the seed's jerk
activity (dense at the FLF minima and G1 joins); ``exact_knots=False`` uses the quantile
knots only.  (A B-spline over arc length, as in the 2021 paper for a Cartesian machine,
cannot leave rest with finite jerk — near rest ṡ ∝ s^{2/3} — hence normalised time.)

A piece with G1 joins (at most MAX_JOINS_CUT) is also searched cut at them (`SubPiece`):
each join passed at a fixed feed with s̈ = s⃛ = 0, each sub-piece a feed spline of its own with
those ends, in its own normalised time.  The feed must dip at a join (bird: to 57–207 mm/s
from ~850 mm/s between them); a whole-piece spline spends its few control points on that dip
and one time stretch couples all of it, while the cut search shapes each dip-to-dip stretch on
its own.  Per piece the faster of the two is kept (measured on bird and bird_kossel:
docs/TUNING.md).

Objective.  Stretching time by λ divides joint velocity by λ, acceleration by λ², jerk by
λ³ and the feed by λ.  So each whole piece's shape is scaled to the smallest λ at which every
limit holds (the exact penalty for violations: time grows with the violation), and the
objective is the execution time λ.  Every evaluated particle is thus feasible on its
samples; the swarm only searches shapes.  A sub-piece's ends are fixed, so its objective is
its duration × max(1, worst ratio)^PENALTY_POWER instead.  The whole swarm is evaluated at
once (particles × samples arrays).  After the search the best profile is sampled at T and
checked with the independent metrics; a discretisation excess is removed by a further small
stretch of the whole piece (with its join feeds).  The seed is returned where it is faster and
feasible; where it is faster but breaks a limit at T, its fit is stretched at T the same way
and each rest-to-rest piece takes the shorter of that and the swarm's.

Polish: after the swarm, a few steps of sequential linear programming on a finer spline
(polish.py).  ``polish_steps=0`` returns the swarm alone.  The swarm runs 20 iterations by
default (why: docs/TUNING.md).

Seeded: the swarm starts around the `scurve_joint` profile (its feed fitted by least
squares), ``seed`` drives all random numbers and the iteration count ends the search, so the
same inputs give the same profile on any machine.  An optional wall-clock ``time_budget_s``
(off by default: it would make the result depend on the machine's speed) is reported in
``info['stopped_by']`` when it ends the search.

Modules: tuning (the constants), basis (the feed's B-splines), problem (a whole piece and a
sub-piece behind one protocol), join (G1 joins), seed (the start from the seed profile), swarm,
polish, result (the best profile at T, against the seed).
"""
from __future__ import annotations

import math
import time

import numpy as np

from ..constraints import (PathTable, PlanningError, check_limits, check_path, join_jumps, rest_pieces,
                           table_feed_cap)
from ..profile import Profile
from .polish import polish_best
from .result import stretch_at_T, swarm_or_seed, t_check_stretch
from .seed import Setting, start
from .swarm import Progress, Swarm
from . import tuning
from .tuning import JOIN_FEED_FRACTION, POLISH_ITERATIONS

__all__ = ["plan", "JOIN_FEED_FRACTION"]


def plan(path, machine, limits=None, *, seed: int = 0, particles: int = 40, iterations: int = 20,
         control_points: int = 60, samples: int = 400, margin: float = 0.005,
         time_budget_s: float | None = None, seed_profile=None, target_time_s: float | None = None,
         exact_knots: bool = True, extra_knots: float = 0.5, spread: float = 0.05,
         polish_steps: int | None = None) -> Profile:
    """PSO-optimised feed.  ``control_points``: total over the pieces (≥ 8 each, shared in
    proportion to the seed's time on each); ``polish_steps``: SLP steps per piece after the
    swarm (POLISH_ITERATIONS if None, 0: none); ``target_time_s``: record when the best total
    (swarm, then polished) first reaches it (``info['time_to_target_s']``), for the benchmark."""
    from ..scurve import plan_joint

    t0 = time.perf_counter()
    polish_steps = POLISH_ITERATIONS if polish_steps is None else polish_steps
    limits = machine.limits if limits is None else limits
    check_limits(limits, "pso")
    check_path(path, "pso")
    if particles < 2 or iterations < 0:
        raise PlanningError(f"pso: need ≥ 2 particles and ≥ 0 iterations (got {particles}, {iterations})")
    T = machine.servo_period_s
    rng = np.random.default_rng(seed)
    table = PathTable(path, machine)
    st = Setting(table, limits, T, join_jumps(path, table, machine), table_feed_cap(path, table, limits, T),
                 margin)
    seed_prof = plan_joint(path, machine, limits) if seed_profile is None else seed_profile
    pcs = rest_pieces(path)
    begin = start(st, seed_prof, pcs, control_points, samples, exact_knots, extra_knots)
    swarm = Swarm(begin.probs, begin.X0, begin.tags, rng, particles, spread, margin)
    _all_feasible(swarm, pcs)
    progress = Progress(t0, target_time_s)
    progress.record(swarm.total())
    stopped_by = swarm.run(iterations, progress, time_budget_s)
    swarm_total = progress.history[-1][1]
    # the swarm finds the shape (which option, which basin); a few SLP steps on a finer spline
    # converge it (docs/TUNING.md)
    polished = polish_best(swarm, polish_steps, margin, progress) if polish_steps > 0 else []

    chosen = swarm.chosen()
    pieces = [pr.piece(sw.g, sw.fg, g) for _, pr, sw, g in chosen]
    info = _info(seed, particles, stopped_by, [int(pr.K) for _, pr, _, _ in chosen], swarm, len(pcs),
                 seed_prof, progress, swarm_total, polished, begin.fallback)
    # check at T with the independent metrics; stretch the pieces whose samples at T read
    # above a limit (the swarm saw only its own samples) by just that excess
    prof, r = stretch_at_T(pieces, len(pcs), T, path, machine, limits, info)
    if prof is None:
        raise PlanningError(f"pso: best particle breaks a joint limit at T: {r['joint_peak_ratio']}")
    prof.info["t_check_stretch"] = t_check_stretch(pieces)
    prof.info["returned"] = "swarm best"
    prof = swarm_or_seed(prof, seed_prof, pieces, begin.seed_pieces, len(pcs), T, path, machine, limits,
                         info)
    prof.planning_time_s = time.perf_counter() - t0
    return prof


def _all_feasible(swarm, pcs):
    """A clear error unless every rest-to-rest piece has an option whose swarms all started."""
    bad = [g for g, (_, v) in swarm.best_options().items() if not math.isfinite(v)]
    if bad:
        raise PlanningError(f"pso: no feasible particle on piece(s) {bad} (s = "
                            f"{', '.join(f'{pcs[i][0]:.6g}…{pcs[i][1]:.6g}' for i in bad)} mm)")


def _info(seed, particles, stopped_by, control_points, swarm, n_pieces, seed_prof, progress, swarm_total,
          polished, fallback):
    """The profile's info: the search's settings, its choices and its progress."""
    history, options = progress.history, swarm.best_options()
    return {"seed": seed, "particles": particles, "iterations_run": len(history) - 1,
            "stopped_by": stopped_by, "control_points": control_points,
            "searched_as": [options[g][0] for g in range(n_pieces)],
            "seed_time_s": float(seed_prof.execution_time_s),
            "history": [[round(history[i][0], 4), float(history[i][1])]        # ~50 and the last
                        for i in sorted(set(range(0, len(history), max(1, len(history) // 50)))
                                        | {len(history) - 1})],
            "swarm_time_s": float(swarm_total), "polish": polished,
            **({"fallback": {"reason": f"piece over the size bound of {tuning.BASIS_MAX_ELEMENTS} basis elements: "
                                       "sparse basis at the seed's switch times, no polish",
                             "pieces": fallback}} if fallback else {}),
            "time_to_target_s": progress.time_to_target}
