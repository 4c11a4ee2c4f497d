"""The swarm's start: the seed profile (`scurve_joint` by default) read on each rest-to-rest
piece, the problems of each piece (whole, and cut at its G1 joins) with the seed fitted on them."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import tuning
from .join import join_feed
from .problem import PieceProblem, SubPiece
from .result import SplinePiece
from .tuning import JOIN_FEED_FRACTION, MAX_JOINS_CUT, MIN_KNOT_GAP_T, SUBPIECE_CONTROL_POINTS, SUBPIECE_SAMPLES


def seed_window(prof, s0, s1):
    """(τ, ṡ, s⃛, duration, switch τ) of a profile on piece [s0, s1], τ normalised to [0, 1].

    The piece starts and ends at rest between two samples; with the seed's jerk switch times
    (scurve's info) its ends are exact, else the sample just outside is taken."""
    t = prof.t
    idx = np.nonzero((prof.s >= s0 - 1e-9) & (prof.s <= s1 + 1e-9))[0]
    i0, i1 = max(idx[0] - 1, 0), min(idx[-1] + 1, len(t) - 1)
    t0, t1 = t[i0], t[i1]
    sw = np.asarray(prof.info.get("jerk_switch_times_s", []), float)
    rest = np.asarray(prof.info.get("rest_times_s", []), float)
    if len(sw) and len(rest):
        # the rest moments (path start, corners, end) nearest to where s crosses s0 and s1
        t0 = rest[np.argmin(np.abs(rest - np.interp(s0, prof.s, t)))]
        t1 = rest[np.argmin(np.abs(rest - np.interp(s1, prof.s, t)))]
    else:
        sw = np.zeros(0)
    D = t1 - t0
    inside = (t >= t0) & (t <= t1)
    tau = np.concatenate([[0.0], (t[inside] - t0) / D, [1.0]])
    vv = np.concatenate([[0.0], prof.sd[inside], [0.0]])
    jj = np.concatenate([[0.0], prof.sddd[inside], [0.0]])
    knots = None
    if len(sw):
        # switch times closer than ~2 servo periods (a jerk phase the s-curve's bisection left
        # almost empty) become one knot: a knot span holding no seed sample leaves the
        # least-squares fit undetermined there, and its jerk exploded (×2000 on bird)
        kept = []
        for ts in sw[(sw > t0 + 1e-9) & (sw < t1 - 1e-9)]:
            if not kept or ts - kept[-1] >= MIN_KNOT_GAP_T * prof.T:
                kept.append(ts)
        knots = (np.array(kept) - t0) / D
    return tau, vv, jj, D, knots


def knot_density(tau, jerk):
    """Half the knots uniform in time, half where the seed's jerk is busy (its transitions:
    the feed dips at the FLF minima and G1 joins need the resolution)."""
    aj = np.abs(jerk)
    w = np.convolve(aj, np.ones(9) / 9, mode="same")
    area = np.trapezoid(w, tau)          # numpy ≥ 2 (constraints.txt pins 2.4)
    return tau, 1.0 + (w / area if area > 0 else 0.0)


@dataclass
class Setting:
    """What every problem of one plan shares."""
    table: object          # constraints.PathTable
    limits: object
    T: float
    joins: list            # constraints.join_jumps: [(s, Δq″)]
    cap: np.ndarray        # the feed cap on table.s
    margin: float


@dataclass
class Start:
    """The problems to search, the seed fitted on each (X0), and what each searches: (rest-to-rest
    piece, "whole" | "cut").  seed_pieces: the seed's fit per piece (None unless every piece has
    the seed's switch times); fallback: the pieces over the size bound."""
    probs: list
    X0: list
    tags: list
    seed_pieces: list | None
    fallback: list


def start(st: Setting, seed_prof, pcs, control_points, samples, exact_knots, extra_knots) -> Start:
    """Each piece is searched whole (one time stretch, knots at the seed's switches) and, if it
    has G1 joins, also cut at them (`SubPiece`); plan() keeps the faster of the two per piece."""
    # control points in proportion to the seed's time on each piece
    tp = np.array([max(np.count_nonzero((seed_prof.s > a) & (seed_prof.s < b)), 1) for a, b in pcs], float)
    Ks = np.maximum(8, np.round(control_points * tp / tp.sum()).astype(int))
    out = Start([], [], [], [], [])
    for g, ((s0, s1), K) in enumerate(zip(pcs, Ks)):
        pr, x0, seed_piece = _whole(st, seed_prof, g, s0, s1, K, samples, exact_knots, extra_knots,
                                    out.fallback)
        out.probs.append(pr)
        out.X0.append(x0)
        out.tags.append((g, "whole"))
        if out.seed_pieces is not None and seed_piece is not None:
            out.seed_pieces.append(seed_piece)
        else:
            out.seed_pieces = None               # not every piece has the seed's switch times
        for pr, x0 in _cut(st, seed_prof, s0, s1):
            out.probs.append(pr)
            out.X0.append(x0)
            out.tags.append((g, "cut"))
    return out


def _whole(st, seed_prof, g, s0, s1, K, samples, exact_knots, extra_knots, fallback):
    """(problem, the seed's fit on it, that fit as a SplinePiece or None) of piece g, searched
    whole; a piece over the size bound is added to ``fallback``."""
    tau, vv, jj, D, knots = seed_window(seed_prof, s0, s1)
    # with the seed's jerk switch times as knots a quadratic B-spline holds the s-curve exactly:
    # the swarm starts from the seed itself.  Samples at least every 8 servo periods of the
    # seed's time on the piece (a 17 s piece of kossel's test_part would get one per 42 ms,
    # coarser than its feed dips)
    M = max(samples, int(math.ceil(D / (8 * st.T))))
    exact = knots is not None and exact_knots
    over = exact and (M + 2 * len(knots) + len(tau)) * (len(knots) + K) > tuning.BASIS_MAX_ELEMENTS
    pr = PieceProblem(st.table, s0, s1, st.limits, st.T, st.joins, int(K * extra_knots) if exact else int(K), M,
                      st.table.s, st.cap, knot_density(tau, jj), inner=knots if exact else None,
                      sparse=over)
    if over:
        fallback.append({"piece": g, "s_mm": [round(float(s0), 6), round(float(s1), 6)],
                         "seed_knots": len(knots), "control_points": int(pr.shape.K),
                         "samples": int(len(pr.shape.tau)), "polish": "skipped"})
    x0 = pr.shape.fit(tau, vv)
    if not exact:
        return pr, x0, None
    return pr, x0, SplinePiece(D, pr.shape.full(x0[None, :])[0], pr.shape.knots, pr.shape.degree,
                               s0, s1 - s0, g)


def _cut(st, seed_prof, s0, s1):
    """[(sub-piece, the seed's fit on it)] of the piece cut at its G1 joins: none if it has no
    join or more than MAX_JOINS_CUT."""
    inside = [(sj, d) for sj, d in st.joins if s0 + 1e-6 < sj < s1 - 1e-6]
    if not inside or len(inside) > MAX_JOINS_CUT:
        return []
    bnd = [s0] + [sj for sj, _ in inside] + [s1]
    vs = [0.0] + [JOIN_FEED_FRACTION * join_feed(st.table, sj, d, st.limits, st.margin, st.T, st.cap)
                  for sj, d in inside] + [0.0]
    out = []
    for k in range(len(bnd) - 1):
        ends = []
        if k > 0:
            e = st.table.joints(np.array([bnd[k] + 1e-9]))
            ends.append((0, inside[k - 1][1], e[0][0], e[1][0], e[2][0]))
        if k < len(bnd) - 2:
            e = st.table.joints(np.array([bnd[k + 1] - 1e-9]))
            ends.append((-1, inside[k][1], e[0][0], e[1][0], e[2][0]))
        tk = np.interp([bnd[k], bnd[k + 1]], seed_prof.s, seed_prof.t)
        M = max(SUBPIECE_SAMPLES, int(math.ceil((tk[1] - tk[0]) / (8 * st.T))))
        pr = SubPiece(st.table, bnd[k], bnd[k + 1], vs[k], vs[k + 1], ends, st.limits, st.T,
                      SUBPIECE_CONTROL_POINTS, M, st.table.s, st.cap)
        out.append((pr, pr.fit(seed_prof)))
    return out
