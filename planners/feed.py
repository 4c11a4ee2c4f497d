"""The programmed feed: what caps the feed of every planner on a G-code path.

As on the real machine, a G-code move runs at most at its programmed F and a rapid (G0) at
the rapid rate (here F_max, the machine's TRAJ MAX_LINEAR_VELOCITY); F_max caps both.
A path that is not G-code (NURBS, segment JSON) has no programmed feed: F_max.

``use_max_feed(path)`` sets the path's ``feed_mode`` (planners.paths.base.Path) to run it at
F_max regardless of its F words (the suite's planner-only comparison mode, ``pkmbench run
--max-feed``): the mode travels with the path, so every planner and the checker see it.
"""
from __future__ import annotations

import numpy as np


def use_max_feed(path, on: bool = True):
    """Mark ``path`` to be planned at F_max (``on``) or at its programmed feed; returns it."""
    path.feed_mode = "max" if on else "programmed"
    return path


def feed_mode(path) -> str:
    """"programmed" (the default) or "max"."""
    return path.feed_mode


def segment_feeds(path, feed_max: float) -> np.ndarray | None:
    """Per segment of a G-code path: min(F_max, programmed F) (rapids: F_max), mm/s;
    None when nothing is programmed (not G-code) or the path runs at F_max."""
    prog = path.program           # only a SegmentPath read from G-code has one
    if prog is None or path.feed_mode == "max":
        return None
    # kept on the path: planners ask per piece or per point (toppra 10³ times, scurve's FLF
    # minima per bracket), and building it is a pass over every move and segment
    key = (feed_max, id(path.segments))
    cached = path.__dict__.get("_segment_feeds")
    if cached is not None and cached[0] == key:
        return cached[1]
    # a blend arc carries the line number of a move of the program, so it gets that F
    by_line = {m.line: (m.feed_mm_s if not m.rapid else None) for m in prog.moves}
    f = np.array([min(feed_max, by_line.get(g.line) or feed_max) for g in path.segments])
    f.flags.writeable = False
    path._segment_feeds = (key, f)
    return f


def feed_ceiling(path, s, feed_max: float) -> np.ndarray:
    """min(F_max, programmed F) at arc lengths ``s`` (mm/s)."""
    s = np.asarray(s, float)
    f = segment_feeds(path, feed_max)
    if f is None:
        return np.full(s.shape, float(feed_max))
    return f[path.segment_index(s)]
