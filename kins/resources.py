"""Where the checkout's data and output folders are: the one place that knows.

kins is the bottom layer, so every layer (kins, planners, harness) can ask it without an
upward import. The folders are those of the checkout this code runs from (an editable
install or PYTHONPATH), not of the current directory.
"""
from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parent.parent          # the checkout: kins/ is one level down
BENCHMARKS = REPO / "benchmarks"
MACHINE_DIR = BENCHMARKS / "machines"
PATH_DIR = BENCHMARKS / "paths"
SUITE_DIR = BENCHMARKS / "suites"
FMU_DIR = REPO / "fmus" / "build"                      # built .fmu files and the native master
RESULTS = REPO / "results"                             # every command's default output lives here
FIGURES_DIR = RESULTS / "figures"
CI_DIR = RESULTS / "ci"
BASELINE = RESULTS / "baseline.json"


def run_dir(machine: str, path: str) -> Path:
    """Default folder of `pkmbench run --machine M --path P`: results/<machine>_<path>."""
    return RESULTS / f"{Path(machine).stem}_{Path(path).stem}"


def suite_run_dir(suite_file) -> Path:
    """Default folder of `pkmbench run SUITE.toml`: results/<suite>."""
    return RESULTS / Path(suite_file).stem


def sweep_dir(suite_file) -> Path:
    """Default folder of `pkmbench sweep SUITE.toml`: results/sweeps/<suite>."""
    return RESULTS / "sweeps" / Path(suite_file).stem


def repo_relative(p: Path) -> str:
    """``p`` relative to the checkout when inside it (names equal across clones), else as is."""
    try:
        return str(Path(p).resolve().relative_to(REPO))
    except ValueError:
        return str(p)
