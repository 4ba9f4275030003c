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

#: a §4.13.2 parameter section of two records, written with struct
_CPRM_SECTION = (struct.pack("<H", 2) + struct.pack("<bB", -1, 0) + b"\x05POINT" + b"\x033-D"
                 + struct.pack("<bB", 1, 1) + b"\x04USED" + b"\x00" + struct.pack("<bB", 2, 1)
                 + b"\x02" + struct.pack("<hh", 7, -1))

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
    # §4.15 smrc (MPZ 1.1, issue 14.12): the level headers, then the coded field to the end
    ("§4.15", "smrc",
     dict(space=1, dims=2, level_count=2,
          levels=[dict(k=3, wssse=1.5, step=0.5), dict(k=1, wssse=-0.0, step=2.0)],
          coded=b"\x00\x12\x34\x56\x78\x9a"),
     struct.pack("<BIB", 1, 2, 2) + struct.pack("<Idd", 3, 1.5, 0.5)
     + struct.pack("<Idd", 1, -0.0, 2.0) + b"\x00\x12\x34\x56\x78\x9a"),
    ("§4.11", "meta", dict(count=1, entries=[dict(key="subject", value="02")]),
     struct.pack("<H", 1) + b"\x07subject" + struct.pack("<H", 2) + b"02"),
    ("§4.12", "MEND", dict(), b""),
    # §4.13 C3D archive chunks (MPZ 1.1): bytes written with struct, independently
    # chdr and cprm stored (§4.13 coding 0); their content grammars are in CONTENT_CASES
    ("§4.13.1", "chdr", dict(processor=84, coding=0, body=b"\x02\x50" + bytes(510)),
     b"\x54\x00" + b"\x02\x50" + bytes(510)),
    ("§4.13.2", "cprm", dict(coding=0, body=_CPRM_SECTION), b"\x00" + _CPRM_SECTION),
    ("§4.13.3", "cpnt",
     dict(storage=1, point_count=2, slots=[1, 0],
          words=[dict(mode=0, shift=-3, order=1, low_bits=0),
                 dict(mode=1, shift=0, order=2, low_bits=3)],
          model_count=1, models=[dict(kind=2, axes=[
              dict(offset=0.5, step=0.25, bound=0.125, order=a) for a in range(3)])],
          coded=b"\x00" * 5),
     struct.pack("<BH", 1, 2) + struct.pack("<HH", 1, 0) + struct.pack("<BbBB", 0, -3, 1, 0)
     + struct.pack("<BbBB", 1, 0, 2, 3) + struct.pack("<H", 1) + b"\x02"
     + b"".join(struct.pack("<dddB", 0.5, 0.25, 0.125, a) for a in range(3)) + b"\x00" * 5),
    ("§4.13.4", "cana",
     dict(storage=0, channels=1, samples=4, table=[dict(mode=0, shift=0, order=2, low_bits=0)],
          coded=b"\x00" * 5),
     struct.pack("<BHH", 0, 1, 4) + struct.pack("<BbBB", 0, 0, 2, 0) + b"\x00" * 5),
    # §4.14 skeleton chunks (MPZ 1.1, issue 13): bytes written with struct, independently
    ("§4.14.1", "bvhs",
     dict(encoding=0, frame_time=0.0083333, joint_count=2,
          joints=[dict(name="Hips", parent=0xFFFF, offset=[0.0, 0.0, 0.0], channel_count=4,
                       channels=[0, 1, 5, 3]),
                  dict(name="", parent=0, offset=[0.0, 1.5, -2.0], channel_count=0,
                       channels=[])],
          channel_count=4, position_bound=0.25,
          channels=[dict(step_mantissa=m, step_digits=2, wrap=w, low=lo, order=o, group=gr)
                    for m, w, lo, o, gr in ((2, 0, 0, 2, 0), (2, 0, 0, 1, 1),
                                            (2, 1, -9000, 2, 1), (5, 1, -18000, 0, 0))],
          coded=b"\x00" * 5),
     struct.pack("<BdH", 0, 0.0083333, 2)
     + b"\x04Hips" + struct.pack("<H3dB", 0xFFFF, 0.0, 0.0, 0.0, 4) + bytes([0, 1, 5, 3])
     + b"\x00" + struct.pack("<H3dB", 0, 0.0, 1.5, -2.0, 0)
     + struct.pack("<Hd", 4, 0.25)
     + struct.pack("<HBBiBB", 2, 2, 0, 0, 2, 0) + struct.pack("<HBBiBB", 2, 2, 0, 0, 1, 1)
     + struct.pack("<HBBiBB", 2, 2, 1, -9000, 2, 1) + struct.pack("<HBBiBB", 5, 2, 1, -18000, 0, 0)
     + b"\x00" * 5),
    ("§4.14.2", "asfs",
     dict(encoding=1, angle_unit=0, length_unit=0.45, mass="1.0", version="1.10", name="VICON",
          documentation="a\nb", comments=" c", root_order_count=2, root_order=[0, 3],
          root_axis_order=0, root_position=[0.0, 0.0, 0.0], root_orientation=[0.0, 0.0, 0.0],
          bone_count=1,
          bones=[dict(bone_id=1, name="lfemur", parent=0, direction=[0.0, -1.0, 0.0],
                      length=7.5, axis=[0.0, 0.0, 20.0], axis_order=5, dof_count=2,
                      dofs=[3, 6], limit_count=2,
                      limits=[[-160.0, 20.0], [float("-inf"), float("inf")]])],
          amc_header=":FULLY-SPECIFIED\n:DEGREES", first_frame=1, amc_count=2,
          amc_order=[0, 1], channel_count=4, position_bound=0.0,
          channels=[dict(step_mantissa=1, step_digits=4, wrap=0, low=0, order=2, group=0)] * 4,
          coded=b"\x00" * 5),
     struct.pack("<BBd", 1, 0, 0.45) + b"\x031.0" + b"\x041.10" + b"\x05VICON"
     + struct.pack("<H", 3) + b"a\nb" + struct.pack("<H", 2) + b" c"
     + b"\x02\x00\x03" + b"\x00" + struct.pack("<6d", 0, 0, 0, 0, 0, 0)
     + struct.pack("<H", 1) + struct.pack("<I", 1) + b"\x06lfemur"
     + struct.pack("<H3dd3dB", 0, 0.0, -1.0, 0.0, 7.5, 0.0, 0.0, 20.0, 5) + b"\x02\x03\x06"
     + b"\x02" + struct.pack("<4d", -160.0, 20.0, float("-inf"), float("inf"))
     + struct.pack("<H", 25) + b":FULLY-SPECIFIED\n:DEGREES" + struct.pack("<IH2H", 1, 2, 0, 1)
     + struct.pack("<Hd", 4, 0.0) + struct.pack("<HBBiBB", 1, 4, 0, 0, 2, 0) * 4
     + b"\x00" * 5),
]


