#!/usr/bin/env python3
"""Coverage-guided fuzzing of the format readers, and of the encoder on what they accept,
with atheris (not run by CI).

    pip install atheris
    python conformance/fuzz/fuzz_readers.py --seeds SEEDS ../shared/data   # seed corpus
    python conformance/fuzz/fuzz_readers.py -max_total_time=2700 -rss_limit_mb=3000 \\
        -max_len=65536 -timeout=60 CORPUS_DIR SEEDS

An input is one byte that picks the format (its value modulo 6: C3D, TRC, BVH, AMC, NPY,
CSV), then the file's bytes; an AMC's may hold its ASF first (:data:`PAIR`). The properties, for any
bytes:

- ``mpz.io.read`` (of the bytes written to a file of that extension) returns a Motion or
  raises an ``MPZError`` (``InputFormatError`` above all). **Every other exception is a
  crash**, as in fuzz_decoder.py: a reader must say what is wrong with a file, never
  fail in its own code (a ``ValueError`` of numpy, an ``IndexError``, a ``MemoryError``
  of a count the file made up);
- a Motion read is consistent (:func:`mpz.motion.check_consistent`);
- one of at most 2^16 marker-frames encodes at a 1-unit bound (``mpz.encode``) or is
  refused with an ``MPZError``, and what it encodes to decodes with the same shape, the
  same gaps and every valid sample within the bound;
- it writes back to its own format (``mpz.io.write``) or is refused with an ``MPZError``.

Inputs that crashed are kept by atheris (``crash-*``); ``--replay FILE...`` runs the
properties on them without atheris, with the traceback.
"""
from __future__ import annotations

import argparse
import os
import pkgutil
import sys
import tempfile
import warnings

import numpy as np

try:
    import atheris
except ImportError:        # --seeds and --replay need no atheris
    atheris = None

import mpz
from mpz.errors import MPZError
import mpz.io
from mpz.motion import check_consistent

#: the format an input's first byte picks (modulo the length)
FORMATS = (".c3d", ".trc", ".bvh", ".amc", ".npy", ".csv")

#: in an AMC input, what parts an ASF (before) from its AMC (after); without it, the
#: bytes are an AMC read with the fixed ASF of :func:`_fixed_pair`
PAIR = b"\n%%ASF-AMC%%\n"

# keep each input cheap: encode only motions of at most 2^16 marker-frames
MAX_SAMPLES = 1 << 16
#: the bound the encoder is asked to keep (file units)
BOUND = 1.0


def _instrument() -> None:
    """Instrument the Python of the readers and writers (numba kernels cannot be)."""
    from fuzz_decoder import instrument  # this folder: the script's own
    instrument(["mpz.motion", "mpz.skeleton", "mpz.io"] + [
        f"mpz.io.{m.name}" for m in pkgutil.iter_modules(mpz.io.__path__)])


def _fixed_pair() -> tuple[str, str]:
    """The ASF and a 2-frame AMC of the synthetic skeleton of the vectors: the fixed
    partner of a fuzzed AMC that holds no ASF of its own (:data:`PAIR`)."""
    from mpz.tools.make_vectors import _SKELETON_ASF, _skeleton_amc_text
    return _SKELETON_ASF, _skeleton_amc_text(F=2)


def _warm_up() -> None:
    from mpz.synth import generate
    m = generate("walk", frames=20, markers=4, seed=0, gap_fraction=0.1)
    mpz.decode(mpz.encode(m, max_error=BOUND, threads=1))


def read_input(data: bytes, folder: str) -> mpz.Motion | None:
    """The Motion that the input's reader makes of it, or None when it is refused with an
    MPZError (anything else escapes)."""
    if not data:
        return None
    fmt = FORMATS[data[0] % len(FORMATS)]
    body = data[1:]
    path = os.path.join(folder, "take" + fmt)
    asf = os.path.join(folder, "skel.asf")
    if fmt == ".amc":
        skeleton, paired, amc = body.partition(PAIR)
        with open(asf, "wb") as fh:
            fh.write(skeleton if paired else _fixed_pair()[0].encode())
        body = amc if paired else body
    with open(path, "wb") as fh:
        fh.write(body)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return mpz.io.read(path, asf=asf if fmt == ".amc" else None)
    except MPZError:
        return None


def check(data: bytes) -> None:
    """The properties above for one input (raises AssertionError or the escaped exception)."""
    with tempfile.TemporaryDirectory(prefix="mpz-fuzz-") as folder:
        m = read_input(data, folder)
        if m is None:
            return
        check_consistent(m)
        F, M = m.n_frames, m.n_markers
        assert m.positions.shape == (F, M, 3) and m.valid.shape == (F, M)
        if F * M <= MAX_SAMPLES:
            _encodes(m)
        ext = FORMATS[data[0] % len(FORMATS)]
        out = os.path.join(folder, "back" + ext)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                mpz.io.write(m, out, asf=os.path.join(folder, "back.asf")
                             if out.endswith(".amc") else None)
        except MPZError:
            pass


