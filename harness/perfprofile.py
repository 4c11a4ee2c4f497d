"""The Dolan–Moré performance profile, once, for every report (`pkmbench corpus` and the HTML
report of a sweep): Dolan & Moré, "Benchmarking optimization software with performance
profiles", Math. Program. 91 (2002).

A run is (case, planner, T) with T the execution time of a profile that keeps the joint limits
at T, or None (no profile, or one that breaks the joint limits: its time is no time the machine
could run, so it neither counts for its planner nor sets the best). The ratio of a run is T
over the case's denominator: the converged optimum T_reference where the case has one (the
corpus), else the shortest time of the case's runs; ∞ for None or where the case has no
denominator. A planner with several runs on a case (a stochastic planner over seeds) gives
each the weight 1/runs, as COCO's ECDFs aggregate runs: ρ_k(τ) = the share of (case, run) with
ratio ≤ τ, each case weighing 1. Every case of the runs counts, solved by someone or not.
"""
from __future__ import annotations

import math
from collections import defaultdict

import numpy as np


def run_ratios(runs, reference: dict | None = None) -> dict[str, dict]:
    """planner → case → [ratio per run] (see the module doc)."""
    runs = list(runs)
    best: dict = {}
    for case, _, T in runs:
        best.setdefault(case, math.inf)
        if T is not None and math.isfinite(T) and T > 0:
            best[case] = min(best[case], T)
    den = {c: (reference or {}).get(c) or best[c] for c in best}
    out: dict[str, dict] = defaultdict(lambda: defaultdict(list))
    for case, planner, T in runs:
        d = den[case]
        ok = T is not None and math.isfinite(T) and T > 0 and math.isfinite(d)
        out[planner][case].append(T / d if ok else math.inf)
    return {k: dict(v) for k, v in out.items()}


def performance_profile(runs, taus, reference: dict | None = None) -> dict[str, np.ndarray]:
    """planner → ρ(τ) at each τ of ``taus``."""
    runs = list(runs)
    R = run_ratios(runs, reference)
    cases = list(dict.fromkeys(c for c, _, _ in runs))
    taus = np.asarray(taus, float)
    out = {}
    for k, by_case in R.items():
        rho = np.zeros(len(taus))
        for c in cases:
            r = np.asarray(by_case.get(c, [math.inf]), float)
            rho += (r[None, :] <= taus[:, None] * (1 + 1e-12)).mean(axis=1)
        out[k] = rho / max(len(cases), 1)
    return out


def tau_grid(R: dict, n: int = 400, at_least: float = 2.0) -> np.ndarray:
    """A log grid of τ from 1 (or the smallest ratio, below 1 against a reference) to past the
    largest finite ratio of ``R`` (run_ratios)."""
    finite = [x for by_case in R.values() for rs in by_case.values() for x in rs if math.isfinite(x)]
    lo = min([1.0] + finite)
    hi = max(at_least, 1.1 * max(finite)) if finite else at_least
    return np.geomspace(lo, hi, n)
