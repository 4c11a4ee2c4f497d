"""KEOPS-Delta paper (Erwinski, Karasek, Živanović, Dimić, Slavković 2022), Figs. 5 and 6:
the s-curve FLF profile of the bird under Cartesian limits 1000 mm/s, 10 000 mm/s², 5·10⁵ mm/s³
(ε = 1 µm), its Cartesian v/a/j within the limits (Fig. 5) and the linear axes after the IK
beyond them (Fig. 6); the same joint panel for pso, which plans under the joint limits."""
from __future__ import annotations

from pathlib import Path

import numpy as np

import planners
from harness.report.figures import pyplot, save
from kins import load_machine
from planners.constraints import PathTable, corner_list, join_jumps
from planners.paths import resolve_path
from planners.verify import command_metrics, differences

ORDERS = (("velocity", "mm/s", "v"), ("acceleration", "mm/s²", "a"), ("jerk", "mm/s³", "j"))


def _panels(plt, title, t, D, lim, labels):
    fig, axes = plt.subplots(3, 1, figsize=(9, 7.5), sharex=True)
    for ax, (order, unit, key) in zip(axes, ORDERS):
        d = D[order]
        tt = t[-len(d):]
        for k, lab in enumerate(labels):
            ax.plot(tt, d[:, k], lw=0.9, label=lab)
        L = getattr(lim, key)
        ax.axhline(L, color="k", ls="--", lw=1, label="limit")
        ax.axhline(-L, color="k", ls="--", lw=1)
        ax.set_ylabel(f"{order} ({unit})")
    axes[0].set_title(title)
    axes[0].legend(loc="upper right", fontsize=8, ncol=4)
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    return fig


def figures(out: Path, path_name: str = "bird", pso: bool = True) -> dict:

    plt = pyplot()
    m = load_machine("keops")
    T = m.servo_period_s
    path = resolve_path(path_name)
    result = {}
    for name in ("scurve", "pso") if pso else ("scurve",):
        prof = planners.plan(name, path, m)
        P = prof.path.point(prof.s)
        Q = m.ik(P)
        met = command_metrics(m, P, T, prof.s)
        result[name] = {"execution_time_s": prof.execution_time_s,
                        "cartesian": met["cartesian_peak_ratio"], "joint": met["joint_peak_ratio"]}
        t = prof.t
        if name == "scurve":   # Fig. 5: feed profile and the Cartesian axes
            fig, ax = plt.subplots(figsize=(9, 3))
            ax.plot(t, prof.sd, label=f"{name} feed ṡ")
            ax.axhline(m.limits.feed_max, color="k", ls="--", lw=1, label="F_max")
            ax.set(xlabel="time (s)", ylabel="feed (mm/s)", title=f"Fig. 5a — {name} feed profile, keops / {path_name}")
            ax.legend(fontsize=8)
            fig.tight_layout()
            save(fig, out, f"keops_fig5a_{name}_feed", {"t_s": t, "feed_mm_s": prof.sd})
            D = differences(P, T, rest=False)
            fig = _panels(plt, f"Fig. 5 — {name}: Cartesian axes (limits dashed), keops / {path_name}", t, D,
                          m.limits.cartesian, ["x", "y", "z"])
            save(fig, out, f"keops_fig5_{name}_cartesian",
                 {"t_s": t, **{f"{o}_{a}": D[o][:, k] for o, _, _ in ORDERS for k, a in enumerate("xyz")}})
        D = differences(Q, T, rest=False)
        fig = _panels(plt, f"Fig. 6 — {name}: linear axes after the IK (joint limits dashed), keops / {path_name}",
                      t, D, m.limits.joint, ["q1", "q2", "q3"])
        save(fig, out, f"keops_fig6_{name}_joints",
             {"t_s": t, **{f"{o}_q{k + 1}": D[o][:, k] for o, _, _ in ORDERS for k in range(3)}})
    return result


def feed_over_arc_length(out: Path, path_name: str = "bird") -> dict:
    """The swarm and its polish against the jerk-limited optimum: the feed of scurve_joint (pso's
    seed), pso (the swarm alone), pso_socp (the swarm polished) and optimal over arc length, all within the
    joint limits. Returns the execution times and, per stretch between corners and G1 joins,
    how the swarm alone compares with the optimum (the numbers REPORT.md quotes)."""

    plt = pyplot()
    m = load_machine("keops")
    path = resolve_path(path_name)
    s = np.linspace(0.0, path.length, int(path.length / 0.25) + 1)
    cols, result, profs = {"s_mm": s}, {}, {}
    fig, ax = plt.subplots(figsize=(10, 3.6))
    for name, planner, options in (("scurve_joint", "scurve_joint", {}), ("pso", "pso", {}),
                                   ("pso_socp", "pso_socp", {}), ("optimal", "optimal", {})):
        prof = planners.plan(planner, path, m, **options)
        profs[name] = prof
        result[name] = prof.execution_time_s
        cols[f"{name}_feed_mm_s"] = np.interp(s, prof.s, prof.sd)
        ax.plot(s, cols[f"{name}_feed_mm_s"], lw=1, label=f"{name}: {prof.execution_time_s:.4f} s")
    ax.set(xlabel="arc length s (mm)", ylabel="feed ṡ (mm/s)",
           title=f"keops / {path_name}: feed over arc length, every profile within the joint limits")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save(fig, out, f"keops_{path_name}_feed_over_s", cols)
    return {"execution_time_s": result, **_stretches(path, m, profs, s, cols)}


def _stretches(path, m, profs, s, cols) -> dict:
    """pso's swarm alone against the optimum on each stretch between the path's ends, corners and
    G1 joins: its time in excess and its peak-feed shortfall, in %, and the seed's highest feed."""

    joins = [sj for sj, _ in join_jumps(path, PathTable(path, m), m)]
    bounds = sorted([0.0, path.length] + corner_list(path) + joins)

    def time_at(prof, x):
        sg, i = np.unique(prof.s, return_index=True)
        return np.interp(x, sg, prof.t[i])

    excess, gap, peaks = [], [], []
    for a, b in zip(bounds[:-1], bounds[1:]):
        dt = {n: float(time_at(profs[n], b) - time_at(profs[n], a)) for n in ("pso", "optimal")}
        inside = (s > a) & (s < b)
        if dt["optimal"] <= 0 or not inside.any():
            continue
        excess.append(100 * (dt["pso"] - dt["optimal"]) / dt["optimal"])
        fp, fo = cols["pso_feed_mm_s"][inside].max(), cols["optimal_feed_mm_s"][inside].max()
        gap.append(100 * (fo - fp) / fo)
        peaks.append((float(fo), float(fp), float(s[inside][np.argmax(cols["optimal_feed_mm_s"][inside])])))
    top = max(peaks)
    return {"joins_mm": joins, "stretch_excess_pct": [min(excess), max(excess)],
            "peak_shortfall_pct": [min(gap), max(gap)],
            "top_peak": {"optimal_mm_s": top[0], "pso_mm_s": top[1], "s_mm": top[2]},
            "seed_peak_mm_s": float(cols["scurve_joint_feed_mm_s"].max())}
