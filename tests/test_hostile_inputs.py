"""Issue 34: the store, sweeps, plug-ins and metrics under hostile and sloppy input. Each test
failed before its fix: a wrong result given silently, rows lost, a file written outside its
folder, a traceback or a hang. Bad input gets one line naming the file or key, exit 2."""
from __future__ import annotations

import json
import os
import re
import sqlite3
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

import planners
from harness.cli import main as cli
from harness.outdir import run_lock
from harness.store import ResultStore, make_row
from harness.sweep import SuiteError, TaskTable, expand, load_suite, run_sweep
from kins import load_machine
from kins.resources import FMU_DIR, REPO

LINE = {"type": "nurbs", "units": "mm", "degree": 1, "knots": [0, 0, 1, 1],
        "control_points": [[-50, 0, -400], [50, 0, -400]], "weights": [1, 1]}
LINE_TASK = "harness.sweep.tasks:line_task"

# plug-ins, each a module written into a folder put on sys.path
PLUGINS = {
    # what the README says a plug-in is: plan(path, machine, limits=None, **options) -> planners.Profile
    "readme_plug": ("import numpy as np\nfrom planners import Profile\n\n"
                    "def plan(path, machine, limits=None, **options):\n"
                    "    n = 4001\n    u = np.arange(n) / (n - 1)\n"
                    "    return Profile.from_s('readme_plug', machine.servo_period_s,\n"
                    "                          path.length * u**3 * (10 - 15 * u + 6 * u**2), path)\n"),
    # the same quintic, its Profile imported from the module that held it before planners did
    "quintic_plug": ("import numpy as np\nfrom planners.profile import Profile\n\n"
                     "def plan(path, machine, limits=None, **options):\n"
                     "    n = 4001\n    u = np.arange(n) / (n - 1)\n"
                     "    return Profile.from_s('quintic_plug', machine.servo_period_s,\n"
                     "                          path.length * u**3 * (10 - 15 * u + 6 * u**2), path)\n"),
    # 100 mm in one period, from rest to rest
    "jump_plug": ("from planners.profile import Profile\n\n"
                  "def plan(path, machine, limits=None, **options):\n"
                  "    return Profile.from_s('jump', machine.servo_period_s, [0.0, path.length], path)\n"),
    # the README's plug-in at ten times the machine's period
    "slow_t_plug": ("import quintic_plug\n\n"
                    "def plan(path, machine, limits=None, **options):\n"
                    "    p = quintic_plug.plan(path, machine)\n    p.T *= 10\n    return p\n"),
    # changes the machine it was given: its limits a thousandth, its period doubled
    "greedy_plug": ("import dataclasses\nimport quintic_plug\n\n"
                    "def plan(path, machine, limits=None, **options):\n"
                    "    L = machine.limits\n"
                    "    machine.limits = dataclasses.replace(L, joint=dataclasses.replace(L.joint, v=L.joint.v / 1000))\n"
                    "    machine.servo_period_s *= 2\n"
                    "    return quintic_plug.plan(path, machine)\n"),
    # what the machine looked like to it
    "spy_plug": ("import quintic_plug\nSEEN = []\n\n"
                 "def plan(path, machine, limits=None, **options):\n"
                 "    SEEN.append((machine.limits.joint.v, machine.servo_period_s))\n"
                 "    return quintic_plug.plan(path, machine)\n"),
    # never returns
    "sleepy_plug": ("import time\n\ndef plan(path, machine, limits=None, **options):\n"
                    "    time.sleep(3600)\n"),
    # prints on stdout, then plans as the trapezoid does
    "chatty_plug": ("import planners\n\ndef plan(path, machine, limits=None, **options):\n"
                    "    print('chatty: planning', path.length)\n"
                    "    return planners.get_planner('trapezoid')(path, machine, limits)\n"),
}


@pytest.fixture
def plugins(tmp_path, monkeypatch) -> Path:
    folder = tmp_path / "plugins"
    folder.mkdir()
    for name, text in PLUGINS.items():
        (folder / f"{name}.py").write_text(text)
    monkeypatch.syspath_prepend(str(folder))
    for name in PLUGINS:
        sys.modules.pop(name, None)
    return folder


@pytest.fixture
def line(tmp_path) -> Path:
    f = tmp_path / "line.json"
    f.write_text(json.dumps(LINE))
    return f


