"""The converged minimum time of every corpus path: the yardstick of the corpus (issue 32).

    PYTHONPATH=. nice -n 10 .venv/bin/python benchmarks/paths/corpus/reference.py [--paths GLOB] [--force]

Writes benchmarks/paths/corpus/reference.json: per path {"T_reference_s", "error_s", "grids":
[{"nodes", "T_s", "solve_s", "iterations"}, …], "order", "check_at_T"}. A path whose path file,
machine and settings are unchanged keeps its entry (its ``key``), so a rerun solves only what
changed; --force solves again.

This is data, not a planner, and it shares no code with the planners' solvers (topp3, copp,
toppra, nlp): only the constraint *definitions* of planners/constraints.py (the joint
derivatives q′, q″, q‴ of kins' IK along the path's exact derivatives, the feed cap with the
chord-error term, the jerk a G1 join's jump of q″ reads as at T) and the path's own geometry.

The problem (the planners' constraint set): per rest-to-rest piece (split at exact-stop
corners, ṡ = s̈ = 0 at its ends), minimise the time subject to |q′ṡ| ≤ V, |q″ṡ² + q′s̈| ≤ A,
|q‴ṡ³ + 3q″ṡs̈ + q′s⃛| ≤ J per joint, ṡ ≤ min(F_max, programmed F, chord-error cap) and, at a
G1 join, |jerk| + κṡ² ≤ J (κ = JUMP_READ_FACTOR·Δq″/T) on either side.

The transcription: over arc length, the path-parameter form of Verscheure et al. (IEEE TAC 54,
2009: b = ṡ², a = s̈, db/ds = 2a), with the jerk s⃛ = ṡ·da/ds as in Pham & Pham's TOPP-RA line of
work and Wang et al.'s COPP, written here as a nonlinear programme (CasADi + IPOPT) in
v = ṡ and a = s̈ at the nodes: a linear in s between nodes (da/ds = c constant on a cell), so
v²_{i+1} − v²_i = (a_i + a_{i+1})Δ exactly, the cell's time 2Δ/(v_i + v_{i+1}), every limit at
every node (the jerk with the c of the cell either side, and the one-sided derivatives of that
side). Nodes: at every segment join, NURBS knot and curvature peak, equidistributed between
them by a monitor that adds nodes per radian turned, graded towards the rest ends as s ∝ σ³
(there ṡ ∝ s^(2/3): in σ the profile is smooth, so the grids converge at their order). The
grids are nested (each halves every cell of the one before); the times of the last three give
the observed order p and the Richardson limit T* = T₃ + (T₃ − T₂)/(2^p − 1), and the error bar is
the larger of |T* − T₃| and the change of T* from the previous triple. The finest profile is
sampled at T and checked with planners.verify.command_metrics (``check_at_T``).
"""
from __future__ import annotations

import argparse
import fnmatch
import hashlib
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.interpolate import PchipInterpolator
from scipy.signal import peak_prominences

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent.parent
sys.path.insert(0, str(REPO))

from kins import load_machine  # noqa: E402
from planners.constraints import (JUMP_READ_FACTOR, PathTable, breakpoints, corner_list, feed_cap,  # noqa: E402
                                  join_jumps, joint_derivs, rest_pieces)
from planners.paths import resolve_path  # noqa: E402

OUT = HERE / "reference.json"
VERSION = 5                    # bump when the transcription changes: every cached entry is redone
# the grids: level 0 has about BASE_NODES nodes (the monitor's), each next one halves every cell
BASE_NODES = 600
LEVELS = 3
SLOW_FRACTION = 0.25           # a break whose speed cap is below this part of F_max is graded like a stop
TURN_RAD = 0.1                 # level 0: a node at least every 0.1 rad of turn
PEAK_PROMINENCE = 1e-9         # a curvature peak's prominence over κ below this is rounding
V_FLOOR = 1e-9                 # speeds ≥ this (units A²/J): the time's 1/v stays finite
SIDE = 1e-7                    # mm: one-sided derivatives either side of a join or knot
IPOPT = {"tol": 1e-10, "acceptable_tol": 1e-8, "max_iter": 1500, "max_cpu_time": 900.0, "print_level": 0,
         "mu_strategy": "adaptive", "linear_solver": "mumps", "bound_relax_factor": 0.0}

