"""The reference decoder as a conformance-runner command.

Usage: ``python -m mpz.conformance.refdecoder [--implements 1.N] IN.mpz OUT.npy``

``--implements 1.0`` decodes as a decoder of MPZ 1.0 alone does (spec §2.1): the chunk
types of 1.1 are unknown to it, so it checks their frame and CRC and skips them (§2.3).

Writes the three files of the spec §7.3 contract: OUT.npy (float64
[frames, markers, 3], NaN at gaps), OUT.npy.json (names, rate, units code and
meta, §6.8) and OUT.npy.intlayer (the spec §7.1 integer-layer digest, hex).
Exit status: 0 decoded, 2 the file is rejected (the MPZError message on
stderr), 3 usage or I/O error.
"""
from __future__ import annotations

import json
import sys
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: the sidecar written next to OUT.npy (spec §7.3: the output path with ".json" appended)
SIDECAR_SUFFIX = ".json"
#: the optional integer-layer digest file (spec §7.3)
DIGEST_SUFFIX = ".intlayer"


def sidecar_of(stream: Any) -> dict[str, Any]:
    """The §7.3 sidecar of a decoded :class:`mpz.decoder.Stream`: names in MNAM order, the
    rate as the exact binary64 of MHDR, the units code and the metadata (last value of a
    repeated key, §4.11; ``{}`` without a meta chunk)."""
    h = stream.header
    return {"names": list(stream.names), "rate": float(h.rate), "units": int(h.units),
            "meta": dict(stream.meta)}


def decode_file(src: str, minor: int | None = None
                ) -> tuple[NDArray[np.float64], str, dict[str, Any]]:
    """(positions float64 [F, M, 3] with NaN gaps, integer-layer digest hex, sidecar) of a
    file, read by a decoder of 1.0 .. 1.``minor`` (default: every minor version this package
    implements)."""
    with open(src, "rb") as fh:
        data = fh.read()
    return decode_bytes(data, minor)


def decode_bytes(data: bytes, minor: int | None = None
                 ) -> tuple[NDArray[np.float64], str, dict[str, Any]]:
    """:func:`decode_file` of the bytes of a file."""
    from mpz.decoder import decode_layers
    return outputs(decode_layers(data) if minor is None else decode_layers(data, minor=minor))


def outputs(d: Any) -> tuple[NDArray[np.float64], str, dict[str, Any]]:
    """(positions, integer-layer digest, sidecar) of a :class:`mpz.decoder.Decoded`: what
    the §7.3 contract has a decoder write."""
    from mpz.conformance.manifest import intlayer_digest
    return d.positions(), intlayer_digest(d.q, d.valid), sidecar_of(d.stream)


def implemented_minor(text: str) -> int:
    """The minor version of ``--implements 1.N``: 1.0 up to the version this package
    implements. Raises ValueError naming what is allowed."""
    from mpz.spec.grammar import VERSION_MAJOR, VERSION_MINOR
    allowed = [f"{VERSION_MAJOR}.{n}" for n in range(VERSION_MINOR + 1)]
    if text not in allowed:
        raise ValueError(f"--implements {text!r}: one of {', '.join(allowed)}")
    return int(text.split(".")[1])


def sidecar_bytes(side: dict[str, Any]) -> bytes:
    """RFC 8259 JSON in UTF-8; Python writes each float in the shortest form that reads back
    exactly, which §7.3 asks for (U+0000 and other controls become escapes)."""
    return (json.dumps(side, ensure_ascii=False, allow_nan=False) + "\n").encode("utf-8")


def write_output(dst: str, x: NDArray[np.float64], digest: str | None,
                 side: dict[str, Any] | None = None) -> None:
    """Write OUT.npy, then OUT.npy.json (if ``side``) and OUT.npy.intlayer (if ``digest``)."""
    with open(dst, "wb") as fh:                      # np.save(path) would append ".npy"
        np.save(fh, np.ascontiguousarray(x, dtype="<f8"), allow_pickle=False)
    if side is not None:
        with open(dst + SIDECAR_SUFFIX, "wb") as fh:
            fh.write(sidecar_bytes(side))
    if digest is not None:
        with open(dst + DIGEST_SUFFIX, "w", encoding="ascii") as fh:
            fh.write(digest + "\n")


def main(argv: list[str] | None = None) -> int:
    from mpz.errors import MPZError
    argv = sys.argv[1:] if argv is None else list(argv)
    minor = None
    if len(argv) == 4 and argv[0] == "--implements":
        try:
            minor = implemented_minor(argv[1])
        except ValueError as exc:
            print(f"refdecoder: {exc}", file=sys.stderr)
            return 3
        argv = argv[2:]
    if len(argv) != 2:
        print("usage: python -m mpz.conformance.refdecoder [--implements 1.N] IN.mpz OUT.npy",
              file=sys.stderr)
        return 3
    src, dst = argv
    try:
        x, digest, side = decode_file(src, minor)
    except MPZError as exc:
        print(f"{type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"{src}: {exc.strerror or exc}", file=sys.stderr)
        return 3
    try:
        write_output(dst, x, digest, side)
    except OSError as exc:
        print(f"{dst}: {exc.strerror or exc}", file=sys.stderr)
        return 3
    return 0


if __name__ == "__main__":
    sys.exit(main())
