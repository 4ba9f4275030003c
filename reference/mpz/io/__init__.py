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
.bvh      yes      yes      FK joint centres + end sites, units ""; writes the skeleton
.amc      yes      yes      needs the .asf; FK joint positions in mm; writes AMC + ASF
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
...     notes = write(m, os.path.join(d, "a.trc"))      # what the format drops: none here
...     back = read(os.path.join(d, "a.trc"))
>>> notes
[]
>>> back.names, back.rate, back.units
(['A'], 100.0, 'mm')

:func:`detect_format` tells the format from the first bytes (for standard
input, which has no name); :func:`read_bytes` reads a motion from bytes.
:func:`write` refuses what a target format cannot hold (:func:`check_writable`)
so that every file it writes reads back.
"""
from __future__ import annotations

from collections.abc import Callable
import math
import os
import tempfile

import numpy as np
from numpy.typing import NDArray

from mpz._worker import spelled
from mpz.errors import InputFormatError
from mpz.format import SIGNATURE
from mpz.io import amc, bvh, c3dbin
from mpz.io._common import (
    MAX_MOTION_BYTES,
    StrPath,
    check_rate_argument,
    ext_of,
    is_utf8,
    open_input,
    read_open,
    reopen_name,
    start_frame,
    translate,
    utf8_name,
)
from mpz.io.amc import (
    amc_from_bytes,
    asf_text_changes,
    default_asf_path,
    find_asf,
    read_amc,
    read_asf,
    write_amc,
)
from mpz.io.bvh import bvh_from_bytes, read_bvh, skeleton_problems, write_bvh
from mpz.io.c3d import MIN_RATE, c3d_from_bytes, read_c3d, write_c3d
from mpz.io.kinematics import Skeleton
from mpz.io.table import (
    MAX_NPY_BYTES,
    csv_from_bytes,
    npy_from_bytes,
    read_csv,
    read_npy,
    write_csv,
    write_npy,
)
from mpz.io.trc import read_trc, trc_from_bytes, write_trc
from mpz.motion import Motion, check_consistent, held_extras

#: extension -> reader(path, **options)
READERS: dict[str, Callable[..., Motion]] = {
    ".c3d": read_c3d,
    ".trc": read_trc,
    ".bvh": read_bvh,
    ".amc": read_amc,
    ".npy": read_npy,
    ".csv": read_csv,
}

#: extension -> reader(path, data, **options) of a file's bytes, read once by :func:`read`
#: (``path`` names the file; it is not opened again)
BYTES_READERS: dict[str, Callable[..., Motion]] = {
    ".c3d": c3d_from_bytes,
    ".trc": trc_from_bytes,
    ".bvh": bvh_from_bytes,
    ".amc": amc_from_bytes,
    ".npy": npy_from_bytes,
    ".csv": csv_from_bytes,
}

#: the formats that carry a skeleton (issue 13): read with it, written from it
SKELETON_FORMATS = (".bvh", ".amc")

#: extension -> writer(motion, path) (the C3D writer returns what its file reads back
#: otherwise, :func:`mpz.io.c3d.read_back`; the others return None)
WRITERS: dict[str, Callable[..., object]] = {
    ".c3d": write_c3d,
    ".trc": write_trc,
    ".npy": write_npy,
    ".csv": write_csv,
    ".bvh": write_bvh,      # a motion with a BVH skeleton (issue 13)
    ".amc": write_amc,      # a motion with an ASF skeleton: the AMC, and the ASF beside it
}

#: extension -> the format's name, as messages say it
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
        Not a regular file (a device, FIFO or socket: refused before it is
        opened), unknown format (a file without a known extension is
        recognised by its content, see :func:`detect_format`), missing file
        ("no such file"), or unreadable content.
    ValueError
        For a ``rate`` that is not a finite number above 0 (it was blamed on the file).
    """
    check_rate_argument(rate)
    _path_arg("path", path)           # a QA run (stop 33): bytes were taken for a path,
    if asf is not None:               # and asf=3 read and closed the caller's descriptor 3
        _path_arg("asf", asf)
    ext = ext_of(path)
    # the file is opened once, refused unless regular, and read once: a FIFO swapped in for
    # it after a check hung a later open (a QA run of stop 49), and the bytes that were
    # checked are the bytes that are parsed; a C3D's ezc3d reads the same open file
    with open_input(path) as fh:
        head = fh.read(DETECT_BYTES)
        if ext not in READERS:        # no known extension: the content may still say
            ext = _format_of_content(path, head, ext)
        if ext == ".c3d":             # a 5 GB sparse file of zeros named .c3d was read
            _check_c3d_key(path, head)  # whole before its key byte was checked (QA)
        data = read_open(fh, path, MAX_NPY_BYTES if ext == ".npy" else MAX_MOTION_BYTES)
        m = _from_bytes(ext, path, data, asf=asf, rate=rate, reopen=reopen_name(fh, path))
    last = data[-1:]
    if ext in (".trc", ".csv", ".bvh", ".amc") and last not in (b"", b"\n", b"\r"):
        # a text file cut in the middle of its last number reads as fewer digits (a QA
        # run); every writer of these formats, and every real file here, ends its lines
        _warn(m, "the file does not end with a line break: its last line may have been "
              "cut short (check that the file is complete)")
        if ext in (".trc", ".csv") and last in b"0123456789.":
            _gap_the_last_value(m)
    # file names that are not UTF-8 ('source', an AMC's 'asf'): MPZ's strings are UTF-8
    # (§4.11), and such a name made the encoder refuse the file
    for key, value in list(m.metadata.items()):
        if isinstance(value, str) and not is_utf8(value):
            m.metadata[key] = utf8_name(value)
            what = "a file name" if key in ("source", "asf") else "a value read from the file"
            _warn(m, f"{what} is not UTF-8: metadata {key!r} holds it as "
                     f"{m.metadata[key]!r}")
    return m


def _warn(m: Motion, note: str) -> None:
    """Add ``note`` to the motion's ``warning`` metadata (what the tools print)."""
    old = m.metadata.get("warning")
    m.metadata["warning"] = note if not old else f"{old}; {note}"


