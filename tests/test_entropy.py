"""The range coder of spec §5 against an independent, straight-from-the-text
pure-Python implementation, plus hand-derived vectors and round-trip properties."""
from hypothesis import given, settings
from hypothesis import strategies as st
import numpy as np
import pytest

from mpz.conformance.rangecoder import RefEncoder
from mpz.entropy import BlockDecoder, BlockEncoder
from mpz.errors import FormatError, LimitExceededError


def test_empty_payload_is_five_zero_bytes():
    # §5.1: flushing a fresh coder emits the cache byte 0 then the 4 bytes of low = 0
    assert BlockEncoder().finish() == b"\x00" * 5
    BlockDecoder(b"\x00" * 5).close()


@pytest.mark.parametrize("values,period,signed", [
    ([[[0, 0, 0]]], None, True),
    ([[[1, -1, 2]], [[3, -4, 0]]], None, True),
    ([[[2 ** 29 + 5, -(2 ** 30 - 1), 7]]], None, True),
    ([[[5, 6, 7], [1, 2, 3]], [[0, 0, 1], [9, 9, 9]]], 1, True),
    ([[[0], [1]], [[1], [1]]], None, False),
])
def test_matches_reference_implementation(values, period, signed):
    v = np.array(values, dtype=np.int64)
    ref = RefEncoder()
    ref.block(v, period, signed)
    enc = BlockEncoder(capacity=8)
    enc.block(v, period=period, signed=signed)
    assert enc.finish() == ref.finish()


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 12), st.integers(1, 4), st.integers(1, 3), st.integers(0, 2 ** 30 - 1),
       st.integers(0, 2 ** 32 - 1))
def test_roundtrip_and_reference_agree(T, M, A, scale, seed):
    rng = np.random.default_rng(seed)
    v = np.clip(np.round(rng.laplace(0, scale + 1e-9, (T, M, A))), -(2 ** 30 - 1), 2 ** 30 - 1)
    v = v.astype(np.int64)
    enc = BlockEncoder()
    enc.block(v)
    enc.block(v[:, :1], period=2)
    data = enc.finish()
    ref = RefEncoder()
    ref.block(v)
    ref.block(v[:, :1], period=2)
    assert data == ref.finish()
    dec = BlockDecoder(data)
    assert np.array_equal(dec.block(T, M, A), v)
    assert np.array_equal(dec.block(T, 1, A, period=2), v[:, :1])
    dec.close()


def test_value_out_of_range_is_refused():
    with pytest.raises(LimitExceededError):
        BlockEncoder().block(np.array([[[2 ** 30, 0, 0]]]))


