"""The toolpath corpus benchmark (issue 19): every planner on every corpus path, plan + the
independent check at T (planners.verify.command_metrics), a table and a Dolan–Moré
performance profile.

A row per (path, planner): execution time, joint feasibility, worst joint and Cartesian peak
ratios, planning time, and the error when the planner returned no profile. A planner that
fails is a row with its error and the others go on; an exception other than PlanningError is
a defect of the planner and is recorded as ``internal error: …`` (never a traceback).

Performance profile (Dolan & Moré, Math. Program. 91, 2002): with T_best(p) the shortest
execution time of a joint-feasible profile on path p, planner k's ratio on p is
r = T_k(p) / T_best(p) when its profile is feasible, ∞ otherwise; ρ_k(τ) is the fraction of
paths with r ≤ τ.
"""
from __future__ import annotations

import csv
import fnmatch
import json
import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

import planners
from harness.sweep.suite import SuiteError, suite_runs
from kins import load_machine
from kins.resources import REPO
from planners.paths import resolve_path
from planners.verify import command_metrics

CORPUS_DIR = REPO / "benchmarks" / "paths" / "corpus"
MANIFEST = CORPUS_DIR / "manifest.json"
FAST_PLANNERS = ("trapezoid", "scurve", "scurve_joint")
# --quick: one small path per machine × the fast planners (the part `make test` runs)
QUICK_PATHS = ("rand_planar_kossel", "rand_3d_weights_keops", "contour_lcnc")
# the limits each planner promises to keep (issue 19 item 5): trapezoid and LinuxCNC limit the
# Cartesian velocity and acceleration only, scurve the Cartesian v/a/j, the others the joints
OWN_LIMITS = {"trapezoid": "cartesian v/a", "linuxcnc": "cartesian v/a", "scurve": "cartesian v/a/j"}
TOL = 1e-6                  # planners.verify.FEASIBLE_TOL: a ratio ≤ 1 + 1e-6 is within its limit
CSV_FIELDS = ("path", "machine", "kind", "planner", "status", "execution_time_s", "feasible",
              "cartesian_feasible", "joint_v", "joint_a", "joint_j", "cart_v", "cart_a", "cart_j",
              "own_limits_ok", "feed", "joint_worst", "cart_worst", "planning_time_s", "lower_bound_s",
              "swarm_time_s", "error")


class CorpusError(ValueError):
    """Bad corpus input (manifest, path glob, planner name): the message names it."""


@dataclass
class Row:
    path: str
    machine: str
    kind: str
    planner: str
    status: str = "ok"               # ok | failed (PlanningError) | error (any other exception)
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
    extra: dict = field(default_factory=dict)

    @property
    def own_limits_ok(self) -> bool:
        """Within the limits this planner promises (OWN_LIMITS; default the joint v/a/j)."""
        if self.status != "ok":
            return False
        kind = OWN_LIMITS.get(self.planner, "joint v/a/j")
        if kind == "cartesian v/a":
            return max(self.cart_v, self.cart_a) <= 1 + TOL
        return self.cartesian_feasible if kind == "cartesian v/a/j" else self.feasible

    @property
    def joint_worst(self) -> float:
        return max(self.joint_v, self.joint_a, self.joint_j)

    @property
    def cart_worst(self) -> float:
        return max(self.cart_v, self.cart_a, self.cart_j)


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


def entries_from_suite(file) -> list[tuple[dict, list[str]]]:
    """(entry, planners) of every path of a suite file's [[run]] tables (corpus paths are
    described by the manifest; any other path file gets kind '-')."""
    import tomllib

    try:
        text = Path(file).read_text()
        suite = tomllib.loads(text)
        runs = suite_runs(suite, str(file), text)
    except OSError as e:
        raise CorpusError(f"{file}: cannot read suite: {e.strerror}") from None
    except (tomllib.TOMLDecodeError, SuiteError) as e:
        raise CorpusError(f"{file}: {e}") from None
    by_file = {}
    try:
        by_file = {(CORPUS_DIR / e["file"]).resolve(): e for e in load_manifest()}
    except CorpusError:
        pass
    out = []
    for machines, paths, planners_, _max_feed in runs:
        for m in machines:
            for p in paths:
                f = Path(p) if Path(p).is_absolute() else REPO / p
                e = by_file.get(f.resolve(), {"name": Path(p).stem, "file": str(f), "kind": "-"})
                out.append((dict(e, machine=m, file=str(f)), list(planners_)))
    return out