def _gap_the_last_value(m: Motion) -> None:
    """A TRC or CSV that ends inside a number: the number may have been cut ("726." of
    "726.93756" read as 726.0, valid, a QA of stop 42), and it is the last coordinate of
    the last marker present on the last row, so that sample becomes a gap, said."""
    f = m.n_frames - 1                       # a Motion has at least one frame
    present = np.flatnonzero(m.valid[f])
    if not present.size:
        return
    j = int(present[-1])
    m.valid[f, j] = False
    m.positions[f, j] = np.nan
    _warn(m, f"the file ends inside a number, which may have been cut: marker "
             f"{m.names[j]!r} at frame index {f} is taken as a gap")


#: metadata keys the readers set to describe the source (mpz.io's readers), rebuilt when a
#: written file is read: not counted as free metadata that a format drops
READER_KEYS = frozenset({
    "format", "source", "reader", "reader_note", "warning", "units_in_file", "start_time",
    "frame_time",
    "channels", "joints", "end_sites", "mm_per_unit", "rate_assumed", "subject",
    "renamed_points", "processor", "model_outputs", "asf_length_unit", "skeleton", "asf"})
#: the namespaces of the header fields a text reader keeps for its writer (``trc.Decimals``,
#: ``trc.FirstFrame``, ``csv.FirstFrame``): set from the file read, like READER_KEYS
READER_PREFIXES = ("trc.", "csv.")


def write(motion: Motion, path: StrPath, *, file_name: str | None = None,
          asf: StrPath | None = None, atomic: bool = True) -> list[str]:
    """Write a Motion, choosing the writer by extension; returns the notes of
    :func:`check_writable`: what the format does not hold of the motion (for example
    NPY's marker names, rate and units, or a C3D's metadata), each a sentence; and, for
    a C3D, a last note, beginning with :data:`READ_BACK_NOTE`, when mpz's reader reads
    the file written otherwise (:func:`mpz.io.c3d.read_back`).

    Parameters
    ----------
    motion : Motion
    path : str or os.PathLike
        A ``.c3d``, ``.trc``, ``.npy``, ``.csv``, ``.bvh`` or ``.amc`` file name (BVH
        and AMC need the motion's skeleton).
    file_name : str, optional
        The name to record in formats that store their own file name (TRC);
        default: the base name of ``path``. For writing to a temporary file.
    asf : str or os.PathLike, optional
        Where ``.amc`` output puts its ASF skeleton (default: beside it, same stem); only
        for ``.amc``, and another file than ``path``.
    atomic : bool, optional
        True (default): each file is written under a hidden name beside it and renamed
        when whole. False: written in place, for a caller that writes to a temporary
        file of its own (``mpz decode``).

    Raises
    ------
    MotionError
        For a motion changed since it was made so that it is no longer consistent
        (:func:`mpz.motion.check_consistent`).
    InputFormatError
        For an extension no writer handles, or a motion the format cannot
        hold so that it reads back (see :func:`check_writable`).
    FileNotFoundError
        When the folder of ``path`` does not exist (ezc3d then wrote nothing, silently).
    ValueError
        For an ``asf`` with another format than AMC, or naming ``path`` itself.
    EncoderError
        With ``atomic``, when the file cannot be written (a full disk, no permission),
        naming ``path``; ``path`` (and an AMC's ASF) is never left cut short
        (:func:`mpz.api.atomic_output`); an existing file is replaced, and so is a
        symbolic link at ``path`` (its target is left as it was), as the commands do.
    """
    if not isinstance(motion, Motion):    # it failed deep in check_writable (QA, stop 33)
        raise TypeError(f"mpz.io.write: expected an mpz.Motion, got {type(motion).__name__}")
    check_consistent(motion)
    _path_arg("path", path)
    if not isinstance(atomic, bool):
        raise TypeError(f"atomic must be True or False, got {atomic!r}")
    if file_name is not None and not isinstance(file_name, str):
        raise TypeError(f"file_name must be a str, got {type(file_name).__name__}")
    ext = ext_of(path)
    fn = WRITERS.get(ext)
    if fn is None:
        raise InputFormatError(
            f"cannot write {ext or '(no extension)'!r}; can write {', '.join(WRITERS)}",
            path=os.fspath(path))
    if asf is not None:
        # the AMC replaced its own ASF, silently, and a BVH ignored it (a QA run of the
        # API, stop 54; the CLI refused both)
        _path_arg("asf", asf)
        if ext != ".amc":
            raise ValueError(f"asf is where an AMC's ASF skeleton goes; "
                             f"{os.fspath(path)!r} is {FORMAT_NAMES.get(ext, ext)}")
        if _same_path(asf, path):
            raise ValueError(f"asf {os.fspath(asf)!r} is the AMC output itself: the AMC "
                             "would replace its skeleton")
    notes = check_writable(motion, ext, path=file_name or os.fspath(path))
    folder = os.path.dirname(os.path.abspath(os.fspath(path)))
    if not os.path.isdir(folder):
        raise FileNotFoundError(f"cannot write {os.fspath(path)!r}: no folder {folder!r}")
    if os.path.isdir(path):
        raise InputFormatError(f"cannot write {FORMAT_NAMES.get(ext, ext)}: a folder has "
                               "that name", path=os.fspath(path))
    name = os.path.basename(os.fspath(path)) if file_name is None else file_name
    asf_path = default_asf_path(path) if asf is None else asf
    if not atomic:
        return notes + _write_in_place(motion, ext, path, name, asf_path)
    # through a hidden file beside each output, renamed when whole (mpz.api.atomic_output):
    # a full disk left a cut file and a raw OSError (a QA run of stop 49)
    from mpz.api import atomic_output
    with atomic_output(path, force=True) as tmp:
        if ext == ".amc":          # the ASF first: its faults name it, not the AMC
            with atomic_output(asf_path, force=True) as tmp_asf:
                amc.write_asf(motion, tmp_asf)
            amc.write_amc_text(motion, tmp)
        else:
            notes += _write_in_place(motion, ext, tmp, name, asf_path)
        if not os.path.exists(tmp):                 # a writer that failed without a word
            raise OSError(f"the {FORMAT_NAMES.get(ext, ext)} writer wrote nothing to "
                          f"{os.fspath(path)!r}")
    return notes


