"""pkmbench ci / history: pass on an unchanged baseline, fail on an injected regression with the
metric named, JUnit XML + Markdown written, history appended; tolerance rules; the committed
baseline matches the nightly suite.
"""
from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from harness.cli import main as cli
from harness.ci import baseline as ci
from harness.ci.history import History
from harness.sweep.suite import REPO

LINE = {"type": "nurbs", "units": "mm", "degree": 1, "knots": [0, 0, 1, 1],
        "control_points": [[-50, 0, -400], [50, 0, -400]], "weights": [1, 1]}
LINE_TASK = "harness.sweep.tasks:line_task"
ENTRY = "keops/line/quintic/seed0/none/base"


def suite(tmp: Path, options: str) -> Path:
    (tmp / "line.json").write_text(json.dumps(LINE))
    f = tmp / "suite.toml"
    f.write_text(f'[[run]]\nmachine = "keops"\npath = "{tmp / "line.json"}"\nplanners = ["quintic"]\n'
                 f'[planner_options.quintic]\n{options}\n')
    return f


def run_ci(tmp: Path, suite_file: Path, *extra: str) -> int:
    return cli(["ci", "--suite", str(suite_file), "--baseline", str(tmp / "baseline.json"),
                "--out", str(tmp / "ci"), "--task", LINE_TASK, "--workers", "1",
                "--store", str(tmp / "store"), *extra])


def test_store_none_appends_to_no_store(tmp_path, capsys, monkeypatch):
    """--store none: no results store, as for corpus and sweep (it made a folder named 'none')."""
    monkeypatch.chdir(tmp_path)
    good = suite(tmp_path, "feed_mm_s = 500.0")
    assert cli(["ci", "--suite", str(good), "--baseline", str(tmp_path / "baseline.json"), "--out",
                str(tmp_path / "ci"), "--task", LINE_TASK, "--workers", "1", "--store", "none",
                "--update-baseline"]) == 0
    assert "no results store (--store none)" in capsys.readouterr().out
    assert not (tmp_path / "none").exists() and (tmp_path / "baseline.json").exists()


def drifting_task(task, out_dir):
    """A "planner" whose execution time grows by a servo period at every call (a counter file)."""
    counter = Path(task["planner_options"]["counter"])
    n = len(counter.read_text()) if counter.exists() else 0
    counter.write_text("x" * (n + 1))
    return {"execution_time_s": 1.0 + 250e-6 * n, "feasible": True, "planning_time_s": 0.01}


@pytest.mark.parametrize("timing, runs", [(True, ci.CI_REPEAT), (False, ci.CI_REPEAT_NO_TIMING)])
def test_a_planner_that_is_not_deterministic_fails_by_name(tmp_path, capsys, timing, runs):
    """Each task runs more than once (three times to time it, twice under --no-timing) and its
    runs must agree: the first and the last differing fail the task, naming the metric."""
    counter = tmp_path / "calls"
    s = suite(tmp_path, f'counter = "{counter}"')
    code = cli(["ci", "--suite", str(s), "--baseline", str(tmp_path / "baseline.json"), "--out",
                str(tmp_path / "ci"), "--task", f"{__name__}:drifting_task", "--workers", "0",
                "--store", "none", "--update-baseline", *([] if timing else ["--no-timing"])])
    out = capsys.readouterr().out
    assert len(counter.read_text()) == ci.CI_REPEAT          # --update-baseline always times
    assert code == 1 and "not deterministic: execution_time_s differ" in out, out
    assert not (tmp_path / "baseline.json").exists()
    (tmp_path / "baseline.json").write_text(json.dumps(
        {"format": ci.FORMAT, "suite": str(s), "task_fn": LINE_TASK, "code_version": "x",
         "reference_s": 0.05, "entries": {ENTRY: {"execution_time_s": 1.0}}}))
    counter.unlink()
    code = cli(["ci", "--suite", str(s), "--baseline", str(tmp_path / "baseline.json"), "--out",
                str(tmp_path / "ci"), "--task", f"{__name__}:drifting_task", "--workers", "0",
                "--store", "none", *([] if timing else ["--no-timing"])])
    out = capsys.readouterr().out
    assert len(counter.read_text()) == runs
    assert code == 1 and "not deterministic: execution_time_s differ" in out, out


