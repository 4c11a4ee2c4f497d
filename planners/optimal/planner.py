"""`optimal` — minimum time with joint velocity, acceleration and jerk limits: the yardstick.

The constraint set is the planners' shared one (joint v, a, j; F_max; the chord-error feed
cap; the G1-join reads).  Two transcriptions:

* COPP's TOPP3-SOCP over arc length (planners/optimal/topp3.py; its rows solved by the banded
  interior-point method of planners/optimal/ipm.py, copp-py's Clarabel where that has none): stations
  ≤ GRID_MM apart and ≤ STATION_RADII curvature radii (closer than `copp`'s, down to
  STATION_MIN_MM at µm tips) and graded 2× outward from every G1 join
  (topp3.Settings.join_grading: the SOCP's chord time is the profile's time also where the feed
  falls near 0 at a G64 corner), every G1 join's jump held as each third difference at T
  reads it, whatever the samples' phase (topp3.Settings.window_reads), the feed cap held at
  every cell's middle too
  (topp3.Settings.midpoint_cap), the jerk limit linearised by tangents (a restriction: the time
  never grows from one linearisation to the next; they stop where the next is predicted to gain
  < LIN_PREDICTED: topp3.linearisation_cost), checked at T and repaired in windows where a
  difference reads above a limit (a joint read within half of CHAIN_MARGIN is left:
  Settings.read_slack; a station's extra tightening doubles each time it is tightened again);
  where topp3.MAX_REPAIRS rounds of that leave reads above, the fastest of the rounds' profiles
  stretched in time around their reads (topp3._stretch).  The stations are solved
  twice as coarse first (the first linearisation of the finer solve, the NURBS knots whose
  false cap the coarse speed reaches: topp3.binding_knots, a station at each without jerk rows,
  so each side's cell holds its own q‴; and the cells where the coarse speed changes by more
  than 1 %, split, and the cells at the rest ends, graded: topp3.speed_stations, without which
  the jerk-limited starts and stops kept the SOCP 0.2–0.75 % above the optimum at any spacing;
  where none are added, the time the halving moved); the path is
  solved again on finer stations where a halving moved it by more than SPACING_GAIN, where a
  limit still reads above 1 after the repairs, or where they cost more than REPAIR_COST
  (_socp_within_limits).  The coarse stations are repaired at T too and returned where that
  is the fastest within the limits: where a path's G1 joins' reads dominate, the repairs cost
  more on finer stations (_faster_within).
  No other planner's profile is ever returned: without a profile within the limits `optimal`
  raises a PlanningError naming the path and the limit;
* the time-domain NLP (CasADi + IPOPT, planners/optimal/nlp.py): direct multiple shooting with
  constant jerk on each interval, the limits at the nodes, started from the SOCP's profile.  It
  runs with ``polish=True`` and, by default, where its nodes resolve every piece
  (_nlp_resolves); the faster of it and its start is returned (info["source"]: "socp" or "nlp").

info["lower_bound_s"] bounds the continuous problem from below (bound.py: the velocity limit
curve and the acceleration from and to rest, each interval at its worst case), info["gap"] is
the profile's excess over it.  The SOCP's station relaxation (info["station_relaxation_s"]) and
the NLP's node relaxation (info["node_relaxation_s"]) bound only their transcriptions.

The NLP's solution is sampled at T exactly and checked with the independent metrics; if a
discretisation effect pushes a joint ratio above 1 the problem is re-solved: on a grid twice
as fine (from the seed again) where the node budget had spread the nodes ≥ 3× thinner than
`node_period_s` (up to MAX_NODES_REFINED per piece), else from the last solution, in the
pieces where a limit read above 1: with the margin doubled on each limit read above 1 (each
piece has one margin per limit) and, if it was a or j on a grid not refined, these bounded
at each interval's midpoint too.  Still above after `retries`, the pieces are slowed down
uniformly until they pass (_slowed_down).  A wider margin and the slow-down only slow the
solution: one that reads above and is already no faster than its start ends the polish there
(NoFasterThanStart; the start is returned).  (Why refining comes first and why margins are per
piece and per limit: docs/TUNING.md.)
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

from planners.constraints import (PathTable, PlanningError, check_limits, check_path, join_jumps, rest_pieces,
                                  table_feed_cap)
from planners.optimal import topp3
from planners.optimal.bound import lower_bound
from planners.optimal.nlp import LIMIT_KINDS, IpoptFailure, _Piece
from planners.profile import Profile
from planners.verify import command_metrics, keeps_joints_and_feed, windows_above, worst_sample

# where the SOCP's profile still breaks a limit at T: solved again on stations this many times
# closer, up to REFINE_LEVELS times
STATION_REFINEMENT = 2
REFINE_LEVELS = 2
# ... and where the repairs cost more than this fraction of the time the stations alone allowed
# (station_relaxation_s), while a refinement gains at least as much: at a cusp tip the repairs
# at 0.05 mm cost 2.4 % of the time, at 0.025 mm 0.01 %; at 0.1 % most kossel paths took 5× the
# time for 0.03 % (docs/TUNING.md)
REPAIR_COST = 3e-3
# ... and where the last halving of the stations moved their time by more than this fraction
# (info["spacing_gain"]), either way: TOPP3's b linear in s between stations is a restriction
# (finer stations are faster; its excess shrinks ~3× a halving, order ~1.6 on rand_edge_lcnc:
# 0.60 % from 0.1 to 0.05 mm, 0.20 % from 0.05 to 0.025), the limits held at the stations only a
# relaxation (finer stations are slower: meander_lcnc 6.539 → 6.582 s from 0.1 to 0.05 mm, and
# 6.597 → 6.577 s after the repairs at 0.025 mm).  The repairs' rule alone never refines where the
# repairs cost nothing
SPACING_GAIN = 2e-3
# stations ≤ GRID_MM apart and ≤ STATION_RADII curvature radii (copp's engine: 0.1 mm and 0.5 radii).
# TOPP3's b is linear in s between stations, a restriction whose time excess shrinks about in
# proportion to the spacing: at 0.1 mm / 0.1 radii the stations alone kept optimal 0.2–0.46 % above
# the converged reference on keops's paths, at half that spacing ≤ 0.2 % (docs/TUNING.md)
GRID_MM = 0.05
STATION_RADII = 0.05
# ... and no closer than this (copp's floor, 1 µm, is 0.05 radii of a 20 µm radius: at
# cusp_trochoid_lcnc's 1.8 µm tips it left ~2 stations a tip and the stations alone 1.6 % above
# T_ref, at any spacing in mm; docs/TUNING.md); the floor of the join grading
STATION_MIN_MM = topp3.GRADED_MIN_MM
# the SOCP plans to the joint limits less this fraction: its repairs stop at a read of
# 1 + FEASIBLE_TOL, and the FMU chain's command read the joints up to 1e-6 above the planner's
# samples (keops/bird: jerk 1.0000006 → 1.0000014, "breaks the limit"); 1e-5 costs ~3e-6 of the time.
# The samples at T may use half of it (topp3.Settings.read_slack): repaired down to 1 + 1e-6 of the
# inner limits, reads of a few 10⁻⁶ crept along rose3_keops_tilted's acceleration plateaus from
# window to window, and 8 rounds of ever larger tightenings cost 0.08 % (docs/TUNING.md)
CHAIN_MARGIN = 1e-5
# the linearisations stop where the next one is predicted to gain less than this share of the
# time (topp3.linearisation_cost), without the solve that would confirm it: a finer grid's second
# solve, linearised around its first, is ~⅓ of the planning time on keops's NURBS paths and
# gained a few 1e-6 there (docs/TUNING.md)
LIN_PREDICTED = 5e-5
# Nodes per phase (between G1 joins) at least: the limits hold at the nodes only, and on a
# short G64 blend arc the joint derivatives turn through 90° (docs/TUNING.md).
MIN_PHASE_NODES = 24
# A piece's grid is refined on a failed check up to this many nodes (more than the default
# budget, which bounds the solve's time)
MAX_NODES_REFINED = 1500
# ... when the budget had spread its nodes this many times thinner than node_period_s
THIN_GRID_FACTOR = 3.0
# Where the path turns, a node at least every NODE_RADII curvature radii of travel (6° of turn;
# the 24 nodes of MIN_PHASE_NODES on a 90° blend arc are 3.75° apart)
NODE_RADII = 0.1
# Where IPOPT fails from the warm start slowed by warm_stretch, or its solution reads above a limit
# no faster than the start, it starts again from this (a start further inside the constraints:
# on contour_keops from two SOCP profiles 1e-6 apart IPOPT's first solution read above at 2.545 s
# from one and was 2.362 s from the other; from 1.05 or 1.1 × the first, 2.362 s)
RETRY_STRETCH = 1.1
# an NLP solution (or its slow-down) slower than this many times its start is no candidate
# (_faster_of keeps the start) and is not sampled at T: the samples' memory stays bounded
TOO_SLOW = 10.0


def broken_limits(machine, path, prof, pcs, limits) -> set:
    """{(piece index, limit kind)} read above its limit at T (planners.verify.windows_above): the
    joint velocity, acceleration, jerk of the IK'd samples (each window blamed on the piece its
    first sample is in) and the feed against F_max."""
    edges = np.array([a for a, _ in pcs[1:]])
    above = windows_above(machine.ik(path.point(prof.s)), prof.T, limits.joint, prof.s, limits.feed_max)
    return {(int(np.searchsorted(edges, prof.s[i], side="right")), kind) for kind, i, _ in above}


def turn_nodes(path, table):
    """(s, the nodes the path's turning asks for up to s: ∫κ ds / NODE_RADII) on the table's rows
    (refined at lobe tips, so a tip narrower than the base spacing is counted in full)."""
    s = table.s
    k = np.asarray(path.curvature(s), float)
    return s, np.concatenate([[0.0], np.cumsum(np.diff(s) * (k[1:] + k[:-1]) / 2)]) / NODE_RADII


def _warm_start(prof, bounds, node_period_s, max_nodes, stretch=1.15, turn=None):
    """Phase sizes, interval durations and nodes from a profile (the warm start) on one piece,
    slowed down by `stretch`.  ``bounds`` = [s0, joins…, s1].  Nodes come one per
    ``node_period_s`` and, where the path turns (``turn`` = turn_nodes(…)), one more per
    NODE_RADII curvature radii of travel: the limits hold at the nodes only, and a lobe tip
    passed in a few ms fell between nodes spread by time alone.  Over the budget the time share is thinned first."""
    t = prof.t
    sgrid, idx = np.unique(prof.s, return_index=True)
    tb = np.interp(bounds, sgrid, t[idx])
    D = np.maximum(np.diff(tb), 4 * prof.T)
    tf = [np.linspace(tb[k], tb[k] + D[k], max(400, int(np.ceil(D[k] / prof.T))) + 1) for k in range(len(D))]
    geo = [np.zeros(len(x)) for x in tf]
    if turn is not None:
        geo = [np.interp(np.interp(x, t, prof.s), *turn) for x in tf]
        geo = [g - g[0] for g in geo]
    base = [(x - x[0]) * stretch / node_period_s for x in tf]
    for scale in 0.8 ** np.arange(40):      # thin the time share until the nodes fit the budget
        Ns = np.array([max(MIN_PHASE_NODES, int(np.ceil(b[-1] * scale + g[-1]))) for b, g in zip(base, geo)])
        if Ns.sum() <= max_nodes:
            break
    if Ns.sum() > max_nodes:
        Ns = np.maximum(MIN_PHASE_NODES, (Ns * max_nodes / Ns.sum()).astype(int))
    tt, H = [], []
    for k in range(len(D)):
        # nodes at equal steps of the cumulative count (the 1e-9 keeps it increasing)
        c = base[k] * scale + geo[k] + 1e-9 * np.arange(len(tf[k]))
        tk = np.interp(np.linspace(0, c[-1], Ns[k] + 1), c, tf[k])
        tt.append(tk[:-1])
        H.append(np.diff(tk) * stretch)
    tt = np.concatenate(tt + [[tf[-1][-1]]])
    H = np.concatenate(H)
    S = np.interp(tt, t, prof.s)
    S[0], S[-1] = bounds[0], bounds[-1]
    V = np.interp(tt, t, prof.sd) / stretch
    V[0] = V[-1] = 0.0
    A = np.zeros_like(V)
    A[1:-1] = (V[2:] - V[:-2]) / (H[1:] + H[:-1])
    U = np.diff(A) / H
    return Ns, H, S, V, A, U


class _CubicSpans:
    """The piecewise-cubic solutions joined end to end: one piece of `Profile.from_pieces`,
    evaluated by span index; s and ṡ floored at 0 (a solver's rounding below rest)."""

    s0 = 0.0

    def __init__(self, pieces_sol):
        knots_t, S, V, A, U = [], [], [], [], []
        t0 = 0.0
        for (h, s, v, a, u) in pieces_sol:
            knots_t.append(t0 + np.concatenate([[0.0], np.cumsum(h)[:-1]]))
            S.append(s[:-1]); V.append(v[:-1]); A.append(a[:-1]); U.append(u)
            t0 += float(np.sum(h))
        self.kt = np.concatenate(knots_t)
        self.S, self.V, self.A, self.U = (np.concatenate(x) for x in (S, V, A, U))
        self.duration = t0

    def at(self, tt):
        k = np.clip(np.searchsorted(self.kt, tt, side="right") - 1, 0, len(self.kt) - 1)
        tau = tt - self.kt[k]
        S, V, A, U = self.S[k], self.V[k], self.A[k], self.U[k]
        s = S + V * tau + A * tau ** 2 / 2 + U * tau ** 3 / 6
        sd = V + A * tau + U * tau ** 2 / 2
        return np.maximum(s, 0.0), np.maximum(sd, 0.0), A + U * tau, U.copy()


def sample_cubic(pieces_sol, T, path, info) -> Profile:
    """Join the piecewise-cubic solutions and sample at exact multiples of T."""
    prof = Profile.from_pieces("optimal", T, [_CubicSpans(pieces_sol)], path, info)
    prof.sd[0] = prof.sdd[0] = 0.0
    return prof


def plan(path, machine, limits=None, *, grid_mm: float = GRID_MM, polish: bool | None = None,
         margin: float = 0.005, node_period_s: float = 1e-3, max_nodes_per_piece: int = 600,
         warm_stretch: float = 1.02, retries: int = 3, read_phases: int = 1) -> Profile:
    """Minimum-time jerk-limited reference: the TOPP3-SOCP (stations ≤ ``grid_mm`` apart, finer
    where its profile breaks a limit at T), with ``polish`` the IPOPT NLP from there (module
    docstring); ``polish=None`` (the default): where the NLP's grid resolves every piece, a node
    per ``node_period_s`` within ``max_nodes_per_piece`` (_nlp_resolves).  info["lower_bound_s"]:
    a bound of the continuous problem (bound.py), info["gap"] the time's excess over it.
    ``read_phases``: the SOCP's repairs read the samples at T at that many phases of the
    servo clock (topp3.Settings.read_phases); 1 reads the one the harness checks."""
    t0 = time.perf_counter()
    limits = machine.limits if limits is None else limits
    check_limits(limits, "optimal")
    check_path(path, "optimal")
    if isinstance(read_phases, bool) or not isinstance(read_phases, int) or read_phases < 1:
        raise PlanningError(f"optimal: read_phases = {read_phases!r} must be an integer ≥ 1")
    prof = _socp_within_limits(path, machine, limits, grid_mm, read_phases)
    if polish is None:
        polish = _nlp_resolves(prof, path, node_period_s, max_nodes_per_piece)
    if polish:
        prof = _polish(path, machine, limits, prof, margin, node_period_s, max_nodes_per_piece,
                       warm_stretch, retries)
    bound = lower_bound(path, machine, limits)
    prof.info["lower_bound_s"] = bound
    prof.info["gap"] = prof.execution_time_s / bound - 1
    prof.planning_time_s = time.perf_counter() - t0
    return prof


def _nlp_resolves(prof, path, node_period_s, max_nodes) -> bool:
    """Whether the NLP's nodes fit every rest-to-rest piece of ``prof`` at one per node_period_s
    within max_nodes: spread thinner, its grids missed the limits between nodes and it lost to
    its start (docs/TUNING.md)."""
    t = np.interp([a for a, _ in rest_pieces(path)] + [path.length], prof.s, prof.t)
    return bool(np.all(np.diff(t) <= max_nodes * node_period_s))


def _within(machine, path, prof, limits) -> tuple[bool, str]:
    """(within the joint limits and F_max at T, what reads worst where it is not)."""
    r = command_metrics(machine, path.point(prof.s), prof.T, prof.s, limits)
    if keeps_joints_and_feed(r):
        return True, ""
    feed = r["cartesian_peak_ratio"].get("feed", 0.0)
    if not r["feasible"]:
        order, i, ratio = worst_sample(machine.ik(path.point(prof.s)), prof.T, limits.joint)
        return False, f"joint {order} {ratio:.6g} × its limit at s = {prof.s[i]:.6g} mm"
    return False, f"feed {feed:.6g} × F_max"


def _settings(grid_mm, f, knots=(), extra=(), read_phases=1) -> topp3.Settings:
    """optimal's engine settings on stations ``f`` times closer than grid_mm / STATION_RADII,
    with cells at ``knots`` (topp3.binding_knots) and the stations ``extra`` (topp3.speed_stations)."""
    return topp3.Settings("optimal", grid_mm / f, station_radii=STATION_RADII / f, station_min_mm=STATION_MIN_MM,
                          join_grading=True, window_reads=True, read_slack=CHAIN_MARGIN / 2, midpoint_cap=True,
                          knot_cells=knots,
                          extra_stations=extra, read_phases=read_phases, lin_predicted=LIN_PREDICTED)


def _socp_within_limits(path, machine, limits, grid_mm, read_phases=1) -> Profile:
    """The TOPP3-SOCP's profile, checked at T.  The stations are first solved STATION_REFINEMENT
    times coarser, for the first linearisation of the solve at grid_mm, for the knots that get
    cells (topp3.binding_knots), for the stations its speed asks for (topp3.speed_stations) and,
    where it asks for none, for how much the halving moved their time.  The path is solved
    again on stations STATION_REFINEMENT times closer (also in curvature radii), up to
    REFINE_LEVELS times, each linearised around the last, where the last halving of the
    stations moved their time by more than SPACING_GAIN, where the engine's repairs (tightened
    windows, then stretches) still leave a limit above 1, or where they cost more than
    REPAIR_COST of the time the stations alone allowed (and the last refinement gained as
    much): the limits hold at the stations, so finer stations leave less to read between them
    and to repair.  A refinement that has no solution or is no faster ends the search; the
    coarse stations, repaired too, are the last candidate (_faster_within) where their time at
    the stations alone is below the best's.  The fastest profile within the limits is returned.
    Never another planner's profile: without a profile within the limits a PlanningError names
    the path and the limit."""
    why, best = [], None
    inner = limits.joint_scaled(1 - CHAIN_MARGIN)
    coarse = _settings(grid_mm, 1 / STATION_REFINEMENT, read_phases=read_phases)
    try:
        prev = coarse_pieces = topp3.pieces_of(path, machine, inner, coarse)
        relax_prev = coarse_time = topp3.station_time(prev, coarse)
        knots = topp3.binding_knots(prev, path, machine, inner)
        extra = topp3.speed_stations(prev)
        # the coarse stations lack them: their time is no measure of the spacing's gain
        relax_prev = None if extra else relax_prev
    except PlanningError:           # the finer stations are solved from TOPP2-RA's profile
        prev, relax_prev, knots, extra, coarse_pieces, coarse_time = None, None, (), (), None, None
    for level in range(REFINE_LEVELS + 1):
        settings = _settings(grid_mm, STATION_REFINEMENT ** level, knots, extra, read_phases)
        try:
            pieces = topp3.pieces_of(path, machine, inner, settings)
            if prev is not None:
                topp3.linearise_around(pieces, prev)
            prof = topp3.solve(path, machine, inner, settings, pieces)
        except PlanningError as e:
            why.append(f"stations ≤ {settings.grid_mm:g} mm: {e}")
            if best is not None:
                break
            prev, relax_prev = None, None
            continue
        relax = prof.info["station_relaxation_s"]
        spacing_gain = 0.0 if relax_prev is None else 1 - relax / relax_prev
        prev, relax_prev = pieces, relax
        ok, worst = _within(machine, path, prof, limits)
        if not ok:
            why.append(f"stations ≤ {settings.grid_mm:g} mm: {worst}")
            continue
        # continuous times (the samples at T round up by up to one period)
        t_new = prof.info["continuous_time_s"]
        if best is not None and t_new >= best.info["continuous_time_s"]:
            break
        gain = 1.0 if best is None else 1 - t_new / best.info["continuous_time_s"]
        prof.info.update(source="socp", grid_mm=settings.grid_mm, spacing_gain=spacing_gain)
        best = prof
        repairs_cost = t_new > (1 + REPAIR_COST) * relax and gain >= REPAIR_COST
        if not (repairs_cost or abs(spacing_gain) > SPACING_GAIN):
            break
    # the repairs at T only add rows to the coarse stations' problem: where its stations alone
    # are no faster than the best, repaired it cannot be faster either
    if coarse_pieces is not None and (best is None or coarse_time < best.info["continuous_time_s"]):
        best = _faster_within(best, coarse_pieces, coarse, path, machine, inner, limits, why)
    if best is None:
        raise PlanningError(f"optimal: {getattr(path, 'source', 'the path')}: no profile within the limits at T; "
                            + "; ".join(why))
    return best


def _faster_within(best, pieces, settings, path, machine, inner, limits, why) -> Profile | None:
    """``best`` or, where faster and within the limits at T, the coarse stations' solution
    (``pieces``, solved at the stations) repaired at T.  Where many G1 joins read above at T the
    repairs, not the stations, decide the time, and they can cost more on finer stations
    (cam_dense_lcnc: docs/TUNING.md, thirty-fifth session)."""
    try:
        prof = topp3.solve(path, machine, inner, settings, pieces)
    except PlanningError as e:
        why.append(f"stations ≤ {settings.grid_mm:g} mm: {e}")
        return best
    ok, worst = _within(machine, path, prof, limits)
    if not ok:
        why.append(f"stations ≤ {settings.grid_mm:g} mm: {worst}")
        return best
    if best is not None and prof.info["continuous_time_s"] >= best.info["continuous_time_s"]:
        return best
    prof.info.update(source="socp", grid_mm=settings.grid_mm, spacing_gain=0.0)   # no coarser level
    return prof


def _polish(path, machine, limits, warm, margin=0.005, node_period_s=1e-3, max_nodes_per_piece=600,
            warm_stretch=1.02, retries=3) -> Profile:
    """The NLP from ``warm`` slowed down by ``warm_stretch``; where IPOPT fails from there or
    its solution reads above a limit and is no faster than its start, once more from
    RETRY_STRETCH (a start further inside the constraints).  The faster of the solution and the
    start is returned, both checked at T."""
    T = machine.servo_period_s
    table = PathTable(path, machine, refine=True)
    cap = table_feed_cap(path, table, limits, T)
    joins = join_jumps(path, table, machine)
    pcs = rest_pieces(path)
    _check_node_budget(path, joins, pcs)
    turn = turn_nodes(path, table)
    prof, failure = None, None
    for stretch in sorted({warm_stretch, max(warm_stretch, RETRY_STRETCH)}):
        problems = [_Piece(table, cap, s0, s1, limits, margin, joins, T) for s0, s1 in pcs]
        try:
            prof = _solve(path, machine, limits, problems, pcs, warm, stretch, node_period_s,
                          max_nodes_per_piece, retries, turn)
            prof.info["warm_stretch"] = stretch
            break
        except PlanningError as e:          # IPOPT failed, or still above a limit when slowed down
            failure = e
            if not isinstance(e, (IpoptFailure, NoFasterThanStart)):
                break
    return _faster_of(prof, warm, machine, path, limits, failure)


def _faster_of(prof, warm, machine, path, limits, failure) -> Profile:
    """The NLP's solution or, where its start is within the limits at T and faster (the NLP
    failed, or its slow-down cost more than it gained), the start as `optimal`'s answer, saying
    so in info["source"]."""
    r = command_metrics(machine, path.point(warm.s), warm.T, warm.s, limits)
    warm_ok = keeps_joints_and_feed(r)
    if prof is not None and (not warm_ok or prof.execution_time_s <= warm.execution_time_s):
        prof.info["source"] = "nlp"
        return prof
    if not warm_ok:
        raise failure
    info = dict(warm.info, source=warm.info.get("source", f"warm start ({warm.planner})"),
                nlp=str(failure) if prof is None else f"{prof.execution_time_s:.6g} s")
    return dataclasses.replace(warm, planner="optimal", info=info)


def _solve(path, machine, limits, problems, pcs, warm, stretch, node_period_s, max_nodes,
           retries, turn) -> Profile:
    """Solve, check at T, and on a limit read above 1 refine the thin grids or widen the
    margins; the last resort slows the pieces still above a limit down (_slowed_down)."""
    T = machine.servo_period_s
    bounds = [[p.s0] + [sj for sj, _ in p.joins] + [p.s1] for p in problems]
    starts = [_warm_start(warm, b, node_period_s, max_nodes, stretch, turn) for b in bounds]
    budgets = [max_nodes] * len(pcs)
    too_slow = TOO_SLOW * warm.execution_time_s
    for attempt in range(retries + 1):
        sols, statuses, nxt = _solve_pieces(problems, starts)
        _check_duration(sols, too_slow, "solution")
        margins = [dict(p.margins) for p in problems]
        prof = sample_cubic(sols, T, path, {"pieces": len(pcs), "ipopt": statuses,
                                            "margin": max(max(m.values()) for m in margins),
                                            "margins": margins, "midpoints": [p.midpoints for p in problems],
                                            "nodes": [int(np.sum(x[0])) for x in starts],
                                            "phases": sum(len(p.joins) + 1 for p in problems)})
        if attempt == 0:
            # the lower bound: scaled in time by 1/(1 − m), a profile within the limits becomes one
            # within the limits less the margin m, so the margin-free optimum on these nodes is
            # ≥ T₁·(1 − m) (IPOPT's optimum is local: a bound of the node relaxation, not a certificate)
            bound = duration(sols) * (1 - max(max(m.values()) for m in margins))
        r = command_metrics(machine, path.point(prof.s), T, prof.s, limits)
        if keeps_joints_and_feed(r):
            break
        # the limits hold at the nodes only: where the node budget spread a piece's grid
        # ≥ THIN_GRID_FACTOR times thinner than node_period_s, a grid twice as fine comes before a
        # larger margin, which costs time everywhere.  Warm-started from the feasible seed again:
        # from this solution (on the limits at the old nodes, off them between) IPOPT took
        # many times longer
        thin = [float(np.mean(st[1])) >= THIN_GRID_FACTOR * node_period_s
                and budgets[i] < MAX_NODES_REFINED for i, st in enumerate(starts)]
        if attempt == retries or not any(thin):
            # a wider margin or the slow-down only makes the solution slower: already no faster
            # than its start (within the limits at T), no later one can win in _faster_of
            start_s = warm.info.get("continuous_time_s", warm.execution_time_s)
            solved_s = duration(sols)
            if solved_s >= start_s:
                raise NoFasterThanStart(f"optimal: the NLP's solution {attempt + 1} takes {solved_s:.6g} s "
                                        f"and reads above a limit at T, no faster than its start's "
                                        f"{start_s:.6g} s")
        if attempt == retries:
            prof = _slowed_down(machine, path, prof, pcs, limits, sols, r, T, statuses, too_slow)
            break
        if any(thin):
            for i, b in enumerate(bounds):
                if thin[i]:
                    budgets[i] = min(2 * budgets[i], MAX_NODES_REFINED)
                    nxt[i] = _warm_start(warm, b, node_period_s, budgets[i], stretch, turn)
        else:
            _widen_margins(machine, path, prof, pcs, limits, problems, budgets, max_nodes)
        starts = nxt
    prof.info["node_relaxation_s"] = bound
    return prof


class NoFasterThanStart(PlanningError):
    """The polish ended: a solution that read above a limit at T was already no faster than its
    start, and a wider margin or the slow-down would only slow it."""


def duration(sols) -> float:
    """The continuous time of the pieces' NLP solutions (their interval lengths summed)."""
    return sum(float(np.sum(x[0])) for x in sols)


def _check_duration(sols, too_slow, what) -> None:
    """A solution slower than ``too_slow`` is not sampled at T (a wild NLP solution slowed down
    by its worst read asked for gigabytes of samples); the start is kept."""
    d = duration(sols)
    if not d <= too_slow:
        raise PlanningError(f"optimal: the NLP's {what} takes {d:.6g} s, more than {TOO_SLOW:g} × its start's "
                            f"{too_slow / TOO_SLOW:.6g} s: not sampled")


def _slowed_down(machine, path, prof, pcs, limits, sols, r, T, statuses, too_slow) -> Profile:
    """The last resort, feasible by construction: each piece that still breaks a limit at T is
    run slower, uniformly (t → λt scales the joint velocity by 1/λ, the acceleration by 1/λ², the
    jerk by 1/λ³), by the factor its worst ratio needs; the info says by how much."""
    total = np.ones(len(sols))
    info = dict(prof.info)
    for _ in range(4):
        ratio = r["joint_peak_ratio"]
        need = max(ratio.get("velocity", 0.0), ratio.get("acceleration", 0.0) ** 0.5,
                   ratio.get("jerk", 0.0) ** (1 / 3), r["cartesian_peak_ratio"].get("feed", 0.0))
        lam = np.ones(len(sols))
        for g in {g for g, _ in broken_limits(machine, path, prof, pcs, limits)}:
            lam[g] = max(need, 1.0) * (1 + 1e-4)
        sols = [(h * k, s, v / k, a / k ** 2, u / k ** 3) for (h, s, v, a, u), k in zip(sols, lam)]
        total *= lam
        _check_duration(sols, too_slow, "solution slowed down to the limits")
        prof = sample_cubic(sols, T, path, dict(info, slowed_down=[float(x) for x in total]))
        r = command_metrics(machine, path.point(prof.s), T, prof.s, limits)
        if keeps_joints_and_feed(r):
            return prof
    raise _limit_error(machine, path, prof, limits, r, statuses)


def _check_node_budget(path, joins, pcs) -> None:
    """Node budget (issue 17): every phase between G1 joins needs MIN_PHASE_NODES, so a piece
    of many short blended chords outgrew any budget and IPOPT ran for hours: refused before
    the warm start is planned."""
    for g, (s0, s1) in enumerate(pcs):
        phases = 1 + sum(1 for sj, _ in joins if s0 + 1e-6 < sj < s1 - 1e-6)
        if phases * MIN_PHASE_NODES > MAX_NODES_REFINED:
            la, lb = (int(x) for x in path.line_at(np.array([s0, s1])))
            where = f", G-code lines {la}…{lb}" if la >= 0 and lb >= 0 else ""
            raise PlanningError(f"optimal: piece {g} (s = {s0:.6g}…{s1:.6g} mm{where}) has {phases} phases "
                                f"between G1 joins, needing {phases * MIN_PHASE_NODES} nodes "
                                f"({MIN_PHASE_NODES} a phase): over the node budget of "
                                f"{MAX_NODES_REFINED} nodes a piece")


def _solve_pieces(problems, starts):
    """Solve each piece from its start; returns the solutions, IPOPT's status of each and
    the next start of each (this solution, as phase sizes, durations and node values)."""
    sols, statuses, nxt = [], [], []
    for piece, (Ns, H, S, V, A, U) in zip(problems, starts):
        sol, status, iters = piece.solve(Ns, H, S, V, A, U)
        sols.append(sol)
        statuses.append(f"{status} ({iters} it)")
        hh = sol[0]
        nxt.append((Ns, hh, sol[1], sol[2], sol[3], sol[4]))
    return sols, statuses, nxt


def _limit_error(machine, path, prof, limits, r, statuses) -> PlanningError:
    """The error when the last attempt still breaks a limit at T: where and by how much."""
    T = prof.T
    order, i, ratio = worst_sample(machine.ik(path.point(prof.s)), T, limits.joint)
    return PlanningError(f"optimal: solution breaks a limit at T even with margins up to "
                         f"{prof.info['margin']:g}: joint "
                         f"{order} {ratio:.4g} × its limit in the window from s = {prof.s[i]:.6g} mm "
                         f"(t = {prof.t[i]:.6g} s); joint peak ratios "
                         f"{ {k: round(v, 4) for k, v in r['joint_peak_ratio'].items()} }, feed / F_max "
                         f"{r['cartesian_peak_ratio'].get('feed', 0):.6g}; IPOPT per piece: "
                         f"{', '.join(statuses)}")


def _widen_margins(machine, path, prof, pcs, limits, problems, budgets, max_nodes_per_piece) -> None:
    """Only the limits read above 1, only in the pieces where they were: a doubled margin,
    and an a or j bounded between the nodes too where the grid was not refined (a refined
    grid is dense, and at a blend join the midpoints do not help and slowed IPOPT down)."""
    broken = broken_limits(machine, path, prof, pcs, limits) or {
        (g, kind) for g in range(len(pcs)) for kind in LIMIT_KINDS}
    for g, kind in broken:
        problems[g].margins[kind] *= 2
        if kind in ("acceleration", "jerk") and budgets[g] == max_nodes_per_piece:
            problems[g].midpoints = True
