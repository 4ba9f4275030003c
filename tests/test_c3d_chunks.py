"""The C3D archive chunks (spec §4.13, §6.9): each § rule, the exact channel codec, and
hostile input (truncations, mutated payloads with repaired CRCs, length fields at their
maximum): only MPZError may escape. Synthetic data only (make_vectors.c3d_motion)."""
from __future__ import annotations

import dataclasses
import struct

from hypothesis import given, settings
from hypothesis import strategies as st
import numpy as np
import pytest

import mpz
from mpz import container
from mpz.c3dcodec import decode_channel, decode_channels, encode_channel, ordered, plan, unordered
from mpz.chunks import CHUNKS, Context
from mpz.entropy import BlockDecoder, BlockEncoder
from mpz.errors import FormatError, LimitExceededError, MPZError
from mpz.tools.make_vectors import c3d_motion


@pytest.fixture(scope="module")
def archive_file() -> bytes:
    return mpz.encode(c3d_motion(5, storage=1, F=12, M=4, J=2, C=2, n=2), max_error=1.0)


@pytest.fixture(scope="module")
def int16_file() -> bytes:
    return mpz.encode(c3d_motion(6, storage=0, F=12, M=4, J=1, C=2, n=3))


def _records(data: bytes) -> dict:
    return {c.type: c.record for c in container.scan(data).chunks}


def _ctx(data: bytes) -> Context:
    chunks = container.scan(data).chunks
    return Context(chunks[0].record, 1 << 26, types=tuple(c.type for c in chunks))


# ------------------------------------------------------------- round trip --
def test_archive_comes_back_bit_for_bit(archive_file):
    m = c3d_motion(5, storage=1, F=12, M=4, J=2, C=2, n=2)
    a, b = m.extras["c3d"], mpz.decode(archive_file).extras["c3d"]
    assert a.records == b.records and a.header == b.header and a.slots == b.slots
    assert a.words.view(np.uint32).tolist() == b.words.view(np.uint32).tolist()
    assert a.analog.view(np.uint32).tolist() == b.analog.view(np.uint32).tolist()
    assert np.array_equal(a.model_valid, b.model_valid)
    err = np.abs(a.models - b.models)[a.model_valid]
    assert (err.reshape(-1, 3) <= b.model_bounds.max(axis=0) + 1e-12).all()


def test_a_decode_runs_each_archive_payload_once(archive_file, monkeypatch):
    """cpnt's and cana's check() decode their payloads (§6.9: they must decode) and the
    archive needs the words: one decode of each per file, kept on the record until the
    archive takes it (chunks.base.kept / forget)."""
    from mpz.chunks.c3d import Cana, Cpnt
    calls: list[str] = []
    for cls in (Cpnt, Cana):
        real = cls._decode
        monkeypatch.setattr(cls, "_decode", lambda self, F, real=real, t=cls.TYPE:
                            calls.append(t) or real(self, F))
    mpz.decode(archive_file)
    assert sorted(calls) == ["cana", "cpnt"]
    rec = _records(archive_file)["cana"]
    ctx = _ctx(archive_file)
    calls.clear()
    rec.check(ctx)
    rec.decode(ctx.header.frame_count)
    assert calls == ["cana"]
    from mpz.chunks.base import forget
    forget(rec)
    rec.decode(ctx.header.frame_count)
    assert calls == ["cana", "cana"]


def test_version_minor_is_1_only_with_archive_chunks(archive_file):
    from mpz.decoder import read_stream
    assert read_stream(archive_file).header.version_minor == 1
    plain = mpz.encode(mpz.synth.generate("walk", frames=10, markers=4, seed=1), max_error=1.0)
    assert read_stream(plain).header.version_minor == 0


# ------------------------------------------------------------- § rules --
def _fails(data: bytes, ctype: str, section: str, err: type = FormatError, **changes) -> None:
    rec = dataclasses.replace(_records(data)[ctype], **changes)
    with pytest.raises(err) as info:
        rec.check(_ctx(data))
    assert info.value.section == section, str(info.value)


def test_chdr_rules(archive_file):
    _fails(archive_file, "chdr", "§4.13.1", processor=83)
    blk = bytearray(_records(archive_file)["chdr"].block)
    blk[1] = 0
    _fails(archive_file, "chdr", "§4.13.1", block=bytes(blk))


def test_set_rules(archive_file):
    ctx = _ctx(archive_file)
    rec = _records(archive_file)["chdr"]
    for types in (ctx.types + ("chdr",), tuple(t for t in ctx.types if t != "cpnt"),
                  ctx.types + ("cana",)):
        with pytest.raises(FormatError, match="C3D archive"):
            rec.check(dataclasses.replace(ctx, types=types))


