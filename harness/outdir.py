"""Output folders of the commands: checked up front, and locked while a run writes them.

    out = output_dir(args.out)          # created; refused with one line if a file or unwritable
    f = output_file(args.junit)         # its folder checked the same way
    with run_lock(out): ...             # a second run into `out` is refused, not interleaved

The errors are :class:`OutDirError`: the CLI prints them as one line (as its own CliError),
before any work is done.
"""
from __future__ import annotations

import fcntl
import os
from contextlib import contextmanager
from pathlib import Path

LOCK_NAME = ".pkmbench.lock"


class OutDirError(ValueError):
    """An output folder or file that cannot be written."""


def output_dir(path, what: str = "output folder") -> Path:
    """Create ``path`` (with its parents) and prove it writable by writing a probe file."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutDirError(f"{what} {path} is a file, not a folder")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        blocker = next((p for p in path.parents if p.exists()), None)
        why = f"{blocker} is a file" if blocker is not None and not blocker.is_dir() else e.strerror
        raise OutDirError(f"cannot create {what} {path}: {why}") from None
    probe = path / f".pkmbench-write-test.{os.getpid()}"   # a per-process name: two commands may probe at once
    try:
        probe.write_bytes(b"")
    except OSError as e:
        raise OutDirError(f"cannot write to {what} {path}: {e.strerror}") from None
    finally:
        probe.unlink(missing_ok=True)
    return path


def output_file(path, what: str = "output file") -> Path:
    """A file a command will write: not a folder, and its folder as :func:`output_dir` wants it."""
    path = Path(path)
    if path.is_dir():
        raise OutDirError(f"{what} {path} is a folder, not a file")
    output_dir(path.parent, f"folder of the {what}")
    return path


@contextmanager
def run_lock(folder: Path):
    """Hold an advisory lock on ``folder`` (FOLDER/.pkmbench.lock) for the body, or raise
    OutDirError at once if another process holds it. The lock file is removed on exit."""
    lock = Path(folder) / LOCK_NAME
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.read(fd, 32).decode(errors="replace").strip()
            os.close(fd)
            raise OutDirError(f"{folder}: another pkmbench run is writing to this folder "
                              f"(pid {holder or '?'} holds {LOCK_NAME}); wait for it or choose another --out") from None
        # The holder before us may have removed the file between our open and our lock:
        # then we locked an orphan inode, and must lock the file now at that name instead.
        try:
            same = os.stat(lock).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        yield lock
    finally:
        lock.unlink(missing_ok=True)   # while still locked: a process that opened it meanwhile sees the inode gone
        os.close(fd)
