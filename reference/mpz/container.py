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

from collections.abc import Collection, Iterable
from dataclasses import dataclass, field
import zlib

from mpz.chunks import CHUNKS, Record, _build, _parse
from mpz.errors import ChecksumError, FormatError, LimitExceededError, MPZError
from mpz.format import MAX_CHUNK_LENGTH
from mpz.spec.grammar import SIGNATURE, VERSION_MINOR, ChunkCRC, ChunkHeader


@dataclass
class Chunk:
    """One chunk as found in (or destined for) a file."""

    type: str
    record: Record | None = None       # the typed payload (mpz.chunks), None if unknown/bad
    payload: bytes = b""
    offset: int | None = 0             # byte offset of the chunk's type field (None: not in a file)
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
    def payload_offset(self) -> int | None:
        return None if self.offset is None else self.offset + 8

    @property
    def crc_ok(self) -> bool:
        return self.crc_stored == self.crc_computed


@dataclass
class Scan:
    """What :func:`scan` found: the chunks, and every problem on the way."""

    chunks: list[Chunk] = field(default_factory=list)
    errors: list[MPZError] = field(default_factory=list)
    warnings: list[MPZError] = field(default_factory=list)
    size: int = 0
    complete: bool = False            # an MEND chunk was reached
    #: unknown ancillary chunks skipped (§2.3), by type: how many
    skipped: dict[str, int] = field(default_factory=dict)


def is_chunk_type(ctype: bytes) -> bool:
    """§3.2: a chunk type is four bytes, each an ASCII letter A-Z or a-z."""
    return len(ctype) == 4 and all(65 <= b <= 90 or 97 <= b <= 122 for b in ctype)


def _byte_order_hint(data: bytes, pos: int, ctype: bytes, length: int) -> str:
    """What to add to a framing or CRC error when the chunk at ``pos`` checks out with its
    length's four bytes read the other way round (its CRC then matches, stored either
    way): a writer that put the length big-endian (a clean-room encoder's mistake, stop 60)
    was told that the file looked cut. Only error paths call it."""
    swapped = int.from_bytes(length.to_bytes(4, "little"), "big")
    if swapped == length or pos + 12 + swapped > len(data):
        return ""
    crc = crc32(ctype, memoryview(data)[pos + 8: pos + 8 + swapped])
    tail = data[pos + 8 + swapped: pos + 12 + swapped]
    if crc not in (int.from_bytes(tail, "little"), int.from_bytes(tail, "big")):
        return ""
    return (f"; read big-endian, the length would be {swapped} and the chunk's CRC would "
            f"match: lengths are little-endian")


def crc32(ctype: bytes, payload: bytes | memoryview) -> int:
    """§3.3 CRC-32 over the type and the payload."""
    return zlib.crc32(payload, zlib.crc32(ctype)) & 0xFFFFFFFF


def locate(exc: MPZError, chunk: Chunk) -> MPZError:
    """Give ``exc`` the chunk type and offset of ``chunk`` where it has none (the one place
    rule violations found in records get their location)."""
    if exc.chunk is None:
        exc.chunk = chunk.type
    if exc.offset is None:
        exc.offset = chunk.offset
    return exc


