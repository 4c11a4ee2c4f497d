"""planners.optimal.timewarp: the local stretch's chain rule against finite differences, its inverse,
the whole periods that leave the samples after a bump as they were, its bump width in closed
form, and topp3's last resort choosing it where it is cheaper."""
import dataclasses
import math

import numpy as np
import pytest

import planners.optimal.topp3 as topp3
from kins import Limits, load_machine
from planners.paths import Line, SegmentPath
from planners.profile import Profile
from planners.optimal.timewarp import (REACH, WIDTH_REACH, WIDTH_SPEED_MARGIN, Local, Uniform, bump_width, bumps_for,
                                       local_widths)
from planners.verify import stretch_need

KOSSEL = load_machine("kossel")


class Quintic:
    """s(t) = L·(10u³ − 15u⁴ + 6u⁵), u = t/D: a rest-to-rest move with its derivatives exact."""
    s0 = 0.0

    def __init__(self, L=10.0, D=2.0):
        self.L, self.duration = L, D

    def at(self, t):
        u = np.clip(np.asarray(t, float), 0.0, self.duration) / self.duration
        L, D = self.L, self.duration
        return (L * (10 * u ** 3 - 15 * u ** 4 + 6 * u ** 5), L * (30 * u ** 2 - 60 * u ** 3 + 30 * u ** 4) / D,
                L * (60 * u - 180 * u ** 2 + 120 * u ** 3) / D ** 2, L * (60 - 360 * u + 360 * u ** 2) / D ** 3)


def test_local_stretch_derivatives_are_the_chain_rule_of_its_positions():
    """ṡ, s̈, s⃛ of the stretched motion equal central differences of its own positions
    (an independent second method), and t(t′) inverts t′(t)."""
    w = Local(Quintic(), tau=0.1)
    w.add([0.6, 1.3], [0.02, 0.05])
    assert w.duration == pytest.approx(2.0 + math.pi * 0.1 * 0.07, rel=1e-12)
    tp = np.linspace(0.2, w.duration - 0.2, 41)
    h = 1e-3
    S = [w.at(tp + k * h)[0] for k in (-2, -1, 0, 1, 2)]
    _, sd, sdd, sddd = w.at(tp)
    assert np.allclose(sd, (S[3] - S[1]) / (2 * h), rtol=1e-5, atol=1e-6)
    assert np.allclose(sdd, (S[3] - 2 * S[2] + S[1]) / h ** 2, rtol=1e-4, atol=1e-4)
    assert np.allclose(sddd, (S[4] - 2 * S[3] + 2 * S[1] - S[0]) / (2 * h ** 3), rtol=1e-3, atol=1e-2)
    t = w.original(tp)
    off, lam, _, _ = w._terms(t)
    assert np.allclose(t + off, tp, rtol=0, atol=1e-13)
    assert lam.min() >= 1.0 and lam.max() > 1.04          # the bumps overlap around 1 s


def test_a_bump_of_whole_periods_leaves_the_later_samples_as_they_were():
    """Samples beyond a bump's reach are the unstretched samples n periods earlier, to round-off:
    they read at T as they did."""
    T, n, tau = 1e-3, 7, 0.02
    base = Quintic(L=10.0, D=3.0)
    w = Local(base, tau)
    w.add([0.5], [n * T / (math.pi * tau)])
    k = np.arange(int((0.5 + REACH * tau) / T) + 1, 2900)
    assert np.allclose(w.at(k * T + n * T)[0], base.at(k * T)[0], rtol=0, atol=1e-12)
    k = np.arange(0, int((0.5 - REACH * tau) / T))
    assert np.allclose(w.at(k * T)[0], base.at(k * T)[0], rtol=0, atol=1e-12)
    assert w.duration == pytest.approx(3.0 + n * T, abs=1e-15)


def test_uniform_stretch_scales_time():
    u = Uniform(Quintic(), 1.25)
    s, sd, sdd, sddd = u.at(np.array([1.0]))
    ref = Quintic().at(np.array([0.8]))
    assert u.duration == 2.5
    assert np.allclose([s, sd, sdd, sddd], [ref[0], ref[1] / 1.25, ref[2] / 1.25 ** 2, ref[3] / 1.25 ** 3])


@pytest.mark.parametrize("V, A, J, tau", [
    (1000.0, 1e4, 5e5, 0.1),                                        # keops: V/A
    (20.0, 500.0, 1e4, 0.05 + math.sqrt(0.05 ** 2 + 2 * 20 / 3e4)),  # kossel: the jerk's terms
])
def test_bump_width_keeps_the_first_order_terms_within_half_the_relief(V, A, J, tau):
    w = bump_width(Limits(V, A, J))
    assert w == pytest.approx(tau, rel=1e-12)
    tu = A / J
    assert tu / w + V / (3 * J * w * w) <= 0.5 + 1e-12 and V / (2 * A * w) <= 0.5 + 1e-12


