"""optimal: the TOPP3-SOCP (planners/optimal/topp3.py) against the jerk-limited closed form on a line that
drives the joints 1:1, its lower bound (bound.py) against the jerk-free closed form, finer
stations where the check at T fails and an error (never another planner's profile) where
nothing passes, order against toppra, errors; the IPOPT NLP (the polish) on its own."""
import dataclasses
import math

import numpy as np
import pytest

from planners.verify import command_metrics
from kins import Limits, MachineLimits, load_machine
from planners import PlanningError, plan
from planners.optimal import planner as optimal
from planners.constraints import join_jumps, rest_pieces, table_feed_cap
from planners.paths import Line, SegmentPath

KOSSEL = load_machine("kossel")


def vertical(L=30.0):
    return SegmentPath([Line([0, 0, -300], [0, 0, -300 + L])])


def nlp(path, machine, warm, **options):
    """The IPOPT NLP alone from ``warm`` (what ``polish=True`` runs from the SOCP's profile)."""
    return optimal._polish(path, machine, machine.limits, warm, **options)


def test_vertical_line_is_the_jerk_limited_closed_form_and_its_bound_the_jerk_free_one():
    """q = z + const on every joint: the minimum time is the 1-D rest-to-rest optimum, here
    L/V + 2√(V/J) (V·J ≤ A²: A is never reached; tests/test_optimal_topp3.py checks it against ruckig).
    The SOCP is above it by the 0.1 mm grid's loss.  The lower bound drops the jerk: q′ = 1,
    q″ = 0, so it is the trapezoid's L/V + V/A (its ramps integrated in closed form)."""
    L = 30.0
    lim = KOSSEL.limits.joint
    exact = L / lim.v + 2 * math.sqrt(lim.v / lim.j)
    p = plan("optimal", vertical(L), KOSSEL)
    assert p.info["source"] == "socp"
    assert command_metrics(KOSSEL, vertical(L).point(p.s), p.T, p.s)["feasible"]
    assert exact - p.T <= p.execution_time_s <= exact * 1.003 + p.T
    lb = p.info["lower_bound_s"]
    jerk_free = L / lim.v + lim.v / lim.a
    assert lb == pytest.approx(jerk_free, rel=1e-6) and lb < exact
    assert p.info["gap"] == pytest.approx(p.execution_time_s / lb - 1)


def test_nlp_on_the_vertical_line_is_the_seven_phase_closed_form_within_its_margin():
    """The NLP tightens every limit by its margin m: the full s-curve L/V + V/A + A/J becomes
    L/(mV) + V/A + A/J (to its discretisation's 0.5 %)."""
    from planners.scurve import plan_joint
    L = 30.0
    p = nlp(vertical(L), KOSSEL, plan_joint(vertical(L), KOSSEL), margin=0.005)
    assert p.info["source"] == "nlp"
    lim = KOSSEL.limits.joint
    m = 1 - 0.005
    exact = L / (m * lim.v) + lim.v / lim.a + lim.a / lim.j
    assert p.info["continuous_time_s"] == pytest.approx(exact, rel=5e-3)
    r = command_metrics(KOSSEL, vertical(L).point(p.s), p.T, p.s)
    assert r["feasible"]
    s = plan("scurve_joint", vertical(L), KOSSEL, margin=0.0)
    assert p.execution_time_s == pytest.approx(s.execution_time_s, rel=6e-3)
    # its node relaxation T₁·(1 − m) lies below the margin-free L/V + V/A + A/J by at most m
    free = L / lim.v + lim.v / lim.a + lim.a / lim.j
    assert free * (1 - 0.005) * (1 - 1e-4) <= p.info["node_relaxation_s"] <= free * (1 + 1e-6)


def test_nlp_stops_before_widening_its_margins_where_its_solution_is_no_faster_than_its_start(monkeypatch):
    """A wider margin or the slow-down only makes the NLP slower, so a solution that breaks a
    limit at T (here: every check reads above) and is already no faster than its start ends the
    polish without widening (keops/bird: 3 widenings, ~90 s, for a 1.772 s that lost to the
    SOCP's 1.76375 s).  From scurve_joint's slow start the same reads widen the margins."""
    from planners.scurve import plan_joint
    path = vertical(30.0)
    socp = plan("optimal", path, KOSSEL, polish=False)
    widened = []
    monkeypatch.setattr(optimal, "keeps_joints_and_feed", lambda r: False)
    monkeypatch.setattr(optimal, "_widen_margins", lambda *a: widened.append(1))
    with pytest.raises(optimal.NoFasterThanStart, match="no faster than its start's"):
        nlp(path, KOSSEL, socp)
    assert widened == []
    with pytest.raises(PlanningError) as e:
        nlp(path, KOSSEL, plan_joint(path, KOSSEL))
    assert not isinstance(e.value, optimal.NoFasterThanStart) and widened


