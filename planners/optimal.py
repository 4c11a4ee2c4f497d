"""`optimal` — minimum time with joint velocity, acceleration and jerk limits (CasADi + IPOPT).

The jerk-limited reference: no profile that meets the shared constraint set (joint v, a, j;
F_max; the chord-error feed cap) can be faster, within solver tolerance and the resolution
of the grid.  Formulation (direct multiple shooting, exact integration):

* the path is split at exact-stop corners; each piece is a rest-to-rest problem of its own
  (at a corner ṡ = s̈ = 0, so the pieces do not interact);
* per piece N intervals of one common duration h (a variable): states s, ṡ, s̈ at the nodes,
  constant jerk s⃛ on each interval, so s(t) is a cubic spline and the dynamics are exact;
* at every node: |q′ṡ| ≤ V, |q″ṡ² + q′s̈| ≤ A, |q‴ṡ³ + 3q″ṡs̈ + q′s⃛| ≤ J (the jerk of both
  intervals that meet there), ṡ ≤ feed cap(s); q′, q″, q‴ and the cap are B-spline
  interpolants of the PathTable over s, so IPOPT sees exact derivatives;
* the feed cap also holds the G1-join caps (constraints.second_derivative_jumps);
* objective N·h, warm start from the `scurve_joint` profile (feasible, so IPOPT starts inside
  the constraint set: from the faster but jerk-infeasible `toppra` profile IPOPT lost itself
  in restoration on kossel's test_part, whose 0.04 mm blend arcs make it 68× over the jerk
  limit), slowed down by 2 %.

The solution is sampled at T exactly and checked with the independent metrics; if a
discretisation effect pushes a joint ratio above 1 the problem is re-solved: on a grid twice
as fine (from the seed again) where the node budget had spread the nodes ≥ 3× thinner than
`node_period_s` (up to MAX_NODES_REFINED per piece), else from the last solution, in the
pieces where a limit read above 1: with the margin doubled on each limit read above 1 (each
piece has one margin per limit) and, if it was a or j on a grid not refined, these bounded
at each interval's midpoint too (keops' flower: the jerk read 1.04 × between nodes 2 ms
apart at margin 0.005, still 1.003 × at 0.04 without the midpoints).  (Why refining
comes first and why margins are per piece and per limit: the measurements in docs/TUNING.md.)

Size: _Piece.solve (~115 lines) is over the project's 80-line guide on purpose this time:
another branch is changing this module's internals for memory on long programs (issue 18
left them alone).
"""
from __future__ import annotations

import os
import time

import casadi as ca
import numpy as np

from .constraints import (JUMP_READ_FACTOR, PathTable, PlanningError, check_limits, check_path,
                          join_jumps, rest_pieces, table_feed_cap)
from .profile import Profile
# Nodes per phase (between G1 joins) at least: the limits hold at the nodes only, and on a
# 0.04 mm G64 blend arc the joint derivatives turn through 90°; with 6 nodes there the jerk
# read at T peaked 2 % above the limit between them.
MIN_PHASE_NODES = 24
# A piece's grid is refined on a failed check up to this many nodes (more than the default
# budget: a 90 s solve on flower at 1500 nodes from the start, against ≤ 60 s wanted)
MAX_NODES_REFINED = 1500
# ... when the budget had spread its nodes this many times thinner than node_period_s (kossel's
# 3 s pieces: 5 ms; keops' flower: 2 ms, where refining cost time and still failed the check)
THIN_GRID_FACTOR = 3.0
# IPOPT's own progress table, for diagnosing a solve: PKM_IPOPT_PRINT=5 (default 0, silent)
IPOPT_PRINT_LEVEL = int(os.environ.get("PKM_IPOPT_PRINT", "0"))


LIMIT_KINDS = ("velocity", "acceleration", "jerk", "feed")     # each with its own margin


