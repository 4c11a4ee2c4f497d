"""A Drive made with pythonfmu (another tool than ours): a first-order lag, exact for a target
held over the step: p(t+h) = target + (p(t) − target)·exp(−h/τ). tests/test_user_fmu.py builds it
into an FMU and runs it in the chain in place of our Drive."""
import math

from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class LagDrive(Fmi2Slave):
    author = "pkmbench tests"
    description = "first-order lag drive (pythonfmu)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.tau = 0.002
        self.target = 0.0
        self.sync_ok = True
        self.position = self.velocity = self.current = self.following_error = 0.0
        self.fault = False
        self.register_variable(Real("tau", causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable))
        self.register_variable(Real("target", causality=Fmi2Causality.input))
        self.register_variable(Boolean("sync_ok", causality=Fmi2Causality.input))
        for name in ("position", "velocity", "current", "following_error"):
            self.register_variable(Real(name, causality=Fmi2Causality.output))
        self.register_variable(Boolean("fault", causality=Fmi2Causality.output))

    def exit_initialization_mode(self):
        self.position = self.target          # at rest on the first target, as our Drive starts

    def do_step(self, current_time, step_size):
        new = self.target + (self.position - self.target) * math.exp(-step_size / self.tau)
        self.velocity = (new - self.position) / step_size
        self.position = new
        self.following_error = self.target - self.position
        return True
