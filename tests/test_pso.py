"""pso and pso_socp: the feed spline's closed forms and time-scaling law, the exact time map of
its samples, knots placed by the path's limits (not the seed) and refined by insertion (the same
feed), the push's and the cooperative swarm's invariants, seeded determinism, never slower than
its seed, feasible at T, declared stochastic, clear errors."""
import numpy as np
import pytest

from kins import load_machine
from planners import PlanningError, plan
from planners.optimal import topp3
from planners.paths import Arc, Line, SegmentPath
from planners.pso.feed import KNOT_STEP_TU, MIN_SPAN_STATIONS, FeedSpline, jerk_free_a
from planners.pso.planner import swarm_settings
from planners.pso.span import FeedSpan
from planners.pso.swarm import BLOCK, BlockSwarm
from planners.verify import command_metrics

KEOPS = load_machine("keops")
Z = -400.0
PATH = SegmentPath([Line([-40, -20, Z], [0, -20, Z]), Arc([0, -20, Z], [0, 0, Z], [0, 0, 1], np.pi / 2),
                    Line([20, 0, Z], [20, 30, Z])])
FAST = {"iterations": 4, "particles": 8}


def _feed(path=PATH, machine=KEOPS, margin=0.0):
    pieces = topp3.pieces_of(path, machine, machine.limits, topp3.Settings("pso"))
    return FeedSpline(pieces[0], margin)


def _greville(feed):
    t = feed.knots
    return (t[1:feed.K + 1] + t[2:feed.K + 2] + t[3:feed.K + 3]) / 3


def test_a_linear_w_is_the_constant_jerk_start():
    """w = αx reproduces every linear function, so ṡ = (αx)^{2/3}, s̈ = ⅔α^{4/3}x^{1/3}, s⃛ = 2α²/9,
    and from rest x(t) = α²t³/27 (scaled time): the jerk-limited start, in closed form."""
    feed, alpha = _feed(), 3.0
    c = alpha * _greville(feed)
    x = feed.x[1:40]
    sd, sdd, sddd = (m[1:40, 0] for m in feed.motion(c[:, None]))
    np.testing.assert_allclose(sd, (alpha * x) ** (2 / 3), rtol=1e-12)
    np.testing.assert_allclose(sdd, 2 / 3 * alpha ** (4 / 3) * x ** (1 / 3), rtol=1e-12)
    np.testing.assert_allclose(sddd, 2 * alpha ** 2 / 9, rtol=1e-9)
    span = FeedSpan(feed, c, 0)
    tt = np.linspace(0.0, 0.4, 50) * float(span.tx[5]) * span.tu
    x_t, sd_t, _, sddd_t = span.at(tt)
    u = tt / span.tu
    np.testing.assert_allclose(x_t, alpha ** 2 * u ** 3 / 27, rtol=1e-11, atol=1e-15)
    np.testing.assert_allclose(sd_t * span.tu, alpha ** 2 * u ** 2 / 9, rtol=1e-10, atol=1e-15)
    np.testing.assert_allclose(sddd_t * span.tu ** 3, 2 * alpha ** 2 / 9, rtol=1e-9)


def test_the_basis_matrices_are_the_spline_and_its_derivatives():
    """w, w′, w″ at the stations by the sparse bases (de Boor's derivative coefficients) against
    scipy's BSpline evaluated with nu = 0, 1, 2."""
    feed = _feed()
    C = np.random.default_rng(0).random((feed.K, 3))
    spl = feed.spline(C)
    for nu, B in enumerate(feed.bases):
        np.testing.assert_allclose(B @ C, spl(feed.x, nu), rtol=0, atol=1e-12 * np.abs(spl(feed.x, nu)).max())


def test_the_time_map_inverts_and_the_samples_reach_the_end():
    """s(t) from Newton on the Gauss–Legendre time map: t(s(t)) = t at 2000 times, s(T_end) = L."""
    feed = _feed()
    c = feed.start_within(feed.fit(np.sqrt(feed.a_ra)))
    span = FeedSpan(feed, c, 0)
    tt = np.linspace(0.0, span.duration, 2000)
    x = span.at(tt)[0]
    assert np.all(np.diff(x) > 0) and x[-1] == pytest.approx(feed.L, abs=1e-9)
    # the time back from each sample: station time + the quadrature to it
    k = np.clip(np.searchsorted(span.x, x, side="right") - 1, 1, len(span.x) - 3)
    inner = (x > span.x[1]) & (x < span.x[-2])
    back = span.tx[k[inner]] + span._integral(span.x[k[inner]], x[inner])
    np.testing.assert_allclose(back * span.tu, tt[inner], rtol=0, atol=1e-12)