def broken_limits(machine, path, prof, pcs, limits) -> set:
    """{(piece index, limit kind)} read above 1 at T: the joint velocity, acceleration, jerk
    (differences of the IK'd samples, each window blamed on the piece its first sample is in)
    and the feed against F_max."""
    from planners.verify import differences
    T = prof.T
    edges = np.array([a for a, _ in pcs[1:]])
    lim = {"velocity": limits.joint.v, "acceleration": limits.joint.a, "jerk": limits.joint.j}
    out = set()
    for kind, D in differences(machine.ik(path.point(prof.s)), T).items():
        bad = np.nonzero(np.abs(D).max(axis=1) > lim[kind])[0]
        out |= {(int(g), kind) for g in np.searchsorted(edges, prof.s[bad], side="right")}
    feed = np.diff(prof.s) / T
    bad = np.nonzero(feed > limits.feed_max * (1 + 1e-6))[0]
    out |= {(int(g), "feed") for g in np.searchsorted(edges, prof.s[bad], side="right")}
    return out


class _Piece:
    """One rest-to-rest problem between s0 and s1."""

    def __init__(self, table, cap, s0, s1, limits, margin, joins=(), T=1e-3):
        self.s0, self.s1 = s0, s1
        self.joins = [(sj, dq2) for sj, dq2 in joins if s0 + 1e-6 < sj < s1 - 1e-6]
        self.T = T
        # one set of interpolants per phase (between G1 joins), each from one-sided values,
        # so a jump of q″ at a join is never smoothed over
        bounds = [s0] + [sj for sj, _ in self.joins] + [s1]
        self.phase_fns = []
        for k, (a, b) in enumerate(zip(bounds[:-1], bounds[1:])):
            g = table.s[(table.s > a) & (table.s < b)]
            g = np.unique(np.concatenate([[a], g, [b], np.linspace(a, b, 4)]))
            e = np.clip(g, a + 1e-9, b - 1e-9)
            d1, d2, d3 = table.joints(e)
            c = np.interp(g, table.s, cap)
            grid = [g.tolist()]
            mk = lambda name, y: ca.interpolant(name, "bspline", grid, np.ascontiguousarray(y).tolist())
            self.phase_fns.append({
                "q1": [mk(f"q1_{k}_{i}", d1[:, i]) for i in range(3)],
                "q2": [mk(f"q2_{k}_{i}", d2[:, i]) for i in range(3)],
                "q3": [mk(f"q3_{k}_{i}", d3[:, i]) for i in range(3)],
                "cap": mk(f"cap_{k}", c)})
        self.table = table
        self.lim = limits.joint
        # one margin per limit, grown apart: a jerk read above its limit at one blend join
        # must not slow the feed-capped cruise of the whole part
        self.margins = dict.fromkeys(LIMIT_KINDS, margin)
        # the joint a and j bounded at each interval's midpoint too, once a check found them
        # above their limits on a grid that was not refined: on keops' flower (nodes 2 ms
        # apart, T = 250 µs, the 3q″ṡs̈ term moving with s̈ between them) the jerk read 1.04 × at
        # margin 0.005 and still 1.003 × at 0.04; with them it passes at 0.02 (1.2355 s).  Not
        # from the start: they doubled the solve time on bird (6 → 11 s), which passes without,
        # and with them IPOPT stopped at its 600 iterations on test_part's first piece refined
        # to 1200 nodes (from the seed; 58 iterations without)
        self.midpoints = False

    def solve(self, Ns, h0s, S0, V0, A0, U0, max_iter=600):
        """Ns, h0s: intervals and initial interval duration of each phase (the phases are
        separated by the G1 joins, where the node lies exactly on the join)."""
        L = self.s1 - self.s0
        lim = self.lim
        mv, ma, mj, mf = (1 - self.margins[k] for k in LIMIT_KINDS)
        Vs, As, Js = lim.v, lim.a, lim.j
        N = int(sum(Ns))
        opti = ca.Opti()
        # normalised variables (IPOPT likes O(1) numbers)
        eta = opti.variable(len(Ns))        # h_k / h0_k of each phase
        sig = opti.variable(N + 1)          # (s − s0) / L
        nu = opti.variable(N + 1)           # ṡ / V
        al = opti.variable(N + 1)           # s̈ / A
        mu = opti.variable(N)               # s⃛ / J
        phase = np.repeat(np.arange(len(Ns)), Ns)
        sel = ca.DM(np.eye(len(Ns))[phase])             # (N × phases) picks each interval's phase
        h = sel @ (eta * ca.DM(h0s))
        s = self.s0 + L * sig
        v, a, u = Vs * nu, As * al, Js * mu
        bounds = np.cumsum(Ns)[:-1]
        for (sj, dq2), k in zip(self.joins, bounds):
            k = int(k)
            opti.subject_to(sig[k] == (sj - self.s0) / L)
            # one-sided derivatives: the interval before the join is on the curve before it
            D1, D2, D3 = (np.asarray(x) for x in self.table.joints(np.array([sj - 1e-9, sj + 1e-9])))
            left, right = (D1[0], D2[0], D3[0]), (D1[1], D2[1], D3[1])
            for i in range(3):
                read = JUMP_READ_FACTOR * float(dq2[i]) * v[k] ** 2 / self.T
                for uu, (d1, d2, d3) in ((u[k - 1], left), (u[k], right)):
                    cont = d3[i] * v[k] ** 3 + 3 * d2[i] * v[k] * a[k] + d1[i] * uu
                    opti.subject_to((cont + read) / Js <= mj)
                    opti.subject_to((read - cont) / Js <= mj)
        # exact constant-jerk integration over each interval
        opti.subject_to(s[1:] == s[:-1] + v[:-1] * h + a[:-1] * h ** 2 / 2 + u * h ** 3 / 6)
        opti.subject_to(v[1:] == v[:-1] + a[:-1] * h + u * h ** 2 / 2)
        opti.subject_to(a[1:] == a[:-1] + u * h)
        opti.subject_to(sig[1:] >= sig[:-1])
        opti.subject_to([sig[0] == 0, sig[N] == 1, nu[0] == 0, nu[N] == 0, al[0] == 0, al[N] == 0])
        opti.subject_to(opti.bounded(0.05, eta, 20.0))
        opti.subject_to(nu >= 0)
        # ṡ at each interval's midpoint too.  Within the feed cap: at cruise on F_max the jerk
        # chattered between nodes 12 ms apart and the feed read 1.3 % over F_max between them
        # (kossel test_part).  ≥ 0: at a stop ṡ dipped below 0 between nodes, and sampling can only
        # clip s there into a kink (a test_part blend: 1.40 → 1.13 × the jerk limit at T; ṡ ≥ 0 on
        # the whole interval, by the quadratic's middle Bernstein coefficient, removed the kink
        # but left IPOPT without a step on test_part for > 10 min)
        v_mid = v[:-1] + a[:-1] * h / 2 + u * h ** 2 / 8
        opti.subject_to(v_mid >= 0)
        # … and at the quarter points: at a 0.04 mm blend join of test_part the optimum stops
        # (ṡ = 0 at the node) and leaves with s̈ < 0 and s⃛ > 0, so ṡ dipped to −0.0018 mm/s
        # between the node and a midpoint that sat exactly on 0; sampling clipped s there into a
        # kink that read 1.14 × the jerk limit at T.  Between quarter points a dip is 16× smaller.
        near = sorted({int(i) for k in bounds for i in (k - 1, k) if 0 <= i < N})
        for q in (0.25, 0.75):
            for i in near:
                opti.subject_to(v[i] + a[i] * (q * h[i]) + u[i] * (q * h[i]) ** 2 / 2 >= 0)
        sm = ca.fmin(ca.fmax(s, self.s0), self.s1)
        starts = np.concatenate([[0], np.cumsum(Ns)])
        for k, fns in enumerate(self.phase_fns):
            n0, n1 = int(starts[k]), int(starts[k + 1])
            n = n1 - n0 + 1
            ST = sm[n0:n1 + 1].T
            vk, ak, uk = v[n0:n1 + 1], a[n0:n1 + 1], u[n0:n1]
            capv = fns["cap"].map(n)(ST).T
            opti.subject_to(vk <= capv * mf)
            opti.subject_to(v_mid[n0:n1] <= ca.fmin(capv[:-1], capv[1:]) * mf)
            uL = ca.vertcat(uk, uk[n - 2])      # jerk of the interval after each node …
            uR = ca.vertcat(uk[0], uk)          # … and before it (within this phase)
            for i in range(3):
                d1 = fns["q1"][i].map(n)(ST).T
                d2 = fns["q2"][i].map(n)(ST).T
                d3 = fns["q3"][i].map(n)(ST).T
                opti.subject_to(opti.bounded(-mv, d1 * vk / Vs, mv))
                opti.subject_to(opti.bounded(-ma, (d2 * vk ** 2 + d1 * ak) / As, ma))
                base = d3 * vk ** 3 + 3 * d2 * vk * ak
                opti.subject_to(opti.bounded(-mj, (base + d1 * uL) / Js, mj))
                opti.subject_to(opti.bounded(-mj, (base + d1 * uR) / Js, mj))
            if self.midpoints:
                # the joint a and j at each interval's midpoint too (see _Piece.midpoints)
                hk = h[n0:n1] / 2
                sk = sm[n0:n1] + vk[:-1] * hk + ak[:-1] * hk ** 2 / 2 + uk * hk ** 3 / 6
                SM = ca.fmin(ca.fmax(sk, self.s0), self.s1).T
                vm, am = v_mid[n0:n1], ak[:-1] + uk * hk
                for i in range(3):
                    e1 = fns["q1"][i].map(n - 1)(SM).T
                    e2 = fns["q2"][i].map(n - 1)(SM).T
                    e3 = fns["q3"][i].map(n - 1)(SM).T
                    opti.subject_to(opti.bounded(-ma, (e2 * vm ** 2 + e1 * am) / As, ma))
                    opti.subject_to(opti.bounded(-mj, (e3 * vm ** 3 + 3 * e2 * vm * am + e1 * uk) / Js, mj))
        opti.minimize(ca.dot(ca.DM(np.asarray(Ns, float) * np.asarray(h0s)), eta) / float(np.sum(np.asarray(Ns) * np.asarray(h0s))))
        opti.set_initial(eta, np.ones(len(Ns)))
        opti.set_initial(sig, (S0 - self.s0) / L)
        opti.set_initial(nu, V0 / Vs)
        opti.set_initial(al, A0 / As)
        opti.set_initial(mu, U0 / Js)
        opti.solver("ipopt", {"print_time": False},
                    {"print_level": IPOPT_PRINT_LEVEL, "max_iter": max_iter, "tol": 1e-8, "acceptable_tol": 1e-6,
                     "sb": "yes", "mu_strategy": "adaptive"})
        try:
            sol = opti.solve()
            stats = sol.stats()
            val = sol.value
        except RuntimeError as e:
            stats = opti.stats()
            if stats.get("return_status") not in ("Solved_To_Acceptable_Level", "Maximum_Iterations_Exceeded"):
                raise PlanningError(f"optimal: IPOPT failed on piece s = {self.s0:.6g}…{self.s1:.6g} mm: "
                                    f"{stats.get('return_status', e)}") from None
            val = opti.debug.value
        hh = np.asarray(val(h)).ravel()
        out = (hh, np.asarray(val(s)).ravel(), np.asarray(val(v)).ravel(),
               np.asarray(val(a)).ravel(), np.asarray(val(u)).ravel())
        return out, stats.get("return_status", "?"), int(stats.get("iter_count", -1))


