"""Sweeps on dask.distributed: many (machine, path, planner, seed, preset, variation) tasks.

The task-function interface (any ``module:function`` can be one)::

    def task_fn(task: dict, out_dir: pathlib.Path) -> dict
        task     machine, machine_file, path, path_file, planner, planner_options, seed,
                 preset, variation {"name", "set"}, files {"machine.toml": text,
                 "path.json"|"path.ngc": text}, and fmu_dir (a local folder holding the
                 built .fmu files) when the sweep shipped FMUs; with user FMUs (a suite's
                 [fmus], --fmu) fmus {block: {"file", "sha256", "source"}} and fmu_paths
                 {block: the local copy of that FMU}
        out_dir  an empty folder; whatever the task writes there becomes the run's files
        returns  the metrics dict of DESIGN.md (execution_time_s, joint_peak_ratio {…}, …);
                 raising marks the task failed, with the message, and the others go on

Engine: an in-process ``LocalCluster`` (``workers`` processes, one thread each, bound to
127.0.0.1, no set-up), or an existing cluster by scheduler address. Results land in
``OUT/results.sqlite`` (see store.py for why SQLite) and each run's files in
``OUT/runs/<machine>/<path>/<preset>/<variation>/seed<N>/<planner>/``. A task whose key
(hash of its inputs, of the task function and of the code/FMU versions) is already in the
table with status ok is skipped.
"""
from __future__ import annotations

import functools
import hashlib
import importlib
import logging
import os
import shutil
import socket
import sys
import tempfile
import time
import traceback
import uuid
from dataclasses import dataclass, field
from pathlib import Path

from harness.sweep.table import TaskTable, TaskTableError
from harness.sweep.suite import code_version, expand, load_suite, task_key, task_label, with_user_fmus
from kins.resources import FMU_DIR, REPO

DEFAULT_TASK = "harness.sweep.tasks:default_task"
CONNECT_TIMEOUT = "10s"       # to an existing scheduler


class SweepError(RuntimeError):
    """The sweep itself cannot run (bad scheduler address, code mismatch, …)."""


@dataclass
class SweepResult:
    out_dir: Path
    total: int = 0
    skipped: int = 0
    ok: int = 0
    failed: int = 0
    wall_s: float = 0.0
    failures: list[tuple[str, str]] = field(default_factory=list)   # (task label, error)
    keys: list[str] = field(default_factory=list)       # the tasks run this time (results store rows)
    code_version: str = ""


def tasks_from_suite_file(file: str | Path, fmu_specs=()) -> list[dict]:
    """The suite's tasks, with its [fmus] and the ``BLOCK=FILE`` ``fmu_specs`` (checked)."""
    file = Path(file)
    suite = load_suite(file)
    return with_user_fmus(expand(suite, src=str(file), base=Path.cwd()), suite, file, fmu_specs)


# -- worker side ---------------------------------------------------------------------------
def resolve_task_fn(spec: str):
    mod, sep, name = spec.partition(":")
    if not sep or not mod or not name:
        raise SweepError(f"task function '{spec}' must be 'module:function'")
    try:
        fn = getattr(importlib.import_module(mod), name)
    except (ImportError, AttributeError) as e:
        raise SweepError(f"task function '{spec}' cannot be loaded: {e}") from None
    if not callable(fn):
        raise SweepError(f"task function '{spec}' is not callable")
    return fn


def _materialise_fmus(fmus: dict[str, bytes]) -> Path:
    """Write the shipped FMU files once per worker host, into a folder named by their hash."""
    h = hashlib.sha256()
    for name in sorted(fmus):
        h.update(name.encode() + b"\0" + hashlib.sha256(fmus[name]).digest())
    folder = Path(tempfile.gettempdir()) / "pkmbench-fmus" / h.hexdigest()[:16]
    if not (folder / ".complete").exists():
        folder.mkdir(parents=True, exist_ok=True)
        for name, data in fmus.items():
            tmp = folder / f".{name}.{os.getpid()}.part"
            tmp.write_bytes(data)
            os.replace(tmp, folder / name)          # atomic: workers on one host may race
        (folder / ".complete").touch()
    return folder


