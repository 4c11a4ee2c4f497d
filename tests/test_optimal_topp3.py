"""copp reference (COPP's TOPP3-SOCP): the 1-D jerk-limited closed form where every joint moves
like s, feasibility at T and the order against toppra (the jerk-free lower bound), errors."""
import dataclasses
import math

import numpy as np
import pytest
import ruckig

import planners.optimal.topp3 as topp3
from kins import Limits, MachineLimits, load_machine
from planners import PlanningError, plan
from planners.constraints import PathTable
from planners.optimal import planner as optimal
from planners.paths import Arc, Line, SegmentPath, resolve_path
from planners.verify import command_metrics
from test_planner_claims import short_path

KOSSEL = load_machine("kossel")
KEOPS = load_machine("keops")
TOL = 1 + 1e-6


def rest_to_rest_time(L, V, A, J):
    """Minimum time of a 1-D rest-to-rest move of length L under |v| ≤ V, |a| ≤ A, |j| ≤ J when
    neither A nor V is reached within the jerk phases' limits checked below: the cruise at V
    after jerk-only ramps of 2√(V/J) (valid while V·J ≤ A² and L ≥ V·2√(V/J))."""
    assert V * J <= A * A and L >= 2 * V * math.sqrt(V / J)
    return L / V + 2 * math.sqrt(V / J)


def test_vertical_line_on_a_linear_delta_is_the_1d_jerk_limited_optimum():
    """On a linear delta a vertical move drives every joint exactly like z (q′ = 1, q″ = q‴ = 0)
    and the feed cap F_max equals V: the minimum time is the 1-D jerk-limited rest-to-rest
    optimum, here in closed form (V·J = 2·10⁵ ≤ A² = 2.5·10⁵: A is never reached) and from
    ruckig as a second method."""
    L = 30.0
    lim = KOSSEL.limits.joint                                   # 20 mm/s, 500 mm/s², 10⁴ mm/s³
    exact = rest_to_rest_time(L, lim.v, lim.a, lim.j)           # 1.5894 s
    inp = ruckig.InputParameter(1)
    inp.current_position, inp.target_position = [0.0], [L]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [lim.v], [lim.a], [lim.j]
    traj = ruckig.Trajectory(1)
    ruckig.Ruckig(1).calculate(inp, traj)
    assert traj.duration == pytest.approx(exact, rel=1e-9)
    p = plan("copp", SegmentPath([Line([0, 0, -300], [0, 0, -300 + L])]), KOSSEL)
    T = KOSSEL.servo_period_s
    r = command_metrics(KOSSEL, p.path.point(p.s), T, p.s)
    assert r["feasible"] and r["cartesian_peak_ratio"]["feed"] <= TOL
    # no faster than the optimum (the check at T may let a sampled profile gain < T), and
    # within the 0.1 mm grid's loss (measured 0.16 %)
    assert exact - T <= p.execution_time_s <= exact * 1.003 + T


@pytest.mark.parametrize("machine", [KEOPS, KOSSEL], ids=["keops", "kossel"])
def test_short_path_feasible_at_T_and_no_faster_than_toppra(machine):
    """A line, a tangent arc (a G1 join), a line, an exact-stop corner: every joint limit and the
    feed within bounds at T, and the jerk limit costs time against toppra's jerk-free bound."""
    path = short_path(machine)
    p = plan("copp", path, machine)
    r = command_metrics(machine, path.point(p.s), p.T, p.s)
    assert r["feasible"], r["joint_peak_ratio"]
    assert r["cartesian_peak_ratio"]["feed"] <= TOL
    assert p.info["above_at_T"] == 0 and p.info["pieces"] == 2
    assert p.execution_time_s > plan("toppra", path, machine).execution_time_s


@pytest.mark.slow
def test_bird_on_keops_feasible_and_between_toppra_and_optimal():
    """The standard path: feasible at T; toppra (no jerk limit) is faster; the jerk-limited
    optimum (`optimal`, 1.76575 s in results/baseline.json) within 0.5 % (the grid's loss)."""
    path = resolve_path("bird")
    p = plan("copp", path, KEOPS)
    r = command_metrics(KEOPS, path.point(p.s), p.T, p.s)
    assert r["feasible"], r["joint_peak_ratio"]
    assert r["cartesian_peak_ratio"]["feed"] <= TOL
    assert plan("toppra", path, KEOPS).execution_time_s < p.execution_time_s
    assert p.execution_time_s == pytest.approx(1.76575, rel=5e-3)


def test_limit_not_positive():
    lim = KEOPS.limits
    bad = MachineLimits(Limits(lim.joint.v, lim.joint.a, 0.0), lim.cartesian, lim.feed_max, lim.chord_error_mm)
    with pytest.raises(PlanningError, match="copp: joint limit j = 0.0 must be a finite number > 0"):
        plan("copp", SegmentPath([Line([0, 0, -400], [10, 0, -400])]), KEOPS, bad)


@pytest.mark.parametrize("grid", [0.0, -1.0, float("nan"), "0.1"])
def test_bad_grid(grid):
    with pytest.raises(PlanningError, match="copp: grid_mm = .* must be a finite number > 0"):
        plan("copp", SegmentPath([Line([0, 0, -400], [10, 0, -400])]), KEOPS, grid_mm=grid)


