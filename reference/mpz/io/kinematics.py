"""Rotation matrices for the skeletal formats (BVH, ASF/AMC).

Contract: pure numpy on arrays of angles in degrees, vectorised over
frames; column-vector convention (``v_world = R @ v_local``).
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def axis_rotation(axis: str, deg: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrices about one principal axis.

    Parameters
    ----------
    axis : {"X", "Y", "Z"}
    deg : array_like, shape (n,)
        Angles in degrees.

    Returns
    -------
    ndarray, shape (n, 3, 3)

    Examples
    --------
    >>> R = axis_rotation("Z", np.array([90.0]))[0]
    >>> np.round(R @ [1.0, 0.0, 0.0], 12).tolist()
    [0.0, 1.0, 0.0]
    """
    a = np.radians(np.asarray(deg, dtype=np.float64))
    c, s = np.cos(a), np.sin(a)
    one, zero = np.ones_like(a), np.zeros_like(a)
    axis = axis.upper()
    if axis == "X":
        rows = [[one, zero, zero], [zero, c, -s], [zero, s, c]]
    elif axis == "Y":
        rows = [[c, zero, s], [zero, one, zero], [-s, zero, c]]
    elif axis == "Z":
        rows = [[c, -s, zero], [s, c, zero], [zero, zero, one]]
    else:
        raise ValueError(f"unknown rotation axis {axis!r}, expected X, Y or Z")
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)