def one_error_line(err: str, command: str) -> str:
    """The command's stderr is one error line (no traceback); returns it."""
    assert "Traceback" not in err, err
    lines = [ln for ln in err.strip().splitlines() if ln.startswith(f"pkmbench {command}: error:")]
    assert len(lines) == 1, err
    return lines[0]


def line_suite(tmp_path: Path, line: Path, extra: str = "", planners_=("quintic",)) -> Path:
    suite = tmp_path / "s.toml"
    suite.write_text(f'[[run]]\nmachine = "keops"\npath = "{line}"\nplanners = {json.dumps(list(planners_))}\n'
                     f'[planner_options.quintic]\nfeed_mm_s = 500.0\n{extra}')
    return suite


# -- wrong results, silently ------------------------------------------------------------------
def test_a_plugin_jumping_in_one_period_is_infeasible_in_plan(plugins, line, capsys):
    """A 2-sample profile (14 mm … here 100 mm in one period): before, its acceleration and
    jerk read 0 (differences between samples only) and `plan` said 'feasible yes'."""
    assert cli(["plan", "--machine", "keops", "--path", str(line), "--planners", "jump_plug:plan"]) == 0
    row = next(ln for ln in capsys.readouterr().out.splitlines() if "jump_plug:plan" in ln)
    assert row.split()[-1] == "NO"
    m = load_machine("keops")
    # the joint jerk of a 100 mm step read with the rest around it: ≫ 1, never 0
    assert float(row.split()[-2]) > 1e3 and m.servo_period_s == 250e-6


def test_a_profile_at_another_period_is_refused_where_it_enters(plugins, line, capsys):
    """Sampled at 10 T, the profile read 10 × the time with the same ratios, 'feasible yes'."""
    m = load_machine("keops")
    with pytest.raises(planners.PlanningError, match=r"'slow_t_plug:plan' returned a profile sampled at "
                                                     r"T = 0.0025 s; keops's servo period is 0.00025 s"):
        planners.plan("slow_t_plug:plan", str(line), m)
    assert cli(["plan", "--machine", "keops", "--path", str(line), "--planners", "slow_t_plug:plan,quintic_plug:plan"]) == 1
    out = capsys.readouterr().out
    assert re.search(r"slow_t_plug:plan\s+failed: planner 'slow_t_plug:plan' returned a profile sampled at T = 0.0025 s", out)
    assert re.search(r"quintic_plug:plan\s+1\.0000", out)          # the other planner's row stays


def test_a_plugin_changing_the_machine_changes_it_for_itself_only(plugins, line):
    m = load_machine("keops")
    v, T = m.limits.joint.v, m.servo_period_s
    with pytest.raises(planners.PlanningError, match="sampled at T = 0.0005 s"):   # its own doubled T
        planners.plan("greedy_plug:plan", str(line), m)
    planners.plan("spy_plug:plan", str(line), m)
    import spy_plug
    assert spy_plug.SEEN == [(v, T)]                  # the planner after it saw the machine's limits
    assert (m.limits.joint.v, m.servo_period_s) == (v, T)


def test_unknown_keys_of_sweep_tables_are_refused(tmp_path, line, capsys):
    suite = line_suite(tmp_path, line, "[sweep]\nseedz = [1, 2]\n")
    with pytest.raises(SuiteError, match=r"s.toml:line 8: \[sweep\]: unknown key 'seedz' \(valid: seeds, presets, variation\)"):
        load_suite(suite)
    suite.write_text(suite.read_text().replace("seedz = [1, 2]", 'seeds = [1]\n[[sweep.variation]]\nname = "a"\nsett = {}'))
    with pytest.raises(SuiteError, match=r"\[\[sweep.variation\]\] #1: unknown key 'sett'"):
        load_suite(suite)
    assert cli(["sweep", str(suite), "--workers", "0", "--task", LINE_TASK, "--out", str(tmp_path / "o")]) == 2
    assert "unknown key 'sett'" in one_error_line(capsys.readouterr().err, "sweep")
    assert not (tmp_path / "o").exists()


# -- data lost ------------------------------------------------------------------------------
def store_of_one_row(folder: Path) -> None:
    with ResultStore(folder) as st:
        st.append([make_row(entry="keops/line/quintic/seed0/none/base", machine="keops", path="line",
                            planner="quintic", seed=0, metrics={"execution_time_s": 0.375})], kind="sweep")


