"""Behaviours the 1.1 text now states explicitly (a clean-room decoder's log of places
where it had to guess): each test takes its expected values from spec/mpz-1.md, and
fails if the reference did otherwise.

- §6.9 "Writing a C3D": which header words and parameters restate the written storage,
  0, 0, 0 at gaps, int16 only on the grid, float32 rounding; checked on the bytes of the
  written file with a parser written here.
- §4.13.1: header counts that disagree with the chunks are not checked, and come back.
- §6.2 / §6.9 step 2: the guard and |k| < 2^31 cover model-output gap samples.
- §4.14.2: only U+000A and U+000D are line breaks; `root` is four exact bytes.
- §4.14: a text writer gives back the binary64 value.
- §7.3: `angle_bound`, `translation_bound` and `c3d_parameters`.
"""
from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
import struct

import numpy as np
import pytest

import mpz
from mpz import container
from mpz.chunks.c3d import Channel
from mpz.entropy import BlockEncoder
from mpz.errors import FormatError, MPZError
from mpz.io.amc import parse_amc, parse_asf
from mpz.io.bvh import format_bvh, parse_bvh
from mpz.tools.make_vectors import c3d_motion

REPO = Path(__file__).resolve().parents[1]
VECTORS = REPO / "conformance" / "vectors"
BLOCK = 512


# ------------------------------------------------ a C3D parser written from the guide --
def _u16(b: bytes, at: int) -> int:
    return int.from_bytes(b[at:at + 2], "little")


def _word(blob: bytes, w: int) -> int:
    """Header word w (1-based, as in the C3D user guide), unsigned."""
    return _u16(blob, 2 * w - 2)


def _params(blob: bytes) -> tuple[bytes, list[tuple[int, bytes, int, bytes]]]:
    """The 4 bytes that open the parameter section and its records, each
    (group, name, type, data) with type 0 for a group, by following the next-record
    offsets (Intel byte order)."""
    sec = blob[(blob[0] - 1) * BLOCK:]
    out = []
    pos = 4
    while True:
        n = abs(struct.unpack_from("b", sec, pos)[0])
        gid = struct.unpack_from("b", sec, pos + 1)[0]
        name = bytes(sec[pos + 2:pos + 2 + n])
        at = pos + 2 + n
        nxt = _u16(sec, at)
        if gid < 0:
            out.append((gid, name, 0, b""))
        else:
            ptype = struct.unpack_from("b", sec, at + 2)[0]
            nd = sec[at + 3]
            size = abs(ptype) * math.prod(sec[at + 4:at + 4 + nd])
            out.append((gid, name, ptype, bytes(sec[at + 4 + nd:at + 4 + nd + size])))
        if nxt == 0:
            return bytes(sec[:4]), out
        pos = at + nxt


def _point(records, name: bytes) -> tuple[int, bytes]:
    """(type, data) of parameter POINT:name."""
    gid = next(-g for g, n, _, _ in records if g < 0 and n.upper() == b"POINT")
    return next((t, d) for g, n, t, d in records if g == gid and n.upper() == name)


def _frames(blob: bytes, P: int, analog: int, dtype: str, F: int) -> tuple:
    """Points [F, P, 4] and analog words [F, analog] of the data section."""
    w = np.dtype(dtype).itemsize
    start = (_word(blob, 9) - 1) * BLOCK
    per = (4 * P + analog) * w
    raw = np.frombuffer(blob[start:start + F * per], dtype).reshape(F, 4 * P + analog)
    return raw[:, :4 * P].reshape(F, P, 4), raw[:, 4 * P:]


def _written(motion: mpz.Motion, tmp_path: Path) -> bytes:
    out = tmp_path / "out.c3d"
    mpz.io.write(motion, out)
    return out.read_bytes()


def _with_positions(m: mpz.Motion, positions: np.ndarray) -> mpz.Motion:
    return mpz.Motion(positions, m.names, m.rate, m.units, m.valid, dict(m.metadata),
                      extras=dict(m.extras))


@pytest.fixture(scope="module")
def float_source() -> mpz.Motion:
    """Float storage whose stored POINT:SCALE is +0.5 (the header says -0.5)."""
    return c3d_motion(5, storage=1, F=12, M=4, J=2, C=2, n=2)


