"""One run: a machine × a toolpath × planners, each profile through the full FMU chain.

    from harness.cosim.run import run_case
    summary = run_case("keops", "bird", ["scurve", "pso"], "results/keops_bird")

Per planner: plan (offline) → ``NAME/path.json`` + ``NAME/profile.csv`` → the system as SSP
(``NAME/SystemStructure.ssd``) → co-simulation of what that file describes → metrics →
``NAME/command.csv``, ``NAME/run.mcap``, ``NAME/run.rrd``. Then ``summary.json`` (metrics;
deterministic: same inputs and seed ⇒ same bytes) and ``timing.json`` (wall times).
A planner or co-simulation that fails is recorded with its reason; the others go on.
The folder is locked for the run (a second run into it is refused); the summary of an
earlier run, and its planner folders this run does not redo, are removed first.
"""
from __future__ import annotations

import math
import shutil
import time
from pathlib import Path

import numpy as np

import planners
from harness.cosim.blocks import check_blocks, check_user_fmu
from harness.cosim.master import CoSimError, simulate
from harness.cosim.measure import measure
from harness.cosim.record import replacing, write_command_csv, write_json, write_mcap, write_rrd
from harness.cosim.system import SystemError_, chain, check_chain_fmus, read_ssp, write_ssp
from harness.outdir import OutDirError, output_dir, run_lock
from harness.seed import SeedError, check_seed
from kins import load_machine
from kins.machine import MachineFileError
from planners.feed import feed_mode, use_max_feed
from planners.paths import PathError, resolve_path
from planners.verify import differences

# Interpolator output → command; Kinematics → joints; EtherCAT → delivered targets; drives
RECORD = (["interpolator.x", "interpolator.y", "interpolator.z", "interpolator.s", "interpolator.feed",
           "interpolator.done", "kinematics.q1_cmd", "kinematics.q2_cmd", "kinematics.q3_cmd",
           "kinematics.workspace_ok", "ethercat.lateness", "ethercat.lost_frames"]
          + [f"ethercat.q{k}_target" for k in (1, 2, 3)]
          + [f"drive{k}.{v}" for k in (1, 2, 3) for v in ("position", "velocity", "current", "following_error", "fault")])

# every file a run writes into a planner folder (stale_planner_dirs removes only such folders);
# SystemStructure.ssv: written by earlier versions, so their folders are recognised too
PLANNER_FILES = {"path.json", "profile.csv", "SystemStructure.ssd", "SystemStructure.ssv", "lateness.csv",
                 "command.csv", "run.mcap", "run.rrd"}
TAIL_S = 0.02   # co-simulate a little past the profile's end, so the drives settle


def planner_folder(name: str) -> str:
    """The folder of a planner's files in a run's output: its name with every character but
    letters, digits, '-', '_' and '.' made '_', never starting with '.', so that a
    ``module:function`` spec such as '../../x:plan' or '/abs/x:plan' stays inside the output
    folder (the built-in names are unchanged)."""
    safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in name)
    return safe if safe and not safe.startswith(".") else "_" + safe


class RunError(Exception):
    """A run cannot start (unknown machine/path/planner, a missing or corrupt FMU, an output
    folder that cannot be written or that another run holds)."""


def feed_summary(path) -> str:
    """How the feed was capped, for summary.json."""
    if path.program is None:
        return "F_max (not a G-code program)"
    return "F_max (--max-feed)" if feed_mode(path) == "max" else "programmed F, capped at F_max"


def cosimulate(machine, profile, out: Path, *, seed: int = 0, jitter: str | None = None, ideal: bool = False,
               engine: str = "native", jacobi: bool = False, fmus: dict | None = None):
    """Write the profile's files and system, run it, return the master's Result."""
    path_file, profile_file = out / "path.json", out / "profile.csv"
    profile.path.to_file(path_file)
    profile.save_csv(profile_file)
    system = chain(machine, path_file, profile_file, profile.execution_time_s + TAIL_S,
                   seed=seed, jitter=jitter, ideal=ideal, histogram_out=str(out / "lateness.csv"), fmus=fmus)
    # round the duration to whole periods so every step is exactly T
    n = int(math.ceil(system.stop_time / system.step_size - 1e-9))
    system.stop_time = n * system.step_size
    ssd = write_ssp(system, out)
    return simulate(read_ssp(ssd), RECORD, engine=engine, jacobi=jacobi)


