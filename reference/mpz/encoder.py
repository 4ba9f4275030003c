"""The MPZ reference encoder: the paper's pipeline, plus a hard error bound.

Strategy (reads as Fig. 2 of Gu, Peng & Deng), one function per stage:

1. :func:`plan_hierarchy` - the body-part hierarchy (§III-A) and ADDH, the head scale
   every threshold is relative to;
2. :func:`plan_grid` - the quantisation grid (spec §4.4): with ``max_error=E`` the step
   keeps the Euclidean error <= E; without it, a fine grid (ADDH / 1000);
3. :func:`code_root` - the root marker as an absolute track (§III-D, spec §4.6);
4. :func:`code_node` - node by node, parents first, in *closed loop* (each node is coded
   relative to the decoded, not the original, reference marker of its parent, so errors
   do not pile up down the tree): :func:`code_patterns` (segmentation, Alg. 1 ->
   normalisation -> adaptive K-means -> patterns quantised and predicted -> (pattern
   index, frame count) pairs -> the decoder's own de-normalisation and smoothing), then,
   with a bound, the cheapest :class:`ResidualLayer` that restores every sample to within
   E (beyond the paper);
5. :func:`file_records` - header, names, hierarchy, grid, mask, the coded nodes, the
   optional Fisher summary and metadata, as typed chunk records (:mod:`mpz.chunks`),
   framed by :func:`mpz.container.build`, the same table the decoder reads with.

The encoder never writes files; see :func:`mpz.write_mpz` for atomic output.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import Executor, Future, ThreadPoolExecutor
from dataclasses import dataclass, field, fields, replace
import math
import os
import threading
import time
from typing import Any, Never, TypedDict, TypeVar

import numpy as np
from numpy.typing import NDArray

from mpz import container, keyframe
from mpz._worker import spelled
from mpz.c3darchive import binary32_values, float32_bound
from mpz.chunks import (
    Hier,
    HierNode,
    Mask,
    Mend,
    Meta,
    MetaEntry,
    Mhdr,
    Mnam,
    Patt,
    Qunt,
    Record,
    Resi,
    Root,
    Segs,
    Smrc,
    Smry,
    SummaryLevel,
)
from mpz.chunks.summary import MEAN_LIMIT, CodedSummaryLevel
from mpz.chunks.summary import encode_levels as encode_summary_levels
from mpz.cluster import adaptive_kmeans
from mpz.entropy import MAX_EXP, BlockEncoder
from mpz.errors import EncoderError, LimitExceededError, MotionError
from mpz.extensions import EXTENSIONS
from mpz.format import (
    FLAG_RESIDUAL,
    MAX_BITS,
    MAX_FRAMES,
    MAX_MARKERS,
    MAX_PATTERN_LENGTH,
    MAX_SAMPLES,
    MAX_SMOOTHING,
    MAX_SUMMARY_LEVELS,
    MM_PER_UNIT,
    ROOT_PARENT,
    VERSION_MAJOR,
    ErrorMetric,
    ModelKind,
    ResidualBase,
    SummarySpace,
    unit_code,
)
from mpz.hierarchy import Hierarchy, Node, build_hierarchy, head_scale
from mpz.hierarchy import root_marker as hierarchy_root
from mpz.hierarchy.measure import pair_frames
from mpz.hierarchy.model import MAX_WEIGHT, MIN_WEIGHT
from mpz.motion import READER_NOT_KEPT, Motion, held_extras, metadata_type_error
from mpz.normalize import denormalize, normalize, segment_starts
from mpz.predict import reconstruct, residuals
from mpz.quantize import choose_lattice, grid_units
from mpz.segment import segment
from mpz.smooth import smooth_frames, window

IntArray = NDArray[np.int64]
#: grid values a candidate layer keeps (|w| < 2^30, §5.4): half the memory of int64
Int32Array = NDArray[np.int32]
FloatArray = NDArray[np.float64]
Progress = Callable[[float, str], None]
#: how far the progress callback of :func:`encode_motion` is when the nodes start (the
#: hierarchy plan took 16 % of a 54,000-frame walk's default encode), and, within a node
#: coded by key frames, when its fit and then its key-frame coding end (56 % and 63 % of
#: that node's time): measured proportions, so that a long capture's bar moves while its
#: one flat node is coded (it stood at 0 % for the 30 s of a 30-minute capture)
PLANNED = 0.15
FITTED, KEYS_CODED = 0.55, 0.62

SQRT3 = math.sqrt(3.0)
#: shrink the grid step by 2^-20 so float rounding can never push an error past E
SAFETY = 1.0 - 2.0 ** -20
#: key frames are fitted on a grid this many times finer than the bound's own grid: the
#: interpolated values are rounded to the grid, and on the coarse grid that rounding alone
#: can use up the whole error budget (measured: 5 mm files 36 -> 51:1 on cmu_02_01)
KEY_REFINE = 2


# ----------------------------------------------------------------- options --
class FrozenMapping(Mapping[Any, Any]):
    """A read-only mapping for :class:`EncodeOptions`' mapping fields: immutable like a
    ``MappingProxyType``, and also picklable, deep-copyable and hashable (when its values
    are), so that options cross process boundaries (``concurrent.futures``,
    ``multiprocessing``) and can key a cache. Equal to any mapping with the same items."""

    __slots__ = ("_items",)

    def __init__(self, items: Mapping[Any, Any]) -> None:
        self._items = dict(items)

    def __getitem__(self, key: Any) -> Any:
        return self._items[key]

    def __iter__(self) -> Iterator[Any]:
        return iter(self._items)

    def __len__(self) -> int:
        return len(self._items)

    def __hash__(self) -> int:
        return hash(frozenset(self._items.items()))

    def __repr__(self) -> str:
        return repr(self._items)

    def __reduce__(self) -> tuple[Any, ...]:
        return (FrozenMapping, (self._items,))


def _as_dict(value: object, name: str) -> dict[Any, Any]:
    """A mapping option as a dict (issue 11.6: anything else is an EncoderError)."""
    if not isinstance(value, Mapping):
        raise EncoderError(f"{name} must be a mapping (name -> value), got "
                           f"{type(value).__name__}")
    return dict(value)


def _plain(value: Any) -> Any:
    """A numpy scalar as the Python value it holds (float, int or bool); anything else as
    it is, for the checks to judge."""
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, np.floating):
        return float(value)
    if isinstance(value, np.integer):
        return int(value)
    return value


@dataclass(frozen=True)
class EncodeOptions:
    """Every control of the encoder; the field defaults are the one definition of the
    defaults (``mpz encode`` reads them from here).

    Options are immutable: :meth:`validate` checks them without changing them, and
    derived settings (:attr:`pattern_mode`) are properties.

    Global distortion controls (paper §IV): ``theta`` (key-frame threshold, fraction of
    ADDH), ``k0`` (initial clusters), ``tau`` (clustering threshold, fraction of ADDH),
    ``metric`` ("max" or "ave"). Local controls: ``weights`` (marker or node name ->
    weight) and ``group_errors`` (node name -> max error, under a bound). Beyond the
    paper: ``max_error`` (hard bound, motion units), ``patterns`` ("auto" keeps the
    pattern layer of a node only where it makes the file smaller; "on"; "off"; None: "off"
    under a bound, "on" without), ``segmentation`` ("adaptive" = Alg. 1, "optimal" =
    Fisher partition).
    """

    max_error: float | None = None
    group_errors: Mapping[str, float] = field(default_factory=dict)
    theta: float = 0.2
    k0: int = 10
    tau: float = 0.05
    metric: str = "max"
    weights: Mapping[str, float] | None = None
    #: "cmu41", "skeleton", "auto", "flat", a JSON hierarchy file or its dict; None: one
    #: flat node when patterns are off and no group_errors are given, else from the names
    hierarchy: Any = None
    #: boundary smoothing half-width, 0..16 (spec §6.4)
    smoothing: int = 2
    patterns: str | None = None
    segmentation: str = "adaptive"
    #: grid step in motion units: an upper limit under a bound, the step itself if lossy
    grid: float | None = None
    #: the longest segment in frames, 2..4096
    max_segment: int = 240
    #: segment counts k of the optional summary chunk (Fisher's partition, §4.15 / §4.10)
    summary: tuple[int, ...] = ()
    #: what the summary segments: "positions" (relative to the centroid) or "angles"
    summary_space: str = "positions"
    #: issue 14.12: "smrc" the range-coded summary chunk (§4.15, MPZ 1.1; the default), or
    #: "smry" the raw 1.0 chunk (§4.10) for readers that know only 1.0
    summary_format: str = "smrc"
    #: extra §4.11 metadata, added to ``motion.metadata``; not the keys the readers set to
    #: describe their file (``mpz.io.READER_KEYS``: ``format`` ...; ``mpz.io.
    #: READER_PREFIXES``: ``trc.Decimals`` ...), but for ``subject`` and ``source``
    #: (:func:`reader_key`)
    metadata: Mapping[str, str] = field(default_factory=dict)
    #: seed of the clustering (the encoder is deterministic)
    seed: int = 0
    # issue 12: a safe default bound, the paper's unbounded mode only by name, model outputs
    #: the paper's lossy mode (no residual layer, no declared bound): only when asked for
    lossy: bool = False
    #: the bound when neither max_error nor lossy is given, for motions in known units
    #: (spec Appendix C: below the reconstruction residual of every real capture measured)
    default_error_mm: float = 0.1
    #: ... and for motions without units: this fraction of the largest extent of the data
    default_error_fraction: float = 1e-4
    #: code positions exactly on this grid (x = q x step, error 0); by default the grid of an
    #: int16 C3D source (|POINT:SCALE|), when no bound is given
    source_grid: float | None = None
    #: model outputs (§4.13.3): max error as a fraction of each channel's range
    model_error: float = 1e-4
    #: ... per kind (ANGLES, FORCES, MOMENTS, POWERS, SCALARS, REACTIONS), e.g. looser angles
    model_errors: Mapping[str, float] = field(default_factory=dict)
    # issue 13, skeletal input (BVH, AMC/ASF; spec §4.14, mpz.skeleton):
    #: False: write no skeleton chunks (a plain 1.0 file of joint positions)
    keep_skeleton: bool = True
    #: bound on rotation channels in degrees; None: mpz.skeleton.DEFAULT_CHANNEL_ERROR (0.01),
    #: or as position_error allows when that is set
    angle_error: float | None = None
    #: bound on translation channels in the skeleton's length unit; None: the same default
    #: as angle_error's (0.01, or as position_error allows when that is set), whatever
    #: angle_error is given (it said "as angle_error": an API QA run of stop 74)
    translation_error: float | None = None
    #: bound on joint positions computed from the channels (spec §6.10), in motion units;
    #: None: max_error when that is given (resolve_bound), else none
    position_error: float | None = None
    # issue 15, speed:
    #: threads for the independent work within one file (the candidate residual layers of a
    #: node, the key-frame fit of each member); None: os.cpu_count() capped at
    #: MAX_DEFAULT_THREADS, and 1 below MIN_THREADED_SAMPLES marker-frames. The bytes
    #: written do not depend on it.
    threads: int | None = None

    def __post_init__(self) -> None:
        # numpy scalars as Python numbers: a np.float16 max_error made the encoder's
        # arithmetic float16 and broke the bound it declared, by up to 1.00025x (a QA run
        # of the API, stop 54); a np.float32 one gave other bytes than float(x)
        for f in fields(self):
            object.__setattr__(self, f.name, _plain(getattr(self, f.name)))
        for name in ("group_errors", "weights", "model_errors"):
            v = getattr(self, name)
            if isinstance(v, Mapping):
                object.__setattr__(self, name, {k: _plain(x) for k, x in v.items()})
        # read-only views, so an options object cannot change after it is made
        object.__setattr__(self, "group_errors",
                           FrozenMapping(_as_dict(self.group_errors, "group_errors")))
        object.__setattr__(self, "metadata", FrozenMapping(_as_dict(self.metadata,
                                                                    "metadata")))
        object.__setattr__(self, "model_errors", FrozenMapping(
            {str(k).upper(): v for k, v in _as_dict(self.model_errors, "model_errors").items()}))
        if self.weights is not None:
            object.__setattr__(self, "weights", FrozenMapping(_as_dict(self.weights,
                                                                       "weights")))
        if isinstance(self.summary, (str, bytes)) or not isinstance(self.summary, Iterable):
            raise EncoderError(f"summary must be a sequence of segment counts, got "
                               f"{self.summary!r}")
        object.__setattr__(self, "summary", tuple(_plain(k) for k in self.summary))

    @property
    def bounded(self) -> bool:
        """A hard bound is declared (every mode but ``lossy``): every node gets a residual
        layer. Without ``max_error`` the bound is the default (:func:`resolve_bound`)."""
        return not self.lossy

    @property
    def pattern_mode(self) -> str:
        """``patterns`` with its default resolved: "off" under a bound, else "on"."""
        if self.patterns is None:
            return "off" if self.bounded else "on"
        return self.patterns

    def validate(self) -> None:
        """Raise EncoderError for options that cannot be honoured (changes nothing)."""
        check_option_values(self)          # issue 11.6: types and ranges, each option named
        e = self.max_error
        if e is not None and not (math.isfinite(e) and e > 0):
            raise EncoderError(f"max_error must be finite and > 0, got {self.max_error!r}")
        for name, e in self.group_errors.items():
            if not (math.isfinite(e) and e > 0):
                raise EncoderError(f"group error for {name!r} must be finite and > 0, got {e!r}")
        if self.lossy and (self.max_error is not None or self.source_grid is not None):
            raise EncoderError(f"{_flag('lossy')} (the paper's unbounded mode) and a bound ("
                               f"{spelled('--max-error', 'max_error, source_grid')}) exclude "
                               "each other")
        if self.group_errors and self.lossy:
            raise EncoderError(f"group error bounds need a bound: not with {_flag('lossy')}")
        for name, v in (("default_error_mm", self.default_error_mm),
                        ("default_error_fraction", self.default_error_fraction),
                        ("model_error", self.model_error),
                        *((("source_grid", self.source_grid),)
                          if self.source_grid is not None else ()),
                        *((f"model_errors[{k!r}]", e) for k, e in self.model_errors.items())):
            if (isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating))
                    or not (math.isfinite(v) and v > 0)):
                raise EncoderError(f"{name} must be finite and > 0, got {v!r}")
        for name, v in (("model_error", self.model_error),
                        *((f"model_errors[{k!r}]", e) for k, e in self.model_errors.items())):
            if v > 1:         # a fraction of a channel's range (1e308 made an infinite bound)
                raise EncoderError(f"{name} (--model-error) is a fraction of each channel's "
                                   f"range, at most 1, got {v!r}")
        kinds = {k.name for k in ModelKind}
        unknown = sorted(set(self.model_errors) - kinds)
        if unknown:
            raise EncoderError(f"model error given for {', '.join(unknown)}; the model-output "
                               f"kinds are {', '.join(sorted(kinds))}")
        if not self.theta > 0 or not self.tau > 0:
            raise EncoderError("theta and tau must be > 0 (fractions of the head size ADDH)")
        if not 1 <= self.k0 <= 65535:
            raise EncoderError(f"k0 must be in 1..65535, got {self.k0}")
        if self.metric not in ("max", "ave"):
            raise EncoderError(f"metric must be 'max' or 'ave', got {self.metric!r}")
        if self.pattern_mode not in ("auto", "on", "off"):
            raise EncoderError(f"patterns must be auto, on or off, got {self.patterns!r}")
        if self.pattern_mode == "off" and not self.bounded:
            raise EncoderError("patterns='off' needs a bound, not lossy (the residual layer "
                               "carries the motion)")
        if self.segmentation not in ("adaptive", "optimal"):
            raise EncoderError(f"segmentation must be adaptive or optimal, got "
                               f"{self.segmentation!r}")
        if not 0 <= self.smoothing <= MAX_SMOOTHING:
            raise EncoderError(f"smoothing must be in 0..{MAX_SMOOTHING}")
        if self.grid is not None and not (math.isfinite(self.grid) and self.grid > 0):
            raise EncoderError(f"grid must be finite and > 0, got {self.grid!r}")
        if not 2 <= self.max_segment <= MAX_PATTERN_LENGTH:
            raise EncoderError(f"max_segment must be in 2..{MAX_PATTERN_LENGTH}")


#: the defaults, for tools that show or restate them
DEFAULTS = EncodeOptions()


# ------------------------------------------------------ issue 11.6: inputs --
# Every option and every input is checked before any work, by type and range, and a bad
# one is an EncoderError naming it: nothing else may escape the encoder (a ValueError
# from scipy, a ZeroDivisionError, a UnicodeEncodeError after the whole encode, ...).

#: lengths (max_error, group errors, grid) in motion units: the grid step, about E / sqrt(3),
#: stays a normal binary64 number, and step x 2^31 stays finite (§4.4)
MIN_LENGTH = 1e-300
MAX_LENGTH = 1e300
#: theta and tau are fractions of the head size ADDH; above this they change nothing
MAX_FRACTION = 1e6
#: the largest position magnitude taken, in motion units: the encoder squares distances and
#: sums them over up to 2^26 samples (hierarchy, segmentation, summary), which must stay
#: finite in binary64 ((2 x 10^100)^2 x 2^26 x 3 < 10^210)
MAX_MAGNITUDE = 1e100


#: the options of :class:`EncodeOptions` that ``mpz encode`` sets from a flag of the same
#: name (``max_error`` from ``--max-error``): their messages name the flag when a command
#: runs (:func:`_flag`; a newcomer's QA run, stop 73, was told "threads must be in 1..64"
#: for ``--threads -1``)
FLAG_OPTIONS = frozenset({"max_error", "grid", "theta", "tau", "k0", "smoothing", "seed",
                          "threads", "metric", "segmentation", "summary_space",
                          "summary_format", "patterns", "lossy", "angle_error",
                          "translation_error", "summary", "hierarchy"})


#: the options that act on the pattern layer alone (code_patterns): a file without one is
#: the same whatever they are (weights act there too, a mapping given or not)
PATTERN_OPTIONS = ("theta", "k0", "tau", "metric", "segmentation", "max_segment", "seed")


def _flag(name: str) -> str:
    """An option's name as the reader of a message knows it: ``--max-error`` where a
    command runs, ``max_error`` in a program (:func:`mpz._worker.spelled`)."""
    return spelled("--" + name.replace("_", "-"), name) if name in FLAG_OPTIONS else name


def _number(value: object, name: str) -> float:
    """``value`` as a float; only real numbers (not bool, not text) are numbers."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise EncoderError(f"{name} must be a number, got {value!r}")
    try:
        return float(value)
    except OverflowError:               # an int beyond binary64
        raise EncoderError(f"{name} must be a number in binary64 range, got {value!r}") from None


