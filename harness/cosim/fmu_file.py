"""An FMU file: whether it is one this platform can load, and the error of a system that
cannot be built (harness.cosim.system re-exports both; harness.cosim.blocks checks user FMUs
with them without importing the system)."""
from __future__ import annotations

import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path


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
