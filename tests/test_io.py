"""Unit tests of mpz.io that need no real recordings.

Expected values are derived by hand in the comments (forward kinematics of
tiny skeletons, byte layouts of tiny C3D files), never taken from the code
under test.
"""
from __future__ import annotations

import re
import struct

from hypothesis import given, settings
from hypothesis import strategies as st
import numpy as np
import pytest

from mpz import Motion
from mpz.errors import InputFormatError, MotionError, MPZError
from mpz.io import c3dbin, detect_format, read, read_amc, read_bvh, read_bytes, read_c3d, write
from mpz.io.amc import find_asf, parse_asf
from mpz.io.bvh import frame_rate_from_frame_time
from mpz.io.table import rate_from_times
from mpz.synth import generate
from mpz.tools import cmd_show, mpz_cli

DANCE_RATE = 65.0364227294921875  # float32 POINT:RATE of c3d.org Dance1.c3d


def synthetic(frames=7, rate=DANCE_RATE, units="mm", seed=1):
    """A small Motion with gaps and awkward names."""
    rng = np.random.default_rng(seed)
    names = ["Subj:LASI", "R.Knee", "a b", "Ünï", "x_y_z"]
    pos = rng.normal(0.0, 500.0, (frames, len(names), 3))
    valid = np.ones((frames, len(names)), bool)
    valid[0, 1] = valid[3, 2] = valid[3, 4] = False
    valid[:, 3] = False
    valid[2, 3] = True
    pos[~valid] = np.nan
    return Motion(pos, names, rate, units, valid)


# -- round trips ---------------------------------------------------------

# (extension, exact positions?, names kept?, units kept?, atol)
ROUND_TRIPS = [
    (".npy", True, False, False, 0.0),
    (".csv", True, True, False, 0.0),
    (".trc", False, True, True, 5e-7),     # 6 decimals
    (".c3d", False, True, True, None),     # float32 storage
]


@pytest.mark.parametrize("ext,exact,keeps_names,keeps_units,atol", ROUND_TRIPS)
def test_round_trip(tmp_path, ext, exact, keeps_names, keeps_units, atol):
    m = synthetic()
    p = tmp_path / f"m{ext}"
    write(m, p)
    # NPY stores no rate; everything else must give it back bit-exactly
    back = read(p, rate=m.rate) if ext == ".npy" else read(p)
    assert back.rate == DANCE_RATE
    assert back.n_frames == m.n_frames and back.n_markers == m.n_markers
    np.testing.assert_array_equal(back.valid, m.valid)
    assert np.isnan(back.positions[~back.valid]).all()
    if exact:
        np.testing.assert_array_equal(back.positions[m.valid], m.positions[m.valid])
    elif atol is None:
        np.testing.assert_array_equal(back.positions[m.valid],
                                      m.positions[m.valid].astype(np.float32).astype(np.float64))
    else:
        np.testing.assert_allclose(back.positions[m.valid], m.positions[m.valid], rtol=0, atol=atol)
    if keeps_names:
        assert back.names == m.names
    else:
        assert back.names == [f"M{i}" for i in range(m.n_markers)]
    assert back.units == (m.units if keeps_units else "")


@pytest.mark.parametrize("units", ["mm", "cm", "m"])
def test_c3d_and_trc_keep_units(tmp_path, units):
    m = synthetic(units=units, rate=100.0)
    for ext in (".c3d", ".trc"):
        write(m, tmp_path / f"u{ext}")
        assert read(tmp_path / f"u{ext}").units == units


@pytest.mark.parametrize(("to", "scale", "decimals"),
                         [("m", 1e-3, 5), ("cm", 0.1, 3), ("in", 1 / 25.4, 4), ("mm", 1, 2)])
def test_trc_header_says_the_units_the_positions_are_in(tmp_path, to, scale, decimals):
    # A TRC read in mm with 2 decimals (10 um), rescaled and written again: the header's
    # stale "mm" would make every length wrong by the scale. The resolution is kept:
    # 0.01 mm is 0.00001 m (5 decimals), 0.001 cm (3), 0.0004 in (4: 0.0001 in < 0.01 mm).
    import dataclasses
    m = synthetic(units="mm")
    m = dataclasses.replace(m, positions=np.round(m.positions, 2),
                            metadata={"trc.Units": "mm", "trc.Decimals": "2"})
    rescaled = dataclasses.replace(m, positions=m.positions * scale, units=to)
    write(rescaled, tmp_path / "r.trc")
    back = read(tmp_path / "r.trc")
    assert back.units == to
    assert back.metadata["trc.Decimals"] == str(decimals)
    np.testing.assert_allclose(back.positions[m.valid] / scale, m.positions[m.valid],
                               rtol=0, atol=0.005 + 1e-9)


def test_c3d_written_by_ezc3d_reads_the_same_with_the_numpy_reader(tmp_path):
    m = synthetic()
    write(m, tmp_path / "m.c3d")
    d = c3dbin.parse_c3d((tmp_path / "m.c3d").read_bytes())
    assert d.processor == c3dbin.PROC_INTEL and d.float_storage
    assert d.points.shape == (m.n_frames, m.n_markers, 3)
    np.testing.assert_array_equal(d.residual_words < 0, ~m.valid)
    np.testing.assert_array_equal(d.points[m.valid], m.positions[m.valid].astype(np.float32))
    assert d.params["POINT"]["LABELS"] == m.names
    assert float(d.params["POINT"]["RATE"][0]) == DANCE_RATE


def test_uppercase_c3d_extension(tmp_path):
    m = synthetic(rate=120.0)
    write(m, tmp_path / "UP.C3D")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["UP.C3D"]
    assert read(tmp_path / "UP.C3D").names == m.names


def test_csv_layout(tmp_path):
    m = Motion(np.array([[[1.0, 2.0, 3.0], [np.nan] * 3]]), ["A", "B"], rate=2.0)
    write(m, tmp_path / "a.csv")
    lines = (tmp_path / "a.csv").read_text().splitlines()
    assert lines == ["frame,time,A_x,A_y,A_z,B_x,B_y,B_z", "0,0.0,1.0,2.0,3.0,,,"]


def _npy_bytes(header: str, data: bytes) -> bytes:
    """An .npy 1.0 file written by hand: magic, header length, header padded to 64."""
    text = header + " " * (-(10 + len(header) + 1) % 64) + "\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(text)) + text.encode() + data


@pytest.mark.parametrize("header,rows,match", [
    ("{'descr': '<f8', 'fortran_order': False, 'shape': (2, 1, 3)", 2, "not a valid .npy"),
    ("{'descr': '<f8', 'fortran_order': False, 'shape': (1000000000000, 41, 3), }", 2,
     r"declares \(1000000000000, 41, 3\)"),
    ("{'descr': '<f8', 'fortran_order': False, 'shape': (1, 1, 3), }", 2, "holds 48 after"),
    ("{'descr': '<f8', 'fortran_order': False, 'shape': (-1, 1, 3), }", 2, "negative"),
    ("{'descr': '|O', 'fortran_order': False, 'shape': (2, 1, 3), }", 2, "Python objects"),
])
def test_npy_header_is_checked_against_the_file_before_loading(tmp_path, header, rows, match):
    """A header that does not parse (numpy raised tokenize.TokenError: a traceback), or
    whose shape does not fill the bytes after it: a 2 KB file declaring 10^12 frames made
    numpy allocate (exit 3), one declaring 1 frame over 2 read 1 silently."""
    p = tmp_path / "h.npy"
    p.write_bytes(_npy_bytes(header, np.arange(rows * 3, dtype="<f8").tobytes()))
    with pytest.raises(InputFormatError, match=match):
        read(p)
    p.write_bytes(_npy_bytes("{'descr': '<f8', 'fortran_order': False, 'shape': (2, 1, 3), }",
                             np.arange(6, dtype="<f8").tobytes()))
    assert read(p).positions.tolist() == [[[0, 1, 2]], [[3, 4, 5]]]     # the same writer


def test_npy_layout(tmp_path):
    m = synthetic()
    write(m, tmp_path / "a.npy")
    arr = np.load(tmp_path / "a.npy")
    assert arr.dtype == np.float64 and arr.shape == (7, 5, 3)
    assert np.isnan(arr[0, 1]).all() and np.isfinite(arr[0, 0]).all()


@pytest.mark.parametrize("rate", [DANCE_RATE, 120.0, 60.00328826904297, 1 / 3, 29.97])
def test_rate_from_times_is_exact(rate):
    t = np.array([repr(f / rate) for f in range(50)], dtype=float)
    assert rate_from_times(t) == rate


# -- TRC -------------------------------------------------------------------

TRC_TEXT = (
    "PathFileType\t4\t(X/Y/Z)\tx.trc\n"
    "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n"
    "60.00\t60.00\t3\t2\tm\t60.00\t1\t3\n"
    "Frame#\tTime\tA\t\t\tB\t\t\n"
    "\t\tX1\tY1\tZ1\tX2\tY2\tZ2\n"
    "\n"
    "1\t0.000\t1\t2\t3\t4\t5\t6\n"
    "2\t0.017\t1.5\t2\t3\t\t\t\n"
    "3\t0.033\tNaN\tNaN\tNaN\t7\t8\t9\n"
)


def test_trc_parse(tmp_path):
    p = tmp_path / "x.trc"
    p.write_text(TRC_TEXT)
    m = read(p)
    assert (m.n_frames, m.n_markers, m.rate, m.units, m.names) == (3, 2, 60.0, "m", ["A", "B"])
    assert m.valid.tolist() == [[True, True], [True, False], [False, True]]
    assert m.positions[1, 0].tolist() == [1.5, 2.0, 3.0]
    assert m.positions[2, 1].tolist() == [7.0, 8.0, 9.0]


@pytest.mark.parametrize("cut", [
    lambda t: t.split("\n", 2)[0],                       # header only
    lambda t: "\n".join(t.split("\n")[:6]),              # no data rows
    lambda t: t.replace("DataRate", "Rate"),             # no DataRate
    lambda t: t.replace("\t2\tm\t", "\t5\tm\t"),         # NumMarkers disagrees
    lambda t: t.replace("1.5\t2", "1.5\tabc"),           # non-numeric value
    lambda t: t.replace("7\t8\t9", "7\t8\t9\t10\t11\t12"),  # row too long
    lambda t: "X" + t,                                  # not a TRC
    # what Python's float() takes and a QA run found read silently: 1000, 12, gaps
    lambda t: t.replace("1.5\t2", "1.5\t1_000"),
    lambda t: t.replace("1.5\t2", "1.5\t\u0661\u0662"),         # Arabic-Indic 12
    lambda t: t.replace("1.5\t2", "1.5\t\uff11\uff12"),         # full-width 12
    lambda t: t.replace("1.5\t2", "1.5\tinf"),
    lambda t: t.replace("1.5\t2", "1.5\t1e400"),
    lambda t: t.replace("1.5\t2", "1.5\t\u00a0"),                # a no-break space
])
def test_trc_bad(tmp_path, cut):
    p = tmp_path / "bad.trc"
    p.write_text(cut(TRC_TEXT))
    with pytest.raises(InputFormatError) as ei:
        read(p)
    assert ei.value.path == str(p)



@pytest.mark.parametrize("edit, said", [
    (lambda t: t.replace("\t", " "), "line 2 is separated by spaces, not tabs"),
    (lambda t: t.replace("60.00\t60.00\t3", "0\t60.00\t3"),
     "DataRate '0' is not a frame rate: it must be a positive number"),
    (lambda t: t.replace("60.00\t60.00\t3", "-60\t60.00\t3"),
     "DataRate '-60' is not a frame rate"),
])
def test_a_trc_header_refusal_names_what_is_wrong(edit, said):
    """A QA run of exporters: a TRC written with spaces said "header has no DataRate" of a
    header that has one, and a DataRate of 0 "inconsistent data: frame rate must be finite
    and positive", naming no field."""
    from mpz.io.trc import parse_trc
    with pytest.raises(InputFormatError, match=re.escape(said)):
        parse_trc(edit(TRC_TEXT))


@pytest.mark.parametrize("blank", ["", "\n"])
def test_trc_without_its_coordinate_label_row_is_refused(blank):
    """A QA run of exporters: a TRC without the X1 Y1 Z1 row (line 5 a data row) was read
    with its first frame taken for the labels and dropped; only NumFrames, where present,
    disagreed in a warning. Without NumFrames nothing was said at all."""
    from mpz.io.trc import parse_trc
    rows = TRC_TEXT.split("\n")
    text = "\n".join(rows[:4] + ([""] if blank else []) + rows[6:])
    if blank:                                       # line 5 blank: no labels, as before
        with pytest.raises(InputFormatError, match="coordinate row has 0 labels"):
            parse_trc(text)
        return
    with pytest.raises(InputFormatError, match="line 5 must be the coordinate labels"):
        parse_trc(text)
    no_count = text.replace("NumFrames\t", "").replace("60.00\t3\t", "60.00\t")
    with pytest.raises(InputFormatError, match="line 5 must be the coordinate labels"):
        parse_trc(no_count)
    assert parse_trc(TRC_TEXT).n_frames == 3

def _through_mpz(source, out):
    """``source`` read, encoded, decoded and written to ``out``: the notes of the write."""
    import mpz
    return write(mpz.decode(mpz.encode(read(source), max_error=1.0)), out)


def _trc_with_ends(ends):
    """TRC_TEXT with header lines 1-5 ended by ``ends`` (the tabs after each line's last
    field) instead of the ends this package's writer gives them (0, 0, 0, 2, 0)."""
    lines = TRC_TEXT.split("\n")
    return "\n".join([row.rstrip("\t") + end
                      for row, end in zip(lines[:5], ends, strict=True)] + lines[5:])


@pytest.mark.parametrize("ends", [
    ("", "", "", "\t\t\t", "\t"),           # OpenSim's and BTK's: a tab closes lines 4-5
    ("", "", "", "", ""),                   # nothing after the last name, B
    ("\t" * 9, "\t" * 5, "\t" * 5, "\t\t", ""),  # lines 1-3 padded (another OpenSim file)
    ("", "", "", "\t\t", "\t"),             # line 5 alone differs from the writer's ends
], ids=["lines-4-5-end-with-a-tab", "no-tabs", "lines-1-3-padded", "line-5-alone"])
def test_trc_header_lines_end_as_the_source_ends_them(tmp_path, ends):
    """The written TRC dropped the tab that ends lines 4 and 5 of the OpenSim and BTK files
    (the last name and three tabs came back with two, Z41 and a tab as Z41) and the tabs
    that pad lines 1-3 of an OpenSim file: no field, but not what the source holds. Through
    read, encode, decode and write, the five header lines come back byte for byte, and
    nothing is said."""
    text = _trc_with_ends(ends)
    (tmp_path / "x.trc").write_text(text)
    notes = _through_mpz(tmp_path / "x.trc", tmp_path / "back.trc")
    back = (tmp_path / "back.trc").read_text()
    assert back.split("\n")[:5] == text.split("\n")[:5]
    assert not any("TrailingTabs" in n for n in notes), notes


def test_trc_header_tabs_before_a_trailing_blank_are_kept(tmp_path):
    """A line 4 ending "B<tab><tab><tab> " was counted as ending in no tab and came back as
    "B", where the writer's own ends give "B<tab><tab>": the tabs are kept, the blank after
    them (a whitespace-only field) is not."""
    from mpz.io.trc import parse_trc
    text = _trc_with_ends(("", "", "", "\t\t\t ", ""))
    assert parse_trc(text).metadata["trc.TrailingTabs"] == "0 0 0 3 0"
    (tmp_path / "x.trc").write_text(text)
    _through_mpz(tmp_path / "x.trc", tmp_path / "back.trc")
    line = (tmp_path / "back.trc").read_text().split("\n")[3]
    assert line == text.split("\n")[3][:-1], repr(line)


def test_trc_header_tab_runs_inside_a_line_are_read_in_linear_time():
    """A regex that counted a line's last tabs backtracked over every run of tabs inside
    it: 40,000 tabs took 27 s (a self-review of stop 59), a hostile header line hours.
    A line of 2^21 inner tabs, in its own process: the old code did not return (days), so
    the generous timeout guards a hang, it times nothing."""
    import subprocess
    import sys

    from mpz.io.trc import _tabs_at_end
    assert _tabs_at_end("a\t\t \t\t\x0c ") == 2 and _tabs_at_end("a\t\tx") == 0
    code = ("from mpz.io.trc import _tabs_at_end; "
            "print(_tabs_at_end('a' + chr(9) * (1 << 21) + 'x'))")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 0 and p.stdout.strip() == "0", p.stderr


def test_trc_header_lines_the_writer_ends_so_anyway_add_no_metadata():
    """A TRC whose header lines end as the writer ends them gets no trc.TrailingTabs: its
    meta chunk, and so its MPZ file, is what it was before the key was kept."""
    from mpz.io.trc import parse_trc
    assert "trc.TrailingTabs" not in parse_trc(TRC_TEXT).metadata
    assert parse_trc(_trc_with_ends(("", "", "", "\t\t\t", "\t"))).metadata[
        "trc.TrailingTabs"] == "0 0 0 3 1"


