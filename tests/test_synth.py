"""mpz.synth: deterministic, plausible synthetic motion."""
from __future__ import annotations

import numpy as np
import pytest

import mpz
from mpz.synth import KINDS, MARKERS, generate

CMU41 = ("LFHD RFHD LBHD RBHD C7 T10 CLAV STRN RBAC LSHO LUPA LELB LFRM LWRA LWRB LFIN "
         "RSHO RUPA RELB RFRM RWRA RWRB RFIN LFWT RFWT LBWT RBWT LTHI LKNE LSHN LANK LHEE "
         "LTOE LMT5 RTHI RKNE RSHN RANK RHEE RTOE RMT5").split()


def _dist(m, a, b):
    i, j = m.names.index(a), m.names.index(b)
    return np.linalg.norm(m.positions[:, i] - m.positions[:, j], axis=1)


@pytest.mark.parametrize("kind", KINDS)
def test_same_seed_is_byte_identical(kind):
    a = generate(kind, frames=300, seed=7, gap_fraction=0.05)
    b = generate(kind, frames=300, seed=7, gap_fraction=0.05)
    assert a.positions.tobytes() == b.positions.tobytes()
    assert a.valid.tobytes() == b.valid.tobytes()


@pytest.mark.parametrize("kind", KINDS)
def test_different_seed_differs(kind):
    a = generate(kind, frames=200, seed=1)
    b = generate(kind, frames=200, seed=2)
    assert a.positions.tobytes() != b.positions.tobytes()


@pytest.mark.parametrize("kind", KINDS)
def test_shape_names_units_metadata(kind):
    m = generate(kind, frames=50, rate=100.0, seed=3)
    assert isinstance(m, mpz.Motion)
    assert m.positions.shape == (50, 41, 3)
    assert m.names == CMU41
    assert list(MARKERS) == CMU41
    assert m.units == "mm" and m.rate == 100.0
    assert m.valid.all() and np.isfinite(m.positions).all()
    assert m.metadata == {"generator": "mpz.synth", "kind": kind, "seed": "3"}


def test_markers_subset_is_a_prefix():
    full = generate("walk", frames=40, seed=5)
    few = generate("walk", frames=40, seed=5, markers=5)
    assert few.names == CMU41[:5]
    np.testing.assert_array_equal(few.positions, full.positions[:, :5])


@pytest.mark.parametrize("frac", [0.01, 0.05, 0.2, 0.5])
def test_gap_fraction_reached(frac):
    m = generate("walk", frames=600, seed=11, gap_fraction=frac)
    # at most one run (60 frames of one marker) above the request
    assert frac <= m.gap_fraction <= frac + 60 / (600 * 41) + 1e-12
    assert np.isnan(m.positions[~m.valid]).all()
    assert np.isfinite(m.positions[m.valid]).all()


def test_gaps_are_runs_of_at_least_five_frames():
    m = generate("jump", frames=1000, seed=4, gap_fraction=0.03)
    for k in range(m.n_markers):
        g = np.concatenate([[0], (~m.valid[:, k]).astype(int), [0]])
        starts = np.flatnonzero(np.diff(g) == 1)
        ends = np.flatnonzero(np.diff(g) == -1)
        if starts.size:
            # runs may merge, but none is shorter than the minimum run length
            assert (ends - starts).min() >= 5


def test_no_gaps_by_default_and_all_gaps_possible():
    assert generate("static", frames=20).gap_fraction == 0.0
    assert generate("static", frames=20, gap_fraction=1.0).gap_fraction == 1.0


@pytest.mark.parametrize("kind", KINDS)
def test_rigid_segments_keep_their_length(kind):
    m = generate(kind, frames=1200, seed=2, noise_mm=0.3)
    # markers on one rigid segment or on a hinge axis: only noise changes the distance
    for a, b in [("LKNE", "LANK"), ("RKNE", "RANK"), ("LFHD", "RBHD"), ("LWRA", "LWRB"),
                 ("C7", "T10"), ("LFWT", "RBWT"), ("LTHI", "LKNE")]:
        assert _dist(m, a, b).std() < 3.0, (a, b)
    # but limbs do move: elbow-to-sternum distance is not constant
    if kind != "static":
        assert _dist(m, "RWRA", "STRN").std() > 10.0


@pytest.mark.parametrize("kind", KINDS)
def test_figure_is_human_sized_and_on_the_floor(kind):
    m = generate(kind, frames=600, seed=0)
    z = m.positions[..., 2]
    feet = [m.names.index(n) for n in ("LHEE", "LTOE", "RHEE", "RTOE", "LMT5", "RMT5")]
    assert 0.0 < z[:, feet].min() < 60.0          # a foot touches the floor (Z-up, mm)
    head = m.names.index("LFHD")
    assert 1550.0 < np.median(z[:, head]) < 1800.0   # head height of a ~1.75 m adult
    assert np.nanmin(z) > -5.0                   # nothing below the floor


def test_walk_travels_forward():
    m = generate("walk", frames=600, rate=120.0, seed=9)   # 5 s
    hips = [m.names.index(n) for n in ("LFWT", "RFWT", "LBWT", "RBWT")]
    pelvis = m.positions[:, hips].mean(axis=1)
    dx = pelvis[-1, 0] - pelvis[0, 0]
    assert dx > 2000.0                            # > 0.4 m/s along +X
    assert abs(pelvis[-1, 1] - pelvis[0, 1]) < 0.2 * dx
    # and static standing does not travel
    s = generate("static", frames=600, seed=9)
    ps = s.positions[:, s.names.index("C7")]
    assert np.linalg.norm(ps[-1, :2] - ps[0, :2]) < 30.0


def test_walk_cycles_similar_but_not_identical():
    m = generate("walk", frames=1200, rate=120.0, seed=3, noise_mm=0.0)
    knee = _dist(m, "LHEE", "LFWT")   # leg extension, periodic with the gait
    k = knee - knee.mean()
    ac = np.correlate(k, k, "full")[k.size - 1:] / (k @ k)
    lag = 60 + int(np.argmax(ac[60:240]))        # stride period, 0.5..2 s
    assert ac[lag] > 0.7
    assert np.abs(knee[lag:] - knee[:-lag]).max() > 1.0


def test_jump_leaves_the_ground():
    m = generate("jump", frames=1200, seed=1)
    feet = [m.names.index(n) for n in ("LHEE", "RHEE", "LTOE", "RTOE")]
    lowest = m.positions[:, feet, 2].min(axis=1)
    assert lowest.max() > 150.0 and lowest.min() < 60.0


def test_wave_raises_the_right_hand_above_the_shoulder():
    m = generate("wave", frames=600, seed=1)
    wrist = m.positions[:, m.names.index("RWRA"), 2]
    shoulder = m.positions[:, m.names.index("RSHO"), 2]
    assert (wrist[120:] > shoulder[120:]).mean() > 0.5
    lw = m.positions[:, m.names.index("LWRA"), 2]
    assert (lw < m.positions[:, m.names.index("LSHO"), 2]).all()


@pytest.mark.parametrize("kwargs", [dict(kind="run"), dict(frames=0), dict(rate=0.0),
                                    dict(gap_fraction=1.5), dict(markers=0), dict(markers=42),
                                    dict(noise_mm=-1.0)])
def test_bad_arguments_raise_mpz_errors(kwargs):
    with pytest.raises(mpz.MotionError):
        generate(**kwargs)
