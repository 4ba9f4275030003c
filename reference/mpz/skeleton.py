"""Skeletal motion (BVH, AMC/ASF) in MPZ 1.1: the ``"skeleton"`` extension.

Strategy: the marker layer of MPZ 1.0 keeps holding the joint positions (forward
kinematics of the skeleton, one marker per joint), so a 1.0 decoder still decodes
positions (spec §2.1). What the source file holds besides, the skeleton and the channel
values per frame, goes in one ancillary chunk (spec §4.14): ``bvhs`` for a BVH
hierarchy, ``asfs`` for an ASF skeleton with the layout of its AMC motion. This module

- turns a :class:`mpz.io.kinematics.Skeleton` and its channel values into that record and
  back (:func:`skeleton_record`, :func:`skeleton_of_record`);
- chooses each channel's decimal step from the declared bounds (:func:`plan_steps`: degrees
  for rotations, the skeleton's length unit for translations), or, for a bound on joint
  positions, the coarsest steps that keep it (:func:`steps_for_position`); the channel
  codec itself is :mod:`mpz.channels`;
- measures the joint-position error the channels cause (:func:`position_error`) and
  declares it in the record;
- is the extension of :data:`mpz.extensions.EXTENSIONS` (:class:`SkeletonExtension`).

What was measured, and kept or not (bench/bench_skeleton.py, the closing note of issue
13): the file's own Euler channels on a decimal grid (it reproduces the text), the
predictor order per channel, activity groups (6-10 % smaller than one block), wrapping;
not kept: quaternions and exponential maps per joint (they cannot give back the file's
Euler values within the bound, and were larger at the same joint-position error),
prediction from the parent joint (< 1 % on the real files), noise-shaped quantisation on a
finer grid (15-20 % larger).
"""
from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace
import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from mpz.channels import (
    Step,
    coded_values,
    dequantise,
    group,
    plan,
    quantise,
    step_for,
)
from mpz.chunks import Record
from mpz.chunks.skeleton import SKELETON_TYPES, AsfBone, Asfs, BvhJoint, Bvhs, ChannelCoding
from mpz.errors import EncoderError, MotionError
from mpz.format import (
    AXIS_ORDERS,
    MAX_CHANNEL_SAMPLES,
    MAX_STEP_DIGITS,
    MM_PER_UNIT,
    ROOT_PARENT,
    AngleUnit,
    ChannelKind,
    TextEncoding,
)
from mpz.io.kinematics import (
    MM_PER_INCH,
    Joint,
    Skeleton,
    _farthest,
    forward,
    rest_height,
    squared_lengths,
)
from mpz.motion import Motion

if TYPE_CHECKING:
    from mpz.encoder import EncodeOptions

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]

#: the default bound on every channel: 0.01 degrees for rotations, 0.01 of the skeleton's
#: length unit for translations (issue 13: "round-trips every channel within 0.01")
DEFAULT_CHANNEL_ERROR = 0.01
#: the reference encoder codes the marker layer of a skeletal file, when no bound is asked
#: for, within this fraction of the skeleton's size (Appendix C: 3.4 mm for a 1.7 m body)
PREVIEW_FRACTION = 2e-3
#: joint positions computed at a time where the encoder measures the channels' error
#: (:func:`position_error`, :func:`lever_arms_of`): 2^16 joint-frames, 1.5 MiB a block.
#: The joint positions of every frame were held there, each measure with a second set
#: and their difference: a 183 KB BVH of 4096 joints and 10,000 frames took 3.3 times
#: its 983 MB of positions for it, beside the marker layer's coding
JOINT_FRAMES = 1 << 16
#: (point, pivot) pairs of :func:`lever_arms_of` measured at a time
ARM_PAIRS = 1 << 18
#: the position search (:func:`steps_for_position`) holds the source's joint positions of
#: every frame when there are at most this many (48 MiB; every real capture here, and a
#: BVH of 57 joints up to 36,000 frames), and computes them a block at a time in each
#: measure beyond: a measure then costs two forward kinematics instead of one
HELD_JOINTS = 1 << 21


# --------------------------------------------------------------- records --
def _encoding_code(name: str) -> int:
    return int(TextEncoding.LATIN1 if name == "latin-1" else TextEncoding.UTF8)


def _encoding_name(code: int) -> str:
    return "latin-1" if code == TextEncoding.LATIN1 else "utf-8"


def _vec(v: Sequence[float]) -> tuple[float, float, float]:
    return float(v[0]), float(v[1]), float(v[2])