def test_time_scaling_law_of_the_reads():
    """Stretching time by λ multiplies w by λ^{−3/2}: every station's need and every interval's
    time scale by 1/λ and λ exactly (v ∝ 1/λ, a ∝ 1/λ², j ∝ 1/λ³), except at a G1 join, whose
    row adds the read κṡ² of its q″ jump (∝ 1/λ²) to the jerk."""
    feed = _feed()
    joins = [i for i, *_ in feed.joins]
    assert len(joins) == 2
    c = feed.fit(np.sqrt(feed.a_ra))
    dt, need = feed.reads(c)
    free = np.setdiff1d(np.arange(len(need)), joins)
    for lam in (0.5, 2.0, 3.7):
        dt2, need2 = feed.reads(c * lam ** -1.5)
        np.testing.assert_allclose(need2[free], need[free] / lam, rtol=1e-10, atol=1e-300)
        np.testing.assert_allclose(dt2, dt * lam, rtol=1e-10)


def test_join_reads_are_the_signed_read_of_the_spline_at_each_row():
    """At each join row (the join either side, and the graded stations near it, weighted) the need
    is the larger of the station's own limits and ∛(max(|jerk|, |jerk + κṡ²|)/J), the jerk
    evaluated here from scipy's BSpline derivatives of w (not the basis matrices), each column of
    the coefficients on its own."""
    piece = topp3.pieces_of(PATH, KEOPS, KEOPS.limits, topp3.Settings("pso", join_grading=True))[0]
    feed = FeedSpline(piece, 0.0)
    assert len(feed.join_reads) > len(feed.joins) >= 2          # graded rows too
    c = feed.fit(np.sqrt(feed.a_ra))
    C = np.column_stack([c, c * 0.7, c * 1.3])
    _, need = feed.reads(C)
    bare = FeedSpline.__new__(FeedSpline)
    bare.__dict__.update(feed.__dict__, jr_at=np.empty(0, np.intp))     # no join rows
    _, own = bare.reads(C)
    J = feed.lims[2]
    want = own.copy()
    for p in range(C.shape[1]):
        spl = feed.spline(C[:, p])
        for i, D1, D2, D3, kappa in feed.join_reads:
            x = feed.x[i]
            w, w1, w2 = (float(spl.derivative(k)(x)) if k else float(spl(x)) for k in range(3))
            sd, sdd, sddd = w ** (2 / 3), 2 / 3 * w ** (1 / 3) * w1, 2 / 9 * w1 ** 2 + 2 / 3 * w * w2
            for side in range(len(D1)):
                jerk = D3[side] * sd ** 3 + 3 * D2[side] * sd * sdd + D1[side] * sddd
                read = np.maximum(np.abs(jerk), np.abs(jerk + kappa * sd * sd)).max()
                want[i, p] = max(want[i, p], np.cbrt(read / J))
    np.testing.assert_allclose(need, want, rtol=1e-9)


def test_knots_follow_the_limits_not_the_seed():
    """The knots come from the jerk-free optimum's time on the piece's stations, one per
    KNOT_STEP_TU of it (to the station they are moved to): the same for any seed profile."""
    seed = plan("scurve_joint", PATH, KEOPS)
    slow = plan("trapezoid", PATH, KEOPS)
    a = plan("pso", PATH, KEOPS, seed_profile=seed, **FAST)
    b = plan("pso", PATH, KEOPS, seed_profile=slow, **FAST)
    assert a.info["control_points"] == b.info["control_points"]
    feed = _feed()
    t_ra = feed.station_times(np.sqrt(feed.a_ra))
    m = int(np.ceil(t_ra[-1] / KNOT_STEP_TU))
    even = np.interp(np.linspace(0.0, t_ra[-1], m + 1)[1:-1], t_ra, feed.x)
    # and graded toward the dips (test_knots_are_graded_toward_a_g1_join)
    wanted = np.sort(np.concatenate([even, feed._graded_at_dips(feed.joins, even)]))
    inner = feed.knots[4:-4]
    # moved to a station, at most MIN_SPAN_STATIONS intervals off (kept that far apart, so
    # a wanted knot that close to the end is dropped)
    assert 0 <= len(wanted) - len(inner) <= 1 and feed.K == len(inner) + 4
    assert np.abs(inner - wanted[:len(inner)]).max() <= MIN_SPAN_STATIONS * feed.dx.max() + 1e-12


def test_blocks_cover_every_coefficient_once_and_one_colour_shares_no_station():
    feed = _feed()
    sw = BlockSwarm(feed, feed.start_within(feed.fit(np.sqrt(feed.a_ra))), np.random.default_rng(0), 4, 0.05)
    for it in range(BLOCK):
        sw.iteration = it
        seen = []
        for colour in range(2):
            idx = sw._blocks(colour)
            ks = [sw.free[b[b >= 0]] for b in idx]
            seen += [k for b in ks for k in b]
            spans = sorted((feed.sup_lo[b[0]], feed.sup_hi[b[-1]]) for b in ks)
            assert all(hi < lo for (_, hi), (lo, _) in zip(spans, spans[1:]))
        assert sorted(seen) == list(sw.free)


