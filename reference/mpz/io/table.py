"""NPY and CSV: plain array layouts of marker trajectories.

Contract:

* NPY is float64 ``[frames, markers, 3]`` in the motion's marker order and
  units, NaN at gaps (the layout the conformance suite uses). It carries no
  names, rate or units: readers name markers ``M0, M1, ...`` and take
  ``rate`` (default 1.0) and ``units`` (default ``""``) as arguments.
* CSV has the header ``frame,time,<name>_x,<name>_y,<name>_z,...`` and an
  empty field at a gap. Times are written with ``repr`` so that the rate
  can be recovered exactly (see :func:`rate_from_times`); a CSV source's
  first frame number and time are kept (``csv.FirstFrame``, ``start_time``).
  Units are not stored (default ``""``).
"""
from __future__ import annotations

from collections.abc import Iterable, Iterator
import csv
import io
import itertools
import math
import os
import tokenize

import numpy as np
from numpy.typing import ArrayLike

from mpz.errors import InputFormatError
from mpz.io._common import (
    RowTable,
    StrPath,
    decode_text,
    integer,
    number,
    read_regular,
    reader,
    values_at_gaps,
)
from mpz.motion import Motion, finite_samples

MAX_NPY_BYTES = 1 << 34  # refuse absurd arrays before loading (16 GiB)


def _bad(fmt: str, msg: str) -> InputFormatError:
    return InputFormatError(f"{fmt}: {msg}")


def motion_from_array(arr: ArrayLike, *, rate: float = 1.0, units: str = "",
                      names: Iterable[str] | None = None, source: str = "",
                      fmt: str = "npy", owned: bool = False) -> Motion:
    """A Motion from a ``[frames, markers, 3]`` array with NaN gaps; ``owned``: ``arr`` is
    the caller's to give away, used (and its gaps set to NaN) in place when float64."""
    arr = np.asarray(arr)
    if arr.dtype.kind not in "fiu":
        raise _bad(fmt, f"array dtype {arr.dtype} is not numeric")
    if arr.ndim != 3 or arr.shape[2] != 3:
        raise _bad(fmt, f"array shape {arr.shape} is not (frames, markers, 3)")
    # a copy: gaps are set to NaN in it (an NPY's array is a view of the file's bytes);
    # the CSV reader's own array is taken as it is (issue 15.3)
    pos = arr if owned and arr.dtype == np.float64 else arr.astype(np.float64)
    valid = finite_samples(pos)
    names = list(names) if names is not None else [f"M{i}" for i in range(pos.shape[1])]
    # a sample with one or two coordinates NaN or infinite is a gap, said as the TRC reader
    # says it (it became a gap silently: a QA run of stop 52)
    partial = values_at_gaps(pos, ~valid, names, "with a coordinate empty or NaN" if fmt == "csv"
                             else "with a coordinate NaN or infinite")
    # a sample of infinite coordinates alone holds no finite one, so values_at_gaps says
    # nothing of it, though NaN, not inf, marks a gap: it became one silently (a corpus QA
    # run of stop 55)
    infinite = ~valid & np.isinf(pos).any(axis=2) & ~np.isfinite(pos).any(axis=2)
    if infinite.any():
        n = int(infinite.sum())
        f, m = (int(i) for i in np.argwhere(infinite)[0])
        said = (f"{n} sample{'s' * (n != 1)} with no finite coordinate and an infinite one "
                f"(the first: frame index {f}, marker {names[m]!r}): each is a gap (NaN marks "
                "a gap; an infinite value is no position)")
        partial = f"{partial}; {said}" if partial else said
    pos[~valid] = np.nan
    meta = {"format": fmt}
    if partial:
        meta["warning"] = partial
    if source:
        meta["source"] = source
    return Motion(pos, names, rate, units, valid, meta)


