"""Error-bounded choice of grid values (encoder only; beyond the paper).

Rounding each axis to a grid of step s keeps the Euclidean error within
E = s sqrt(3) / 2, but the E-ball around a sample holds on average 2.7 grid
points, not one. :func:`choose_lattice` walks each track in time and picks,
among the grid points within the ball, the one closest to what the decoder
will predict from the values already chosen (order-p temporal prediction).
The decoder is unchanged (it just reads integers), the bound still holds for
every sample, and the residuals shrink: 10-15 % smaller files on real CMU and
HDM05 captures at 1-5 mm (bench/bench_rd.py).
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mpz._jit import njit

#: weight of the squared distance to the target in a grid point's cost (the L1 distance
#: to the prediction is the main term; this one prefers the nearer of equal L1 points)
_LAMBDA = 1e-3
#: boxes of more grid points than this are searched by :func:`_pick_pruned`, which skips
#: what cannot win and picks the same point; smaller ones (the usual radius of 0.87-2 grid
#: steps: 8-125 points) by :func:`_pick_box`, which is quicker there
_BOX_MAX = 512
#: no grid point farther than this from the target along any axis can win, whatever the
#: radius: one step back towards the target stays in the ball and lowers that axis's
#: cost by at least _LAMBDA (the L1 term rises by at most 1, the squared term falls by
#: at least _LAMBDA (2 x 501 - 1)). So a radius of 1e5 grid steps (a grid far finer
#: than the bound) is searched in a box of 1,003 points an axis, not 200,001
_REACH = 0.5 / _LAMBDA + 1.0


@njit(cache=True, nogil=True)
def grid_units(x: NDArray[np.float64], cols: NDArray[np.int64], offset: NDArray[np.float64],
               step: float, out: NDArray[np.float64]) -> None:
    """``out[t, j, a] = (x[t, cols[j], a] - offset[a]) / step``: markers ``cols`` of the
    motion ``x[F, M, 3]`` (any layout) in grid units (spec §4.4: x = o_a + q s, so this
    is q before it is rounded), each value with the two roundings numpy's
    ``(x - offset) / step`` gives it."""
    T, D = x.shape[0], x.shape[2]
    for j in range(cols.shape[0]):
        m = cols[j]
        for t in range(T):
            for a in range(D):
                out[t, j, a] = (x[t, m, a] - offset[a]) / step


@njit(cache=True, nogil=True)
def _pick_box(y0: float, y1: float, y2: float, radius: float,
              p0: float, p1: float, p2: float) -> tuple[int, int, int]:
    """The grid point of least cost ``|w - p|_1 + _LAMBDA |w - y|^2`` with
    ``|w - y|^2 <= radius^2``, the first in (a, b, c) order on a tie: every point of the
    box around the ball is tried."""
    r2 = radius * radius
    best = 1e300
    b0 = math.floor(y0 + 0.5)
    b1 = math.floor(y1 + 0.5)
    b2 = math.floor(y2 + 0.5)
    c_from, c_to = math.ceil(y2 - radius), math.floor(y2 + radius)
    for a in range(math.ceil(y0 - radius), math.floor(y0 + radius) + 1):
        for b in range(math.ceil(y1 - radius), math.floor(y1 + radius) + 1):
            best, b0, b1, b2 = _try_c(a, b, c_from, c_to, y0, y1, y2, r2, p0, p1, p2,
                                      best, b0, b1, b2)
    return b0, b1, b2


@njit(cache=True, nogil=True)
def _try_c(a: int, b: int, c_from: int, c_to: int, y0: float, y1: float, y2: float,
           r2: float, p0: float, p1: float, p2: float, best: float, b0: int, b1: int,
           b2: int) -> tuple[float, int, int, int]:
    """The grid points (a, b, c_from..c_to) against the best so far ``best`` at
    (b0, b1, b2): each in the ball ``|w - y|^2 <= r2`` and of a strictly smaller cost
    replaces it. The one test and cost of both searches."""
    da = a - y0
    db = b - y1
    for c in range(c_from, c_to + 1):
        dc = c - y2
        d2 = da * da + db * db + dc * dc
        if d2 <= r2:
            cost = abs(a - p0) + abs(b - p1) + abs(c - p2) + _LAMBDA * d2
            if cost < best:
                best = cost
                b0 = a
                b1 = b
                b2 = c
    return best, b0, b1, b2


@njit(cache=True, nogil=True)
def _axis_costs(lo: int, hi: int, y: float, p: float) -> NDArray[np.float64]:
    """``|x - p| + _LAMBDA (x - y)^2`` for x = lo..hi: one axis's share of the cost."""
    g = np.empty(hi - lo + 1)
    for k in range(hi - lo + 1):
        d = (lo + k) - y
        g[k] = abs((lo + k) - p) + _LAMBDA * d * d
    return g


