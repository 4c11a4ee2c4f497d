"""Line/arc toolpaths: lines and circular/helical/spiral arcs (from G-code, from G64 corner
blending, or a NURBS cut into G1 lines), with exact closed forms (a spiral's arc length by
quadrature, planners.paths.spiral).
"""
from __future__ import annotations

import math

import numpy as np

from planners.paths.base import CONTIG_TOL, CORNER_ANGLE, END_TOL, Path, PathError, cross3, norm3, vec3
from planners.paths.spiral import SpiralMeasure, spiral_derivs

_CHUNK = 65536          # arc lengths per block when a segment path evaluates many at once

class Line:
    kind = "line"

    def __init__(self, start, end, line: int | None = None, where: str = "<segment>", direction=None):
        self.start = vec3(start, "line start", where)
        self.end = vec3(end, "line end", where)
        self.line = line
        self.length = norm3(self.end - self.start)
        if not self.length > CONTIG_TOL:
            raise PathError(f"{where}: zero-length line at {self.start.tolist()}")
        self.direction = (self.end - self.start) / self.length
        if direction is not None:
            # A known exact direction (e.g. a line trimmed by corner blends): for a very short
            # line, the direction of end − start would carry the rounding of both ends.
            d = np.asarray(direction, float)
            d = d / norm3(d)
            if norm3(self.start + self.length * d - self.end) > END_TOL:
                raise PathError(f"{where}: line direction {d.tolist()} does not lead from start to end")
            self.direction = d

    @classmethod
    def exact(cls, start, end, direction, line: int | None = None) -> "Line":
        """A line from geometry a planner computed (a blend's trimmed line, keeping its
        original direction): no re-validation (see Arc.exact)."""
        g = cls.__new__(cls)
        g.start, g.end, g.line, g.direction = start, end, line, direction
        g.length = norm3(end - start)
        return g

    def tangent_in(self):
        return self.direction

    def tangent_out(self):
        return self.direction

    def to_dict(self) -> dict:
        d = {"type": "line", "start": self.start.tolist(), "end": self.end.tolist()}
        if self.line is not None:
            d["line"] = int(self.line)
        return d


