"""The one check of a profile at the servo period T (DESIGN.md "The metrics"), used by the
planners themselves (pso and optimal check their result with it), by the harness's run
metrics, by `pkmbench plan`, the sweeps and the tests.

Peak ratios are read on the commanded trajectory exactly as a drive would see it: the
positions at period T, derivatives by backward finite differences at T (velocity a first
difference, acceleration a second, jerk a third). At 250 µs this makes an 8 nm position error
read as 5·10⁵ mm/s³, which is why everything upstream keeps full double precision.

The drive holds the first position before t = 0 and the last one after the end: the
differences are taken over the samples with that rest on both sides (:func:`at_rest`), so the
step out of rest and into it counts, whatever the profile's length (a 2-sample profile that
jumps 14 mm reads that jump as a velocity, an acceleration and a jerk).
"""
from __future__ import annotations

import numpy as np

from kins.machine import Limits

FEASIBLE_TOL = 1e-6          # DESIGN.md: feasible ⇔ every peak ratio ≤ 1 + 1e-6
ORDERS = ("velocity", "acceleration", "jerk")
BLOCK = 1 << 14               # samples per block of difference_peaks
# rest samples on each side: a jerk window (4 samples) reaching one moving sample needs 2 more
REST_PAD = len(ORDERS) - 1


def at_rest(X: np.ndarray) -> np.ndarray:
    """X (N, k) with its first row repeated REST_PAD times before it and its last row after it:
    the trajectory with the rest it starts and ends in."""
    X = np.asarray(X, float)
    if len(X) == 0:
        return X
    return np.concatenate([np.repeat(X[:1], REST_PAD, axis=0), X, np.repeat(X[-1:], REST_PAD, axis=0)])


def window_sample(i, n: int, k: int = 0):
    """The sample of X (n samples) that sample ``k`` of rest-padded difference window ``i``
    reads (clipped to 0 … n-1: the rest before and after is the first and last sample)."""
    return np.clip(np.asarray(i) + k - REST_PAD, 0, max(n - 1, 0))


def differences(X: np.ndarray, T: float, rest: bool = True) -> dict[str, np.ndarray]:
    """Velocity, acceleration, jerk of samples X (N, k) at period T. With ``rest`` (the
    metrics) over :func:`at_rest` (X): lengths N+3, N+2, N+1, window i reading samples i-2 …
    (:func:`window_sample`); without it (plots of the sampled motion) lengths N-1, N-2, N-3."""
    X = at_rest(X) if rest else np.asarray(X, float)
    v = np.diff(X, 1, axis=0) / T
    a = np.diff(v, 1, axis=0) / T
    j = np.diff(a, 1, axis=0) / T
    return {"velocity": v, "acceleration": a, "jerk": j}


def limit_ratios(X: np.ndarray, T: float, limits: Limits) -> tuple[dict, dict]:
    """(peak ratio, violation time in s) per derivative order, over all columns of X."""
    lim = {"velocity": limits.v, "acceleration": limits.a, "jerk": limits.j}
    peak, viol = {}, {}
    for order, D in differences(X, T).items():
        r = np.abs(D).max(axis=1) / lim[order] if len(D) else np.zeros(0)
        peak[order] = float(r.max()) if len(r) else 0.0
        viol[order] = float(np.count_nonzero(r > 1.0 + FEASIBLE_TOL) * T)
    return peak, viol


def within(ratio) -> bool:
    """A peak ratio within its limit at T (DESIGN.md: ≤ 1 + FEASIBLE_TOL)."""
    return ratio <= 1.0 + FEASIBLE_TOL


def keeps_joints_and_feed(metrics: dict) -> bool:
    """``command_metrics(…, s)`` of a profile that keeps every joint limit and F_max at T."""
    return metrics["feasible"] and within(metrics["cartesian_peak_ratio"].get("feed", 0.0))


def windows_above(X: np.ndarray, T: float, limits: Limits, s=None, feed_max: float | None = None) -> list:
    """[(order, first sample of the window, ratio)] of every difference window of X at T that
    reads above its limit (ratio > 1 + FEASIBLE_TOL), by order (velocity, acceleration, jerk,
    then "feed": the arc lengths ``s`` against ``feed_max``) and sample: where a profile breaks
    a limit, for the planners that repair it there. A window starting in the rest before t = 0
    gives sample 0 (:func:`window_sample`)."""
    out = []
    for order, (w, _), L in zip(ORDERS, difference_peaks(X, T), (limits.v, limits.a, limits.j)):
        r = w / L
        out += [(order, int(window_sample(i, len(X))), float(r[i])) for i in np.nonzero(r > 1.0 + FEASIBLE_TOL)[0]]
    if s is not None:
        r = np.diff(np.asarray(s, float)) / T / feed_max
        out += [("feed", int(i), float(r[i])) for i in np.nonzero(r > 1.0 + FEASIBLE_TOL)[0]]
    return out


def worst_sample(X: np.ndarray, T: float, limits: Limits) -> tuple[str, int, float]:
    """(order, first sample index of its difference window, ratio) of the largest limit ratio
    of X at T: where a trajectory breaks its limits worst, for an error message (a window
    starting in the rest before t = 0 gives sample 0)."""
    lim = {"velocity": limits.v, "acceleration": limits.a, "jerk": limits.j}
    best = ("velocity", 0, 0.0)
    for order, D in differences(X, T).items():
        if len(D):
            r = np.abs(D).max(axis=1) / lim[order]
            i = int(np.argmax(r))
            if r[i] > best[2]:
                best = (order, int(window_sample(i, len(X))), float(r[i]))
    return best


