"""Output folders (issue 17, defects 3 and 4): every command refuses an output folder it cannot
write with one line before any work; `run` locks its folder, leaves no temporary or stale
file when interrupted, and removes the planner folders of an earlier run that it did not redo."""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from harness.cli import main
from harness.outdir import LOCK_NAME, OutDirError, output_dir, run_lock
from harness.cosim.record import replacing
from harness.cosim.system import FMU_DIR

ROOT = Path(__file__).resolve().parent.parent
SHORT_LINE = str(ROOT / "tests" / "data" / "short_line.json")
needs_fmus = pytest.mark.skipif(not all((FMU_DIR / f"{n}.fmu").exists()
                                        for n in ("Interpolator", "Kinematics", "EtherCAT", "Drive")),
                                reason="FMUs not built (make fmus)")


def run_argv(out, planners="scurve"):
    return ["run", "--machine", "keops", "--path", SHORT_LINE, "--planners", planners, "--out", str(out),
            "--no-recordings"]


def command_argv(command: str, tmp: Path, out: Path) -> list[str]:
    """A cheap, otherwise valid invocation of ``command`` writing to ``out``."""
    suite = tmp / "suite.toml"
    suite.write_text(f'[[run]]\nmachine = "keops"\npath = "{SHORT_LINE}"\nplanners = ["scurve"]\n')
    sweep = tmp / "sweep"
    sweep.mkdir(exist_ok=True)
    from harness.sweep import TaskTable, expand
    with TaskTable(sweep / "results.sqlite") as sw:   # one finished task: report checks its table first
        task = expand({"run": [{"machine": "keops", "path": SHORT_LINE, "planners": ["scurve"]}]})[0]
        sw.put("k", task, "v", {"status": "ok", "metrics": {"execution_time_s": 1.0}}, None)
    from harness.store import ResultStore, make_row
    with ResultStore(tmp / "store") as st:            # one ci run for `history` to plot
        st.append([make_row(entry="keops/l/scurve/seed0/none/base", machine="keops", path="l", planner="scurve",
                            seed=0, metrics={"execution_time_s": 1.0})], kind="ci", run_info={"passed": True})
    return {
        "run": run_argv(out),
        "plan": ["plan", "--machine", "keops", "--path", SHORT_LINE, "--out", str(out)],
        "sweep": ["sweep", str(suite), "--workers", "0", "--no-progress", "--out", str(out)],
        "report": ["report", str(sweep), "--out", str(out)],
        "figures": ["figures", "--quick", "--out", str(out)],
        "ci": ["ci", "--suite", str(suite), "--update-baseline", "--baseline", str(tmp / "b.json"),
               "--workers", "0", "--out", str(out)],
        "kins-demo": ["kins-demo", "--machines", "keops", "--out", str(out)],
        "history": ["history", "--store", str(tmp / "store"), "--out", str(out / "trend.png")],
    }[command]


COMMANDS = ["run", "plan", "sweep", "report", "figures", "ci", "kins-demo", "history"]


def one_error_line(capsys, command: str) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = [ln for ln in err.splitlines() if ln.startswith(f"pkmbench {command}: error:")]
    assert len(lines) == 1, err
    return lines[0]


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_refuses_an_output_folder_under_a_file(command, tmp_path, capsys):
    blocker = tmp_path / "a-file"
    blocker.write_text("mine")
    out = blocker / "out"
    assert main(command_argv(command, tmp_path, out)) == 2
    line = one_error_line(capsys, command)
    assert line.startswith(f"pkmbench {command}: error: cannot create ")
    assert line.endswith(f"{blocker} is a file")
    assert blocker.read_text() == "mine"


@pytest.mark.parametrize("command", [c for c in COMMANDS if c != "history"])
def test_every_command_refuses_a_file_as_output_folder(command, tmp_path, capsys):
    out = tmp_path / "a-file"
    out.write_text("mine")
    assert main(command_argv(command, tmp_path, out)) == 2
    assert one_error_line(capsys, command).endswith(f"{out} is a file, not a folder")
    assert out.read_text() == "mine"


def test_history_refuses_a_folder_as_plot_file(tmp_path, capsys):
    argv = command_argv("history", tmp_path, tmp_path)
    (tmp_path / "trend.png").mkdir()
    assert main(argv) == 2
    assert one_error_line(capsys, "history").endswith(f"plot file {tmp_path / 'trend.png'} is a folder, not a file")


