"""Seeds: every seed a user gives is an integer with 0 ≤ seed < 2⁶⁴.

numpy's ``default_rng(seed)`` takes such a seed whole. EtherCAT.fmu takes its seed as an FMI
Integer (32 bits, which the FMU reads as unsigned), so :func:`fmu_seed` maps a seed to it:

- seed < 2³²: its own 32 bits (written as the signed Integer with the same bits), so the bus
  draws of the seeds 0, 1, … are those of earlier versions;
- seed ≥ 2³²: ``numpy.random.SeedSequence(seed).generate_state(1, numpy.uint32)[0]``, the
  same on every machine. Such a seed's bus draws can coincide with those of a seed < 2³²
  (2⁶⁴ seeds onto 2³² values); its numpy draws (pso) cannot.
"""
from __future__ import annotations

import numpy as np

SEED_LIMIT = 2**64


class SeedError(ValueError):
    """A seed is not an integer in [0, 2⁶⁴); the message names where it came from."""


def check_seed(value, where: str = "seed") -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 <= value < SEED_LIMIT:
        raise SeedError(f"{where} = {value!r}: a seed must be an integer with 0 <= seed < 2**64")
    return int(value)


def fmu_seed(value, where: str = "seed") -> int:
    """The EtherCAT.fmu Integer for a seed (see the module docstring)."""
    seed = check_seed(value, where)
    u32 = seed if seed < 2**32 else int(np.random.SeedSequence(seed).generate_state(1, np.uint32)[0])
    return u32 - 2**32 if u32 >= 2**31 else u32
