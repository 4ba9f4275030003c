"""Memory of the text readers and the skeleton writers on long captures (issue 15.3: memory
per worker stays bounded on a 30-minute capture).

A 30-minute capture read from text peaked at 1.36 GB (TRC, 320 MB of text), 1.67 GB (BVH,
278 MB) and 1.14 GB (AMC, 167 MB), and `mpz decode` of it to BVH at 2.28 GB
(docs/corpus.md, "Memory per worker"). The readers held the text beside its lines (TRC),
every line of it as a list (AMC), the text while the joints were computed (BVH) and a
second copy of the joint angles (every skeleton reader); the BVH and AMC writers made
every value a Python float and the whole text at once, and the check that the positions
are the channels' joints computed every joint with two more arrays of their size.

The peaks are measured with tracemalloc (numpy's allocations report to it) on synthetic
files of 20,000-40,000 frames, and held to multiples of the bytes the result must hold
anyway: the file's bytes, which :func:`mpz.io.read` keeps while it parses, and the
float64 arrays of the motion. Each bound failed on the code before this change (its old
figure is given). The tests after them hold the pieces to the whole: the same text, the
same encoding, the same largest distance.
"""
from __future__ import annotations

import codecs
import math
from pathlib import Path
import tracemalloc

from hypothesis import example, given, settings
from hypothesis import strategies as st
import numpy as np
import pytest

from mpz import skeleton as sk
import mpz.io
from mpz.io import amc, bvh
from mpz.io.bvh import parse_bvh
from mpz.motion import Motion

ROT = "Zrotation Xrotation Yrotation"


def bvh_text(joints: int, frames: int, seed: int = 0) -> str:
    """A ROOT with 6 channels and a chain of ``joints - 1`` JOINTs with 3 rotations each,
    an End Site at its end; ``frames`` lines of random values with 2 decimals."""
    rng = np.random.default_rng(seed)
    head = ["HIERARCHY", "ROOT j0", "{", "\tOFFSET 0 0 0",
            f"\tCHANNELS 6 Xposition Yposition Zposition {ROT}"]
    for k in range(1, joints):
        head += [f"JOINT j{k}", "{", "\tOFFSET 0 1 0", f"\tCHANNELS 3 {ROT}"]
    head += ["End Site", "{", "\tOFFSET 0 1 0", "}"] + ["}"] * joints
    values = rng.integers(-9000, 9000, (frames, 3 * joints + 3)) / 100
    rows = [" ".join(map(repr, r)) for r in values.tolist()]
    return "\n".join(head + ["MOTION", f"Frames: {frames}", "Frame Time: 0.01", *rows]) + "\n"


def amc_text(frames: int, seed: int = 0) -> str:
    """The AMC of :func:`one_bone_asf`'s skeleton (6 root and 2 bone channels): ``frames``
    frames of random values with 2 decimals, written as the AMC writer writes numbers."""
    rng = np.random.default_rng(seed)
    v = (rng.integers(-9000, 9000, (frames, 8)) / 100).tolist()
    out = [":FULLY-SPECIFIED", ":DEGREES"]
    for f, r in enumerate(v, 1):
        out += [str(f), f"root {bvh.nums(r[:6])}", f"b1 {bvh.nums(r[6:])}"]
    return "\n".join(out) + "\n"


