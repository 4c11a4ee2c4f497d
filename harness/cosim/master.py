"""Co-simulation masters: a native stepping loop (default) and a plain-Python reference.

Both take a :class:`harness.cosim.system.System`, instantiate every component with fmpy (start
values, logging), then step at the system's fixed step in Gauss–Seidel order (the order of
the components) or Jacobi, and record the requested variables after every macro step
(row 0 = after initialisation). An fmi2Error from any FMU ends the run with a
:class:`CoSimError` naming the FMU, the time and the FMU's log.
"""
from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from harness.cosim.fmu_file import unpack
from harness.cosim.system import CHAIN_FMUS, FMU_DIR, System, SystemError_, check_fmu

TYPES = {"Real": 0, "Integer": 1, "Boolean": 2, "Enumeration": 1, "Float64": 0, "Int32": 1}   # FMI 2.0 and 3.0 names
NATIVE_SRC = Path(__file__).with_name("native_master.c")


class CoSimError(RuntimeError):
    """A co-simulation failed: which FMU, when, and what it logged."""


@dataclass
class Result:
    t: np.ndarray
    columns: list[str]            # "component.variable"
    data: np.ndarray              # (steps + 1, len(columns))
    logs: dict[str, list[str]]

    def __getitem__(self, name: str) -> np.ndarray:
        return self.data[:, self.columns.index(name)]


def rebuild_hint(fmu: Path) -> str:
    """What to do about an FMU that does not load: one named as our blocks are is rebuilt with
    make; a user's FMU (blocks.check_user_fmu loads its binary first) is its maker's to rebuild."""
    ours = Path(fmu).name in {f"{b}.fmu" for b in CHAIN_FMUS}
    return "rebuild with 'make fmus'" if ours else "rebuild it for this platform with the tool that made it"


def extract(fmu: Path) -> Path:
    """The unpacked folder of an FMU (harness.cosim.fmu_file.unpack); a missing or corrupt one
    is a SystemError_ naming it."""
    return unpack(check_fmu(fmu))


class _Instance:
    """One FMU instance, FMI 2.0 or 3.0 co-simulation (fmpy's FMU2Slave / FMU3Slave): typed
    access by variable name (``set``, ``get``) or by type code and value reference (``get_vr``,
    ``set_vr``: TYPES' 0 Real/Float64, 1 Integer/Int32, 2 Boolean)."""

    def __init__(self, comp, start_time: float, logs: list[str], logging_on: bool = False):
        from fmpy import read_model_description

        self.name = comp.name
        unzip = Path(comp.fmu) if Path(comp.fmu).is_dir() else extract(comp.fmu)   # a folder: already unzipped
        try:
            md = read_model_description(str(unzip), validate=False)
        except Exception as e:
            raise SystemError_(f"{comp.fmu}: unreadable modelDescription.xml: {e}; {rebuild_hint(comp.fmu)}") from None
        self.vars = {v.name: v for v in md.modelVariables}
        self.logs = logs
        self.fmi3 = str(md.fmiVersion).startswith("3.")
        cwd = os.getcwd()
        try:   # loads the shared library; fmpy raises a bare Exception when it cannot
            from fmpy.fmi2 import FMU2Slave
            from fmpy.fmi3 import FMU3Slave
            self.fmu = (FMU3Slave if self.fmi3 else FMU2Slave)(
                guid=md.guid, unzipDirectory=str(unzip), modelIdentifier=md.coSimulation.modelIdentifier,
                instanceName=comp.name)
        except Exception as e:
            os.chdir(cwd)   # fmpy left the process in the FMU's binaries folder
            raise SystemError_(f"{comp.fmu}: cannot load the FMU's binary ({e}); {rebuild_hint(comp.fmu)}") from None
        try:
            self._instantiate(logging_on)
        except Exception as e:
            raise CoSimError(f"{comp.name} ({comp.fmu.name}): instantiation failed: {e}; log: {logs[-5:]}") from None
        f = self.fmu
        self._get = ({0: f.getFloat64, 1: f.getInt32, 2: f.getBoolean} if self.fmi3
                     else {0: f.getReal, 1: f.getInteger, 2: f.getBoolean})
        self._set = ({0: f.setFloat64, 1: f.setInt32, 2: f.setBoolean} if self.fmi3
                     else {0: f.setReal, 1: f.setInteger, 2: f.setBoolean})
        if not self.fmi3:   # FMI 3.0 takes the start time at fmi3EnterInitializationMode (0.0)
            self.fmu.setupExperiment(startTime=start_time)
        for var, value in comp.start.items():
            self.set(var, value)

    def _instantiate(self, logging_on: bool) -> None:
        labels = ['OK', 'WARNING', 'DISCARD', 'ERROR', 'FATAL', 'PENDING']
        if self.fmi3:
            def log3(env, status, category, message):
                self.logs.append(f"[{labels[status]}] {message.decode(errors='replace')}")
            self.fmu.instantiate(loggingOn=logging_on, logMessage=log3)
            return
        from fmpy.fmi2 import fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, calloc, free
        from fmpy.fmi2 import fmi2CallbackFunctions, fmi2CallbackLoggerTYPE

        def logger(env, instance, status, category, message):
            self.logs.append(f"[{labels[status]}] {message.decode(errors='replace')}")

        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = fmi2CallbackLoggerTYPE(logger)
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self.fmu.instantiate(callbacks=self.callbacks, loggingOn=logging_on)

    def vr(self, name: str) -> int:
        if name not in self.vars:
            raise SystemError_(f"component {self.name}: no variable '{name}'")
        return self.vars[name].valueReference

    def get_vr(self, code: int, vr: int) -> float:
        return float(self._get[code]([vr])[0])

    def set_vr(self, code: int, vr: int, x: float) -> None:
        self._set[code]([vr], [x if code == 0 else int(x) if code == 1 else x != 0.0])

    def set(self, name: str, value) -> None:
        v = self.vars.get(name)
        if v is None:
            raise SystemError_(f"component {self.name}: no variable '{name}'")
        try:
            if v.type == "String":
                self.fmu.setString([v.valueReference], [str(value)])
            else:
                code = TYPES[v.type]
                self._set[code]([v.valueReference], [float(value) if code == 0 else int(value) if code == 1
                                                     else bool(value)])
        except Exception:
            raise CoSimError(f"component {self.name}: cannot set {name} = {value!r}: {' | '.join(self.logs[-3:])}") from None

    def get(self, name: str) -> float:
        v = self.vars[name]
        return self.get_vr(TYPES[v.type], v.valueReference)

    def do_step(self, t: float, h: float) -> None:
        self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)


