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

from collections.abc import Callable, Sequence
from concurrent.futures import Executor, Future
from dataclasses import dataclass
import functools
import math
from typing import TYPE_CHECKING, NoReturn, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mpz._jit import njit
from mpz.errors import FormatError
from mpz.format import KEY_VALUE_LIMIT

if TYPE_CHECKING:
    from mpz.entropy import BlockDecoder, BlockEncoder

_T = TypeVar("_T")
#: the key values are searched within this radius (grid steps) when a larger one is given:
#: :func:`_fit` lists every grid point of the ball, (2r)^3 of them, so a radius of 350
#: (a grid step 10^7 times finer than the bound, the scale g at its cap of 65535) would
#: allocate 11 GB. Every sample is then within the smaller radius, so within the given
#: one too. The encoder's own radii stay below 2 sqrt(3) = 3.46 while g < 65535 (key
#: frames use g // 2 steps, per-sample layers g: g = 2 or 3 with key frames on g = 1),
#: and are then unchanged
MAX_RADIUS = 4.0


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


@njit(cache=True, inline="always")
def _predict_key(mode: int, k: int, tk: int, t1: int, t2: int, w1: int, w2: int,
                 R: NDArray[np.int64] | NDArray[np.int32], c: int) -> int:
    """§6.5 prediction of key k (axis c) of a member at time ``tk``, from the two keys
    before it (times t1 = t_{k-1}, t2 = t_{k-2}, values w1, w2 on axis c, where they
    exist); R is the reference member's track ``[F, 3]`` (unused for mode 0).

    Inlined into its callers before typing: called as a kernel of its own it was
    compiled once per literal argument type, three times on the first decode (issue 15.2)."""
    if mode == 0:
        if k == 0:
            return 0
        if k == 1:
            return w1
        d1 = tk - t1
        d0 = t1 - t2
        return w1 + (2 * (w1 - w2) * d1 + d0) // (2 * d0)
    if k == 0:
        return R[tk, c]
    if mode == 1 or k == 1:
        return w1 + R[tk, c] - R[t1, c]
    d1 = tk - t1
    d0 = t1 - t2
    r1 = w1 - R[t1, c]
    r0 = w2 - R[t2, c]
    return R[tk, c] + r1 + (2 * (r1 - r0) * d1 + d0) // (2 * d0)


@njit(cache=True)
def _predict(mode: int, k: int, times: NDArray[np.int64], w: NDArray[np.int64],
             R: NDArray[np.int64] | NDArray[np.int32], c: int) -> int:
    """:func:`_predict_key` for key k of a member whose times and values are all known."""
    t1 = times[k - 1] if k >= 1 else 0
    t2 = times[k - 2] if k >= 2 else 0
    w1 = w[k - 1, c] if k >= 1 else 0
    w2 = w[k - 2, c] if k >= 2 else 0
    return _predict_key(mode, k, times[k], t1, t2, w1, w2, R, c)


@njit(cache=True)
def _mark_keys(counts: NDArray[np.int64], spans: NDArray[np.int64], F: int,
               bits: NDArray[np.uint8]) -> tuple[int, int, int]:
    """Check each member's spans (``d - 1``) and mark its key times in ``bits[m]`` (one bit
    per frame, little-endian in each byte); returns (1, member, sum) for spans that do not
    add up to F - 1, else (0, 0, 0). A member's times are marked only after its check
    (§6.5, §1.1)."""
    at = 0
    for m in range(counts.shape[0]):
        K = counts[m]
        total = 0
        for k in range(K - 1):
            total += spans[at + k] + 1
        # R-6.5-3
        if total != F - 1:
            return 1, m, total
        t = 0
        bits[m, 0] |= 1
        for k in range(K - 1):
            t += spans[at + k] + 1
            bits[m, t >> 3] |= np.uint8(1 << (t & 7))
        at += K - 1
    return 0, 0, 0


@njit(cache=True)
def _rebuild(refs: NDArray[np.int64], counts: NDArray[np.int64], bits: NDArray[np.uint8],
             keys: NDArray[np.int64], F: int, out: NDArray[np.int64],
             cols: NDArray[np.int64]) -> tuple[int, int, int]:
    """Key values from residuals (§6.5) and their interpolation, member m into
    ``out[:, cols[m]]``; returns an error code (0: none; 2: key value k, the detail, has
    |w_k| >= 2^31; 3: the member names a reference that is not an earlier member, which
    the caller has refused first), the member and a detail, which
    is max |w_k| over every key value when the code is 0: the largest magnitude of the
    whole layer, since each interpolated value lies between its two keys (§6.7 rule 1
    without reading the layer again: that was 12 % of decoding cmu_135_02).

    Streaming: only the last three key times and values are held, so the scratch memory
    does not grow with F (spec §8)."""
    k_at = 0
    peak = 0
    n = counts.shape[0]
    wk = np.empty(3, np.int64)
    w1 = np.empty(3, np.int64)
    w2 = np.empty(3, np.int64)
    for c in range(3):                  # np.empty: np.zeros is one more compile
        w1[c] = 0
        w2[c] = 0
    for m in range(n):
        K = counts[m]
        p = refs[m]
        mode = 0 if p == 0 else (1 if p % 2 == 1 else 2)
        j = (p - 1) // 2 if p > 0 else 0
        # R-6.5-1
        if p > 0 and j >= m:            # checked by the caller first: a guard of memory
            return 3, m, j
        R = out[:, cols[j]]
        col = cols[m]
        t1 = 0
        t2 = 0
        tk = 0
        for k in range(K):
            if k > 0:                       # the next marked frame (the spans add up)
                tk = t1 + 1
                while not (bits[m, tk >> 3] >> (tk & 7)) & 1:
                    tk += 1
            for c in range(3):
                v = _predict_key(mode, k, tk, t1, t2, w1[c], w2[c], R, c) + keys[k_at + k, c]
                if v >= KEY_VALUE_LIMIT or v <= -KEY_VALUE_LIMIT:  # R-6.5-4
                    return 2, m, k
                wk[c] = v
                if abs(v) > peak:
                    peak = abs(v)
            if k > 0:                       # frames t_{k-1} .. t_k - 1
                nn = tk - t1
                for jj in range(nn):
                    for c in range(3):
                        out[t1 + jj, col, c] = w1[c] + (2 * (wk[c] - w1[c]) * jj + nn) // (2 * nn)
            for c in range(3):
                w2[c] = w1[c]
                w1[c] = wk[c]
            t2 = t1
            t1 = tk
        for c in range(3):
            out[F - 1, col, c] = w1[c]
        k_at += K
    return 0, 0, peak