def run_case(machine_name: str, path_name: str, planner_names: list[str], out_dir, *, seed: int = 0,
             jitter: str | None = None, ideal: bool = False, engine: str = "native", jacobi: bool = False,
             planner_options: dict | None = None, recordings: bool = True, progress=None,
             max_feed: bool = False, fmus: dict | None = None, start=None, reader: str = "pkmbench",
             planner_timeout_s: float | None = None, setup=None) -> dict:
    """``max_feed``: run a G-code program at F_max instead of its programmed F (planner-only
    comparisons); summary.json's ``feed`` says which. ``fmus``: {block: user .fmu} in place of
    ours (harness.cosim.blocks), checked before anything runs; summary.json's ``fmus`` names them.
    ``start``: G-code only, the machine position before the program (default: its first positioning
    move, else the machine's home; planners.paths.gcode.parse_gcode); ``reader``: G-code read by
    pkmbench's interpreter or LinuxCNC's (summary.json names it when it is not pkmbench's).
    ``planner_timeout_s``: each planner's time limit (planners.plan_in_time; None: none); a planner
    over it is that planner's error, the others run. ``setup``: G-code only, the tool table, var
    file and work offsets it starts with (planners.paths.gcode.rs274.setup.Setup; summary.json's
    ``gcode_setup`` names them)."""

    try:
        machine = load_machine(machine_name)
    except MachineFileError as e:
        raise RunError(str(e)) from None
    try:
        path = resolve_path(path_name, home=machine.home, start=start, reader=reader,
                            **({"setup": setup} if setup else {}))
    except PathError as e:
        raise RunError(str(e)) from None
    use_max_feed(path, bool(max_feed))
    unknown = [p for p in planner_names if not planners.registry.known(p)]
    if unknown:
        raise RunError(planners.registry.unknown_message(unknown))
    folders: dict[str, str] = {}
    for p in planner_names:
        other = folders.setdefault(planner_folder(p), p)
        if other != p:
            raise RunError(f"planners {other!r} and {p!r} would share the output folder {planner_folder(p)!r}; "
                           f"run them apart")
    try:
        seed = check_seed(seed)
        for name, opts in (planner_options or {}).items():
            if "seed" in opts:
                check_seed(opts["seed"], f"planner_options.{name}.seed")
    except SeedError as e:
        raise RunError(str(e)) from None
    try:
        check_chain_fmus()
        if fmus:
            check_blocks(fmus)
            fmus = {b: check_user_fmu(b, f) for b, f in fmus.items()}
    except SystemError_ as e:   # before anything is planned or removed: every planner would fail alike
        raise RunError(str(e)) from None
    out_dir = Path(out_dir)
    try:
        with run_lock(output_dir(out_dir)):
            return _run(machine, path, path_name, planner_names, out_dir, seed=seed, jitter=jitter, ideal=ideal,
                        engine=engine, jacobi=jacobi, planner_options=planner_options, recordings=recordings,
                        progress=progress, fmus=fmus, start=start, reader=reader,
                        planner_timeout_s=planner_timeout_s, setup=setup)
    except OutDirError as e:
        raise RunError(str(e)) from None


def _run(machine, path, path_name, planner_names, out_dir: Path, *, seed, jitter, ideal, engine, jacobi,
         planner_options, recordings, progress, fmus=None, start=None, reader="pkmbench",
         planner_timeout_s=None, setup=None) -> dict:
    """run_case's work, with the folder locked: nothing of an earlier run may look like this one's."""

    for stale in ("summary.json", "timing.json", "comparison.png"):
        (out_dir / stale).unlink(missing_ok=True)
    for d in stale_planner_dirs(out_dir, [planner_folder(n) for n in planner_names]):
        shutil.rmtree(d)

    summary = {"machine": machine.name, "path": path_name, "servo_period_s": machine.servo_period_s,
               "seed": seed, "jitter": jitter or "machine default", "ideal_chain": ideal,
               "feed": feed_summary(path), "planners": {}}
    if start is not None:      # only then, as fmus below
        summary["start_mm"] = [float(v) for v in start]
    if reader != "pkmbench":
        summary["gcode_reader"] = reader
    if setup:      # only then: the summaries of other runs keep their bytes
        summary["gcode_setup"] = [f"{kind}: {what}" for kind, what in setup.sources]
    if fmus:   # only then: the summaries of runs with our chain keep their bytes
        summary["fmus"] = {b: str(f) for b, f in sorted(fmus.items())}
    timing = {}
    for k, name in enumerate(planner_names):
        if progress:
            progress(k, len(planner_names), name)
        pdir = out_dir / planner_folder(name)
        shutil.rmtree(pdir, ignore_errors=True)
        pdir.mkdir(parents=True)
        try:
            profile = planners.plan_in_time(planner_timeout_s, name, path, machine,
                                            **planners.registry.seeded(name, (planner_options or {}).get(name), seed))
        except Exception as e:   # PlanningError and anything a planner raised: record, go on
            summary["planners"][name] = {"error": f"planning failed: {type(e).__name__}: {e}"}
            continue
        t1 = time.perf_counter()
        try:
            res = cosimulate(machine, profile, pdir, seed=seed, jitter=jitter, ideal=ideal, engine=engine,
                             jacobi=jacobi, fmus=fmus)
        except (CoSimError, SystemError_) as e:
            summary["planners"][name] = {"error": f"co-simulation failed: {e}",
                                         "execution_time_s": profile.execution_time_s}
            timing[name] = {"planning_time_s": profile.planning_time_s}
            continue
        t2 = time.perf_counter()
        m = measure(machine, profile, res)
        summary["planners"][name] = m
        timing[name] = {"planning_time_s": profile.planning_time_s, "cosimulation_wall_s": t2 - t1,
                        "simulated_s": float(res.t[-1]), "real_time_factor": float(res.t[-1]) / max(t2 - t1, 1e-9)}
        n = len(profile.s)
        P = np.column_stack([res[f"interpolator.{a}"] for a in "xyz"])[:n]
        Q = np.column_stack([res[f"kinematics.q{k}_cmd"] for k in (1, 2, 3)])[:n]
        write_command_csv(pdir / "command.csv", res.t[:n], P, Q)
        if recordings:
            _recordings(pdir, machine, res, P, Q)
        timing[name]["recording_wall_s"] = time.perf_counter() - t2
    write_json(out_dir / "timing.json", timing)
    comparison_plot(summary, out_dir / "comparison.png")
    write_json(out_dir / "summary.json", summary)   # last: its presence means the run finished
    return summary


