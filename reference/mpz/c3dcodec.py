"""Exact coding of sampled channels for the C3D archive (spec §4.13, §6.9).

Strategy: a C3D stores each point's fourth word and every analog sample as an int16 or
a float32 *word*. Each channel (one point's words, one analog channel) is turned into
integers without loss, predicted in time (§6.2) and range-coded (§5) with the project's
own coder, never stored as raw bytes:

- mode 0, integer: the word is ``k x 2^shift`` with ``|k| < 2^24`` (every int16 word;
  float32 words that are integers, half-integers, multiples of 2^-15 ... as ADC counts
  and their fixed-point scalings are);
- mode 1, float32 bit pattern: the 32 bits as an *ordered* integer ``v`` (``v = bits``
  for a clear sign bit, ``-(bits & 0x7FFFFFFF) - 1`` otherwise), so that larger floats
  have larger ``v`` and -0.0, NaN payloads and infinities come back bit for bit.

The prediction residual ``e`` is coded as ``h = e div 2^b`` (a signed block) and, when
``b > 0``, ``l = e mod 2^b`` (an unsigned block), so that ``|h| < 2^30`` (§5.4) for every
32-bit pattern. :func:`plan` picks mode, shift, order and ``b`` per channel by the size
proxy ``sum(log2(1 + |e|))``; :func:`decode_channel` is §6.9 step by step and raises
:class:`mpz.errors.FormatError` for the rules of §4.13 it finds broken.

Model outputs (§4.13.3) are floats coded on a per-axis grid ``x = offset + k x step``,
like marker positions (§6.8), with their own bound: :func:`model_grid`.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mpz._jit import njit
from mpz.entropy import MAX_EXP, BlockDecoder, BlockEncoder
from mpz.errors import FormatError
from mpz.format import C3D_MAX_LOW_BITS, C3D_MAX_SHIFT, C3D_MIN_SHIFT, MAX_ORDER, ChannelMode
from mpz.predict import reconstruct, residuals

IntArray = NDArray[np.int64]
#: 2^24: the magnitude limit of k in mode 0 (a binary32 holds 24 significant bits)
K_LIMIT = 1 << 24
#: 2^31: the magnitude limit of a model-output grid value (§4.13.3)
MODEL_LIMIT = 1 << 31
#: the storage types of C3D words (§4.13.3, §4.13.4 ``storage``)
INT16, FLOAT32 = np.dtype("<i2"), np.dtype("<f4")


@dataclass(frozen=True)
class Plan:
    """How one channel is coded (the four bytes of a §4.13 channel entry) and its integers."""

    mode: int
    shift: int
    order: int
    low_bits: int
    values: IntArray            # k (mode 0) or the ordered bit pattern v (mode 1)


# ---------------------------------------------------------------- words <-> v --
def ordered(bits: NDArray[np.uint32]) -> IntArray:
    """§6.9 float32 bit patterns -> ordered integers in -2^31 .. 2^31 - 1."""
    b = bits.astype(np.int64)
    return np.where(b < (1 << 31), b, -(b & 0x7FFFFFFF) - 1)


def unordered(v: IntArray) -> NDArray[np.uint32]:
    """The inverse of :func:`ordered` (``v`` must lie in -2^31 .. 2^31 - 1)."""
    return np.where(v >= 0, v, (-v - 1) | (1 << 31)).astype(np.uint32)


def _dyadic_rows(x: NDArray[np.float32]) -> list[tuple[int, IntArray] | None]:
    """For each row (channel) of ``x[C, T]``, C-contiguous: (shift, k) with ``x == k x
    2^shift`` exactly and |k| < 2^24 (mode 0), or None (mode 1), always None for a channel
    holding -0.0, NaN or an infinity (mode 1 keeps their bits).

    Each channel is decided on its own values only, and its k is a contiguous row; one
    kernel pass over the bit patterns (:func:`_dyadic_kernel`) instead of a dozen numpy
    calls per channel (issue 15.1: 1.7 ms of a short clip's C3D words, 10 ms of a long
    analog block)."""
    C, T = x.shape
    usable = np.zeros(C, np.bool_)
    shift = np.zeros(C, np.int64)
    k = np.zeros((C, T), np.int64)
    _dyadic_kernel(np.ascontiguousarray(x).view(np.uint32), C3D_MIN_SHIFT, C3D_MAX_SHIFT,
                   usable, shift, k)
    return [(int(shift[c]), k[c]) if usable[c] else None for c in range(C)]


#: above the exponent of every binary32 word (at most 127): a row of zeros has none
_NO_EXPONENT = 1 << 20


@njit(cache=True, inline="always")
def _significand(b: int) -> int:
    """The integer significand of binary32 word ``b``: 2^23 + m when normal, m when not."""
    return (b & 0x7FFFFF) | (0x800000 if (b >> 23) & 0xFF else 0)


@njit(cache=True, inline="always")
def _exponent(b: int) -> int:
    """The power of two of :func:`_significand`'s unit: the word is sig x 2^exponent."""
    e = (b >> 23) & 0xFF
    return e - 150 if e else -149