# a refinement starts at the coarse optimum: kept where it is (IPOPT's default pushes of 1e-2
# off the bounds and μ = 0.1 moved a near-stop's speed 10-fold; level 2 of a pocket_kossel
# piece took 274 s with them, 26 s without)
IPOPT_WARM = {"warm_start_init_point": "yes", "mu_init": 1e-6, "warm_start_bound_push": 1e-9,
              "warm_start_bound_frac": 1e-9, "warm_start_slack_bound_push": 1e-9,
              "warm_start_slack_bound_frac": 1e-9, "warm_start_mult_bound_push": 1e-9}

# --- the grid ---------------------------------------------------------------------------
def curvature_peaks(path, s0, s1, step=0.02):
    """Arc lengths of the strict local maxima of κ in (s0, s1) (sampled every ≤ step mm) that
    stand out of the rounding: an arc's or a helix's constant κ, evaluated, has a strict
    maximum every few samples (2357 on helix_kossel, each a break of ≥ 3 cells), with a
    prominence of 1e-16·κ; a NURBS lobe's is ≥ 4e-5·κ on the corpus."""
    n = int(min(400_000, max(64, math.ceil((s1 - s0) / step) + 1)))
    s = np.linspace(s0, s1, n)[1:-1]
    if len(s) < 3:
        return np.zeros(0)
    k = path.curvature(s)
    i = np.nonzero((k[1:-1] > k[:-2]) & (k[1:-1] > k[2:]) & (k[1:-1] > 1e-3))[0] + 1
    if len(i):
        i = i[peak_prominences(k, i)[0] > PEAK_PROMINENCE * k[i]]
    return s[i]


class Map:
    """The monotone map σ ∈ [0, n] → s of one rest piece: nodes at σ = k/2^level, ``breaks`` at
    integer σ. Monitor w(s) = 1/h + (κ + √|P‴|)/TURN_RAD, and around each of ``slow`` (the rest ends and
    the G1 joins and the points where the speed cap falls low) the grading (ℓ/d)^(2/3)/h within ℓ
    of it (ℓ at most half the way to the next): near a stop ṡ ∝ d^(2/3), which these nodes
    (d ∝ σ³) resolve as smoothly as the rest, and a join's read uses the one-sided da/ds of the
    cell next to it, which is then short."""

    def __init__(self, path, s0, s1, breaks, h, ell, slow=()):
        edges = np.concatenate([[s0], np.asarray(breaks, float), [s1]])
        centres = np.unique(np.concatenate([[s0, s1], np.asarray(slow, float)]))
        # each centre's zone: ℓ, at most half the way to the next centre
        gap = np.diff(centres)
        ells = np.minimum(ell, 0.5 * np.minimum(np.concatenate([[np.inf], gap]), np.concatenate([gap, [np.inf]])))

        def g(d, e):
            d = np.minimum(d, e)
            return (3 * e ** (2 / 3) * np.cbrt(d) - d) / h

        # G(x) = Σ sgn(x − c)·g(|x − c|): increasing, so the map stays monotone
        G = lambda x: sum(np.sign(x - c) * g(np.abs(x - c), e) for c, e in zip(centres, ells))
        cube = np.linspace(0, 1, 200) ** 3
        self.pieces = []                      # (σ at start, cells, s table, σ table)
        sig = 0
        for a, b in zip(edges[:-1], edges[1:]):
            m = int(min(4000, max(16, math.ceil((b - a) / (0.2 * h)))))
            near = [c + sg * e * cube for c, e in zip(centres, ells) if a - e <= c <= b + e for sg in (-1, 1)]
            x = np.unique(np.clip(np.concatenate([np.linspace(a, b, m)] + near), a, b))
            inner = np.clip(x, a + SIDE, b - SIDE) if b - a > 4 * SIDE else x
            # turn per node, and the length scale of the curvature's change (1/√|P‴|, as the
            # planners' tables use): a lobe whose curvature grows 80-fold in 1.6 mm gets its nodes
            _, _, P2, P3 = path.derivs(inner)
            w = 1.0 / h + (np.linalg.norm(P2, axis=1) + np.sqrt(np.linalg.norm(P3, axis=1))) / TURN_RAD
            M = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(x))])
            M = M + G(x) - G(a)
            n = max(3, int(math.ceil(M[-1] - 1e-9)))
            # s(σ) C¹ (monotone cubic): a linear in σ on a cell assumes a smooth map; table rows
            # closer than the rounding of M (a µm blend arc) are dropped
            keep = np.concatenate([[True], np.diff(M) > 1e-12 * M[-1]])
            keep[-1] = True
            keep[:-1] &= M[:-1] < M[-1]
            self.pieces.append((sig, n, x[keep], PchipInterpolator(M[keep] / M[-1] * n, x[keep])))
            sig += n
        self.cells = sig

    def nodes(self, level):
        """(s of the nodes, indices of the break nodes) at ``level`` (2^level cells per σ unit)."""
        k = 2 ** level
        out, brk = [], []
        for sig, n, x, f in self.pieces:
            t = np.arange(n * k) / k
            out.append(np.clip(f(t), x[0], x[-1]))
            brk.append(sum(len(o) for o in out[:-1]))
        out.append(np.array([self.pieces[-1][2][-1]]))
        return np.concatenate(out), np.array(brk[1:], int)


