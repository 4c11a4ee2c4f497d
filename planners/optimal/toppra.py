"""`toppra` — time-optimal path parametrisation by reachability analysis (TOPP-RA).

Pham & Pham, "A new approach to time-optimal path parameterization based on reachability
analysis", IEEE T-RO 2018; the `toppra` library.  The constraint set shared with `pso` and
`optimal`: joint velocity and acceleration limits (no jerk limit) and the feed caps
(F_max and the chord-error cap F_clim of TII 2022).  Without a jerk limit this is a lower
bound on the execution time of every profile that meets those limits.

The path is split at exact-stop corners (the feed is zero there); each piece is handed to
toppra as a 4-dof geometric path (q₁, q₂, q₃, s) over arc length: the joints carry the joint
limits, the fourth coordinate (q₄ = s, q₄′ = 1) carries the varying feed cap as a velocity
limit.  toppra returns ṡ on a grid; between grid points s̈ is constant (ṡ² linear in s),
which gives s(t) in closed form for sampling at T.
"""
from __future__ import annotations

import time

import numpy as np
import toppra
import toppra.algorithm as algo
import toppra.constraint as constraint

from planners.constraints import (PathTable, PlanningError, check_limits, check_path, feed_cap, rest_pieces,
                                  station_grid)
from planners.profile import Profile

toppra.setup_logging("ERROR")   # a failed interpolation-scheme try is handled below

# The fourth coordinate q₄ = s needs an acceleration bound too (toppra applies one to every
# coordinate); 100·A never binds while some joint has |q′| > 0.01, and a finite bound keeps
# the reachability LPs well conditioned (1e12 made them fail).
S_ACC_FACTOR = 100.0
# Where joints move alike on part of a piece (a vertical move of a linear delta), their
# constraint rows coincide and toppra's 2-D LP solver fails; bounds apart by 1e-9 relative
# (far below any tolerance that matters) make the rows parallel but not coincident.
ROW_STAGGER = 1.0 - 1e-9 * np.arange(3)


class _PieceGeometry(toppra.interpolator.AbstractGeometricPath):
    """Joints and arc length of one corner-to-corner piece, read from a PathTable."""

    def __init__(self, table: PathTable, s0: float, s1: float, joints=(0, 1, 2)):
        self.table, self.s0, self.s1 = table, s0, s1
        self.cols = list(joints)

    def __call__(self, ss, order=0):
        ss = np.asarray(ss, float)
        scalar = ss.ndim == 0
        s = np.clip(np.atleast_1d(ss), self.s0 + 1e-9, self.s1 - 1e-9)   # one-sided at corners
        if order == 0:
            out = np.column_stack([self.table.joint_positions(s)[:, self.cols], s])
        else:
            d = self.table.joints(s)[order - 1]
            last = np.ones(len(s)) if order == 1 else np.zeros(len(s))
            out = np.column_stack([d[:, self.cols], last])
        return out[0] if scalar else out

    @property
    def dof(self):
        return len(self.cols) + 1

    @property
    def path_interval(self):
        return np.array([self.s0, self.s1])


