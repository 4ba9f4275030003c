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

The module also holds the conversion of a :class:`mpz.Motion` to a series, the
piecewise preview and the threshold rule used by the encoder. The equal-length
(PAA), DFT and Haar baselines of the paper's Figs 3-7 are research code and
live with the benchmarks, in ``bench/baselines.py``.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
import math
import os
import threading
import types
from typing import TYPE_CHECKING, Any, cast

import numba
from numba import prange
import numpy as np
from numpy.typing import ArrayLike, NDArray

from mpz._jit import njit
from mpz.errors import EncoderError

if TYPE_CHECKING:
    from mpz.motion import Motion

__all__ = ["Partition", "optimal_partitions", "threshold_partition", "summary_partitions",
           "block_length",
           "summary_check", "check_table", "block_means", "EXACT_MAX_FRAMES", "MAX_TABLE",
           "wssse", "segment_means", "motion_series", "preview_series",
           "choose_k_for_threshold", "max_deviation"]

#: Ends processed together (one parallel region each, so fewer is better on a busy
#: machine); ``_BLOCK * k_max`` best/arg pairs per thread stay in L2.
_BLOCK = 128

#: frames up to which a summary (an ``smry``/``smrc`` chunk, an index's levels) is the exact
#: optimal partition; beyond, its cuts fall on blocks of frames (:func:`summary_partitions`).
#: The dynamic programme is quadratic in the frame count: about 10 s at 2^14 frames of 41
#: markers on one core, half an hour for a 30-minute capture (216,000 frames)
EXACT_MAX_FRAMES = 16384
#: entries of the dynamic programme's tables, (rows + 1) x k_max of 12 bytes (the least
#: WSSSE in float64, the back-pointer in int32), at most: 403 MB. More is refused
#: (:func:`check_table`): k = 20,000 on 40,000 frames (13,334 blocks) took 2.4 GB and six
#: minutes (a QA run, stop 38); at 16,384 rows this allows k up to 2,047
MAX_TABLE = 1 << 25

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
    starts: NDArray[np.int64]
    means: NDArray[np.float64]
    wssse: float

    def lengths(self, n_frames: int) -> NDArray[np.int64]:
        """Frames per segment for a series of ``n_frames`` frames."""
        return np.diff(np.append(self.starts, n_frames))

    def __repr__(self) -> str:
        return f"Partition(k={self.k}, starts={self.starts.tolist()}, wssse={self.wssse:.6g})"


# -- input checks ---------------------------------------------------------------
def _as_series(x: ArrayLike) -> NDArray[np.float64]:
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


def _check_k(k: object, n: int, what: str = "k") -> int:
    """``k`` as an int in ``1..n``; anything else is an :class:`EncoderError`."""
    if isinstance(k, (bool, np.bool_)) or not isinstance(k, (int, np.integer)):
        raise EncoderError(f"{what} must be an integer, got {k!r}")
    k = int(k)
    if k < 1:
        raise EncoderError(f"{what} must be at least 1, got {k}")
    if k > n:
        raise EncoderError(f"{what}={k} exceeds the {n} frames of the series; "
                           f"a partition has at most one segment per frame")
    return k


def _check_starts(starts: ArrayLike, n: int) -> NDArray[np.int64]:
    """``starts`` as int64 segment starts: 0 first, strictly increasing, below ``n``."""
    s = np.asarray(starts)
    if s.ndim != 1 or s.size < 1 or not np.issubdtype(s.dtype, np.integer):
        raise EncoderError(f"starts must be a non-empty 1-D integer array, got {starts!r}")
    s = s.astype(np.int64)
    if s[0] != 0:
        raise EncoderError(f"starts[0] must be 0, got {int(s[0])}")
    if np.any(np.diff(s) <= 0) or s[-1] >= n:
        raise EncoderError(f"starts must be strictly increasing frame indices below {n}, "
                           f"got {s.tolist()}")
    return s


# -- segment statistics -----------------------------------------------------------
def segment_means(x: ArrayLike, starts: ArrayLike) -> NDArray[np.float64]:
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


