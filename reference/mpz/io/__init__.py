"""Readers and writers for motion-capture files: ``mpz.io``.

Contract: :func:`read` and :func:`write` dispatch on the file extension
through the explicit tables :data:`READERS` and :data:`WRITERS`. Every
reader returns a :class:`mpz.Motion` and raises only
:class:`mpz.errors.InputFormatError` (naming the file and the reason) for
input it cannot read; parsing errors of other types never escape.

========  =======  =======  ==========================================
suffix    read     write    notes
========  =======  =======  ==========================================
.c3d      yes      yes      ezc3d, pure-numpy fallback (MIPS, quirks)
.trc      yes      yes      OpenSim/Motion Analysis marker file
.bvh      yes      no       FK joint centres + end sites, units ""
.amc      yes      no       needs the .asf; FK joint positions in mm
.npy      yes      yes      float64 [frames, markers, 3], NaN gaps
.csv      yes      yes      frame,time,<name>_x,<name>_y,<name>_z,...
========  =======  =======  ==========================================

Examples
--------
>>> import numpy as np, tempfile, os
>>> from mpz import Motion
>>> from mpz.io import read, write
>>> m = Motion(np.arange(6.0).reshape(2, 1, 3), ["A"], rate=100.0)
>>> with tempfile.TemporaryDirectory() as d:
...     write(m, os.path.join(d, "a.trc"))
...     back = read(os.path.join(d, "a.trc"))
>>> back.names, back.rate, back.units
(['A'], 100.0, 'mm')
"""
from __future__ import annotations

from collections.abc import Callable
import os

from mpz.errors import InputFormatError
from mpz.io._common import StrPath, ext_of
from mpz.io.amc import find_asf, read_amc, read_asf
from mpz.io.bvh import read_bvh
from mpz.io.c3d import read_c3d, write_c3d
from mpz.io.table import read_csv, read_npy, write_csv, write_npy
from mpz.io.trc import read_trc, write_trc
from mpz.motion import Motion

#: extension -> reader(path, **options)
READERS: dict[str, Callable[..., Motion]] = {
    ".c3d": read_c3d,
    ".trc": read_trc,
    ".bvh": read_bvh,
    ".amc": read_amc,
    ".npy": read_npy,
    ".csv": read_csv,
}

#: extension -> writer(motion, path)
WRITERS: dict[str, Callable[..., None]] = {
    ".c3d": write_c3d,
    ".trc": write_trc,
    ".npy": write_npy,
    ".csv": write_csv,
}

FORMAT_NAMES = {".c3d": "C3D", ".trc": "TRC", ".bvh": "BVH", ".amc": "AMC/ASF",
                ".npy": "NPY", ".csv": "CSV"}


def read(path: StrPath, *, asf: StrPath | None = None, rate: float | None = None) -> Motion:
    """Read a motion-capture file, choosing the reader by extension.

    Parameters
    ----------
    path : str or os.PathLike
        A ``.c3d``, ``.trc``, ``.bvh``, ``.amc``, ``.npy`` or ``.csv`` file.
    asf : str or os.PathLike, optional
        Skeleton for ``.amc``; default: the longest ``*.asf`` in the same
        folder whose stem is a prefix of the AMC stem.
    rate : float, optional
        Frame rate for formats that do not store one (``.amc``: default
        120, ``.npy``: default 1.0, ``.csv``: default from the time column).
        Ignored by formats that store a rate.

    Returns
    -------
    Motion

    Raises
    ------
    InputFormatError
        Unknown extension, missing file ("no such file"), or unreadable content.
    """
    ext = ext_of(path)
    fn = READERS.get(ext)
    if fn is None:
        raise InputFormatError(
            f"unknown file extension {ext or '(none)'!r}; can read {', '.join(READERS)}",
            path=os.fspath(path))
    if ext == ".amc":
        return fn(path, asf, **({} if rate is None else {"rate": rate}))
    if ext in (".npy", ".csv") and rate is not None:
        return fn(path, rate=rate)
    return fn(path)


def write(motion: Motion, path: StrPath, *, file_name: str | None = None) -> None:
    """Write a Motion, choosing the writer by extension.

    Parameters
    ----------
    motion : Motion
    path : str or os.PathLike
        A ``.c3d``, ``.trc``, ``.npy`` or ``.csv`` file name.
    file_name : str, optional
        The name to record in formats that store their own file name (TRC);
        default: the base name of ``path``. For writing to a temporary file.

    Raises
    ------
    InputFormatError
        For an extension no writer handles.
    """
    ext = ext_of(path)
    fn = WRITERS.get(ext)
    if fn is None:
        raise InputFormatError(
            f"cannot write {ext or '(no extension)'!r}; can write {', '.join(WRITERS)}",
            path=os.fspath(path))
    if file_name is not None and ext == ".trc":
        fn(motion, path, file_name=file_name)
    else:
        fn(motion, path)


__all__ = ["read", "write", "READERS", "WRITERS", "FORMAT_NAMES",
           "read_c3d", "write_c3d", "read_trc", "write_trc", "read_bvh",
           "read_amc", "read_asf", "find_asf", "read_npy", "write_npy",
           "read_csv", "write_csv"]
