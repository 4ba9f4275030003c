"""Write the seed corpus for the fuzzer: small valid files of each kind.

    python conformance/fuzz/make_seeds.py conformance/corpus
"""
from pathlib import Path
import sys

import mpz
from mpz.synth import generate


def main(out):
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    seeds = {
        "seed-bounded.mpz": mpz.encode(generate("walk", frames=16, markers=5, seed=1, gap_fraction=0.1),
                                       max_error=1.0),
        "seed-lossy.mpz": mpz.encode(generate("wave", frames=40, markers=6, seed=2)),
        "seed-summary.mpz": mpz.encode(generate("jump", frames=24, markers=4, seed=3), max_error=2.0,
                                       summary=(2, 3)),
        "seed-patterns.mpz": mpz.encode(generate("walk", frames=48, markers=6, seed=4), max_error=1.0,
                                        patterns="on"),
    }
    for name, data in seeds.items():
        (out / name).write_bytes(data)
    print(f"wrote {len(seeds)} seeds to {out}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "conformance/corpus")
