"""C3D files with more than 65,535 frames (issue 12, the last defect).

C3D header words 4-5 (first and last frame) are 16-bit. The C3D user guide's appendix
"The C3D frame count" puts larger counts in the parameters: the header's last frame is
65535, TRIAL:ACTUAL_START_FIELD / ACTUAL_END_FIELD hold the first and last frame as two
int16 words (low, high), POINT:LONG_FRAMES the count as a float. These tests write
such files with ``mpz.io.write`` and read them back with our reader and with ezc3d; take
a hand-built Vicon-style source (first frame 397, int16 storage) through MPZ and back;
and check that inconsistent frame parameters are refused cleanly. Expected values come
from the synthetic data and from the guide's arithmetic (70000 = 4464 + 1 x 65536),
never from the writer under test.
"""
from __future__ import annotations

from pathlib import Path
import struct
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st
import numpy as np
import pytest

import mpz
from mpz.errors import InputFormatError
from mpz.io import c3dbin, read, write
from mpz.motion import Motion

ezc3d = pytest.importorskip("ezc3d")

F = 70_000  # more frames than a 16-bit header word can count


def _motion(frames: int = F) -> Motion:
    t = np.arange(frames) / 100.0
    pos = np.empty((frames, 2, 3))
    pos[:, 0] = np.stack([100 * np.sin(t), 50 * np.cos(t), 900 + t], axis=1)
    pos[:, 1] = np.stack([t, -t, np.full(frames, 1000.0)], axis=1) + 1.0
    valid = np.ones((frames, 2), bool)
    valid[[5, min(65_535, frames - 2), frames - 1], 1] = False   # gaps, past 2^16 too
    pos[~valid] = np.nan
    return Motion(pos, ["LASI", "RASI"], 100.0, "mm", valid, {})


@pytest.fixture(scope="module")
def long_file(tmp_path_factory: Any) -> tuple[Path, Motion]:
    m = _motion()
    path = tmp_path_factory.mktemp("long") / "long.c3d"
    write(m, path)
    return path, m


def _ez_points(path: Path) -> tuple[Any, np.ndarray]:
    c = ezc3d.c3d(str(path))
    return c, np.asarray(c["data"]["points"])[:3].transpose(2, 1, 0)


# ------------------------------------------------------- writing a long motion --
def test_written_long_c3d_follows_the_frame_count_convention(long_file):
    path, _ = long_file
    raw = path.read_bytes()
    params: Any = c3dbin.parse_c3d(raw).params
    assert struct.unpack_from("<HH", raw, 6) == (1, 65535)       # header words 4-5
    # TRIAL: two int16 words, low then high: 70000 = 4464 + 1 * 65536
    assert list(params["TRIAL"]["ACTUAL_START_FIELD"]) == [1, 0]
    assert list(params["TRIAL"]["ACTUAL_END_FIELD"]) == [4464, 1]
    assert float(params["POINT"]["LONG_FRAMES"][0]) == 70000.0
    # POINT:FRAMES is an int16 (ezc3d refuses a float) holding 0xFFFF
    assert int(params["POINT"]["FRAMES"][0]) & 0xFFFF == 0xFFFF


def test_long_c3d_reads_back_with_our_reader(long_file):
    path, m = long_file
    d = c3dbin.parse_c3d(path.read_bytes())
    assert d.points.shape == (F, 2, 3) and d.first_frame == 1
    np.testing.assert_array_equal(d.residual_words < 0, ~m.valid)
    np.testing.assert_array_equal(d.points[m.valid], m.positions[m.valid].astype(np.float32))
    back = read(path)
    assert back.n_frames == F and back.names == m.names and back.rate == 100.0
    np.testing.assert_array_equal(back.valid, m.valid)
    np.testing.assert_array_equal(back.positions[m.valid],
                                  m.positions[m.valid].astype(np.float32))
    assert "c3d" in back.extras and "warning" not in back.metadata


def test_long_c3d_reads_back_with_ezc3d(long_file):
    path, m = long_file
    c, pts = _ez_points(path)
    assert pts.shape == (F, 2, 3)
    assert c["header"]["points"]["first_frame"] == 0          # ezc3d counts from 0
    assert c["header"]["points"]["last_frame"] == F - 1
    assert np.isnan(pts[~m.valid]).all()
    np.testing.assert_array_equal(pts[m.valid], m.positions[m.valid].astype(np.float32))