def _finite(x) -> float:
    return float(x) if x is not None and np.isfinite(x) else math.nan


def run_one(entry: dict, planner: str, machine, path) -> Row:
    """Plan ``planner`` on a loaded path and check its profile; never raises for a planner's
    failure (the row carries the error)."""

    row = Row(entry["name"], entry["machine"], entry.get("kind", "-"), planner)
    t0 = time.perf_counter()
    try:
        prof = planners.plan(planner, path, machine)
    except planners.PlanningError as e:
        row.status, row.error = "failed", f"{entry['name']}: {e}"
        row.planning_time_s = time.perf_counter() - t0
        return row
    except Exception as e:                   # a defect of the planner: recorded, not raised
        row.status, row.error = "error", f"{entry['name']}: internal error {type(e).__name__}: {e}"
        row.planning_time_s = time.perf_counter() - t0
        return row
    row.planning_time_s = float(prof.planning_time_s)
    row.lower_bound_s = _finite((prof.info or {}).get("lower_bound_s"))
    row.swarm_time_s = _finite((prof.info or {}).get("swarm_time_s"))
    T = machine.servo_period_s
    try:
        met = command_metrics(machine, prof.points(), T, prof.s)
    except Exception as e:                   # the profile leaves the workspace
        row.status, row.error = "error", f"{entry['name']}: check failed: {type(e).__name__}: {e}"
        return row
    j, c = met["joint_peak_ratio"], met["cartesian_peak_ratio"]
    row.execution_time_s = float(met["execution_time_s"])
    row.joint_v, row.joint_a, row.joint_j = (_finite(j[k]) for k in ("velocity", "acceleration", "jerk"))
    row.cart_v, row.cart_a, row.cart_j = (_finite(c[k]) for k in ("velocity", "acceleration", "jerk"))
    row.feed = _finite(c.get("feed"))
    row.feasible = bool(met["feasible"])
    row.cartesian_feasible = bool(max(row.cart_v, row.cart_a, row.cart_j) <= 1 + TOL)
    return row


def run_corpus(selection: list[tuple[dict, list[str]]], progress=None) -> list[Row]:
    """Every (entry, planners) of the selection, serially (planning-time measurements stay
    comparable). A path that cannot be loaded gives one failed row per planner."""

    rows, machines = [], {}
    for entry, names in selection:
        mname = entry["machine"]
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
        for name in names:
            row = run_one(entry, name, m, path)
            rows.append(row)
            if progress:
                progress(row)
    return rows


# -- analysis -------------------------------------------------------------------------------
def best_times(rows: list[Row]) -> dict[str, float]:
    """Per path, the shortest execution time of a joint-feasible profile (inf if none)."""
    best: dict[str, float] = {}
    for r in rows:
        best.setdefault(r.path, math.inf)
        if r.status == "ok" and r.feasible:
            best[r.path] = min(best[r.path], r.execution_time_s)
    return best


def ratios(rows: list[Row]) -> dict[str, dict[str, float]]:
    """planner → path → T/T_best (inf when infeasible, failed, or no feasible profile exists)."""
    best = best_times(rows)
    out: dict[str, dict[str, float]] = {}
    for r in rows:
        ok = r.status == "ok" and r.feasible and math.isfinite(best[r.path])
        out.setdefault(r.planner, {})[r.path] = r.execution_time_s / best[r.path] if ok else math.inf
    return out


def performance_profile(rows: list[Row], taus) -> dict[str, np.ndarray]:
    """planner → ρ(τ) at each τ: the fraction of the paths with T/T_best ≤ τ."""
    R = ratios(rows)
    paths = sorted({r.path for r in rows})
    taus = np.asarray(taus, float)
    return {k: np.array([sum(R[k].get(p, math.inf) <= t * (1 + 1e-12) for p in paths) / len(paths)
                         for t in taus]) for k in R}