@reader
def read_npy(path: StrPath, *, rate: float | None = None, units: str = "") -> Motion:
    """Read a float ``[frames, markers, 3]`` .npy array (NaN = gap).

    Parameters
    ----------
    path : str or os.PathLike
    rate : float, optional
        Frames per second (not stored in the file). Default: 1.0, assumed, which the
        metadata's ``rate_assumed`` says (as an AMC's 120 Hz).
    units : str, optional
        ``"mm"``, ``"cm"``, ``"m"``, ``"in"`` or ``""`` (unknown, the default).

    Raises
    ------
    InputFormatError
        If the file is not an .npy array of that shape (object arrays are
        refused: ``allow_pickle=False``).
    ValueError
        For a ``rate`` or ``units`` argument out of range (not the file's fault).
    """
    return npy_from_bytes(path, read_regular(path, MAX_NPY_BYTES), rate=rate, units=units)


@reader
def npy_from_bytes(path: StrPath, data: bytes, *, rate: float | None = None,
                   units: str = "") -> Motion:
    """:func:`read_npy` of the file's bytes, read once by :func:`mpz.io.read` (``path``
    names the file; it is not opened). The array is taken from the bytes after the header
    has been checked (:func:`_npy_layout`), not by ``np.load``."""
    shape, fortran, dtype, start = _npy_layout(data)
    arr = np.frombuffer(data, dtype=dtype, count=math.prod(shape), offset=start)
    arr = arr.reshape(shape, order="F" if fortran else "C")
    m = motion_from_array(arr, rate=1.0 if rate is None else rate, units=units,
                          source=os.path.basename(os.fspath(path)))
    if rate is None:        # the reader's assumption, said as an AMC's and a CSV's: `mpz
        # show` of an .mpz encoded with --rate 60 said "assumed" (a review of stop 75)
        m.metadata["rate_assumed"] = repr(m.rate)
    return m


def _npy_layout(data: bytes) -> tuple[tuple[int, ...], bool, np.dtype, int]:
    """The shape, Fortran order, dtype and data offset of an .npy file's bytes. Refuses a
    header that does not parse, or whose declared shape and dtype do not fill exactly the
    bytes after it: before anything is allocated by the header (a 2 KB file declaring
    895 TiB), part of the data read (a header of 10 frames over 20), or numpy's header
    parser fails with an exception of its own (``TokenError``)."""
    fmt = np.lib.format
    fh = io.BytesIO(data)
    try:
        version = fmt.read_magic(fh)
        if version == (1, 0):
            shape, fortran, dtype = fmt.read_array_header_1_0(fh)
        elif version == (2, 0):
            shape, fortran, dtype = fmt.read_array_header_2_0(fh)
        else:
            raise _bad("npy", f"format version {version[0]}.{version[1]} is not read "
                              "(numpy writes 1.0, or 2.0 for a long header)")
    except (ValueError, EOFError, SyntaxError, tokenize.TokenError) as exc:
        why = str(exc) if len(str(exc)) <= 120 else str(exc)[:117] + "..."
        raise _bad("npy", f"not a valid .npy header ({why})") from None
    start = fh.tell()
    if dtype.hasobject:
        raise _bad("npy", "holds Python objects (pickled data), not numbers")
    if dtype.subdtype is not None:
        # a header of shape (F, M) and descr ('<f8', (3,)): each element is 3 numbers, the
        # array (F, M, 3) of the element type; it raised numpy's "cannot reshape array of
        # size 24 into shape (4,2)" (a CLI QA run of stop 54). numpy writes no such header
        base, sub = dtype.subdtype
        if fortran:
            raise _bad("npy", f"the header declares a Fortran-ordered array of {dtype}, "
                              "elements that are arrays themselves: their order is not "
                              "defined; write it as a C-ordered array of numbers")
        shape, dtype = (*shape, *sub), base
    if any(int(n) < 0 for n in shape):
        raise _bad("npy", f"the header declares a negative dimension: {tuple(shape)}")
    need = math.prod(int(n) for n in shape) * dtype.itemsize
    if need != len(data) - start:
        raise _bad("npy", f"the header declares {tuple(shape)} {dtype} ({need} bytes of "
                          f"data), but the file holds {len(data) - start} after it")
    return tuple(int(n) for n in shape), bool(fortran), dtype, start


