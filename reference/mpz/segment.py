"""Adaptive segmentation of a node's motion (paper §III-B, Alg. 1). Encoder only.

Decision (non-normative, the decoder never sees it): Alg. 1's ratio test is
undefined for a one-frame segment and §V states the threshold as a fraction
of ADDH, so MPZ cuts a new segment at frame i when the weighted mean marker
distance between frame i and the segment's key (first) frame exceeds
``theta * ADDH``, or when the segment reaches ``max_len`` frames.
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mpz._jit import njit


@njit(cache=True)
def _cut(x: NDArray[np.float64], w: NDArray[np.float64], thr: float, min_len: int,
         max_len: int) -> NDArray[np.int64]:
    F, n = x.shape[0], x.shape[1]
    starts = np.empty(F, np.int64)
    S = 1
    starts[0] = 0
    key = 0
    for i in range(1, F):
        d = 0.0
        for m in range(n):
            dx = x[i, m, 0] - x[key, m, 0]
            dy = x[i, m, 1] - x[key, m, 1]
            dz = x[i, m, 2] - x[key, m, 2]
            d += w[m] * np.sqrt(dx * dx + dy * dy + dz * dz)
        length = i - key
        if (d > thr and length >= min_len) or length >= max_len:
            starts[S] = i
            S += 1
            key = i
    return starts[:S]


def segment(x: ArrayLike, weights: ArrayLike, threshold: float, *, min_len: int = 2,
            max_len: int = 240) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Cut ``x[F, n, 3]`` into segments; returns (starts, counts).

    Parameters
    ----------
    x : array_like, shape (F, n, 3)
        A node's local trajectories.
    weights : array_like, shape (n,)
        One weight per member (paper's W); normalised to sum to 1 here.
    threshold : float
        Key-frame threshold in the units of ``x`` (theta * ADDH).
    min_len : int
        Frames a segment must have before the threshold may cut it.
    max_len : int
        Frames after which a segment is cut regardless of the threshold.

    Returns
    -------
    starts : ndarray of int64, shape (S,)
        First frame of each segment (``starts[0] == 0``).
    counts : ndarray of int64, shape (S,)
        Frames in each segment.
    """
    x = np.ascontiguousarray(x, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    w = w / w.sum()
    starts = _cut(x, w, float(threshold), int(min_len), int(max_len))
    counts = np.diff(np.append(starts, x.shape[0]))
    return starts, counts