def test_solver_failure_names_the_piece(monkeypatch):
    """A failure of the engine's solvers (the IPM, then Clarabel on the same rows) is a
    PlanningError naming the rest-to-rest piece and the cause."""
    def no_solution(*_a, **_k):
        raise topp3.ipm.NoSolution("no convergence")

    def fail(*_a, **_k):
        raise topp3.copp.CoppError("topp3_socp reported a failure in Clarabel solver with status MaxIterations")
    monkeypatch.setattr(topp3.ipm, "solve", no_solution)
    monkeypatch.setattr(topp3.copp.solver.topp3_socp, "solve_expert", fail)
    c = KEOPS.home
    path = SegmentPath([Line(c, c + np.array([10.0, 0, 0])), Line(c + np.array([10.0, 0, 0]), c + np.array([10.0, 8, 0]))])
    with pytest.raises(PlanningError, match=r"copp: no solution of piece 0 \(s = 0…10 mm\): CoppError: .*MaxIterations"):
        plan("copp", path, KEOPS)


def test_a_stop_inside_a_piece_gets_s_double_dot_zero():
    """Five stations of kossel/test_part's SOCP profile around a blend join where it stops
    (a = 3·10⁻¹⁰) with a round-off b = −6·10⁻⁸: copp's time map is NaN there; with s̈ = 0 at the
    stop (_stops_at_rest) it is finite, and nothing else moves."""
    s = np.array([0.0, 0.011100381273053017, 0.022200762546106034, 0.03168135703579367, 0.0411619515254813])
    a = np.array([0.006523849746075891, 0.001763219172480894, 2.9998583642125146e-10,
                  0.0007065829169277021, 0.0017255190110691658])
    b = np.array([-0.2700278489204022, -0.1588430570958467, -6.31863824898243e-08, 0.07452942078401634,
                  0.03294654976291122])
    prof = topp3.copp.Profile3rd(a, b, (0, 0))
    with pytest.raises(topp3.copp.CoppError, match="NaN"):
        topp3.copp.interpolation.s_to_t_topp3(s, prof)
    fixed = topp3._stops_at_rest(prof)
    assert fixed.b[2] == 0.0 and np.array_equal(np.delete(fixed.b, 2), np.delete(b, 2))
    assert np.array_equal(fixed.a, a)
    tf, _ = topp3.copp.interpolation.s_to_t_topp3(s, fixed)
    assert math.isfinite(tf) and tf > 0
    moving = topp3.copp.Profile3rd(a + 0.01, b, (0, 0))
    assert topp3._stops_at_rest(moving) is moving


def test_repair_windows_reach_the_speed_valleys_and_merge():
    """A window covers its changed stations and the margin either side, then reaches out to
    the next local minimum of a on each side (a braking phase is never cut); windows that
    meet are merged."""
    grid = np.arange(100.0)
    a = 1.0 + np.cos(grid * 2 * np.pi / 25)          # valleys at 13, 38, 63, 88 (and the ends)
    changed = np.zeros(100, bool)
    changed[[30, 80]] = True
    assert topp3._windows(changed, grid, a, 2.0, 1) == [(13, 38), (63, 88)]
    changed[[45]] = True                             # 45 ± 10 spans the valley at 38: merged
    assert topp3._windows(changed, grid, a, 10.0, 1) == [(13, 99)]
    assert topp3._windows(np.zeros(100, bool), grid, a, 2.0, 1) == []


def test_a_stations_tightening_extra_doubles_with_its_own_repairs_not_the_round():
    """A window read at ratio r tightens its limit at the stations under it (and one either
    side) to factor / (r·(1 + e·2^n)), n the times that station's limit was tightened before:
    a window first read in a late round is tightened by e, not by e·2^round (doubled per round,
    the reads of many G1 joins compounded instead of converging: docs/TUNING.md).  The other
    limits are left alone."""
    grid = np.arange(0.0, 10.01, 1.0)
    p = topp3.Piece.__new__(topp3.Piece)
    p.grid, p.s0 = grid, 0.0
    p.factor = np.ones((len(grid), len(topp3.LIMIT_COLUMNS)))
    p.times_tightened = np.zeros_like(p.factor, dtype=int)
    p.changed = np.zeros(len(grid), bool)
    p.span = "solved"
    e, jerk = topp3.TIGHTEN_EXTRA, 2
    topp3._tighten([p], [(jerk, 2.0, 2.0, 1.1)], e)          # round 0: stations 1…3
    assert p.factor[1:4, jerk] == pytest.approx(1 / (1.1 * (1 + e)))
    assert p.factor[0, jerk] == 1 and np.all(p.factor[4:, jerk] == 1) and np.all(p.factor[:, [0, 1, 3]] == 1)
    assert p.span is None and p.changed[1:4].all() and not p.changed[4:].any()
    topp3._tighten([p], [(jerk, 8.0, 8.0, 1.05)], e)         # round 1: fresh stations 7…9
    assert p.factor[7:10, jerk] == pytest.approx(1 / (1.05 * (1 + e)))
    topp3._tighten([p], [(jerk, 2.0, 2.0, 1.02)], e)         # round 2: stations 1…3 again
    assert p.factor[1:4, jerk] == pytest.approx(1 / (1.1 * (1 + e) * 1.02 * (1 + 2 * e)))
    assert list(p.times_tightened[:, jerk]) == [0, 2, 2, 2, 0, 0, 0, 1, 1, 1, 0]


