"""Recorders of a run (DESIGN.md "Files a run writes"): command.csv, run.mcap, run.rrd.

All writes go to a temporary name and are renamed when complete, so an interrupted run never
leaves a file that looks finished.
"""
from __future__ import annotations

import json
import math
import os
import uuid
from contextlib import contextmanager
from pathlib import Path

import numpy as np


@contextmanager
def replacing(path: Path):
    """A temporary name beside ``path`` for the body to write; renamed to ``path`` when the body
    ends, removed if it raises (KeyboardInterrupt too). The name is unique per process and call,
    so two writers of one file never write into each other's temporary."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}-{uuid.uuid4().hex[:8]}.part")
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def atomic_write_bytes(path: Path, data: bytes) -> None:
    with replacing(path) as tmp:
        tmp.write_bytes(data)


def _clean(obj):
    """JSON-safe and NaN-free: a non-finite number becomes null (DESIGN: no NaN in results)."""
    if isinstance(obj, dict):
        return {k: _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def write_json(path: Path, obj) -> None:
    """A JSON file of a run (summary.json, timing.json, metrics.json): sorted keys, indent 2,
    NaN-free, written atomically. The one writer of these contract files."""
    atomic_write_bytes(path, (json.dumps(_clean(obj), indent=2, sort_keys=True, allow_nan=False) + "\n").encode())


def write_command_csv(path: Path, t, P, Q) -> None:
    """header t,x,y,z,q1,q2,q3 — the commanded trajectory at period T, 17 significant digits."""
    data = np.column_stack([t, P, Q])
    lines = ["t,x,y,z,q1,q2,q3"] + [",".join(f"{v:.17g}" for v in row) for row in data]
    atomic_write_bytes(Path(path), ("\n".join(lines) + "\n").encode())


def read_command_csv(path: Path) -> np.ndarray:
    return np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


# channel → (fields); every field is one recorded column, numbers in JSON
MCAP_CHANNELS = {
    "/command": ("t", "s", "feed", "x", "y", "z"),
    "/joints/command": ("t", "q1", "q2", "q3"),
    "/joints/target": ("t", "q1", "q2", "q3"),
    "/drives/actual": ("t", "q1", "q2", "q3", "v1", "v2", "v3", "i1", "i2", "i3"),
    "/drives/following_error": ("t", "e1", "e2", "e3"),
    "/bus": ("t", "lateness", "lost_frames"),
}


def write_mcap(path: Path, channels: dict[str, dict[str, np.ndarray]]) -> None:
    """All signals as JSON messages with JSON-schema channels (Foxglove reads them).

    ``channels``: topic → {field: array}; log time = t in ns (deterministic, not wall time).
    """
    from mcap.writer import Writer

    with replacing(path) as tmp, open(tmp, "wb") as f:
        w = Writer(f)
        w.start(profile="", library="pkmbench")
        for topic, cols in channels.items():
            schema = {"type": "object", "title": topic.strip("/").replace("/", "_"),
                      "properties": {k: {"type": "number"} for k in cols}}
            sid = w.register_schema(name=schema["title"], encoding="jsonschema", data=json.dumps(schema).encode())
            cid = w.register_channel(topic=topic, message_encoding="json", schema_id=sid)
            names = list(cols)
            arr = np.column_stack([np.asarray(cols[k], float) for k in names])
            for seq, row in enumerate(arr):
                ns = int(round(row[0] * 1e9))
                msg = "{" + ",".join(f'"{k}":{v!r}' for k, v in zip(names, row.tolist())) + "}"
                w.add_message(channel_id=cid, log_time=ns, data=msg.encode(), publish_time=ns, sequence=seq)
        w.finish()


def read_mcap(path: Path) -> dict[str, dict[str, np.ndarray]]:
    from mcap.reader import make_reader

    out: dict[str, dict[str, list]] = {}
    with open(path, "rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages():
            d = json.loads(message.data)
            cols = out.setdefault(channel.topic, {k: [] for k in d})
            for k, v in d.items():
                cols[k].append(v)
    return {t: {k: np.array(v) for k, v in cols.items()} for t, cols in out.items()}


def write_rrd(path: Path, machine, t, P_cmd, Q_cmd, joint_ratio_per_sample, derivs: dict, frames: int = 60) -> None:
    """rerun recording: the machine in 3D (base, carriages, rods, effector) at ``frames`` instants,
    the toolpath coloured by the worst joint-limit ratio, and joint v/a/j against their limits."""
    import rerun as rr

    rec = rr.RecordingStream("pkmbench", recording_id=f"pkmbench-{machine.name}")
    with replacing(path) as tmp:
        rec.save(str(tmp))
        # toolpath coloured green (ratio 0) → red (ratio ≥ 1)
        r = np.clip(np.asarray(joint_ratio_per_sample, float), 0, 1)
        colors = np.column_stack([255 * r, 255 * (1 - r), np.full_like(r, 40)]).astype(np.uint8)
        rec.log("machine/toolpath", rr.Points3D(P_cmd, colors=colors, radii=0.3), static=True)
        carriage, effector = machine.joint_points(P_cmd[:: max(1, len(P_cmd) // frames)])
        idx = np.arange(0, len(P_cmd), max(1, len(P_cmd) // frames))
        base = np.concatenate([carriage[:, :, :].min(axis=0), carriage.max(axis=0)])  # the rails' extent
        rec.log("machine/rails", rr.LineStrips3D([[base[k], base[k + 3]] for k in range(3)], colors=[90, 90, 90]), static=True)
        for f, i in enumerate(idx[: len(carriage)]):
            rec.set_time("t", duration=float(t[i]))
            rec.log("machine/carriages", rr.Points3D(carriage[f], radii=4.0, colors=[60, 120, 220]))
            rec.log("machine/rods", rr.LineStrips3D([[carriage[f, k], effector[f, k]] for k in range(3)], colors=[200, 200, 200]))
            rec.log("machine/effector", rr.Points3D(P_cmd[i][None], radii=5.0, colors=[230, 160, 30]))
        lim = {"velocity": machine.limits.joint.v, "acceleration": machine.limits.joint.a, "jerk": machine.limits.joint.j}
        for order, D in derivs.items():
            n = len(D)
            times = rr.TimeColumn("t", duration=np.asarray(t[-n:], float))
            for k in range(3):
                rec.send_columns(f"joints/{order}/q{k + 1}", indexes=[times], columns=rr.Scalars.columns(scalars=D[:, k]))
            rec.send_columns(f"joints/{order}/limit", indexes=[times], columns=rr.Scalars.columns(scalars=np.full(n, lim[order])))
            rec.send_columns(f"joints/{order}/-limit", indexes=[times], columns=rr.Scalars.columns(scalars=np.full(n, -lim[order])))
        rec.flush()
        rec.disconnect()
