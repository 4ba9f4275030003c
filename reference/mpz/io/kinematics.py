"""The skeleton model of BVH and ASF/AMC files, and their forward kinematics.

Contract: pure numpy, no file I/O. A :class:`Skeleton` holds everything a BVH
hierarchy or an ASF skeleton (plus the layout of its AMC motion) defines; the
channel values of a motion are a float64 array ``[frames, channels]`` in the
skeleton's channel order (:attr:`Skeleton.channel_names`). :func:`forward` turns
them into joint positions, one per joint, in the skeleton's length unit. The
readers (:mod:`mpz.io.bvh`, :mod:`mpz.io.amc`), the writers and the skeleton
extension (:mod:`mpz.skeleton`, spec §4.14 and §6.10) all share this one model.

Conventions (spec §6.10), column vectors (``v_world = R @ v_local``), angles in
degrees unless the skeleton says radians:

- BVH: a joint's local transform is ``T(OFFSET + position channels) @ R``, where ``R``
  multiplies the rotation channels in the order listed (``Zrotation Xrotation
  Yrotation`` gives ``Rz @ Rx @ Ry``). An End Site is a joint without channels.
- ASF/AMC (Acclaim, as in the CMU viewer): with ``C`` the bone's ``axis`` rotation and
  ``M`` its dof rotation, ``W = W_parent @ C @ M @ C^-1`` and
  ``end = start + W @ (direction * (length + l)) + W_parent @ C @ t``, where ``l`` is the
  bone's ``l`` dof and ``t`` its ``tx ty tz`` dofs (0 when absent); the first letter of
  an axis order or of the dof list is applied first (``XYZ``: ``Rz @ Ry @ Rx``). The root
  is joint 0: its position is ``position`` plus its translation channels, its rotation
  ``C @ M @ C^-1`` with ``C`` from ``orientation``.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import functools
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mpz._jit import njit
from mpz.format import AXIS_ORDERS, ChannelKind

Vec3 = tuple[float, float, float]
FloatArray = NDArray[np.float64]

#: BVH channel keywords, by channel kind (spec §4.14.1)
BVH_CHANNELS: dict[ChannelKind, str] = {
    ChannelKind.TX: "Xposition", ChannelKind.TY: "Yposition", ChannelKind.TZ: "Zposition",
    ChannelKind.RX: "Xrotation", ChannelKind.RY: "Yrotation", ChannelKind.RZ: "Zrotation"}
#: ASF dof keywords, by channel kind (spec §4.14.2); the root's ``order`` uses upper case
ASF_DOFS: dict[ChannelKind, str] = {
    ChannelKind.TX: "tx", ChannelKind.TY: "ty", ChannelKind.TZ: "tz", ChannelKind.RX: "rx",
    ChannelKind.RY: "ry", ChannelKind.RZ: "rz", ChannelKind.L: "l"}
#: millimetres per inch (ASF ``:units length`` counts file units per inch)
MM_PER_INCH = 25.4


def axis_rotation(axis: str, deg: ArrayLike) -> FloatArray:
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


def _axes_matrix(order: str, deg: Sequence[float]) -> FloatArray:
    """Acclaim ``axis``: rotations about the axes of ``order``, the first letter applied
    first, angles ``deg`` given in x, y, z order."""
    R = np.eye(3)
    for ax in order:
        R = axis_rotation(ax, np.array([deg["XYZ".index(ax)]]))[0] @ R
    return R


@dataclass(frozen=True)
class Joint:
    """One joint of a skeleton: a BVH ROOT, JOINT or End Site, or the ASF root or a bone.

    ``channels`` are :class:`~mpz.format.ChannelKind` codes in the file's order. The
    fields after ``end_site`` are the ASF ones (``axis`` holds the root's
    ``orientation``, ``offset`` its ``position``).
    """

    name: str
    parent: int                                  # -1: a root
    channels: tuple[int, ...] = ()
    offset: Vec3 = (0.0, 0.0, 0.0)               # BVH OFFSET; ASF root: position
    end_site: bool = False                       # BVH End Site (no name, no channels)
    direction: Vec3 = (0.0, 0.0, 0.0)            # ASF bone
    length: float = 0.0                          # ASF bone
    axis: Vec3 = (0.0, 0.0, 0.0)                 # ASF bone axis, or root orientation
    axis_order: str = "XYZ"                      # ASF
    limits: tuple[tuple[float, float], ...] = () # ASF, one (low, high) per dof, or none
    bone_id: int = 0                             # ASF ``id`` (0: none)


@dataclass(frozen=True)
class Skeleton:
    """A BVH hierarchy or an ASF skeleton with the layout of its AMC motion.

    Attributes
    ----------
    convention : {"bvh", "asf"}
    joints : tuple of Joint
        Parents precede their children. BVH: every ROOT, JOINT and End Site in file
        order. ASF: the root, then the bones.
    angle_unit : {"deg", "rad"}
        Unit of the rotation channels (and of ASF axes, orientations and rotation limits).
    frame_time : float
        BVH ``Frame Time`` in seconds as written (0 for ASF/AMC, which stores none).
    encoding : {"utf-8", "latin-1"}
        Text encoding of the source file, used again when writing it.
    length : float
        ASF ``:units length`` (file lengths are inches / ``length``); 1 for BVH.
    mass, version, name, documentation, comments : str
        ASF ``:units mass`` text, ``:version``, ``:name``, ``:documentation`` lines and the
        comment lines before the first keyword.
    amc_header : str
        AMC lines before the first frame (comments and keywords), newline-separated.
    first_frame : int
        Number of the first AMC frame.
    amc_order : tuple of int
        Joint indices in the order an AMC frame lists them.
    """

    convention: str
    joints: tuple[Joint, ...]
    angle_unit: str = "deg"
    frame_time: float = 0.0
    encoding: str = "utf-8"
    length: float = 1.0
    mass: str = ""
    version: str = ""
    name: str = ""
    documentation: str = ""
    comments: str = ""
    amc_header: str = ""
    first_frame: int = 1
    amc_order: tuple[int, ...] = ()

    @property
    def channel_count(self) -> int:
        return sum(len(j.channels) for j in self.joints)

    def channel_starts(self) -> list[int]:
        """Index of each joint's first channel in a frame of values."""
        out, n = [], 0
        for j in self.joints:
            out.append(n)
            n += len(j.channels)
        return out

    def channel_kinds(self) -> list[int]:
        """The :class:`~mpz.format.ChannelKind` of every channel, in order."""
        return [c for j in self.joints for c in j.channels]

    def channel_joints(self) -> list[int]:
        """The joint index of every channel, in order."""
        return [i for i, j in enumerate(self.joints) for _ in j.channels]

    def channel_names(self) -> list[str]:
        """``<joint>.<channel>`` per channel: ``Hips.Xrotation`` (BVH), ``lfemur.rx`` (ASF)."""
        table = BVH_CHANNELS if self.convention == "bvh" else ASF_DOFS
        return [f"{j.name}.{table[ChannelKind(c)]}" for j in self.joints for c in j.channels]

    def parents(self) -> list[int]:
        return [j.parent for j in self.joints]

    @property
    def mm_per_unit(self) -> float | None:
        """Millimetres per length unit of an ASF skeleton (BVH: None, the file has no unit)."""
        return MM_PER_INCH / self.length if self.convention == "asf" else None

    def degrees(self, v: FloatArray) -> FloatArray:
        """Angles in this skeleton's angle unit, in degrees."""
        return np.degrees(v) if self.angle_unit == "rad" else v