def test_a_reference_at_the_fixed_point_ends_the_linearisations_after_one_solve(monkeypatch):
    """From TOPP2-RA's profile the SCP takes ≥ 2 solves (the gain of the second decides); from
    a reference that is already its fixed point (the converged solution) the first solve moves
    the reference's time by < lin_tol and ends them, at the same profile."""
    path = SegmentPath([Line([0, 0, -300], [0, 0, -300 + 30.0])])
    settings = topp3.Settings("copp")
    solves = []
    real = topp3.Piece._socp
    monkeypatch.setattr(topp3.Piece, "_socp", lambda self, *a, **k: solves.append(1) or real(self, *a, **k))
    piece, = topp3.pieces_of(path, KOSSEL, KOSSEL.limits, settings)
    first, _ = piece.solve(settings)
    assert len(solves) >= 2
    again, = topp3.pieces_of(path, KOSSEL, KOSSEL.limits, settings)
    again.reference = first.a
    solves.clear()
    prof, _ = again.solve(settings)
    assert len(solves) == 1
    # within the solves' own tolerance (ipm.TOL on the residuals: the last of ``first``'s solves,
    # warm-started, ends 2.5e-6 from where a cold start ends)
    assert np.allclose(prof.a, first.a, rtol=1e-5, atol=1e-9 * first.a.max())


@pytest.mark.parametrize("machine", [KEOPS, KOSSEL], ids=["keops", "kossel"])
def test_linearisation_cost_predicts_the_next_solves_gain(machine, monkeypatch):
    """short_path (a line, a G1 arc, a line, a corner), five linearisations from TOPP2-RA's
    profile with no stop: the gain of each solve lies within 0.1–4 × linearisation_cost of the
    solve before it (where that predicts ≥ 1e-5; measured 0.94–2.31 ×, and 1.5–3.2 × since the
    G1 joins' reads are signed: their rows' tangent of κ√a, on the side the read adds to the
    jerk, is a linearisation the prediction leaves out, and the arc's joins are now passed
    faster).  Its ε is the tangent's shortfall: J/√a
    against f(a_lin) + f′(a_lin)(a − a_lin), f = 1/√a, by derivative.  With lin_predicted the
    linearisations stop at the first solve predicting less, within 3 × that of the time the five reach."""
    r = np.array([0.5, 0.9, 1.0, 1.1, 2.0])
    tangent = 1 + (-0.5) * (r - 1)                      # f(1) + f′(1)(r − 1), a_lin = 1
    eps = 1 - tangent * np.sqrt(r)
    ts = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    w = np.array([1, 2, 2, 2, 1.0]) / 8
    assert topp3.linearisation_cost(np.ones(5), r, ts) == pytest.approx(np.sum(eps * w) / 3, rel=1e-12)
    path = short_path(machine)
    full = topp3.Settings("copp", 0.1, lin_tol=0.0, max_linearisations=5)
    log = []
    real = topp3.Piece._socp

    def logged(self, rob, a_lin, *a, **k):
        prof, start = real(self, rob, a_lin, *a, **k)
        _, tf, ts = self._timed(prof)
        log.append((self.k, tf, topp3.linearisation_cost(a_lin, prof.a, ts)))
        return prof, start

    monkeypatch.setattr(topp3.Piece, "_socp", logged)
    t_full = topp3.station_time(topp3.pieces_of(path, machine, machine.limits, full), full)
    checked = 0
    for (k0, t0, predicted), (k1, t1, _) in zip(log, log[1:]):
        if k0 == k1 and predicted >= 1e-5:
            assert 0.1 * predicted <= (t0 - t1) / t1 <= 4 * predicted
            checked += 1
    assert checked >= 4
    log.clear()
    stop = dataclasses.replace(full, lin_predicted=1e-4)
    t_stop = topp3.station_time(topp3.pieces_of(path, machine, machine.limits, stop), stop)
    assert len(log) < 5 * len(topp3.rest_pieces(path))
    assert t_full <= t_stop <= t_full * (1 + 3e-4)


def test_speed_stations_hold_the_jerk_limited_start_from_rest():
    """b = s̈ is linear in s on a cell, so s⃛ = ṡ·db/ds follows ṡ across it and the jerk limit,
    held at both ends, binds at the faster end only.  On a 5 mm vertical move (the 1-D closed
    form; its jerk-only ramps, 2·2√(V/J) = 0.18 s, are half its time) uniform stations stay above
    the optimum at every spacing, the more so the finer (0.23 % at 0.05 mm, 0.46 % at 0.003 mm:
    the cell from rest, one constant jerk, shrinks with them); split where a coarser solve's ṡ
    changes by more than SPEED_STEP and graded toward the rest ends, within 0.1 %."""
    L = 5.0
    lim = KOSSEL.limits.joint
    exact = rest_to_rest_time(L, lim.v, lim.a, lim.j)               # 0.33944 s
    path = SegmentPath([Line([0, 0, -300], [0, 0, -300 + L])])

    def station_time(settings):
        return topp3.station_time(topp3.pieces_of(path, KOSSEL, KOSSEL.limits, settings), settings)

    for grid_mm in (0.05, 0.0125):
        assert station_time(optimal._settings(grid_mm, 1)) > exact * 1.002
    coarse = optimal._settings(optimal.GRID_MM, 0.5)
    solved = topp3.pieces_of(path, KOSSEL, KOSSEL.limits, coarse)
    topp3.station_time(solved, coarse)
    extra = topp3.speed_stations(solved)
    t = station_time(optimal._settings(optimal.GRID_MM, 1, (), extra))
    # a restriction of the 1-D problem: never below the optimum
    assert exact * (1 - 1e-6) <= t <= exact * 1.001
    p = plan("optimal", path, KOSSEL)
    assert p.info["source"] == "socp" and p.info["continuous_time_s"] <= exact * 1.001


