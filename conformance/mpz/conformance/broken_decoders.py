"""Deliberately broken decoders, to prove that the runner catches each kind of bug.

Usage: ``python -m mpz.conformance.broken_decoders MODE IN.mpz OUT.npy``

MODE is one of:

``offbyone``
    decodes correctly, then adds one grid step to one valid sample (the
    middle frame, last marker, axis y); writes no integer-layer digest, so
    only the float tier can catch it.
``noresidual``
    ignores the residual layer (RESI chunks decode as zeros), as a decoder
    written from the paper alone would; writes the digest of what it decoded.
``accept-all``
    never rejects: files the reference rejects come out as zeros of the
    declared shape (or [1, 1, 3]).
``crash``
    raises an exception on every file (so exits 1, which also "rejects"
    every invalid vector: the exit-code contract cannot tell the two apart).

And one broken *encoder*, ``python -m mpz.conformance.broken_decoders
loose-encoder IN.npy OUT.mpz --max-error E``, which encodes with bound 2E
(so it declares more than it was asked for).
"""
from __future__ import annotations

import sys

import numpy as np

MODES = ("offbyone", "noresidual", "accept-all", "crash")


def _decode(data: bytes, *, residual=True):
    from mpz import decoder
    from mpz.conformance.manifest import intlayer_digest
    s = decoder.read_stream(data)
    valid = decoder.decode_mask(s)
    if not residual:
        saved = decoder.decode_residual
        decoder.decode_residual = lambda s, i: np.zeros(
            (s.header.frame_count, s.nodes[i].member_count, 3), np.int64)
        try:
            q = decoder.decode_integers(s)
        finally:
            decoder.decode_residual = saved
    else:
        q = decoder.decode_integers(s)
    return s, q, valid, decoder.to_positions(s, q, valid), intlayer_digest(q, valid)


def main(argv=None) -> int:
    from mpz.conformance.refdecoder import write_output
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
        s, q, valid, x, digest = _decode(data, residual=(mode != "noresidual"))
    except MPZError as exc:
        if mode != "accept-all":
            print(f"{type(exc).__name__}: {exc}", file=sys.stderr)
            return 2
        from mpz.chunks import Mhdr
        from mpz.container import scan
        shape = (1, 1, 3)
        found = scan(data).chunks
        h = found[0].record if found else None
        if isinstance(h, Mhdr) and h.frame_count * h.marker_count <= 1 << 20:
            shape = (h.frame_count, h.marker_count, 3)
        write_output(dst, np.zeros(shape), None)
        return 0
    if mode == "offbyone":
        F, M = valid.shape
        f = F // 2
        ms = np.flatnonzero(valid[f])
        if ms.size:
            x = x.copy()
            x[f, ms[-1], 1] += float(s.quant.step)
        digest = None
    write_output(dst, x, digest)
    return 0


if __name__ == "__main__":
    sys.exit(main())
