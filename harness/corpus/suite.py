"""A suite file's paths as corpus entries (``pkmbench corpus --suite``): kept apart from run.py,
so that the code a corpus row is keyed by (harness.corpus.journal) holds no sweep machinery."""
from __future__ import annotations

import tomllib
from pathlib import Path

from harness.corpus.run import CORPUS_DIR, CorpusError, load_manifest
from harness.sweep.suite import SuiteError, suite_runs
from kins.resources import REPO


def entries_from_suite(file) -> list[tuple[dict, list[str]]]:
    """(entry, planners) of every path of a suite file's [[run]] tables (corpus paths are
    described by the manifest; any other path file gets kind '-')."""
    try:
        text = Path(file).read_text()
        suite = tomllib.loads(text)
        runs = suite_runs(suite, str(file), text)
    except OSError as e:
        raise CorpusError(f"{file}: cannot read suite: {e.strerror}") from None
    except (tomllib.TOMLDecodeError, SuiteError) as e:
        raise CorpusError(f"{file}: {e}") from None
    by_file = {}
    try:
        by_file = {(CORPUS_DIR / e["file"]).resolve(): e for e in load_manifest()}
    except CorpusError:
        pass
    out = []
    for machines, paths, planners_, _max_feed, _gcode in runs:
        for m in machines:
            for p in paths:
                f = Path(p) if Path(p).is_absolute() else REPO / p
                e = by_file.get(f.resolve(), {"name": Path(p).stem, "file": str(f), "kind": "-"})
                out.append((dict(e, machine=m, file=str(f)), list(planners_)))
    return out
