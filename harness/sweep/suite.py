"""Sweep suites: a suite file expanded into tasks, and the task keys.

A suite (benchmarks/suites/*.toml) names what one run covers; the sweep adds axes:

    name = "nightly"
    planner_timeout_s = 600      # optional: a planner over it is its row's error (--planner-timeout)
    [[run]]                      # any number; machines × paths × planners of each are crossed
    machine = "keops"            # or machines = [...]; an id of benchmarks/machines/ or a .toml file
    path = "bird"                # or paths = [...]; an id of benchmarks/paths/ or a .json/.ngc file
    planners = ["trapezoid", "scurve"]
    tool_table = "my.tbl"        # optional, G-code: LinuxCNC tool table, var file (paths relative
    var_file = "my.var"          # to the suite file) and work offsets (as --offset), see
    offset = ["G54=0,0,-300"]    # planners/paths/gcode/rs274/setup.py
    [planner_options.pso]        # optional, passed to the planner
    iterations = 40
    [sweep]                      # optional axes, crossed with every run
    seeds = [0, 1]               # default [0]; each 0 <= seed < 2**64: the bus's and a stochastic planner's
    presets = ["none", "tuned_rt"]  # EtherCAT jitter presets ("machine" = the machine file's), default ["none"]
    [[sweep.variation]]          # default: one variation "base" that changes nothing
    name = "jerk_half"
    set = { "limits.joint.j" = 2.5e5 }   # dotted keys of the machine file, overridden

This module is the one parser of suite files: `pkmbench run SUITE` takes the [[run]] tables
(:func:`suite_runs`), `pkmbench sweep`/`ci` expand them with the axes (:func:`expand`); both
refuse the same unknown keys (in every table) and accept ``planner``/``planners`` alike; a
suite expands to at most MAX_TASKS tasks.

One task = (machine, path, planner, seed, preset, variation). A task carries the *contents*
of its machine and path files, so a worker on another host needs only the code.
"""
from __future__ import annotations

import ast
import hashlib
import json
import math
import re
import tomllib
from pathlib import Path

from harness.cosim.blocks import check_user_fmu, command_fmus
from harness.cosim.system import SystemError_
from harness.seed import SeedError, check_seed
from kins.resources import FMU_DIR, MACHINE_DIR, PATH_DIR, REPO, repo_relative
from planners.paths.gcode.rs274 import RS274Error
from planners.paths.gcode.rs274.setup import make_setup
from planners.registry import plugin_version

PATH_SUFFIXES = (".json", ".ngc")
# Sources whose change can change a result: every task key depends on their hash.
CODE_DIRS = ("kins", "planners", "harness")


TOP_KEYS = ("name", "description", "run", "sweep", "planner_options", "ci", "fmus", "planner_timeout_s")
RUN_KEYS = ("machine", "machines", "path", "paths", "planner", "planners", "max_feed",
            "tool_table", "var_file", "offset")
SWEEP_KEYS = ("seeds", "presets", "variation")
VARIATION_KEYS = ("name", "set")
# tasks a suite may expand to: each is a co-simulation of seconds (10⁵ is days on one host);
# a suite asking for 10⁶ seeds filled 9.7 GB of task dicts before this limit
MAX_TASKS = 100_000


class SuiteError(ValueError):
    """A suite file is malformed; the message names the file and the key."""


def _line_of(text: str | None, key: str) -> str:
    """':line N' of the first assignment to key in the file's text (tomllib reports no
    positions), or '' without the text."""
    if text is None:
        return ""
    for i, line in enumerate(text.splitlines(), start=1):
        if re.match(rf"\s*\"?{re.escape(key)}\"?\s*=", line):
            return f":line {i}"
    return ":line ?"


