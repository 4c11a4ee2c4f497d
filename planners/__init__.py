"""Feedrate planners: a toolpath + a machine → a feed profile s(t) at the servo period.

Each planner is a callable ``plan(path, machine, limits=None, **options) -> Profile``
(:class:`planners.registry.Planner`). :mod:`planners.registry` says which exist (built-ins,
installed plug-ins of the entry-point group ``pkmbench.planners``, ``module:function``);
:func:`plan` times the call into ``profile.planning_time_s`` and validates the result.
"""
from __future__ import annotations

import copy
import math
import time

from planners import registry
from planners.errors import PlanningError
from planners.paths import Path, resolve_path
from planners.profile import Profile, ProfileError
from planners.timeout import run_limited

# the built-in planners (registry.names() adds the installed plug-ins)
PLANNERS = tuple(registry.BUILTIN)

__all__ = ["PLANNERS", "PlanningError", "Profile", "get_planner", "plan", "plan_in_time", "registry"]


def get_planner(name: str):
    """The plan function of planner ``name`` (built-in, plug-in or module:function)."""
    return registry.get(name)


def plan(name: str, path, machine, limits=None, **options):
    """Run planner ``name``; the profile's ``planning_time_s`` is the wall time of the call.

    ``path`` may be a Path or a file / standard path name (resolved first, not timed).
    The planner gets its own copy of ``machine``: what it changes there (its limits, T) stays
    with it, not with the planners after it. A result that is not a valid :class:`Profile`
    sampled at the machine's servo period is a PlanningError naming the planner.
    """

    fn = get_planner(name)
    if not isinstance(path, Path):
        path = resolve_path(path)
    own = copy.deepcopy(machine)
    t0 = time.perf_counter()
    profile = fn(path, own, limits, **options)
    elapsed = time.perf_counter() - t0
    if not isinstance(profile, Profile):
        raise PlanningError(f"planner {name!r} returned {type(profile).__name__}, not a planners.Profile")
    T = machine.servo_period_s
    if not (isinstance(profile.T, (int, float)) and math.isclose(profile.T, T, rel_tol=1e-9)):
        raise PlanningError(f"planner {name!r} returned a profile sampled at T = {profile.T!r} s; "
                            f"{machine.name}'s servo period is {T:g} s")
    profile.planning_time_s = elapsed
    try:
        profile.validate()
    except ProfileError as e:   # the message starts with the profile's own label: say whose it is
        raise PlanningError(f"planner {name!r} returned an invalid profile: {e}") from None
    return profile


def plan_in_time(timeout_s, name: str, path, machine, limits=None, **options):
    """:func:`plan` stopped after ``timeout_s`` seconds (None: no limit, in this process), the
    planner's error naming the timeout (planners.timeout: in a child process, killed when it is over)."""
    if timeout_s is None:
        return plan(name, path, machine, limits, **options)
    return run_limited(timeout_s, name, path, machine, limits, options)