#: §4.13.1, §4.13.2 the content of chdr and cprm (stored or inflated, §4.13 byte coding)
CONTENT_CASES = [
    (g.CHDR_BLOCK, dict(block=b"\x02\x50" + bytes(510)), b"\x02\x50" + bytes(510)),
    (g.CPRM_SECTION,
     dict(count=2, records=[
         dict(group=-1, locked=0, name=b"POINT", description=b"3-D", type=None, dims=None,
              data=None),
         dict(group=1, locked=1, name=b"USED", description=b"", type=2, dims=b"\x02",
              data=struct.pack("<hh", 7, -1))]),
     _CPRM_SECTION),
]


@pytest.mark.parametrize("grammar,obj,expected", CONTENT_CASES, ids=["chdr-block", "cprm-section"])
def test_c3d_content_grammar(grammar, obj, expected):
    assert grammar.build(obj) == expected
    assert grammar.build(grammar.parse(expected)) == expected


def test_c3d_deflated_payloads_hold_the_same_content():
    """§4.13 coding 1: the records read the inflated content (stream made with zlib here)."""
    co = zlib.compressobj(9, zlib.DEFLATED, -15)
    stream = co.compress(_CPRM_SECTION) + co.flush()
    rec = CHUNKS["cprm"].load(b"\x01" + stream)
    assert rec.coding == 1 and rec.count == 2 and rec.records[1].name == b"USED"
    assert CHUNKS["cprm"].load(rec.dump()) == rec


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


@pytest.mark.parametrize("bug", [ValueError("a bug"), OverflowError("a bug"),
                                 IndexError("a bug")])
