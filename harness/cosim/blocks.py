"""The block interface: what an FMU must offer to take the place of one block of the chain.

A user FMU (FMI 2.0 or 3.0 co-simulation, from any tool: pythonfmu, pythonfmu3, OpenModelica,
Dymola, …) replaces Interpolator, Kinematics, EtherCAT or Drive when it has every variable of
that block's interface below, by name, with that causality and type (FMI 3.0: Float64 for Real,
Int32 for Integer). Parameters the harness sets on our
block (``chain()``'s start values) are set on a user FMU only where it has a variable of that
name; the interface's ``parameter`` entries are the ones it must have. A mismatch is refused
before anything runs, in one line naming the FMU, the variable and what was expected.

    pkmbench run --machine keops --path bird --fmu Drive=mydrive.fmu
    # or in a suite:   [fmus]
    #                  Drive = "models/mydrive.fmu"

Both masters run FMI 3.0 FMUs beside our FMI 2.0 ones: the Python one through fmpy, the native
one (native_master.c) through each FMU's own C API (fmi3DoStep, fmi3GetFloat64, …).
"""
from __future__ import annotations

from pathlib import Path

from harness.cosim.fmu_file import SystemError_, fmu_problem, unpack

# block → {variable: (causality, type)}: what the chain connects and run.RECORD reads
INTERFACE = {
    "Interpolator": {"path_file": ("parameter", "String"), "profile_file": ("parameter", "String"),
                     **{v: ("output", "Real") for v in ("x", "y", "z", "s", "feed")}, "done": ("output", "Boolean")},
    "Kinematics": {**{f"{a}_cmd": ("input", "Real") for a in "xyz"},
                   **{f"q{k}_act": ("input", "Real") for k in (1, 2, 3)},
                   **{f"q{k}_cmd": ("output", "Real") for k in (1, 2, 3)}, "workspace_ok": ("output", "Boolean")},
    "EtherCAT": {**{f"q{k}_cmd": ("input", "Real") for k in (1, 2, 3)},
                 **{f"q{k}_target": ("output", "Real") for k in (1, 2, 3)},
                 **{f"sync_ok{k}": ("output", "Boolean") for k in (1, 2, 3)},
                 "lateness": ("output", "Real"), "lost_frames": ("output", "Integer")},
    "Drive": {"target": ("input", "Real"), "sync_ok": ("input", "Boolean"),
              **{v: ("output", "Real") for v in ("position", "velocity", "current", "following_error")},
              "fault": ("output", "Boolean")},
}
BLOCKS = tuple(INTERFACE)
# a parameter may also be tunable or a structural parameter (FMI 2.0 causality "parameter" covers both)
_CAUSALITY_OK = {"parameter": {"parameter", "calculatedParameter", "structuralParameter"}, "input": {"input"},
                 "output": {"output"}}
# interface type → the FMI 2.0 and 3.0 types that carry it
_TYPE_OK = {"Real": {"Real", "Float64"}, "Integer": {"Integer", "Int32"}, "Boolean": {"Boolean"}, "String": {"String"}}


def parse_fmu_args(specs) -> dict[str, Path]:
    """``["Drive=file.fmu", …]`` → {"Drive": Path}; SystemError_ on a malformed or unknown block."""
    out = {}
    for spec in specs or ():
        block, sep, f = str(spec).partition("=")
        if not sep or not f:
            raise SystemError_(f"--fmu {spec}: expected BLOCK=FILE.fmu (BLOCK one of {', '.join(BLOCKS)})")
        out[block.strip()] = Path(f.strip())
    check_blocks(out)
    return out


def command_fmus(specs=(), suite: dict | None = None, suite_file=None) -> dict[str, Path]:
    """The user FMUs of a command: a suite's ``[fmus]`` table (paths relative to the suite file)
    and ``--fmu BLOCK=FILE`` specs, which win; parsed, not yet checked (:func:`check_user_fmu`)."""
    table = (suite or {}).get("fmus", {})
    if not isinstance(table, dict) or not all(isinstance(f, str) for f in table.values()):
        raise SystemError_(f"{suite_file}: [fmus] must map a block name to an .fmu file name")
    base = Path(suite_file).parent if suite_file else Path()
    return parse_fmu_args([f"{b}={base / f}" for b, f in table.items()]) | parse_fmu_args(specs)


def check_blocks(fmus: dict) -> None:
    for block in fmus:
        if block not in INTERFACE:
            raise SystemError_(f"unknown block '{block}' for a user FMU; valid: {', '.join(BLOCKS)}")


def check_user_fmu(block: str, fmu) -> Path:
    """``fmu`` if it fits ``block``'s interface, else SystemError_ naming the FMU, the variable and
    what was expected."""
    from fmpy import read_model_description
    fmu = Path(fmu)
    if not fmu.is_file():
        raise SystemError_(f"{block} FMU {fmu}: file not found")
    try:
        md = read_model_description(str(fmu), validate=False)
    except Exception as e:
        raise SystemError_(f"{block} FMU {fmu}: not a readable FMU ({type(e).__name__}: {e})") from None
    if not str(md.fmiVersion).startswith(("2.", "3.")):
        raise SystemError_(f"{block} FMU {fmu}: FMI {md.fmiVersion}; the harness runs FMI 2.0 and 3.0 "
                           f"co-simulation FMUs")
    if md.coSimulation is None:
        raise SystemError_(f"{block} FMU {fmu}: no co-simulation interface (model exchange only)")
    why = fmu_problem(fmu) or _binary_problem(fmu, md)
    if why:
        raise SystemError_(f"{block} FMU {fmu}: not loadable here ({why})")
    have = {v.name: v for v in md.modelVariables}
    for name, (causality, typ) in INTERFACE[block].items():
        v = have.get(name)
        want = f"{causality} {typ}"
        if v is None:
            raise SystemError_(f"{block} FMU {fmu.name}: no variable '{name}' (the {block} interface needs {want})")
        if v.causality not in _CAUSALITY_OK[causality] or v.type not in _TYPE_OK[typ]:
            raise SystemError_(f"{block} FMU {fmu.name}: variable '{name}' is {v.causality} {v.type}, "
                               f"expected {want}")
    return fmu


def _binary_problem(fmu: Path, md) -> str | None:
    """Why the FMU's shared library does not load in this process (junk bytes, another
    platform's, a missing dependency), or None: found here, not in every planner's run."""
    import ctypes
    from fmpy import platform, platform_tuple, sharedLibraryExtension

    fmi3 = str(md.fmiVersion).startswith("3.")
    rel = f"binaries/{platform_tuple if fmi3 else platform}/{md.coSimulation.modelIdentifier}{sharedLibraryExtension}"
    try:
        ctypes.CDLL(str(unpack(fmu) / rel))     # the master's unpacked folder: the run loads this same file
    except OSError as e:
        return f"its binary {rel} does not load: {e}"
    return None


def user_start(fmu: Path, start: dict) -> dict:
    """The harness's start values that a user FMU has a variable for (others are our block's own)."""
    from fmpy import read_model_description
    names = {v.name for v in read_model_description(str(fmu), validate=False).modelVariables}
    return {k: v for k, v in start.items() if k in names}