def test_an_nlp_solution_no_faster_than_its_start_is_tried_again_from_further_inside(monkeypatch):
    """Where the NLP's solution from the start slowed by warm_stretch reads above a limit and is
    no faster than its start, the NLP runs once more from RETRY_STRETCH; its solution, faster
    than the start and within the limits, is returned (contour_keops: 2.372 → 2.362 s)."""
    from planners.scurve import plan_joint
    path = vertical(30.0)
    start = plan_joint(path, KOSSEL)                # a start the NLP beats
    real, stretches = optimal._solve, []

    def solve(*a):
        stretches.append(a[6])
        if len(stretches) == 1:
            raise optimal.NoFasterThanStart("optimal: the NLP's solution 1 … no faster than its start's")
        return real(*a)
    monkeypatch.setattr(optimal, "_solve", solve)
    p = nlp(path, KOSSEL, start)
    assert stretches == [1.02, optimal.RETRY_STRETCH]
    assert p.info["source"] == "nlp" and p.info["warm_stretch"] == optimal.RETRY_STRETCH
    assert p.execution_time_s < start.execution_time_s
    assert command_metrics(KOSSEL, path.point(p.s), p.T, p.s)["feasible"]


def test_optimal_is_not_faster_than_toppra():
    t_opt = plan("optimal", vertical(), KOSSEL).info["continuous_time_s"]
    t_top = plan("toppra", vertical(), KOSSEL).info["continuous_time_s"]
    assert t_top <= t_opt


def test_limit_not_positive():
    lim = KOSSEL.limits
    bad = MachineLimits(Limits(lim.joint.v, lim.joint.a, 0.0), lim.cartesian, lim.feed_max, lim.chord_error_mm)
    with pytest.raises(PlanningError, match="joint limit j = 0"):
        plan("optimal", vertical(), KOSSEL, bad)


def test_empty_path():
    class Empty:
        length = 0.0
    with pytest.raises(PlanningError, match="non-empty"):
        optimal.plan(Empty(), KOSSEL)


@pytest.mark.slow
def test_g64_blend_arc_between_toppra_and_scurve_joint():
    """Two lines blended by a 0.038 mm G64 arc (two G1 joins where q″ jumps): IPOPT starts from
    the feasible scurve_joint plan, ends feasible, no slower than it and no faster than toppra.
    (From toppra's start, 68× over the jerk limit on such arcs, it did not converge.)"""
    from planners.paths.gcode import parse_gcode, program_path
    path = program_path(parse_gcode("G21 G90 G64 P0.01\nG1 X-20 Y-20 Z-250 F1200\nX20\nY20\n"))
    sj, tp = plan("scurve_joint", path, KOSSEL), plan("toppra", path, KOSSEL)
    p = nlp(path, KOSSEL, sj)
    assert p.info["source"] == "nlp"
    assert all(st.startswith("Solve_Succeeded") for st in p.info["ipopt"])
    assert command_metrics(KOSSEL, path.point(p.s), p.T, p.s)["feasible"]
    assert tp.execution_time_s <= p.execution_time_s <= sj.execution_time_s


@pytest.mark.slow
def test_thin_grid_is_refined_before_the_margin_grows():
    """bird_kossel's 3 s pieces get 600 nodes (5 ms apart, 5× node_period_s): the first
    solution reads above the jerk limit at T between nodes.  Doubling the margin until it
    passed (0.04) cost 6 % over the toppra bound (15.936 s against 14.991 s); the refined grid
    passes at the first margin and ends within 3 % of it (15.392 s)."""
    from planners.paths import resolve_path
    from planners.scurve import plan_joint
    path = resolve_path("bird_kossel")
    p = nlp(path, KOSSEL, plan_joint(path, KOSSEL))
    assert p.info["source"] == "nlp" and p.info["margin"] == 0.005
    assert max(p.info["nodes"]) > 600
    assert command_metrics(KOSSEL, path.point(p.s), p.T, p.s)["feasible"]
    tp = plan("toppra", path, KOSSEL)
    assert tp.execution_time_s <= p.execution_time_s <= 1.03 * tp.execution_time_s


