"""The converged minimum time of every corpus path: the yardstick of the corpus (issue 32).

    PYTHONPATH=. nice -n 10 .venv/bin/python benchmarks/paths/corpus/reference.py [--paths GLOB] [--force]

Writes benchmarks/paths/corpus/reference.json: per path {"T_reference_s", "error_s", "grids":
[{"nodes", "T_s", "solve_s", "iterations"}, …], "order", "check_at_T"}. A path whose path file,
machine and settings are unchanged keeps its entry (its ``key``), so a rerun solves only what
changed; --force solves again. A study writes its state before every solve to
reference.checkpoints/<path>.pkl (--checkpoints) and, stopped, goes on from there when run again
with the same key (--restart: afresh): the CAM programs' studies take longer than a session.

This is data, not a planner, and it shares no code with the planners' solvers (topp3, copp,
toppra, nlp): only the constraint *definitions* of planners/constraints.py (the joint
derivatives q′, q″, q‴ of kins' IK along the path's exact derivatives, the feed cap with the
chord-error term, the jerk a G1 join's jump of q″ reads as at T) and the path's own geometry.

The problem (the planners' constraint set): per rest-to-rest piece (split at exact-stop
corners, ṡ = s̈ = 0 at its ends), minimise the time subject to |q′ṡ| ≤ V, |q″ṡ² + q′s̈| ≤ A,
|q‴ṡ³ + 3q″ṡs̈ + q′s⃛| ≤ J per joint, ṡ ≤ min(F_max, programmed F, chord-error cap) and, at a
G1 join and at a NURBS knot where q″ jumps (knot_jumps), the jump read at T: every third
difference whose window holds the join reads the joint jerk averaged by its kernel (the quadratic
B-spline over 3 periods) plus the jump κṡ² weighted by where it falls in the window (κ =
JUMP_READ_FACTOR·Δq″/T, Δq″ signed from the left side to the right). The rows hold that read
within J for the windows centred δ periods from the join, δ = −1.4375 … 1.4375 by 1/16 (KERNEL_PHASES):
whatever the samples' phase, to the read's change over 1/32 period, the kernel's weights evaluated
at the last solve's times and solved again until they stop moving (VERSION 12, add_kernel_reads;
VERSION 11 held the same rows with the times as unknowns of the weights, by ⅛;
VERSION 7–10 held |jerk + w·κṡ²| ≤ J pointwise at every node within 3 periods, w = 1 within 1.5:
sufficient, but a window reads the jerk's average, and those rows held it off J at every point
of it: they lay up to 1.2 % above `optimal`'s feasible profiles on the joins' paths; VERSION 6 held
the join's node alone and its profiles read up to 1.99 × J at T).

The transcription: per rest piece, nodes fixed along the arc length and s(t) a cubic on every
cell between two of them (a constant path jerk s⃛ over the cell's own duration Δt): at the
nodes ṡ, s̈, per cell Δt and s⃛, tied by the cubic's exact relations s̈₁ = s̈₀ + s⃛Δt,
ṡ₁ = ṡ₀ + (s̈₀ + s̈₁)Δt/2, Δs = ṡ₀Δt + (2s̈₀ + s̈₁)Δt²/6; minimise ΣΔt (CasADi + IPOPT). Every
limit at every node, the jerk at both ends of each cell (with that side's one-sided
derivatives), ṡ ≥ 0 at each cell's half time. The time-domain form of a jerk-limited profile
(piecewise-cubic s(t) between fixed path points, as in the time-optimal spline literature);
it has no quadrature of 1/ṡ, so a slow node costs exactly the time its cells take (the
path-parameter form before it, VERSION 5, weighted 1/ṡ by a five-point ds/dσ that went ≤ 0 at
σ³-graded nodes: meander_keops's objective came out negative). Nodes: at every segment join,
NURBS knot and curvature peak, equidistributed between them by a monitor that adds nodes per
radian turned, graded towards the rest ends and slow points as s ∝ σ³ (each side of a point
its own zone: VERSION 8). The grids are nested
(each halves every cell of the one before; LEVELS of them, a fourth where their bar is wide and
it stays small: WIDE_BAR); the times of the last three give the observed
order p and the Richardson limit T* = T₃ + (T₃ − T₂)/(2^p − 1), and the error bar is the
larger of |T* − T₃| and the change of T* from the previous triple. The finest profile is
sampled at T and checked with planners.verify.command_metrics (``check_at_T``).
"""
from __future__ import annotations

import argparse
import fnmatch
import hashlib
import json
import math
import os
import pickle
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.interpolate import PchipInterpolator
from scipy.signal import peak_prominences

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent.parent
sys.path.insert(0, str(REPO))

from kins import load_machine  # noqa: E402
from planners.constraints import (JUMP_READ_FACTOR, READ_REACH, PathTable, breakpoints, feed_cap,  # noqa: E402
                                  interior_knots, join_jumps, joint_derivs, rest_pieces)
from planners.paths import resolve_path  # noqa: E402

