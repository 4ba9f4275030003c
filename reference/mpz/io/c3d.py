"""C3D reading and writing.

Contract: :func:`read_c3d` returns the markers of a C3D file as a
:class:`mpz.Motion`, and everything else the file holds in
``motion.extras["c3d"]``, a :class:`mpz.c3darchive.C3DArchive` (spec §4.13): the
header, every parameter (events, force plates, subjects ...), the fourth word
(residual, camera mask) of every point, the model outputs (points listed in
POINT:ANGLES, FORCES, MOMENTS, POWERS, SCALARS or REACTIONS, which are not
markers) and the analog channels. Points come from ``ezc3d``, or from the
pure-numpy reader :mod:`mpz.io.c3dbin` for files ezc3d refuses (SGI/MIPS
big-endian files; parameter sections ezc3d cannot parse even with
``ignore_bad_formatting``); the archive always comes from :mod:`mpz.io.c3dbin`.

:func:`write_c3d` writes a motion with an archive back as the C3D it came from
(:func:`mpz.io.c3dbin.build_c3d`: every point in its slot, parameters, header
and analog as stored; Intel byte order; int16 storage when the source had it and
every coordinate is still on its grid, float32 otherwise), and a motion without
one as a float C3D of its points through ezc3d (more than 65535 frames, which ezc3d
reads back short: our own writer, :func:`long_bytes`).

Gaps: a sample is a gap when its residual word is negative, when a
coordinate is NaN, or when it is exactly (0, 0, 0). The last rule is the
usual convention of Vicon-style exporters and is what the numediart file
needs (its 23% occluded samples have residual 0 at the origin).
"""
from __future__ import annotations

from collections.abc import Mapping
import functools
import math
import os
import shutil
import tempfile
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from mpz.errors import InputFormatError
from mpz.io import c3dbin
from mpz.io._common import (
    StrPath,
    is_utf8,
    open_input,
    read_open,
    reader,
    reopen_name,
    start_frame,
    unique_names,
    values_at_gaps,
)
from mpz.motion import Motion, finite_samples

if TYPE_CHECKING:
    from mpz.c3darchive import C3DArchive

#: POINT:UNITS values we recognise; anything else is unknown ("")
_UNITS = {"mm": "mm", "cm": "cm", "m": "m"}


def _text(point_params: Mapping[str, Any], key: str, numeric: list[str]) -> list[str]:
    """The rows of the char parameter POINT:``key`` ([] when absent). A parameter stored as
    numbers (its type byte says int8, int16 or float32 where the C3D user guide has char)
    gives [] and its name is appended to ``numeric``: its bytes are not read as text."""
    value = point_params.get(key)
    if value is None:
        return []
    if isinstance(value, np.ndarray) and value.dtype.kind not in "OUS":
        numeric.append(f"POINT:{key}")
        return []
    return [str(s) for s in value]


def _numeric_text(numeric: list[str]) -> str:
    """The warning for the char parameters :func:`_text` found stored as numbers."""
    return (f"{', '.join(numeric)} stored as numbers, not text (a wrong type byte?): "
            "not used for names or units")


def point_labels(point_params: Mapping[str, Any], used: int,
            numeric: list[str] | None = None) -> list[str]:
    """POINT:LABELS, then LABELS2, LABELS3, ... (files with > 255 points), ``used`` of
    them ("" past the last; ANALOG's the same way); label parameters stored as numbers
    are skipped and named in ``numeric`` (:func:`_text`)."""
    numeric = [] if numeric is None else numeric
    labels = _text(point_params, "LABELS", numeric)
    k = 2
    while f"LABELS{k}" in point_params and len(labels) < used:
        labels += _text(point_params, f"LABELS{k}", numeric)
        k += 1
    labels = [s.strip() for s in labels[:used]]
    labels += [""] * (used - len(labels))
    return labels


def motion_from_points(points: NDArray[Any], residuals: NDArray[Any],
                       point_params: Mapping[str, Any], rate: float, *, subject: str = "",
                       source: str = "", extra: Mapping[str, str] | None = None) -> Motion:
    """Build a Motion from C3D point data and the POINT group.

    Parameters
    ----------
    points : ndarray, shape (frames, points, 3)
    residuals : ndarray, shape (frames, points)
        Residual values; negative marks a gap. A NaN residual (a float file's fourth
        word NaN) does not: ezc3d reads it as 0, and both readers keep the sample and its
        coordinates (nothing is dropped; the word itself is kept in the C3D archive).
    point_params : dict
        ``{"LABELS": [...], "UNITS": [...], ...}`` (stripped strings).
    rate : float
        POINT:RATE (or the header rate).
    subject, source : str, optional
        Metadata ``subject`` and ``source``, when not empty.
    extra : dict of str to str, optional
        More metadata.
    """
    used = points.shape[1]
    if used == 0:       # "inconsistent data: a motion needs at least one marker" (QA, stop 52)
        raise InputFormatError("C3D: the file holds no points (POINT:USED 0): MPZ codes "
                               "marker trajectories, and a C3D of analog channels alone "
                               "(force plates, EMG) is not supported")
    numeric: list[str] = []
    names, renamed = unique_names(point_labels(point_params, used, numeric))
    units_raw = (_text(point_params, "UNITS", numeric) or [""])[0].strip().lower()
    units = _UNITS.get(units_raw, "")
    pos = np.asarray(points, dtype=np.float64)
    res = np.asarray(residuals, dtype=np.float64)
    valid = finite_samples(pos) & ~(res < 0) & ~np.all(pos == 0, axis=2)
    pos = pos.copy()
    pos[~valid] = np.nan
    meta = {"format": "c3d"}
    if source:
        meta["source"] = source
    if subject:
        meta["subject"] = subject
    if units_raw and not units:
        meta["units_in_file"] = units_raw
    if renamed:
        meta["renamed_points"] = "; ".join(renamed)
    meta.update(extra or {})
    if numeric:
        meta["warning"] = _joined(meta.get("warning"), _numeric_text(numeric))
    return Motion(pos, names, float(rate), units, valid, meta)


def _subject(params: Mapping[str, Any]) -> str:
    subj = params.get("SUBJECTS", {})
    names = subj.get("NAMES") if isinstance(subj, dict) else None
    if names is None:
        return ""
    return ", ".join(n for n in (str(x).strip() for x in names) if n)


