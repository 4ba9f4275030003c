"""Time normalisation of segments (paper §III-B; spec §6.3 for the decoder side).

Strategy: the *decoder* side (:func:`denormalize`) is normative and works on
integers only, so every conforming decoder produces the same samples. The
*encoder* side (:func:`normalize`) is its float counterpart and is free.

§6.3: a segment of n frames drawn from a pattern of L frames takes, at its
frame j, the pattern position u = j (L-1) / (n-1), written i0 = floor(u),
r = j (L-1) - i0 (n-1), and the value
``P[i0] + floor((2 (P[i0+1] - P[i0]) r + (n-1)) / (2 (n-1)))`` (round half up);
for n = 1 the value is P[0].
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def segment_starts(counts: ArrayLike) -> NDArray[np.int64]:
    """First frame of each segment: ``[0, c0, c0 + c1, ...]`` for segment lengths ``counts``."""
    counts = np.asarray(counts, dtype=np.int64)
    return np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)


def denormalize(patterns: ArrayLike, index: ArrayLike, counts: ArrayLike) -> NDArray[np.int64]:
    """Rebuild ``[sum(counts), n, A]`` integer samples from patterns ``[K, L, n, A]`` (§6.3)."""
    patterns = np.asarray(patterns, dtype=np.int64)
    index = np.asarray(index, dtype=np.int64)
    counts = np.asarray(counts, dtype=np.int64)
    L = patterns.shape[1]
    F = int(counts.sum())
    seg = np.repeat(np.arange(len(counts)), counts)
    j = np.arange(F, dtype=np.int64) - np.repeat(segment_starts(counts), counts)
    n = counts[seg]
    den = np.maximum(n - 1, 1)
    num = j * (L - 1)
    i0 = np.where(n > 1, num // den, 0)
    r = np.where(n > 1, num - i0 * den, 0)
    i1 = np.minimum(i0 + 1, L - 1)
    p = index[seg]
    a = patterns[p, i0]
    b = patterns[p, i1]
    den_b = den[:, None, None]
    return a + (2 * (b - a) * r[:, None, None] + den_b) // (2 * den_b)


def normalize(x: ArrayLike, starts: ArrayLike, counts: ArrayLike, L: int) -> NDArray[np.float64]:
    """Resample each segment of ``x[F, ...]`` to L frames by linear interpolation (encoder side).

    Returns ``[S, L, ...]`` float64.
    """
    x = np.asarray(x, dtype=np.float64)
    starts = np.asarray(starts, dtype=np.int64)
    counts = np.asarray(counts, dtype=np.int64)
    u = np.arange(L, dtype=np.float64)
    scale = np.where(L > 1, (counts - 1) / max(L - 1, 1), 0.0)
    pos = starts[:, None] + u[None, :] * scale[:, None]          # [S, L]
    i0 = np.floor(pos).astype(np.int64)
    i1 = np.minimum(i0 + 1, (starts + counts - 1)[:, None])
    f = pos - i0
    shape = (slice(None), slice(None)) + (None,) * (x.ndim - 1)
    return x[i0] * (1 - f)[shape] + x[i1] * f[shape]
