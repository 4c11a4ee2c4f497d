"""The results table of a sweep: one SQLite file, one row per task.

Why SQLite rather than Parquet: rows arrive one at a time, in completion order, while the
sweep runs. SQLite commits each row atomically (a sweep killed half-way keeps everything
finished so far, which is exactly what the resume logic needs: "is this key done?" is a
primary-key lookup), it is in the standard library (readers need no pyarrow), and it is
queryable from the `sqlite3` shell (`json_extract(metrics, '$.execution_time_s')`).
Parquet files are immutable: appending per task would mean one file per task or a rewrite
of the whole table every time. `TaskTable.to_rows()` gives the flat table for export.
"""
from __future__ import annotations

import json
import math
import sqlite3
from pathlib import Path

SCHEMA = """
CREATE TABLE IF NOT EXISTS results (
    key           TEXT PRIMARY KEY,   -- sha256 of the task inputs and code/FMU versions
    machine       TEXT NOT NULL,
    path          TEXT NOT NULL,
    planner       TEXT NOT NULL,
    seed          INTEGER NOT NULL,   -- signed 64-bit: a seed >= 2**63 is stored as seed - 2**64
    preset        TEXT NOT NULL,
    variation     TEXT NOT NULL,      -- variation name
    task          TEXT NOT NULL,      -- the whole task, JSON
    status        TEXT NOT NULL,      -- 'ok' | 'error'
    error         TEXT,               -- 'Type: message' of a failed task
    traceback     TEXT,
    metrics       TEXT,               -- JSON of the metrics dict (DESIGN.md names)
    elapsed_s     REAL,               -- wall time of the task on its worker
    worker        TEXT,
    code_version  TEXT NOT NULL,
    run_dir       TEXT                -- this run's files, relative to the sweep folder
);
CREATE TABLE IF NOT EXISTS appended (   -- which rows reached which results store (harness.store)
    key           TEXT NOT NULL,      -- a row of results; deleted when the task runs again
    store         TEXT NOT NULL,      -- the results store folder
    run_id        TEXT NOT NULL,      -- the store's file RUN_ID.parquet that holds the row
    done          INTEGER NOT NULL,   -- 0 while that file is written, 1 once it is in the store
    PRIMARY KEY (key, store)
);
"""


class TaskTableError(ValueError):
    """A sweep folder's results.sqlite cannot be read (not a database, corrupt); names the file."""


def _finite_json(obj) -> str:
    """JSON with a clear error instead of NaN/Infinity sneaking into the table."""
    def check(x, where):
        if isinstance(x, float) and not math.isfinite(x):
            raise ValueError(f"metric {where} is {x}; a result may not hold NaN or Inf")
        if isinstance(x, dict):
            for k, v in x.items():
                check(v, f"{where}.{k}" if where else str(k))
        elif isinstance(x, (list, tuple)):
            for i, v in enumerate(x):
                check(v, f"{where}[{i}]")
    check(obj, "")
    return json.dumps(obj, sort_keys=True, allow_nan=False)


def _sql_int64(n: int) -> int:
    """SQLite integers are signed 64-bit; seeds go up to 2**64 - 1 (the task JSON keeps them exact)."""
    return n - 2**64 if n >= 2**63 else n