OUT = HERE / "reference.json"
# bump when the transcription or its inputs change: every cached entry is redone (VERSION 11: a
# join's reads are the third differences' kernel averages, not a pointwise envelope; VERSION 12:
# their weights fixed at the last solve's times and iterated, the phases by 1/16)
VERSION = 12
# the grids: level 0 has about BASE_NODES nodes (the monitor's), each next one halves every cell
BASE_NODES = 600
LEVELS = 3
# ... and one more while the bar is above WIDE_BAR of T* and the next grid has ≤ WIDE_NODES nodes:
# three grids can stop short of the asymptotic range (an observed order well below 1, the bar
# wide: corpus README, forty-fifth session), and a CAM program's fourth grid would take hours
WIDE_BAR = 2e-3
WIDE_NODES = 25_000
SLOW_FRACTION = 0.25           # a break whose speed cap is below this part of F_max is graded like a stop
TURN_RAD = 0.1                 # level 0: a node at least every 0.1 rad of turn
PEAK_PROMINENCE = 1e-9         # a curvature peak's prominence over κ below this is rounding
MERGE_MM = 1e-6               # breaks and grading centres closer than this are one point
SIDE = 1e-7                    # mm: one-sided derivatives either side of a join or knot
CONTINUOUS = 1e3               # a knot's Δq″ below this many times q‴'s 2·SIDE is a steep q″, no jump
# a join's read is imposed at the nodes within 2·READ_REACH periods of it at the start's node
# times widened by READ_SLACK; a solution with a node closer outside that set is solved again with it
READ_SLACK = 1.2
# a join's reads are held for the windows centred these many periods from it, by KERNEL_STEP
# (by ½ the G64 head of tests/test_reference.py read 1.023 × J a quarter period off, by ¼
# contour_keops 1.011 × J at T, by ⅛ with VERSION 12's weights 1.0069: the read bulges between two
# held phases), each cell's share of a window's average by a composite trapezoid whose intervals
# are at most KERNEL_H periods at the weights' durations (its error on the head: 0.003 × J)
KERNEL_STEP = 0.0625
KERNEL_PHASES = np.arange(-1.5 + KERNEL_STEP, 1.5 - 1e-9, KERNEL_STEP)
KERNEL_H = 0.2
# the kernel's weights are evaluated at the start's times: solved again until no node's time moves
# by FIX_TOL periods (cam_blend_kossel's level 0: 11 solves, each move ~0.3 × the last), the
# weights' times relaxed by a step in [FIX_STEP_MIN, 1]
FIX_TOL = 1e-4
FIX_ROUNDS = 40
FIX_STEP_MIN = 1 / 16
# max_cpu_time and max_iter stop a solve that runs away, never shorten one that converges (a stop
# is an error of the path; the largest CAM grids need up to ~1700 s: corpus README; VERSION 8's
# cold level 0 of cam_dense_lcnc ran out of 1500 iterations)
IPOPT = {"tol": 1e-10, "acceptable_tol": 1e-8, "max_iter": 4000, "max_cpu_time": 3600.0, "print_level": 0,
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
    of it (ℓ on each side at most half the way to the next): near a stop ṡ ∝ d^(2/3), which these nodes
    (d ∝ σ³) resolve as smoothly as the rest, and a join's read uses the one-sided da/ds of the
    cell next to it, which is then short."""

    def __init__(self, path, s0, s1, breaks, h, ell, slow=()):
        edges = np.concatenate([[s0], np.asarray(breaks, float), [s1]])
        centres = np.unique(np.concatenate([[s0, s1], np.asarray(slow, float)]))
        # one centre per point: a join listed again from its rounded break (1e-13 mm off) had a
        # zone of half that gap, so no grading (VERSION 7: meander_keops's joins had none)
        centres = centres[np.concatenate([[True], np.diff(centres) > MERGE_MM])]
        # each centre's zone on either side: ℓ, at most half the way to the next centre on that
        # side (one zone for both sides took the nearer: a curvature peak 0.14 mm into a U-turn
        # left the 50 mm braking on the leg before it ungraded, its last cell 0.5 mm long)
        half = 0.5 * np.diff(centres)
        left = np.minimum(ell, np.concatenate([[0.0], half]))
        right = np.minimum(ell, np.concatenate([half, [0.0]]))

        def g(d, e):
            d = np.minimum(d, e)
            return (3 * e ** (2 / 3) * np.cbrt(d) - d) / h

        # G(x) = Σ ±g(|x − c|) (+ right of c, − left of it): increasing, so the map stays monotone
        G = lambda x: sum(np.where(x >= c, g(np.maximum(x - c, 0.0), r), -g(np.maximum(c - x, 0.0), le))
                          for c, le, r in zip(centres, left, right))
        cube = np.linspace(0, 1, 200) ** 3
        self.pieces = []                      # (σ at start, cells, s table, σ table)
        sig = 0
        for a, b in zip(edges[:-1], edges[1:]):
            m = int(min(4000, max(16, math.ceil((b - a) / (0.2 * h)))))
            near = [c + sg * e * cube for c, le, r in zip(centres, left, right) if a - r <= c <= b + le
                    for sg, e in ((-1, le), (1, r))]
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
        i = np.abs(s - sj) < MERGE_MM
        cap[i] = np.minimum(cap[i], read_cap(machine, max(np.max(dq2), 1e-300)))
    return s[cap < frac * limits.feed_max]


def read_cap(machine, dq2):
    """The speed at which a jump Δq″ (largest over the joints) reads at T as the jerk limit:
    κṡ² = J with κ = JUMP_READ_FACTOR·Δq″/T."""
    with np.errstate(divide="ignore"):
        return np.sqrt(machine.limits.joint.j * machine.servo_period_s / (JUMP_READ_FACTOR * np.asarray(dq2)))


def knot_jumps(path, machine, knots):
    """[(s, |Δq″| per joint)] at the NURBS knots where q″ jumps (by more than CONTINUOUS × what
    q‴ moves it over the two sides' 2·SIDE: a cusp tip's q″ is steep, not broken) and the jump
    reads at T as a jerk that matters (κṡ² = J at a speed below 10 × F_max).  A quadratic
    NURBS's P″ jumps at every knot, and join_jumps (the planners' G1 joins) does not list all of
    them (benchmarks/paths/corpus/README.md)."""
    if not knots:
        return []
    k = np.asarray(knots, float)
    q = joint_derivs(machine, path, np.concatenate([k - SIDE, k + SIDE]), fit_scale=True)
    n = len(k)
    dq2 = np.abs(q[2][n:] - q[2][:n])
    steep = np.maximum(np.abs(q[3][n:]), np.abs(q[3][:n])) * 2 * SIDE
    cap = read_cap(machine, dq2.max(axis=1))
    broken = (dq2 > CONTINUOUS * steep).any(axis=1)
    return [(float(s), d) for s, d, c, b in zip(k, dq2, cap, broken) if b and c < 10 * machine.limits.feed_max]


# --- one piece's NLP ----------------------------------------------------------------------
class PieceData:
    """The constraint data of a rest piece on a node grid, in scaled units (time t_u = A/J,
    speed A·t_u; then A = J = 1): per node the joint derivatives from the right (the cell after
    it) and from the left (the cell before; they differ at joins and knots only), the speed cap
    per node and, at a G1 join, its read κ."""

    def __init__(self, path, machine, limits, s, brk, joins, tu):
        T = machine.servo_period_s
        n = len(s)
        sl, sr = s.copy(), s.copy()
        sl[brk] -= SIDE
        sr[brk] += SIDE
        sr[0], sl[-1] = s[0] + 1e-9, s[-1] - 1e-9
        sl[0], sr[-1] = sr[0], sl[-1]
        vu = limits.joint.a * tu
        su = vu * tu          # the length unit: q′ keeps its value, q″ scales by su, q‴ by su²
        self.brk = np.asarray(brk, int)
        both = np.concatenate([sr, sl[self.brk]])
        cart = path.derivs(both)
        Q = joint_derivs(machine, path, both, cart=cart, fit_scale=True)
        Q = (Q[0], Q[1], Q[2] * su, Q[3] * su * su)
        self.right = tuple(q[:n] for q in Q[1:])
        self.left = tuple(q[:n].copy() for q in Q[1:])
        for q, ql in zip(Q[1:], self.left):
            ql[self.brk] = q[n:]
        kap = np.linalg.norm(np.cross(cart[1], cart[2]), axis=1)
        cap = feed_cap(path, both, limits, T, kappa=kap)
        cap_node = cap[:n].copy()
        cap_node[self.brk] = np.minimum(cap_node[self.brk], cap[n:])
        qv = np.abs(Q[1][:n]).max(axis=1)
        qv[self.brk] = np.maximum(qv[self.brk], np.abs(Q[1][n:]).max(axis=1))
        with np.errstate(divide="ignore", invalid="ignore"):
            self.vmax = np.minimum(cap_node, limits.joint.v / qv) / vu
        if np.isnan(self.vmax).any():
            i = int(np.flatnonzero(np.isnan(self.vmax))[0])
            raise RuntimeError(f"s = {s[i]:.9g} mm: the joint derivatives there are not finite")
        # break node → the join's read κ per joint, scaled and signed: the jump of q″ from the
        # left to the right side (a third difference reads q″ṡ² jumping up as a positive jerk)
        self.kappa = {}
        for sj, dq2 in joins:
            i = int(np.argmin(np.abs(s - sj)))
            if abs(s[i] - sj) < MERGE_MM:
                sign = np.sign(self.right[1][i] - self.left[1][i])
                self.kappa[i] = JUMP_READ_FACTOR * sign * np.asarray(dq2) * su / (T / tu)
        self.s, self.scale, self.period = s, (tu, vu), T / tu


def bspline2(x):
    """The quadratic B-spline on [0, 3] (mass 1; planners.constraints.third_difference_weight),
    0 outside: the kernel of a third difference at T."""
    x = np.asarray(x, float)
    return np.where((x <= 0) | (x >= 3), 0.0,
                    np.where(x < 1, x * x / 2, np.where(x < 2, (-2 * x * x + 6 * x - 3) / 2, (3 - x) ** 2 / 2)))


def add_join_node_reads(D: PieceData, add, v, a, j, b):
    """The cold start's rows (VERSION 6's): |jerk + κṡ²| ≤ J at each join's node, either side with
    that side's cell, κ signed (TII 2022's read at T of the window centred on the join). Not
    enough at T (a window off the join reads the jump and the jerk beside it: up to 1.99 × J on
    the CAM programs); add_kernel_reads replaces them once the nodes' times are known."""
    m = j.shape[0]
    for i, kap in D.kappa.items():
        for cell, (q1, q2, q3) in ((i - 1, D.left), (i, D.right)):
            if 0 <= cell < m:
                for k in range(3):
                    jerk = v[i] * (q3[i, k] * b[i] + 3 * q2[i, k] * a[i]) + q1[i, k] * j[cell]
                    add(jerk + kap[k] * b[i], -1.0, 1.0)


