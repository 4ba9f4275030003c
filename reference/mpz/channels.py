"""The channel layer of the skeleton chunks (spec §4.14, §6.10): joint channels coded
as integers on decimal steps, predicted in time, range-coded.

Strategy: channel c of a skeletal motion (a BVH ``Zrotation``, an ASF ``rx``, a root
translation) is quantised to ``x = round(v / step)`` with ``step = m x 10^-d``: the
decoded value ``x m / 10^d`` is a decimal number, so a text writer prints it exactly and
the error is at most half a step, in degrees or length units, whatever the magnitude.
Each channel is predicted in time (§6.2 orders 0-2); a rotation in degrees whose values
fit in one turn is *wrapped*: residuals are taken modulo the turn (360 / step steps) and
the decoder folds every value back into ``low .. low + turn - 1``, so the jump of an
angle from +179.99 to -179.99 degrees codes as one step and decodes exactly. Channels
are coded in *groups* of similar activity, one range-coded block (§5.5) each.

This module is sans-IO and knows no chunk: :mod:`mpz.chunks.skeleton` checks and decodes
with it, :mod:`mpz.skeleton` encodes with it. :func:`decode` is §6.10; everything else
is the reference encoder's choice (spec Appendix C).
"""
from __future__ import annotations

import bisect
from collections.abc import Sequence
from dataclasses import dataclass
import functools
import math
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from mpz._jit import njit
from mpz._worker import spelled
from mpz.entropy import MAX_EXP, BlockDecoder, BlockEncoder
from mpz.errors import EncoderError, FormatError
from mpz.format import CHANNEL_VALUE_LIMIT, MAX_STEP_DIGITS
from mpz.predict import _DIFF_LIMIT, _overflow, residuals

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]

#: what a wrapped channel is taken modulo, in its own units (§4.14): one turn of an angle
#: in degrees
TURN_DEGREES = 360
#: step mantissas the reference encoder uses; each divides 360 x 10^d, so every one of its
#: steps can wrap (§4.14)
MANTISSAS = (1, 2, 4, 5, 8)
#: group counts the reference encoder may try (§4.14 allows 1..256), in increasing order;
#: :func:`group` searches them from FIRST_GROUP_COUNT (spec Appendix C item 11)
GROUP_COUNTS = (1, 2, 4, 8, 12, 16)
FIRST_GROUP_COUNT = 8


class Coding(Protocol):
    """What §6.10 needs of a channel entry (:class:`mpz.chunks.skeleton.ChannelCoding`)."""

    @property
    def step_mantissa(self) -> int: ...
    @property
    def step_digits(self) -> int: ...
    @property
    def wrap(self) -> int: ...
    @property
    def low(self) -> int: ...
    @property
    def order(self) -> int: ...
    @property
    def group(self) -> int: ...


def turn_steps(mantissa: int, digits: int) -> int | None:
    """N, the steps in 360 of a channel's units (one turn of an angle in degrees) at step
    ``m x 10^-d``, or None when 360 is not a whole number of steps (§4.14)."""
    whole = TURN_DEGREES * 10 ** digits
    return None if whole % mantissa else whole // mantissa


# ------------------------------------------------------------------ steps --
@dataclass(frozen=True)
class Step:
    """A channel's quantisation step ``mantissa x 10^-digits`` (§4.14)."""

    mantissa: int
    digits: int

    @property
    def value(self) -> float:
        return self.mantissa / 10.0 ** self.digits

    @property
    def bound(self) -> float:
        """The largest error of rounding to this step: half of it."""
        return self.value / 2

    @property
    def turn(self) -> int | None:
        return turn_steps(self.mantissa, self.digits)

    def __str__(self) -> str:
        return f"{self.value:.{self.digits}f}"


@functools.cache
def _step_ladder() -> tuple[list[float], list[Step]]:
    """Every step ``m x 10^-d`` (m in MANTISSAS, d = MAX_STEP_DIGITS..0) by increasing value,
    each value's first in that order, with the values: :func:`step_for` takes the largest
    at most its target (a search of the ladder; scanning it was the position-bound search's
    cost, 2232 calls and 117 ms an encode of 02_01.amc at 1 mm)."""
    first: dict[float, Step] = {}
    for d in range(MAX_STEP_DIGITS, -1, -1):
        for m in MANTISSAS:
            s = Step(m, d)
            first.setdefault(s.value, s)
    values = sorted(first)
    return values, [first[v] for v in values]


