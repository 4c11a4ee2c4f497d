"""toppra reference: closed forms where only one constraint binds; bad input."""
import math

import numpy as np
import pytest

from kins import Limits, MachineLimits, load_machine
from planners import PlanningError, plan
from planners.paths import Arc, Line, SegmentPath

KOSSEL = load_machine("kossel")
KEOPS = load_machine("keops")


def test_vertical_line_on_a_linear_delta_is_the_trapezoid_closed_form():
    """On a linear delta a vertical move drives every joint exactly like z (q′ = 1, q″ = 0),
    so TOPP-RA with joint v, a limits gives the trapezoid: L/V + V/A."""
    L = 30.0
    path = SegmentPath([Line([0, 0, -300], [0, 0, -300 + L])])
    p = plan("toppra", path, KOSSEL)
    V, A = KOSSEL.limits.joint.v, KOSSEL.limits.joint.a          # 20 mm/s = F_max, 500 mm/s²
    exact = L / V + V / A
    assert p.info["continuous_time_s"] == pytest.approx(exact, rel=2e-3)
    assert abs(p.execution_time_s - exact) <= 2 * KOSSEL.servo_period_s + 2e-3 * exact


def test_chord_error_cap_sets_the_feed_on_an_arc():
    """With huge joint limits the feed on an arc is the chord-error cap (2/T)√(2ρε − ε²)."""
    big = Limits(1e9, 1e12, 1e15)
    lim = MachineLimits(big, big, 1e9, 0.001)
    r = 0.5
    path = SegmentPath([Arc([r, 0, -400], [0, 0, -400], [0, 0, 1], 6.0)])
    p = plan("toppra", path, KEOPS, lim)
    T = KEOPS.servo_period_s
    cap = 2 / T * math.sqrt(2 * r * 0.001 - 1e-6)                 # ≈ 252.8 mm/s
    assert p.sd.max() == pytest.approx(cap, rel=1e-3)
    # cruise at the cap; the first and last grid intervals start/stop at constant s̈
    ds = path.length / (p.info["grid_points"] - 1)
    assert path.length / cap <= p.info["continuous_time_s"] <= (path.length + 2 * ds) / cap


def test_lower_bound_below_the_jerk_limited_planners():
    z = -400.0
    path = SegmentPath([Line([-40, -20, z], [0, -20, z]), Arc([0, -20, z], [0, 0, z], [0, 0, 1], np.pi / 2)])
    t_top = plan("toppra", path, KEOPS).execution_time_s
    assert t_top < plan("scurve_joint", path, KEOPS).execution_time_s


def test_limit_not_positive():
    lim = KEOPS.limits
    bad = MachineLimits(Limits(lim.joint.v, -1.0, lim.joint.j), lim.cartesian, lim.feed_max, lim.chord_error_mm)
    with pytest.raises(PlanningError, match="joint limit a = -1"):
        plan("toppra", SegmentPath([Line([0, 0, -400], [10, 0, -400])]), KEOPS, bad)
