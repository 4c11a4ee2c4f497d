"""Build every FMU in fmus/: one folder per model → fmus/build/<Name>.fmu.

A model folder holds config.h, model.c (and any other .c/.h), modelDescription.xml and an
optional resources/ folder. Each model is compiled with the shared layer fmus/common/ against
the FMI 2.0 headers of the installed fmpy (fmpy/c-code), packed with binaries/linux64/<Name>.so,
its modelDescription.xml (the <SourceFiles> list is filled in here) and sources/ (flat), so
`fmpy compile` can rebuild it on another platform.

Incremental: a model is rebuilt when a hash of its inputs changes, or when its .fmu is not
the one built (its hash differs from the stamp's) or not a whole FMU (a truncated or corrupt
zip, a modelDescription.xml that does not parse or names another model, no binary). The zip
is deterministic (fixed timestamps, sorted entries): same sources ⇒ same .fmu bytes.

    python fmus/build.py [--force] [Name ...]
"""
from __future__ import annotations

import argparse
import hashlib
import os
import re
import shutil
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

FMUS = Path(__file__).resolve().parent
COMMON = FMUS / "common"
BUILD = FMUS / "build"
CFLAGS = ["-std=c11", "-O2", "-fPIC", "-Wall", "-Wextra", "-Werror", "-D_POSIX_C_SOURCE=200809L"]
CC = os.environ.get("CC", "cc")


def fmi_headers() -> Path:
    import fmpy
    return Path(fmpy.__file__).parent / "c-code"


def models() -> list[Path]:
    return sorted(p for p in FMUS.iterdir() if (p / "modelDescription.xml").exists() and (p / "model.c").exists())


def sources_of(model: Path) -> list[Path]:
    files = sorted(COMMON.glob("*.[ch]")) + sorted(model.glob("*.[ch]"))
    names = [f.name for f in files]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise SystemExit(f"fmus/build.py: {model.name}: file names clash with fmus/common: {sorted(dup)}")
    return files


def resources_of(model: Path) -> list[Path]:
    r = model / "resources"
    return sorted(p for p in r.rglob("*") if p.is_file()) if r.is_dir() else []


def input_hash(model: Path) -> str:
    h = hashlib.sha256()
    h.update(" ".join([CC] + CFLAGS).encode())
    for f in sources_of(model) + resources_of(model) + [model / "modelDescription.xml", Path(__file__)]:
        h.update(str(f.relative_to(FMUS)).encode())
        h.update(f.read_bytes())
    for f in sorted(fmi_headers().glob("fmi2*.h")):
        h.update(f.read_bytes())
    return h.hexdigest()


def model_description(model: Path, sources: list[Path]) -> str:
    """The modelDescription.xml with <SourceFiles> listing the .c files of sources/."""
    xml = (model / "modelDescription.xml").read_text()
    files = "".join(f'\n      <File name="{f.name}"/>' for f in sources if f.suffix == ".c")
    block = f"\n    <SourceFiles>{files}\n    </SourceFiles>\n  "
    xml = re.sub(r"\s*<SourceFiles>.*?</SourceFiles>\s*", "\n  ", xml, flags=re.S)
    m = re.search(r"<CoSimulation\b[^>]*?(/?)>", xml)
    if not m:
        raise SystemExit(f"fmus/build.py: {model.name}/modelDescription.xml has no <CoSimulation> element")
    if m.group(1):   # self-closing: open it
        open_tag = m.group(0)[:-2].rstrip() + ">"
        return xml[:m.start()] + open_tag + block + "</CoSimulation>" + xml[m.end():]
    return xml[:m.end()] + block + xml[m.end():]


def file_hash(f: Path) -> str:
    return hashlib.sha256(f.read_bytes()).hexdigest()


