"""The s-curve's segment checks (planners.scurve.planner) for many segments in one numpy pass.

A round of the repair loop checks every changed segment, and each repair tests a segment at
several J and A values: a Python pass per test is too slow on a long program. Here the tests of one round are run in lockstep
(:func:`drive`) and each step's tests are evaluated together (:class:`Checker`). Every value
is computed with the same floating-point operations in the same order as the per-segment
form it replaces (phase samples, ``Segment.at``, the table, the reads at T of the joins), and
maxima are exact, so the plan is the same bit for bit.
"""
from __future__ import annotations

import numpy as np

from planners.constraints import JUMP_READ_FACTOR
from planners.scurve.pieces import Segment

CHUNK_POINTS = 32_768     # samples per numpy pass (its choice: docs/TUNING.md, "scurve's checks")


def drive(gens, checker):
    """Run generators in lockstep and return their return values.

    Each generator yields requests (``("flf", seg)``: is its feed under the FLF; ``("check", seg)``:
    its :class:`Check`) and is sent the answer; one step answers every pending request at once."""
    results = [None] * len(gens)
    pending = []

    def step(k, answer):
        try:
            pending.append((k, gens[k].send(answer)))
        except StopIteration as e:
            results[k] = e.value

    for k in range(len(gens)):
        step(k, None)
    while pending:
        batch, pending = pending, []
        for (k, _), answer in zip(batch, checker.answer([req for _, req in batch])):
            step(k, answer)
    return results


class Check:
    """A segment's peak [v, a, j] ratios with (``r``) and without (``r0``) the reads at T of the
    joins at its ends, whether each is within the limits (``ok``, ``ok0``: all ratios ≤ 1), and
    ``reads``: per read (end, signed read per axis, max and min of the continuous jerk within
    3T of that end)."""

    __slots__ = ("_rr", "ok", "ok0", "_src", "_k")

    def __init__(self, rr, ok, ok0, src, k):
        self._rr, self.ok, self.ok0, self._src, self._k = rr, ok, ok0, src, k

    # rows of the chunk's (r, r0) arrays, taken when asked: most checks are only asked ok
    @property
    def r(self):
        return self._rr[0][self._k]

    @property
    def r0(self):
        return self._rr[1][self._k]

    @property
    def reads(self):
        # picked out of the chunk's arrays when asked: only a repair through the joins reads them
        out = []
        for end, where, read, jmax, jmin in self._src:
            p = where[self._k]
            if p >= 0:
                out.append((end, read[p], jmax[:, p], jmin[:, p]))
        return out


class Stack:
    """Many fitted segments in arrays: s0, L, v0, v1, dur per segment, flat 7 phase jerks and
    8 boundary states a, v, p per segment (ruckig's), and ``tcum`` (N, 8), the phases' start
    times and the end."""

    def __init__(self, segs):
        rows = np.frombuffer(b"".join([g.prof for g in segs]), float).reshape(len(segs), 43)
        # cumsum along a row adds in the order of Segment.tcum's 1-D cumsum
        self.tcum = np.concatenate([np.zeros((len(segs), 1)), np.cumsum(rows[:, Segment.T], axis=1)], axis=1)
        self.j = rows[:, Segment.J_].ravel()
        self.a, self.v, self.p = (rows[:, c].ravel() for c in (Segment.A_, Segment.V_, Segment.P_))
        self.s0, self.L, self.v0, self.v1, self.dur = rows[:, Segment.HEAD].T.copy()

    def at(self, idx, tt):
        """Segment.at of segment idx[k] at tt[k] (the same operations in the same order)."""
        tt = np.minimum(np.maximum(tt, 0.0), self.dur[idx])
        # searchsorted(tcum, tt, "right") − 1, as tcum[0] = 0 ≤ tt and tcum is sorted
        base = idx * 8
        flat = self.tcum.ravel()
        k = np.zeros(len(idx), np.int64)
        for c in range(1, 7):
            k += flat[base + c] <= tt
        dt = tt - flat[base + k]
        j = self.j[idx * 7 + k]
        row = base + k
        a0, v0, p0 = self.a[row], self.v[row], self.p[row]
        a = a0 + j * dt
        v = v0 + a0 * dt + j * dt * dt / 2
        p = p0 + v0 * dt + a0 * dt * dt / 2 + j * dt ** 3 / 6
        return p, v, a, j