def suite_runs(suite: dict, src: str = "<suite>", text: str | None = None) -> list[tuple[list, list, list, bool, dict]]:
    """The (machines, paths, planners, max_feed, gcode) of each [[run]] table, keys checked: what
    `pkmbench run` runs and :func:`expand` crosses with the sweep axes. ``max_feed = true`` runs
    G-code at F_max instead of its programmed F (planner-only comparisons); ``gcode``: the
    run's tool_table / var_file (Paths, relative to the suite file's folder) and offset specs,
    {} when it has none (:func:`gcode_setup` makes them a Setup)."""
    for key in suite:
        if key not in TOP_KEYS:
            raise SuiteError(f"{src}{_line_of(text, key)}: unknown key '{key}' (valid: {', '.join(sorted(TOP_KEYS))})")
    _check_tables(suite, src, text)
    runs = suite.get("run")
    if not isinstance(runs, list) or not runs:
        raise SuiteError(f"{src}: no [[run]] tables (need machine(s), path(s), planners)")
    out = []
    for i, run in enumerate(runs):
        where = f"[[run]] #{i + 1}"
        for key in run:
            if key not in RUN_KEYS:
                raise SuiteError(f"{src}{_line_of(text, key)}: {where}: unknown key '{key}' "
                                 f"(valid: machine(s), path(s), planner(s), max_feed, tool_table, var_file, offset)")
        if not isinstance(run.get("max_feed", False), bool):
            raise SuiteError(f"{src}{_line_of(text, 'max_feed')}: {where}: max_feed must be true or false")
        out.append((_list(run, "machine", "machines", src, where), _list(run, "path", "paths", src, where),
                    _list(run, "planner", "planners", src, where), run.get("max_feed", False),
                    _gcode_keys(run, src, text, where)))
    return out


def _gcode_keys(run: dict, src: str, text: str | None, where: str) -> dict:
    """A [[run]]'s tool_table, var_file (resolved next to the suite file) and offset, each
    checked by reading it (a bad file or spec: SuiteError naming it)."""
    base = Path(src).parent if src != "<suite>" else Path(".")
    g = {}
    for key in ("tool_table", "var_file"):
        if key in run:
            if not isinstance(run[key], str):
                raise SuiteError(f"{src}{_line_of(text, key)}: {where}: {key} must be a file name")
            f = Path(run[key])
            g[key] = f if f.is_absolute() else base / f
    if "offset" in run:
        specs = [run["offset"]] if isinstance(run["offset"], str) else run["offset"]
        if not (isinstance(specs, list) and all(isinstance(x, str) for x in specs)):
            raise SuiteError(f"{src}{_line_of(text, 'offset')}: {where}: offset must be a list of "
                             f"'CODE=X,Y,Z' strings")
        g["offset"] = list(specs)
    if g:
        try:
            gcode_setup(g)
        except SuiteError as e:
            raise SuiteError(f"{src}: {where}: {e}") from None
    return g


def gcode_setup(g: dict):
    """The planners.paths.gcode.rs274 Setup of a run's gcode keys (None without them)."""
    if not g:
        return None
    try:
        return make_setup(g.get("tool_table"), g.get("var_file"), g.get("offset", ()))
    except (RS274Error, ValueError) as e:
        raise SuiteError(str(e)) from None


def _list(d: dict, one: str, many: str, src: str, where: str) -> list:
    if one in d and many in d:
        raise SuiteError(f"{src}: {where} has both '{one}' and '{many}'; use one")
    v = [d[one]] if one in d else d.get(many)
    if not isinstance(v, list) or not v:
        raise SuiteError(f"{src}: {where} needs '{one}' or a non-empty list '{many}'")
    bad = next((x for x in v if not isinstance(x, str) or not x.strip()), None)
    if bad is not None:
        raise SuiteError(f"{src}: {where}: {one if one in d else many} = {bad!r}: expected a name "
                         f"(a string){' or a list of names' if many in d else ''}")
    return v