def _is_run_file(f: Path) -> bool:
    if f.is_symlink():
        return False
    if f.is_dir():   # the SSP's copies of the chain's FMUs (system.write_ssp)
        return f.name == "resources" and all(g.is_file() and g.suffix == ".fmu" for g in f.iterdir())
    return f.name in PLANNER_FILES or f.name.endswith(".part")


def stale_planner_dirs(out_dir: Path, keep) -> list[Path]:
    """Planner folders of an earlier run in ``out_dir`` that are not among ``keep``: folders
    holding a planner's command or profile and nothing but files a run writes (a folder with
    anything else in it is the user's, and stays)."""
    out = []
    for d in sorted(out_dir.iterdir()):
        if d.name in keep or not d.is_dir() or d.is_symlink():
            continue
        files = list(d.iterdir())
        ours = all(_is_run_file(f) for f in files)
        if ours and any(f.name in ("command.csv", "profile.csv", "run.mcap") for f in files):
            out.append(d)
    return out


def comparison_plot(summary: dict, file: Path) -> None:
    """Execution time and worst joint-limit ratios per planner, side by side."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = {n: m for n, m in summary["planners"].items() if "error" not in m}
    if not ok:
        return
    names = list(ok)
    x = np.arange(len(names))
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 3.8))
    a1.bar(x, [ok[n]["execution_time_s"] for n in names], color="tab:blue")
    a1.set(xticks=x, xticklabels=names, ylabel="execution time (s)",
           title=f"{summary['machine']} / {summary['path']}")
    for k, order in enumerate(("velocity", "acceleration", "jerk")):
        a2.bar(x + (k - 1) * 0.27, [ok[n]["joint_peak_ratio"][order] for n in names], 0.27, label=order)
    a2.axhline(1.0, color="k", ls="--", lw=1, label="joint limit")
    a2.set(xticks=x, xticklabels=names, ylabel="peak |joint derivative| / limit", yscale="log",
           title="joint-limit ratios on the commanded trajectory (IK at T)")
    a2.legend(fontsize=8)
    for a in (a1, a2):
        a.tick_params(axis="x", rotation=30)
    fig.tight_layout()
    try:
        with replacing(file) as tmp:
            fig.savefig(tmp, dpi=110, format="png")
    finally:
        plt.close(fig)


def _recordings(pdir: Path, machine, res, P, Q) -> None:
    t = res.t
    ch = {
        "/command": {"t": t, "s": res["interpolator.s"], "feed": res["interpolator.feed"],
                     "x": res["interpolator.x"], "y": res["interpolator.y"], "z": res["interpolator.z"]},
        "/joints/command": {"t": t, **{f"q{k}": res[f"kinematics.q{k}_cmd"] for k in (1, 2, 3)}},
        "/joints/target": {"t": t, **{f"q{k}": res[f"ethercat.q{k}_target"] for k in (1, 2, 3)}},
        "/drives/actual": {"t": t, **{f"q{k}": res[f"drive{k}.position"] for k in (1, 2, 3)},
                           **{f"v{k}": res[f"drive{k}.velocity"] for k in (1, 2, 3)},
                           **{f"i{k}": res[f"drive{k}.current"] for k in (1, 2, 3)}},
        "/drives/following_error": {"t": t, **{f"e{k}": res[f"drive{k}.following_error"] for k in (1, 2, 3)}},
        "/bus": {"t": t, "lateness": res["ethercat.lateness"], "lost_frames": res["ethercat.lost_frames"]},
    }
    write_mcap(pdir / "run.mcap", ch)
    T = machine.servo_period_s
    d = differences(Q, T, rest=False)   # the sampled motion, plotted sample by sample
    lim = machine.limits.joint
    ratio = np.zeros(len(Q))
    for order, L in (("velocity", lim.v), ("acceleration", lim.a), ("jerk", lim.j)):
        r = np.abs(d[order]).max(axis=1) / L
        ratio[-len(r):] = np.maximum(ratio[-len(r):], r) if len(r) else ratio[-len(r):]
    write_rrd(pdir / "run.rrd", machine, t[: len(Q)], P, Q, ratio, d)
