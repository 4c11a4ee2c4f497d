"""The NLP of `optimal` on one rest-to-rest piece (CasADi Opti, solved by IPOPT): its
variables, the constant-jerk dynamics, the G1-join, feed-cap and joint v/a/j constraints, the
objective.  The formulation and why it is built so: planners/optimal/planner.py's docstring."""
from __future__ import annotations

import os

import casadi as ca
import numpy as np

from planners.constraints import JUMP_READ_FACTOR, PlanningError

# IPOPT's own progress table, for diagnosing a solve: PKM_IPOPT_PRINT=5 (default 0, silent)
IPOPT_PRINT_LEVEL = int(os.environ.get("PKM_IPOPT_PRINT", "0"))

class IpoptFailure(PlanningError):
    """IPOPT stopped without a solution (neither optimal nor acceptable nor at its limit)."""


LIMIT_KINDS = ("velocity", "acceleration", "jerk", "feed")     # each with its own margin
# IPOPT's iterations per solve (a count, not a clock: the result must not depend on the machine's
# speed). From copp's start a solve that converges takes 15–90; one that does not ran > 20 min on
# a 150-control-point NURBS at 600, and its iterate then lost to the start anyway
MAX_ITER = 150
# The interpolants' grid (_phase_grid): rows closer than this are merged, and no cell is more
# than GRADE times as wide as a neighbour
MIN_GAP_MM = 1e-5
GRADE = 2.0


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
            g = _phase_grid(table.s[(table.s > a) & (table.s < b)], a, b)
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

    def solve(self, Ns, H0, S0, V0, A0, U0, max_iter=MAX_ITER):
        """Ns: intervals of each phase (the phases are separated by the G1 joins, where the
        node lies exactly on the join); H0: each interval's initial duration (a phase's
        durations scale together)."""
        L = self.s1 - self.s0
        lim = self.lim
        opti = ca.Opti()
        eta, sig, nu, al, mu, h = _variables(opti, Ns, H0)
        s = self.s0 + L * sig
        v, a, u = lim.v * nu, lim.a * al, lim.j * mu
        bounds = np.cumsum(Ns)[:-1]
        self._join_constraints(opti, bounds, sig, v, a, u)
        v_mid = self._dynamics(opti, Ns, bounds, eta, sig, nu, al, h, s, v, a, u)
        sm = ca.fmin(ca.fmax(s, self.s0), self.s1)
        starts = np.concatenate([[0], np.cumsum(Ns)])
        for k, fns in enumerate(self.phase_fns):
            self._phase_constraints(opti, fns, int(starts[k]), int(starts[k + 1]), h, sm, v, a, u, v_mid)
        D0 = np.add.reduceat(np.asarray(H0, float), np.concatenate([[0], np.cumsum(Ns)[:-1]]))
        opti.minimize(ca.dot(ca.DM(D0), eta) / float(np.sum(D0)))
        opti.set_initial(eta, np.ones(len(Ns)))
        opti.set_initial(sig, (S0 - self.s0) / L)
        opti.set_initial(nu, V0 / lim.v)
        opti.set_initial(al, A0 / lim.a)
        opti.set_initial(mu, U0 / lim.j)
        val, stats = self._run_ipopt(opti, max_iter)
        hh = np.asarray(val(h)).ravel()
        out = (hh, np.asarray(val(s)).ravel(), np.asarray(val(v)).ravel(),
               np.asarray(val(a)).ravel(), np.asarray(val(u)).ravel())
        return out, stats.get("return_status", "?"), int(stats.get("iter_count", -1))

    def _bound_factors(self):
        """1 − margin of each limit: v, a, j, feed."""
        return tuple(1 - self.margins[k] for k in LIMIT_KINDS)

    def _join_constraints(self, opti, bounds, sig, v, a, u) -> None:
        """At each G1 join (a node): its position, and the jerk of both intervals that meet
        there plus the join's jump of q″ as the check at T reads it."""
        L = self.s1 - self.s0
        Js = self.lim.j
        mj = self._bound_factors()[2]
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

    def _dynamics(self, opti, Ns, bounds, eta, sig, nu, al, h, s, v, a, u):
        """Exact constant-jerk integration, rest at both ends, s monotone, ṡ ≥ 0 at the nodes,
        the interval midpoints and, next to the joins, the quarter points; returns ṡ at the
        midpoints."""
        N = int(sum(Ns))
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
        return v_mid

    def _phase_constraints(self, opti, fns, n0, n1, h, sm, v, a, u, v_mid) -> None:
        """Nodes n0 … n1 of one phase (between G1 joins): the feed cap (nodes and midpoints),
        the joint v, a and j at the nodes (the jerk of the intervals on both sides), and a and
        j at the midpoints when ``midpoints`` is set."""
        lim = self.lim
        Vs, As, Js = lim.v, lim.a, lim.j
        mv, ma, mj, mf = self._bound_factors()
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

    def _run_ipopt(self, opti, max_iter):
        """Solve; IPOPT's acceptable level or its iteration limit still give a solution (the
        check at T decides), any other failure is an error naming the piece."""
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
                raise IpoptFailure(f"optimal: IPOPT failed on piece s = {self.s0:.6g}…{self.s1:.6g} mm: "
                                    f"{stats.get('return_status', e)}") from None
            val = opti.debug.value
        return val, stats


def _phase_grid(rows, a, b):
    """The interpolants' grid on one phase: the table's rows (refined at lobe tips), without
    rows closer than MIN_GAP_MM (the ±1e-7 mm rows at NURBS knots: a cubic B-spline through
    them overshoots), graded so that no cell is over GRADE × a neighbour (a B-spline
    interpolant rings where the spacing jumps 64×, as a refined lobe tip's does)."""
    g = np.unique(np.concatenate([[a], rows, [b], np.linspace(a, b, 4)]))
    keep = np.concatenate([[True], np.diff(g) > MIN_GAP_MM])
    keep[-1] = True
    g = g[keep]
    if len(g) > 2 and g[-1] - g[-2] <= MIN_GAP_MM:
        g = np.delete(g, -2)
    for _ in range(64):
        h = np.diff(g)
        nb = np.minimum(np.concatenate([[np.inf], h[:-1]]), np.concatenate([h[1:], [np.inf]]))
        wide = np.nonzero(h > GRADE * nb)[0]
        if len(wide) == 0:
            break
        g = np.sort(np.concatenate([g, g[wide] + h[wide] / 2]))
    return g


def _variables(opti, Ns, H0):
    """The normalised variables (IPOPT likes O(1) numbers): η = h / h0 of each phase, σ = (s −
    s0) / L, ν = ṡ / V, α = s̈ / A at the nodes, μ = s⃛ / J on the intervals; and each interval's h."""
    N = int(sum(Ns))
    eta = opti.variable(len(Ns))
    sig = opti.variable(N + 1)
    nu = opti.variable(N + 1)
    al = opti.variable(N + 1)
    mu = opti.variable(N)
    phase = np.repeat(np.arange(len(Ns)), Ns)
    sel = ca.DM(np.eye(len(Ns))[phase])             # (N × phases) picks each interval's phase
    h = (sel @ eta) * ca.DM(np.asarray(H0, float))
    return eta, sig, nu, al, mu, h
