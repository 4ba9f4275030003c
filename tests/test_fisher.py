"""Exact optimal partition (mpz.fisher): oracles, invariants, baselines, helpers.

Oracles: brute force over every (n-1 choose k-1) partition for n <= 12, and an
independent O(k n^2) numpy DP over an explicit cost matrix for larger n.

Baselines: PAA, DFT and Haar are research code in ``bench/baselines.py``, not
in the ``mpz`` package. This module loads that file by its path
(``importlib.util.spec_from_file_location``; ``sys.path`` is not touched)
instead of computing the baselines again inside the test, because the claims
checked here (optimal <= PAA, optimal <= first-k Haar, first-k Haar = dyadic
PAA, Parseval for DFT and Haar) are claims about the very functions whose
numbers ``bench/bench_fisher.py`` prints for the paper's Figs 3-7; a second
copy in the test could agree with itself while the bench's copy drifted. The
oracles for the optimal partition itself stay independent of both.
"""
from __future__ import annotations

import importlib.util
import itertools
from pathlib import Path
import sys
from types import ModuleType

from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
import numba
import numpy as np
import pytest

from mpz import Motion
from mpz.errors import EncoderError, MPZError
from mpz.fisher import (
    Partition,
    choose_k_for_threshold,
    max_deviation,
    motion_series,
    optimal_partitions,
    preview_series,
    segment_means,
    wssse,
)


def _load_baselines() -> ModuleType:
    """``bench/baselines.py``, imported from its path (see the module docstring)."""
    path = Path(__file__).resolve().parents[1] / "bench" / "baselines.py"
    spec = importlib.util.spec_from_file_location("mpz_bench_baselines", path)
    assert spec is not None and spec.loader is not None, path
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # so that pickling and dataclasses can find it
    spec.loader.exec_module(module)
    return module


baselines = _load_baselines()
paa, dft_approx, haar_approx = baselines.paa, baselines.dft_approx, baselines.haar_approx


# -- oracles ------------------------------------------------------------------------
def _cost_matrix(x):
    """c[t, j] = squared error of frames t..j-1 about their mean, two-pass, for t < j."""
    n = x.shape[0]
    c = np.full((n + 1, n + 1), np.inf)
    for t in range(n):
        for j in range(t + 1, n + 1):
            seg = x[t:j]
            c[t, j] = float(((seg - seg.mean(axis=0)) ** 2).sum())
    return c


def brute_force(x, k):
    """Least WSSSE over all partitions of x into k segments, and every minimiser's starts."""
    n = x.shape[0]
    c = _cost_matrix(x)
    best, arg = np.inf, None
    for cuts in itertools.combinations(range(1, n), k - 1):
        b = (0, *cuts, n)
        v = sum(c[b[i], b[i + 1]] for i in range(k))
        if v < best:
            best, arg = v, b[:-1]
    return best, arg


def reference_table(x, k_max):
    """Plain O(k n^2) DP over an explicit cost matrix.

    T[j, k-1] = least WSSSE of x[:j] in k segments.
    """
    n = x.shape[0]
    c = _cost_matrix(x)
    T = np.full((n + 1, k_max), np.inf)
    T[:, 0] = c[0]  # one segment
    for k in range(2, k_max + 1):
        for j in range(k, n + 1):
            T[j, k - 1] = np.min(T[:j, k - 2] + c[:j, j])
    return T


def reference_dp(x, k_max):
    """Least WSSSE of the whole series per k, from :func:`reference_table`."""
    T = reference_table(x, k_max)
    return {k: T[-1, k - 1] for k in range(1, k_max + 1)}


def total_ss(x):
    x = np.asarray(x, float).reshape(len(x), -1)
    return float(((x - x.mean(axis=0)) ** 2).sum())