@pytest.mark.slow
def test_a_stop_at_a_blend_join_leaves_forward():
    """Blended within 0.04 mm, the corner's arc is so tight that the optimum stops at a join
    (ṡ = 0 at the node) and leaves it with s̈ < 0, s⃛ > 0: without ṡ ≥ 0 at the quarter points of
    the intervals at a join, ṡ dipped below 0 between a node and a midpoint that sat on 0, and
    sampling clipped s into a kink that read 1.54 × the jerk limit at T (2.69 × at P0.1), which
    no margin removes.  With them the solution passes the check."""
    from planners.paths.gcode import parse_gcode, program_path
    from planners.scurve import plan_joint
    path = program_path(parse_gcode("G21 G90 G64 P0.04\nG0 X-25 Y-25 Z-250\nG1 X25 F1200\nY25\nX-25\n"))
    p = nlp(path, KOSSEL, plan_joint(path, KOSSEL))
    assert command_metrics(KOSSEL, path.point(p.s), p.T, p.s)["feasible"]
    assert np.all(np.diff(p.s) >= 0)


@pytest.mark.parametrize("fast", [0, 1])
def test_broken_limits_names_the_piece_and_the_limit(fast):
    """A feed of 1.5 × F_max on one of two pieces and 0.5 × on the other: the feed is blamed
    on the fast piece only, so only its feed margin grows."""
    from types import SimpleNamespace
    z = KOSSEL.home[2]
    path = SegmentPath([Line([-20, 0, z], [0, 0, z]), Line([0, 0, z], [0, 20, z])])
    pcs = rest_pieces(path)
    assert len(pcs) == 2
    T, F = KOSSEL.servo_period_s, KOSSEL.limits.feed_max
    k = [1.5, 0.5] if fast == 0 else [0.5, 1.5]
    s = np.concatenate([np.arange(0, 20, k[0] * F * T), np.arange(20, 40, k[1] * F * T), [40.0]])
    out = optimal.broken_limits(KOSSEL, path, SimpleNamespace(T=T, s=s), pcs, KOSSEL.limits)
    assert (fast, "feed") in out and (1 - fast, "feed") not in out


@pytest.mark.slow
@pytest.mark.parametrize("midpoints", [False, True])
def test_midpoints_bound_a_and_j_between_nodes(midpoints):
    """keops' flower on 150 nodes (8 ms apart): the joint jerk q‴ṡ³ + 3q″ṡs̈ + q′s⃛ at each
    interval's midpoint (its state from the cubic, here in numpy) goes above the bound the
    nodes keep, unless the midpoints are bounded too (as a retry after such a check does).
    The joint derivatives are the NLP's own interpolants: the kinematics agree with them but
    where a NURBS knot makes q‴ jump between table rows."""
    from planners.paths import resolve_path
    from planners.scurve import plan_joint
    keops = load_machine("keops")
    path = resolve_path("flower")
    lim, m = keops.limits, 0.005
    table = optimal.PathTable(path, keops)
    piece = optimal._Piece(table, table_feed_cap(path, table, lim, keops.servo_period_s), 0.0,
                           path.length, lim, m, join_jumps(path, table, keops), keops.servo_period_s)
    piece.midpoints = midpoints
    start = optimal._warm_start(plan_joint(path, keops, lim), [0.0, path.length], 1e-3, 150, 1.02)
    (h, s, v, a, u), status, _ = piece.solve(*start, max_iter=600)   # to convergence, whatever the cap
    assert status == "Solve_Succeeded"
    hm = h / 2
    sm = s[:-1] + v[:-1] * hm + a[:-1] * hm ** 2 / 2 + u * hm ** 3 / 6
    vm, am = v[:-1] + a[:-1] * hm + u * hm ** 2 / 2, a[:-1] + u * hm
    fns = piece.phase_fns[0]
    d1, d2, d3 = (np.array([[float(fns[q][i](x)) for i in range(3)] for x in sm]) for q in ("q1", "q2", "q3"))
    jerk = np.abs(d3 * vm[:, None] ** 3 + 3 * d2 * (vm * am)[:, None] + d1 * u[:, None]).max() / lim.joint.j
    acc = np.abs(d2 * vm[:, None] ** 2 + d1 * am[:, None]).max() / lim.joint.a
    if midpoints:
        assert max(jerk, acc) <= (1 - m) * (1 + 1e-6)
    else:
        assert jerk > 1.0