def command_metrics(machine, P: np.ndarray, T: float, s: np.ndarray | None = None, limits=None) -> dict:
    """Metrics of a commanded Cartesian trajectory P (N, 3) sampled at T on ``machine``,
    against ``limits`` (kins.MachineLimits; None: the machine's own).

    ``s`` (arc length at each sample) adds the feed ratio against F_max.
    Raises kins.WorkspaceError if a point leaves the workspace.
    """
    limits = machine.limits if limits is None else limits
    Q = machine.ik(P)
    jpeak, jviol = limit_ratios(Q, T, limits.joint)
    cpeak, cviol = limit_ratios(P, T, limits.cartesian)
    out = {
        "execution_time_s": float((len(P) - 1) * T),
        "joint_peak_ratio": jpeak,
        "violation_time_s": jviol,
        "cartesian_peak_ratio": cpeak,
        "cartesian_violation_time_s": cviol,
        "feasible": bool(all(v <= 1.0 + FEASIBLE_TOL for v in jpeak.values())),
    }
    if s is not None:
        feed = np.diff(np.asarray(s, float)) / T
        out["cartesian_peak_ratio"]["feed"] = float(np.abs(feed).max() / limits.feed_max) if len(feed) else 0.0
    return out


def chord_error_mm(P: np.ndarray, path, s: np.ndarray) -> float:
    """Largest distance between the chord of two consecutive samples and the path between them.

    Measured at the chord midpoint against the path point at the mid arc length: for a
    circle of radius ρ and step Δs this is ρ(1 − cos(Δs/2ρ)) ≈ Δs²/8ρ, the quantity that
    the FLF's chord-error term caps at ε.
    """
    s = np.asarray(s, float)
    mid = 0.5 * (P[1:] + P[:-1])
    on_path = path.point(0.5 * (s[1:] + s[:-1]))
    return float(np.linalg.norm(mid - on_path, axis=1).max()) if len(mid) else 0.0


def stretch_need(Q: np.ndarray, s: np.ndarray, T: float, limits) -> np.ndarray:
    """Per sample, the time stretch λ ≥ its ratios that brings joint samples Q (N, 3) and the
    feed of arc lengths s back within ``limits`` at T: velocity and feed scale as 1/λ,
    acceleration as 1/λ², jerk as 1/λ³; a difference window counts at its last sample (a
    window ending in the rest after the end, at the last one)."""
    lim = limits.joint
    n = len(s)
    need = np.zeros(n)
    need[1:] = np.diff(s) / T / limits.feed_max
    for k, (o, x) in enumerate(differences(Q, T).items(), start=1):
        r = np.abs(x).max(axis=1) / {"velocity": lim.v, "acceleration": lim.a, "jerk": lim.j}[o]
        np.maximum.at(need, window_sample(np.arange(len(r)), n, k), r ** (1.0 / k))
    return need


def difference_peaks(X, T: float, orders: int = 3) -> list:
    """Per window, the largest |k-th difference at T| over the columns of X and the column of
    it (the first of equals, as np.argmax), for k = 1 … ``orders``: [(peaks, columns)] of the
    differences of :func:`differences` (with the rest at both ends: window i reads samples
    i-2 …, :func:`window_sample`), in blocks of samples (a 10⁶-sample profile's
    temporaries stay in cache instead of being fresh 10⁶-element arrays each)."""
    X = np.asarray(X, float)
    n_x = len(X)
    n_rest = n_x + 2 * REST_PAD if n_x else 0           # len(at_rest(X))
    sizes = [max(n_rest - k, 0) for k in range(1, orders + 1)]
    # the axis of each maximum as one byte (an axis number < 3): fresh memory is slow to
    # touch the first time, and 6 such arrays of 10⁶ samples were 80 MB as np.intp
    out = [(np.empty(n), np.empty(n, np.int8)) for n in sizes]
    for a in range(0, sizes[0], BLOCK):
        # rows a … of at_rest(X), read from X itself (no padded copy of a 10⁶-sample X): X's
        # rows a − REST_PAD …, the first and last repeated where the block reaches the rest
        lo, hi = a - REST_PAD, min(a + BLOCK + orders, n_rest) - REST_PAD
        rows = slice(lo, hi) if 0 <= lo and hi <= n_x else np.clip(np.arange(lo, hi), 0, n_x - 1)
        # one contiguous array per axis: numpy's reductions over the 3 columns of an (N, 3)
        # array run in inner loops of 3, several times slower than elementwise maxima
        D = [np.ascontiguousarray(X[rows, c]) for c in range(X.shape[1])]
        for (worst, col), n in zip(out, sizes):
            D = [np.diff(d) / T for d in D]
            b = min(a + BLOCK, n)
            if b > a:
                worst[a:b], col[a:b] = _abs_max([d[:b - a] for d in D])
    return out


def _abs_max(D):
    """(max |d| over the axes per sample, the axis of it: the first of equals, as np.argmax)
    of the per-axis arrays ``D``."""
    worst, col = np.abs(D[0]), np.zeros(len(D[0]), np.intp)
    for c, d in enumerate(D[1:], start=1):
        a = np.abs(d)
        col[a > worst] = c
        worst = np.maximum(worst, a)
    return worst, col
