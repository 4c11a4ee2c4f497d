"""`pkmbench corpus`: every planner on every path of the toolpath corpus (plan + the independent
check at T), a table, a performance profile and a per-path T/T_best chart.

    pkmbench corpus --out results/corpus                          # all paths × all planners
    pkmbench corpus --quick --out /tmp/c                          # 3 paths × the fast planners
    pkmbench corpus --paths 'butterfly_*,rand_*kossel' --planners scurve,scurve_joint --out D
    pkmbench corpus --suite benchmarks/suites/corpus.toml --out D  # the nightly run

Writes OUT/corpus.csv, OUT/corpus.md, OUT/performance_profile.png, OUT/ratio_to_reference.png
(every run against the path's converged minimum time, benchmarks/paths/corpus/reference.json),
and appends one row per plan to the results store (kind = 'corpus'; `pkmbench query`). A
stochastic planner (pso) runs over --seeds seeds (default 10) and is reported as a distribution.
Each row is kept in OUT/rows.jsonl as it ends: an interrupted run loses none, and `--resume`
plans only what it had not finished (harness/corpus/journal.py); the tables are written at the end.
Exit 0 when every planner returned a profile or a PlanningError, 1 when a planner raised
something else (an internal error, listed), 2 on a user error.
"""
from __future__ import annotations

# Local imports: every command module is imported to build the parser; a command loads what it
# needs when it runs (`pkmbench --help` and the other commands stay fast)

from harness.cli import CliError
from harness.outdir import OutDirError, output_dir, run_lock


def add_arguments(p) -> None:
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--planners", default=None,
                   help="comma-separated planners (default: all but linuxcnc; --quick: trapezoid,scurve,scurve_joint)")
    p.add_argument("--paths", default=None, metavar="GLOB[,GLOB…]",
                   help="corpus path names (or files) matching these globs (default: all)")
    p.add_argument("--quick", action="store_true",
                   help="a small subset (3 paths, one per machine; the fast planners unless --planners)")
    p.add_argument("--suite", default=None,
                   help="take machines × paths × planners from a suite file (e.g. benchmarks/suites/corpus.toml)")
    p.add_argument("--seeds", type=int, default=None,
                   help="runs of each stochastic planner (pso) per path, seeds 0 … N−1 (default 10)")
    p.add_argument("--resume", action="store_true",
                   help="keep the rows an interrupted run into OUT finished (OUT/rows.jsonl, made by the same "
                        "code of their planner) and plan only the rest")
    p.add_argument("--store", default=None,
                   help="results store folder the rows are appended to (default: $PKMBENCH_STORE "
                        "or results/store; 'none' = do not append)")


def main(args) -> int:
    import planners
    from harness.corpus.analysis import load_reference, summary
    from harness.corpus.run import FAST_PLANNERS, SEEDS, CorpusError, load_manifest, select
    from harness.corpus.suite import entries_from_suite
    seeds = SEEDS if args.seeds is None else args.seeds
    if seeds < 1:
        raise CliError(f"--seeds {args.seeds}: need at least 1")
    try:
        if args.suite:
            if args.paths or args.quick:
                raise CliError("--suite takes its paths from the suite: no --paths / --quick with it")
            selection = entries_from_suite(args.suite)
            if args.planners:
                want = _planners(args.planners)
                selection = [(e, [p for p in ps if p in want]) for e, ps in selection]
        else:
            names = _planners(args.planners) if args.planners else \
                (list(FAST_PLANNERS) if args.quick else [p for p in planners.PLANNERS if p != "linuxcnc"])
            selection = [(e, names) for e in select(load_manifest(), args.paths, args.quick)]
    except CorpusError as e:
        raise CliError(str(e)) from None
    try:
        out = output_dir(args.out)
        with run_lock(out):
            rows, files = _run(selection, seeds, out, args.resume)
    except OutDirError as e:
        raise CliError(str(e)) from None
    if args.store != "none":
        _append(rows, args, out)
    reference = load_reference()
    print(f"{'planner':13s} {'profiles':>9s} {'feasible':>9s} {'cart-feas':>9s} {'own-lim':>7s} {'T/Tref med':>10s} "
          f"{'IQR':>15s} {'worst':>7s} {'T/Tbest med':>11s} {'plan med s':>10s} {'worst':>8s}")
    for k, s in summary(rows, reference).items():
        q = s["to_reference"]
        own = "—" if s["own_limits"] is None else str(s["own_limits"])
        print(f"{k:13s} {s['profiles']:4d}/{s['runs']:<4d} {s['feasible']:9d} {s['cartesian_feasible']:9d} {own:>7s} "
              f"{q['median']:10.4g} {q['q1']:7.4g}–{q['q3']:<7.4g} {q['worst']:7.4g} {s['ratio_median']:11.4g} "
              f"{s['plan_median_s']:10.3g} {s['plan_worst_s']:8.3g}")
    print("wrote " + ", ".join(str(f) for f in files.values()))
    errors = [r for r in rows if r.status == "error"]
    for r in errors:
        print(f"  INTERNAL ERROR {r.path} / {r.planner}: {r.error}")
    return 1 if errors else 0


def _run(selection, seeds, out, resume):
    """The rows (each kept in OUT/rows.jsonl as it ends) and the tables written from them."""
    from harness.corpus.analysis import load_reference
    from harness.corpus.report import write_outputs
    from harness.corpus.run import run_corpus
    from harness.corpus.journal import Journal
    n = sum(len(ps) for _, ps in selection)
    print(f"corpus: {len(selection)} paths, {n} plans → {out}")
    journal = Journal(out, resume)
    if resume:
        print(f"resumed: {journal.summary()}")
    reference = load_reference()

    def progress(r):
        what = (f"T = {r.execution_time_s:.4f} s, joint {r.joint_worst:.3f}, cart {r.cart_worst:.3f}, "
                f"{'feasible' if r.feasible else 'INFEASIBLE'}") if r.status == "ok" else r.error
        ref = reference.get(r.path)
        if r.status == "ok" and ref:
            what += f", T/T_ref {r.execution_time_s / ref[0]:.4f}"
        seed = f" s{r.seed}" if r.seed is not None else ""
        print(f"  {r.path:28s} {r.planner + seed:13s} {r.planning_time_s:8.2f} s  {what}", flush=True)

    try:
        rows = run_corpus(selection, progress=progress, seeds=seeds, kept=journal.kept, keep=journal.add)
    except KeyboardInterrupt:
        print(f"the rows finished are kept in {journal.file}: the same command with --resume plans the rest")
        raise
    return rows, write_outputs(rows, out, reference)


def _append(rows, args, out) -> None:
    from harness.store import ResultStore, StoreError, rows_from_corpus
    from harness.sweep import code_version
    info = {"out": str(out), "paths": args.paths, "quick": bool(args.quick)}
    try:
        with ResultStore(args.store) as st:
            st.append(rows_from_corpus(rows), kind="corpus", suite=str(args.suite or ""),
                      code_version=code_version(), run_info=info)
    except StoreError as e:
        raise CliError(f"{e} (the corpus's results are in {out})") from None


def _planners(spec: str) -> list[str]:
    """Built-ins, installed plug-ins and module:function specs (planners.registry)."""
    from planners import registry
    names = [n.strip() for n in spec.split(",") if n.strip()]
    bad = [n for n in names if not registry.known(n)]
    if bad or not names:
        raise CliError(f"--planners {spec}: unknown planner(s) {', '.join(bad) or '(none given)'}; "
                       f"valid: {', '.join(registry.names())}")
    return names