def solve_grid(path, machine, limits, table: PathTable, grid_mm: float):
    """TOPP-RA on each piece: (s grid, ṡ on it, pieces solved by collocation) for the whole
    path, ṡ = 0 at corners."""
    T = machine.servo_period_s
    vj, aj = limits.joint.v, limits.joint.a
    S, SD, fallbacks = [], [], []
    for k, (s0, s1) in enumerate(rest_pieces(path)):
        # the stations: every join of the path's segments on the grid
        grid = station_grid(table.edges[(table.edges >= s0 - 1e-12) & (table.edges <= s1 + 1e-12)],
                            grid_mm, s0, s1)
        # joints that move identically on this piece (e.g. a vertical move of a linear delta)
        # give identical constraint rows, which toppra's LP solver cannot handle: keep one
        e = np.clip(grid, s0 + 1e-9, s1 - 1e-9)
        P1, P2, _ = table.cartesian(e)
        cap = feed_cap(path, grid, limits, T, kappa=np.linalg.norm(np.cross(P1, P2), axis=1))
        d1, d2, _ = table.joints(e)
        keep = []
        for i in range(3):
            if not any(np.allclose(d1[:, i], d1[:, j], rtol=0, atol=1e-9) and
                       np.allclose(d2[:, i], d2[:, j], rtol=0, atol=1e-9) for j in keep):
                keep.append(i)
        # a joint that moves exactly like s (|q′| = 1, q″ = 0) duplicates the s coordinate:
        # fold its limits into that coordinate's
        s_acc = S_ACC_FACTOR * aj
        like_s = [i for i in keep if np.allclose(np.abs(d1[:, i]), 1, rtol=0, atol=1e-9)
                  and np.allclose(d2[:, i], 0, rtol=0, atol=1e-9)]
        if like_s:
            keep = [i for i in keep if i not in like_s]
            cap = np.minimum(cap, vj)
            s_acc = aj
        geo = _PieceGeometry(table, s0, s1, keep)
        nj = len(keep)

        def vlim(s, grid=grid, cap=cap):
            c = float(np.interp(s, grid, cap))
            return np.vstack([np.outer(ROW_STAGGER[:nj], [-vj, vj]), [[-c, c]]])

        sd = None
        # the interpolation scheme is the more accurate; at some joins (a vertical move into a
        # tiny blend arc) its reachability LP fails, and collocation still solves
        for scheme in (constraint.DiscretizationType.Interpolation, constraint.DiscretizationType.Collocation):
            cons = [constraint.JointVelocityConstraintVarying(vlim),
                    constraint.JointAccelerationConstraint(
                        np.vstack([np.outer(ROW_STAGGER[:nj], [-aj, aj]), [[-s_acc, s_acc]]]),
                        discretization_scheme=scheme)]
            inst = algo.TOPPRA(cons, geo, gridpoints=grid, parametrizer="ParametrizeConstAccel")
            sdd, sd, _, _ = inst.compute_parameterization(0.0, 0.0, return_data=True)
            if sd is not None and np.all(np.isfinite(sd)):
                break
            fallbacks.append(k)
        if sd is None or not np.all(np.isfinite(sd)):
            raise PlanningError(f"toppra: no feasible parametrisation of piece {k} "
                                f"(s = {s0:.6g}…{s1:.6g} mm)")
        sd = np.maximum(np.asarray(sd, float), 0.0)
        sd[0] = sd[-1] = 0.0
        S.append(grid if k == 0 else grid[1:])
        SD.append(sd if k == 0 else sd[1:])
    return np.concatenate(S), np.concatenate(SD), fallbacks


class _ConstAccelGrid:
    """s(t) with constant s̈ between grid points (ṡ² linear in s): the whole grid as one piece of
    `Profile.from_pieces`, evaluated by span index."""

    s0 = 0.0

    def __init__(self, s_grid, sd_grid):
        ds = np.diff(s_grid)
        self.s_grid, self.v0, v1 = s_grid, sd_grid[:-1], sd_grid[1:]
        self.dt = 2 * ds / np.maximum(self.v0 + v1, 1e-300)
        self.acc = (v1 * v1 - self.v0 * self.v0) / (2 * ds)
        self.starts = np.concatenate([[0.0], np.cumsum(self.dt)])
        self.duration = float(self.starts[-1])

    def at(self, tt):
        k = np.clip(np.searchsorted(self.starts, tt, side="right") - 1, 0, len(self.dt) - 1)
        tau = np.clip(tt - self.starts[k], 0.0, self.dt[k])
        v0, acc = self.v0[k], self.acc[k]
        return self.s_grid[k] + v0 * tau + acc * tau * tau / 2, v0 + acc * tau, acc.copy(), np.zeros_like(tau)


def sample_const_accel(s_grid, sd_grid, T, path, planner, info) -> Profile:
    """s(t) with constant s̈ between grid points (ṡ² linear in s), sampled at multiples of T."""
    return Profile.from_pieces(planner, T, [_ConstAccelGrid(s_grid, sd_grid)], path, info)


def plan(path, machine, limits=None, *, grid_mm: float = 0.25) -> Profile:
    """TOPP-RA reference: joint v, a limits and the feed caps (a lower bound on time)."""
    t0 = time.perf_counter()
    limits = machine.limits if limits is None else limits
    check_limits(limits, "toppra")
    check_path(path, "toppra")
    table = PathTable(path, machine)
    s_grid, sd_grid, fallbacks = solve_grid(path, machine, limits, table, grid_mm)
    prof = sample_const_accel(s_grid, sd_grid, machine.servo_period_s, path, "toppra",
                              {"grid_points": int(len(s_grid)), "pieces": len(rest_pieces(path)),
                               "collocation_pieces": fallbacks})
    prof.planning_time_s = time.perf_counter() - t0
    return prof
