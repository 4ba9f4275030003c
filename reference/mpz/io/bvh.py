"""BVH (Biovision hierarchy) reading.

Contract: :func:`parse_bvh` takes the text of a BVH file and returns a
:class:`mpz.Motion` of joint-centre trajectories computed by forward
kinematics: one point per ROOT/JOINT, plus one per ``End Site`` named
``<parent>_End``, in file order. ``parents`` gives the hierarchy; the raw
channel values are kept in ``angles`` with names like ``Hips.Xrotation``.

Conventions: a joint's local transform is ``T(OFFSET + position channels)
@ R``, where ``R`` multiplies the rotation channels in the order listed
(``CHANNELS 3 Zrotation Xrotation Yrotation`` gives ``Rz @ Rx @ Ry``), the
usual BVH reading. BVH has no unit field; units are ``""`` (the CMU
conversions here are roughly centimetre-like, see docs/io-notes.md).
"""
from __future__ import annotations

import os

import numpy as np
from numpy.typing import NDArray

from mpz.errors import InputFormatError
from mpz.io._common import StrPath, decode_text, reader
from mpz.io.kinematics import axis_rotation
from mpz.motion import Motion

_CHANNELS = {"XPOSITION", "YPOSITION", "ZPOSITION", "XROTATION", "YROTATION", "ZROTATION"}
MAX_JOINTS = 10000  # sanity bound on the hierarchy size
MAX_CHANNELS_PER_JOINT = 6 * 4  # generous: a joint rarely has more than 6


class _Joint:
    """A ROOT, JOINT or End Site: parent index (-1 for a root) and its channels."""

    __slots__ = ("name", "parent", "offset", "channels", "first_channel", "end")

    def __init__(self, name: str, parent: int, end: bool = False) -> None:
        self.name, self.parent, self.end = name, parent, end
        self.offset: NDArray[np.float64] = np.zeros(3)
        self.channels: list[str] = []
        self.first_channel = 0


def _bad(msg: str) -> InputFormatError:
    return InputFormatError(f"BVH: {msg}")


def _parse_hierarchy(tokens: list[str], pos: int) -> tuple[list[_Joint], int, int]:
    """Parse from after 'HIERARCHY' to 'MOTION'. Returns (joints, n_channels, pos)."""
    joints: list[_Joint] = []
    stack: list[int] = []
    pending: _Joint | None = None
    n_channels = 0
    while pos < len(tokens):
        t = tokens[pos]
        up = t.upper()
        if up == "MOTION":
            break
        if up in ("ROOT", "JOINT"):
            if up == "JOINT" and not stack:
                raise _bad("JOINT outside of a ROOT block")
            if pos + 1 >= len(tokens):
                raise _bad(f"{t} without a name")
            pending = _Joint(tokens[pos + 1], stack[-1] if stack else -1)
            pos += 2
        elif up == "END":
            if not stack:
                raise _bad("End Site outside of a joint")
            # "End Site": named after its parent
            pending = _Joint(f"{joints[stack[-1]].name}_End", stack[-1], end=True)
            pos += 2
        elif t == "{":
            if pending is None:
                raise _bad("'{' without ROOT/JOINT/End Site")
            if len(joints) >= MAX_JOINTS:
                raise _bad(f"more than {MAX_JOINTS} joints")
            joints.append(pending)
            stack.append(len(joints) - 1)
            pending = None
            pos += 1
        elif t == "}":
            if not stack:
                raise _bad("unbalanced '}'")
            stack.pop()
            pos += 1
        elif up == "OFFSET":
            if not stack:
                raise _bad("OFFSET outside of a joint")
            joints[stack[-1]].offset = np.array([float(x) for x in tokens[pos + 1:pos + 4]])
            if joints[stack[-1]].offset.shape != (3,):
                raise _bad("OFFSET needs 3 numbers")
            pos += 4
        elif up == "CHANNELS":
            if not stack:
                raise _bad("CHANNELS outside of a joint")
            j = joints[stack[-1]]
            n = int(tokens[pos + 1])
            if not 0 <= n <= MAX_CHANNELS_PER_JOINT:
                raise _bad(f"bad channel count {n} for joint {j.name!r}")
            chans = tokens[pos + 2:pos + 2 + n]
            if len(chans) != n or any(c.upper() not in _CHANNELS for c in chans):
                raise _bad(f"bad CHANNELS for joint {j.name!r}: {chans}")
            j.channels = [c[0].upper() + c[1:].lower() for c in chans]
            j.first_channel = n_channels
            n_channels += n
            pos += 2 + n
        else:
            raise _bad(f"unexpected token {t!r} in HIERARCHY")
    if stack:
        raise _bad("HIERARCHY ends inside a joint block (missing '}')")
    if not joints:
        raise _bad("no joints in HIERARCHY")
    return joints, n_channels, pos


