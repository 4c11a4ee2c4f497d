"""The engine's banded interior-point method (planners/optimal/ipm.py) against a second method on
the same rows (copp-py's Clarabel), the principle of optimality on a window with held ends, and
its failures."""
import numpy as np
import pytest

import planners.optimal.topp3 as topp3
from kins import load_machine
from planners.optimal import ipm
from test_planner_claims import short_path

KEOPS = load_machine("keops")
KOSSEL = load_machine("kossel")


def optimal_piece(machine):
    """The first rest-to-rest piece of the short path (a line, a tangent arc: a G1 join with its
    read rows, a line) on `optimal`'s stations (graded at the join, midpoint caps), its rows
    linearised around TOPP2-RA's profile as the engine's first solve is."""
    settings = topp3.Settings("optimal", 0.1, join_grading=True, midpoint_cap=True)
    piece = topp3.pieces_of(short_path(machine), machine, machine.limits, settings)[0]
    a_lin = np.minimum(piece.topp2_ra(), piece.cap2)
    return piece, piece._rows(a_lin), a_lin


def clarabel(rows, a_lin, lo=0, a_ends=(0.0, 0.0), b_ends=(0.0, 0.0), stationary=1):
    prob = topp3.copp.solver.topp3_socp.Problem(rows.copp_robot().constraints, a_lin, idx_s_start=lo,
                                                a_boundary=a_ends, b_boundary=b_ends, num_stationary_max=stationary)
    return topp3.copp.solver.topp3_socp.solve_expert(prob, topp3.Settings("copp").clarabel())


def _random_rows(rng, n, m, wide_every=0):
    """(G, E): m rows over the unknowns (a_0, b_0, …) of n stations, each coupling a station's
    (a, b) with the next's as the engine's do, every ``wide_every``-th up to 30 unknowns wide (the
    joins' window reads); E the engine's b-linear equalities."""
    import scipy.sparse as sp
    nv, rows = 2 * n, []
    for r in range(m):
        lo = 2 * int(rng.integers(0, n - 2))
        wide = bool(wide_every) and r % wide_every == 0
        pool = np.arange(lo, min(lo + (30 if wide else 4), nv))
        c = rng.choice(pool, size=min(len(pool), int(rng.integers(1, 4)) + (20 if wide else 0)), replace=False)
        rows.append((np.full(len(c), r), c, rng.normal(size=len(c))))
    G = sp.csr_matrix((np.concatenate([v for *_, v in rows]), (np.concatenate([r for r, _, _ in rows]),
                                                               np.concatenate([c for _, c, _ in rows]))), shape=(m, nv))
    k = np.arange(n - 1)
    E = sp.csr_matrix((np.r_[np.ones(n - 1), -np.ones(n - 1), rng.random(n - 1), rng.random(n - 1)],
                       (np.tile(k, 4), np.r_[2 * k, 2 * k + 2, 2 * k + 1, 2 * k + 3])), shape=(n - 1, nv))
    return G, E


