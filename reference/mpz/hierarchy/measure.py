"""Distances and sizes measured on a motion, shared by the builders and the scale.

Contract: every function reads ``motion.positions`` and ``motion.valid`` only,
uses a sample only where it is valid, and is total: a pair never valid together
is ``math.inf`` apart, a motion with no two valid markers in any frame has size
0.0. Frame samples are evenly spaced, sorted and unique, so results do not
depend on the machine.
"""
from __future__ import annotations

import math
from typing import cast

import numpy as np

from mpz._jit import njit
from mpz.motion import Motion

#: markers^2 x frames that a pair analysis (the auto hierarchy's distance table, the
#: encoder's rigidity chain) aims at: 400 frames of 256 markers (the chain takes every
#: F div k-th frame, up to 2k - 1 of them, and no analysis fewer than PAIR_MIN_FRAMES)
PAIR_FRAME_BUDGET = 400 * 256 * 256
#: the fewest frames a pair analysis samples, however many markers (when the clip has
#: that many; Appendix C)
PAIR_MIN_FRAMES = 32


def pair_frames(n_markers: int, most: int) -> int:
    """The frames a pair analysis of ``n_markers`` samples: ``most`` while
    n_markers^2 x most is within :data:`PAIR_FRAME_BUDGET`, else the budget over
    n_markers^2 (rounded down), and never below :data:`PAIR_MIN_FRAMES` (Appendix C).

    Why: every pair is scored on every sampled frame, so the work is quadratic in the
    markers: 27 s of a 69 s encode of 4096 markers took 400 frames (stop 67); no real
    capture here has more than 68 markers, and up to 256 the sample is what it was."""
    return max(PAIR_MIN_FRAMES, min(most, PAIR_FRAME_BUDGET // max(n_markers, 1) ** 2))


def sample_frames(n: int, k: int) -> np.ndarray:
    """At most ``k`` evenly spaced, sorted, unique frame indices of ``0..n-1``."""
    return np.unique(np.linspace(0, n - 1, min(n, k)).round().astype(np.int64))


def sampled(motion: Motion, frames: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(positions, valid)`` of ``motion``, restricted to ``frames`` if given."""
    x, v = motion.positions, cast(np.ndarray, motion.valid)  # Motion always sets valid
    if frames is None:
        return x, v
    return x[frames], v[frames]


def mean_distance(motion: Motion, a: int, b: int, frames: np.ndarray | None = None) -> float:
    """Mean distance between markers a and b over frames where both are valid."""
    x, v = motion.positions, cast(np.ndarray, motion.valid)
    rows = slice(None) if frames is None else frames      # only the two markers' samples
    both = v[rows, a] & v[rows, b]
    if not both.any():
        return math.inf
    return float(np.linalg.norm(x[rows, a][both] - x[rows, b][both], axis=1).mean())


def body_size(motion: Motion, frames: np.ndarray | None = None) -> float:
    """Median over frames of the bounding-box diagonal of the valid markers (frames with
    fewer than two valid markers left out; 0.0 when none is left)."""
    x, v = sampled(motion, frames)
    diag = _bbox_diagonals(np.ascontiguousarray(x, dtype=np.float64),
                           np.ascontiguousarray(v, dtype=np.bool_))
    return float(np.median(diag)) if diag.size else 0.0


@njit(cache=True, nogil=True)
def _bbox_diagonals(x: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The bounding-box diagonal of the valid markers of each frame of ``x[S, M, 3]`` that
    has at least two (``v[S, M]``): per axis the extremes of the valid coordinates, then
    sqrt(((0 + d0^2) + d1^2) + d2^2), the bits of ``np.linalg.norm`` over the three axes
    (tests/test_hierarchy.py keeps the numpy expression this replaced as the oracle).
    Speed (issue 15): twice per encode, 0.15-0.4 ms of numpy temporaries on a short clip."""
    S, M = v.shape
    out = np.empty(S)
    n = 0
    for f in range(S):
        cnt = 0
        for m in range(M):
            if v[f, m]:
                cnt += 1
        if cnt < 2:
            continue
        s = 0.0
        for c in range(3):
            hi = -math.inf
            lo = math.inf
            for m in range(M):
                if v[f, m]:
                    if x[f, m, c] > hi:
                        hi = x[f, m, c]
                    if x[f, m, c] < lo:
                        lo = x[f, m, c]
            d = hi - lo
            s += d * d
        out[n] = math.sqrt(s)
        n += 1
    return out[:n]
