"""The coded summary chunk smrc (spec §4.15, MPZ 1.1, issue 14.12).

Expected values come from outside the code under test: the prediction of §4.15 step 4
worked by hand and coded with the §5 transcription of the conformance package
(:class:`~mpz.conformance.rangecoder.RefEncoder`), segment means computed with numpy from
the series the summary describes, and the smry size from the §4.10 layout.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
import shutil
import subprocess
import sys
import warnings

from hypothesis import given, settings
from hypothesis import strategies as st
import numpy as np
import pytest

import mpz
from mpz.chunks import CHUNKS, Context, Mhdr, Smrc
from mpz.chunks.summary import encode_levels
from mpz.conformance.rangecoder import RefEncoder
from mpz.encoder import EncodeOptions, summary_record
from mpz.errors import EncoderError, FormatError, LimitExceededError
from mpz.fisher import motion_series
from mpz.synth import generate

KS = (6, 12, 24, 48)


def _header(F: int, M: int = 1) -> Mhdr:
    return Mhdr(version_major=1, version_minor=1, flags=1, frame_count=F, marker_count=M,
                node_count=1, rate=120.0, units=1, error_metric=0, error_bound=0.0,
                smoothing=0)


def _ctx(F: int, M: int = 1) -> Context:
    return Context(_header(F, M), 1 << 26)


def _ref_coded(blocks) -> bytes:
    """A coded field from (values [T, M, A], signed) blocks, each of period T, with the §5
    transcription (shares no code with mpz.entropy)."""
    enc = RefEncoder()
    for v, signed in blocks:
        v = np.asarray(v, np.int64)
        enc.block(v, period=v.shape[0], signed=signed)
    return enc.finish()


def _smrc(space, dims, levels, coded) -> Smrc:
    from mpz.chunks.summary import CodedSummaryLevel
    return Smrc(space=space, dims=dims, level_count=len(levels),
                levels=tuple(CodedSummaryLevel(k=k, wssse=0.0, step=s) for k, s in levels),
                coded=coded)


# ----------------------------------------------------------- §4.15 by hand --
def test_prediction_worked_by_hand():
    """F = 4, an angle summary with D = 2. Level 1 (the last, k = 2, lengths 2 and 2) is
    predicted along j; level 0 (k = 1) from level 1 by the frame-weighted mean rounded half
    up: (2 * (1*2 + 2*2) + 4) div 8 = 2 (1.5 up), (2 * (-1*2 - 2*2) + 4) div 8 = -1
    (-1.5 up). Residuals of 3 and 0 give means 5 and -1."""
    lengths0, lengths1 = [[[3]]], [[[1]], [[1]]]       # n - 1
    e1 = [[[1], [-1]], [[1], [-1]]]                     # q1 = [[1, -1], [2, -2]]
    e0 = [[[3], [0]]]                                   # q0 = [[2 + 3, -1 + 0]]
    coded = _ref_coded([(lengths0, False), (e0, True), (lengths1, False), (e1, True)])
    rec = _smrc(1, 2, [(1, 0.5), (2, 0.25)], coded)
    rec.check(_ctx(4))
    (s0, q0), (s1, q1) = rec.levels_decoded(4)
    assert s0.tolist() == [0] and s1.tolist() == [0, 2]
    assert q1.tolist() == [[1, -1], [2, -2]]
    assert q0.tolist() == [[5, -1]]
    # and mpz's own coder writes the same bytes for the same levels
    assert encode_levels(1, 4, [(s0, q0), (s1, q1)]) == coded


def test_overlap_weights_with_unaligned_boundaries():
    """Level 0 (k = 2, starts 0, 3) from level 1 (k = 3, starts 0, 1, 4) over F = 6:
    segment 0 (frames 0-2) overlaps q' = 10 (1 frame) and 40 (2 frames): (2*90 + 3) div 6
    = 30; segment 1 (frames 3-5) overlaps 40 (1) and 70 (2): (2*180 + 3) div 6 = 60."""
    e1 = [[[10]], [[30]], [[30]]]                      # q1 = 10, 40, 70
    coded = _ref_coded([([[[2]], [[2]]], False), ([[[0]], [[1]]], True),
                        ([[[0]], [[2]], [[1]]], False), (e1, True)])
    rec = _smrc(1, 1, [(2, 1.0), (3, 1.0)], coded)
    rec.check(_ctx(6))
    (s0, q0), (_, q1) = rec.levels_decoded(6)
    assert s0.tolist() == [0, 3] and q1.ravel().tolist() == [10, 40, 70]
    assert q0.ravel().tolist() == [30, 61]


@st.composite
def _two_partitions(draw):
    F = draw(st.integers(1, 40))

    def starts():
        cuts = draw(st.sets(st.integers(1, F - 1), max_size=F - 1)) if F > 1 else set()
        return np.asarray([0, *sorted(cuts)], np.int64)
    s, src_s = starts(), starts()
    D = draw(st.integers(0, 4))
    big = 2**31 - 1
    src = np.asarray(draw(st.lists(st.integers(-big, big), min_size=len(src_s) * D,
                                   max_size=len(src_s) * D)), np.int64).reshape(len(src_s), D)
    return F, s, src_s, src


@settings(max_examples=300, deadline=None)
@given(_two_partitions())
def test_overlap_prediction_is_the_frame_by_frame_mean(case):
    """§4.15 step 4 read frame by frame, in Python integers: every frame t of segment j
    adds the source mean of the segment holding t, and the prediction is
    floor((2 sum + n_j) / (2 n_j)). Means at the s32 limits, partitions of any shape."""
    from mpz.chunks.summary import overlap_prediction
    F, s, src_s, src = case
    seg = np.searchsorted(s, np.arange(F), side="right") - 1
    src_seg = np.searchsorted(src_s, np.arange(F), side="right") - 1
    D = src.shape[1]
    want = []
    for j in range(len(s)):
        frames = [t for t in range(F) if seg[t] == j]
        n = len(frames)
        want.append([(2 * sum(int(src[src_seg[t], d]) for t in frames) + n) // (2 * n)
                     for d in range(D)])
    got = overlap_prediction(s, src, src_s, F)
    assert got.shape == (len(s), D)
    assert got.tolist() == want


# -------------------------------------------------------- round trip (prop) --
@st.composite
def _levels(draw):
    F = draw(st.integers(1, 60))
    space = draw(st.sampled_from([0, 1]))
    dims = 3 * draw(st.integers(1, 4)) if space == 0 else draw(st.integers(0, 5))
    out = []
    for _ in range(draw(st.integers(1, 5))):
        k = draw(st.integers(1, F))
        starts = [0] + sorted(draw(st.sets(st.integers(1, F - 1), min_size=k - 1,
                                           max_size=k - 1))) if k > 1 else [0]
        step = draw(st.sampled_from([0.25, 1.0, 2.0, 0.1]))
        exact = draw(st.lists(st.floats(-1e4, 1e4), min_size=k * dims, max_size=k * dims))
        out.append((np.asarray(starts, np.int64), step, np.asarray(exact).reshape(k, dims)))
    return F, space, dims, out


@settings(max_examples=150, deadline=None)
@given(_levels())
def test_round_trip_record_bytes_parse(case):
    """random levels -> record -> bytes -> parse -> the same starts, means within step/2."""
    F, space, dims, levels = case
    q = [(starts, np.rint(exact / step).astype(np.int64)) for starts, step, exact in levels]
    rec = _smrc(space, dims, [(len(s), step) for s, step, _ in levels],
                encode_levels(space, F, q))
    back = Smrc.load(rec.dump())
    back.check(_ctx(F, max(1, dims // 3)))
    for (starts, step, exact), (s2, q2) in zip(levels, back.levels_decoded(F), strict=True):
        assert s2.tolist() == starts.tolist()
        assert np.all(np.abs(q2 * step - exact) <= step / 2 * (1 + 1e-12))


# ----------------------------------------------------------------- checks --
def test_checks_before_decoding_and_after():
    ok = _ref_coded([([[[3]]], False)])                  # one level, k = 1, F = 4, D = 0
    _smrc(1, 0, [(1, 1.0)], ok).check(_ctx(4))
    with pytest.raises(FormatError, match="k = 5"):       # k > F, before anything is decoded
        _smrc(1, 0, [(5, 1.0)], b"").check(_ctx(4))
    # the sums are limits: a 5-byte field never gets decoded for 3 x 2^23 means or 2^24 + 64
    # segments
    with pytest.raises(LimitExceededError):
        _smrc(1, 1 << 23, [(3, 1.0)], b"\0" * 5).check(_ctx(4))
    with pytest.raises(LimitExceededError):
        _smrc(1, 0, [((1 << 18) + 1, 1.0)] * 64, b"\0" * 5).check(_ctx((1 << 18) + 1))
    with pytest.raises(FormatError, match="add up to 5"):  # lengths 2 + 3 for F = 4
        _smrc(1, 0, [(2, 1.0)], _ref_coded([([[[1]], [[2]]], False)])).check(_ctx(4))
    with pytest.raises(FormatError, match="§5.3|left after"):
        _smrc(1, 0, [(1, 1.0)], ok + b"\0").check(_ctx(4))
    with pytest.raises(FormatError):
        _smrc(1, 0, [(1, 1.0)], ok[:-1] if len(ok) > 5 else b"\0\0\0").check(_ctx(4))
    big = _ref_coded([([[[1]], [[1]]], False), ([[[(1 << 31) - 1]], [[1]]], True)])
    with pytest.raises(FormatError, match="2\\^31"):
        _smrc(1, 1, [(2, 1.0)], big).check(_ctx(4))
    with pytest.raises(FormatError, match="step"):
        _smrc(1, 0, [(1, 0.0)], ok).check(_ctx(4))
    with pytest.raises(FormatError, match="dims"):
        _smrc(0, 4, [(1, 1.0)], ok).check(_ctx(4, 2))


def test_info_shows_levels_step_and_coded_bytes():
    rec = _smrc(1, 0, [(1, 0.5)], _ref_coded([([[[3]]], False)]))
    info = rec.info()
    assert info["levels"] == [{"k": 1, "wssse": 0.0, "step": 0.5}]
    assert info["coded"]["bytes"] == len(rec.coded)


# ---------------------------------------------------- encoder and reader --
def _segment_means(series: np.ndarray, starts: np.ndarray) -> np.ndarray:
    ends = np.append(starts[1:], series.shape[0])
    return np.stack([series[a:b].mean(axis=0) for a, b in zip(starts, ends, strict=True)])


def test_read_summary_smrc_matches_smry_and_the_exact_means():
    m = generate("walk", frames=120, seed=5)
    a = mpz.encode(m, max_error=2.0, summary=(2, 5, 9))
    b = mpz.encode(m, max_error=2.0, summary=(2, 5, 9), summary_format="smry")
    assert mpz.info(a).version == "1.1" and mpz.info(b).version == "1.0"   # §2.1
    assert "smrc" in mpz.info(a).chunk_bytes and "smry" not in mpz.info(a).chunk_bytes
    sa, sb = mpz.read_summary(a), mpz.read_summary(b)
    series, _ = motion_series(m, space="positions")
    assert [lv.k for lv in sa.levels] == [lv.k for lv in sb.levels] == [2, 5, 9]
    for la, lb in zip(sa.levels, sb.levels, strict=True):
        assert la.starts.tolist() == lb.starts.tolist() and la.wssse == lb.wssse
        assert la.step == 2.0                          # the declared bound (§4.15)
        exact = _segment_means(series, la.starts)
        assert np.abs(la.means - exact).max() <= la.step / 2 + 1e-9
        assert np.abs(lb.means - exact).max() <= lb.step / 2 + 1e-9
    assert len(a) < len(b)


def _with_step(data: bytes, step: float) -> bytes:
    """``data`` with the step of every summary level set to ``step`` and the summary
    chunk's CRC made again (§3.2 chunk layout, §3.3 CRC; §4.10 and §4.15 level headers:
    u32 k, f64 wssse, f64 step, then smry's starts and means)."""
    import struct
    import zlib
    b = bytearray(data)
    pos = 8                                             # after the signature (§3.1)
    while True:
        kind, size = bytes(b[pos:pos + 4]), struct.unpack_from("<I", b, pos + 4)[0]
        if kind in (b"smry", b"smrc"):
            break
        pos += 12 + size
    payload = pos + 8
    dims, count = struct.unpack_from("<IB", b, payload + 1)
    at = payload + 6
    for _ in range(count):
        k = struct.unpack_from("<I", b, at)[0]
        struct.pack_into("<d", b, at + 12, step)
        at += 20 if kind == b"smrc" else 20 + 4 * k + 4 * k * dims
    struct.pack_into("<I", b, payload + size, zlib.crc32(bytes(b[pos:pos + 4]) +
                                                       bytes(b[payload:payload + size])))
    return bytes(b)


