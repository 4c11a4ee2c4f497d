"""The toolpath corpus benchmark (issues 19, 32): every planner on every corpus path, plan +
the independent check at T, each run against the path's converged minimum time.

    run       the manifest, the selection, a row per (path, planner, seed)
    suite     a suite file's paths as corpus entries
    journal   the rows kept as they end, keyed by the code each planner's row runs
    analysis  the reference, the ratios, the performance profile (harness.perfprofile), summaries
    report    corpus.csv, corpus.md and the figures

Nothing is imported here: importing run.py (the rows) must not import the reports, whose
code a row does not depend on (harness.corpus.journal keys rows by what they import).
"""
