"""Adaptive K-means into motion patterns (paper §III-C). Encoder only.

Strategy: start from K0 clusters (k-means++ seeded, Lloyd iterations), then
instead of restarting K-means with K+1 as the paper does (superlinear), split
every cluster that violates the criterion in two (bisecting 2-means) and
repeat. Each round touches every segment once, so the cost grows about
linearly with the number of segments times log K.

Errors are measured per segment as the RMS marker distance between the
segment and its pattern (Eq. 2's |x - mu| divided by sqrt(frames x markers),
so the threshold reads in length units, relative to ADDH as in §V):
``MaxError`` = the largest of these, ``AveError`` = their root mean square.
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

METRICS = ("max", "ave")


def _kmeans(v: NDArray[np.float64], k: int, rng: np.random.Generator,
            iters: int = 12) -> NDArray[np.int64]:
    """Labels of ``k``-means (k-means++ seeds, at most ``iters`` Lloyd rounds) on rows of ``v``."""
    n = v.shape[0]
    # k-means++ seeding
    centers = np.empty((k, v.shape[1]))
    centers[0] = v[rng.integers(n)]
    d2 = ((v - centers[0]) ** 2).sum(1)
    for j in range(1, k):
        total = d2.sum()
        idx = rng.integers(n) if total <= 0 else rng.choice(n, p=d2 / total)
        centers[j] = v[idx]
        d2 = np.minimum(d2, ((v - centers[j]) ** 2).sum(1))
    labels = np.zeros(n, np.int64)
    for _ in range(iters):
        dist = ((v ** 2).sum(1)[:, None] - 2 * v @ centers.T + (centers ** 2).sum(1)[None, :])
        new = dist.argmin(1)
        if _ > 0 and (new == labels).all():
            break
        labels = new
        for j in range(k):
            sel = labels == j
            if sel.any():
                centers[j] = v[sel].mean(0)
    return labels


def adaptive_kmeans(vectors: ArrayLike, k0: int, threshold: float, *, metric: str = "max",
                    per_sample: int = 1, seed: int = 0,
                    max_k: int = 65535) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Cluster segment vectors until the error criterion holds.

    Parameters
    ----------
    vectors : array_like, shape (S, D)
        Normalised (and weight-scaled) segments.
    k0 : int
        Initial number of clusters (paper's K0).
    threshold : float
        Clustering threshold in length units (tau * ADDH).
    metric : {"max", "ave"}
        Paper's MaxError (Eq. 2) or AveError (Eq. 1).
    per_sample : int
        frames x markers per vector, to turn |x - mu| into an RMS distance.
    seed : int
        Seed of the ``numpy.random.default_rng`` used for seeding and splits.
    max_k : int
        Most clusters to make.

    Returns
    -------
    labels : ndarray of int, shape (S,)
        Cluster of each segment, in ``0..K-1``.
    errors : ndarray of float64, shape (S,)
        RMS distance of each segment to its centre.
    """
    if metric not in METRICS:
        raise ValueError(f"metric must be one of {METRICS}, got {metric!r}")
    v = np.asarray(vectors, dtype=np.float64)
    S = v.shape[0]
    rng = np.random.default_rng(seed)
    k = max(1, min(int(k0), S, max_k))
    labels = _kmeans(v, k, rng)
    norm = 1.0 / np.sqrt(max(per_sample, 1))
    while True:
        K = int(labels.max()) + 1
        centers = np.zeros((K, v.shape[1]))
        np.add.at(centers, labels, v)
        sizes = np.bincount(labels, minlength=K)
        centers /= np.maximum(sizes, 1)[:, None]
        err = np.sqrt(((v - centers[labels]) ** 2).sum(1)) * norm
        if metric == "max":
            bad_clusters = np.unique(labels[err > threshold])
        else:
            if np.sqrt((err ** 2).mean()) <= threshold:
                bad_clusters = np.array([], np.int64)
            else:  # split the clusters holding the largest share of squared error
                sse = np.bincount(labels, weights=err ** 2, minlength=K)
                order = np.argsort(-sse)
                bad_clusters = order[: max(1, K // 4)]
        to_split = [c for c in bad_clusters if sizes[c] > 1]
        if not to_split or K >= min(S, max_k):
            return labels, err
        next_label = K
        for c in to_split:
            if next_label >= max_k:
                break
            idx = np.flatnonzero(labels == c)
            sub = _kmeans(v[idx], 2, rng, iters=8)
            if sub.min() == sub.max():   # degenerate: split off the farthest segment
                sub = np.zeros(len(idx), np.int64)
                sub[np.argmax(err[idx])] = 1
            labels[idx[sub == 1]] = next_label
            next_label += 1
