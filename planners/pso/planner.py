"""`pso` — the feed optimised by particle swarm, as the KEOPS papers plan it: the s-curve FLF
profile as the initial guess, turned into a B-spline feed, adjusted by PSO within the joint
limits (Erwinski, Szczepanski, Tarczewski, IOP Conf. Ser. MSE 1140, 2021, for planar machines;
extended to a delta's joints as planned in Erwinski et al., NU·ROBOTI·FTS 2022, shared/SOURCES.md
§A).  No convex solver touches its profile.  `pso_socp` is the memetic hybrid: the same swarm,
then the TOPP3-SOCP polish.

Constraint set shared with `optimal` and `copp` (planners/optimal/topp3.py's stations, down to
`optimal`'s 1 nm at µm tips, here also a hair either side of every NURBS knot, where q‴ may
jump: swarm_settings): joint v, a, j limits, F_max and the chord-error feed cap, and at a G1 join
the jerk its jump of q″ reads as at T added to the continuous jerk, there and, weighted, at
stations graded toward the join within 1.5 periods' travel (topp3.Settings.join_grading, as
`optimal`: held at the join alone, the swarm's profile read 2 × J at T next to pocket_keops's µm
blends and no stretch brought it within).

Parametrisation (feed.py): per rest-to-rest piece (the path's, also split where the jerk-free
optimum all but stops: _near_stops) w = ṡ^{3/2} as a cubic B-spline over arc length, its knots
placed by the limits (equal steps of the jerk-free optimum's time), so the swarm's dimension
follows the path and its limits, never a seed profile's segments or switch times, and nothing
is chosen per path.  The search runs on these knots, then on knots twice as
dense (REFINEMENTS times): knot insertion keeps the feed, so each level starts where the last
ended, and the coarse levels move the feed broadly where the fine ones would need many steps.

Start: the `scurve_joint` seed's feed fitted by the spline (knots also graded toward each G1
join, where the seed dips), brought within the limits by the least the climb of
feed.start_within finds: stretched as a whole, then raised back toward the fit as far as its
stations allow, in groups of neighbours from the whole piece down to one coefficient.

Search (swarm.py): a cooperative swarm, one small swarm per block of 4 coefficients, judged on
the stations the block moves (van den Bergh & Engelbrecht's CPSO-S_K); the context (every
block's best) stays within the limits at the stations (Deb's feasibility rule); after each
iteration the context is pushed to the limits (feed.push: a notch filled toward its
neighbours, a valley toward its rims, then groups of 16 neighbours down to each coefficient
raised, all by one small even step first, then each by the largest step that keeps their
stations within the limits: a repair operator in the sense of Michalewicz's GENOCOP, toward
the boundary where a time-optimal feed lies).  Where its samples at T read above
a limit, the limit is held lower at the stations there, the context is brought within it again
(feed.start_within) and the swarm goes on (_search).

Polish (`pso_socp` only): the TOPP3-SOCP (topp3.py), linearised on each piece around the larger
of the swarm's and the seed's ṡ² at each station instead of TOPP2-RA's profile (at most 2
solves; a first solve within lin_tol of that reference's time ends them), then checked and
repaired at T like `optimal`'s; where it has no solution, solved again on the engine's own
stations around TOPP2-RA's profile (info["polish_reference"]; the failure in info["polish"]).
The swarm's, the polished and the seed's times are in info (``swarm_time_s``,
``polished_time_s``, ``seed_time_s``).

Returned: the fastest of the swarm's profile, the seed (the swarm's initial guess) and, for
`pso_socp`, the polished profile, each checked at T (joint limits and F_max), so neither is
slower than its seed (info["returned"]).  The seed is another planner's profile: returned, it is
named in info["source"], and the corpus counts the row as a fallback, a failure.  The swarm's
own profile is sampled from the exact time map of its spline (span.py) and brought within the
limits at T by a time warp of it: stretched around its reads above (`optimal`'s last resort,
topp3.stretch_locally) or per piece by its worst read, whichever is faster, for the context of
every repair round; the fastest is the swarm's.

Deterministic: ``seed`` drives every random number (`plan.stochastic`: the corpus runs both
over seeds), the iteration count ends the search (an optional wall-clock ``time_budget_s``
would make the result depend on the machine: off by default, reported in info["stopped_by"]
when it ends the search).
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

from planners.constraints import PlanningError, check_limits, check_path
from planners.optimal import topp3
from planners.profile import Profile
from planners.pso.feed import FeedSpline, jerk_free_a
from planners.pso.span import FeedSpan
from planners.pso.swarm import BlockSwarm
from planners.scurve import plan_joint
from planners.verify import command_metrics, keeps_joints_and_feed, stretch_need

__all__ = ["plan", "plan_socp"]

# stations ≤ this many curvature radii apart for the swarm: its spline, held to the limits at
# the stations, read above them between coarser ones at lobe tips
SWARM_STATION_RADII = 0.1
# ... down to this spacing (`optimal`'s floor, not the engine's 1 µm): a near-cusp's curvature
# peaks µm apart (cusp_trochoid_lcnc: radii down to 0.84 µm) lay in cells up to 0.28 radii
# wide, the swarm's knots could not follow its dip, and a station on a peak's shoulder held the
# feed far below `optimal`'s for tens of µm (cusp_trochoid_lcnc 1.21–1.25 × T_ref; docs/TUNING.md)
SWARM_STATION_MIN_MM = topp3.GRADED_MIN_MM
# the swarm's knots are made twice as dense this many times, ``iterations`` on each
REFINEMENTS = 3
SWARM_REPAIRS = 4          # rounds of tightening where the swarm's samples at T read above a limit
REPAIR_ITERATIONS = 10     # swarm iterations after each
# the swarm's pieces also end at rest where the jerk-free optimum's feed falls below this fraction
# of its piece's fastest (_near_stops): at a minimum of the velocity limit curve, where
# time-optimal profiles switch (Shin & McKay, IEEE TAC 30(6), 1985); `optimal` stopped at
# cusp_trochoid_lcnc's five tips (0.0005–0.0011 of its fastest) is 1.4 % slower (docs/TUNING.md)
NEAR_STOP = 0.01
# ... a stretch of stations below this many times that fraction is one dip: one stop, at its lowest
NEAR_STOP_SPREAD = 4.0
# the swarm's profile at T is stretched, each piece by its samples' worst need, up to this many
# rounds a piece (and STRETCH_ROUNDS_MAX in all): a read next to a stop moves with the samples'
# phase, so the next round may find one at another piece's stop (cusp_trochoid_lcnc's six pieces
# took 4–15 rounds over seeds 0–3, 7 and 8, where 8 in all left 7 and 8 without a profile)
STRETCH_ROUNDS = 8
STRETCH_ROUNDS_MAX = 64
# a repair whose context takes this many times the last one's time stops the repairs: the
# tightened limits made a stretch crawl (a G1 join's read at T the station rows do not follow)
COLLAPSE = 2.0


def plan(path, machine, limits=None, *, seed: int = 0, particles: int = 20, iterations: int = 10,
         margin: float = 0.002, spread: float = 0.05, grid_mm: float = 0.1,
         time_budget_s: float | None = None, seed_profile=None) -> Profile:
    """`pso`: the swarm alone (module docstring): ``particles`` per block swarm, ``iterations`` of
    every swarm, limits held at the stations to 1 − ``margin`` during the search."""
    return _plan("pso", path, machine, limits, seed=seed, particles=particles, iterations=iterations,
                 margin=margin, spread=spread, grid_mm=grid_mm, time_budget_s=time_budget_s,
                 seed_profile=seed_profile, polish=False, polish_linearisations=0)


def plan_socp(path, machine, limits=None, *, seed: int = 0, particles: int = 20, iterations: int = 10,
              margin: float = 0.002, spread: float = 0.05, grid_mm: float = 0.1,
              polish_linearisations: int = 2, time_budget_s: float | None = None, seed_profile=None) -> Profile:
    """`pso_socp`: the swarm, then the TOPP3-SOCP polish (at most ``polish_linearisations`` SOCP
    solves a piece before its repairs) linearised around the swarm's and the seed's feed."""
    return _plan("pso_socp", path, machine, limits, seed=seed, particles=particles, iterations=iterations,
                 margin=margin, spread=spread, grid_mm=grid_mm, time_budget_s=time_budget_s,
                 seed_profile=seed_profile, polish=True, polish_linearisations=polish_linearisations)


# the corpus and the suites run a stochastic planner over seeds (planners.registry.stochastic)
plan.stochastic = True
plan_socp.stochastic = True


def _plan(name, path, machine, limits, *, seed, particles, iterations, margin, spread, grid_mm,
          time_budget_s, seed_profile, polish, polish_linearisations) -> Profile:

    t0 = time.perf_counter()
    limits = machine.limits if limits is None else limits
    check_limits(limits, name)
    check_path(path, name)
    if particles < 2 or iterations < 0:
        raise PlanningError(f"{name}: need ≥ 2 particles and ≥ 0 iterations (got {particles}, {iterations})")
    T = machine.servo_period_s
    rng = np.random.default_rng(seed)
    settings = swarm_settings(name, grid_mm, polish_linearisations)
    pieces, a_ra, stops = swarm_pieces(path, machine, limits, settings)
    seed_prof = plan_joint(path, machine, limits) if seed_profile is None else seed_profile

    feeds, starts = [], []
    for p, a in zip(pieces, a_ra):
        # the papers' start: the s-curve seed's feed as a spline, within the limits (or else
        # stretched as a whole)
        feed = FeedSpline(p, margin, a_ra=a)
        c = feed.fit(_seed_feed(seed_prof, p))
        c = _first_not_none(feed.start_within(c), feed.scaled_within(c))
        feeds.append(feed)
        starts.append(c if feed.within(c) else None)
    no_start = [p.where() for p, c in zip(pieces, starts) if c is None]
    swarm_prof, spans, progress, repairs, feeds = (None, None, _Progress(t0, None, time_budget_s), [], feeds) if no_start else \
        _search(feeds, starts, rng, particles, spread, iterations, time_budget_s, t0, T, path, machine, limits,
                10 * seed_prof.execution_time_s)
    history = progress.history
    info = {"seed": seed, "particles": particles, "iterations_run": len(history) - 1, "near_stops": stops,
            "stopped_by": progress.stopped_by, "control_points": [f.K for f in feeds],
            "start_time_s": None if no_start else progress.history[0][1] * pieces[0].tu,
            "seed_time_s": float(seed_prof.execution_time_s), "swarm_repairs": repairs,
            **({"swarm": f"no start within the limits on {', '.join(no_start)}"} if no_start else {}),
            "history": [[h[0], h[1] * pieces[0].tu] for h in history[:: max(1, len(history) // 50)] + history[-1:]
                        if h[1] is not None]}
    info["swarm_time_s"] = swarm_prof.execution_time_s if swarm_prof is not None else None
    info["swarm_planning_s"] = time.perf_counter() - t0
    candidates = [("swarm", swarm_prof)] if swarm_prof is not None else []
    if polish:
        # linearised around the larger of the swarm's and the seed's ṡ² at each station: the
        # tangent rows hold the limits around any reference, and they allow at most 3 × its ṡ²
        # in one solve, so a reference further below the optimum costs linearisations
        # where that fails (the IPM without a solution, then Clarabel's NUMERICAL_ERROR:
        # butterfly_lcnc and rand_tilted_weights_keops on some seeds), on fresh pieces of the
        # engine's own stations (not the swarm's denser ones) around TOPP2-RA's profile, with
        # the engine's linearisations (TOPP2-RA is far above any jerk-limited feed), as `optimal`
        # starts
        for k, p in enumerate(pieces):
            p.reference = _seed_feed(seed_prof, p) ** 2
            if spans:
                p.reference = np.maximum(p.reference, spans[k].a_at_stations())
        failed = []
        for reference in ("seed and swarm" if spans else "seed", "TOPP2-RA"):
            if reference == "TOPP2-RA":
                settings = topp3.Settings(name, grid_mm, join_grading=True)
                pieces = topp3.pieces_of(path, machine, limits, settings, stops)
            try:
                pol = topp3.solve(path, machine, limits, settings, pieces)
            except PlanningError as e:
                failed.append(f"around {reference}: {e}")
                continue
            info["polish_reference"] = reference
            info["polished_time_s"] = pol.execution_time_s
            candidates.append(("polished", pol))
            break
        if failed:
            info["polish"] = "; ".join(failed)
    candidates.append(("seed", seed_prof))
    ok = []
    for which, prof in candidates:
        r = command_metrics(machine, path.point(prof.s), T, prof.s, limits)
        if keeps_joints_and_feed(r):
            ok.append((prof.execution_time_s, which, prof))
    if not ok:
        raise PlanningError(f"{name}: neither the swarm's" + (", the polished" if polish else "") + " nor the seed's profile is within the limits at T"
                            + "".join(f"; {k}: {info[k]}" for k in ("swarm", "polish") if k in info))
    _, which, best = min(ok, key=lambda x: x[:2])
    if which == "seed":
        # the seed is another planner's profile: the row reports it as that planner's
        # (harness.corpus counts it as the row's failure, a fallback)
        info["source"] = seed_prof.planner
    prof = dataclasses.replace(best, planner=name, info=dict(best.info, **info, returned=which))
    prof.planning_time_s = time.perf_counter() - t0
    return prof


def swarm_settings(name: str = "pso", grid_mm: float = 0.1, linearisations: int = 1) -> topp3.Settings:
    """The engine's settings for the swarm's pieces (and the polish's first solve): stations
    ≤ SWARM_STATION_RADII curvature radii apart down to SWARM_STATION_MIN_MM, a hair either side
    of every NURBS knot, graded toward every G1 join."""
    return topp3.Settings(name, grid_mm, max_linearisations=max(linearisations, 1),
                          station_radii=SWARM_STATION_RADII, station_min_mm=SWARM_STATION_MIN_MM,
                          knot_stations=True, join_grading=True)


def swarm_pieces(path, machine, limits, settings):
    """(the swarm's rest-to-rest pieces, TOPP2-RA's ṡ² on each, the near-stops they also end at):
    the path's pieces, split again at _near_stops where there are any."""
    pieces = topp3.pieces_of(path, machine, limits, settings)
    a_ra = [jerk_free_a(p) for p in pieces]
    stops = _near_stops(pieces, a_ra)
    if stops:
        pieces = topp3.pieces_of(path, machine, limits, settings, stops)
        a_ra = [jerk_free_a(p) for p in pieces]
    return pieces, a_ra, stops


def _search(feeds, starts, rng, particles, spread, iterations, budget, t0, T, path, machine, limits, too_slow):
    """(the swarm's profile or None, its spans, the progress, the repairs' windows): the swarm
    from ``starts``, its iterations, then its repairs at T (below).  A profile slower than
    ``too_slow`` (10 × the seed's time) is no candidate: sampling it would only cost memory."""
    swarms = [BlockSwarm(f, c, rng, particles, spread) for f, c in zip(feeds, starts)]
    progress = _Progress(t0, _total(swarms), budget)
    progress.run(swarms, iterations)
    # then on knots twice as dense, from the same feed (knot insertion keeps it), REFINEMENTS times
    for _ in range(REFINEMENTS):
        finer = [sw.feed.refined(sw.c) for sw in swarms]
        swarms = [BlockSwarm(f, _first_not_none(f.start_within(c), f.scaled_within(c)), rng, particles, spread)
                  for f, c in finer]
        progress.run(swarms, iterations)
    feeds = [sw.feed for sw in swarms]
    # the swarm's limits hold at the stations; where its samples at T read above one, the
    # limit is held lower at the stations there and the swarm goes on from its context made
    # feasible again (as topp3 repairs its SOCP).  The swarm's profile: the fastest of each
    # round's brought within the limits at T by a time warp (_stretched_at_T): a round's
    # tightening costs time everywhere under its windows, and the reads left before it can
    # cost less to stretch (as topp3._stretch chooses among its rounds)
    repairs, found = [], []
    for rnd in range(SWARM_REPAIRS + 1):
        spans = [FeedSpan(f, sw.c, k) for k, (f, sw) in enumerate(zip(feeds, swarms))]
        if sum(sp.duration for sp in spans) > too_slow:
            break
        at_T = Profile.from_pieces("pso", T, spans, path)
        above = topp3.reads_above(at_T, machine, path, limits)
        found.append((_stretched_at_T(spans, at_T, path, machine, limits, too_slow), spans))
        if not above or rnd == SWARM_REPAIRS:
            break
        for col, i, width, ratio in above:
            lo, hi = at_T.s[i], at_T.s[min(i + width, len(at_T.s) - 1)]
            for f in feeds:
                if f.piece.s0 <= hi and f.piece.s1 >= lo:
                    f.tighten(col, lo, hi, ratio, topp3.TIGHTEN_EXTRA * 2 ** rnd)
        # the context within the tightened limits again (start_within: below it by the least
        # the climb finds); the swarm's pushes then raise it where it may be
        again = [_first_not_none(sw.feed.start_within(sw.c), sw.feed.scaled_within(sw.c)) for sw in swarms]
        times = [sw.feed.time(c) for sw, c in zip(swarms, again)]
        if sum(times) > COLLAPSE * _total(swarms):
            break       # a context that collapsed somewhere
        repairs.append(len(above))
        for sw, c in zip(swarms, again):
            sw.c = c
        progress.run(swarms, REPAIR_ITERATIONS)
    found = [(prof, sp) for prof, sp in found if prof is not None]
    prof, spans = min(found, key=lambda x: x[0].execution_time_s) if found else (None, spans)
    return prof, spans, progress, repairs, feeds


class _Progress:
    """The swarms' iterations: the best total after each (``history``: (seconds since t0, scaled
    time)), and what stopped them."""

    def __init__(self, t0, start, budget):
        self.t0, self.budget = t0, budget
        self.history, self.stopped_by = [(0.0, start)], "iterations"

    def run(self, swarms, iterations):
        for _ in range(iterations):
            if self.budget is not None and time.perf_counter() - self.t0 > self.budget:
                self.stopped_by = "time budget"
                return
            for sw in swarms:
                sw.step()
            self.history.append((round(time.perf_counter() - self.t0, 4), _total(swarms)))


def _near_stops(pieces, a_ra) -> list[float]:
    """Arc lengths inside the pieces where the jerk-free optimum (``a_ra``: ṡ² of TOPP2-RA at
    each piece's stations, feed.jerk_free_a) all but stops: the lowest station of each stretch
    where its feed is below NEAR_STOP_SPREAD × NEAR_STOP of the piece's fastest, if that station
    is below NEAR_STOP × it (a near-cusp's tip, a µm blend).
    The swarm's pieces end there at rest: a spline of ṡ^{3/2} that must dip to ~0 inside a piece
    is fitted with a ringing that reads far above the limits, and its start was stretched
    uniformly by that (docs/TUNING.md)."""
    out = []
    for p, a in zip(pieces, a_ra):
        sd = np.sqrt(a)
        low = np.diff(np.r_[0, (sd < NEAR_STOP_SPREAD * NEAR_STOP * sd.max()).astype(int), 0])
        for a, b in zip(np.flatnonzero(low == 1), np.flatnonzero(low == -1)):
            i = a + int(np.argmin(sd[a:b]))
            if 0 < a and b < len(sd) and sd[i] < NEAR_STOP * sd.max():
                out.append(float(p.grid[i]))
    return out


def _first_not_none(*xs):
    return next(x for x in xs if x is not None)


def _total(swarms) -> float:
    """The swarms' contexts' time in scaled time (their own station model)."""
    return float(sum(sw.feed.time(sw.c) for sw in swarms))


def _seed_feed(seed_prof, piece):
    """The seed's feed (scaled time) at the piece's stations."""
    return np.interp(piece.grid, seed_prof.s, seed_prof.sd) * piece.tu


def _stretched_at_T(spans, at_T, path, machine, limits, too_slow):
    """The spans (``at_T``: sampled at T) brought within the limits there by the faster of two time
    warps of the spline (the path and the feed over s stay; only the time along them moves):
    stretched around each read above by sech bumps of whole periods (topp3.stretch_locally,
    `optimal`'s last resort: on a G64 program of hundreds of joins in one piece, a read at one
    join stretched the whole piece, docs/TUNING.md), and each rest-to-rest piece stretched
    uniformly by the worst need of its samples (planners.verify.stretch_need), up to
    STRETCH_ROUNDS rounds a piece; None if neither is within the limits or faster than
    ``too_slow``."""
    T = at_T.T
    local = topp3.stretch_locally(at_T, spans, machine, path, limits, {}, "pso")
    # stretch_locally ends at stretch_need ≤ 1 + tol, a k-th root of the ratio: (1 + tol)^k on
    # a and j, looser than the check every candidate of _plan must pass
    if local is not None and not keeps_joints_and_feed(command_metrics(machine, path.point(local.s), T, local.s,
                                                                       limits)):
        local = None
    uniform = _stretched_uniformly(spans, T, path, machine, limits, too_slow)
    fits = [p for p in (local, uniform) if p is not None and p.execution_time_s <= too_slow]
    return min(fits, key=lambda p: p.execution_time_s) if fits else None


def _stretched_uniformly(spans, T, path, machine, limits, too_slow):
    """The spans sampled at T, each rest-to-rest piece stretched by the worst need of its samples
    (planners.verify.stretch_need), up to STRETCH_ROUNDS rounds a piece; None if still above a
    limit or slower than ``too_slow``."""
    for _ in range(min(STRETCH_ROUNDS * len(spans), STRETCH_ROUNDS_MAX)):
        if sum(sp.duration for sp in spans) > too_slow:
            return None
        prof = Profile.from_pieces("pso", T, spans, path)
        r = command_metrics(machine, path.point(prof.s), T, prof.s, limits)
        if keeps_joints_and_feed(r):
            return prof
        need = stretch_need(machine.ik(path.point(prof.s)), prof.s, T, limits)
        starts = np.concatenate([[0.0], np.cumsum([sp.duration for sp in spans])])
        g = np.clip(np.searchsorted(starts, prof.t, side="right") - 1, 0, len(spans) - 1)
        worst = np.zeros(len(spans))
        np.maximum.at(worst, g, need)
        for sp, w in zip(spans, worst):
            if w > 1.0:
                sp.lam *= w * (1 + 1e-4)
    return None
