"""The metrics of one co-simulated profile (DESIGN.md "The metrics"): the check at T of the
commanded trajectory (planners.verify) plus what only the co-simulation shows — following
and contour error, lost frames, faulted drives.
"""
from __future__ import annotations

import numpy as np

from planners import verify as M


def measure(machine, profile, res) -> dict:
    """DESIGN.md metrics of one co-simulated profile."""
    T = machine.servo_period_s
    n = len(profile.s)                      # the commanded motion: rows 0 … n-1
    P = np.column_stack([res[f"interpolator.{a}"] for a in "xyz"])
    s = res["interpolator.s"]
    out = M.command_metrics(machine, P[:n], T, s[:n])
    Q_act = np.column_stack([res[f"drive{k}.position"] for k in (1, 2, 3)])
    Q_tgt = np.column_stack([res[f"ethercat.q{k}_target"] for k in (1, 2, 3)])
    out["max_following_error_um"] = following_error_um(Q_tgt, Q_act)
    try:
        P_act = machine.fk(Q_act)
        out["max_contour_error_um"] = contour_error_um(P_act, P)
    except Exception as e:   # an actual joint vector with no assembly: say so, no NaN
        out["max_contour_error_um"] = None
        out["contour_error_note"] = f"FK of the actual joints failed: {e}"
    geom = float(profile.info.get("geometry_deviation_mm", 0.0))
    out["max_chord_error_um"] = (M.chord_error_mm(P[:n], profile.path, s[:n]) + geom) * 1e3
    out["lost_frames"] = int(res["ethercat.lost_frames"][-1])
    out["faulted_drives"] = int(sum(res[f"drive{k}.fault"].max() > 0 for k in (1, 2, 3)))
    return out


def following_error_um(targets: np.ndarray, actual: np.ndarray) -> float:
    """Largest |joint target − actual joint position| over joints and samples, in µm."""
    d = np.abs(np.asarray(targets, float) - np.asarray(actual, float))
    return float(d.max() * 1e3) if d.size else 0.0


def contour_error_um(P_act: np.ndarray, P_cmd: np.ndarray, window: int = 50) -> float:
    """Largest distance of the actual tool points from the commanded path, in µm.

    The commanded path is the polyline of the commanded samples (its own chord error is
    reported separately); each actual point is measured against the segments within
    ``window`` samples behind and ahead of its own index, which covers any realistic lag.
    """
    P_act = np.asarray(P_act, float)
    A, B = np.asarray(P_cmd[:-1], float), np.asarray(P_cmd[1:], float)
    if len(A) == 0:
        return float(np.linalg.norm(P_act - P_cmd, axis=1).max() * 1e3)
    n = len(P_act)
    best = np.full(n, np.inf)
    idx = np.arange(n)
    for off in range(-window, window + 1):
        j = np.clip(idx + off, 0, len(A) - 1)
        a, ab = A[j], B[j] - A[j]
        L2 = np.einsum("ij,ij->i", ab, ab)
        u = np.where(L2 > 0, np.einsum("ij,ij->i", P_act - a, ab) / np.where(L2 > 0, L2, 1.0), 0.0)
        d = np.linalg.norm(P_act - (a + np.clip(u, 0, 1)[:, None] * ab), axis=1)
        np.minimum(best, d, out=best)
    return float(best.max() * 1e3)
