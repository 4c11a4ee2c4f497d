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
share. The per-task SQLite table of a sweep (harness/sweep/table.py) stays: it is the resume
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


# the columns every file of the store has (older files may lack later ones, never these)
CORE = ("run_id", "kind", "entry", "status")
# what `pkmbench query` may run over a store opened read-only: reads, nothing that writes
READ_STATEMENTS = ("SELECT", "EXPLAIN")


class StoreError(ValueError):
    """The store cannot be read or written, or a query is wrong; the message says which."""


def default_store() -> Path:
    return Path(os.environ.get(ENV) or RESULTS / "store")


def existing_store(folder=None) -> Path:
    """The store folder to read, StoreError if it does not exist (a mistyped --store would
    otherwise answer 0 rows as if the store were empty)."""
    folder = Path(folder) if folder else default_store()
    if not folder.is_dir():
        raise StoreError(f"results store {folder}: no such folder (sweep, ci and corpus create it; "
                         f"--store or ${ENV} names another)")
    return folder


def file_problem(db, file: Path) -> str | None:
    """Why ``file`` is not a file of the store (unreadable, truncated, another table's), or None."""
    import duckdb
    name = str(file).replace("'", "''")
    try:
        cols = {c: t for c, t, *_ in db.execute(f"DESCRIBE SELECT * FROM read_parquet('{name}')").fetchall()}
    except duckdb.Error as e:
        return f"not a readable Parquet file ({str(e).strip().splitlines()[0]})"
    types = dict(SCHEMA)
    missing = [c for c in CORE if c not in cols]
    if missing:
        return f"not a results-store file: no column {', '.join(missing)}"
    odd = [f"{c} {t}" for c, t in cols.items() if types.get(c) != t]
    if odd:
        return f"not a results-store file: column(s) {', '.join(odd)[:200]} not in the store's schema"
    return None


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
    """The store's files as the views ``results`` and ``runs``. A file that is not one of the
    store's (truncated, foreign) is skipped and named in ``skipped``, so the others stay
    readable. ``read_only``: the connection may read the store's files and nothing else (no
    COPY, ATTACH, other files, extensions), and :meth:`query` runs only SELECT / EXPLAIN."""

    def __init__(self, folder: str | Path | None = None, read_only: bool = False):
        import duckdb
        self.folder = Path(folder) if folder else default_store()
        try:
            if self.folder.exists() and not self.folder.is_dir():
                raise StoreError(f"results store {self.folder} is a file, not a folder")
        except OSError as e:      # a name too long, a folder we may not enter
            raise StoreError(f"results store {self.folder}: {e.strerror}") from None
        self.read_only = read_only
        self.skipped: list[tuple[Path, str]] = []
        self.db = duckdb.connect()
        self._view()
        if read_only:   # after the views are made: they read the files, nothing else may
            paths = ", ".join("'" + str(f).replace("'", "''") + "'" for f in self.files)
            self.db.execute(f"SET allowed_paths = [{paths}]")
            self.db.execute("SET enable_external_access = false")
            self.db.execute("SET lock_configuration = true")

    def _view(self) -> None:
        try:
            found = sorted(self.folder.glob("*.parquet")) if self.folder.is_dir() else []
        except OSError as e:
            raise StoreError(f"results store {self.folder}: cannot list it: {e.strerror}") from None
        files, self.skipped = [], []
        for f in found:
            why = file_problem(self.db, f)
            if why:
                self.skipped.append((f, why))
            else:
                files.append(f)
        self.files = files
        cols = ", ".join(f'"{c}" {t}' for c, t in SCHEMA)
        self.db.execute("DROP VIEW IF EXISTS runs")
        kind = self.db.execute("SELECT 'VIEW' FROM duckdb_views() WHERE view_name = 'results' UNION ALL "
                               "SELECT 'TABLE' FROM duckdb_tables() WHERE table_name = 'results'").fetchone()
        if kind:      # DuckDB drops a view or a table only by its own kind
            self.db.execute(f"DROP {kind[0]} results")
        if files:   # union_by_name: files written by an older schema lack the newer columns
            names = ", ".join("'" + str(f).replace("'", "''") + "'" for f in files)
            self.db.execute(f"CREATE VIEW results AS SELECT * FROM read_parquet([{names}], union_by_name = true)")
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
    @staticmethod
    def new_run_id(kind: str, time: datetime | None = None) -> str:
        time = time or datetime.now(timezone.utc)
        return f"{kind}-{time.strftime('%Y%m%dT%H%M%S%f')}-{secrets.token_hex(3)}"

    def append(self, rows: list[dict], *, kind: str, suite: str = "", code_version: str = "",
               run_info: dict | None = None, time: datetime | None = None, run_id: str | None = None) -> str:
        """Append one command run's rows (from :func:`make_row`) as one Parquet file, named
        ``run_id`` (default a new one); returns the run_id."""
        if not rows:
            return ""
        if self.read_only:
            raise StoreError(f"results store {self.folder}: opened read-only")
        time = time or datetime.now(timezone.utc)
        run_id = run_id or self.new_run_id(kind, time)
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
        if not sql.strip():
            raise StoreError("query is empty")
        try:
            if self.read_only:
                kinds = [st.type.name for st in self.db.extract_statements(sql)]
                bad = [k for k in kinds if k not in READ_STATEMENTS]
                if bad:
                    raise StoreError(f"query refused: {bad[0]} statement; the results store is read-only "
                                     f"here (only {' and '.join(READ_STATEMENTS)})")
            cur = self.db.execute(sql, params) if params is not None else self.db.execute(sql)
            if cur is None or cur.description is None:      # only comments, or a statement with no result
                return [], []
            return [d[0] for d in cur.description], cur.fetchall()
        except duckdb.Error as e:
            first = str(e).strip().splitlines()[0]
            raise StoreError(f"query failed: {first}") from None

    def dicts(self, sql: str, params=None) -> list[dict]:
        cols, rows = self.query(sql, params)
        return [dict(zip(cols, r)) for r in rows]


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
