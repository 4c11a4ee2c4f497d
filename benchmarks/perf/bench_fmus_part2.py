"""Speed of Drive.fmu and EtherCAT.fmu per communication step (issue 4).

Compiles a small C driver (bench_fmus_part2.c) that loads each built FMU's shared library
and times fmi2DoStep in a tight loop, so the number is the model's cost, not Python's.
Targets (issue 4): Drive ≤ 1 µs per 250 µs step (4 inner steps) per axis; EtherCAT ≤ 0.5 µs
per cycle.   usage: .venv/bin/python benchmarks/perf/bench_fmus_part2.py [N]
"""
from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

import fmpy
from fmpy import extract, read_model_description

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent


def build_driver(tmp: Path) -> Path:
    exe = tmp / "bench_fmus_part2"
    inc = Path(fmpy.__file__).parent / "c-code"
    subprocess.run(["cc", "-O2", "-I", str(inc), "-o", str(exe), str(HERE / "bench_fmus_part2.c"),
                    "-ldl"], check=True)
    return exe


def time_fmu(exe: Path, name: str, step: float, n: int, reals: dict, strings: dict,
             tmp: Path) -> float:
    fmu = ROOT / "fmus" / "build" / f"{name}.fmu"
    if not fmu.exists():
        subprocess.run([sys.executable, str(ROOT / "fmus" / "build.py")], check=True)
    d = Path(extract(str(fmu), unzipdir=str(tmp / name)))
    md = read_model_description(str(d))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    ident = md.coSimulation.modelIdentifier
    lib = d / "binaries" / "linux64" / f"{ident}.so"
    args = [str(exe), str(lib), md.guid, (d / "resources").as_uri(), repr(step), str(n)]
    args += [f"{vr[k]}={v!r}" for k, v in reals.items()]
    args += [f"s{vr[k]}={v}" for k, v in strings.items()]
    out = subprocess.run(args, check=True, capture_output=True, text=True).stdout
    return float(out.split()[1])


CASES = [  # key, FMU, what, step, Real start values, String start values, budget ns (issue 4)
    ("drive_keops_250us", "Drive", "keops linear motor, 250 µs step (4 × 62.5 µs)", 250e-6,
     {"target": 0.0}, {"motor": "linear"}, 1000.0),
    ("drive_kossel_1ms", "Drive", "kossel stepper, 1 ms step (16 × 62.5 µs)", 1e-3,
     {"target": 0.0, "mass_kg": 0.25}, {"motor": "stepper_belt"}, None),
    ("ethercat_tuned_rt_250us", "EtherCAT", "tuned_rt preset, 250 µs cycle", 250e-6,
     {"cycle_s": 250e-6, "sync0_shift_s": 125e-6}, {"preset": "tuned_rt"}, 500.0),
    ("ethercat_linuxcnc_1ms", "EtherCAT", "linuxcnc_rt_preempt preset, 1 ms cycle", 1e-3,
     {"cycle_s": 1e-3, "sync0_shift_s": 500e-6}, {"preset": "linuxcnc_rt_preempt"}, 500.0),
]


def main(n: int = 1_000_000) -> dict:
    """Returns {case: {"ns_per_step", "budget_ns", "ok"}} (run_all.py calls this)."""
    results = {}
    with tempfile.TemporaryDirectory() as t:
        tmp = Path(t)
        exe = build_driver(tmp)
        for key, name, what, step, reals, strings, budget in CASES:
            ns = time_fmu(exe, name, step, n, reals, strings, tmp)
            ok = None if budget is None else ns <= budget
            verdict = "" if budget is None else ("  ok" if ok else f"  OVER {budget:g} ns")
            print(f"{name:9s} {what:48s} {ns:9.1f} ns/step{verdict}", flush=True)
            results[key] = {"ns_per_step": ns, "budget_ns": budget, "ok": ok}
    return results


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 1_000_000)
