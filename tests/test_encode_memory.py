"""Encoder memory against the positions it codes (issue 11.11; the project standard: bad
input gets no huge allocation).

A QA run encoded a 183 KB BVH of 4096 joints (most without channels, so each frame line
is short) and 10,000 frames: 983 MB of joint positions, within MAX_SAMPLES, took about
11 GB to encode. The position-bound search held every joint position, their difference
with a second set, and J x depth (point, pivot) pairs of the chain with a Python list of
them; the marker layer held float64 copies of a whole node's targets on each thread
beside its lattices, and the key frames a list of every task's keys beside their
concatenation. Each stage now works a block of frames, or a few members, at a time.

The peaks are measured with tracemalloc, which numpy's and numba's allocations report to
(zero-filled buffers that only become resident as written count whole there, so these
are upper bounds of the resident memory), on small joint-heavy BVH files: a chain of
joints whose root alone has channels, random single digits (so that every frame is a
key frame of every joint), as in the QA run's file. The bounds are multiples of the
positions' own bytes, stated in docs/io-notes.md ("Size and memory"); each of these
tests failed on the encoder before this change (its old figure is given). The tests after
them hold each stage that works in blocks to the values of the whole arrays, bit for bit.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st
import numpy as np
import pytest

import mpz
from mpz import keyframe as kf
from mpz import metrics
from mpz import skeleton as sk
from mpz.encoder import EncodeOptions
from mpz.entropy import BlockEncoder
from mpz.io.bvh import parse_bvh
from mpz.io.kinematics import Joint, Skeleton, forward, lever_arms, squared_lengths
from mpz.motion import Motion


def chain_bvh(joints: int, frames: int, seed: int = 0) -> str:
    """A ROOT with 6 channels and a chain of ``joints - 1`` JOINTs without channels, an End
    Site at its end; ``frames`` lines of 6 random digits."""
    rng = np.random.default_rng(seed)
    head = ["HIERARCHY", "ROOT j0", "{", "OFFSET 0 0 0",
            "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"]
    for k in range(1, joints):
        head += [f"JOINT j{k}", "{", "OFFSET 0 1 0"]
    head += ["End Site", "{", "OFFSET 0 1 0", "}"] + ["}"] * joints
    rows = [" ".join(map(str, r)) for r in rng.integers(0, 10, (frames, 6))]
    return "\n".join(head + ["MOTION", f"Frames: {frames}", "Frame Time: 0.01", *rows]) + "\n"


@pytest.fixture(scope="module")
def warm() -> None:
    """Every kernel loaded (or compiled) before a peak is measured."""
    m = parse_bvh(chain_bvh(8, 40))
    for kw in ({}, {"max_error": 1.0}):
        mpz.metrics.summary(m, mpz.decode(mpz.encode(m, threads=1, **kw)))


@pytest.mark.parametrize("bound", [None, 1.0])
def test_a_joint_heavy_bvh_encodes_within_four_and_a_half_times_its_positions(warm, bound,
                                                                              traced_peak):
    """1024 joints x 300 frames (7.4 MB of positions), one thread (the peak of two
    threads depends on how their work overlaps): the encode allocates at most 4.5 times
    the positions' bytes, the default bound and 1 mm alike. The old encoder: 4.9 and
    10.2 times (the position search's 524,800 pairs of the chain)."""
    m = parse_bvh(chain_bvh(1024, 300, seed=1))
    peak = traced_peak(lambda: mpz.encode(m, threads=1, max_error=bound))
    assert peak <= 4.5 * m.positions.nbytes, peak / m.positions.nbytes


def test_the_position_search_holds_no_joint_positions_of_every_frame(warm, monkeypatch,
                                                                     traced_peak):
    """The steps for a joint-position bound (spec Appendix C) are searched on at most 511
    frames and checked on every frame a block at a time, with the lever arms of the
    joints that turn only: under the positions' own bytes (256 joints x 2000 frames,
    here 0.5 times), once there are more joint positions than HELD_JOINTS (a long
    capture; set low here). The old search: 3.2 times (every joint position, a second set
    and their difference, and the pairs)."""
    m = parse_bvh(chain_bvh(256, 2000, seed=2))
    monkeypatch.setattr(sk, "HELD_JOINTS", 1 << 16, raising=False)
    opts = EncodeOptions(position_error=1.0)
    peak = traced_peak(lambda: sk.settings(m, m.extras["skeleton"], opts))
    assert peak <= m.positions.nbytes, peak / m.positions.nbytes


def test_the_error_report_measures_a_block_of_frames_at_a_time(warm, traced_peak):
    """mpz encode's report (metrics.summary) computes the distances a block of frames at
    a time, and ARMS from them: 1.1 times the positions at most (the old one: 3.3, the
    differences and their squares whole, twice)."""
    m = parse_bvh(chain_bvh(1024, 300, seed=3))
    back = mpz.decode(mpz.encode(m, threads=1))
    peak = traced_peak(lambda: metrics.summary(m, back))
    assert peak <= 1.1 * m.positions.nbytes, peak / m.positions.nbytes


def test_the_error_report_lets_every_distance_go_before_the_valid_ones_are_kept(traced_peak):
    """metrics.summary takes what needs the distances of every sample (each marker's
    largest and RMS error, ARMS) before it keeps those of the valid samples, and lets
    the first go; the squares are formed in place, and the 99th percentile partitions the
    valid ones in place: at most 0.8 times the positions on a long motion of 41 markers
    (0.74; before: 1.06, both sets of distances held, with two temporaries of their size
    and numpy's copy for the percentile; the peak of `mpz encode` of the 30-minute
    capture as NPY at 1 mm). The distances are made a block of frames at a time, so the
    motion is long beside a block (the test above: 300 frames, four blocks)."""
    F, M = 20_000, 41
    rng = np.random.default_rng(5)
    a = np.cumsum(rng.normal(0, 1, (F, M, 3)), axis=0)
    b = a + rng.normal(0, 0.3, (F, M, 3))
    valid = rng.random((F, M)) > 0.05
    a[~valid], b[~valid] = np.nan, np.nan
    names = [f"m{k}" for k in range(M)]
    m = Motion(a, names, 100.0, "mm", valid)
    back = Motion(b, names, 100.0, "mm", valid.copy())
    peak = traced_peak(lambda: metrics.summary(m, back))
    assert peak <= 0.8 * m.positions.nbytes, peak / m.positions.nbytes


def _old_summary(d: np.ndarray) -> dict[str, Any]:
    """The report's figures of the distances ``d`` as metrics.summary computed them before
    it was made to hold less."""
    flat = d[~np.isnan(d)]
    have = ~np.isnan(d)

    def rms_over(axis: int) -> np.ndarray:
        s = (np.where(have, d, 0.0) ** 2).sum(axis=axis)
        out = np.full(s.shape, np.nan)
        n = have.sum(axis=axis)
        np.divide(s, n, out=out, where=n > 0)
        return np.sqrt(out)
    per_frame = rms_over(1)
    per_frame = per_frame[~np.isnan(per_frame)]
    none = flat.size == 0
    finite = np.isfinite(flat)
    if none or finite.all():
        p99 = None if none else float(np.percentile(flat, 99))
    else:
        top = float(flat[finite].max()) if finite.any() else -np.inf
        p99 = float(np.percentile(np.where(finite, flat, np.finfo(np.float64).max), 99))
        p99 = np.inf if p99 > top else p99
    return {"max": None if none else float(flat.max()),
            "arms": None if none else (float(per_frame.mean()) if per_frame.size else 0.0),
            "rms": None if none else float(np.sqrt((flat ** 2).mean())),
            "p99": p99, "mean": None if none else float(flat.mean()),
            "per_max": np.where(np.isnan(d), -np.inf, d).max(axis=0, initial=-np.inf),
            "per_rms": rms_over(0)}


@settings(max_examples=80, deadline=None)
@given(st.integers(1, 30), st.integers(1, 6), st.integers(0, 2 ** 32 - 1))
def test_the_leaner_error_report_gives_the_same_figures(F, M, seed):
    """metrics.summary gives, bit for bit, what it gave when it held every distance beside
    the valid ones: gaps in either motion (NaN and infinite distances), markers and
    frames that are gaps throughout."""
    rng = np.random.default_rng(seed)
    a = rng.normal(0, 10, (F, M, 3))
    b = a + rng.normal(0, 1, (F, M, 3)) * rng.integers(0, 2, (F, M, 1))
    va = rng.integers(0, 4, (F, M)) > 0
    vb = va & (rng.integers(0, 5, (F, M)) > 0)
    if rng.integers(0, 3) == 0:
        va[:, int(rng.integers(0, M))] = False
    if rng.integers(0, 3) == 0:
        va[int(rng.integers(0, F))] = False
    a[~va], b[~vb] = np.nan, np.nan
    mo = Motion(a, [f"m{k}" for k in range(M)], 100.0, "mm", va)
    md = Motion(b, [f"m{k}" for k in range(M)], 100.0, "mm", vb)
    got = metrics.summary(mo, md)
    want = _old_summary(metrics.errors(mo, md))
    for key in ("max", "arms", "rms", "p99", "mean"):
        assert got[key] == want[key] or (got[key] is None and want[key] is None)
    old_max = [None if not np.isfinite(v) and v < 0 else float(v) for v in want["per_max"]]
    old_rms = [None if np.isnan(v) else float(v) for v in want["per_rms"]]
    assert list(got["per_marker_max"].values()) == old_max
    assert list(got["per_marker_rms"].values()) == old_rms


def test_the_bvh_reader_scales_the_joint_positions_in_place(warm, traced_peak):
    """parse_bvh: the joint positions once (forward kinematics), scaled in place; the old
    reader made a second array for the scale of 1 (2.1 times in all)."""
    text = chain_bvh(1024, 300, seed=4)
    box: list[Motion] = []
    peak = traced_peak(lambda: box.append(parse_bvh(text)))
    assert peak <= 1.5 * box[0].positions.nbytes, peak / box[0].positions.nbytes


def test_the_member_order_reorders_the_scores_in_place(warm, traced_peak):
    """The flat hierarchy's member order (chain_order of every pair's score, issue 15.1)
    moves the root's row and column first in place: the plan of 1024 markers over 20
    frames allocates the M x M scores (8.4 MB) and little else; the reordered copy made
    it twice that before."""
    from mpz.encoder import DEFAULTS, plan_hierarchy
    m = parse_bvh(chain_bvh(1023, 20, seed=6))
    M = m.n_markers
    peak = traced_peak(lambda: plan_hierarchy(m, DEFAULTS))
    assert peak <= 1.25 * M * M * 8, peak / (M * M * 8)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 90), st.data(), st.integers(1, 70))
