"""Output folders (issue 17, defect 3): every command refuses an output folder it cannot
write with one line before any work."""
import os
from pathlib import Path

import pytest

from harness.cli import main
from harness.outdir import OutDirError, output_dir

ROOT = Path(__file__).resolve().parent.parent
SHORT_LINE = str(ROOT / "tests" / "data" / "short_line.json")


def run_argv(out, planners="scurve"):
    return ["run", "--machine", "keops", "--path", SHORT_LINE, "--planners", planners, "--out", str(out),
            "--no-recordings"]


def command_argv(command: str, tmp: Path, out: Path) -> list[str]:
    """A cheap, otherwise valid invocation of ``command`` writing to ``out``."""
    suite = tmp / "suite.toml"
    suite.write_text(f'[[run]]\nmachine = "keops"\npath = "{SHORT_LINE}"\nplanners = ["scurve"]\n')
    sweep = tmp / "sweep"
    sweep.mkdir(exist_ok=True)
    (sweep / "results.sqlite").touch()
    (tmp / "history.sqlite").touch()
    return {
        "run": run_argv(out),
        "plan": ["plan", "--machine", "keops", "--path", SHORT_LINE, "--out", str(out)],
        "sweep": ["sweep", str(suite), "--workers", "0", "--no-progress", "--out", str(out)],
        "report": ["report", str(sweep), "--out", str(out)],
        "figures": ["figures", "--quick", "--out", str(out)],
        "ci": ["ci", "--suite", str(suite), "--update-baseline", "--baseline", str(tmp / "b.json"),
               "--workers", "0", "--out", str(out)],
        "kins-demo": ["kins-demo", "--machines", "keops", "--out", str(out)],
        "history": ["history", "--history", str(tmp / "history.sqlite"), "--out", str(out / "trend.png")],
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
