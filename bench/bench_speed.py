"""Encode and decode speed in MB/s of raw float32, next to lossless zstd -19 and the
error-bounded peers (qpz, SZ3), in the same process.

    python bench/bench_speed.py [--files cmu_135_02 bvh/cmu_14_19 ... | --files all]
                                [--bounds 1mm default] [--threads 1,2] [--repeat 3]
                                [--json out.json]

For every file (a name under ../shared/data, or ``$MPZ_SHARED_DATA``, with or without its
folder and extension, or ``all`` for every C3D, TRC, BVH and AMC file there) and bound
("1mm": 1 mm in the file's units, or 1 unit when it declares none; "default": the
encoder's default bound) it prints MPZ's encode speed with each thread count (the
``threads`` option: 1 = one core, 2 = both cores of this machine; the bytes are the same),
its decode speed, ratio and decoded max error, and the peers. The numba kernels are
loaded first on the first file asked for (not timed).

The yardstick input (issue 15: "on the same float32 bytes") is every sample MPZ codes, as
float32 (``_common.coded_float32``): the marker positions, and a C3D's point words, model
outputs and analog samples, or a skeleton's channel values. ``MB`` is its size; every MB/s
and ratio of a row counts those bytes. For a file with such extras a second zstd row,
``zstd -19 mk``, is given the marker positions alone (12 bytes per marker-frame: the input
of the stops before this yardstick), and so are the error-bounded peers, which code markers
only (``(mk)``; their MB is the markers' float32 size). The peers are ``bench/peers.py``'s,
the ones bench_rd.py runs:

- ``zstd -19``: lossless, on the yardstick input;
- ``qpz``: quantise with step 2E/sqrt(3), second-order prediction, zstd -19 on the
  residuals as zigzag byte planes, and the validity mask when the motion has gaps (so that
  it can give the gaps back); decode = zstd + reconstruct + scale;
- ``SZ3``: SZ3 (``pysz``, the ``bench`` extra) at an absolute bound per value, in the
  configuration (layout x predictor) that gives the fewest bytes within the bound for this
  file and bound, chosen once before the timing (``peers.sz3_codec``; the choice is in the
  JSON). Without pysz one line says SZ3 is skipped.

``max err`` is the largest Euclidean error of the decoded positions over the valid
samples, in the file's units; a row whose error passes its bound is flagged ``OVER``
and the command exits 1. The peers run at the bounded rows only (not ``default``).

Times are the best of at least ``--repeat`` wall-clock runs, more until 0.3 s have passed
(``timed``; zstd's too: on a short clip the best of three varied threefold from one run
of this bench to the next). The machine may be shared: the load average is printed with the
table, and ``cpu`` is the process CPU time of the best one-thread encode (a figure that does
not depend on the other processes). ``enc xN`` are MPZ's encode speeds with N threads;
``peer enc`` is a peer's encode speed (one thread). The same zstd -19 compression is timed
twice, on purpose, and so gives two figures: its own row, ``zstd -19 alone``, is timed on
its own, before MPZ; ``x zstd`` is MPZ's fastest encode over zstd -19's on the same bytes
of the same file, the two timed in alternation (``timed_together``: rounds of one call of
each, so that the host's drift moves both; MPZ's ``enc`` columns come from those rounds
too), and the ``total`` lines give zstd's speed from those alternated rounds (one figure
per bound asked, since each bound's rounds are timed apart). ``x mk`` is the alternated
ratio over zstd's time on the markers alone (MPZ still coding everything).

The last lines give the verdicts: issue 4 (encode >= 2 MB/s, decode >= 20 MB/s); issue 15
on cmu_135_02 at 1 mm (the issue's own measurement: encode with both cores >= 2x zstd -19,
decode >= 0.1x zstd's decode speed) and the issue's table there (MPZ, zstd -19, qpz and SZ3
encode and decode MB/s); every row against 2x, naming those below; every row's decode
against 0.1x zstd -19's decompression of the same bytes timed in alternation with it
(``dec x``), naming those below; and the rows' totals
(bytes over summed best times, one core and both), which is the archive's view: a corpus
run gives each file one core.

Exit status: 0; 1 when a decoded max error passes its bound, or a thread count changed
MPZ's bytes, or zstandard (the ``bench`` extra) is missing; 2 for a usage error. An absent
or empty data folder prints "skipped: ..." and exits 0.
"""
from __future__ import annotations

import argparse
from functools import partial
import json
import math
import os
from pathlib import Path
import sys
import time

