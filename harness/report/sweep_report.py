"""The report of a sweep (`pkmbench report SWEEP_DIR`): Markdown and HTML comparison of a sweep, with plots.

    pkmbench report results/sweeps/nightly            # → SWEEP_DIR/report/report.md, report.html, *.png

One table per machine × path (× preset × variation when the sweep has several): per planner
and seed the execution time, its ratio to `optimal` (when the sweep ran it on the same
case), feasibility, worst joint peak ratios (v / a / j), following and contour error,
planning time; failed tasks with their error. Under each table a plot: execution time and
worst joint ratio per planner.
"""
from __future__ import annotations

from collections import defaultdict
from pathlib import Path

from harness.ci.history import History
from harness.corpus.analysis import load_reference, reference_cell, reference_for
from harness.report.html_report import write_html
from harness.sweep import TaskTable
from kins import load_machine
from kins.resources import REPO
from planners.verify import within

COLUMNS = ["planner", "seed", "execution time s", "÷ optimal", "÷ T_ref", "feasible", "joint v", "joint a",
           "joint j", "following µm", "contour µm", "planning s", "status"]


def _f(v, fmt="{:.4g}") -> str:
    return "—" if v is None else fmt.format(v)


def build(rows: list[dict], reference: str) -> list[dict]:
    """Groups of table rows: [{"title", "key", "rows": [[cells]], "plot": {...}}]; a corpus
    path on its machine gets T / T_reference (benchmarks/paths/corpus/reference.json)."""
    refs = load_reference()
    multi_case = len({(r["preset"], r["variation"]) for r in rows}) > 1
    groups = defaultdict(list)
    for r in rows:
        key = (r["machine"], r["path"]) + ((r["preset"], r["variation"]) if multi_case else ())
        groups[key].append(r)
    out = []
    for key in sorted(groups):
        rs = sorted(groups[key], key=lambda r: (r["planner"], r["seed"]))
        ref_time = {(r["preset"], r["variation"], r["seed"]): r["metrics"]["execution_time_s"]
                    for r in rs if r["planner"] == reference and r["status"] == "ok"}
        table, plot = [], {"planner": [], "time": [], "worst": []}
        t_ref = reference_for(key[0], key[1], refs)
        for r in rs:
            m = r["metrics"] or {}
            if r["status"] != "ok":
                table.append([r["planner"], str(r["seed"])] + ["—"] * 10 + [f"FAILED: {r['error']}"])
                continue
            jp = m.get("joint_peak_ratio", {})
            ref = ref_time.get((r["preset"], r["variation"], r["seed"]))
            et = m.get("execution_time_s")
            table.append([r["planner"], str(r["seed"]), _f(et), _f(et / ref if ref and et else None, "{:.3f}"),
                          reference_cell(et, t_ref), "yes" if m.get("feasible") else "**no**",
                          _f(jp.get("velocity"), "{:.3f}"), _f(jp.get("acceleration"), "{:.3f}"),
                          _f(jp.get("jerk"), "{:.3f}"), _f(m.get("max_following_error_um")),
                          _f(m.get("max_contour_error_um")), _f(m.get("planning_time_s"), "{:.3g}"), "ok"])
            plot["planner"].append(f"{r['planner']}" + (f"/s{r['seed']}" if len({x['seed'] for x in rs}) > 1 else ""))
            plot["time"].append(et or 0.0)
            plot["worst"].append(max(jp.values()) if jp else 0.0)
        title = " / ".join(key)
        out.append({"title": title, "key": key, "rows": table, "plot": plot})
    return out


def _plot(group: dict, file: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    p = group["plot"]
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(9, 2.8))
    a1.bar(p["planner"], p["time"], color="tab:blue")
    a1.set_ylabel("execution time, s")
    a2.bar(p["planner"], p["worst"], color=["tab:green" if within(w) else "tab:red" for w in p["worst"]])
    a2.axhline(1.0, color="k", lw=0.8, ls="--")
    if p["worst"] and min(p["worst"]) > 0 and max(p["worst"]) / min(p["worst"]) > 20:
        a2.set_yscale("log")                 # a jerk ratio of 600 would flatten the feasible ones
    a2.set_ylabel("worst joint peak ratio")
    for a in (a1, a2):
        a.tick_params(axis="x", labelrotation=30, labelsize=7)
        a.grid(axis="y", alpha=0.3)
    fig.suptitle(group["title"], fontsize=9)
    fig.tight_layout()
    fig.savefig(file, dpi=100, metadata={"Software": None})
    plt.close(fig)


class ReportError(ValueError):
    """The folder holds no sweep results; the message names it."""


def write_report(sweep: Path, out: Path, reference: str = "optimal", results_store=None) -> tuple[int, int]:
    """report.md with a groupNN.png per table, and report.html (one self-contained interactive
    file: harness/report/html_report.py, the nightly trend from the results store ``results_store``,
    default the default store) of the sweep in ``sweep`` into ``out``; returns (tables, runs).
    ReportError if ``sweep`` holds no results."""
    sweep, out = Path(sweep), Path(out)
    db = sweep / "results.sqlite"
    if not db.exists():
        raise ReportError(f"{sweep}: not a sweep folder (no results.sqlite); run `pkmbench sweep` first")
    out.mkdir(parents=True, exist_ok=True)
    with TaskTable(db) as store:
        rows = store.to_rows()
    if not rows:
        raise ReportError(f"{db}: the sweep has no results")
    # several code versions of one task: keep the last stored (rowid order = completion order)
    latest = {}
    for r in rows:
        latest[(r["machine"], r["path"], r["planner"], r["seed"], r["preset"], r["variation"])] = r
    groups = build(list(latest.values()), reference)
    n_ok = sum(r["status"] == "ok" for r in latest.values())
    md = [f"# pkmbench sweep report — `{sweep}`", "",
          f"{len(latest)} runs, {n_ok} ok, {len(latest) - n_ok} failed. Joint ratios are peak "
          f"|derivative| / limit on the commanded joints (feasible ⇔ all ≤ 1 + 1e-6); "
          f"÷ optimal is the execution time over `{reference}`'s on the same case; ÷ T_ref over the "
          f"path's converged minimum time (corpus paths: benchmarks/paths/corpus/reference.json), "
          f"± its error bar.", ""]
    for i, g in enumerate(groups):
        png = f"group{i:02d}.png"
        _plot(g, out / png)
        md += [f"## {g['title']}", "", "| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
        md += ["| " + " | ".join(c.replace("|", "\\|") for c in row) + " |" for row in g["rows"]]
        md += ["", f"![{g['title']}]({png})", ""]
    (out / "report.md").write_text("\n".join(md) + "\n")

    def machine_of(r):
        """The run's own (varied) machine file, which the task wrote to inputs/, else the suite's."""
        mine = sorted(Path(r["run_dir"], "inputs").glob("*.toml"))
        f = mine[0] if mine else Path(r["task"]["machine_file"])
        return load_machine(str(f if f.is_absolute() or mine else REPO / f))

    rows = [r | {"run_dir": str(sweep / r["run_dir"]) if r["run_dir"] else None} for r in latest.values()]
    with History(results_store) as h:
        write_html(rows, out / "report.html", title=f"pkmbench report — {sweep.name}", reference=reference,
                   machine_of=machine_of, history=h)
    return len(groups), len(latest)