def assert_valid(p: Partition, x, k):
    x = np.asarray(x, float).reshape(len(x), -1)
    n = x.shape[0]
    assert p.k == k and p.starts.dtype == np.int64 and p.starts.shape == (k,)
    assert p.starts[0] == 0 and np.all(np.diff(p.starts) > 0) and p.starts[-1] < n
    # every frame in exactly one segment
    owner = np.searchsorted(p.starts, np.arange(n), side="right") - 1
    assert np.array_equal(np.bincount(owner, minlength=k), p.lengths(n))
    assert p.lengths(n).sum() == n and np.all(p.lengths(n) >= 1)
    assert p.means.shape == (k, x.shape[1])
    np.testing.assert_allclose(p.means, segment_means(x, p.starts), rtol=0,
                               atol=1e-12 * (1 + np.abs(x).max()))
    assert p.wssse == pytest.approx(wssse(x, p.starts), rel=1e-12, abs=1e-12)


def random_walk(n, D, seed):
    return np.cumsum(np.random.default_rng(seed).normal(size=(n, D)), axis=0)


def random_starts(rng, n, k):
    return np.sort(np.concatenate([[0], rng.choice(np.arange(1, n), k - 1, replace=False)]))


# -- table tests ----------------------------------------------------------------------
# (case, x, k, expected starts, expected WSSSE)
CASES = [
    ("single frame", [[3.0]], 1, [0], 0.0),
    ("k = 1 is the total sum of squares", [1.0, 0.0, 1.0], 1, [0], 2.0 / 3.0),
    ("ANCHORS x=[1,0,1], tie -> smallest split", [1.0, 0.0, 1.0], 2, [0, 1], 0.5),
    ("k = n is zero", [1.0, 0.0, 1.0], 3, [0, 1, 2], 0.0),
    ("constant series, tie -> smallest splits", [2.0] * 5, 3, [0, 1, 2], 0.0),
    ("two plateaus", [1, 1, 1, 5, 5], 2, [0, 3], 0.0),
    ("three plateaus, 2-D", [[0, 0], [0, 0], [4, 1], [4, 1], [4, 1], [-2, 7]], 3, [0, 2, 5], 0.0),
    ("outlier gets its own segment", [0, 0, 0, 100, 0, 0], 3, [0, 3, 4], 0.0),
    ("ramp in two", [0, 1, 2, 3], 2, [0, 2], 1.0),
]


@pytest.mark.parametrize("case,x,k,starts,expected", CASES, ids=[c[0] for c in CASES])
def test_table(case, x, k, starts, expected):
    p = optimal_partitions(np.asarray(x, float), k)[k]
    assert p.starts.tolist() == starts
    assert p.wssse == pytest.approx(expected, abs=1e-12)
    assert_valid(p, np.asarray(x, float), k)


def test_anchor_cost_is_not_quadrangle_convex():
    # ANCHORS: w(1,2) + w(2,3) = 1.0 > w(1,3) + w(2,2) = 0.667 (1-based, inclusive)
    x = np.array([1.0, 0.0, 1.0])

    def w(i, j):
        return wssse(x[i - 1:j], [0])

    assert w(1, 2) + w(2, 3) == pytest.approx(1.0)
    assert w(1, 3) + w(2, 2) == pytest.approx(2.0 / 3.0)
    assert w(1, 2) + w(2, 3) > w(1, 3) + w(2, 2)


# -- brute-force oracle (hypothesis) -------------------------------------------------------
series_small = st.integers(1, 12).flatmap(lambda n: st.integers(1, 3).flatmap(
    lambda D: st.one_of(
        hnp.arrays(np.float64, (n, D), elements=st.floats(-1e3, 1e3, allow_subnormal=False)),
        # small integers: many exact ties and zero-cost segments
        hnp.arrays(np.float64, (n, D), elements=st.integers(-3, 3).map(float)))))


@settings(max_examples=300, deadline=None)
@given(series_small)
def test_matches_brute_force(x):
    n = x.shape[0]
    parts = optimal_partitions(x, n)
    assert sorted(parts) == list(range(1, n + 1))
    scale = total_ss(x)
    for k, p in parts.items():
        assert_valid(p, x, k)
        best, _ = brute_force(x, k)
        # 1e-9 relative, plus rounding of the prefix-sum costs (~n eps of the total)
        # and of the two-pass WSSSE itself (~(eps |x|)^2 per frame)
        tol = 1e-9 * best + 1e-12 * scale + 1e-24 * float((x ** 2).sum())
        assert abs(p.wssse - best) <= tol, (k, p, best)


