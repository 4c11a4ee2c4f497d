"""planners.verify and planners.profile against closed forms and round trips."""
import numpy as np
import pytest

from planners.verify import chord_error_mm, command_metrics, differences, limit_ratios
from kins import Limits, load_machine
from planners.profile import Profile, ProfileError


class Line:
    """A stand-in path: straight line from a to b (arc-length parametrised)."""

    def __init__(self, a, b):
        self.a, self.b = np.asarray(a, float), np.asarray(b, float)
        self.length = float(np.linalg.norm(self.b - self.a))

    def point(self, s):
        return self.a + np.asarray(s, float)[:, None] / self.length * (self.b - self.a)


class Circle:
    def __init__(self, r):
        self.r, self.length = r, 2 * np.pi * r

    def point(self, s):
        th = np.asarray(s, float) / self.r
        return np.stack([self.r * np.cos(th), self.r * np.sin(th), np.zeros_like(th)], axis=1)


def test_differences_of_a_cubic_are_exact():
    T = 1e-3
    t = np.arange(50) * T
    x = 2.0 + 3.0 * t + 5.0 * t**2 + 7.0 * t**3          # third derivative 42
    d = differences(x[:, None], T, rest=False)
    assert d["velocity"].shape == (49, 1) and d["jerk"].shape == (47, 1)
    np.testing.assert_allclose(d["jerk"], 42.0, rtol=1e-6)
    # backward difference of a quadratic: exact derivative at the midpoint
    np.testing.assert_allclose(d["acceleration"][:, 0], 10.0 + 42.0 * (t[1:-1]), rtol=1e-6)


@pytest.mark.parametrize("n", [1, 2, 3, 4, 6])
def test_differences_count_the_rest_before_and_after_for_every_length(n):
    """A ramp x_k = k·d (k < n) between rest before t = 0 and after the end: the third
    differences with the rest read d/T³ where the motion starts and stops (coefficients 1, −3,
    3, −1 on x = 0, 0, 0, d), except for n = 2 (0, 0, d, d: −2d) and n = 1 (no motion); the
    velocity d/T, the acceleration d/T² (0, 0, d). Before, n < 4 read jerk 0 (n = 1, 2, 3)."""
    T, d = 1e-3, 1e-5          # a 10 nm step per period, as a 10 nm G1 sampled at 1 ms
    x = (np.arange(n) * d)[:, None]
    D = differences(x, T)
    assert [len(D[o]) for o in ("velocity", "acceleration", "jerk")] == [n + 3, n + 2, n + 1]
    peak = {o: float(np.abs(D[o]).max()) for o in D}
    moving = n > 1
    assert peak["velocity"] == pytest.approx(moving * d / T, rel=1e-9)
    assert peak["acceleration"] == pytest.approx(moving * d / T**2, rel=1e-9)
    assert peak["jerk"] == pytest.approx(moving * (2 if n == 2 else 1) * d / T**3, rel=1e-9)
    # the metrics read the same: a 10 nm move at 1 ms is 1e4 mm/s³ of jerk, not 0
    ratios, viol = limit_ratios(x, T, Limits(v=1.0, a=1.0, j=1.0))
    assert ratios["jerk"] == pytest.approx(peak["jerk"], rel=1e-9)
    assert (ratios["jerk"] > 1) == moving and (viol["jerk"] > 0) == moving


@pytest.mark.parametrize("n", [0, 1, 2, 3, 5, "BLOCK-5", "BLOCK-2", "BLOCK+1", "2*BLOCK+3"])
def test_difference_peaks_are_the_maxima_of_the_differences_block_by_block(n):
    # difference_peaks reads its blocks from X itself (the rest before and after by repeated
    # first and last rows): per window the largest |difference| over the axes of
    # differences(X) (which pads X with its rest) and its axis, bit for bit, at any length and
    # across the block boundaries
    from planners.verify import BLOCK, ORDERS, difference_peaks
    n = eval(str(n), {"BLOCK": BLOCK})
    T = 1e-3
    X = np.random.default_rng(n).normal(size=(n, 3)).cumsum(axis=0)
    D = differences(X, T)
    for order, (worst, col) in zip(ORDERS, difference_peaks(X, T)):
        A = np.abs(D[order])
        assert worst.tobytes() == (A.max(axis=1) if len(A) else np.zeros(0)).tobytes()
        assert col.tolist() == (A.argmax(axis=1).tolist() if len(A) else [])