def _warm_start(prof, bounds, node_period_s, max_nodes, stretch=1.15):
    """Phase sizes, interval durations and nodes from a profile (the warm start) on one piece,
    slowed down by `stretch`.  ``bounds`` = [s0, joins…, s1]."""
    t = prof.t
    sgrid, idx = np.unique(prof.s, return_index=True)
    tb = np.interp(bounds, sgrid, t[idx])
    D = np.maximum(np.diff(tb), 4 * prof.T)
    Ns = np.clip(np.ceil(D * stretch / node_period_s).astype(int), MIN_PHASE_NODES, None)
    if Ns.sum() > max_nodes:
        Ns = np.maximum(MIN_PHASE_NODES, (Ns * max_nodes / Ns.sum()).astype(int))
    tt = np.concatenate([np.linspace(tb[k], tb[k] + D[k], Ns[k] + 1)[:-1] for k in range(len(Ns))]
                        + [[tb[-1]]])
    S = np.interp(tt, t, prof.s)
    S[0], S[-1] = bounds[0], bounds[-1]
    V = np.interp(tt, t, prof.sd) / stretch
    V[0] = V[-1] = 0.0
    hs = D * stretch / Ns
    H = np.repeat(hs, Ns)
    A = np.zeros_like(V)
    A[1:-1] = (V[2:] - V[:-2]) / (H[1:] + H[:-1])
    U = np.diff(A) / H
    return Ns, hs, S, V, A, U


