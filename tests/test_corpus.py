"""The toolpath corpus (issue 19): its manifest and files, the generator's reproducibility,
`pkmbench corpus` on the quick subset, the performance-profile arithmetic, failures as rows,
and the fixes the corpus exposed (blend gaps, stencil off the path, tables missing lobe tips,
scurve_joint's joint jerk on the butterfly in kossel)."""
from __future__ import annotations

import csv
import importlib.util
import json
import math
import re

import numpy as np
import pytest

import planners
from harness.cli import main as cli_main
from harness.corpus.analysis import (below_reference, performance_profile, ratios, seed_spread, summary,
                                     swarm_spread)
from harness.corpus.report import write_markdown
from harness.corpus.run import CORPUS_DIR, QUICK_PATHS, Row, load_manifest, run_corpus
from kins import load_machine
from planners.constraints import PathTable, check_path_in_workspace, join_jumps, joint_derivs
from planners.paths import load_path
from planners.paths.blend import blend_corners
from planners.paths.segments import Arc, Line, SegmentPath
from planners.verify import command_metrics


def _maker():
    spec = importlib.util.spec_from_file_location("make_corpus", CORPUS_DIR / "make_corpus.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


# -- the corpus itself --------------------------------------------------------------------------
def test_manifest_covers_machines_kinds_and_sources():
    E = load_manifest()
    assert len(E) >= 40
    by_machine = {m: sum(e["machine"] == m for e in E) for m in ("keops", "kossel", "linuxcnc_delta")}
    assert min(by_machine.values()) >= 8, by_machine
    kinds = {e["kind"] for e in E}
    assert {"nurbs-literature", "nurbs-random", "gcode-contour", "gcode-pocket", "gcode-helix", "gcode-cam",
            "nurbs-knot", "nurbs-rational", "gcode-meander", "nurbs-meander", "nurbs-spiral", "nurbs-cusp"} <= kinds
    assert len({e["name"] for e in E}) == len(E)
    for e in E:
        assert (CORPUS_DIR / e["file"]).is_file(), e["file"]
        assert e["source"] and e["hard"], e["name"]
        if e["kind"] == "nurbs-literature":
            assert "github.com/aygxywlw/CNC-NURBS-Interpolation" in e["source"]
    # the generator's ranges: 20…150 control points, radii down to ≤ 0.1 mm
    cps = [e["control_points"] for e in E if e["kind"] == "nurbs-random"]
    assert min(cps) <= 20 and max(cps) >= 150
    assert min(e["min_radius_mm"] for e in E if e["kind"] == "nurbs-random") <= 0.1


def test_every_corpus_path_fits_its_machine():
    for e in load_manifest():
        m = load_machine(e["machine"])
        path = load_path(CORPUS_DIR / e["file"], home=m.home)
        check_path_in_workspace(path, m, step_mm=1.0)       # raises naming the point
        assert path.length == pytest.approx(e["length_mm"], abs=2e-3)


def test_generator_reproduces_the_files_byte_for_byte(tmp_path):
    names = {"rand_3d_weights_kossel", "rand_hairpin_keops", "cam_blend_kossel", "butterfly_kossel",
             "rational_quadratic_kossel", "meander_kossel"}
    C = _maker().build(out=tmp_path, only=names)
    assert {e["name"] for e in C.entries} == names
    for e in C.entries:
        got, want = (tmp_path / e["file"]).read_bytes(), (CORPUS_DIR / e["file"]).read_bytes()
        if got != want and e["file"].endswith(".json"):
            # another SIMD path moves a control point's last digit (rand_3d_weights_kossel on an
            # AMD EPYC, 2026-12-05): equal within 1e-12 relative, the cross-machine contract
            a, b = json.loads(got), json.loads(want)
            assert {k: v for k, v in a.items() if not isinstance(v, list)} == \
                {k: v for k, v in b.items() if not isinstance(v, list)}, e["file"]
            for k, v in b.items():
                if isinstance(v, list):
                    np.testing.assert_allclose(np.asarray(a[k], float), np.asarray(v, float), rtol=1e-12,
                                               atol=1e-12, err_msg=e["file"])
        else:
            assert got == want, e["file"]
    man = {e["name"]: e for e in load_manifest()}
    for e in C.entries:
        assert e["seed"] == man[e["name"]]["seed"]


def test_suite_lists_every_corpus_path_once():
    import tomllib
    suite = tomllib.loads((CORPUS_DIR.parent.parent / "suites" / "corpus.toml").read_text())
    files = [(r["machine"], p) for r in suite["run"] for p in r["paths"]]
    want = [(e["machine"], f"benchmarks/paths/corpus/{e['file']}") for e in load_manifest()]
    assert sorted(files) == sorted(want)


def test_a_suite_s_paths_are_corpus_entries_with_the_manifest_s_names(tmp_path):
    """`pkmbench corpus --suite`: each suite path on each machine is an entry; a corpus path
    carries its manifest entry (name, kind), any other path its file's stem and kind '-'."""
    from harness.corpus.run import CorpusError
    from harness.corpus.suite import entries_from_suite
    by_name = {e["name"]: e for e in load_manifest()}
    corpus = f"benchmarks/paths/corpus/{by_name['contour_lcnc']['file']}"
    other = tmp_path / "line.ngc"
    other.write_text("G21 G90\nG0 X0 Y0 Z-300\nF600\nG1 X10\nM2\n")
    suite = tmp_path / "s.toml"
    suite.write_text(f'name = "s"\n[[run]]\nmachine = "kossel"\npaths = ["{corpus}", "{other}"]\n'
                     f'planners = ["trapezoid", "scurve"]\n[[run]]\nmachine = "keops"\npaths = ["{other}"]\n'
                     f'planners = ["trapezoid"]\n')
    got = entries_from_suite(suite)
    assert [(e["name"], e["machine"], e["kind"], p) for e, p in got] == [
        ("contour_lcnc", "kossel", by_name["contour_lcnc"]["kind"], ["trapezoid", "scurve"]),
        ("line", "kossel", "-", ["trapezoid", "scurve"]),
        ("line", "keops", "-", ["trapezoid"])]
    assert got[0][0]["file"] == str(CORPUS_DIR / by_name["contour_lcnc"]["file"])
    suite.write_text("[[run]\n")
    with pytest.raises(CorpusError, match="s.toml"):
        entries_from_suite(suite)
    with pytest.raises(CorpusError, match="cannot read suite"):
        entries_from_suite(tmp_path / "missing.toml")


# -- the performance profile -----------------------------------------------------------------
def _row(path, planner, T=math.nan, feasible=False, status="ok"):
    return Row(path, "m", "k", planner, status, T, feasible, True, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 1.0)


def test_performance_profile_by_hand():
    rows = [_row("A", "p", 1.0, True), _row("A", "q", 2.0, True),
            _row("B", "p", 0.5, False), _row("B", "q", 3.0, True),
            _row("C", "p", status="failed"), _row("C", "q", status="failed")]
    R = ratios(rows)
    # A: best 1.0 → p 1, q 2; B: p infeasible (its shorter T does not count) → q is best; C: none
    assert R["p"] == {"A": 1.0, "B": math.inf, "C": math.inf}
    assert R["q"] == {"A": 2.0, "B": 1.0, "C": math.inf}
    rho = performance_profile(rows, [1.0, 1.5, 2.0, 100.0])
    assert rho["p"].tolist() == pytest.approx([1 / 3, 1 / 3, 1 / 3, 1 / 3])
    assert rho["q"].tolist() == pytest.approx([1 / 3, 1 / 3, 2 / 3, 2 / 3])
    S = summary(rows)
    assert (S["q"]["ratio_median"], S["q"]["ratio_worst"], S["q"]["feasible"], S["p"]["failed"]) == (1.5, 2.0, 2, 1)


# -- the command on the quick subset ----------------------------------------------------------
def test_corpus_quick_command(tmp_path, capsys):
    rc = cli_main(["corpus", "--quick", "--out", str(tmp_path), "--store", str(tmp_path / "store")])
    assert rc == 0, capsys.readouterr().out
    with open(tmp_path / "corpus.csv") as f:
        rows = list(csv.DictReader(f))
    assert {(r["path"], r["planner"]) for r in rows} == {(p, k) for p in QUICK_PATHS
                                                         for k in ("trapezoid", "scurve", "scurve_joint")}
    best = {}
    for r in rows:
        assert r["status"] == "ok", r
        jr = max(float(r[k]) for k in ("joint_v", "joint_a", "joint_j"))
        assert (r["feasible"] == "yes") == (jr <= 1 + 1e-6)
        if r["feasible"] == "yes":
            best[r["path"]] = min(best.get(r["path"], math.inf), float(r["execution_time_s"]))
    for r in rows:
        assert float(r["ratio_to_best"]) == pytest.approx(float(r["execution_time_s"]) / best[r["path"]], rel=1e-9)
        if r["planner"] == "scurve_joint":          # its definition: joint-feasible
            assert r["feasible"] == "yes", r
    md = (tmp_path / "corpus.md").read_text()
    assert "| scurve_joint | 3 | 3 | 3 |" in md
    # the same rows, appended to the results store as one corpus run
    from harness.store import ResultStore
    with ResultStore(tmp_path / "store") as st:
        stored = st.dicts("SELECT path, planner, kind, status, execution_time_s, feasible, joint_velocity, "
                          "joint_acceleration, joint_jerk, planning_time_s, "
                          "metrics->>'$.\"cartesian_peak_ratio.jerk\"' AS cart_j FROM results")
        assert st.dicts("SELECT kind, rows, failed FROM runs") == [{"kind": "corpus", "rows": 9, "failed": 0}]
    by = {(r["path"], r["planner"]): r for r in stored}
    assert set(by) == {(r["path"], r["planner"]) for r in rows}
    for r in rows:
        got = by[(r["path"], r["planner"])]
        assert got["kind"] == "corpus" and got["status"] == "ok" and got["feasible"] == (r["feasible"] == "yes")
        for col, csv_col in (("execution_time_s", "execution_time_s"), ("joint_velocity", "joint_v"),
                             ("joint_acceleration", "joint_a"), ("joint_jerk", "joint_j"),
                             ("planning_time_s", "planning_time_s"), ("cart_j", "cart_j")):
            assert float(got[col]) == pytest.approx(float(r[csv_col]), rel=1e-9), (col, r)
    for png in ("performance_profile.png", "ratio_to_reference.png"):
        assert (tmp_path / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_an_interrupted_corpus_keeps_its_rows_and_resume_plans_only_the_rest(tmp_path, monkeypatch, capsys):
    import harness.corpus.run as corpus_run
    from harness.corpus import journal
    from harness.corpus.journal import JOURNAL
    real, calls, stop_at = corpus_run.run_one, [], [2]

    def one(entry, planner, machine, path, seed=None):
        if len(calls) == stop_at[0]:
            raise KeyboardInterrupt
        calls.append((entry["name"], planner))
        return real(entry, planner, machine, path, seed)

    monkeypatch.setattr(corpus_run, "run_one", one)
    args = ["corpus", "--quick", "--planners", "scurve_joint,trapezoid", "--out", str(tmp_path), "--store", "none"]
    (tmp_path / "corpus.csv").write_text("an earlier run's table\n")
    assert cli_main(args) == 130
    assert "--resume" in capsys.readouterr().out
    assert not (tmp_path / "corpus.csv").exists()              # nothing that looks complete
    kept = [json.loads(x)["row"] for x in (tmp_path / JOURNAL).read_text().splitlines()]
    assert [(r["path"], r["planner"]) for r in kept] == calls and [k for _, k in calls] == ["scurve_joint", "trapezoid"]
    with open(tmp_path / JOURNAL, "a") as f:
        f.write('{"code": "cut by the kil')                    # a line the interruption cut
    stop_at[0] = None
    assert cli_main(args + ["--resume"]) == 0
    assert "2 rows kept" in capsys.readouterr().out
    assert len(calls) == 6 and len(set(calls)) == 6            # only the four not finished were planned
    with open(tmp_path / "corpus.csv") as f:
        rows = {(r["path"], r["planner"]): r for r in csv.DictReader(f)}
    assert len(rows) == 6
    for r in kept:
        assert float(rows[(r["path"], r["planner"])]["execution_time_s"]) == r["execution_time_s"]
    # the rows of a planner whose code changed are planned again, the others' are kept
    code = journal.planner_code
    monkeypatch.setattr(journal, "planner_code", lambda name: "other" if name == "trapezoid" else code(name))
    assert cli_main(args + ["--resume"]) == 0
    out = capsys.readouterr().out
    assert "3 rows kept" in out and "3 made by other code planned again" in out
    assert len(calls) == 9 and {k for _, k in calls[6:]} == {"trapezoid"}
    # one run at a time writes a folder's rows
    from harness.outdir import run_lock
    with run_lock(tmp_path):
        assert cli_main(args + ["--resume"]) == 2
    assert "another pkmbench run is writing" in capsys.readouterr().err and len(calls) == 9


def test_scurve_and_trapezoid_keep_their_cartesian_limits_on_the_quick_paths():
    """scurve keeps what the registry says it keeps (Cartesian v/a/j and feed); trapezoid
    declares nothing (own limits: None) but keeps the Cartesian v and a it plans with."""
    e = {x["name"]: x for x in load_manifest()}
    rows = run_corpus([(e[p], ["trapezoid", "scurve"]) for p in QUICK_PATHS])
    assert all(r.own_limits_ok for r in rows if r.planner == "scurve")
    assert all(r.own_limits_ok is None for r in rows if r.planner == "trapezoid")
    bad = [(r.path, r.cart_v, r.cart_a) for r in rows if r.planner == "trapezoid" and max(r.cart_v, r.cart_a) > 1 + 1e-6]
    assert not bad, bad


def test_corpus_store_none_appends_nothing(tmp_path, monkeypatch):
    monkeypatch.setenv("PKMBENCH_STORE", str(tmp_path / "store"))
    args = ["corpus", "--paths", "contour_lcnc", "--planners", "trapezoid", "--out", str(tmp_path / "o")]
    assert cli_main(args + ["--store", "none"]) == 0
    assert not (tmp_path / "store").exists()
    assert cli_main(args) == 0                                    # the default store: $PKMBENCH_STORE
    assert len(list((tmp_path / "store").glob("*.parquet"))) == 1


def test_bad_paths_glob_is_a_user_error(tmp_path, capsys):
    assert cli_main(["corpus", "--paths", "no_such_path*", "--out", str(tmp_path)]) == 2
    assert "no_such_path*" in capsys.readouterr().err


def _fails(path, machine, limits=None, **kw):
    raise planners.PlanningError("scurve: at s = 1 mm the joint jerk limit 1e4 cannot be met")


def _crashes(path, machine, limits=None, **kw):
    return 1 / 0


def test_a_failing_planner_is_a_row_and_the_others_go_on(monkeypatch):
    from planners import registry
    monkeypatch.setitem(registry.BUILTIN, "trapezoid", (__name__, "_fails"))
    monkeypatch.setitem(registry.BUILTIN, "scurve", (__name__, "_crashes"))
    e = next(e for e in load_manifest() if e["name"] == "contour_kossel")
    rows = run_corpus([(e, ["trapezoid", "scurve", "scurve_joint"])])
    assert [r.status for r in rows] == ["failed", "error", "ok"]
    assert rows[0].error.startswith("contour_kossel: scurve: at s = 1 mm")
    assert rows[1].error.startswith("contour_kossel: internal error ZeroDivisionError")
    assert rows[2].feasible


# -- the fixes the corpus exposed ---------------------------------------------------------------
def test_blend_of_a_nearly_straight_corner_is_contiguous():
    # a 2e-6 rad turn between 0.04 mm lines on a tilted plane: the blend arc's R ≈ 1e4 mm put its
    # end 1e-7 mm off the next line (acos of the turn, the normal not ⟂ its radius)
    d = 2e-6
    R3 = np.array([[1, 0, 0], [0, np.cos(0.7), -np.sin(0.7)], [0, np.sin(0.7), np.cos(0.7)]])
    p0 = np.array([10.0, -4.0, 12.0])
    u1 = R3 @ np.array([1.0, 0.0, 0.0])
    u2 = R3 @ np.array([np.cos(d), np.sin(d), 0.0])
    a = Line(p0, p0 + 0.04 * u1)
    b = Line(a.end, a.end + 0.04 * u2)
    segs, done = blend_corners([a, b], [0.001])
    assert len(done) == 1
    arc = next(g for g in segs if isinstance(g, Arc))
    assert arc.radius > 5e3
    assert np.linalg.norm(arc.eval(np.array([0.0]), 0)[0][0] - arc.start) < 1e-10
    SegmentPath(segs, "blend")                              # contiguous within 1e-9 mm


def _hairpin(radius):
    """Two lines joined by a half circle of the given radius in kossel's work plane z = -252."""
    c = np.array([-13.0, -10.0, -252.0])
    a = Line(c + [-5.0, radius, 0.0], c + [0.0, radius, 0.0])
    arc = Arc(a.end, c, [0.0, 0.0, 1.0], math.pi)
    return SegmentPath([a, arc, Line(arc.end, arc.end + [-5.0, 0.0, 0.0])], "hairpin"), 5.0 + 0.5 * arc.length


def _central_q1(m, path, s, h):
    return (m.ik(path.point(s + h)) - m.ik(path.point(s - h))) / (2 * h)


def test_joint_derivatives_on_a_micron_blend_arc():
    # a G64 blend of radius 2 µm: the 0.02 mm stencil of the local cubic left the path by
    # h³/6ρ² ≈ 2.7 mm (in reach, but nothing of q(s)); the s-curve's stencil fits the curve
    m = load_machine("kossel")
    path, s = _hairpin(0.002)
    s = np.array([s])
    q, q1, q2, q3 = joint_derivs(m, path, s, fit_scale=True)
    assert q1[0] == pytest.approx(_central_q1(m, path, s, 1e-5)[0], rel=1e-5, abs=1e-8)
    # q″ by a second method: central second difference of the exact IK along the arc
    h = 2e-6
    fd2 = (m.ik(path.point(s + h)) - 2 * q + m.ik(path.point(s - h))) / h ** 2
    assert q2[0] == pytest.approx(fd2[0], rel=1e-3)
    assert np.isfinite(q3).all()


def test_joint_derivatives_where_the_stencil_leaves_the_reach():
    # pocket_kossel's reversal blend has a radius of 0.06 µm: the cubic at ±0.04 mm lies
    # h³/6ρ² ≈ 3 m off the path; this raised "at the edge of reach" (scurve_joint failed)
    m = load_machine("kossel")
    path, s = _hairpin(6e-5)
    s = np.array([s])
    _, q1, _, q3 = joint_derivs(m, path, s)
    assert q1[0] == pytest.approx(_central_q1(m, path, s, 1e-7)[0], rel=1e-4, abs=1e-7)
    assert np.isfinite(q3).all()


def test_table_resolves_the_butterfly_lobe_tip():
    # kossel's butterfly: a lobe tip of ρ ≈ 0.02 mm at s ≈ 84.5 mm, narrower than the 0.05 mm
    # base grid; the s-curve's refined tables' peak q″, q‴ per joint must be the exact ones (the
    # check reads peaks; pointwise, q‴ jumps at the cubic's knots and a straddling cell blends
    # the two sides). The default tables stay unrefined: optimal on keops/bird ran > 10 min on them
    m = load_machine("kossel")
    path = load_path(CORPUS_DIR / "butterfly_kossel.json")
    tab = PathTable(path, m, ds=0.05, fit_scale=True, refine=True)
    s = np.linspace(84.40, 84.65, 2001)
    _, q2_tab, q3_tab = tab.joints(s)
    _, _, q2, q3 = joint_derivs(m, path, s)
    for a, b in ((q2_tab, q2), (q3_tab, q3)):
        assert np.abs(a).max(axis=0) == pytest.approx(np.abs(b).max(axis=0), rel=0.005)


def test_scurve_joint_is_joint_feasible_on_the_kossel_butterfly():
    # issue 19: joint jerk 1.08 × its limit at the lobe tip where the feed drops to ~2 mm/s
    m = load_machine("kossel")
    path = load_path(CORPUS_DIR / "butterfly_kossel.json")
    prof = planners.plan("scurve_joint", path, m)
    met = command_metrics(m, path.point(prof.s), m.servo_period_s, prof.s)
    assert met["joint_peak_ratio"]["jerk"] <= 1 + 1e-6
    assert met["feasible"]


# -- issue 32: the reference, fallbacks, stochastic planners, one table and one profile -----------
def _fallback(path, machine, limits=None, **kw):
    p = planners.plan("scurve_joint", path, machine)
    p.info["source"] = "scurve_joint"
    return p


def test_a_profile_from_another_planner_is_its_rows_failure(monkeypatch):
    """optimal returning scurve_joint's profile (info['source']) is the row's failure: status
    'fallback', measured but never counted (not in the profile, not the best)."""
    from planners import registry
    monkeypatch.setitem(registry.BUILTIN, "optimal", (__name__, "_fallback"))
    e = next(e for e in load_manifest() if e["name"] == "rand_planar_kossel")
    rows = run_corpus([(e, ["optimal", "scurve_joint"])])
    assert [r.status for r in rows] == ["fallback", "ok"]
    assert "scurve_joint's profile" in rows[0].error and rows[0].feasible
    assert ratios(rows)["optimal"] == {"rand_planar_kossel": math.inf}
    assert summary(rows)["optimal"]["failed"] == 1 and summary(rows)["optimal"]["fallbacks"] == 1


def _coin(path, machine, limits=None, seed=0, **kw):
    """A stochastic plug-in: scurve_joint with F_max lowered by seed × 10 %."""
    import dataclasses
    lim = machine.limits
    return planners.plan("scurve_joint", path, machine, dataclasses.replace(lim, feed_max=lim.feed_max / (1 + seed / 10)))


_coin.stochastic = True


def test_a_stochastic_planner_runs_over_seeds_and_is_a_distribution():
    from planners import registry
    assert registry.stochastic("pso") and not registry.stochastic("optimal")
    assert registry.stochastic(f"{__name__}:_coin")
    e = next(e for e in load_manifest() if e["name"] == "rand_planar_kossel")
    name = f"{__name__}:_coin"
    rows = run_corpus([(e, [name, "scurve_joint"])], seeds=4)
    coin = [r for r in rows if r.planner == name]
    assert [r.seed for r in coin] == [0, 1, 2, 3] and all(r.feasible for r in coin)
    sj = next(r for r in rows if r.planner == "scurve_joint")
    assert sj.seed is None and coin[0].execution_time_s == sj.execution_time_s
    T = sorted(r.execution_time_s / sj.execution_time_s for r in coin)   # over the best run, seed 0's
    assert T[0] == 1.0 and T[-1] > 1.1 and len(set(T)) == 4                # F_max binds on this path
    sp = seed_spread(rows, {})[("rand_planar_kossel", name)]
    assert (sp["best"], sp["worst"], sp["n"]) == (pytest.approx(1.0), pytest.approx(T[-1]), 4)
    assert sp["median"] == pytest.approx(np.median(T)) and sp["q1"] == pytest.approx(np.quantile(T, 0.25))
    assert sp["q3"] == pytest.approx(np.quantile(T, 0.75))
    # the profile: the ECDF of the runs, each a quarter of the path
    rho = performance_profile(rows, [1.0, T[1], T[-1]])
    assert rho[name].tolist() == pytest.approx([0.25, 0.5, 1.0])


def test_the_reference_is_the_denominator_where_a_path_has_one():
    rows = [_row("A", "p", 1.02, True), _row("A", "q", 1.10, True), _row("B", "p", 2.0, True)]
    R = ratios(rows, {"A": (1.0, 0.001)})
    assert R["p"] == pytest.approx({"A": 1.02, "B": 1.0}) and R["q"] == pytest.approx({"A": 1.10})
    S = summary(rows, {"A": (1.0, 0.001)})
    assert S["p"]["to_reference"]["median"] == pytest.approx(1.02) and S["p"]["to_reference"]["n"] == 1


def test_the_swarm_alone_is_a_distribution_over_the_reference(tmp_path):
    """pso_socp's swarm before its polish is reported over T_ref (T_best without one), a run
    without a swarm profile as ∞; planners without a swarm get no line."""
    import dataclasses
    rows = [dataclasses.replace(_row("A", "pso_socp", 1.01, True), seed=k, swarm_time_s=t)
            for k, t in enumerate([1.05, 1.20, math.nan, 1.10])]
    rows += [_row("A", "optimal", 1.0, True), dataclasses.replace(_row("B", "pso_socp", 2.0, True), swarm_time_s=3.0)]
    S = swarm_spread(rows, {"A": (1.0, 0.001)})
    assert list(S) == ["pso_socp"]
    q = S["pso_socp"]
    assert (q["n"], q["best"], q["worst"]) == (5, pytest.approx(1.05), math.inf)
    assert q["median"] == pytest.approx(1.20) and q["q1"] == pytest.approx(1.10)   # order statistics: 1.05 1.1 1.2 1.5 ∞
    write_markdown(rows, tmp_path / "c.md", {"A": (1.0, 0.001)})
    assert "pso_socp's swarm alone" in (tmp_path / "c.md").read_text() and "optimal's swarm" not in (tmp_path / "c.md").read_text()


def test_a_reference_a_counted_run_beats_beyond_its_bar_is_named_an_upper_estimate(tmp_path):
    """A path where a joint-feasible run of its own is faster than T_ref − bar is listed with its
    fastest such run; one within the bar, an infeasible run and a fallback are not."""
    reference = {"A": (1.0, 0.01), "B": (2.0, 0.01), "C": (3.0, 0.01)}
    rows = [_row("A", "optimal", 0.985, True), _row("A", "pso", 0.97, True), _row("A", "copp", 0.95, False),
            _row("B", "optimal", 1.995, True), _row("C", "pso", 2.5, True, status="fallback")]
    below = below_reference(rows, reference)
    assert below == {"A": {"T_reference_s": 1.0, "error_s": 0.01, "best_s": 0.97, "planner": "pso"}}
    write_markdown(rows, tmp_path / "c.md", reference)
    assert "| A | 1.00000 ± 0.01 | 0.97000 | pso | 3.00% |" in (tmp_path / "c.md").read_text()
    write_markdown(rows[3:], tmp_path / "d.md", reference)
    assert "upper estimate" not in (tmp_path / "d.md").read_text()


def _module_sources(*roots):
    import ast
    from pathlib import Path
    repo = Path(__file__).resolve().parent.parent
    for root in roots:
        for f in sorted((repo / root).rglob("*.py")):
            yield f.relative_to(repo).as_posix(), ast.parse(f.read_text())


def test_one_table_of_what_a_planner_keeps():
    """planners/registry.py's BUILTIN_GUARANTEES (and plug-ins' `guarantees`) is the one table:
    no other module keeps a table keyed by planner names whose values name limits (the corpus
    had its own, OWN_LIMITS: "cartesian v/a" for trapezoid, …)."""
    import ast
    from planners import registry
    names = set(registry.BUILTIN)
    found = []
    for rel, tree in _module_sources("harness", "planners"):
        if rel == "planners/registry.py":
            continue
        for node in ast.walk(tree):
            if isinstance(node, ast.Dict):
                keys = {k.value for k in node.keys if isinstance(k, ast.Constant) and isinstance(k.value, str)}
                # values that say which limits: {"joint": [...]} dicts or "cartesian v/a"-like strings
                text = " ".join(ast.unparse(v) for v in node.values).lower()
                if len(keys & names) >= 2 and re.search(r"'(joint|cartesian)'\s*:|(joint|cartesian) v/a", text):
                    found.append(f"{rel}:{node.lineno}")
    assert not found, f"a second table keyed by planner names: {found}"


def test_one_performance_profile():
    """The Dolan–Moré profile is harness/perfprofile.py's: every other function of that name
    calls it (the corpus and the HTML report counted different runs before issue 32)."""
    import ast
    found = []
    for rel, tree in _module_sources("harness"):
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef) and "performance_profile" in node.name and rel != "harness/perfprofile.py":
                calls = [n for n in ast.walk(node) if isinstance(n, ast.Attribute) and n.attr == "performance_profile"
                         and isinstance(n.value, ast.Name) and n.value.id == "perfprofile"]
                if not calls:
                    found.append(f"{rel}:{node.lineno} {node.name}")
    assert not found, f"a second performance profile: {found}"


def _diagnose():
    spec = importlib.util.spec_from_file_location("corpus_diagnose", CORPUS_DIR / "diagnose.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_diagnose_phases_a_whole_period_late_reads_as_on_time(capsys):
    """A start delayed by exactly one period T is one more rest sample, which the rest padding
    of the metrics already holds: the same peaks as the harness's own phase. A half period
    reads other samples of the same pieces: other peaks (scurve plans Cartesian limits, so its
    joint peaks need not be within them)."""
    diagnose = _diagnose()
    diagnose.main(["phases", "rand_planar_kossel", "--planner", "scurve", "--delays", "0,1,0.5"])
    reads = re.findall(r"start (\S+) T late: joint v/a/j (\S+) / (\S+) / (\S+)", capsys.readouterr().out)
    assert [r[0] for r in reads] == ["0", "1", "0.5"]
    on_time, late, half = ([float(x) for x in r[1:]] for r in reads)
    assert late == on_time
    assert half != on_time and all(x > 0 for x in on_time)


def test_diagnose_where_reads_a_study_under_way_from_its_checkpoint(tmp_path, capsys):
    """``where --checkpoint``: the finest grid a study has finished, not solved again; its time
    as the study logged it, and the losses near the joins and elsewhere add up to the difference
    of the two times (t_ref − t_planner at the path's end). A checkpoint of another study, or
    without a finished grid, is refused by name."""
    diagnose = _diagnose()
    ref = diagnose.ref
    path, m = diagnose.corpus_path("contour_kossel")
    key = ref.entry_key(diagnose.corpus_entry("contour_kossel"))
    file = tmp_path / "contour_kossel.pkl"
    r = ref.reference(path, m, levels=1, base_nodes=150, checkpoint=ref.Checkpoint(file, key))
    diagnose.main(["where", "contour_kossel", "--planner", "scurve", "--checkpoint", str(file), "--within", "1"])
    out = capsys.readouterr().out
    T_ref, T_plan = (float(x) for x in re.search(r"finest grid (\S+) s, scurve (\S+) s", out).groups())
    assert T_ref == round(r["grids"][0]["T_s"], 6)
    near, far = (float(x) for x in re.search(r"of them: (\S+) s, elsewhere (\S+) s", out).groups())
    assert near + far == pytest.approx(T_ref - T_plan, abs=2e-5)
    ref.Checkpoint(file, "another study").save({"grids": []})
    with pytest.raises(SystemExit, match="holds no finished grid of contour_kossel"):
        diagnose.main(["where", "contour_kossel", "--checkpoint", str(file)])


def test_diagnose_a_name_not_in_the_corpus_is_refused():
    with pytest.raises(SystemExit, match="'no_such_path' is not a corpus path"):
        _diagnose().main(["phases", "no_such_path"])


def test_join_jumps_into_a_micron_arc_are_the_ik_jacobian_times_its_curvature():
    # at a line → arc join P and P′ are continuous and P″ jumps by n/ρ, so q″ = J(P)·P″ + (a term
    # in P, P′) jumps by J(P)·n/ρ; the IK's Jacobian along n here by a central difference. The
    # fixed 0.02 mm stencil of the local cubic reads this one 8 % off
    m = load_machine("kossel")
    rho = 0.002
    c = np.array([-13.0, -10.0, -252.0])
    a = Line(c + [-5.0, rho, 0.0], c + [0.0, rho, 0.0])
    arc = Arc(a.end, c, [0.0, 0.0, -1.0], math.pi / 2)      # clockwise: tangent to the line
    path = SegmentPath([a, arc, Line(arc.end, arc.end + [0.0, -5.0, 0.0])], "line-arc-line")
    assert len(path.corners()) == 0
    got = dict(join_jumps(path, PathTable(path, m), m))
    assert len(got) == 2
    P, P1 = path.point(np.array([5.0]))[0], path.derivs(np.array([5.0 - 1e-9]))[1][0]
    n = np.array([0.0, -1.0, 0.0])                          # toward the arc's centre
    assert abs(n @ P1) < 1e-9
    eps = 1e-6
    jac_n = (m.ik((P + eps * n)[None]) - m.ik((P - eps * n)[None]))[0] / (2 * eps)
    s_join = min(got, key=lambda s: abs(s - 5.0))
    assert s_join == pytest.approx(5.0, abs=1e-9)
    assert got[s_join] == pytest.approx(np.abs(jac_n) / rho, rel=1e-3)


def test_a_corpus_row_is_keyed_by_the_code_its_planner_imports(tmp_path):
    """pso_socp's rows depend on the TOPP3-SOCP engine but not on `optimal`'s own planner.py;
    an edit to what a planner imports changes its key, an edit elsewhere does not."""
    import shutil

    from harness.corpus.journal import ROW_MODULES
    from harness.sweep.suite import closure_version, import_closure
    from kins.resources import REPO
    from planners.registry import BUILTIN

    for d in ("kins", "planners", "harness"):
        shutil.copytree(REPO / d, tmp_path / d, ignore=shutil.ignore_patterns("__pycache__"))

    def mods(name):
        return [BUILTIN[name][0], *ROW_MODULES]

    rel = {f.relative_to(tmp_path).as_posix() for f in import_closure(mods("pso_socp"), tmp_path)}
    assert {"planners/pso/swarm.py", "planners/optimal/topp3.py", "planners/optimal/ipm.py", "kins/keops.py",
            "planners/verify.py", "harness/corpus/run.py"} <= rel
    assert not rel & {"planners/optimal/planner.py", "harness/corpus/report.py", "harness/sweep/engine.py"}
    before = {n: closure_version(mods(n), tmp_path) for n in ("pso_socp", "optimal", "scurve_joint")}
    with open(tmp_path / "planners/optimal/planner.py", "a") as f:
        f.write("# an edit to the yardstick alone\n")
    after = {n: closure_version(mods(n), tmp_path) for n in before}
    assert after["optimal"] != before["optimal"]
    assert after["pso_socp"] == before["pso_socp"] and after["scurve_joint"] == before["scurve_joint"]
    with open(tmp_path / "planners/optimal/ipm.py", "a") as f:
        f.write("# an edit to the engine both use\n")
    again = {n: closure_version(mods(n), tmp_path) for n in before}
    assert again["optimal"] != after["optimal"] and again["pso_socp"] != after["pso_socp"]
    assert again["scurve_joint"] == before["scurve_joint"]
    with open(tmp_path / "kins/machine.py", "a") as f:     # the check at T: every row
        f.write("# an edit to the kinematics\n")
    assert all(closure_version(mods(n), tmp_path) != again[n] for n in before)


def test_the_import_closure_follows_relative_nested_and_from_imports(tmp_path):
    pkg = tmp_path / "planners" / "x"
    pkg.mkdir(parents=True)
    (tmp_path / "planners" / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("from .a import f\n")
    (pkg / "a.py").write_text("def f():\n    from planners.x import b\n    return b\n")
    (pkg / "b.py").write_text("from planners.x import c, nothing\nimport numpy\n")
    (pkg / "c.py").write_text("")
    (pkg / "unused.py").write_text("")
    from harness.sweep.suite import import_closure
    got = [f.relative_to(tmp_path).as_posix() for f in import_closure(["planners.x"], tmp_path)]
    assert got == ["planners/__init__.py", "planners/x/__init__.py", "planners/x/a.py", "planners/x/b.py",
                   "planners/x/c.py"]
