"""Every test's results store is a temporary folder: no test appends to the checkout's results/store."""
from __future__ import annotations

import pytest


@pytest.fixture(autouse=True, scope="session")
def _results_store(tmp_path_factory):
    mp = pytest.MonkeyPatch()
    mp.setenv("PKMBENCH_STORE", str(tmp_path_factory.mktemp("results-store")))
    yield
    mp.undo()
