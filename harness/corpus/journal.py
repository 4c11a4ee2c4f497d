"""The rows of a corpus run, kept as each one ends: OUT/rows.jsonl, one JSON line per row with
the code that made it. A run of hours (pso over 10 seeds on 44 paths) that is stopped keeps
what it finished; `pkmbench corpus --resume` plans only the rest, and reuses a kept row only
when its planner's code is the same (:func:`planner_code`).

A row's code is what its plan and its check import (harness.sweep.suite.import_closure), not
all of kins/, planners/ and harness/ with the FMUs: the corpus runs no FMU, and a change to
`optimal` alone must not throw away CPU-hours of `pso_socp` rows.

The tables and figures (corpus.csv, corpus.md, the PNGs) are written when every row is there;
a run removes an earlier run's at its start, so an interrupted run leaves no table that looks
complete.
"""
from __future__ import annotations

import functools
import json
import os
from dataclasses import asdict, fields
from pathlib import Path

from harness.corpus.run import Row
from harness.sweep.suite import closure_version, code_version
from planners import registry

JOURNAL = "rows.jsonl"
TABLES = ("corpus.csv", "corpus.md", "performance_profile.png", "ratio_to_reference.png")
_FIELDS = {f.name for f in fields(Row)}
ROW_MODULES = ("harness.corpus.run",)    # plans a row and checks it at T


@functools.cache
def planner_code(name: str) -> str:
    """Hash of the code a corpus row of planner ``name`` runs: the import closure of its module
    (planners.registry.BUILTIN) and of the row's check. A plug-in or ``module:function`` planner
    lives outside the repository: all of its code (code_version) and its installed version."""
    if name in registry.BUILTIN:
        return closure_version([registry.BUILTIN[name][0], *ROW_MODULES])
    return f"{code_version()}+{name}@{registry.plugin_version(name) or ''}"


class Journal:
    """OUT/rows.jsonl of one corpus run. ``resume``: keep the rows whose planner's ``code``
    (name → hash; default :func:`planner_code`) made them (``kept``: key → Row); else start
    afresh. Either way the earlier run's tables are removed."""

    def __init__(self, out: Path, resume: bool, code=None):
        self.file, self.code = Path(out) / JOURNAL, code or planner_code
        self.kept: dict[tuple, Row] = {}
        self.other_code = self.unreadable = 0
        for name in TABLES:
            (Path(out) / name).unlink(missing_ok=True)
        if resume and self.file.exists():
            self._read()
        # what is kept is written again, so the file holds this code's rows only
        with open(self.file, "w") as f:
            for r in self.kept.values():
                f.write(self._line(r))

    def _read(self) -> None:
        for line in self.file.read_text(errors="replace").splitlines():
            try:
                d = json.loads(line)
                row = Row(**{k: v for k, v in d["row"].items() if k in _FIELDS})
            except (ValueError, KeyError, TypeError):
                self.unreadable += 1        # a line cut by the interruption, or not ours
                continue
            if d.get("code") != self.code(row.planner):
                self.other_code += 1
                continue
            self.kept[row.key] = row

    def _line(self, r: Row) -> str:
        return json.dumps({"code": self.code(r.planner), "row": asdict(r)}) + "\n"

    def add(self, r: Row) -> None:
        """Append a finished row (flushed to disk: a killed run keeps it)."""
        with open(self.file, "a") as f:
            f.write(self._line(r))
            f.flush()
            os.fsync(f.fileno())

    def summary(self) -> str:
        s = f"{len(self.kept)} rows kept from {self.file}"
        if self.other_code:
            s += f"; {self.other_code} made by other code planned again"
        if self.unreadable:
            s += f"; {self.unreadable} unreadable lines skipped"
        return s