def test_a_one_period_jump_is_infeasible():
    """A 2-sample profile jumping 14 mm in one period (a plug-in's): velocity 14 mm / T,
    infeasible; before, its acceleration and jerk read 0 and a 3-sample one read 'feasible'."""
    m = load_machine("keops")
    T = m.servo_period_s
    P = np.array([[0.0, 0.0, -400.0], [14.0, 0.0, -400.0]])
    out = command_metrics(m, P, T, np.array([0.0, 14.0]))
    assert out["cartesian_peak_ratio"]["velocity"] == pytest.approx(14.0 / T / m.limits.cartesian.v, rel=1e-12)
    assert out["cartesian_peak_ratio"]["jerk"] == pytest.approx(2 * 14.0 / T**3 / m.limits.cartesian.j, rel=1e-9)
    assert out["feasible"] is False


def test_limit_ratios_peak_and_violation_time():
    T = 0.01
    v = np.array([0, 1, 3, 3, 3, 1, 0], float)     # speeds per period
    x = np.concatenate([[0.0], np.cumsum(v * T)])
    peak, viol = limit_ratios(x[:, None], T, Limits(v=2.0, a=1e9, j=1e12))
    assert peak["velocity"] == pytest.approx(1.5)
    assert viol["velocity"] == pytest.approx(3 * T)   # three periods at 3 > 2


def test_command_metrics_keops_line_closed_form():
    """A constant-feed straight line through the centre of keops along x: the Cartesian
    velocity ratio is feed/v_max exactly; joints move at |∂q/∂x|·feed."""
    m = load_machine("keops")
    T = m.servo_period_s
    feed = 100.0
    n = 400
    s = np.arange(n) * feed * T
    P = np.column_stack([-20.0 + s, np.zeros(n), np.full(n, -400.0)])
    out = command_metrics(m, P, T, s)
    assert out["cartesian_peak_ratio"]["velocity"] == pytest.approx(feed / 1000.0, rel=1e-9)
    assert out["cartesian_peak_ratio"]["feed"] == pytest.approx(feed / 1000.0, rel=1e-9)
    # it starts and stops at full feed: from and into rest, a step of feed/T (acceleration) and
    # of feed/T² (jerk: third differences 1, −3, 3, −1 on x0, x0, x0, x0 + feed·T)
    assert out["cartesian_peak_ratio"]["acceleration"] == pytest.approx(feed / T / 1e4, rel=1e-9)
    assert out["cartesian_peak_ratio"]["jerk"] == pytest.approx(feed / T**2 / 5e5, rel=1e-9)
    assert out["cartesian_violation_time_s"]["acceleration"] == pytest.approx(2 * T)
    dq = np.abs(m.jacobian(P)[:, :, 0]).max() * feed
    assert out["joint_peak_ratio"]["velocity"] == pytest.approx(dq / 1000.0, rel=1e-3)
    assert out["feasible"] is False
    assert out["execution_time_s"] == pytest.approx((n - 1) * T)


def test_chord_error_of_sampled_circle():
    r, ds = 10.0, 0.5
    c = Circle(r)
    s = np.arange(0, c.length, ds)
    err = chord_error_mm(c.point(s), c, s)
    assert err == pytest.approx(r * (1 - np.cos(ds / (2 * r))), rel=1e-9)


def test_profile_round_trip_is_exact(tmp_path):
    path = Line([0, 0, 0], [10.0 / 3.0, 0, 0])
    T = 1e-3
    t = np.linspace(0, 1, 1001)
    s = path.length * (3 * t**2 - 2 * t**3)
    p = Profile.from_s("test", T, s, path)
    p.validate()
    f = tmp_path / "profile.csv"
    p.save_csv(f)
    q = Profile.load_csv(f, path)
    for k in ("s", "sd", "sdd", "sddd"):
        assert np.array_equal(getattr(p, k), getattr(q, k))
    assert q.T == pytest.approx(T, rel=1e-12)
    assert f.read_text().splitlines()[0] == "t,s,sd,sdd,sddd"


def test_profile_validation_errors():
    path = Line([0, 0, 0], [1, 0, 0])
    T = 1e-3
    with pytest.raises(ProfileError, match="runs backwards at sample 2"):
        Profile.from_s("p", T, [0, 0.6, 0.5, 1.0], path).validate()
    with pytest.raises(ProfileError, match="ends at s = 0.9"):
        Profile.from_s("p", T, [0, 0.5, 0.9], path).validate()
    with pytest.raises(ProfileError, match=r"sd\[1\] .* is not finite"):
        Profile("p", T, np.array([0, 1.0]), np.array([0, np.nan]), np.zeros(2), np.zeros(2), path).validate()


