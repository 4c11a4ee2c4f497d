"""Output folders of the commands: checked up front.

    out = output_dir(args.out)          # created; refused with one line if a file or unwritable
    f = output_file(args.junit)         # its folder checked the same way

The errors are :class:`OutDirError`, a :class:`harness.cli.CliError`: the CLI prints them
as one line, before any work is done.
"""
from __future__ import annotations

import os
from pathlib import Path

from harness.cli import CliError

class OutDirError(CliError):
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