@settings(max_examples=100, deadline=None)
@given(series_small)
def test_monotone_in_k_and_exact_at_n(x):
    n = x.shape[0]
    parts = optimal_partitions(x, n)
    w = [parts[k].wssse for k in range(1, n + 1)]
    tol = 1e-12 * total_ss(x) + 1e-24 * float((x ** 2).sum())
    assert all(b <= a + tol for a, b in zip(w, w[1:], strict=False)), w
    assert w[-1] == 0.0
    assert w[0] == pytest.approx(total_ss(x), rel=1e-12, abs=tol)


def test_oracle_can_fail():
    """The brute-force check is not vacuous: a non-optimal partition is caught."""
    x = np.array([[0.0], [0.0], [5.0], [5.0], [1.0]])
    best, starts = brute_force(x, 2)
    assert list(starts) == [0, 2]
    assert wssse(x, [0, 1]) > best + 1e-6


# -- larger n: independent DP, baselines, determinism ---------------------------------------
@pytest.mark.parametrize("n,D,k_max,seed",
                         [(70, 2, 12, 1), (150, 5, 20, 2), (40, 1, 40, 3), (300, 2, 300, 8)])
def test_matches_reference_dp(n, D, k_max, seed):
    x = random_walk(n, D, seed)
    ref = reference_dp(x, k_max)
    parts = optimal_partitions(x, k_max)
    for k in range(1, k_max + 1):
        assert parts[k].wssse == pytest.approx(ref[k], rel=1e-9, abs=1e-12 * total_ss(x))


@pytest.mark.parametrize("threads", [1, 2])
def test_whole_dp_table_matches_reference(threads):
    """Every prefix and every k, across many blocks and both thread splits."""
    from mpz.fisher import _tables
    x = random_walk(260, 3, 9)
    T = reference_table(x, 12)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
        F, P = _tables(x, 12)
    finally:
        numba.set_num_threads(before)
    feasible = np.isfinite(T)
    assert np.array_equal(np.isfinite(F[1:]), feasible[1:])
    np.testing.assert_allclose(F[1:][feasible[1:]], T[1:][feasible[1:]], rtol=1e-9, atol=1e-9)


def haar_sse(x, k):
    """Squared error of the first-k Haar reconstruction (a piecewise constant, <= k pieces)."""
    return float(((haar_approx(x, k) - x) ** 2).sum())


@pytest.mark.parametrize("n,D,seed", [(200, 3, 4), (500, 7, 5), (100, 2, 6)])
def test_better_than_paa_haar_and_random_partitions(n, D, seed):
    """The paper's claim: optimal <= PAA and optimal <= Haar at the same k numbers per dim."""
    x = random_walk(n, D, seed)
    rng = np.random.default_rng(seed)
    parts = optimal_partitions(x, 48, ks=[1, 2, 3, 6, 12, 24, 48])
    for k, p in parts.items():
        assert_valid(p, x, k)
        assert p.wssse <= paa(x, k).wssse * (1 + 1e-12)
        assert p.wssse <= haar_sse(x, k) * (1 + 1e-12) + 1e-9
        for _ in range(20):
            assert p.wssse <= wssse(x, random_starts(rng, n, k)) * (1 + 1e-12) + 1e-9


def test_same_answer_for_any_thread_count():
    # periodic integers: exact ties everywhere; n spans many blocks so the
    # threads' minima are merged, which must keep the smallest split
    x = np.tile([[1.0, 0.0], [0.0, 1.0], [1.0, 0.0], [2.0, 2.0]], (60, 1))
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = optimal_partitions(x, 16)
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        many = optimal_partitions(x, 16)
    finally:
        numba.set_num_threads(before)
    for k in one:
        assert one[k].starts.tolist() == many[k].starts.tolist()
        assert one[k].wssse == many[k].wssse