def add_kernel_reads(D: PieceData, add, v, a, j, b, reads, dt0):
    """Every join's reads at T, whatever the samples' phase: the third difference centred c
    (c − t_join = δ periods, δ ∈ KERNEL_PHASES) reads the joint jerk averaged by its kernel
    K(t − c) = bspline2((t − c)/T + 1.5)/T, plus each jump within its window weighted by
    bspline2 at the jump, κṡ²·join_read_weight (the jumps of every join near, not only this
    one's). The average is a composite trapezoid over each cell near the join, the jerk linear
    between the cell's two ends (their rows above), in intervals of at most KERNEL_H periods.
    The kernel's weights are numbers, evaluated at the cells' durations ``dt0`` (the start's):
    each read is linear in the cells' end jerks, and solve_with_reads solves again from each
    solution until its times are the ones the weights were evaluated at (VERSION 11 made the
    cells' times unknowns of the weights: the same rows at the solution, but CasADi's Hessian
    of them took 11 GB on cam_blend_kossel's level 0 before IPOPT started)."""
    import casadi as ca
    P = D.period
    m = j.shape[0]
    dt0 = np.maximum(np.asarray(dt0, float), 0.0)
    t0 = np.concatenate([[0.0], np.cumsum(dt0)])
    per_cell = [int(min(max(math.ceil(dt0[c] / (KERNEL_H * P)), 1), 256)) for c in range(m)]
    # the window centred δ periods from the join reads its kernel at (t − t_join)/P − δ + 1.5
    shift = 1.5 - KERNEL_PHASES
    for i, (cells, jumps) in read_cells(D, reads, m).items():
        # the quadrature points of every cell (its share θ of the cell, the trapezoid's weight)
        owner = np.concatenate([np.full(per_cell[c] + 1, q) for q, c in enumerate(cells)])
        th = np.concatenate([np.linspace(0.0, 1.0, per_cell[c] + 1) for c in cells])
        w = np.concatenate([np.r_[0.5, np.ones(per_cell[c] - 1), 0.5] / per_cell[c] for c in cells])
        span = dt0[cells]
        at = ((t0[cells] - t0[i])[owner] + th * span[owner]) / P
        K = (w / P)[:, None] * bspline2(at[:, None] + shift[None, :])
        # each cell's weights of its start and end jerk in each window's average (cells × phases)
        to_start = sp.csc_matrix((1 - th, (owner, np.arange(len(th)))), shape=(len(cells), len(th)))
        to_end = sp.csc_matrix((th, (owner, np.arange(len(th)))), shape=(len(cells), len(th)))
        ws, we = ca.DM(span[:, None] * (to_start @ K)), ca.DM(span[:, None] * (to_end @ K))
        nxt = [c + 1 for c in cells]
        reads_k = []
        for k in range(3):
            fs = v[cells] * (ca.DM(D.right[2][cells, k]) * b[cells] + 3 * ca.DM(D.right[1][cells, k]) * a[cells]) \
                + ca.DM(D.right[0][cells, k]) * j[cells]
            fe = v[nxt] * (ca.DM(D.left[2][nxt, k]) * b[nxt] + 3 * ca.DM(D.left[1][nxt, k]) * a[nxt]) \
                + ca.DM(D.left[0][nxt, k]) * j[cells]
            read = ws.T @ fs + we.T @ fe
            for n in jumps:
                weight = bspline2((t0[n] - t0[i]) / P + shift) / JUMP_READ_FACTOR
                read += D.kappa[n][k] * b[n] * ca.DM(weight)
            reads_k.append(read)
        # row by row as before: per phase, per joint
        add(ca.vec(ca.horzcat(*reads_k).T), -1.0, 1.0)