def _write_in_place(motion: Motion, ext: str, path: StrPath, name: str,
                    asf: StrPath) -> list[str]:
    """The writer of ``ext`` writing ``path`` itself (``name``: the TRC's own file name;
    ``asf``: where an AMC's ASF goes); the notes of what the file written reads back
    otherwise (C3D: :func:`mpz.io.c3d.read_back`)."""
    fn = WRITERS[ext]
    if ext == ".trc":
        fn(motion, path, file_name=name)
    elif ext == ".amc":
        fn(motion, path, asf=asf)
    elif ext == ".c3d":
        found = write_c3d(motion, path)           # typed: its list of findings
        why = (" (spec §6.9 writes an archive's header and parameters as it holds them)"
               if motion.extras.get("c3d") is not None else "")
        return [READ_BACK_NOTE + "; ".join(found) + why] if found else []
    else:
        fn(motion, path)
    return []


#: How :func:`write` begins its last note when mpz's C3D reader reads the C3D it wrote
#: otherwise than the motion (:func:`mpz.io.c3d.read_back`); ``mpz decode`` prints that note
#: as a warning (exit 1).
READ_BACK_NOTE = "mpz's C3D reader reads the file written otherwise: "


def _same_path(a: StrPath, b: StrPath) -> bool:
    """Whether two paths name one file: the same absolute path, or one existing file."""
    if os.path.abspath(os.fspath(a)) == os.path.abspath(os.fspath(b)):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:                          # either is missing: not one file yet
        return False


def _path_arg(name: str, value: object) -> None:
    """Raise TypeError unless ``value`` is a path: a str or an os.PathLike of str."""
    if not (isinstance(value, str) or (isinstance(value, os.PathLike)
                                       and isinstance(os.fspath(value), str))):
        raise TypeError(f"{name} must be a file name (str or os.PathLike), got "
                        f"{type(value).__name__}")


def asf_not_a_motion() -> str:
    """What reading an ASF as a motion says (a QA run of stop 61 found "unknown file
    extension" by name, "cannot tell the format" on standard input), naming the option as
    the caller spells it."""
    return ("an ASF file is the skeleton of AMC motions, not a motion: read an .amc (its ASF "
            f"is found beside it, or given with {spelled('--asf', 'asf=')})")


def _is_asf_text(head: bytes) -> bool:
    """Whether ``head`` starts like an ASF file: among its first keyword lines, one of the
    sections only an ASF has (``:bonedata``, ``:root``, ``:hierarchy``) or ``:version``
    with ``:name`` (the first two lines of every ASF; an AMC has neither)."""
    keys = _keywords(head.decode("latin-1"))
    return bool(keys & {":bonedata", ":root", ":hierarchy"}) or \
        {":version", ":name"} <= keys


def _keywords(text: str) -> set[str]:
    """The ``:keywords`` that lead lines of ASF or AMC ``text``, lower case."""
    return {ln.split(None, 1)[0].lower() for ln in (x.strip() for x in text.splitlines())
            if ln.startswith(":")}


def _format_of_content(path: StrPath, head: bytes, ext: str) -> str:
    """The format of a file without a known extension, from its first bytes ``head``
    (:func:`detect_format`); InputFormatError when none is known, or for an MPZ file."""
    found = detect_format(head)
    if found == ".mpz":           # a batch said "no known format in the content" (a QA run)
        raise InputFormatError(
            "an MPZ file, not a motion file: mpz.decode reads it (mpz encode re-encodes "
            "one .mpz given alone, within the bounds of both encodes)", path=os.fspath(path))
    if found not in READERS and (ext == ".asf" or _is_asf_text(head)):
        raise InputFormatError(asf_not_a_motion(), path=os.fspath(path))
    if found not in READERS:
        raise InputFormatError(
            f"unknown file extension {ext or '(none)'!r} and no known format in the "
            f"content; can read {', '.join(READERS)}", path=os.fspath(path))
    return found


def _check_c3d_key(path: StrPath, head: bytes) -> None:
    try:
        c3dbin.check_key(head[:2])
    except InputFormatError as exc:
        raise translate(path, exc) from None


def _from_bytes(ext: str, path: StrPath, data: bytes, *, asf: StrPath | None,
                rate: float | None, reopen: StrPath | None) -> Motion:
    """The motion in ``data``, the bytes of a file of format ``ext`` named ``path``
    (messages and ``metadata["source"]`` name it; it is not opened again: a C3D's ezc3d
    opens ``reopen``, which holds the same bytes)."""
    kw = {} if rate is None else {"rate": rate}
    if ext == ".c3d":
        return c3d_from_bytes(path, data, reopen=reopen)
    if ext == ".amc":
        return amc_from_bytes(path, data, asf, **kw)
    if ext in (".npy", ".csv"):
        return BYTES_READERS[ext](path, data, **kw)
    return BYTES_READERS[ext](path, data)


#: ``detect_format`` looks at no more than this many leading bytes
DETECT_BYTES = 4096



def _as_bytes(data: object, name: str) -> bytes:
    """``data`` as bytes: bytes, a bytearray or a memoryview; TypeError for anything else."""
    if isinstance(data, bytes):
        return data
    if isinstance(data, (bytearray, memoryview)):
        return bytes(data)
    raise TypeError(f"{name} must be bytes, a bytearray or a memoryview, got "
                    f"{type(data).__name__}")


