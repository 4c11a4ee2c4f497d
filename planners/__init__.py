"""Feedrate planners: a toolpath + a machine → a feed profile s(t) at the servo period.

Each planner is a module with ``plan(path, machine, limits=None, **options) -> Profile``.
This package holds the registry; :func:`plan` times the call into
``profile.planning_time_s`` and validates the result.
"""
from __future__ import annotations

import importlib
import time

# name → (module, function): scurve_joint is the s-curve with a joint-space repair step.
_REGISTRY = {
    "trapezoid": ("planners.trapezoid", "plan"),
    "scurve": ("planners.scurve", "plan"),
    "scurve_joint": ("planners.scurve", "plan_joint"),
    "pso": ("planners.pso", "plan"),
    "toppra": ("planners.toppra_ref", "plan"),
    "optimal": ("planners.optimal", "plan"),
    "linuxcnc": ("planners.linuxcnc", "plan"),   # the real LinuxCNC 2.9, run headless
}
PLANNERS = ("trapezoid", "scurve", "scurve_joint", "pso", "toppra", "optimal", "linuxcnc")


from planners.errors import PlanningError

__all__ = ["PLANNERS", "PlanningError", "get_planner", "plan"]


def get_planner(name: str):
    """The plan function of planner ``name`` (module imported on first use)."""
    if name not in _REGISTRY:
        raise PlanningError(f"unknown planner {name!r}; valid planners: {', '.join(PLANNERS)}")
    module, func = _REGISTRY[name]
    try:
        mod = importlib.import_module(module)
    except ModuleNotFoundError as e:
        if e.name == module:
            raise PlanningError(f"planner {name!r}: module {module} is not available") from None
        raise
    try:
        return getattr(mod, func)
    except AttributeError:
        raise PlanningError(f"planner {name!r}: {module} has no function {func}()") from None


def plan(name: str, path, machine, limits=None, **options):
    """Run planner ``name``; the profile's ``planning_time_s`` is the wall time of the call.

    ``path`` may be a Path or a file / standard path name (resolved first, not timed).
    """
    fn = get_planner(name)
    if not hasattr(path, "point"):
        from planners.paths import resolve_path
        path = resolve_path(path)
    t0 = time.perf_counter()
    profile = fn(path, machine, limits, **options)
    profile.planning_time_s = time.perf_counter() - t0
    profile.validate()
    return profile

