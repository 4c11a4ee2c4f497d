"""pso: seeded determinism, beats its scurve_joint seed, feasible at T, clear errors."""
import dataclasses
import numpy as np
import pytest

from planners.verify import command_metrics
from kins import load_machine
from planners import PlanningError, plan
from planners.pso import basis, join, problem, seed as pso_seed, tuning
from planners.pso.polish import polish
from planners.constraints import rest_pieces
from planners.paths import Arc, Line, SegmentPath

KEOPS = load_machine("keops")
Z = -400.0
PATH = SegmentPath([Line([-40, -20, Z], [0, -20, Z]), Arc([0, -20, Z], [0, 0, Z], [0, 0, 1], np.pi / 2),
                    Line([20, 0, Z], [20, 30, Z])])
FAST = {"iterations": 20, "particles": 16, "control_points": 30}


def test_same_seed_same_profile_other_seed_other_search():
    a = plan("pso", PATH, KEOPS, seed=3, **FAST)
    b = plan("pso", PATH, KEOPS, seed=3, **FAST)
    assert np.array_equal(a.s, b.s) and np.array_equal(a.sddd, b.sddd)
    assert [h[1] for h in a.info["history"]] == [h[1] for h in b.info["history"]]
    # knots at quantiles (not at the seed's switch times): the swarm moves off its start,
    # and where it goes depends on the seed
    c = plan("pso", PATH, KEOPS, seed=3, exact_knots=False, **FAST)
    d = plan("pso", PATH, KEOPS, seed=4, exact_knots=False, **FAST)
    assert not np.array_equal(c.s, d.s)


def test_beats_its_seed_and_is_feasible():
    seed = plan("scurve_joint", PATH, KEOPS)
    p = plan("pso", PATH, KEOPS, seed_profile=seed, **FAST)
    assert p.execution_time_s < seed.execution_time_s
    r = command_metrics(KEOPS, PATH.point(p.s), p.T, p.s)
    assert r["feasible"] and r["cartesian_peak_ratio"]["feed"] <= 1 + 1e-6
    assert p.info["returned"] == "swarm best" and len(p.info["t_check_stretch"]) == 1
    # the swarm's best never gets worse
    best = [h[1] for h in p.info["history"]]
    assert all(x >= y for x, y in zip(best, best[1:]))


def test_time_scaling_law():
    """Stretching time by λ divides joint v, a, j by λ, λ², λ³: the λ a particle gets makes its
    worst ratio exactly 1 (margin 0)."""
    m = KEOPS
    from planners.constraints import PathTable
    table = PathTable(PATH, m)
    pr = problem.PieceProblem(table, 0.0, PATH.length, m.limits, m.servo_period_s, [], 12, 300,
                           table.s, np.full(len(table.s), 1e9))
    X = np.linspace(1, 3, 8)[None, :] * np.array([[1.0], [2.0]])
    lam, (s, v, a, j) = pr.scale(X, 0.0)
    d1, d2, d3 = table.joints(np.clip(s, 1e-9, PATH.length - 1e-9))
    v3, a3, j3 = (x[..., None] / lam[:, None, None] ** k for x, k in ((v, 1), (a, 2), (j, 3)))
    qv = np.abs(d1 * v3).max(axis=(1, 2)) / m.limits.joint.v
    qa = np.abs(d2 * v3 ** 2 + d1 * a3).max(axis=(1, 2)) / m.limits.joint.a
    qj = np.abs(d3 * v3 ** 3 + 3 * d2 * v3 * a3 + d1 * j3).max(axis=(1, 2)) / m.limits.joint.j
    np.testing.assert_allclose(np.maximum.reduce([qv, qa, qj]), 1.0, rtol=1e-9)


def test_no_feasible_particle_is_a_clear_error(monkeypatch):
    # PATH's line–arc–line has two G1 joins: one piece, searched whole and cut into three
    monkeypatch.setattr(problem.PieceProblem, "start", lambda self, x0, margin: None)
    monkeypatch.setattr(problem.SubPiece, "start", lambda self, x0, margin: None)
    with pytest.raises(PlanningError, match=r"pso: no feasible particle on piece\(s\) \[0\]"):
        plan("pso", PATH, KEOPS, **FAST)