def _materialise_user_fmus(named: dict, shipped: dict[str, bytes] | None) -> dict[str, str]:
    """{block: local file} of a task's user FMUs, written once per host into a folder named by
    the content's hash (under the FMU's own file name: the SSP names it)."""
    out = {}
    for block, d in named.items():
        data = (shipped or {}).get(d["sha256"])
        if data is None:
            raise SweepError(f"{block} FMU {d['source']} was not shipped to this worker")
        f = Path(tempfile.gettempdir()) / "pkmbench-fmus" / "user" / d["sha256"][:16] / d["file"]
        if not f.exists():
            f.parent.mkdir(parents=True, exist_ok=True)
            tmp = f.with_name(f".{f.name}.{os.getpid()}.part")
            tmp.write_bytes(data)
            os.replace(tmp, f)                      # atomic: workers on one host may race
        out[block] = str(f)
    return out


def execute_task(task_fn: str, task: dict, fmus: dict[str, bytes] | None = None,
                 user_fmus: dict[str, bytes] | None = None) -> dict:
    """Run one task on this process; never raises. Returns status, metrics or error, files.
    ``fmus``: our built FMUs by file name; ``user_fmus``: the tasks' user FMUs by sha256."""
    t0 = time.perf_counter()
    tmp = Path(tempfile.mkdtemp(prefix="pkmbench-task-"))
    try:
        if fmus:
            task = task | {"fmu_dir": str(_materialise_fmus(fmus))}
        if task.get("fmus"):
            task = task | {"fmu_paths": _materialise_user_fmus(task["fmus"], user_fmus)}
        metrics = resolve_task_fn(task_fn)(task, tmp)
        if not isinstance(metrics, dict):
            raise TypeError(f"task function {task_fn} returned {type(metrics).__name__}, not a metrics dict")
        result = {"status": "ok", "metrics": metrics}
    except Exception as e:                          # a failed task is data, not a crash
        result = {"status": "error", "error": f"{type(e).__name__}: {e}",
                  "traceback": traceback.format_exc()}
    files = {}
    for f in sorted(tmp.rglob("*")):
        if f.is_file():
            files[str(f.relative_to(tmp))] = f.read_bytes()
    shutil.rmtree(tmp, ignore_errors=True)
    result["files"] = files
    result["elapsed_s"] = time.perf_counter() - t0
    result["worker"] = f"{socket.gethostname()}:{os.getpid()}"
    return result


def _worker_code_version() -> str:
    return code_version()


def _worker_malloc_trim() -> str | None:
    return os.environ.get("MALLOC_TRIM_THRESHOLD_")


# -- client side ---------------------------------------------------------------------------
class Progress:
    """A one-line progress bar on a terminal; a line per 10 % otherwise (logs stay short)."""

    def __init__(self, total: int, enabled: bool = True, stream=None):
        self.total, self.done, self.failed = total, 0, 0
        self.stream = stream or sys.stderr
        self.enabled = enabled and total > 0
        self.tty = self.stream.isatty()
        self.t0 = time.perf_counter()
        self.last_decile = -1

    def update(self, ok: bool) -> None:
        self.done += 1
        self.failed += not ok
        if not self.enabled:
            return
        el = time.perf_counter() - self.t0
        eta = el / self.done * (self.total - self.done)
        width = 30
        fill = int(width * self.done / self.total)
        line = (f"[{'#' * fill}{'.' * (width - fill)}] {self.done}/{self.total} "
                f"failed {self.failed}  {el:6.1f} s  eta {eta:6.1f} s")
        if self.tty:
            self.stream.write("\r" + line + ("\n" if self.done == self.total else ""))
            self.stream.flush()
        else:
            decile = 10 * self.done // self.total
            if decile != self.last_decile:
                self.last_decile = decile
                print(line, file=self.stream, flush=True)


def run_dir_of(task: dict) -> str:
    safe = lambda s: "".join(c if c.isalnum() or c in "-_." else "_" for c in str(s))  # noqa: E731
    return "/".join(["runs", safe(task["machine"]), safe(task["path"]), safe(task["preset"]),
                     safe(task["variation"]["name"]), f"seed{task['seed']}",
                     safe(task["planner"]) + ("-max_feed" if task.get("max_feed") else "")])


