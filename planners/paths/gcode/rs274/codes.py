"""The words of one block and their G/M codes, as rs274ngc reads and checks them: the code
tables with their modal groups (interp_read.cc's read_g/read_m, interp_internal.hh's groups),
one code per modal group a line (interp_check.cc's check_g_codes/check_m_codes), and no word
that no code of the line uses (check_other_codes)."""
from __future__ import annotations

import math

from planners.paths.gcode.rs274.errors import LineError

MM_PER_INCH = 25.4
# G codes (×10, as interp_read.cc's read_g) → modal group
G_GROUP = {0: 1, 10: 1, 20: 1, 30: 1, 800: 1,
           40: 0, 100: 0, 280: 0, 281: 0, 300: 0, 301: 0, 530: 0, 920: 0, 921: 0, 922: 0, 923: 0,
           170: 2, 180: 2, 190: 2, 900: 3, 910: 3, 901: 4, 911: 4, 930: 5, 940: 5, 950: 5,
           200: 6, 210: 6, 400: 7, 430: 8, 431: 8, 490: 8, 980: 10, 990: 10,
           540: 12, 550: 12, 560: 12, 570: 12, 580: 12, 590: 12, 591: 12, 592: 12, 593: 12,
           610: 13, 611: 13, 640: 13, 970: 14, 80: 15,
           730: 1, 740: 1, 810: 1, 820: 1, 830: 1, 840: 1, 850: 1, 860: 1, 870: 1, 880: 1, 890: 1,
           382: 1, 383: 1, 384: 1, 385: 1}
UNSUPPORTED_G = {
    50: "G5 (cubic spline)", 51: "G5.1 (quadratic spline)", 52: "G5.2 (NURBS)", 70: "G7 (lathe diameter mode)",
    330: "G33 (spindle-synchronised motion)", 331: "G33.1 (rigid tapping)", 760: "G76 (threading cycle)",
    410: "G41 (cutter radius compensation)", 420: "G42 (cutter radius compensation)",
    411: "G41.1 (cutter radius compensation)", 421: "G42.1 (cutter radius compensation)",
    432: "G43.2 (additional tool length offset)", 171: "G17.1 (UV plane)", 181: "G18.1 (WU plane)",
    191: "G19.1 (VW plane)", 930: "G93 (inverse-time feed)", 950: "G95 (feed per revolution)",
    960: "G96 (constant surface speed)", 520: "G52 (local offset)", 700: "G70 (lathe finishing cycle)",
    710: "G71 (lathe roughing cycle)", 720: "G72 (lathe facing cycle)", 150: "G15 (polar coordinates)",
    160: "G16 (polar coordinates)",
}
# interp_internal.hh: a line may carry one M code of each group
M_GROUP = {0: 4, 1: 4, 2: 4, 30: 4, 60: 4, 6: 6, 61: 6, 3: 7, 4: 7, 5: 7, 7: 8, 8: 8, 9: 8,
           48: 9, 49: 9, 50: 9, 51: 9, 52: 9, 53: 9, 70: 10, 71: 10, 72: 10, 73: 10,
           62: 5, 63: 5, 64: 5, 65: 5, 66: 5, 67: 5, 68: 5}
UNSUPPORTED_M = {19: "M19 (spindle orient)", 98: "M98 (Fanuc subroutine call)", 99: "M99 (Fanuc return)"}
PLANES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}   # (first, second, normal) axis indices
AXES = "xyz"
_ROTARY = "abcuvw"


def read_words(words, evaluate, fr):
    """The values of a block's words: letter → value (each letter once), the G codes ×10 and
    the M codes, in the order of the line."""
    w: dict[str, float] = {}
    gs: list[int] = []
    ms: list[int] = []
    for letter, node in words:
        v = node if isinstance(node, float) else evaluate(node, fr)
        if not math.isfinite(v):
            raise LineError(f"{letter.upper()} value is not finite")
        if letter == "g":
            g10 = round(v * 10)
            if abs(v * 10 - g10) > 1e-6:
                raise LineError(f"G{v:g}: G codes have at most one decimal")
            gs.append(g10)
        elif letter == "m":
            if abs(v - round(v)) > 1e-6:
                raise LineError(f"M{v:g}: M codes are integers")
            ms.append(int(round(v)))
        else:
            if letter in w:
                raise LineError(f"{letter.upper()} word given twice on one line")
            w[letter] = v
    return w, gs, ms


def g_groups(gs) -> dict[int, int]:
    """Modal group → the line's G code of that group (×10)."""
    groups: dict[int, int] = {}
    for g in gs:
        if g in UNSUPPORTED_G:
            raise LineError(f"{UNSUPPORTED_G[g]} is not supported")
        grp = G_GROUP.get(g)
        if grp is None:
            raise LineError(f"unknown or unsupported G code G{g / 10:g}")
        if grp in groups:
            # interp_read.cc read_g: G80 beside another motion code yields to it
            if grp == 1 and 800 in (g, groups[1]):
                groups[1] = groups[1] if g == 800 else g
                continue
            raise LineError(f"G{groups[grp] / 10:g} and G{g / 10:g} are in the same modal group")
        groups[grp] = g
    return groups


def m_groups(ms) -> dict[int, int]:
    """Modal group → the line's M code of that group (M7 and M8 may share a line)."""
    mgroups: dict[int, int] = {}
    for mc in ms:
        if mc in UNSUPPORTED_M:
            raise LineError(f"{UNSUPPORTED_M[mc]} is not supported")
        grp = M_GROUP.get(mc, 11 if 100 <= mc <= 199 else None)
        if grp is None:
            raise LineError(f"unknown M code M{mc}")
        if grp in mgroups and not (grp == 8 and {mc, mgroups[grp]} == {7, 8}):
            raise LineError(f"M{mgroups[grp]} and M{mc} are in the same modal group")
        mgroups[grp] = mc
    return mgroups


def check_axis_words(w) -> None:
    for letter in w:
        if letter in _ROTARY:
            raise LineError(f"{letter.upper()} axis word: rotary/extra axes are not supported (X, Y, Z only)")


# the words a canned cycle or probe uses beyond the axes (interp_check.cc check_other_codes)
_MOTION_WORDS = {730: "rlq", 830: "rlq", 810: "rl", 850: "rl", 820: "rlp", 860: "rlp", 880: "rlp", 890: "rlp",
                 740: "rlp", 840: "rlp", 870: "rlijk"}


def check_other_codes(w, g0, groups, mg, arc_done: bool, motion=None) -> None:
    """interp_check.cc's check_other_codes: a word no code on the line uses is an error
    (``motion``: the motion the line ran, LinuxCNC's motion_to_be)."""
    used = set("xyzfstgmn@^")
    if motion in _MOTION_WORDS:
        used |= set(_MOTION_WORDS[motion])
    if g0 == 40:
        used.add("p")
    if g0 == 100:
        used |= set("lpr")
    if groups.get(13) == 640:
        used |= set("pq")
    if 8 in groups:
        used.add("h")
    if 6 in mg and mg[6] == 61:
        used.add("q")
    if 5 in mg or 9 in mg:
        used |= set("pqle")
    if 11 in mg:                     # a user M code (M100–M199) gets P and Q as its arguments
        used |= set("pq")
    if arc_done:
        used |= set("ijkrp")
    for letter in w:
        if letter not in used:
            raise LineError(f"{letter.upper()} word with no code on the line that uses it")