def fmu_problem(fmu: Path, name: str) -> str | None:
    """What is wrong with the built ``fmu`` of model ``name``, or None when it is a whole FMU."""
    try:
        with zipfile.ZipFile(fmu) as z:
            if z.testzip() is not None:
                return "corrupt zip"
            members = set(z.namelist())
            md = ET.fromstring(z.read("modelDescription.xml")) if "modelDescription.xml" in members else None
    except ET.ParseError as e:
        return f"modelDescription.xml does not parse: {e}"
    except Exception:   # whatever the zip reader raises on damaged bytes (BadZipFile, zlib, lzma…)
        return "corrupt zip"
    if md is None:
        return "no modelDescription.xml"
    cs = md.find("CoSimulation")
    if cs is None or cs.get("modelIdentifier") != name or md.get("modelName") != name:
        return f"modelDescription.xml does not describe model {name}"
    if f"binaries/linux64/{name}.so" not in members:
        return f"no binaries/linux64/{name}.so"
    return None


def stale_reason(out: Path, stamp: Path, digest: str) -> str | None:
    """Why ``out`` must be (re)built, or None when it is up to date. The stamp holds the input
    hash and the hash of the .fmu written, so a .fmu damaged or replaced since is rebuilt too."""
    if not out.exists():
        return "not built yet"
    if not stamp.exists():
        return "no build stamp"
    recorded = stamp.read_text().split()
    if len(recorded) != 2 or recorded[0] != digest:
        return "its sources changed"
    why = fmu_problem(out, out.stem)
    if why:
        return f"{out.name} is damaged ({why})"
    if recorded[1] != file_hash(out):
        return f"{out.name} changed since it was built"
    return None


def build(model: Path, force: bool = False) -> Path:
    name = model.name
    out = BUILD / f"{name}.fmu"
    stamp = BUILD / f"{name}.stamp"
    digest = input_hash(model)
    why = "--force" if force else stale_reason(out, stamp, digest)
    if why is None:
        print(f"  {name}.fmu is up to date")
        return out
    if out.exists():
        print(f"  rebuilding {name}.fmu: {why}")
    BUILD.mkdir(exist_ok=True)
    sources = sources_of(model)
    with tempfile.TemporaryDirectory() as tmp:
        so = Path(tmp) / f"{name}.so"
        cmd = [CC, *CFLAGS, "-shared", "-o", str(so), f"-I{fmi_headers()}", f"-I{COMMON}", f"-I{model}",
               *[str(f) for f in sources if f.suffix == ".c"], "-lm"]
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            sys.stderr.write(r.stdout + r.stderr)
            raise SystemExit(f"fmus/build.py: compiling {name} failed (command: {' '.join(cmd)})")
        entries = {
            "modelDescription.xml": model_description(model, sources).encode(),
            f"binaries/linux64/{name}.so": so.read_bytes(),
        }
        for f in sources:
            entries[f"sources/{f.name}"] = f.read_bytes()
        for f in resources_of(model):
            entries["resources/" + f.relative_to(model / "resources").as_posix()] = f.read_bytes()
        # never a half-written FMU under the final name; a per-process temporary, removed if interrupted
        part = out.with_name(f".{out.name}.{os.getpid()}.part")
        try:
            with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
                for arc in sorted(entries):
                    info = zipfile.ZipInfo(arc, date_time=(2000, 1, 1, 0, 0, 0))
                    info.external_attr = (0o755 if arc.endswith(".so") else 0o644) << 16
                    info.compress_type = zipfile.ZIP_DEFLATED
                    z.writestr(info, entries[arc])
            os.replace(part, out)
        finally:
            part.unlink(missing_ok=True)
    stamp.write_text(f"{digest} {file_hash(out)}\n")
    print(f"  built {os.path.relpath(out, FMUS.parent)}")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("names", nargs="*", help="models to build (default: all)")
    ap.add_argument("--force", action="store_true", help="rebuild even if up to date")
    a = ap.parse_args(argv)
    found = {m.name: m for m in models()}
    unknown = [n for n in a.names if n not in found]
    if unknown:
        raise SystemExit(f"fmus/build.py: unknown model(s) {unknown}; valid: {sorted(found)}")
    if shutil.which(CC) is None:
        raise SystemExit(f"fmus/build.py: C compiler '{CC}' not found (set CC)")
    print("fmus: building", ", ".join(a.names or found))
    for n in a.names or found:
        build(found[n], a.force)
    return 0


if __name__ == "__main__":
    sys.exit(main())