def test_speed_squared_at_follows_copps_time_map_between_and_below_the_stations():
    """topp3.speed_squared_at (the first linearisation of a finer grid, linearise_around) against
    a second method: ṡ from finite differences of copp's own s(t) (t_to_s_topp3_samples) on a 5 mm
    vertical move from rest to rest on kossel's 0.1 mm stations.  Its model (quadratic in a cell,
    ∝ x^(4/3) in the constant-jerk cells at the ends) is within 0.1 % of the top speed everywhere;
    ṡ² linear between stations is off by 4 %, in the cells at rest."""
    import copp_py as copp
    path = SegmentPath([Line([0, 0, -300], [0, 0, -295])])
    coarse = optimal._settings(optimal.GRID_MM, 0.5)
    q = topp3.pieces_of(path, KOSSEL, KOSSEL.limits, coarse)
    topp3.station_time(q, coarse)
    q = q[0]
    prof, _, ts = q._timed(q.relaxed)
    assert prof.num_stationary == (1, 1)
    grid = q.grid - q.s0
    u = np.linspace(0.0, ts[-1], 20001)
    s = copp.interpolation.t_to_s_topp3_samples(grid, prof, ts, u)
    sd, mid = np.diff(s) / np.diff(u), (s[1:] + s[:-1]) / 2
    model = np.sqrt(topp3.speed_squared_at(grid, prof, mid))
    linear = np.sqrt(np.interp(mid, grid, prof.a))
    assert np.max(np.abs(model - sd)) < 1e-3 * sd.max()
    assert np.max(np.abs(linear - sd)) > 1e-2 * sd.max()


def test_a_finer_grid_linearised_around_a_coarser_solution_reaches_its_fixed_point_in_fewer_solves(monkeypatch):
    """A line, a G1 arc, a line and a corner on kossel: stations twice as close, their first
    linearisation around the coarse grid's solution (topp3.linearise_around), reach the time
    the same stations reach from TOPP2-RA's profile within lin_tol, in fewer SOCP solves;
    station_time is that solution's time."""
    path = short_path(KOSSEL)
    coarse, fine = topp3.Settings("copp", 0.2), topp3.Settings("copp", 0.1)
    solves = []
    real = topp3.Piece._socp
    monkeypatch.setattr(topp3.Piece, "_socp", lambda self, *a, **k: solves.append(1) or real(self, *a, **k))
    cold = topp3.pieces_of(path, KOSSEL, KOSSEL.limits, fine)
    t_cold = topp3.station_time(cold, fine)
    n_cold = len(solves)
    first = topp3.pieces_of(path, KOSSEL, KOSSEL.limits, coarse)
    t_coarse = topp3.station_time(first, coarse)
    warm = topp3.pieces_of(path, KOSSEL, KOSSEL.limits, fine)
    topp3.linearise_around(warm, first)
    solves.clear()
    t_warm = topp3.station_time(warm, fine)
    assert len(solves) < n_cold
    assert t_warm == pytest.approx(t_cold, rel=fine.lin_tol)
    assert t_warm < t_coarse
    # station_time is the time solve() reports for the stations alone
    prof = topp3.solve(path, KOSSEL, KOSSEL.limits, fine)
    assert prof.info["station_relaxation_s"] == pytest.approx(t_cold, rel=1e-12)


def test_knot_cells_where_the_false_cap_binds_hold_each_sides_jerk():
    """rand_3d_lcnc (a cubic NURBS: q‴ jumps at every knot) on 0.4 mm stations.  binding_knots
    lists the knots where the solved speed reaches KNOT_CAP_SHARE of (2J/max|Δq‴|)^⅓, Δq‴ here
    from second differences of q″ either side (a second method); with knot_cells each such knot
    is a station with one KNOT_CELL_MM either side, and the cells beside those hold the jerk
    with their own side's derivatives."""
    from harness.corpus.run import CORPUS_DIR
    from planners.constraints import interior_knots, joint_derivs
    lcnc = load_machine("linuxcnc_delta")
    path = resolve_path(str(CORPUS_DIR / "rand_3d_lcnc.json"), home=lcnc.home)
    coarse = topp3.Settings("copp", 0.4)
    pieces = topp3.pieces_of(path, lcnc, lcnc.limits, coarse)
    topp3.station_time(pieces, coarse)
    knots = np.array(topp3.binding_knots(pieces, path, lcnc, lcnc.limits))
    assert 0 < len(knots) < len(interior_knots(path))
    d = 1e-4
    q2 = [joint_derivs(lcnc, path, knots + o, fit_scale=True)[2] for o in (-2 * d, -d, d, 2 * d)]
    jump = np.abs((q2[3] - q2[2]) / d - (q2[1] - q2[0]) / d).max(axis=1)
    cap = np.cbrt(2 * lcnc.limits.joint.j / jump)
    p, = pieces
    speed = np.sqrt(np.interp(knots, p.grid, p.relaxed.a)) / p.tu
    assert np.all(speed >= topp3.KNOT_CAP_SHARE * cap * (1 - 1e-2))
    cells = topp3.Settings("copp", 0.4, knot_cells=tuple(knots))
    q, = topp3.pieces_of(path, lcnc, lcnc.limits, cells)
    topp3.station_time([q], cells)
    i = np.searchsorted(q.grid, knots)
    assert np.allclose(q.grid[i], knots, atol=1e-12)
    assert np.allclose(q.grid[i + 1] - q.grid[i], topp3.KNOT_CELL_MM) and np.allclose(q.grid[i] - q.grid[i - 1], topp3.KNOT_CELL_MM)
    a, b = q.relaxed.a, q.relaxed.b
    c = np.diff(b) / np.diff(q.grid)
    _, d1, d2, d3 = q.deriv
    for st, cell in [(k, cl) for j in i for k, cl in ((j - 1, j - 2), (j + 1, j + 1))]:
        jerk = np.sqrt(a[st]) * (d3[st] * a[st] + 3 * d2[st] * b[st] + d1[st] * c[cell])
        assert np.abs(jerk).max() <= q.lims[2] * (1 + 1e-6)


