"""A minimal fmpy driver for FMU unit tests: instantiate, set start values, initialise, and
collect the FMU's log."""
from __future__ import annotations

from pathlib import Path

from harness.master import _Instance
from harness.system import Component, FMU_DIR


class Fmu:
    def __init__(self, name: str, start: dict | None = None, fmu=None):
        self.logs: list[str] = []
        self.inst = _Instance(Component(name.lower(), fmu or FMU_DIR / f"{name}.fmu", dict(start or {})), 0.0, self.logs)
        self.fmu = self.inst.fmu

    def init(self) -> bool:
        """True if initialisation succeeded (the FMU's message is in self.logs otherwise)."""
        self.fmu.enterInitializationMode()
        try:
            self.fmu.exitInitializationMode()
            return True
        except Exception:
            return False

    def set(self, **values):
        for k, v in values.items():
            self.inst.set(k, v)

    def get(self, *names):
        return [self.inst.get(n) for n in names]

    def step(self, t: float, h: float) -> bool:
        try:
            self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
            return True
        except Exception:
            return False

    def close(self):
        try:
            self.fmu.terminate()
        except Exception:
            pass
        self.fmu.freeInstance()


class SteppedFmu:
    """One FMU instance (an unzipped folder) initialised with ``start`` and stepped at ``step``
    from Python; every message of its logger is kept (``messages``, and the class's
    ``last_messages`` for instances whose initialisation raised)."""

    last_messages: list = []

    def __init__(self, unzipdir, start: dict, step: float, name: str = "fmu"):
        self.messages: list[str] = []
        type(self).last_messages = self.messages
        self.inst = _Instance(Component(name, Path(unzipdir), {}), 0.0, self.messages, logging_on=True)
        self.fmu, self.vars = self.inst.fmu, self.inst.vars
        self.step, self.t = step, 0.0
        self.set(start)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()

    def set(self, values: dict) -> None:
        for name, value in values.items():
            self.inst.set(name, value)

    def get(self, name: str):
        v = self.vars[name]
        if v.type == "Real":
            return self.fmu.getReal([v.valueReference])[0]
        if v.type in ("Integer", "Enumeration"):
            return self.fmu.getInteger([v.valueReference])[0]
        if v.type == "Boolean":
            return bool(self.fmu.getBoolean([v.valueReference])[0])
        return self.fmu.getString([v.valueReference])[0]

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()
