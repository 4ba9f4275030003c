"""Deterministic synthetic human motion for vectors, property tests and examples.

Contract: :func:`generate` returns a :class:`mpz.Motion` of the CMU/Vicon
41-marker set (``"mm"``) placed on an articulated figure about 1.75 m tall,
driven by smooth periodic joint angles with per-cycle variation. The result
depends only on the arguments: every random draw comes from one
``numpy.random.default_rng(seed)``, and equal arguments give byte-identical
arrays. Real recordings may not be copied into the repository, so this is the
motion that conformance vectors and the README quick start are made from.

Strategy: joint angles (degrees, per frame) -> forward kinematics of the
figure in a body frame -> marker positions -> the figure is placed on the
floor by keeping the lowest sole point at height 0 (soft minimum) and moved
horizontally by the opposite of the contact foot's motion, so stance feet stay
planted -> sensor noise -> occlusion gaps.

Coordinates are **Z-up**, in millimetres: +X is the walking direction, +Y the
subject's left, +Z up (right-handed). This matches the CMU and HDM05 C3D files
in the developer data set, whose point data are Z-up with the floor at z ~ 0.
"""
from __future__ import annotations

from collections.abc import Callable
import math

import numpy as np
from numpy.typing import NDArray

from mpz.errors import MotionError
from mpz.format import MAX_FRAMES
from mpz.motion import Motion

_F64 = NDArray[np.float64]
#: joint angles (joint name -> [F, 3] degrees), flight height [F] (mm), forward speed [F] (mm/s)
_Drive = tuple[dict[str, _F64], _F64, _F64]

#: The CMU/Vicon 41-marker set, in the order :func:`generate` returns it.
MARKERS = ("LFHD RFHD LBHD RBHD C7 T10 CLAV STRN RBAC LSHO LUPA LELB LFRM LWRA LWRB "
           "LFIN RSHO RUPA RELB RFRM RWRA RWRB RFIN LFWT RFWT LBWT RBWT LTHI LKNE LSHN "
           "LANK LHEE LTOE LMT5 RTHI RKNE RSHN RANK RHEE RTOE RMT5").split()

KINDS = ("walk", "jump", "wave", "mixed", "static")

# -- the figure --------------------------------------------------------------
#: Joints as (name, parent, offset from the parent joint in the parent's rest
#: frame, mm). A joint's segment is the rigid body distal to it. Left side
#: only; right-side joints mirror y. Head joint 1560 mm + ~190 mm of head
#: gives a height of ~1.75 m; leg 430 + 420 mm, upper arm 300 mm, forearm 260 mm.
_LEFT_JOINTS = (
    ("pelvis", None, (0.0, 0.0, 1000.0)),
    ("lumbar", "pelvis", (-20.0, 0.0, 100.0)),
    ("chest", "lumbar", (0.0, 0.0, 180.0)),
    ("neck", "chest", (10.0, 0.0, 190.0)),
    ("head", "neck", (10.0, 0.0, 90.0)),
    ("l_shoulder", "chest", (-10.0, 175.0, 150.0)),
    ("l_elbow", "l_shoulder", (0.0, 0.0, -300.0)),
    ("l_wrist", "l_elbow", (0.0, 0.0, -260.0)),
    ("l_hip", "pelvis", (0.0, 85.0, -70.0)),
    ("l_knee", "l_hip", (0.0, 0.0, -430.0)),
    ("l_ankle", "l_knee", (0.0, 0.0, -420.0)),
    ("l_toe", "l_ankle", (130.0, 0.0, -60.0)),
)

