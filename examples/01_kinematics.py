"""Inverse and forward kinematics of every machine at its workspace centre, and how far a
joint moves per mm of tool motion there (the Jacobian's largest entry)."""
import numpy as np

from kins import available_machines, load_machine

print(f"{'machine':16s} {'q at centre (mm)':>30s} {'FK(IK) error (nm)':>18s} {'max |dq/dp|':>12s}")
for name in available_machines():
    m = load_machine(name)
    q = m.ik(m.home)
    err_nm = np.linalg.norm(m.fk(q) - m.home) * 1e6
    J = np.asarray(m.jacobian(m.home))
    print(f"{name:16s} {np.array2string(np.asarray(q), precision=3):>30s} {err_nm:18.3g} {np.abs(J).max():12.3f}")
