"""The C3D archive: everything a C3D file holds besides marker positions (spec §4.13).

Strategy: the C3D reader (:mod:`mpz.io.c3d`) puts the markers in the Motion and the rest
in ``motion.extras["c3d"]``, a :class:`C3DArchive`: the header block, every parameter
record as stored, the fourth word (residual, camera mask) of every point, the points
that are model outputs (listed in POINT:ANGLES, FORCES, MOMENTS, POWERS, SCALARS or
REACTIONS: not markers, so never under the marker bound in millimetres) and the analog
words. :class:`C3DExtension` turns it into the ancillary chunks chdr, cprm, cpnt and
cana (:mod:`mpz.chunks.c3d`) and back; the C3D writer puts every point back in its slot.

What comes back: the header, the parameters and the analog words exactly (bit for bit);
the fourth words exactly; model outputs within their declared bound (by default 1e-4 of
each channel's range, or exact on an int16 file's grid); markers within the file's bound.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
import functools
import math
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from mpz.c3dcodec import (
    BATCH_VALUES,
    INT16,
    MODEL_LIMIT,
    IntArray,
    best_orders,
    encode_channels,
    model_grid,
    on_model_grid,
    plan_all,
    residual_rows,
)
from mpz.chunks.base import forget
from mpz.chunks.c3d import C3D_TYPES, Cana, Channel, Chdr, Cpnt, Cprm, Model, ModelAxis, Param
from mpz.entropy import BlockEncoder
from mpz.errors import EncoderError
from mpz.format import (
    MAX_ANALOG_SAMPLES,
    MAX_C3D_PARAMETER_BYTES,
    MAX_MARKERS,
    MAX_SAMPLES,
    ByteCoding,
    C3DStorage,
    ModelKind,
)
from mpz.io.c3dbin import ParamRecord, header_range_holds, named

if TYPE_CHECKING:
    from mpz.chunks import Record
    from mpz.encoder import EncodeOptions
    from mpz.motion import Motion

R = TypeVar("R", Chdr, Cprm)

#: the POINT parameters that list model outputs, in ModelKind order
MODEL_PARAMETERS = tuple(k.name for k in ModelKind)


@dataclass(eq=False)
class C3DArchive:
    """What a C3D file holds besides the marker positions of the Motion it belongs to.

    Attributes
    ----------
    processor : int
        The source's processor type (84 Intel, 85 DEC, 86 MIPS).
    header : bytes
        The 512-byte header block, normalised (integers little-endian, IEEE floats).
    records : list of ParamRecord
        Every group and parameter record, in file order, normalised.
    slots : list of int
        Per C3D point, in file order: ``s < M`` is marker ``s`` of the Motion, ``s >= M``
        model output ``s - M``.
    words : ndarray, shape (frames, points)
        The fourth word of every point, int16 or float32 values (``word_storage``).
    models : ndarray, float64, shape (frames, J, 3)
        Model-output values, NaN at gaps; ``model_valid`` [frames, J], ``model_kinds`` [J]
        (:class:`mpz.format.ModelKind`), ``model_bounds`` [J, 3] the declared bounds after
        decoding (None before encoding).
    analog : ndarray, shape (frames * analog_samples, channels)
        The analog words in file order, int16 or float32 values (``analog_storage``).
    layer : (names, units, rate) or None
        The marker names, units and rate of the motion the archive was read or decoded
        with: writing and encoding refuse a motion described otherwise since (renamed,
        converted, another rate), whose archive would contradict it. None for an archive
        made by hand, whose POINT parameters are compared instead.
    """

    processor: int
    header: bytes
    records: list[ParamRecord]
    slots: list[int]
    words: NDArray[Any]
    word_storage: int
    models: NDArray[np.float64]
    model_valid: NDArray[np.bool_]
    model_kinds: list[int]
    analog: NDArray[Any]
    analog_samples: int
    analog_storage: int
    model_bounds: NDArray[np.float64] | None = None
    notes: list[str] = field(default_factory=list)
    #: the marker names, units and rate of the motion the archive was read or decoded with,
    #: which writing and encoding compare with the motion's (:func:`described_otherwise`);
    #: None for an archive made by hand, whose POINT parameters are compared instead
    layer: tuple[tuple[str, ...], str, float] | None = field(default=None, compare=False,
                                                              repr=False)

    def stale_header(self, frames: int) -> list[str]:
        """What header words 2, 3, 10 and 4-5 (§4.13.1) say that the archive's points,
        analog words and ``frames`` frames contradict, each as "what it says, what the
        file holds"; empty when they agree. §4.13.1 keeps such stale counts and a writer
        writes them back, so the C3D it writes is read otherwise by its readers: the
        writers say so (a fuzzing QA run of stop 54, an archive without its cana)."""
        w = np.frombuffer(self.header[:20], "<u2")
        C = self.channels
        n = self.analog_samples if C else 0
        out = []
        for word, says, holds, what in ((2, w[1], len(self.slots), "points"),
                                        (3, w[2], C * n, "analog words a frame"),
                                        (10, w[9], n, "analog samples a frame")):
            if int(says) != holds and not (word == 10 and C == 0):
                out.append(f"word {word} says {int(says)} {what}, the file holds {holds}")
        first, last = int(w[3]), int(w[4])
        if last != 0xFFFF and last - first + 1 != frames:
            out.append(f"words 4-5 say frames {first}..{last}, the file holds {frames}")
        return out

    @property
    def frames(self) -> int:
        return int(self.words.shape[0])

    @property
    def channels(self) -> int:
        return int(self.analog.shape[1])

    @property
    def markers(self) -> int:
        """M, the points in marker slots (``slots`` below M; model outputs from M on)."""
        return len(self.slots) - int(self.models.shape[1])

    def parameter(self, group: str, name: str) -> ParamRecord | None:
        """The first record of parameter ``group:name`` (names compared without case)."""
        at = named(self.records, group.encode("latin-1"), name.encode("latin-1"))
        return self.records[at[0]] if at else None

    def header_scale(self) -> float:
        """Header words 7-8, the scale (float32): its sign says the storage."""
        return float(np.frombuffer(self.header, "<f4", 1, 12)[0])

    def point_scale(self) -> float:
        """|POINT:SCALE| (the int16 grid step), or the header's scale without one."""
        r = self.parameter("POINT", "SCALE")
        if r is not None and r.type == 4 and len(r.data) >= 4:
            s = float(np.frombuffer(r.data, "<f4", 1)[0])
        else:
            s = self.header_scale()
        return abs(s) if math.isfinite(s) and s != 0 else 1.0

    def one_point_scale(self) -> bool:
        """Whether the POINT:SCALE record :meth:`point_scale` reads (if any) gives every
        point one scale: all its elements have its first one's magnitude (spec §6.9,
        Storage: ezc3d scales point p by element p)."""
        r = self.parameter("POINT", "SCALE")
        if r is None or r.type != 4 or len(r.data) < 4:
            return True
        v = np.abs(np.frombuffer(r.data, "<f4", len(r.data) // 4))
        return bool((v == v[0]).all())

    def point_grid(self) -> float | None:
        """The grid every point coordinate of an int16 source lies on (|POINT:SCALE|)."""
        return self.point_scale() if self.word_storage == C3DStorage.INT16 else None

    def first_frame(self) -> int:
        """The source's first frame number (the C3D user guide: frames are numbered from
        it; 1 in most files), as the reader decides it (:func:`mpz.io.c3dbin.frame_range`):
        header word 4, unless the header cannot describe the range (its last frame, word 5,
        is 65535, or the range is empty) and TRIAL:ACTUAL_START_FIELD holds the number as
        two int16 words (low, high), as in a file of more than 65535 frames."""
        first = int.from_bytes(self.header[6:8], "little")
        last = int.from_bytes(self.header[8:10], "little")
        if header_range_holds(first, last):
            return first
        r = self.parameter("TRIAL", "ACTUAL_START_FIELD")
        if r is not None and r.type == 2 and len(r.data) == 4:
            return int.from_bytes(r.data[0:2], "little") | int.from_bytes(r.data[2:4],
                                                                           "little") << 16
        return first

    def header_events(self) -> int:
        """The events of the header's event block: word 151 (bytes 300-301) when word 150
        holds its key, 12345; else 0 (the C3D user guide)."""
        if int.from_bytes(self.header[298:300], "little") != 12345:
            return 0
        return min(int.from_bytes(self.header[300:302], "little"), 18)

    def contents(self) -> dict[str, Any]:
        """What the archive holds beyond the markers (``mpz show``, :meth:`describe`):
        model outputs and the share of their samples that are gaps, analog channels and
        samples a frame, the event count (EVENT:USED; None without one), the events of
        the header's event block (:meth:`header_events`, 0 without one: c3dorg_Eb015pi has
        3 there and no EVENT group), the first frame, the parameter section's groups and
        parameters, and the point storage."""
        J = int(self.models.shape[1])
        used = self.parameter("EVENT", "USED")
        groups = sum(r.is_group for r in self.records)
        return {"model_outputs": J,
                "model_gap_fraction": float(1 - self.model_valid.mean()) if J else 0.0,
                "analog_channels": self.channels,
                "analog_samples_per_frame": self.analog_samples,
                "events": (int(np.frombuffer(used.data, "<i2", 1)[0])
                           if used is not None and used.type == 2 and len(used.data) >= 2
                           else None),
                "header_events": self.header_events(),
                "first_frame": self.first_frame(), "parameter_records": len(self.records),
                "parameter_groups": groups,
                "storage": "int16" if self.word_storage == C3DStorage.INT16 else "float32"}

    def describe(self) -> str:
        """:meth:`contents` as words, for a note of what a format that cannot hold the
        archive drops."""
        c = self.contents()
        J, C, E = c["model_outputs"], c["analog_channels"], c["events"]
        parts = [f"{J} model output{'s' * (J != 1)} (C3D points that are not markers)"] \
            if J else []
        if C:
            parts.append(f"{C} analog channel{'s' * (C != 1)} at "
                         f"{c['analog_samples_per_frame']} sample"
                         f"{'s' * (c['analog_samples_per_frame'] != 1)} a frame")
        if E:
            parts.append(f"{E} event{'s' * (E != 1)}")
        elif E is None and self.parameter("EVENT", "TIMES") is not None:
            parts.append("the events")
        H = c["header_events"]
        if H:
            parts.append(f"{H} event{'s' * (H != 1)} (header)")
        groups = c["parameter_groups"]
        params = c["parameter_records"] - groups
        parts += [f"the parameter section ({groups} group{'s' * (groups != 1)}, {params} "
                  f"parameter{'s' * (params != 1)})", "the header",
                  "the points' residual and camera words"]
        return ", ".join(parts)

    def sizes(self) -> dict[str, int]:
        """Bytes of the source's data section by part: markers' and model outputs' xyz,
        fourth words, analog."""
        w = 2 if self.word_storage == C3DStorage.INT16 else 4
        F, P = self.words.shape
        J = self.models.shape[1]
        aw = 2 if self.analog_storage == C3DStorage.INT16 else 4
        return {"markers": 3 * w * F * (P - J), "models": 3 * w * F * J,
                "words": w * F * P, "analog": aw * int(self.analog.size)}


# ------------------------------------------------------------------ encoding --
def _channel(p: Any) -> Channel:
    return Channel(mode=p.mode, shift=p.shift, order=p.order, low_bits=p.low_bits)


def _fill(k: NDArray[np.float64], valid: NDArray[np.bool_]) -> NDArray[np.int64]:
    """Grid values with the gaps filled by linear interpolation (cheap to predict)."""
    t = np.arange(k.shape[0])
    if valid.all():
        return np.rint(k).astype(np.int64)
    if not valid.any():
        return np.zeros(k.shape, np.int64)
    return np.rint(np.interp(t, t[valid], k[valid])).astype(np.int64)


def float32_bound(e: float, peak: float, exact: Callable[[], bool], dims: int = 3) -> float:
    """The error to code within, so that values within ``e`` of their source still are
    once a C3D writer rounds them to float32 (spec Appendix C, item 3; the markers' in
    :func:`mpz.encoder.c3d_bound`, each model-output axis's in :func:`_model_batch`).

    ``peak`` is the largest |value| of the source; ``exact()`` says whether every valid
    source value is a binary32 value (a float C3D's always are); ``dims`` 3 for a
    position (Euclidean), 1 for a model-output axis. A decoded value x' lies within
    ``peak + e`` of 0, where float32 spacing is at most 2^(f - 23), f = floor(log2(peak +
    e)): rounding moves each coordinate by h <= 2^(f - 24), so within e - sqrt(dims) h
    of the source is within e after it. And when the source value x is binary32, the
    nearest binary32 to x' is no farther from x' than x is, so within e / 2 is enough:
    the larger of the two, never less than half of e. Values that are not all binary32
    where e is below that (a motion changed after reading) keep e: no float32 file can
    hold them within it, whatever is coded, and the binary64 decode still does.
    """
    h = math.ldexp(1.0, math.frexp(peak + e)[1] - 25)
    cut = e - math.sqrt(dims) * h
    if cut >= e / 2:
        return cut
    return e / 2 if exact() else e


def binary32_values(v: NDArray[np.float64]) -> bool:
    """True when every value of ``v`` is a binary32 value (as a float C3D holds them)."""
    return bool(np.array_equal(v.astype(np.float32).astype(np.float64), v))


def _column_binary32(x: NDArray[np.float64], valid: NDArray[np.bool_], c: int) -> bool:
    """:func:`binary32_values` of column ``c``'s valid values, sliced only when asked (most
    axes never need it: the float32 margin is below half their bound)."""
    return binary32_values(x[:, c][valid[:, c]])


def _model_axes(a: C3DArchive, opts: EncodeOptions) -> Iterator[tuple[list[Model], IntArray]]:
    """§4.13.3 the model outputs' entries, in order, a batch of model outputs at a time:
    (their entries, the residuals ``[3 x n, F]`` of their axes in entry order).

    Each axis j, ax gets a bound of ``rel`` x its range over the valid frames (``rel``
    the kind's entry of ``opts.model_errors``, else ``opts.model_error``), a grid
    (:func:`mpz.c3dcodec.model_grid`: exact on an int16 file's |POINT:SCALE| when every
    value lies on it, unless the kind's bound is given), its grid values k with the gaps
    filled (:func:`_fill`) and the predictor order of least cost. The axes of a batch are
    formed at once, as the columns of one array, each with the operations and sums it had
    on its own (issue 15.1: one axis at a time cost 0.1 ms, 11 ms of a 279-frame clip
    with 36 model outputs); a batch holds about :data:`mpz.c3dcodec.BATCH_VALUES` values
    (a short clip's model outputs are one batch; issue 11.11: bounded temporaries).
    """
    F, J, _ = a.models.shape
    names = [ModelKind(kind).name for kind in a.model_kinds]
    grid = a.point_grid()
    step_j = max(1, BATCH_VALUES // max(1, 3 * F))
    for j0 in range(0, J, step_j):
        yield _model_batch(a, opts, j0, min(J, j0 + step_j), names, grid)


def _model_batch(a: C3DArchive, opts: EncodeOptions, j0: int, j1: int, names: list[str],
                 grid: float | None) -> tuple[list[Model], IntArray]:
    """:func:`_model_axes` of model outputs j0 .. j1 - 1."""
    F = a.models.shape[0]
    n = 3 * (j1 - j0)
    x = a.models[:, j0:j1].reshape(F, n)
    ok = np.repeat(a.model_valid[:, j0:j1], 3, axis=1)
    bad = np.argwhere((ok & ~np.isfinite(x)).T)            # (column, frame), in order
    if bad.size:
        col, t = int(bad[0, 0]), int(bad[0, 1])
        raise EncoderError(f"model output {j0 + col // 3} axis {'xyz'[col % 3]}: "
                           f"{x[t, col]} at frame {t} is not finite, and a valid model "
                           "output is coded on a finite grid (§4.13.3)")
    count = ok.sum(axis=0)
    lo = np.where(ok, x, np.inf).min(axis=0)
    hi = np.where(ok, x, -np.inf).max(axis=0)
    on = on_model_grid(x, ok, grid) if grid is not None else np.zeros(n, np.bool_)
    offset, step, declared = np.zeros(n), np.ones(n), np.zeros(n)
    for c in range(n):
        name = names[j0 + c // 3]
        rel = opts.model_errors.get(name, opts.model_error)
        bound = rel * (float(hi[c]) - float(lo[c]) if count[c] else 0.0)
        exact = bool(on[c]) and name not in opts.model_errors
        within = bound
        if not exact and bound > 0:
            # off the int16 grid, the C3D is written with float32 points (§6.9): code
            # within what stays within the bound after that rounding (Appendix C, item 3)
            within = float32_bound(bound, max(abs(float(lo[c])), abs(float(hi[c]))),
                                   functools.partial(_column_binary32, x, ok, c), 1)
        offset[c], step[c], declared[c] = model_grid(float(lo[c]), float(hi[c]),
                                                     int(count[c]), within,
                                                     grid if exact else None)
        declared[c] = max(declared[c], bound) if not exact and count[c] else declared[c]
    u = np.where(ok, (np.nan_to_num(x) - offset) / step, 0.0)
    k = np.rint(u).astype(np.int64)               # 0 where no value is valid
    for part in np.flatnonzero(~ok.all(axis=0) & ok.any(axis=0)):
        k[:, part] = _fill(u[:, part], ok[:, part])
    del u
    far = np.asarray((np.abs(k) >= MODEL_LIMIT // 2).any(axis=0))
    err = np.where(ok, np.abs(k.astype(np.float64) * step + offset - x), 0.0).max(axis=0)
    orders, _ = best_orders(k, max_low=0)       # each k residual coded whole (§5.4)
    axes = [ModelAxis(offset=float(offset[c]), step=float(step[c]), bound=float(declared[c]),
                      order=int(orders[c])) for c in range(n)]
    for c, ax in enumerate(axes):   # refused here, not written for the decoder to refuse
        what = f"model output {j0 + c // 3} axis {'xyz'[c % 3]}"
        fault = ax.fault()
        if fault is not None or far[c]:           # a range beyond float64: hi - lo overflows
            raise EncoderError(f"{what}: values {lo[c]} .. {hi[c]} have no grid of 2^31 "
                               f"steps ({fault or 'k beyond 2^30'}, §4.13.3)")
        if err[c] > declared[c]:
            raise EncoderError(f"{what}: error {err[c]} exceeds the bound {declared[c]} (a bug)")
    models = [Model(kind=a.model_kinds[j], axes=tuple(axes[3 * (j - j0): 3 * (j - j0) + 3]))
              for j in range(j0, j1)]
    return models, residual_rows(k, orders)


def point_records(a: C3DArchive, opts: EncodeOptions, M: int) -> Cpnt:
    """§4.13.3 the cpnt record of an archive: the fourth words' channels, then the model
    outputs' gap mask and axes."""
    F, P = a.words.shape
    J = a.models.shape[1]
    enc = BlockEncoder(capacity=max(1 << 16, 8 * F * (P + 3 * J)))
    plans = plan_all(a.words)
    encode_channels(enc, plans)
    models: list[Model] = []
    if J:
        enc.block((~a.model_valid).astype(np.int64)[:, :, None], signed=False)
        for batch, rows in _model_axes(a, opts):
            models += batch
            enc.rows(rows, np.ones(len(rows), np.bool_))
    return Cpnt(storage=a.word_storage, point_count=P, slots=tuple(a.slots),
                words=tuple(_channel(p) for p in plans), model_count=J, models=tuple(models),
                coded=enc.finish())


def analog_record(a: C3DArchive) -> Cana | None:
    """§4.13.4 the cana record of an archive (None without analog channels)."""
    T, C = a.analog.shape
    if C == 0 or T == 0:
        return None
    enc = BlockEncoder(capacity=max(1 << 16, 4 * T * C))
    plans = plan_all(a.analog)
    encode_channels(enc, plans)
    return Cana(storage=a.analog_storage, channels=C, samples=a.analog_samples,
                table=tuple(_channel(p) for p in plans), coded=enc.finish())


def stored_parameters(records: list[ParamRecord]) -> Cprm:
    """§4.13.2 the cprm record of a C3D's parameter records, stored (not deflated)."""
    recs = tuple(Param(group=r.group, locked=int(r.locked), name=r.name,
                       description=r.description,
                       type=None if r.is_group else r.type,
                       dims=None if r.is_group else bytes(r.dims),
                       data=None if r.is_group else r.data) for r in records)
    return Cprm(coding=ByteCoding.STORED, count=len(recs), records=recs)


def section_fault(stored: Cprm) -> str | None:
    """Why a cprm chunk cannot hold the parameter section ``stored``
    (:func:`stored_parameters`), or None: a §4.13.2 record rule it breaks (a group declared
    twice, which a C3D may hold), or a section longer than MAX_C3D_PARAMETER_BYTES (§8; a
    C3D written by ezc3d with 3,000 parameters, 271 blocks, was encoded into a file its
    decoder refused: a QA run of stop 52)."""
    fault = stored.fault()
    if fault is not None:
        return f"{fault} (§4.13.2)"
    n = len(stored.content())
    if n > MAX_C3D_PARAMETER_BYTES:
        return (f"its records take {n} bytes, more than the {MAX_C3D_PARAMETER_BYTES} of a "
                "cprm chunk (spec §8, MAX_C3D_PARAMETER_BYTES)")
    return None


def parameter_record(a: C3DArchive) -> Cprm:
    """§4.13.2 the cprm record of an archive. A section that a cprm cannot hold
    (:func:`section_fault`) is refused here, not written for the decoder to refuse."""
    stored = stored_parameters(a.records)
    fault = section_fault(stored)
    if fault is not None:
        raise EncoderError(f"the C3D parameter section cannot be kept: {fault}")
    return smaller(stored, stored.recoded(ByteCoding.DEFLATE))


def header_record(a: C3DArchive) -> Chdr:
    """§4.13.1 the chdr record of an archive."""
    return smaller(Chdr(processor=a.processor, coding=ByteCoding.STORED, block=a.header),
                   Chdr(processor=a.processor, coding=ByteCoding.DEFLATE, block=a.header))


def smaller(stored: R, deflated: R) -> R:
    """§4.13 the reference encoder's choice of coding: DEFLATE when its payload is
    shorter, the stored bytes otherwise (ties: stored)."""
    return deflated if len(deflated.dump()) < len(stored.dump()) else stored


def check_matches(a: C3DArchive, motion: Motion) -> None:
    """Refuse an archive that no longer describes ``motion``: frames or markers changed, or
    marker names, units or rate other than those its parameters give them (a motion
    renamed, converted to metres or given another rate after reading). The parameters are
    written back as stored, so the file would contradict the markers. An archive without
    a known POINT:UNITS contradicts no unit."""
    differ = described_otherwise(a, motion)
    if differ:
        raise EncoderError(f"the C3D archive no longer describes the motion: "
                           f"{differ}; the archive cannot be kept. Drop it "
                           "(dataclasses.replace(motion, extras={})) to keep the markers "
                           f"alone, without {a.describe()}")


def described_otherwise(a: C3DArchive, motion: Motion) -> str:
    """How ``motion``'s markers are described otherwise (names, units, rate) than when the
    archive was read or decoded (``a.layer``), or, for an archive made by hand, than its
    POINT parameters give them; '' when they agree. EncoderError for an archive of other
    frames or markers, which cannot be kept at all (:func:`check_matches`).

    A decoded file is compared with itself, not with its POINT parameters: spec §6.9
    writes those as stored even where they name the markers otherwise than MNAM does
    (nothing ties them), and the command line wrote such a valid file as markers alone
    (a clean-room review of stop 53)."""
    F, M = motion.n_frames, motion.n_markers
    P = len(a.slots)
    J = a.models.shape[1]
    if a.frames != F or P != M + J or sorted(a.slots) != list(range(P)):
        raise EncoderError(f"the C3D archive describes {a.frames} frames and {P - J} markers, "
                           f"the motion has {F} frames and {M} markers; it cannot be kept")
    if a.layer is not None:
        names, units, rate = list(a.layer[0]), a.layer[1], a.layer[2]
        where = ("in the file it was read from",) * 3
    else:
        from mpz.io.c3d import archive_describes
        names, units, rate = archive_describes(a, M)
        where = ("in POINT:LABELS", "in POINT:UNITS", "in POINT:RATE")
    differ = []
    if list(motion.names) != names:
        i = next(i for i, (x, y) in enumerate(zip(motion.names, names, strict=True))
                 if x != y)
        differ.append(f"marker {i} is {motion.names[i]!r} in the motion, {names[i]!r} "
                      f"{where[0]}")
    if units and motion.units != units:
        differ.append(f"the units are {motion.units!r} in the motion, {units!r} {where[1]}")
    if np.float32(motion.rate) != np.float32(rate):
        differ.append(f"the rate is {motion.rate!r} Hz in the motion, {rate!r} {where[2]}")
    return "; ".join(differ)


# ------------------------------------------------------------------ decoding --
def archive_from_records(records: Mapping[str, list[Record]], motion: Motion) -> C3DArchive:
    """§6.9 the archive of checked chdr, cprm, cpnt and cana records."""
    hdr = records["chdr"][0]
    prm = records["cprm"][0]
    pnt = records["cpnt"][0]
    assert isinstance(hdr, Chdr) and isinstance(prm, Cprm) and isinstance(pnt, Cpnt)
    F, M = motion.n_frames, motion.n_markers
    pd = pnt.decode(F, M)
    forget(pnt)
    ana = records.get("cana", [])
    if ana:
        cana = ana[0]
        assert isinstance(cana, Cana)
        analog = cana.decode(F)
        forget(cana)
        samples, astore = cana.samples, cana.storage
    else:
        analog = np.zeros((0, 0), INT16 if pnt.storage == C3DStorage.INT16 else "<f4")
        samples = int.from_bytes(hdr.block[18:20], "little")
        astore = pnt.storage
    params = [ParamRecord(r.group, bool(r.locked), r.name, r.description,
                          0 if r.type is None else r.type, tuple(r.dims or b""),
                          r.data or b"") for r in prm.records]
    bounds = np.array([[ax.bound for ax in m.axes] for m in pnt.models],
                      np.float64).reshape(-1, 3)
    return C3DArchive(hdr.processor, hdr.block, params, list(pnt.slots), pd.words, pnt.storage,
                      pd.models, pd.valid, [m.kind for m in pnt.models], analog, samples,
                      astore, bounds, layer=(tuple(motion.names), motion.units, motion.rate))


class C3DExtension:
    """The ``c3d`` entry of :data:`mpz.extensions.EXTENSIONS` (spec §4.13, §6.9)."""

    name: str = "c3d"
    chunk_types: tuple[str, ...] = C3D_TYPES
    sections: tuple[str, ...] = ("§4.13", "§6.9")
    per_frame: bool = True
    held: str = "the C3D archive (analog data, events, parameters and model outputs)"

    def check(self, motion: Motion, opts: EncodeOptions) -> None:
        """The §8 limits of the cpnt and cana chunks, before anything is encoded (the
        skeleton's limit was found only by decoding the file written: a QA run of stop
        51)."""
        a = motion.extras.get(self.name)
        if not isinstance(a, C3DArchive):
            return                          # records() says what is wrong with it
        F = motion.n_frames
        J = a.models.shape[1]
        T, C = a.analog.shape
        fault = ""
        if J > MAX_MARKERS or F * J > MAX_SAMPLES:
            fault = (f"{J} model outputs over {F} frames: at most {MAX_MARKERS}, and "
                     f"{MAX_SAMPLES} frames x outputs (spec §8, MAX_SAMPLES)")
        elif C and T * C > MAX_ANALOG_SAMPLES:
            fault = (f"{T} analog samples x {C} channels = {T * C} words, more than "
                     f"{MAX_ANALOG_SAMPLES} (spec §8, MAX_ANALOG_SAMPLES)")
        elif C and C * a.analog_samples > 0xFFFF:
            fault = (f"{C} analog channels x {a.analog_samples} samples a frame, more than "
                     "the 65535 analog words a frame of a C3D (§4.13.4)")
        if fault:
            raise EncoderError(f"the C3D archive cannot be kept: {fault}. Split the capture, "
                               "or keep the markers alone without the archive (in Python: "
                               "dataclasses.replace(motion, extras={}))")

    def records(self, motion: Motion, opts: EncodeOptions) -> list[Record]:
        a = motion.extras.get(self.name)
        if a is None:
            return []
        if not isinstance(a, C3DArchive):
            raise EncoderError(f"motion.extras['c3d'] is a {type(a).__name__}, not a "
                               "C3DArchive")
        prm = parameter_record(a)       # a section cprm cannot hold: refused by its rule
        check_matches(a, motion)        # before its labels, units and rate are compared
        out: list[Record] = [header_record(a), prm, point_records(a, opts, motion.n_markers)]
        ana = analog_record(a)
        if ana is not None:
            out.append(ana)
        return out

    def attach(self, records: dict[str, list[Record]], motion: Motion) -> None:
        motion.extras[self.name] = archive_from_records(records, motion)

    def cut(self, part: object, start: int) -> None:
        """None: the archive's point words, analog samples and events belong to the
        source's frames, and its parameters describe them."""
        return None


#: the extension object EXTENSIONS lists
C3D_EXTENSION = C3DExtension()
