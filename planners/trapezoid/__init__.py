"""``trapezoid``: LinuxCNC 2.9's trajectory planner (type 0), cycle by cycle (see planner.py)."""
from planners.trapezoid.planner import plan

__all__ = ["plan"]
