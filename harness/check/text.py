"""The checker's text report: a summary per kind, then the findings worst first, consecutive
lines of one kind merged into a range."""
from __future__ import annotations

from harness.check.findings import Finding, Report, badness


TEXT_LIMIT = 50          # entries of the default text report (--all: every finding)

# what the default planners stand for (issue 21: check reports what LinuxCNC would do)
_PLANNER_NOTES = {"trapezoid": " (LinuxCNC 2.9's tp: the programmed F, its blends and stops; "
                               "--planner linuxcnc runs the real one)",
                  "linuxcnc": " (the real LinuxCNC 2.9, run headless)"}

def _first_line(f: Finding) -> int:
    return f.lines[0] if f.lines else 0

def _runs(findings: list[Finding]) -> list[list[Finding]]:
    """Findings of one kind and severity on consecutive lines, grouped (file order)."""
    runs: list[list[Finding]] = []
    last: dict[tuple, list[Finding]] = {}
    for f in sorted(findings, key=lambda f: (f.kind, f.severity, _first_line(f))):
        key = (f.kind, f.severity)
        run = last.get(key)
        if run is not None and f.lines and run[-1].lines and _first_line(f) - _first_line(run[-1]) == 1:
            run.append(f)
        else:
            run = [f]
            runs.append(run)
            last[key] = run
    return runs

def _entry(program: str, run: list[Finding]) -> str:
    worst = max(run, key=badness)
    if len(run) == 1:
        return f"{program}:{_first_line(worst)}: {worst.severity}: {worst.message}"
    return (f"{program}:{_first_line(run[0])}-{_first_line(run[-1])}: {worst.severity}: {len(run)} lines, "
            f"worst at line {_first_line(worst)}: {worst.message}")


def as_text(report: Report, limit: int | None = TEXT_LIMIT) -> str:
    """Summary per kind, then the findings worst first: consecutive lines of one kind merged
    into a range and at most ``limit`` entries (None: every finding, one per line)."""
    head = f"{report.program}: {report.machine}, planner {report.planner}" + _PLANNER_NOTES.get(report.planner, "")
    if report.invalid:
        return head + "\n" + "\n".join(f"  {report.program}:{f.lines[0] if f.lines else 0}: error: {f.message}"
                                       for f in report.findings if f.kind == "compile")
    if "nothing_to_check" in report.stats:
        return head + f"\n  nothing to check: {report.stats['nothing_to_check']}"
    messages = [f"  {report.program}:{f.lines[0]}: message: {f.message}" for f in report.findings if f.severity == "info"]
    if limit is not None and len(messages) > limit:
        messages = messages[:limit] + [f"  … {len(messages) - limit} more message(s): --all prints every one"]
    problems = [f for f in report.findings if f.severity != "info"]
    if not problems:
        return "\n".join([head] + messages + [f"  clean: {report.stats.get('moves', 0)} moves, "
                                               f"{report.stats.get('samples', 0)} samples checked"])
    n_lines = len({ln for f in problems for ln in f.lines})
    out = [head] + messages + [f"  {report.errors} error(s), {len(problems) - report.errors} warning(s) "
                               f"on {n_lines} line(s)"]
    for r in report.summary():
        if r["severity"] == "info":
            continue
        worst = ("" if r["worst_value"] is None or r["limit"] is None else
                 f", worst {abs(r['worst_value']):.6g} {r['unit']} against {r['limit']:g} {r['unit']}"
                 + (f" (ratio {r['worst_ratio']:.3f})" if r["worst_ratio"] is not None else ""))
        out.append(f"    {r['kind']:<22} {r['severity']:<7} {r['count']:>7} on {r['lines']} line(s)"
                   + worst + (f" at line {r['worst_line']}" if r["worst_line"] else ""))
    entries = _runs(problems) if limit is not None else [[f] for f in problems]
    entries.sort(key=lambda run: (tuple(-x for x in max(badness(f) for f in run)), _first_line(run[0]), run[0].kind))
    shown = entries if limit is None else entries[:limit]
    out.append("  worst first:" if limit is None or len(entries) <= limit else
               f"  worst first ({len(shown)} of {len(entries)} entries):")
    for run in shown:
        out.append("  " + _entry(report.program, run))
    if len(shown) < len(entries):
        rest = sum(len(r) for r in entries[len(shown):])
        out.append(f"  … {rest} more finding(s) in {len(entries) - len(shown)} more entries: "
                   "--all prints every one (--json too)")
    return "\n".join(out)
