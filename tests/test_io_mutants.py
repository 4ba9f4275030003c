"""mpz.io readers and writers against the formats' own definitions (mutation audit, stop 46).

Each test here kills a mutant of mpz.io that the other tests let through (the table is
in the audit's report). Expected values come from the file formats (the TRC header
fields, the C3D user guide's words and parameters, the BVH and ASF/AMC text), from the
real recordings' own text and from ezc3d, never from the code under test. Real
recordings come from ../shared/data and the tests that need them skip when it is absent.
"""
from __future__ import annotations

from dataclasses import replace
import math
from pathlib import Path

from hypothesis import example, given, settings
from hypothesis import strategies as st
import numpy as np
import pytest

import mpz
from mpz import Motion
from mpz.io import read_trc
from mpz.io.trc import format_trc, parse_trc

WALK = "trc/opensim_subject01_walk1.trc"


def _table(text: str) -> list[list[str]]:
    """The data rows of TRC text, each split at tabs (the rows after the 5 header lines
    and the optional blank line)."""
    return [ln.split("\t") for ln in text.splitlines()[5:] if ln.strip()]


def _header(text: str) -> dict[str, str]:
    """Line 2's keys with line 3's values, stripped (the TRC header fields)."""
    lines = text.splitlines()
    return {k.strip(): v.strip() for k, v in zip(lines[1].split("\t"), lines[2].split("\t"),
                                                  strict=False) if k.strip()}


SMALL = ("PathFileType\t4\t(X/Y/Z)\tsmall.trc\n"
         "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t"
         "OrigDataStartFrame\tOrigNumFrames\n"
         "60.00\t60.00\t4\t2\tmm\t60.00\t1\t4\n"
         "Frame#\tTime\tA\t\t\tB\t\t\n"
         "\t\tX1\tY1\tZ1\tX2\tY2\tZ2\n"
         "\n"
         "1\t0.000\t1.5\t2.5\t3.5\t4.0\t5.0\t6.0\n"
         "2\t0.017\t1.6\t2.6\t3.6\t\t\t\n"
         "3\t0.033\t1.7\t2.7\t3.7\t4.2\t5.2\t6.2\n"
         "4\t0.050\t1.8\t2.8\t3.8\t4.3\t5.3\t6.3\n")


# -- TRC ---------------------------------------------------------------------------------
def test_trc_time_column_written_back_as_the_file_has_it(shared_data: Path) -> None:
    """A TRC read and written again has the source's time column, field for field: the
    file's own text is the expected value (its last time, 2.500000, has one significant
    decimal; the others three)."""
    text = (shared_data / WALK).read_text()
    back = format_trc(parse_trc(text))
    src = [row[1].strip() for row in _table(text)]
    got = [row[1].strip() for row in _table(back)]
    assert got == src


def test_trc_written_after_a_rate_change_says_the_new_rate() -> None:
    """DataRate is the rate of the rows (the TRC header): a motion read at 60 Hz and
    given 120 Hz must not be written with the source's 60.00."""
    m = parse_trc(SMALL)
    faster = replace(m, rate=120.0)
    text = format_trc(faster)
    assert float(_header(text)["DataRate"]) == 120.0
    assert parse_trc(text).rate == 120.0


def test_trc_written_after_a_cut_says_its_frame_count() -> None:
    """NumFrames counts the rows: 2 frames cut from 4 are written as NumFrames 2."""
    m = parse_trc(SMALL).select_frames(1, 3)
    text = format_trc(m)
    assert _header(text)["NumFrames"] == "2"
    assert len(_table(text)) == 2
    assert "warning" not in parse_trc(text).metadata


