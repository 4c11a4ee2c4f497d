"""`pkmbench check` on a generated 3-D surfacing job (issue 7 target: 10⁵ lines in ≤ 10 s).

The job is generated at run time (not committed): a zig-zag raster over a gently curved
surface inside the keops workspace, one G1 per ~0.5 mm.
    .venv/bin/python benchmarks/perf/bench_check.py [LINES]
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def surfacing_job(lines: int) -> str:
    rows = max(2, int(np.sqrt(lines / 2)))
    per_row = max(2, lines // rows)
    out = ["G21 G90 G64 P0.01", "G1 X-60 Y-60 Z-400 F6000"]
    for r in range(rows):
        y = -60 + 120 * r / (rows - 1)
        xs = np.linspace(-60, 60, per_row)
        if r % 2:
            xs = xs[::-1]
        for x in xs[1:] if r == 0 else xs:
            z = -400 + 10 * np.sin(x / 25) * np.cos(y / 25)
            out.append(f"G1 X{x:.4f} Y{y:.4f} Z{z:.4f}")
    return "\n".join(out[: lines + 2]) + "\nM2\n"


def main(lines: int = 100_000) -> dict:
    from harness.gcode_check import check_program
    from kins import load_machine

    m = load_machine("keops")
    with tempfile.TemporaryDirectory() as d:
        f = Path(d) / "surface.ngc"
        f.write_text(surfacing_job(lines))
        t0 = time.perf_counter()
        rep = check_program(f, m)
        dt = time.perf_counter() - t0
    n = sum(1 for _ in surfacing_job(lines).splitlines())
    print(f"check: {n} lines, {rep.stats.get('samples', 0)} samples, {len(rep.findings)} findings "
          f"in {dt:.2f} s (target ≤ 10 s for 10⁵ lines)")
    return {"lines": n, "seconds": dt, "samples": rep.stats.get("samples", 0)}


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 100_000)
