"""Nightly performance CI: compare a sweep's metrics with a committed baseline.

Baseline file (``results/baseline.json``, written only by ``pkmbench ci --update-baseline``)::

    {"format": "pkmbench-ci-baseline/1", "suite": "...", "task_fn": "...", "code_version": "...",
     "reference_s": 0.05, "host": {...}, "created_utc": "...",
     "entries": {"keops/bird/scurve/seed0/none/base": {"execution_time_s": 1.23,
                 "joint_peak_ratio.jerk": 1.7, "feasible": false, "planning_time_ratio": 0.4, ...}}}

Entry names are ``machine/path/planner/seed<N>/preset/variation``; metrics are the run's
metrics flattened with dots. Wall-clock planning time is kept only as a ratio to a fixed
reference workload timed in the same run (``planning_time_ratio``), so a baseline made on
one computer holds on another.
"""
from __future__ import annotations

import fnmatch
import json
import math
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from xml.sax.saxutils import escape, quoteattr

import numpy as np

from harness.cosim.drive_params import encoder_increment_mm
from harness.provenance import host_info
from harness.sweep import flatten, resolve_task_fn, task_label
from kins import load_machine
from kins.machine import MachineFileError

FORMAT = "pkmbench-ci-baseline/1"

# (pattern, rule), first match wins. rel/abs: |value − baseline| ≤ max(rel·|baseline|, abs);
# increments: N encoder increments of the entry's machine. This is the cross-machine contract of
# docs/REPRODUCIBILITY.md: each rule is ≥ 10× the spread measured between numpy's SIMD code
# paths (benchmarks/repro/cross_cpu.py), but for the drive-quantised errors, which move by up to
# one increment however small the change upstream. Planning time is a ratio to the reference
# workload, one-sided and generous because CI machines are noisy.
DEFAULT_TOLERANCES: list[tuple[str, dict]] = [
    ("planning_time_s", {"ignore": True}),                      # wall time: only its ratio counts
    ("reference_s", {"ignore": True}),
    ("planning_time_ratio", {"max_factor": 1.5, "min_excess": 0.1}),
    ("execution_time_s", {"rel": 0.005}),
    ("feasible", {"exact": True}),
    # optimal's (and pso_socp's, polished by the same SOCP) Cartesian peaks are not limits they
    # keep, and the solver-based profiles (Clarabel, IPOPT) moved them by 8.7e-5 relative under
    # other numpy SIMD (kossel repro_part; tests/test_reproducibility.py): ±0.1 % there
    ("*/optimal*:cartesian_peak_ratio.*", {"abs": 1e-6, "rel": 1e-3}),
    ("*/pso*:cartesian_peak_ratio.*", {"abs": 1e-6, "rel": 1e-3}),
    # … and for the same reason the time their samples spend above a Cartesian limit: a sample
    # near one flips (on repro_part, stations 0.05 mm apart: 1.018 → 0.920 s of Cartesian jerk,
    # −9.6 %)
    ("*/optimal*:cartesian_violation_time_s.*", {"abs": 1e-6, "rel": 0.2}),
    # optimal's joint peaks that do not bind sit on a flat optimum: Clarabel's fine solve (0.05 mm
    # stations) ends 5.6e-6 apart in Σa under other SIMD, a repair round then reads 3 jerk windows
    # above the limit instead of 2, and the joint acceleration peak of kossel moves by 1.9e-4
    # (repro_part 0.88492 → 0.88512; bird_kossel 1.75e-4) at the same time. ~10× that; a binding
    # peak moved by 7.6e-7 (keops/bird's joint jerk, 0.99999) and `feasible` is compared exactly
    ("*/optimal*:joint_peak_ratio.*", {"abs": 2e-3}),
    # pso's swarm compares times whose last bits move with the SIMD path, so under other SIMD it
    # can take another path: the swarm alone (pso, issue 32) on repro_part 4.187 → 4.199 s
    # (+0.29 %), its joint acceleration peak 0.7493 → 0.7460 (−0.44 %); the hybrid (pso_socp)
    # had 3.3e-6 and 6.7 % of Cartesian jerk violation time (docs/REPRODUCIBILITY.md)
    ("*/pso*:joint_peak_ratio.*", {"abs": 5e-3}),
    ("*/pso*:cartesian_violation_time_s.*", {"abs": 1e-6, "rel": 0.7}),
    ("*peak_ratio.*", {"abs": 1e-6}),
    ("*violation_time_s.*", {"abs": 1e-6}),
    ("max_chord_error_um", {"rel": 0.005, "abs": 1e-3}),          # geometry: no quantisation
    ("*_error_um", {"rel": 0.005, "abs": 1e-3, "increments": 1}),
    ("*", {"rel": 0.005, "abs": 1e-9}),
]