def wssse(x: ArrayLike, starts: ArrayLike) -> float:
    """Within-segment sum of squared error (paper eq. 3), computed directly.

    Two-pass (means first, then squared residuals), so it is exact to rounding: a
    constant segment gives 0 when its mean is exact (a run of 0.1 gives about 1e-32, the
    rounding of the mean), never the cancellation of a one-pass sum of squares.

    Examples
    --------
    >>> wssse([1.0, 0.0, 1.0], [0, 1])
    0.5
    """
    a = _as_series(x)
    s = _check_starts(starts, a.shape[0])
    return _wssse(a, s)


def _wssse(a: NDArray[np.float64], s: NDArray[np.int64]) -> float:
    lengths = np.diff(np.append(s, a.shape[0]))
    means = np.add.reduceat(a, s, axis=0) / lengths[:, None]
    r = a - np.repeat(means, lengths, axis=0)
    return float(np.einsum("ij,ij->", r, r))


def max_deviation(x: ArrayLike, starts: ArrayLike) -> NDArray[np.float64]:
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


def _max_dev(a: NDArray[np.float64], s: NDArray[np.int64]) -> NDArray[np.float64]:
    lengths = np.diff(np.append(s, a.shape[0]))
    means = np.add.reduceat(a, s, axis=0) / lengths[:, None]
    r = a - np.repeat(means, lengths, axis=0)
    dist = np.sqrt(np.einsum("ij,ij->i", r, r))
    return np.maximum.reduceat(dist, s)


# -- the dynamic programme ----------------------------------------------------------
@njit(cache=_CACHE, fastmath={"reassoc", "contract"}, ship=True)
def _cost(S: NDArray[np.float64], Q: NDArray[np.float64], t: int, j: int) -> float:
    """d(t, j): squared error of frames t..j-1 about their mean, from prefix sums."""
    acc = 0.0
    for d in range(S.shape[1]):
        diff = S[j, d] - S[t, d]
        acc += diff * diff
    c = (Q[j] - Q[t]) - acc / (j - t)
    return c if c > 0.0 else 0.0  # clamp rounding below zero


@njit(cache=_CACHE, inline="always")
def _relax(Ft: NDArray[np.float64], d: float, t: int, bb: NDArray[np.float64],
           ba: NDArray[np.int32], K: int) -> None:
    """best[m] = min(best[m], F[t, m-1] + d(t, j)); strict < keeps the smallest t."""
    for m in range(1, K):
        v = Ft[m - 1] + d
        better = v < bb[m]
        bb[m] = v if better else bb[m]
        ba[m] = t if better else ba[m]


def _fisher_tables_py(S: NDArray[np.float64], Q: NDArray[np.float64], K: int, block: int,
                      nthr: int) -> tuple[NDArray[np.float64], NDArray[np.int32]]:
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


def _named(fn: Callable[..., Any], name: str) -> Callable[..., Any]:
    """``fn`` under another name: numba's cache files are named by a function's qualified
    name and line, and do not tell a parallel compile from a serial one."""
    out = types.FunctionType(fn.__code__, fn.__globals__, name, fn.__defaults__,
                             fn.__closure__)
    out.__qualname__ = name
    return out


# shipped (mpz._jit): a first --summary compiled them for 2.5-4 s (QA, stop 62); a kernel
# cached by one threading layer (omp) loads under another (workqueue), the same tables
_fisher_tables = njit(cache=_CACHE, parallel=True, ship=True)(
    _named(_fisher_tables_py, "_fisher_tables"))
#: the same kernel compiled without threads (``prange`` is ``range``): the same tables, as
#: the chunks' minima merge in order of t
_fisher_tables_serial = njit(cache=_CACHE, ship=True)(
    _named(_fisher_tables_py, "_fisher_tables_serial"))

#: set in a child made by fork(): there the tables are made by the serial kernel. A parent
#: whose parallel kernel had started GNU OpenMP's threads (numba's default layer here)
#: forks children that cannot start them: numba terminates the child ("fork() called from
#: a process already using GNU OpenMP"), and a multiprocessing.Pool waited for it for ever
#: (an ML pipeline's QA run of stop 51)
_FORKED = False
#: one parallel kernel at a time: numba's workqueue layer (NUMBA_THREADING_LAYER=workqueue,
#: fork-safe) aborts the process when two threads enter it at once (the same QA run), and
#: two at once gain nothing on the cores the first already uses
_PARALLEL = threading.Lock()


def _after_fork_in_child() -> None:
    global _FORKED
    _FORKED = True


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_after_fork_in_child)


