"""Raw DEFLATE streams (RFC 1951) written bit by bit, for the vectors of spec §4.13.

zlib writes only the streams it chooses. The vectors of R-4.13-3 and R-4.13-5 need
streams it never writes: a dynamic block that declares 31 distance codes, a literal/length
code that is incomplete, a fixed block that uses distance symbol 30, code lengths that
start with a repeat, nonzero bits after the final block, a distance code of one code of
one bit, a block without distance codes. This module writes them, one choice at a time,
and nothing here checks that a stream is valid: the vectors that use it check each
stream against zlib's inflate (``conformance/test_deflate_streams.py``), which §4.13
makes the definition of valid DEFLATE.

Bits are packed as RFC 1951 section 3.1.1 says: the first bit of the stream is the
least significant bit of its first byte. A number of n bits (a block header field, an
extra-bits field) goes in least significant bit first. A Huffman code goes in most
significant bit first (the bit nearest the root of the tree first): :meth:`BitWriter.code`
does that, so callers pass a code as the integer that section 3.2.2 assigns to it.

A stream is written block by block: :func:`fixed_block` (BTYPE 1) and
:func:`dynamic_block` (BTYPE 2) write the block header, the code description of a
dynamic block, the data (from :func:`lz77` tokens) and the end-of-block symbol 256.
"""
from __future__ import annotations

from dataclasses import dataclass

#: the order in which a dynamic block lists the code length code's lengths (RFC 1951 3.2.7)
CL_ORDER = (16, 17, 18, 0, 8, 7, 9, 6, 10, 5, 11, 4, 12, 3, 13, 2, 14, 1, 15)

#: literal/length symbols 257..285: (base length, extra bits), RFC 1951 section 3.2.5
LENGTHS = ((3, 0), (4, 0), (5, 0), (6, 0), (7, 0), (8, 0), (9, 0), (10, 0), (11, 1),
           (13, 1), (15, 1), (17, 1), (19, 2), (23, 2), (27, 2), (31, 2), (35, 3), (43, 3),
           (51, 3), (59, 3), (67, 4), (83, 4), (99, 4), (115, 4), (131, 5), (163, 5),
           (195, 5), (227, 5), (258, 0))

#: distance symbols 0..29: (base distance, extra bits), RFC 1951 section 3.2.5
DISTANCES = ((1, 0), (2, 0), (3, 0), (4, 0), (5, 1), (7, 1), (9, 2), (13, 2), (17, 3),
             (25, 3), (33, 4), (49, 4), (65, 5), (97, 5), (129, 6), (193, 6), (257, 7),
             (385, 7), (513, 8), (769, 8), (1025, 9), (1537, 9), (2049, 10), (3073, 10),
             (4097, 11), (6145, 11), (8193, 12), (12289, 12), (16385, 13), (24577, 13))

#: the fixed block's code lengths (RFC 1951 section 3.2.6): 288 literal/length symbols,
#: of which 286 and 287 never occur in valid data, and 32 distance symbols, of which 30
#: and 31 never occur
FIXED_LITLEN = (8,) * 144 + (9,) * 112 + (7,) * 24 + (8,) * 8
FIXED_DIST = (5,) * 32

#: a complete literal/length code over all 286 symbols (226 of 8 bits, 60 of 9:
#: 226 / 256 + 60 / 512 = 1), so that any data can be written with it
FULL_LITLEN = (8,) * 226 + (9,) * 60
#: a complete distance code over the 30 symbols (2 of 4 bits, 28 of 5: 2/16 + 28/32 = 1)
FULL_DIST = (4, 4) + (5,) * 28
#: a complete code length code over all 19 symbols (13 of 4 bits, 6 of 5), so that any
#: sequence of code lengths can be written with it
FULL_CL = (4,) * 13 + (5,) * 6


@dataclass(frozen=True)
class Match:
    """A back-reference: copy ``length`` (3..258) bytes from ``distance`` (1..32768) back."""

    length: int
    distance: int


@dataclass(frozen=True)
class Raw:
    """A symbol written as it is, for data RFC 1951 does not allow: ``symbol`` of the
    literal/length alphabet (``alphabet`` "litlen") or the distance alphabet ("dist"),
    then ``extra`` in ``extra_bits`` bits."""

    alphabet: str
    symbol: int
    extra: int = 0
    extra_bits: int = 0


