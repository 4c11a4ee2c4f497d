"""A sweep's finished tasks into the results store (harness.store): the sweep knows the store,
the store knows no producer."""
from __future__ import annotations

from pathlib import Path

from harness.store import ResultStore, make_row
from harness.sweep.suite import task_label
from harness.sweep.table import TaskTable


def rows_from_sweep(sweep_db: Path, keys=None, regressions: dict | None = None) -> list[dict]:
    """Store rows of a sweep's SQLite table (only ``keys`` when given); ``regressions`` maps a
    task label to its metrics out of tolerance (ci)."""
    with TaskTable(sweep_db) as s:
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


def append_unstored(sweep_db: Path, *, kind: str, suite: str, store: str | Path | None = None,
                    run_info: dict | None = None, code_version: str = "") -> tuple[str, int]:
    """Append every finished task of a sweep folder that has not reached this store yet, as one
    file: (its run_id, the rows; "" and 0 when there were none). Exactly once, whatever was
    interrupted when: the sweep's table records the file's name before the file is written
    (``appended``, pending) and that it is in the store after; a pending file found in the store
    is complete (written under a temporary name, renamed in), one not found is written again."""
    with ResultStore(store) as st, TaskTable(sweep_db) as sw:
        keys = sw.unappended(st.folder)
        if not keys:
            return "", 0
        rows = rows_from_sweep(sweep_db, keys)
        run_id = st.new_run_id(kind)
        sw.begin_append(keys, run_id, st.folder)
        st.append(rows, kind=kind, suite=suite, code_version=code_version, run_info=run_info, run_id=run_id)
        sw.end_append(run_id, st.folder)
        return run_id, len(rows)