def detect_format(head: bytes) -> str | None:
    """The extension (``".c3d"``, ``".trc"``, ...) of a file whose first bytes are ``head``.

    What each format starts with:

    * MPZ (``".mpz"``): the signature ``89 4D 50 5A 0D 0A 1A 0A`` (spec §3.1);
    * NPY: ``93 4E 55 4D 50 59`` (``\\x93NUMPY``);
    * C3D: byte 2 (index 1) is the parameter-section key 0x50, byte 1 points to the
      parameter block (>= 2, the header being block 1), and that block's fourth byte,
      when within the first 4096 bytes, is a processor type (84 Intel, 85 DEC, 86 MIPS);
    * TRC: a first line starting with ``PathFileType``;
    * BVH: a first word ``HIERARCHY``;
    * AMC: ``:FULLY-SPECIFIED``, ``:DEGREES`` or ``:RADIANS`` in the comment-led header,
      and no ASF section (``:version``, ``:bonedata``);
    * CSV: a first row starting ``frame,time`` (the layout :func:`write` produces).

    Returns None when nothing matches.

    >>> from mpz.io import detect_format
    >>> detect_format(b"PathFileType\\t4\\t(X/Y/Z)\\tx.trc\\n")
    '.trc'
    >>> detect_format(bytes(512)) is None
    True
    """
    if isinstance(head, (bytearray, memoryview)):
        head = head[:DETECT_BYTES]                  # no copy of the rest
    head = _as_bytes(head, "head")[:DETECT_BYTES]
    if head.startswith(SIGNATURE):        # spec §3.1
        return ".mpz"
    if head.startswith(b"\x93NUMPY"):
        return ".npy"
    if len(head) >= 2 and head[1] == 0x50 and head[0] >= 2:
        proc = 512 * (head[0] - 1) + 3     # the parameter section's processor type byte
        if len(head) <= proc or 84 <= head[proc] <= 86:
            return ".c3d"
    text = head.decode("latin-1").lstrip("\ufeff\xef\xbb\xbf \t\r\n")
    if text.startswith("PathFileType"):
        return ".trc"
    if text.split(None, 1)[:1] == ["HIERARCHY"]:
        return ".bvh"
    keys = _keywords(text)
    if keys & {":fully-specified", ":degrees", ":radians"} and \
            not keys & {":version", ":bonedata", ":root", ":hierarchy"}:
        return ".amc"
    if text.replace(" ", "").lower().startswith("frame,time"):
        return ".csv"
    return None


def read_bytes(data: bytes, *, fmt: str | None = None, name: str = "-",
               asf: StrPath | None = None, rate: float | None = None) -> Motion:
    """Read a motion from its bytes (standard input), the format found by :func:`detect_format`.

    Parameters
    ----------
    data : bytes
    fmt : str, optional
        An extension (``".c3d"``) to use instead of detecting it.
    name : str, optional
        What messages call the input, and ``metadata["source"]`` unless it is the
        default ``"-"`` (then the motion has no ``source``).
    asf, rate
        As for :func:`read`; AMC from bytes needs ``asf``.

    Raises
    ------
    InputFormatError
        For content of no known format, or that its reader refuses.
    """
    data = _as_bytes(data, "data")
    if fmt is not None and (not isinstance(fmt, str) or not fmt.startswith(".")):
        # "trc" was "trc content cannot be read as a motion here" (a QA run, stop 50)
        raise ValueError(f"fmt must be an extension with its dot, such as '.trc', got "
                         f"{fmt!r}")
    ext = fmt.lower() if fmt else detect_format(data)
    if ext is None and _is_asf_text(data[:DETECT_BYTES]):   # `mpz encode - < 35.asf`
        raise InputFormatError(asf_not_a_motion(), path=name)
    if ext is None:
        raise InputFormatError(f"cannot tell the format from the content (first bytes "
                               f"{data[:8]!r}); can read {', '.join(READERS)}, and MPZ "
                               f"content is read by mpz.decode and the mpz commands",
                               path=name)
    if ext == ".mpz":       # it said it could read .mpz, then refused it (API QA, stop 72)
        raise InputFormatError("MPZ content is not a motion file to read here: decode it "
                               "with mpz.decode", path=name)
    if ext not in READERS:
        raise InputFormatError(f"{FORMAT_NAMES.get(ext, ext)} content cannot be read as a "
                               "motion here", path=name)
    if ext == ".amc" and asf is None:
        raise InputFormatError("AMC content needs its skeleton: give the .asf file", path=name)
    with tempfile.TemporaryDirectory(prefix="mpz-stdin-") as d:
        tmp = os.path.join(d, "stdin" + ext)
        with open(tmp, "wb") as fh:
            fh.write(data)
        try:
            m = read(tmp, asf=asf, rate=rate)
        except InputFormatError as exc:
            exc.path = name
            raise
    m.metadata.pop("source", None)
    if name != "-":
        m.metadata["source"] = name
    return m


def _c3d_section_problems(motion: Motion) -> list[str]:
    """Why the parameter section of a C3D of ``motion``'s bare points
    (:func:`mpz.io.c3dbin.plain_parts`) cannot be written: more blocks than a C3D header
    counts (ezc3d wrote the count modulo 256: 490 of 1000 long names came back unnamed, a
    QA run of stop 50), too many points, a name too long."""
    from mpz.io.c3d import plain_blocks
    if not all(is_utf8(n) for n in motion.names):
        return []                                 # refused as names that are not text
    try:
        blocks = plain_blocks(motion)
    except InputFormatError as exc:
        return [exc.message]
    if blocks <= c3dbin.MAX_PARAM_BLOCKS:
        return []
    return [f"C3D: the {motion.n_markers} marker names need a parameter section of {blocks} "
            f"blocks of 512 bytes, and a C3D header counts at most "
            f"{c3dbin.MAX_PARAM_BLOCKS}: give fewer or shorter names"]


def _names_with(names: list[str], bad: Callable[[str], bool]) -> list[str]:
    return [repr(n) for n in names if bad(n)][:5]


def skeleton_read_back(motion: Motion, ext: str) -> tuple[list[str], Skeleton | None]:
    """The marker names that ``motion`` written as BVH or AMC/ASF reads back with (those
    formats name each joint as the skeleton does, made unique as the readers do, while
    the motion's names are MNAM's), and for AMC the ASF skeleton read back. Written and
    read from the first two frames: the names, the skeleton and the AMC header are those
    of every frame, and the numbers are written as they read back. For a motion that
    format holds (:func:`mpz.io.bvh.skeleton_problems`).

    Raises
    ------
    InputFormatError
        The reader's, for a file that would not read back: §4.14.2 allows an ASF bone
        name with a ``#`` or one that reads as a keyword, and takes an AMC header as
        text, so a valid file decoded without a word to an AMC that no reader read back
        (a fuzzing QA run of stop 54).
    """
    from dataclasses import replace as _with
    n = min(2, motion.n_frames)
    head = _with(motion, positions=motion.positions[:n], valid=motion.valid[:n],
                 angles=None if motion.angles is None else motion.angles[:n])
    if ext == ".bvh":
        return bvh.parse_bvh(bvh.format_bvh(head)).names, None
    skel = motion.extras["skeleton"]
    asf, _ = amc._parse_asf(amc.format_asf(skel), skel.encoding)
    return amc.parse_amc(amc.format_amc(head), asf, encoding=skel.encoding).names, asf


