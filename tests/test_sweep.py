"""pkmbench sweep: failing tasks, resume, keys, variations, a real scheduler + 2 worker processes.

The tasks are ``harness.sweep.tasks:line_task`` (a quintic move along a line on KEOPS), whose
metrics have closed forms: for s = L(10τ³ − 15τ⁴ + 6τ⁵) over D, peak speed 15L/8D, peak
acceleration 10L/(√3 D²), peak jerk 60L/D³.
"""
from __future__ import annotations

import json
import math
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from harness.cli import main as cli
from harness.sweep import (TaskTable, make_task, run_sweep, task_key, task_label, tasks_from_suite_file)
from harness.sweep.suite import REPO

LINE = {"type": "nurbs", "units": "mm", "degree": 1, "knots": [0, 0, 1, 1],
        "control_points": [[-50, 0, -400], [50, 0, -400]], "weights": [1, 1]}
LINE_TASK = "harness.sweep.tasks:line_task"


def write_suite(tmp: Path, planners=("quintic", "bogus"), extra="") -> Path:
    (tmp / "line.json").write_text(json.dumps(LINE))
    suite = tmp / "suite.toml"
    suite.write_text(f"""name = "test"
[[run]]
machine = "keops"
path = "{tmp / 'line.json'}"
planners = {json.dumps(list(planners))}
[planner_options.quintic]
feed_mm_s = 500.0
{extra}""")
    return suite


def test_failing_task_is_recorded_others_finish_and_rerun_skips(tmp_path):
    tasks = tasks_from_suite_file(write_suite(tmp_path, extra="[sweep]\nseeds = [0, 1]\n"))
    assert len(tasks) == 4
    out = tmp_path / "out"
    r = run_sweep(tasks, out, task_fn=LINE_TASK, workers=2, progress=False)
    assert (r.ok, r.failed, r.skipped) == (2, 2, 0)
    assert all("bogus" in err and "TaskError" in err for _, err in r.failures)
    rows = TaskTable(out / "results.sqlite").to_rows()
    ok = [row for row in rows if row["status"] == "ok"]
    assert len(ok) == 2 and {row["seed"] for row in ok} == {0, 1}
    # closed forms of the quintic: L = 100 mm, peak feed 500 mm/s ⇒ D = 0.375 s; limits 1000/1e4/5e5
    L, D = 100.0, 15 / 8 * 100.0 / 500.0
    m = ok[0]["metrics"]
    assert m["execution_time_s"] == pytest.approx(D, abs=250e-6)
    assert m["cartesian_peak_ratio"]["velocity"] == pytest.approx(0.5, rel=1e-5)
    assert m["cartesian_peak_ratio"]["acceleration"] == pytest.approx(10 * L / math.sqrt(3) / D**2 / 1e4, rel=1e-3)
    # jerk 60L/D³(1 − 6τ + 6τ²) peaks at τ = 0; the first third difference reads it at t = 1.5 T
    tau = 1.5 * 250e-6 / D
    assert m["cartesian_peak_ratio"]["jerk"] == pytest.approx(60 * L / D**3 * (1 - 6 * tau + 6 * tau**2) / 5e5, rel=1e-5)
    assert m["feasible"] is True
    # each run's files are kept under the sweep folder
    summary = json.loads((out / ok[0]["run_dir"] / "summary.json").read_text())
    assert summary["planners"]["quintic"]["execution_time_s"] == m["execution_time_s"]
    assert (out / ok[0]["run_dir"] / "command.csv").read_text().startswith("t,x,y,z,q1,q2,q3\n")
    failed = [row for row in rows if row["status"] == "error"]
    assert len(failed) == 2 and all("Traceback" in row["traceback"] for row in failed)

    # second run: the finished tasks are skipped; only the failed ones are tried again
    r2 = run_sweep(tasks, out, task_fn=LINE_TASK, workers=0, progress=False)
    assert (r2.skipped, r2.ok, r2.failed) == (2, 0, 2)
    # a changed input (the planner option) is new work
    tasks[0]["planner_options"] = {"feed_mm_s": 250.0}
    r3 = run_sweep(tasks, out, task_fn=LINE_TASK, workers=0, progress=False)
    assert (r3.skipped, r3.ok) == (1, 1)


