"""Hostile input (spec §8): truncation at every byte, bit flips, maxed lengths,
unknown and reordered chunks. Only MPZError may escape, quickly, with bounded memory."""
import struct

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
import numpy as np
import pytest

import mpz
from mpz import container
from mpz.errors import (
    ChecksumError,
    FormatError,
    LimitExceededError,
    MPZError,
    UnsupportedVersionError,
)
from mpz.spec.grammar import SIGNATURE
from mpz.synth import generate


@pytest.fixture(scope="module")
def small():
    m = generate("walk", frames=12, markers=6, seed=1, gap_fraction=0.1)
    return mpz.encode(m, max_error=1.0, summary=(2,))


@pytest.fixture(scope="module")
def lossy():
    return mpz.encode(generate("wave", frames=60, markers=8, seed=2))


def test_truncation_at_every_byte(small):
    for n in range(len(small)):
        with pytest.raises(MPZError):
            mpz.decode(small[:n])


def test_truncation_lossy_every_byte(lossy):
    for n in range(0, len(lossy), 3):
        with pytest.raises(MPZError):
            mpz.decode(lossy[:n])


def _rechunk(data, edit):
    """Apply ``edit(chunks)`` and rebuild with valid CRCs."""
    chunks = container.parse(data)
    chunks = edit(chunks)
    return SIGNATURE + b"".join(container.build_chunk(c.type, payload=c.payload) for c in chunks)


@settings(max_examples=200, deadline=2000, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.data())
def test_bit_flips_only_raise_mpzerror(small, data):
    pos = data.draw(st.integers(0, len(small) - 1))
    bit = data.draw(st.integers(0, 7))
    b = bytearray(small)
    b[pos] ^= 1 << bit
    with pytest.raises(MPZError):       # every flip is caught: CRC covers all but the frame
        mpz.decode(bytes(b))


@settings(max_examples=200, deadline=2000, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.data())
def test_payload_mutations_with_valid_crc(small, data):
    """Mutate a payload and fix the CRC: decode succeeds or raises MPZError only."""
    chunks = container.parse(small)
    idx = data.draw(st.integers(0, len(chunks) - 2))
    payload = bytearray(chunks[idx].payload)
    if not payload:
        return
    for _ in range(data.draw(st.integers(1, 4))):
        p = data.draw(st.integers(0, len(payload) - 1))
        payload[p] = data.draw(st.integers(0, 255))
    chunks[idx] = container.Chunk(chunks[idx].type, None, bytes(payload))
    blob = SIGNATURE + b"".join(container.build_chunk(c.type, payload=c.payload) for c in chunks)
    try:
        out = mpz.decode(blob, max_samples=1 << 16)
    except MPZError:
        return
    assert out.n_frames >= 1


def test_named_corruptions(small):
    def set_field(ctype, fmt, offset, value):
        def edit(chunks):
            for c in chunks:
                if c.type == ctype:
                    p = bytearray(c.payload)
                    struct.pack_into(fmt, p, offset, value)
                    c.payload = bytes(p)
            return chunks
        return _rechunk(small, edit)

    cases = [
        (b"MPZ\x00" + small[4:], FormatError, "signature"),
        (small[:20] + bytes([small[20] ^ 0xFF]) + small[21:], ChecksumError, "CRC"),
        (set_field("MHDR", "<B", 0, 2), UnsupportedVersionError, "major version"),
        (set_field("MHDR", "<I", 4, 0xFFFFFFFF), LimitExceededError, "frame_count"),
        (set_field("MHDR", "<H", 8, 4097), LimitExceededError, "marker_count"),
        (set_field("MHDR", "<H", 8, 4000), FormatError, "names for 4000 markers"),
        (set_field("MHDR", "<H", 2, 0x8001), FormatError, "reserved"),
        (set_field("QUNT", "<d", 0, float("nan")), FormatError, "step"),
        (_rechunk(small, lambda c: c[:1] + [container.Chunk("ABCD", None, b"x")] + c[1:]),
         FormatError, "unknown critical"),
        (_rechunk(small, lambda c: [c[0], c[2], c[1]] + c[3:]), FormatError, "expected"),
        (_rechunk(small, lambda c: c[:-1]), FormatError, "MEND"),
        (small + b"\x00", FormatError, "after the MEND"),
    ]
    for blob, cls, words in cases:
        with pytest.raises(cls, match=words):
            mpz.decode(blob)


def test_unknown_ancillary_chunk_is_skipped(small):
    blob = _rechunk(small, lambda c: c[:3] + [container.Chunk("zzzz", None, b"hello")] + c[3:])
    a, b = mpz.decode(small), mpz.decode(blob)
    assert np.array_equal(a.valid, b.valid)
    assert np.array_equal(np.nan_to_num(a.positions), np.nan_to_num(b.positions))


def test_lengths_at_their_maximum():
    for ctype in (b"MHDR", b"ROOT", b"zzzz"):
        blob = SIGNATURE + ctype + struct.pack("<I", 0xFFFFFFFF) + b"\x00" * 64
        with pytest.raises(LimitExceededError):
            mpz.decode(blob)


def test_huge_declared_size_is_refused_before_allocation(small):
    # F = 2^24, M = 4096: 2^36 samples would be 1.5 TB; must be refused up front
    def edit(chunks):
        p = bytearray(chunks[0].payload)
        struct.pack_into("<IH", p, 4, 1 << 24, 4096)
        chunks[0].payload = bytes(p)
        return chunks
    with pytest.raises(LimitExceededError):
        mpz.decode(_rechunk(small, edit))
