"""Error-bounded choice of grid values (encoder only; beyond the paper).

Rounding each axis to a grid of step s keeps the Euclidean error within
E = s sqrt(3) / 2, but the E-ball around a sample holds on average 2.7 grid
points, not one. :func:`choose_lattice` walks each track in time and picks,
among the grid points within the ball, the one closest to what the decoder
will predict from the values already chosen (order-p temporal prediction).
The decoder is unchanged (it just reads integers), the bound still holds for
every sample, and the residuals shrink: 10-15 % smaller files on real CMU and
HDM05 captures at 1-5 mm (bench/bench_rd.py).
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mpz._jit import njit


@njit(cache=True, nogil=True)
def _choose(y: NDArray[np.float64], radius: float, order: int) -> NDArray[np.int64]:
    T, M = y.shape[0], y.shape[1]
    w = np.empty((T, M, 3), np.int64)       # every value is written below
    r2 = radius * radius
    for t in range(T):              # each track is independent: frame by frame, so that
        for m in range(M):          # w[t - 1] and y[t] are read in memory order
            p0 = 0.0
            p1 = 0.0
            p2 = 0.0
            if order == 1 or (order == 2 and t == 1):
                if t >= 1:
                    p0 = w[t - 1, m, 0]
                    p1 = w[t - 1, m, 1]
                    p2 = w[t - 1, m, 2]
            elif order == 2 and t >= 2:
                p0 = 2 * w[t - 1, m, 0] - w[t - 2, m, 0]
                p1 = 2 * w[t - 1, m, 1] - w[t - 2, m, 1]
                p2 = 2 * w[t - 1, m, 2] - w[t - 2, m, 2]
            if order == 0 or t == 0:
                # nothing to predict from: nearest grid point
                w[t, m, 0] = math.floor(y[t, m, 0] + 0.5)
                w[t, m, 1] = math.floor(y[t, m, 1] + 0.5)
                w[t, m, 2] = math.floor(y[t, m, 2] + 0.5)
                continue
            best = 1e300
            b0 = math.floor(y[t, m, 0] + 0.5)
            b1 = math.floor(y[t, m, 1] + 0.5)
            b2 = math.floor(y[t, m, 2] + 0.5)
            lo0 = math.ceil(y[t, m, 0] - radius)
            hi0 = math.floor(y[t, m, 0] + radius)
            lo1 = math.ceil(y[t, m, 1] - radius)
            hi1 = math.floor(y[t, m, 1] + radius)
            lo2 = math.ceil(y[t, m, 2] - radius)
            hi2 = math.floor(y[t, m, 2] + radius)
            for a in range(lo0, hi0 + 1):
                da = a - y[t, m, 0]
                for b in range(lo1, hi1 + 1):
                    db = b - y[t, m, 1]
                    for c in range(lo2, hi2 + 1):
                        dc = c - y[t, m, 2]
                        d2 = da * da + db * db + dc * dc
                        if d2 <= r2:
                            cost = abs(a - p0) + abs(b - p1) + abs(c - p2) + 1e-3 * d2
                            if cost < best:
                                best = cost
                                b0 = a
                                b1 = b
                                b2 = c
            w[t, m, 0] = b0
            w[t, m, 1] = b1
            w[t, m, 2] = b2
    return w


def choose_lattice(y: ArrayLike, radius: float, order: int) -> NDArray[np.int64]:
    """Integer values ``w[T, M, 3]`` with ``|w - y| <= radius`` (Euclidean, per sample).

    Parameters
    ----------
    y : ndarray, float, shape (T, M, 3)
        Targets in grid units.
    radius : float
        Allowed distance in grid units; must be >= sqrt(3)/2 so that the
        nearest grid point always qualifies.
    order : int
        Temporal predictor order the values will be coded with (0..2).

    Returns
    -------
    ndarray of int64, shape (T, M, 3)

    Raises
    ------
    ValueError
        If ``radius`` is below sqrt(3)/2.
    """
    if radius < np.sqrt(3.0) / 2:
        raise ValueError(f"radius {radius} < sqrt(3)/2 cannot guarantee a grid point")
    return _choose(np.ascontiguousarray(y, dtype=np.float64), float(radius), int(order))