import numpy as np

from _common import (
    RECORDING_EXTS,
    cannot_run,
    coded_float32,
    find_recording,
    has_option,
    is_bound_label,
    positive_int,
    shared_data_dir,
    shared_data_name,
    warm_up,
)
import mpz
import mpz.io
from peers import PeerMissing, max_error, qpz_codec, sz3_codec

DEFAULT_FILES = ["c3d/cmu_135_02", "c3d/cmu_02_01", "c3d/HDM_dg_06-03_03_120",
                 "c3d/auckland_FMC_MH0222_BP06", "bvh/cmu_14_19", "amc/49_18"]
EXTS = RECORDING_EXTS
#: the encoder has the threads option (issue 15); without it every column is one thread
HAS_THREADS = has_option("threads")


def find(root: Path, name: str) -> Path:
    """:func:`_common.find_recording`, or SystemExit naming what is missing."""
    p = find_recording(root, name)
    if p is not None:
        return p
    raise SystemExit(f"no file {name!r} under {root} ({shared_data_name()})")


#: every timing runs for at least this long (and ``--repeat`` times): the best of three
#: 4 ms runs of zstd on a short clip varied by 3x from one bench to the next (stop 28)
MIN_SECONDS = 0.3
MAX_RUNS = 100


def timed(fn, repeat: int) -> tuple[float, float]:
    """(best wall seconds, process CPU seconds of that run) over at least ``repeat`` calls,
    and more until :data:`MIN_SECONDS` have passed (at most :data:`MAX_RUNS`): the same
    rule for every codec of a row, so that short files are timed as steadily as long
    ones."""
    best = (math.inf, math.inf)
    start = time.perf_counter()
    runs = 0
    while runs < repeat or (time.perf_counter() - start < MIN_SECONDS and runs < MAX_RUNS):
        c, w = time.process_time(), time.perf_counter()
        fn()
        w, c = time.perf_counter() - w, time.process_time() - c
        best = min(best, (w, c))
        runs += 1
    return best


def timed_together(fns: dict, repeat: int) -> dict:
    """:func:`timed` of several functions in alternation: rounds of one call each (the
    order turning every round), at least ``repeat`` rounds and until each function has
    had :data:`MIN_SECONDS` in all; the best (wall, CPU) of each. A ratio of two of them
    is then taken over the same stretch of the host's load: timed one after the other,
    02_01.amc's encode moved from 1.15x to 1.87x zstd -19 between two runs ten minutes
    apart (stop 34)."""
    best = {k: (math.inf, math.inf) for k in fns}
    spent = dict.fromkeys(fns, 0.0)
    keys = list(fns)
    rounds = 0
    while rounds < repeat or (min(spent.values()) < MIN_SECONDS and rounds < MAX_RUNS):
        for k in keys[rounds % len(keys):] + keys[:rounds % len(keys)]:
            c, w = time.process_time(), time.perf_counter()
            fns[k]()
            w, c = time.perf_counter() - w, time.process_time() - c
            best[k] = min(best[k], (w, c))
            spent[k] += w
        rounds += 1
    return best


def bound_kwargs(m, label: str) -> tuple[dict, float | None, str]:
    """Encoder keywords, the bound in motion units (None: default) and its description."""
    from _common import mm_per_unit
    if label == "default":
        return {}, None, "default"
    mm = float(label.removesuffix("mm"))
    per = mm_per_unit(m)                                    # unitless BVH: the skeleton's
    e = mm / per if per else mm
    return {"max_error": e}, e, label if per else f"{mm:g} unit"


def files_of(root: Path, names: list[str]) -> list[Path]:
    """The files named on the command line; ``all``: every recording under ``root``."""
    if names == ["all"]:
        return sorted(p for p in root.rglob("*") if p.suffix.lower() in EXTS)
    return [find(root, n) for n in names]


def thread_counts(text: str) -> list[int]:
    """``--threads``: comma-separated counts of 1 or more (argparse type)."""
    try:
        counts = [int(t) for t in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"wants whole numbers such as 1,2, got {text!r}") from None
    if any(t < 1 for t in counts):
        raise argparse.ArgumentTypeError(f"wants counts of 1 or more, got {text!r}")
    return list(dict.fromkeys(counts))


def bound_label(text: str) -> str:
    """``--bounds``: ``default``, or a positive length in mm such as ``1mm`` (argparse
    type)."""
    if not is_bound_label(text):
        raise argparse.ArgumentTypeError(
            f"wants default or a length in mm such as 1mm, got {text!r}")
    return text


