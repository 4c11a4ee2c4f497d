"""Feedrate planners: a toolpath + a machine → a feed profile s(t) at the servo period.

Each planner is a callable ``plan(path, machine, limits=None, **options) -> Profile``
(:class:`planners.registry.Planner`). :mod:`planners.registry` says which exist (built-ins,
installed plug-ins of the entry-point group ``pkmbench.planners``, ``module:function``);
:func:`plan` times the call into ``profile.planning_time_s`` and validates the result.
"""
from __future__ import annotations

import time

from planners import registry
from planners.errors import PlanningError
from planners.paths import Path, resolve_path
from planners.profile import Profile, ProfileError

# the built-in planners (registry.names() adds the installed plug-ins)
PLANNERS = tuple(registry.BUILTIN)

__all__ = ["PLANNERS", "PlanningError", "get_planner", "plan", "registry"]


def get_planner(name: str):
    """The plan function of planner ``name`` (built-in, plug-in or module:function)."""
    return registry.get(name)


def plan(name: str, path, machine, limits=None, **options):
    """Run planner ``name``; the profile's ``planning_time_s`` is the wall time of the call.

    ``path`` may be a Path or a file / standard path name (resolved first, not timed).
    A result that is not a valid :class:`Profile` is a PlanningError naming the planner.
    """

    fn = get_planner(name)
    if not isinstance(path, Path):
        path = resolve_path(path)
    t0 = time.perf_counter()
    profile = fn(path, machine, limits, **options)
    elapsed = time.perf_counter() - t0
    if not isinstance(profile, Profile):
        raise PlanningError(f"planner {name!r} returned {type(profile).__name__}, not a planners.Profile")
    profile.planning_time_s = elapsed
    try:
        profile.validate()
    except ProfileError as e:   # the message starts with the profile's own label: say whose it is
        raise PlanningError(f"planner {name!r} returned an invalid profile: {e}") from None
    return profile
