"""Analog coding of the C3D archive (spec §4.13.4) against zstd -19 and FLAC, one process.

Usage: ``python bench/bench_c3d.py`` (reads the C3D files of ../shared/data, or
``$MPZ_SHARED_DATA``, in place; without a C3D that has analog channels it prints
"skipped: ..." and exits 0).

For every real C3D with analog channels:

- *all channels*: the cana chunk (MPZ's own prediction and range coder, exact to the bit)
  against zstd -19 on the same analog words as stored (int16 or float32, little-endian);
- *integer channels* (those whose words are k x 2^shift with |k| < 2^24, channel mode 0),
  on the same integers k: MPZ (those channels alone), zstd -19 on k as int16 or int32, and
  FLAC (the reference for lossless coding of sampled signals: fixed and LPC prediction,
  Rice-coded residuals) on k as PCM_16 or PCM_24 at the analog rate, one multichannel file.

FLAC needs ``soundfile`` (``pip install mpz[bench]``); without it that column is skipped.
Every coder is checked to give back its input exactly. Sizes in bytes; ratios vs raw.
"""
from __future__ import annotations

import argparse
import io
import sys

import numpy as np

from _common import no_data_reason, shared_data_dir, shared_data_name


def _flac(k: np.ndarray, rate: int) -> int | None:
    """Bytes of a FLAC file of the integer channels k [T, C] (exact round trip checked)."""
    try:
        import soundfile as sf
    except ImportError:
        return None
    peak = int(np.abs(k).max(initial=0))
    if peak < 1 << 15:
        data, subtype, dtype = k.astype(np.int16), "PCM_16", "int16"
    elif peak < 1 << 23:
        data, subtype, dtype = (k.astype(np.int32) << 8), "PCM_24", "int32"
    else:
        return None
    if data.shape[1] > 8:              # FLAC holds at most 8 channels per stream
        return sum(_flac(k[:, i:i + 8], rate) or 0 for i in range(0, k.shape[1], 8))
    buf = io.BytesIO()
    sf.write(buf, data, samplerate=max(1, min(rate, 655350)), format="FLAC", subtype=subtype)
    buf.seek(0)
    back, _ = sf.read(buf, dtype=dtype, always_2d=True)
    assert np.array_equal(back, data), "FLAC did not give the channels back"
    return len(buf.getvalue())


def _mpz(words: np.ndarray) -> int:
    """Bytes of the cana chunk (payload + 12 framing bytes) for the words [T, C]."""
    from mpz.c3dcodec import decode_channel, encode_channel, plan
    from mpz.entropy import BlockDecoder, BlockEncoder
    enc = BlockEncoder(capacity=max(1 << 16, 8 * words.size))
    plans = []
    for c in range(words.shape[1]):
        p = plan(np.ascontiguousarray(words[:, c]))
        encode_channel(enc, p)
        plans.append(p)
    coded = enc.finish()
    dec = BlockDecoder(coded)
    for c, p in enumerate(plans):
        back = decode_channel(dec, words.shape[0], p.mode, p.shift, p.order, p.low_bits,
                              words.dtype, "§6.9")
        assert back.view(np.uint8).tobytes() == np.ascontiguousarray(
            words[:, c]).view(np.uint8).tobytes()
    dec.close()
    return 12 + 5 + 4 * words.shape[1] + len(coded)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description="Analog coding of the C3D archive (spec §4.13.4) against zstd -19 and "
        "FLAC, on every C3D with analog channels under ../shared/data (or "
        "$MPZ_SHARED_DATA). Takes no options.")
    ap.parse_args(argv)
    reason = no_data_reason("c3d", (".c3d",))
    if reason:
        print(f"skipped: {reason}")
        return 0
    try:
        import zstandard
    except ImportError:
        print("skipped: zstandard is not installed (the bench extra: pip install -e "
              "'.[bench]')")
        return 0

    from mpz.c3dcodec import plan
    from mpz.io import read
    data_dir = shared_data_dir()
    assert data_dir is not None
    try:
        import soundfile  # noqa: F401
        have_flac = True
    except ImportError:
        have_flac = False
        print("soundfile is not installed (pip install mpz[bench]): FLAC column skipped")
    z = zstandard.ZstdCompressor(level=19)
    print(f"{'file':<42} {'ch':>3} {'raw':>9} {'MPZ':>8} {'zstd19':>8} | {'int ch':>6} "
          f"{'raw':>9} {'MPZ':>8} {'zstd19':>8} {'FLAC':>8}")
    tot = np.zeros(7)
    flac_tot = np.zeros(4)      # raw, MPZ, zstd, FLAC over the files FLAC can hold
    measured = 0
    for path in sorted((data_dir / "c3d").glob("*.c3d")):
        m = read(path)
        a = m.extras.get("c3d")
        if a is None or a.channels == 0:
            continue
        measured += 1
        words = a.analog
        raw = words.size * words.itemsize
        mpz_all = _mpz(words)
        zst_all = len(z.compress(np.ascontiguousarray(words).tobytes()))
        # the integer channels, as their integers k
        ints, ks = [], []
        for c in range(words.shape[1]):
            p = plan(np.ascontiguousarray(words[:, c]))
            if p.mode == 0:
                ints.append(c)
                ks.append(p.values)
        line = (f"{path.name:<42} {words.shape[1]:>3} {raw:>9} {mpz_all:>8} {zst_all:>8} | "
                f"{len(ints):>6}")
        if ints:
            k = np.stack(ks, axis=1)
            kdt = np.int16 if np.abs(k).max(initial=0) < 1 << 15 else np.int32
            kraw = k.size * np.dtype(kdt).itemsize
            mpz_int = _mpz(k.astype(kdt) if kdt == np.int16 else
                           k.astype(np.float32))      # |k| < 2^24: exact as float32
            zst_int = len(z.compress(np.ascontiguousarray(k.astype(kdt)).tobytes()))
            rate = int(round(m.rate * a.analog_samples))
            fl = _flac(k, rate) if have_flac else None
            line += (f" {kraw:>9} {mpz_int:>8} {zst_int:>8} "
                     f"{'-' if fl is None else fl:>8}")
            tot += [raw, mpz_all, zst_all, kraw, mpz_int, zst_int, fl or 0]
            if fl is not None:
                flac_tot += [kraw, mpz_int, zst_int, fl]
        else:
            tot += [raw, mpz_all, zst_all, 0, 0, 0, 0]
        print(line)
    if not measured:
        print(f"skipped: no C3D under {shared_data_name()}/c3d has analog channels")
        return 0
    print(f"{'total':<42} {'':>3} {int(tot[0]):>9} {int(tot[1]):>8} {int(tot[2]):>8} | "
          f"{'':>6} {int(tot[3]):>9} {int(tot[4]):>8} {int(tot[5]):>8} {int(tot[6]):>8}")
    ints = (f"integer channels MPZ {tot[3] / tot[4]:.2f}, zstd-19 {tot[3] / tot[5]:.2f}"
            if tot[4] else "no integer channels")
    print(f"ratio vs raw: all channels MPZ {tot[0] / tot[1]:.2f}, zstd-19 {tot[0] / tot[2]:.2f}; "
          + ints)
    if flac_tot[3]:
        print(f"integer channels FLAC can hold (|k| < 2^23; Qualisys and Vicon fixed-point "
              f"channels need 24 bits and more): MPZ {flac_tot[0] / flac_tot[1]:.2f}, "
              f"zstd-19 {flac_tot[0] / flac_tot[2]:.2f}, FLAC {flac_tot[0] / flac_tot[3]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
