"""Spec 1.0.1 (Appendix B, issues 10 and 18): the reference decoder does what the text
now says, and reports each rejection with the right class, §, chunk and offset.

The vectors are the frozen ones in conformance/vectors (written by make_vectors); the
offsets expected here are computed from the spec's tables (§3.2 frame, §4 layouts),
not from the decoder's own helpers.
"""
from __future__ import annotations

import math
import struct

import numpy as np
import pytest

import mpz
from mpz import container
from mpz.conformance import manifest as mf
from mpz.decoder import decode_layers
from mpz.entropy import BlockDecoder, BlockEncoder
from mpz.errors import FormatError, LimitExceededError, MPZError

VDIR = mf.DEFAULT_DIR
#: §4.5-§4.9: where the coded field starts in each payload
CODED_AT = {"MASK": 0, "ROOT": 1, "PATT": 9, "SEGS": 6, "RESI": 6}


def _vector(name: str) -> bytes:
    (path,) = [p for p in VDIR.rglob(f"{name}.mpz")]
    return path.read_bytes()


def _chunk_offset(data: bytes, ctype: str, n: int = 0) -> int:
    """File offset of the n-th chunk of ``ctype``, walking the §3.2 frames by hand."""
    pos, seen = 8, 0
    while pos < len(data):
        t = data[pos:pos + 4].decode("latin-1")
        (length,) = struct.unpack_from("<I", data, pos + 4)
        if t == ctype:
            if seen == n:
                return pos
            seen += 1
        pos += 12 + length
    raise AssertionError(f"no chunk {ctype} #{n}")


def _reject(data: bytes) -> MPZError:
    with pytest.raises(MPZError) as info:
        mpz.decode(data)
    return info.value


# ------------------------------------------------------------------ §4.4 (10.3) --
@pytest.mark.parametrize("name,axis", [("x60-qunt-step-1e300", 0),
                                       ("x61-qunt-offset-plus-range-infinite", 1),
                                       ("x62-qunt-range-tie-rounds-to-infinity", 2)])
def test_qunt_output_range_is_rejected(name, axis):
    data = _vector(name)
    exc = _reject(data)
    assert type(exc) is FormatError and exc.section == "§4.4" and exc.chunk == "QUNT"
    assert exc.offset == _chunk_offset(data, "QUNT")
    assert f"axis {axis}" in exc.message


def test_qunt_output_range_boundary_is_the_binary64_rounding():
    # 2^1024 - 2^970 is the smallest real that rounds to +inf; just below it rounds to
    # DBL_MAX. u16 sits just below (valid), x62 exactly on it (invalid).
    step = float((2 ** 53 - 1) * 2 ** 940)
    assert math.isinf(2.0 ** 970 + step * 2.0 ** 31)
    assert 2.0 ** 969 + step * 2.0 ** 31 == float.fromhex("0x1.fffffffffffffp+1023")
    for name in ("u15-qunt-step-2pow992-bits-31", "u16-qunt-range-rounds-to-max-finite"):
        x = decode_layers(_vector(name)).positions()
        assert np.isfinite(x).all() and np.abs(x).max() > 2.0 ** 1022


# --------------------------------------------------------- §5.3 entropy offsets --
def _coded(values, **kw) -> bytes:
    enc = BlockEncoder()
    enc.block(np.asarray(values, np.int64), **kw)
    return enc.finish()