def archive_subject(a: C3DArchive) -> str:
    """The subject that the C3D of archive ``a`` gives when read (SUBJECTS:NAMES, as
    :func:`read_c3d` takes it), '' when it names none."""
    return _subject(c3dbin.record_params(a.records))


def c3d_first_frame(motion: Motion) -> int:
    """The first frame number a C3D of ``motion`` without an archive gets: the source's
    (:func:`mpz.io._common.start_frame`), or 1 when that is below 1, where C3D does not
    count (header word 4 is 1-based; :func:`mpz.io.check_writable` says so)."""
    return max(1, start_frame(motion))


def _ezc3d_taken(c: Any) -> dict[str, Any]:
    """What :func:`_from_ezc3d` reads of the ``ezc3d.c3d`` object ``c``, in the same
    nesting: the header's point rate, the groups POINT and SUBJECTS, the points and their
    residuals (numpy arrays that own their data). The caller then lets ``c`` go before
    the points are converted: with it goes ezc3d's C++ copy of every point (about 160
    bytes a point-frame, 1.4 GB of a 30-minute capture of 41 markers) and the arrays the
    reader does not use (camera masks, analogs), which stayed held while the positions
    were copied, and made the peak of reading that capture (docs/corpus.md, "Memory per
    worker")."""
    params = c["parameters"]
    meta = c["data"]["meta_points"]
    return {"parameters": {k: params[k] for k in ("POINT", "SUBJECTS") if k in params},
            "data": {"points": c["data"]["points"],
                     "meta_points": {"residuals": meta["residuals"]}},
            "header": {"points": {"frame_rate": c["header"]["points"]["frame_rate"]}}}


def _from_ezc3d(c: Any, source: str, extra: Mapping[str, str], declared: int,
                data: bytes) -> Motion:
    """A Motion from an ``ezc3d.c3d`` object of the C3D bytes ``data``, or from what
    :func:`_ezc3d_taken` takes of one; ``declared`` is their frame count
    (:func:`mpz.io.c3dbin.declared_frames`)."""
    params = c["parameters"]
    got = np.asarray(c["data"]["points"]).shape[2]
    if got < declared:  # ezc3d silently returns the frames that fit
        # ezc3d stops at POINT:FRAMES and sizes a frame from the parameters (ANALOG:RATE /
        # POINT:RATE samples), the C3D user guide and c3dbin from the header (words 4-5,
        # 10): a whole file whose two disagree was refused as truncated (a C3D QA run of
        # stop 52). c3dbin reads it, and the warning gives the cause frames_missing finds
        short = c3dbin.frames_missing(data, declared, got)
        why = ("its parameters size a frame otherwise than the header"
               if short.message.startswith("C3D: truncated") else
               short.message.removeprefix("C3D: "))
        try:
            m = motion_from_c3d_bytes(data, source=source, extra={**extra, "warning": _joined(
                extra.get("warning"), f"ezc3d found {got} of the {declared} frames the "
                f"header declares ({why}); read with mpz.io.c3dbin, which follows the "
                "header")})
        except InputFormatError:
            raise short from None
        if m.n_frames == declared:
            return m
        raise short
    point = {k: v["value"] for k, v in params["POINT"].items() if k != "__METADATA__"}
    pts = np.asarray(c["data"]["points"])[:3].transpose(2, 1, 0)
    res = np.asarray(c["data"]["meta_points"]["residuals"])[0].T
    # POINT:RATE as stored (float32 widened, not rounded); header rate otherwise
    rate_v = point.get("RATE")
    rate = float(rate_v[0]) if rate_v is not None and len(rate_v) else float(
        c["header"]["points"]["frame_rate"])
    _check_rate(rate, data)
    plist = {k: (list(v) if not isinstance(v, np.ndarray) or v.dtype.kind in "OUS" else v)
             for k, v in point.items()}
    subject = _subject({"SUBJECTS": {k: v["value"] for k, v in params["SUBJECTS"].items()
                                     if k != "__METADATA__"}} if "SUBJECTS" in params else {})
    return motion_from_points(pts, res, plist, rate, subject=subject, source=source,
                              extra={"reader": "ezc3d", **extra})


def motion_from_c3d_bytes(data: bytes, *, source: str = "",
                          extra: Mapping[str, str] | None = None,
                          parsed: list[c3dbin.C3DData] | None = None) -> Motion:
    """Parse C3D bytes with the pure-numpy reader into a Motion; the parse is appended to
    ``parsed`` when given, so that the archive (:func:`c3d_from_bytes`) is made from it,
    not from a second parse of the same bytes, which held a second copy of every point
    (their float64 values, residual and fourth words: 1.5 times the positions) beside the
    first's Motion."""
    d = c3dbin.parse_c3d(data)
    if parsed is not None:
        parsed.append(d)
    return _motion_from_data(d, data, source=source, extra=extra)


def _motion_from_data(d: c3dbin.C3DData, data: bytes, *, source: str = "",
                      extra: Mapping[str, str] | None = None) -> Motion:
    """:func:`motion_from_c3d_bytes` of ``d``, the parsed ``data``."""
    point = d.params.get("POINT", {})
    rate = c3dbin.param_number(d.params, "POINT", "RATE", d.header_rate)
    _check_rate(rate, data)
    proc = {c3dbin.PROC_INTEL: "intel", c3dbin.PROC_DEC: "dec",
            c3dbin.PROC_MIPS: "mips"}[d.processor]
    meta = {"reader": "mpz.io.c3dbin", "processor": proc, **(extra or {})}
    for note in d.warnings:
        meta["warning"] = _joined(meta.get("warning"), note)
    return motion_from_points(d.points, d.residual_words, point, rate,
                              subject=_subject(d.params), source=source, extra=meta)


#: the slowest frame rate read (Hz): one frame in about 11.6 days
MIN_RATE = 1e-6


def _check_rate(rate: float, data: bytes) -> None:
    """Refuse a frame rate that is not a normal positive float32 of at least
    :data:`MIN_RATE` Hz (NaN, infinite, negative, zero, subnormal: what a float read
    in the wrong byte order or float format gives), naming the processor byte and the rate
    each other processor type would give.

    Raises
    ------
    InputFormatError
        For such a rate.
    """
    if math.isfinite(rate) and MIN_RATE <= rate <= c3dbin.F32_MAX:
        return
    raise InputFormatError(f"C3D: frame rate {rate!r} Hz is not a plausible rate"
                           f"{c3dbin.processor_hint(data)}")