def trc_text(markers: int, frames: int, seed: int = 0) -> str:
    """A TRC of ``markers`` markers and ``frames`` frames of random values (3 decimals)."""
    rng = np.random.default_rng(seed)
    names = "\t\t\t".join(f"M{k}" for k in range(markers))
    coords = "\t".join(f"X{k}\tY{k}\tZ{k}" for k in range(1, markers + 1))
    lines = ["PathFileType\t4\t(X/Y/Z)\tlong.trc",
             "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits",
             f"100\t100\t{frames}\t{markers}\tmm",
             f"Frame#\tTime\t{names}", f"\t\t{coords}"]
    v = (rng.integers(-999999, 999999, (frames, 3 * markers)) / 1000).tolist()
    lines += [f"{f + 1}\t{f / 100:.2f}\t" + "\t".join(map(repr, r)) for f, r in enumerate(v)]
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def long_bvh(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """20 joints (63 channels, 21 positions with the End Site) over 20,000 frames."""
    path = tmp_path_factory.mktemp("bvh") / "long.bvh"
    path.write_text(bvh_text(20, 20_000))
    return path


@pytest.fixture(scope="module")
def long_amc(tmp_path_factory: pytest.TempPathFactory, one_bone_asf) -> Path:
    """40,000 frames of a root and one bone (8 channels, 2 positions)."""
    folder = tmp_path_factory.mktemp("amc")
    (folder / "long.asf").write_text(one_bone_asf())
    path = folder / "long.amc"
    path.write_text(amc_text(40_000))
    return path


@pytest.fixture(scope="module")
def warm(long_bvh: Path, long_amc: Path, tmp_path_factory: pytest.TempPathFactory) -> None:
    """Every kernel and module the measured steps use, loaded once before a peak."""
    out = tmp_path_factory.mktemp("warm")
    small = out / "small.bvh"
    small.write_text(bvh_text(3, 5))
    mpz.io.write(mpz.io.read(small), out / "back.bvh")
    (out / "small.asf").write_text(long_amc.with_suffix(".asf").read_text())
    (out / "small.amc").write_text(amc_text(5))
    mpz.io.write(mpz.io.read(out / "small.amc"), out / "back.amc")
    small_trc = out / "small.trc"
    small_trc.write_text(trc_text(2, 5))
    mpz.io.read(small_trc)


def _floats(m: Motion) -> int:
    """The bytes of the motion's float64 arrays: positions and joint angles."""
    return m.positions.nbytes + (0 if m.angles is None else m.angles.nbytes)


def test_bvh_read_lets_the_text_go_before_the_joints(long_bvh, warm, monkeypatch):
    """What is held when forward kinematics starts: the file's bytes and the values, not
    the text too. (The whole read's traced peak is the values' conversion, a fixed 4 MB of
    text at a time, on a file this small; on the 30-minute capture the joints were.)"""
    held: list[int] = []
    compute = bvh.source_joints

    def measured(*args, **kw):          # type: ignore[no-untyped-def]
        held.append(tracemalloc.get_traced_memory()[0])
        return compute(*args, **kw)

    monkeypatch.setattr(bvh, "source_joints", measured)
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        m = mpz.io.read(long_bvh)
    finally:
        tracemalloc.stop()
    size = long_bvh.stat().st_size
    assert m.angles is not None and len(held) == 1
    # before: the bytes, the text and the values (2 x 7.9 MB + 10.1 MB)
    assert held[0] - before < 1.25 * size + m.angles.nbytes, (held[0] - before, size)


def test_motion_keeps_float64_angles_as_given() -> None:
    """A float64 array of angles is the Motion's own, as its positions are (a reader's copy
    of a 30-minute capture's angles was the peak of reading it); other dtypes convert."""
    m = parse_bvh(bvh_text(3, 4))
    angles = np.ascontiguousarray(m.angles)
    kept = Motion(m.positions, m.names, m.rate, m.units, m.valid, m.metadata, m.parents,
                  angles, m.angle_names, m.extras)
    assert kept.angles is angles and kept.positions is m.positions
    as_int = Motion(m.positions, m.names, m.rate, m.units, m.valid, m.metadata, m.parents,
                    angles.astype(np.int32), m.angle_names, m.extras)
    assert as_int.angles is not None and as_int.angles.dtype == np.float64


def test_amc_read_holds_no_list_of_its_lines(long_amc, warm, traced_peak):
    box: list[Motion] = []
    peak = traced_peak(lambda: box.append(mpz.io.read(long_amc)))
    size = long_amc.stat().st_size
    # before: 3.1 x: every line of the text as a str, a list of them all (now 2.0 x)
    assert peak < 2.5 * (size + _floats(box[0])), (peak, size, _floats(box[0]))


def test_trc_read_lets_the_text_go(tmp_path, warm, traced_peak):
    path = tmp_path / "long.trc"
    path.write_text(trc_text(20, 20_000))
    box: list[Motion] = []
    peak = traced_peak(lambda: box.append(mpz.io.read(path)))
    size = path.stat().st_size
    # before: 2.3 x: the bytes, the text and its lines together (now 1.7 x)
    assert peak < 2.0 * (size + _floats(box[0])), (peak, size, _floats(box[0]))


@pytest.mark.parametrize("ext", [".bvh", ".amc"])
def test_skeleton_writers_hold_a_block_of_frames(ext, long_bvh, long_amc, warm, tmp_path,
                                                 traced_peak):
    m = mpz.io.read(long_bvh if ext == ".bvh" else long_amc)
    out = tmp_path / f"back{ext}"
    peak = traced_peak(lambda: mpz.io.write(m, out))
    # before: 2.5 x (BVH) and 4.4 x (AMC) the motion's arrays: every joint again with two
    # arrays of their size, every value a Python float, the whole text and its bytes
    # (now 0.9 x and 0.7 x, a block of frames at a time)
    assert peak < 1.5 * _floats(m), (peak, _floats(m))
    back = mpz.io.read(out)
    assert back.angles is not None and m.angles is not None
    assert np.array_equal(back.angles, m.angles)


@settings(max_examples=25, deadline=None)
@given(frames=st.integers(1, 12), block=st.integers(1, 5), seed=st.integers(0, 2**31 - 1))
def test_skeleton_writers_in_pieces_write_the_whole_text(frames, block, seed, tmp_path_factory,
                                                          one_bone_asf):
    """The pieces written, TEXT_BLOCK frames at a time, are the text format_* gives."""
    folder = tmp_path_factory.mktemp("pieces")
    m = parse_bvh(bvh_text(3, frames, seed))
    (folder / "s.asf").write_text(one_bone_asf())
    (folder / "s.amc").write_text(amc_text(frames, seed))
    a = mpz.io.read(folder / "s.amc")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(bvh, "TEXT_BLOCK", block)
        mp.setattr(amc, "TEXT_BLOCK", block)
        bvh.write_bvh(m, folder / "x.bvh")
        amc.write_amc_text(a, folder / "y.amc")
    assert (folder / "x.bvh").read_bytes() == bvh.format_bvh(m).encode()
    assert (folder / "y.amc").read_bytes() == amc.format_amc(a).encode()
    assert amc.format_amc(a) == (folder / "s.amc").read_text()


@pytest.mark.parametrize(("name", "encoding", "written"), [
    ("Jöint", "latin-1", "latin-1"),        # the source's encoding holds it
    ("J\u4e2d", "latin-1", "utf-8"),        # it does not: the whole file in UTF-8
    ("J\u4e2d", "utf-8", "utf-8"),
])
def test_skeleton_writers_in_pieces_keep_the_encoding_rule(name, encoding, written, tmp_path,
                                                           one_bone_asf, monkeypatch):
    """A name beyond the source's encoding makes the whole file UTF-8, as before; the
    numbers in the frame pieces are ASCII in either."""
    import dataclasses
    monkeypatch.setattr(bvh, "TEXT_BLOCK", 2)
    monkeypatch.setattr(amc, "TEXT_BLOCK", 2)
    m = parse_bvh(bvh_text(3, 5).replace("JOINT j1", f"JOINT {name}"))
    m.extras["skeleton"] = dataclasses.replace(m.extras["skeleton"], encoding=encoding)
    bvh.write_bvh(m, tmp_path / "x.bvh")
    assert (tmp_path / "x.bvh").read_bytes() == bvh.format_bvh(m).encode(written)
    (tmp_path / "s.asf").write_text(one_bone_asf().replace("b1", name), encoding="utf-8")
    (tmp_path / "s.amc").write_text(amc_text(5).replace("b1", name), encoding="utf-8")
    a = mpz.io.read(tmp_path / "s.amc")
    a.extras["skeleton"] = dataclasses.replace(a.extras["skeleton"], encoding=encoding)
    amc.write_amc_text(a, tmp_path / "y.amc")
    assert (tmp_path / "y.amc").read_bytes() == amc.format_amc(a).encode(written)


@settings(max_examples=40, deadline=None)
@given(frames=st.integers(1, 15), block=st.integers(1, 6), seed=st.integers(0, 2**31 - 1),
       gaps=st.floats(0, 1))
def test_largest_joint_offset_is_the_whole_arrays(frames, block, seed, gaps):
    """Block by block, the same figure as every joint at once (bit for bit), and None
    where no sample is valid."""
    m = parse_bvh(bvh_text(4, frames, seed))
    rng = np.random.default_rng(seed)
    pos = m.positions + rng.normal(0, 0.01, m.positions.shape)
    valid = rng.random(pos.shape[:2]) >= gaps
    pos[~valid] = np.nan
    edited = Motion(pos, m.names, m.rate, m.units, valid, m.metadata, m.parents,
                    m.angles, m.angle_names, m.extras)
    whole = np.linalg.norm(sk.with_joint_positions(edited).positions - pos, axis=2)[valid]
    want = float(whole.max()) if whole.size else None
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(sk, "JOINT_BLOCK", block)
        assert sk.largest_joint_offset(edited) == want


def test_bvh_row_check_and_encoding_check_hold_a_piece_at_a_time(long_bvh, monkeypatch,
                                                                  traced_peak):
    """The check that each frame is one line, and the check that the bytes are UTF-8, hold
    a piece of the text at a time (they held a copy of the whole, with its lines: 0.56 GB
    and 0.28 GB of a 30-minute BVH beside its text)."""
    monkeypatch.setattr(bvh, "_VALUES_CHUNK", 1 << 16)
    data = long_bvh.read_bytes()
    text = data.decode()
    start = text.index("Frame Time:")
    start = text.index("\n", start) + 1
    frames = text[start:].count("\n")
    assert traced_peak(lambda: bvh._check_rows(text, start, frames, 63)) < 0.25 * len(text)
    old_mac = text.replace("\n", "\r")       # lines ended by a CR alone are cut there too
    assert traced_peak(lambda: bvh._check_rows(old_mac, start, frames, 63)) < 0.25 * len(text)
    assert traced_peak(lambda: bvh.text_encoding(data)) < 0.25 * len(data)


_BREAKS = ["\n", "\r", "\r\n", "\x0b", "\x0c", "\x1c", "\x85", "\u2028", " ", "\t"]


@settings(max_examples=200, deadline=None)
@given(parts=st.lists(st.one_of(st.sampled_from(_BREAKS), st.text("ab1.", min_size=1,
                                                                    max_size=4)),
                      max_size=40),
       chunk=st.integers(1, 8), start=st.integers(0, 5))
def test_line_pieces_split_as_the_whole_text(parts, chunk, start):
    """The pieces' lines are the lines of the whole, whatever the piece size: each piece
    ends at a line feed, which neither starts nor splits any of str.splitlines' breaks."""
    text = "".join(parts)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(bvh, "_VALUES_CHUNK", chunk)
        pieces = list(bvh._line_pieces(text, min(start, len(text))))
    assert "".join(pieces) == text[min(start, len(text)):]
    assert [ln for p in pieces for ln in p.splitlines()] == \
        text[min(start, len(text)):].splitlines()


@settings(max_examples=200, deadline=None)
@example(data=b"\xef", chunk=1)            # a BOM's first byte alone is not UTF-8
@example(data=b"\xef\xbb", chunk=5)
@given(data=st.one_of(st.binary(max_size=40),
                      st.text(max_size=20).map(lambda t: t.encode("utf-8")),
                      st.text(max_size=20).map(lambda t: codecs.BOM_UTF8 + t.encode())),
       chunk=st.integers(1, 7))
def test_text_encoding_by_pieces_is_the_whole_decoding(data, chunk):
    """UTF-8 (a BOM allowed) exactly when the whole bytes decode as such, wherever the
    pieces cut a character."""
    try:
        data.decode("utf-8-sig")
        want = "utf-8"
    except UnicodeDecodeError:
        want = "latin-1"
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(bvh, "_VALUES_CHUNK", chunk)
        assert bvh.text_encoding(data) == want


def test_csv_read_makes_its_table_once_and_lets_the_text_go(tmp_path, warm, traced_peak):
    """The table is made the size of the rows at once and is the positions (it doubled as
    rows came, held the time column beside the coordinates, and was copied twice)."""
    rng = np.random.default_rng(0)
    pos = rng.integers(-999999, 999999, (20_000, 20, 3)) / 1000
    pos[5, 3] = np.nan
    path = tmp_path / "long.csv"
    mpz.io.write_csv(Motion(pos, [f"M{k}" for k in range(20)], 100.0), path)
    box: list[Motion] = []
    peak = traced_peak(lambda: box.append(mpz.io.read(path)))
    size = path.stat().st_size
    assert np.array_equal(box[0].positions, pos, equal_nan=True)
    assert not box[0].valid[5, 3] and box[0].valid.sum() == 20_000 * 20 - 1
    # before: 3.0 x (its bytes + its positions); now 1.6 x
    assert peak < 2.0 * (size + _floats(box[0])), (peak, size, _floats(box[0]))


@pytest.mark.parametrize("first_ok", [False, True])
def test_csv_of_a_wide_header_over_short_lines_is_refused_without_a_large_table(
        tmp_path, warm, traced_peak, first_ok):
    """Lines that cannot be rows do not size the table: it is made once a row has passed
    its checks, and at most twice the text's bytes at once (a review of stop 77: the
    first version counted 25 million lines in 30 s and asked 8 bytes a character of a
    100 MB file before refusing its row 2)."""
    head = "frame,time," + ",".join(f"m{i}_{c}" for i in range(1000) for c in "xyz")
    first = "0,0" + ",1" * 3000 + "\n" if first_ok else ""
    path = tmp_path / "short.csv"
    path.write_text(head + "\n" + first + "0,0\n" * 500_000)
    with pytest.raises(mpz.io.InputFormatError, match=f"row {3 if first_ok else 2} has 2 "
                       "fields, header has 3002"):
        traced_peak(lambda: mpz.io.read(path))
    peak = traced_peak(lambda: pytest.raises(mpz.io.InputFormatError, mpz.io.read, path))
    size = path.stat().st_size
    # the version before the review: 9.6 x its bytes (a table of 8 bytes a character)
    assert peak < 4.5 * size, (peak, size)


def test_largest_joint_offset_of_a_joint_beyond_float_is_nan_as_the_whole_arrays():
    """A joint that overflows to NaN (1.7e308 on two chained translations, one of them
    turned: inf - inf) gives NaN, as the whole array's max does, in whichever block it
    comes (a review of stop 77: the blocks' max dropped a NaN that came after a number).
    Only a motion made in Python gets here: the readers refuse such angles."""
    text = bvh_text(3, 2).replace(f"CHANNELS 3 {ROT}", f"CHANNELS 6 Xposition Yposition "
                                  f"Zposition {ROT}", 1)
    text = text.replace(f"CHANNELS 3 {ROT}", "CHANNELS 3 Xposition Yposition Zposition", 1)
    m = parse_bvh(text.split("Frame Time: 0.01\n")[0] + "Frame Time: 0.01\n"
                  + ("0 " * 14 + "0\n") * 2)
    assert m.angles is not None and m.angles.shape == (2, 15)
    angles = m.angles.copy()
    angles[1] = [1.7e308, 0, 0, 0, 0, 0, 1.7e308, 0, 0, 135, 0, 0, 1.7e308, 1.7e308, 0]
    pos = np.nan_to_num(m.positions)
    pos[0, 3, 1] += 500.0                   # frame 0: an End Site moved by 500
    moved = Motion(pos, m.names, m.rate, m.units, None, m.metadata, m.parents, angles,
                   m.angle_names, m.extras)
    with np.errstate(over="ignore", invalid="ignore"):
        joints = sk.with_joint_positions(moved).positions
        whole = float(np.linalg.norm(joints - pos, axis=2)[moved.valid].max())
        assert math.isnan(whole)
        for block in (1, 2, 4096):
            with pytest.MonkeyPatch.context() as mp:
                mp.setattr(sk, "JOINT_BLOCK", block)
                assert math.isnan(sk.largest_joint_offset(moved) or 0.0)


@pytest.mark.parametrize("encoding", ["utf-8-sig", "utf-16"])
def test_skeleton_writers_in_pieces_write_one_bom(encoding, tmp_path, one_bone_asf,
                                                  monkeypatch):
    """An encoding that writes a byte order mark writes it once, as for the whole text (a
    review of stop 77: each piece wrote its own, one in the middle of the file)."""
    import dataclasses
    monkeypatch.setattr(bvh, "TEXT_BLOCK", 2)
    monkeypatch.setattr(amc, "TEXT_BLOCK", 2)
    m = parse_bvh(bvh_text(3, 5))
    m.extras["skeleton"] = dataclasses.replace(m.extras["skeleton"], encoding=encoding)
    bvh.write_bvh(m, tmp_path / "x.bvh")
    assert (tmp_path / "x.bvh").read_bytes() == bvh.format_bvh(m).encode(encoding)
    (tmp_path / "s.asf").write_text(one_bone_asf())
    (tmp_path / "s.amc").write_text(amc_text(5))
    a = mpz.io.read(tmp_path / "s.amc")
    a.extras["skeleton"] = dataclasses.replace(a.extras["skeleton"], encoding=encoding)
    amc.write_amc_text(a, tmp_path / "y.amc")
    assert (tmp_path / "y.amc").read_bytes() == amc.format_amc(a).encode(encoding)