@pytest.mark.parametrize("value", ["3 1", "0 0 0 3 1 0", "0 0 0 x 1", "0 0 0 -1 1",
                                   "0 0 0 3.0 1", "0  0 0 3 1", "0 0 0 3 1 ",
                                   "0 0 0 1048577 1", "0 0 0 " + "9" * 13 + " 1", "",
                                   # a doubled sign crashed the writer (exit 70), and a
                                   # sign, a leading zero or a no-break space passed
                                   "+-1 0 0 0 0", "--0 0 0 3 1", "+1 0 0 3 1", "-0 0 0 3 1",
                                   "0 0 0 0003 1", "0\u00a0 0 0 3 1", "\u0663 0 0 3 1"])
def test_trc_hand_edited_trailing_tabs_are_said_and_not_used(tmp_path, value):
    """trc.TrailingTabs is free text in the meta chunk: a value that is not five whole
    numbers 0 .. 2^20 (a hand edit) is named in a note, and the header lines are written
    as without it; a terabyte of tabs is not asked for."""
    from mpz.io.trc import parse_trc, trc_meta_problems
    m = parse_trc(_trc_with_ends(("", "", "", "\t\t\t", "\t")))
    m.metadata["trc.TrailingTabs"] = value
    assert "trc.TrailingTabs" in trc_meta_problems(m.metadata)
    notes = write(m, tmp_path / "back.trc")
    assert any(n.startswith("metadata trc.TrailingTabs ") for n in notes), notes
    assert (tmp_path / "back.trc").read_text().split("\n")[:5] == TRC_TEXT.split("\n")[:5]


def test_trc_header_line_of_more_tabs_than_are_kept_is_said():
    """A header line that ends with more than 2^20 tabs keeps 2^20, with a warning."""
    from mpz.io.trc import MAX_TRAILING_TABS, format_trc, parse_trc
    m = parse_trc(_trc_with_ends(("", "", "", "\t" * (MAX_TRAILING_TABS + 5), "")))
    assert m.metadata["trc.TrailingTabs"] == f"0 0 0 {MAX_TRAILING_TABS} 0"
    assert (f"header line 4 ends with {MAX_TRAILING_TABS + 5} tabs: {MAX_TRAILING_TABS} are "
            "written back") in m.metadata["warning"]
    line = format_trc(m).split("\n")[3]
    assert len(line) - len(line.rstrip("\t")) == MAX_TRAILING_TABS
    # exactly 2^20 are kept without a word
    m = parse_trc(_trc_with_ends(("", "", "", "\t" * MAX_TRAILING_TABS, "")))
    assert m.metadata["trc.TrailingTabs"] == f"0 0 0 {MAX_TRAILING_TABS} 0"
    assert "warning" not in m.metadata


def test_trc_too_many_tabs_keeps_the_other_warnings():
    """The warning of a header line past 2^20 tabs is added to the reader's others (an
    edited time here), not put in their place."""
    from mpz.io.trc import MAX_TRAILING_TABS, parse_trc
    lines = _trc_with_ends(("", "", "", "\t" * (MAX_TRAILING_TABS + 1), "")).split("\n")
    cells = lines[6].split("\t")
    cells[1] = str(float(cells[1]) + 0.5)             # a time that is not frame / rate
    lines[6] = "\t".join(cells)
    warning = parse_trc("\n".join(lines)).metadata["warning"]
    assert f"header line 4 ends with {MAX_TRAILING_TABS + 1} tabs" in warning, warning
    assert "time" in warning.split("header line 4")[0], warning

# -- BVH -------------------------------------------------------------------

BVH_TEXT = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Chest
  {
    OFFSET 0 10 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 5 0
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.0333333
1 2 3 0 0 0 0 0 0
0 0 0 90 0 0 0 0 0
0 0 0 0 0 0 90 90 0
"""


def test_bvh_forward_kinematics(tmp_path):
    p = tmp_path / "t.bvh"
    p.write_text(BVH_TEXT)
    m = read_bvh(p)
    assert m.names == ["Hips", "Chest", "Chest_End"]
    assert m.parents == [-1, 0, 1]
    assert m.rate == 30.0 and m.units == ""
    assert m.angles.shape == (3, 9)
    assert m.angle_names[:4] == ["Hips.Xposition", "Hips.Yposition", "Hips.Zposition",
                                 "Hips.Zrotation"]
    # frame 0: translation only
    np.testing.assert_allclose(m.positions[0], [[1, 2, 3], [1, 12, 3], [1, 17, 3]], atol=1e-12)
    # frame 1: Rz(90) at the root maps +y to -x
    np.testing.assert_allclose(m.positions[1], [[0, 0, 0], [-10, 0, 0], [-15, 0, 0]], atol=1e-12)
    # frame 2: chest Rz(90) @ Rx(90): (0,5,0) -Rx-> (0,0,5) -Rz-> (0,0,5)
    # (the other order would give (-5,0,0))
    np.testing.assert_allclose(m.positions[2, 2], [0, 10, 5], atol=1e-12)


@pytest.mark.parametrize("ft,rate", [(0.0083333, 120.0), (0.00833333, 120.0), (0.04, 25.0),
                                     (0.0333333, 30.0), (1 / 65.0364227, 65.0364227),
                                     # below 1 Hz nothing snaps: 1/1500 Hz was snapped to 0
                                     # and the file refused (a QA run of stop 54)
                                     (1500.0, 1 / 1500), (999.0, 1 / 999), (2.0, 0.5),
                                     (2.0 ** 31, 2.0 ** -31)])
def test_bvh_frame_rate(ft, rate):
    assert frame_rate_from_frame_time(ft) == pytest.approx(rate, rel=1e-12)


@pytest.mark.parametrize("written,rate", [
    # Blender's and MotionBuilder's exporters print the Frame Time with 6 decimals: 120 fps
    # read as 120.0048 Hz, 60 fps as 59.9988 Hz, 240 fps as 239.98 Hz (a QA run of BVH
    # exporters); a frame time that rounds to no single integer's stays 1 / Frame Time
    ("0.008333", 120.0), ("0.016667", 60.0), ("0.004167", 240.0), ("0.041667", 24.0),
    ("0.0333", 30.0), ("8.3333e-03", 120.0), ("0.033367", 1 / 0.033367),
    ("0.03", 1 / 0.03), ("1500", 1 / 1500), ("0.0083333", 120.0)])
def test_bvh_frame_rate_from_the_frame_time_as_printed(written, rate):
    from mpz.io.bvh import parse_bvh
    m = parse_bvh(BVH_TEXT.replace("Frame Time: 0.0333333", f"Frame Time: {written}"))
    assert m.rate == pytest.approx(rate, rel=1e-12)
    assert m.extras["skeleton"].frame_time == float(written)     # written back as read


def test_an_mpz_of_the_old_bvh_rate_still_compares_with_its_source(tmp_path):
    """Before the rate fix, 0.008333 read as 120.0048 Hz, which an .mpz encoded then keeps:
    compared with its source, now read at 120 Hz, it was refused ("frame rates differ",
    exit 2). One BVH Frame Time is one rate: compared, with a note; another Frame Time
    at the same rates is still refused."""
    import dataclasses
    import subprocess
    import sys

    import mpz
    src = tmp_path / "b.bvh"
    src.write_text(BVH_TEXT.replace("Frame Time: 0.0333333", "Frame Time: 0.008333"))
    m = mpz.io.read(src)
    assert m.rate == 120.0
    old = dataclasses.replace(m, rate=1 / 0.008333)            # what the old reader gave
    (tmp_path / "old.mpz").write_bytes(mpz.encode(old))
    assert mpz.max_error(m, mpz.decode(tmp_path / "old.mpz")) < 1.0
    cmd = [sys.executable, "-m", "mpz.tools.mpz_cli", "compare", "b.bvh", "old.mpz"]
    p = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert "one BVH Frame Time (0.008333 s) rounded two ways" in p.stdout + p.stderr
    other = dataclasses.replace(old, metadata={**old.metadata, "frame_time": "0.0083330001"})
    (tmp_path / "other.mpz").write_bytes(mpz.encode(other))
    with pytest.raises(MotionError, match="frame rates differ"):
        mpz.max_error(m, mpz.decode(tmp_path / "other.mpz"))
    p = subprocess.run(cmd[:-1] + ["other.mpz"], cwd=tmp_path, capture_output=True,
                       text=True, timeout=300)
    assert p.returncode == 2 and "frame rates differ" in p.stderr, p.stderr


@pytest.mark.parametrize("mutate", [
    lambda t: t.replace("Frames: 3", "Frames: 4"),          # truncated motion
    lambda t: t.replace("90 90 0\n", "90 90\n"),            # short last row
    lambda t: t.replace("  }\n}\n", "  }\n"),               # unbalanced braces
    lambda t: t.replace("Zrotation Xrotation Yrotation", "Zrotation Xrotation Wrotation"),
    lambda t: t.replace("OFFSET 0 10 0", "OFFSET 0 ten 0"),
    # refused at reading, not by the encoder in terms of an asfs/bvhs chunk (a QA run)
    lambda t: t.replace("OFFSET 0 10 0", "OFFSET 0 nan 0"),
    lambda t: t.replace("0 0 0 90 0 0 0 0 0", "0 0 0 9_0 0 0 0 0 0"),
    lambda t: t.replace("Frame Time: 0.0333333", "Frame Time: 5e-324"),   # 1/ft overflows
    lambda t: t.replace("CHANNELS 3 Zrotation Xrotation Yrotation",      # two CHANNELS:
                        "CHANNELS 3 Zrotation Xrotation Yrotation\n    CHANNELS 1 Xrotation"),
    lambda t: t.replace("CHANNELS 3 Zrotation Xrotation Yrotation",
                        "CHANNELS 3 Zrotation Xrotation Zrotation"),
    lambda t: t.replace("0 0 0 90 0 0 0 0 0", "0 0 0 \uff19\uff10 0 0 0 0 0"),
    lambda t: t.replace("JOINT Chest", "JOINT Ch\x00est"),
    lambda t: t.replace("MOTION", "MOTON"),
    lambda t: t.split("MOTION")[0],
    lambda t: "",
])
def test_bvh_bad(tmp_path, mutate):
    p = tmp_path / "bad.bvh"
    p.write_text(mutate(BVH_TEXT))
    with pytest.raises(InputFormatError):
        read(p)


# -- ASF/AMC -------------------------------------------------------------------

ASF_TEXT = """# tiny skeleton
:version 1.10
:name TINY
:units
  mass 1.0
  length 0.45
  angle deg
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name b1
     direction 1 0 0
     length 2
     axis 0 0 90 XYZ
    dof rx rz
    limits (-180 180)
           (-180 180)
  end
  begin
     id 2
     name b2
     direction 0 1 0
     length 1
     axis 0 0 0 XYZ
    dof rx
    limits (-180 180)
  end
:hierarchy
  begin
    root b1
    b1 b2
  end
"""

AMC_TEXT = """# comment with a latin-1 byte: \xe4
:FULLY-SPECIFIED
:DEGREES
1
root 1 2 3 0 0 0
b1 0 90
b2 0
2
root 0 0 0 0 0 0
b1 90 0
b2 0
"""


def test_amc_forward_kinematics(tmp_path):
    (tmp_path / "tiny.asf").write_text(ASF_TEXT)
    (tmp_path / "tiny_01.amc").write_bytes(AMC_TEXT.encode("latin-1"))
    m = read(tmp_path / "tiny_01.amc")  # finds tiny.asf
    mm = 25.4 / 0.45  # one ASF unit is 1/0.45 inch
    assert m.names == ["root", "b1", "b2"] and m.parents == [-1, 0, 1]
    assert m.rate == 120.0 and m.units == "mm"
    assert m.angles.shape == (2, 6 + 2 + 1)
    assert m.angle_names == ["root.tx", "root.ty", "root.tz", "root.rx", "root.ry", "root.rz",
                             "b1.rx", "b1.rz", "b2.rx"]
    # frame 1: C = Rz90, M = Rz90 -> W = Rz90; b1 end = (1,2,3) + Rz90 (2,0,0) = (1,4,3);
    # b2 inherits W: (1,4,3) + Rz90 (0,1,0) = (0,4,3)
    np.testing.assert_allclose(m.positions[0] / mm, [[1, 2, 3], [1, 4, 3], [0, 4, 3]], atol=1e-12)
    # frame 2: rx=90 about the bone's local x, which C = Rz90 puts on global y:
    # W = Rz90 Rx90 Rz-90 is Ry(90); (2,0,0) -> (0,0,-2); b2: (0,1,0) stays (0,1,0)
    np.testing.assert_allclose(m.positions[1] / mm, [[0, 0, 0], [0, 0, -2], [0, 1, -2]], atol=1e-12)
    m2 = read(tmp_path / "tiny_01.amc", rate=60.0)
    assert m2.rate == 60.0


@pytest.mark.parametrize("asf_unit, amc_flag, warned", [
    ("deg", ":DEGREES", False), ("deg", ":RADIANS", True), ("rad", ":RADIANS", False),
    ("rad", ":DEGREES", True), ("deg", "", False), ("rad", "", False),
    ("deg", ":radians  # lower case, with a comment", True), (None, ":RADIANS", True),
])
def test_amc_angle_flag_against_asf_units(tmp_path, asf_unit, amc_flag, warned):
    """An AMC's :DEGREES/:RADIANS line that contradicts the ASF's :units angle is said in the
    motion's warning; the values are read in the ASF's unit either way, and the header kept."""
    (tmp_path / "tiny.asf").write_text(ASF_TEXT.replace(
        "  angle deg\n", "" if asf_unit is None else f"  angle {asf_unit}\n"))
    asf_unit = asf_unit or "deg"                   # an ASF without :units angle: degrees
    (tmp_path / "tiny_01.amc").write_bytes(
        AMC_TEXT.replace(":DEGREES", amc_flag).encode("latin-1"))
    m = read(tmp_path / "tiny_01.amc")
    warning = m.metadata.get("warning", "")
    assert (f"its ASF's angles are in {asf_unit}" in warning) is warned
    assert (bool(amc_flag) and amc_flag[:9].upper() in warning) is warned
    assert m.extras["skeleton"].angle_unit == asf_unit
    assert not amc_flag or amc_flag in m.extras["skeleton"].amc_header.splitlines()


def test_find_asf_longest_prefix(tmp_path):
    for n in ("HDM.asf", "HDM_dg.asf", "HDM_mm.asf", "02.asf", "0.asf"):
        (tmp_path / n).write_text("")
    assert find_asf(tmp_path / "HDM_dg_06-03_03_120.amc").endswith("HDM_dg.asf")
    assert find_asf(tmp_path / "02_01.amc").endswith("02.asf")
    with pytest.raises(InputFormatError):
        find_asf(tmp_path / "17_01.amc")


def test_find_asf_refuses_two_skeletons_that_fit_alike(tmp_path):
    """A corpus QA run: beside 02.asf and 02.ASF, whichever sorted last was taken without a
    word (the wrong skeleton there). Two that differ are refused, naming both; two copies
    of one file are not a choice."""
    (tmp_path / "02.asf").write_text(":name a\n")
    (tmp_path / "02.ASF").write_text(":name b\n")
    with pytest.raises(InputFormatError, match=r"2 skeletons fit 02_01.amc: 02.ASF, 02.asf "
                                               r"differ; name one with asf="):
        find_asf(tmp_path / "02_01.amc")
    (tmp_path / "02.ASF").write_text(":name a\n")
    assert find_asf(tmp_path / "02_01.amc").endswith("02.asf")
    (tmp_path / "0.asf").write_text(":name c\n")          # a shorter stem is no rival
    assert find_asf(tmp_path / "02_01.amc").endswith("02.asf")


@pytest.mark.parametrize("mutate", [
    lambda t: t.replace("b1 90 0", "b1 90"),          # value count
    lambda t: t.replace("b2 0\n2", "bx 0\n2"),        # unknown bone
    lambda t: t.replace("\n2\n", "\n3\n"),            # frame numbering
    lambda t: t.replace("b1 0 90\n", ""),             # bone missing in a frame
    lambda t: ":FULLY-SPECIFIED\n",                   # no frames
    lambda t: t.replace("root 1 2 3", "root 1 two 3"),
    lambda t: t.replace("root 1 2 3", "root 1 2_0 3"),
    lambda t: t.replace("root 1 2 3", "root 1 \uff12 3"),
    lambda t: t.replace("root 1 2 3", "root 1 inf 3"),
])
def test_amc_bad(tmp_path, mutate):
    (tmp_path / "tiny.asf").write_text(ASF_TEXT)
    (tmp_path / "tiny_01.amc").write_text(mutate(AMC_TEXT))
    with pytest.raises(InputFormatError):
        read_amc(tmp_path / "tiny_01.amc", tmp_path / "tiny.asf")


def test_commas_are_white_space_in_asf_and_amc(tmp_path):
    """The Acclaim ASF definition (V1.10) reads commas as white space; ``direction 1, 0, 0``,
    ``limits (-180, 180)`` and an AMC line ``b1 0, 90`` were refused ("'1,' is not a number":
    an archive QA run). They read as without the commas; the text fields keep theirs."""
    (tmp_path / "plain.asf").write_text(ASF_TEXT)
    (tmp_path / "plain_01.amc").write_bytes(AMC_TEXT.encode("latin-1"))
    (tmp_path / "comma.asf").write_text(
        ASF_TEXT.replace("direction 1 0 0", "direction 1, 0, 0")
        .replace("limits (-180 180)\n           (-180 180)", "limits (-180, 180), (-180,180)")
        .replace("position 0 0 0", "position 0,0,0").replace("root b1", "root, b1")
        .replace(":name TINY", ":name TINY, v2"))
    (tmp_path / "comma_01.amc").write_bytes(
        AMC_TEXT.replace("b1 0 90", "b1 0, 90").replace("root 1 2 3 0 0 0", "root 1,2,3,0,0,0")
        .encode("latin-1"))
    a, b = read(tmp_path / "plain_01.amc"), read(tmp_path / "comma_01.amc")
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.angles, b.angles)
    sa, sb = a.extras["skeleton"], b.extras["skeleton"]
    assert sa.joints == sb.joints and sb.name == "TINY, v2"


@pytest.mark.parametrize("old, new, said", [
    ("name b2", "name b1", "bone name 'b1' is given to the bones of blocks 1, 2 of :bonedata"),
    ("name b2", "name root", "bone name 'root' is given to the bone of block 2 of :bonedata"),
    ("     name b2\n", "", "the bone of block 2 of :bonedata (counted from 1, begin ... end) "
                           "has no name"),
])
def test_an_asf_bone_name_refusal_says_which_bone(old, new, said):
    """"bone names must be unique and not 'root'" and "bone without a name" named no bone
    and no place, in a skeleton of 30 (a fuzzing QA run of the text readers): the name and
    the :bonedata blocks are said."""
    assert ASF_TEXT.count(old) == 1
    with pytest.raises(InputFormatError, match=re.escape(f"ASF/AMC: {said}")):
        parse_asf(ASF_TEXT.replace(old, new))


@pytest.mark.parametrize("after", ["   axis XYZ\n", "  begin\n     id 2\n", "    b1 b2\n"],
                         ids=[":root", ":bonedata", ":hierarchy"])
def test_an_asf_line_of_commas_alone_is_a_blank_line(tmp_path, after):
    """Commas are white space in an ASF (V1.10), so a line of them alone is blank: in
    :root, :bonedata or :hierarchy it raised an IndexError out of mpz.io.read (its first
    word, of none: a fuzzing QA run of the text readers). A text field keeps it."""
    (tmp_path / "plain.asf").write_text(ASF_TEXT)
    (tmp_path / "plain_01.amc").write_bytes(AMC_TEXT.encode("latin-1"))
    assert ASF_TEXT.count(after) == 1
    (tmp_path / "comma.asf").write_text(
        ASF_TEXT.replace(after, after + " , ,\n").replace(":name TINY", ":documentation\n,\n"
                                                                      ":name TINY"))
    (tmp_path / "comma_01.amc").write_bytes(AMC_TEXT.encode("latin-1"))
    a, b = read(tmp_path / "plain_01.amc"), read(tmp_path / "comma_01.amc")
    np.testing.assert_array_equal(a.positions, b.positions)
    assert a.extras["skeleton"].joints == b.extras["skeleton"].joints
    assert b.extras["skeleton"].documentation == ","


@pytest.mark.parametrize("mutate, said", [
    (lambda t: t.replace("b1 90 0\n", ""),
     r"frame 2 \(from line 8, the last frame\) has no line for b1: .*may be cut short"),
    (lambda t: t.replace("b1 0 90\n", ""), r"frame 1 \(from line 4\) has no line for b1: every"),
    (lambda t: t.replace("\n1\n", "\n-1\n").replace("\n2\n", "\n0\n"),
     "line 4: frame number -1: negative frame numbers are not supported"),
])
def test_an_amc_refusal_names_the_frame(tmp_path, mutate, said):
    """A frame without a bone's line was "frame ending at line end lacks [...]" (a file cut
    short) or named the next frame's line; a negative frame number was "data before the first
    frame number" (an archive QA run)."""
    (tmp_path / "tiny.asf").write_text(ASF_TEXT)
    (tmp_path / "tiny_01.amc").write_text(mutate(AMC_TEXT))
    with pytest.raises(InputFormatError, match=said):
        read_amc(tmp_path / "tiny_01.amc", tmp_path / "tiny.asf")


