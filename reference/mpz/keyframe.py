"""Key-frame residual layer (spec §4.9 base 2, §6.5): error-bounded curve fitting.

Strategy: each marker of a node is a polyline through key frames on the grid;
the decoder fills the frames between two keys by the same exact integer
interpolation as pattern de-normalisation (§6.3). The *encoder* (beyond the
paper: the paper's key frames only cut segments) grows each span greedily as
long as every sample in it stays within the error bound of the interpolated
value, so the bound holds by construction and only the keys are coded.

Payload (§4.9, base 2), four blocks in one range-coded payload:
  0. ``[n, 1, 1]`` unsigned: p_m, where member m's keys are predicted from:
     0 its own keys; 2j+1 the displacement of member j < m; 2j+2 the
     relative motion against member j < m, extrapolated (§6.5);
  1. ``[n, 1, 1]`` unsigned: K_m - 1, the key count of each member minus 1;
  2. ``[sum(K_m - 1), 1, 1]`` unsigned: d - 1 for each span length d >= 1,
     member by member; the spans of a member add up to F - 1;
  3. ``[sum(K_m), 1, 3]`` signed: each key value minus its prediction.

Markers on one body segment move together, so predicting a key from an
already decoded neighbour (rather than from the marker's own past keys)
halves the key residuals at 5 mm on real captures.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, NoReturn

from numba import njit
import numpy as np
from numpy.typing import ArrayLike, NDArray

from mpz.errors import FormatError

if TYPE_CHECKING:
    from mpz.entropy import BlockDecoder, BlockEncoder

_VALUE_LIMIT = 1 << 31


def interpolate(times: ArrayLike, values: ArrayLike, F: int) -> NDArray[np.int64]:
    """Fill ``F`` frames from key ``times`` ``[K]`` and key ``values`` ``[K, A]`` (§6.5).

    Frames between keys t_{k-1} < t < t_k get
    ``w_{k-1} + floor((2 (w_k - w_{k-1}) j + n) / (2 n))`` with n = t_k - t_{k-1},
    j = t - t_{k-1}; frame F - 1 takes the last key value.
    """
    times = np.asarray(times, np.int64)
    values = np.asarray(values, np.int64)
    if len(times) == 1:
        return np.repeat(values[:1], F, axis=0)
    n = np.diff(times)
    seg = np.repeat(np.arange(len(n)), n)
    j = np.arange(F - 1, dtype=np.int64) - np.repeat(times[:-1], n)
    a, b = values[:-1][seg], values[1:][seg]
    nn = n[seg][:, None]
    out = np.empty((F, values.shape[1]), np.int64)
    out[:-1] = a + (2 * (b - a) * j[:, None] + nn) // (2 * nn)
    out[-1] = values[-1]
    return out


@njit(cache=True)
def _predict(mode: int, k: int, times: NDArray[np.int64], w: NDArray[np.int64],
             R: NDArray[np.int64], c: int) -> int:
    """§6.5 prediction of key k (axis c) of a member; R is the reference track or unused."""
    if mode == 0:
        if k == 0:
            return 0
        if k == 1:
            return w[0, c]
        d1 = times[k] - times[k - 1]
        d0 = times[k - 1] - times[k - 2]
        return w[k - 1, c] + (2 * (w[k - 1, c] - w[k - 2, c]) * d1 + d0) // (2 * d0)
    if k == 0:
        return R[times[0], c]
    if mode == 1 or k == 1:
        return w[k - 1, c] + R[times[k], c] - R[times[k - 1], c]
    d1 = times[k] - times[k - 1]
    d0 = times[k - 1] - times[k - 2]
    r1 = w[k - 1, c] - R[times[k - 1], c]
    r0 = w[k - 2, c] - R[times[k - 2], c]
    return R[times[k], c] + r1 + (2 * (r1 - r0) * d1 + d0) // (2 * d0)


@njit(cache=True)
def _rebuild(refs: NDArray[np.int64], counts: NDArray[np.int64], spans: NDArray[np.int64],
             keys: NDArray[np.int64], F: int, out: NDArray[np.int64]) -> tuple[int, int, int]:
    """Key values from residuals (§6.5) and interpolation; returns an error code."""
    s_at = 0
    k_at = 0
    n = counts.shape[0]
    w = np.empty((F + 1, 3), np.int64)
    times = np.empty(F + 1, np.int64)
    for m in range(n):
        K = counts[m]
        p = refs[m]
        mode = 0 if p == 0 else (1 if p % 2 == 1 else 2)
        j = (p - 1) // 2 if p > 0 else 0
        if p > 0 and j >= m:
            return 3, m, j
        R = out[:, j]
        total = 0
        for k in range(K - 1):
            total += spans[s_at + k]
        if total != F - 1:
            return 1, m, total
        times[0] = 0
        for k in range(1, K):
            times[k] = times[k - 1] + spans[s_at + k - 1]
        for k in range(K):
            for c in range(3):
                v = _predict(mode, k, times, w, R, c) + keys[k_at + k, c]
                if v >= _VALUE_LIMIT or v <= -_VALUE_LIMIT:
                    return 2, m, k
                w[k, c] = v
        for k in range(1, K):
            a = times[k - 1]
            nn = times[k] - a
            for jj in range(nn):
                for c in range(3):
                    out[a + jj, m, c] = (w[k - 1, c]
                                         + (2 * (w[k, c] - w[k - 1, c]) * jj + nn) // (2 * nn))
        for c in range(3):
            out[F - 1, m, c] = w[K - 1, c]
        s_at += K - 1
        k_at += K
    return 0, 0, 0


def decode_payload(dec: BlockDecoder, F: int, n: int, *, chunk: str | None = None,
                   offset: int | None = None) -> NDArray[np.int64]:
    """Read the four blocks of a base-2 RESI payload; returns ``[F, n, 3]`` grid values."""
    def fail(msg: str) -> NoReturn:
        raise FormatError(msg, chunk=chunk, offset=offset, section="§6.5")
    refs = dec.block(n, 1, 1, signed=False)[:, 0, 0]
    bad = np.flatnonzero((refs > 0) & ((refs - 1) // 2 >= np.arange(n)))
    if bad.size:
        fail(f"member {int(bad[0])} names reference {int(refs[bad[0]])}: it must be a member "
             f"before it")
    counts = dec.block(n, 1, 1, signed=False)[:, 0, 0] + 1
    if (counts > F).any() or (F > 1 and (counts < 2).any()) or (F == 1 and (counts != 1).any()):
        fail(f"key counts must be 2..F per member (1 when F = 1), got {counts.tolist()[:8]}")
    total_spans = int((counts - 1).sum())
    spans = dec.block(total_spans, 1, 1, signed=False)[:, 0, 0] + 1
    keys = dec.block(int(counts.sum()), 1)[:, 0]
    out = np.zeros((F, n, 3), np.int64)
    code, m, detail = _rebuild(refs.astype(np.int64), counts.astype(np.int64),
                               spans.astype(np.int64), keys, F, out)
    if code == 1:
        fail(f"member {m}: key spans add up to {detail}, not F - 1 = {F - 1}")
    if code == 2:
        # checked as each w_k is computed, before it enters a later prediction (§6.5, §1.1)
        fail(f"member {m}: key value w_{detail} has |w_k| >= 2^31")
    return out


# ---------------------------------------------------------------- encoder --
@njit(cache=True)
def _span_ok(y: NDArray[np.float64], a: int, b: int, wa: NDArray[np.int64], wb: NDArray[np.int64],
             r2: float) -> bool:
    n = b - a
    for j in range(1, n):
        d2 = 0.0
        for c in range(3):
            v = wa[c] + ((2 * (wb[c] - wa[c]) * j + n) // (2 * n))
            dd = v - y[a + j, c]
            d2 += dd * dd
        if d2 > r2:
            return False
    return True


@njit(cache=True)
def _fit(y: NDArray[np.float64], radius: float, max_span: int,
         lam: float) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    T = y.shape[0]
    r2 = radius * radius
    times = np.empty(T, np.int64)
    vals = np.empty((T, 3), np.int64)
    for c in range(3):
        vals[0, c] = int(np.floor(y[0, c] + 0.5))
    times[0] = 0
    K = 1
    a = 0
    cand = np.empty(3, np.int64)
    best = np.empty(3, np.int64)
    keep = np.empty(3, np.int64)
    while a < T - 1:
        # prediction of the next key (linear extrapolation), for choosing among candidates
        b = a + 1
        good = -1
        d0 = 1
        d1 = 1
        while b < T and b - a <= max_span:
            found = False
            bestc = 1e300
            if K >= 2:
                d0 = times[K - 1] - times[K - 2]
                d1 = b - a
            lo0 = int(np.ceil(y[b, 0] - radius))
            hi0 = int(np.floor(y[b, 0] + radius))
            lo1 = int(np.ceil(y[b, 1] - radius))
            hi1 = int(np.floor(y[b, 1] + radius))
            lo2 = int(np.ceil(y[b, 2] - radius))
            hi2 = int(np.floor(y[b, 2] + radius))
            for p in range(lo0, hi0 + 1):
                for q in range(lo1, hi1 + 1):
                    for s in range(lo2, hi2 + 1):
                        dd = (p - y[b, 0]) ** 2 + (q - y[b, 1]) ** 2 + (s - y[b, 2]) ** 2
                        if dd > r2:
                            continue
                        cand[0] = p
                        cand[1] = q
                        cand[2] = s
                        if not _span_ok(y, a, b, vals[K - 1], cand, r2):
                            continue
                        cost = lam * dd
                        for c in range(3):
                            if K >= 2:
                                w1 = vals[K - 1, c]
                                w0 = vals[K - 2, c]
                                pred = w1 + (2 * (w1 - w0) * d1 + d0) // (2 * d0)
                            else:
                                pred = vals[K - 1, c]
                            cost += abs(cand[c] - pred)
                        if cost < bestc:
                            bestc = cost
                            found = True
                            best[0] = p
                            best[1] = q
                            best[2] = s
            if not found:
                break
            good = b
            keep[0] = best[0]
            keep[1] = best[1]
            keep[2] = best[2]
            b += 1
        if good < 0:   # cannot happen: the nearest grid point always qualifies for b = a + 1
            good = a + 1
            for c in range(3):
                keep[c] = int(np.floor(y[good, c] + 0.5))
        times[K] = good
        vals[K, 0] = keep[0]
        vals[K, 1] = keep[1]
        vals[K, 2] = keep[2]
        K += 1
        a = good
    return times[:K], vals[:K]


def fit(y: ArrayLike, radius: float, max_span: int = 256,
        lam: float = 1.0) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Key frames of one track ``y[T, 3]`` (grid units) with every sample within ``radius``.

    Returns the key times ``[K]`` and the key values ``[K, 3]`` on the grid.
    """
    if radius < np.sqrt(3.0) / 2:
        raise ValueError("radius < sqrt(3)/2 cannot guarantee a grid point")
    return _fit(np.ascontiguousarray(y, dtype=np.float64), float(radius), int(max_span), float(lam))