def test_the_context_stays_within_the_limits_and_never_slows_down():
    """From the start slowed to 85 % of its feed, 12 iterations stay within the limits, never
    slow down, and end faster than the start itself (18.11 against 18.26 scaled, measured)."""
    feed = _feed()
    c0 = feed.start_within(feed.fit(np.sqrt(feed.a_ra)))
    sw = BlockSwarm(feed, c0 * 0.85 ** 1.5, np.random.default_rng(1), 8, 0.05)
    times = [feed.time(sw.c)]
    for _ in range(12):
        sw.step()
        assert feed.reads(sw.c)[1].max() <= 1.0
        times.append(feed.time(sw.c))
    assert all(b <= a for a, b in zip(times, times[1:])) and times[-1] < feed.time(c0)


def test_same_seed_same_profile_other_seed_other_swarm():
    a = plan("pso", PATH, KEOPS, seed=3, **FAST)
    b = plan("pso", PATH, KEOPS, seed=3, **FAST)
    assert np.array_equal(a.s, b.s) and np.array_equal(a.sddd, b.sddd)
    assert [h[1] for h in a.info["history"]] == [h[1] for h in b.info["history"]]
    c = plan("pso", PATH, KEOPS, seed=4, **FAST)
    assert [h[1] for h in a.info["history"]] != [h[1] for h in c.info["history"]]


def test_feasible_at_T_never_slower_than_its_seed_and_both_results_reported():
    """pso_socp returns the fastest of its polish, its swarm and its seed, all checked at T;
    pso is its swarm alone (no polish), within the limits at T too."""
    seed = plan("scurve_joint", PATH, KEOPS)
    p = plan("pso_socp", PATH, KEOPS, seed_profile=seed, **FAST)
    r = command_metrics(KEOPS, PATH.point(p.s), p.T, p.s)
    assert r["feasible"] and r["cartesian_peak_ratio"]["feed"] <= 1 + 1e-6
    info = p.info
    assert p.planner == "pso_socp" and p.execution_time_s <= seed.execution_time_s
    assert p.execution_time_s == min(info["swarm_time_s"], info["polished_time_s"], info["seed_time_s"])
    assert info["returned"] == "polished" and info["swarm_time_s"] < info["start_time_s"]
    q = plan("pso", PATH, KEOPS, seed_profile=seed, **FAST)
    rq = command_metrics(KEOPS, PATH.point(q.s), q.T, q.s)
    assert q.planner == "pso" and rq["feasible"] and "polished_time_s" not in q.info
    assert q.execution_time_s == pytest.approx(min(q.info["swarm_time_s"], seed.execution_time_s))
    assert q.info["returned"] == "swarm" and q.execution_time_s < seed.execution_time_s
    assert "source" not in q.info and "source" not in p.info


def _pso_seeded_by_copp(path, machine, limits=None, seed=0, **kw):
    from planners.pso.planner import plan as pso    # the module's: the registry's "pso" is this in the test
    return pso(path, machine, limits, seed=seed, seed_profile=plan("copp", path, machine, limits), **FAST)


_pso_seeded_by_copp.stochastic = True


def test_its_seed_returned_is_another_planners_profile_and_the_rows_failure(monkeypatch):
    """Seeded by copp's near-optimal profile, the swarm ends slower (0.3655 against 0.353 s
    measured): pso returns the seed, names it in info["source"], and the corpus row is a
    fallback, a failure, as optimal's would be."""
    from harness.corpus.run import run_one
    from planners import registry
    q = _pso_seeded_by_copp(PATH, KEOPS)
    assert q.info["returned"] == "seed" and q.info["source"] == "copp" and q.planner == "pso"
    assert q.execution_time_s == q.info["seed_time_s"] < q.info["swarm_time_s"]
    monkeypatch.setitem(registry.BUILTIN, "pso", (__name__, "_pso_seeded_by_copp"))
    row = run_one({"name": "corner", "machine": "keops"}, "pso", KEOPS, PATH, seed=0)
    assert row.status == "fallback" and "copp's profile" in row.error and row.feasible


def test_both_are_declared_stochastic_and_the_others_not():
    from planners.registry import describe, get, stochastic
    assert stochastic("pso") and stochastic("pso_socp")
    assert not stochastic("optimal") and not stochastic("scurve_joint")
    assert not stochastic("no_such_planner")
    assert describe("pso")["stochastic"] and not describe("copp")["stochastic"]
    # the registry's table of the built-ins and their plan functions' own attribute agree
    assert get("pso").stochastic is True and get("pso_socp").stochastic is True


def _blend_path(r):
    """Two lines joined by a quarter arc of radius r: a G64 blend of a few µm when r is."""
    return SegmentPath([Line([-40, -r, Z], [0, -r, Z]), Arc([0, -r, Z], [0, 0, Z], [0, 0, 1], np.pi / 2),
                        Line([r, 0, Z], [r, 40, Z])])


