"""Fuzz the G-code reader: random and mutated programs must either parse or raise GCodeError
(a clean message with a line number) — never another exception.

    .venv/bin/python tests/fuzz_gcode.py [N] [SEED]     # the long run (issue 7: ≥ 10⁵ inputs)
tests/test_check.py runs a short one.
"""
from __future__ import annotations

import random
import sys

from planners.paths.gcode import GCodeError, parse_gcode

SEED_PROGRAMS = [
    "G21 G90 G64 P0.01\nN10 G1 X0 Y0 Z-400 F600\nN20 G2 X10 Y0 I5 J0\nN30 G3 X0 Y0 R5\nG91 G1 Z-2\nG90 G17 G2 X0 Y0 I-5 J0 P2 Z-410\nM2\n",
    "G20 G90\nG0 X0 Y0 Z-15\nG1 X1 F10 (comment)\nG18 G2 X2 Z-15 I0.5 K0\nG19 G3 Y1 Z-14 J0.5 K0.5\nG61\nG1 Y0\n",
]
ALPHABET = "GXYZIJKRFNPMST0123456789.-+ ()\n;%"


def mutate(text: str, rng: random.Random) -> str:
    s = list(text)
    for _ in range(rng.randint(1, 8)):
        r = rng.random()
        i = rng.randrange(len(s) + 1)
        if r < 0.35 and s:
            del s[min(i, len(s) - 1)]
        elif r < 0.75:
            s.insert(i, rng.choice(ALPHABET))
        else:
            j, k = sorted(rng.randrange(len(s) + 1) for _ in range(2))
            s[i:i] = s[j:k]
    return "".join(s)


def fuzz(n: int, seed: int = 0) -> dict:
    rng = random.Random(seed)
    counts = {"parsed": 0, "GCodeError": 0}
    for k in range(n):
        if k % 5 == 4:
            text = "".join(rng.choice(ALPHABET) for _ in range(rng.randint(0, 80)))
        else:
            text = mutate(rng.choice(SEED_PROGRAMS), rng)
        try:
            parse_gcode(text, "fuzz.ngc")
            counts["parsed"] += 1
        except GCodeError as e:
            assert e.line >= 0 and str(e).startswith("fuzz.ngc:"), f"unclear error for {text!r}: {e}"
            counts["GCodeError"] += 1
        except Exception as e:   # anything else is a bug: show the input
            raise AssertionError(f"input {k} raised {type(e).__name__}: {e}\n---\n{text}") from e
    return counts


if __name__ == "__main__":
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 100_000
    print(fuzz(n, int(sys.argv[2]) if len(sys.argv) > 2 else 0))
