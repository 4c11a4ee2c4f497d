"""The layers: kins ← planners ← harness. Every import (module level or inside a function) in
kins/, planners/ and harness/ is read with ast; a lower layer importing a higher one, or a
module importing a private name (``_x``) from another package, fails the test. The second test
plants an upward import in a copy of the tree and checks that the walk catches it.
"""
from __future__ import annotations

import ast
import shutil
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
LAYERS = {"kins": 0, "planners": 1, "harness": 2}


def _module_name(root: Path, f: Path) -> str:
    parts = list(f.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(root: Path, f: Path):
    """(line, imported module, [names]) of every import in f, relative ones made absolute."""
    mod = _module_name(root, f)
    pkg = mod if f.name == "__init__.py" else mod.rpartition(".")[0]
    for node in ast.walk(ast.parse(f.read_text(), str(f))):
        if isinstance(node, ast.Import):
            for a in node.names:
                yield node.lineno, a.name, []
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = pkg.split(".")[: len(pkg.split(".")) - (node.level - 1)]
                base = ".".join(up + ([base] if base else []))
            yield node.lineno, base, [a.name for a in node.names]


def violations(root: Path = REPO) -> list[str]:
    """Every upward import and every private name imported from another package under root."""
    out = []
    for top in LAYERS:
        for f in sorted((root / top).rglob("*.py")):
            mod = _module_name(root, f)
            pkg = mod if f.name == "__init__.py" else mod.rpartition(".")[0]
            where = f"{f.relative_to(root)}"
            for line, target, names in _imports(root, f):
                layer = LAYERS.get(target.split(".")[0])
                if layer is not None and layer > LAYERS[top]:
                    out.append(f"{where}:{line}: {top} imports {target} (a higher layer)")
                if layer is None:
                    continue
                # `from pkg.mod import _x` from outside pkg: a private name crossing a package
                target_pkg = target.rpartition(".")[0] if (root / (target.replace(".", "/") + ".py")).exists() \
                    else target
                if pkg != target_pkg and not pkg.startswith(target_pkg + "."):
                    for n in names:
                        if n.startswith("_") and not n.startswith("__"):
                            out.append(f"{where}:{line}: imports private {n} from {target}")
                if target.rpartition(".")[2].startswith("_") and not target.endswith("__") \
                        and target.rpartition(".")[0] != pkg:
                    out.append(f"{where}:{line}: imports private module {target}")
    return out


def test_no_upward_or_private_cross_package_import():
    assert violations() == []


def test_a_planted_upward_import_is_caught(tmp_path):
    for top in LAYERS:
        shutil.copytree(REPO / top, tmp_path / top, ignore=shutil.ignore_patterns("__pycache__"))
    assert violations(tmp_path) == []
    f = tmp_path / "planners" / "profile.py"
    f.write_text(f.read_text() + "\n\ndef _planted():\n    from harness.cosim.run import run_case  # noqa\n")
    g = tmp_path / "harness" / "cli" / "plan.py"
    g.write_text(g.read_text() + "\nfrom planners.scurve.planner import _Planner  # noqa\n")
    found = violations(tmp_path)
    assert any("planners/profile.py" in v and "harness.cosim.run (a higher layer)" in v for v in found), found
    assert any("harness/cli/plan.py" in v and "private _Planner" in v for v in found), found
