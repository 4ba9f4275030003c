"""The MPZ 1.x format's shared constants, in one place: code tables, flags and limits.
A constant that one module alone needs stays beside its rule there (for example
:data:`mpz.channels.TURN_DEGREES`, :data:`mpz.c3dcodec.K_LIMIT`, ``SMRC_MINOR`` in
:mod:`mpz.chunks.summary`).

Contract: nothing here computes anything. Code tables of the spec are ``IntEnum`` s,
limits are plain integers with their derivation. The grammar
(:mod:`mpz.spec.grammar`) describes byte layout; this module says what the numbers
in it mean. The encoder, the decoder, the chunk table and the tools all import from
here, so the encoder never imports from the decoder.
"""
from __future__ import annotations

from enum import IntEnum

from mpz.spec.grammar import MAX_C3D_PARAMETER_BYTES, SIGNATURE, VERSION_MAJOR, VERSION_MINOR

__all__ = [
    "SIGNATURE", "VERSION_MAJOR", "VERSION_MINOR", "Units", "ErrorMetric", "ResidualBase",
    "SummarySpace", "FLAG_RESIDUAL", "ROOT_PARENT", "MAX_FRAMES", "MAX_MARKERS",
    "MAX_SAMPLES", "MAX_CHUNK_LENGTH", "MAX_PATTERN_LENGTH", "MAX_PATTERN_SAMPLES",
    "MAX_SMOOTHING", "MAX_SUMMARY_LEVELS", "MAX_SUMMARY_VALUES", "MAX_ORDER", "MAX_BITS",
    "LIMITS", "LAYER_LIMIT", "KEY_VALUE_LIMIT", "UNIT_NAMES", "MM_PER_UNIT", "unit_code",
    "unit_name",
]


class Units(IntEnum):
    """§4.1 ``units``: the length unit of every position in the file."""

    UNKNOWN = 0
    MM = 1
    CM = 2
    M = 3
    IN = 4


#: §4.1 the name of each unit code, as :class:`mpz.Motion` spells it ("" = unknown)
UNIT_NAMES: dict[Units, str] = {Units.UNKNOWN: "", Units.MM: "mm", Units.CM: "cm",
                                Units.M: "m", Units.IN: "in"}


#: millimetres per unit, for every unit name MPZ knows (conversions and bounds given in mm)
MM_PER_UNIT: dict[str, float] = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4}


def unit_name(code: int) -> str:
    """The Motion unit name of a §4.1 unit code (the code must be valid)."""
    return UNIT_NAMES[Units(code)]


def unit_code(name: str) -> Units:
    """The §4.1 unit code of a Motion unit name; names MPZ has no code for map to UNKNOWN."""
    for code, text in UNIT_NAMES.items():
        if text == name:
            return code
    return Units.UNKNOWN


class ErrorMetric(IntEnum):
    """§4.1 ``error_metric``: what ``error_bound`` promises."""

    NONE = 0               # no bound declared
    MAX_EUCLIDEAN = 1      # every valid sample within error_bound (Euclidean, in units)


class ResidualBase(IntEnum):
    """§4.9 ``base``: what a node's residual layer is added to."""

    PARENT = 0             # the pattern layer, relative to the parent's reference marker
    ABSOLUTE = 1           # nothing: the members' grid values directly
    KEYFRAMES = 2          # nothing: key frames, interpolated (§6.5)


class SummarySpace(IntEnum):
    """§4.10 ``space``: what the summary's segment means describe."""

    POSITIONS = 0          # marker positions relative to the per-frame centroid, D = 3M
    ANGLES = 1             # joint angles, any D


#: §4.1 ``flags`` bit 0: the file has a residual layer (one RESI per non-root node)
FLAG_RESIDUAL = 0x0001
#: §4.3 the ``parent`` of node 0, which has none
ROOT_PARENT = 0xFFFF
#: §4.6, §4.7, §4.9 the temporal predictor orders are 0, 1 and 2
MAX_ORDER = 2
#: §4.4 every decoded q satisfies |q| < 2^bits, bits in 1..31
MAX_BITS = 31

# ------------------------------------------------------------------ §8 limits --
# Each is checked before anything is allocated; §8 derives the memory budget from them.
MAX_FRAMES = 1 << 24            # 16 777 216 frames: > 38 h at 120 Hz
MAX_MARKERS = 4096
MAX_SAMPLES = 1 << 26           # F * M <= 67 108 864 marker-frames (1.5 GiB of float64 output)
MAX_CHUNK_LENGTH = 1 << 30      # 1 GiB per chunk payload
MAX_PATTERN_LENGTH = 4096       # L, frames per pattern
MAX_PATTERN_SAMPLES = 1 << 24   # K * L * n_i per node
MAX_SMOOTHING = 16              # h, the boundary filter's half-width
MAX_SUMMARY_LEVELS = 64
MAX_SUMMARY_VALUES = 1 << 24    # sum over the levels of k * D (smry or smrc), and of k (smrc)
#: the §8 limits table, by name (the spec's machine-readable ``mpz:limits`` block lists the same)
LIMITS: dict[str, int] = {
    "MAX_FRAMES": MAX_FRAMES, "MAX_MARKERS": MAX_MARKERS, "MAX_SAMPLES": MAX_SAMPLES,
    "MAX_CHUNK_LENGTH": MAX_CHUNK_LENGTH, "MAX_PATTERN_LENGTH": MAX_PATTERN_LENGTH,
    "MAX_PATTERN_SAMPLES": MAX_PATTERN_SAMPLES, "MAX_SMOOTHING": MAX_SMOOTHING,
    "MAX_SUMMARY_LEVELS": MAX_SUMMARY_LEVELS, "MAX_SUMMARY_VALUES": MAX_SUMMARY_VALUES,
}
#: §6.7 rule 1: every scaled pattern and residual value is below 2^36 in magnitude
LAYER_LIMIT = 1 << 36
#: §6.5 every key-frame value w_k satisfies |w_k| < 2^31
KEY_VALUE_LIMIT = 1 << 31


