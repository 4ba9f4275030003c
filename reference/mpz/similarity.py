"""Motion similarity from Fisher summaries (Yang & Shum's segment means), without decoding.

Contract: :func:`summarize` turns a :class:`mpz.Motion` into a :class:`MotionSummary`
(the least-WSSSE partitions of its centroid-relative marker positions at a few segment
counts ``k``, computed with :mod:`mpz.fisher`); :func:`from_stored` reads the same thing
back from what an index or an ``smry`` chunk stores. :func:`descriptor` maps a summary to a
short vector of features that do not depend on the marker set, the units, the axes or the
frame rate, so that a C3D of surface markers, an AMC of joint centres and a BVH of unknown
units can be compared; :func:`rank` orders candidates by the distance of their descriptors.

Strategy:

* The summary is exact (:func:`mpz.fisher.optimal_partitions`) up to
  :data:`EXACT_MAX_FRAMES` frames. The dynamic programme is quadratic in the frame count
  (about 1 s at 5,000 frames, 30 min at 216,000), so a longer motion is partitioned on the
  means of blocks of ``b = ceil(frames / EXACT_MAX_FRAMES)`` frames
  (:func:`mpz.fisher.summary_partitions`, which the encoder's summary chunks use too),
  and its means and WSSSE are recomputed on every frame. :attr:`MotionSummary.method`
  says which was used.
* A marker valid in fewer than :data:`MIN_VALID_SHARE` of the frames is left out of the
  summary (its columns are zeros, as a marker's that is a gap throughout); a motion of
  fewer than :data:`MIN_FRAMES` frames or :data:`MIN_MARKERS` such markers has no pose
  to describe (:class:`NotDescribable`).
* Means are kept as float32, the precision of C3D data, which halves an index; a query
  summarised here is rounded the same way, so the same capture gives the same descriptor
  bit for bit.
* The descriptor (:data:`FEATURES`) reads only segment means, lengths and WSSSE: the
  share of the motion's variance that ``k`` segments explain (one per level), the
  amplitude of the motion and the speed of the mean pose relative to the body's size, the
  shape of the mean pose (eigenvalues of its marker cloud), the duration and the spread of
  segment lengths; the speed has a floor (:data:`MIN_SPEED`), so that a static file does
  not set the feature's spread over an index. :func:`rank` standardises each feature
  over the candidates and sorts by Euclidean distance; ties go to a candidate whose
  source is byte-identical to the query (same sha256), then to the path.

The module works on arrays only (no file I/O); :mod:`mpz.corpus` stores summaries in an
index and ``mpz search`` queries it.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from mpz.errors import EncoderError
from mpz.fisher import EXACT_MAX_FRAMES, motion_series, summary_partitions

if TYPE_CHECKING:
    from mpz.api import Summary
    from mpz.motion import Motion

__all__ = ["SUMMARY_LEVELS", "EXACT_MAX_FRAMES", "FEATURES", "DESCRIPTOR_VERSION", "Level",
           "MotionSummary", "NotDescribable", "summarize", "from_stored", "from_smry",
           "descriptor", "rank", "features_for", "MIN_VALID_SHARE", "MIN_FRAMES",
           "MIN_MARKERS", "MIN_SPEED", "described_markers"]

#: segment counts of the stored summary (those of ``mpz summary``'s default)
SUMMARY_LEVELS: tuple[int, ...] = (6, 12, 24, 48)

#: changes whenever :func:`summarize` or :func:`descriptor` computes anything differently
#: (indexes store it; an index of another version is rebuilt by the next corpus run and
#: refused by a search until then). 2: markers valid in under :data:`MIN_VALID_SHARE` of
#: the frames are left out of the summary, and the speed has a floor (:data:`MIN_SPEED`).
DESCRIPTOR_VERSION = "2"

#: a marker valid in fewer than this share of a motion's frames is left out of its summary
#: (as a marker that is a gap throughout is): the gap filling holds it at its last valid
#: position, and a marker seen in 8 of 2,751 frames (CMU 01_01's RBAC-1, a QA run) then
#: stood still in the world for 22 s and set the shape of the mean pose
MIN_VALID_SHARE = 0.1
#: fewest frames a descriptor describes (one frame has no motion: no variance, no speed)
MIN_FRAMES = 2
#: fewest markers (valid in at least :data:`MIN_VALID_SHARE` of the frames) of a pose:
#: relative to their centroid, one marker is always at 0, and two have no shape
MIN_MARKERS = 3
#: floor of the speed feature (body sizes per second) before its log: a perfectly static
#: file gave log(1e-9) = -20.7 and raised the feature's spread over an index from 0.73 to
#: 3.77, which switched the feature off for every query; the slowest capture of the
#: developer set has 0.14
MIN_SPEED = 0.05

#: distances (standardised features) closer than this to the nearest of their run are
#: ties in :func:`rank`: two files that hold the same values (c3d.org's Eb015 trial in
#: three encodings) differ by float rounding, 7e-8, and that decided their order
TIE_DISTANCE = 1e-6

#: names of the descriptor's features, in order; ``ev_k`` is one per level
FEATURES_FIXED = ("amplitude", "log_speed", "shape_1", "shape_2", "log_duration",
                  "length_cv")


def features_for(levels: Sequence[int]) -> tuple[str, ...]:
    """Feature names of a descriptor over summary ``levels``."""
    return tuple(f"ev_{k}" for k in levels) + FEATURES_FIXED


#: the features of a descriptor over :data:`SUMMARY_LEVELS`
FEATURES = features_for(SUMMARY_LEVELS)


class NotDescribable(EncoderError):
    """A motion the descriptor cannot describe: fewer than :data:`MIN_FRAMES` frames, or
    fewer than :data:`MIN_MARKERS` markers valid in at least :data:`MIN_VALID_SHARE` of
    them (no valid sample at all, one marker). Its numbers would be NaN or meaningless."""


@dataclass(frozen=True, eq=False)
class Level:
    """One partition: segment starts (int64, first 0), float32 means ``[k, dims]``, WSSSE."""

    k: int
    starts: NDArray[np.int64]
    means: NDArray[np.float32]
    wssse: float


@dataclass(frozen=True, eq=False)
class MotionSummary:
    """The partitions of one motion at several ``k``, and what is needed to read them.

    ``method`` is ``"exact"`` or ``"blocks:B"`` (cuts on blocks of ``B`` frames), or
    ``"smry"`` for the quantised means of a file's summary chunk.
    """

    n_frames: int
    rate: float
    dims: int
    method: str
    levels: tuple[Level, ...]

    def level_ks(self) -> tuple[int, ...]:
        return tuple(lv.k for lv in self.levels)


def summarize(motion: Motion, levels: Sequence[int] = SUMMARY_LEVELS, *,
              max_frames: int | None = None) -> MotionSummary:
    """The Fisher summary of a motion's marker positions (relative to their centroid).

    Parameters
    ----------
    motion : mpz.Motion
    levels : sequence of int
        Segment counts; a count above the number of frames (or blocks) is lowered to it,
        as the encoder does for the ``smry`` chunk.
    max_frames : int, optional
        Longest motion partitioned exactly (see the module docstring); default
        :data:`EXACT_MAX_FRAMES`, as the encoder's summary chunks.

    Returns
    -------
    MotionSummary

    A marker valid in fewer than :data:`MIN_VALID_SHARE` of the frames is left out (its
    columns are zeros, as those of a marker that is a gap throughout, and it is not part
    of the centroid).

    Raises
    ------
    EncoderError
        For levels that are not positive integers.
    NotDescribable
        For fewer than :data:`MIN_FRAMES` frames or :data:`MIN_MARKERS` markers valid in
        at least :data:`MIN_VALID_SHARE` of them.

    Examples
    --------
    >>> from mpz.synth import generate
    >>> s = summarize(generate("walk", frames=120), (2, 4))
    >>> s.method, s.level_ks(), s.levels[1].means.shape
    ('exact', (2, 4), (4, 123))
    """
    ks = sorted({int(k) for k in levels})
    if not ks or ks[0] < 1:
        raise EncoderError(f"summary levels must be positive integers, got {list(levels)}")
    motion = _without_sparse_markers(motion)
    series, _ = motion_series(motion, space="positions")
    b, parts = summary_partitions(series, ks, max_frames)
    out = tuple(Level(k, p.starts.astype(np.int64), p.means.astype(np.float32), float(p.wssse))
                for k, p in sorted(parts.items()))
    return MotionSummary(series.shape[0], motion.rate, series.shape[1],
                         "exact" if b == 1 else f"blocks:{b}", out)


def described_markers(valid: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """The markers a summary describes, of a validity mask ``valid[F, M]``: those valid
    in at least :data:`MIN_VALID_SHARE` of the frames (none of a motion of no frames)."""
    valid = np.asarray(valid, bool)
    if not valid.size:
        return np.zeros(valid.shape[1] if valid.ndim == 2 else 0, bool)
    return valid.mean(axis=0) >= MIN_VALID_SHARE


def _without_sparse_markers(motion: Motion) -> Motion:
    """``motion`` with the markers valid in fewer than :data:`MIN_VALID_SHARE` of its frames
    made gaps throughout (the same object when there are none).

    Raises
    ------
    NotDescribable
        See :func:`summarize`.
    """
    from dataclasses import replace
    frames = motion.n_frames
    if frames < MIN_FRAMES:
        raise NotDescribable(f"too short to describe: {frames} frame{'' if frames == 1 else 's'}"
                             f" (a motion needs at least {MIN_FRAMES})")
    valid = np.asarray(motion.valid, bool)
    keep = described_markers(valid)
    share = valid.mean(axis=0) if valid.size else np.zeros(motion.n_markers)
    if int(keep.sum()) < MIN_MARKERS:
        seen = int((share > 0).sum())
        what = ("no valid marker sample" if not seen else
                f"{int(keep.sum())} marker{'' if keep.sum() == 1 else 's'} valid in at least "
                f"{MIN_VALID_SHARE:.0%} of its frames ({seen} valid at all)")
        raise NotDescribable(f"no pose to describe: {what}; a pose needs at least "
                             f"{MIN_MARKERS} markers")
    if keep.all():
        return motion
    return replace(motion, valid=valid & keep[None, :])


def from_stored(n_frames: int, rate: float, dims: int, method: str,
                levels: Sequence[tuple[int, bytes, bytes, float]]) -> MotionSummary:
    """A summary from stored bytes: per level ``(k, starts <u4, means <f4, wssse)``.

    Raises
    ------
    EncoderError
        If a level's byte strings do not hold ``k`` starts and ``k x dims`` means, or
        the starts are not a partition of ``n_frames`` frames.
    """
    out = []
    for k, starts_b, means_b, w in levels:
        if len(starts_b) != 4 * k or len(means_b) != 4 * k * dims:
            raise EncoderError(f"stored summary level k={k} has {len(starts_b)} bytes of "
                               f"starts and {len(means_b)} of means; expected {4 * k} and "
                               f"{4 * k * dims}")
        starts = np.frombuffer(starts_b, "<u4").astype(np.int64)
        if starts[0] != 0 or np.any(np.diff(starts) <= 0) or starts[-1] >= n_frames:
            raise EncoderError(f"stored summary level k={k} is not a partition of "
                               f"{n_frames} frames")
        means = np.frombuffer(means_b, "<f4").reshape(k, dims).astype(np.float32)
        out.append(Level(int(k), starts, means, float(w)))
    out.sort(key=lambda lv: lv.k)
    return MotionSummary(int(n_frames), float(rate), int(dims), method, tuple(out))


def from_smry(summary: Summary) -> MotionSummary:
    """The summary chunk of an MPZ file (:func:`mpz.read_summary`), as a MotionSummary.

    Raises
    ------
    EncoderError
        If the chunk summarises joint angles (the descriptor needs positions).
    """
    if summary.space != "positions":
        raise EncoderError("the file's summary chunk holds joint angles; similarity needs a "
                           "position summary")
    levels = tuple(Level(int(lv.k), np.asarray(lv.starts, np.int64),
                         np.asarray(lv.means, np.float64).astype(np.float32), float(lv.wssse))
                   for lv in sorted(summary.levels, key=lambda lv: lv.k))
    return MotionSummary(int(summary.n_frames), float(summary.rate), int(summary.dims), "smry",
                         levels)


def descriptor(s: MotionSummary, levels: Sequence[int] = SUMMARY_LEVELS) -> NDArray[np.float64]:
    """Marker-set-, unit-, axis- and rate-free features of a summary (:func:`features_for`).

    ``ev_k`` is taken from the stored level nearest to ``k`` (a short motion stores fewer
    segments than asked), the smaller of two equally near. The other features use the
    finest level of at most ``max(levels)`` segments, the coarsest stored when none is
    that coarse: a finer level, which an .mpz query's summary chunk may hold beside the
    index's, measures another amplitude and speed (its own source ranked past 1.0 away,
    a QA run of stop 53). The speed has a floor of :data:`MIN_SPEED` before its log.

    Raises
    ------
    NotDescribable
        For fewer than :data:`MIN_FRAMES` frames, or fewer than :data:`MIN_MARKERS`
        markers that are not zero throughout (a gap throughout, or left out by
        :func:`summarize`).
    EncoderError
        If the summary is not of marker positions (``dims`` not a multiple of 3), has
        no level, or holds a value that is not finite (a damaged one, or a mean that
        overflowed binary64, which §4.10 allows).
    """
    if not s.levels or s.dims % 3:
        raise EncoderError(f"a descriptor needs a position summary, got dims={s.dims} and "
                           f"{len(s.levels)} levels")
    F, rate = s.n_frames, s.rate
    if F < MIN_FRAMES:
        raise NotDescribable(f"too short to describe: {F} frame{'' if F == 1 else 's'} (a "
                             f"motion needs at least {MIN_FRAMES})")
    if not (math.isfinite(rate) and rate > 0) or not all(
            math.isfinite(lv.wssse) and np.all(np.isfinite(lv.means)) for lv in s.levels):
        raise EncoderError("the summary holds values that are not finite (or a rate that "
                           "is not above 0)")
    top = max(levels, default=0)
    fine = max((lv for lv in s.levels if lv.k <= top), key=lambda lv: lv.k,
               default=min(s.levels, key=lambda lv: lv.k))
    n = np.diff(np.append(fine.starts, F)).astype(np.float64)
    mu = fine.means.astype(np.float64)
    # markers that are zero in every segment were gaps throughout: not part of the body
    pts = mu.reshape(fine.k, -1, 3)
    present = np.any(pts != 0.0, axis=(0, 2))
    m = int(present.sum())
    if m < MIN_MARKERS:
        raise NotDescribable(f"no pose to describe: {m} marker{'' if m == 1 else 's'} with "
                             f"a position (a pose needs at least {MIN_MARKERS})")
    # sum over frames of |x_t|^2 = sum_i n_i |mu_i|^2 + WSSSE (x relative to the centroid)
    sq = float((n * np.einsum("ij,ij->i", mu, mu)).sum()) + fine.wssse
    radius = math.sqrt(sq / (F * m)) or 1.0
    grand = (n[:, None] * mu).sum(axis=0) / F
    total = max(sq - F * float(grand @ grand), 0.0)

    def explained(lv: Level) -> float:
        ln = np.diff(np.append(lv.starts, F)).astype(np.float64)
        d = lv.means.astype(np.float64) - grand
        between = float((ln * np.einsum("ij,ij->i", d, d)).sum())
        return min(between / total, 1.0) if total > 0 else 1.0

    evs = []
    for k in levels:
        lv = min(s.levels, key=lambda lv: (abs(lv.k - k), lv.k))
        evs.append(explained(lv))
    amplitude = math.sqrt(total / (F * m)) / radius
    duration = F / rate
    # one segment (an index of level 1) has no step between segment means: speed 0
    step = (np.linalg.norm((pts[1:] - pts[:-1])[:, present].reshape(fine.k - 1, -1), axis=1)
            if fine.k > 1 else np.zeros(0))
    speed = float(step.sum()) / math.sqrt(m) / radius / duration
    pose = grand.reshape(-1, 3)[present]
    pose = pose - pose.mean(axis=0)
    eig = np.sort(np.linalg.eigvalsh(pose.T @ pose / m))[::-1]
    eig = eig / eig.sum() if eig.sum() > 0 else np.full(3, 1 / 3)
    cv = float(n.std() / n.mean())
    out = np.array([*evs, amplitude, math.log(max(speed, MIN_SPEED)), float(eig[0]),
                    float(eig[1]), math.log(duration), cv], dtype=np.float64)
    if not np.all(np.isfinite(out)):
        raise EncoderError("the summary gives a descriptor that is not finite")
    return out


def rank(query: NDArray[np.float64], table: NDArray[np.float64], *,
         identical: Sequence[bool] | None = None,
         names: Sequence[str] | None = None) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Order the rows of ``table`` (candidates x features) by distance to ``query``.

    Each feature is divided by its standard deviation over the candidates (features
    constant over them are left as they are), then rows are sorted by Euclidean
    distance. Ties go first to rows flagged ``identical`` (a byte-identical source),
    then by ``names``. Distances within :data:`TIE_DISTANCE` of the nearest of their run
    are ties: they differ by rounding alone (a copy of c3d.org's Eb015pi ranked its own
    file third, 7e-8 behind the Eb015sr and Eb015vr files that hold the same values,
    all three printed as 0.000), so within a tie the distances may decrease by less
    than that.

    Returns
    -------
    order : ndarray of int64
        Row indices, nearest first.
    distances : ndarray of float64
        The distance of each row (in row order, not sorted).

    Examples
    --------
    >>> t = np.array([[0.0, 1.0], [2.0, 1.0], [0.1, 1.0]])
    >>> rank(np.array([0.0, 1.0]), t)[0].tolist()
    [0, 2, 1]
    """
    table = np.asarray(table, np.float64)
    if table.ndim != 2 or table.shape[1] != query.shape[0]:
        raise EncoderError(f"{table.shape} descriptors cannot be compared with a query of "
                           f"{query.shape[0]} features")
    sd = table.std(axis=0) if table.shape[0] > 1 else np.ones(table.shape[1])
    # a feature that hardly varies over the index is not scaled up: a spread of 1e-9 (two
    # takes that hold the same values) made every distance 3e8 (a QA run)
    tiny = 1e-6 * np.maximum(np.abs(table).max(axis=0), 1.0)
    sd[~(sd > tiny)] = 1.0
    dist = np.sqrt((((table - query) / sd) ** 2).sum(axis=1))
    same = list(identical) if identical is not None else [False] * len(dist)
    label = list(names) if names is not None else [""] * len(dist)
    near = sorted(range(len(dist)), key=lambda i: (dist[i], i))
    order: list[int] = []
    a = 0
    while a < len(near):         # a run of distances within TIE_DISTANCE of its nearest
        b = a + 1
        while b < len(near) and dist[near[b]] - dist[near[a]] <= TIE_DISTANCE:
            b += 1
        order += sorted(near[a:b], key=lambda i: (not same[i], label[i], dist[i], i))
        a = b
    return np.asarray(order, np.int64), dist
