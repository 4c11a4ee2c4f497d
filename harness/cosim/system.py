"""The co-simulation system of one run, and its standard form: SSP.

DESIGN.md chain, every servo period T:
  Interpolator ─x,y,z─► Kinematics (IK) ─q_cmd─► EtherCAT ─q_target, sync_ok─► Drive ×3
  Drive position ─q_act─► Kinematics (FK)
A run writes its system as ``SystemStructure.ssd`` (SSP 1.0) and the harness runs what it reads
back from that file, so other SSP tools load the same system. Each component carries its start
values in its own ``ParameterBinding`` (inline ``ssv:ParameterSet``, names as in the FMU): OSP
libcosim applies only component-level bindings, FMPy's ``read_ssd`` parses them too.
The folder is self-contained, as an unzipped .ssp: the FMUs are copied to ``resources/`` and
every path in the file that lies in the folder is relative to it, so the folder can be moved,
or zipped into an .ssp for ``fmpy.ssp``. A master other than the harness resolves those
relative file names from its working folder (an FMU opens files from the process's folder), so
it runs in the SSP's folder (``harness.cosim.libcosim``). (A latency ``histogram_file`` outside
the folder stays absolute.)
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

from harness.cosim.blocks import check_blocks, check_user_fmu, user_start
from harness.cosim.drive_params import drive_start_values, ethercat_start_values
from harness.cosim.fmu_file import SystemError_, fmu_problem
from kins.resources import FMU_DIR, REPO

NS = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
      "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
      "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues"}


# SSP 1.0 connector types of the FMI 3.0 types the chain uses (FMI 2.0 names are SSP's own)
SSP_TYPE = {"Float64": "Real", "Int32": "Integer"}

# String parameters that name files: relative to the .ssd's folder when they lie in it
FILE_PARAMS = ("path_file", "profile_file", "histogram_file", "histogram_out")


@dataclass
class Component:
    name: str
    fmu: Path                                   # the .fmu file
    start: dict = field(default_factory=dict)   # variable name → start value
    period_steps: int = 1                       # stepped every k-th macro step


@dataclass
class Connection:
    src: str
    src_var: str
    dst: str
    dst_var: str


@dataclass
class System:
    components: list[Component]                 # also the Gauss–Seidel order
    connections: list[Connection]
    step_size: float
    stop_time: float

    def component(self, name: str) -> Component:
        for c in self.components:
            if c.name == name:
                return c
        raise SystemError_(f"no component '{name}' in the system")


CHAIN_FMUS = ("Interpolator", "Kinematics", "EtherCAT", "Drive")


def _shown(f: Path) -> Path:
    return f.relative_to(REPO) if f.is_relative_to(REPO) else f


def check_fmu(fmu: Path, model: str | None = None) -> Path:
    """``fmu`` if it is a loadable FMU (:func:`fmu_problem`), else SystemError_ in one line:
    the file, what is wrong and the command that rebuilds it."""
    fmu = Path(fmu)
    if not fmu.is_file():
        raise SystemError_(f"{_shown(fmu)}: FMU file not found (build with 'make fmus')")
    try:
        why = fmu_problem(fmu, model)
    except OSError as e:
        why = f"cannot read it: {e.strerror}"
    if why:
        raise SystemError_(f"{_shown(fmu)}: not a valid FMU ({why}); rebuild with 'make fmus'")
    return fmu


def fmu_file(name: str) -> Path:
    f = FMU_DIR / f"{name}.fmu"
    if not f.exists():
        raise SystemError_(f"{_shown(f)} is missing: build the FMUs with 'make fmus' "
                           f"(or '.venv/bin/python fmus/build.py {name}')")
    return check_fmu(f, name)


def check_chain_fmus() -> None:
    """SystemError_ naming the first FMU of the chain that is missing or corrupt."""
    for name in CHAIN_FMUS:
        fmu_file(name)


def kinematics_start(machine) -> dict:
    """Kinematics.fmu parameters from a machine (kins.Kinematics)."""
    fam = {"keops": "keops", "lineardelta": "lineardelta", "pn101": "pn101"}[machine.family]
    start = {"machine": fam, "q_min": machine.q_min, "q_max": machine.q_max}
    start.update({k: float(v) for k, v in machine.params.items()})
    return start


def chain(machine, path_file: Path, profile_file: Path, duration_s: float, *, seed: int = 0,
          jitter: str | None = None, ideal: bool = False, histogram_out: str = "",
          fmus: dict | None = None) -> System:
    """The DESIGN.md chain for one feed profile on ``machine``.

    ``fmus``: {block: user .fmu} replacing our Interpolator / Kinematics / EtherCAT / Drive
    (harness.cosim.blocks: checked against the block's interface; it gets the start values it
    has variables for).

    ``ideal``: zero-jitter bus, no transport delay and ideal drives (position = target), so the
    chain must reproduce the commanded joint trajectory exactly (a test).
    """

    T = machine.servo_period_s
    comps = [
        Component("interpolator", fmu_file("Interpolator"),
                  {"path_file": str(path_file), "profile_file": str(profile_file), "T": T}),
        Component("kinematics", fmu_file("Kinematics"), kinematics_start(machine)),
    ]
    if ideal:
        bus = {"cycle_s": T, "distribution": "none", "delay_cycles": 0}
        drive = {"ideal": True}
    else:
        bus = ethercat_start_values(machine, histogram_out=histogram_out, seed=seed)
        if jitter == "none":          # an ideal bus clock, the rest of the machine's bus as is
            bus.update(preset="", distribution="none")
        elif jitter:
            bus["preset"] = jitter
        drive = drive_start_values(machine)
    comps.append(Component("ethercat", fmu_file("EtherCAT"), bus))
    for k in (1, 2, 3):
        comps.append(Component(f"drive{k}", fmu_file("Drive"), dict(drive)))
    conns = [Connection("interpolator", a, "kinematics", f"{a}_cmd") for a in "xyz"]
    for k in (1, 2, 3):
        conns += [Connection("kinematics", f"q{k}_cmd", "ethercat", f"q{k}_cmd"),
                  Connection("ethercat", f"q{k}_target", f"drive{k}", "target"),
                  Connection("ethercat", f"sync_ok{k}", f"drive{k}", "sync_ok"),
                  Connection(f"drive{k}", "position", "kinematics", f"q{k}_act")]
    if fmus:
        check_blocks(fmus)
        for comp in comps:
            block = comp.fmu.stem
            if block in fmus:
                comp.fmu = check_user_fmu(block, fmus[block])
                comp.start = user_start(comp.fmu, comp.start)
    return System(comps, conns, T, duration_s)


# -- SSP ---------------------------------------------------------------------------------
def _type_of(value) -> str:
    if isinstance(value, bool):
        return "Boolean"
    if isinstance(value, int):
        return "Integer"
    if isinstance(value, float):
        return "Real"
    return "String"


def _start_text(var: str, value, out_dir: Path) -> tuple[str, str]:
    """(ssv type, value attribute) of one start value; a file inside the folder becomes relative
    to it, one outside absolute (read_ssp's rule)."""
    t = _type_of(value)
    if var in FILE_PARAMS and value:
        f = Path(value).resolve()
        value = f.relative_to(out_dir.resolve()).as_posix() if f.is_relative_to(out_dir.resolve()) else str(f)
    return t, (("true" if value else "false") if t == "Boolean" else repr(value) if t == "Real" else str(value))


def write_ssp(system: System, out_dir: Path) -> Path:
    """Write SystemStructure.ssd: components with their connectors and start values,
    connections, experiment. Returns its path."""
    import shutil

    from fmpy import read_model_description

    out_dir = Path(out_dir)
    resources = out_dir / "resources"
    resources.mkdir(parents=True, exist_ok=True)
    for ns in NS:
        ET.register_namespace(ns, NS[ns])
    q = lambda ns, tag: f"{{{NS[ns]}}}{tag}"  # noqa: E731
    root = ET.Element(q("ssd", "SystemStructureDescription"), {"version": "1.0", "name": "pkmbench"})
    sysel = ET.SubElement(root, q("ssd", "System"), {"name": "chain"})
    elements = ET.SubElement(sysel, q("ssd", "Elements"))
    used = {(c.src, c.src_var) for c in system.connections} | {(c.dst, c.dst_var) for c in system.connections}
    for comp in system.components:
        md = read_model_description(str(comp.fmu), validate=False)
        variables = {v.name: v for v in md.modelVariables}
        local = resources / Path(comp.fmu).name
        if not local.exists() or local.resolve() != Path(comp.fmu).resolve():
            shutil.copyfile(comp.fmu, local)
        el = ET.SubElement(elements, q("ssd", "Component"),
                           {"name": comp.name, "type": "application/x-fmu-sharedlibrary",
                            "source": f"resources/{local.name}"})
        if comp.period_steps != 1:
            el.set("description", f"period_steps={comp.period_steps}")
        cons = ET.SubElement(el, q("ssd", "Connectors"))
        for (cn, var) in sorted(v for v in used if v[0] == comp.name):
            if var not in variables:
                raise SystemError_(f"{comp.fmu.name} has no variable '{var}' (component {comp.name})")
            v = variables[var]
            c = ET.SubElement(cons, q("ssd", "Connector"), {"name": var, "kind": v.causality})
            ET.SubElement(c, q("ssc", SSP_TYPE.get(v.type, v.type)))
        if comp.start:
            binding = ET.SubElement(ET.SubElement(el, q("ssd", "ParameterBindings")), q("ssd", "ParameterBinding"))
            pset = ET.SubElement(ET.SubElement(binding, q("ssd", "ParameterValues")), q("ssv", "ParameterSet"),
                                 {"version": "1.0", "name": "start values"})
            params = ET.SubElement(pset, q("ssv", "Parameters"))
        for var, value in comp.start.items():
            if var not in variables:
                raise SystemError_(f"{comp.fmu.name} has no parameter '{var}' (component {comp.name})")
            t, text = _start_text(var, value, out_dir)
            ET.SubElement(ET.SubElement(params, q("ssv", "Parameter"), {"name": var}), q("ssv", t), {"value": text})
    conns = ET.SubElement(sysel, q("ssd", "Connections"))
    for c in system.connections:
        ET.SubElement(conns, q("ssd", "Connection"), {"startElement": c.src, "startConnector": c.src_var,
                                                      "endElement": c.dst, "endConnector": c.dst_var})
    de = ET.SubElement(root, q("ssd", "DefaultExperiment"), {"startTime": "0", "stopTime": repr(system.stop_time)})
    ann = ET.SubElement(ET.SubElement(de, q("ssd", "Annotations")), q("ssc", "Annotation"),
                        {"type": "org.pkmbench.master"})
    ET.SubElement(ann, "FixedStepMaster", {"stepSize": repr(system.step_size)})
    ET.indent(root)
    ssd = out_dir / "SystemStructure.ssd"
    ET.ElementTree(root).write(ssd, xml_declaration=True, encoding="UTF-8")
    # earlier versions kept the start values in a separate file; one left here would contradict the .ssd
    (out_dir / "SystemStructure.ssv").unlink(missing_ok=True)
    return ssd


def read_ssp(ssd: Path) -> System:
    """Read back a system written by :func:`write_ssp` (the harness runs this)."""
    ssd = Path(ssd)
    try:
        root = ET.parse(ssd).getroot()
        sysel = root.find("ssd:System", NS)
        comps = []
        for el in sysel.find("ssd:Elements", NS).findall("ssd:Component", NS):
            k = 1
            desc = el.get("description") or ""
            if desc.startswith("period_steps="):
                k = int(desc.split("=", 1)[1])
            comp = Component(el.get("name"), ssd.parent / el.get("source"), {}, k)
            for p in el.findall("ssd:ParameterBindings/ssd:ParameterBinding/ssd:ParameterValues/"
                                "ssv:ParameterSet/ssv:Parameters/ssv:Parameter", NS):
                comp.start[p.get("name")] = _start_value(p, ssd.parent)
            comps.append(comp)
        conns = [Connection(c.get("startElement"), c.get("startConnector"), c.get("endElement"), c.get("endConnector"))
                 for c in sysel.find("ssd:Connections", NS).findall("ssd:Connection", NS)]
        de = root.find("ssd:DefaultExperiment", NS)
        step = float(de.find(".//FixedStepMaster").get("stepSize"))
        stop = float(de.get("stopTime"))
    except (ET.ParseError, AttributeError, KeyError, ValueError, TypeError) as e:
        raise SystemError_(f"{ssd}: not a pkmbench SSP system ({type(e).__name__}: {e})") from None
    return System(comps, conns, step, stop)


def _start_value(p: ET.Element, folder: Path):
    """The value of one ssv:Parameter; a relative file name is made absolute from ``folder``
    (the FMUs open files from the process's folder)."""
    (val_el,) = list(p)
    tag = val_el.tag.split("}")[1]
    raw = val_el.get("value")
    if tag == "String" and p.get("name") in FILE_PARAMS and raw and not Path(raw).is_absolute():
        return str(folder / raw)
    return (raw == "true" if tag == "Boolean" else int(raw) if tag == "Integer"
            else float(raw) if tag == "Real" else raw)