class Arc:
    """Circle or helix: c + Rot(n, φ)(start − c) + (φ/θ)·h·n, φ ∈ [0, θ] (contract); with a
    ``spiral`` σ ≠ 0 (mm, LinuxCNC's r_end − r_start) the radius grows linearly in φ:
    c + (1 + σφ/(θ·r0))·Rot(n, φ)(start − c) + (φ/θ)·h·n (planners.paths.spiral)."""

    kind = "arc"

    def __init__(self, start, center, normal, angle: float, rise: float = 0.0,
                 line: int | None = None, where: str = "<segment>", end=None, spiral: float = 0.0):
        self.start = vec3(start, "arc start", where)
        self.center = vec3(center, "arc center", where)
        n = vec3(normal, "arc normal", where)
        nn = norm3(n)
        if not nn > 0:
            raise PathError(f"{where}: arc normal is the zero vector")
        if abs(nn - 1.0) > 1e-6:
            raise PathError(f"{where}: arc normal {n.tolist()} is not a unit vector (|n| = {nn:.9g})")
        self.normal = n / nn
        try:
            self.angle = float(angle)
            self.rise = float(rise)
            self.spiral = float(spiral)
        except (TypeError, ValueError):
            raise PathError(f"{where}: arc angle, rise and spiral must be numbers") from None
        if not (np.isfinite(self.angle) and self.angle > 0):
            raise PathError(f"{where}: arc angle θ = {angle!r} must be > 0 (radians)")
        if not np.isfinite(self.rise):
            raise PathError(f"{where}: arc rise h = {rise!r} is not finite")
        if not np.isfinite(self.spiral):
            raise PathError(f"{where}: arc spiral = {spiral!r} is not finite")
        if self.spiral and self.angle > 1e6:      # its arc-length table has a panel per 0.5 rad
            raise PathError(f"{where}: a spiral arc's angle θ = {self.angle:.6g} rad exceeds 1e6")
        self.line = line
        off = self._derive()
        if abs(off) > END_TOL:
            raise PathError(f"{where}: arc center is {off:.6g} mm off the plane through start ⟂ normal")
        if not self.radius > CONTIG_TOL:
            raise PathError(f"{where}: arc radius is zero (center = start)")
        if not self.radius + self.spiral > CONTIG_TOL:
            raise PathError(f"{where}: arc end radius r0 + spiral = {self.radius:.9g} + {self.spiral:.9g} mm "
                            "must be > 0")
        if end is not None:
            e = vec3(end, "arc end", where)
            if norm3(e - self.end) > END_TOL:
                raise PathError(f"{where}: arc end {e.tolist()} disagrees with start/center/normal/angle/rise "
                                f"(computed {self.end.tolist()}, off by {norm3(e - self.end):.3g} mm)")

    @classmethod
    def exact(cls, start, center, normal, angle: float, line: int | None = None, spiral: float = 0.0) -> "Arc":
        """A planar arc from geometry a planner computed (a G64 blend, a trimmed arc): no
        re-validation, which costs more than the arc itself when a program has 10⁵ corners."""
        g = cls.__new__(cls)
        g.start, g.center, g.normal, g.angle, g.rise, g.line = start, center, normal, angle, 0.0, line
        g.spiral = spiral
        g._derive()
        return g

    @classmethod
    def from_parts(cls, start, center, normal, angle: float, line, a, b, radius: float, length: float,
                   end) -> "Arc":
        """A circular arc whose derived values (what _derive computes) the caller computed
        for many arcs at once (planners.paths.blend)."""
        g = cls.__new__(cls)
        g.start, g.center, g.normal, g.angle, g.rise, g.line = start, center, normal, angle, 0.0, line
        g.a, g.b, g.radius, g.length, g.end, g.spiral = a, b, radius, length, end, 0.0
        return g

    def _derive(self) -> float:
        """In-plane basis a, b, radius, length and end; returns the centre's offset from the plane."""
        a = self.start - self.center
        nv = self.normal
        off = float(a[0] * nv[0] + a[1] * nv[1] + a[2] * nv[2])
        self.a = a - off * nv
        self.b = cross3(nv, self.a)
        self.radius = norm3(self.a)
        if self.spiral:
            th = self.angle
            self._measure = SpiralMeasure(self.radius, self.spiral / th, self.rise / th, th)
            self.length = self._measure.length
            grow = 1.0 + self.spiral / self.radius      # end radius / start radius
            self.end = self.center + grow * (math.cos(th) * self.a + math.sin(th) * self.b) + self.rise * nv
            return off
        self.length = float(self.angle * math.hypot(self.radius, self.rise / self.angle))
        # eval() at φ = θ for one point, without arrays
        self.end = self.center + math.cos(self.angle) * self.a + math.sin(self.angle) * self.b + self.rise * nv
        return off

    def _spiral_eval(self, phi: np.ndarray, order: int) -> list[np.ndarray]:
        r0, th = self.radius, self.angle
        frame = (self.center, self.a / r0, self.b / r0, self.normal)
        return spiral_derivs(phi, r0, self.spiral / th, self.rise / th, frame, order)

    def at_angle(self, phi: np.ndarray, order: int) -> list[np.ndarray]:
        """Point and s-derivatives at sweep angles φ (N,) from the start."""
        if self.spiral:
            return self._spiral_eval(phi, order)
        return self.eval(phi * (self.length / self.angle), order)

    def ds_dphi(self, phi: float) -> float:
        """Arc length per radian of sweep at φ."""
        return float(self._measure.speed(phi)) if self.spiral else self.length / self.angle

    def planar_point(self, phi: float) -> np.ndarray:
        """The point at sweep φ without the rise (blends are planar)."""
        if not self.spiral:
            return self.center + math.cos(phi) * self.a + math.sin(phi) * self.b
        grow = 1.0 + self.spiral * phi / (self.angle * self.radius)
        return self.center + grow * (math.cos(phi) * self.a + math.sin(phi) * self.b)

    def eval(self, t: np.ndarray, order: int) -> list[np.ndarray]:
        """Point and s-derivatives at arc length t from the arc start."""
        if self.spiral:
            return self._spiral_eval(self._measure.phi_of(t), order)
        k = self.angle / self.length                # dφ/ds
        phi = (t * k)[:, None]
        c, s_ = np.cos(phi), np.sin(phi)
        hn = (self.rise / self.angle) * self.normal
        out = [self.center + c * self.a + s_ * self.b + phi * hn]
        if order >= 1:
            out.append(k * (-s_ * self.a + c * self.b + hn))
        if order >= 2:
            out.append(k**2 * (-c * self.a - s_ * self.b))
        if order >= 3:
            out.append(k**3 * (s_ * self.a - c * self.b))
        return out

    def _tangent(self, phi: float) -> np.ndarray:
        """dP/ds at sweep φ: the first derivative of eval() for one point, without arrays."""
        if self.spiral:
            return self._spiral_eval(np.array([phi]), 1)[1][0]
        k = self.angle / self.length
        hn = (self.rise / self.angle) * self.normal
        return k * (-math.sin(phi) * self.a + math.cos(phi) * self.b + hn)

    def tangent_in(self):
        return self._tangent(0.0)

    def tangent_out(self):
        return self._tangent(self.angle)

    def to_dict(self) -> dict:
        d = {"type": "arc", "start": self.start.tolist(), "center": self.center.tolist(),
             "normal": self.normal.tolist(), "angle": self.angle, "rise": self.rise}
        if self.spiral:
            d["spiral"] = self.spiral            # absent: 0 (a circle or helix), as before
        d["end"] = self.end.tolist()
        if self.line is not None:
            d["line"] = int(self.line)
        return d


