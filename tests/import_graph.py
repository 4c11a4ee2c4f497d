"""The project's import graph, read with ast (every import, at module level or inside a function).

    python tests/import_graph.py          # prints every import cycle and every layer violation

Rules it checks (tests/test_layers.py asserts them):
- layers: kins ← planners ← harness; a layer imports only those below it;
- planner families (planners/trapezoid, scurve, pso, optimal, linuxcnc) import the shared
  vocabulary (planners.profile, constraints, verify, feed, registry, errors), planners.paths,
  their own modules and another family's package (its ``__init__``: ``plan``) only —
  the exceptions are FAMILY_EXCEPTIONS, each with its reason;
- no private name (``_x``) crosses a package: not imported, not read as a module attribute;
- no import cycle between modules.
"""
from __future__ import annotations

import ast
import sys
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
LAYERS = {"kins": 0, "planners": 1, "harness": 2}
FAMILIES = ("trapezoid", "scurve", "pso", "optimal", "linuxcnc")
SHARED = ("profile", "constraints", "verify", "feed", "registry", "errors", "paths")
# (importing family, imported module) → why it may reach inside another family
FAMILY_EXCEPTIONS = {
    ("pso", "planners.optimal.topp3"): "pso_socp polishes the swarm with optimal's TOPP3-SOCP engine",
}


@dataclass(frozen=True)
class Import:
    file: str
    line: int
    source: str        # importing module
    target: str        # the deepest project module the import names
    names: tuple       # names imported from it (from … import a, b)
    local: bool        # inside a function


def module_name(root: Path, f: Path) -> str:
    parts = list(f.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _is_module(root: Path, name: str) -> bool:
    p = root / name.replace(".", "/")
    return p.with_suffix(".py").is_file() or (p / "__init__.py").is_file()


def _files(root: Path):
    for top in LAYERS:
        yield from sorted((root / top).rglob("*.py"))


def _walk(tree):
    """(node, inside a function) for every node."""
    stack = [(tree, False)]
    while stack:
        node, local = stack.pop()
        yield node, local
        inner = local or isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
        stack.extend((c, inner) for c in ast.iter_child_nodes(node))


def imports(root: Path = REPO):
    """Every import of a project module under root, with what it binds (for attribute checks)."""
    out, bound = [], {}
    for f in _files(root):
        mod = module_name(root, f)
        pkg = mod if f.name == "__init__.py" else mod.rpartition(".")[0]
        tree = ast.parse(f.read_text(), str(f))
        names = bound.setdefault(mod, {})
        for node, local in _walk(tree):
            if isinstance(node, ast.Import):
                for a in node.names:
                    if a.name.split(".")[0] in LAYERS:
                        out.append(Import(str(f.relative_to(root)), node.lineno, mod, a.name, (), local))
                        names[a.asname or a.name.split(".")[0]] = a.name if a.asname else a.name.split(".")[0]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = pkg.split(".")[: len(pkg.split(".")) - (node.level - 1)]
                    base = ".".join(up + ([base] if base else []))
                if base.split(".")[0] not in LAYERS:
                    continue
                plain = []
                for a in node.names:
                    sub = f"{base}.{a.name}"
                    if _is_module(root, sub):       # `from pkg import module`: an edge to the module
                        out.append(Import(str(f.relative_to(root)), node.lineno, mod, sub, (), local))
                        names[a.asname or a.name] = sub
                    else:
                        plain.append(a.name)
                if plain:
                    out.append(Import(str(f.relative_to(root)), node.lineno, mod, base, tuple(plain), local))
    return out, bound


def package_of(root: Path, name: str) -> str:
    return name if (root / name.replace(".", "/") / "__init__.py").is_file() else name.rpartition(".")[0]


def _family(mod: str) -> str | None:
    parts = mod.split(".")
    return parts[1] if len(parts) > 1 and parts[0] == "planners" and parts[1] in FAMILIES else None


def violations(root: Path = REPO) -> list[str]:
    """Every upward import, cross-family reach and private name crossing a package under root."""
    found, bound = imports(root)
    out = []
    for i in found:
        where = f"{i.file}:{i.line}"
        top = i.source.split(".")[0]
        if LAYERS[i.target.split(".")[0]] > LAYERS[top]:
            out.append(f"{where}: {top} imports {i.target} (a higher layer)")
        src_pkg, dst_pkg = package_of(root, i.source), package_of(root, i.target)
        crosses = src_pkg != dst_pkg and not src_pkg.startswith(dst_pkg + ".")
        if crosses:
            out += [f"{where}: imports private {n} from {i.target}" for n in i.names
                    if n.startswith("_") and not n.startswith("__")]
            if i.target.rpartition(".")[2].startswith("_") and not i.target.endswith("__"):
                out.append(f"{where}: imports private module {i.target}")
        fam, fam_to = _family(i.source), _family(i.target)
        if fam and fam_to and fam != fam_to and i.target != f"planners.{fam_to}" \
                and (fam, i.target) not in FAMILY_EXCEPTIONS:
            out.append(f"{where}: family {fam} reaches into {i.target} (import planners.{fam_to} only)")
    # a private attribute of a module of another package: `mod._x`
    for f in _files(root):
        mod = module_name(root, f)
        names = bound.get(mod, {})
        src_pkg = package_of(root, mod)
        for node in ast.walk(ast.parse(f.read_text(), str(f))):
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) \
                    and node.attr.startswith("_") and not node.attr.startswith("__") \
                    and node.value.id in names:
                dst_pkg = package_of(root, names[node.value.id])
                if src_pkg != dst_pkg and not src_pkg.startswith(dst_pkg + "."):
                    out.append(f"{f.relative_to(root)}:{node.lineno}: reads private "
                               f"{names[node.value.id]}.{node.attr}")
    return out


def cycles(root: Path = REPO) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each sorted."""
    found, _ = imports(root)
    graph: dict[str, set] = {}
    for i in found:
        if i.target != i.source:
            graph.setdefault(i.source, set()).add(i.target)
    index, low, on, stack, out = {}, {}, set(), [], []

    def strong(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(10_000)
    for v in sorted(graph):
        if v not in index:
            strong(v)
    return sorted(out)


LOCAL_IMPORTS_REASON = "# Local imports: "


def local_imports_without_reason(root: Path = REPO) -> list[str]:
    """Imports of project modules inside a function with no comment on their line or the line
    above (a local import says why it is local), in a module without a line starting with
    LOCAL_IMPORTS_REASON (the reason of all its local imports)."""
    found, _ = imports(root)
    out = []
    texts: dict[str, list[str]] = {}
    for i in found:
        if not i.local:
            continue
        lines = texts.setdefault(i.file, (root / i.file).read_text().splitlines())
        if any(line.startswith(LOCAL_IMPORTS_REASON) for line in lines):
            continue
        here, above = lines[i.line - 1], lines[i.line - 2] if i.line > 1 else ""
        if "#" not in here and not above.strip().startswith("#"):
            out.append(f"{i.file}:{i.line}: {here.strip()}")
    return sorted(set(out))


if __name__ == "__main__":
    cyc, bad, loc = cycles(), violations(), local_imports_without_reason()
    for c in cyc:
        print("cycle:", " ↔ ".join(c))
    for v in bad:
        print("violation:", v)
    for v in loc:
        print("local import without a reason:", v)
    print(f"{len(cyc)} cycles, {len(bad)} violations, {len(loc)} local imports without a reason")
    sys.exit(1 if cyc or bad else 0)
