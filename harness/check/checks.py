"""Offline G-code checker for a PKM: compile, simulate through the kinematics, report.

Like the off-line programming system of the LOLA pn101 (Dimić et al., ICPE-S 2018): a
program is valid only if, run as the planner would run it at the servo period, every point
is in the workspace, no singularity is approached and every joint stays within its stroke,
velocity, acceleration and jerk limits. Each finding carries the G-code line(s) it comes
from and the worst value against the limit.

    report = check_program("part.ngc", load_machine("kossel"))
    print(as_text(report)); exit(report.exit_code)      # 0 clean, 1 findings, 2 invalid

The text report gives a summary per kind first, then the 50 worst entries (as_text(report, None):
every finding); report.to_json() holds every finding, "parsed" (it compiled) and "valid"
(parsed and no error finding: exit code 0).
"""
from __future__ import annotations



import re


from pathlib import Path

import numpy as np

import planners

from planners import verify as M

from planners.paths.base import gc_paused

from planners.paths.gcode import EmptyProgram, GCodeError, program_path, read_gcode, strip_comments


from harness.check.findings import CheckError, Finding, Report


_N_WORD = re.compile(r"^\s*[Nn]\s*(\d+)")

def _n_number_warnings(text: str, source: str) -> list[Finding]:
    """N numbers must increase (a warning: LinuxCNC ignores them, but a reordered program is suspect)."""

    out, last = [], None
    for ln, raw in enumerate(text.splitlines(), start=1):
        try:
            body = strip_comments(raw, source, ln)
        except GCodeError:
            continue
        m = _N_WORD.match(body)
        if not m:
            continue
        n = int(m.group(1))
        if last is not None and n <= last[0]:
            out.append(Finding("compile", "warning", [ln], float(n), float(last[0]), "",
                               f"N{n} does not increase (line {last[1]} has N{last[0]})"))
        last = (n, ln)
    return out

def _lines_of(path, s: np.ndarray) -> np.ndarray:
    """G-code line of each arc length; blend arcs (no line of their own) take the line before."""
    lines = path.line_at(s)
    if (lines < 0).any():
        seg_lines = np.array([-1 if g.line is None else g.line for g in path.segments])
        filled = seg_lines.copy()
        for i in range(1, len(filled)):
            if filled[i] < 0:
                filled[i] = filled[i - 1]
        lines = filled[path.segment_index(s)]
    return lines

def _group(kind: str, mask: np.ndarray, values: np.ndarray, lines: np.ndarray, limit: float, unit: str,
           what: str, joints: np.ndarray | None = None, feed=None) -> list[Finding]:
    """One finding per G-code line where mask holds, with that line's worst value (and, given
    ``joints``, the joint of that worst sample named first: "joint 2 …"; given ``feed`` = (path
    speed at each sample, {line: programmed F mm/s or None}, velocity?), what the machine does
    there: its feed, the programmed F and, for a velocity, the feed that keeps it within)."""
    out = []
    idx = np.nonzero(mask)[0]
    if not len(idx):
        return out
    # sort by line, then by |value| descending: the first sample of each line is its worst
    order = np.lexsort((-np.abs(values[idx]), lines[idx]))
    idx, ln = idx[order], lines[idx][order]
    first = np.r_[0, np.nonzero(np.diff(ln))[0] + 1]
    count = np.diff(np.r_[first, len(idx)]).tolist()
    # plain Python numbers for the loop: a 10⁵-line program has 10⁵ findings, and indexing
    # numpy arrays one element at a time cost most of this function
    vals = values[idx[first]].tolist()
    lns = ln[first].tolist()
    jts = None if joints is None else joints[idx[first]].tolist()
    speeds = None if feed is None else feed[0][idx[first]].tolist()
    keep = _keep_feed(values, lines, feed[0], limit, lns) if feed is not None and feed[2] else [None] * len(lns)
    # the parts of the message that do not change from line to line, formatted once
    names = {} if jts is None else {j: f"joint {int(j) + 1} {what}" for j in set(jts)}
    over = f" {unit} > limit {limit:g} {unit} (ratio "
    progs = {} if feed is None else {f: _programmed(f) for f in set(map(feed[1].get, lns))}
    for k, (v, c) in enumerate(zip(vals, count)):
        name = what if jts is None else names[jts[k]]
        where = "" if speeds is None else _feed_note(speeds[k], progs[feed[1].get(lns[k])], keep[k])
        out.append(Finding(kind, "error", [int(lns[k])], v, limit, unit,
                           f"{name} {abs(v):.6g}{over}{abs(v) / limit:.3f}, {c} sample(s)){where}"))
    return out