@pytest.mark.slow
def test_flower_passes_with_a_and_j_bounded_between_nodes():
    """The whole retry: flower's first solution reads 1.04 × the jerk limit at T between nodes
    2 ms apart; the retries bound a and j at the midpoints and it passes, between toppra's
    bound and scurve_joint."""
    from planners.paths import resolve_path
    keops = load_machine("keops")
    from planners.scurve import plan_joint
    path = resolve_path("flower")
    p = nlp(path, keops, plan_joint(path, keops))
    assert p.info["source"] == "nlp" and p.info["midpoints"] == [True]
    assert command_metrics(keops, path.point(p.s), p.T, p.s)["feasible"]
    tp, sj = plan("toppra", path, keops), plan("scurve_joint", path, keops)
    assert tp.execution_time_s <= p.execution_time_s <= sj.execution_time_s


def zigzag():
    # 40 chords of a zigzag under G64 P0.01: each corner a blend arc, so 2 G1 joins a corner
    # (line → arc → line, q″ jumps at both) and 2·39 + 1 = 79 phases of 24 nodes > 1500
    from planners.paths.gcode import parse_gcode, program_path
    pts = [(-20 + i, 3.0 * (i % 2), -250.0) for i in range(41)]
    text = "G21 G90 G64 P0.01\nG0 X-20 Y0 Z-250\n" + "".join(
        f"G1 X{x:g} Y{y:g} F1200\n" for x, y, _ in pts[1:]) + "M2\n"
    return program_path(parse_gcode(text, "zigzag.ngc"))


def test_nlp_piece_over_the_node_budget_is_refused_naming_it():
    from planners.scurve import plan_joint
    path = zigzag()
    with pytest.raises(PlanningError) as e:
        nlp(path, KOSSEL, plan_joint(path, KOSSEL))
    msg = str(e.value)
    assert "piece 0 " in msg and "79 phases" in msg and "1896 nodes" in msg and "1500 nodes" in msg
    assert "G-code lines 3…42" in msg


def test_many_blend_joins_are_planned_within_the_limits():
    """The zigzag the NLP refuses: the SOCP plans it within the limits at T, its own profile
    (scurve_joint's, faster here because its samples at T straddle the µm blend arcs whose
    continuous limits the SOCP keeps, is never returned), above its bound."""
    path = zigzag()
    p = plan("optimal", path, KOSSEL)
    assert command_metrics(KOSSEL, path.point(p.s), p.T, p.s)["feasible"]
    assert p.info["source"] == "socp" and p.planner == "optimal"
    assert p.info["lower_bound_s"] <= p.execution_time_s


def test_a_profile_above_a_limit_is_solved_on_finer_stations_then_refused(monkeypatch):
    """Where the SOCP's profile reads above a limit at T the path is solved again on stations
    STATION_REFINEMENT times closer; where none passes, a PlanningError names the path and the
    limit, and no other planner's profile is returned."""
    path = vertical(10.0)
    lim = KOSSEL.limits
    double = MachineLimits(Limits(2 * lim.joint.v, 2 * lim.joint.a, 2 * lim.joint.j), lim.cartesian,
                           2 * lim.feed_max, lim.chord_error_mm)
    over = optimal.topp3.solve(path, KOSSEL, double, optimal.topp3.Settings("optimal"))   # above KOSSEL's
    good = optimal.topp3.solve(path, KOSSEL, lim, optimal.topp3.Settings("optimal"))
    grids = []
    monkeypatch.setattr(optimal, "SPACING_GAIN", math.inf)     # the halvings' own rule aside

    def solve(path_, machine, limits, settings, pieces=None):
        grids.append(settings.grid_mm)
        return over if len(grids) < 2 or settings.grid_mm > optimal.GRID_MM else good
    monkeypatch.setattr(optimal.topp3, "solve", solve)
    p = optimal.plan(path, KOSSEL, polish=False)
    coarse = optimal.GRID_MM * optimal.STATION_REFINEMENT       # repaired last, above a limit too: refused
    assert grids == [optimal.GRID_MM, optimal.GRID_MM / optimal.STATION_REFINEMENT, coarse]
    assert p.info["source"] == "socp" and p.info["grid_mm"] == grids[1] and np.array_equal(p.s, good.s)
    grids.clear()
    monkeypatch.setattr(optimal.topp3, "solve", lambda *a, **k: grids.append(a[3].grid_mm) or over)
    with pytest.raises(PlanningError, match=r"optimal: .*no profile within the limits at T.*joint (velocity|acceleration|jerk) [0-9.]+ × its limit"):
        optimal.plan(path, KOSSEL, polish=False)
    assert len(grids) == optimal.REFINE_LEVELS + 2 and grids[-1] == coarse


