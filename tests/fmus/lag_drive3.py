"""The FMI 3.0 twin of lag_drive.py, made with pythonfmu3: a first-order lag, exact for a target
held over the step: p(t+h) = target + (p(t) − target)·exp(−h/τ). tests/test_user_fmu.py builds it
into an FMU and runs it in the chain in place of our Drive."""
import math

from pythonfmu3 import Boolean, Fmi3Causality, Fmi3Slave, Fmi3Variability, Float64


class LagDrive3(Fmi3Slave):
    author = "pkmbench tests"
    description = "first-order lag drive (pythonfmu3, FMI 3.0)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.time = 0.0
        self.tau = 0.002
        self.target = 0.0
        self.sync_ok = True
        self.position = self.velocity = self.current = self.following_error = 0.0
        self.fault = False
        self.register_variable(Float64("time", causality=Fmi3Causality.independent,
                                       variability=Fmi3Variability.continuous))
        self.register_variable(Float64("tau", causality=Fmi3Causality.parameter, variability=Fmi3Variability.tunable))
        self.register_variable(Float64("target", causality=Fmi3Causality.input))
        self.register_variable(Boolean("sync_ok", causality=Fmi3Causality.input, variability=Fmi3Variability.discrete))
        for name in ("position", "velocity", "current", "following_error"):
            self.register_variable(Float64(name, causality=Fmi3Causality.output))
        self.register_variable(Boolean("fault", causality=Fmi3Causality.output, variability=Fmi3Variability.discrete))

    def exit_initialization_mode(self):
        self.position = self.target          # at rest on the first target, as our Drive starts

    def do_step(self, current_time, step_size):
        new = self.target + (self.position - self.target) * math.exp(-step_size / self.tau)
        self.velocity = (new - self.position) / step_size
        self.position = new
        self.following_error = self.target - self.position
        self.time = current_time + step_size
        return True