def test_the_reader_lets_ezc3d_go_before_it_converts_the_points(long_file, monkeypatch):
    """ezc3d's object (its C++ copy of every point, about 160 bytes a point-frame, and
    arrays the reader does not use) is gone when the points are converted
    (motion_from_points copies the positions): it was held until the Motion was made,
    the peak of reading a 30-minute capture (218,484 frames x 41 markers: 2.41 GB of
    RSS to read it, 2.42 GB for `mpz encode`; 2.15 and 2.16 GB now, docs/corpus.md
    "Memory per worker"). This test failed before: the object was alive at the
    conversion."""
    import sys
    import types
    import weakref

    from mpz.io import c3d as c3dmod
    path, m = long_file
    made: list[weakref.ref[Any]] = []

    def recorded(*args: Any, **kwargs: Any) -> Any:
        c = ezc3d.c3d(*args, **kwargs)
        made.append(weakref.ref(c))
        return c
    # the reader imports ezc3d where it reads; ezc3d's own code keeps its module
    seen = types.ModuleType("ezc3d")
    seen.__dict__.update(vars(ezc3d))
    seen.c3d = recorded  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "ezc3d", seen)
    alive: list[list[bool]] = []
    convert = c3dmod.motion_from_points

    def converting(*args: Any, **kwargs: Any) -> Motion:
        alive.append([r() is not None for r in made])
        return convert(*args, **kwargs)
    monkeypatch.setattr(c3dmod, "motion_from_points", converting)
    back = read(path)
    assert back.metadata["reader"] == "ezc3d" and back.n_frames == F
    assert alive == [[False]]
    np.testing.assert_array_equal(back.valid, m.valid)


def test_a_file_the_numpy_reader_reads_is_parsed_once(long_file, monkeypatch):
    """A C3D that ezc3d does not read (here: one it may not have the memory for) gives
    its archive from the parse that read its points: a second parse held a second copy
    of every point (1.5 times the positions) beside the first's Motion (the 30-minute
    capture read so: 1.27 GB of RSS for `mpz encode`, 1.15 GB now)."""
    from mpz.io import c3d as c3dmod
    path, m = long_file
    monkeypatch.setattr(c3dmod, "memory_short", lambda need: "a test's limit")
    calls: list[int] = []
    parse = c3dbin.parse_c3d

    def counted(data: bytes) -> Any:
        calls.append(len(data))
        return parse(data)
    monkeypatch.setattr(c3dbin, "parse_c3d", counted)
    back = read(path)
    assert back.metadata["reader"] == "mpz.io.c3dbin" and "c3d" in back.extras
    assert len(calls) == 1
    np.testing.assert_array_equal(back.valid, m.valid)


def test_a_c3d_is_written_back_without_copies_of_its_points(tmp_path, traced_peak):
    """archive_bytes (mpz decode to C3D) of a float32 source: the points to write
    (float64, [F, P, 3]), the file's buffer and its bytes, and little else: at most 2.75
    times the points' float64 bytes (2.67 here). Before, it divided every coordinate by
    the scale and rounded it (deciding int16 storage, which a float32 source never gets)
    and took |x| of all of them: 3.0 times (`mpz decode` of the 30-minute capture to C3D
    peaked at 1.08 GB of RSS, 0.93 GB now)."""
    from mpz.io.c3d import archive_bytes
    F, M = 4000, 20
    rng = np.random.default_rng(3)
    pos = np.cumsum(rng.normal(0, 1, (F, M, 3)), axis=0) + 500
    write(Motion(pos, [f"m{k}" for k in range(M)], 100.0, "mm"), tmp_path / "f.c3d")
    m = read(tmp_path / "f.c3d")
    assert m.extras["c3d"].word_storage == 1            # float32 points
    box: list[bytes] = []
    peak = traced_peak(lambda: box.append(archive_bytes(m)))
    back = c3dbin.parse_c3d(box[0]).points
    np.testing.assert_array_equal(back, m.positions)   # float32 values, widened
    assert peak <= 2.75 * m.positions.nbytes, peak / m.positions.nbytes


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 9), st.integers(1, 5), st.integers(1, 40), st.sampled_from(
    [0.1, 0.5, 1.0, 1e-300]), st.integers(0, 2 ** 32 - 1))
