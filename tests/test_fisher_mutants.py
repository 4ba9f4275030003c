"""mpz.fisher and mpz.similarity against hand computations (mutation audit, stop 46).

Each expected value is worked out by hand (in the comments) from the definitions the
modules' docstrings give: segment means and deviations, the block length
``ceil(n / max_frames)``, the linear preview through segment centres, the gap filling of
:func:`mpz.fisher.motion_series`, the descriptor's features. None is taken from the code
under test.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from mpz import Motion
from mpz.fisher import (
    block_means,
    choose_k_for_threshold,
    max_deviation,
    motion_series,
    optimal_partitions,
    preview_series,
    summary_partitions,
)
from mpz.similarity import (
    MIN_SPEED,
    Level,
    MotionSummary,
    NotDescribable,
    descriptor,
    features_for,
    rank,
    summarize,
)


# -- fisher ------------------------------------------------------------------------------
def test_tie_goes_to_the_smallest_split() -> None:
    """[1, 0, 1] in 2 segments: [1 | 0 1] and [1 0 | 1] both cost 0.5 (a pair (a, b) costs
    (a - b)^2 / 2); the module's contract gives the smallest split index, 1."""
    p = optimal_partitions([1.0, 0.0, 1.0], 2)[2]
    assert p.starts.tolist() == [0, 1]
    assert p.wssse == pytest.approx(0.5, abs=1e-15)


def test_block_length_is_the_ceiling() -> None:
    """13 frames with at most 6 exact rows: blocks of ceil(13 / 6) = 3 frames (5 blocks,
    the last of 1 frame); blocks of 2 would make 7 rows, more than 6."""
    x = np.repeat([0.0, 4.0, 1.0, 7.0, 2.0], [3, 3, 3, 3, 1])
    b, parts = summary_partitions(x, (5,), max_frames=6)
    assert b == 3
    # the five blocks are the five constant runs: cut at every block, WSSSE 0
    assert parts[5].starts.tolist() == [0, 3, 6, 9, 12]
    assert parts[5].wssse == 0.0


def test_block_means_of_a_short_last_block() -> None:
    """Rows 0..6 in blocks of 3: means 1 (0 1 2), 4 (3 4 5) and 6 (the last block, one
    row, is not divided by 3)."""
    got = block_means(np.arange(7.0)[:, None], 3)
    np.testing.assert_array_equal(got, [[1.0], [4.0], [6.0]])


def test_linear_preview_through_segment_centres() -> None:
    """Segments [0, 2) and [2, 4) of means 0 and 4 have centres 0.5 and 2.5 (frame
    (start + end - 1) / 2); linear between, held outside: 0, 1, 3, 4."""
    got = preview_series([0, 2], [[0.0], [4.0]], 4, "linear")
    np.testing.assert_array_equal(got.ravel(), [0.0, 1.0, 3.0, 4.0])


def test_max_deviation_is_euclidean() -> None:
    """Frames (0, 0) and (3, 4) in one segment: mean (1.5, 2), each frame 2.5 away."""
    assert max_deviation([[0.0, 0.0], [3.0, 4.0]], [0]).tolist() == [2.5]


def test_threshold_met_with_equality() -> None:
    """[0, 2] in one segment: mean 1, worst frame 1 away; a threshold of 1 is met
    ("<= threshold"), so one segment, not two."""
    assert choose_k_for_threshold([0.0, 2.0], 1.0, 2).starts.tolist() == [0]