@pytest.mark.parametrize("index,changes", [
    (0, {"group": 0}), (0, {"name": b""}), (0, {"name": b"x" * 128}), (0, {"locked": 2}),
    (1, {"type": 3}), (1, {"dims": b"\x01" * 8}),
])
def test_cprm_record_rules(archive_file, index, changes):
    prm = _records(archive_file)["cprm"]
    recs = list(prm.records)
    recs[index] = dataclasses.replace(recs[index], **changes)
    with pytest.raises(FormatError):
        dataclasses.replace(prm, records=tuple(recs)).check(_ctx(archive_file))


@pytest.mark.parametrize("changes", [
    {"mode": 2}, {"shift": 105}, {"shift": -129}, {"order": 3}, {"low_bits": 4},
    {"mode": 1, "shift": 2},
])
def test_channel_entry_rules(archive_file, changes):
    pnt = _records(archive_file)["cpnt"]
    words = list(pnt.words)
    words[0] = dataclasses.replace(words[0], **changes)
    _fails(archive_file, "cpnt", "§4.13", words=tuple(words))      # R-4.13-2


def test_int16_storage_needs_integer_channels(int16_file):
    ana = _records(int16_file)["cana"]
    table = list(ana.table)
    table[0] = dataclasses.replace(table[0], mode=1)
    _fails(int16_file, "cana", "§4.13", table=tuple(table))       # R-4.13-2


def test_cpnt_and_cana_limits(archive_file):
    _fails(archive_file, "cpnt", "§8", LimitExceededError, model_count=4097)
    _fails(archive_file, "cana", "§4.13.4", channels=2, samples=40000)
    big = dataclasses.replace(_records(archive_file)["cana"], samples=1 << 15, channels=1)
    ctx = _ctx(archive_file)
    hdr = dataclasses.replace(ctx.header, frame_count=1 << 14)
    with pytest.raises(LimitExceededError):
        big.check(dataclasses.replace(ctx, header=hdr))


def test_model_axis_rules(archive_file):
    pnt = _records(archive_file)["cpnt"]
    for change in ({"step": 0.0}, {"step": float("nan")}, {"step": 2.0 ** 1000},
                   {"bound": -0.5}, {"offset": float("inf")}, {"order": 3}):
        models = list(pnt.models)
        axes = list(models[0].axes)
        axes[2] = dataclasses.replace(axes[2], **change)
        models[0] = dataclasses.replace(models[0], axes=tuple(axes))
        _fails(archive_file, "cpnt", "§4.13.3", models=tuple(models))
    for kind in (6, 255):                    # R-4.13.3-1: kinds 0..5
        models = list(pnt.models)
        models[-1] = dataclasses.replace(models[-1], kind=kind)
        with pytest.raises(FormatError, match=f"unknown kind {kind}"):
            dataclasses.replace(pnt, models=tuple(models)).check(_ctx(archive_file))


# ----------------------------------------------------------- the channel codec --
floats = st.floats(width=32, allow_nan=True, allow_infinity=True)


@settings(max_examples=60, deadline=None)
@given(st.lists(floats, min_size=1, max_size=40))
def test_float_channels_are_bit_exact(values):
    x = np.array(values, "<f4")
    assert _coded_and_back(x).view(np.uint32).tolist() == x.view(np.uint32).tolist()


def _coded_and_back(x: np.ndarray) -> np.ndarray:
    """One channel of words planned, range-coded and decoded again (§6.9)."""
    p = plan(x)
    enc = BlockEncoder()
    encode_channel(enc, p)
    dec = BlockDecoder(enc.finish())
    back = decode_channel(dec, x.size, p.mode, p.shift, p.order, p.low_bits, x.dtype, "§6.9")
    dec.close()
    return back


@settings(max_examples=40, deadline=None)
@given(st.lists(st.integers(-32768, 32767), min_size=1, max_size=40))
def test_int16_channels_are_exact(values):
    x = np.array(values, "<i2")
    assert _coded_and_back(x).tolist() == x.tolist()


def _outcome(f):
    try:
        return f().tolist()
    except FormatError as exc:
        return (str(exc), exc.offset, exc.section)


_entry = st.tuples(st.sampled_from([0, 1]), st.integers(0, 2), st.integers(0, 3),
                   st.sampled_from([0, 3, 2 ** 12, 2 ** 20, 2 ** 28]), st.integers(0, 9))


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 24),
       st.lists(st.tuples(st.one_of(_entry, st.sampled_from([(0, 1, 0, 2 ** 12, 0),
                                                            (0, 2, 0, 2 ** 28, 0)])),
                          st.integers(1, 4)), min_size=1, max_size=4),
       st.integers(0, 2 ** 32 - 1), st.floats(0.0, 1.0))
