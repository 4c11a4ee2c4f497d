"""Motion of one block, mixed into the Interpreter: the end point (interp_find.cc's find_ends,
polar @ ^ included), straight moves (interp_convert.cc's convert_straight) and arcs
(convert_arc2, with interp_arc.cc's arc_data_r and arc_data_ijk for the centre)."""
from __future__ import annotations

import math

from planners.paths.gcode.rs274.codes import AXES, MM_PER_INCH, PLANES
from planners.paths.gcode.rs274.errors import LineError

# interp_internal.hh: R-form reach tolerance and the spiral tolerance of I/J/K arcs (mm)
RADIUS_TOLERANCE_MM = 0.00005 * MM_PER_INCH
CENTER_ARC_RADIUS_TOLERANCE_MM = 2 * 0.01 * math.sqrt(2)
CENTER_ARC_RADIUS_TOLERANCE_INCH = 2 * 0.001 * math.sqrt(2)
SPIRAL_RELATIVE_TOLERANCE = 0.001
TINY = 1e-12
PROBES = (382, 383, 384, 385)


class Motion:
    """Uses the Interpreter's m (modal state), pos, rot, unit/to_program/to_machine and emit."""

    def polar(self, w, prog, endp, axes) -> None:
        # as interp_find.cc's find_ends: @ (distance) and ^ (angle, degrees) about the origin,
        # or, in G91, added to the current point's distance and angle
        if "x" in axes or "y" in axes:
            raise LineError("X or Y words with polar coordinates (@ ^)")
        px, py = prog[0], prog[1]
        u = self.unit()
        if self.m.absolute:
            if "@" in w and "^" in w:
                px, py = w["@"] * u * math.cos(math.radians(w["^"])), w["@"] * u * math.sin(math.radians(w["^"]))
            elif "@" in w:
                if px == 0 and py == 0:
                    raise LineError("polar @ at the origin needs an angle ^")
                t = math.atan2(py, px)
                px, py = w["@"] * u * math.cos(t), w["@"] * u * math.sin(t)
            else:
                r = math.hypot(py, px)
                px, py = r * math.cos(math.radians(w["^"])), r * math.sin(math.radians(w["^"]))
        else:
            if px == 0 and py == 0:
                raise LineError("incremental polar motion at the origin is indeterminate")
            if "@" in w:
                t = math.atan2(py, px)
                r = math.hypot(py, px) + w["@"] * u
                px, py = r * math.cos(t), r * math.sin(t)
            if "^" in w:
                t = math.atan2(py, px) + math.radians(w["^"])
                r = math.hypot(py, px)
                px, py = r * math.cos(t), r * math.sin(t)
        endp[0], endp[1] = px, py

    def motion(self, mm: int, w, axes, g53: bool) -> None:
        m = self.m
        u = self.unit()
        prog = self.to_program(self.pos)
        axes = [a for a in axes if a != "@"]
        if g53:
            end = self._g53_end(mm, w, axes, u)
        else:
            endp = list(prog)
            for a in axes:
                i = AXES.index(a)
                endp[i] = w[a] * u if m.absolute else prog[i] + w[a] * u
        if "@" in w or "^" in w:
            if g53:
                raise LineError("polar coordinates (@ ^) with G53")
            self.polar(w, prog, endp, axes)
        if mm in PROBES:
            if g53:
                raise LineError("G53 needs a G0 or G1 move")
            self.probe(mm, endp)
            return
        if mm in (0, 10):
            for letter in "ijkr":
                if letter in w:
                    raise LineError(f"{letter.upper()} word on a G{mm // 10} (straight) move")
            if mm == 10 and not m.feed:
                raise LineError("G1 feed move with a zero feed rate: give F")
            self.emit("rapid" if mm == 0 else "feed", end if g53 else self.to_machine(endp))
            return
        self.arc(mm, w, u, prog, endp)

    def probe(self, mm: int, endp) -> None:
        """G38.2–G38.5 (interp_convert.cc convert_probe, then motion's control.c): a straight
        feed towards ``endp`` (program coordinates, mm) that stops where the probe input
        changes: G38.2/G38.3 when it makes contact, G38.4/G38.5 when it loses contact. The probe
        touches ``probe_surface`` (in contact at or below it); with none it never makes contact,
        as in LinuxCNC's simulation. G38.2 and G38.4 that end without a change, or start in the
        state they seek, are LinuxCNC's errors (control.c, command.c); G38.3 and G38.5 are
        not. The point where it stops is #5061–#5063 (program coordinates and units) and
        #5070 = 1 if the probe changed, 0 if not (interp_internal.cc set_probe_data)."""
        m = self.m
        g = f"G38.{mm - 380}"
        if not m.feed:
            raise LineError("Cannot probe with zero feed rate")
        prog = self.to_program(self.pos)
        seek_clear, errors = mm in (384, 385), mm in (382, 384)
        if errors and prog == list(endp):
            raise LineError(f"Start point too close to probe point ({g})")
        start, end = list(self.pos), self.to_machine(endp)
        touching = _contact(self.probe_surface, start)
        if touching != seek_clear and errors:
            raise LineError("Probe is already clear when starting G38.4 or G38.5 move" if seek_clear
                            else "Probe is already tripped when starting G38.2 or G38.3 move")
        t = 0.0 if touching != seek_clear else _change(self.probe_surface, start, end, seek_clear)
        self.flush()                     # emccanon.cc STRAIGHT_PROBE: flush_segments
        if t is None:
            if errors:
                raise LineError(f"{g} move finished without {'breaking' if seek_clear else 'making'} contact")
            stop = end
        else:
            stop = [a + t * (b - a) for a, b in zip(start, end)]
        self.emit("feed", stop)
        self.event("probe", int(t is not None))
        self.out.notes.append((self.cur_line, f"{g}: " + ("no contact, ran to its end" if t is None else
                               "stopped at contact at ({:.6g}, {:.6g}, {:.6g}) mm".format(*stop))))
        u = self.unit()
        at = self.to_program(stop)
        for i in range(3):
            self.params.set(5061 + i, at[i] / u)
        self.params.set(5070, float(t is not None))

    def _g53_end(self, mm: int, w, axes, u):
        """The end of a G53 move: the axis words are machine coordinates."""
        if mm not in (0, 10):
            raise LineError("G53 needs a G0 or G1 move")
        if not self.m.absolute:
            raise LineError("G53 with G91 (incremental) in force")
        end = list(self.pos)
        for a in axes:
            end[AXES.index(a)] = w[a] * u
        return end

    def arc(self, mm: int, w, u, prog, endp) -> None:
        """G2 / G3 from ``prog`` to ``endp`` (program coordinates): as convert_arc2."""
        m = self.m
        if not m.feed:
            raise LineError(f"G{mm // 10} arc with a zero feed rate: give F")
        i1, i2 = PLANES[m.plane][:2]
        letters = "ijk"
        allowed = {letters[i1], letters[i2]}
        offs = [c for c in "ijk" if c in w]
        bad = [c for c in offs if c not in allowed]
        if bad:
            raise LineError(f"{bad[0].upper()} word for an arc in the G{m.plane} plane")
        if self.rot and m.plane != 17:
            raise LineError("G18/G19 arc with an XY rotation in force is not supported")
        turns = _arc_turns(w)
        s1, s2 = prog[i1], prog[i2]
        e1, e2 = endp[i1], endp[i2]
        if "r" in w:
            if offs:
                raise LineError("R and I/J/K given together: use one arc form")
            c1, c2 = _center_from_radius(mm, w["r"], u, s1, s2, e1, e2)
        else:
            if not offs:
                raise LineError(f"G{mm // 10} arc needs I/J/K (centre) or R")
            o = {c: w[c] * u for c in offs}
            c1, c2 = _center_from_offsets(o.get(letters[i1], 0.0), o.get(letters[i2], 0.0),
                                          m.ijk_absolute, m.units, s1, s2, e1, e2)
        cen = list(prog)
        cen[i1], cen[i2] = c1, c2
        turn = -turns if mm == 20 else turns
        self.emit("arc", self.to_machine(endp), center=tuple(self.to_machine(cen)), plane=m.plane, turn=turn)
        self._arc_done = True


