"""``linuxcnc``: the real LinuxCNC 2.9 trajectory planner, run headless (see planner.py)."""
from planners.linuxcnc.planner import plan
from planners.linuxcnc.runner import IO_CYCLE_S, TASK_CYCLE_S

__all__ = ["plan", "IO_CYCLE_S", "TASK_CYCLE_S"]