@pytest.mark.parametrize("mutate", [
    lambda t: t.replace("    b1 b2\n", ""),                # b2 not in hierarchy
    lambda t: t.replace(":hierarchy", ":hierarchyx"),
    lambda t: t.replace("dof rx\n", "dof qq\n"),
    lambda t: t.replace("root b1", "root bz"),
    lambda t: t.replace("length 0.45", "length 0"),
    lambda t: t.replace("length 0.45", "length 1e-320"),   # 25.4 / length overflows: it
    lambda t: t.replace("axis 0 0 90 XYZ", "axis 0 0 9_0 XYZ"),
    # reached the encoder as NaN; NaN here reached it as a chunk error; a second parent
    # silently replaced the first
    lambda t: t.replace("axis 0 0 90 XYZ", "axis 0 nan 90 XYZ"),
    lambda t: t.replace("direction 0 1 0", "direction 0 inf 0"),
    lambda t: t.replace("position 0 0 0", "position nan 0 0"),
    lambda t: t.replace("    b1 b2\n", "    b1 b2\n    root b2\n"),
    lambda t: t.replace("  angle deg\n", "  angle\n"),      # was "cannot read: IndexError"
    lambda t: t.replace("  angle deg\n", "  angle grad\n"),
])
def test_asf_bad(mutate):
    with pytest.raises(InputFormatError):
        parse_asf(mutate(ASF_TEXT))


_TRC_HEAD = "60.00\t60.00\t3\t2\tm\t60.00\t1\t3\n"


@pytest.mark.parametrize("fmt,mutate,match", [
    # Python's int() and float() took these: read silently as 1000, 120, 40, 6, 0.45
    ("trc", lambda t: t.replace(_TRC_HEAD, _TRC_HEAD.replace("60.00", "6_0.00", 1)),
     "DataRate: '6_0.00' is not a plain"),
    ("trc", lambda t: t.replace(_TRC_HEAD, "\uff16\uff10" + _TRC_HEAD[5:]),
     "DataRate: '\uff16\uff10' is not a plain"),
    ("bvh", lambda t: t.replace("Frames: 3", "Frames: \u0663"), "MOTION header: '\u0663'"),
    ("bvh", lambda t: t.replace("CHANNELS 3", "CHANNELS 0_3"),
     "CHANNELS of joint 'Chest': '0_3' is not a whole number"),
    ("asf", lambda t: t.replace("length 0.45", "length 0_45"), ":units length: '0_45'"),
    ("amc", lambda t: t.replace("\n2\n", "\n\u0662\n"), "unknown bone '\u0662'"),
    # were "cannot read: ValueError ..." (or OverflowError, IndexError) from Python's int()
    ("trc", lambda t: t.replace(_TRC_HEAD, "\t" + _TRC_HEAD[5:]), "DataRate: '' is not"),
    ("trc", lambda t: t.replace(_TRC_HEAD, _TRC_HEAD.replace("\t3\t2\t", "\tinf\t2\t")),
     "NumFrames: 'inf' is not a finite"),
    ("trc", lambda t: t.replace(_TRC_HEAD, _TRC_HEAD.replace("\t3\t2\t", "\t3\tnan\t")),
     "NumMarkers: 'nan' is not a finite"),
    ("trc", lambda t: t.replace(_TRC_HEAD, _TRC_HEAD.replace("\t3\t2\t", "\t3\t1.5\t")),
     "NumMarkers: '1.5' is not a count"),
    ("bvh", lambda t: t.replace("Frames: 3", "Frames: 3.0"), "MOTION header: '3.0'"),
    ("bvh", lambda t: t.replace("0 0 0 90 0 0", "0 0 0 0x10 0 0"), "MOTION: '0x10' is not"),
    ("bvh", lambda t: t.replace("0 0 0 90 0 0", "0 0 0 9-0 0 0"), "MOTION: '9-0' is not"),
    ("asf", lambda t: t.replace("id 2", "id 2.5"), "id of bone 'b2': '2.5'"),
    ("asf", lambda t: t.replace("length 1\n", "length\n"), "bone 'b2' has no length"),
    ("asf", lambda t: t.replace("length 0.45", "length"), ":units length: '' is not"),
    ("asf", lambda t: t.replace("limits (-180 180)\n  end", "limits (-1.0.0 180)\n  end"),
     "bad limits of b2: '-1.0.0' is not"),
])
def test_header_fields_are_plain_numbers_and_errors_name_them(tmp_path, fmt, mutate, match):
    """A hostile-input QA (stop 33): header counts and numbers read by Python's int() and
    float() took '1_000' and other scripts' digits silently, and reported malformed ones
    as the reader's 'cannot read: ValueError'. Now each is read as the data are
    (:func:`mpz.io._common.number`, :func:`~mpz.io._common.integer`) and an error names
    the field."""
    text = {"trc": TRC_TEXT, "bvh": BVH_TEXT, "asf": ASF_TEXT, "amc": AMC_TEXT}[fmt]
    changed = mutate(text)
    assert changed != text
    (tmp_path / "tiny.asf").write_text(changed if fmt == "asf" else ASF_TEXT)
    (tmp_path / "tiny_01.amc").write_text(changed if fmt == "amc" else AMC_TEXT)
    path = tmp_path / {"asf": "tiny_01.amc"}.get(fmt, f"tiny_01.{fmt}")
    if fmt in ("trc", "bvh"):
        path.write_text(changed)
    with pytest.raises(InputFormatError) as ei:
        read(path)
    assert match in str(ei.value) and "cannot read" not in str(ei.value), str(ei.value)


# -- C3D bytes built by hand -------------------------------------------------


def _ieee_to_dec(values) -> bytes:
    """Inverse of the VAX F conversion: IEEE bits of 4x the value, words swapped."""
    raw = np.asarray(values, "<f4") * np.float32(4.0)
    b = raw.astype("<f4").view(np.uint8).reshape(-1, 4)
    return b[:, [2, 3, 0, 1]].tobytes()


def build_c3d(points, residual, labels, rate, *, processor=84, scale=-1.0, units="mm"):
    """A minimal C3D: header, one parameter block (POINT group), point data.

    points: (frames, n, 3) float; residual: (frames, n) int. Written with the
    C3D.org layout independently of the reader.
    """
    big = processor == 86
    e = ">" if big else "<"
    fl = e + "f"
    frames, n, _ = points.shape

    def f32(v):
        return _ieee_to_dec([v]) if processor == 85 else struct.pack(fl, v)

    def param(name, gid, ptype, dims, data):
        body = struct.pack("bB", ptype, len(dims)) + bytes(dims) + data + b"\x00"
        nm = name.encode()
        return struct.pack("bb", len(nm), gid) + nm + struct.pack(e + "H", 2 + len(body)) + body

    width = max(len(s) for s in labels)
    plist = b"".join([
        struct.pack("bb", 5, -1) + b"POINT" + struct.pack(e + "H", 3) + b"\x00",
        param("USED", 1, 2, [], struct.pack(e + "h", n)),
        param("SCALE", 1, 4, [], f32(scale)),
        param("RATE", 1, 4, [], f32(rate)),
        param("DATA_START", 1, 2, [], struct.pack(e + "h", 3)),
        param("FRAMES", 1, 2, [], struct.pack(e + "h", frames)),
        param("UNITS", 1, -1, [len(units)], units.encode()),
        param("LABELS", 1, -1, [width, n], b"".join(s.ljust(width).encode() for s in labels)),
    ])
    pblock = bytes([1, 80, 1, processor]) + plist
    assert len(pblock) <= 512
    pblock = pblock.ljust(512, b"\x00")
    header = bytearray(512)
    header[0], header[1] = 2, 0x50
    header[2:4] = struct.pack(e + "h", n)
    header[6:10] = struct.pack(e + "HH", 1, frames)
    header[12:16] = f32(scale)
    header[16:18] = struct.pack(e + "H", 3)
    header[20:24] = f32(rate)
    words = np.concatenate([points, residual[..., None]], axis=2)
    if scale < 0:
        flat = words.astype(np.float32).ravel()
        data = _ieee_to_dec(flat) if processor == 85 else flat.astype(e + "f4").tobytes()
    else:
        ints = np.concatenate([np.round(points / abs(scale)), residual[..., None]], axis=2)
        data = ints.astype(e + "i2").tobytes()
    return bytes(header) + pblock + data


def _c3d_example():
    pts = np.array([[[1.0, 2.0, 3.0], [-4.5, 5.25, 6.0]],
                    [[7.0, 8.0, 9.0], [0.0, 0.0, 0.0]],
                    [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]])
    res = np.array([[0, 3], [0, -1], [-1, 2]])
    return pts, res


@pytest.mark.parametrize("processor,scale", [(84, -1.0), (85, -1.0), (86, -1.0),
                                             (84, 0.25), (86, 0.25)])
def test_c3d_numpy_reader_processors(tmp_path, processor, scale):
    pts, res = _c3d_example()
    blob = build_c3d(pts, res, ["Subj:A", "B"], DANCE_RATE, processor=processor, scale=scale,
                     units="cm")
    d = c3dbin.parse_c3d(blob)
    assert d.processor == processor and d.float_storage == (scale < 0)
    np.testing.assert_array_equal(d.points, pts)       # all values exact in f32 and in 0.25 steps
    np.testing.assert_array_equal(d.residual_words < 0, res < 0)
    assert d.params["POINT"]["LABELS"] == ["Subj:A", "B"]
    # through the public reader (ezc3d for Intel/DEC, the fallback for MIPS)
    p = tmp_path / "h.c3d"
    p.write_bytes(blob)
    m = read_c3d(p)
    assert m.names == ["Subj:A", "B"] and m.units == "cm"
    assert m.rate == DANCE_RATE
    # gaps: negative residual, and (0,0,0) with residual >= 0 at frame 2 / marker 0
    assert m.valid.tolist() == [[True, True], [True, False], [False, True]]
    assert m.positions[0, 1].tolist() == [-4.5, 5.25, 6.0]
    if processor == 86:     # ezc3d does not read MIPS files: a note of the reader, no warning
        assert m.metadata["reader"] == "mpz.io.c3dbin" and "warning" not in m.metadata
        assert "MIPS" in m.metadata["reader_note"]


def test_c3d_duplicate_and_empty_labels(tmp_path):
    pts = np.ones((2, 4, 3))
    blob = build_c3d(pts, np.zeros((2, 4), int), ["A", "", "A", "A"], 100.0)
    (tmp_path / "d.c3d").write_bytes(blob)
    m = read(tmp_path / "d.c3d")
    assert m.names == ["A", "_unnamed_1", "A#2", "A#3"]
    assert "A->A#2" in m.metadata["renamed_points"]


def test_c3d_unknown_units(tmp_path):
    blob = build_c3d(np.ones((1, 1, 3)), np.zeros((1, 1), int), ["A"], 100.0, units="furlong")
    (tmp_path / "u.c3d").write_bytes(blob)
    m = read(tmp_path / "u.c3d")
    assert m.units == "" and m.metadata["units_in_file"] == "furlong"


# -- errors ------------------------------------------------------------------

def test_unknown_extension(tmp_path):
    p = tmp_path / "a.xyz"
    p.write_text("1 2 3")
    with pytest.raises(InputFormatError, match="unknown file extension") as ei:
        read(p)
    assert ei.value.path == str(p)
    with pytest.raises(InputFormatError):
        write(synthetic(), tmp_path / "a.bvh")


def test_an_asf_read_as_a_motion_is_told_it_is_a_skeleton(tmp_path):
    """An AMC's skeleton given where its motion goes (mpz search 35.asf, mpz encode 35.asf)
    was an 'unknown file extension' whose list of formats names .amc, with no word that
    the ASF belongs to one (a QA run of stop 61)."""
    p = tmp_path / "35.asf"
    p.write_text(":version 1.10\n:name VICON\n:units\n  mass 1.0\n")
    with pytest.raises(InputFormatError, match="an ASF file is the skeleton of AMC motions, "
                       "not a motion: read an .amc") as ei:
        read(p)
    assert ei.value.path == str(p)