def test_last_resort_stretches_locally_where_one_stretch_of_the_line_reads_above():
    """The kossel vertical line (copp's profile), sped up by a negative bump around t = 2.5 s: its
    reads above lie there only.  The last resort brings every read within the limits by bumps
    there, for less than the uniform stretch of the piece costs, and leaves the samples before
    the bumps as they were."""
    path = SegmentPath([Line([0, 0, -300], [0, 0, -200])])
    T = KOSSEL.servo_period_s
    piece = topp3.pieces_of(path, KOSSEL, KOSSEL.limits, topp3.Settings("copp"))[0]
    prof_c, ts = piece.solve(topp3.Settings("copp"))
    span = topp3._Topp3Span(piece, prof_c, ts)
    fast = Local(span, 0.05)
    fast.add([2.5], [-0.01])                        # 1 % faster around t = 2.5 s: reads above there

    prof = Profile.from_pieces("copp", T, [fast], path, {})
    # read against the limits the unstretched profile keeps (copp's cruise reads F_max 1 + 2e-4)
    base = Profile.from_pieces("copp", T, [span], path, {})
    r0 = stretch_need(KOSSEL.ik(path.point(base.s)), base.s, T, KOSSEL.limits).max()
    lim = dataclasses.replace(KOSSEL.limits.joint_scaled(r0 ** 3), feed_max=KOSSEL.limits.feed_max * r0)
    assert not topp3.reads_above(base, KOSSEL, path, lim)
    need = stretch_need(KOSSEL.ik(path.point(prof.s)), prof.s, T, lim)
    above = np.nonzero(need > 1 + 1e-6)[0]
    assert len(above) and abs(prof.t[above] - 2.5).max() < 0.5
    local = topp3.stretch_locally(prof, [fast], KOSSEL, path, lim, {}, "copp")
    uniform = topp3._stretch_uniformly(prof, [fast], KOSSEL, path, lim, {}, "copp")
    assert not topp3.reads_above(local, KOSSEL, path, lim)
    assert not topp3.reads_above(uniform, KOSSEL, path, lim)
    assert local.execution_time_s < uniform.execution_time_s
    # the last resort: the fastest within the limits, here the local stretch of the last round
    out = topp3._stretch(prof, [[fast]], KOSSEL, path, lim, {}, "copp")
    assert out.execution_time_s == local.execution_time_s and out.info["local_stretch"]["round"] == 0
    # before the bumps the samples move by no more than their tails' offset, ≤ 2τ·Σδ·e^(−d/τ)
    # at a distance d (a time), times the speed
    tau = bump_width(KOSSEL.limits.joint)
    assert local.info["local_stretch"]["bumps"] >= 1
    d = 2.5 - 0.6 - prof.t[:1500]
    heights = local.info["local_stretch"]["added_s"] / (math.pi * tau)
    bound = KOSSEL.limits.feed_max * 2 * tau * heights * np.exp(-d / tau) + 1e-12
    assert np.all(np.abs(local.s[:1500] - prof.s[:1500]) <= bound)


def test_bumps_cover_each_cell_of_reads_by_whole_periods():
    """One bump per τ-cell of reads, at its worst read, as high as that read needs, its added
    time a whole number of periods (at least one)."""
    T, tau = 2.5e-4, 0.1
    w = Local(Quintic(D=3.0), tau)
    c, d, taus = bumps_for(w, np.array([0.51, 0.52, 0.58, 1.43]), np.array([1.001, 1.02, 1.0000001, 1.003]), T, 1e-5)
    assert np.allclose(c, [0.52, 1.43], rtol=0, atol=1e-12) and np.array_equal(taus, [tau, tau])
    periods = d * math.pi * tau / T
    assert np.allclose(periods, np.round(periods), rtol=0, atol=1e-9) and periods.min() >= 1
    assert d[0] >= 0.02 * (1 + 1e-5) and d[0] - 0.02 < T / (math.pi * tau) + 1e-5


def test_a_bump_where_the_joints_are_slow_is_narrower_and_adds_its_time_by_its_own_width():
    """keops (V/A = 0.1 s sets the widest bump): a bump's τ is bump_width at the fastest joint
    speed within WIDTH_REACH widest bumps, × WIDTH_SPEED_MARGIN (closed form), never wider than
    at V; near a fast stretch it is as wide as there; a cell's bump takes its reads' widest τ,
    its height whole periods of T at that τ."""
    lim = Limits(1000.0, 1e4, 5e5)
    T, widest = 2.5e-4, bump_width(lim)
    # one joint at 10 mm/s for 2 s, then 500 mm/s for 1 s, then 900 mm/s
    v = np.r_[np.full(8000, 10.0), np.full(4000, 500.0), np.full(4000, 900.0)]
    Q = np.zeros((len(v), 3))
    Q[:, 1] = np.cumsum(v) * T
    tu = lim.a / lim.j
    slow = WIDTH_SPEED_MARGIN * 10.0
    assert local_widths(Q, T, lim, [100])[0] == pytest.approx(max(tu + math.sqrt(tu * tu + 2 * slow / (3 * lim.j)),
                                                                  slow / lim.a), rel=1e-12)
    assert local_widths(Q, T, lim, [100])[0] < 0.5 * widest
    near = 8000 - int(WIDTH_REACH * widest / T) + 10            # the fast stretch within reach
    fast = bump_width(lim, WIDTH_SPEED_MARGIN * 500.0)
    assert local_widths(Q, T, lim, [near])[0] == pytest.approx(fast, rel=1e-12) and fast < widest
    assert local_widths(Q, T, lim, [15000])[0] == widest         # 900 mm/s × the margin: capped at V
    w = Local(Quintic(D=3.0), widest)
    c, d, taus = bumps_for(w, np.array([0.51, 0.52]), np.array([1.02, 1.001]), T, 1e-5, np.array([0.03, 0.05]))
    assert np.array_equal(taus, [0.05]) and np.allclose(c, [0.51])
    periods = d * math.pi * taus / T
    assert np.allclose(periods, np.round(periods), rtol=0, atol=1e-9)
    w.add(c, d, taus)
    assert w.added_s == pytest.approx(np.round(periods)[0] * T, rel=1e-12)
    assert w.duration == pytest.approx(3.0 + w.added_s, rel=1e-12)