def slow_points(path, machine, limits, s, joins, frac=SLOW_FRACTION):
    """The points of ``s`` where the speed cap (feed cap with the chord-error term, the joints'
    velocity, √(A/|q″|), a join's √(J/κ)) is below ``frac`` of F_max."""
    if len(s) == 0:
        return np.zeros(0)
    T = machine.servo_period_s
    cart = path.derivs(s)
    q = joint_derivs(machine, path, s, cart=cart, fit_scale=True)
    kap = np.linalg.norm(np.cross(cart[1], cart[2]), axis=1)
    with np.errstate(divide="ignore"):
        cap = np.minimum.reduce([feed_cap(path, s, limits, T, kappa=kap),
                                 limits.joint.v / np.abs(q[1]).max(axis=1),
                                 np.sqrt(limits.joint.a / np.abs(q[2]).max(axis=1))])
    for sj, dq2 in joins:
        i = np.abs(s - sj) < 1e-6
        cap[i] = np.minimum(cap[i], np.sqrt(limits.joint.j * T / (JUMP_READ_FACTOR * max(np.max(dq2), 1e-300))))
    return s[cap < frac * limits.feed_max]


# --- one piece's NLP ----------------------------------------------------------------------
class PieceData:
    """The constraint data of a rest piece on a node grid, in scaled units (time t_u = A/J,
    speed A·t_u; then A = J = 1): per node the joint derivatives of the cell before (left) and
    after (right) it (they differ at joins and knots only), per cell those at its midpoint, the
    speed cap per node and, at a G1 join, its read κ."""

    def __init__(self, path, machine, limits, s, brk, joins, tu, s4):
        T = machine.servo_period_s
        self.s4 = np.column_stack([s4[k:-1:4] for k in range(4)] + [s4[4::4]])   # per cell: u = 0, ¼, ½, ¾, 1
        n = len(s)
        sl, sr = s.copy(), s.copy()
        sl[brk] -= SIDE
        sr[brk] += SIDE
        sr[0], sl[-1] = s[0] + 1e-9, s[-1] - 1e-9
        sl[0], sr[-1] = sr[0], sl[-1]
        vu = limits.joint.a * tu
        su = vu * tu          # the length unit: q′ keeps its value, q″ scales by su, q‴ by su²
        self.brk = np.asarray(brk, int)
        sb = sl[self.brk]
        # one-sided rows: every node from the right, the break nodes also from the left
        both = np.concatenate([sr, sb])
        cart = path.derivs(both)
        Q = joint_derivs(machine, path, both, cart=cart, fit_scale=True)
        Q = (Q[0], Q[1], Q[2] * su, Q[3] * su * su)
        self.right = tuple(q[:n] for q in Q[1:])
        self.left = tuple(q[n:] for q in Q[1:])
        kap = np.linalg.norm(np.cross(cart[1], cart[2]), axis=1)
        cap = feed_cap(path, both, limits, T, kappa=kap)
        cap_node = cap[:n].copy()
        cap_node[self.brk] = np.minimum(cap_node[self.brk], cap[n:])
        qv = np.abs(Q[1][:n]).max(axis=1)
        qv[self.brk] = np.maximum(qv[self.brk], np.abs(Q[1][n:]).max(axis=1))
        with np.errstate(divide="ignore", invalid="ignore"):
            self.vmax = np.minimum(cap_node, limits.joint.v / qv) / vu
        if not np.isfinite(self.vmax).all() and np.isnan(self.vmax).any():
            i = int(np.flatnonzero(np.isnan(self.vmax))[0])
            raise RuntimeError(f"s = {s[i]:.9g} mm: the joint derivatives there are not finite")
        m = joint_derivs(machine, path, self.s4[:, 2], fit_scale=True)
        self.mid = (m[1], m[2] * su, m[3] * su * su)
        self.kappa = {}                          # break node → the join's read κ per joint, scaled
        for sj, dq2 in joins:
            i = int(np.argmin(np.abs(s - sj)))
            if abs(s[i] - sj) < 1e-6:
                self.kappa[i] = JUMP_READ_FACTOR * np.asarray(dq2) * su / (T / tu)
        self.s, self.scale = s, (tu, vu)


