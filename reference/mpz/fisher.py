"""Exact optimal partition of a motion into contiguous segments (Fisher 1958).

Contract: :func:`optimal_partitions` splits a series ``x[n, D]`` into ``k``
contiguous segments that minimise the within-segment sum of squared error
(WSSSE, Yang et al. 2016 eq. 3), for every ``k = 1..k_max`` in one dynamic
programme. The answer is exact up to float64 rounding of the segment costs
(see Notes of :func:`optimal_partitions`); ties go to the smallest split index.

Strategy: prefix sums of the globally centred data give each segment cost in
O(D). Ends are processed in blocks; for a block the costs of all earlier
starts are computed once, in parallel over starts, and fed straight into the
recurrence for every ``k`` at once. Time O(n^2 (D + k_max)), memory
O(n k_max): only the cost rows ``F[n+1, k_max]`` and back-pointers
``P[n+1, k_max]`` (int32) are kept, never an ``n x n`` matrix.

No Knuth, SMAWK or divide-and-conquer shortcut is used: for unsorted series the
cost is not quadrangle-convex (x = [1, 0, 1]: w(1,2)+w(2,3) = 1.0 > w(1,3)+w(2,2)
= 0.667), so those shortcuts are not exact here.

The module also holds the equal-length (PAA), DFT and Haar baselines of the
paper's Figs 3-7, the conversion of a :class:`mpz.Motion` to a series, the
piecewise preview and the threshold rule used by the encoder.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numba
from numba import njit, prange
import numpy as np

from mpz.errors import EncoderError

__all__ = ["Partition", "optimal_partitions", "wssse", "segment_means", "paa", "dft_approx",
           "haar_approx", "motion_series", "preview_series", "choose_k_for_threshold",
           "max_deviation"]

#: Ends processed together (one parallel region each, so fewer is better on a busy
#: machine); ``_BLOCK * k_max`` best/arg pairs per thread stay in L2.
_BLOCK = 128

#: numba's on-disk cache records the importing module's name; a doctest run that
#: imports this file as ``reference.fisher`` would leave entries that
#: ``mpz.fisher`` cannot load, so only the installed name caches.
_CACHE = __name__ == "mpz.fisher"


@dataclass(eq=False)
class Partition:
    """``k`` contiguous segments of a series and their means.

    Attributes
    ----------
    k : int
        Number of segments.
    starts : ndarray of int64, shape (k,)
        First frame of each segment; ``starts[0] == 0``, strictly increasing.
        Segment ``i`` covers frames ``starts[i] : starts[i+1]`` (the last one
        runs to the end of the series).
    means : ndarray of float64, shape (k, D)
        Mean of each segment.
    wssse : float
        Within-segment sum of squared error of ``x`` about ``means``.
    """

    k: int
    starts: np.ndarray
    means: np.ndarray
    wssse: float

    def lengths(self, n_frames: int) -> np.ndarray:
        """Frames per segment for a series of ``n_frames`` frames."""
        return np.diff(np.append(self.starts, n_frames))

    def __repr__(self) -> str:
        return f"Partition(k={self.k}, starts={self.starts.tolist()}, wssse={self.wssse:.6g})"


# -- input checks ---------------------------------------------------------------
def _as_series(x) -> np.ndarray:
    """``x`` as a finite float64 ``[n, D]`` array (1-D input is one dimension)."""
    try:
        a = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise EncoderError(f"series must be numeric, got {type(x).__name__}: {exc}") from None
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2:
        raise EncoderError(f"series must have shape (frames, dims), got {a.shape}")
    if a.shape[0] < 1 or a.shape[1] < 1:
        raise EncoderError(f"series needs at least one frame and one dimension, got {a.shape}")
    if not np.all(np.isfinite(a)):
        f = int(np.argwhere(~np.isfinite(a))[0, 0])
        raise EncoderError(f"series must be finite; frame {f} holds NaN or inf (fill gaps first)")
    return a


def _check_k(k, n: int, what: str = "k") -> int:
    if isinstance(k, (bool, np.bool_)) or not isinstance(k, (int, np.integer)):
        raise EncoderError(f"{what} must be an integer, got {k!r}")
    k = int(k)
    if k < 1:
        raise EncoderError(f"{what} must be at least 1, got {k}")
    if k > n:
        raise EncoderError(f"{what}={k} exceeds the {n} frames of the series; "
                           f"a partition has at most one segment per frame")
    return k


def _check_starts(starts, n: int) -> np.ndarray:
    s = np.asarray(starts)
    if s.ndim != 1 or s.size < 1 or not np.issubdtype(s.dtype, np.integer):
        raise EncoderError(f"starts must be a non-empty 1-D integer array, got {starts!r}")
    s = s.astype(np.int64)
    if s[0] != 0:
        raise EncoderError(f"starts[0] must be 0, got {int(s[0])}")
    if np.any(np.diff(s) <= 0) or s[-1] >= n:
        raise EncoderError(f"starts must be strictly increasing frame indices below {n}, got {s.tolist()}")
    return s


# -- segment statistics -----------------------------------------------------------
def segment_means(x, starts) -> np.ndarray:
    """Mean of each segment.

    Parameters
    ----------
    x : array_like, shape (n, D) or (n,)
    starts : array_like of int, shape (k,)
        First frame of each segment (``starts[0] == 0``, strictly increasing).

    Returns
    -------
    ndarray of float64, shape (k, D)

    Examples
    --------
    >>> segment_means([1.0, 0.0, 1.0, 5.0], [0, 3]).ravel().tolist()
    [0.6666666666666666, 5.0]
    """
    a = _as_series(x)
    s = _check_starts(starts, a.shape[0])
    lengths = np.diff(np.append(s, a.shape[0]))
    return np.add.reduceat(a, s, axis=0) / lengths[:, None]


def wssse(x, starts) -> float:
    """Within-segment sum of squared error (paper eq. 3), computed directly.

    Two-pass (means first, then squared residuals), so it is exact to rounding
    and is exactly 0 when every segment is constant.

    Examples
    --------
    >>> wssse([1.0, 0.0, 1.0], [0, 1])
    0.5
    """
    a = _as_series(x)
    s = _check_starts(starts, a.shape[0])
    return _wssse(a, s)


def _wssse(a: np.ndarray, s: np.ndarray) -> float:
    lengths = np.diff(np.append(s, a.shape[0]))
    means = np.add.reduceat(a, s, axis=0) / lengths[:, None]
    r = a - np.repeat(means, lengths, axis=0)
    return float(np.einsum("ij,ij->", r, r))


def max_deviation(x, starts) -> np.ndarray:
    """Per segment, the largest Euclidean distance of a frame from its segment mean.

    The distance is taken over the whole D-vector of a frame:
    ``max_f ||x[f] - mean[seg(f)]||_2``.

    Returns
    -------
    ndarray of float64, shape (k,)
    """
    a = _as_series(x)
    s = _check_starts(starts, a.shape[0])
    return _max_dev(a, s)


def _max_dev(a, s):
    lengths = np.diff(np.append(s, a.shape[0]))
    means = np.add.reduceat(a, s, axis=0) / lengths[:, None]
    r = a - np.repeat(means, lengths, axis=0)
    dist = np.sqrt(np.einsum("ij,ij->i", r, r))
    return np.maximum.reduceat(dist, s)


# -- the dynamic programme ----------------------------------------------------------
@njit(cache=_CACHE, fastmath={"reassoc", "contract"})
def _cost(S, Q, t, j):
    """d(t, j): squared error of frames t..j-1 about their mean, from prefix sums."""
    acc = 0.0
    for d in range(S.shape[1]):
        diff = S[j, d] - S[t, d]
        acc += diff * diff
    c = (Q[j] - Q[t]) - acc / (j - t)
    return c if c > 0.0 else 0.0  # clamp rounding below zero


@njit(cache=_CACHE, inline="always")
def _relax(Ft, d, t, bb, ba, K):
    """best[m] = min(best[m], F[t, m-1] + d(t, j)); strict < keeps the smallest t."""
    for m in range(1, K):
        v = Ft[m - 1] + d
        better = v < bb[m]
        bb[m] = v if better else bb[m]
        ba[m] = t if better else ba[m]


@njit(cache=_CACHE, parallel=True)
def _fisher_tables(S, Q, K, block, nthr):
    """F[j, m]: least WSSSE of frames 0..j-1 in m+1 segments; P[j, m]: start of the last one."""
    n = S.shape[0] - 1
    F = np.full((n + 1, K), np.inf)
    P = np.zeros((n + 1, K), np.int32)
    for J0 in range(1, n + 1, block):
        J1 = min(J0 + block, n + 1)
        B = J1 - J0
        # starts before the block: independent of the block, split over threads
        nch = min(nthr, J0)
        cb = np.full((nch, B, K), np.inf)
        ca = np.zeros((nch, B, K), np.int32)
        c0 = np.empty(B)
        for c in prange(nch):
            lo = J0 * c // nch
            hi = J0 * (c + 1) // nch
            for t in range(lo, hi):
                Ft = F[t]
                for jj in range(B):
                    d = _cost(S, Q, t, J0 + jj)
                    if t == 0:
                        c0[jj] = d  # one segment: F[j, 0] = d(0, j)
                    else:
                        _relax(Ft, d, t, cb[c, jj], ca[c, jj], K)
        # merge the threads' minima in order of t, so ties keep the smallest split
        best = cb[0]
        arg = ca[0]
        for c in range(1, nch):
            for jj in range(B):
                for m in range(1, K):
                    if cb[c, jj, m] < best[jj, m]:
                        best[jj, m] = cb[c, jj, m]
                        arg[jj, m] = ca[c, jj, m]
        # starts inside the block, in order of the end, so F[t] is final when used
        for jj in range(B):
            j = J0 + jj
            for t in range(J0, j):
                _relax(F[t], _cost(S, Q, t, j), t, best[jj], arg[jj], K)
            F[j, 0] = c0[jj]
            P[j, 0] = 0
            for m in range(1, K):
                F[j, m] = best[jj, m]
                P[j, m] = arg[jj, m]
    return F, P


def _tables(a: np.ndarray, k_max: int):
    """Prefix sums of the centred series, then the DP tables."""
    xc = a - a.mean(axis=0)  # centring keeps the prefix sums small
    n, D = xc.shape
    S = np.zeros((n + 1, D))
    np.cumsum(xc, axis=0, out=S[1:])
    Q = np.zeros(n + 1)
    np.cumsum(np.einsum("ij,ij->i", xc, xc), out=Q[1:])
    return _fisher_tables(S, Q, int(k_max), _BLOCK, numba.get_num_threads())


def _backtrack(P: np.ndarray, n: int, k: int) -> np.ndarray:
    starts = np.empty(k, np.int64)
    j = n
    for m in range(k - 1, -1, -1):
        t = int(P[j, m])
        starts[m] = t
        j = t
    return starts


def _partition(a: np.ndarray, starts: np.ndarray) -> Partition:
    lengths = np.diff(np.append(starts, a.shape[0]))
    means = np.add.reduceat(a, starts, axis=0) / lengths[:, None]
    return Partition(k=len(starts), starts=starts, means=means, wssse=_wssse(a, starts))


def optimal_partitions(x, k_max: int, ks=None) -> dict:
    """Least-WSSSE partitions into ``k`` contiguous segments, for many ``k`` at once.

    Parameters
    ----------
    x : array_like, shape (n, D) or (n,)
        Finite series, one row per frame.
    k_max : int
        Largest number of segments; ``1 <= k_max <= n``.
    ks : iterable of int, optional
        Which ``k`` to return (each ``<= k_max``); default ``1..k_max``.

    Returns
    -------
    dict of int to Partition
        Keyed by ``k``. ``wssse`` is recomputed directly from the returned
        ``starts`` (two-pass), so it is what the partition really achieves.

    Raises
    ------
    EncoderError
        For an empty or non-finite series, or ``k`` outside ``1..n``. A ``k``
        larger than the frame count is an error, not clamped: such a level
        does not exist and silently returning fewer levels would hide it.

    Notes
    -----
    Segment costs come from prefix sums of the globally centred data in float64;
    their rounding error is about ``n * eps * max_f |x_f - mean|^2``, so the
    returned WSSSE is optimal to within roughly ``2 k n eps`` times the total
    sum of squares (1e-11 of it for ``n = 10^4``, ``k = 48``).

    Examples
    --------
    >>> p = optimal_partitions([1.0, 1.0, 5.0, 5.0, 5.0, 0.0], 3)
    >>> p[3].starts.tolist(), p[3].wssse
    ([0, 2, 5], 0.0)
    >>> optimal_partitions([1.0, 0.0, 1.0], 2)[2].starts.tolist()  # tie: smallest split
    [0, 1]
    """
    a = _as_series(x)
    n = a.shape[0]
    k_max = _check_k(k_max, n, "k_max")
    if ks is None:
        ks = range(1, k_max + 1)
    ks = [_check_k(k, n) for k in ks]
    for k in ks:
        if k > k_max:
            raise EncoderError(f"k={k} exceeds k_max={k_max}")
    _, P = _tables(a, max(ks) if ks else 1)
    return {k: _partition(a, _backtrack(P, n, k)) for k in ks}


def choose_k_for_threshold(x, threshold: float, k_max: int) -> Partition:
    """The smallest ``k`` whose optimal partition keeps every frame near its segment mean.

    A frame's deviation is the Euclidean norm of ``x[f] - mean`` over the whole
    D-vector (for marker positions: over all markers at once, in the units of
    ``x``). The returned partition is the least-WSSSE partition for the
    smallest ``k`` in ``1..k_max`` whose largest deviation is ``<= threshold``.
    It is WSSSE-optimal for its ``k``, not the partition with fewest segments
    under the deviation bound (that would be a minimax problem).

    Parameters
    ----------
    x : array_like, shape (n, D)
    threshold : float
        Non-negative bound on the per-frame deviation.
    k_max : int
        Largest ``k`` tried; clamped to ``n`` (``k = n`` always meets any bound).

    Raises
    ------
    EncoderError
        If ``threshold`` is negative or not finite, or no ``k <= k_max`` meets it.

    Examples
    --------
    >>> choose_k_for_threshold([0.0, 0.1, 5.0, 5.2], 0.2, 4).starts.tolist()
    [0, 2]
    """
    a = _as_series(x)
    n = a.shape[0]
    threshold = float(threshold)
    if not math.isfinite(threshold) or threshold < 0:
        raise EncoderError(f"threshold must be finite and non-negative, got {threshold!r}")
    if isinstance(k_max, (int, np.integer)) and k_max > n:
        k_max = n
    k_max = _check_k(k_max, n, "k_max")
    _, P = _tables(a, k_max)
    worst = []
    for k in range(1, k_max + 1):
        s = _backtrack(P, n, k)
        dev = float(_max_dev(a, s).max())
        if dev <= threshold:
            return _partition(a, s)
        worst.append(dev)
    raise EncoderError(f"no partition with k <= {k_max} keeps every frame within {threshold:g} "
                       f"of its segment mean (at k={k_max} the worst frame is {worst[-1]:.6g} away); "
                       f"raise k_max or the threshold")


# -- baselines of the paper's Figs 3-7 ----------------------------------------------
def paa(x, k: int) -> Partition:
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
    return _partition(a, starts)


def dft_approx(x, k: int, select: str = "first") -> np.ndarray:
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
    nb = X.shape[0]
    # each real slot: (bin, is_imag); orthonormal energy weight of a slot
    slots = [(0, False)]
    for f in range(1, nb):
        slots.append((f, False))
        if not (n % 2 == 0 and f == n // 2):
            slots.append((f, True))
    assert len(slots) == n
    bins = np.array([s[0] for s in slots])
    imag = np.array([s[1] for s in slots])
    vals = np.where(imag[:, None], X[bins].imag, X[bins].real)  # [n, D]
    edge = (bins == 0) | ((n % 2 == 0) & (bins == n // 2))
    energy = vals ** 2 * np.where(edge, 1.0, 2.0)[:, None]
    if select == "first":
        keep = np.zeros((n, D), bool)
        keep[:k] = True
    elif select == "largest":
        order = np.argsort(-energy, axis=0, kind="stable")[:k]
        keep = np.zeros((n, D), bool)
        np.put_along_axis(keep, order, True, axis=0)
    else:
        raise EncoderError(f"select must be 'first' or 'largest', got {select!r}")
    Y = np.zeros_like(X)
    kv = np.where(keep, vals, 0.0)
    np.add.at(Y, bins[~imag], kv[~imag])
    np.add.at(Y, bins[imag], 1j * kv[imag])
    out = np.fft.irfft(Y, n=n, axis=0)
    return out[:, 0] if a0.ndim == 1 else out


def _haar_forward(a: np.ndarray) -> np.ndarray:
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


def _haar_inverse(w: np.ndarray) -> np.ndarray:
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


def haar_approx(x, k: int, select: str = "first", pad: str = "edge") -> np.ndarray:
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
    w = _haar_forward(p)
    keep = np.zeros_like(w, dtype=bool)
    if select == "largest":
        order = np.argsort(-np.abs(w), axis=0, kind="stable")[:k]
        np.put_along_axis(keep, order, True, axis=0)
    elif select == "first":
        keep[:k] = True
    else:
        raise EncoderError(f"select must be 'largest' or 'first', got {select!r}")
    out = _haar_inverse(np.where(keep, w, 0.0))[:n]
    return out[:, 0] if a0.ndim == 1 else out


# -- motions as series, previews ------------------------------------------------------
def _fill_gaps(pos: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Linear interpolation over time per marker, holding at the ends.

    Returns the filled ``[frames, markers, 3]`` array and a ``[markers]`` mask
    of markers with at least one valid sample (the others are left at zero).
    """
    frames, markers, _ = pos.shape
    out = np.zeros_like(pos)
    seen = valid.any(axis=0)
    t = np.arange(frames)
    for m in np.flatnonzero(seen):
        ok = valid[:, m]
        if ok.all():
            out[:, m] = pos[:, m]
            continue
        for c in range(3):
            out[:, m, c] = np.interp(t, t[ok], pos[ok, m, c])
    return out, seen