class _CubicSpans:
    """The piecewise-cubic solutions joined end to end: one piece of `Profile.from_pieces`,
    evaluated by span index; s and ṡ floored at 0 (a solver's rounding below rest)."""

    s0 = 0.0

    def __init__(self, pieces_sol):
        knots_t, S, V, A, U = [], [], [], [], []
        t0 = 0.0
        for (h, s, v, a, u) in pieces_sol:
            knots_t.append(t0 + np.concatenate([[0.0], np.cumsum(h)[:-1]]))
            S.append(s[:-1]); V.append(v[:-1]); A.append(a[:-1]); U.append(u)
            t0 += float(np.sum(h))
        self.kt = np.concatenate(knots_t)
        self.S, self.V, self.A, self.U = (np.concatenate(x) for x in (S, V, A, U))
        self.duration = t0

    def at(self, tt):
        k = np.clip(np.searchsorted(self.kt, tt, side="right") - 1, 0, len(self.kt) - 1)
        tau = tt - self.kt[k]
        S, V, A, U = self.S[k], self.V[k], self.A[k], self.U[k]
        s = S + V * tau + A * tau ** 2 / 2 + U * tau ** 3 / 6
        sd = V + A * tau + U * tau ** 2 / 2
        return np.maximum(s, 0.0), np.maximum(sd, 0.0), A + U * tau, U.copy()