# ------------------------------------------------ §4.14 skeleton chunks (MPZ 1.1) --
#: §2.1, §4.14 the minor version that introduced the skeleton chunks
SKELETON_MINOR = 1


class ChannelKind(IntEnum):
    """§4.14 the kind of a joint channel: BVH ``Xposition`` .. ``Zrotation``, ASF ``tx`` ..
    ``rz`` and ``l`` (bone stretch)."""

    TX = 0                 # translation along x (BVH Xposition, ASF tx / TX)
    TY = 1
    TZ = 2
    RX = 3                 # rotation about x (BVH Xrotation, ASF rx / RX)
    RY = 4
    RZ = 5
    L = 6                  # ASF bone length change


class AngleUnit(IntEnum):
    """§4.14.2 ``angle_unit``: the unit of ASF/AMC angles (BVH angles are degrees)."""

    DEG = 0
    RAD = 1


class TextEncoding(IntEnum):
    """§4.14.1, §4.14.2 ``encoding``: the text encoding of the source file."""

    UTF8 = 0
    LATIN1 = 1


#: §4.14.2 ``axis_order`` codes: the index of the order in this tuple
AXIS_ORDERS = ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX")
#: §4.14 a channel step is m x 10^-d with 0 <= d <= MAX_STEP_DIGITS
MAX_STEP_DIGITS = 9
#: §4.14, §6.10 every decoded channel integer satisfies |x| < 2^31
CHANNEL_VALUE_LIMIT = 1 << 31
#: §8 F x C, channel-frames of a skeleton chunk (512 MiB of int64 while decoding)
MAX_CHANNEL_SAMPLES = 1 << 26
LIMITS["MAX_CHANNEL_SAMPLES"] = MAX_CHANNEL_SAMPLES
__all__ += ["SKELETON_MINOR", "ChannelKind", "AngleUnit", "TextEncoding", "AXIS_ORDERS",
            "MAX_STEP_DIGITS", "CHANNEL_VALUE_LIMIT", "MAX_CHANNEL_SAMPLES"]


# --------------------------------------------- §4.13 C3D archive chunks (MPZ 1.1) --
#: §2.1, §4.13 the minor version that introduced the C3D archive chunks
C3D_MINOR = 1


class C3DProcessor(IntEnum):
    """§4.13.1 ``processor``: the processor type of the source C3D (informative)."""

    INTEL = 84
    DEC = 85
    MIPS = 86


class C3DStorage(IntEnum):
    """§4.13.3, §4.13.4 ``storage``: how the source stored these words."""

    INT16 = 0
    FLOAT32 = 1


class ChannelMode(IntEnum):
    """§4.13 channel entry ``mode``: how a channel's words become integers (§6.9)."""

    INTEGER = 0            # word = k x 2^shift, |k| < 2^24
    BITS = 1               # the float32 bit pattern, as an ordered integer


class ModelKind(IntEnum):
    """§4.13.3 model output ``kind``: the POINT parameter that lists the point."""

    ANGLES = 0
    FORCES = 1
    MOMENTS = 2
    POWERS = 3
    SCALARS = 4
    REACTIONS = 5


#: §4.13 channel entry ``shift`` of mode 0: every k x 2^shift with |k| < 2^24 is a binary32
C3D_MIN_SHIFT, C3D_MAX_SHIFT = -128, 104
#: §4.13 channel entry ``low_bits`` b: residual e = h x 2^b + l; 3 covers 33-bit residuals
C3D_MAX_LOW_BITS = 3
#: §8 F x n x C, analog samples of a cana chunk (2 GiB of int64 for the largest channel)
MAX_ANALOG_SAMPLES = 1 << 28
LIMITS["MAX_ANALOG_SAMPLES"] = MAX_ANALOG_SAMPLES


class ByteCoding(IntEnum):
    """§4.13 ``coding`` of chdr and cprm: how the bytes of the chunk's content are stored."""

    STORED = 0             # as they are
    DEFLATE = 1            # one raw DEFLATE stream (RFC 1951), inflated before the checks


#: §4.13.2, §8 the largest inflated cprm section (defined with the grammar, which bounds a
#: record's data by it)
LIMITS["MAX_C3D_PARAMETER_BYTES"] = MAX_C3D_PARAMETER_BYTES
__all__ += ["C3D_MINOR", "C3DProcessor", "C3DStorage", "ChannelMode", "ModelKind",
            "C3D_MIN_SHIFT", "C3D_MAX_SHIFT", "C3D_MAX_LOW_BITS", "MAX_ANALOG_SAMPLES",
            "ByteCoding", "MAX_C3D_PARAMETER_BYTES"]