def solve_piece(D: PieceData, warm=None):
    """(time in s, v, a, w, IPOPT iterations, status) of one piece's NLP (scaled v, a, w); ``warm``: (v, a) at its nodes."""
    import casadi as ca   # casadi only where a piece is solved (the cache answers the rest)

    tu, vu = D.scale
    su = vu * tu
    x = (D.s - D.s[0]) / su
    dx = np.diff(x)
    n = len(x)
    W = cell_weights((D.s4 - D.s[0]) / su)
    v, a, w = ca.SX.sym("v", n), ca.SX.sym("a", n), ca.SX.sym("w", n - 1)
    b = v * v
    c = (a[1:] - a[:-1]) / W["ds_mid"]        # da/ds at each cell's midpoint (a linear in σ)
    # The end cells (ṡ = 0 at one end): there the optimum starts (ends) at the jerk limit,
    # s ∝ t³, so they are that cubic: v² = 1.5|a|Δ at the inner node, time 3Δ/v, path jerk
    # |a|·v/(3Δ). The others: Simpson's rule on (ds/dσ)/ṡ over σ.
    inner = slice(1, n - 2)
    T = (ca.sum1((W["ds0"][inner] / v[1:-2] + 4 * W["ds_mid"][inner] / w[inner] + W["ds1"][inner] / v[2:-1]) / 6)
         + 3 * dx[0] / v[1] + 3 * dx[-1] / v[-2])
    g = [b[2:-1] - b[1:-2] - 2 * (a[1:-2] * W["w0"][inner] + a[2:-1] * W["w1"][inner]),
         ca.vertcat(b[1] - 1.5 * a[1] * dx[0], b[-2] + 1.5 * a[-2] * dx[-1])]
    lb, ub = [np.zeros(n - 3), np.zeros(2)], [np.zeros(n - 3), np.zeros(2)]
    jend = (a[1] * v[1] / (3 * dx[0]), -a[-2] * v[-2] / (3 * dx[-1]))

    def add(expr, lo, hi):
        g.append(expr)
        lb.append(np.full(expr.shape[0], lo))
        ub.append(np.full(expr.shape[0], hi))

    # acceleration at every node (from the right), and from the left at the break nodes
    d1, d2, _ = D.right
    for k in range(3):
        add(d2[1:-1, k] * b[1:-1] + d1[1:-1, k] * a[1:-1], -1.0, 1.0)
    bk = [int(i) for i in D.brk]
    if bk:
        e1, e2, _ = D.left
        for k in range(3):
            add(e2[:, k] * b[bk] + e1[:, k] * a[bk], -1.0, 1.0)
    # jerk at every cell's midpoint in σ, where b = v² follows from db/ds = 2a exactly for a
    # linear in σ; its speed w (w² = b there) is a variable of its own
    m1, m2, m3 = D.mid
    am = 0.5 * (a[1:] + a[:-1])
    add(w * w - b[:-1] - 2 * (a[:-1] * W["v0"] + a[1:] * W["v1"]), 0.0, 0.0)
    mid = slice(1, n - 2)
    for k in range(3):
        add(w[mid] * (m3[mid, k] * w[mid] * w[mid] + 3 * m2[mid, k] * am[mid] + m1[mid, k] * c[mid]), -1.0, 1.0)
        for cell, i, je in ((0, 1, jend[0]), (n - 2, n - 2, jend[1])):
            add(v[i] * (m3[cell, k] * b[i] + 3 * m2[cell, k] * a[i]) + m1[cell, k] * je, -1.0, 1.0)
    # a G1 join: |jerk| + κṡ² ≤ J either side, with that side's cell (TII 2022's read at T)
    for i, kap in D.kappa.items():
        j = bk.index(i) if i in bk else None
        for side, cell in (("left", i - 1), ("right", i)):
            if cell < 0 or cell >= n - 1 or (side == "left" and j is None):
                continue
            q1, q2, q3 = (x_[j] for x_ in D.left) if side == "left" else (x_[i] for x_ in D.right)
            for k in range(3):
                jerk = v[i] * (q3[k] * b[i] + 3 * q2[k] * a[i] + q1[k] * c[cell])
                add(ca.vertcat(jerk + kap[k] * b[i], -jerk + kap[k] * b[i]), -np.inf, 1.0)
    vmax = np.minimum(D.vmax, 1e6)
    # the time is Σ Δ/v: a speed at its bound 0 (IPOPT moves a bound its slack crowds by ~1e-8)
    # made it −∞ (pocket_kossel); the floor lies far below every optimum's (asserted below)
    lbx = np.concatenate([np.full(n, V_FLOOR), np.full(n, -np.inf), np.full(n - 1, V_FLOOR)])
    lbx[[2 * n, 3 * n - 2]] = 0.0              # the end cells' midpoints: not in the time
    ubx = np.concatenate([vmax, np.full(n, np.inf), np.full(n - 1, np.inf)])
    lbx[:n] = np.minimum(lbx[:n], vmax)
    for i in (0, n - 1):                       # rest: ṡ = s̈ = 0 at both ends
        lbx[i] = ubx[i] = 0.0
        lbx[n + i] = ubx[n + i] = 0.0
    if warm is None:
        v0 = initial_guess(D, x, vmax)
        a0 = np.gradient(0.5 * v0 ** 2, x)
        a0[[0, -1]] = 0.0
    else:
        v0, a0 = warm
    v0 = np.clip(v0, 0, vmax)
    # the midpoints' speeds as their equality constraint gives them
    w0 = np.sqrt(np.maximum(v0[:-1] ** 2 + 2 * (a0[:-1] * W["v0"] + a0[1:] * W["v1"]), 0.0))
    x0 = np.clip(np.concatenate([v0, a0, w0]), lbx, ubx)   # a 0 where Δ/ṡ is summed: grad_f Inf
    nlp = {"x": ca.vertcat(v, a, w), "f": T, "g": ca.vertcat(*g)}
    opts = IPOPT if warm is None else {**IPOPT, **IPOPT_WARM}
    solver = ca.nlpsol("reference", "ipopt", nlp, {"ipopt": opts, "print_time": False})
    res = solver(x0=x0, lbx=lbx, ubx=ubx, lbg=np.concatenate(lb), ubg=np.concatenate(ub))
    st = solver.stats()
    sol = np.asarray(res["x"]).ravel()
    return (float(res["f"]) * tu, sol[:n], sol[n:2 * n], sol[2 * n:], int(st.get("iter_count", -1)),
            st["return_status"])


