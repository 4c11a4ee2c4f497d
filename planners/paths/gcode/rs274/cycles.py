"""Canned cycles G73, G74, G81–G89, mixed into the Interpreter: the moves, dwells and spindle
calls of LinuxCNC 2.9's interp_cycles.cc, in its order.

convert_cycle (the checks: feed, R, L) → convert_cycle_xy / _zx / _yz (the plane's axes
aa, bb and cc, G90/G91, the initial level, the R and clearance levels, the rapid up to R when
below it, exact-path mode for the cycle) → CYCLE_MACRO (interp_internal.hh: per repeat, the
rapids to the hole and down to R) → convert_cycle_g81 … g89 (the cycle itself). Lengths here are
program coordinates in program units, as the interpreter's settings are; the moves go out in
machine mm (Offsets.to_machine).

The state LinuxCNC keeps between cycle blocks (cycle_r, cycle_cc, cycle_p, cycle_q, cycle_i/j/k,
the initial level cycle_il) lives on the interpreter; the class attributes are its start values
(zero, as rs274ngc's settings start).
"""
from __future__ import annotations

import math

from planners.paths.gcode.rs274.codes import AXES, MM_PER_INCH, PLANES
from planners.paths.gcode.rs274.errors import LineError

CYCLES = frozenset((730, 740, 810, 820, 830, 840, 850, 860, 870, 880, 890))
G83_RAPID_DELTA_INCH = 0.010           # interp_internal.hh G83_RAPID_DELTA (inches)
_PLANE_NAME = {17: "xy", 18: "xz", 19: "yz"}
# the P (dwell) word is required on the first block of these (NCE_DWELL_TIME_P_WORD_MISSING_WITH_G8x)
_NEEDS_P = {820, 860, 880, 890}
_NEEDS_Q = {730, 830}