def test_motion_series_fills_gaps_and_uses_the_centroid_of_seen_markers() -> None:
    """motion_series: gaps filled linearly per marker over time, the root the per-frame
    centroid of the markers valid at least once, a marker never valid all zeros."""
    nan = np.nan
    pos = np.array([
        # A            B                C              D (a gap throughout)
        [[0, 0, 0], [10, 0, 0], [0, 10, 0], [nan, nan, nan]],
        [[1, 0, 0], [nan, nan, nan], [0, 10, 0], [nan, nan, nan]],
        [[2, 0, 0], [10, 0, 6], [0, 10, 0], [nan, nan, nan]],
    ], dtype=np.float64)
    m = Motion(pos, ["A", "B", "C", "D"], 10.0, "mm")
    series, what = motion_series(m)
    # B at frame 1 by hand: halfway between (10, 0, 0) and (10, 0, 6)
    filled = pos[:, :3].copy()
    filled[1, 1] = [10.0, 0.0, 3.0]
    # centroids by hand: (10/3, 10/3, 0), (11/3, 10/3, 1), (4, 10/3, 2)
    centre = np.array([[10 / 3, 10 / 3, 0.0], [11 / 3, 10 / 3, 1.0], [4.0, 10 / 3, 2.0]])
    want = np.zeros((3, 4, 3))
    want[:, :3] = filled - centre[:, None, :]
    np.testing.assert_allclose(series, want.reshape(3, 12), rtol=0, atol=1e-12)
    assert "centroid" in what and "mm" in what


# -- similarity --------------------------------------------------------------------------
P0 = np.array([[2, 0, 0], [-2, 0, 0], [0, 1, 0], [0, -1, 0]], dtype=np.float64)
P1 = np.array([[3, 0, 0], [-3, 0, 0], [0, 1, 0], [0, -1, 0]], dtype=np.float64)


def _summary(second: np.ndarray, wssse: float) -> MotionSummary:
    """4 frames at 2 Hz of 4 markers: segment [0, 2) of mean pose P0, [2, 4) of ``second``
    (the fine level, k = 2), and the one-segment level of the grand mean."""
    grand = (P0 + second) / 2
    fine = Level(2, np.array([0, 2], np.int64),
                 np.stack([P0.ravel(), second.ravel()]).astype(np.float32), wssse)
    one = Level(1, np.array([0], np.int64), grand.ravel()[None].astype(np.float32),
                wssse + 4 * float(((P0 - grand) ** 2).sum()))
    return MotionSummary(4, 2.0, 12, "exact", (one, fine))


def test_descriptor_by_hand() -> None:
    """The features of :func:`_summary` (P0 then P1, WSSSE 4), by hand:

    |P0|^2 = 10, |P1|^2 = 20; sum of |x_t|^2 = 2*10 + 2*20 + 4 = 64; 4 markers;
    radius = sqrt(64 / (4 * 4)) = 2. Grand mean G = (±2.5, 0, 0), (0, ±1, 0): |G|^2 = 14.5;
    total = 64 - 4 * 14.5 = 6. ev_1 = 0 (the one segment is G); ev_2: each segment mean is
    0.5 (squared) from G, between = 2*0.5 + 2*0.5 = 2, ev = 2 / 6. amplitude =
    sqrt(6 / 16) / 2. Duration 4 / 2 Hz = 2 s. The step P1 - P0 is (±1, 0, 0) on two
    markers: norm sqrt(2); speed = sqrt(2) / sqrt(4) / 2 / 2 = sqrt(2) / 8. Pose G: G^T G / 4
    = diag(12.5, 2, 0) / 4 = diag(3.125, 0.5, 0), normalised by 3.625. Segments of 2 and
    2 frames: length cv 0.
    """
    got = descriptor(_summary(P1, 4.0), levels=(1, 2))
    want = {"ev_1": 0.0, "ev_2": 1 / 3, "amplitude": math.sqrt(6 / 16) / 2,
            "log_speed": math.log(math.sqrt(2) / 8), "shape_1": 3.125 / 3.625,
            "shape_2": 0.5 / 3.625, "log_duration": math.log(2.0), "length_cv": 0.0}
    names = features_for((1, 2))
    assert len(got) == len(names)
    for name, value in zip(names, got, strict=True):
        assert value == pytest.approx(want[name], rel=1e-6, abs=1e-9), name


