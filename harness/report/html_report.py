"""One self-contained HTML report a person opens (`pkmbench report`): no server, plotly.js inlined.

Sections: the comparison table (per machine × path × case), the performance profile over every
case of the sweep (Dolan & Moré, Math. Program. 91, 2002: ρ_p(τ) = share of cases where planner
p's execution time ≤ τ × the best planner's there; a failed run never counts), feed over arc
length and the worst joint-limit ratio over arc length per planner (from each run's
command.csv), and the nightly trend per metric from the ci runs of the results store, with the
runs where a metric was out of tolerance marked.

Deterministic: same sweep and store ⇒ the same bytes (plot ids are numbered, not random).
"""
from __future__ import annotations

import html
import math
from collections import defaultdict
from pathlib import Path

import numpy as np

from harness import perfprofile
from harness.corpus.analysis import load_reference, reference_cell, reference_for

TABLE_HEAD_COLOUR = "#1f3b5c"    # tests/test_html_report.py finds the table in a screenshot by it
MAX_POINTS = 1500                # per trace: the report stays a few MB
TREND_METRICS = ("execution_time_s", "joint_peak_ratio.jerk", "planning_time_ratio")


def _case(r) -> tuple:
    return (r["machine"], r["path"], r["preset"], r["variation"], r["seed"])


def _profile_runs(rows: list[dict], worst: bool | None = None):
    """(case, planner, T or None) per run for harness.perfprofile: a case is machine × path ×
    preset × variation (the seeds are runs of it); T only for a joint-feasible profile. With
    ``worst`` True/False: each planner's worst/best seed per case alone (the spread band)."""
    out = {}
    for r in rows:
        m = r["metrics"] or {}
        et = m.get("execution_time_s") if r["status"] == "ok" and m.get("feasible") else None
        t = et if et and et > 0 else None
        key = (_case(r)[:4], r["planner"])
        if worst is None:
            out.setdefault(key, []).append(t)
            continue
        v = math.inf if t is None else t
        old = out.get(key, [None])[0]
        ov = math.inf if old is None else old
        if key not in out or (v > ov if worst else v < ov):
            out[key] = [t]
    return [("/".join(map(str, c)), p, t) for (c, p), ts in out.items() for t in ts]


def _references(rows: list[dict]) -> dict:
    """case → T_reference_s of the cases whose path is a corpus path on its machine."""
    ref = load_reference()
    out = {}
    for r in rows:
        got = reference_for(r["machine"], r["path"], ref)
        if got:
            out["/".join(map(str, _case(r)[:4]))] = got[0]
    return out


def _thin(*arrays, n=MAX_POINTS):
    k = max(1, math.ceil(len(arrays[0]) / n))
    return [a[::k] for a in arrays]


def along_path(run_dir: Path, machine) -> dict | None:
    """s, feed and the worst joint ratio (max over joints and v/a/j of |derivative| / limit) per
    sample of a run's command.csv; None without one."""
    f = Path(run_dir) / "command.csv"
    if not f.exists():
        return None
    d = np.loadtxt(f, delimiter=",", skiprows=1, ndmin=2)
    if len(d) < 4:
        return None
    T = machine.servo_period_s
    P, Q = d[:, 1:4], d[:, 4:7]
    step = np.linalg.norm(np.diff(P, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(step)])
    feed = np.concatenate([[0.0], step / T])
    lim = machine.limits.joint
    worst = np.zeros(len(Q))
    for order, L in ((1, lim.v), (2, lim.a), (3, lim.j)):
        r = np.abs(np.diff(Q, order, axis=0)).max(axis=1) / T**order / L
        worst[order:] = np.maximum(worst[order:], r)
    return {"s": s, "feed": feed, "worst": worst}


def _fig_html(fig, div_id: str, first: bool) -> str:
    return fig.to_html(full_html=False, include_plotlyjs="inline" if first else False, div_id=div_id,
                       config={"displaylogo": False, "responsive": True})


def _f(v, fmt="{:.4g}") -> str:
    return "—" if v is None else fmt.format(v)


def write_html(rows: list[dict], out: Path, *, title: str, reference: str = "optimal",
               machine_of=None, history=None) -> dict:
    """Write the report to ``out``; returns what it holds ({"tables", "plots", "trend_runs"}).

    ``machine_of(row)`` → the row's kins machine (for the joint limits), ``history`` a
    harness.ci.history.History or None.
    """
    doc = _Doc()
    groups = defaultdict(list)
    for r in rows:
        groups[(r["machine"], r["path"], r["preset"], r["variation"])].append(r)
    _comparison(doc, rows, groups, reference)
    _profile_section(doc, rows)
    _along_path_section(doc, groups, machine_of)
    trend_runs = _trend_section(doc, history)
    Path(out).write_text(doc.html(title))
    return {"tables": len(groups), "plots": doc.plots, "trend_runs": trend_runs}


