"""Rotation matrices for the skeletal formats (BVH, ASF/AMC).

Contract: pure numpy on arrays of angles in degrees, vectorised over
frames; column-vector convention (``v_world = R @ v_local``).
"""
from __future__ import annotations

import numpy as np


def axis_rotation(axis: str, deg: np.ndarray) -> np.ndarray:
    """Rotation matrices about one principal axis.

    Parameters
    ----------
    axis : {"X", "Y", "Z"}
    deg : ndarray, shape (n,)
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


def euler_matrix(order: str, deg: np.ndarray) -> np.ndarray:
    """Compose ``R = R_order[0] @ R_order[1] @ ...`` (intrinsic, BVH-style).

    Parameters
    ----------
    order : str
        Axis letters, e.g. ``"ZXY"``; ``deg[:, i]`` is the angle about ``order[i]``.
    deg : ndarray, shape (n, len(order))

    Returns
    -------
    ndarray, shape (n, 3, 3)
    """
    deg = np.asarray(deg, dtype=np.float64)
    n = deg.shape[0]
    R = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    for i, ax in enumerate(order):
        R = R @ axis_rotation(ax, deg[:, i])
    return R