def test_descriptor_speed_floor() -> None:
    """A static summary (P0 throughout, WSSSE 0) has speed 0: its log_speed is
    log(MIN_SPEED), the floor the module documents (0.05 body sizes a second)."""
    assert MIN_SPEED == 0.05
    got = dict(zip(features_for((1, 2)), descriptor(_summary(P0, 0.0), levels=(1, 2)),
                   strict=True))
    assert got["log_speed"] == pytest.approx(math.log(0.05), rel=1e-12)


def test_descriptor_markers_with_a_zero_coordinate_are_present() -> None:
    """A marker is absent only where it is zero in every segment (all three coordinates);
    each marker of P0 has a zero coordinate and is present (4 >= 3 markers)."""
    descriptor(_summary(P1, 4.0), levels=(1, 2))                   # no NotDescribable
    gone = P1.copy()
    gone[2:] = 0.0                                                  # two markers at 0
    with pytest.raises(NotDescribable):
        descriptor(MotionSummary(4, 2.0, 12, "exact", (Level(
            1, np.array([0], np.int64), gone.ravel()[None].astype(np.float32), 1.0),)),
            levels=(1,))


def test_marker_valid_in_exactly_a_tenth_of_the_frames_is_kept() -> None:
    """MIN_VALID_SHARE: a marker valid in *fewer* than 10 % of the frames is left out; one
    valid in 1 frame of 10 is kept (its columns hold its held position, not zeros)."""
    t = np.arange(10, dtype=np.float64)
    pos = np.zeros((10, 4, 3))
    pos[:, 0] = np.stack([t, 0 * t, 0 * t], axis=1)
    pos[:, 1] = [100.0, 0.0, 0.0]
    pos[:, 2] = [0.0, 100.0, 0.0]
    pos[:, 3] = [50.0, 50.0, 50.0]
    valid = np.ones((10, 4), bool)
    valid[1:, 3] = False                                           # D: 1 frame of 10
    m = Motion(pos, ["A", "B", "C", "D"], 10.0, "mm", valid)
    s = summarize(m, (1,))
    d = s.levels[0].means.reshape(4, 3)[3]
    assert np.abs(d).max() > 10.0


def test_rank_tie_goes_to_the_identical_source() -> None:
    """Two candidates at the same distance: the one flagged identical comes first, even
    when its name sorts last."""
    table = np.array([[1.0, 0.0], [1.0, 0.0], [5.0, 3.0]])
    order, dist = rank(np.array([0.0, 0.0]), table, identical=[False, True, False],
                       names=["a", "b", "c"])
    assert dist[0] == dist[1]
    assert order.tolist() == [1, 0, 2]


def test_rank_does_not_scale_up_a_feature_that_hardly_varies() -> None:
    """rank: each feature is divided by its spread over the candidates, except a feature
    that hardly varies (1e-12 here), which is left as it is. Query (0, 0), candidates
    (1, 0) and (2, 1e-12): the first feature's spread is 0.5, so the distances are 2 and
    4 (the second feature adds 1e-24 under the root)."""
    table = np.array([[1.0, 0.0], [2.0, 1e-12]])
    order, dist = rank(np.array([0.0, 0.0]), table)
    assert order.tolist() == [0, 1]
    np.testing.assert_allclose(dist, [2.0, 4.0], rtol=1e-12)


def test_ev_of_a_k_between_two_stored_levels_takes_the_smaller() -> None:
    """``ev_k`` comes from the stored level nearest to ``k``, the smaller of two equally
    near (the docstring's rule, written down after the audit): with levels 2 and 6,
    ev_4 is ev_2, not ev_6 (which differ on this motion)."""
    from mpz.synth import generate
    s = summarize(generate("walk", frames=240, seed=5), (2, 6))
    ev = {k: float(descriptor(s, (k,))[0]) for k in (2, 4, 6)}
    assert ev[2] != ev[6]
    assert ev[4] == ev[2]
