"""The results store: every sweep, corpus and ci run appends its rows here; SQL reads them.

    from harness.store import ResultStore
    with ResultStore() as st:                       # results/store/ (or $PKMBENCH_STORE)
        st.query("SELECT planner, median(execution_time_s) FROM results GROUP BY planner")

Form: a folder of Parquet files, one file per appending command run, read together by DuckDB
(``read_parquet('DIR/*.parquet', union_by_name = true)``) as the view ``results``.

Why Parquet files read by DuckDB rather than one DuckDB database file: a DuckDB file takes one
writer process at a time (a second sweep, a nightly ci and a corpus run at once would wait or
fail on its lock), and a file in DuckDB's own format is tied to its storage version. A Parquet
file is written once, whole, under a temporary name and renamed in (atomic: a reader never sees
half a file, a killed run leaves nothing); any number of writers append side by side, and the
files can be copied, merged (``cp``) and read by DuckDB, pandas, polars or Spark: results to
share. The per-task SQLite table of a sweep (harness/sweep/store.py) stays: it is the resume
log of one sweep folder, written row by row while the sweep runs; the store gets the finished
rows.

Columns (``SCHEMA``): one row per task (machine × path × planner × seed × preset × variation)
of one command run (``run_id``, ``kind`` = sweep | ci | corpus, ``time`` UTC), its status,
the common metrics as typed columns, every metric in ``metrics`` (JSON, flattened with dots:
``metrics->>'$."joint_peak_ratio.jerk"'``), ``regressions`` (ci: the metrics out of tolerance),
the code version, git commit, pkmbench version and host, ``run_info`` (JSON: ci's mode, pass,
timings) and ``run_dir`` (the run's files).
"""
from __future__ import annotations

import json
import math
import os
import secrets
from datetime import datetime, timezone
from pathlib import Path

from harness.provenance import git_commit, host_info, package_version
from harness.sweep import SweepStore, task_label
from kins.resources import RESULTS

ENV = "PKMBENCH_STORE"

# (name, DuckDB type): the table every Parquet file of the store has
SCHEMA = [
    ("run_id", "VARCHAR"), ("kind", "VARCHAR"), ("suite", "VARCHAR"), ("time", "TIMESTAMP"),
    ("entry", "VARCHAR"), ("machine", "VARCHAR"), ("path", "VARCHAR"), ("planner", "VARCHAR"),
    ("seed", "UBIGINT"), ("preset", "VARCHAR"), ("variation", "VARCHAR"),
    ("status", "VARCHAR"), ("error", "VARCHAR"),
    ("execution_time_s", "DOUBLE"), ("feasible", "BOOLEAN"),
    ("joint_velocity", "DOUBLE"), ("joint_acceleration", "DOUBLE"), ("joint_jerk", "DOUBLE"),
    ("max_following_error_um", "DOUBLE"), ("max_contour_error_um", "DOUBLE"),
    ("planning_time_s", "DOUBLE"),
    ("metrics", "JSON"), ("regressions", "VARCHAR[]"),
    ("code_version", "VARCHAR"), ("git_commit", "VARCHAR"), ("pkmbench_version", "VARCHAR"),
    ("host", "JSON"), ("run_info", "JSON"), ("run_dir", "VARCHAR"),
]
COLUMNS = [c for c, _ in SCHEMA]

# typed column → flattened metric name
TYPED = {"execution_time_s": "execution_time_s", "feasible": "feasible",
         "joint_velocity": "joint_peak_ratio.velocity", "joint_acceleration": "joint_peak_ratio.acceleration",
         "joint_jerk": "joint_peak_ratio.jerk", "max_following_error_um": "max_following_error_um",
         "max_contour_error_um": "max_contour_error_um", "planning_time_s": "planning_time_s"}


class StoreError(ValueError):
    """The store cannot be read or written, or a query is wrong; the message says which."""


def default_store() -> Path:
    return Path(os.environ.get(ENV) or RESULTS / "store")