def scan(data: bytes, *, minor: int = VERSION_MINOR, keep_unknown: bool = True,
         load: Collection[str] | None = None) -> Scan:
    """Walk the chunks of ``data`` and report everything found (never raises MPZError).

    Parameters
    ----------
    data : bytes
        A complete MPZ file.
    minor : int, optional
        The highest minor version of 1.x that the reading decoder implements (§2.1): chunk
        types introduced after it are unknown to it, so their frame and CRC are checked and
        their payload is not read (§2.3). ``minor=0`` reads a file as a 1.0 decoder does.
        ValueError outside 0 .. VERSION_MINOR (an argument, not the file).
    keep_unknown : bool, optional
        Keep a :class:`Chunk` and a warning for each unknown ancillary chunk (mpzinfo
        lists them); False counts them in ``skipped`` alone, after their frame and CRC
        are checked, so that a decoder holds nothing per skipped chunk (spec §8: a valid
        file of 10^6 empty unknown chunks, 12 MB, took 884 MiB, a fuzzing QA run of
        stop 48).
    load : collection of str, optional
        The chunk types whose payload is read into a record (default: every known type);
        the others' frames and CRCs are checked, and their ``record`` is None (a corpus
        ``--verify`` reads only ``meta``: loading every record made it 10 MB/s).

    Returns
    -------
    Scan
        Chunks parsed so far, plus ``errors`` and ``warnings`` (MPZError
        instances with offsets). Scanning stops at MEND or at the first
        framing error; a bad CRC or a malformed payload is recorded and the
        scan goes on with the next chunk.
    """
    if not (isinstance(minor, int) and 0 <= minor <= VERSION_MINOR):
        raise ValueError(f"minor must be an int 0 .. {VERSION_MINOR}, got {minor!r}")
    data = bytes(data)
    res = Scan(size=len(data))
    if len(data) < len(SIGNATURE) or data[: len(SIGNATURE)] != SIGNATURE:  # R-2.4-1, R-3.1-1
        # no bytes at all: said as such ("bad signature b''" left a caller that had read
        # the stream to its end guessing; an ML pipeline's QA run of the API)
        got = repr(data[: len(SIGNATURE)]) if data else ("(no bytes: an empty file, or a "
                                                         "stream read to its end)")
        res.errors.append(FormatError(f"bad signature {got}, expected {SIGNATURE!r}",
                                      offset=0, section="§3.1"))
        return res
    pos = len(SIGNATURE)
    while True:
        left = len(data) - pos
        if left == 0:  # R-3.4-12
            res.errors.append(FormatError("file ends without an MEND chunk (truncated?)",
                                          offset=pos, section="§3.4"))
            return res
        if left < 12:  # R-3.2-1
            res.errors.append(FormatError(
                f"truncated chunk frame: {left} byte(s) left, a chunk needs 12",
                offset=pos, section="§3.2"))
            return res
        hdr = _parse.parse(ChunkHeader, data[pos: pos + 8])
        ctype, length = hdr.type, hdr.length
        tname = ctype.decode("latin-1")
        # R-2.4-2
        if not is_chunk_type(ctype):
            res.errors.append(FormatError(f"chunk type {ctype!r} is not four ASCII letters",
                                          offset=pos, section="§3.2"))
            return res
        # R-2.4-3, R-8-2
        if length > MAX_CHUNK_LENGTH:
            res.errors.append(LimitExceededError(
                f"chunk length {length} exceeds the limit {MAX_CHUNK_LENGTH}"
                f"{_byte_order_hint(data, pos, ctype, length)}",
                offset=pos, chunk=tname, section="§8"))
            return res
        # R-3.2-2
        if length > left - 12:
            hint = _byte_order_hint(data, pos, ctype, length)
            res.errors.append(LimitExceededError(
                f"chunk length {length} exceeds the {left - 12} byte(s) left in the file"
                f"{hint or ' (truncated?)'}",
                offset=pos, chunk=tname, section="§3.2"))
            return res
        stored = _parse.parse(ChunkCRC, data[pos + 8 + length: pos + 12 + length])
        computed = crc32(ctype, memoryview(data)[pos + 8: pos + 8 + length])
        # R-2.3-3, R-3.3-1, R-3.3-2
        if computed != stored:
            res.errors.append(ChecksumError(
                f"CRC-32 mismatch: computed 0x{computed:08x}, stored 0x{stored:08x}"
                f"{_byte_order_hint(data, pos, ctype, length)}",
                offset=pos, chunk=tname, section="§3.3"))
        known = tname in CHUNKS and CHUNKS[tname].MINOR <= minor  # R-2.3-5
        if not known and not tname[:1].isupper():
            res.skipped[tname] = res.skipped.get(tname, 0) + 1
            # checked and counted, nothing kept; but the file's first chunk is kept
            # whatever it is, so that the decoder's first-chunk rule (R-3.4-1) sees an
            # unknown ancillary chunk before MHDR (dropped, it let MHDR pass as the first)
            if not keep_unknown and res.chunks:
                pos += 12 + length
                continue
        payload = data[pos + 8: pos + 8 + length]
        chunk = Chunk(tname, None, payload, pos, stored, computed)
        res.chunks.append(chunk)
        if known and load is not None and tname not in load:
            pass                               # frame and CRC checked, payload not read
        elif known:
            try:
                chunk.record = CHUNKS[tname].load(payload)
            except MPZError as exc:
                exc.offset = pos + 8           # the payload that does not fit its layout
                if exc.chunk is None:          # (a record's load may not name it)
                    exc.chunk = tname
                res.errors.append(exc)
        # R-2.3-1
        elif chunk.critical:
            res.errors.append(FormatError(f"unknown critical chunk {tname!r}", offset=pos,
                                          chunk=tname, section="§2.3"))
        else:
            res.warnings.append(FormatError(f"unknown ancillary chunk {tname!r} skipped",
                                            offset=pos, chunk=tname, section="§2.3"))
        pos += 12 + length
        if ctype == b"MEND":  # R-2.3-5
            res.complete = True
            # R-3.4-11
            if pos != len(data):
                res.errors.append(FormatError(f"{len(data) - pos} byte(s) after the MEND chunk",
                                              offset=pos, section="§3.4"))
            return res