#: Marker -> (segment joint, offset in that segment's frame, mm). Left-side
#: and midline markers are listed; R* markers mirror their L* twin (y -> -y).
#: The head markers form a 135 x 160 mm rectangle (diagonal ~209 mm, close to
#: the ~200 mm ADDH measured on the CMU and HDM05 files).
MARKER_OFFSETS = {
    "LFHD": ("head", (75.0, 80.0, 95.0)),
    "LBHD": ("head", (-60.0, 80.0, 85.0)),
    "C7": ("chest", (-85.0, 0.0, 200.0)),
    "T10": ("chest", (-105.0, 0.0, -20.0)),
    "CLAV": ("chest", (75.0, 0.0, 150.0)),
    "STRN": ("chest", (110.0, 0.0, 10.0)),
    "RBAC": ("chest", (-100.0, -85.0, 100.0)),   # right scapula only: the set's asymmetry marker
    "LSHO": ("chest", (-10.0, 180.0, 185.0)),
    "LUPA": ("l_shoulder", (-35.0, 45.0, -190.0)),
    "LELB": ("l_shoulder", (0.0, 40.0, -300.0)),   # on the elbow flexion axis
    "LFRM": ("l_elbow", (-30.0, 35.0, -130.0)),
    "LWRA": ("l_elbow", (65.0, 10.0, -260.0)),     # wrist bar, radial (thumb) side
    "LWRB": ("l_elbow", (-65.0, 10.0, -260.0)),    # wrist bar, ulnar side
    "LFIN": ("l_wrist", (30.0, 20.0, -95.0)),
    "LFWT": ("pelvis", (110.0, 135.0, 40.0)),      # ASIS
    "LBWT": ("pelvis", (-90.0, 55.0, 60.0)),       # PSIS
    "LTHI": ("l_hip", (20.0, 75.0, -250.0)),
    "LKNE": ("l_hip", (0.0, 55.0, -430.0)),        # on the knee hinge axis
    "LSHN": ("l_knee", (35.0, 45.0, -220.0)),
    "LANK": ("l_knee", (0.0, 40.0, -420.0)),       # lateral malleolus
    "LHEE": ("l_ankle", (-75.0, 0.0, -40.0)),
    "LMT5": ("l_ankle", (110.0, 40.0, -60.0)),
    "LTOE": ("l_toe", (15.0, 5.0, 15.0)),
}

#: Sole points per foot (segment, offset): heel, ball and toe tip at floor level
#: in the rest pose. Used to put the figure on the floor.
_SOLE = (("l_ankle", (-75.0, 0.0, -80.0)), ("l_toe", (0.0, 0.0, -20.0)),
         ("l_toe", (60.0, 0.0, -20.0)))


def _mirror_name(n: str) -> str:
    if n.startswith("l_"):
        return "r_" + n[2:]
    if n[0] == "L":
        return "R" + n[1:]
    return n


def _build_figure() -> tuple[list[str], NDArray[np.intp], _F64, NDArray[np.bool_],
                              NDArray[np.intp], _F64, NDArray[np.intp], _F64]:
    """Joint names, parent index (-1: root), rest offsets and right-side flags of the
    figure; segment and offset of each marker; segment and offset of each sole point."""
    joints: list[tuple[str, str | None, tuple[float, float, float]]] = []
    for name, parent, off in _LEFT_JOINTS:
        joints.append((name, parent, off))
    for name, parent, off in _LEFT_JOINTS:
        if name.startswith("l_"):
            assert parent is not None  # only the pelvis has no parent
            joints.append((_mirror_name(name), _mirror_name(parent),
                           (off[0], -off[1], off[2])))
    # parents before children: insertion order already satisfies it
    index = {n: i for i, (n, _, _) in enumerate(joints)}
    parent_index = np.array([-1 if p is None else index[p] for _, p, _ in joints])
    offset = np.array([o for _, _, o in joints], dtype=np.float64)
    right = np.array([n.startswith("r_") for n, _, _ in joints])
    seg: list[int] = []
    moff: list[tuple[float, float, float]] = []
    for m in MARKERS:
        if m in MARKER_OFFSETS:
            s, o = MARKER_OFFSETS[m]
        else:  # right twin of a left marker
            s, o = MARKER_OFFSETS["L" + m[1:]]
            s, o = _mirror_name(s), (o[0], -o[1], o[2])
        seg.append(index[s])
        moff.append(o)
    sole_seg: list[int] = []
    sole_off: list[tuple[float, float, float]] = []
    for side in ("l", "r"):
        for s, o in _SOLE:
            sole_seg.append(index[s if side == "l" else _mirror_name(s)])
            sole_off.append(o if side == "l" else (o[0], -o[1], o[2]))
    return ([n for n, _, _ in joints], parent_index, offset, right, np.array(seg),
            np.array(moff, dtype=np.float64), np.array(sole_seg),
            np.array(sole_off, dtype=np.float64))