@pytest.mark.parametrize("head", [
    "# AST/ASF file\n:version 1.10\n:name VICON\n:units\n  mass 1.0\n",  # CMU's first lines
    ":version 1.10\n:name x\n",
    ":root\n   order TX TY TZ RX RY RZ\n:bonedata\n"])
def test_an_asf_without_its_extension_is_told_it_is_a_skeleton(tmp_path, head):
    """Only the name told an ASF apart: on standard input (mpz encode - < 35.asf) and
    under another extension it was 'cannot tell the format' or 'unknown file extension'
    (stop 61's list of what was not done)."""
    said = "an ASF file is the skeleton of AMC motions, not a motion"
    with pytest.raises(InputFormatError, match=said) as ei:
        read_bytes(head.encode())
    assert ei.value.path == "-"
    p = tmp_path / "skeleton.txt"
    p.write_text(head)
    with pytest.raises(InputFormatError, match=said):
        read(p)
    # an AMC, whose header may name its ASF in a comment, is still read as one
    assert detect_format(b"#!OML:ASF 35.asf\n:FULLY-SPECIFIED\n:DEGREES\n1\n") == ".amc"


@pytest.mark.parametrize("ext", [".c3d", ".trc", ".bvh", ".amc", ".npy", ".csv"])
def test_missing_file(tmp_path, ext):
    with pytest.raises(InputFormatError, match="no such file"):
        read(tmp_path / f"nothing{ext}", asf=tmp_path / "nothing.asf")


@pytest.mark.parametrize("content", [
    b"",
    b"\x02\x50" + b"\x00" * 100,                            # header cut short
    bytes(np.random.default_rng(3).integers(0, 256, 4096, dtype=np.uint8)),
    b"\x02\x50" + bytes(np.random.default_rng(4).integers(0, 256, 2000, dtype=np.uint8)),
    b"PK\x03\x04 not a c3d at all" * 100,
])
def test_garbage_c3d(tmp_path, content):
    p = tmp_path / "g.c3d"
    p.write_bytes(content)
    with pytest.raises(InputFormatError):
        read(p)


def test_truncated_c3d(tmp_path):
    pts, res = _c3d_example()
    blob = build_c3d(pts, res, ["A", "B"], 50.0)
    p = tmp_path / "t.c3d"
    p.write_bytes(blob[:-8])
    with pytest.raises(InputFormatError, match="truncated"):
        read(p)


def test_c3d_numpy_reader_fuzz():
    """Mutated bytes: parse_c3d either returns or raises InputFormatError."""
    pts, res = _c3d_example()
    good = build_c3d(pts, res, ["A", "B"], 50.0, processor=86)
    rng = np.random.default_rng(2024)
    outcomes = set()
    for _ in range(400):
        b = bytearray(good)
        for _ in range(int(rng.integers(1, 6))):
            b[int(rng.integers(0, len(b)))] = int(rng.integers(0, 256))
        if rng.random() < 0.3:
            b = b[:int(rng.integers(0, len(b)))]
        try:
            c3dbin.parse_c3d(bytes(b))
            outcomes.add("ok")
        except InputFormatError:
            outcomes.add("error")
    assert outcomes == {"ok", "error"}


@pytest.mark.parametrize("ext,content", [
    (".npy", b"\x93NUMPY garbage"),
    (".npy", None),                   # wrong shape, filled below
    (".csv", b"frame,time,A_x,A_y\n0,0,1,2\n"),
    (".csv", b"frame,time,A_x,A_y,A_z\n0,0,1,2\n"),
    (".csv", b"\xff\xfe\x00garbage"),
    (".trc", b"\xff\xfe\x00\x00garbage"),
    (".bvh", b"HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 1 Xposition\n}\nMOTION\nFrames: 1\n"
             b"Frame Time: 0\n1\n"),
])
def test_only_input_format_errors_escape(tmp_path, ext, content):
    p = tmp_path / f"x{ext}"
    if content is None:
        np.save(p, np.zeros((3, 4)))
    else:
        p.write_bytes(content)
    with pytest.raises(InputFormatError):
        read(p)


def test_error_is_an_mpz_value_error(tmp_path):
    p = tmp_path / "x.trc"
    p.write_text("PathFileType\n")
    with pytest.raises(ValueError) as ei:
        read(p)
    assert isinstance(ei.value, MPZError)
    assert not isinstance(ei.value, (KeyError, IndexError))


# -- mpz show ------------------------------------------------------------------

def show(argv) -> int:
    """Run ``mpz show`` alone, with the dispatcher's MPZError -> 2 rule."""
    import argparse
    parser = argparse.ArgumentParser(prog="mpz")
    cmd_show.add_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except MPZError:
        return 2


def test_show_is_registered():
    assert mpz_cli.SUBCOMMANDS["show"] == "mpz.tools.cmd_show"


def test_show(tmp_path, capsys):
    m = synthetic()
    write(m, tmp_path / "s.trc")
    assert show(["show", str(tmp_path / "s.trc")]) == 0
    out = capsys.readouterr().out
    assert "frames:    7" in out and "markers:   5" in out and "TRC" in out


def test_show_json(tmp_path, capsys):
    import json
    m = synthetic()
    write(m, tmp_path / "s.c3d")
    assert show(["show", "--json", str(tmp_path / "s.c3d")]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["schema"] == "mpz-show/2" and info["format"] == "C3D"
    assert info["frames"] == 7 and info["markers"] == 5 and info["rate"] == DANCE_RATE
    assert info["units"] == "mm"
    # 5 gaps out of 35 marker-frames, plus marker 3 missing in 6 of 7 frames
    assert info["gap_fraction"] == pytest.approx((3 + 6) / 35)
    assert info["duration"] == pytest.approx(7 / DANCE_RATE)    # frames / rate, as mpz.info


def test_show_errors(tmp_path, capsys):
    (tmp_path / "bad.c3d").write_bytes(b"nope")
    assert show(["show", str(tmp_path / "bad.c3d")]) == 2
    assert show(["show", str(tmp_path / "x.mpz")]) == 2         # no such .mpz
    capsys.readouterr()
    import json

    import mpz
    (tmp_path / "ok.mpz").write_bytes(mpz.encode(synthetic(), max_error=1.0))
    assert show(["show", "--json", str(tmp_path / "ok.mpz")]) == 0  # decoded and shown
    info = json.loads(capsys.readouterr().out)
    assert info["format"] == "MPZ" and info["frames"] == 7 and info["markers"] == 5
    assert show(["show", str(tmp_path / "missing.trc")]) == 2


def test_bvh_without_channels_counts_its_frame_lines(tmp_path):
    """CHANNELS 0 leaves nothing but 'Frames:' to bound the frame count, and the positions
    are allocated by it: 'Frames: 1000000000' in 114 bytes ran out of memory (exit 3). Spec
    §4.14.1 writes one line per frame, empty without channels; fewer lines are refused,
    and the writer's own file reads back."""
    head = ("HIERARCHY\nROOT r\n{\nOFFSET 0 0 0\nCHANNELS 0\nEnd Site\n{\nOFFSET 0 1 0\n}\n}\n"
            "MOTION\n")
    p = tmp_path / "c0.bvh"
    p.write_text(head + "Frames: 1000000000\nFrame Time: 0.01\n")
    with pytest.raises(InputFormatError, match="0 frame lines"):
        read(p)
    p.write_text(head + "Frames: 3\nFrame Time: 0.01\n\n\n\n")
    m = read(p)
    assert m.n_frames == 3
    write(m, tmp_path / "back.bvh")
    assert read(tmp_path / "back.bvh").n_frames == 3


@pytest.mark.parametrize("cell,times,match", [
    ("1_000", None, "plain decimal"),
    ("inf", None, "finite"),
    ("1.0", [0.0, 0.5, 0.1, 0.9], "do not increase.*row 4 has time 0.1"),   # out of order
    ("1.0", [0.0, 0.5, 1.3, 1.5], "not evenly spaced"),
])
def test_csv_numbers_and_times_are_checked(tmp_path, cell, times, match):
    """Python's float() took '1_000' and 'inf'; a time column that no rate explains was
    read at its (n - 1) / span rate (a QA run). Times printed to 3 decimals still read."""
    t = times or [0.0, 0.5, 1.0, 1.5]
    rows = "".join(f"{k},{t[k]},{cell if k == 2 else 1.0},2.0,3.0\n" for k in range(4))
    p = tmp_path / "a.csv"
    p.write_text("frame,time,A_x,A_y,A_z\n" + rows)
    with pytest.raises(InputFormatError, match=match):
        read(p)
    p.write_text("frame,time,A_x,A_y,A_z\n" + "".join(
        f"{k},{round(k / 60, 3)},1.0,2.0,3.0\n" for k in range(100)))
    assert read(p).rate == pytest.approx(60.0, rel=1e-3)


@pytest.mark.parametrize("number", ["x", "nan", "", "1e30", "100000000000000000000"])
def test_trc_frame_numbers_that_are_not_whole_numbers_are_said(tmp_path, number):
    """A Frame# that is not a whole number (or is one too large for any frame) was taken
    silently, or raised OverflowError ('cannot read: Python int too large'): the rows are
    still consecutive frames, and the motion's warning says why."""
    p = tmp_path / "f.trc"
    p.write_text(TRC_TEXT.replace("\n2\t0.017", f"\n{number}\t0.017"))
    m = read(p)
    assert m.n_frames == 3
    assert "Frame# column" in m.metadata.get("warning", "")


@pytest.mark.parametrize("rate", [-1, 0, float("nan"), True, "60"])
def test_a_bad_rate_argument_is_named_not_blamed_on_the_file(tmp_path, rate):
    """read(x.npy, rate=-1) said 'inconsistent data', an error of the file (a QA run)."""
    p = tmp_path / "r.npy"
    np.save(p, np.zeros((3, 2, 3)))
    with pytest.raises(ValueError, match="rate must be a finite number") as e:
        read(p, rate=rate)
    assert not isinstance(e.value, InputFormatError)
    assert read(p, rate=np.float32(60)).rate == 60.0


@pytest.mark.parametrize("ext,text,cut", [
    (".trc", TRC_TEXT, 2), (".bvh", BVH_TEXT, 1),     # BVH: a value less is refused anyway
    (".csv", "frame,time,A_x,A_y,A_z\n0,0.0,1.0,2.0,3.0\n1,0.5,1.0,2.0,3.25\n", 2),
])
def test_a_text_file_cut_inside_its_last_line_is_said(tmp_path, ext, text, cut):
    """Cut in the middle of its last number, a text file read as fewer digits (3.25 as 3.2)
    without a word (a QA run). Every writer and real file ends its lines: a file that does
    not is read with a warning."""
    p = tmp_path / f"x{ext}"
    p.write_text(text)
    assert "line break" not in read(p).metadata.get("warning", "")
    p.write_text(text[:-cut])                     # the last line's break (and last digit)
    m = read(p)
    assert "does not end with a line break" in m.metadata["warning"]
    if ext != ".bvh":
        # ending inside a number, which may be cut, the last marker of the row (B's z "9"
        # in the TRC; A's 3.2 of 3.25 in the CSV) is a gap, said, not a wrong value
        p.write_text(text[:-1])
        m = read(p)
        j = m.n_markers - 1
        assert not m.valid[-1, j] and np.isnan(m.positions[-1, j]).all()
        assert f"marker {m.names[j]!r} at frame index {m.n_frames - 1} is taken as a gap" \
            in m.metadata["warning"]
        assert m.valid[0].all()                                 # the rows before: as read
        p.write_text(text[:-1] + "\t")            # no break, but not inside a number
        m = read(p)
        assert "line break" in m.metadata["warning"] and "taken as a gap" not in \
            m.metadata["warning"] and m.valid[-1, j]


def test_wrong_argument_types_are_named(tmp_path):
    """QA (stop 33): wrong types reached internal code: AttributeError in write, an int
    asf opened as the caller's file descriptor 3 (read, then closed), bytes taken for a
    path, a model_errors value and a text stream failing without naming themselves."""
    import io as _io
    import os

    import mpz
    from mpz.errors import EncoderError
    from mpz.synth import generate
    m = generate("walk", frames=30, seed=1)
    with pytest.raises(TypeError, match="expected an mpz.Motion, got ndarray"):
        write(m.positions, tmp_path / "x.trc")
    with pytest.raises(TypeError, match="file_name must be a str"):
        write(m, tmp_path / "x.trc", file_name=3)
    write(m, tmp_path / "x.trc")
    with pytest.raises(TypeError, match="path must be a file name"):
        read((tmp_path / "x.trc").read_bytes())
    r, w = os.pipe()
    try:
        with pytest.raises(TypeError, match="asf must be a file name"):
            read(tmp_path / "x.trc", asf=r)
        os.fstat(r)                                   # still the caller's
    finally:
        os.close(r)
        os.close(w)
    with pytest.raises(EncoderError, match=r"model_errors\['ANGLES'\]"):
        mpz.encode(m, max_error=1.0, model_errors={"ANGLES": "x"})

    class TextRead(_io.RawIOBase):
        def read(self, n=-1):
            return "abc"
    with pytest.raises(TypeError, match="binary mode"):
        mpz.decode(TextRead())


def test_edited_positions_of_a_skeletal_motion_are_noted(two_joint_bvh, tmp_path):
    """BVH and AMC are written from the skeleton's channels: positions edited after reading
    (re-centred here) are not what the file gives, and io.write now says so (API review
    F12: it returned no note). A motion as read gets no such note."""
    import dataclasses

    import mpz
    from mpz.io.bvh import parse_bvh
    m = parse_bvh(two_joint_bvh)
    assert not [n for n in mpz.io.write(m, tmp_path / "same.bvh") if "not positions" in n]
    moved = dataclasses.replace(m, positions=m.positions + 100.0)
    notes = [n for n in mpz.io.write(moved, tmp_path / "moved.bvh") if "not positions" in n]
    assert len(notes) == 1 and "173.2" in notes[0]          # |(100, 100, 100)|
    back = mpz.io.read(tmp_path / "moved.bvh")
    assert np.allclose(back.positions, m.positions)


def test_a_broken_asf_is_named_as_the_asf(tmp_path, shared_data):
    """QA (stop 45): an ASF line of ':' alone gave "cannot read: IndexError: list index out
    of range", and every ASF fault named the .amc file."""
    src = (shared_data / "amc" / "02.asf").read_text(encoding="latin-1")
    bad = tmp_path / "colon.asf"
    bad.write_text(":\n" + src, encoding="latin-1")
    with pytest.raises(InputFormatError) as info:
        read(shared_data / "amc" / "02_01.amc", asf=bad)
    assert info.value.path == str(bad)
    assert "':' with no keyword" in info.value.message and "IndexError" not in str(info.value)


@pytest.mark.parametrize("bug", [IndexError, KeyError, TypeError, AttributeError,
                                 ZeroDivisionError])
def test_a_readers_bug_is_not_reported_as_bad_input(tmp_path, monkeypatch, bug):
    """A reader that indexes past what it checked has a bug: the exception surfaces as
    itself, not as "cannot read: IndexError: ..." blaming the file (until stop 45 these
    were translated into InputFormatError). A ValueError of a bad number still is."""
    import mpz.io.trc as trc
    from mpz.synth import generate
    p = tmp_path / "w.trc"
    write(generate("walk", frames=5, markers=2), p)

    def broken(text, **kw):
        raise bug("a reader's own mistake")
    monkeypatch.setattr(trc, "parse_trc", broken)
    with pytest.raises(bug):
        read(p)

    def bad_number(text, **kw):
        return int("x1")
    monkeypatch.setattr(trc, "parse_trc", bad_number)
    with pytest.raises(InputFormatError, match="ValueError"):
        read(p)


@pytest.mark.parametrize("ext", [".c3d", ".trc", ".csv"])
def test_a_name_that_is_not_unicode_text_is_refused_and_nothing_written(tmp_path, ext):
    """A lone surrogate (a file name's undecodable byte, as os.fsdecode gives it) cannot be
    written as text: mpz.io.write raised UnicodeEncodeError and left an empty TRC or CSV
    (a QA run of stop 47). It is refused by name, as check_writable refuses what a format
    cannot hold, and no file is made."""
    m = Motion(np.zeros((5, 2, 3)), ["A\udcff", "C"], 100.0)
    with pytest.raises(InputFormatError, match="not valid Unicode"):
        write(m, tmp_path / f"s{ext}")
    assert not (tmp_path / f"s{ext}").exists()


def test_a_c3d_name_with_a_nul_is_refused(tmp_path):
    """C3D labels are padded with NULs, which readers strip: "A\\0" read back as "A", and
    the marker really called "A" became "A#2", with no note (a QA run of stop 47)."""
    m = Motion(np.ones((5, 2, 3)), ["A\0", "A"], 100.0)
    with pytest.raises(InputFormatError, match="NUL"):
        write(m, tmp_path / "n.c3d")
    assert not (tmp_path / "n.c3d").exists()
    write(m, tmp_path / "n.npy")                     # a format without names takes it


def _trc_rows(path) -> tuple[list[str], list[list[str]]]:
    lines = path.read_text().splitlines()
    return lines[:6], [ln.split("\t") for ln in lines[6:] if ln.strip()]


def test_trc_values_a_gap_cannot_keep_are_said(tmp_path):
    """A QA of stop 48: a sample with one cell empty lost its two other coordinates, and a
    time off the rate's grid came back as the rate's, both without a word. The edits are
    made on the text here; an unedited file reads without a warning."""
    m = Motion(np.arange(10 * 2 * 3, dtype=float).reshape(10, 2, 3) + 1.0, ["A", "B"],
               100.0, "mm")
    write(m, tmp_path / "a.trc")
    assert "warning" not in read(tmp_path / "a.trc").metadata
    head, rows = _trc_rows(tmp_path / "a.trc")
    rows[4][2 + 3 + 1] = ""                       # frame index 4, marker B, Y empty
    rows[7][1] = f"{float(rows[7][1]) + 0.004:.6f}"   # frame index 7, 4 ms late
    (tmp_path / "b.trc").write_text("\n".join(head + ["\t".join(r) for r in rows]) + "\n")
    got = read(tmp_path / "b.trc")
    warning = got.metadata["warning"]
    assert ("1 sample with 1 or 2 of 3 coordinates empty (the first: frame index 4, marker "
            "'B'): each is a gap" in warning)
    assert ("the Time column is not the first time plus (frame - first) / DataRate at 1 of "
            "10 rows (the first: frame index 7, 0.074 s where the rate gives 0.07)"
            in warning), warning
    assert not got.valid[4, 1] and got.valid.sum() == 19


def test_c3d_values_a_gap_cannot_keep_are_said(tmp_path):
    """A QA of stop 48: coordinates beside a negative residual, or beside a NaN, and a NaN
    sample with a residual >= 0 (written back as a point at the origin) went without a
    word. The float C3D is patched here by its layout (C3D: header word 9 is the data's
    first 512-byte block, then per frame and point x, y, z and the residual word)."""
    m = Motion(np.arange(5 * 3 * 3, dtype=float).reshape(5, 3, 3) + 1.0, ["A", "B", "C"],
               100.0, "mm")
    write(m, tmp_path / "a.c3d")
    assert "warning" not in read(tmp_path / "a.c3d").metadata
    data = bytearray((tmp_path / "a.c3d").read_bytes())
    base = (struct.unpack_from("<H", data, 16)[0] - 1) * 512

    def put(f: int, p: int, k: int, v: float) -> None:
        struct.pack_into("<f", data, base + ((f * 3 + p) * 4 + k) * 4, v)
    put(1, 0, 3, -1.0)                      # residual -1, coordinates kept
    put(2, 1, 1, float("nan"))              # y NaN, residual 0
    for k in range(3):
        put(3, 2, k, float("nan"))          # all NaN, residual 0
    (tmp_path / "b.c3d").write_bytes(bytes(data))
    got = read(tmp_path / "b.c3d")
    warning = got.metadata["warning"]
    assert ("2 samples with a negative residual or a NaN coordinate (the first: frame index "
            "1, marker 'A'): each is a gap, and the coordinates it holds are not kept"
            in warning), warning
    assert "2 samples with a NaN coordinate and a residual >= 0 will be written back as " \
           "(0, 0, 0)" in warning
    assert got.valid.sum() == 15 - 3


@pytest.mark.parametrize("ext", [".xyz", "npy", ""])
def test_check_writable_refuses_an_extension_no_writer_has(ext):
    """A QA run of stop 48: check_writable(m, ".xyz") and (m, "npy") returned [], no note,
    as if the format could hold the motion; the writers are named."""
    from mpz.io import check_writable
    m = Motion(np.ones((2, 1, 3)), ["A"], 10.0, "mm")
    with pytest.raises(InputFormatError, match=r"cannot write .*; can write \.c3d"):
        check_writable(m, ext)
    assert check_writable(m, ".trc") == []           # a writer that holds it all


_TRC_KEYS = ["trc.PathFileType", "trc.FileName", "trc.DataRate", "trc.CameraRate",
             "trc.NumFrames", "trc.Units", "trc.OrigDataStartFrame", "trc.FirstFrame",
             "trc.Decimals", "trc.TimeDecimals", "trc.TimeDigits", "trc.TrailingTabs",
             "start_time"]


@settings(max_examples=150, deadline=None)
@given(st.dictionaries(st.sampled_from(_TRC_KEYS),
                       st.one_of(st.text(max_size=12),
                                 st.sampled_from(["abc", "-3", "-1", "100000000", "31", "nan",
                                                  "inf", "1e309", "4\n\n\nFrame#", "a\tb",
                                                  "9" * 40, "0", "30", "0 0 0 3 1",
                                                  "1 2 3 4 99999999"])),
                       max_size=6))
def test_trc_writer_takes_any_trc_metadata_and_writes_a_file_it_reads(tmp_path_factory, meta):
    """A file's meta chunk is free text (spec §4.11), and the TRC writer wrote its trc.*
    entries back unchecked: a DataRate of "abc" or negative decimals crashed it (exit 70),
    decimals of 10^8 asked for 24 GB of text, a line break in PathFileType wrote a TRC its
    own reader refused (a fuzzing QA run of stop 48). Whatever the entries, the TRC is
    written, reads back with the names, frames and (to its decimals) the positions, and
    each entry the writer could not use is named in a note."""
    from mpz.io.trc import column_decimals, trc_meta_problems
    pos = np.arange(4 * 2 * 3, dtype=float).reshape(4, 2, 3) * 1.25 + 0.5
    m = Motion(pos, ["A", "B"], 100.0, "mm", metadata=meta)
    path = tmp_path_factory.mktemp("trc") / "m.trc"
    notes = write(m, path)
    back = read(path)
    assert back.names == ["A", "B"] and back.n_frames == 4 and back.rate == 100.0
    d = column_decimals(m)                           # the source's, when it can be used
    assert 0 <= d <= 30
    assert np.abs(back.positions - pos).max() <= 0.5 * 10.0 ** -d + 1e-9
    for key in trc_meta_problems(meta):
        assert any(f"metadata {key} " in n for n in notes), (key, notes)


def test_an_mpz_given_to_read_is_named_as_such(tmp_path):
    """QA, stop 49: `mpz encode A.mpz B.mpz -o OUT/` (mpz.io.read in a batch) said
    "unknown file extension '.mpz' and no known format in the content" of an MPZ file."""
    import mpz
    from mpz.synth import generate
    data = mpz.encode(generate("walk", frames=20), max_error=1.0)
    for name in ("a.mpz", "a.bin"):
        (tmp_path / name).write_bytes(data)
        with pytest.raises(InputFormatError, match=r"an MPZ file.*mpz\.decode") as err:
            read(tmp_path / name)
        assert "no known format" not in str(err.value)


@pytest.mark.parametrize("ext", [".trc", ".amc"])
def test_write_leaves_no_cut_file_and_names_a_full_disk(tmp_path, monkeypatch, ext, request):
    """mpz.io.write wrote in place: a full disk left a cut file over the old one, and a raw
    OSError (a QA run of stop 49; the CLI's writes were atomic, the library's were not).
    The disk fills here in the writer, half-way through (and, for AMC, in the ASF)."""
    import errno

    from mpz.errors import EncoderError
    import mpz.io
    from mpz.synth import generate
    if ext == ".amc":
        m = mpz.io.read(request.getfixturevalue("shared_data") / "amc" / "02_01.amc")
    else:
        m = generate("walk", frames=20, seed=2)
    target = tmp_path / f"out{ext}"
    mpz.io.write(m, target)
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}

    def full(motion, path, **kw):
        with open(path, "wb") as fh:
            fh.write(b"PathFileType\t4")
        raise OSError(errno.ENOSPC, "No space left on device")
    if ext == ".amc":                      # the disk fills in the ASF
        monkeypatch.setattr(mpz.io.amc, "write_asf", full)
        target = target.with_suffix(".asf")
    else:
        monkeypatch.setitem(mpz.io.WRITERS, ext, full)
    with pytest.raises(EncoderError, match="No space left on device") as got:
        mpz.io.write(m, tmp_path / f"out{ext}")
    assert f"cannot write {target}:" in str(got.value)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


