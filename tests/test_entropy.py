"""The range coder of spec §5 against an independent, straight-from-the-text
pure-Python implementation, plus hand-derived vectors and round-trip properties."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from mpz.entropy import BlockDecoder, BlockEncoder
from mpz.errors import FormatError, LimitExceededError


class RefEncoder:
    """Spec §5.1-§5.6 written out independently (slow, obviously correct)."""

    def __init__(self):
        self.low, self.range, self.cache, self.csize, self.out = 0, 0xFFFFFFFF, 0, 1, bytearray()

    def shift_low(self):
        if self.low < 0xFF000000 or self.low >= 1 << 32:
            carry = self.low >> 32
            temp = self.cache
            while True:
                self.out.append((temp + carry) & 0xFF)
                temp = 0xFF
                self.csize -= 1
                if self.csize == 0:
                    break
            self.cache = (self.low >> 24) & 0xFF
        self.csize += 1
        self.low = (self.low & 0x00FFFFFF) << 8

    def bit(self, probs, key, b):
        p = probs.get(key, 1024)
        bound = (self.range >> 11) * p
        if b == 0:
            self.range = bound
            probs[key] = p + ((2048 - p) >> 5)
        else:
            self.low += bound
            self.range -= bound
            probs[key] = p - (p >> 5)
        while self.range < 1 << 24:
            self.range = (self.range << 8) & 0xFFFFFFFF
            self.shift_low()

    def integer(self, probs, a, c, v, signed):
        if v == 0:
            self.bit(probs, ("Z", a, c), 0)
            return
        self.bit(probs, ("Z", a, c), 1)
        u = abs(v)
        if signed:
            self.bit(probs, ("S", a, c), 1 if v < 0 else 0)
        k = u.bit_length() - 1
        for i in range(k):
            self.bit(probs, ("E", a, c, i), 1)
        if k < 30:
            self.bit(probs, ("E", a, c, k), 0)
        for j in range(k):
            self.bit(probs, ("X", a, k, j), (u >> (k - 1 - j)) & 1)

    def block(self, v, period=None, signed=True):
        T, M, A = v.shape
        period = period or T
        probs = {}
        for t in range(T):
            for m in range(M):
                for a in range(A):
                    cv = 0
                    if t % period:
                        cv += 2 * abs(int(v[t - 1, m, a]))
                    if m:
                        cv += abs(int(v[t, m - 1, a]))
                    self.integer(probs, a, min(7, cv.bit_length()), int(v[t, m, a]), signed)

    def finish(self):
        for _ in range(5):
            self.shift_low()
        return bytes(self.out)


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
