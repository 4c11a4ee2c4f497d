"""`pkmbench kins-demo`: per machine, a workspace slice coloured by cond(J) and the joint
ranges over the workspace box — a first look at each machine's kinematics."""
from __future__ import annotations

# Local imports: every command module is imported to build the parser; a command loads what it
# needs when it runs (`pkmbench --help` and the other commands stay fast)

import numpy as np

from harness.outdir import output_dir
from kins.resources import RESULTS


def add_arguments(p):
    p.add_argument("--out", default=str(RESULTS / "kins"), help="output folder (default: %(default)s)")
    p.add_argument("--machines", default=None, help="comma-separated machine ids (default: all)")


def main(args) -> int:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from kins import available_machines, load_machine

    out = output_dir(args.out)
    names = args.machines.split(",") if args.machines else available_machines()
    for name in names:
        m = load_machine(name)
        lo, hi = m.workspace_min, m.workspace_max
        n = 121
        x, y = np.meshgrid(np.linspace(lo[0], hi[0], n), np.linspace(lo[1], hi[1], n))
        P = np.stack([x.ravel(), y.ravel(), np.full(x.size, m.home[2])], axis=1)
        cond = m.condition_number(P).reshape(x.shape)
        Q, reach = m._ik(P)
        Q[(reach < 0)] = np.nan
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.5))
        im = a1.pcolormesh(x, y, np.where(np.isfinite(cond), cond, np.nan), shading="auto")
        fig.colorbar(im, ax=a1, label="cond(∂q/∂p)")
        a1.set(xlabel="x (mm)", ylabel="y (mm)", title=f"{name}: z = {m.home[2]:g} mm", aspect="equal")
        for k in range(3):
            a2.hist(Q[:, k][np.isfinite(Q[:, k])], bins=60, histtype="step", lw=1.5, label=f"q{k + 1}")
        for q in (m.q_min, m.q_max):
            a2.axvline(q, color="k", ls="--")
        a2.set(xlabel="joint position (mm)", ylabel="points", title="joint range over the slice (stroke dashed)")
        a2.legend()
        fig.tight_layout()
        f = out / f"{name}_workspace.png"
        fig.savefig(f, dpi=110)
        plt.close(fig)
        print(f"{name:16s} cond(J) {np.nanmin(cond):6.3g}…{np.nanmax(cond):6.3g}  "
              f"q {np.nanmin(Q):8.2f}…{np.nanmax(Q):8.2f} mm  → {f}")
    return 0
