"""The nightly CI history: a query over the results store (harness.store), not a file of its own.

Every `pkmbench ci` run appends its rows to the store with ``kind = 'ci'``; a ci run's own
facts (mode, pass, reference workload, wall time) are in ``run_info`` and the metrics out of
tolerance in each row's ``regressions``. `pkmbench history` and the HTML report read it here.
"""
from __future__ import annotations

import json

from harness.store import ResultStore


class History:
    """The ci runs of a results store, numbered 1, 2, … in time order."""

    def __init__(self, store=None):
        self.store = ResultStore(store)
        self._runs = None

    def close(self):
        self.store.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def runs(self) -> list[dict]:
        """[{id, run_id, utc, git_commit, code_version, suite, mode, passed, regressions,
        reference_s, wall_s}] of every ci run, oldest first."""
        if self._runs is None:
            rows = self.store.dicts("SELECT run_id, time, git_commit, code_version, suite, run_info, "
                                    "regressions FROM runs WHERE kind = 'ci' ORDER BY time, run_id")
            out = []
            for i, r in enumerate(rows, start=1):
                info = json.loads(r["run_info"] or "{}")
                out.append({"id": i, "run_id": r["run_id"], "utc": r["time"].isoformat(timespec="seconds") + "+00:00",
                            "git_commit": r["git_commit"], "code_version": r["code_version"], "suite": r["suite"],
                            "mode": info.get("mode"), "passed": int(bool(info.get("passed"))),
                            "regressions": int(r["regressions"] or 0), "reference_s": info.get("reference_s"),
                            "wall_s": info.get("wall_s")})
            self._runs = out
        return self._runs

    def series(self, metric: str) -> dict[str, list[tuple[int, float]]]:
        """{entry: [(run #, value), …]} of one metric (booleans as 0/1)."""
        return {e: [(n, v) for n, v, _ in pts] for e, pts in self.series_marked(metric).items()}

    def series_marked(self, metric: str) -> dict[str, list[tuple[int, float, bool]]]:
        """{entry: [(run #, value, out of tolerance in that run), …]} of one metric."""
        number = {r["run_id"]: r["id"] for r in self.runs()}
        rows = self.store.query(
            "SELECT run_id, entry, json_extract(metrics, ?) AS v, list_contains(regressions, ?) "
            "FROM results WHERE kind = 'ci' AND status = 'ok' ORDER BY time, run_id, entry",
            [f'$."{metric}"', metric])[1]
        out: dict[str, list] = {}
        for run_id, entry, v, bad in rows:
            if v is None:
                continue
            x = json.loads(str(v))
            if x is None:
                continue
            out.setdefault(entry, []).append((number[run_id], float(x), bool(bad)))
        return out

    def metric_names(self) -> list[str]:
        rows = self.store.query("SELECT DISTINCT unnest(json_keys(metrics)) AS m FROM results "
                                "WHERE kind = 'ci' ORDER BY m")[1]
        return [m for (m,) in rows]
