"""Reference codec end to end: round trips, the hard bound, gaps, options."""

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
import numpy as np
import pytest

import mpz
from mpz.decoder import read_stream
from mpz.encoder import EncodeOptions, encode_motion
from mpz.errors import EncoderError
from mpz.synth import generate


def motion_from(arr, gaps=None, rate=120.0):
    names = [f"M{i}" for i in range(arr.shape[1])]
    valid = None if gaps is None else ~gaps
    pos = arr.copy()
    if gaps is not None:
        pos[gaps] = np.nan
    return mpz.Motion(pos, names, rate, "mm", valid)


@pytest.mark.parametrize("E", [0.5, 1.0, 2.0, 5.0])
def test_bound_on_synthetic_walk_with_gaps(E):
    m = generate("walk", frames=300, gap_fraction=0.05, seed=3)
    data = mpz.encode(m, max_error=E)
    out = mpz.decode(data)
    assert mpz.max_error(m, out) <= E
    assert np.array_equal(out.valid, m.valid)           # gaps come back as gaps
    assert np.isnan(out.positions[~out.valid]).all()
    assert out.names == m.names and out.rate == m.rate and out.units == m.units
    hdr = read_stream(data).header
    assert hdr.error_metric == 1 and hdr.error_bound == E


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(frames=st.integers(1, 40), markers=st.integers(1, 6), seed=st.integers(0, 2 ** 31),
       scale=st.sampled_from([1e-3, 1.0, 1e3, 1e5]), E=st.sampled_from([0.01, 0.5, 5.0]),
       gap=st.floats(0, 0.5))
def test_bound_property(frames, markers, seed, scale, E, gap):
    rng = np.random.default_rng(seed)
    arr = np.cumsum(rng.normal(0, scale, (frames, markers, 3)), axis=0)
    gaps = rng.random((frames, markers)) < gap
    m = motion_from(arr, gaps)
    try:
        data = mpz.encode(m, max_error=E)
    except EncoderError as exc:            # only for a grid too fine for the range
        assert "too fine" in str(exc) or "31-bit" in str(exc)
        return
    out = mpz.decode(data)
    assert mpz.max_error(m, out) <= E
    assert np.array_equal(out.valid, m.valid)


def test_marker_gap_throughout_and_single_frame():
    arr = np.random.default_rng(1).normal(0, 100, (1, 3, 3))
    out = mpz.decode(mpz.encode(motion_from(arr), max_error=1.0))
    assert out.n_frames == 1 and mpz.max_error(motion_from(arr), out) <= 1.0
    m = generate("jump", frames=50, seed=2)
    valid = m.valid.copy()
    valid[:, 5] = False
    pos = m.positions.copy()
    pos[:, 5] = np.nan
    m2 = mpz.Motion(pos, m.names, m.rate, m.units, valid)
    out = mpz.decode(mpz.encode(m2, max_error=2.0))
    assert not out.valid[:, 5].any() and mpz.max_error(m2, out) <= 2.0


def test_lossy_paper_mode_uses_patterns():
    m = generate("walk", frames=600, seed=4)
    data, rep = encode_motion(m, EncodeOptions(lossy=True))     # only by name (issue 12)
    s = read_stream(data)
    assert s.segs and not s.residual            # SEGS present, no residual layer
    assert all(n.used_patterns for n in rep.nodes)
    out = mpz.decode(data)
    assert mpz.arms(m, out) < 0.1 * rep.addh    # within a tenth of the head size
    assert len(data) < m.raw_size() / 3


def test_patterns_forced_on_with_bound_round_trips():
    m = generate("wave", frames=240, seed=5)
    data, rep = encode_motion(m, EncodeOptions(max_error=1.0, patterns="on"))
    s = read_stream(data)
    assert s.segs and all(r.record.base == 0 for r in s.resi.values())
    assert mpz.max_error(m, mpz.decode(data)) <= 1.0


def test_group_error_tightens_one_node():
    m = generate("walk", frames=240, seed=6)
    data, rep = encode_motion(m, EncodeOptions(max_error=5.0, group_errors={"l_foot": 0.5}))
    out = mpz.decode(data)
    err = mpz.metrics.errors(m, out)
    foot = [m.names.index(n) for n in ("LHEE", "LTOE", "LMT5")]
    assert np.nanmax(err[:, foot]) <= 0.5
    assert mpz.max_error(m, out) <= 5.0
    assert np.nanmax(np.delete(err, foot, axis=1)) > 0.5    # others did use the looser bound


def test_summary_chunk_roundtrip_without_decoding_motion():
    m = generate("mixed", frames=400, seed=7)
    data = mpz.encode(m, max_error=2.0, summary=(6, 12))
    summ = mpz.read_summary(data)
    assert [lv.k for lv in summ.levels] == [6, 12]
    for lv in summ.levels:
        assert lv.starts[0] == 0 and (np.diff(lv.starts) > 0).all()
        assert lv.means.shape == (lv.k, 3 * m.n_markers)
    prev = summ.preview(12)
    assert prev.n_frames == m.n_frames and prev.names == m.names
    assert mpz.read_summary(mpz.encode(m, max_error=2.0)) is None


def test_options_are_checked():
    m = generate("walk", frames=20)
    for bad in (dict(max_error=-1), dict(metric="median"), dict(patterns="off", lossy=True),
                dict(lossy=True, max_error=1.0), dict(model_errors={"ANGELS": 1e-3}),
                dict(model_error=0.0), dict(default_error_mm=-1.0),
                dict(max_error=1.0, group_errors={"nosuchnode": 0.1}), dict(k0=0),
                dict(bogus=1)):
        with pytest.raises(EncoderError):
            mpz.encode(m, **bad)


def test_encode_is_deterministic():
    m = generate("walk", frames=120, seed=8)
    assert mpz.encode(m, max_error=1.0) == mpz.encode(m, max_error=1.0)
    assert mpz.encode(m) == mpz.encode(m)
    assert mpz.encode(m, lossy=True) == mpz.encode(m, lossy=True)