def sample_cubic(pieces_sol, T, path, info) -> Profile:
    """Join the piecewise-cubic solutions and sample at exact multiples of T."""
    prof = Profile.from_pieces("optimal", T, [_CubicSpans(pieces_sol)], path, info)
    prof.sd[0] = prof.sdd[0] = 0.0
    return prof


def plan(path, machine, limits=None, *, margin: float = 0.005, node_period_s: float = 1e-3,
         max_nodes_per_piece: int = 600, warm=None, warm_stretch: float = 1.02,
         retries: int = 3) -> Profile:
    """Minimum-time jerk-limited reference (CasADi + IPOPT), warm-started from ``warm`` (a
    Profile; default the `scurve_joint` plan) slowed down by ``warm_stretch``."""
    from planners.verify import command_metrics, worst_sample

    t0 = time.perf_counter()
    limits = machine.limits if limits is None else limits
    check_limits(limits, "optimal")
    check_path(path, "optimal")
    T = machine.servo_period_s
    table = PathTable(path, machine)
    cap = table_feed_cap(path, table, limits, T)
    joins = join_jumps(path, table, machine)
    pcs = rest_pieces(path)
    for g, (s0, s1) in enumerate(pcs):
        # node budget (issue 17): every phase between G1 joins needs MIN_PHASE_NODES, so a piece
        # of many short blended chords outgrew any budget (a 44 s piece of a CAM-like kossel
        # program: 830 phases, 20 000 nodes) and IPOPT ran for hours: refused before the warm start
        # (the seed) is planned
        phases = 1 + sum(1 for sj, _ in joins if s0 + 1e-6 < sj < s1 - 1e-6)
        if phases * MIN_PHASE_NODES > MAX_NODES_REFINED:
            la, lb = (int(x) for x in path.line_at(np.array([s0, s1])))
            where = f", G-code lines {la}…{lb}" if la >= 0 and lb >= 0 else ""
            raise PlanningError(f"optimal: piece {g} (s = {s0:.6g}…{s1:.6g} mm{where}) has {phases} phases "
                                f"between G1 joins, needing {phases * MIN_PHASE_NODES} nodes "
                                f"({MIN_PHASE_NODES} a phase): over the node budget of "
                                f"{MAX_NODES_REFINED} nodes a piece")
    if warm is None:
        from .scurve import plan_joint
        warm = plan_joint(path, machine, limits)
    problems, starts, bounds = [], [], []
    budgets = [max_nodes_per_piece] * len(pcs)
    for s0, s1 in pcs:
        piece = _Piece(table, cap, s0, s1, limits, margin, joins, T)
        bounds.append([s0] + [sj for sj, _ in piece.joins] + [s1])
        problems.append(piece)
        starts.append(_warm_start(warm, bounds[-1], node_period_s, max_nodes_per_piece, warm_stretch))
    for attempt in range(retries + 1):
        sols, statuses, nxt = [], [], []
        for piece, (Ns, hs, S, V, A, U) in zip(problems, starts):
            sol, status, iters = piece.solve(Ns, hs, S, V, A, U)
            sols.append(sol)
            statuses.append(f"{status} ({iters} it)")
            hh = sol[0]
            nxt.append((Ns, hh[np.cumsum(Ns) - 1], sol[1], sol[2], sol[3], sol[4]))
        margins = [dict(p.margins) for p in problems]
        prof = sample_cubic(sols, T, path, {"pieces": len(pcs), "ipopt": statuses,
                                            "margin": max(max(m.values()) for m in margins),
                                            "margins": margins, "midpoints": [p.midpoints for p in problems],
                                            "nodes": [int(np.sum(x[0])) for x in starts],
                                            "g1_joins": len(joins)})
        r = command_metrics(machine, path.point(prof.s), T, prof.s)
        if r["feasible"] and r["cartesian_peak_ratio"].get("feed", 0) <= 1 + 1e-6:
            break
        if attempt == retries:
            order, i, ratio = worst_sample(machine.ik(path.point(prof.s)), T, limits.joint)
            raise PlanningError(f"optimal: solution breaks a limit at T even with margins up to "
                                f"{prof.info['margin']:g}: joint "
                                f"{order} {ratio:.4g} × its limit in the window from s = {prof.s[i]:.6g} mm "
                                f"(t = {prof.t[i]:.6g} s); joint peak ratios "
                                f"{ {k: round(v, 4) for k, v in r['joint_peak_ratio'].items()} }, feed / F_max "
                                f"{r['cartesian_peak_ratio'].get('feed', 0):.6g}; IPOPT per piece: "
                                f"{', '.join(statuses)}")
        # the limits hold at the nodes only: where the node budget spread a piece's grid
        # ≥ THIN_GRID_FACTOR times thinner than node_period_s, a grid twice as fine comes before a
        # larger margin, which costs time everywhere.  Warm-started from the feasible seed again:
        # from this solution (on the limits at the old nodes, off them between) IPOPT took
        # > 4 min on test_part's first piece at 1200 nodes, from the seed 29 s
        thin = [sum(st[1] * st[0]) / sum(st[0]) >= THIN_GRID_FACTOR * node_period_s
                and budgets[i] < MAX_NODES_REFINED for i, st in enumerate(starts)]
        if any(thin):
            for i, b in enumerate(bounds):
                if thin[i]:
                    budgets[i] = min(2 * budgets[i], MAX_NODES_REFINED)
                    nxt[i] = _warm_start(warm, b, node_period_s, budgets[i], warm_stretch)
        else:
            # only the limits read above 1, only in the pieces where they were: a doubled margin,
            # and an a or j bounded between the nodes too where the grid was not refined (a
            # refined grid is dense; test_part's refined pieces read above 1 at a blend join,
            # where the midpoints do not help, and with them IPOPT took > 5 min)
            broken = broken_limits(machine, path, prof, pcs, limits) or {
                (g, kind) for g in range(len(pcs)) for kind in LIMIT_KINDS}
            for g, kind in broken:
                problems[g].margins[kind] *= 2
                if kind in ("acceleration", "jerk") and budgets[g] == max_nodes_per_piece:
                    problems[g].midpoints = True
        starts = nxt
    prof.planning_time_s = time.perf_counter() - t0
    return prof