@njit(cache=True, nogil=True)
def _least(g: NDArray[np.float64], lo: int, star: int, first: int, last: int) -> float:
    """The least of a convex axis cost ``g`` (g[k] for x = lo + k, least at x = star) over
    x = first..last: at star moved into the range."""
    return g[min(max(star, first), last) - lo]


@njit(cache=True, nogil=True)
def _within(y: float, rem: float, lo: int, hi: int) -> tuple[int, int]:
    """The x in lo..hi with (x - y)^2 <= rem, or a few more, never fewer: rem is widened by
    what binary64 sums can be off (the caller applies the exact test to each)."""
    if rem < 0.0:
        return 1, 0
    rho = math.sqrt(rem)
    return max(lo, math.ceil(y - rho)), min(hi, math.floor(y + rho))


@njit(cache=True, nogil=True)
def _disc_bound(e1: float, e2: float, rho2: float) -> float:
    """A lower bound of |u - e1| + |v - e2| + _LAMBDA (u^2 + v^2) over the real (u, v)
    with u^2 + v^2 <= rho2 (Lagrange's dual at a multiplier nu >= 0: any nu gives a bound;
    the one taken is where the minimiser of the relaxed sum, u_i = min(|e_i|, 1/(2 kappa))
    with kappa = _LAMBDA + nu, meets the circle, which is the best)."""
    e1, e2 = abs(e1), abs(e2)
    if e1 > e2:
        e1, e2 = e2, e1
    kappa = _LAMBDA
    cap = 0.5 / _LAMBDA
    if min(e1, cap) ** 2 + min(e2, cap) ** 2 > rho2:       # the circle binds: water-fill
        mu = math.sqrt(rho2 / 2.0)
        if e1 < mu:
            mu = math.sqrt(max(rho2 - e1 * e1, 0.0))
        if mu > 0.0:
            kappa = max(_LAMBDA, 0.5 / mu)
        else:
            return 0.0
    total = -(kappa - _LAMBDA) * rho2
    for e in (e1, e2):
        total += e - 0.25 / kappa if e > 0.5 / kappa else kappa * e * e
    return total


