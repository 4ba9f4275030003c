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
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

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


def _channel(values: FloatArray, start: int, joint: Joint, kind: ChannelKind) -> FloatArray | None:
    """The values of ``joint``'s channel of ``kind`` (None when it has none)."""
    if kind in joint.channels:
        return values[:, start + joint.channels.index(kind)]
    return None


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
    if skel.convention == "bvh":
        return _forward_bvh(skel, v)
    return _forward_asf(skel, v)


def _forward_bvh(skel: Skeleton, v: FloatArray) -> FloatArray:
    F = v.shape[0]
    starts = skel.channel_starts()
    pos = np.empty((len(skel.joints), F, 3))
    rot = np.empty((len(skel.joints), F, 3, 3))
    for i, j in enumerate(skel.joints):
        trans = np.broadcast_to(np.asarray(j.offset, np.float64), (F, 3)).copy()
        R = np.broadcast_to(np.eye(3), (F, 3, 3)).copy()
        for k, c in enumerate(j.channels):
            x = v[:, starts[i] + k]
            if c <= ChannelKind.TZ:
                trans[:, c] += x
            else:
                R = R @ axis_rotation("XYZ"[c - ChannelKind.RX], skel.degrees(x))
        if j.parent < 0:
            pos[i], rot[i] = trans, R
        else:
            p = j.parent
            pos[i] = pos[p] + np.einsum("fij,fj->fi", rot[p], trans)
            rot[i] = rot[p] @ R
    return pos.transpose(1, 0, 2)


def _dof_rotation(joint: Joint, v: FloatArray, start: int, skel: Skeleton) -> FloatArray:
    """The dof rotation M of an ASF joint: the first rotation dof listed is applied first."""
    F = v.shape[0]
    M = np.broadcast_to(np.eye(3), (F, 3, 3)).copy()
    for k, c in enumerate(joint.channels):
        if ChannelKind.RX <= c <= ChannelKind.RZ:
            M = axis_rotation("XYZ"[c - ChannelKind.RX], skel.degrees(v[:, start + k])) @ M
    return M


def _forward_asf(skel: Skeleton, v: FloatArray) -> FloatArray:
    F = v.shape[0]
    starts = skel.channel_starts()
    pos = np.empty((len(skel.joints), F, 3))
    world: list[FloatArray] = []
    for i, j in enumerate(skel.joints):
        C = _axes_matrix(j.axis_order, [float(a) for a in skel.degrees(np.asarray(j.axis))])
        M = _dof_rotation(j, v, starts[i], skel)
        W_local = C @ M @ C.T
        t = np.zeros((F, 3))
        for a, kind in enumerate((ChannelKind.TX, ChannelKind.TY, ChannelKind.TZ)):
            x = _channel(v, starts[i], j, kind)
            if x is not None:
                t[:, a] = x
        if j.parent < 0:
            # the root: position plus its translation channels, rotation C M C^-1
            pos[i] = np.asarray(j.offset, np.float64) + t
            world.append(W_local)
            continue
        Wp = world[j.parent]
        W = Wp @ W_local
        world.append(W)
        ln = _channel(v, starts[i], j, ChannelKind.L)
        length = j.length + (ln if ln is not None else np.zeros(F))
        bone = np.asarray(j.direction, np.float64)[None, :] * length[:, None]
        pos[i] = (pos[j.parent] + np.einsum("fij,fj->fi", W, bone)
                  + np.einsum("fij,fj->fi", Wp @ C, t))
    return pos.transpose(1, 0, 2)


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
    p = np.asarray(positions, dtype=np.float64)
    n = len(skel.joints)
    arm = np.zeros(n)
    for k in range(n):
        # every ancestor a of k (and k itself) turns point k around a's pivot
        a = k
        while a >= 0:
            parent = skel.joints[a].parent
            pivot = a if skel.convention == "bvh" or parent < 0 else parent
            d = float(np.linalg.norm(p[:, k] - p[:, pivot], axis=1).max(initial=0.0))
            arm[a] = max(arm[a], d)
            a = parent
    return arm


def rest_height(skel: Skeleton) -> float:
    """The skeleton's size: the largest extent over x, y, z of its joints at the zero pose
    (all channels 0), in its length unit; at least the longest single offset or bone."""
    p = forward(skel, np.zeros((1, skel.channel_count)))[0]
    extent = float(np.ptp(p, axis=0).max()) if len(p) else 0.0
    longest = max((math.hypot(*j.offset) + abs(j.length) * math.hypot(*j.direction)
                   for j in skel.joints), default=0.0)
    return max(extent, longest)
