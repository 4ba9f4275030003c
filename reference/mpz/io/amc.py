"""Acclaim ASF/AMC (CMU, HDM05) reading.

Contract: :func:`parse_asf` turns ASF text into a :class:`Skeleton`;
:func:`parse_amc` turns AMC text plus a skeleton into a :class:`mpz.Motion`
of joint positions: the root, then the end point of every bone in ASF
order, with ``parents`` from ``:hierarchy`` and every DOF channel in
``angles``. :func:`read_amc` is the thin file wrapper.

Forward kinematics (the Acclaim convention, as in the CMU viewer): with
``C`` the bone's ``axis`` rotation and ``M`` its DOF rotation,
``W_bone = W_parent @ C @ M @ C^-1`` and
``end = start + W_bone @ (direction * length)``; bone starts are the
parent bone's end (the root position for children of the root).
Rotation order: ``axis ... XYZ`` and ``dof rx ry rz`` both mean "X first",
i.e. ``R = Rz @ Ry @ Rx``.

Units: lengths are multiplied by ``(1 / :units length) * 25.4`` to give
millimetres (CMU ``length 0.45``: one file unit is 1/0.45 inch). This is
checked against the C3D of the same CMU take in docs/io-notes.md.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
import glob
import os

import numpy as np
from numpy.typing import NDArray

from mpz.errors import InputFormatError
from mpz.io._common import StrPath, decode_text, reader
from mpz.io.kinematics import axis_rotation
from mpz.motion import Motion

MM_PER_INCH = 25.4
_DOF = {"rx", "ry", "rz", "tx", "ty", "tz", "l"}
MAX_BONES = 1000


@dataclass
class Bone:
    """One ``:bonedata`` entry of an ASF file (``dof`` lower-case, e.g. ``"rx"``)."""

    name: str
    direction: NDArray[np.float64]
    length: float
    axis: NDArray[np.float64]  # degrees
    axis_order: str
    dof: list[str] = field(default_factory=list)


@dataclass
class Skeleton:
    """What an ASF file defines.

    Attributes
    ----------
    bones : list of Bone
        In ASF order (the root is not a bone).
    parent : dict
        Bone name -> parent name (``"root"`` for children of the root).
    root_order : list of str
        AMC channel order of the root, e.g. ``["TX", "TY", "TZ", "RX", "RY", "RZ"]``.
    root_axis : str
        Rotation order of the root, e.g. ``"XYZ"``.
    root_position, root_orientation : ndarray
    length_unit : float
        ``:units length``: file lengths are inches / this value.
    angle_unit : str
        ``"deg"`` or ``"rad"``.
    """

    bones: list[Bone]
    parent: dict[str, str]
    root_order: list[str]
    root_axis: str
    root_position: NDArray[np.float64]
    root_orientation: NDArray[np.float64]
    length_unit: float = 1.0
    angle_unit: str = "deg"
    name: str = ""

    @property
    def mm_per_unit(self) -> float:
        """Millimetres per ASF/AMC length unit: ``25.4 / length_unit``."""
        return MM_PER_INCH / self.length_unit


def _bad(msg: str) -> InputFormatError:
    return InputFormatError(f"ASF/AMC: {msg}")


def _sections(text: str) -> dict[str, list[str]]:
    """Split ASF text into ``{keyword: [lines]}`` at lines starting with ':'."""
    out: dict[str, list[str]] = {}
    cur = None
    for raw in text.splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith(":"):
            parts = line[1:].split(None, 1)
            cur = parts[0].lower()
            out.setdefault(cur, [])
            if len(parts) > 1:
                out[cur].append(parts[1])
        elif cur is not None:
            out[cur].append(line)
    return out


def _keyvals(lines: Iterable[str]) -> dict[str, list[str]]:
    """``{first word (lower case): the other words}`` of each line."""
    kv = {}
    for ln in lines:
        parts = ln.split()
        kv[parts[0].lower()] = parts[1:]
    return kv


def _vec3(vals: list[str], what: str) -> NDArray[np.float64]:
    if len(vals) < 3:
        raise _bad(f"{what} needs 3 numbers, got {vals}")
    return np.array([float(v) for v in vals[:3]])


def parse_asf(text: str) -> Skeleton:
    """Parse an ASF skeleton.

    Parameters
    ----------
    text : str

    Returns
    -------
    Skeleton

    Raises
    ------
    InputFormatError
        If ``:root``, ``:bonedata`` or ``:hierarchy`` is missing or malformed.
    """
    sec = _sections(text)
    for need in ("root", "bonedata", "hierarchy"):
        if need not in sec:
            raise _bad(f"ASF has no :{need} section")
    units = _keyvals(sec.get("units", []))
    length_unit = float(units.get("length", ["1.0"])[0])
    if not length_unit > 0:
        raise _bad(f":units length must be positive, got {length_unit}")
    angle_unit = units.get("angle", ["deg"])[0].lower()
    if angle_unit not in ("deg", "rad"):
        raise _bad(f"unknown :units angle {angle_unit!r}")
    root = _keyvals(sec["root"])
    root_order = [c.upper() for c in root.get("order", ["TX", "TY", "TZ", "RX", "RY", "RZ"])]
    root_axis = root.get("axis", ["XYZ"])[0].upper()
    root_position = _vec3(root.get("position", ["0", "0", "0"]), "root position")
    root_orientation = _vec3(root.get("orientation", ["0", "0", "0"]), "root orientation")

    bones: list[Bone] = []
    cur: dict[str, list[str]] | None = None
    for ln in sec["bonedata"]:
        parts = ln.split()
        key = parts[0].lower()
        if key == "begin":
            cur = {}
        elif key == "end":
            if cur is None:
                raise _bad("'end' without 'begin' in :bonedata")
            if "name" not in cur:
                raise _bad("bone without a name")
            axis = cur.get("axis", ["0", "0", "0", "XYZ"])
            bones.append(Bone(
                name=cur["name"][0],
                direction=_vec3(cur.get("direction", []), f"direction of {cur['name'][0]}"),
                length=float(cur.get("length", ["nan"])[0]),
                axis=_vec3(axis, f"axis of {cur['name'][0]}"),
                axis_order=(axis[3] if len(axis) > 3 else "XYZ").upper(),
                dof=[d.lower() for d in cur.get("dof", [])]))
            if len(bones) > MAX_BONES:
                raise _bad(f"more than {MAX_BONES} bones")
            cur = None
        elif cur is not None:
            cur[key] = parts[1:]
    if not bones:
        raise _bad("no bones in :bonedata")
    for b in bones:
        if not np.isfinite(b.length):
            raise _bad(f"bone {b.name!r} has no length")
        bad = [d for d in b.dof if d not in _DOF]
        if bad:
            raise _bad(f"bone {b.name!r} has unknown dof {bad}")
        if sorted(b.axis_order) != ["X", "Y", "Z"]:
            raise _bad(f"bone {b.name!r} has bad axis order {b.axis_order!r}")

    names = {b.name for b in bones}
    parent: dict[str, str] = {}
    for ln in sec["hierarchy"]:
        parts = ln.split()
        if parts[0].lower() in ("begin", "end"):
            continue
        p = parts[0]
        if p != "root" and p not in names:
            raise _bad(f":hierarchy names unknown bone {p!r}")
        for child in parts[1:]:
            if child not in names:
                raise _bad(f":hierarchy names unknown bone {child!r}")
            parent[child] = p
    missing = [b.name for b in bones if b.name not in parent]
    if missing:
        raise _bad(f"bones not in :hierarchy: {missing}")
    return Skeleton(bones, parent, root_order, root_axis, root_position, root_orientation,
                    length_unit, angle_unit, (sec.get("name") or [""])[0])


def _ordered(skel: Skeleton) -> list[Bone]:
    """Bones ordered so that every parent precedes its children (stable)."""
    done = {"root"}
    out: list[Bone] = []
    todo = list(skel.bones)
    while todo:
        rest = [b for b in todo if skel.parent[b.name] not in done]
        ready = [b for b in todo if skel.parent[b.name] in done]
        if not ready:
            raise _bad(f"cycle in :hierarchy around {[b.name for b in rest]}")
        out += ready
        done.update(b.name for b in ready)
        todo = rest
    return out


def _axes_matrix(order: str, deg: NDArray[np.float64]) -> NDArray[np.float64]:
    """Acclaim ``axis``/``dof`` rotation: the first letter is applied first."""
    R = np.eye(3)
    for ax in order:
        R = axis_rotation(ax, np.array([deg["XYZ".index(ax)]]))[0] @ R
    return R


def _dof_matrices(dofs: list[str], vals: NDArray[np.float64]) -> NDArray[np.float64]:
    """Per-frame DOF rotations; ``dofs`` in file order, first applied first."""
    F = vals.shape[0]
    R = np.broadcast_to(np.eye(3), (F, 3, 3)).copy()
    for k, d in enumerate(dofs):
        if d[0] == "r":
            R = axis_rotation(d[1].upper(), vals[:, k]) @ R
    return R


def parse_amc(text: str, skel: Skeleton, *, rate: float = 120.0, source: str = "") -> Motion:
    """Parse AMC frames and compute joint positions by forward kinematics.

    Parameters
    ----------
    text : str
        The AMC file.
    skel : Skeleton
        From :func:`parse_asf`.
    rate : float, optional
        Frames per second (AMC does not store it; CMU and HDM05 use 120).
    source : str, optional
        File name for the metadata.

    Returns
    -------
    Motion
        Points ``root`` then each bone's end, in mm; ``angles`` holds the root
        channels then every bone's DOF values (file units: degrees or radians,
        root translation in ASF length units), ``angle_names`` like
        ``"lfemur.rx"``.

    Raises
    ------
    InputFormatError
        On a frame with a missing or unknown bone, a wrong value count,
        non-consecutive frame numbers, or no frames.
    """
    bones = _ordered(skel)
    by_name = {b.name: b for b in skel.bones}
    # channel layout: root channels, then each bone's dofs in ASF order
    chan_names = [f"root.{c.lower()}" for c in skel.root_order]
    slot = {"root": (0, len(skel.root_order))}
    for b in skel.bones:
        slot[b.name] = (len(chan_names), len(b.dof))
        chan_names += [f"{b.name}.{d}" for d in b.dof]
    n_chan = len(chan_names)

    frames: list[np.ndarray] = []
    seen: set[str] = set()
    cur: NDArray[np.float64] | None = None
    expected_frame: int | None = None
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line or line.startswith(":"):
            continue
        parts = line.split()
        if len(parts) == 1 and parts[0].isdigit():
            n = int(parts[0])
            if expected_frame is not None and n != expected_frame:
                raise _bad(f"line {lineno}: frame {n} follows frame {expected_frame - 1}")
            expected_frame = n + 1
            if cur is not None:
                _check_frame(seen, slot, lineno)
                frames.append(cur)
            cur = np.full(n_chan, np.nan)
            seen = set()
            continue
        if cur is None:
            raise _bad(f"line {lineno}: data before the first frame number")
        name = parts[0]
        if name not in slot:
            raise _bad(f"line {lineno}: unknown bone {name!r}")
        start, count = slot[name]
        if len(parts) - 1 != count:
            raise _bad(f"line {lineno}: {name} has {len(parts) - 1} values, expected {count}")
        cur[start:start + count] = [float(v) for v in parts[1:]]
        seen.add(name)
    if cur is None:
        raise _bad("no frames in AMC")
    _check_frame(seen, slot, "end")
    frames.append(cur)
    values = np.array(frames)
    if not np.isfinite(values).all():
        raise _bad("non-finite value in AMC")

    positions, parents, names = _forward(skel, bones, by_name, slot, values)
    meta = {"format": "amc", "asf_length_unit": repr(skel.length_unit),
            "mm_per_unit": repr(skel.mm_per_unit), "rate_assumed": repr(float(rate))}
    if source:
        meta["source"] = source
    if skel.name:
        meta["skeleton"] = skel.name
    return Motion(positions, names, rate, "mm", None, meta, parents, values, chan_names)


def _check_frame(seen: set[str], slot: dict[str, tuple[int, int]], where: int | str) -> None:
    missing = [n for n, (_, c) in slot.items() if n not in seen and (c > 0 or n == "root")]
    if missing:
        raise _bad(f"frame ending at line {where} lacks {missing}")


def _forward(skel: Skeleton, bones: list[Bone], by_name: dict[str, Bone],
             slot: dict[str, tuple[int, int]],
             values: NDArray[np.float64]) -> tuple[NDArray[np.float64], list[int], list[str]]:
    """Forward kinematics: positions ``[F, 1 + bones, 3]`` (mm), parent indices, point names."""
    F = values.shape[0]
    to_rad = skel.angle_unit == "rad"
    scale = skel.mm_per_unit

    def deg(v: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.degrees(v) if to_rad else v

    # root: translation channels add to the ASF root position
    r0, rn = slot["root"]
    rv = values[:, r0:r0 + rn]
    trans = np.broadcast_to(skel.root_position, (F, 3)).copy()
    rot_dofs: list[str] = []
    rot_vals: list[NDArray[np.float64]] = []
    for k, c in enumerate(skel.root_order):
        if c.startswith("T"):
            trans[:, "XYZ".index(c[1])] += rv[:, k]
        elif c.startswith("R"):
            rot_dofs.append(c.lower())
            rot_vals.append(deg(rv[:, k]))
    C = _axes_matrix(skel.root_axis, deg(skel.root_orientation))
    M = _dof_matrices(rot_dofs, np.stack(rot_vals, axis=1) if rot_vals else np.zeros((F, 0)))
    world = {"root": C @ M @ C.T}
    end = {"root": trans}
    for b in bones:
        p = skel.parent[b.name]
        C = _axes_matrix(b.axis_order, deg(b.axis))
        s, n = slot[b.name]
        M = _dof_matrices(b.dof, deg(values[:, s:s + n]))
        W = world[p] @ C @ M @ C.T
        world[b.name] = W
        end[b.name] = end[p] + np.einsum("fij,j->fi", W, b.direction * b.length)
    names = ["root"] + [b.name for b in skel.bones]
    index = {n: i for i, n in enumerate(names)}
    parents = [-1] + [index[skel.parent[b.name]] for b in skel.bones]
    pos = np.stack([end[n] for n in names], axis=1) * scale
    return pos, parents, names


def find_asf(amc_path: StrPath) -> str:
    """The ASF for an AMC file: the longest ``*.asf`` in the same folder whose
    stem is a prefix of the AMC stem (``02_01.amc`` -> ``02.asf``,
    ``HDM_dg_06-03_03_120.amc`` -> ``HDM_dg.asf``).

    Raises
    ------
    InputFormatError
        If no such file exists.
    """
    amc_path = os.fspath(amc_path)
    folder = os.path.dirname(os.path.abspath(amc_path))
    stem = os.path.splitext(os.path.basename(amc_path))[0]
    cands: list[tuple[int, str]] = []
    for p in glob.glob(os.path.join(glob.escape(folder), "*")):
        s, e = os.path.splitext(os.path.basename(p))
        if e.lower() == ".asf" and stem.startswith(s) and s:
            cands.append((len(s), p))
    if not cands:
        raise InputFormatError(f"no .asf skeleton found for {os.path.basename(amc_path)} "
                               f"(looked for <prefix of {stem!r}>.asf in {folder}); pass asf=",
                               path=amc_path)
    return max(cands)[1]


@reader
def read_asf(path: StrPath) -> Skeleton:
    """Read an ASF skeleton file (see :func:`parse_asf`)."""
    with open(path, "rb") as fh:
        return parse_asf(decode_text(fh.read()))


@reader
def read_amc(amc_path: StrPath, asf_path: StrPath | None = None, *,
             rate: float = 120.0) -> Motion:
    """Read an AMC motion with its ASF skeleton.

    Parameters
    ----------
    amc_path : str or os.PathLike
    asf_path : str or os.PathLike, optional
        Default: found by :func:`find_asf`.
    rate : float, optional
        Frame rate (not stored in AMC); 120 Hz for CMU and HDM05.

    Returns
    -------
    Motion
        Joint positions in mm (see :func:`parse_amc`).

    Raises
    ------
    InputFormatError
    """
    if asf_path is None:
        asf_path = find_asf(amc_path)
    skel = read_asf(asf_path)
    with open(amc_path, "rb") as fh:
        text = decode_text(fh.read())
    m = parse_amc(text, skel, rate=rate, source=os.path.basename(os.fspath(amc_path)))
    m.metadata["asf"] = os.path.basename(os.fspath(asf_path))
    return m
