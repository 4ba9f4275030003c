"""mpz.io on the real recordings in ../shared/data (skipped when absent).

Expected frames, markers, rates and gap shares are copied from
shared/data/SOURCES.md (an independent reading of each file), not from the
code under test. For BVH and AMC the point count is what the forward
kinematics must produce, derived from the file structure:

* BVH: one point per ROOT/JOINT plus one per End Site. SOURCES.md gives the
  joint counts (43 and 31); the End Site counts (14 and 7) are counted in
  the HIERARCHY text by the test itself.
* AMC: the root plus one end point per ASF bone (SOURCES.md: 30 bones) = 31.
"""
from __future__ import annotations

import re

import numpy as np
import pytest

from mpz.io import read, read_amc, read_c3d, write, write_c3d

# file, frames, points, rate (Hz), gap share ("missing" in SOURCES.md) or None
C3D = [
    ("c3d/cmu_01_01.c3d", 2751, 42, 120.0, 0.024),
    ("c3d/cmu_02_01.c3d", 343, 41, 120.0, 0.0),
    ("c3d/cmu_135_02.c3d", 5202, 41, 120.0, 0.0),
    ("c3d/HDM_dg_06-03_03_120.c3d", 202, 44, 120.0, 0.0),
    ("c3d/HDM_mm_01-02_03_120.c3d", 3990, 44, 120.0, 0.0),
    ("c3d/numediart_03_rolling.c3d", 2305, 68, 175.0, 0.2295),
    ("c3d/ezc3d_Vicon.c3d", 580, 51, 100.0, 0.0103),
    ("c3d/ezc3d_Qualisys.c3d", 340, 55, 200.0, 0.0),
    ("c3d/c3dorg_Eb015pi.c3d", 450, 26, 50.0, 0.0193),
    ("c3d/c3dorg_Eb015vr.c3d", 450, 26, 50.0, 0.0193),
    ("c3d/c3dorg_Eb015sr.c3d", 450, 26, 50.0, 0.0193),
    ("c3d/c3dorg_Dance1.c3d", 498, 40, 65.0364, 0.0),
    ("c3d/c3dorg_AlbertoINT.c3d", 4921, 40, 120.0, 0.0),
    ("c3d/c3dorg_Facial-Sing.c3d", 3000, 38, 100.0, 0.0326),
    ("c3d/c3dorg_arthuman-sample.c3d", 4007, 63, 60.0033, 0.0002),
    ("c3d/c3dorg_codamotion_gaitwands_20150204.c3d", 2001, 23, 200.0, 0.2742),
    ("c3d/c3dorg_Sample_Jump2.c3d", 264, 51, 120.0, 0.0),
    # 90 points: 54 markers and 36 model outputs (POINT:ANGLES, FORCES, MOMENTS, POWERS),
    # which the reader keeps apart (issue 12, spec §4.13.3)
    ("c3d/auckland_FMC_MH0222_BP06.c3d", 279, 54, 100.0, 0.0),
]
TRC = [
    ("trc/opensim_subject01_walk1.trc", 151, 41, 60.0, 0.0),
    ("trc/opensim_hamner_subject02_running.trc", 600, 41, 60.0, 0.0),
    ("trc/btk_SprintMotion.trc", 788, 59, 250.0, 0.0),
]
# BVH: joints from SOURCES.md + End Sites (checked against the text below)
BVH = [
    ("bvh/cmu_10_01.bvh", 802, 43 + 14, 120.0, 132),
    ("bvh/cmu_11_01.bvh", 598, 43 + 14, 120.0, 132),
    ("bvh/cmu_14_19.bvh", 2727, 43 + 14, 120.0, 132),
    ("bvh/cmu_131_03.bvh", 1102, 31 + 7, 120.0, 96),
]
# AMC: root + 30 bones; 62 DOF channels incl. the 6-DOF root (SOURCES.md)
AMC = [
    ("amc/02_01.amc", "02.asf", 343),
    ("amc/35_01.amc", "35.asf", 358),
    ("amc/49_18.amc", "49.asf", 1102),
    ("amc/HDM_dg_06-03_03_120.amc", "HDM_dg.asf", 202),
]
UNITS = {"c3d/c3dorg_arthuman-sample.c3d": "cm"}  # every other C3D/TRC file says mm


def test_table_covers_every_file(shared_data):
    listed = {f for f, *_ in C3D + TRC + BVH} | {f for f, *_ in AMC} | {
        f"amc/{a}" for _, a, _ in AMC}
    present = {str(p.relative_to(shared_data)) for p in shared_data.rglob("*")
               if p.suffix.lower() in (".c3d", ".trc", ".bvh", ".amc", ".asf")}
    assert present == listed


@pytest.mark.parametrize("name,frames,markers,rate,gaps", C3D + TRC,
                         ids=[r[0] for r in C3D + TRC])
