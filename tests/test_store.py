"""The results store (harness.store): sweeps and ci append Parquet files, `pkmbench query` answers
SQL over them; the README's question "median pso/optimal ratio per machine over the last 10
nightly runs" is checked against statistics.median over the same numbers kept in Python."""
from __future__ import annotations

import json
import statistics
from datetime import datetime, timedelta, timezone
from pathlib import Path

import pytest

from harness.cli import main as cli
from harness.cli.query import PSO_OPTIMAL
from harness.store import ResultStore, make_row

LINE = {"type": "nurbs", "units": "mm", "degree": 1, "knots": [0, 0, 1, 1],
        "control_points": [[-50, 0, -400], [50, 0, -400]], "weights": [1, 1]}


def nightly(store: Path, n: int = 12) -> dict:
    """n ci runs a day apart; per run and machine a pso and an optimal time. The two oldest runs
    have ratios of 5 (outside the last 10: they must not count). Returns the expected medians."""
    t0 = datetime(2026, 1, 1, tzinfo=timezone.utc)
    ratios: dict[str, list[float]] = {"keops": [], "kossel": []}
    with ResultStore(store) as st:
        for i in range(n):
            rows = []
            for m, base in (("keops", 1.7), ("kossel", 20.0)):
                r = 5.0 if i < n - 10 else 1.0 + 0.01 * ((i * 7 + len(m)) % 5)
                if i >= n - 10:
                    ratios[m].append(r)
                for planner, t in (("pso", base * r), ("optimal", base), ("scurve", 3 * base)):
                    rows.append(make_row(entry=f"{m}/bird/{planner}/seed0/none/base", machine=m, path="bird",
                                         planner=planner, seed=0, preset="none", variation="base",
                                         metrics={"execution_time_s": t, "joint_peak_ratio": {"jerk": r}}))
            st.append(rows, kind="ci", suite="nightly", run_info={"passed": True}, time=t0 + timedelta(days=i))
        # a sweep's rows in between: not nightly runs, must not count
        st.append([make_row(entry="keops/bird/pso/seed0/none/base", machine="keops", path="bird", planner="pso",
                            seed=0, preset="none", variation="base", metrics={"execution_time_s": 99.0})],
                  kind="sweep", time=t0 + timedelta(days=n + 1))
    return {m: statistics.median(v) for m, v in ratios.items()}


def test_query_answers_median_pso_over_optimal_of_the_last_10_nightly_runs(tmp_path, capsys):
    expected = nightly(tmp_path / "store")
    assert cli(["query", "--store", str(tmp_path / "store"), "--json", PSO_OPTIMAL]) == 0
    got = json.loads(capsys.readouterr().out)
    assert [r["machine"] for r in got] == ["keops", "kossel"]
    for r in got:
        assert r["n"] == 10
        assert r["pso_over_optimal"] == pytest.approx(expected[r["machine"]], rel=1e-12)
    assert list((tmp_path / "store").glob("*.part")) == [] and len(list((tmp_path / "store").glob("*.parquet"))) == 13
    # metrics JSON with dotted names, and the runs view
    with ResultStore(tmp_path / "store") as st:
        (v,) = st.query("""SELECT max(CAST(metrics->>'$."joint_peak_ratio.jerk"' AS DOUBLE)) FROM results
                           WHERE kind = 'ci'""")[1][0]
        assert v == 5.0
        assert st.query("SELECT count(*), sum(rows) FROM runs")[1] == [(13, 12 * 6 + 1)]


def test_empty_store_answers_no_rows_and_bad_sql_is_one_line(tmp_path, capsys):
    (tmp_path / "empty").mkdir()       # an empty store; one that does not exist is said (test_hostile_inputs)
    assert cli(["query", "--store", str(tmp_path / "empty"), "SELECT count(*) AS n FROM results"]) == 0
    assert capsys.readouterr().out.split() == ["n", "0"]
    assert cli(["query", "--store", str(tmp_path / "empty"), "SELECT nope FROM results"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("pkmbench query: error: query failed:") and "nope" in err[0]


def test_sweep_appends_its_finished_tasks(tmp_path, capsys):
    (tmp_path / "line.json").write_text(json.dumps(LINE))
    suite = tmp_path / "s.toml"
    suite.write_text(f'[[run]]\nmachine = "keops"\npath = "{tmp_path / "line.json"}"\n'
                     f'planners = ["quintic", "nope"]\n[planner_options.quintic]\nfeed_mm_s = 500.0\n')
    argv = ["sweep", str(suite), "--workers", "0", "--no-progress", "--task", "harness.sweep.tasks:line_task",
            "--out", str(tmp_path / "sw"), "--store", str(tmp_path / "store")]
    assert cli(argv) == 1                                  # 'nope' fails, its row says why
    assert cli(argv) == 1                                  # the failed one re-runs; quintic is skipped
    with ResultStore(tmp_path / "store") as st:
        rows = st.dicts("SELECT kind, planner, status, execution_time_s, run_dir FROM results ORDER BY time, planner")
    assert [(r["planner"], r["status"]) for r in rows] == [("nope", "error"), ("quintic", "ok"), ("nope", "error")]
    # quintic: D = 15/8 · L / feed = 0.375 s, a whole number of 250 µs periods
    assert rows[1]["execution_time_s"] == pytest.approx(0.375, abs=1e-12)
    assert (Path(rows[1]["run_dir"]) / "summary.json").exists()