def read_cells(D: PieceData, reads, m) -> dict:
    """Per join node (D.kappa's order): the cells whose jerk its windows average (either side of
    each node in ``reads``) and the join nodes among them, whose jumps they read."""
    out = {}
    for i in D.kappa:
        near = sorted(set(reads.get(i, ())) | {i})
        out[i] = (sorted({c for n in near for c in (n - 1, n) if 0 <= c < m}), [n for n in near if n in D.kappa])
    return out


def read_nodes(D: PieceData, dt, reach=1.0) -> dict:
    """Per join node, the other nodes less than ``reach`` × 2·READ_REACH periods from it at the
    cells' durations ``dt`` (scaled): the nodes a window reading the join's jump can reach."""
    t = np.concatenate([[0.0], np.cumsum(dt)])
    return {i: {int(c) for c in np.nonzero(np.abs(t - t[i]) < reach * 2 * READ_REACH * D.period)[0] if c != i}
            for i in D.kappa}


def solve_piece(D: PieceData, warm=None, reads=None, at=None):
    """One piece's NLP: (time in s, then per node ṡ, s̈ and per cell its duration and path jerk,
    all scaled; IPOPT iterations, status). ``warm``: (v, a, dt, j) on this grid; ``reads``: per
    join node the nodes whose jerk holds the join's read weighted by their time from it, the
    kernel's weights at the cells' durations ``at`` (default: the warm start's)."""
    import casadi as ca   # casadi only where a piece is solved (the cache answers the rest)

    tu, vu = D.scale
    su = vu * tu
    dx = np.diff((D.s - D.s[0]) / su)
    n, m = len(dx) + 1, len(dx)
    v, a = ca.SX.sym("v", n), ca.SX.sym("a", n)
    dt, j = ca.SX.sym("dt", m), ca.SX.sym("j", m)
    b = v * v
    # a cell is s(t) cubic: constant path jerk j over its duration dt, exact from node to node
    g = [a[1:] - a[:-1] - j * dt,
         v[1:] - v[:-1] - 0.5 * (a[:-1] + a[1:]) * dt,
         dx - v[:-1] * dt - (2 * a[:-1] + a[1:]) * dt * dt / 6]
    lb, ub = [np.zeros(3 * m)], [np.zeros(3 * m)]

    def add(expr, lo, hi):
        g.append(expr)
        lb.append(np.full(expr.shape[0], lo))
        ub.append(np.full(expr.shape[0], hi))

    r1, r2, r3 = D.right
    l1, l2, l3 = D.left
    bk = [int(i) for i in D.brk]
    for k in range(3):
        # acceleration at every node from the right, and from the left at the break nodes
        add(r2[1:-1, k] * b[1:-1] + r1[1:-1, k] * a[1:-1], -1.0, 1.0)
        if bk:
            add(l2[bk, k] * b[bk] + l1[bk, k] * a[bk], -1.0, 1.0)
        # jerk of each cell at both its ends (its start from the right, its end from the left)
        add(v[:-1] * (r3[:-1, k] * b[:-1] + 3 * r2[:-1, k] * a[:-1]) + r1[:-1, k] * j, -1.0, 1.0)
        add(v[1:] * (l3[1:, k] * b[1:] + 3 * l2[1:, k] * a[1:]) + l1[1:, k] * j, -1.0, 1.0)
    # ṡ ≥ 0 inside a cell too (at its half time)
    add(v[:-1] + 0.5 * a[:-1] * dt + j * dt * dt / 8, 0.0, np.inf)
    # a G1 join: its jump of q″ reads at T as a jerk in every third difference whose window holds
    # it; with ``reads`` (the nodes near each join) every such window's read, whatever the phase,
    # from the start's solve (no reads) the join's node alone
    if reads is not None and D.kappa:
        add_kernel_reads(D, add, v, a, j, b, reads, warm[2] if at is None else at)
    else:
        add_join_node_reads(D, add, v, a, j, b)
    vmax = np.minimum(D.vmax, 1e6)
    lbx = np.concatenate([np.zeros(n), np.full(n, -np.inf), np.zeros(m), np.full(m, -np.inf)])
    ubx = np.concatenate([vmax, np.full(n, np.inf), np.full(m, np.inf), np.full(m, np.inf)])
    for i in (0, n - 1):                       # rest: ṡ = s̈ = 0 at both ends
        ubx[i] = 0.0
        lbx[n + i] = ubx[n + i] = 0.0
    x0 = np.concatenate(initial_guess(D, dx, vmax) if warm is None else warm)
    x0 = np.clip(x0, lbx, ubx)
    x = ca.vertcat(v, a, dt, j)
    nlp = {"x": x, "f": ca.sum1(dt), "g": ca.vertcat(*g)}
    opts = IPOPT if warm is None else {**IPOPT, **IPOPT_WARM}
    solver = ca.nlpsol("reference", "ipopt", nlp, {"ipopt": opts, "print_time": False})
    res = solver(x0=x0, lbx=lbx, ubx=ubx, lbg=np.concatenate(lb), ubg=np.concatenate(ub))
    st = solver.stats()
    sol = np.asarray(res["x"]).ravel()
    parts = np.split(sol, [n, 2 * n, 2 * n + m, 2 * n + 2 * m])[:4]
    return (float(res["f"]) * tu, *parts, int(st.get("iter_count", -1)), st["return_status"])