def test_scores_moved_to_the_front_in_place_are_the_reordered_copy(M, data, rows):
    """_to_front gives scores[np.ix_(idx, idx)] for idx = [r] + the others in order, for
    any block of rows."""
    import mpz.encoder as E
    r = data.draw(st.integers(0, M - 1))
    a = np.random.default_rng(M * 1000 + r).normal(size=(M, M))
    idx = [r] + [k for k in range(M) if k != r]
    want = a[np.ix_(idx, idx)]
    old = E._FRONT_ROWS
    E._FRONT_ROWS = rows
    try:
        E._to_front(a, r)
    finally:
        E._FRONT_ROWS = old
    assert a.tobytes() == want.tobytes()


def test_the_decoded_joints_are_scaled_in_place(warm, traced_peak):
    """with_joint_positions (mpz decode of a BVH or AMC file): the joint positions once,
    scaled in place; it made a second array for the scale before (2.0 times in all)."""
    back = mpz.decode(mpz.encode(parse_bvh(chain_bvh(1024, 300, seed=5)), threads=1))
    box: list[Motion] = []
    peak = traced_peak(lambda: box.append(sk.with_joint_positions(back)))
    assert peak <= 1.5 * box[0].positions.nbytes, peak / box[0].positions.nbytes


# ------------------------------------------------------------ the same values --
@st.composite
def skeletons(draw: st.DrawFn) -> tuple[Skeleton, np.ndarray]:
    """A random tree of either convention whose joints have random channels (rotations or
    not), and random channel values."""
    J = draw(st.integers(1, 14))
    parents = [-1] + [draw(st.integers(-1 if k > 3 else 0, k - 1)) for k in range(1, J)]
    joints = []
    for k in range(J):
        kinds = draw(st.lists(st.integers(0, 5), unique=True, max_size=4))
        off = st.floats(-50, 50)
        joints.append(Joint(f"j{k}", parents[k], tuple(kinds), (draw(off), draw(off), draw(off)),
                            direction=(0.0, 1.0, 0.0), length=draw(st.floats(0, 20))))
    skel = Skeleton(draw(st.sampled_from(["bvh", "asf"])), tuple(joints))
    F = draw(st.integers(0, 40))
    values = np.array(draw(st.lists(st.floats(-180, 180), min_size=F * skel.channel_count,
                                    max_size=F * skel.channel_count)),
                      np.float64).reshape(F, skel.channel_count)
    return skel, values