def test_blockwise_grid_and_peak_are_those_of_the_whole_array(F, P, values, scale, seed):
    """_on_int16_grid and _largest_magnitude, a few values at a time, decide and give what
    the whole array's expressions did (NaN, infinities, off-grid and out-of-range values
    among them)."""
    from mpz.io import c3d as c3dmod
    rng = np.random.default_rng(seed)
    xyz = rng.integers(-40000, 40000, (F, P, 3)) * scale
    pick = rng.integers(0, 8, xyz.shape)
    xyz[pick == 0] = rng.normal(0, 100, int((pick == 0).sum()))
    if rng.integers(0, 4) == 0 and xyz.size:
        xyz.flat[int(rng.integers(0, xyz.size))] = rng.choice([np.nan, np.inf, -np.inf, 1e308])
    with np.errstate(over="ignore", invalid="ignore"):
        q = np.rint(xyz / scale)
        want = bool(np.array_equal(q * scale, xyz) and np.abs(q).max(initial=0) <= 32767)
    old_grid, old_peak = c3dmod._GRID_VALUES, c3dbin._PEAK_VALUES
    c3dmod._GRID_VALUES = c3dbin._PEAK_VALUES = values
    try:
        assert c3dmod._on_int16_grid(xyz, scale) == want
        got = c3dbin._largest_magnitude(xyz)
    finally:
        c3dmod._GRID_VALUES, c3dbin._PEAK_VALUES = old_grid, old_peak
    whole = float(np.abs(xyz).max(initial=0.0))
    assert got == whole or (np.isnan(got) and np.isnan(whole))


@pytest.mark.parametrize("frames", [65_535, 65_536, 70_001])
def test_frame_counts_around_the_limit(tmp_path, frames):
    """Both readers agree on every count near 2^16, whatever the last block's fill."""
    m = _motion(frames)
    write(m, tmp_path / "m.c3d")
    _, pts = _ez_points(tmp_path / "m.c3d")
    d = c3dbin.parse_c3d((tmp_path / "m.c3d").read_bytes())
    assert pts.shape[0] == d.points.shape[0] == frames
    np.testing.assert_array_equal(d.points[m.valid], pts[m.valid])


def test_long_motion_through_mpz(long_file, tmp_path):
    """C3D -> MPZ -> C3D: same header and parameters, same frames for both readers."""
    path, m = long_file
    src = read(path)
    back = mpz.decode(mpz.encode(src, max_error=1.0))
    assert back.n_frames == F and "c3d" in back.extras
    out = tmp_path / "back.c3d"
    write(back, out)
    a, b = path.read_bytes(), out.read_bytes()
    start = 512 * (struct.unpack_from("<H", a, 16)[0] - 1)
    assert len(a) == len(b) and a[:start] == b[:start]       # header + parameter section
    _, pts = _ez_points(out)
    assert pts.shape == (F, 2, 3)
    assert np.isnan(pts[~m.valid]).all()
    err = np.linalg.norm(pts[m.valid] - m.positions[m.valid], axis=1)
    assert err.max() <= 1.0 + 1e-3    # 1 mm, plus float32 storage of ~1 km coordinates


# ------------------------------------ a Vicon-style source with > 65535 frames --
def _param(name: str, gid: int, ptype: int, dims: list[int], data: bytes, desc: bytes = b""
           ) -> bytes:
    body = struct.pack("bB", ptype, len(dims)) + bytes(dims) + data + bytes([len(desc)]) + desc
    return struct.pack("bb", len(name), gid) + name.encode() + struct.pack("<H", 2 + len(body)) \
        + body


def _group(name: str, gid: int) -> bytes:
    return struct.pack("bb", len(name), -gid) + name.encode() + struct.pack("<H", 3) + b"\x00"


