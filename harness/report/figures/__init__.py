"""Reproductions of the source publications' figures (`pkmbench figures`).

One module per source: keops_paper (Erwinski et al. 2022, Figs. 5–6, and where pso and the
optimum differ), kossel_thesis (Wąsowski 2024, Figs. 29, 41–43 and 44–46), tii2022 (Erwinski, Wawrzak, Paprocki, planning/execution
table). Each figure is a PNG with the plotted data as CSV beside it (compared across runs for
determinism); every function returns the numbers that REPORT.md quotes.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np


def save(fig, out: Path, name: str, columns: dict[str, np.ndarray]) -> Path:
    """Write NAME.png and NAME.csv (17 significant digits; columns padded to one length)."""
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    png = out / f"{name}.png"
    fig.savefig(png, dpi=110, metadata={"Software": None})   # no version string: same bytes
    plt.close(fig)
    n = max(len(v) for v in columns.values())
    cols = {k: np.concatenate([np.asarray(v, float), np.full(n - len(v), np.nan)]) for k, v in columns.items()}
    lines = [",".join(cols)] + [",".join("" if np.isnan(x) else f"{x:.17g}" for x in row)
                                for row in np.column_stack(list(cols.values()))]
    (out / f"{name}.csv").write_text("\n".join(lines) + "\n")
    return png


def pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt
