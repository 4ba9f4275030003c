"""Chunk framing of spec §3: signature, chunks, CRC-32, order, limits.

Strategy: :func:`scan` walks the file with an explicit loop (never
``GreedyRange``), checks every length against its limit *and* against the
bytes left before slicing, and records problems as :class:`~mpz.errors.MPZError`
objects instead of raising, so that ``mpzinfo`` can keep going past a bad CRC.
:func:`parse` is the strict front door used by the decoder: it raises the
first problem. :func:`build` is the inverse; ``parse(build(c)) == c`` and
``build(parse(b)) == b`` (tested).
"""
from __future__ import annotations

from dataclasses import dataclass, field
import zlib

import construct

from mpz.errors import ChecksumError, FormatError, LimitExceededError, MPZError
from mpz.spec.grammar import PAYLOADS, SIGNATURE, ChunkCRC, ChunkHeader

# §8 limits (each one is checked before anything is allocated)
MAX_FRAMES = 1 << 24            # 16 777 216 frames: > 38 h at 120 Hz
MAX_MARKERS = 4096
MAX_SAMPLES = 1 << 26           # F * M <= 67 108 864 marker-frames (1.5 GiB of float64 output)
MAX_CHUNK_LENGTH = 1 << 30      # 1 GiB per chunk
MAX_PATTERN_LENGTH = 4096
MAX_PATTERN_SAMPLES = 1 << 24   # K * L * n_i per node
MAX_SMOOTHING = 16
MAX_SUMMARY_LEVELS = 64
MAX_SUMMARY_VALUES = 1 << 24    # sum over levels of k * D


@dataclass
class Chunk:
    """One chunk as found in (or destined for) a file."""

    type: str
    fields: object = None             # parsed payload (construct Container) or None
    payload: bytes = b""
    offset: int = 0                   # byte offset of the chunk's type field
    crc_stored: int | None = None
    crc_computed: int | None = None

    @property
    def critical(self) -> bool:
        """§2.3: an upper-case first letter marks a critical chunk."""
        return self.type[:1].isupper()

    @property
    def length(self) -> int:
        return len(self.payload)

    @property
    def payload_offset(self) -> int:
        return self.offset + 8

    @property
    def crc_ok(self) -> bool:
        return self.crc_stored == self.crc_computed


@dataclass
class Scan:
    """What :func:`scan` found: the chunks, and every problem on the way."""

    chunks: list = field(default_factory=list)
    errors: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    size: int = 0
    complete: bool = False            # an MEND chunk was reached


def crc32(ctype: bytes, payload: bytes) -> int:
    """§3.3 CRC-32 over the type and the payload."""
    return zlib.crc32(payload, zlib.crc32(ctype)) & 0xFFFFFFFF


def _parse_payload(ctype: bytes, payload: bytes, offset: int):
    grammar = PAYLOADS[ctype]
    try:
        return grammar.parse(payload)
    except (construct.ConstructError, UnicodeDecodeError, ValueError, OverflowError) as exc:
        raise FormatError(f"malformed {ctype.decode()} payload: {_short(exc)}",
                          offset=offset, chunk=ctype.decode(), section="§4") from None


def _short(exc) -> str:
    text = str(exc).strip().splitlines()
    return text[-1] if text else type(exc).__name__