def test_ks_subset_and_translation_invariance():
    x = random_walk(120, 4, 6)
    a = optimal_partitions(x, 30, ks=[5, 30])
    b = optimal_partitions(x + 1e4, 30)
    assert sorted(a) == [5, 30]
    for k in a:
        assert a[k].starts.tolist() == b[k].starts.tolist()


def test_real_recording(shared_data):
    ezc3d = pytest.importorskip("ezc3d")
    c = ezc3d.c3d(str(shared_data / "c3d" / "cmu_02_01.c3d"))
    pts = c["data"]["points"][:3].transpose(2, 1, 0)
    names = [f"m{i}" for i in range(pts.shape[1])]
    motion = Motion(pts, names, rate=120.0, units="mm")
    x, what = motion_series(motion)
    assert x.shape == (343, 123) and "centroid" in what
    n = x.shape[0]
    rng = np.random.default_rng(7)
    ks = [1, 2, 6, 12, 24, 48]
    parts = optimal_partitions(x, 48)
    ref = reference_dp(x, 8)
    for k in range(1, 9):
        assert parts[k].wssse == pytest.approx(ref[k], rel=1e-9)
    prev = np.inf
    for k in range(1, 49):
        assert parts[k].wssse <= prev * (1 + 1e-12)
        prev = parts[k].wssse
    for k in ks:
        p = parts[k]
        assert_valid(p, x, k)
        assert p.wssse <= paa(x, k).wssse
        assert p.wssse <= haar_sse(x, k) * (1 + 1e-12)
        for _ in range(20):
            assert p.wssse <= wssse(x, random_starts(rng, n, k))
    assert optimal_partitions(x, n, ks=[n])[n].wssse == 0.0


# -- input validation ------------------------------------------------------------------------
@pytest.mark.parametrize("x,k", [
    (np.zeros((0, 3)), 1),               # no frames
    (np.zeros((3, 0)), 1),               # no dimensions
    (np.zeros((2, 2, 2)), 1),            # wrong rank
    ([1.0, np.nan, 2.0], 1),             # not finite
    ([1.0, np.inf], 1),
    ([1.0, 2.0], 0),                     # k < 1
    ([1.0, 2.0], 3),                     # k > n is an error, not clamped
    ([1.0, 2.0], 1.5),                   # not an integer
    ([1.0, 2.0], True),
    ("abc", 1),
])
def test_bad_input_raises_encoder_error(x, k):
    with pytest.raises(EncoderError) as info:
        optimal_partitions(x, k)
    assert isinstance(info.value, MPZError) and isinstance(info.value, ValueError)


def test_ks_beyond_k_max_and_bad_starts():
    with pytest.raises(EncoderError):
        optimal_partitions(np.arange(10.0), 3, ks=[4])
    for starts in ([1, 2], [0, 2, 2], [0, 5], [], [0.0]):
        with pytest.raises(EncoderError):
            wssse(np.arange(4.0), starts)
    with pytest.raises(EncoderError):
        paa(np.arange(4.0), 5)


# -- baselines --------------------------------------------------------------------------------
def test_paa_starts():
    assert paa(np.arange(10.0), 3).starts.tolist() == [0, 3, 6]
    assert paa(np.arange(7.0), 7).starts.tolist() == list(range(7))
    assert paa(np.arange(7.0), 7).wssse == 0.0


@pytest.mark.parametrize("n", [1, 2, 7, 8, 33])
def test_dft_budget(n):
    x = random_walk(n, 3, n)
    np.testing.assert_allclose(dft_approx(x, n), x, atol=1e-9 * (1 + np.abs(x).max()))
    np.testing.assert_allclose(dft_approx(x, 1), np.broadcast_to(x.mean(axis=0), x.shape),
                               atol=1e-9)
    errs = [((dft_approx(x, k) - x) ** 2).sum() for k in range(1, n + 1)]
    # projections onto nested subspaces
    assert all(b <= a + 1e-9 for a, b in zip(errs, errs[1:], strict=False))
    big = [((dft_approx(x, k, select="largest") - x) ** 2).sum() for k in range(1, n + 1)]
    assert all(g <= e + 1e-9 for g, e in zip(big, errs, strict=True))  # best k beat the first k