def test_a_bug_in_parsing_is_not_reported_as_a_malformed_payload(monkeypatch, bug):
    """Only construct's errors are the payload's fault (FormatError, the chunk's §); an
    exception of any other kind from parsing is a bug of the decoder and surfaces as it is
    (ValueError and OverflowError were translated into "malformed payload")."""
    from mpz.chunks import _parse

    def broken(grammar, payload):
        raise bug
    monkeypatch.setattr(_parse, "parse", broken)
    with pytest.raises(type(bug), match="a bug"):
        CHUNKS["QUNT"].load(struct.pack("<ddddB", 0.5, 1, 2, 3, 20))
    monkeypatch.undo()
    with pytest.raises(FormatError, match="malformed QUNT payload"):
        CHUNKS["QUNT"].load(struct.pack("<ddddB", 0.5, 1, 2, 3, 20) + b"\x00")


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


def test_scan_loads_only_the_types_asked_for_and_checks_every_crc():
    """``load``: the records of those types alone (a corpus --verify reads the meta); every
    frame and CRC is still checked, and a payload not loaded is not judged."""
    import mpz
    from mpz.synth import generate
    data = mpz.encode(generate("walk", frames=40, markers=6, seed=1), max_error=1.0,
                      metadata={"k": "v"})
    every = container.scan(data)
    some = container.scan(data, load=("meta",))
    assert not every.errors and not some.errors and some.complete
    assert [c.type for c in some.chunks] == [c.type for c in every.chunks]
    assert {c.type for c in some.chunks if c.record is not None} == {"meta"}
    assert [c.record for c in some.chunks if c.type == "meta"] == \
        [c.record for c in every.chunks if c.type == "meta"]
    qunt = next(c for c in every.chunks if c.type == "QUNT")
    bad = bytearray(data)
    bad[qunt.payload_offset] ^= 0x01                 # its CRC no longer holds
    assert isinstance(container.scan(bytes(bad), load=()).errors[0], ChecksumError)
    # the same change with the CRC mended: a payload that is not loaded is not read
    mended = container.repair_crcs(bytes(bad))
    assert not container.scan(mended, load=()).errors


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


def test_smrc_levels_are_20_bytes_and_the_coded_field_runs_to_the_end():
    """§4.15: the coded field starts at 6 + 20 n; a payload cut inside the level headers is
    malformed, and an empty coded field still parses (§5.3 rejects it when decoded)."""
    head = struct.pack("<BIB", 0, 6, 2) + struct.pack("<Idd", 2, 0.0, 1.0) * 2
    assert len(head) == 6 + 20 * 2
    assert g.SMRC.parse(head + b"\x00" * 7).coded == b"\x00" * 7
    assert g.SMRC.parse(head).coded == b""
    with pytest.raises(construct.ConstructError):
        g.SMRC.parse(head[:-1])


# ---- the compiled builder (mpz.chunks._build, issue 15.1): construct's bytes, faster ----
def _records_of_vectors():
    """(vector, chunk type, record) of every chunk that parses, in every shipped vector."""
    from pathlib import Path
    root = Path(__file__).resolve().parents[1] / "conformance" / "vectors"
    from mpz.chunks.base import Record
    from mpz.chunks.c3d import Chdr, Cprm, _ChdrBlock, _CprmSection
    out = []
    for path in sorted(root.rglob("*.mpz")):
        for c in container.scan(path.read_bytes()).chunks:
            rec = c.record
            if c.type not in CHUNKS or rec is None:
                continue
            out.append((path.name, c.type, rec))
            # chdr and cprm build their (inflated) content from a record of their own
            if isinstance(rec, Cprm):
                out.append((path.name, "cprm section",
                            _CprmSection(count=rec.count, records=rec.records)))
            elif isinstance(rec, Chdr):
                out.append((path.name, "chdr block", _ChdrBlock(block=rec.block)))
            else:
                assert type(rec).dump is Record.dump, c.type
    return out


def test_compiled_builder_gives_the_table_bytes():
    """The bytes written with struct in CASES and CONTENT_CASES, by the fast path itself
    (not by falling back to construct)."""
    from mpz.chunks import _build
    for _, ctype, obj, expected in CASES:
        assert _build.fast_path(CHUNKS[ctype].GRAMMAR, obj) == expected, ctype
    for grammar, obj, expected in CONTENT_CASES:
        assert _build.fast_path(grammar, obj) == expected


def test_compiled_builder_matches_construct_on_every_chunk_of_every_vector():
    from mpz.chunks import _build
    seen = set()
    records = _records_of_vectors()
    assert len(records) > 1000
    for name, ctype, rec in records:
        if ctype in ("chdr", "cprm"):
            seen.add(ctype)             # built by hand around their content (below)
            continue
        obj = rec.to_build()
        want = bytes(rec.GRAMMAR.build(obj))
        got = _build.fast_path(rec.GRAMMAR, obj)
        assert got == want, (name, ctype)
        seen.add(ctype)
    # every chunk type of the table is among them (the vectors use them all)
    assert seen >= set(CHUNKS) | {"cprm section", "chdr block"}, set(CHUNKS) - seen