# Figure and command CSVs across machines: each cell within CSV_REL × the largest value of its
# quantity (harness.report.compare.csv_difference); 38× the largest spread measured (2.6e-7, a
# joint jerk at T = 250 µs, docs/REPRODUCIBILITY.md).
CSV_REL = 1e-5


class BaselineError(ValueError):
    """A baseline file that is missing or not a pkmbench baseline."""


def load_baseline(file: Path) -> dict:
    """The baseline document of ``file``; BaselineError naming the file and what is wrong."""
    if not file.exists():
        raise BaselineError(f"{file}: no baseline; create it with --update-baseline")
    try:
        b = json.loads(file.read_text())
    except json.JSONDecodeError as e:
        raise BaselineError(f"{file}: not valid JSON (line {e.lineno}): {e.msg}") from None
    except (OSError, UnicodeDecodeError) as e:
        raise BaselineError(f"{file}: cannot read it: {e}") from None
    if not isinstance(b, dict) or b.get("format") != FORMAT or not isinstance(b.get("entries"), dict):
        raise BaselineError(f"{file}: not a pkmbench baseline (format must be '{FORMAT}' with 'entries')")
    bad = next((k for k, v in b["entries"].items() if not isinstance(v, dict)), None)
    if bad is not None:
        raise BaselineError(f"{file}: entries.{bad} must be an object of metrics")
    return b


def write_baseline(file: Path, *, suite: str, task_fn: str, code_version: str, reference_s: float,
                   entries: dict) -> dict:
    """Write the baseline document of a run to ``file``; the document."""
    doc = {"format": FORMAT, "suite": suite, "task_fn": task_fn,
           "code_version": code_version, "reference_s": reference_s, "host": host_info(),
           "created_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
           "entries": entries}
    file.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
    return doc


def rule_for(metric: str, tolerances=DEFAULT_TOLERANCES, entry: str = "") -> dict:
    """The first rule whose pattern matches: ``metric-glob`` or ``entry-glob:metric-glob``."""
    for pattern, rule in tolerances:
        ep, sep, mp = pattern.rpartition(":")
        if fnmatch.fnmatchcase(metric, mp) and (not sep or fnmatch.fnmatchcase(entry, ep)):
            return rule
    return {"exact": True}


def resolve_rule(rule: dict, entry: str) -> dict:
    """``increments: N`` → an absolute tolerance of N encoder increments (in µm) of the entry's
    machine (the first part of the label): a quantised position read moves by a whole
    increment when its input crosses a step, however small the input's change."""
    if "increments" not in rule:
        return rule
    try:
        inc_mm = encoder_increment_mm(entry.split("/", 1)[0])
    except (MachineFileError, OSError, KeyError, ValueError):
        inc_mm = None
    out = {k: v for k, v in rule.items() if k != "increments"}
    if inc_mm:
        out["abs"] = max(out.get("abs", 0.0), rule["increments"] * inc_mm * 1e3)
    return out