def _keep_feed(values, lines, speed, limit: float, lns: list) -> list[float]:
    """The largest feed at which each line's velocity stays within ``limit``: a joint or
    Cartesian velocity is the feed times a factor of the geometry (|q′(s)|), so limit / the
    line's largest factor, over all its samples (not only those over the limit)."""
    moving = 1e-9 * max(float(speed.max()), 1e-300)
    gmax = np.zeros(int(lines.max()) + 2)               # 0: no sample of that line moves
    # in blocks of samples as verify.difference_peaks (fresh 10⁶-element arrays are slow to touch)
    for a in range(0, len(lines), M.BLOCK):
        ok = speed[a:a + M.BLOCK] > moving
        ln, f = lines[a:a + M.BLOCK][ok], values[a:a + M.BLOCK][ok] / speed[a:a + M.BLOCK][ok]
        if not len(ln):
            continue
        # the samples run along the path: a line's samples are runs, maxed per run, then per line
        starts = np.r_[0, np.nonzero(np.diff(ln))[0] + 1]
        np.maximum.at(gmax, ln[starts] + 1, np.maximum.reduceat(f, starts))  # + 1: line −1 at 0
    return [limit / gmax[x + 1] if 0 <= x + 1 < len(gmax) and gmax[x + 1] > 0 else None for x in lns]

def _feed_note(speed: float, prog: str, keep) -> str:
    """', at 12.5 mm/s (F1200 programmed); ≤ 9.8 mm/s keeps it within': what the machine does
    on that line (``prog``: _programmed of its F) and, for a velocity, the feed that keeps the
    line within (``keep``, mm/s); acceleration and jerk depend on the planner's ramps too."""
    return f", at {speed:.4g} mm/s ({prog})" + ("" if keep is None else f"; ≤ {keep:.4g} mm/s keeps it within")

def _programmed(feed_mm_s) -> str:
    """'F1200 programmed' (from the feed in mm/s), or 'rapid' (None)."""
    return "rapid" if feed_mm_s is None else f"F{60 * feed_mm_s:.6g} programmed"

def check_program(file, machine, planner: str = "trapezoid", workspace_step_mm: float = 0.5, *,
                  start=None, reader: str = "pkmbench", setup=None) -> Report:
    """Check a program as ``planner`` runs it on ``machine`` (``start``: the machine position
    before it, see planners.paths.gcode.parse_gcode; default: its first positioning move or
    the machine's home; ``reader``: the G-code interpreter, pkmbench or linuxcnc; ``setup``: the
    tool table, var file and work offsets it starts with, planners.paths.gcode.rs274.setup)."""

    # the cyclic GC's full passes over the 10⁵–10⁶ objects a long program makes (segments,
    # findings, planner pieces) cost ~15 % of a check; none of them needs it to be freed
    with gc_paused():
        return _check(file, machine, planner, workspace_step_mm, start, reader, setup)

def _check(file, machine, planner: str, workspace_step_mm: float, start, reader: str, setup=None) -> Report:

    file = Path(file)
    rep = Report(str(file), machine.name, planner)
    if not planners.registry.known(planner):      # built-ins, installed plug-ins, module:function
        raise CheckError(f"unknown planner '{planner}'; valid: {', '.join(planners.registry.names())} "
                         f"or module:function")
    if not file.exists():
        raise CheckError(f"{file}: no such file")
    # 1. compile
    try:
        prog = read_gcode(file, start, home=machine.home, reader=reader, setup=setup)   # a one-move program starts at home
    except EmptyProgram:
        # a subroutine library or setup file: valid, and nothing in it moves the machine
        rep.stats["moves"] = 0
        rep.stats["nothing_to_check"] = "the program makes no move"
        return rep
    except GCodeError as e:
        rep.invalid = True
        rep.findings.append(Finding("compile", "error", [int(e.line)], None, None, "", e.message))
        return rep
    rep.findings += _n_number_warnings(file.read_text(errors="replace"), str(file))
    # (MSG,…), (DEBUG,…) and (PRINT,…) of the program, as LinuxCNC would show them
    rep.findings += [Finding("message", "info", [int(e.line)], None, None, "", str(e.value))
                     for e in prog.events if e.kind == "message"]
    rep.stats["moves"] = len(prog.moves)
    # 2. plan the program first, then check the geometry of the path that ran: a planner that
    # re-blends the program at its speeds (trapezoid) never builds the standard blends
    path = program_path(prog, deferred=True)
    try:
        prof, plan_error = planners.plan(planner, path, machine), None
    except Exception as e:
        prof, plan_error = None, e
    ran = path if prof is None else prof.path
    rep.stats["length_mm"] = float(ran.length)
    # 3. geometry: every point of the path, densely, against the workspace (all findings)
    if _geometry_findings(rep, ran, machine, workspace_step_mm):
        rep.stats["dynamics"] = "skipped: the path leaves the workspace"
        return rep
    if plan_error is not None:
        rep.findings.append(Finding("planning", "error", [], None, None, "", f"{planner} cannot plan it: {plan_error}"))
        return rep
    # 4. dynamics: the program as the planner runs it, at the servo period, through the IK
    _dynamics_findings(rep, prof, machine)
    return rep

