"""Running the corpus: the manifest, the selection, and a row per (path, planner, seed) from
plan + the independent check at T (planners.verify.command_metrics).

A row carries the execution time, joint feasibility, worst joint and Cartesian peak ratios,
planning time, and the error when the planner returned no profile. A planner that fails is a
row with its error and the others go on; an exception other than PlanningError is a defect of
the planner and is recorded as ``internal error: …`` (never a traceback). A profile that came
from another planner (info["source"] naming one: `optimal`'s fallback to `scurve_joint`) is the
row's failure, status "fallback". A stochastic planner (planners.registry.stochastic) runs
once per seed 0 … seeds − 1.
"""
from __future__ import annotations

import fnmatch
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import planners
from kins import load_machine
from kins.resources import REPO
from planners import registry
from planners.paths import resolve_path
from planners.verify import command_metrics, within

CORPUS_DIR = REPO / "benchmarks" / "paths" / "corpus"
MANIFEST = CORPUS_DIR / "manifest.json"
FAST_PLANNERS = ("trapezoid", "scurve", "scurve_joint")
# --quick: one small path per machine × the fast planners (the part `make test` runs)
QUICK_PATHS = ("rand_planar_kossel", "rand_3d_weights_keops", "contour_lcnc")
SEEDS = 10                  # runs of a stochastic planner per path (issue 32: a distribution)


class CorpusError(ValueError):
    """Bad corpus input (manifest, path glob, planner name): the message names it."""


@dataclass
class Row:
    path: str
    machine: str
    kind: str
    planner: str
    status: str = "ok"               # ok | failed (PlanningError) | error (any other exception) | fallback
    execution_time_s: float = math.nan
    feasible: bool = False           # joint v/a/j within limits at T
    cartesian_feasible: bool = False  # Cartesian v/a/j within the Cartesian limits at T
    joint_v: float = math.nan
    joint_a: float = math.nan
    joint_j: float = math.nan
    cart_v: float = math.nan
    cart_a: float = math.nan
    cart_j: float = math.nan
    feed: float = math.nan
    planning_time_s: float = math.nan
    lower_bound_s: float = math.nan   # a planner's own bound on the optimum (optimal: info["lower_bound_s"])
    swarm_time_s: float = math.nan    # pso: its swarm alone, before the polish (info["swarm_time_s"])
    error: str = ""
    seed: int | None = None           # the seed of a stochastic planner's run, else None
    source: str = ""                  # info["source"]: where the profile came from, if the planner says
    extra: dict = field(default_factory=dict)

    def ratio(self, space: str, order: str) -> float:
        cols = {("joint", "velocity"): self.joint_v, ("joint", "acceleration"): self.joint_a,
                ("joint", "jerk"): self.joint_j, ("cartesian", "velocity"): self.cart_v,
                ("cartesian", "acceleration"): self.cart_a, ("cartesian", "jerk"): self.cart_j,
                ("cartesian", "feed"): self.feed}
        return cols[(space, order)]

    @property
    def own_limits_ok(self) -> bool | None:
        """Within every limit the planner declares it keeps (planners.registry.guarantees);
        None when it declares none (trapezoid, linuxcnc: nothing they keep was measured)."""
        g = registry.guarantees(self.planner)
        if not g:
            return None
        if self.status != "ok":
            return False
        return all(within(self.ratio(space, o)) for space, orders in g.items() for o in orders)

    @property
    def key(self) -> tuple:
        """What the row answers (run_corpus, harness.corpus.journal)."""
        return row_key(self.path, self.machine, self.planner, self.seed)

    @property
    def joint_worst(self) -> float:
        return max(self.joint_v, self.joint_a, self.joint_j)

    @property
    def cart_worst(self) -> float:
        return max(self.cart_v, self.cart_a, self.cart_j)


def row_key(path: str, machine: str, planner: str, seed: int | None) -> tuple:
    return (path, machine, planner, seed)


def load_manifest(file=MANIFEST) -> list[dict]:
    try:
        d = json.loads(Path(file).read_text())
    except OSError as e:
        raise CorpusError(f"{file}: cannot read the corpus manifest: {e.strerror}") from None
    except json.JSONDecodeError as e:
        raise CorpusError(f"{file}: line {e.lineno}: invalid JSON: {e.msg}") from None
    entries = d.get("paths") if isinstance(d, dict) else None
    if not isinstance(entries, list):
        raise CorpusError(f"{file}: no 'paths' list")
    for i, e in enumerate(entries):
        for key in ("name", "file", "machine", "kind"):
            if not isinstance(e, dict) or key not in e:
                raise CorpusError(f"{file}: paths[{i}] lacks '{key}'")
    return entries