def _check_tables(suite: dict, src: str, text: str | None) -> None:
    """The types of the top-level keys, and the keys of [sweep] and [[sweep.variation]]: an
    unknown one is refused (``seedz = [1, 2]`` ran seed 0 only)."""
    for key, typ, what in (("name", str, "a string"), ("description", str, "a string"),
                           ("run", list, "[[run]] tables"), ("sweep", dict, "a [sweep] table"),
                           ("planner_options", dict, "a table of [planner_options.NAME] tables"),
                           ("ci", dict, "a [ci] table"), ("fmus", dict, "an [fmus] table")):
        if key in suite and not isinstance(suite[key], typ):
            raise SuiteError(f"{src}{_line_of(text, key)}: '{key}' must be {what}, got {suite[key]!r}"[:300])
    if not all(isinstance(r, dict) for r in suite.get("run", [])):
        raise SuiteError(f"{src}: 'run' must be [[run]] tables")
    for name, opts in suite.get("planner_options", {}).items():
        if not isinstance(opts, dict):
            raise SuiteError(f"{src}{_line_of(text, name)}: planner_options.{name} must be a table of options")
    if "planner_timeout_s" in suite:
        planner_timeout(suite["planner_timeout_s"], f"{src}{_line_of(text, 'planner_timeout_s')}: planner_timeout_s")
    sweep = suite.get("sweep", {})
    for key in sweep:
        if key not in SWEEP_KEYS:
            raise SuiteError(f"{src}{_line_of(text, key)}: [sweep]: unknown key '{key}' "
                             f"(valid: {', '.join(SWEEP_KEYS)})")
    variations = sweep.get("variation", [])
    if not isinstance(variations, list):
        raise SuiteError(f"{src}: [[sweep.variation]] must be tables")
    for i, v in enumerate(variations):
        for key in (v if isinstance(v, dict) else {}):
            if key not in VARIATION_KEYS:
                raise SuiteError(f"{src}{_line_of(text, key)}: [[sweep.variation]] #{i + 1}: unknown key '{key}' "
                                 f"(valid: {', '.join(VARIATION_KEYS)})")


def planner_timeout(value, where: str) -> float:
    """A planner time limit in seconds (a suite's planner_timeout_s, --planner-timeout): a finite
    number > 0, else SuiteError naming ``where``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise SuiteError(f"{where} = {value!r}: must be a number of seconds > 0")
    return float(value)


def task_count(suite: dict, src: str = "<suite>") -> int:
    """How many tasks the suite's [[run]] tables and [sweep] axes cross to (before listing them)."""
    sweep = suite.get("sweep", {})
    per_run = sum(len(m) * len(p) * len(pl) for m, p, pl, *_ in suite_runs(suite, src))
    axes = [sweep.get("seeds", [0]), sweep.get("presets", ["none"]), sweep.get("variation", [{}])]
    n = per_run
    for a in axes:
        n *= len(a) if isinstance(a, list) else 1
    return n


def resolve_machine(name: str, base: Path = REPO) -> Path:
    p = Path(name)
    if p.suffix == ".toml":
        p = p if p.is_absolute() else (base / p)
    else:
        p = MACHINE_DIR / f"{name}.toml"
    if not p.exists():
        known = ", ".join(sorted(q.stem for q in MACHINE_DIR.glob("*.toml")))
        raise SuiteError(f"machine '{name}': no file {p} (known: {known})")
    return p


def resolve_path(name: str, base: Path = REPO) -> Path:
    p = Path(name)
    if p.suffix in PATH_SUFFIXES:
        p = p if p.is_absolute() else (base / p)
        if p.exists():
            return p
    else:
        for suf in PATH_SUFFIXES:
            if (PATH_DIR / f"{name}{suf}").exists():
                return PATH_DIR / f"{name}{suf}"
    known = ", ".join(sorted(q.stem for q in PATH_DIR.iterdir() if q.suffix in PATH_SUFFIXES)) \
        if PATH_DIR.exists() else ""
    raise SuiteError(f"path '{name}': no file found (looked in {PATH_DIR}; known: {known or 'none'})")


def load_suite(file: str | Path) -> dict:
    file = Path(file)
    if not file.exists():
        raise SuiteError(f"{file}: no such suite file")
    text = file.read_text()
    try:
        suite = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise SuiteError(f"{file}: not valid TOML: {e}") from None
    suite_runs(suite, str(file), text)          # the keys, checked with their line numbers
    return suite


