"""The planners' error type (its own module so the registry and the constraint set share it
without importing each other)."""


class PlanningError(RuntimeError):
    """A planner cannot produce a profile; the message gives the reason."""