def forward(skel: Skeleton, values: ArrayLike) -> FloatArray:
    """Joint positions ``[frames, joints, 3]`` in the skeleton's length unit (spec §6.10).

    Parameters
    ----------
    skel : Skeleton
    values : array_like, shape (frames, channels)
        Channel values in the file's units.

    Examples
    --------
    >>> j = (Joint("A", -1, (0, 1, 2)), Joint("B", 0, (5,), offset=(0.0, 1.0, 0.0)))
    >>> p = forward(Skeleton("bvh", j), [[1.0, 2.0, 3.0, 90.0]])
    >>> np.round(p[0], 12).tolist()
    [[1.0, 2.0, 3.0], [1.0, 3.0, 3.0]]
    """
    v = np.asarray(values, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != skel.channel_count:
        raise ValueError(f"values must be [frames, {skel.channel_count}], got {v.shape}")
    return _forward(np.ascontiguousarray(v), *_forward_arrays(skel))


@njit(cache=True, inline="always")
def _rotate(R: FloatArray, kind: int, angle: float, rad: bool, left: bool) -> None:
    """R <- R @ A (``left`` False) or A @ R (``left`` True), in place, where A is
    :func:`axis_rotation` about axis ``kind`` - RX by ``angle`` (degrees unless ``rad``).
    Only the two rows or columns that A mixes change; the terms A's zeros would add are
    exact zeros, so this is the full 3 x 3 product's value."""
    a = angle if rad else angle * (math.pi / 180.0)
    c, s = math.cos(a), math.sin(a)
    ax = kind - 3
    u, w = (ax + 1) % 3, (ax + 2) % 3              # the plane A turns, in cyclic order
    for i in range(3):
        if left:
            ru, rw = R[u, i], R[w, i]
            R[u, i] = c * ru - s * rw
            R[w, i] = s * ru + c * rw
        else:
            ru, rw = R[i, u], R[i, w]
            R[i, u] = ru * c + rw * s
            R[i, w] = rw * c - ru * s


@njit(cache=True, inline="always")
def _matmul3(X: FloatArray, Y: FloatArray, out: FloatArray) -> None:
    for i in range(3):
        for k in range(3):
            out[i, k] = X[i, 0] * Y[0, k] + X[i, 1] * Y[1, k] + X[i, 2] * Y[2, k]


@njit(cache=True, inline="always")
def _apply(X: FloatArray, y: FloatArray, i: int) -> float:
    return X[i, 0] * y[0] + X[i, 1] * y[1] + X[i, 2] * y[2]


@njit(cache=True, nogil=True)
def _forward(v: FloatArray, bvh: bool, rad: bool, parent: NDArray[np.int64],
             start: NDArray[np.int64], count: NDArray[np.int64], kinds: NDArray[np.int64],
             offset: FloatArray, direction: FloatArray, length: FloatArray,
             axes: FloatArray) -> FloatArray:
    """Joint positions [F, J, 3] of channel values ``v[F, C]`` (spec §6.10, the
    conventions in the module docstring), one frame at a time: parents before children,
    3 x 3 products summed in index order."""
    F = v.shape[0]
    J = parent.shape[0]
    pos = np.empty((F, J, 3))
    world = np.empty((J, 3, 3))
    R = np.empty((3, 3))
    T = np.empty((3, 3))
    t = np.empty(3)
    bone = np.empty(3)
    seen = np.zeros(7, np.bool_)
    for f in range(F):
        for j in range(J):
            p = parent[j]
            R[:, :] = 0.0
            R[0, 0] = R[1, 1] = R[2, 2] = 1.0
            t[:] = 0.0
            ln = 0.0
            seen[:] = False
            for k in range(count[j]):
                kind = kinds[start[j] + k]
                x = v[f, start[j] + k]
                if 3 <= kind <= 5:
                    # BVH: R @ A in listed order; ASF: A @ M, the first listed applied first
                    _rotate(R, kind, x, rad, not bvh)
                elif bvh:
                    t[kind] += x                           # BVH adds every position channel
                elif not seen[kind]:                       # ASF: a dof's first occurrence
                    seen[kind] = True
                    if kind <= 2:
                        t[kind] = x
                    else:
                        ln = x
            if bvh:
                for a in range(3):
                    t[a] = offset[j, a] + t[a]
                if p < 0:
                    pos[f, j] = t
                    world[j] = R
                else:
                    for a in range(3):
                        pos[f, j, a] = pos[f, p, a] + _apply(world[p], t, a)
                    _matmul3(world[p], R, world[j])
                continue
            C = axes[j]
            _matmul3(C, R, T)                                # C M
            _matmul3(T, C.T, R)                              # W_local = C M C^-1
            if p < 0:
                for a in range(3):
                    pos[f, j, a] = offset[j, a] + t[a]
                world[j] = R
                continue
            _matmul3(world[p], R, world[j])                  # W = W_parent W_local
            _matmul3(world[p], C, T)                         # W_parent C
            for a in range(3):
                bone[a] = direction[j, a] * (length[j] + ln)
            for a in range(3):
                pos[f, j, a] = (pos[f, p, a] + _apply(world[j], bone, a)) + _apply(T, t, a)
    return pos


@functools.lru_cache(maxsize=8)
def _forward_arrays(skel: Skeleton) -> tuple:
    """The skeleton as the arrays :func:`_forward` reads (kept for a few recent skeletons:
    an encode calls :func:`forward` several times with the same one)."""
    J = len(skel.joints)
    axes = np.zeros((J, 3, 3))
    if skel.convention == "asf":
        for i, j in enumerate(skel.joints):
            axes[i] = _axes_matrix(j.axis_order,
                                   [float(a) for a in skel.degrees(np.asarray(j.axis))])
    return (skel.convention == "bvh", skel.angle_unit == "rad",
            np.array([j.parent for j in skel.joints], np.int64),
            np.array(skel.channel_starts(), np.int64),
            np.array([len(j.channels) for j in skel.joints], np.int64),
            np.array(skel.channel_kinds(), np.int64).reshape(-1),
            np.array([j.offset for j in skel.joints], np.float64).reshape(J, 3),
            np.array([j.direction for j in skel.joints], np.float64).reshape(J, 3),
            np.array([j.length for j in skel.joints], np.float64), axes)


def axis_order_code(order: str) -> int:
    """The §4.14.2 code of an axis order such as ``"XYZ"`` (its index in AXIS_ORDERS)."""
    return AXIS_ORDERS.index(order.upper())


def lever_arms(skel: Skeleton, positions: ArrayLike) -> FloatArray:
    """For each joint, the largest distance over frames from the pivot of its rotation
    channels to any point they move (the joint's lever arm), from joint positions
    ``[frames, joints, 3]``.

    The pivot is the joint itself in BVH (its rotation turns its children) and the bone's
    start, the parent's end, in ASF (a bone's rotation turns the bone itself); the root
    pivots about its own position in both.
    """
    p = np.ascontiguousarray(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[1:] != (len(skel.joints), 3):
        raise ValueError(f"positions must be [frames, {len(skel.joints)}, 3], got {p.shape}")
    moved, pivots, turner = _lever_pairs(skel)
    # sqrt is monotone: the largest distance is the root of the largest squared one
    far = _farthest(p, moved, pivots)
    arm = np.zeros(len(skel.joints))
    np.maximum.at(arm, turner, np.sqrt(far))
    return arm


@njit(cache=True, nogil=True)
def _farthest(p: FloatArray, moved: NDArray[np.int64], pivots: NDArray[np.int64]
              ) -> FloatArray:
    """Per pair i, the largest over frames f of the squared distance of joints
    ``moved[i]`` and ``pivots[i]`` in ``p[F, J, 3]``, 0 for no frame: x*x + y*y + z*z of
    their difference, added left to right (:func:`squared_lengths`' bits), and NaN once a
    distance is NaN (np.maximum's). One pass over the frames with no [pairs, frames, 3]
    temporary, with the GIL released (issue 15.1: 1.2 ms of an AMC file's 7 ms step
    search as numpy blocks)."""
    F = p.shape[0]
    far = np.zeros(moved.shape[0])
    for f in range(F):
        for i in range(moved.shape[0]):
            a, b = moved[i], pivots[i]
            dx = p[f, a, 0] - p[f, b, 0]
            dy = p[f, a, 1] - p[f, b, 1]
            dz = p[f, a, 2] - p[f, b, 2]
            d = dx * dx + dy * dy + dz * dz
            m = far[i]
            if m == m and not d <= m:         # a NaN stays, as np.maximum keeps it
                far[i] = d
    return far


def squared_lengths(d: FloatArray) -> FloatArray:
    """``x*x + y*y + z*z`` of vectors ``d[..., 3]``, summed left to right: the sums of
    ``np.linalg.norm(d, axis=-1)`` (np.add.reduce over a short last axis), bit for bit, in
    a fraction of its time."""
    sq = d[..., 0] * d[..., 0]
    sq += d[..., 1] * d[..., 1]
    sq += d[..., 2] * d[..., 2]
    return sq


@functools.lru_cache(maxsize=8)
def _lever_pairs(skel: Skeleton) -> tuple[NDArray[np.int64], NDArray[np.int64],
                                          NDArray[np.int64]]:
    """For :func:`lever_arms`: every (point k, pivot, turning joint a) where a is k or an
    ancestor of k, whose rotation turns point k around that pivot."""
    rows = []
    for k in range(len(skel.joints)):
        a = k
        while a >= 0:
            parent = skel.joints[a].parent
            rows.append((k, a if skel.convention == "bvh" or parent < 0 else parent, a))
            a = parent
    out = np.array(rows, np.int64).reshape(-1, 3)
    return out[:, 0], out[:, 1], out[:, 2]


def rest_height(skel: Skeleton) -> float:
    """The skeleton's size: the largest extent over x, y, z of its joints at the zero pose
    (all channels 0), in its length unit; at least the longest single offset or bone."""
    p = forward(skel, np.zeros((1, skel.channel_count)))[0]
    extent = float(np.ptp(p, axis=0).max()) if len(p) else 0.0
    longest = max((math.hypot(*j.offset) + abs(j.length) * math.hypot(*j.direction)
                   for j in skel.joints), default=0.0)
    return max(extent, longest)