def expand(suite: dict, src: str = "<suite>", base: Path = REPO) -> list[dict]:
    """The tasks of a suite, in a stable order (runs × seeds × presets × variations)."""
    runs = suite_runs(suite, src)
    n = task_count(suite, src)
    if n > MAX_TASKS:
        raise SuiteError(f"{src}: the suite expands to {n} tasks (runs × seeds × presets × variations), "
                         f"more than the {MAX_TASKS} a sweep takes; split it into several suites")
    sweep = suite.get("sweep", {})
    seeds = sweep.get("seeds", [0])
    presets = sweep.get("presets", ["none"])
    variations = sweep.get("variation", [{"name": "base"}])
    if not (isinstance(seeds, list) and seeds):
        raise SuiteError(f"{src}: [sweep] seeds must be a non-empty list of integers, got {seeds!r}")
    try:
        for i, s in enumerate(seeds):
            check_seed(s, f"{src}: [sweep] seeds[{i}]")
        for name, opts in suite.get("planner_options", {}).items():
            if isinstance(opts, dict) and "seed" in opts:
                check_seed(opts["seed"], f"{src}: [planner_options.{name}] seed")
    except SeedError as e:
        raise SuiteError(str(e)) from None
    if not (isinstance(presets, list) and presets and all(isinstance(s, str) for s in presets)):
        raise SuiteError(f"{src}: [sweep] presets must be a non-empty list of names, got {presets!r}")
    names = set()
    for i, v in enumerate(variations):
        if not isinstance(v, dict) or not isinstance(v.get("name"), str):
            raise SuiteError(f"{src}: [[sweep.variation]] #{i + 1} needs a name")
        if v["name"] in names:
            raise SuiteError(f"{src}: [[sweep.variation]] name '{v['name']}' is used twice")
        names.add(v["name"])
        if not isinstance(v.get("set", {}), dict):
            raise SuiteError(f"{src}: [[sweep.variation]] '{v['name']}': set must be a table")
    options = suite.get("planner_options", {})
    tasks, seen = [], set()
    for machines, paths, planners, max_feed, gcode in runs:
        for m in machines:
            mfile = resolve_machine(m, base)
            for p in paths:
                pfile = resolve_path(p, base)
                for pl in planners:
                    for seed in seeds:
                        for preset in presets:
                            for v in variations:
                                t = make_task(mfile, pfile, pl, seed, preset, v,
                                              options.get(pl, {}))
                                if max_feed:       # only then: the other tasks' keys stay as they were
                                    t["max_feed"] = True
                                if gcode:          # likewise; the files' contents travel with the task
                                    t["gcode_setup"] = _gcode_contents(gcode)
                                if "planner_timeout_s" in suite:    # the same
                                    t["planner_timeout_s"] = float(suite["planner_timeout_s"])
                                ident = (t["machine"], t["path"], pl, seed, preset, v["name"], max_feed)
                                if ident in seen:
                                    continue           # the same task listed twice runs once
                                seen.add(ident)
                                tasks.append(t)
    return tasks


def _gcode_contents(g: dict) -> dict:
    out = {k: Path(g[k]).read_text() for k in ("tool_table", "var_file") if k in g}
    if "offset" in g:
        out["offset"] = list(g["offset"])
    return out


def user_fmus_info(tasks) -> dict | None:
    """{"fmus": the user FMUs (file, sha256, source) by block} for the results store's run_info,
    None on our own chain (its rows stay as they were)."""
    named = tasks[0].get("fmus") if tasks else None
    return {"fmus": named} if named else None


def with_user_fmus(tasks: list[dict], suite: dict | None, suite_file=None, specs=()) -> list[dict]:
    """The tasks with the command's user FMUs (the suite's [fmus], ``--fmu BLOCK=FILE`` specs),
    each checked against its block's interface before any task runs: a wrong one is a SuiteError
    with harness.cosim.blocks.check_user_fmu's message. A task names each FMU by its file name,
    the sha256 of its content (part of the task key) and its source file (which the client ships
    to the workers: harness.sweep.engine); tasks of our own chain are returned unchanged."""
    try:
        fmus = {b: check_user_fmu(b, f) for b, f in command_fmus(specs, suite, suite_file).items()}
    except SystemError_ as e:
        raise SuiteError(str(e)) from None
    if not fmus:
        return tasks
    named = {b: {"file": f.name, "sha256": hashlib.sha256(f.read_bytes()).hexdigest(), "source": str(f)}
             for b, f in sorted(fmus.items())}
    return [t | {"fmus": {b: dict(d) for b, d in named.items()}} for t in tasks]


def make_task(machine_file: Path, path_file: Path, planner: str, seed: int = 0,
              preset: str = "none", variation: dict | None = None,
              planner_options: dict | None = None) -> dict:
    """One task dict (the task-function interface, see harness.sweep)."""
    try:
        seed = check_seed(seed)
    except SeedError as e:
        raise SuiteError(str(e)) from None
    return {
        "machine": machine_file.stem, "machine_file": repo_relative(machine_file),
        "path": path_file.stem, "path_file": repo_relative(path_file),
        "planner": planner, "planner_options": dict(planner_options or {}),
        "seed": int(seed), "preset": preset,
        "variation": {"name": "base", "set": {}} | dict(variation or {}),
        # contents travel with the task: a remote worker needs no benchmarks/ folder
        "files": {"machine.toml": machine_file.read_text(),
                  f"path{path_file.suffix}": path_file.read_text()},
    }