@pytest.mark.parametrize("text", ["¹", "١٢", "+²", "+-1", "-+1", "--0", "++3"])
def test_trc_metadata_digits_of_other_scripts_are_no_whole_number(text):
    """hypothesis (stop 50): trc.FirstFrame '¹' passed str.isdigit, then int() raised
    ValueError inside mpz.io.write; it is a value the writer does not use. A doubled sign
    did the same (a review of stop 59: exit 70 from mpz decode), for every whole-number key."""
    from mpz.io.trc import trc_meta_problems
    for key in ("trc.FirstFrame", "trc.Decimals", "trc.TimeDecimals", "trc.TimeDigits"):
        assert key in trc_meta_problems({key: text}), key


# -- a review of the stop 50 parsers (TRC, CSV and BVH fill arrays) ---------------------------

def test_a_bvh_joint_named_motion_does_not_end_the_hierarchy(two_joint_bvh):
    """The hierarchy's words were taken up to the first MOTION anywhere: a joint named
    Motion made a valid file "HIERARCHY ends inside a joint block"."""
    from mpz.io.bvh import parse_bvh
    m = parse_bvh(two_joint_bvh.replace("JOINT Spine", "JOINT Motion"))
    assert m.names == ["Hips", "Motion", "Motion_End"] and m.n_frames == 3


@pytest.mark.parametrize("frames, said", [
    ("99999999999999999", "27 values for 99999999999999999 frames x 9 channels (truncated"),
    ("2", "18 values beyond 2 frames x 9 channels"),     # 3 rows and one more of 9
])
def test_a_bvh_frame_count_the_text_cannot_hold_is_no_allocation(two_joint_bvh, frames, said):
    """A 179-byte BVH declaring 10^17 frames asked numpy for 2 EiB (MemoryError: "out of
    memory, the input may be valid"); the count is checked against what the text can hold
    first, as the words were counted before the rewrite."""
    from mpz.io.bvh import parse_bvh
    text = two_joint_bvh.replace("Frames: 3", f"Frames: {frames}")
    if frames == "2":
        text = text.replace("2 0 0 0 10 0 20 0 0", "2 0 0 0 10 0 20 0 0\n" + "1 " * 9)
    with pytest.raises(InputFormatError, match=re.escape(said)):
        parse_bvh(text)


def test_a_bvh_cut_short_is_said_before_a_bad_number_in_it(two_joint_bvh):
    """The count was checked before the values: a truncated BVH with a bad word in it said
    "truncated"; the rewrite said the word. The count comes first again."""
    from mpz.io.bvh import parse_bvh
    with pytest.raises(InputFormatError, match="truncated motion data"):
        parse_bvh(two_joint_bvh.replace("1 0 0 0 5 0 10 0 0\n2 0 0 0 10 0 20 0 0\n", "x\n"))


@pytest.mark.parametrize("old, new, said", [
    # a row cut short in the middle of the file: "truncated motion data", at no place
    ("1 0 0 0 5 0 10 0 0\n", "1 0 0 0 5 0 10 0\n",
     "(truncated motion data); line 20 (frame 2) has 8 values, not 9"),
    ("1 0 0 0 5 0 10 0 0\n", "1 0 0 0 5 0 10 0 0 7\n",
     "1 values beyond 3 frames x 9 channels; line 20 (frame 2) has 10 values, not 9"),
    ("1 0 0 0 5 0 10 0 0\n", "1 0 0 0 5,5 0 10 0 0\n",     # a decimal comma
     "MOTION: '5,5' is not a number, line 20 (frame 2)"),
])
@pytest.mark.parametrize("newline", ["\n", "\r\n", "\r"])
def test_a_bvh_row_of_the_wrong_width_is_named_by_its_line(two_joint_bvh, old, new, said,
                                                           newline):
    """A QA run of BVH exporters: the values are read as one stream, so a short or long
    row in the middle of a file was "N values for F frames x C channels (truncated motion
    data)" with no line to look at; the first row of the wrong width (or with a word that
    is no number) is named by its line in the file and its frame."""
    from mpz.io.bvh import parse_bvh
    text = two_joint_bvh.replace(old, new).replace("\n", newline)
    with pytest.raises(InputFormatError, match=re.escape(said)):
        parse_bvh(text)


@pytest.mark.parametrize("old, new", [("Frames: 3", "Frames:3"),
                                      ("Frame Time: 0.0333333", "Frame Time:0.0333333"),
                                      ("Frames: 3\nFrame Time: ", "frames:3 frame time:")])
def test_a_bvh_motion_header_without_a_space_after_its_colons(two_joint_bvh, old, new):
    """A QA run of BVH exporters: ``Frames:60`` and ``Frame Time:0.041667`` were refused
    ("expected 'Frames: n' and 'Frame Time: t' after MOTION"); they read as with a space."""
    from mpz.io.bvh import parse_bvh
    assert new.split(":")[0] in two_joint_bvh.replace(old, new)
    m, ref = parse_bvh(two_joint_bvh.replace(old, new)), parse_bvh(two_joint_bvh)
    assert (m.n_frames, m.rate) == (ref.n_frames, ref.rate)
    np.testing.assert_array_equal(m.angles, ref.angles)


@pytest.mark.parametrize("newline", ["\n", "\r\n"])
def test_a_bvh_whose_rows_shift_the_frames_is_refused(two_joint_bvh, newline):
    """A QA run of BVH exporters: a row one value short and a later one a value long have
    the right count, and were read as one stream, every frame between them shifted by a
    channel, without a word. A frame wrapped over two lines (no line then says where a frame
    starts) is still read as one stream, each value in its place."""
    from mpz.io.bvh import parse_bvh
    shifted = (two_joint_bvh.replace("1 0 0 0 5 0 10 0 0\n", "1 0 0 0 5 0 10 0\n")
               .replace("2 0 0 0 10 0 20 0 0", "0 2 0 0 0 10 0 20 0 0"))
    with pytest.raises(InputFormatError, match=re.escape(
            "3 frames x 9 channels over 3 lines, but not one frame a line; line 20 (frame 2) "
            "has 8 values, not 9: the frames after it would be read shifted")):
        parse_bvh(shifted.replace("\n", newline))
    wrapped = two_joint_bvh.replace("1 0 0 0 5 0 10 0 0\n", "1 0 0 0 5\n0 10 0 0\n")
    m = parse_bvh(wrapped.replace("\n", newline))
    assert m.angles is not None
    np.testing.assert_array_equal(m.angles, parse_bvh(two_joint_bvh).angles)


def test_blank_lines_do_not_size_the_arrays(tmp_path):
    """A 557 KB CSV (2000 markers, 500,000 blank lines, one row) asked numpy for 22 GiB:
    the arrays were sized by lines times columns. Read here under a 1.5 GiB address-space
    limit, each format in a process of its own."""
    import subprocess
    import sys
    names = [f"m{i}" for i in range(2000)]
    (tmp_path / "b.csv").write_text(
        "frame,time," + ",".join(f"{n}_{c}" for n in names for c in "xyz") + "\n"
        + "\n" * 200_000 + "0,0.0," + ",".join(["1.5"] * 6000) + "\n")
    head = ["PathFileType\t4\t(X/Y/Z)\tb.trc",
            "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits",
            "100\t100\t1\t2000\tmm",
            "Frame#\tTime\t" + "\t".join(f"{n}\t\t" for n in names),
            "\t\t" + "\t".join(f"X{i}\tY{i}\tZ{i}" for i in range(1, 2001))]
    (tmp_path / "b.trc").write_text("\n".join(head) + "\n" + "\n" * 200_000 + "1\t0.0\t"
                                    + "\t".join(["1.5"] * 6000) + "\n")
    script = ("import resource, sys\n"
              "import mpz.io\n"
              "resource.setrlimit(resource.RLIMIT_AS, (3 << 29, 3 << 29))\n"
              "m = mpz.io.read(sys.argv[1])\n"
              "print(m.n_frames, m.n_markers, float(m.positions[0, 1999, 2]))\n")
    for name in ("b.csv", "b.trc"):
        p = subprocess.run([sys.executable, "-c", script, str(tmp_path / name)],
                           capture_output=True, text=True, timeout=120)
        assert p.returncode == 0 and p.stdout.split() == ["1", "2000", "1.5"], \
            (name, p.stderr[-600:])