def _channel_bounds() -> str:
    """The channel bounds, as the reader of a message spells them (a QA run of the API:
    a program was told of the command's options)."""
    return spelled("--angle-error or --translation-error", "angle_error or translation_error")


def step_for(bound: float) -> Step:
    """The coarsest step ``m x 10^-d``, m in :data:`MANTISSAS` times a power of ten, whose
    rounding error (half the step) stays within ``bound``.

    Examples
    --------
    >>> str(step_for(0.01)), str(step_for(0.004)), str(step_for(3.0)), str(step_for(60.0))
    ('0.02', '0.008', '5', '80')

    Raises
    ------
    EncoderError
        For a bound that is not finite and > 0, or finer than 10^-9 / 2.
    """
    if not (math.isfinite(bound) and bound > 0):
        raise EncoderError(f"a channel bound must be finite and > 0, got {bound!r}")
    target = 2.0 * bound * (1 + 1e-12)
    values, ladder = _step_ladder()
    i = bisect.bisect_right(values, target)
    best = ladder[i - 1] if i else None
    if best is None:
        raise EncoderError(f"a channel bound of {bound!r} is finer than the finest step, "
                           f"10^-{MAX_STEP_DIGITS}; give a larger {_channel_bounds()}")
    if best.digits == 0:                     # steps of 10 and more: m x 10^k, d = 0
        m = best.mantissa
        while m * 10 <= target and m * 10 <= 0xFFFF:
            m *= 10
        best = Step(m, 0)
    return best


def quantise(values: FloatArray, steps: Sequence[Step],
             names: Sequence[str] | None = None) -> IntArray:
    """``round(v / step)`` per channel of ``values[F, C]``, int64: the integer whose
    ``x m / 10^d`` is nearest to v. ``names``: the channels' names, for the error (it
    gave an index alone, "channel 10": a QA run of stop 75).

    Raises
    ------
    EncoderError
        If a value needs |x| >= 2^27 at its step, so that order-2 residuals could leave the
        coder's range (|e| < 2^30, §5.4).
    """
    v = np.asarray(values, np.float64)
    scale = np.array([10.0 ** s.digits / s.mantissa for s in steps])
    with np.errstate(over="ignore"):          # a value of 1e308 is reported just below
        x = np.floor(v * scale + 0.5) if v.size else np.zeros(v.shape)
    if x.size and np.abs(x).max() >= 2.0 ** (MAX_EXP - 3):
        c = int(np.argmax(np.abs(x).max(axis=0)))
        which = f"{names[c]} (channel {c})" if names is not None else f"channel {c}"
        raise EncoderError(f"{which} reaches {float(np.abs(v[:, c]).max()):g}, too large "
                           f"for a step of {steps[c]} (|value / step| must stay below 2^27); "
                           f"give a larger {_channel_bounds()}")
    return x.astype(np.int64)


#: values of the channel layer worked on at a time while decoding (spec §8, memory budget:
#: whole-layer temporaries took about 30 bytes a channel value, a QA run of stop 40)
_CELLS = 1 << 20


