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
SEED_PROGRAMS += [
    # issue 20: expressions, parameters, O-words, offsets, M70-M73
    "G21\n#1=2 #<r>=[#1*2.5]\no<s> sub\nM73\nG91 G1 X#1 F[100*#2]\nG90\no<s> endsub\n"
    "G0 X0 Y0 Z-400\no10 while [#1 lt 5]\n#1=[#1+1]\no<s> call [#1] [2]\no10 endwhile\n"
    "o20 if [#<r> gt 4]\nG2 X0 Y0 I[-#<r>] J0 F300\no20 elseif [1]\nG1 X1\no20 else\nG1 Y1\no20 endif\nM2\n",
    "G90 G94 G91.1 G40 G49 G17\nG54\nG10 L2 P1 X1 Y2 Z3\nG80 G00 X1 Y2 Z-400\nG92 X0\nG1 X[sin[30]+cos[60]] F[2**8]\n"
    "o1 repeat [3]\nG91 G1 X1\no1 endrepeat\nG90\nM70\nG20\nM72\no2 do\n#3=[#3+1]\no2 while [#3 le 2]\n"
    "G28.1\nG28 Z-390\nG53 G0 X0\n/G1 Y1\nG64 P0.01 Q0.005\nG1 @1 ^45\nN70 Z-400 M09\nM30\n",
]
SEED_PROGRAMS += [
    # issue 33: canned cycles, probing, messages
    "G21 G90 G0 X0 Y0 Z-390\nF300 S1000 M3\nG99 G81 X1 Y1 Z-400 R-395\nX2\nG98 G83 X3 Z-401 R-395 Q1.5 L2\n"
    "G91 G73 X1 Z-3 R-2 Q0.7 L3\nG90 G82 X4 Z-400 R-395 P0.1\nG84 X5 Z-400 R-395\nG86 X6 Z-400 R-395 P0\n"
    "G87 X7 Z-405 R-395 I1 J0 K-401\nG88 X8 Z-400 R-395 P0.2\nG18 G81 X1 Z1 Y-2 R1\nG19 G85 Y1 Z1 X-2 R1\n"
    "G17 G80\n(MSG, drilled)\nG38.3 Z-410 F50\nG0 Z[#5063+#5070]\n(DEBUG, at #5063 %d#5070)\nM2\n",
]
ALPHABET = "GXYZIJKRFNPMST0123456789.-+ ()\n;%#[]<>=*/oO_@^"
TOKENS = ["sub", "endsub", "call", "while", "endwhile", "if", "endif", "else", "do", "repeat", "endrepeat",
          "break", "continue", "return", "sin[", "atan[1]/[", "mod", "**", "#<a>", "#5220", "##1", "G10 L2",
          "G92", "G43.1 Z1", "M72", "M73", "exists[#<a>]", "G81 R1 Z-1", "G83 Q", "G73", "L2", "G98", "G99",
          "G38.2 Z", "G38.4 X", "G80", "(ABORT,", "(DEBUG,#1)", "(MSG,"]


def mutate(text: str, rng: random.Random) -> str:
    s = list(text)
    for _ in range(rng.randint(1, 8)):
        r = rng.random()
        i = rng.randrange(len(s) + 1)
        if r < 0.35 and s:
            del s[min(i, len(s) - 1)]
        elif r < 0.65:
            s.insert(i, rng.choice(ALPHABET))
        elif r < 0.75:
            s[i:i] = list(rng.choice(TOKENS))
        else:
            j, k = sorted(rng.randrange(len(s) + 1) for _ in range(2))
            s[i:i] = s[j:k]
    return "".join(s)


def fuzz(n: int, seed: int = 0) -> dict:
    rng = random.Random(seed)
    counts = {"parsed": 0, "GCodeError": 0, "loop limit": 0}
    for k in range(n):
        if k % 5 == 4:
            text = "".join(rng.choice(ALPHABET) for _ in range(rng.randint(0, 80)))
        else:
            text = mutate(rng.choice(SEED_PROGRAMS), rng)
        try:
            parse_gcode(text, "fuzz.ngc", max_loops=10_000)   # an endless loop: a clear error
            counts["parsed"] += 1
        except GCodeError as e:
            assert e.line >= 0 and str(e).startswith("fuzz.ngc:"), f"unclear error for {text!r}: {e}"
            counts["GCodeError"] += 1
            counts["loop limit"] += "loop iterations" in e.message
        except Exception as e:   # anything else is a bug: show the input
            raise AssertionError(f"input {k} raised {type(e).__name__}: {e}\n---\n{text}") from e
    return counts


if __name__ == "__main__":
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 100_000
    print(fuzz(n, int(sys.argv[2]) if len(sys.argv) > 2 else 0))
