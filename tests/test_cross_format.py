"""Writing a motion to another format than its source's: what comes along and what is said.

Found by the QA review of issue 15's stop 27: a C3D decoded to TRC or CSV lost its first
frame number (398 -> 1) without a word, the note named the internal key "c3d" instead of
what was dropped, a TRC with rows left out came back renumbered (its last frame 151 at
2.5 s became frame 101 at 1.667 s), and a BVH written as C3D got an empty POINT:UNITS
silently. Expected values come from how each input is built here, never from the writers.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import mpz
from mpz.io import read, write, writer_problems
from mpz.synth import generate
from mpz.tools.make_vectors import c3d_motion


def _trc(tmp_path: Path, frame_numbers: list[int], rate: float = 60.0) -> Path:
    """A two-marker TRC whose rows carry ``frame_numbers``; marker A at x = frame number."""
    lines = ["PathFileType\t4\t(X/Y/Z)\tt.trc",
             "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t"
             "OrigDataStartFrame\tOrigNumFrames",
             f"{rate}\t{rate}\t{len(frame_numbers)}\t2\tmm\t{rate}\t1\t{len(frame_numbers)}",
             "Frame#\tTime\tA\t\t\tB\t\t", "\t\tX1\tY1\tZ1\tX2\tY2\tZ2", ""]
    for f in frame_numbers:
        lines.append(f"{f}\t{(f - 1) / rate:.6f}\t{f}.0\t1.0\t2.0\t3.0\t4.0\t5.0")
    path = tmp_path / "t.trc"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_a_trc_with_rows_left_out_keeps_each_frames_time(tmp_path):
    keep = [f for f in range(1, 31) if f % 3 != 0]          # 20 rows, frames 1 .. 29
    m = read(_trc(tmp_path, keep))
    assert m.n_frames == 29
    assert np.array_equal(np.flatnonzero(m.valid[:, 0]) + 1, keep)
    assert np.array_equal(m.positions[m.valid[:, 0], 0, 0], keep)  # x = the frame number
    assert "skips 9 frames" in m.metadata["warning"]
    write(m, tmp_path / "back.trc")
    last = (tmp_path / "back.trc").read_text().splitlines()[-1].split("\t")
    assert last[0] == "29" and abs(float(last[1]) - 28 / 60.0) <= 5e-7     # 6 decimals


def test_a_frame_number_far_away_allocates_nothing(tmp_path):
    m = read(_trc(tmp_path, [1, 2, 3, 10 ** 9]))
    assert m.n_frames == 4                      # rows taken as they are, and said
    assert "not one number a row" in m.metadata["warning"]


def test_the_first_frame_number_goes_where_the_format_holds_it(tmp_path):
    m = read(_trc(tmp_path, list(range(100, 130))))
    write(m, tmp_path / "out.c3d")
    head = (tmp_path / "out.c3d").read_bytes()[:512]
    assert int.from_bytes(head[6:8], "little") == 100                     # word 4
    assert int.from_bytes(head[8:10], "little") == 129                    # word 5
    _, notes = writer_problems(m, ".npy")
    assert any("first frame number (100)" in n for n in notes)


def test_a_trcs_header_fields_written_elsewhere_are_said(tmp_path):
    """A TRC's header fields (trc.* metadata) have no place in C3D, CSV or NPY: before,
    decode said nothing of them (the 'free metadata' note leaves out dotted keys)."""
    m = read(_trc(tmp_path, list(range(1, 31))))
    fields = [k for k in m.metadata if k.startswith("trc.")]
    assert len(fields) >= 8
    for ext in (".c3d", ".csv", ".npy"):
        _, notes = writer_problems(m, ext)
        assert any(f"the {len(fields)} trc.* entries" in n for n in notes), (ext, notes)
    _, notes = writer_problems(m, ".trc")
    assert not any("trc.*" in n for n in notes)


def test_a_c3d_archive_written_as_trc_keeps_its_frame_numbers_and_says_what_it_drops(tmp_path):
    m = c3d_motion(7, storage=1, F=12, M=4, J=2, C=3, n=2)   # header first frame 10
    first = int.from_bytes(m.extras["c3d"].header[6:8], "little")
    assert first == 10
    back = mpz.decode(mpz.encode(m, max_error=1.0))
    write(back, tmp_path / "out.trc")
    lines = (tmp_path / "out.trc").read_text().splitlines()
    assert lines[2].split("\t")[6] == "10"                       # OrigDataStartFrame
    row = lines[6].split("\t")
    assert row[0] == "10" and abs(float(row[1]) - 9 / m.rate) <= 5e-7   # (n - 1) / rate
    _, notes = writer_problems(back, ".trc")
    said = " ".join(notes)
    assert "2 model outputs" in said and "3 analog channels at 2 samples a frame" in said
    assert "the parameter section" in said and "'c3d'" not in said


def test_a_motion_without_units_written_as_c3d_says_so():
    m = generate("walk", frames=4)
    m = mpz.Motion(m.positions, m.names, m.rate, "", m.valid)
    _, notes = writer_problems(m, ".c3d")
    assert any("no length unit" in n and "POINT:UNITS is left empty" in n for n in notes)


def test_a_subject_no_written_file_holds_is_said(tmp_path):
    """QA, stop 49: `--meta subject=Alice` decoded to C3D (no archive), TRC or CSV was
    dropped without a word, because subject is also a key the C3D reader sets. Only a C3D
    whose archive's SUBJECTS:NAMES gives the same subject holds it."""
    m = generate("walk", frames=4)
    m = mpz.Motion(m.positions, m.names, m.rate, "mm", m.valid, {"subject": "Alice"})
    for ext in (".c3d", ".trc", ".csv"):
        _, notes = writer_problems(m, ext)
        assert any("'subject'" in n and "not written" in n for n in notes), (ext, notes)