def summary(rows: list[Row]) -> dict[str, dict]:
    """Per planner: paths, profiles, joint-feasible, Cartesian-feasible, failed, errors,
    median / worst T/T_best over its feasible paths, median / worst planning time."""
    R = ratios(rows)
    out = {}
    for k in dict.fromkeys(r.planner for r in rows):
        mine = [r for r in rows if r.planner == k]
        rr = [v for v in R[k].values() if math.isfinite(v)]
        pt = [r.planning_time_s for r in mine if math.isfinite(r.planning_time_s)]
        out[k] = {"paths": len(mine), "profiles": sum(r.status == "ok" for r in mine),
                  "feasible": sum(r.status == "ok" and r.feasible for r in mine),
                  "cartesian_feasible": sum(r.status == "ok" and r.cartesian_feasible for r in mine),
                  "own_limits": sum(r.own_limits_ok for r in mine),
                  "failed": sum(r.status == "failed" for r in mine),
                  "errors": sum(r.status == "error" for r in mine),
                  "ratio_median": float(np.median(rr)) if rr else math.nan,
                  "ratio_worst": float(max(rr)) if rr else math.nan,
                  "plan_median_s": float(np.median(pt)) if pt else math.nan,
                  "plan_worst_s": float(max(pt)) if pt else math.nan}
    return out


# -- output ----------------------------------------------------------------------------------
def _fmt(x, nd=6) -> str:
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, float):
        return "" if math.isnan(x) else (f"{x:.{nd}g}")
    return str(x)


