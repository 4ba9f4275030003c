"""Helpers shared by the format modules of :mod:`mpz.io`.

Contract: :func:`reader` is the single error boundary of every public
``read_*`` function. Whatever a parser raises while reading a file
(``KeyError``, ``IndexError``, ``struct.error``, ``UnicodeDecodeError``,
``OSError``, a :class:`~mpz.errors.MotionError` from inconsistent data, ...)
leaves as :class:`~mpz.errors.InputFormatError` naming the file and the
reason. Only the file-touching wrappers use it; parsers take ``str``/``bytes``.
"""
from __future__ import annotations

import codecs
from collections.abc import Callable, Iterable, Iterator
import csv
import functools
import inspect
import math
import os
import re
import struct
from typing import BinaryIO, ParamSpec, TypeAlias, TypeVar

import numpy as np
from numpy.typing import NDArray

from mpz.errors import InputFormatError, MPZError
from mpz.format import MAX_SAMPLES
from mpz.motion import Motion

#: a file name as the readers and writers accept it
StrPath: TypeAlias = str | os.PathLike[str]

_P = ParamSpec("_P")
_R = TypeVar("_R")
_N = TypeVar("_N", int, float)

#: exception types a parser may raise on bad input; translated by type: the ones that
#: the standard library's parsing raises on bad text or bytes (``int("x")``, ``struct``,
#: a codec, a short read, the csv module). ``MemoryError`` is not one: running out of
#: memory says nothing about the file, and the tools report it as its own exit code
#: (issue 11.3). Neither are IndexError, KeyError, TypeError, AttributeError,
#: ZeroDivisionError and RuntimeError (translated until stop 45): they are bugs of the
#: reader, which must check what it indexes, and surface as such (a mutant sweep of
#: 5,800 real-file mutants, every reader, found none left to translate)
_PARSE_ERRORS = (ValueError, struct.error, UnicodeDecodeError, OSError, OverflowError,
                 EOFError, csv.Error)


#: where a line of a text motion file ends: CR LF, LF or CR alone, and nowhere else
#: (str.splitlines also breaks at U+0085, U+2028 and form feeds inside a name or a row)
LINE_BREAK = re.compile(r"\r\n|\r|\n")


def split_lines(text: str) -> Iterator[str]:
    """``LINE_BREAK.split(text)``, one line at a time: a reader that reads each line once
    holds one, not a list of them all (the lines of a 30-minute AMC took 0.5 GB, three
    times its text: issue 15.3)."""
    start = 0
    for m in LINE_BREAK.finditer(text):
        yield text[start:m.start()]
        start = m.end()
    yield text[start:]


def _reason(exc: BaseException) -> str:
    text = str(exc) or type(exc).__name__
    return f"{type(exc).__name__}: {text}" if not isinstance(exc, MPZError) else text


def translate(path: StrPath, exc: BaseException) -> InputFormatError:
    """The :class:`InputFormatError` to raise for ``exc`` met while reading ``path``."""
    p = os.fspath(path)
    if isinstance(exc, InputFormatError):
        if exc.path is None:
            exc.path = p
        return exc
    if isinstance(exc, FileNotFoundError):
        return InputFormatError("no such file", path=p)
    if isinstance(exc, IsADirectoryError):
        return InputFormatError("is a directory, not a file", path=p)
    return InputFormatError(f"cannot read: {_reason(exc)}", path=p)


def _finite(x: float | np.integer | np.floating) -> bool:
    """math.isfinite, False for an int past binary64's range (10**400 raised a raw
    OverflowError from read(p, rate=...), a QA run of the API at stop 54)."""
    try:
        return math.isfinite(x)
    except OverflowError:
        return False


def check_rate_argument(rate: object) -> None:
    """Raise ValueError unless ``rate`` (a reader's argument, not the file's) is None or a
    finite number of frames per second above 0: a bad argument is the caller's, not the
    file's, to blame."""
    number = (int, float, np.integer, np.floating)
    if rate is not None and (isinstance(rate, bool) or not isinstance(rate, number)
                             or not (_finite(rate) and rate > 0)):
        raise ValueError(f"rate must be a finite number of frames per second above 0, got "
                         f"{rate!r}")