def test_channels_decoded_together_fail_where_one_at_a_time_would(T, runs, seed, keep):
    """decode_channels decodes many channels' blocks ahead in one kernel call, and takes a
    run of channels with the same entry as one array; a payload with faults (values past
    int16 or 2^24, low parts past 2^b, order-2 differences past §6.2's guard) and cut
    anywhere gives the values, or the first error with its message and offset, of
    channel-by-channel decoding. The residuals are drawn at random, so faults are common;
    runs of 1 to 4 equal entries, so that some fault inside a run."""
    chans = [c for c, k in runs for _ in range(k)]
    rng = np.random.default_rng(seed)
    entries, rows, signed = [], [], []
    for mode, order, low_bits, scale, low_scale in chans:
        entries.append((mode, 0, order, low_bits))
        rows.append(np.clip(np.round(rng.laplace(0, scale + 0.5, T)), 1 - 2 ** 30,
                            2 ** 30 - 1).astype(np.int64))
        signed.append(True)
        if low_bits:
            rows.append(rng.integers(0, low_scale + 1, T))
            signed.append(False)
    enc = BlockEncoder()
    enc.rows(np.array(rows, np.int64).reshape(len(rows), T), signed)
    data = enc.finish()
    data = data[: max(5, int(len(data) * keep))] if keep < 1 else data
    storage = np.dtype("<i2") if all(m == 0 for m, *_ in entries) and seed % 2 else \
        np.dtype("<f4")
    entries = [(m if storage == np.dtype("<f4") else 0, s, o, b) for m, s, o, b in entries]

    def together():
        out = np.zeros((T, len(entries)), storage)
        dec = BlockDecoder(data, chunk="cana", offset=40)
        decode_channels(dec, T, entries, storage, "§6.9", out)
        dec.close()
        return out

    def one_at_a_time():
        out = np.zeros((T, len(entries)), storage)
        dec = BlockDecoder(data, chunk="cana", offset=40)
        for c, e in enumerate(entries):
            decode_channel(dec, T, *e, storage, "§6.9", out[:, c])
        dec.close()
        return out
    assert _outcome(together) == _outcome(one_at_a_time)


def test_a_run_whose_guard_fails_later_reports_an_earlier_channels_fault_first():
    """Three channels with one entry (order 2), taken as one run: channel 0 decodes past
    2^24, channel 1's order-2 differences pass §6.2's guard at an earlier frame than that.
    A channel-by-channel decoder meets channel 0's fault first, and so must the run."""
    T = 8
    e = np.zeros((3, T), np.int64)
    e[0, T - 1] = 2 ** 25                        # channel 0: 2^25 at the last frame
    e[1, :] = 2 ** 30 - 1                        # channel 1: |d| reaches 2^32 at frame 4
    enc = BlockEncoder()
    enc.rows(e, [True] * 3)
    dec = BlockDecoder(enc.finish(), chunk="cana")
    out = np.zeros((T, 3), np.float32)
    with pytest.raises(FormatError, match="is not below 2\\^24") as got:
        decode_channels(dec, T, [(0, 0, 2, 0)] * 3, np.dtype("<f4"), "§6.9", out)
    assert got.value.section == "§6.9"


def test_model_axes_in_one_run_fail_where_one_at_a_time_would():
    """Model-output axes with one order are taken as one run: axis x of output 0 passes
    2^31 (its differences stay within §6.2's guard), axis y's differences pass the guard at
    an earlier frame. An axis-by-axis decoder meets x's fault first, and so must the run;
    without faults the run gives k x step + offset, the product rounded first."""
    from mpz.c3dcodec import decode_model_axes
    T = 8
    e = np.zeros((3, T), np.int64)
    e[0, 1] = 2 ** 30 - 1                        # x: k = t (2^30 - 1), up to 7 (2^30 - 1)
    e[1, :] = 2 ** 30 - 1                        # y: |d| reaches 2^32 at frame 4
    enc = BlockEncoder()
    enc.rows(e, [True] * 3)
    out = np.zeros((T, 3))
    with pytest.raises(FormatError, match="model output 0 axis x: value 7516192761 is not "
                                          "below 2\\^31") as got:
        decode_model_axes(BlockDecoder(enc.finish()), T, [(2, 0.5, 1.0)] * 3, "§6.9", out)
    assert got.value.section == "§6.9"
    good = np.array([[3, -1, 2, 0, 5, 1, 1, 1], [0] * 8, [7] * 8], np.int64)
    enc = BlockEncoder()
    enc.rows(good, [True] * 3)
    axes = [(1, 0.1, 3.0), (1, 0.3, -1.0), (0, 2.0 ** -7, 0.25)]
    dec = BlockDecoder(enc.finish())
    decode_model_axes(dec, T, axes, "§6.9", out)
    dec.close()
    for a, (order, step, offset) in enumerate(axes):
        k = np.cumsum(good[a]) if order == 1 else good[a]
        want = [float(np.float64(v) * np.float64(step)) + offset for v in k.tolist()]
        assert out[:, a].tolist() == want, a


#: 32-bit words at the ends of the ordered map (§6.9): NaN patterns, infinities, +-0
EXTREME_WORDS = [0x7FFFFFFF, 0x7FFFFFFE, 0x80000000, 0x80000001, 0xFFFFFFFF, 0xFFFFFFFE,
                 0x00000000, 0x00000001, 0x7F800000, 0xFF800000]