def test_dft_recovers_a_sinusoid_with_three_numbers():
    t = np.arange(64)
    x = 2.0 + np.cos(2 * np.pi * t / 64) + 0.5 * np.sin(2 * np.pi * t / 64)
    np.testing.assert_allclose(dft_approx(x, 3), x, atol=1e-12)
    assert np.abs(dft_approx(x, 2) - x).max() > 0.4  # sine part dropped


@pytest.mark.parametrize("n", [1, 4, 16])
def test_haar_exact_and_parseval(n):
    x = random_walk(n, 2, 10 + n)
    np.testing.assert_allclose(haar_approx(x, n), x, atol=1e-9)
    np.testing.assert_allclose(haar_approx(x, n, select="largest"), x, atol=1e-9)
    if n >= 4:
        # orthonormal: error equals the energy of the dropped coefficients, and keeping
        # the largest is optimal among all coefficient subsets of that size
        w = np.sort(np.abs(baselines.haar_forward(x)), axis=0)[::-1]
        for k in range(1, n + 1):
            err = ((haar_approx(x, k, select="largest") - x) ** 2).sum()
            assert err == pytest.approx((w[k:] ** 2).sum(), abs=1e-9)
            assert err <= ((haar_approx(x, k) - x) ** 2).sum() + 1e-9


@pytest.mark.parametrize("k", [1, 2, 4, 8, 16])
def test_haar_first_is_dyadic_paa(k):
    x = random_walk(64, 3, k)
    p = paa(x, k)
    np.testing.assert_allclose(haar_approx(x, k), preview_series(p.starts, p.means, 64), atol=1e-9)


def test_haar_piecewise_constant_and_padding():
    x = np.array([5.0, 5.0, 5.0, 5.0, 1.0, 1.0, 1.0, 1.0])
    np.testing.assert_allclose(haar_approx(x, 2), x, atol=1e-12)
    y = np.array([3.0, 3.0, 3.0, 3.0, 3.0])  # padded to 8
    np.testing.assert_allclose(haar_approx(y, 1, pad="edge"), y, atol=1e-12)
    assert np.abs(haar_approx(y, 1, pad="zero") - y).max() > 1.0
    with pytest.raises(EncoderError):
        haar_approx(y, 1, pad="mirror")


# -- motions, previews, threshold ----------------------------------------------------------------
def _gappy_motion():
    pos = np.zeros((5, 3, 3))
    pos[:, 0] = np.arange(5)[:, None] * [1.0, 0.0, 0.0]   # marker A moves along x
    pos[:, 1] = [0.0, 10.0, 0.0]                           # marker B fixed
    valid = np.ones((5, 3), bool)
    valid[[0, 2, 3], 0] = False                            # A: gap at start and in the middle
    valid[:, 2] = False                                    # C: gap throughout
    pos[~valid] = np.nan
    return Motion(pos, ["A", "B", "C"], rate=100.0, units="mm", valid=valid)


def test_motion_series_fills_gaps_and_centres():
    m = _gappy_motion()
    x, what = motion_series(m)
    assert x.shape == (5, 9) and np.all(np.isfinite(x)) and "(mm)" in what
    a = np.array([1.0, 1.0, 2.0, 3.0, 4.0])  # held before frame 1, interpolated over 2-3
    centroid_x = (a + 0.0) / 2
    np.testing.assert_allclose(x[:, 0], a - centroid_x)
    np.testing.assert_allclose(x[:, 4], 10.0 - 5.0)
    np.testing.assert_allclose(x[:, 6:], 0.0)            # C all gap -> zeros
    xr, what = motion_series(m, root="B")
    np.testing.assert_allclose(xr[:, 3:6], 0.0)
    np.testing.assert_allclose(xr[:, 0], a)
    for bad in ("Z", "C"):
        with pytest.raises(EncoderError):
            motion_series(m, root=bad)


