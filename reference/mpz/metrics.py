"""Error statistics between an original and a decoded motion.

All distances are Euclidean per marker-frame, in the motions' units, over
samples valid in the original (a sample the decoder marks as a gap where the
original was valid counts as an infinite error, so it cannot hide).
"""
from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from mpz.errors import MotionError
from mpz.motion import Motion


def _dist(original: Motion, decoded: Motion) -> NDArray[np.float64]:
    for what, m in (("original", original), ("decoded", decoded)):
        if not isinstance(m, Motion):       # an AttributeError deep inside, before
            raise TypeError(f"{what} must be an mpz.Motion, got {type(m).__name__}")
    if original.positions.shape != decoded.positions.shape:
        raise MotionError(f"shapes differ: {original.positions.shape} vs {decoded.positions.shape}")
    # the same sample of the same marker in the same unit, or the distance means nothing
    # (a motion in cm scored 1518 against itself in mm; `mpz compare` aligns by name)
    if original.units and decoded.units and original.units != decoded.units:
        raise MotionError(f"units differ: {original.units!r} vs {decoded.units!r} (convert "
                          "one first; a motion without units is compared as numbers)")
    if list(original.names) != list(decoded.names):
        k = next(i for i, (a, b) in enumerate(zip(original.names, decoded.names, strict=True))
                 if a != b)
        raise MotionError(f"marker names differ at index {k}: {original.names[k]!r} vs "
                          f"{decoded.names[k]!r} (reorder one motion first)")
    d = np.linalg.norm(original.positions - decoded.positions, axis=2)
    d[~original.valid] = np.nan
    d[original.valid & ~decoded.valid] = np.inf
    return d


def errors(original: Motion, decoded: Motion) -> NDArray[np.float64]:
    """Per-sample Euclidean error ``[F, M]``, NaN where the original is a gap."""
    return _dist(original, decoded)


def max_error(original: Motion, decoded: Motion) -> float:
    """Largest Euclidean error over valid samples (0 if there are none)."""
    d = _dist(original, decoded)
    return float(np.nanmax(d)) if np.isfinite(d).any() or np.isinf(d).any() else 0.0


def _rms_over(d: NDArray[np.float64], axis: int) -> NDArray[np.float64]:
    """RMS of the non-NaN entries along ``axis``; NaN where there are none.

    Counted by hand rather than with ``np.nanmean``, which warns "Mean of empty
    slice" for every frame (or marker) that is a gap throughout (arthuman).
    """
    have = ~np.isnan(d)
    n = have.sum(axis=axis)
    total = np.where(have, d, 0.0) ** 2
    s = total.sum(axis=axis)
    out = np.full(s.shape, np.nan)
    np.divide(s, n, out=out, where=n > 0)
    return np.sqrt(out)


def arms(original: Motion, decoded: Motion) -> float:
    """Paper Eq. 3: mean over frames of the RMS marker error of the frame (valid markers only).

    Frames without a valid marker do not count.
    """
    d = _dist(original, decoded)
    per_frame = _rms_over(d, axis=1)
    per_frame = per_frame[~np.isnan(per_frame)]
    return float(per_frame.mean()) if per_frame.size else 0.0


def summary(original: Motion, decoded: Motion) -> dict[str, Any]:
    """max, ARMS, RMS, p99 and mean error, plus per-marker max and RMS."""
    d = _dist(original, decoded)
    flat = d[~np.isnan(d)]
    if flat.size == 0:
        flat = np.zeros(1)
    per_max = np.where(np.isnan(d), -np.inf, d).max(axis=0, initial=-np.inf)
    per_rms = _rms_over(d, axis=0)
    return {
        "max": float(flat.max()),
        "arms": arms(original, decoded),
        "rms": float(np.sqrt((flat ** 2).mean())),
        "p99": float(np.percentile(flat, 99)),
        "mean": float(flat.mean()),
        "per_marker_max": {n: (None if not np.isfinite(v) and v < 0 else float(v))
                           for n, v in zip(original.names, per_max, strict=False)},
        "per_marker_rms": {n: (None if np.isnan(v) else float(v))
                           for n, v in zip(original.names, per_rms, strict=False)},
    }
