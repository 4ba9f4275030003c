"""Smoothing across segment boundaries (paper §III-E; spec §6.4).

The paper applies "a spline filter" at boundaries without saying which. MPZ
uses a centred moving average of width w = 2h + 1, because it is exact in
integer arithmetic and so identical in every decoder. Only the frames within
h of a boundary change; every output is computed from the unsmoothed input.

§6.4: for each boundary b (first frame of every segment but the first) and
each frame t in [b - h, b + h - 1] within [0, F-1]:
``S[t] = floor((2 * sum_{u=t-h}^{t+h} P[clamp(u, 0, F-1)] + w) / (2 w))``.
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def smooth_boundaries(p: ArrayLike, starts: ArrayLike, h: int) -> NDArray[np.int64]:
    """Apply §6.4 to integer samples ``p[F, ...]`` with segments starting at ``starts``."""
    p = np.asarray(p, dtype=np.int64)
    F = p.shape[0]
    starts = np.asarray(starts, dtype=np.int64)
    if h <= 0 or len(starts) < 2 or F < 2:
        return p.copy()
    w = 2 * h + 1
    idx = np.clip(np.arange(-h, F + h), 0, F - 1)
    padded = p[idx]
    csum = np.concatenate([np.zeros((1,) + p.shape[1:], np.int64), np.cumsum(padded, axis=0)])
    # window sum for output t covers padded[t : t + w]
    sums = csum[w: w + F] - csum[:F]
    region = np.zeros(F, bool)
    for b in starts[1:]:
        region[max(0, b - h): min(F, b + h)] = True
    out = p.copy()
    out[region] = (2 * sums[region] + w) // (2 * w)
    return out