def test_bad_options():
    with pytest.raises(PlanningError, match="≥ 2 particles"):
        plan("pso", PATH, KEOPS, particles=1)


@pytest.mark.slow
def test_the_swarm_starts_from_its_seed_on_every_piece_of_bird():
    """Fitted with the seed's jerk switch times as knots, each piece's start particle needs no
    stretch beyond the seed's own duration (±1 %).  A knot span holding no seed sample once
    left the fit undetermined there and stretched one piece of bird 19× (0.69 → 13.2 s)."""
    from planners.constraints import PathTable, feed_cap
    from planners.paths import resolve_path
    from planners.scurve import plan_joint
    path, m = resolve_path("bird"), KEOPS
    table = PathTable(path, m)
    kappa = np.linalg.norm(np.cross(table.cart[1], table.cart[2]), axis=1)
    cap = feed_cap(path, table.s, m.limits, m.servo_period_s, kappa=kappa)
    seed = plan_joint(path, m)
    for s0, s1 in rest_pieces(path):
        tau, v, jerk, D, knots = pso_seed.seed_window(seed, s0, s1)
        pr = problem.PieceProblem(table, s0, s1, m.limits, m.servo_period_s, [], 15, 400, table.s, cap,
                               pso_seed.knot_density(tau, jerk), inner=knots)
        lam, _ = pr.scale(pr.shape.fit(tau, v)[None, :], 0.005)
        assert lam[0] == pytest.approx(D, rel=0.01), (s0, s1)


@pytest.mark.slow
def test_never_slower_than_a_feasible_seed():
    """With no search, no polish and a 5 % margin the swarm's best is the seed stretched to 95 %
    of every limit, slower than the seed: pso then returns the seed itself (feasible), and says so."""
    seed = plan("scurve_joint", PATH, KEOPS)
    p = plan("pso", PATH, KEOPS, seed_profile=seed, iterations=0, particles=4, margin=0.05,
             polish_steps=0)
    assert p.execution_time_s == seed.execution_time_s and p.planner == "pso"
    assert p.info["returned"].startswith("seed (scurve_joint)")
    assert command_metrics(KEOPS, PATH.point(p.s), p.T, p.s)["feasible"]


def test_join_stretch_is_the_root_of_the_join_cubic():
    """λ with read/λ² + cont/λ³ = J exactly, checked against numpy's companion-matrix roots;
    at the limits of a pure reading or a pure jerk it is √(read/J) or ∛(cont/J)."""
    rng = np.random.default_rng(1)
    J = 5e5
    read = rng.uniform(0, 3e6, 200) * rng.integers(0, 2, 200)
    cont = rng.uniform(0, 3e6, 200) * rng.integers(0, 2, 200)
    lam = join.join_stretch(read, cont, J)
    for r, c, x in zip(read, cont, lam):
        roots = np.roots([J, 0.0, -r, -c])
        ref = max(z.real for z in roots if abs(z.imag) < 1e-9 * max(1.0, abs(z)))
        assert x == pytest.approx(max(ref, 0.0), rel=1e-10, abs=1e-12)
    np.testing.assert_allclose(join.join_stretch(np.array([2e6]), np.array([0.0]), J), [2.0], rtol=1e-12)
    np.testing.assert_allclose(join.join_stretch(np.array([0.0]), np.array([4e6]), J), [2.0], rtol=1e-12)


def test_sub_piece_duration_and_ratio_at_constant_feed():
    """A sub-piece whose every control point is c moves at ṡ ≡ c (s̈ = s⃛ = 0): it lasts L/c, and
    its worst ratio is the joint velocity |dq/ds|·c/V, here with dq/ds by central differences
    of the IK (not the path table the planner reads)."""
    from planners.constraints import PathTable
    m, L, c = KEOPS, 40.0, 150.0
    line = SegmentPath([Line([-20, 0, Z], [20, 0, Z])])
    table = PathTable(line, m)
    sub = problem.SubPiece(table, 0.0, L, c, c, [], m.limits, m.servo_period_s, 10, 300, table.s,
                        np.full(len(table.s), 1e9))
    X = np.full((1, len(sub.free)), c)
    d, need = sub.ratio(X, 0.0)
    assert d[0] == pytest.approx(L / c, rel=1e-12)
    s = np.linspace(1e-3, L - 1e-3, 2001)
    h = 1e-4
    dq = (m.ik(line.point(s + h)) - m.ik(line.point(s - h))) / (2 * h)
    assert need[0] == pytest.approx(np.abs(dq).max() * c / m.limits.joint.v, rel=1e-4)


