"""The C3D files of the conformance vectors, checked against a writer written here from
spec §6.9 ("Writing a C3D") alone: struct and numpy, none of mpz's C3D code
(:mod:`mpz.io.c3dbin`, :mod:`mpz.io.c3d`). The archive comes from the reference decoder
(``mpz.decode``), which §6.9 steps 1-3 define and ``c3d_archive_sha256`` checks.

For every vector with a C3D archive: ``features.c3d_file_sha256`` (§7.3) is the digest of
this writer's file, and ``mpz.io.c3d.archive_bytes`` writes the same bytes; where this
writer refuses (§6.9, first met first: a next-record offset beyond 65535, a section of
more than 255 blocks, a coordinate beyond binary32), the digest is null,
``features.c3d_file_refused`` names that refusal and the reference refuses too, with the
same one. The vectors of
``make_vectors.c3d_writer_vectors`` (stop 72, one per branch of the writer no vector
reached) are also read back with ezc3d where ezc3d reads them, and their bytes that §6.9
sets are checked one by one."""
from __future__ import annotations

import hashlib
import math
from pathlib import Path
import struct

import numpy as np
import pytest

import mpz
from mpz.conformance import manifest as mf

VDIR = Path(mf.DEFAULT_DIR)
MAN = mf.load(VDIR)
C3D = {v["name"]: v for v in MAN["vectors"]
       if v["expected"] == "decode" and "c3d_archive_sha256" in v["features"]}
F32_MAX = 3.4028234663852886e38


class Refused(Exception):
    """§6.9's writer refuses the archive; the argument names which refusal."""


def _same(x: bytes, y: bytes) -> bool:
    """§6.9 "compared as ASCII without case": the same length, a-z folded, nothing
    trimmed (bytes.upper folds ASCII letters alone)."""
    return len(x) == len(y) and x.upper() == y.upper()


def _named(recs, group: bytes, name: bytes) -> list[int]:
    gids = {-r.group for r in recs if r.group < 0 and _same(r.name, group)}
    return [i for i, r in enumerate(recs) if r.group > 0 and r.group in gids
            and _same(r.name, name)]


def _record(r, last: bool) -> bytes:
    """One C3D record, as §6.9's table lays it out."""
    n = len(r.name)
    head = bytes([(-n if r.locked else n) & 0xFF, r.group & 0xFF]) + r.name
    if r.group < 0:
        body = bytes([len(r.description)]) + r.description
    else:
        body = (bytes([r.type & 0xFF, len(r.dims)]) + bytes(r.dims) + r.data
                + bytes([len(r.description)]) + r.description)
    nxt = 0 if last else 2 + len(body)
    if nxt > 0xFFFF:
        raise Refused("offset")
    return head + struct.pack("<H", nxt) + body


