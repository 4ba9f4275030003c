"""mpz.metrics against hand-computed error statistics (mutation audit, stop 46).

Each expected value below is worked out by hand from the definitions in the module's
docstrings and the paper's Eq. 3 (ARMS: the mean over frames of each frame's RMS marker
error, over the samples valid in the original), never taken from the code under test.
The motions are built so that every statistic differs from its plausible wrong twin:
p99 from p95, RMS from the mean square, ARMS from the RMS over markers first, a frame that
is a gap throughout from a frame of error 0.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from mpz import Motion
from mpz.errors import MotionError
from mpz.metrics import arms, errors, max_error, summary

G = None        # a gap in the table below

#: the Euclidean error of each sample (frames x markers A, B, C, D), None at a gap of
#: the original; marker D is a gap throughout, frame 3 is a gap throughout
TABLE: list[list[float | None]] = [
    [3.0, 4.0, 0.0, G],
    [0.0, G, 12.0, G],
    [1.0, 1.0, 1.0, G],
    [G, G, G, G],
    [6.0, 8.0, 0.0, G],
]
NAMES = ["A", "B", "C", "D"]


def _pair(junk_under_gaps: bool = False) -> tuple[Motion, Motion]:
    """An original and a decoded motion whose sample errors are :data:`TABLE`: the decoded
    marker is moved by the error along a direction that changes with the sample (x, y or z
    and a diagonal), so that only the Euclidean norm gives the table's numbers."""
    F, M = len(TABLE), len(NAMES)
    base = np.arange(F * M * 3, dtype=np.float64).reshape(F, M, 3) * 10.0
    valid = np.array([[v is not None for v in row] for row in TABLE])
    moved = base.copy()
    dirs = [np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), np.array([0, 0, 1.0]),
            np.array([0.6, 0.0, 0.8])]                       # unit vectors: |.| = 1
    for f, row in enumerate(TABLE):
        for m, v in enumerate(row):
            if v is not None:
                moved[f, m] += v * dirs[(f + m) % 4]
    orig_pos = base.copy()
    if not junk_under_gaps:
        orig_pos[~valid] = np.nan
    # junk under the gaps of the original: a position the valid mask says to ignore,
    # 1000 units from the decoded one
    else:
        orig_pos[~valid] = base[~valid] + 1000.0
    dec_valid = valid.copy()
    dec_pos = moved.copy()
    dec_pos[~valid] = base[~valid]       # decoded holds something valid there
    dec_valid[~valid] = True
    original = Motion(orig_pos, NAMES, 100.0, "mm", valid)
    decoded = Motion(dec_pos, NAMES, 100.0, "mm", dec_valid)
    return original, decoded


# valid samples of TABLE: 3 4 0 | 0 12 | 1 1 1 | 6 8 0  (11 of them)
# sorted: 0 0 0 1 1 1 3 4 6 8 12
N = 11
TOTAL = 3 + 4 + 0 + 0 + 12 + 1 + 1 + 1 + 6 + 8 + 0                    # 36
SQUARES = 9 + 16 + 0 + 0 + 144 + 1 + 1 + 1 + 36 + 64 + 0               # 272
# numpy's default percentile (linear): position (N - 1) q of the sorted values
# q = 0.99: 9.9 -> 8 + 0.9 * (12 - 8) = 11.6 ; q = 0.95 would be 9.5 -> 10.0
P99 = 11.6
# ARMS: per frame, sqrt(mean of the valid squares); frame 3 has none and does not count
# f0: (9 + 16 + 0) / 3 ; f1: (0 + 144) / 2 ; f2: 3 / 3 ; f4: (36 + 64 + 0) / 3
ARMS = (math.sqrt(25 / 3) + math.sqrt(72) + 1.0 + math.sqrt(100 / 3)) / 4
# per marker: A 3 0 1 6 ; B 4 1 8 ; C 0 12 1 0 ; D none
PER_MAX: dict[str, float | None] = {"A": 6.0, "B": 8.0, "C": 12.0, "D": None}
PER_RMS: dict[str, float | None] = {"A": math.sqrt(46 / 4), "B": math.sqrt(81 / 3),
                                    "C": math.sqrt(145 / 4), "D": None}


def test_summary_statistics_are_the_hand_computed_ones() -> None:
    original, decoded = _pair()
    s = summary(original, decoded)
    assert s["max"] == pytest.approx(12.0, rel=1e-12)
    assert s["mean"] == pytest.approx(TOTAL / N, rel=1e-12)
    assert s["rms"] == pytest.approx(math.sqrt(SQUARES / N), rel=1e-12)
    assert s["p99"] == pytest.approx(P99, rel=1e-12)
    assert s["arms"] == pytest.approx(ARMS, rel=1e-12)


