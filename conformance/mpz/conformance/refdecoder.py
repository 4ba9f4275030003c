"""The reference decoder as a conformance-runner command.

Usage: ``python -m mpz.conformance.refdecoder IN.mpz OUT.npy``

Writes OUT.npy (float64 [frames, markers, 3], NaN at gaps) and
OUT.npy.intlayer (the spec §7.1 integer-layer digest, hex). Exit status:
0 decoded, 2 the file is rejected (the MPZError message on stderr), 3 usage
or I/O error.
"""
from __future__ import annotations

import sys

import numpy as np


def decode_file(src: str):
    """(positions float64 [F, M, 3] with NaN gaps, integer-layer digest hex) of an MPZ file."""
    from mpz.conformance.manifest import intlayer_digest
    from mpz.decoder import decode_layers
    with open(src, "rb") as fh:
        data = fh.read()
    d = decode_layers(data)
    return d.positions(), intlayer_digest(d.q, d.valid)


def write_output(dst: str, x, digest: str | None) -> None:
    with open(dst, "wb") as fh:                      # np.save(path) would append ".npy"
        np.save(fh, np.ascontiguousarray(x, dtype="<f8"), allow_pickle=False)
    if digest is not None:
        with open(dst + ".intlayer", "w", encoding="ascii") as fh:
            fh.write(digest + "\n")


def main(argv=None) -> int:
    from mpz.errors import MPZError
    argv = sys.argv[1:] if argv is None else list(argv)
    if len(argv) != 2:
        print("usage: python -m mpz.conformance.refdecoder IN.mpz OUT.npy", file=sys.stderr)
        return 3
    src, dst = argv
    try:
        x, digest = decode_file(src)
    except MPZError as exc:
        print(f"{type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"{src}: {exc.strerror or exc}", file=sys.stderr)
        return 3
    try:
        write_output(dst, x, digest)
    except OSError as exc:
        print(f"{dst}: {exc.strerror or exc}", file=sys.stderr)
        return 3
    return 0


if __name__ == "__main__":
    sys.exit(main())