def _instantiate(system: System) -> tuple[list[_Instance], dict[str, list[str]]]:
    logs: dict[str, list[str]] = {}
    insts = []
    try:
        for comp in system.components:
            logs[comp.name] = []
            insts.append(_Instance(comp, 0.0, logs[comp.name]))
        for inst in insts:
            inst.fmu.enterInitializationMode()
        # Leave initialisation along the signal flow: each component gets its inputs from the
        # components already initialised (the Interpolator's start point reaches the IK, the
        # IK's joints reach the bus and the drives' start positions). Feedback inputs from
        # components not yet initialised keep their start values.
        by = {i.name: i for i in insts}
        ready: set[str] = set()
        for inst in insts:
            for c in system.connections:
                if c.dst == inst.name and c.src in ready:
                    inst.set(c.dst_var, by[c.src].get(c.src_var))
            try:
                inst.fmu.exitInitializationMode()
            except Exception:
                raise CoSimError(f"{inst.name}: initialisation failed: {' | '.join(inst.logs[-5:]) or 'no log'}") from None
            ready.add(inst.name)
    except BaseException:
        _free(insts)
        raise
    return insts, logs


def _free(insts) -> None:
    for inst in insts:
        try:
            inst.fmu.terminate()
        except Exception:
            pass
        try:
            inst.fmu.freeInstance()
        except Exception:
            pass


def _plan(system: System, insts, record):
    index = {i.name: k for k, i in enumerate(insts)}
    by = {i.name: i for i in insts}
    conn = []
    for c in system.connections:
        v = by[c.src].vars.get(c.src_var)
        if v is None or c.dst_var not in by[c.dst].vars:
            raise SystemError_(f"connection {c.src}.{c.src_var} → {c.dst}.{c.dst_var}: unknown variable")
        conn.append((TYPES[v.type], index[c.src], v.valueReference, index[c.dst], by[c.dst].vr(c.dst_var)))
    rec = []
    for name in record:
        comp, var = name.split(".", 1)
        if comp not in by:
            raise SystemError_(f"record {name}: no component '{comp}'")
        v = by[comp].vars.get(var)
        if v is None:
            raise SystemError_(f"record {name}: no variable '{var}'")
        rec.append((TYPES[v.type], index[comp], v.valueReference))
    return conn, rec


def _fail(insts, k: int, step: int, h: float, what: str) -> CoSimError:
    inst = insts[k]
    log = " | ".join(inst.logs[-5:]) or "no log"
    return CoSimError(f"{inst.name} {what} at t = {step * h:.6g} s: {log}")


def simulate_python(system: System, record: list[str], jacobi: bool = False) -> Result:
    """Reference master: the same loop as native_master.c, in Python (fmpy calls)."""
    insts, logs = _instantiate(system)
    try:
        conn, rec = _plan(system, insts, record)
        h = system.step_size
        n = int(round(system.stop_time / h))
        out = np.empty((n + 1, len(rec)))
        out[0] = [insts[c].get_vr(t, vr) for t, c, vr in rec]
        for k in range(n):
            t = k * h
            if jacobi:
                vals = [insts[s].get_vr(ty, svr) for ty, s, svr, d, dvr in conn]
                for (ty, s, svr, d, dvr), x in zip(conn, vals):
                    if k % system.components[d].period_steps == 0:
                        insts[d].set_vr(ty, dvr, x)
            for i, inst in enumerate(insts):
                per = system.components[i].period_steps
                if k % per:
                    continue
                if not jacobi:
                    for ty, s, svr, d, dvr in conn:
                        if d == i:
                            inst.set_vr(ty, dvr, insts[s].get_vr(ty, svr))
                try:
                    inst.do_step(t, h * per)
                except Exception:
                    raise _fail(insts, i, k, h, "failed") from None
            out[k + 1] = [insts[c].get_vr(t_, vr) for t_, c, vr in rec]
        return Result(np.arange(n + 1) * h, list(record), out, logs)
    finally:
        _free(insts)


