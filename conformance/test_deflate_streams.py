"""The DEFLATE streams of the §4.13 vectors are what their descriptions say, by zlib.

Spec §4.13 defines valid DEFLATE as zlib's ``inflate`` reads a raw stream. The vectors of
R-4.13-3 and R-4.13-5 hold streams written bit by bit (``mpz.tools.deflate_bits``,
``make_vectors.deflate_streams``); this file checks, on the frozen vector files, that each
invalid one makes zlib fail with the intended message (and only that: its twin, the same
stream with the one fault undone, inflates to the content), and that each valid one
inflates to exactly the content. It also checks the bit writer itself against RFC 1951.
"""
from __future__ import annotations

import random
import zlib

import pytest

from mpz.conformance import manifest as mf
from mpz.container import scan
from mpz.tools import deflate_bits as db
from mpz.tools.make_vectors import DeflateCase, deflate_streams

VDIR = mf.DEFAULT_DIR
MAN = mf.load(VDIR)
BY_SLUG = {v["name"].split("-", 1)[1]: v for v in MAN["vectors"]}


def _bodies(file: str) -> dict[str, bytes]:
    """The chdr and cprm bodies of a vector (after the processor and coding bytes)."""
    p = {c.type: bytes(c.payload) for c in scan((VDIR / file).read_bytes()).chunks}
    return {"chdr": p["chdr"][2:], "cprm": p["cprm"][1:]}


def _inflate(stream: bytes) -> bytes:
    """zlib's reading of a raw stream as the reference reads it: the whole stream, which
    must end with its final block and fill the body exactly."""
    d = zlib.decompressobj(-15)
    out = d.decompress(stream)
    assert d.eof and not d.unused_data
    return out


@pytest.fixture(scope="module")
def cases() -> dict[str, DeflateCase]:
    """The streams, made from the content of u41 (the same archive, stored)."""
    stored = _bodies(BY_SLUG["c3d-stored-header-and-parameters"]["file"])
    assert len(stored["chdr"]) == 512
    return deflate_streams(stored["cprm"], stored["chdr"])


def test_every_stream_has_its_vector(cases):
    for slug, c in cases.items():
        v = BY_SLUG[slug]
        assert v["expected"] == ("reject" if c.zlib_error else "decode"), slug
        assert _bodies(v["file"])[c.chunk] == c.stream, f"{slug}: the frozen stream differs"


def test_invalid_streams_fail_in_zlib_for_their_one_fault(cases):
    content = _bodies(BY_SLUG["c3d-stored-header-and-parameters"]["file"])
    invalid = {s: c for s, c in cases.items() if c.zlib_error}
    assert len(invalid) == 4
    for slug, c in invalid.items():
        with pytest.raises(zlib.error, match=c.zlib_error):
            _inflate(c.stream)
        assert c.twin is not None and _inflate(c.twin) == content[c.chunk], slug
        assert f"data: {c.zlib_error})" in BY_SLUG[slug]["reference_message"], slug
    messages = {c.zlib_error for c in invalid.values()}
    assert messages == {"too many length or distance symbols", "invalid literal/lengths set",
                        "invalid distance code", "invalid bit length repeat"}


def test_valid_streams_inflate_to_the_content(cases):
    content = _bodies(BY_SLUG["c3d-stored-header-and-parameters"]["file"])
    valid = {s: c for s, c in cases.items() if c.zlib_error is None}
    assert len(valid) == 3
    for slug, c in valid.items():
        assert _inflate(c.stream) == content[c.chunk], slug
    pad = valid["cprm-deflate-padding-ones"].stream
    assert pad[-1] & 0x80, "the padding bits are 1"


def test_bit_writer_packs_fields_lsb_first_and_codes_msb_first():
    bw = db.BitWriter()
    bw.bits(0b101, 3)          # bits 1, 0, 1 from bit 0 of the byte
    bw.code(0b110, 3)          # code 110: bits 1, 1, 0 from bit 3
    bw.bits(1, 2)              # 1, 0 from bit 6
    assert bw.finish() == bytes([0b01011101])
    bw = db.BitWriter()
    bw.bits(1, 1)
    assert bw.finish() == b"\x01" and bw.finish(fill=True) == b"\xff"


def test_canonical_codes_are_rfc_1951s():
    # RFC 1951 section 3.2.2's example: lengths (3, 3, 3, 3, 3, 2, 4, 4) for A..H
    codes = db.canonical_codes([3, 3, 3, 3, 3, 2, 4, 4])
    assert codes == [(0b010, 3), (0b011, 3), (0b100, 3), (0b101, 3), (0b110, 3), (0b00, 2),
                     (0b1110, 4), (0b1111, 4)]
    # the fixed code of section 3.2.6
    fixed = db.canonical_codes(db.FIXED_LITLEN)
    assert fixed[0] == (0b00110000, 8) and fixed[144] == (0b110010000, 9)
    assert fixed[256] == (0, 7) and fixed[280] == (0b11000000, 8)


def test_length_and_distance_codes_are_rfc_1951s():
    assert db.length_code(3) == (257, 0, 0) and db.length_code(10) == (264, 0, 0)
    assert db.length_code(11) == (265, 0, 1) and db.length_code(257) == (284, 30, 5)
    assert db.length_code(258) == (285, 0, 0)
    assert db.distance_code(1) == (0, 0, 0) and db.distance_code(5) == (4, 0, 1)
    assert db.distance_code(32768) == (29, 8191, 13)


def test_blocks_written_here_inflate_in_zlib():
    rng = random.Random(70)
    for _ in range(20):
        data = bytes(rng.choice(b"ab\x00\x00xyz") for _ in range(rng.randrange(0, 700)))
        tokens = db.lz77(data)
        assert db.inflated(tokens) == data
        for write in (lambda bw, t, f: db.fixed_block(bw, t, final=f),
                      lambda bw, t, f: db.dynamic_block(bw, t, db.FULL_LITLEN, db.FULL_DIST,
                                                        final=f)):
            bw = db.BitWriter()
            write(bw, tokens[:len(tokens) // 2], False)
            write(bw, tokens[len(tokens) // 2:], True)
            assert _inflate(bw.finish(fill=True)) == data