def test_a_subject_the_archive_holds_is_not_said_dropped(tmp_path):
    from mpz.io import c3dbin
    m = c3d_motion(7, storage=1, F=12, M=4, J=0, C=0, n=0)
    # SUBJECTS:NAMES as the reader takes it, checked on the archive's own records
    params = c3dbin.record_params(m.extras["c3d"].records)
    held = ", ".join(str(x).strip() for x in params.get("SUBJECTS", {}).get("NAMES", [])
                     if str(x).strip())
    meta = {**m.metadata, "subject": held} if held else {
        k: v for k, v in m.metadata.items() if k != "subject"}
    m = dataclasses.replace(m, metadata=meta)
    _, notes = writer_problems(m, ".c3d")
    assert not any("'subject'" in n for n in notes), notes
    other = dataclasses.replace(m, metadata={**meta, "subject": held + "Bob"})
    _, notes = writer_problems(other, ".c3d")
    assert any("'subject'" in n for n in notes), notes


def test_a_first_frame_c3d_cannot_number_is_said_and_written_from_1(tmp_path):
    """QA, stop 49: a TRC whose Frame# starts at 0 became a C3D whose header word 4 is 0
    (C3D counts from 1; ezc3d and mpz then numbered its frames differently), without a
    word; a negative first frame failed inside the writer after check_writable passed."""
    for first in (0, -5):
        m = read(_trc(tmp_path, list(range(first, first + 30))))
        refuse, notes = writer_problems(m, ".c3d")
        assert not refuse
        assert any(f"first frame {first}" in n and "from 1" in n for n in notes), notes
        write(m, tmp_path / "out.c3d")
        head = (tmp_path / "out.c3d").read_bytes()[:512]
        assert int.from_bytes(head[6:8], "little") == 1                   # word 4
        assert int.from_bytes(head[8:10], "little") == 30                 # word 5


def test_units_a_bvh_cannot_hold_are_said(tmp_path, two_joint_bvh):
    """QA, stop 49: a BVH encoded with --units cm and decoded to .bvh lost the unit
    without a note (CSV says so)."""
    (tmp_path / "t.bvh").write_text(two_joint_bvh)
    m = read(tmp_path / "t.bvh")
    assert m.units == ""
    _, notes = writer_problems(m, ".bvh")
    assert not any("units" in n for n in notes)
    _, notes = writer_problems(dataclasses.replace(m, units="cm"), ".bvh")
    assert any("BVH does not store units (cm)" in n for n in notes), notes


