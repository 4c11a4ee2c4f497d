"""Plan the KEOPS bird with two planners and compare them at the servo period: the s-curve
planned under Cartesian limits breaks the joint limits, its joint-space repair does not."""
import planners
from kins import load_machine
from planners.verify import command_metrics

m = load_machine("keops")
print(f"{'planner':14s} {'exec s':>8s} {'joint v':>8s} {'joint a':>8s} {'joint j':>8s} feasible")
for name in ("scurve", "scurve_joint"):
    prof = planners.plan(name, "bird", m)
    met = command_metrics(m, prof.path.point(prof.s), prof.T, prof.s)
    j = met["joint_peak_ratio"]
    print(f"{name:14s} {prof.execution_time_s:8.4f} {j['velocity']:8.3f} {j['acceleration']:8.3f} "
          f"{j['jerk']:8.3f} {'yes' if met['feasible'] else 'NO'}")