def test_records_past_the_declared_parameter_blocks_are_read_and_said(tmp_path):
    """c3d.org Dance1 declares 3 parameter blocks and holds records in 11: mpz reads them
    all, as ezc3d does, and a C3D written back declares what it fills, so a reader that
    stops at the declared count (py-c3d) found two more groups there, and analog values of
    the other sign (ANALOG:GEN_SCALE -1), while encode, decode and compare said nothing (a
    QA run of stop 62). The reader now says so; a file whose count is right says nothing."""
    m = generate("walk", frames=20, seed=1)
    p = tmp_path / "w.c3d"
    write(m, p)
    data = bytearray(p.read_bytes())
    pstart = (data[0] - 1) * 512
    assert data[pstart + 2] >= 2, "the test needs a parameter section of several blocks"
    assert "parameter section declares" not in (read(p).metadata.get("warning") or "")
    data[pstart + 2] = 1                        # the count says one block; the records go on
    short = tmp_path / "short.c3d"
    short.write_bytes(bytes(data))
    back = read(short)
    said = back.metadata.get("warning") or ""
    assert "the parameter section declares 1 block but its records go on past it" in said
    assert "a reader that stops at the declared count" in said
    assert back.names == m.names                 # everything read, as before
    assert "in a C3D written back but not in this file" in said
    data[pstart + 2] = 0                        # 0 is read as 1 (as ezc3d does), said as 0
    short.write_bytes(bytes(data))
    said = read(short).metadata.get("warning") or ""
    assert "the parameter section declares 0 blocks but its records go on past them" in said


def test_an_ezc3d_older_than_the_floor_is_not_handed_files(tmp_path, monkeypatch):
    """pip refuses ezc3d < 1.7.2 (pyproject.toml), but conda, --no-deps or a system package
    may install 1.5.16, which ends the process on a C3D 1.7.2 reads: nothing checked it at
    run time (the review of stop 62). Such an ezc3d is not used to read; c3dbin reads the
    same points, and a note says why."""
    from importlib import metadata

    from mpz.io import c3d
    m = generate("walk", frames=20, seed=1)
    p = tmp_path / "w.c3d"
    write(m, p)
    usual = read(p)
    real = metadata.version
    monkeypatch.setattr(metadata, "version",
                        lambda name: "1.5.16" if name == "ezc3d" else real(name))
    c3d.ezc3d_too_old.cache_clear()
    try:
        assert c3d.ezc3d_too_old() == "1.5.16"
        back = read(p)
    finally:
        c3d.ezc3d_too_old.cache_clear()
    assert "not read with ezc3d 1.5.16, older than 1.7.2" in back.metadata["reader_note"]
    assert np.array_equal(back.positions, usual.positions, equal_nan=True)
    assert back.names == usual.names and back.rate == usual.rate
    # nor asked to write one: mpz's own writer does (the second review)
    import ezc3d
    monkeypatch.setattr(c3d, "ezc3d_too_old", lambda: "1.5.16")
    monkeypatch.setattr(ezc3d, "c3d", lambda *a, **k: pytest.fail("ezc3d was used"))
    written = tmp_path / "written.c3d"
    write(m, written)
    monkeypatch.undo()
    again = read(written)
    assert np.allclose(again.positions, m.positions, atol=1e-3, equal_nan=True)
    assert again.names == m.names
    monkeypatch.setattr(metadata, "version", lambda name: "1.7.2" if name == "ezc3d" else
                        real(name))
    assert c3d.ezc3d_too_old() is None
    c3d.ezc3d_too_old.cache_clear()
    # conda-forge's build has no package metadata, only ezc3d.__version__ (the review)
    import ezc3d

    def missing(name):
        if name == "ezc3d":
            raise metadata.PackageNotFoundError(name)
        return real(name)
    monkeypatch.setattr(metadata, "version", missing)
    monkeypatch.setattr(ezc3d, "__version__", "1.5.16", raising=False)
    try:
        assert c3d.ezc3d_too_old() == "1.5.16"
    finally:
        c3d.ezc3d_too_old.cache_clear()


# -- a hostile-input QA of the text readers (TRC, BVH, ASF/AMC, CSV) ----------------------------

def _wide_bvh(joints: int, frames: int) -> str:
    """A BVH of ``joints`` joints without channels, and ``frames`` empty frame lines."""
    body = "".join(f"JOINT j{i}\n{{\nOFFSET 0 1 0\nCHANNELS 0\n}}\n" for i in range(joints - 1))
    return (f"HIERARCHY\nROOT r\n{{\nOFFSET 0 0 0\nCHANNELS 0\n{body}}}\nMOTION\n"
            f"Frames: {frames}\nFrame Time: 0.01\n" + "\n" * frames)


def _bare_asf(bones: int) -> str:
    """An ASF of a root without dofs and a chain of ``bones`` bones without dofs."""
    blocks = "".join(f"begin\nname b{i}\ndirection 0 1 0\nlength 1\nend\n" for i in range(bones))
    chain = "".join(f"{'root' if i == 0 else f'b{i - 1}'} b{i}\n" for i in range(bones))
    return f":units\nlength 1\n:root\norder\n:bonedata\n{blocks}:hierarchy\nbegin\n{chain}end\n"


