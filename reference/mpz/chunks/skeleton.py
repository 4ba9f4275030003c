"""The skeleton chunk types of MPZ 1.1 (spec §4.14), one record class each.

``bvhs`` (a BVH hierarchy) or ``asfs`` (an ASF skeleton with the layout of its AMC
motion) describes the skeleton whose joints are the file's markers, and carries its
channel layer: every joint channel, quantised on a decimal step and range-coded (§4.14,
§6.10). Both are ancillary: a 1.0 decoder skips them and still decodes the markers
(§2.1, §2.3). Each record checks its own § rules, the rule that a file holds one
skeleton chunk at most (from the chunk list in its :class:`~mpz.chunks.base.Context`),
and decodes its channel layer (:mod:`mpz.channels`), so a file that cannot be decoded
fails where every other chunk does. :mod:`mpz.skeleton` is the extension that turns
them into :attr:`mpz.Motion.extras` and back.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from mpz.channels import decode as decode_channels
from mpz.channels import dequantise, turn_steps
from mpz.chunks.base import Context, Record, forget, kept
from mpz.chunks.base import fail as _fail
from mpz.errors import LimitExceededError
from mpz.format import (
    AXIS_ORDERS,
    CHANNEL_VALUE_LIMIT,
    MAX_ORDER,
    MAX_STEP_DIGITS,
    ROOT_PARENT,
    SKELETON_MINOR,
    AngleUnit,
    ChannelKind,
    TextEncoding,
    Units,
)
from mpz.spec import grammar

#: channels per BVH joint: each of the six kinds at most once
MAX_BVH_CHANNELS = 6
#: §4.14 the skeleton chunk types: a file holds at most one of them
SKELETON_TYPES = ("bvhs", "asfs")


def _finite(values: tuple[float, ...]) -> bool:
    return all(math.isfinite(v) for v in values)


def _token(name: str) -> bool:
    """A name a text format can write as one word: no white space, no NUL."""
    return bool(name) and not any(c.isspace() or c == "\x00" for c in name)


def _kinds(channels: tuple[int, ...], top: int, what: str, section: str) -> None:
    """Channel kinds 0..top, none repeated."""
    if any(c > top for c in channels):  # R-4.14.1-1, R-4.14.2-1
        bad = next(c for c in channels if c > top)
        _fail(f"{what}: channel kind {bad} is not in 0..{top}", section)
    if len(set(channels)) != len(channels):  # R-4.14.1-1, R-4.14.2-1
        _fail(f"{what}: a channel kind repeats in {list(channels)}", section)


# ------------------------------------------------------- §4.14 channel layer --
@dataclass(frozen=True)
class ChannelCoding(Record):
    """§4.14 how one channel is quantised (step m x 10^-d, wrap) and predicted."""

    GRAMMAR = grammar.ChannelCoding

    step_mantissa: int
    step_digits: int
    wrap: int
    low: int
    order: int
    group: int


def _set_rule(ctx: Context) -> None:
    """§4.14: at most one skeleton chunk (bvhs or asfs) in a file (checked wherever the chunk
    list is known, that is for every chunk the decoder reads)."""
    n = sum(ctx.types.count(t) for t in SKELETON_TYPES)
    if n > 1:  # R-4.14-1
        _fail(f"a file holds at most one skeleton chunk (bvhs or asfs); this one has {n}",
              "§4.14")


def _check_layer(channel_count: int, expected: int, position_bound: float,
                 channels: tuple[ChannelCoding, ...], ctx: Context) -> None:
    """The §4.14 rules of a channel layer whose skeleton has ``expected`` channels."""
    F = ctx.header.frame_count
    if channel_count != expected:  # R-4.14-2
        _fail(f"the channel layer holds {channel_count} channels, the skeleton has {expected}",
              "§4.14")
    limit, lowered = ctx.limit("MAX_CHANNEL_SAMPLES")
    if F * channel_count > limit:  # R-4.14-3, R-8-2
        _fail(f"frame_count x channel_count = {F} x {channel_count} exceeds "
              f"{limit}{lowered}", "§8", LimitExceededError)
    # R-4.14-2
    if not (math.isfinite(position_bound) and position_bound >= 0):
        _fail(f"position bound {position_bound!r} is not finite and >= 0", "§4.14")
    for k, c in enumerate(channels):
        what = f"channel {k}"
        if c.step_mantissa < 1 or c.step_digits > MAX_STEP_DIGITS:  # R-4.14-2
            _fail(f"{what}: step {c.step_mantissa} x 10^-{c.step_digits} needs m >= 1 and "
                  f"d <= {MAX_STEP_DIGITS}", "§4.14")
        if c.order > MAX_ORDER or c.wrap > 1:  # R-4.14-2
            _fail(f"{what}: order {c.order} / wrap {c.wrap} out of range", "§4.14")
        if c.wrap:
            turn = turn_steps(c.step_mantissa, c.step_digits)
            if turn is None:  # R-4.14-2
                _fail(f"{what}: a wrapped channel needs a step that divides 360 of its units "
                      f"(360 x 10^d a multiple of m); {c.step_mantissa} x 10^-{c.step_digits} "
                      "does not", "§4.14")
                return
            # spec §4.14: "every value low .. low + N - 1 satisfies |x| < 2^31"
            # R-4.14-2
            if not (-CHANNEL_VALUE_LIMIT < c.low and c.low + turn <= CHANNEL_VALUE_LIMIT):
                _fail(f"{what}: the turn {c.low} .. {c.low} + {turn} - 1 leaves |x| < 2^31",
                      "§4.14")
        elif c.low:  # R-4.14-2
            _fail(f"{what}: low is {c.low}, but must be 0 when wrap is 0", "§4.14")
    groups = {c.group for c in channels}
    G = 1 + max(groups, default=-1)
    if groups != set(range(G)):  # R-4.14-2
        _fail(f"groups {sorted(set(range(G)) - groups)} hold no channel; groups are "
              f"numbered 0 .. G - 1", "§4.14")


class _Layer:
    """What both skeleton records do with their channel layer (§4.14, §6.10)."""

    TYPE: ClassVar[str]
    channels: tuple[ChannelCoding, ...]
    coded: bytes

    def integers(self, frames: int) -> NDArray[np.int64]:
        """§6.10 steps 1-3: the channel integers x ``[F, C]`` (after :meth:`check`),
        read-only: :meth:`check` decodes the layer to know that it decodes, and the result
        is kept until :meth:`values` takes it (:func:`~mpz.chunks.base.kept`)."""
        return kept(self, frames, lambda: self._integers(frames))

    def _integers(self, frames: int) -> NDArray[np.int64]:
        x = decode_channels(self.channels, self.coded, frames, chunk=self.TYPE)
        x.flags.writeable = False
        return x

    def values(self, frames: int) -> NDArray[np.float64]:
        """§6.10: the channel values ``[F, C]`` in the file's units (after :meth:`check`);
        the integers kept by :meth:`integers` are let go here."""
        x = self.integers(frames)
        forget(self)
        return dequantise(x, self.channels)


# ---------------------------------------------------------------- §4.14.1 bvhs --
@dataclass(frozen=True)
class BvhJoint(Record):
    """§4.14.1 one joint of a BVH hierarchy: a ROOT, a JOINT or (empty name) an End Site."""

    GRAMMAR = grammar.BvhJoint

    name: str
    parent: int
    offset: tuple[float, float, float]
    channel_count: int
    channels: tuple[int, ...]

    @property
    def end_site(self) -> bool:
        return not self.name


@dataclass(frozen=True)
class Bvhs(_Layer, Record):
    """§4.14.1 a BVH hierarchy, whose joints are the markers in order, and its channels
    (ancillary, 1.1)."""

    TYPE = "bvhs"
    SECTION = "§4.14.1"
    GRAMMAR = grammar.BVHS
    NESTED = {"joints": BvhJoint, "channels": ChannelCoding}
    MINOR = SKELETON_MINOR
    PART = "skeleton"

    encoding: int
    frame_time: float
    joint_count: int
    joints: tuple[BvhJoint, ...]
    channel_count: int
    position_bound: float
    channels: tuple[ChannelCoding, ...]
    coded: bytes

    @property
    def skeleton_channels(self) -> int:
        """The channel count the joints declare."""
        return sum(j.channel_count for j in self.joints)

    def check(self, ctx: Context) -> None:
        _set_rule(ctx)
        if self.encoding not in set(TextEncoding):  # R-4.14.1-1
            _fail(f"unknown text encoding {self.encoding}", "§4.14.1")
        # R-4.14.1-1
        if not (math.isfinite(self.frame_time) and self.frame_time > 0):
            _fail(f"frame time {self.frame_time!r} is not finite and > 0", "§4.14.1")
        M = ctx.header.marker_count
        if self.joint_count != M:  # R-4.14.1-1
            _fail(f"bvhs lists {self.joint_count} joints for {M} markers", "§4.14.1")
        # spec §4.14.1: a joint's parent is joint i - 1 or an ancestor of joint i - 1
        # (depth-first order), or none for a ROOT
        chain: list[int] = []          # joint i - 1, its parent, its grandparent, ...
        for i, j in enumerate(self.joints):
            what = f"joint {i}"
            if j.parent == ROOT_PARENT:
                above: list[int] = []
            elif j.parent in chain:
                above = chain[chain.index(j.parent):]
                if self.joints[j.parent].end_site:  # R-4.14.1-1
                    _fail(f"{what} is the child of an End Site (joint {j.parent})", "§4.14.1")
            else:  # R-4.14.1-1
                _fail(f"{what} has parent {j.parent}, which is neither joint {i - 1} nor one "
                      f"of its ancestors (joints are listed depth first)", "§4.14.1")
            chain = [i, *above]
            if j.end_site:
                if j.parent == ROOT_PARENT or j.channel_count:  # R-4.14.1-1
                    _fail(f"{what}: an End Site (empty name) needs a parent and no channels",
                          "§4.14.1")
            elif not _token(j.name):  # R-4.14.1-1
                _fail(f"{what}: name {j.name!r} contains white space or NUL", "§4.14.1")
            if not _finite(j.offset):  # R-4.14.1-1
                _fail(f"{what}: OFFSET must be finite", "§4.14.1")
            if j.channel_count > MAX_BVH_CHANNELS:  # R-4.14.1-1
                _fail(f"{what}: {j.channel_count} channels, at most {MAX_BVH_CHANNELS}",
                      "§4.14.1")
            _kinds(j.channels, ChannelKind.RZ, what, "§4.14.1")
        _check_layer(self.channel_count, self.skeleton_channels, self.position_bound,
                     self.channels, ctx)
        self.integers(ctx.header.frame_count)          # §6.10: the layer must decode


# ---------------------------------------------------------------- §4.14.2 asfs --
@dataclass(frozen=True)
class AsfBone(Record):
    """§4.14.2 one bone of an ASF skeleton (joint b + 1 of the skeleton)."""

    GRAMMAR = grammar.AsfBone

    bone_id: int
    name: str
    parent: int
    direction: tuple[float, float, float]
    length: float
    axis: tuple[float, float, float]
    axis_order: int
    dof_count: int
    dofs: tuple[int, ...]
    limit_count: int
    limits: tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class Asfs(_Layer, Record):
    """§4.14.2 an ASF skeleton (joint 0 the root, then the bones), the layout of its AMC
    motion, and its channels (ancillary, 1.1)."""

    TYPE = "asfs"
    SECTION = "§4.14.2"
    GRAMMAR = grammar.ASFS
    NESTED = {"bones": AsfBone, "channels": ChannelCoding}
    MINOR = SKELETON_MINOR
    PART = "skeleton"

    encoding: int
    angle_unit: int
    length_unit: float
    mass: str
    version: str
    name: str
    documentation: str
    comments: str
    root_order_count: int
    root_order: tuple[int, ...]
    root_axis_order: int
    root_position: tuple[float, float, float]
    root_orientation: tuple[float, float, float]
    bone_count: int
    bones: tuple[AsfBone, ...]
    amc_header: str
    first_frame: int
    amc_count: int
    amc_order: tuple[int, ...]
    channel_count: int
    position_bound: float
    channels: tuple[ChannelCoding, ...]
    coded: bytes

    @property
    def skeleton_channels(self) -> int:
        """The channel count the root order and the bones' dofs declare."""
        return self.root_order_count + sum(b.dof_count for b in self.bones)

    def check(self, ctx: Context) -> None:
        sec = "§4.14.2"
        _set_rule(ctx)
        if ctx.header.units != Units.MM:  # R-4.14.2-1
            _fail(f"an asfs file's markers are in mm (units 1), not units "
                  f"{ctx.header.units}", sec)
        if self.encoding not in set(TextEncoding):  # R-4.14.2-1
            _fail(f"unknown text encoding {self.encoding}", sec)
        if self.angle_unit not in set(AngleUnit):  # R-4.14.2-1
            _fail(f"unknown angle unit {self.angle_unit}", sec)
        if not (math.isfinite(self.length_unit) and self.length_unit > 0):  # R-4.14.2-1
            _fail(f"length unit {self.length_unit!r} is not finite and > 0", sec)
        for what, text in (("mass", self.mass), ("version", self.version), ("name", self.name)):
            # R-4.14.2-1
            if "\n" in text or "\r" in text:
                _fail(f"the {what} text is one line; it holds a line break", sec)
        if self.root_order_count > ChannelKind.RZ + 1:  # R-4.14.2-1
            _fail(f"root order lists {self.root_order_count} channels, at most 6", sec)
        _kinds(self.root_order, ChannelKind.RZ, "root", sec)
        # R-4.14.2-1
        if self.root_axis_order >= len(AXIS_ORDERS):
            _fail(f"root axis order {self.root_axis_order} not in 0..5", sec)
        # R-4.14.2-1
        if not _finite(self.root_position + self.root_orientation):
            _fail("root position and orientation must be finite", sec)
        M = ctx.header.marker_count
        if self.bone_count != M - 1:  # R-4.14.2-1
            _fail(f"asfs lists {self.bone_count} bones for {M} markers (the root is marker 0)",
                  sec)
        names: set[str] = set()
        for b, bone in enumerate(self.bones):
            what = f"bone {b} ({bone.name!r})"
            if not _token(bone.name) or bone.name == "root" or bone.name in names:  # R-4.14.2-1
                _fail(f"{what}: names are unique words other than 'root'", sec)
            names.add(bone.name)
            # bone b is joint b + 1: its parent is the root (0) or an earlier bone
            # R-4.14.2-1
            if bone.parent > b:
                _fail(f"{what} has parent joint {bone.parent}; parents come first", sec)
            # R-4.14.2-1
            if not (_finite(bone.direction + bone.axis) and math.isfinite(bone.length)):
                _fail(f"{what}: direction, length and axis must be finite", sec)
            if bone.axis_order >= len(AXIS_ORDERS):  # R-4.14.2-1
                _fail(f"{what}: axis order {bone.axis_order} not in 0..5", sec)
            if bone.dof_count > ChannelKind.L + 1:  # R-4.14.2-1
                _fail(f"{what}: {bone.dof_count} dofs, at most 7", sec)
            _kinds(bone.dofs, ChannelKind.L, what, sec)
            if bone.limit_count not in (0, bone.dof_count):  # R-4.14.2-1
                _fail(f"{what}: {bone.limit_count} limits for {bone.dof_count} dofs", sec)
            if any(math.isnan(v) for lim in bone.limits for v in lim):  # R-4.14.2-1
                _fail(f"{what}: a limit is NaN", sec)
        joints = self.bone_count + 1
        if not 1 <= self.amc_count <= joints:  # R-4.14.2-1
            _fail(f"AMC order lists {self.amc_count} joints, not 1..{joints}", sec)
        seen: set[int] = set()
        for k in self.amc_order:
            # R-4.14.2-1
            if k >= joints or k in seen:
                _fail(f"AMC order: joint {k} is out of range or repeated", sec)
            seen.add(k)
        need = {0} | {b + 1 for b, bone in enumerate(self.bones) if bone.dof_count}
        if not need <= seen:  # R-4.14.2-1
            _fail(f"AMC order leaves out joints {sorted(need - seen)} that have channels", sec)
        _check_layer(self.channel_count, self.skeleton_channels, self.position_bound,
                     self.channels, ctx)
        self.integers(ctx.header.frame_count)          # §6.10: the layer must decode


#: the skeleton chunk types, in the order of the spec's catalogue (§4.14.1, §4.14.2)
SKELETON = (Bvhs, Asfs)
