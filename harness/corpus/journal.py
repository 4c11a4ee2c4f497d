"""The rows of a corpus run, kept as each one ends: OUT/rows.jsonl, one JSON line per row with
the code version that made it. A run of hours (pso over 10 seeds on 44 paths) that is stopped
keeps what it finished; `pkmbench corpus --resume` plans only the rest, and reuses a kept row
only when the same code made it (harness.sweep.code_version: kins/, planners/, harness/, FMUs).

The tables and figures (corpus.csv, corpus.md, the PNGs) are written when every row is there;
a run removes an earlier run's at its start, so an interrupted run leaves no table that looks
complete.
"""
from __future__ import annotations

import json
import os
from dataclasses import asdict, fields
from pathlib import Path

from harness.corpus.run import Row

JOURNAL = "rows.jsonl"
TABLES = ("corpus.csv", "corpus.md", "performance_profile.png", "ratio_to_reference.png")
_FIELDS = {f.name for f in fields(Row)}


class Journal:
    """OUT/rows.jsonl of one corpus run. ``resume``: keep the rows made by ``code`` (``kept``:
    key → Row); else start afresh. Either way the earlier run's tables are removed."""

    def __init__(self, out: Path, code: str, resume: bool):
        self.file, self.code = Path(out) / JOURNAL, code
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
            if d.get("code") != self.code:
                self.other_code += 1
                continue
            self.kept[row.key] = row

    def _line(self, r: Row) -> str:
        return json.dumps({"code": self.code, "row": asdict(r)}) + "\n"

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
