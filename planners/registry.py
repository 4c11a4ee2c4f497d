"""Which planners exist and where their code is: built-ins, installed plug-ins, ``module:function``.

Every command (run, plan, sweep, ci, corpus, …) asks this module, so a plug-in installed with
pip appears everywhere at once, with no edit of pkmbench:

    names()        built-ins, then the entry points of the group ``pkmbench.planners``, sorted
    known(name)    a name of names(), or a ``module:function`` spec (importable or not: get() says)
    get(name)      the plan function; a PlanningError naming the planner and the cause otherwise
    describe(name) where it comes from (built-in / distribution and version / spec), its guarantees
    guarantees(name)  the limits it keeps (BUILTIN_GUARANTEES, or a plug-in's ``guarantees``)
    stochastic(name)  whether its result depends on its ``seed`` option (BUILTIN_STOCHASTIC, or
                   a plug-in's ``stochastic = True``): reports run it over seeds

A plug-in is any callable that follows :class:`Planner`::

    # pyproject.toml of the plug-in package
    [project.entry-points."pkmbench.planners"]
    ruckig_axis = "pkmbench_ruckig:plan"

or, without installing anything, ``--planners mypkg.mod:plan`` (the module must be importable:
on sys.path / PYTHONPATH).
"""
from __future__ import annotations

import importlib
from importlib.metadata import entry_points
from typing import Any, Protocol, runtime_checkable

from planners.errors import PlanningError

GROUP = "pkmbench.planners"

# name → (module, function): scurve_joint is the s-curve with a joint-space repair step.
BUILTIN = {
    "trapezoid": ("planners.trapezoid", "plan"),
    "scurve": ("planners.scurve", "plan"),
    "scurve_joint": ("planners.scurve", "plan_joint"),
    "pso": ("planners.pso", "plan"),                 # the particle swarm alone (Erwinski et al.)
    "pso_socp": ("planners.pso", "plan_socp"),       # the swarm polished by the TOPP3-SOCP (memetic)
    "toppra": ("planners.optimal.toppra", "plan"),
    "optimal": ("planners.optimal.planner", "plan"),
    "copp": ("planners.optimal.copp", "plan"),       # COPP's TOPP3-SOCP (copp-py): a second jerk-limited reference
    "linuxcnc": ("planners.linuxcnc", "plan"),   # the real LinuxCNC 2.9, run headless
}

# What a planner may declare it keeps within (its ``guarantees`` attribute): space → orders.
GUARANTEE_KEYS = {"joint": ("velocity", "acceleration", "jerk"),
                  "cartesian": ("velocity", "acceleration", "jerk", "feed")}

# What the built-ins keep: only what tests/test_planner_claims.py measures on keops and kossel
# (toppra's acceleration holds on its own grid, not at T; trapezoid and linuxcnc claim nothing
# there). Declared here so the planner modules need no edit.
BUILTIN_GUARANTEES = {
    "scurve": {"cartesian": ["velocity", "acceleration", "jerk", "feed"]},
    "scurve_joint": {"joint": ["velocity", "acceleration", "jerk"], "cartesian": ["feed"]},
    "pso": {"joint": ["velocity", "acceleration", "jerk"], "cartesian": ["feed"]},
    "pso_socp": {"joint": ["velocity", "acceleration", "jerk"], "cartesian": ["feed"]},
    "toppra": {"joint": ["velocity"], "cartesian": ["feed"]},
    "optimal": {"joint": ["velocity", "acceleration", "jerk"], "cartesian": ["feed"]},
    "copp": {"joint": ["velocity", "acceleration", "jerk"], "cartesian": ["feed"]},
}


# The built-ins whose profile depends on their ``seed`` option (the swarm's random numbers):
# the corpus and the reports run them over seeds and show the distribution.
BUILTIN_STOCHASTIC = frozenset({"pso", "pso_socp"})   # their plan functions say so too (.stochastic)


@runtime_checkable
class Planner(Protocol):
    """The planner interface (built-ins and plug-ins alike).

    ``plan(path, machine, limits=None, **options) -> planners.Profile``

    - ``path``: a :class:`planners.paths.Path` (arc-length parametrised geometry: ``length``,
      ``point(s)``, ``derivs(s)``, ``tangent(s)``, ``curvature(s)``; ``program`` for G-code).
    - ``machine``: a :class:`kins.Kinematics` (``servo_period_s`` = T, ``limits`` with
      ``joint``/``cartesian`` v, a, j and ``feed_max``, ``ik(P)``, ``home``).
    - ``limits``: a :class:`kins.machine.MachineLimits` to plan under instead of
      ``machine.limits`` (None: the machine's).
    - ``options``: keyword options from ``[planner_options.NAME]`` of a suite.
    - returns a :class:`planners.Profile` sampled at T: s from 0 to ``path.length``, at rest at
      both ends, monotone, finite (:meth:`Profile.validate` checks it; anything else is
      reported as that planner's error, and the other planners go on).

    Optional attribute ``stochastic = True``: the result depends on the ``seed`` option; the
    corpus runs it over seeds and reports the distribution.

    Optional attribute ``guarantees``: ``{"joint": [...], "cartesian": [...]}`` naming the
    orders (velocity, acceleration, jerk; Cartesian also feed) whose limits the planner keeps
    by construction; `pkmbench plan --list` shows it. The harness measures every order anyway.
    """

    def __call__(self, path: Any, machine: Any, limits: Any = None, **options: Any) -> Any: ...


