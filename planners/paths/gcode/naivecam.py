"""G64 Q: LinuxCNC's "naive CAM detector", which joins runs of short G1 moves into one line.

LinuxCNC 2.9 does this in its canon layer, between the interpreter and the trajectory planner
(src/emc/task/emccanon.cc ``see_segment``, ``linkable``, ``flush_segments``; the XY arcs of
``ARC_FEED``), so every planner here sees the joined moves, as LinuxCNC's tp does:

- in G64 with Q > 0, each STRAIGHT_FEED end point joins the current chain when every point of the
  chain lies within Q of the line from the chain's start to the new point (at most 101 points);
  otherwise the chain is sent as one line (start → last point, the last point's line number)
  and a new chain starts with the point;
- an XY arc (G17, G64) whose sagitta r·(1 − cos(θ/2)) is below Q becomes two points: its
  angular midpoint (z halfway) and its end (``chord_deviation``);
- any other canonical call that flushes in emccanon.cc ends the chain first: rapids, other arcs,
  the events between moves (M codes, dwells, tool changes, messages) and the interpreter's
  flushes (an F, S or G64 word, even with the same value; a work or tool offset).
"""
from __future__ import annotations

import math
from dataclasses import replace

MAX_CHAIN = 100          # linkable(): "if (chained_points.size() > 100) return false"


def join_moves(moves: list, events: list, stateless_m=frozenset(), flushes=()) -> tuple[list, list]:
    """(moves, events) with the G64 Q chains joined; each event's index (moves before it) is
    mapped onto the joined moves. ``stateless_m``: M codes that flush nothing (M70–M73);
    ``flushes``: the other canon calls that end a chain (moves emitted before each)."""
    if not any(m.path_mode[0] == "blend" and m.path_mode[2] > 0 for m in moves):
        return moves, events
    flush_at = {e.index for e in events if not (e.kind == "m" and e.value in stateless_m)} | set(flushes)
    out: list = []
    chain: list = []           # [(end point, the move it comes from)]
    start = None               # the chain's start: where the last move sent ended
    offsets: list = []         # each chained point less start, per axis (as _linkable reads them)
    index_of = [0] * (len(moves) + 1)

    def flush():
        if chain:
            end, last = chain[-1]
            out.append(last if len(chain) == 1 and last.kind == "feed" and tuple(last.start) == start
                       else replace(last, kind="feed", start=start, end=end, center=None, turn=0))
            chain.clear()
            offsets.clear()

    for k, m in enumerate(moves):
        # a feed or mode change comes with an F or G64 word (a flush) except where M72 restores
        # the modal state: LinuxCNC's canon sees SET_FEED_RATE / SET_MOTION_CONTROL_MODE there too
        if k in flush_at or (chain and (m.feed_mm_min != chain[-1][1].feed_mm_min
                                        or m.path_mode != chain[-1][1].path_mode)):
            flush()
        index_of[k] = len(out)
        points = _chain_points(m)
        if points is None:
            flush()
            out.append(m)
            continue
        for p in points:
            if chain and not _linkable(start, offsets, p, m.path_mode):
                flush()
            if not chain:
                start = tuple(m.start) if p is points[0] else tuple(chain_end)
            chain.append((p, m))
            offsets.append((p[0] - start[0], p[1] - start[1], p[2] - start[2]))
            chain_end = p
    flush()
    index_of[len(moves)] = len(out)
    return out, [replace(e, index=index_of[e.index]) for e in events]


def _chain_points(m):
    """The points a move adds to a chain, or None when it flushes and is sent as it is (and
    so does a move from an unknown point: the positioning first move, which is no segment)."""
    if not all(map(math.isfinite, m.start)):
        return None
    if m.kind == "feed":
        return [tuple(m.end)]
    if m.kind == "arc" and m.plane == 17 and m.path_mode[0] == "blend":
        mx, my, dev = _chord_deviation(m.start, m.end, m.center, m.turn)
        if dev < m.path_mode[2]:
            return [(mx, my, 0.5 * (m.start[2] + m.end[2])), tuple(m.end)]
    return None


def _linkable(start, offsets, p, path_mode) -> bool:
    """emccanon.cc linkable(): every chained point within Q of the line start → p
    (``offsets``: each chained point less start, per axis)."""
    q = path_mode[2] if path_mode[0] == "blend" else 0.0
    if q == 0 or len(offsets) > MAX_CHAIN or tuple(p) == tuple(start):
        return False
    # the per-axis lists and generator written out (the same operations; sum() kept, whose
    # float summation changed in Python 3.12): a 10⁵-line program calls this per move, and
    # min(max(t, 0.0), 1.0) as the conditionals it evaluates (a call each cost more); the
    # chained points' offsets from start are made once, as they join (a chain holds ≤ 101)
    s0, s1, s2 = start
    M0, M1, M2 = p[0] - s0, p[1] - s1, p[2] - s2
    mm = M0 * M0 + M1 * M1 + M2 * M2
    # a point whose squared distance is clearly below q² (by far more than the rounding of
    # either form) is within: the exact sqrt(sum(…)) > q is only evaluated near the limit
    # (and always for a q whose square under- or overflows)
    q2 = q * q * (1.0 - 1e-9) if 1e-150 < q < 1e150 else -1.0
    for d0, d1, d2 in offsets:
        t = (M0 * d0 + M1 * d1 + M2 * d2) / mm
        t = 0.0 if 0.0 > t else (1.0 if 1.0 < t else t)
        e0, e1, e2 = d0 - t * M0, d1 - t * M1, d2 - t * M2
        if e0 * e0 + e1 * e1 + e2 * e2 <= q2:
            continue
        if math.sqrt(sum((e0 ** 2, e1 ** 2, e2 ** 2))) > q:
            return False
    return True


def _chord_deviation(s, e, c, rotation):
    """emccanon.cc chord_deviation() in the XY plane: (x, y of the arc's angular midpoint, its
    sagitta r·(1 − cos(θ/2)) with θ the included angle, at most one turn)."""
    th1 = math.atan2(s[1] - c[1], s[0] - c[0])
    th2 = math.atan2(e[1] - c[1], e[0] - c[0])
    r = math.hypot(s[1] - c[1], s[0] - c[0])
    for _ in range(2):      # twice: atan2 may give −π and π for the two ends
        if rotation < 0 and th2 - th1 >= -1e-5:
            th2 -= 2 * math.pi
        elif rotation >= 0 and th2 - th1 <= 1e-5:
            th2 += 2 * math.pi
    mid = 0.5 * (th1 + th2)
    return c[0] + r * math.cos(mid), c[1] + r * math.sin(mid), r * (1 - math.cos(abs(th2 - th1) / 2))