def cell_weights(X):
    """Per cell, from s at σ-fractions u = 0, ¼, ½, ¾, 1 (X, (cells, 5)), the weights of a(σ)
    linear in u: ∫₀¹ (1 − u, u)·s′ du (w0, w1; by parts, ∫ u s′ = s(1) − ∫ s, Boole's rule),
    the same over [0, ½] (v0, v1; Simpson), and s′ at u = 0, ½, 1 (ds0, ds_mid, ds1)."""
    s0, q1, sm, q3, s1 = X.T
    I = (7 * s0 + 32 * q1 + 12 * sm + 32 * q3 + 7 * s1) / 90
    Ih = (s0 + 4 * q1 + sm) / 12
    w1 = s1 - I
    v1 = 0.5 * sm - Ih
    return {"w0": (s1 - s0) - w1, "w1": w1, "v0": (sm - s0) - v1, "v1": v1,
            "ds0": 2 * (-3 * s0 + 4 * q1 - sm), "ds_mid": 2 * (q3 - q1), "ds1": 2 * (3 * s1 - 4 * q3 + sm)}


def node_times(D, v, w):
    """Node times (s) of a solution (v, w in m/s scale units) by the NLP's own rules."""
    tu, vu = D.scale
    W = cell_weights(D.s4)
    with np.errstate(divide="ignore", invalid="ignore"):
        dt = (W["ds0"] / v[:-1] + 4 * W["ds_mid"] / w + W["ds1"] / v[1:]) / 6
    ds = np.diff(D.s)
    dt[0], dt[-1] = 3 * ds[0] / v[1], 3 * ds[-1] / v[-2]
    return np.concatenate([[0.0], np.cumsum(dt)])


