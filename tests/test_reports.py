"""What mpz compare and mpz summary report: the motion compared, its units and rate.

Each expected figure is computed here with numpy from the arrays written (or from what
``mpz decode`` writes, to NPY), not by the command under test. The tests on the real
recordings skip without them (conftest.shared_data)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import mpz
from mpz.io import write
from mpz.motion import Motion
from mpz.synth import generate
from mpz.tools import mpz_cli


def cli(capsys, *argv: object) -> tuple[int, str, str]:
    code = mpz_cli.main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def max_error(a: np.ndarray, b: np.ndarray) -> float:
    """The largest Euclidean distance between two [frames, markers, 3] arrays."""
    return float(np.linalg.norm(a - b, axis=2).max())


def bvh_text(frames: int = 60) -> str:
    """A three-joint BVH whose angles sweep smoothly (no length unit, as every BVH)."""
    t = np.arange(frames) / frames
    rows = []
    for v in t:
        ch = [10 * v, 2.0, 3 * v, 30 * np.sin(6 * v), 20 * v, 5.0,
              40 * np.sin(4 * v), 10.0, 25 * np.cos(5 * v), 60 * v]
        rows.append(" ".join(f"{c:.4f}" for c in ch))
    return ("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n"
            "  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
            "  JOINT Spine\n  {\n    OFFSET 0 10 0\n"
            "    CHANNELS 3 Zrotation Xrotation Yrotation\n"
            "    End Site\n    {\n      OFFSET 0 12 0\n    }\n  }\n"
            "  JOINT Leg\n  {\n    OFFSET 2 -1 0\n    CHANNELS 1 Xrotation\n"
            "    End Site\n    {\n      OFFSET 0 -15 0\n    }\n  }\n}\n"
            f"MOTION\nFrames: {frames}\nFrame Time: 0.0333333\n" + "\n".join(rows) + "\n")


def decoded_npy(capsys, tmp_path: Path, packed: Path) -> np.ndarray:
    """What ``mpz decode`` writes (NPY: float64 positions, NaN gaps)."""
    out = tmp_path / (packed.stem + "_decoded.npy")
    code, _, err = cli(capsys, "decode", packed, "-o", out, "-f")
    assert code == 0, err
    return np.load(out)


# -- 1. a skeletal .mpz is compared as mpz decode writes it ---------------------------------

def encoded_sweep(capsys, tmp_path: Path, *options: str) -> tuple[Path, Path]:
    """The sweep BVH and its .mpz, encoded with ``options``."""
    src = tmp_path / "sweep.bvh"
    src.write_text(bvh_text())
    packed = tmp_path / "sweep.mpz"
    code, _, err = cli(capsys, "encode", src, "-o", packed, *options, "-q")
    assert code == 0, err
    return src, packed


def test_compare_of_a_skeletal_mpz_uses_the_joint_positions_decode_writes(tmp_path, capsys):
    src, packed = encoded_sweep(capsys, tmp_path, "--units", "cm")
    a = mpz.io.read(src).positions
    want = max_error(a, decoded_npy(capsys, tmp_path, packed))
    layer = max_error(a, mpz.decode(packed.read_bytes()).positions)
    assert layer > 3 * want          # the 1.0 marker layer is a coarse preview: they differ
    code, out, err = cli(capsys, "compare", src, packed, "--json")
    doc = json.loads(out)
    assert code == 0 and doc["max"] == pytest.approx(want, rel=1e-9, abs=1e-12)
    assert doc["positions"]["decoded"].startswith("joint positions from the skeleton's channels")
    # a unitless BVH against the cm file: the figures are in cm, and that is said
    assert doc["units"] == "cm" and doc["original_units"] is None
    code, out, err = cli(capsys, "compare", src, packed)
    assert code == 0 and f"max {want:.4g} cm" in out
    assert "joint positions from the skeleton's channels" in out
    assert "has no length unit" in err and "compared as numbers" in err


def test_summary_of_a_skeletal_mpz_measures_shares_on_the_joint_positions(tmp_path, capsys):
    _, packed = encoded_sweep(capsys, tmp_path, "--summary", "3")
    pos = decoded_npy(capsys, tmp_path, packed)                 # no gaps in a BVH
    x = (pos - pos.mean(axis=1, keepdims=True)).reshape(len(pos), -1)
    code, out, _ = cli(capsys, "summary", packed, "--json")
    (level,) = json.loads(out)["levels"]
    starts = [s["start"] for s in level["segments"]]
    sse = [float(((x[s:e] - x[s:e].mean(axis=0)) ** 2).sum())
           for s, e in zip(starts, [*starts[1:], len(x)], strict=True)]
    got = [s["share"] for s in level["segments"]]
    assert got == pytest.approx([100 * v / sum(sse) for v in sse], rel=1e-9)


@pytest.mark.parametrize("name, asf, units", [("bvh/cmu_10_01.bvh", None, "cm"),
                                              ("amc/02_01.amc", "amc/02.asf", "mm")])
def test_compare_real_skeletal_files_as_decode_writes_them(shared_data, tmp_path, capsys,
                                                          name, asf, units):
    """QA report: cmu_10_01 (--units cm) compared 0.3054 against the .mpz, 0.055 against
    the BVH mpz decode wrote; 02_01.amc 3.333 mm against 1.045 mm."""
    src = shared_data / name
    packed = tmp_path / "r.mpz"
    extra = ["--units", "cm"] if units == "cm" else []
    code, _, err = cli(capsys, "encode", src, "-o", packed, "-q", *extra)
    assert code == 0, err
    a = mpz.io.read(src, **({"asf": shared_data / asf} if asf else {})).positions
    want = max_error(a, decoded_npy(capsys, tmp_path, packed))
    code, out, _ = cli(capsys, "compare", src, packed, "--json")
    doc = json.loads(out)
    assert code == 0 and doc["max"] == pytest.approx(want, rel=1e-9)
    assert doc["units"] == units
    assert want < max_error(a, mpz.decode(packed.read_bytes()).positions) / 3


# -- 2. units and frame rate ------------------------------------------------------------------

@pytest.fixture(scope="module")
def walk() -> Motion:
    m = generate("walk", frames=60, rate=60.0, seed=4)
    pos = np.round(m.positions, 3)        # exact in a TRC's text: the files hold these numbers
    return Motion(pos, m.names, 60.0, "mm")


def with_(m: Motion, positions=None, rate=None, units=None) -> Motion:
    return Motion(m.positions if positions is None else positions, m.names,
                  m.rate if rate is None else rate, m.units if units is None else units)


def test_compare_converts_lengths_to_one_unit(walk, tmp_path, capsys):
    a = tmp_path / "walk_mm.trc"
    write(walk, a)
    same = tmp_path / "walk_m.trc"               # the same positions, in metres
    write(with_(walk, positions=walk.positions / 1000, units="m"), same)
    code, out, err = cli(capsys, "compare", a, same, "--json")
    assert code == 0 and json.loads(out)["max"] < 1e-3 and "converted to mm" in err
    meta = parts(json.loads(out))["metadata"]         # the header's Units: not a failure
    assert meta["status"] == "changed" and "trc.Units" in meta["detail"]
    code, out, err = cli(capsys, "compare", a, same)  # the text report too (QA: a crash)
    assert code == 0 and "metadata            changed: " in out and "trc.Units" in out
    relabelled = tmp_path / "walk_relabelled_m.trc"   # the numbers of mm, labelled m (QA)
    write(with_(walk, units="m"), relabelled)
    want = max_error(walk.positions, 1000 * walk.positions)
    code, out, err = cli(capsys, "compare", a, relabelled, "--json")
    doc = json.loads(out)
    assert code == 0 and doc["max"] == pytest.approx(want, rel=1e-9)
    assert doc["units"] == "mm" and doc["decoded_units"] == "m"


def test_compare_holds_the_markers_to_the_bound_the_mpz_declares(walk, tmp_path, capsys):
    """Against an .mpz the marker errors are held to its bound as spec §7.2 states it
    (E + max|x| 2^-50); a source moved 5 mm at one sample is beyond it: exit 2, the
    sample named. Before, the report gave max 5 mm and exit 0, the bound unmentioned."""
    src, packed = tmp_path / "w.trc", tmp_path / "w.mpz"
    write(walk, src)
    code, _, err = cli(capsys, "encode", src, "-o", packed, "--max-error", "1mm", "-q")
    assert code == 0, err
    code, out, _ = cli(capsys, "compare", src, packed, "--json")
    doc = json.loads(out)
    assert code == 0 and doc["bound_check"] == {"bound": 1.0, "beyond": 0, "first": None,
                                             "of": "markers"}
    code, out, _ = cli(capsys, "compare", src, packed)
    assert "  bound 1 mm declared by " in out and "every sample within" in out
    moved = walk.positions.copy()
    moved[9, 2, 1] += 5.0
    write(with_(walk, positions=moved), tmp_path / "moved.trc")
    decoded = mpz.decode(packed.read_bytes()).positions
    want = float(np.linalg.norm(moved[9, 2] - decoded[9, 2]))
    assert want > 1.0
    code, out, _ = cli(capsys, "compare", tmp_path / "moved.trc", packed, "--json")
    doc = json.loads(out)
    assert code == 2 and doc["bound_check"]["beyond"] == 1
    assert doc["bound_check"]["first"] == {"frame": 9, "marker": walk.names[2],
                                           "error": pytest.approx(want, rel=1e-12)}
    code, out, _ = cli(capsys, "compare", tmp_path / "moved.trc", packed)
    assert f"BEYOND at 1 sample, the first {walk.names[2]!r} at frame index 9" in out
    # not against a file that declares no bound (the .mpz as the original: its bound is
    # against its own source)
    code, out, _ = cli(capsys, "compare", packed, src, "--json")
    assert code == 0 and json.loads(out)["bound_check"] is None


def test_compare_names_markers_the_decoded_file_added(walk, tmp_path, capsys):
    """A marker the original has not is a difference (exit 2), named; it was ignored."""
    write(walk, tmp_path / "a.trc")
    more = Motion(np.concatenate([walk.positions, walk.positions[:, :1] + 1], axis=1),
                  [*walk.names, "EXTRA"], walk.rate, walk.units)
    write(more, tmp_path / "b.csv")
    code, out, err = cli(capsys, "compare", tmp_path / "a.trc", tmp_path / "b.csv", "--json")
    assert code == 2 and json.loads(out)["added_markers"] == ["EXTRA"]
    assert "has 1 marker the original has not: EXTRA" in err



def test_compare_gives_the_errors_of_the_samples_valid_in_both(walk, tmp_path, capsys):
    """A valid sample that became a gap is an infinite error (it cannot hide), and it hid
    every other error: "max inf  p99 0" (a QA run of stop 47). The report also gives the
    figures over the samples valid in both, here one sample moved by (0.5, 0.5, 0.5):
    max sqrt(3) / 2, computed with numpy."""
    write(walk, tmp_path / "a.trc")
    pos = walk.positions.copy()
    valid = walk.valid.copy()
    valid[5:9, 2] = False
    pos[20, 4] += 0.5
    write(Motion(pos, walk.names, walk.rate, walk.units, valid), tmp_path / "b.trc")
    code, out, _ = cli(capsys, "compare", tmp_path / "a.trc", tmp_path / "b.trc", "--json")
    doc = json.loads(out)
    assert code == 2 and doc["valid_became_gap"] == 4 and doc["max"] is None   # inf: null
    both = doc["valid_in_both"]
    d = np.linalg.norm(pos - walk.positions, axis=2)[valid & walk.valid]
    assert both["max"] == pytest.approx(np.sqrt(3) / 2, rel=1e-9)
    assert both["rms"] == pytest.approx(float(np.sqrt((d ** 2).mean())), rel=1e-9)
    code, out, _ = cli(capsys, "compare", tmp_path / "a.trc", tmp_path / "b.trc")
    assert f"valid in both: max {np.sqrt(3) / 2:.4g} mm" in out
    write(walk, tmp_path / "c.trc")                 # no sample lost: no such line
    code, out, _ = cli(capsys, "compare", tmp_path / "a.trc", tmp_path / "c.trc", "--json")
    assert json.loads(out)["valid_in_both"] is None

def test_compare_refuses_two_frame_rates(walk, tmp_path, capsys):
    a = tmp_path / "walk_60.trc"
    b = tmp_path / "walk_120.trc"
    write(walk, a)
    write(with_(walk, rate=120.0), b)
    code, out, err = cli(capsys, "compare", a, b)
    assert code == 2 and out == ""
    assert "frame rates differ" in err and "60 Hz" in err and "120 Hz" in err


def test_compare_with_an_npy_does_not_check_the_rate_it_lacks(walk, tmp_path, capsys):
    named = Motion(walk.positions, [f"M{i}" for i in range(walk.n_markers)], 60.0, "mm")
    write(named, tmp_path / "walk.trc")
    write(named, tmp_path / "walk.npy")           # NPY keeps no names, rate nor units
    code, out, err = cli(capsys, "compare", tmp_path / "walk.trc", tmp_path / "walk.npy")
    assert code == 0 and "NPY stores no frame rate" in err and "max 0 mm" in out


def test_compare_with_an_npy_takes_its_unnamed_markers_in_order(walk, tmp_path, capsys):
    """NPY stores no names: an NPY that mpz decode wrote is compared marker by marker in
    order (before, it failed: "markers missing"); another count cannot be matched."""
    write(walk, tmp_path / "walk.trc")
    moved = walk.positions.copy()
    moved[:, 2, 0] += 0.5                                   # the third marker, 0.5 mm in x
    np.save(tmp_path / "walk.npy", moved)
    code, out, err = cli(capsys, "compare", tmp_path / "walk.trc", tmp_path / "walk.npy",
                         "--json")
    doc = json.loads(out)
    assert code == 0 and "NPY stores no marker names; markers compared in order" in err
    assert doc["max"] == pytest.approx(0.5) and doc["per_marker_max"][walk.names[2]] == \
        pytest.approx(0.5) and doc["per_marker_max"][walk.names[0]] == 0
    np.save(tmp_path / "few.npy", moved[:, :3])
    code, out, err = cli(capsys, "compare", tmp_path / "walk.trc", tmp_path / "few.npy")
    assert code == 2 and out == "" and f"marker counts differ ({walk.n_markers} vs 3)" in err


def test_compare_unitless_against_units_compares_numbers(walk, tmp_path, capsys):
    a = tmp_path / "walk.trc"
    write(walk, a)
    b = tmp_path / "walk.csv"                      # CSV keeps no units
    moved = walk.positions + np.array([0.0, 0.0, 2.0])
    write(with_(moved_m := with_(walk, positions=moved), units=""), b)
    code, out, err = cli(capsys, "compare", a, b, "--json")
    doc = json.loads(out)
    assert code == 0 and doc["max"] == pytest.approx(max_error(walk.positions, moved_m.positions))
    assert doc["units"] == "mm" and "has no length unit" in err and "as numbers" in err


def test_compare_real_trc_in_metres_at_120_hz(shared_data, tmp_path, capsys):
    """QA report: the sed-edited TRC (m, 120 Hz) compared "max 0 mm", exit 0."""
    src = shared_data / "trc" / "opensim_subject01_walk1.trc"
    lines = src.read_text().split("\n")
    assert lines[2].startswith("60.00\t60.00") and "\tmm\t" in lines[2]
    in_m = lines[:2] + [lines[2].replace("\tmm\t", "\tm\t")] + lines[3:]
    (tmp_path / "m.trc").write_text("\n".join(in_m))
    at_120 = in_m[:2] + [in_m[2].replace("60.00\t60.00", "120.00\t120.00", 1)] + in_m[3:]
    (tmp_path / "m120.trc").write_text("\n".join(at_120))
    code, out, err = cli(capsys, "compare", src, tmp_path / "m120.trc")
    assert code == 2 and "60 Hz" in err and "120 Hz" in err
    a = mpz.io.read(src)
    ok = a.valid
    want = float(np.linalg.norm(999 * a.positions[ok], axis=1).max())
    code, out, err = cli(capsys, "compare", src, tmp_path / "m.trc", "--json")
    assert code == 0 and json.loads(out)["max"] == pytest.approx(want, rel=1e-9)


# -- 3. an angle summary is in the skeleton's angle unit ------------------------------------



def amc(values: np.ndarray, unit: str) -> str:
    head = ":FULLY-SPECIFIED\n" + (":DEGREES\n" if unit == "deg" else "")
    rows = [f"{i + 1}\nroot {' '.join(f'{v:g}' for v in r[:6])}\n"
            f"b1 {' '.join(f'{v:g}' for v in r[6:])}\n" for i, r in enumerate(values)]
    return head + "".join(rows)


def best_two_segments(x: np.ndarray) -> float:
    """The least sum of squared deviations from the segment means, over every split in two."""
    return min(float(((x[:s] - x[:s].mean(0)) ** 2).sum() + ((x[s:] - x[s:].mean(0)) ** 2).sum())
               for s in range(1, len(x)))


@pytest.mark.parametrize("unit, scale", [("deg", 1.0), ("rad", 0.01)])
def test_angle_summary_is_labelled_in_the_skeletons_angle_unit(tmp_path, capsys, unit, scale,
                                                              one_bone_asf):
    rng = np.random.default_rng(7)
    values = np.round(np.concatenate([rng.normal(0, 1, (8, 8)), rng.normal(5, 1, (8, 8))]), 2)
    values[:, 3:] *= scale                        # the rotations, in the ASF's angle unit
    (tmp_path / "t.asf").write_text(one_bone_asf(angle=unit))
    (tmp_path / "t.amc").write_text(amc(values, unit))
    want = best_two_segments(values)
    code, out, err = cli(capsys, "summary", tmp_path / "t.amc", "--asf", tmp_path / "t.asf",
                         "--space", "angles", "--k", "2", "--json")
    doc = json.loads(out)
    assert code == 0, err
    assert doc["units"] == unit and doc["wssse_units"] == f"{unit}^2"
    assert doc["levels"][0]["wssse"] == pytest.approx(want, rel=1e-9)
    assert "3 translations in the skeleton's length units" in doc["description"]
    code, out, _ = cli(capsys, "summary", tmp_path / "t.amc", "--asf", tmp_path / "t.asf",
                       "--space", "angles", "--k", "2")
    assert f"WSSSE {want:.6g} {unit}\u00b2" in out and "mm\u00b2" not in out
    packed = tmp_path / "t.mpz"                    # read back from an .mpz: the same label
    code, _, err = cli(capsys, "encode", tmp_path / "t.amc", "--asf", tmp_path / "t.asf",
                       "-o", packed, "--summary", "2", "--summary-space", "angles", "-q")
    assert code == 0, err
    code, out, _ = cli(capsys, "summary", packed, "--json", "--no-decode")
    assert json.loads(out)["wssse_units"] == f"{unit}^2"


def test_real_amc_angle_summary_is_in_degrees(shared_data, capsys):
    """QA report: 02_01.amc --space angles --k 6 printed "WSSSE 571181 mm²"."""
    code, out, _ = cli(capsys, "summary", shared_data / "amc" / "02_01.amc", "--space",
                       "angles", "--k", "6", "--json")
    doc = json.loads(out)
    assert code == 0 and doc["units"] == "deg" and doc["wssse_units"] == "deg^2"


# -- 4. a k asked of an .mpz that the file does not store -----------------------------------

def test_summary_of_an_mpz_warns_of_a_k_it_does_not_store(tmp_path, capsys):
    m = generate("walk", frames=20, seed=2)
    packed = tmp_path / "short.mpz"
    packed.write_bytes(mpz.encode(m, max_error=1.0, summary=(3, 300)))
    code, out, err = cli(capsys, "summary", packed, "--no-decode", "--json")
    assert code == 0 and [lv["k"] for lv in json.loads(out)["levels"]] == [3, 20]
    code, out, err = cli(capsys, "summary", packed, "--no-decode", "--k", "3,300")
    assert code == 1 and "k=300 not stored in the file (stored: 3, 20)" in err
    assert [lv["k"] for lv in _levels_of_table(out)] == [3]
    # none of the k asked is stored: an error, as for a motion none of whose k fits (it
    # printed the header of a table of no row, exit 1: a QA run of stop 53)
    code, out, err = cli(capsys, "summary", packed, "--no-decode", "--k", "300")
    assert code == 2 and out == ""
    assert f"{packed}: no requested k is stored in the file (stored: 3, 20)" in err


def _levels_of_table(out: str) -> list[dict]:
    """The k of each level table ``mpz summary`` prints ("k = 3: ..." lines)."""
    import re
    return [{"k": int(k)} for k in re.findall(r"^k\s*=\s*(\d+)", out, re.M)]


# -- 5. besides the markers: what else a source keeps comes back -----------------------------
# A C3D's archive and a BVH's skeleton and channels (issue 12's "nothing is lost"): mpz
# compare says which parts came back the same, within their declared bound, changed, or not.

def parts(doc: dict) -> dict[str, dict]:
    return {p["name"]: p for p in doc["besides_markers"]}


@pytest.fixture(scope="module")
def c3d_pair(tmp_path_factory) -> tuple[Path, Path, Motion]:
    """A synthetic C3D with model outputs, analog words and events, and its .mpz."""
    from mpz.tools.make_vectors import c3d_motion
    d = tmp_path_factory.mktemp("c3d")
    src, packed = d / "a.c3d", d / "a.mpz"
    write(c3d_motion(3, storage=1, F=30, M=5, J=2, C=3, n=2), src)
    m = mpz.io.read(src)
    packed.write_bytes(mpz.encode(m, max_error=0.5))
    return src, packed, m


def test_compare_says_a_c3d_archive_came_back(c3d_pair, tmp_path, capsys):
    src, packed, m = c3d_pair
    a, b = m.extras["c3d"], mpz.decode(packed.read_bytes()).extras["c3d"]
    code, out, err = cli(capsys, "compare", src, packed, "--json")
    got = parts(json.loads(out))
    # one part per model output kind: c3d_motion(3) has an angle (kind 0) and a power (3)
    assert a.model_kinds == [0, 3]
    assert code == 0 and list(got) == ["C3D header", "C3D parameters", "point words",
                                       "analog", "model angles", "model powers"]
    assert all(got[n]["status"] == "same" for n in list(got)[:4])
    assert got["C3D header"]["detail"] == "512 bytes, 2 events in its event block"
    assert got["analog"]["detail"] == f"3 channels x {30 * 2} samples"
    for j, name in enumerate(("model angles", "model powers")):
        e = np.abs(a.models[:, j] - b.models[:, j])[a.model_valid[:, j]]
        assert got[name]["status"] == "within"
        assert got[name]["error"] == float(e.max())
        assert got[name]["bound"] == float(b.model_bounds[j].max())
        assert got[name]["unit"] is None        # the synthetic file names no POINT:*_UNITS
    code, out, _ = cli(capsys, "compare", src, packed)
    assert "besides the markers:" in out and "analog              same: 3 channels" in out
    # written back as C3D: the model outputs have no bound in a C3D file
    back = tmp_path / "back.c3d"
    code, _, err = cli(capsys, "decode", packed, "-o", back)
    assert code == 0, err
    code, out, _ = cli(capsys, "compare", src, back, "--json")
    got = parts(json.loads(out))
    assert code == 0 and got["C3D header"]["status"] == "same"
    assert got["C3D parameters"]["status"] == "same"
    c = mpz.io.read(back).extras["c3d"]                    # float32 values of the decode
    for j, name in enumerate(("model angles", "model powers")):
        d = np.where(a.model_valid[:, j, None], np.abs(a.models[:, j] - c.models[:, j]), 0)
        f, x = np.unravel_index(int(np.argmax(d)), d.shape)
        assert got[name]["status"] == "changed" and got[name]["error"] == float(d.max()) > 0
        assert got[name]["detail"].endswith(f"largest at 'OUT{j}', frame index {f}, "
                                            f"{'xyz'[x]}")


def test_compare_names_a_lost_archive_and_fails_on_a_changed_one(c3d_pair, tmp_path, capsys):
    src, packed, m = c3d_pair
    code, out, err = cli(capsys, "decode", packed, "-o", tmp_path / "a.csv")
    assert code == 0, err
    code, out, err = cli(capsys, "compare", src, tmp_path / "a.csv", "--json")
    got = parts(json.loads(out))
    assert code == 0 and got["C3D archive"]["status"] == "missing"       # as decode's note
    assert "a.csv does not hold the original's C3D archive: 2 model outputs" in err
    # one analog word changed in a C3D otherwise the same: exit 2, the part named
    a = m.extras["c3d"]
    analog = a.analog.copy()
    analog[5, 2] += 1
    import dataclasses
    changed = dataclasses.replace(m, extras={"c3d": dataclasses.replace(a, analog=analog)})
    write(changed, tmp_path / "b.c3d")
    code, out, _ = cli(capsys, "compare", src, tmp_path / "b.c3d")
    assert code == 2 and "analog              differs: 3 channels" in out
    assert "C3D header          same" in out


def test_each_part_of_an_archive_is_compared():
    """Each change the comparison must see, and the two it must not (the data start)."""
    import dataclasses

    from mpz.io.c3dbin import record_params
    from mpz.metrics import besides_markers
    from mpz.tools.make_vectors import c3d_motion
    m = c3d_motion(4, storage=1, F=20, M=4, J=2, C=2, n=2)
    a = m.extras["c3d"]
    b = dataclasses.replace(a, model_bounds=np.full((2, 3), 1e-9))
    start = next(i for i, r in enumerate(a.records) if r.name == b"DATA_START")
    other = next(i for i, r in enumerate(a.records) if r.name == b"RATE")

    def status(**change) -> dict[str, str]:
        d = dataclasses.replace(m, extras={"c3d": dataclasses.replace(b, **change)})
        return {p.name: p.status for p in besides_markers(m, d)}

    def where(name: str, **change) -> str:
        """What the detail says after the part's own description, where it differs."""
        d = dataclasses.replace(m, extras={"c3d": dataclasses.replace(b, **change)})
        return next(p.detail for p in besides_markers(m, d) if p.name == name).split("; ", 1)[-1]

    def header(at: int) -> bytes:
        h = bytearray(a.header)
        h[at] ^= 1
        return bytes(h)

    def record(i: int) -> list:
        rs = list(a.records)
        rs[i] = dataclasses.replace(rs[i], data=bytes([rs[i].data[0] ^ 1]) + rs[i].data[1:])
        return rs
    assert set(status().values()) == {"same", "within"}
    assert status(header=header(16))["C3D header"] == "same"          # word 9: data start
    assert status(header=header(17))["C3D header"] == "same"
    assert status(header=header(18))["C3D header"] == "differs"
    assert status(header=header(0))["C3D header"] == "differs"
    assert status(header=a.header[:500])["C3D header"] == "differs"
    assert status(records=record(start))["C3D parameters"] == "same"
    assert status(records=record(other))["C3D parameters"] == "differs"
    assert status(records=a.records[:-1])["C3D parameters"] == "differs"
    words = a.words.copy()
    words[3, 1] = -words[3, 1] - 1
    assert status(words=words)["point words"] == "differs"
    assert status(slots=a.slots[::-1])["point words"] == "differs"
    assert status(analog=a.analog.astype("<f8"))["analog"] == "differs"    # same values
    nan = a.analog.copy()
    nan.view("<u4")[nan != nan] ^= 1                                       # NaN payload
    assert (nan != nan).any() and status(analog=nan)["analog"] == "differs"
    models = a.models.copy()
    models[~np.isnan(models)] += 2e-9
    assert status(models=models)["model angles"] == "differs"              # beyond 1e-9
    assert status(models=models, model_bounds=np.full((2, 3), 3e-9))["model angles"] \
        == "within"
    assert a.model_valid[0, 1]
    gaps = a.model_valid.copy()
    gaps[0, 1] = False
    assert status(model_valid=gaps)["model powers"] == "differs"
    assert status(model_valid=gaps)["model angles"] == "within"
    assert status(model_bounds=None)["model angles"] == "same"            # no bound: equal
    assert status(models=models, model_bounds=None)["model powers"] == "changed"
    assert status(model_kinds=[0, 0])["model outputs"] == "differs"
    # where each differs: the C3D points are RFHD LBHD LFHD OUT1 OUT0 RBHD (slots 1 2 0 5 4
    # 3: model output 0 is OUT0, 1 is OUT1); the analog channels have no labels
    rf = record_params(a.records)["POINT"]["LABELS"]
    assert rf == ["RFHD", "LBHD", "LFHD", "OUT1", "OUT0", "RBHD"] and a.model_kinds == [0, 3]
    assert where("C3D header", header=header(18)).startswith("byte 18 (word 10) differs")
    rates = [f"{g}:RATE" for g in record_params(a.records) if "RATE" in
             record_params(a.records)[g]]
    assert where("C3D parameters", records=record(other)) == f"differ: {rates[0]}"
    assert where("C3D parameters", records=a.records[:-1]).endswith(
        f"{len(a.records)} records against {len(a.records) - 1}; lost: group 9:ORPHAN")
    assert where("point words", words=words) == "first at 'LBHD', frame index 3"
    changed = a.analog.copy()
    changed[7, 1] = 12345.0
    changed[9, 0] = -2.5
    assert a.analog[7, 1] != 12345.0 and a.analog[9, 0] != -2.5
    assert where("analog", analog=changed) == ("2 words differ, the first of 'channel 2' at "
                                               "sample index 7 (frame index 3)")
    assert where("model powers", model_valid=gaps) == "a gap came at 'OUT1', frame index 0"
    one = a.models.copy()
    one[5, 0, 2] += 2e-9
    assert where("model angles", models=one).startswith(
        "first beyond its bound at 'OUT0', frame index 5, z: 2e-09 > 1e-09")
    lost = dataclasses.replace(m, extras={})
    assert [p.status for p in besides_markers(m, lost)] == ["missing"]