class Cycles:
    """Uses the Interpreter's m (modal state), pos, unit/to_program/to_machine, emit, event and
    flush."""

    cycle_il = None          # the initial level (cycle_il_flag: set on the first cycle block)
    cycle_r = 0.0
    cycle_cc = 0.0
    cycle_p = 0.0
    cycle_q = 0.0
    cycle_ijk = (0.0, 0.0, 0.0)

    def cycle(self, motion: int, prev_motion, w) -> None:
        """One canned-cycle block (``prev_motion``: the motion mode before the block); its
        errors name the cycle."""
        try:
            self._cycle(motion, prev_motion, w)
        except LineError as e:
            raise LineError(f"G{motion // 10} canned cycle: {e}") from None

    def _cycle(self, motion: int, prev_motion, w) -> None:
        m = self.m
        g = f"G{motion // 10}"
        if not m.feed:
            raise LineError("Cannot feed with zero feed rate (canned cycle)")
        if "r" in w:
            r_word = w["r"]
        elif prev_motion == motion:
            r_word = self.cycle_r
        else:
            raise LineError(f"R clearance plane unspecified in cycle ({g} needs R on its first block)")
        reps = w.get("l", -1.0)
        if reps != -1.0:
            if abs(reps - round(reps)) > 0.0001:
                raise LineError(f"L{reps:g}: the number of repeats must be an integer")
            if reps < 0:
                raise LineError("Negative L word used")
            if round(reps) == 0:
                raise LineError("Cannot do zero repeats of cycle (L0)")
        reps = 1 if reps == -1.0 else int(round(reps))
        if reps > self.max_loops:
            raise LineError(f"L{reps}: more repeats than the limit of {self.max_loops} loop iterations")
        i1, i2, i3 = PLANES[m.plane]
        ca = AXES[i3]                                 # the cycle's axis letter (z in G17)
        if prev_motion != motion and ca not in w:
            raise LineError(f"{ca.upper()} value unspecified in {_PLANE_NAME[m.plane]} plane canned cycle")
        if ("@" in w or "^" in w) and m.plane != 17:
            raise LineError("Cannot use polar coordinate except in G17 plane")
        u = self.unit()
        cur = [v / u for v in self.to_program(self.pos)]
        cc_word = w.get(ca, self.cycle_cc)
        current_cc = cur[i3]
        if self.cycle_il is None:
            self.cycle_il = current_cc
        old_cc = self.cycle_il
        inc_a = inc_b = inc_rad = inc_theta = 0.0
        letter_a, letter_b = AXES[i1], AXES[i2]
        if m.absolute:
            r = r_word
            cc = cc_word
            if "@" in w or "^" in w:
                rad = w["@"] if "@" in w else math.hypot(cur[1], cur[0])
                th = math.radians(w["^"]) if "^" in w else math.atan2(cur[1], cur[0])
                aa, bb = rad * math.cos(th), rad * math.sin(th)
            else:
                aa = w.get(letter_a, cur[i1])
                bb = w.get(letter_b, cur[i2])
        else:
            inc_a = w.get(letter_a, 0.0)
            inc_b = w.get(letter_b, 0.0)
            inc_rad = w.get("@", 0.0)
            inc_theta = math.radians(w.get("^", 0.0))
            r = r_word + old_cc
            cc = r + cc_word                          # [NCMS, page 98]: Z from R
            aa, bb = cur[i1], cur[i2]
        if r < cc:
            raise LineError(f"R less than {ca} in cycle in {_PLANE_NAME[m.plane]} plane "
                            f"(R{r:g} below the bottom {ca.upper()}{cc:g})")

        def point(a, b, c):
            p = [0.0, 0.0, 0.0]
            p[i1], p[i2], p[i3] = a * u, b * u, c * u
            return self.to_machine(p)

        def traverse(a, b, c):
            self.emit("rapid", point(a, b, c))

        def feed(a, b, c):
            self.emit("feed", point(a, b, c))

        if old_cc < r:                                # below the R plane: straight up to it first
            traverse(cur[i1], cur[i2], r)
            old_cc = current_cc = r
        clear_cc = r if m.retract == 99 else old_cc
        saved_path = m.path
        if saved_path != ("exact", "path"):            # SET_MOTION_CONTROL_MODE(CANON_EXACT_PATH)
            self.flush()
            m.path = ("exact", "path")
        # rs274ngc's blocks hold −1 for "no P" and "no Q": P−1 and Q−1 read as absent
        p_word, q_word = w.get("p", -1.0), w.get("q", -1.0)
        p = q = None
        if motion in _NEEDS_P and prev_motion != motion and p_word == -1.0:
            raise LineError(f"Dwell time P word missing with {g.lower()}")
        if motion in _NEEDS_Q and prev_motion != motion and q_word == -1.0:
            raise LineError(f"Q word missing with {g.lower()}")
        if motion in _NEEDS_P or motion in (740, 840):
            p = self.cycle_p if p_word == -1.0 else p_word
        if motion in _NEEDS_Q:
            q = self.cycle_q if q_word == -1.0 else q_word
        if motion == 870:
            ijk = self._g87_words(w, prev_motion)
        spin = m.spindle
        for k in range(reps):                          # CYCLE_MACRO
            aa, bb = aa + inc_a, bb + inc_b
            if inc_rad or inc_theta:
                if aa == 0 and bb == 0:
                    raise LineError("Incremental motion with polar coordinates is indeterminate when at the origin")
                th = math.atan2(bb, aa) + inc_theta
                rad = math.hypot(bb, aa) + inc_rad
                aa, bb = rad * math.cos(th), rad * math.sin(th)
            if k == 0 and current_cc > r:
                traverse(aa, bb, current_cc)
                traverse(aa, bb, r)
            else:
                traverse(aa, bb, clear_cc)
                if clear_cc > r:
                    traverse(aa, bb, r)
            if motion in (810, 820, 890, 850):
                # g81: feed down, rapid out; g82: … dwell …; g89: dwell, feed out; g85: feed out to R
                feed(aa, bb, cc)
                if motion in (820, 890):
                    self.event("dwell", p)
                if motion in (850, 890):
                    feed(aa, bb, r if motion == 850 else clear_cc)
                if motion != 890:
                    traverse(aa, bb, clear_cc)
            elif motion in (730, 830):
                self._peck(motion, q, u, aa, bb, r, clear_cc, cc, traverse, feed)
            elif motion in (740, 840):
                self._tap(motion, spin, p, aa, bb, clear_cc, cc, feed, point)
            elif motion == 860:
                # convert_cycle_g86: feed down, dwell, spindle stop, rapid out, spindle on again
                self._spindle_turning(g, spin)
                feed(aa, bb, cc)
                self.event("dwell", p)
                self.event("m", 5)
                traverse(aa, bb, clear_cc)
                self.event("m", spin)
            elif motion == 870:
                self._back_bore(spin, ijk, aa, bb, r, clear_cc, cc, traverse, feed)
            else:
                # convert_cycle_g88: feed down, dwell, spindle stop, program stop (the operator
                # retracts by hand), spindle on again: no retract move
                self._spindle_turning(g, spin)
                feed(aa, bb, cc)
                self.event("dwell", p)
                self.event("m", 5)
                self.event("m", 0)
                self.event("m", spin)
                self.out.notes.append((self.cur_line, "G88: the program stops at the bottom of the hole for the "
                                                      "operator to retract by hand; the next move starts there"))
        if p is not None:
            self.cycle_p = p
        if q is not None:
            self.cycle_q = q
        # the interpreter's position after the cycle is the clearance point, also after G88
        # (whose last move ends at the bottom): convert_cycle_xy sets current_z = clear_cc
        self.pos = point(aa, bb, clear_cc)
        self.cycle_cc = cc_word
        if m.path != saved_path:
            m.path = saved_path
            self.flush()
        self.cycle_r = r_word
        m.motion = motion

    def _g87_words(self, w, prev_motion):
        if prev_motion != 870:
            for c in "ijk":
                if c not in w:
                    raise LineError(f"{c.upper()} word missing with g87")
        self.cycle_ijk = tuple(w.get(c, v) for c, v in zip("ijk", self.cycle_ijk))
        return self.cycle_ijk

    def _peck(self, motion, q, u, aa, bb, r, clear_cc, cc, traverse, feed) -> None:
        """convert_cycle_g73 / g83: pecks of Q down from R; G73 backs off by G83_RAPID_DELTA
        after each, G83 rapids out to R and back down to that far above the last depth."""
        if q <= 0.0:
            raise LineError("Negative or zero q value used")
        if (r - cc) / q > self.max_loops:
            raise LineError(f"Q{q:g} from R{r:g} to {cc:g}: more pecks than the limit of {self.max_loops} "
                            "loop iterations")
        delta = G83_RAPID_DELTA_INCH * (MM_PER_INCH if u == 1.0 else 1.0)
        depth = r - q
        while depth > cc:
            feed(aa, bb, depth)
            if motion == 830:
                traverse(aa, bb, r)
            traverse(aa, bb, depth + delta)
            depth -= q
        feed(aa, bb, cc)
        traverse(aa, bb, clear_cc)

    def _tap(self, motion, spin, p, aa, bb, clear_cc, cc, feed, point) -> None:
        """convert_cycle_g74_g84: feed in, spindle stop, reversed, dwell P, feed out, stop, the
        first direction again. In G18/G19 LinuxCNC 2.9 passes the coordinates to cycle_feed in
        another order than its other cycles (interp_cycles.cc, the CANON_PLANE_YZ / XZ cases):
        the moves go where LinuxCNC sends them, not along the plane's axis."""
        g = "G84" if motion == 840 else "G74"
        if spin == 5:
            raise LineError(f"Spindle not turning in {g}")
        if (spin == 4) == (motion == 840):
            raise LineError(f"Spindle turning {'counterclockwise' if motion == 840 else 'clockwise'} in {g}")
        first, back = (3, 4) if motion == 840 else (4, 3)
        plane = self.m.plane
        u = self.unit()
        if plane != 17:
            self.out.notes.append((self.cur_line, f"{g} in G{plane}: the tapping feeds go where LinuxCNC 2.9 sends "
                                                  "them (interp_cycles.cc convert_cycle_g74_g84 swaps the axes)"))

        def tap_feed(c):
            if plane == 17:
                feed(aa, bb, c)
                return
            # cycle_feed(plane, c, aa, bb) in YZ, cycle_feed(plane, bb, c, aa) in XZ
            i1, i2, i3 = PLANES[plane]
            e1, e2, e3 = (c, aa, bb) if plane == 19 else (bb, c, aa)
            pt = [0.0, 0.0, 0.0]
            pt[i1], pt[i2], pt[i3] = e1 * u, e2 * u, e3 * u
            self.emit("feed", self.to_machine(pt))

        tap_feed(cc)
        self.event("m", 5)
        self.event("m", back)
        self.event("dwell", p)
        tap_feed(clear_cc)
        self.event("m", 5)
        self.event("m", first)

    def _back_bore(self, spin, ijk, aa, bb, r, clear_cc, cc, traverse, feed) -> None:
        """convert_cycle_g87 (back boring): I J K as the plane's offsets and top of the bore."""
        self._spindle_turning("G87", spin)
        m = self.m
        i, j, k = ijk
        if m.plane == 17:
            off_a, off_b, middle = i, j, k
        elif m.plane == 19:
            off_a, off_b, middle = j, k, i
        else:
            off_a, off_b, middle = k, i, j
        if not m.absolute:
            middle = cc + middle                      # the top of the bore from the bottom
        oa, ob = aa + off_a, bb + off_b
        traverse(oa, ob, r)
        self.event("m", 5)
        self.event("m", 19)                           # ORIENT_SPINDLE
        traverse(oa, ob, cc)
        traverse(aa, bb, cc)
        self.event("m", spin)
        feed(aa, bb, middle)
        feed(aa, bb, cc)
        self.event("m", 5)
        self.event("m", 19)
        traverse(oa, ob, cc)
        traverse(oa, ob, clear_cc)
        traverse(aa, bb, clear_cc)
        self.event("m", spin)

    @staticmethod
    def _spindle_turning(g: str, spin: int) -> None:
        if spin not in (3, 4):
            raise LineError(f"Spindle not turning in {g.lower()}")
