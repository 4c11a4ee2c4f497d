"""`copp` — jerk-limited time-optimal path parametrisation by COPP's TOPP3-SOCP, at COPP's
settings and by its own solver (copp-py's Clarabel, not the engine's banded IPM that `optimal`
uses): a second, independent jerk-limited reference on the planners' constraint set.

Wang, Hu, Li, Yu, Yan, Liang & Jin, Int. J. Machine Tools and Manufacture 215 (2026) 104355;
the `copp-py` package.  The transcription, its check at T and its repairs: planners/optimal/topp3.py.
The linearisations stop when a solve gains < 0.1 % of a piece's time, after at most 4 solves
(topp3.Settings' defaults; docs/TUNING.md says what more cost).
"""
from __future__ import annotations

import time

from planners.optimal import topp3



def plan(path, machine, limits=None, *, grid_mm: float = 0.1):
    """COPP TOPP3-SOCP: joint v, a, j limits and the feed caps, checked and repaired at T."""
    t0 = time.perf_counter()
    limits = machine.limits if limits is None else limits
    prof = topp3.solve(path, machine, limits, topp3.Settings("copp", grid_mm, solver="clarabel"))
    prof.planning_time_s = time.perf_counter() - t0
    return prof
