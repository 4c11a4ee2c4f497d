"""`pkmbench figures`: regenerate the published figures and REPORT.md under results/figures."""
from __future__ import annotations

# Local imports: every command module is imported to build the parser; a command loads what it
# needs when it runs (`pkmbench --help` and the other commands stay fast)

from pathlib import Path

from harness.cli import CliError
from harness.outdir import output_dir
from harness.cosim.system import SystemError_
from kins.resources import FIGURES_DIR


def add_arguments(p):
    p.add_argument("--out", default=str(FIGURES_DIR), help="output folder (default: %(default)s)")
    p.add_argument("--compare", metavar="DIR", help="afterwards compare every CSV with DIR's (e.g. the "
                   "committed results/figures) within the cross-machine contract (docs/REPRODUCIBILITY.md); "
                   "exit 1 if any differs or is missing")
    p.add_argument("--exact", action="store_true", help="with --compare: byte for byte (the same-machine contract)")
    p.add_argument("--quick", action="store_true", help="10⁵ latency cycles instead of 10⁶, no pso (a fast check)")
    p.add_argument("--readme", metavar="RUN_DIR", help="only README's picture and caption, from a finished run "
                   "(e.g. results/default/keops_bird of `make run`): copied to results/figures/, the caption "
                   "written from its summary.json")


def main(args) -> int:
    from harness.report.figures import keops_paper, kossel_thesis, tii2022
    from harness.ci import baseline as ci
    from harness.report.compare import compare_csvs
    from harness.report.figures_report import report

    if args.readme:
        from harness.report import readme
        if not (Path(args.readme) / "summary.json").is_file():
            raise CliError(f"--readme {args.readme}: no summary.json there (a finished run folder)")
        print(readme.update(Path(args.readme)))
        return 0
    out = output_dir(args.out)
    steps = [("KEOPS paper Figs. 5–6", lambda: keops_paper.figures(out, pso=not args.quick)),
             ("KEOPS flat bird at the workspace centre",
              lambda: keops_paper.figures(out / "bird_flat", "bird_flat", pso=False)),
             ("KEOPS feed over arc length", lambda: keops_paper.feed_over_arc_length(out)),
             ("Kossel thesis Fig. 29", lambda: kossel_thesis.latency(out, 100_000 if args.quick else 1_000_000)),
             ("Kossel thesis Figs. 41–43", lambda: kossel_thesis.velocity_responses(out)),
             ("Kossel thesis Figs. 44–46", lambda: kossel_thesis.moves(out)),
             ("TII 2022 table", lambda: tii2022.table(out))]
    res = {}
    for k, (what, fn) in enumerate(steps, 1):
        print(f"[{k}/{len(steps)}] {what} …", flush=True)
        try:
            res[what] = fn()
        except SystemError_ as e:   # a missing or corrupt FMU: one line, naming it
            raise CliError(str(e)) from None
    (out / "REPORT.md").write_text(report(res))
    print(f"figures and REPORT.md in {out}")
    if not args.compare:
        return 0
    return compare_csvs(out, Path(args.compare), 0.0 if args.exact else ci.CSV_REL)