def writer_problems(motion: Motion, ext: str) -> tuple[list[str], list[str]]:
    """What format ``ext`` cannot hold of ``motion``: (refusals, notes).

    A refusal means the written file would not read back as this motion
    (issue 11.9: a rate C3D stores as 0, CSV times that overflow, a name that
    breaks a TRC line); a note names what the format drops or changes, which
    the tools print.
    """
    refuse: list[str] = []
    notes: list[str] = []
    names = list(motion.names)
    rate, F = float(motion.rate), motion.n_frames
    fmt = FORMAT_NAMES.get(ext, ext)
    first = start_frame(motion)            # the source's first frame number

    if ext in (".c3d", ".trc", ".csv"):
        # a CSV column is <name>_x, so only a leading space is lost ("B " was read from
        # "B _x" and refused on writing: a QA run of stop 52)
        padded = _names_with(names, (lambda n: n != n.lstrip()) if ext == ".csv"
                             else (lambda n: n != n.strip()))
        if padded:
            refuse.append(f"{fmt} strips spaces around marker names: "
                          f"{', '.join(padded)}")
        # a lone surrogate (a file name's undecodable byte, os.fsdecode) is no text: the
        # writers raised UnicodeEncodeError and left an empty file (a QA run of stop 47)
        unencodable = _names_with(names, lambda n: not is_utf8(n))
        if unencodable:
            refuse.append(f"{fmt} stores marker names as text, and these are not valid "
                          f"Unicode (lone surrogates): {', '.join(unencodable)}")
    if ext == ".trc":
        # what breaks its lines (LINE_BREAK) or its tab-separated fields; other control
        # characters read back (DEL, ESC, a form feed inside a name were refused, and a TRC
        # read with them could not be written back: a QA run of stop 72)
        ctl = _names_with(names, lambda n: any(c in n for c in "\t\r\n"))
        if ctl:
            refuse.append(f"{fmt} is text with one record per line and tab-separated "
                          f"fields: marker names with a tab, a line feed or a carriage "
                          f"return would break it: {', '.join(ctl)}")
    if ext == ".csv":
        # the header is written by csv.writer, which quotes a name with a line feed or a
        # tab, and it reads back; names read from a CSV were refused when written to one
        # (a CLI fuzzing QA run of stop 54). A lone carriage return does not read back
        cr = _names_with(names, lambda n: "\r" in n.replace("\r\n", ""))
        if cr:
            refuse.append(f"{fmt} readers take a carriage return for the end of a line, "
                          f"even quoted: marker names with one would break it: "
                          f"{', '.join(cr)}")
    if ext in (".trc", ".csv"):
        last = (F - 1) / rate if F > 1 else 0.0
        if not math.isfinite(last):
            refuse.append(f"{fmt} times (frame / rate) overflow at rate {rate!r} Hz")
    if ext == ".c3d":
        with np.errstate(over="ignore"):     # a rate beyond float32 becomes inf: refused
            r32 = float(np.float32(rate)) if math.isfinite(rate) else math.inf
        if not (math.isfinite(r32) and r32 > 0):
            refuse.append(f"C3D stores the rate as float32, which turns {rate!r} Hz into "
                          f"{r32!r}")
        elif r32 < MIN_RATE:
            # written, then refused by mpz's own reader (a review of stop 55): 1e-6 Hz is
            # 9.99999997e-07 as float32
            refuse.append(f"C3D stores the rate as float32, which turns {rate!r} Hz into "
                          f"{r32!r}, below {MIN_RATE:g} Hz, the slowest rate mpz's C3D "
                          "reader takes")
        elif r32 != rate:
            notes.append(f"C3D stores the rate as float32: {rate!r} Hz reads back as {r32!r}")
        archive = motion.extras.get("c3d")
        from mpz.c3darchive import C3DArchive
        from mpz.io.c3d import archive_units
        # an archive that contradicts the motion is refused by its writer (archive_bytes)
        if isinstance(archive, C3DArchive):
            stale = archive.stale_header(F)
            if stale:
                # spec §4.13.1 keeps stale counts, so a valid file without its cana wrote a
                # C3D that read back "truncated", with no word (a fuzzing QA run of stop 54)
                notes.append("the C3D header is written back as the archive holds it (spec "
                             "§4.13.1), and disagrees with the file's content: "
                             + "; ".join(stale) + "; readers that go by the header read the "
                             "file otherwise")
            if motion.units and archive_units(archive) == "":
                notes.append(f"the source's POINT:UNITS names no unit C3D readers know, and "
                             f"is written as stored: the file does not say {motion.units!r}")
        long = c3dbin.long_offsets(list(getattr(archive, "records", [])))
        if long:
            notes.append(f"parameter record(s) {', '.join(repr(n) for n in long)} need a "
                         f"next-record offset beyond {c3dbin.SIGNED_OFFSET_LIMIT}: written "
                         "unsigned as the source held them (spec §6.9), which readers that "
                         "take the offset as signed (ezc3d) cannot follow")
        proc = getattr(archive, "processor", c3dbin.PROC_INTEL)
        if proc != c3dbin.PROC_INTEL:
            notes.append(f"the source was a {'DEC' if proc == c3dbin.PROC_DEC else 'MIPS'} "
                         f"C3D (processor {proc}); it is written in Intel byte order, every "
                         "value the same")
        if motion.units not in ("", "mm", "cm", "m"):
            notes.append(f"C3D readers know mm, cm and m: units {motion.units!r} read back "
                         "as unknown")
        elif motion.units == "":
            notes.append("this motion has no length unit (a BVH source?): POINT:UNITS is "
                         "left empty, and most C3D readers will take millimetres; encode "
                         "the source with --units to name it")
        if archive is None and first < 1:
            notes.append(f"C3D counts frames from 1: the source's first frame {first} is "
                         f"written as 1 (every frame number {1 - first} higher)")
        if archive is None:
            refuse += _c3d_section_problems(motion)
    if ext == ".trc":
        said = motion.metadata.get("trc.Units", "").strip()
        if motion.units == "" and said:
            # a TRC source whose Units word is no unit MPZ knows ("unknown"): written back
            # as it was, so that the file round-trips (it was refused: a QA run of stop 52)
            notes.append(f"the source TRC's Units {said!r} is no length unit MPZ knows: "
                         "written back as it was")
        elif motion.units == "":
            refuse.append("TRC needs units (mm, cm, m, in) and this motion has none (a BVH "
                          "source?); write .npy or .csv, or encode the source with its units")
        from mpz.io.trc import trc_meta_problems
        for key, why in trc_meta_problems(motion.metadata).items():
            notes.append(f"metadata {key} {motion.metadata[key][:40]!r} {why}: the TRC "
                         "writer's own value is written in its place")
    if ext == ".csv":
        notes.append("CSV does not store units" + (f" ({motion.units})" if motion.units else ""))
        if F < 2:
            notes.append(f"a one-frame CSV does not hold the rate ({rate!r} Hz)")
        elif not refuse:
            from mpz.io.table import csv_start, rate_from_times
            t0 = csv_start(motion)[1]          # the times the writer writes (a review)
            frames = np.arange(F, dtype=np.float64)
            try:
                back = rate_from_times(t0 + frames / rate if t0 else frames / rate)
            except ValueError:
                back = math.nan
            if back != rate:
                refuse.append(f"CSV times cannot give back the rate {rate!r} Hz "
                              f"(they read back as {back!r})")
    if ext == ".bvh" and motion.units:
        notes.append(f"BVH does not store units ({motion.units}): the file reads back "
                     "without a unit")
    if ext == ".npy":
        notes.append("NPY holds positions only: marker names, rate and units are not stored")
    if ext in (".c3d", ".trc", ".csv", ".npy"):     # NPY's were not said (QA, stop 50)
        free = [k for k in motion.metadata if k not in READER_KEYS and "." not in k]
        if motion.metadata.get("subject") and not _subject_held(motion, ext):
            free.insert(0, "subject")     # a reader key, but here the file has no place
        if free:
            notes.append(f"{fmt} has no place for free metadata: not written: "
                         + ", ".join(repr(k) for k in free[:8])
                         + (f" and {len(free) - 8} more" if len(free) > 8 else ""))
    renamed = motion.metadata.get("renamed_points")
    if renamed and ext in (".trc", ".csv"):
        pairs = [p for p in str(renamed).split("; ") if p]
        # unique_names' three kinds: empty ("->_unnamed_3"), a NUL, a repeat ("A->A#2"); a
        # source of empty labels was said to repeat its names (a QA run of stop 72)
        kinds = [k for k, hit in (
            ("are empty", any(p.startswith("->") for p in pairs)),
            ("hold a NUL", any("\x00" in p for p in pairs)),
            ("repeat", any(not p.startswith("->") and "\x00" not in p for p in pairs)))
            if hit]
        notes.append(f"some of the source's point names {' or '.join(kinds)}: {len(pairs)} "
                     f"point{'s are' if len(pairs) != 1 else ' is'} written under the names "
                     f"given them on reading ({'; '.join(pairs[:4])}"
                     + (f" and {len(pairs) - 4} more" if len(pairs) > 4 else "") + ")")
    header = [k for k in motion.metadata if k.startswith("trc.")]
    if header and ext != ".trc":        # a TRC source's header fields (mpz compare: missing)
        notes.append(f"{fmt} has no place for a TRC's header fields: not written: the "
                     f"{len(header)} trc.* entries (file name, rates, decimals...)")
    first_csv = motion.metadata.get("csv.FirstFrame")
    if first_csv is not None and ext != ".csv":     # mpz compare: missing (a review)
        notes.append(f"{fmt} does not take a CSV's frame numbers: the first, {first_csv!r}, "
                     "is not written")
    if ext == ".c3d":
        zero = motion.valid & (motion.positions == 0.0).all(axis=2)
        if zero.any():
            f, m = (int(i) for i in np.argwhere(zero)[0])
            notes.append(f"{int(zero.sum())} valid sample(s) at exactly (0, 0, 0) (the first: "
                         f"frame {f}, marker {names[m]!r}) read back as gaps: C3D readers "
                         "take a point at the origin as missing")
        over = _float32_overflow(motion)
        if over:
            refuse.append(over)
        too_long = _names_with(names, lambda n: is_utf8(n) and len(n.encode("utf-8")) > 255)
        if too_long:
            refuse.append(f"C3D labels hold at most 255 bytes: {', '.join(too_long)}")
        nul = _names_with(names, lambda n: "\0" in n)
        if nul:         # "A\0" read back as "A", and the real "A" became "A#2" (QA, stop 47)
            refuse.append("C3D pads labels with NULs, which readers strip: marker names with "
                          f"a NUL would read back as other names: {', '.join(nul)}")
    if ext in SKELETON_FORMATS:        # issue 13: the skeleton formats need their skeleton
        refuse += skeleton_problems(motion, ext)
        if not refuse:
            moved = _positions_off_channels(motion)
            if moved is not None:
                notes.append(f"{fmt} holds the skeleton and its channels, not positions: the "
                             f"motion's positions differ from the joints its channels give by "
                             f"up to {moved:.4g} {motion.units or 'units'} (an edit, or a "
                             "lossy marker layer), and the file gives the channels' joints")
        read_back: tuple[list[str], Skeleton | None] | None = None
        if not refuse:
            try:
                read_back = skeleton_read_back(motion, ext)
            except InputFormatError as exc:
                if ext == ".amc":
                    refuse.append(
                        f"the AMC and ASF written would not read back ({exc.message}): a "
                        "bone name with '#' or that starts with ':', or an AMC header line "
                        "that is neither a comment nor a keyword, reads otherwise; write the "
                        "joint positions (.npy, .csv) instead")
        otherwise = [] if read_back is None else [
            (a, b) for a, b in zip(motion.names, read_back[0], strict=False) if a != b]
        if otherwise:
            # a valid file whose MNAM names its joints otherwise than its skeleton chunk
            # (u36, u43) decoded to a BVH whose compare with its own .mpz found markers
            # missing, with no word (a CLI fuzzing QA run of stop 54)
            notes.append(f"{fmt} names each joint as the skeleton does, not as the "
                         f"motion's marker names: {len(otherwise)} read back otherwise ("
                         + ", ".join(f"{a!r} as {b!r}" for a, b in otherwise[:5])
                         + (", ..." if len(otherwise) > 5 else "") + ")")
        if ext == ".amc" and rate != 120.0:
            notes.append(f"AMC does not store the rate: {rate!r} Hz reads back as 120 Hz "
                         "unless the reader is told")
        skel = motion.extras.get("skeleton")
        if read_back is not None and read_back[1] is not None and isinstance(skel, Skeleton):
            changed = asf_text_changes(skel, read_back[1])
            if changed:
                notes.append("the ASF's text will not read back as stored: " + "; ".join(
                    f"{k} {getattr(skel, k, '')!r} reads back as {v!r}"
                    for k, v in changed.items()) + " (ASF readers split lines at U+000B, "
                    "U+000C, U+001C-U+001E, U+0085, U+2028 and U+2029, and words at white "
                    "space)")
    elif motion.angles is not None:
        notes.append(f"joint angles and the skeleton are not written to {fmt}")
    held = {".c3d": {"c3d"}, ".bvh": {"skeleton"}, ".amc": {"skeleton"}}.get(ext, set())
    if motion.angles is not None:      # the note above already says the skeleton is dropped
        held = held | {"skeleton"}
    for key in sorted(held_extras(motion.extras) - held):   # the reader's list: no data
        value = motion.extras[key]
        what = value.describe() if hasattr(value, "describe") else key
        notes.append(f"{fmt} does not hold the source's {'C3D archive' if key == 'c3d' else key}"
                     f", not written: {what}")
    if first != 1 and ext in (".npy", ".csv", ".bvh"):
        notes.append(f"{fmt} does not hold the first frame number ({first}): frames are "
                     "counted from " + ("0" if ext == ".csv" else "the start"))
    return refuse, notes