def write_csv(rows: list[Row], file) -> None:
    best = best_times(rows)
    with open(file, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(list(CSV_FIELDS) + ["ratio_to_best"])
        for r in rows:
            d = asdict(r) | {"joint_worst": r.joint_worst, "cart_worst": r.cart_worst,
                             "own_limits_ok": r.own_limits_ok}
            b = best[r.path]
            ratio = r.execution_time_s / b if r.status == "ok" and math.isfinite(b) else math.nan
            w.writerow([_fmt(d[k], 10) if k != "error" else d[k] for k in CSV_FIELDS] + [_fmt(ratio, 10)])


def write_markdown(rows: list[Row], file, title="Toolpath corpus") -> None:
    S = summary(rows)
    best = best_times(rows)
    npaths = len(best)
    L = [f"# {title}", "",
         f"{npaths} paths × {len(S)} planners; plan + the independent check at T "
         "(planners.verify.command_metrics). feasible = joint v/a/j ≤ limit (1 + 1e-6); "
         "T/T_best = execution time over the shortest joint-feasible one on that path.", "",
         "own limits = within what the planner promises (trapezoid: Cartesian v/a; scurve: "
         "Cartesian v/a/j; the others: joint v/a/j).", "",
         "| planner | profiles | joint-feasible | Cartesian-feasible | own limits | failed | internal errors | "
         "T/T_best median | worst | planning s median | worst |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for k, s in S.items():
        L.append(f"| {k} | {s['profiles']}/{s['paths']} | {s['feasible']} | {s['cartesian_feasible']} | {s['own_limits']} | "
                 f"{s['failed']} | {s['errors']} | {_fmt(s['ratio_median'], 4)} | {_fmt(s['ratio_worst'], 4)} | "
                 f"{_fmt(s['plan_median_s'], 3)} | {_fmt(s['plan_worst_s'], 3)} |")
    swarm = [r for r in rows if r.status == "ok" and math.isfinite(r.swarm_time_s) and math.isfinite(best[r.path])]
    if swarm:
        q = [r.swarm_time_s / best[r.path] for r in swarm]
        L += ["", f"pso's swarm alone (before its polish, info['swarm_time_s']) on {len(swarm)} paths: "
                  f"T/T_best median {np.median(q):.4f}, worst {max(q):.4f}."]
    L += ["", "## Every row", "",
          "| path | machine | planner | T (s) | T/T_best | feasible | joint v/a/j | Cartesian v/a/j | plan (s) | "
          "gap to its bound | swarm alone (s) | error |",
          "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        b = best[r.path]
        ratio = r.execution_time_s / b if r.status == "ok" and math.isfinite(b) else math.nan
        jr = "/".join(_fmt(x, 3) for x in (r.joint_v, r.joint_a, r.joint_j)) if r.status == "ok" else ""
        cr = "/".join(_fmt(x, 3) for x in (r.cart_v, r.cart_a, r.cart_j)) if r.status == "ok" else ""
        err = r.error.replace("|", "\\|").replace("\n", " ")
        L.append(f"| {r.path} | {r.machine} | {r.planner} | {_fmt(r.execution_time_s, 5)} | {_fmt(ratio, 4)} | "
                 f"{_fmt(r.feasible) if r.status == 'ok' else r.status} | {jr} | {cr} | "
                 f"{_fmt(r.planning_time_s, 3)} | {_fmt(r.execution_time_s / r.lower_bound_s - 1, 4)} | "
                 f"{_fmt(r.swarm_time_s, 5)} | {err} |")
    Path(file).write_text("\n".join(L) + "\n")


def plot_performance_profile(rows: list[Row], file) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    R = ratios(rows)
    finite = [v for d in R.values() for v in d.values() if math.isfinite(v)]
    tmax = max(2.0, 1.1 * max(finite)) if finite else 2.0
    taus = np.geomspace(1.0, tmax, 400)
    rho = performance_profile(rows, taus)
    fig, ax = plt.subplots(figsize=(7, 4.5), dpi=110)
    for k, y in rho.items():
        ax.step(taus, y, where="post", label=k)
    ax.set_xscale("log")
    ax.set_ylim(-0.02, 1.02)
    ax.set_xlabel("τ (T / T_best, log scale)")
    ax.set_ylabel("fraction of paths with T ≤ τ · T_best (joint-feasible)")
    ax.set_title(f"Performance profile over {len(best_times(rows))} corpus paths")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(file, metadata={"Software": None})
    plt.close(fig)


def plot_ratio_to_best(rows: list[Row], file) -> None:
    """Per path, each planner's T/T_best: filled = joint-feasible, hollow = infeasible, × on
    the top line = no profile (PlanningError or error)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    best = best_times(rows)
    paths = list(dict.fromkeys(r.path for r in rows))
    names = list(dict.fromkeys(r.planner for r in rows))
    vals = [r.execution_time_s / best[r.path] for r in rows
            if r.status == "ok" and math.isfinite(best[r.path])]
    top = max(2.0, 1.15 * max(vals)) if vals else 2.0
    fig, ax = plt.subplots(figsize=(max(8, 0.32 * len(paths) + 3), 5), dpi=110)
    x = {p: i for i, p in enumerate(paths)}
    for n, k in enumerate(names):
        dx = (n - (len(names) - 1) / 2) * 0.1
        color = f"C{n}"
        for r in (r for r in rows if r.planner == k):
            b = best[r.path]
            if r.status != "ok" or not math.isfinite(b):
                ax.plot(x[r.path] + dx, top, "x", color=color, ms=6)
                continue
            v = r.execution_time_s / b
            ax.plot(x[r.path] + dx, v, "o", ms=5, color=color,
                    mfc=color if r.feasible else "none")
        ax.plot([], [], "o", color=color, label=k)
    ax.axhline(1.0, color="k", lw=0.6)
    ax.set_yscale("log")
    ax.set_xticks(range(len(paths)))
    ax.set_xticklabels(paths, rotation=75, ha="right", fontsize=7)
    ax.set_ylabel("T / T_best (filled: feasible, hollow: infeasible, ×: no profile)")
    ax.set_title("Execution time over the best joint-feasible one, per corpus path")
    ax.grid(True, axis="y", which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=min(len(names), 4), loc="upper left")
    fig.tight_layout()
    fig.savefig(file, metadata={"Software": None})
    plt.close(fig)


def write_outputs(rows: list[Row], out: Path) -> dict[str, Path]:
    out = Path(out)
    files = {"csv": out / "corpus.csv", "md": out / "corpus.md",
             "profile": out / "performance_profile.png", "ratio": out / "ratio_to_best.png"}
    write_csv(rows, files["csv"])
    write_markdown(rows, files["md"])
    plot_performance_profile(rows, files["profile"])
    plot_ratio_to_best(rows, files["ratio"])
    return files