# ------------------------------------------------------------- §6.9 writing a C3D --
def test_float_c3d_restates_its_storage_in_the_parameters(float_source, tmp_path):
    """§6.9: words 7-8 = -s for float32 storage, word 9 = 2 + B, and POINT:SCALE and
    POINT:DATA_START restate them; byte 0 = 2; the section opens with 1, 0x50, B, 84;
    every other header byte and record as stored."""
    src = float_source.extras["c3d"]
    stored = [r for r in src.records if r.name == b"SCALE"][0]
    assert struct.unpack("<f", stored.data)[0] == 0.5          # the premise: positive
    decoded = mpz.decode(mpz.encode(float_source, max_error=1.0))
    blob = _written(decoded, tmp_path)
    head, records = _params(blob)
    B = head[2]
    assert blob[0] == 2 and blob[1] == 0x50
    assert head == bytes([1, 0x50, B, 84])
    assert _word(blob, 9) == 2 + B
    assert struct.unpack_from("<f", blob, 12)[0] == -0.5
    assert _point(records, b"SCALE") == (4, struct.pack("<f", -0.5))
    assert _point(records, b"DATA_START") == (2, struct.pack("<h", 2 + B))
    assert blob[2:12] + blob[18:BLOCK] == src.header[2:12] + src.header[18:BLOCK]
    rest = [(g, n, t, d) for g, n, t, d in records if n not in (b"SCALE", b"DATA_START")]
    assert rest == [(r.group, r.name, 0 if r.is_group else r.type, r.data)
                    for r in src.records if r.name not in (b"SCALE", b"DATA_START")]


def test_float_c3d_points_gaps_and_words(float_source, tmp_path):
    """§6.9: marker s at slot s, model output j at slot M + j, 0, 0, 0 at a gap of
    either with the decoded fourth word; each coordinate the nearest binary32; analog
    words as decoded."""
    decoded = mpz.decode(mpz.encode(float_source, max_error=1.0))
    a = decoded.extras["c3d"]
    F, P = a.words.shape
    M = decoded.n_markers
    C, n = a.analog.shape[1], a.analog_samples
    assert not a.model_valid.all()                       # the premise: a model gap
    blob = _written(decoded, tmp_path)
    pts, analog = _frames(blob, P, C * n, "<f4", F)
    for p, slot in enumerate(a.slots):
        if slot < M:
            x, ok = decoded.positions[:, slot], decoded.valid[:, slot]
        else:
            x, ok = a.models[:, slot - M], a.model_valid[:, slot - M]
        want = np.where(ok[:, None], x, 0.0).astype(np.float32)   # IEEE: ties to even
        assert pts[:, p, :3].tobytes() == want.tobytes(), p
        assert pts[:, p, 3].tobytes() == a.words[:, p].astype("<f4").tobytes(), p
    assert analog.tobytes() == a.analog.reshape(F, n * C).astype("<f4").tobytes()


def test_int16_c3d_stays_int16_on_its_grid_and_goes_float_off_it(tmp_path):
    """§6.9 Storage: int16 (words 7-8 = +s, q = x / s) while every coordinate is on the
    grid; one coordinate off it makes the file float32 (-s), int16 words as binary32."""
    src = c3d_motion(6, storage=0, F=12, M=4, J=1, C=2, n=3)
    decoded = mpz.decode(mpz.encode(src))
    a = decoded.extras["c3d"]
    F, P = a.words.shape
    s = 0.5                                              # |POINT:SCALE| of c3d_motion
    blob = _written(decoded, tmp_path)
    _, records = _params(blob)
    assert struct.unpack_from("<f", blob, 12)[0] == s
    assert _point(records, b"SCALE") == (4, struct.pack("<f", s))
    pts, _ = _frames(blob, P, 2 * 3, "<i2", F)
    slot0 = a.slots.index(0)
    want = np.where(decoded.valid[:, :1], decoded.positions[:, 0], 0.0) / s
    assert pts[:, slot0, :3].tolist() == want.tolist()
    assert pts[:, :, 3].tolist() == a.words.tolist()

    off = decoded.positions.copy()
    t = int(np.argmax(decoded.valid[:, 0]))
    off[t, 0, 0] += s / 4
    blob = _written(_with_positions(decoded, off), tmp_path)
    _, records = _params(blob)
    assert struct.unpack_from("<f", blob, 12)[0] == -s
    assert _point(records, b"SCALE") == (4, struct.pack("<f", -s))
    pts, analog = _frames(blob, P, 2 * 3, "<f4", F)
    assert pts[t, slot0, 0] == np.float32(off[t, 0, 0])
    assert pts[:, :, 3].tolist() == a.words.astype(float).tolist()
    assert analog.tolist() == a.analog.reshape(F, 6).astype(float).tolist()


