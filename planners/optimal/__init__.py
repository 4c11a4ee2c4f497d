"""``optimal`` (the yardstick) and the references beside it: ``copp`` (copp.py), ``toppra``
(toppra.py); the TOPP3-SOCP engine they share (topp3.py), its last resort's time stretches
(timewarp.py) and the IPOPT polish (nlp.py)."""
from planners.optimal.planner import plan

__all__ = ["plan"]