(_JOINT_NAMES, _PARENT, _OFFSET, _RIGHT, _MSEG, _MOFF, _SOLE_SEG, _SOLE_OFF) = _build_figure()
_J = {n: i for i, n in enumerate(_JOINT_NAMES)}


# -- angle helpers -------------------------------------------------------------
def _bump(p: _F64, mu: float, sigma: float) -> _F64:
    """A Gaussian bump on the unit circle of cycle phase ``p`` (cycles)."""
    d = (p - mu + 0.5) % 1.0 - 0.5
    return np.exp(-0.5 * (d / sigma) ** 2)


def _smooth_noise(t: _F64, period: float, rng: np.random.Generator, sd: float) -> _F64:
    """A C1 random function: normal knots every ``period`` s, cosine-interpolated."""
    n = int(np.ceil((t[-1] if t.size else 0.0) / period)) + 2
    knots = rng.normal(0.0, sd, n)
    u = t / period
    k = np.floor(u).astype(int)
    w = 0.5 - 0.5 * np.cos(np.pi * (u - k))
    return knots[k] * (1 - w) + knots[k + 1] * w


def _phase(t: _F64, f0: float, rng: np.random.Generator, fsd: float = 0.04) -> _F64:
    """Cycle phase (in cycles) at a frequency varying smoothly around ``f0``."""
    f = f0 * (1.0 + _smooth_noise(t, 1.0 / f0, rng, fsd))
    dt = np.diff(t, prepend=t[0])
    return rng.uniform(0.0, 1.0) + np.cumsum(f * dt)


def _zeros(F: int) -> dict[str, _F64]:
    """Zero angles ``[F, 3]`` for every joint."""
    return {n: np.zeros((F, 3)) for n in _JOINT_NAMES}


def _walk(t: _F64, rng: np.random.Generator) -> _Drive:
    F = t.size
    a = _zeros(F)
    p = _phase(t, 0.9, rng)
    amp = 1.0 + _smooth_noise(t, 1.1, rng, 0.06)
    for side, ph in (("l", p), ("r", p + 0.5)):
        hip = 8.0 + 20.0 * amp * np.cos(2 * np.pi * (ph + 0.05))
        knee = 5.0 + amp * (15.0 * _bump(ph, 0.15, 0.07) + 55.0 * _bump(ph, 0.72, 0.09))
        # foot pitch relative to the pelvis: heel strike toes-up, flat in stance,
        # heel rise at push-off; the ankle angle follows from hip and knee
        pitch = (15.0 * _bump(ph, 0.0, 0.05) - 30.0 * amp * _bump(ph, 0.58, 0.06)
                 + 5.0 * _bump(ph, 0.85, 0.08))
        ankle = pitch - (hip - knee)
        a[f"{side}_hip"][:, 0] = hip
        a[f"{side}_hip"][:, 1] = 3.0 + 3.0 * np.sin(2 * np.pi * ph)
        a[f"{side}_knee"][:, 0] = -knee
        a[f"{side}_ankle"][:, 0] = ankle
        a[f"{side}_toe"][:, 0] = 27.0 * amp * _bump(ph, 0.58, 0.06)   # toes stay on the floor
        # arms swing opposite to the same-side leg
        a[f"{side}_shoulder"][:, 0] = -0.8 * (hip - 8.0)
        a[f"{side}_shoulder"][:, 1] = 8.0
        a[f"{side}_elbow"][:, 0] = 20.0 + 0.4 * np.maximum(-(hip - 8.0), 0.0)
        a[f"{side}_wrist"][:, 0] = 5.0
    a["pelvis"][:, 2] = 5.0 * amp * np.cos(2 * np.pi * p)        # yaw
    a["pelvis"][:, 1] = 3.0 * np.sin(4 * np.pi * p)              # obliquity
    a["lumbar"][:, 0] = -4.0                                       # lean forward
    a["lumbar"][:, 2] = -6.0 * amp * np.cos(2 * np.pi * p)       # counter-rotation
    a["neck"][:, 0] = 4.0
    a["head"][:, 2] = 2.0 * np.cos(2 * np.pi * p)
    return a, np.zeros(F), np.zeros(F)


