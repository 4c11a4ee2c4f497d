"""`pkmbench store check`: the files of the results store that queries skip.

    pkmbench store check                       # results/store (or $PKMBENCH_STORE)
    pkmbench store check --store DIR

A file that is not one of the store's (a truncated copy, another program's Parquet file) is
skipped by `query`, `history`, `report` and the appends of `sweep`, `ci` and `corpus`, each
naming it on stderr; this lists them all, and the temporary files of appends that were
interrupted. Exit 0 when every file is readable, 1 when some are not, 2 on a user error.
"""
from __future__ import annotations

# Local imports: every command module is imported to build the parser; a command loads what it
# needs when it runs (`pkmbench --help` and the other commands stay fast)

from harness.cli import CliError


def add_arguments(p) -> None:
    p.add_argument("action", choices=("check",), help="check: list the files queries skip")
    p.add_argument("--store", default=None, help="results store folder (default: $PKMBENCH_STORE or results/store)")


def main(args) -> int:
    from harness.store import ResultStore, StoreError, existing_store
    try:
        with ResultStore(existing_store(args.store), read_only=True) as st:
            folder, good, bad = st.folder, st.files, st.skipped
    except StoreError as e:
        raise CliError(str(e)) from None
    parts = sorted(folder.glob(".*.parquet.part"))
    for f, why in bad:
        print(f"SKIPPED {f}: {why}")
    for f in parts:
        print(f"PARTIAL {f}: an append that was interrupted (readers ignore it; it may be deleted)")
    print(f"store {folder}: {len(good)} file(s) read, {len(bad)} skipped, {len(parts)} partial")
    return 1 if bad else 0