def test_knots_are_graded_toward_a_g1_join():
    """At a µm blend the joins' reads cap the feed in a dip TOPP2-RA passes in no time, so its
    even time steps put no knot near; the seed's feed fitted on those knots rings (its stations
    read 20.7 × a limit, measured) and its start is 0.570 s against the seed's 0.301 s.  Knots at
    each join and h·2^k either side: the fit reads 4.1 ×, the start 0.374 s."""
    path = _blend_path(0.002)
    piece = topp3.pieces_of(path, KEOPS, KEOPS.limits, topp3.Settings("pso"))[0]
    graded, (read_g, read_e), (start_g, start_e), seed_T = _seed_on_graded_and_even_knots(piece, path, KEOPS)
    assert len(graded.joins) == 2
    for i, *_ in graded.joins:
        assert np.abs(graded.knots - graded.x[i]).min() <= MIN_SPAN_STATIONS * max(graded.dx[i - 1], graded.dx[i])
    assert read_g < read_e / 3
    assert start_g < 0.8 * start_e and start_g < 1.3 * seed_T


def _seed_on_graded_and_even_knots(piece, path, machine):
    """The scurve_joint seed fitted on the piece's knots (graded) and on the even knots alone:
    (the graded FeedSpline, the fits' largest reads (graded, even), their starts' times in s
    (graded, even), the seed's time)."""
    graded = FeedSpline(piece, 0.0)
    t_ra = graded.t_ra
    m = int(np.ceil(t_ra[-1] / KNOT_STEP_TU))
    even = FeedSpline(piece, 0.0, inner=graded._on_stations(np.interp(np.linspace(0.0, t_ra[-1], m + 1)[1:-1], t_ra, graded.x)))
    seed = plan("scurve_joint", path, machine)
    sd = np.interp(piece.grid, seed.s, seed.sd) * piece.tu
    fits = [f.fit(sd) for f in (graded, even)]
    reads = tuple(f.reads(c)[1].max() for f, c in zip((graded, even), fits))
    starts = tuple(f.time(f.start_within(c)) * piece.tu for f, c in zip((graded, even), fits))
    return graded, reads, starts, seed.execution_time_s


def test_knots_are_graded_toward_a_near_cusp():
    """cusp_trochoid_lcnc's near-cusps (radius ~2 µm) dip TOPP2-RA's feed to < 5 % of its
    largest over a few µm: no even time step lands there, and the seed's feed fitted on even
    knots reads 213 × a limit, its start 21.5 s against the seed's 2.50 s (measured on the
    swarm's stations). Graded toward every local minimum that dips as a join does: 3.1 ×, 3.63 s."""
    from harness.corpus.run import CORPUS_DIR
    from planners.paths import resolve_path
    m = load_machine("linuxcnc_delta")
    path = resolve_path(str(CORPUS_DIR / "cusp_trochoid_lcnc.json"), home=m.home)
    piece = topp3.pieces_of(path, m, m.limits, swarm_settings())[0]
    graded, (read_g, read_e), (start_g, start_e), seed_T = _seed_on_graded_and_even_knots(piece, path, m)
    sd_ra = np.sqrt(graded.a_ra)
    lows = np.nonzero((sd_ra[1:-1] < sd_ra[:-2]) & (sd_ra[1:-1] <= sd_ra[2:]) & (sd_ra[1:-1] < 0.05 * sd_ra.max()))[0] + 1
    # the 7 feet of the 6 arches (some with a double dip), none of them a G1 join
    assert len(np.setdiff1d(lows, [j[0] for j in piece.joins])) >= 7
    # a knot at every deep dip (moved to a station at most MIN_SPAN_STATIONS intervals off)
    for i in lows:
        assert np.abs(graded.knots - graded.x[i]).min() <= MIN_SPAN_STATIONS * max(graded.dx[i - 1], graded.dx[i]) + 1e-12
    assert read_g < read_e / 10
    assert start_g < 0.3 * start_e and start_g < 2 * seed_T


def test_the_start_is_the_target_where_it_holds_and_below_it_by_a_climb_elsewhere():
    """start_within: within the limits, never above the target (coefficient by coefficient), the
    target itself where the target holds, and faster than the target stretched as a whole (the
    climb raises the stretches that hold back toward the target).  Deterministic."""
    path = _blend_path(0.002)
    feed = FeedSpline(topp3.pieces_of(path, KEOPS, KEOPS.limits, topp3.Settings("pso"))[0], 0.0)
    target = feed.fit(np.sqrt(feed.a_ra)) * 1.3 ** 1.5          # 30 % above the jerk-free optimum
    assert feed.reads(target)[1].max() > 1.2
    c = feed.start_within(target)
    assert feed.reads(c)[1].max() <= 1.0 and np.all(c <= target)
    uniform = feed.scaled_within(target)
    assert feed.time(c) < feed.time(uniform) - 0.5 * (feed.time(uniform) - feed.time(target))
    assert np.array_equal(feed.start_within(target), c)
    ok = feed.start_within(c)
    assert np.array_equal(ok, c)