def check_table(rows: int, k_max: int) -> None:
    """Refuse a partition of ``rows`` frames (or blocks) into up to ``k_max`` segments whose
    tables would pass :data:`MAX_TABLE` entries, naming the largest k that fits."""
    if (rows + 1) * k_max > MAX_TABLE:
        raise EncoderError(
            f"a partition of {rows} frames (or blocks of frames) into up to {k_max} segments "
            f"needs tables of {rows + 1} x {k_max} = {(rows + 1) * k_max:,} entries of 12 "
            f"bytes, more than the {MAX_TABLE:,} ({MAX_TABLE * 12 / 1e6:.0f} MB) allowed; at "
            f"most k = {MAX_TABLE // (rows + 1)} here (fewer segments summarise as well)")


def _tables(a: NDArray[np.float64], k_max: int) -> tuple[NDArray[np.float64], NDArray[np.int32]]:
    """Prefix sums of the centred series, then the DP tables (:func:`check_table` first)."""
    check_table(a.shape[0], int(k_max))
    xc = a - a.mean(axis=0)  # centring keeps the prefix sums small
    n, D = xc.shape
    S = np.zeros((n + 1, D))
    np.cumsum(xc, axis=0, out=S[1:])
    Q = np.zeros(n + 1)
    np.cumsum(np.einsum("ij,ij->i", xc, xc), out=Q[1:])
    if _FORKED:               # numba.get_num_threads() would start the threads too
        return _fisher_tables_serial(S, Q, int(k_max), _BLOCK, 1)
    with _PARALLEL:
        return _fisher_tables(S, Q, int(k_max), _BLOCK, numba.get_num_threads())


def _backtrack(P: NDArray[np.int32], n: int, k: int) -> NDArray[np.int64]:
    """Starts of the best ``k``-partition of frames ``0..n-1`` from the back-pointers ``P``."""
    starts = np.empty(k, np.int64)
    j = n
    for m in range(k - 1, -1, -1):
        t = int(P[j, m])
        starts[m] = t
        j = t
    return starts


def _partition(a: NDArray[np.float64], starts: NDArray[np.int64]) -> Partition:
    lengths = np.diff(np.append(starts, a.shape[0]))
    means = np.add.reduceat(a, starts, axis=0) / lengths[:, None]
    return Partition(k=len(starts), starts=starts, means=means, wssse=_wssse(a, starts))


def optimal_partitions(x: ArrayLike, k_max: int,
                       ks: Iterable[int] | None = None) -> dict[int, Partition]:
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