class _Comp(ctypes.Structure):
    _fields_ = [("c", ctypes.c_void_p), ("do_step", ctypes.c_void_p), ("get_real", ctypes.c_void_p),
                ("set_real", ctypes.c_void_p), ("get_int", ctypes.c_void_p), ("get_bool", ctypes.c_void_p),
                ("set_int", ctypes.c_void_p), ("set_bool", ctypes.c_void_p), ("period", ctypes.c_int),
                ("fmi3", ctypes.c_int)]
# the C functions native_master.c calls, in _Comp's order, by FMI version
_C_API = {False: ("fmi2DoStep", "fmi2GetReal", "fmi2SetReal", "fmi2GetInteger", "fmi2GetBoolean",
                  "fmi2SetInteger", "fmi2SetBoolean"),
          True: ("fmi3DoStep", "fmi3GetFloat64", "fmi3SetFloat64", "fmi3GetInt32", "fmi3GetBoolean",
                 "fmi3SetInt32", "fmi3SetBoolean")}


_native = None


def native_library() -> ctypes.CDLL:
    """Compile native_master.c once per source hash into fmus/build/, load it."""
    global _native
    if _native is None:
        src = NATIVE_SRC.read_bytes()
        so = FMU_DIR / f"native_master-{hashlib.sha256(src).hexdigest()[:12]}.so"
        if not so.exists():
            FMU_DIR.mkdir(parents=True, exist_ok=True)
            tmp = so.with_name(f".{so.name}.{os.getpid()}.part")   # two runs may compile it at once
            try:
                r = subprocess.run(["cc", "-std=c11", "-O2", "-fPIC", "-shared", "-Wall", "-Wextra", "-Werror",
                                    "-o", str(tmp), str(NATIVE_SRC)], capture_output=True, text=True)
                if r.returncode:
                    raise SystemError_(f"compiling {NATIVE_SRC.name} failed:\n{r.stderr}")
                tmp.rename(so)
            finally:
                tmp.unlink(missing_ok=True)
        lib = ctypes.CDLL(str(so))
        lib.pkm_run.restype = ctypes.c_int
        lib.pkm_run.argtypes = [ctypes.c_int, ctypes.POINTER(_Comp), ctypes.c_int, ctypes.POINTER(ctypes.c_int),
                                ctypes.c_int, ctypes.POINTER(ctypes.c_int), ctypes.c_double, ctypes.c_double,
                                ctypes.c_long, ctypes.c_int, ctypes.POINTER(ctypes.c_double),
                                ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_long)]
        _native = lib
    return _native


def simulate_native(system: System, record: list[str], jacobi: bool = False) -> Result:
    """Default master: fmpy instantiates, native_master.c steps, routes and records (through the
    FMI 2.0 or 3.0 C API of each FMU)."""
    lib = native_library()
    insts, logs = _instantiate(system)
    try:
        conn, rec = _plan(system, insts, record)
        h = system.step_size
        n = int(round(system.stop_time / h))
        comps = (_Comp * len(insts))()
        for k, inst in enumerate(insts):
            fns = [ctypes.cast(getattr(inst.fmu.dll, f), ctypes.c_void_p).value for f in _C_API[inst.fmi3]]
            comps[k] = _Comp(inst.fmu.component, *fns, system.components[k].period_steps, int(inst.fmi3))
        c_conn = (ctypes.c_int * max(1, 5 * len(conn)))(*[x for c in conn for x in c])
        c_rec = (ctypes.c_int * max(1, 3 * len(rec)))(*[x for r in rec for x in r])
        out = np.empty((n + 1, len(rec)))
        buf = np.empty(max(1, len(conn)))
        fail_step = ctypes.c_long(0)
        rc = lib.pkm_run(len(insts), comps, len(conn), c_conn, len(rec), c_rec, 0.0, h, n, int(jacobi),
                         out.ctypes.data_as(ctypes.POINTER(ctypes.c_double)),
                         buf.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), ctypes.byref(fail_step))
        if rc > 0:
            raise _fail(insts, rc - 1, fail_step.value, h, "failed")
        if rc < 0:
            raise _fail(insts, -rc - 1, fail_step.value, h, "refused an input")
        return Result(np.arange(n + 1) * h, list(record), out, logs)
    finally:
        _free(insts)


def simulate(system: System, record: list[str], *, engine: str = "native", jacobi: bool = False) -> Result:
    if engine == "native":
        return simulate_native(system, record, jacobi)
    if engine == "python":
        return simulate_python(system, record, jacobi)
    raise ValueError(f"unknown engine '{engine}'; valid: native, python")