def test_ci_passes_unchanged_and_fails_on_slower_or_worse_planner(tmp_path, capsys):
    good = suite(tmp_path, "feed_mm_s = 500.0")
    assert run_ci(tmp_path, good, "--update-baseline") == 0
    base = json.loads((tmp_path / "baseline.json").read_text())
    assert base["format"] == ci.FORMAT and set(base["entries"]) == {ENTRY}
    assert base["entries"][ENTRY]["execution_time_s"] == pytest.approx(0.375, abs=250e-6)
    assert "planning_time_ratio" in base["entries"][ENTRY]
    capsys.readouterr()

    assert run_ci(tmp_path, good) == 0                                     # unchanged: pass
    assert "PASS" in capsys.readouterr().out
    suites = ET.parse(tmp_path / "ci/junit.xml").getroot()
    assert suites.get("failures") == "0" and int(suites.get("tests")) > 10

    # a worse planner: 1 % lower peak feed ⇒ 1 % longer execution, beyond ±0.5 %
    assert run_ci(tmp_path, suite(tmp_path, "feed_mm_s = 495.0")) == 1
    out = capsys.readouterr().out
    assert "FAIL" in out and ENTRY in out and "`execution_time_s`" in out and "±0.5 %" in out
    failures = {tc.get("name") for tc in ET.parse(tmp_path / "ci/junit.xml").getroot().iter("testcase")
                if tc.find("failure") is not None}
    assert "execution_time_s" in failures
    md = (tmp_path / "ci/summary.md").read_text()
    assert "execution_time_s increased" in md

    # a slower planner: the same profile computed 3000 times inside the timed planning
    assert run_ci(tmp_path, suite(tmp_path, "feed_mm_s = 500.0\nplanning_repeat = 3000")) == 1
    out = capsys.readouterr().out
    assert "`planning_time_ratio`" in out and "slower" in out
    assert "`execution_time_s`" not in out                                 # only what changed

    with History(tmp_path / "store") as h:
        runs = h.runs()
        assert [r["passed"] for r in runs] == [1, 1, 0, 0]
        assert [r["mode"] for r in runs] == ["update-baseline", "check", "check", "check"]
        exec_series = h.series("execution_time_s")[ENTRY]
        D = [15 / 8 * 100 / f for f in (500, 500, 495, 500)]             # quintic duration, ceil'd to T
        assert [v for _, v in exec_series] == pytest.approx(D, abs=250e-6)
        # the failing runs name their regressions in the store
        marked = h.series_marked("execution_time_s")[ENTRY]
        assert [bad for _, _, bad in marked] == [False, False, True, False]
    assert cli(["history", "--store", str(tmp_path / "store"), "--out", str(tmp_path / "ci/trend.png")]) == 0
    assert (tmp_path / "ci/trend.png").stat().st_size > 1000


def test_failed_task_is_a_regression_and_does_not_update_the_baseline(tmp_path, capsys):
    good = suite(tmp_path, "feed_mm_s = 500.0")
    assert run_ci(tmp_path, good, "--update-baseline") == 0
    before = (tmp_path / "baseline.json").read_text()
    bad = suite(tmp_path, "feed_mm_s = -1.0")       # negative feed ⇒ NaN-free error in the task
    bad.write_text(bad.read_text().replace('["quintic"]', '["quintic", "bogus"]'))
    assert run_ci(tmp_path, bad, "--update-baseline") == 1
    assert (tmp_path / "baseline.json").read_text() == before
    capsys.readouterr()
    assert run_ci(tmp_path, bad) == 1
    out = capsys.readouterr().out
    assert "task failed" in out and "bogus" in out