def _task_fn_files(spec: str) -> list[Path]:
    """The source file of a task function outside kins/planners/harness joins the code hash."""
    mod = spec.partition(":")[0]
    try:
        f = Path(importlib.import_module(mod).__file__ or "")
    except Exception:
        return []
    return [] if not f.is_file() or REPO / "harness" in f.parents else [f]


def _fmu_payload() -> dict[str, bytes]:
    return {f.name: f.read_bytes() for f in sorted(FMU_DIR.glob("*.fmu"))} if FMU_DIR.exists() else {}


def _user_fmu_payload(tasks) -> dict[str, bytes]:
    """The user FMUs the tasks name, by content hash: each file read once, and refused if it
    changed since the tasks were made (their keys hold the old hash)."""
    out = {}
    for task in tasks:
        for block, d in (task.get("fmus") or {}).items():
            if d["sha256"] not in out:
                data = Path(d["source"]).read_bytes()
                if hashlib.sha256(data).hexdigest() != d["sha256"]:
                    raise SweepError(f"{block} FMU {d['source']} changed while the sweep was set up; run it again")
                out[d["sha256"]] = data
    return out


def _same(x):
    return x


def _connect(scheduler: str | None, workers: int, processes: bool):
    from distributed import Client, LocalCluster
    if scheduler:
        try:
            return Client(scheduler, timeout=CONNECT_TIMEOUT), None
        except (OSError, TimeoutError) as e:
            raise SweepError(f"cannot reach the dask scheduler at {scheduler}: {e}") from None
    import dask
    # dask sets MALLOC_TRIM_THRESHOLD_ in its workers; glibc then stops adapting its mmap
    # threshold and maps and unmaps every array ≥ 128 KiB: pso planned 2 × slower
    # (kossel/bird_kossel pso 44 → 88 s, 36 s of it in the kernel)
    environ = {k: v for k, v in dask.config.get("distributed.nanny.pre-spawn-environ").items()
               if k != "MALLOC_TRIM_THRESHOLD_"}
    with dask.config.set({"distributed.nanny.pre-spawn-environ": environ}):
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=processes,
                               host="127.0.0.1", dashboard_address=None,
                               silence_logs=logging.CRITICAL)   # worker heartbeats racing the shutdown
    return Client(cluster), cluster


def _worker_lost(msg, labels: dict, log) -> None:
    """Warn of each sweep task that was running on a worker the scheduler lost."""
    if not isinstance(msg, dict) or msg.get("action") != "remove-worker" or msg.get("expected"):
        return
    for k in sorted(k for k in msg.get("processing-tasks", ()) if k in labels):
        log(f"sweep: warning: worker {msg.get('worker')} died while running {labels[k]}; "
            f"dask runs that task again on another worker")


def run_sweep(tasks: list[dict], out_dir: str | Path, *, task_fn: str = DEFAULT_TASK,
              workers: int = 2, scheduler: str | None = None, processes: bool = True,
              force: bool = False, progress: bool = True, log=None) -> SweepResult:
    """Run ``tasks`` (dicts from ``expand``/``make_task``) and store their results in ``out_dir``.

    ``workers = 0`` runs the tasks one after the other in this process (no Dask; debugging).
    ``force`` re-runs tasks already done.
    """
    log = log or (lambda msg: print(msg, file=sys.stderr))
    out_dir = Path(out_dir)
    t0 = time.perf_counter()
    resolve_task_fn(task_fn)                         # fail early, here, with a clear message
    version = code_version(extra=_task_fn_files(task_fn))
    res = SweepResult(out_dir, total=len(tasks), code_version=version)
    try:
        store = TaskTable(out_dir / "results.sqlite")
    except TaskTableError as e:
        raise SweepError(str(e)) from None
    with store:
        done = set() if force else store.done_keys()
        keyed = [(task_key(t, version, task_fn), t) for t in tasks]
        todo = [(k, t) for k, t in keyed if k not in done]
        res.skipped = len(keyed) - len(todo)
        if res.skipped:
            log(f"sweep: {res.skipped} of {len(keyed)} tasks already done, skipped")
        bar = Progress(len(todo), progress)
        record = functools.partial(_record, store, res, bar, out_dir, version)
        user = _user_fmu_payload(t for _, t in todo)
        if todo and workers == 0 and not scheduler:
            fmus = _fmu_payload()
            for key, task in todo:
                record(key, task, execute_task(task_fn, task, fmus or None, user or None))
        elif todo:
            _run_on_dask(todo, task_fn, scheduler, workers, processes, log, record, user)
    res.wall_s = time.perf_counter() - t0
    return res


