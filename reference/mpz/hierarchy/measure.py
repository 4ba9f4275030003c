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

from mpz.motion import Motion


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
    """Median over frames of the bounding-box diagonal of the valid markers."""
    x, v = sampled(motion, frames)
    ok = v.sum(axis=1) >= 2
    if not ok.any():
        return 0.0
    # per frame and axis, the extremes of the valid markers (valid samples are finite, so
    # this is nanmax / nanmin of the gaps as NaN, exactly), reduced along a contiguous
    # axis: 4.7 -> 1.5 ms on 1000 frames x 68 markers, twice per encode (issue 15.1)
    xt = np.ascontiguousarray(x[ok].transpose(0, 2, 1))        # [S, 3, M]
    vt = v[ok][:, None, :]
    hi = np.where(vt, xt, -np.inf).max(axis=2)
    lo = np.where(vt, xt, np.inf).min(axis=2)
    diag = np.linalg.norm(hi - lo, axis=1)
    return float(np.median(diag))
