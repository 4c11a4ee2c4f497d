"""`pkmbench check` on generated CAM programs: time and peak RSS per program size and planner.

Issue 17 target: linear scaling, ≤ 10 s and ≤ 1 GB peak RSS for a 10⁵-line program with
trapezoid and with scurve. The programs come from cam_program.make_cam_program (kossel
workspace, seed 1, generated at run time, not committed). Each case runs in its own child
process so that its peak RSS (os.wait4's ru_maxrss) is its own, not the largest so far.

    .venv/bin/python benchmarks/perf/bench_check.py [--lines 1000 10000 100000]
                                                    [--planners trapezoid scurve] [--timeout 900] [--q0]

The program says G64 P0.01: LinuxCNC (and the reader) join runs of moves within 0.01 mm of a
line (Q = P); --q0 turns that off to time the planners on every move. --cycles: the CAM
program with drilling patterns by canned cycles between its rows (issue 33's target: ≤ 10 s
at 10⁵ lines too).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
sys.path.insert(0, str(HERE))

from cam_program import make_cam_program  # noqa: E402

LINES = (1_000, 10_000, 100_000)
PLANNERS = ("trapezoid", "scurve")

# the child: check one program, print its wall time and counts as one JSON line
_CHILD = """
import json, sys, time
from harness.check import as_text, check_program
from kins import load_machine
m = load_machine("kossel")
t0 = time.perf_counter()
rep = check_program(sys.argv[1], m, sys.argv[2])
text = as_text(rep)
dt = time.perf_counter() - t0
print(json.dumps({"seconds": dt, "samples": rep.stats.get("samples", 0), "findings": len(rep.findings),
                  "errors": sum(f.severity == "error" for f in rep.findings), "text_bytes": len(text.encode())}))
"""


def run_case(program: Path, planner: str, timeout: float) -> dict:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]))
    with tempfile.TemporaryFile("w+") as out:
        p = subprocess.Popen([sys.executable, "-c", _CHILD, str(program), planner], stdout=out,
                             stderr=subprocess.DEVNULL, env=env, cwd=REPO)
        # reap it with wait4 ourselves (Popen.wait would discard the child's rusage)
        t_end = time.monotonic() + timeout
        while True:
            pid, status, ru = os.wait4(p.pid, os.WNOHANG)
            if pid:
                break
            if time.monotonic() > t_end:
                p.kill()
                _, status, ru = os.wait4(p.pid, 0)
                break
            time.sleep(0.05)
        p.returncode = status        # reaped: keep Popen from waiting on it again
        out.seek(0)
        lines = out.read().strip().splitlines()
    # CPU seconds of the whole child (imports included): on a shared, loaded machine the
    # wall time varies 2× between runs, the CPU time much less
    res = {"peak_rss_mb": round(ru.ru_maxrss / 1024.0, 1), "cpu_s": round(ru.ru_utime + ru.ru_stime, 2)}
    if os.WIFSIGNALED(status):
        res["error"] = f"killed after the {timeout:g} s timeout"
    elif os.WEXITSTATUS(status) != 0 or not lines:
        res["error"] = f"exit status {os.WEXITSTATUS(status)}"
    else:
        res.update(json.loads(lines[-1]))
    return res


def main(lines=LINES, planners=PLANNERS, timeout: float = 900.0, q0: bool = False, cycles: bool = False) -> dict:
    results = {}
    with tempfile.TemporaryDirectory() as d:
        for n in lines:
            f = Path(d) / f"cam_{n}.ngc"
            text = make_cam_program(n, seed=1, cycles=cycles)
            if q0:      # G64 P without Q joins short moves (Q = P): Q0 keeps every move
                text = text.replace("G64 P0.01", "G64 P0.01 Q0", 1)
            f.write_text(text)
            for planner in planners:
                r = run_case(f, planner, timeout)
                results[f"{planner}@{n}"] = r
                what = r.get("error") or (f"{r['seconds']:8.2f} s  {r['samples']:>8} samples  "
                                          f"{r['findings']:>7} findings  text {r['text_bytes'] / 1e3:.1f} kB")
                print(f"check {planner:<10} {n:>7} lines: {what}  peak RSS {r['peak_rss_mb']:.0f} MB  "
                      f"CPU {r['cpu_s']:.1f} s", flush=True)
    return results


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--lines", type=int, nargs="+", default=list(LINES))
    ap.add_argument("--planners", nargs="+", default=list(PLANNERS))
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds per case (default %(default)s)")
    ap.add_argument("--q0", action="store_true",
                    help="G64 P0.01 Q0: no naive-CAM joining, every one of the program's moves is planned")
    ap.add_argument("--cycles", action="store_true", help="drilling patterns by canned cycles between the rows")
    a = ap.parse_args()
    main(a.lines, a.planners, a.timeout, a.q0, a.cycles)
