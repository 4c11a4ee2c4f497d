"""``linuxcnc``: the real LinuxCNC 2.9 trajectory planner, run headless (see planner.py)."""
from planners.linuxcnc.planner import plan

__all__ = ["plan"]
