"""The baselines of the paper's Figs 3-7 (Yang et al. 2016): PAA, DFT and Haar.

Contract: each baseline describes a series ``x[n, D]`` (or ``x[n]``) with ``k``
numbers per dimension, like the ``k`` segment means of a ``k``-partition from
:func:`mpz.fisher.optimal_partitions`, so their errors can be compared with
its WSSSE. :func:`paa` returns a :class:`mpz.fisher.Partition`;
:func:`dft_approx` and :func:`haar_approx` return the reconstruction, with the
shape of ``x``. Input is checked by the same rules as the optimal partition
(finite numeric series, ``1 <= k <= n``), and a bad input raises
:class:`mpz.errors.EncoderError`. The ``select="largest"`` variants need ``k``
positions per dimension on top, so their budget is larger.

These are research baselines, not part of the codec: they live with the
benchmarks (``bench/bench_fisher.py``) and nothing in ``mpz`` imports them.
``tests/test_fisher.py`` loads this file by its path.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from mpz.errors import EncoderError
from mpz.fisher import Partition, _as_series, _check_k, segment_means, wssse


def paa(x: ArrayLike, k: int) -> Partition:
    """Piecewise aggregate approximation: ``k`` equal-length segments.

    ``starts[i] = floor(i * n / k)`` (Keogh et al. 2001), so lengths differ by
    at most one frame.

    Examples
    --------
    >>> paa(np.arange(5.0), 2).starts.tolist()
    [0, 2]
    """
    a = _as_series(x)
    n = a.shape[0]
    k = _check_k(k, n)
    starts = (np.arange(k, dtype=np.int64) * n) // k
    return Partition(k=k, starts=starts, means=segment_means(a, starts), wssse=wssse(a, starts))


def dft_approx(x: ArrayLike, k: int, select: str = "first") -> np.ndarray:
    """Reconstruction from ``k`` real Fourier coefficients per dimension.

    Budget: the real DFT of ``n`` samples has exactly ``n`` real degrees of
    freedom, listed as DC, Re X1, Im X1, Re X2, Im X2, ... (Nyquist has no
    imaginary part). ``select="first"`` keeps the first ``k`` of them, i.e. the
    lowest frequencies, as in the paper and Faloutsos et al. 1994;
    ``select="largest"`` keeps the ``k`` carrying the most energy, per dimension
    (their positions would also have to be stored, so its budget is larger).
    ``k`` numbers per dimension match the ``k`` segment means per dimension of
    a ``k``-partition. ``k = n`` reproduces ``x``.

    Returns
    -------
    ndarray of float64, shape (n, D) (or (n,) for 1-D input)
    """
    a0 = np.asarray(x)
    a = _as_series(x)
    n, D = a.shape
    k = _check_k(k, n)
    X = np.fft.rfft(a, axis=0)
    bins, imag = _dft_slots(n, X.shape[0])
    vals = np.where(imag[:, None], X[bins].imag, X[bins].real)  # [n, D]
    edge = (bins == 0) | ((n % 2 == 0) & (bins == n // 2))
    energy = vals ** 2 * np.where(edge, 1.0, 2.0)[:, None]
    keep = np.zeros((n, D), bool)
    if select == "first":
        keep[:k] = True
    elif select == "largest":
        order = np.argsort(-energy, axis=0, kind="stable")[:k]
        np.put_along_axis(keep, order, True, axis=0)
    else:
        raise EncoderError(f"select must be 'first' or 'largest', got {select!r}")
    Y = np.zeros_like(X)
    kv = np.where(keep, vals, 0.0)
    np.add.at(Y, bins[~imag], kv[~imag])
    np.add.at(Y, bins[imag], 1j * kv[imag])
    out = np.fft.irfft(Y, n=n, axis=0)
    return out[:, 0] if a0.ndim == 1 else out


def _dft_slots(n: int, n_bins: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``n`` real slots of an ``n``-sample real DFT: (bin, is imaginary part), in order."""
    slots = [(0, False)]
    for f in range(1, n_bins):
        slots.append((f, False))
        if not (n % 2 == 0 and f == n // 2):
            slots.append((f, True))
    assert len(slots) == n
    return np.array([s[0] for s in slots]), np.array([s[1] for s in slots])


def haar_forward(a: np.ndarray) -> np.ndarray:
    """Orthonormal Haar DWT along axis 0 (length a power of two), coarsest first."""
    c = a.copy()
    N = c.shape[0]
    out = np.empty_like(c)
    h = N
    while h > 1:
        even, odd = c[0:h:2], c[1:h:2]
        out[h // 2:h] = (even - odd) / math.sqrt(2.0)  # details of this level
        c[: h // 2] = (even + odd) / math.sqrt(2.0)
        h //= 2
    out[0] = c[0]
    return out


def haar_inverse(w: np.ndarray) -> np.ndarray:
    """Inverse of :func:`haar_forward`."""
    N = w.shape[0]
    c = w[:1].copy()
    h = 1
    while h < N:
        det = w[h:2 * h]
        nxt = np.empty((2 * h,) + w.shape[1:])
        nxt[0::2] = (c + det) / math.sqrt(2.0)
        nxt[1::2] = (c - det) / math.sqrt(2.0)
        c = nxt
        h *= 2
    return c


def haar_approx(x: ArrayLike, k: int, select: str = "first", pad: str = "edge") -> np.ndarray:
    """Reconstruction from ``k`` orthonormal Haar wavelet coefficients per dimension.

    Budget: the series is padded to the next power of two ``N`` and transformed
    with the full orthonormal Haar DWT: ``N`` coefficients per dimension, the
    scaling coefficient first, then the details from the coarsest level to the
    finest, each level in time order. ``select="first"`` (default) keeps the
    first ``k`` of them, the classic DWT reduction of Chan & Fu 1999 and what
    the paper compares against: ``k`` numbers per dimension and nothing else,
    like the ``k`` segment means of a ``k``-partition (for ``k = 2^m`` and
    ``n = N`` it is exactly PAA with ``k`` segments). ``select="largest"`` keeps
    the ``k`` largest-magnitude coefficients per dimension, which is the best
    ``k``-term Haar approximation but also needs their ``k`` positions per
    dimension, so its budget is larger. The reconstruction is cut back to
    ``n`` frames.

    ``pad="edge"`` (default) repeats the last frame; ``pad="zero"`` pads with
    zeros. We hold the last frame rather than zero-pad because a jump to zero
    would spend coefficients on an artificial step outside the series.

    Returns
    -------
    ndarray of float64, shape (n, D) (or (n,) for 1-D input)

    Examples
    --------
    >>> haar_approx([5.0, 5.0, 1.0, 1.0, 2.0, 2.0, 2.0, 2.0], 2).round(12).tolist()
    [3.0, 3.0, 3.0, 3.0, 2.0, 2.0, 2.0, 2.0]
    """
    a0 = np.asarray(x)
    a = _as_series(x)
    n, D = a.shape
    k = _check_k(k, n)
    N = 1 << max(0, (n - 1).bit_length())
    if pad == "edge":
        p = np.concatenate([a, np.repeat(a[-1:], N - n, axis=0)])
    elif pad == "zero":
        p = np.concatenate([a, np.zeros((N - n, D))])
    else:
        raise EncoderError(f"pad must be 'edge' or 'zero', got {pad!r}")
    w = haar_forward(p)
    keep = np.zeros_like(w, dtype=bool)
    if select == "largest":
        order = np.argsort(-np.abs(w), axis=0, kind="stable")[:k]
        np.put_along_axis(keep, order, True, axis=0)
    elif select == "first":
        keep[:k] = True
    else:
        raise EncoderError(f"select must be 'largest' or 'first', got {select!r}")
    out = haar_inverse(np.where(keep, w, 0.0))[:n]
    return out[:, 0] if a0.ndim == 1 else out
