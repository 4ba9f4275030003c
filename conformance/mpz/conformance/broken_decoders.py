"""Deliberately broken decoders, to prove that the runner catches each kind of bug.

Usage: ``python -m mpz.conformance.broken_decoders MODE IN.mpz OUT.npy``

Each mode decodes with the reference and then breaks exactly one thing, so that
``conformance/test_runner.py`` can assert that the runner fails it for that reason
(and passes it where the bug does not show). MODE is one of:

Float tier (the integer-layer digest is left out unless noted, so only the float
comparison can see the bug):

``offbyone``
    adds one grid step to one valid sample (the middle frame, last marker, axis y).
``overtol``
    adds 1.5 x max_abs of §7.1 to that sample: just over the tolerance, so a runner
    with any slack on max_abs (even a factor 2) passes it.
``half-tol``
    adds max_abs / 2 to every valid coordinate: within max_abs everywhere, but the
    RMS error is max_abs / 2, so it fails any manifest whose rms tolerance is lower.
``fill-gaps``
    writes 0.0 instead of NaN at every gap: a value where a gap is expected. Writes
    the correct digest (the integers and the mask are right; the output is not).
``extra-gap``
    writes NaN at one valid sample (a gap where a value is expected); correct digest.

Integer tier and acceptance:

``noresidual``
    ignores the residual layer (RESI chunks decode as zeros), as a decoder written
    from the paper alone would; writes the digest of what it decoded.
``accept-all``
    never rejects: files the reference rejects come out as zeros of the declared
    shape (or [1, 1, 3]).

The rest of the decoded result (spec §6.8, the ``OUT.npy.json`` sidecar of §7.3):

``no-sidecar``
    a 1.0-contract decoder: correct array and digest, no sidecar (passes only with
    ``--array-only``).
``nfc-names``
    Unicode-normalises the marker names (NFC), which §4.2 forbids: names are bytes.
``rate-15-digits``
    writes the rate with 15 significant digits (C's ``%.15g``), which changes a
    float32 C3D rate such as 65.0364227294921875.
``first-meta-value``
    keeps the first value of a repeated meta key instead of the last (§4.11).

Rejecting the wrong way (each decodes valid files correctly):

``crash``
    raises an exception on every file (so exits 1, which also "rejects" every
    invalid vector: the exit-code contract cannot tell the two apart).
``segv-on-invalid``
    kills itself with SIGSEGV where the reference rejects the file.
``abort-on-invalid``
    calls ``abort()`` (SIGABRT) where the reference rejects the file.
``exit139-on-invalid``
    exits 139 = 128 + SIGSEGV, as a shell wrapper reports a crashed decoder.
``oom-on-invalid``
    allocates 64 GiB where the reference rejects the file, so it dies of MemoryError
    under the runner's address-space limit (a decoder that trusts a count).
``hang-on-invalid``
    sleeps for an hour where the reference rejects the file.

And one broken *encoder*, ``python -m mpz.conformance.broken_decoders
loose-encoder IN.npy OUT.mpz --max-error E``, which encodes with bound 2E
(so it declares more than it was asked for).
"""
from __future__ import annotations

import os
import signal
import sys
import time
from typing import Any
import unicodedata

import numpy as np
from numpy.typing import NDArray

MODES = ("offbyone", "overtol", "half-tol", "fill-gaps", "extra-gap", "noresidual",
         "accept-all", "no-sidecar", "nfc-names", "rate-15-digits", "first-meta-value",
         "crash", "segv-on-invalid", "abort-on-invalid", "exit139-on-invalid", "oom-on-invalid",
         "hang-on-invalid")


def _decode(data: bytes, *, residual: bool = True) -> tuple[Any, NDArray[np.int64],
                                                           NDArray[np.bool_],
                                                           NDArray[np.float64], str]:
    from mpz import decoder
    from mpz.conformance.manifest import intlayer_digest
    s = decoder.read_stream(data)
    valid = decoder.decode_mask(s)
    if not residual:
        saved = decoder.decode_residual

        def zeros(s: decoder.Stream, i: int, *,
                  out: NDArray[np.int64] | None = None) -> NDArray[np.int64]:
            if out is not None:
                out[...] = 0
                return out
            return np.zeros((s.header.frame_count, s.nodes[i].member_count, 3), np.int64)
        decoder.decode_residual = zeros
        try:
            q = decoder.decode_integers(s)
        finally:
            decoder.decode_residual = saved
    else:
        q = decoder.decode_integers(s)
    return s, q, valid, decoder.to_positions(s, q, valid), intlayer_digest(q, valid)