@njit(cache=True, nogil=True)
def _pick_pruned(y0: float, y1: float, y2: float, radius: float,
                 p0: float, p1: float, p2: float) -> tuple[int, int, int]:
    """The point :func:`_pick_box` picks, without trying every point of a large box.

    The cost is a sum of one convex term per axis, g0(a) + g1(b) + g2(c), and the ball
    leaves b and c a range for each a (and c one for each (a, b)), over which a convex
    term is least at its own least point moved into the range. So no point whose a has
    g0(a) plus those least g1 and g2 above a cost already reached can win, nor one whose
    (a, b) has g0(a) + g1(b) plus the least g2 above it, nor a c whose g2(c) exceeds what
    is left; the least of g1 + g2 over the disc of b and c is bounded from below by
    :func:`_disc_bound` as well, which is tighter when p is outside the ball. Everything
    else is tried in the same (a, b, c) order, with the same test and
    cost as :func:`_pick_box`, so the first least point is the same. Only the box within
    ``_REACH`` of the target is searched: nothing beyond it can win. The first cost
    reached is the least of four points in the ball: the nearest grid point, each axis at
    its own least, the prediction, and the point nearest the prediction in L1 (within
    rounding). Margins of 1e-9 cover the rounding of sums and square roots. A radius of
    177 grid steps (a root bound 100 times a group's) takes microseconds a sample, where
    the box takes 0.1 s; so does a radius of 1e9.
    """
    r2 = radius * radius
    slack = 1e-9 * (1.0 + r2)
    reach = min(radius, _REACH)
    lo0, hi0 = math.ceil(y0 - reach), math.floor(y0 + reach)
    lo1, hi1 = math.ceil(y1 - reach), math.floor(y1 + reach)
    lo2, hi2 = math.ceil(y2 - reach), math.floor(y2 + reach)
    g0 = _axis_costs(lo0, hi0, y0, p0)
    g1 = _axis_costs(lo1, hi1, y1, p1)
    g2 = _axis_costs(lo2, hi2, y2, p2)
    s0 = lo0 + int(np.argmin(g0))
    s1 = lo1 + int(np.argmin(g1))
    s2 = lo2 + int(np.argmin(g2))
    b0 = math.floor(y0 + 0.5)
    b1 = math.floor(y1 + 0.5)
    b2 = math.floor(y2 + 0.5)
    # the first cost reached: four points, each counted only if in the ball
    bound = 1e300
    da, db, dc = b0 - y0, b1 - y1, b2 - y2
    d2 = da * da + db * db + dc * dc
    if d2 <= r2:
        bound = abs(b0 - p0) + abs(b1 - p1) + abs(b2 - p2) + _LAMBDA * d2
    da, db, dc = s0 - y0, s1 - y1, s2 - y2      # each axis at its own least: the least
    d2 = da * da + db * db + dc * dc            # of all when in the ball, as it always
    if d2 <= r2:                                # is from a radius of 868
        bound = min(bound, abs(s0 - p0) + abs(s1 - p1) + abs(s2 - p2) + _LAMBDA * d2)
    da, db, dc = p0 - y0, p1 - y1, p2 - y2
    d2 = da * da + db * db + dc * dc
    if d2 <= r2:
        bound = min(bound, _LAMBDA * d2)
    else:           # towards p by t_i = min(|p_i - y_i|, mu), sum t_i^2 = R^2 (water-filling)
        big = radius - 0.8660254037844387 - 1e-6        # rounding then stays in the ball
        if big > 0.0:
            e = np.sort(np.array([abs(da), abs(db), abs(dc)]))
            used = 0.0
            mu = big
            for k in range(3):
                mu = math.sqrt(max(big * big - used, 0.0) / (3 - k))
                if e[k] >= mu:
                    break
                used += e[k] * e[k]
            q0 = math.floor(y0 + math.copysign(min(abs(da), mu), da) + 0.5)
            q1 = math.floor(y1 + math.copysign(min(abs(db), mu), db) + 0.5)
            q2 = math.floor(y2 + math.copysign(min(abs(dc), mu), dc) + 0.5)
            da, db, dc = q0 - y0, q1 - y1, q2 - y2
            d2 = da * da + db * db + dc * dc
            if d2 <= r2:
                bound = min(bound, abs(q0 - p0) + abs(q1 - p1) + abs(q2 - p2) + _LAMBDA * d2)
    bound += 1e-9 * (1.0 + abs(bound))
    best = 1e300
    for a in range(lo0, hi0 + 1):
        da = a - y0
        rem_a = r2 + slack - da * da
        f1, l1 = _within(y1, rem_a, lo1, hi1)
        if f1 > l1:
            continue
        f2, l2 = _within(y2, rem_a, lo2, hi2)
        ga = g0[a - lo0]
        if ga + max(_least(g1, lo1, s1, f1, l1) + _least(g2, lo2, s2, f2, l2),
                    _disc_bound(p1 - y1, p2 - y2, rem_a)) > bound:
            continue
        for b in range(f1, l1 + 1):
            db = b - y1
            c_first, c_last = _within(y2, rem_a - db * db, lo2, hi2)
            if c_first > c_last:
                continue
            gab = ga + g1[b - lo1]
            c = min(max(s2, c_first), c_last)   # g2's least point in the range
            left = bound - gab                  # g2(c) may be at most this
            if g2[c - lo2] > left:
                continue
            c_lo = c                            # g2 is convex: its c within `left` are
            while c_lo > c_first and g2[c_lo - 1 - lo2] <= left:    # one run around c
                c_lo -= 1
            c_hi = c
            while c_hi < c_last and g2[c_hi + 1 - lo2] <= left:
                c_hi += 1
            best, b0, b1, b2 = _try_c(a, b, c_lo, c_hi, y0, y1, y2, r2, p0, p1, p2,
                                      best, b0, b1, b2)
            bound = min(bound, best + 1e-9 * (1.0 + abs(best)))
    return b0, b1, b2