def solve_with_reads(D: PieceData, warm, where: str, log=None, resume=None, save=None):
    """solve_piece with the joins' reads at the nodes near them: from a cold start first without
    them (IPOPT finds the coupled problem from a cold start far slower than from a warm one),
    then with the nodes near at the start's times (READ_SLACK wider) and the kernel's weights at
    the start's durations, again from each solution while its times are FIX_TOL periods or more
    from the ones the weights were read at, or it has a node within 2·READ_REACH periods of a
    join outside the set (added; the kernel is 0 beyond). The last solve's rows are its own
    reads. The weights' times step towards each solution's by Aitken's relaxation (undamped, a
    pocket_kossel piece flipped between two solutions 0.028 periods apart). ``save``: called
    with the iteration's state before each solve; ``resume``: such a state to go on from."""
    if resume is None:
        iters = 0
        if warm is None:
            Tk, v, a, dt, j, iters, status = _solved(solve_piece(D), where)
            if not D.kappa:
                return Tk, v, a, dt, j, iters, status
            warm = (v, a, dt, j)
        reads = read_nodes(D, warm[2], READ_SLACK)
        at, step, last, first = np.maximum(np.asarray(warm[2], float), 0.0), 1.0, None, 0
    else:
        first, iters, warm, reads, at, step, last = (resume[k] for k in ROUND_STATE)
    for r in range(first, FIX_ROUNDS):
        if save:
            save(dict(zip(ROUND_STATE, (r, iters, warm, reads, at, step, last))))
        Tk, v, a, dt, j, it, status = _solved(solve_piece(D, warm, reads, at), where)
        iters += it
        if not D.kappa:
            return Tk, v, a, dt, j, iters, status
        # how far each node's time lies from where the weights read it
        off = np.cumsum(dt) - np.cumsum(at)
        move = float(np.max(np.abs(off))) / D.period
        missing = {i: c - reads[i] for i, c in read_nodes(D, dt).items() if c - reads[i]}
        if log:
            log(f"    {where} round {r}: T {Tk:.9f} s, times moved {move:.3g} periods, step {step:g}")
        if not missing and move < FIX_TOL:
            return Tk, v, a, dt, j, iters, status
        for i, c in missing.items():
            reads[i] |= c
        change = None if last is None else off - last
        if change is not None and float(change @ change) > 0:
            # Aitken's dynamic relaxation (Irons & Tuck 1969; Küttler & Wall, Comput. Mech. 2008):
            # the step that zeroes the offset along its last change
            step = float(np.clip(-step * (last @ change) / (change @ change), FIX_STEP_MIN, 1.0))
        last = off
        at = at + step * (np.maximum(dt, 0.0) - at)
        warm = (v, a, dt, j)
    raise RuntimeError(f"{where}: after {FIX_ROUNDS} solves a node's time still moved {move:.3g} periods "
                       f"or the nodes within {2 * READ_REACH} periods of a join still grew")


