"""Task functions for sweeps (the interface is in harness/sweep/__init__.py).

- ``default_task`` = ``cosim_task``: the harness's full co-simulation of one planner.
- ``plan_task``: planning only — ``planners.plan`` + ``planners.verify`` on the commanded
  trajectory (no FMUs): cheap, deterministic apart from ``planning_time_s``.
- ``line_task``: a quintic (minimum-jerk) move along a straight line, with no planner at
  all: its numbers have a closed form, so the sweep machinery can be tested while the
  planners are being written, and it can be made CPU-heavy (``repeat``) for the speed-up
  benchmark.
"""
from __future__ import annotations

import copy
import json
import math
import time
import tomllib
from pathlib import Path

import numpy as np

import planners
from harness.cosim.record import write_command_csv, write_json
from harness.cosim.run import run_case
from harness.sweep.suite import gcode_setup
from planners.paths import load_path
from planners.verify import chord_error_mm, command_metrics


class TaskError(ValueError):
    """A task's inputs are unusable; the message names the task's file and key."""


# -- machine of a task, with its variation applied ---------------------------------------
def machine_raw(task: dict) -> dict:
    """The machine file of the task as a dict, the variation's dotted keys overridden."""
    raw = tomllib.loads(task["files"]["machine.toml"])
    var = task["variation"]
    for dotted, value in sorted(var.get("set", {}).items()):
        node, parts = raw, dotted.split(".")
        for p in parts[:-1]:
            if not isinstance(node.get(p), dict):
                raise TaskError(f"variation '{var['name']}': {task['machine_file']} has no table "
                                f"'{p}' (in key '{dotted}')")
            node = node[p]
        if parts[-1] not in node:
            raise TaskError(f"variation '{var['name']}': {task['machine_file']} has no key '{dotted}'")
        node[parts[-1]] = copy.deepcopy(value)
    return raw


def task_machine(task: dict):
    from kins import machine_from_dict  # the loader's validation, on the varied dict
    src = task["machine_file"]
    if task["variation"].get("set"):
        src += f" (variation {task['variation']['name']})"
    return machine_from_dict(machine_raw(task), src)


def write_toml(d: dict, file: Path) -> None:
    """Minimal TOML writer (numbers, strings, booleans, lists, tables) for varied machine files."""
    def val(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, (int, float)):
            return repr(v)
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, list):
            return "[" + ", ".join(val(x) for x in v) + "]"
        raise TypeError(f"cannot write {type(v).__name__} to TOML")

    lines = []

    def table(node, prefix):
        scalars = {k: v for k, v in node.items() if not isinstance(v, dict)}
        if prefix and scalars:
            lines.append(f"[{prefix}]")
        for k, v in scalars.items():
            lines.append(f"{k} = {val(v)}")
        for k, v in node.items():
            if isinstance(v, dict):
                table(v, f"{prefix}.{k}" if prefix else k)
    table(d, "")
    file.write_text("\n".join(lines) + "\n")