@pytest.mark.parametrize("costly, refined_faster, grids_run, returned", [
    (True, True, 2, "refined"),       # repairs cost 10 × REPAIR_COST: finer stations, faster: theirs
    (True, False, 2, "first"),        # ... no faster there: the first profile, the search ends
    (False, True, 1, "first"),        # repairs cost nothing: no finer stations
])
def test_costly_repairs_are_solved_again_on_finer_stations_and_the_faster_kept(monkeypatch, costly, refined_faster,
                                                                                grids_run, returned):
    """Where the SOCP's repairs cost more than REPAIR_COST of the time its stations allowed
    (continuous_time_s against station_relaxation_s) the path is solved again on stations
    STATION_REFINEMENT times closer; the faster profile within the limits is returned."""
    path = vertical(10.0)
    lim = KOSSEL.limits
    half = MachineLimits(Limits(lim.joint.v / 2, lim.joint.a / 2, lim.joint.j / 2), lim.cartesian,
                         lim.feed_max, lim.chord_error_mm)
    fast = optimal.topp3.solve(path, KOSSEL, lim, optimal.topp3.Settings("optimal"))
    slow = optimal.topp3.solve(path, KOSSEL, half, optimal.topp3.Settings("optimal"))
    assert slow.execution_time_s > fast.execution_time_s

    def with_cost(prof, cost):
        info = dict(prof.info, station_relaxation_s=prof.info["continuous_time_s"] / (1 + cost))
        return dataclasses.replace(prof, info=info)
    first = with_cost(slow if refined_faster else fast, 10 * optimal.REPAIR_COST if costly else 0.0)
    refined = with_cost(fast if refined_faster else slow, 0.0)
    # the halvings' own rule aside (the two profiles' station times are far apart):
    # test_stations_are_halved_while_the_last_halving_moved_their_time
    monkeypatch.setattr(optimal, "SPACING_GAIN", math.inf)
    grids = []

    def solve(path_, machine, limits, settings, pieces=None):
        grids.append(settings.grid_mm)
        if settings.grid_mm > optimal.GRID_MM:          # the coarse stations, repaired last: no faster
            return with_cost(slow, 0.0)
        return first if len(grids) == 1 else refined
    monkeypatch.setattr(optimal.topp3, "solve", solve)
    p = optimal.plan(path, KOSSEL, polish=False)
    assert grids == [optimal.GRID_MM / optimal.STATION_REFINEMENT ** k for k in range(grids_run)] + [
        optimal.GRID_MM * optimal.STATION_REFINEMENT]
    want = first if returned == "first" else refined
    assert np.array_equal(p.s, want.s) and p.info["grid_mm"] == grids[0 if returned == "first" else 1]


def test_lower_bound_below_the_optimum_on_a_curved_path():
    """keops' bird: the bound (velocity and acceleration only, each interval's worst case) lies
    below optimal's time and below toppra's jerk-free time, which drops only the jerk."""
    from planners.optimal.bound import lower_bound
    from planners.paths import resolve_path
    keops = load_machine("keops")
    path = resolve_path("bird")
    lb = lower_bound(path, keops, keops.limits)
    tp = plan("toppra", path, keops)
    assert 0 < lb <= tp.info["continuous_time_s"]