def _entry_points() -> dict:
    """name → EntryPoint of the group; a built-in name wins over a plug-in of the same name."""
    return {ep.name: ep for ep in sorted(entry_points(group=GROUP), key=lambda e: e.name)
            if ep.name not in BUILTIN}


def is_spec(name: str) -> bool:
    mod, sep, fn = name.partition(":")
    return bool(sep and mod and fn)


def names() -> list[str]:
    """Every planner a command accepts by name: the built-ins, then the installed plug-ins."""
    return list(BUILTIN) + sorted(_entry_points())


def known(name: str) -> bool:
    return name in BUILTIN or is_spec(name) or name in _entry_points()


def unknown_message(bad: list[str]) -> str:
    return (f"unknown planner(s) {', '.join(bad)}; valid: {', '.join(names())} "
            f"or module:function")


def _load(name: str, module: str, func: str, origin: str):
    try:
        mod = importlib.import_module(module)
    except Exception as e:   # a plug-in's own import error is its problem, reported in one line
        if isinstance(e, ModuleNotFoundError) and e.name == module:
            raise PlanningError(f"planner {name!r} ({origin}): module {module} is not available") from None
        raise PlanningError(f"planner {name!r} ({origin}): importing {module} failed: "
                            f"{type(e).__name__}: {e}") from None
    fn = getattr(mod, func, None)
    if fn is None:
        raise PlanningError(f"planner {name!r} ({origin}): {module} has no attribute {func}")
    if not callable(fn):
        raise PlanningError(f"planner {name!r} ({origin}): {module}.{func} is not callable")
    return fn


def get(name: str):
    """The plan function of ``name`` (its module imported on first use)."""
    if name in BUILTIN:
        module, func = BUILTIN[name]
        return _load(name, module, func, "built-in")
    eps = _entry_points()
    if name in eps:
        ep = eps[name]
        module, _, func = ep.value.partition(":")
        return _load(name, module.strip(), func.strip() or "plan", f"plug-in {ep.value}")
    if is_spec(name):
        module, _, func = name.partition(":")
        return _load(name, module, func, "module:function")
    raise PlanningError(unknown_message([name]))


def describe(name: str) -> dict:
    """{"name", "source", "version", "guarantees" (or None), "stochastic", "error" (if it cannot
    be loaded)}."""
    out: dict = {"name": name, "version": None, "guarantees": None, "stochastic": False}
    if name in BUILTIN:
        out["source"] = "built-in " + ":".join(BUILTIN[name])
    else:
        ep = _entry_points().get(name)
        if ep is not None:
            dist = getattr(ep, "dist", None)
            out["source"] = f"plug-in {ep.value}" + (f" from {dist.name}" if dist else "")
            out["version"] = dist.version if dist else None
        else:
            out["source"] = "module:function"
    try:
        fn = get(name)
    except PlanningError as e:
        out["error"] = str(e)
        return out
    out["guarantees"] = _guarantees(name, fn)
    out["stochastic"] = _stochastic(name, fn)
    return out


def _guarantees(name: str, fn) -> dict | None:
    g = BUILTIN_GUARANTEES.get(name) if name in BUILTIN else getattr(fn, "guarantees", None)
    if not isinstance(g, dict):
        return None
    return {k: list(g[k]) for k in GUARANTEE_KEYS if k in g}


def _stochastic(name: str, fn) -> bool:
    return name in BUILTIN_STOCHASTIC if name in BUILTIN else getattr(fn, "stochastic", False) is True


def guarantees(name: str) -> dict | None:
    """{"joint": [...], "cartesian": [...]}: the orders whose limits ``name`` keeps (the one
    table of them: the corpus, `plan --list` and the claims test read it here); None when it
    declares nothing or cannot be loaded."""
    if name in BUILTIN:
        return _guarantees(name, None)
    try:
        return _guarantees(name, get(name))
    except PlanningError:
        return None


def stochastic(name: str) -> bool:
    """Whether ``name``'s result depends on its ``seed`` option."""
    if name in BUILTIN:
        return name in BUILTIN_STOCHASTIC
    try:
        return _stochastic(name, get(name))
    except PlanningError:
        return False


def seeded(name: str, options: dict | None, seed: int) -> dict:
    """``options`` for planner ``name`` in a run with ``seed``: a stochastic planner takes the
    run's seed unless its options name one, so a sweep over seeds is a distribution of its plans
    (not of the bus alone)."""
    out = dict(options or {})
    if stochastic(name):
        out.setdefault("seed", seed)
    return out


def plugin_version(name: str) -> str | None:
    """The installed distribution version of a plug-in (None for built-ins and specs): part of
    a sweep task's key, so upgrading a plug-in re-runs its tasks."""
    if name in BUILTIN:
        return None
    ep = _entry_points().get(name)
    dist = getattr(ep, "dist", None) if ep is not None else None
    return f"{dist.name}=={dist.version}" if dist else None