def test_motion_series_angles():
    m = _gappy_motion()
    with pytest.raises(EncoderError, match="no joint angles"):
        motion_series(m, space="angles")
    with pytest.raises(EncoderError):
        motion_series(m, space="quaternions")
    ang = np.arange(10.0).reshape(5, 2)
    m2 = Motion(np.zeros((5, 1, 3)), ["r"], 120.0, angles=ang)
    x, _ = motion_series(m2, space="angles")
    np.testing.assert_array_equal(x, ang)


def test_preview_series():
    starts, means = [0, 2, 3], [[0.0, 1.0], [4.0, 1.0], [6.0, 0.0]]
    c = preview_series(starts, means, 6)
    np.testing.assert_array_equal(c[:, 0], [0, 0, 4, 6, 6, 6])
    lin = preview_series(starts, means, 6, mode="linear")
    # centres 0.5, 2, 4: hold, ramps, hold
    np.testing.assert_allclose(lin[:, 0], [0.0, 4 / 3, 4.0, 5.0, 6.0, 6.0])
    x = random_walk(50, 3, 11)
    p = optimal_partitions(x, 5)[5]
    assert ((preview_series(p.starts, p.means, 50) - x) ** 2).sum() == pytest.approx(p.wssse)
    with pytest.raises(EncoderError):
        preview_series([0, 1], [[1.0]], 3)
    with pytest.raises(EncoderError):
        preview_series([0], [[1.0]], 3, mode="cubic")


def test_choose_k_for_threshold():
    x = np.array([[0.0, 0.0], [0.1, 0.0], [5.0, 5.0], [5.0, 5.2], [9.0, 0.0]])
    p = choose_k_for_threshold(x, 0.15, 10)       # k_max clamped to n
    assert p.k == 3 and p.starts.tolist() == [0, 2, 4]
    assert max_deviation(x, p.starts).max() <= 0.15
    # the chosen k is the smallest: every smaller optimal partition breaks the bound
    parts = optimal_partitions(x, p.k)
    for k in range(1, p.k):
        assert max_deviation(x, parts[k].starts).max() > 0.15
    assert choose_k_for_threshold(x, 0.0, 5).k == 5
    with pytest.raises(EncoderError, match="raise k_max"):
        choose_k_for_threshold(x, 0.15, 2)
    with pytest.raises(EncoderError):
        choose_k_for_threshold(x, -1.0, 3)


@settings(max_examples=50, deadline=None)
@given(series_small, st.floats(0, 50))
def test_choose_k_respects_bound(x, thr):
    p = choose_k_for_threshold(x, thr, x.shape[0])
    assert max_deviation(x, p.starts).max() <= thr
    assert_valid(p, x, p.k)


@settings(max_examples=80, deadline=None)
@given(series_small, st.floats(0, 50), st.integers(1, 14))
def test_threshold_partition_is_choose_k_else_the_finest(x, thr, k_max):
    """What segmentation="optimal" takes, from one run of the programme where it ran it
    twice: choose_k_for_threshold's partition, or where that refuses, the least-WSSSE
    partition of k_max segments (k_max clamped to the frames)."""
    from mpz.errors import EncoderError
    from mpz.fisher import threshold_partition
    k = min(k_max, x.shape[0])
    got = threshold_partition(x, thr, k_max)
    try:
        want = choose_k_for_threshold(x, thr, k_max)
    except EncoderError:
        want = optimal_partitions(x, k, ks=[k])[k]
    assert got.starts.tolist() == want.starts.tolist() and got.wssse == want.wssse


@pytest.mark.parametrize("bad", [0, -3, 2.5, True])
def test_summary_max_frames_is_checked(bad):
    """summary_partitions' max_frames of 0 divided by zero (ZeroDivisionError)."""
    from mpz.errors import EncoderError
    from mpz.fisher import summary_partitions
    with pytest.raises(EncoderError, match="max_frames"):
        summary_partitions(np.zeros((5, 2)), (2,), bad)


def test_baselines_are_not_in_the_runtime_package():
    import mpz.fisher
    for name in ("paa", "dft_approx", "haar_approx", "_haar_forward", "_haar_inverse"):
        assert not hasattr(mpz.fisher, name), name
    assert baselines.__file__.endswith(str(Path("bench") / "baselines.py"))
