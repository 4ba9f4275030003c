"""Error statistics between an original and a decoded motion.

All distances are Euclidean per marker-frame, in the motions' units, over
samples valid in the original (a sample the decoder marks as a gap where the
original was valid counts as an infinite error, so it cannot hide).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, replace
import math
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from mpz.errors import MotionError
from mpz.motion import Motion

if TYPE_CHECKING:
    from collections.abc import Callable

    from mpz.c3darchive import C3DArchive


def _motions(original: object, decoded: object) -> None:
    """Refuse what is not a Motion (an AttributeError deep inside, before)."""
    for what, m in (("original", original), ("decoded", decoded)):
        if not isinstance(m, Motion):
            raise TypeError(f"{what} must be an mpz.Motion, got {type(m).__name__}")


#: marker-frames whose distances :func:`_dist` computes at a time (1.5 MiB of differences)
_DIST_SAMPLES = 1 << 16


def _dist(original: Motion, decoded: Motion) -> NDArray[np.float64]:
    _motions(original, decoded)
    if original.positions.shape != decoded.positions.shape:
        raise MotionError(f"shapes differ: {original.positions.shape} vs {decoded.positions.shape}")
    # the same sample of the same marker in the same unit, or the distance means nothing
    # (a motion in cm scored 1518 against itself in mm; `mpz compare` aligns by name)
    if original.units and decoded.units and original.units != decoded.units:
        raise MotionError(f"units differ: {original.units!r} vs {decoded.units!r} (convert "
                          "one first; a motion without units is compared as numbers)")
    if _rates_differ(original, decoded):
        # frame f is not the same moment in both: max_error and arms scored 120 Hz
        # against 60 Hz as if it were (a QA run of stop 53; mpz compare refused it)
        raise MotionError(f"frame rates differ: {original.rate:.10g} vs {decoded.rate:.10g} "
                          "Hz, so the same frame is not the same moment (a motion read from "
                          "NPY or AMC, which store no rate, is compared frame by frame)")
    if list(original.names) != list(decoded.names):
        k = next(i for i, (a, b) in enumerate(zip(original.names, decoded.names, strict=True))
                 if a != b)
        raise MotionError(f"marker names differ at index {k}: {original.names[k]!r} vs "
                          f"{decoded.names[k]!r} (reorder one motion first)")
    # a block of frames at a time: the differences and their squares of every sample were
    # two temporaries of the positions' size, three times the distances' (each row's norm
    # is the same computation either way)
    a, b = original.positions, decoded.positions
    d = np.empty(a.shape[:2])
    rows = max(1, _DIST_SAMPLES // max(1, a.shape[1]))
    for f in range(0, a.shape[0], rows):
        d[f: f + rows] = np.linalg.norm(a[f: f + rows] - b[f: f + rows], axis=2)
    d[~original.valid] = np.nan
    d[original.valid & ~decoded.valid] = np.inf
    return d


def errors(original: Motion, decoded: Motion) -> NDArray[np.float64]:
    """Per-sample Euclidean error ``[F, M]``, NaN where the original is a gap."""
    return _dist(original, decoded)


def max_error(original: Motion, decoded: Motion) -> float:
    """Largest Euclidean error over valid samples (0 if there are none).

    ``original`` and ``decoded`` must have the same shape, marker names in the same order,
    the same units (either may have none) and the same frame rate (within
    :data:`RATE_TOLERANCE`; a rate a reader assumed, an NPY's or an AMC's, is not
    compared); a sample counts where ``original`` is valid. Raises
    :class:`~mpz.MotionError` otherwise."""
    d = _dist(original, decoded)
    return float(np.nanmax(d)) if np.isfinite(d).any() or np.isinf(d).any() else 0.0


def _rms_over(d: NDArray[np.float64], axis: int) -> NDArray[np.float64]:
    """RMS of the non-NaN entries along ``axis``; NaN where there are none.

    Counted by hand rather than with ``np.nanmean``, which warns "Mean of empty
    slice" for every frame (or marker) that is a gap throughout (arthuman).
    """
    have = ~np.isnan(d)
    n = have.sum(axis=axis)
    total = np.where(have, d, 0.0)
    np.square(total, out=total)         # ** 2 in place: one array of d's size, not two
    s = total.sum(axis=axis)
    out = np.full(s.shape, np.nan)
    np.divide(s, n, out=out, where=n > 0)
    return np.sqrt(out)


def arms(original: Motion, decoded: Motion) -> float:
    """Paper Eq. 3: mean over frames of the RMS marker error of the frame (valid markers only).

    Frames without a valid marker do not count. ``original`` and ``decoded`` as for
    :func:`max_error`.
    """
    return _arms_of(_dist(original, decoded))


def _arms_of(d: NDArray[np.float64]) -> float:
    """:func:`arms` of the distances ``d`` (:func:`_dist`)."""
    per_frame = _rms_over(d, axis=1)
    per_frame = per_frame[~np.isnan(per_frame)]
    return float(per_frame.mean()) if per_frame.size else 0.0


def _percentile(values: NDArray[np.float64], q: float) -> float:
    """``np.percentile`` of values without NaN that may hold +inf (a valid sample that
    became a gap). numpy's interpolation takes inf - inf between two infinite values, and
    inf x 0 next to a finite one: NaN, and a RuntimeWarning printed into ``mpz compare``'s
    report (QA runs of stop 52). The infinities are taken as the largest float, and a
    percentile above every finite value is +inf (it interpolates towards one).

    ``values`` is reordered (numpy partitions it in place: the order statistics, and so
    the percentile, are the same; a copy of it was the largest array of the error
    report, :func:`summary`)."""
    finite = np.isfinite(values)
    if finite.all():
        return float(np.percentile(values, q, overwrite_input=True))
    top = float(values[finite].max()) if finite.any() else -math.inf
    p = float(np.percentile(np.where(finite, values, np.finfo(np.float64).max), q,
                            overwrite_input=True))
    return math.inf if p > top else p


def summary(original: Motion, decoded: Motion) -> dict[str, Any]:
    """max, ARMS, RMS, p99 and mean error, plus per-marker max and RMS; each None where no
    sample of the original is valid (nothing was compared: a CLI audit found 0.0 there, and
    "every sample within" the bound)."""
    d = _dist(original, decoded)
    # what needs the distances of every sample first, then those of the valid ones, and the
    # first let go: the report held both, and two temporaries of their size (issue 11.11)
    per_max = np.fmax.reduce(d, axis=0, initial=-np.inf)      # NaN (a gap) never counts
    per_rms = _rms_over(d, axis=0)
    arms_d = _arms_of(d)                # (arms(original, decoded): d again)
    flat = d[~np.isnan(d)]
    del d
    big: float | None = None
    rms: float | None = None
    p99: float | None = None
    mean: float | None = None
    if flat.size:
        big, rms, mean = float(flat.max()), float(np.sqrt((flat ** 2).mean())), float(flat.mean())
        p99 = _percentile(flat, 99)     # last: it reorders flat in place
    return {
        "max": big,
        "arms": None if big is None else arms_d,
        "rms": rms,
        "p99": p99,
        "mean": mean,
        "per_marker_max": {n: (None if not np.isfinite(v) and v < 0 else float(v))
                           for n, v in zip(original.names, per_max, strict=False)},
        "per_marker_rms": {n: (None if np.isnan(v) else float(v))
                           for n, v in zip(original.names, per_rms, strict=False)},
    }


# -- besides the markers ---------------------------------------------------------------
@dataclass(frozen=True)
class Part:
    """What a comparison found for one part of the original besides its markers.

    ``status`` is ``"same"`` (bit for bit), ``"within"`` (a lossy part within the bound
    the decoded file declares, with 4 units in the last place of the values for the
    rounding of a step's multiple), ``"changed"`` (a lossy part, with no declared bound
    to hold it to; metadata entries with other values in a motion of other units),
    ``"differs"`` (a lossless part that is not the same, metadata entries with other
    values, or a lossy part beyond its bound), ``"missing"`` (the
    decoded motion does not hold it) or, from ``mpz compare`` only, ``"unchecked"`` (an
    AMC decoded input read with the original's skeleton). ``detail`` says what the part
    is and where it differs first, or where a changed part changed most (a byte, a
    parameter's group and name, a channel or point and a frame index from 0). ``error``
    and ``bound`` are a lossy part's largest difference and its declared bound, in
    ``unit`` (None: the part's own unit is not known).
    """

    name: str
    status: str
    detail: str
    error: float | None = None
    bound: float | None = None
    unit: str | None = None


#: bytes 16-17 of a C3D header, word 9: the block where the data starts, which a written
#: C3D moves to just after its parameters (as POINT:DATA_START; docs/io-notes.md)
_DATA_START = slice(16, 18)
#: header words 7-8, the scale (float32), whose sign a C3D writer sets (spec §6.9)
_SCALE = slice(12, 16)


def _same_but_sign(x: bytes, y: bytes) -> bool:
    """Whether two runs of float32 (little-endian) differ at most in the signs of their
    elements: what spec §6.9's writer changes in POINT:SCALE and header words 7-8."""
    if len(x) != len(y) or len(x) % 4:
        return False
    mask = np.uint32(0x7FFFFFFF)
    return bool((np.frombuffer(x, "<u4") & mask == np.frombuffer(y, "<u4") & mask).all())
#: at most this many names listed in a detail, then "and N more"
_LISTED = 5


def _listed(names: list[str]) -> str:
    """``names`` for a detail: the first :data:`_LISTED`, then how many more."""
    more = len(names) - _LISTED
    return ", ".join(names[:_LISTED]) + (f" and {more} more" if more > 0 else "")


def besides_markers(original: Motion, decoded: Motion, *,
                    channel_bounds: tuple[float, float] | None = None) -> list[Part]:
    """Each part of ``original`` besides its marker trajectories, compared with
    ``decoded``: its metadata (a TRC's header fields...), a C3D's archive (header,
    parameters with the events, the points' fourth words, analog words, model outputs
    one part per kind, in the unit its POINT parameter names) and a BVH's or AMC's
    skeleton and joint channels.

    Where the data starts is not compared (a written C3D moves it); nor is the processor
    type (a written C3D is Intel; the archive keeps its values normalised). Model outputs
    are held to the bounds the decoded archive declares (per coordinate, spec §6.9; the
    sum of both when both were decoded from MPZ files); the joint channels to
    ``channel_bounds``, (rotations in degrees, translations in skeleton units), the
    largest error the decoded file's channel steps allow (:func:`mpz.skeleton.report`;
    for two MPZ files the caller gives the sum), when given.
    """
    _motions(original, decoded)
    if channel_bounds is not None and not (
            isinstance(channel_bounds, (tuple, list)) and len(channel_bounds) == 2 and all(
                isinstance(b, (int, float, np.integer, np.floating)) and not isinstance(b, bool)
                and math.isfinite(b) and b >= 0 for b in channel_bounds)):
        raise ValueError(f"channel_bounds must be two finite numbers >= 0 (rotations in "
                         f"degrees, translations in skeleton units), got {channel_bounds!r:.80}")
    return (_rate_parts(original, decoded) + _metadata_parts(original, decoded)
            + _archive_parts(original, decoded)
            + _skeleton_parts(original, decoded, channel_bounds))


def parts_missing_from(original: Motion, decoded: Motion) -> list[Part]:
    """The parts of :func:`besides_markers` (``original`` against ``decoded``) that
    ``decoded`` does not hold, ``"missing"``, and nothing else: the parts held by both are
    not compared (``mpz compare`` of two .mpz files asks it both ways, and compared every
    part a second time for it; review of stop 73)."""
    from mpz.c3darchive import C3DArchive
    from mpz.io.kinematics import Skeleton
    _motions(original, decoded)
    parts = _metadata_parts(original, decoded)
    if not isinstance(decoded.extras.get("c3d"), C3DArchive):     # else held: not compared
        parts += _archive_parts(original, decoded)
    if decoded.angles is None or not isinstance(decoded.extras.get("skeleton"), Skeleton):
        parts += _skeleton_parts(original, decoded, None)
    return [p for p in parts if p.status == "missing"]


#: relative tolerance on two frame rates (a C3D stores its rate as a float32, a TRC as
#: text); ``mpz compare`` refuses two rates beyond it before it compares anything
RATE_TOLERANCE = 1e-6


def rate_assumed(m: Motion) -> bool:
    """Whether ``m``'s rate is its reader's assumption, not stored: an NPY's, an AMC's, a
    one-row CSV's (``rate_assumed`` in its metadata, which ``--rate`` takes away). Every
    NPY counted until stop 75, also one given ``--rate``; the NPY reader now says so
    itself (an .mpz made from an NPY before that holds no such entry)."""
    return "rate_assumed" in m.metadata


def same_frame_time(a: Motion, b: Motion) -> bool:
    """Whether both motions hold one BVH Frame Time (``metadata["frame_time"]``): then their
    rates are one rate, however a reader rounded it. The BVH reader snaps ``0.008333`` to
    120 Hz since the QA run of exporters; an .mpz encoded before holds 120.0048 Hz, and was
    refused against its own source."""
    ft = a.metadata.get("frame_time")
    return bool(ft) and ft == b.metadata.get("frame_time")


def _rates_differ(original: Motion, decoded: Motion) -> bool:
    """Whether two motions' frame rates differ beyond :data:`RATE_TOLERANCE`, both stored
    (a rate assumed by a reader is unknown: not compared; two of one BVH Frame Time are
    one rate: :func:`same_frame_time`)."""
    return not math.isclose(original.rate, decoded.rate, rel_tol=RATE_TOLERANCE) and not (
        rate_assumed(original) or rate_assumed(decoded) or same_frame_time(original, decoded))


def _rate_parts(original: Motion, decoded: Motion) -> list[Part]:
    """The frame rate, named only when it differs (beyond :data:`RATE_TOLERANCE`): the
    same frame is then not the same moment (a QA of stop 42: 120 Hz against 60 Hz gave
    max 0 and every part same)."""
    if not _rates_differ(original, decoded):
        return []
    return [Part("rate", "differs", f"{decoded.rate:.10g} Hz against {original.rate:.10g} Hz")]


def _metadata_parts(original: Motion, decoded: Motion) -> list[Part]:
    """The original's metadata entries besides those a reader sets to describe the file it
    read (:data:`mpz.io.READER_KEYS`: its name, format, reader...; a written file read
    again gets its own): a TRC's header fields, and what was given at encoding. Entries
    with other values (differs) and lost entries (missing: a format without a place for
    them) are two parts: one does not hide the other."""
    from mpz.io import READER_KEYS
    keys = sorted(k for k in original.metadata if k not in READER_KEYS)
    if not keys:
        return []
    got = decoded.metadata
    changed = [k for k in keys if k in got and got[k] != original.metadata[k]]
    lost = [k for k in keys if k not in got]

    def of(n: int) -> str:
        return f"{n} of its {len(keys)} entries" if len(keys) > 1 else "its one entry"
    parts = []
    if changed:     # a header field written back with another value: not the file; but a
        # file in other units (compared converted) has other fields by right: Units...
        parts.append(Part("metadata", "differs" if original.units == decoded.units
                          else "changed",
                          f"{of(len(changed))} with other values: {_listed(changed)}"))
    if lost:
        parts.append(Part("metadata", "missing", f"{of(len(lost))}: {_listed(lost)}"))
    return parts or [Part("metadata", "same", f"{len(keys)} entr"
                          f"{'ies' if len(keys) > 1 else 'y'}")]


def _archive_parts(original: Motion, decoded: Motion) -> list[Part]:
    from mpz.c3darchive import C3DArchive
    from mpz.io.c3dbin import record_params
    a, b = original.extras.get("c3d"), decoded.extras.get("c3d")
    if not isinstance(a, C3DArchive):
        return []
    if not isinstance(b, C3DArchive):
        return [Part("C3D archive", "missing", a.describe())]
    ha, hb = bytearray(a.header), bytearray(b.header)
    ha[_DATA_START] = hb[_DATA_START] = b"\0\0"
    # spec §6.9: a writer sets the data start, and words 7-8 to ±s, the scale its *Scale*
    # reads, with the sign of the storage it writes (a C3D decoded from a file was "differs"
    # from that file: a QA run of stop 54; and s = 1 for words 7-8 of 0, vector u89)
    if _same_but_sign(bytes(ha[_SCALE]), bytes(hb[_SCALE])) \
            or abs(a.header_scale()) == b.point_scale() \
            or abs(b.header_scale()) == a.point_scale():
        ha[_SCALE] = hb[_SCALE]
    at = next((i for i in range(min(len(ha), len(hb))) if ha[i] != hb[i]),
              None if len(ha) == len(hb) else min(len(ha), len(hb)))
    ev = a.header_events()
    # the archive holds them normalised (Intel byte order, IEEE floats): a DEC or MIPS
    # source's bytes differ from the Intel C3D decoded from it, and "same" said nothing
    # of that (a report QA run of stop 55)
    from mpz.io.c3dbin import PROCESSOR_NAMES
    order = [PROCESSOR_NAMES.get(x.processor, str(x.processor)) for x in (a, b)]
    values = (f"; compared as values: the bytes are in {order[0]} order against "
              f"{order[1]} (spec §6.9 writes Intel)" if order[0] != order[1] else "")
    parts = [Part("C3D header", "same" if at is None else "differs",
                  (f"{len(ha)} bytes" if at is None else
                   f"byte {at} (word {at // 2 + 1}) differs")
                  + (f", {ev} events in its event block" if ev else "") + values)]
    param = _parameters(a, b)
    parts.append(replace(param, detail=param.detail + values))
    params = record_params(a.records)
    parts.append(_words(a, b, params.get("POINT", {})))
    if a.channels:
        parts.append(_analog(a, b, params.get("ANALOG", {})))
    if a.models.shape[1]:
        parts += _models(a, b, params.get("POINT", {}))
    return parts


def _parameters(a: C3DArchive, b: C3DArchive) -> Part:
    """The parameter records, each the same (POINT:DATA_START's value and POINT:SCALE's
    signs aside, which spec §6.9's writer sets); those that differ, are added or are lost
    named by group and name."""
    c = a.contents()
    events = f", EVENT:USED {c['events']}" if c["events"] else ""
    groups = c["parameter_groups"]
    n = len(a.records) - groups
    what = (f"{groups} group{'s' * (groups != 1)}, {n} parameter{'s' * (n != 1)}"
            f"{events}")
    from mpz.io.c3dbin import ParamRecord, named, scale_as_written
    ka, kb = _record_keys(a), _record_keys(b)
    start = a.parameter("POINT", "DATA_START")
    scales = {id(a.records[i]) for i in named(a.records, b"POINT", b"SCALE")}
    words = [a.header_scale(), b.header_scale()]

    def as_written(r: ParamRecord, s: ParamRecord) -> bool:
        """What spec §6.9's writer changes: POINT:DATA_START's value, and each float32
        POINT:SCALE as :func:`~mpz.io.c3dbin.scale_as_written` writes it beside the
        written file's header words 7-8, whichever of the two that file is (its signs
        alone were allowed: a scale of 0 or -inf written as 1 differed, u71, u72)."""
        if r != replace(s, data=r.data):
            return False
        return r is start or (id(r) in scales and (scale_as_written(s, words[0]) == r
                                                   or scale_as_written(r, words[1]) == s))
    if len(a.records) == len(b.records) and ka == kb:
        bad = [k for k, r, s in zip(ka, a.records, b.records, strict=True)
               if r != s and not as_written(r, s)]
        return Part("C3D parameters", "differs" if bad else "same",
                    what + (f"; differ: {_listed(bad)}" if bad else ""))
    sa, sb = set(ka), set(kb)                     # up to 2^16 records each: not per item
    lost = [k for k in ka if k not in sb]
    added = [k for k in kb if k not in sa]
    found = ([f"lost: {_listed(lost)}"] if lost else []) + \
        ([f"added: {_listed(added)}"] if added else [])
    return Part("C3D parameters", "differs", f"{what}; {len(a.records)} records against "
                f"{len(b.records)}; " + ("; ".join(found) or "in another order"))


def _record_keys(a: C3DArchive) -> list[str]:
    """Each record as ``GROUP:NAME`` (a group as ``GROUP``), for saying which differ."""
    groups = {-r.group: r.name.decode("latin-1") for r in a.records if r.is_group}
    return [r.name.decode("latin-1") if r.is_group else
            f"{groups.get(r.group, f'group {r.group}')}:{r.name.decode('latin-1')}"
            for r in a.records]


def _words(a: C3DArchive, b: C3DArchive, point: dict[str, Any]) -> Part:
    """The points' fourth words (residual and camera mask), bit for bit, in the same
    point order."""
    from mpz.io.c3d import point_labels
    F, P = a.words.shape
    what = f"residual and camera words, {P} points x {F} frames"
    # both in the C3D's point order: the slots (which MPZ marker each point is) may
    # number the markers otherwise, as for a C3D read again after it was written from a
    # file whose slots are not in point order (a QA run of stop 54; the markers are
    # compared by name), but must make the same points markers and model outputs
    if [s >= a.markers for s in a.slots] != [s >= b.markers for s in b.slots]:
        return Part("point words", "differs", f"{what}; other points are model outputs")
    if _bits(a.words, b.words):
        return Part("point words", "same", what)
    if _same_as_written(a, b, a.words, b.words, unsigned=False):
        return Part("point words", "same", f"{what}; stored as {b.words.dtype} against "
                    f"{a.words.dtype}, the same values{_ONE_STORAGE}")
    if a.words.dtype != b.words.dtype or a.words.shape != b.words.shape:
        return Part("point words", "differs", f"{what}; stored as {b.words.dtype} "
                    f"{list(b.words.shape)}")
    f, p = _first_other(a.words, b.words)
    name = point_labels(point, P)[p] or f"point {p + 1}"
    return Part("point words", "differs", f"{what}; first at {name!r}, frame index {f}")


def _analog(a: C3DArchive, b: C3DArchive, analog: dict[str, Any]) -> Part:
    """The analog words, bit for bit (NaN payloads too)."""
    from mpz.io.c3d import point_labels
    what = f"{a.channels} channels x {a.analog.shape[0]} samples"
    if a.analog_samples == b.analog_samples and _bits(a.analog, b.analog):
        return Part("analog", "same", what)
    if a.analog_samples == b.analog_samples and _same_as_written(a, b, a.analog, b.analog,
                                                                 unsigned=True):
        return Part("analog", "same", f"{what}; stored as {b.analog.dtype} against "
                    f"{a.analog.dtype}, the same values{_ONE_STORAGE}")
    if (a.analog_samples != b.analog_samples or a.analog.dtype != b.analog.dtype
            or a.analog.shape != b.analog.shape):
        return Part("analog", "differs", f"{what}; {b.channels} channels x "
                    f"{b.analog.shape[0]} samples of {b.analog.dtype} against "
                    f"{a.analog.dtype}, {b.analog_samples} a frame against "
                    f"{a.analog_samples}")
    n, c = _first_other(a.analog, b.analog)
    name = point_labels(analog, a.channels)[c] or f"channel {c + 1}"
    count = int((a.analog.view(f"u{a.analog.itemsize}")
                 != b.analog.view(f"u{b.analog.itemsize}")).sum())
    return Part("analog", "differs", f"{what}; {count} word{'s' * (count != 1)} "
                f"differ{'s' * (count == 1)}, the first of "
                f"{name!r} at sample index {n} (frame index {n // a.analog_samples})")


#: why a C3D's words may come back in the other storage (spec §6.9, Storage)
_ONE_STORAGE = (" (a C3D holds its points and analog words in one storage: int16 words of "
                "an archive whose other chunk is float32 are written as float32)")


def _same_as_written(a: C3DArchive, b: C3DArchive, x: NDArray[Any], y: NDArray[Any], *,
                     unsigned: bool) -> bool:
    """Whether words ``x`` of ``a`` and ``y`` of ``b``, one side int16 and the other float32
    of one shape, are the same words as spec §6.9 writes int16 words into a float32 C3D:
    the binary32 of each value, or with ``unsigned`` (analog words) of v + 65536 for v < 0
    when the int16 side's ANALOG:FORMAT is UNSIGNED. A valid MPZ file may hold int16
    points and float32 analog words (R-4.13.4-3), which a C3D writer must write as float32:
    the values come back, their storage cannot."""
    from mpz.io.c3dbin import analog_unsigned
    if x.shape != y.shape or {x.dtype.str, y.dtype.str} != {"<i2", "<f4"}:
        return False
    (ints, source), floats = ((x, a), y) if x.dtype.kind == "i" else ((y, b), x)
    if unsigned and analog_unsigned(source.records):
        ints = ints.astype(np.int64) & 0xFFFF
    return _bits(ints.astype("<f4"), floats)


def _first_other(x: NDArray[Any], y: NDArray[Any]) -> tuple[int, int]:
    """The first (row, column) where two arrays of one dtype and shape differ bit for bit."""
    u = f"u{x.itemsize}"
    rows, cols = np.nonzero(x.view(u) != y.view(u))
    return int(rows[0]), int(cols[0])


def _bits(x: NDArray[Any], y: NDArray[Any]) -> bool:
    """The same dtype, shape and bytes (NaNs with their payloads, -0.0 apart from 0.0)."""
    return x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes()


#: the POINT parameter naming each model output kind's unit (the C3D user guide; SCALARS
#: and REACTIONS have none), by :class:`mpz.format.ModelKind` value
_KIND_UNITS = {0: "ANGLE_UNITS", 1: "FORCE_UNITS", 2: "MOMENT_UNITS", 3: "POWER_UNITS"}


def _models(a: C3DArchive, b: C3DArchive, point: dict[str, Any]) -> list[Part]:
    """Model outputs, one part per kind, in its unit (POINT:ANGLE_UNITS...): the same
    gaps, and each coordinate within the decoded bound. The first place beyond it (or
    where a gap came or went) is named by its point's label and frame index."""
    from mpz.format import ModelKind
    from mpz.io.c3d import point_labels
    J = a.models.shape[1]
    b = _models_in_point_order_of(a, b)
    if b.models.shape != a.models.shape or a.model_kinds != b.model_kinds:
        return [Part("model outputs", "differs", f"{J} points: {b.models.shape[1]} points "
                     f"x {b.models.shape[0]} frames against {J} x {a.models.shape[0]}, or "
                     "other kinds")]
    labels = point_labels(point, len(a.slots))
    M = len(a.slots) - J
    label = {s - M: labels[p] for p, s in enumerate(a.slots) if s >= M}
    kinds = np.array(a.model_kinds)
    parts = []
    for kind in dict.fromkeys(a.model_kinds):
        js = np.flatnonzero(kinds == kind)
        kname = ModelKind(kind).name
        key = _KIND_UNITS.get(kind)
        rows = point.get(key) if key else None         # text: a list (numbers: not a unit)
        unit = rows[0].strip() or None if isinstance(rows, list) and rows else None
        what = f"{len(js)} points, " + (f"in {unit} (POINT:{key})" if unit else
                                         "no unit named" if key is None else
                                         f"no POINT:{key}")

        def where(f: int, j: int) -> str:
            return f"{label.get(int(j)) or f'model output {int(j) + 1}'!r}, frame index {f}"
        part = _model_kind(a, b, js, where, f"model {kname.lower()}", what)
        parts.append(dataclasses.replace(part, unit=unit))
    return parts


def _models_in_point_order_of(a: C3DArchive, b: C3DArchive) -> C3DArchive:
    """``b`` with its model outputs renumbered as ``a`` numbers the same C3D points
    (model output j is the point whose slot is M + j, and two archives of one C3D may
    number them otherwise: a C3D written from a vector and read again); ``b`` as it is
    when the two do not make the same points model outputs."""
    Ma, Mb = a.markers, b.markers
    if len(a.slots) != len(b.slots):
        return b
    pairs = sorted((sa - Ma, sb - Mb) for sa, sb in zip(a.slots, b.slots, strict=True)
                   if sa >= Ma or sb >= Mb)
    if any(ja < 0 or jb < 0 for ja, jb in pairs) or len(pairs) != a.models.shape[1]:
        return b
    order = [jb for _, jb in pairs]
    if order == list(range(len(order))):
        return b
    return dataclasses.replace(
        b, models=b.models[:, order], model_valid=b.model_valid[:, order],
        model_kinds=[b.model_kinds[j] for j in order],
        model_bounds=None if b.model_bounds is None else b.model_bounds[order])


def _model_kind(a: C3DArchive, b: C3DArchive, js: NDArray[np.intp],
                where: Callable[[int, int], str], name: str, what: str) -> Part:
    """The model outputs ``js`` of one kind compared (:func:`_models`)."""
    va, vb = a.model_valid[:, js], b.model_valid[:, js]
    if not np.array_equal(va, vb):
        f, j = (int(v[0]) for v in np.nonzero(va != vb))
        return Part(name, "differs", f"{what}; a gap {'came' if va[f, j] else 'went'} at "
                    f"{where(f, js[j])}")
    err = np.abs(a.models[:, js] - b.models[:, js])                 # [F, j, 3]
    err[~va] = 0.0
    e = float(err.max(initial=0.0))
    # two decoded archives (two encodes of one source) are each within their own bounds of
    # it: held to the sum, as the markers are (one file's bound failed two good files, a
    # QA run of stop 53)
    declared = [x.model_bounds for x in (a, b) if x.model_bounds is not None]
    bounds = None if not declared else sum(declared[1:], declared[0])
    if bounds is None:
        if e == 0:
            return Part(name, "same", f"{what}; no bound declared", error=e)
        f, j, x = _largest(err)
        return Part(name, "changed", f"{what}; no bound declared; largest at "
                    f"{where(f, js[j])}, {'xyz'[x]}", error=e)
    bound = np.broadcast_to(bounds[js][None], err.shape)
    beyond = ~(err <= bound)                                          # NaN too
    top = float(bounds[js].max(initial=0.0))
    if not beyond.any():
        return Part(name, "within", what, error=e, bound=top)
    f, j, x = (int(v[0]) for v in np.nonzero(beyond))
    return Part(name, "differs", f"{what}; first beyond its bound at {where(f, js[j])}, "
                f"{'xyz'[x]}: {err[f, j, x]:.4g} > {bound[f, j, x]:.4g}", error=e, bound=top)


def _skeleton_parts(original: Motion, decoded: Motion,
                    bounds: tuple[float, float] | None) -> list[Part]:
    from mpz.io.kinematics import Skeleton
    from mpz.skeleton import is_rotation
    sa, sb = original.extras.get("skeleton"), decoded.extras.get("skeleton")
    if not isinstance(sa, Skeleton) or original.angles is None:
        return []
    if not isinstance(sb, Skeleton) or decoded.angles is None:
        return [Part("skeleton", "missing", f"{_joints(sa)} and their "
                     f"{sa.channel_count} channels")]
    parts = [_skeleton(sa, sb)]
    x, y = original.angles, decoded.angles
    if x.shape != y.shape or original.angle_names != decoded.angle_names:
        return parts + [Part("joint channels", "differs",
                             f"{x.shape[1]} channels x {x.shape[0]} frames against "
                             f"{y.shape[1]} x {y.shape[0]}, or other names")]
    turns = np.array([is_rotation(k) for k in sa.channel_kinds()], bool)
    to_deg = 180 / math.pi if sa.angle_unit == "rad" else 1.0
    if sa.convention == "asf":
        length, unit = f"the ASF's length unit (1/{sa.length:g} in)", None
    else:                       # a BVH has none; the .mpz of one has what --units named
        known = original.units or decoded.units
        length, unit = (known, known) if known else ("the BVH's length unit", None)
    for name, cols, scale, k, u in (("joint rotations", turns, to_deg, 0, "deg"),
                                    ("joint translations", ~turns, 1.0, 1, unit)):
        if not cols.any():
            continue
        d = np.abs(x[:, cols] - y[:, cols])
        e = float(d.max(initial=0.0)) * scale
        what = f"{int(cols.sum())} channels, in {u if k == 0 else length}"
        if bounds is None:
            if e != 0:
                f, c = _largest(d)
                what += f"; no bound declared; largest at {_channel(original, cols, c)}, " \
                    f"frame index {f}"
            else:
                what += "; no bound declared"
            parts.append(Part(name, "same" if e == 0 else "changed", what, error=e, unit=u))
            continue
        # a value k x step comes back within step / 2 and the rounding of that product
        slack = 4 * np.spacing(np.maximum(np.abs(x[:, cols]), np.abs(y[:, cols])))
        beyond = ~(d <= bounds[k] / scale + slack)
        if beyond.any():
            f, c = (int(v[0]) for v in np.nonzero(beyond))
            what += (f"; first beyond its bound at {_channel(original, cols, c)}, "
                     f"frame index {f}: "
                     f"{d[f, c] * scale:.4g} > {bounds[k]:.4g}")
        parts.append(Part(name, "differs" if beyond.any() else "within", what, error=e,
                          bound=bounds[k], unit=u))
    return parts


def _largest(d: NDArray[np.float64]) -> tuple[int, ...]:
    """The index of the largest value of ``d``, a NaN counting as the largest."""
    flat = int(np.argmax(np.where(np.isnan(d), np.inf, d)))
    return tuple(int(v) for v in np.unravel_index(flat, d.shape))


def _channel(motion: Motion, cols: NDArray[np.bool_], c: int) -> str:
    """The name of column ``c`` of the joint channels ``cols`` selects, quoted."""
    i = int(np.flatnonzero(cols)[c])
    return repr(((motion.angle_names or [])[i:i + 1] or [f"channel {i + 1}"])[0])


def _skeleton(sa: Any, sb: Any) -> Part:
    """The skeleton's fields, each the same; the joints that differ named."""
    fields = [f.name for f in dataclasses.fields(sa)
              if getattr(sa, f.name) != getattr(sb, f.name)]
    if not fields:
        return Part("skeleton", "same", _joints(sa))
    found = [f for f in fields if f != "joints"]
    if "joints" in fields:
        if len(sa.joints) != len(sb.joints):
            found.append(f"{len(sb.joints)} joints against {len(sa.joints)}")
        else:
            bad = [ja.name or (f"end site of {sa.joints[ja.parent].name}"
                               if 0 <= ja.parent < len(sa.joints) else f"joint {i + 1}")
                   for i, (ja, jb) in enumerate(zip(sa.joints, sb.joints, strict=True))
                   if ja != jb]
            found.append(f"joints {_listed(bad)}")
    return Part("skeleton", "differs", f"{_joints(sa)}; differ: {', '.join(found)}")


def _joints(skel: Any) -> str:
    """"31 joints and 7 End Sites" of a skeleton (:func:`mpz.skeleton.joints_text`)."""
    from mpz.skeleton import joints_text
    return joints_text(len(skel.joints), sum(bool(j.end_site) for j in skel.joints))
