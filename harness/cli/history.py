"""`pkmbench history`: the trend of the nightly ci runs in the results store, as a table and plots.

    pkmbench history                                  # the ci rows of results/store (or --store)
    pkmbench history --metric execution_time_s --metric 'joint_peak_ratio.*' --out results/ci/trend.png
"""
from __future__ import annotations

# Local imports: every command module is imported to build the parser; a command loads what it
# needs when it runs (`pkmbench --help` and the other commands stay fast)

import fnmatch
from harness.cli import CliError, warn_skipped
from harness.outdir import output_file
from kins.resources import CI_DIR

DEFAULT_METRICS = ["execution_time_s", "planning_time_ratio", "joint_peak_ratio.jerk"]


def add_arguments(p) -> None:
    p.add_argument("--store", default=None, help="results store folder (default: $PKMBENCH_STORE or results/store)")
    p.add_argument("--metric", action="append", metavar="PATTERN",
                   help=f"metric name or glob, repeatable (default: {', '.join(DEFAULT_METRICS)})")
    p.add_argument("--entry", default="*", metavar="PATTERN", help="runs to plot (glob on machine/path/planner/…)")
    p.add_argument("--out", help=f"PNG file for the plot (default: {CI_DIR / 'trend.png'})")
    p.add_argument("--last", type=int, default=20, help="CI runs listed in the table")


def main(args) -> int:
    from harness.ci.history import History
    from harness.store import StoreError, existing_store
    try:
        h = History(existing_store(args.store))
    except StoreError as e:
        raise CliError(str(e)) from None
    warn_skipped("history", h.store)
    with h:
        runs = h.runs()
        if not runs:
            raise CliError(f"{h.store.folder}: no ci runs in the results store yet; `pkmbench ci` appends them")
        out = output_file(args.out or CI_DIR / "trend.png", "plot file")
        names = h.metric_names()
        patterns = args.metric or DEFAULT_METRICS
        metrics = [m for m in names if any(fnmatch.fnmatchcase(m, p) for p in patterns)]
        if not metrics:
            raise CliError(f"no metric matches {', '.join(patterns)}; known: {', '.join(names)}")
        series = {m: {e: pts for e, pts in h.series(m).items() if fnmatch.fnmatchcase(e, args.entry)}
                  for m in metrics}
    print(f"{'run':>4s} {'utc':25s} {'commit':9s} {'mode':16s} {'result':6s} {'regr':>4s} {'wall s':>7s} {'ref ms':>7s}")
    for r in runs[-args.last:]:
        print(f"{r['id']:4d} {r['utc']:25s} {r['git_commit'] or '-':9s} {r['mode']:16s} "
              f"{'pass' if r['passed'] else 'FAIL':6s} {r['regressions']:4d} {r['wall_s']:7.1f} "
              f"{1e3 * r['reference_s']:7.2f}")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(len(metrics), 1, figsize=(9, 2.6 * len(metrics)), squeeze=False, sharex=True)
    for ax, m in zip(axes[:, 0], metrics):
        for entry, pts in sorted(series[m].items()):
            ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", ms=3, label=entry)
        ax.set_ylabel(m, fontsize=8)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("ci run #")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    if labels:
        fig.legend(handles, labels, loc="upper center", fontsize=6, ncol=2, bbox_to_anchor=(0.5, 1.0))
    fig.tight_layout(rect=(0, 0, 1, 0.9 if labels else 1))
    fig.savefig(out, dpi=110)
    plt.close(fig)
    print(f"history: {len(runs)} ci runs, {len(metrics)} metric(s) plotted → {out}")
    return 0