def test_unwritable_output_folder(tmp_path, capsys, monkeypatch):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        if os.access(ro, os.W_OK):   # root writes anyway: make the probe fail as the kernel would
            real = Path.write_bytes
            monkeypatch.setattr(Path, "write_bytes", lambda self, data: (_ for _ in ()).throw(
                PermissionError(13, "Permission denied")) if self.parent == ro else real(self, data))
        with pytest.raises(OutDirError, match=f"cannot write to output folder {ro}: Permission denied"):
            output_dir(ro)
        assert main(["kins-demo", "--machines", "keops", "--out", str(ro)]) == 2
        assert one_error_line(capsys, "kins-demo").endswith(f"cannot write to output folder {ro}: Permission denied")
    finally:
        ro.chmod(0o700)
    assert list(ro.iterdir()) == []


def test_temporary_names_are_unique_and_removed(tmp_path):
    f = tmp_path / "summary.json"
    with replacing(f) as a, replacing(f) as b:       # two writers of one file at once
        assert a != b and a.parent == b.parent == tmp_path
        a.write_text("first")
        b.write_text("second")
    assert f.read_text() == "first"                   # the outer writer finished last
    with pytest.raises(KeyboardInterrupt):
        with replacing(f) as c:
            c.write_text("half")
            raise KeyboardInterrupt
    assert f.read_text() == "first"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["summary.json"]


def test_lock_is_exclusive_between_processes_and_removed(tmp_path):
    holder = subprocess.Popen([sys.executable, "-c", (
        "import sys, time\nfrom harness.outdir import run_lock\n"
        f"with run_lock({str(tmp_path)!r}):\n    print('held', flush=True)\n    sys.stdin.readline()\n")],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT)})
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(OutDirError, match=f"{tmp_path}: another pkmbench run is writing to this folder "
                                              rf"\(pid {holder.pid} holds {LOCK_NAME}\)"):
            with run_lock(tmp_path):
                pass
    finally:
        holder.communicate("\n", timeout=30)
    assert holder.returncode == 0
    assert not (tmp_path / LOCK_NAME).exists()
    with run_lock(tmp_path):                          # free again once the holder is done
        assert (tmp_path / LOCK_NAME).read_text() == f"{os.getpid()}\n"
    assert list(tmp_path.iterdir()) == []


@needs_fmus
def test_second_run_into_a_locked_folder_is_refused(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    with run_lock(out):                               # another run holds the folder
        assert main(run_argv(out)) == 2
    line = one_error_line(capsys, "run")
    assert line == (f"pkmbench run: error: {out}: another pkmbench run is writing to this folder "
                    f"(pid {os.getpid()} holds {LOCK_NAME}); wait for it or choose another --out")
    assert list(out.iterdir()) == []                  # nothing planned, nothing written


@needs_fmus
def test_interrupted_run_leaves_no_part_and_nothing_complete(tmp_path, capsys, monkeypatch):
    out = tmp_path / "out"
    assert main(run_argv(out)) == 0                   # an earlier, complete run
    assert (out / "summary.json").exists()

    import harness.cosim.run

    def interrupted(path, *a, **k):                   # Ctrl-C while command.csv is being written
        with replacing(path) as tmp:
            tmp.write_text("t,x,y,z,q1,q2,q3\n0,")
            raise KeyboardInterrupt

    monkeypatch.setattr(harness.cosim.run, "write_command_csv", interrupted)
    assert main(run_argv(out)) == 130
    assert "pkmbench run: interrupted" in capsys.readouterr().err
    files = sorted(str(p.relative_to(out)) for p in out.rglob("*"))
    assert not [f for f in files if f.endswith(".part") or LOCK_NAME in f], files
    assert "summary.json" not in files and "timing.json" not in files   # the old ones are gone too
    assert "scurve/command.csv" not in files


@needs_fmus
def test_rerun_with_fewer_planners_removes_their_old_folders(tmp_path):
    out = tmp_path / "out"
    assert main(run_argv(out, "scurve,trapezoid")) == 0
    assert (out / "trapezoid" / "command.csv").exists()
    mine = out / "notes"                                       # folders a run did not write stay
    mine.mkdir()
    (mine / "command.csv").write_text("my own")
    (mine / "todo.txt").write_text("keep")
    assert main(run_argv(out, "scurve")) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert list(summary["planners"]) == ["scurve"]
    dirs = sorted(p.name for p in out.iterdir() if p.is_dir())
    assert dirs == ["notes", "scurve"]
    assert (mine / "todo.txt").read_text() == "keep"
    assert not (out / LOCK_NAME).exists()
