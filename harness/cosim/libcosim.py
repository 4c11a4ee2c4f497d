"""The SSP a run writes, run in another master: OSP libcosim (through ``libcosimpy``).

libcosim loads the run folder's ``SystemStructure.ssd`` as it is (standard SSP 1.0, no OSP
annotations; the start values are the components' parameter bindings), initialises the FMUs
its own way (all in Initialization Mode, values passed along the connections, then all leave
it) and steps them with its fixed-step algorithm: every FMU steps from the same inputs, then
outputs go to inputs — the harness's ``--jacobi`` order. So its run of an SSP must equal the
harness's Jacobi run of the same SSP (tests/test_ssp_libcosim.py):

    python -m harness.cosim.libcosim results/keops_bird/scurve     # max |difference| per signal

The FMUs open the relative file names of the SSP (path.json, profile.csv) from the process's
working folder, so the run changes into the SSP's folder while it lasts. libcosim initialises
on its first step: the result has rows 1 … n (after each step), not the harness's row 0.
"""
from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path

import numpy as np

from harness.cosim.master import CoSimError, Result, simulate
from harness.cosim.run import RECORD
from harness.cosim.system import SystemError_, read_ssp

NS_PER_S = 1_000_000_000


@contextlib.contextmanager
def _in_folder(folder: Path):
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        yield
    finally:
        os.chdir(cwd)


def _recorders(ex, record):
    """[(slave index, [(column, value reference, type)])] for the "component.variable" names."""
    from libcosimpy.CosimEnums import CosimVariableType
    by_slave: dict[int, list] = {}
    for col, name in enumerate(record):
        comp, _, var = name.partition(".")
        k = ex.slave_index_from_instance_name(comp)
        if k is None or k < 0:
            raise SystemError_(f"record {name}: no component '{comp}' in libcosim's execution")
        v = next((v for v in ex.slave_variables(k) if v.name.decode() == var), None)
        if v is None:
            raise SystemError_(f"record {name}: no variable '{var}'")
        typ = CosimVariableType(v.type)
        if typ is CosimVariableType.STRING:
            raise SystemError_(f"record {name}: a String cannot be recorded")
        by_slave.setdefault(k, []).append((col, v.reference, typ))
    return by_slave


def simulate_libcosim(ssd: Path, record: list[str]) -> Result:
    """Run ``ssd`` (a SystemStructure.ssd written by harness.cosim.system.write_ssp) in libcosim
    for its stop time at its step; record ``record`` after every step."""
    from libcosimpy._internal import get_last_error_message
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level

    ssd = Path(ssd).resolve()
    system = read_ssp(ssd)
    slow = [c.name for c in system.components if c.period_steps != 1]
    if slow:   # the harness writes periods in a description, not as OSP's step-size hints
        raise SystemError_(f"{ssd}: components {', '.join(slow)} step every k-th period; libcosim runs one step for all")
    h_ns = round(system.step_size * NS_PER_S)
    if abs(h_ns / NS_PER_S - system.step_size) > 1e-12 * system.step_size:
        raise SystemError_(f"{ssd}: step {system.step_size!r} s is not a whole number of nanoseconds (libcosim's clock)")
    n = int(round(system.stop_time / system.step_size))
    log_output_level(CosimLogLevel.WARNING)
    with _in_folder(ssd.parent):
        try:
            ex = CosimExecution.from_ssp_file(str(ssd), step_size=h_ns)
        except AssertionError:
            raise CoSimError(f"libcosim cannot load {ssd}: {get_last_error_message()}") from None
        try:
            out = _steps(ex, record, n, system.step_size)
        finally:
            del ex   # frees the FMUs now, in the folder: the EtherCAT writes its histogram_out there
    return Result(np.arange(1, n + 1) * system.step_size, list(record), out, {})


def _steps(ex, record, n: int, h: float) -> np.ndarray:
    """n steps of ``ex``; row k = the recorded values after step k + 1."""
    from libcosimpy._internal import get_last_error_message
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimObserver import CosimObserver

    rec = _recorders(ex, record)
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    read = {CosimVariableType.REAL: obs.last_real_values, CosimVariableType.INTEGER: obs.last_integer_values,
            CosimVariableType.BOOLEAN: obs.last_boolean_values}
    groups = [(slave, [c[0] for c in cols if c[2] is typ], [c[1] for c in cols if c[2] is typ], read[typ])
              for slave, cols in rec.items() for typ in read if any(c[2] is typ for c in cols)]
    out = np.empty((n, len(record)))
    for k in range(n):
        if not ex.step(1):
            raise CoSimError(f"libcosim: step {k + 1} (t = {(k + 1) * h:.6g} s) failed: {get_last_error_message()}")
        for slave, columns, refs, get in groups:
            out[k, columns] = get(slave, refs)
    return out


def compare(ssd: Path, record: list[str]) -> dict[str, float]:
    """Max |libcosim − harness Jacobi| per recorded signal, on the same SSP."""
    theirs = simulate_libcosim(ssd, record)
    ours = simulate(read_ssp(Path(ssd)), record, jacobi=True)
    return {name: float(np.max(np.abs(theirs[name] - ours[name][1:]))) for name in record}


def main(argv=None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1:
        print("usage: python -m harness.cosim.libcosim RUN_FOLDER/PLANNER (or its SystemStructure.ssd)", file=sys.stderr)
        return 2
    ssd = Path(args[0])
    ssd = ssd / "SystemStructure.ssd" if ssd.is_dir() else ssd
    if not ssd.is_file():
        print(f"{ssd}: no such file", file=sys.stderr)
        return 2
    try:
        diff = compare(ssd, RECORD)
    except (SystemError_, CoSimError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    print(f"{ssd}: max |libcosim - harness (Jacobi)| per signal")
    for name, d in diff.items():
        print(f"  {name:28s} {d:.3e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
