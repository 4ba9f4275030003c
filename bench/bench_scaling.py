"""The paper's Table I on our data, and its key claim: the ratio rises with input size.

    python bench/bench_scaling.py [--quick]

Needs c3d/cmu_02_01, cmu_135_02 and HDM_mm_01-02_03_120 under ../shared/data (or
``$MPZ_SHARED_DATA``); without them it prints "skipped: ..." and exits 0.

Lossy (paper) mode, default thresholds. Short input: one take; long input:
takes concatenated as the paper did (same markers). Then 1x, 2x, 4x and 8x
concatenations of one motion type (walk, cmu_02_01 ~ and HDM_mm): ratio and
encode time, with the time ratio against the 1x run in the same process
(target: 8x input in at most 10x the time). Bounded mode (1 mm) is shown
alongside for contrast: without pattern reuse its ratio stays flat.
"""
import argparse
import sys
import time

from _common import shared_data_dir, shared_data_name
import mpz
from mpz.encoder import EncodeOptions, encode_motion
import mpz.io


def strip(m):
    """Names without the 'Subject:' prefix, so takes of different subjects concatenate."""
    names = [n.split(":")[-1] for n in m.names]
    return mpz.Motion(m.positions, names, m.rate, m.units, m.valid)


def row(label, m, opts):
    t = time.perf_counter()
    data, rep = encode_motion(m, opts)
    dt = time.perf_counter() - t
    out = mpz.decode(data)
    segs = sum(n.segments for n in rep.nodes)
    pats = sum(n.patterns for n in rep.nodes)
    print(f"{label:<34} {m.raw_size() / 1e6:>8.2f} {segs:>8} {pats:>8} {len(data) / 1e3:>9.1f} "
          f"{mpz.arms(m, out):>6.2f} {m.raw_size() / len(data):>6.1f} {dt:>7.2f}")
    return m.raw_size() / len(data), dt


def main(argv=None):
    p = argparse.ArgumentParser(
        description="The paper's Table I on our data (lossy mode, one take and three "
        "concatenated), then the ratio and encode time of 1x, 2x, 4x and 8x "
        "concatenations of one walk (cmu_02_01), with a bounded 1 mm encode for contrast. "
        "Reads c3d/cmu_02_01, cmu_135_02 and HDM_mm_01-02_03_120 from ../shared/data "
        "(or $MPZ_SHARED_DATA).")
    p.add_argument("--quick", action="store_true",
                   help="1x and 2x only, and the bounded row at 1x (the full run goes to 8x)")
    args = p.parse_args(argv)
    d = shared_data_dir()
    if d is None:
        print(f"skipped: {shared_data_name()} is absent")
        return 0
    need = [n for n in ("cmu_02_01.c3d", "cmu_135_02.c3d", "HDM_mm_01-02_03_120.c3d")
            if not (d / "c3d" / n).is_file()]
    if need:
        print(f"skipped: {shared_data_name()} has no c3d/{', c3d/'.join(need)}")
        return 0
    read = lambda n: strip(mpz.io.read(d / "c3d" / n))  # noqa: E731
    walk = read("cmu_02_01.c3d")
    takes = [read(n) for n in ("cmu_02_01.c3d", "cmu_135_02.c3d", "HDM_mm_01-02_03_120.c3d")]
    common = [n for n in takes[0].names if all(n in t.names for t in takes)]

    def pick(m):
        idx = [m.names.index(n) for n in common]
        return mpz.Motion(m.positions[:, idx], common, m.rate, m.units, m.valid[:, idx])

    lossy = EncodeOptions(lossy=True)                     # the paper's mode, by name
    mpz.decode(mpz.encode(walk.select_frames(0, 40), lossy=True))     # JIT warm-up, not timed
    print("Table I (paper) on our data, lossy mode (theta 0.2, K0 10, tau 0.05, MaxError):")
    hdr = (f"{'input':<34} {'raw MB':>8} {'segments':>8} {'clusters':>8} {'size KB':>9} "
           f"{'ARMS':>6} {'ratio':>6} {'enc s':>7}")
    print(hdr)
    row("short: cmu_02_01 (walk)", walk, lossy)
    long = mpz.concatenate([pick(t) for t in takes])
    row("long: 02_01 + 135_02 + HDM_mm", long, lossy)

    print("\nRatio vs input size: k x concatenations of one walk (cmu_02_01)")
    print(hdr)
    base = None
    for k in (1, 2, 4, 8) if not args.quick else (1, 2):
        m = mpz.concatenate([walk] * k)
        r, t = row(f"lossy {k}x", m, lossy)
        if base is None:
            base = (r, t)
        print(f"{'':<34} ratio x{r / base[0]:.2f} vs 1x, time x{t / base[1]:.2f} vs 1x"
              + (f" (target <= 10x: {'MET' if t / base[1] <= 10 else 'MISSED'})" if k == 8 else ""))
    for k in (1, 8) if not args.quick else (1,):
        row(f"bounded 1 mm {k}x", mpz.concatenate([walk] * k), EncodeOptions(max_error=1.0))
    return 0


if __name__ == "__main__":
    sys.exit(main())