#: a token of the data: a literal byte, a back-reference, or a raw symbol
Token = int | Match | Raw


class BitWriter:
    """Bits packed least significant bit first (RFC 1951 section 3.1.1)."""

    def __init__(self) -> None:
        self._acc = 0          # the bits so far, bit i of the stream = bit i of _acc
        self._n = 0

    @property
    def bit_length(self) -> int:
        return self._n

    def bits(self, value: int, count: int) -> None:
        """A number of ``count`` bits, least significant bit first (header fields, extra
        bits)."""
        assert 0 <= value < 1 << count or count == 0 == value, (value, count)
        self._acc |= value << self._n
        self._n += count

    def code(self, code: int, length: int) -> None:
        """A Huffman code of ``length`` bits, most significant bit first."""
        assert length >= 1 and 0 <= code < 1 << length, (code, length)
        for i in range(length - 1, -1, -1):
            self.bits((code >> i) & 1, 1)

    def finish(self, fill: bool = False) -> bytes:
        """The stream as bytes. The bits after the last one written, up to the end of the
        last byte, are 0, or 1 with ``fill``."""
        nbytes = (self._n + 7) // 8
        acc = self._acc
        if fill:
            acc |= ((1 << (8 * nbytes - self._n)) - 1) << self._n
        return acc.to_bytes(nbytes, "little")


def canonical_codes(lengths: tuple[int, ...] | list[int]) -> list[tuple[int, int] | None]:
    """The code of each symbol as (code, length) (RFC 1951 section 3.2.2), None for a
    length of 0. Over-subscribed or incomplete lengths are not refused: their codes are
    what the algorithm gives."""
    top = max(lengths, default=0)
    count = [0] * (top + 1)
    for n in lengths:
        if n:
            count[n] += 1
    next_code = [0] * (top + 2)
    code = 0
    for bits in range(1, top + 1):
        code = (code + count[bits - 1]) << 1
        next_code[bits] = code
    out: list[tuple[int, int] | None] = []
    for n in lengths:
        if n:
            out.append((next_code[n], n))
            next_code[n] += 1
        else:
            out.append(None)
    return out


def length_code(length: int) -> tuple[int, int, int]:
    """(symbol 257..285, extra value, extra bits) of a match length 3..258."""
    assert 3 <= length <= 258, length
    for i in range(len(LENGTHS) - 1, -1, -1):
        base, extra = LENGTHS[i]
        if length >= base and (extra or length == base):
            return 257 + i, length - base, extra
    raise AssertionError(length)


def distance_code(distance: int) -> tuple[int, int, int]:
    """(symbol 0..29, extra value, extra bits) of a distance 1..32768."""
    assert 1 <= distance <= 32768, distance
    for i in range(len(DISTANCES) - 1, -1, -1):
        base, extra = DISTANCES[i]
        if distance >= base:
            return i, distance - base, extra
    raise AssertionError(distance)


def lz77(data: bytes, *, distances: tuple[int, ...] | None = None) -> list[Token]:
    """A greedy parse of ``data`` into literals and matches of 3..258 bytes, the longest
    match at each position (the nearest of equal length); only at the distances listed
    in ``distances`` if given, else at any distance up to 32768. Every match points
    into the bytes before it, so it is valid whatever blocks hold them."""
    out: list[Token] = []
    i = 0
    n = len(data)
    while i < n:
        best = (0, 0)
        cands = distances if distances is not None else range(1, min(i, 32768) + 1)
        for d in cands:
            if d > i:
                continue
            k = 0
            while k < 258 and i + k < n and data[i + k] == data[i + k - d]:
                k += 1
            if k > best[0]:
                best = (k, d)
        if best[0] >= 3:
            out.append(Match(*best))
            i += best[0]
        else:
            out.append(data[i])
            i += 1
    return out


def inflated(tokens: list[Token]) -> bytes:
    """What ``tokens`` inflate to (no :class:`Raw` token): the check of :func:`lz77`."""
    out = bytearray()
    for t in tokens:
        if isinstance(t, Match):
            for _ in range(t.length):
                out.append(out[-t.distance])
        else:
            assert isinstance(t, int)
            out.append(t)
    return bytes(out)