def test_compare_holds_joint_channels_to_the_steps_bound(tmp_path, capsys):
    src, packed = encoded_sweep(capsys, tmp_path, "--angle-error", "0.3",
                                "--translation-error", "0.05")
    a = mpz.io.read(src)
    b = mpz.decode(packed.read_bytes())
    from mpz.skeleton import is_rotation, report
    rep = report(packed.read_bytes())
    turns = np.array([is_rotation(k) for k in a.extras["skeleton"].channel_kinds()])
    d = np.abs(a.angles - b.angles)
    code, out, _ = cli(capsys, "compare", src, packed, "--json")
    got = parts(json.loads(out))
    assert code == 0 and got["skeleton"]["status"] == "same"
    rot, tra = got["joint rotations"], got["joint translations"]
    assert rot["status"] == tra["status"] == "within"
    assert rot["error"] == float(d[:, turns].max()) and rot["bound"] == rep["angle_bound"]
    assert tra["error"] == float(d[:, ~turns].max()) and tra["bound"] == rep["translation_bound"]
    assert 0 < rot["error"] <= 0.3 and 0 < tra["error"] <= 0.05 + 1e-12    # decimal steps
    # from standard input, the bound is read from the same bytes
    import subprocess
    import sys
    p = subprocess.run([sys.executable, "-m", "mpz.tools.mpz_cli", "compare", str(src), "-",
                        "--json"], stdin=packed.open("rb"), capture_output=True, check=False)
    assert p.returncode == 0, p.stderr
    assert parts(json.loads(p.stdout))["joint rotations"] == rot
    # a BVH written back holds no bound; a CSV holds no skeleton
    code, _, err = cli(capsys, "decode", packed, "-o", tmp_path / "back.bvh")
    code, out, _ = cli(capsys, "compare", src, tmp_path / "back.bvh", "--json")
    got = parts(json.loads(out))["joint rotations"]
    c = mpz.io.read(tmp_path / "back.bvh")
    d = np.abs(a.angles - c.angles)[:, turns]
    f, k = np.unravel_index(int(np.argmax(d)), d.shape)
    name = [n for n, t in zip(a.angle_names, turns, strict=True) if t][k]
    assert got["status"] == "changed" and got["error"] == float(d.max()) > 0
    assert got["detail"].endswith(f"no bound declared; largest at {name!r}, frame index {f}")
    code, _, err = cli(capsys, "decode", packed, "-o", tmp_path / "back.csv")
    code, out, err = cli(capsys, "compare", src, tmp_path / "back.csv", "--json")
    assert code == 0 and parts(json.loads(out))["skeleton"]["status"] == "missing"
    assert "does not hold the original's skeleton: 3 joints and 2 End Sites" in err