@pytest.mark.parametrize("rate", ["1e-320", "5e-324", "1e-308"])
def test_trc_data_rate_whose_frame_times_overflow_is_refused(rate: str) -> None:
    """A subnormal DataRate made numpy warn of an overflow on stderr and `mpz show` print
    a duration of "inf s" (a fuzzing QA run of stop 54); the TRC writer refuses such a
    rate, so the reader does too, naming it."""
    import warnings

    from mpz.errors import InputFormatError
    text = SMALL.replace("60.00\t60.00\t4", f"{rate}\t60.00\t4", 1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(InputFormatError, match=f"DataRate {float(rate)!r} is too small"):
            parse_trc(text)
    assert parse_trc(SMALL.replace("60.00\t60.00\t4", "1e-300\t60.00\t4", 1)).n_frames == 4
    # one frame has the one time 0: written by the TRC writer, so read (a review of stop 54)
    one = Motion(np.ones((1, 2, 3)), ["a", "b"], float(rate), "mm")
    assert parse_trc(format_trc(one)).rate == float(rate)


def test_a_cut_is_written_with_the_source_frame_numbers_and_times() -> None:
    """select_frames(1, 3) of a TRC holds its frames 2-3: they were written as frames 1-2
    from time 0 (a QA run of the API, stop 54); the rows now come back as the source had
    them, and so do a CSV's times."""
    from mpz.io.table import format_csv, parse_csv
    cut = parse_trc(SMALL).select_frames(1, 3)
    assert _table(format_trc(cut)) == _table(SMALL)[1:3]
    csv = parse_csv(format_csv(parse_trc(SMALL)))
    rows = format_csv(csv.select_frames(2, None)).splitlines()[1:]
    assert rows == format_csv(csv).splitlines()[3:]
    assert parse_trc(SMALL).select_frames(0, 2).metadata == parse_trc(SMALL).metadata


def test_trc_with_a_byte_order_mark_reads_as_without(tmp_path: Path) -> None:
    """A UTF-8 TRC that starts with a BOM (Windows editors write one) is the same file."""
    plain, bom = tmp_path / "plain.trc", tmp_path / "bom.trc"
    plain.write_bytes(SMALL.encode())
    bom.write_bytes(b"\xef\xbb\xbf" + SMALL.encode())
    a, b = read_trc(plain), read_trc(bom)
    assert b.names == ["A", "B"] and b.rate == 60.0 and b.units == "mm"
    np.testing.assert_array_equal(a.valid, b.valid)
    np.testing.assert_array_equal(a.as_nan(), b.as_nan())
    assert not b.valid[1, 1] and b.valid[1, 0]          # the empty fields of row 2



@pytest.mark.parametrize(("written", "units"), [("MM", "mm"), (" Cm ", "cm"), ("Inches", "in"),
                                                ("M", "m"), ("mms", "")])
def test_trc_units_match_whatever_their_case(written: str, units: str) -> None:
    """docs/io-notes.md, TRC: the Units field is matched without regard to case or the
    blanks around it (writers differ: "mm", "MM"); a word it does not know is no unit."""
    m = parse_trc(SMALL.replace("\t60.00\t4\t2\tmm\t", f"\t60.00\t4\t2\t{written}\t"))
    assert m.units == units


@pytest.mark.parametrize(("first", "rate", "start"), [(50, 120.0, None), (1368, 120.0, None),
                                                      (1, 60.0, 0.25)])
def test_trc_time_column_written_again_is_the_same(first: int, rate: float,
                                                   start: float | None) -> None:
    """A trimmed trial's Time column (frame n at (n - 1) / rate, 6 decimals) is written back
    as it was, again and again (a QA run of stop 47: each write counted from the rounded
    first time, and 0.408333 + 1/120 printed 0.416666 where the file had 0.416667, on a
    third of the rows). A column that starts elsewhere (0.25 s at frame 1) keeps its start
    and its step."""
    n = 400
    t0 = (first - 1) / rate if start is None else start
    times = [f"{t0 + i / rate:.6f}" for i in range(n)]
    rows = "".join(f"{first + i}\t{times[i]}\t1.000\t2.000\t3.000\n" for i in range(n))
    text = ("PathFileType\t4\t(X/Y/Z)\tt.trc\n"
            "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t"
            "OrigDataStartFrame\tOrigNumFrames\n"
            f"{rate:.2f}\t{rate:.2f}\t{n}\t1\tmm\t{rate:.2f}\t{first}\t{n}\n"
            "Frame#\tTime\tA\t\t\n\t\tX1\tY1\tZ1\n\n" + rows)
    once = format_trc(parse_trc(text))
    twice = format_trc(parse_trc(once))
    for written in (once, twice):
        assert [r[1] for r in _table(written)] == times
        assert [r[0] for r in _table(written)] == [str(first + i) for i in range(n)]


def test_trc_of_a_motion_from_elsewhere_counts_from_frame_1_at_time_0() -> None:
    """format_trc without a TRC source: frames from 1, times from 0 (its docstring), one
    frame every 1 / rate."""
    m = Motion(np.ones((3, 1, 3)), ["A"], 4.0, "mm")
    rows = _table(format_trc(m))
    assert [r[0] for r in rows] == ["1", "2", "3"]
    assert [float(r[1]) for r in rows] == [0.0, 0.25, 0.5]


def test_trc_values_keep_the_most_decimals_of_the_first_row() -> None:
    """Values written back with as many decimals as the most precise of the source's first
    row (here 3), so that each reads back as the source's number."""
    text = SMALL.replace("1\t0.000\t1.5\t2.5\t3.5\t4.0\t5.0\t6.0",
                         "1\t0.000\t1.5\t2.25\t3.125\t4.0\t5.0\t6.0")
    m = parse_trc(text)
    back = parse_trc(format_trc(m))
    np.testing.assert_array_equal(back.positions[0, 0], [1.5, 2.25, 3.125])
    np.testing.assert_array_equal(back.as_nan(), m.as_nan())


def test_trc_decimals_are_the_most_of_any_row_not_of_the_first() -> None:
    """Times written by repr start at "0.0" and values at "10.5": the first row's decimals
    (1) were used for every row, so 0.016666... came back as 0.0 and later values lost
    their decimals, past a 0.01 mm bound (a text-formats QA run of stop 52). Exact
    round trip: every time and value reads back as the source's number."""
    rows = [f"{f + 1}\t{f / 60!r}\t{10.5 + f * 0.12345:.5f}\t20.25\t30.0" for f in range(6)]
    rows[0] = "1\t0.0\t10.5\t20.25\t30.0"
    text = ("PathFileType\t4\t(X/Y/Z)\tr.trc\nDataRate\tCameraRate\tNumFrames\tNumMarkers\t"
            "Units\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n"
            "60\t60\t6\t1\tmm\t60\t1\t6\nFrame#\tTime\tA\t\t\n\t\tX1\tY1\tZ1\n\n"
            + "\n".join(rows) + "\n")
    m = parse_trc(text)
    assert m.metadata["trc.Decimals"] == "5" and int(m.metadata["trc.TimeDecimals"]) >= 17
    again = format_trc(m)
    back = parse_trc(again)
    np.testing.assert_array_equal(back.as_nan(), m.as_nan())
    times = [float(line.split("\t")[1]) for line in again.splitlines()[6:]]
    assert times == [f / 60 for f in range(6)]


# -- NPY / CSV ---------------------------------------------------------------------------
def test_npy_sample_with_one_nan_coordinate_is_a_gap(tmp_path: Path) -> None:
    """NPY layout (mpz.io.table): NaN at gaps; a sample missing any of its three
    coordinates is a gap, and the other samples stay valid."""
    from mpz.io import read_npy
    arr = np.arange(2 * 3 * 3, dtype=np.float64).reshape(2, 3, 3)
    arr[1, 2, 1] = np.nan                       # only y of marker 2 at frame 1
    p = tmp_path / "one.npy"
    np.save(p, arr)
    m = read_npy(p, rate=50.0, units="mm")
    want = np.ones((2, 3), bool)
    want[1, 2] = False
    np.testing.assert_array_equal(m.valid, want)
    np.testing.assert_array_equal(m.positions[0], arr[0])
    assert m.rate == 50.0 and m.units == "mm"



def test_npy_units_argument_is_the_motions_unit(tmp_path: Path) -> None:
    """NPY stores no unit: read_npy takes it as an argument (mpz.io.table)."""
    from mpz.io import read_npy
    p = tmp_path / "u.npy"
    np.save(p, np.ones((2, 1, 3)))
    assert read_npy(p, units="m").units == "m"
    assert read_npy(p).units == ""


@pytest.mark.parametrize("rate", [65.0364227294921875, 127.05968475341797, 250.51327514648438,
                                  60.0033, 119.88, 29.97, 1000 / 7,
                                  100.0 / 3, 250.0, 0.1])
def test_csv_rate_survives_the_time_column_exactly(rate: float) -> None:
    """The CSV layout stores times as repr(frame / rate), so that the rate comes back
    exactly (mpz.io.table): the rate read back is the one written, bit for bit. Among the
    rates, float32 ones as C3D files store them (127.0597 Hz, 250.5133 Hz) whose
    1 / times[1] lands a few ulps above the rate, and 60.0033 Hz (c3d.org's arthuman)."""
    from mpz.io.table import format_csv, parse_csv
    m = Motion(np.ones((50, 1, 3)), ["A"], rate, "")
    assert parse_csv(format_csv(m)).rate == rate


# -- BVH ---------------------------------------------------------------------------------
FINE_BVH = """HIERARCHY
ROOT Hips
{
  OFFSET 0.123456789 10.5 -3.25
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Spine
  {
    OFFSET 0 10.000000125 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 5.5 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.0083333
1.2345678901 90.87654321 -3.000000004 12.3456789 -45.6789012 0.000123456789 1 2 3
-1.2345678901 91.87654321 3.000000004 -12.3456789 45.6789012 -0.000123456789 4 5 6
"""


def test_bvh_written_back_keeps_every_digit_of_its_values() -> None:
    """A BVH written from a BVH holds its numbers, not rounded ones: each value read
    back is the binary64 of the source's text (the digits above are more than float32
    or six significant digits hold)."""
    from mpz.io.bvh import format_bvh, parse_bvh
    back = parse_bvh(format_bvh(parse_bvh(FINE_BVH)))
    rows = FINE_BVH.split("Frame Time: 0.0083333\n", 1)[1].split("\n")
    want = np.array([[float(t) for t in ln.split()] for ln in rows if ln.strip()])
    assert back.angles is not None
    np.testing.assert_array_equal(back.angles, want)
    skel = back.extras["skeleton"]
    assert skel.joints[0].offset == (0.123456789, 10.5, -3.25)
    assert skel.joints[1].offset == (0.0, 10.000000125, 0.0)
    assert skel.frame_time == 0.0083333


# -- ASF / AMC ---------------------------------------------------------------------------
TINY_ASF = """:version 1.10
:name tiny
:units
  mass 1.0
  length 0.45
  angle rad
:documentation
   hand-made for the mutation audit
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name femur
     direction 0 -1 0
     length 10
     axis 0.5 0 0.25 XYZ
    dof rx ry rz
    limits (-1.5 1.5)
           (-0.5 0.75)
           (-1 1)
  end
:hierarchy
  begin
    root femur
  end
"""
TINY_AMC = """:FULLY-SPECIFIED
:RADIANS
5
root 1 2 3 0 0 0
femur 0.1 0.2 0.3
6
root 1 2 3 0.1 0 0
femur 0 0 0
"""
#: millimetres per ASF length unit: 1 / 0.45 inch (the ASF's ``:units length``)
MM = 25.4 / 0.45


def _rot(axis: str, a: float) -> np.ndarray:
    """The right-handed rotation by ``a`` radians about one principal axis."""
    c, s = np.cos(a), np.sin(a)
    return {"X": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
            "Y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
            "Z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])}[axis]


def _tiny() -> Motion:
    from mpz.io.amc import parse_amc, parse_asf
    return parse_amc(TINY_AMC, parse_asf(TINY_ASF))


def test_amc_joint_positions_by_hand() -> None:
    """The Acclaim convention (spec §6.10): ``W = C M C^-1`` with ``XYZ`` meaning X first
    (``Rz Ry Rx``), angles in the ASF's ``:units angle`` (rad here), lengths times
    25.4 / 0.45 mm. Frame 5 turns the femur, frame 6 the root."""
    m = _tiny()
    root = np.array([1.0, 2.0, 3.0]) * MM
    bone = np.array([0.0, -10.0, 0.0]) * MM
    C = _rot("Z", 0.25) @ _rot("Y", 0.0) @ _rot("X", 0.5)
    M = _rot("Z", 0.3) @ _rot("Y", 0.2) @ _rot("X", 0.1)
    want = np.array([[root, root + C @ M @ C.T @ bone],
                     [root, root + _rot("X", 0.1) @ bone]])
    assert m.names == ["root", "femur"] and m.units == "mm"
    np.testing.assert_allclose(m.positions, want, rtol=0, atol=1e-9)


def test_amc_written_back_numbers_its_frames_from_the_source() -> None:
    """The AMC's frame numbers (5 and 6 here) come back as written, not renumbered
    from 1."""
    from mpz.io.amc import format_amc
    text = format_amc(_tiny())
    numbers = [ln.strip() for ln in text.splitlines() if ln.strip().isdigit()]
    assert numbers == ["5", "6"]


def test_asf_written_back_keeps_its_angle_unit_and_limits() -> None:
    """``:units angle rad`` and each dof's (lo hi) limits, in order, come back."""
    from mpz.io.amc import format_asf, parse_asf
    skel = parse_asf(format_asf(_tiny().extras["skeleton"]))
    assert skel.angle_unit == "rad"
    assert skel.joints[1].limits == ((-1.5, 1.5), (-0.5, 0.75), (-1.0, 1.0))
    assert skel.length == 0.45




def test_amc_metadata_says_millimetres_per_asf_unit() -> None:
    """:units length 0.45: one ASF unit is 1 / 0.45 inch, 25.4 / 0.45 mm."""
    assert float(_tiny().metadata["mm_per_unit"]) == pytest.approx(MM, rel=1e-15)


def test_amc_frame_numbers_must_follow_each_other() -> None:
    """Frame 5 then frame 7: a frame is missing, and the AMC is refused (parse_amc)."""
    from mpz.errors import InputFormatError
    from mpz.io.amc import parse_amc, parse_asf
    with pytest.raises(InputFormatError, match="frame 7"):
        parse_amc(TINY_AMC.replace("\n6\n", "\n7\n"), parse_asf(TINY_ASF))


def test_asf_root_axis_order_is_used() -> None:
    """The root's ``axis ZYX`` with an orientation on two axes: C = Rx Ry Rz (Z first),
    the root's rotation C M C^-1 (spec §6.10), M from the root's RX RY RZ values (X
    first: Rz Ry Rx). The femur (no dof turned) ends at root + W bone."""
    from mpz.io.amc import parse_amc, parse_asf
    asf = TINY_ASF.replace("   axis XYZ\n   position 0 0 0\n   orientation 0 0 0",
                           "   axis ZYX\n   position 0 0 0\n   orientation 0.3 0 0.2")
    amc = ":FULLY-SPECIFIED\n:RADIANS\n1\nroot 1 2 3 0.1 0.2 0\nfemur 0 0 0\n"
    m = parse_amc(amc, parse_asf(asf))
    C = _rot("X", 0.3) @ _rot("Y", 0.0) @ _rot("Z", 0.2)
    M = _rot("Z", 0.0) @ _rot("Y", 0.2) @ _rot("X", 0.1)
    root = np.array([1.0, 2.0, 3.0]) * MM
    want = root + C @ M @ C.T @ (np.array([0.0, -10.0, 0.0]) * MM)
    np.testing.assert_allclose(m.positions[0, 0], root, rtol=0, atol=1e-9)
    np.testing.assert_allclose(m.positions[0, 1], want, rtol=0, atol=1e-9)


# -- C3D ---------------------------------------------------------------------------------
def _ezc3d_file(path: Path, labels: list[str], frames: int = 3, rate: float = 100.0) -> None:
    """A float C3D written by ezc3d (an independent writer): point p at (p+1, 2p, 3) mm
    in every frame, residual 0."""
    import ezc3d
    c = ezc3d.c3d()
    P = len(labels)
    c["parameters"]["POINT"]["RATE"]["value"] = np.array([rate])
    c["parameters"]["POINT"]["LABELS"]["value"] = list(labels)
    c.add_parameter("POINT", "UNITS", ["mm"])
    pts = np.ones((4, P, frames))
    pts[0] = (np.arange(P) + 1.0)[:, None]
    pts[1] = (2.0 * np.arange(P))[:, None]
    pts[2] = 3.0
    c["data"]["points"] = pts
    c.write(str(path))


def test_c3d_of_more_than_255_points_names_them_from_labels2(tmp_path: Path) -> None:
    """The C3D user guide: POINT:LABELS holds 255 labels, LABELS2 the next 255 ... ezc3d
    writes 300 labels so; every point keeps its own name."""
    from mpz.io import read_c3d
    labels = [f"P{i}" for i in range(300)]
    _ezc3d_file(tmp_path / "many.c3d", labels)
    m = read_c3d(tmp_path / "many.c3d")
    assert m.names == labels
    np.testing.assert_array_equal(m.positions[0, :, 0], np.arange(300) + 1.0)


def test_c3d_labels_padded_with_nuls_are_the_labels(tmp_path: Path) -> None:
    """A C3D char field is padded with blanks or NULs (writers differ): a label "A" padded
    with NULs is "A", as ezc3d reads it."""
    import ezc3d

    from mpz.io import read_c3d
    src = tmp_path / "spaces.c3d"
    _ezc3d_file(src, ["A", "LONGNAME"])
    data = src.read_bytes()
    assert data.count(b"A       LONGNAME") == 1           # ezc3d pads with blanks
    nul = tmp_path / "nuls.c3d"
    nul.write_bytes(data.replace(b"A       LONGNAME", b"A" + b"\0" * 7 + b"LONGNAME"))
    want = [str(s).strip() for s in ezc3d.c3d(str(nul))["parameters"]["POINT"]["LABELS"]["value"]]
    assert want == ["A", "LONGNAME"]
    m = read_c3d(nul)
    assert m.names == want
    assert "renamed_points" not in m.metadata



def test_c3d_byte_parameter_reads_signed_as_ezc3d_reads_it(tmp_path: Path) -> None:
    """The C3D user guide's parameter type 1 is a one-byte integer; ezc3d reads it signed
    (0xFD is -3). The numpy reader (the files ezc3d refuses, MIPS files) reads the same
    bytes the same way: the audit's D3 (read as unsigned) gave 253 and 128."""
    import ezc3d

    from mpz.io.c3dbin import ParamRecord, build_c3d, parse_c3d, plain_parts
    head, records = plain_parts(["A", "B"], 100.0, "mm", 3)
    records += [ParamRecord(-4, False, b"TEST", b""),
                ParamRecord(4, False, b"BYTES", b"type 1", 1, (3,), bytes([0x05, 0xFD, 0x80]))]
    data = build_c3d(head, records, np.ones((3, 2, 3)), np.zeros((3, 2), np.float32),
                     np.zeros((3, 0), np.float32), float_storage=True, scale=1.0)
    (tmp_path / "bytes.c3d").write_bytes(data)
    by_ezc3d = ezc3d.c3d(str(tmp_path / "bytes.c3d"))["parameters"]["TEST"]["BYTES"]
    assert by_ezc3d["type"] == 1
    assert list(by_ezc3d["value"]) == [5, -3, -128]
    assert list(parse_c3d(data).params["TEST"]["BYTES"]) == [5, -3, -128]

def _both_readers(path: Path) -> list[Motion]:
    """The motion of the C3D file ``path`` by read_c3d (through ezc3d) and by the numpy
    reader (mpz.io.c3dbin: MIPS files and the files ezc3d refuses)."""
    from mpz.io import read_c3d
    from mpz.io.c3d import motion_from_c3d_bytes
    by_ezc3d = read_c3d(path)
    assert by_ezc3d.metadata["reader"] == "ezc3d"
    return [by_ezc3d, motion_from_c3d_bytes(path.read_bytes())]


@pytest.mark.parametrize(("written", "units"), [("MM", "mm"), ("Cm", "cm"), ("M", "m"),
                                                ("inch", "")])
def test_c3d_units_match_whatever_their_case(tmp_path: Path, written: str, units: str) -> None:
    """docs/io-notes.md, C3D: POINT:UNITS is matched without regard to case; a word it does
    not know is no unit and stays in metadata["units_in_file"]. Both readers alike."""
    import ezc3d
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = np.array([100.0])
    c["parameters"]["POINT"]["LABELS"]["value"] = ["A"]
    c.add_parameter("POINT", "UNITS", [written])
    c["data"]["points"] = np.ones((4, 1, 2))
    c.write(str(tmp_path / "u.c3d"))
    for m in _both_readers(tmp_path / "u.c3d"):
        assert m.units == units
        assert m.metadata.get("units_in_file") == (None if units else written)


def test_c3d_subject_is_every_name_of_subjects_names(tmp_path: Path) -> None:
    """docs/io-notes.md, C3D: metadata["subject"] is every non-blank entry of
    SUBJECTS:NAMES, in stored order, joined by ", " (a trial with two subjects names both).
    Both readers alike."""
    src = tmp_path / "two.c3d"
    _ezc3d_file(src, ["A"])
    import ezc3d
    c = ezc3d.c3d(str(src))
    c.add_parameter("SUBJECTS", "NAMES", ["Ann", "  ", "Bob"])
    c.write(str(src))
    for m in _both_readers(src):
        assert m.metadata["subject"] == "Ann, Bob"


def test_c3d_model_outputs_gaps_are_ezc3ds(shared_data: Path) -> None:
    """Model outputs (POINT:ANGLES, FORCES ...) of the Auckland file: valid where the
    fourth word (residual) is not negative, as ezc3d reads it: a residual of 0 is a valid
    sample (the C3D user guide: only a negative residual marks an invalid point)."""
    import ezc3d

    from mpz.io import read_c3d
    path = shared_data / "c3d/auckland_FMC_MH0222_BP06.c3d"
    m = read_c3d(path)
    a = m.extras["c3d"]
    c = ezc3d.c3d(str(path))
    res = np.asarray(c["data"]["meta_points"]["residuals"])[0].T          # [F, P]
    pts = np.asarray(c["data"]["points"])[:3].transpose(2, 1, 0)          # [F, P, 3]
    M = m.n_markers
    models = [(p, s - M) for p, s in enumerate(a.slots) if s >= M]
    assert len(models) == 36
    for p, j in models:
        want = (res[:, p] >= 0) & np.isfinite(pts[:, p]).all(axis=1)
        np.testing.assert_array_equal(a.model_valid[:, j], want)
        np.testing.assert_allclose(a.models[want, j], pts[want, p], rtol=1e-6, atol=1e-4)
    assert 0 < a.model_valid.mean() < 1


def _raw_words(data: bytes) -> tuple[np.ndarray, float]:
    """The x, y, z words of every point of an Intel C3D as stored (int16 or float32), and
    the header's scale, from the C3D user guide's layout alone (no reader): header word 2
    the points, word 3 the analog words a frame, words 4-5 the frame range, word 7 the
    scale (negative: float32), word 9 the data block."""
    head = np.frombuffer(data[:512], "<u2")
    P, A, first, last = int(head[1]), int(head[2]), int(head[3]), int(head[4])
    scale = float(np.frombuffer(data, "<f4", 1, 12)[0])
    start = (int(head[8]) - 1) * 512
    F = last - first + 1
    dtype = "<f4" if scale < 0 else "<i2"
    words = np.frombuffer(data, dtype, F * (4 * P + A), start).reshape(F, 4 * P + A)
    return words[:, :4 * P].reshape(F, P, 4)[:, :, :3], scale


def _raw_points(data: bytes) -> np.ndarray:
    """The x, y, z of every point of an Intel C3D (:func:`_raw_words`, times the scale
    for int16 storage)."""
    xyz, scale = _raw_words(data)
    return xyz.astype(np.float64) if scale < 0 else xyz.astype(np.float64) * scale


def test_c3d_written_with_its_archive_stores_zeros_at_gaps(shared_data: Path,
                                                           tmp_path: Path) -> None:
    """write_c3d (the archive's C3D): 0 at gaps, whatever a Motion holds under a gap (its
    contract: the position stored under a gap is ignored). A reader that goes by the
    coordinates alone (the (0, 0, 0) rule of Vicon-style exporters) must not see junk."""
    import ezc3d

    from mpz.io import read_c3d, write_c3d
    m = read_c3d(shared_data / "c3d/cmu_01_01.c3d")
    gaps = ~m.valid
    assert gaps.any()
    pos = m.positions.copy()
    pos[gaps] = 12345.0                             # junk under the gaps
    junk = replace(m, positions=pos)
    out = tmp_path / "out.c3d"
    write_c3d(junk, out)
    c = ezc3d.c3d(str(out))
    labels = [str(s).strip() for s in c["parameters"]["POINT"]["LABELS"]["value"]]
    cols = [labels.index(n) for n in m.names]
    raw = _raw_points(out.read_bytes())[:, cols]
    np.testing.assert_allclose(raw[m.valid], m.positions[m.valid], rtol=1e-6, atol=1e-3)
    at_gaps = raw[gaps]
    assert not (at_gaps == 12345.0).any()
    np.testing.assert_array_equal(at_gaps, 0.0)


def test_c3d_nan_residual_word_read_alike_by_both_readers(tmp_path: Path) -> None:
    """A float C3D whose fourth word is NaN at one sample (a damaged or hand-edited file):
    the numpy reader (mpz.io.c3dbin, used for the files ezc3d refuses) and read_c3d
    (through ezc3d) give the same valid mask for the same bytes (the numpy reader made it
    a gap, ezc3d reads the word as residual 0): the sample is kept, coordinates and all."""
    from mpz.io import read_c3d
    from mpz.io.c3d import motion_from_c3d_bytes
    src = tmp_path / "src.c3d"
    _ezc3d_file(src, ["A", "B"], frames=4)
    data = bytearray(src.read_bytes())
    head = np.frombuffer(bytes(data[:512]), "<u2")
    P, A, start = int(head[1]), int(head[2]), (int(head[8]) - 1) * 512
    assert np.frombuffer(bytes(data), "<f4", 1, 12)[0] < 0          # float storage
    f, p = 2, 1
    at = start + 4 * (f * (4 * P + A) + 4 * p + 3)                  # B's fourth word, frame 2
    data[at:at + 4] = np.array([np.nan], "<f4").tobytes()
    bad = tmp_path / "nan.c3d"
    bad.write_bytes(bytes(data))
    through_ezc3d = read_c3d(bad)
    assert through_ezc3d.metadata["reader"] == "ezc3d"
    assert np.isnan(through_ezc3d.extras["c3d"].words[f, p])       # the word is kept
    by_numpy = motion_from_c3d_bytes(bytes(data))
    np.testing.assert_array_equal(by_numpy.valid, through_ezc3d.valid)
    assert by_numpy.valid[f, p]                                      # kept, not a gap
    np.testing.assert_array_equal(by_numpy.positions[f, p], through_ezc3d.positions[f, p])


def test_c3d_of_100000_frames_counts_them_all(tmp_path: Path) -> None:
    """Past 65535 frames the C3D user guide puts the range in TRIAL:ACTUAL_START_FIELD and
    ACTUAL_END_FIELD, each two *unsigned* 16-bit words (low, high): frame 100000 is
    (34464, 1), whose low word read as a signed int16 is negative."""
    import ezc3d

    from mpz.io import read_c3d, write_c3d
    F = 100_000
    pos = np.zeros((F, 1, 3))
    pos[:, 0, 0] = np.arange(F) % 1000 + 1.0
    pos[:, 0, 1] = 2.0
    m = Motion(pos, ["A"], 100.0, "mm")
    out = tmp_path / "long.c3d"
    write_c3d(m, out)
    trial = ezc3d.c3d(str(out), ignore_bad_formatting=True)["parameters"]["TRIAL"]
    end = [int(v) & 0xFFFF for v in trial["ACTUAL_END_FIELD"]["value"]]
    assert end[0] + (end[1] << 16) == F and end[0] >= 1 << 15
    back = read_c3d(out)
    assert back.n_frames == F
    np.testing.assert_array_equal(back.positions[:, 0, 0], pos[:, 0, 0])


def test_c3d_int16_file_written_back_has_its_words(shared_data: Path, tmp_path: Path) -> None:
    """An int16 C3D (c3d.org's AlbertoINT, scale 0.3076) read and written again stores the
    same int16 coordinate words: each value is a multiple of the scale, and the writer
    must find that multiple again (the source file is the expected value)."""
    from mpz.io import read_c3d, write_c3d
    src = shared_data / "c3d/c3dorg_AlbertoINT.c3d"
    out = tmp_path / "out.c3d"
    write_c3d(read_c3d(src), out)
    a, sa = _raw_words(src.read_bytes())
    b, sb = _raw_words(out.read_bytes())
    assert sa > 0 and sb == sa                        # int16 storage, the same scale
    assert a.dtype == b.dtype == np.dtype("<i2")
    np.testing.assert_array_equal(b, a)


def test_c3d_of_a_trc_keeps_its_first_frame_number(tmp_path: Path) -> None:
    """A TRC whose Frame# starts at 5, written as C3D: header word 4 (the first frame, the
    C3D user guide) is 5, and reading the C3D back keeps the numbering."""
    from mpz.io import read_c3d, write_c3d
    text = SMALL
    for k in (4, 3, 2, 1):
        text = text.replace(f"\n{k}\t0.", f"\n{k + 4}\t0.")
    m = parse_trc(text)
    out = tmp_path / "five.c3d"
    write_c3d(m, out)
    head = np.frombuffer(out.read_bytes()[:512], "<u2")
    assert (int(head[3]), int(head[4])) == (5, 8)
    assert read_c3d(out).extras["c3d"].first_frame() == 5


def test_c3d_written_without_an_archive_names_300_points(tmp_path: Path) -> None:
    """Our own C3D writer (a motion numbered from frame 3, which ezc3d cannot write):
    labels 256 to 300 go to POINT:LABELS2 (the C3D user guide), and ezc3d reads every
    name back."""
    import ezc3d

    from mpz.io import write_c3d
    names = [f"M{i}" for i in range(300)]
    m = Motion(np.ones((2, 300, 3)), names, 50.0, "mm", metadata={"trc.FirstFrame": "3"})
    out = tmp_path / "many.c3d"
    write_c3d(m, out)
    point = ezc3d.c3d(str(out))["parameters"]["POINT"]
    got = [str(s).strip() for s in point["LABELS"]["value"]]
    got += [str(s).strip() for s in point["LABELS2"]["value"]]
    assert got == names


@given(st.binary(min_size=4, max_size=4))
@example(b"\xff\x7f\xff\xff")        # exponent 255: 1.70e38, read as NaN before
@example(b"\x80\x00\x00\x00")        # exponent 1: 2^-128, a float32 subnormal
@example(b"\x7f\x00\xff\xff")        # exponent 0, a fraction: a VAX (dirty) zero
@settings(max_examples=400, deadline=None)
def test_dec_floats_convert_exactly_above_2_to_the_minus_126(word):
    """A VAX F_floating word (high 16-bit word first) against its definition, computed in
    binary64: (-1)^s x 0.1f x 2^(e - 128). Exact for exponents 3-255 (the significands
    are the same, spec §4.13); exponent 255, 2^126 and above, came back inf or NaN (a C3D
    QA run of stop 52: 1.70e38 read as nan). Exponents 1-2 are rounded, and counted."""
    from mpz.io.c3dbin import _dec_to_ieee
    w = int.from_bytes(word[2:4] + word[0:2], "little")
    s, e, f = w >> 31, (w >> 23) & 0xFF, w & 0x7FFFFF
    got, rounded = _dec_to_ieee(word)
    assert rounded == (e in (1, 2))
    want = (-1.0) ** s * (0.5 + f / 2.0 ** 24) * 2.0 ** (e - 128)
    if e >= 3:
        assert float(got[0]) == want
    elif e:
        assert float(got[0]) == float(np.float32(want))          # rounded to nearest
    else:                                   # a VAX zero, whatever its fraction: +-0.0
        assert float(got[0]) == 0.0 and math.copysign(1.0, float(got[0])) == (-1.0) ** s


def test_trc_header_fields_past_the_standard_eight_come_back() -> None:
    """A Subject and a Comment column in the header, and an exporter's name after the file
    name on line 1, were dropped without a word (a text-formats QA run of stop 52), where
    the module promises that nothing of the header is lost."""
    text = SMALL.replace("small.trc\n", "small.trc\tExported by X\n").replace(
        "OrigNumFrames\n", "OrigNumFrames\tSubject\tComment\n").replace(
        "60.00\t1\t4\n", "60.00\t1\t4\tS01\tcalib 2\n")
    m = parse_trc(text)
    assert m.metadata["trc.MoreNames"] == "Subject\tComment"
    again = format_trc(m)
    assert again.splitlines()[:3] == text.splitlines()[:3]
    assert parse_trc(SMALL).metadata.keys().isdisjoint({"trc.MoreNames", "trc.MoreFileFields"})


def _csv(frames: list[str], times: list[str]) -> str:
    rows = [f"{f},{t},{1.5 + k},{2.5},{3.5}"
            for k, (f, t) in enumerate(zip(frames, times, strict=True))]
    return "frame,time,A_x,A_y,A_z\n" + "\n".join(rows) + "\n"


def test_csv_first_frame_and_time_come_back_and_nice_rates_are_found() -> None:
    """The frame column was not read, and times from 1.0 gave 99.99999999999991 Hz: frames
    100.. and times 1.0.. came back from 0, with nothing said; times printed to 6
    decimals at 60 Hz gave 59.99997 Hz (a text-formats QA run of stop 52)."""
    from mpz.io.table import format_csv, parse_csv
    m = parse_csv(_csv([str(100 + k) for k in range(30)], [f"{1 + k / 100:.2f}"
                                                            for k in range(30)]))
    assert m.rate == 100.0 and "warning" not in m.metadata
    again = format_csv(m).splitlines()
    assert again[1].startswith("100,1.0,") and again[30].startswith("129,1.29,")
    six = parse_csv(_csv([str(k) for k in range(41)], [f"{k / 60:.6f}" for k in range(41)]))
    assert six.rate == 60.0 and "warning" not in six.metadata
    exact = 65.0364227294921875
    assert parse_csv(_csv([str(k) for k in range(9)], [repr(k / exact) for k in range(9)])
                     ).rate == exact


def test_csv_times_or_frames_the_file_cannot_keep_are_a_warning() -> None:
    """Odd times 1 ms late at 100 Hz were read as 98.9 Hz without a word (the TRC reader
    warns of the same), and a frame column of "f0" was taken silently."""
    from mpz.io.table import parse_csv
    late = [f"{k / 100 + (0.001 if k % 2 else 0):.3f}" for k in range(10)]
    m = parse_csv(_csv([str(k) for k in range(10)], late))
    assert "the time column is not the first time plus frame / rate" in m.metadata["warning"]
    m = parse_csv(_csv(["f0", "f1", "f2"], ["0.0", "0.01", "0.02"]))
    assert "the frame column is not consecutive whole numbers (row 2 has frame 'f0')" in \
        m.metadata["warning"]
    assert "csv.FirstFrame" not in m.metadata


def test_trc_lines_end_at_line_ends_only_and_unit_words_are_read() -> None:
    """str.splitlines broke a header at U+2028 or U+0085 inside a marker name ("NumMarkers
    says 2, the name row has 1 names"), and Units "millimeters" was no unit, so the TRC
    could not be written back (a text-formats QA run of stop 52)."""
    for name in ("A\u2028x", "A\x85x", "A\x0cx"):
        text = SMALL.replace("\tA\t", f"\t{name}\t").replace("\tmm\t", "\tmillimeters\t")
        m = parse_trc(text)
        assert m.names == [name, "B"] and m.units == "mm" and m.n_frames == 4
        assert parse_trc(format_trc(m)).names == [name, "B"]
    assert parse_trc(SMALL.replace("\n", "\r")).n_frames == 4           # CR alone: still a line end


def test_a_csv_name_ending_in_a_space_is_written_back(tmp_path: Path) -> None:
    """"B _x" reads as marker "B ", and the writer refused it: only a leading space is lost
    in a CSV column name (a text-formats QA run of stop 52)."""
    from mpz.io import read, write
    from mpz.io.table import parse_csv
    m = parse_csv("frame,time,B _x,B _y,B _z\n0,0.0,1,2,3\n1,0.01,1,2,3\n")
    assert m.names == ["B "]
    write(m, tmp_path / "b.csv")
    assert read(tmp_path / "b.csv").names == ["B "]


def test_npy_samples_with_a_coordinate_nan_or_infinite_are_said(tmp_path: Path) -> None:
    """[nan, 10, 11] and [21, inf, 23] became gaps with exit 0 and nothing said, where the
    TRC reader warns of the coordinates a gap drops (a text-formats QA run of stop 52)."""
    from mpz.io import read_npy
    arr = np.arange(2 * 2 * 3, dtype=np.float64).reshape(2, 2, 3) + 1.0
    arr[0, 0, 0] = np.nan
    arr[1, 1, 1] = np.inf
    np.save(tmp_path / "p.npy", arr)
    m = read_npy(tmp_path / "p.npy")
    assert not m.valid[0, 0] and not m.valid[1, 1]
    assert "2 samples with a coordinate NaN or infinite" in m.metadata["warning"]
    np.save(tmp_path / "q.npy", np.where(np.isfinite(arr), arr, 0.0))
    assert "warning" not in read_npy(tmp_path / "q.npy").metadata


def test_trc_numframes_warning_counts_the_frames_when_frame_numbers_skip() -> None:
    """Frame# 1, 2, 4, 5 make 5 frames of 4 rows; with NumFrames 4 the warning said
    "NumFrames says 4, file has 4 rows", which reads as no disagreement at all."""
    text = (SMALL.replace("\n3\t0.033\t", "\n4\t0.050\t", 1)
            .replace("\n4\t0.050\t1.8", "\n5\t0.067\t1.8", 1))
    m = parse_trc(text)
    assert m.n_frames == 5
    assert "NumFrames says 4, file has 4 rows over 5 frames" in m.metadata["warning"]


def test_a_trc_unit_word_that_is_no_unit_is_named_in_the_bound_error(tmp_path: Path) -> None:
    """--max-error 1mm on a TRC whose Units say "unknown" was refused with "TRC stores
    none", which is not so: the field is there and holds no length unit."""
    import subprocess
    import sys
    (tmp_path / "u.trc").write_text(SMALL.replace("\tmm\t", "\tunknown\t"))
    run = subprocess.run([sys.executable, "-m", "mpz.tools.mpz_cli", "encode",
                          str(tmp_path / "u.trc"), "-o", str(tmp_path / "u.mpz"),
                          "--max-error", "1mm"], capture_output=True, text=True, timeout=300)
    assert run.returncode == 2
    assert "its units 'unknown' are not mm, cm, m or in" in run.stderr, run.stderr


def test_a_trc_whose_units_word_is_unknown_is_written_back_as_it_was(tmp_path: Path) -> None:
    """Units "unknown": encoded (no unit), and then refused when decoded to TRC as "TRC
    needs units ... (a BVH source?)" (a text-formats QA run of stop 52)."""
    import mpz
    from mpz.io import read, write
    (tmp_path / "u.trc").write_text(SMALL.replace("\tmm\t", "\tunknown\t"))
    m = read(tmp_path / "u.trc")
    assert m.units == "" and m.metadata["trc.Units"] == "unknown"
    write(mpz.decode(mpz.encode(m)), tmp_path / "back.trc")
    back = (tmp_path / "back.trc").read_text().splitlines()
    assert back[2].split("\t")[4] == "unknown"


def test_a_trc_without_a_file_name_is_written_back_without_one() -> None:
    """An empty file name on line 1 was replaced by the output's name, and mpz compare
    then reported the header changed (trc.FileName)."""
    m = parse_trc(SMALL.replace("\tsmall.trc\n", "\t\n"))
    assert m.metadata["trc.FileName"] == ""
    assert format_trc(m, file_name="out.trc").splitlines()[0] == "PathFileType\t4\t(X/Y/Z)\t"
    assert "small.trc" in format_trc(parse_trc(SMALL), file_name="out.trc").splitlines()[0]


def test_a_trc_count_written_as_a_float_is_written_back_as_it_was() -> None:
    """NumFrames "4.0" was rewritten "4", and mpz compare reported the header changed; a
    count that no longer holds is still corrected."""
    m = parse_trc(SMALL.replace("\t4\t2\tmm\t", "\t4.0\t2\tmm\t"))
    assert format_trc(m).splitlines()[2].split("\t")[2] == "4.0"
    fewer = Motion(m.positions[:3], m.names, m.rate, m.units, m.valid[:3], m.metadata)
    assert format_trc(fewer).splitlines()[2].split("\t")[2] == "3"


@pytest.mark.parametrize("rate, rows", [(120.0, 100), (120.0, 25), (59.94, 200)])
def test_csv_times_in_scientific_notation_give_their_rate(rate, rows) -> None:
    """numpy.savetxt's "%.6e" times added no decimals, so every time was allowed 0.5 s:
    120 Hz over 100 rows was refused as uneven at 100 Hz, 59.94 Hz read as 60 (the review
    of stop 52). Each time is allowed half a unit of its own last digit."""
    from mpz.io.table import parse_csv
    m = parse_csv(_csv([f"{k:.18e}" for k in range(rows)], [f"{k / rate:.6e}"
                                                             for k in range(rows)]))
    assert m.rate == pytest.approx(rate, rel=1e-6) and "warning" not in m.metadata


def test_csv_short_files_and_first_times_keep_their_exact_rate(tmp_path: Path) -> None:
    """A 2-frame motion at 494.12123170888594 Hz was written, read back as the rounder
    494.121231708886 (which gives its 2 times too), and so refused by the writer's check;
    that check took times from 0 where the writer writes them from the start time; a first
    frame past 2^31 dropped the start time with it (the review of stop 52)."""
    from mpz.io import read, write
    from mpz.io.table import format_csv, parse_csv
    r = 494.12123170888594
    m = Motion(np.zeros((2, 1, 3)), ["a"], r, "mm")
    write(m, tmp_path / "two.csv")
    assert read(tmp_path / "two.csv").rate == r
    late = parse_csv(_csv([str(k) for k in range(9)], [repr(1000 + k / 65.0364227294921875)
                                                        for k in range(9)]),
                     rate=65.0364227294921875)
    # times from 1000 s cannot give that rate back to the bit: refused, not changed
    with pytest.raises(mpz.MPZError, match="cannot give back the rate 65.036"):
        write(late, tmp_path / "late.csv")
    big = parse_csv(_csv([str(3_000_000_000 + k) for k in range(3)], ["2.5", "2.51", "2.52"]))
    assert format_csv(big).splitlines()[1].startswith("3000000000,2.5,")


def test_csv_frame_numbers_in_float_form_and_empty_fields_are_said_rightly() -> None:
    """savetxt writes frame 0 as 0.000000000000000000e+00: not "not consecutive whole
    numbers"; an empty field was called "NaN or infinite"."""
    from mpz.io.table import parse_csv
    m = parse_csv(_csv([f"{k:.18e}" for k in range(3)], ["0.0", "0.01", "0.02"]))
    assert "warning" not in m.metadata
    m = parse_csv("frame,time,A_x,A_y,A_z\n0,0.0,,2,3\n1,0.01,1,2,3\n")
    assert "1 sample with a coordinate empty or NaN" in m.metadata["warning"]


def test_trc_decimals_skip_mantissas_and_rows_without_values() -> None:
    """"1.5E-03" was counted as 1 decimal and written back as 0.0; "10." gave no
    decimals (written 10.000000); a row of a frame and a time alone scanned the time (the
    review of stop 52)."""
    sci = SMALL.replace("1\t0.000\t1.5\t2.5\t3.5\t4.0\t5.0\t6.0",
                        "1\t0.000\t1.5E-03\t2.5E-03\t-3.5e-04\t4.0\t5.0\t6.0")
    m = parse_trc(sci)
    back = parse_trc(format_trc(m))
    np.testing.assert_allclose(back.positions[0, 0], [1.5e-3, 2.5e-3, -3.5e-4], atol=1e-6)
    assert m.metadata["trc.Decimals"] == "5"              # -3.5e-04 is -0.00035
    dots = SMALL.replace("\t4.0\t5.0\t6.0\n", "\t4.\t5.\t6.\n").replace(
        "1.5\t2.5\t3.5", "1.\t2.\t3.").replace("1.6\t2.6\t3.6", "1.\t2.\t3.").replace(
        "1.7\t2.7\t3.7\t4.2\t5.2\t6.2", "1.\t2.\t3.\t4.\t5.\t6.").replace(
        "1.8\t2.8\t3.8\t4.3\t5.3\t6.3", "1.\t2.\t3.\t4.\t5.\t6.")
    assert parse_trc(dots).metadata["trc.Decimals"] == "0"


def test_trc_more_names_cannot_name_a_standard_field() -> None:
    """trc.MoreNames "DataRate" (meta is free text) wrote a second DataRate column, the one
    a reader takes: written at 60 Hz, read back at 999 (the review of stop 52)."""
    from mpz.io.trc import trc_meta_problems
    m = parse_trc(SMALL)
    m.metadata.update({"trc.MoreNames": "DataRate", "trc.MoreValues": "999"})
    assert trc_meta_problems(m.metadata)["trc.MoreNames"] == \
        "names a field the writer writes itself"
    assert parse_trc(format_trc(m)).rate == 60.0


def test_a_csv_first_frame_written_elsewhere_is_a_note(tmp_path: Path) -> None:
    """A CSV numbered from 100 decoded to TRC: mpz compare then found csv.FirstFrame
    missing, and the writer had said nothing (the review of stop 52)."""
    from mpz.io import writer_problems
    from mpz.io.table import parse_csv
    m = parse_csv(_csv(["100", "101", "102"], ["0.0", "0.01", "0.02"]))
    m.units = "mm"
    _, notes = writer_problems(m, ".trc")
    assert any("the first, '100', is not written" in n for n in notes)
    assert not any("CSV's frame numbers" in n for n in writer_problems(m, ".csv")[1])


# -- reader messages a CLI QA run of stop 54 found unclear --------------------------------
def test_a_csv_whose_lines_end_with_a_carriage_return_alone_is_read(tmp_path: Path) -> None:
    """The old Mac line end, a carriage return alone, which spreadsheets still write: the
    whole file reached csv.reader as one line ("new-line character seen in unquoted
    field"). Read as the same CSV with line feeds is read."""
    text = ("frame,time,A_x,A_y,A_z,B_x,B_y,B_z\n1,0,1.5,2,3,,,\n2,0.01,1,2,3.25,4,5,6\n"
            "3,0.02,1,2,3,4,5,6\n")
    (tmp_path / "lf.csv").write_bytes(text.encode())
    (tmp_path / "cr.csv").write_bytes(text.replace("\n", "\r").encode())
    lf, cr = mpz.io.read(tmp_path / "lf.csv"), mpz.io.read(tmp_path / "cr.csv")
    assert (cr.names, cr.rate, cr.n_frames) == (["A", "B"], 100.0, 3)
    assert (cr.names, cr.rate) == (lf.names, lf.rate)
    assert np.array_equal(cr.as_nan(), lf.as_nan(), equal_nan=True)
    assert cr.positions[0, 0].tolist() == [1.5, 2.0, 3.0] and not cr.valid[0, 1]


@pytest.mark.parametrize("times, row, said", [
    (["0", "0", "0.02"], 3, "row 3 has time 0.0, after 0.0 in row 2"),
    (["0", "0.01", "0.005"], 4, "row 4 has time 0.005, after 0.01 in row 3"),
])
def test_csv_times_that_do_not_increase_name_the_row(tmp_path: Path, times, row, said) -> None:
    """They gave "cannot read: ValueError: times do not increase", naming no row."""
    rows = "".join(f"{k + 1},{t},1,2,3\n" for k, t in enumerate(times))
    (tmp_path / "t.csv").write_text("frame,time,A_x,A_y,A_z\n" + rows)
    with pytest.raises(mpz.InputFormatError) as err:
        mpz.io.read(tmp_path / "t.csv")
    assert said in str(err.value) and "ValueError" not in str(err.value)
    assert mpz.io.read(tmp_path / "t.csv", rate=50.0).rate == 50.0     # the rate given


def _npy_with_header(path: Path, descr: str, shape: str, fortran: bool,
                     data: bytes) -> None:
    """An .npy file of version 1.0 with this header (the NPY format's own layout: magic,
    version, little-endian u16 header length, a dict literal padded to 64 bytes)."""
    import struct
    h = f"{{'descr': {descr}, 'fortran_order': {fortran}, 'shape': {shape}, }}"
    h += " " * ((64 - (10 + len(h) + 1) % 64) % 64) + "\n"
    path.write_bytes(b"\x93NUMPY\x01\x00" + struct.pack("<H", len(h)) + h.encode() + data)


def test_an_npy_whose_elements_are_triples_is_read_as_frames_markers_xyz(tmp_path: Path
                                                                         ) -> None:
    """A header of shape (F, M) whose descr is ('<f8', (3,)): each element holds x, y and
    z, so the array is (F, M, 3) of float64, in C order. It raised numpy's "cannot
    reshape array of size 24 into shape (4,2)". Fortran order of such elements is not
    defined by the format, and is refused by name."""
    xyz = np.arange(24, dtype="<f8").reshape(4, 2, 3) + 0.5
    _npy_with_header(tmp_path / "t.npy", "('<f8', (3,))", "(4, 2)", False, xyz.tobytes())
    m = mpz.io.read(tmp_path / "t.npy")
    assert (m.n_frames, m.n_markers) == (4, 2) and np.array_equal(m.positions, xyz)
    _npy_with_header(tmp_path / "f.npy", "('<f8', (3,))", "(4, 2)", True, xyz.tobytes())
    with pytest.raises(mpz.InputFormatError, match="Fortran-ordered array of .*not defined"):
        mpz.io.read(tmp_path / "f.npy")


def test_a_csv_with_mixed_line_ends_names_the_line(tmp_path: Path) -> None:
    """A carriage return alone inside a file of line-feed lines gave csv's raw "new-line
    character seen in unquoted field"; it now names the line (a review of stop 55)."""
    (tmp_path / "m.csv").write_bytes(b"frame,time,A_x,A_y,A_z\r\n1,0,1,2,3\r\n2,0.01,1,2,3\r"
                                     b"3,0.02,1,2,3\r\n")
    with pytest.raises(mpz.InputFormatError, match=r"csv: line 3: .*are the line ends mixed"):
        mpz.io.read(tmp_path / "m.csv")


def test_an_npy_sample_of_infinite_coordinates_is_a_gap_said_so(tmp_path: Path) -> None:
    """A sample whose three coordinates are infinite became a gap with no word, while one
    infinite coordinate beside finite ones was said (a corpus QA run of stop 55). NaN marks
    an NPY gap; an all-NaN sample is a gap and says nothing."""
    a = np.ones((4, 2, 3))
    a[1, 0] = np.inf
    a[2, 1] = [-np.inf, np.nan, np.inf]
    a[3, 0] = np.nan
    np.save(tmp_path / "a.npy", a)
    m = mpz.io.read(tmp_path / "a.npy")
    assert not m.valid[1, 0] and not m.valid[2, 1] and not m.valid[3, 0]
    assert ("2 samples with no finite coordinate and an infinite one (the first: frame index "
            "1, marker 'M0')") in m.metadata["warning"]
    b = np.ones((4, 2, 3))
    b[3, 0] = np.nan
    np.save(tmp_path / "b.npy", b)
    assert "warning" not in mpz.io.read(tmp_path / "b.npy").metadata
