"""``scurve`` and ``scurve_joint``: the FLF s-curve of Erwinski et al., TII 2022 (see planner.py)."""
from planners.scurve.planner import plan, plan_joint

__all__ = ["plan", "plan_joint"]
