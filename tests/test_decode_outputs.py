"""What ``mpz decode`` and ``mpz show`` say of what comes out (QA 45c, D1-D3, D5): an ASF
that would be the AMC itself, float32 and decimals rounding beyond the declared bound, a
coordinate beyond float32, the C3D header's event block, skipped ancillary chunks, renamed
duplicate labels, a C3D given to decode. Expected values are reasoned from the inputs built
here or read with ezc3d, not taken from the code's output."""
from __future__ import annotations

import json
from pathlib import Path
import re
import subprocess
import sys

import numpy as np
import pytest

import mpz
from mpz import Motion
from mpz.errors import MotionError
from mpz.io import read, write
from mpz.skeleton import with_joint_positions
from mpz.synth import generate

REPO = Path(__file__).resolve().parents[1]
U16 = REPO / "conformance" / "vectors" / "uncommon" / "u16-qunt-range-rounds-to-max-finite.mpz"
U06 = REPO / "conformance" / "vectors" / "uncommon" / "u06-unknown-ancillary-zzzz.mpz"


def _mpz(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    exe = Path(sys.executable).parent / "mpz"
    return subprocess.run([str(exe), *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300)


# ------------------------------------------------------------------ D1: --asf --
@pytest.fixture(scope="module")
def amc_mpz(tmp_path_factory, shared_data) -> Path:
    d = tmp_path_factory.mktemp("amc")
    src = shared_data / "amc" / "HDM_dg_06-03_03_120.amc"
    p = _mpz("encode", str(src), "-o", "h.mpz", "--max-error", "1mm", "-q", cwd=d)
    assert p.returncode == 0, p.stderr
    return d / "h.mpz"


@pytest.mark.parametrize("asf", ["h3.amc", "./h3.amc", "sub/../h3.amc"])
def test_asf_naming_the_amc_is_refused_before_anything_is_written(amc_mpz, asf, tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "h.mpz").write_bytes(amc_mpz.read_bytes())
    for extra in ([], ["-f"]):
        p = _mpz("decode", "h.mpz", "-o", "h3.amc", "--asf", asf, *extra, cwd=tmp_path)
        assert p.returncode == 64, p.stderr
        assert "same file" in p.stderr
        assert sorted(x.name for x in tmp_path.iterdir()) == ["h.mpz", "sub"]


def test_asf_dash_makes_no_file_named_dash(amc_mpz, tmp_path):
    (tmp_path / "h.mpz").write_bytes(amc_mpz.read_bytes())
    p = _mpz("decode", "h.mpz", "-o", "h5.amc", "--asf", "-", cwd=tmp_path)
    assert p.returncode == 64 and "standard output" in p.stderr
    assert sorted(x.name for x in tmp_path.iterdir()) == ["h.mpz"]
    # the ordinary use still writes both
    p = _mpz("decode", "h.mpz", "-o", "h6.amc", "--asf", "s.asf", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert ":bonedata" in (tmp_path / "s.asf").read_text(encoding="latin-1")
    assert ":bonedata" not in (tmp_path / "h6.amc").read_text(encoding="latin-1")


# ------------------------------------------------------- D2: float32 and decimals --
def test_c3d_beyond_float32_is_refused_and_nothing_written(tmp_path):
    # u16's values reach 1.8e308, far beyond float32's 3.4e38 (IEEE 754 binary32)
    back = mpz.decode(U16)
    assert np.abs(back.positions[back.valid]).max() > 3.5e38
    p = _mpz("decode", str(U16), "-o", "out.c3d", cwd=tmp_path)
    assert p.returncode == 2
    assert "float32" in p.stderr and "infinit" in p.stderr
    assert not (tmp_path / "out.c3d").exists()
    assert _mpz("decode", str(U16), "-o", "out.npy", "-q", cwd=tmp_path).returncode == 0


def test_trc_rounding_of_whole_numbers_past_2_to_52_is_none(tmp_path):
    """A TRC of coordinates near 1e30 reads back exact (6 decimals print a whole number
    exactly), and its note said "1 of 8 valid samples change, by up to 1.1e+12 mm":
    np.round(v, 6) multiplies by 10^6 first (a QA run of the API, stop 54). The note is
    checked against what the written file reads back as."""
    from mpz.io import rounding_notes
    rng = np.random.default_rng(1)
    pos = rng.normal(0, 1e30, (4, 2, 3))
    pos[0, 0] = [0.1234567, 2.0 ** 52 - 0.5, 3.0]       # below 2^52: rounded as before
    m = Motion(pos, ["A", "B"], rate=100.0, units="mm")
    mpz.io.write(m, tmp_path / "x.trc")
    back = mpz.io.read(tmp_path / "x.trc").positions
    err = np.linalg.norm(back - pos, axis=2)
    changed = int((err > 0).sum())
    (note,) = rounding_notes(m, ".trc", None)
    assert changed == 1 and f"{changed} of 8 valid samples change, by up to " \
        f"{err.max():.2g} mm" in note, (note, err)


def _off_grid_motion() -> Motion:
    """60 frames x 4 markers near 1500 mm, at coordinates no float32 holds (k/3 + 0.1)."""
    rng = np.random.default_rng(7)
    pos = 1500.0 + rng.uniform(-400, 400, size=(60, 4, 3))
    pos = np.round(pos * 3) / 3 + 0.1
    return Motion(pos, ["A", "B", "C", "D"], rate=100.0, units="mm")


def test_c3d_float32_rounding_beyond_the_bound_is_noted(tmp_path):
    import ezc3d
    m = _off_grid_motion()
    write(m, tmp_path / "s.trc")
    assert _mpz("encode", "s.trc", "-o", "s.mpz", "--max-error", "0.01mm", "-q",
                cwd=tmp_path).returncode == 0
    p = _mpz("decode", "s.mpz", "-o", "s.c3d", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    # by hand: float32 spacing at 1024..2048 mm is 2^-13 mm, so rounding moves each axis
    # by <= 2^-14 and a point by <= sqrt(3) 2^-14 = 1.06e-4 mm, against a bound of 0.01 mm
    pts = ezc3d.c3d(str(tmp_path / "s.c3d"))["data"]["points"][:3].transpose(2, 1, 0)
    dec = mpz.decode(tmp_path / "s.mpz").positions
    moved = np.linalg.norm(pts - dec, axis=2).max()
    assert 0 < moved <= np.sqrt(3) * 2.0 ** -14
    note = [ln for ln in p.stderr.splitlines() if "float32" in ln]
    assert len(note) == 1 and "0.01 mm bound" in note[0], p.stderr
    stated = float(note[0].split("rounded by up to ")[1].split()[0])
    assert stated == pytest.approx(moved, rel=0.05)
    # NPY and CSV keep every value: no such note
    for ext in ("npy", "csv"):
        p = _mpz("decode", "s.mpz", "-o", f"s.{ext}", cwd=tmp_path)
        assert p.returncode == 0 and "rounded" not in p.stderr


def test_c3d_from_a_c3d_gets_no_rounding_note(tmp_path, shared_data):
    """A float C3D source: the encoder coded within the bound less float32's rounding."""
    src = shared_data / "c3d" / "ezc3d_Vicon.c3d"
    assert _mpz("encode", str(src), "-o", "v.mpz", "--max-error", "1mm", "-q",
                cwd=tmp_path).returncode == 0
    for ext in ("c3d", "trc"):
        p = _mpz("decode", "v.mpz", "-o", f"v.{ext}", cwd=tmp_path)
        assert p.returncode == 0 and "rounded by" not in p.stderr, p.stderr


@pytest.fixture(scope="module")
def eb015(tmp_path_factory, shared_data) -> Path:
    d = tmp_path_factory.mktemp("eb")
    p = _mpz("encode", str(shared_data / "c3d" / "c3dorg_Eb015pi.c3d"), "-o", "e.mpz", "-q",
             cwd=d)
    assert p.returncode == 0, p.stderr
    return d / "e.mpz"


def test_trc_decimals_beyond_an_exact_bound_are_noted(eb015, shared_data, tmp_path):
    import ezc3d
    c = ezc3d.c3d(str(shared_data / "c3d" / "c3dorg_Eb015pi.c3d"))
    pts = c["data"]["points"]
    valid = c["data"]["meta_points"]["residuals"][0] >= 0
    xyz = pts[:3].transpose(2, 1, 0)[valid.T]               # int16 x POINT:SCALE, in mm
    off6 = np.abs(np.round(xyz, 6) - xyz).max(axis=1) > 0
    assert mpz.info(eb015).error_bound == 0.0
    p = _mpz("decode", str(eb015), "-o", "e.trc", cwd=tmp_path)
    assert p.returncode == 0
    note = [ln for ln in p.stderr.splitlines() if "decimals" in ln]
    assert len(note) == 1, p.stderr
    assert f"at {int(off6.sum())} of {int(valid.sum())} valid samples" in note[0]
    # the C3D is written as int16 on the source's grid: exact, no note
    p = _mpz("decode", str(eb015), "-o", "e.c3d", cwd=tmp_path)
    assert p.returncode == 0 and "rounded" not in p.stderr


# -------------------------------------------------------------- D3: header events --
def test_header_events_are_counted_by_show_and_decode_notes(eb015, shared_data, tmp_path):
    import ezc3d
    ev = ezc3d.c3d(str(shared_data / "c3d" / "c3dorg_Eb015pi.c3d"))["header"]["events"]
    n = sum(1 for label in ev["events_label"] if label.strip())
    assert n == 3                                   # RIC, RHS, RTO
    p = _mpz("show", "--json", str(eb015), cwd=tmp_path)
    c = json.loads(p.stdout)["c3d"]
    assert c["header_events"] == n and c["events"] is None
    assert f"{n} events (header)" in _mpz("show", str(eb015), cwd=tmp_path).stdout
    for ext in ("trc", "csv", "npy"):
        p = _mpz("decode", str(eb015), "-o", f"e.{ext}", cwd=tmp_path)
        assert p.returncode == 0 and f"{n} events (header)" in p.stderr, (ext, p.stderr)


# ------------------------------------------------------------------------ D5 --
def test_show_gives_the_declared_bound_and_a_json_error(tmp_path):
    from mpz.synth import generate
    (tmp_path / "w.mpz").write_bytes(mpz.encode(generate("walk", frames=30), max_error=0.5))
    p = _mpz("show", "w.mpz", cwd=tmp_path)
    assert "max error \u2264 0.5 mm" in p.stdout
    assert json.loads(_mpz("show", "--json", "w.mpz", cwd=tmp_path).stdout)[
        "error_bound"] == 0.5
    data = (tmp_path / "w.mpz").read_bytes()
    (tmp_path / "cut.mpz").write_bytes(data[:len(data) // 2])
    p = _mpz("show", "--json", "cut.mpz", cwd=tmp_path)
    assert p.returncode == 2
    doc = json.loads(p.stdout)
    assert doc["status"] == "error" and doc["error"]["message"]


def test_show_names_marker_names_made_unique(tmp_path):
    """A QA run of exporters: a TRC whose name row repeats a marker was shown without a word
    of the rename (LASI -> LASI#2), which --json's metadata alone held."""
    rows = ["PathFileType\t4\t(X/Y/Z)\td.trc", "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits",
            "60\t60\t2\t2\tmm", "Frame#\tTime\tLASI\t\t\tLASI\t\t",
            "\t\tX1\tY1\tZ1\tX2\tY2\tZ2", "", "1\t0\t1\t2\t3\t4\t5\t6",
            "2\t0.0167\t1\t2\t3\t4\t5\t6"]
    (tmp_path / "d.trc").write_text("\n".join(rows) + "\n")
    p = _mpz("show", "d.trc", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert "renamed:   marker names that repeat or are empty, made unique: LASI->LASI#2" \
        in p.stdout.splitlines()
    from mpz.tools._common import renamed_list  # 32545 renames printed in full
    many = {"renamed_points": "; ".join(f"->_unnamed_{i}" for i in range(25))}
    assert renamed_list(many) == "; ".join(f"->_unnamed_{i}" for i in range(10)) \
        + "; and 15 more"
    assert renamed_list({}) == "" and renamed_list({"renamed_points": "a->b"}) == "a->b"


def test_show_gives_a_skeletal_files_bound_on_the_joints_it_shows(shared_data, tmp_path):
    """A newcomer's QA run: mpz show summarises a skeletal file's joint positions computed
    from its channels, and gave MHDR's bound (the marker layer's) as theirs. It now gives
    the joints' declared bound, and the joints decoded are within it of the source's (its
    own forward kinematics); MHDR's is named as the marker layer's."""
    amc = shared_data / "amc" / "35_01.amc"
    assert _mpz("encode", str(amc), "-o", "a.mpz", "-q", cwd=tmp_path).returncode == 0
    doc = json.loads(_mpz("show", "--json", "a.mpz", cwd=tmp_path).stdout)
    joints, layer = doc["position_bound"], doc["error_bound"]
    assert joints is not None and layer is not None and joints != layer
    got = with_joint_positions(mpz.decode(tmp_path / "a.mpz")).positions
    want = read(amc).positions
    err = float(np.sqrt(((got - want) ** 2).sum(-1)).max())
    assert err <= joints, (err, joints)
    text = _mpz("show", "a.mpz", cwd=tmp_path).stdout
    said = re.search(r"bound:     joints within (\S+) mm \(declared\), computed from the "
                     r"channels; the marker layer: max error \u2264 (\S+) mm \(declared\)", text)
    assert said is not None, text
    # each as printed: 6 significant digits at most, and not below the file's (rounded up,
    # stop 72: %g printed 1.16141 for 1.161413)
    for printed, stored in zip(said.groups(), (joints, layer), strict=True):
        assert float(printed) >= stored and len(printed.replace(".", "").lstrip("0")) <= 6
        assert float(printed) - stored < 1e-5 * stored, (printed, stored)
    # a file of markers: the one bound, the same in both fields
    (tmp_path / "w.mpz").write_bytes(mpz.encode(read(amc), max_error=0.5, keep_skeleton=False))
    doc = json.loads(_mpz("show", "--json", "w.mpz", cwd=tmp_path).stdout)
    assert doc["position_bound"] == doc["error_bound"] == 0.5


def test_with_joint_positions_refuses_a_motion_without_channels(shared_data, tmp_path):
    """A newcomer's QA run: given a motion without a skeleton's channels (decoded with
    markers_only=True, or a file of markers) it handed the marker layer back as it was,
    which the caller took for the joints."""
    amc = read(shared_data / "amc" / "35_01.amc")
    data = mpz.encode(amc)
    plain = mpz.encode(amc, keep_skeleton=False)
    for motion in (mpz.decode(data, markers_only=True), mpz.decode(plain),
                   generate("walk", frames=20)):
        with pytest.raises(MotionError, match="no skeleton and channels to compute joint"):
            with_joint_positions(motion)
    joints = with_joint_positions(mpz.decode(data)).positions
    assert joints.shape == amc.positions.shape


def test_decode_names_skipped_chunks_and_renamed_labels(tmp_path):
    p = _mpz("decode", str(U06), "-o", "u.npy", cwd=tmp_path)
    assert p.returncode == 0 and "'qqqq', 'zzzz'" in p.stderr and "skipped" in p.stderr
    m = Motion(np.ones((3, 2, 3)), ["RKNE", "RKNE#2"], rate=50.0, units="mm")
    m.metadata["renamed_points"] = "RKNE->RKNE#2"
    (tmp_path / "r.mpz").write_bytes(mpz.encode(m, max_error=0.1))
    p = _mpz("decode", "r.mpz", "-o", "r.trc", cwd=tmp_path)
    assert p.returncode == 0 and "RKNE->RKNE#2" in p.stderr and "names repeat" in p.stderr


@pytest.mark.parametrize("out", [None, "z.csv"])
def test_decode_of_any_motion_file_says_to_encode_it_with_or_without_o(shared_data, tmp_path,
                                                                      out):
    """A newcomer's QA run: without -o, mpz decode of a TRC said only "bad signature
    b'PathFile'" (the default output name is read from the file first), with -o it said
    what to do; an ASF said "bad signature" either way, and the article was "a AMC/ASF"."""
    np.save(tmp_path / "q.npy", np.zeros((3, 2, 3)))
    cases = {str(shared_data / "trc" / "opensim_subject01_walk1.trc"): "a TRC file",
             str(shared_data / "amc" / "35_01.amc"): "an AMC/ASF file",
             str(tmp_path / "q.npy"): "an NPY file",
             str(shared_data / "amc" / "35.asf"): "an ASF skeleton; mpz encode compresses "
                                                  "the AMC motion that goes with it"}
    for path, said in cases.items():
        p = _mpz("decode", path, *(["-o", out] if out else []), cwd=tmp_path)
        assert p.returncode == 2 and "not an MPZ file (first bytes " in p.stderr, p.stderr
        assert f"this is {said}" in p.stderr and "bad signature" not in p.stderr, p.stderr
    assert sorted(f.name for f in tmp_path.iterdir()) == ["q.npy"]


def test_decode_of_a_no_skeleton_amc_says_to_choose_the_format(shared_data, tmp_path):
    """A newcomer's QA run: a file encoded from AMC with --no-skeleton could not be decoded
    without options: the default output is the source's format, which needs the skeleton,
    and the writer's refusal named an output (ns.amc) nobody had asked for."""
    amc = shared_data / "amc" / "35_01.amc"
    p = _mpz("encode", str(amc), "--no-skeleton", "-o", "ns.mpz", "-q", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    p = _mpz("decode", "ns.mpz", cwd=tmp_path)
    assert p.returncode == 2, p.stderr
    assert "ns.mpz: it was encoded from AMC/ASF without its skeleton (--no-skeleton)" \
        in p.stderr and "give --format npy or csv" in p.stderr, p.stderr
    assert sorted(f.name for f in tmp_path.iterdir()) == ["ns.mpz"]
    p = _mpz("decode", "ns.mpz", "--format", "npy", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert np.load(tmp_path / "ns.npy").shape == (mpz.info(tmp_path / "ns.mpz").frames, 31, 3)


def test_decode_of_a_c3d_says_to_encode_it(shared_data, tmp_path):
    p = _mpz("decode", str(shared_data / "c3d" / "c3dorg_Eb015pi.c3d"), "-o", "z.trc",
             cwd=tmp_path)
    assert p.returncode == 2 and "this is a C3D file; use mpz encode" in p.stderr
    assert not (tmp_path / "z.trc").exists()


def test_decode_notes_the_warning_the_source_was_read_with(tmp_path):
    """The reader's warning about a source (Dance1: parameter records past the declared
    blocks, which readers of the C3D written back see otherwise) is kept in the file's
    metadata; encode, show and decode -v said it, a plain decode did not (an interop QA
    run of stop 64). -q keeps quiet, as for every note."""
    m = generate("walk", frames=20, markers=3, seed=1)
    said = "the header's frame range is stale"
    mpz.write_mpz(Motion(m.positions, m.names, m.rate, m.units, metadata={"warning": said}),
                  tmp_path / "w.mpz")
    p = _mpz("decode", "w.mpz", "-o", "w.trc", cwd=tmp_path)
    assert p.returncode == 0 and f"read with a warning when it was encoded (kept in the " \
        f"file's metadata): {said}" in p.stderr, p.stderr
    p = _mpz("decode", "w.mpz", "-o", "w2.trc", "-q", cwd=tmp_path)
    assert p.returncode == 0 and said not in p.stderr
    m2 = generate("walk", frames=20, markers=3, seed=1)
    mpz.write_mpz(m2, tmp_path / "plain.mpz")
    assert "a warning" not in _mpz("decode", "plain.mpz", "-o", "p.trc", cwd=tmp_path).stderr