def test_arms_is_eq3_mean_over_frames_of_frame_rms() -> None:
    original, decoded = _pair()
    assert arms(original, decoded) == pytest.approx(ARMS, rel=1e-12)
    # not the mean over markers of the RMS over frames (the other order of Eq. 3)
    over_markers = (math.sqrt(46 / 4) + math.sqrt(81 / 3) + math.sqrt(145 / 4)) / 3
    assert abs(arms(original, decoded) - over_markers) > 0.1


def test_per_marker_max_and_rms() -> None:
    original, decoded = _pair()
    s = summary(original, decoded)
    assert set(s["per_marker_max"]) == set(NAMES)
    for name in NAMES:
        want_max, want_rms = PER_MAX[name], PER_RMS[name]
        got_max, got_rms = s["per_marker_max"][name], s["per_marker_rms"][name]
        if want_max is None:
            assert got_max is None and got_rms is None, name
        else:
            assert got_max == pytest.approx(want_max, rel=1e-12), name
            assert got_rms == pytest.approx(want_rms, rel=1e-12), name


def test_positions_under_a_gap_of_the_original_are_ignored() -> None:
    """The module docstring: statistics over samples valid in the original. The original's
    gaps hold junk 1000 units away; the decoded motion is valid there."""
    original, decoded = _pair(junk_under_gaps=True)
    s = summary(original, decoded)
    assert s["max"] == pytest.approx(12.0, rel=1e-12)
    assert s["arms"] == pytest.approx(ARMS, rel=1e-12)
    assert max_error(original, decoded) == pytest.approx(12.0, rel=1e-12)
    e = errors(original, decoded)
    want = np.array([[np.nan if v is None else v for v in row] for row in TABLE])
    np.testing.assert_allclose(e, want, rtol=1e-12, atol=1e-12)


def test_a_sample_the_decoder_loses_is_an_infinite_error() -> None:
    """The module docstring: a sample the decoder marks as a gap where the original was
    valid counts as an infinite error, so it cannot hide."""
    original, decoded = _pair()
    valid = decoded.valid.copy()
    valid[2, 1] = False                          # B at frame 2: error 1 in TABLE
    pos = decoded.positions.copy()
    pos[2, 1] = np.nan
    lost = Motion(pos, NAMES, 100.0, "mm", valid)
    assert max_error(original, lost) == math.inf
    assert errors(original, lost)[2, 1] == math.inf
    with np.errstate(invalid="ignore"):             # numpy's percentile of an inf
        assert summary(original, lost)["per_marker_max"]["B"] == math.inf


def test_motions_in_other_units_are_refused() -> None:
    """1 cm against 10 mm is no error at all, not an error of 9: the module refuses to
    compare numbers of two units rather than report one."""
    pos = np.ones((2, 1, 3))
    with pytest.raises(MotionError, match="units"):
        max_error(Motion(pos, ["A"], 100.0, "cm"), Motion(10 * pos, ["A"], 100.0, "mm"))


def test_motions_at_other_rates_are_refused_unless_a_rate_was_assumed() -> None:
    """Frame f at 120 Hz and at 60 Hz are not the same moment: max_error and arms scored
    them as if they were (a QA run of stop 53). A rate within RATE_TOLERANCE (a C3D's
    float32) is the same; one a reader assumed (an NPY's 1 Hz, ``rate_assumed`` in its
    metadata) is not compared, and one given with --rate (no such entry) is: every NPY
    counted as assumed until the review of stop 75."""
    pos = np.ones((2, 1, 3))
    a, b = Motion(pos, ["A"], 120.0, "mm"), Motion(pos, ["A"], 60.0, "mm")
    for f in (max_error, arms, errors, summary):
        with pytest.raises(MotionError, match="frame rates differ: 120 vs 60 Hz"):
            f(a, b)
    assert max_error(a, Motion(pos + 1, ["A"], 120.0 * (1 + 1e-7), "mm")) == math.sqrt(3)
    npy = Motion(pos, ["A"], 1.0, "mm", metadata={"format": "npy", "rate_assumed": "1.0"})
    assert max_error(a, npy) == 0.0 and arms(npy, a) == 0.0
    given = Motion(pos, ["A"], 60.0, "mm", metadata={"format": "npy"})
    with pytest.raises(MotionError, match="frame rates differ: 120 vs 60 Hz"):
        max_error(a, given)


def test_a_one_row_csv_has_an_assumed_rate(tmp_path: Path) -> None:
    """One time gives no rate: the CSV reader takes 1 Hz, and that was compared with the
    TRC's 60 Hz as a stored rate (a review of stop 53)."""
    from mpz.io import read, write
    m = Motion(np.array([[[1.0, 2.0, 3.0]]]), ["A"], 60.0, "mm")
    write(m, tmp_path / "one.trc")
    write(m, tmp_path / "one.csv")
    csv = read(tmp_path / "one.csv")
    assert csv.rate == 1.0 and csv.metadata["rate_assumed"] == "1.0"
    assert max_error(read(tmp_path / "one.trc"), csv) == 0.0
    write(Motion(np.ones((2, 1, 3)), ["A"], 60.0, "mm"), tmp_path / "two.csv")
    assert "rate_assumed" not in read(tmp_path / "two.csv").metadata


