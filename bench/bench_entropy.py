"""Range coder speed in symbols per second (encode and decode), spec §5.

    python bench/bench_entropy.py

A symbol is one coded integer. Inputs are Laplacian residuals of three
scales, like the RESI blocks of real captures. The baseline in the same
process is the pure-Python transcription of §5 used by tests/test_entropy.py.
Target (issue 3): >= 5 M symbols/s decoding.
"""

import numpy as np

from _common import best_of
from mpz.conformance.rangecoder import RefEncoder
from mpz.entropy import BlockDecoder, BlockEncoder


def main():
    rng = np.random.default_rng(0)
    BlockDecoder(_enc(np.zeros((2, 1, 3), np.int64))).block(2, 1)   # JIT warm-up
    print(f"{'scale':>6} {'symbols':>9} {'bits/sym':>9} {'enc Msym/s':>11} {'dec Msym/s':>11} "
          f"{'py-ref Msym/s':>14} {'dec speed-up':>12}")
    ok = True
    for scale in (0.5, 3.0, 50.0):
        v = np.round(rng.laplace(0, scale, (5202, 41, 3))).astype(np.int64)
        data = _enc(v)
        small = v[:200]
        te = best_of(lambda v=v: _enc(v), 5)
        td = best_of(lambda data=data: BlockDecoder(data).block(5202, 41), 5)
        tr = best_of(lambda small=small: _ref(small), n=1) * (v.shape[0] / small.shape[0])
        n = v.size
        dec = n / td / 1e6
        ok &= dec >= 5
        print(f"{scale:>6g} {n:>9} {8 * len(data) / n:>9.3f} {n / te / 1e6:>11.1f} {dec:>11.1f} "
              f"{n / tr / 1e6:>14.3f} {tr / td:>11.0f}x")
    print(f"decode >= 5 M symbols/s: {'MET' if ok else 'MISSED'}")


def _enc(v):
    e = BlockEncoder()
    e.block(v)
    return e.finish()


def _ref(v):
    r = RefEncoder()
    r.block(v)
    return r.finish()


if __name__ == "__main__":
    main()
