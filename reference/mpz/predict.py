"""Temporal prediction of integer blocks (spec §6.2), and the summary levels' prediction
from one another (§4.15, :func:`add_overlap`).

Strategy: a block ``x[T, M, A]`` is split into runs of ``period`` rows (one
pattern each, or the whole clip); within a run the order-p predictor gives
``e[t] = x[t] - pred[t]`` with pred = 0 (order 0), x[t-1] (order 1) or
2x[t-1] - x[t-2] (order 2), where rows before the run start count as absent
(the first row of a run is coded raw, the second with order <= 1).
:func:`reconstruct` is the exact inverse with the overflow guards of §6.2.
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mpz._jit import njit
from mpz.errors import FormatError
from mpz.format import MAX_ORDER

_DIFF_LIMIT = 1 << 32   # §6.2: |x[t] - x[t-1]| < 2^32 for any valid stream
#: values per block of work in :func:`residuals`: 2^20 int64 = 8 MiB per temporary (§8)
_BLOCK_VALUES = 1 << 20


def _runs(x: NDArray[np.int64], period: int | None) -> NDArray[np.int64]:
    """``x[T, ...]`` as ``[T // period, period, ...]`` (one run: the whole block)."""
    T = x.shape[0]
    period = T if period is None else int(period)
    if period <= 0 or T % period:
        raise ValueError(f"period {period} does not divide {T} rows")
    return x.reshape((T // period, period) + x.shape[1:])


def residuals(x: ArrayLike, order: int, period: int | None = None, *,
              inplace: bool = False) -> NDArray[np.int64]:
    """Prediction residuals of ``x`` (int64) for ``order`` in 0..2 (§6.2).

    No temporary of the block's size is made; with ``inplace`` the residuals overwrite
    ``x`` (an int64 array), a block of rows at a time from the end of each run, and
    :func:`reconstruct` with ``inplace`` turns them back (the encoder keeps one array per
    candidate this way).
    """
    x = np.asarray(x, dtype=np.int64)
    if not 0 <= order <= MAX_ORDER:
        raise ValueError(f"predictor order {order} not in 0..{MAX_ORDER}")
    if x.shape[0] == 0:
        return x if inplace else x.copy()
    r = _runs(x, period)
    if not inplace:
        e = r.copy()
        if order >= 1:
            e[:, 1:] -= r[:, :-1]
        if order == 2 and r.shape[1] > 2:       # x[t] - x[t-1], then - x[t-1] + x[t-2]
            e[:, 2:] -= r[:, 1:-1]
            e[:, 2:] += r[:, :-2]
        return e.reshape(x.shape)
    if order == 0:
        return x
    P = r.shape[1]
    step = max(1, _BLOCK_VALUES // max(1, r[0].size))       # runs per block
    rows = max(1, _BLOCK_VALUES // max(1, r[0, 0].size))     # rows per block
    for k0 in range(0, r.shape[0], step):
        g = r[k0: k0 + step]
        for b in range(P, 1, -rows):                         # rows a .. b-1, a >= 1
            a = max(1, b - rows)
            blk = g[:, a:b] - g[:, a - 1: b - 1]
            if order == 2:
                lo = max(a, 2)                               # row 1 stays a first difference
                blk[:, lo - a:] -= g[:, lo - 1: b - 1]
                blk[:, lo - a:] += g[:, lo - 2: b - 2]
            g[:, a:b] = blk
    return x


def reconstruct(e: ArrayLike, order: int, period: int | None = None, *,
                chunk: str | None = None, offset: int | None = None,
                inplace: bool = False) -> NDArray[np.int64]:
    """Invert :func:`residuals` exactly.

    One pass over the rows (:func:`_integrate`); the only scratch is one row of carried
    differences, whatever the block size (spec §8). With ``inplace`` the result overwrites
    ``e`` (an int64 array) and nothing of its size is allocated (when ``e`` is
    C-contiguous; otherwise a contiguous copy is integrated and written back).

    Raises
    ------
    FormatError
        If an intermediate difference leaves the range of §6.2 (hostile
        input that would otherwise overflow 64-bit arithmetic).
    """
    e = np.asarray(e, dtype=np.int64)
    x = e if inplace else e.copy()
    if order == 0 or x.shape[0] == 0:
        return x
    T = x.shape[0]
    P = _runs(x, period).shape[1]
    work = x if x.flags.c_contiguous else np.ascontiguousarray(x)
    bad = _integrate(work.reshape(T, -1), P, int(order))
    if bad >= 0:  # R-6.2-1
        raise _overflow(chunk, offset)
    if work is not x:
        x[...] = work
    return x


@njit(cache=True, nogil=True)
def _integrate(x: NDArray[np.int64], P: int, order: int) -> int:
    """:func:`reconstruct` of ``x[T, C]`` in place, runs of P rows: order 1 adds each row
    to the next; order 2 carries the differences d[t] = d[t-1] + e[t] (d[1] = e[1]) and
    adds them, after §6.2's guard |d| < 2^32. Returns the first row whose difference
    fails the guard, or -1 (speed, issue 15.1: the numpy version made five passes and
    two temporaries per block; this one reads and writes each value once)."""
    T, C = x.shape
    d = np.empty(C, np.int64)
    for r0 in range(0, T, P):
        for t in range(r0 + 1, r0 + P):
            for c in range(C):
                if order == 1:
                    x[t, c] += x[t - 1, c]
                    continue
                dd = x[t, c] if t == r0 + 1 else d[c] + x[t, c]
                # R-6.2-1
                if dd >= _DIFF_LIMIT or dd <= -_DIFF_LIMIT:
                    return t
                d[c] = dd
                x[t, c] = x[t - 1, c] + dd
    return -1


@njit(cache=True, nogil=True)
def add_overlap(starts: NDArray[np.int64], src: NDArray[np.int64],
                src_starts: NDArray[np.int64], frames: int, x: NDArray[np.int64],
                sign: int) -> None:
    """§4.15 step 4: add ``sign`` x the prediction of a summary level to ``x[k, D]`` in
    place. Segment j (``starts[j]`` .. the next start or ``frames``: n_j frames) is
    predicted, per dimension d, by (2 sum_i src[i, d] ov(j, i) + n_j) div (2 n_j), where
    ov(j, i) is the number of frames it shares with segment i of the source level
    (``src_starts``, ``src[k', D]``); div is floor division. Both start lists begin at 0
    and increase. sign 1 turns residuals into means (the decoder), -1 means into
    residuals (the encoder).

    One merge of the two start lists, O((k + k') D) and one row of scratch (spec §8: the
    numpy version made [k + k', D] temporaries and took 0.7 GiB and 9 s on an 80 KB file
    of two levels of 2^22 and 2^23 segments). Every value is below 2^57 in magnitude
    (|src| < 2^31, the overlaps of a segment add up to n_j <= 2^24): int64 is exact."""
    k, D = x.shape
    ks = src_starts.shape[0]
    acc = np.zeros(D, np.int64)
    i = 0
    for j in range(k):
        a = starts[j]
        b = starts[j + 1] if j + 1 < k else frames
        acc[:] = 0
        while i + 1 < ks and src_starts[i + 1] <= a:
            i += 1                                   # the source segment holding frame a
        t = a
        while t < b:
            end = src_starts[i + 1] if i + 1 < ks else frames
            w = min(end, b) - t
            for d in range(D):
                acc[d] += src[i, d] * w
            t += w
            if end <= b and i + 1 < ks:
                i += 1
        n = b - a
        for d in range(D):
            x[j, d] += sign * ((2 * acc[d] + n) // (2 * n))


def _overflow(chunk: str | None, offset: int | None) -> FormatError:
    return FormatError("order-2 prediction residuals leave the valid range",
                       chunk=chunk, offset=offset, section="§6.2")