def decode_payload(dec: BlockDecoder, F: int, n: int, *, chunk: str | None = None,
                   offset: int | None = None, out: NDArray[np.int64] | None = None,
                   columns: ArrayLike | None = None) -> NDArray[np.int64]:
    """Read the four blocks of a base-2 RESI payload; returns ``[F, n, 3]`` grid values
    (:func:`decode_payload_peak` without the peak)."""
    return decode_payload_peak(dec, F, n, chunk=chunk, offset=offset, out=out,
                               columns=columns)[0]


def decode_payload_peak(dec: BlockDecoder, F: int, n: int, *, chunk: str | None = None,
                        offset: int | None = None, out: NDArray[np.int64] | None = None,
                        columns: ArrayLike | None = None) -> tuple[NDArray[np.int64], int]:
    """Read the four blocks of a base-2 RESI payload; returns ``[F, n, 3]`` grid values and
    their largest magnitude (the largest key value's, :func:`_rebuild`).

    With ``out`` (``[F, M, 3]``) and ``columns`` (n indices), member m is written to
    ``out[:, columns[m]]`` instead, and ``out`` is returned: the decoder rebuilds the
    members straight into q. Memory (spec §8): the key times are kept as one bit per
    frame and member, and the span block is freed before the key block is decoded.
    """
    def fail(msg: str) -> NoReturn:
        raise FormatError(msg, chunk=chunk, offset=offset, section="§6.5")
    refs = dec.block(n, 1, 1, signed=False)[:, 0, 0]
    bad = np.flatnonzero((refs > 0) & ((refs - 1) // 2 >= np.arange(n)))
    if bad.size:  # R-6.5-1
        fail(f"member {int(bad[0])} names reference {int(refs[bad[0]])}: it must be a member "
             f"before it")
    counts = dec.block(n, 1, 1, signed=False)[:, 0, 0] + 1
    # R-6.5-2
    if (counts > F).any() or (F > 1 and (counts < 2).any()) or (F == 1 and (counts != 1).any()):
        fail(f"key counts must be 2..F per member (1 when F = 1), got {counts.tolist()[:8]}")
    total_spans = int((counts - 1).sum())
    spans = dec.block(total_spans, 1, 1, signed=False).reshape(-1)     # d - 1
    bits = np.zeros((n, (F + 7) // 8), np.uint8)
    code, m, detail = _mark_keys(counts.astype(np.int64), spans, F, bits)
    if code == 1:  # R-6.5-3
        fail(f"member {m}: key spans add up to {detail}, not F - 1 = {F - 1}")
    del spans
    keys = dec.block(int(counts.sum()), 1)[:, 0]
    if out is None:
        out = np.zeros((F, n, 3), np.int64)
        cols = np.arange(n, dtype=np.int64)
    else:
        cols = np.asarray(columns, dtype=np.int64)
    code, m, detail = _rebuild(refs.astype(np.int64), counts.astype(np.int64), bits, keys, F,
                               out, cols)
    if code == 2:  # R-6.5-4
        # checked as each w_k is computed, before it enters a later prediction (§6.5, §1.1)
        fail(f"member {m}: key value w_{detail} has |w_k| >= 2^31")
    if code == 3:       # the references were checked above: a defect, never a bad file
        raise AssertionError(f"_rebuild: member {m} references member {detail}, not an "
                             "earlier one, after the check of the references")
    return out, int(detail)


# ---------------------------------------------------------------- encoder --
@njit(cache=True, inline="always")
def _hint_terms(y: NDArray[np.float64], h: int, a: int, b: int, wa: NDArray[np.int64],
                lo: NDArray[np.int64], hi: NDArray[np.int64], hx: NDArray[np.float64]) -> float:
    """For :func:`_fit`'s span a..b and a frame a < h < b: ``hx[c, w - lo[c]]`` = the square
    of the §6.5 interpolation of key value w (axis c) at h minus y[h, c], for every w of the
    candidate box ``lo..hi``: the very terms (same bits) a candidate's check at h adds, in
    axis order. Returns the least sum of one term per axis, added in that order: rounding is
    monotone, so when it exceeds radius^2, every candidate of the box fails at h.
    floor((2 (w - wa) j + n) / 2n) steps with w by its remainder: one division per axis."""
    n = b - a
    j = h - a
    D = 2 * n
    least = 0.0
    for c in range(3):
        num = 2 * (lo[c] - wa[c]) * j + n
        qv = num // D
        rv = num - qv * D
        mc = math.inf
        for w in range(lo[c], hi[c] + 1):
            e = wa[c] + qv - y[h, c]
            hx[c, w - lo[c]] = e * e
            if e * e < mc:
                mc = e * e
            rv += 2 * j                    # 0 < 2j < D: at most one carry
            if rv >= D:
                rv -= D
                qv += 1
        least = mc if c == 0 else least + mc
    return least


@njit(cache=True, nogil=True)
def _fit(y: NDArray[np.float64], radius: float, max_span: int, lam: float,
         track: NDArray[np.int32]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Greedy key frames (see :func:`fit`). For each end frame b the key value is, among the
    grid points within ``radius`` of y[b] whose span from the previous key keeps every frame
    within ``radius``, the one of least cost ``lam |w - y[b]|^2 + |w - pred|_1`` (on a tie:
    the first in (x, y, z) order); the span grows while such a point exists. ``track``
    ``[T, 3]`` receives the keys' §6.5 interpolation, the decoded track (here, where the
    GIL is released, rather than by :func:`interpolate`: issue 15.1).

    Speed (issue 15): the candidates of b are listed with their costs first and the span
    check, O(b - a), is made for the cheapest first; only when it fails are the others
    checked, in list order, skipping every candidate whose cost cannot beat the cheapest
    one that passed so far (no sort: at the end of a span all of them fail). A check tries
    one frame first: the frame that failed last if it lies in the span, else b - 1. Its
    terms for the whole candidate box come from :func:`_hint_terms`, which also shows
    when every candidate fails there: then the span ends without listing them (at the
    default bound, 90 % of span ends; the fit of cmu_135_02 takes 103 -> 68 ms). The keys
    are the same as checking every candidate and taking the least (cost, list position)
    that passes: which frame is checked first changes only how soon a failing candidate
    is dropped."""
    T = y.shape[0]
    r2 = radius * radius
    times = np.empty(T, np.int64)
    vals = np.empty((T, 3), np.int64)
    for c in range(3):
        vals[0, c] = math.floor(y[0, c] + 0.5)
    times[0] = 0
    K = 1
    a = 0
    side = math.floor(2.0 * radius) + 2            # grid points per axis in the box
    cap = side * side * side
    cands = np.empty((cap, 3), np.int64)
    costs = np.empty(cap, np.float64)
    keep = np.empty(3, np.int64)
    pred = np.empty(3, np.int64)
    dzz = np.empty(side, np.float64)
    azz = np.empty(side, np.int64)
    hx = np.empty((3, side), np.float64)
    blo = np.empty(3, np.int64)
    bhi = np.empty(3, np.int64)
    hint = -1
    while a < T - 1:
        b = a + 1
        good = -1
        wa = vals[K - 1]
        while b < T and b - a <= max_span:
            # prediction of the next key (linear extrapolation), for choosing among candidates
            for c in range(3):
                if K >= 2:
                    d0 = times[K - 1] - times[K - 2]
                    d1 = b - a
                    w1 = vals[K - 1, c]
                    w0 = vals[K - 2, c]
                    pred[c] = w1 + (2 * (w1 - w0) * d1 + d0) // (2 * d0)
                else:
                    pred[c] = vals[K - 1, c]
            blo[0], bhi[0] = math.ceil(y[b, 0] - radius), math.floor(y[b, 0] + radius)
            blo[1], bhi[1] = math.ceil(y[b, 1] - radius), math.floor(y[b, 1] + radius)
            blo[2], bhi[2] = math.ceil(y[b, 2] - radius), math.floor(y[b, 2] + radius)
            # a frame between the keys that may fail every candidate at once: the one that
            # failed last if it lies in this span, else b - 1. th: the frame whose terms
            # are in hx (-1: none, when b = a + 1 leaves no frame to check)
            th = -1
            if b - a >= 2:
                h = hint if a < hint < b else b - 1
                if _hint_terms(y, h, a, b, wa, blo, bhi, hx) > r2:
                    break                            # every candidate fails at h
                th = h
            lo0, hi0, lo1, hi1, lo2, hi2 = blo[0], bhi[0], blo[1], bhi[1], blo[2], bhi[2]
            nc = 0
            i0 = -1
            bestc = 1e300
            for s in range(lo2, hi2 + 1):
                dzz[s - lo2] = (s - y[b, 2]) ** 2
                azz[s - lo2] = abs(s - pred[2])
            for p in range(lo0, hi0 + 1):
                dxx = (p - y[b, 0]) ** 2
                ap = abs(p - pred[0])
                for q in range(lo1, hi1 + 1):
                    dxy = dxx + (q - y[b, 1]) ** 2
                    if dxy > r2:              # adding dz^2 >= 0 cannot bring it back
                        continue
                    aq = abs(q - pred[1])
                    for s in range(lo2, hi2 + 1):
                        dd = dxy + dzz[s - lo2]
                        if dd > r2:
                            continue
                        cost = lam * dd
                        cost += ap
                        cost += aq
                        cost += azz[s - lo2]
                        cands[nc, 0] = p
                        cands[nc, 1] = q
                        cands[nc, 2] = s
                        costs[nc] = cost
                        if cost < bestc:      # the cheapest, the first on a tie
                            bestc = cost
                            i0 = nc
                        nc += 1
            found = -1
            # the span check, written out at its one call site (a called kernel compiles
            # on its own, issue 15.2); the candidates after the first are
            # sorted only when the first fails
            # the cheapest first; if it fails, the others in list order, skipping those
            # that cannot beat the best that passed: the least (cost, index) that passes,
            # which is the first that passes in a stable sort by cost, without the sort
            bestp = 1e300
            for k in range(nc + 1 if nc > 0 else 0):
                if k == 0:
                    i = i0
                else:
                    i = k - 1
                    if i == i0 or costs[i] >= bestp:
                        continue
                n = b - a
                f = 0
                if th >= 0:                        # frame th first, from its table
                    d2 = (hx[0, cands[i, 0] - lo0] + hx[1, cands[i, 1] - lo1]) \
                        + hx[2, cands[i, 2] - lo2]
                    if d2 > r2:
                        f = th
                if f == 0:
                    # floor((2 d j + n) / 2n) step by step, without a division per frame:
                    # the numerator grows by 2d = 2n qd + rd (0 <= rd < 2n) a frame
                    D = 2 * n
                    q0 = wa[0]
                    q1 = wa[1]
                    q2 = wa[2]
                    r0 = n
                    r1 = n
                    r2_ = n
                    s0 = 2 * (cands[i, 0] - wa[0])
                    s1 = 2 * (cands[i, 1] - wa[1])
                    s2 = 2 * (cands[i, 2] - wa[2])
                    qd0 = s0 // D
                    qd1 = s1 // D
                    qd2 = s2 // D
                    rd0 = s0 - qd0 * D
                    rd1 = s1 - qd1 * D
                    rd2 = s2 - qd2 * D
                    for j in range(1, n):
                        q0 += qd0
                        r0 += rd0
                        if r0 >= D:
                            r0 -= D
                            q0 += 1
                        q1 += qd1
                        r1 += rd1
                        if r1 >= D:
                            r1 -= D
                            q1 += 1
                        q2 += qd2
                        r2_ += rd2
                        if r2_ >= D:
                            r2_ -= D
                            q2 += 1
                        e0 = q0 - y[a + j, 0]
                        e1 = q1 - y[a + j, 1]
                        e2 = q2 - y[a + j, 2]
                        if e0 * e0 + e1 * e1 + e2 * e2 > r2:
                            f = a + j
                            break
                if f == 0:
                    if k == 0 or costs[i] < bestp:
                        found = i
                        bestp = costs[i]
                    if k == 0:
                        break
                else:
                    hint = f
                    if f != th:                    # a new frame failed: its table
                        th = f
                        if _hint_terms(y, f, a, b, wa, blo, bhi, hx) > r2:
                            break                  # the rest fail there too
            if found < 0:
                break
            good = b
            keep[0] = cands[found, 0]
            keep[1] = cands[found, 1]
            keep[2] = cands[found, 2]
            b += 1
        if good < 0:   # cannot happen: the nearest grid point always qualifies for b = a + 1
            good = a + 1
            for c in range(3):
                keep[c] = math.floor(y[good, c] + 0.5)
        times[K] = good
        vals[K, 0] = keep[0]
        vals[K, 1] = keep[1]
        vals[K, 2] = keep[2]
        K += 1
        a = good
    # the decoded track: interpolate() (§6.5), frame by frame
    for k in range(1, K):
        t1 = times[k - 1]
        nn = times[k] - t1
        for j in range(nn):
            for c in range(3):
                w1 = vals[k - 1, c]
                track[t1 + j, c] = w1 + (2 * (vals[k, c] - w1) * j + nn) // (2 * nn)
    for c in range(3):
        track[T - 1, c] = vals[K - 1, c]
    return times[:K].copy(), vals[:K].copy()      # not views that keep T-sized arrays alive


def fit(y: ArrayLike, radius: float, max_span: int = 256, lam: float = 1.0,
        track: NDArray[np.int32] | None = None) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Key frames of one track ``y[T, 3]`` (grid units) with every sample within ``radius``.

    Returns the key times ``[K]`` and the key values ``[K, 3]`` on the grid; with
    ``track`` (C-contiguous int32 ``[T, 3]``), also writes there what the decoder rebuilds
    from them (:func:`interpolate`). A ``radius`` above :data:`MAX_RADIUS` is searched
    within :data:`MAX_RADIUS`.
    """
    y = np.ascontiguousarray(y, dtype=np.float64)
    if track is None:
        track = np.empty((len(y), 3), np.int32)
    return _fit(y, _search_radius(radius), int(max_span), float(lam), track)


def _search_radius(radius: float) -> float:
    """The radius :func:`_fit` searches for a given one: at most :data:`MAX_RADIUS`."""
    if not radius >= np.sqrt(3.0) / 2:
        raise ValueError("radius < sqrt(3)/2 cannot guarantee a grid point")
    return min(float(radius), MAX_RADIUS)


@njit(cache=True)
def _residuals(mode: int, times: NDArray[np.int64], w: NDArray[np.int64],
               R: NDArray[np.int64] | NDArray[np.int32]) -> NDArray[np.int64]:
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


#: |e| below this take log2(1 + |e|) from a table (:func:`_log2_table`)
_LOG2_TABLE = 1 << 12


@functools.cache
def _log2_table(n: int) -> NDArray[np.float64]:
    """log2(1 + i) for i < n, read-only, made once per process. ``math.log2`` is the C
    library's log2, which numba's ``np.log2`` calls in :func:`_cost` and
    :func:`_best_reference`: the same bits (tests/test_stages.py checks), without a kernel
    to compile on the first encode (issue 15.2). numpy's own ``np.log2`` differs in the
    last bit for some i, which could change a tie in the reference choice."""
    t = np.array([math.log2(1.0 + i) for i in range(n)], np.float64)
    t.flags.writeable = False
    return t


@njit(cache=True, nogil=True)
def _best_reference(m: int, times: NDArray[np.int64], w: NDArray[np.int64],
                    tracks: NDArray[np.int32], tab: NDArray[np.float64],
                    e: NDArray[np.int64], window: int) -> int:
    """p_m of member m (§6.5): 0, or 2j + mode for an earlier member j of the ``window``
    before m (m - window <= j < m; Appendix C; none for a window of 0 or less; a review
    of stop 67 found member m - 1 tried with a window of 0) and mode 1 or 2, whose
    residuals have the
    least ``_cost`` (the first on a tie: none, then j = m - window or 0, ... with mode 1
    before 2); ``tracks[j]`` is member j's decoded track ``[F, 3]`` (member-major, so
    that reading it at the key times walks one contiguous array).

    The window (:data:`REFERENCE_WINDOW`) keeps the choice linear in the members: every
    earlier member was 47 s of a 69 s encode of 4096 markers at 1 mm (stop 67); a node
    of the real files holds at most 67 members, so their choice is what it was.

    Speed (issue 15): one call per member instead of two small kernel calls per candidate;
    the likely best candidate is summed first, and a candidate's sum stops as soon as it can
    no longer win (its terms are >= 0, so its total cannot shrink); log2(1 + |e|) comes from
    ``tab`` for small |e|. Both modes of a member j are summed in one pass: with
    g_k = w_k - R[t_k] (R = 0 for none), the §6.5 residuals are g_0 at k = 0, then
    g_k - g_{k-1} (mode 1, and mode 2 at k = 1), less floor((2 (g_{k-1} - g_{k-2}) d1 + d0)
    / 2 d0) for mode 2 and none from k = 2 (d1 = t_k - t_{k-1}, d0 = t_{k-1} - t_{k-2}):
    one read of R per key and axis, where the two modes read it five times. Each
    candidate's terms are still added in key, then axis order, so its total has the same
    bits; the choice is that of summing every term with :func:`_cost`. The residuals of
    the chosen p go to ``e`` ``[K, 3]`` (those of :func:`_residuals`; one kernel less to
    compile on the first encode, issue 15.2)."""
    # units in the order: the previous member j = m - 1 (after _chain's ordering usually the
    # best, so the sums of the others stop early), none (0), then j = first .. m - 2; the
    # winner is the least (cost, p), which is what the first-on-tie scan in p order keeps.
    # tests/test_stages.py checks the choice and the residuals against _residuals/_cost.
    K = w.shape[0]
    best = np.inf
    p = 0
    ntab = tab.shape[0]
    g1 = np.empty(3, np.int64)                    # g_{k-1}, g_{k-2} per axis
    g2 = np.empty(3, np.int64)
    first = min(max(m - window, 0), m)            # the earliest member tried (m: none)
    for unit in range(m - first + 1):
        j = -1 if first == m or unit == 1 else (m - 1 if unit == 0 else first + unit - 2)
        R = tracks[max(j, 0)]
        q1 = 2 * j + 1 if j >= 0 else 0           # the unit's two candidates (none: one)
        q2 = 2 * j + 2
        on1 = True
        on2 = j >= 0
        s1 = 0.0
        s2 = 0.0
        for k in range(K):
            tk = times[k]
            d1 = tk - times[k - 1] if k >= 2 else 0
            d0 = times[k - 1] - times[k - 2] if k >= 2 else 1
            for c in range(3):
                g = w[k, c] - R[tk, c] if j >= 0 else w[k, c]
                if k == 0:
                    e1 = g
                    e2 = g
                elif k == 1:
                    e1 = g - g1[c]
                    e2 = e1
                else:
                    e1 = g - g1[c]
                    e2 = e1 - (2 * (g1[c] - g2[c]) * d1 + d0) // (2 * d0)
                g2[c] = g1[c]
                g1[c] = g
                if j < 0:                         # none predicts as mode 2 with R = 0
                    e1 = e2
                if on1:
                    u = abs(e1)
                    s1 += tab[u] if u < ntab else np.log2(1.0 + u)
                if on2:
                    u = abs(e2)
                    s2 += tab[u] if u < ntab else np.log2(1.0 + u)
            if on1 and (s1 > best or (s1 == best and q1 > p)):
                on1 = False
            if on2 and (s2 > best or (s2 == best and q2 > p)):
                on2 = False
            if not on1 and not on2:
                break
        if on1 and (s1 < best or (s1 == best and q1 < p)):
            best = s1
            p = q1
        if on2 and (s2 < best or (s2 == best and q2 < p)):
            best = s2
            p = q2
    # the winner's residuals, by the §6.5 prediction itself (_predict_key, inlined)
    mode = 0 if p == 0 else (1 if p % 2 == 1 else 2)
    R = tracks[(p - 1) // 2 if p > 0 else 0]
    for k in range(K):
        tk = times[k]
        t1 = times[k - 1] if k >= 1 else 0
        t2 = times[k - 2] if k >= 2 else 0
        for c in range(3):
            w1 = w[k - 1, c] if k >= 1 else 0
            w2 = w[k - 2, c] if k >= 2 else 0
            e[k, c] = w[k, c] - _predict_key(mode, k, tk, t1, t2, w1, w2, R, c)
    return p


@njit(cache=True, inline="always")
def _run_sum(a: NDArray[np.float64], lo: int, n: int) -> float:
    """numpy's sum of a run of n <= 128 values: by 8 interleaved partial sums."""
    if n < 8:
        res = -0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = lo + 8
    end = lo + n - n % 8
    while i < end:
        r0 += a[i]
        r1 += a[i + 1]
        r2 += a[i + 2]
        r3 += a[i + 3]
        r4 += a[i + 4]
        r5 += a[i + 5]
        r6 += a[i + 6]
        r7 += a[i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < lo + n:
        res += a[i]
        i += 1
    return res


@njit(cache=True)
def _pairwise_sum(a: NDArray[np.float64]) -> float:
    """The sum of ``a`` in numpy's order for a contiguous float64 row: runs of at most 128
    by :func:`_run_sum`, longer runs split in halves at a multiple of 8 and their sums
    added (numpy's pairwise summation), so that :func:`chain_scores` has numpy's bits."""
    return _pairwise_sum_in(a, np.empty(64, np.int64), np.empty(64, np.int64),
                            np.empty(64), np.zeros(64, np.bool_))


@njit(cache=True, nogil=True)
def _pairwise_sum_in(a: NDArray[np.float64], los: NDArray[np.int64], ns: NDArray[np.int64],
                     left: NDArray[np.float64], started: NDArray[np.bool_]) -> float:
    """:func:`_pairwise_sum` with its stack in the caller's arrays (64 entries each), so
    that a caller summing many rows allocates it once (issue 15.1). The recursion is
    walked with an explicit stack: numba's cache cannot reload a recursive kernel (it
    crashes)."""
    los[0], ns[0], started[0] = 0, a.size, False
    top = 0
    while True:
        n = ns[top]
        if n > 128 and not started[top]:                   # descend into the left half
            n2 = n // 2
            n2 -= n2 % 8
            top += 1
            los[top], ns[top], started[top] = los[top - 1], n2, False
            continue
        v = _run_sum(a, los[top], n)
        while True:                                          # return v to the parent
            top -= 1
            if top < 0:
                return v
            n2 = ns[top] // 2
            n2 -= n2 % 8
            if not started[top]:                             # left half done: go right
                started[top] = True
                left[top] = v
                top += 1
                los[top], ns[top], started[top] = los[top - 1] + n2, ns[top - 1] - n2, False
                break
            v = left[top] + v                                # both halves done


@njit(cache=True, nogil=True)
def chain_scores(c: NDArray[np.float64], ok: NDArray[np.bool_]) -> NDArray[np.float64]:
    """How rigidly each pair of markers moves together, for the encoder's member order.

    ``c[3, N, S]`` are finite coordinates (axis, marker, frame) and ``ok[N, S]`` their
    validity. With d the distance of markers i and j at a frame and b = 1 where both are
    valid at it, else 0, the score of (i, j) is std + 0.05 mean of d over the frames with
    b = 1, where mean = sum(d b) / n, std = sqrt(max(sum(d^2 b) / n - mean^2, 0)) and
    n = max(sum(b), 1); +inf where sum(b) < 2. Lower is more rigid.

    Bit for bit what the encoder's numpy expression computed before (tests/test_stages.py
    keeps it): the squares of the three axis differences added in axis order, products
    with b included where b = 0, and each sum over frames taken in numpy's pairwise
    order (:func:`_pairwise_sum`) from 0. Each pair is computed once and no [S, N, N]
    temporary is made: about 10x faster on a 343-frame, 42-marker clip (issue 15.1).
    Then the frames of a pair in a loop without a branch (b as 1.0 or 0.0, the count in
    integers), which the compiler vectorises, and the sums' stack allocated once: 1.7-2x
    faster again (hamner's 600 x 42 sample: 4.7 -> 2.2 ms), the same bits.
    """
    N, S = ok.shape
    score = np.empty((N, N))
    t1 = np.empty(S)
    t2 = np.empty(S)
    okf = np.empty((N, S))                       # b as 1.0 / 0.0, and as 1 / 0
    oki = np.empty((N, S), np.int64)
    for i in range(N):
        for f in range(S):
            okf[i, f] = 1.0 if ok[i, f] else 0.0
            oki[i, f] = 1 if ok[i, f] else 0
    los = np.empty(64, np.int64)                 # _pairwise_sum_in's stack
    ns = np.empty(64, np.int64)
    left = np.empty(64)
    started = np.zeros(64, np.bool_)
    for i in range(N):
        xi, yi, zi, bi, ci = c[0, i], c[1, i], c[2, i], okf[i], oki[i]
        for j in range(i, N):
            xj, yj, zj, bj, cj = c[0, j], c[1, j], c[2, j], okf[j], oki[j]
            cnt = 0
            for f in range(S):                   # no branch: the compiler vectorises it
                dx = xi[f] - xj[f]
                dy = yi[f] - yj[f]
                dz = zi[f] - zj[f]
                d = math.sqrt(dx * dx + dy * dy + dz * dz)
                b = bi[f] * bj[f]
                t1[f] = d * b
                t2[f] = d * d * b
                cnt += ci[f] & cj[f]
            n = max(cnt, 1)
            mean = (0.0 + _pairwise_sum_in(t1, los, ns, left, started)) / n
            v = (0.0 + _pairwise_sum_in(t2, los, ns, left, started)) / n - mean * mean
            if v < 0.0:
                v = 0.0
            sc = math.sqrt(v) + 0.05 * mean if cnt >= 2 else math.inf
            score[i, j] = sc
            score[j, i] = sc
    return score


@njit(cache=True, nogil=True)
def chain_order(score: NDArray[np.float64]) -> NDArray[np.int64]:
    """The greedy member order of :func:`chain_scores`' ``score[N, N]`` from index 0: next
    the unplaced index j >= 1 with the least ``best[j]`` (the lowest j on a tie), where
    ``best`` is the element-wise minimum of the score rows of the indices placed so far.
    Returns the N - 1 indices after 0, in order (issue 15.1: the Python loop was O(N^2)
    keyed ``min`` calls, 0.6 ms of a short clip). A NaN score (coordinates so large that
    a distance overflows) counts as no score: above every number, +inf included."""
    N = score.shape[0]
    best = score[0].copy()
    placed = np.zeros(N, np.bool_)
    placed[0] = True
    order = np.empty(max(N - 1, 0), np.int64)
    for i in range(N - 1):
        nxt = -1
        for j in range(1, N):
            if not placed[j] and (nxt < 0 or best[j] < best[nxt]
                                  or (math.isnan(best[nxt]) and not math.isnan(best[j]))):
                nxt = j
        order[i] = nxt
        placed[nxt] = True
        for j in range(N):
            if score[nxt, j] < best[j] or math.isnan(best[j]):
                best[j] = score[nxt, j]
    return order


#: the earlier members a member's key-frame reference is chosen from (Appendix C): the
#: choice tries none and the members m - 128 .. m - 1 (all of them in a node of at most 129)
REFERENCE_WINDOW = 128

#: frames per fitting task: a task fits members until it holds about this many frames, so
#: that on a short clip its kernel call is not mostly the cost of starting it (issue 15)
TASK_FRAMES = 4096
#: the share of :func:`fit_members`' time that its fits take, the references the rest
#: (measured on a 54,000-frame walk at 1 mm and at the default bound: 1.98 s against
#: 1.82 s), for its progress
FIT_SHARE = 0.52


@njit(cache=True, nogil=True)
def _fit_range(y: NDArray[np.float64], lo: int, hi: int, radius: float, max_span: int,
               lam: float, tracks: NDArray[np.int32]
               ) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """:func:`_fit` of members ``lo .. hi-1`` of ``y[T, n, 3]``, each writing its decoded
    track to ``tracks[m]`` (its own array, so that tasks can run on several threads): their
    key times and key values one member after another, and each member's key count.

    The outputs grow by doubling, so they stay K-sized (issue 11.11); one call fits many
    members, with the GIL released throughout (issue 15: a call per member spent more time
    taking the GIL back than fitting, on a short clip with another thread busy)."""
    counts = np.empty(hi - lo, np.int64)
    cap = 64
    tb = np.empty(cap, np.int64)
    vb = np.empty((cap, 3), np.int64)
    used = 0
    for i in range(hi - lo):
        times, vals = _fit(np.ascontiguousarray(y[:, lo + i, :]), radius, max_span, lam,
                           tracks[lo + i])
        K = times.shape[0]
        if used + K > cap:
            while used + K > cap:
                cap *= 2
            tb2 = np.empty(cap, np.int64)
            tb2[:used] = tb[:used]
            tb = tb2
            vb2 = np.empty((cap, 3), np.int64)
            vb2[:used] = vb[:used]
            vb = vb2
        tb[used: used + K] = times
        vb[used: used + K] = vals
        counts[i] = K
        used += K
    return tb[:used], vb[:used], counts


@njit(cache=True, nogil=True)
def _best_references(lo: int, hi: int, times: NDArray[np.int64], w: NDArray[np.int64],
                     start: NDArray[np.int64], tracks: NDArray[np.int32],
                     tab: NDArray[np.float64], e: NDArray[np.int64], window: int
                     ) -> NDArray[np.int64]:
    """:func:`_best_reference` of members ``lo .. hi-1``, whose keys are rows
    ``start[m] .. start[m + 1] - 1`` of ``times`` and ``w``; their residuals go to the same
    rows of ``e``. One call for many members, as :func:`_fit_range`."""
    ps = np.empty(hi - lo, np.int64)
    for i in range(hi - lo):
        m = lo + i
        a, b = start[m], start[m + 1]
        ps[i] = _best_reference(m, times[a:b], w[a:b], tracks, tab, e[a:b], window)
    return ps


def task_ranges(n: int, T: int) -> list[tuple[int, int]]:
    """Members ``0 .. n-1`` of ``T`` frames in k consecutive ranges ``(lo, hi)``, where
    k = ceil(n / max(1, floor(TASK_FRAMES / T))) is the number of tasks of about
    :data:`TASK_FRAMES` frames (of one member at least), with sizes that differ by at most
    one member: two threads then finish together, where ranges of a full task each left
    one thread waiting (a 151-frame clip's 40 members split 27 + 13)."""
    if n <= 0:
        return []
    per = max(1, TASK_FRAMES // max(T, 1))
    k = -(-n // per)                        # the tasks that ranges of per members make
    return [(i * n // k, (i + 1) * n // k) for i in range(k)]


def _spread(pool: Executor | None, task: Callable[[int, int], _T],
            ranges: list[tuple[int, int]],
            done: Callable[[int], None] | None = None,
            sink: Callable[[_T], None] | None = None) -> list[_T]:
    """``task(lo, hi)`` of every range, in order: the first on this thread and the others on
    ``pool``'s threads, where this thread also takes each one that no pool thread has
    started yet (it would otherwise wait idle while another thread is busy elsewhere).
    While the next range in order runs on a pool thread, this thread takes the later
    ones that no thread has started, and holds their results until their turn: it
    waited for each range in turn, so that on two threads it ran the first range and
    then mostly waited (hamner's encode at 1 mm spent 6.8 of its 21 ms there, stop 67).
    ``done(i)``, when given, is called on this thread as the result of the i-th range
    (1-based) is in hand, in range order. With ``sink``, each result is handed to
    ``sink(result)`` on this thread in range order instead, and not kept (the list
    returned is empty): what it was made of can be freed, and its memory used again by
    the next tasks, before the last task ends (issue 11.11); a result held for its turn
    is one more range's, as a pool thread's would be."""
    out: list[_T] = []
    count = 0

    def take(result: _T) -> None:
        nonlocal count
        if sink is None:
            out.append(result)
        else:
            sink(result)
        count += 1
        if done is not None:
            done(count)

    if pool is None or len(ranges) < 2:
        for lo, hi in ranges:
            take(task(lo, hi))
        return out
    jobs: list[Future[_T] | None] = [pool.submit(task, lo, hi) for lo, hi in ranges[1:]]
    held: dict[int, _T] = {}                    # later ranges' results, taken early here
    try:
        take(task(*ranges[0]))
        for k, (lo, hi) in enumerate(ranges[1:]):
            job = jobs[k]
            if job is None:                     # run here while an earlier one ran there
                result = held.pop(k)
            elif job.cancel():
                result = task(lo, hi)
            else:                               # running on a pool thread: meanwhile
                j = k + 1                       # the next ones that no thread has started
                while not job.done() and j < len(jobs):
                    later = jobs[j]
                    if later is not None and later.cancel():
                        jobs[j] = None
                        held[j] = task(*ranges[j + 1])
                    j += 1
                result = job.result()
            jobs[k] = job = None                # a future holds its result until it goes
            take(result)
            del result
    finally:                        # on an error, what has not started does not start
        for job in jobs:
            if job is not None:
                job.cancel()
    return out


def _tasks_done(progress: Callable[[float, str], None] | None, ranges: list[tuple[int, int]],
                lo: float, hi: float, stage: str) -> Callable[[int], None] | None:
    """:func:`_spread`'s ``done`` for a stage that runs from ``lo`` to ``hi`` of
    ``progress``, in proportion to the tasks of ``ranges`` done (None without progress)."""
    if progress is None:
        return None
    return lambda i: progress(lo + (hi - lo) * i / len(ranges), stage)


@dataclass(frozen=True)
class Members:
    """Targets ``[T, n, 3]`` given a range of members at a time: ``of(lo, hi)`` is a new
    float64 array ``[T, hi - lo, 3]`` of members ``lo .. hi-1``. :func:`fit_members` fits
    each task's members from their own array, and the encoder chooses its lattices a few
    members at a time, instead of holding a float64 copy of the whole node (issue 11.11:
    a 183 KB BVH of 4096 joints and 10,000 frames held 983 MB for each such copy)."""

    of: Callable[[int, int], NDArray[np.float64]]
    T: int
    n: int


@dataclass
class Fitted:
    """The key frames of a node's members, before coding (:func:`fit_members`).

    ``rows``, when set, is ``(times, residuals, start)``: every member's key times and
    residuals one member after another, member m's in rows ``start[m] .. start[m+1] - 1``,
    of which ``times`` and ``residuals`` are views; :func:`write_blocks` codes them from
    there instead of copying them."""

    times: list[NDArray[np.int64]]      # member m's key times [K_m]
    refs: list[int]                     # p_m (§6.5)
    residuals: list[NDArray[np.int64]]  # member m's key values minus their prediction
    out: NDArray[np.int32]              # what the decoder rebuilds, [T, n, 3]
    rows: tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]] | None = None

    def part(self, cols: Sequence[int] | NDArray[np.int64]) -> Fitted:
        """The members ``cols`` alone, in that order, for :func:`write_blocks` to code
        (the encoder's base-1 sample): their refs are kept as they are, so they may name
        members outside the part."""
        return Fitted([self.times[m] for m in cols], [self.refs[m] for m in cols],
                      [self.residuals[m] for m in cols], self.out[:, cols])


def fit_members(y: NDArray[np.float64] | Members, radius: float, max_span: int = 256,
                pool: Executor | None = None,
                progress: Callable[[float, str], None] | None = None) -> Fitted:
    """Fit every member of ``y[T, n, 3]``, choose each one's reference, and form the
    decoded tracks; :func:`write_blocks` codes the result.

    Each member's keys are predicted from whichever earlier member (or none)
    gives the smallest residuals, by the proxy sum(log2(1 + |e|)).

    Speed (issue 15): the members are fitted independently of each other, in tasks of
    consecutive members holding about :data:`TASK_FRAMES` frames (one member a task from
    that length on), of sizes as equal as can be (:func:`task_ranges`), spread over this
    thread and those of ``pool`` when one is given (the kernels release the GIL); the key
    lists held meanwhile are K-sized, not T-sized. Then each member's reference is chosen,
    also independently (from the finished tracks), so the result does not depend on the
    threads or the tasks. A ``radius`` above :data:`MAX_RADIUS` is searched within
    :data:`MAX_RADIUS`, as in :func:`fit`.

    ``progress(fraction, stage)``, when given, is called on this thread as each task's
    result is in hand: the fits take fractions 0 to :data:`FIT_SHARE` ("key frames"), the
    references the rest up to 1 ("references"), each in proportion to its tasks done.

    Memory (issue 11.11): ``y`` may be :class:`Members`, whose tasks then make their own
    members' targets. Each task's key times and values are copied, as it ends, into arrays
    sized for the most keys there can be (T a member) and zero-filled, so that only the
    part written becomes resident, and let go: a list of every task's keys and a
    concatenated copy of it were held at once, and the list's memory was not given back
    to the system. The key values (24 bytes a key) are let go once the references are
    chosen, before the decoded tracks (12 bytes a member-frame) are transposed; the
    result holds its key rows (:attr:`Fitted.rows`), which :func:`write_blocks` codes as
    they are.
    """
    radius = _search_radius(radius)
    if isinstance(y, Members):
        T, n = y.T, y.n
    else:
        T, n, _ = y.shape
        y = np.ascontiguousarray(y, dtype=np.float64)
    tracks = np.empty((n, T, 3), np.int32)     # member-major: each fit writes its own
    ranges = task_ranges(n, T)
    fitting = _tasks_done(progress, ranges, 0.0, FIT_SHARE, "key frames")
    references = _tasks_done(progress, ranges, FIT_SHARE, 1.0, "references")
    times, w, counts = _fit_tasks(y, T, n, radius, int(max_span), tracks, pool, ranges, fitting)
    start = np.zeros(n + 1, np.int64)
    np.cumsum(counts, out=start[1:])
    res = np.empty_like(w)                         # each member's key residuals, in rows
    ps = _references(times, w, start, tracks, res, pool, ranges, references)
    del w
    out = np.ascontiguousarray(tracks.transpose(1, 0, 2))    # [T, n, 3]
    del tracks
    return Fitted([times[start[m]: start[m + 1]] for m in range(n)], [int(p) for p in ps],
                  [res[start[m]: start[m + 1]] for m in range(n)], out, (times, res, start))


def _fit_tasks(y: NDArray[np.float64] | Members, T: int, n: int, radius: float,
               max_span: int, tracks: NDArray[np.int32], pool: Executor | None,
               ranges: list[tuple[int, int]], done: Callable[[int], None] | None
               ) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """:func:`fit_members`' fits: every member's key times and values, one member after
    another, and each member's key count (what concatenating the tasks' gives). Each
    task's are copied as it ends into arrays sized for T keys a member and zero-filled,
    of which only the part written becomes resident (:func:`fit_members`, memory)."""
    def task(lo: int, hi: int) -> tuple[NDArray[np.int64], NDArray[np.int64],
                                        NDArray[np.int64]]:
        if not isinstance(y, Members):
            return _fit_range(y, lo, hi, radius, max_span, 1.0, tracks)
        # the same member values (each from its own targets) and the same fits
        part = np.ascontiguousarray(y.of(lo, hi), dtype=np.float64)
        return _fit_range(part, 0, hi - lo, radius, max_span, 1.0, tracks[lo:hi])
    times = np.zeros(T * n, np.int64)
    w = np.zeros((T * n, 3), np.int64)
    counts = np.empty(n, np.int64)
    at = members = 0

    def keep(part: tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]) -> None:
        nonlocal at, members
        t, v, c = part
        times[at: at + len(t)] = t
        w[at: at + len(t)] = v
        counts[members: members + len(c)] = c
        at, members = at + len(t), members + len(c)
    _spread(pool, task, ranges, done, keep)
    # the times are kept (Fitted.rows): the size written, not T a member (the rest is
    # not resident, but an address-space limit counts it)
    return times[:at].copy(), w[:at], counts


def _references(times: NDArray[np.int64], w: NDArray[np.int64], start: NDArray[np.int64],
                tracks: NDArray[np.int32], res: NDArray[np.int64], pool: Executor | None,
                ranges: list[tuple[int, int]], done: Callable[[int], None] | None
                ) -> NDArray[np.int64]:
    """:func:`fit_members`' references p_m, each member's key residuals written to its rows
    of ``res``."""
    if not len(start) - 1:
        return np.zeros(0, np.int64)
    tab = _log2_table(_LOG2_TABLE)
    return np.concatenate(_spread(pool, lambda lo, hi: _best_references(
        lo, hi, times, w, start, tracks, tab, res, REFERENCE_WINDOW), ranges, done))


def write_blocks(enc: BlockEncoder, fitted: Fitted, T: int) -> None:
    """Code the four blocks of :func:`fit_members`' result for ``T`` frames, in member order.

    Memory (issue 11.11): the spans and key residuals go straight into arrays sized for
    the most keys there can be (T per member) and zero-filled, so that only the part
    written becomes resident, and the blocks are coded from their filled prefixes: no
    list of per-member arrays and no concatenated copy of it. A result that holds its key
    rows (:attr:`Fitted.rows`, :func:`fit_members`') is coded from them: its residuals
    are the fourth block as they are, and only the spans are made (a BVH of 4096 joints
    whose every frame is a key copied 32 bytes a member-frame here).
    """
    n = len(fitted.times)
    refs = np.asarray(fitted.refs, np.int64)
    if fitted.rows is not None:
        times, keys, start = fitted.rows
        enc.block(refs.reshape(-1, 1, 1), signed=False)
        enc.block((np.diff(start) - 1).reshape(-1, 1, 1), signed=False)      # K_m - 1
        # each member's span lengths less one: its key times' differences, less one, but
        # those from one member's last key to the next member's first
        spans = np.diff(times)
        spans -= 1
        enc.block(np.delete(spans, start[1:-1] - 1).reshape(-1, 1, 1), signed=False)
        del spans
        enc.block(keys[:, None, :])
        return
    counts = np.zeros(n, np.int64)
    spans = np.zeros(max(0, T - 1) * n, np.int64)
    keys = np.zeros((T * n, 3), np.int64)
    s_at = k_at = 0
    for m in range(n):
        times, e = fitted.times[m], fitted.residuals[m]
        K = len(e)
        counts[m] = K - 1
        spans[s_at: s_at + K - 1] = np.diff(times) - 1
        keys[k_at: k_at + K] = e
        s_at += K - 1
        k_at += K
    enc.block(refs.reshape(-1, 1, 1), signed=False)
    enc.block(counts.reshape(-1, 1, 1), signed=False)
    enc.block(spans[:s_at].reshape(-1, 1, 1), signed=False)
    enc.block(keys[:k_at][:, None, :])
