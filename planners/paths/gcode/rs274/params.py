"""Parameters: numbered #1–#5602 (unset reads 0), #1–#30 local to a subroutine call, and global
named #<_x> (local named ones live in the call frame). Stored values of the system parameters
(#5161 G28, #5181 G30, #5211 G92, #5221… G54–G59.3) are in mm here."""
from __future__ import annotations

from planners.paths.gcode.rs274.errors import LineError

MAX_PARAMETER = 5602        # rs274ngc's RS274NGC_MAX_PARAMETERS − 1


class Parameters:
    __slots__ = ("num", "named_global")

    def __init__(self):
        self.num = [0.0] * (MAX_PARAMETER + 1)
        self.named_global: dict[str, float] = {}
        self.num[5220] = 1.0                    # G54 active
        self.num[5599] = 1.0                    # (DEBUG,…) messages on (rs274ngc_pre.cc init)

    def get(self, n: int) -> float:
        if not 1 <= n <= MAX_PARAMETER:
            raise LineError(f"parameter #{n} out of range (#1 … #{MAX_PARAMETER})")
        return self.num[n]

    def set(self, n: int, v: float) -> None:
        if not 1 <= n <= MAX_PARAMETER:
            raise LineError(f"parameter #{n} out of range (#1 … #{MAX_PARAMETER})")
        self.num[n] = v

    def save_locals(self):
        return self.num[1:31]

    def restore_locals(self, saved) -> None:
        self.num[1:31] = saved
