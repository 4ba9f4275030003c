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
    return mpz.encode(generate("wave", frames=60, markers=8, seed=2), lossy=True)


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


@settings(max_examples=200, deadline=2000,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.data())
def test_bit_flips_only_raise_mpzerror(small, data):
    pos = data.draw(st.integers(0, len(small) - 1))
    bit = data.draw(st.integers(0, 7))
    b = bytearray(small)
    b[pos] ^= 1 << bit
    with pytest.raises(MPZError):       # every flip is caught: CRC covers all but the frame
        mpz.decode(bytes(b))


@settings(max_examples=200, deadline=2000,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
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


@pytest.mark.parametrize("markers_only", [False, True])
@pytest.mark.parametrize("ctype", ["zzzz", "smrc"])
def test_an_ancillary_chunk_unknown_to_the_decoder_before_mhdr_is_refused(small, ctype,
                                                                         markers_only):
    """R-3.4-1: MHDR is the first chunk, also when an unknown ancillary chunk stands before
    it (smrc is unknown to a 1.0 decoder, markers_only). The decoder skipped such a chunk
    without keeping it and took MHDR for the first chunk (a fuzzing QA run)."""
    def first(c):
        extra = [x for x in c if x.type == ctype] or [container.Chunk(ctype, None, b"hello")]
        return extra[:1] + [x for x in c if x.type != ctype]
    blob = _rechunk(small, first)
    for call in (lambda: mpz.decode(blob, markers_only=markers_only), lambda: mpz.info(blob)):
        with pytest.raises(FormatError, match="first chunk must be MHDR") as exc:
            call()
        assert exc.value.offset == 8 and exc.value.chunk == ctype


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


# ---------------------------------------------------------------- issue 11.5 --
def _with_step(data: bytes, step: float) -> bytes:
    def edit(chunks):
        for c in chunks:
            if c.type == "QUNT":
                p = bytearray(c.payload)
                struct.pack_into("<d", p, 0, step)
                c.payload = bytes(p)
        return chunks
    return _rechunk(data, edit)


def test_qunt_step_1e308_decode_and_mpzinfo_agree(small, tmp_path):
    """Issue 11.5: a QUNT step of 1e308 is finite and > 0, but |offset| + step x 2^bits is
    +inf, so spec 1.0.1 §4.4 makes the file invalid. mpz.decode, mpzinfo (library and CLI)
    and mpz show / decode must all reject it, at the QUNT chunk."""
    import subprocess
    import sys

    from mpz.tools.mpzinfo import inspect

    blob = _with_step(small, 1e308)
    qunt = next(c for c in container.parse(blob) if c.type == "QUNT")
    with pytest.raises(FormatError) as got:
        mpz.decode(blob)
    e = got.value
    assert (e.chunk, e.offset, e.section) == ("QUNT", qunt.offset, "§4.4")
    assert "step" in str(e) and "mask" not in str(e)
    info = inspect(blob, "x.mpz")
    assert info["status"] == "error"
    assert [(x["class"], x["chunk"], x["offset"], x["section"]) for x in info["errors"]] == [
        ("FormatError", "QUNT", qunt.offset, "§4.4")]
    path = tmp_path / "step.mpz"
    path.write_bytes(blob)
    for argv in (["-m", "mpz.tools.mpzinfo", str(path)],
                 ["-m", "mpz.tools.mpz_cli", "show", str(path)],
                 ["-m", "mpz.tools.mpz_cli", "decode", str(path), "-o",
                  str(tmp_path / "out.npy")]):
        run = subprocess.run([sys.executable, *argv], capture_output=True, text=True,
                             timeout=300)
        assert run.returncode == 2, (argv, run.stdout, run.stderr)
        assert "§4.4" in run.stdout + run.stderr
    assert not (tmp_path / "out.npy").exists()
    # the largest legal step for this offset and bits still decodes, to finite values
    bits = next(c.record for c in container.parse(blob) if c.type == "QUNT").bits
    ok = _with_step(small, 2.0 ** (1023 - bits))
    assert np.isfinite(mpz.decode(ok).positions[mpz.decode(ok).valid]).all()


# ---------------------------------------------------------------- issue 11.7 --
#: the rejections that have no chunk, because no complete chunk frame is at their offset
#: (spec §8, "Error reports"): each still carries its offset
NO_CHUNK = ("bad signature", "file ends without an MEND chunk", "truncated chunk frame",
            "is not four ASCII letters", "after the MEND chunk")


def _invalid_vectors():
    import json
    from pathlib import Path
    root = Path(__file__).resolve().parents[1] / "conformance" / "vectors"
    man = json.loads((root / "manifest.json").read_text())
    return [(v["name"], root / v["file"]) for v in man["vectors"] if v["group"] == "invalid"]


@pytest.mark.parametrize("name,path", _invalid_vectors(), ids=lambda v: str(v)[:40])
def test_every_rejection_is_located(name, path):
    """Issue 11.7: every invalid vector is rejected with an offset and a chunk (and a §),
    except the framing errors of NO_CHUNK, which have an offset only. The offset lies in
    the file (at most its end: a truncated file fails there) and, with a chunk, within a
    chunk of that type."""
    data = path.read_bytes()
    with pytest.raises(MPZError) as got:
        mpz.decode(data, max_samples=1 << 22)
    e = got.value
    assert e.offset is not None and 0 <= e.offset <= len(data), (name, str(e))
    assert e.section is not None, (name, str(e))
    if any(text in e.message for text in NO_CHUNK):
        assert e.chunk is None, (name, str(e))
    else:
        assert e.chunk is not None, (name, str(e))
        # the offset is in a chunk of that type (its start, a field or the failing byte), or
        # is the start of a frame of that type whose length field is refused
        assert (any(c.type == e.chunk and c.offset <= e.offset <= c.offset + 12 + c.length
                    for c in container.scan(data).chunks)
                or data[e.offset: e.offset + 4] == e.chunk.encode("latin-1")), (name, str(e))


def test_a_payload_that_does_not_load_names_its_chunk(monkeypatch):
    """A record whose load raised an MPZError without naming its chunk reached the user
    with an offset and no chunk (a newcomer adding a chunk type, stop 51): spec errors
    carry offset, chunk and §. The scan names the chunk it was loading."""
    from mpz import container
    from mpz.chunks import CHUNKS
    from mpz.errors import FormatError
    from mpz.synth import generate
    data = mpz.encode(generate("walk", frames=20, seed=1), max_error=1.0)

    def fails(payload):
        raise FormatError("does not fit its layout", section="§4.4")
    monkeypatch.setattr(CHUNKS["QUNT"], "load", staticmethod(fails))
    errors = container.scan(data).errors
    assert [(e.chunk, e.section) for e in errors] == [("QUNT", "§4.4")], errors
    assert errors[0].offset is not None


# -- messages that name a writer's likely mistake (a clean-room encoder, stop 60) ---------
def _chunk_at(data: bytes, ctype: bytes) -> int:
    """The offset of the first chunk of type ``ctype`` (its type field)."""
    pos = len(SIGNATURE)
    while data[pos:pos + 4] != ctype:
        pos += 12 + struct.unpack_from("<I", data, pos + 4)[0]
    return pos


def test_resi_without_the_residual_flag_names_the_flag(small):
    """A bounded file's RESI chunks with MHDR flags bit 0 cleared: the order error said
    'expected a PATT chunk here, found RESI' and nothing of the flag the writer forgot."""
    b = bytearray(small)
    flags = _chunk_at(small, b"MHDR") + 8 + 2               # §4.1: flags at offset 2
    assert b[flags] & 1
    b[flags] &= 0xFE
    with pytest.raises(FormatError, match=r"found RESI; .*MHDR flags bit 0") as ei:
        mpz.decode(container.repair_crcs(bytes(b)))
    assert ei.value.section == "§3.4"


def _chunks(data: bytes) -> list[tuple[bytes, int, int]]:
    """(type, offset, payload length) of every chunk of a valid file."""
    out, pos = [], len(SIGNATURE)
    while pos < len(data):
        length = struct.unpack_from("<I", data, pos + 4)[0]
        out.append((data[pos:pos + 4], pos, length))
        pos += 12 + length
    return out


def test_a_big_endian_chunk_length_is_named():
    """A length written big-endian read as 'exceeds the bytes left (truncated?)', or, with
    a low byte of 0x40 or more, as over the §8 limit, and sent the writer after a cut file
    (a review of stop 60 found the limit's case without the hint). Every chunk of a file,
    one at a time."""
    data = mpz.encode(generate("walk", frames=60, seed=2), max_error=1.0,
                      metadata={"subject": "s"})
    seen = set()
    for ctype, pos, length in _chunks(data):
        if int.from_bytes(length.to_bytes(4, "little"), "big") == length:
            continue                                  # a palindrome: nothing to tell
        b = bytearray(data)
        struct.pack_into(">I", b, pos + 4, length)
        with pytest.raises(MPZError) as ei:
            mpz.decode(bytes(b))
        assert f"read big-endian, the length would be {length} and the chunk's CRC " \
            "would match" in str(ei.value), (ctype, str(ei.value))
        assert "truncated?" not in str(ei.value)
        seen.add(ei.value.section)
    assert {"§8", "§3.2"} <= seen                     # both framing errors were met


def test_a_truncated_file_gets_no_byte_order_hint(small):
    """Cut inside any chunk, a file is said to be cut; also where the cut chunk's length,
    read the other way round, fits what is left (a 131,328-byte meta chunk cut 100,000
    bytes in: 66,048 fits, and the hint was given before it checked the CRC)."""
    for _, pos, length in _chunks(small):
        with pytest.raises(MPZError) as ei:
            mpz.decode(small[:pos + 8 + length // 2])
        assert "big-endian" not in str(ei.value)
    m = generate("walk", frames=30, markers=6, seed=1)

    def with_meta(c: int) -> tuple[bytes, int, int]:
        data = mpz.encode(m, max_error=1.0,
                          metadata={"a": "x" * 65535, "b": "y" * 65535, "c": "z" * c})
        _, pos, length = next(c for c in _chunks(data) if c[0] == b"meta")
        return data, pos, length
    _, _, length = with_meta(244)                    # then the encoder's own entries less
    data, pos, length = with_meta(244 - (length - 131328))
    assert length == 131328 and length & 0xFF == 0
    with pytest.raises(MPZError, match=r"truncated\?\)") as ei:
        mpz.decode(data[:pos + 8 + 100_000])
    assert "big-endian" not in str(ei.value)


def test_a_range_error_names_quntbits(small):
    """Values beyond |q| < 2^bits: the §6.7 message gave 2^bits, not the field that sets
    it, so a writer one bit short looked for a wrong value rather than a wrong header."""
    b = bytearray(small)
    bits = _chunk_at(small, b"QUNT") + 8 + 32                # §4.4: bits at offset 32
    b[bits] -= 2             # the reference writes one bit more than |q| < 2^bits needs
    with pytest.raises(FormatError, match=rf"QUNT's bits field \({b[bits]}\) declares") as ei:
        mpz.decode(container.repair_crcs(bytes(b)))
    assert ei.value.section == "§6.7"
