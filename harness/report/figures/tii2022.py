"""TII 2022 table (Erwinski, Wawrzak, Paprocki, IEEE TII 18(11)): planning and execution time of
the FLF s-curve for bird and flower at F = 2500 mm/s, T = 0.25 ms, ε = 1 µm, limit set 1
(A = 10 000 mm/s², J = 60 000 mm/s³) and set 2 (A = 15 000, J = 200 000). Our bird and flower are
not the paper's curves (those are not published), so only the trend compares."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

import planners
from harness.report.figures import pyplot, save
from kins import Limits, load_machine
from planners.paths import resolve_path

PAPER = {("bird", 1): (0.608, 5.665), ("bird", 2): (0.412, 3.728),
         ("flower", 1): (1.109, 7.971), ("flower", 2): (0.778, 5.374)}
SETS = {1: (10_000.0, 60_000.0), 2: (15_000.0, 200_000.0)}
F, EPS = 2500.0, 0.001


def table(out: Path) -> dict:

    m = load_machine("keops")            # T = 0.25 ms
    rows = {}
    for (name, k), (p_plan, p_exec) in PAPER.items():
        A, J = SETS[k]
        lim = Limits(F, A, J)             # the paper limits the Cartesian axes; joints set equal
        limits = replace(m.limits, joint=lim, cartesian=lim, feed_max=F, chord_error_mm=EPS)
        prof = planners.plan("scurve", resolve_path(name), m, limits)
        rows[f"{name} set {k}"] = {"paper_planning_s": p_plan, "paper_execution_s": p_exec,
                                   "planning_s": prof.planning_time_s, "execution_s": prof.execution_time_s}
    plt = pyplot()
    names = list(rows)
    x = np.arange(len(names))
    fig, ax = plt.subplots(figsize=(8, 3.5))
    ax.bar(x - 0.2, [rows[n]["paper_execution_s"] for n in names], 0.4, label="paper (its curves, i5-6600)")
    ax.bar(x + 0.2, [rows[n]["execution_s"] for n in names], 0.4, label="pkmbench scurve (our curves)")
    ax.set(xticks=x, xticklabels=names, ylabel="execution time (s)",
           title="TII 2022 — s-curve execution time, F = 2500 mm/s, T = 0.25 ms, ε = 1 µm")
    ax.legend(fontsize=8)
    fig.tight_layout()
    # the CSV keeps the deterministic numbers only (planning time is wall time)
    save(fig, out, "tii2022_table", {"paper_execution_s": [rows[n]["paper_execution_s"] for n in names],
                                     "execution_s": [rows[n]["execution_s"] for n in names]})
    return rows