@njit(cache=True)
def _residuals(mode: int, times: NDArray[np.int64], w: NDArray[np.int64],
               R: NDArray[np.int64]) -> NDArray[np.int64]:
    e = np.empty_like(w)
    for k in range(w.shape[0]):
        for c in range(3):
            e[k, c] = w[k, c] - _predict(mode, k, times, w, R, c)
    return e


@njit(cache=True)
def _cost(e: NDArray[np.int64]) -> float:
    total = 0.0
    for k in range(e.shape[0]):
        for c in range(3):
            total += np.log2(1.0 + abs(e[k, c]))
    return total


def encode_blocks(enc: BlockEncoder, y: NDArray[np.float64], radius: float,
                  max_span: int = 256) -> NDArray[np.int64]:
    """Fit every member of ``y[T, n, 3]`` and code the four blocks; returns the grid values.

    Each member's keys are predicted from whichever earlier member (or none)
    gives the smallest residuals, by the proxy sum(log2(1 + |e|)).
    """
    T, n, _ = y.shape
    refs: list[int] = []
    counts: list[int] = []
    spans: list[NDArray[np.int64]] = []
    keys: list[NDArray[np.int64]] = []
    out = np.zeros((T, n, 3), np.int64)
    for m in range(n):
        times, w = fit(y[:, m], radius, max_span)
        best = (_cost(_residuals(0, times, w, out[:, 0])), 0)
        for j in range(m):
            for mode in (1, 2):
                c = _cost(_residuals(mode, times, w, out[:, j]))
                if c < best[0]:
                    best = (c, 2 * j + mode)
        p = best[1]
        mode = 0 if p == 0 else (1 if p % 2 else 2)
        e = _residuals(mode, times, w, out[:, (p - 1) // 2 if p else 0])
        refs.append(p)
        counts.append(len(w) - 1)
        spans.append(np.diff(times) - 1)
        keys.append(e)
        out[:, m] = interpolate(times, w, T)
    enc.block(np.array(refs, np.int64).reshape(-1, 1, 1), signed=False)
    enc.block(np.array(counts, np.int64).reshape(-1, 1, 1), signed=False)
    enc.block(np.concatenate(spans).reshape(-1, 1, 1) if spans else np.zeros((0, 1, 1), np.int64),
              signed=False)
    enc.block(np.concatenate(keys)[:, None, :])
    return out