def initial_guess(D, x, vmax, share=0.5):
    """A start for IPOPT built from the limits (scaled, A = J = 1): per node the speed that
    spends ``share`` of a joint's acceleration on q″ṡ² alone, of its jerk on q‴ṡ³ alone (at
    the node and at the cells' midpoints) and of a join's read on κṡ², under vmax; then the
    forward and backward passes of a path acceleration ``share``/|q′| (the rest ends left along
    the jerk-limited ṡ^(3/2) ∝ s). Not feasible at the passes' switches, but within a small
    factor of it: the slow start it replaced put 0.2·F_max through a µm blend arc, and IPOPT spent
    its iterations (221 on a pocket_kossel piece, restorations, 10¹⁰ regularisation) getting out."""
    q1, q2, q3 = (np.abs(q).max(axis=1) for q in D.right)
    m3 = np.abs(D.mid[2]).max(axis=1)
    with np.errstate(divide="ignore"):
        cap = np.minimum.reduce([vmax, np.sqrt(share / q2), np.cbrt(share / q3),
                                 np.cbrt(share / np.concatenate([m3, [0.0]])),
                                 np.cbrt(share / np.concatenate([[0.0], m3]))])
        for i, kap in D.kappa.items():
            cap[i] = min(cap[i], math.sqrt(share / np.abs(kap).max()))
        acc = share / q1
    v = cap.copy()
    v[0] = v[-1] = 0.0
    dx = np.diff(x)
    for order in (range(1, len(x)), range(len(x) - 2, -1, -1)):
        for i in order:
            j = i - 1 if order.step == 1 else i + 1
            d = dx[min(i, j)]
            v[i] = min(v[i], math.sqrt(v[j] ** 2 + 2 * acc[j] * d),
                       (v[j] ** 1.5 + 2.12 * math.sqrt(acc[j]) * d) ** (2 / 3))
    return v


def refine_warm(s, v, a, w, s_fine):
    """The coarse solution (nodes s, speeds v, w at the cells' σ-midpoints) on the nested grid
    twice as fine, as the coarse NLP's own profile: a new node is a coarse cell's σ-midpoint,
    where ṡ is that cell's w and s̈ the mean (s̈ linear in σ); in the two end cells ṡ ∝ d^(2/3),
    s̈ ∝ d^(1/3) from the rest (the averages it replaced started a refinement 347 off feasible
    at a near-stop and IPOPT took 180 iterations, 1.8 s each, to recover)."""
    vf, af = np.empty(len(s_fine)), np.empty(len(s_fine))
    vf[0::2], af[0::2] = v, a
    vf[1::2], af[1::2] = w, 0.5 * (a[1:] + a[:-1])
    for i, j, e in ((1, 1, 0), (-2, -2, -1)):
        r = abs(s_fine[i] - s_fine[e]) / abs(s[j] - s[e])
        vf[i], af[i] = v[j] * r ** (2 / 3), a[j] * np.cbrt(r)
    return vf, af


# --- a path -------------------------------------------------------------------------------
def richardson(T):
    """(T*, error, order p) from the times of nested grids (each halving the cells): per triple
    the observed order p = log2(d1/d2) and T* = T₃ + d₂/(2^p − 1); the bar is the larger of the
    last correction |T* − T₃| and the change of T* from the triple before. A triple whose
    differences change sign or shrink by less than √2 (p < ½: no asymptotic range yet) has no
    order (p NaN): T* = T₃ with the bar max(|d₁|, |d₂|)."""
    if len(T) < 3:
        return T[-1], abs(T[-1] - T[-2]) if len(T) > 1 else math.inf, math.nan
    est = []
    for t0, t1, t2 in zip(T[:-2], T[1:-1], T[2:]):
        d1, d2 = t1 - t0, t2 - t1
        if d1 * d2 > 0 and abs(d1) > 2 ** 0.5 * abs(d2):
            p = min(math.log2(d1 / d2), 4.0)
            est.append((t2 + d2 / (2 ** p - 1), p, abs(d2 / (2 ** p - 1))))
        else:
            est.append((t2, math.nan, max(abs(d1), abs(d2))))
    Ts, p, err = est[-1]
    if len(est) > 1:
        err = max(err, abs(Ts - est[-2][0]))
    return Ts, err, p


