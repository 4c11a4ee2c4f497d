"""The best profile found, sampled at T: checked with the independent metrics, stretched where its
samples at T read above a limit, and compared with the seed it started from."""
from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import BSpline

from ..profile import Profile


@dataclass
class SplinePiece:
    """One (sub-)piece's feed ṡ(τ) = Σ Cₖ Bₖ(τ) over τ ∈ [0, 1], run in ``lam`` seconds over the arc
    [s0, s0 + L] of rest-to-rest piece ``group``; ``lam0`` its time before the check at T."""
    lam: float
    C: np.ndarray
    knots: np.ndarray
    degree: int
    s0: float
    L: float
    group: int
    lam0: float = field(default=None)

    def __post_init__(self):
        if self.lam0 is None:
            self.lam0 = self.lam

    @property
    def duration(self):
        return self.lam

    def at(self, tt):
        """(s − s0, ṡ, s̈, s⃛) at local times tt: the B-spline evaluated exactly."""
        lam = self.lam
        spl = BSpline(self.knots, self.C, self.degree)
        anti = spl.antiderivative(1)
        area = anti(1.0) - anti(0.0)
        tau = np.clip(tt / lam, 0.0, 1.0)
        kk = self.L / area
        return (kk * (anti(tau) - anti(0.0)), kk * spl(tau) / lam, kk * spl.derivative(1)(tau) / lam ** 2,
                kk * spl.derivative(2)(tau) / lam ** 3)


def stretch_at_T(pieces, groups, T, path, machine, limits, info):
    """(profile, its metrics) of the pieces sampled at T, each group (a rest-to-rest piece)
    stretched, up to 8 times, by the worst need of the samples whose time falls in it; profile
    None if still infeasible.  Mutates the pieces' λ."""
    from planners.verify import command_metrics, stretch_need
    for _ in range(8):
        prof = Profile.from_pieces("pso", T, pieces, path, info)
        r = command_metrics(machine, path.point(prof.s), T, prof.s)
        if r["feasible"] and r["cartesian_peak_ratio"]["feed"] <= 1 + 1e-6:
            return prof, r
        need = stretch_need(machine.ik(path.point(prof.s)), prof.s, T, limits)
        starts = np.concatenate([[0.0], np.cumsum([p.lam for p in pieces])])
        k = np.clip(np.searchsorted(starts, prof.t, side="right") - 1, 0, len(pieces) - 1)
        grp = np.array([p.group for p in pieces])[k]
        for g in range(groups):
            # a whole rest-to-rest piece is stretched (its sub-pieces' join feeds scale with it),
            # by the worst need of the samples whose time falls in it
            near = grp == g
            worst = float(need[near].max()) if near.any() else 0.0
            if worst > 1.0:
                for p in pieces:
                    if p.group == g:
                        p.lam *= worst * (1 + 1e-4)
    return None, r


def t_check_stretch(pieces):
    """The check at T's stretch of each rest-to-rest piece (of its first sub-piece)."""
    first = {}
    for p in pieces:
        first.setdefault(p.group, p)
    return [round(p.lam / p.lam0, 6) for p in first.values()]


def swarm_or_seed(prof, seed_prof, pieces, seed_pieces, groups, T, path, machine, limits, info):
    """The best feasible profile known: the swarm's (prof), or its seed where the swarm did not
    beat it (the swarm's constraint set carries a margin the seed's own check does not: on paths
    where the feed limit rules, as kossel's, the stretched seed ends a few ms slower)."""
    from planners.verify import command_metrics
    if seed_prof.execution_time_s >= prof.execution_time_s:
        return prof
    rs = command_metrics(machine, path.point(seed_prof.s), T, seed_prof.s)
    if rs["feasible"] and rs["cartesian_peak_ratio"]["feed"] <= 1 + 1e-6:
        return Profile("pso", T, seed_prof.s, seed_prof.sd, seed_prof.sdd, seed_prof.sddd, path,
                       info=dict(prof.info, continuous_time_s=seed_prof.info.get("continuous_time_s"),
                                 returned=f"seed ({seed_prof.planner}): the swarm's best was "
                                          f"{prof.execution_time_s:.6g} s"))
    if not seed_pieces:
        return prof
    # the seed breaks a limit at T (on CAM-like kossel programs scurve_joint reads up to 1.10 ×
    # the jerk limit), while the swarm's start, its fit stretched to the swarm's stricter sample
    # model (the continuous jerk on 0.04 mm blend arcs, the joins' T reading, the margin), can be
    # slower still: the seed's fit stretched at T by just its excess per piece is feasible too
    sp_prof, _ = stretch_at_T(seed_pieces, groups, T, path, machine, limits, info)
    if sp_prof is None:
        return prof
    mixed, pick = _per_piece_faster(pieces, seed_pieces, groups)
    mx_prof, _ = stretch_at_T(mixed, groups, T, path, machine, limits, info)
    if mx_prof is None or mx_prof.execution_time_s >= prof.execution_time_s:
        return prof
    mx_prof.info.update(
        t_check_stretch=t_check_stretch(mixed),
        pieces_from=pick,
        returned=f"per piece the swarm's best or the seed ({seed_prof.planner}) fitted "
                 f"on its switch times, each stretched at T (the seed read "
                 f"{max(rs['joint_peak_ratio'].values()):.4g} × a joint limit): "
                 f"the swarm's best alone was {prof.execution_time_s:.6g} s")
    return mx_prof


def _per_piece_faster(pieces, seed_pieces, groups):
    """(copies of the swarm's or the seed's pieces, whichever is shorter per rest-to-rest piece,
    in path order; which was picked per piece).  The fit misses the seed where switch times
    closer than MIN_KNOT_GAP_T share a knot, and reads higher there: checked at T once more."""
    dur = {}
    for name, pp in (("swarm", pieces), ("seed", seed_pieces)):
        for q in pp:
            dur[name, q.group] = dur.get((name, q.group), 0.0) + q.lam
    pick = ["seed" if dur["seed", g] < dur["swarm", g] else "swarm" for g in range(groups)]
    mixed = [copy.copy(q) for q in pieces if pick[q.group] == "swarm"] + \
            [copy.copy(q) for q in seed_pieces if pick[q.group] == "seed"]
    mixed.sort(key=lambda q: q.s0)
    return mixed, pick