@pytest.mark.parametrize("grammar,obj", [
    (g.MNAM, dict(count=3, names=["a", "b"])),                 # count and list disagree
    (g.MHDR, dict(version_major=256, version_minor=0, flags=0, frame_count=1,
                  marker_count=1, node_count=1, rate=1.0, units=1, error_metric=0,
                  error_bound=0.0, smoothing=0)),               # 256 in a u8
    (g.META, dict(count=1, entries=[dict(key=b"k", value="v")])),   # bytes for a string
    (g.MNAM, dict(count=1, names=["x" * 300])),                # suffix beyond a u8 length
    (g.QUNT, dict(step=0.5, offset=[1.0, 2.0], bits=20)),      # 2 of 3 offsets
    (g.CPRM_SECTION, dict(count=1, records=[dict(
        group=1, locked=0, name=b"A", description=b"", type=2, dims=b"\x02",
        data=b"\x00\x00")])),                                   # 2 bytes for 2 x int16
    (g.RESI, dict(node=0, base=1, order=1, scale=1)),          # a field missing
])
def test_compiled_builder_leaves_every_error_to_construct(grammar, obj):
    """Values construct refuses: the fast path gives up and build() raises construct's own
    error, the one grammar.build raises."""
    from mpz.chunks import _build
    with pytest.raises(Exception) as want:
        grammar.build(obj)
    assert _build.fast_path(grammar, obj) is None
    with pytest.raises(type(want.value)) as got:
        _build.build(grammar, obj)
    assert str(got.value) == str(want.value)


_u8 = construct.Int8ul
_NESTED = [     # constructs the builder writes as a loop, a sub-stream or a top level
    construct.Struct("n" / _u8, "xs" / construct.Array(construct.this.n, construct.Struct(
        "a" / _u8, "b" / construct.Prefixed(_u8, construct.GreedyBytes)))),
    construct.Struct("p" / construct.Prefixed(_u8, construct.Struct(
        "a" / construct.Int16ul, "rest" / construct.PascalString(_u8, "utf8"))), "z" / _u8),
    construct.Array(2, construct.Struct("a" / _u8, "b" / construct.Int16ul)),
    construct.Prefixed(construct.Int16ul, construct.Array(2, construct.Struct("a" / _u8))),
]


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(st.integers(-1, 256), st.binary(max_size=3)), max_size=3),
       st.integers(-1, 3), st.integers(-1, 0x10000), st.text(max_size=3), st.integers(-1, 256))
def test_compiled_builder_agrees_with_construct_on_nested_constructs(items, n, a, text, z):
    """Arrays of records, Prefixed records and grammars that are not Structs, on values in
    and out of range and counts that disagree: construct's bytes, or construct's error
    (stop 71)."""
    from mpz.chunks import _build
    objs = [dict(n=n, xs=[dict(a=x, b=b) for x, b in items]),
            dict(p=dict(a=a, rest=text), z=z),
            [dict(a=x, b=a) for x, _ in items],
            [dict(a=x) for x, _ in items]]
    for grammar, obj in zip(_NESTED, objs, strict=True):
        try:
            want = bytes(grammar.build(obj))
        except Exception as exc:
            assert _build.fast_path(grammar, obj) is None, (grammar, obj)
            with pytest.raises(type(exc)):
                _build.build(grammar, obj)
        else:
            assert _build.fast_path(grammar, obj) == want, (grammar, obj)


_u16 = st.integers(-2, 0x10001)


@settings(max_examples=150, deadline=None)
@given(st.lists(st.fixed_dictionaries(dict(
    parent=_u16, ref=_u16, members=st.lists(_u16, max_size=4),
    weights=st.lists(st.floats(-1, 20), max_size=4))), max_size=4),
    st.lists(st.tuples(st.text(max_size=4), st.text(max_size=4)), max_size=3),
    st.lists(st.text(min_size=0, max_size=6), max_size=5))
