"""The toolpath base: one geometry, parametrised by arc length s (mm), shared by every planner.

Every path gives ``length``, ``point(s)``, ``derivs(s)`` (P, P′, P″, P‴ with respect to arc
length), ``curvature(s)``, ``corners()`` (arc lengths where the tangent is discontinuous:
the exact-stop points), ``segment_joins()``, ``line_at(s)``, ``bounds()`` and ``to_file(file)``.
The kinds are :mod:`planners.paths.nurbs` and :mod:`planners.paths.segments`.
"""
from __future__ import annotations

import gc
import json
import math
import threading
from contextlib import contextmanager

import numpy as np

S_TOL = 1e-9            # mm: arc lengths this far outside [0, L] are clipped, beyond → error
CONTIG_TOL = 1e-9       # mm: consecutive segments must join this closely (file contract)
END_TOL = 1e-6          # mm: an arc's redundant "end" must agree this closely
CORNER_ANGLE = 1e-6     # rad: a tangent turn larger than this is a corner (exact stop)


class PathError(ValueError):
    """A toolpath is malformed or a query is outside it; the message names file and problem."""


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b of two 3-vectors (np.cross costs ~15 µs a call; paths build one per segment)."""
    # on Python floats: the same IEEE operations as on numpy's scalars, which cost more each
    a0, a1, a2 = a.tolist() if type(a) is np.ndarray else a
    b0, b1, b2 = b.tolist() if type(b) is np.ndarray else b
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def vec3(v, what: str, where: str) -> np.ndarray:
    a = np.asarray(v, float)
    # math.isfinite on three floats: np.isfinite(a).all() costs ~3 µs, paths build 10⁵ of these
    if a.shape != (3,) or not (math.isfinite(a[0]) and math.isfinite(a[1]) and math.isfinite(a[2])):
        raise PathError(f"{where}: {what} must be 3 finite numbers [x, y, z], got {v!r}")
    return a


def norm3(v) -> float:
    """|v| of one 3-vector (np.linalg.norm costs ~3 µs a call)."""
    x, y, z = v.tolist() if type(v) is np.ndarray else v      # Python floats, as cross3
    return math.sqrt(x * x + y * y + z * z)


class Path:
    """Base class: a curve from s = 0 to s = length (mm)."""

    kind = "abstract"
    length: float
    source: str
    program = None      # the G-code program a path was read from (planners.paths.gcode), else None
    feed_mode = "programmed"   # or "max": G-code run at F_max, its F words ignored (planners.feed)

    # -- subclasses -------------------------------------------------------------------
    def _derivs(self, s: np.ndarray, order: int) -> list[np.ndarray]:
        raise NotImplementedError

    def corners(self) -> np.ndarray:
        raise NotImplementedError

    def to_dict(self) -> dict:
        raise NotImplementedError

    def segment_joins(self) -> np.ndarray | None:
        """Interior arc lengths where the path's pieces join, when the path knows them (the
        segment ends of a line/arc path); None when they must be searched (a NURBS)."""
        return None

    def line_at(self, s) -> np.ndarray:
        """G-code line number of the segment at each arc length (−1: none; for messages)."""
        a, _ = self._check_s(s)
        return np.full(len(a), -1)

    # -- public -------------------------------------------------------------------------
    def _check_s(self, s) -> tuple[np.ndarray, bool]:
        a = np.asarray(s, float)
        scalar = a.ndim == 0
        a = np.atleast_1d(a).ravel()
        if not np.isfinite(a).all():
            i = int(np.argmax(~np.isfinite(a)))
            raise PathError(f"{self.source}: arc length #{i} is {a[i]} (not finite)")
        if len(a) and (a.min() < -S_TOL or a.max() > self.length + S_TOL):
            i = int(np.argmax((a < -S_TOL) | (a > self.length + S_TOL)))
            raise PathError(f"{self.source}: arc length #{i} = {a[i]:.12g} mm is outside "
                            f"the path [0, {self.length:.12g}] mm")
        return np.clip(a, 0.0, self.length), scalar

    def point(self, s) -> np.ndarray:
        """Points (N, 3) at arc lengths s (mm); a scalar s gives shape (3,)."""
        a, scalar = self._check_s(s)
        P = self._remembered(a, 0)[0]
        return P[0] if scalar else P

    def derivs(self, s) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(P, dP/ds, d²P/ds², d³P/ds³) at arc lengths s, each (N, 3).

        At a corner the outgoing (right-hand) values are returned, at s = length the
        incoming ones.
        """
        a, _ = self._check_s(s)
        return self._remembered(a, 3)

    def _remembered(self, a: np.ndarray, order: int) -> tuple[np.ndarray, ...]:
        """_derivs(a, order), copies of the last results kept (_MEMO): a planner asks
        again for the stations it solved on (its checks, its lower bound), and a NURBS
        inverts its arc length at each (Newton on a Gauss–Legendre quadrature)."""
        token = self.__dict__.get("_memo_token")
        if token is None:
            token = self.__dict__["_memo_token"] = _Token()
        key = (token, order, a.tobytes())
        out = _MEMO.get(key)
        if out is None:
            out = tuple(self._derivs(a, order))
            _MEMO.put(key, out)
        return tuple(x.copy() for x in out)

    def tangent(self, s) -> np.ndarray:
        a, _ = self._check_s(s)
        return self._derivs(a, 1)[1]

    def curvature(self, s) -> np.ndarray:
        """κ(s) = |d²P/ds²| (1/mm), shape (N,)."""
        a, _ = self._check_s(s)
        return np.linalg.norm(self._derivs(a, 2)[2], axis=1)

    def sample(self, ds: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
        """(s, P) on a uniform grid of step ≤ ds that includes both ends."""
        n = max(2, int(np.ceil(self.length / ds)) + 1)
        s = np.linspace(0.0, self.length, n)
        return s, self.point(s)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(min xyz, max xyz) of the path, from dense sampling (step ≤ 0.05 mm) and corners."""
        s, P = self.sample(min(0.05, self.length / 16))
        return P.min(axis=0), P.max(axis=0)

    def to_file(self, file) -> None:
        """Write the path file (JSON, 17 significant digits) that Interpolator.fmu reads."""
        with open(file, "w") as f:
            json.dump(self.to_dict(), f, indent=1)
            f.write("\n")

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.source!r} length={self.length:.6g} mm>"


class _Token:
    """A path's key in _MEMO: compared by identity, a new one for a path's pickled or deep copy
    (another process's keys are its own)."""

    def __reduce__(self):
        return _Token, ()


class _DerivsMemo:
    """The process's last path evaluations ((path, order, arc lengths) → derivatives), up to
    MAX_BYTES of results, the oldest dropped first; thread-safe (a sweep's threads share it)."""

    MAX_BYTES = 64 << 20

    def __init__(self):
        self._items: dict = {}
        self._lock = threading.Lock()

    def get(self, key):
        with self._lock:
            out = self._items.pop(key, None)
            if out is not None:
                self._items[key] = out            # the newest again
            return out

    def put(self, key, value) -> None:
        with self._lock:
            self._items[key] = value
            size = lambda kv: len(kv[0][-1]) + sum(x.nbytes for x in kv[1])
            while len(self._items) > 1 and sum(map(size, self._items.items())) > self.MAX_BYTES:
                del self._items[next(iter(self._items))]


_MEMO = _DerivsMemo()


@contextmanager
def gc_paused():
    """Pause the cyclic garbage collector while 10⁵ segment objects are built: its full
    passes over the growing object graph cost ~30 % of reading and blending a 10⁵-line
    program. Nothing is freed later than it would be but cycles (collected on resuming)."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()
