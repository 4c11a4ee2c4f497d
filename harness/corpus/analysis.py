"""What the corpus's rows say: the converged reference of each path (benchmarks/paths/corpus/
reference.json), each run's ratio to it (and to the best run), the performance profile
(harness.perfprofile, the one implementation the HTML report uses too) and the per-planner
summary, a stochastic planner's as the distribution over its seeds (median, inter-quartile
range, best and worst).

A run counts only with a joint-feasible profile of its own (status "ok" and feasible): a time
that breaks the joint limits, or that came from another planner (a fallback), neither counts
for its planner nor sets a path's best.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from harness import perfprofile
from harness.corpus.run import CORPUS_DIR, CorpusError, Row, load_manifest

REFERENCE = CORPUS_DIR / "reference.json"


def load_reference(file=REFERENCE) -> dict[str, tuple[float, float]]:
    """path name → (T_reference_s, error_s); empty when the file is missing or unreadable
    (the tables then leave the reference columns empty)."""
    try:
        d = json.loads(Path(file).read_text())
    except (OSError, json.JSONDecodeError):
        return {}
    out = {}
    for name, r in (d.get("paths") or {}).items():
        try:
            T, e = float(r["T_reference_s"]), float(r["error_s"])
        except (KeyError, TypeError, ValueError):
            continue
        if math.isfinite(T) and T > 0 and math.isfinite(e):
            out[name] = (T, e)
    return out


def reference_for(machine: str, path: str, reference: dict | None = None) -> tuple[float, float] | None:
    """(T_reference_s, error_s) of a sweep's or a report's (machine, path) when the path is a
    corpus path (its file stem a manifest name) on its own machine, else None."""
    name = Path(str(path)).stem
    reference = load_reference() if reference is None else reference
    if name not in reference:
        return None
    try:
        machines = {e["name"]: e["machine"] for e in load_manifest()}
    except CorpusError:
        return None
    return reference[name] if machines.get(name) == machine else None


def reference_cell(T, ref) -> str:
    """A table cell: T / T_reference ± the reference's error bar (as a ratio); '—' without
    a reference or a time."""
    if not ref or not T:
        return "—"
    q = T / ref[0]
    return f"{q:.4f} ± {q * ref[1] / ref[0]:.1g}"


def counts(r: Row) -> bool:
    """A run whose time counts: its own profile, joint-feasible."""
    return r.status == "ok" and r.feasible


def runs(rows: list[Row]):
    """(path, planner, T or None) per row, for harness.perfprofile."""
    return [(r.path, r.planner, r.execution_time_s if counts(r) else None) for r in rows]


def best_times(rows: list[Row]) -> dict[str, float]:
    """Per path, the shortest execution time of a run that counts (inf if none)."""
    best: dict[str, float] = {}
    for r in rows:
        best.setdefault(r.path, math.inf)
        if counts(r):
            best[r.path] = min(best[r.path], r.execution_time_s)
    return best


def below_reference(rows: list[Row], reference: dict) -> dict[str, dict]:
    """path → {"T_reference_s", "error_s", "best_s", "planner"} where a run that counts (its own
    profile, within the joint limits at T) is faster than T_reference by more than its error bar:
    there the reference is not the optimum but an upper estimate of it (its refinement study
    extrapolates from grids outside their asymptotic range, or its joins' reads, held whatever the
    samples' phase, are stricter than the check at T), and ratios to it flatter every planner."""
    out: dict = {}
    for r in rows:
        ref = reference.get(r.path)
        if not ref or not counts(r) or not r.execution_time_s < ref[0] - ref[1]:
            continue
        if r.path not in out or r.execution_time_s < out[r.path]["best_s"]:
            out[r.path] = {"T_reference_s": ref[0], "error_s": ref[1], "best_s": r.execution_time_s,
                           "planner": r.planner}
    return dict(sorted(out.items()))


def ratios(rows: list[Row], reference: dict | None = None) -> dict[str, dict[str, float]]:
    """planner → path → T/T_best (T/T_reference where ``reference`` has the path); ∞ when the
    run does not count; a planner with several runs on a path (seeds): their median."""
    ref = {k: v[0] for k, v in (reference or {}).items()}
    R = perfprofile.run_ratios(runs(rows), ref)
    return {k: {p: float(np.median(v)) for p, v in by.items()} for k, by in R.items()}


def performance_profile(rows: list[Row], taus, reference: dict | None = None) -> dict[str, np.ndarray]:
    """planner → ρ(τ) (harness.perfprofile: a stochastic planner's runs as an ECDF)."""
    ref = {k: v[0] for k, v in (reference or {}).items()}
    return perfprofile.performance_profile(runs(rows), taus, ref)


def spread(values) -> dict:
    """median, q1, q3 (inter-quartile range), best (min), worst (max) of ``values`` (∞ = a run
    that does not count: it sorts last, as the worst)."""
    v = np.asarray(list(values), float)
    if len(v) == 0:
        return {"median": math.nan, "q1": math.nan, "q3": math.nan, "best": math.nan, "worst": math.nan, "n": 0}
    q1, med, q3 = (float(x) for x in np.quantile(v, [0.25, 0.5, 0.75], method="linear")) \
        if np.isfinite(v).all() else _inf_quantiles(v)
    return {"median": med, "q1": q1, "q3": q3, "best": float(v.min()), "worst": float(v.max()), "n": len(v)}


def _inf_quantiles(v):
    """Quantiles by order statistics where some values are ∞ (np.quantile would give NaN)."""
    s = np.sort(v)
    pick = lambda q: float(s[min(len(s) - 1, int(math.floor(q * (len(s) - 1) + 0.5)))])
    return pick(0.25), pick(0.5), pick(0.75)


def to_reference(r: Row, reference: dict) -> float:
    """T / T_reference of a row (NaN without a time or a reference)."""
    ref = reference.get(r.path)
    return r.execution_time_s / ref[0] if ref and r.status in ("ok", "fallback") and math.isfinite(r.execution_time_s) else math.nan


def seed_spread(rows: list[Row], reference: dict) -> dict[tuple[str, str], dict]:
    """(path, planner) → spread of T/T_reference (T/T_best without a reference) over the seeds
    of a stochastic planner's runs (a run that does not count: ∞)."""
    best = best_times(rows)
    groups: dict = {}
    for r in rows:
        if r.seed is None:
            continue
        den = reference[r.path][0] if r.path in reference else best[r.path]
        groups.setdefault((r.path, r.planner), []).append(r.execution_time_s / den if counts(r) and math.isfinite(den) else math.inf)
    return {k: spread(v) for k, v in groups.items()}


def swarm_spread(rows: list[Row], reference: dict) -> dict[str, dict]:
    """planner → spread of its swarm's own time (info["swarm_time_s"]: pso_socp's before its
    polish) over T_reference (T_best without one), over every run of a planner that reports a
    swarm; a run without a swarm profile within the limits at T is ∞."""
    best = best_times(rows)
    out: dict = {}
    for k in dict.fromkeys(r.planner for r in rows if math.isfinite(r.swarm_time_s)):
        q = []
        for r in rows:
            if r.planner != k:
                continue
            den = reference[r.path][0] if r.path in reference else best[r.path]
            q.append(r.swarm_time_s / den if math.isfinite(r.swarm_time_s) and math.isfinite(den) else math.inf)
        out[k] = spread(q)
    return out


def summary(rows: list[Row], reference: dict | None = None) -> dict[str, dict]:
    """Per planner: paths, runs, profiles, joint-feasible, Cartesian-feasible, own limits
    (None: declares none), failed (incl. fallbacks), fallbacks, errors, T/T_best median / worst
    over its counted runs, the spread of T/T_reference over every run (∞ = does not count),
    median / worst planning time."""
    reference = reference or {}
    R = perfprofile.run_ratios(runs(rows))
    Rref = perfprofile.run_ratios(runs(rows), {k: v[0] for k, v in reference.items()})
    out = {}
    for k in dict.fromkeys(r.planner for r in rows):
        mine = [r for r in rows if r.planner == k]
        rr = [x for v in R[k].values() for x in v if math.isfinite(x)]
        ref_runs = [x for p, v in Rref[k].items() if p in reference for x in v]
        pt = [r.planning_time_s for r in mine if math.isfinite(r.planning_time_s)]
        own = [r.own_limits_ok for r in mine]
        out[k] = {"paths": len({r.path for r in mine}), "runs": len(mine),
                  "seeds": len({r.seed for r in mine if r.seed is not None}),
                  "profiles": sum(r.status == "ok" for r in mine),
                  "feasible": sum(counts(r) for r in mine),
                  "cartesian_feasible": sum(r.status == "ok" and r.cartesian_feasible for r in mine),
                  "own_limits": None if all(o is None for o in own) else sum(bool(o) for o in own),
                  "failed": sum(r.status in ("failed", "fallback") for r in mine),
                  "fallbacks": sum(r.status == "fallback" for r in mine),
                  "errors": sum(r.status == "error" for r in mine),
                  "ratio_median": float(np.median(rr)) if rr else math.nan,
                  "ratio_worst": float(max(rr)) if rr else math.nan,
                  "to_reference": spread(ref_runs),
                  "plan_median_s": float(np.median(pt)) if pt else math.nan,
                  "plan_worst_s": float(max(pt)) if pt else math.nan}
    return out