words32 = st.one_of(st.sampled_from(EXTREME_WORDS), st.integers(0, 2 ** 32 - 1))


@settings(max_examples=200, deadline=None)
@given(st.lists(words32, min_size=1, max_size=12))
def test_float_channels_of_any_bit_pattern_are_bit_exact(words):
    """Every float32 word a C3D can hold, NaN payloads included. The word 0xFFFFFFFE (e =
    -(2^31 - 1) at order 0) was refused with LimitExceededError: b was taken from |e|
    alone, and floor division gave h = -2^30, outside the coder's range (spec review,
    stop 34)."""
    x = np.array(words, np.uint32).view("<f4")
    assert _coded_and_back(x).view(np.uint32).tolist() == list(words)


def _orders_as_defined(column: list[int], max_low: int) -> tuple[int, int]:
    """(order, b) of one column by the definition, in Python integers: the cheapest order
    by sum(log2(1 + |e|)), lowest on a tie, among those with a b <= max_low that puts every
    floor(e / 2^b) strictly within +-2^30 (§5.4); (0, -1) if none has one."""
    best: tuple[float, int, int] | None = None
    for order in range(3):
        e = [v - (column[t - 1] if order and t >= 1 else 0)
             - ((column[t - 1] - column[t - 2]) if order == 2 and t >= 2 else 0)
             for t, v in enumerate(column)]
        fit = [b for b in range(max_low + 1)
               if all(-(2 ** 30) < (r // 2 ** b) < 2 ** 30 for r in e)]
        cost = float(np.log2(1.0 + np.abs(np.array(e, np.float64))).sum())
        if fit and (best is None or cost < best[0]):
            best = (cost, order, fit[0])
    return (0, -1) if best is None else (best[1], best[2])


@settings(max_examples=150, deadline=None)
@given(st.integers(1, 8), st.integers(1, 4), st.sampled_from([0, 3]), st.data())
def test_best_orders_takes_only_orders_the_coder_can_code(T, C, max_low, data):
    """A channel's order and b (§6.9) and a model output's order (§4.13.3, b = 0): an
    order whose residuals do not fit the coder is never chosen, however cheap."""
    from mpz.c3dcodec import best_orders
    ends = st.sampled_from([-(2 ** 31), -(2 ** 31) + 1, 2 ** 31 - 1, -(2 ** 30) + 1, 2 ** 30 - 1,
                            -(2 ** 29), 2 ** 29, 0])
    value = st.one_of(ends, st.integers(-(2 ** 31), 2 ** 31 - 1), st.integers(-4, 4))
    cols = [data.draw(st.lists(value, min_size=T, max_size=T)) for _ in range(C)]
    orders, lows = best_orders(np.array(cols, np.int64).T.copy(), max_low)
    for c, col in enumerate(cols):
        assert (int(orders[c]), int(lows[c])) == _orders_as_defined(col, max_low), col


def _lowest_bit_exponent(x: float) -> int:
    """e with x = odd x 2^e, from Python's exact ratio (independent of c3dcodec)."""
    n, d = abs(x).as_integer_ratio()                       # d is a power of two
    return (n & -n).bit_length() - 1 - (d.bit_length() - 1)


@settings(max_examples=80, deadline=None)
@given(st.lists(st.floats(width=32, allow_nan=False, allow_infinity=False),
                min_size=1, max_size=30))
def test_dyadic_shift_is_the_lowest_set_bit(values):
    """The shift is the least exponent of the lowest set bit over the nonzero words,
    clamped to the §4.13 range, and k x 2^shift gives the words back."""
    from mpz.c3dcodec import _dyadic_rows
    x = np.array(values, "<f4")
    _dyadic_as_defined(x, _dyadic_rows(x.reshape(1, -1))[0])


def _dyadic_as_defined(x, got):
    """The oracle of the k x 2^shift coding of one channel ``x``, in Python's exact
    arithmetic."""
    from mpz.format import C3D_MAX_SHIFT, C3D_MIN_SHIFT
    if (x.view(np.uint32) == 0x80000000).any() or not np.isfinite(x).all():
        assert got is None                   # -0.0, NaN, inf: mode 1 keeps the bits
        return
    nz = [float(v) for v in x if v != 0]
    want = min((_lowest_bit_exponent(v) for v in nz), default=0) if nz else 0
    want = max(C3D_MIN_SHIFT, min(C3D_MAX_SHIFT, want))
    fits = all(abs(v) / 2.0 ** want < 2 ** 24 and (v / 2.0 ** want).is_integer() for v in nz)
    if not fits:
        assert got is None
        return
    assert got is not None and got[0] == (want if nz else 0)
    assert np.array_equal(np.ldexp(got[1].astype(np.float64), got[0]).astype("<f4"), x)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 12), st.integers(1, 6), st.data())
def test_dyadic_rows_decide_each_channel_on_its_own(T, C, data):
    """plan_all decides every channel in one pass (issue 15.1): each column must get what
    the definition gives it alone, next to columns of NaN, -0.0, infinities, zeros,
    fixed-point values, subnormal words or arbitrary floats."""
    from mpz.c3dcodec import _dyadic_rows
    kinds = st.sampled_from(["any", "fixed", "tiny", "zeros", "special"])
    cols = []
    for _ in range(C):
        kind = data.draw(kinds)
        if kind == "fixed":
            e = data.draw(st.integers(-20, 4))
            ks = data.draw(st.lists(st.integers(-2 ** 23, 2 ** 23), min_size=T, max_size=T))
            col = np.ldexp(np.array(ks, np.float64), e).astype("<f4")
        elif kind == "tiny":           # subnormal words (below 2^-126), some exact at 2^-128
            e = data.draw(st.integers(-149, -124))
            ks = data.draw(st.lists(st.integers(-9, 9), min_size=T, max_size=T))
            col = np.ldexp(np.array(ks, np.float64), e).astype("<f4")
        elif kind == "zeros":
            col = np.zeros(T, "<f4")
        else:
            vals = st.floats(width=32, allow_nan=kind == "special",
                             allow_infinity=kind == "special")
            col = np.array(data.draw(st.lists(vals, min_size=T, max_size=T)), "<f4")
        cols.append(col)
    x = np.ascontiguousarray(np.stack(cols))                       # [C, T]
    for c, got in enumerate(_dyadic_rows(x)):
        _dyadic_as_defined(x[c], got)


def test_dyadic_at_the_subnormal_edge():
    """Subnormal words are m x 2^-149 (no implicit bit); the §4.13 shift stops at -128, so
    2^-128 and its multiples take mode 0 and 2^-149 cannot (k would not be an integer)."""
    from mpz.c3dcodec import _dyadic_rows
    rows = [[2.0 ** -128, 3 * 2.0 ** -128, -(2.0 ** -127), 0.0],   # subnormal, exact at -128
            [2.0 ** -126, 2.0 ** -127, 5 * 2.0 ** -126, 2.0 ** -100],  # normal and subnormal
            [2.0 ** -149, 0.0, 0.0, 0.0],                           # below the range
            [2.0 ** 103, -(2.0 ** 104), 2.0 ** 126, 1.0]]           # above 2^24 x 2^shift
    x = np.array(rows, "<f4")
    got = _dyadic_rows(x)
    for c in range(len(rows)):
        _dyadic_as_defined(x[c], got[c])
    assert got[0] is not None and got[0][0] == -128 and got[0][1].tolist() == [1, 3, -2, 0]
    assert got[2] is None


def test_ordered_map_is_monotonic_and_inverts():
    x = np.array([-np.inf, -1e38, -1.0, -1e-45, -0.0, 0.0, 1e-45, 1.0, 3e38, np.inf], "<f4")
    v = ordered(x.view(np.uint32))
    assert (np.diff(v) > 0).all() and v[4] == -1 and v[5] == 0
    assert unordered(v).tolist() == x.view(np.uint32).tolist()


def test_fixed_point_floats_take_mode_0():
    x = (np.arange(-50, 50) * 2.0 ** -15).astype("<f4")
    p = plan(x)
    assert (p.mode, p.shift) == (0, -15)
    assert plan(np.array([0.0, -0.0], "<f4")).mode == 1        # -0.0 keeps its sign bit


# ------------------------------------------------------------- hostile input --
@pytest.mark.parametrize("dims", [bytes([255]) * 200, bytes([2]) * 17 + bytes([8])])
def test_a_parameter_larger_than_any_section_is_named_so(dims):
    """A parameter record of more than 7 dimensions that multiply past the 2^17 bytes of
    a section (a misread or hostile dims count of up to 255) is refused with a message of
    one line that says so, not construct's request for a read of a 600-digit length (a
    QA run, stop 40): 255^200 bytes, and 2^17 x 8 (its 18th dimension passes the
    limit). Up to 7 dimensions the read fails as before (vector x183)."""
    from mpz.chunks.c3d import Cprm
    record = bytes([1, 0, 1]) + b"A" + bytes([0, 1, len(dims)]) + dims   # no data follows
    payload = bytes([0]) + (1).to_bytes(2, "little") + record        # coding 0: stored
    with pytest.raises(FormatError, match=r"malformed cprm payload: a parameter of "
                       rf"{len(dims)} dimensions .* holds more than the 131072 bytes "
                       r"of a parameter section \(§4.13.2, §8\)") as err:
        Cprm.load(payload)
    assert len(str(err.value)) < 300 and "\n" not in str(err.value)


def test_a_misread_string_quotes_a_few_bytes():
    """A payload whose strings are read from the wrong place (an asfs with a bone count
    too large) gives a message that quotes the first bytes of the string and its length,
    not all of them (a QA run, stop 40: 507 characters)."""
    from mpz.chunks.base import _short
    junk = bytes(range(128, 256)) * 3
    try:
        junk.decode("utf-8")
    except UnicodeDecodeError:
        pass
    msg = _short(ValueError(f"cannot use encoding 'utf8' to decode {junk!r}"))
    assert msg.startswith("cannot use encoding 'utf8' to decode b'\\x80\\x81")
    assert msg.endswith(f"... ({len(repr(junk))} characters)") and len(msg) < 100
    assert _short(ValueError("requested " + "7" * 40 + " bytes")) == \
        "requested <a 40-digit number> bytes"
    assert _short(ValueError("short b'abc' 12345")) == "short b'abc' 12345"    # as it was


def test_a_coordinate_past_float32_is_refused_without_a_numpy_warning(archive_file):
    """Writing a decoded C3D archive back whose marker holds 1e308 (valid in MPZ) refuses
    with the writer's error alone: its int16 test divided by the scale first, and numpy's
    overflow warning came out before the error (a QA run, stop 40)."""
    import warnings

    from mpz.errors import InputFormatError
    from mpz.io.c3d import archive_bytes
    m = mpz.decode(archive_file)
    m.positions[0, 0, 0] = 1e308
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(InputFormatError, match="does not fit a float32 C3D"):
            archive_bytes(m)


def _only_mpz_errors(data: bytes) -> None:
    try:
        mpz.decode(data)
    except MPZError:
        pass


def test_truncation_at_every_byte_of_the_archive_chunks(archive_file):
    chunks = container.scan(archive_file).chunks
    start = next(c.offset for c in chunks if c.type == "chdr")
    for n in range(start, len(archive_file), 7):
        with pytest.raises(MPZError):
            mpz.decode(archive_file[:n])


def test_mutated_archive_payloads_with_repaired_crcs(archive_file):
    rng = np.random.default_rng(12)
    chunks = container.scan(archive_file).chunks
    spans = [(c.offset + 8, c.offset + 8 + c.length) for c in chunks
             if c.type in ("chdr", "cprm", "cpnt", "cana")]
    for _ in range(300):
        lo, hi = spans[int(rng.integers(len(spans)))]
        b = bytearray(archive_file)
        for _ in range(int(rng.integers(1, 4))):
            b[int(rng.integers(lo, hi))] = int(rng.integers(256))
        _only_mpz_errors(container.repair_crcs(bytes(b)))


def _stored(data: bytes) -> bytes:
    """The file with chdr and cprm stored (§4.13 coding 0), so their fields sit at fixed
    payload offsets."""
    out = []
    for c in container.scan(data).chunks:
        if c.type in ("chdr", "cprm"):
            out.append((c.type, dataclasses.replace(c.record, coding=0).dump()))
        else:
            out.append((c.type, c.payload))
    return container.build(out)


@pytest.mark.parametrize("ctype,field_offset,width", [
    ("cprm", 1, 2),            # record count, after the coding byte
    ("cpnt", 1, 2),            # point_count
    ("cana", 1, 2),            # channels
    ("cana", 3, 2),            # samples
])
def test_length_fields_at_their_maximum(archive_file, ctype, field_offset, width):
    stored = _stored(archive_file)
    mpz.decode(stored)                     # valid as it is: only the field makes it bad
    c = next(c for c in container.scan(stored).chunks if c.type == ctype)
    b = bytearray(stored)
    at = c.offset + 8 + field_offset
    b[at:at + width] = b"\xff" * width
    with pytest.raises(MPZError):
        mpz.decode(container.repair_crcs(bytes(b)))


def test_cprm_dimensions_at_their_maximum(archive_file):
    """7 dimensions of 255 declare about 2^57 data bytes: malformed, nothing allocated."""
    prm = _records(archive_file)["cprm"]
    recs = list(prm.records)
    i = next(k for k, r in enumerate(recs) if not r.is_group)
    payload = bytearray(dataclasses.replace(prm, coding=0).dump())
    raw = recs[i]
    head = struct.pack("<bB", raw.group, raw.locked) + bytes([len(raw.name)]) + raw.name
    at = payload.index(head) + len(head) + 1 + len(raw.description) + 1
    payload[at:at + 1 + len(raw.dims or b"")] = bytes([7]) + b"\xff" * 7
    chunks = [(c.type, bytes(payload) if c.type == "cprm" else c.payload)
              for c in container.scan(archive_file).chunks]
    with pytest.raises(FormatError):
        mpz.decode(container.build(chunks))


def test_every_archive_chunk_type_is_in_the_table():
    assert [t for t in CHUNKS if t[0] == "c"] == ["chdr", "cprm", "cpnt", "cana"]


def test_coordinates_beyond_float32_are_refused_by_the_c3d_writer(tmp_path):
    """A valid MPZ file may hold coordinates past float32 (§4.4); a float C3D cannot, so
    writing one is a clear InputFormatError, not an overflow to infinity."""
    from mpz.errors import InputFormatError
    m = c3d_motion(5, storage=1, F=12, M=4, J=2, C=2, n=2)
    huge = mpz.Motion(m.positions * 1e36, m.names, m.rate, m.units, m.valid,
                      dict(m.metadata), extras=dict(m.extras))
    back = mpz.decode(mpz.encode(huge, max_error=1e33))
    assert float(np.nanmax(np.abs(back.positions))) > float(np.finfo(np.float32).max)
    with pytest.raises(InputFormatError, match=r"float32.* beyond it"):   # check_writable
        mpz.io.write(back, tmp_path / "out.c3d")


# ------------------------------------------------------ model outputs (§4.13.3) --
def _axis_oracle(x, ok, rel, grid):
    """§4.13.3 one model-output axis, one axis at a time, restated from the spec and the
    encoder's documented choices (the per-axis loop the encoder ran before issue 15.1):
    (offset, step, declared, order, residuals)."""
    from mpz.c3dcodec import MODEL_LIMIT, SQRT_SAFETY
    from mpz.predict import residuals
    v = x[ok]
    bound = rel * (float(v.max() - v.min()) if v.size else 0.0)
    if grid is not None and v.size and np.array_equal(np.rint(v / grid) * grid, v) \
            and np.abs(v / grid).max() < MODEL_LIMIT // 2:
        offset, step, declared = 0.0, float(grid), 0.0
    elif v.size == 0:
        offset, step, declared = 0.0, 1.0, 0.0
    elif float(v.min()) == float(v.max()):
        offset, step, declared = float(v.min()), 1.0, 0.0
    else:
        lo, hi = float(v.min()), float(v.max())
        # Appendix C item 3: off the int16 grid the C3D is written as float32, which moves
        # a value by up to h = half float32's spacing at max|v| + bound; code within
        # bound - h, or bound / 2 when every value is binary32 (the nearest binary32 is
        # then no farther than the source), or bound when neither is possible
        h = 2.0 ** (np.floor(np.log2(max(abs(lo), abs(hi)) + bound)) - 24)
        within = bound - h
        if within < bound / 2:
            within = bound / 2 if np.array_equal(v.astype(np.float32), v) else bound
        step = 2.0 * within * SQRT_SAFETY
        offset = (lo + hi) / 2.0
        if not (np.isfinite(step) and step > 0) or (hi - lo) / step >= MODEL_LIMIT // 2:
            step = (hi - lo) / (MODEL_LIMIT // 2)
        declared = max(within, step / 2.0, bound)
    u = np.where(ok, (np.nan_to_num(x) - offset) / step, 0.0)
    t = np.arange(len(u))
    k = (np.rint(u) if ok.all() else np.zeros(len(u)) if not ok.any()
         else np.rint(np.interp(t, t[ok], u[ok]))).astype(np.int64)
    assert (np.abs(k) < MODEL_LIMIT // 2).all()
    assert np.abs(k * step + offset - x)[ok].max(initial=0.0) <= declared
    costs = [float(np.log2(1.0 + np.abs(residuals(k[:, None, None], o))).sum())
             for o in range(3)]
    order = int(np.argmin(costs))
    return offset, step, declared, order, residuals(k[:, None, None], order)


_COLUMNS = st.sampled_from(["walk", "gaps", "constant", "none", "grid", "late", "tiny"])


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10 ** 6), st.sampled_from([0, 1]), st.integers(2, 40),
       st.lists(_COLUMNS, min_size=1, max_size=5), st.sampled_from([None, 1e-4, 0.3]),
       st.booleans())
def test_model_axes_are_each_axis_on_its_own(seed, storage, F, kinds, angles, late_gap):
    """The encoder forms all J x 3 model axes at once (issue 15.1). Each axis's grid,
    order and residuals must be those of the axis on its own, whatever the others hold
    (gaps, constants, no valid frame, values on the int16 grid, tiny ranges)."""
    from mpz.c3darchive import _model_axes
    from mpz.encoder import EncodeOptions
    J = len(kinds)
    a = c3d_motion(seed % 1000, storage=storage, F=F, M=3, J=J, C=1, n=1).extras["c3d"]
    rng = np.random.default_rng(seed)
    x = np.cumsum(rng.normal(0, 0.3, (F, J, 3)), axis=0) + 5.0
    ok = np.ones((F, J), bool)
    for j, kind in enumerate(kinds):
        if kind == "gaps":
            ok[:, j] = rng.random(F) < 0.6
        elif kind == "constant":
            x[:, j] = 2.5
        elif kind == "none":
            ok[:, j] = False
        elif kind == "grid":                                  # on |POINT:SCALE| = 0.5
            x[:, j] = np.rint(x[:, j] / 0.5) * 0.5
        elif kind == "late":
            ok[: F // 2, j] = False
        elif kind == "tiny":
            x[:, j] = 1e6 + rng.integers(0, 3, (F, 3)) * 1e-9
    if late_gap:
        ok[-1] = False
    x[~ok] = np.nan
    a.models, a.model_valid = x, ok
    opts = EncodeOptions(model_errors={} if angles is None else {"ANGLES": angles})
    grid = a.point_grid()
    models, rows = [], []
    for batch, r in _model_axes(a, opts):
        models += batch
        rows.append(r)
    blocks = np.concatenate(rows)
    assert len(models) == J and blocks.shape == (3 * J, F)
    for j in range(J):
        name = "ANGLES" if a.model_kinds[j] == 0 else "POWERS"
        rel = opts.model_errors.get(name, opts.model_error)
        for ax in range(3):
            want = _axis_oracle(x[:, j, ax], ok[:, j], rel,
                                None if name in opts.model_errors else grid)
            got = models[j].axes[ax]
            assert (got.offset, got.step, got.bound, got.order) == want[:4]
            assert np.array_equal(blocks[3 * j + ax], want[4][:, 0, 0])


def test_a_model_output_off_any_grid_is_refused_by_number():
    """A valid model value that is not finite, or a range too wide for float64, leaves no
    grid for its axis (§4.13.3): the encoder refuses it with EncoderError, naming the
    first such model output, axis and frame, rather than a coder-range error or a file
    its own decoder rejects."""
    from mpz.c3darchive import _model_axes
    from mpz.encoder import EncodeOptions
    from mpz.errors import EncoderError
    a = c3d_motion(3, storage=1, F=10, M=3, J=3, C=1, n=1).extras["c3d"]
    a.models[6, 2, 0] = -np.inf
    a.models[4, 1, 2] = np.inf
    with pytest.raises(EncoderError, match="model output 1 axis z: inf at frame 4 is not fin"):
        list(_model_axes(a, EncodeOptions()))
    a.models[4, 1, 2] = 1.5
    a.models[5, 1, 0] = np.nan                          # valid, but NaN
    with pytest.raises(EncoderError, match="model output 1 axis x: nan at frame 5"):
        list(_model_axes(a, EncodeOptions()))
    a.models[5, 1, 0] = 1.5
    a.models[:, 2, 0] = 0.0
    a.models[6, 2, 0] = -1.7e308                        # hi - lo overflows to inf
    a.models[7, 2, 0] = 1.7e308
    with pytest.raises(EncoderError, match=r"output 2 axis x: values -1.7e\+308 .. 1.7e\+308"):
        with np.errstate(all="ignore"):
            list(_model_axes(a, EncodeOptions()))


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10 ** 6), st.sampled_from([0, 1]), st.integers(1, 30),
       st.integers(0, 5), st.integers(1, 4), st.integers(1, 200))
