"""The feed profile: what every planner returns and Interpolator.fmu replays.

A profile is the arc length s(t) along one path geometry and its derivatives, sampled at
the servo period T from t = 0 (rest at the path start) to the end (rest at the path end).
File form (the `profile_file` of Interpolator.fmu): CSV ``t,s,sd,sdd,sddd`` with 17
significant digits, so a round trip through the file is exact.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path as FsPath
from typing import Any

import numpy as np

from planners.errors import PlanningError

HEADER = "t,s,sd,sdd,sddd"
# samples a profile may have (5 arrays of them: 0.8 GB): 83 min at 250 µs.  A planner's wild
# intermediate profile (2.4·10⁵ s) once asked for 7 GB and a run was killed for memory
MAX_SAMPLES = 20_000_000


class ProfileError(ValueError):
    """A profile is inconsistent (runs backwards, does not end at rest, NaN, …)."""


class Rest:
    """A piece of `Profile.from_pieces` at rest at s = 0 for ``duration`` s: put first, it
    delays the motion's start, so its samples at T fall at another phase of the servo clock."""
    s0 = 0.0

    def __init__(self, duration: float):
        self.duration = duration

    def at(self, tt):
        z = np.zeros(len(tt))
        return z, z, z, z


@dataclass
class Profile:
    planner: str
    T: float                      # servo period, s
    s: np.ndarray                 # arc length, mm
    sd: np.ndarray                # ṡ, mm/s
    sdd: np.ndarray               # s̈, mm/s²
    sddd: np.ndarray              # s⃛, mm/s³
    path: Any                     # the geometry s refers to (planners.paths.Path)
    planning_time_s: float = 0.0
    info: dict = field(default_factory=dict)   # planner diagnostics (JSON-serialisable)
    _points: Any = field(default=None, repr=False, compare=False)   # (s, path.point(s)) of points()

    @property
    def t(self) -> np.ndarray:
        return np.arange(len(self.s)) * self.T

    @property
    def execution_time_s(self) -> float:
        return (len(self.s) - 1) * self.T

    def points(self) -> np.ndarray:
        """path.point(s), the commanded Cartesian positions, computed once: a planner that reads
        its own result at T and the metrics after it read the same array (a NURBS point is a
        Newton solve of its arc length)."""
        if self._points is None or self._points[0] is not self.s:
            self._points = (self.s, self.path.point(self.s))
        return self._points[1]

    @classmethod
    def from_s(cls, planner: str, T: float, s: np.ndarray, path, **kw) -> "Profile":
        """Build a profile from s sampled at T; derivatives by differences at T.

        Backward differences, matching how the metrics read the trajectory: sd[k] is the
        mean speed over the period ending at t_k (0 at k = 0).
        """
        s = np.asarray(s, float)
        sd = np.zeros_like(s)
        sdd = np.zeros_like(s)
        sddd = np.zeros_like(s)
        sd[1:] = np.diff(s) / T
        sdd[1:] = np.diff(sd) / T
        sddd[1:] = np.diff(sdd) / T
        return cls(planner, T, s, sd, sdd, sddd, path, **kw)

    @classmethod
    def from_pieces(cls, planner: str, T: float, pieces, path, info: dict | None = None) -> "Profile":
        """Sample pieces laid end to end from t = 0 at exact multiples of T, ending at s = L at rest.

        Each piece has ``duration`` (s), ``s0`` (mm, its start on the path) and ``at(tt)`` →
        (s − s0, ṡ, s̈, s⃛) at local times tt ∈ [0, duration] (arrays).  The samples after the last
        piece's end evaluate it there; s is made monotone, ≤ L and 0 at t = 0.  info gains the
        pieces' total ``continuous_time_s``.
        """
        starts = np.concatenate([[0.0], np.cumsum([g.duration for g in pieces])])
        total = float(starts[-1])
        N = max(1, int(math.ceil(total / T - 1e-9))) if math.isfinite(total) else math.inf
        if N > MAX_SAMPLES:
            raise PlanningError(f"{planner}: a profile of {total:.6g} s would take {N:.4g} samples at T = "
                                f"{T:g} s, more than {MAX_SAMPLES:.0e}: not sampled")
        t = np.arange(N + 1) * T
        s = np.empty(N + 1)
        sd, sdd, sddd = np.zeros(N + 1), np.zeros(N + 1), np.zeros(N + 1)
        if (np.diff(starts) >= 0).all():
            # each piece's samples are one slice: piece i (0 < i < last) starts at the first
            # t ≥ its start (the slices of the per-sample piece index below, without its
            # arrays of N samples, fresh memory that is slow to touch)
            bounds = np.r_[0, np.searchsorted(t, starts[1:-1], side="left"), N + 1]
        else:
            k = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(pieces) - 1)
            # k is sorted: each piece's samples are one slice (a mask per piece was O(pieces × N))
            bounds = np.searchsorted(k, np.arange(len(pieces) + 1), side="left")
        for i, g in enumerate(pieces):
            m = slice(bounds[i], bounds[i + 1])
            if m.stop > m.start:
                p, v, a, j = g.at(t[m] - starts[i])
                np.add(g.s0, p, out=s[m])           # s0 + p, straight into s
                sd[m], sdd[m], sddd[m] = v, a, j
        L = path.length
        s = np.minimum(np.maximum.accumulate(s, out=s), L, out=s)     # in place: no fresh arrays
        s[0] = 0.0
        s[-1], sd[-1], sdd[-1], sddd[-1] = L, 0.0, 0.0, 0.0
        return cls(planner, T, s, sd, sdd, sddd, path, info=dict(info or {}, continuous_time_s=total))

    def validate(self, length: float | None = None, tol: float = 1e-9) -> None:
        """Raise ProfileError unless the profile is finite, monotone and at rest at both ends."""
        arrays = {"s": self.s, "sd": self.sd, "sdd": self.sdd, "sddd": self.sddd}
        n = len(self.s)
        if n < 2:
            raise ProfileError(f"{self.planner}: profile has {n} sample(s); need ≥ 2")
        for k, a in arrays.items():
            if len(a) != n:
                raise ProfileError(f"{self.planner}: {k} has {len(a)} samples, s has {n}")
            if not np.isfinite(a).all():
                i = int(np.argmax(~np.isfinite(a)))
                raise ProfileError(f"{self.planner}: {k}[{i}] (t = {i * self.T:.6g} s) is not finite")
        if not self.T > 0:
            raise ProfileError(f"{self.planner}: servo period T = {self.T} must be > 0")
        back = np.diff(self.s) < -tol
        if back.any():
            i = int(np.argmax(back)) + 1
            raise ProfileError(f"{self.planner}: profile runs backwards at sample {i} "
                               f"(t = {i * self.T:.6g} s): s {self.s[i - 1]:.12g} → {self.s[i]:.12g} mm")
        if abs(self.s[0]) > tol:
            raise ProfileError(f"{self.planner}: profile starts at s = {self.s[0]:.12g} mm, not 0")
        L = self.path.length if length is None else length
        if abs(self.s[-1] - L) > tol:
            raise ProfileError(f"{self.planner}: profile ends at s = {self.s[-1]:.12g} mm, "
                               f"path length is {L:.12g} mm")

    # -- file form ------------------------------------------------------------------
    def save_csv(self, file) -> None:
        data = np.column_stack([self.t, self.s, self.sd, self.sdd, self.sddd])
        np.savetxt(file, data, delimiter=",", header=HEADER, comments="", fmt="%.17g")

    @classmethod
    def load_csv(cls, file, path, planner: str = "file") -> "Profile":
        file = FsPath(file)
        try:
            with open(file) as f:
                head = f.readline().strip()
            if head != HEADER:
                raise ProfileError(f"{file}: header is '{head}', expected '{HEADER}'")
            data = np.loadtxt(file, delimiter=",", skiprows=1, ndmin=2)
        except OSError as e:
            raise ProfileError(f"{file}: cannot read profile: {e.strerror}") from None
        except ValueError as e:
            raise ProfileError(f"{file}: malformed profile: {e}") from None
        if data.shape[1] != 5 or len(data) < 2:
            raise ProfileError(f"{file}: expected ≥ 2 rows of 5 columns, got shape {data.shape}")
        T = float(data[1, 0] - data[0, 0])
        return cls(planner, T, data[:, 1], data[:, 2], data[:, 3], data[:, 4], path)