def reference(path, machine, levels=LEVELS, base_nodes=BASE_NODES, log=None):
    """The refinement study of one path: {"grids": [...], "T_reference_s", "error_s", "order",
    "check_at_T"}."""
    limits = machine.limits
    J = limits.joint
    tu = J.a / J.j
    table = PathTable(path, machine)
    joins = join_jumps(path, table, machine)
    brk_all = sorted(set(breakpoints(path)) | {sj for sj, _ in joins})
    knots = []
    U = getattr(path, "knots", None)
    if U is not None and hasattr(path, "s_of_u"):
        knots = list(np.asarray(path.s_of_u(np.unique(np.asarray(U, float))[1:-1]), float))
    pieces = rest_pieces(path)
    h = path.length / base_nodes
    # the rest ends' graded zone: the distance the jerk-limited start covers to reach ~F_max
    ell = (limits.feed_max ** 1.5) / math.sqrt(J.j) * 2
    maps = []
    for s0, s1 in pieces:
        br = [b for b in brk_all + knots if s0 + 1e-6 < b < s1 - 1e-6]
        br += list(curvature_peaks(path, s0, s1))
        br = np.unique(np.round(np.array(br, float), 12))
        if len(br):
            keep = np.concatenate([[True], np.diff(br) > 1e-6])
            br = br[keep]
            br = br[(br > s0 + 1e-6) & (br < s1 - 1e-6)]
        slow = np.concatenate([slow_points(path, machine, limits, br, joins),
                               [sj for sj, _ in joins if s0 < sj < s1]])
        maps.append(Map(path, s0, s1, br, h, ell, slow))
    grids, warm, prof = [], [None] * len(maps), None
    for level in range(levels):
        t0 = time.process_time()
        total, iters, nodes, prof = 0.0, 0, 0, []
        for k, ((s0, s1), mp) in enumerate(zip(pieces, maps)):
            s, brk = mp.nodes(level)
            D = PieceData(path, machine, limits, s, brk, joins, tu, mp.nodes(level + 2)[0])
            w = None if warm[k] is None else refine_warm(*warm[k], s)
            Tk, v, a, wm, it, status = solve_piece(D, w)
            if status not in ("Solve_Succeeded", "Solved_To_Acceptable_Level"):
                raise RuntimeError(f"piece {k} (s = {s0:.6g}…{s1:.6g}) level {level}: IPOPT {status}")
            if v[1:-1].min() < 2 * V_FLOOR:
                raise RuntimeError(f"piece {k} (s = {s0:.6g}…{s1:.6g}) level {level}: a speed at its floor")
            warm[k] = (s, v, a, wm)
            total += Tk
            iters += it
            nodes += len(s)
            V, Wm = v * D.scale[1], wm * D.scale[1]
            prof.append((s, V, a * D.scale[1] / D.scale[0], node_times(D, V, Wm)))
        g = {"nodes": nodes, "T_s": total, "solve_s": round(time.process_time() - t0, 2), "iterations": iters}
        grids.append(g)
        if log:
            log(f"  level {level}: {nodes} nodes T = {total:.9f} s ({g['solve_s']} s CPU, {iters} it)")
    Ts, err, p = richardson([g["T_s"] for g in grids])
    return {"T_reference_s": Ts, "error_s": err, "order": None if math.isnan(p) else p, "grids": grids,
            "check_at_T": check_at_T(path, machine, prof)}


def sample_profile(prof, T):
    """Arc lengths at t = kT of the piecewise profile [(s, ṡ, s̈, node times) per piece]:
    quintic Hermite in t between nodes (s, ṡ, s̈ at both ends)."""
    S, V, A, tt = [], [], [], []
    t_off = 0.0
    for s, v, a, tn in prof:
        t = t_off + tn
        S.append(s), V.append(v), A.append(a), tt.append(t)
        t_off = t[-1]
    S, V, A, t = (np.concatenate(x) for x in (S, V, A, tt))
    keep = np.concatenate([[True], np.diff(t) > 0])
    S, V, A, t = S[keep], V[keep], A[keep], t[keep]
    tq = np.arange(int(math.ceil(t[-1] / T)) + 1) * T
    tq[-1] = min(tq[-1], t[-1])
    i = np.clip(np.searchsorted(t, tq, side="right") - 1, 0, len(t) - 2)
    h = t[i + 1] - t[i]
    u = np.clip((tq - t[i]) / h, 0, 1)
    u2, u3, u4, u5 = u ** 2, u ** 3, u ** 4, u ** 5
    h0 = 1 - 10 * u3 + 15 * u4 - 6 * u5
    h1 = u - 6 * u3 + 8 * u4 - 3 * u5
    h2 = 0.5 * (u2 - 3 * u3 + 3 * u4 - u5)
    h3 = 10 * u3 - 15 * u4 + 6 * u5
    h4 = -4 * u3 + 7 * u4 - 3 * u5
    h5 = 0.5 * (u3 - 2 * u4 + u5)
    s = (h0 * S[i] + h1 * h * V[i] + h2 * h * h * A[i] + h3 * S[i + 1] + h4 * h * V[i + 1]
         + h5 * h * h * A[i + 1])
    return np.maximum.accumulate(np.clip(s, S[0], S[-1]))


