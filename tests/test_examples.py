"""examples/: each numbered script runs and prints its table (03, the full FMU chain, is slow)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
EXAMPLES = sorted((REPO / "examples").glob("[0-9][0-9]_*.py"))
SLOW = {"03_run_the_fmu_chain.py"}


def test_the_examples_are_numbered_and_all_here():
    assert [f.name[:2] for f in EXAMPLES] == ["01", "02", "03", "04", "05"]


@pytest.mark.parametrize("script", [pytest.param(f, id=f.name, marks=[pytest.mark.slow] if f.name in SLOW else [])
                                    for f in EXAMPLES])
def test_example_runs(script):
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    r = subprocess.run([sys.executable, str(script)], cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip(), "an example prints what it shows"