def dequantise(x: IntArray, codings: Sequence[Coding]) -> FloatArray:
    """§6.10 step 5: ``v = x m / 10^d``, one correctly rounded binary64 division of the exact
    integer ``x m`` (|x m| < 2^47, exact in binary64) by ``10^d`` (exact for d <= 22), of
    ``x[F, C]``; a block of rows at a time into the output, so that no temporary is of
    its size."""
    m = np.array([c.step_mantissa for c in codings], np.int64)
    p = np.array([10.0 ** c.step_digits for c in codings])
    out = np.empty(x.shape, np.float64)
    rows = max(1, _CELLS // max(x.shape[1], 1))
    for r0 in range(0, x.shape[0], rows):
        out[r0: r0 + rows] = (x[r0: r0 + rows] * m).astype(np.float64) / p
    return out


# ---------------------------------------------------------------- encoding --
def _wrap(e: IntArray, turn: int | IntArray) -> IntArray:
    """The residue of ``e`` modulo ``turn`` nearest to 0 (in -turn/2 .. turn/2 - 1); a
    ``turn`` per column of ``e[F, k]`` when it is an array of k."""
    half = turn // 2
    return np.asarray(np.mod(e + half, turn) - half, np.int64)


@dataclass(frozen=True)
class Plan:
    """How the encoder codes one channel: step, wrap (and its ``low``), predictor order."""

    step: Step
    wrap: bool
    low: int
    order: int


def coded_values(x: IntArray, plans: Sequence[Plan]) -> IntArray:
    """The values e ``[F, C]`` the coded field holds: each channel's prediction residuals,
    taken modulo its turn (the residue nearest to 0) when it wraps (:func:`decode` inverts
    them), the channels of one order together (:func:`_by_order`)."""
    e = np.empty_like(x)
    assert all(p.step.turn is not None for p in plans if p.wrap)    # plan() wraps only then
    turns = np.array([(p.step.turn or 0) if p.wrap else 0 for p in plans], np.int64)
    for order, plain, wrapped in _by_order([p.order for p in plans], turns):
        if plain.size:
            e[:, plain] = residuals(x[:, plain], order)
        if wrapped.size:
            e[:, wrapped] = _wrap(residuals(x[:, wrapped], order), turns[wrapped])
    return e


def _by_order(orders: Sequence[int], turns: NDArray[np.int64]
              ) -> list[tuple[int, NDArray[np.int64], NDArray[np.int64]]]:
    """(order, columns that do not wrap, columns that wrap) for each predictor order in
    use, lowest first; ``turns`` is each channel's turn, 0 where it does not wrap. The
    channel layer is coded and decoded a group at a time (issue 15.1: a numpy call or
    two per channel was a tenth of an AMC file's decode), each column as on its own."""
    o = np.asarray(orders, np.int64)
    return [(order, np.flatnonzero((o == order) & (turns == 0)),
             np.flatnonzero((o == order) & (turns > 0))) for order in np.unique(o).tolist()]


def _cost(e: IntArray) -> FloatArray:
    """A bit-cost estimate per column: the sum of log2(1 + |e|)."""
    return np.asarray(np.log2(1.0 + np.abs(e.astype(np.float64))).sum(axis=0), np.float64)


def plan(x: IntArray, steps: Sequence[Step], rotations: Sequence[bool]) -> list[Plan]:
    """Per channel: wrap when it is a rotation in degrees (``rotations``) whose values fit
    in one turn, and the predictor order (0, 1 or 2) with the smallest :func:`_cost` (the
    lowest order on a tie). Each order is tried on all channels at once; each channel's
    cost is still summed over its own frames alone, as numpy sums a contiguous row, so the
    choice does not depend on the other channels."""
    F, C = x.shape
    lo = x.min(axis=0) if F else np.zeros(C, np.int64)
    hi = x.max(axis=0) if F else np.zeros(C, np.int64)
    turns = np.zeros(C, np.int64)
    wraps = np.zeros(C, bool)
    for c, (s, rot) in enumerate(zip(steps, rotations, strict=True)):
        turn = s.turn
        wraps[c] = bool(rot and turn is not None and F and int(hi[c]) - int(lo[c]) < turn
                        and int(lo[c]) + turn <= CHANNEL_VALUE_LIMIT)
        if wraps[c] and turn is not None:
            turns[c] = turn
        else:
            turns[c] = 1                              # not used: the channel does not wrap
    costs = np.empty((3, C))
    for order in (0, 1, 2):
        e = residuals(x, order)
        if wraps.any():
            half = turns // 2
            e = np.where(wraps, np.mod(e + half, turns) - half, e)     # as _wrap
        cost = np.log2(1.0 + np.abs(e.astype(np.float64)))
        costs[order] = np.ascontiguousarray(cost.T).sum(axis=1)
    best = np.argmin(costs, axis=0)                                  # the first least
    return [Plan(s, bool(wraps[c]), int(lo[c]) if wraps[c] else 0, int(best[c]))
            for c, s in enumerate(steps)]


def _encode_groups(e: IntArray, groups: NDArray[np.int64], limit: int | None = None
                   ) -> bytes | None:
    """The coded field of ``e`` in these groups; None once it is sure to be longer than
    ``limit`` bytes (the coder stops there)."""
    enc = BlockEncoder(capacity=max(1024, 2 * e.size), limit=limit)
    for g in range(int(groups.max(initial=-1)) + 1):
        enc.block(e[:, np.flatnonzero(groups == g), None])
        if enc.over:
            return None
    return enc.finish()


def group(e: IntArray) -> tuple[NDArray[np.int64], bytes]:
    """Channels grouped by activity (quantiles of their :func:`_cost`), each group one block
    with its own models. Returns (group of each channel, the coded field).

    The count of groups G is searched among :data:`GROUP_COUNTS` up to C, from
    :data:`FIRST_GROUP_COUNT` (or the largest count below it), and the next smaller and
    next larger counts; from the one of these that codes smallest, on to further counts
    in the same direction while each codes smaller. "Smaller" is a shorter field, or as
    short with fewer groups, and the smallest count found is kept. Where the coded length
    falls and then rises with G, that is the count coding every one of them would keep,
    with 3-4 codings instead of 6 (issue 15.1: they were the skeleton chunk's longest
    step). Elsewhere it can miss the smallest: 2 of 480 real channel sets, +0.0002 % of
    their bytes (spec Appendix C item 11, bench/bench_grouping.py). A coding stops once it
    cannot be smaller.
    """
    C = e.shape[1]
    if C == 0:
        return np.zeros(0, np.int64), BlockEncoder().finish()
    if e.size and int(np.abs(e).max()) >= 1 << MAX_EXP:
        raise EncoderError("a channel residual exceeds the coder's range (spec §5.4); give a "
                           f"larger {_channel_bounds()}")
    rank = np.empty(C, np.int64)
    rank[np.argsort(_cost(e), kind="stable")] = np.arange(C)
    counts = [G for G in GROUP_COUNTS if G <= C]
    start = max(i for i, G in enumerate(counts) if G <= FIRST_GROUP_COUNT)   # 1 <= C
    first = _encode_groups(e, (rank * counts[start]) // C)
    assert first is not None                     # no limit: the coder does not stop
    best, field = start, first

    def smaller(i: int) -> bool:
        """Whether count i codes smaller than the best so far (then the best)."""
        nonlocal best, field
        limit = len(field) - (1 if i > best else 0)      # more groups: strictly shorter
        data = _encode_groups(e, (rank * counts[i]) // C, limit)
        if data is None or len(data) > limit:            # (None: stopped past the limit)
            return False
        best, field = i, data
        return True

    for i in (start - 1, start + 1):
        if 0 <= i < len(counts):
            smaller(i)
    step = best - start
    i = best + step
    while step and 0 <= i < len(counts) and smaller(i):
        i += step
    return (rank * counts[best]) // C, field


# ----------------------------------------------------------- §6.10 decoding --
def decode(codings: Sequence[Coding], coded: bytes, frames: int, *,
           chunk: str | None = None, offset: int | None = None) -> IntArray:
    """§6.10 steps 1-3: the channel integers x ``[F, C]``.

    ``codings`` are checked channel entries (§4.14); ``offset`` is the file offset of the
    coded field, for error reports.

    Raises
    ------
    FormatError
        For a coded field that §5.3 rejects, an order-2 difference beyond §6.2's guard, or a
        value with |x| >= 2^31.
    """
    F, C = frames, len(codings)
    dec = BlockDecoder(coded, chunk=chunk, offset=offset)  # R-6.10-1
    groups = np.array([c.group for c in codings], np.int64)
    G = int(groups.max(initial=-1)) + 1
    if G == 1 and (groups == 0).all():                  # one block of every column: as is
        e = dec.block(F, C, 1).reshape(F, C)
    else:
        e = np.empty((F, C), np.int64)
        for g in range(G):
            cols = np.flatnonzero(groups == g)
            e[:, cols] = dec.block(F, len(cols), 1)[:, :, 0]      # step 1: group g
    dec.close()
    # steps 2 and 3 overwrite e with x in place, column by column (spec §8: no temporary
    # of the layer's size), in one kernel pass: a few numpy calls per order and group of
    # columns were a tenth of a CMU AMC file's decode (issue 15.1, stop 70)
    turns = np.array([(turn_steps(cc.step_mantissa, cc.step_digits) or 0) if cc.wrap else 0
                      for cc in codings], np.int64)
    lows = np.array([cc.low for cc in codings], np.int64)
    orders = np.array([cc.order for cc in codings], np.int64)
    peak = _values(e, orders, turns, lows)
    if peak < 0:                                                            # R-6.10-1
        raise _overflow(chunk, offset)
    if peak >= CHANNEL_VALUE_LIMIT:                                         # R-6.10-1
        c = int(np.argmax(np.abs(e).max(axis=0)))
        t = int(np.argmax(np.abs(e[:, c])))
        raise FormatError(f"channel {c}, frame {t}: decoded value {int(e[t, c])} is outside "
                          f"|x| < 2^31", chunk=chunk, section="§6.10")
    return e


@njit(cache=True, nogil=True)
def _values(e: IntArray, orders: IntArray, turns: IntArray, lows: IntArray) -> int:
    """§6.10 steps 2 and 3 in place: each column c of ``e[F, C]`` becomes its channel's x.
    A channel that does not wrap (``turns[c]`` = 0) is reconstructed with ``orders[c]``
    as :func:`mpz.predict.reconstruct` does with period F; one that wraps is the order-p
    reconstruction taken modulo N = ``turns[c]`` into ``lows[c]`` .. ``lows[c]`` + N - 1.
    Returns the largest |x| of the layer (0 for none; step 4 checks it), or -1 as soon as
    an order-2 difference of a channel that does not wrap fails §6.2's guard (|d| <
    2^32), which rejects the file whatever else it holds.

    A wrapped channel is computed on residues, so that no intermediate value exceeds 2^56:
    every value added into a running sum is first reduced modulo N (order 2: the running
    sums of e, the first differences, before they are summed again), which gives the same
    residue (reduction commutes with sums). The bound needs N < 2^32, which §4.14's wrap
    check has established when the chunk was read (spec §1.2, §6.10 step 3). ``%`` is
    Python's floor modulo, as in the spec (§1).

    Examples
    --------
    >>> e = np.array([[17999], [2], [-4]])
    >>> _values(e, np.array([1]), np.array([18000]), np.array([-9000])), e[:, 0].tolist()
    (3, [-1, 1, -3])
    """
    F, C = e.shape
    peak = 0
    for c in range(C):
        order = orders[c]
        N = turns[c]
        if N == 0:
            if order == 1:
                for t in range(1, F):
                    e[t, c] += e[t - 1, c]
            elif order == 2:
                d = 0
                for t in range(1, F):
                    d = e[t, c] if t == 1 else d + e[t, c]
                    if d >= _DIFF_LIMIT or d <= -_DIFF_LIMIT:
                        return -1
                    e[t, c] = e[t - 1, c] + d
        else:
            low = lows[c]
            if order == 1:                       # y[t] = sum of e[0..t] mod N
                y = 0
                for t in range(F):
                    y += e[t, c] % N
                    e[t, c] = low + (y - low) % N
            elif order == 2:                     # y[t] = e[0] + sum of (e[1..u] sums mod N)
                s = 0
                y = e[0, c]
                e[0, c] = low + (y - low) % N
                for t in range(1, F):
                    s += e[t, c]
                    y += s % N
                    e[t, c] = low + (y - low) % N
            else:
                for t in range(F):
                    e[t, c] = low + (e[t, c] - low) % N
        for t in range(F):
            v = e[t, c]
            if v > peak:
                peak = v
            elif -v > peak:
                peak = -v
    return peak

