"""Generate the toolpath corpus of benchmarks/paths/corpus/ (deterministic: re-run to rebuild).

    PYTHONPATH=. .venv/bin/python benchmarks/paths/corpus/make_corpus.py

Writes the path files (NURBS .json, G-code .ngc), manifest.json (machine, kind, source, what
makes each path hard, and measured facts: length, smallest curvature radius, Jacobian
condition range) and benchmarks/suites/corpus.toml (every planner on every corpus path).

The corpus is data to test the planners on, not material to tune them: every random path comes
from one seed (SEED + its index), every path is checked against its machine (kins'
machine.check, sampled every 0.05 mm) before it is written, and a path that does not fit is
redrawn with the next sub-seed (the attempt count is in the manifest).
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
from scipy.interpolate import make_interp_spline

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent.parent
sys.path.insert(0, str(REPO))

from kins import load_machine  # noqa: E402
from planners.paths import load_path, path_from_dict  # noqa: E402

SEED = 20190          # corpus seed: path k of the generator draws from SEED + 1000·k + attempt
PLANNERS = ["trapezoid", "scurve", "scurve_joint", "pso", "toppra", "optimal", "copp"]

# --- the literature curve ---------------------------------------------------------------
# The "butterfly": a degree-3 NURBS with 51 control points, non-uniform knots and weights
# 1…5, the test curve of many CNC NURBS-interpolation papers. Values as published in the
# code of github.com/aygxywlw/CNC-NURBS-Interpolation, butterfly_nurbsinterp.cpp
# (commit 990275a061669c934c1c4ad59637b3a9e1f354c4), units mm.
BUTTERFLY_SOURCE = ("butterfly NURBS of the CNC NURBS-interpolation literature (51 control points, "
                    "degree 3), control points/knots/weights from github.com/aygxywlw/CNC-NURBS-"
                    "Interpolation butterfly_nurbsinterp.cpp @990275a0; scaled and placed here")
BUTTERFLY_XY = [
    (54.493, 52.139), (55.507, 52.139), (56.082, 49.615), (56.780, 44.971), (69.575, 51.358),
    (77.786, 58.573), (90.526, 67.081), (105.973, 63.801), (100.400, 47.326), (94.567, 39.913),
    (92.369, 30.485), (83.440, 33.757), (91.892, 28.509), (89.444, 20.393), (83.218, 15.446),
    (87.621, 4.830), (80.945, 9.267), (79.834, 14.535), (76.074, 8.522), (70.183, 12.550),
    (64.171, 16.865), (59.993, 22.122), (55.680, 36.359), (56.925, 24.995), (59.765, 19.828),
    (54.493, 14.940), (49.220, 19.828), (52.060, 24.994), (53.305, 36.359), (48.992, 22.122),
    (44.814, 16.865), (38.802, 12.551), (32.911, 8.521), (29.152, 14.535), (28.040, 9.267),
    (21.364, 4.830), (25.768, 15.447), (19.539, 20.391), (17.097, 28.512), (25.537, 33.750),
    (16.602, 30.496), (14.199, 39.803), (8.668, 47.408), (3.000, 63.794), (18.465, 67.084),
    (31.197, 58.572), (39.411, 51.358), (52.204, 44.971), (52.904, 49.614), (53.478, 52.139),
    (54.492, 52.139)]
BUTTERFLY_KNOTS = [
    0.0, 0.0, 0.0, 0.0, 0.008286, 0.014978, 0.036118, 0.085467, 0.129349, 0.150871, 0.193075,
    0.227259, 0.243467, 0.256080, 0.269242, 0.288858, 0.316987, 0.331643, 0.348163, 0.355261,
    0.364853, 0.383666, 0.400499, 0.426851, 0.451038, 0.465994, 0.489084, 0.499973, 0.510862,
    0.533954, 0.548910, 0.573096, 0.599447, 0.616280, 0.635094, 0.644687, 0.651784, 0.668304,
    0.682958, 0.711087, 0.730703, 0.743865, 0.756479, 0.772923, 0.806926, 0.849130, 0.870652,
    0.914534, 0.963883, 0.985023, 0.991714, 1.0, 1.0, 1.0, 1.0]
BUTTERFLY_WEIGHTS = [
    1, 1, 1, 1.2, 1, 1, 1, 1, 1, 1, 1, 2, 1, 1, 5, 3, 1, 1.1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1,
    1, 1, 1, 1.1, 1, 3, 5, 1, 1, 2, 1, 1, 1, 1, 1, 1, 1, 1.2, 1, 1, 1]

# Where each machine's paths go (mm): the centre of its box, the usable half-widths (kossel:
# above z ≈ −150 its box corners exceed the joints' 25 mm top, so its z range stops at −165).
FRAME = {
    "keops": {"centre": (0.0, 0.0, -400.0), "half": (95.0, 95.0, 95.0)},
    "kossel": {"centre": (0.0, 0.0, -250.0), "half": (47.0, 47.0, 80.0)},
    "linuxcnc_delta": {"centre": (0.0, 0.0, 0.0), "half": (76.0, 76.0, 95.0)},
}
# programmed feeds (mm/min): at or above each machine's F_max, so the planners, not F, set the pace
FEED = {"keops": 60000.0, "kossel": 1200.0, "linuxcnc_delta": 18000.0}


# --- helpers ----------------------------------------------------------------------------
def nurbs_dict(P, knots, weights, degree=3) -> dict:
    return {"type": "nurbs", "units": "mm", "degree": int(degree),
            "knots": [float(k) for k in knots],
            "control_points": [[float(x) for x in p] for p in np.asarray(P, float)],
            "weights": [float(w) for w in weights]}


def place(P, machine, fill=1.0, centre=None, tilt=(0.0, 0.0)):
    """Scale points P (n, 3) uniformly to fill ``fill`` of the machine's usable box, centred,
    then tilt: z += tilt · (x, y) about the centre (a NURBS maps onto a plane exactly)."""
    f = FRAME[machine]
    c = np.array(centre if centre is not None else f["centre"], float)
    half = np.array(f["half"], float) * fill
    P = np.asarray(P, float)
    mid = 0.5 * (P.min(axis=0) + P.max(axis=0))
    ext = 0.5 * (P.max(axis=0) - P.min(axis=0))
    with np.errstate(divide="ignore"):
        k = np.min(np.where(ext > 1e-12, half / np.maximum(ext, 1e-300), np.inf))
    Q = (P - mid) * k + c
    Q[:, 2] += tilt[0] * (Q[:, 0] - c[0]) + tilt[1] * (Q[:, 1] - c[1])
    return Q


def clamped_knots(n, rng=None, degree=3, spread=0.0):
    """Clamped knots for n control points; interior knots uniform, or (rng, spread > 0) with
    spans drawn from [1 − spread, 1 + spread] — non-uniform parametrisation."""
    m = n - degree
    spans = np.ones(m) if rng is None or spread <= 0 else rng.uniform(1 - spread, 1 + spread, m)
    inner = np.cumsum(spans)[:-1] / spans.sum()
    return [0.0] * (degree + 1) + [float(x) for x in inner] + [1.0] * (degree + 1)


def random_walk(rng, n, dims=2, turn=0.9, z_sd=0.0):
    """n control points of a random walk whose heading turns by N(0, turn) rad per step (large
    turns make loops and lobes); with dims = 3 the height walks with steps N(0, z_sd)."""
    h = rng.uniform(0, 2 * math.pi)
    p = np.zeros(3)
    out = [p.copy()]
    for _ in range(n - 1):
        h += rng.normal(0.0, turn)
        step = rng.uniform(0.5, 1.5)
        p = p + np.array([step * math.cos(h), step * math.sin(h), rng.normal(0.0, z_sd) if dims == 3 else 0.0])
        out.append(p.copy())
    return np.array(out)


def add_hairpins(rng, P, count, gap_range, reach=(4.0, 12.0)):
    """Add ``count`` fingers to the control polygon: at an interior point it runs out sideways
    ``reach`` mm, across ``gap`` mm and back — a lobe whose tip turns 180° within ~gap."""
    P = [p for p in P]
    idx = sorted(rng.choice(np.arange(3, len(P) - 3), size=count, replace=False))
    for i in reversed(idx):
        a, b = P[i - 1], P[i]
        d = b - a
        d[2] = 0.0
        L = np.linalg.norm(d) or 1.0
        u = d / L
        nrm = np.array([-u[1], u[0], 0.0]) * (1 if rng.random() < 0.5 else -1)
        gap, H = rng.uniform(*gap_range), rng.uniform(*reach)
        # the points 2·gap short of the tip on both legs keep the turn's radius a fraction of
        # gap whatever the finger's length
        P[i:i + 1] = [b, b + (H - 2 * gap) * nrm, b + H * nrm, b + H * nrm + gap * u,
                      b + (H - 2 * gap) * nrm + gap * u, b + gap * u]
    return np.array(P)


def measure(path, machine, step=0.01):
    """(length, smallest curvature radius, Jacobian condition min/max) along the path, and the
    first machine.check finding (None when the path fits)."""
    L = float(path.length)
    n = int(min(200_000, max(2001, math.ceil(L / step) + 1)))
    s = np.linspace(0, L, n)
    P = path.point(s)
    kappa = np.abs(np.asarray(path.curvature(np.clip(s, 1e-9, L - 1e-9)), float))
    rmin = float(1.0 / kappa.max()) if kappa.max() > 0 else math.inf
    ss = np.linspace(0, L, int(max(2, math.ceil(L / 0.05) + 1)))
    found = machine.check(path.point(ss))
    cond = machine.condition_number(P[:: max(1, n // 5000)])
    return L, rmin, float(cond.min()), float(cond.max()), (found[0].message if found else None)


class Corpus:
    """Builds the paths in order (path k draws from SEED + 1000·k); ``out``: where the files
    go; ``only``: names to build (the others are skipped but keep their seeds)."""

    def __init__(self, out=HERE, only=None):
        self.out, self.only = Path(out), only
        self.entries = []
        self.machines = {m: load_machine(m) for m in FRAME}
        self.k = 0

    def _check(self, name, path, m):
        L, rmin, cmin, cmax, bad = measure(path, self.machines[m])
        return {"length_mm": round(L, 3), "min_radius_mm": round(rmin, 4),
                "jacobian_cond": [round(cmin, 3), round(cmax, 3)]}, bad

    def nurbs(self, name, machine, kind, source, hard, build):
        """build(rng) -> NURBS dict; redrawn (next sub-seed) until the path fits the machine."""
        self.k += 1
        if self.only is not None and name not in self.only:
            return
        for attempt in range(40):
            seed = SEED + 1000 * self.k + attempt
            rng = np.random.default_rng(seed)
            try:
                d = build(rng)
                path = path_from_dict(d, name)
            except Exception as e:              # a drawn curve with a cusp: redraw
                last = str(e)
                continue
            facts, bad = self._check(name, path, machine)
            if bad is None:
                break
            last = bad
        else:
            raise SystemExit(f"{name}: no draw fits {machine} in 40 attempts (last: {last})")
        file = f"{name}.json"
        with open(self.out / file, "w") as f:
            json.dump(d, f, indent=1)
            f.write("\n")
        self.entries.append({"name": name, "file": file, "machine": machine, "kind": kind,
                             "control_points": len(d["control_points"]), "seed": seed if source == "generated" else None,
                             "attempts": attempt + 1, "source": source if source != "generated" else
                             f"generated by make_corpus.py, seed {seed}", "hard": hard, **facts})

    def gcode(self, name, machine, kind, hard, lines_fn):
        """lines_fn(rng) -> program lines; redrawn (next sub-seed) until it fits the machine."""
        self.k += 1
        if self.only is not None and name not in self.only:
            return
        m = self.machines[machine]
        file = f"{name}.ngc"
        for attempt in range(40):
            seed = SEED + 1000 * self.k + attempt
            text = "\n".join(lines_fn(np.random.default_rng(seed))) + "\n"
            (self.out / file).write_text(text)
            path = load_path(self.out / file, home=m.home)
            facts, bad = self._check(name, path, machine)
            if bad is None:
                break
        else:
            raise SystemExit(f"{name}: no draw fits {machine} in 40 attempts (last: {bad})")
        self.entries.append({"name": name, "file": file, "machine": machine, "kind": kind,
                             "segments": len(path.segments), "seed": seed, "attempts": attempt + 1,
                             "source": f"generated by make_corpus.py, seed {seed}", "hard": hard, **facts})


# --- NURBS builders -----------------------------------------------------------------------
def butterfly(machine, fill=0.95, tilt=(0.0, 0.0)):
    P = np.array([[x, y, 0.0] for x, y in BUTTERFLY_XY])
    return lambda rng: nurbs_dict(place(P, machine, fill, tilt=tilt), BUTTERFLY_KNOTS, BUTTERFLY_WEIGHTS)


def random_nurbs(machine, n, dims=2, turn=0.9, z_sd=0.0, weights=(1.0, 1.0), spread=0.0,
                 tilt_deg=0.0, hairpins=0, gap=(0.35, 1.5), reach=(4.0, 12.0), fill=0.9, centre=None, box_fill=None):
    def build(rng):
        P = random_walk(rng, n, dims, turn, z_sd)
        if hairpins:
            # hairpins in walk units: the walk is scaled below, so convert the gap afterwards
            P = place(P, machine, fill, centre=centre)
            P = add_hairpins(rng, P, hairpins, gap, reach)
        tilt = (0.0, 0.0)
        if tilt_deg:
            a = rng.uniform(0, 2 * math.pi)
            g = math.tan(math.radians(tilt_deg))
            tilt = (g * math.cos(a), g * math.sin(a))
        if box_fill is not None:          # fill a sub-box (near the edge): scale per axis
            lo, hi = np.array(box_fill[0], float), np.array(box_fill[1], float)
            mn, mx = P.min(axis=0), P.max(axis=0)
            span = np.where(mx - mn > 1e-12, mx - mn, 1.0)
            Q = lo + (P - mn) / span * (hi - lo)
            Q[:, 2] = np.where(mx[2] - mn[2] > 1e-12, Q[:, 2], 0.5 * (lo[2] + hi[2]))
        else:
            Q = place(P, machine, fill if not hairpins else 1.0, centre=centre,
                      tilt=tilt) if not hairpins else P
            if hairpins and tilt_deg:
                c = np.array(FRAME[machine]["centre"])
                Q = Q.copy()
                Q[:, 2] += tilt[0] * (Q[:, 0] - c[0]) + tilt[1] * (Q[:, 1] - c[1])
        lw = np.log(weights)
        w = np.exp(rng.uniform(lw[0], lw[1], len(Q)))
        w[0] = w[-1] = 1.0
        return nurbs_dict(Q, clamped_knots(len(Q), rng, 3, spread), w)
    return build


def interp_curve(machine, fn, n, fill=0.9, tilt=(0.0, 0.0), centre=None):
    """A cubic B-spline interpolating fn(t) at n points (t ∈ [0, 1]): an analytic curve as a
    NURBS with n control points (weights 1)."""
    def build(rng):
        t = np.linspace(0.0, 1.0, n)
        X = np.array([fn(x) for x in t])
        X = place(X, machine, fill, centre=centre, tilt=tilt)
        spl = make_interp_spline(t, X, k=3)
        return nurbs_dict(spl.c, spl.t, np.ones(len(spl.c)))
    return build


def dense_curve(machine, fn, n, fill=0.9, tilt=(0.0, 0.0), turn_density=0.0):
    """Like interp_curve, with the n interpolation points spread by arc length and, with
    ``turn_density`` > 0, by turned angle too (a spiral's centre or a near-cusp gets its points
    where the curve turns, so the spline follows the curve there instead of cutting it)."""
    def build(rng):
        t = np.linspace(0.0, 1.0, 40 * n)
        X = np.array([fn(x) for x in t])
        d = np.linalg.norm(np.diff(X, axis=0), axis=1)
        T = np.diff(X, axis=0) / np.maximum(d, 1e-300)[:, None]
        ang = np.concatenate([[0.0], np.arccos(np.clip((T[1:] * T[:-1]).sum(axis=1), -1, 1))])
        w = d / d.sum() + turn_density * ang / max(ang.sum(), 1e-300)
        m = np.concatenate([[0.0], np.cumsum(w)])
        tt = np.interp(np.linspace(0, m[-1], n), m, t)
        P = place(np.array([fn(x) for x in tt]), machine, fill, tilt=tilt)
        spl = make_interp_spline(np.linspace(0.0, 1.0, n), P, k=3)
        return nurbs_dict(spl.c, spl.t, np.ones(len(spl.c)))
    return build


def rational_nurbs(machine, n, weights=(0.05, 20.0), degree=3, dims=3, turn=0.7, fill=0.85):
    """A smooth random control polygon with weights log-uniform over a wide range: weight
    spikes pull the curve hard towards single control points, light weights flatten it."""
    def build(rng):
        P = random_walk(rng, n, dims=dims, turn=turn, z_sd=0.6)
        Q = place(P, machine, fill)
        lw = np.log(weights)
        w = np.exp(rng.uniform(lw[0], lw[1], n))
        w[0] = w[-1] = 1.0
        return nurbs_dict(Q, clamped_knots(n, rng, degree, 0.4), w, degree)
    return build


# --- G-code builders ----------------------------------------------------------------------
def _n(x):
    s = f"{x:.4f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def contour_program(machine, n_sides=9, blend=0.02, z_levels=2, radius_frac=0.7):
    """A closed contour of lines and arcs (random radii, some tangent, most not) at a few
    depths, G64 P blends; arcs by R and by I/J, both directions."""
    c = np.array(FRAME[machine]["centre"])
    h = FRAME[machine]["half"]

    def lines(rng):
        R = radius_frac * min(h[0], h[1])
        ang = np.sort(rng.uniform(0, 2 * math.pi, n_sides))
        rad = R * rng.uniform(0.55, 1.0, n_sides)
        pts = [(c[0] + r * math.cos(a), c[1] + r * math.sin(a)) for a, r in zip(ang, rad)]
        out = ["%", f"(pkmbench corpus: {machine} contour, lines and arcs, G64 P{blend})",
               f"G21 G90 G17 G64 P{_n(blend)}",
               f"G0 X{_n(pts[0][0])} Y{_n(pts[0][1])} Z{_n(c[2])}"]
        for lev in range(z_levels):
            z = c[2] - 5.0 * lev
            out.append(f"G1 Z{_n(z)} F{_n(FEED[machine] / 4)}")
            out.append(f"F{_n(FEED[machine])}")
            for i in range(1, n_sides + 1):
                x, y = pts[i % n_sides]
                px, py = pts[i - 1]
                chord = math.hypot(x - px, y - py)
                kind = rng.integers(0, 3)
                if kind == 0:
                    out.append(f"G1 X{_n(x)} Y{_n(y)}")
                elif kind == 1:      # arc by R, bulging either way
                    r = chord / 2 * rng.uniform(1.05, 3.0)
                    out.append(f"{'G2' if rng.random() < 0.5 else 'G3'} X{_n(x)} Y{_n(y)} R{_n(r)}")
                else:                # arc by I/J: centre off the chord's midpoint
                    mx, my = (px + x) / 2, (py + y) / 2
                    nx, ny = -(y - py) / chord, (x - px) / chord
                    off = chord * rng.uniform(-1.0, 1.0)
                    out.append(f"{'G2' if rng.random() < 0.5 else 'G3'} X{_n(x)} Y{_n(y)} "
                               f"I{_n(mx + off * nx - px)} J{_n(my + off * ny - py)}")
        out += ["M2", "%"]
        return out
    return lines


def pocket_program(machine, size_frac=0.7, stepover=4.0, depths=2, blend=0.01):
    """A rectangular zig-zag pocket with a circular boss pocket after it: dense parallel
    passes with 180° turns at each end (G64 blends), ramps between depths."""
    c = np.array(FRAME[machine]["centre"])
    h = FRAME[machine]["half"]

    def lines(rng):
        ax = size_frac * h[0] * rng.uniform(0.8, 1.0)
        ay = size_frac * h[1] * rng.uniform(0.6, 0.9)
        out = ["%", f"(pkmbench corpus: {machine} zig-zag pocket + circular pocket, G64 P{blend})",
               f"G21 G90 G17 G64 P{_n(blend)}",
               f"G0 X{_n(c[0] - ax)} Y{_n(c[1] - ay)} Z{_n(c[2])}", f"F{_n(FEED[machine])}"]
        for d in range(depths):
            z = c[2] - 2.0 * (d + 1)
            out.append(f"G1 X{_n(c[0] - ax + 5)} Z{_n(z)}")        # ramp in
            out.append(f"G1 X{_n(c[0] - ax)}")
            y, k = c[1] - ay, 0
            while y <= c[1] + ay + 1e-9:
                x = c[0] + ax if k % 2 == 0 else c[0] - ax
                out.append(f"G1 X{_n(x)} Y{_n(y)}")
                y += stepover
                if y <= c[1] + ay + 1e-9:
                    out.append(f"G1 Y{_n(y)}")
                k += 1
            out.append(f"G1 X{_n(c[0] - ax)} Y{_n(c[1] - ay)}")
        # circular pocket: concentric full circles joined by short radial steps
        r0 = 0.3 * min(ax, ay)
        out.append(f"G1 X{_n(c[0] + 1.0)} Y{_n(c[1])}")
        r = 1.0
        while r < r0:
            out.append(f"G3 X{_n(c[0] + r)} Y{_n(c[1])} I{_n(-r)} J0")
            r = min(r + 0.5 * stepover, r0)
            out.append(f"G1 X{_n(c[0] + r)}")
        out.append(f"G3 X{_n(c[0] + r)} Y{_n(c[1])} I{_n(-r)} J0")
        out += ["M2", "%"]
        return out
    return lines


def helix_program(machine, radius_frac=0.6, turns=4, pitch=3.0):
    """Helical interpolation: G2 with Z and P turns down, a G3 helix of small radius back up,
    a full circle at the bottom; exact stops between them (G61)."""
    c = np.array(FRAME[machine]["centre"])
    h = FRAME[machine]["half"]

    def lines(rng):
        r = radius_frac * min(h[0], h[1]) * rng.uniform(0.8, 1.0)
        r2 = 0.15 * r
        z0 = c[2] + turns * pitch / 2
        z1 = z0 - turns * pitch
        out = ["%", f"(pkmbench corpus: {machine} helices, G61 exact stops)", "G21 G90 G17 G61",
               f"G0 X{_n(c[0] + r)} Y{_n(c[1])} Z{_n(z0)}", f"F{_n(FEED[machine])}",
               f"G2 X{_n(c[0] + r)} Y{_n(c[1])} Z{_n(z1)} I{_n(-r)} J0 P{turns}",
               f"G2 X{_n(c[0] + r)} Y{_n(c[1])} I{_n(-r)} J0",
               f"G1 X{_n(c[0] + r2)}",
               f"G3 X{_n(c[0] - r2)} Y{_n(c[1])} Z{_n(z0)} I{_n(-r2)} J0 P{turns}",
               "M2", "%"]
        return out
    return lines


def meander_program(machine, legs=12, radius=1.0, size_frac=0.8, z_step=0.0):
    """A meander: parallel G1 legs joined by tangent G2/G3 half circles of ``radius`` (tight
    U-turns, no exact stop: every join a G1 join where the curvature jumps), legs of random
    length, z stepping down ``z_step`` per leg."""
    c = np.array(FRAME[machine]["centre"])
    h = FRAME[machine]["half"]

    def lines(rng):
        width = 2 * size_frac * h[0]
        y0 = c[1] - radius * legs
        x0 = c[0] - width / 2
        z = c[2]
        out = ["%", f"(pkmbench corpus: {machine} meander, U-turns of radius {radius})",
               "G21 G90 G17 G64", f"G0 X{_n(x0)} Y{_n(y0)} Z{_n(z)}", f"F{_n(FEED[machine])}"]
        y = y0
        for k in range(legs):
            right = k % 2 == 0
            # right legs end in the last 30 % of the width, left legs in the first 30 %
            x = x0 + width * (rng.uniform(0.7, 1.0) if right else rng.uniform(0.0, 0.3))
            z = c[2] - z_step * (k + 1)
            out.append(f"G1 X{_n(x)} Z{_n(z)}" if z_step else f"G1 X{_n(x)}")
            if k < legs - 1:        # heading +x turns left (G3), heading −x turns right (G2)
                y += 2 * radius
                out.append(f"{'G3' if right else 'G2'} X{_n(x)} Y{_n(y)} I0 J{_n(radius)}")
        out += ["M2", "%"]
        return out
    return lines


def cam_program(machine, n_harm=5, step=(0.15, 0.6), blend=0.01, fill=0.85, turns=1.0, decimals=3):
    """A dense CAM-like program: a smooth closed curve (a random Fourier series, z wavy)
    written as G1 lines of 0.15…0.6 mm, coordinates rounded to ``decimals`` as a CAM post
    writes them (the rounding makes the chord directions jitter), G64 P blends."""
    c = np.array(FRAME[machine]["centre"])
    h = np.array(FRAME[machine]["half"])

    def lines(rng):
        a = rng.normal(0, 1, (n_harm, 4)) / (1 + np.arange(n_harm))[:, None] ** 1.3
        zc = rng.normal(0, 1, (3, 2))

        def curve(t):
            th = 2 * math.pi * turns * t
            x = math.cos(th) + sum(a[k, 0] * math.cos((k + 2) * th) + a[k, 1] * math.sin((k + 2) * th) for k in range(n_harm))
            y = math.sin(th) + sum(a[k, 2] * math.cos((k + 2) * th) + a[k, 3] * math.sin((k + 2) * th) for k in range(n_harm))
            z = sum(zc[k, 0] * math.cos((k + 1) * th) + zc[k, 1] * math.sin((k + 1) * th) for k in range(3))
            return np.array([x, y, 0.1 * z])

        t = np.linspace(0, 1, 20001)
        X = np.array([curve(x) for x in t])
        ext = np.abs(X - X.mean(axis=0)).max(axis=0)
        k = fill * min(h[0] / ext[0], h[1] / ext[1])
        X = (X - X.mean(axis=0)) * k + c
        X[:, 2] = c[2] + np.clip(X[:, 2] - c[2], -0.5 * h[2], 0.5 * h[2])
        seg = np.linalg.norm(np.diff(X, axis=0), axis=1)
        s = np.concatenate([[0.0], np.cumsum(seg)])
        out = ["%", f"(pkmbench corpus: {machine} CAM-like short segments {step[0]}-{step[1]} mm, G64 P{blend})",
               f"G21 G90 G17 G64 P{_n(blend)}",
               f"G0 X{X[0, 0]:.{decimals}f} Y{X[0, 1]:.{decimals}f} Z{X[0, 2]:.{decimals}f}",
               f"F{_n(FEED[machine])}"]
        pos = 0.0
        while True:
            pos += rng.uniform(*step)
            if pos >= s[-1]:
                break
            p = np.array([np.interp(pos, s, X[:, i]) for i in range(3)])
            out.append(f"G1 X{p[0]:.{decimals}f} Y{p[1]:.{decimals}f} Z{p[2]:.{decimals}f}")
        out += ["M2", "%"]
        return out
    return lines


# --- the corpus ---------------------------------------------------------------------------
def build(out=HERE, only=None) -> Corpus:
    C = Corpus(out, only)
    lit = BUTTERFLY_SOURCE
    # literature: the butterfly on each machine, flat and tilted
    C.nurbs("butterfly_keops", "keops", "nurbs-literature", lit,
            "51 control points, weights up to 5: wing lobes whose tips are tight (the feed drops "
            "to a few mm/s), many FLF minima close together", butterfly("keops"))
    C.nurbs("butterfly_keops_tilted", "keops", "nurbs-literature", lit,
            "the butterfly on a plane falling 0.4 mm/mm: accelerations get a z part, which keops's "
            "45° rails add up in one joint", butterfly("keops", 0.85, tilt=(-0.4, -0.2)))
    C.nurbs("butterfly_kossel", "kossel", "nurbs-literature", lit,
            "the butterfly scaled into kossel's 94 mm box at 1 ms: lobe tips where the feed drops "
            "to ~2 mm/s and the joint jerk of the s-curve peaks", butterfly("kossel"))
    C.nurbs("butterfly_lcnc", "linuxcnc_delta", "nurbs-literature", lit,
            "the butterfly on LinuxCNC's sim delta, tilted (z falls 0.3 mm/mm along x)",
            butterfly("linuxcnc_delta", 0.9, tilt=(0.3, 0.0)))
    # analytic curves as interpolating B-splines
    C.nurbs("rose3_keops_tilted", "keops", "nurbs-analytic",
            "3-petal rose r = cos 3θ (analytic), interpolated by a cubic B-spline",
            "passes through the centre three times (straight crossings between curved petals), "
            "on a plane tilted ~27°: every petal turn loads the joints differently",
            interp_curve("keops", lambda t: (math.cos(3 * math.pi * t) * math.cos(math.pi * t),
                                            math.cos(3 * math.pi * t) * math.sin(math.pi * t), 0.0),
                         121, 0.9, tilt=(0.4, 0.3)))
    C.nurbs("lissajous32_kossel", "kossel", "nurbs-analytic",
            "3:2 Lissajous figure x = sin 3πt, y = sin 2πt (analytic) with a linear z ramp, cubic interpolation",
            "self-crossing figure whose turns come in pairs, z ramps 40 mm: a 3-D path with "
            "curvature that never vanishes for long",
            interp_curve("kossel", lambda t: (math.sin(3 * 2 * math.pi * t + 0.5), math.sin(2 * 2 * math.pi * t),
                                             0.8 * t), 101, 0.6))
    C.nurbs("lissajous54_lcnc", "linuxcnc_delta", "nurbs-analytic",
            "5:4 Lissajous figure with a sinusoidal z (analytic), cubic interpolation",
            "dense self-crossing 3-D figure: z changes sign of slope 4 times per x period",
            interp_curve("linuxcnc_delta", lambda t: (math.sin(5 * 2 * math.pi * t + 0.3),
                                                      math.sin(4 * 2 * math.pi * t),
                                                      0.4 * math.sin(2 * math.pi * t * 3)), 241, 0.7))
    # seeded random NURBS
    gen = "generated"
    C.nurbs("rand_planar_keops", "keops", "nurbs-random", gen,
            "60 control points, flat (z = −400), heading turns N(0, 0.9) rad per point: loops and "
            "lobes, non-uniform knots", random_nurbs("keops", 60, spread=0.6))
    C.nurbs("rand_tilted_weights_keops", "keops", "nurbs-random", gen,
            "90 control points on a plane tilted 30°, weights 0.3…3 (log-uniform): weight spikes "
            "pull the curve into sharp turns", random_nurbs("keops", 90, weights=(0.3, 3.0), tilt_deg=30.0, spread=0.4, fill=0.8))
    C.nurbs("rand_3d_weights_keops", "keops", "nurbs-random", gen,
            "40 control points walking in 3-D (z steps N(0, 1)), weights 0.3…3", 
            random_nurbs("keops", 40, dims=3, z_sd=1.0, weights=(0.3, 3.0), spread=0.5))
    C.nurbs("rand_150_keops", "keops", "nurbs-random", gen,
            "150 control points, 3-D, tight heading changes (N(0, 1.4) rad): many lobes and "
            "curvature peaks in a row", random_nurbs("keops", 150, dims=3, turn=1.4, z_sd=0.5, spread=0.3))
    C.nurbs("rand_hairpin_keops", "keops", "nurbs-random", gen,
            "50 control points + 6 fingers (the polygon runs 4…12 mm out sideways, 0.35…1.5 mm "
            "across and back): 180° lobe tips of radius ~0.1…0.4 mm", random_nurbs("keops", 50, hairpins=6))
    C.nurbs("rand_edge_keops", "keops", "nurbs-random", gen,
            "80 control points in a slab along the box's low-x, low-z edge (x −95…−55, z −495…−455): "
            "the Jacobian far from the centre's",
            random_nurbs("keops", 80, dims=3, z_sd=0.7, box_fill=((-95, -95, -495), (-55, 95, -455))))
    C.nurbs("rand_3d_weights_kossel", "kossel", "nurbs-random", gen,
            "40 control points, 3-D, weights 0.3…3, non-uniform knots: the issue's seeded random 3-D NURBS kind",
            random_nurbs("kossel", 40, dims=3, z_sd=1.0, weights=(0.3, 3.0), spread=0.5))
    C.nurbs("rand_planar_kossel", "kossel", "nurbs-random", gen,
            "20 control points, flat, wide lobes", random_nurbs("kossel", 20, turn=1.1))
    C.nurbs("rand_hairpin_kossel", "kossel", "nurbs-random", gen,
            "40 control points + 5 fingers 2…6 mm long, 0.35…1 mm wide: curvature radii ~0.1 mm at 1 ms",
            random_nurbs("kossel", 40, hairpins=5, gap=(0.35, 1.0), reach=(2.0, 6.0)))
    C.nurbs("rand_edge_kossel", "kossel", "nurbs-random", gen,
            "60 control points high in kossel's box (z −185…−168) along its +y edge, where the "
            "joints approach their 25 mm top",
            random_nurbs("kossel", 60, dims=3, z_sd=0.5, box_fill=((-45, 10, -185), (45, 46, -168))))
    C.nurbs("rand_3d_lcnc", "linuxcnc_delta", "nurbs-random", gen,
            "120 control points, 3-D, weights 0.5…2", random_nurbs("linuxcnc_delta", 120, dims=3, z_sd=1.0, weights=(0.5, 2.0), spread=0.4))
    C.nurbs("rand_hairpin_lcnc", "linuxcnc_delta", "nurbs-random", gen,
            "60 control points, tilted 20°, 8 fingers 0.35…2 mm wide",
            random_nurbs("linuxcnc_delta", 60, hairpins=8, gap=(0.35, 2.0), tilt_deg=20.0))
    C.nurbs("rand_edge_lcnc", "linuxcnc_delta", "nurbs-random", gen,
            "80 control points low in the box (z −95…−70) along its +x edge",
            random_nurbs("linuxcnc_delta", 80, dims=3, z_sd=0.5, box_fill=((40, -76, -95), (76, 76, -70))))
    # G-code programs
    C.gcode("contour_keops", "keops", "gcode-contour",
            "9-sided contour of lines, R arcs and I/J arcs (mostly non-tangent joins) at 2 depths, G64 P0.02 blends",
            contour_program("keops"))
    C.gcode("contour_kossel", "kossel", "gcode-contour",
            "11-sided contour of lines and arcs, G64 P0.01 blends, F1200",
            contour_program("kossel", n_sides=11, blend=0.01, z_levels=1, radius_frac=0.6))
    C.gcode("contour_lcnc", "linuxcnc_delta", "gcode-contour",
            "13-sided contour of lines and arcs at 2 depths, G64 P0.05 blends",
            contour_program("linuxcnc_delta", n_sides=13, blend=0.05))
    C.gcode("pocket_keops", "keops", "gcode-pocket",
            "zig-zag pocket, 8 mm step-over, then a circular pocket of concentric circles; G64 P0.01",
            pocket_program("keops", size_frac=0.5, stepover=8.0, depths=1))
    C.gcode("pocket_kossel", "kossel", "gcode-pocket",
            "zig-zag pocket, 3 mm step-over (many 180° turns), circular pocket; G64 P0.01",
            pocket_program("kossel", size_frac=0.3, stepover=3.0, depths=1))
    C.gcode("pocket_lcnc", "linuxcnc_delta", "gcode-pocket",
            "zig-zag pocket, 5 mm step-over, 2 depths, circular pocket; G64 P0.005",
            pocket_program("linuxcnc_delta", size_frac=0.4, stepover=5.0, blend=0.005))
    C.gcode("helix_keops", "keops", "gcode-helix",
            "G2 helix, 4 turns × 3 mm down, a full circle, a small G3 helix back up (G61 exact stops)",
            helix_program("keops"))
    C.gcode("helix_kossel", "kossel", "gcode-helix",
            "G2/G3 helices on kossel, 2 turns × 2 mm, the small one r ≈ 2 mm",
            helix_program("kossel", radius_frac=0.35, turns=2, pitch=2.0))
    C.gcode("helix_lcnc", "linuxcnc_delta", "gcode-helix",
            "G2/G3 helices, 4 turns × 4 mm", helix_program("linuxcnc_delta", pitch=4.0))
    C.gcode("cam_dense_keops", "keops", "gcode-cam",
            "~2000 G1 lines of 0.15…0.6 mm (3 decimals) along a smooth 3-D curve, G64 P0.01",
            cam_program("keops"))
    C.gcode("cam_blend_kossel", "kossel", "gcode-cam",
            "blended short-segment program: ~900 G1 lines of 0.1…0.4 mm, G64 P0.005, the issue's "
            "'blended short-segment G-code' kind", cam_program("kossel", step=(0.1, 0.4), blend=0.005))
    C.gcode("cam_dense_lcnc", "linuxcnc_delta", "gcode-cam",
            "~1500 G1 lines of 0.2…0.5 mm along a 2-turn curve, G64 P0.02",
            cam_program("linuxcnc_delta", step=(0.2, 0.5), blend=0.02, turns=2.0))
    # issue 32: the families the corpus lacked (appended: the paths above keep their seeds)
    trefoil = lambda t: (math.sin(2 * math.pi * t) + 2 * math.sin(4 * math.pi * t),
                         math.cos(2 * math.pi * t) - 2 * math.cos(4 * math.pi * t),
                         -math.sin(6 * math.pi * t))

    def torus_knot(p, q, R=2.0, r=1.0):
        return lambda t: ((R + r * math.cos(2 * math.pi * q * t)) * math.cos(2 * math.pi * p * t),
                          (R + r * math.cos(2 * math.pi * q * t)) * math.sin(2 * math.pi * p * t),
                          r * math.sin(2 * math.pi * q * t))
    C.nurbs("trefoil_keops", "keops", "nurbs-knot", "trefoil knot x = sin t + 2 sin 2t, y = cos t − 2 cos 2t, "
            "z = −sin 3t (analytic), cubic interpolation",
            "a 3-D knot: z swings through the box's height three times per loop, so every "
            "turn loads all three joints at once", interp_curve("keops", trefoil, 181, 0.85))
    C.nurbs("torus_knot_3_5_kossel", "kossel", "nurbs-knot", "(3, 5) torus knot on a torus R = 2, r = 1 "
            "(analytic), cubic interpolation",
            "a 3-D knot winding 5 times through the torus's hole: tight helix-like turns with "
            "z reversing 10 times", interp_curve("kossel", torus_knot(3, 5), 301, 0.8))
    C.nurbs("torus_knot_2_7_lcnc", "linuxcnc_delta", "nurbs-knot", "(2, 7) torus knot on a torus R = 2, "
            "r = 0.8 (analytic), cubic interpolation",
            "a 3-D knot of 7 windings, tilted 0.3 mm/mm along y", 
            interp_curve("linuxcnc_delta", torus_knot(2, 7, 2.0, 0.8), 301, 0.85, tilt=(0.0, 0.3)))
    C.nurbs("rational_keops", "keops", "nurbs-rational", gen,
            "rational cubic, 50 control points in 3-D, weights 0.05…20 (log-uniform): weight "
            "spikes pull single points into tight turns, light weights flatten whole spans",
            rational_nurbs("keops", 50))
    C.nurbs("rational_quadratic_kossel", "kossel", "nurbs-rational", gen,
            "rational quadratic (degree 2), 40 control points, weights 0.1…10: P″ jumps at every "
            "knot (a G1 join whose jerk the drive reads at T)",
            rational_nurbs("kossel", 40, weights=(0.1, 10.0), degree=2))
    C.gcode("meander_keops", "keops", "gcode-meander",
            "meander of 14 legs joined by tangent half circles of radius 1 mm (G2/G3): 180° "
            "U-turns at full programmed F, the curvature jumping at every join",
            meander_program("keops", legs=14, radius=1.0))
    C.gcode("meander_kossel", "kossel", "gcode-meander",
            "meander of 16 legs, U-turns of radius 0.3 mm, z stepping 0.5 mm per leg",
            meander_program("kossel", legs=16, radius=0.3, size_frac=0.7, z_step=0.5))
    C.nurbs("meander_lcnc", "linuxcnc_delta", "nurbs-meander",
            "serpentine x = 0.8·sin-like square wave of 9 legs (analytic, tanh-sharpened), cubic interpolation",
            "a meander as one NURBS: 8 U-turns whose radius (~1 mm) is set by the sharpening, "
            "straight legs between",
            dense_curve("linuxcnc_delta", lambda t: (math.tanh(6 * math.sin(9 * math.pi * t)), 2 * t - 1, 0.0),
                        500, 0.85, turn_density=1.0))
    spiral = lambda turns, r_in, z=0.0: (lambda t: ((1 - (1 - r_in) * t) * math.cos(2 * math.pi * turns * t),
                                                    (1 - (1 - r_in) * t) * math.sin(2 * math.pi * turns * t),
                                                    z * t))
    C.nurbs("spiral_in_keops", "keops", "nurbs-spiral",
            "Archimedean spiral r = 1 − 0.99·t over 6 turns (analytic), inwards, cubic interpolation",
            "curvature grows towards the centre (radius ~1 mm at the end): the feed falls turn by "
            "turn, the chord-error cap takes over", dense_curve("keops", spiral(6, 0.01), 500, 0.9, turn_density=0.5))
    C.nurbs("spiral_cone_kossel", "kossel", "nurbs-spiral",
            "conical Archimedean spiral, 5 turns inwards to r = 0.02, rising 40 % of the box (analytic)",
            "3-D spiral whose radius falls to ~1 mm at the centre while z rises: curvature and "
            "the joints' mix both change along it",
            dense_curve("kossel", spiral(5, 0.02, 0.6), 500, 0.85, turn_density=0.5))
    C.nurbs("cusp_epitrochoid_keops", "keops", "nurbs-cusp",
            "epitrochoid of 5 lobes, pen at 0.95 of the rolling radius (analytic), cubic interpolation",
            "5 near-cusps: the curve almost stops turning and reverses (radius ~0.1 mm at each)",
            dense_curve("keops", lambda t: (6 * math.cos(2 * math.pi * t) - 0.95 * math.cos(12 * math.pi * t),
                                            6 * math.sin(2 * math.pi * t) - 0.95 * math.sin(12 * math.pi * t), 0.0),
                        600, 0.85, turn_density=1.0))
    C.nurbs("cusp_trochoid_lcnc", "linuxcnc_delta", "nurbs-cusp",
            "curtate trochoid x = t − 0.97 sin t, y = 1 − 0.97 cos t over 6 arches with a z ramp (analytic)",
            "6 near-cusps at the arches' feet (radius ~0.05 mm): the feed falls almost to rest "
            "and the direction reverses there",
            dense_curve("linuxcnc_delta", lambda t: (12 * math.pi * t - 0.97 * math.sin(12 * math.pi * t),
                                                     1 - 0.97 * math.cos(12 * math.pi * t), 0.3 * t),
                        600, 0.9, turn_density=1.0))
    return C


def write_suite(entries):
    lines = ["# The toolpath corpus (issue 19): every planner on every corpus path. Written by",
             "# benchmarks/paths/corpus/make_corpus.py from its manifest; run it with",
             "#   pkmbench corpus --suite benchmarks/suites/corpus.toml --out DIR",
             "# (plan + the independent check at T; heavy: pso and optimal on every path).",
             'name = "corpus"',
             'description = "every planner on every path of benchmarks/paths/corpus/ (plan + check)"', ""]
    for m in FRAME:
        files = [f"benchmarks/paths/corpus/{e['file']}" for e in entries if e["machine"] == m]
        lines += ["[[run]]", f'machine = "{m}"', "paths = ["] + [f'  "{f}",' for f in files] + \
                 ["]", "planners = [" + ", ".join(f'"{p}"' for p in PLANNERS) + "]", ""]
    (REPO / "benchmarks" / "suites" / "corpus.toml").write_text("\n".join(lines))


if __name__ == "__main__":
    C = build()
    with open(HERE / "manifest.json", "w") as f:
        json.dump({"seed": SEED, "paths": C.entries}, f, indent=1, ensure_ascii=False)
        f.write("\n")
    write_suite(C.entries)
    for e in C.entries:
        print(f"{e['name']:28s} {e['machine']:15s} {e['kind']:17s} L = {e['length_mm']:9.2f} mm  "
              f"r_min = {e['min_radius_mm']:.4g} mm  cond {e['jacobian_cond']}  attempts {e['attempts']}")
    print(f"{len(C.entries)} paths")