def _trochoid_seed_fit(k):
    """(cusp_trochoid_lcnc's k-th swarm piece, its FeedSpline, the papers' start before the climb:
    the scurve_joint seed fitted in the spline)."""
    from harness.corpus.run import CORPUS_DIR
    from planners.paths import resolve_path
    from planners.pso.planner import _seed_feed, swarm_pieces
    from planners.scurve import plan_joint
    m = load_machine("linuxcnc_delta")
    path = resolve_path(str(CORPUS_DIR / "cusp_trochoid_lcnc.json"), home=m.home)
    piece = swarm_pieces(path, m, m.limits, swarm_settings())[0][k]
    feed = FeedSpline(piece, 0.002)
    return piece, feed, feed.fit(_seed_feed(plan_joint(path, m, m.limits), piece))


def test_the_climb_raises_wide_groups_before_narrow_ones():
    """cusp_trochoid_lcnc's piece after its fourth near-cusp, from the papers' start (the
    scurve_joint seed fitted in the spline, 1.5 × a limit at 117.6 mm): climbed back toward the
    seed in groups of 1–4 neighbours, the coefficients around that read stop where their
    neighbours already reached the seed, and the start dips to a third of the seed's feed there
    (27.7 against 80.1 mm/s at 117.1 mm; 0.4429 s). Climbed from the widest group the piece holds down to one, they rise
    together: 0.4148 s. Within the limits and below the target either way."""
    piece, feed, target = _trochoid_seed_fit(4)
    assert feed.reads(target)[1].max() > 1.2
    wide = feed._climb_groups()
    assert wide[-1] == 1 and wide[0] <= feed.K - 2 < 2 * wide[0]
    starts = []
    for groups in (wide, [1, 2, 4]):
        feed._climb_groups = lambda: groups
        c = feed.start_within(target)
        assert feed.reads(c)[1].max() <= 1.0 and np.all(c <= target * (1 + 1e-12))
        starts.append(feed.time(c) * piece.tu)
    assert starts[0] < 0.96 * starts[1]


def test_a_valley_of_the_coefficients_is_filled_in_one_push():
    """A valley 16 coefficients wide, 0.3 × the pushed feed's coefficients at its floor, in the
    middle of a 209 mm line (stretched as a whole to be within the limits): one push raises its
    floor to ≥ 0.8 of them (0.917 measured; its groups of ≤ 16 alone reach 0.638, as they bend
    the flanks that the jerk holds), within the limits, only raising."""
    line = SegmentPath([Line([-100, -30, Z], [100, 30, Z])])
    feed = _feed(line)
    top = feed.push(feed.start_within(feed.fit(np.sqrt(feed.a_ra))), 3)
    width, k0 = 16, feed.K // 2 - 8
    dip = np.ones(feed.K)
    dip[k0:k0 + width] -= 0.7 * np.sin(np.pi * (np.arange(width) + 0.5) / width) ** 2
    c = feed.scaled_within(top * dip)
    floor = slice(k0, k0 + width)
    pushed = feed.push(c)
    assert (pushed[floor] / top[floor]).min() >= 0.8
    assert feed.reads(pushed)[1].max() <= 1.0 and np.all(pushed >= c)
    assert feed.time(pushed) < 1.05 * feed.time(top)


def test_the_push_raises_wide_groups_before_narrow_ones(monkeypatch):
    """cusp_trochoid_lcnc's first piece, from the papers' start (the scurve_joint seed fitted and
    climbed within the limits), pushed by the greedy steps alone (no even round) until it no
    longer moves: single coefficients raised first reach their stations' limits one by one and
    hold the wider groups (0.3578 s); groups of 16 raised first, down to one, lift neighbours
    together (0.3423 s). Within the limits and only raising either way."""
    from planners.pso import feed as feed_module
    from planners.pso.feed import PUSH_GROUPS
    monkeypatch.setattr(feed_module, "PUSH_EVEN", np.array([0.0]))
    _, feed, target = _trochoid_seed_fit(0)
    start = feed.start_within(target)
    assert PUSH_GROUPS[0] > PUSH_GROUPS[-1] == 1
    times = []
    for groups in (PUSH_GROUPS, PUSH_GROUPS[::-1]):
        c = start
        for _ in range(12):
            c = feed.push(c, 1, groups)
        assert feed.reads(c)[1].max() <= 1.0 and np.all(c >= start)
        times.append(feed.time(c))
    assert times[0] < 0.97 * times[1]