class TaskTable:
    def __init__(self, file: str | Path):
        self.file = Path(file)
        self.file.parent.mkdir(parents=True, exist_ok=True)
        self.db = sqlite3.connect(self.file)
        try:
            legacy = self.db.execute("SELECT count(*) FROM sqlite_master WHERE name = 'results'").fetchone()[0] \
                and not self.db.execute("SELECT count(*) FROM sqlite_master WHERE name = 'appended'").fetchone()[0]
            self.db.executescript(SCHEMA)
            self.db.execute("SELECT key, status FROM results LIMIT 1").fetchall()
            if legacy:   # a folder of an earlier version appended its rows at once: to some store ('*')
                with self.db:
                    self.db.execute("INSERT INTO appended SELECT key, '*', '', 1 FROM results")
        except sqlite3.DatabaseError as e:
            self.db.close()
            raise TaskTableError(f"{self.file}: not a sweep's results table ({e}); move it away "
                                  f"or choose another folder") from None

    def close(self) -> None:
        self.db.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def status(self, key: str) -> str | None:
        row = self.db.execute("SELECT status FROM results WHERE key = ?", (key,)).fetchone()
        return row[0] if row else None

    def done_keys(self) -> set[str]:
        return {k for (k,) in self.db.execute("SELECT key FROM results WHERE status = 'ok'")}

    def put(self, key: str, task: dict, code_version: str, result: dict, run_dir: str | None) -> None:
        """Insert or replace one task's row (a re-run of a failed task replaces its error)."""
        metrics = result.get("metrics")
        status, error, tb = result["status"], result.get("error"), result.get("traceback")
        metrics_json = None
        if status == "ok":
            try:
                metrics_json = _finite_json(metrics)
            except (ValueError, TypeError) as e:
                status, error, tb = "error", f"BadMetrics: {e}", None
        with self.db:      # one transaction: a new result is one the results store has not had
            self.db.execute("DELETE FROM appended WHERE key = ?", (key,))
            self.db.execute(
                "INSERT OR REPLACE INTO results VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)",
                (key, task["machine"], task["path"], task["planner"], _sql_int64(int(task["seed"])),
                 task["preset"], task["variation"]["name"], json.dumps(task, sort_keys=True),
                 status, error, tb, metrics_json, result.get("elapsed_s"), result.get("worker"),
                 code_version, run_dir))

    # -- which rows reached a results store (harness.store.append_unstored) ----------------
    def unappended(self, store: Path) -> list[str]:
        """Keys of the finished tasks not yet in ``store``. A file left pending by an interrupted
        append counts as in the store if it is there (files are renamed in whole), else its
        rows are to be appended again."""
        where = str(Path(store).resolve())
        with self.db:
            for (run_id,) in self.db.execute("SELECT DISTINCT run_id FROM appended WHERE store = ? AND done = 0",
                                             (where,)).fetchall():
                if (Path(store) / f"{run_id}.parquet").exists():
                    self.db.execute("UPDATE appended SET done = 1 WHERE run_id = ? AND store = ?", (run_id, where))
                else:
                    self.db.execute("DELETE FROM appended WHERE run_id = ? AND store = ?", (run_id, where))
        return [k for (k,) in self.db.execute(
            "SELECT key FROM results WHERE key NOT IN (SELECT key FROM appended WHERE store IN (?, '*')) "
            "ORDER BY key",
            (where,))]

    def begin_append(self, keys, run_id: str, store: Path) -> None:
        with self.db:
            self.db.executemany("INSERT OR REPLACE INTO appended VALUES (?, ?, ?, 0)",
                                [(k, str(Path(store).resolve()), run_id) for k in keys])

    def end_append(self, run_id: str, store: Path) -> None:
        with self.db:
            self.db.execute("UPDATE appended SET done = 1 WHERE run_id = ? AND store = ?",
                            (run_id, str(Path(store).resolve())))

    def to_rows(self) -> list[dict]:
        """Every row as a dict, metrics decoded, in a stable order."""
        cur = self.db.execute("SELECT * FROM results ORDER BY machine, path, preset, variation, "
                              "planner, seed, key")
        cols = [d[0] for d in cur.description]
        rows = []
        for r in cur:
            row = dict(zip(cols, r))
            row["task"] = json.loads(row["task"])
            row["seed"] = row["task"]["seed"]          # exact, whatever the column holds
            row["metrics"] = json.loads(row["metrics"]) if row["metrics"] else None
            rows.append(row)
        return rows


def flatten(metrics: dict, prefix: str = "") -> dict:
    """{'joint_peak_ratio': {'jerk': 1.2}} → {'joint_peak_ratio.jerk': 1.2}."""
    out = {}
    for k, v in metrics.items():
        name = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flatten(v, name + "."))
        else:
            out[name] = v
    return out