def store_with_bad_files(folder: Path) -> None:
    store_of_one_row(folder)
    good = next(folder.glob("*.parquet"))
    (folder / "truncated.parquet").write_bytes(good.read_bytes()[:300])
    import duckdb
    duckdb.connect().execute(f"COPY (SELECT 1 AS x, 'y' AS run_id) TO '{folder / 'foreign.parquet'}' (FORMAT parquet)")


def test_a_bad_parquet_file_is_skipped_and_named(tmp_path, line, capsys):
    store = tmp_path / "store"
    store_with_bad_files(store)
    assert cli(["query", "--store", str(store), "--csv", "SELECT count(*) AS n FROM results"]) == 0
    out, err = capsys.readouterr()
    assert out.split() == ["n", "1"]
    assert "warning: skipped" in err and "truncated.parquet" in err and "foreign.parquet" in err
    assert "Traceback" not in err
    assert cli(["store", "check", "--store", str(store)]) == 1
    out = capsys.readouterr().out.splitlines()
    assert sorted(ln.split(":")[0] for ln in out if ln.startswith("SKIPPED")) == \
        [f"SKIPPED {store / 'foreign.parquet'}", f"SKIPPED {store / 'truncated.parquet'}"]
    assert out[-1] == f"store {store}: 1 file(s) read, 2 skipped, 0 partial"
    # the sweep's rows reach the store beside the bad files
    suite = line_suite(tmp_path, line)
    assert cli(["sweep", str(suite), "--workers", "0", "--no-progress", "--task", LINE_TASK,
                "--out", str(tmp_path / "o"), "--store", str(store)]) == 0
    with ResultStore(store) as st:
        assert st.query("SELECT count(*) FROM results")[1] == [(2,)]


def test_an_interrupted_sweep_brings_every_finished_task_to_the_store_once(tmp_path, line):
    """Tasks finished before an interrupt were in results.sqlite and never reached the store."""
    suite = line_suite(tmp_path, line, "[sweep]\nseeds = [0, 1, 2, 3]\n")
    out, store = tmp_path / "o", tmp_path / "store"
    # the interrupted sweep: 2 of 4 tasks finished, recorded, never appended
    run_sweep(expand(load_suite(suite))[:2], out, task_fn=LINE_TASK, workers=0, progress=False)
    argv = ["sweep", str(suite), "--workers", "0", "--no-progress", "--task", LINE_TASK, "--out", str(out),
            "--store", str(store)]
    assert cli(argv) == 0
    assert cli(argv) == 0                              # again: nothing new, nothing appended twice
    with ResultStore(store) as st:
        rows = st.query("SELECT entry, count(*) FROM results GROUP BY entry ORDER BY entry")[1]
    assert rows == [(f"keops/line/quintic/seed{s}/none/base", 1) for s in range(4)]


def test_an_append_interrupted_around_its_rename_is_not_repeated(tmp_path, line):
    """The sweep table says which file holds which row before the file is written: a file found
    in the store is complete (renamed in whole), one not found is written again."""
    from harness.sweep.to_store import append_unstored
    suite = line_suite(tmp_path, line, "[sweep]\nseeds = [0, 1]\n")
    out, store = tmp_path / "o", tmp_path / "store"
    run_sweep(expand(load_suite(suite)), out, task_fn=LINE_TASK, workers=0, progress=False)
    db = out / "results.sqlite"
    with TaskTable(db) as sw:                         # killed after marking, before writing
        sw.begin_append(sw.unappended(store), "sweep-lost", store)
    run_id, n = append_unstored(db, kind="sweep", suite="s", store=store)
    assert n == 2 and (store / f"{run_id}.parquet").exists()
    with TaskTable(db) as sw:                         # killed after the rename, before the mark
        sw.db.execute("UPDATE appended SET done = 0")
        sw.db.commit()
    assert append_unstored(db, kind="sweep", suite="s", store=store) == ("", 0)
    assert len(list(store.glob("*.parquet"))) == 1


def test_a_second_sweep_into_a_folder_is_refused(tmp_path, line, capsys):
    suite = line_suite(tmp_path, line)
    out = tmp_path / "o"
    out.mkdir()
    with run_lock(out):
        assert cli(["sweep", str(suite), "--workers", "0", "--task", LINE_TASK, "--out", str(out)]) == 2
    assert "another pkmbench run is writing to this folder" in one_error_line(capsys.readouterr().err, "sweep")
    assert not (out / "results.sqlite").exists()