def test_join_grading_makes_the_socp_time_the_profiles_time(tmp_path):
    """Three G64 P0.01 corners (33°, 90°, 127°) on keops, where the feed falls near 0: without
    graded stations the line's 0.05 mm cell beside each blend left a(s) one quadratic from ~0,
    whose time (copp's exact time map: a log) the SOCP's chord time 2Δs/(√a₀ + √a₁) missed by
    up to 66 % in a cell; with them (Settings.join_grading) the two agree within 0.5 % over the
    piece and 5 % in any cell, and the profile is faster.  The graded stations: the cells either
    side of a join no wider than the travel in one period at its cap or its smaller cell, and
    each cell of a graded run ≤ 2 × the one before (the last ≤ 2 × it + the first's half)."""
    f = tmp_path / "corners.ngc"
    f.write_text("G21 G90 G17 G64 P0.01\nG0 X-10 Y-6 Z-400\nF60000\nG1 X-8 Y-6\nG1 X1 Y0\nG1 X1 Y8\n"
                 "G1 X-5 Y0\nM2\n")
    path = resolve_path(str(f), home=KEOPS.home)
    out = {}
    for graded in (False, True):
        st = topp3.Settings("optimal", 0.05, station_radii=0.05, join_grading=graded)
        (p,) = topp3.pieces_of(path, KEOPS, KEOPS.limits, st)
        prof, ts = p.solve(st)
        r = np.sqrt(np.maximum(prof.a, 0.0))
        chord = 2 * np.diff(p.grid) / (r[:-1] + r[1:])
        h0, h1 = prof.num_stationary                   # copp's constant-jerk start and stop
        inner = slice(h0, len(chord) - h1)
        ratio = np.diff(ts)[inner] / chord[inner]
        out[graded] = (ts[-1] * p.tu, np.diff(ts)[inner].sum() / chord[inner].sum(), ratio.max(), p)
    assert len(out[True][3].joins) == 6
    assert out[False][2] > 1.3                          # measured 1.66
    assert out[True][1] < 1.005 and out[True][2] < 1.05
    assert out[True][0] < out[False][0] * 0.98          # measured 0.3075 against 0.3207 s
    p, old = out[True][3], out[False][3].grid
    travel = p._join_travel(path, KEOPS.limits, KEOPS.servo_period_s)
    for (i, *_), v in zip(p.joins, travel):
        sj = p.grid[i]
        k = int(np.searchsorted(old, sj))
        for end in (old[k - 1], old[k + 1]):           # the old cells either side of the join
            run = np.sort(np.abs(p.grid[(p.grid >= min(sj, end)) & (p.grid <= max(sj, end))] - sj))
            cells = np.diff(run)
            assert cells[0] <= max(v, topp3.GRADED_MIN_MM) * (1 + 1e-9)
            # doubling offsets h·2^k kept while < room − h/2: every cell ≤ 2 × the one before,
            # the last (to the old station) ≤ 2 × it + h/2, so ≤ 2.5 × it
            assert np.all(cells[1:-1] <= 2 * cells[:-2] * (1 + 1e-9))
            assert len(cells) == 1 or cells[-1] <= 2 * cells[-2] + cells[0] / 2 + 1e-12
    # the join's read, weighted, at every other station within 1.5 periods' travel of it
    near = {(i, k) for (i, *_), v in zip(p.joins, travel) for k in range(len(p.grid))
            if 0 < abs(p.grid[k] - p.grid[i]) < 1.5 * v}
    assert len(p.join_reads) == len(p.joins) + len(near) > len(p.joins)