def test_a_skeleton_file_whose_positions_its_text_does_not_hold_is_refused(tmp_path):
    """Forward kinematics makes a position for every joint in every frame, with channels or
    not: a 0.4 MB BVH (10,000 joints without channels, 7000 empty frame lines) asked 1.7 GB,
    one of 100,000 lines 24 GB. Past MAX_SAMPLES positions the text must write them; the
    file is refused before anything is computed, here under a 1 GiB address-space limit."""
    import subprocess
    import sys
    (tmp_path / "wide.bvh").write_text(_wide_bvh(10_000, 7000))
    script = ("import resource, sys\n"
              "import mpz.io\n"
              "from mpz.errors import InputFormatError\n"
              "resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))\n"
              "try:\n"
              "    mpz.io.read(sys.argv[1])\n"
              "except InputFormatError as exc:\n"
              "    print(exc.message)\n")
    p = subprocess.run([sys.executable, "-c", script, str(tmp_path / "wide.bvh")],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr[-600:]
    assert p.stdout.startswith(
        "BVH: 7000 frames x 10000 joints and End Sites is 70000000 samples, past the 67108864 "
        "an MPZ file holds (spec §8, MAX_SAMPLES), and the text does not write them"), p.stdout


def test_a_skeleton_file_within_max_samples_or_its_text_is_read(monkeypatch):
    """The bound is MAX_SAMPLES positions (lowered here), or one character of text a
    coordinate: a BVH of more positions than MAX_SAMPLES whose text holds them reads as
    before. An AMC of bones without dofs (a line "root" a frame, 1000 bones: a 1 MB file
    asked 2.4 GB) is refused likewise."""
    from mpz.io import _common
    from mpz.io.amc import parse_amc
    from mpz.io.bvh import parse_bvh
    monkeypatch.setattr(_common, "MAX_SAMPLES", 10)
    with pytest.raises(InputFormatError, match="30 frames x 3 joints and End Sites is 90"):
        parse_bvh(_wide_bvh(3, 30))
    assert parse_bvh(_wide_bvh(3, 3)).n_frames == 3           # 9 positions: within
    text = _wide_bvh(3, 0).replace("CHANNELS 0\nJOINT j0", "CHANNELS 1 Xrotation\nJOINT j0", 1)
    text = text.replace("Frames: 0", "Frames: 30") + "10.000000\n" * 30     # 270 coordinates,
    assert parse_bvh(text).n_frames == 30                 # 300 characters of values alone
    skel = parse_asf(_bare_asf(9))
    with pytest.raises(InputFormatError, match="ASF/AMC: 6 frames x 10 joints is 60 samples"):
        parse_amc("".join(f"{f}\nroot\n" for f in range(1, 21)), skel)   # at the first frame
    #                                                                     past the bound
    assert parse_amc("1\nroot\n", skel).n_markers == 10


def _short_row_trc(markers: int, rows: int, values: int = 0) -> str:
    """A TRC of ``markers`` markers and ``rows`` rows of ``values`` values each."""
    names = "\t\t\t".join(f"m{i}" for i in range(markers))
    labels = "\t".join(f"X{i}\tY{i}\tZ{i}" for i in range(1, markers + 1))
    head = (f"PathFileType\t4\t(X/Y/Z)\tx.trc\nDataRate\tNumMarkers\tUnits\n100\t{markers}\tmm\n"
            f"Frame#\tTime\t{names}\n\t\t{labels}\n")
    return head + "".join(f"{f + 1}\t{f / 100}" + "\t1" * values + "\n" for f in range(rows))


def test_trc_rows_shorter_than_the_header_pad_no_more_than_max_samples(monkeypatch):
    """Rows shorter than the header are padded with gaps: a 3 MB TRC of 100,000 markers and
    rows of a frame number and a time alone asked 4.8 GB (MemoryError). Past MAX_SAMPLES
    (lowered here) the padding is refused, naming the line; rows the text writes are read."""
    from mpz.io import _common
    from mpz.io.trc import parse_trc
    monkeypatch.setattr(_common, "MAX_SAMPLES", 1000)
    with pytest.raises(InputFormatError, match=re.escape(
            "TRC: line 16: 11 frames x 100 markers is 1100 samples, past the 1000 an MPZ file "
            "holds (spec §8, MAX_SAMPLES), and the text does not write them")):
        parse_trc(_short_row_trc(100, 20))
    assert parse_trc(_short_row_trc(100, 10)).n_frames == 10
    m = parse_trc(_short_row_trc(100, 20, values=300))         # written out: read
    assert m.n_frames == 20 and bool(m.valid.all())


def test_trc_rows_past_max_samples_are_refused_before_any_row_is_read(monkeypatch):
    """The padding's bound was checked row by row: a 3.9 MB TRC of 100,000 markers and
    100,000 rows of one marker each grew its table to 2.9 GB over 12 s before its 672nd
    row was refused (a fuzzing QA run of the text readers). The rows are the data lines
    that are not blank, counted first: the same refusal, naming the same line, comes
    before a table is made."""
    from mpz.io import _common, trc
    monkeypatch.setattr(_common, "MAX_SAMPLES", 1000)

    def no_table(*args, **kwargs):
        raise AssertionError("a table was made for rows that are refused")

    text = _short_row_trc(100, 20, values=3).replace("\n3\t", "\n\n\n3\t", 1)
    with monkeypatch.context() as patched:
        patched.setattr(trc, "RowTable", no_table)
        with pytest.raises(InputFormatError, match=re.escape(
                "TRC: line 18: 11 frames x 100 markers is 1100 samples")):
            trc.parse_trc(text)
    assert trc.parse_trc(_short_row_trc(100, 10, values=3)).n_frames == 10


def test_trc_table_grows_to_its_bound_not_twice_it():
    """The rows array doubles as rows come, up to the most the bound lets come."""
    from mpz.io._common import RowTable
    t = RowTable(2, most=20)
    for _ in range(20):
        t.append([1.0])
    assert len(t._data) == 20 and t.rows().shape == (20, 2)


def test_a_wide_trc_is_read_within_twice_its_positions():
    """A TRC of 100,000 markers and 670 rows of one marker each (3 MB, padded with gaps to
    2^26 samples, the most MAX_SAMPLES lets come) took 25-38 s and 4.5 GB to read: its
    table doubled as the rows came, each larger array filled with NaN, and was copied once
    more at the end (a fuzzing QA run of the readers). Its rows are counted before the
    table is made, so it is made their size once and given as it is: 6-7 s and 2.9 GB.
    Traced here on 20,000 markers and 200 rows (96 MB of positions): 3.1 times the
    positions before, 1.8 now."""
    import tracemalloc
    text = _short_row_trc(20000, 200, values=3)
    from mpz.io.trc import parse_trc
    tracemalloc.start()
    try:
        m = parse_trc(text)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert m.positions.shape == (200, 20000, 3) and m.valid[:, 0].all() \
        and not m.valid[:, 1:].any()
    assert peak <= 2.0 * m.positions.nbytes, peak / m.positions.nbytes


def test_a_table_told_its_rows_is_made_once_and_given_as_it_is():
    from mpz.io._common import RowTable
    t = RowTable(3, most=50, expect=5)
    first = t._data
    for k in range(5):
        t.append([float(k)])
    assert t._data is first and t.rows() is first
    assert t.rows()[:, 0].tolist() == [0.0, 1.0, 2.0, 3.0, 4.0] and np.isnan(t.rows()[:, 1:]).all()
    short = RowTable(3, most=50, expect=5)
    short.append([1.0])
    assert short.rows().shape == (1, 3)            # fewer than told: a copy of their size
    assert len(RowTable(3, most=4, expect=9)._data) == 4    # never past the bound


@pytest.mark.parametrize("old, said", [
    ("    OFFSET 0 10 0\n", "joint 'Spine' has two OFFSET lines"),
    ("      OFFSET 0 10 0\n", "the End Site of 'Spine' has two OFFSET lines"),
])
def test_a_bvh_joint_with_two_offsets_is_refused(two_joint_bvh, old, said):
    """A second OFFSET line replaced the first without a word (a second CHANNELS line is
    refused): the joint's positions were those of the last, whichever was meant."""
    from mpz.io.bvh import parse_bvh
    text = two_joint_bvh.replace(old, old + old.replace("10", "99"), 1)
    assert text.count("OFFSET") == 4
    second = _line_holding(text, "99")
    with pytest.raises(InputFormatError, match=re.escape(f"BVH: line {second}: {said}")):
        parse_bvh(text)


def _line_holding(text: str, word: str, nth: int = 1) -> int:
    """The line number (from 1) of the ``nth`` line of ``text`` that holds ``word``."""
    return [i for i, ln in enumerate(text.split("\n"), 1) if word in ln][nth - 1]


@pytest.mark.parametrize("brk", ["\x85", "\x0b", "\x0c", "\x1c", "\u2028"])
def test_asf_and_amc_lines_end_at_line_ends_only(tmp_path, brk):
    """str.splitlines also broke lines at U+0085 (byte 0x85, cp1252's ellipsis, read as
    Latin-1), U+2028, form feeds ...: an AMC whose comment held one was refused ("line 2:
    data before the first frame number"), and an ASF comment or documentation line lost its
    tail or was cut in two without a word. They are kept, and written back."""
    asf = ASF_TEXT.replace(":version", f"# made by{brk} a tool\n:version", 1)
    asf = asf.replace(":name", f":documentation\n  one{brk}line\n:name", 1)
    amc = AMC_TEXT.replace("\xe4\n", f"\xe4{brk}more\n", 1)
    enc = "latin-1" if brk <= "\xff" else "utf-8"
    (tmp_path / "tiny.asf").write_bytes(asf.encode(enc))
    (tmp_path / "tiny_01.amc").write_bytes(amc.encode(enc))
    skel = read(tmp_path / "tiny_01.amc").extras["skeleton"]
    assert skel.comments == f" tiny skeleton\n made by{brk} a tool"
    assert skel.documentation == f"one{brk}line"
    assert skel.amc_header.startswith(f"# comment with a latin-1 byte: \xe4{brk}more\n")
    write(read(tmp_path / "tiny_01.amc"), tmp_path / "w.amc")
    back = read(tmp_path / "w.amc").extras["skeleton"]
    assert (back.comments, back.documentation, back.amc_header) == \
        (skel.comments, skel.documentation, skel.amc_header)


@pytest.mark.parametrize("digits", [19, 5000])
def test_an_amc_frame_number_of_many_digits_is_named(tmp_path, digits):
    """A frame number of 5000 digits was "cannot read: ValueError: Exceeds the limit (4300
    digits) for integer string conversion ... use sys.set_int_max_str_digits()": the
    reader's number, not the file's fault, said; one of 19 digits was read (and refused
    only by the encoder, §4.14.2 keeps a u32)."""
    (tmp_path / "tiny.asf").write_text(ASF_TEXT)
    (tmp_path / "tiny_01.amc").write_bytes(AMC_TEXT.replace("\n1\n", f"\n{'9' * digits}\n")
                                           .encode("latin-1"))
    with pytest.raises(InputFormatError, match=r"ASF/AMC: line 4: frame number: '9{19,24}'\.\.\. "
                                               r"is too large a number"):
        read(tmp_path / "tiny_01.amc")


def test_a_bvh_value_past_binary64_is_named_by_its_line(two_joint_bvh):
    """"1e400" is made of a plain number's characters: the one conversion of a piece of
    values took it as an infinity, refused later as "non-finite channel value", with no
    word or line to look at."""
    from mpz.io.bvh import parse_bvh
    with pytest.raises(InputFormatError, match=re.escape(
            "BVH: MOTION: '1e400' is not a finite number, line 20 (frame 2)")):
        parse_bvh(two_joint_bvh.replace("1 0 0 0 5 0 10", "1 0 0 0 1e400 0 10"))


@pytest.mark.parametrize("fmt", ["csv", "trc"])
def test_a_no_break_space_for_a_number_is_shown(fmt):
    """A field of a no-break space (U+00A0) alone was said as "'' is not a number"."""
    from mpz.io.table import parse_csv
    from mpz.io.trc import parse_trc
    if fmt == "csv":
        with pytest.raises(InputFormatError, match=re.escape("row 3: '\\xa0' is not a number")):
            parse_csv("frame,time,A_x,A_y,A_z\n0,0.0,1,2,3\n1,0.01,1,\xa0,3\n")
    else:
        with pytest.raises(InputFormatError, match=re.escape("line 6: '\\xa0' is not a number")):
            parse_trc(_short_row_trc(1, 2, values=3).replace("\t1\n", "\t\xa0\n"))


@pytest.mark.parametrize("ext", [".trc", ".csv", ".bvh", ".amc"])
@pytest.mark.parametrize("codec, name", [("utf-16", "UTF-16"), ("utf-32", "UTF-32")])
def test_a_utf16_text_file_is_told_so(tmp_path, two_joint_bvh, ext, codec, name):
    """Windows tools save "Unicode" text as UTF-16 with a BOM; read as Latin-1 each reader
    said its first line was not one, showing "got 'ÿþP\\x00a\\x00...'"."""
    text = {".trc": _short_row_trc(1, 2, values=3), ".csv": "frame,time,A_x,A_y,A_z\n",
            ".bvh": two_joint_bvh, ".amc": AMC_TEXT}[ext]
    (tmp_path / "tiny.asf").write_text(ASF_TEXT)
    (tmp_path / f"tiny_01{ext}").write_bytes(text.encode(codec))
    with pytest.raises(InputFormatError, match=f"tiny_01{ext}: the text is {name} "
                                               rf"\(it starts with a {name} byte order mark\)"):
        read(tmp_path / f"tiny_01{ext}")


@pytest.mark.parametrize("frame", ["\u0663", "\uff13", "3_0"])
def test_a_csv_frame_number_of_other_digits_is_no_frame_number(frame):
    """The frame column's numbers were read by float(): an Arabic-Indic or fullwidth 3, or
    3_0, became the first frame (3, 3, 30), and the warning blamed the next row."""
    from mpz.io.table import parse_csv
    m = parse_csv(f"frame,time,A_x,A_y,A_z\n{frame},0.0,1,2,3\n4,0.01,1,2,3\n")
    assert "csv.FirstFrame" not in m.metadata
    assert f"(row 2 has frame {frame!r})" in m.metadata["warning"]



def test_an_asf_bone_name_with_a_nul_is_refused_as_a_bvh_joint_name_is(one_bone_asf):
    """Spec §4.14.1: a name holds no U+0000. The BVH reader refused one; the ASF reader
    took it, and only the encoder refused it (a hostile-input QA run of stop 64)."""
    text = one_bone_asf().replace("name b1", "name b\x001").replace("root b1", "root b\x001")
    with pytest.raises(InputFormatError, match=r"bone name 'b\\x001' holds a NUL character"):
        parse_asf(text)
    assert parse_asf(one_bone_asf()).joints[1].name == "b1"


@pytest.mark.parametrize("block, what", [
    ("ROOT Hips", "joint 'Hips'"), ("JOINT Spine", "joint 'Spine'"),
    ("End Site", "the End Site of 'Spine'"),
])
def test_a_bvh_block_without_an_offset_is_refused_naming_its_lines(two_joint_bvh, block,
                                                                    what):
    """A block without an OFFSET line was read as OFFSET 0 0 0 without a word: the joint
    drawn at its parent's place, and written back with a line the file did not have. Every
    BVH description has the line in every ROOT, JOINT and End Site block; it is refused,
    naming the line of the '}' that closes the block and the line that opens it."""
    from mpz.io.bvh import parse_bvh
    lines = two_joint_bvh.split("\n")
    at = next(i for i, ln in enumerate(lines) if ln.strip() == block)
    assert lines[at + 1].strip() == "{" and lines[at + 2].strip().startswith("OFFSET")
    del lines[at + 2]
    # the '}' that closes the block: the first line after it that is '}' at its indent
    indent = lines[at][:len(lines[at]) - len(lines[at].lstrip())]
    end = next(i for i, ln in enumerate(lines[at + 1:], at + 2) if ln == indent + "}")
    with pytest.raises(InputFormatError, match=re.escape(
            f"BVH: line {end}: {what} (from line {at + 1}) has no OFFSET line")):
        parse_bvh("\n".join(lines))


@pytest.mark.parametrize("old, new, said", [
    # "End Sight" was read as an End Site; "End" alone took the '{' after it for "Site"
    ("End Site", "End Sight", "End followed by 'Sight', not 'Site'"),
    ("End Site", "End", "End followed by '{', not 'Site'"),
    # '{' was taken for the joint's name, and the refusal was of two OFFSET lines of 'Hips'
    ("JOINT Spine", "JOINT", "JOINT without a name (followed by '{')"),
    # "unexpected token 'Yrotation' in HIERARCHY", and "bad CHANNELS ... [..., 'End']"
    ("CHANNELS 3 Zrotation", "CHANNELS 2 Zrotation",
     "CHANNELS of joint 'Spine' says 2 but names 3: Zrotation Xrotation Yrotation"),
    ("CHANNELS 3 Zrotation", "CHANNELS 4 Zrotation",
     "CHANNELS of joint 'Spine' says 4 but names 3: Zrotation Xrotation Yrotation"),
    # "'CHANNELS' is not a number", and "unexpected token '7'"
    ("OFFSET 0 10 0\n    CHANNELS", "OFFSET 0 10\n    CHANNELS",
     "OFFSET of joint 'Spine' has 2 numbers, not 3"),
    ("OFFSET 0 10 0\n    CHANNELS", "OFFSET 0 10 0 7\n    CHANNELS",
     "OFFSET of joint 'Spine' has more than 3 numbers, not 3"),
])
def test_a_bvh_hierarchy_refusal_says_what_and_where(two_joint_bvh, old, new, said):
    """A QA run of the text readers: the hierarchy's refusals named no line, and these said
    something else than what is wrong (or, "End Sight", nothing). Each names the line of
    the word that starts what it refuses."""
    from mpz.io.bvh import parse_bvh
    assert two_joint_bvh.count(old) == 1
    text = two_joint_bvh.replace(old, new)
    line = _line_holding(text, new.split("\n")[0])
    with pytest.raises(InputFormatError, match=re.escape(f"BVH: line {line}: {said}")):
        parse_bvh(text)


@pytest.mark.parametrize("cut, said", [
    ("CHANNELS 3 Zrotation", "says 3 but the file ends after 1: Zrotation"),
    ("CHANNELS 3", "says 3 but the file ends after 0"),
])
def test_a_bvh_cut_inside_a_channels_list_is_refused(tmp_path, two_joint_bvh, cut, said):
    """A BVH that ends inside a CHANNELS list (a file cut short) raised an IndexError out
    of the reader (a fuzzing QA run of the text readers); it is refused naming the joint,
    the line and the channels that are there."""
    text = two_joint_bvh[:two_joint_bvh.index(cut) + len(cut)]
    line = _line_holding(text, cut)
    (tmp_path / "cut.bvh").write_text(text)
    with pytest.raises(InputFormatError, match=re.escape(
            f"BVH: line {line}: CHANNELS of joint 'Spine' {said}")):
        read(tmp_path / "cut.bvh")


def test_a_negative_asf_bone_length_flips_the_bone_and_is_said(tmp_path):
    """A negative ASF ``length`` was read without a word. The bone's end is at length x
    direction (Acclaim's length scales the direction), defined for any sign: the bone is
    flipped against its direction, kept as written, and a warning says so, which ``mpz
    encode`` prints (exit 1), the file keeps and ``mpz decode`` notes."""
    (tmp_path / "tiny.asf").write_text(ASF_TEXT.replace("length 2\n", "length -2\n"))
    (tmp_path / "tiny_01.amc").write_bytes(AMC_TEXT.encode("latin-1"))
    m = read(tmp_path / "tiny_01.amc")
    mm = 25.4 / 0.45
    # frame 1 (see test_amc_forward_kinematics): W = Rz90 for b1 and b2; b1's end is
    # (1,2,3) + Rz90 (-2,0,0) = (1,0,3), and b2's (1,0,3) + Rz90 (0,1,0) = (0,0,3)
    np.testing.assert_allclose(m.positions[0] / mm, [[1, 2, 3], [1, 0, 3], [0, 0, 3]],
                               atol=1e-12)
    assert m.extras["skeleton"].joints[1].length == -2.0
    assert "the ASF gives bone 'b1' (-2) a negative length" in m.metadata["warning"]
    (tmp_path / "tiny.asf").write_text(ASF_TEXT)                # the file as it was: no word
    assert "warning" not in read(tmp_path / "tiny_01.amc").metadata
    (tmp_path / "tiny.asf").write_text(ASF_TEXT.replace("length 2\n", "length -2\n"))
    import subprocess
    import sys
    run = [sys.executable, "-m", "mpz.tools.mpz_cli"]
    enc = subprocess.run(run + ["encode", "tiny_01.amc", "-o", "t.mpz"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=300)
    assert enc.returncode == 1, enc.stderr
    assert "warning: tiny_01.amc: the ASF gives bone 'b1' (-2) a negative length" in enc.stderr
    dec = subprocess.run(run + ["decode", "t.mpz", "-o", "back.amc", "--asf", "back.asf"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert dec.returncode == 0, dec.stderr
    assert "read with a warning when it was encoded" in dec.stderr
    assert "bone 'b1' (-2) a negative length" in dec.stderr
    assert "length -2\n" in (tmp_path / "back.asf").read_text()


@pytest.mark.parametrize("name, amc, line, said", [
    # the bone's line in the middle of frame 1, then frame 2: "frame 12 follows frame 1"
    ("12", "1\nR\n12\n2\nR\n12\n", 3, "line 3: frame 12 follows frame 1; "),
    # read as frame 2, and the real frame 2 after it: "frame 2 follows frame 2"
    ("2", "1\nR\n2\n2\nR\n2\n", 3, "line 4: frame 2 follows frame 2; "),
    # first in its frame: frame 1 ended without its root line
    ("2", "1\n2\nR\n", 2, "frame 1 (from line 1) has no line for root: every frame "
     "needs one for the root and each bone with dofs; "),
    # the last line of the file: a last frame 2 without a root line
    ("2", "1\nR\n2\n", 3, "frame 2 (from line 3, the last frame) has no line for root: "
     "every frame needs one for the root and each bone with dofs; "),
])
def test_an_amc_line_of_a_bone_named_by_digits_is_told_from_a_frame_number(
        one_bone_asf, name, amc, line, said):
    """A lone whole number is an AMC frame number, and a bone's line its name and values:
    the name alone for a bone without dofs, so that line of a bone named "12" was read as
    a frame number, and the refusal spoke of frames only. It says which line was both; the
    ASF is read, and an AMC that leaves the bone out (as CMU's leave out every bone without
    dofs) reads as before."""
    from mpz.io.amc import parse_amc
    asf = parse_asf(one_bone_asf().replace("name b1", f"name {name}")
                    .replace("root b1", f"root {name}").replace("    dof rx rz\n", ""))
    text = amc.replace("R\n", "root 1 2 3 0 0 0\n")
    assert text.split("\n")[line - 1] == name
    with pytest.raises(InputFormatError, match=re.escape(
            f"ASF/AMC: {said}line {line} ({name!r}) was read as a frame number, and it is also "
            f"the line of bone {name!r}, which has no dofs: a lone whole number is a frame "
            "number, so an AMC cannot hold that bone's line")):
        parse_amc(text, asf)
    m = parse_amc("1\nroot 1 2 3 0 0 0\n2\nroot 1 2 3 0 0 0\n", asf)   # the bone left out
    assert m.names == ["root", name] and m.n_frames == 2 and "warning" not in m.metadata


@pytest.mark.parametrize("where, old, new, said", [
    ("asf", "length 2\n", "length (2)\n", "length of bone 'b1': '(2)' is not a number"),
    ("asf", "direction 1 0 0", "direction (1 0 0)", "direction of b1: '(1' is not a number"),
    ("asf", "position 0 0 0", "position (0 0 0)", "root position: '(0' is not a number"),
    ("amc", "b1 0 90", "b1 (0) 90", "line 6: b1: '(0)' is not a number"),
])
def test_asf_and_amc_numbers_in_parentheses_are_refused_saying_why(tmp_path, where, old, new,
                                                                     said):
    """A QA run of the text readers asked what of parentheses outside ``limits`` was
    refused. Written here: a number in parentheses anywhere else (no writer puts them
    there; the Acclaim definition has them around limits pairs only) is refused, and the
    refusal now says where parentheses belong (it said only "'(2)' is not a number")."""
    asf, amc = ASF_TEXT, AMC_TEXT
    if where == "asf":
        assert asf.count(old) == 1
        asf = asf.replace(old, new)
    else:
        assert amc.count(old) == 1
        amc = amc.replace(old, new)
    (tmp_path / "tiny.asf").write_text(asf)
    (tmp_path / "tiny_01.amc").write_bytes(amc.encode("latin-1"))
    with pytest.raises(InputFormatError, match=re.escape(
            f"{said}; parentheses enclose only the (lo hi) pairs of an ASF's limits, and a "
            "comment after '#' may hold any")):
        read(tmp_path / "tiny_01.amc")


def test_asf_limits_of_one_number_say_a_limit_is_a_pair():
    """``limits (1.0)`` was "bad limits of b2: '(1.0)'", which said nothing of what is bad."""
    with pytest.raises(InputFormatError, match=re.escape(
            "bad limits of b2: '(1.0)': each limit is a pair of two numbers (lo hi)")):
        parse_asf(ASF_TEXT.replace("limits (-180 180)\n  end", "limits (1.0)\n  end"))


def test_asf_and_amc_parentheses_in_comments_names_and_text_are_read(tmp_path):
    """Parentheses where they are text (a comment, :name, :documentation, a bone's name) or
    limits pairs (also ``limits(-180 180)`` without a blank, whose limits were not kept, said
    as a dropped key "limits(-180") read as without them."""
    plain = read_amc_pair(tmp_path / "a", ASF_TEXT, AMC_TEXT)
    asf = (ASF_TEXT.replace(":name TINY", ":name TINY (v2)")
           .replace(":units", ":documentation\n  made (by hand)\n:units")
           .replace("dof rx rz", "dof rx rz   # (x and z)")
           .replace("    limits (-180 180)\n  end", "    limits(-180 180)\n  end")
           .replace("name b2", "name b(2)").replace("b1 b2", "b1 b(2)"))
    amc = (AMC_TEXT.replace("b2 0\n", "b(2) 0\n")
           .replace("b1 0 90", "b1 0 90  # (a comment)"))
    m = read_amc_pair(tmp_path / "b", asf, amc)
    np.testing.assert_array_equal(m.positions, plain.positions)
    np.testing.assert_array_equal(m.angles, plain.angles)
    skel = m.extras["skeleton"]
    assert skel.name == "TINY (v2)" and skel.documentation == "made (by hand)"
    assert m.names == ["root", "b1", "b(2)"]
    assert [j.limits for j in skel.joints] == [j.limits for j in plain.extras["skeleton"].joints]
    assert skel.joints[2].limits == ((-180.0, 180.0),)
    assert "asf_dropped" not in m.metadata or "limits" not in m.metadata["asf_dropped"]


def read_amc_pair(folder, asf: str, amc: str) -> Motion:
    """The motion of ``amc`` with its skeleton ``asf``, written into ``folder``."""
    folder.mkdir()
    (folder / "tiny.asf").write_text(asf)
    (folder / "tiny_01.amc").write_bytes(amc.encode("latin-1"))
    return read(folder / "tiny_01.amc")


@pytest.mark.parametrize("old, new, said", [
    ("direction 1 0 0", "direction 1 0 0 5", "bone b1: direction values after the third (5)"),
    ("length 2\n", "length 2 3\n", "bone b1: length values after the first (3)"),
    ("axis 0 0 90 XYZ", "axis 0 0 90 XYZ 7", "bone b1: axis values after the fourth (7)"),
    ("position 0 0 0", "position 0 0 0 9", ":root position values after the third (9)"),
    ("orientation 0 0 0", "orientation 0 0 0 9",
     ":root orientation values after the third (9)"),
    ("   axis XYZ", "   axis XYZ ZYX", ":root axis values after the first (ZYX)"),
    ("length 0.45", "length 0.45 7", ":units length values after the first (7)"),
    ("angle deg", "angle deg rad", ":units angle values after the first (rad)"),
    ("   position 0 0 0", "   position 5 5 5\n   position 0 0 0",
     "an earlier :root position line (the last is kept)"),
    ("  length 0.45", "  length 9\n  length 0.45",
     "an earlier :units length line (the last is kept)"),
    (":bonedata\n", ":bonedata\n  bodymass 3\n",
     "a :bonedata line outside begin ... end (bodymass 3)"),
    ("    b1 b2\n", "    b1 b2\n    b1 b2\n", ":hierarchy links b1 to b2 again"),
    ("name b2\n", "name b2 b3\n", "bone b2: name values after the first (b3)"),
    (":version 1.10\n", "x:version 1.10\n:version 1.10\n",
     "a line before the first keyword (x:version 1.10)"),
    # an unknown section is not written back at all: said once, as such, not as joined
    (":bonedata\n", ":skin\n  a\n:skin\n  b\n:bonedata\n", ":skin"),
    ("  end\n  begin\n     id 2", "  end\n:bonedata\n  begin\n     id 2",
     "a second :bonedata keyword (its lines are written back under the first)"),
    ("    b1 b2\n  end\n", "  end\n    b1 b2\n  end\n",
     "an end in :hierarchy outside begin ... end"),
    ("    b1 b2\n  end\n", "  end\n  begin\n    b1 b2\n  end\n",
     "a second begin in :hierarchy (written back as one begin ... end block)"),
    # before the block too, not only after it (a review of stop 67)
    (":hierarchy\n  begin\n", ":hierarchy\n  end\n  begin\n",
     "an end in :hierarchy outside begin ... end"),
])
def test_asf_words_not_read_are_said_as_not_kept(tmp_path, old, new, said):
    """A QA run of the text readers: words of an ASF that the reader does not read were
    lost without a word (a fourth direction value, a second length value, the first of
    two :root position lines, a line of :bonedata outside its blocks; a :hierarchy link
    given twice, a second begin ... end block of it, a section keyword given twice, a
    second word on a bone's name line: a round-trip QA run of stop 67),
    where a second id value was said. Each is now listed in ``asf_dropped`` and this
    read's not-kept list (``mpz encode`` prints it); the values read are those of the
    file without them."""
    from mpz.motion import READER_NOT_KEPT
    assert ASF_TEXT.count(old) == 1
    plain = read_amc_pair(tmp_path / "a", ASF_TEXT, AMC_TEXT)
    m = read_amc_pair(tmp_path / "b", ASF_TEXT.replace(old, new), AMC_TEXT)
    assert said in m.metadata["asf_dropped"].split("; ")
    assert said in m.extras[READER_NOT_KEPT][0]
    assert not any("written back under the first" in n and ":skin" in n
                   for n in m.metadata["asf_dropped"].split("; "))
    np.testing.assert_array_equal(m.positions, plain.positions)
    assert m.extras["skeleton"].joints == plain.extras["skeleton"].joints
    assert "asf_dropped" not in plain.metadata



@pytest.mark.parametrize("old, new", [
    ("Zrotation Xrotation Yrotation\n    End", "zrotation xrotation yrotation\n    End"),
    ("JOINT Spine", "joint Spine"),
    ("End Site", "END SITE"),
    ("MOTION\nFrames: 3\nFrame Time:", "motion\nframes: 3\nframe time:"),
])
def test_bvh_words_spelled_otherwise_are_said_as_not_kept(two_joint_bvh, old, new):
    """The BVH reader takes its keywords and channel names in any case, and the writer
    spells them its own way: ``xrotation`` came back as ``Xrotation`` without a word (a
    round-trip QA run). The reader lists them under ``extras["not_kept"]``, which ``mpz
    encode`` reports as dropped; a file spelled as written is listed under nothing."""
    from mpz.io.bvh import format_bvh, parse_bvh
    from mpz.motion import READER_NOT_KEPT
    assert READER_NOT_KEPT not in parse_bvh(two_joint_bvh).extras
    assert old in two_joint_bvh
    m = parse_bvh(two_joint_bvh.replace(old, new))
    said = m.extras[READER_NOT_KEPT][0]
    assert said.startswith("from the BVH: the spelling of ")
    assert new.split()[0] in said
    assert READER_NOT_KEPT not in parse_bvh(format_bvh(m)).extras


def test_a_bvh_joint_without_a_channels_line_is_said_as_not_kept(two_joint_bvh, tmp_path):
    """A JOINT without a CHANNELS line (none of its own) is written back with "CHANNELS
    0": the skeleton chunk holds each joint's channels, the same for both. It came back so
    without a word; the reader now lists it under ``extras["not_kept"]``, which ``mpz
    encode`` reports, and the file as written back lists nothing."""
    from mpz.io.bvh import format_bvh, parse_bvh
    from mpz.motion import READER_NOT_KEPT
    text = two_joint_bvh.replace("    CHANNELS 3 Zrotation Xrotation Yrotation\n", "")
    text = "\n".join(line.rsplit(" ", 3)[0] if line.startswith(("0 ", "1 ", "2 ")) else line
                     for line in text.split("\n"))          # the 3 Spine values go too
    m = parse_bvh(text)
    assert m.extras[READER_NOT_KEPT] == [
        "from the BVH: that 1 joint has no CHANNELS line (Spine): written back with "
        "CHANNELS 0"]
    back = format_bvh(m)
    assert "\n\t\tCHANNELS 0\n" in back
    assert READER_NOT_KEPT not in parse_bvh(back).extras
    assert READER_NOT_KEPT not in parse_bvh(text.replace(
        "    OFFSET 0 10 0\n", "    OFFSET 0 10 0\n    CHANNELS 0\n", 1)).extras


@pytest.mark.parametrize("old, new, said", [
    ("    End Site", "    JOINT Toe\n    End Site",
     "BVH: line 11: JOINT Toe (line 10) is not followed by '{' but by 'End'"),
    ("    OFFSET 0 10 0\n    CHANNELS", "    ROOT root\n    OFFSET 0 10 0\n    CHANNELS",
     "BVH: line 8: ROOT inside joint 'Spine' (from line 6): a ROOT opens a hierarchy"),
    ("  JOINT Spine\n  {", "  JOINT Spine\n  OFFSET 1 2 3\n  {",
     "BVH: line 7: JOINT Spine (line 6) is not followed by '{' but by 'OFFSET'"),
])
def test_a_bvh_joint_not_opened_by_a_brace_is_refused(two_joint_bvh, old, new, said):
    """A ROOT, JOINT or End Site not followed by ``{`` was replaced by the next one, and
    an OFFSET or CHANNELS after it went to the joint around it: ``ROOT root`` between a
    joint's ``{`` and its OFFSET was lost without a word, and a ROOT inside a block was
    read as a JOINT and written back as one (a round-trip QA run of mutated files)."""
    from mpz.io.bvh import parse_bvh
    assert old in two_joint_bvh
    with pytest.raises(InputFormatError) as err:
        parse_bvh(two_joint_bvh.replace(old, new, 1))
    assert str(err.value).startswith(said)


@pytest.mark.parametrize("old, new, said", [
    ("     length 2\n", "     LENGTH 2\n", "LENGTH"),
    (":units\n", ":UNITS\n", ":UNITS"),
    ("    dof rx rz", "    dof RX rz", "RX"),
    ("   order TX TY TZ RX RY RZ", "   order tx TY TZ RX RY RZ", "tx"),
    ("     axis 0 0 90 XYZ", "     axis 0 0 90 xyz", "xyz"),
    ("  angle deg", "  angle DEG", "DEG"),
])
def test_asf_keywords_spelled_otherwise_are_said_as_not_kept(tmp_path, old, new, said):
    """The ASF reader takes its keywords in any case, and the writer spells them its own
    way: ``LENGTH`` came back as ``length`` without a word (a round-trip QA run of mutated
    files). They are listed under ``extras["not_kept"]``, which ``mpz encode`` reports as
    dropped; the file as written lists nothing."""
    from mpz.motion import READER_NOT_KEPT
    (tmp_path / "tiny_01.amc").write_bytes(AMC_TEXT.encode("latin-1"))
    (tmp_path / "tiny.asf").write_text(ASF_TEXT)
    assert READER_NOT_KEPT not in read(tmp_path / "tiny_01.amc").extras
    assert old in ASF_TEXT
    (tmp_path / "tiny.asf").write_text(ASF_TEXT.replace(old, new, 1))
    m = read(tmp_path / "tiny_01.amc")
    assert f"the spelling of 1 keyword ({said}:" in m.extras[READER_NOT_KEPT][0]


def test_compare_says_what_the_sources_reader_does_not_keep(tmp_path, capsys):
    """`mpz compare SOURCE OUT.mpz` reads the source with the reader that encoded it, so
    what that reader does not keep (here an ASF's ``LENGTH``, written back ``length``) was
    on neither side: "same", exit 0, where `mpz encode` lists it as dropped (a round-trip
    QA run). It is said in a note, as `mpz encode` says it."""
    from mpz.tools import mpz_cli
    amc = tmp_path / "tiny_01.amc"
    amc.write_bytes(AMC_TEXT.encode("latin-1"))
    (tmp_path / "tiny.asf").write_text(ASF_TEXT)
    assert mpz_cli.main(["encode", str(amc), "-o", str(tmp_path / "a.mpz")]) == 0
    capsys.readouterr()
    assert mpz_cli.main(["compare", str(amc), str(tmp_path / "a.mpz")]) == 0
    assert "does not keep" not in capsys.readouterr().err
    (tmp_path / "tiny.asf").write_text(ASF_TEXT.replace("length", "LENGTH", 1))
    assert mpz_cli.main(["encode", str(amc), "-o", str(tmp_path / "b.mpz")]) == 1   # warned
    assert f"mpz encode: warning: {amc}: not kept: from the ASF: the spelling" in \
        capsys.readouterr().err
    assert mpz_cli.main(["compare", str(amc), str(tmp_path / "b.mpz")]) == 0
    err = capsys.readouterr().err
    assert f"mpz compare: note: {amc}: its reader does not keep from the ASF: the " \
        "spelling of 1 keyword (LENGTH:" in err and "(on neither side, so not compared)" \
        in err, err


def test_an_asf_begin_inside_an_open_bone_block(tmp_path):
    """A ``begin`` inside a bone's open block started a new bone, and the lines read of
    the open one were lost without a word (a round-trip QA run of mutated files): it is
    refused, naming the block; a ``begin`` twice at a block's start loses nothing but the
    word, which the read lists as not kept."""
    from mpz.motion import READER_NOT_KEPT
    (tmp_path / "tiny_01.amc").write_bytes(AMC_TEXT.encode("latin-1"))
    asf = tmp_path / "tiny.asf"
    asf.write_text(ASF_TEXT.replace("     id 2\n", "  begin\n     id 2\n", 1))
    assert "a second 'begin' of a :bonedata block" in read(
        tmp_path / "tiny_01.amc").extras[READER_NOT_KEPT][0]
    asf.write_text(ASF_TEXT.replace("     length 2\n", "     length 2\n  begin\n", 1))
    with pytest.raises(InputFormatError, match=re.escape(
            "'begin' inside block 1 of :bonedata (counted from 1, begin ... end; bone b1): "
            "its 'end' is missing")):
        read(tmp_path / "tiny_01.amc")


def test_a_trc_first_line_apart_by_blanks_keeps_its_fields(tmp_path):
    """A TRC whose first line's fields are apart by blanks, not tabs, read them as none:
    its type and file name were dropped without a word, and the TRC written back began
    with "PathFileType" alone (a round-trip QA run of mutated files). They are read as
    the fields they are (the file name with its blanks) and written back with tabs."""
    first = TRC_TEXT.split("\n", 1)[0]
    assert first.count("\t") >= 3
    spaced = " ".join(first.split("\t")[:3]) + " C:\\My Data\\walk.trc"
    (tmp_path / "a.trc").write_text(TRC_TEXT.replace(first, spaced, 1))
    m = read(tmp_path / "a.trc")
    assert m.metadata["trc.PathFileType"] == "\t".join(first.split("\t")[1:3])
    assert m.metadata["trc.FileName"] == "C:\\My Data\\walk.trc"
    write(m, tmp_path / "back.trc")
    assert (tmp_path / "back.trc").read_text().split("\n", 1)[0] == "\t".join(
        first.split("\t")[:3] + ["C:\\My Data\\walk.trc"])


@pytest.mark.parametrize("spelled", ["PathFileType\x80", "PathFileTypes", "PathFileType:",
                                     "PathFileType\xa0", "PathFileType\x0b"])
@pytest.mark.parametrize("apart", ["\t", " "])
def test_a_trc_first_line_keyword_spelled_otherwise_is_said(tmp_path, spelled, apart):
    """The reader takes any line 1 that starts with "PathFileType", and the writer writes
    that keyword: "PathFileType\x80 4 (X/Y/Z) ..." came back as "PathFileType" without a
    word (a round-trip QA run of mutated files, stop 67). It is now a warning; the rest
    of the line is read as before."""
    first = TRC_TEXT.split("\n", 1)[0]
    fields = first.split("\t")
    (tmp_path / "a.trc").write_text(TRC_TEXT.replace(
        first, apart.join([spelled] + fields[1:4]), 1), encoding="latin-1")
    m = read(tmp_path / "a.trc")
    assert f"line 1 begins with {spelled!r}: written back as 'PathFileType'" in \
        m.metadata["warning"].split("; ")
    assert m.metadata["trc.PathFileType"] == "\t".join(fields[1:3])
    from mpz.io.trc import parse_trc
    plain = parse_trc(TRC_TEXT)
    assert "warning" not in plain.metadata or "line 1" not in plain.metadata["warning"]
    np.testing.assert_array_equal(m.positions, plain.positions)



@pytest.mark.parametrize("frame_two", [
    "2\nroot 0 0 0 0 0 0\nb2 0\nb1 90 0\n",                 # another order
    "2\nroot 0 0 0 0 0 0\nb1 90 0\nb2 0\nb3\n",             # a bone without dofs, here only
])
def test_an_amc_frame_listed_otherwise_than_the_first_is_said(tmp_path, frame_two):
    """The writer writes every frame's bone lines in the first frame's order: a later frame
    in another order, or with a line for a bone without dofs that the first frame lacks,
    came back otherwise without a word (a round-trip QA run of mutated files, stop 67).
    The read says so in its not-kept list; the values are those of the file."""
    from mpz.motion import READER_NOT_KEPT
    asf = ASF_TEXT.replace("  end\n:hierarchy", "  end\n  begin\n     id 3\n     name b3\n"
                           "     direction 0 0 1\n     length 1\n     axis 0 0 0 XYZ\n"
                           "  end\n:hierarchy").replace("    b1 b2\n", "    b1 b2 b3\n")
    plain = read_amc_pair(tmp_path / "a", asf, AMC_TEXT)
    m = read_amc_pair(tmp_path / "b", asf, AMC_TEXT.replace(
        "2\nroot 0 0 0 0 0 0\nb1 90 0\nb2 0\n", frame_two))
    assert READER_NOT_KEPT not in plain.extras
    assert m.extras[READER_NOT_KEPT] == [
        "from the AMC: the bone lines of 1 frame as listed (other bones or another order "
        "than the first frame's; written back as the first frame lists them)"]
    np.testing.assert_array_equal(m.angles, plain.angles)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.one_of(st.floats(), st.integers(-10 ** 6, 10 ** 6).map(float),
                          st.sampled_from([0.0, -0.0, 10.0, 1e16, 1e-5, 2.5e-308])),
                max_size=12))
def test_a_row_of_numbers_is_each_number_as_num_writes_it(values):
    """nums (the BVH and AMC writers' rows, issue 15) is the space-joined num() of each
    value: the shortest text that reads back as the same binary64, no trailing ``.0``."""
    from mpz.io.bvh import num, nums
    assert nums(values) == " ".join(num(v) for v in values)
    assert [float(w) for w in nums(values).split()] == pytest.approx(values, nan_ok=True)


def test_amc_rows_keep_a_bone_name_with_braces(tmp_path):
    """The AMC writer fills a per-frame template of bone names: a name holding { or } is
    written as it is, and the file reads back with the same angles."""
    (tmp_path / "tiny.asf").write_text(ASF_TEXT.replace("b2", "b{2}"))
    (tmp_path / "tiny_01.amc").write_bytes(AMC_TEXT.replace("b2", "b{2}").encode("latin-1"))
    m = read(tmp_path / "tiny_01.amc")
    write(m, tmp_path / "out_01.amc")
    text = (tmp_path / "out_01.amc").read_text("latin-1")
    assert "\nb{2} 0\n" in text and "\nb1 0 90\n" in text and "\nroot 1 2 3 0 0 0\n" in text
    back = read_amc(tmp_path / "out_01.amc", tmp_path / "out_01.asf")
    np.testing.assert_array_equal(back.angles, m.angles)


_word = st.one_of(st.floats().map(repr), st.integers(-10 ** 20, 10 ** 20).map(str),
                  st.sampled_from(["", " 1.5", "1_000", "١٢", "inf", "-inf", "nan", "NaN",
                                   "1e400", "1.5\u00a0", "(2)", "0x10", "+.5", "-0"]),
                  st.text(max_size=4))


@settings(max_examples=400, deadline=None)
@given(st.lists(_word, max_size=8), st.booleans())
def test_a_list_of_numbers_reads_as_each_number_alone(words, gaps):
    """number_list (the AMC and TRC readers' rows, issue 15) gives what reading each word
    alone gives: the same values, or the same refusal of the first bad word."""
    from mpz.io._common import number, number_list

    def one(w):
        return number(w, nan=gaps)

    def outcome(f):
        try:
            return [repr(v) for v in f()]
        except InputFormatError as exc:
            return exc.message
    assert outcome(lambda: number_list(words, one)) == outcome(lambda: [one(w) for w in words])