def _jump(t: _F64, rng: np.random.Generator) -> _Drive:
    F = t.size
    a = _zeros(F)
    p = _phase(t, 0.6, rng, fsd=0.05)
    amp = 1.0 + _smooth_noise(t, 1.0 / 0.6, rng, 0.08)
    c = amp * _bump(p, 0.32, 0.06) + 0.6 * _bump(p, 0.70, 0.06)       # crouch depth 0..1
    for side in ("l", "r"):
        a[f"{side}_hip"][:, 0] = 5.0 + 70.0 * c
        a[f"{side}_hip"][:, 1] = 4.0
        a[f"{side}_knee"][:, 0] = -(5.0 + 95.0 * c)
        a[f"{side}_ankle"][:, 0] = 30.0 * c - 25.0 * _bump(p, 0.50, 0.05)
        a[f"{side}_toe"][:, 0] = 20.0 * _bump(p, 0.44, 0.03)
        a[f"{side}_shoulder"][:, 0] = (-45.0 * _bump(p, 0.30, 0.07)
                                       + 140.0 * amp * _bump(p, 0.50, 0.07))
        a[f"{side}_shoulder"][:, 1] = 10.0
        a[f"{side}_elbow"][:, 0] = 15.0 + 20.0 * c
    a["lumbar"][:, 0] = -35.0 * c
    a["neck"][:, 0] = 15.0 * c
    # flight: ballistic height between take-off and landing, forward drift
    u = (p % 1.0 - 0.46) / 0.18
    fly = (u > 0) & (u < 1)
    height = 250.0 * amp
    air = np.where(fly, 4.0 * height * u * (1.0 - u), 0.0)
    vx = np.where(fly, 1000.0 * amp, 0.0)  # ~0.2 m per jump
    return a, air, vx


def _wave(t: _F64, rng: np.random.Generator) -> _Drive:
    F = t.size
    a = _zeros(F)
    p = _phase(t, 1.8, rng, fsd=0.06)
    amp = 1.0 + _smooth_noise(t, 1.0 / 1.8, rng, 0.1)
    raise_ = np.clip(t / 0.6, 0.0, 1.0)
    raise_ = raise_ * raise_ * (3 - 2 * raise_)                        # smoothstep up
    a["r_shoulder"][:, 1] = 100.0 * raise_                            # abduct
    a["r_shoulder"][:, 2] = 80.0 * raise_                             # external rotation
    a["r_elbow"][:, 0] = 15.0 + raise_ * (75.0 + 25.0 * amp * np.sin(2 * np.pi * p))
    a["r_wrist"][:, 1] = 15.0 * raise_ * np.sin(2 * np.pi * p - 0.6)
    sway = _smooth_noise(t, 2.0, rng, 1.0)
    for side in ("l", "r"):
        a[f"{side}_hip"][:, 1] = 2.0 + 0.5 * sway
        a[f"{side}_knee"][:, 0] = -5.0
        a[f"{side}_ankle"][:, 0] = 2.0
    a["l_shoulder"][:, 0] = 3.0 * sway
    a["l_shoulder"][:, 1] = 6.0
    a["l_elbow"][:, 0] = 15.0
    a["lumbar"][:, 1] = -3.0 * raise_ + 1.0 * np.sin(2 * np.pi * p)
    a["head"][:, 2] = -10.0 * raise_
    return a, np.zeros(F), np.zeros(F)


def _static(t: _F64, rng: np.random.Generator) -> _Drive:
    F = t.size
    a = _zeros(F)
    breath = np.sin(2 * np.pi * (0.25 * t + rng.uniform()))
    sway = _smooth_noise(t, 3.0, rng, 0.4)
    for side in ("l", "r"):
        a[f"{side}_hip"][:, 1] = 2.0
        a[f"{side}_ankle"][:, 0] = sway
        a[f"{side}_knee"][:, 0] = -3.0
        a[f"{side}_shoulder"][:, 1] = 6.0
        a[f"{side}_elbow"][:, 0] = 10.0
    a["lumbar"][:, 0] = 0.5 * breath
    a["chest"][:, 0] = 0.5 * breath
    return a, np.zeros(F), np.zeros(F)


