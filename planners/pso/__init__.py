"""``pso``: a particle swarm over a B-spline feed (see planner.py)."""
from planners.pso.planner import plan

__all__ = ["plan"]
