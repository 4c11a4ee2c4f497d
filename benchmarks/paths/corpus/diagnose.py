"""Why a planner and the reference differ on a corpus path (docs/TUNING.md, twenty-first session).

    PYTHONPATH=. .venv/bin/python benchmarks/paths/corpus/diagnose.py phases pocket_keops [--read-phases 4]
    PYTHONPATH=. .venv/bin/python benchmarks/paths/corpus/diagnose.py where pocket_kossel [--levels 3]

``phases``: the planner's profile sampled at T with its start delayed by d (the pieces it was
sampled from, each evaluated at kT − d): the joint peaks a servo clock at another phase reads.
``where``: the reference's finest profile (reference.py, solved again, or a study's checkpoint's
finest finished grid: ``--checkpoint FILE``) against the planner's,
by t_ref(s) − t_planner(s): the time each loses within a distance of the G1 joins and NURBS
knots (where q″ jumps) and elsewhere, and the speeds at the joins.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent.parent.parent))
sys.path.insert(0, str(HERE))

import reference as ref  # noqa: E402
from kins import load_machine  # noqa: E402
from planners import plan  # noqa: E402
from planners.constraints import PathTable, join_jumps  # noqa: E402
from planners.paths import resolve_path  # noqa: E402
from planners.profile import Profile, Rest  # noqa: E402
from planners.verify import command_metrics  # noqa: E402


def corpus_entry(name):
    entries = {e["name"]: e for e in json.loads((HERE / "manifest.json").read_text())["paths"]}
    if name not in entries:
        raise SystemExit(f"diagnose.py: {name!r} is not a corpus path (benchmarks/paths/corpus/manifest.json)")
    return entries[name]


def corpus_path(name):
    e = corpus_entry(name)
    m = load_machine(e["machine"])
    return resolve_path(str(HERE / e["file"]), home=m.home), m


def plan_with_pieces(planner, path, machine, **options):
    """(profile, the pieces Profile.from_pieces sampled it from)."""
    made = []
    original = Profile.from_pieces.__func__

    def spy(cls, name, T, pieces, p, info=None):
        out = original(cls, name, T, pieces, p, info)
        made.append((list(pieces), out))
        return out

    Profile.from_pieces = classmethod(spy)
    try:
        prof = plan(planner, path, machine, **options)
    finally:
        Profile.from_pieces = classmethod(original)
    for pieces, out in reversed(made):
        if np.array_equal(out.s, prof.s):
            return prof, pieces
    raise SystemExit(f"diagnose.py: {planner}'s profile was not sampled by Profile.from_pieces")


def phases(args):
    path, m = corpus_path(args.path)
    opts = {"read_phases": args.read_phases} if args.read_phases else {}
    prof, pieces = plan_with_pieces(args.planner, path, m, **opts)
    print(f"{args.path} {args.planner} {opts}: {prof.execution_time_s:.6f} s, planned in {prof.planning_time_s:.1f} s")
    for d in args.delays:
        p = prof if d == 0 else Profile.from_pieces(prof.planner, prof.T, [Rest(d * prof.T), *pieces], path)
        r = command_metrics(m, p.points(), p.T, p.s)
        j = r["joint_peak_ratio"]
        print(f"  start {d:g} T late: joint v/a/j {j['velocity']:.6f} / {j['acceleration']:.6f} / {j['jerk']:.6f}"
              f"{'' if r['feasible'] else '  (above)'}")


def study_profile(args, path, m):
    """(the finest grid's profile, its time): solved again, or the finest grid a study under way
    has finished (``--checkpoint``: its state file; a CAM program's study takes hours)."""
    if args.checkpoint:
        state = ref.Checkpoint(args.checkpoint, ref.entry_key(corpus_entry(args.path))).state
        if state is None or not state["grids"]:
            raise SystemExit(f"diagnose.py: {args.checkpoint} holds no finished grid of {args.path}'s current study")
        return state["finest"], state["grids"][-1]["T_s"]
    finest = {}
    check = ref.check_at_T
    ref.check_at_T = lambda p, machine, prof: (finest.setdefault("prof", prof), check(p, machine, prof))[1]
    try:
        r = ref.reference(path, m, levels=args.levels)
    finally:
        ref.check_at_T = check
    return finest["prof"], r["grids"][-1]["T_s"]


def where(args):
    path, m = corpus_path(args.path)
    finest, T_finest = study_profile(args, path, m)
    s_ref = np.concatenate([q[0] for q in finest])
    v_ref = np.concatenate([q[1] for q in finest])
    t_ref, off = [], 0.0
    for s, v, a, j, dt in finest:
        t_ref.append(off + np.concatenate([[0.0], np.cumsum(dt)]))
        off = t_ref[-1][-1]
    t_ref = np.concatenate(t_ref)
    prof = plan(args.planner, path, m)
    grid = np.linspace(0.0, path.length, 200_001)
    gained = np.diff(np.interp(grid, s_ref, t_ref) - np.interp(grid, prof.s, prof.t))
    jumps = np.array([sj for sj, _ in join_jumps(path, PathTable(path, m), m)] + list(ref.interior_knots(path)))
    print(f"{args.path}: reference's finest grid {T_finest:.6f} s, {args.planner} "
          f"{prof.execution_time_s:.6f} s; {len(jumps)} G1 joins and knots")
    for w in args.within:
        near = np.zeros(len(grid) - 1, bool)
        for sj in jumps:
            near |= np.abs(grid[1:] - sj) < w
        print(f"  t_ref − t_{args.planner} within {w:g} mm of them: {gained[near].sum():+.5f} s, "
              f"elsewhere {gained[~near].sum():+.5f} s")
    if len(jumps):
        ratio = np.interp(jumps, s_ref, v_ref) / np.maximum(np.interp(jumps, prof.s, prof.sd), 1e-12)
        print(f"  speed there, reference / {args.planner}: median {np.median(ratio):.3f}, lowest {ratio.min():.3f}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    a = sub.add_parser("phases", help="the planner's joint peaks with its start delayed")
    a.add_argument("path")
    a.add_argument("--planner", default="optimal")
    a.add_argument("--read-phases", type=int, default=0, help="optimal's read_phases (0: its default)")
    a.add_argument("--delays", type=lambda x: [float(v) for v in x.split(",")], default=[0, 0.25, 0.5, 0.75],
                   help="delays in periods, comma-separated")
    a.set_defaults(run=phases)
    b = sub.add_parser("where", help="where the reference's time differs from the planner's")
    b.add_argument("path")
    b.add_argument("--planner", default="optimal")
    b.add_argument("--levels", type=int, default=ref.LEVELS)
    b.add_argument("--checkpoint", help="a study's checkpoint (reference.py): its finest finished grid, not solved again")
    b.add_argument("--within", type=lambda x: [float(v) for v in x.split(",")], default=[0.5, 2.0, 5.0],
                   help="distances in mm, comma-separated")
    b.set_defaults(run=where)
    args = ap.parse_args(argv)
    args.run(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