class _Doc:
    """The report's HTML parts in order; plots numbered as added, plotly.js inlined in the first."""

    def __init__(self):
        self.parts: list[str] = []
        self.plots = 0

    def add(self, fig, name: str) -> None:
        self.parts.append(_fig_html(fig, f"plot-{self.plots:02d}-{name}", self.plots == 0))
        self.plots += 1

    def html(self, title: str) -> str:
        style = ("body{font-family:sans-serif;max-width:1200px;margin:auto;padding:0 1em}"
                 "table{border-collapse:collapse;margin-bottom:1em}"
                 f"th{{background:{TABLE_HEAD_COLOUR};color:white;padding:4px 8px;font-size:13px}}"
                 "td{border:1px solid #ccc;padding:2px 8px;font-size:13px;text-align:right}"
                 "tr.bad td{background:#fde8e8}")
        return ("<!doctype html>\n<html><head><meta charset='utf-8'>"
                f"<title>{html.escape(title)}</title><style>{style}</style></head><body>\n"
                f"<h1>{html.escape(title)}</h1>\n" + "\n".join(self.parts) + "\n</body></html>\n")


def _comparison(doc: _Doc, rows, groups, reference: str) -> None:
    """The run counts and one table per machine × path × preset × variation."""
    parts = doc.parts
    n_ok = sum(r["status"] == "ok" for r in rows)
    parts.append(f"<p>{len(rows)} runs, {n_ok} ok, {len(rows) - n_ok} failed. Joint ratios: peak "
                 f"|derivative| / limit on the commanded joints (feasible ⇔ all ≤ 1). ÷ best: execution "
                 f"time over the fastest planner's on the same case; ÷ {html.escape(reference)}: over "
                 f"{html.escape(reference)}'s.</p>")
    cols = ["planner", "seed", "execution time s", "÷ best", f"÷ {reference}", "÷ T_ref", "feasible", "joint v", "joint a",
            "joint j", "following µm", "contour µm", "planning s", "status"]
    parts.append("<h2>Comparison</h2>")
    refs = load_reference()
    for key in sorted(groups):
        t_ref = reference_for(key[0], key[1], refs)
        rs = sorted(groups[key], key=lambda r: (r["planner"], r["seed"]))
        t = {(r["seed"], r["planner"]): r["metrics"]["execution_time_s"] for r in rs if r["status"] == "ok"}
        parts.append(f"<h3>{html.escape(' / '.join(map(str, key)))}</h3><table class='comparison'><tr>"
                     + "".join(f"<th>{html.escape(c)}</th>" for c in cols) + "</tr>")
        for r in rs:
            cells = _cells(r, t, reference, t_ref)
            cls = " class='bad'" if r["status"] != "ok" or not (r["metrics"] or {}).get("feasible") else ""
            parts.append(f"<tr{cls}>" + "".join(f"<td>{html.escape(c)}</td>" for c in cells) + "</tr>")
        parts.append("</table>")


def _cells(r, t: dict, reference: str, t_ref=None) -> list[str]:
    """One run's table cells; ``t``: (seed, planner) → execution time of the case's ok runs;
    ``t_ref``: (T_reference_s, error_s) of a corpus path."""
    if r["status"] != "ok":
        return [r["planner"], str(r["seed"])] + ["—"] * 11 + [f"FAILED: {r['error']}"]
    m = r["metrics"]
    jp = m.get("joint_peak_ratio", {})
    et = m["execution_time_s"]
    best = min(v for (sd, _), v in t.items() if sd == r["seed"])
    ref = t.get((r["seed"], reference))
    return [r["planner"], str(r["seed"]), _f(et), _f(et / best, "{:.3f}"),
            _f(et / ref if ref else None, "{:.3f}"), reference_cell(et, t_ref), "yes" if m.get("feasible") else "NO",
            _f(jp.get("velocity"), "{:.3f}"), _f(jp.get("acceleration"), "{:.3f}"),
            _f(jp.get("jerk"), "{:.3f}"), _f(m.get("max_following_error_um")),
            _f(m.get("max_contour_error_um")), _f(m.get("planning_time_s"), "{:.3g}"), "ok"]