def test_joint_translations_are_in_the_unit_units_named(tmp_path, capsys):
    """A BVH has no length unit; its .mpz has the one --units named: the translations'
    figures are in it (before: "the BVH's length unit", unit null)."""
    src, packed = encoded_sweep(capsys, tmp_path, "--units", "cm")
    code, out, _ = cli(capsys, "compare", src, packed, "--json")
    got = parts(json.loads(out))["joint translations"]
    assert code == 0 and got["unit"] == "cm" and got["detail"].startswith("3 channels, in cm")
    code, out, _ = cli(capsys, "compare", src, tmp_path / "sweep.bvh", "--json")
    got = parts(json.loads(out))["joint translations"]
    assert got["unit"] is None and "in the BVH's length unit" in got["detail"]


def test_joint_channels_beyond_their_bound_differ():
    import dataclasses

    from mpz.metrics import besides_markers
    from mpz.motion import Motion as M_
    a = mpz.io.read_bytes(bvh_text().encode(), fmt=".bvh")
    moved = a.angles.copy()
    moved[7, 4] += 0.25                                    # a rotation (Xrotation of Hips)
    b = M_(a.positions, a.names, a.rate, a.units, a.valid, a.metadata, a.parents, moved,
           a.angle_names, a.extras)
    got = {p.name: p for p in besides_markers(a, b, channel_bounds=(0.2, 1.0))}
    assert got["joint rotations"].status == "differs"
    assert got["joint rotations"].error == pytest.approx(0.25)
    assert a.angle_names[4] == "Hips.Xrotation"    # bvh_text: X/Y/Zposition Z/X/Yrotation
    assert got["joint rotations"].detail == ("7 channels, in deg; first beyond its bound at "
                                             "'Hips.Xrotation', frame index 7: 0.25 > 0.2")
    sk = a.extras["skeleton"]
    joints = list(sk.joints)
    joints[1] = dataclasses.replace(joints[1], offset=(0.0, 11.0, 0.0))
    other = dataclasses.replace(sk, joints=tuple(joints))
    c = M_(a.positions, a.names, a.rate, a.units, a.valid, a.metadata, a.parents, a.angles,
           a.angle_names, {**a.extras, "skeleton": other})
    (skel, *_) = besides_markers(a, c)
    ends = sum(j.end_site for j in joints)                   # BVH End Sites (stop 55)
    assert ends == 2 and (skel.status, skel.detail) == (
        "differs", f"{len(joints) - ends} joints and 2 End Sites; differ: joints Spine")
    assert got["joint translations"].status == "within" and got["joint translations"].error == 0
    got = {p.name: p for p in besides_markers(a, b, channel_bounds=(0.3, 1.0))}
    assert got["joint rotations"].status == "within"