def vicon_style(frames: int, first: int, *, trial: tuple[int, int] | None = None,
                long_frames: float | None = None, trial_type: int = 2,
                header_last: int = 65535, only_start: bool = False) -> tuple[bytes, np.ndarray]:
    """An int16 C3D (scale 0.1) of 2 points, written here from the C3D guide: header
    last frame ``header_last``, POINT:FRAMES the int16 -1, TRIAL fields (default: the
    true range), optional POINT:LONG_FRAMES; no padding after the data."""
    start, end = trial if trial is not None else (first, first + frames - 1)

    def words(v: int) -> bytes:
        if trial_type == 4:
            return struct.pack("<ff", v & 0xFFFF, v >> 16)
        return struct.pack("<HH", v & 0xFFFF, v >> 16)

    recs = [_group("POINT", 1),
            _param("USED", 1, 2, [], struct.pack("<h", 2)),
            _param("SCALE", 1, 4, [], struct.pack("<f", 0.1)),
            _param("RATE", 1, 4, [], struct.pack("<f", 200.0)),
            _param("DATA_START", 1, 2, [], struct.pack("<h", 3)),
            _param("FRAMES", 1, 2, [], struct.pack("<h", -1)),
            _param("LABELS", 1, -1, [4, 2], b"LASIRASI", b"marker names"),
            _param("UNITS", 1, -1, [2], b"mm")]
    if long_frames is not None:
        recs.append(_param("LONG_FRAMES", 1, 4, [], struct.pack("<f", long_frames)))
    recs.append(_group("TRIAL", 2))
    recs.append(_param("ACTUAL_START_FIELD", 2, trial_type, [2], words(start)))
    if not only_start:
        recs.append(_param("ACTUAL_END_FIELD", 2, trial_type, [2], words(end)))
    at = 2 + recs[-1][0]                         # the last record's next offset is 0
    recs[-1] = recs[-1][:at] + b"\x00\x00" + recs[-1][at + 2:]
    section = bytes([1, 0x50, 1, 84]) + b"".join(recs)
    assert len(section) <= 512
    header = bytearray(512)
    header[0:2] = bytes([2, 0x50])
    struct.pack_into("<hHHHhf", header, 2, 2, 0, first, header_last, 0, 0.1)
    struct.pack_into("<HHf", header, 16, 3, 0, 200.0)
    rng = np.random.default_rng(7)
    grid = np.cumsum(rng.integers(-3, 4, (frames, 2, 3)), axis=0) + 1000
    four = np.zeros((frames, 2, 4), "<i2")
    four[:, :, :3] = grid
    four[:, :, 3] = 3                                    # residual word, camera byte 0
    four[100, 1] = (0, 0, 0, -1)                          # one gap
    return bytes(header) + section.ljust(512, b"\x00") + four.tobytes(), four


def test_vicon_style_source_comes_back_identical(tmp_path):
    frames, first = 70_000, 397
    blob, four = vicon_style(frames, first)
    src = tmp_path / "vicon.c3d"
    src.write_bytes(blob)
    d = c3dbin.parse_c3d(blob)
    assert d.points.shape[0] == frames and d.first_frame == first
    c, pts = _ez_points(src)
    assert pts.shape[0] == frames and c["header"]["points"]["first_frame"] == first - 1
    m = read(src)
    assert m.n_frames == frames and "c3d" in m.extras
    # int16 storage: coordinate = word x POINT:SCALE (the stored binary32 0.1)
    np.testing.assert_allclose(m.positions[:, 0], four[:, 0, :3] * float(np.float32(0.1)),
                               rtol=1e-12)
    back = mpz.decode(mpz.encode(m))            # default: exact on the int16 grid
    out = tmp_path / "out.c3d"
    write(back, out)
    assert out.read_bytes() == blob
    assert c3dbin.parse_c3d(out.read_bytes()).first_frame == first