_KIND_FUNCS: dict[str, Callable[[_F64, np.random.Generator], _Drive]] = {
    "walk": _walk, "jump": _jump, "wave": _wave, "static": _static}
_MIX_SEGMENT_S = 4.0   # seconds per activity in "mixed"
_MIX_BLEND_S = 0.6     # cross-fade between activities


def _mixed(t: _F64, rng: np.random.Generator) -> _Drive:
    order = [("walk", "jump", "wave", "static")[i] for i in rng.permutation(4)]
    parts = [_KIND_FUNCS[k](t, rng) for k in order]
    # weight of activity j: smoothstep cross-fades at segment boundaries, cycling
    slot = t / _MIX_SEGMENT_S
    w = np.zeros((len(order), t.size))
    for j in range(len(order)):
        for start in np.arange(j, np.ceil(slot[-1]) + 1, len(order)):
            lo = np.clip((slot - start) * _MIX_SEGMENT_S / _MIX_BLEND_S + 0.5, 0, 1)
            hi = np.clip((start + 1 - slot) * _MIX_SEGMENT_S / _MIX_BLEND_S + 0.5, 0, 1)
            s = np.minimum(lo, hi)
            w[j] += s * s * (3 - 2 * s)
    w[0, slot < 0.5] = 1.0  # no fade-in at t = 0
    w /= np.maximum(w.sum(axis=0), 1e-12)
    angles = {n: sum(w[j][:, None] * parts[j][0][n] for j in range(len(order)))
              for n in _JOINT_NAMES}
    air = sum(w[j] * parts[j][1] for j in range(len(order)))
    vx = sum(w[j] * parts[j][2] for j in range(len(order)))
    return angles, air, vx


_KIND_FUNCS["mixed"] = _mixed


# -- kinematics ----------------------------------------------------------------
def _rotations(ang: _F64, right: bool) -> _F64:
    """Local rotation matrices [F, 3, 3] from (flex, abd, twist) in degrees.

    R = R_flex @ R_abd @ R_twist; flexion turns about the subject's right axis
    (-Y, a downward limb swings forward), abduction about +X, twist about +Z.
    Right-side joints negate abduction and twist so both sides abduct outward.
    """
    r = np.deg2rad(ang)
    f, b, w = r[:, 0], r[:, 1], r[:, 2]
    if right:
        b, w = -b, -w
    F = r.shape[0]
    cf, sf = np.cos(f), np.sin(f)
    cb, sb = np.cos(b), np.sin(b)
    cw, sw = np.cos(w), np.sin(w)
    one, zero = np.ones(F), np.zeros(F)
    Rf = np.stack([np.stack([cf, zero, -sf], -1), np.stack([zero, one, zero], -1),
                   np.stack([sf, zero, cf], -1)], -2)
    Rb = np.stack([np.stack([one, zero, zero], -1), np.stack([zero, cb, -sb], -1),
                   np.stack([zero, sb, cb], -1)], -2)
    Rw = np.stack([np.stack([cw, -sw, zero], -1), np.stack([sw, cw, zero], -1),
                   np.stack([zero, zero, one], -1)], -2)
    return Rf @ Rb @ Rw


def _forward(angles: dict[str, _F64]) -> tuple[_F64, _F64]:
    """Segment positions [F, J, 3] and orientations [F, J, 3, 3] in the body frame."""
    F = next(iter(angles.values())).shape[0]
    J = len(_JOINT_NAMES)
    pos = np.empty((F, J, 3))
    rot = np.empty((F, J, 3, 3))
    for j, name in enumerate(_JOINT_NAMES):
        R = _rotations(angles[name], _RIGHT[j])
        p = _PARENT[j]
        if p < 0:
            rot[:, j] = R
            pos[:, j] = _OFFSET[j]
        else:
            rot[:, j] = rot[:, p] @ R
            pos[:, j] = pos[:, p] + rot[:, p] @ _OFFSET[j]
    return pos, rot


