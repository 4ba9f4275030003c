"""§4.13 byte coding of chdr and cprm: stored or one raw DEFLATE stream (RFC 1951).

Every rejection rule of §4.13 (R-4.13-3), §4.13.1 (R-4.13.1-2) and §4.13.2 (R-4.13.2-4)
on payloads built here with the standard library's zlib, independently of the records'
own dump; both codings decode alike; the inflation limit holds against a stream that
would expand far past it; on the real C3D files the deflated payloads are smaller and
decode to the same content.
"""
from __future__ import annotations

import dataclasses
import glob
import os
import warnings
import zlib

from hypothesis import given, settings
from hypothesis import strategies as st
import pytest

import mpz
from mpz import container
from mpz.chunks import Chdr, Cprm
from mpz.errors import FormatError
from mpz.format import MAX_C3D_PARAMETER_BYTES
from mpz.tools.make_vectors import c3d_motion


def raw_deflate(data: bytes, level: int = 6) -> bytes:
    co = zlib.compressobj(level, zlib.DEFLATED, -15)
    return co.compress(data) + co.flush()


@pytest.fixture(scope="module")
def archive_file() -> bytes:
    return mpz.encode(c3d_motion(9, storage=1, F=10, M=3, J=1, C=1, n=2), max_error=1.0)


def _payloads(data: bytes) -> dict[str, bytes]:
    return {c.type: c.payload for c in container.scan(data).chunks}


def _with(data: bytes, ctype: str, payload: bytes) -> bytes:
    return container.build([(c.type, payload if c.type == ctype else c.payload)
                            for c in container.scan(data).chunks])


def _section(prm: Cprm) -> bytes:
    """The cprm content (count + records), from its stored payload."""
    return dataclasses.replace(prm, coding=0).dump()[1:]


def test_reference_encoder_deflates_both(archive_file):
    p = _payloads(archive_file)
    assert p["chdr"][1] == 1 and p["cprm"][0] == 1
    assert len(p["chdr"]) < 2 + 512


def test_stored_and_deflated_decode_alike(archive_file):
    p = _payloads(archive_file)
    hdr, prm = Chdr.load(p["chdr"]), Cprm.load(p["cprm"])
    section = _section(prm)
    base = mpz.decode(archive_file).extras["c3d"]
    for hdr_body, prm_body in ((bytes([hdr.processor, 0]) + hdr.block, b"\0" + section),
                               (bytes([hdr.processor, 1]) + raw_deflate(hdr.block, 1),
                                b"\1" + raw_deflate(section, 1))):
        f = _with(_with(archive_file, "chdr", hdr_body), "cprm", prm_body)
        got = mpz.decode(f).extras["c3d"]
        assert got.header == base.header and got.records == base.records


def _rejects(data: bytes, section: str, text: str) -> None:
    with pytest.raises(FormatError) as info:
        mpz.decode(data)
    assert info.value.section == section and text in str(info.value), str(info.value)
    assert info.value.chunk in ("chdr", "cprm") and info.value.offset is not None


@pytest.mark.parametrize("ctype", ["chdr", "cprm"])
def test_coding_rules(archive_file, ctype):
    p = _payloads(archive_file)
    if ctype == "chdr":
        rec = Chdr.load(p["chdr"])
        head, content, sec = bytes([rec.processor]), rec.block, "§4.13.1"
    else:
        head, content, sec = b"", _section(Cprm.load(p["cprm"])), "§4.13.2"
    stream = raw_deflate(content)
    _rejects(_with(archive_file, ctype, head + b"\2" + content), "§4.13", "coding 2")
    # the stream's own faults are the byte coding's rule (R-4.13-3, §4.13); its content
    # limit is the chunk's, as for stored content (test_chdr_content_must_be_512_bytes)
    assert sec.startswith("§4.13.")
    _rejects(_with(archive_file, ctype, head + b"\1" + stream[:-2]), "§4.13",
             "ends before its final block")
    _rejects(_with(archive_file, ctype, head + b"\1" + stream + b"\0"), "§4.13",
             "1 byte(s) after the end")
    _rejects(_with(archive_file, ctype, head + b"\1" + b"\xff" * 8), "§4.13",
             "invalid DEFLATE")


def test_chdr_content_must_be_512_bytes(archive_file):
    rec = Chdr.load(_payloads(archive_file)["chdr"])
    for body in (b"\0" + rec.block[:511], b"\0" + rec.block + b"\0",
                 b"\1" + raw_deflate(rec.block[:511])):
        with pytest.raises(FormatError) as info:
            mpz.decode(_with(archive_file, "chdr", bytes([rec.processor]) + body))
        assert info.value.chunk == "chdr"
    _rejects(_with(archive_file, "chdr", b"\x54"), "§4.13.1", "shorter than")
    # 513 inflated bytes: over the limit, found while inflating
    _rejects(_with(archive_file, "chdr", bytes([rec.processor, 1]) +
                   raw_deflate(rec.block + b"\0")), "§4.13.1", "more than 512 bytes")


def test_cprm_content_limit_and_empty_payload(archive_file):
    _rejects(_with(archive_file, "cprm", b""), "§4.13.2", "empty")
    section = _section(Cprm.load(_payloads(archive_file)["cprm"]))
    # a 1 KiB stream that would inflate to 64 MiB: refused at 2^17 + 1 bytes
    bomb = raw_deflate(section + bytes((1 << 26) - len(section)), 9)
    assert len(bomb) < 1 << 17
    _rejects(_with(archive_file, "cprm", b"\1" + bomb), "§4.13.2",
             f"more than {MAX_C3D_PARAMETER_BYTES} bytes")
    stored = section + bytes(MAX_C3D_PARAMETER_BYTES + 1 - len(section))
    _rejects(_with(archive_file, "cprm", b"\0" + stored), "§4.13.2",
             f"more than {MAX_C3D_PARAMETER_BYTES}")
    # records that do not fill the content: a byte too many
    with pytest.raises(FormatError) as info:
        mpz.decode(_with(archive_file, "cprm", b"\1" + raw_deflate(section + b"\0")))
    assert info.value.chunk == "cprm"


@settings(max_examples=60, deadline=None)
@given(block=st.binary(min_size=512, max_size=512), level=st.integers(0, 9),
       coding=st.integers(0, 1))
def test_chdr_load_inverts_any_valid_stream(block, level, coding):
    block = block[:1] + b"\x50" + block[2:]
    body = raw_deflate(block, level) if coding else block
    rec = Chdr.load(bytes([84, coding]) + body)
    assert rec.block == block and rec.coding == coding
    assert Chdr.load(rec.dump()).block == block


def _real_c3d() -> list[str]:
    root = os.environ.get("MPZ_SHARED_DATA") or os.path.join(
        os.path.dirname(__file__), "..", "..", "shared", "data")
    return sorted(glob.glob(os.path.join(root, "c3d", "*.c3d")))


@pytest.mark.skipif(not _real_c3d(), reason="no ../shared/data (set MPZ_SHARED_DATA)")
def test_real_parameter_sections_shrink_and_come_back():
    for path in _real_c3d():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            m = mpz.io.read(path)
        data = mpz.encode(m, max_error=1.0)
        p = _payloads(data)
        a = m.extras["c3d"]
        assert p["cprm"][0] == 1 and p["chdr"][1] == 1, path
        assert len(p["chdr"]) < 100, (path, len(p["chdr"]))
        stored = len(_section(Cprm.load(p["cprm"]))) + 1
        assert len(p["cprm"]) < stored, (path, len(p["cprm"]), stored)
        back = mpz.decode(data).extras["c3d"]
        assert back.header == a.header and back.records == a.records, path