def test_task_key_covers_inputs_and_code(tmp_path):
    write_suite(tmp_path)
    mfile = REPO / "benchmarks/machines/keops.toml"
    t = make_task(mfile, tmp_path / "line.json", "quintic", seed=0)
    k = task_key(t, "v1")
    assert k == task_key(make_task(mfile, tmp_path / "line.json", "quintic", seed=0), "v1")
    assert k != task_key(t, "v2")                                           # code/FMU version
    assert k != task_key(make_task(mfile, tmp_path / "line.json", "quintic", seed=1), "v1")
    assert k != task_key(make_task(mfile, tmp_path / "line.json", "quintic", preset="heavy"), "v1")
    alt = tmp_path / "keops.toml"
    alt.write_text(mfile.read_text().replace("j = 5.0e5", "j = 4.0e5", 1))
    assert k != task_key(make_task(alt, tmp_path / "line.json", "quintic"), "v1")  # file content
    (tmp_path / "line.json").write_text(json.dumps(LINE | {"weights": [1, 1.0000001]}))
    assert k != task_key(make_task(mfile, tmp_path / "line.json", "quintic"), "v1")


def test_a_max_feed_run_is_its_own_task(tmp_path):
    # the same machine, path and planner at the programmed F and at F_max: two results, two keys,
    # two run folders, two baseline names (the store skipped the second as done before)
    from harness.sweep.engine import run_dir_of
    suite = tmp_path / "feeds.toml"
    suite.write_text('[[run]]\nmachine = "keops"\npath = "bird"\nplanner = "scurve"\n\n'
                     '[[run]]\nmachine = "keops"\npath = "bird"\nplanner = "scurve"\nmax_feed = true\n')
    a, b = tasks_from_suite_file(suite)
    assert (a.get("max_feed", False), b["max_feed"]) == (False, True)
    assert task_key(a, "v1") != task_key(b, "v1")
    assert run_dir_of(a) != run_dir_of(b) and task_label(a) != task_label(b)
    # a programmed-feed task keeps its key: the stores and baselines of before stay valid
    assert "max_feed" not in a


def test_variation_changes_the_machine_and_bad_variation_is_a_clear_failure(tmp_path):
    suite = write_suite(tmp_path, planners=["quintic"], extra="""[sweep]
[[sweep.variation]]
name = "base"
[[sweep.variation]]
name = "slow_axes"
set = { "limits.cartesian.v" = 500.0 }
[[sweep.variation]]
name = "typo"
set = { "limits.cartesian.vv" = 1.0 }
""")
    r = run_sweep(tasks_from_suite_file(suite), tmp_path / "o", task_fn=LINE_TASK, workers=0, progress=False)
    assert (r.ok, r.failed) == (2, 1)
    assert "typo" in r.failures[0][1] and "limits.cartesian.vv" in r.failures[0][1]
    rows = {row["variation"]: row["metrics"] for row in TaskTable(tmp_path / "o/results.sqlite").to_rows()}
    base, slow = rows["base"]["cartesian_peak_ratio"]["velocity"], rows["slow_axes"]["cartesian_peak_ratio"]["velocity"]
    assert slow == pytest.approx(2 * base, rel=1e-12)