@pytest.mark.slow
def test_cut_piece_passes_each_join_at_its_join_feed():
    """PATH's piece is searched cut at its two G1 joins (line–arc–line): the profile passes
    each join at JOIN_FEED_FRACTION of the join's feed (divided by the T-check stretch), with
    ṡ continuous there (a sub-piece's ends are fixed, so neighbours agree)."""
    from planners.constraints import PathTable, feed_cap
    p = plan("pso", PATH, KEOPS, **FAST)
    assert p.info["searched_as"] == ["cut"]
    m, T = KEOPS, KEOPS.servo_period_s
    table = PathTable(PATH, m)
    kappa = np.linalg.norm(np.cross(table.cart[1], table.cart[2]), axis=1)
    cap = feed_cap(PATH, table.s, m.limits, T, kappa=kappa)
    a_max = m.limits.cartesian.a               # one sample's feed change is below a·T (2.5 mm/s)
    for sj in (40.0, 40.0 + 10 * np.pi):        # the arc's ends
        h = 1e-4                                # one-sided q″ by second differences of the IK
        dq2 = np.diff(m.ik(PATH.point(sj + h * np.arange(-2, 3))), 2, axis=0)[[0, 2]] / h ** 2
        want = tuning.JOIN_FEED_FRACTION * join.join_feed(table, sj, np.abs(dq2[1] - dq2[0]), m.limits,
                                                          0.005, T, cap) / p.info["t_check_stretch"][0]
        i = int(np.searchsorted(p.s, sj))
        assert np.interp(sj, p.s, p.sd) == pytest.approx(want, rel=2e-3)
        assert abs(p.sd[i] - p.sd[i - 1]) < a_max * T


@pytest.mark.slow
def test_polish_climbs_to_the_feed_cap():
    """Under a feed cap c alone (joint limits out of reach, ends fixed at c) the fastest
    sub-piece moves at ṡ ≡ c and lasts L/c.  From ṡ = c/2 inside, the polish's LP steps get there
    (rel 1e-4) with the cap met (to the 1e-7 the penalised objective leaves)."""
    from types import SimpleNamespace
    from planners.constraints import PathTable
    m, L, c = KEOPS, 40.0, 150.0
    line = SegmentPath([Line([-20, 0, Z], [20, 0, Z])])
    table = PathTable(line, m)
    free = SimpleNamespace(joint=SimpleNamespace(v=1e9, a=1e12, j=1e15))
    sub = problem.SubPiece(table, 0.0, L, c, c, [], free, m.servo_period_s, 10, 300, table.s,
                        np.full(len(table.s), c))
    x0 = np.full(len(sub.free), c / 2)
    assert sub.duration(x0[None, :])[0] > 1.3 * L / c
    x, f, its = polish(sub, x0, 0.0, 60)
    d, need = sub.ratio(x[None, :], 0.0)
    assert need[0] <= 1 + 1e-7 and f == pytest.approx(d[0], rel=1e-6)
    assert d[0] == pytest.approx(L / c, rel=1e-4)
    assert 0 < its <= 60


def test_join_index_search_is_the_first_sample_at_or_after_each_join():
    # the per-join (P, M) comparison it replaces: first index with s ≥ join, 0 if none, clipped
    rng = np.random.default_rng(5)
    s = np.cumsum(rng.random((7, 50)), axis=1)
    s[2, 20:23] = s[2, 19] - 0.5                 # a row that dips (rounding at a plateau)
    pts = [-1.0, 0.3, 3.0, 10.0, 24.9, 25.0, 1e9]
    want = np.stack([np.clip(np.argmax(s >= p, axis=1), 1, 49) for p in pts], axis=1)
    assert np.array_equal(join.first_at_or_after(s, pts), want)
    assert join.first_at_or_after(s, []).shape == (7, 0)