def test_a_join_s_read_carries_the_sign_of_its_jump():
    """At a line → arc join P and P′ are continuous and P″ jumps by n/ρ, so q″ jumps by J(P)·n/ρ
    (J(P) the IK's Jacobian, here along n by a central difference); at the arc → line join by
    minus that.  A third difference at T reads the jump with its sign, so each join's κ per joint
    is JUMP_READ_FACTOR·Δq″/T (scaled time) with that sign, not its size alone."""
    from planners.constraints import JUMP_READ_FACTOR
    rho = 0.5
    c = np.array([-13.0, -10.0, -252.0])
    a = Line(c + [-5.0, rho, 0.0], c + [0.0, rho, 0.0])
    arc = Arc(a.end, c, [0.0, 0.0, -1.0], math.pi / 2)      # clockwise: tangent to the line
    path = SegmentPath([a, arc, Line(arc.end, arc.end + [0.0, -5.0, 0.0])], "line-arc-line")
    st = optimal._settings(optimal.GRID_MM, 1)
    (p,) = topp3.pieces_of(path, KOSSEL, KOSSEL.limits, st)
    assert len(p.joins) == 2
    T_scaled = KOSSEL.servo_period_s / p.tu
    eps = 1e-6
    for (i, *_, kappa), s_join, sign in zip(p.joins, (5.0, 5.0 + rho * math.pi / 2), (1.0, -1.0)):
        assert p.grid[i] == pytest.approx(s_join, abs=1e-9)
        P = path.point(np.array([s_join]))[0]
        n = (c - P) * [1, 1, 0] / rho                        # toward the arc's centre
        jac_n = (KOSSEL.ik((P + eps * n)[None]) - KOSSEL.ik((P - eps * n)[None]))[0] / (2 * eps)
        np.testing.assert_allclose(kappa, sign * JUMP_READ_FACTOR * jac_n / rho / T_scaled, rtol=1e-3)
        assert (np.sign(kappa) == sign * np.sign(jac_n)).all()


def test_read_weight_is_the_third_difference_of_a_second_derivative_jump():
    """third_difference_weight(u): a unit jump of f″ at u periods into the window [0, 3] reads in
    the third difference f(3) − 3f(2) + 3f(1) − f(0) of f = ½(t − u)₊² as this weight (T = 1):
    computed here directly; 0.75 at the centre (JUMP_READ_FACTOR), 0 at the window's ends.
    join_read_weight(d) is the window centred d periods from the jump, relative to the centre's."""
    from planners.constraints import READ_REACH, join_read_weight, third_difference_weight
    f = lambda t, u: 0.5 * max(t - u, 0.0) ** 2
    for u in np.linspace(0.0, 3.0, 31):
        third = f(3, u) - 3 * f(2, u) + 3 * f(1, u) - f(0, u)
        assert third_difference_weight(u) == pytest.approx(third, abs=1e-12)
        d = u - READ_REACH
        assert join_read_weight(d) == pytest.approx(third / topp3.JUMP_READ_FACTOR, abs=1e-12)
    assert third_difference_weight(1.5) == pytest.approx(topp3.JUMP_READ_FACTOR)


def test_read_slack_spares_the_reads_inside_the_planners_margin(monkeypatch):
    """`optimal` hands the engine its limits less CHAIN_MARGIN and lets its samples at T use
    half of it (Settings.read_slack).  On the short keops path the first solve's samples read
    the inner acceleration limit above 1 by a few 10⁻⁶ only: without the slack a round of
    tightening chases them (on rose3_keops_tilted eight rounds crept along a plateau and cost
    0.08 %); with it none is made, and the profile, no slower, is within the machine's limits."""
    from planners.optimal.planner import CHAIN_MARGIN, GRID_MM, STATION_RADII
    path = short_path(KEOPS)
    inner = KEOPS.limits.joint_scaled(1 - CHAIN_MARGIN)
    reads, real = [], topp3.reads_above
    monkeypatch.setattr(topp3, "reads_above", lambda *a: reads.append(real(*a)) or reads[-1])
    runs = {}
    for slack in (CHAIN_MARGIN / 2, 0.0):
        settings = topp3.Settings("optimal", GRID_MM, station_radii=STATION_RADII, join_grading=True,
                                  read_slack=slack)
        reads.clear()
        runs[slack] = topp3.solve(path, KEOPS, inner, settings)
    first = reads[0]            # the strict engine's first reads (the first solve is the same)
    strict, spared = runs[0.0], runs[CHAIN_MARGIN / 2]
    assert strict.info["tightened"], "the strict engine should have read above the inner limits"
    assert first and max(r for *_, r in first) <= 1 + CHAIN_MARGIN / 2
    assert spared.info["tightened"] == [] and spared.info["above_at_T"] == 0
    assert spared.info["continuous_time_s"] <= strict.info["continuous_time_s"]
    r = command_metrics(KEOPS, path.point(spared.s), spared.T, spared.s)
    assert r["feasible"] and max(r["joint_peak_ratio"].values()) <= 1 - CHAIN_MARGIN / 4
    # F_max has no margin, so no slack (given one, rand_edge_kossel's samples read F_max above
    # 1 + 1e-6 at every station spacing and `optimal` had no profile)
    read = topp3._read_limits(inner, CHAIN_MARGIN / 2)
    assert read.feed_max == inner.feed_max and read.joint.j == pytest.approx(inner.joint.j * (1 + CHAIN_MARGIN / 2))