def test_an_even_round_first_keeps_the_swarm_from_locking_a_rise(monkeypatch):
    """cusp_trochoid_lcnc's first piece, the swarm alone on its first knots for 10 iterations
    from the papers' start, rng seeds 0–5: with the push's greedy steps alone, a pass's first
    groups rise up to 1.5 × and take the jerk the rise after the tip needs (median 0.3535 s;
    the feed at 1.5 mm 54.5–78.9 mm/s, `optimal` 97); an even round of 3 % first, where the
    stations allow, leaves the rise free (median 0.3427 s, 67–93 mm/s)."""
    from planners.pso import feed as feed_module
    from planners.pso.swarm import BlockSwarm
    piece, feed, target = _trochoid_seed_fit(0)
    start = feed.start_within(target)
    medians = []
    for even in (feed_module.PUSH_EVEN, np.array([0.0])):
        monkeypatch.setattr(feed_module, "PUSH_EVEN", even)
        times = []
        for seed in range(6):
            sw = BlockSwarm(feed, start, np.random.default_rng(seed), 20, 0.05)
            for _ in range(10):
                sw.step()
            assert feed.reads(sw.c)[1].max() <= 1.0
            times.append(feed.time(sw.c) * piece.tu)
        medians.append(np.median(times))
    assert medians[0] < 0.98 * medians[1]


def test_the_push_keeps_the_limits_and_only_raises_the_feed():
    """Every coefficient only grows (so w and the feed only grow: the basis is ≥ 0), every
    station stays within its limits, and from a start scaled down to half the feed the push
    gains back at least a third of the lost time."""
    feed = _feed()
    c0 = feed.start_within(feed.fit(np.sqrt(feed.a_ra)))
    low = c0 * 0.5 ** 1.5                              # half the feed everywhere: twice the time
    c = feed.push(low, 3)
    assert np.all(c >= low) and feed.reads(c)[1].max() <= 1.0
    assert feed.time(c) < feed.time(low) - (feed.time(low) - feed.time(c0)) / 3
    assert np.array_equal(feed.push(low, 3), c)       # deterministic


def test_refined_knots_keep_the_old_ones_and_the_same_feed():
    """Knot insertion: the refined spline has every old knot, about twice as many coefficients,
    and the same w at the stations (to the least squares' round-off)."""
    feed = _feed()
    c = feed.start_within(feed.fit(np.sqrt(feed.a_ra)))
    fine, cf = feed.refined(c)
    assert np.all(np.isin(feed.knots[4:-4], fine.knots[4:-4]))
    assert feed.K < fine.K <= 2 * feed.K
    w, wf = feed.bases[0] @ c, fine.bases[0] @ cf
    np.testing.assert_allclose(wf, w, rtol=0, atol=1e-9 * w.max())
    assert fine.time(cf) == pytest.approx(feed.time(c), rel=1e-9)


def test_time_budget_is_reported_and_zero_iterations_return_the_start():
    p = plan("pso", PATH, KEOPS, time_budget_s=0.0, **FAST)
    assert p.info["stopped_by"] == "time budget" and p.info["iterations_run"] == 0


def test_bad_options():
    with pytest.raises(PlanningError, match="particles"):
        plan("pso", PATH, KEOPS, particles=1)
    with pytest.raises(PlanningError, match="iterations"):
        plan("pso_socp", PATH, KEOPS, iterations=-1)
    with pytest.raises(TypeError):
        plan("pso", PATH, KEOPS, polish=True)          # the swarm has no polish: pso_socp has


def test_the_swarms_pieces_end_at_rest_where_the_jerk_free_optimum_all_but_stops():
    """cusp_trochoid_lcnc's 6 arches meet at 5 near-cusps where TOPP2-RA's feed falls to
    0.05–0.11 % of its fastest: the swarm's pieces end there at rest (one stop a foot, though
    some feet dip twice); the short keops path's join (a G1 line–arc join) is no such stop."""
    from harness.corpus.run import CORPUS_DIR
    from planners.paths import resolve_path
    from planners.pso.planner import NEAR_STOP, _near_stops
    m = load_machine("linuxcnc_delta")
    path = resolve_path(str(CORPUS_DIR / "cusp_trochoid_lcnc.json"), home=m.home)
    settings = swarm_settings()
    piece, = topp3.pieces_of(path, m, m.limits, settings)
    a_ra = jerk_free_a(piece)
    stops = _near_stops([piece], [a_ra])
    assert len(stops) == 5
    # the feet: a sixth of the path apart, each at the curvature's peak there
    assert np.allclose(np.diff(np.r_[0.0, stops, path.length]), path.length / 6, rtol=0.02)
    for s in stops:
        near = np.linspace(s - 0.5, s + 0.5, 2001)
        assert abs(near[np.argmax(path.curvature(near))] - s) < 0.05
    sd = np.sqrt(a_ra)
    assert np.all(np.interp(stops, piece.grid, sd) < NEAR_STOP * sd.max())
    split = topp3.pieces_of(path, m, m.limits, settings, stops)
    assert [(p.s0, p.s1) for p in split] == list(zip([0.0] + stops, stops + [path.length]))
    short = topp3.pieces_of(PATH, KEOPS, KEOPS.limits, settings)
    assert _near_stops(short, [jerk_free_a(p) for p in short]) == []