def select(entries: list[dict], globs: str | None = None, quick: bool = False) -> list[dict]:
    """Entries whose name (or file) matches one of the comma-separated globs; --quick: QUICK_PATHS."""
    if quick and not globs:
        globs = ",".join(QUICK_PATHS)
    if not globs:
        return list(entries)
    pats = [g.strip() for g in globs.split(",") if g.strip()]
    out = [e for e in entries if any(fnmatch.fnmatch(e["name"], p) or fnmatch.fnmatch(e["file"], p) for p in pats)]
    if not out:
        raise CorpusError(f"--paths {globs}: matches no corpus path (names: {', '.join(e['name'] for e in entries)})")
    return out


def finite(x) -> float:
    return float(x) if x is not None and np.isfinite(x) else math.nan


def run_one(entry: dict, planner: str, machine, path, seed: int | None = None) -> Row:
    """Plan ``planner`` (with ``seed`` when given) on a loaded path and check its profile;
    never raises for a planner's failure (the row carries the error)."""

    row = Row(entry["name"], entry["machine"], entry.get("kind", "-"), planner, seed=seed)
    t0 = time.perf_counter()
    try:
        prof = planners.plan(planner, path, machine, **({} if seed is None else {"seed": seed}))
    except planners.PlanningError as e:
        row.status, row.error = "failed", f"{entry['name']}: {e}"
        row.planning_time_s = time.perf_counter() - t0
        return row
    except Exception as e:                   # a defect of the planner: recorded, not raised
        row.status, row.error = "error", f"{entry['name']}: internal error {type(e).__name__}: {e}"
        row.planning_time_s = time.perf_counter() - t0
        return row
    row.planning_time_s = float(prof.planning_time_s)
    row.lower_bound_s = finite((prof.info or {}).get("lower_bound_s"))
    row.swarm_time_s = finite((prof.info or {}).get("swarm_time_s"))
    T = machine.servo_period_s
    try:
        met = command_metrics(machine, prof.points(), T, prof.s)
    except Exception as e:                   # the profile leaves the workspace
        row.status, row.error = "error", f"{entry['name']}: check failed: {type(e).__name__}: {e}"
        return row
    j, c = met["joint_peak_ratio"], met["cartesian_peak_ratio"]
    row.execution_time_s = float(met["execution_time_s"])
    row.joint_v, row.joint_a, row.joint_j = (finite(j[k]) for k in ("velocity", "acceleration", "jerk"))
    row.cart_v, row.cart_a, row.cart_j = (finite(c[k]) for k in ("velocity", "acceleration", "jerk"))
    row.feed = finite(c.get("feed"))
    row.feasible = bool(met["feasible"])
    row.cartesian_feasible = bool(within(max(row.cart_v, row.cart_a, row.cart_j)))
    src = (prof.info or {}).get("source")
    row.source = str(src) if src is not None else ""
    if row.source and row.source != planner and registry.known(row.source) and not registry.is_spec(row.source):
        # the profile is another planner's (a fallback): the row reports it, as that row's failure
        row.status = "fallback"
        row.error = f"{entry['name']}: returned {row.source}'s profile (info['source']), not its own"
    return row


def run_corpus(selection: list[tuple[dict, list[str]]], progress=None, seeds: int = SEEDS,
               kept: dict | None = None, keep=None) -> list[Row]:
    """Every (entry, planners) of the selection, serially (planning-time measurements stay
    comparable), a stochastic planner once per seed 0 … seeds − 1. A path that cannot be
    loaded gives one failed row per planner. ``kept``: (path, machine, planner, seed) → a Row
    of an interrupted run (harness.corpus.journal), used instead of planning again; ``keep``
    is called with each row planned here as it ends."""

    rows, machines, kept = [], {}, kept or {}
    for entry, names in selection:
        mname = entry["machine"]
        todo = [(name, seed) for name in names for seed in (range(seeds) if registry.stochastic(name) else [None])]
        keys = [row_key(entry["name"], mname, name, seed) for name, seed in todo]
        if all(k in kept for k in keys):
            rows += [kept[k] for k in keys]
            continue
        try:
            m = machines.get(mname) or machines.setdefault(mname, load_machine(mname))
            f = Path(entry["file"])
            f = f if f.is_absolute() else CORPUS_DIR / f
            path = resolve_path(str(f), home=m.home)
        except Exception as e:               # MachineFileError, PathError: name the path
            for name in names:
                rows.append(Row(entry["name"], mname, entry.get("kind", "-"), name, "failed",
                                error=f"{entry['name']}: cannot load: {e}"))
            continue
        for (name, seed), k in zip(todo, keys):
            row = kept.get(k)
            if row is None:
                row = run_one(entry, name, m, path, seed)
                if keep:
                    keep(row)
                if progress:
                    progress(row)
            rows.append(row)
    return rows