def describe(rule: dict) -> str:
    if rule.get("ignore"):
        return "not compared"
    if rule.get("exact"):
        return "exact"
    if "max_factor" in rule:
        return (f"fail if > {rule['max_factor']:g}× baseline and > baseline + "
                f"{rule.get('min_excess', 0):g} (ratio to the reference workload; faster is fine)")
    parts = []
    if rule.get("rel"):
        parts.append(f"±{100 * rule['rel']:g} %")
    if rule.get("abs"):
        parts.append(f"±{rule['abs']:g}")
    if rule.get("increments"):
        parts.append(f"±{rule['increments']:g} encoder increment(s) of the machine")
    return " or ".join(parts) or "exact"


# -- the reference workload ----------------------------------------------------------------
def reference_workload_s(repeat: int = 5, stat: str = "min") -> float:
    """Best-of-``repeat`` (``stat="min"``) or mean (``"mean"``) wall time of a fixed numpy computation (≈ 50 ms on a 2020 laptop core).

    Planning times are divided by it: a computer twice as fast halves both, so the ratio
    holds across machines. The work resembles planning: vectorised kinematics and
    differences over a long trajectory, plus a dense solve.
    """
    m = load_machine("keops")
    rng = np.random.default_rng(12345)
    P = m.home + rng.uniform(-50, 50, (400_000, 3))
    A = rng.standard_normal((200, 200)) + 200 * np.eye(200)
    b = rng.standard_normal(200)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        Q = m.ik(P)
        np.diff(Q, 3, axis=0)
        np.linalg.solve(A, b)
        times.append(time.perf_counter() - t0)
    return min(times) if stat == "min" else sum(times) / len(times)


# -- the CI task wrapper (runs on the workers) ---------------------------------------------
CI_REPEAT = 3
# without timing the runs only have to agree: two show a planner that is not deterministic
CI_REPEAT_NO_TIMING = 2


def _strip_times(flat: dict) -> dict:
    return {k: v for k, v in flat.items()
            if k not in ("planning_time_s", "reference_s", "planning_time_ratio")}


def reference_timed_task(task: dict, out_dir) -> dict:
    """The task function ``task["ci_inner_task"]`` run ``task["ci_repeat"]`` (CI_REPEAT) times
    on this worker, interleaved with the reference workload: ref, run, ref, run, ref, run, ref.

    Each run's planning time is divided by the mean of the reference timings just before
    and after it (a mean, not a best-of: a busy machine slows a long planning run on
    average, and the reference must see the same average), and ``planning_time_ratio`` is
    the median over the runs — the first call in a fresh worker, which pays for lazy
    imports, and a burst of load from other processes both fall out. The other metrics
    must agree exactly between the runs: a planner that is not deterministic fails here,
    by name.
    """
    import shutil
    import statistics
    from pathlib import Path

    inner = resolve_task_fn(task["ci_inner_task"])
    refs, runs = [reference_workload_s(3, "mean")], []
    repeat = int(task.get("ci_repeat", CI_REPEAT))
    for i in range(repeat):
        last = i == repeat - 1
        folder = Path(out_dir) if last else Path(out_dir) / f".repeat{i}"
        folder.mkdir(parents=True, exist_ok=True)
        runs.append(inner(task, folder))
        refs.append(reference_workload_s(3, "mean"))
        if not last:
            shutil.rmtree(folder, ignore_errors=True)
    first, final = _strip_times(flatten(runs[0])), _strip_times(flatten(runs[-1]))
    differ = sorted(k for k in set(first) | set(final) if first.get(k) != final.get(k))
    if differ:
        raise RuntimeError(f"not deterministic: {', '.join(differ[:5])} differ between two runs "
                           f"of the same task ({first.get(differ[0])} vs {final.get(differ[0])})")
    metrics = runs[-1]
    metrics["reference_s"] = statistics.fmean(refs)
    if "planning_time_s" in metrics:
        times = [r["planning_time_s"] for r in runs]
        metrics["planning_time_s"] = statistics.median(times)
        metrics["planning_time_ratio"] = statistics.median(
            t / (0.5 * (refs[i] + refs[i + 1])) for i, t in enumerate(times))
    return metrics


