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


def denormalize(patterns: ArrayLike, index: ArrayLike, counts: ArrayLike, *,
                frames: tuple[int, int] | None = None,
                starts: ArrayLike | None = None) -> NDArray[np.int64]:
    """Rebuild ``[sum(counts), n, A]`` integer samples from patterns ``[K, L, n, A]`` (§6.3).

    Parameters
    ----------
    patterns : array_like of int, shape (K, L, n, A)
    index, counts : array_like of int, shape (S,)
        Pattern index and frame count of each segment (every count >= 1, §4.8).
    frames : (int, int), optional
        Only frames ``t0 .. t1 - 1`` of the result, ``[t1 - t0, n, A]``: the same
        values, with temporaries the size of that block (spec §8: a decoder works a
        block of frames at a time, so a SEGS chunk of a few bytes that stretches one
        pattern over 2^26 marker-frames costs no more than the output).
    starts : array_like of int, shape (S,), optional
        ``segment_starts(counts)``, when the caller has it already.
    """
    patterns = np.asarray(patterns, dtype=np.int64)
    index = np.asarray(index, dtype=np.int64)
    counts = np.asarray(counts, dtype=np.int64)
    starts = segment_starts(counts) if starts is None else np.asarray(starts, np.int64)
    L = patterns.shape[1]
    t0, t1 = (0, int(counts.sum())) if frames is None else frames
    f = np.arange(t0, t1, dtype=np.int64)
    # the segment of each frame: the last one starting at or before it (a segment of no
    # frames shares its start with the next one and so is never chosen)
    seg = np.searchsorted(starts, f, side="right") - 1
    j = f - starts[seg]
    n = counts[seg]
    den = np.maximum(n - 1, 1)
    num = j * (L - 1)
    i0 = np.where(n > 1, num // den, 0)
    r = np.where(n > 1, num - i0 * den, 0)
    i1 = np.minimum(i0 + 1, L - 1)
    p = index[seg]
    a = patterns[p, i0]
    b = patterns[p, i1]
    b -= a
    b *= 2 * r[:, None, None]
    den_b = den[:, None, None]
    b += den_b
    b //= 2 * den_b
    b += a
    return b


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
    # x[i0] (1 - f) + x[i1] f, each product and the sum formed in place (the same
    # roundings as the expression, two arrays of the result's size instead of four)
    out = x[i0]
    out *= (1 - f)[shape]
    right = x[i1]
    right *= f[shape]
    out += right
    return out
