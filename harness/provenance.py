"""What produced a result: the package version, the git commit of the checkout and the host —
one home for the CLI's --version, the results store's rows and the CI baseline's runs."""
from __future__ import annotations

import os
import platform
import subprocess
from importlib.metadata import PackageNotFoundError, version

import numpy as np

from kins.resources import REPO


def package_version() -> str | None:
    try:
        return version("pkmbench")
    except PackageNotFoundError:
        return None


def git_commit(length: int = 7, dirty: bool = False) -> str | None:
    """The checkout's HEAD (``length`` hex digits), ``+dirty`` when asked and tracked files
    differ from it; None outside a git checkout or without git."""
    def git(*a):
        return subprocess.run(["git", "-C", str(REPO), *a], capture_output=True, text=True, timeout=10)
    try:
        head = git("rev-parse", f"--short={length}", "HEAD")
        commit = head.stdout.strip() if head.returncode == 0 else ""
        if commit and dirty and git("status", "--porcelain", "--untracked-files=no").stdout.strip():
            commit += "+dirty"
    except (OSError, subprocess.SubprocessError):
        return None
    return commit or None


def host_info() -> dict:
    return {"node": platform.node(), "machine": platform.machine(), "cpus": os.cpu_count(),
            "python": platform.python_version(), "system": platform.system(), "numpy": np.__version__}
