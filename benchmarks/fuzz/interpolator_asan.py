"""Fuzz Interpolator.fmu's file parsers under AddressSanitizer + UBSan (issue 3).

Builds fmus/Interpolator/interp_path.c with a small driver (interpolator_asan_driver.c) using
-fsanitize=address,undefined, writes N mutated path/profile files (the mutations of
tests/test_fmu_interpolator.py), and loads + replays each; any sanitizer report aborts.
    .venv/bin/python benchmarks/fuzz/interpolator_asan.py [N] [SEED]      (default 100000, 12)
"""
from __future__ import annotations

import json
import random
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))


def main(n: int = 100_000, seed: int = 12) -> int:
    from tests.test_fmu_interpolator import GOOD_NURBS, mutate

    rng = random.Random(seed)
    seeds = [json.dumps(GOOD_NURBS), (ROOT / "tests/data/short_line.json").read_text()]
    prof = "t,s,sd,sdd,sddd\n0,0,0,0,0\n0.00025,0.001,4,0,0\n0.0005,0.002,4,0,0\n"
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        exe = d / "driver"
        subprocess.run(["cc", "-g", "-O1", "-fsanitize=address,undefined", "-fno-sanitize-recover=all",
                        f"-I{ROOT / 'fmus/Interpolator'}", str(Path(__file__).with_name("interpolator_asan_driver.c")),
                        str(ROOT / "fmus/Interpolator/interp_path.c"), "-lm", "-o", str(exe)], check=True)
        (d / "good.json").write_text(seeds[0])
        (d / "good.csv").write_text(prof)
        with open(d / "list.txt", "w") as listing:
            for k in range(n):
                f = d / f"in{k}"
                if k % 2:
                    f.write_text(mutate(rng.choice(seeds), rng))
                    listing.write(f"{f} {d / 'good.csv'}\n")
                else:
                    f.write_text(mutate(prof, rng))
                    listing.write(f"{d / 'good.json'} {f}\n")
        r = subprocess.run([str(exe), str(d / "list.txt")], capture_output=True, text=True)
    print(r.stdout.strip() or r.stderr[-2000:])
    return r.returncode


if __name__ == "__main__":
    sys.exit(main(*(int(a) for a in sys.argv[1:3])))