def _geometry_findings(rep: Report, path, machine, step_mm: float) -> bool:
    """Add a finding per G-code line and kind where the path leaves the workspace, passes its
    box or nears a singularity; True if it is out of reach or beyond a stroke (no dynamics)."""
    n = max(2, int(np.ceil(path.length / step_mm)) + 1)
    s = np.linspace(0.0, path.length, n)
    P = path.point(s)
    lines = _lines_of(path, s)
    found = machine.check(P)
    box_excess = np.maximum(np.maximum(machine.workspace_min - P, P - machine.workspace_max), 0.0).max(axis=1)
    bad_geometry = False
    for kind in ("unreachable", "stroke", "singularity", "box"):
        fs = [f for f in found if f.kind == kind]
        if not fs:
            continue
        bad_geometry |= kind in ("unreachable", "stroke")
        if kind == "singularity":
            vals = np.zeros(n)
            for f in fs:
                vals[f.index] = f.value
            rep.findings += _group("singularity", vals > 0, vals, lines, machine.cond_max, "",
                                   "Jacobian condition number")
            continue
        by_line: dict[int, list] = {}          # one pass (a scan of fs per line was quadratic)
        for f in fs:
            by_line.setdefault(int(lines[f.index]), []).append(f)
        rep.findings += [_workspace_finding(kind, ln, by_line[ln], P, box_excess) for ln in sorted(by_line)]
    return bad_geometry

def _workspace_finding(kind: str, ln: int, fs: list, P: np.ndarray, box_excess: np.ndarray) -> Finding:
    """The finding of one G-code line: its worst point of the kins findings ``fs`` of one kind."""
    if kind == "box":      # kins gives no distance: the farthest point outside is the worst
        worst = max(fs, key=lambda f: box_excess[f.index])
    else:
        worst = max(fs, key=lambda f: abs(f.value - f.limit))
    at = P[worst.index]
    where = f"at ({at[0]:.4g}, {at[1]:.4g}, {at[2]:.4g}) mm"
    if kind == "unreachable":
        msg = f"rod {worst.joint} cannot reach the point {where} (short by {worst.value:.4g} mm)"
        val, lim = worst.value, 0.0
    elif kind == "stroke":
        msg = (f"joint {worst.joint} at {worst.value:.6g} mm is beyond its stroke limit "
               f"{worst.limit:g} mm by {abs(worst.value - worst.limit):.4g} mm {where}")
        val, lim = worst.value, worst.limit
    else:
        val, lim = float(box_excess[worst.index]), 0.0
        msg = f"outside the workspace box by {val:.4g} mm {where}"
    return Finding(kind, "error", [ln], val, lim, "mm", msg)

def _dynamics_findings(rep: Report, prof, machine) -> None:
    """Joint and Cartesian velocity, acceleration and jerk of the sampled profile, read as
    differences at T (planners.verify), one finding per G-code line and limit exceeded."""
    T = machine.servo_period_s
    P = prof.points()
    Q = machine.ik(P)
    slines = _lines_of(prof.path, prof.s)
    prog = prof.path.program
    programmed = {} if prog is None else {m.line: m.feed_mm_s for m in prog.moves}
    speed = _path_speed(P, T)
    rep.stats["samples"] = int(len(P))
    rep.stats["execution_time_s"] = prof.execution_time_s
    for space, X, lim in (("joint", Q, machine.limits.joint), ("Cartesian", P, machine.limits.cartesian)):
        for order, (worst, col) in zip(M.ORDERS, M.difference_peaks(X, T, len(M.ORDERS))):
            L = {"velocity": lim.v, "acceleration": lim.a, "jerk": lim.j}[order]
            unit = {"velocity": "mm/s", "acceleration": "mm/s²", "jerk": "mm/s³"}[order]
            mask = worst > L * (1 + M.FEASIBLE_TOL)
            if not mask.any():
                continue
            k = M.ORDERS.index(order) + 1
            if order != "velocity":
                # only the windows above the limit count (the feed that keeps a velocity
                # within reads every sample): their values alone, in their order
                at = np.nonzero(mask)[0]
                worst, col, mask = worst[at], col[at], np.ones(len(at), bool)
            else:
                at = np.arange(len(worst))
            last = M.window_sample(at, len(P), k)   # each window at its last sample
            ln = slines[last]
            feed = (speed[np.clip(last - 1, 0, None)] if len(speed) else np.zeros(len(last)),
                    programmed, order == "velocity")
            if space == "joint":
                rep.findings += _group(f"joint_{order}", mask, worst, ln, L, unit, order, joints=col, feed=feed)
            else:
                rep.findings += _group(f"cartesian_{order}", mask, worst, ln, L, unit, f"Cartesian {order}",
                                       feed=feed)

def _path_speed(P, T):
    """The path speed of each period: np.linalg.norm(np.diff(P, axis=0), axis=1) / T's operations
    on the columns (on (N, 3) arrays numpy runs them in inner loops of 3), in blocks as
    verify.difference_peaks."""
    n = max(len(P) - 1, 0)
    speed = np.empty(n)
    for a in range(0, n, M.BLOCK):
        b = min(a + M.BLOCK, n)
        dx, dy, dz = (np.diff(P[a:b + 1, c]) for c in range(3))
        speed[a:b] = np.sqrt(dx * dx + dy * dy + dz * dz) / T
    return speed
