"""TRC (Motion Analysis / OpenSim marker file) reading and writing.

Contract: :func:`parse_trc` / :func:`format_trc` convert between TRC text
and :class:`mpz.Motion`; :func:`read_trc` / :func:`write_trc` touch files.

Layout (tab-separated)::

    PathFileType  4  (X/Y/Z)  <file name>
    DataRate  CameraRate  NumFrames  NumMarkers  Units  OrigDataRate  ...
    <values of the row above>
    Frame#  Time  <marker 1>  ''  ''  <marker 2>  ''  ''  ...
    ''  ''  X1  Y1  Z1  X2  Y2  Z2 ...
    (optional blank line)
    <frame>  <time>  x  y  z  ...

An empty field or ``NaN`` is a gap (a sample is a gap if any of its three
coordinates is missing). The rate is ``DataRate``; units are ``Units``
(``mm``, ``cm``, ``m``; anything else becomes ``""``).
"""
from __future__ import annotations

import math
import os

import numpy as np

from mpz.errors import InputFormatError
from mpz.io._common import StrPath, decode_text, reader, unique_names
from mpz.motion import Motion

_UNITS = {"mm": "mm", "cm": "cm", "m": "m", "in": "in", "inch": "in", "inches": "in"}


def _bad(msg: str) -> InputFormatError:
    return InputFormatError(f"TRC: {msg}")


def _num(field: str) -> float:
    field = field.strip()
    if field == "":
        return math.nan
    return float(field)  # accepts "NaN", "nan"


def parse_trc(text: str, *, source: str = "") -> Motion:
    """Parse TRC text.

    Parameters
    ----------
    text : str
    source : str, optional
        File name for the metadata.

    Returns
    -------
    Motion

    Raises
    ------
    InputFormatError
        On a missing header line, a header without ``DataRate``/``Units``,
        marker-name and coordinate counts that disagree, a data row that is
        too long or not numeric, or no data rows.
    """
    lines = text.splitlines()
    if len(lines) < 5:
        raise _bad(f"only {len(lines)} lines; a TRC file needs 5 header lines and data")
    if not lines[0].startswith("PathFileType"):
        raise _bad(f"first line must start with 'PathFileType', got {lines[0][:40]!r}")
    keys = [k.strip() for k in lines[1].split("\t")]
    vals = [v.strip() for v in lines[2].split("\t")]
    header = {k: v for k, v in zip(keys, vals, strict=False) if k}
    if "DataRate" not in header:
        raise _bad("header has no DataRate")
    rate = float(header["DataRate"])
    units_raw = header.get("Units", "").strip()
    units = _UNITS.get(units_raw.lower(), "")
    name_row = lines[3].rstrip("\r\n").split("\t")
    if len(name_row) < 2 or name_row[0].strip() != "Frame#":
        raise _bad(f"line 4 must start with 'Frame#', got {lines[3][:40]!r}")
    # marker names sit every third column from column 2
    raw_names = [n.strip() for n in name_row[2:]]
    names = [raw_names[i] for i in range(0, len(raw_names), 3)]
    while names and names[-1] == "":  # trailing tabs
        names.pop()
    coord_row = [c.strip() for c in lines[4].split("\t")[2:]]
    while coord_row and coord_row[-1] == "":
        coord_row.pop()
    n_markers = len(names)
    declared = header.get("NumMarkers")
    if declared not in (None, "") and int(float(declared)) != n_markers:
        if int(float(declared)) < n_markers and all(n == "" for n in names[int(float(declared)):]):
            n_markers = int(float(declared))
            names = names[:n_markers]
        else:
            raise _bad(f"NumMarkers says {declared}, the name row has {n_markers} names")
    if n_markers == 0:
        raise _bad("no marker names")
    if len(coord_row) < 3 * n_markers:
        raise _bad(f"coordinate row has {len(coord_row)} labels for {n_markers} markers")

    rows = []
    times = []
    for lineno, line in enumerate(lines[5:], 6):
        if not line.strip():
            continue
        fields = line.rstrip("\r\n").split("\t")
        if len(fields) < 2:
            raise _bad(f"line {lineno}: data row has {len(fields)} field(s)")
        values = fields[2:]
        # tolerate trailing empty columns, not extra data
        while len(values) > 3 * n_markers and values[-1].strip() == "":
            values.pop()
        if len(values) > 3 * n_markers:
            raise _bad(f"line {lineno}: {len(values)} values for {n_markers} markers")
        row = [_num(v) for v in values] + [math.nan] * (3 * n_markers - len(values))
        rows.append(row)
        times.append(_num(fields[1]))
    if not rows:
        raise _bad("no data rows")
    pos = np.array(rows, dtype=np.float64).reshape(len(rows), n_markers, 3)
    declared_frames = header.get("NumFrames", "").strip()
    meta = {"format": "trc"}
    if declared_frames and int(float(declared_frames)) != len(rows):
        meta["warning"] = f"NumFrames says {declared_frames}, file has {len(rows)} rows"
    valid = np.isfinite(pos).all(axis=2)
    pos[~valid] = np.nan
    names, renamed = unique_names(names)
    if renamed:
        meta["renamed_points"] = "; ".join(renamed)
    if source:
        meta["source"] = source
    if units_raw and not units:
        meta["units_in_file"] = units_raw
    if times and math.isfinite(times[0]):
        meta["start_time"] = repr(times[0])
    return Motion(pos, names, rate, units, valid, meta)


def _fmt(v: float) -> str:
    return "" if not math.isfinite(v) else f"{v:.6f}"


def format_trc(motion: Motion, *, file_name: str = "") -> str:
    """TRC text for a Motion (OpenSim layout, 6 decimals, gaps as empty fields).

    The rate is written with ``repr`` so that it reads back exactly.
    """
    rate = repr(float(motion.rate))
    F, M = motion.n_frames, motion.n_markers
    out = [
        f"PathFileType\t4\t(X/Y/Z)\t{file_name}",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t"
        "OrigDataStartFrame\tOrigNumFrames",
        f"{rate}\t{rate}\t{F}\t{M}\t{motion.units}\t{rate}\t1\t{F}",
        "Frame#\tTime\t" + "\t".join(f"{n}\t\t" for n in motion.names),
        "\t\t" + "\t".join(f"X{i}\tY{i}\tZ{i}" for i in range(1, M + 1)),
        "",
    ]
    pos = motion.as_nan()
    for f in range(F):
        vals = "\t".join(_fmt(v) for v in pos[f].ravel())
        out.append(f"{f + 1}\t{f / motion.rate:.6f}\t{vals}")
    return "\n".join(out) + "\n"


@reader
def read_trc(path: StrPath) -> Motion:
    """Read a TRC file (see :func:`parse_trc`).

    Raises
    ------
    InputFormatError
    """
    with open(path, "rb") as fh:
        text = decode_text(fh.read())
    return parse_trc(text, source=os.path.basename(os.fspath(path)))


def write_trc(motion: Motion, path: StrPath, *, file_name: str | None = None) -> None:
    """Write a Motion as TRC (see :func:`format_trc`).

    ``file_name`` is the name recorded in the header (default: the base name
    of ``path``); give the final name when ``path`` is a temporary file.
    """
    if file_name is None:
        file_name = os.path.basename(os.fspath(path))
    text = format_trc(motion, file_name=file_name)
    with open(path, "w", encoding="utf-8", newline="\n") as fh:
        fh.write(text)
