"""Issue 34's kill test: `pkmbench sweep` SIGKILLed at 20 random (seeded) moments and resumed;
afterwards the results store holds every finished task exactly once, and results.sqlite and the
store agree row by row (status and metrics). After each kill the store never holds a task twice.

The suite is the line_task toy (no planner, no FMU), each task made to take a few tens of
milliseconds (its metrics computed ``repeat`` times), in-process (``--workers 0``: a SIGKILL
takes the whole sweep down, as a power cut would). In four rounds a user widens the sweep by 12
seeds and resumes it; each round is killed 5 times at moments drawn (seeded) from half-way
through the start-up to past the time its remaining tasks take, so they land in the start-up,
between and inside tasks and in the final append to the store.
"""
from __future__ import annotations

import json
import os
import random
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from harness.store import ResultStore
from harness.sweep import TaskTable
from kins.resources import REPO

LINE = {"type": "nurbs", "units": "mm", "degree": 1, "knots": [0, 0, 1, 1],
        "control_points": [[-50, 0, -400], [50, 0, -400]], "weights": [1, 1]}
ROUND, ROUNDS = 12, 4          # seeds added per round, rounds
KILLS = 20


def store_rows(store: Path) -> list[dict]:
    if not store.exists():
        return []
    with ResultStore(store) as st:
        assert st.skipped == []                      # no half-written file is ever visible
        return st.dicts("SELECT entry, status, execution_time_s, joint_jerk, metrics FROM results ORDER BY entry")


def write_suite(suite: Path, line: Path, seeds: int) -> None:
    suite.write_text(f'[[run]]\nmachine = "keops"\npath = "{line}"\nplanners = ["quintic"]\n'
                     f'[planner_options.quintic]\nfeed_mm_s = 500.0\nrepeat = 20\n'
                     f'[sweep]\nseeds = {list(range(seeds))}\n')


def finished(out: Path) -> int:
    db = out / "results.sqlite"
    if not db.exists():
        return 0
    with sqlite3.connect(db) as c:
        return c.execute("SELECT count(*) FROM results").fetchone()[0]


@pytest.mark.slow
def test_a_sweep_killed_20_times_and_resumed_stores_each_task_once(tmp_path):
    line = tmp_path / "line.json"
    line.write_text(json.dumps(LINE))
    suite = tmp_path / "kill.toml"
    out, store = tmp_path / "sweep", tmp_path / "store"
    argv = [sys.executable, "-m", "harness.cli", "sweep", str(suite), "--workers", "0", "--no-progress",
            "--task", "harness.sweep.tasks:line_task", "--out", str(out), "--store", str(store)]
    env = dict(os.environ, PYTHONPATH=str(REPO))

    def timed(args) -> float:
        t0 = time.perf_counter()
        r = subprocess.run(args, env=env, capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, r.stderr
        return time.perf_counter() - t0

    # here: a sweep's start-up (a sweep with nothing to do) and one task's time, into folders of their own
    write_suite(suite, line, ROUND)
    ref = [*argv[:-4], "--out", str(tmp_path / "ref"), "--store", str(tmp_path / "ref-store")]
    whole_s = timed(ref)
    start_s = timed(ref)
    task_s = max(whole_s - start_s, 0.0) / ROUND

    # rounds of ROUND more seeds each (a user widening a sweep), each killed KILLS // ROUNDS times at a
    # moment drawn over what is left of it (from half-way through the start-up to past its append)
    rng = random.Random(34)
    killed, runs = 0, 0
    for r in range(1, ROUNDS + 1):
        write_suite(suite, line, r * ROUND)
        while killed < r * KILLS // ROUNDS and runs < 10 * KILLS:
            left = r * ROUND - finished(out)
            p = subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            runs += 1
            time.sleep(rng.uniform(0.5 * start_s, start_s + (left + 1) * task_s))
            if p.poll() is None:
                p.send_signal(signal.SIGKILL)
                killed += 1
            p.wait(timeout=600)
            entries = [e["entry"] for e in store_rows(store)]
            assert len(entries) == len(set(entries)), "a task reached the store twice"
        done = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr
    assert killed == KILLS, f"{killed} kills in {runs} runs"

    rows = store_rows(store)
    labels = [f"keops/line/quintic/seed{s}/none/base" for s in range(ROUNDS * ROUND)]
    assert sorted(r["entry"] for r in rows) == sorted(labels)            # each task exactly once
    with TaskTable(out / "results.sqlite") as sw:
        table = {f"keops/line/quintic/seed{r['seed']}/none/base": r for r in sw.to_rows()}
    assert sorted(table) == sorted(labels)
    for r in rows:                                   # the store and results.sqlite agree
        t = table[r["entry"]]
        assert r["status"] == t["status"] == "ok"
        assert r["execution_time_s"] == t["metrics"]["execution_time_s"] == pytest.approx(0.375, abs=1e-12)
        assert r["joint_jerk"] == t["metrics"]["joint_peak_ratio"]["jerk"]
        assert json.loads(r["metrics"])["planning_time_s"] == t["metrics"]["planning_time_s"]
    print(f"\nkill test: {killed} kills in {runs} runs (start-up {start_s:.2f} s, a task {1e3 * task_s:.0f} ms), "
          f"{len(list(store.glob('*.parquet')))} store files, {len(rows)} rows, each task once")