def skeleton_record(skel: Skeleton, codings: tuple[ChannelCoding, ...], coded: bytes,
                    position_bound: float) -> Bvhs | Asfs:
    """The ``bvhs`` or ``asfs`` record of a skeleton and its channel layer (spec §4.14).

    Raises
    ------
    EncoderError
        For what the chunk cannot hold (a BVH joint that lists a channel twice, text
        longer than its field, ...).
    """
    C, bound = len(codings), float(position_bound)
    if skel.convention == "bvh":
        joints = []
        for i, j in enumerate(skel.joints):
            if len(set(j.channels)) != len(j.channels):
                raise EncoderError(f"BVH joint {j.name!r} lists a channel twice; MPZ stores "
                                   "each channel kind once per joint (spec §4.14.1)")
            _fits(j.name, 255, f"joint {i} name")
            joints.append(BvhJoint(name=j.name, parent=ROOT_PARENT if j.parent < 0 else j.parent,
                                   offset=_vec(j.offset), channel_count=len(j.channels),
                                   channels=tuple(j.channels)))
        return Bvhs(encoding=_encoding_code(skel.encoding), frame_time=float(skel.frame_time),
                    joint_count=len(joints), joints=tuple(joints), channel_count=C,
                    position_bound=bound, channels=codings, coded=coded)
    root = skel.joints[0]
    bones = []
    for b, j in enumerate(skel.joints[1:]):
        _fits(j.name, 255, f"bone {b} name")
        bones.append(AsfBone(bone_id=int(j.bone_id), name=j.name, parent=j.parent,
                             direction=_vec(j.direction), length=float(j.length),
                             axis=_vec(j.axis), axis_order=AXIS_ORDERS.index(j.axis_order),
                             dof_count=len(j.channels), dofs=tuple(j.channels),
                             limit_count=len(j.limits),
                             limits=tuple((float(lo), float(hi)) for lo, hi in j.limits)))
    for what, text, n in (("mass", skel.mass, 255), ("version", skel.version, 255),
                          ("name", skel.name, 255), ("documentation", skel.documentation, 65535),
                          ("comments", skel.comments, 65535),
                          ("AMC header", skel.amc_header, 65535)):
        _fits(text, n, f"ASF {what}")
    return Asfs(encoding=_encoding_code(skel.encoding),
                angle_unit=int(AngleUnit.RAD if skel.angle_unit == "rad" else AngleUnit.DEG),
                length_unit=float(skel.length), mass=skel.mass, version=skel.version,
                name=skel.name, documentation=skel.documentation, comments=skel.comments,
                root_order_count=len(root.channels), root_order=tuple(root.channels),
                root_axis_order=AXIS_ORDERS.index(root.axis_order),
                root_position=_vec(root.offset), root_orientation=_vec(root.axis),
                bone_count=len(bones), bones=tuple(bones), amc_header=skel.amc_header,
                first_frame=int(skel.first_frame), amc_count=len(skel.amc_order),
                amc_order=tuple(skel.amc_order), channel_count=C, position_bound=bound,
                channels=codings, coded=coded)


def _fits(text: str, limit: int, what: str) -> None:
    if len(text.encode("utf-8")) > limit:
        raise EncoderError(f"{what} is longer than the {limit} bytes its field holds "
                           "(spec §4.14)")


def skeleton_of_record(rec: Bvhs | Asfs) -> Skeleton:
    """The skeleton a checked ``bvhs`` or ``asfs`` record describes."""
    if isinstance(rec, Bvhs):
        joints = tuple(Joint(j.name, -1 if j.parent == ROOT_PARENT else j.parent,
                             tuple(j.channels), _vec(j.offset), end_site=not j.name)
                       for j in rec.joints)
        return Skeleton("bvh", joints, frame_time=rec.frame_time,
                        encoding=_encoding_name(rec.encoding))
    root = Joint("root", -1, tuple(rec.root_order), _vec(rec.root_position),
                 axis=_vec(rec.root_orientation), axis_order=AXIS_ORDERS[rec.root_axis_order])
    bones = tuple(Joint(b.name, b.parent, tuple(b.dofs), direction=_vec(b.direction),
                        length=b.length, axis=_vec(b.axis), axis_order=AXIS_ORDERS[b.axis_order],
                        limits=tuple((lo, hi) for lo, hi in b.limits), bone_id=b.bone_id)
                  for b in rec.bones)
    return Skeleton("asf", (root, *bones),
                    angle_unit="rad" if rec.angle_unit == AngleUnit.RAD else "deg",
                    encoding=_encoding_name(rec.encoding), length=rec.length_unit,
                    mass=rec.mass, version=rec.version, name=rec.name,
                    documentation=rec.documentation, comments=rec.comments,
                    amc_header=rec.amc_header, first_frame=rec.first_frame,
                    amc_order=tuple(rec.amc_order))


def marker_scale(skel: Skeleton) -> float:
    """Marker units per skeleton length unit: 25.4 / ``length`` for ASF (the marker layer
    is in mm), 1 for BVH (the marker layer is in the file's own unit)."""
    return MM_PER_INCH / skel.length if skel.convention == "asf" else 1.0


# ---------------------------------------------------------------- steps --
def is_rotation(kind: int) -> bool:
    return ChannelKind.RX <= kind <= ChannelKind.RZ


def plan_steps(skel: Skeleton, angle_error: float, translation_error: float) -> list[Step]:
    """One step per channel: rotations within ``angle_error`` degrees (converted for a
    skeleton in radians), translations and bone stretch within ``translation_error``
    skeleton length units."""
    rad = skel.angle_unit == "rad"
    rot = step_for(math.radians(angle_error) if rad else angle_error)
    lin = step_for(translation_error)
    return [rot if is_rotation(k) else lin for k in skel.channel_kinds()]


def code_channels(values: FloatArray, skel: Skeleton, steps: Sequence[Step]
                  ) -> tuple[tuple[ChannelCoding, ...], bytes]:
    """The channel layer of values ``[F, C]`` at the given steps (spec §4.14): the channel
    entries and the coded field."""
    x = quantise(values, steps, skel.channel_names())
    degrees = skel.angle_unit == "deg"
    plans = plan(x, steps, [degrees and is_rotation(k) for k in skel.channel_kinds()])
    groups, coded = group(coded_values(x, plans))
    codings = tuple(ChannelCoding(step_mantissa=p.step.mantissa, step_digits=p.step.digits,
                                  wrap=int(p.wrap), low=p.low, order=p.order, group=int(g))
                    for p, g in zip(plans, groups, strict=True))
    return codings, coded