def _subject_held(motion: Motion, ext: str) -> bool:
    """Whether the file written as ``ext`` gives back ``motion``'s subject: only a C3D whose
    archive's SUBJECTS:NAMES names the same (the archive's parameters are written as
    stored; no writer makes a SUBJECTS group of its own)."""
    archive = motion.extras.get("c3d")
    if ext != ".c3d" or archive is None:
        return False
    from mpz.io.c3d import archive_subject
    return archive_subject(archive) == motion.metadata.get("subject")


def _positions_off_channels(motion: Motion) -> float | None:
    """How far a skeletal motion's valid positions lie from the joints its channels give,
    when that is more than 1 % of the skeleton's rest height: BVH and AMC are written from
    the channels, so such positions (an edit after reading) are not what the file gives.
    A decoded file's marker layer is a preview within far less (spec Appendix C)."""
    from mpz.io.kinematics import rest_height
    from mpz.skeleton import largest_joint_offset, marker_scale
    skel = motion.extras.get("skeleton")
    if not isinstance(skel, Skeleton) or motion.angles is None or not motion.valid.any():
        return None
    worst = largest_joint_offset(motion)
    return (worst if worst is not None and worst > 0.01 * rest_height(skel) * marker_scale(skel)
            else None)


def _float32_overflow(motion: Motion) -> str | None:
    """Why C3D's float32 points cannot hold the motion's valid coordinates (some beyond
    float32's largest finite value, 3.4028235e38, would be written as infinities that read
    back as valid: a QA run), or None."""
    v = motion.positions[motion.valid]
    with np.errstate(over="ignore", invalid="ignore"):
        inf = np.isinf(v.astype(np.float32)) & np.isfinite(v)
    if not inf.any():
        return None
    k, j = (int(i) for i in np.argwhere(inf)[0])
    f, m = (int(i) for i in np.argwhere(motion.valid)[k])
    x = float(motion.positions[f, m, j])
    return (f"C3D stores points as float32, whose largest value is "
            f"{float(np.finfo(np.float32).max):.8g}: {int(inf.sum())} valid coordinate(s) "
            f"are beyond it and would be written as infinities (the first: frame {f}, "
            f"marker {motion.names[m]!r}, {x!r}); write .npy or .csv, which keep them")