def test_compiled_builder_agrees_with_construct_on_any_values(nodes, entries, names):
    """HIER, meta and MNAM of arbitrary values (counts that disagree, numbers out of range,
    empty strings): the same bytes as construct, or construct's error."""
    from mpz.chunks import _build
    objs = [
        (g.HIER, dict(count=len(nodes), nodes=[dict(
            parent=n["parent"], ref=n["ref"], member_count=len(n["members"]),
            members=n["members"], weights=n["weights"][:len(n["members"])]) for n in nodes])),
        (g.META, dict(count=len(entries), entries=[dict(key=k, value=v) for k, v in entries])),
        (g.MNAM, dict(count=len(names), names=names)),
    ]
    for grammar, obj in objs:
        try:
            want = bytes(grammar.build(obj))
        except Exception as exc:        # construct's error: the fast path leaves it to it
            assert _build.fast_path(grammar, obj) is None
            with pytest.raises(type(exc)):
                _build.build(grammar, obj)
        else:
            assert _build.fast_path(grammar, obj) == want


# ---- the compiled parser (mpz.chunks._parse, issue 15.1): construct's fields, faster ----
def _tree(v):
    """A parse result as plain values to compare: records as dicts without construct's and
    the fast path's private keys (``_io``, ``_``), arrays as lists, floats as their bits."""
    if isinstance(v, dict):
        return {k: _tree(x) for k, x in v.items() if not k.startswith("_")}
    if isinstance(v, (list, tuple)):
        return [_tree(x) for x in v]
    if isinstance(v, float):
        return ("float", struct.pack("<d", v))
    return v


def _agree(grammar, payload, where):
    """The fast path gives construct's fields, or gives up exactly where construct raises;
    and parse() gives construct's fields or construct's own error. Returns whether the
    payload parsed."""
    from mpz.chunks import _parse
    try:
        want = grammar.parse(payload)
    except Exception as exc:
        assert _parse.fast_path(grammar, payload) is None, where
        with pytest.raises(type(exc)) as got:
            _parse.parse(grammar, payload)
        assert str(got.value) == str(exc), where
        return False
    got = _parse.fast_path(grammar, payload)
    assert got is not None, (where, "the fast path gave up on a payload construct parses")
    assert _tree(got) == _tree(want), where
    return True


def test_compiled_parser_gives_the_table_fields():
    """The values of CASES and CONTENT_CASES (written independently of the parser) from
    their struct-written bytes, by the fast path itself (not by falling back)."""
    from mpz.chunks import _parse
    for _, ctype, obj, data in CASES:
        got = _parse.fast_path(CHUNKS[ctype].GRAMMAR, data)
        assert got is not None and _tree(got) == _tree(obj), ctype
    for grammar, obj, data in CONTENT_CASES:
        got = _parse.fast_path(grammar, data)
        assert got is not None and _tree(got) == _tree(obj)
    # the chunk frame and its CRC, which container.scan parses per chunk
    hdr = _parse.fast_path(g.ChunkHeader, b"MNAM" + struct.pack("<I", 70000))
    assert (hdr.type, hdr.length) == (b"MNAM", 70000)
    assert _parse.fast_path(g.ChunkCRC, struct.pack("<I", 0xDEADBEEF)) == 0xDEADBEEF
    # the buffers construct reads read the same; a strided view construct refuses is left
    # to it (QA, stop 32)
    data = CASES[1][3]
    strided = memoryview(bytes(b for x in data for b in (x, 0)))[::2]   # data, every other
    for buf in (bytearray(data), memoryview(data), strided):
        _agree(g.MNAM, buf, type(buf))


def _payloads_of_vectors():
    """(vector, grammar, payload) of every framed chunk of the table in every shipped
    vector, the invalid ones included, and the content of each chdr and cprm that loads."""
    from pathlib import Path
    root = Path(__file__).resolve().parents[1] / "conformance" / "vectors"
    out = []
    for path in sorted(root.rglob("*.mpz")):
        for c in container.scan(path.read_bytes()).chunks:
            if c.type not in CHUNKS:
                continue
            out.append((path.name, CHUNKS[c.type].GRAMMAR if c.type not in ("chdr", "cprm")
                        else {"chdr": g.CHDR, "cprm": g.CPRM}[c.type], c.payload))
            if c.type == "cprm" and c.record is not None:
                out.append((path.name, g.CPRM_SECTION, c.record.content()))
            elif c.type == "chdr" and c.record is not None:
                out.append((path.name, g.CHDR_BLOCK, c.record.block))
    return out


