"""The architecture, read from the code (tests/import_graph.py walks every import with ast):
layers kins ← planners ← harness, planner families that meet only through their ``plan``, no
private name across packages, no import cycle. Each rule is also planted in a copy of the tree
to show the walk catches it.
"""
from __future__ import annotations

import shutil

import pytest

from tests.import_graph import FAMILIES, LAYERS, REPO, cycles, local_imports_without_reason, violations


def test_no_upward_import_no_cross_family_reach_no_private_name_across_packages():
    assert violations() == []


def test_no_import_cycle():
    assert cycles() == []


def test_every_local_import_of_the_project_says_why():
    assert local_imports_without_reason() == []


def test_planners_top_level_is_the_families_and_the_shared_vocabulary():
    entries = sorted(p.name for p in (REPO / "planners").iterdir() if p.name != "__pycache__")
    assert len(entries) <= 15, entries
    assert set(FAMILIES) <= set(entries)


@pytest.fixture
def tree(tmp_path):
    for top in LAYERS:
        shutil.copytree(REPO / top, tmp_path / top, ignore=shutil.ignore_patterns("__pycache__"))
    return tmp_path


def _append(f, text):
    f.write_text(f.read_text() + text)


def test_a_planted_upward_import_and_private_import_are_caught(tree):
    _append(tree / "planners" / "profile.py", "\n\ndef _planted():\n    from harness.cosim.run import run_case  # noqa\n")
    _append(tree / "harness" / "cli" / "plan.py", "\nfrom planners.scurve.planner import _Planner  # noqa\n")
    found = violations(tree)
    assert any("planners/profile.py" in v and "harness.cosim.run (a higher layer)" in v for v in found), found
    assert any("harness/cli/plan.py" in v and "private _Planner" in v for v in found), found


def test_a_planted_cross_family_import_is_caught_and_a_package_import_is_not(tree):
    _append(tree / "planners" / "pso" / "planner.py", "\nfrom planners.scurve.batch import Checker  # noqa\n")
    _append(tree / "planners" / "optimal" / "planner.py", "\nfrom planners.trapezoid import plan as _tp  # noqa\n")
    found = violations(tree)
    assert any("planners/pso/planner.py" in v and "family pso reaches into planners.scurve.batch" in v
               for v in found), found
    assert not any("planners/optimal/planner.py" in v and "trapezoid" in v for v in found), found


def test_a_planted_private_attribute_use_is_caught(tree):
    _append(tree / "harness" / "cli" / "plan.py",
            "\nfrom planners.optimal import topp3  # noqa\n\ndef _planted():\n    return topp3._grid\n")
    found = violations(tree)
    assert any("harness/cli/plan.py" in v and "reads private planners.optimal.topp3._grid" in v for v in found), found


def test_a_planted_cycle_is_caught(tree):
    _append(tree / "planners" / "feed.py", "\n\ndef _planted():\n    from planners.profile import Profile  # noqa: a planted cycle\n")
    _append(tree / "planners" / "profile.py", "\nfrom planners.feed import feed_mode  # noqa\n")
    assert ["planners.feed", "planners.profile"] in cycles(tree)
