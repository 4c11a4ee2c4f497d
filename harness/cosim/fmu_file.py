"""An FMU file: whether it is one this platform can load, and the error of a system that
cannot be built (harness.cosim.system re-exports both; harness.cosim.blocks checks user FMUs
with them without importing the system)."""
from __future__ import annotations

import hashlib
import shutil
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

from kins.resources import FMU_DIR

EXTRACT_DIR = FMU_DIR / "extracted"          # our FMUs, beside their build
# a user's FMU is unpacked outside the checkout, in a folder of its own per content
USER_EXTRACT_DIR = Path(tempfile.gettempdir()) / "pkmbench-fmus" / "extracted"


class SystemError_(ValueError):
    """A system cannot be built or read (missing FMU, malformed SSD, unknown variable)."""


def fmu_problem(fmu: Path, model: str | None = None) -> str | None:
    """Why ``fmu`` is not a loadable FMU, or None: a zip whose members pass their CRC, whose
    modelDescription.xml parses and names a co-simulation model (``model``, when given) whose
    binary for this platform is inside."""
    from fmpy import platform, platform_tuple, sharedLibraryExtension

    with open(fmu, "rb") as f:   # an unreadable file: OSError, for the caller to word
        try:
            with zipfile.ZipFile(f) as z:
                if z.testzip() is not None:
                    return "corrupt zip"
                names = set(z.namelist())
                if "modelDescription.xml" not in names:
                    return "no modelDescription.xml"
                xml = z.read("modelDescription.xml")
        except Exception:   # whatever the zip reader raises on damaged bytes (BadZipFile, zlib, lzma…)
            return "corrupt zip"
    try:
        root = ET.fromstring(xml)
    except ET.ParseError as e:
        return f"modelDescription.xml does not parse: {e}"
    cs = root.find("CoSimulation")
    ident = cs.get("modelIdentifier") if cs is not None else None
    if not ident:
        return "modelDescription.xml has no co-simulation modelIdentifier"
    if model and ident != model:
        return f"modelDescription.xml names model '{ident}', not '{model}'"
    fmi3 = (root.get("fmiVersion") or "").startswith("3.")   # FMI 3.0 names platforms as x86_64-linux
    binary = f"binaries/{platform_tuple if fmi3 else platform}/{ident}{sharedLibraryExtension}"
    if binary not in names:
        return f"no {binary}"
    return None


def is_ours(fmu: Path) -> bool:
    """Whether ``fmu`` (or a copy of it, as a run folder's resources/) is one of our built FMUs."""
    built = FMU_DIR / Path(fmu).name
    try:
        return built.is_file() and built.read_bytes() == Path(fmu).read_bytes()
    except OSError:
        return False


def unpack(fmu: Path) -> Path:
    """Unzip an FMU (already checked) once per content hash, FMUs being re-used across runs and
    processes: ours under fmus/build/extracted, a user's under the temporary folder."""
    fmu = Path(fmu)
    digest = hashlib.sha256(fmu.read_bytes()).hexdigest()[:16]
    root = EXTRACT_DIR if is_ours(fmu) else USER_EXTRACT_DIR
    target = root / f"{fmu.stem}-{digest}"
    if not (target / ".complete").exists():
        root.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(dir=root))
        try:
            with zipfile.ZipFile(fmu) as z:
                z.extractall(tmp)
            (tmp / ".complete").write_text("ok")
            try:
                tmp.rename(target)
            except OSError:   # another process got there first
                pass
        finally:   # an interrupted or failed extraction leaves no half-filled folder
            shutil.rmtree(tmp, ignore_errors=True)
    return target