def motion_series(motion, space: str = "positions", root: str | None = None) -> tuple[np.ndarray, str]:
    """A motion as a finite ``[frames, D]`` series for partitioning.

    Parameters
    ----------
    motion : mpz.Motion
    space : {"positions", "angles"}
        ``"positions"``: marker positions relative to the root, flattened to
        ``D = 3 * markers`` (x, y, z of marker 0, then marker 1, ...). Gaps are
        filled first by linear interpolation per marker over time, holding the
        first/last valid sample at the ends; a marker that is a gap throughout
        becomes zeros. The root is the named marker ``root`` if given, else the
        per-frame centroid of the (filled) markers that are valid at least once.
        ``"angles"``: the joint-angle channels ``motion.angles`` of skeletal
        input (AMC, BVH), as stored.
    root : str, optional
        Marker to use as the root for ``"positions"``.

    Returns
    -------
    series : ndarray of float64, shape (frames, D)
    description : str
        What the columns are, with units.

    Raises
    ------
    EncoderError
        For an unknown space, a motion without joint angles in ``"angles"``,
        or an unknown or never-valid root marker.
    """
    if space == "angles":
        if getattr(motion, "angles", None) is None:
            raise EncoderError("this motion has no joint angles (space='angles' needs skeletal input "
                               "such as AMC/ASF or BVH); use space='positions'")
        ang = np.asarray(motion.angles, dtype=np.float64)
        if not np.all(np.isfinite(ang)):
            raise EncoderError("joint angles contain NaN or inf")
        return ang.copy(), f"joint angles, {ang.shape[1]} channels"
    if space != "positions":
        raise EncoderError(f"space must be 'positions' or 'angles', got {space!r}")
    filled, seen = _fill_gaps(motion.positions, motion.valid)
    if root is not None:
        if root not in motion.names:
            raise EncoderError(f"root marker {root!r} is not one of the {motion.n_markers} markers")
        r = motion.names.index(root)
        if not seen[r]:
            raise EncoderError(f"root marker {root!r} is a gap in every frame")
        origin = filled[:, r]
        what = f"marker {root!r}"
    elif seen.any():
        origin = filled[:, seen].mean(axis=1)
        what = "the marker centroid"
    else:
        origin = np.zeros((motion.n_frames, 3))
        what = "the origin (every marker is a gap throughout)"
    rel = filled - origin[:, None, :]
    rel[:, ~seen] = 0.0
    units = motion.units or "unitless"
    return rel.reshape(motion.n_frames, -1), f"marker positions relative to {what} ({units})"


