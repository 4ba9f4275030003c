"""Adaptive binary range coder and the integer binarisations of spec §5.

Strategy: the coder is the LZMA range coder (32-bit range, 11-bit
probabilities, adaptation shift 5), specified bit-exactly in §5.1-§5.3. Every
coded MPZ payload is a sequence of integer *blocks* (§5.5): a ``[T, M, A]``
array (A <= 3) coded frame-major with one model set per axis and a context taken from
the neighbouring already-coded values (§5.6). Bulk loops run under numba;
the public functions validate sizes and translate decoder failures into
:class:`mpz.errors.FormatError` / :class:`mpz.errors.LimitExceededError`.

Decoder contract (§5.3): reading past the end of the payload is an error, and
after the last symbol the decoder must have consumed every byte of it.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from typing import Any, NoReturn, TypeVar, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mpz._jit import njit
from mpz.errors import FormatError, LimitExceededError

# §5.1-§5.2 constants
PROB_BITS = 11          # probabilities are 11-bit, p(0) = p / 2048; p stays in 31..2017 (§5.2)
PROB_INIT = 1 << (PROB_BITS - 1)   # 1024: 50 %
MOVE_BITS = 5           # adaptation rate 2^-5
TOP = 1 << 24           # renormalise when range < 2^24
MAX_EXP = 30            # |v| < 2^30 (§5.4): at most 30 exponent bits
N_CTX = 8               # contexts 0..7 (§5.6)
N_AXES = 3

# Model-set layout (§5.4): per axis a and context c
#   Z[a, c]            zero flag
#   S[a, c]            sign
#   E[a, c, i]         i-th bit of the unary exponent, i in [0, 30)
#   X[a, k, j]         j-th mantissa bit (from the top) of a value with exponent k
_Z, _S, _E, _X = 0, 1, 2, 3

# The one failure the jitted decoder reports (err[0]); BlockDecoder turns it into a FormatError.
ERR_OVERRUN = 1

# Lookup tables the kernels read as constants (issue 15.1: a loop per value before).
#: §5.6: the context of a sum s < _CTX_TABLE is min(7, bit length of s); 7 beyond
_CTX_TABLE = 1 << (N_CTX - 1)
_CTX = np.array([min(N_CTX - 1, i.bit_length()) for i in range(_CTX_TABLE)], np.int64)
#: §5.4: the exponent k = floor(log2 u) of 1 <= u < _EXP_TABLE (the entry for 0 is unused)
_EXP_BITS = 12
_EXP_TABLE = 1 << _EXP_BITS
_EXP = np.array([max(0, i.bit_length() - 1) for i in range(_EXP_TABLE)], np.int64)

#: one model array (int32 probabilities, 1..2047)
_Probs = NDArray[np.int32]

_F = TypeVar("_F", bound=Callable[..., Any])


def _kernel(fn: _F) -> _F:
    """``njit(cache=True)`` (numba's, cached as :mod:`mpz._jit` says), keeping the kernel's
    Python signature for type checkers.

    numba's ``njit`` is not annotated, so a kernel it decorates would be ``Any``
    to mypy and no call to it would be checked. The dispatcher numba returns is
    called exactly like ``fn``.
    """
    return cast(_F, njit(cache=True, nogil=True)(fn))


def new_models() -> tuple[_Probs, _Probs, _Probs, _Probs]:
    """Fresh model arrays ``(Z, S, E, X)``, every probability at 1024 (§5.2)."""
    z = np.full((N_AXES, N_CTX), PROB_INIT, np.int32)
    s = np.full((N_AXES, N_CTX), PROB_INIT, np.int32)
    e = np.full((N_AXES, N_CTX, MAX_EXP), PROB_INIT, np.int32)
    x = np.full((N_AXES, MAX_EXP + 1, MAX_EXP), PROB_INIT, np.int32)
    return z, s, e, x


#: a block's model set ``(Z, S, E, X)`` in the shapes of :func:`new_models`
Models = tuple[_Probs, _Probs, _Probs, _Probs]


def copy_models(models: Models) -> Models:
    """Writable int32 copies of ``models``, checked against the shapes of :func:`new_models`."""
    fresh = new_models()
    out = []
    for given, ref in zip(models, fresh, strict=True):
        arr = np.array(given, dtype=np.int32)
        if arr.shape != ref.shape:
            raise ValueError(f"model array of shape {arr.shape}, expected {ref.shape}")
        out.append(arr)
    return out[0], out[1], out[2], out[3]


# ---------------------------------------------------------------- encoder --
@njit(cache=True, inline="always")
def _encode_bit(probs: _Probs, i: int, bit: int, low: int, rng: int, cache: int, csize: int,
                pos: int, buf: NDArray[np.uint8], ok: bool
                ) -> tuple[int, int, int, int, int, bool]:
    """§5.1 encode_bit of ``bit`` with model ``probs[i]`` (updated), then renormalisation
    and shift_low; the coder state (low, range, cache, cache size, write position, no
    overflow yet) goes in and comes out, so that it stays in registers: inlined into
    :func:`_encode_block` before typing, the one copy of the §5.1 step.

    bit 0: range = bound, p += (2048 - p) >> 5; bit 1: low += bound, range -= bound,
    p -= p >> 5, with bound = (range >> 11) p. Without a branch on the bit (mk: 0 or all
    ones): the bits are what the coder cannot predict, and neither can the CPU."""
    p = probs[i]
    bound = (rng >> PROB_BITS) * p
    mk = -bit
    low += bound & mk
    rng = bound + ((rng - 2 * bound) & mk)
    probs[i] = p + (((2048 - p) >> MOVE_BITS) & ~mk) - ((p >> MOVE_BITS) & mk)
    while rng < TOP:
        rng = (rng << 8) & 0xFFFFFFFF
        if low < 0xFF000000 or low >= 0x100000000:     # shift_low
            carry = low >> 32
            temp = cache
            while True:
                if pos < buf.shape[0]:
                    buf[pos] = (temp + carry) & 0xFF
                    pos += 1
                else:
                    ok = False
                temp = 0xFF
                csize -= 1
                if csize == 0:
                    break
            cache = (low >> 24) & 0xFF
        csize += 1
        low = (low & 0x00FFFFFF) << 8
    return low, rng, cache, csize, pos, ok


@_kernel
def _encode_block(vals: NDArray[np.int64], period: int, signed: bool, probs: _Probs,
                  st: NDArray[np.int64], buf: NDArray[np.uint8], at: NDArray[np.int64],
                  limit: int) -> int:
    """Code a block (§5.4-§5.6): the decisions of §5.4 with the contexts of §5.6, coded by
    the §5.1 encoder.

    ``probs`` is the block's model set as one flat int32 array, Z [3, 8] | S [3, 8] |
    E [3, 8, 30] | X [3, 31, 30] (:func:`_flat_models`), updated in place; the coder
    writes ``buf`` from position ``at[0]``.

    Speed (issue 15): one loop with the coder state (low, range, cache, cache size, write
    position) in locals, instead of a call per bit on arrays; each decision is coded as it
    is made by :func:`_encode_bit`, inlined (a list of decisions coded afterwards was 25 %
    slower); the §5.6 context and the exponent come from tables. The
    bytes are those of the §5 transcription in :mod:`mpz.conformance.rangecoder`
    (tests/test_entropy.py). Cold start (issue 15.2): the flat models come
    ready from the caller (no reshape or copies here), and every caller passes the same
    argument types, so the kernel compiles once.

    Returns 0 when done, 1 if ``buf`` overflowed, 2 if coding stopped because more than
    ``limit`` bytes were written (the payload can then only end longer than ``limit``:
    bytes once written stay, issue 15.1's early exit for candidates that lose)."""
    T, M, A = vals.shape[0], vals.shape[1], vals.shape[2]
    pos = at[0]
    low, rng, cache, csize = st[0], st[1], st[2], st[3]
    o_s = N_AXES * N_CTX
    o_e = 2 * o_s
    o_x = o_e + N_AXES * N_CTX * MAX_EXP
    n_ctx = N_CTX
    n_exp = MAX_EXP
    ok = True
    for t in range(T):
        first = (t % period) == 0
        for m in range(M):
            for a in range(A):
                v = vals[t, m, a]
                cv = 0          # §5.6 context; the decoder kernel has the same lines (a
                #                 shared inlined helper measured 5-15 % slower)
                if not first:
                    cv += 2 * abs(vals[t - 1, m, a])
                if m > 0:
                    cv += abs(vals[t, m - 1, a])
                c = _CTX[cv] if cv < _CTX_TABLE else N_CTX - 1
                ac = a * n_ctx + c
                # §5.4: zero flag, sign, unary exponent, mantissa (top bit first)
                low, rng, cache, csize, pos, ok = _encode_bit(
                    probs, ac, 0 if v == 0 else 1, low, rng, cache, csize, pos, buf, ok)
                if v != 0:
                    u = -v if v < 0 else v
                    if signed:
                        low, rng, cache, csize, pos, ok = _encode_bit(
                            probs, o_s + ac, 1 if v < 0 else 0, low, rng, cache, csize, pos,
                            buf, ok)
                    if u < _EXP_TABLE:                   # k = floor(log2 u)
                        k = _EXP[u]
                    else:
                        k = _EXP_BITS
                        while (u >> (k + 1)) != 0:
                            k += 1
                    eb = o_e + ac * n_exp
                    for i in range(k):
                        low, rng, cache, csize, pos, ok = _encode_bit(
                            probs, eb + i, 1, low, rng, cache, csize, pos, buf, ok)
                    if k < MAX_EXP:
                        low, rng, cache, csize, pos, ok = _encode_bit(
                            probs, eb + k, 0, low, rng, cache, csize, pos, buf, ok)
                    xb = o_x + (a * (MAX_EXP + 1) + k) * n_exp
                    for j in range(k):
                        low, rng, cache, csize, pos, ok = _encode_bit(
                            probs, xb + j, (u >> (k - 1 - j)) & 1, low, rng, cache, csize,
                            pos, buf, ok)
                if pos > limit:
                    at[0] = pos
                    return 2
    st[0], st[1], st[2], st[3] = low, rng, cache, csize
    at[0] = pos
    return 0 if ok else 1


#: the most values :meth:`BlockDecoder.rows` decodes ahead of its caller (512 KiB of int64;
#: a row longer than this is decoded alone)
ROW_WORDS = 1 << 16

#: the flat model set of :func:`_encode_block` with every probability at 1024 (§5.2)
_FLAT_INIT = np.full(2 * N_AXES * N_CTX + N_AXES * N_CTX * MAX_EXP
                     + N_AXES * (MAX_EXP + 1) * MAX_EXP, PROB_INIT, np.int32)


@_kernel
def _encode_rows(rows: NDArray[np.int64], signed: NDArray[np.bool_], init: _Probs,
                 st: NDArray[np.int64], buf: NDArray[np.uint8], at: NDArray[np.int64],
                 limit: int) -> int:
    """:func:`_encode_block` of each row of ``rows[B, T]`` as a block [T, 1, 1] of one run,
    with fresh models (a copy of ``init``) and ``signed[b]``, in row order; the first
    nonzero return code stops it and is returned."""
    T = rows.shape[1]
    for b in range(rows.shape[0]):
        code = _encode_block(rows[b].reshape((T, 1, 1)), max(1, T), signed[b], init.copy(),
                             st, buf, at, limit)
        if code != 0:
            return code
    return 0


def _flat_models(models: Models | None) -> _Probs:
    """A writable flat copy of ``models`` (fresh ones when None) for :func:`_encode_block`
    and :func:`_decode_block`."""
    if models is None:
        return _FLAT_INIT.copy()
    return np.concatenate([a.reshape(-1) for a in copy_models(models)])


def _finish(st: NDArray[np.int64], buf: NDArray[np.uint8], at: NDArray[np.int64]) -> None:
    """Flush (§5.1): five shift_low steps, in Python (5 steps a payload; a kernel would
    only add compile time to the first encode, issue 15.2). ``buf`` has room for them.
    The same steps as :func:`_encode_bit`'s shift_low, written twice on purpose: one
    helper for both, jitted and inlined there, made the encoder 3.4x slower (stop 23)."""
    low, cache, csize = int(st[0]), int(st[2]), int(st[3])
    pos = int(at[0])
    for _ in range(5):
        if low < 0xFF000000 or low >= 0x100000000:
            carry = low >> 32
            temp = cache
            while True:
                buf[pos] = (temp + carry) & 0xFF
                pos += 1
                temp = 0xFF
                csize -= 1
                if csize == 0:
                    break
            cache = (low >> 24) & 0xFF
        csize += 1
        low = (low & 0x00FFFFFF) << 8
    st[0], st[2], st[3] = low, cache, csize
    at[0] = pos


# ---------------------------------------------------------------- decoder --
@njit(cache=True, inline="always")
def _decode_bit(probs: _Probs, i: int, code: int, rng: int, pos: int,
                buf: NDArray[np.uint8]) -> tuple[int, int, int, int, bool]:
    """§5.3 decode_bit with model ``probs[i]``, then renormalisation: ``(bit, code, range,
    pos, ok)``; ``ok`` is False when renormalisation needs the byte past the payload's
    end (the state is then as far as it got)."""
    p = probs[i]
    bound = (rng >> PROB_BITS) * p
    bit = 1 if code >= bound else 0       # as the encoder, without a branch
    mk = -bit
    code -= bound & mk
    rng = bound + ((rng - 2 * bound) & mk)
    probs[i] = p + (((2048 - p) >> MOVE_BITS) & ~mk) - ((p >> MOVE_BITS) & mk)
    while rng < TOP:
        if pos >= buf.shape[0]:
            return bit, code, rng, pos, False
        rng = (rng << 8) & 0xFFFFFFFF
        code = ((code << 8) | buf[pos]) & 0xFFFFFFFF
        pos += 1
    return bit, code, rng, pos, True


@njit(cache=True, inline="always")
def _overrun(ds: NDArray[np.int64], err: NDArray[np.int64], code: int, rng: int,
             pos: int) -> None:
    """Keep the decoder state where an overrun stopped it, and report ERR_OVERRUN."""
    ds[0], ds[1], ds[2] = code, rng, pos
    err[0] = ERR_OVERRUN


@_kernel
def _decode_block(buf: NDArray[np.uint8], ds: NDArray[np.int64], T: int, M: int, period: int,
                  signed: bool, probs: _Probs, out: NDArray[np.int64],
                  err: NDArray[np.int64]) -> None:
    """Decode a block (§5.3 decode_bit, §5.4 decode_int, §5.5 decode_block, §5.6 context).

    ``ds`` is the decoder state (code, range, pos), read at the start and written back at
    the end or on an overrun; ``probs`` the block's flat model set, as for
    :func:`_encode_block` (Z | S | E | X). On an overrun (renormalisation needs byte
    n of an n-byte payload) ``err[0]`` is set to ERR_OVERRUN and decoding stops.

    Speed (issue 15): the coder state stays in locals, and each value takes §5.4's
    decisions in straight code: the zero flag Z[a][c], the sign S[a][c] (signed blocks
    only), the unary exponent E[a][c][k] (k one-bits, then a zero-bit unless k = 30), the
    mantissa X[a][k][j], top bit first, each by :func:`_decode_bit` (inlined). Stop 32:
    10-25 % faster on range-decoding-bound files than one loop dispatching on a phase per
    bit, with the same decisions in the same order."""
    A = out.shape[2]
    code, rng, pos = ds[0], ds[1], ds[2]
    o_s = N_AXES * N_CTX
    o_e = 2 * o_s
    o_x = o_e + N_AXES * N_CTX * MAX_EXP
    for t in range(T):
        first = (t % period) == 0
        for m in range(M):
            for a in range(A):
                ctx_v = 0       # §5.6 context of v[t, m, a], as in _encode_block
                if not first:
                    ctx_v += 2 * abs(out[t - 1, m, a])
                if m > 0:
                    ctx_v += abs(out[t, m - 1, a])
                c = _CTX[ctx_v] if ctx_v < _CTX_TABLE else N_CTX - 1
                ac = a * N_CTX + c
                bit, code, rng, pos, ok = _decode_bit(probs, ac, code, rng, pos, buf)
                if not ok:
                    _overrun(ds, err, code, rng, pos)
                    return
                if bit == 0:                      # zero flag: 0 means v = 0
                    out[t, m, a] = 0
                    continue
                neg = False
                if signed:                        # sign
                    bit, code, rng, pos, ok = _decode_bit(probs, o_s + ac, code, rng, pos,
                                                          buf)
                    if not ok:
                        _overrun(ds, err, code, rng, pos)
                        return
                    neg = bit == 1
                k = 0                             # exponent: k one-bits, then 0
                ie = o_e + ac * MAX_EXP
                while k < MAX_EXP:                # no zero-bit after k = 30
                    bit, code, rng, pos, ok = _decode_bit(probs, ie + k, code, rng, pos, buf)
                    if not ok:
                        _overrun(ds, err, code, rng, pos)
                        return
                    if bit == 0:
                        break
                    k += 1
                u = 1                             # mantissa: k bits under the leading 1
                ix = o_x + (a * (MAX_EXP + 1) + k) * MAX_EXP
                for j in range(k):
                    bit, code, rng, pos, ok = _decode_bit(probs, ix + j, code, rng, pos, buf)
                    if not ok:
                        _overrun(ds, err, code, rng, pos)
                        return
                    u = (u << 1) | bit
                out[t, m, a] = -u if neg else u
    ds[0], ds[1], ds[2] = code, rng, pos


@_kernel
def _decode_rows(buf: NDArray[np.uint8], ds: NDArray[np.int64], signed: NDArray[np.bool_],
                 init: _Probs, out: NDArray[np.int64], err: NDArray[np.int64]) -> int:
    """:func:`_decode_block` of each row of ``out[B, T]`` as a block [T, 1, 1] of one run,
    with fresh models (a copy of ``init``) and ``signed[b]``, in row order, as
    :func:`_encode_rows` codes them. Returns the number of rows decoded whole: B, or the
    row that overran (``err[0]`` is then ERR_OVERRUN)."""
    T = out.shape[1]
    for b in range(out.shape[0]):
        _decode_block(buf, ds, T, 1, max(1, T), signed[b], init.copy(),
                      out[b].reshape((T, 1, 1)), err)
        if err[0] != 0:
            return b
    return int(out.shape[0])


# ------------------------------------------------------------- public API --
class BlockEncoder:
    """Encode a sequence of integer blocks into one range-coded payload.

    Each block gets fresh models (§5.5), so blocks are independent in their
    statistics but share one arithmetic-coded byte string.

    Examples
    --------
    >>> import numpy as np
    >>> enc = BlockEncoder()
    >>> enc.block(np.array([[[1, -2, 0]]]))
    >>> data = enc.finish()
    >>> dec = BlockDecoder(data)
    >>> dec.block(1, 1).tolist()
    [[[1, -2, 0]]]
    >>> dec.close()
    """

    def __init__(self, capacity: int = 1 << 16, *, limit: int | None = None) -> None:
        self._buf = np.zeros(capacity, np.uint8)
        self._pos = np.zeros(1, np.int64)
        self._st = np.array([0, 0xFFFFFFFF, 0, 1], np.int64)
        #: with ``limit``, coding stops once the payload is sure to be longer than ``limit``
        #: bytes; ``over`` is then True, later blocks are skipped and :meth:`finish` raises
        #: (the encoder drops candidate payloads that cannot be the smallest, issue 15.1)
        self._limit = (1 << 62) if limit is None else int(limit)
        self.over = False

    def _grow(self) -> None:
        new = np.zeros(self._buf.shape[0] * 2, np.uint8)
        new[: self._buf.shape[0]] = self._buf
        self._buf = new

    def _ready(self, v: NDArray[np.int64], negative: bool, blocks: int) -> bool:
        """The checks before coding ``v`` (§5.4: every |value| < 2^30; ``negative``: some
        value of an unsigned block is < 0), and room in the buffer for ``blocks`` blocks of
        its values (worst case ~ 8 bytes a value). False when coding has stopped (``over``).
        """
        # max |v| without a temporary of the block's size (issue 11.11: encoder memory)
        peak = max(int(v.max()), -int(v.min())) if v.size else 0
        if peak >= (1 << MAX_EXP):
            raise LimitExceededError(
                f"value {peak} does not fit the 2^30 coder range", section="§5.4")
        if negative:
            raise ValueError("negative value in an unsigned block")
        need = int(self._pos[0]) + 8 * v.size + 64 * blocks
        while self._buf.shape[0] < need:
            self._grow()
        return not self.over

    def _coded(self, code: int) -> None:
        """The return code of a coding kernel: 2 sets ``over`` (the limit was passed)."""
        if code == 1:
            raise RuntimeError("range coder buffer overflow")  # unreachable: sized above
        self.over = code == 2

    def block(self, values: ArrayLike, *, period: int | None = None,
              signed: bool = True, models: Models | None = None) -> None:
        """Code ``values`` (int, shape ``[T, M, A]``, A in 1..3).

        Contexts restart every ``period`` rows (default: one run of all T rows).
        ``models`` are the initial probabilities ``(Z, S, E, X)`` (trained
        dictionaries, bench/bench_dictionary.py); by default every model starts at 1024
        (§5.2). They are copied.
        """
        v = np.ascontiguousarray(values, dtype=np.int64)
        if v.ndim != 3 or not 1 <= v.shape[2] <= 3:
            raise ValueError(f"blocks are [T, M, A] with A in 1..3, got {v.shape}")
        if not self._ready(v, not signed and v.size > 0 and v.min() < 0, 1):
            return
        period = max(1, v.shape[0] if period is None else int(period))
        self._coded(_encode_block(v, period, signed, _flat_models(models), self._st,
                                  self._buf, self._pos, self._limit))

    def rows(self, rows: ArrayLike, signed: ArrayLike) -> None:
        """Code each row of ``rows`` (int, shape ``[B, T]``) as its own block ``[T, 1, 1]``
        with fresh models, signed where ``signed[b]``: the bytes of B calls of
        :meth:`block`, made in one kernel call (issue 15.1: a C3D clip's channels are
        hundreds of short blocks, and each call of :meth:`block` costs about 5 us).

        The checks of :meth:`block` are made for all rows before any is coded.
        """
        v = np.ascontiguousarray(rows, dtype=np.int64)
        sg = np.ascontiguousarray(signed, dtype=np.bool_)
        if v.ndim != 2 or sg.shape != (v.shape[0],):
            raise ValueError(f"rows are [B, T] with one sign flag a row, got {v.shape} and "
                             f"{sg.shape}")
        if not self._ready(v, v.size > 0 and bool((v[~sg] < 0).any()), v.shape[0] + 1):
            return
        self._coded(_encode_rows(v, sg, _FLAT_INIT, self._st, self._buf, self._pos,
                                 self._limit))

    def finish(self) -> bytes:
        """Flush the coder (§5.1) and return the payload."""
        if self.over:
            raise ValueError(f"the payload is longer than its limit of {self._limit} bytes")
        while self._buf.shape[0] < int(self._pos[0]) + 16:
            self._grow()
        _finish(self._st, self._buf, self._pos)
        return self._buf[: int(self._pos[0])].tobytes()


class BlockDecoder:
    """Decode the blocks of one payload, in the order they were coded.

    Parameters
    ----------
    data : bytes
        The range-coded field (§5.3 ``b[0 .. n-1]``).
    chunk : str, optional
        The chunk type the field belongs to, for error reports.
    offset : int, optional
        The file offset of ``data[0]``, the coded field's first byte (not the chunk's
        start): errors then carry the offset of the byte where decoding failed.

    Raises
    ------
    FormatError
        If the payload does not start with the byte 0, runs out before the
        last symbol, or has bytes left after it (§5.3). Its ``offset`` is that of the
        failing byte: the first byte (a non-zero first byte), the first byte past the
        field (too short for the preamble, or a renormalisation that needs a byte past
        the end), or the first byte left over after the last symbol.
    """

    def __init__(self, data: bytes, *, chunk: str | None = None,
                 offset: int | None = None) -> None:
        self._buf = np.frombuffer(bytes(data), np.uint8)
        self.chunk, self.offset = chunk, offset
        n = self._buf.shape[0]
        # R-2.4-43
        if n < 5:
            self._fail(f"range-coded payload of {n} bytes is shorter than its 5-byte preamble",
                       n)
        # R-2.4-44
        if self._buf[0] != 0:
            self._fail(f"range-coded payload must start with byte 0, got {int(self._buf[0])}", 0)
        code = 0
        for i in range(1, 5):
            code = (code << 8) | int(self._buf[i])
        self._ds = np.array([code, 0xFFFFFFFF, 5], np.int64)
        self._err = np.zeros(1, np.int64)

    def _fail(self, msg: str, pos: int) -> NoReturn:
        """Raise for the byte at ``pos`` of the field (``pos`` = n: the byte past its end)."""
        raise FormatError(msg, chunk=self.chunk,
                          offset=None if self.offset is None else self.offset + pos,
                          section="§5.3")

    def block(self, T: int, M: int, A: int = 3, *, period: int | None = None,
              signed: bool = True, models: Models | None = None) -> NDArray[np.int64]:
        """Decode a ``[T, M, A]`` block of int64 values (T = 0: empty, no decisions, §5.5).

        ``models``: initial probabilities, as for :meth:`BlockEncoder.block`.
        """
        out = np.zeros((T, M, A), np.int64)
        period = max(1, T if period is None else int(period))
        _decode_block(self._buf, self._ds, T, M, period, signed, _flat_models(models), out,
                      self._err)
        if self._err[0] == ERR_OVERRUN:
            self._ran_out()
        return out

    def rows(self, T: int, signed: Sequence[bool]) -> Rows:
        """The values of ``len(signed)`` blocks ``[T, 1, 1]`` with fresh models, signed
        where ``signed[b]``, as ``[T]`` rows in coding order (:class:`Rows`): what that
        many calls of :meth:`block` give, and what :meth:`BlockEncoder.rows` codes."""
        return Rows(self, T, signed)

    def _ran_out(self) -> NoReturn:
        n = self._buf.shape[0]
        # R-5.3-1
        self._fail(f"range-coded payload ends before its last symbol (renormalisation "
                   f"needs byte {n} of a {n}-byte field)", n)

    @property
    def consumed(self) -> int:
        return int(self._ds[2])

    def close(self) -> None:
        """Check that every byte of the payload was consumed (§5.3)."""
        left = self._buf.shape[0] - self.consumed
        # R-5.3-2
        if left:
            self._fail(f"{left} byte(s) left after the last range-coded symbol", self.consumed)


class Rows:
    """The rows of :meth:`BlockDecoder.rows`, taken in coding order.

    The blocks are decoded ahead of what the caller has taken, :data:`ROW_WORDS` values at
    most (spec §8: that much memory), by one kernel call each time (issue 15.1: a C3D
    clip's channels are hundreds of short blocks, and a call of :meth:`block` costs a few
    us). A block the payload runs out in raises where the block() of it would: when the
    caller asks for it, after whatever the caller did with the rows before it.
    """

    def __init__(self, dec: BlockDecoder, T: int, signed: Sequence[bool]) -> None:
        self._dec, self._T = dec, int(T)
        self._signed = np.asarray(signed, np.bool_)
        self._next = 0                              # the first row not yet decoded
        self._ahead = np.zeros((0, self._T), np.int64)  # the rows decoded ahead
        self._whole = 0                             # how many of them decoded whole
        self._at = 0                                # how many of them were taken

    def __len__(self) -> int:
        """The rows not taken yet."""
        return int(self._signed.shape[0] - self._next + self._ahead.shape[0] - self._at)

    def take(self, n: int) -> NDArray[np.int64]:
        """The next rows, at least one and at most ``n``, as ``[m, T]`` (a view of the rows
        decoded ahead: fewer than ``n`` where those end). Raises FormatError (§5.3) when
        the next row is one the payload runs out in."""
        if self._at == self._ahead.shape[0]:
            if self._next == self._signed.shape[0]:
                raise IndexError("every row was taken")
            per = max(1, ROW_WORDS // max(1, self._T))
            flags = self._signed[self._next: self._next + per]
            self._ahead = np.zeros((flags.shape[0], self._T), np.int64)
            self._whole = _decode_rows(self._dec._buf, self._dec._ds, flags, _FLAT_INIT,
                                       self._ahead, self._dec._err)
            self._next += flags.shape[0]
            self._at = 0
        if self._at == self._whole:
            self._dec._ran_out()
        m = min(max(1, n), self._whole - self._at)
        self._at += m
        return self._ahead[self._at - m: self._at]

    def __iter__(self) -> Iterator[NDArray[np.int64]]:
        while len(self):
            yield self.take(1)[0]
