"""The toolpath corpus benchmark (issues 19, 32): every planner on every corpus path, plan +
the independent check at T, each run against the path's converged minimum time.

    run       the manifest, the selection, a row per (path, planner, seed)
    analysis  the reference, the ratios, the performance profile (harness.perfprofile), summaries
    report    corpus.csv, corpus.md and the figures
"""
from harness.corpus.analysis import (below_reference, best_times, load_reference, performance_profile, ratios,
                                     seed_spread, spread, summary, swarm_spread)
from harness.corpus.report import write_csv, write_markdown, write_outputs
from harness.corpus.run import (CORPUS_DIR, FAST_PLANNERS, MANIFEST, QUICK_PATHS, SEEDS, CorpusError, Row,
                                entries_from_suite, load_manifest, run_corpus, run_one, select)

__all__ = ["CORPUS_DIR", "FAST_PLANNERS", "MANIFEST", "QUICK_PATHS", "SEEDS", "CorpusError", "Row",
           "below_reference", "best_times", "entries_from_suite", "load_manifest", "load_reference",
           "performance_profile", "ratios", "run_corpus", "run_one", "select", "seed_spread", "spread", "summary",
           "swarm_spread", "write_csv", "write_markdown", "write_outputs"]
