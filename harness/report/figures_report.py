"""REPORT.md of `pkmbench figures`: the template REPORT.template.md filled with the numbers the
figure functions (harness/report/figures/) return — no measured number is typed here."""
from __future__ import annotations

from pathlib import Path
from string import Template

from harness.cosim.drive_params import encoder_increment_mm
from kins import load_machine

TEMPLATE = Path(__file__).with_name("REPORT.template.md")


def _vaj(d: dict) -> str:
    return " / ".join(f"{d[k]:.3f}" for k in ("velocity", "acceleration", "jerk"))


def _jacobian_row_horizontal() -> float:
    """Length of the horizontal part of a KEOPS joint's unit Jacobian row at the workspace centre."""
    import numpy as np

    m = load_machine("keops")
    J = np.asarray(m.jacobian(m.home), float)
    return float((np.linalg.norm(J[:, :2], axis=1) / np.linalg.norm(J, axis=1)).max())


def report(r: dict) -> str:
    """REPORT.md from the figure steps' results, keyed as `pkmbench figures` names the steps."""

    kp, kc = r["KEOPS paper Figs. 5–6"], r["KEOPS flat bird at the workspace centre"]
    fo = r["KEOPS feed over arc length"]
    lat, vel, mv, tii = (r["Kossel thesis Fig. 29"], r["Kossel thesis Figs. 41–43"],
                         r["Kossel thesis Figs. 44–46"], r["TII 2022 table"])
    worst_move = max(mv.values(), key=lambda d: d["max_following_error_um"])
    values = {
        "pso_panel": "![](keops_fig6_pso_joints.png)\n" if "pso" in kp else "",
        "keops_rows": "\n".join(f"| {n} | {d['execution_time_s']:.4f} | {_vaj(d['cartesian'])} | {_vaj(d['joint'])} |"
                                for n, d in kp.items()),
        "row_horizontal": f"{_jacobian_row_horizontal():.2f}",
        "flat_joint": _vaj(kc["scurve"]["joint"]),
        "feed_times": ", ".join(f"{k} {v:.4f}" for k, v in fo["execution_time_s"].items()),
        "n_joins": len(fo["joins_mm"]),
        "pso_time": f"{fo['execution_time_s']['pso_socp']:.4f}", "opt_time": f"{fo['execution_time_s']['optimal']:.4f}",
        "excess_lo": f"{fo['stretch_excess_pct'][0]:.1f}", "excess_hi": f"{fo['stretch_excess_pct'][1]:.1f}",
        "gap_lo": f"{fo['peak_shortfall_pct'][0]:.1f}", "gap_hi": f"{fo['peak_shortfall_pct'][1]:.1f}",
        "top_pso": f"{fo['top_peak']['pso_mm_s']:.0f}", "top_opt": f"{fo['top_peak']['optimal_mm_s']:.0f}",
        "top_s": f"{fo['top_peak']['s_mm']:.0f}", "seed_peak": f"{fo['seed_peak_mm_s']:.0f}",
        "cycles": f"{lat['cycles']:,}", "within20": f"{100 * lat['within_20us']:.2f}",
        "worst_us": f"{lat['worst_us']:.0f}",
        "velocity_pictures": "\n".join(f"![](kossel_{name}_velocity.png)" for name in vel),
        "velocity_rows": "\n".join(f"| {d['target']} | ~20 ms lag, no overshoot, ~60 ms oscillation | "
                                   f"{d['lag_ms']:.1f} ms / {d['overshoot_pct']:.1f} % / {d['ripple_mm_s']:.1f} mm/s |"
                                   for d in vel.values()),
        "overshoot_max": f"{max(d['overshoot_pct'] for d in vel.values()):.1f}",
        "lag_max": f"{max(d['lag_ms'] for d in vel.values()):.1f}",
        "ripple_max": f"{max(d['ripple_mm_s'] for d in vel.values()):.1f}",
        "increment_um": f"{1e3 * encoder_increment_mm('kossel'):.2f}",
        "move_pictures": "\n".join(f"![](kossel_{name}_move.png)" for name in mv),
        "move_rows": "\n".join(f"| {d['move']} | (one value for all moves) | {d['max_following_error_um']:.1f} µm |"
                               for d in mv.values()),
        "worst_following": f"{worst_move['max_following_error_um']:.1f}",
        "worst_move": worst_move["move"],
        "tii_rows": "\n".join(f"| {n} | {d['paper_planning_s']:.3f} / {d['paper_execution_s']:.3f} | "
                              f"{d['planning_s']:.3f} / {d['execution_s']:.3f} |" for n, d in tii.items()),
    }
    return Template(TEMPLATE.read_text()).substitute(values)