def _contact(surface, p) -> bool:
    """Is the probe at machine point ``p`` touching ``surface`` (None, a height, f(x, y))?"""
    if surface is None:
        return False
    top = surface(p[0], p[1]) if callable(surface) else surface
    return p[2] <= top


PROBE_SAMPLE_MM = 0.01        # a function surface is sampled this finely along the probe move
PROBE_SAMPLES_MAX = 1_000_000  # … in at most this many steps (coarser on a move over 10 m)


def _change(surface, a, b, seek_clear: bool):
    """The fraction t ∈ (0, 1] of the move a → b where the contact with ``surface`` changes
    (to contact, or to clear with ``seek_clear``), or None: a plane in closed form, a function
    sampled every PROBE_SAMPLE_MM (PROBE_SAMPLES_MAX steps at most) then bisected to 1e-12 of
    the move."""
    if surface is None:
        return None
    if not callable(surface):
        dz = b[2] - a[2]
        if dz == 0.0:
            return None
        t = (surface - a[2]) / dz
        return t if 0.0 < t <= 1.0 else None
    n = min(PROBE_SAMPLES_MAX, max(1, int(math.ceil(math.dist(a, b) / PROBE_SAMPLE_MM))))
    changed = lambda t: _contact(surface, [x + t * (y - x) for x, y in zip(a, b)]) != seek_clear
    lo = 0.0
    for k in range(1, n + 1):
        hi = k / n
        if changed(hi):
            while hi - lo > 1e-12:
                mid = 0.5 * (lo + hi)
                lo, hi = (lo, mid) if changed(mid) else (mid, hi)
            return hi
        lo = hi
    return None