def test_the_swarms_stations_resolve_the_curvature_peaks_at_a_near_cusp():
    """Each foot of cusp_trochoid_lcnc is a cluster of curvature peaks µm apart (radii
    0.8–20 µm). The grid splits a cell by the curvature at its ends to ≤ SWARM_STATION_RADII
    radii; with the engine’s 1 µm floor a cell holding a peak was up to 0.28 radii wide (measured),
    the swarm's knots could not follow the dip and it crawled past it (1.21–1.28 × T_ref over ten
    seeds). Down to `optimal`'s floor every peak's cell is ≤ 0.1 radii at its ends; between them
    the peak reads a little more (≤ 0.097 measured)."""
    from scipy.signal import find_peaks
    from harness.corpus.run import CORPUS_DIR
    from planners.constraints import PathTable
    from planners.paths import resolve_path
    from planners.pso.planner import SWARM_STATION_RADII
    m = load_machine("linuxcnc_delta")
    path = resolve_path(str(CORPUS_DIR / "cusp_trochoid_lcnc.json"), home=m.home)
    peaks = []
    for foot in path.length * np.arange(1, 6) / 6:
        s = foot + np.linspace(-0.02, 0.02, 40001)
        kappa = path.curvature(s)
        at, _ = find_peaks(kappa, prominence=0.05 * kappa.max())
        peaks.append(np.c_[s[at], kappa[at]])
    peaks = np.concatenate(peaks)
    table, widest = PathTable(path, m), []
    for floor in (swarm_settings().station_min_mm, 1e-3):
        # one NURBS, no G1 join: the grid is grid_of's alone
        grid = topp3.grid_of(path, table, [], 0.0, path.length, 0.1, SWARM_STATION_RADII, True, floor)
        i = np.searchsorted(grid, peaks[:, 0]) - 1
        widest.append(((grid[i + 1] - grid[i]) * peaks[:, 1]).max())
    assert widest[0] <= 1.2 * SWARM_STATION_RADII < widest[1]


def test_a_swarm_stretched_across_many_pieces_gets_the_rounds_they_need():
    """cusp_trochoid_lcnc's swarm, seed 7: its six pieces' reads next to their stops move from
    piece to piece as the stretch changes the samples' phase; 8 rounds in all left it without a
    profile within the limits (the row fell back to its seed). With 8 a piece it returns its own,
    within the limits at T; on stations that resolve the feet (SWARM_STATION_MIN_MM) within
    1.10 × the corpus's converged reference, the issue's worst-case target (its history:
    docs/TUNING.md)."""
    import json
    from harness.corpus.run import CORPUS_DIR
    from planners.paths import resolve_path
    m = load_machine("linuxcnc_delta")
    path = resolve_path(str(CORPUS_DIR / "cusp_trochoid_lcnc.json"), home=m.home)
    prof = plan("pso", path, m, seed=7)
    assert prof.info["returned"] == "swarm" and len(prof.info["near_stops"]) == 5
    assert command_metrics(m, path.point(prof.s), m.servo_period_s, prof.s)["feasible"]
    t_ref = json.loads((CORPUS_DIR / "reference.json").read_text())["paths"]["cusp_trochoid_lcnc"]["T_reference_s"]
    assert prof.execution_time_s < 1.10 * t_ref


def test_the_swarms_profile_at_T_is_stretched_around_its_reads_where_that_is_cheaper():
    """The head of cam_dense_keops (250 lines of 0.15–0.6 mm chords under G64, one piece): the
    papers' start (the seed fitted, within the limits at the stations) reads above a limit at T
    in a few windows only.  Stretched uniformly, the whole piece slows by the worst read; stretched
    around the reads by whole periods (topp3.stretch_locally) it costs only the bumps' time, and
    the swarm's profile at T is the cheaper one, within the limits."""
    from harness.corpus.run import CORPUS_DIR
    from planners.paths.gcode import parse_gcode, program_path
    from planners.profile import Profile
    from planners.pso import planner as pso
    from planners.scurve import plan_joint
    from planners.verify import stretch_need
    text = "\n".join((CORPUS_DIR / "cam_dense_keops.ngc").read_text().splitlines()[:250]) + "\nM2\n"
    path = program_path(parse_gcode(text, "cam_dense_keops_head.ngc"))
    T = KEOPS.servo_period_s
    settings = pso.swarm_settings()
    piece, = topp3.pieces_of(path, KEOPS, KEOPS.limits, settings)
    feed = FeedSpline(piece, 0.002)
    c = feed.start_within(feed.fit(pso._seed_feed(plan_joint(path, KEOPS), piece)))
    start = Profile.from_pieces("pso", T, [FeedSpan(feed, c, 0)], path)
    need = stretch_need(KEOPS.ik(path.point(start.s)), start.s, T, KEOPS.limits)
    above = need > 1 + 1e-6
    assert 0 < above.sum() < 0.01 * len(need) and need.max() > 1.005
    uniform = pso._stretched_uniformly([FeedSpan(feed, c, 0)], T, path, KEOPS, KEOPS.limits, np.inf)
    out = pso._stretched_at_T([FeedSpan(feed, c, 0)], start, path, KEOPS, KEOPS.limits, np.inf)
    assert command_metrics(KEOPS, path.point(out.s), T, out.s)["feasible"]
    # the uniform stretch pays the worst read over the whole piece (to the sampling's period)
    assert uniform.execution_time_s >= start.execution_time_s * need.max() - 2 * T
    bumps = out.info["local_stretch"]
    assert bumps["bumps"] >= 1
    assert out.execution_time_s <= start.execution_time_s + bumps["added_s"] + T
    assert out.execution_time_s < uniform.execution_time_s