def symbols_used(tokens: list[Token]) -> tuple[set[int], set[int]]:
    """The literal/length and distance symbols that ``tokens`` need (256 included)."""
    lit, dist = {256}, set()
    for t in tokens:
        if isinstance(t, Match):
            lit.add(length_code(t.length)[0])
            dist.add(distance_code(t.distance)[0])
        elif isinstance(t, Raw):
            (lit if t.alphabet == "litlen" else dist).add(t.symbol)
        else:
            lit.add(t)
    return lit, dist


def _write_data(bw: BitWriter, tokens: list[Token], lit: list, dist: list) -> None:
    def put(table: list, symbol: int) -> None:
        c = table[symbol] if symbol < len(table) else None
        assert c is not None, f"symbol {symbol} has no code"
        bw.code(*c)

    for t in tokens:
        if isinstance(t, Match):
            sym, extra, n = length_code(t.length)
            put(lit, sym)
            bw.bits(extra, n)
            sym, extra, n = distance_code(t.distance)
            put(dist, sym)
            bw.bits(extra, n)
        elif isinstance(t, Raw):
            put(lit if t.alphabet == "litlen" else dist, t.symbol)
            bw.bits(t.extra, t.extra_bits)
        else:
            put(lit, t)
    put(lit, 256)


def fixed_block(bw: BitWriter, tokens: list[Token], *, final: bool) -> None:
    """A block with the fixed codes (BTYPE 1): header, data, end of block."""
    bw.bits(int(final), 1)
    bw.bits(1, 2)
    _write_data(bw, tokens, canonical_codes(FIXED_LITLEN), canonical_codes(FIXED_DIST))


def code_length_symbols(lengths: list[int] | tuple[int, ...]) -> list[tuple[int, int]]:
    """The code length sequence of ``lengths`` as (symbol 0..18, extra value) pairs:
    runs of zeros as 17 (3..10) or 18 (11..138), runs of a length that repeats the one
    before as 16 (3..6), the rest one by one (RFC 1951 section 3.2.7)."""
    out: list[tuple[int, int]] = []
    i, n = 0, len(lengths)
    while i < n:
        v = lengths[i]
        run = 1
        while i + run < n and lengths[i + run] == v:
            run += 1
        if v == 0 and run >= 3:
            take = min(run, 138)
            out.append((18, take - 11) if take >= 11 else (17, take - 3))
            i += take
            continue
        out.append((v, 0))
        i += 1
        run -= 1
        while run >= 3:
            take = min(run, 6)
            out.append((16, take - 3))
            i += take
            run -= take
    return out


#: extra bits of the code length symbols 16, 17 and 18
CL_EXTRA = {16: 2, 17: 3, 18: 7}


def dynamic_block(bw: BitWriter, tokens: list[Token], litlen: tuple[int, ...] | list[int],
                  dist: tuple[int, ...] | list[int], *, final: bool,
                  cl_sequence: list[tuple[int, int]] | None = None,
                  cl_lengths: tuple[int, ...] = FULL_CL) -> None:
    """A block with its own codes (BTYPE 2): header, HLIT = len(litlen) - 257, HDIST =
    len(dist) - 1, HCLEN and the code length code (``cl_lengths``, by symbol 0..18,
    written in :data:`CL_ORDER` up to its last nonzero entry, at least 4), the code
    lengths (``cl_sequence``, by default :func:`code_length_symbols` of litlen + dist),
    then the data and end of block. Any count that fits its field is written: nothing
    is refused here."""
    assert 0 <= len(litlen) - 257 < 32 and 0 <= len(dist) - 1 < 32
    order = [cl_lengths[s] for s in CL_ORDER]
    hclen = max([i + 1 for i, n in enumerate(order) if n] + [4])
    bw.bits(int(final), 1)
    bw.bits(2, 2)
    bw.bits(len(litlen) - 257, 5)
    bw.bits(len(dist) - 1, 5)
    bw.bits(hclen - 4, 4)
    for n in order[:hclen]:
        bw.bits(n, 3)
    cl = canonical_codes(cl_lengths)
    seq = code_length_symbols(list(litlen) + list(dist)) if cl_sequence is None else cl_sequence
    for sym, extra in seq:
        c = cl[sym]
        assert c is not None, f"code length symbol {sym} has no code"
        bw.code(*c)
        if sym in CL_EXTRA:
            bw.bits(extra, CL_EXTRA[sym])
    _write_data(bw, tokens, canonical_codes(litlen), canonical_codes(dist))
