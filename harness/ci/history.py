"""The CI history store: every `pkmbench ci` run appends here (SQLite, like the sweep table).

Tables: ``runs`` (one row per ci run) and ``metrics`` (one row per run × entry × metric, the
value and the baseline it was compared with). `pkmbench history` reads it.
"""
from __future__ import annotations

import json
import sqlite3
import subprocess
from datetime import datetime, timezone
from pathlib import Path

SCHEMA = """
CREATE TABLE IF NOT EXISTS runs (
    id            INTEGER PRIMARY KEY AUTOINCREMENT,
    utc           TEXT NOT NULL,
    git_commit    TEXT,
    code_version  TEXT,
    suite         TEXT,
    mode          TEXT,       -- 'check' | 'update-baseline'
    passed        INTEGER,    -- 1 / 0
    regressions   INTEGER,
    reference_s   REAL,
    wall_s        REAL,
    host          TEXT        -- JSON
);
CREATE TABLE IF NOT EXISTS metrics (
    run_id    INTEGER NOT NULL REFERENCES runs(id),
    entry     TEXT NOT NULL,
    metric    TEXT NOT NULL,
    value     REAL,           -- booleans as 0/1
    baseline  REAL,
    ok        INTEGER
);
CREATE INDEX IF NOT EXISTS metrics_by_name ON metrics(metric, entry);
"""


def git_commit(repo: Path) -> str | None:
    try:
        r = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=repo, capture_output=True,
                           text=True, timeout=10)
        return r.stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        return None


def _num(v):
    if isinstance(v, bool):
        return float(v)
    return float(v) if isinstance(v, (int, float)) else None


class History:
    def __init__(self, file: str | Path):
        self.file = Path(file)
        self.file.parent.mkdir(parents=True, exist_ok=True)
        self.db = sqlite3.connect(self.file)
        self.db.executescript(SCHEMA)

    def close(self):
        self.db.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def append(self, *, entries: dict, checks: list, baseline_entries: dict, mode: str,
               passed: bool, reference_s: float, wall_s: float, suite: str, code_version: str,
               host: dict, repo: Path) -> int:
        ok_of = {(c.entry, c.metric): c.ok for c in checks}
        with self.db:
            cur = self.db.execute(
                "INSERT INTO runs (utc, git_commit, code_version, suite, mode, passed, regressions,"
                " reference_s, wall_s, host) VALUES (?,?,?,?,?,?,?,?,?,?)",
                (datetime.now(timezone.utc).isoformat(timespec="seconds"), git_commit(repo),
                 code_version, suite, mode, int(passed), sum(not c.ok for c in checks),
                 reference_s, wall_s, json.dumps(host, sort_keys=True)))
            run_id = cur.lastrowid
            rows = []
            for entry, flat in sorted(entries.items()):
                base = baseline_entries.get(entry, {})
                for metric, value in sorted(flat.items()):
                    rows.append((run_id, entry, metric, _num(value), _num(base.get(metric)),
                                 int(ok_of.get((entry, metric), True))))
            self.db.executemany("INSERT INTO metrics VALUES (?,?,?,?,?,?)", rows)
        return run_id

    def runs(self) -> list[dict]:
        cur = self.db.execute("SELECT * FROM runs ORDER BY id")
        cols = [d[0] for d in cur.description]
        return [dict(zip(cols, r)) for r in cur]

    def series(self, metric: str) -> dict[str, list[tuple[int, float]]]:
        """{entry: [(run id, value), …]} of one metric."""
        out: dict[str, list] = {}
        for run_id, entry, value in self.db.execute(
                "SELECT run_id, entry, value FROM metrics WHERE metric = ? ORDER BY run_id", (metric,)):
            out.setdefault(entry, []).append((run_id, value))
        return out

    def metric_names(self) -> list[str]:
        return [m for (m,) in self.db.execute("SELECT DISTINCT metric FROM metrics ORDER BY metric")]
