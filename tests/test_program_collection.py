"""The public program collection (benchmarks/paths/programs/collection.toml): CAM programs of
many generators, each read by LinuxCNC 2.9's interpreter and ours with the collection's tool
table. A program LinuxCNC reads gives the same canonical moves, feeds included (1e-9 mm against
its full-precision module, rs274's 4 decimals where that module cannot run); one it refuses we
refuse at the same line; one using a construct not implemented yet (canned cycles, probing) is
refused naming the construct and its line — or, once implemented, gives the same moves.

The program files live in benchmarks/paths/programs/collection/ or ../shared/programs/collection/
(see the programs README); without them only the manifest is checked."""
import hashlib
import re
import tomllib
from pathlib import Path

import pytest

from planners.paths.gcode.rs274 import RS274Error, interpret
from planners.paths.gcode.rs274.interp import _read_text
from planners.paths.gcode.rs274.reference import (RS274_DECIMALS_TOL, available, compare, linuxcnc_moves,
                                                  rs274_moves)
from planners.paths.gcode.rs274.setup import make_setup

ROOT = Path(__file__).resolve().parents[1]
PROGRAMS = ROOT / "benchmarks/paths/programs"
MANIFEST = tomllib.loads((PROGRAMS / "collection.toml").read_text())
ENTRIES = MANIFEST["program"]
LICENCES = {"GPL-2.0", "GPL-2.0-or-later", "GPL-3.0", "Apache-2.0"}       # each allows redistribution
DIR = next((d for d in (PROGRAMS / "collection", ROOT.parent / "shared/programs/collection")
            if (d / ENTRIES[0]["file"]).is_file()), None)
WHY = available()


def test_manifest_names_source_licence_and_expectation_of_every_program():
    files = [e["file"] for e in ENTRIES]
    assert len(files) == len(set(files)) >= 40
    named = {e["generator"] for e in ENTRIES if not e["generator"].startswith(("unknown", "hand-written"))}
    assert len(named) >= 10, named
    for e in ENTRIES:
        assert re.fullmatch(r"[0-9a-f]{40}", e["commit"]) and re.fullmatch(r"[0-9a-f]{64}", e["sha256"]), e
        assert e["licence"] in LICENCES and e["repository"].count("/") == 1 and e["path"], e
        assert e["expect"] in ("same", "refused", "construct"), e
    assert any(e["lines"] > 5000 and e["expect"] == "same" for e in ENTRIES)


needs_files = pytest.mark.skipif(DIR is None, reason="the collection's files are not here (programs README)")


@needs_files
def test_files_are_the_published_ones():
    bad = [e["file"] for e in ENTRIES if hashlib.sha256((DIR / e["file"]).read_bytes()).hexdigest() != e["sha256"]]
    assert not bad


@needs_files
@pytest.mark.skipif(WHY is not None, reason=str(WHY))
@pytest.mark.parametrize("e", ENTRIES, ids=[e["file"] for e in ENTRIES])
def test_program_reads_as_linuxcnc_reads_it(e):
    f = DIR / e["file"]
    setup = make_setup(PROGRAMS / MANIFEST["tool_table"])
    if e["expect"] == "refused":
        _, end = rs274_moves(f, setup=setup)
        assert end["error"] and e["linuxcnc_error"] in end["error"]
        with pytest.raises(RS274Error) as err:
            interpret(_read_text(str(f)), str(f), setup=setup)
        assert err.value.line == e["line"] and e["ours"] in err.value.message
        return
    ref, end = linuxcnc_moves(f, setup=setup, timeout=600)
    assert end["error"] == e.get("linuxcnc_end") or e.get("linuxcnc_end", "?") in (end["error"] or "")
    tol = RS274_DECIMALS_TOL if end.get("decimals") else 1e-9
    try:
        ours = interpret(_read_text(str(f)), str(f), setup=setup).moves
    except RS274Error as err:
        # a construct not implemented yet: refused by name, at its first line
        assert e["expect"] == "construct", f"{f}: {err}"
        code, line = next(iter(e["constructs"].items()))
        assert (err.line, code) == (line, err.message.split()[0]), err
        return
    assert compare(ours, ref, tol, feeds=True) is None
    assert len(ours) == len(ref) > 0