def _integer(value: object, name: str, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise EncoderError(f"{name} must be an integer, got {value!r}")
    if not lo <= int(value) <= hi:
        raise EncoderError(f"{name} must be in {lo}..{hi}, got {value!r}")
    return int(value)


def _length(value: object, name: str) -> float:
    v = _number(value, name)
    if not MIN_LENGTH <= v <= MAX_LENGTH:      # NaN fails too
        raise EncoderError(f"{name} must be a length from {MIN_LENGTH:g} to {MAX_LENGTH:g} in "
                           f"the motion's units, got {value!r}")
    return v


def _metadata_utf8(meta: Mapping[Any, Any]) -> None:
    """Metadata that maps str to str (in :func:`mpz.motion.metadata_type_error`'s words, a
    Motion's too) and that UTF-8 can hold (§4.11)."""
    if not isinstance(meta, Mapping):       # a Motion's set to None after it was made
        raise EncoderError(f"metadata must be a mapping of str to str, got "
                           f"{type(meta).__name__}")
    said = metadata_type_error(meta)
    if said is not None:
        raise EncoderError(said)
    for k, text in meta.items():
        _utf8(k, "metadata key")
        _utf8(text, f"metadata value of {k!r}")


def _utf8(text: object, what: str) -> str:
    """``text`` if it is a str that UTF-8 can hold (no lone surrogates, which readers make
    of undecodable bytes); the MPZ strings (MNAM, meta) are UTF-8 (§4.2, §4.11)."""
    if not isinstance(text, str):
        raise EncoderError(f"{what} must be text, got {type(text).__name__} {text!r}")
    try:
        text.encode("utf-8")
    except UnicodeEncodeError as exc:
        raise EncoderError(f"{what} is not valid Unicode text: {ascii(text)} holds a lone "
                           f"surrogate at character {exc.start} (what undecodable bytes of a "
                           f"source file become), and MPZ stores UTF-8") from None
    return text


def check_option_names(given: Iterable[str]) -> None:
    """Refuse option names that are not fields of :class:`EncodeOptions`, naming the
    closest field (only MPZError leaves the API, mpz.errors)."""
    names = [f.name for f in fields(EncodeOptions)]
    bad = sorted(set(given) - set(names))
    if bad:
        import difflib
        close = difflib.get_close_matches(bad[0], names, n=1)
        hint = f"; did you mean {close[0]}?" if close else ""
        raise EncoderError(f"unknown option {', '.join(bad)}{hint} (the options are the "
                           "fields of EncodeOptions)")


def check_option_values(o: EncodeOptions) -> None:
    """Issue 11.6: the type and range of every option, naming the option at fault.

    Raises
    ------
    EncoderError
        For the first option that is not of its type or not in its range.
    """
    if o.max_error is not None:
        _length(o.max_error, _flag("max_error"))
    for k, v in o.group_errors.items():
        _utf8(k, "group_errors: a node name")
        _length(v, f"group error of node {k!r}")
    if o.grid is not None:
        _length(o.grid, _flag("grid"))
    for name in ("theta", "tau"):
        v = _number(getattr(o, name), _flag(name))
        if not 0 < v <= MAX_FRACTION:
            raise EncoderError(f"{_flag(name)} must be a fraction of the head size ADDH in "
                               f"(0, {MAX_FRACTION:g}], got {getattr(o, name)!r}")
    _integer(o.k0, _flag("k0"), 1, 65535)
    _integer(o.smoothing, _flag("smoothing"), 0, MAX_SMOOTHING)
    _integer(o.max_segment, "max_segment", 2, MAX_PATTERN_LENGTH)
    _integer(o.seed, _flag("seed"), 0, 2 ** 63 - 1)
    if o.threads is not None:
        _integer(o.threads, _flag("threads"), 1, MAX_THREADS)
    for name in ("metric", "segmentation", "summary_space", "summary_format"):
        if not isinstance(getattr(o, name), str):
            raise EncoderError(f"{name} must be text, got {getattr(o, name)!r}")
    if o.summary_space not in ("positions", "angles"):
        raise EncoderError(f"{_flag('summary_space')} must be positions or angles, got "
                           f"{o.summary_space!r}")
    if o.summary_format not in ("smrc", "smry"):
        raise EncoderError(f"{_flag('summary_format')} must be smrc (coded, MPZ 1.1) or smry "
                           "(raw, 1.0), "
                           f"got {o.summary_format!r}")
    if o.patterns is not None and not isinstance(o.patterns, str):
        raise EncoderError(f"patterns must be auto, on, off or None, got {o.patterns!r}")
    for name in ("lossy", "keep_skeleton"):       # "no" was taken as true
        if not isinstance(getattr(o, name), bool):
            raise EncoderError(f"{name} must be True or False, got {getattr(o, name)!r}")
    for name in ("angle_error", "translation_error", "position_error"):
        v = getattr(o, name)            # checked whether or not the motion has a skeleton
        if v is not None and not 0 < _number(v, _flag(name)) < math.inf:
            raise EncoderError(f"{_flag(name)} must be a finite number above 0, got {v!r}")
    for count in o.summary:
        _integer(count, f"{_flag('summary')}: a segment count", 1, MAX_FRAMES)
    if len(set(o.summary)) > MAX_SUMMARY_LEVELS:
        raise EncoderError(f"{_flag('summary')}: at most {MAX_SUMMARY_LEVELS} segment counts "
                           f"(§8), got {len(set(o.summary))}")
    for k, w in (o.weights or {}).items():
        _utf8(k, "weights: a marker or node name")
        v = _number(w, f"weight of {k!r}")
        if not MIN_WEIGHT <= v <= MAX_WEIGHT:
            raise EncoderError(f"weight of {k!r} must be from 1/16 to 16 (what HIER holds, "
                               f"§4.3), got {w!r}")
    _metadata_utf8(o.metadata)
    check_metadata(o.metadata)      # an empty key was refused only with the motion's own
    reserved = [k for k in o.metadata if reader_key(k)]
    if reserved:
        raise EncoderError(f"metadata {reserved[0]!r}: a key the readers set to describe the "
                           "file they read, which the tools go by (mpz decode, mpz show); "
                           f"give your own name, e.g. {own_key(reserved[0])}")


#: the reader keys (:data:`mpz.io.READER_KEYS`) that the options' metadata may set: a C3D's
#: subject names a person, which a caller may give a motion from any source; the source's
#: file name, which the CLI and corpus runs set this way and by which `mpz decode` names
#: its output (a caller encoding a motion made in memory may give one)
OWN_METADATA_KEYS = frozenset({"subject", "source"})


def own_key(key: str) -> str:
    """A name to suggest in place of the reader key ``key``, itself not one: ``format`` ->
    ``format_note``, ``trc.Decimals`` -> ``note_trc_Decimals`` (``trc.Decimals_note`` is
    a reader key too: a review of stop 56 was sent round that loop)."""
    from mpz.io import READER_PREFIXES
    if key.startswith(READER_PREFIXES):
        return "note_" + key.replace(".", "_")
    return f"{key}_note"


def reader_key(key: str) -> bool:
    """Whether ``key`` is one the readers set to describe the file they read and the tools
    go by (``format`` picks ``mpz decode``'s writer): refused in ``metadata`` (the CLI's
    ``--meta``), since a file claiming ``format=bvh`` could not be decoded by name (a QA
    run of stop 48: the API took it, the CLI refused it), except :data:`OWN_METADATA_KEYS`;
    and the header fields a text reader keeps (:data:`mpz.io.READER_PREFIXES`)."""
    from mpz.io import READER_KEYS, READER_PREFIXES
    # a TRC's or CSV's header fields too: `--meta trc.Decimals=1` replaced the source's
    # own value, and its TRC was written back with one decimal (stop 54's list)
    return (key in READER_KEYS and key not in OWN_METADATA_KEYS
            or key.startswith(READER_PREFIXES))


def _consistent(motion: Motion) -> None:
    """The checks of :class:`Motion`'s constructor, made again: a Motion is a plain mutable
    object, and a rate set to -5, a names list grown by one or NaN written into the
    caller's array after it was made gave a file the decoder rejects, or an IndexError
    (a QA run of the API)."""
    from mpz.motion import check_consistent
    try:
        check_consistent(motion)
    except MotionError as exc:
        raise EncoderError(exc.message) from None


def check_metadata(meta: Mapping[str, str]) -> None:
    """§4.11's limits on the metadata a file will hold (the motion's and the options'):
    at most 65535 entries, keys of 1..255 bytes of UTF-8, values of at most 65535. They
    were cut to fit, silently: two long keys could become one, an empty one '_'."""
    if len(meta) > 65535:
        raise EncoderError(f"{len(meta)} metadata entries, more than the 65535 of §4.11")
    for k, v in meta.items():       # str to str: _metadata_utf8 checked both sources
        n = len(k.encode("utf-8", "surrogatepass"))
        if not 1 <= n <= 255:
            raise EncoderError(f"metadata key {ascii(k[:60])}: {n} bytes; keys are 1..255 "
                               "bytes of UTF-8 (§4.11)")
        n = len(v.encode("utf-8", "surrogatepass"))
        if n > 65535:
            raise EncoderError(f"metadata value of {ascii(k[:60])}: {n} bytes, more than the "
                               "65535 of §4.11")


def check_motion(motion: Motion) -> None:
    """Issue 11.6: what the file will hold, checked before any work: marker names and
    metadata as UTF-8 (§4.2, §4.11), and position magnitudes up to :data:`MAX_MAGNITUDE`.

    Raises
    ------
    EncoderError
        Naming the marker, the key, or the frame and marker of the largest position.
    """
    for i, name in enumerate(motion.names):
        _utf8(name, f"marker {i} name")
        if not 1 <= len(name.encode("utf-8")) <= 255 or "\x00" in name:
            shown = (ascii(name) if len(name) <= 80     # not a 100 KB message for a long one
                     else f"{ascii(name[:60])}... ({len(name)} characters)")
            raise EncoderError(f"marker {i} name {shown}: marker names are 1..255 bytes "
                               f"of UTF-8 without NUL (§4.2)")
    _metadata_utf8(motion.metadata)
    F = motion.n_frames
    step = max(1, (1 << 20) // max(1, motion.n_markers))    # bounded temporaries
    for t0 in range(0, F, step):
        blk = np.abs(motion.positions[t0: t0 + step])
        blk[~motion.valid[t0: t0 + step]] = 0.0
        peak = float(blk.max(initial=0.0))
        if peak > MAX_MAGNITUDE:
            t, m, _ = np.unravel_index(int(np.argmax(blk)), blk.shape)
            raise EncoderError(f"position magnitude {peak:g} (frame {t0 + int(t)}, marker "
                               f"{ascii(motion.names[int(m)])}) is beyond the "
                               f"{MAX_MAGNITUDE:g} {motion.units or 'units'} the encoder "
                               f"takes")


# ----------------------------------------------------------------- reports --
@dataclass
class NodeReport:
    """What the encoder did with one hierarchy node below the root, an entry of
    :attr:`EncodeReport.nodes` (the root marker's own track is coded as ROOT, §4.6, and
    has no entry)."""

    #: the node's name in the coding hierarchy (HIER, §4.3)
    name: str
    #: its member markers
    members: int
    #: the segments of its pattern layer (SEGS, §4.8); 0 without patterns
    segments: int = 0
    #: K, its motion patterns (PATT, §4.7); 0 without patterns
    patterns: int = 0
    #: L, the frames of each pattern (§4.7); 0 without patterns
    pattern_length: int = 0
    #: the bytes of its coded patterns (PATT's range-coded payload)
    pattern_bytes: int = 0
    #: the bytes of its coded segments (SEGS's range-coded payload)
    segment_bytes: int = 0
    #: the bytes of its coded residual layer (RESI, §4.9); 0 without one (lossy mode)
    residual_bytes: int = 0
    #: the residual layer's scale g (§4.9); 1 without one
    residual_scale: int = 1
    #: the residual layer's order field (§4.9); None without one
    residual_order: int | None = None
    #: whether the node is coded with patterns (PATT and SEGS written)
    used_patterns: bool = False


@dataclass
class EncodeReport:
    """What the encoder did: sizes, grid, per-node segments and patterns."""

    #: F, the motion's frame count
    frames: int
    #: M, the motion's marker count
    markers: int
    #: the motion as float32 xyz (:meth:`Motion.raw_size`), what :attr:`ratio` divides
    raw_bytes: int
    #: the MPZ file's length in bytes
    file_bytes: int = 0
    #: the grid step (QUNT, §4.4) in the motion's units
    step: float = 0.0
    #: the head scale ADDH (paper §V) in the motion's units
    addh: float = 0.0
    #: how ``addh`` was found (:func:`mpz.hierarchy.head_scale`): "addh" (head markers),
    #: "bbox" (a tenth of the body's bounding box) or "unit"
    addh_rule: str = ""
    #: how the coding hierarchy was made: one of :data:`mpz.hierarchy.METHODS`
    hierarchy: str = ""
    #: one :class:`NodeReport` a hierarchy node below the root, in HIER order: its markers,
    #: segments, patterns and bytes (the root marker's track, ROOT, has none)
    nodes: list[NodeReport] = field(default_factory=list)
    #: each chunk type's bytes in the file, its 12-byte frame included
    chunk_bytes: dict[str, int] = field(default_factory=dict)
    #: the encode's wall-clock time
    seconds: float = 0.0
    #: issue 12: the declared bound (None: lossy, 0.0: exact)
    bound: float | None = None
    #: how the bound was chosen, in words ("max error 1 (given)", "default ...")
    bound_rule: str = ""
    #: what of the source the file does not keep (:func:`not_kept`; empty: everything)
    not_kept: list[str] = field(default_factory=list)
    #: the summary chunk's partitions: 0 none, 1 exact, b > 1 cuts on blocks of b frames
    #: (a motion over :data:`mpz.fisher.EXACT_MAX_FRAMES` frames)
    summary_blocks: int = 0
    #: options given that did less than they seem in this encode, each in a sentence:
    #: those the motion and the options show (:func:`mpz.encoder.option_notes`), then
    #: those the encoded file shows (:func:`mpz.encoder.outcome_notes`); empty: none
    notes: list[str] = field(default_factory=list)

    @property
    def ratio(self) -> float:
        """Compression ratio: ``raw_bytes`` (the motion as float32 xyz,
        :meth:`Motion.raw_size`) over ``file_bytes``."""
        return self.raw_bytes / max(self.file_bytes, 1)


_T = TypeVar("_T")


#: the name prefix of the encoder's threads (``mpz-codec_0`` ...): what the commands wait
#: for after an interrupt (:func:`mpz.tools._cli.reports_ctrl_c`)
CODEC_THREADS = "mpz-codec"
#: how long an interrupted encode waits for its threads to finish their tasks; one still
#: running then is stuck (a lock the signal left held), and is left behind
INTERRUPT_WAIT_SECONDS = 3.0


class _Pool(ThreadPoolExecutor):
    """A ThreadPoolExecutor whose ``submit`` does not fail when the system cannot start one
    more thread while one of the pool's runs: the work waits for a running thread."""

    def _adjust_thread_count(self) -> None:
        try:
            super()._adjust_thread_count()
        except RuntimeError:                 # "can't start new thread"
            if not self._threads:
                raise


def start_pool(threads: int, first: Callable[..., _T], *args: Any
               ) -> tuple[ThreadPoolExecutor | None, Future[_T] | None]:
    """A pool of up to ``threads`` threads and its first task, ``first(*args)``, submitted;
    (None, None) for one thread, or when not even the pool's first thread can start: the
    encode then runs on the calling thread, with the same bytes. Under a memory limit each
    thread's stack counts, and a thread that could not start raised "can't start new
    thread" in the middle of the encode (a QA run: --threads 64 under ulimit -v); a later
    one that cannot start now leaves its work to the pool's running threads
    (:class:`_Pool`)."""
    if threads <= 1:
        return None, None
    pool = _Pool(threads, thread_name_prefix=CODEC_THREADS)
    try:
        return pool, pool.submit(first, *args)
    except RuntimeError:                       # the task waits in the queue: cancelled
        pool.shutdown(wait=True, cancel_futures=True)
        return None, None


#: :func:`not_kept`'s entry for a skeleton not written, which ``keep_skeleton=False``
#: (``--no-skeleton``) asks for: not a warning (:func:`unasked`)
SKELETON_NOT_KEPT = "joint angles and the skeleton"
#: how :func:`not_kept`'s entry for a C3D archive its reader could not keep begins: the
#: reader's own warning says it already (:func:`unasked`)
ARCHIVE_NOT_KEPT = "analog, parameters and residuals ("


def unasked(dropped: Iterable[str]) -> list[str]:
    """The entries of :func:`not_kept`'s ``dropped`` that no option asked for and no
    reader warning said: content of the source that the output will not give back, which
    the command line says as a warning (exit 1; an animation studio's QA run of stop 75:
    an AMC's comments among its frames, an ASF's unknown sections, were a note that ``-q``
    hid, exit 0). Readers give a skeleton with their joint angles, so
    :data:`SKELETON_NOT_KEPT` is asked for; a C3D archive not kept is its reader's
    warning (:data:`ARCHIVE_NOT_KEPT`: a corpus printed it twice, the review of stop 75)."""
    return [d for d in dropped if d != SKELETON_NOT_KEPT
            and not d.startswith(ARCHIVE_NOT_KEPT)]


def reader_not_kept(motion: Motion) -> list[str]:
    """What the reader of ``motion`` listed as not kept of its source
    (``motion.extras[READER_NOT_KEPT]``: an AMC's comments among its frames, an ASF's
    unknown keys, a BVH's keyword spelling); part of :func:`not_kept`."""
    return [str(s) for s in motion.extras.get(READER_NOT_KEPT, ())]


def not_kept(motion: Motion, opts: EncodeOptions) -> list[str]:
    """What of its source an encode of ``motion`` with ``opts`` does not keep, so that no
    report counts the whole source file against what was kept (issue 12): a C3D's analog
    data, parameters and residuals when its reader could not keep the C3D archive (with
    the reader's reason), and a skeletal motion's joint angles and skeleton when no
    skeleton chunk is written (``keep_skeleton=False``, or no skeleton was read), or its
    ``parents`` alone (a motion built with them and without angles), what the
    reader listed under ``motion.extras[READER_NOT_KEPT]``, and any other
    ``motion.extras`` key that no extension (:data:`mpz.extensions.EXTENSIONS`) writes."""
    from mpz.c3darchive import C3D_EXTENSION
    from mpz.extensions import EXTENSIONS
    from mpz.motion import cut_leaves
    listed = reader_not_kept(motion)
    out = []
    if (motion.metadata.get("format") == "c3d" and "c3d" not in motion.extras
            and cut_leaves(C3D_EXTENSION.held) not in listed):   # a cut names it itself
        why = motion.metadata.get("warning", "C3D archive not kept")
        out.append(f"{ARCHIVE_NOT_KEPT}{why})")
    if motion.angles is not None and (not opts.keep_skeleton
                                      or "skeleton" not in motion.extras):
        out.append(SKELETON_NOT_KEPT)
    elif motion.parents is not None and (not opts.keep_skeleton
                                         or "skeleton" not in motion.extras):
        # a motion built with parents and no skeleton decoded without them, and this list
        # said everything was kept (an ML pipeline's QA run of the API)
        out.append("the markers' parents (motion.parents; only a skeleton chunk keeps them)")
    # what the reader itself could not carry (an AMC's comments among its frames, an
    # ASF's unknown keys): listed by the reader of this read (a QA run of stop 61)
    out += listed
    # extras that no extension writes were dropped without a word (a QA run of stop 50)
    known = {ext.name for ext in EXTENSIONS}
    out += [f"motion.extras[{k!r}] (no extension of mpz.extensions writes it)"
            for k in motion.extras if k in held_extras(motion.extras) - known]
    return out


def option_notes(motion: Motion, opts: EncodeOptions, *, resolved: bool = False
                 ) -> list[str]:
    """The options given to encode ``motion`` that do less than they seem, each in a
    sentence: a group error not tighter than the bound the file declares (a node is coded
    within the smaller of the two), group errors where every sample is coded exactly on the
    source's int16 grid (:func:`exact_on_source_grid`), and ``angle_error``,
    ``translation_error`` or ``position_error`` where no skeleton chunk is written. They
    were accepted without a word from the API (a QA run of the API, stop 72; ``mpz
    encode`` noted the first alone, and only against a bound it was given).

    ``resolved``: ``opts`` is already what :func:`resolve_bound` made of them (the
    encoder's own call); otherwise it is resolved here, and raises as the encode would."""
    if not resolved:
        opts, _ = resolve_bound(motion, opts)
    notes = []
    # exact without them: a group error below the grid's own rounding makes the whole
    # file exact (plan_grid), which is no "bound nothing"
    if opts.group_errors and exact_on_source_grid(replace(opts, group_errors={})):
        notes.append(f"{spelled('--group-error', 'group_errors')} bound nothing: every "
                     f"position is coded exactly on the source's grid of step "
                     f"{opts.source_grid:g} (error 0)")
    elif opts.max_error is not None:
        # not "changes nothing": giving group errors selects the body-part hierarchy
        # (plan_hierarchy), which changes the bytes if not the error
        notes += [f"{spelled(f'--group-error {k}', f'group_errors[{k!r}]')}: {v:g} is not "
                  f"tighter than the bound {opts.max_error:g}, so it bounds that node no "
                  "more tightly (a node is coded within the smaller of the two)"
                  for k, v in opts.group_errors.items() if v >= opts.max_error]
    given = [(cli, api) for cli, api in (("--angle-error", "angle_error"),
                                         ("--translation-error", "translation_error"),
                                         ("position_error", "position_error"))
             if getattr(opts, api) is not None]
    if given and (not opts.keep_skeleton or "skeleton" not in motion.extras):
        names = " and ".join(spelled(cli, api) for cli, api in given)
        why = (spelled("--no-skeleton", "keep_skeleton=False") if "skeleton" in motion.extras
               else "the motion has no skeleton")
        notes.append(f"{names} change{'s' * (len(given) == 1)} nothing: no skeleton chunk "
                     f"is written ({why}), so no channel is coded")
    if opts.model_errors:
        # a kind the source holds no model output of was accepted without a word (an API
        # QA run of stop 74)
        from mpz.c3darchive import C3DArchive
        from mpz.format import ModelKind
        arc = motion.extras.get("c3d")
        held = ({ModelKind(k).name for k in arc.model_kinds}
                if isinstance(arc, C3DArchive) else set())
        for kind in opts.model_errors:
            if kind not in held:
                notes.append(f"{spelled(f'--model-error {kind}', f'model_errors[{kind!r}]')}"
                             f" changes nothing: the file keeps no {kind} model output")
    return notes


def outcome_notes(motion: Motion, opts: EncodeOptions, data: bytes, *,
                  resolved: bool = False) -> list[str]:
    """The options that the encoded file ``data`` shows did less than they seem, each in a
    sentence: a ``grid`` step the bound or the source's grid overruled (the file's QUNT
    step, spec §4.4), ``weights`` where no node kept a pattern layer (they act on it
    alone), and a ``model_errors`` fraction finer than some model-output axes could be
    held (their §4.13.3 ``bound``; ``model_error`` too where it is not the default).
    ``opts`` are those ``data`` was encoded with;
    ``resolved`` as for :func:`option_notes`.

    From the file alone, so that a corpus run says them of an output it keeps; they were
    said by ``mpz encode`` only, and neither :attr:`EncodeReport.notes` nor a corpus run
    had them (a docs QA run of stop 74). The file is parsed only when one of those
    options is given."""
    # smoothing too: it writes MHDR's half-width, so the bytes differ, but §6.4 smooths
    # pattern layers alone (under a bound, --smoothing 5 went unsaid: a QA run of stop 74)
    pattern_only = [n for n in (*PATTERN_OPTIONS, "smoothing")
                    if getattr(opts, n) != getattr(DEFAULTS, n)]
    if opts.grid is None and not opts.weights and not pattern_only and not opts.model_errors \
            and opts.model_error == DEFAULTS.model_error:
        return []
    if not resolved:
        opts, _ = resolve_bound(motion, opts)
    # the three record types read below alone, nothing kept per unknown chunk (a file the
    # encoder just wrote is valid: scan's errors cannot be met here)
    res = container.scan(data, keep_unknown=False, load=("QUNT", "PATT", "cpnt"))
    if res.errors:
        raise res.errors[0]
    records = [c.record for c in res.chunks if c.record is not None]
    notes = []
    units = f" {motion.units}" if motion.units else ""
    step = next(r.step for r in records if isinstance(r, Qunt))
    if opts.grid is not None and step != opts.grid:
        grid = source_grid_of(motion)
        ratio = None if not grid else step / grid
        # an int16 C3D is coded on its own grid: the note blamed the bound (0.2 mm asked,
        # 0.0833 mm, "the bound 0.5 mm needs a finer one": a QA run of stop 53)
        why = (f"the source's int16 grid, POINT:SCALE {grid:g}"
               if ratio is not None and abs(ratio - round(ratio)) < 1e-9 and ratio >= 1
               else f"the bound {opts.max_error:g}{units} needs a finer one"
               if step < opts.grid and opts.max_error is not None
               else "the source's own grid")
        # the flag in the file's units (--grid 0.5cm is --grid 5mm of a file in mm), and
        # the step to as many digits as tell it from the grid asked: "the grid step is 5
        # mm instead" of 5 mm, for 5.000000149 (a review of stop 74)
        asked = f"{opts.grid:.12g}"
        digits = next((d for d in (6, 9, 12, 17) if f"{step:.{d}g}" != asked), 17)
        flag = f"--grid {asked}{motion.units or ''}"
        notes.append(f"{spelled(flag, f'grid={asked}')}: "
                     f"the grid step is {step:.{digits}g}{units} instead ({why})")
    patterns = any(isinstance(r, Patt) and r.pattern_count > 0 for r in records)
    if opts.weights and not pattern_only and not patterns:
        notes.append(f"{spelled('--weight', 'weights')}: the weights act on the pattern "
                     "layer only (the paper's distortion control), and no node kept one "
                     "(under a bound, key frames or per-sample residuals won): they do not "
                     "change the decoded motion")
    elif pattern_only and not patterns:
        # theta, k0, tau, ... under a bound gave the default encode's bytes, unsaid, where
        # weights were noted (an API QA run of stop 74)
        names = ([spelled("--weight", "weights")] if opts.weights else []) \
            + [_flag(n) for n in pattern_only]
        notes.append(f"{', '.join(names)}: they act on the pattern layer only (the paper's "
                     "segmentation, clustering, distortion control and boundary smoothing), "
                     "and no node kept one (under a bound, key frames or per-sample "
                     "residuals won): they do not change the decoded motion")
    return notes + _model_bound_notes(motion, opts, records)


def _model_bound_notes(motion: Motion, opts: EncodeOptions, records: list[Record]
                       ) -> list[str]:
    """A note per model_errors kind whose bound some axes could not keep: finer than
    float32 values or 2^31 grid steps allow, they are coded at the finest bound that holds
    and declare it (spec §4.13.3, the axis's ``bound``), which went unsaid (a QA run:
    ANGLES=1e-10 declared 4.7e-10 of the range)."""
    from mpz.c3darchive import C3DArchive
    from mpz.chunks import Cpnt
    from mpz.format import ModelKind
    arc = motion.extras.get("c3d")
    cpnt = next((r for r in records if isinstance(r, Cpnt)), None)
    if not isinstance(arc, C3DArchive) or not arc.model_kinds or cpnt is None:
        return []
    coarser: dict[str, list[float]] = {}
    for j, model in enumerate(cpnt.models):
        name = ModelKind(arc.model_kinds[j]).name
        # the kind's own bound, else model_error where it was given: model_error=1e-12
        # alone gave the same file as {kind: 1e-12}, and no note (an API QA run, stop 74)
        rel = opts.model_errors.get(name, None if opts.model_error == DEFAULTS.model_error
                                    else opts.model_error)
        ok = arc.model_valid[:, j]
        if rel is None or not ok.any():
            continue
        for axis, ax in enumerate(model.axes):
            col = arc.models[ok, j, axis]
            span = float(np.max(col) - np.min(col))
            if span > 0 and ax.bound > rel * span * (1 + 1e-9):
                coarser.setdefault(name, []).append(ax.bound / span)
    return [(f"{spelled(f'--model-error {name}', f'model_errors[{name!r}]')}="
             f"{opts.model_errors[name]:g}" if name in opts.model_errors
             else f"model_error={opts.model_error:g} ({name})")
            + f": {len(fr)} axis(es) cannot be held that fine (float32 values, or 2^31 grid "
            f"steps) and declare the finest bound that holds, up to {max(fr):.2g} of their "
            "range"
            for name, fr in coarser.items()]


# ----------------------------------------------------------------- helpers --
def fill_gaps(x: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Linear interpolation over time of each marker's gaps (held at the ends).

    A marker that is a gap throughout copies the first marker that has data
    (so it costs almost nothing); if no marker has data, zeros.
    """
    x = x.copy()
    F, M, _ = x.shape
    t = np.arange(F)
    donor = None
    for m in range(M):
        v = valid[:, m]
        if v.all():
            donor = m if donor is None else donor
            continue
        if not v.any():
            continue
        for a in range(3):
            x[~v, m, a] = np.interp(t[~v], t[v], x[v, m, a])
        donor = m if donor is None else donor
    for m in range(M):
        if not valid[:, m].any():
            x[:, m] = x[:, donor] if donor is not None else 0.0
    return x


def _filled(x: FloatArray, valid: NDArray[np.bool_]) -> FloatArray:
    """:func:`fill_gaps`, except that a motion without gaps is returned as it is, not
    copied (issue 11.11: the encoder then holds no second copy of its input)."""
    return x if valid.all() else fill_gaps(x, valid)


#: issue 15: at most this many threads for one file (the option's range)
MAX_THREADS = 64
#: ... and by default the CPU count capped at this: the independent work within one file
#: (candidate layers, members) gains little beyond two threads, and whole-archive runs get
#: their parallelism from several files at once (each can ask for threads=1)
MAX_DEFAULT_THREADS = 2


#: ... and one thread by default below this many marker-frames, where a second thread
#: costs more than it saves: 8 % slower on the three real clips under 10^4 (6-9 thousand),
#: 8-47 % faster on the 18 of 10^4 to 5 x 10^4 (bench/bench_speed.py, stop 22)
MIN_THREADED_SAMPLES = 10_000


def thread_count(opts: EncodeOptions, samples: int | None = None) -> int:
    """The threads an encode with ``opts`` uses: ``opts.threads``, or else the CPU count
    capped at :data:`MAX_DEFAULT_THREADS`, and 1 for a motion of fewer than
    :data:`MIN_THREADED_SAMPLES` marker-frames (``samples``, when given)."""
    if opts.threads is not None:
        return int(opts.threads)
    if samples is not None and samples < MIN_THREADED_SAMPLES:
        return 1
    return max(1, min(MAX_DEFAULT_THREADS, os.cpu_count() or 1))


def _capacity(values: int) -> int:
    """A BlockEncoder capacity that holds a block of ``values`` without growing (its worst
    case is 8 bytes a value, plus the flush). The buffer is zero-filled memory that the
    system maps on first write, so only the bytes the coder writes become resident; a
    buffer that grows by doubling copies, and so touches, every byte it held (issue 11.11)."""
    return 8 * values + 256


def _round(a):
    return np.floor(np.asarray(a) + 0.5).astype(np.int64)


def _best_order(block: IntArray, period: int | None = None,
                orders: tuple[int, ...] = (0, 1, 2)) -> tuple[int, bytes] | None:
    """Code ``block`` with each predictor order; return (order, payload) of the smallest,
    or None when none fits. An order whose residuals pass the coder's range (§5.4) is not
    chosen (as in :func:`_coded`; a QA run, stop 37: the lossy root of values near 2^29
    grid steps)."""
    best: tuple[int, bytes] | None = None
    for order in orders:
        enc = BlockEncoder(capacity=_capacity(block.size))
        try:
            enc.block(residuals(block, order, period), period=period)
        except LimitExceededError:
            continue
        data = enc.finish()
        if best is None or len(data) < len(best[1]):
            best = (order, data)
    return best


#: target values made at a time where base 1's lattice is chosen from
#: :class:`keyframe.Members` (:func:`_lattice`): 2^18, 2 MiB of float64
LATTICE_VALUES = 1 << 18


def _lattice(y: FloatArray | keyframe.Members, radius: float, order: int,
             sample: AbsoluteSample | None = None) -> IntArray:
    """The residuals of order ``order`` of the lattice values chosen for targets ``y``
    (grid units) within ``radius`` (:func:`choose_lattice`), formed in place; the tracks
    of ``sample`` are its values, not chosen again.

    :class:`keyframe.Members` are chosen :data:`LATTICE_VALUES` targets at a time (one
    member at least): each track is chosen independently of the others, so the values
    are the same, and the targets of the whole node, a float64 copy of its members'
    coordinates, are never held beside the lattice (issue 11.11: a 183 KB BVH of 4096
    joints held two such copies of its 983 MB of positions, one on each thread)."""
    if not isinstance(y, keyframe.Members):
        known = None if sample is None else (sample.cols, sample.values[order])
        return residuals(choose_lattice(y, radius, order, known), order, inplace=True)
    w = np.empty((y.T, y.n, 3), np.int64)
    per = max(1, LATTICE_VALUES // max(1, 3 * y.T))
    for lo in range(0, y.n, per):
        hi = min(lo + per, y.n)
        part = None
        if sample is not None:
            inside = (sample.cols >= lo) & (sample.cols < hi)
            if inside.any():
                part = (sample.cols[inside] - lo, sample.values[order][:, inside])
        w[:, lo:hi] = choose_lattice(y.of(lo, hi), radius, order, part)
    return residuals(w, order, inplace=True)


def _coded(e: IntArray, limit: int | None) -> bytes | None:
    """The payload of residuals ``e``, or None when it is longer than ``limit`` bytes (the
    coder stops as soon as it is sure of that, issue 15.1; the flush can still add bytes
    past the limit, so the finished length is checked too), or when a residual is beyond
    the coder's range (§5.4: |e| < 2^30): order 2 of values that pass the grid's check
    (|u| < 2^29) can reach 2^31, and that order then cannot be chosen (a QA run, stop 37)."""
    enc = BlockEncoder(capacity=_capacity(e.size), limit=limit)
    try:
        enc.block(e)
    except LimitExceededError:
        return None
    if enc.over:
        return None
    data = enc.finish()
    return None if limit is not None and len(data) > limit else data


def _kept(e: IntArray, order: int, data: bytes) -> tuple[int, Int32Array, bytes]:
    """(order, values, payload) of a chosen order: its residuals ``e`` turned back into
    values in place, kept as int32 (|w| < 2^30; issue 11.11)."""
    return order, reconstruct(e, order, inplace=True).astype(np.int32), data


def _bounded(y: FloatArray | keyframe.Members, radius: float, orders: tuple[int, ...] = (1, 2),
             limit: int | None = None, sample: AbsoluteSample | None = None
             ) -> tuple[int, Int32Array, bytes] | None:
    """Best (order, values, payload) for targets ``y`` (grid units) within ``radius``.

    With ``limit`` (issue 15.1), an order whose payload is sure to be longer than ``limit``
    bytes stops being coded (and a later order longer than the best so far), and None is
    returned when no order fits in ``limit``: the caller's other candidate, of ``limit``
    bytes, wins against it anyway. The result is otherwise the same. None is also
    returned when every order's residuals pass the coder's range (see :func:`_coded`).

    ``sample``: :func:`sample_absolute`'s result for these targets, whose tracks are not
    chosen again.

    Memory (issue 11.11): the values of each order become their residuals in place and,
    for the best order, turn back and are kept as int32 (|w| < 2^30); so besides ``y`` at
    most one int64 and one int32 array of its size live (and of :class:`keyframe.Members`,
    only a few members' at a time).
    """
    best: tuple[int, Int32Array, bytes] | None = None
    for order in orders:
        e = _lattice(y, radius, order, sample)
        # a later order replaces the best only if strictly smaller
        data = _coded(e, limit if best is None else len(best[2]) - 1)
        if data is not None:
            best = None                          # let the previous best go first
            best = _kept(e, order, data)
        del e
    return best


#: when no candidate's residuals fit the coder; unreachable (the root's and base 1's order
#: 1 always fits: |u| < 2^29), kept as a clear refusal rather than an assertion
_BEYOND_RANGE = ("the residuals of every prediction order exceed the coder's range (spec §5.4: "
                 "|e| < 2^30); give a larger --max-error")


def _patterns_beyond_range(i: int, opts: EncodeOptions) -> EncoderError:
    """The refusal when node i's pattern layer cannot be coded and patterns are asked for
    ("on"; or lossy, where the pattern layer is all there is): near the grid's limit (|u|
    close to 2^29), pattern values relative to the parent's reference, and residuals
    against a pattern's prediction, can reach 2^30 (a QA run, stop 37: random-sign values
    from 0.9 x 2^29 steps). Under "auto" with a bound the node goes without patterns."""
    fix = ("give a coarser --grid" if opts.lossy else
           "patterns='auto' or 'off' code it without them")
    return EncoderError(f"node {i}: its values relative to its motion patterns exceed the "
                        f"coder's range (spec §5.4: |e| < 2^30), near the grid's limit of "
                        f"2^29 steps; {fix}")


def _weights_for(node: Node) -> FloatArray:
    w = np.asarray(node.weights, dtype=np.float64)
    return w if w.size else np.ones(len(node.members))


def _chain_sample(x: FloatArray, valid: NDArray[np.bool_]
                  ) -> tuple[FloatArray, NDArray[np.bool_]]:
    """The frames :func:`_chain` scores of every marker, every step-th frame with
    step = max(1, F div k), k = 400 up to 256 markers and fewer beyond
    (:func:`~mpz.hierarchy.measure.pair_frames`): finite coordinates ``[3, M, S]`` and
    their validity ``[M, S]``."""
    step = max(1, x.shape[0] // pair_frames(x.shape[1], 400))
    sub = np.nan_to_num(x[::step])
    return (np.ascontiguousarray(sub.transpose(2, 1, 0)),
            np.ascontiguousarray(valid[::step].T))


def chain_scores_of(x: FloatArray, valid: NDArray[np.bool_]) -> FloatArray | None:
    """:func:`keyframe.chain_scores` of every pair of markers, in marker order; None when
    :func:`_chain` needs none (fewer than 4 markers)."""
    if x.shape[1] < 4:
        return None
    return keyframe.chain_scores(*_chain_sample(x, valid))


def _chain(scores: FloatArray, root_marker: int, members: list[int]) -> list[int]:
    """Order ``members`` so that each follows the already ordered marker it moves most
    rigidly with (std over time of their distance), starting next to the root: every
    marker then has a good key-frame reference before it (spec §6.5, base 2). ``scores``:
    :func:`chain_scores_of` the whole motion. A pair's score is the same bits whichever
    marker comes first (the axis differences are squared), so the rows and columns of
    ``[root] + members`` are what scoring the markers in that order gives."""
    if len(members) < 3:
        return list(members)
    idx = [root_marker] + list(members)
    return [idx[j] for j in keyframe.chain_order(scores[np.ix_(idx, idx)])]


#: rows of a score matrix moved at a time by :func:`_to_front`
_FRONT_ROWS = 64


def _to_front(scores: FloatArray, r: int) -> None:
    """``scores[np.ix_(idx, idx)]`` for ``idx = [r, 0, .., r-1, r+1, ..]``, in place: row and
    column r first, the others after them in order, a few rows at a time (numpy copies
    overlapping operands whole first). The copy was M^2 x 8 bytes beside the scores,
    134 MB for 4096 markers (issue 11.11)."""
    M = scores.shape[0]
    row = scores[r].copy()
    for hi in range(r, 0, -_FRONT_ROWS):             # rows 0 .. r-1 down by one
        lo = max(0, hi - _FRONT_ROWS)
        scores[lo + 1: hi + 1] = scores[lo: hi]
    scores[0] = row
    for a in range(0, M, _FRONT_ROWS):                 # columns 0 .. r-1 right by one
        blk = scores[a: a + _FRONT_ROWS]
        col = blk[:, r].copy()
        blk[:, 1: r + 1] = blk[:, :r]
        blk[:, 0] = col


def _reroot(root_marker: int, M: int, scores: FloatArray | None = None) -> Hierarchy:
    """A flat hierarchy (root + one node) whose root is ``root_marker``; with ``scores``
    (:func:`chain_scores_of`, then reordered in place), its members in :func:`_chain`'s
    order."""
    rest = [m for m in range(M) if m != root_marker]
    if scores is not None and len(rest) >= 3:
        # _chain's order of [root] + rest without a reordered copy of the scores
        _to_front(scores, root_marker)
        idx = [root_marker] + rest
        rest = [idx[j] for j in keyframe.chain_order(scores)]
    nodes = [Node("root", -1, root_marker, [root_marker], [1.0])]
    if rest:
        nodes.append(Node("body", 0, rest[0], rest, [1.0] * len(rest)))
    return Hierarchy(nodes, "flat")


# -------------------------------------------------------- 0: the bound --
#: issue 12: with source_grid, each sample's lattice search radius in grid steps: no grid
#: point but the target's own lies within it (the next one is 1 step away)
EXACT_RADIUS = 0.875


def source_grid_of(motion: Motion) -> float | None:
    """The grid an int16 C3D source stored its points on (|POINT:SCALE|), if any."""
    a = motion.extras.get("c3d")
    grid = getattr(a, "point_grid", None)
    return grid() if callable(grid) else None


def on_grid(motion: Motion, step: float) -> bool:
    """True if every valid coordinate is exactly q x step, |q| < 2^29 (§5.4 margin)."""
    x = motion.positions[motion.valid]
    q = np.rint(x / step)
    return bool(np.array_equal(q * step, x) and np.abs(q).max(initial=0) < 2.0 ** (MAX_EXP - 1))


def default_error(motion: Motion, opts: EncodeOptions) -> tuple[float, str]:
    """The default bound in motion units, and what gave it: ``default_error_mm`` for known
    units, else ``default_error_fraction`` of the largest extent of the data, or
    ``default_error_mm`` units when the data has none (spec Appendix C); for a skeletal
    motion whose skeleton chunk is written, the marker layer's preview bound (issue 13,
    :func:`mpz.skeleton.preview_bound`)."""
    if opts.keep_skeleton:
        from mpz.skeleton import preview_bound
        preview = preview_bound(motion)
        if preview is not None:
            return preview, ("1/500 of the skeleton's size: a preview, the channels hold "
                             "the motion")
    mm = MM_PER_UNIT.get(motion.units)
    if mm is not None:
        return opts.default_error_mm / mm, f"{opts.default_error_mm:g} mm"
    x = motion.positions[motion.valid]
    extent = float((x.max(0) - x.min(0)).max()) if x.size else 0.0
    if extent > 0:
        return (opts.default_error_fraction * extent,
                f"{opts.default_error_fraction:g} of the largest extent")
    # a QA run (stop 49): this was said to be "0.0001 of the largest extent", which is 0
    return opts.default_error_mm, (f"{opts.default_error_mm:g} units: the motion has no "
                                   "extent and no unit")


def resolve_bound(motion: Motion, opts: EncodeOptions) -> tuple[EncodeOptions, str]:
    """Issue 12: the bound a file declares, and how it was chosen (for the report).

    ``lossy`` keeps the paper's mode (no bound); an explicit ``max_error`` or
    ``source_grid`` is kept; otherwise an int16 C3D source is coded exactly on its own grid,
    and any other motion within the default bound (:func:`default_error`).
    """
    if opts.group_errors and opts.keep_skeleton and "skeleton" in motion.extras:
        # they bound the marker layer, and a skeletal file's positions are its channels'
        # (spec §6.10, what mpz decode gives): a QA run found a 0.3 mm group at 1.1 mm
        raise EncoderError(
            "group error bounds hold on the marker layer, and a skeletal file's joint "
            "positions come from its channels, which they do not bound: bound the joints "
            "with max_error (--max-error), the channels with angle_error and "
            "translation_error, or drop the skeleton (keep_skeleton=False, --no-skeleton) "
            "to code markers that keep the group bounds")
    if opts.lossy:
        grid = source_grid_of(motion)
        if grid is not None and on_grid(motion, grid):
            opts = replace(opts, source_grid=grid)
        return opts, "lossy (no bound: the paper's mode, asked for by name)"
    if opts.source_grid is not None:
        if not on_grid(motion, opts.source_grid):
            raise EncoderError(f"source_grid {opts.source_grid!r}: the positions are not exact "
                               "multiples of it")
        if opts.max_error is not None:
            # coded within it on multiples of the grid, exactly only when it is below the
            # grid's diagonal (plan_grid): "error 0" said of 55 changed samples, a QA run
            return opts, (f"max error {opts.max_error:g} (given), on the grid of step "
                          f"{opts.source_grid:g}")
        return opts, f"exact on the grid of step {opts.source_grid:g} (error 0)"
    grid = source_grid_of(motion)
    if grid is not None and not on_grid(motion, grid):
        grid = None
    if opts.max_error is not None:
        if grid is not None:
            return (replace(opts, source_grid=grid),
                    f"max error {opts.max_error:g} (given), on the source's int16 grid")
        if opts.position_error is None and opts.keep_skeleton and "skeleton" in motion.extras:
            # a skeletal motion's positions are its channels' (the marker layer is their
            # preview, issue 13): a given bound bounds them too, as position_error
            return (replace(opts, position_error=opts.max_error),
                    f"max error {opts.max_error:g} (given), on the joint positions the "
                    "channels give too")
        return opts, f"max error {opts.max_error:g} (given)"
    if grid is not None:
        return (replace(opts, source_grid=grid),
                f"exact on the source's int16 grid (POINT:SCALE {grid:g}), error 0 (default)")
    e, how = default_error(motion, opts)
    return replace(opts, max_error=e), f"max error {e:g} ({how}, default)"


# ---------------------------------------------------------- 1-2: the plan --
def plan_hierarchy(motion: Motion, opts: EncodeOptions, pool: Executor | None = None
                   ) -> Hierarchy:
    """Stage 1: the coding hierarchy (paper §III-A). With a ``pool`` (issue 15.1), the flat
    hierarchy's member scores are computed on one of its threads while this one chooses
    the root: they do not depend on it (:func:`_chain`), so the result is the same."""
    if opts.pattern_mode == "off" and opts.hierarchy is None and not opts.group_errors:
        # without patterns the residual layers are absolute (base 1/2) and the tree carries
        # nothing; one node for all non-root markers lets the models adapt once (smaller)
        scoring = (pool.submit(chain_scores_of, motion.positions, motion.valid)
                   if pool is not None else None)
        root_marker = hierarchy_root(motion, None, weights=opts.weights)
        scores = (scoring.result() if scoring is not None
                  else chain_scores_of(motion.positions, motion.valid))
        hier = _reroot(root_marker, motion.n_markers, scores)
    else:
        hier = build_hierarchy(motion, opts.hierarchy, weights=opts.weights)
    hier.validate(motion.n_markers)
    return hier


class DecodedTracks:
    """What the decoder will rebuild, as far as the encoder needs it (issue 11.11): the
    decoded track of every marker that is a node's reference (the closed loop codes each
    node against its parent's) and the largest |q| (QUNT ``bits``), instead of all of q.

    ``tracks[:, ref]`` gives a reference marker's ``[F, 3]`` track, as q would.
    """

    def __init__(self, refs: set[int]) -> None:
        self.refs = refs
        self.tracks: dict[int, IntArray] = {}
        self.peak = 0

    def add(self, members: Sequence[int], decoded: IntArray) -> None:
        """The decoded values ``[F, n, 3]`` of ``members``."""
        for j, m in enumerate(members):
            if m in self.refs:
                self.tracks[m] = decoded[:, j].copy()
        if decoded.size:
            self.peak = max(self.peak, int(decoded.max()), -int(decoded.min()))

    def __getitem__(self, key: tuple[slice, int]) -> IntArray:
        rows, marker = key
        return self.tracks[marker][rows]


def _exact_pair(decoded: IntArray, motion: Motion, members: Sequence[int],
                grid: Grid) -> tuple[NDArray[Any], NDArray[Any]]:
    """(q x step, x) at the valid samples of ``members``: issue 12's exactness check of
    the whole of q, made node by node (issue 11.11)."""
    ok = motion.valid[:, list(members)]
    return (decoded * grid.step)[ok], motion.positions[:, list(members)][ok]


class GridCoordinates:
    """The motion in grid units, u = (x - offset) / step, formed for the markers asked for
    (``u[:, members]``) rather than held for all of them (issue 11.11). Each value takes
    the same two roundings as in the whole array, so the values are the same.
    """

    def __init__(self, x: FloatArray, offset: FloatArray, step: float) -> None:
        self.x, self.offset, self.step = x, offset, step

    def __getitem__(self, key: Any) -> FloatArray:
        x = self.x
        if (isinstance(key, tuple) and len(key) == 2 and key[0] == slice(None)
                and isinstance(key[1], list) and x.ndim == 3 and x.dtype == np.float64):
            # u[:, members] in one kernel pass from x's own layout (a C3D's positions are
            # marker-major) into a C-ordered array: numpy's fancy index gives one laid
            # out marker-major, which the kernels then copied again, and a copy, a
            # subtraction and a division took 0.9 ms of a short clip's encode, holding
            # the GIL for much of it (issue 15.1)
            out = np.empty((x.shape[0], len(key[1]), x.shape[2]), np.float64)
            grid_units(x, np.asarray(key[1], np.int64),
                       np.asarray(self.offset, np.float64), float(self.step), out)
            return out
        out = x[key]
        if np.may_share_memory(out, self.x):     # a view (basic indexing): a new array
            out = out - self.offset
        else:                                    # already a copy (fancy indexing)
            out -= self.offset
        out /= self.step
        return out

    def peak(self) -> float:
        """max |u| over every value, a block of frames at a time."""
        F, M = self.x.shape[0], self.x.shape[1]
        step = max(1, (1 << 20) // max(1, M))
        peak = 0.0
        for t0 in range(0, F, step):
            blk = self[t0: t0 + step]
            peak = max(peak, float(blk.max()), -float(blk.min()))
        return peak


@dataclass(frozen=True)
class Grid:
    """Stage 2: the quantisation grid (spec §4.4) and each node's error budget."""

    step: float
    offset: FloatArray                  # per axis, the middle of the data range
    scale: dict[int, int]               # node -> residual multiplier g (§6.5)
    bounds: dict[int, float]            # node -> max error in motion units (bounded mode)
    exact: bool = False                 # issue 12: every valid sample exact on the grid


def c3d_bound(motion: Motion, opts: EncodeOptions, peak: float) -> Callable[[float], float]:
    """The bound a node is coded within: the bound asked for, or for a motion whose C3D
    archive will be written back with float32 points (§6.9: any point storage but the
    source's int16 grid), :func:`float32_bound` of it (issue 15 QA: the written C3D broke
    a 0.1 mm bound by up to 1.2e-4 mm)."""
    if "c3d" not in motion.extras or opts.source_grid is not None:
        return lambda e: e

    def exact() -> bool:
        return binary32_values(motion.positions[motion.valid])
    return lambda e: float32_bound(e, peak, exact)


class _NodeNameError(EncoderError):
    """A ``group_errors`` key that names no node: not a bound the coordinates cannot
    allow, so :func:`encode_motion` does not add the default bound's advice (a QA run of
    the API, stop 54: it told a caller with a misspelled node to give a max_error)."""


def exact_on_source_grid(opts: EncodeOptions) -> bool:
    """Whether :func:`plan_grid` codes every valid sample exactly on ``opts.source_grid``
    (resolved options): without a bound, or with a bound (the smallest of ``max_error``
    and the group errors) too fine for the source grid's own rounding."""
    src = opts.source_grid
    if src is None or not opts.bounded:
        return False
    e_all = [opts.max_error, *opts.group_errors.values()] if opts.max_error is not None else []
    return not e_all or min(e_all) < float(src) * SQRT3 / SAFETY


def plan_grid(motion: Motion, opts: EncodeOptions, hier: Hierarchy, addh: float,
              x: FloatArray) -> Grid:
    """Stage 2: grid step, offset and per-node residual multipliers g (spec §4.4, §6.5)."""
    # per axis: no copy of x, whatever its layout (readers give marker-major arrays)
    lo = np.array([x[..., k].min() for k in range(3)])
    hi = np.array([x[..., k].max() for k in range(3)])
    offset = (lo + hi) / 2.0
    peak = float(max(np.abs(lo).max(), np.abs(hi).max()))
    within = c3d_bound(motion, opts, peak)
    # issue 12: with a source grid s (an int16 C3D's), the stored grid is s itself and the
    # offset 0, so every decoded value is q x s, the reader's own product, and the C3D can
    # be written back as int16 with its residual words and camera masks as they were
    src = None if opts.source_grid is None else float(opts.source_grid)
    if src is not None and exact_on_source_grid(opts):
        # exact: a radius of 0.875 grid steps (>= sqrt(3)/2, as the lattice search needs)
        # holds no grid point but the target's own, so valid samples are reproduced exactly
        n = len(hier.nodes)
        return Grid(src, np.zeros(3), {i: 1 for i in range(1, n)},
                    {i: EXACT_RADIUS * src for i in range(n)}, exact=True)
    if opts.max_error is None:
        step = opts.grid if opts.grid is not None else addh / 1000.0
        if src is not None:                       # lossy, on a multiple of the source grid
            return Grid(src * max(1, round(step / src)), np.zeros(3), {}, {})
        return Grid(step, offset, {}, {})
    names = {node.name: i for i, node in enumerate(hier.nodes)}
    group: dict[int, float] = {}
    for key, e in opts.group_errors.items():
        if key not in names:
            # the default's flat hierarchy (root, body) gives way to the body-part one
            # when group errors are given: its names are the ones that count
            raise _NodeNameError(f"group error given for unknown node {key!r}; the nodes "
                                 f"of the {hier.method} hierarchy (the one group errors "
                                 f"use) are {', '.join(names)}")
        group[names[key]] = within(min(e, opts.max_error))
    e_all_nodes = within(opts.max_error)
    e_min = min([e_all_nodes, *group.values()])
    # rounding each axis to a grid of step s errs by <= s/2 per axis, sqrt(3) s / 2 in 3-D;
    # the stored grid is KEY_REFINE times finer, so that key-frame interpolation rounds
    # finely (base 2); per-sample residuals (base 0, 1) use g = KEY_REFINE, the same lattice
    step = 2.0 * e_min / SQRT3 * SAFETY / KEY_REFINE
    if opts.grid is not None:
        step = min(step, opts.grid)
    if src is not None:                           # on the source grid (finer than step)
        step, offset = src, np.zeros(3)
    g = {}
    for i in range(1, len(hier.nodes)):
        e = group.get(i, e_all_nodes)
        g[i] = int(max(1, min(65535, math.floor(2.0 * e / SQRT3 * SAFETY / step))))
    # §6.8 rounds each decoded value twice in binary64 (q s, then + offset: per axis at
    # most 2^-53 (|q s| + |x|)), and the encoder's grid coordinates and distances are
    # binary64 too (2^-53 of the half range, twice, and of the radius): the nodes are coded
    # within the bound less 2^-51 (|x|max + 3 half range + 3 e), > sqrt(3) times all of it,
    # so that every decoded sample is within the bound itself, not only within §7.2's
    # float slack (a QA run: 1.005e-7 for a bound of 1e-7 at coordinates of 1e7). On the
    # real files the margin is below 10^-11 of the bound and changes no byte.
    margin = 2.0 ** -51 * (peak + 3.0 * float((hi - lo).max()) / 2.0 + 3.0 * e_min)
    if margin > e_min / 2:
        # the finest bound sets e_min: name it as it was given (max error or a node's)
        tight = [hier.nodes[i].name for i, e in group.items() if e == e_min]
        finest = (f"max error {opts.max_error:g}" if e_min == e_all_nodes else
                  "group error " + ", ".join(f"{n}={opts.group_errors[n]:g}" for n in tight))
        raise EncoderError(f"{finest} is too fine for coordinates of "
                           f"{peak:g} {motion.units or 'units'}: binary64 rounds them by up "
                           f"to {margin:g}")
    bounds = {i: group.get(i, e_all_nodes) - margin for i in range(len(hier.nodes))}
    for i in g:                 # a residual lattice still holds a point within its radius
        while g[i] > 1 and bounds[i] / (g[i] * step) < SQRT3 / 2:
            g[i] -= 1
    return Grid(step, offset, g, bounds)


# --------------------------------------------------------- 3: the root track --
def code_root(u_root: FloatArray, opts: EncodeOptions, grid: Grid) -> tuple[Root, IntArray]:
    """Stage 3: the root marker's track (spec §4.6); returns the record and the decoded
    integer track ``[F, 3]``."""
    if opts.bounded:
        best = _bounded(u_root[:, None, :], grid.bounds[0] / grid.step)
        if best is None:
            raise EncoderError(_BEYOND_RANGE)
        order, w, data = best
        return Root(order=order, coded=data), w[:, 0].astype(np.int64)
    q = _round(u_root)
    lossy = _best_order(q[:, None, :])
    if lossy is None:
        raise EncoderError(_BEYOND_RANGE)
    return Root(order=lossy[0], coded=lossy[1]), q


# ------------------------------------------------------------ 4: one node --
@dataclass(frozen=True)
class PatternLayer:
    """The paper's layer for one node: K patterns of L frames and the segments using them."""

    K: int
    L: int
    scale: int                          # pattern grid multiplier (§4.7)
    order: int                          # predictor order within each pattern
    coded: bytes                        # PATT payload data
    segments: int                       # S
    segments_coded: bytes               # SEGS payload data
    prediction: IntArray                # P, what the decoder rebuilds, [F, n, 3]

    @property
    def cost(self) -> int:
        return len(self.coded) + len(self.segments_coded)

    def records(self, node: int) -> list[Record]:
        return [Patt(node=node, pattern_count=self.K, length=self.L, scale=self.scale,
                     order=self.order, coded=self.coded),
                Segs(node=node, segment_count=self.segments, coded=self.segments_coded)]


@dataclass(frozen=True)
class ResidualLayer:
    """One candidate residual layer of a node (spec §4.9): what it adds and what it costs."""

    base: ResidualBase
    order: int
    scale: int                          # g
    values: Int32Array                  # w, before multiplying by g (int32: issue 11.11)
    coded: bytes

    def record(self, node: int) -> Resi:
        return Resi(node=node, base=int(self.base), order=self.order, scale=self.scale,
                    coded=self.coded)


def _segments(x: FloatArray, w: FloatArray, threshold: float, n: int,
              opts: EncodeOptions) -> tuple[IntArray, IntArray]:
    """Segment starts and frame counts: Alg. 1, or the Fisher optimal partition."""
    if opts.segmentation == "optimal":
        from mpz.fisher import block_length, block_means, threshold_partition
        F = x.shape[0]
        flat = x.reshape(F, -1)
        b = block_length(F)         # past 16,384 frames, on the means of blocks of b frames
        if b > 1:                   # (Appendix C item 6: the programme is quadratic in F)
            flat = block_means(flat, b)
        # the Fisher deviation is the norm over all n members; Alg. 1's is a mean
        # marker distance, so scale by sqrt(n) to make theta mean the same thing
        thr = threshold * math.sqrt(n)
        k_max = max(1, min(flat.shape[0], F // 4 + 1, 512))
        # the smallest k within thr, else the finest (k_max), from one run of the programme
        part = threshold_partition(flat, thr, k_max)
        starts = np.asarray(part.starts, dtype=np.int64) * b
        counts = np.diff(np.append(starts, F))
        return starts, counts
    return segment(x, w, threshold, max_len=opts.max_segment)


def code_patterns(x: FloatArray, w: FloatArray, opts: EncodeOptions, addh_q: float,
                  seed: int) -> PatternLayer | None:
    """The pattern layer of ``x[F, n, 3]`` (grid units, relative to the parent's reference),
    or None when its pattern values pass the coder's range (:func:`_patterns_beyond_range`).

    The node's mean weight divides its thresholds (paper §IV: a heavier marker group is
    segmented and clustered more finely); the relative weights of its members shape the
    distances.
    """
    F, n, _ = x.shape
    boost = max(float(np.mean(w)), 1e-6)
    starts, counts = _segments(x, w, opts.theta * addh_q / boost, n, opts)
    L = int(max(1, min(MAX_PATTERN_LENGTH, round(float(counts.mean())))))
    segs = normalize(x, starts, counts, L)                       # [S, L, n, 3]
    S = segs.shape[0]
    sw = np.sqrt(w / w.mean())[None, None, :, None]
    vec = (segs * sw).reshape(S, -1)
    labels, _ = adaptive_kmeans(vec, opts.k0, opts.tau * addh_q / boost,
                                metric=opts.metric, per_sample=L * n, seed=seed)
    # only the clusters that kept a segment become patterns (an empty one has no mean: a
    # QA run, stop 37, met one and coded its NaN centre as -2^63)
    labels = np.unique(labels, return_inverse=True)[1].reshape(-1)
    K = int(labels.max()) + 1
    # relabel by frequency so the most used pattern gets index 0
    order = np.argsort(-np.bincount(labels, minlength=K), kind="stable")
    remap = np.empty(K, np.int64)
    remap[order] = np.arange(K)
    labels = remap[labels]
    centers = np.zeros((K, L, n, 3))
    np.add.at(centers, labels, segs)
    centers /= np.bincount(labels, minlength=K)[:, None, None, None]
    # pattern grid: a fraction of the clustering threshold (paper: 8-bit deltas)
    scale = int(max(1, min(65535, math.floor(opts.tau * addh_q / boost / 3))))
    v = _round(centers / scale)
    coded = _best_order(v.reshape(K * L, n, 3), period=L, orders=(1, 2))
    if coded is None:
        return None
    porder, pdata = coded
    enc = BlockEncoder()
    enc.block(np.stack([labels, counts - L], axis=1)[:, None, :])
    sdata = enc.finish()
    p = _prediction(v * scale, labels, counts, opts.smoothing, F)
    return PatternLayer(K, L, scale, porder, pdata, S, sdata, p)


def _prediction(patterns: IntArray, labels: IntArray, counts: IntArray, h: int,
                F: int) -> IntArray:
    """The decoder's pattern layer P' (§6.3, §6.4), built a block of frames at a time as the
    decoder builds it, so that only the result is of the node's size (issue 11.11)."""
    n = patterns.shape[2]
    starts = segment_starts(counts)
    p = np.empty((F, n, 3), np.int64)
    step = max(1, (1 << 18) // max(1, n))
    for t0 in range(0, F, step):
        t1 = min(F, t0 + step)
        lo, hi = window(F, h, (t0, t1))
        raw = denormalize(patterns, labels, counts, frames=(lo, hi), starts=starts)
        p[t0:t1] = smooth_frames(raw, lo, starts, h, F, (t0, t1))
    return p


#: base 1 is not tried when, on every ABSOLUTE_SAMPLE-th member of a node, it codes
#: longer than ABSOLUTE_LOSES times the key frames (spec Appendix C item 6). On the 87
#: real encodes (29 files x the default bound, 1 mm, 5 mm) the sample's ratio is 0.88-1.22
#: times the whole node's, and base 1 is longer than the key frames wherever the sample
#: says 1.3 (the node's own ratio is 1.17 or more there)
ABSOLUTE_SAMPLE = 4
ABSOLUTE_LOSES = 1.3
#: the sample is taken only when a node has at least this many member-frames per key
#: (at most a third of them are keys): denser key frames lose to base 1 or win by less
#: than the margin (on the real encodes the ratio is 0.82-1.18 there), and the sample's
#: coding would be spent for nothing
ABSOLUTE_FRAMES_PER_KEY = 3
#: and only when the sample holds at least 2 members and 1,000 member-frames: a smaller
#: one misjudges by the coder's learning (its models start empty) and by one member's
#: motion; on 2,000 synthetic motions 21 files came out up to 7.3 % larger without these
#: limits, and 4 of 6,000 (1.2-6.6 %) with them (bench/bench_sample.py, docs/speed.md,
#: stop 39). Every real node passes them.
ABSOLUTE_MIN_MEMBERS = 2
ABSOLUTE_MIN_SAMPLES = 1000


def worth_sampling(fitted: keyframe.Fitted) -> bool:
    """Whether :func:`sample_absolute` may leave base 1 untried: the node has at least
    :data:`ABSOLUTE_FRAMES_PER_KEY` member-frames per key (in integers: keys x 3 <= F n,
    exactly), and the sample holds at least :data:`ABSOLUTE_MIN_MEMBERS` members and
    :data:`ABSOLUTE_MIN_SAMPLES` member-frames."""
    T, n = fitted.out.shape[0], len(fitted.times)
    size = -(-n // ABSOLUTE_SAMPLE)                  # the sample's members: ceil(n / 4)
    return (size >= ABSOLUTE_MIN_MEMBERS and size * T >= ABSOLUTE_MIN_SAMPLES
            and sum(len(t) for t in fitted.times) * ABSOLUTE_FRAMES_PER_KEY <= T * n)


@dataclass
class AbsoluteSample:
    """Base 1 on a sample of a node's members (:func:`sample_absolute`)."""

    cols: IntArray                      # the sampled members, in member order
    values: dict[int, IntArray]         # order -> their lattice values [T, len(cols), 3]
    loses: bool                         # longer than ABSOLUTE_LOSES x the key frames


def sample_absolute(fitted: keyframe.Fitted, targets: Callable[..., FloatArray],
                    radius: float) -> AbsoluteSample:
    """Whether base 1 (absolute values, orders 1 and 2) is sure enough to code longer than
    the key frames ``fitted`` to be left untried, judged on every
    :data:`ABSOLUTE_SAMPLE`-th member in order of key count (from the stillest to the
    most moving, so that the sample mixes them as the node does): both orders' payloads
    of the sample against :data:`ABSOLUTE_LOSES` times the sample's key frames (each
    coded as the whole node would be, its key residuals predicted as they are there).

    ``targets(cols)`` gives base 1's targets of those members. The sample's lattice values
    are kept: the whole node's choice (:func:`_bounded`) reuses them, so a node whose base
    1 is tried pays only the sample's coding for the test (issue 15.1).
    """
    T = fitted.out.shape[0]
    keys = [len(t) for t in fitted.times]
    by_keys = sorted(range(len(keys)), key=lambda m: (keys[m], m))
    cols = np.array(sorted(by_keys[::ABSOLUTE_SAMPLE]), np.int64)
    kdata = _keyframes_coded(fitted.part(cols), T, len(cols))
    y = targets(cols)
    values = {order: choose_lattice(y, radius, order) for order in (2, 1)}
    del y
    # longer than the limit, or beyond the coder's range (then so is the whole node's);
    # order 2 first: where base 1 is tried, it is the smaller on most real captures, and
    # one order within the limit settles it
    loses = kdata is not None and all(
        _coded(residuals(w, order), math.floor(ABSOLUTE_LOSES * len(kdata))) is None
        for order, w in values.items())
    return AbsoluteSample(cols, values, loses)


def residual_candidates(i: int, xl: FloatArray | None, u_members: Callable[..., FloatArray],
                        pat: PatternLayer | None, opts: EncodeOptions,
                        grid: Grid, pool: Executor | None = None,
                        stage: Progress | None = None, *, shape: tuple[int, int]
                        ) -> list[tuple[int, ResidualLayer]]:
    """(cost, layer) of every residual layer that keeps node i within its bound (beyond
    the paper): on the pattern layer (base 0), absolute per sample (base 1), key frames
    (base 2).

    ``u_members()`` gives a new copy of the members' grid coordinates each time it is
    called, ``u_members(cols)`` of the members at those positions: each candidate divides
    its own copy in place (issue 11.11); ``shape``: (frames, members).

    The key frames are made first. Where they are sparse (:func:`worth_sampling`), base 1
    is then tried on a sample of the members (:func:`sample_absolute`): when it codes well
    beyond the key frames there, base 1 is not tried on the node (spec Appendix C item
    6). Otherwise it stops coding an order as
    soon as it is sure to be longer than the key frames: it would lose then (the key
    frames come after it in the list, so it wins only ties). Both save most of the
    encoder's work at 1 mm (issue 15.1). With a ``pool`` (issue 15), the key-frame
    members are fitted on its threads; then, while this thread codes the key frames, a
    pool thread takes the sample, or, without one, chooses order 1's values; if base 1
    is tried, a pool thread codes order 1 and order 2's values are chosen by whichever
    thread is free first (the comment in the code). The smaller wins, order 1 on a tie,
    which is what :func:`_bounded` picks from the two in turn. That holds both orders'
    arrays at once, where the sequential path keeps one (issue 11.11).

    ``stage(fraction, message)``, when given, is told on this thread as each task of the
    key frames' fit ends (:func:`keyframe.fit_members`' progress, up to :data:`FITTED` of
    the node) and as their coding ends (:data:`KEYS_CODED`).
    """
    g = grid.scale.get(i, 1)
    radius = grid.bounds[i] / (g * grid.step)
    out = []
    if pat is not None:
        assert xl is not None
        y = xl - pat.prediction
        y /= g
        parent = _bounded(y, radius)
        del y
        if parent is not None:
            order, wv, data = parent
            del parent
            out.append((pat.cost + len(data),
                        ResidualLayer(ResidualBase.PARENT, order, g, wv, data)))
        elif opts.pattern_mode == "on":
            raise _patterns_beyond_range(i, opts)
    if opts.pattern_mode != "on":
        gk = max(1, g // KEY_REFINE)
        T, n = shape

        def scaled(by: int) -> Callable[[int, int], FloatArray]:
            def of(lo: int, hi: int) -> FloatArray:             # members lo .. hi-1, a copy
                y = u_members(np.arange(lo, hi))
                y /= by
                return y
            return of
        # the key frames' targets, and base 1's, made a few members at a time (issue 11.11)
        fitted = keyframe.fit_members(
            keyframe.Members(scaled(gk), T, n), grid.bounds[i] / (gk * grid.step),
            pool=pool,
            progress=None if stage is None else lambda f, what: stage(FITTED * f, what))
        if stage is not None:
            stage(FITTED, "coding keys")

        def targets(cols: IntArray | None = None) -> FloatArray:    # base 1's, a copy
            y = u_members(cols)
            y /= g
            return y
        whole = keyframe.Members(scaled(g), T, n)
        absolute: tuple[int, Int32Array, bytes] | None = None
        sample: AbsoluteSample | None = None
        if pool is not None:
            # Both cores stay busy until the end. Without a sample, a pool thread chooses
            # the lattice of order 1 while this one codes the key frames (their length is
            # the limit of both orders); with one, a pool thread takes the sample
            # meanwhile, and the lattices start once it is known. The lattice of order 2
            # is made by whichever thread is free first, and this thread codes it. The
            # smaller wins, order 1 on a tie: _bounded's choice.
            klen: Future[int | None] = Future()
            second: Future[IntArray] = Future()
            claim = threading.Lock()            # held by the thread that makes order 2's

            def make_second() -> None:
                if not claim.acquire(blocking=False):
                    return                      # the other thread has it
                try:
                    second.set_result(_lattice(whole, radius, 2, sample))
                except BaseException as exc:
                    second.set_exception(exc)
                    raise

            def first() -> tuple[IntArray, bytes | None]:
                e1 = _lattice(whole, radius, 1, sample)
                make_second()
                return e1, _coded(e1, klen.result())
            sampling = (pool.submit(sample_absolute, fitted, targets, radius)
                        if worth_sampling(fitted) else None)
            job = pool.submit(first) if sampling is None else None
            try:
                kdata = _keyframes_coded(fitted, T, n)
            except BaseException as exc:
                klen.set_exception(exc)
                raise
            klen.set_result(None if kdata is None else len(kdata))
            if stage is not None:
                stage(KEYS_CODED, "residuals")
            sample = None if sampling is None else sampling.result()
            # the key lists are coded: the decoded tracks alone are kept, and the key lists
            # (32 bytes a key) are let go before base 1's lattices (issue 11.11)
            wk = fitted.out
            del fitted
            if kdata is None or sample is None or not sample.loses:
                if job is None:
                    job = pool.submit(first)
                make_second()
                e2 = second.result()
                data2 = _coded(e2, None if kdata is None else len(kdata))
                e1, data1 = job.result()
                del job
                if data1 is not None and (data2 is None or len(data1) <= len(data2)):
                    del e2
                    absolute = _kept(e1, 1, data1)
                    del e1
                else:
                    del e1
                    absolute = None if data2 is None else _kept(e2, 2, data2)
                    del e2
            del sample
        else:
            kdata = _keyframes_coded(fitted, T, n)
            if stage is not None:
                stage(KEYS_CODED, "residuals")
            sample = sample_absolute(fitted, targets, radius) if worth_sampling(fitted) else None
            wk = fitted.out
            del fitted
            if kdata is None or sample is None or not sample.loses:
                absolute = _bounded(whole, radius, (1, 2),
                                    None if kdata is None else len(kdata), sample)
        if absolute is None and kdata is None:
            raise EncoderError(_BEYOND_RANGE)
        if absolute is not None:
            order, wv, data = absolute
            del absolute
            out.append((len(data), ResidualLayer(ResidualBase.ABSOLUTE, order, g, wv, data)))
        if kdata is not None:
            out.append((len(kdata), ResidualLayer(ResidualBase.KEYFRAMES, 0, gk, wk, kdata)))
    return out


def _keyframes_coded(fitted: keyframe.Fitted, T: int, n: int) -> bytes | None:
    """The key-frame layer's payload of ``n`` members over ``T`` frames, or None when a key
    residual is beyond the coder's range (§5.4: |e| < 2^30; keys near |u| = 2^29 predicted
    from a member on the other side can be): that base then cannot be chosen, and base 1's
    order 1 (|e| <= 2 |u| + 1 < 2^30) always can (a QA run, stop 37)."""
    # 3 values a key and a span between two, plus a source and a count a member: at most
    # T keys a member (the buffer is resident only as written, but counted whole by
    # tracemalloc and an address-space limit, so sized by the keys when they are known)
    keys = T * n if fitted.rows is None else len(fitted.rows[0])
    enc = BlockEncoder(capacity=_capacity(4 * keys + 2 * n))
    try:
        keyframe.write_blocks(enc, fitted, T)
    except LimitExceededError:
        return None
    return enc.finish()


@dataclass(frozen=True)
class NodeCode:
    """Stage 4's result for one node: its records and its decoded grid values."""

    records: list[Record]
    decoded: IntArray                   # q of the members, [F, n, 3]
    report: NodeReport


#: the ``decoded`` of a NodeCode once qhat holds its values
_SPENT: IntArray = np.zeros((0, 0, 3), np.int64)


def code_node(i: int, node: Node, ref: int, u: GridCoordinates, qhat: DecodedTracks,
              opts: EncodeOptions, grid: Grid, addh_q: float,
              pool: Executor | None = None, stage: Progress | None = None) -> NodeCode:
    """Stage 4: node i, coded against the *decoded* track of ``ref``, the reference marker of
    its parent (closed loop); ``pool``: threads for its independent work (issue 15);
    ``stage(fraction of the node, message)``: told as its stages end
    (:func:`residual_candidates`)."""
    members = list(node.members)
    rep = NodeReport(node.name, len(members))
    pat = None
    xl = None
    ref_q = None                        # read only with patterns (see encode_motion)
    if opts.pattern_mode != "off":
        ref_q = qhat[:, ref][:, None, :]
        xl = u[:, members]
        xl -= ref_q
        pat = code_patterns(xl, _weights_for(node), opts, addh_q, opts.seed + i)
        if pat is None:
            if opts.pattern_mode == "on" or not opts.bounded:   # lossy: nothing else codes it
                raise _patterns_beyond_range(i, opts)
            xl = ref_q = None                   # "auto": the node goes without them
    records: list[Record] = []
    # the decoded values, formed in place on the chosen layer's own arrays (exact integers,
    # so the order of the sums does not matter): issue 11.11
    if opts.bounded:
        # the cheapest candidate; on a tie the first (min keeps the first minimum)
        def u_members(cols: IntArray | None = None) -> FloatArray:    # a new copy each time
            return u[:, members if cols is None else [members[int(c)] for c in cols]]
        _, layer = min(residual_candidates(i, xl, u_members, pat, opts, grid, pool, stage,
                                           shape=(u.x.shape[0], len(members))),
                       key=lambda c: c[0])
        del xl
        local = layer.values.astype(np.int64)
        local *= layer.scale
        if layer.base == ResidualBase.PARENT:
            assert pat is not None and ref_q is not None
            local += pat.prediction
            local += ref_q                  # P' + g w + q[ref]
        else:
            pat = None                      # g w: the members' grid values themselves
        rep.residual_bytes, rep.residual_scale = len(layer.coded), layer.scale
        rep.residual_order = layer.order
    else:
        assert pat is not None and ref_q is not None    # validate(): lossy mode has patterns
        del xl
        local = pat.prediction
        local += ref_q                      # P' + q[ref]
    if pat is not None:
        records += pat.records(i)
        rep.segments, rep.patterns, rep.pattern_length = pat.segments, pat.K, pat.L
        rep.pattern_bytes, rep.segment_bytes = len(pat.coded), len(pat.segments_coded)
        rep.used_patterns = True
    # with a residual layer and no patterns, PATT is left out (spec §3.4)
    if opts.bounded:
        records.append(layer.record(i))
    return NodeCode(records, local, rep)


# ------------------------------------------------------ 5: the file records --
def summary_record(motion: Motion, ks: tuple[int, ...] | list[int], space: str,
                   step: float, fmt: str = "smry") -> Smry | Smrc:
    """The ancillary summary chunk from the optimal partition: smry (spec §4.10, raw s32
    means) or, with ``fmt="smrc"``, smrc (§4.15, MPZ 1.1: the same levels, range-coded).
    Over :data:`mpz.fisher.EXACT_MAX_FRAMES` frames the cuts fall on blocks of frames
    (:func:`mpz.fisher.summary_partitions`, spec Appendix C item 8)."""
    from mpz.fisher import motion_series, summary_partitions
    series, _ = motion_series(motion, space=space)
    levels_k = sorted({int(k) for k in ks})
    if not levels_k or levels_k[0] < 1:
        raise EncoderError(f"summary levels must be positive integers, got {levels_k}")
    if len(levels_k) > MAX_SUMMARY_LEVELS:
        raise EncoderError(f"at most {MAX_SUMMARY_LEVELS} summary levels")
    F = series.shape[0]
    _, parts = summary_partitions(series, levels_k)
    levels = []
    coded: list[tuple[NDArray[np.int64], NDArray[np.int64]]] = []
    for k in sorted(parts):
        p = parts[k]
        means_q = _round(np.asarray(p.means) / step)
        if np.abs(means_q).max(initial=0) >= MEAN_LIMIT:   # §4.10, §4.15 step 5
            raise EncoderError("summary means do not fit 32 bits at this step")
        levels.append(SummaryLevel(k=int(p.k), wssse=float(p.wssse), step=float(step),
                                   starts=np.asarray(p.starts, "<u4").tobytes(),
                                   means=means_q.astype("<i4").tobytes()))
        coded.append((np.asarray(p.starts, np.int64),
                      np.asarray(means_q, np.int64).reshape(int(p.k), series.shape[1])))
    space_code = SummarySpace.POSITIONS if space == "positions" else SummarySpace.ANGLES
    if fmt == "smrc":      # §4.15: levels by increasing k, each predicted from the next
        return Smrc(space=int(space_code), dims=int(series.shape[1]), level_count=len(levels),
                    levels=tuple(CodedSummaryLevel(k=lv.k, wssse=lv.wssse, step=lv.step)
                                 for lv in levels),
                    coded=encode_summary_levels(int(space_code), F, coded))
    return Smry(space=int(space_code), dims=int(series.shape[1]), level_count=len(levels),
                levels=tuple(levels))


def _meta_record(motion: Motion, opts: EncodeOptions) -> Meta | None:
    """§4.11 metadata: the motion's, then the options' (limits are in UTF-8 bytes)."""
    meta = dict(motion.metadata)
    meta.update(opts.metadata)
    if not meta:
        return None

    entries = [MetaEntry(key=k, value=v) for k, v in meta.items()]     # check_metadata
    return Meta(count=len(entries), entries=tuple(entries))


def ancillary_records(motion: Motion, opts: EncodeOptions) -> list[Record]:
    """What the source holds besides markers (the extensions' chunks): they depend only on
    the motion and the options, so an encode with threads makes them meanwhile."""
    out: list[Record] = []
    for ext in EXTENSIONS:
        out += ext.records(motion, opts)
    return out


def file_records(motion: Motion, opts: EncodeOptions, hier: Hierarchy, grid: Grid,
                 root: Root, nodes: list[NodeCode], bits: int,
                 ancillary: list[Record] | None = None) -> list[Record]:
    """Stage 5: every chunk of the file, in the §3.4 order; ``ancillary``:
    :func:`ancillary_records`' result, if already made."""
    F, M = motion.n_frames, motion.n_markers       # names: checked by check_motion (§4.2)
    records: list[Record] = [
        Mhdr(version_major=VERSION_MAJOR, version_minor=0,
             flags=FLAG_RESIDUAL if opts.bounded else 0, frame_count=F, marker_count=M,
             node_count=len(hier.nodes), rate=motion.rate, units=int(unit_code(motion.units)),
             error_metric=int(ErrorMetric.MAX_EUCLIDEAN if opts.bounded else ErrorMetric.NONE),
             error_bound=float(opts.max_error) if opts.max_error is not None else 0.0,
             smoothing=opts.smoothing),
        Mnam(count=M, names=tuple(motion.names)),
        Hier(count=len(hier.nodes), nodes=tuple(
            HierNode(parent=ROOT_PARENT if nd.parent < 0 else nd.parent, ref=nd.ref,
                     member_count=len(nd.members), members=tuple(nd.members),
                     weights=tuple(float(v) for v in nd.weights)) for nd in hier.nodes)),
        Qunt(step=grid.step, offset=(float(grid.offset[0]), float(grid.offset[1]),
                                     float(grid.offset[2])), bits=bits),
    ]
    if not motion.valid.all():
        enc = BlockEncoder(capacity=_capacity(motion.valid.size))
        enc.block((~motion.valid).astype(np.int64)[:, :, None], signed=False)
        records.append(Mask(coded=enc.finish()))
    records.append(root)
    for n in nodes:
        records += n.records
    if opts.summary:
        sstep = grid.step if opts.summary_space == "positions" else 1e-3   # angles: 0.001 deg
        bound = opts.max_error if opts.bounded else None
        if (opts.summary_format == "smrc" and opts.summary_space == "positions"
                and bound is not None and math.isfinite(bound) and bound > 0):
            # §4.15, Appendix C: step = the declared bound E, so each mean is within E/2; the
            # decoded motion is itself only within E, and a step of E costs 15 % less than
            # the grid step E/sqrt(3) (docs/summary-size.md)
            sstep = float(bound)
        records.append(summary_record(motion, opts.summary, opts.summary_space, sstep,
                                      opts.summary_format))
    meta = _meta_record(motion, opts)
    if meta is not None:
        records.append(meta)
    records += ancillary_records(motion, opts) if ancillary is None else ancillary
    records.append(Mend())
    # §2.1: the lowest minor version that describes the file: the newest chunk type in it
    minor = max(r.MINOR for r in records)
    head = records[0]
    if minor and isinstance(head, Mhdr):
        records[0] = replace(head, version_minor=minor)
    return records


# ------------------------------------------------------------------ encode --
def encode_motion(motion: Motion, opts: EncodeOptions | None = None, *,
                  progress: Progress | None = None) -> tuple[bytes, EncodeReport]:
    """Encode ``motion``; returns ``(bytes, EncodeReport)``.

    Parameters
    ----------
    motion : Motion
    opts : EncodeOptions
    progress : callable(fraction, message), optional
        Called on this thread as each node starts (the first at :data:`PLANNED`, once the
        hierarchy and the grid are planned) and ends, and within a node as each task of
        its key frames' fit ends (the members in tasks of about
        :data:`keyframe.TASK_FRAMES` frames, so one member a task on a long capture) and as
        their coding ends; the fraction never decreases and ends at 1.0, and each
        node's share of the rest is its share of the coded markers. A hierarchy of the
        root alone (one marker) gets one call, at 1.0, once it is coded.

    Raises
    ------
    EncoderError
        For options that cannot be honoured.
    """
    t0 = time.perf_counter()
    opts = opts if opts is not None else DEFAULTS
    if not isinstance(opts, EncodeOptions):
        raise EncoderError(f"expected EncodeOptions, got {type(opts).__name__}")
    opts.validate()
    if not isinstance(motion, Motion):
        raise EncoderError(f"expected an mpz.Motion, got {type(motion).__name__}")
    _consistent(motion)                  # a Motion is mutable: its invariants, again
    # the §8 size first: 32800 points with 255 labels were refused for the 575 KB list of
    # the names made for the others (metadata 'renamed_points'), not for being 32800 (a C3D
    # QA run)
    F, M = motion.n_frames, motion.n_markers
    if F > MAX_FRAMES or M > MAX_MARKERS or F * M > MAX_SAMPLES:
        raise EncoderError(f"{F} frames x {M} markers exceeds the limits of spec §8: at "
                           f"most {MAX_FRAMES} frames, {MAX_MARKERS} markers and "
                           f"{MAX_SAMPLES} frames x markers")
    check_motion(motion)                 # issue 11.6: names, metadata, magnitudes up front
    check_metadata({**motion.metadata, **opts.metadata})
    for ext in EXTENSIONS:              # the ancillary chunks' limits, up front too
        ext.check(motion, opts)
    if opts.summary:
        from mpz.fisher import summary_check
        summary_check(F, opts.summary)      # a summary too large for its tables, up front
    opts, bound_rule = resolve_bound(motion, opts)          # issue 12: never unbounded unasked
    # issue 15: the bytes do not depend on it
    threads = thread_count(opts, motion.n_frames * motion.n_markers)
    # the ancillary chunks need only the motion: made on a thread meanwhile (issue 15.1)
    pool, ancillary = start_pool(threads, ancillary_records, motion, opts)
    try:
        hier = plan_hierarchy(motion, opts, pool)
        addh, addh_rule = head_scale(motion, hier)
        x = _filled(motion.positions, motion.valid)   # issue 11.11: not copied without gaps
        try:
            grid = plan_grid(motion, opts, hier, addh, x)
        except EncoderError as exc:
            if not bound_rule.endswith(", default)") or isinstance(exc, _NodeNameError):
                raise
            # the caller gave no bound: a QA run (stop 49) was told of a max error it never
            # gave
            raise EncoderError(f"{exc}; that is the default bound ({bound_rule}): give a "
                               "max_error (--max-error) these coordinates allow") from None
        report = EncodeReport(F, M, motion.raw_size(), step=grid.step, addh=addh,
                              addh_rule=addh_rule, hierarchy=hier.method,
                              bound=(opts.max_error if opts.max_error is not None
                                     else 0.0 if grid.exact else None),
                              bound_rule=bound_rule, not_kept=not_kept(motion, opts),
                              notes=option_notes(motion, opts, resolved=True))
        u = GridCoordinates(x, grid.offset, grid.step)           # grid coordinates (float)
        if u.peak() * 2 + 2 >= 2.0 ** MAX_EXP:
            span = float((x.reshape(-1, 3).max(0) - x.reshape(-1, 3).min(0)).max())
            raise EncoderError(f"grid step {grid.step:g} is too fine for a data range of "
                               f"{span:g} {motion.units}: values exceed 2^29")

        # what the decoder will rebuild: the tracks the closed loop needs (issue 11.11)
        qhat = DecodedTracks({n.ref for n in hier.nodes})
        root_marker = hier.nodes[0].members[0]
        # without patterns no node reads the root's decoded track (code_node), so a pool
        # thread codes the root while this one codes the nodes (issue 15.1)
        rooting = (pool.submit(code_root, u[:, root_marker], opts, grid)
                   if pool is not None and opts.pattern_mode == "off" else None)
        if rooting is None:
            root, root_q = code_root(u[:, root_marker], opts, grid)
            qhat.add([root_marker], root_q[:, None, :])
        exact = []
        coded: list[NodeCode] = []
        n_nodes = len(hier.nodes)
        # each node's share of the bar after the plan: its share of the coded markers
        shares = np.cumsum([0] + [len(n.members) for n in hier.nodes[1:]], dtype=np.float64)
        shares = PLANNED + (1.0 - PLANNED) * shares / max(shares[-1], 1.0)
        for i in range(1, n_nodes):
            node = hier.nodes[i]
            stage = None
            if progress is not None:
                lo, hi = float(shares[i - 1]), float(shares[i])
                progress(lo, f"{node.name}: " + ("key frames" if opts.pattern_mode == "off"
                                                  else "patterns"))

                def stage(f: float, what: str, lo: float = lo, hi: float = hi,
                          name: str = node.name) -> None:
                    progress(lo + (hi - lo) * f, f"{name}: {what}")
            nc = code_node(i, node, hier.nodes[node.parent].ref, u, qhat, opts, grid,
                           addh / grid.step, pool, stage)
            qhat.add(node.members, nc.decoded)
            if grid.exact:
                exact.append(np.array_equal(*_exact_pair(nc.decoded, motion, node.members,
                                                         grid)))
            coded.append(replace(nc, decoded=_SPENT))   # only the records are kept
            report.nodes.append(nc.report)
            del nc
            if progress is not None:
                progress(float(shares[i]), node.name)

        if rooting is not None:
            root, root_q = rooting.result()
            qhat.add([root_marker], root_q[:, None, :])
        if progress is not None and n_nodes == 1:      # the root alone: no node above
            progress(1.0, hier.nodes[0].name)
        if grid.exact:                                   # issue 12: the promise of error 0
            exact.append(np.array_equal(*_exact_pair(root_q[:, None, :], motion,
                                                     [root_marker], grid)))
            if not all(exact):                           # (checked node by node, issue 11.11)
                raise EncoderError("exact grid coding did not reproduce every sample (a bug)")
        bits = qhat.peak.bit_length() + 1
        if bits > MAX_BITS:
            raise EncoderError("decoded values exceed the 31-bit range of spec §4.4; use a coarser "
                               "grid")
        data = container.build(file_records(motion, opts, hier, grid, root, coded, bits,
                                            None if ancillary is None else ancillary.result()))
        report.notes += outcome_notes(motion, opts, data, resolved=True)
    except (KeyboardInterrupt, SystemExit, SystemError):
        # a signal (or a kernel's report of one, SystemError): waited for a while only,
        # since it may have left a lock held that a pool thread waits on for ever (numba's
        # compiler lock while a kernel loads): a review of stop 56 saw a Ctrl-C hang the
        # command for good. Not at all, it let this thread unwind while the pool's still
        # ran kernels, and two of 60 interrupted runs then crashed (SIGSEGV).
        if pool is not None:
            pool.shutdown(wait=False, cancel_futures=True)
            deadline = time.monotonic() + INTERRUPT_WAIT_SECONDS
            for t in list(getattr(pool, "_threads", ())):
                t.join(max(0.0, deadline - time.monotonic()))
            pool = None
        raise
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
    report.chunk_bytes = container.chunk_sizes(data)
    report.file_bytes = len(data)
    if opts.summary:
        from mpz.fisher import block_length
        report.summary_blocks = block_length(F)
    report.seconds = time.perf_counter() - t0
    return data, report


class EncodeKeywords(TypedDict, total=False):
    """The keywords of :func:`encode`, each with its type, for the functions that pass them
    on (``mpz.write_mpz(motion, path, **options: Unpack[EncodeKeywords])``), so that a type
    checker catches a misspelt or mistyped option there as it does in :func:`encode`
    (``tests/test_api_calls.py`` holds the two lists together)."""

    max_error: float | None
    group_errors: Mapping[str, float] | None
    theta: float
    k0: int
    tau: float
    metric: str
    weights: Mapping[str, float] | None
    hierarchy: str | os.PathLike[str] | Mapping[str, Any] | None
    smoothing: int
    patterns: str | None
    segmentation: str
    grid: float | None
    max_segment: int
    summary: Sequence[int]
    summary_space: str
    summary_format: str
    metadata: Mapping[str, str] | None
    seed: int
    lossy: bool
    default_error_mm: float
    default_error_fraction: float
    source_grid: float | None
    model_error: float
    model_errors: Mapping[str, float] | None
    keep_skeleton: bool
    angle_error: float | None
    translation_error: float | None
    position_error: float | None
    threads: int | None


#: :func:`encode`'s mappings whose None means "empty" (EncodeOptions takes a mapping)
NONE_IS_EMPTY = ("group_errors", "metadata", "model_errors")


def keyword_options(options: EncodeKeywords) -> EncodeOptions:
    """The :class:`EncodeOptions` of :func:`encode`'s keywords ``options`` (a mapping of
    :data:`NONE_IS_EMPTY` given as None is empty, as :func:`encode` takes it).

    Raises
    ------
    EncoderError
        An unknown keyword, with the closest option name.
    """
    check_option_names(options)
    given: dict[str, Any] = dict(options)
    for name in NONE_IS_EMPTY:
        if name in given and given[name] is None:
            given[name] = {}
    return EncodeOptions(**given)


def encode(motion: Motion, *,
           max_error: float | None = None,
           group_errors: Mapping[str, float] | None = None,
           theta: float = 0.2,
           k0: int = 10,
           tau: float = 0.05,
           metric: str = "max",
           weights: Mapping[str, float] | None = None,
           hierarchy: str | os.PathLike[str] | Mapping[str, Any] | None = None,
           smoothing: int = 2,
           patterns: str | None = None,
           segmentation: str = "adaptive",
           grid: float | None = None,
           max_segment: int = 240,
           summary: Sequence[int] = (),
           summary_space: str = "positions",
           summary_format: str = "smrc",
           metadata: Mapping[str, str] | None = None,
           seed: int = 0,
           lossy: bool = False,
           default_error_mm: float = 0.1,
           default_error_fraction: float = 1e-4,
           source_grid: float | None = None,
           model_error: float = 1e-4,
           model_errors: Mapping[str, float] | None = None,
           keep_skeleton: bool = True,
           angle_error: float | None = None,
           translation_error: float | None = None,
           position_error: float | None = None,
           threads: int | None = None,
           **unknown: Never) -> bytes:
    """Encode a motion to MPZ bytes.

    Every keyword is the field of :class:`EncodeOptions` with the same name and
    the same default (a test holds the two together; ``None`` for a mapping
    means "empty"). Lengths are plain numbers in the motion's own units
    (``motion.units``, e.g. ``max_error=1.0`` is 1 mm for a motion in mm and
    1 cm for one in cm); the CLI is the place that converts ``1mm``.

    Parameters
    ----------
    motion : Motion
    max_error : float, optional
        Hard bound, in motion units: every valid sample decodes within this
        Euclidean distance. For skeletal input (BVH, AMC: a motion with
        ``extras["skeleton"]``) it bounds the joint positions that the decoded channels
        give as well (``position_error``, unless that is given), as ``mpz encode
        --max-error`` does. Default None: the default bound (``lossy`` is the only way
        to have none): exact on the grid of an int16 C3D source; for skeletal input,
        1/500 of the skeleton's size on the marker layer, a preview, with the channels
        within ``angle_error`` and ``translation_error``; else ``default_error_mm``
        (``default_error_fraction`` of the extent for a motion without units).
    group_errors : mapping of str to float, optional
        Tighter bounds for hierarchy nodes, node name -> bound in motion
        units (needs a bound, ``max_error`` or the default one: not with ``lossy``).
        Default: none.
    theta : float, default 0.2
        Key-frame threshold, a fraction of the head size ADDH.
    k0 : int, default 10
        Initial number of clusters.
    tau : float, default 0.05
        Clustering threshold, a fraction of ADDH.
    metric : {"max", "ave"}, default "max"
        Clustering error metric (paper Eq. 2 or Eq. 1).
    weights : mapping of str to float, optional
        Marker or node name -> weight (local distortion control).
    hierarchy : str, path or mapping, optional
        "cmu41", "skeleton", "auto", "flat", a JSON hierarchy file or its
        parsed dict. Default: one flat node when the pattern layer is off and there are
        no ``group_errors`` (every bounded encode by default), else chosen from the
        marker names.
    smoothing : int, default 2
        Boundary smoothing half-width, 0..16 (spec §6.4).
    patterns : {"auto", "on", "off"}, optional
        Pattern layer per node. Default: "on" with ``lossy``, else "off" (every bounded
        encode, ``max_error`` or the default bound).
    segmentation : {"adaptive", "optimal"}, default "adaptive"
        Paper's Alg. 1, or Fisher's optimal partition.
    grid : float, optional
        Grid step in motion units: an upper limit under a bound (the step the bound needs
        is used when finer, and an int16 C3D's own grid when coded on it), the step
        itself in ``lossy`` mode. Default: the step the bound needs (``max_error`` or the
        default bound); ADDH/1000 with ``lossy``.
    max_segment : int, default 240
        Longest segment in frames, 2..4096.
    summary : sequence of int, default ()
        Segment counts k of the optional summary chunk (spec §4.15, or §4.10), each 1 to
        MAX_FRAMES. A count above the motion's frame count gives the level of one segment
        a frame (k = frames), and each count is written once, in increasing order:
        ``Summary.level`` takes the k written (``mpz.info(...).summary_levels``).
    summary_space : {"positions", "angles"}, default "positions"
    summary_format : {"smrc", "smry"}, default "smrc"
        The summary chunk: smrc, range-coded (§4.15; the file is then MPZ 1.1), or smry,
        raw 32-bit means (§4.10), which 1.0 readers know.
    metadata : mapping of str to str, optional
        Extra §4.11 metadata (added to ``motion.metadata``).
    seed : int, default 0
        Seed of the clustering (the encoder is deterministic).
    lossy : bool, default False
        The paper's mode: patterns only, no residual layer, no declared bound.
    default_error_mm, default_error_fraction : float, default 0.1 and 1e-4
        The default bound (see ``max_error``).
    source_grid : float, optional
        Code the positions on this grid (every coordinate must be a multiple of
        it): exactly (error 0), unless ``max_error`` is also given and above
        about sqrt(3) times the grid, when they are coded within ``max_error`` on
        this grid (the report says which). By default an int16 C3D source's
        |POINT:SCALE| when no bound is given.
    model_error : float, default 1e-4
        Model outputs of a C3D (spec §4.13.3): max error as a fraction of each
        channel's range.
    model_errors : mapping of str to float, optional
        The same per kind (ANGLES, FORCES, MOMENTS, POWERS, SCALARS, REACTIONS).
    keep_skeleton : bool, default True
        Skeletal input (BVH, AMC/ASF, spec §4.14): write the skeleton chunk.
    angle_error, translation_error : float, optional
        Bounds on the rotation channels (degrees) and translation channels (the
        skeleton's length unit). Default: 0.01 each, unless ``position_error`` is given.
    position_error : float, optional
        Bound on the joint positions computed from the channels (spec §6.10), in motion
        units; the channel steps are then the coarsest that keep it. Default: ``max_error``
        when that is given.
    threads : int, optional
        Threads for the independent work within the file (1..64); default: the CPU count,
        at most 2, and 1 for a motion of fewer than 10,000 marker-frames (a second thread
        costs more than it saves there). The output bytes are the same for any number.

    Returns
    -------
    bytes
        A complete MPZ file. :func:`encode_motion` and :func:`mpz.write_mpz` return an
        :class:`EncodeReport` too, whose ``notes`` name the options given that did less
        than they seem (:func:`mpz.encoder.option_notes`, which can also be called
        before encoding, then :func:`mpz.encoder.outcome_notes` of the file written).

    Raises
    ------
    EncoderError
        For options that cannot be honoured, and for an unknown keyword (with the
        closest option name; type checkers reject it already: ``**unknown`` is
        typed ``Never``).

    Examples
    --------
    >>> from mpz import encode
    >>> from mpz.synth import generate
    >>> data = encode(generate("walk", frames=30), max_error=2.0)
    >>> data[:4]
    b'\\x89MPZ'
    """
    check_option_names(unknown)
    opts = EncodeOptions(
        max_error=max_error, group_errors=group_errors or {}, theta=theta, k0=k0, tau=tau,
        metric=metric, weights=weights, hierarchy=hierarchy, smoothing=smoothing,
        patterns=patterns, segmentation=segmentation, grid=grid, max_segment=max_segment,
        summary=summary,  # type: ignore[arg-type]  # made a tuple, or refused, there
        summary_space=summary_space, summary_format=summary_format,
        metadata=metadata or {},
        seed=seed, lossy=lossy, default_error_mm=default_error_mm,
        default_error_fraction=default_error_fraction, source_grid=source_grid,
        model_error=model_error, model_errors=model_errors or {},
        keep_skeleton=keep_skeleton, angle_error=angle_error,
        translation_error=translation_error, position_error=position_error,
        threads=threads)
    return encode_motion(motion, opts)[0]