def test_block_decoder_reports_the_failing_byte():
    data = _coded(np.arange(30).reshape(10, 1, 3))
    n = len(data)
    cases = [
        (lambda: BlockDecoder(data[:3], chunk="ROOT", offset=100), 103, "shorter"),
        (lambda: BlockDecoder(b"\x01" + data[1:], chunk="ROOT", offset=100), 100, "byte 0"),
        (lambda: BlockDecoder(data[: n // 2], chunk="ROOT", offset=100).block(10, 1),
         100 + n // 2, "ends before"),
    ]
    for call, offset, words in cases:
        with pytest.raises(FormatError, match=words) as info:
            call()
        assert (info.value.offset, info.value.chunk, info.value.section) == (offset, "ROOT",
                                                                            "§5.3")
    dec = BlockDecoder(data + b"\x00\x00", chunk="RESI", offset=1000)
    dec.block(10, 1)
    with pytest.raises(FormatError, match="2 byte") as info:
        dec.close()
    assert info.value.offset == 1000 + n                 # the first byte left over
    with pytest.raises(FormatError) as info:             # no offset given: none reported
        BlockDecoder(b"\x01\x00\x00\x00\x00")
    assert info.value.offset is None


@pytest.mark.parametrize("ctype", sorted(CODED_AT))
def test_entropy_errors_point_into_the_coded_field(ctype):
    """A non-zero first coded byte is reported at that byte, in every coded chunk type."""
    base = _vector("v09-all-chunk-types")
    chunks = container.parse(base)
    i = next(k for k, c in enumerate(chunks) if c.type == ctype)
    body = bytearray(chunks[i].payload)
    body[CODED_AT[ctype]] = 0x01
    data = container.build([(c.type, bytes(body) if k == i else c.payload)
                            for k, c in enumerate(chunks)])
    exc = _reject(data)
    assert (exc.section, exc.chunk) == ("§5.3", ctype)
    assert exc.offset == _chunk_offset(data, ctype) + 8 + CODED_AT[ctype]


@pytest.mark.parametrize("name,ctype,n,pos", [
    ("x43-rc-leftover-bytes", "ROOT", 0, "leftover"),
    ("x44-rc-first-byte-nonzero", "RESI", 0, 0),
    ("x45-rc-payload-short", "RESI", 0, "end"),
])
def test_entropy_vectors_carry_byte_offsets(name, ctype, n, pos):
    data = _vector(name)
    exc = _reject(data)
    start = _chunk_offset(data, ctype, n)
    (length,) = struct.unpack_from("<I", data, start + 4)
    field = start + 8 + CODED_AT[ctype]
    if pos == "end":
        want = start + 8 + length                        # the byte after the field
    elif pos == "leftover":
        want = start + 8 + length - 2                    # the 2 bytes appended
    else:
        want = field + pos
    assert (exc.chunk, exc.section, exc.offset) == (ctype, "§5.3", want)


# -------------------------------------------------------- §6.7 rule 2 names a node --
def test_declared_range_names_the_root():
    data = _vector("x59-value-beyond-bits")
    exc = _reject(data)
    assert (exc.section, exc.chunk) == ("§6.7", "ROOT")
    assert exc.offset == _chunk_offset(data, "ROOT") and "node 0" in exc.message


def _with_bits(data: bytes, bits: int) -> bytes:
    chunks = container.parse(data)
    out = []
    for c in chunks:
        p = c.payload
        if c.type == "QUNT":
            p = p[:32] + bytes([bits])
        out.append((c.type, p))
    return container.build(out)


@pytest.mark.parametrize("name,layer", [("v04-orders-residual-only", "RESI"),
                                        ("v02-jump-lossy-gaps", "PATT")])
def test_declared_range_names_the_first_node_out_of_range(name, layer):
    data = _vector(name)
    d = decode_layers(data)
    s, q = d.stream, d.q
    peaks = [int(np.abs(q[:, list(node.members)]).max()) for node in s.nodes]
    # the smallest bits that still hold the root but not some later node
    bits = peaks[0].bit_length()
    bad = [i for i, p in enumerate(peaks) if p >= 1 << bits]
    assert bad and bad[0] > 0, peaks
    exc = _reject(_with_bits(data, bits))
    i = bad[0]
    assert (type(exc), exc.section, exc.chunk) == (FormatError, "§6.7", layer)
    assert f"node {i}:" in exc.message
    assert exc.offset == _chunk_offset(data, layer, i - 1)


# ----------------------------------------------------- the other 1.0.1 rejections --
#: name -> (class, §, chunk, which chunk of that type holds the offset)
REJECTED = {
    "x63-meta-value-surrogate": (FormatError, "§4.11", "meta", None),
    "x64-meta-value-overlong-nul": (FormatError, "§4.11", "meta", None),
    "x65-smry-starts-not-at-0": (FormatError, "§4.10", "smry", 0),
    "x66-smry-starts-repeated": (FormatError, "§4.10", "smry", 0),
    "x67-smry-last-start-at-f": (FormatError, "§4.10", "smry", 0),
    "x68-rate-minus-zero": (FormatError, "§4.1", "MHDR", 0),
    "x69-unused-pattern-out-of-range": (FormatError, "§6.7", "PATT", 0),
    "x70-unused-pattern-order2-overflow": (FormatError, "§6.2", "PATT", 0),
    "x71-residual-2pow49-times-g-2pow15": (FormatError, "§6.7", "RESI", 0),
    "x72-segs-counts-wrap-32-bits": (FormatError, "§4.8", "SEGS", 0),
    "x73-keyframe-count-2pow31": (FormatError, "§6.5", "RESI", 1),
    "x74-keyframe-spans-wrap-32-bits": (FormatError, "§6.5", "RESI", 1),
    "x75-keyframe-value-2pow32-minus-2": (FormatError, "§6.5", "RESI", 1),
    "x76-patt-samples-2pow32": (LimitExceededError, "§8", "PATT", 0),
    "x77-patt-samples-2pow40": (LimitExceededError, "§8", "PATT", 0),
    "x78-smry-4kd-wraps-32-bits": (FormatError, "§4.10", "smry", None),
    "x79-root-order2-difference-2pow32": (FormatError, "§6.2", "ROOT", 0),
    "x80-keyframe-prediction-2pow47": (FormatError, "§6.5", "RESI", 0),
    "x81-patt-left-out-without-residual-flag": (FormatError, "§3.4", "MEND", 0),
    "x82-patt-left-out-then-segs": (FormatError, "§3.4", "SEGS", 0),
}


@pytest.mark.parametrize("name", sorted(REJECTED))
def test_101_vector_is_rejected_where_the_spec_says(name):
    cls, section, ctype, n = REJECTED[name]
    data = _vector(name)
    exc = _reject(data)
    assert (type(exc), exc.section, exc.chunk) == (cls, section, ctype), str(exc)
    start = _chunk_offset(data, ctype, n or 0)
    # a payload that does not fit its layout is located at the payload (§3.2, §4)
    assert exc.offset == (start + 8 if n is None else start), str(exc)


#: §4.1's table: (offset, width, field) of MHDR's 31 bytes
MHDR_FIELDS = [(0, 1, "version_major"), (1, 1, "version_minor"), (2, 2, "flags"),
               (4, 4, "frame_count"), (8, 2, "marker_count"), (10, 2, "node_count"),
               (12, 8, "rate"), (20, 1, "units"), (21, 1, "error_metric"),
               (22, 8, "error_bound"), (30, 1, "smoothing")]


def _with_payload(data: bytes, ctype: str, change) -> bytes:
    return container.build([(c.type, change(c.payload) if c.type == ctype else c.payload)
                            for c in container.parse(data)])


@pytest.mark.parametrize("cut", range(31))
def test_short_payload_names_the_field_it_ends_inside(cut):
    """§3.2/§4: an MHDR cut to ``cut`` bytes is rejected under §4.1, naming the field of
    §4.1's table that the payload ends inside, its width and the bytes left of it."""
    offset, width, field = next(f for f in MHDR_FIELDS if f[0] <= cut < f[0] + f[1])
    exc = _reject(_with_payload(_vector("v01-walk-bounded-1mm"), "MHDR", lambda p: p[:cut]))
    assert (type(exc), exc.section, exc.chunk, exc.offset) == (FormatError, "§4.1", "MHDR",
                                                              8 + 8), str(exc)
    need = f"{width} byte{'s' if width > 1 else ''} needed"
    assert f"ends inside field '{field}': {need}, {cut - offset} left" in exc.message


@pytest.mark.parametrize("ctype,section", [("MHDR", "§4.1"), ("QUNT", "§4.4"),
                                           ("MEND", "§4.12")])
def test_payload_longer_than_its_layout_says_so(ctype, section):
    exc = _reject(_with_payload(_vector("v01-walk-bounded-1mm"), ctype, lambda p: p + b"\0"))
    assert (type(exc), exc.section, exc.chunk) == (FormatError, section, ctype), str(exc)
    assert "left after the last field" in exc.message


def test_string_not_utf8_names_its_bytes():
    exc = _reject(_vector("x64-meta-value-overlong-nul"))
    assert "not valid UTF-8" in exc.message and "b'\\xc0\\x80'" in exc.message
    assert "construct" not in exc.message and "cannot use encoding" not in exc.message


def test_layer_range_tests_the_unscaled_value_first():
    exc = _reject(_vector("x71-residual-2pow49-times-g-2pow15"))
    assert "before scaling" in exc.message and str(1 << 49) in exc.message
    exc = _reject(_vector("x69-unused-pattern-out-of-range"))
    assert f"= {1 << 36}" in exc.message


def test_key_values_are_checked_as_they_are_computed():
    # w_1 = 2^32 - 2 is reported at key 1, before it could enter any later step
    assert "w_1" in _reject(_vector("x75-keyframe-value-2pow32-minus-2")).message
    # w_2 = -(2^31 - 1) x 2^16: a prediction far beyond 32 bits, rejected at key 2
    assert "w_2" in _reject(_vector("x80-keyframe-prediction-2pow47")).message


# ------------------------------------------------------- valid files stay valid --
@pytest.mark.parametrize("name", [
    "u13-patt-k0-coded-empty", "u14-patt-k0-coded-3-bytes", "u17-keyframes-one-frame",
    "u18-meta-nul", "u19-names-compared-as-bytes", "u20-error-bound-minus-zero",
    "u21-smry-angles-no-dims", "u22-root-values-k30", "u23-context-value-2pow32"])
def test_101_valid_vectors_decode(name):
    m = mpz.decode(_vector(name))
    assert m.n_frames >= 1


def test_meta_nul_and_byte_exact_names_are_returned_unchanged():
    m = mpz.decode(_vector("u18-meta-nul"))
    assert m.metadata == {"a\x00b": "x\x00y\x00", "empty": ""}
    names = mpz.decode(_vector("u19-names-compared-as-bytes")).names
    assert [n.encode() for n in names] == [b"a", b"A", b"\xc3\xa9", b"\xc3\xa8", b"e\xcc\x81"]


def test_values_with_exponent_30_decode():
    q = decode_layers(_vector("u22-root-values-k30")).q
    assert int(q.max()) == 2 ** 31 - 1 and int(q.min()) == -(2 ** 31 - 1)
    assert 2 ** 30 in q and -(2 ** 30) in q