def _flatten(metrics: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in (metrics or {}).items():
        if isinstance(v, dict):
            out.update(_flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def _num(v):
    if isinstance(v, bool) or v is None:
        return v
    return float(v) if isinstance(v, (int, float)) and math.isfinite(v) else None


def make_row(*, entry: str, machine: str, path: str, planner: str, seed: int, preset: str = "",
             variation: str = "", status: str = "ok", error: str | None = None,
             metrics: dict | None = None, regressions=(), run_dir: str | None = None) -> dict:
    """One task's row (the command-level columns are filled in by :meth:`ResultStore.append`)."""
    flat = _flatten(metrics or {})
    row = {"entry": entry, "machine": machine, "path": path, "planner": planner, "seed": int(seed),
           "preset": preset, "variation": variation, "status": status, "error": error,
           "metrics": json.dumps({k: _num(v) if not isinstance(v, str) else v for k, v in sorted(flat.items())},
                                 sort_keys=True, allow_nan=False),
           "regressions": sorted(regressions), "run_dir": run_dir}
    for col, name in TYPED.items():
        v = flat.get(name)
        row[col] = bool(v) if col == "feasible" and v is not None else _num(v)
    return row


class ResultStore:
    def __init__(self, folder: str | Path | None = None):
        import duckdb
        self.folder = Path(folder) if folder else default_store()
        if self.folder.exists() and not self.folder.is_dir():
            raise StoreError(f"results store {self.folder} is a file, not a folder")
        self.db = duckdb.connect()
        self._view()

    def _view(self) -> None:
        files = sorted(self.folder.glob("*.parquet")) if self.folder.is_dir() else []
        cols = ", ".join(f'"{c}" {t}' for c, t in SCHEMA)
        self.db.execute("DROP VIEW IF EXISTS runs")
        kind = self.db.execute("SELECT 'VIEW' FROM duckdb_views() WHERE view_name = 'results' UNION ALL "
                               "SELECT 'TABLE' FROM duckdb_tables() WHERE table_name = 'results'").fetchone()
        if kind:      # DuckDB drops a view or a table only by its own kind
            self.db.execute(f"DROP {kind[0]} results")
        if files:   # union_by_name: files written by an older schema lack the newer columns
            glob = str(self.folder / "*.parquet").replace("'", "''")
            self.db.execute(f"CREATE VIEW results AS SELECT * FROM read_parquet('{glob}', union_by_name = true)")
        else:       # an empty store answers with no rows, not with an error
            self.db.execute(f"CREATE TABLE results ({cols})")
        # one row per command run: what the nightly history and "the last N runs" are about
        self.db.execute("CREATE OR REPLACE VIEW runs AS SELECT run_id, any_value(kind) AS kind, "
                        "any_value(suite) AS suite, min(time) AS time, any_value(git_commit) AS git_commit, "
                        "any_value(code_version) AS code_version, any_value(run_info) AS run_info, "
                        "count(*) AS rows, count(*) FILTER (status <> 'ok') AS failed, "
                        "sum(len(regressions)) AS regressions FROM results GROUP BY run_id")

    def close(self) -> None:
        self.db.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # -- writing ---------------------------------------------------------------------------
    def append(self, rows: list[dict], *, kind: str, suite: str = "", code_version: str = "",
               run_info: dict | None = None, time: datetime | None = None) -> str:
        """Append one command run's rows (from :func:`make_row`) as one Parquet file; returns its run_id."""
        if not rows:
            return ""
        time = time or datetime.now(timezone.utc)
        run_id = f"{kind}-{time.strftime('%Y%m%dT%H%M%S%f')}-{secrets.token_hex(3)}"
        common = {"run_id": run_id, "kind": kind, "suite": suite, "time": time.replace(tzinfo=None),
                  "code_version": code_version, "git_commit": git_commit(), "pkmbench_version": package_version(),
                  "host": json.dumps(host_info(), sort_keys=True),
                  "run_info": json.dumps(run_info or {}, sort_keys=True, allow_nan=False)}
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise StoreError(f"results store {self.folder}: cannot create it: {e.strerror}") from None
        cols = ", ".join(f'"{c}" {t}' for c, t in SCHEMA)
        db = self.db
        db.execute(f"CREATE OR REPLACE TEMP TABLE incoming ({cols})")
        db.executemany(f"INSERT INTO incoming VALUES ({', '.join('?' * len(COLUMNS))})",
                       [[(common | r).get(c) for c in COLUMNS] for r in rows])
        final = self.folder / f"{run_id}.parquet"
        tmp = self.folder / f".{run_id}.parquet.part"
        target = str(tmp).replace("'", "''")
        try:
            db.execute(f"COPY (SELECT * FROM incoming ORDER BY entry) TO '{target}' (FORMAT parquet)")
            os.replace(tmp, final)            # atomic: readers see the whole file or none of it
        except Exception as e:
            tmp.unlink(missing_ok=True)
            raise StoreError(f"results store {self.folder}: cannot write {final.name}: {e}") from None
        finally:
            db.execute("DROP TABLE IF EXISTS incoming")
        self._view()
        return run_id

    # -- reading ---------------------------------------------------------------------------
    def query(self, sql: str, params=None) -> tuple[list[str], list[tuple]]:
        """(column names, rows) of ``sql`` over the views ``results`` and ``runs``."""
        import duckdb
        try:
            cur = self.db.execute(sql, params) if params is not None else self.db.execute(sql)
            cols = [d[0] for d in cur.description] if cur.description else []
            return cols, cur.fetchall()
        except duckdb.Error as e:
            first = str(e).strip().splitlines()[0]
            raise StoreError(f"query failed: {first}") from None

    def dicts(self, sql: str, params=None) -> list[dict]:
        cols, rows = self.query(sql, params)
        return [dict(zip(cols, r)) for r in rows]


def rows_from_sweep(sweep_db: Path, keys=None, regressions: dict | None = None) -> list[dict]:
    """Store rows of a sweep's SQLite table (only ``keys`` when given); ``regressions`` maps a
    task label to its metrics out of tolerance (ci)."""
    with SweepStore(sweep_db) as s:
        rows = s.to_rows()
    want = set(keys) if keys is not None else None
    out = []
    for r in rows:
        if want is not None and r["key"] not in want:
            continue
        label = task_label(r["task"])
        out.append(make_row(entry=label, machine=r["machine"], path=r["path"], planner=r["planner"],
                            seed=r["seed"], preset=r["preset"], variation=r["variation"],
                            status=r["status"], error=r["error"], metrics=r["metrics"],
                            regressions=(regressions or {}).get(label, ()),
                            run_dir=str(Path(sweep_db).parent / r["run_dir"]) if r["run_dir"] else None))
    return out


def rows_from_corpus(rows) -> list[dict]:
    """Store rows of `pkmbench corpus` (harness.corpus.Row: planned and checked at T, no
    co-simulation); metrics named as a run's summary.json names them."""
    out = []
    for r in rows:
        ok = r.status == "ok"
        metrics = {"path_kind": r.kind, "planning_time_s": r.planning_time_s}
        if ok:
            metrics |= {"execution_time_s": r.execution_time_s, "feasible": r.feasible,
                        "cartesian_feasible": r.cartesian_feasible, "own_limits_ok": r.own_limits_ok,
                        "joint_peak_ratio": {"velocity": r.joint_v, "acceleration": r.joint_a, "jerk": r.joint_j},
                        "cartesian_peak_ratio": {"velocity": r.cart_v, "acceleration": r.cart_a,
                                                 "jerk": r.cart_j, "feed": r.feed}}
        out.append(make_row(entry=f"{r.machine}/{r.path}/{r.planner}", machine=r.machine, path=r.path,
                            planner=r.planner, seed=r.seed or 0, status=r.status, error=r.error or None, metrics=metrics))
    return out


def append_sweep(sweep_db: Path, keys, *, kind: str, suite: str, store: str | Path | None = None,
                 run_info: dict | None = None, regressions: dict | None = None,
                 code_version: str = "") -> str:
    """Append the rows ``keys`` of a sweep folder's table to the store (sweep and ci call this;
    corpus appends :func:`rows_from_corpus`)."""
    rows = rows_from_sweep(sweep_db, keys, regressions)
    with ResultStore(store) as st:
        return st.append(rows, kind=kind, suite=suite, code_version=code_version, run_info=run_info)
