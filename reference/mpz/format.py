"""Every constant of the MPZ 1.x format, in one place: code tables, flags and limits.

Contract: nothing here computes anything. Code tables of the spec are ``IntEnum`` s,
limits are plain integers with their derivation. The grammar
(:mod:`mpz.spec.grammar`) describes byte layout; this module says what the numbers
in it mean. The encoder, the decoder, the chunk table and the tools all import from
here, so the encoder never imports from the decoder.
"""
from __future__ import annotations

from enum import IntEnum

from mpz.spec.grammar import SIGNATURE, VERSION_MAJOR, VERSION_MINOR

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

    POSITIONS = 0          # marker positions relative to the root marker, D = 3M
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
MAX_SUMMARY_VALUES = 1 << 24    # sum over smry levels of k * D
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