class Joined:
    """The segments laid end to end as one piece of Profile.from_pieces: each sample evaluated
    in its segment at its time less the segment's start, as with a piece per segment, without
    a Python call per segment (and in chunks: a 10⁵-line program has ~10⁶ samples)."""

    s0 = 0.0

    def __init__(self, segs):
        self.st = Stack(segs)
        self.starts = np.concatenate([[0.0], np.cumsum([g.duration for g in segs])])
        self.duration = float(self.starts[-1])

    def at(self, tt):
        out = [np.empty(len(tt)) for _ in range(4)]
        for c in range(0, len(tt), CHUNK_POINTS):
            t = tt[c:c + CHUNK_POINTS]
            k = np.clip(np.searchsorted(self.starts, t, side="right") - 1, 0, len(self.starts) - 2)
            p, v, a, j = self.st.at(k, t - self.starts[k])
            for o, x in zip(out, (self.st.s0[k] + p, v, a, j)):
                o[c:c + CHUNK_POINTS] = x
        return out

    def switch_times(self):
        """(the times where a phase of nonzero duration ends, the starts of the segments that
        start at rest): for planners that start from this profile (pso)."""
        tc = self.st.tcum
        sw = (self.starts[:-1, None] + tc[:, 1:])[np.diff(tc, axis=1) > 1e-12]
        return sw.tolist(), self.starts[:-1][self.st.v0 == 0.0].tolist()


class _Layout:
    """Sample times grouped by segment (see :meth:`Checker.samples`): ``t``, ``idx`` (the
    segment), ``loc`` (its place in segs) and ``block`` per sample; ``end`` per segment (past its samples, the last
    ``nfine`` of them left for the refined rows); per block (8 per segment: its 7 phases, then
    a tail of 0, the duration and the refined rows) the phase's start ``lo`` and the end ``hi``
    below which Stack.at reads that phase (a tail: −inf), and the phase's j, a, v, p."""

    def __init__(self, st, segs, T, nfine):
        m = len(segs)
        tc = st.tcum[segs]
        a, b = tc[:, :-1], tc[:, 1:]
        d = b - a
        nz = d > 0
        n = np.where(nz, np.minimum(4000, np.maximum(16, np.ceil(d / T))), 0).astype(np.int64)
        # a phase's end is sampled unless the next phase of nonzero duration starts there (the
        # same time and values), and 0 unless a phase starts there
        nxt = np.minimum.accumulate(np.where(nz, np.arange(7), 7)[:, ::-1], axis=1)[:, ::-1]
        after = np.concatenate([nxt[:, 1:], np.full((m, 1), 7)], axis=1)
        a_next = np.take_along_axis(np.concatenate([a, np.full((m, 1), np.nan)], axis=1), after, axis=1)
        keep_b = nz & (a_next != b)
        keep0 = ~(nz.any(axis=1) & (np.take_along_axis(a, np.minimum(nxt[:, :1], 6), axis=1)[:, 0] == 0.0))
        size = np.zeros((m, 8), np.int64)
        size[:, :7] = np.where(nz, n + keep_b, 0)          # n − 1 grid points, [b], just inside b
        size[:, 7] = keep0 + 1 + nfine                    # [0], the duration, the refined rows
        first = np.cumsum(size.ravel()) - size.ravel()
        blk = np.repeat(np.arange(8 * m), size.ravel())
        k = (np.arange(len(blk)) - first[blk]).astype(float)
        # the grid points as numpy.linspace gives them (constraints.linspaces): k·step + a, or
        # k/div·Δ + a where the step underflows
        pad = lambda x, v: np.concatenate([x, np.full((m, 1), v, x.dtype)], axis=1).ravel()
        A, D, div = pad(a, 0.0), pad(d, 0.0), pad(n - 1, 1).astype(float)
        step = D / div
        t = k * step[blk] + A[blk]
        under = nz.ravel() & (step.reshape(m, 8)[:, :7] == 0).ravel()
        if under.any():
            z = np.nonzero(np.repeat(pad(under.reshape(m, 7), False), size.ravel()))[0]
            t[z] = k[z] / div[blk[z]] * D[blk[z]] + A[blk[z]]
        at = first.reshape(m, 8)[:, :7] + n - 1             # just after the grid
        t[at[keep_b]] = b[keep_b]
        t[(at + keep_b)[nz]] = (b - 1e-9 * d)[nz]
        tail = first.reshape(m, 8)[:, 7]
        t[tail] = 0.0
        t[tail + keep0] = st.dur[segs]
        self.t, self.block = t, blk
        self.end = np.cumsum(size.sum(axis=1))            # past each segment's samples
        self.loc = np.repeat(np.arange(m), self.end - np.concatenate([[0], self.end[:-1]]))
        self.idx = segs[self.loc]
        # Stack.at finds phase p for times in [tcum[p], tcum[p + 1]) (the last: to the end) that
        # its clip to [0, duration] leaves alone: with phases of no negative duration
        sane = (d >= 0).all(axis=1)[:, None]
        hi = np.concatenate([b[:, :6], np.full((m, 1), np.inf)], axis=1)
        hi = np.minimum(hi, np.nextafter(st.dur[segs], np.inf)[:, None])
        self.lo = A
        self.hi = pad(np.where(sane, hi, -np.inf), -np.inf)
        row = np.minimum(segs[:, None] * 8 + np.arange(8), len(st.a) - 1).ravel()
        jrow = np.minimum(segs[:, None] * 7 + np.arange(8), len(st.j) - 1).ravel()
        self.j, self.a0, self.v0, self.p0 = st.j[jrow], st.a[row], st.v[row], st.p[row]


