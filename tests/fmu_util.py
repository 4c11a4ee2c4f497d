"""A minimal fmpy driver for FMU unit tests: instantiate, set start values, initialise, and
collect the FMU's log."""
from __future__ import annotations

from harness.cosim.fmu_driver import SteppedFmu  # noqa: F401  (re-exported for the FMU tests)
from harness.cosim.master import _Instance
from harness.cosim.system import Component, FMU_DIR


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