@pytest.mark.parametrize("change,scale,point_scale", [
    ({"data": struct.pack("<f", 0.0)}, 1.0, (4, struct.pack("<f", -1.0))),
    ({"data": struct.pack("<f", -2.0)}, 2.0, (4, struct.pack("<f", -2.0))),
    ({"type": 2, "data": struct.pack("<h", 3)}, 0.5, (2, struct.pack("<h", 3))),
], ids=["zero", "negative", "not-float32"])
def test_which_scale_the_writer_uses(float_source, tmp_path, change, scale, point_scale):
    """§6.9 Scale: s = |POINT:SCALE| when it is a float32, header words 7-8 otherwise,
    1 when that is 0; a POINT:SCALE that is not a float32 of one element is kept."""
    src = float_source.extras["c3d"]
    records = [dataclasses.replace(r, **change) if r.name == b"SCALE" else r
               for r in src.records]
    m = mpz.Motion(float_source.positions, float_source.names, float_source.rate,
                   float_source.units, float_source.valid, dict(float_source.metadata),
                   extras={"c3d": dataclasses.replace(src, records=records)})
    blob = _written(mpz.decode(mpz.encode(m, max_error=1.0)), tmp_path)
    assert struct.unpack_from("<f", blob, 12)[0] == -scale
    assert _point(_params(blob)[1], b"SCALE") == point_scale


# ---------------------------------------------------- §4.13.1 counts not checked --
def _rebuild(data: bytes, ctype: str, record) -> bytes:
    """``data`` with its first ``ctype`` chunk replaced by ``record``, CRCs correct."""
    out, done = [], False
    for c in container.scan(data).chunks:
        if c.type == ctype and not done:
            out.append((c.type, record.dump()))
            done = True
        else:
            out.append((c.type, c.payload))
    return container.build(out)


def _record(data: bytes, ctype: str):
    return next(c.record for c in container.scan(data).chunks if c.type == ctype)


def test_header_counts_that_disagree_are_accepted_and_written_back(float_source, tmp_path):
    """§4.13.1 Not checked: words 2, 3, 4-5 and 10 against P, C x n, F and cana.n; a
    writer writes them back as stored."""
    data = mpz.encode(float_source, max_error=1.0)
    hdr = _record(data, "chdr")
    block = bytearray(hdr.block)
    for w, v in ((2, 99), (3, 7), (4, 3), (5, 40), (10, 5)):
        block[2 * w - 2:2 * w] = v.to_bytes(2, "little")
    bad = _rebuild(data, "chdr", dataclasses.replace(hdr, block=bytes(block)))
    decoded = mpz.decode(bad)                            # accepted
    assert decoded.n_frames == 12
    blob = _written(decoded, tmp_path)
    assert [_word(blob, w) for w in (2, 3, 4, 5, 10)] == [99, 7, 3, 40, 5]


# ------------------------------------------- §6.2 guard and |k| at model-output gaps --
def _model_file(data: bytes, axis_order: int, axis_e: list[int]) -> bytes:
    """``data`` with a cpnt whose output 0 is a gap at every frame and whose axis x
    carries the residuals ``axis_e`` with ``axis_order``; every other block is 0."""
    pnt = _record(data, "cpnt")
    F = _record(data, "MHDR").frame_count
    J = pnt.model_count
    entry = Channel(mode=0, shift=0, order=0, low_bits=0)
    enc = BlockEncoder()
    for _ in range(pnt.point_count):
        enc.block(np.zeros((F, 1, 1)))
    flags = np.zeros((F, J, 1))
    flags[:, 0] = 1
    enc.block(flags, signed=False)
    for j in range(J):
        for a in range(3):
            e = axis_e if (j, a) == (0, 0) else [0] * F
            enc.block(np.array(e).reshape(F, 1, 1))
    models = list(pnt.models)
    axes = list(models[0].axes)
    axes[0] = dataclasses.replace(axes[0], order=axis_order)
    models[0] = dataclasses.replace(models[0], axes=tuple(axes))
    new = dataclasses.replace(pnt, words=(entry,) * pnt.point_count, models=tuple(models),
                              coded=enc.finish())
    return _rebuild(data, "cpnt", new)


def test_model_output_guard_and_range_cover_gap_samples(float_source):
    """§6.9 step 2 (§6.2 with its guard): an order-2 difference of 5 (2^30 - 1) >= 2^32,
    and a k of 2^31, at samples that are gaps, reject the file; 2^31 - 1 does not."""
    data = mpz.encode(float_source, max_error=1.0)
    big = 2**30 - 1
    with pytest.raises(FormatError) as info:
        mpz.decode(_model_file(data, 2, [0, 0] + [big] * 10))
    assert info.value.section == "§6.2"
    with pytest.raises(FormatError, match="2\\^31"):
        mpz.decode(_model_file(data, 1, [big, big, 2] + [0] * 9))
    ok = mpz.decode(_model_file(data, 1, [big, big, 1] + [0] * 9))
    assert np.isnan(ok.extras["c3d"].models[:, 0]).all()