class Checker:
    """The tests of :meth:`planners.scurve.planner._Planner.fit_peak` and of the segment check, for many
    segments at once; ``pl`` is the planner (its grid, FLF, tables, joins and check limits)."""

    def __init__(self, pl):
        self.pl = pl
        # the checked axes' x′, x″, x‴ tables as one (3·axes, rows) array: numpy runs an (n, 3)
        # array's arithmetic in inner loops of 3, several times slower than along rows of n,
        # and one np.take of all of them costs less than a gather per table
        tab = pl.table.joint if pl.joint else pl.table.cart
        self.tabT = np.ascontiguousarray(np.concatenate(tab[1:], axis=1).T)

    def answer(self, reqs):
        """Answers to [(kind, segment)] requests (see :func:`drive`), in order."""
        out = [None] * len(reqs)
        for kind, fn in (("flf", self.under_flf), ("check", self.check)):
            ks = [k for k, r in enumerate(reqs) if r[0] == kind]
            if ks:
                for k, val in zip(ks, fn([reqs[k][1] for k in ks])):
                    out[k] = val
        return out

    def under_flf(self, segs):
        """Per segment: its feed ≤ FLF + 1e-6 at 48 points evenly spread over its duration."""
        st, pl, m = Stack(segs), self.pl, 48
        out = np.empty(len(segs), bool)
        step = max(1, CHUNK_POINTS // m)
        for c in range(0, len(segs), step):
            idx = np.arange(c, min(c + step, len(segs)))
            # np.linspace(0, duration, 48): k·(duration/47) (+ 0), the last point set to the duration
            tt = np.arange(m, dtype=float)[None, :] * (st.dur[idx] / (m - 1))[:, None] + 0.0
            tt[:, -1] = st.dur[idx]
            rows = np.repeat(idx, m)
            p, vv, _, _ = st.at(rows, tt.ravel())
            ok = vv <= np.interp(st.s0[rows] + p, pl.grid, pl.F) + 1e-6
            out[idx] = ok.reshape(len(idx), m).all(axis=1)
        return out

    def check(self, segs):
        """:class:`Check` of each segment, in chunks of about CHUNK_POINTS samples."""
        st, T = Stack(segs), self.pl.T
        # samples per segment as the phases give them (≥ 16 each), to cut the chunks
        d = np.diff(st.tcum, axis=1)
        est = np.cumsum(np.where(d > 0, np.minimum(4000, np.maximum(16, np.ceil(d / T))) + 1, 0).sum(axis=1) + 2)
        cuts = np.searchsorted(est, np.arange(CHUNK_POINTS, est[-1], CHUNK_POINTS), side="right") + 1
        bounds = np.unique(np.concatenate([[0], np.minimum(cuts, len(segs)), [len(segs)]])).tolist()
        out = []
        for c, e in zip(bounds[:-1], bounds[1:]):
            out += self._check_chunk(st, np.arange(c, e))
        return out

    def samples(self, st, segs):
        """The check's samples of the segments ``segs``, grouped by segment (in no order within
        one; a time may repeat: only maxima are taken): (t, segment, p, v, a, j, the segment's
        place in ``segs``). The times:
        every jerk phase on its own (≥ 16 points, ≤ T apart), just inside each phase's end (at a
        phase's end at() reads the next phase's jerk), 0, the duration and the refined rows of
        the table. A phase's last point that is the next phase's first is taken once."""
        fine = self.pl.fine_s
        flo, fhi = np.searchsorted(fine, st.s0[segs]), np.searchsorted(fine, st.s0[segs] + st.L[segs])
        L = _Layout(st, segs, self.pl.T, fhi - flo)
        t, idx, ph = L.t, L.idx, L.block
        for k in np.nonzero(fhi > flo)[0].tolist():
            # the times of the refined rows inside a segment (p(t) is monotone, the times sorted
            # and unique as np.interp needs them): a jerk peak narrower than a period's travel
            # falls between samples ≤ T apart
            g, e = segs[k], L.end[k] - (fhi[k] - flo[k])
            tg = np.unique(t[L.end[k - 1] if k else 0:e])
            pg = st.at(np.full(len(tg), g), tg)[0]
            t[e:L.end[k]] = np.interp(fine[flo[k]:fhi[k]] - st.s0[g], pg, tg)
        # Stack.at's operations, with the phase each time was made for where it is the one at()
        # finds; the others (0, the duration, the refined rows, a time rounded onto a phase's
        # end) go through Stack.at itself
        lo = L.lo[ph]
        ok = (t >= lo) & (t < L.hi[ph])
        dt = t - lo
        j, a0, v0, p0 = L.j[ph], L.a0[ph], L.v0[ph], L.p0[ph]
        a = a0 + j * dt
        v = v0 + a0 * dt + j * dt * dt / 2
        p = p0 + v0 * dt + a0 * dt * dt / 2 + j * dt ** 3 / 6
        bad = np.nonzero(~ok)[0]
        p[bad], v[bad], a[bad], j[bad] = st.at(idx[bad], t[bad])
        return t, idx, p, v, a, j, L.loc

    def locate(self, st, s, loc, segs, starts):
        """PathTable._locate(s) of the samples s (of the segments ``segs[loc]``, grouped from
        ``starts``). On a refined table: first the row a uniform piece would hold, kept where the
        grid's rows confirm it (row ≤ s < next row, inside the piece: it is the last row ≤ s, as
        the search finds it); the others searched."""
        tab = self.pl.table
        if not tab.refined:
            return tab._locate(s, _window_search(starts))
        grid = tab.s
        s = np.clip(s, 0.0, tab.length)
        mid = np.searchsorted(grid, st.s0[segs] + 0.5 * st.L[segs], side="right") - 1
        pc = tab.row_piece[np.clip(mid, 0, len(grid) - 1)]
        i0, n0 = tab.offset[pc], tab.counts[pc]
        x = (s - tab.edges[pc][loc]) / tab.hs[pc][loc]
        # fmax/fmin: a NaN guess (a piece of no length) becomes a row, then fails the test
        i = np.fmin(np.fmax(np.floor(x), 0), (n0 - 2)[loc]).astype(np.int64) + i0[loc]
        lo, hi = grid[i], grid[i + 1]
        bad = np.nonzero(~((lo <= s) & (s < hi)))[0]
        if len(bad):
            r = np.searchsorted(grid, s[bad], side="right") - 1
            p = tab.row_piece[r]
            i[bad] = np.clip(r, tab.offset[p], tab.offset[p] + tab.counts[p] - 2)
            lo[bad], hi[bad] = grid[i[bad]], grid[i[bad] + 1]
        h = hi - lo
        return i, (s - lo) / h, h

    def derivs(self, st, s, loc, segs, starts):
        """x′, x″, x‴ of the checked axes at s (grouped by segment from ``starts``) as (axes, n):
        PathTable._interp's operations."""
        i, w, h = self.locate(st, s, loc, segs, starts)
        w2, w3 = w ** 2, w ** 3
        h00, h10 = 2 * w3 - 3 * w2 + 1, w3 - 2 * w2 + w
        h01, h11 = -2 * w3 + 3 * w2, w3 - w2
        h10h, h11h = h10 * h, h11 * h
        k = len(self.tabT) // 3
        A, B = np.take(self.tabT, i, axis=1), np.take(self.tabT, i + 1, axis=1)
        A1, A2, A3, B1, B2, B3 = A[:k], A[k:2 * k], A[2 * k:], B[:k], B[k:2 * k], B[2 * k:]
        d1 = h00 * A1 + h10h * A2 + h01 * B1 + h11h * B2
        d2 = h00 * A2 + h10h * A3 + h01 * B2 + h11h * B3
        d3 = (1 - w) * A3 + w * B3
        return d1, d2, d3

    def _check_chunk(self, st, segs):
        """:class:`Check` of the segments ``segs`` of the stack ``st``."""
        pl = self.pl
        lim = pl.check
        tt, idx, p, v, a, j, loc = self.samples(st, segs)
        s0 = st.s0[idx]
        # evaluate just inside the segment: at a corner the derivatives are one-sided
        s = np.clip(s0 + p, s0 + 1e-9, (st.s0 + st.L)[idx] - 1e-9)
        starts = np.searchsorted(loc, np.arange(len(segs)))
        D1, D2, D3 = self.derivs(st, s, loc, segs, starts)
        # constraints.time_derivs with the axes first (the same products in the same order)
        xv = D1 * v
        xa = D2 * v * v + D1 * a
        xj = D3 * v ** 3 + 3 * D2 * v * a + D1 * j
        jrow = _abs_max(xj)
        peak = lambda rowmax: np.maximum.reduceat(rowmax, starts)
        mv, ma, mj = peak(_abs_max(xv)), peak(_abs_max(xa)), peak(jrow)
        reads, jrow_r = self._reads(st, segs, tt, loc, xj, jrow)
        mjr = mj if jrow_r is None else peak(jrow_r)
        r0 = np.column_stack([mv / lim.v, ma / lim.a, mj / lim.j])
        r = np.column_stack([mv / lim.v, ma / lim.a, mjr / lim.j])
        if pl.tight is not None:         # checks tightened after a reading at T (scurve.tighten)
            t = pl.tight[np.searchsorted(pl.s_c, st.s0[segs])]
            r0, r = r0 * t, r * t
        ok, ok0 = (r <= 1.0).all(axis=1).tolist(), (r0 <= 1.0).all(axis=1).tolist()
        rr = (r, r0)
        return [Check(rr, ok[k], ok0[k], reads, k) for k in range(len(segs))]

    def _reads(self, st, segs, tt, loc, xj, jrow):
        """The reads at T of the joins at the segments' ends: a third difference at T is the jerk
        averaged by a quadratic B-spline kernel (support 3T, peak 0.75/T), so the jump Δx″v² of
        the acceleration at a join adds up to JUMP_READ_FACTOR·Δx″v²/T, with its sign, to the
        continuous jerk within 3T of it (without it a segment next to a join passes its own check
        and not the one at T). Returns ([(end, per segment its row in the next three or −1,
        the reads, the max and min of the jerk near that end)] for Check.reads, and per sample
        the largest |jerk| with the reads added, or None: no read)."""
        pl = self.pl
        T, joins, d2 = pl.T, pl.joins, pl.join_d2
        dur = st.dur[segs][loc]
        reads, near = [], {}
        for end, s_end, v_end in ((0, st.s0[segs], st.v0[segs]), (1, st.s0[segs] + st.L[segs], st.v1[segs])):
            k = np.searchsorted(joins, s_end)
            slots = []
            for n in (k - 1, k) if len(joins) else ():      # a join within 1 µm (merged critical points)
                nn = np.minimum(np.maximum(n, 0), len(joins) - 1)
                which = np.nonzero((n == nn) & (v_end > 0) & (np.abs(joins[nn] - s_end) < 1e-3))[0]
                if len(which):
                    # v² as the scalar power of the per-segment form (an array's square can differ in the last bit)
                    vsq = np.array([x ** 2 for x in v_end[which].tolist()])
                    slots.append((which, JUMP_READ_FACTOR * d2[nn[which]] * vsq[:, None] / T))
            if slots:
                # the samples within 3T of this end (each segment has one at least: its end)
                near[end] = tt <= 3 * T if end == 0 else tt >= dur - 3 * T
                rows = np.nonzero(near[end])[0]
                first = np.searchsorted(loc[rows], np.arange(len(segs)))
                xn = xj[:, rows]
                jmax, jmin = np.maximum.reduceat(xn, first, axis=1), np.minimum.reduceat(xn, first, axis=1)
                for which, read in slots:
                    where = np.full(len(segs), -1)          # segment → its row in this slot's arrays
                    where[which] = np.arange(len(which))
                    reads.append((end, where, read, jmax[:, which], jmin[:, which]))
        if not reads:
            return reads, None
        # the jerk with the reads added on the samples next to a join, in the per-segment
        # order (end 0, then 1): each read where it applies, ±0 elsewhere (no |value| changes)
        U = np.nonzero(near[0] | near[1] if len(near) == 2 else next(iter(near.values())))[0]
        lu = loc[U]
        hi = xj[:, U]
        lo = hi.copy()
        for end, where, read, _, _ in reads:
            k = where[lu]
            on = near[end][U] & (k >= 0)
            # the read where it applies, else 0 (its max or min with 0 is then 0 as well): a
            # gather of the transposed reads keeps the rows contiguous for the sums
            r = np.where(on, np.take(np.ascontiguousarray(read.T), np.maximum(k, 0), axis=1), 0.0)
            hi += np.maximum(r, 0)
            lo += np.minimum(r, 0)
        jrow_r = jrow.copy()
        jrow_r[U] = _abs_max(np.maximum(np.abs(hi), np.abs(lo)))
        return reads, jrow_r


def _window_search(starts):
    """np.searchsorted(a, q, side="right") for queries grouped by segment (``starts``), each
    group searched among the rows between its smallest and largest query: a whole-grid search
    per sample strayed over a 10⁶-row grid (cache misses) and cost more than the arithmetic.
    The last row ≤ q lies between the last rows ≤ the group's extremes, so it is the same."""
    def search(a, q):
        lo = np.searchsorted(a, np.minimum.reduceat(q, starts), side="right") - 1
        hi = np.searchsorted(a, np.maximum.reduceat(q, starts), side="right") - 1
        if lo[0] < 0 or np.any(np.diff(lo) < 0):      # not in increasing windows: search all
            return np.searchsorted(a, q, side="right")
        # the windows' rows, each once and in order (a window may reach into the next)
        first = np.maximum(lo, np.concatenate([[-1], np.maximum.accumulate(hi)[:-1]]) + 1)
        n = np.maximum(hi - first + 1, 0)
        rows = np.repeat(first - (np.cumsum(n) - n), n) + np.arange(int(n.sum()))
        return rows[np.searchsorted(a[rows], q, side="right") - 1] + 1
    return search


def _abs_max(x):
    """max |x| over the axes (the first index) per sample: numpy's max(axis=0) of a (3, n)
    array cost several times the elementwise maxima of its rows."""
    m = np.abs(x[0])
    for row in x[1:]:
        m = np.maximum(m, np.abs(row))
    return m
