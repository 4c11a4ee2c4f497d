"""``pso`` (the particle swarm over a B-spline feed) and ``pso_socp`` (the swarm polished by the
TOPP3-SOCP): planner.py."""
from planners.pso.planner import plan, plan_socp

__all__ = ["plan", "plan_socp"]
