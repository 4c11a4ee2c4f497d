"""The corpus's outputs: corpus.csv, corpus.md, performance_profile.png (Dolan–Moré against
the converged reference, a stochastic planner's band from its best to its worst seed) and
ratio_to_reference.png. Every row shows T / T_reference with the reference's error bar
(benchmarks/paths/corpus/reference.json)."""
from __future__ import annotations

import csv
import math
from dataclasses import asdict
from pathlib import Path

import numpy as np

from harness import perfprofile
from harness.corpus.analysis import (below_reference, best_times, counts, load_reference, runs, seed_spread, summary,
                                     swarm_spread, to_reference)
from harness.corpus.run import Row

CSV_FIELDS = ("path", "machine", "kind", "planner", "seed", "status", "execution_time_s", "feasible",
              "cartesian_feasible", "joint_v", "joint_a", "joint_j", "cart_v", "cart_a", "cart_j",
              "own_limits_ok", "feed", "joint_worst", "cart_worst", "planning_time_s", "lower_bound_s",
              "swarm_time_s", "source", "error")


def _fmt(x, nd=6) -> str:
    if x is None:
        return ""
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, float):
        return "" if math.isnan(x) else (f"{x:.{nd}g}")
    return str(x)


def _ratio_best(r: Row, best: dict) -> float:
    b = best[r.path]
    return r.execution_time_s / b if r.status == "ok" and math.isfinite(b) else math.nan