@pytest.mark.parametrize("layout", ["smrc", "smry"])
def test_a_step_whose_means_overflow_reads_as_infinite_means(layout, tmp_path):
    """§4.10, §4.15 step 6: a step of 1e308 is in range (finite, > 0), and a mean of
    q x step beyond the largest binary64 is +-inf, not a reason to refuse the file. The
    reference read it with numpy's "overflow encountered in multiply" on stderr, and the
    spec did not say whether such a file is valid (stop 66's open questions)."""
    m = generate("walk", frames=120, seed=5)
    data = _with_step(mpz.encode(m, max_error=2.0, summary=(2, 5), summary_format=layout),
                      1e308)
    q = mpz.read_summary(_with_step(data, 1.0))          # the stored q, by a step of 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")                   # no RuntimeWarning
        s = mpz.read_summary(data)
    for lq, lv in zip(q.levels, s.levels, strict=True):
        assert lv.step == 1e308
        big = np.abs(lq.means) >= 2                      # 2e308 > 1.8e308: overflows
        assert big.any() and (np.abs(lq.means) == 1).any()
        assert np.isinf(lv.means[big]).all()
        assert (np.sign(lv.means[big]) == np.sign(lq.means[big])).all()
        assert lv.means[lq.means == 1].tolist() == [1e308] * int((lq.means == 1).sum())
    path = tmp_path / "big.mpz"
    path.write_bytes(data)
    run = subprocess.run([sys.executable, "-m", "mpz.tools.mpz_cli", "summary", str(path)],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0 and run.stderr == "", run.stderr
    assert "k=2" in run.stdout and "k=5" in run.stdout
    # and its plot: the poses of infinite means had infinite axis limits, exit 70 (a
    # review of stop 67); the segments are drawn without them
    pytest.importorskip("matplotlib")
    png = tmp_path / "big.png"
    run = subprocess.run([sys.executable, "-m", "mpz.tools.mpz_cli", "summary", str(path),
                          "--plot", str(png)], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0 and png.stat().st_size > 0, run.stderr


def test_summary_format_option_is_checked_up_front():
    with pytest.raises(EncoderError, match="summary_format"):
        EncodeOptions(summary_format="zip").validate()
    with pytest.raises(EncoderError, match="summary_format"):
        mpz.encode(generate("walk", frames=30), summary=(2,), summary_format="raw")


def test_a_one_zero_decoder_skips_smrc(monkeypatch):
    """§2.1, §2.3: a 1.0 decoder (the reference without smrc in its chunk table) skips the
    chunk as unknown ancillary, decodes the same markers, and sees no summary."""
    m = generate("walk", frames=60, seed=6)
    data = mpz.encode(m, max_error=1.0, summary=(3, 6))
    full = mpz.decode(data)
    saved = dict(CHUNKS)              # restored whole, in order (the table's order is tested)
    try:
        del CHUNKS["smrc"]
        old = mpz.decode(data)
        assert mpz.read_summary(data) is None
    finally:
        CHUNKS.clear()
        CHUNKS.update(saved)
    assert old.names == full.names
    assert np.array_equal(old.as_nan(), full.as_nan(), equal_nan=True)
    assert mpz.read_summary(data) is not None


def test_a_long_motion_has_its_summary_cut_on_blocks(monkeypatch, tmp_path, capsys):
    """Appendix C item 8: past EXACT_MAX_FRAMES frames (16,384; 12 here) the summary's cuts
    fall on blocks of ceil(F / 16384) frames, since the exact programme is quadratic in F
    (half an hour for a 30-minute capture, with no word of it). The DP runs on the block
    means, each k lowered to the block count; means and WSSSE are of every frame. The
    encode report and the CLI say so."""
    import itertools

    import mpz.fisher
    from mpz.tools import mpz_cli
    m = generate("walk", frames=46, seed=3)
    assert mpz.encode_motion(m, EncodeOptions(max_error=1.0, summary=(3,)))[1].summary_blocks == 1
    assert mpz.encode_motion(m, EncodeOptions(max_error=1.0))[1].summary_blocks == 0
    monkeypatch.setattr(mpz.fisher, "EXACT_MAX_FRAMES", 12)    # 46 frames: blocks of 4
    data, rep = mpz.encode_motion(m, EncodeOptions(max_error=1.0, summary=(3, 40)))
    assert rep.summary_blocks == 4
    s = mpz.read_summary(data)
    assert [lv.k for lv in s.levels] == [3, 12]             # 40 lowered to the 12 blocks
    series, _ = motion_series(m, space="positions")
    blocks = np.stack([series[i:i + 4].mean(axis=0) for i in range(0, 46, 4)])

    def cost(cuts):                       # the blocks' SSE, every block weighed alike
        edges = [0, *cuts, len(blocks)]
        return sum(float(((blocks[a:b] - blocks[a:b].mean(axis=0)) ** 2).sum())
                   for a, b in zip(edges, edges[1:], strict=False))
    best = min(itertools.combinations(range(1, 12), 2), key=cost)
    for lv in s.levels:
        assert all(v % 4 == 0 for v in lv.starts)
        exact = _segment_means(series, lv.starts)
        assert np.abs(lv.means - exact).max() <= lv.step / 2 + 1e-9
        ends = np.append(lv.starts[1:], 46)
        w = sum(float(((series[a:b] - series[a:b].mean(axis=0)) ** 2).sum())
                for a, b in zip(lv.starts, ends, strict=True))
        assert lv.wssse == pytest.approx(w, rel=1e-12)
    assert s.levels[0].starts.tolist() == [0, 4 * best[0], 4 * best[1]]
    assert s.levels[1].starts.tolist() == list(range(0, 46, 4))
    src = tmp_path / "long.npy"
    np.save(src, m.positions)
    assert mpz_cli.main(["encode", str(src), "--rate", "120", "--max-error", "1",
                         "--summary", "3", "-o", str(tmp_path / "long.mpz")]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines()
                if x.strip().startswith("summary"))
    assert "cuts on blocks of 4 frames" in line, line
    # mpz summary of the motion file: the same rule, said in the head line and in JSON
    assert mpz_cli.main(["summary", str(src), "--k", "3"]) == 0
    assert "cuts on blocks of 4 frames" in capsys.readouterr().out.splitlines()[0]
    assert mpz_cli.main(["summary", str(src), "--k", "3,13", "--json"]) == 1
    got = capsys.readouterr()
    js = json.loads(got.out)
    assert js["method"] == "blocks:4" and [lv["k"] for lv in js["levels"]] == [3]
    assert [g["start"] for g in js["levels"][0]["segments"]] == s.levels[0].starts.tolist()
    assert "k=13 dropped: the motion has only 12 blocks of 4 frames" in got.err
    assert mpz_cli.main(["summary", str(tmp_path / "long.mpz"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["method"] == "stored"
    # an .mpz's stored levels: its head line said "cuts on blocks of stored frames"
    assert mpz_cli.main(["summary", str(tmp_path / "long.mpz")]) == 0
    assert "blocks" not in capsys.readouterr().out.splitlines()[0]


def test_a_summary_whose_tables_pass_the_limit_is_refused_up_front(monkeypatch):
    """k = 20,000 on 40,000 frames took 2.4 GB and six minutes (a QA run, stop 38): the
    programme's tables, (rows + 1) x k entries, are held to fisher.MAX_TABLE (here 100),
    and the encoder says so before coding anything, naming the largest k that fits."""
    from mpz import encoder
    import mpz.fisher
    monkeypatch.setattr(mpz.fisher, "MAX_TABLE", 100)
    m = generate("walk", frames=46, seed=3)

    def never(*a, **k):
        raise AssertionError("the motion was planned before the summary was checked")
    with monkeypatch.context() as mp:
        mp.setattr(encoder, "plan_hierarchy", never)
        with pytest.raises(EncoderError, match=r"46 frames .* 3 segments .* 47 x 3 = 141 "
                           r"entries .* more than the 100 .* at most k = 2 "):
            mpz.encode(m, max_error=1.0, summary=(1, 3))
    assert [lv.k for lv in mpz.read_summary(mpz.encode(m, max_error=1.0, summary=(2,))).levels] \
        == [2]
    with pytest.raises(EncoderError, match="at most k = 2 "):     # the API refuses it too
        mpz.fisher.optimal_partitions(np.zeros((46, 1)), 3)


def test_optimal_segmentation_of_a_long_node_runs_on_blocks(monkeypatch):
    """segmentation="optimal" ran Fisher's programme on every frame of a node (hours and
    1.3 GB for a 30-minute capture); past EXACT_MAX_FRAMES it runs on the means of blocks
    (Appendix C item 6), so the segments start on block boundaries; the file still
    decodes within its bound."""
    from mpz import encoder
    import mpz.fisher
    m = generate("walk", frames=60, seed=2)
    x = m.positions[:, :4]
    opts = EncodeOptions(segmentation="optimal", patterns="on", max_error=2.0)
    starts, counts = encoder._segments(x, np.ones(4), 30.0, 4, opts)
    assert any(v % 5 for v in starts)                  # exact: any frame may start one
    monkeypatch.setattr(mpz.fisher, "EXACT_MAX_FRAMES", 12)      # 60 frames: blocks of 5
    starts, counts = encoder._segments(x, np.ones(4), 30.0, 4, opts)
    assert starts[0] == 0 and all(v % 5 == 0 for v in starts) and counts.sum() == 60
    back = mpz.decode(mpz.encode(m, max_error=2.0, segmentation="optimal", patterns="on"))
    assert float(np.linalg.norm(back.positions - m.positions, axis=2).max()) <= 2.0


def _smry_bytes(ks, dims) -> int:
    """§4.10 layout: 6 bytes, then per level 20 + 4k + 4kD; plus the 12-byte chunk frame."""
    return 12 + 6 + sum(20 + 4 * k + 4 * k * dims for k in ks)


def test_cli_quick_start_reports_the_smrc_size(tmp_path):
    exe = Path(sys.executable).parent
    mpz_cmd = str(exe / "mpz") if (exe / "mpz").exists() else shutil.which("mpz")
    assert mpz_cmd, "mpz is not installed (pip install -e .)"
    subprocess.run([sys.executable, "-m", "mpz.tools.make_example", "walk.c3d"], cwd=tmp_path,
                   check=True, capture_output=True, timeout=300)
    base = [mpz_cmd, "encode", "walk.c3d", "--max-error", "2mm", "--summary", "6,12,24,48"]
    text = subprocess.run([*base, "-o", "walk-summary.mpz"], cwd=tmp_path, check=True,
                          capture_output=True, text=True, timeout=600)
    line = next(x for x in text.stdout.splitlines() if x.strip().startswith("summary"))
    assert "smrc chunk" in line and "k = 6, 12, 24, 48" in line, line
    assert "larger than the motion" not in text.stderr
    js = subprocess.run([*base, "-o", "j.mpz", "--json"], cwd=tmp_path, check=True,
                        capture_output=True, text=True, timeout=600)
    rep = json.loads(js.stdout)
    rep = rep[0] if isinstance(rep, list) else rep
    old = subprocess.run([*base, "-o", "old.mpz", "--json", "--summary-format", "smry"],
                         cwd=tmp_path, check=True, capture_output=True, text=True, timeout=600)
    rep_old = json.loads(old.stdout)
    rep_old = rep_old[0] if isinstance(rep_old, list) else rep_old
    assert rep["summary_chunk"] == "smrc" and rep_old["summary_chunk"] == "smry"
    M = rep["markers"]
    assert rep_old["summary_bytes"] == _smry_bytes(KS, 3 * M)
    smrc, smry = rep["summary_bytes"], rep_old["summary_bytes"]
    motion = rep["file_bytes"] - smrc
    print(f"\nquick start: smry {smry} B, smrc {smrc} B ({smry / smrc:.1f}x smaller), "
          f"rest of the file {motion} B")
    assert smrc < motion < smry          # smaller than the motion (issue 14.12)
    assert mpz.read_summary((tmp_path / "walk-summary.mpz").read_bytes()).levels[0].k == 6


def _real_files(root: Path) -> list[Path]:
    return sorted(p for ext in ("c3d", "trc", "bvh", "amc") for p in root.rglob(f"*.{ext}"))


def test_real_files_smrc_smaller_than_smry(shared_data):
    """Every real recording, --summary 6,12,24,48, position summary at a 1-unit bound: the
    coded chunk against the §4.10 size of smry (which does not depend on the step)."""
    from mpz.io import read
    rows = []
    for path in _real_files(shared_data):
        m = read(path)
        rec = summary_record(m, KS, "positions", 1.0, "smrc")
        smrc = 12 + len(rec.dump())
        ks = [lv.k for lv in rec.levels]
        smry = _smry_bytes(ks, rec.dims)
        assert smry == 12 + len(summary_record(m, KS, "positions", 1.0 / math.sqrt(3),
                                               "smry").dump())
        rows.append((path.name, m.n_frames, m.n_markers, smry, smrc))
        assert smrc < smry, path.name
    assert rows
    print("\nfile  F  M  smry  smrc  ratio")
    for name, F, M, a, b in rows:
        print(f"{name} {F} {M} {a} {b} {a / b:.1f}")


@pytest.mark.parametrize("fmt", ["smry", "smrc"])
def test_means_past_32_bits_are_refused_before_they_wrap(fmt):
    """Means of 10^4 mm at a step of 10^-9 are about 10^13 steps: written as int32 they
    would wrap to other values with no error. The encoder refuses them (§4.10's s32 field,
    §4.15 step 5's |q| < 2^31)."""
    m = generate("walk", frames=20, seed=3)
    with pytest.raises(EncoderError, match="do not fit 32 bits"):
        summary_record(m, (1, 2), "positions", 1e-9, fmt)
    assert summary_record(m, (1, 2), "positions", 1e-3, fmt).level_count == 2


@pytest.mark.parametrize("fmt", ["smrc", "smry"])
def test_each_k_is_written_once_in_increasing_order(fmt):
    """Spec Appendix C item 8: in either chunk each requested k is written once, after it
    is lowered to F, and the levels go by increasing k (an implementer's reading of the
    spec found this said only in the API's help)."""
    m = generate("walk", frames=40, seed=3)
    data = mpz.encode(m, max_error=1.0, summary=(500, 400, 12, 6, 6),
                      summary_format=fmt)
    assert [lv.k for lv in mpz.read_summary(data).levels] == [6, 12, 40]