def check_at_T(path, machine, prof):
    """The finest grid's profile sampled at T, checked by planners.verify.command_metrics:
    {"execution_time_s", "joint_peak_ratio" {v, a, j}, "feasible"}."""
    from planners.verify import command_metrics
    T = machine.servo_period_s
    s = sample_profile(prof, T)
    m = command_metrics(machine, path.point(s), T, s)
    r = m["joint_peak_ratio"]
    return {"execution_time_s": m["execution_time_s"],
            "joint_peak_ratio": {k: round(float(r[k]), 6) for k in ("velocity", "acceleration", "jerk")},
            "feed_ratio": round(float(m["cartesian_peak_ratio"]["feed"]), 6), "feasible": m["feasible"]}


# --- the corpus ---------------------------------------------------------------------------
def entry_key(entry) -> str:
    """What a cached reference depends on: the path file's bytes, the machine, the settings."""
    h = hashlib.sha256((HERE / entry["file"]).read_bytes())
    h.update(json.dumps([entry["machine"], VERSION, BASE_NODES, LEVELS, TURN_RAD]).encode())
    return h.hexdigest()[:16]


def load(file=OUT) -> dict:
    try:
        return json.loads(Path(file).read_text())
    except (OSError, json.JSONDecodeError):
        return {"paths": {}}


def write(data, file=OUT):
    Path(file).write_text(json.dumps(data, indent=1, ensure_ascii=False) + "\n")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--paths", default="*", help="comma-separated globs of corpus path names")
    ap.add_argument("--force", action="store_true", help="solve again even where the cache is current")
    ap.add_argument("--out", default=str(OUT))
    args = ap.parse_args(argv)
    entries = json.loads((HERE / "manifest.json").read_text())["paths"]
    pats = [p.strip() for p in args.paths.split(",") if p.strip()]
    todo = [e for e in entries if any(fnmatch.fnmatch(e["name"], p) for p in pats)]
    if not todo:
        print(f"reference.py: --paths {args.paths} matches no corpus path", file=sys.stderr)
        return 2
    data = load(args.out)
    data.setdefault("paths", {})
    data["method"] = ("path-parameter NLP (v = ṡ, a = s̈ at nodes; CasADi + IPOPT) on nested grids, "
                      "Richardson limit of the last three; see benchmarks/paths/corpus/reference.py")
    machines = {}
    for e in todo:
        key = entry_key(e)
        old = data["paths"].get(e["name"])
        if old and old.get("key") == key and not args.force:
            # the extrapolation is arithmetic on the stored study: redone, never stale
            Ts, err, p = richardson([g["T_s"] for g in old["grids"]])
            old.update(T_reference_s=Ts, error_s=err, order=None if math.isnan(p) else p)
            print(f"{e['name']}: cached T_ref = {Ts:.6f} ± {err:.2g} s")
            continue
        m = machines.get(e["machine"]) or machines.setdefault(e["machine"], load_machine(e["machine"]))
        path = resolve_path(str(HERE / e["file"]), home=m.home)
        print(f"{e['name']} ({e['machine']}):", flush=True)
        t0 = time.process_time()
        try:
            r = reference(path, m, log=lambda s: print(s, flush=True))
        except RuntimeError as err:
            print(f"{e['name']}: {err}", file=sys.stderr)
            continue
        r = {"key": key, "T_reference_s": r["T_reference_s"], "error_s": r["error_s"], **r,
             "cpu_s": round(time.process_time() - t0, 1)}
        data["paths"][e["name"]] = r
        data["paths"] = dict(sorted(data["paths"].items()))
        write(data, args.out)
        c = r["check_at_T"]
        print(f"{e['name']}: T_ref = {r['T_reference_s']:.6f} ± {r['error_s']:.2g} s (order {r['order']}); "
              f"finest at T: {c['execution_time_s']:.6f} s, joint v/a/j {c['joint_peak_ratio']} "
              f"({r['cpu_s']} s CPU)", flush=True)
    data["paths"] = dict(sorted(data["paths"].items()))
    write(data, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