def write_csv(rows: list[Row], file, reference: dict) -> None:
    best = best_times(rows)
    with open(file, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(list(CSV_FIELDS) + ["ratio_to_best", "T_reference_s", "T_reference_error_s", "ratio_to_reference"])
        for r in rows:
            d = asdict(r) | {"joint_worst": r.joint_worst, "cart_worst": r.cart_worst,
                             "own_limits_ok": r.own_limits_ok}
            ref = reference.get(r.path, (math.nan, math.nan))
            w.writerow([_fmt(d[k], 10) if k != "error" else d[k] for k in CSV_FIELDS]
                       + [_fmt(_ratio_best(r, best), 10), _fmt(ref[0], 10), _fmt(ref[1], 3),
                          _fmt(to_reference(r, reference), 10)])


def _ref_cell(r: Row, reference: dict) -> str:
    """T/T_ref ± the reference's bar (as a ratio), '' without one."""
    q = to_reference(r, reference)
    if math.isnan(q):
        return ""
    return f"{q:.4f} ± {q * reference[r.path][1] / reference[r.path][0]:.1g}"


def write_markdown(rows: list[Row], file, reference: dict, title="Toolpath corpus") -> None:
    S = summary(rows, reference)
    best = best_times(rows)
    npaths = len(best)
    nref = sum(p in reference for p in best)
    L = [f"# {title}", "",
         f"{npaths} paths × {len(S)} planners; plan + the independent check at T "
         "(planners.verify.command_metrics). feasible = joint v/a/j ≤ limit (1 + 1e-6). "
         f"T/T_ref = execution time over the path's converged minimum time ({nref} of {npaths} paths "
         "have one: benchmarks/paths/corpus/reference.json, ± its error bar); T/T_best = over the "
         "shortest joint-feasible run on that path. A run counts only with a joint-feasible profile of "
         "its own: a fallback (a profile from another planner, info['source']) is its row's failure.", "",
         "own limits = within what the planner declares it keeps (planners.registry.guarantees; "
         "'—': it declares nothing). A stochastic planner (planners.registry.stochastic) runs once per "
         "seed; its T/T_ref columns are the spread over all its runs (a run that does not count: ∞).", "",
         "| planner | runs | profiles | joint-feasible | Cartesian-feasible | own limits | failed | of which fallbacks | "
         "internal errors | T/T_ref median | IQR | best | worst | T/T_best median | worst | planning s median | worst |",
         "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for k, s in S.items():
        q = s["to_reference"]
        own = "—" if s["own_limits"] is None else str(s["own_limits"])
        runs_ = f"{s['runs']}" + (f" ({s['seeds']} seeds)" if s["seeds"] else "")
        L.append(f"| {k} | {runs_} | {s['profiles']} | {s['feasible']} | {s['cartesian_feasible']} | {own} | "
                 f"{s['failed']} | {s['fallbacks']} | {s['errors']} | {_fmt(q['median'], 4)} | "
                 f"{_fmt(q['q1'], 4)}–{_fmt(q['q3'], 4)} | {_fmt(q['best'], 4)} | {_fmt(q['worst'], 4)} | "
                 f"{_fmt(s['ratio_median'], 4)} | {_fmt(s['ratio_worst'], 4)} | "
                 f"{_fmt(s['plan_median_s'], 3)} | {_fmt(s['plan_worst_s'], 3)} |")
    if reference:
        errs = [reference[p][1] / reference[p][0] for p in best if p in reference]
        if errs:
            L += ["", f"The reference's error bar over these paths: {min(errs):.2g} … {max(errs):.2g} of T_ref."]
        below = below_reference(rows, reference)
        if below:
            L += ["", "Where a run that counts is faster than the reference by more than its bar, the reference is "
                      "an upper estimate of the optimum, not the optimum (T/T_ref < 1 there flatters every planner):", "",
                  "| path | T_ref ± bar (s) | fastest run (s) | planner | below T_ref |", "|---|---|---|---|---|"]
            for p, b in below.items():
                L.append(f"| {p} | {b['T_reference_s']:.5f} ± {b['error_s']:.2g} | {b['best_s']:.5f} | {b['planner']} | "
                         f"{1 - b['best_s'] / b['T_reference_s']:.2%} |")
    spreads = seed_spread(rows, reference)
    if spreads:
        L += ["", "## Stochastic planners per path (over their seeds)", "",
              "| path | planner | seeds | T/T_ref median | IQR | best | worst |", "|---|---|---|---|---|---|---|"]
        for (p, k), q in spreads.items():
            L.append(f"| {p} | {k} | {q['n']} | {_fmt(q['median'], 5)} | {_fmt(q['q1'], 5)}–{_fmt(q['q3'], 5)} | "
                     f"{_fmt(q['best'], 5)} | {_fmt(q['worst'], 5)} |")
    for k, q in swarm_spread(rows, reference).items():
        L += ["", f"{k}'s swarm alone (its own profile before any polish, info['swarm_time_s']; ∞ where it had "
                  f"none within the limits at T) over {q['n']} runs: T/T_ref median {_fmt(q['median'], 4)}, "
                  f"IQR {_fmt(q['q1'], 4)}–{_fmt(q['q3'], 4)}, best {_fmt(q['best'], 4)}, worst {_fmt(q['worst'], 4)}."]
    L += ["", "## Every row", "",
          "| path | machine | planner | seed | T (s) | T/T_ref | T/T_best | feasible | joint v/a/j | Cartesian v/a/j | "
          "plan (s) | gap to its bound | swarm alone (s) | error |",
          "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        jr = "/".join(_fmt(x, 3) for x in (r.joint_v, r.joint_a, r.joint_j)) if r.status in ("ok", "fallback") else ""
        cr = "/".join(_fmt(x, 3) for x in (r.cart_v, r.cart_a, r.cart_j)) if r.status in ("ok", "fallback") else ""
        err = r.error.replace("|", "\\|").replace("\n", " ")
        state = _fmt(r.feasible) if r.status == "ok" else f"**{r.status}**"
        L.append(f"| {r.path} | {r.machine} | {r.planner} | {_fmt(r.seed)} | {_fmt(r.execution_time_s, 5)} | "
                 f"{_ref_cell(r, reference)} | {_fmt(_ratio_best(r, best), 4)} | {state} | {jr} | {cr} | "
                 f"{_fmt(r.planning_time_s, 3)} | {_fmt(r.execution_time_s / r.lower_bound_s - 1, 4)} | "
                 f"{_fmt(r.swarm_time_s, 5)} | {err} |")
    Path(file).write_text("\n".join(L) + "\n")


def _extreme_seeds(rows: list[Row], worst: bool):
    """The runs with each stochastic planner's best (or worst) seed per path alone."""
    keep: dict = {}
    for r in rows:
        key = (r.path, r.planner)
        t = r.execution_time_s if counts(r) else math.inf
        if key not in keep or (t > keep[key][0] if worst else t < keep[key][0]):
            keep[key] = (t, r)
    return [(p, k, t if math.isfinite(t) else None) for (p, k), (t, _) in keep.items()]


def plot_performance_profile(rows: list[Row], file, reference: dict) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ref = {k: v[0] for k, v in reference.items()}
    R = perfprofile.run_ratios(runs(rows), ref)
    taus = perfprofile.tau_grid(R)
    rho = perfprofile.performance_profile(runs(rows), taus, ref)
    stoch = {r.planner for r in rows if r.seed is not None}
    lo = perfprofile.performance_profile(_extreme_seeds(rows, worst=True), taus, ref) if stoch else {}
    hi = perfprofile.performance_profile(_extreme_seeds(rows, worst=False), taus, ref) if stoch else {}
    fig, ax = plt.subplots(figsize=(7, 4.5), dpi=110)
    for n, (k, y) in enumerate(rho.items()):
        ax.step(taus, y, where="post", label=k + (" (all seeds)" if k in stoch else ""), color=f"C{n}")
        if k in stoch:
            ax.fill_between(taus, lo[k], hi[k], step="post", color=f"C{n}", alpha=0.2, lw=0)
    ax.set_xscale("log")
    ax.set_ylim(-0.02, 1.02)
    den = "T_ref" if ref else "T_best"
    ax.set_xlabel(f"τ (T / {den}, log scale)")
    ax.set_ylabel(f"share of paths with T ≤ τ · {den} (joint-feasible)")
    ax.set_title(f"Performance profile over {len(best_times(rows))} corpus paths"
                 + (" (band: best to worst seed)" if stoch else ""))
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(file, metadata={"Software": None})
    plt.close(fig)


def plot_ratio_to_reference(rows: list[Row], file, reference: dict) -> None:
    """Per path, each planner's T/T_ref (T/T_best where the path has no reference): filled =
    joint-feasible, hollow = infeasible, × on the top line = no profile or a fallback; a
    stochastic planner's seeds as a vertical bar from best to worst with its median marked."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    best = best_times(rows)
    den = {p: (reference[p][0] if p in reference else best[p]) for p in best}
    paths = list(dict.fromkeys(r.path for r in rows))
    names = list(dict.fromkeys(r.planner for r in rows))
    vals = [r.execution_time_s / den[r.path] for r in rows if r.status == "ok" and math.isfinite(den[r.path])]
    top = max(2.0, 1.15 * max(vals)) if vals else 2.0
    fig, ax = plt.subplots(figsize=(max(8, 0.32 * len(paths) + 3), 5), dpi=110)
    x = {p: i for i, p in enumerate(paths)}
    for n, k in enumerate(names):
        dx = (n - (len(names) - 1) / 2) * 0.1
        color = f"C{n}"
        by_path: dict = {}
        for r in (r for r in rows if r.planner == k):
            by_path.setdefault(r.path, []).append(r)
        for p, rs in by_path.items():
            d = den[p]
            ok = [r for r in rs if r.status == "ok" and math.isfinite(d)]
            if not ok:
                ax.plot(x[p] + dx, top, "x", color=color, ms=6)
                continue
            v = np.array([r.execution_time_s / d for r in ok])
            if len(rs) > 1:
                ax.plot([x[p] + dx] * 2, [v.min(), v.max()], "-", color=color, lw=1.5)
            feas = any(r.feasible for r in ok)
            ax.plot(x[p] + dx, float(np.median(v)), "o", ms=5, color=color, mfc=color if feas else "none")
        ax.plot([], [], "o", color=color, label=k)
    ax.axhline(1.0, color="k", lw=0.6)
    ax.set_yscale("log")
    ax.set_xticks(range(len(paths)))
    ax.set_xticklabels(paths, rotation=75, ha="right", fontsize=7)
    ax.set_ylabel("T / T_ref (filled: feasible, hollow: infeasible, ×: no profile)")
    ax.set_title("Execution time over the converged reference, per corpus path")
    ax.grid(True, axis="y", which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=min(len(names), 4), loc="upper left")
    fig.tight_layout()
    fig.savefig(file, metadata={"Software": None})
    plt.close(fig)


def write_outputs(rows: list[Row], out: Path, reference: dict | None = None) -> dict[str, Path]:
    out = Path(out)
    reference = load_reference() if reference is None else reference
    files = {"csv": out / "corpus.csv", "md": out / "corpus.md",
             "profile": out / "performance_profile.png", "ratio": out / "ratio_to_reference.png"}
    write_csv(rows, files["csv"], reference)
    write_markdown(rows, files["md"], reference)
    plot_performance_profile(rows, files["profile"], reference)
    plot_ratio_to_reference(rows, files["ratio"], reference)
    return files