def summary_check(n: int, ks: Iterable[int]) -> None:
    """Refuse, before any work, summary levels ``ks`` of a motion of ``n`` frames that
    :func:`summary_partitions` would refuse for the size of its tables."""
    b = block_length(n)
    rows = -(-int(n) // b)
    top = max((min(int(k), rows) for k in ks), default=0)
    if top:
        check_table(rows, top)


def block_length(n: int, max_frames: int | None = None) -> int:
    """The block length the programme uses for ``n`` frames (summaries:
    :func:`summary_partitions`; the encoder's optimal segmentation): 1, exact, up to
    ``max_frames`` (default :data:`EXACT_MAX_FRAMES`) frames, else ``ceil(n / max_frames)``."""
    top = EXACT_MAX_FRAMES if max_frames is None else _check_k(max_frames, 1 << 62,
                                                                "max_frames")
    return max(1, -(-int(n) // top))


def block_means(a: NDArray[np.float64], b: int) -> NDArray[np.float64]:
    """The means of consecutive blocks of ``b`` rows of ``a`` (the last may be shorter)."""
    at = np.arange(0, a.shape[0], b)
    return np.add.reduceat(a, at, axis=0) / np.diff(np.append(at, a.shape[0]))[:, None]


def summary_partitions(x: ArrayLike, ks: Iterable[int],
                       max_frames: int | None = None) -> tuple[int, dict[int, Partition]]:
    """The partitions a summary holds for the segment counts ``ks``: ``(b, {k: Partition})``.

    Up to ``max_frames`` (default :data:`EXACT_MAX_FRAMES`) frames, ``b = 1`` and each is
    the least-WSSSE partition (:func:`optimal_partitions`), k lowered to the frame count.
    Beyond, the dynamic programme runs on the means of blocks of ``b = ceil(n /
    max_frames)`` frames (every block but the last of ``b`` frames, all weighed equally),
    k lowered to the block count: the cuts fall on block boundaries, and each partition's
    means and WSSSE are computed on every frame. Why: the exact programme is quadratic in
    the frame count.

    Examples
    --------
    >>> b, p = summary_partitions(np.repeat([0.0, 4.0, 1.0], 4), (2, 9), max_frames=6)
    >>> b, sorted(p), p[2].starts.tolist(), p[2].wssse
    (2, [2, 6], [0, 4], 18.0)
    """
    a = _as_series(x)
    n = a.shape[0]
    counts = [_check_k(k, 1 << 62) for k in ks]      # integers >= 1; lowered below
    b = block_length(n, max_frames)
    if b == 1:
        levels = sorted({min(k, n) for k in counts})
        return 1, optimal_partitions(a, max(levels, default=1), ks=levels)
    blocks = block_means(a, b)
    levels = sorted({min(k, blocks.shape[0]) for k in counts})
    parts = optimal_partitions(blocks, max(levels, default=1), ks=levels)
    return b, {k: _partition(a, parts[k].starts.astype(np.int64) * b) for k in levels}


def choose_k_for_threshold(x: ArrayLike, threshold: float, k_max: int) -> Partition:
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
    part, dev, threshold, k_max = _threshold_partition(a, threshold, k_max)
    if dev > threshold:
        raise EncoderError(f"no partition with k <= {k_max} keeps every frame within "
                           f"{threshold:g} of its segment mean (at k={k_max} the worst frame "
                           f"is {dev:.6g} away); raise k_max or the threshold")
    return part


def threshold_partition(x: ArrayLike, threshold: float, k_max: int) -> Partition:
    """:func:`choose_k_for_threshold`'s partition, or, where no ``k <= k_max`` keeps every
    frame within ``threshold``, the least-WSSSE one of ``k_max`` segments (from the same
    tables: the programme runs once). ``k_max`` is clamped to the frame count."""
    return _threshold_partition(_as_series(x), threshold, k_max)[0]


def _threshold_partition(a: NDArray[np.float64], threshold: object,
                         k_max: object) -> tuple[Partition, float, float, int]:
    """The first k whose partition's worst frame is within ``threshold``, else k_max's:
    (partition, its worst frame's deviation, the threshold and k_max as checked)."""
    n = a.shape[0]
    thr = float(threshold)      # type: ignore[arg-type]  # anything float() takes
    if not math.isfinite(thr) or thr < 0:
        raise EncoderError(f"threshold must be finite and non-negative, got {threshold!r}")
    if isinstance(k_max, (int, np.integer)) and k_max > n:
        k_max = n
    top = _check_k(k_max, n, "k_max")
    _, P = _tables(a, top)
    for k in range(1, top + 1):
        s = _backtrack(P, n, k)
        dev = float(_max_dev(a, s).max())
        if dev <= thr or k == top:
            return _partition(a, s), dev, thr, top
    raise AssertionError("unreachable: k_max >= 1")


# -- motions as series, previews ------------------------------------------------------
def _fill_gaps(pos: NDArray[np.float64],
               valid: NDArray[np.bool_]) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Linear interpolation over time per marker, holding at the ends.

    Returns the filled ``[frames, markers, 3]`` array and a ``[markers]`` mask
    of markers with at least one valid sample (the others are left at zero).
    """
    frames, markers, _ = pos.shape
    out = np.zeros_like(pos)
    seen = cast("NDArray[np.bool_]", valid.any(axis=0))  # 2-D in, so an array out
    t = np.arange(frames)
    for m in np.flatnonzero(seen):
        ok = valid[:, m]
        if ok.all():
            out[:, m] = pos[:, m]
            continue
        for c in range(3):
            out[:, m, c] = np.interp(t, t[ok], pos[ok, m, c])
    return out, seen


def motion_series(motion: Motion, space: str = "positions",
                  root: str | None = None) -> tuple[NDArray[np.float64], str]:
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
            # worded for both callers: space="angles" in Python, --space angles in the CLI
            raise EncoderError("this motion has no joint angles: the angles space needs "
                               "skeletal input (AMC/ASF or BVH); use the positions space")
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


def preview_series(starts: ArrayLike, means: ArrayLike, n_frames: int,
                   mode: str = "constant") -> NDArray[np.float64]:
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