def spec_c3d(m) -> bytes:
    """The C3D file §6.9 defines for the decoded motion ``m`` (with its archive)."""
    a = m.extras["c3d"]
    recs = list(a.records)
    F, P = a.words.shape
    M = m.n_markers
    # Scale
    first = _named(recs, b"POINT", b"SCALE")[:1]
    read = recs[first[0]] if first and recs[first[0]].type == 4 and \
        len(recs[first[0]].data) >= 4 else None
    v = struct.unpack_from("<f", read.data if read else a.header, 0 if read else 12)[0]
    s = abs(v) if math.isfinite(v) and v != 0 else 1.0
    # Points: marker s at slot s, model output j at slot M + j, 0 at gaps
    xyz = np.zeros((F, P, 3))
    for p, slot in enumerate(a.slots):
        if slot < M:
            xyz[:, p] = np.where(m.valid[:, slot, None], m.positions[:, slot], 0.0)
        else:
            j = slot - M
            xyz[:, p] = np.where(a.model_valid[:, j, None], a.models[:, j], 0.0)
    # Storage
    one = True
    if read is not None:
        el = [abs(x) for x in struct.unpack_from(f"<{len(read.data) // 4}f", read.data)]
        one = all(x == el[0] for x in el)           # a NaN equals nothing
    with np.errstate(over="ignore", invalid="ignore"):
        q = np.rint(xyz / s)                        # ties to even
        int16 = (a.word_storage == 0 and (a.analog.size == 0 or a.analog_storage == 0)
                 and one and bool((np.abs(q) <= 32767).all()) and np.array_equal(q * s, xyz))
    signed = s if int16 else -s
    sign = 0 if int16 else 0x80000000
    # the parameter section: B from the record sizes (the rewrites keep every size); the
    # refusals in §6.9's order: a record's offset, then B, then a coordinate of the data
    size = 4 + sum(len(_record(r, i == len(recs) - 1)) for i, r in enumerate(recs))
    B = max(1, -(-size // 512))
    if B > 255:
        raise Refused("section")
    if not int16 and (np.abs(xyz) > F32_MAX).any():
        raise Refused("coordinate")
    for i in _named(recs, b"POINT", b"DATA_START"):
        r = recs[i]
        if r.type == 2 and len(r.data) >= 2:
            recs[i] = type(r)(r.group, r.locked, r.name, r.description, r.type, r.dims,
                              struct.pack("<h", 2 + B) + r.data[2:])
    for i in _named(recs, b"POINT", b"SCALE"):
        r = recs[i]
        if r.type == 4 and len(r.data) >= 4:
            k = len(r.data) // 4
            bits = [(b & 0x7FFFFFFF) | sign for b in struct.unpack_from(f"<{k}I", r.data)]
            data = struct.pack("<f", signed) + struct.pack(f"<{k - 1}I", *bits[1:]) + \
                r.data[4 * k:]
            recs[i] = type(r)(r.group, r.locked, r.name, r.description, r.type, r.dims, data)
    section = bytes([1, 0x50, B, 84]) + b"".join(
        _record(r, i == len(recs) - 1) for i, r in enumerate(recs))
    section += bytes(B * 512 - len(section))
    head = bytearray(a.header)
    head[0], head[1] = 2, 0x50
    head[12:16] = struct.pack("<f", signed)
    head[16:18] = struct.pack("<H", 2 + B)
    # Data
    fmt = [_named(recs, b"ANALOG", b"FORMAT")[:1]]
    unsigned = bool(fmt[0]) and recs[fmt[0][0]].type == -1 and \
        _same(recs[fmt[0][0]].data.strip(b" \0"), b"UNSIGNED")
    n = a.analog.shape[0] // F if a.analog.size else 0
    out = bytearray()
    for t in range(F):
        for p in range(P):
            if int16:
                out += struct.pack("<3h", *(int(x) for x in q[t, p]))
                out += struct.pack("<h", int(a.words[t, p]))
            else:
                out += np.asarray(xyz[t, p], "<f4").tobytes()     # nearest, ties to even
                w = a.words[t, p]
                out += (np.asarray(w, "<f4").tobytes() if a.word_storage == 0
                        else np.asarray(w).astype("<f4").tobytes())
        for k in range(n):
            for c in range(a.analog.shape[1]):
                w = a.analog[t * n + k, c]
                if int16:
                    out += struct.pack("<h", int(w))
                elif a.analog_storage == 0:
                    v = int(w)
                    out += struct.pack("<f", float(v + 65536 if unsigned and v < 0 else v))
                else:
                    out += np.asarray(w).astype("<f4").tobytes()
    if head[8:10] != b"\xff\xff":
        out += bytes(-len(out) % 512)
    return bytes(head) + section + bytes(out)


def _spec(name: str) -> bytes | str:
    try:
        return spec_c3d(mpz.decode(VDIR / C3D[name]["file"]))
    except Refused as exc:
        return str(exc)


@pytest.mark.parametrize("name", sorted(C3D))
def test_c3d_file_digest_is_the_spec_writers_and_the_references(name):
    from mpz.errors import InputFormatError
    from mpz.io.c3d import archive_bytes
    v = C3D[name]
    feats = v["features"]
    if name == "u66-c3d-archive-in-file-marked-1.0":     # features {"c3d_archive": True}
        pytest.skip("no c3d features")
    got = _spec(name)
    m = mpz.decode(VDIR / v["file"])
    if isinstance(got, str):
        assert feats["c3d_file_sha256"] is None, name
        assert feats["c3d_file_refused"].startswith(
            {"coordinate": "a coordinate beyond binary32",
             "section": "a parameter section of more than 255 blocks",
             "offset": "a next-record offset beyond 65535"}[got]), name
        with pytest.raises(InputFormatError, match="C3D: ") as info:
            archive_bytes(m)
        assert {"coordinate": "does not fit a float32 C3D",
                "section": "the parameter section needs",
                "offset": "needs a next-record offset of"}[got] in str(info.value), name
        return
    assert "c3d_file_refused" not in feats, name
    assert hashlib.sha256(got).hexdigest() == feats["c3d_file_sha256"], name
    assert archive_bytes(m) == got, name


# -- the bytes §6.9 sets, one by one, in the vectors of c3d_writer_vectors (stop 72) --
def _section(blob: bytes) -> tuple[int, dict]:
    """B and {(GROUP, NAME) exact bytes: [(type, dims, data, next-record offset)]} of a C3D
    parameter section walked by its next-record offsets (unsigned, as §6.9 writes them)."""
    assert blob[512 + 1] == 0x50 and blob[512 + 3] == 84
    B = blob[512 + 2]
    pos, groups, out = 512 + 4, {}, {}
    raw: list[tuple[int, bytes, int, tuple, bytes, int]] = []
    while True:
        n, gid = abs(struct.unpack_from("<b", blob, pos)[0]), struct.unpack_from("<b", blob,
                                                                                pos + 1)[0]
        name = blob[pos + 2:pos + 2 + n]
        at = pos + 2 + n
        nxt = struct.unpack_from("<H", blob, at)[0]
        if gid < 0:
            groups[-gid] = name
        else:
            t, D = struct.unpack_from("<bB", blob, at + 2)
            dims = tuple(blob[at + 4:at + 4 + D])
            size = abs(t) * math.prod(dims)
            raw.append((gid, name, t, dims, blob[at + 4 + D:at + 4 + D + size], nxt))
        if nxt == 0:
            break
        pos = at + nxt
    for gid, name, t, dims, data, nxt in raw:
        out.setdefault((groups.get(gid, b"?"), name), []).append((t, dims, data, nxt))
    return B, out


def _f32(data: bytes) -> list[float]:
    return list(struct.unpack(f"<{len(data) // 4}f", data))


def _bits(*values: float) -> list[int]:
    return [struct.unpack("<I", struct.pack("<f", v))[0] for v in values]


def _written(stem: str):
    """The reference's C3D of vector ``stem`` (name without the number), its decoded
    motion, B and parameters, words 7-8 and word 9."""
    from mpz.io.c3d import archive_bytes
    name = next(n for n in C3D if n[4:] == stem)
    m = mpz.decode(VDIR / C3D[name]["file"])
    blob = archive_bytes(m)
    assert hashlib.sha256(blob).hexdigest() == C3D[name]["features"]["c3d_file_sha256"]
    B, prm = _section(blob)
    return blob, m, B, prm, struct.unpack_from("<f", blob, 12)[0], \
        struct.unpack_from("<H", blob, 16)[0]


def _data(blob: bytes, m, B: int, int16: bool) -> tuple[np.ndarray, np.ndarray]:
    """The points [F, P, 4] and analog words [F, C n] of the data section."""
    a = m.extras["c3d"]
    F, P = a.words.shape
    an = a.analog.shape[1] * (a.analog.shape[0] // F)
    dt = "<i2" if int16 else "<f4"
    w = np.frombuffer(blob, dt, F * (4 * P + an), 512 * (1 + B)).reshape(F, 4 * P + an)
    return w[:, :4 * P].reshape(F, P, 4), w[:, 4 * P:]


WRITER_STEMS = sorted(n[4:] for n in C3D if n.startswith("u") and int(n[1:3]) >= 67)


def test_the_writer_vectors_are_there():
    assert len(WRITER_STEMS) == 28 and "c3d-no-point-scale" in WRITER_STEMS


def test_two_blocks_and_data_start():
    blob, m, B, prm, s, w9 = _written("c3d-parameter-section-of-2-blocks")
    assert (B, w9, s, len(blob)) == (2, 4, -0.5, 512 * 4)
    (t, dims, data, _), = prm[(b"POINT", b"DATA_START")]
    assert (t, dims, struct.unpack("<2h", data)) == (2, (2,), (4, 7))


@pytest.mark.parametrize("stem, int16, scale, records", [
    ("c3d-no-point-scale", True, 0.5, []),
    ("c3d-point-scale-int16-then-float32", True, 0.5,
     [(2, struct.pack("<h", 3)), (4, struct.pack("<2f", 0.5, 0.125))]),
    ("c3d-point-scale-no-element", False, 0.75, [(4, b"")]),
    ("c3d-point-scale-zero", True, 1.0, [(4, struct.pack("<f", 1.0))]),
    ("c3d-point-scale-minus-infinity", True, 1.0, [(4, struct.pack("<f", 1.0))]),
    # Storage compares the magnitudes also when the first is 0 (a review of stop 72), and
    # s = 1 also for v = 0 from header words 7-8
    ("c3d-point-scale-zero-then-other-magnitude", False, 1.0,
     [(4, struct.pack("<2f", -1.0, -0.5))]),
    ("c3d-no-point-scale-header-scale-zero", True, 1.0, []),
    ("c3d-point-scale-nan-element", False, 0.5,
     [(4, struct.pack("<4I", *_bits(-0.5), 0xFFC01234, *_bits(-0.5, -0.5)))]),
    ("c3d-point-scale-magnitudes-differ", False, 0.5,
     [(4, struct.pack("<4f", -0.5, -0.25, -0.5, -0.5))]),
    ("c3d-point-scale-signs-differ-int16", True, 0.5, [(4, struct.pack("<4f", *[0.5] * 4))]),
    ("c3d-int16-off-grid-written-float32", False, 0.5, [(4, struct.pack("<f", -0.5))]),
    ("c3d-int16-on-grid-beyond-32767", False, 0.5, [(4, struct.pack("<f", -0.5))]),
    # stop 73: a DEC and a MIPS source, written Intel; a POINT group record after its
    # parameters, whose SCALE (0.5) is read although header words 7-8 are 1.0
    ("c3d-dec-source-processor-85", True, 0.5, [(4, struct.pack("<f", 0.5))]),
    ("c3d-mips-source-processor-86", False, 0.5, [(4, struct.pack("<f", -0.5))]),
    ("c3d-point-group-record-after-its-parameters", True, 0.5, [(4, struct.pack("<f", 0.5))]),
])
def test_scale_and_storage(stem, int16, scale, records):
    """Words 7-8 (+s int16, -s float32), the POINT:SCALE records as §6.9 rewrites them, and
    the points: int16 q = x / s, or binary32 x; the fourth words and the analog words of an
    int16 source written as binary32 of the same value in a float file."""
    blob, m, B, prm, s, w9 = _written(stem)
    assert s == (scale if int16 else -scale) and w9 == 2 + B == 3
    assert [(t, d) for t, _, d, _ in prm.get((b"POINT", b"SCALE"), [])] == records
    a = m.extras["c3d"]
    pts, an = _data(blob, m, B, int16)
    M = m.n_markers
    for p, slot in enumerate(a.slots):
        x, ok = ((m.positions[:, slot], m.valid[:, slot]) if slot < M else
                 (a.models[:, slot - M], a.model_valid[:, slot - M]))
        want = np.where(ok[:, None], x, 0.0)
        got = pts[:, p, :3].astype(float) * (scale if int16 else 1.0)
        assert np.array_equal(got, want if int16 else want.astype("<f4")), (stem, p)
    assert np.array_equal(pts[:, :, 3].astype(float), a.words.astype(float))
    if a.analog_storage == 0:
        assert np.array_equal(an.reshape(a.analog.shape).astype(float), a.analog.astype(float))
        assert (a.analog < 0).any()               # negative words written negative


@pytest.mark.parametrize("stem, unsigned", [("c3d-analog-format-unsigned", True),
                                            ("c3d-analog-format-unsigned-not-first", False)])
def test_analog_format(stem, unsigned):
    blob, m, B, prm, s, w9 = _written(stem)
    a = m.extras["c3d"]
    assert s == -0.5 and a.analog_storage == 0 and (a.analog < 0).any()
    _, an = _data(blob, m, B, False)
    v = a.analog.astype(np.int64)
    want = np.where(v < 0, v + 65536, v) if unsigned else v
    assert np.array_equal(an.reshape(a.analog.shape), want.astype("<f4"))


def test_last_frame_65535_is_not_padded():
    blob, m, B, prm, s, w9 = _written("c3d-last-frame-65535")
    a = m.extras["c3d"]
    F, P = a.words.shape
    assert blob[8:10] == b"\xff\xff"
    assert len(blob) == 512 * (1 + B) + F * (16 * P + 4 * a.analog.size // F)
    assert len(blob) % 512 != 0


def test_names_compared_as_ascii_without_case():
    blob, m, B, prm, s, w9 = _written("c3d-group-point-lowercase")
    assert s == -0.5 and w9 == 3
    assert [d for _, _, d, _ in prm[(b"point", b"Scale")]] == [struct.pack("<f", -0.5)]
    assert [d for _, _, d, _ in prm[(b"point", b"data_start")]] == [struct.pack("<h", 3)]
    blob, m, B, prm, s, w9 = _written("c3d-group-point-trailing-space")
    assert s == 0.5 and w9 == 3                   # int16: 'POINT ' SCALE not read
    assert [d for _, _, d, _ in prm[(b"POINT ", b"SCALE")]] == [struct.pack("<2f", 0.25, 1.0)]
    assert [d for _, _, d, _ in prm[(b"POINT ", b"DATA_START")]] == [struct.pack("<h", 11)]


@pytest.mark.parametrize("stem, processor", [("c3d-dec-source-processor-85", 85),
                                             ("c3d-mips-source-processor-86", 86)])
def test_a_dec_or_mips_source_is_written_intel(stem, processor):
    """§6.9: processor 84 and Intel byte order whatever chdr.processor says; the header
    block's words as chdr holds them, normalised (§4.13.1): the rate, words 11-12, a
    little-endian binary32 equal to POINT:RATE, the point count, word 2, little-endian."""
    blob, m, B, prm, s, w9 = _written(stem)
    a = m.extras["c3d"]
    assert a.processor == processor and blob[512 + 3] == 84
    assert blob[2:12] == a.header[2:12] and blob[18:512] == a.header[18:]
    (t, _, rate, _), = prm[(b"POINT", b"RATE")]
    assert t == 4 and struct.unpack_from("<f", blob, 20) == struct.unpack("<f", rate)
    assert struct.unpack_from("<h", blob, 2)[0] == len(a.slots)


def test_a_point_group_record_after_its_parameters():
    """§6.9: POINT's SCALE and DATA_START are looked up under any group record named
    POINT, wherever it stands: here after them, with header words 7-8 of 1.0."""
    blob, m, B, prm, s, w9 = _written("c3d-point-group-record-after-its-parameters")
    a = m.extras["c3d"]
    at = {r.name: i for i, r in enumerate(a.records) if r.group in (-1, 1)}
    assert at[b"POINT"] > max(i for n, i in at.items() if n != b"POINT")
    assert struct.unpack_from("<f", a.header, 12)[0] == 1.0 and (s, w9, B) == (0.5, 3, 1)
    assert [d for _, _, d, _ in prm[(b"POINT", b"DATA_START")]] == [struct.pack("<h", 3)]


def test_the_refusals_come_in_spec_order():
    """§6.9 (stop 73): an archive that meets several refusals is refused for the first of
    a next-record offset beyond 65535, a section of more than 255 blocks, a coordinate
    beyond binary32. u94 meets all three; with its POINT:HUGE moved last (whose offset is
    then 0) it meets the last two, without FILL0 the first and the last, without both the
    coordinate alone. This writer and the reference name the same one each time."""
    import dataclasses

    from mpz.errors import InputFormatError
    from mpz.io.c3d import archive_bytes
    name = next(n for n in C3D if n[4:] == "c3d-writer-refuses-next-record-offset-first-of-three")
    assert C3D[name]["features"]["c3d_file_refused"].startswith("a next-record offset")
    m = mpz.decode(VDIR / C3D[name]["file"])
    a = m.extras["c3d"]
    said = {"coordinate": "does not fit a float32 C3D", "section": "the parameter section needs",
            "offset": "needs a next-record offset of"}
    huge = [r for r in a.records if r.name == b"HUGE"]
    rest = [r for r in a.records if r.name != b"HUGE"]
    assert len(huge) == 1 and a.records[-1].name == b"FILL0"
    for what, recs, want in (("all three", a.records, "offset"),
                             ("HUGE last", rest + huge, "section"),
                             ("no FILL0", a.records[:-1], "offset"),
                             ("neither", rest[:-1], "coordinate")):
        mm = dataclasses.replace(m, extras={"c3d": dataclasses.replace(a, records=recs)})
        with pytest.raises(Refused) as info:
            spec_c3d(mm)
        assert str(info.value) == want, what
        with pytest.raises(InputFormatError, match=said[want]):
            archive_bytes(mm)


def test_next_record_offsets():
    blob, m, B, prm, s, w9 = _written("c3d-next-record-offset-above-32767")
    (t, dims, data, nxt), = prm[(b"POINT", b"LONG")]
    assert len(data) == 33000 and nxt == 2 + 2 + 2 + 33000 + 1 + 11 > 32767 and w9 == 2 + B
    blob, m, B, prm, s, w9 = _written("c3d-last-record-above-65535")
    (t, dims, data, nxt), = prm[(b"?", b"LAST")]          # group 9 is never declared
    assert len(data) == 65790 and nxt == 0 and B == -(-(blob.index(data) + 65790 + 16 - 512)
                                                        // 512)


_EZC3D = r"""
import sys, numpy as np, ezc3d
c = ezc3d.c3d(sys.argv[1])
np.savez(sys.argv[2], points=c["data"]["points"], analogs=c["data"]["analogs"])
"""


@pytest.mark.parametrize("stem", [
    "c3d-parameter-section-of-2-blocks", "c3d-point-scale-zero", "c3d-point-scale-minus-infinity",
    "c3d-point-scale-magnitudes-differ", "c3d-point-scale-signs-differ-int16",
    "c3d-int16-off-grid-written-float32", "c3d-int16-on-grid-beyond-32767",
    "c3d-analog-format-unsigned-not-first", "c3d-last-frame-65535",
    "c3d-next-record-offset-above-32767", "c3d-last-record-above-65535",
    "c3d-dec-source-processor-85", "c3d-mips-source-processor-86",
    "c3d-point-group-record-after-its-parameters"])
def test_ezc3d_reads_back_the_motion(stem, tmp_path):
    """ezc3d (its own C3D reader) reads each written file back as the decoded motion: the
    points within binary32 rounding, 0 at gaps aside, and the analog words. Run in a
    child: ezc3d 1.7 crashes on some files. The vectors it reads otherwise (no POINT:SCALE,
    several SCALE records, a NaN element, a lowercase ANALOG, names it compares with case)
    are left to the byte checks above, as §6.9 says readers may read them."""
    import subprocess
    import sys
    pytest.importorskip("ezc3d")
    blob, m, B, prm, s, w9 = _written(stem)
    (tmp_path / "x.c3d").write_bytes(blob)
    subprocess.run([sys.executable, "-c", _EZC3D, str(tmp_path / "x.c3d"),
                    str(tmp_path / "x.npz")], check=True, timeout=120)
    got = np.load(tmp_path / "x.npz")
    a = m.extras["c3d"]
    M = m.n_markers
    pts = got["points"]
    assert pts.shape[2] == m.n_frames
    for p, slot in enumerate(a.slots):
        x, ok = ((m.positions[:, slot], m.valid[:, slot]) if slot < M else
                 (a.models[:, slot - M], a.model_valid[:, slot - M]))
        np.testing.assert_allclose(pts[:3, p, :].T[ok], x[ok], rtol=2.0 ** -23, atol=0)
    an = got["analogs"][0].T
    np.testing.assert_array_equal(an, a.analog.astype(float))