def _with_f_max(machine, f_max):
    import dataclasses
    from kins.machine import MachineLimits
    lim = machine.limits
    return dataclasses.replace(machine, limits=MachineLimits(lim.joint, lim.cartesian, f_max, lim.chord_error_mm))


def test_a_feed_at_f_max_is_held_at_f_max_not_below_it():
    """The corner path with F_max = 100 mm/s (a tenth of keops's, far below what the joints allow
    on its lines): the swarm cruises at F_max itself, read at T (0.99965 measured; held to
    1 − margin, 0.998 at most: spiral_cone_kossel, at F_max nearly everywhere, lost 0.22 % to its
    seed on every seed).  The joint limits keep their margin."""
    slow = _with_f_max(KEOPS, 100.0)
    p = plan("pso", PATH, slow, **FAST)
    r = command_metrics(slow, PATH.point(p.s), p.T, p.s)
    assert p.info["returned"] == "swarm" and r["feasible"]
    assert 0.9995 < r["cartesian_peak_ratio"]["feed"] <= 1 + 1e-6


def test_a_notch_in_the_feed_is_filled_in_one_push():
    """A coefficient at 1e-4 of its neighbours (where a refinement's least squares can leave one)
    is raised toward them in one push, where the push's relative steps alone reach at most
    1.5⁵ ≈ 7.6 × it: the feed no longer crawls there, and the stations stay within the limits."""
    from planners.pso.feed import NOTCH
    feed = _feed()
    c = feed.start_within(feed.fit(np.sqrt(feed.a_ra))) * 0.5 ** 1.5
    k = feed.K // 2
    c[k] *= 1e-4
    pushed = feed.push(c)
    assert pushed[k] >= NOTCH * min(pushed[k - 1], pushed[k + 1])
    assert feed.reads(pushed)[1].max() <= 1.0 and np.all(pushed >= c)


def test_a_polish_that_fails_is_solved_again_around_topp2_ra(monkeypatch):
    """Where the polish linearised around the swarm's and the seed's feed has no solution (the
    IPM, then Clarabel's NUMERICAL_ERROR, as on butterfly_lcnc seed 0), it is solved again on
    fresh pieces around TOPP2-RA's profile, and that profile is checked at T and returned."""
    solve, calls = topp3.solve, []

    def first_fails(path, machine, limits, settings, pieces):
        calls.append(settings)
        if len(calls) == 1:
            raise PlanningError("pso_socp: no solution of piece 0: NUMERICAL_ERROR (the test's)")
        return solve(path, machine, limits, settings, pieces)

    monkeypatch.setattr(topp3, "solve", first_fails)
    p = plan("pso_socp", PATH, KEOPS, **FAST)
    assert len(calls) == 2 and calls[1].station_radii == topp3.STATION_RADII
    assert p.info["polish_reference"] == "TOPP2-RA" and "the test's" in p.info["polish"]
    assert p.info["returned"] == "polished" and p.execution_time_s == p.info["polished_time_s"]
    r = command_metrics(KEOPS, PATH.point(p.s), p.T, p.s)
    assert r["feasible"] and p.execution_time_s < p.info["swarm_time_s"]


def test_the_feed_cap_is_read_between_the_stations_too():
    """The need at each station covers the feed at the middle of the interval after it (the
    spline evaluated there by scipy, against the higher cap of the two stations): held to F_max
    at the stations only, the spline bulged up to 1.1e-3 above it between them (rand_planar_kossel)."""
    feed = _feed(machine=_with_f_max(KEOPS, 100.0))
    c = feed.push(feed.start_within(feed.fit(np.sqrt(feed.a_ra))), 2)
    x_mid = (feed.x[:-1] + feed.x[1:]) / 2
    sd_mid = np.cbrt(np.maximum(feed.spline(c)(x_mid), 0.0)) ** 2
    cap_mid = np.sqrt(np.maximum(feed.cap2[:-1], feed.cap2[1:]))
    need = feed.reads(c)[1][:, 0]
    assert np.all(need[:-1] >= sd_mid / cap_mid * (1 - 1e-12))
    assert (sd_mid / cap_mid).max() > 1 - 1e-6       # the cap binds: the test reads it