def test_decoder_errors():
    enc = BlockEncoder()
    enc.block(np.arange(30).reshape(10, 1, 3))
    data = enc.finish()
    with pytest.raises(FormatError, match="start with byte 0"):
        BlockDecoder(b"\x01" + data[1:])
    with pytest.raises(FormatError, match="shorter than"):
        BlockDecoder(data[:3])
    with pytest.raises(FormatError, match="ends before"):
        BlockDecoder(data[: len(data) // 2]).block(10, 1)
    dec = BlockDecoder(data + b"\x00")
    dec.block(10, 1)
    with pytest.raises(FormatError, match="left after"):
        dec.close()


# issue 15: the encoder kernel keeps the coder state in locals and the models in one flat
# array; its bytes must stay those of the §5 text (RefEncoder), block after block
_block = st.tuples(st.integers(0, 9), st.integers(1, 4), st.integers(1, 3),
                   st.sampled_from([0.3, 2.0, 40.0, 3e4, 2 ** 29]), st.booleans(),
                   st.integers(0, 2 ** 32 - 1))


def _laplace_values(T: int, M: int, A: int, scale: float, signed: bool,
                    seed: int) -> np.ndarray:
    """A block of Laplace-distributed integers within the coder's 2^30 (non-negative for an
    unsigned block)."""
    rng = np.random.default_rng(seed)
    v = np.clip(np.round(rng.laplace(0, scale, (T, M, A))), -(2 ** 30 - 1), 2 ** 30 - 1)
    v = v.astype(np.int64)
    return v if signed else np.abs(v)


@settings(max_examples=80, deadline=None)
@given(st.lists(_block, min_size=1, max_size=4), st.integers(1, 64))
def test_fast_encoder_matches_reference_over_several_blocks(blocks, capacity):
    enc = BlockEncoder(capacity=capacity)          # a small buffer grows between blocks
    ref = RefEncoder()
    for T, M, A, scale, signed, seed in blocks:
        v = _laplace_values(T, M, A, scale, signed, seed)
        period = None if T < 2 or seed % 3 == 0 else (T if T % 2 else 2)
        enc.block(v, period=period, signed=signed)
        ref.block(v, period, signed)
    assert enc.finish() == ref.finish()


@settings(max_examples=80, deadline=None)
@given(st.lists(_block, min_size=1, max_size=3), st.integers(0, 400))
def test_limit_stops_only_payloads_longer_than_it(blocks, limit):
    """issue 15.1: with ``limit`` the coder gives up exactly when the whole payload (the §5
    reference coder's, computed here independently) would be longer than ``limit`` bytes;
    otherwise it returns the same bytes."""
    ref = RefEncoder()
    enc = BlockEncoder(capacity=16, limit=limit)
    for T, M, A, scale, signed, seed in blocks:
        v = _laplace_values(T, M, A, scale, signed, seed)
        enc.block(v, signed=signed)
        ref.block(v, None, signed)
    full = ref.finish()
    if len(full) > limit and enc.over:
        with pytest.raises(ValueError, match="limit"):
            enc.finish()
    else:
        assert not enc.over            # it may stop only when the payload is too long
        assert enc.finish() == full


#: rows of a C3D-like record: (Laplace scale, signed) each
_row_specs = st.lists(st.tuples(st.integers(0, 2 ** 30 - 1), st.booleans()), max_size=6)


def _reference_rows(T: int, rows: list[tuple[int, bool]], seed: int
                    ) -> tuple[np.ndarray, bytes]:
    """Values ``[len(rows), T]`` drawn by ``rows`` (scale, signed), and the payload the §5
    reference coder writes for each row as a block [T, 1, 1] with fresh models."""
    ref = RefEncoder()
    vals = np.zeros((len(rows), T), np.int64)
    for b, (scale, signed) in enumerate(rows):
        vals[b] = _laplace_values(T, 1, 1, scale, signed, seed + b)[:, 0, 0]
        ref.block(vals[b][:, None, None], None, signed)
    return vals, ref.finish()


@settings(max_examples=80, deadline=None)
@given(st.integers(0, 40), _row_specs,
       st.integers(0, 2 ** 32 - 1), st.integers(1, 64), st.sampled_from([None, 0, 30, 200]))
def test_rows_are_the_blocks_of_the_reference_coder(T, rows, seed, capacity, limit):
    """BlockEncoder.rows (issue 15.1: one kernel call for a C3D record's channels) writes
    what the §5 reference coder writes for each row as a block [T, 1, 1] of one run with
    fresh models, signed or not; with a limit it stops only payloads longer than it."""
    vals, full = _reference_rows(T, rows, seed)
    enc = BlockEncoder(capacity=capacity, limit=limit)
    enc.rows(vals, [s for _, s in rows])
    if enc.over:
        assert limit is not None and len(full) > limit
    else:
        assert enc.finish() == full


def test_rows_check_their_values_first():
    enc = BlockEncoder()
    with pytest.raises(LimitExceededError, match="2\\^30"):
        enc.rows(np.array([[1, 2], [0, 2 ** 30]]), [True, True])
    with pytest.raises(ValueError, match="negative value in an unsigned block"):
        enc.rows(np.array([[1, -2], [0, -1]]), [True, False])
    with pytest.raises(ValueError, match="one sign flag a row"):
        enc.rows(np.array([[1, 2]]), [True, False])
    assert enc.finish() == BlockEncoder().finish()          # nothing was coded


@settings(max_examples=80, deadline=None)
@given(st.integers(0, 40), _row_specs,
       st.integers(0, 2 ** 32 - 1), st.integers(0, 12), st.lists(st.integers(1, 4)))
def test_decoded_rows_are_the_reference_coders_blocks(T, rows, seed, words, takes):
    """BlockDecoder.rows gives back, in order, the blocks [T, 1, 1] the §5 reference coder
    wrote with fresh models, signed or not, however few values it may decode ahead
    (``ROW_WORDS``: here 1 to 4096) and however many rows are asked for at a time (each
    take(n) gives 1 to n); the payload is then consumed exactly."""
    from mpz import entropy
    vals, data = _reference_rows(T, rows, seed)
    old = entropy.ROW_WORDS
    entropy.ROW_WORDS = 1 << words
    try:
        dec = BlockDecoder(data)
        reader = dec.rows(T, [s for _, s in rows])
        got = []
        for n in takes:
            if not len(reader):
                break
            part = reader.take(n)
            assert 1 <= part.shape[0] <= n and part.shape[1] == T
            got += list(part)
        got += list(reader)
        assert len(reader) == 0
    finally:
        entropy.ROW_WORDS = old
    assert len(got) == len(rows)
    for b, row in enumerate(got):
        assert np.array_equal(row, vals[b]), b
    dec.close()


@pytest.mark.parametrize("words", [0, 3, 16])
def test_rows_run_out_where_the_block_calls_would(words):
    """A payload cut short: rows gives every row that decodes whole, and raises the §5.3
    error (same message, same offset) only when the caller asks for the row that runs out,
    as the block() of that row would; decoding ahead never raises early."""
    from mpz import entropy
    enc = BlockEncoder()
    vals = np.arange(60).reshape(6, 10) * 37 - 500
    enc.rows(vals, [True] * 6)
    data = enc.finish()
    dec = BlockDecoder(data)
    for _ in range(3):
        dec.block(10, 1, 1)
    cut = dec.consumed + 1               # the fourth row needs bytes past this
    seq = BlockDecoder(data[:cut], chunk="cana", offset=100)
    whole = 0
    with pytest.raises(FormatError) as want:
        for _ in range(6):
            seq.block(10, 1, 1)
            whole += 1
    old = entropy.ROW_WORDS
    entropy.ROW_WORDS = 1 << words
    try:
        rows = BlockDecoder(data[:cut], chunk="cana", offset=100).rows(10, [True] * 6)
        for b in range(whole):
            assert np.array_equal(rows.take(1)[0], vals[b])
        with pytest.raises(FormatError) as got:
            rows.take(1)
    finally:
        entropy.ROW_WORDS = old
    assert whole >= 3
    assert (str(got.value), got.value.offset, got.value.chunk) == (
        str(want.value), want.value.offset, want.value.chunk)