def test_midpoint_cap_stops_the_feed_chattering_at_F_max():
    """On the vertical kossel line the feed cruises at F_max = V.  Held at the stations alone,
    the SOCP's b chatters there (±b at alternate stations), each cell's middle bulges above the
    cap and the first solve's samples read F_max above 1 along the cruise; with the cap also at
    the cells' middles (Settings.midpoint_cap, `optimal`'s) none does, for the same time within
    10⁻⁵, and that time is the 1-D closed form's within the grid's loss."""
    path = SegmentPath([Line([0, 0, -300], [0, 0, -270])])
    lim = KOSSEL.limits.joint
    exact = rest_to_rest_time(30.0, lim.v, lim.a, lim.j)
    first = {}
    for mid in (False, True):
        settings = topp3.Settings("optimal", 0.05, join_grading=True, midpoint_cap=mid)
        pieces = topp3.pieces_of(path, KOSSEL, KOSSEL.limits, settings)
        prof = topp3._sample(pieces, KOSSEL.servo_period_s, path, {}, settings)
        feed = [r for col, _, _, r in topp3.reads_above(prof, KOSSEL, path, KOSSEL.limits) if col == 3]
        first[mid] = (pieces[0].span.duration, feed)
    assert len(first[False][1]) > 100 and max(first[False][1]) > 1 + 1e-5
    assert first[True][1] == []
    assert first[True][0] == pytest.approx(first[False][0], rel=1e-5)
    assert exact <= first[True][0] <= exact * 1.003


def test_station_floor_lets_a_micron_tip_have_its_stations():
    """A 90° arc of 2 µm radius between two lines: at 0.05 radii the arc needs ~31 cells.
    copp's floor of STATION_MIN_MM (1 µm) leaves it ≤ 4; optimal's (planner.STATION_MIN_MM)
    gives it its ~31 (the stations alone were 1.6 % above T_ref at cusp_trochoid_lcnc's
    1.8 µm tips with the 1 µm floor)."""
    r, c = 2e-3, KEOPS.home
    path = SegmentPath([Line(c + [-5, -r, 0], c + [0, -r, 0]),
                        Arc(c + [0, -r, 0], c, [0, 0, 1], math.pi / 2),
                        Line(c + [r, 0, 0], c + [r, 5, 0])])
    table = PathTable(path, KEOPS)
    s_arc = (5.0, 5.0 + r * math.pi / 2)

    def cells_on_arc(min_mm):
        g = topp3.grid_of(path, table, [], 0.0, path.length, 0.05, 0.05, min_mm=min_mm)
        return int(np.sum((g > s_arc[0] + 1e-9) & (g < s_arc[1] - 1e-9))) + 1

    assert cells_on_arc(topp3.STATION_MIN_MM) <= 4
    assert cells_on_arc(optimal.STATION_MIN_MM) >= 30


def test_the_window_kernel_reads_a_jump_and_a_smooth_acceleration_as_the_third_difference():
    """constraints.second_derivative_kernel G: ∫q̈(t)·G(t − c)dt is the third difference (q(c + 1.5T) − 3q(c + ½T)
    + 3q(c − ½T) − q(c − 1.5T))/T³, computed here from q directly: for a jump of q″ d periods
    from the centre (q = ½(t − t_j)₊²: third_difference_weight(1.5 − d)/T) and for q = sin."""
    from planners.constraints import second_derivative_kernel, third_difference_weight
    T = 1e-3
    t = np.linspace(-2 * T, 2 * T, 400001)
    w = np.full(len(t), t[1] - t[0])
    w[[0, -1]] /= 2
    G = second_derivative_kernel(t, T)
    third = lambda q: (q(1.5 * T) - 3 * q(0.5 * T) + 3 * q(-0.5 * T) - q(-1.5 * T)) / T ** 3
    for d in np.linspace(-1.5, 1.5, 13):
        tj = -d * T                                     # the centre d periods after the jump
        jump = np.sum(w * (t >= tj) * G)
        assert jump == pytest.approx(third(lambda x: 0.5 * max(x - tj, 0.0) ** 2), rel=1e-4, abs=1e-3 / T)
        assert jump == pytest.approx(third_difference_weight(1.5 - d) / T, rel=1e-4, abs=1e-3 / T)
    om = 2 * math.pi / (7 * T)
    smooth = np.sum(w * -om ** 2 * np.sin(om * (t + 0.3 * T)) * G)
    assert smooth == pytest.approx(third(lambda x: math.sin(om * (x + 0.3 * T))), rel=1e-6)


def _corners(tmp_path, blend):
    f = tmp_path / "corners.ngc"
    f.write_text(f"G21 G90 G17 G64 P{blend}\nG0 X-10 Y-6 Z-400\nF60000\nG1 X-8 Y-6\nG1 X1 Y0\nG1 X1 Y8\n"
                 "G1 X-5 Y0\nM2\n")
    return resolve_path(str(f), home=KEOPS.home)