def _arc_turns(w) -> int:
    """The P word of an arc: the number of turns, an integer ≥ 1 (1 without P)."""
    turns = 1
    if "p" in w:
        turns = int(round(w["p"]))
        if abs(w["p"] - turns) > 1e-6 or turns < 1:
            raise LineError(f"arc P{w['p']:g} (turns) must be an integer ≥ 1")
    return turns


def _center_from_radius(mm: int, r_word: float, u: float, s1, s2, e1, e2):
    """interp_arc.cc's arc_data_r: the centre of the R-form arc from s to e (R < 0: the long
    way round); R too small to reach the end by more than the tolerance is an error."""
    if e1 == s1 and e2 == s2:
        raise LineError("R-form arc whose end is its start: a full circle needs I/J/K")
    r = r_word * u
    ar = abs(r)
    mid1, mid2 = (e1 + s1) / 2.0, (e2 + s2) / 2.0
    half = math.hypot(mid1 - e1, mid2 - e2)
    if half - ar > RADIUS_TOLERANCE_MM:
        raise LineError(f"arc radius R{abs(r_word):g} is too small to reach the end point")
    if ar == 0.0 or half / ar > 1 - TINY:
        half = ar
    if (mm == 20 and r > 0) or (mm == 30 and r < 0):
        theta = math.atan2(e2 - s2, e1 - s1) - math.pi / 2
    else:
        theta = math.atan2(e2 - s2, e1 - s1) + math.pi / 2
    off = ar * math.cos(math.asin(half / ar)) if ar else 0.0
    return mid1 + off * math.cos(theta), mid2 + off * math.sin(theta)


def _center_from_offsets(a1: float, a2: float, ijk_absolute: bool, units: int, s1, s2, e1, e2):
    """interp_arc.cc's arc_data_ijk: the centre from the I/J/K words (mm; offsets from the
    start, or absolute in G90.1); the radii to start and end must agree within LinuxCNC's
    tolerance."""
    if ijk_absolute:
        c1, c2 = a1, a2
    else:
        c1, c2 = s1 + a1, s2 + a2
    r1 = math.hypot(c1 - s1, c2 - s2)
    r2 = math.hypot(c1 - e1, c2 - e2)
    rtol = RADIUS_TOLERANCE_MM
    if r1 < rtol or r2 < rtol:
        raise LineError(f"zero-radius arc (radius to start {r1:.6g} mm, to end {r2:.6g} mm)")
    err = abs(r1 - r2)
    tol = CENTER_ARC_RADIUS_TOLERANCE_MM if units == 21 else CENTER_ARC_RADIUS_TOLERANCE_INCH * MM_PER_INCH
    if err > tol * 100.0 or (err / max(r1, r2) > SPIRAL_RELATIVE_TOLERANCE and err > tol):
        raise LineError(f"arc radius to end ({r2:.6g} mm) differs from radius to start ({r1:.6g} mm) "
                        f"by {err:.3g} mm (LinuxCNC accepts {tol:.3g} mm or 0.1 %)")
    return c1, c2