def _profile_section(doc: _Doc, rows) -> None:
    """The performance profile of harness.perfprofile (the corpus's too): joint-feasible runs
    only, against the converged reference where the case is a corpus path; a planner with
    several seeds per case as the ECDF of its runs, its best-to-worst-seed band shaded."""
    import plotly.graph_objects as go

    ref = _references(rows)
    runs = _profile_runs(rows)
    cases = list(dict.fromkeys(c for c, _, _ in runs))
    R = perfprofile.run_ratios(runs, ref)
    tau = perfprofile.tau_grid(R)
    prof = perfprofile.performance_profile(runs, tau, ref)
    multi = {p for p, by in R.items() if any(len(v) > 1 for v in by.values())}
    lo = perfprofile.performance_profile(_profile_runs(rows, worst=True), tau, ref) if multi else {}
    hi = perfprofile.performance_profile(_profile_runs(rows, worst=False), tau, ref) if multi else {}
    doc.parts.append(f"<h2>Performance profile</h2><p>Over {len(cases)} case(s): the share of cases in which a "
                     f"planner's joint-feasible execution time is within τ × the case's denominator "
                     f"(Dolan &amp; Moré 2002): the converged minimum time on the {len(ref)} corpus case(s), "
                     f"else the fastest joint-feasible run; a run that breaks the joint limits never counts. "
                     f"A planner run over several seeds is the share of its runs (as COCO's ECDFs), "
                     f"shaded from its worst to its best seed. Higher and further left is better.</p>")
    traces = []
    for n, p in enumerate(sorted(prof)):
        colour = f"hsl({(n * 67) % 360},60%,45%)"
        if p in multi:
            traces.append(go.Scatter(x=tau, y=lo[p], mode="lines", line_shape="hv", line=dict(width=0, color=colour),
                                     showlegend=False, hoverinfo="skip"))
            traces.append(go.Scatter(x=tau, y=hi[p], mode="lines", line_shape="hv", line=dict(width=0, color=colour),
                                     fill="tonexty", opacity=0.2, name=f"{p} best–worst seed"))
        traces.append(go.Scatter(x=tau, y=prof[p], name=p, mode="lines", line_shape="hv", line=dict(color=colour)))
    fig = go.Figure(traces)
    fig.update_layout(xaxis_title="τ (execution time ÷ best)", yaxis_title="ρ(τ)", yaxis_range=[0, 1.05],
                      height=380, margin=dict(t=30))
    doc.add(fig, "profile")


def _along_path_section(doc: _Doc, groups, machine_of) -> None:
    """Per case: feed and the worst joint ratio over arc length of each ok run with files."""
    import plotly.graph_objects as go
    doc.parts.append("<h2>Along the path</h2>")
    for key in sorted(groups):
        curves = {}
        for r in sorted(groups[key], key=lambda r: (r["planner"], r["seed"])):
            if r["status"] == "ok" and r.get("run_dir") and machine_of is not None:
                c = along_path(Path(r["run_dir"]), machine_of(r))
                if c is not None:
                    curves[f"{r['planner']}" + (f" s{r['seed']}" if r["seed"] else "")] = c
        if not curves:
            continue
        from plotly.subplots import make_subplots
        fig = make_subplots(rows=2, cols=1, shared_xaxes=True, vertical_spacing=0.08,
                            subplot_titles=("feed over arc length", "worst joint ratio (v, a, j ÷ limit)"))
        for i, (name, c) in enumerate(curves.items()):
            s, feed, worst = _thin(c["s"], c["feed"], c["worst"])
            colour = f"hsl({(i * 360) // max(len(curves), 1)},65%,45%)"
            fig.add_trace(go.Scatter(x=s, y=feed, name=name, legendgroup=name, line_color=colour), 1, 1)
            fig.add_trace(go.Scatter(x=s, y=np.maximum(worst, 1e-6), name=name, legendgroup=name,
                                     showlegend=False, line_color=colour), 2, 1)
        fig.add_hline(y=1.0, line_dash="dash", line_color="black", row=2, col=1)
        fig.update_yaxes(title_text="feed mm/s", row=1, col=1)
        fig.update_yaxes(title_text="ratio", type="log", row=2, col=1)
        fig.update_xaxes(title_text="arc length s, mm", row=2, col=1)
        fig.update_layout(height=560, margin=dict(t=40), title_text=" / ".join(map(str, key)))
        doc.add(fig, "path")


def _trend_section(doc: _Doc, history) -> int:
    """The ci runs' values of TREND_METRICS, out-of-tolerance ones marked; the number of runs."""
    import plotly.graph_objects as go
    doc.parts.append("<h2>Nightly trend</h2>")
    runs = history.runs() if history is not None else []
    if not runs:
        doc.parts.append("<p>No ci runs in the results store yet (`pkmbench ci` appends them).</p>")
        return 0
    doc.parts.append(f"<p>{len(runs)} ci runs; a red ✕ marks a value out of tolerance in that run.</p>")
    names = set(history.metric_names())
    for metric in [m for m in TREND_METRICS if m in names]:
        fig = go.Figure()
        for entry, pts in sorted(history.series_marked(metric).items()):
            fig.add_trace(go.Scatter(x=[p[0] for p in pts], y=[p[1] for p in pts], name=entry, mode="lines+markers"))
            bad = [p for p in pts if p[2]]
            if bad:
                fig.add_trace(go.Scatter(x=[p[0] for p in bad], y=[p[1] for p in bad], mode="markers",
                                         name=f"{entry}: regression", marker=dict(symbol="x", size=13, color="red")))
        fig.update_layout(title_text=metric, xaxis_title="ci run #", height=360, margin=dict(t=40))
        doc.add(fig, "trend")
    return len(runs)