def parse(data: bytes, *, minor: int = VERSION_MINOR, keep_unknown: bool = True
          ) -> list[Chunk]:
    """Strictly parse the chunk list of ``data`` (``minor`` and ``keep_unknown``: as in
    :func:`scan`; the decoder keeps no unknown ancillary chunk).

    Raises
    ------
    FormatError, ChecksumError, LimitExceededError
        The first problem :func:`scan` found, with its offset and chunk.
    """
    res = scan(data, minor=minor, keep_unknown=keep_unknown)
    if res.errors:
        raise res.errors[0]
    return res.chunks


def build_chunk(ctype: str, payload: bytes) -> bytes:
    """Frame one payload: type, length, payload, CRC (§3.2, §3.3)."""
    t = ctype.encode("ascii")
    if len(payload) > MAX_CHUNK_LENGTH:
        raise LimitExceededError(
            f"{ctype} payload of {len(payload)} bytes exceeds {MAX_CHUNK_LENGTH}",
            chunk=ctype, section="§8")
    header = _build.build(ChunkHeader, {"type": t, "length": len(payload)})
    crc = _build.build(ChunkCRC, crc32(t, payload))
    return header + payload + crc


def chunk_sizes(data: bytes) -> dict[str, int]:
    """Framed bytes (12 + payload) per chunk type of a well-formed file, from the frames alone."""
    sizes: dict[str, int] = {}
    pos = len(SIGNATURE)
    while pos + 12 <= len(data):
        hdr = _parse.parse(ChunkHeader, data[pos: pos + 8])
        t = hdr.type.decode("latin-1")
        sizes[t] = sizes.get(t, 0) + 12 + hdr.length
        pos += 12 + hdr.length
    return sizes


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
        crc = crc32(bytes(out[pos: pos + 4]), bytes(out[pos + 8: end]))
        out[end: end + 4] = ChunkCRC.build(crc)
        pos = end + 4
    return bytes(out)


def build(chunks: Iterable[Record | Chunk | tuple[str, bytes]]) -> bytes:
    """The signature followed by every chunk, framed (the write side of :func:`scan`).

    Each item is a :class:`~mpz.chunks.Record` (its payload is built), a :class:`Chunk`
    (its payload bytes are kept, or built from its record when it has none), or a
    ``(type, payload bytes)`` pair for chunks the table does not know.
    """
    out = [SIGNATURE]
    for c in chunks:
        if isinstance(c, Record):
            out.append(build_chunk(c.TYPE, c.dump()))
        elif isinstance(c, Chunk):
            payload = c.payload if (c.payload or c.record is None) else c.record.dump()
            out.append(build_chunk(c.type, payload))
        else:
            out.append(build_chunk(c[0], c[1]))
    return b"".join(out)