def scan(data: bytes) -> Scan:
    """Walk the chunks of ``data`` and report everything found (never raises MPZError).

    Parameters
    ----------
    data : bytes
        A complete MPZ file.

    Returns
    -------
    Scan
        Chunks parsed so far, plus ``errors`` and ``warnings`` (MPZError
        instances with offsets). Scanning stops at MEND or at the first
        framing error; a bad CRC or a malformed payload is recorded and the
        scan goes on with the next chunk.
    """
    data = bytes(data)
    res = Scan(size=len(data))
    if len(data) < len(SIGNATURE) or data[: len(SIGNATURE)] != SIGNATURE:
        got = data[: len(SIGNATURE)]
        res.errors.append(FormatError(f"bad signature {got!r}, expected {SIGNATURE!r}",
                                      offset=0, section="§3.1"))
        return res
    pos = len(SIGNATURE)
    while True:
        left = len(data) - pos
        if left == 0:
            res.errors.append(FormatError("file ends without an MEND chunk (truncated?)",
                                          offset=pos, section="§3.4"))
            return res
        if left < 12:
            res.errors.append(FormatError(f"truncated chunk frame: {left} byte(s) left, a chunk needs 12",
                                          offset=pos, section="§3.2"))
            return res
        hdr = ChunkHeader.parse(data[pos: pos + 8])
        ctype, length = hdr.type, hdr.length
        tname = ctype.decode("latin-1")
        if not all(65 <= b <= 90 or 97 <= b <= 122 for b in ctype):
            res.errors.append(FormatError(f"chunk type {ctype!r} is not four ASCII letters",
                                          offset=pos, section="§3.2"))
            return res
        if length > MAX_CHUNK_LENGTH:
            res.errors.append(LimitExceededError(
                f"chunk length {length} exceeds the limit {MAX_CHUNK_LENGTH}",
                offset=pos, chunk=tname, section="§8"))
            return res
        if length > left - 12:
            res.errors.append(LimitExceededError(
                f"chunk length {length} exceeds the {left - 12} byte(s) left in the file (truncated?)",
                offset=pos, chunk=tname, section="§3.2"))
            return res
        payload = data[pos + 8: pos + 8 + length]
        stored = ChunkCRC.parse(data[pos + 8 + length: pos + 12 + length])
        chunk = Chunk(tname, None, payload, pos, stored, crc32(ctype, payload))
        res.chunks.append(chunk)
        if not chunk.crc_ok:
            res.errors.append(ChecksumError(
                f"CRC-32 mismatch: computed 0x{chunk.crc_computed:08x}, stored 0x{stored:08x}",
                offset=pos, chunk=tname, section="§3.3"))
        if ctype in PAYLOADS:
            try:
                chunk.fields = _parse_payload(ctype, payload, pos + 8)
            except MPZError as exc:
                res.errors.append(exc)
        elif chunk.critical:
            res.errors.append(FormatError(f"unknown critical chunk {tname!r}", offset=pos,
                                          chunk=tname, section="§2.3"))
        else:
            res.warnings.append(FormatError(f"unknown ancillary chunk {tname!r} skipped",
                                            offset=pos, chunk=tname, section="§2.3"))
        pos += 12 + length
        if ctype == b"MEND":
            res.complete = True
            if pos != len(data):
                res.errors.append(FormatError(f"{len(data) - pos} byte(s) after the MEND chunk",
                                              offset=pos, section="§3.4"))
            return res


def parse(data: bytes) -> list:
    """Strictly parse the chunk list of ``data``.

    Raises
    ------
    FormatError, ChecksumError, LimitExceededError
        The first problem :func:`scan` found, with its offset and chunk.
    """
    res = scan(data)
    if res.errors:
        raise res.errors[0]
    return res.chunks


def build_chunk(ctype: str, fields=None, payload: bytes | None = None) -> bytes:
    """Frame one chunk: type, length, payload, CRC (§3.2)."""
    t = ctype.encode("ascii")
    if payload is None:
        payload = PAYLOADS[t].build(fields if fields is not None else {})
    if len(payload) > MAX_CHUNK_LENGTH:
        raise LimitExceededError(f"{ctype} payload of {len(payload)} bytes exceeds {MAX_CHUNK_LENGTH}",
                                 chunk=ctype, section="§8")
    return (ChunkHeader.build({"type": t, "length": len(payload)}) + payload
            + ChunkCRC.build(crc32(t, payload)))


def repair_crcs(data: bytes) -> bytes:
    """Recompute the CRC of every chunk whose frame fits in ``data`` (a testing aid).

    Lets a deliberately corrupted file reach the checks behind the CRC
    (fuzzing, conformance vectors); frames that run past the end are left alone.
    """
    out = bytearray(data)
    pos = len(SIGNATURE)
    while pos + 12 <= len(out):
        length = int.from_bytes(out[pos + 4: pos + 8], "little")
        end = pos + 8 + length
        if end + 4 > len(out):
            break
        out[end: end + 4] = ChunkCRC.build(crc32(bytes(out[pos: pos + 4]), bytes(out[pos + 8: end])))
        pos = end + 4
    return bytes(out)


def build(chunks) -> bytes:
    """Signature followed by every chunk (each a :class:`Chunk` or ``(type, fields)``)."""
    out = [SIGNATURE]
    for c in chunks:
        if isinstance(c, Chunk):
            use_payload = bool(c.payload) or c.fields is None
            out.append(build_chunk(c.type, payload=c.payload if use_payload else None,
                                   fields=c.fields))
        else:
            ctype, fields = c
            out.append(build_chunk(ctype, fields))
    return b"".join(out)