def _hash_files(files, root: Path | None = None) -> str:
    """Hash of (repo-relative name, content) pairs: equal across clones of the repository."""
    h = hashlib.sha256()
    rel = repo_relative if root is None else (lambda f: f.relative_to(root).as_posix())
    for name, f in sorted((rel(f), f) for f in files):
        h.update(name.encode() + b"\0")
        h.update(hashlib.sha256(f.read_bytes()).digest())
    return h.hexdigest()


def code_version(extra: list[Path] = ()) -> str:
    """Hash of the sources of kins/, planners/, harness/ and of the built FMUs."""
    files = [f for d in CODE_DIRS for f in (REPO / d).rglob("*.py") if "__pycache__" not in f.parts]
    files += list(FMU_DIR.glob("*.fmu")) if FMU_DIR.exists() else []
    files += [Path(e) for e in extra]
    return _hash_files([f for f in files if f.exists()])


def _module_file(name: str, root: Path) -> Path | None:
    parts = name.split(".")
    if parts[0] not in CODE_DIRS:
        return None
    base = root.joinpath(*parts)
    for f in (base / "__init__.py", base.with_suffix(".py")):
        if f.is_file():
            return f
    return None


def import_closure(modules, root: Path = REPO) -> list[Path]:
    """The files of kins/, planners/ and harness/ that importing ``modules`` can run: each one's
    import statements at any depth (a function's lazy import counts), followed transitively, and
    every parent package's __init__. By name through importlib (the planner registry) is not
    followed: the caller names such modules."""
    found: dict[str, Path | None] = {}
    todo = list(modules)
    while todo:
        parts = todo.pop().split(".")
        for i in range(1, len(parts) + 1):
            mod = ".".join(parts[:i])
            if mod in found:
                continue
            f = found[mod] = _module_file(mod, root)
            if f is None:
                continue
            package = mod if f.name == "__init__.py" else mod.rpartition(".")[0]
            for node in ast.walk(ast.parse(f.read_bytes(), str(f))):
                if isinstance(node, ast.Import):
                    todo += [a.name for a in node.names]
                elif isinstance(node, ast.ImportFrom):
                    if node.level:      # from .x (level 1: this package), from ..x (its parent) …
                        up = package.rsplit(".", node.level - 1)[0]
                        base = f"{up}.{node.module}" if node.module else up
                    else:
                        base = node.module
                    todo.append(base)
                    todo += [f"{base}.{a.name}" for a in node.names]   # when the name is a module
    return sorted(f for f in found.values() if f is not None)


def closure_version(modules, root: Path = REPO) -> str:
    """Hash of :func:`import_closure` of ``modules``: the code that running them depends on."""
    return _hash_files(import_closure(modules, root), root)


def task_key(task: dict, version: str, task_fn: str = "") -> str:
    """sha256 of everything that determines a task's result."""
    ident = {k: task[k] for k in ("planner", "planner_options", "seed", "preset", "variation", "files")}
    ident |= {"machine": task["machine"], "path": task["path"], "code": version, "task_fn": task_fn}
    if task.get("gcode_setup"):   # only then, likewise
        ident["gcode_setup"] = task["gcode_setup"]
    if task.get("max_feed"):      # likewise: the feed at the machine's F_max, not the programmed F
        ident["max_feed"] = True
    # not planner_timeout_s: only finished (ok) tasks are skipped, and their result is the same
    if task.get("fmus"):    # only then: the keys of tasks on our own chain stay as they were
        ident["fmus"] = {b: [d["file"], d["sha256"]] for b, d in task["fmus"].items()}
    plugin = plugin_version(task["planner"])
    if plugin:   # a plug-in's code is not in code_version: its installed version stands for it
        ident["plugin"] = plugin
    return hashlib.sha256(json.dumps(ident, sort_keys=True).encode()).hexdigest()


def task_label(task: dict) -> str:
    """Human name of a task, also the entry name in CI baselines."""
    return (f"{task['machine']}/{task['path']}/{task['planner']}/seed{task['seed']}/"
            f"{task['preset']}/{task['variation']['name']}" + ("/max_feed" if task.get("max_feed") else ""))
