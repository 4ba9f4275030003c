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
    return smooth_frames(p, 0, starts, h, F, (0, F))


def window(F: int, h: int, frames: tuple[int, int]) -> tuple[int, int]:
    """The frames ``lo .. hi - 1`` of P that §6.4 reads to smooth frames ``t0 .. t1 - 1``."""
    t0, t1 = frames
    return max(0, t0 - h), min(F, t1 + h)


def smooth_frames(p: ArrayLike, first: int, starts: ArrayLike, h: int, F: int,
                  frames: tuple[int, int]) -> NDArray[np.int64]:
    """§6.4 for frames ``t0 .. t1 - 1`` of a clip of ``F`` frames: ``[t1 - t0, ...]``.

    ``p`` holds the unsmoothed P from frame ``first`` on, covering at least
    :func:`window` (F, h, frames). Every temporary is the size of the block, so a
    decoder can smooth a clip of any length a block of frames at a time (spec §8).
    """
    p = np.asarray(p, dtype=np.int64)
    starts = np.asarray(starts, dtype=np.int64)
    t0, t1 = frames
    out = p[t0 - first: t1 - first].copy()
    if h <= 0 or len(starts) < 2 or F < 2 or t1 <= t0:
        return out
    # frame t is smoothed when a boundary b (the start of every segment but the first)
    # has b - h <= t <= b + h - 1, that is b in [t - h + 1, t + h]
    bounds = starts[1:]
    f = np.arange(t0, t1, dtype=np.int64)
    region = (np.searchsorted(bounds, f + h, side="right")
              > np.searchsorted(bounds, f - h + 1, side="left"))
    if not region.any():
        return out
    w = 2 * h + 1
    idx = np.clip(np.arange(t0 - h, t1 + h), 0, F - 1) - first
    padded = p[idx]
    csum = np.concatenate([np.zeros((1,) + p.shape[1:], np.int64), np.cumsum(padded, axis=0)])
    # window sum for output t covers padded[t - t0 : t - t0 + w]
    sums = csum[w: w + (t1 - t0)] - csum[: t1 - t0]
    out[region] = (2 * sums[region] + w) // (2 * w)
    return out