@settings(max_examples=80, deadline=None)
@given(skeletons(), st.integers(1, 40), st.integers(1, 30))
def test_lever_arms_of_are_the_arms_of_the_turning_joints(case, joint_frames, pairs):
    """lever_arms_of (blocks of frames, the turning joints' pairs a few at a time) gives
    lever_arms of every joint position bit for bit at the joints that have a rotation
    channel, and 0 at the others, whatever the block sizes."""
    skel, values = case
    got = sk.lever_arms_of(skel, values, joint_frames=joint_frames, pairs=pairs)
    want = lever_arms(skel, forward(skel, values))
    turns = np.array([any(3 <= c <= 5 for c in j.channels) for j in skel.joints], bool)
    assert got[turns].tobytes() == want[turns].tobytes()
    assert not got[~turns].any()


@settings(max_examples=40, deadline=None)
@given(skeletons(), st.integers(1, 40), st.floats(1e-3, 10))
def test_position_error_in_blocks_is_that_of_every_frame_at_once(case, joint_frames, noise):
    """position_error computed JOINT_FRAMES joint positions at a time is the largest
    distance of the whole arrays, bit for bit."""
    skel, a = case
    b = a + noise
    want = (np.sqrt(squared_lengths(forward(skel, a) - forward(skel, b)).max(initial=0.0))
            * sk.marker_scale(skel)) if skel.channel_count else 0.0
    old = sk.JOINT_FRAMES
    sk.JOINT_FRAMES = joint_frames
    try:
        got = sk.position_error(skel, a, b)
    finally:
        sk.JOINT_FRAMES = old
    assert got == want


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("bound", [1.0, 5.0])
def test_the_lattice_in_chunks_of_members_gives_the_same_file(monkeypatch, threads, bound):
    """Base 1's lattices chosen a few members at a time (LATTICE_VALUES), with a sample's
    tracks split over the chunks, give the bytes of one chunk for the whole node."""
    import mpz.encoder as E
    from mpz.synth import generate
    m = generate("walk", frames=600, markers=30, seed=7)
    whole = mpz.encode(m, max_error=bound, threads=threads)
    monkeypatch.setattr(E, "LATTICE_VALUES", 3 * 600 * 2 + 1)      # two members a chunk
    assert mpz.encode(m, max_error=bound, threads=threads) == whole


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 9), st.integers(2, 80), st.integers(1, 300), st.booleans(),
       st.integers(0, 2 ** 32 - 1))