def segment_from_dict(d: dict, where: str):
    if not isinstance(d, dict) or "type" not in d:
        raise PathError(f"{where}: a segment must be an object with a 'type'")
    line = d.get("line")
    try:
        if d["type"] == "line":
            return Line(d["start"], d["end"], line, where)
        if d["type"] == "arc":
            return Arc(d["start"], d["center"], d["normal"], d["angle"], d.get("rise", 0.0),
                       line, where, end=d.get("end"), spiral=d.get("spiral", 0.0))
    except KeyError as e:
        raise PathError(f"{where}: {d['type']} segment lacks {e}") from None
    raise PathError(f"{where}: unknown segment type {d['type']!r} (line | arc)")


class SegmentPath(Path):
    """Consecutive lines and arcs; s runs from 0 at the first start to the total length."""

    kind = "segments"

    def __init__(self, segments, source: str = "<segments>", program=None):
        self.source = source
        # the G-code program the segments were read from (planners.paths.gcode), or None
        self.program = program
        self._corners = None
        segs = list(segments)
        if not segs:
            raise PathError(f"{source}: empty path (no segments)")
        starts_all = np.array([g.start for g in segs])
        if len(segs) > 1:
            starts = starts_all[1:]
            gaps = np.linalg.norm(starts - np.array([g.end for g in segs[:-1]]), axis=1)
            bad = np.nonzero(gaps > CONTIG_TOL * np.maximum(1.0, np.abs(starts).max(axis=1)))[0]
            if len(bad):
                i, gap = int(bad[0]) + 1, float(gaps[bad[0]])
                ln = f" (G-code line {segs[i].line})" if segs[i].line is not None else ""
                raise PathError(f"{source}: segment #{i}{ln} starts {gap:.3g} mm away from the end "
                                f"of segment #{i - 1}: segments must be contiguous")
        self.segments = segs
        lens = np.array([g.length for g in segs])
        self.seg_start = np.concatenate([[0.0], np.cumsum(lens)])
        self.length = float(self.seg_start[-1])
        # Vectorised tables (lines use a = direction, arcs the circle frame; zeros elsewhere).
        n = len(segs)
        self._is_arc = np.array([g.kind == "arc" for g in segs])
        arcs = [g for g in segs if g.kind == "arc"]
        ia, il = np.nonzero(self._is_arc)[0], np.nonzero(~self._is_arc)[0]
        self._origin = starts_all.copy()
        self._dir, self._a, self._b, self._hn = (np.zeros((n, 3)) for _ in range(4))
        self._k = np.zeros(n)
        if len(il):
            self._dir[il] = np.array([segs[i].direction for i in il.tolist()])
        if arcs:
            self._origin[ia] = np.array([g.center for g in arcs])
            self._a[ia] = np.array([g.a for g in arcs])
            self._b[ia] = np.array([g.b for g in arcs])
            self._hn[ia] = np.array([(g.rise / g.angle) * g.normal for g in arcs])
            self._k[ia] = [g.angle / g.length for g in arcs]
        # spiral arcs: the tables above hold their circle; _derivs overwrites their rows
        self._spiral = np.array([g.kind == "arc" and bool(g.spiral) for g in segs])
        self._lens = lens
        assert len(self._k) == n
        # each table's x, y, z columns as contiguous rows: _derivs gathers a column per axis,
        # and take() from a contiguous row is faster than indexing the (n, 3) table
        self._columns = tuple(np.ascontiguousarray(tab.T) for tab in (self._origin, self._a, self._b, self._hn, self._dir))

    @classmethod
    def from_dict(cls, d: dict, source: str = "<segments>") -> "SegmentPath":
        if d.get("units", "mm") != "mm":
            raise PathError(f"{source}: units must be 'mm', got {d.get('units')!r}")
        segs = d.get("segments")
        if not isinstance(segs, list):
            raise PathError(f"{source}: a segments path needs a list 'segments'")
        return cls([segment_from_dict(g, f"{source}: segment #{i}") for i, g in enumerate(segs)], source)

    def to_dict(self) -> dict:
        return {"type": "segments", "units": "mm", "segments": [g.to_dict() for g in self.segments]}

    def segment_index(self, s: np.ndarray) -> np.ndarray:
        """Index of the segment holding each s (a junction belongs to the outgoing segment)."""
        return np.clip(np.searchsorted(self.seg_start, s, side="right") - 1, 0, len(self.segments) - 1)

    def _derivs(self, s: np.ndarray, order: int) -> list[np.ndarray]:
        if len(s) > _CHUNK:
            # ~15 temporaries of (N, 3) each: a 10⁶-sample profile in one go peaked at ~0.5 GB;
            # element-wise, so chunks give the same bits
            parts = [self._derivs(s[k:k + _CHUNK], order) for k in range(0, len(s), _CHUNK)]
            return [np.concatenate([p[d] for p in parts]) for d in range(order + 1)]
        i = self.segment_index(s)
        t = np.minimum(s - self.seg_start[i], self._lens[i])
        arc = self._is_arc[i]
        k = self._k[i]
        phi = t * k
        c, sn = np.cos(phi), np.sin(phi)
        k2, k3 = k ** 2, k ** 3
        out = [np.empty((len(s), 3)) for _ in range(order + 1)]
        # one axis at a time on (N,) arrays (the same operations as on (N, 3) ones broadcast
        # against (N, 1): numpy ran those in inner loops of 3, twice the time)
        origin, A, B, HN, D = self._columns
        for x in range(3):
            a, b, hn, d = A[x].take(i), B[x].take(i), HN[x].take(i), D[x].take(i)
            out[0][:, x] = origin[x].take(i) + np.where(arc, c * a + sn * b + phi * hn, t * d)
            if order >= 1:
                out[1][:, x] = np.where(arc, k * (-sn * a + c * b + hn), d)
            if order >= 2:
                out[2][:, x] = np.where(arc, k2 * (-c * a - sn * b), 0.0)
            if order >= 3:
                out[3][:, x] = np.where(arc, k3 * (sn * a - c * b), 0.0)
        if self._spiral.any():
            self._spiral_rows(out, i, t, order)
        return out

    def _spiral_rows(self, out, i: np.ndarray, t: np.ndarray, order: int) -> None:
        """Overwrite the rows of ``out`` that fall on spiral arcs with their exact values."""
        on = self._spiral[i]
        for j in np.unique(i[on]).tolist():
            rows = np.nonzero(i == j)[0]
            vals = self.segments[j].eval(t[rows], order)
            for d in range(order + 1):
                out[d][rows] = vals[d]

    def corners(self) -> np.ndarray:
        # segments are immutable: the tangent breaks are computed once, all joins at a time
        if self._corners is None:
            if len(self.segments) < 2:
                self._corners = np.array([])
            else:
                # unit tangents from the struct-of-arrays tables: a line's direction; an arc's
                # k·(b + hn) at φ = 0 and k·(−sin θ·a + cos θ·b + hn) at φ = θ
                th = np.array([g.angle if g.kind == "arc" else 0.0 for g in self.segments])[:, None]
                arc, k = self._is_arc[:, None], self._k[:, None]
                t_in = np.where(arc, k * (self._b + self._hn), self._dir)
                t_out = np.where(arc, k * (-np.sin(th) * self._a + np.cos(th) * self._b + self._hn), self._dir)
                for j in np.nonzero(self._spiral)[0].tolist():
                    t_in[j], t_out[j] = self.segments[j].tangent_in(), self.segments[j].tangent_out()
                t0, t1 = t_out[:-1], t_in[1:]
                c = np.einsum("ij,ij->i", t0, t1) / (np.linalg.norm(t0, axis=1) * np.linalg.norm(t1, axis=1))
                sharp = np.arccos(np.clip(c, -1.0, 1.0)) > CORNER_ANGLE
                self._corners = np.asarray(self.seg_start[1:len(self.segments)][sharp], float)
        return self._corners.copy()

    def segment_joins(self) -> np.ndarray:
        return self.seg_start[1:-1]

    def line_at(self, s) -> np.ndarray:
        """G-code line number (or −1) of the segment at each arc length (for messages)."""
        a, _ = self._check_s(s)
        lines = np.array([-1 if g.line is None else g.line for g in self.segments])
        return lines[self.segment_index(a)]
