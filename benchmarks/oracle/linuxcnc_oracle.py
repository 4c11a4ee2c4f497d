"""`trapezoid` against the real LinuxCNC 2.9 tp (planner `linuxcnc`) on the oracle programs.

    PYTHONPATH=. python benchmarks/oracle/linuxcnc_oracle.py [--only NAME,...] [--repeat N]

Every program of benchmarks/oracle/programs/ (plus the standard test_part, the corpus CAM
programs and public CAM programs placed on the kossel by a work offset: PLACED) runs on LinuxCNC (headless, serialised: minutes of wall time, one heavy job) and
is planned by `trapezoid` with the programmed feed. Prints a Markdown table — execution times, Δ % and the joint
velocity peak ratio Δ % (both from planners.verify on each planner's own geometry) — and
writes results/oracle/linuxcnc_oracle.json. ``--repeat N`` runs LinuxCNC N times per program
and reports the spread of its execution time (the determinism of the `linuxcnc` planner).

A program with io commands between its moves (coolant, tool change) waits for LinuxCNC's io
task, whose cycle (0.1 s) runs free of the program: the wait depends on the phase the program
meets, run to run. `trapezoid` rests the mean; such a program runs ``--io-phases N`` times
(default 10), the k-th started k/N of an io cycle later, and LinuxCNC's time is the mean.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
CORPUS = REPO / "benchmarks/paths/corpus"
sys.path.insert(0, str(REPO))

from planners.verify import command_metrics  # noqa: E402
from kins import load_machine  # noqa: E402
from planners import plan  # noqa: E402
from planners.paths import resolve_path  # noqa: E402
from planners.paths.gcode.rs274.setup import make_setup  # noqa: E402
from planners.linuxcnc import IO_CYCLE_S  # noqa: E402
from planners.trapezoid.program import IO_COMMANDS  # noqa: E402

# program → machine (the delta's program is written for linuxcnc_delta's workspace)
PROGRAMS = {
    "test_part": ("kossel", REPO / "benchmarks/paths/test_part.ngc"),
    "thesis_f80_f160": ("kossel", HERE / "programs/thesis_f80_f160.ngc"),
    "square_g64": ("kossel", HERE / "programs/square_g64.ngc"),
    "square_g64p": ("kossel", HERE / "programs/square_g64p.ngc"),
    "zigzag_short": ("kossel", HERE / "programs/zigzag_short.ngc"),
    "line_arc_tangent": ("kossel", HERE / "programs/line_arc_tangent.ngc"),
    "mcodes": ("kossel", HERE / "programs/mcodes.ngc"),
    "spiral_arcs": ("kossel", HERE / "programs/spiral_arcs.ngc"),
    "delta_star": ("linuxcnc_delta", HERE / "programs/delta_star.ngc"),
    # G64 Q (LinuxCNC's naive-CAM joining): our program and LinuxCNC's own quick tests
    "naive_cam_q": ("kossel", HERE / "programs/naive_cam_q.ngc"),
    "lcnc_naive_cam_corner1": ("kossel", HERE / "programs/lcnc_naive_cam_corner1.ngc"),
    "lcnc_naive_cam_corner2": ("kossel", HERE / "programs/lcnc_naive_cam_corner2.ngc"),
    "lcnc_naive_cam_reversal": ("kossel", HERE / "programs/lcnc_naive_cam_reversal.ngc"),
    # G61 exact path: the kink's acceleration reduction stays at a corner that stops
    "g61_square": ("kossel", HERE / "programs/g61_square.ngc"),
    # the corpus CAM programs (benchmarks/paths/corpus)
    "cam_blend_kossel": ("kossel", CORPUS / "cam_blend_kossel.ngc"),
    "pocket_kossel": ("kossel", CORPUS / "pocket_kossel.ngc"),
    "contour_kossel": ("kossel", CORPUS / "contour_kossel.ngc"),
    "helix_kossel": ("kossel", CORPUS / "helix_kossel.ngc"),
    "cam_dense_lcnc": ("linuxcnc_delta", CORPUS / "cam_dense_lcnc.ngc"),
}
# public CAM programs placed on the kossel by a work offset (issue 33): (file, --offset, var
# file); the collection's files are not in the repository (benchmarks/paths/programs/README.md)
COLLECTION = REPO / "benchmarks/paths/programs/collection"
LCNC = REPO / "benchmarks/paths/programs/linuxcnc/nc_files"
PLACED = {
    "lcnc_3dtest": (LCNC / "3dtest.ngc", "G54=-25.4,-25.4,-250", None),
    "lcnc_3dtest_var": (LCNC / "3dtest.ngc", None, HERE / "programs/g55_3dtest.var"),
    "jscut_outside": (COLLECTION / "jscut/jscut-outside.gcode", "G54=-21,21,-250", None),
    "fusion360_1022": (COLLECTION / "fusion360/1022_block2x2_17bit.nc", "G54=-10,-10,-250", None),
    "fusion360_bore": (COLLECTION / "fusion360/1101_bore_tests.nc", "G54=-22.5,-15,-250", None),
    "gcodetools_arc": (COLLECTION / "gcodetools/arc_0001.gcode", "G54=-15,-25,-250", None),
    "pcb2gcode_d1mini_front": (COLLECTION / "pcb2gcode/D1MiniGSR_front.ngc", "G54=-12.5,-10,-250", None),
    "openvoronoi_vcarve": (COLLECTION / "openvoronoi/vcarve.ngc", "G54=-5,-2.5,-250", None),
    "pcb2gcode_drill_g81": (COLLECTION / "pcb2gcode/example_board_new_default_drill.ngc", "G54=-21,10,-250", None),
    "lcnc_tort": (LCNC / "tort.ngc", "G54=-10,-13,-250", None),
    "gcmc_wheels": (COLLECTION / "gcmc/wheels.ngc", "G54=-43.7,-39.3,-250", None),
}
TOOLS = REPO / "benchmarks/paths/programs/collection.tbl"


def measure(name, planner, path, machine, **options):
    pr = plan(planner, path, machine, **options)
    m = command_metrics(machine, pr.path.point(pr.s), pr.T, pr.s)
    return pr, m


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="", help="comma-separated program names")
    ap.add_argument("--repeat", type=int, default=1, help="LinuxCNC runs per program")
    ap.add_argument("--io-phases", type=int, default=10,
                    help="LinuxCNC runs, over one io cycle, of a program with io waits between moves")
    ap.add_argument("--out", default=str(REPO / "results/oracle/linuxcnc_oracle.json"))
    args = ap.parse_args(argv)
    names = [n for n in args.only.split(",") if n] or list(PROGRAMS) + list(PLACED)
    rows = []
    print("| program | machine | LinuxCNC s | trapezoid s | Δ % | joint v ratio LinuxCNC | trapezoid | Δ % |")
    print("|---|---|---|---|---|---|---|---|")
    for name in names:
        if name in PLACED:
            file, offset, var = PLACED[name]
            if not file.is_file():
                print(f"| {name} | not here: {file} |")
                continue
            mname, setup = "kossel", make_setup(TOOLS, var, [offset] if offset else [])
        else:
            (mname, file), setup = PROGRAMS[name], None
        machine = load_machine(mname)
        # a placed CAM program starts where the machine is (its first move need not give X, Y
        # and Z), as `pkmbench plan` reads it: from the machine's home
        path = resolve_path(str(file), **({"setup": setup, "home": machine.home} if setup else {}))
        moves = path.program.moves
        io_waits = any(e.kind == "m" and e.value in IO_COMMANDS and 0 < e.index < len(moves)
                       for e in path.program.events)
        n = max(1, args.io_phases) if io_waits else max(1, args.repeat)
        delays = [k * IO_CYCLE_S / n if io_waits else 0.0 for k in range(n)]
        runs = [measure(name, "linuxcnc", path, machine, start_delay_s=d) for d in delays]
        lc, mlc = runs[0]
        tz, mtz = measure(name, "trapezoid", path, machine)
        t_l, t_t = float(np.mean([r[0].execution_time_s for r in runs])), tz.execution_time_s
        v_l, v_t = mlc["joint_peak_ratio"]["velocity"], mtz["joint_peak_ratio"]["velocity"]
        row = {"program": name, "machine": mname, "linuxcnc_s": t_l, "trapezoid_s": t_t,
               "dt_pct": 100 * (t_t - t_l) / t_l, "joint_v_linuxcnc": v_l, "joint_v_trapezoid": v_t,
               "dv_pct": 100 * (v_t - v_l) / v_l,
               "linuxcnc_runs_s": [r[0].execution_time_s for r in runs], "start_delays_s": delays,
               "operator_pause_s": [r[0].info["operator_pause_s"] for r in runs]}
        rows.append(row)
        print(f"| {name} | {mname} | {t_l:.3f} | {t_t:.3f} | {row['dt_pct']:+.2f} | {v_l:.4f} | {v_t:.4f} "
              f"| {row['dv_pct']:+.2f} |" + (f" runs: {row['linuxcnc_runs_s']}" if len(runs) > 1 else ""),
              flush=True)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(rows, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