@reader
def read_c3d(path: StrPath) -> Motion:
    """Read a C3D file: its markers, and everything else in ``extras["c3d"]``.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    Motion
        The markers: names from POINT:LABELS (duplicates get ``#2``..., empty ones
        ``_unnamed_<i>``; the labels themselves are kept exactly in the archive), rate
        from POINT:RATE as stored, units from POINT:UNITS (``mm``/``cm``/``m``,
        otherwise ``""``). Metadata: ``source``, ``format``, ``reader``, ``subject`` (if
        any), ``renamed_points``, ``model_outputs`` and ``warning`` when applicable.
        ``extras["c3d"]``: the :class:`mpz.c3darchive.C3DArchive` (module docstring).

    Raises
    ------
    InputFormatError
        If the file is missing or is not a readable C3D file.
    """
    with open_input(path) as fh:
        c3dbin.check_key(fh.read(2))     # before the rest is read
        return c3d_from_bytes(path, read_open(fh, path), reopen=reopen_name(fh, path))


@reader
def c3d_from_bytes(path: StrPath, data: bytes, *, reopen: StrPath | None = None) -> Motion:
    """:func:`read_c3d` of the file's bytes, read once by :func:`mpz.io.read`: ``path``
    names the file in messages and ``metadata["source"]``; ezc3d, which reads only from
    a file, opens ``reopen`` (default ``path``; :func:`mpz.io.read` gives it the open
    file, :func:`reopen_name`, so that both readers see the same bytes)."""
    path = os.fspath(path)
    parsed: list[c3dbin.C3DData] = []           # the numpy reader's parse, when it read
    full = _read_points(path, data, os.fspath(path if reopen is None else reopen), parsed)
    try:
        d = parsed.pop() if parsed else c3dbin.parse_c3d(data)
    except InputFormatError as exc:
        full.metadata["warning"] = _joined(full.metadata.get("warning"),
                                           f"C3D archive not kept: {exc}")
        return full
    unread = c3dbin.frames_unread(data, full.n_frames)
    for lost in [*_values_at_gaps(full, d), *([c3dbin.DEC_ROUNDED] if d.dec_rounded else []),
                 *([unread] if unread else [])]:
        full.metadata["warning"] = _joined(full.metadata.get("warning"), lost)
    return split_archive(full, d)


def _values_at_gaps(full: Motion, d: c3dbin.C3DData) -> list[str]:
    """What of the points' values at gaps the archive cannot give back, from the words as
    stored (ezc3d reads a negative residual's coordinates as NaN): coordinates at a gap
    (a gap keeps none, spec §4.5), and gaps that the C3D written back will show as a point
    at the origin (§6.9 writes (0, 0, 0) and the fourth word as stored, so a NaN
    coordinate beside a residual >= 0 becomes one). A QA of stop 48: both went without a
    word."""
    if d.points.shape[:2] != full.valid.shape:
        return []                       # split_archive says the archive is not kept
    out = [values_at_gaps(d.points, ~full.valid, full.names,
                          "with a negative residual or a NaN coordinate")]
    origin = int((~finite_samples(d.points) & (d.residual_words >= 0)).sum())
    if origin:
        out.append(f"{origin} sample{'s' * (origin != 1)} with a NaN coordinate and a "
                   "residual >= 0 will be written back as (0, 0, 0) with that residual, "
                   "which C3D readers that do not take the origin for a gap read as a point")
    return [text for text in out if text]


def _joined(old: str | None, new: str) -> str:
    return new if not old else f"{old}; {new}"


def split_archive(full: Motion, d: c3dbin.C3DData) -> Motion:
    """The markers of ``full`` (every C3D point) with the rest of the file in
    ``extras["c3d"]``: model outputs leave the marker set (spec §4.13.3)."""
    from mpz.c3darchive import MODEL_PARAMETERS, C3DArchive, section_fault, stored_parameters
    F, P = full.n_frames, full.n_markers
    if d.points.shape[:2] != (F, P) or d.point_words.shape != (F, P):
        full.metadata["warning"] = _joined(full.metadata.get("warning"), (
            f"C3D archive not kept: the numpy reader sees {d.points.shape[1]} points x "
            f"{d.points.shape[0]} frames, ezc3d {P} x {F}"))
        return full
    fault = section_fault(stored_parameters(list(d.records)))
    if fault is not None:          # a C3D may, MPZ's cprm (§4.13.2, §8) may not
        full.metadata["warning"] = _joined(full.metadata.get("warning"), (
            f"C3D archive not kept (its analog data, events and parameters are dropped): "
            f"MPZ's cprm chunk cannot hold its parameter section: {fault}"))
        return full
    point = d.params.get("POINT", {})
    labels = point_labels(point, P)
    kinds: list[int | None] = [None] * P
    for kind, key in enumerate(MODEL_PARAMETERS):
        value = point.get(key)
        listed = {str(v).strip() for v in value} if isinstance(value, list) else set()
        for p in range(P):
            if kinds[p] is None and labels[p] and labels[p] in listed:
                kinds[p] = kind
    marker = [p for p in range(P) if kinds[p] is None]
    model = [p for p in range(P) if kinds[p] is not None]
    meta = dict(full.metadata)
    if not marker:      # a Motion needs one marker: keep the model outputs as markers
        meta["warning"] = _joined(meta.get("warning"), "every point is a model output; "
                                  "they are kept as markers (under the marker bound)")
        marker, model = list(range(P)), []
    M = len(marker)
    slots = [0] * P
    for i, p in enumerate(marker):
        slots[p] = i
    for j, p in enumerate(model):
        slots[p] = M + j
    names, renamed = unique_names([labels[p] for p in marker])
    meta.pop("renamed_points", None)
    if renamed:
        meta["renamed_points"] = "; ".join(renamed)
    if model:
        meta["model_outputs"] = str(len(model))
    vals = d.points[:, model].astype(np.float64)
    ok = finite_samples(vals) & (d.residual_words[:, model] >= 0)
    vals[~ok] = np.nan
    storage = 1 if d.float_storage else 0
    archive = C3DArchive(d.processor, d.header_block, list(d.records), slots, d.point_words,
                         storage, vals, ok, [int(kinds[p] or 0) for p in model], d.analog,
                         d.analog_samples, storage, layer=(tuple(names), full.units, full.rate))
    # the subject as the archive gives it (SUBJECTS:NAMES as UTF-8, else Latin-1, as the
    # names are read): ezc3d gave the Latin-1 byte of 'Jos\xe9' as a lone surrogate, so
    # the subject was escaped ('Jos\\xe9'), said to be "a file name" that is not UTF-8,
    # and differed from the archive's, so a C3D decoded from it noted the subject as not
    # written although its SUBJECTS:NAMES was written as stored (a C3D QA run)
    subject = archive_subject(archive)
    if subject:
        meta["subject"] = subject
    else:
        meta.pop("subject", None)
    scales = _point_scales(archive)
    if len(set(scales)) > 1:
        # the readers take the last, spec §6.9's writer the first (a C3D QA run of stop 52)
        meta["warning"] = _joined(meta.get("warning"), (
            f"POINT:SCALE is given {len(scales)} times, with other values "
            f"({', '.join(f'{v:g}' for v in scales)}): the points are read with the last, "
            "as ezc3d reads them, and the decoded C3D is written with the first (spec §6.9), "
            "so its residuals are scaled by the first, and an int16 source may not stay on "
            "its grid"))
    for elements in _point_scale_elements(archive):
        if len(set(elements)) > 1:
            # ezc3d 1.7 scales point p by element p; the C3D user guide has one scale (a
            # clean-room review of stop 54)
            meta["warning"] = _joined(meta.get("warning"), (
                f"POINT:SCALE holds {len(elements)} values that differ "
                f"({', '.join(f'{v:g}' for v in elements[:8])}"
                f"{', ...' if len(elements) > 8 else ''}), where the C3D user guide has "
                "one scale: " + (
                    "ezc3d, which read this file, scales point p by element p (mpz's own "
                    "reader, for files ezc3d cannot read, takes the first)"
                    if meta.get("reader") == "ezc3d" else
                    "mpz's own reader, which read this file, scales every point by the "
                    "first (ezc3d scales point p by element p)")
                + "; a C3D written from it stores float32 points (spec §6.9), which need "
                "no scale"))
            break
    return Motion(full.positions[:, marker], names, full.rate, full.units,
                  full.valid[:, marker], meta, extras={"c3d": archive})