def test_sparse_basis_is_the_dense_basis():
    # a small piece's knots (uneven, as the seed's switch times are); dense arrays from
    # BSpline per basis function, the sparse ones from design matrices and the derivative
    # and antiderivative recurrences
    rng = np.random.default_rng(2)
    inner = np.sort(rng.random(25))
    d = basis.Shape(0, 300, inner=inner)
    s = basis.Shape(0, 300, inner=inner, sparse=True)
    assert s.K == d.K and np.array_equal(s.tau, d.tau)
    for D, S in ((d.B, s.B), (d.B1, s.B1), (d.B2, s.B2)):
        assert np.abs(D - S.toarray()).max() <= 1e-12 * np.abs(D).max()
    C = rng.random((4, d.K))
    for x, y in zip(d.eval(C), s.eval(C)):
        assert np.abs(x - y).max() <= 1e-12 * np.abs(x).max()
    tau = np.linspace(0.0, 1.0, 2000)
    v = 1.5 + np.sin(3 * tau)
    assert np.allclose(s.fit(tau, v), d.fit(tau, v), rtol=0, atol=1e-12)


def test_piece_over_the_size_bound_is_searched_sparse_from_its_seed(monkeypatch):
    seed = plan("scurve_joint", PATH, KEOPS)
    opts = dict(seed=3, seed_profile=seed, particles=16, iterations=20, control_points=30)
    monkeypatch.setattr(tuning, "BASIS_MAX_ELEMENTS", 1000)
    a = plan("pso", PATH, KEOPS, polish_steps=0, **opts)
    b = plan("pso", PATH, KEOPS, polish_steps=0, **opts)
    assert np.array_equal(a.s, b.s) and np.array_equal(a.sddd, b.sddd)
    (fb,) = a.info["fallback"]["pieces"]             # one rest-to-rest piece, over the bound
    assert fb["piece"] == 0 and fb["s_mm"] == [0.0, round(PATH.length, 6)] and fb["polish"] == "skipped"
    assert fb["seed_knots"] > 8 and fb["control_points"] > fb["seed_knots"]
    assert a.execution_time_s <= seed.execution_time_s
    r = command_metrics(KEOPS, PATH.point(a.s), a.T, a.s)
    assert r["feasible"] and r["cartesian_peak_ratio"]["feed"] <= 1 + 1e-6
    # the whole piece's swarm is the dense one's (same knots, same start, same random numbers):
    # its best per iteration agrees to rounding
    monkeypatch.undo()
    d = plan("pso", PATH, KEOPS, polish_steps=0, **opts)
    assert "fallback" not in d.info
    assert np.allclose([h[1] for h in a.info["history"]], [h[1] for h in d.info["history"]],
                       rtol=1e-9, atol=0)


def test_an_infeasible_seed_is_stretched_at_T_where_the_swarm_is_slower():
    # a seed planned for 1.3 × the jerk and 1.2 × the acceleration limit breaks the limits at T;
    # with a wide margin the swarm's start (the seed stretched to 0.8 × every limit) is slower
    # than the seed stretched at T by just its excess: ∛(jerk ratio), the jerk ruling
    hot = dataclasses.replace(KEOPS.limits, joint=dataclasses.replace(
        KEOPS.limits.joint, a=1.2 * KEOPS.limits.joint.a, j=1.3 * KEOPS.limits.joint.j))
    seed = plan("scurve_joint", PATH, KEOPS, limits=hot)
    rs = command_metrics(KEOPS, PATH.point(seed.s), seed.T, seed.s)
    assert not rs["feasible"] and rs["joint_peak_ratio"]["jerk"] > 1.1
    opts = dict(seed=3, seed_profile=seed, iterations=0, polish_steps=0, margin=0.2, control_points=30)
    a = plan("pso", PATH, KEOPS, **opts)
    b = plan("pso", PATH, KEOPS, **opts)
    assert np.array_equal(a.s, b.s) and np.array_equal(a.sddd, b.sddd)
    assert a.info["returned"].startswith("per piece") and a.info["pieces_from"] == ["seed"]
    r = command_metrics(KEOPS, PATH.point(a.s), a.T, a.s)
    assert r["feasible"] and r["cartesian_peak_ratio"]["feed"] <= 1 + 1e-6
    assert a.execution_time_s < a.info["swarm_time_s"]
    stretched = seed.execution_time_s * rs["joint_peak_ratio"]["jerk"] ** (1 / 3)
    assert a.execution_time_s == pytest.approx(stretched, abs=3 * a.T)
