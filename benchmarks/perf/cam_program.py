"""Reproducible CAM-style G-code for the `check` benchmarks, inside the kossel workspace.

A 3-D raster finishing job as a CAM post writes it: layers 0.5 mm apart over a wavy surface
(z = −250 mm ± 2 mm, well inside kossel's X, Y ±50 mm box and below its z ≈ −150 mm corner
limit), each layer 30 rows along X from −30 to +30 mm in dense G1 steps of ~0.3 mm (jittered
by the seed), rows joined by helical G2/G3 half-circles of radius 1 mm, corners blended G64
P0.01. Same (n_lines, seed) ⇒ the same bytes.

``cycles=True``: after every CYCLE_EVERY rows, a drilling pattern between the contour moves as a
CAM post writes one: a lift, then HOLES holes on a jittered grid by canned cycles (G81, G83
pecks, G73 chip breaking in turn, G98/G99), each pattern one cycle block and then lines with
only X Y (the cycle again, modally), G80, and back down to the row.

    make_cam_program(100_000, seed=1, file="cam.ngc")    # → the text (and writes it if file=)
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

X_HALF = 30.0          # rows run X −30 … +30 mm
ROWS = 30              # rows per layer, 2 mm apart (Y −30 … +28 mm)
STEP_OVER = 2.0
STEP = 0.3             # mean G1 length along X, mm
LAYER_DZ = 0.5
Z0 = -250.0
CYCLE_EVERY = 10       # rows between drilling patterns (cycles=True): 3 a layer
HOLES = 16             # holes a pattern: 8 × 2 on a 7 × 4 mm grid, jittered
_PATTERNS = ("G98 G81 {xy} Z{z:.4f} R{r:.4f} F600", "G99 G83 {xy} Z{z:.4f} R{r:.4f} Q2 F600",
             "G98 G73 {xy} Z{z:.4f} R{r:.4f} Q1.5 F600")


def _surface(x, y, layer: int):
    return Z0 - LAYER_DZ * layer + 2.0 * np.sin(x / 7.0) * np.cos(y / 9.0)


def _drill_pattern(rng, k: int, y: float, layer: int, back: tuple) -> list[str]:
    """The k-th drilling pattern: lift, the holes (a cycle block, then X Y lines), G80, and
    back to ``back`` = (x, y, z) where the contour goes on."""
    top = Z0 - LAYER_DZ * layer + 2.0          # above the surface there (± 2 mm)
    gx, gy = np.meshgrid(np.arange(8) * 7.0 - 24.5, np.arange(2) * 4.0 - 2.0 + np.clip(y, -20.0, 20.0))
    xs = gx.ravel() + rng.uniform(-0.5, 0.5, HOLES)
    ys = gy.ravel() + rng.uniform(-0.5, 0.5, HOLES)
    out = [f"G0 Z{top + 6:.4f}"]
    out.append(_PATTERNS[k % len(_PATTERNS)].format(xy=f"X{xs[0]:.4f} Y{ys[0]:.4f}", z=top - 4.0, r=top + 1.0))
    out += [f"X{x:.4f} Y{yy:.4f}" for x, yy in zip(xs[1:], ys[1:])]
    out += ["G80", f"G0 X{back[0]:.4f} Y{back[1]:.4f}", f"G1 Z{back[2]:.4f} F600", "F1200"]
    return out


def make_cam_program(n_lines: int, seed: int = 1, file=None, cycles: bool = False) -> str:
    """A program of exactly ``n_lines`` lines (≥ 10), ending with M2 (``cycles``: with
    drilling patterns by canned cycles between the rows)."""
    if n_lines < 10:
        raise ValueError("make_cam_program: n_lines must be ≥ 10")
    rng = np.random.default_rng(seed)
    body = n_lines - 1                     # the last line is M2
    out = ["%", f"( pkmbench CAM benchmark: {n_lines} lines, seed {seed}, kossel workspace )",
           "G21 G90 G17 G64 P0.01",
           f"G0 X{-X_HALF:.4f} Y{-X_HALF:.4f} Z{_surface(-X_HALF, -X_HALF, 0) + 5:.4f}",
           "F1200"]
    layer = 0
    patterns = 0
    n_step = int(round(2 * X_HALF / STEP))
    while len(out) < body:
        y = -X_HALF
        out.append(f"G1 Z{_surface(-X_HALF, y, layer):.4f} F600")
        out.append("F1200")
        for r in range(ROWS):
            # interior X stations: a regular grid jittered by ±30 % of a step (the seed's part)
            x = np.linspace(-X_HALF, X_HALF, n_step + 1)
            x[1:-1] += rng.uniform(-0.3, 0.3, n_step - 1) * STEP
            if r % 2:
                x = x[::-1]
            z = _surface(x, y, layer)
            out += [f"G1 X{xi:.4f} Z{zi:.4f}" for xi, zi in zip(x[1:], z[1:])]
            if cycles and r % CYCLE_EVERY == CYCLE_EVERY - 1:
                out += _drill_pattern(rng, patterns, y, layer, (x[-1], y, z[-1]))
                patterns += 1
            if r == ROWS - 1:
                break
            # half-circle to the next row, on the outside of the row's end; helical in Z
            word = "G3" if r % 2 == 0 else "G2"
            z_next = _surface(x[-1], y + STEP_OVER, layer)
            out.append(f"{word} X{x[-1]:.4f} Y{y + STEP_OVER:.4f} Z{z_next:.4f} I0 J{STEP_OVER / 2:.4f}")
            y += STEP_OVER
        # lift, go back to the layer's corner and start the next layer lower
        out.append(f"G0 Z{_surface(-X_HALF, -X_HALF, 0) + 5:.4f}")
        out.append(f"G0 X{-X_HALF:.4f} Y{-X_HALF:.4f}")
        layer += 1
    text = "\n".join(out[:body] + ["M2"]) + "\n"
    if file is not None:
        Path(file).write_text(text)
    return text