# ------------------------------------------------------------------- §4.14.2 asfs --
AMC = """:FULLY-SPECIFIED
:DEGREES
1
root 1 2 3 0 0 0
b1 10
2
root 0 0 0 0 0 0
b1 20
"""


@pytest.fixture(scope="module")
def asf_file(one_bone_asf) -> bytes:
    asf = one_bone_asf(axis="0 0 0", dofs="rx")
    return mpz.encode(parse_amc(AMC, parse_asf(asf)), max_error=0.5)


def _asfs(data: bytes, **changes) -> bytes:
    return _rebuild(data, "asfs", dataclasses.replace(_record(data, "asfs"), **changes))


def _bone_named(data: bytes, name: str) -> bytes:
    rec = _record(data, "asfs")
    bone = dataclasses.replace(rec.bones[0], name=name)
    return _asfs(data, bones=(bone,))


def test_bone_name_root_is_four_exact_bytes(asf_file):
    """§4.14.2: `Root` and `ROOT` are valid bone names; `root` is not."""
    for name in ("Root", "ROOT"):
        back = mpz.decode(_bone_named(asf_file, name))
        assert back.extras["skeleton"].joints[1].name == name
    with pytest.raises(MPZError) as info:
        mpz.decode(_bone_named(asf_file, "root"))
    assert info.value.section == "§4.14.2"


@pytest.mark.parametrize("field", ["mass", "version", "name"])
def test_only_lf_and_cr_break_a_one_line_text(asf_file, field):
    """§4.14.2: U+000A and U+000D are rejected in mass, version and name; the other
    separators str.splitlines knows, and U+0000, pass."""
    for ch in "\x0b\x0c\x1c\x1d\x1e\x85\u2028\u2029\x00":
        mpz.decode(_asfs(asf_file, **{field: f"a{ch}b"}))
    for ch in "\n\r":
        with pytest.raises(MPZError) as info:
            mpz.decode(_asfs(asf_file, **{field: f"a{ch}b"}))
        assert info.value.section == "§4.14.2"



@pytest.mark.parametrize("field", ["mass", "version", "name"])
def test_writing_an_asf_says_which_text_does_not_read_back(asf_file, field, tmp_path):
    """Such a separator passes §4.14.2 but splits the word (mass) when the ASF written is
    read, and a leading blank is not read: the writer says so and names the value it reads
    back as (nothing lost silently), and the file read back has exactly that value. A plain
    value, or one line of text with a separator inside (the reader splits lines at CR and LF
    alone since a hostile-input QA run): no note."""
    from mpz.io import writer_problems
    for value, expect_note in (("a\u2028b", field == "mass"), ("a\x0bb", field == "mass"),
                               (" ab", True), ("ab", False)):
        m = mpz.decode(_asfs(asf_file, **{field: value}))
        refuse, notes = writer_problems(m, ".amc")
        said = [n for n in notes if "will not read back as stored" in n]
        assert not refuse and bool(said) == expect_note, (value, notes)
        mpz.io.write(m, tmp_path / "w.amc")
        back = getattr(mpz.io.read(tmp_path / "w.amc").extras["skeleton"], field)
        if expect_note:
            assert back != value and f"reads back as {back!r}" in said[0]
        else:
            assert back == value


def test_real_asf_text_reads_back_as_stored(shared_data):
    """No false note: every real ASF's text fields come back from the ASF MPZ writes."""
    from mpz.io.amc import asf_text_changes
    for amc in sorted((shared_data / "amc").glob("*.amc")):
        skel = mpz.io.read(amc).extras["skeleton"]
        assert asf_text_changes(skel) == {}, amc.name