#: the float slack of spec §7.2, relative to the largest |coordinate|
SPEC_FLOAT_SLACK = 2.0 ** -50

#: :func:`rounding_notes` says nothing of a TRC's rounding that can take a value beyond a
#: bound above 0 by no more than this share of it (TRC's 6 decimals round by 8.7e-7 mm at
#: most, 1e-6 of a 1 mm bound: a note on every TRC would be noise); a bound of 0 gets every
#: one, and so does C3D's float32 rounding, whatever its share
ROUNDING_NOTE_SHARE = 1e-4


#: valid samples :func:`rounding_notes` measures at a time (a block of frames)
ROUNDING_BLOCK = 1 << 18


def rounding_notes(motion: Motion, ext: str, bound: float | None) -> list[str]:
    """What the number format of ``ext`` adds to a decoded motion's error, when it can put
    values beyond the file's declared ``bound``; with no bound (None: a motion written by
    :func:`write`), how many valid samples the number format changes at all, and by how
    much.

    C3D without an archive stores float32 points, TRC a fixed number of decimals
    (:func:`mpz.io.trc.column_decimals`); CSV (``repr``) and NPY (float64) keep every
    value, and a C3D archive's points are either int16 words on the source's own grid
    (exact) or float32 values the encoder coded within the bound less float32's rounding
    (spec Appendix C item 3, :func:`mpz.c3darchive.float32_bound`). The rounding is
    measured on the valid values; it is said when it exceeds what the bound leaves for
    it: spec §7.2's float slack max|x| x 2^-50, plus for a float C3D source the margin
    :func:`~mpz.c3darchive.float32_bound` kept (estimated from below). A bound of 0 (the
    source's int16 grid, exact) leaves nothing, so every rounded sample is over it and
    counted; otherwise the decoder cannot know each sample's own error, so the note says
    how far beyond the bound a value may lie: for a C3D whenever it can, for a TRC when
    that is more than :data:`ROUNDING_NOTE_SHARE` of the bound.
    """
    from mpz.c3darchive import C3DArchive, C3DStorage, float32_bound
    if (bound is not None and not math.isfinite(bound)) or ext not in (".c3d", ".trc") \
            or not motion.valid.any():
        return []
    archive = motion.extras.get("c3d")
    if ext == ".c3d" and isinstance(archive, C3DArchive):
        return []
    # in blocks of frames: the valid samples, their rounding and the differences at once
    # took 1.3 GB for 2^24 marker-frames, more than decoding them
    step = max(1, ROUNDING_BLOCK // max(1, motion.n_markers))
    blocks = [(i, min(i + step, motion.n_frames)) for i in range(0, motion.n_frames, step)]

    def valid_in(a: int, b: int) -> NDArray[np.float64]:
        return motion.positions[a:b][motion.valid[a:b]]

    peak = max(float(np.abs(valid_in(a, b)).max(initial=0.0)) for a, b in blocks)
    if not math.isfinite(peak):
        return []
    if ext == ".c3d":
        what = "C3D stores points as float32"
    else:
        from mpz.io.trc import column_decimals
        d = column_decimals(motion)
        what = f"TRC is written with {d} decimals"

    def rounding(v: NDArray[np.float64]) -> NDArray[np.float64]:
        """Each sample's distance to the value the format writes (0 at an overflow, which
        is refused, not noted)."""
        with np.errstate(over="ignore", invalid="ignore"):
            if ext == ".c3d":
                w = v.astype(np.float32).astype(np.float64)
            else:
                # a value of 2^52 or more is a whole number, which d decimals print
                # exactly; np.round(v, d) multiplies by 10^d first, and so reported 1e30 as
                # changed by 1.1e12 where the TRC reads back exact (a QA run of stop 54)
                w = np.where(np.abs(v) >= 2.0 ** 52, v, np.round(v, d))
            r = np.sqrt(((w - v) ** 2).sum(axis=1))
        return np.where(np.isfinite(r), r, 0.0)

    u = f" {motion.units}" if motion.units else ""
    kept = 0.0
    if bound is not None:
        bound = max(float(bound), 0.0)
        if isinstance(archive, C3DArchive) and archive.word_storage != C3DStorage.INT16 \
                and bound > 0:
            # the encoder coded within float32_bound(e, peak of the source); the source's
            # peak is at least the decoded one less e, and a lower peak gives a lower margin
            kept = bound - float32_bound(bound, max(0.0, peak - bound), lambda: True)
    samples = changed = over = 0
    worst = 0.0
    for a, b in blocks:
        r = rounding(valid_in(a, b))
        samples += r.size
        changed += int((r > 0).sum())
        over += int((r > kept + SPEC_FLOAT_SLACK * peak).sum())
        worst = max(worst, float(r.max(initial=0.0)))
    if bound is None:        # no bound to weigh it against: any change is said (QA, stop 50)
        return [] if not changed else [
            f"{what}: {changed} of {samples} valid samples change, by up to "
            f"{worst:.2g}{u}; write .csv or .npy for the exact values"]
    # TRC's decimals below the share are noise; C3D's float32 is said whenever it can pass
    # the bound (a QA of stop 48: BVH and AMC decoded to C3D passed their position_bound
    # by up to 6.7e-6 mm without a word)
    share = ROUNDING_NOTE_SHARE if ext == ".trc" else 0.0
    if not over or worst - kept <= share * bound:
        return []
    if bound == 0:
        return [f"{what}: values rounded by up to {worst:.2g}{u}, beyond the file's "
                f"declared bound of 0{u} (exact) at {over} of {samples} valid "
                "samples; write .csv or .npy for the exact values"]
    return [f"{what}: values rounded by up to {worst:.2g}{u}, which the file's declared "
            f"{bound:g}{u} bound does not budget: a value may lie up to "
            f"{worst - kept:.2g}{u} beyond it; write .csv or .npy to keep the bound"]


def check_writable(motion: Motion, ext: str, *, path: StrPath | None = None,
                   bound: float | None = None) -> list[str]:
    """Raise if format ``ext`` cannot hold ``motion`` faithfully; return the notes, with
    :func:`rounding_notes` against a decoded file's declared ``bound`` when given.

    Raises
    ------
    InputFormatError
        Naming ``path`` and every reason (see :func:`writer_problems`); for an ``ext``
        that no writer has (``".xyz"``, or ``"npy"`` without its dot: it returned no
        note, as if writable; a QA run of stop 48).
    """
    if not isinstance(motion, Motion):       # AttributeError of None (a QA run, stop 50)
        raise TypeError(f"expected an mpz.Motion, got {type(motion).__name__}")
    if not isinstance(ext, str):
        raise TypeError(f"ext must be a str such as '.trc', got {type(ext).__name__}")
    ext = ext.lower()           # ".C3D", as write(m, "Z.C3D") takes it (a QA run, stop 50)
    if ext not in WRITERS:      # ".xyz", or "npy" without its dot, passed as writable
        raise InputFormatError(f"cannot write {ext or '(no extension)'!r}; can write "
                               f"{', '.join(WRITERS)}",
                               path=None if path is None else os.fspath(path))
    refuse, notes = writer_problems(motion, ext)
    if refuse:
        raise InputFormatError(f"cannot write {FORMAT_NAMES.get(ext, ext)}: "
                               + "; ".join(refuse),
                               path=None if path is None else os.fspath(path))
    return notes + rounding_notes(motion, ext, bound)


__all__ = ["read", "write", "READERS", "WRITERS", "FORMAT_NAMES", "SKELETON_FORMATS",
           "read_c3d", "write_c3d", "read_trc", "write_trc", "read_bvh",
           "read_amc", "read_asf", "find_asf", "read_npy", "write_npy",
           "read_csv", "write_csv", "detect_format", "read_bytes", "check_writable",
           "writer_problems", "rounding_notes", "READER_KEYS", "READER_PREFIXES",
           "READ_BACK_NOTE"]
