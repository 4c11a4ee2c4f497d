"""README's picture and caption, made from a finished run (`pkmbench figures --readme RUN_DIR`):
the run's comparison.png and summary.json are copied to results/figures/ and the caption
between README's markers is written from that summary.json, never typed."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

from kins.resources import FIGURES_DIR, REPO
from planners.verify import within

NAME = "default_keops_bird"
BEGIN = f"<!-- caption from results/figures/{NAME}.json: pkmbench figures --readme RUN_DIR -->"
END = "<!-- end of caption -->"
ORDERS = ("velocity", "acceleration", "jerk")
WHAT = {"trapezoid": "the LinuxCNC-style trapezoid", "scurve": "the s-curve planned under Cartesian limits",
        "scurve_joint": "the s-curve checked on the joints", "toppra": "the time-optimal TOPP-RA reference (no jerk limit)",
        "optimal": "the jerk-limited optimum", "pso": "pso", "pso_socp": "pso_socp", "copp": "copp"}


def _pct(r: float) -> str:
    """How far above its limit a peak ratio r > 1 is: 0.01 % … 99 %, then 2× …"""
    return f"{r:.0f}×" if r >= 2 else f"{(r - 1) * 100:.2g} %" if r < 1.1 else f"{(r - 1) * 100:.0f} %"


def _names(names) -> str:
    names = list(names)
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def caption(summary: dict) -> str:
    """One paragraph: what each planner breaks (joint limits at T), who stays within, and the
    fastest within every joint limit against the others."""
    P = summary["planners"]
    T_us = summary["servo_period_s"] * 1e6
    parts = [f"`make run` on {summary['machine'].upper()} / {summary['path']} (T = {T_us:g} µs), "
             "through the full FMU chain"]
    breaks, keeps = [], []
    for name, m in P.items():
        if "joint_peak_ratio" not in m:
            continue
        over = [(o, m["joint_peak_ratio"][o]) for o in ORDERS if not within(m["joint_peak_ratio"][o])]
        if not over:
            keeps.append(name)
            continue
        cart_ok = all(within(m["cartesian_peak_ratio"][o]) for o in ORDERS)
        limits = _names(o for o, _ in over)
        by = _names(_pct(r) for _, r in over)
        breaks.append(f"{WHAT.get(name, name)}{' keeps its axes within their limits but' if cart_ok else ''} "
                      f"breaks the joints' {limits} limit{'s' if len(over) > 1 else ''} by {by}")
    parts += breaks
    if keeps:
        parts.append(f"{_names(keeps)} stay{'s' if len(keeps) == 1 else ''} within every joint limit")
    times = {n: P[n]["execution_time_s"] for n in keeps}
    if len(times) > 1:
        best = min(times, key=times.get)
        others = sorted((n for n in times if n != best), key=times.get)
        parts.append(f"the fastest of these is {best} ({times[best]:.4f} s): " + _names(
            f"{n} takes {(times[n] / times[best] - 1) * 100:.2f} % longer ({times[n]:.4f} s)" for n in others))
    return "*" + parts[0] + ": " + "; ".join(parts[1:]) + ".*"


def update(run_dir: Path, readme: Path = REPO / "README.md", figures: Path = FIGURES_DIR) -> str:
    """Copy the run's picture and summary to ``figures`` and write the caption into ``readme``."""
    summary_file = Path(run_dir) / "summary.json"
    summary = json.loads(summary_file.read_text())
    shutil.copyfile(Path(run_dir) / "comparison.png", figures / f"{NAME}.png")
    shutil.copyfile(summary_file, figures / f"{NAME}.json")
    text = readme.read_text()
    if BEGIN not in text or END not in text:
        raise ValueError(f"{readme}: no caption markers ({BEGIN} … {END})")
    head, rest = text.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    cap = caption(summary)
    readme.write_text(f"{head}{BEGIN}\n{cap}\n{END}{tail}")
    return cap