def test_members_fit_as_the_whole_array_and_code_the_same_blocks(n, T, task_frames, threaded,
                                                                 seed):
    """fit_members of Members (each task makes its own members' targets) is fit_members
    of the whole array; and write_blocks codes a result's key rows (Fitted.rows) as it
    codes its per-member lists, byte for byte."""
    rng = np.random.default_rng(seed)
    base = np.cumsum(rng.normal(0, 3, (T, 1, 3)), axis=0)
    y = base + rng.normal(0, 2.0, (T, n, 3)) * np.arange(n)[None, :, None]
    asked: list[tuple[int, int]] = []

    def of(lo: int, hi: int) -> np.ndarray:
        asked.append((lo, hi))
        return y[:, lo:hi].copy()
    old = kf.TASK_FRAMES
    kf.TASK_FRAMES = task_frames
    try:
        with ThreadPoolExecutor(2) as pool:
            want = kf.fit_members(y, 1.7320508, pool=pool if threaded else None)
            got = kf.fit_members(kf.Members(of, T, n), 1.7320508,
                                 pool=pool if threaded else None)
        ranges = kf.task_ranges(n, T)
    finally:
        kf.TASK_FRAMES = old
    assert sorted(asked) == ranges
    assert [t.tolist() for t in got.times] == [t.tolist() for t in want.times]
    assert got.refs == want.refs
    assert [e.tolist() for e in got.residuals] == [e.tolist() for e in want.residuals]
    assert got.out.tobytes() == want.out.tobytes()
    assert got.rows is not None
    lists = kf.Fitted(got.times, got.refs, got.residuals, got.out)     # no rows
    codes = []
    for fitted in (got, lists):
        enc = BlockEncoder()
        kf.write_blocks(enc, fitted, T)
        codes.append(enc.finish())
    assert codes[0] == codes[1]


def test_spread_hands_each_result_on_in_order_and_keeps_none():
    """_spread with a sink: the results in range order on this thread, none kept."""
    import threading
    ranges = [(0, 2), (2, 4), (4, 5), (5, 9)]
    for pool in (ThreadPoolExecutor(2), None):
        got: list[tuple[tuple[int, int], int]] = []
        me = threading.get_ident()
        assert kf._spread(pool, lambda lo, hi: (lo, hi), ranges,
                          sink=lambda r, got=got: got.append((r, threading.get_ident()))) == []
        assert got == [(r, me) for r in ranges]
        if pool is not None:
            pool.shutdown()