def _point_scales(a: C3DArchive) -> list[float]:
    """The values of every POINT:SCALE record of ``a`` (float32, at least one element):
    each one's first element."""
    return [e[0] for e in _point_scale_elements(a)]


def _point_scale_elements(a: C3DArchive) -> list[list[float]]:
    """The elements of every POINT:SCALE record of ``a`` that is a float32 of at least one
    element, one list per record."""
    records = [a.records[i] for i in c3dbin.named(a.records, b"POINT", b"SCALE")]
    return [np.frombuffer(r.data, "<f4", len(r.data) // 4).astype(float).tolist()
            for r in records if r.type == 4 and len(r.data) >= 4]


def archive_describes(a: C3DArchive, markers: int) -> tuple[list[str], str, float]:
    """The marker names, units and rate that the C3D of archive ``a`` gives its ``markers``
    markers when read (:func:`read_c3d`, :func:`split_archive`): POINT:LABELS of the points
    in marker slots, made unique; POINT:UNITS; POINT:RATE, or the header's rate."""
    params = c3dbin.record_params(a.records)
    point = params.get("POINT", {})
    P = len(a.slots)
    labels = point_labels(point, P)
    order = sorted((s, p) for p, s in enumerate(a.slots) if s < markers)
    names, _ = unique_names([labels[p] for _, p in order])
    units = archive_units(a)
    with np.errstate(invalid="ignore"):
        header_rate = float(np.frombuffer(a.header, "<f4", 1, 20)[0])
    rate = c3dbin.param_number(params, "POINT", "RATE", header_rate)
    return names, units, rate


def archive_units(a: C3DArchive) -> str:
    """The units the C3D of archive ``a`` gives its markers when read: POINT:UNITS, if it
    names one of mm, cm and m (without case and spaces around it), else ''."""
    point = c3dbin.record_params(a.records).get("POINT", {})
    return _UNITS.get((_text(point, "UNITS", []) or [""])[0].strip().lower(), "")


#: What ezc3d allocates to read a C3D, per byte of its data section, as an upper bound:
#: about 200 bytes a point-frame (16 bytes in float storage, 8 in int16) and 17 an analog
#: value (4 or 2 bytes), measured on the real files (docs/io-notes.md)
EZC3D_BYTES_PER_BYTE = 26
EZC3D_BYTES_FIXED = 32 << 20
#: What :func:`write_c3d` allocates through ezc3d per point-frame, as an upper bound: the
#: numpy arrays it is given (96 bytes) and ezc3d's own copy; 257 measured on 1.64 million
EZC3D_WRITE_BYTES = 320

#: The address-space limits a failed allocation meets, with their /proc/self/status line
_LIMITS = (("RLIMIT_AS", "VmSize", "ulimit -v"), ("RLIMIT_DATA", "VmData", "ulimit -d"))


def memory_short(need: int) -> str | None:
    """Why ``need`` more bytes would not fit under this process's address-space limits
    (``ulimit -v``, ``ulimit -d``), else None; None too where the limits or the usage cannot
    be read (not Linux).

    ezc3d cannot be asked: where its C++ allocation fails outside the calls its Python
    wrapper translates, ``std::bad_alloc`` terminates the process (SIGABRT), so a read
    that may not fit is given to :mod:`mpz.io.c3dbin`, whose numpy allocations fail with
    MemoryError (the command line's "out of memory", exit 3).
    """
    try:
        import resource
    except ImportError:
        return None
    limits = [(soft, field, flag) for name, field, flag in _LIMITS
              if (soft := resource.getrlimit(getattr(resource, name))[0])
              != resource.RLIM_INFINITY]
    if not limits:                  # the usual case: no /proc read on every C3D
        return None
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            status = dict(line.split(":", 1) for line in f if ":" in line)
    except (OSError, ValueError):
        return None
    for soft, field, flag in limits:
        if field not in status:
            continue
        used = int(status[field].split()[0]) * 1024
        if used + need > soft:
            return (f"it would need about {need >> 20} MB beyond the {used >> 20} MB in "
                    f"use, and the limit ({flag}) is {soft >> 20} MB")
    return None


def _first_line(exc: BaseException) -> str:
    """The first line of an ezc3d error ("" for none)."""
    return str(exc).splitlines()[0] if str(exc) else ""


def _first_sentence(exc: BaseException) -> str:
    """The first sentence of an ezc3d error: "The format is not standard", without its
    advice to set ``ignoreBadFormatting``, which the reader decides."""
    return _first_line(exc).split(". ")[0]


#: the oldest ezc3d the reader hands files to: c3dbin's hazard rules are 1.7.2's, and 1.5.16
#: ends the process on a file 1.7.2 reads (pyproject.toml, .ci/lowest.txt)
EZC3D_OLDEST = (1, 7, 2)


@functools.cache
def ezc3d_too_old() -> str | None:
    """The installed ezc3d's version when it is older than :data:`EZC3D_OLDEST` (pip
    refuses it, but conda, ``--no-deps`` or a system package may not); else None, also
    when its version is not known. Such an ezc3d is not used to read: the review of stop
    62 (a crash is never an answer)."""
    from importlib import metadata
    import re
    version: object
    try:
        version = metadata.version("ezc3d")
    except metadata.PackageNotFoundError:
        # conda-forge's CMake install has no metadata, only its _version.py (the review
        # of stop 62)
        import ezc3d
        version = getattr(ezc3d, "__version__", None)
    if not isinstance(version, str):
        return None
    parts = re.match(r"(\d+)\.(\d+)(?:\.(\d+))?", version)
    if parts is None:
        return None
    found = tuple(int(p or 0) for p in parts.groups())
    return version if found < EZC3D_OLDEST else None


def _read_points(path: str, data: bytes, reopen: str,
                 parsed: list[c3dbin.C3DData] | None = None) -> Motion:
    """Every point of the C3D file as a Motion: ezc3d (reading the file ``reopen``, which
    holds ``data``), or the numpy reader it refuses; the numpy reader's parse of ``data``
    is appended to ``parsed`` (:func:`motion_from_c3d_bytes`)."""
    import ezc3d

    source = os.path.basename(path)
    head = data[:c3dbin.BLOCK]
    if len(head) < c3dbin.BLOCK or head[1] != c3dbin.C3D_KEY:
        # not a C3D file; let the numpy reader produce the precise error
        return motion_from_c3d_bytes(data, source=source, parsed=parsed)
    # the frames the file declares (header words 4-5, or the frame parameters when the
    # header cannot say: more than 65535 frames); ezc3d itself rewrites its header to
    # the frames it found, so truncation must be checked here
    checks = c3dbin.reader_checks(data)
    declared, note = checks.declared, checks.note
    if checks.hazard is not None:
        fault = c3dbin.hazard_is_fault(checks.hazard)     # else ezc3d's own fragility
        return motion_from_c3d_bytes(data, source=source, parsed=parsed, extra={
            "warning" if fault else "reader_note":
                f"not read with ezc3d: {checks.hazard}; read with mpz.io.c3dbin"})
    if checks.conflict is not None:    # c3dbin's warnings say what the conflict is
        # ezc3d 1.7.2 reads a float file whose POINT:SCALE is positive as int16 (stop 64),
        # and moved Sample_Jump2 with a header scale of 0 by 2 m (stop 38)
        return motion_from_c3d_bytes(data, source=source, parsed=parsed, extra={
            "warning": "not read with ezc3d, which reads some such files as other numbers; "
                       "read with mpz.io.c3dbin"})
    if not is_utf8(reopen):        # ezc3d takes a str path to UTF-8: a TypeError of SWIG
        return motion_from_c3d_bytes(data, source=source, parsed=parsed, extra={
            "reader_note": "not read with ezc3d, which cannot open a file whose name is not "
                           "UTF-8; read with mpz.io.c3dbin"})
    if checks.data_start != checks.word9:
        # ezc3d reads from header word 9: the data is elsewhere (c3dbin.data_start says why)
        return motion_from_c3d_bytes(data, source=source, parsed=parsed, extra={
            "warning": "not read with ezc3d, which reads from the header's data start; "
                       "read with mpz.io.c3dbin"})
    if checks.case is not None:
        return motion_from_c3d_bytes(data, source=source, parsed=parsed, extra={
            "reader_note": f"not read with ezc3d, which compares names exactly and would not "
                           f"find {checks.case} (C3D compares names without case); read "
                           "with mpz.io.c3dbin"})
    short = memory_short(EZC3D_BYTES_PER_BYTE * (len(data) - checks.data_start)
                         + EZC3D_BYTES_FIXED)
    if short is not None:
        return motion_from_c3d_bytes(data, source=source, parsed=parsed, extra={
            "reader_note": f"not read with ezc3d, which aborts the process when an "
                           f"allocation fails: {short}; read with mpz.io.c3dbin"})
    old = ezc3d_too_old()
    if old is not None:          # the checks above hold; ezc3d itself is not trusted
        extra = {"reader_note": f"not read with ezc3d {old}, older than "
                                f"{'.'.join(map(str, EZC3D_OLDEST))}, which ends the process "
                                "on some files that newer releases read; read with "
                                "mpz.io.c3dbin"}
        return motion_from_c3d_bytes(data, source=source, parsed=parsed,
                                     extra=extra if note is None else {**extra, "warning": note})
    # only ezc3d's own refusals are caught, not what our code does with its result
    first_error: OSError | RuntimeError | ValueError
    try:
        c = ezc3d.c3d(reopen)
    except (RuntimeError, ValueError) as exc:  # "MIPS processor type not supported",
        first_error = exc                      # "SCALE parameter is not a FLOAT"
    except OSError as exc:  # "The format is not standard ..."
        lenient = c3dbin.ezc3d_hazard(data, ignore_bad_formatting=True)
        if lenient is not None:
            # ezc3d then reads on where a record ends, not where the section says the next
            # begins: what it reads there can crash it or take gigabytes (stop 57)
            return motion_from_c3d_bytes(data, source=source, parsed=parsed, extra={
                "warning": _joined(note, f"ezc3d refused the file ({type(exc).__name__}: "
                                         f"{_first_sentence(exc)}), and told to ignore "
                                         f"that it would meet {lenient}; read with "
                                         "mpz.io.c3dbin")})
        warning = _joined(note, f"non-standard C3D read with ignore_bad_formatting: {exc}")
        try:
            c = ezc3d.c3d(reopen, ignore_bad_formatting=True)
        except (OSError, RuntimeError, ValueError) as exc2:
            first_error = exc2
        else:
            taken = _ezc3d_taken(c)
            del c                   # ezc3d's own copy of the points (_ezc3d_taken)
            return _from_ezc3d(taken, source, {"warning": warning}, declared, data)
    else:
        taken = _ezc3d_taken(c)
        del c                       # ezc3d's own copy of the points (_ezc3d_taken)
        return _from_ezc3d(taken, source, {} if note is None else {"warning": note},
                           declared, data)
    # a MIPS file is valid C3D that ezc3d does not read (a note); any other refusal is
    # about the file (Facial-Sing: a parameter type ezc3d does not know): a warning
    return motion_from_c3d_bytes(data, source=source, parsed=parsed, extra={
        "reader_note" if c3dbin.is_mips(data) else "warning":
            f"ezc3d refused the file ({type(first_error).__name__}: "
            f"{_first_line(first_error)}); "
            "read with mpz.io.c3dbin"})


def write_c3d(motion: Motion, path: StrPath) -> list[str]:
    """Write a Motion as a C3D file; return how mpz's own reader reads the file written
    otherwise than ``motion`` (:func:`read_back`; always empty for a file written
    through ezc3d).

    With ``extras["c3d"]`` (a motion read from, or decoded from, a C3D): the file
    it came from (:func:`archive_bytes`). Without: a float C3D of the points
    through ezc3d, gaps with residual -1 and NaN coordinates; names, rate and
    units in POINT:LABELS, POINT:RATE and POINT:UNITS. ezc3d writes at most 65535
    frames that it reads back, and numbers them from 1, so a longer motion without an
    archive, or one whose source counted its frames from another number (a TRC's first
    Frame#, :func:`mpz.io._common.start_frame`), goes through our own writer instead
    (:func:`long_bytes`); so does one that ezc3d may not have the address space for
    (:func:`memory_short`: its failed allocation would abort the process), and every
    motion when the installed ezc3d is older than :data:`EZC3D_OLDEST`
    (:func:`ezc3d_too_old`).

    Parameters
    ----------
    motion : Motion
    path : str or os.PathLike

    Returns
    -------
    list of str
        What the file reads back otherwise (its header or parameters as an archive made
        by hand holds them, spec §6.9), each a phrase; the file is written all the same,
        since it holds everything the archive holds.
    """
    import ezc3d

    path = os.fspath(path)
    if motion.extras.get("c3d") is not None or motion.n_frames > c3dbin.HEADER_MAX_FRAME \
            or c3d_first_frame(motion) != 1 or memory_short(
                EZC3D_WRITE_BYTES * motion.n_frames * motion.n_markers + EZC3D_BYTES_FIXED) \
            or _many_parameter_blocks(motion) or ezc3d_too_old() is not None:
        blob = archive_bytes(motion) if motion.extras.get("c3d") is not None else \
            long_bytes(motion)
        with open(path, "wb") as fh:
            fh.write(blob)
        return read_back(motion, blob)
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = np.array([motion.rate])
    c["parameters"]["POINT"]["LABELS"]["value"] = list(motion.names)
    c.add_parameter("POINT", "UNITS", [motion.units])
    pts = np.ones((4, motion.n_markers, motion.n_frames))
    pts[:3] = motion.as_nan().transpose(2, 1, 0)
    c["data"]["points"] = pts
    res = np.zeros((1, motion.n_markers, motion.n_frames))
    res[0][~motion.valid.T] = -1.0
    c["data"]["meta_points"]["residuals"] = res
    c["data"]["meta_points"]["camera_masks"] = np.zeros((7, motion.n_markers, motion.n_frames),
                                                        dtype=bool)
    if not is_utf8(path):
        # ezc3d takes a str path to UTF-8 only (a SWIG TypeError): write under a name it
        # takes, then copy
        with tempfile.TemporaryDirectory(prefix="mpz-c3d-") as folder:
            tmp = os.path.join(folder, "motion.c3d")
            c.write(tmp)
            with open(tmp, "rb") as src, open(path, "wb") as dst:
                shutil.copyfileobj(src, dst)
        return []
    if path.endswith(".c3d"):
        c.write(path)
        return []
    # ezc3d appends ".c3d" to any other name: write a temporary ".c3d" beside, then rename
    from mpz.api import atomic_output
    with atomic_output(path, force=True, suffix=".c3d") as tmp:
        c.write(tmp)
    return []


#: the frames of a C3D just written whose gaps and positions :func:`read_back` compares
READ_BACK_FRAMES = 2


def read_back(motion: Motion, blob: bytes) -> list[str]:
    """How mpz's C3D reader (:mod:`mpz.io.c3dbin`) reads ``blob``, the C3D written of
    ``motion``, otherwise than ``motion``: its refusal, or the frames, the markers' names,
    units and rate, the first frame number, the model outputs, the analog channels, and
    the gaps and positions of the first :data:`READ_BACK_FRAMES` frames, each a phrase;
    empty when they agree. The header and parameters are read whole, the data of the
    first frames only: the cost does not grow with the file, and what can go wrong is
    in the header and the parameters, which say how every frame is read.

    Spec §6.9 writes an archive's header and parameters as stored, and a valid archive
    made by hand may hold ones that contradict its points (group ids, a renamed
    parameter, a header frame range that disagrees with the frames, a last frame of 65535
    without TRIAL): such
    files were written with exit 0 and read back with other values, or not at all (a
    fuzzing QA run of stop 54). What was written is not changed, since it holds all the
    archive does; the writers say what a reader finds.

    Differences the writers already state are not repeated: a rate that float32 rounds,
    units no C3D reader knows, and a valid sample at exactly (0, 0, 0), which C3D readers
    take for a gap (:func:`mpz.io.check_writable`, :func:`round_trip_warnings`).
    """
    from mpz.c3darchive import C3DArchive
    try:
        d = c3dbin.parse_c3d(blob, frames=READ_BACK_FRAMES)
        got = _motion_from_data(d, blob)
        got = split_archive(got, d)
    except InputFormatError as exc:
        return [f"it does not read: {exc}"]
    a = motion.extras.get("c3d")
    out = []
    if d.frames_in_file != motion.n_frames:
        out.append(f"it holds {d.frames_in_file} frames, not {motion.n_frames}")
    same_names = sorted(got.names) == sorted(motion.names)
    if not same_names:
        extra = [n for n in got.names if n not in motion.names]
        gone = [n for n in motion.names if n not in got.names]
        out.append(f"its markers are {got.n_markers}, not {motion.n_markers}" if
                   got.n_markers != motion.n_markers else "its markers are named otherwise")
        if gone:
            out[-1] += f": {', '.join(repr(n) for n in gone[:3])} missing"
        if extra:
            out[-1] += f"{',' if gone else ':'} {', '.join(repr(n) for n in extra[:3])} new"
        if not gone and not extra:      # the same names, some of them repeated otherwise
            out[-1] += f": {list(got.names)[:5]!r}"
    known = motion.units in _UNITS.values() and \
        not (isinstance(a, C3DArchive) and archive_units(a) == "")
    if known and got.units != motion.units:
        out.append(f"its units are {got.units or 'unknown'}, not {motion.units}")
    if np.float32(got.rate) != np.float32(motion.rate):
        out.append(f"its rate is {float(got.rate)!r} Hz, not "
                   f"{float(np.float32(motion.rate))!r}")
    # an archive's own first frame, not a trc.FirstFrame the metadata may carry, which the
    # archive's C3D does not write (a review of stop 55: a false warning)
    first = a.first_frame() if isinstance(a, C3DArchive) else c3d_first_frame(motion)
    if d.first_frame != first:
        out.append(f"its first frame is {d.first_frame}, not {first}")
    b = got.extras.get("c3d")
    if isinstance(a, C3DArchive) and isinstance(b, C3DArchive):
        J, K = a.models.shape[1], b.models.shape[1]
        if J != K:
            out.append(f"it holds {K} model outputs, not {J}")
        if (a.channels, a.analog_samples if a.channels else 0) != \
                (b.channels, b.analog_samples if b.channels else 0):
            out.append(f"it holds {b.channels} analog channel{'s' * (b.channels != 1)} of "
                       f"{b.analog_samples} sample{'s' * (b.analog_samples != 1)} a frame, "
                       f"not {a.channels} of {a.analog_samples}")
    # the gaps and positions only when the rest agrees: they are read as the rest says
    return out if out or not same_names else _head_differs(motion, got)


def _head_differs(motion: Motion, got: Motion) -> list[str]:
    """How the first frames of ``got`` (``motion``'s C3D read back, the same marker names)
    differ from ``motion``'s: gaps, or a position beyond float32's rounding (int16 points
    lie on their grid exactly, :func:`_points_to_write`). A valid sample at exactly the
    origin is a gap in C3D (:func:`read_back`)."""
    n = got.n_frames
    at = {name: i for i, name in enumerate(motion.names)}
    order = [at[name] for name in got.names]
    pos = motion.positions[:n, order]
    valid = motion.valid[:n, order] & ~(pos == 0.0).all(axis=2)
    if not np.array_equal(valid, got.valid):
        f, m = (int(i) for i in np.argwhere(valid != got.valid)[0])
        return [f"marker {got.names[m]!r} in frame {f} is {'a gap' if valid[f, m] else 'a point'}"
                f", not {'a point' if valid[f, m] else 'a gap'}"]
    want = np.where(valid[..., None], pos, 0.0)
    have = np.where(valid[..., None], got.positions, 0.0)
    with np.errstate(over="ignore", invalid="ignore"):     # float32's rounding, subnormals
        off = ~(np.abs(have - want) <= 2.0 ** -22 * np.abs(want) + 2.0 ** -149)   # included
    if off.any():
        f, m, k = (int(i) for i in np.argwhere(off)[0])
        return [f"marker {got.names[m]!r} in frame {f} reads back at "
                f"{float(have[f, m, k])!r}, not {float(want[f, m, k])!r} ({'xyz'[k]})"]
    return []


def plain_blocks(motion: Motion) -> int:
    """The 512-byte blocks of the parameter section of a C3D of ``motion``'s bare points
    (:func:`long_bytes`' records, :func:`mpz.io.c3dbin.plain_parts`), which a C3D header
    counts up to :data:`mpz.io.c3dbin.MAX_PARAM_BLOCKS`. Raises InputFormatError as
    plain_parts does (too many points, a name too long)."""
    _, records = c3dbin.plain_parts(list(motion.names), 1.0, motion.units, motion.n_frames,
                                    first=c3d_first_frame(motion))
    return c3dbin.param_blocks(records)


def _many_parameter_blocks(motion: Motion) -> bool:
    """True when the section (:func:`plain_blocks`) takes more than a quarter of the
    blocks a C3D header counts: ezc3d writes that count modulo 256 (a QA run of stop 50),
    and its section is not exactly ours, so such a file is written by :func:`long_bytes`,
    which refuses what does not fit. Names that are not text are left to the writers'
    own refusal."""
    if not all(is_utf8(n) for n in motion.names):
        return False
    try:
        return plain_blocks(motion) > c3dbin.MAX_PARAM_BLOCKS // 4
    except InputFormatError:
        return True                    # long_bytes says why it cannot be written


def long_bytes(motion: Motion) -> bytes:
    """A float C3D of the points of a motion without an archive, for any frame count.

    Frames numbered from the source's first (:func:`mpz.io._common.start_frame`, 1 when
    none is known); above 65535 frames the header's last frame is 65535 and the
    count is in POINT:LONG_FRAMES and TRIAL:ACTUAL_START_FIELD/ACTUAL_END_FIELD, as the
    C3D user guide asks (:func:`mpz.io.c3dbin.plain_parts`). Gaps: coordinates 0 and
    fourth word -1 (valid samples 0).

    Raises
    ------
    InputFormatError
        For names or a point count a C3D cannot hold.
    """
    header, records = c3dbin.plain_parts(list(motion.names), motion.rate, motion.units,
                                         motion.n_frames, first=c3d_first_frame(motion))
    valid = motion.valid
    xyz = np.where(valid[:, :, None], motion.positions, 0.0)
    words = np.where(valid, np.float32(0.0), np.float32(-1.0)).astype("<f4")
    return c3dbin.build_c3d(header, records, xyz, words, np.zeros((0, 0), "<f4"),
                            float_storage=True, scale=1.0)


def archive_bytes(motion: Motion) -> bytes:
    """The C3D file of a motion with a C3D archive: every point back in its slot (markers
    from the motion, model outputs from the archive, 0 at gaps, the fourth words as
    stored), parameters, header and analog words as stored. int16 storage when the source
    had it and every coordinate is still on its grid, float32 otherwise.

    Raises
    ------
    InputFormatError
        When the archive does not describe this motion (frames or markers changed), or
        holds a parameter section a C3D cannot hold.
    """
    from mpz.c3darchive import C3DArchive, check_matches
    from mpz.errors import EncoderError
    a = motion.extras["c3d"]
    if not isinstance(a, C3DArchive):
        raise InputFormatError(f"extras['c3d'] is a {type(a).__name__}, not a C3DArchive")
    try:
        check_matches(a, motion)
    except EncoderError as exc:
        raise InputFormatError(str(exc)) from None
    xyz, scale, int16 = _points_to_write(motion, a)
    return c3dbin.build_c3d(a.header, a.records, xyz, a.words, a.analog,
                            float_storage=not int16, scale=scale)


def _points_to_write(motion: Motion, a: C3DArchive) -> tuple[NDArray[np.float64], float, bool]:
    """Spec §6.9: every C3D point of ``motion`` and its archive ``a`` ([F, P, 3], 0 at
    gaps), the point scale s, and whether int16 storage holds them (the source's storage,
    and every coordinate on the grid with |q| <= 32767), else float32."""
    F, P = a.words.shape
    M = motion.n_markers
    xyz = np.zeros((F, P, 3))
    for p, slot in enumerate(a.slots):
        if slot < M:
            v, ok = motion.positions[:, slot], motion.valid[:, slot]
        else:
            v, ok = a.models[:, slot - M], a.model_valid[:, slot - M]
        xyz[:, p] = np.where(ok[:, None], v, 0.0)
    scale = a.point_scale()
    # one scale for every point: ezc3d scales point p by element p of POINT:SCALE, so an
    # int16 file written with the first element alone read back with point 1 halved for
    # [0.5, 0.25] (a review of stop 54); float32 points need no scale
    one_scale = a.one_point_scale()
    int16 = bool(a.word_storage == 0 and (a.analog.size == 0 or a.analog_storage == 0)
                 and one_scale and _on_int16_grid(xyz, scale))
    return xyz, scale, int16


#: coordinates :func:`_on_int16_grid` divides at a time (2 MiB of float64)
_GRID_VALUES = 1 << 18


def _on_int16_grid(xyz: NDArray[np.float64], scale: float) -> bool:
    """Whether every coordinate of ``xyz`` is q x ``scale`` for q = rint(xyz / scale) with
    |q| <= 32767, a block of frames at a time. The whole array's quotients and their
    products were formed for every C3D written from an archive, float32 sources too, where
    they decide nothing: twice the points' float64 size beside them, the peak of `mpz
    decode` of a 30-minute capture (docs/corpus.md, "Memory per worker")."""
    rows = max(1, _GRID_VALUES // max(1, math.prod(xyz.shape[1:])))
    with np.errstate(over="ignore", invalid="ignore"):   # 1e308 / scale: not int16 then,
        for f in range(0, xyz.shape[0], rows):           # and build_c3d says why not float32
            blk = xyz[f: f + rows]
            q = blk / scale
            np.rint(q, out=q)
            if not (np.array_equal(q * scale, blk) and np.abs(q).max(initial=0) <= 32767):
                return False
    return True


def round_trip_warnings(source: Motion, decoded: Motion) -> list[str]:
    """What the C3D file of ``decoded`` (an .mpz of ``source``, a C3D read with its
    archive, decoded) does not give back as ``source`` read it, for ``mpz encode`` to
    say (a C3D QA run of stop 52 found both said by nothing, or only by a note of
    ``mpz decode`` that -q hides):

    - valid samples written at exactly (0, 0, 0), which C3D readers, this one included,
      take for gaps: a marker within the bound of the origin;
    - an int16 source written as float32 (§6.9: a coordinate decoded off the int16 grid,
      or at -32768): a larger file, POINT:SCALE negative (its ANALOG:FORMAT UNSIGNED
      words are written as their unsigned values, §6.9)."""
    from mpz.c3darchive import C3DArchive
    a, b = source.extras.get("c3d"), decoded.extras.get("c3d")
    if not isinstance(a, C3DArchive) or not isinstance(b, C3DArchive) or \
            decoded.positions.shape != source.positions.shape:
        return []
    out = []
    zero = decoded.valid & source.valid & (decoded.positions == 0.0).all(axis=2) \
        & ~(source.positions == 0.0).all(axis=2)
    if zero.any():
        f, m = (int(i) for i in np.argwhere(zero)[0])
        out.append(f"{int(zero.sum())} valid sample(s) within the bound of the origin (the "
                   f"first: frame {f}, marker {source.names[m]!r}) decode to exactly (0, 0, 0), "
                   "which C3D readers, mpz's included, read as gaps: a --max-error smaller "
                   "than their distance from the origin keeps them")
    if a.word_storage == 0 and not _points_to_write(decoded, b)[2]:
        said = ("the source stores int16 points, and the decoded C3D will store float32 "
                "(a coordinate decoded off the int16 grid or outside -32767..32767, spec "
                "§6.9): the file is larger, and POINT:SCALE is written negative")
        # the analog words change too: a reader that takes int16 words as signed (ezc3d)
        # read -1 in the source and reads 65535.0 in the float file, so its force-plate
        # and EMG values moved by 65536 x scale without a word (a C3D QA run)
        high = int((np.asarray(a.analog) < 0).sum()) if a.analog.size else 0
        if high and c3dbin.analog_unsigned(list(a.records)):
            said += (f"; ANALOG:FORMAT is UNSIGNED, so its {high} analog word"
                     f"{'s' * (high != 1)} stored below 0 (65535 as -1) are written as their "
                     "unsigned values (65535.0), which readers that take the int16 words as "
                     "signed (ezc3d) read otherwise than the source")
        out.append(said)
    return out