def test_compiled_parser_matches_construct_on_every_chunk_of_every_vector():
    """Every payload of the vectors, valid or not: the same fields, or the same error."""
    payloads = _payloads_of_vectors()
    assert len(payloads) > 1000
    parsed = sum(_agree(grammar, payload, name) for name, grammar, payload in payloads)
    refused = len(payloads) - parsed
    assert parsed > 1000 and refused > 0, (parsed, refused)   # both paths were taken


@pytest.fixture(scope="module")
def vector_payloads():
    payloads = [(gr, p) for _, gr, p in _payloads_of_vectors()]
    # the payloads that parse, one of each (grammar, length) kind, to mutate below
    seen, out = set(), []
    for gr, p in payloads:
        key = (id(gr), len(p) // 64)
        if key not in seen:
            seen.add(key)
            out.append((gr, p))
    return out


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_compiled_parser_agrees_with_construct_on_mutated_payloads(vector_payloads, data):
    """A vector's payload with bytes changed, cut or added (counts and lengths that do not
    fit what follows, text that is not UTF-8, trailing bytes): construct's fields or its
    error, never anything else."""
    grammar, payload = data.draw(st.sampled_from(vector_payloads))
    buf = bytearray(payload)
    for _ in range(data.draw(st.integers(1, 4))):
        kind = data.draw(st.sampled_from(["set", "cut", "add"]))
        if kind == "set" and buf:
            buf[data.draw(st.integers(0, len(buf) - 1))] = data.draw(st.integers(0, 255))
        elif kind == "cut" and buf:
            del buf[data.draw(st.integers(0, len(buf) - 1)):]
        else:
            buf += data.draw(st.binary(min_size=1, max_size=8))
    _agree(grammar, bytes(buf), grammar)


def test_compiled_parser_gives_up_on_every_short_field():
    """Each kind of field a Struct's generated source writes out in place, as the last field
    (no Terminated or later field to catch an overrun), on every cut of a payload that
    parses: construct's fields or construct's error (stop 70)."""
    u8, this = construct.Int8ul, construct.this
    cases = [
        (construct.Struct("n" / u8, "a" / construct.Prefixed(u8, construct.GreedyBytes)),
         b"\x00\x03abc"),
        (construct.Struct("n" / u8, "xs" / construct.Array(this.n, construct.Int16ul)),
         b"\x02\x01\x00\x02\x00"),
        (construct.Struct("n" / u8, "xs" / construct.Array(2, construct.Int16ul)),
         b"\x02\x01\x00\x02\x00"),
        (construct.Struct("n" / u8, "b" / construct.Bytes(this.n)), b"\x03abc"),
        (construct.Struct("n" / u8, "b" / construct.If(this.n > 0, construct.Int32ul)),
         b"\x01\x01\x02\x03\x04"),
        (construct.Struct("x" / construct.Int32ul, "y" / construct.Int16ul),
         b"\x01\x02\x03\x04\x05\x06"),
        (construct.Struct("n" / u8, "s" / construct.PascalString(u8, "utf8")), b"\x00\x02\xc3\xa9"),
        # a loop over items that are not numbers, and a Prefixed's own stream: a Struct
        # inside reads up to its end (GreedyBytes, Terminated) or stops short of it, and
        # the next field starts after it either way (stop 71)
        (construct.Struct("n" / u8, "xs" / construct.Array(this.n, construct.Struct(
            "a" / u8, "b" / construct.Prefixed(u8, construct.GreedyBytes)))),
         b"\x02\x07\x01x\x08\x02yz"),
        (construct.Struct("p" / construct.Prefixed(u8, construct.Struct(
            "a" / u8, "rest" / construct.GreedyBytes)), "z" / u8), b"\x03\x01xy\x07"),
        (construct.Struct("p" / construct.Prefixed(u8, construct.Struct("a" / u8)),
                          "z" / u8), b"\x03\x01xy\x07"),
        (construct.Struct("p" / construct.Prefixed(u8, construct.Struct(
            "a" / u8, construct.Terminated)), "z" / u8), b"\x01\x01\x07"),
        # grammars that are not Structs: generated in their caller's context
        (construct.Array(2, construct.Struct("a" / u8, "b" / construct.Int16ul)),
         b"\x01\x02\x00\x03\x04\x00"),
        (construct.Prefixed(u8, construct.Array(2, construct.Struct("a" / u8))), b"\x02\x05\x06"),
    ]
    for grammar, payload in cases:
        assert _agree(grammar, payload, grammar)
        for cut in range(len(payload)):
            assert not _agree(grammar, payload[:cut], (grammar, cut))


def test_compiled_parser_leaves_what_it_does_not_compile_to_construct():
    """A class outside the grammar's set, or a parsed hook: construct parses."""
    from mpz.chunks import _parse
    seen = []

    def hook(obj, ctx):
        seen.append(obj)
    u8 = construct.Int8ul
    hooked = construct.Struct("a" / u8 * hook)
    greedy = construct.Struct("xs" / construct.GreedyRange(u8))
    # a hook anywhere a Struct's generated source writes a field out in place (stop 70)
    nested = [(construct.Struct("a" / construct.If(True, u8 * hook)), b"\x05"),
              (construct.Struct("a" / construct.Array(1, u8 * hook)), b"\x05"),
              (construct.Struct("a" / construct.Prefixed(u8 * hook, construct.GreedyBytes)),
               b"\x01\x05"),
              (construct.Struct("a" / construct.Hex(u8 * hook)), b"\x05"),
              (construct.Struct("a" / construct.Renamed(u8 * hook, newname="b")), b"\x05")]
    for grammar, payload in [(hooked, b"\x05"), (greedy, b"\x05"), *nested]:
        before = len(seen)
        assert _parse.fast_path(grammar, payload) is None, grammar
        assert len(seen) == before               # the fast path ran no hook
        assert _tree(_parse.parse(grammar, payload)) == _tree(grammar.parse(payload))
        assert len(seen) > before or grammar is greedy    # construct's parses ran it


def _offsets_by_prefixes(grammar, payload):
    """The definition of ``Record.field_offsets``: field i starts where a parse of the
    fields before it ends; the list stops at the first field whose start does not parse."""
    subcons = [s for s in grammar.subcons if s.name]
    out = []
    for i, sc in enumerate(subcons):
        try:
            start = construct.Struct(*subcons[:i], "_pos" / construct.Tell).parse(payload)._pos
        except (construct.ConstructError, UnicodeDecodeError, ValueError, OverflowError):
            break
        out.append((sc.name, start))
    return out


def test_field_offsets_are_where_each_prefix_ends_on_every_chunk_of_every_vector():
    """mpzinfo -vv's offsets, taken in one parse (issue 15), are the prefix definition's on
    every framed chunk of the vectors, and on each cut short (malformed: the fields that
    parse, by the slow path)."""
    from pathlib import Path
    root = Path(__file__).resolve().parents[1] / "conformance" / "vectors"
    checked = cut = 0
    for path in sorted(root.rglob("*.mpz")):
        for c in container.scan(path.read_bytes()).chunks:
            cls = CHUNKS.get(c.type)
            if cls is None:
                continue
            for payload in (c.payload, c.payload[: len(c.payload) * 2 // 3]):
                expected = _offsets_by_prefixes(cls.GRAMMAR, payload)
                assert cls.field_offsets(payload) == expected, (path.name, c.type)
                cut += payload is not c.payload and 0 < len(expected) < len(
                    [s for s in cls.GRAMMAR.subcons if s.name])
            checked += 1
    assert checked > 1000 and cut > 50, (checked, cut)


_EXPRESSIONS = [
    construct.this.count,
    construct.this._.count,
    construct.this.group > 0,
    construct.this.count * 2 + construct.this._.count,
    (construct.this.count == 3) | (construct.this.group < 0),
    -construct.this.count,
    ~(construct.this.group > 0),
    construct.len_(construct.this.items),
    lambda ctx: ctx.count - 1,
    7,
    True,
]


@settings(max_examples=200, deadline=None)
@given(count=st.integers(-5, 300), group=st.integers(-128, 127), outer=st.integers(0, 9),
       items=st.lists(st.integers(0, 9), max_size=5))
def test_compiled_expressions_give_constructs_values(count, group, outer, items):
    """The counts, lengths and conditions the fast paths evaluate as plain functions
    (_build._expression) give what construct's own evaluation gives, on any context."""
    from mpz.chunks._build import _Context, _expression
    ctx = _Context(count=count, group=group, items=items)
    ctx["_"] = _Context(count=outer)
    from mpz.chunks._build import _source
    written = 0
    for e in _EXPRESSIONS + [4 * construct.this.count * construct.this._.count,
                             construct.this.count // 3 - construct.this.group % 5 >= 1]:
        want = e(ctx) if callable(e) else e
        assert _expression(e)(ctx) == want, e
        source = _source(e)          # as a generated function writes it out (stop 70)
        if source is not None:
            written += 1
            assert eval(source, {}, {"context": ctx}) == want, (e, source)
    assert written == 7             # the paths, operators and int constants are written out


def test_loaded_records_are_the_records_their_init_makes():
    """Record.from_parsed sets a record's fields without the dataclass __init__: on every
    chunk of every vector that loads, the record holds exactly what __init__ would set."""
    from dataclasses import fields
    from pathlib import Path
    root = Path(__file__).resolve().parents[1] / "conformance" / "vectors"
    seen = set()
    for path in sorted(root.rglob("*.mpz")):
        for c in container.scan(path.read_bytes()).chunks:
            rec = c.record
            if rec is None:
                continue
            seen.add(c.type)
            todo = [rec]
            while todo:
                r = todo.pop()
                made = type(r)(**{f.name: getattr(r, f.name) for f in fields(r)})
                assert vars(made) == vars(r) and hash(made) == hash(r), c.type
                for f in fields(r):         # and the records nested in it
                    v = getattr(r, f.name)
                    if isinstance(v, tuple):
                        todo += [x for x in v if hasattr(x, "__dataclass_fields__")]
    assert {"MNAM", "HIER", "cprm", "asfs", "bvhs"} <= seen, seen


def test_records_from_constructs_parse_equal_the_fast_paths():
    """Record.from_parsed (a generated function per class, stop 70) makes the same record
    of construct's Containers and ListContainers as of the fast path's dicts and tuples,
    on one payload of every chunk type in the vectors: lists become tuples at any depth,
    nested records are made by their own class."""
    from mpz.chunks import _parse
    done = set()
    for name, grammar, payload in _payloads_of_vectors():
        cls = next((c for c in CHUNKS.values() if c.GRAMMAR is grammar
                    and "load" not in vars(c)), None)     # not chdr, cprm: their own load
        if cls is None or cls in done or _parse.fast_path(grammar, payload) is None:
            continue
        done.add(cls)
        want = cls.from_parsed(_parse.fast_path(grammar, payload))
        got = cls.from_parsed(grammar.parse(payload))
        assert got == want and type(got) is type(want), name
        assert all(not isinstance(v, list) for v in vars(got).values()), name
    assert {"MNAM", "HIER", "asfs", "bvhs", "smry"} <= {c.TYPE for c in done}, done


def test_a_record_with_a_post_init_is_made_by_its_init():
    """from_parsed skips the dataclass __init__ only where nothing else runs in it: a record
    class with a __post_init__ (none of the chunk table has one today) gets it run."""
    from dataclasses import dataclass

    from mpz.chunks.base import Record
    seen = []

    @dataclass(frozen=True)
    class Checked(Record):
        a: int
        b: tuple[int, ...]

        def __post_init__(self):
            seen.append((self.a, self.b))
    rec = Checked.from_parsed(construct.Container(a=3, b=construct.ListContainer([1, 2])))
    assert rec == Checked(3, (1, 2)) and seen == [(3, (1, 2))] * 2


def _named_fields(obj, path: str, seen: set[int]):
    """(path, docs) of every named field below ``obj``: a ``"name" / X * "doc"`` is a Renamed
    named ``name`` whose docs are the doc, around one of the same name (construct's ``/``)."""
    if id(obj) in seen:
        return
    seen.add(id(obj))
    if isinstance(obj, construct.Renamed):
        if obj.name and not path.endswith("." + obj.name):
            path = f"{path}.{obj.name}"
            docs, inner = obj.docs or "", obj.subcon
            while isinstance(inner, construct.Renamed):
                docs, inner = docs + (inner.docs or ""), inner.subcon
            yield path, docs
        yield from _named_fields(obj.subcon, path, seen)
        return
    for sub in getattr(obj, "subcons", None) or ():
        yield from _named_fields(sub, path, seen)
    sub = getattr(obj, "subcon", None)
    if isinstance(sub, construct.Construct):
        yield from _named_fields(sub, path, seen)


def test_every_grammar_field_carries_its_section():
    """spec/README.md: "Every field carries its § in a doc string". Five did not (HIER's
    nodes, both summaries' levels, meta's count and entries: a newcomer's QA run, stop 73)."""
    from mpz.spec import grammar as g
    seen: set[int] = set()
    fields = [f for name in sorted(vars(g)) if isinstance(getattr(g, name), construct.Construct)
              for f in _named_fields(getattr(g, name), name, seen)]
    assert len(fields) > 150
    assert [path for path, docs in fields if "§" not in docs] == []