@njit(cache=True, nogil=True)
def _dyadic_kernel(bits: NDArray[np.uint32], lo: int, hi: int, usable: NDArray[np.bool_],
                   shift: NDArray[np.int64], k: NDArray[np.int64]) -> None:
    """For each row of binary32 patterns ``bits[C, T]``: whether every word is k x 2^shift
    exactly with |k| < 2^24 (``usable``; never for -0.0, NaN or an infinity), the shift (the
    least exponent of the lowest set bit over the nonzero words, clamped to ``lo .. hi``;
    0 for a row of zeros) and the k. Integer arithmetic on the fields of each word: a
    normal word is (2^23 + m) x 2^(e - 150), a subnormal one m x 2^-149
    (:func:`_significand`, :func:`_exponent`)."""
    C, T = bits.shape
    for c in range(C):
        ok = True
        least = _NO_EXPONENT
        for t in range(T):
            b = int(bits[c, t])
            e = (b >> 23) & 0xFF
            if e == 0xFF or b == 0x80000000:       # NaN, an infinity, or -0.0
                ok = False
                break
            if b & 0x7FFFFFFF == 0:
                continue                           # +0.0: any shift
            sig = _significand(b)
            ex = _exponent(b)
            while sig & 1 == 0:                    # its lowest set bit
                sig >>= 1
                ex += 1
            if ex < least:
                least = ex
        if not ok:
            continue
        s = 0 if least == _NO_EXPONENT else min(max(least, lo), hi)
        for t in range(T):
            b = int(bits[c, t])
            if b & 0x7FFFFFFF == 0:
                k[c, t] = 0
                continue
            sig = _significand(b)
            d = _exponent(b) - s                   # the word is sig x 2^(d + s)
            if d >= 0:
                if d > 24 or sig << d >= 1 << 24:
                    ok = False
                    break
                v = sig << d
            else:
                if d < -24 or sig & ((1 << -d) - 1):
                    ok = False                     # bits below 2^s: not an integer k
                    break
                v = sig >> -d
            k[c, t] = -v if b >> 31 else v
        usable[c] = ok
        shift[c] = s


#: values per batch of channels in :func:`best_orders` and :func:`encode_channels` (as
#: ``predict._BLOCK_VALUES``): their temporaries stay a few MiB however long the capture
#: (issue 11.11), and a short clip is one batch (issue 15.1)
BATCH_VALUES = 1 << 20