def test_tolerance_rules():
    base = {"entries": {"e": {"execution_time_s": 1.0, "joint_peak_ratio.jerk": 1.2, "feasible": False,
                              "planning_time_ratio": 0.2, "planning_time_s": 0.01}}}

    def fails(**now):
        cur = dict(base["entries"]["e"]) | now
        return {c.metric for c in ci.compare(base, {"e": cur}, {}) if not c.ok}

    assert fails() == set()
    assert fails(execution_time_s=1.0049) == set() and fails(execution_time_s=0.9951) == set()
    assert fails(execution_time_s=1.0051) == {"execution_time_s"}
    assert fails(**{"joint_peak_ratio.jerk": 1.2 + 9e-7}) == set()
    assert fails(**{"joint_peak_ratio.jerk": 1.2 - 2e-6}) == {"joint_peak_ratio.jerk"}
    assert fails(feasible=True) == {"feasible"}
    assert fails(planning_time_s=10.0) == set()                 # raw wall time is not compared
    assert fails(planning_time_ratio=0.29) == set()              # ≤ 1.5×
    assert fails(planning_time_ratio=0.299) == set()
    assert fails(planning_time_ratio=0.01) == set()              # faster is fine
    assert fails(planning_time_ratio=0.31) == {"planning_time_ratio"}                # > 1.5× and > +0.1
    tiny = {"entries": {"e": {"planning_time_ratio": 0.001}}}
    assert not [c for c in ci.compare(tiny, {"e": {"planning_time_ratio": 0.01}}, {}) if not c.ok]  # noise floor
    # a suite's own rule for one run goes first (entry-glob:metric-glob)
    tol = ci.tolerances_from_suite({"ci": {"tolerances": {"e*:planning_time_ratio": {"max_factor": 2.0}}}})
    cur = dict(base["entries"]["e"]) | {"planning_time_ratio": 0.39}
    assert all(c.ok for c in ci.compare(base, {"e": cur}, {}, tol))
    assert not all(c.ok for c in ci.compare({"entries": {"x": base["entries"]["e"]}}, {"x": cur}, {}, tol))
    # --no-timing: planning time is not compared at all, everything else still is
    slow = dict(base["entries"]["e"]) | {"planning_time_ratio": 9.0}
    assert not all(c.ok for c in ci.compare(base, {"e": slow}, {}))
    assert all(c.ok for c in ci.compare(base, {"e": slow}, {}, ci.without_timing(ci.DEFAULT_TOLERANCES)))
    assert "planning_time_ratio" not in {c.metric for c in
                                         ci.compare(base, {"e": slow}, {}, ci.without_timing(ci.DEFAULT_TOLERANCES))}
    drift = dict(base["entries"]["e"]) | {"execution_time_s": 1.01}
    assert not all(c.ok for c in ci.compare(base, {"e": drift}, {}, ci.without_timing(ci.DEFAULT_TOLERANCES)))
    cs = ci.compare(base, {}, {})
    assert [(c.metric, c.ok) for c in cs] == [("entry", False)]


def test_reference_workload_is_a_positive_time():
    # (its speed is measured in benchmarks, never asserted here: the machine may be busy)
    assert 0 < ci.reference_workload_s(1) < 60


def test_committed_baseline_matches_the_nightly_suite():
    """The committed baseline was written by `pkmbench ci --update-baseline` for this suite."""
    from harness.sweep import expand, load_suite, task_label
    bfile, sfile = REPO / "results/baseline.json", REPO / "benchmarks/suites/nightly.toml"
    b = json.loads(bfile.read_text())
    assert b["format"] == ci.FORMAT
    labels = {task_label(t) for t in expand(load_suite(sfile), str(sfile))}
    assert set(b["entries"]) == labels
    for name, e in b["entries"].items():
        assert isinstance(e["feasible"], bool) and e["execution_time_s"] > 0, name
        assert all(v == v for v in e.values() if isinstance(v, float)), name     # no NaN


@pytest.mark.slow
def test_ci_passes_on_the_committed_baseline(tmp_path, capsys):
    """`pkmbench ci --no-timing` on the nightly suite passes against results/baseline.json.

    Runs on any code: the tolerances of harness/ci/baseline.py hold across machines, so a
    failure means the numbers moved. Planning time is left to the nightly runner (`make test`
    may run on a slower or busier machine than the one that wrote the baseline).
    """
    bfile = REPO / "results/baseline.json"
    b = json.loads(bfile.read_text())
    code = cli(["ci", "--suite", str(REPO / "benchmarks/suites/nightly.toml"), "--baseline", str(bfile),
                "--out", str(tmp_path / "ci"), "--task", b["task_fn"], "--no-timing"])
    out = capsys.readouterr().out
    assert code == 0, (f"the nightly suite's numbers moved from results/baseline.json; if the change is "
                       f"intended, run `pkmbench ci --update-baseline` and commit the baseline\n{out}")
    assert "PASS" in out and "0 regressions" in out