def _sz3_missing() -> str | None:
    """PeerMissing's message when pysz (SZ3) is not installed, else None."""
    import peers
    try:
        peers._pysz()
    except PeerMissing as exc:
        return str(exc)
    return None


def run(args) -> tuple[list[dict], int]:
    """The table's rows, and the exit status (1: a bound passed or the bytes moved)."""
    import zstandard
    root = shared_data_dir()
    assert root is not None
    threads: list[int] = args.threads
    paths = files_of(root, args.files)
    rows = []
    status = 0
    warm_up(paths[0])                                           # JIT warm-up, not timed
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs; MB/s of raw "
          f"float32 (every sample MPZ codes: see the docstring); best of {args.repeat} runs "
          f"or more (at least {MIN_SECONDS} s each)")
    print("enc xN: MPZ with N threads; peer enc: one thread. zstd -19 alone: timed on its "
          "own; x zstd, x mk: MPZ over zstd -19 timed in alternation with it (so other "
          "figures for the same bytes); MPZ's dec and dec x: its decode, and its speed over "
          "zstd -19's decompression of the same bytes, the two timed in alternation")
    sz3_missing = _sz3_missing()
    if sz3_missing:
        print(f"SZ3 skipped: {sz3_missing}")
    head = (f"{'file':<28} {'MB':>5} {'bound':>7} {'codec':<17} " + " ".join(
        f"{'enc x' + str(t):>7}" for t in threads) + f" {'peer enc':>8} {'cpu s':>6} "
        f"{'dec':>7} {'ratio':>6} {'max err':>8} {'x zstd':>6} {'x mk':>5} {'dec x':>6}")
    print(head)
    blank = " " * (8 * len(threads))            # the MPZ thread columns, for the peers' rows

    def flag(err: float, e: float | None) -> str:
        nonlocal status
        if e is not None and err > e:
            status = 1
            return " OVER"
        return ""

    def zstd_row(label: str, data: bytes, codec: str) -> tuple[dict, bytes]:
        """zstd -19 timed alone on ``data``: its row, and the compressed bytes (which the
        MPZ rows' decode is timed in alternation with)."""
        zc = zstandard.ZstdCompressor(level=19)
        z = zc.compress(data)
        tz, _ = timed(lambda: zc.compress(data), args.repeat)
        tzd, _ = timed(lambda: zstandard.ZstdDecompressor().decompress(z), args.repeat)
        mb = len(data) / 1e6
        print(f"{label:<28} {mb:>5.2f} {'':>7} {codec + ' alone':<17} {blank}{mb / tz:>8.1f} "
              f"{'':>6} {mb / tzd:>7.1f} {len(data) / len(z):>6.2f}")
        return {"codec": codec, "timing": "alone", "mb": mb, "enc": mb / tz,
                "dec": mb / tzd, "ratio": len(data) / len(z)}, z

    def peer_row(path: Path, m, desc: str, e: float, codec: str, enc, dec,
                 extra: dict) -> None:
        """Time one error-bounded peer (its configuration already chosen) on the markers,
        and check its decoded positions against the bound."""
        data = enc()
        err = max_error(m, dec(data))
        tq, _ = timed(enc, args.repeat)
        tqd, _ = timed(lambda: dec(data), args.repeat)
        qmb = m.n_frames * m.n_markers * 12 / 1e6
        ratio = qmb * 1e6 / len(data)
        print(f"{'':<28} {qmb:>5.2f} {desc:>7} {codec + ' (mk)':<17} {blank}{qmb / tq:>8.1f} "
              f"{'':>6} {qmb / tqd:>7.1f} {ratio:>6.2f} {err:>8.4g}{flag(err, e)}")
        rows.append({"file": path.stem, "bound": desc, "codec": codec, "mb": qmb,
                     "enc": qmb / tq, "dec": qmb / tqd, "ratio": ratio, "bytes": len(data),
                     "E": e, "max_err": err, **extra})

    for path in paths:
        m = mpz.io.read(path)
        coded = coded_float32(m)
        markers = np.nan_to_num(m.positions.astype(np.float32)).tobytes()
        raw, mb = len(coded), len(coded) / 1e6
        row, z = zstd_row(path.stem[:27], coded, "zstd -19")
        rows.append({"file": path.stem, **row})
        if len(markers) != raw:
            rows.append({"file": path.stem, **zstd_row("", markers, "zstd -19 mk")[0]})
        for b in args.bounds:
            kw, e, desc = bound_kwargs(m, b)
            if e is not None:
                peer_row(path, m, desc, e, "qpz", *qpz_codec(m, e), {})
                if not sz3_missing:
                    try:            # the best configuration, chosen once, outside the timing
                        (se, sd), config, _ = sz3_codec(m, e)
                    except ValueError as exc:
                        print(f"{'':<28} {'':>5} {desc:>7} {'SZ3 (mk)':<17} skipped: {exc}")
                    else:
                        peer_row(path, m, desc, e, "SZ3", se, sd, {"config": config})
            data = mpz.encode(m, **kw)
            encoders = {}
            for t in threads:
                tk = {"threads": t} if HAS_THREADS else {}      # an mpz before issue 15
                if mpz.encode(m, **tk, **kw) != data:
                    print(f"ERROR {path.name} {desc}: threads={t} changed the bytes")
                    status = 1
                encoders[t] = lambda tk=tk, m=m, kw=kw: mpz.encode(m, **tk, **kw)
            # MPZ and zstd -19 in alternation: the ratio over the same stretch of load
            zc = zstandard.ZstdCompressor(level=19)
            pair = timed_together({**encoders, "zstd": partial(zc.compress, coded),
                                   **({"zstd mk": partial(zc.compress, markers)}
                                      if len(markers) != raw else {})}, args.repeat)
            enc = {t: mb / pair[t][0] for t in threads}
            sec = {t: pair[t][0] for t in threads}
            cpu = pair[1][1] if 1 in pair else math.nan
            tz = pair["zstd"][0]
            tzm = pair.get("zstd mk", pair["zstd"])[0]
            # the decode in alternation with zstd's decompression of the same bytes (issue
            # 15.1's 0.1x aim, read row by row as the encode is)
            paired = timed_together({"mpz": partial(mpz.decode, data), "zstd": partial(
                zstandard.ZstdDecompressor().decompress, z)}, args.repeat)
            td, tzd = paired["mpz"][0], paired["zstd"][0]
            err = max_error(m, mpz.decode(data).positions)
            fastest = min(sec.values())
            # the issue-15 yardstick: the fastest thread count over zstd -19, this run
            print(f"{'':<28} {mb:>5.2f} {desc:>7} {'MPZ':<17} " + " ".join(
                f"{enc[t]:>7.1f}" for t in threads) + f" {'':>8} {cpu:>6.3f} {mb / td:>7.1f} "
                f"{raw / len(data):>6.2f} {err:>8.4g} {tz / fastest:>6.2f} "
                f"{tzm / fastest:>5.2f} {tzd / td:>6.3f}{flag(err, e)}")
            rows.append({"file": path.stem, "name": path.name, "bound": desc, "asked": b,
                         "codec": "mpz", "mb": mb, "frames": m.n_frames,
                         **{f"enc_{t}": enc[t] for t in threads},
                         **{f"sec_{t}": sec[t] for t in threads}, "cpu_s_1": cpu,
                         "dec": mb / td, "ratio": raw / len(data), "bytes": len(data),
                         "E": e, "max_err": err,
                         "zstd_s": tz, "zstd_mk_s": tzm, "zstd_alternated_enc": mb / tz,
                         "x_zstd": tz / fastest, "x_zstd_mk": tzm / fastest,
                         "zstd_dec_s": tzd, "dec_x_zstd": tzd / td})
    return rows, status