def test_a_store_that_does_not_exist_is_said(tmp_path, capsys):
    for argv in (["query", "--store", str(tmp_path / "nope"), "SELECT 1"],
                 ["history", "--store", str(tmp_path / "nope")],
                 ["store", "check", "--store", str(tmp_path / "nope")]):
        assert cli(argv) == 2
        assert f"results store {tmp_path / 'nope'}: no such folder" in one_error_line(capsys.readouterr().err, argv[0])
    assert not (tmp_path / "nope").exists()


# -- writes where it must not -----------------------------------------------------------------
@pytest.mark.parametrize("spec", ["../../x:plan", "/{tmp}/abs/x:plan"])
def test_a_planner_name_is_no_folder_outside_the_output(tmp_path, line, spec, capsys):
    deep = tmp_path / "a" / "b"
    deep.mkdir(parents=True)
    spec = spec.format(tmp=str(tmp_path).strip("/"))
    before = sorted(p for p in tmp_path.rglob("*"))
    assert cli(["run", "--machine", "keops", "--path", str(line), "--planners", spec, "--ideal",
                "--no-recordings", "--out", str(deep / "out")]) == 1
    new = sorted(set(tmp_path.rglob("*")) - set(before))
    assert new and all(p.is_relative_to(deep / "out") for p in new), new
    s = json.loads((deep / "out" / "summary.json").read_text())["planners"]
    assert list(s) == [spec] and "module" in s[spec]["error"]


def test_query_cannot_write_or_read_other_files(tmp_path, capsys):
    store = tmp_path / "store"
    store_of_one_row(store)
    target = tmp_path / "written.csv"
    for sql in (f"COPY (SELECT 1) TO '{target}'", f"ATTACH '{tmp_path / 'x.db'}'",
                f"SELECT * FROM read_csv('{REPO / 'README.md'}')", "CREATE TABLE t (a INT)",
                f"COPY (SELECT 1 AS a) TO '{next(store.glob('sweep-*.parquet'))}' (FORMAT parquet, USE_TMP_FILE false)"):
        assert cli(["query", "--store", str(store), sql]) == 2, sql
        one_error_line(capsys.readouterr().err, "query")
    assert not target.exists() and not (tmp_path / "x.db").exists()
    with ResultStore(store) as st:                      # the store file is whole
        assert st.query("SELECT count(*) FROM results")[1] == [(1,)]


def test_a_user_fmu_is_unpacked_outside_the_checkout(tmp_path):
    from harness.cosim.fmu_file import EXTRACT_DIR, USER_EXTRACT_DIR
    from harness.cosim.master import extract
    user = tmp_path / "mydrive.fmu"                    # our Drive with one more file: not our build
    with zipfile.ZipFile(FMU_DIR / "Drive.fmu") as a, zipfile.ZipFile(user, "w") as b:
        for n in a.namelist():
            b.writestr(n, a.read(n))
        b.writestr("documentation/user.txt", "a user's FMU")
    before = set(EXTRACT_DIR.iterdir()) if EXTRACT_DIR.exists() else set()
    folder = extract(user)
    assert folder.is_relative_to(USER_EXTRACT_DIR) and not folder.is_relative_to(REPO)
    assert (folder / "documentation" / "user.txt").read_text() == "a user's FMU"
    assert (set(EXTRACT_DIR.iterdir()) if EXTRACT_DIR.exists() else set()) == before
    assert extract(FMU_DIR / "Drive.fmu").is_relative_to(EXTRACT_DIR)      # ours stay beside the build


# -- tracebacks and hangs ---------------------------------------------------------------------
LONG = "x" * 300


@pytest.mark.parametrize("argv", [
    ["run", "--machine", "keops", "--path", "bird", "--planners", "scurve", "--out", "{tmp}/" + LONG],
    ["plan", "--machine", "keops", "--path", "{tmp}/" + LONG + ".ngc"],
    ["check", "{tmp}/" + LONG + ".ngc", "--machine", "keops"],
    ["sweep", "{tmp}/" + LONG + ".toml"],
    ["report", "{tmp}/" + LONG],
])
def test_a_too_long_file_name_is_one_line(tmp_path, capsys, argv):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    assert cli(argv) == 2
    err = one_error_line(capsys.readouterr().err, argv[0])
    assert "xxxxx" in err and ("too long" in err or "no such" in err or "not a sweep folder" in err)


