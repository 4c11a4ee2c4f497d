"""Each concept has one home (issue 31): the name is defined in that module and nowhere else in
kins/, planners/ and harness/, and the literal a concept replaced does not come back. A second
copy (a constant of the same name with another value, a function written again) fails here."""
from __future__ import annotations

import ast

import pytest

from tests.import_graph import REPO, _files, module_name

# concept name → the module that defines it (docs: planners/README.md)
HOMES = {
    "FEASIBLE_TOL": "planners.verify",                 # feasible at T: every ratio ≤ 1 + FEASIBLE_TOL
    "within": "planners.verify",
    "keeps_joints_and_feed": "planners.verify",
    "windows_above": "planners.verify",                # where a profile reads above a limit at T
    "differences": "planners.verify",
    "stretch_need": "planners.verify",
    "station_grid": "planners.constraints",            # the stations of a piece
    "curvature_splits": "planners.constraints",        # cells split by curvature radii
    "REFINE_RADII": "planners.constraints",            # the path tables' refinement (topp3's is STATION_RADII)
    "REFINE_MIN_MM": "planners.constraints",
    "JUMP_READ_FACTOR": "planners.constraints",
    "ACC_RATIO_NORMAL": "planners.trapezoid.rules",    # LinuxCNC's constants and arc rule
    "ACC_RATIO_TANGENTIAL": "planners.trapezoid.rules",
    "GAP_CYCLES": "planners.trapezoid.rules",
    "KINK_RATIO": "planners.trapezoid.rules",
    "effective_min_radius": "planners.trapezoid.rules",
    "BUILTIN_GUARANTEES": "planners.registry",         # what a planner keeps
    "guarantees": "planners.registry",
    "BUILTIN_STOCHASTIC": "planners.registry",         # which planners are run over seeds
    "stochastic": "planners.registry",
    "run_ratios": "harness.perfprofile",               # Dolan–Moré (and test_corpus::test_one_performance_profile)
    "prepare_geometry": "planners.paths.post",         # the CAM post step
    "host_info": "harness.provenance",                 # what produced a result
    "git_commit": "harness.provenance",
    "load_baseline": "harness.ci.baseline",            # the baseline file
    "write_baseline": "harness.ci.baseline",
    "fmu_problem": "harness.cosim.fmu_file",
}


def _definitions():
    """name → [modules defining it at module level (def, class, assignment)]."""
    out: dict[str, list[str]] = {}
    for f in _files(REPO):
        mod = module_name(REPO, f)
        for node in ast.parse(f.read_text(), str(f)).body:
            names = []
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                names = [node.name]
            elif isinstance(node, (ast.Assign, ast.AnnAssign)):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                names = [t.id for t in targets if isinstance(t, ast.Name)]
            for n in names:
                out.setdefault(n, []).append(mod)
    return out


DEFINED = _definitions()


@pytest.mark.parametrize("name", sorted(HOMES))
def test_a_concept_is_defined_once_in_its_home(name):
    assert DEFINED.get(name) == [HOMES[name]], f"{name}: defined in {DEFINED.get(name)}, home {HOMES[name]}"


def test_the_feasibility_literal_is_not_written_again():
    # `1 + 1e-6` (the tolerance of DESIGN.md's "feasible") is verify.FEASIBLE_TOL / verify.within
    found = []
    for f in _files(REPO):
        for node in ast.walk(ast.parse(f.read_text(), str(f))):
            if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add) \
                    and {getattr(node.left, "value", None), getattr(node.right, "value", None)} == {1, 1e-6}:
                found.append(f"{f.relative_to(REPO)}:{node.lineno}")
    assert found == []