# ---------------------------------------------------------- §4.14 channel values --
BVH = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 3 Xposition Yposition Zrotation
  End Site
  {
    OFFSET 0 1 0
  }
}
MOTION
Frames: 3
Frame Time: 0.01
0.0000024 -0.0000024 180
1.5 0 -179.99
-0.3 2.25 12.34
"""


def test_bvh_text_reads_back_as_the_decoded_values():
    """§4.14: a text writer gives back v, the binary64 of §6.10 step 5 (any text that
    reads back as v: the reference prints the shortest)."""
    m = mpz.decode(mpz.encode(parse_bvh(BVH), max_error=0.01))
    rows = format_bvh(m).split("Frame Time:")[1].splitlines()[1:]
    back = np.array([[float(v) for v in row.split()] for row in rows if row.strip()])
    assert back.tobytes() == m.angles.tobytes()


# ------------------------------------------------------------------ §7.3 features --
def _manifest() -> list[dict]:
    return json.loads((VECTORS / "manifest.json").read_text())["vectors"]


def _kinds(rec) -> list[int]:
    """The channel kinds in channel (joint) order (§4.14)."""
    if rec.TYPE == "bvhs":
        return [k for j in rec.joints for k in j.channels]
    return list(rec.root_order) + [k for b in rec.bones for k in b.dofs]


def _skeleton_vectors():
    """(manifest entry, its features.skeleton, file bytes, skeleton record) of every vector
    with a skeleton chunk."""
    for v in _manifest():
        feat = v.get("features", {}).get("skeleton")
        if feat is not None:
            data = (VECTORS / v["file"]).read_bytes()
            yield v, feat, data, _record(data, feat["chunk"])


def test_skeleton_bounds_are_the_spec_formula():
    """§7.3: h = (m / 10^d) / 2 in binary64; translation_bound the largest h of kinds
    0-2 and 6, angle_bound of kinds 3-5, times 180/pi for radians; 0 without one."""
    seen = 0
    for v, feat, _, rec in _skeleton_vectors():
        h = [c.step_mantissa / 10.0 ** c.step_digits / 2 for c in rec.channels]
        kinds = _kinds(rec)
        rot = max((x for x, k in zip(h, kinds, strict=True) if 3 <= k <= 5), default=0.0)
        lin = max((x for x, k in zip(h, kinds, strict=True) if not 3 <= k <= 5), default=0.0)
        if rec.TYPE == "asfs" and rec.angle_unit == 1:
            rot = rot * (180 / math.pi)
        assert (feat["angle_bound"], feat["translation_bound"]) == (rot, lin), v["name"]
        seen += 1
    assert seen >= 4


def test_c3d_parameters_counts_groups_and_parameters():
    """§7.3: c3d_parameters is R, the cprm records, groups and parameters together."""
    seen = 0
    for v in _manifest():
        feat = v.get("features", {})
        if "c3d_parameters" not in feat:
            continue
        rec = _record((VECTORS / v["file"]).read_bytes(), "cprm")
        assert feat["c3d_parameters"] == rec.count == len(rec.records), v["name"]
        assert any(r.group < 0 for r in rec.records) and any(r.group > 0 for r in rec.records)
        seen += 1
    assert seen >= 1


def test_skeleton_channel_digest_is_of_the_integers_the_coded_field_holds():
    """§7.3 `channels_sha256`: SHA-256 of x [F, C] (§6.10 after step 3) as little-endian
    int64, C order. Checked without the reference decoder: the x that hashes to the digest
    must be what the coded field holds, so re-coding it with the independent coder of the
    conformance package (mpz.conformance.rangecoder, written from §5), with each entry's
    order, wrap and group, must give the stored bytes; and wrapped channels lie in their
    turn, low .. low + N - 1."""
    import hashlib

    from mpz.channels import decode as decode_channels
    from mpz.conformance.rangecoder import RefEncoder
    seen = 0
    for v, feat, data, rec in _skeleton_vectors():
        F = mpz.info(data).frames
        x = decode_channels(rec.channels, rec.coded, F)
        assert x.shape == (F, rec.channel_count)
        assert hashlib.sha256(np.ascontiguousarray(x, "<i8").tobytes()).hexdigest() \
            == feat["channels_sha256"], v["name"]
        e = np.empty_like(x)
        for c, cc in enumerate(rec.channels):
            col = x[:, c]
            r = col.copy()                       # §6.2 residuals of order 0, 1, 2, by hand
            if cc.order >= 1:
                r[1:] = col[1:] - col[:-1]
            if cc.order == 2:
                r[2:] = col[2:] - 2 * col[1:-1] + col[:-2]
            if cc.wrap:
                n = 360 * 10 ** cc.step_digits // cc.step_mantissa
                assert ((cc.low <= col) & (col < cc.low + n)).all(), v["name"]
                r = (r + n // 2) % n - n // 2    # the residue nearest 0, as the encoder
            e[:, c] = r
        enc = RefEncoder()
        groups = np.array([cc.group for cc in rec.channels])
        for g in range(int(groups.max(initial=-1)) + 1):
            enc.block(e[:, groups == g, None])
        assert enc.finish() == rec.coded, v["name"]
        seen += 1
    assert seen >= 7