def test_a_closed_stdout_is_one_line(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(REPO))
    p = subprocess.Popen([sys.executable, "-m", "harness.cli", "plan", "--list"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, env=env, cwd=tmp_path)
    p.stdout.close()                                   # the reader leaves before anything is written
    err = p.stderr.read().decode()
    assert p.wait(timeout=120) == 2
    assert one_error_line(err, "plan").endswith("output closed before it was all written (broken pipe)")


@pytest.mark.parametrize("command", ["run", "sweep"])
@pytest.mark.parametrize("slot, bad, key", [("machine", 'machine = 42', "machine = 42"),
                                            ("machine", 'machines = ["keops", 7]', "machines = 7"),
                                            ("path", 'path = true', "path = True"),
                                            ("planners", 'planners = [[1]]', "planners = [1]")])
def test_a_value_of_the_wrong_type_in_a_suite_is_named(tmp_path, line, capsys, command, slot, bad, key):
    good = {"machine": 'machine = "keops"', "path": f'path = "{line}"', "planners": 'planners = ["quintic"]'}
    good[slot] = bad
    suite = tmp_path / "s.toml"
    suite.write_text("[[run]]\n" + "\n".join(good.values()) + "\n")
    assert cli([command, str(suite), "--out", str(tmp_path / "o")]) == 2
    assert f"{key}: expected a name" in one_error_line(capsys.readouterr().err, command)


def test_a_corrupt_results_sqlite_is_one_line(tmp_path, line, capsys):
    sweep = tmp_path / "sweep"
    sweep.mkdir()
    (sweep / "results.sqlite").write_bytes(b"this is not a database" * 100)
    assert cli(["report", str(sweep)]) == 2
    assert f"{sweep / 'results.sqlite'}: not a sweep's results table" in one_error_line(capsys.readouterr().err, "report")
    assert not (sweep / "report").exists()
    assert cli(["sweep", str(line_suite(tmp_path, line)), "--workers", "0", "--task", LINE_TASK,
                "--out", str(sweep)]) == 2
    assert f"{sweep / 'results.sqlite'}: not a sweep's results table" in one_error_line(capsys.readouterr().err, "sweep")
    with sqlite3.connect(tmp_path / "empty.sqlite"):
        pass


@pytest.mark.parametrize("doc", ["[1, 2]", '"baseline"', '{"format": "pkmbench-ci-baseline/1", "entries": {"a": 3}}'])
def test_ci_refuses_a_baseline_that_is_json_but_not_one(tmp_path, line, capsys, doc):
    from harness.ci.baseline import FORMAT
    (tmp_path / "b.json").write_text(doc.replace("pkmbench-ci-baseline/1", FORMAT))
    assert cli(["ci", "--suite", str(line_suite(tmp_path, line)), "--baseline", str(tmp_path / "b.json"),
                "--task", LINE_TASK, "--workers", "0", "--out", str(tmp_path / "ci")]) == 2
    err = one_error_line(capsys.readouterr().err, "ci")
    assert str(tmp_path / "b.json") in err and ("not a pkmbench baseline" in err or "entries.a" in err)


def test_a_user_fmu_with_a_junk_binary_is_refused_before_planning(tmp_path, line, capsys):
    user = tmp_path / "mydrive.fmu"
    with zipfile.ZipFile(FMU_DIR / "Drive.fmu") as a, zipfile.ZipFile(user, "w") as b:
        for n in a.namelist():
            b.writestr(n, b"\x7fELF but junk" if n.endswith(".so") else a.read(n))
    out = tmp_path / "run"
    assert cli(["run", "--machine", "keops", "--path", str(line), "--planners", "scurve", "--ideal",
                "--fmu", f"Drive={user}", "--out", str(out)]) == 2
    err = one_error_line(capsys.readouterr().err, "run")
    assert f"Drive FMU {user}: not loadable here (its binary binaries/" in err and "does not load" in err
    assert "make fmus" not in err
    assert not (out / "scurve").exists()


def test_a_suite_of_a_million_tasks_is_refused_and_a_sweep_says_its_count(tmp_path, line, capsys):
    from harness.sweep.suite import MAX_TASKS
    big = line_suite(tmp_path, line, f"[sweep]\nseeds = [{', '.join(map(str, range(MAX_TASKS + 1)))}]\n")
    assert cli(["sweep", str(big), "--workers", "0", "--task", LINE_TASK, "--out", str(tmp_path / "o")]) == 2
    assert (f"expands to {MAX_TASKS + 1} tasks (runs × seeds × presets × variations), more than the "
            f"{MAX_TASKS}") in one_error_line(capsys.readouterr().err, "sweep")
    small = line_suite(tmp_path, line, "[sweep]\nseeds = [0, 1, 2]\n")
    assert cli(["sweep", str(small), "--workers", "0", "--no-progress", "--task", LINE_TASK,
                "--out", str(tmp_path / "o"), "--store", "none"]) == 0
    assert f"sweep {small}: 3 tasks → {tmp_path / 'o'}" in capsys.readouterr().err.splitlines()[0]


def test_a_planner_over_its_timeout_is_its_rows_error(plugins, line, tmp_path, capsys):
    assert cli(["plan", "--machine", "keops", "--path", str(line), "--planners", "sleepy_plug:plan,quintic_plug:plan",
                "--planner-timeout", "3"]) == 1
    out = capsys.readouterr().out
    assert re.search(r"sleepy_plug:plan\s+failed: planner 'sleepy_plug:plan' exceeded the planner timeout of 3 s", out)
    assert re.search(r"quintic_plug:plan\s+1\.0000", out)
    # the suite key, in a sweep: the row names the timeout, the other task is done
    suite = tmp_path / "t.toml"
    suite.write_text(f'planner_timeout_s = 3\n[[run]]\nmachine = "keops"\npath = "{line}"\n'
                     f'planners = ["sleepy_plug:plan", "quintic_plug:plan"]\n')
    assert cli(["sweep", str(suite), "--workers", "0", "--no-progress", "--task", "harness.sweep.tasks:plan_task",
                "--out", str(tmp_path / "o"), "--store", "none"]) == 1
    rows = {r["planner"]: r for r in TaskTable(tmp_path / "o/results.sqlite").to_rows()}
    assert rows["quintic_plug:plan"]["status"] == "ok"
    assert "exceeded the planner timeout of 3 s" in rows["sleepy_plug:plan"]["error"]
    with pytest.raises(SystemExit) as e:               # argparse's one line
        cli(["plan", "--machine", "keops", "--path", str(line), "--planner-timeout", "-1"])
    assert e.value.code == 2 and "--planner-timeout: '-1': expected a number of seconds > 0" in capsys.readouterr().err


def test_check_json_keeps_stdout_for_the_report(plugins, tmp_path, capsys):
    prog = tmp_path / "p.ngc"
    prog.write_text("G21 G90\nG0 X0 Y0 Z-250\nF600\nG1 X10 Y0\nM2\n")
    code = cli(["check", str(prog), "--machine", "kossel", "--planner", "chatty_plug:plan", "--json"])
    out, err = capsys.readouterr()
    rep = json.loads(out)                              # stdout is the JSON alone
    assert code in (0, 1) and "findings" in rep
    assert "chatty: planning 10" in err


def test_query_json_is_strict_json(tmp_path, capsys):
    store = tmp_path / "store"
    store_of_one_row(store)
    assert cli(["query", "--store", str(store), "--json",
                "SELECT 'nan'::DOUBLE AS a, 'inf'::DOUBLE AS b, '-inf'::DOUBLE AS c, 1.5 AS d"]) == 0

    def refuse(name):
        raise ValueError(f"not strict JSON: {name}")
    assert json.loads(capsys.readouterr().out, parse_constant=refuse) == [{"a": None, "b": None, "c": None, "d": 1.5}]


def test_a_plugin_written_from_the_readme_imports_and_runs(plugins, line, capsys):
    readme = (REPO / "README.md").read_text()
    assert "`plan(path, machine, limits=None, **options) ->\nplanners.Profile`" in readme
    assert "Profile" in planners.__all__ and planners.Profile is planners.profile.Profile
    assert cli(["plan", "--machine", "keops", "--path", str(line), "--planners", "readme_plug:plan"]) == 0
    row = next(ln for ln in capsys.readouterr().out.splitlines() if "readme_plug:plan" in ln)
    assert float(row.split()[1]) == pytest.approx(4000 * 250e-6)
    assert np.isfinite([float(x) for x in row.split()[3:6]]).all()