ROUND_STATE = ("round", "iterations", "warm", "reads", "at", "step", "last")


def _solved(result, where: str):
    """solve_piece's result, or an error naming the piece where IPOPT did not converge."""
    if result[-1] not in ("Solve_Succeeded", "Solved_To_Acceptable_Level"):
        raise RuntimeError(f"{where}: IPOPT {result[-1]}")
    return result


def initial_guess(D, dx, vmax, share=0.5):
    """A start for IPOPT built from the limits (scaled, A = J = 1): per node the speed that
    spends ``share`` of a joint's acceleration on q″ṡ² alone, of its jerk on q‴ṡ³ alone and of
    a join's read on κṡ², under vmax; then the forward and backward passes of a path
    acceleration ``share``/|q′| (the rest ends left along the jerk-limited ṡ^(3/2) ∝ s); the
    cells' durations and jerks as that speed gives them. Not feasible at the passes' switches,
    but within a small factor of it (a slow start put 0.2·F_max through a µm blend arc, and
    IPOPT spent its iterations getting out)."""
    q1, q2, q3 = (np.abs(q).max(axis=1) for q in D.right)
    q3 = np.maximum(q3, np.abs(D.left[2]).max(axis=1))
    with np.errstate(divide="ignore"):
        cap = np.minimum.reduce([vmax, np.sqrt(share / q2), np.cbrt(share / q3)])
        for i, kap in D.kappa.items():
            cap[i] = min(cap[i], math.sqrt(share / np.abs(kap).max()))
        acc = share / q1
    v = cap.copy()
    v[0] = v[-1] = 0.0
    for order in (range(1, len(v)), range(len(v) - 2, -1, -1)):
        for i in order:
            k = i - 1 if order.step == 1 else i + 1
            d = dx[min(i, k)]
            v[i] = min(v[i], math.sqrt(v[k] ** 2 + 2 * acc[k] * d),
                       (v[k] ** 1.5 + 2.12 * math.sqrt(acc[k]) * d) ** (2 / 3))
    x = np.concatenate([[0.0], np.cumsum(dx)])
    a = np.gradient(0.5 * v ** 2, x)
    a[[0, -1]] = 0.0
    dt = 2 * dx / np.maximum(v[:-1] + v[1:], 1e-12)
    return v, a, dt, np.diff(a) / dt


def cell_state(v, a, j, dt, ds):
    """Per cell (start speed v, acceleration a, jerk j, duration dt): the time τ ∈ [0, dt] at
    which s(τ) = v·τ + a·τ²/2 + j·τ³/6 reaches ``ds`` (bisection: s is monotone in a cell), and
    ṡ, s̈ there."""
    lo, hi = np.zeros_like(dt), dt.copy()
    for _ in range(60):
        t = 0.5 * (lo + hi)
        below = v * t + a * t * t / 2 + j * t ** 3 / 6 < ds
        lo, hi = np.where(below, t, lo), np.where(below, hi, t)
    t = 0.5 * (lo + hi)
    return t, v + a * t + j * t * t / 2, a + j * t


def refine_warm(s, v, a, dt, j, s_fine):
    """The coarse solution on the nested grid twice as fine, as the coarse NLP's own profile:
    a new node is a coarse cell's σ-midpoint, reached along that cell's cubic."""
    t, vm, am = cell_state(v[:-1], a[:-1], j, dt, s_fine[1::2] - s[:-1])
    vf, af = np.empty(len(s_fine)), np.empty(len(s_fine))
    vf[0::2], af[0::2], vf[1::2], af[1::2] = v, a, vm, am
    dtf, jf = np.empty(2 * len(dt)), np.repeat(j, 2)
    dtf[0::2], dtf[1::2] = t, dt - t
    return vf, af, dtf, jf


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


