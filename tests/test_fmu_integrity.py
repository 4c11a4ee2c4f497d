"""A damaged FMU (issue 17, defect 2): `make fmus` rebuilds it, and loading one is a one-line
error naming the file and `make fmus`, never a traceback."""
import importlib.util
import shutil
import zipfile
from pathlib import Path

import pytest

import harness.cosim.fmu_file
import harness.cosim.master
import harness.cosim.system
from harness.cli import main
from harness.cosim.fmu_driver import SteppedFmu
from harness.cosim.system import FMU_DIR, SystemError_

ROOT = Path(__file__).resolve().parent.parent
SHORT_LINE = str(ROOT / "tests" / "data" / "short_line.json")
CHAIN = ("Interpolator", "Kinematics", "EtherCAT", "Drive")

pytestmark = pytest.mark.skipif(not all((FMU_DIR / f"{n}.fmu").exists() for n in CHAIN),
                                reason="FMUs not built (make fmus)")


def rezip(src: Path, dst: Path, change) -> None:
    """dst = the zip src with each (name, bytes) passed through ``change`` (None drops it)."""
    with zipfile.ZipFile(src) as a, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as b:
        for name in a.namelist():
            data = change(name, a.read(name))
            if data is not None:
                b.writestr(name, data)


@pytest.fixture
def build_module(tmp_path, monkeypatch):
    """fmus/build.py, writing into tmp_path instead of fmus/build."""
    if shutil.which("cc") is None:
        pytest.skip("no C compiler")
    spec = importlib.util.spec_from_file_location("fmus_build", ROOT / "fmus" / "build.py")
    b = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(b)
    monkeypatch.setattr(b, "BUILD", tmp_path)
    return b


def test_build_rebuilds_a_damaged_or_foreign_fmu(build_module, tmp_path, capsys):
    b = build_module
    model = b.FMUS / "Drive"
    out = b.build(model)
    good = out.read_bytes()
    assert b.fmu_problem(out, "Drive") is None
    b.build(model)
    assert "Drive.fmu is up to date" in capsys.readouterr().out

    other = tmp_path / "other.fmu"
    damaged = {
        "corrupt zip": lambda: out.write_bytes(good[: len(good) // 2]),    # truncated
        "modelDescription.xml does not describe model Drive":
            lambda: rezip(other, out, lambda n, d: d.replace(b'modelIdentifier="Drive"', b'modelIdentifier="Kinematics"')
                          if n == "modelDescription.xml" else d),
        "no binaries/linux64/Drive.so": lambda: rezip(other, out, lambda n, d: None if n.endswith(".so") else d),
        "Drive.fmu changed since it was built": lambda: rezip(other, out, lambda n, d: d),   # whole, other bytes
    }
    for why, damage in damaged.items():
        other.write_bytes(good)
        damage()
        assert out.read_bytes() != good
        b.build(model)
        assert why in capsys.readouterr().out
        assert out.read_bytes() == good              # the build is deterministic: the same FMU again
        assert not list(tmp_path.glob("*.part")) and not list(tmp_path.glob(".*.part"))


def chain_copy(tmp_path, monkeypatch) -> Path:
    fmus = tmp_path / "fmus"
    fmus.mkdir()
    for n in CHAIN:
        shutil.copy(FMU_DIR / f"{n}.fmu", fmus)
    monkeypatch.setattr(harness.cosim.system, "FMU_DIR", fmus)
    return fmus


def test_run_with_a_truncated_or_missing_fmu_is_one_line(tmp_path, monkeypatch, capsys):
    fmus = chain_copy(tmp_path, monkeypatch)
    drive = fmus / "Drive.fmu"
    drive.write_bytes(drive.read_bytes()[:15000])
    out = tmp_path / "out"
    argv = ["run", "--machine", "keops", "--path", SHORT_LINE, "--planners", "scurve", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.splitlines()[-1] == f"pkmbench run: error: {drive}: not a valid FMU (corrupt zip); rebuild with 'make fmus'"
    assert "Traceback" not in err
    assert not (out / "summary.json").exists() and not (out / "scurve").exists()   # refused before planning
    drive.unlink()
    assert main(argv) == 2
    assert "Drive.fmu is missing: build the FMUs with 'make fmus'" in capsys.readouterr().err.splitlines()[-1]


def test_stepped_fmu_on_a_damaged_fmu(tmp_path, monkeypatch):
    monkeypatch.setattr(harness.cosim.fmu_file, "EXTRACT_DIR", tmp_path / "extracted")
    monkeypatch.setattr(harness.cosim.fmu_file, "USER_EXTRACT_DIR", tmp_path / "extracted")   # the damaged ones
    good = tmp_path / "Drive.fmu"
    shutil.copy(FMU_DIR / "Drive.fmu", good)
    sim = SteppedFmu(good, {}, 1e-3, "drive")                  # the checks accept a whole FMU
    sim.close()

    truncated = tmp_path / "a" / "Drive.fmu"
    truncated.parent.mkdir()
    truncated.write_bytes(good.read_bytes()[:20000])
    with pytest.raises(SystemError_, match=r"a/Drive.fmu: not a valid FMU \(corrupt zip\); rebuild with 'make fmus'"):
        SteppedFmu(truncated, {}, 1e-3, "drive")

    bad_so = tmp_path / "b" / "Drive.fmu"                      # a whole zip whose binary is not a library
    bad_so.parent.mkdir()
    rezip(good, bad_so, lambda n, d: b"not an ELF file" if n.endswith(".so") else d)
    cwd = Path.cwd()
    with pytest.raises(SystemError_, match=r"b/Drive.fmu: cannot load the FMU's binary .*; rebuild with 'make fmus'"):
        SteppedFmu(bad_so, {}, 1e-3, "drive")
    assert Path.cwd() == cwd                                   # not left in the FMU's binaries folder
    assert [p.name for p in (tmp_path / "extracted").iterdir()
            if not (p / ".complete").exists()] == []             # no half-extracted folder left