def task_input_files(task: dict, folder: Path) -> tuple[Path, Path]:
    """Write the task's (varied) machine file and its path file into ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    mfile = folder / f"{task['machine']}.toml"
    if task["variation"].get("set"):
        write_toml(machine_raw(task), mfile)
    else:
        mfile.write_text(task["files"]["machine.toml"])
    (pname, ptext), = [(k, v) for k, v in task["files"].items() if k.startswith("path.")]
    pfile = folder / f"{task['path']}{Path(pname).suffix}"
    pfile.write_text(ptext)
    return mfile, pfile


def task_gcode_setup(task: dict, folder: Path):
    """The Setup (tool table, var file, offsets) of a task's G-code run, its files written into
    ``folder``; None when the task has none (harness.sweep.suite's gcode keys)."""
    g = task.get("gcode_setup")
    if not g:
        return None
    files = {}
    for key, name in (("tool_table", "tool.tbl"), ("var_file", "params.var")):
        if key in g:
            files[key] = folder / name
            files[key].write_text(g[key])
    return gcode_setup(files | {k: v for k, v in g.items() if k == "offset"})


def _write_command(file: Path, T: float, P: np.ndarray, Q: np.ndarray) -> None:
    write_command_csv(file, np.arange(len(P)) * T, P, Q)


def _write_summary(out_dir: Path, task: dict, machine, metrics: dict) -> None:
    write_json(out_dir / "summary.json", {"machine": task["machine"], "path": task["path"],
                                          "servo_period_s": machine.servo_period_s,
                                          "planners": {task["planner"]: metrics}})


# -- line_task -------------------------------------------------------------------------------
def line_task(task: dict, out_dir: Path) -> dict:
    """Quintic move s(τ) = L(10τ³ − 15τ⁴ + 6τ⁵) along a line path (a degree-1 NURBS of 2 points).

    Options: ``feed_mm_s`` (peak feed, default the machine's feed_max/2; duration
    D = 1.875 L / feed, the quintic's peak speed being 15/8 · L/D), ``repeat`` (compute the
    metrics this many times: CPU load for benchmarks, result unchanged), ``planning_repeat``
    (compute the profile this many times inside the timed planning: a slower planner).
    Planner name ``quintic``; any other name is an error (so a sweep can contain a failing task).
    """
    if task["planner"] != "quintic":
        raise TaskError(f"line_task knows only planner 'quintic', not '{task['planner']}'")
    machine = task_machine(task)
    ptext = task["files"].get("path.json")
    nurbs = json.loads(ptext) if ptext else {}
    cps = nurbs.get("control_points", [])
    if nurbs.get("degree") != 1 or len(cps) != 2:
        raise TaskError(f"{task['path_file']}: line_task needs a degree-1 NURBS with 2 control points")
    A, B = np.array(cps[0], float), np.array(cps[1], float)
    L = float(np.linalg.norm(B - A))
    opts = task["planner_options"]
    feed = float(opts.get("feed_mm_s", machine.limits.feed_max / 2))
    if not (math.isfinite(feed) and feed > 0):
        raise TaskError(f"planner_options.quintic.feed_mm_s = {feed} must be a number > 0")
    T = machine.servo_period_s
    t0 = time.perf_counter()
    for _ in range(int(opts.get("planning_repeat", 1))):      # a deliberately slower "planner"
        D = 15 / 8 * L / feed
        n = math.ceil(D / T)
        tau = np.minimum(np.arange(n + 1) * T / D, 1.0)
        s = L * tau**3 * (10 - 15 * tau + 6 * tau**2)
        P = A + np.outer(s / L, B - A)
    planning = time.perf_counter() - t0
    for _ in range(int(opts.get("repeat", 1))):
        metrics = command_metrics(machine, P, T, s)
    metrics["planning_time_s"] = planning
    metrics["max_chord_error_um"] = 0.0          # chords of a line lie on the line
    _write_command(out_dir / "command.csv", T, P, machine.ik(P))
    _write_summary(out_dir, task, machine, metrics)
    return metrics


# -- plan_task ---------------------------------------------------------------------------------
def plan_task(task: dict, out_dir: Path) -> dict:
    """Planning only: the planner's profile, interpolated at T, and its metrics (no FMUs)."""
    machine = task_machine(task)
    _, pfile = task_input_files(task, out_dir / "inputs")
    setup = task_gcode_setup(task, out_dir / "inputs")
    path = load_path(pfile, **({"setup": setup} if setup else {}))
    prof = planners.plan_in_time(task.get("planner_timeout_s"), task["planner"], path, machine,
                                 **planners.registry.seeded(task["planner"], task["planner_options"], int(task["seed"])))
    P = path.point(prof.s)
    metrics = command_metrics(machine, P, prof.T, prof.s)
    metrics["planning_time_s"] = float(prof.planning_time_s)
    metrics["max_chord_error_um"] = 1e3 * chord_error_mm(P, path, prof.s)
    _write_command(out_dir / "command.csv", prof.T, P, machine.ik(P))
    _write_summary(out_dir, task, machine, metrics)
    return metrics


def cosim_task(task: dict, out_dir: Path) -> dict:
    """The full co-simulation of one planner (harness.cosim.run.run_case): plan, FMU chain, metrics.

    The task's preset is the EtherCAT jitter preset ("none" = an ideal bus clock; "machine" or
    empty = the machine file's). Run files (summary.json, command.csv, the SSP system) land in
    out_dir; recordings (mcap, rrd) are skipped in sweeps to keep them light. The task's user
    FMUs (``fmu_paths``, the engine's local copies) take the place of our blocks.
    """

    planner = task["planner"]
    mfile, pfile = task_input_files(task, out_dir / "inputs")
    preset = task.get("preset") or "machine"
    summary = run_case(str(mfile), str(pfile), [planner], out_dir, seed=int(task.get("seed", 0)),
                       jitter=None if preset == "machine" else preset,
                       planner_options={planner: dict(task.get("planner_options") or {})},
                       recordings=False, max_feed=bool(task.get("max_feed", False)),
                       fmus=task.get("fmu_paths"), planner_timeout_s=task.get("planner_timeout_s"),
                       setup=task_gcode_setup(task, out_dir / "inputs"))
    m = summary["planners"][planner]
    if "error" in m:
        raise TaskError(m["error"])
    timing = json.loads((out_dir / "timing.json").read_text())
    m["planning_time_s"] = timing[planner]["planning_time_s"]
    return m


def default_task(task: dict, out_dir: Path) -> dict:
    """The full co-simulation (cosim_task)."""
    return cosim_task(task, out_dir)
