"""`pkmbench query "SQL"`: SQL (DuckDB) over the results store.

    pkmbench query "SELECT planner, median(execution_time_s) FROM results GROUP BY planner"
    pkmbench query --store results/store --csv "SELECT * FROM runs"

Views: ``results`` (one row per task of every sweep / corpus / ci run, harness/store) and
``runs`` (one row per command run: run_id, kind, suite, time, git_commit, rows, failed,
regressions). Every metric is in ``metrics`` (JSON, dotted names):
``metrics->>'$."joint_peak_ratio.jerk"'``.
"""
from __future__ import annotations

# Local imports: every command module is imported to build the parser; a command loads what it
# needs when it runs (`pkmbench --help` and the other commands stay fast)

import csv
import decimal
import json
import math
import sys

from harness.cli import CliError, warn_skipped

# README's example: the median pso/optimal execution-time ratio per machine, last 10 nightly runs
PSO_OPTIMAL = """
WITH last AS (SELECT run_id FROM runs WHERE kind = 'ci' ORDER BY time DESC LIMIT 10)
SELECT p.machine, median(p.execution_time_s / o.execution_time_s) AS pso_over_optimal,
       count(*) AS n
FROM results p JOIN results o
  ON p.run_id = o.run_id AND p.machine = o.machine AND p.path = o.path AND p.seed = o.seed
 AND p.preset = o.preset AND p.variation = o.variation
WHERE p.planner = 'pso' AND o.planner = 'optimal' AND p.status = 'ok' AND o.status = 'ok'
  AND p.run_id IN (SELECT run_id FROM last)
GROUP BY p.machine ORDER BY p.machine
""".strip()


def add_arguments(p) -> None:
    p.add_argument("sql", help="a DuckDB SQL query over the views results and runs")
    p.add_argument("--store", default=None, help="results store folder (default: $PKMBENCH_STORE or results/store)")
    fmt = p.add_mutually_exclusive_group()
    fmt.add_argument("--csv", action="store_true", help="CSV on stdout")
    fmt.add_argument("--json", action="store_true", help="a JSON list of objects on stdout")


def _cell(v) -> str:
    if v is None:
        return "—"
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def strict_json(v):
    """A value as strict JSON has it: NaN and ±Infinity (which JSON parsers refuse) as null,
    decimals as numbers."""
    if isinstance(v, decimal.Decimal):        # DuckDB's DECIMAL: a JSON number, not a string
        v = float(v)
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, dict):
        return {k: strict_json(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [strict_json(x) for x in v]
    return v


def main(args) -> int:
    from harness.store import ResultStore, StoreError, existing_store
    try:
        with ResultStore(existing_store(args.store), read_only=True) as st:
            warn_skipped("query", st)
            cols, rows = st.query(args.sql)
    except StoreError as e:
        raise CliError(str(e)) from None
    if args.csv:
        w = csv.writer(sys.stdout)
        w.writerow(cols)
        w.writerows(rows)
    elif args.json:
        print(json.dumps([strict_json(dict(zip(cols, r))) for r in rows], default=str, indent=1,
                         allow_nan=False))
    else:
        cells = [[_cell(v) for v in r] for r in rows]
        width = [max([len(c)] + [len(r[i]) for r in cells]) for i, c in enumerate(cols)]
        print("  ".join(c.ljust(w) for c, w in zip(cols, width)))
        for r in cells:
            print("  ".join(v.ljust(w) for v, w in zip(r, width)))
        print(f"({len(rows)} row{'s' if len(rows) != 1 else ''})", file=sys.stderr)
    return 0