def reference(path, machine, levels=LEVELS, base_nodes=BASE_NODES, log=None, wide_nodes=0, round_log=None,
              checkpoint=None):
    """The refinement study of one path: {"grids": [...], "T_reference_s", "error_s", "order",
    "check_at_T"}: ``levels`` grids and, while their bar is above WIDE_BAR of T* and the next
    grid has at most ``wide_nodes`` nodes, one more. ``log``: a line per grid; ``round_log``: a
    line per solve of a piece with joins; ``checkpoint`` (a Checkpoint): the study's state saved
    before every solve and gone on from (the CAM programs' studies outlast a session)."""
    limits = machine.limits
    J = limits.joint
    tu = J.a / J.j
    table = PathTable(path, machine)
    joins = join_jumps(path, table, machine)
    brk_all = sorted(set(breakpoints(path)) | {sj for sj, _ in joins})
    knots = list(interior_knots(path))
    joins += knot_jumps(path, machine, [k for k in knots if all(abs(k - sj) > MERGE_MM for sj, _ in joins)])
    pieces = rest_pieces(path)
    h = path.length / base_nodes
    # the rest ends' graded zone: the distance the jerk-limited start covers to reach ~F_max
    ell = (limits.feed_max ** 1.5) / math.sqrt(J.j) * 2
    maps = []
    for s0, s1 in pieces:
        br = [b for b in brk_all + knots if s0 + MERGE_MM < b < s1 - MERGE_MM]
        br += list(curvature_peaks(path, s0, s1))
        br = np.unique(np.round(np.array(br, float), 12))
        if len(br):
            keep = np.concatenate([[True], np.diff(br) > MERGE_MM])
            br = br[keep]
            br = br[(br > s0 + MERGE_MM) & (br < s1 - MERGE_MM)]
        slow = np.concatenate([slow_points(path, machine, limits, br, joins),
                               [sj for sj, _ in joins if s0 < sj < s1]])
        maps.append(Map(path, s0, s1, br, h, ell, slow))
    # the study so far: what a checkpoint holds, from which the same solves go on
    st = {"level": 0, "grids": [], "warm": [None] * len(maps), "piece": 0, "T_s": 0.0, "iterations": 0,
          "nodes": 0, "prof": [], "cpu_s": 0.0, "rounds": None, "finest": None}
    if checkpoint is not None and checkpoint.state is not None:
        st = checkpoint.state
        if log:
            r = st["rounds"]
            log(f"  resumed at level {st['level']}, piece {st['piece']}" + (f", round {r['round']}" if r else ""))
    while (st["level"] < levels or _wide([g["T_s"] for g in st["grids"]])
           and 2 * st["grids"][-1]["nodes"] <= wide_nodes):
        level, t0 = st["level"], time.process_time() - st["cpu_s"]

        def keep(rounds):
            st.update(rounds=rounds, cpu_s=time.process_time() - t0)
            checkpoint.save(st)

        while st["piece"] < len(pieces):
            k = st["piece"]
            (s0, s1), mp = pieces[k], maps[k]
            s, brk = mp.nodes(level)
            D = PieceData(path, machine, limits, s, brk, joins, tu)
            x = (s - s[0]) / (D.scale[0] * D.scale[1])
            w = None if st["warm"][k] is None else refine_warm(*st["warm"][k], x)
            Tk, v, a, dt, j, it, status = solve_with_reads(
                D, w, f"piece {k} (s = {s0:.6g}…{s1:.6g}) level {level}", round_log,
                resume=st["rounds"], save=keep if checkpoint is not None else None)
            tu_, vu = D.scale
            st["warm"][k] = (x, v, a, dt, j)
            st["prof"].append((s, v * vu, a * vu / tu_, j * vu / tu_ ** 2, dt * tu_))
            st.update(piece=k + 1, T_s=st["T_s"] + Tk, iterations=st["iterations"] + it, nodes=st["nodes"] + len(s))
            if checkpoint is not None:
                keep(None)
        g = {"nodes": st["nodes"], "T_s": st["T_s"], "solve_s": round(time.process_time() - t0, 2),
             "iterations": st["iterations"]}
        st["grids"].append(g)
        if log:
            log(f"  level {level}: {g['nodes']} nodes T = {g['T_s']:.9f} s ({g['solve_s']} s CPU, {g['iterations']} it)")
        st.update(level=level + 1, piece=0, T_s=0.0, iterations=0, nodes=0, prof=[], cpu_s=0.0, rounds=None,
                  finest=st["prof"])
        if checkpoint is not None:
            checkpoint.save(st)
    grids, prof = st["grids"], st["finest"]
    Ts, err, p = richardson([g["T_s"] for g in grids])
    return {"T_reference_s": Ts, "error_s": err, "order": None if math.isnan(p) else p, "grids": grids,
            "check_at_T": check_at_T(path, machine, prof)}


def _wide(T) -> bool:
    """Whether the grids' times ``T`` leave a bar above WIDE_BAR of their limit."""
    Ts, err, _ = richardson(T)
    return err > WIDE_BAR * Ts


def sample_profile(prof, T, delay=0.0):
    """Arc lengths at t = kT of the piecewise-cubic profile [(s, ṡ, s̈ at the nodes, each cell's
    jerk and duration) per rest piece], evaluated exactly; ``delay``: the motion starts that
    long after a sample (a servo clock at another phase), at rest before."""
    S, V, A, Jk, t0 = [], [], [], [], []
    t_off = 0.0
    for s, v, a, j, dt in prof:
        S.append(s[:-1]), V.append(v[:-1]), A.append(a[:-1]), Jk.append(j)
        t0.append(t_off + np.concatenate([[0.0], np.cumsum(dt)[:-1]]))
        t_off += float(np.sum(dt))
    S, V, A, Jk, t0 = (np.concatenate(x) for x in (S, V, A, Jk, t0))
    tq = np.arange(int(math.ceil((t_off + delay) / T)) + 1) * T - delay
    tq = np.clip(tq, 0.0, t_off)
    i = np.clip(np.searchsorted(t0, tq, side="right") - 1, 0, len(t0) - 1)
    u = tq - t0[i]
    s = S[i] + V[i] * u + A[i] * u * u / 2 + Jk[i] * u ** 3 / 6
    s_end = prof[-1][0][-1]
    return np.maximum.accumulate(np.clip(s, S[0], s_end))


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
class Checkpoint:
    """A study's state in a file, written before every solve (atomically: a kill leaves the last
    whole state) and read back when the same study (the same key) starts again: it goes on with
    the same solves from the same starts, so it ends with the same numbers. Not a result: the
    file is deleted when the study is written to the reference file. ``cpu_s``: the CPU the
    study has taken, the processes' before this one's included."""

    def __init__(self, file: Path, key: str):
        self.file, self.key, self.state, self.before = Path(file), key, None, 0.0
        self.t0 = time.process_time()
        try:
            saved = pickle.loads(self.file.read_bytes())
            if saved.get("key") == key:
                self.state, self.before = saved["state"], float(saved["cpu_s"])
        except FileNotFoundError:
            return
        # a pickle of something else (no dict, no state) is as unreadable as a truncated one
        except (OSError, pickle.UnpicklingError, EOFError, ValueError, AttributeError, KeyError, TypeError) as err:
            raise RuntimeError(f"checkpoint {self.file} is unreadable ({type(err).__name__}: {err}); "
                               "delete it or run with --restart") from err

    @property
    def cpu_s(self) -> float:
        return self.before + time.process_time() - self.t0

    def save(self, state):
        tmp = self.file.with_name(self.file.name + ".tmp")
        tmp.write_bytes(pickle.dumps({"key": self.key, "state": state, "cpu_s": self.cpu_s},
                                     protocol=pickle.HIGHEST_PROTOCOL))
        os.replace(tmp, self.file)

    def clear(self):
        self.file.unlink(missing_ok=True)


