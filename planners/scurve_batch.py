"""The s-curve's segment checks (planners.scurve) for many segments in one numpy pass.

A round of the repair loop checks every changed segment, and each repair tests a segment at
several J and A values: a Python pass per test (~30 numpy calls on ~100 samples) made a
10⁵-line program take minutes. Here the tests of one round are run in lockstep
(:func:`drive`) and each step's tests are evaluated together (:class:`Checker`). Every value
is computed with the same floating-point operations in the same order as the per-segment
form it replaces (phase samples, ``Segment.at``, the table, the reads at T of the joins), and
maxima are exact, so the plan is the same bit for bit.
"""
from __future__ import annotations

import numpy as np

from .constraints import JUMP_READ_FACTOR, time_derivs

CHUNK_POINTS = 200_000     # samples per numpy pass: bounds the temporaries (~20 arrays of (n, 3))


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
    joins at its ends, and per read (end, signed read per axis, max and min of the continuous
    jerk within 3T of that end)."""

    __slots__ = ("r", "r0", "reads")

    def __init__(self, r, r0, reads):
        self.r, self.r0, self.reads = r, r0, reads


class Stack:
    """The seven phases of many fitted segments, flat: jerk 7 per segment, the boundary states
    a, v, p 8 per segment (ruckig's), ``tcum`` (N, 8)."""

    def __init__(self, segs):
        self.s0 = np.array([g.s0 for g in segs], float)
        self.L = np.array([g.L for g in segs], float)
        self.v0 = np.array([g.v0 for g in segs], float)
        self.v1 = np.array([g.v1 for g in segs], float)
        self.dur = np.array([g.duration for g in segs], float)
        self.tcum = np.array([g.tcum for g in segs]).reshape(len(segs), 8)
        self.j = np.array([g.j for g in segs]).reshape(-1)
        self.a, self.v, self.p = (np.array([getattr(g, k) for g in segs]).reshape(-1) for k in ("a", "v", "p"))
        self.n_state = len(self.a) // max(len(segs), 1)

    def at(self, idx, tt):
        """Segment.at of segment idx[k] at tt[k] (the same operations in the same order)."""
        tc = self.tcum[idx]
        tt = np.minimum(np.maximum(tt, 0.0), self.dur[idx])
        # searchsorted(tcum, tt, "right") − 1, as tcum[0] = 0 ≤ tt and tcum is sorted
        k = np.minimum((tc[:, 1:] <= tt[:, None]).sum(axis=1), 6)
        dt = tt - tc[np.arange(len(idx)), k]
        j = self.j[idx * 7 + k]
        row = idx * self.n_state + k
        a0, v0, p0 = self.a[row], self.v[row], self.p[row]
        a = a0 + j * dt
        v = v0 + a0 * dt + j * dt * dt / 2
        p = p0 + v0 * dt + a0 * dt * dt / 2 + j * dt ** 3 / 6
        return p, v, a, j


def phase_grid(a, b, T):
    """np.linspace(a, b, min(4000, max(16, ⌈(b − a)/T⌉))) of every phase [a, b] with b > a,
    concatenated, and the phases' sample counts: numpy's linspace values (k·step + a, the end
    set to b; k/div·Δ + a where the step underflows), without a Python call per phase."""
    keep = b > a
    a, b = a[keep], b[keep]
    n = np.minimum(4000, np.maximum(16, np.ceil((b - a) / T))).astype(np.int64)
    first = np.cumsum(n) - n
    ph = np.repeat(np.arange(len(n)), n)
    k = (np.arange(int(n.sum())) - first[ph]).astype(float)
    delta, div = b - a, (n - 1).astype(float)
    step = delta / div
    y = np.where(step[ph] == 0, k / div[ph] * delta[ph], k * step[ph]) + a[ph]
    y[first + n - 1] = b
    return y, n


def _unique_per_segment(t, seg):
    """(times, segment index) sorted by segment then time, exact duplicates within a segment
    dropped: np.unique per segment."""
    order = np.lexsort((t, seg))
    t, seg = t[order], seg[order]
    keep = np.ones(len(t), bool)
    keep[1:] = (t[1:] != t[:-1]) | (seg[1:] != seg[:-1])
    return t[keep], seg[keep]


class Checker:
    """The tests of :meth:`planners.scurve._Planner.fit_peak` and of the segment check, for many
    segments at once; ``pl`` is the planner (its grid, FLF, tables, joins and check limits)."""

    def __init__(self, pl):
        self.pl = pl

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
        est = np.where(d > 0, np.minimum(4000, np.maximum(16, np.ceil(d / T))) + 1, 0).sum(axis=1) + 2
        ends = np.searchsorted(np.cumsum(est), np.arange(1, int(est.sum() // CHUNK_POINTS) + 2) * CHUNK_POINTS)
        out, c = [], 0
        for e in np.unique(np.minimum(np.maximum(ends + 1, 1), len(segs))).tolist():
            if e > c:
                out += self._check_chunk(st, np.arange(c, e))
                c = e
        return out

    def times(self, st, segs):
        """Sorted sample times per segment of ``segs`` (and their segment index): every jerk
        phase on its own (≥ 16 points, ≤ T apart), just inside each phase's end (at a phase's
        end at() reads the next phase's jerk) and at the refined rows of the table."""
        T, fine = self.pl.T, self.pl.fine_s
        tc = st.tcum[segs]
        a, b = tc[:, :-1], tc[:, 1:]
        y, n = phase_grid(a.ravel(), b.ravel(), T)
        d = b - a
        rows, _ = np.nonzero(d > 0)
        t = np.concatenate([y, np.zeros(len(segs)), st.dur[segs], (b - 1e-9 * d)[d > 0]])
        seg = np.concatenate([np.repeat(segs[rows], n), segs, segs, segs[rows]])
        t, seg = _unique_per_segment(t, seg)
        lo, hi = np.searchsorted(fine, st.s0[segs]), np.searchsorted(fine, st.s0[segs] + st.L[segs])
        with_fine = np.nonzero(hi > lo)[0]
        if len(with_fine):
            # the times of the refined rows inside a segment (p(t) is monotone): a jerk peak
            # narrower than a period's travel falls between samples ≤ T apart
            extra_t, extra_seg = [], []
            for k in with_fine.tolist():
                g = segs[k]
                a_, b_ = np.searchsorted(seg, [g, g + 1])
                p = st.at(seg[a_:b_], t[a_:b_])[0]
                extra_t.append(np.interp(fine[lo[k]:hi[k]] - st.s0[g], p, t[a_:b_]))
                extra_seg.append(np.full(hi[k] - lo[k], g))
            t, seg = _unique_per_segment(np.concatenate([t] + extra_t), np.concatenate([seg] + extra_seg))
        return t, seg

    def _check_chunk(self, st, segs):
        pl = self.pl
        T, lim = pl.T, pl.check
        tt, idx = self.times(st, segs)
        p, v, a, j = st.at(idx, tt)
        s0 = st.s0[idx]
        # evaluate just inside the segment: at a corner the derivatives are one-sided
        s = np.clip(s0 + p, s0 + 1e-9, (st.s0 + st.L)[idx] - 1e-9)
        D = pl.table.joints(s) if pl.joint else pl.table.cartesian(s)
        xv, xa, xj = time_derivs(D[0], D[1], D[2], v, a, j)
        starts = np.searchsorted(idx, segs)
        peak = lambda x: np.maximum.reduceat(np.abs(x).max(axis=1), starts)
        mv, ma, mj = peak(xv), peak(xa), peak(xj)
        reads, hi, lo = self._reads(st, segs, tt, idx, xj, starts)
        mjr = mj if hi is None else peak(np.maximum(np.abs(hi), np.abs(lo)))
        r0 = np.column_stack([mv / lim.v, ma / lim.a, mj / lim.j])
        r = np.column_stack([mv / lim.v, ma / lim.a, mjr / lim.j])
        return [Check(r[k], r0[k], reads[k]) for k in range(len(segs))]

    def _reads(self, st, segs, tt, idx, xj, starts):
        """The reads at T of the joins at the segments' ends: a third difference at T is the jerk
        averaged by a quadratic B-spline kernel (support 3T, peak 0.75/T), so the jump Δx″v² of
        the acceleration at a join adds up to JUMP_READ_FACTOR·Δx″v²/T, with its sign, to the
        continuous jerk within 3T of it (without it a segment next to a join passes its own check
        and not the one at T). Returns (per segment [(end, read, max and min of the jerk near
        that end)], the jerk with the positive and with the negative reads added, or None, None)."""
        pl = self.pl
        T, joins, d2 = pl.T, pl.joins, pl.join_d2
        reads = [[] for _ in segs]
        hi = lo = None
        for end, s_end, v_end in ((0, st.s0[segs], st.v0[segs]), (1, st.s0[segs] + st.L[segs], st.v1[segs])):
            near = tt <= 3 * T if end == 0 else tt >= st.dur[idx] - 3 * T
            k = np.searchsorted(joins, s_end)
            for n in (k - 1, k):          # a join within 1 µm (merged critical points)
                nn = np.clip(n, 0, max(len(joins) - 1, 0))
                ok = (n >= 0) & (n < len(joins)) & (v_end > 0)
                if len(joins):
                    ok &= np.abs(joins[nn] - s_end) < 1e-3
                which = np.nonzero(ok)[0]
                if len(which) == 0:
                    continue
                # v² as the scalar power of the per-segment form (an array's square can differ in the last bit)
                vsq = np.array([x ** 2 for x in v_end[which].tolist()])
                read = np.zeros((len(segs), d2.shape[1]))
                read[which] = JUMP_READ_FACTOR * d2[nn[which]] * vsq[:, None] / T
                pos = np.nonzero(np.isin(idx, segs[which]))[0]     # rows of those segments
                m = near[pos][:, None]
                r_at = read[np.searchsorted(segs, idx[pos])]
                if hi is None:
                    hi, lo = xj.copy(), xj.copy()
                hi[pos] = hi[pos] + m * np.maximum(r_at, 0)
                lo[pos] = lo[pos] + m * np.minimum(r_at, 0)
                big = np.where(near[:, None], xj, -np.inf)
                small = np.where(near[:, None], xj, np.inf)
                jmax, jmin = np.maximum.reduceat(big, starts), np.minimum.reduceat(small, starts)
                for w in which.tolist():
                    reads[w].append((end, read[w], jmax[w], jmin[w]))
        return reads, hi, lo
