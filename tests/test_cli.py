"""Issue 17: seeds, console output, help/version, portable SSP folders."""
from __future__ import annotations

import json
import re
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from harness.cli import main as cli
from harness.cosim.record import read_command_csv
from harness.cosim.system import FMU_DIR

DATA = Path(__file__).parent / "data"
LINE = str(DATA / "short_line.json")
needs_fmus = pytest.mark.skipif(not all((FMU_DIR / f"{n}.fmu").exists()
                                        for n in ("Interpolator", "Kinematics", "EtherCAT", "Drive")),
                                reason="FMUs not built (make fmus)")


# -- seeds ---------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", ["-1", str(2**64)])
def test_run_refuses_a_seed_outside_0_to_2_pow_64(seed, tmp_path, capsys):
    assert cli(["run", "--machine", "keops", "--path", LINE, "--planners", "scurve",
                "--seed", seed, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"pkmbench run: error: --seed = {seed}: a seed must be an integer with 0 <= seed < 2**64"
    assert not (tmp_path / "o").exists()


def test_suite_task_and_api_seeds_are_checked(tmp_path, capsys):
    from harness.cosim.run import RunError, run_case
    from harness.sweep import SuiteError, make_task
    from harness.sweep.suite import MACHINE_DIR

    suite = tmp_path / "s.toml"
    suite.write_text(f'[[run]]\nmachine = "keops"\npath = "{LINE}"\nplanners = ["scurve"]\n'
                     "[sweep]\nseeds = [0, -1]\n")
    assert cli(["sweep", str(suite), "--workers", "0", "--out", str(tmp_path / "o")]) == 2
    assert f"{suite}: [sweep] seeds[1] = -1: a seed must be" in capsys.readouterr().err
    suite.write_text(f'[[run]]\nmachine = "keops"\npath = "{LINE}"\nplanners = ["pso"]\n'
                     f"[planner_options.pso]\nseed = {2**64}\n")
    assert cli(["sweep", str(suite), "--workers", "0", "--out", str(tmp_path / "o")]) == 2
    assert "[planner_options.pso] seed = 18446744073709551616" in capsys.readouterr().err
    with pytest.raises(SuiteError, match="seed = -3"):
        make_task(MACHINE_DIR / "keops.toml", Path(LINE), "scurve", seed=-3)
    with pytest.raises(RunError, match=r"seed = True: a seed must be an integer"):
        run_case("keops", LINE, ["scurve"], tmp_path / "r", seed=True)
    with pytest.raises(RunError, match="planner_options.pso.seed = -2"):
        run_case("keops", LINE, ["pso"], tmp_path / "r", planner_options={"pso": {"seed": -2}})


def test_fmu_seed_keeps_32_bit_seeds_and_hashes_larger_ones():
    from harness.cosim.drive_params import ethercat_start_values
    from harness.seed import fmu_seed

    # < 2³²: the same 32 bits as before (the FMU reads its Integer as unsigned)
    assert [fmu_seed(s) for s in (0, 1, 2**31 - 1, 2**31, 3_000_000_000, 2**32 - 1)] == \
        [0, 1, 2**31 - 1, -2**31, 3_000_000_000 - 2**32, -1]
    # ≥ 2³²: SeedSequence's first 32-bit word, not the low 32 bits (2³² used to wrap to seed 0)
    big = fmu_seed(2**32)
    assert big % 2**32 == int(np.random.SeedSequence(2**32).generate_state(1, np.uint32)[0]) != 0
    assert fmu_seed(2**64 - 1) == fmu_seed(2**64 - 1) and -2**31 <= fmu_seed(2**64 - 1) < 2**31
    assert ethercat_start_values("keops", seed=2**32)["seed"] == big


@needs_fmus
def test_a_64_bit_seed_reaches_the_bus_and_the_sweep_store(tmp_path):
    """Seed 2³² drew the bus lateness of seed 0 (ctypes wrapped it); 2⁶⁴ − 1 overflowed SQLite."""
    from harness.sweep import TaskTable, run_sweep
    from harness.sweep.suite import expand

    suite = {"run": [{"machine": "keops", "path": LINE, "planners": ["trapezoid"]}],
             "sweep": {"seeds": [0, 2**32, 2**64 - 1], "presets": ["tuned_rt"]}}
    res = run_sweep(expand(suite), tmp_path, workers=0, progress=False)
    assert (res.ok, res.failed) == (3, 0), res.failures
    rows = TaskTable(tmp_path / "results.sqlite").to_rows()
    assert sorted(r["seed"] for r in rows) == [0, 2**32, 2**64 - 1]
    hist = {s: next(tmp_path.glob(f"runs/**/seed{s}/trapezoid/trapezoid/lateness.csv")).read_text()
            for s in (0, 2**32)}
    assert hist[0].splitlines()[0] == hist[2**32].splitlines()[0]      # the same cycles …
    assert hist[0] != hist[2**32]                                      # … other draws


# -- SSP -----------------------------------------------------------------------------------
@needs_fmus
def test_a_run_folder_moved_elsewhere_loads_in_the_harness_and_in_fmpy(tmp_path):
    """The SSP files name the FMUs and the run's files relative to the folder (resources/)."""
    from fmpy.ssp.ssd import read_ssd

    from harness.cosim.master import simulate
    from harness.cosim.run import RECORD
    from harness.cosim.system import read_ssp

    assert cli(["run", "--machine", "keops", "--path", LINE, "--planners", "scurve",
                "--out", str(tmp_path / "a"), "--no-recordings"]) == 0
    moved = shutil.move(tmp_path / "a", tmp_path / "elsewhere" / "b")
    pdir = Path(moved) / "scurve"
    assert str(tmp_path / "a") not in (pdir / "SystemStructure.ssd").read_text()
    assert "path.json" in (pdir / "SystemStructure.ssd").read_text()      # the start values are in it
    res = simulate(read_ssp(pdir / "SystemStructure.ssd"), RECORD)
    P = read_command_csv(pdir / "command.csv")[:, 1:4]          # t, x, y, z, q1, q2, q3
    assert len(P) > 500
    np.testing.assert_array_equal(np.column_stack([res[f"interpolator.{a}"] for a in "xyz"])[:len(P)], P)
    # the folder zipped is an .ssp that fmpy reads, every component's FMU inside it
    ssp = tmp_path / "run.ssp"
    with zipfile.ZipFile(ssp, "w") as z:
        for f in pdir.rglob("*"):
            z.write(f, f.relative_to(pdir).as_posix())
    names = set(zipfile.ZipFile(ssp).namelist())
    comps = read_ssd(str(ssp), validate=True).system.elements
    assert len(comps) == 6 and {c.source for c in comps} == {"resources/Interpolator.fmu", "resources/Kinematics.fmu",
                                                             "resources/EtherCAT.fmu", "resources/Drive.fmu"}
    assert all(c.source in names for c in comps)
    assert json.loads((Path(moved) / "summary.json").read_text())["planners"]["scurve"]["feasible"] is True


# -- console ---------------------------------------------------------------------------------
@needs_fmus
def test_run_prints_whole_errors_and_names_only_the_files_it_wrote(tmp_path, capsys):
    """The error was cut at 110 characters; mcap/rrd were announced with --no-recordings."""
    assert cli(["run", "--machine", "kossel", "--path", LINE, "--planners", "trapezoid,scurve",
                "--out", str(tmp_path), "--no-recordings"]) == 1        # trapezoid fails
    out = capsys.readouterr().out
    err = json.loads((tmp_path / "summary.json").read_text())["planners"]["trapezoid"]["error"]
    assert len(err) > 110 and f"  trapezoid       {err}\n" in out
    assert f"results: {tmp_path}/summary.json; per planner: command.csv\n" in out
    assert (tmp_path / "scurve/command.csv").exists() and not list(tmp_path.rglob("run.*"))


# -- help and version --------------------------------------------------------------------------
def test_help_is_a_whole_sentence_and_lists_every_command(capsys):
    """The description was the docstring's first line, cut mid-sentence ('… with')."""
    from harness.cli import COMMANDS, DESCRIPTION
    with pytest.raises(SystemExit) as e:
        cli(["--help"])
    assert e.value.code == 0
    out = " ".join(capsys.readouterr().out.split())
    assert " ".join(DESCRIPTION.split()) in out and DESCRIPTION.endswith(".")
    assert not out.split("positional arguments")[0].rstrip().endswith(" with")
    for name, (_, help_) in COMMANDS.items():
        assert f"{name} {' '.join(help_.split())}" in out


def test_version_prints_the_package_version_and_git_commit(capsys):
    import subprocess
    from importlib.metadata import version
    repo = Path(__file__).resolve().parent.parent
    with pytest.raises(SystemExit) as e:
        cli(["--version"])
    assert e.value.code == 0
    out = capsys.readouterr().out.strip()
    head = subprocess.run(["git", "-C", str(repo), "rev-parse", "--short=12", "HEAD"],
                          capture_output=True, text=True)
    expect = f"pkmbench {version('pkmbench')}"
    if head.returncode == 0:                     # a git checkout: its commit follows
        assert out.startswith(f"{expect} (git {head.stdout.strip()}") and out.endswith(")")
    else:
        assert out == expect


# -- README --------------------------------------------------------------------------------------
README = (Path(__file__).resolve().parent.parent / "README.md").read_text()


def test_readme_lists_every_command_and_reports_on_the_sweeps_default_folder():
    from harness.cli import COMMANDS
    commands = README.split("## Commands")[1].split("```")[1]
    for name in COMMANDS:
        assert f"\npkmbench {name} " in commands, name
    # `sweep S.toml` writes results/sweeps/<suite stem>: the report example must read there
    assert "pkmbench sweep benchmarks/suites/nightly.toml" in commands
    assert "pkmbench report results/sweeps/nightly " in commands


@needs_fmus
def test_readme_output_files_names_every_file_a_run_writes(tmp_path):
    assert cli(["run", "--machine", "keops", "--path", LINE, "--planners", "scurve",
                "--out", str(tmp_path), "--jitter", "tuned_rt"]) == 0
    section = README.split("## Output files")[1].split("\n## ")[0]
    written = sorted(f.relative_to(tmp_path).as_posix().replace("scurve/", "<planner>/")
                     for f in tmp_path.rglob("*") if f.is_file())
    assert len(written) >= 14
    for name in written:
        shown = re.sub(r"resources/\w+\.fmu", "resources/*.fmu", name).replace("SystemStructure.ssv", "SystemStructure.ssd`, `.ssv")
        assert f"`{shown}`" in section, name


@needs_fmus
def test_run_start_plans_a_program_from_the_given_position(tmp_path, capsys):
    # a program whose only move is a G1 to (30, 40, -250): it starts at --start, else at home
    prog = tmp_path / "one.ngc"
    prog.write_text("G21 G90\nG1 X30 Y40 Z-250 F3000\nM2\n")
    for start, first in (("0,0,-250", [0.0, 0.0, -250.0]), (None, [0.0, 0.0, -200.0])):
        out = tmp_path / f"run_{start is None}"
        args = ["run", "--machine", "kossel", "--path", str(prog), "--planners", "scurve", "--out", str(out),
                "--no-recordings", "--ideal"] + (["--start", start] if start else [])
        assert cli(args) == 0
        summary = json.loads((out / "summary.json").read_text())
        assert summary.get("start_mm") == ([0.0, 0.0, -250.0] if start else None)
        xyz = np.loadtxt(out / "scurve/command.csv", delimiter=",", skiprows=1, usecols=(1, 2, 3))
        assert xyz[0] == pytest.approx(first, abs=1e-9) and xyz[-1] == pytest.approx([30.0, 40.0, -250.0], abs=1e-9)
    assert cli(["run", "--machine", "kossel", "--path", str(prog), "--start", "a,b,c"]) == 2
    assert "--start a,b,c: expected X,Y,Z in mm" in capsys.readouterr().err