def test_turn_nodes_count_the_turned_angle():
    """∫κ ds over an arc is its angle θ: θ / NODE_RADII nodes, none on the lines either side."""
    from planners.constraints import PathTable
    from planners.paths import Arc
    R, th = 2.0, 1.5
    a = Arc([R, 0, -300], [0, 0, -300], [0, 0, 1], th)
    path = SegmentPath([Line([R, -5, -300], [R, 0, -300]), a, Line(a.end, a.end + 5 * a.tangent_out())])
    s, N = optimal.turn_nodes(path, PathTable(path, KOSSEL))
    assert N[-1] == pytest.approx(th / optimal.NODE_RADII, rel=1e-6)
    assert N[s <= 5.0 - 1e-6].max() == pytest.approx(0.0, abs=1e-9)


def test_warm_start_puts_the_turn_nodes_on_the_arc():
    """With the turn counted, the arc (1.5 rad) gets ≥ θ / NODE_RADII intervals of its own; without,
    the nodes are spread in time only."""
    from planners.constraints import PathTable
    from planners.paths import Arc
    from planners.scurve import plan_joint
    R, th = 0.5, 1.5
    a = Arc([R, 0, -300], [0, 0, -300], [0, 0, 1], th)
    path = SegmentPath([Line([R, -40, -300], [R, 0, -300]), a, Line(a.end, a.end + 40 * a.tangent_out())])
    warm = plan_joint(path, KOSSEL)
    turn = optimal.turn_nodes(path, PathTable(path, KOSSEL))
    lo, hi = 40.0, 40.0 + R * th
    for t, need in ((turn, th / optimal.NODE_RADII), (None, 0)):
        Ns, H, S, V, A, U = optimal._warm_start(warm, [0.0, path.length], 1e-3, 80, 1.02, t)
        on_arc = np.count_nonzero((S > lo) & (S < hi))
        assert len(H) == Ns.sum() and np.all(H > 0)
        assert on_arc >= need - 1
    assert on_arc < th / optimal.NODE_RADII - 1     # time-spread only: fewer than the turn asks


def test_slowed_down_scales_each_order_by_its_power(monkeypatch):
    """t → λt scales the joint velocity by 1/λ, the acceleration by 1/λ², the jerk by 1/λ³: a
    solution 1.3 × over a jerk limit comes back within it, λ ≈ 1.3^(1/3), its time × λ."""
    from planners.constraints import PathTable
    from planners.scurve import plan_joint
    path = vertical(10.0)
    lim = KOSSEL.limits
    table = PathTable(path, KOSSEL)
    T = KOSSEL.servo_period_s
    piece = optimal._Piece(table, table_feed_cap(path, table, lim, T), 0.0, path.length, lim, 0.0,
                           join_jumps(path, table, KOSSEL), T)
    sol, _, _ = piece.solve(*optimal._warm_start(plan_joint(path, KOSSEL), [0.0, path.length], 1e-3, 300, 1.02))
    prof = optimal.sample_cubic([sol], T, path, {})
    tight = MachineLimits(Limits(lim.joint.v, lim.joint.a, lim.joint.j / 1.3), lim.cartesian, lim.feed_max,
                          lim.chord_error_mm)
    r = command_metrics(KOSSEL, path.point(prof.s), T, prof.s)
    r["joint_peak_ratio"]["jerk"] *= 1.3
    out = optimal._slowed_down(KOSSEL, path, prof, rest_pieces(path), tight, [sol], r, T, [], math.inf)
    lam = out.info["slowed_down"][0]
    assert lam == pytest.approx(1.3 ** (1 / 3), rel=2e-3)
    assert out.info["continuous_time_s"] == pytest.approx(lam * prof.info["continuous_time_s"], rel=1e-9)
    after = command_metrics(KOSSEL, path.point(out.s), T, out.s)["joint_peak_ratio"]["jerk"]
    assert after * 1.3 <= 1 + 1e-6                       # within the tightened jerk limit
    # a slow-down past TOO_SLOW × its start is refused before any sample at T is made (a wild
    # solution's read of 10¹⁵ × a limit once asked for 7 GB of samples)
    r["joint_peak_ratio"]["jerk"] = 1e15
    sampled = []
    real = optimal.sample_cubic
    monkeypatch.setattr(optimal, "sample_cubic", lambda *a: sampled.append(1) or real(*a))
    with pytest.raises(PlanningError, match="more than 10 × its start's"):
        optimal._slowed_down(KOSSEL, path, prof, rest_pieces(path), tight, [sol], r, T, [],
                             optimal.TOO_SLOW * prof.execution_time_s)
    assert not sampled


