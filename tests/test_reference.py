"""The corpus's yardstick (issue 32): benchmarks/paths/corpus/reference.py against the
jerk-limited closed form on a line, its Richardson arithmetic, and reference.json covering
every corpus path with a current entry."""
from __future__ import annotations

import importlib.util
import json
import math
import pickle

import numpy as np
import pytest

from harness.corpus.run import CORPUS_DIR, load_manifest
from kins import load_machine
from planners.paths import Line, NurbsPath, SegmentPath


def _ref():
    spec = importlib.util.spec_from_file_location("corpus_reference", CORPUS_DIR / "reference.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_richardson_recovers_a_second_order_limit():
    R = _ref()
    T = [2.0 + 0.3 * h ** 2 for h in (1.0, 0.5, 0.25, 0.125)]
    Ts, err, p = R.richardson(T)
    assert p == pytest.approx(2.0, abs=1e-9)
    assert Ts == pytest.approx(2.0, abs=1e-12)
    # its bar: the last correction |T* − T₄| = 0.3/64 (the limits of the two triples agree)
    assert err == pytest.approx(0.3 / 64, rel=1e-6)
    # differences that change sign: no order, no extrapolation, the larger difference as the bar
    Ts, err, p = R.richardson([1.0, 1.003, 1.001])
    assert (Ts, err, math.isnan(p)) == (1.001, pytest.approx(0.003), True)


def test_a_fourth_grid_where_three_leave_a_wide_bar_and_it_stays_small(monkeypatch):
    """After LEVELS grids, reference() adds one while the bar is above WIDE_BAR of T* and the
    next grid has at most ``wide_nodes`` nodes. The solves stubbed with a first-order time
    T = 1 + c/cells: T* = 1 exactly and the bar is the last correction c/cells, so on the grids
    of 172, 344, 688 cells c = 2 leaves 0.29 % (a fourth grid, 1376 cells: 0.15 %), c = 1 0.15 %."""
    R = _ref()
    m = load_machine("kossel")
    path = SegmentPath([Line([0, 0, -300], [0, 0, -290])])

    def stub(c):
        def solve(D, warm, where, log=None, resume=None, save=None):
            n = len(D.s)
            x = (D.s - D.s[0]) / (D.scale[0] * D.scale[1])
            return 1.0 + c / (n - 1), np.ones(n), np.zeros(n), np.diff(x), np.zeros(n - 1), 1, "Solve_Succeeded"
        return solve

    monkeypatch.setattr(R, "check_at_T", lambda *a: {})
    out = {}
    for c, wide_nodes in ((2.0, 10 ** 6), (2.0, 1000), (1.0, 10 ** 6)):
        monkeypatch.setattr(R, "solve_with_reads", stub(c))
        r = R.reference(path, m, levels=3, base_nodes=100, wide_nodes=wide_nodes)
        out[c, wide_nodes] = ([g["nodes"] for g in r["grids"]], r["T_reference_s"], r["error_s"])
    n, Ts, err = out[2.0, 1000]
    assert n == [173, 345, 689] and Ts == pytest.approx(1.0, abs=1e-12) and err == pytest.approx(2 / 688)
    assert out[2.0, 10 ** 6][0] == n + [1377] and out[2.0, 10 ** 6][2] == pytest.approx(2 / 1376)
    assert out[1.0, 10 ** 6][0] == n


def test_a_slow_point_is_graded_on_each_side_by_that_side_s_room():
    """Map's grading around a slow point c: within its zone ℓ the map adds G = (3ℓ^⅔d^⅓ − d)/h
    cells at d from c, so next to c the nodes lie at d ∝ σ³ (d₂/d₁ = 8, d₃/d₂ = 27/8) and the
    zone holds ℓ/h + 2ℓ/h cells.  A second slow point 0.2 mm to the right limits the zone on that
    side only, and the same point listed twice 1e-13 mm apart is one (VERSION 7 gave c one zone of
    half the nearer gap on both sides: the braking before a U-turn's join was not graded)."""
    R = _ref()
    h, ell = 1.0, 20.0
    path = SegmentPath([Line([0, 0, -300], [100, 0, -300])])
    s, brk = R.Map(path, 0.0, 100.0, [50.0], h, ell, slow=[50.0, 50.0 + 1e-13, 50.2]).nodes(0)
    k = int(np.argmin(np.abs(s - 50.0)))
    assert s[k] == 50.0 and list(brk) == [k]
    d = 50.0 - s[k - 3:k][::-1]
    assert d[1] / d[0] == pytest.approx(8.0, rel=0.02)
    assert d[2] / d[1] == pytest.approx(27 / 8, rel=0.02)
    assert np.count_nonzero((s >= 50.0 - ell) & (s < 50.0)) == pytest.approx(3 * ell / h, abs=1)
    # to the right the zone is 0.1 mm (half the way to 50.2): 0.2 cells, no node before 50.2
    assert not np.any((s > 50.0) & (s < 50.2 - 1e-9))


@pytest.mark.slow
def test_a_line_driving_the_joints_one_to_one_is_the_closed_form():
    """q = z + const on kossel's three joints: the minimum time rest to rest is the 1-D
    jerk-limited optimum L/V + 2√(V/J) (V·J ≤ A²: A is never reached). The extrapolated
    reference lies within its error bar of it, the bar is < 0.03 %, and the finest profile,
    sampled at T, keeps the joint limits to 0.1 % (what it overshoots between its nodes)."""
    R = _ref()
    m = load_machine("kossel")
    lim = m.limits.joint
    assert lim.v * lim.j <= lim.a ** 2
    L = 5.0
    exact = L / lim.v + 2 * math.sqrt(lim.v / lim.j)
    r = R.reference(SegmentPath([Line([0, 0, -300], [0, 0, -300 + L])]), m, levels=4, base_nodes=150)
    assert abs(r["T_reference_s"] - exact) <= r["error_s"] + 1e-7
    assert r["error_s"] < 3e-4 * exact          # a tenth of the 0.3 % the planners are held to
    # nested grids: each twice the cells of the one before; the finest within 0.01 % already
    n = [g["nodes"] for g in r["grids"]]
    assert all(b - 1 == 2 * (a - 1) for a, b in zip(n, n[1:]))
    assert r["grids"][-1]["T_s"] == pytest.approx(exact, rel=1e-4)
    assert max(r["check_at_T"]["joint_peak_ratio"].values()) <= 1 + 1e-3   # the finest grid between its nodes


def test_a_refined_start_is_the_coarse_profile_itself():
    """refine_warm puts the coarse cubic on the twice-finer nodes: every new node lies on it
    (s(τ) reaches the node's arc length), the cells' relations of the transcription hold
    exactly, and the durations add up to the coarse ones, so a refinement starts from a
    profile as fast and as feasible as the coarse optimum."""
    R = _ref()
    rng = np.random.default_rng(3)
    n = 9
    a = np.concatenate([[0.0], rng.uniform(-0.3, 0.6, n - 1)])
    dt = rng.uniform(0.5, 1.5, n - 1)
    j = np.diff(a) / dt
    v = 0.5 + np.concatenate([[0.0], np.cumsum(0.5 * (a[:-1] + a[1:]) * dt)])   # a chain of cubics
    x = np.concatenate([[0.0], np.cumsum(v[:-1] * dt + (2 * a[:-1] + a[1:]) * dt ** 2 / 6)])
    assert (np.diff(x) > 0).all()
    xf = np.empty(2 * n - 1)
    xf[0::2] = x
    xf[1::2] = x[:-1] + rng.uniform(0.2, 0.8, n - 1) * np.diff(x)
    vf, af, dtf, jf = R.refine_warm(x, v, a, dt, j, xf)
    np.testing.assert_allclose(dtf[0::2] + dtf[1::2], dt, rtol=1e-12)
    np.testing.assert_allclose(af[1:] - af[:-1], jf * dtf, atol=1e-12)
    np.testing.assert_allclose(vf[1:] - vf[:-1], 0.5 * (af[:-1] + af[1:]) * dtf, atol=1e-12)
    np.testing.assert_allclose(np.diff(xf), vf[:-1] * dtf + (2 * af[:-1] + af[1:]) * dtf ** 2 / 6, atol=1e-12)


def test_knot_jumps_are_the_knots_where_q2_jumps():
    """A quadratic NURBS's P″ jumps at every simple interior knot: each one's read matters; a
    cubic's P″ is continuous there: none does."""
    R = _ref()
    m = load_machine("kossel")
    P = [[-8, -6, -300], [-3, 6, -300], [2, -6, -300], [6, 5, -300], [9, -4, -300], [12, 3, -300]]
    quad = NurbsPath(2, [0, 0, 0, 0.25, 0.5, 0.75, 1, 1, 1], P)
    cubic = NurbsPath(3, [0, 0, 0, 0, 1 / 3, 2 / 3, 1, 1, 1, 1], P)
    for path, expect in ((quad, 3), (cubic, 0)):
        knots = list(path.s_of_u(np.unique(path.knots)[1:-1]))
        assert len(R.knot_jumps(path, m, knots)) == expect


# the head of cam_dense_keops.ngc: 9 chords of 0.15–0.6 mm under G64 P0.01 on keops
CAM_LINES = 12
# half the corpus's BASE_NODES: the same contrast at a third of the CPU (docs/TUNING.md, twenty-eighth session)
CAM_BASE_NODES = 300


def _cam_head(m):
    from planners.paths.gcode import parse_gcode, program_path
    text = "\n".join((CORPUS_DIR / "cam_dense_keops.ngc").read_text().splitlines()[:CAM_LINES]) + "\nM2\n"
    return program_path(parse_gcode(text, "cam_dense_keops_head.ngc"))


def test_a_join_s_rows_read_what_its_samples_read_at_t(monkeypatch):
    """add_kernel_reads's rows, evaluated on the solved grid, against a second method: the
    profile's exact samples (its cubics, R.sample_profile, at the phase that centres a window δ
    periods from the join), through the IK, third-differenced. They agree to the quadrature's
    error at every join and phase, and the solve holds them within J."""
    import casadi as ca
    from planners.verify import differences
    R = _ref()
    m = load_machine("keops")
    path = _cam_head(m)
    calls, finest = [], {}
    solve = R.solve_piece

    def spy(D, warm=None, reads=None, at=None):
        out = solve(D, warm, reads, at)
        calls.append((D, reads, out))
        return out

    monkeypatch.setattr(R, "solve_piece", spy)
    monkeypatch.setattr(R, "check_at_T", lambda p, machine, prof: finest.setdefault("prof", prof) and {})
    R.reference(path, m, levels=1, base_nodes=CAM_BASE_NODES)
    D, reads, (_, v, a, dt, j, _, _) = [c for c in calls if c[1] is not None and c[0].s[0] == 0.0][-1]
    assert len(finest["prof"]) == 1 and len(D.kappa) >= 5          # one rest piece, its joins
    n, mc = len(v), len(dt)
    sv, sa, sj = (ca.SX.sym(x, k) for x, k in (("v", n), ("a", n), ("j", mc)))
    rows = []
    # the reads' rows (−1 ≤ read ≤ 1) with the kernel's weights at the solution's own times
    R.add_kernel_reads(D, lambda e, lo, hi: rows.append(e), sv, sa, sj, sv * sv, reads, dt)
    f = ca.Function("reads", [sv, sa, sj], [ca.vertcat(*rows)])
    tn = np.concatenate([[0.0], np.cumsum(dt)])
    model = np.asarray(f(v, a, j)).reshape(len(D.kappa), len(R.KERNEL_PHASES), 3)
    assert np.abs(model).max() <= 1.0 + 1e-6
    T, J = m.servo_period_s, m.limits.joint.j
    tu = D.scale[0]
    worst = 0.0
    for row, i in zip(model, D.kappa):
        for read, delta in zip(row, R.KERNEL_PHASES):
            start = tn[i] * tu + (delta - 1.5) * T                 # the window's first sample
            s = R.sample_profile(finest["prof"], T, delay=(-start) % T)
            k0 = int(round((start + (-start) % T) / T))
            Q = m.ik(path.point(s[k0:k0 + 4]))
            exact = differences(Q, T, rest=False)["jerk"][0] / J
            worst = max(worst, float(np.abs(exact - read).max()))
    assert worst < 0.01, worst           # the quadrature: 0.0031 × J here (docs/TUNING.md)


def _pocket_head(R):
    """pocket_kossel's first 7 lines (one rest piece with a 158° blend), its machine and the
    corpus path's node spacing as base_nodes."""
    from planners.paths.gcode import parse_gcode, program_path
    text = "\n".join((CORPUS_DIR / "pocket_kossel.ngc").read_text().splitlines()[:7]) + "\nM2\n"
    path = program_path(parse_gcode(text, "pocket_kossel_head.ngc"))
    whole = next(e for e in load_manifest() if e["name"] == "pocket_kossel")
    return path, load_machine("kossel"), R.BASE_NODES * path.length / whole["length_mm"]


def test_the_kernel_weights_times_settle_where_undamped_they_flip_between_two_solutions(monkeypatch):
    """The first rest piece of pocket_kossel (two G64 lines, a 158° blend), its level 0 at the
    corpus's node spacing: solved again with the weights at each solution's times, it flips
    between two solutions 0.028 periods apart; relaxed (Aitken's step) it settles within
    FIX_TOL, where the rows are its own reads."""
    R = _ref()
    path, m, base = _pocket_head(R)
    rounds = []
    r = R.reference(path, m, levels=1, base_nodes=base, round_log=rounds.append)
    moves = [float(x.split("moved ")[1].split()[0]) for x in rounds]
    steps = [float(x.split("step ")[1]) for x in rounds]
    assert moves[-1] < R.FIX_TOL and min(steps) < 0.9
    assert r["grids"][0]["nodes"] == 107
    monkeypatch.setattr(R, "FIX_STEP_MIN", 1.0)
    monkeypatch.setattr(R, "FIX_ROUNDS", 12)
    flips = []
    with pytest.raises(RuntimeError, match=r"piece 0 .* level 0: after 12 solves"):
        R.reference(path, m, levels=1, base_nodes=base, round_log=flips.append)
    T = [float(x.split("T ")[1].split()[0]) for x in flips]
    assert abs(T[-1] - T[-3]) < 1e-8 < abs(T[-1] - T[-2])           # a 2-cycle, not a slow drift


def test_a_study_stopped_and_gone_on_from_its_checkpoint_ends_with_the_same_numbers(tmp_path):
    """The pocket_kossel head's two-level study, killed mid-iteration in level 0 (after Aitken's
    step left 1) and again in level 1, each time gone on from its checkpoint by a new process's
    worth of state (the file alone): its grids, limit and check at T equal the uninterrupted
    study's to the bit. A checkpoint of another key is not read; a corrupt one is an error
    naming the file."""
    R = _ref()
    path, m, base = _pocket_head(R)
    plain = R.reference(path, m, levels=2, base_nodes=base)

    class Killed(Exception):
        pass

    class KilledAt(R.Checkpoint):
        def __init__(self, file, key, at):
            super().__init__(file, key)
            self.at = at

        def save(self, state):
            super().save(state)
            r = state["rounds"]
            if r and (state["level"], r["round"]) == self.at:
                raise Killed

    file = tmp_path / "head.pkl"
    for at in ((0, 3), (1, 2)):
        with pytest.raises(Killed):
            R.reference(path, m, levels=2, base_nodes=base, checkpoint=KilledAt(file, "k", at))
    cp = R.Checkpoint(file, "k")
    assert (cp.state["level"], cp.state["rounds"]["round"]) == (1, 2)
    assert cp.state["grids"][0]["T_s"] == plain["grids"][0]["T_s"]
    logs = []
    gone_on = R.reference(path, m, levels=2, base_nodes=base, checkpoint=cp, log=logs.append)
    assert logs[0] == "  resumed at level 1, piece 0, round 2"
    key = lambda r: ([(g["nodes"], g["T_s"], g["iterations"]) for g in r["grids"]],  # noqa: E731
                     r["T_reference_s"], r["error_s"], r["check_at_T"])
    assert key(gone_on) == key(plain)
    assert R.Checkpoint(file, "another key").state is None
    for junk in (b"not a pickle", pickle.dumps([1, 2]), pickle.dumps({"key": "k"})):
        file.write_bytes(junk)
        with pytest.raises(RuntimeError, match="head.pkl is unreadable"):
            R.Checkpoint(file, "k")


def test_a_study_written_keeps_the_studies_another_run_wrote_meanwhile(tmp_path, monkeypatch, capsys):
    """Two runs on one reference file (a path per core): each writes its study into the file as it
    is then, so the other's, written while this one solved, is kept; the entry is this run's key
    and numbers, the checkpoint is gone."""
    R = _ref()
    out = tmp_path / "ref.json"
    R.store({"butterfly_kossel": {"key": "old"}}, out)
    study = {"T_reference_s": 2.5, "error_s": 0.01, "order": 2.0, "grids": [{"nodes": 3, "T_s": 2.6}],
             "check_at_T": {"execution_time_s": 2.6, "joint_peak_ratio": {"jerk": 1.0}}}

    def solve_while_the_other_run_writes(path, machine, checkpoint=None, **kw):
        checkpoint.save({"level": 0})
        R.store({"butterfly_lcnc": {"key": "the other run's"}}, out)
        return study

    monkeypatch.setattr(R, "reference", solve_while_the_other_run_writes)
    assert R.main(["--paths", "butterfly_keops", "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    assert list(data["paths"]) == ["butterfly_keops", "butterfly_kossel", "butterfly_lcnc"]
    assert data["paths"]["butterfly_lcnc"] == {"key": "the other run's"}
    e = next(e for e in load_manifest() if e["name"] == "butterfly_keops")
    assert data["paths"]["butterfly_keops"]["key"] == R.entry_key(e)
    assert data["paths"]["butterfly_keops"]["T_reference_s"] == 2.5
    assert not (tmp_path / "ref.checkpoints" / "butterfly_keops.pkl").exists()
    assert "butterfly_keops: T_ref = 2.500000" in capsys.readouterr().out


@pytest.mark.slow
def test_a_g64_program_s_reference_keeps_the_jerk_at_t_whatever_the_phase(monkeypatch):
    """Short chords blended under G64: with the joins' kernel reads, the finest profile sampled
    at T keeps J (to 0.5 %) at four phases of the servo clock, the three between KERNEL_PHASES's
    too; with the join's node alone (VERSION 6's rows) the same grid reads 1.87 × J next to the
    joins."""
    from planners.verify import command_metrics
    R = _ref()
    m = load_machine("keops")
    path = _cam_head(m)
    finest = {}
    check = R.check_at_T
    monkeypatch.setattr(R, "check_at_T", lambda p, machine, prof: (finest.setdefault("prof", prof),
                                                                      check(p, machine, prof))[1])
    r = R.reference(path, m, levels=2, base_nodes=CAM_BASE_NODES)
    assert r["check_at_T"]["joint_peak_ratio"]["jerk"] <= 1.005
    T = m.servo_period_s
    for d in (0.25, 0.5, 0.75):
        s = R.sample_profile(finest["prof"], T, delay=d * T)
        assert command_metrics(m, path.point(s), T, s)["joint_peak_ratio"]["jerk"] <= 1.005, d
    monkeypatch.setattr(R, "check_at_T", check)
    monkeypatch.setattr(R, "add_kernel_reads", lambda D, add, v, a, j, b, reads, dt0:
                        R.add_join_node_reads(D, add, v, a, j, b))
    alone = R.reference(path, m, levels=2, base_nodes=CAM_BASE_NODES)
    assert alone["check_at_T"]["joint_peak_ratio"]["jerk"] > 1.3
    # the reads cost time: the node-alone profile is faster by what it breaks
    assert alone["T_reference_s"] < r["T_reference_s"]


# Issue 32 is open on these (benchmarks/paths/corpus/README.md): paths without a reference yet
# (none since the thirtieth session), paths whose study is not of the current VERSION (12:
# cam_dense_lcnc keeps VERSION 10's, whose pointwise rows lie above the kernel's), and bars above
# 0.2 % of T_ref (cam_dense_lcnc's VERSION 10 study; cam_dense_keops's VERSION 12 one, 0.25 %, order
# 1.42, a fourth grid barred by WIDE_NODES).
# The test fails when one is closed (shrink the set) and when a new one appears.
NO_REFERENCE = set()
NOT_CURRENT = {"cam_dense_lcnc"}
WIDE_BAR = {"cam_dense_keops", "cam_dense_lcnc"}
# finest profiles that read above 1.005 × J at T: VERSION 12 held the phases by 1/16 (VERSION 11,
# by ⅛: pocket_kossel 1.009 → 1.0004, pocket_lcnc 1.0089 → 1.0017), but cam_dense_keops's finest
# grid reads 1.0093 × J next to its joins (docs/TUNING.md, forty-ninth session)
OVER_J = {"cam_dense_keops"}


def test_reference_json_has_a_current_entry_for_every_corpus_path_but_the_known_gaps():
    R = _ref()
    data = json.loads((CORPUS_DIR / "reference.json").read_text())["paths"]
    missing, wide, old, over = set(), set(), set(), set()
    for e in load_manifest():
        if e["name"] not in data:
            missing.add(e["name"])
            continue
        r = data[e["name"]]
        if r["key"] != R.entry_key(e):
            old.add(e["name"])
        assert set(r) >= {"T_reference_s", "error_s", "grids"}
        T = [g["T_s"] for g in r["grids"]]
        assert len(T) >= 3 and all(g["nodes"] > 0 for g in r["grids"])
        assert r["error_s"] >= 0
        # the bar: at most 0.2 % of the time (optimal is held to 0.3 % of it)
        if r["error_s"] > 2e-3 * r["T_reference_s"]:
            wide.add(e["name"])
        # a reference is a profile, not only a number: its finest grid, sampled at T, keeps the
        # joint limits to what it overshoots between nodes, on every path (VERSION 5 read up to
        # 1.75 × J on smooth paths, VERSION 6 up to 1.99 × J next to the G1 joins of the CAM programs)
        peak = max(r["check_at_T"]["joint_peak_ratio"].values())
        assert peak <= 1.01, e["name"]
        if peak > 1.005:
            over.add(e["name"])
    assert missing == NO_REFERENCE, "paths without a reference (run benchmarks/paths/corpus/reference.py)"
    assert old == NOT_CURRENT, "paths whose reference is out of date (run benchmarks/paths/corpus/reference.py)"
    assert wide == WIDE_BAR, "paths whose reference's bar is above 0.2 %"
    assert over == OVER_J, "paths whose finest profile reads above 1.005 × a joint limit at T"