def test_suite_errors_name_the_file_and_key(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text('[[run]]\nmachine = "nosuch"\npath = "x.json"\nplanners = ["a"]\n')
    assert cli(["sweep", str(bad)]) == 2
    assert "machine 'nosuch'" in capsys.readouterr().err
    bad.write_text('[[run]]\nmachine = "keops"\nplanners = ["a"]\n')
    assert cli(["sweep", str(bad)]) == 2
    assert "[[run]] #1 needs 'path'" in capsys.readouterr().err


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_sweep_through_a_real_scheduler_with_two_worker_processes(tmp_path, capsys):
    suite = write_suite(tmp_path, extra="[sweep]\nseeds = [0, 1, 2]\n")
    addr = f"tcp://127.0.0.1:{_free_port()}"
    dask = [sys.executable, "-m", "dask"]
    procs = [subprocess.Popen(dask + ["scheduler", "--host", "127.0.0.1", "--port", addr.rsplit(":", 1)[1],
                                      "--no-dashboard"], cwd=REPO,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        for nanny in ("--no-nanny", "--nanny"):     # a nanny's worker gets MALLOC_TRIM_THRESHOLD_
            procs.append(subprocess.Popen(dask + ["worker", addr, "--nthreads", "1", "--no-dashboard",
                                                  nanny], cwd=REPO,
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from distributed import Client
        with Client(addr, timeout="20s") as c:                 # wait until both workers joined
            c.wait_for_workers(2, timeout=30)
        code = cli(["sweep", str(suite), "--scheduler", addr, "--task", LINE_TASK,
                    "--out", str(tmp_path / "out"), "--no-progress"])
        out, err = capsys.readouterr()
        assert "sweep: warning: 1 worker(s) (tcp://127.0.0.1:" in err and "MALLOC_TRIM_THRESHOLD_" in err, err
        assert code == 1                                     # the bogus tasks failed …
        assert "3 run, 0 already done, 3 failed" in out      # … and the others finished
        rows = TaskTable(tmp_path / "out/results.sqlite").to_rows()
        assert sorted(r["status"] for r in rows) == ["error"] * 3 + ["ok"] * 3
        pids = {r["worker"].rsplit(":", 1)[1] for r in rows}
        assert str(__import__("os").getpid()) not in pids    # ran on the workers, not here
        # the second run through the scheduler skips the finished ones
        cli(["sweep", str(suite), "--scheduler", addr, "--task", LINE_TASK,
             "--out", str(tmp_path / "out"), "--no-progress"])
        assert "0 run, 3 already done, 3 failed" in capsys.readouterr().out
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                p.kill()


def test_unreachable_scheduler_is_a_clear_error(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("harness.sweep.engine.CONNECT_TIMEOUT", "1s")
    suite = write_suite(tmp_path, planners=["quintic"])
    t0 = time.perf_counter()
    assert cli(["sweep", str(suite), "--scheduler", f"tcp://127.0.0.1:{_free_port()}",
                "--task", LINE_TASK, "--out", str(tmp_path / "o")]) == 2
    assert "cannot reach the dask scheduler" in capsys.readouterr().err
    assert time.perf_counter() - t0 < 30


def test_report_tables_ratio_failures_and_plots(tmp_path, capsys):
    suite = write_suite(tmp_path)
    run_sweep(tasks_from_suite_file(suite), tmp_path / "s", task_fn=LINE_TASK, workers=0, progress=False)
    assert cli(["report", str(tmp_path / "s"), "--reference", "quintic"]) == 0
    md = (tmp_path / "s/report/report.md").read_text()
    assert "## keops / line" in md
    quintic = next(line for line in md.splitlines() if line.startswith("| quintic |"))
    cells = [c.strip() for c in quintic.strip("|").split("|")]
    assert cells[2] == "0.375" and cells[3] == "1.000" and cells[5] == "yes"     # ÷ itself = 1
    assert cells[4] == "—"                        # ÷ T_ref: not a corpus path, no reference
    assert "FAILED: TaskError" in md and "bogus" in md
    assert (tmp_path / "s/report/group00.png").stat().st_size > 1000
    assert "<table class='comparison'>" in (tmp_path / "s/report/report.html").read_text()
    assert cli(["report", str(tmp_path / "nothing")]) == 2
    assert "not a sweep folder" in capsys.readouterr().err


def fmu_size_task(task, out_dir):
    """Reads the FMU files the sweep shipped to this worker (a test task function)."""
    folder = Path(task["fmu_dir"])
    return {"execution_time_s": float((folder / "Fake.fmu").stat().st_size),
            "feasible": str(folder) != ""}


def test_fmus_reach_dask_workers_as_files(tmp_path, monkeypatch):
    fmus = tmp_path / "fmus"
    fmus.mkdir()
    (fmus / "Fake.fmu").write_bytes(b"PK" + bytes(1234))
    monkeypatch.setattr("harness.sweep.engine.FMU_DIR", fmus)
    tasks = tasks_from_suite_file(write_suite(tmp_path, planners=["quintic"]))
    r = run_sweep(tasks, tmp_path / "o", task_fn=f"{__name__}:fmu_size_task", workers=1, progress=False)
    assert (r.ok, r.failed) == (1, 0), r.failures
    row, = TaskTable(tmp_path / "o/results.sqlite").to_rows()
    assert row["metrics"]["execution_time_s"] == 1236.0
    assert row["worker"].rsplit(":", 1)[1] != str(__import__("os").getpid())   # another process


def dying_task(task, out_dir):
    """Kills its worker process the first time it runs (a marker file remembers), then succeeds."""
    marker = Path(task["planner_options"]["marker"])
    if not marker.exists():
        marker.write_text("died once")
        __import__("os")._exit(1)
    return {"execution_time_s": 1.0, "feasible": True}


def test_a_killed_worker_is_reported_with_its_task_and_the_sweep_completes(tmp_path):
    """Dask re-ran a dead worker's task silently; now a warning names the task and the worker."""
    (tmp_path / "line.json").write_text(json.dumps(LINE))
    suite = {"run": [{"machine": "keops", "path": str(tmp_path / "line.json"), "planners": ["quintic"]}],
             "planner_options": {"quintic": {"marker": str(tmp_path / "died")}}}
    from harness.sweep import expand
    said = []
    r = run_sweep(expand(suite), tmp_path / "o", task_fn=f"{__name__}:dying_task", workers=2,
                  progress=False, log=said.append)
    assert (r.ok, r.failed) == (1, 0), r.failures
    assert (tmp_path / "died").read_text() == "died once"
    warn = [s for s in said if "warning" in s]
    assert len(warn) == 1, said
    assert warn[0].startswith("sweep: warning: worker tcp://127.0.0.1:")
    assert warn[0].endswith("died while running keops/line/quintic/seed0/none/base; "
                            "dask runs that task again on another worker")


def _malloc_env():
    import os
    return os.environ.get("MALLOC_TRIM_THRESHOLD_"), os.environ.get("OMP_NUM_THREADS")


def test_local_workers_keep_glibc_s_adaptive_mmap_threshold():
    """dask's workers get MALLOC_TRIM_THRESHOLD_=65536, which makes glibc map and unmap every
    large array (pso planned 2 x slower); ours run without it, still one BLAS thread each."""
    from harness.sweep.engine import _connect
    client, cluster = _connect(None, 2, True)
    try:
        seen = client.run(_malloc_env)
    finally:
        client.close()
        cluster.close()
    assert len(seen) == 2 and set(seen.values()) == {(None, "1")}, seen


def test_a_local_sweep_ends_without_a_traceback_on_the_console(tmp_path):
    # the worker-loss subscription once made the scheduler log a CRITICAL CommClosedError
    # traceback at every close: a clean sweep prints none
    suite = write_suite(tmp_path, planners=("quintic",))
    r = subprocess.run([sys.executable, "-m", "harness.cli", "sweep", str(suite), "--workers", "2",
                        "--task", LINE_TASK, "--out", str(tmp_path / "out"), "--no-progress"],
                       cwd=REPO, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "1 run, 0 already done, 0 failed" in r.stdout
    assert "Traceback" not in r.stderr and "CRITICAL" not in r.stderr, r.stderr


def test_run_and_sweep_read_a_suite_with_the_one_parser(tmp_path):
    """`planner = "x"` (one planner) is accepted by `run` and `sweep` alike, and an unknown key
    is refused by both with the same message: they share harness.sweep.suite."""
    from argparse import Namespace

    from harness.cli import CliError
    from harness.cli.run import cases_of
    from harness.sweep import SuiteError, tasks_from_suite_file

    one = tmp_path / "one.toml"
    one.write_text('[[run]]\nmachine = "keops"\npath = "bird"\nplanner = "scurve"\n')
    cases, _ = cases_of(Namespace(suite=str(one), out=str(tmp_path / "o"), max_feed=False))
    assert [(m, p, pl) for m, p, pl, *_ in cases] == [("keops", "bird", ["scurve"])]
    assert [t["planner"] for t in tasks_from_suite_file(one)] == ["scurve"]

    bad = tmp_path / "bad.toml"
    bad.write_text('[[run]]\nmachine = "keops"\npath = "bird"\nplanners = ["scurve"]\nplaners = ["x"]\n')
    with pytest.raises(CliError) as run_err:
        cases_of(Namespace(suite=str(bad), out=str(tmp_path / "o"), max_feed=False))
    with pytest.raises(SuiteError) as sweep_err:
        tasks_from_suite_file(bad)
    assert str(run_err.value) == str(sweep_err.value)
    assert "bad.toml:line 5: [[run]] #1: unknown key 'planers'" in str(sweep_err.value)


def _seeded_feed(path, machine, limits=None, seed=0, **kw):
    """A stochastic plug-in: scurve_joint with F_max lowered by seed × 10 %."""
    import dataclasses

    import planners
    lim = machine.limits
    return planners.plan("scurve_joint", path, machine, dataclasses.replace(lim, feed_max=lim.feed_max / (1 + seed / 10)))


_seeded_feed.stochastic = True


def test_a_suites_seeds_seed_a_stochastic_planner_unless_its_options_pin_one(tmp_path):
    """The sweep's seed is a stochastic planner's seed too (the bus's only, before): a suite over
    seeds is a distribution of its plans. A seed in its planner_options wins."""
    import planners
    from harness.cosim.run import run_case
    from kins import load_machine
    from planners.paths import load_path
    name = f"{__name__}:_seeded_feed"
    (tmp_path / "line.json").write_text(json.dumps(LINE))
    suite = tmp_path / "suite.toml"
    head = f'[[run]]\nmachine = "keops"\npath = "{tmp_path / "line.json"}"\nplanners = ["{name}"]\n[sweep]\nseeds = [0, 9]\n'
    m, path = load_machine("keops"), load_path(tmp_path / "line.json")
    direct = {k: planners.plan(name, path, m, seed=k).execution_time_s for k in (0, 9)}
    assert direct[9] > direct[0] + 0.01                       # F_max binds on the line

    def times(text, out):
        suite.write_text(text)
        r = run_sweep(tasks_from_suite_file(suite), out, task_fn="harness.sweep.tasks:plan_task", workers=0, progress=False)
        assert (r.ok, r.failed) == (2, 0), r.failures
        return {row["seed"]: row["metrics"]["execution_time_s"] for row in TaskTable(out / "results.sqlite").to_rows()}

    assert times(head, tmp_path / "a") == pytest.approx(direct, abs=1e-12)
    pinned = times(head + f'[planner_options."{name}"]\nseed = 0\n', tmp_path / "b")
    assert pinned == pytest.approx({0: direct[0], 9: direct[0]}, abs=1e-12)
    # `pkmbench run --seed 9` (run_case: the full chain, ideal) plans it with seed 9 as well
    s = run_case("keops", str(tmp_path / "line.json"), [name], tmp_path / "run", seed=9, ideal=True, recordings=False)
    assert s["planners"][name]["execution_time_s"] == pytest.approx(direct[9], abs=1e-12)