def test_the_faster_of_the_solution_and_its_start_within_the_limits():
    """_faster_of keeps the NLP's profile unless its start, checked against the limits it is given,
    is faster; a start above a limit is never returned: with no solution the NLP's failure is raised."""
    path = vertical(10.0)
    fast = plan("scurve_joint", path, KOSSEL)
    slow = plan("scurve_joint", path, KOSSEL, margin=0.1)
    assert slow.execution_time_s > fast.execution_time_s
    out = optimal._faster_of(slow, fast, KOSSEL, path, KOSSEL.limits, None)
    assert out.planner == "optimal" and out.info["source"] == "warm start (scurve_joint)"
    assert np.array_equal(out.s, fast.s)
    assert optimal._faster_of(fast, slow, KOSSEL, path, KOSSEL.limits, None) is fast
    lim = KOSSEL.limits
    double = MachineLimits(Limits(2 * lim.joint.v, 2 * lim.joint.a, 2 * lim.joint.j), lim.cartesian,
                           2 * lim.feed_max, lim.chord_error_mm)
    over = plan("scurve_joint", path, KOSSEL, double)           # above KOSSEL's own limits
    assert not command_metrics(KOSSEL, path.point(over.s), over.T, over.s)["feasible"]
    with pytest.raises(PlanningError, match="IPOPT failed"):
        optimal._faster_of(None, over, KOSSEL, path, KOSSEL.limits, PlanningError("optimal: IPOPT failed on piece …"))
    assert optimal._faster_of(slow, over, KOSSEL, path, KOSSEL.limits, None) is slow
    # checked against the limits it is given: within the doubled ones, the faster start wins
    assert np.array_equal(optimal._faster_of(slow, over, KOSSEL, path, double, None).s, over.s)


@pytest.mark.parametrize("coarse, relaxations, grids_run", [
    (1.010, [1.000, 0.999], 2),     # the halving to grid_mm gained 1 %: once finer; that one 0.1 %: done
    (1.010, [1.000, 0.996, 0.995], 3),   # ... and the next 0.4 %: finer again, up to REFINE_LEVELS
    (1.001, [1.000], 1),            # 0.1 %: grid_mm's stations are kept
    (0.990, [1.000, 0.999], 2),     # the station time grew by 1 % (the limits between stations): finer
])
def test_stations_are_halved_while_the_last_halving_moved_their_time(monkeypatch, coarse, relaxations, grids_run):
    """The stations are solved again STATION_REFINEMENT times closer while the last halving moved
    their time (station_relaxation_s) by more than SPACING_GAIN either way, also where the
    repairs cost nothing; the fastest profile is returned with the gain it was refined for."""
    path = vertical(10.0)
    base = optimal.topp3.solve(path, KOSSEL, KOSSEL.limits, optimal.topp3.Settings("optimal"))
    monkeypatch.setattr(optimal.topp3, "station_time", lambda pieces, settings: coarse)
    grids, out = [], []

    def solve(path_, machine, limits, settings, pieces=None):
        r = relaxations[len(grids)] if settings.grid_mm <= optimal.GRID_MM else 2.0   # the coarse candidate: slower
        grids.append(settings.grid_mm)
        out.append(dataclasses.replace(base, info=dict(base.info, station_relaxation_s=r, continuous_time_s=r)))
        return out[-1]
    monkeypatch.setattr(optimal.topp3, "solve", solve)
    p = optimal.plan(path, KOSSEL, polish=False)
    finer = [optimal.GRID_MM / optimal.STATION_REFINEMENT ** k for k in range(grids_run)]
    # the coarse stations repaired, last: only where their time alone is below the best's (no faster here)
    tried = [optimal.GRID_MM * optimal.STATION_REFINEMENT] if coarse < min(relaxations[:grids_run]) else []
    assert grids == finer + tried and (coarse == 0.990) == bool(tried)
    assert p.info["grid_mm"] == finer[-1]
    previous = ([coarse] + relaxations)[grids_run - 1]
    assert p.info["spacing_gain"] == pytest.approx(1 - relaxations[grids_run - 1] / previous)