# ------------------------------------------------------------ bounds --
def position_error(skel: Skeleton, a: FloatArray, b: FloatArray,
                   joints_a: FloatArray | None = None) -> float:
    """The largest distance, in marker units, between the joint positions of channel
    values ``a`` and ``b`` (spec §6.10); ``joints_a``: ``forward(skel, a)``, when the
    caller already has it (the position-bound search compares one ``a`` many times).

    The joints are computed :data:`JOINT_FRAMES` joint-frames at a time: forward
    kinematics works frame by frame, and the maximum of the blocks' maxima is the
    maximum, so the value is the one of the whole arrays, bit for bit."""
    if skel.channel_count == 0:
        return 0.0
    far = np.float64(0.0)
    for rows in _frame_blocks(a.shape[0], len(skel.joints)):
        pa = forward(skel, a[rows]) if joints_a is None else joints_a[rows]
        # sqrt is monotone: the largest distance is the root of the largest squared one;
        # np.maximum keeps a NaN, as the whole array's max did
        far = np.maximum(far, squared_lengths(pa - forward(skel, b[rows])).max(initial=0.0))
    return math.sqrt(float(far)) * marker_scale(skel)


def _frame_blocks(F: int, J: int, joint_frames: int | None = None) -> list[slice]:
    """Consecutive slices of ``F`` frames of about ``joint_frames`` (default
    :data:`JOINT_FRAMES`) joint positions each, for ``J`` joints (one frame at least)."""
    rows = max(1, (JOINT_FRAMES if joint_frames is None else joint_frames) // max(J, 1))
    return [slice(f, f + rows) for f in range(0, F, rows)]


def _arm_pairs(skel: Skeleton, turning: NDArray[np.bool_], limit: int
               ) -> Iterator[tuple[IntArray, IntArray, IntArray]]:
    """:func:`mpz.io.kinematics.lever_arms`' (point k, pivot, turning joint a) triples, for
    the joints a where ``turning`` is set only, in lists of about ``limit`` (one ancestor
    level of every point at a time, so at most ``limit`` + J each): the whole list is J
    times the depth of the tree, 8.4 million triples (201 MB, and a Python list of them
    several times that) for a chain of 4096 joints."""
    parent = np.array(skel.parents(), np.int64)
    bvh = skel.convention == "bvh"
    k = np.arange(len(parent), dtype=np.int64)       # the points ...
    a = k.copy()                                     # ... and an ancestor of each (or self)
    moved: list[IntArray] = []
    pivots: list[IntArray] = []
    turner: list[IntArray] = []
    held = 0
    while k.size:
        sel = turning[a]
        if sel.any():
            ks, ts = k[sel], a[sel]
            moved.append(ks)
            pivots.append(ts if bvh else np.where(parent[ts] < 0, ts, parent[ts]))
            turner.append(ts)
            held += len(ks)
            if held >= limit:
                yield np.concatenate(moved), np.concatenate(pivots), np.concatenate(turner)
                moved, pivots, turner, held = [], [], [], 0
        a = parent[a]
        keep = a >= 0
        k, a = k[keep], a[keep]
    if moved:
        yield np.concatenate(moved), np.concatenate(pivots), np.concatenate(turner)


def lever_arms_of(skel: Skeleton, values: FloatArray, *, joint_frames: int | None = None,
                  pairs: int | None = None, joints: FloatArray | None = None) -> FloatArray:
    """:func:`mpz.io.kinematics.lever_arms` of ``forward(skel, values)`` at the joints that
    have a rotation channel, the only arms the position search uses, bit for bit; 0 at the
    others.

    Neither the joint positions of every frame nor every (point, pivot) pair are held:
    the pairs of those joints alone, about ``pairs`` (default :data:`ARM_PAIRS`) at a
    time, each list measured over the frames, ``joint_frames`` (default
    :data:`JOINT_FRAMES`) joint positions at a time. An arm is the maximum of the same
    squared distances in another order (and np.maximum keeps a NaN as the kernel does),
    so it is the same. A 183 KB BVH of 4096 joints and 10,000 frames whose root alone has
    channels held its 983 MB of joint positions for them, and a chain of 4096 joints
    8.4 million pairs (and a Python list of them), whichever joints turn. ``joints``:
    ``forward(skel, values)``, when the caller holds it."""
    J = len(skel.joints)
    turning = np.array([any(is_rotation(c) for c in j.channels) for j in skel.joints],
                       np.bool_).reshape(J)
    arm = np.zeros(J)
    if not turning.any():
        return arm
    blocks = _frame_blocks(values.shape[0], J, joint_frames)
    for moved, pivots, turner in _arm_pairs(skel, turning,
                                            ARM_PAIRS if pairs is None else pairs):
        far = np.zeros(len(moved))
        for rows in blocks:
            p = forward(skel, values[rows]) if joints is None else joints[rows]
            np.maximum(far, _farthest(p, moved, pivots), out=far)
        np.maximum.at(arm, turner, np.sqrt(far))
    return arm


def declared(measured: float, scale: float) -> float:
    """A position bound to declare for a measured error: a margin of 2^-20 relative and
    2^-30 of the skeleton's size (``scale``) absorbs the rounding of an independent forward
    kinematics (§6.10 leaves the order of its operations free)."""
    return measured * (1 + 2.0 ** -20) + scale * 2.0 ** -30


def within(bound: float, scale: float) -> float:
    """The largest measured error that :func:`declared` keeps within ``bound`` (the inverse
    of its margin); 0 or less when the bound is inside the margin itself."""
    return (bound - scale * 2.0 ** -30) / (1 + 2.0 ** -20)


def skeleton_size(skel: Skeleton) -> float:
    """The skeleton's size in marker units, at least 1: the ``scale`` of :func:`declared`."""
    return max(rest_height(skel) * marker_scale(skel), 1.0)


def _rebuilt(x: IntArray, steps: Sequence[Step]) -> FloatArray:
    """The channel values a decoder rebuilds from integers ``x[F, C]`` at ``steps``."""
    return dequantise(x, [ChannelCoding(s.mantissa, s.digits, 0, 0, 0, 0) for s in steps])


def steps_for_position(skel: Skeleton, values: FloatArray, target: float,
                       angle_cap: float | None, translation_cap: float | None
                       ) -> tuple[list[Step], float]:
    """The coarsest steps whose joint-position error stays within ``target`` marker units,
    and that error, measured on every frame.

    Each channel gets a bound inversely proportional to how far its error moves a joint
    (a rotation: its joint's lever arm; a translation: one to one), times a common factor
    made as large as the measured error allows (spec Appendix C: aimed at in proportion,
    bracketed, bisected), aiming below ``target`` by the rounding margin of
    :func:`declared`; ``angle_cap`` / ``translation_cap`` (when given) cap the bounds.
    """
    scale = marker_scale(skel)
    # the source's joints of every frame, once, when they are few (HELD_JOINTS); else a
    # block at a time wherever they are needed (issue 11.11)
    held = (forward(skel, values) if values.shape[0] * len(skel.joints) <= HELD_JOINTS
            else None)
    arms = lever_arms_of(skel, values, joints=held) * scale    # marker units
    joint = skel.channel_joints()
    rotation = [is_rotation(k) for k in skel.channel_kinds()]
    rad = skel.angle_unit == "rad"
    # marker units per radian; 0 for a rotation that moves no joint measurably (a one-
    # joint BVH: a camera or a prop; End Sites at or a hair off their joint): its arm is at
    # most 1/256 of the bound, so that even half a turn moves what it moves by less than
    # 1/128 of it, and no joint position shows its error. It had the 90-degree cap and
    # came back 40 degrees off (a QA run and a review of stop 61)
    still = max(skeleton_size(skel) * 2.0 ** -30, target / 256)
    per_rad = [float(arms[j]) if arms[j] > still else 0.0 for j in joint]
    angle_limit = None if angle_cap is None else (math.radians(angle_cap) if rad
                                                  else angle_cap)
    # such a rotation keeps the default channel bound, or --angle-error's when given
    unmoved = angle_limit if angle_limit is not None else (
        math.radians(DEFAULT_CHANNEL_ERROR) if rad else DEFAULT_CHANNEL_ERROR)

    # a channel's step depends on kappa and on whether it turns and its joint's arm only:
    # each distinct (turns, arm) is worked out once a kappa (31 for an ASF's 62 channels)
    index: dict[tuple[bool, float], int] = {}
    kind_of = [index.setdefault(k, len(index)) for k in zip(rotation, per_rad, strict=True)]
    kinds = list(index)

    def steps(kappa: float) -> list[Step]:
        cache: dict[float, Step] = {}                 # one step_for a bound
        of_kind = []
        for turns, arm in kinds:
            if turns and arm == 0.0:
                bound = unmoved
                cap = None
            elif turns:
                bound = kappa / arm                             # radians
                bound = bound if rad else math.degrees(bound)
                bound = min(bound, 90.0 if not rad else math.pi / 2)
                cap = angle_limit
            else:
                bound = kappa / scale
                cap = translation_cap
            if cap is not None:
                bound = min(bound, cap)
            bound = min(max(bound, 10.0 ** -MAX_STEP_DIGITS), 1e300)    # finite: step_for
            step = cache.get(bound)
            if step is None:
                step = cache[bound] = step_for(bound)
            of_kind.append(step)
        return [of_kind[k] for k in kind_of]

    # the search measures the error on at most 256 frames; the result is then checked on
    # every frame and made finer until it holds there too
    stride = max(1, values.shape[0] // 256)
    sub = values[::stride]
    # the source's joints on the subsample, once (at most 511 frames)
    sub_joints = forward(skel, sub) if held is None else held[::stride]
    # error() depends on kappa only through the steps, which are discrete: bisection meets
    # the same steps again (and with stride 1 the whole check repeats a sub check)
    measured: dict[tuple[bool, tuple[Step, ...]], float] = {}

    def error(kappa: float, whole: bool = False) -> float:
        return measure(steps(kappa), whole)

    def measure(st: list[Step], whole: bool = False) -> float:
        whole = whole and stride > 1                    # with stride 1 the sub is whole
        key = (whole, tuple(st))
        if key in measured:
            return measured[key]
        v, joints = (values, held) if whole else (sub, sub_joints)
        try:
            x = quantise(v, st)
        except EncoderError:             # too fine for the value range: cannot be used
            measured[key] = math.inf
            return math.inf
        measured[key] = e = position_error(skel, v, _rebuilt(x, st), joints)
        return e

    # error(kappa) grows with kappa (in steps, as the step ladder is discrete) and about in
    # proportion to it; it is inf where the steps are too fine for the value range, which
    # only coarser steps (a larger kappa) cure. The search keeps the largest kappa found
    # within the aim (lo), the smallest beyond it (hi) and the largest too fine (fine).
    size = skeleton_size(skel)
    aim = within(target, size)
    if aim <= 0.0:
        raise EncoderError(f"a joint-position bound of {target:g} is within the rounding of "
                           f"forward kinematics on this skeleton (2^-30 of its size "
                           f"{size:g}, spec Appendix C); give a --max-error above "
                           f"{size * 2.0 ** -30:.3g}")
    limit = min(1e12 * target, 1e300)
    lo, hi, fine = 0.0, math.inf, 0.0

    def probe(kappa: float) -> float:
        nonlocal lo, hi, fine
        e = error(kappa)
        if e <= aim:
            lo = max(lo, kappa)
        elif e == math.inf:
            fine = max(fine, kappa)
        else:
            hi = min(hi, kappa)
        return e

    # A joint's error adds up the errors of the channels along its chain, so error is
    # 2-5 x kappa on the real files: measure at a quarter of the target and aim at it
    # in proportion (coarser while too fine to quantise)
    first = probe(target / 4)
    kappa = target / 4 * min(aim / first, 1e6) if 0.0 < first < math.inf else target
    while probe(kappa) == math.inf and kappa < limit:
        kappa = min(kappa * 2, limit)
    # bracket it: factors from 1.04 that square (up to 2) at each further step, never
    # below a kappa known within, and halving the gap to one too fine
    factor = 1.04
    for _ in range(200):
        if lo >= kappa and hi == math.inf and kappa < limit:
            kappa = min(kappa * factor, limit)                      # coarser
        elif lo == 0.0 and fine == 0.0:
            kappa = hi / factor                                     # finer
        elif lo == 0.0 and hi < math.inf and hi - fine > 0.01 * fine:
            kappa = (fine + hi) / 2                                 # finer, not too fine
        else:
            break
        probe(kappa)
        factor = min(factor * factor, 2.0)
    # then bisect to within 1 % (on the real files 3-12 measures in all, against 9-16
    # when doubling and halving from the target itself; issue 15.1)
    while lo and hi < math.inf and hi - lo > 0.01 * lo:
        probe((lo + hi) / 2)
    # the subsample may miss the worst frame: check every frame, shrink in proportion to
    # the excess until it holds, then bisect back to within 3 %
    good, bad = 0.0, 0.0
    kappa = lo
    for _ in range(200):
        if not kappa:
            break
        err = error(kappa, whole=True)
        if err <= aim:
            good = kappa
            break
        bad = kappa
        kappa *= min(0.97, aim / err)             # 0 once too fine for the value range
    if not good:
        # no common factor: the channels' own decimals may still give every value back
        # (a QA run, stop 37: integer angles near 1e7 degrees, refused at any factor)
        exact = exact_steps(values)
        if exact is not None and (err := measure(exact, whole=True)) <= aim:
            return exact, err
        # the search ties every channel's step to one factor; a QA run (stop 49) met a root
        # 10^5 units from the origin whose translations, at the factor the rotations need,
        # were too fine for their values, while steps chosen apart kept the bound
        raise EncoderError(f"the step search found no channel steps that keep the joint "
                           f"positions within {target:g} and stay coarse enough for the "
                           f"channels' values (|value / step| < 2^27); choose the steps "
                           f"with angle_error and translation_error (--angle-error, "
                           f"--translation-error), or give a larger max error")
    while bad and bad - good > 0.03 * good:
        mid = (good + bad) / 2
        if error(mid, whole=True) <= aim:
            good = mid
        else:
            bad = mid
    return steps(good), error(good, whole=True)


def exact_steps(values: FloatArray) -> list[Step] | None:
    """Per channel of ``values[F, C]``, the coarsest step 10^-d (d = 0 .. 9) at which every
    value comes back exactly (a file's own decimals), or None when a channel has none."""
    out = []
    for col in np.asarray(values, np.float64).T:
        for d in range(MAX_STEP_DIGITS + 1):
            step = Step(1, d)
            try:
                x = quantise(col[:, None], [step])
            except EncoderError:                  # finer steps cannot be quantised either
                return None
            if np.array_equal(_rebuilt(x, [step])[:, 0], col):
                out.append(step)
                break
        else:
            return None
    return out


def preview_bound(motion: Motion) -> float | None:
    """The bound (motion units) the reference encoder gives the marker layer of a skeletal
    motion when none is asked for: :data:`PREVIEW_FRACTION` of the skeleton's size (None for
    a motion without a skeleton)."""
    skel = motion.extras.get("skeleton")
    if not isinstance(skel, Skeleton):
        return None
    size = rest_height(skel) * marker_scale(skel)
    if not size > 0:
        size = float(np.ptp(motion.positions[motion.valid], axis=0).max(initial=1.0))
    return PREVIEW_FRACTION * size


def has_channels(motion: Motion) -> bool:
    """Whether ``motion`` holds a skeleton and its channel values, which
    :func:`with_joint_positions` computes joint positions from."""
    return isinstance(motion.extras.get("skeleton"), Skeleton) and motion.angles is not None


def with_joint_positions(motion: Motion) -> Motion:
    """A decoded skeletal motion whose positions are the joint positions computed from its
    channels (spec §6.10: within the file's declared position bound of the source's),
    instead of the marker layer (within MHDR's bound, which the reference encoder makes
    coarser, Appendix C).

    Raises
    ------
    MotionError
        For a motion without a skeleton and its channels (a file of markers, one encoded
        with ``keep_skeleton=False``, or decoded with ``markers_only=True``): it has no
        joints to compute; for joint angles without their skeleton (``extras`` replaced or
        emptied), which it names. Before, it came back as it was, its positions the marker
        layer, which a caller took for the joints (a newcomer's QA run).
    """
    skel, values = _joint_inputs(motion)
    pos = forward(skel, values)
    pos *= marker_scale(skel)       # in place: no second array of every joint position
    return Motion(pos, motion.names, motion.rate, motion.units, None, motion.metadata,
                  motion.parents, motion.angles, motion.angle_names, motion.extras)


def _joint_inputs(motion: Motion) -> tuple[Skeleton, FloatArray]:
    """The skeleton and channel values that :func:`with_joint_positions` computes the
    joints from, refused as it says."""
    if not isinstance(motion, Motion):       # AttributeError of None (a QA run, stop 50)
        raise TypeError(f"expected an mpz.Motion, got {type(motion).__name__}")
    if motion.angles is not None and not isinstance(motion.extras.get("skeleton"), Skeleton):
        # angles without their skeleton were blamed on three causes that did not apply
        # (an ML pipeline's QA run of the API: a select_frames cut, which now keeps it)
        raise MotionError("the motion has joint angles but no skeleton (extras['skeleton'], "
                          "an mpz.io.kinematics.Skeleton) to compute joint positions from: "
                          "keep the extras of the motion as it was read or decoded")
    if not has_channels(motion):
        raise MotionError("the motion has no skeleton and channels to compute joint "
                          "positions from (a file of markers, one encoded with "
                          "keep_skeleton=False / --no-skeleton, or decoded with "
                          "markers_only=True): its positions are already all it holds")
    skel = motion.extras["skeleton"]
    return skel, _values(motion, skel)


#: frames whose joints :func:`largest_joint_offset` computes at a time
JOINT_BLOCK = 4096


def largest_joint_offset(motion: Motion) -> float | None:
    """The largest distance between a valid position of ``motion`` and the joint that its
    channels give there (:func:`with_joint_positions`), or None when no sample is valid.

    The joints are computed :data:`JOINT_BLOCK` frames at a time (every joint of a
    30-minute capture, with the differences and their squares, was 0.9 GB at once when a
    BVH was written: issue 15.3); forward kinematics is frame by frame, so the figure is
    the one the whole array gives, NaN where a joint or position is not finite.

    Raises
    ------
    MotionError
        As :func:`with_joint_positions`.
    """
    skel, values = _joint_inputs(motion)
    scale = marker_scale(skel)
    worst: float | None = None
    for lo in range(0, motion.n_frames, JOINT_BLOCK):
        hi = lo + JOINT_BLOCK
        joints = forward(skel, values[lo:hi])
        joints *= scale
        joints -= motion.positions[lo:hi]
        d = np.linalg.norm(joints, axis=2)[motion.valid[lo:hi]]
        if d.size:
            most = float(d.max())
            if math.isnan(most):            # the whole array's max is NaN then, as here
                return most
            worst = most if worst is None else max(worst, most)
    return worst


def mm_per_unit(motion: Motion) -> float | None:
    """Millimetres per length unit of the motion's skeleton: 25.4 / ``length`` for ASF, the
    motion's unit for BVH (None when it has none, or the motion has no skeleton)."""
    skel = motion.extras.get("skeleton")
    if not isinstance(skel, Skeleton):
        return None
    if skel.convention == "asf":
        return MM_PER_INCH / skel.length
    return MM_PER_UNIT.get(motion.units)


def report(data: bytes, *, end_sites: bool = False) -> dict[str, object] | None:
    """What the skeleton chunk of an MPZ file holds, for tools: its type and size, joints,
    channels, the largest channel error its steps allow (rotations in degrees, translations
    in skeleton units) and its declared joint-position bound; None without one. With
    ``end_sites``, also how many of the joints are BVH End Sites (:func:`record_report`)."""
    from mpz.container import scan
    # the skeleton chunks alone loaded, and no unknown chunk kept: mpz compare and mpz show
    # held an object per unknown chunk here (1.07 GB for a valid 12 MB file of 10^6 of
    # them, the cost spec §8 names; a security QA run, stop 73)
    res = scan(data, keep_unknown=False, load=SKELETON_TYPES)
    if res.errors:
        raise res.errors[0]
    for c in res.chunks:
        rec = c.record
        if isinstance(rec, (Bvhs, Asfs)):
            return record_report(rec, len(c.payload), end_sites=end_sites)
    return None


def record_report(rec: Bvhs | Asfs, payload_bytes: int, *,
                  end_sites: bool = False) -> dict[str, object]:
    """:func:`report` of a checked skeleton record whose payload is ``payload_bytes``
    long: the figures spec §7.3 defines for ``features.skeleton`` (h = (m / 10^d) / 2
    per channel, rotations times the binary64 180/π for radians; 0 without such a
    channel), which ``mpzinfo`` shows. ``joints`` is the chunk's joint count, BVH End
    Sites included (§4.14.1); with ``end_sites`` the report also gives their number,
    ``end_sites`` (not in §7.3's features), for the tools' "31 joints and 7 End Sites"
    (:func:`joints_text`)."""
    skel = skeleton_of_record(rec)
    kinds = skel.channel_kinds()
    rot = [c.step_mantissa / 10.0 ** c.step_digits / 2
           for c, k in zip(rec.channels, kinds, strict=True) if is_rotation(k)]
    lin = [c.step_mantissa / 10.0 ** c.step_digits / 2
           for c, k in zip(rec.channels, kinds, strict=True) if not is_rotation(k)]
    to_deg = 180 / math.pi if skel.angle_unit == "rad" else 1.0
    out: dict[str, object] = {
        "chunk": rec.TYPE, "bytes": 12 + payload_bytes,
        "joints": len(skel.joints), "channels": rec.channel_count,
        "angle_bound": max(rot, default=0.0) * to_deg,
        "translation_bound": max(lin, default=0.0),
        "position_bound": rec.position_bound}
    if end_sites:
        out["end_sites"] = sum(j.end_site for j in skel.joints)
    return out


def joints_text(joints: int, end_sites: int) -> str:
    """How the tools count a skeleton's ``joints``, ``end_sites`` of them BVH End Sites:
    "31 joints and 7 End Sites". The chunk counts an End Site as a joint (§4.14.1: one
    marker each), a reader of the BVH file does not: "38 joints" of cmu_131_03 was read
    as a wrong count (a QA run of stop 55)."""
    if not end_sites:
        return f"{joints} joint{'s' * (joints != 1)}"
    return (f"{joints - end_sites} joint{'s' * (joints - end_sites != 1)} and {end_sites} "
            f"End Site{'s' * (end_sites != 1)}")


def channel_bounds(data: bytes) -> tuple[float, float] | None:
    """(rotations in degrees, translations in skeleton units): the largest error with which
    the joint channels of MPZ ``data`` come back, half of its skeleton chunk's largest
    steps (:func:`report`); None without a skeleton chunk. For
    :func:`mpz.metrics.besides_markers`."""
    r = report(data)
    if r is None:
        return None
    rot, lin = r["angle_bound"], r["translation_bound"]
    assert isinstance(rot, float) and isinstance(lin, float)
    return rot, lin


def with_units(motion: Motion, units: str) -> Motion:
    """The motion with its length unit set (``mpz encode --units``): BVH files have none.

    Raises
    ------
    EncoderError
        When the motion already has another unit (only unitless input takes one).
    """
    if units not in ("mm", "cm", "m", "in"):
        raise EncoderError(f"--units must be mm, cm, m or in, got {units!r}")
    if motion.units == units:
        return motion
    if motion.units:
        raise EncoderError(f"the input is already in {motion.units}; --units only names the "
                           "unit of input that has none (BVH)")
    return Motion(motion.positions, motion.names, motion.rate, units, motion.valid,
                  motion.metadata, motion.parents, motion.angles, motion.angle_names,
                  motion.extras)


# ------------------------------------------------------------ extension --
@dataclass(frozen=True)
class Settings:
    """The resolved skeleton options of one encode: per-channel steps, the position
    bound to declare (None: the measured error) and, when the steps were searched for that
    bound, the joint error they give on every frame (None: not yet measured)."""

    steps: tuple[Step, ...]
    position_bound: float | None
    measured: float | None = None


def settings(motion: Motion, skel: Skeleton, opts: EncodeOptions) -> Settings:
    """Resolve :class:`~mpz.encoder.EncodeOptions` ``angle_error``, ``translation_error`` and
    ``position_error`` for this skeleton (see :class:`SkeletonExtension`)."""
    angle, lin, pos = opts.angle_error, opts.translation_error, opts.position_error
    for what, v in (("angle_error", angle), ("translation_error", lin),
                    ("position_error", pos)):
        if v is not None and not (math.isfinite(v) and v > 0):
            raise EncoderError(f"{what} must be finite and > 0, got {v!r}")
    values = _values(motion, skel)
    if pos is None:
        steps = plan_steps(skel, DEFAULT_CHANNEL_ERROR if angle is None else angle,
                           DEFAULT_CHANNEL_ERROR if lin is None else lin)
        return Settings(tuple(steps), None)
    steps, measured = steps_for_position(skel, values, pos, angle, lin)
    return Settings(tuple(steps), pos, measured)


def _values(motion: Motion, skel: Skeleton) -> FloatArray:
    C = skel.channel_count
    ang = motion.angles
    if ang is None:
        if C:
            raise EncoderError("the motion has a skeleton but no channel values (angles)")
        return np.zeros((motion.n_frames, 0))
    if ang.shape != (motion.n_frames, C):
        raise EncoderError(f"the skeleton has {C} channels, the motion's angles are {ang.shape}")
    if len(skel.joints) != motion.n_markers:
        raise EncoderError(f"the skeleton has {len(skel.joints)} joints for "
                           f"{motion.n_markers} markers; the marker layer must hold one "
                           "marker per joint (spec §4.14)")
    if not np.isfinite(ang).all():
        raise EncoderError("a channel value is not finite")
    return ang


class SkeletonExtension:
    """The ``"skeleton"`` extension (spec §4.14): one ``bvhs`` or ``asfs`` chunk.

    Encoding options (fields of :class:`~mpz.encoder.EncodeOptions`, issue 13):
    ``keep_skeleton`` (False leaves the chunk out: a plain 1.0 file), ``angle_error``
    (degrees) and ``translation_error`` (skeleton length units), both
    :data:`DEFAULT_CHANNEL_ERROR` unless ``position_error`` (marker units) is given, which
    then chooses the steps. Decoding sets ``motion.angles``, ``angle_names``, ``parents``
    and ``extras["skeleton"]``.
    """

    name: str = "skeleton"
    chunk_types: tuple[str, ...] = SKELETON_TYPES
    sections: tuple[str, ...] = ("§4.14", "§6.10")
    per_frame: bool = False
    held: str = "the skeleton (BVH hierarchy or ASF)"

    def check(self, motion: Motion, opts: EncodeOptions) -> None:
        """The §8 limit of the chunk this motion would get, before anything is encoded: a
        2-hour BVH was encoded for minutes into a file that its decoder refused (F x C
        past MAX_CHANNEL_SAMPLES), and the file was left behind (a QA run of stop 51)."""
        skel = motion.extras.get(self.name)
        if skel is None or not opts.keep_skeleton:
            return
        if not isinstance(skel, Skeleton):
            # it was dropped without a word (QA, stop 50); checked in records(), after this
            # check's first use of skel.joints, which raised AttributeError (an ML
            # pipeline's QA run of the API)
            raise EncoderError(f"motion.extras[{self.name!r}] is a {type(skel).__name__}, "
                               "not an mpz.io.kinematics.Skeleton")
        if motion.angles is None:
            return
        first = getattr(skel, "first_frame", 0)
        if isinstance(first, int) and not 0 <= first <= 0xFFFFFFFF:
            # §4.14.2's u32: it failed in the chunk's build, exit 70 (a QA run of stop 52)
            raise EncoderError(
                f"the AMC's first frame number {first} is outside 0..{0xFFFFFFFF} (2^32 - 1), "
                "what an asfs chunk holds (spec §4.14.2): renumber the AMC's frames, or keep "
                "the joint positions alone without the skeleton (--no-skeleton, "
                "keep_skeleton=False)")
        odd = next((j for j in skel.joints if isinstance(j.bone_id, int)
                    and not 0 <= j.bone_id <= 0xFFFFFFFF), None)
        if odd is not None:
            # §4.14.2's u32 too: construct refused it in the chunk's build, exit 70 (a QA run
            # of stop 54)
            raise EncoderError(
                f"the ASF's bone {odd.name!r} has the id {odd.bone_id}, outside 0..{0xFFFFFFFF} "
                "(2^32 - 1), what an asfs chunk holds (spec §4.14.2): renumber it in the ASF, "
                "or keep the joint positions alone without the skeleton (--no-skeleton, "
                "keep_skeleton=False)")
        F, C = motion.angles.shape
        if F * C > MAX_CHANNEL_SAMPLES:
            most = MAX_CHANNEL_SAMPLES // max(C, 1)
            raise EncoderError(
                f"the skeleton's {C} channels over {F} frames are {F * C} values, more than "
                f"the {MAX_CHANNEL_SAMPLES} (2^26) a skeleton chunk holds (spec §8, "
                f"MAX_CHANNEL_SAMPLES): at most {most} frames "
                f"({most / motion.rate / 60:.1f} minutes at {motion.rate:g} Hz) with "
                f"{C} channels. Split the capture, or keep the joint positions alone "
                "without the skeleton and its channels (--no-skeleton, keep_skeleton=False)")

    def records(self, motion: Motion, opts: EncodeOptions) -> list[Record]:
        skel = motion.extras.get(self.name)
        if skel is None or not opts.keep_skeleton:
            return []
        assert isinstance(skel, Skeleton), "check() refuses any other"   # runs first
        values = _values(motion, skel)
        st = settings(motion, skel, opts)
        codings, coded = code_channels(values, skel, st.steps)
        err = st.measured
        if err is None:
            err = position_error(skel, values, dequantise(quantise(values, st.steps), codings))
        bound = st.position_bound
        if bound is None:
            bound = declared(err, skeleton_size(skel))
        if err > bound:                                    # steps_for_position checked it
            raise EncoderError(f"the channels move joints by {err:g}, beyond the bound "
                               f"{bound:g} (spec §4.14, position_bound)")
        return [skeleton_record(skel, codings, coded, bound)]

    def attach(self, records: dict[str, list[Record]], motion: Motion) -> None:
        found = [*records.get("bvhs", []), *records.get("asfs", [])]
        rec = found[0] if found else None
        if not isinstance(rec, (Bvhs, Asfs)):
            return
        skel = skeleton_of_record(rec)
        motion.angles = rec.values(motion.n_frames)
        motion.angle_names = skel.channel_names()
        motion.parents = skel.parents()
        motion.extras[self.name] = skel

    def cut(self, part: object, start: int) -> object:
        """The skeleton describes every frame alike and goes with the cut's angles; an AMC's
        first frame number moves with the first frame kept, as a TRC's FirstFrame does, so
        that the cut is written with the source's frame numbers (it was dropped, and the cut
        wrote no AMC and gave no joint positions: an ML pipeline's QA run of the API)."""
        if isinstance(part, Skeleton) and part.convention == "asf" and start:
            return replace(part, first_frame=part.first_frame + start)
        return part


#: the extension instance registered in :data:`mpz.extensions.EXTENSIONS`
EXTENSION = SkeletonExtension()