def test_marker_files(shared_data, name, frames, markers, rate, gaps):
    m = read(shared_data / name)
    assert (m.n_frames, m.n_markers) == (frames, markers)
    # SOURCES.md rounds rates to 4 decimals (65.0364, 60.0033)
    assert m.rate == pytest.approx(rate, abs=5e-5)
    assert m.gap_fraction == pytest.approx(gaps, abs=5e-5 if gaps >= 0.001 else 1e-4)
    assert m.units == UNITS.get(name, "mm")
    assert np.isfinite(m.positions[m.valid]).all()
    assert np.isnan(m.positions[~m.valid]).all()


def test_c3d_rate_is_the_float32_value(shared_data):
    m = read(shared_data / "c3d/c3dorg_Dance1.c3d")
    assert m.rate == float(np.float32(65.0364227))  # not rounded, not re-parsed
    assert m.rate != 65.0364227


def test_numediart_gap_share(shared_data):
    m = read(shared_data / "c3d/numediart_03_rolling.c3d")
    assert m.gap_fraction == pytest.approx(0.2295, abs=1e-4)


def test_quirky_c3d_files_are_read_with_a_note_or_a_warning(shared_data):
    """docs/io-notes.md: the MIPS file is valid C3D that ezc3d does not read (a note of the
    reader, no warning); Facial-Sing has a parameter type ezc3d does not know (a warning:
    ezc3d refuses it, and would meet that type if told to ignore that)."""
    m = read(shared_data / "c3d/c3dorg_Eb015sr.c3d")
    assert "warning" not in m.metadata and "MIPS" in m.metadata["reader_note"]
    m = read(shared_data / "c3d/c3dorg_Facial-Sing.c3d")
    assert "reader_note" not in m.metadata
    assert "ezc3d refused the file" in m.metadata["warning"]
    assert "told to ignore that it would meet a parameter of type 0" in m.metadata["warning"]
    assert read(shared_data / "c3d/cmu_02_01.c3d").metadata["subject"] == "TakeoMonday"
    names = read(shared_data / "c3d/c3dorg_Sample_Jump2.c3d").names
    assert "RKNE" in names and "RKNE#2" in names


@pytest.mark.parametrize("name,frames,points,rate,channels", BVH, ids=[r[0] for r in BVH])
def test_bvh_files(shared_data, name, frames, points, rate, channels):
    text = (shared_data / name).read_text()
    n_joints = len(re.findall(r"^\s*(ROOT|JOINT)\s", text, re.M))
    n_ends = len(re.findall(r"^\s*End Site", text, re.M))
    assert n_joints + n_ends == points
    m = read(shared_data / name)
    assert (m.n_frames, m.n_markers, m.rate) == (frames, points, rate)
    assert m.angles.shape == (frames, channels)
    assert m.parents[0] == -1 and all(0 <= p < i for i, p in enumerate(m.parents) if i)
    assert sum(n.endswith("_End") for n in m.names) == n_ends
    # FK keeps bone lengths: |child - parent| equals |OFFSET| in every frame
    # (checked as: constant over frames, for every non-root point)
    P = m.positions
    lengths = np.linalg.norm(P[:, 1:] - P[:, [p for p in m.parents[1:]]], axis=2)
    assert np.ptp(lengths, axis=0).max() < 1e-6 * max(1.0, lengths.max())


@pytest.mark.parametrize("name,asf,frames", AMC, ids=[r[0] for r in AMC])
def test_amc_files(shared_data, name, asf, frames):
    m = read(shared_data / name)  # finds the ASF by prefix
    assert m.metadata["asf"] == asf
    assert (m.n_frames, m.n_markers, m.rate, m.units) == (frames, 31, 120.0, "mm")
    assert m.angles.shape == (frames, 62)
    # a standing adult: 1.3 m to 2.2 m between the lowest and highest point
    height = np.ptp(m.positions[0, :, 1])  # ASF is Y-up
    assert 1300 < height < 2200


def test_eb015_three_encodings_agree(shared_data):
    """Intel int16, DEC float and MIPS float copies of one recording."""
    pi = read(shared_data / "c3d/c3dorg_Eb015pi.c3d")
    vr = read(shared_data / "c3d/c3dorg_Eb015vr.c3d")
    sr = read(shared_data / "c3d/c3dorg_Eb015sr.c3d")
    assert sr.metadata["reader"] == "mpz.io.c3dbin"  # ezc3d cannot read MIPS
    assert pi.names == vr.names == sr.names
    np.testing.assert_array_equal(pi.valid, vr.valid)
    np.testing.assert_array_equal(pi.valid, sr.valid)
    step = 0.08333334  # |POINT:SCALE| of the integer file
    ok = pi.valid
    assert np.abs(pi.positions[ok] - sr.positions[ok]).max() <= step
    assert np.abs(vr.positions[ok] - sr.positions[ok]).max() <= 1e-3  # both float32
    assert np.abs(pi.positions[ok] - vr.positions[ok]).max() <= step


