"""Encode and decode speed on cmu_135_02.c3d (5202 frames x 41 markers), in MB/s of raw float32.

    python bench/bench_speed.py

Targets (issue 4): encode >= 2 MB/s, decode >= 20 MB/s. Baseline in the same
process: zstd -19 and -3 on the float32 array (a lossless general-purpose codec).
"""
import sys

import numpy as np

from _common import best_of, shared_data_dir
import mpz
import mpz.io


def main():
    d = shared_data_dir()
    if d is None:
        print("skipped: ../shared/data is absent")
        return 0
    import zstandard
    m = mpz.io.read(d / "c3d" / "cmu_135_02.c3d")
    raw = m.raw_size() / 1e6
    f32 = m.positions.astype(np.float32).tobytes()
    mpz.decode(mpz.encode(m.select_frames(0, 50), max_error=1.0))     # JIT warm-up
    print(f"cmu_135_02: {raw:.2f} MB raw float32")
    print(f"{'mode':<22} {'enc MB/s':>9} {'dec MB/s':>9} {'ratio':>7}")
    for lvl in (3, 19):
        c = zstandard.ZstdCompressor(level=lvl)
        z = c.compress(f32)
        te = best_of(lambda c=c: c.compress(f32), 1 if lvl == 19 else 3)
        td = best_of(lambda z=z: zstandard.ZstdDecompressor().decompress(z))
        label = f"zstd -{lvl} (lossless)"
        print(f"{label:<22} {raw / te:>9.1f} {raw / td:>9.1f} {len(f32) / len(z):>7.1f}")
    rows = []
    for label, kw in (("MPZ max-error 1 mm", {"max_error": 1.0}),
                      ("MPZ max-error 5 mm", {"max_error": 5.0}),
                      ("MPZ lossy (paper)", {"lossy": True})):
        data = mpz.encode(m, **kw)
        te = best_of(lambda kw=kw: mpz.encode(m, **kw))
        td = best_of(lambda data=data: mpz.decode(data))
        rows.append((raw / te, raw / td))
        print(f"{label:<22} {raw / te:>9.1f} {raw / td:>9.1f} {m.raw_size() / len(data):>7.1f}")
    enc_ok = all(r[0] >= 2 for r in rows)
    dec_ok = all(r[1] >= 20 for r in rows)
    print(f"encode >= 2 MB/s: {'MET' if enc_ok else 'MISSED'}; decode >= 20 MB/s: "
          f"{'MET' if dec_ok else 'MISSED'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