def test_the_coarse_stations_repaired_are_returned_where_they_are_the_fastest_within(monkeypatch):
    """The coarse stations (STATION_REFINEMENT × grid_mm, solved first for the finer solve's
    linearisation) are repaired at T too, and returned where that is faster within the limits
    (where many G1 joins read above at T the repairs can cost more on finer stations:
    docs/TUNING.md); where it reads above a limit at T it is never returned."""
    path = vertical(10.0)
    base = optimal.topp3.solve(path, KOSSEL, KOSSEL.limits, optimal.topp3.Settings("optimal"))
    for coarse_ok in (True, False):
        grids = []

        def solve(path_, machine, limits, settings, pieces=None):
            t = 0.9 if settings.grid_mm > optimal.GRID_MM else 1.0
            grids.append(settings.grid_mm)
            return dataclasses.replace(base, info=dict(base.info, station_relaxation_s=t, continuous_time_s=t))
        monkeypatch.setattr(optimal.topp3, "solve", solve)
        monkeypatch.setattr(optimal, "_within", lambda m, pa, prof, lim: (True, "") if coarse_ok or
                            prof.info["continuous_time_s"] == 1.0 else (False, "joint jerk 1.2 × its limit"))
        p = optimal.plan(path, KOSSEL, polish=False)
        assert grids[-1] == optimal.GRID_MM * optimal.STATION_REFINEMENT
        assert p.info["grid_mm"] == (grids[-1] if coarse_ok else optimal.GRID_MM)
        assert p.info["continuous_time_s"] == (0.9 if coarse_ok else 1.0) and p.info["source"] == "socp"


def _delayed_s(pieces, T, path, delay):
    """Arc lengths at t = kT of ``pieces`` (Profile.from_pieces') started ``delay`` s late,
    each evaluated at its own local time: the read of a servo clock at another phase."""
    starts = np.concatenate([[0.0], np.cumsum([g.duration for g in pieces])])
    t = np.arange(int(math.ceil((starts[-1] + delay) / T)) + 1) * T - delay
    s = np.zeros(len(t))
    k = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(pieces) - 1)
    for i, g in enumerate(pieces):
        m = (k == i) & (t >= 0)
        s[m] = g.s0 + g.at(np.minimum(t[m] - starts[i], g.duration))[0]
    s = np.minimum(np.maximum.accumulate(s), path.length)
    s[-1] = path.length
    return s


def test_read_phases_hold_the_joint_jerk_at_every_phase_they_read(monkeypatch):
    """A G64 square's blend joins read at T at the one phase of the harness's clock are
    repaired there only; the SOCP's window rows (topp3.Settings.window_reads) hold every phase
    but to their linearisation: with its start ¼–¾ T late the same profile reads up to 1.0016 × J
    (1.04 × J with the rows at the graded stations before them). With read_phases=4 the
    repairs read four phases and every one holds J, at the same time."""
    from planners.paths.gcode import parse_gcode, program_path
    from planners.profile import Profile
    path = program_path(parse_gcode("G21 G90 G64 P0.04\nG0 X-25 Y-25 Z-250\nG1 X25 F1200\nY25\nX-25\n"))
    made = []
    original = Profile.from_pieces.__func__

    def spy(cls, planner, T, pieces, path, info=None):
        made.append((list(pieces), out := original(cls, planner, T, pieces, path, info)))
        return out

    monkeypatch.setattr(Profile, "from_pieces", classmethod(spy))
    worst, times = {}, {}
    for phases in (1, 4):
        made.clear()
        p = plan("optimal", path, KOSSEL, read_phases=phases)
        pieces = next(pc for pc, out in reversed(made) if np.array_equal(out.s, p.s))
        times[phases] = p.execution_time_s
        worst[phases] = [command_metrics(KOSSEL, path.point(s), p.T, s)["joint_peak_ratio"]["jerk"]
                         for s in (_delayed_s(pieces, p.T, path, d * p.T) for d in (0, 0.25, 0.5, 0.75))]
    assert 1 + 1e-4 < max(worst[1]) <= 1.003, worst[1]   # the path exercises the phase
    assert max(worst[4]) <= 1 + 1e-6, worst[4]
    assert times[4] == pytest.approx(times[1], rel=1e-3)


@pytest.mark.parametrize("bad", [0, 2.5, True, "4"])
def test_read_phases_not_a_positive_integer_is_refused(bad):
    with pytest.raises(PlanningError, match="read_phases"):
        plan("optimal", vertical(), KOSSEL, read_phases=bad)