@njit(cache=True, nogil=True)
def _choose(y: NDArray[np.float64], radius: float, order: int, w: NDArray[np.int64],
            cols: NDArray[np.int64]) -> None:
    """:func:`choose_lattice` of the tracks ``cols`` of ``y``, written to the same tracks of
    ``w`` (the others are not touched: each track is independent of the others)."""
    T = y.shape[0]
    side = math.floor(2.0 * min(radius, _REACH)) + 1     # grid points an axis in the box
    pruned = side * side * side > _BOX_MAX
    for t in range(T):              # frame by frame, so that w[t - 1] and y[t] are read
        for m in cols:              # in memory order
            p0 = 0.0
            p1 = 0.0
            p2 = 0.0
            if order == 1 or (order == 2 and t == 1):
                if t >= 1:
                    p0 = w[t - 1, m, 0]
                    p1 = w[t - 1, m, 1]
                    p2 = w[t - 1, m, 2]
            elif order == 2 and t >= 2:
                p0 = 2 * w[t - 1, m, 0] - w[t - 2, m, 0]
                p1 = 2 * w[t - 1, m, 1] - w[t - 2, m, 1]
                p2 = 2 * w[t - 1, m, 2] - w[t - 2, m, 2]
            if order == 0 or t == 0:
                # nothing to predict from: nearest grid point
                w[t, m, 0] = math.floor(y[t, m, 0] + 0.5)
                w[t, m, 1] = math.floor(y[t, m, 1] + 0.5)
                w[t, m, 2] = math.floor(y[t, m, 2] + 0.5)
                continue
            if pruned:
                a, b, c = _pick_pruned(y[t, m, 0], y[t, m, 1], y[t, m, 2], radius, p0, p1, p2)
            else:
                a, b, c = _pick_box(y[t, m, 0], y[t, m, 1], y[t, m, 2], radius, p0, p1, p2)
            w[t, m, 0] = a
            w[t, m, 1] = b
            w[t, m, 2] = c


def choose_lattice(y: ArrayLike, radius: float, order: int,
                   known: tuple[ArrayLike, NDArray[np.int64]] | None = None
                   ) -> NDArray[np.int64]:
    """Integer values ``w[T, M, 3]`` with ``|w - y| <= radius`` (Euclidean, per sample).

    Parameters
    ----------
    y : ndarray, float, shape (T, M, 3)
        Targets in grid units.
    radius : float
        Allowed distance in grid units; must be >= sqrt(3)/2 so that the
        nearest grid point always qualifies.
    order : int
        Temporal predictor order the values will be coded with (0..2).
    known : (columns, values), optional
        Tracks already chosen, by an earlier call on ``y[:, columns]`` with the same
        radius and order: ``values[T, len(columns), 3]`` is that call's result. They are
        copied, not chosen again (each track is chosen independently of the others, so
        the result is the same as without ``known``).

    Returns
    -------
    ndarray of int64, shape (T, M, 3)

    Raises
    ------
    ValueError
        If ``radius`` is below sqrt(3)/2, or ``known`` is not distinct integer columns
        of ``y`` with integer values of shape ``(T, len(columns), 3)``.
    """
    if radius < np.sqrt(3.0) / 2:
        raise ValueError(f"radius {radius} < sqrt(3)/2 cannot guarantee a grid point")
    y = np.ascontiguousarray(y, dtype=np.float64)
    w = np.empty(y.shape, np.int64)             # every value is written below
    todo = np.ones(y.shape[1], np.bool_)
    if known is not None:
        cols, values = np.asarray(known[0]), np.asarray(known[1])
        if cols.ndim != 1 or (cols.size and not np.issubdtype(cols.dtype, np.integer)):
            raise ValueError("known columns must be a 1-D array of integers")
        if cols.size and (cols.min() < 0 or cols.max() >= y.shape[1]
                          or np.unique(cols).size != cols.size):
            raise ValueError(f"known columns must be distinct, in 0..{y.shape[1] - 1}")
        want = (y.shape[0], cols.size, 3)
        if values.shape != want or not np.issubdtype(values.dtype, np.integer):
            raise ValueError(f"known values must be integers of shape {want}, got "
                             f"{values.dtype} {values.shape}")
        cols = cols.astype(np.int64)
        w[:, cols] = values
        todo[cols] = False
    _choose(y, float(radius), int(order), w, np.flatnonzero(todo).astype(np.int64))
    return w