def _attach(pos: _F64, rot: _F64, seg: NDArray[np.intp], off: _F64) -> _F64:
    """World positions of points fixed on segments: p_seg + R_seg @ offset."""
    return pos[:, seg] + np.einsum("fmij,mj->fmi", rot[:, seg], off)


def _place(sole: _F64, air: _F64, vx: _F64, dt: float) -> _F64:
    """Root translation [F, 3] that keeps contact feet planted on the floor z = 0."""
    tau = 5.0  # mm, softness of the contact minimum
    z = sole[:, :, 2]
    zmin = z.min(axis=1, keepdims=True)
    e = np.exp(-(z - zmin) / tau)
    soft = zmin[:, 0] - tau * np.log(e.sum(axis=1))
    w = e / e.sum(axis=1, keepdims=True)
    # contact-weighted horizontal displacement of the feet, undone at the root
    wm = 0.5 * (w[1:] + w[:-1])
    dfoot = np.einsum("fm,fmk->fk", wm, np.diff(sole[:, :, :2], axis=0))
    ground = np.exp(-air / 10.0)
    gm = 0.5 * (ground[1:] + ground[:-1])
    step = -gm[:, None] * dfoot
    step[:, 0] += (1.0 - gm) * 0.5 * (vx[1:] + vx[:-1]) * dt
    root = np.zeros((sole.shape[0], 3))
    root[1:, :2] = np.cumsum(step, axis=0)
    root[:, 2] = air - soft
    return root


def _whole(value: object, name: str, low: int) -> int:
    """``value`` as a whole number of at least ``low`` (an int or numpy integer; not
    "10", 2.5 or True), else MotionError: "10" was taken, 2.5 cut to 2, and a seed of "a"
    or -1 failed inside numpy (a QA run of stop 48)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise MotionError(f"{name} must be a whole number, got {value!r}")
    if value < low:
        raise MotionError(f"{name} must be at least {low}, got {value}")
    return int(value)


def _real(value: object, name: str) -> float:
    """``value`` as a float if it is a real number (not a str, not a bool), else
    MotionError: rate="x" was a bare ValueError of float() (a QA run of stop 50)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer,
                                                         np.floating)):
        raise MotionError(f"{name} must be a number, got {value!r}")
    try:
        return float(value)
    except OverflowError:
        return math.inf


#: the longest motion :func:`generate` makes, in seconds (2^24, MAX_FRAMES at 1 Hz, about
#: 194 days): its random functions of time hold a knot every second or so
MAX_SECONDS = float(1 << 24)


