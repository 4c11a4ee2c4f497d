"""Planner ``linuxcnc``: the real LinuxCNC 2.9 trajectory planner, run headless.

The program goes through LinuxCNC's own interpreter, task and motion controller (tp.c,
planner type 0) on a generated sim configuration of the machine (``runner.py``); the
profile is the tp's Cartesian command ``axis.L.pos-cmd`` at every servo period. It lives on
the geometry LinuxCNC actually ran: ``profile.path`` is the polyline through those samples
(each Line tagged with LinuxCNC's ``motion.program-line``), so the interpolator replays the
real command exactly at every period, blend arcs and all.

Paths that are not G-code (NURBS, segment JSON) are written as G-code first, as a CAM post
would: G1 lines within the chord tolerance, ``G64 P<chord>``, F = F_max.

Feed: the programmed F caps the feed (``programmed_feed=True``, the default: it is what
LinuxCNC does); ``programmed_feed=False`` replaces every F word by F_max (the suite's
planner-only comparison mode).

Determinism: LinuxCNC runs in a non-real-time ``rtapi_app`` here, but its tp advances by the
nominal period, not the clock, so the command at T depends only on what is in the motion queue;
a queue sync (M codes) waits a task cycle that is not aligned to the servo thread, so such a
stop varies by some periods (measurements: docs/TUNING.md, "linuxcnc").
"""
from __future__ import annotations

import re
from pathlib import Path as FsPath

import numpy as np

from planners.constraints import check_limits
from planners.errors import PlanningError
from planners.feed import feed_mode
from planners.linuxcnc.runner import LinuxCNCError, Samples, missing, run_program  # noqa: F401
from planners.paths import Line, SegmentPath
from planners.paths.gcode import write_gcode
from planners.paths.post import prepare_geometry
from planners.profile import Profile

_F_WORD = re.compile(r"(?<![A-Za-z])([Ff])\s*[+-]?\s*(?:\d+\.?\d*|\.\d+)")
MIN_STEP_MM = 1e-9        # a sample closer than this to the last vertex is "at rest"


def program_for(path, machine, limits, programmed_feed: bool):
    """(G-code text, start xyz, rough duration s) of what LinuxCNC is to run for ``path``."""
    prog = path.program
    fmax = limits.feed_max
    if prog is not None and FsPath(prog.source).is_file():
        text = FsPath(prog.source).read_bytes().decode("utf-8", errors="replace")
        if not programmed_feed:
            # every F word (outside or inside comments: harmless there) becomes F_max
            text = _F_WORD.sub(lambda m: f"F{fmax * 60.0:.6f}", text)
        feeds = [m.feed_mm_s or fmax for m in prog.moves] if programmed_feed else [fmax] * len(prog.moves)
        expected = sum(m.segment.length / max(min(f, fmax), 1e-3) for m, f in zip(prog.moves, feeds))
        return text, np.asarray(prog.start, float), expected
    # not a G-code file: write it as a CAM post would (planners.paths.post)
    import tempfile

    chord = limits.chord_error_mm
    planned, _ = prepare_geometry(path, chord, None) if not isinstance(path, SegmentPath) else (path, {})
    with tempfile.TemporaryDirectory() as d:
        f = FsPath(d) / "path.ngc"
        try:
            write_gcode(planned, f, fmax, chord, comment=f"pkmbench: {path.source}")
        except Exception as e:       # an arc about a skew axis has no G-code form
            raise PlanningError(f"linuxcnc: {path.source} cannot be written as G-code: {e}") from None
        text = f.read_text()
    return text, np.asarray(planned.segments[0].start, float), planned.length / fmax


def profile_from_samples(smp: Samples, source: str) -> Profile:
    """The profile (and its polyline path) of LinuxCNC's Cartesian command from the last
    sample at rest before motion to the first at the final point."""
    k0, k1 = smp.moving_span()
    P = smp.xyz[k0:k1 + 1]
    lines = smp.line[k0:k1 + 1]
    segs, s = [], np.zeros(len(P))
    last, s_last = P[0], 0.0
    for k in range(1, len(P)):
        d = float(np.linalg.norm(P[k] - last))
        if d > MIN_STEP_MM:
            segs.append(Line(last, P[k], line=int(lines[k])))
            last, s_last = P[k], s_last + d
            s[k] = s_last
        else:
            s[k] = s_last + d       # ≤ 1 nm from the vertex: the rest of a stop
    s[-1] = s_last                  # the last sample is a vertex (it moved onto it)
    path = SegmentPath(segs, f"{source} (LinuxCNC 2.9 command)")
    return Profile.from_s("linuxcnc", smp.T, s, path)


def plan(path, machine, limits=None, *, programmed_feed: bool = True,
         keep_dir: str | None = None, start_delay_s: float = 0.0) -> Profile:
    """Run ``path`` on the real LinuxCNC 2.9 for ``machine``; its command as a profile.
    ``start_delay_s``: wait that long before the AUTO run (runner.run_program). An M0/M1 pause
    is the operator's time and is left out of the profile (``info["operator_pause_s"]``; where
    each began is known to a poll of the display, ± ``info["operator_pause_uncertainty_s"]`` in all)."""
    limits = limits or machine.limits
    check_limits(limits, "linuxcnc")
    if getattr(machine, "family", None) != "lineardelta":
        raise PlanningError(f"linuxcnc: machine {machine.name} is not a linear delta; the "
                            "LinuxCNC planner runs lineardeltakins machines (kossel, linuxcnc_delta)")
    why = missing()
    if why:
        raise PlanningError(f"linuxcnc: {why}")
    programmed_feed = programmed_feed and feed_mode(path) != "max"
    text, start, expected = program_for(path, machine, limits, programmed_feed)
    try:
        smp = run_program(text, machine, start, expected_s=expected, keep_dir=keep_dir,
                          setup=getattr(path.program, "setup", None), start_delay_s=start_delay_s)
    except LinuxCNCError as e:
        raise PlanningError(str(e)) from None
    prof = profile_from_samples(smp, getattr(path, "source", "<path>"))
    k0, k1 = smp.moving_span()
    Q = machine.ik(smp.xyz[k0:k1 + 1])
    # LinuxCNC's joints lag its Cartesian command by 2 periods (motion's cubic joint
    # interpolator); this is the kinematics cross-check, not a fit
    J = smp.joints[k0 + 2:k1 + 1]
    kin_dev = float(np.abs(Q[:len(J)] - J).max()) if len(J) else 0.0
    prof.info.update({"programmed_feed": bool(programmed_feed), "linuxcnc": "2.9 (tp, planner type 0)",
                      "samples": int(k1 - k0 + 1), "joint_vs_ik_deviation_mm": kin_dev,
                      "operator_pause_s": smp.paused_s,
                      "operator_pause_uncertainty_s": smp.pause_uncertainty_s, "start_delay_s": float(start_delay_s)})
    return prof
