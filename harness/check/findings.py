"""The checker's findings and its report (harness.check): what a finding is, the exit code,
the summary per kind and the JSON report. The text report is harness.check.text."""
from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field


EXIT_CLEAN, EXIT_FINDINGS, EXIT_INVALID = 0, 1, 2

@dataclass
class Finding:
    kind: str              # compile | unreachable | stroke | singularity | box | joint_velocity | message | …
    severity: str          # "error" | "warning" | "info" (a message of the program: (MSG,…), (DEBUG,…))
    lines: list[int]       # G-code line numbers (1-based file lines)
    value: float | None    # worst value (unit below)
    limit: float | None
    unit: str
    message: str

@dataclass
class Report:
    program: str
    machine: str
    planner: str
    findings: list[Finding] = field(default_factory=list)
    invalid: bool = False
    stats: dict = field(default_factory=dict)

    @property
    def exit_code(self) -> int:
        if self.invalid:
            return EXIT_INVALID
        return EXIT_FINDINGS if self.errors else EXIT_CLEAN

    @property
    def errors(self) -> int:
        return sum(f.severity == "error" for f in self.findings)

    def summary(self) -> list[dict]:
        """Per (kind, severity): count, lines, and the worst finding (value against limit)."""
        rows: dict[tuple, dict] = {}
        for f in self.findings:
            b = badness(f)           # once per finding (10⁵ of them on a long program)
            r = rows.setdefault((f.kind, f.severity), {"kind": f.kind, "severity": f.severity, "count": 0,
                                                       "lines": set(), "worst": f, "bad": b})
            r["count"] += 1
            r["lines"].update(f.lines)
            if b > r["bad"]:
                r["worst"], r["bad"] = f, b
        out = []
        for r in sorted(rows.values(), key=lambda r: (r["severity"] != "error", -badness(r["worst"])[0], r["kind"])):
            w = r["worst"]
            out.append({"kind": r["kind"], "severity": r["severity"], "count": r["count"],
                        "lines": len(r["lines"]), "worst_value": w.value, "limit": w.limit, "unit": w.unit,
                        "worst_ratio": ratio(w), "worst_line": w.lines[0] if w.lines else 0})
        return out

    def to_json(self) -> str:
        # every finding, and fields that cannot be misread: "valid" means no error at all
        d = {"program": self.program, "machine": self.machine, "planner": self.planner,
             "parsed": not self.invalid, "valid": self.exit_code == EXIT_CLEAN,
             "errors": self.errors, "warnings": sum(f.severity == "warning" for f in self.findings),
             "exit_code": self.exit_code, "stats": self.stats, "summary": self.summary(),
             "findings": [asdict(f) for f in self.findings]}
        return json.dumps(d, indent=2, sort_keys=True)

def badness(f: Finding) -> tuple[float, float]:
    """Ratio of the worst value to its limit (1 when the finding has no such ratio), then the
    value itself (a box excess in mm has a limit of 0: no ratio, but a larger one is worse)."""
    r = ratio(f)
    return (1.0 if r is None else r, 0.0 if f.value is None else abs(f.value))

def ratio(f: Finding) -> float | None:
    if f.value is None or not f.limit:
        return None
    return abs(f.value) / abs(f.limit)

class CheckError(Exception):
    """The checker itself cannot run (no such file, unknown machine or planner)."""