def verdict(rows: list[dict], threads: list[int]) -> None:
    mpz_rows = [r for r in rows if r["codec"] == "mpz"]
    if not mpz_rows:
        return
    top = max(threads)
    enc_ok = all(r[f"enc_{top}"] >= 2 for r in mpz_rows)
    dec_ok = all(r["dec"] >= 20 for r in mpz_rows)
    print(f"issue 4: encode >= 2 MB/s: {'MET' if enc_ok else 'MISSED'}; decode >= 20 MB/s: "
          f"{'MET' if dec_ok else 'MISSED'}")
    z = next((r for r in rows if r["codec"] == "zstd -19" and r["file"] == "cmu_135_02"), None)
    m1 = next((r for r in mpz_rows if r["file"] == "cmu_135_02" and r["bound"] == "1mm"), None)
    if z and m1:
        # encode: against zstd timed in alternation with it (the row's x zstd yardstick)
        e, d = m1["zstd_s"] / m1[f"sec_{top}"], m1["dec"] / z["dec"]
        print(f"issue 15 (cmu_135_02, 1 mm, {top} threads): encode {e:.2f}x zstd -19 "
              f"alternated (target 2x: {'MET' if e >= 2 else 'MISSED'}); decode {d:.3f}x "
              f"zstd -19 alone (target 0.1x: {'MET' if d >= 0.1 else 'MISSED'})")
        # the table: every codec's encode / decode MB/s and ratio on that file
        peer = {r["codec"]: r for r in rows if r["file"] == "cmu_135_02"
                and r.get("bound") == "1mm" and r["codec"] in ("qpz", "SZ3")}
        parts = [f"MPZ ({top} threads) {m1[f'enc_{top}']:.1f} / {m1['dec']:.1f} "
                 f"(ratio {m1['ratio']:.2f}, {m1['mb']:.2f} MB)",
                 f"zstd -19 alone {z['enc']:.1f} / {z['dec']:.1f} (ratio {z['ratio']:.2f})"]
        parts += [f"{c} {r['enc']:.1f} / {r['dec']:.1f} (ratio {r['ratio']:.2f}, "
                  f"markers {r['mb']:.2f} MB)" for c, r in peer.items()]
        if "SZ3" not in peer:
            parts.append("SZ3 not run")
        print("issue 15 table (cmu_135_02, 1 mm), encode / decode MB/s: " + "; ".join(parts))
    # every row against the same yardstick, so that no file is left out of the verdict
    for key, what in (("x_zstd", "the same bytes"), ("x_zstd_mk", "zstd given the markers")):
        missed = [f"{r['name']} {r['bound']} ({r[key]:.2f}x)" for r in mpz_rows if r[key] < 2]
        print(f"issue 15, every row ({what}; fastest thread count / zstd -19 alternated): "
              f"{len(mpz_rows) - len(missed)} of {len(mpz_rows)} at 2x or more"
              + (f"; below: {', '.join(missed)}" if missed else ""))
    missed = [f"{r['name']} {r['bound']} ({r['dec_x_zstd']:.3f}x)" for r in mpz_rows
              if r["dec_x_zstd"] < 0.1]
    print(f"issue 15, decode every row (MPZ / zstd -19 decompression alternated): "
          f"{len(mpz_rows) - len(missed)} of {len(mpz_rows)} at 0.1x or more"
          + (f"; below: {', '.join(missed)}" if missed else ""))
    # the archive's view: all rows' bytes over their summed best times (per bound asked)
    for b in dict.fromkeys(r["asked"] for r in mpz_rows):
        rs = [r for r in mpz_rows if r["asked"] == b]
        mb = sum(r["mb"] for r in rs)
        zs = sum(r["zstd_s"] for r in rs)
        parts = [f"x{t} {mb / sum(r[f'sec_{t}'] for r in rs):.1f} MB/s = "
                 f"{zs / sum(r[f'sec_{t}'] for r in rs):.2f}x" for t in threads]
        print(f"total, {b}, {len(rs)} files, {mb:.1f} MB: zstd -19 alternated with these "
              f"encodes {mb / zs:.1f} MB/s; MPZ " + ", ".join(parts))
    over = [f"{r['file']} {r['bound']} {r['codec']} ({r['max_err']:.4g} > {r['E']:.4g})"
            for r in rows if r.get("E") is not None and r["max_err"] > r["E"]]
    print("decoded max error within the bound: "
          + ("every bounded row" if not over else "BROKEN by " + ", ".join(over)))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--files", nargs="+", default=DEFAULT_FILES,
                    help="names under the data folder, or all (default: six files)")
    ap.add_argument("--bounds", nargs="+", type=bound_label, default=["1mm", "default"],
                    help="default, or lengths in mm such as 1mm (default: 1mm default)")
    ap.add_argument("--threads", type=thread_counts, default=[1, 2],
                    help="comma-separated thread counts to time (default 1,2)")
    ap.add_argument("--repeat", type=positive_int, default=3,
                    help="at least this many timed runs of each codec (default 3)")
    ap.add_argument("--json", help="write the rows here")
    args = ap.parse_args(argv)
    status = cannot_run("bench_speed")
    if status is not None:
        return status
    try:
        rows, status = run(args)
    except PeerMissing as exc:
        print(f"bench_speed: {exc}", file=sys.stderr)
        return 1
    verdict(rows, args.threads)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return status


if __name__ == "__main__":
    sys.exit(main())