def entry_key(entry) -> str:
    """What a cached reference depends on: the path file's bytes, the machine, the settings."""
    h = hashlib.sha256((HERE / entry["file"]).read_bytes())
    h.update(json.dumps([entry["machine"], VERSION, BASE_NODES, LEVELS, TURN_RAD, KERNEL_STEP, KERNEL_H, FIX_TOL, FIX_STEP_MIN, WIDE_BAR, WIDE_NODES]).encode())
    return h.hexdigest()[:16]


def load(file=OUT) -> dict:
    try:
        return json.loads(Path(file).read_text())
    except (OSError, json.JSONDecodeError):
        return {"paths": {}}


METHOD = ("piecewise-cubic s(t) between fixed path nodes (ṡ, s̈ at nodes, Δt and s⃛ per cell; CasADi + IPOPT) on nested "
          "grids, Richardson limit of the last three; see benchmarks/paths/corpus/reference.py")


def store(studies: dict, file=OUT):
    """Write ``studies`` (path name → study) into the reference file as it is now, not as it was
    when this run started: the studies another run wrote meanwhile (one path per core) are kept.
    Atomic: a kill leaves the old file or the new one."""
    data = load(file)
    data["method"] = METHOD
    data["paths"] = dict(sorted({**data.get("paths", {}), **studies}.items()))
    tmp = Path(f"{file}.tmp{os.getpid()}")
    tmp.write_text(json.dumps(data, indent=1, ensure_ascii=False) + "\n")
    os.replace(tmp, file)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--paths", default="*", help="comma-separated globs of corpus path names")
    ap.add_argument("--force", action="store_true", help="solve again even where the cache is current")
    ap.add_argument("--out", default=str(OUT))
    ap.add_argument("--verbose", action="store_true", help="a line per solve of a piece with joins, not only per grid")
    ap.add_argument("--checkpoints", help="folder of the studies' checkpoints (default: next to --out, "
                    "<out>.checkpoints/): a study stopped before its end goes on from its last solve")
    ap.add_argument("--restart", action="store_true", help="start the studies afresh, not from their checkpoints")
    args = ap.parse_args(argv)
    entries = json.loads((HERE / "manifest.json").read_text())["paths"]
    pats = [p.strip() for p in args.paths.split(",") if p.strip()]
    todo = [e for e in entries if any(fnmatch.fnmatch(e["name"], p) for p in pats)]
    if not todo:
        print(f"reference.py: --paths {args.paths} matches no corpus path", file=sys.stderr)
        return 2
    cached = load(args.out).get("paths", {})
    machines, failed, mine = {}, [], {}
    cps = Path(args.checkpoints) if args.checkpoints else Path(args.out).with_suffix(".checkpoints")
    for e in todo:
        key = entry_key(e)
        old = cached.get(e["name"])
        if old and old.get("key") == key and not args.force:
            # the extrapolation is arithmetic on the stored study: redone, never stale
            Ts, err, p = richardson([g["T_s"] for g in old["grids"]])
            mine[e["name"]] = {**old, "T_reference_s": Ts, "error_s": err, "order": None if math.isnan(p) else p}
            print(f"{e['name']}: cached T_ref = {Ts:.6f} ± {err:.2g} s")
            continue
        m = machines.get(e["machine"]) or machines.setdefault(e["machine"], load_machine(e["machine"]))
        path = resolve_path(str(HERE / e["file"]), home=m.home)
        print(f"{e['name']} ({e['machine']}):", flush=True)
        try:
            cps.mkdir(parents=True, exist_ok=True)
            if args.restart:
                (cps / f"{e['name']}.pkl").unlink(missing_ok=True)
            cp = Checkpoint(cps / f"{e['name']}.pkl", key)
        except (OSError, RuntimeError) as err:
            print(f"{e['name']}: {err}", file=sys.stderr)
            failed.append(e["name"])
            continue
        try:
            say = lambda s: print(s, flush=True)  # noqa: E731
            r = reference(path, m, log=say, wide_nodes=WIDE_NODES, round_log=say if args.verbose else None,
                          checkpoint=cp)
        except RuntimeError as err:
            print(f"{e['name']}: {err}", file=sys.stderr)
            failed.append(e["name"])
            continue
        except KeyboardInterrupt:
            print(f"{e['name']}: interrupted; run again to go on from {cp.file}", file=sys.stderr)
            return 130
        r = {"key": key, "T_reference_s": r["T_reference_s"], "error_s": r["error_s"], **r,
             "cpu_s": round(cp.cpu_s, 1)}
        mine[e["name"]] = r
        store(mine, args.out)
        cp.clear()
        c = r["check_at_T"]
        print(f"{e['name']}: T_ref = {r['T_reference_s']:.6f} ± {r['error_s']:.2g} s (order {r['order']}); "
              f"finest at T: {c['execution_time_s']:.6f} s, joint v/a/j {c['joint_peak_ratio']} "
              f"({r['cpu_s']} s CPU)", flush=True)
    store(mine, args.out)
    if failed:
        print(f"reference.py: no study of {', '.join(failed)}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