def _encodes(m: mpz.Motion) -> None:
    try:
        blob = mpz.encode(m, max_error=BOUND, threads=1)
    except MPZError:
        return
    d = mpz.decode(blob)
    assert d.positions.shape == m.positions.shape, (d.positions.shape, m.positions.shape)
    assert (d.valid == m.valid).all(), "the gaps differ"
    if m.valid.any():
        err = np.linalg.norm(d.positions[m.valid] - m.positions[m.valid], axis=-1)
        assert float(err.max()) <= BOUND * (1 + 1e-9), f"max error {err.max()} > {BOUND}"


def TestOneInput(data: bytes) -> None:
    check(data)


def make_seeds(folder: str, data: str, frames: int = 8) -> int:
    """Write seed inputs into ``folder``, each under 64 KB: the first ``frames`` frames of
    each real file of ``data`` (its subfolders c3d, trc, bvh, amc; a C3D cut by ezc3d,
    which some of them refuse, the text formats line by line), and the files the writers
    make of a synthetic motion; returns how many."""
    from mpz.synth import generate
    os.makedirs(folder, exist_ok=True)
    n = 0

    def put(fmt: str, body: bytes, name: str) -> None:
        nonlocal n
        with open(os.path.join(folder, name), "wb") as fh:
            fh.write(bytes([FORMATS.index(fmt)]) + body[:65535])
        n += 1

    def files(sub: str, ext: str) -> list[str]:
        d = os.path.join(data, sub)
        return sorted(os.path.join(d, f) for f in os.listdir(d)
                      if f.lower().endswith(ext)) if os.path.isdir(d) else []

    for path in files("c3d", ".c3d"):
        cut = _c3d_cut(path, frames)
        if cut is not None:
            put(".c3d", cut, "real-" + os.path.basename(path))
    for path in files("trc", ".trc"):
        with open(path, "rb") as fh:
            lines = fh.read().splitlines(keepends=True)
        put(".trc", b"".join(lines[:6 + frames]), "real-" + os.path.basename(path))
    for path in files("bvh", ".bvh"):
        with open(path, "rb") as fh:
            text = fh.read()
        head, _, motion = text.partition(b"MOTION")
        rows = motion.splitlines(keepends=True)
        rows = [rows[0], b"Frames: %d\n" % frames, rows[2], *rows[3:3 + frames]]
        put(".bvh", head + b"MOTION" + b"".join(rows), "real-" + os.path.basename(path))
    for path in files("amc", ".amc"):
        asf = os.path.join(os.path.dirname(path), os.path.basename(path).split("_")[0] + ".asf")
        if not os.path.exists(asf):
            asf = next(iter(files("amc", ".asf")), "")
        with open(path, "rb") as fh:
            lines = fh.read().splitlines(keepends=True)
        starts = [i for i, ln in enumerate(lines) if ln.strip().isdigit()]
        amc = b"".join(lines[:starts[frames]] if len(starts) > frames else lines)
        with open(asf, "rb") as fh:
            put(".amc", fh.read() + PAIR + amc, "real-" + os.path.basename(path))
    m = generate("walk", frames=12, markers=5, seed=1, gap_fraction=0.1)
    with tempfile.TemporaryDirectory() as tmp:
        for ext in (".c3d", ".trc", ".npy", ".csv"):
            p = os.path.join(tmp, "synth" + ext)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                mpz.io.write(m, p)
            with open(p, "rb") as fh:
                put(ext, fh.read(), f"synth{ext}")
    asf_text, amc_text = _fixed_pair()
    put(".amc", amc_text.encode(), "fixed.amc")
    put(".amc", asf_text.encode() + PAIR + amc_text.encode(), "fixed-pair.amc")
    return n


def _c3d_cut(path: str, frames: int) -> bytes | None:
    """The first ``frames`` frames of a C3D, as ezc3d writes them (None where ezc3d
    cannot: a processor type it lacks, labels it finds inconsistent)."""
    import ezc3d
    try:
        c = ezc3d.c3d(path, extract_forceplat_data=False)
        points = c["data"]["points"]
        n = min(frames, points.shape[2])
        analogs = c["data"]["analogs"]
        per_frame = analogs.shape[2] // max(points.shape[2], 1) if analogs.size else 0
        c["data"]["points"] = points[:, :, :n]
        if analogs.size:
            c["data"]["analogs"] = analogs[:, :, :n * per_frame]
        if "meta_points" in c["data"]:
            del c["data"]["meta_points"]
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "cut.c3d")
            c.write(out)
            with open(out, "rb") as fh:
                return fh.read()
    except (RuntimeError, ValueError, OSError):
        return None


def main() -> None:
    parser = argparse.ArgumentParser(add_help=False)
    parser.add_argument("--seeds", nargs=2, metavar=("FOLDER", "DATA"))
    parser.add_argument("--replay", nargs="+", metavar="FILE")
    parser.add_argument("-h", "--help", action="store_true")
    known, rest = parser.parse_known_args()
    if known.help:
        print(__doc__)
        return
    if known.seeds:
        print(f"{make_seeds(*known.seeds)} seeds written to {known.seeds[0]}")
        return
    if known.replay:
        for f in known.replay:
            with open(f, "rb") as fh:
                data = fh.read()
            print(f"{f}: {FORMATS[data[0] % len(FORMATS)] if data else '(empty)'}",
                  flush=True)
            check(data)
        return
    from fuzz_decoder import require_atheris  # this folder: the script's own
    require_atheris()
    _warm_up()
    _instrument()
    atheris.Setup([sys.argv[0], *rest], TestOneInput)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