def check_units_argument(units: object) -> None:
    """Raise ValueError unless ``units`` (a reader's argument) is one of
    :data:`mpz.motion.UNITS`: a bad unit was reported as the file's fault ("x.npy:
    inconsistent data: unknown units 'MM'", an API user's QA run of stop 72), as a bad
    rate was before :func:`check_rate_argument`."""
    from mpz.motion import UNITS
    if not isinstance(units, str) or units not in UNITS:
        raise ValueError(f"units must be one of {', '.join(map(repr, UNITS))}, got {units!r}")


def reader(func: Callable[_P, _R]) -> Callable[_P, _R]:
    """Decorate a ``read_*(path, ...)`` function with the error boundary: the file's faults
    become InputFormatErrors naming it, a bad ``rate`` or ``units`` argument a ValueError
    (:func:`check_rate_argument`, :func:`check_units_argument`). The signature is kept
    whole, so that type checkers take the path by keyword too (``read_c3d(path=p)``)."""
    first = next(iter(inspect.signature(func).parameters))

    @functools.wraps(func)
    def wrapper(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        path: StrPath = args[0] if args else kwargs[first]      # type: ignore[assignment]
        check_rate_argument(kwargs.get("rate"))    # before the file, which it is not about
        if "units" in kwargs:                      # read_npy and read_csv take one
            check_units_argument(kwargs["units"])
        try:
            return func(*args, **kwargs)
        except MPZError as exc:
            if isinstance(exc, InputFormatError):
                raise translate(path, exc) from None
            # a MotionError here means the file's content is inconsistent
            raise InputFormatError(f"inconsistent data: {exc.message}",
                                   path=os.fspath(path)) from exc
        except _PARSE_ERRORS as exc:
            raise translate(path, exc) from exc

    return wrapper


#: The most bytes read of one motion file other than NPY (4 GiB, as of an MPZ file or of
#: standard input, :data:`mpz.api.MAX_INPUT_BYTES`), refused from its size before it is
#: read. The text readers hold about 4 bytes of memory per byte of a TRC (docs/io-notes.md):
#: a sparse 10 GiB .trc read whole took 21 GB (a QA run of stop 49).
MAX_MOTION_BYTES = 1 << 32


def walk(top: StrPath, onerror: Callable[[OSError], object] | None = None
         ) -> Iterator[tuple[str, list[str], list[str]]]:
    """``os.walk(top, onerror=onerror)``, top-down, links to folders listed but not followed
    (a loop cannot hang it), each folder's ``dirs`` pruned or sorted in place by the caller
    as os.walk allows, in the same order; but with a stack instead of recursion. Python
    3.11's os.walk recursed once a folder level: ``mpz encode -r`` over folders nested 1000
    deep ended in RecursionError, exit 70 (a security QA run, stop 73)."""
    stack = [os.fspath(top)]
    while stack:
        here = stack.pop()
        try:
            entries = os.scandir(here)
        except OSError as exc:
            if onerror is not None:
                onerror(exc)
            continue
        dirs: list[str] = []
        files: list[str] = []
        with entries:
            while True:
                try:
                    entry = next(entries)
                except StopIteration:
                    break
                except OSError as exc:          # os.walk gives up on the folder too
                    if onerror is not None:
                        onerror(exc)
                    break
                try:
                    is_dir = entry.is_dir()
                except OSError:
                    is_dir = False
                (dirs if is_dir else files).append(entry.name)
        yield here, dirs, files
        stack += [os.path.join(here, d) for d in reversed(dirs)
                  if not os.path.islink(os.path.join(here, d))]


def is_folder(folder: StrPath | None) -> Callable[[str], bool]:
    """A test of whether a path names ``folder`` (by device and inode, links followed;
    never, where ``folder`` is None or cannot be reached): a walk leaves out its output
    folder with it. ``os.path.realpath`` of every folder met, which it replaced, took a
    system call a level of each path: 8 s for folders nested 1000 deep (stop 73)."""
    try:
        st = os.stat(folder) if folder is not None else None
    except (OSError, ValueError):
        st = None
    if st is None:
        return lambda path: False
    key = (st.st_dev, st.st_ino)

    def test(path: str) -> bool:
        try:
            other = os.stat(path)
        except (OSError, ValueError):
            return False
        return (other.st_dev, other.st_ino) == key
    return test


def open_input(path: StrPath) -> BinaryIO:
    """``path`` opened for reading by :func:`mpz.api.open_regular` (a device such as
    ``/dev/zero``, a FIFO or a socket is refused before it is read, without blocking, and
    checked on the open descriptor); InputFormatError naming the path."""
    from mpz.api import open_regular
    from mpz.errors import FormatError
    try:
        return open_regular(path)
    except FormatError as exc:
        raise InputFormatError(exc.message, path=os.fspath(path)) from None


def read_open(fh: BinaryIO, path: StrPath, limit: int = MAX_MOTION_BYTES) -> bytes:
    """All of the regular file ``fh`` (opened by :func:`open_input`) from its start: its
    size is checked against ``limit`` before anything is read, and a file that grows
    past it while read is refused too."""
    size = os.fstat(fh.fileno()).st_size
    if size > limit:
        raise InputFormatError(f"{size} bytes, more than the {limit} this reader reads of "
                               "one file", path=os.fspath(path))
    fh.seek(0)
    # read(n) sets n bytes aside first: read(limit + 1) took 4 GiB for a 176-byte file, and
    # under ulimit -v every read failed (a QA run of stop 50); so the size, and what a file
    # that grows meanwhile adds, a block at a time
    parts = [fh.read(size + 1)]
    total = len(parts[0])
    while total > size:
        more = fh.read(min(1 << 20, limit + 1 - total))
        if not more:
            break
        parts.append(more)
        total += len(more)
        if total > limit:
            raise InputFormatError(f"the file grew past {limit} bytes while it was read",
                                   path=os.fspath(path))
    return parts[0] if len(parts) == 1 else b"".join(parts)


def reopen_name(fh: BinaryIO, path: StrPath) -> str:
    """A name that opens the very file ``fh`` holds open, for a library that reads only
    from a name (ezc3d): on Linux ``/proc/self/fd/N``, which opens that file even when
    ``path`` has been renamed, replaced (by a FIFO: a hang) or deleted since; elsewhere
    ``path`` itself."""
    proc = f"/proc/self/fd/{fh.fileno()}"
    return proc if os.path.exists(proc) else os.fspath(path)


def read_regular(path: StrPath, limit: int = MAX_MOTION_BYTES) -> bytes:
    """The bytes of the file at ``path``, opened once by :func:`open_input` and read by
    :func:`read_open`: a device, FIFO or socket is refused before it is read, which
    :func:`mpz.io.read`'s check did only for the file it was given, not for an ASF named
    beside an AMC (a QA run: ``--asf /dev/zero`` read until memory ran out, a FIFO hung).
    Raises InputFormatError naming the path."""
    with open_input(path) as fh:
        return read_open(fh, path, limit)


def number(text: str, *, nan: bool = False) -> float:
    """A number of a text motion file (TRC, CSV, BVH, ASF/AMC): decimal ASCII as C's
    ``strtod`` reads it, finite; ``nan`` in any case only where ``nan`` is true (a TRC gap).

    Python's ``float`` also takes ``1_000``, digits of other scripts (``١٢``, ``１２``),
    ``inf`` and ``1e400``: a hostile-input QA found them read silently as 1000, 12 and a
    gap. Raises InputFormatError naming the text.
    """
    try:
        v = float(text)
    except ValueError:
        raise InputFormatError(f"{_said(text)} is not a number") from None
    if not text.isascii() or "_" in text:
        raise InputFormatError(f"{_said(text)} is not a plain decimal number (ASCII digits, "
                               "'.', an exponent)")
    if not math.isfinite(v) and not (nan and math.isnan(v)):
        raise InputFormatError(f"{_said(text)} is not a finite number")
    return v


def _said(text: str) -> str:
    """The text of a number as a refusal quotes it: ASCII blanks stripped, not a no-break
    space (U+00A0 said "'' is not a number", a hostile-input QA run)."""
    return repr(text.strip(" \t\r\n"))


def number_list(words: list[str], read: Callable[[str], float] = number) -> list[float]:
    """``[read(w) for w in words]`` for ``read`` :func:`number` or a stricter wrapper of it:
    where every word is finite plain ASCII decimal, the words are read by one ``float`` loop
    in C and checked together (issue 15: one call of :func:`number` a value was a third of
    an AMC file's read); otherwise each is read by ``read``, which refuses the first bad
    one with its own message."""
    joined = "".join(words)
    if joined.isascii() and "_" not in joined:
        try:
            values = list(map(float, words))
        except ValueError:
            pass
        else:
            if all(map(math.isfinite, values)):
                return values
    return [read(w) for w in words]


def integer(text: str) -> int:
    """A whole number of a text motion file (a count, a frame number, a bone id): an
    optional sign and at most 18 ASCII digits.

    Python's ``int`` also takes ``1_000`` and digits of other scripts (``١٢``): a
    hostile-input QA found BVH's ``Frames:`` and ``CHANNELS`` counts read silently from
    them. Raises InputFormatError naming the text.
    """
    t = text.strip()
    digits = t[1:] if t[:1] in ("+", "-") else t
    if not (digits.isascii() and digits.isdigit()):
        raise InputFormatError(f"{t!r} is not a whole number")
    if len(digits) > 18:
        raise InputFormatError(f"{t[:24]!r}... is too large a number")
    return int(t)


def named(read: Callable[[str], _N], text: str, what: str,
          bad: Callable[[str], InputFormatError]) -> _N:
    """``text`` read by ``read`` (:func:`number`, :func:`integer`, :func:`count`); an error
    names the field ``what``, in the reader's words (``bad`` adds its format's prefix)."""
    try:
        return read(text)
    except InputFormatError as exc:
        raise bad(f"{what}: {exc.message}") from None


def count(text: str) -> int:
    """A count written as a :func:`number` (``151`` or ``151.0``): whole, 0 or more, and
    below 2^62. Raises InputFormatError naming the text."""
    v = number(text)
    if not (v.is_integer() and 0 <= v < 2.0 ** 62):
        raise InputFormatError(f"{text.strip()!r} is not a count")
    return int(v)


def samples_problem(frames: int, points: int, text_chars: int, noun: str) -> str | None:
    """Why a text reader must not make ``frames x points`` samples (three coordinates each;
    ``noun`` names the points: "markers", "joints") from a text of ``text_chars``
    characters, or None when it may: past MAX_SAMPLES marker-frames (spec §8, the most an
    MPZ file holds) they must be written in the text, one character a coordinate at least.
    Checked before the array is allocated.

    What a text holds bounds the memory of its reader (docs/io-notes.md), except where
    one line stands for many samples: a BVH or AMC frame makes a position for every joint,
    even one without channels, and a TRC row shorter than the header is padded with gaps.
    A 0.5 MB BVH (10,000 joints without channels, 100,000 empty frame lines) asked 24 GB, a
    1 MB AMC (1000 bones without dofs) 2.4 GB and a 3 MB TRC of 100,000 markers with short
    rows 4.8 GB (a hostile-input QA run of the text readers). Within MAX_SAMPLES a file may
    still ask 1.5 GiB (as a small MPZ file may, spec §8).
    """
    n = frames * points
    if n <= MAX_SAMPLES or 3 * n <= text_chars:
        return None
    return (f"{frames} frames x {points} {noun} is {n} samples, past the {MAX_SAMPLES} an "
            "MPZ file holds (spec §8, MAX_SAMPLES), and the text does not write them "
            f"({text_chars} characters for {3 * n} coordinates)")


def most_frames(points: int, text_chars: int) -> int:
    """The most frames of ``points`` points that :func:`samples_problem` lets a text of
    ``text_chars`` characters make (at least 1)."""
    return max(1, MAX_SAMPLES // points, text_chars // (3 * points))


#: the characters of plain decimal numbers (no NaN, no inf, no hexadecimal)
_PLAIN = "0123456789+-.eE"


class RowTable:
    """Rows of ``width`` float64 values (NaN where a row is short), appended one at a time
    into an array that doubles when full: sized by the rows that come, not by the lines of
    the text (blank lines times the columns asked 22 GiB of a 557 KB CSV, a QA run of stop
    50), nor held as Python floats (32 bytes a value)."""

    def __init__(self, width: int, most: int | None = None, *, expect: int | None = None
                 ) -> None:
        self.width = width
        self.n = 0
        #: the most rows the caller lets come (it checks before each append): the array
        #: grows to it, not to twice what is needed
        self.most = most
        # ``expect``: the rows the caller knows will come (within ``most``), allocated at
        # once: doubling a table of wide rows filled every larger array with NaN in turn,
        # 15 s of a 25 s read (a TRC of 100,000 markers, a fuzzing QA run of the readers)
        first = 16 if expect is None else expect
        self._data = np.full((max(1, first if most is None else min(first, most)), width),
                             np.nan)

    def append(self, values: list[float]) -> None:
        """Add a row of at most ``width`` values (the rest NaN)."""
        if self.n == len(self._data):
            rows = 2 * len(self._data)
            if self.most is not None:
                rows = max(self.n + 1, min(rows, self.most))
            grown = np.full((rows, self.width), np.nan)
            grown[:self.n] = self._data
            self._data = grown
        self._data[self.n, :len(values)] = values
        self.n += 1

    def rows(self) -> NDArray[np.float64]:
        """The ``n x width`` rows, in an array of their own size (the table's own when it is
        full: no second copy of it)."""
        if self.n == len(self._data):
            return self._data
        return self._data[:self.n].copy()


def plain_numbers(tokens: list[str]) -> NDArray[np.float64]:
    """The tokens as float64, each a :func:`number` (no NaN): one conversion of them all in
    the common case, where every character is a plain number's; else the first offender
    is named (raises InputFormatError)."""
    if not "".join(tokens).strip(_PLAIN):
        try:
            out = np.array(tokens, dtype=np.float64)
        except ValueError:                 # plain characters, not a number: "1-2", "1.0.0"
            pass
        else:        # "1e400" is plain characters too, an infinity: said by number() below,
            if np.isfinite(out).all():    # with its line (it was "non-finite channel value")
                return out
    for t in tokens:
        number(t)
    return np.array(tokens, dtype=np.float64)


def decode_text(data: bytes) -> str:
    """Text of a motion file: UTF-8 (BOM tolerated), else Latin-1.

    Comments in real files carry Latin-1 bytes (HDM05 AMC headers), so a
    non-UTF-8 byte is not by itself an error. Text that starts with a UTF-16 or UTF-32
    byte order mark (Windows tools save "Unicode" so) is refused as such: read as Latin-1,
    each reader said its first line was not one ("got 'ÿþP\x00a\x00t\x00...'", a
    hostile-input QA run).
    """
    for bom, name in ((codecs.BOM_UTF32_LE, "UTF-32"), (codecs.BOM_UTF32_BE, "UTF-32"),
                      (codecs.BOM_UTF16_LE, "UTF-16"), (codecs.BOM_UTF16_BE, "UTF-16")):
        if data.startswith(bom):
            raise InputFormatError(f"the text is {name} (it starts with a {name} byte order "
                                   "mark): save it as UTF-8 (or ASCII) to read it")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def unique_names(names: Iterable[object]) -> tuple[list[str], list[str]]:
    """Make names non-empty and unique.

    Empty names become ``_unnamed_<i>`` (``i`` is the 0-based point index); a NUL inside
    a name, which an MPZ name cannot hold (spec §4.2), becomes U+FFFD (a fuzzed C3D label
    ``Dani\x00l:LFRM`` stopped the encode); exact duplicates get ``#2``, ``#3``, ... in
    order of appearance, skipping a suffixed name that the list itself holds (A, A, A#2
    gave A, A#2, A#2#2: the second A took the name of the joint called A#2).

    Returns
    -------
    names : list of str
    renamed : list of str
        One ``"old->new"`` note per changed name (for the metadata).

    Examples
    --------
    >>> unique_names(["A", "", "A", "A"])
    (['A', '_unnamed_1', 'A#2', 'A#3'], ['->_unnamed_1', 'A->A#2', 'A->A#3'])
    """
    given = [str(n) for n in names]
    out: list[str] = []
    notes: list[str] = []
    seen: set[str] = set()
    literal = {n.replace("\x00", "\ufffd") for n in given if n}   # names the list holds
    counts: dict[str, int] = {}
    for i, n in enumerate(given):
        new = n.replace("\x00", "\ufffd") if n else f"_unnamed_{i}"
        if new in seen:
            k = counts.get(new, 1)
            cand = new
            while cand in seen or cand in literal:
                k += 1
                cand = f"{new}#{k}"
            counts[new] = k
            new = cand
        seen.add(new)
        out.append(new)
        if new != n:
            notes.append(f"{n}->{new}")
    return out, notes


def encoded_text(text: str, encoding: str) -> bytes:
    """``text`` in the source's ``encoding`` (a skeleton's: "utf-8" or "latin-1"), or in
    UTF-8 when that cannot hold it (:func:`text_encoding_of`)."""
    return text.encode(text_encoding_of(text, encoding))


def text_encoding_of(text: str, encoding: str) -> str:
    """The source's ``encoding`` (a skeleton's: "utf-8" or "latin-1") if it can hold
    ``text``, else "utf-8". A skeleton keeps one encoding, an AMC's, and a UTF-8 ASF read
    beside a Latin-1 AMC was written in Latin-1 with '?' for each character it lacks (a QA
    run of stop 52); the readers tell the two apart (:func:`mpz.io.bvh.text_encoding`).

    A writer that writes its text in pieces gives the pieces that hold every character
    beyond ASCII (the header and the names; numbers are ASCII), and writes every piece
    in the encoding returned: the bytes :func:`encoded_text` gives of the whole text."""
    try:
        text.encode(encoding)
    except UnicodeEncodeError:
        return "utf-8"
    return encoding


#: frames a piece of the text that a skeleton writer writes at a time (issue 15.3)
TEXT_BLOCK = 4096


def write_pieces(path: StrPath, pieces: Iterable[str], encoding: str) -> None:
    """Write the pieces of a text to ``path`` in ``encoding`` (:func:`text_encoding_of`'s
    choice), with one encoder for the whole text: what it writes once (a BOM) is written
    once, where each piece encoded alone wrote its own (a review of stop 77)."""
    encoder = codecs.getincrementalencoder(encoding)()
    with open(path, "wb") as fh:
        for piece in pieces:
            fh.write(encoder.encode(piece))
        fh.write(encoder.encode("", final=True))


def is_utf8(name: str) -> bool:
    """Whether UTF-8 can hold ``name``: a file name that is not UTF-8 comes from the
    system as lone surrogates (``os.fsdecode``), which ezc3d, SQLite and MPZ's strings
    cannot take."""
    try:
        name.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def utf8_name(name: str) -> str:
    """``name`` as UTF-8 text: the bytes of a name that is not UTF-8 as ``\\xNN``."""
    return name if is_utf8(name) else os.fsencode(name).decode("utf-8", "backslashreplace")


def ext_of(path: StrPath) -> str:
    """Lower-case extension with the dot, e.g. ``".c3d"``."""
    return os.path.splitext(os.fspath(path))[1].lower()


#: the largest |first frame number| read from metadata (``trc.FirstFrame``): it is a file's
#: free text, and 10^4000 made every TRC row 4 KB
MAX_FIRST_FRAME = 2**31 - 1


def start_frame(motion: Motion) -> int:
    """The number of the motion's first frame in its source: a TRC's first Frame#, a
    C3D's first frame (header word 4, or TRIAL:ACTUAL_START_FIELD past 65535 frames:
    :meth:`mpz.c3darchive.C3DArchive.first_frame`), an AMC's first frame; 1 when none says."""
    meta = motion.metadata
    try:
        if "trc.FirstFrame" in meta:
            n = int(meta["trc.FirstFrame"])
            if abs(n) <= MAX_FIRST_FRAME:
                return n
    except ValueError:
        pass
    a = motion.extras.get("c3d")
    if a is not None and hasattr(a, "first_frame"):
        return int(a.first_frame())
    skel = motion.extras.get("skeleton")
    if getattr(skel, "convention", "") == "asf":
        return int(getattr(skel, "first_frame", 1))
    return 1


def values_at_gaps(pos: NDArray[np.float64], gap: NDArray[np.bool_], names: list[str],
                   what: str) -> str:
    """A reader's warning for the samples of ``pos[F, M, 3]`` that become gaps (``gap``)
    while they hold a coordinate (other than C3D's usual gap, exactly (0, 0, 0)): a gap
    keeps none (spec §4.5), so the value is lost. ``what`` says which samples those are
    in the format's words. Empty when there are none. (A QA of stop 48: TRC cells and C3D
    coordinates went without a word.)"""
    # a finite coordinate, unless the sample is (0, 0, 0), C3D's usual gap
    held = gap & np.isfinite(pos).any(axis=2) & ~(pos == 0).all(axis=2)
    n = int(held.sum())
    if not n:
        return ""
    f, m = (int(i) for i in np.argwhere(held)[0])
    return (f"{n} sample{'s' * (n != 1)} {what} (the first: frame index {f}, marker "
            f"{names[m]!r}): each is a gap, and the coordinates it holds are not kept")