def _names(joints: list[_Joint]) -> list[str]:
    """Unique point names: a repeated name gets '#2', '#3', ..."""
    seen: dict[str, int] = {}
    out: list[str] = []
    for j in joints:
        n = j.name
        if n in seen:
            seen[n] += 1
            n = f"{n}#{seen[j.name]}"
        else:
            seen[n] = 1
        out.append(n)
    return out


def frame_rate_from_frame_time(ft: float) -> float:
    """``1 / ft``, snapped to the nearest integer when within 1e-3 of it.

    BVH stores the frame time with few digits (``0.0083333`` for 120 Hz).

    Examples
    --------
    >>> frame_rate_from_frame_time(0.0083333)
    120.0
    >>> frame_rate_from_frame_time(0.04)
    25.0
    """
    if not ft > 0:
        raise _bad(f"Frame Time must be positive, got {ft!r}")
    r = 1.0 / ft
    return float(round(r)) if abs(r - round(r)) < 1e-3 else r


def forward_kinematics(joints: list[_Joint], values: NDArray[np.float64]) -> NDArray[np.float64]:
    """World positions of every joint, shape (frames, joints, 3)."""
    F = values.shape[0]
    rot = np.empty((len(joints), F, 3, 3))
    pos = np.empty((len(joints), F, 3))
    for i, j in enumerate(joints):
        trans = np.broadcast_to(j.offset, (F, 3)).copy()
        R = np.broadcast_to(np.eye(3), (F, 3, 3)).copy()
        for k, ch in enumerate(j.channels):
            v = values[:, j.first_channel + k]
            if ch.endswith("position"):
                trans[:, "XYZ".index(ch[0])] += v
            else:
                R = R @ axis_rotation(ch[0], v)
        if j.parent < 0:
            pos[i], rot[i] = trans, R
        else:
            p = j.parent
            pos[i] = pos[p] + np.einsum("fij,fj->fi", rot[p], trans)
            rot[i] = rot[p] @ R
    return pos.transpose(1, 0, 2)


def parse_bvh(text: str, *, source: str = "") -> Motion:
    """Parse BVH text into a Motion of joint centres.

    Parameters
    ----------
    text : str
        The whole file.
    source : str, optional
        File name for the metadata.

    Returns
    -------
    Motion

    Raises
    ------
    InputFormatError
        On a malformed hierarchy, a missing MOTION section, or a frame
        count or row width that does not match the channels.
    """
    tokens = text.split()
    if not tokens or tokens[0].upper() != "HIERARCHY":
        raise _bad("file does not start with HIERARCHY")
    joints, n_channels, pos = _parse_hierarchy(tokens, 1)
    if pos >= len(tokens):
        raise _bad("no MOTION section")
    # MOTION / Frames: n / Frame Time: t
    head = tokens[pos + 1:pos + 6]
    if (len(head) < 5 or head[0].rstrip(":").upper() != "FRAMES"
            or head[2].upper() != "FRAME" or head[3].rstrip(":").upper() != "TIME"):
        raise _bad(f"expected 'Frames: n' and 'Frame Time: t' after MOTION, got {head}")
    n_frames = int(head[1])
    ft = float(head[4])
    rate = frame_rate_from_frame_time(ft)
    data = tokens[pos + 6:]
    if n_frames <= 0:
        raise _bad(f"Frames must be positive, got {n_frames}")
    need = n_frames * n_channels
    if len(data) < need:
        raise _bad(f"{len(data)} values for {n_frames} frames x {n_channels} channels "
                   f"(truncated motion data)")
    if len(data) > need:
        raise _bad(f"{len(data) - need} values beyond {n_frames} frames x {n_channels} channels")
    values = np.array(data, dtype=np.float64).reshape(n_frames, n_channels) if n_channels \
        else np.zeros((n_frames, 0))
    if not np.isfinite(values).all():
        raise _bad("non-finite channel value")
    positions = forward_kinematics(joints, values)
    angle_names = [f"{j.name}.{c}" for j in joints for c in j.channels]
    meta = {"format": "bvh", "frame_time": repr(ft), "channels": str(n_channels),
            "joints": str(sum(not j.end for j in joints)),
            "end_sites": str(sum(j.end for j in joints))}
    if source:
        meta["source"] = source
    return Motion(positions, _names(joints), rate, "", None, meta,
                  [j.parent for j in joints], values, angle_names)


@reader
def read_bvh(path: StrPath) -> Motion:
    """Read a BVH file (see :func:`parse_bvh`).

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    Motion
        Joint centres and end sites, ``units=""``, ``parents`` and ``angles`` set.

    Raises
    ------
    InputFormatError
    """
    with open(path, "rb") as fh:
        text = decode_text(fh.read())
    return parse_bvh(text, source=os.path.basename(os.fspath(path)))
