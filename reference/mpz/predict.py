"""Temporal prediction of integer blocks (spec §6.2).

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

from mpz.errors import FormatError
from mpz.format import MAX_ORDER

_DIFF_LIMIT = 1 << 32   # §6.2: |x[t] - x[t-1]| < 2^32 for any valid stream


def _runs(x: NDArray[np.int64], period: int | None) -> NDArray[np.int64]:
    """``x[T, ...]`` as ``[T // period, period, ...]`` (one run: the whole block)."""
    T = x.shape[0]
    period = T if period is None else int(period)
    if period <= 0 or T % period:
        raise ValueError(f"period {period} does not divide {T} rows")
    return x.reshape((T // period, period) + x.shape[1:])


def residuals(x: ArrayLike, order: int, period: int | None = None) -> NDArray[np.int64]:
    """Prediction residuals of ``x`` (int64) for ``order`` in 0..2 (§6.2)."""
    x = np.asarray(x, dtype=np.int64)
    if not 0 <= order <= MAX_ORDER:
        raise ValueError(f"predictor order {order} not in 0..{MAX_ORDER}")
    if x.shape[0] == 0:
        return x.copy()
    r = _runs(x, period)
    e = r.copy()
    if order >= 1:
        e[:, 1:] = r[:, 1:] - r[:, :-1]
    if order == 2 and r.shape[1] > 2:
        e[:, 2:] = r[:, 2:] - 2 * r[:, 1:-1] + r[:, :-2]
    return e.reshape(x.shape)


def reconstruct(e: ArrayLike, order: int, period: int | None = None, *,
                chunk: str | None = None, offset: int | None = None) -> NDArray[np.int64]:
    """Invert :func:`residuals` exactly.

    Raises
    ------
    FormatError
        If an intermediate difference leaves the range of §6.2 (hostile
        input that would otherwise overflow 64-bit arithmetic).
    """
    e = np.asarray(e, dtype=np.int64)
    if order == 0 or e.shape[0] == 0:
        return e.copy()
    r = _runs(e, period)
    if order == 1:
        x = np.cumsum(r, axis=1)
    else:
        d = r.copy()
        # differences: d[0] = x[0] (kept), d[1] = e[1], d[t] = e[t] + d[t-1]
        d[:, 1:] = np.cumsum(r[:, 1:], axis=1)
        if d.shape[1] > 1 and np.abs(d[:, 1:]).max(initial=0) >= _DIFF_LIMIT:
            raise FormatError("order-2 prediction residuals leave the valid range",
                              chunk=chunk, offset=offset, section="§6.2")
        x = np.cumsum(d, axis=1)
    return x.reshape(e.shape)