def test_compare_reads_a_decoded_amc_with_its_own_asf(tmp_path, capsys, one_bone_asf):
    """--asf is the original's skeleton: a decoded AMC is read with the .asf mpz decode
    wrote beside it, so a bone that came back another length is seen (it was not)."""
    rng = np.random.default_rng(3)
    (tmp_path / "t.asf").write_text(one_bone_asf())
    (tmp_path / "t.amc").write_text(amc(np.round(rng.normal(0, 5, (12, 8)), 2), "deg"))
    src, asf, packed = tmp_path / "t.amc", tmp_path / "t.asf", tmp_path / "t.mpz"
    code, _, err = cli(capsys, "encode", src, "--asf", asf, "-o", packed, "-q")
    assert code == 0, err
    out_dir = tmp_path / "back"
    out_dir.mkdir()
    code, _, err = cli(capsys, "decode", packed, "-o", out_dir / "t.amc")
    assert code == 0 and (out_dir / "t.asf").exists(), err
    code, out, _ = cli(capsys, "compare", src, out_dir / "t.amc", "--asf", asf, "--json")
    assert code == 0 and parts(json.loads(out))["skeleton"]["status"] == "same"
    text = (out_dir / "t.asf").read_text()
    assert "     length 2\n" in text
    (out_dir / "t.asf").write_text(text.replace("     length 2\n", "     length 3\n"))
    for extra in ((), ("--decoded-asf", out_dir / "t.asf")):
        code, out, _ = cli(capsys, "compare", src, out_dir / "t.amc", "--asf", asf, "--json",
                           *extra)
        assert code == 2 and parts(json.loads(out))["skeleton"]["status"] == "differs"
    # an AMC with no .asf beside it is read with --asf's, and the report says so
    lone = tmp_path / "lone"
    lone.mkdir()
    (lone / "x.amc").write_bytes((out_dir / "t.amc").read_bytes())
    code, out, err = cli(capsys, "compare", src, lone / "x.amc", "--asf", asf, "--json")
    assert code == 0 and parts(json.loads(out))["skeleton"]["status"] == "unchecked"
    assert "has no .asf beside it" in err and "is not checked" in err
    # without --asf either: the error names the option for the decoded input
    code, out, err = cli(capsys, "compare", out_dir / "t.amc", lone / "x.amc")
    assert code == 2 and "no .asf skeleton found beside the decoded x.amc; name it: " \
        "--decoded-asf PATH" in err
    # an .asf found by its prefix, not <stem>.asf: named in a note
    (lone / "x.asf").write_bytes((out_dir / "t.asf").read_bytes())
    (lone / "x.amc").rename(lone / "x_01.amc")
    code, out, err = cli(capsys, "compare", src, lone / "x_01.amc", "--asf", asf)
    assert "x_01.amc is read with " in err and "x.asf (the .asf beside it" in err
    # a skeleton option for an input that is no AMC: said, not silently unused
    code, out, err = cli(capsys, "compare", src, packed, "--asf", asf, "--decoded-asf", asf)
    assert code == 0 and "--decoded-asf names an AMC decoded input's skeleton" in err


