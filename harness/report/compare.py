"""Figure CSVs of two `pkmbench figures` runs compared: byte for byte (the same-machine
contract) or within the cross-machine contract (each cell within rel × its column's largest value)."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def _read_csv(f: Path) -> tuple[list[str], list[list[str]]]:
    lines = f.read_text().splitlines()
    return lines[0].split(","), [ln.split(",") for ln in lines[1:]]


def csv_difference(a: Path, b: Path, rel: float) -> str | None:
    """Why CSV b is not a's within the contract (None when it is): the same header and shape,
    non-numeric cells equal, each numeric cell within rel × the largest magnitude in a's columns
    of its quantity (jerk_x, jerk_y, jerk_z: 'jerk'). A third difference at T magnifies a
    last-bit change of a position by 1/T³, so the scale that matters is the quantity's: a
    column that is zero but for round-off (jerk_z of a flat path) has none of its own."""
    ha, ra = _read_csv(a)
    hb, rb = _read_csv(b)
    if ha != hb:
        return f"header differs: {','.join(hb)}"
    if len(ra) != len(rb) or any(len(x) != len(y) for x, y in zip(ra, rb)):
        return f"shape differs: {len(rb)} rows against {len(ra)}"
    numeric: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for j, name in enumerate(ha):
        col_a, col_b = [r[j] for r in ra], [r[j] for r in rb]
        try:
            va = np.array([float(x) if x else np.nan for x in col_a])
            vb = np.array([float(x) if x else np.nan for x in col_b])
        except ValueError:
            if col_a != col_b:
                k = next(i for i, (x, y) in enumerate(zip(col_a, col_b)) if x != y)
                return f"column {name}, row {k + 2}: {col_b[k]!r} against {col_a[k]!r}"
            continue
        if not np.array_equal(np.isnan(va), np.isnan(vb)):
            return f"column {name}: empty cells differ"
        numeric[name] = (va, vb)
    scale: dict[str, float] = {}
    for name, (va, _) in numeric.items():
        q = name.rsplit("_", 1)[0]
        scale[q] = max(scale.get(q, 0.0), float(np.nanmax(np.abs(va), initial=0.0)))
    for name, (va, vb) in numeric.items():
        sc = scale[name.rsplit("_", 1)[0]]
        diff = np.nan_to_num(np.abs(vb - va))
        k = int(np.argmax(diff)) if len(diff) else 0
        if len(diff) and diff[k] > rel * sc:
            return (f"column {name}, row {k + 2}: {float(vb[k])!r} against {float(va[k])!r} "
                    f"(|Δ| {diff[k]:.3g} > {rel:g} × {sc:.6g})")
    return None


def compare_csvs(out: Path, ref: Path, rel: float = 0.0) -> int:
    """Every figure CSV under out against the same file under ref: byte for byte (rel = 0) or
    within the cross-machine contract of docs/REPRODUCIBILITY.md."""
    bad = []
    files = sorted(out.rglob("*.csv"))
    for f in files:
        g = ref / f.relative_to(out)
        if not g.exists():
            bad.append(f"{g}: missing")
        elif g.read_bytes() != f.read_bytes():
            why = csv_difference(g, f, rel) if rel > 0 else "differs byte for byte"
            if why:
                bad.append(f"{f.relative_to(out)}: {why}")
    how = "byte for byte" if rel == 0 else f"within {rel:g} × each quantity's largest value"
    print(f"compared {len(files)} CSVs with {ref} ({how}): " + ("all agree" if not bad else f"{len(bad)} differ"))
    for b in bad:
        print("  " + b)
    return 1 if bad else 0
