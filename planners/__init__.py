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


class PlanningError(RuntimeError):
    """A planner cannot produce a profile; the message gives the reason."""


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
        from planners.path import resolve_path
        path = resolve_path(path)
    t0 = time.perf_counter()
    profile = fn(path, machine, limits, **options)
    profile.planning_time_s = time.perf_counter() - t0
    profile.validate()
    return profile


def check_limits(limits, planner: str = "planner") -> None:
    """Raise PlanningError unless every limit is a finite number > 0."""
    vals = {"feed_max": limits.feed_max, "chord_error_mm": limits.chord_error_mm}
    for group in ("joint", "cartesian"):
        lim = getattr(limits, group)
        vals.update({f"{group}.v": lim.v, f"{group}.a": lim.a, f"{group}.j": lim.j})
    for name, v in vals.items():
        try:
            ok = v > 0 and v < float("inf")
        except TypeError:
            ok = False
        if not ok:
            raise PlanningError(f"{planner}: limit {name} = {v!r} must be a finite number > 0")


def check_workspace(path, machine, step_mm: float = 0.5) -> None:
    """Raise PlanningError naming the first path point (arc length, G-code line, xyz and the
    joint or box side) that ``machine.check`` flags — out of reach, beyond a joint stroke,
    outside the workspace box or near a singularity — sampling the path every ≤ step_mm."""
    s, P = path.sample(step_mm)
    findings = machine.check(P)
    if not findings:
        return
    f = findings[0]
    where = ""
    if hasattr(path, "line_at"):
        ln = int(path.line_at(s[f.index])[0])
        where = f" (G-code line {ln})" if ln >= 0 else ""
    joint = f" [joint {f.joint}]" if f.joint is not None else ""
    raise PlanningError(f"{path.source}: the path leaves the workspace of {machine.name} at "
                        f"s = {s[f.index]:.6g} mm{where}{joint}: {f.message}")
