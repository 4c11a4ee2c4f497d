"""planners.constraints: the station grid, splitting cells by curvature, the limits' check —
against what they must give by construction."""
import math

import numpy as np
import pytest

from kins import load_machine
from kins.machine import Limits, MachineLimits
from kins.resources import REPO
from planners.constraints import PathTable, check_limits, curvature_splits, second_derivative_jumps, station_grid
from planners.errors import PlanningError
from planners.paths import NurbsPath, resolve_path


def test_station_grid_puts_every_edge_on_it_within_the_step_and_resolves_short_segments():
    edges = np.array([0.0, 0.04, 10.0, 10.3])        # a 0.04 mm blend arc between two lines
    g = station_grid(edges, 0.1, 0.0, 10.3)
    assert g[0] == 0.0 and g[-1] == 10.3 and (np.diff(g) > 0).all()
    assert all(np.isclose(g, e, rtol=0, atol=1e-15).any() for e in edges)
    assert np.diff(g).max() <= 0.1 + 1e-12
    assert ((g > 0) & (g < 0.04)).sum() == 3            # ≥ 4 intervals between two edges: 3 inside
    # ≥ 19 intervals on a short piece, however coarse grid_mm
    assert len(station_grid(np.array([0.0, 1.0]), 5.0, 0.0, 1.0)) - 1 == 19


def test_curvature_splits_cells_wider_than_the_radii_into_equal_parts():
    h = np.array([1.0, 1.0, 1.0, 1e-6])
    kappa = np.array([0.0, 0.0, 1.0, 10.0, 10.0])       # radii ∞, ∞, 1, 0.1, 0.1 at the cell ends
    need, parts = curvature_splits(h, kappa, 0.5, 1e-5, 16)
    # cell 1: 1 mm at radius 1 → 2 parts; cell 2: 1 mm at radius 0.1 → 20, capped at 16; cell 3 below min_mm
    assert need.tolist() == [1, 2] and parts.tolist() == [2, 16]
    need, _ = curvature_splits(h, kappa, 0.5, 1e-5, 16, mask=np.array([True, False, True, True]))
    assert need.tolist() == [2]


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan, math.inf])
def test_check_limits_refuses_a_limit_that_is_not_a_positive_number_naming_it(bad):
    ok = Limits(v=1.0, a=1.0, j=1.0)
    lim = MachineLimits(joint=Limits(v=1.0, a=bad, j=1.0), cartesian=ok, feed_max=1.0, chord_error_mm=0.001)
    with pytest.raises(PlanningError, match=r"test: joint limit a = .* must be a finite number > 0"):
        check_limits(lim, "test")


def test_a_second_derivative_jump_in_the_last_cell_is_read_within_the_path():
    """The epitrochoid's cusp tip at its end: P″ changes fastest in the table's last cell, whose
    one-sided reads 1e-7 mm beyond it lay outside the path (a PathError from every planner on
    the path); read within it, the end is no join."""
    machine = load_machine("keops")
    path = resolve_path(str(REPO / "benchmarks/paths/corpus/cusp_epitrochoid_keops.json"), home=machine.home)
    jumps = second_derivative_jumps(path, PathTable(path, machine), machine)
    assert all(0.0 < s < path.length for s, _ in jumps)


def test_every_knot_of_a_quadratic_nurbs_is_a_second_derivative_jump_and_none_of_a_cubics():
    """P″ of a quadratic NURBS jumps at each simple interior knot (its pieces are conics) and is
    continuous at a cubic's. rational_quadratic_kossel's jumps are small beside its steep P″:
    the cell search alone found 17 of its 37 knots, and optimal's profile broke J at T at the rest."""
    machine = load_machine("kossel")
    path = resolve_path(str(REPO / "benchmarks/paths/corpus/rational_quadratic_kossel.json"), home=machine.home)
    knots = path.s_of_u(np.unique(path.knots)[1:-1])
    jumps = second_derivative_jumps(path, PathTable(path, machine), machine)
    assert len(knots) == 37 and np.allclose([s for s, _ in jumps], knots, rtol=0, atol=1e-6)
    P = [[-8, -6, -300], [-3, 6, -300], [2, -6, -300], [6, 5, -300], [9, -4, -300], [12, 3, -300]]
    cubic = NurbsPath(3, [0, 0, 0, 0, 1 / 3, 2 / 3, 1, 1, 1, 1], P)
    assert second_derivative_jumps(cubic, PathTable(cubic, machine), machine) == []