def _on_invalid(mode: str) -> int:
    """What the rejecting modes do instead of a clean non-zero exit."""
    if mode == "segv-on-invalid":
        os.kill(os.getpid(), signal.SIGSEGV)
    elif mode == "abort-on-invalid":
        os.abort()
    elif mode == "exit139-on-invalid":
        os._exit(128 + int(signal.SIGSEGV))
    elif mode == "oom-on-invalid":
        hog = bytearray(64 << 30)        # MemoryError under the runner's RLIMIT_AS
        return len(hog)
    elif mode == "hang-on-invalid":
        time.sleep(3600)
    return 2


def _first_meta(s: Any) -> dict[str, str]:
    """The meta chunk with the *first* value of each repeated key (the bug)."""
    from mpz.chunks import Meta
    out: dict[str, str] = {}
    for c in s.chunks:
        if isinstance(c.record, Meta):
            for e in c.record.entries:
                out.setdefault(e.key, e.value)
    return out


def main(argv: list[str] | None = None) -> int:
    from mpz.conformance.refdecoder import sidecar_of, write_output
    from mpz.errors import MPZError
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["loose-encoder"] and len(argv) == 5 and argv[3] == "--max-error":
        from mpz.conformance.refencoder import main as encode
        return encode([argv[1], argv[2], "--max-error", repr(2.0 * float(argv[4]))])
    if len(argv) != 3 or argv[0] not in MODES:
        print(f"usage: python -m mpz.conformance.broken_decoders {{{','.join(MODES)}}} IN OUT",
              file=sys.stderr)
        return 3
    mode, src, dst = argv
    with open(src, "rb") as fh:
        data = fh.read()
    if mode == "crash":
        raise RuntimeError("broken decoder 'crash': deliberate failure")
    try:
        s, q, valid, x, found_digest = _decode(data, residual=(mode != "noresidual"))
    except MPZError as exc:
        if mode != "accept-all":
            print(f"{type(exc).__name__}: {exc}", file=sys.stderr)
            return _on_invalid(mode)
        from mpz.chunks import Mhdr
        from mpz.container import scan
        shape = (1, 1, 3)
        found = scan(data).chunks
        h = found[0].record if found else None
        if isinstance(h, Mhdr) and h.frame_count * h.marker_count <= 1 << 20:
            shape = (h.frame_count, h.marker_count, 3)
        write_output(dst, np.zeros(shape), None,
                     {"names": [], "rate": 1.0, "units": 0, "meta": {}})
        return 0
    digest: str | None = found_digest
    side: dict[str, Any] | None = sidecar_of(s)
    assert side is not None
    F, M = valid.shape
    f = F // 2
    ms = np.flatnonzero(valid[f])
    if mode in ("offbyone", "overtol", "half-tol"):
        from mpz.conformance.manifest import tolerances
        tol = tolerances(float(s.quant.step), float(np.abs(x[valid]).max(initial=0.0)))
        x = x.copy()
        if mode == "half-tol":
            x[valid] += tol["max_abs"] / 2
        elif ms.size:
            x[f, ms[-1], 1] += float(s.quant.step) if mode == "offbyone" else 1.5 * tol["max_abs"]
        digest = None
    elif mode == "fill-gaps":
        x = np.where(np.isnan(x), 0.0, x)
    elif mode == "extra-gap" and ms.size:
        x = x.copy()
        x[f, ms[-1], :] = np.nan
    elif mode == "no-sidecar":
        side = None
    elif mode == "nfc-names":
        side["names"] = [unicodedata.normalize("NFC", n) for n in side["names"]]
    elif mode == "rate-15-digits":
        side["rate"] = float(f"{side['rate']:.15g}")
    elif mode == "first-meta-value":
        side["meta"] = _first_meta(s)
    write_output(dst, x, digest, side)
    return 0


if __name__ == "__main__":
    sys.exit(main())
