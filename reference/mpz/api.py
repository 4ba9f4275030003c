"""File-level helpers around the sans-IO core: read, write (atomically), summary.

Only this module and :mod:`mpz.io` touch the file system.
"""
from __future__ import annotations

import os
from pathlib import Path
import tempfile

import numpy as np

from mpz.errors import EncoderError, FormatError, MPZError


def write_atomic(path, data: bytes, *, source=None) -> None:
    """Write ``data`` to ``path`` via a temporary file and a rename.

    No partial file is ever left at ``path``; ``path`` must not be the
    ``source`` file (the encoder never overwrites its input).
    """
    path = Path(path)
    if source is not None:
        try:
            if path.exists() and os.path.samefile(path, source):
                raise EncoderError(f"refusing to overwrite the input file {source}")
        except OSError:
            pass
        if path.resolve() == Path(source).resolve():
            raise EncoderError(f"refusing to overwrite the input file {source}")
    directory = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=directory)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def read_mpz(path, **kw):
    """Decode the MPZ file at ``path`` into a Motion."""
    from mpz.decoder import decode
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise FormatError(f"cannot read: {exc.strerror or exc}", path=str(path)) from None
    try:
        return decode(data, **kw)
    except MPZError as exc:
        exc.path = str(path)
        raise


def write_mpz(motion, path, *, source=None, **options):
    """Encode ``motion`` and write it atomically; returns the EncodeReport."""
    from mpz.encoder import EncodeOptions, encode_motion
    data, report = encode_motion(motion, EncodeOptions(**options))
    write_atomic(path, data, source=source)
    return report


class SummaryLevel:
    """One level of the smry chunk, dequantised."""

    def __init__(self, k, starts, means, wssse, step):
        self.k, self.starts, self.means, self.wssse, self.step = k, starts, means, wssse, step

    def __repr__(self):
        return f"SummaryLevel(k={self.k}, wssse={self.wssse:.6g})"


class Summary:
    """The optimal-partition summary of a file (spec §4.10), read without decoding motion."""

    def __init__(self, space, dims, levels, n_frames, rate, names, units):
        self.space, self.dims, self.levels = space, dims, levels
        self.n_frames, self.rate, self.names, self.units = n_frames, rate, names, units

    def level(self, k):
        for lv in self.levels:
            if lv.k == k:
                return lv
        raise KeyError(k)

    def preview(self, k=None, mode="constant"):
        """A preview Motion rebuilt from the summary alone (positions relative to the root)."""
        from mpz.fisher import preview_series
        from mpz.motion import Motion
        if self.space != "positions":
            raise FormatError("a preview Motion needs a position summary (space 0)")
        lv = self.levels[-1] if k is None else self.level(k)
        series = preview_series(lv.starts, lv.means, self.n_frames, mode=mode)
        pos = series.reshape(self.n_frames, -1, 3)
        return Motion(pos, list(self.names), self.rate, self.units,
                      metadata={"preview": f"summary k={lv.k} ({mode})"})


def read_summary(data: bytes) -> Summary | None:
    """Read the smry chunk of an MPZ file without decoding the motion.

    Returns None when the file has no summary chunk.

    Raises
    ------
    MPZError
        If the file is invalid.
    """
    from mpz.decoder import UNIT_CODES, read_stream
    s = read_stream(data)
    if s.summary is None:
        return None
    f = s.summary.fields
    levels = []
    for lv in f.levels:
        starts = np.frombuffer(lv.starts, "<u4").astype(np.int64)
        means = np.frombuffer(lv.means, "<i4").astype(np.float64).reshape(lv.k, f.dims) * lv.step
        levels.append(SummaryLevel(lv.k, starts, means, lv.wssse, lv.step))
    space = "positions" if f.space == 0 else "angles"
    return Summary(space, f.dims, levels, s.header.frame_count, s.header.rate, s.names,
                   UNIT_CODES[s.header.units])