def generate(kind: str = "walk", *, frames: int = 240, rate: float = 120.0, seed: int = 0,
             noise_mm: float = 0.3, gap_fraction: float = 0.0,
             markers: int | None = None) -> Motion:
    """Generate plausible human motion with the CMU 41-marker set.

    Parameters
    ----------
    kind : {"walk", "jump", "wave", "mixed", "static"}
        ``"walk"``: gait at ~0.9 strides/s along +X. ``"jump"``: repeated
        countermovement jumps (~0.25 m high, ~0.2 m forward). ``"wave"``:
        the right arm is raised and waves at ~1.8 Hz. ``"mixed"``: the other
        four in 4 s turns (seeded order) with 0.6 s cross-fades. ``"static"``:
        quiet standing with breathing and sway.
    frames : int
        Number of frames (>= 1).
    rate : float
        Frames per second; the motion is a function of time, so the rate only
        changes the sampling.
    seed : int
        Seed of ``numpy.random.default_rng``, the only randomness used.
    noise_mm : float
        Standard deviation of white Gaussian noise added to each coordinate.
    gap_fraction : float
        Share of marker-frames to occlude, in [0, 1]. Gaps are runs of 5..60
        contiguous frames of one marker, added until the share is reached
        (so it may be exceeded by less than one run).
    markers : int, optional
        Keep only the first ``markers`` of :data:`MARKERS`.

    Returns
    -------
    Motion
        Units ``"mm"``, Z-up; ``valid`` is False and positions NaN under gaps.
        ``metadata`` holds ``generator``, ``kind`` and ``seed``.

    Raises
    ------
    MotionError
        For an unknown kind or an out-of-range argument.

    Examples
    --------
    >>> from mpz.synth import generate
    >>> m = generate("walk", frames=120, seed=1)
    >>> m.n_frames, m.n_markers, m.units, m.names[4]
    (120, 41, 'mm', 'C7')
    >>> bool((generate("walk", frames=120, seed=1).positions == m.positions).all())
    True
    """
    if kind not in _KIND_FUNCS:
        raise MotionError(f"unknown synthetic motion kind {kind!r}, expected one of {KINDS}")
    frames = _whole(frames, "frames", 1)
    if frames > MAX_FRAMES:      # 10**9 ran until the kernel ended the process (QA, stop 50)
        raise MotionError(f"frames must be at most {MAX_FRAMES} (MAX_FRAMES, spec §8), got "
                          f"{frames}")
    seed = _whole(seed, "seed", 0)
    rate = _real(rate, "rate")
    if not np.isfinite(rate) or rate <= 0:
        raise MotionError(f"rate must be finite and positive, got {rate!r}")
    if frames / rate > MAX_SECONDS:
        # the motion is a function of time with random knots about a second apart: rate
        # 1e-9 asked numpy for 329 GiB (a QA run of the API, stop 54)
        raise MotionError(f"frames / rate must be at most {MAX_SECONDS:g} s (MAX_SECONDS), "
                          f"got {frames / rate:.6g} s ({frames} frames at {rate!r} Hz)")
    noise_mm = _real(noise_mm, "noise_mm")
    if not (np.isfinite(noise_mm) and noise_mm >= 0):
        raise MotionError(f"noise_mm must be finite and >= 0, got {noise_mm!r}")
    gap_fraction = _real(gap_fraction, "gap_fraction")
    if not (0.0 <= gap_fraction <= 1.0):
        raise MotionError(f"gap_fraction must be in [0, 1], got {gap_fraction!r}")
    n_out = len(MARKERS) if markers is None else _whole(markers, "markers", 1)
    if not 1 <= n_out <= len(MARKERS):
        raise MotionError(f"markers must be in 1..{len(MARKERS)}, got {markers!r}")

    rng = np.random.default_rng(seed)
    t = np.arange(frames) / rate
    angles, air, vx = _KIND_FUNCS[kind](t, rng)
    pos, rot = _forward(angles)
    body = _attach(pos, rot, _MSEG, _MOFF)
    sole = _attach(pos, rot, _SOLE_SEG, _SOLE_OFF)
    root = _place(sole, air, vx, 1.0 / rate)
    x = body + root[:, None, :]
    # sensor noise (drawn for all 41 markers so `markers=` is a pure subset)
    x = x + rng.normal(0.0, 1.0, x.shape) * noise_mm
    x = x[:, :n_out]
    valid = _gaps(rng, frames, n_out, gap_fraction)
    x[~valid] = np.nan
    return Motion(x, list(MARKERS[:n_out]), rate, "mm", valid,
                  {"generator": "mpz.synth", "kind": kind, "seed": str(seed)})


def _gaps(rng: np.random.Generator, frames: int, markers: int,
          fraction: float) -> NDArray[np.bool_]:
    """Validity mask with occlusion runs of 5..60 frames until ``fraction`` is hidden."""
    valid = np.ones((frames, markers), dtype=bool)
    total = frames * markers
    target = int(round(fraction * total))
    if target <= 0:
        return valid
    if target >= total:
        valid[:] = False
        return valid
    hidden = 0
    while hidden < target:
        # draw runs in batches; apply them one by one until the target is met
        n = max(8, (target - hidden) // 20)
        mk = rng.integers(0, markers, n)
        length = np.minimum(rng.integers(5, 61, n), frames)
        start = (rng.random(n) * (frames - length + 1)).astype(np.int64)
        for m, ln, s in zip(mk, length, start, strict=True):
            col = valid[s:s + ln, m]
            hidden += int(col.sum())
            col[:] = False
            if hidden >= target:
                break
    return valid
