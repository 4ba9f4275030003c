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

Nothing of the header is lost (issue 12): every header field as written
(DataRate, CameraRate, OrigDataRate, OrigDataStartFrame, OrigNumFrames, Units,
the file name and type of line 1), the first frame number, the first time and
the decimals of the time and value columns (the most of any row) go to ``metadata`` under ``trc.*``
keys (stored in the MPZ meta chunk), and :func:`format_trc` writes them back,
so that a TRC decoded from a TRC is the same table. The tabs that end header lines 1-5
go to ``trc.TrailingTabs`` when they are not the ones :func:`format_trc` writes.
"""
from __future__ import annotations

from collections.abc import Iterator, Mapping
import itertools
import math
import os
import re

import numpy as np
from numpy.typing import NDArray

from mpz.errors import InputFormatError
from mpz.io._common import (
    LINE_BREAK,
    MAX_FIRST_FRAME,
    RowTable,
    StrPath,
    count,
    decode_text,
    integer,
    most_frames,
    named,
    number,
    number_list,
    read_regular,
    reader,
    samples_problem,
    start_frame,
    unique_names,
    utf8_name,
    values_at_gaps,
)
from mpz.motion import Motion, finite_samples

_UNITS = {"mm": "mm", "cm": "cm", "m": "m", "in": "in", "inch": "in", "inches": "in",
          # the words some exporters write (a QA run of stop 52: 'millimeters' was no unit)
          "millimeters": "mm", "millimetres": "mm", "millimeter": "mm", "millimetre": "mm",
          "centimeters": "cm", "centimetres": "cm", "centimeter": "cm", "centimetre": "cm",
          "meters": "m", "metres": "m", "meter": "m", "metre": "m"}


def _bad(msg: str) -> InputFormatError:
    return InputFormatError(f"TRC: {msg}")


def _num(field: str) -> float:
    field = field.strip(" \t\r\n")      # not str.strip(): a lone U+00A0 is not a gap
    if field == "":
        return math.nan
    return number(field, nan=True)       # "NaN", "nan": a gap


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
    # lines end at CR LF, LF or CR alone, and nowhere else: str.splitlines also breaks at
    # U+0085 (a cp1252 "..." read as Latin-1), U+2028 and form feeds inside a marker name,
    # which made the header refuse itself ("NumMarkers says 2, the name row has 1 names",
    # a QA run of stop 52)
    lines = LINE_BREAK.split(text)
    # the lines hold the text: the caller's copy is let go (issue 15.3: a 30-minute TRC of
    # 320 MB was held three times over, as bytes, text and lines, while its table was made)
    size = len(text)
    del text
    if lines and lines[-1] == "":
        lines.pop()
    if len(lines) < 5:
        raise _bad(f"only {len(lines)} lines; a TRC file needs 5 header lines and data")
    if not lines[0].startswith("PathFileType"):
        raise _bad(f"first line must start with 'PathFileType', got {lines[0][:40]!r}")
    keys = [k.strip() for k in lines[1].split("\t")]
    vals = [v.strip() for v in lines[2].split("\t")]
    header = {k: v for k, v in zip(keys, vals, strict=False) if k}
    if "DataRate" not in header:
        if "\t" not in lines[1] and "DataRate" in lines[1].split():
            # said "header has no DataRate" of a header that has one (a QA run of exporters)
            raise _bad("line 2 is separated by spaces, not tabs: a TRC's fields are "
                       "tab-separated (marker names may hold spaces)")
        raise _bad("header has no DataRate")
    rate = named(number, header["DataRate"], "DataRate", _bad)
    if not (math.isfinite(rate) and rate > 0):
        # was "inconsistent data: frame rate must be finite and positive", naming no field
        raise _bad(f"DataRate {header['DataRate']!r} is not a frame rate: it must be a "
                   "positive number")
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
    listed = (named(count, declared, "NumMarkers", _bad) if declared not in (None, "")
              else n_markers)
    if listed != n_markers:
        if listed < n_markers and all(n == "" for n in names[listed:]):
            n_markers = listed
            names = names[:n_markers]
        else:
            raise _bad(f"NumMarkers says {declared}, the name row has {n_markers} names")
    if n_markers == 0:
        raise _bad("no marker names")
    if len(coord_row) < 3 * n_markers:
        raise _bad(f"coordinate row has {len(coord_row)} labels for {n_markers} markers")
    if all(_is_number(c) for c in lines[4].split("\t") if c.strip()):
        # a file without the X1 Y1 Z1 row: its first frame was taken for the labels and
        # dropped, said only when NumFrames was there to disagree (a QA run of exporters)
        raise _bad(f"line 5 must be the coordinate labels (X1 Y1 Z1 ...), got numbers "
                   f"{lines[4][:40]!r}: is the label row missing? its first frame would be "
                   "lost")

    # (not a list of rows of Python floats: 32 bytes a value); at most the rows that
    # samples_problem lets a text of this length pad
    most = most_frames(n_markers, size)
    # each non-blank line after the header is a row: one past those is refused before any
    # row is read (3.9 MB of 100,000 markers and 100,000 rows of one marker each grew the
    # table to 2.9 GB over 12 s, to be refused at its 672nd row: a fuzzing QA run)
    data_rows = sum(1 for ln in lines[5:] if ln.strip())
    too_many = (samples_problem(most + 1, n_markers, size, "markers")
                if data_rows > most else None)
    if too_many:
        past = next(itertools.islice((k for k, ln in enumerate(lines[5:], 6) if ln.strip()),
                                     most, None))
        raise _bad(f"line {past}: {too_many}: rows shorter than the header are padded with "
                   "gaps, refused before the table grows")
    # ... and so many rows come, or the file is refused: the table is made their size
    table = RowTable(3 * n_markers, most, expect=min(most, data_rows))
    times = []
    numbers: list[str] = []          # the Frame# column
    frames: list[list[str]] = []
    digits = 0                       # significant decimals of the time column
    # the most decimals of the time column and of the values, over every row (the first
    # row's alone gave 1 decimal to a TRC whose times were written by repr from 0.0: every
    # time came back rounded to 0.1 s, and values past a first row of 10.5 lost their
    # decimals: a QA run of stop 52)
    time_decimals = value_decimals = -1
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
        try:
            row = number_list(values, _num)
            times.append(_num(fields[1]))
        except InputFormatError as exc:
            raise _bad(f"line {lineno}: {exc.message}") from None
        table.append(row)
        t = fields[1].strip()
        if "." in t and "e" not in t.lower():      # the time's decimals: printed, significant
            printed = len(t) - t.index(".") - 1
            time_decimals = max(time_decimals, printed)
            digits = max(digits, printed - (len(t) - len(t.rstrip("0"))))
        value_decimals = _most_decimals(line, line.find("\t", len(fields[0]) + 1) + 1,
                                        value_decimals)
        numbers.append(fields[0].strip())
        if not frames:
            frames.append(fields)
    del lines[5:]                    # the header's lines are all that is read again
    n_rows = table.n
    if not n_rows:
        raise _bad("no data rows")
    pos = table.rows().reshape(n_rows, n_markers, 3)
    meta = {"format": "trc"}
    warnings: list[str] = []                     # metadata "warning", joined by "; "
    pos, skipped = _frames_by_number(pos, numbers)
    if skipped:
        warnings.append(skipped)
    declared_frames = header.get("NumFrames", "").strip()
    if declared_frames and named(count, declared_frames, "NumFrames", _bad) != len(pos):
        # the frames as Frame# places them: "NumFrames says 5, file has 5 rows" when rows
        # skipped frames (a QA run of stop 52)
        held = (f"{n_rows} rows" if len(pos) == n_rows
                else f"{n_rows} rows over {len(pos)} frames (Frame# skips some)")
        warnings.append(f"NumFrames says {declared_frames}, file has {held}")
    valid = finite_samples(pos)
    names, renamed = unique_names(names)
    partial = values_at_gaps(pos, ~valid, names, "with 1 or 2 of 3 coordinates empty")
    if partial:
        warnings.append(partial)
    pos[~valid] = np.nan
    if warnings:                                 # second, as it always was
        meta["warning"] = "; ".join(warnings)
    if renamed:
        meta["renamed_points"] = "; ".join(renamed)
    if source:
        meta["source"] = source
    if units_raw and not units:
        meta["units_in_file"] = units_raw
    if times and math.isfinite(times[0]):
        meta["start_time"] = repr(times[0])
    meta.update(_header_meta(lines, header, frames, time_decimals, value_decimals))
    if "trc.TimeDecimals" in meta:
        meta["trc.TimeDigits"] = str(digits)
    if rate > 0 and len(pos) > 1 and not math.isfinite((len(pos) - 1) / rate):
        # a subnormal DataRate: numpy warned of an overflow on stderr and a duration of
        # "inf s" was shown (a fuzzing QA run of stop 54); the TRC writer refuses it too,
        # from the same second frame on (one frame has the one time 0)
        raise _bad(f"DataRate {rate!r} is too small: the frame times (frame / DataRate) "
                   "overflow")
    motion = Motion(pos, names, rate, units, valid, meta)
    if times and math.isfinite(times[0]):        # the writer's times need the motion
        placed = len(pos) != n_rows             # rows put at their Frame# (frames skipped)
        at = (np.array([integer(x) for x in numbers], np.int64) - integer(numbers[0])
              if placed else np.arange(n_rows, dtype=np.int64))
        lost = _times_not_kept(motion, times, at)
        if lost:
            warnings.append(lost)
            motion.metadata["warning"] = "; ".join(warnings)
    tabs, cut = _trailing_tabs(lines[:5], motion)
    if tabs:                                     # last: the keys before keep their order
        motion.metadata["trc.TrailingTabs"] = tabs
    if cut:
        warnings.append(cut)
    # "PathFileType\x80 4 ..." came back as "PathFileType" without a word (a round-trip QA
    # run of mutated files, stop 67): the writer writes the keyword as it is spelled.
    # Blanks alone are stripped: str.strip() also takes U+00A0, U+0085 and the other
    # characters Python counts as white space, which the writer does not give back
    word = _first_field(lines[0])
    respelled = word.strip(" ") != "PathFileType"
    if respelled:
        warnings.append(f"line 1 begins with {word!r}: written back as 'PathFileType'")
    if cut or respelled:
        motion.metadata["warning"] = "; ".join(warnings)
    return motion


def _first_field(line: str) -> str:
    """The first field of line 1: up to its first tab, or, on a line without tabs, up to
    its first blank (U+0020; :func:`_header_meta` splits at any white space there, and
    "PathFileType\xa0 4 ..." then lost its U+00A0)."""
    line = line.rstrip("\r\n")
    return line.split("\t", 1)[0] if "\t" in line else line.split(" ", 1)[0]


def _tabs_at_end(row: str) -> int:
    """The tabs a header line ends with, before any other trailing whitespace: of
    "B\t\t\t " the three tabs are kept and the blank is not (a review of stop 59: they
    were counted as none, and written back as none, where the writer's own gave two)."""
    end = len(row)          # a loop, not a regex: "(\t*)[^\S\t]*\Z" took 27 s for a line
    while end and row[end - 1] != "\t" and row[end - 1].isspace():   # of 40,000 inner tabs
        end -= 1
    core = row[:end]
    return len(core) - len(core.rstrip("\t"))


def _trailing_tabs(rows: list[str], motion: Motion) -> tuple[str, str]:
    """``trc.TrailingTabs`` for a TRC whose header ``rows`` (lines 1-5) end with other tabs
    than :func:`format_trc` writes for ``motion``: the tabs each line ends with, or "" when
    they all end as it writes them (then the meta chunk is what it was before the key; an
    MPZ file without it is written as before); and a warning when a line ends with more
    than MAX_TRAILING_TABS, which are not kept. The writer dropped the tab that ends lines
    4 and 5 of the OpenSim and BTK files and the tabs that pad lines 1-3 of another OpenSim
    file (a fidelity review)."""
    ends = [_tabs_at_end(row) for row in rows]
    if ends == [_tabs_at_end(row) for row in itertools.islice(_trc_lines(motion), 5)]:
        return "", ""
    over = [(i, n) for i, n in enumerate(ends, 1) if n > MAX_TRAILING_TABS]
    cut = "; ".join(f"header line {i} ends with {n} tabs: {MAX_TRAILING_TABS} are written "
                    "back" for i, n in over)
    return " ".join(str(min(n, MAX_TRAILING_TABS)) for n in ends), cut


def _is_number(x: str) -> bool:
    try:
        number(x.strip(), nan=True)
    except InputFormatError:
        return False
    return True


def _is_int(x: str) -> bool:
    try:
        integer(x)
    except InputFormatError:
        return False
    return True


def _frames_by_number(pos: NDArray[np.float64], numbers: list[str]
                      ) -> tuple[NDArray[np.float64], str]:
    """The rows ``pos`` placed by their Frame# when the numbers skip some frames (a TRC
    with rows left out): a motion has one frame per 1 / DataRate, so each missing frame
    becomes a frame of gaps, and a warning says how many. Rows stay as they are, with a
    warning, when the numbers are not increasing integers, or when filling would more
    than double the frames (a hostile Frame# must not allocate without bound)."""
    try:
        n = [integer(x) for x in numbers]
    except InputFormatError:
        bad = next(x for x in numbers if not _is_int(x))
        return pos, (f"the Frame# column is not whole numbers ({bad!r}): the rows are taken "
                     "as consecutive frames at DataRate")
    if any(abs(x) >= 1 << 62 for x in n):
        return pos, ("the Frame# column holds numbers beyond 2^62: the rows are taken as "
                     "consecutive frames at DataRate")
    steps = np.diff(np.array(n, dtype=np.int64))
    if not steps.size or (steps == 1).all():
        return pos, ""
    first_skip = int(np.flatnonzero(steps != 1)[0])
    if (steps < 1).any() or n[-1] - n[0] + 1 > 2 * len(n):
        return pos, (f"the Frame# column is not one number a row (row {first_skip + 2} is "
                     f"frame {n[first_skip + 1]} after {n[first_skip]}): the rows are "
                     "taken as consecutive frames at DataRate")
    out = np.full((n[-1] - n[0] + 1, *pos.shape[1:]), np.nan)
    out[np.array(n) - n[0]] = pos
    missing = len(out) - len(n)
    return out, (f"the Frame# column skips {missing} frame{'s' * (missing != 1)} (the first "
                 f"after frame {n[first_skip]}): they are gaps, so that every frame keeps "
                 "its time")


#: header fields format_trc writes back as they were read (NumFrames and NumMarkers too, when
#: they still count the frames and markers)
_KEPT = ("DataRate", "CameraRate", "NumFrames", "NumMarkers", "Units", "OrigDataRate",
         "OrigDataStartFrame", "OrigNumFrames")


class _MoreDecimals(dict[int, "re.Pattern[str]"]):
    """``[n]``: a pattern of a decimal point followed by n or more digits, not those of a
    mantissa ("1.5E-03" has no decimals here: counted as 1, it was written back as 0.0, a
    review of stop 52), compiled once; n is at most MAX_DECIMALS + 1."""

    def __missing__(self, n: int) -> re.Pattern[str]:
        self[n] = pattern = re.compile(rf"\.(\d{{{n},}})(?![\deE])")
        return pattern


_MORE_DECIMALS = _MoreDecimals()
#: a number in scientific notation: the digits after its point, and its exponent
_SCIENTIFIC = re.compile(r"\d(?:\.(\d*))?[eE]([-+]?\d{1,4})")


def _most_decimals(line: str, start: int, known: int) -> int:
    """The most decimals of the values of a TRC row (from ``start``; 0: the row has none)
    and ``known``, at most MAX_DECIMALS: a value with more than ``known`` is looked for by
    one regular expression (a C scan; per value in Python it made reading 60 % slower),
    and a value in scientific notation counts the decimals of its fixed-point form
    (1.5E-03 has 4: it was written back as 0.0, a review of stop 52)."""
    if not start:
        return known
    more = _MORE_DECIMALS[known + 1].search(line, start) if known < MAX_DECIMALS else None
    while more is not None:
        known = min(len(more.group(1)), MAX_DECIMALS)
        more = (_MORE_DECIMALS[known + 1].search(line, more.end())
                if known < MAX_DECIMALS else None)
    if "e" in line or "E" in line:
        for frac, exp in _SCIENTIFIC.findall(line, start):
            known = max(known, min(max(len(frac) - int(exp), 0), MAX_DECIMALS))
    return known


def _header_meta(lines: list[str], header: dict[str, str], frames: list[list[str]],
                 time_decimals: int, value_decimals: int) -> dict[str, str]:
    """The ``trc.*`` metadata: what the header and the table layout say, as written, and
    the most decimals of the time and value columns over every row (-1: none)."""
    first = lines[0].rstrip("\r\n").split("\t")
    if len(first) == 1:     # fields apart by blanks, not tabs: the type and the file name
        # were dropped without a word, and the line came back as "PathFileType" (a
        # round-trip QA run of mutated files); the file name keeps its blanks
        first = first[0].split(None, 3)
    out = {"trc.PathFileType": "\t".join(first[1:3]),
           "trc.FileName": first[3] if len(first) > 3 else ""}
    raw = dict(zip([k.strip() for k in lines[1].rstrip("\r\n").split("\t")],
                   lines[2].rstrip("\r\n").split("\t"), strict=False))
    for key in _KEPT:
        if key in header:
            out[f"trc.{key}"] = raw.get(key, header[key])      # as written, padding and all
    # what else lines 1-3 hold (a Subject column, an exporter's name after the file name:
    # dropped without a word before, a QA run of stop 52); trailing empty fields are not
    # kept as fields (the OpenSim files pad with tabs: trc.TrailingTabs keeps those)
    names = lines[1].rstrip("\r\n").split("\t")
    values = lines[2].rstrip("\r\n").split("\t")
    more = [(k, values[i] if i < len(values) else "") for i, k in enumerate(names)
            if k.strip() not in _KEPT]
    more += [("", v) for v in values[len(names):]]
    while more and not (more[-1][0].strip() or more[-1][1].strip()):
        more.pop()
    if more:
        out["trc.MoreNames"] = "\t".join(k for k, _ in more)
        out["trc.MoreValues"] = "\t".join(v for _, v in more)
    after = first[4:]
    while after and not after[-1].strip():
        after.pop()
    if after:
        out["trc.MoreFileFields"] = "\t".join(after)
    if frames:
        out["trc.FirstFrame"] = frames[0][0].strip()
        if time_decimals >= 0:
            out["trc.TimeDecimals"] = str(time_decimals)
        if value_decimals >= 0:
            out["trc.Decimals"] = str(value_decimals)
    return out


#: the trc.* entries that hold tab-separated fields: the first line's type, the header
#: fields besides _KEPT (names and values) and the first line's fields after the file name
_TABBED = ("PathFileType", "MoreNames", "MoreValues", "MoreFileFields")

#: the most decimals a TRC's columns are written with (trc.Decimals, trc.TimeDecimals,
#: trc.TimeDigits): more than binary64 holds, far fewer than a hostile value asks for
MAX_DECIMALS = 30
#: the most tabs trc.TrailingTabs gives a header line (1 MB of tabs): a hand-edited 10^12
#: must not ask for a terabyte of text
MAX_TRAILING_TABS = 1 << 20


def trc_meta_problems(meta: Mapping[str, str]) -> dict[str, str]:
    """The ``trc.*`` entries (and ``start_time``) of ``meta`` that :func:`format_trc` cannot
    write back as they are, each with why; the writer uses its own value for them, and
    ``mpz.io.writer_problems`` says so. A file's meta chunk is free text (spec §4.11), and
    these came from one: a DataRate of "abc" and negative decimals crashed the writer,
    decimals of 10^8 asked for 24 GB of text, and a line break in PathFileType wrote a TRC
    that its own reader refused (a fuzzing QA run of stop 48)."""
    bad: dict[str, str] = {}
    for key, value in meta.items():
        if not (key.startswith("trc.") or key == "start_time"):
            continue
        name = key[4:]
        if LINE_BREAK.search(value):    # the reader's line ends (U+2028 is text there)
            bad[key] = "holds a line break"
        elif name == "MoreNames" and {k.strip() for k in value.split("\t")} & set(_KEPT):
            # a second DataRate column would be the one a reader takes (a review of stop 52:
            # written at 100 Hz, read back at 999)
            bad[key] = "names a field the writer writes itself"
        elif name == "PathFileType" and value.count("\t") > 1:
            bad[key] = "holds more than one tab"
        elif name not in _TABBED and "\t" in value:
            bad[key] = "holds a tab"
        elif name == "MoreValues" and value.count("\t") != meta.get(
                "trc.MoreNames", "").count("\t"):
            bad[key] = "does not have a field for each of trc.MoreNames"
        elif name in ("Decimals", "TimeDecimals", "TimeDigits") and not _whole_in(
                value, 0, MAX_DECIMALS):
            bad[key] = f"is not a whole number 0 .. {MAX_DECIMALS}"
        elif name == "FirstFrame" and not _whole_in(value, -MAX_FIRST_FRAME, MAX_FIRST_FRAME):
            bad[key] = "is not a whole number of magnitude below 2^31"
        elif name == "TrailingTabs" and _tab_counts(value) is None:
            bad[key] = (f"is not 5 whole numbers 0 .. {MAX_TRAILING_TABS} (digits, no sign or "
                        "leading zero), one space apart")
        elif (name == "DataRate" or key == "start_time") and not _finite_text(value):
            bad[key] = "is not a finite number"
    return bad


def _tab_counts(text: str) -> list[int] | None:
    """The tabs ``trc.TrailingTabs`` ends the header lines 1-5 with, or None when it is not
    5 whole numbers 0 .. MAX_TRAILING_TABS, one space apart."""
    # as the reader writes it: digits alone ("+1", "0001" and a no-break space were taken)
    if re.fullmatch(r"(?:0|[1-9][0-9]{0,6})(?: (?:0|[1-9][0-9]{0,6})){4}", text) is None:
        return None
    counts = [int(p) for p in text.split(" ")]
    return counts if max(counts) <= MAX_TRAILING_TABS else None


def _counts(text: str, n: int) -> bool:
    """Whether a header count as written (``50``, `` 50``, ``50.0``) reads as ``n``."""
    try:
        return float(text) == n
    except ValueError:
        return False


def _whole_in(text: str, low: int, high: int) -> bool:
    t = text.strip()
    # isdigit is true of "¹" and "١", which int() refuses or reads (hypothesis, stop 50);
    # one sign at most: "+-1" passed lstrip("+-") and int() raised (a review of stop 59)
    digits = t[1:] if t[:1] in ("+", "-") else t
    if not 0 < len(t) <= 12 or not digits.isascii() or not digits.isdigit():
        return False
    return low <= int(t) <= high


def _finite_text(text: str) -> bool:
    try:
        return len(text) <= 100 and math.isfinite(float(text))
    except ValueError:
        return False


def _usable(meta: Mapping[str, str]) -> dict[str, str]:
    """``meta`` without what :func:`trc_meta_problems` names."""
    bad = trc_meta_problems(meta)
    return {k: v for k, v in meta.items() if k not in bad}


def _decimals_in(units: str, read_as: str, decimals: int) -> int:
    """The column decimals a TRC read in ``read_as`` needs in ``units`` to keep its
    resolution (mm with 2 decimals is m with 5), never fewer than it had."""
    from mpz.format import MM_PER_UNIT
    if units == read_as or units not in MM_PER_UNIT or read_as not in MM_PER_UNIT:
        return decimals
    shift = math.ceil(math.log10(MM_PER_UNIT[units] / MM_PER_UNIT[read_as]) - 1e-9)
    return max(decimals, decimals + shift)


def column_decimals(motion: Motion) -> int:
    """The decimals :func:`format_trc` writes the coordinates with: the source TRC's
    (``trc.Decimals``, more when the units were rescaled since), else 6."""
    meta = _usable(motion.metadata)
    read_as = _UNITS.get(meta.get("trc.Units", motion.units).strip().lower(), "")
    try:
        return _decimals_in(motion.units, read_as, int(meta.get("trc.Decimals", "6")))
    except ValueError:
        return 6


def _fmt(v: float, decimals: int = 6) -> str:
    return "" if not math.isfinite(v) else f"{v:.{decimals}f}"


def _time_column(motion: Motion) -> tuple[float, int, int]:
    """How :func:`format_trc` writes the Time column: frame f's time is
    ``round(t0 + f / rate, tdig)`` printed with ``dt`` decimals; returns (t0, dt, tdig).
    A motion read from a TRC keeps its first time and decimals (``start_time``,
    ``trc.TimeDecimals``, ``trc.TimeDigits``); others start at (first frame - 1) / rate,
    6 decimals."""
    meta = _usable(motion.metadata)
    try:
        # a C3D's frame n is at (n - 1) / rate (its frames count from 1)
        on_grid = (start_frame(motion) - 1) / motion.rate
        t0 = float(meta.get("start_time", repr(on_grid)))
        dt = int(meta.get("trc.TimeDecimals", "6"))
        tdig = int(meta.get("trc.TimeDigits", str(dt)))
        if round(t0, tdig) == round(on_grid, tdig):
            # the first time as printed is (first - 1) / rate's: count from that, not from
            # its rounding, so that a file written again keeps every time (a QA run of
            # stop 47: 0.408333 + 1/120 printed 0.416666 where the source had 0.416667)
            t0 = on_grid
    except ValueError:
        return 0.0, 6, 6
    return t0, dt, tdig


def _times_not_kept(motion: Motion, times: list[float], rows: NDArray[np.int64]) -> str:
    """A warning when the Time column is not what :func:`format_trc` writes back (times
    from the first, at the rate): those times are not kept (a QA of stop 48: an edited
    time came back as the rate's without a word). ``rows`` is each row's frame index.
    One unit of the last decimal is allowed for the source's own rounding."""
    t0, _, tdig = _time_column(motion)
    got = np.array(times, dtype=np.float64)
    want = np.round(t0 + rows / motion.rate, tdig)
    with np.errstate(invalid="ignore"):
        off = ~(np.abs(got - want) <= 1.01 * 10.0 ** -tdig)
    n = int(off.sum())
    if not n:
        return ""
    r = int(np.flatnonzero(off)[0])
    return (f"the Time column is not the first time plus (frame - first) / DataRate at {n} "
            f"of {len(times)} rows (the first: frame index {int(rows[r])}, {times[r]!r} s "
            f"where the rate gives {float(want[r])!r}): those times are not kept, a TRC "
            "written back takes them from the rate")


def format_trc(motion: Motion, *, file_name: str = "") -> str:
    """TRC text for a Motion (OpenSim layout, gaps as empty fields): the lines of
    :func:`_trc_lines`, each ended by a line feed."""
    return "".join(line + "\n" for line in _trc_lines(motion, file_name=file_name))


def _trc_lines(motion: Motion, *, file_name: str = "") -> Iterator[str]:
    """The lines of TRC text for a Motion (OpenSim layout, gaps as empty fields), one at a
    time: :func:`write_trc` writes them as they come (the whole text and its lines took
    2.9 GB for 2^24 marker-frames, 3.5 times what decoding needs).

    A motion read from a TRC (``trc.*`` metadata) gets its header fields, first frame
    number, first time and column decimals back (``Units`` and the decimals follow
    ``motion.units`` when the motion was rescaled since); otherwise the rate is written with
    ``repr`` (it reads back exactly), frames from 1, times from 0, 6 decimals.
    ``file_name`` is used when the source's file name is not known.
    """
    meta = _usable(motion.metadata)
    rate = repr(float(motion.rate))
    F, M = motion.n_frames, motion.n_markers
    head = {"DataRate": rate, "CameraRate": rate, "NumFrames": str(F), "NumMarkers": str(M),
            "Units": motion.units, "OrigDataRate": rate, "OrigDataStartFrame": "1",
            "OrigNumFrames": str(F)}
    for key in _KEPT:
        if f"trc.{key}" in meta:
            head[key] = meta[f"trc.{key}"]
    for key, n in (("NumFrames", F), ("NumMarkers", M)):
        if not _counts(head[key], n):      # "50.0" stays as written (a QA run of stop 52)
            head[key] = str(n)
    if float(head["DataRate"]) != motion.rate:        # the header text must give the rate
        head["DataRate"] = rate
    read_as = _UNITS.get(head["Units"].strip().lower(), "")
    if read_as != motion.units:    # the header must give the positions' unit, not a stale one
        head["Units"] = motion.units
    kind = meta.get("trc.PathFileType", "4\t(X/Y/Z)")
    # a TRC source's file name as it was, empty too (the output's name took an empty one's
    # place, and mpz compare then found the header changed: a QA run of stop 52)
    name = meta["trc.FileName"] if "trc.FileName" in meta else file_name
    first = start_frame(motion)
    if "trc.OrigDataStartFrame" not in meta:
        head["OrigDataStartFrame"] = str(first)
    t0, dt, tdig = _time_column(motion)
    try:
        dv = column_decimals(motion)
    except ValueError:
        dv = 6
    more = {k: "\t" + meta[f"trc.{k}"] if f"trc.{k}" in meta else ""
            for k in ("MoreFileFields", "MoreNames", "MoreValues")}
    if bool(more["MoreNames"]) != bool(more["MoreValues"]):
        more["MoreNames"] = more["MoreValues"] = ""
    header = [
        f"PathFileType\t{kind}\t{name}{more['MoreFileFields']}",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t"
        f"OrigDataStartFrame\tOrigNumFrames{more['MoreNames']}",
        f"{head['DataRate']}\t{head['CameraRate']}\t{head['NumFrames']}\t"
        f"{head['NumMarkers']}\t{head['Units']}\t"
        f"{head['OrigDataRate']}\t{head['OrigDataStartFrame']}\t{head['OrigNumFrames']}"
        f"{more['MoreValues']}",
        "Frame#\tTime\t" + "\t".join(f"{n}\t\t" for n in motion.names),
        "\t\t" + "\t".join(f"X{i}\tY{i}\tZ{i}" for i in range(1, M + 1)),
    ]
    # the tabs that end the source's header lines, as they were (meta holds the key only
    # when trc_meta_problems finds it 5 counts)
    tabs = _tab_counts(meta["trc.TrailingTabs"]) if "trc.TrailingTabs" in meta else None
    if tabs is not None:
        header = [row.rstrip("\t") + "\t" * n for row, n in zip(header, tabs, strict=True)]
    yield from [*header, ""]
    pos = motion.as_nan().reshape(F, 3 * M)
    whole = np.isfinite(pos).all(axis=1)
    # a row without a gap in one % (the same text as _fmt's format of each value: 4x
    # faster; 42 s for the rows of 2^24 marker-frames)
    row_format = "\t".join([f"%.{dv}f"] * (3 * M))
    for f in range(F):
        vals = (row_format % tuple(pos[f].tolist()) if whole[f] else
                "\t".join(_fmt(v, dv) for v in pos[f]))
        t = round(t0 + f / motion.rate, tdig)      # the source's significant decimals
        yield f"{first + f}\t{t:.{dt}f}\t{vals}"


@reader
def read_trc(path: StrPath) -> Motion:
    """Read a TRC file (see :func:`parse_trc`); :func:`mpz.io.read` does the same for a
    ``.trc`` name.

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Returns
    -------
    Motion

    Raises
    ------
    InputFormatError
        For a file this reader cannot read, naming it.
    """
    return trc_from_bytes(path, read_regular(path))


@reader
def trc_from_bytes(path: StrPath, data: bytes) -> Motion:
    """:func:`read_trc` of the file's bytes, read once by :func:`mpz.io.read`: ``path``
    names the file in messages and ``metadata["source"]``; it is not opened."""
    return parse_trc(decode_text(data), source=os.path.basename(os.fspath(path)))


def write_trc(motion: Motion, path: StrPath, *, file_name: str | None = None) -> None:
    """Write a Motion as TRC (see :func:`format_trc`).

    Parameters
    ----------
    motion : Motion
    path : str or os.PathLike
        The file, written in place (:func:`mpz.io.write` writes through a hidden file
        beside it, renamed when whole, and says what the format does not hold).
    file_name : str, optional
        The name recorded in the header (default: the base name of ``path``); give the
        final name when ``path`` is a temporary file.

    Raises
    ------
    InputFormatError
        For marker names a TRC line cannot hold (:func:`mpz.io.check_writable`).
    """
    if file_name is None:
        file_name = os.path.basename(os.fspath(path))
    # name safety (issue 11.9): refuse marker names that would break a line or a field, and
    # keep the informational file name on its line (control characters become "?")
    from mpz.io import check_writable
    check_writable(motion, ".trc", path=file_name or os.fspath(path))
    file_name = "".join("?" if ord(c) < 0x20 or 0x7F <= ord(c) <= 0x9F else c
                        for c in utf8_name(file_name))     # a name that is not UTF-8
    lines = _trc_lines(motion, file_name=file_name)
    with open(path, "w", encoding="utf-8", newline="\n") as fh:
        for batch in iter(lambda: list(itertools.islice(lines, 4096)), []):
            fh.write("".join(line + "\n" for line in batch))