# ---------------------------------------------------- inconsistent parameters --
BAD: dict[str, dict[str, Any]] = {
    "end before start": dict(trial=(80_000, 397)),
    "TRIAL and LONG_FRAMES disagree": dict(long_frames=69_000.0),
    "LONG_FRAMES not a count": dict(long_frames=70_000.5),
    "LONG_FRAMES beyond 32 bits": dict(long_frames=1e38),
    "TRIAL, LONG_FRAMES and the float32 nearest disagree": dict(
        trial=(1, 2 ** 25 + 1), long_frames=float(2 ** 25 + 4)),
    "TRIAL stored as floats": dict(trial_type=4),
    "only ACTUAL_START_FIELD": dict(only_start=True),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_inconsistent_frame_parameters_are_refused(tmp_path, case):
    blob, _ = vicon_style(70_000, 1, **BAD[case])
    with pytest.raises(InputFormatError, match="C3D: .*(TRIAL|LONG_FRAMES|frame)"):
        c3dbin.parse_c3d(blob)
    (tmp_path / "bad.c3d").write_bytes(blob)
    with pytest.raises(InputFormatError, match="TRIAL|LONG_FRAMES|frame"):
        read(tmp_path / "bad.c3d")


def test_agreeing_parameters_are_accepted():
    blob, _ = vicon_style(70_000, 5, long_frames=70_000.0)
    d = c3dbin.parse_c3d(blob)
    assert d.points.shape[0] == 70_000 and d.first_frame == 5


def test_trial_fields_override_a_saturated_header():
    """The guide lets the header say 1..65535 for any long range: TRIAL decides."""
    blob, _ = vicon_style(70_000, 1, trial=(2, 60_001))
    d = c3dbin.parse_c3d(blob)
    assert d.points.shape[0] == 60_000 and d.first_frame == 2


def test_frame_parameters_only_count_when_the_header_cannot(tmp_path):
    """A header that is not saturated stays authoritative (Dance1-style files whose
    parameters disagree keep reading as before)."""
    blob, _ = vicon_style(600, 1, trial=(1, 9_000), header_last=600)
    assert c3dbin.parse_c3d(blob).points.shape[0] == 600


def test_a_huge_declared_count_is_checked_against_the_bytes():
    """2^32 - 1 frames declared, 70000 present: a clean error, nothing allocated for it."""
    blob, _ = vicon_style(70_000, 1, trial=(1, 0xFFFFFFFF), long_frames=float(2 ** 32 - 1))
    with pytest.raises(InputFormatError, match="truncated point data: 4294967295 frames"):
        c3dbin.parse_c3d(blob)


# ----------------------------------------------------------------- property --
@settings(max_examples=60, deadline=None)
@given(first=st.integers(1, 2 ** 20), frames=st.integers(1, 2 ** 31))
def test_any_frame_range_is_declared_and_read_back(first, frames):
    """plain_parts + build_c3d declare (first, frames) for any range a 32-bit TRIAL field
    holds; with no points the data is empty, so even 2^31 frames cost nothing."""
    header, records = c3dbin.plain_parts([], 50.0, "mm", frames, first)
    blob = c3dbin.build_c3d(header, records, np.zeros((frames, 0, 3)),
                            np.zeros((frames, 0), "<f4"), np.zeros((0, 0), "<f4"),
                            float_storage=True, scale=1.0)
    assert c3dbin.declared_frames(blob) == (first, frames)
    h_first, h_last = struct.unpack_from("<HH", blob, 6)
    if first + frames - 1 <= 65535:
        assert (h_first, h_last) == (first, first + frames - 1)
    else:
        assert h_last == 65535


# ------------------------------- the first frame number in other formats (TRC) --
@pytest.mark.parametrize(("first", "trial", "expected"), [
    (397, None, 397),              # header word 4 and TRIAL agree
    (1, (2, 60_001), 2),           # a saturated header says 1: TRIAL decides, as it does
    (1, (70_000, 139_999), 70_000),  # for the frame count; past 2^16 (high word 1)
])
def test_a_long_c3d_numbers_its_frames_from_trial_in_a_trc(tmp_path, first, trial, expected):
    """A C3D of more than 65535 frames keeps its first frame number in its TRIAL
    parameters; written as a TRC (which holds it as the first Frame#), it must number
    its rows from there, not from the saturated header (before: 1 for the last two)."""
    frames = 70_000 if trial is None else trial[1] - trial[0] + 1
    blob, _ = vicon_style(frames, first, trial=trial)
    src = tmp_path / "long.c3d"
    src.write_bytes(blob)
    m = read(src)
    assert m.extras["c3d"].first_frame() == expected
    back = mpz.decode(mpz.encode(m))
    out = tmp_path / "long.trc"
    write(back, out)
    rows = [ln for ln in out.read_text().splitlines()[5:] if ln.strip()]
    numbers = [int(r.split("\t")[0]) for r in (rows[0], rows[-1])]
    assert numbers == [expected, expected + frames - 1]
    first_row_time = float(rows[0].split("\t")[1])
    assert first_row_time == pytest.approx((expected - 1) / 200.0)
