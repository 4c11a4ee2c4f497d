"""Planner plug-ins (issue 22): the example package installed with pip appears in `plan --list`
and runs in `run`, `sweep` and `ci` by name, with no edit of pkmbench; its execution time on a
line is the closed form of a jerk-limited rest-to-rest move. Broken plug-ins (an import error, a
wrong return type, NaN in the profile) are reported by name and the other planners' results stay.

Plug-ins are installed with pip into a temporary --target folder put first on PYTHONPATH of a
pkmbench subprocess: the same discovery (entry points of the installed distribution) as an
install into the venv, without changing the shared venv.
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
EXAMPLE = REPO / "examples" / "ruckig_planner"
LINE = {"type": "nurbs", "units": "mm", "degree": 1, "knots": [0, 0, 1, 1],
        "control_points": [[-50, 0, -400], [50, 0, -400]], "weights": [1, 1]}

BROKEN = {
    "imp.py": "import pkmbench_no_such_dependency  # noqa\n",
    "wrong.py": "def plan(path, machine, limits=None, **o):\n    return {'s': [0.0, path.length]}\n",
    "nan.py": ("import numpy as np\nfrom planners.profile import Profile\n"
               "def plan(path, machine, limits=None, **o):\n"
               "    s = np.linspace(0.0, path.length, 50)\n    s[20] = np.nan\n"
               "    return Profile.from_s('nan', machine.servo_period_s, s, path)\n"),
}
ENTRY_POINTS = ("[pkmbench.planners]\nbroken_import = brokenplug.imp:plan\n"
                "wrong_type = brokenplug.wrong:plan\nnan_profile = brokenplug.nan:plan\n")


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """pip-installed example plug-in + a hand-made distribution of three broken ones."""
    site = tmp_path_factory.mktemp("site")
    r = subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "--no-build-isolation",
                        "--no-index", "-q", "--target", str(site), str(EXAMPLE)],
                       capture_output=True, text=True, cwd=site)
    assert r.returncode == 0, r.stderr
    pkg = site / "brokenplug"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    for name, text in BROKEN.items():
        (pkg / name).write_text(text)
    dist = site / "brokenplug-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: brokenplug\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(ENTRY_POINTS)
    return site


def pkmbench(site: Path, *argv: str, cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), str(REPO)]))
    return subprocess.run([sys.executable, "-m", "harness.cli", *argv], capture_output=True,
                          text=True, env=env, cwd=cwd, timeout=900)


def closed_form_duration(L: float, v: float, a: float, j: float) -> float:
    """Rest-to-rest jerk-limited move reaching both v and a: L/v + v/a + a/j (needs
    L ≥ v²/a + v·a/j and v ≥ a²/j)."""
    assert L >= v * v / a + v * a / j and v >= a * a / j
    return L / v + v / a + a / j


def test_installed_plugin_is_listed_with_its_source_and_guarantees(site, tmp_path):
    r = pkmbench(site, "plan", "--list", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith("ruckig_path "))
    assert "plug-in pkmbench_ruckig:plan from pkmbench-ruckig 0.1.0" in lines[i]
    assert lines[i + 1].split() == ["keeps:", "cartesian:", "velocity,", "acceleration,", "feed"]
    assert any(ln.startswith("trapezoid ") and "built-in" in ln for ln in lines)
    j = next(k for k, ln in enumerate(lines) if ln.startswith("broken_import "))
    assert "BROKEN" in lines[j + 2] and "pkmbench_no_such_dependency" in lines[j + 2]


def test_plugin_runs_through_the_chain_and_matches_the_closed_form(site, tmp_path):
    (tmp_path / "line.json").write_text(json.dumps(LINE))
    (tmp_path / "suite.toml").write_text(
        f'[[run]]\nmachine = "keops"\npath = "{tmp_path / "line.json"}"\n'
        f'planners = ["ruckig_path", "trapezoid", "broken_import", "wrong_type", "nan_profile"]\n'
        f'[planner_options.ruckig_path]\nfeed_mm_s = 150.0\n')
    r = pkmbench(site, "run", str(tmp_path / "suite.toml"), "--ideal", "--no-recordings",
                 "--out", str(tmp_path / "run"), cwd=tmp_path)
    assert r.returncode == 1, r.stderr          # some planners failed …
    s = json.loads((tmp_path / "run/summary.json").read_text())["planners"]
    # … by name, one line each, and the others' results are all there
    assert s["broken_import"]["error"].startswith("planning failed: PlanningError: planner 'broken_import' "
                                                  "(plug-in brokenplug.imp:plan): importing brokenplug.imp failed")
    assert "pkmbench_no_such_dependency" in s["broken_import"]["error"]
    assert "planner 'wrong_type' returned dict, not a planners.Profile" in s["wrong_type"]["error"]
    assert "planner 'nan_profile' returned an invalid profile" in s["nan_profile"]["error"]
    assert "is not finite" in s["nan_profile"]["error"]
    assert s["trapezoid"]["execution_time_s"] > 0
    # keops: Cartesian a = 1e4, j = 5e5; the plug-in plans under a/2, j/2 and the 150 mm/s cap
    T = 250e-6
    D = closed_form_duration(100.0, 150.0, 5e3, 2.5e5)
    assert s["ruckig_path"]["execution_time_s"] == pytest.approx(math.ceil(D / T) * T, abs=1e-12)
    assert s["ruckig_path"]["cartesian_peak_ratio"]["feed"] == pytest.approx(0.15, rel=1e-6)
    # the move reaches the a/2 and j/2 it planned under (third differences: round-off ~1e-8)
    assert s["ruckig_path"]["cartesian_peak_ratio"]["acceleration"] == pytest.approx(0.5, rel=1e-6)
    assert s["ruckig_path"]["cartesian_peak_ratio"]["jerk"] == pytest.approx(0.5, rel=1e-6)
    assert s["ruckig_path"]["max_following_error_um"] == pytest.approx(0.0, abs=1e-6)   # ideal chain


def test_plugin_runs_in_sweep_and_ci(site, tmp_path):
    (tmp_path / "line.json").write_text(json.dumps(LINE))
    suite = tmp_path / "suite.toml"
    suite.write_text(f'[[run]]\nmachine = "keops"\npath = "{tmp_path / "line.json"}"\n'
                     f'planners = ["ruckig_path", "wrong_type"]\n'
                     f'[planner_options.ruckig_path]\nfeed_mm_s = 150.0\n')
    r = pkmbench(site, "sweep", str(suite), "--workers", "0", "--no-progress", "--task",
                 "harness.sweep.tasks:plan_task", "--out", str(tmp_path / "sweep"), cwd=tmp_path)
    assert r.returncode == 1 and "FAILED keops/line/wrong_type/" in r.stdout, r.stdout + r.stderr
    assert "1 run, 0 already done, 1 failed" in r.stdout
    D = math.ceil(closed_form_duration(100.0, 150.0, 5e3, 2.5e5) / 250e-6) * 250e-6
    s = json.loads(next((tmp_path / "sweep/runs").rglob("ruckig_path/summary.json")).read_text())
    assert s["planners"]["ruckig_path"]["execution_time_s"] == pytest.approx(D, abs=1e-12)

    suite.write_text(suite.read_text().replace(', "wrong_type"', ""))
    r = pkmbench(site, "ci", "--suite", str(suite), "--baseline", str(tmp_path / "baseline.json"),
                 "--out", str(tmp_path / "ci"), "--task", "harness.sweep.tasks:plan_task", "--workers", "0",
                 "--update-baseline", "--store", str(tmp_path / "store"), cwd=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    base = json.loads((tmp_path / "baseline.json").read_text())
    (entry,) = base["entries"]
    assert entry == "keops/line/ruckig_path/seed0/none/base"
    assert base["entries"][entry]["execution_time_s"] == pytest.approx(D, abs=1e-12)