def test_real_c3d_archives_come_back(shared_data, tmp_path, capsys):
    """auckland: 36 model outputs, 24 analog channels, 12 events, 10 parameter groups."""
    src = shared_data / "c3d" / "auckland_FMC_MH0222_BP06.c3d"
    packed = tmp_path / "a.mpz"
    code, _, err = cli(capsys, "encode", src, "-o", packed, "--max-error", "1mm", "-q")
    assert code == 0, err
    code, out, _ = cli(capsys, "compare", src, packed, "--json")
    got = parts(json.loads(out))
    assert code == 0 and [p["status"] for p in got.values()] == ["same"] * 4 + ["within"] * 4
    assert "EVENT:USED 12" in got["C3D parameters"]["detail"]
    # each kind in the unit its POINT parameter names (auckland: deg, W, N, Nmm)
    assert {n: (p["unit"], p["detail"]) for n, p in got.items() if n.startswith("model")} == {
        "model angles": ("deg", "12 points, in deg (POINT:ANGLE_UNITS)"),
        "model powers": ("W", "6 points, in W (POINT:POWER_UNITS)"),
        "model forces": ("N", "10 points, in N (POINT:FORCE_UNITS)"),
        "model moments": ("Nmm", "8 points, in Nmm (POINT:MOMENT_UNITS)")}
    code, out, _ = cli(capsys, "compare", src, packed)
    assert "model moments       within " in out and " Nmm: largest " in out
    # cmu_02_01 written back as C3D: its data starts elsewhere (header word 9 and
    # POINT:DATA_START), which is not a difference
    src = shared_data / "c3d" / "cmu_02_01.c3d"
    code, _, err = cli(capsys, "encode", src, "-o", packed, "--max-error", "1mm", "-q", "-f")
    code, _, err = cli(capsys, "decode", packed, "-o", tmp_path / "back.c3d")
    assert code == 0, err
    assert mpz.io.read(tmp_path / "back.c3d").extras["c3d"].header[16:18] != \
        mpz.io.read(src).extras["c3d"].header[16:18]
    code, out, _ = cli(capsys, "compare", src, tmp_path / "back.c3d", "--json")
    got = parts(json.loads(out))
    assert code == 0 and got["C3D header"]["status"] == got["C3D parameters"]["status"] \
        == "same"


def test_compare_says_whether_a_trcs_header_fields_came_back(walk, tmp_path, capsys):
    """A TRC's header fields are free metadata (not mpz.io.READER_KEYS): kept in the .mpz,
    written back to a TRC, not held by a CSV."""
    import dataclasses

    from mpz.io import READER_KEYS
    from mpz.metrics import besides_markers
    src, packed = tmp_path / "w.trc", tmp_path / "w.mpz"
    write(walk, src)
    m = mpz.io.read(src)
    fields = sorted(k for k in m.metadata if k not in READER_KEYS)
    assert len(fields) >= 10 and all(k.startswith("trc.") for k in fields)
    code, _, err = cli(capsys, "encode", src, "-o", packed, "--max-error", "0.01mm", "-q")
    assert code == 0, err
    code, out, _ = cli(capsys, "compare", src, packed, "--json")
    assert code == 0 and parts(json.loads(out))["metadata"] == {
        "name": "metadata", "status": "same", "detail": f"{len(fields)} entries",
        "error": None, "bound": None, "unit": None}
    for ext, status in ((".trc", "same"), (".csv", "missing")):
        code, _, err = cli(capsys, "decode", packed, "-o", tmp_path / f"back{ext}")
        code, out, err = cli(capsys, "compare", src, tmp_path / f"back{ext}", "--json")
        assert code == 0 and parts(json.loads(out))["metadata"]["status"] == status
    assert f"does not hold the original's metadata: {len(fields)} of its" in err
    edited = dataclasses.replace(m, metadata={**m.metadata, fields[0]: "edited"})
    (got,) = besides_markers(m, edited)
    assert got.status == "differs"                 # a header field came back edited
    assert got.detail == f"1 of its {len(fields)} entries with other values: {fields[0]}"
    (got,) = besides_markers(m, dataclasses.replace(edited, units="m"))
    assert got.status == "changed"                 # a file in other units: Units differs
    # an entry lost beside one changed: both said, the one does not hide the other
    md = {**m.metadata, fields[0]: "edited"}
    del md[fields[1]], md[fields[2]]
    assert [(p.status, p.detail) for p in besides_markers(m, dataclasses.replace(
        m, metadata=md))] == [
        ("differs", f"1 of its {len(fields)} entries with other values: {fields[0]}"),
        ("missing", f"2 of its {len(fields)} entries: {fields[1]}, {fields[2]}")]
    (got,) = besides_markers(m, dataclasses.replace(m, metadata={**m.metadata,
                                                                 "source": "other.trc"}))
    assert got.status == "same"                     # the name of the file read: not content