def preview_series(starts, means, n_frames: int, mode: str = "constant") -> np.ndarray:
    """Expand segment means to a full-rate series.

    Parameters
    ----------
    starts : array_like of int, shape (k,)
    means : array_like, shape (k, D)
    n_frames : int
    mode : {"constant", "linear"}
        ``"constant"``: each frame takes its segment mean (the WSSSE model).
        ``"linear"``: linear interpolation between segment centres (frame
        ``(start + end - 1) / 2`` of each segment), holding the first mean
        before the first centre and the last after the last centre.

    Returns
    -------
    ndarray of float64, shape (n_frames, D)

    Examples
    --------
    >>> preview_series([0, 2], [[0.0], [4.0]], 4, "linear").ravel().tolist()
    [0.0, 1.0, 3.0, 4.0]
    """
    n_frames = int(n_frames)
    if n_frames < 1:
        raise EncoderError(f"n_frames must be at least 1, got {n_frames}")
    s = _check_starts(starts, n_frames)
    mu = np.asarray(means, dtype=np.float64)
    if mu.ndim == 1:
        mu = mu[:, None]
    if mu.shape[0] != s.size:
        raise EncoderError(f"{s.size} starts but {mu.shape[0]} means")
    lengths = np.diff(np.append(s, n_frames))
    if mode == "constant":
        return np.repeat(mu, lengths, axis=0)
    if mode == "linear":
        centres = s + (lengths - 1) / 2.0
        t = np.arange(n_frames, dtype=np.float64)
        return np.stack([np.interp(t, centres, mu[:, d]) for d in range(mu.shape[1])], axis=1)
    raise EncoderError(f"mode must be 'constant' or 'linear', got {mode!r}")