@pytest.mark.parametrize("case", ["kossel-line-arc-line", "keops-g64-corners"])
def test_window_reads_read_what_the_samples_read_at_T(case, tmp_path):
    """Settings.window_reads (optimal's): each window join's rows, evaluated on the solved piece
    (built on its own time map), against the third differences of the profile's exact samples
    (its cubics through the IK) centred at every READ_CENTRES phase: within 0.002 × J on a
    line–arc–line (measured 7e-4) and 0.006 × J at G64 P0.0005 corners (measured 0.0044)."""
    if case.startswith("kossel"):
        machine, rho, c = KOSSEL, 0.5, np.array([-13.0, -10.0, -252.0])
        a = Line(c + [-5.0, rho, 0.0], c + [0.0, rho, 0.0])
        arc = Arc(a.end, c, [0.0, 0.0, -1.0], math.pi / 2)
        path, tol = SegmentPath([a, arc, Line(arc.end, arc.end + [0.0, -5.0, 0.0])], "line-arc-line"), 0.002
    else:
        machine, path, tol = KEOPS, _corners(tmp_path, 0.0005), 0.006
    st = optimal._settings(optimal.GRID_MM, 1)
    (p,) = topp3.pieces_of(path, machine, machine.limits, st)
    assert len(p.window_joins) >= 2
    prof, ts = p.solve(st)
    span = topp3._Topp3Span(p, prof, ts)
    rows = p._rows(prof.a)
    x = np.empty(2 * len(p.grid))
    x[0::2], x[1::2] = prof.a, prof.b
    T, J, nc = machine.servo_period_s, machine.limits.joint.j, len(topp3.READ_CENTRES)
    assert len(rows.linear) == len(p.window_joins)
    worst = peak = 0.0
    for (i, *_), (cols, vals, _) in zip(p.window_joins, rows.linear):
        read = (vals[:len(vals) // 2] @ x[cols]).reshape(-1, nc) / p.tu ** 3
        for k, delta in enumerate(topp3.READ_CENTRES):
            s = span.at(ts[i] * p.tu + (delta + np.array([-1.5, -0.5, 0.5, 1.5])) * T)[0]
            q = machine.ik(path.point(s + p.s0))
            third = (q[3] - 3 * q[2] + 3 * q[1] - q[0]) / T ** 3
            worst = max(worst, np.abs(read[:, k] - third).max() / J)
            peak = max(peak, np.abs(third).max() / J)
    assert worst < tol
    assert peak > 0.5           # the reads are not trivially small


def test_window_reads_are_faster_than_the_rows_at_the_graded_stations(tmp_path):
    """The same G64 corners with the jumps held by the window rows and by the rows at the
    graded stations (join_read_weight at the station, the jerk there not averaged): the window
    rows are a looser restriction of the same limit, so the piece's time at the stations is
    lower (measured 0.30589 against 0.30690 s); both are judged at T by the repairs."""
    path = _corners(tmp_path, 0.01)
    out = {}
    for window in (False, True):
        st = dataclasses.replace(optimal._settings(optimal.GRID_MM, 1), window_reads=window)
        (p,) = topp3.pieces_of(path, KEOPS, KEOPS.limits, st)
        assert len(p.window_joins) == (6 if window else 0)
        out[window] = p.solve(st)[1][-1] * p.tu
    assert out[True] < out[False] * 0.999


def test_repair_windows_hold_every_join_block_they_touch_whole(tmp_path):
    """A window solve holds only the window-row blocks wholly inside it (ipm.solve), so a repair
    window is widened over every join's block it cuts (_covering).  At G64 P0.01 corners, the
    jerk tightened two stations past the second join: the window reaches the speed valleys and
    cut the third join's block (507…516 of 0…772); with the block dropped its reads came out
    at 1.30 × J, held whole 1.0045 × J (the rows rebuilt on the new time map: a linearisation)."""
    assert topp3._covering([(5, 20), (40, 50)], [(0, 6), (18, 25), (45, 47), (52, 60)]) == [(0, 25), (40, 50)]
    assert topp3._covering([(5, 20), (24, 30)], [(18, 25)]) == [(5, 30)]
    assert topp3._covering([(5, 20)], []) == [(5, 20)]
    path = _corners(tmp_path, 0.01)
    st = optimal._settings(optimal.GRID_MM, 1)
    (p,) = topp3.pieces_of(path, KEOPS, KEOPS.limits, st)
    prof, _ = p.solve(st)
    blocks = [(int(c.min()) // 2, int(c.max()) // 2) for c, _, _ in p._rows(prof.a).linear]
    k = p.window_joins[2][0] + 2
    p.factor[k, 2] *= 0.8
    p.changed[k] = True
    windows = topp3._windows(p.changed, p.grid, prof.a, topp3.WINDOW_TU * math.sqrt(prof.a[k]), topp3.WINDOW_STATIONS)
    assert any(b0 <= hi and b1 >= lo and (b0 < lo or b1 > hi) for lo, hi in windows for b0, b1 in blocks)
    new, _ = p.solve(st)
    x = np.empty(2 * len(p.grid))
    x[0::2], x[1::2] = new.a, new.b
    worst = max(float(np.max(vals @ x[cols] / rhs)) for cols, vals, rhs in p._rows(new.a).linear)
    assert worst < 1.01


@pytest.mark.parametrize("blend", [0.01, 0.5])
def test_the_repairs_at_T_never_make_stations_faster_than_they_are_alone(tmp_path, blend):
    """optimal solves the coarse stations again with their repairs only where their time alone is
    below its best (_socp_within_limits): the repairs add rows to the same problem, so they only
    slow it. G64 corners on keops, where joins read above at T and the repairs run."""
    path = _corners(tmp_path, blend)
    inner = KEOPS.limits.joint_scaled(1 - optimal.CHAIN_MARGIN)
    st = optimal._settings(optimal.GRID_MM, 1 / optimal.STATION_REFINEMENT)
    pieces = topp3.pieces_of(path, KEOPS, inner, st)
    alone = topp3.station_time(pieces, st)
    prof = topp3.solve(path, KEOPS, inner, st, pieces)
    assert prof.info["tightened"]                          # it was repaired
    assert prof.info["continuous_time_s"] >= alone * (1 - 1e-9)