def test_channel_batches_do_not_change_the_bytes(seed, storage, F, J, C, batch):
    """The C3D channel coder works in batches of channels (c3dcodec.BATCH_VALUES, for
    bounded memory on long captures, issue 11.11); the cpnt and cana payloads must not
    depend on the batch size."""
    from mpz import c3dcodec
    from mpz.c3darchive import analog_record, point_records
    from mpz.encoder import EncodeOptions
    m = c3d_motion(seed, storage=storage, F=F, M=3, J=J, C=C, n=2)
    a, opts = m.extras["c3d"], EncodeOptions()
    want = point_records(a, opts, 3).dump(), analog_record(a).dump()
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(c3dcodec, "BATCH_VALUES", batch)
        mp.setattr("mpz.c3darchive.BATCH_VALUES", batch)
        assert (point_records(a, opts, 3).dump(), analog_record(a).dump()) == want


def test_model_outputs_beyond_a_lowered_sample_limit_are_refused_before_allocation():
    """§4.13.3 / §8: F x J <= MAX_SAMPLES (lowered by max_samples) before the model outputs
    are allocated. A mutation run removed the F x J test and no test failed: a valid file of
    2 markers and 5 model outputs passes F x M = 48 and must stop at F x J = 120."""
    m = c3d_motion(74, storage=1, M=2, J=5, C=0)
    data = mpz.encode(m, max_error=1.0)
    assert mpz.decode(data, max_samples=24 * 5).extras["c3d"].models.shape[1] == 5
    with pytest.raises(LimitExceededError, match="5 model outputs x 24 frames") as err:
        mpz.decode(data, max_samples=24 * 2)
    assert err.value.chunk == "cpnt"


def test_an_archive_without_cana_keeps_header_word_10_as_its_analog_samples():
    """§6.9: without a cana chunk, the archive's analog samples per frame come from header
    word 10 (bytes 18-19), which a writer puts back; a mutation run read word 9 (here 11,
    the analog words a frame) and no test failed."""
    m = c3d_motion(73, storage=1, C=0, n=4, J=0)
    assert m.extras["c3d"].header[16:20] == bytes([11, 0, 4, 0])       # words 9 and 10
    back = mpz.decode(mpz.encode(m, max_error=1.0)).extras["c3d"]
    assert back.analog_samples == 4