def test_c3d_names_past_the_parameter_blocks_a_header_counts(tmp_path):
    """A QA run of stop 50: 1000 names of 254 bytes written to .c3d with no note; ezc3d
    wrote the parameter block count modulo 256, and 490 names read back as _unnamed_*.
    Such names are refused; 300 of them (149 blocks) are written, by our writer, and read
    back whole, by ezc3d too."""
    import ezc3d

    import mpz
    from mpz.errors import InputFormatError
    import mpz.io
    rng = np.random.default_rng(0)

    def motion(n):
        return mpz.Motion(rng.normal(size=(2, n, 3)) * 100,
                          [f"{i:04d}" + "x" * 250 for i in range(n)], 100.0, "mm")
    with pytest.raises(InputFormatError, match="need a parameter section of 49[0-9] blocks"):
        mpz.io.write(motion(1000), tmp_path / "big.c3d")
    assert not (tmp_path / "big.c3d").exists()
    m = motion(300)
    assert [n[:41] for n in mpz.io.write(m, tmp_path / "ok.c3d")] == [
        "C3D stores points as float32: 600 of 600 "]
    back = mpz.io.read(tmp_path / "ok.c3d")
    assert back.names == m.names and back.metadata.get("warning") is None
    labels = ezc3d.c3d(str(tmp_path / "ok.c3d"))["parameters"]["POINT"]["LABELS"]["value"]
    labels += ezc3d.c3d(str(tmp_path / "ok.c3d"))["parameters"]["POINT"]["LABELS2"]["value"]
    assert [x.strip() for x in labels] == m.names


def test_writing_says_what_float32_and_decimals_round(tmp_path):
    """A QA run of stop 50: a float64 motion written to .c3d came back changed by up to
    1.2e-4 mm (amc/02_01) with no note, while check_writable noted the rate's float32
    rounding; the TRC writer's 6 decimals likewise. Values they hold exactly: no note."""
    base = np.arange(12.0).reshape(2, 2, 3)
    exact = mpz.Motion(base * 0.5, ["A", "B"], 100.0, "mm")
    assert write(exact, tmp_path / "e.c3d") == [] and write(exact, tmp_path / "e.trc") == []
    m = dataclasses.replace(exact, positions=base + 0.1234567891)
    notes = write(m, tmp_path / "m.c3d")
    assert len(notes) == 1 and notes[0].startswith(
        "C3D stores points as float32: 4 of 4 valid samples change, by up to "), notes
    back = read(tmp_path / "m.c3d")
    worst = float(np.sqrt(((back.positions - m.positions) ** 2).sum(axis=2)).max())
    assert f"by up to {worst:.2g} mm" in notes[0]
    notes = write(m, tmp_path / "m.trc")
    back = read(tmp_path / "m.trc")               # 0.1234567891 -> 0.123457 on each axis
    worst = float(np.sqrt(((back.positions - m.positions) ** 2).sum(axis=2)).max())
    assert notes == [f"TRC is written with 6 decimals: 4 of 4 valid samples change, by up "
                     f"to {worst:.2g} mm; write .csv or .npy for the exact values"], notes
    assert 3.6e-7 < worst < 3.7e-7                # sqrt(3) x 2.109e-7


def test_npy_says_the_metadata_it_drops():
    """A QA run of stop 50: metadata subject and take vanished from an .npy with only the
    note that names, rate and units are not stored; TRC and CSV named them."""
    m = mpz.Motion(np.zeros((2, 1, 3)), ["A"], 100.0, "mm",
                   metadata={"subject": "s1", "take": "t1"})
    notes = writer_problems(m, ".npy")[1]
    assert "NPY has no place for free metadata: not written: 'subject', 'take'" in notes