#: two frames of conftest's one-bone ASF (bone b1, dofs rx ry rz), in radians
AMC_RAD = """:FULLY-SPECIFIED
:RADIANS
1
root 1 2 3 0 0 0
b1 0.1 0.2 0.3
2
root 1 2 3 0 0 0
b1 0.1 0.2 0.3
"""


def test_joint_rotation_error_of_a_radian_skeleton_is_in_degrees(one_bone_asf) -> None:
    """besides_markers reports joint rotations in degrees: a channel of an ASF in radians
    changed by 0.01 rad is 0.01 * 180 / pi = 0.5729578 degrees off."""
    from dataclasses import replace

    from mpz.io.amc import parse_amc, parse_asf
    from mpz.metrics import besides_markers
    m = parse_amc(AMC_RAD, parse_asf(one_bone_asf(angle="rad", axis="0 0 0",
                                                  dofs="rx ry rz")))
    assert m.angles is not None and m.angle_names is not None
    k = m.angle_names.index("b1.ry")
    angles = m.angles.copy()
    angles[1, k] += 0.01
    parts = {p.name: p for p in besides_markers(m, replace(m, angles=angles))}
    rot = parts["joint rotations"]
    assert rot.unit == "deg" and rot.status == "changed"
    assert rot.error == pytest.approx(0.01 * 180 / math.pi, rel=1e-9)
    assert parts["joint translations"].error == 0.0


def test_a_model_output_that_came_back_nan_is_beyond_its_bound(shared_data: Path) -> None:
    """besides_markers: a lossy part beyond its declared bound "differs". A model output
    (Auckland's 36 POINT:ANGLES ... outputs) that comes back NaN where the original holds
    a number is not within any bound."""
    from dataclasses import replace

    from mpz.io import read_c3d
    from mpz.metrics import besides_markers
    m = read_c3d(shared_data / "c3d/auckland_FMC_MH0222_BP06.c3d")
    a = m.extras["c3d"]
    J = a.models.shape[1]
    bounds = np.full((J, 3), 0.5)                            # per coordinate (§6.9)
    same = replace(a, model_bounds=bounds)
    f, j = (int(v[0]) for v in np.nonzero(a.model_valid))      # a valid model sample
    models = a.models.copy()
    models[f, j, 1] = np.nan
    broken = replace(a, models=models, model_bounds=bounds)
    ok = [p for p in besides_markers(m, replace(m, extras={"c3d": same}))
          if p.name.startswith("model ")]
    assert ok and all(p.status == "within" for p in ok)
    bad = [p for p in besides_markers(m, replace(m, extras={"c3d": broken}))
           if p.name.startswith("model ")]
    assert sorted(p.status for p in bad).count("differs") == 1


def test_p99_of_samples_that_became_gaps_is_infinite_and_silent():
    """With more than 1 % of the valid samples lost to gaps, the 99th percentile lies
    between two infinite errors: numpy's interpolation took inf - inf, gave NaN and
    printed a RuntimeWarning into `mpz compare`'s report (QA runs of stop 52)."""
    import warnings
    pos = np.zeros((100, 1, 3))
    a = Motion(pos, ["m"], 100.0, "mm")
    lost = np.ones((100, 1), bool)
    lost[:5] = False                    # 5 % of the samples became gaps
    b = Motion(pos, ["m"], 100.0, "mm", lost)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        s = summary(a, b)
    assert s["p99"] == math.inf and s["max"] == math.inf
    b = Motion(pos + 1.0, ["m"], 100.0, "mm")
    assert summary(a, b)["p99"] == pytest.approx(math.sqrt(3))


@pytest.mark.parametrize("frames, lost, want", [
    (100, 5, math.inf),             # between two infinite errors: inf - inf
    (101, 1, math.sqrt(3)),         # weight 0 on an infinite error: inf x 0, p99 finite
    (1000, 1, math.sqrt(3)),
    (3, 3, math.inf),               # every sample lost
])
def test_p99_with_lost_samples_is_what_the_finite_errors_make_it(frames, lost, want):
    """The review of stop 52's first fix: it took every NaN of numpy's interpolation for
    +inf, where weight 0 on an infinite neighbour (inf x 0) hides a finite percentile."""
    import warnings
    pos = np.zeros((frames, 1, 3))
    a = Motion(pos, ["m"], 100.0, "mm")
    kept = np.ones((frames, 1), bool)
    kept[frames - lost:] = False
    b = Motion(pos + 1.0, ["m"], 100.0, "mm", kept)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = summary(a, b)["p99"]
    assert got == pytest.approx(want) if math.isfinite(want) else got == want
