"""The in-memory motion model shared by readers, writers, encoder and decoder.

Contract: a :class:`Motion` is always consistent. Positions are float64
``[frames, markers, 3]``; ``valid`` is a boolean ``[frames, markers]`` mask and
gaps (``valid == False``) are first-class: nothing here fills them, and the
position stored under a gap is ignored (readers store NaN there).
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
import math
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mpz.errors import MotionError
from mpz.format import MM_PER_UNIT

#: Units a Motion may declare (spec §4.1 lists their codes).
UNITS = ("mm", "cm", "m", "in", "")
#: the ``extras`` key where a reader lists, one sentence each, what of its source the
#: motion does not hold (an AMC's comments among its frames, an ASF's unknown keys);
#: :func:`mpz.encoder.not_kept` reports it, and no file stores it
READER_NOT_KEPT = "not_kept"


def held_extras(extras: Mapping[str, Any]) -> set[str]:
    """The keys of ``extras`` that hold part of the source (a C3D archive, a skeleton, an
    extension's data): all but :data:`READER_NOT_KEPT`, the reader's list of what it did
    not keep, which no writer writes and which motions joined together merge."""
    return set(extras) - {READER_NOT_KEPT}


def unit_scale_mm(units: str) -> float | None:
    """Millimetres per unit, or None for unitless/unknown data."""
    return MM_PER_UNIT.get(units)


def metadata_type_error(meta: Mapping[Any, Any]) -> str | None:
    """The first key or value of ``meta`` that is not a str, said as an error message (None
    when all are): a Motion and ``mpz.encode(metadata=...)`` refuse them in the same words,
    rather than convert them with str()."""
    for k, v in meta.items():
        if not isinstance(k, str):
            return f"metadata must map str to str: a key is {type(k).__name__} {_shown(k)}"
        if not isinstance(v, str):
            return (f"metadata must map str to str: the value of {_shown(k)} is "
                    f"{type(v).__name__}")
    return None


def _shown(x: object, width: int = 60) -> str:
    """``ascii(x)``, cut to ``width`` characters with "..." when longer."""
    a = ascii(x)
    return a if len(a) <= width else a[:width - 3] + "..."


def finite_samples(pos: NDArray[np.float64]) -> NDArray[np.bool_]:
    """``[F, M]``: whether each sample of ``pos[F, M, 3]`` has three finite coordinates.

    ``np.isfinite(pos).all(axis=2)`` reduces over an axis of 3, which numpy does slowly:
    2.8 ms on 4500 x 41 samples, against 0.16 ms for the three columns (11 % of decoding
    cmu_135_02, issue 15.1)."""
    return np.isfinite(pos[..., 0]) & np.isfinite(pos[..., 1]) & np.isfinite(pos[..., 2])


@dataclass(eq=False)
class Motion:
    """Marker trajectories with gaps, names, an exact frame rate and units.

    Parameters
    ----------
    positions : array_like, shape (frames, markers, 3)
        Marker positions in ``units``. Values under a gap are ignored. A float64
        array is kept as given, not copied (``valid`` always is): change it afterwards
        only through the Motion's own methods, or the mask no longer matches it.
    names : sequence of str
        One unique, non-empty name per marker.
    rate : float
        Frames per second, kept exactly as read (C3D rates such as
        65.0364227 Hz are float32 values and survive as such).
    units : str
        One of ``"mm"``, ``"cm"``, ``"m"``, ``"in"`` or ``""`` (unknown).
    valid : array_like of bool, shape (frames, markers), optional
        False where a marker is occluded. Default: every finite sample.
    metadata : dict of str to str, optional
        Free metadata (subject, take, source file, ...); None is none. Keys and values must
        be str: others are refused, not converted (as ``mpz.encode(metadata=...)`` refuses
        them).
    parents : sequence of int, optional
        For skeleton-derived points, the parent point of each point (-1 for
        the root). Used as the coding hierarchy for BVH and AMC input.
    angles : ndarray, shape (frames, channels), optional
        Joint-angle channels of skeletal input, with ``angle_names``. A float64 array is
        kept as given, not copied, as ``positions`` is.

    Raises
    ------
    MotionError
        On a shape mismatch, zero frames or markers, duplicate or empty
        names, a non-positive or non-finite rate, unknown units, or a
        non-finite position where ``valid`` is True.

    Examples
    --------
    >>> import numpy as np
    >>> from mpz import Motion
    >>> m = Motion(np.zeros((2, 1, 3)), ["A"], rate=120.0, units="mm")
    >>> m.n_frames, m.n_markers, m.duration
    (2, 1, 0.016666666666666666)
    """

    # The field types are those of a constructed Motion: __post_init__ converts
    # the arguments (any array_like, valid=None) to them. The __init__ below tells
    # type checkers which arguments are accepted; at run time the dataclass one is used.
    positions: NDArray[np.float64]
    names: list[str]
    rate: float
    units: str = "mm"
    valid: NDArray[np.bool_] = None  # type: ignore[assignment]  # None: every finite sample
    metadata: dict[str, str] = field(default_factory=dict)
    parents: list[int] | None = None
    angles: NDArray[np.float64] | None = None
    angle_names: list[str] | None = None
    #: what the source file holds besides marker positions, by extension name (see
    #: :mod:`mpz.extensions`: ``"c3d"``, ``"skeleton"``): written to ancillary chunks and
    #: rebuilt on decoding; other keys are not written (``EncodeReport.not_kept`` names them)
    extras: dict[str, Any] = field(default_factory=dict)

    if TYPE_CHECKING:
        def __init__(self, positions: ArrayLike, names: Iterable[str], rate: float,
                     units: str = "mm", valid: ArrayLike | None = None,
                     metadata: Mapping[str, str] = ..., parents: Sequence[int] | None = None,
                     angles: ArrayLike | None = None,
                     angle_names: list[str] | None = None,
                     extras: Mapping[str, Any] = ...) -> None: ...

    def __post_init__(self) -> None:
        valid_arg = cast("ArrayLike | None", self.valid)  # still the argument, see above
        try:
            raw = np.asarray(self.positions)
        except ValueError as exc:           # ragged nested lists: numpy's own wording
            raise MotionError(f"positions must be an array of shape (frames, markers, 3): "
                              f"{exc}") from None
        if raw.dtype.kind not in "fiu":    # complex lost its imaginary part, bool became 0/1
            raise MotionError(f"positions must be real numbers, got dtype {raw.dtype}")
        pos = np.asarray(raw, dtype=np.float64)
        if pos.ndim != 3 or pos.shape[2] != 3:
            raise MotionError(f"positions must have shape (frames, markers, 3), got {pos.shape}")
        frames, markers, _ = pos.shape
        if frames == 0:
            raise MotionError("a motion needs at least one frame, got 0")
        if markers == 0:
            raise MotionError("a motion needs at least one marker, got 0")
        # list("LFHD") is four names, silently; None or 5 raised a bare TypeError (QA)
        if isinstance(self.names, (str, bytes)) or not hasattr(self.names, "__iter__"):
            raise MotionError(f"names must be a sequence of str (one per marker), got a "
                              f"{type(self.names).__name__} {self.names!r:.60}")
        if isinstance(self.names, (set, frozenset)):
            # the order of a set's names changes with PYTHONHASHSEED, so a Dask worker gave
            # the markers other names than the driver (a QA run of the API, stop 54)
            raise MotionError("names must be a sequence of str in marker order; a set has no "
                              "order (give a list)")
        names = list(self.names)
        # str(b"x") is "b'x'": no silent conversion; a None among them was taken for "no
        # such name" and kept (found by the decoder helper of stop 77)
        odd = [n for n in names if not isinstance(n, str)]
        if odd:
            raise MotionError(f"marker names must be str, got {type(odd[0]).__name__} "
                              f"{odd[0]!r}")
        if len(names) != markers:
            raise MotionError(f"{len(names)} names for {markers} markers")
        if any(n == "" for n in names):
            raise MotionError("marker names must not be empty")
        seen: set[str] = set()
        for n in names:
            if n in seen:
                raise MotionError(f"duplicate marker name {n!r}")
            seen.add(n)
        if valid_arg is None:
            valid = finite_samples(pos)
        else:
            given = np.asarray(valid_arg)
            if given.dtype != bool and not (given.dtype.kind in "iu"
                                            and ((given == 0) | (given == 1)).all()):
                raise MotionError(f"the valid mask must be booleans (or 0 and 1), got "
                                  f"dtype {given.dtype}")
            valid = given.astype(bool)
            if valid.shape != (frames, markers):
                raise MotionError(
                    f"valid mask must have shape {(frames, markers)}, got {valid.shape}")
            # with every sample valid, whether one is not finite is one pass over the
            # positions (half the time of the three strided passes and masks, issue 15.1)
            if not (valid.all() and np.isfinite(pos).all()):
                bad = valid & ~finite_samples(pos)
                if bad.any():
                    f, m = np.argwhere(bad)[0]
                    raise MotionError(f"non-finite position at frame {f}, marker {names[m]!r} "
                                      "where the mask says valid")
        if isinstance(self.rate, (bool, np.bool_)) or not isinstance(
                self.rate, (int, float, np.integer, np.floating)):
            raise MotionError(f"frame rate must be a number, got {type(self.rate).__name__} "
                              f"{self.rate!r}")
        try:
            rate = float(self.rate)
        except OverflowError:          # an int past float's range (10**400): a QA run
            rate = math.inf
        if not math.isfinite(rate) or rate <= 0:
            raise MotionError(f"frame rate must be finite and positive, got {self.rate!r:.40}")
        if self.units not in UNITS:
            raise MotionError(f"unknown units {self.units!r}, expected one of {UNITS}")
        if self.parents is not None:
            self.parents = _parents(self.parents, markers)
        if self.angles is not None:
            self.angles = _angles(self.angles, frames)
        if self.angle_names is not None:
            if self.angles is None:
                raise MotionError("angle_names without angles")
            an = self.angle_names
            if isinstance(an, (str, bytes, set, frozenset)) or not hasattr(an, "__iter__") or \
                    not all(isinstance(n, str) for n in an):
                raise MotionError(f"angle_names must be a sequence of str, got {an!r:.60}")
            if len(list(an)) != self.angles.shape[1]:
                raise MotionError(f"{len(list(an))} angle_names for "
                                  f"{self.angles.shape[1]} angle channels")
            self.angle_names = list(an)
        self.positions = pos
        self.valid = valid
        self.names = names
        self.rate = rate
        if self.metadata is None:
            self.metadata = {}
        if not isinstance(self.metadata, Mapping):
            raise MotionError(f"metadata must be a mapping of str to str, got "
                              f"{type(self.metadata).__name__}")
        meta = dict(self.metadata)
        said = metadata_type_error(meta)
        if said is not None:    # as encode(metadata=...) refuses them: no silent str()
            raise MotionError(said)
        self.metadata = meta
        if not isinstance(self.extras, Mapping) or \
                not all(isinstance(k, str) for k in self.extras):
            raise MotionError(f"extras must be a mapping of str keys, got "
                              f"{self.extras!r:.60}")
        self.extras = dict(self.extras)

    # -- derived facts ---------------------------------------------------
    @property
    def n_frames(self) -> int:
        """Number of frames: ``positions.shape[0]``."""
        return self.positions.shape[0]

    @property
    def n_markers(self) -> int:
        """Number of markers: ``positions.shape[1]``."""
        return self.positions.shape[1]

    @property
    def duration(self) -> float:
        """Seconds the frames cover, frames / rate: the same as :attr:`mpz.FileInfo.duration`
        and the corpus index's ``duration_s`` (it was (frames - 1) / rate, a frame less)."""
        return self.n_frames / self.rate

    @property
    def gap_fraction(self) -> float:
        """Share of marker-frames that are gaps."""
        return float(1.0 - self.valid.mean())

    def as_nan(self) -> np.ndarray:
        """Positions as float64 with NaN at every gap (the decoder's output layout)."""
        out = self.positions.copy()
        out[~self.valid] = np.nan
        return out

    def raw_size(self) -> int:
        """Bytes of the same data as float32 xyz: 12 bytes per marker-frame."""
        return 12 * self.n_frames * self.n_markers

    def select_frames(self, start: int | None, stop: int | None) -> Motion:
        """A copy holding frames ``start:stop``. The metadata that says where the source's
        frames start moves with the first frame kept: the first frame number of a TRC or CSV
        (``trc.FirstFrame``, ``csv.FirstFrame``) and the first time (``start_time``), so
        that the cut is written with the source's frame numbers and times (frames 51-100 of
        a TRC were written as 1-50 from time 0: a QA run of the API, stop 54).

        Of ``extras``, a cut keeps what describes every frame alike: a BVH or ASF skeleton
        (with an AMC's first frame number moved likewise), so that the cut's angles still
        give joint positions and are written and encoded with their skeleton. A C3D archive
        (its analog samples, events and parameters belong to the source's frames) and any
        key no extension owns are not carried over, and the cut names them under
        ``extras["not_kept"]``, which :func:`mpz.encode_motion`'s ``not_kept`` reports.

        Raises
        ------
        MotionError
            For a bound that is not a whole number (None: the start or the end), or a
            range without frames (it raised numpy's TypeError, or a Motion's own error
            about its positions; a QA run of stop 48)."""
        for name, v in (("start", start), ("stop", stop)):
            if v is not None and (isinstance(v, bool) or not isinstance(v, (int, np.integer))):
                raise MotionError(f"select_frames: {name} must be a whole number or None, "
                                  f"got {v!r}")
        kept = range(self.n_frames)[start:stop]
        if not len(kept):
            raise MotionError(f"select_frames({start}, {stop}) holds no frame of the "
                              f"{self.n_frames}")
        meta = dict(self.metadata)
        if kept.start:
            _moved_start(meta, kept.start, self.rate)
        return Motion(self.positions[start:stop].copy(), list(self.names), self.rate, self.units,
                      self.valid[start:stop].copy(), meta, self.parents,
                      None if self.angles is None else self.angles[start:stop].copy(),
                      self.angle_names, _cut_extras(self.extras, kept.start))

    def __repr__(self) -> str:
        return (f"Motion({self.n_frames} frames, {self.n_markers} markers, {self.rate:g} Hz, "
                f"units={self.units!r}, gaps={self.gap_fraction:.1%})")


def cut_leaves(held: str) -> str:
    """What a frame cut says under :data:`READER_NOT_KEPT` of an extension's part that it
    does not carry (``held``: the extension's words for it)."""
    return f"{held}: a cut of the frames does not carry what belongs to the source's frames"


def _cut_extras(extras: Mapping[str, Any], k: int) -> dict[str, Any]:
    """``extras`` of a motion's frames from index ``k`` on (:meth:`Motion.select_frames`):
    each extension's part as its ``cut`` keeps it; what none keeps is named, after what
    the reader did not keep, under :data:`READER_NOT_KEPT` (they were all dropped without
    a word: an ML pipeline's QA run of the API)."""
    from mpz.extensions import EXTENSIONS  # here: the extensions import this module
    owners = {e.name: e for e in EXTENSIONS}
    out: dict[str, Any] = {}
    dropped = [str(s) for s in extras.get(READER_NOT_KEPT, ())]
    for key in sorted(held_extras(extras)):
        ext = owners.get(key)
        part = None if ext is None else ext.cut(extras[key], k)
        if part is not None:
            out[key] = part
        elif ext is not None:
            dropped.append(cut_leaves(ext.held))
        else:
            dropped.append(f"motion.extras[{key!r}], which a cut of the frames does not "
                           "carry")
    if dropped:
        out[READER_NOT_KEPT] = list(dict.fromkeys(dropped))
    return out


def _moved_start(meta: dict[str, str], k: int, rate: float) -> None:
    """``meta`` of a motion's frames from index ``k`` on (:meth:`Motion.select_frames`):
    the first frame number (``trc.FirstFrame``; ``csv.FirstFrame``, 0 when a CSV's is not
    given) plus k, and the first time (``start_time``, 0 when a CSV's is not given) plus
    k / rate; values that are not numbers are left as they are (the writers then ignore
    them, as before the cut)."""
    csv = meta.get("format") == "csv"
    for key, given in (("trc.FirstFrame", meta.get("trc.FirstFrame")),
                       ("csv.FirstFrame", meta.get("csv.FirstFrame", "0" if csv else None))):
        try:
            if given is not None:
                meta[key] = str(int(given) + k)
        except ValueError:
            pass
    try:
        t0 = meta.get("start_time", "0" if csv else None)
        t = float(t0) + k / rate if t0 is not None else math.nan
        if math.isfinite(t):
            meta["start_time"] = repr(t)
    except ValueError:
        pass


def check_consistent(motion: Motion) -> None:
    """The checks of :class:`Motion`'s constructor, made again on a Motion that may have
    been changed since it was made (it is a plain mutable object): a rate set to -5, a
    names list grown by one, NaN written into its array where it is valid, or ``valid``
    or ``positions`` replaced by None or a list (a TypeError or AttributeError deep in
    the encoder and the writers, a QA run of the API at stop 54).

    Raises
    ------
    MotionError
        "the motion is not consistent (was it changed after it was made?): " and what is
        not (the encoder and :func:`mpz.io.write` say it so).
    """
    try:
        for name, kind in (("positions", "f"), ("valid", "b")):
            v = getattr(motion, name)
            if not isinstance(v, np.ndarray) or v.dtype.kind != kind:
                dtype = f" of {v.dtype}" if isinstance(v, np.ndarray) else ""
                raise MotionError(f"{name} is a {type(v).__name__}{dtype}, not the "
                                  f"{'float64' if kind == 'f' else 'bool'} array a Motion "
                                  "holds: make a new Motion rather than replacing it")
        Motion(motion.positions, motion.names, motion.rate, motion.units, motion.valid,
               motion.metadata, motion.parents, motion.angles, motion.angle_names,
               motion.extras)
    except MotionError as exc:
        raise MotionError(f"the motion is not consistent (was it changed after it was "
                          f"made?): {exc.message}") from None


def concatenate(motions: Iterable[Motion]) -> Motion:
    """Join motions with the same markers, rate and units end to end.

    What else they hold must agree too, or nothing would say what was dropped (the first
    motion's metadata was kept and the others' lost, and joint angles always): the same
    metadata (but where each starts, when each starts where the motions before it end:
    consecutive cuts of :meth:`Motion.select_frames`, which move ``start_time`` and the
    first frame numbers), joint angles on all or none (with the same channel names), and no extras
    but equal ones; a per-frame extra (a C3D archive, which belongs to its own frames) is
    refused even when equal: join the marker layers (``mpz.decode(data,
    markers_only=True)``)."""
    motions = list(motions)
    if not motions:
        raise MotionError("nothing to concatenate")
    for m in motions:
        if not isinstance(m, Motion):
            raise MotionError(f"can only concatenate Motions, got {type(m).__name__}")
    from mpz.extensions import EXTENSIONS  # here: the extensions import this module
    per_frame = {e.name for e in EXTENSIONS if e.per_frame}
    first = motions[0]
    offset = first.n_frames
    for m in motions[1:]:
        if m.names != first.names or m.rate != first.rate or m.units != first.units:
            raise MotionError("can only concatenate motions with the same names, rate and units")
        # consecutive cuts of one motion (select_frames) differ where their frames start:
        # each must start where the joined motion has got to (two cuts of a TRC could not
        # be joined back: an API QA run of stop 74)
        moved = dict(first.metadata)
        _moved_start(moved, offset, first.rate)
        start, offset = offset, offset + m.n_frames
        if m.metadata != first.metadata and m.metadata != moved:
            k = next(k for k in {**first.metadata, **m.metadata}
                     if first.metadata.get(k) != m.metadata.get(k))
            raise MotionError(f"metadata differ at {k!r}: {first.metadata.get(k)!r} vs "
                              f"{m.metadata.get(k)!r} (make them equal first; cuts of one "
                              "motion join as they are when each starts where the one "
                              "before it ends)")
        if (m.angles is None) != (first.angles is None) or m.angle_names != first.angle_names:
            raise MotionError("joint angles on some motions only, or with other channels")
        # what each reader dropped is not held data: the lists are joined (a review of
        # stop 61: two takes of one ASF, one with a comment among its frames, were refused)
        mine, theirs = held_extras(m.extras), held_extras(first.extras)
        frames_own = sorted(k for k in {*mine, *theirs} if k in per_frame)
        if frames_own:
            # "(c3d vs c3d)" read as a difference of two equal archives, and the way out
            # went unsaid (an API QA run of stop 74)
            raise MotionError(f"cannot join motions that hold {', '.join(frames_own)}: a C3D "
                              "archive belongs to its own frames; join their marker layers "
                              "(mpz.decode(data, markers_only=True), or copies without "
                              "those extras)")
        if mine != theirs:
            raise MotionError(f"cannot join what the motions hold besides positions "
                              f"({', '.join(sorted(m.extras)) or 'none'} vs "
                              f"{', '.join(sorted(first.extras)) or 'none'}); a C3D archive "
                              "belongs to its own frames")
        # an AMC skeleton's first frame number moves with a cut too
        cut = _cut_extras(first.extras, start) if start else {}
        unequal = next((k for k in sorted(mine) if m.extras[k] != first.extras[k]
                        and m.extras[k] != cut.get(k)), None)
        if unequal is not None:
            # say where, as for metadata: two cuts of one AMC were refused as "skeleton vs
            # skeleton; a C3D archive belongs to its own frames" (a QA run of stop 63)
            raise MotionError(f"extras[{unequal!r}] differ"
                              f"{_where(first.extras[unequal], m.extras[unequal])} (make them "
                              "equal first; cuts of one motion join as they are when each "
                              "starts where the one before it ends)")
    angles = (None if first.angles is None
              else np.concatenate([m.angles for m in motions if m.angles is not None]))
    extras = {k: v for k, v in first.extras.items() if k != READER_NOT_KEPT}
    dropped = [s for m in motions for s in m.extras.get(READER_NOT_KEPT, ())]
    if dropped:
        extras[READER_NOT_KEPT] = list(dict.fromkeys(dropped))
    return Motion(np.concatenate([m.positions for m in motions]), list(first.names), first.rate,
                  first.units, np.concatenate([m.valid for m in motions]), dict(first.metadata),
                  first.parents, angles, first.angle_names, extras)


def _where(a: object, b: object) -> str:
    """Where two unequal values of one kind differ, for a message: `` at 'field': A vs B``
    for the first field of two dataclasses of one type that differs, else ``""``."""
    import dataclasses
    if not (dataclasses.is_dataclass(a) and type(a) is type(b)):
        return ""
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if x != y:
            return f" at {f.name!r}: {x!r:.60} vs {y!r:.60}"
    return ""


def _parents(given: object, markers: int) -> list[int]:
    """``parents`` checked (see :class:`Motion`): one whole index in [-1, markers) per
    marker, and no marker its own ancestor. A QA run of stop 50: 5 and ['a'] raised
    TypeError and ValueError of their own, 0.7 was taken as 0, a cycle passed."""
    if isinstance(given, (str, bytes)) or not hasattr(given, "__iter__"):
        raise MotionError(f"parents must be a sequence of int, got {given!r:.60}")
    parents = list(given)
    odd = [p for p in parents if isinstance(p, (bool, np.bool_))
           or not isinstance(p, (int, np.integer))]
    if odd:
        raise MotionError(f"parents must be whole indices, got {odd[0]!r}")
    out = [int(p) for p in parents]
    if len(out) != markers or any(p < -1 or p >= markers for p in out):
        raise MotionError("parents must give one index in [-1, markers) per marker")
    depth = [0] * markers              # 0 unknown, 1 on the current walk, 2 reaches -1
    for start in range(markers):
        walk, m = [], start
        while m != -1 and depth[m] == 0:
            depth[m] = 1
            walk.append(m)
            m = out[m]
        if m != -1 and depth[m] == 1:
            raise MotionError(f"parents loop: marker {m} is its own ancestor")
        for w in walk:
            depth[w] = 2
    return out


def _angles(given: object, frames: int) -> NDArray[np.float64]:
    """``angles`` checked (see :class:`Motion`): real numbers of shape (frames, channels)."""
    try:
        raw = np.asarray(given)
    except ValueError as exc:          # ragged rows
        raise MotionError(f"angles must be an array of shape (frames, channels): {exc}") \
            from None
    if raw.dtype.kind not in "fiu":    # strings, objects; complex lost its imaginary part
        raise MotionError(f"angles must be real numbers, got dtype {raw.dtype}")
    # not copied when float64 already, as positions are not: a reader's copy of a
    # 30-minute capture's angles was the peak of reading it (issue 15.3)
    ang = np.asarray(raw, dtype=np.float64)
    if ang.ndim != 2 or ang.shape[0] != frames:
        raise MotionError(f"angles must have shape (frames, channels), got {ang.shape}")
    return ang
