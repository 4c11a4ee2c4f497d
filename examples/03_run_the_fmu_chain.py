"""A profile through the full FMU chain (Interpolator → Kinematics → EtherCAT → Drives) on the
Kossel test part: run files in results/examples/03, the summary printed. Needs `make fmus`."""
from harness.cosim.run import run_case
from kins.resources import RESULTS

out = RESULTS / "examples" / "03"
summary = run_case("kossel", "test_part", ["scurve_joint"], out, recordings=False)
for name, m in summary["planners"].items():
    if "error" in m:
        print(f"{name}: {m['error']}")
        continue
    print(f"{name}: {m['execution_time_s']:.3f} s, following error {m['max_following_error_um']:.1f} µm, "
          f"contour error {m['max_contour_error_um']:.1f} µm, feasible {m['feasible']}")
print(f"files in {out}")