def batches(T: int, C: int) -> list[tuple[int, int]]:
    """Ranges ``c0 .. c1 - 1`` of C channels of T values each, at most about
    :data:`BATCH_VALUES` values a range (at least one channel)."""
    n = max(1, BATCH_VALUES // max(1, T))
    return [(c, min(C, c + n)) for c in range(0, C, n)]


def _integers(words: NDArray[Any]) -> list[tuple[int, int, IntArray]]:
    """(mode, shift, values) of each channel (column) of ``words[T, C]``: int16 words as
    they are, float32 words as k x 2^shift when exact (mode 0), else their ordered bit
    patterns (mode 1)."""
    T, C = words.shape
    if words.dtype.kind == "i":
        v = words.astype(np.int64)
        return [(int(ChannelMode.INTEGER), 0, v[:, c]) for c in range(C)]
    x = np.ascontiguousarray(words.T, dtype=FLOAT32)      # [C, T]: a channel a row
    out = []
    for c, d in enumerate(_dyadic_rows(x)):
        if d is not None:
            out.append((int(ChannelMode.INTEGER), d[0], d[1]))
        else:
            out.append((int(ChannelMode.BITS), 0, ordered(x[c].view(np.uint32))))
    return out


def plan(words: NDArray[np.int16] | NDArray[np.float32]) -> Plan:
    """The cheapest exact coding of one channel of C3D words (1-D, int16 or float32)."""
    return plan_all(words[:, None])[0]


def best_orders(v: IntArray, max_low: int = C3D_MAX_LOW_BITS
                ) -> tuple[NDArray[np.intp], NDArray[np.int64]]:
    """The predictor order of each column of ``v[T, C]`` (§6.2), the one whose residuals
    e cost least by the size proxy ``sum(log2(1 + |e|))`` (the lowest order on a tie)
    among the orders the coder can take, and its b (:func:`low_bits`; -1 where no order
    fits with b <= ``max_low``).

    Each column's cost is summed over its own samples as a contiguous row (numpy's order
    for a 1-D sum), so a column's order does not depend on the other columns; the columns
    are taken in :func:`batches`, one order at a time."""
    T, C = v.shape
    orders = np.zeros(C, np.intp)
    lows = np.zeros(C, np.int64)
    for c0, c1 in batches(T, C):
        costs = np.empty((MAX_ORDER + 1, c1 - c0))
        low = np.empty((MAX_ORDER + 1, c1 - c0), np.int64)
        for order in range(MAX_ORDER + 1):
            e = residuals(v[:, c0:c1], order)
            low[order] = low_bits(e.max(axis=0, initial=0), e.min(axis=0, initial=0),
                                  max_low)
            costs[order] = np.ascontiguousarray(
                np.log2(1.0 + np.abs(e).astype(np.float64)).T).sum(axis=1)
            del e
        costs[low < 0] = np.inf                 # h would not fit the coder (§5.4)
        best = np.argmin(costs, axis=0)
        orders[c0:c1] = best
        lows[c0:c1] = low[best, np.arange(c1 - c0)]
    return orders, lows


def low_bits(hi: NDArray[np.int64], lo: NDArray[np.int64], max_low: int) -> NDArray[np.int64]:
    """For residuals from ``lo`` <= 0 to ``hi`` >= 0 (per column), the smallest b <=
    ``max_low`` that puts every h = e div 2^b (floor division, §6.9) within the coder's
    -2^30 < h < 2^30 (§5.4), or -1 where none does. Both ends bound b: for e < 0, floor
    division reaches -2^30 from |e| = (2^30 - 1) x 2^b + 1 on, so b is not bitlen(|e|) -
    30 (the word 0xFFFFFFFE, e = -(2^31 - 1) at order 0, needs b = 2, not 1)."""
    out = np.full(hi.shape, -1, np.int64)
    for b in range(max_low, -1, -1):             # the fit is monotonic in b
        fits = ((hi >> b) < (1 << MAX_EXP)) & ((lo >> b) > -(1 << MAX_EXP))
        out[fits] = b
    return out


def plan_all(words: NDArray[Any]) -> list[Plan]:
    """:func:`plan` of every column of ``words[T, C]``, the orders chosen for all
    channels at once (:func:`best_orders`)."""
    T, C = words.shape
    coded = _integers(words)
    v = np.empty((T, C), np.int64)
    for c, (_, _, vc) in enumerate(coded):
        v[:, c] = vc
    best, lows = best_orders(v)
    del v
    assert (lows >= 0).all()        # order 0 of 32-bit words fits with b <= 2
    return [Plan(mode, shift, int(best[c]), int(lows[c]), vc)
            for c, (mode, shift, vc) in enumerate(coded)]


def residual_rows(v: IntArray, orders: NDArray[np.integer[Any]]) -> IntArray:
    """The §6.2 residuals ``[C, T]`` of each column c of ``v[T, C]`` with predictor order
    ``orders[c]``: a channel a row, as :meth:`~mpz.entropy.BlockEncoder.rows` codes them."""
    out = np.empty((v.shape[1], v.shape[0]), np.int64)
    for order in np.unique(orders):
        pick = orders == order
        out[pick] = residuals(v[:, pick], int(order)).T
    return out


def encode_channels(enc: BlockEncoder, plans: list[Plan]) -> None:
    """Code planned channels of T values each, in order: for each, the block of h, then
    (b > 0) the block of l (§6.9). One :meth:`~mpz.entropy.BlockEncoder.rows` call per
    batch of channels (:func:`batches`; issue 15.1: one block() call each was most of a
    short clip's cost here)."""
    T = len(plans[0].values) if plans else 0
    for c0, c1 in batches(T, len(plans)):
        part = plans[c0:c1]
        e = residual_rows(np.stack([p.values for p in part], axis=1),
                          np.array([p.order for p in part]))          # [C, T]
        low = np.array([p.low_bits for p in part], np.int64)
        split = low > 0
        at = np.arange(len(part)) + np.concatenate(([0], np.cumsum(split)[:-1]))  # h rows
        rows = np.empty((len(part) + int(split.sum()), T), np.int64)
        signed = np.ones(rows.shape[0], np.bool_)
        rows[at] = e >> low[:, None]                                 # floor division by 2^b
        rows[at[split] + 1] = e[split] & ((1 << low[split]) - 1)[:, None]
        signed[at[split] + 1] = False
        del e
        enc.rows(rows, signed)


def encode_channel(enc: BlockEncoder, p: Plan) -> None:
    """Code one planned channel (:func:`encode_channels`)."""
    encode_channels(enc, [p])


def _fail(message: str, section: str) -> FormatError:
    return FormatError(message, section=section)


#: rows of a channel checked and converted at a time by :func:`decode_channels`, so that
#: its temporaries are this size, not the channel's (spec §8, memory budget)
_ROWS = 1 << 16


def decode_channel(dec: BlockDecoder, T: int, mode: int, shift: int, order: int,
                   low_bits: int, storage: np.dtype[np.generic], section: str,
                   out: NDArray[np.int16] | NDArray[np.float32] | None = None
                   ) -> NDArray[np.int16] | NDArray[np.float32]:
    """§6.9 one channel of T words (:func:`decode_channels` of one entry), returned as
    int16 or float32 (bit-exact) values, in ``out`` (a [T] array or column of
    ``storage``) when it is given."""
    if out is None:
        out = np.empty(T, storage)
    decode_channels(dec, T, [(mode, shift, order, low_bits)], storage, section, out[:, None])
    return out


def decode_channels(dec: BlockDecoder, T: int, entries: Sequence[tuple[int, int, int, int]],
                    storage: np.dtype[np.generic], section: str,
                    out: NDArray[np.int16] | NDArray[np.float32]) -> None:
    """§6.9 consecutive channels of T words, each into its column of ``out`` ([T, C] of
    ``storage``) as int16 or float32 (bit-exact) values; ``entries`` are the channels'
    ``(mode, shift, order, low_bits)``, which must already have passed the §4.13 checks
    (mode, shift, order, low_bits and, for int16 storage, mode 0 with shift 0).

    Speed (issue 15.1): the range decoding of many short channels is one kernel call
    (:meth:`BlockDecoder.rows`), and a run of channels with the same entry and no low
    parts is reconstructed, checked and converted as one array (a C3D clip's channels are
    mostly such runs: ~6 us a channel of numpy calls before). Every fault is still
    reported as a channel-by-channel decoder meets it first: the checks are made in
    channel order, and a run whose §6.2 guard fails is decoded again one channel at a time.

    Memory (spec §8): the residuals' int64 rows decoded ahead (at most
    :data:`mpz.entropy.ROW_WORDS`, or one channel's and its low parts'), a copy of a run's
    (at most :data:`_ROWS` values) and the output; a long channel is reconstructed in
    place, checked by its largest and least value, and converted :data:`_ROWS` rows at a
    time. Whole-channel temporaries took 32 bytes a word, 8 GiB for the 2^28 words of a
    740 KB file (a QA run, stop 40).

    Raises
    ------
    FormatError
        For a decoded value outside the range §4.13 allows.
    """
    rows = dec.rows(T, [s for e in entries for s in ((True, False) if e[3] else (True,))])
    per = max(1, _ROWS // max(1, T))            # channels in a run at most
    c = 0
    while c < len(entries):
        entry = entries[c]
        e = rows.take(1 if entry[3] else _run_length(entries, c, per))    # [m, T], m channels
        m = e.shape[0]
        if entry[3]:                            # low_bits: its low parts' row follows
            low_bits = entry[3]
            lo = rows.take(1)
            if T and int(lo.max()) >= (1 << low_bits):  # R-6.9-1
                raise _fail(f"low part {int(lo.max())} of a residual is not below "
                            f"2^{low_bits}", section)
            np.left_shift(e, low_bits, out=e)               # h x 2^b + lo, |h| < 2^31
            np.add(e, lo, out=e)
            del lo
        _run(e, entry, storage, section, out[:, c: c + m])
        c += m


def _run(e: IntArray, entry: tuple[int, int, int, int], storage: np.dtype[np.generic],
         section: str, out: NDArray[np.int16] | NDArray[np.float32]) -> None:
    """§6.9 steps after the range decoding, for channels with the same entry: their
    residuals ``e[m, T]`` reconstructed (§6.2), checked in channel order and converted
    into the columns of ``out[T, m]``."""
    mode, shift, order, _ = entry
    m, T = e.shape
    # |e| <= (2^31 - 1) x 2^3 + 7 < 2^34 (b <= 3): an order-1 sum over T <= 2^28 rows
    # stays below 2^62, and order 2 is guarded by §6.2 (|d| < 2^32)
    v = _reconstructed(e, order)
    if v is None:
        for i in range(m):
            _run(e[i: i + 1], entry, storage, section, out[:, i: i + 1])
        return
    tops = v.max(axis=0) if T else np.zeros(m, np.int64)   # (no temporaries of v's size)
    bottoms = v.min(axis=0) if T else np.zeros(m, np.int64)
    for c in range(m):                                      # the first failing channel
        top, bottom = int(tops[c]), int(bottoms[c])
        if mode == ChannelMode.INTEGER:
            if max(top, -bottom) >= K_LIMIT:  # R-6.9-1
                raise _fail(f"integer channel value {max(top, -bottom)} is not below 2^24",
                            section)
            if storage == INT16 and (bottom < -32768 or top > 32767):  # R-6.9-1
                raise _fail("an int16 channel decodes to a value outside -32768..32767",
                            section)
        # R-6.9-1
        elif bottom < -(1 << 31) or top >= (1 << 31):
            raise _fail("a float32 bit-pattern channel decodes outside -2^31..2^31-1", section)
    step = max(1, _ROWS // m)
    for r0 in range(0, T, step):
        part = v[r0: r0 + step]
        if mode != ChannelMode.INTEGER:
            out[r0: r0 + step] = unordered(part).view(FLOAT32)
        elif storage == INT16:
            out[r0: r0 + step] = part
        else:                               # k x 2^shift, rounded once to float32
            out[r0: r0 + step] = np.ldexp(part.astype(np.float64), shift)


def _run_length(keys: Sequence[object], i: int, most: int) -> int:
    """How many of ``keys`` from ``i`` on equal ``keys[i]``, at most ``most``: a run that
    :func:`decode_channels` and :func:`decode_model_axes` take as one array."""
    n = 1
    while n < most and i + n < len(keys) and keys[i + n] == keys[i]:
        n += 1
    return n


def _reconstructed(e: IntArray, order: int) -> IntArray | None:
    """A run's residuals ``e[m, T]`` reconstructed (§6.2) as ``[T, m]``: a view of a single
    row, reconstructed in place, else a copy. None when §6.2's guard fails in a run of
    several: it stops at the run's earliest frame, maybe in a later row than one that
    fails its own check, so the caller takes the run one row at a time; a single row
    raises the guard's error."""
    v = np.ascontiguousarray(e.T)
    try:
        reconstruct(v, order, inplace=True)
    except FormatError:
        if e.shape[0] == 1:
            raise
        return None
    return v


def decode_model_axes(dec: BlockDecoder, T: int, axes: Sequence[tuple[int, float, float]],
                      section: str, out: NDArray[np.float64]) -> None:
    """§6.9 the model outputs' axes, in coding order (output 0's x, y, z, then output 1's,
    ...): each a block [T, 1, 1] of residuals, reconstructed with its order, checked
    |k| < 2^31 and written as k x step + offset (the product rounded first, then the sum,
    as §6.8) into its column of ``out[T, 3J]``; ``axes`` are the ``(order, step, offset)``
    of each, already checked (§4.13.3).

    Speed (issue 15.1), as :func:`decode_channels`: one kernel call range-decodes many
    axes, and a run of axes with the same order is reconstructed, checked and converted as
    one array (auckland's 108 axes were ~15 us of numpy calls each). A fault is reported
    as an axis-by-axis decoder meets it first.
    """
    rows = dec.rows(T, [True] * len(axes))
    per = max(1, _ROWS // max(1, T))            # axes in a run at most
    orders = [ax[0] for ax in axes]
    i = 0
    while i < len(axes):
        e = rows.take(_run_length(orders, i, per))      # [m, T], m axes of one order
        _model_run(e, axes, i, section, out)
        i += e.shape[0]


def _model_run(e: IntArray, axes: Sequence[tuple[int, float, float]], first: int,
               section: str, out: NDArray[np.float64]) -> None:
    """:func:`decode_model_axes` of the axes ``first .. first + m - 1`` (one order), from
    their residuals ``e[m, T]``."""
    m, T = e.shape
    k = _reconstructed(e, axes[first][0])
    if k is None:
        for i in range(m):
            _model_run(e[i: i + 1], axes, first + i, section, out)
        return
    peaks = np.abs(k).max(axis=0) if T else np.zeros(m, np.int64)
    for c in range(m):
        # R-6.9-1
        if peaks[c] >= MODEL_LIMIT:
            j, a = divmod(first + c, 3)
            raise FormatError(f"model output {j} axis {'xyz'[a]}: value {int(peaks[c])} is "
                              f"not below 2^31", section=section)
    steps = np.array([ax[1] for ax in axes[first: first + m]], np.float64)
    offsets = np.array([ax[2] for ax in axes[first: first + m]], np.float64)
    # §6.9 as §6.8: the product rounded first, then the offset added
    x = k.astype(np.float64) * steps
    out[:, first: first + m] = x + offsets


# ------------------------------------------------------------ model outputs --
SQRT_SAFETY = 1.0 - 2.0 ** -20    # as the marker grid (Appendix C): float rounding never


def on_model_grid(x: NDArray[np.float64], valid: NDArray[np.bool_],
                  grid: float) -> NDArray[np.bool_]:
    """For each column of ``x[T, C]``: True when every valid value v is an exact multiple
    of ``grid`` (``rint(v / grid) x grid == v``) with ``|v / grid| < 2^30``, and at least
    one value is valid; :func:`model_grid` then codes the column exactly on ``grid``."""
    q = x / grid
    exact = (np.rint(q) * grid == x) & (np.abs(q) < MODEL_LIMIT // 2)
    return (exact | ~valid).all(axis=0) & valid.any(axis=0)


def model_grid(lo: float, hi: float, count: int, bound: float,
               grid: float | None = None) -> tuple[float, float, float]:
    """(offset, step, declared bound) of one model-output axis (§4.13.3).

    The axis has ``count`` valid values, from ``lo`` to ``hi``; ``bound`` is the allowed
    absolute error; ``grid``, when not None, a step every valid value is an exact
    multiple of (an int16 C3D's |POINT:SCALE|, :func:`on_model_grid`): the axis is then
    coded exactly on it (offset 0, declared bound 0).
    """
    if grid is not None and count:
        return 0.0, float(grid), 0.0
    if count == 0:
        return 0.0, 1.0, 0.0
    if lo == hi:                            # a constant: exact as the offset, k = 0
        return lo, 1.0, 0.0
    step = 2.0 * bound * SQRT_SAFETY
    offset = (lo + hi) / 2.0
    if not (math.isfinite(step) and step > 0) or (hi - lo) / step >= MODEL_LIMIT // 2:
        step = (hi - lo) / (MODEL_LIMIT // 2)   # the finest grid the 31-bit range allows
    return offset, step, max(bound, step / 2.0)