def _kabsch(X, Y, with_scale):
    """Similarity transform s, R, t minimising |s R X + t - Y| (Umeyama 1991)."""
    mx, my = X.mean(0), Y.mean(0)
    U, S, Vt = np.linalg.svd((Y - my).T @ (X - mx))
    D = np.eye(3)
    D[2, 2] = np.sign(np.linalg.det(U @ Vt))
    R = U @ D @ Vt
    s = (S * np.diag(D)).sum() / ((X - mx) ** 2).sum() if with_scale else 1.0
    return s, R, my - s * R @ mx


# AMC point -> C3D markers whose mean it should sit near (CMU marker set)
FK_PAIRS = [
    ("root", ["LFWT", "RFWT", "LBWT", "RBWT"]),
    ("lfemur", ["LKNE"]), ("rfemur", ["RKNE"]),
    ("ltibia", ["LANK"]), ("rtibia", ["RANK"]),
    ("lfoot", ["LTOE"]), ("rfoot", ["RTOE"]),
    ("lhumerus", ["LELB"]), ("rhumerus", ["RELB"]),
    ("lwrist", ["LWRA", "LWRB"]), ("rwrist", ["RWRA", "RWRB"]),
    ("head", ["LFHD", "RFHD", "LBHD", "RBHD"]),
]


def test_amc_forward_kinematics_matches_c3d(shared_data):
    """amc/02_01 + 02.asf and c3d/cmu_02_01 are the same take.

    Joint positions and skin markers differ by soft-tissue offsets (a few
    cm) but after one rigid alignment over all frames each pair must stay
    close and at a nearly constant distance. Measured (docs/io-notes.md):
    median 52 mm, max 95 mm, every pair's std over frames <= 8.1 mm, scale
    1.0065. A wrong rotation order gives a median > 100 mm and stds of
    10-160 mm.
    """
    a = read_amc(shared_data / "amc/02_01.amc", shared_data / "amc/02.asf")
    c = read_c3d(shared_data / "c3d/cmu_02_01.c3d")
    assert a.n_frames == c.n_frames == 343
    assert c.valid.all()
    j = {n: i for i, n in enumerate(a.names)}
    k = {n.split(":")[-1]: i for i, n in enumerate(c.names)}
    X = np.stack([a.positions[:, j[jn]] for jn, _ in FK_PAIRS], axis=1)
    Y = np.stack([c.positions[:, [k[n] for n in ms]].mean(axis=1) for _, ms in FK_PAIRS], axis=1)
    # the unit conversion (25.4 / 0.45 mm per ASF unit) must give scale ~1
    s, _, _ = _kabsch(X.reshape(-1, 3), Y.reshape(-1, 3), with_scale=True)
    assert 0.98 < s < 1.02
    _, R, t = _kabsch(X.reshape(-1, 3), Y.reshape(-1, 3), with_scale=False)
    d = np.linalg.norm(X @ R.T + t - Y, axis=2)  # (frames, pairs), mm
    assert np.median(d) < 70.0
    assert d.mean(axis=0).max() < 100.0
    assert d.std(axis=0).max() < 15.0
    assert d.max() < 150.0


def test_c3d_round_trip_real(shared_data, tmp_path):
    m = read(shared_data / "c3d/cmu_02_01.c3d")
    out = tmp_path / "copy.c3d"
    write_c3d(m, out)
    back = read(out)
    assert back.names == m.names and back.rate == m.rate and back.units == m.units
    np.testing.assert_array_equal(back.valid, m.valid)
    # the source is float32 C3D: the copy is bit-exact
    np.testing.assert_array_equal(back.positions[m.valid], m.positions[m.valid])


def test_c3d_round_trip_with_gaps_and_odd_rate(shared_data, tmp_path):
    for name in ("c3d/numediart_03_rolling.c3d", "c3d/c3dorg_Dance1.c3d",
                 "c3d/c3dorg_Eb015sr.c3d"):
        m = read(shared_data / name)
        write(m, tmp_path / "x.c3d")
        back = read(tmp_path / "x.c3d")
        assert back.rate == m.rate and back.names == m.names
        np.testing.assert_array_equal(back.valid, m.valid)
        np.testing.assert_allclose(back.positions[m.valid], m.positions[m.valid], rtol=1e-6)


@pytest.mark.parametrize("name", [r[0] for r in TRC])
def test_trc_header_lines_come_back_through_mpz(shared_data, tmp_path, name):
    """A real TRC read, encoded, decoded and written again has the source's five header
    lines, to the tabs that end them (the tab closing lines 4 and 5 of
    opensim_subject01_walk1 and btk_SprintMotion, the 117-121 tabs padding lines 1-3 of
    opensim_hamner_subject02_running were dropped). Line ends are the one difference
    docs/io-notes.md names: LF for btk_SprintMotion's CR LF."""
    import mpz
    m = read(shared_data / name)
    write(mpz.decode(mpz.encode(m, max_error=1.0)), tmp_path / "back.trc")
    source = re.split(r"\r\n|\r|\n", (shared_data / name).read_bytes().decode("utf-8"))
    back = (tmp_path / "back.trc").read_bytes().decode("utf-8")
    assert "\r" not in back
    assert back.split("\n")[:5] == source[:5]