def _record(store, res: SweepResult, bar: Progress, out_dir: Path, version: str, key, task, result) -> None:
    """One task's result: its files in its run folder (replacing an earlier run's), its row
    in the store, and the count of ok/failed runs."""
    rd = run_dir_of(task)
    target = out_dir / rd
    shutil.rmtree(target, ignore_errors=True)
    for rel, data in result.get("files", {}).items():
        (target / rel).parent.mkdir(parents=True, exist_ok=True)
        (target / rel).write_bytes(data)
    store.put(key, {k: v for k, v in task.items() if k != "files"}, version, result,
              rd if result.get("files") else None)
    res.keys.append(key)
    if store.status(key) == "ok":
        res.ok += 1
    else:
        res.failed += 1
        err = store.db.execute("SELECT error FROM results WHERE key=?", (key,)).fetchone()[0]
        res.failures.append((task_label(task), err))
    bar.update(store.status(key) == "ok")


def _run_on_dask(todo, task_fn: str, scheduler: str | None, workers: int, processes: bool, log, record,
                 user: dict[str, bytes]) -> None:
    """The tasks on a local cluster or the scheduler's workers, recorded as they complete."""
    client, cluster = _connect(scheduler, workers, processes)
    try:
        if scheduler:
            _check_workers(client, scheduler)
            trimmed = sorted(w for w, v in client.run(_worker_malloc_trim).items() if v is not None)
            if trimmed:
                log(f"sweep: warning: {len(trimmed)} worker(s) ({', '.join(trimmed)}) run with MALLOC_TRIM_THRESHOLD_ set "
                    f"(dask's nanny sets it): pso plans ~2 × slower there; start them with --no-nanny "
                    f"(docs/TUNING.md)")
        fmus = _fmu_payload()
        # held as tasks, not scattered: scattered data dies with the worker holding it and
        # cancels every task that needs it; a task's result the scheduler computes again
        fmus_ref = client.submit(_same, fmus, pure=False) if fmus else None
        user_ref = client.submit(_same, user, pure=False) if user else None
        futures, labels = {}, {}
        # dask re-runs the tasks of a worker that died without telling the client:
        # the scheduler's remove-worker event names them, so the user hears of it
        client.subscribe_topic("all", lambda event: _worker_lost(event[1], labels, log))
        for key, task in todo:
            f = client.submit(execute_task, task_fn, task, fmus_ref, user_ref, pure=False,
                              key=f"pkmbench-{key[:16]}-{uuid.uuid4().hex[:8]}")
            futures[f] = (key, task)
            labels[f.key] = task_label(task)
        from distributed import as_completed
        for f in as_completed(futures):
            key, task = futures[f]
            try:
                result = f.result()
            except Exception as e:   # the worker died (segfault in an FMU, OOM kill, …)
                result = {"status": "error", "error": f"{type(e).__name__}: {e}",
                          "traceback": None}
            record(key, task, result)
    finally:
        # unsubscribed first: else the scheduler sends the client's own remove-client
        # event down the closing comm and logs a CRITICAL traceback
        client.unsubscribe_topic("all")
        client.close()
        if cluster is not None:
            cluster.close()


def _check_workers(client, scheduler: str) -> None:
    """An existing cluster must have workers, all running this checkout's code."""
    theirs = client.run(_worker_code_version)
    mine = code_version()
    odd = sorted(w for w, v in theirs.items() if v != mine)
    if not theirs:
        raise SweepError(f"the scheduler at {scheduler} has no workers")
    if odd:
        raise SweepError(f"workers {', '.join(odd)} run other code (kins/planners/"
                         f"harness/FMU hash differs from this checkout); update them")