def test_profile_load_rejects_bad_files(tmp_path):
    path = Line([0, 0, 0], [1, 0, 0])
    f = tmp_path / "bad.csv"
    f.write_text("t,s\n0,0\n")
    with pytest.raises(ProfileError, match="bad.csv: header is 't,s'"):
        Profile.load_csv(f, path)
    with pytest.raises(ProfileError, match="cannot read profile"):
        Profile.load_csv(tmp_path / "missing.csv", path)
    f.write_text("t,s,sd,sdd,sddd\n0,0,0,0,zero\n")
    with pytest.raises(ProfileError, match="malformed profile"):
        Profile.load_csv(f, path)


def test_worst_sample_finds_a_single_step():
    """One sample displaced by d: its velocity reads d/T, its acceleration 2d/T², its jerk 3d/T³
    (third-difference coefficients 1, −3, 3, −1), first in the window starting two samples
    before it; with these limits the jerk ratio is the largest."""
    from planners.verify import worst_sample
    T, d = 1e-3, 1e-6
    X = np.zeros((30, 3))
    X[10, 1] = d
    order, i, ratio = worst_sample(X, T, Limits(1.0, 1.0, 1e3))
    assert (order, i) == ("jerk", 8)
    assert ratio == pytest.approx(3 * d / T ** 3 / 1e3)
    order, i, ratio = worst_sample(X, T, Limits(1e-4, 1.0, 1e9))
    assert (order, i, ratio) == ("velocity", 9, pytest.approx(d / T / 1e-4))


class _Piece:
    """s0 + p(t) on [0, duration]: a jerk ramp from rest (jerk J) or a cruise at feed F."""

    def __init__(self, duration, s0, J=0.0, F=0.0, sampled=True):
        self.duration, self.s0, self.J, self.F, self.sampled = duration, s0, J, F, sampled

    def at(self, tt):
        assert self.sampled, "a piece with no sample time inside it was evaluated"
        tt = np.minimum(tt, self.duration)
        J, F = self.J, self.F
        return J * tt ** 3 / 6 + F * tt, J * tt ** 2 / 2 + F, J * tt, np.full_like(tt, J)


def test_profile_from_pieces_samples_each_piece_at_its_own_time():
    # ramp 10.5 ms (J = 6e5 mm/s³), cruise 20 ms at 50 mm/s, 0.3 ms between two samples, cruise
    # 9.5 ms: samples at k·T in closed form, the last at the path end at rest
    T, J, F = 1e-3, 6e5, 50.0
    d = [0.0105, 0.020, 0.0003, 0.0095]
    s1 = J * d[0] ** 3 / 6
    s2 = s1 + F * d[1]
    s3 = s2 + F * d[2]
    L = s3 + F * d[3]
    pieces = [_Piece(d[0], 0.0, J=J), _Piece(d[1], s1, F=F), _Piece(d[2], s2, F=F, sampled=False),
              _Piece(d[3], s3, F=F)]
    p = Profile.from_pieces("x", T, pieces, Line([0, 0, 0], [L, 0, 0]), {"a": 1})
    assert len(p.s) == 42 and p.info == {"a": 1, "continuous_time_s": pytest.approx(sum(d), rel=1e-15)}
    t = np.arange(42) * T
    ramp = t < d[0]
    want_s = np.where(ramp, J * t ** 3 / 6, np.where(t < d[0] + d[1], s1 + F * (t - d[0]), s3 + F * (t - sum(d[:3]))))
    assert np.allclose(p.s[:-1], want_s[:-1], rtol=1e-12, atol=0)
    assert np.allclose(p.sd[:-1], np.where(ramp, J * t ** 2 / 2, F)[:-1], rtol=1e-12, atol=0)
    assert np.array_equal(p.sddd[:-1], np.where(ramp, J, 0.0)[:-1])
    assert (p.s[-1], p.sd[-1], p.sdd[-1], p.sddd[-1]) == (L, 0.0, 0.0, 0.0)
    p.validate()


@pytest.mark.parametrize("duration", [2.4e5, float("inf"), float("nan")])
def test_a_profile_of_too_many_samples_is_refused_before_it_is_allocated(duration):
    """A wild intermediate profile (2.4·10⁵ s at 250 µs: 7 GB) is a PlanningError naming its
    length, not a memory error that kills the run; nothing is evaluated."""
    from planners import PlanningError
    with pytest.raises(PlanningError, match="more than 2e\\+07: not sampled"):
        Profile.from_pieces("x", 250e-6, [_Piece(duration, 0.0, F=1.0, sampled=False)], Line([0, 0, 0], [1, 0, 0]))
