"""Drive a single FMU from Python, step by step (tests, figures, diagnostics).

    sim = SteppedFmu(unzipped_dir, {"motor": "stepper_belt", ...}, step=1e-3, name="drive")
    out = sim.run([{"target": 50.001}, {"target": 50.002}], ("position", "following_error"))
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from harness.cosim.master import _Instance
from harness.cosim.system import Component


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

    def run(self, inputs, outputs) -> dict[str, np.ndarray]:
        """One step per element of ``inputs`` (a dict of input values): set it, step from the
        current time, read every output; returns each output's trace."""
        out = {n: [] for n in outputs}
        for values in inputs:
            self.set(values)
            self.fmu.doStep(currentCommunicationPoint=self.t, communicationStepSize=self.step)
            self.t += self.step
            for n in outputs:
                out[n].append(self.get(n))
        return {n: np.array(v) for n, v in out.items()}

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()