# -- comparison -------------------------------------------------------------------------------
@dataclass
class Check:
    entry: str
    metric: str
    baseline: object
    value: object
    tolerance: str
    ok: bool
    message: str = ""


def entries_from_rows(rows: list[dict], reference_s: float) -> tuple[dict, dict]:
    """(entries {label: flat metrics}, errors {label: error}) from a sweep's store rows."""
    entries, errors = {}, {}
    for row in rows:
        label = task_label(row["task"])
        if row["status"] != "ok":
            errors[label] = row["error"]
            continue
        flat = flatten(row["metrics"])
        if "planning_time_s" in flat and "planning_time_ratio" not in flat:
            # (reference_timed_task computes it on the worker; this is for other task functions)
            flat["planning_time_ratio"] = flat["planning_time_s"] / reference_s
        entries[label] = flat
    return entries, errors


def compare_value(metric: str, base, value, rule: dict) -> tuple[bool, str]:
    if isinstance(base, bool) or isinstance(value, bool) or rule.get("exact"):
        return base == value, "" if base == value else f"{metric} changed: {base} → {value}"
    if not isinstance(base, (int, float)) or not isinstance(value, (int, float)):
        return base == value, "" if base == value else f"{metric} changed: {base!r} → {value!r}"
    if "max_factor" in rule:
        limit = max(rule["max_factor"] * base, base + rule.get("min_excess", 0.0))
        ok = value <= limit
        return ok, "" if ok else (f"{metric} slower: {value:.4g} vs baseline {base:.4g} "
                                  f"(×{value / base if base else math.inf:.2f}; limit {limit:.4g})")
    allowed = max(rule.get("rel", 0.0) * abs(base), rule.get("abs", 0.0))
    diff = value - base
    ok = abs(diff) <= allowed
    if ok:
        return True, ""
    rel = f" ({100 * diff / base:+.3g} %)" if base else ""
    return False, f"{metric} {'increased' if diff > 0 else 'decreased'}: {base:.10g} → {value:.10g}{rel}, allowed ±{allowed:.3g}"


def compare(baseline: dict, entries: dict, errors: dict, tolerances=DEFAULT_TOLERANCES) -> list[Check]:
    checks = []
    base_entries = baseline["entries"]
    for label in sorted(set(base_entries) | set(entries) | set(errors)):
        if label in errors:
            checks.append(Check(label, "task", "ok", "error", "must run", False,
                                f"task failed: {errors[label]}"))
            continue
        if label not in base_entries:
            checks.append(Check(label, "entry", None, "new", "in baseline", False,
                                "not in the baseline (suite changed?): accept with --update-baseline"))
            continue
        if label not in entries:
            checks.append(Check(label, "entry", "present", None, "in run", False,
                                "in the baseline but not run (suite changed?)"))
            continue
        b, v = base_entries[label], entries[label]
        for metric in sorted(set(b) | set(v)):
            rule = rule_for(metric, tolerances, label)
            if rule.get("ignore"):
                continue
            tol = describe(rule)
            if metric not in v:
                checks.append(Check(label, metric, b[metric], None, tol, False, f"{metric} missing from the run"))
            elif metric not in b:
                checks.append(Check(label, metric, None, v[metric], tol, False, f"{metric} not in the baseline"))
            else:
                ok, msg = compare_value(metric, b[metric], v[metric], resolve_rule(rule, label))
                checks.append(Check(label, metric, b[metric], v[metric], tol, ok, msg))
    return checks