def write_npy(motion: Motion, path: StrPath) -> None:
    """Write ``motion.as_nan()`` (float64 ``[frames, markers, 3]``) as .npy: the positions
    alone, without the names, rate and units (:func:`mpz.io.write` says so in its notes).

    Parameters
    ----------
    motion : Motion
    path : str or os.PathLike
        The file, written in place (:func:`mpz.io.write` writes through a hidden file
        beside it, renamed when whole, and says what the format does not hold).
    """
    with open(path, "wb") as fh:
        # as_nan() is already a new float64 array: no second copy (issue 11.1, §8 budget)
        np.save(fh, motion.as_nan().astype(np.float64, copy=False), allow_pickle=False)


def rate_from_times(times: ArrayLike, tolerance: ArrayLike = 0.0) -> float:
    """The frame rate whose ``t0 + frame / rate`` reproduces ``times`` exactly.

    From t0 = 0 (what :func:`format_csv` writes): the float64 within 8 ulps of
    ``1 / times[1]`` that does, so a rate such as 65.0364227294921875 survives a CSV round
    trip bit-exactly, else the rate of fewest significant digits that does. From another
    t0, the rate of fewest digits first (the ulps around 1 / (t1 - t0) gave
    99.99999999999991 for times from 1.0 at 100 Hz: a QA run of stop 52), then the ulps.
    Else the rate of fewest digits whose times are all within ``tolerance`` (one figure,
    or one per time) of the column (times printed to a few decimals: 0.016667 at 60 Hz
    gave 59.99997 Hz); else ``(n - 1) / (t[-1] - t[0])``.
    """
    t = np.asarray(times, dtype=np.float64)
    if len(t) < 2 or not np.isfinite(t).all():
        raise ValueError("need at least two finite times to infer the frame rate")
    span = t[-1] - t[0]
    if not span > 0:
        raise ValueError("times do not increase")
    frames = np.arange(len(t), dtype=np.float64)
    t0 = float(t[0])
    fit = float((len(t) - 1) / span)

    def gives(r: float, within: ArrayLike) -> bool:
        got = t0 + frames / r if t0 else frames / r
        return bool(r > 0 and (np.abs(got - t) <= within).all())

    def ulps() -> float | None:
        step = t[1] - t0
        if not step > 0:
            return None
        r = 1.0 / step
        for _ in range(8):  # a few ulps either side
            r = np.nextafter(r, -np.inf)
        for _ in range(17):
            if gives(float(r), 0.0):
                return float(r)
            r = np.nextafter(r, np.inf)
        return None

    nice = [float(f"{fit:.{digits}g}") for digits in range(1, 16)]
    if t0 == 0.0:      # the writer's own times: the exact rate, before a rounder one that
        exact = ulps()  # also gives 2 or 3 times (494.12123170888594 Hz, a review)
        if exact is not None:
            return exact
    for r in nice:                      # the rate of fewest digits that gives them exactly
        if gives(r, 0.0):
            return r
    exact = ulps() if t0 != 0.0 else None
    if exact is not None:
        return exact
    for r in nice:                      # else the one of fewest digits within the tolerance
        if gives(r, tolerance):
            return r
    return fit


@reader
def read_csv(path: StrPath, *, rate: float | None = None, units: str = "") -> Motion:
    """Read the CSV layout ``frame,time,<name>_x,<name>_y,<name>_z,...``.

    Parameters
    ----------
    path : str or os.PathLike
    rate : float, optional
        Override; default: recovered from the time column.
    units : str, optional
        ``"mm"``, ``"cm"``, ``"m"``, ``"in"`` or ``""`` (the default: CSV does not store
        units).

    Raises
    ------
    InputFormatError
    ValueError
        For a ``rate`` or ``units`` argument out of range (not the file's fault).
    """
    return csv_from_bytes(path, read_regular(path), rate=rate, units=units)


