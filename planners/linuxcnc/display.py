#!/usr/bin/python3
"""Headless DISPLAY program for LinuxCNC 2.9 (runs under the SYSTEM python3, not the venv:
only there are LinuxCNC's ``linuxcnc`` and ``hal`` modules).

``linuxcnc`` starts it as ``display.py -ini FILE`` once HAL, motion and task are up.
It does what an operator does in AXIS — estop reset, machine on, home all, MDI G0 to the
program's start point, AUTO run (after ``[PKMBENCH]START_DELAY_S``: the phase of the io
task's cycle the program meets), an M0/M1 resumed at once — while draining the HAL ``sampler`` (loaded on the servo
thread by the generated HAL file) through ``hal.stream``: one row per servo period, full
double precision. The rows are written to ``[PKMBENCH]OUTPUT``; on any failure a one-line
reason goes to ``[PKMBENCH]OUTPUT.err`` and the exit status is non-zero, which ends
LinuxCNC (the ``linuxcnc`` script shuts everything down when its display exits).
An M0/M1 pause is the operator's time, not the planner's: the sample rows from the pause (the
midpoint between the last poll that did not see it and the first that did) to the resume go
to ``[PKMBENCH]OUTPUT.pauses`` ("first last gap" sample numbers, one pause a line; gap: the
samples between the two polls, so where the pause began is known to ± gap/2).
No pkmbench import here: this file must run without the venv.
"""
import sys
import time

import hal
import linuxcnc

SAMPLER_SHMEM_KEY = 0x48534130      # src/hal/components/streamer.h (v2.9.0-pre1), channel 0


def ini_path(argv):
    return argv[argv.index("-ini") + 1]


class Fail(Exception):
    pass


def main(argv):
    ini = linuxcnc.ini(ini_path(argv))
    out = ini.find("PKMBENCH", "OUTPUT")
    program = ini.find("PKMBENCH", "PROGRAM")
    start = ini.find("PKMBENCH", "START")
    cfg = ini.find("PKMBENCH", "SAMPLER_CFG")
    timeout = float(ini.find("PKMBENCH", "TIMEOUT_S") or 600)
    delay = float(ini.find("PKMBENCH", "START_DELAY_S") or 0)
    pauses = []
    try:
        rows = run(program, start, cfg, timeout, delay, pauses)
    except Fail as e:
        with open(out + ".err", "w") as f:
            f.write(str(e) + "\n")
        return 1
    with open(out + ".tmp", "w") as f:
        for sampleno, row in rows:
            f.write(" ".join([str(sampleno)] + [repr(v) for v in row]) + "\n")
    with open(out + ".pauses", "w") as f:
        for a, b, gap in pauses:
            f.write("%d %d %d\n" % (a, b, gap))
    import os
    os.replace(out + ".tmp", out)
    return 0


def run(program, start, cfg, timeout, delay, pauses):
    c, s, e = linuxcnc.command(), linuxcnc.stat(), linuxcnc.error_channel()
    comp = hal.component("pkmsampleread")
    comp.ready()
    stream = hal.stream(comp, SAMPLER_SHMEM_KEY, cfg)
    rows = []
    keep = [False]
    last = [0, 0]        # the newest sample number drained: now, and at the poll before

    def drain():
        while True:
            r = stream.read()
            if r is None:
                return
            last[1] = stream.sampleno
            if keep[0]:
                rows.append((stream.sampleno, r))

    def errors():
        msg = e.poll()
        if msg and msg[0] in (linuxcnc.NML_ERROR, linuxcnc.OPERATOR_ERROR):
            raise Fail("LinuxCNC error: " + msg[1].strip().replace("\n", " "))

    def wait(cond, what, limit=20.0):
        t0 = time.monotonic()
        while True:
            last[0] = last[1]
            drain()
            s.poll()
            errors()
            if cond():
                return
            if time.monotonic() - t0 > limit:
                raise Fail("LinuxCNC: timed out after %g s waiting for %s" % (limit, what))
            time.sleep(0.001)        # a poll takes ~7 ms besides: an M0's start is known to ±4 ms

    wait(lambda: True, "task")
    c.state(linuxcnc.STATE_ESTOP_RESET)
    wait(lambda: s.task_state == linuxcnc.STATE_ESTOP_RESET, "estop reset")
    c.state(linuxcnc.STATE_ON)
    wait(lambda: s.task_state == linuxcnc.STATE_ON, "machine on")
    c.mode(linuxcnc.MODE_MANUAL)
    wait(lambda: s.task_mode == linuxcnc.MODE_MANUAL, "manual mode")
    c.home(-1)                       # HOME_SEARCH_VEL = 0: the joints take their HOME value
    wait(lambda: all(s.homed[j] for j in range(s.joints)), "homing")
    c.mode(linuxcnc.MODE_MDI)
    wait(lambda: s.task_mode == linuxcnc.MODE_MDI, "MDI mode")
    # the program's positioning move, done before sampling: pkmbench's path starts there
    c.mdi("G21 G90 G53 G0 " + start)      # machine coordinates: a var file may offset G54
    wait(lambda: s.interp_state == linuxcnc.INTERP_IDLE and s.queue == 0 and s.inpos,
         "the move to the start point", 120.0)
    c.mode(linuxcnc.MODE_AUTO)
    wait(lambda: s.task_mode == linuxcnc.MODE_AUTO, "auto mode")
    c.program_open(program)
    wait(lambda: True, "program open")
    t0 = time.monotonic()
    while time.monotonic() - t0 < delay:
        drain()
        time.sleep(0.005)
    keep[0] = True
    drain()
    c.auto(linuxcnc.AUTO_RUN, 0)
    wait(lambda: s.interp_state != linuxcnc.INTERP_IDLE, "the program to start", 20.0)
    resumed = [None]         # the serial of the last resume, until task has taken it

    def ended():
        paused = s.interp_state == linuxcnc.INTERP_PAUSED or s.paused
        if resumed[0] is not None and s.echo_serial_number >= resumed[0]:
            resumed[0] = None              # task has taken the resume: a stop seen now is a new one
        if paused and resumed[0] is None:  # M0/M1: resumed at once, as an operator would
            began = (last[0] + last[1]) // 2 + 1        # paused between the two polls
            drain()
            pauses.append((began, last[1], last[1] - last[0]))
            c.auto(linuxcnc.AUTO_RESUME)
            resumed[0] = c.serial
            return False
        return s.interp_state == linuxcnc.INTERP_IDLE and s.queue == 0 and s.inpos

    wait(ended, "the program to end", timeout)
    t0 = time.monotonic()
    while time.monotonic() - t0 < 0.1:   # a few more periods at rest
        drain()
        time.sleep(0.005)
    drain()
    if stream.num_overruns:
        raise Fail("LinuxCNC: the HAL sampler overran %d time(s) (samples lost)" % stream.num_overruns)
    return rows


if __name__ == "__main__":
    sys.exit(main(sys.argv))
