"""Grammar of spec §3-§4: table tests of (§, object, bytes) with the expected
bytes written independently with struct, and parse/build symmetry."""
import struct
import zlib

import construct
from hypothesis import given, settings
from hypothesis import strategies as st
import pytest

from mpz import container
from mpz.chunks import CHUNKS
from mpz.errors import ChecksumError, FormatError, LimitExceededError
from mpz.spec import grammar as g

CASES = [
    ("§4.1", "MHDR",
     dict(version_major=1, version_minor=0, flags=1, frame_count=343, marker_count=41,
          node_count=11, rate=120.0, units=1, error_metric=1, error_bound=2.0, smoothing=2),
     struct.pack("<BBHIHHdBBdB", 1, 0, 1, 343, 41, 11, 120.0, 1, 1, 2.0, 2)),
    ("§4.2", "MNAM", dict(count=2, names=["LFHD", "Ä"]),
     struct.pack("<H", 2) + b"\x00\x04LFHD" + b"\x00\x02\xc3\x84"),
    ("§4.2", "MNAM", dict(count=3, names=["S:AB", "S:AC", "S:AC2"]),
     struct.pack("<H", 3) + b"\x00\x04S:AB" + b"\x03\x01C" + b"\x04\x012"),
    ("§4.3", "HIER",
     dict(count=2, nodes=[dict(parent=0xFFFF, ref=0, member_count=1, members=[0], weights=[1.0]),
                          dict(parent=0, ref=2, member_count=2, members=[1, 2],
                               weights=[1.0, 0.5])]),
     struct.pack("<H", 2) + struct.pack("<HHHHB", 0xFFFF, 0, 1, 0, 15)
     + struct.pack("<HHHHHBB", 0, 2, 2, 1, 2, 15, 7)),
    ("§4.4", "QUNT", dict(step=0.5, offset=[1.0, -2.0, 3.5], bits=20),
     struct.pack("<ddddB", 0.5, 1.0, -2.0, 3.5, 20)),
    ("§4.5", "MASK", dict(coded=b"\x00" * 5), b"\x00" * 5),
    ("§4.6", "ROOT", dict(order=2, coded=b"\x00" * 5), b"\x02" + b"\x00" * 5),
    ("§4.7", "PATT", dict(node=3, pattern_count=4, length=12, scale=2, order=1, coded=b"\x00" * 5),
     struct.pack("<HHHHB", 3, 4, 12, 2, 1) + b"\x00" * 5),
    ("§4.8", "SEGS", dict(node=3, segment_count=9, coded=b"\x00" * 5),
     struct.pack("<HI", 3, 9) + b"\x00" * 5),
    ("§4.9", "RESI", dict(node=3, base=1, order=2, scale=5, coded=b"\x00" * 5),
     struct.pack("<HBBH", 3, 1, 2, 5) + b"\x00" * 5),
    ("§4.10", "smry",
     dict(space=0, dims=3, level_count=1,
          levels=[dict(k=2, wssse=4.0, step=0.25, starts=struct.pack("<II", 0, 5),
                       means=struct.pack("<6i", 1, 2, 3, -1, -2, -3))]),
     struct.pack("<BIB", 0, 3, 1) + struct.pack("<Idd", 2, 4.0, 0.25) + struct.pack("<II", 0, 5)
     + struct.pack("<6i", 1, 2, 3, -1, -2, -3)),
    ("§4.11", "meta", dict(count=1, entries=[dict(key="subject", value="02")]),
     struct.pack("<H", 1) + b"\x07subject" + struct.pack("<H", 2) + b"02"),
    ("§4.12", "MEND", dict(), b""),
]


@pytest.mark.parametrize("section,ctype,obj,expected", CASES,
                         ids=[f"{c[1]}-{i}" for i, c in enumerate(CASES)])
def test_build_parse_table(section, ctype, obj, expected):
    grammar = CHUNKS[ctype].GRAMMAR
    assert grammar.build(obj) == expected
    # the chunk table's typed record reads and writes the same bytes
    assert CHUNKS[ctype].load(expected).dump() == expected
    parsed = grammar.parse(expected)
    assert grammar.build(parsed) == expected
    for key, value in obj.items():
        if key != "nodes" and key != "levels" and key != "entries":
            assert parsed[key] == value


def test_front_coded_names_reject_bad_prefixes():
    import construct
    for payload in (struct.pack("<H", 1) + b"\x01\x01A",            # shares 1 byte of nothing
                    struct.pack("<H", 1) + b"\x00\x00",                # empty name
                    struct.pack("<H", 1) + b"\x00\x01\xff"):           # not UTF-8
        with pytest.raises(construct.ConstructError):
            g.MNAM.parse(payload)


def test_every_chunk_type_has_a_table_case():
    assert {c[1] for c in CASES} == set(CHUNKS)


def test_chunk_frame_and_crc():
    # §3.2/§3.3: type, u32 length, payload, CRC-32 of type + payload
    framed = container.build_chunk("MEND", b"")
    assert framed == b"MEND" + b"\x00\x00\x00\x00" + struct.pack("<I", zlib.crc32(b"MEND"))


def test_trailing_bytes_in_payload_rejected():
    with pytest.raises(construct.ConstructError):
        g.QUNT.parse(struct.pack("<ddddB", 0.5, 1, 2, 3, 20) + b"\x00")


def test_scan_reports_errors_without_raising():
    data = g.SIGNATURE + container.build_chunk("MEND", b"")
    assert container.scan(data).complete
    bad = bytearray(data)
    bad[-1] ^= 0xFF
    res = container.scan(bytes(bad))
    assert isinstance(res.errors[0], ChecksumError)
    with pytest.raises(ChecksumError):
        container.parse(bytes(bad))
    with pytest.raises(FormatError, match="signature"):
        container.parse(b"MPZ\x00" + data[4:])
    huge = g.SIGNATURE + b"MHDR" + struct.pack("<I", 0xFFFFFFFF) + b"\x00" * 8
    with pytest.raises(LimitExceededError):
        container.parse(huge)


@settings(max_examples=80, deadline=None)
@given(st.binary(max_size=64), st.sampled_from(["meta", "zzzz"]))
def test_chunk_roundtrip_property(payload, ctype):
    """parse(build(x)) == x and build(parse(b)) == b for the chunk frame."""
    if ctype == "meta":
        payload = g.META.build({"count": 1, "entries": [{"key": "k", "value": payload.hex()}]})
    data = (g.SIGNATURE + container.build_chunk(ctype, payload=payload)
            + container.build_chunk("MEND", b""))
    chunks = container.parse(data)
    assert chunks[0].payload == payload
    assert container.build(chunks) == data