@pytest.mark.parametrize("kind", ["band", "sparse"])
def test_the_newton_system_is_solved_as_a_dense_solve_does(kind):
    # σ over 20 decades. The band (dgbtrf) stores the upper triangle of Gᵀ·diag(σ)·G and mirrors
    # it; the sparse factor (SuperLU in the stations' order) takes the rows wider than BAND_SPAN
    # next to the narrow ones, as dense blocks
    import scipy.sparse as sp
    rng = np.random.default_rng(7)
    n, m = 60, 400
    G, E = _random_rows(rng, n, m, wide_every=10 if kind == "sparse" else 0)
    assert (ipm._span(G) > ipm.BAND_SPAN) == (kind == "sparse")
    lu = (ipm._Sparse if kind == "sparse" else ipm._Band)(G, E, np.arange(2 * n) // 2)
    sigma = 10.0 ** rng.uniform(-10, 10, m)
    hd = np.where(np.arange(2 * n) % 2 == 0, rng.random(2 * n), 0.0)
    rx, ry = rng.normal(size=2 * n), rng.normal(size=n - 1)
    dx, dy = lu.solve(lu.factor(sigma, hd), rx, ry)
    K = np.block([[np.diag(hd + ipm.REGULARISATION) + (G.T @ sp.diags(sigma) @ G).toarray(), E.T.toarray()],
                  [E.toarray(), -ipm.REGULARISATION * np.eye(n - 1)]])
    want = np.linalg.solve(K, np.r_[rx, ry])
    assert np.allclose(np.r_[dx, dy], want, rtol=1e-6, atol=1e-9 * np.abs(want).max())


@pytest.mark.parametrize("machine", [KEOPS, KOSSEL], ids=["keops", "kossel"])
def test_the_banded_ipm_reaches_clarabels_optimum_on_the_same_rows(machine):
    """The same problem (joint v, a, j, the feed caps, the join's read rows, the midpoint caps, the
    rest ends' constant-jerk blocks) solved by the IPM and by Clarabel's conic form (copp-py):
    the same objective Σ w/√a (Clarabel's η ≥ 1/√a at its optimum) and the same profile."""
    piece, rows, a_lin = optimal_piece(machine)
    assert len(piece.join_reads) > 0
    sol = ipm.solve(rows, a_lin)
    ref = clarabel(rows, a_lin)
    assert ref.profile is not None
    assert sol.num_stationary == tuple(ref.profile.num_stationary) == (1, 1)
    assert sol.objective == pytest.approx(ref.obj_val, rel=1e-7)
    scale = ref.profile.a.max()
    assert np.max(np.abs(sol.a - ref.profile.a)) < 1e-5 * scale
    assert np.max(np.abs(sol.b - ref.profile.b)) < 1e-5 * np.abs(ref.profile.b).max()


def test_a_window_with_its_ends_held_returns_the_whole_solution_there():
    """Principle of optimality: the objective is a sum over stations and every row couples
    neighbours only, so with a window's ends held at the whole piece's optimum (a and b, no rest
    block: copp's num_stationary 0) the window's optimum is that solution on the window."""
    piece, rows, a_lin = optimal_piece(KEOPS)
    whole = ipm.solve(rows, a_lin)
    n = len(a_lin)
    lo, hi = n // 4, n // 2
    win = ipm.solve(rows, a_lin[lo:hi + 1], lo, (whole.a[lo], whole.a[hi]), (whole.b[lo], whole.b[hi]), (0, 0))
    assert win.num_stationary == (0, 0)
    assert win.a[0] == whole.a[lo] and win.b[-1] == whole.b[hi]
    assert np.max(np.abs(win.a - whole.a[lo:hi + 1])) < 1e-5 * whole.a.max()


def test_a_warm_start_from_the_last_linearisation_reaches_the_cold_starts_optimum():
    """The engine's next linearisation starts from the last one's iterate (ipm.Start): the same
    optimum as from the cold start, in fewer iterations, on the same Newton system's layout; a
    start whose rows have another pattern (a window's) is not taken."""
    piece, rows, a_lin = optimal_piece(KOSSEL)
    a1 = ipm.solve(rows, a_lin).a
    first = ipm.solve(piece._rows(a1), a1)             # the second linearisation
    again = piece._rows(first.a)                         # the third's rows
    cold = ipm.solve(again, first.a)
    warm = ipm.solve(again, first.a, start=first.start)
    assert warm.start.band is first.start.band
    assert warm.objective == pytest.approx(cold.objective, rel=1e-9)
    assert np.max(np.abs(warm.a - cold.a)) < 1e-6 * cold.a.max()
    assert warm.iterations < cold.iterations
    n = len(a_lin)
    lo, hi = n // 4, n // 2
    args = (again, first.a[lo:hi + 1], lo, (cold.a[lo], cold.a[hi]), (cold.b[lo], cold.b[hi]), (0, 0))
    win = ipm.solve(*args, start=first.start)
    assert win.start.band is not first.start.band
    assert np.array_equal(win.a, ipm.solve(*args).a)


def test_a_held_end_no_row_can_follow_is_no_solution():
    """An end held at ten times the speed cap squared: the first-order rows at the next stations
    cannot be met (b is continuous), so no solution, named with its stations."""
    piece, rows, a_lin = optimal_piece(KEOPS)
    lo, hi = 10, 60
    a_end = 10 * float(rows.amax[lo])
    with pytest.raises(ipm.NoSolution, match=rf"stations {lo}…{hi}"):
        ipm.solve(rows, a_lin[lo:hi + 1], lo, (a_end, a_lin[hi]), (0.0, 0.0), (0, 0))


def test_the_engine_solves_by_the_ipm_and_falls_back_to_clarabel(monkeypatch):
    """The engine at COPP's settings on the short path: every solve by the IPM
    (info["ipm_fallbacks"] 0) to the time of copp-py's own solve (`copp`: Settings.solver
    "clarabel"); where the IPM has no solution, the same rows go to Clarabel, counted."""
    path = short_path(KEOPS)
    solve = lambda solver: topp3.solve(path, KEOPS, KEOPS.limits, topp3.Settings("engine", 0.1, solver=solver))
    p, c = solve("ipm"), solve("clarabel")
    assert p.info["ipm_fallbacks"] == 0 == c.info["ipm_fallbacks"]
    assert p.execution_time_s == pytest.approx(c.execution_time_s, rel=2e-3)

    def fail(*_a, **_k):
        raise ipm.NoSolution("test")
    monkeypatch.setattr(ipm, "solve", fail)
    q = solve("ipm")
    assert q.info["ipm_fallbacks"] > 0
    assert q.execution_time_s == c.execution_time_s
