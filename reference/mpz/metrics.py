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
    from mpz.c3darchive import C3DArchive


def _dist(original: Motion, decoded: Motion) -> NDArray[np.float64]:
    for what, m in (("original", original), ("decoded", decoded)):
        if not isinstance(m, Motion):       # an AttributeError deep inside, before
            raise TypeError(f"{what} must be an mpz.Motion, got {type(m).__name__}")
    if original.positions.shape != decoded.positions.shape:
        raise MotionError(f"shapes differ: {original.positions.shape} vs {decoded.positions.shape}")
    # the same sample of the same marker in the same unit, or the distance means nothing
    # (a motion in cm scored 1518 against itself in mm; `mpz compare` aligns by name)
    if original.units and decoded.units and original.units != decoded.units:
        raise MotionError(f"units differ: {original.units!r} vs {decoded.units!r} (convert "
                          "one first; a motion without units is compared as numbers)")
    if list(original.names) != list(decoded.names):
        k = next(i for i, (a, b) in enumerate(zip(original.names, decoded.names, strict=True))
                 if a != b)
        raise MotionError(f"marker names differ at index {k}: {original.names[k]!r} vs "
                          f"{decoded.names[k]!r} (reorder one motion first)")
    d = np.linalg.norm(original.positions - decoded.positions, axis=2)
    d[~original.valid] = np.nan
    d[original.valid & ~decoded.valid] = np.inf
    return d


def errors(original: Motion, decoded: Motion) -> NDArray[np.float64]:
    """Per-sample Euclidean error ``[F, M]``, NaN where the original is a gap."""
    return _dist(original, decoded)


def max_error(original: Motion, decoded: Motion) -> float:
    """Largest Euclidean error over valid samples (0 if there are none)."""
    d = _dist(original, decoded)
    return float(np.nanmax(d)) if np.isfinite(d).any() or np.isinf(d).any() else 0.0


def _rms_over(d: NDArray[np.float64], axis: int) -> NDArray[np.float64]:
    """RMS of the non-NaN entries along ``axis``; NaN where there are none.

    Counted by hand rather than with ``np.nanmean``, which warns "Mean of empty
    slice" for every frame (or marker) that is a gap throughout (arthuman).
    """
    have = ~np.isnan(d)
    n = have.sum(axis=axis)
    total = np.where(have, d, 0.0) ** 2
    s = total.sum(axis=axis)
    out = np.full(s.shape, np.nan)
    np.divide(s, n, out=out, where=n > 0)
    return np.sqrt(out)


def arms(original: Motion, decoded: Motion) -> float:
    """Paper Eq. 3: mean over frames of the RMS marker error of the frame (valid markers only).

    Frames without a valid marker do not count.
    """
    d = _dist(original, decoded)
    per_frame = _rms_over(d, axis=1)
    per_frame = per_frame[~np.isnan(per_frame)]
    return float(per_frame.mean()) if per_frame.size else 0.0