@reader
def csv_from_bytes(path: StrPath, data: bytes, *, rate: float | None = None,
                   units: str = "") -> Motion:
    """:func:`read_csv` of the file's bytes, read once by :func:`mpz.io.read` (``path``
    names the file; it is not opened)."""
    return parse_csv(decode_text(data), rate=rate, units=units,
                     source=os.path.basename(os.fspath(path)))


def parse_csv(text: str, *, rate: float | None = None, units: str = "",
              source: str = "") -> Motion:
    """Parse CSV text (see :func:`read_csv`)."""
    # read a record at a time into arrays: a list of every row's fields took 13 bytes of
    # memory per byte of CSV (a QA of stop 50); csv.reader takes lines, "\n" kept
    records = _records(text)
    first = next(records, None)
    if first is None:
        raise _bad("csv", "empty file")
    head = [h.strip() for h in first]
    if head[:2] != ["frame", "time"]:
        raise _bad("csv", f"header must start with 'frame,time', got {head[:2]}")
    cols = head[2:]
    if len(cols) == 0 or len(cols) % 3:
        raise _bad("csv", f"{len(cols)} coordinate columns is not a positive multiple of 3")
    names: list[str] = []
    for i in range(0, len(cols), 3):
        base = [c[:-2] for c in cols[i:i + 3]]
        sfx = [c[-2:] for c in cols[i:i + 3]]
        if sfx != ["_x", "_y", "_z"] or len(set(base)) != 1:
            raise _bad("csv", f"columns {cols[i:i + 3]} are not <name>_x,<name>_y,<name>_z")
        names.append(base[0])
    # the rows come in two tables, the times and the coordinates, each made at once the
    # size of the lines after the header (blank lines are rare; with them the table is
    # copied to its rows' size at the end), so that the coordinates are the motion's
    # positions without a copy, and the text is let go before them (a 30-minute CSV of
    # 515 MB peaked at 1.86 GB, with a table of the time and coordinates that doubled as
    # rows came, then two copies of it: issue 15.3). At most twice the text's bytes are
    # made at once, and only once a row has passed its checks: a wide header over many
    # short lines asked 8 bytes a character, and 30 s to count them, before its first row
    # was refused (a review of stop 77); beyond that the table grows as rows come
    end = "\n" if "\n" in text else "\r"            # as _lines ends a line
    lines = text.count(end) + (not text.endswith(end))
    rows = max(1, min(lines - 1, 2 * len(text) // (8 * len(cols))))
    times_table = table = None          # made when the first row has passed its checks
    # the frame column: consecutive whole numbers from its first, kept as csv.FirstFrame;
    # it was not read at all, and frames from 100 came back from 0 (a QA run of stop 52)
    first_frame: int | None = None
    frame_fault = ""
    resolution: list[float] = []                # each time's last printed digit: its unit
    for k, r in enumerate(records):
        if len(r) != len(head):
            raise _bad("csv", f"row {k + 2} has {len(r)} fields, header has {len(head)}")
        if not frame_fault:
            f = _whole(r[0])
            if k == 0 and f is not None:
                first_frame = f
            if f is None or first_frame is None or f != first_frame + k:
                frame_fault = f"row {k + 2} has frame {r[0].strip()!r}"
        resolution.append(_unit_of_last_digit(r[1]))
        try:
            t = number(r[1])                    # the time first, as it always was
            values = [number(v, nan=True) if v.strip(" \t") else math.nan for v in r[2:]]
        except InputFormatError as exc:
            raise _bad("csv", f"row {k + 2}: {exc.message}") from None
        if times_table is None or table is None:
            times_table, table = RowTable(1, expect=rows), RowTable(len(cols), expect=rows)
        times_table.append([t])
        table.append(values)
    del records, text
    if times_table is None or table is None:
        raise _bad("csv", "no data rows")
    n = table.n
    times, vals = times_table.rows()[:, 0], table.rows()
    warnings = []
    # each time may be off by half a unit of its own last digit (0.0 by 0.05, 1.234567e-02
    # by 5e-9: one figure for every row took 0.5 s for times in scientific notation, a
    # review of stop 52), and what binary64 adds
    tolerance = 0.5 * np.array(resolution) + 4 * np.spacing(np.abs(times).max(initial=0))
    assumed = rate is None and n <= 1      # one time gives no rate: 1 Hz is assumed
    if rate is None:
        # rate_from_times' ValueError came out as "cannot read: ValueError: times do not
        # increase", naming no row (a CLI QA run of stop 54)
        back = np.flatnonzero(np.diff(times) <= 0)
        if back.size:
            k = int(back[0]) + 1
            raise _bad("csv", f"the times do not increase, and the rate is taken from "
                       f"them: row {k + 2} has time {float(times[k])!r}, after "
                       f"{float(times[k - 1])!r} in row {k + 1}")
        rate = rate_from_times(times, tolerance) if n > 1 else 1.0
        # one rate stands for every time: a column that is not t0 + k / rate (a quarter of
        # a frame allows times printed to a few decimals) would be read as another motion
        off = np.abs(times - times[0] - np.arange(len(times)) / rate)
        if len(times) > 1 and off.max() > 0.25 / rate:
            k = int(np.argmax(off))
            raise _bad("csv", f"the times are not evenly spaced: row {k + 2} has "
                              f"{float(times[k])!r} where {rate:g} Hz gives "
                              f"{float(times[0] + k / rate)!r} (mpz encode --rate ignores the "
                              "time column)")
        beyond = off > tolerance
        if beyond.any():     # the TRC reader says so too (a QA run of stop 52: silent here)
            k = int(np.flatnonzero(beyond)[0])
            warnings.append(f"the time column is not the first time plus frame / rate "
                            f"({rate!r} Hz) at {int(beyond.sum())} of {n} rows (the first: row "
                            f"{k + 2}, {float(times[k])!r} s where the rate gives "
                            f"{float(times[0] + k / rate)!r}): those times are not kept, a "
                            "CSV written back takes them from the rate")
    if frame_fault:
        warnings.append(f"the frame column is not consecutive whole numbers ({frame_fault}): "
                        "not kept, a CSV written back numbers its frames from 0")
    m = motion_from_array(vals.reshape(n, -1, 3), rate=rate, units=units,
                          names=names, source=source, fmt="csv", owned=True)
    if assumed:             # as an AMC's: not compared with another rate (mpz.metrics)
        m.metadata["rate_assumed"] = repr(float(rate))
    if not frame_fault and first_frame:
        m.metadata["csv.FirstFrame"] = str(first_frame)
    if times[0] != 0.0 and math.isfinite(times[0]):
        m.metadata["start_time"] = repr(float(times[0]))
    if warnings:
        m.metadata["warning"] = "; ".join([*filter(None, [m.metadata.get("warning")]),
                                           *warnings])
    return m


def _unit_of_last_digit(text: str) -> float:
    """The value of one unit in the last digit of a number as written: 0.01 for "1.25",
    1 for "5", 1e-8 for "1.234567e-02" (a time's printing precision)."""
    t = text.strip()
    mant, _, exp = t.replace("E", "e").partition("e")
    at = mant.find(".")
    digits = len(mant) - at - 1 if at >= 0 else 0
    try:
        shift = int(exp) if exp else 0
    except ValueError:
        shift = 0
    return 10.0 ** (shift - digits) if -300 < shift - digits < 300 else 0.0


def _whole(text: str) -> int | None:
    """A frame number as written: a whole number, also in float form ("3.0",
    "0.000000000000000000e+00", numpy.savetxt's), else None."""
    try:
        return integer(text)
    except InputFormatError:
        pass
    try:
        v = number(text)        # not float(): "٣", "３" and "1_0" were frames 3, 3 and 10
    except InputFormatError:
        return None
    return int(v) if v.is_integer() and abs(v) < 2 ** 53 else None


def _records(text: str) -> Iterator[list[str]]:
    """The non-empty records of CSV text (:func:`_lines`), csv.reader's one error said as a
    line's: a carriage return alone inside a file whose lines end with a line feed (mixed
    line ends) gave "new-line character seen in unquoted field" (a review of stop 55)."""
    reader = csv.reader(_lines(text))
    while True:
        try:
            r = next(reader)
        except StopIteration:
            return
        except csv.Error as exc:
            why = ("a carriage return alone inside a line: are the line ends mixed?"
                   if "new-line" in str(exc) else str(exc))
            raise _bad("csv", f"line {reader.line_num}: {why}") from None
        if r:
            yield r


def _lines(text: str) -> Iterator[str]:
    """The lines of ``text``, each with its end, one at a time: a line feed (a carriage
    return before it is csv's), or a carriage return alone in a text without a line feed
    (the old Mac line end, which spreadsheets still write: csv.reader met the whole file
    as one line, "new-line character seen in unquoted field", a CLI QA run of stop 54)."""
    end_of_line = "\n" if "\n" in text else "\r"
    start = 0
    while start < len(text):
        end = text.find(end_of_line, start) + 1 or len(text)
        yield text[start:end]
        start = end


def format_csv(motion: Motion) -> str:
    """CSV text of a Motion; gaps are empty fields, numbers use ``repr``."""
    return "".join(_csv_lines(motion))


def _csv_lines(motion: Motion) -> Iterator[str]:
    """The lines of :func:`format_csv`, each with its line feed, one at a time:
    :func:`write_csv` writes them as they come (the whole text took 2.8 GB for 2^24
    marker-frames, 3.4 times what decoding needs)."""
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(
        ["frame", "time"] + [f"{n}_{c}" for n in motion.names for c in "xyz"])
    yield buf.getvalue()          # names quoted as csv quotes them
    F, M = motion.n_frames, motion.n_markers
    pos = motion.as_nan().reshape(F, 3 * M)
    first, t0 = csv_start(motion)
    # the rows by hand: a number's repr holds no comma, quote or line break, so csv.writer
    # would write them as they are (a row has at least two fields: no "" for an empty one)
    for f in range(F):
        t = repr(t0 + f / motion.rate if t0 else f / motion.rate)
        vals = ",".join("" if not math.isfinite(v) else repr(v) for v in pos[f].tolist())
        yield f"{first + f},{t}" + (f",{vals}" if M else "") + "\n"


def csv_start(motion: Motion) -> tuple[int, float]:
    """The first frame number and time a CSV is written with: a CSV source's
    (``csv.FirstFrame``, ``start_time``), else 0 and 0.0."""
    meta = motion.metadata
    try:
        first = int(meta.get("csv.FirstFrame", "0"))
    except ValueError:
        first = 0
    try:
        t0 = float(meta.get("start_time", "0")) if meta.get("format") == "csv" else 0.0
    except ValueError:
        t0 = 0.0
    return (first if abs(first) < 2 ** 53 else 0), (t0 if math.isfinite(t0) else 0.0)


def write_csv(motion: Motion, path: StrPath) -> None:
    """Write a Motion as CSV (see :func:`format_csv`).

    Parameters
    ----------
    motion : Motion
    path : str or os.PathLike
        The file, written in place (:func:`mpz.io.write` writes through a hidden file
        beside it, renamed when whole, and says what the format does not hold).
    """
    lines = _csv_lines(motion)
    with open(path, "w", encoding="utf-8", newline="") as fh:
        for batch in iter(lambda: list(itertools.islice(lines, 4096)), []):
            fh.write("".join(batch))