def test_compare_top_0_lists_every_marker(capsys, tmp_path):
    """--top's help says 0 lists them all (as mpz search -n 0): it listed none (a QA run)."""
    m = generate("walk", frames=40, markers=6, seed=3)
    src = tmp_path / "w.npy"
    write(m, src)
    back = m.positions.copy()
    back[:, 2, 0] += np.linspace(0, 0.5, 40)              # marker 2 the worst
    np.save(tmp_path / "b.npy", back)
    code, out, _ = cli(capsys, "compare", src, tmp_path / "b.npy", "--top", "0")
    rows = out.split("marker            max        RMS\n")[1].splitlines()
    listed = [r.split()[0] for r in rows if r.startswith("  ") and len(r.split()) == 3]
    assert len(listed) == 6 and listed[0] == "M2", out   # an NPY's markers are M0, M1...
    code, out, _ = cli(capsys, "compare", src, tmp_path / "b.npy", "--top", "1")
    rows = out.split("marker            max        RMS\n")[1].splitlines()
    assert [r.split()[0] for r in rows if len(r.split()) == 3][:1] == ["M2"]


def test_two_mpz_files_of_one_source_are_held_to_the_sum_of_their_bounds(
        shared_data, tmp_path, capsys):
    """A QA run of stop 48: `mpz compare A.mpz B.mpz` (one capture encoded at 1 and at
    2 mm, or by two versions) held B's 2 mm against A as if A were the source: BEYOND,
    exit 2, for two good files, and nothing said of the files themselves. Each is within
    its own bound of the source, so they are within the sum of each other; the sizes and
    bounds are shown. The distance is measured here on the two decodes."""
    src = shared_data / "c3d" / "cmu_02_01.c3d"
    a, b = tmp_path / "a.mpz", tmp_path / "b.mpz"
    for out, e in ((a, "1mm"), (b, "2mm")):
        assert mpz_cli.main(["encode", str(src), "-o", str(out), "--max-error", e, "-q"]) == 0
    da, db = mpz.decode(a), mpz.decode(b)
    far = float(np.nanmax(np.linalg.norm(da.positions - db.positions, axis=2)))
    assert 2.0 < far <= 3.0                                   # beyond B's bound alone
    capsys.readouterr()
    assert mpz_cli.main(["compare", str(a), str(b), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["bound_check"]["bound"] == pytest.approx(3.0)
    assert doc["bound_check"]["beyond"] == 0 and doc["max"] == pytest.approx(far)
    assert doc["mpz_files"] == {"sizes": [a.stat().st_size, b.stat().st_size],
                                "bounds": [1.0, 2.0], "identical": False}
    assert mpz_cli.main(["compare", str(a), str(a)]) == 0
    assert "(byte-identical), bounds 1 mm and 1 mm" in capsys.readouterr().out


def test_two_mpz_files_differ_where_either_lacks_a_part_and_show_their_reader_entries(
        tmp_path, capsys):
    """A maintainer's QA run (stop 73): `mpz compare A.mpz B.mpz` with B lacking A's
    metadata entry (or skeleton) said "missing" with a note that blamed B's format, exit 0;
    the other way round it said nothing; and two encodes whose bytes differed only in the
    reader's warning were "same" everywhere. An .mpz holds every part: a part either file
    lacks differs (exit 2), and the reader's entries are a part of their own."""
    m = generate("walk", frames=30, markers=6, seed=5)
    m.metadata.update({"format": "trc", "warning": "first"})
    files = {}
    for name, meta, warning in (("a", {"note": "x"}, "first"), ("b", {}, "first"),
                                ("c", {"note": "x"}, "second")):
        m.metadata["warning"] = warning
        files[name] = tmp_path / f"{name}.mpz"
        files[name].write_bytes(mpz.encode(m, max_error=1.0, metadata=meta))

    def parts(a, b, code):
        capsys.readouterr()
        assert mpz_cli.main(["compare", str(files[a]), str(files[b]), "--json"]) == code
        return {(p["name"], p["status"]): p["detail"]
                for p in json.loads(capsys.readouterr().out)["besides_markers"]}
    got = parts("a", "b", 2)
    assert f"(not in {files['b']}, and an .mpz file holds it)" in got[("metadata", "differs")]
    assert ("reader metadata", "same") in got
    got = parts("b", "a", 2)
    assert f"(only in {files['a']}, and an .mpz file holds it)" in got[("metadata", "differs")]
    got = parts("a", "c", 0)
    assert ("metadata", "same") in got and not any(s == "differs" for _, s in got)
    assert got[("reader metadata", "changed")].endswith("(what each file's reader said of "
                                                        "its source): warning")


# -- summaries as the spec allows them (QA, stop 49) -----------------------------------------
VECTORS = Path(__file__).resolve().parents[1] / "conformance" / "vectors"


def _reordered_summary(tmp_path: Path) -> Path:
    """A file whose smry holds its levels k = 5, then k = 2 (spec §4.10: any order)."""
    import dataclasses

    from mpz.chunks import Smry
    from mpz.container import parse
    from mpz.tools.make_vectors import assemble
    data = mpz.encode(generate("walk", frames=60, seed=3), max_error=1.0, summary=(2, 5),
                      summary_format="smry")
    chunks = []
    for c in parse(data):
        payload = c.payload
        if c.type == "smry":
            rec = Smry.load(payload)
            assert [lv.k for lv in rec.levels] == [2, 5]
            payload = dataclasses.replace(rec, levels=rec.levels[::-1]).dump()
        chunks.append([c.type, payload])
    path = tmp_path / "reordered.mpz"
    path.write_bytes(assemble(chunks))
    assert [lv.k for lv in mpz.read_summary(path).levels] == [5, 2]
    return path


def test_the_finest_and_coarsest_levels_are_chosen_by_k_not_by_place(tmp_path, capsys):
    """A summary's levels may come in any order: preview()'s default "finest" took the last
    level stored (k = 2 here) and the plot's "coarsest" the first (k = 5)."""
    path = _reordered_summary(tmp_path)
    assert mpz.read_summary(path).preview().metadata["preview"] == "summary k=5 (constant)"
    pytest.importorskip("matplotlib")
    png = tmp_path / "s.png"
    code, out, err = cli(capsys, "summary", str(path), "--plot", str(png))
    assert code == 0 and png.is_file()
    from mpz.tools.cmd_summary import thumbnail_level
    assert thumbnail_level([{"k": 5}, {"k": 2}, {"k": 2}])["k"] == 2


@pytest.mark.parametrize("name", ["uncommon/u21-smry-angles-no-dims.mpz",
                                  "uncommon/u38-smrc-angles-no-dims.mpz",
                                  "uncommon/u44-smrc-angles-d5.mpz"])
def test_a_plot_of_an_angle_summary_draws_no_poses(name, tmp_path, capsys):
    """An angle summary with D = 0 crashed --plot (exit 70: its empty means taken for
    poses, since 0 % 3 == 0), and one of a BVH (D = 6 + 3 J) drew degrees as poses."""
    pytest.importorskip("matplotlib")
    png = tmp_path / "s.png"
    code, out, err = cli(capsys, "summary", str(VECTORS / name), "--plot", str(png))
    assert code == 0 and png.is_file(), err
    from mpz.tools.cmd_summary import thumbnail_means
    level = {"k": 2, "means": np.zeros((2, 6))}
    assert thumbnail_means({"space": "angles"}, level) is None
    assert thumbnail_means({"space": "positions"}, level) is not None
    assert thumbnail_means({"space": "positions"}, {"k": 2, "means": np.zeros((2, 0))}) is None


def test_space_that_an_mpz_summary_is_not_in_is_said(capsys):
    code, out, err = cli(capsys, "summary", str(VECTORS / "valid/v13-smrc-positions.mpz"),
                         "--space", "angles")
    assert code == 1 and "positions" in err and "--space angles" in err
    code, out, err = cli(capsys, "summary", str(VECTORS / "valid/v13-smrc-positions.mpz"))
    assert code == 0 and "--space" not in err


def test_a_wssse_of_minus_zero_prints_as_zero(capsys):
    code, out, err = cli(capsys, "summary", str(VECTORS / "uncommon/u21-smry-angles-no-dims.mpz"))
    assert code == 0 and "-0 " not in out and "WSSSE 0 " in out, out


def test_compare_says_marker_without_plot_changes_nothing(tmp_path, capsys):
    """A maintainer's QA run (stop 50): --marker NOPE without --plot was ignored without a
    word, while --bound without --plot was noted."""
    m = generate("walk", frames=30, seed=2)
    write(m, tmp_path / "a.trc")
    (tmp_path / "a.mpz").write_bytes(mpz.encode(m, max_error=1.0))
    code, _, err = cli(capsys, "compare", str(tmp_path / "a.trc"), str(tmp_path / "a.mpz"),
                       "--marker", "NOPE")
    assert code == 0, err
    assert "--marker chooses the markers of --plot, which was not asked for" in err


def test_compare_plots_an_original_of_gaps_alone(tmp_path, capsys):
    """No marker of an all-gap original has an error, so the three worst were none and the
    figure had no panel: matplotlib's ValueError, exit 70 (a QA run of stop 53). The first
    three markers are drawn."""
    pytest.importorskip("matplotlib")
    m = Motion(np.full((60, 4, 3), np.nan), ["A", "B", "C", "D"], 120.0, "mm")
    write(m, tmp_path / "g.trc")
    code, out, err = cli(capsys, "compare", str(tmp_path / "g.trc"), str(tmp_path / "g.trc"),
                         "--plot", str(tmp_path / "g.png"))
    assert code == 0, err
    png = (tmp_path / "g.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    import matplotlib.image
    height = matplotlib.image.imread(str(tmp_path / "g.png")).shape[0]
    assert height > 110 * 6, height             # three panels of 2 inches at 110 dpi


def test_summary_of_an_original_of_gaps_alone_says_so_and_plots_quietly(tmp_path, capsys):
    """Every marker a gap throughout: mpz summary printed cuts at 0 WSSSE and exited 0,
    and its plot made matplotlib warn of singular axis limits (a QA run of stop 53)."""
    pytest.importorskip("matplotlib")
    import warnings
    m = Motion(np.full((50, 4, 3), np.nan), ["A", "B", "C", "D"], 100.0, "mm")
    write(m, tmp_path / "g.trc")
    with warnings.catch_warnings():
        warnings.simplefilter("error")              # any matplotlib warning fails
        code, out, err = cli(capsys, "summary", str(tmp_path / "g.trc"), "--k", "2",
                             "--plot", str(tmp_path / "g.png"))
    assert code == 1, err
    assert "every marker is a gap throughout: there is no motion to segment" in err
    assert (tmp_path / "g.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_summary_of_an_npy_says_the_rate_it_assumes_and_takes_rate(tmp_path, capsys):
    """An NPY stores no rate: mpz summary segmented it at 1 Hz without a word, its times in
    frames, and had no --rate (a QA run of stop 53); mpz encode and search had both."""
    x = np.random.default_rng(0).normal(size=(200, 5, 3)).cumsum(axis=0)
    np.save(tmp_path / "q.npy", x)
    code, out, err = cli(capsys, "summary", str(tmp_path / "q.npy"), "--k", "2", "--json")
    assert code == 0 and json.loads(out)["rate"] == 1.0
    assert "NPY stores no frame rate: 1 Hz is assumed; give the true one with --rate HZ" in err
    code, out, err = cli(capsys, "summary", str(tmp_path / "q.npy"), "--k", "2", "--json",
                         "--rate", "100")
    doc = json.loads(out)
    assert code == 0 and doc["rate"] == 100.0 and "assumed" not in err
    last = doc["levels"][0]["segments"][-1]
    assert last["start_time"] == last["start"] / 100 and last["start"] > 0
    write(generate("walk", frames=60), tmp_path / "w.trc")
    code, _, err = cli(capsys, "summary", str(tmp_path / "w.trc"), "--rate", "100")
    assert code == 2 and "this TRC stores its rate (120 Hz)" in err
    (tmp_path / "w.mpz").write_bytes(mpz.encode(generate("walk", frames=60)))
    code, _, err = cli(capsys, "summary", str(tmp_path / "w.mpz"), "--rate", "100")
    assert code == 2 and "an .mpz file stores its rate" in err


def test_summary_escapes_the_file_name_in_its_warnings_and_errors(tmp_path, capsys):
    """The warnings and errors added at stop 53 printed the file name as it was: an ESC
    or a line feed in it drove the terminal (a review of stop 53)."""
    x = np.full((30, 4, 3), np.nan)
    name = tmp_path / "a\x1b[31m\nb.npy"
    np.save(name, x)
    code, out, err = cli(capsys, "summary", str(name), "--k", "2")
    assert code == 1 and "\x1b" not in err and "a\\x1b[31m\\x0ab.npy" in err, err
    assert "every marker is a gap throughout" in err
    code, out, err = cli(capsys, "summary", str(name), "--k", "500")
    assert code == 2 and "\x1b" not in err and "a\\x1b[31m\\x0ab.npy: no requested k" in err


def test_compare_an_amc_with_its_encode_at_another_rate(tmp_path, capsys, one_bone_asf):
    """An AMC stores no rate (its reader assumes 120 Hz); encoded with --rate 60, as the
    README says, it could never be compared with its source: "frame rates differ", exit
    2 (a QA run of stop 53). The rates are not compared, with a note."""
    rng = np.random.default_rng(4)
    (tmp_path / "t.asf").write_text(one_bone_asf())
    (tmp_path / "t.amc").write_text(amc(np.round(rng.normal(0, 5, (12, 8)), 2), "deg"))
    src, asf, packed = tmp_path / "t.amc", tmp_path / "t.asf", tmp_path / "t.mpz"
    code, _, err = cli(capsys, "encode", src, "--asf", asf, "--rate", "60", "-o", packed, "-q")
    assert code == 0, err
    code, out, err = cli(capsys, "compare", src, packed, "--asf", asf, "--json")
    assert code == 0 and json.loads(out)["max"] <= json.loads(out)["bound_check"]["bound"]
    assert "(120 Hz assumed): an AMC stores no frame rate; rates not compared (120 vs 60 Hz)" \
        in err, err
    m = generate("walk", frames=12)                               # a stored rate: refused
    write(m, tmp_path / "w.trc")
    write(Motion(m.positions, m.names, 60.0, m.units), tmp_path / "w60.trc")
    code, _, err = cli(capsys, "compare", tmp_path / "w.trc", tmp_path / "w60.trc")
    assert code == 2 and "frame rates differ: 120 Hz" in err


def test_two_encodes_of_an_amc_are_held_to_the_sum_of_their_channel_steps(
        tmp_path, capsys, one_bone_asf):
    """Two .mpz files of one AMC at two angle errors: each is within its own steps of the
    source, so they may differ by the sum; the channels were held to one file's steps and
    two good files failed (exit 2, a QA run of stop 53). The markers already were."""
    rng = np.random.default_rng(5)
    (tmp_path / "t.asf").write_text(one_bone_asf())
    (tmp_path / "t.amc").write_text(amc(np.round(rng.normal(0, 30, (40, 8)), 3), "deg"))
    src, asf = tmp_path / "t.amc", tmp_path / "t.asf"
    for name, err in (("fine", "0.01"), ("coarse", "0.2")):
        code, _, e = cli(capsys, "encode", src, "--asf", asf, "--angle-error", err, "-o",
                         tmp_path / f"{name}.mpz", "-q")
        assert code == 0, e
    for pair in (("fine", "coarse"), ("coarse", "fine")):
        code, out, err = cli(capsys, "compare", *(tmp_path / f"{n}.mpz" for n in pair),
                             "--json")
        rot = parts(json.loads(out))["joint rotations"]
        assert code == 0 and rot["status"] == "within", (pair, rot, err)
        assert rot["bound"] == pytest.approx(0.01 + 0.2), rot


def test_two_encodes_of_a_c3d_hold_model_outputs_to_the_sum(shared_data, tmp_path, capsys):
    src = shared_data / "c3d" / "auckland_FMC_MH0222_BP06.c3d"
    a, b = tmp_path / "a.mpz", tmp_path / "b.mpz"
    assert cli(capsys, "encode", src, "-o", a, "-q")[0] == 0
    assert cli(capsys, "encode", src, "--model-error", "ANGLES=1e-3", "-o", b, "-q")[0] == 0
    code, out, err = cli(capsys, "compare", a, b, "--json")
    angles = parts(json.loads(out))["model angles"]
    assert code == 0 and angles["status"] == "within", (angles, err)


def test_summary_names_a_damaged_mpz_file_in_its_error(tmp_path, capsys):
    """mpz summary of an .mpz file with a bad CRC said "error: chunk RESI, offset ...",
    naming no file, where mpz show, decode, compare and search name it (a QA run of stop
    53)."""
    data = bytearray(mpz.encode(generate("walk", frames=60), max_error=1.0, summary=(4,)))
    data[-40] ^= 0x55                                   # in the last chunks, before MEND
    bad = tmp_path / "bad.mpz"
    bad.write_bytes(bytes(data))
    for extra in ((), ("--no-decode",)):
        code, out, err = cli(capsys, "summary", str(bad), *extra)
        assert code == 2 and f"mpz summary: error: {bad}, chunk " in err, (extra, err)


def test_compare_names_the_marker_a_renamed_one_became(tmp_path, capsys):
    """A marker renamed in the decoded file was told as missing alone; the name it took
    went unsaid (a report QA run of stop 55). Both are named now, and a marker merely
    missing names no new one."""
    m = generate("walk", frames=20, markers=6, seed=1)
    write(m, tmp_path / "src.trc")
    renamed = Motion(m.positions, [*m.names[:2], "Renamed", *m.names[3:]], m.rate, m.units,
                     m.valid)
    write(renamed, tmp_path / "renamed.trc")
    code, _, err = cli(capsys, "compare", tmp_path / "src.trc", tmp_path / "renamed.trc")
    assert code == 2
    assert (f"markers missing from the decoded motion: {m.names[2]}; it has markers the "
            "original has not: Renamed") in err
    dropped = Motion(m.positions[:, 1:], m.names[1:], m.rate, m.units, m.valid[:, 1:])
    write(dropped, tmp_path / "dropped.trc")
    code, _, err = cli(capsys, "compare", tmp_path / "src.trc", tmp_path / "dropped.trc")
    assert code == 2 and f"missing from the decoded motion: {m.names[0]}" in err
    assert "has not" not in err


def test_summary_json_says_what_each_wssse_is_of(tmp_path, capsys):
    """An .mpz's level wssse is the source's, as stored; its segments' are measured on the
    decoded motion, and in --json they did not add up, with nothing saying why (a report
    QA run of stop 55). Each level now says both, with the segments' sum; for a source
    file the two are of one motion and agree."""
    m = generate("walk", frames=120, markers=6, seed=2)
    write(m, tmp_path / "src.trc")
    (tmp_path / "a.mpz").write_bytes(mpz.encode(m, max_error=5.0, summary=(3,)))
    code, out, _ = cli(capsys, "summary", tmp_path / "a.mpz", "--k", "3", "--json")
    (lv,) = json.loads(out)["levels"]
    assert code == 0 and lv["wssse_of"] == "the source, as stored"
    assert lv["segments_of"] == "the decoded motion"
    assert lv["segments_wssse_total"] == pytest.approx(sum(s["wssse"] for s in lv["segments"]),
                                                       rel=1e-12)
    assert lv["segments_wssse_total"] != lv["wssse"]            # the coding error
    code, out, _ = cli(capsys, "summary", tmp_path / "src.trc", "--k", "3", "--json")
    (lv,) = json.loads(out)["levels"]
    assert lv["wssse_of"] == lv["segments_of"] == "the motion read"
    assert lv["segments_wssse_total"] == pytest.approx(lv["wssse"], rel=1e-9)


def test_compare_of_a_dec_or_mips_c3d_says_it_compares_values(shared_data, tmp_path, capsys):
    """`mpz compare` of a MIPS or DEC C3D with the Intel C3D decoded from it said "C3D
    header same" and "C3D parameters same", where hundreds of their bytes differ (a report
    QA run of stop 55). The values are the same (spec §6.9 writes Intel); the lines now
    say that they compared values, in which byte orders. An Intel source gets no such
    words. The processor is read from the files' own parameter sections (byte 4)."""
    for name in ("c3dorg_Eb015sr.c3d", "c3dorg_Eb015vr.c3d", "c3dorg_Eb015pi.c3d"):
        src = shared_data / "c3d" / name
        data = src.read_bytes()
        proc = {84: "Intel", 85: "DEC", 86: "MIPS"}[data[(data[0] - 1) * 512 + 3]]
        code, _, _ = cli(capsys, "encode", src, "-o", tmp_path / "a.mpz", "-f", "-q")
        code, _, _ = cli(capsys, "decode", tmp_path / "a.mpz", "-o", tmp_path / "a.c3d", "-f",
                         "-q")
        back = tmp_path / "a.c3d"
        assert back.read_bytes()[(back.read_bytes()[0] - 1) * 512 + 3] == 84
        code, out, _ = cli(capsys, "compare", src, back, "--json")
        got = parts(json.loads(out))
        said = f"compared as values: the bytes are in {proc} order against Intel"
        for part in ("C3D header", "C3D parameters"):
            assert got[part]["status"] == "same", got[part]
            assert (said in got[part]["detail"]) == (proc != "Intel"), got[part]


def test_marker_layer_compares_a_skeletal_encode_with_one_without_like_with_like(
        tmp_path, capsys):
    """A maintainer's QA run of stop 75: two versions' encodes of one AMC, the new with a
    skeleton chunk and the old without, were compared as the joint positions of the new
    one's channels against the old one's marker layer (1.66 mm apart, exit 2), where the
    two marker layers agreed to 2e-13 mm, and no option compared those. A note now says
    which is which, and --marker-layer compares the marker layers alone (the distance
    measured here on mpz.decode(markers_only=True)), held to the sum of the MHDR bounds,
    with no part besides the markers; two same-size files that differ say so."""
    src, with_skeleton = encoded_sweep(capsys, tmp_path, "--units", "cm", "--max-error",
                                       "1mm")
    without = tmp_path / "plain.mpz"
    code, _, err = cli(capsys, "encode", src, "-o", without, "--units", "cm", "--max-error",
                       "1mm", "--no-skeleton", "-q")
    assert code == 0, err
    layers = [mpz.decode(p, markers_only=True).positions for p in (without, with_skeleton)]
    far = float(np.nanmax(np.linalg.norm(layers[0] - layers[1], axis=2)))
    code, out, err = cli(capsys, "compare", without, with_skeleton, "--json")
    assert f"{with_skeleton} gives the joint positions of its skeleton's channels and " \
        f"{without} its marker layer" in err and "--marker-layer compares" in err
    assert json.loads(out)["max"] != pytest.approx(far, abs=1e-12)
    assert json.loads(out)["bound_check"]["of"] == "markers and joint positions"
    code, out, err = cli(capsys, "compare", without, with_skeleton, "--marker-layer",
                         "--json")
    doc = json.loads(out)
    assert code == 0 and doc["max"] == pytest.approx(far, rel=1e-9, abs=1e-12)
    assert doc["besides_markers"] == [] and doc["bound_check"]["bound"] == pytest.approx(0.2)
    assert doc["positions"] == {"original": "decoded markers", "decoded": "decoded markers"}
    assert "--marker-layer: the markers alone are compared" in err
    twins = [tmp_path / "t1.mpz", tmp_path / "t2.mpz"]
    for twin, value in zip(twins, ("a", "b"), strict=True):
        assert cli(capsys, "encode", src, "-o", twin, "--units", "cm", "--no-skeleton",
                   "--meta", f"take={value}", "-q")[0] == 0
    code, out, _ = cli(capsys, "compare", *twins)
    assert "(the same size, other bytes)" in out
