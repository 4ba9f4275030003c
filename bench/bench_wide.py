"""Encode speed against the number of markers, next to zstd -19 in the same process.

    python bench/bench_wide.py [--markers 64,256,1024,4096] [--frames 400] [--bound 1]
                               [--repeat 2]

Real captures here have at most 68 markers; the encoder's pair analyses (the auto
hierarchy's distance table, the rigidity chain) and its key-frame reference choice used
to grow with the square of the markers (stop 67: a 4096-marker, 400-frame motion took
69 s). The motions are synthetic (``mpz.synth``'s 41-marker walk, each marker copied with
a fixed offset of up to 50 mm and 0.3 mm of noise per sample, so that copies move
rigidly together like the markers of one segment); the bound is in mm.

For each width it prints the float32 size of the positions, MPZ's encode time and MB/s
with 1 and 2 threads (best of ``--repeat``; the bytes must not depend on the threads),
zstd -19's on the same float32 bytes, the ratio and the decoded max error. Exit status:
0; 1 when an error passes the bound or the threads change the bytes; 2 for a usage
error.
"""
from __future__ import annotations

import argparse
import sys

import numpy as np

from _common import best_of
import mpz
from mpz.synth import generate


def wide(markers: int, frames: int, seed: int = 0) -> mpz.Motion:
    """``markers`` markers: the walk's 41, and copies of them at fixed offsets."""
    base = generate("walk", frames=frames, markers=41, seed=seed)
    rng = np.random.default_rng(seed)
    src = np.arange(markers) % 41
    offset = rng.uniform(-50, 50, (1, markers, 3)) * (np.arange(markers) >= 41)[None, :, None]
    x = base.positions[:, src] + offset + rng.normal(0, 0.3, (frames, markers, 3))
    return mpz.Motion(x, [f"m{i}" for i in range(markers)], base.rate, "mm")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--markers", default="64,256,1024,4096",
                    help="comma-separated marker counts (default 64,256,1024,4096)")
    ap.add_argument("--frames", type=int, default=400, help="frames (default 400)")
    ap.add_argument("--bound", type=float, default=1.0, help="max error in mm (default 1)")
    ap.add_argument("--repeat", type=int, default=2, help="timed runs each (default 2)")
    args = ap.parse_args(argv)
    try:
        widths = [int(w) for w in args.markers.split(",")]
    except ValueError:
        ap.error(f"--markers: whole numbers apart by commas, got {args.markers!r}")
    if any(w < 1 for w in widths) or args.frames < 2 or args.repeat < 1 \
            or not args.bound > 0:
        ap.error("--markers >= 1, --frames >= 2, --repeat >= 1 and --bound > 0")
    try:
        import zstandard
    except ImportError:
        print("zstandard is missing: pip install -e '.[bench]'", file=sys.stderr)
        return 1
    zc = zstandard.ZstdCompressor(level=19)
    mpz.encode(wide(50, 60), max_error=args.bound)                # kernels loaded, not timed
    print(f"{args.frames} frames, bound {args.bound:g} mm, best of {args.repeat}; MB/s of "
          "the positions as float32")
    print(f"{'markers':>7} {'MB':>7} {'x1 s':>7} {'x1 MB/s':>8} {'x2 s':>7} {'x2 MB/s':>8} "
          f"{'zstd s':>7} {'zstd MB/s':>9} {'x2/zstd':>7} {'ratio':>6} {'max err':>8}")
    status = 0
    for w in widths:
        m = wide(w, args.frames)
        raw = m.positions.astype("<f4").tobytes()
        mb = len(raw) / 1e6
        t1 = best_of(lambda m=m: mpz.encode(m, max_error=args.bound, threads=1), args.repeat)
        t2 = best_of(lambda m=m: mpz.encode(m, max_error=args.bound, threads=2), args.repeat)
        tz = best_of(lambda raw=raw: zc.compress(raw), args.repeat)
        a = mpz.encode(m, max_error=args.bound, threads=1)       # the bytes, untimed
        b = mpz.encode(m, max_error=args.bound, threads=2)
        err = mpz.max_error(m, mpz.decode(a))
        flag = ""
        if a != b:
            flag, status = " THREADS CHANGED THE BYTES", 1
        if err > args.bound:
            flag, status = flag + " OVER", 1
        print(f"{w:>7} {mb:>7.2f} {t1:>7.2f} {mb / t1:>8.2f} {t2:>7.2f} {mb / t2:>8.2f} "
              f"{tz:>7.2f} {mb / tz:>9.2f} {tz / t2:>7.2f} {len(raw) / len(a):>6.1f} "
              f"{err:>8.4f}{flag}", flush=True)
    return status


if __name__ == "__main__":
    sys.exit(main())