def tolerances_from_suite(suite: dict) -> list[tuple[str, dict]]:
    """``[ci.tolerances]`` of a suite go first: ``"PATTERN" = {rel, abs, exact, max_factor,
    min_excess, ignore}``, PATTERN a metric glob or ``entry-glob:metric-glob``."""
    extra = suite.get("ci", {}).get("tolerances", {})
    return [(k, dict(v)) for k, v in extra.items()] + DEFAULT_TOLERANCES


def without_timing(tolerances: list[tuple[str, dict]]) -> list[tuple[str, dict]]:
    """The same rules with planning time not compared: for checking that a baseline's numbers
    reproduce on a machine whose speed is not the nightly runner's (``make test``)."""
    return [("planning_time_ratio", {"ignore": True})] + tolerances


# -- outputs ---------------------------------------------------------------------------------
def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    return "—" if v is None else str(v)


def junit_xml(checks: list[Check], time_s: float, suite_name: str = "pkmbench ci") -> str:
    fails = sum(not c.ok for c in checks)
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           f'<testsuites name={quoteattr(suite_name)} tests="{len(checks)}" failures="{fails}" time="{time_s:.3f}">',
           f'  <testsuite name={quoteattr(suite_name)} tests="{len(checks)}" failures="{fails}" errors="0" time="{time_s:.3f}">']
    for c in checks:
        head = f'    <testcase classname={quoteattr(c.entry)} name={quoteattr(c.metric)}'
        if c.ok:
            out.append(head + "/>")
        else:
            detail = f"baseline: {_fmt(c.baseline)}\nvalue: {_fmt(c.value)}\ntolerance: {c.tolerance}"
            out += [head + ">", f"      <failure message={quoteattr(c.message)}>{escape(detail)}</failure>",
                    "    </testcase>"]
    out += ["  </testsuite>", "</testsuites>", ""]
    return "\n".join(out)


def markdown_summary(checks: list[Check], *, reference_s: float, baseline_file: str,
                     suite_file: str, wall_s: float, tolerances=DEFAULT_TOLERANCES) -> str:
    fails = [c for c in checks if not c.ok]
    entries = sorted({c.entry for c in checks})
    lines = [f"# pkmbench ci — {'FAIL' if fails else 'PASS'}", "",
             f"Suite `{suite_file}` against `{baseline_file}`: {len(entries)} runs, {len(checks)} "
             f"checks, **{len(fails)} regression{'s' if len(fails) != 1 else ''}**; wall time "
             f"{wall_s:.1f} s; reference workload {1e3 * reference_s:.2f} ms.", ""]
    if fails:
        lines += ["## Regressions", "", "| run | metric | baseline | now | tolerance | what |",
                  "|---|---|---|---|---|---|"]
        lines += [f"| {c.entry} | `{c.metric}` | {_fmt(c.baseline)} | {_fmt(c.value)} | {c.tolerance} | {c.message} |"
                  for c in fails]
        lines.append("")
    lines += ["## Tolerances", ""]
    for pattern, rule in tolerances:
        lines.append(f"- `{pattern}`: {describe(rule)}")
    lines += ["", "## Every run", "", "| run | execution_time_s | feasible | worst joint ratio | planning_time_ratio | status |",
              "|---|---|---|---|---|---|"]
    by_entry: dict[str, dict] = {}
    for c in checks:
        by_entry.setdefault(c.entry, {})[c.metric] = c
    for e in entries:
        cs = by_entry[e]
        val = lambda m: _fmt(cs[m].value) if m in cs else "—"  # noqa: E731
        worst = [cs[m].value for m in cs if m.startswith("joint_peak_ratio.") and isinstance(cs[m].value, float)]
        status = "ok" if all(c.ok for c in cs.values()) else "REGRESSION"
        lines.append(f"| {e} | {val('execution_time_s')} | {val('feasible')} | "
                     f"{_fmt(max(worst)) if worst else '—'} | {val('planning_time_ratio')} | {status} |")
    return "\n".join(lines) + "\n"
