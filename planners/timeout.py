"""A planner with a time limit: :func:`run_limited` (behind ``planners.plan_in_time``) runs
``planners.plan`` in a child Python process and kills it when the limit passes (a plug-in
that loops forever, or a solver that never returns, costs its row, not the run).

A process rather than a thread: a thread cannot be stopped, so an abandoned one would keep a
core busy (and hold the GIL) for the rest of a run or a sweep worker's life. A plain
subprocess rather than multiprocessing: a Dask worker is a daemonic process, which
multiprocessing forbids to have children. The child gets the parent's sys.path (a
``module:function`` plug-in found there is found in the child) and the inputs pickled on its
stdin; it tells the parent when it is ready (the interpreter's start-up is not the planner's
time), then sends the profile, or the planner's exception, pickled on its stdout. A plug-in's
print() in the child goes to stderr, as the parent's own stdout may be a JSON report.
"""
from __future__ import annotations

import os
import pickle
import selectors
import subprocess
import sys

from planners.errors import PlanningError

READY = b"R"
START_LIMIT_S = 300.0      # the child's imports (numpy, the planners) on a loaded machine
# the child's program: the parent's sys.path, then the package's plan() handed to child() (this
# module does not import the package: the package imports it)
CHILD = ("import pickle, sys; sys.path[:] = pickle.load(sys.stdin.buffer); "
         "import planners, planners.timeout as t; t.child(planners.plan)")


def run_limited(timeout_s: float, name: str, path, machine, limits, options: dict):
    """planners.plan of ``name`` in a child process, stopped after ``timeout_s`` seconds of planning
    with a PlanningError naming the timeout."""
    if not timeout_s > 0:
        raise PlanningError(f"planner timeout {timeout_s!r} s: must be > 0")
    # sys.path first, in a pickle of its own: the inputs' classes are imported through it
    payload = pickle.dumps(list(sys.path)) + pickle.dumps((name, path, machine, limits, options))
    proc = subprocess.Popen([sys.executable, "-c", CHILD], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=None)
    try:
        proc.stdin.write(payload)
        proc.stdin.close()
        if not _wait_readable(proc.stdout, START_LIMIT_S) or proc.stdout.read(1) != READY:
            raise PlanningError(f"planner {name!r}: its worker process did not start "
                                f"(exit code {proc.poll()})")
        if not _wait_readable(proc.stdout, timeout_s):
            raise PlanningError(f"planner {name!r} exceeded the planner timeout of {timeout_s:g} s "
                                f"(--planner-timeout / planner_timeout_s); stopped")
        data = proc.stdout.read()
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait()
        proc.stdout.close()
    try:
        ok, value = pickle.loads(data)
    except Exception:
        raise PlanningError(f"planner {name!r}: its worker process ended without a result "
                            f"(exit code {proc.returncode})") from None
    if ok:
        return value
    raise value


def _wait_readable(stream, seconds: float) -> bool:
    with selectors.DefaultSelector() as sel:
        sel.register(stream, selectors.EVENT_READ)
        return bool(sel.select(seconds))


def child(plan) -> None:
    """The worker process: inputs from stdin, READY then the pickled (ok, ``plan``'s result) on stdout."""
    out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)                         # the planner's prints go to stderr
    sys.stdout = sys.stderr
    name, path, machine, limits, options = pickle.load(sys.stdin.buffer)   # after CHILD's sys.path
    out.write(READY)
    out.flush()
    try:
        result = (True, plan(name, path, machine, limits, **options))
    except Exception as e:
        result = (False, e)
    try:
        data = pickle.dumps(result)
    except Exception:                     # an exception that does not pickle: its text does
        data = pickle.dumps((False, PlanningError(f"{type(result[1]).__name__}: {result[1]}")))
    out.write(data)
    out.flush()