def summary(original: Motion, decoded: Motion) -> dict[str, Any]:
    """max, ARMS, RMS, p99 and mean error, plus per-marker max and RMS."""
    d = _dist(original, decoded)
    flat = d[~np.isnan(d)]
    if flat.size == 0:
        flat = np.zeros(1)
    per_max = np.where(np.isnan(d), -np.inf, d).max(axis=0, initial=-np.inf)
    per_rms = _rms_over(d, axis=0)
    return {
        "max": float(flat.max()),
        "arms": arms(original, decoded),
        "rms": float(np.sqrt((flat ** 2).mean())),
        "p99": float(np.percentile(flat, 99)),
        "mean": float(flat.mean()),
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
    the decoded file declares), ``"changed"`` (a lossy part, with no declared bound to
    hold it to; or metadata entries with other values), ``"differs"`` (a lossless part
    that is not the same, or a lossy one beyond its bound) or ``"missing"`` (the decoded
    motion does not hold it). ``error`` and ``bound`` are a lossy part's largest
    difference and its declared bound.
    """

    name: str
    status: str
    detail: str
    error: float | None = None
    bound: float | None = None


#: bytes 16-17 of a C3D header, word 9: the block where the data starts, which a written
#: C3D moves to just after its parameters (as POINT:DATA_START; docs/io-notes.md)
_DATA_START = slice(16, 18)


def besides_markers(original: Motion, decoded: Motion, *,
                    channel_bounds: tuple[float, float] | None = None) -> list[Part]:
    """Each part of ``original`` besides its marker trajectories, compared with
    ``decoded``: its metadata (a TRC's header fields...), a C3D's archive (header,
    parameters with the events, the points' fourth words, analog words, model outputs)
    and a BVH's or AMC's skeleton and joint channels.

    Where the data starts is not compared (a written C3D moves it); nor is the processor
    type (a written C3D is Intel; the archive keeps its values normalised). Model outputs
    are held to the bounds the decoded archive declares (per coordinate, spec §6.9); the
    joint channels to ``channel_bounds``, (rotations in degrees, translations in skeleton
    units), the largest error the decoded file's channel steps allow
    (:func:`mpz.skeleton.report`), when given.
    """
    return (_metadata_parts(original, decoded) + _archive_parts(original, decoded)
            + _skeleton_parts(original, decoded, channel_bounds))


def _metadata_parts(original: Motion, decoded: Motion) -> list[Part]:
    """The original's metadata entries besides those a reader sets to describe the file it
    read (:data:`mpz.io.READER_KEYS`: its name, format, reader...; a written file read
    again gets its own): a TRC's header fields, and what was given at encoding."""
    from mpz.io import READER_KEYS
    keys = sorted(k for k in original.metadata if k not in READER_KEYS)
    if not keys:
        return []
    got = decoded.metadata
    changed = [k for k in keys if k in got and got[k] != original.metadata[k]]
    lost = [k for k in keys if k not in got]
    if changed:         # not a failure: a file rewritten in other units has other fields
        return [Part("metadata", "changed", f"{len(keys)} entries; other values: "
                     f"{', '.join(changed[:5])}")]
    if lost:
        return [Part("metadata", "missing", f"{len(lost)} of its {len(keys)} entries: "
                     f"{', '.join(lost[:5])}" + (", ..." if len(lost) > 5 else ""))]
    return [Part("metadata", "same", f"{len(keys)} entries")]


def _archive_parts(original: Motion, decoded: Motion) -> list[Part]:
    from mpz.c3darchive import C3DArchive
    a, b = original.extras.get("c3d"), decoded.extras.get("c3d")
    if not isinstance(a, C3DArchive):
        return []
    if not isinstance(b, C3DArchive):
        return [Part("C3D archive", "missing", a.describe())]
    ha, hb = bytearray(a.header), bytearray(b.header)
    ha[_DATA_START] = hb[_DATA_START] = b"\0\0"
    at = next((i for i in range(min(len(ha), len(hb))) if ha[i] != hb[i]),
              None if len(ha) == len(hb) else min(len(ha), len(hb)))
    ev = a.header_events()
    parts = [Part("C3D header", "same" if at is None else "differs",
                  (f"{len(ha)} bytes" if at is None else f"byte {at} differs")
                  + (f", {ev} events in its event block" if ev else ""))]
    c = a.contents()
    events = f", EVENT:USED {c['events']}" if c["events"] else ""
    groups = c["parameter_groups"]
    if len(a.records) != len(b.records):
        parts.append(Part("C3D parameters", "differs",
                          f"{len(a.records)} records against {len(b.records)}"))
    else:
        start = a.parameter("POINT", "DATA_START")
        bad = [r.name.decode("latin-1") for r, s in zip(a.records, b.records, strict=True)
               if r != s and not (r is start and r == replace(s, data=r.data))]
        parts.append(Part("C3D parameters", "differs" if bad else "same",
                          f"{groups} groups, {len(a.records) - groups} parameters{events}"
                          + (f"; differ: {', '.join(bad[:5])}" if bad else "")))
    parts.append(Part("point words", "same" if a.slots == b.slots and _bits(a.words, b.words)
                      else "differs", f"residual and camera words, {a.words.shape[1]} points"
                      f" x {a.frames} frames"))
    if a.channels:
        parts.append(Part("analog", "same" if (a.analog_samples == b.analog_samples
                                                and _bits(a.analog, b.analog)) else "differs",
                          f"{a.channels} channels x {a.analog.shape[0]} samples"))
    J = a.models.shape[1]
    if J:
        parts.append(_models(a, b))
    return parts


def _bits(x: NDArray[Any], y: NDArray[Any]) -> bool:
    """The same dtype, shape and bytes (NaNs with their payloads, -0.0 apart from 0.0)."""
    return x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes()


def _models(a: C3DArchive, b: C3DArchive) -> Part:
    """Model outputs: the same gaps, and each coordinate within the decoded bound."""
    J = a.models.shape[1]
    what = f"{J} points"
    if (b.models.shape != a.models.shape or a.model_kinds != b.model_kinds
            or not np.array_equal(a.model_valid, b.model_valid)):
        return Part("model outputs", "differs", f"{what}: other points, kinds or gaps")
    ok = a.model_valid
    err = np.abs(a.models - b.models)[ok]                            # [n, 3]
    e = float(err.max(initial=0.0))
    if b.model_bounds is None:
        return Part("model outputs", "same" if e == 0 else "changed",
                    f"{what}; no bound declared", error=e)
    bound = np.broadcast_to(b.model_bounds[None], a.models.shape)[ok]
    within = bool((err <= bound).all())
    return Part("model outputs", "within" if within else "differs", what, error=e,
                bound=float(b.model_bounds.max(initial=0.0)))


def _skeleton_parts(original: Motion, decoded: Motion,
                    bounds: tuple[float, float] | None) -> list[Part]:
    from mpz.io.kinematics import Skeleton
    from mpz.skeleton import is_rotation
    sa, sb = original.extras.get("skeleton"), decoded.extras.get("skeleton")
    if not isinstance(sa, Skeleton) or original.angles is None:
        return []
    if not isinstance(sb, Skeleton) or decoded.angles is None:
        return [Part("skeleton", "missing", f"{len(sa.joints)} joints and their "
                     f"{sa.channel_count} channels")]
    fields = [f.name for f in dataclasses.fields(sa)
              if getattr(sa, f.name) != getattr(sb, f.name)]
    parts = [Part("skeleton", "differs" if fields else "same", f"{len(sa.joints)} joints"
                  + (f"; differ: {', '.join(fields)}" if fields else ""))]
    x, y = original.angles, decoded.angles
    if x.shape != y.shape or original.angle_names != decoded.angle_names:
        return parts + [Part("joint channels", "differs",
                             f"{x.shape[1]} channels against {y.shape[1]}, or other names")]
    turns = np.array([is_rotation(k) for k in sa.channel_kinds()], bool)
    to_deg = 180 / math.pi if sa.angle_unit == "rad" else 1.0
    for name, cols, scale, unit, k in (("joint rotations", turns, to_deg, "deg", 0),
                                       ("joint translations", ~turns, 1.0,
                                        "skeleton units", 1)):
        if not cols.any():
            continue
        d = np.abs(x[:, cols] - y[:, cols])
        e = float(d.max(initial=0.0)) * scale
        what = f"{int(cols.sum())} channels, in {unit}"
        if bounds is None:
            parts.append(Part(name, "same" if e == 0 else "changed",
                              f"{what}; no bound declared", error=e))
            continue
        # a value k x step comes back within step / 2 and the rounding of that product
        slack = 4 * np.spacing(np.maximum(np.abs(x[:, cols]), np.abs(y[:, cols])))
        within = bool((d <= bounds[k] / scale + slack).all())
        parts.append(Part(name, "within" if within else "differs", what, error=e,
                          bound=bounds[k]))
    return parts
