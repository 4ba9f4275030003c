"""Helpers shared by the command-line tools (not part of the public API).

Contract:

* ``-`` means standard input as an input and standard output as an output,
  everywhere (as in zstd). Standard input has no name, so its format is found
  from its content (:func:`mpz.io.detect_format`); it is read with a bound
  (:func:`read_stdin`), and never from a terminal.
* Lengths on the command line carry a unit (:func:`parse_length`).
* Several inputs, folders with ``-r`` and ``-o FOLDER/`` are planned by
  :func:`plan_batch`; :func:`run_batch` runs one job per input, keeps going
  past a failed one and reports each (mpz encode, mpz decode).
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
import math
import os
from pathlib import Path
import re
import sys
import time
from typing import IO, TYPE_CHECKING

from mpz.errors import EncoderError, FormatError, MPZError
from mpz.format import MM_PER_UNIT
from mpz.io._common import is_folder, walk
from mpz.tools._cli import (
    EXIT_ERROR,
    EXIT_MEMORY,
    found,
    memory_message,
    printable,
    worst,
)

if TYPE_CHECKING:
    from mpz.container import Scan
    from mpz.motion import Motion

#: the input and output name that means standard input / output
STDIO = "-"

#: units a length on the command line may carry, in millimetres
UNITS_MM: dict[str, float] = dict(MM_PER_UNIT)
ACCEPTED_UNITS = ", ".join(UNITS_MM)


class UsageError(Exception):
    """A combination of arguments that cannot work (exit 64, with the usage)."""


# -- lengths and units -------------------------------------------------------------------

#: a length on the command line: a plain decimal number and an optional unit
_LENGTH = re.compile(r"\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*([A-Za-z]*)\s*")


def parse_length(text: str, units: str, option: str = "--max-error") -> float:
    """``'2mm'``, ``'0.2 cm'``, ``'0.002m'`` -> a length in the motion's ``units``.

    A number without a unit is refused when the motion has units (``--max-error
    1`` on a centimetre file would silently mean 10 mm); it is taken in the
    motion's own units only when the input declares none (BVH), and the
    reports then say "(input units)".

    Raises
    ------
    EncoderError
        Naming ``option``, the text and the accepted units.
    """
    number, unit = _length_parts(text, option)
    value = float(number)
    if not unit:
        if units in UNITS_MM:
            raise EncoderError(f"{option} {text}: give a unit ({ACCEPTED_UNITS}), e.g. "
                               f"{number}mm; a bare number would silently mean "
                               f"{number} {units}, the input's units")
        return value
    if units not in UNITS_MM:
        raise EncoderError(f"{option} {text}: the input does not say its units, so a length "
                           "in mm, cm, m or in cannot be converted; give a plain number in "
                           "the input's own units")
    return value * UNITS_MM[unit] / UNITS_MM[units]


def _length_parts(text: str, option: str) -> tuple[str, str]:
    """(number as written, unit in lower case or "") of a length, or EncoderError for a
    malformed one or an unknown unit, naming ``option``."""
    m = _LENGTH.fullmatch(text)
    if not m and text.strip()[:1] in ("-", "+") and _LENGTH.fullmatch(text.strip()[1:]):
        # "-1mm" is a number and a unit: it was told to write one (a newcomer's QA run)
        raise EncoderError(f"{option} {text.strip()}: a length must be above 0"
                           + (", without a sign" if text.strip()[0] == "+" else ""))
    if not m:
        raise EncoderError(f"{option}: cannot read a length from {text!r}; write a number "
                           f"and a unit ({ACCEPTED_UNITS}), e.g. 2mm or 0.5cm")
    unit = m.group(2).lower()
    if unit and unit not in UNITS_MM:
        raise EncoderError(f"{option}: unknown unit {unit!r} in {text!r}; accepted units: "
                           f"{ACCEPTED_UNITS}")
    return m.group(1), unit


def check_length(text: str | None, option: str) -> None:
    """Refuse, before any input is read, a length that no input's units can make valid: a
    malformed one, an unknown unit, or a number outside the encoder's range of lengths as
    written (0, 1e999 = inf, 1e-320). A unit's conversion is at most a factor of 1000, so
    what passes here fails later only at the range's very ends."""
    if text is None:
        return
    from mpz.encoder import MAX_LENGTH, MIN_LENGTH
    number, _ = _length_parts(text, option)
    if not MIN_LENGTH <= float(number) <= MAX_LENGTH:
        raise EncoderError(f"{option} {text.strip()}: a length's number must be from "
                           f"{MIN_LENGTH:g} to {MAX_LENGTH:g}")


def renamed_list(meta: Mapping[str, str], shown: int = 10) -> str:
    """``metadata["renamed_points"]`` for a message: its first ``shown`` renames and how
    many more (32800 C3D points with 255 labels printed 575 KB of them in one note: a C3D
    QA run); "" when none were renamed."""
    renamed = [r for r in str(meta.get("renamed_points", "")).split("; ") if r]
    more = len(renamed) - shown
    return "; ".join(renamed[:shown]) + (f"; and {more} more" if more > 0 else "")


def ratio_text(ratio: float) -> str:
    """A compression ratio for a report's ``R:1``: one decimal, or, where that shows less
    than 1.0, two significant digits in fixed notation (a one-frame AMC's 0.06 printed
    "0.0:1": an animation studio's QA run of stop 75); 0 as "0.0"."""
    one = f"{ratio:.1f}"
    if float(one) >= 1.0 or ratio <= 0 or not math.isfinite(ratio):
        return one
    return f"{ratio:.{max(1, 1 - math.floor(math.log10(ratio)))}f}"


def human_size(n: int) -> str:
    """``n`` bytes in binary units, named as such (KiB, MiB, GiB: "KB" for 1024 bytes
    disagreed with the corpus table's decimal MB by 5 %, a QA run of stop 47)."""
    for unit, div in (("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n >= div:
            return f"{n / div:.1f} {unit}"
    return f"{n} B"


# -- progress and first-run notice ---------------------------------------------------------

#: inputs at least this large get a line on stderr at each long step of a command (on a
#: terminal): a 2-hour capture read for 20 s, decoded for minutes, with nothing shown (a
#: QA run of stop 51)
STAGE_BYTES = 32 << 20


#: what an .mpz input counts for :func:`stage`: about this many bytes of source a byte (the
#: 29 real files at the default bound code 10-40 x their float32 positions)
MPZ_EXPANSION = 16


def is_clone(root: Path) -> bool:
    """Whether ``root`` is the top of a clone of the repository (its pyproject.toml and
    spec/mpz-1.md are there): the makers of frozen files write into a clone only, not
    into an installed package (a release QA run, stop 74: make_vectors rewrote the
    vectors that the installed mpz-conformance checks against)."""
    return (root / "pyproject.toml").is_file() and (root / "spec" / "mpz-1.md").is_file()


def on_terminal() -> bool:
    """stderr is a terminal (progress and stage lines are for a person watching)."""
    return sys.stderr.isatty()


def input_size(path: str) -> int:
    """The size of an input file, 0 when it has none (standard input, a pipe)."""
    try:
        return os.stat(path).st_size if path != STDIO else 0
    except (OSError, ValueError):
        return 0


def stage(command: str, quiet: bool, size: int, what: str) -> None:
    """One line on stderr before a long step of ``command`` on an input of ``size``
    bytes: on a terminal, without -q, for inputs of :data:`STAGE_BYTES` or more."""
    if not quiet and size >= STAGE_BYTES and on_terminal():
        print(f"mpz {command}: {what}", file=sys.stderr, flush=True)


class Progress:
    """A one-line progress bar on stderr, shown only when stderr is a terminal."""

    def __init__(self, label: str, enabled: bool | None = None):
        self.label = label
        self.enabled = on_terminal() if enabled is None else enabled
        self.t0 = time.perf_counter()

    def __call__(self, fraction: float, message: str = "") -> None:
        if not self.enabled:
            return
        width = 30
        done = int(width * max(0.0, min(1.0, fraction)))
        bar = "#" * done + "-" * (width - done)
        sys.stderr.write(f"\r{self.label} [{bar}] {fraction:4.0%} "
                         f"{printable(message)[:24]:<24} "
                         f"{time.perf_counter() - self.t0:5.1f}s")
        sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            sys.stderr.write("\n")
            sys.stderr.flush()


#: the numba kernels that encoding a file (and checking it by decoding) calls: module,
#: names. Other kernels (the summary's, the tests' references) may never run.
_CODEC_KERNELS = (("mpz.entropy", ("_encode_block", "_decode_block")),
                  ("mpz.keyframe", ("_fit", "_best_reference", "_mark_keys", "_rebuild")),
                  ("mpz.quantize", ("_choose",)))


def kernels_need_compiling() -> bool:
    """True if a numba kernel that encoding calls has no cache yet (the first run after
    install, when the kernels shipped with the package do not serve this process).

    Asks :func:`mpz._jit.will_compile` for each kernel of :data:`_CODEC_KERNELS`: no index
    file in the cache, and none among the shipped kernels (docs/cold-start.md).
    """
    import importlib
    try:
        from numba.core.registry import CPUDispatcher
    except ImportError:
        return False
    from mpz._jit import will_compile
    for name, kernels in _CODEC_KERNELS:
        mod = importlib.import_module(name)
        for k in kernels:
            obj = getattr(mod, k, None)
            if isinstance(obj, CPUDispatcher) and will_compile(obj):
                return True
    return False


def compile_notice(quiet: bool = False, verbose: bool = False, *, announce: bool = True) -> None:
    """One line on stderr, on a terminal only, when the kernels are about to be compiled.

    Why a notice and not a warm-up at install: pip builds and installs wheels
    without running project code, and numba's cache depends on the machine's
    CPU, so the first run is the earliest safe moment; the notice explains the
    pause (about 5 s) instead of hiding it (docs/cold-start.md). With ``verbose``,
    also one line, terminal or not, when no directory can hold the compiled kernels
    (:func:`mpz._jit.cache_note`: every run compiles). ``announce=False`` keeps only
    that line (decoding compiles for about 1 s, not worth a notice).
    """
    if quiet:
        return
    if verbose:
        from mpz._jit import cache_note
        note = cache_note()
        if note is not None:
            print(note, file=sys.stderr, flush=True)
    if not announce or not sys.stderr.isatty():
        return
    if kernels_need_compiling():
        print("mpz: first run after install: compiling the codec's kernels "
              "(about 10-30 s, longer on a busy machine; cached for later runs)",
              file=sys.stderr, flush=True)


# -- inputs: files, standard input ----------------------------------------------------------

def _stdin() -> IO[bytes]:
    if sys.stdin is None:
        raise FormatError("there is no standard input", path=STDIO)
    if sys.stdin.isatty():
        raise FormatError("standard input is a terminal: pipe data into it, or name a file",
                          path=STDIO)
    return sys.stdin.buffer


def read_stdin(limit: int | None = None, *, assume: str | None = None
               ) -> tuple[bytes, str | None]:
    """All of standard input, bounded, and its format from the content, or ``assume`` when
    the content does not say and is text, without a NUL byte in its first 4096 bytes
    (``".amc"`` when ``--asf`` names its skeleton: an AMC without header lines has nothing
    to be known by, a QA run of stop 52; zeros or a binary file are still refused at their
    first bytes).

    MPZ is read chunk by chunk (:func:`mpz.api.read_stream_bytes`: a chunk
    over 2^30 bytes is refused before it is read, reading stops at MEND);
    other formats whole, up to :data:`mpz.api.MAX_INPUT_BYTES`. ``/dev/zero``
    stops at the first bytes: zeros are no known format.

    Returns
    -------
    data, fmt
        The bytes, and the extension :func:`mpz.io.detect_format` gave (None if
        nothing matched).
    """
    from mpz.api import MAX_INPUT_BYTES, _read_exact, read_stream_bytes
    from mpz.errors import LimitExceededError
    from mpz.io import DETECT_BYTES, detect_format
    cap = MAX_INPUT_BYTES if limit is None else limit
    fh = _stdin()
    head = _read_exact(fh, 8)        # the MPZ signature: from here on, read chunk by chunk
    if detect_format(head) == ".mpz":
        return read_stream_bytes(fh, limit=cap, prefix=head), ".mpz"
    head += _read_exact(fh, DETECT_BYTES - len(head))
    fmt = detect_format(head) or (assume if head.strip() and b"\0" not in head else None)
    if fmt is None:
        return head, None
    # the limit as soon as it is passed, and one join: an endless stream was read to the
    # limit in parts, joined, then joined again to the head, and ran out of memory at
    # 4.3 GB before the limit was said (a security QA run, stop 73)
    parts, total = [head], len(head)
    while total <= cap:
        block = _read_exact(fh, min(cap - total + 1, 1 << 22))
        if not block:
            break
        parts.append(block)
        total += len(block)
    if total > cap:
        del parts
        raise LimitExceededError(f"standard input longer than {cap} bytes, the most read",
                                 path=STDIO, section="§8")
    return b"".join(parts), fmt


#: the motion formats that store no frame rate (their readers assume one): ``--rate`` of
#: mpz encode, search and summary names it
RATELESS_FORMATS = (".amc", ".npy")


def with_rate(motion: Motion, rate: float | None, *, batch: bool = False) -> Motion:
    """``--rate``: ``motion`` at ``rate`` Hz when its format stores none
    (:data:`RATELESS_FORMATS`); unchanged for None. For a motion that has a rate of its own
    it is an error (a file's rate is not overridden silently); in a ``batch`` of several
    inputs, ``--rate`` names the rate of those without one and leaves the others.

    Raises
    ------
    EncoderError
        For a ``rate`` given to one motion that stores its own.
    """
    from dataclasses import replace
    if rate is None:
        return motion
    fmt = motion.metadata.get("format", "")
    if f".{fmt}" not in RATELESS_FORMATS:
        if batch:
            return motion
        raise EncoderError(f"--rate {rate:g}: this {fmt.upper() or 'input'} stores its "
                           f"rate ({motion.rate:g} Hz); --rate is for inputs without one "
                           "(AMC, NPY)")
    meta = {k: v for k, v in motion.metadata.items() if k != "rate_assumed"}
    return replace(motion, rate=float(rate), metadata=meta)


def assumed_rate(motion: Motion, rate: float | None) -> str | None:
    """The note for a motion whose format stores no rate and was given no ``--rate``:
    its reader's rate is assumed (an NPY was taken at 1 Hz without a word: QA runs)."""
    fmt = motion.metadata.get("format", "")
    if rate is not None or f".{fmt}" not in RATELESS_FORMATS:
        return None
    return (f"{fmt.upper()} stores no frame rate: {motion.rate:g} Hz is assumed; give the "
            "true one with --rate HZ")


def read_mpz_input(path: str, max_samples: int | None = None, *,
                   marker_layer: bool = False) -> Motion:
    """Decode an MPZ input: a file or ``-`` (standard input), as ``mpz decode`` writes it.

    A skeletal file (BVH, AMC) comes back with the joint positions computed from its
    skeleton's channels (:func:`mpz.skeleton.with_joint_positions`, spec §6.10: within
    the declared position bound), not the 1.0 marker layer, which the reference encoder
    keeps only as a coarse preview: ``mpz compare``, ``show`` and ``summary`` then see
    the motion ``mpz decode`` writes (:func:`joint_positions_from_channels` says which).
    With ``marker_layer``, the marker layer alone, as a 1.0 decoder reads it
    (``mpz.decode(markers_only=True)``: ``mpz compare --marker-layer``).
    """
    if path != STDIO:
        return _decode(path, max_samples, marker_layer)
    data, fmt = read_stdin()
    if fmt != ".mpz":
        raise FormatError(f"standard input is not an MPZ file (first bytes {data[:8]!r})",
                          path=STDIO)
    return read_mpz_input_bytes(data, max_samples, marker_layer=marker_layer)


def _decode(source: str | bytes, max_samples: int | None, marker_layer: bool = False
            ) -> Motion:
    import mpz
    from mpz.format import MAX_SAMPLES
    from mpz.skeleton import has_channels, with_joint_positions
    motion = mpz.decode(source, max_samples=MAX_SAMPLES if max_samples is None
                        else max_samples, markers_only=marker_layer)
    return with_joint_positions(motion) if has_channels(motion) else motion


def joint_positions_from_channels(motion: Motion, ext: str | None) -> bool:
    """True if ``motion``, read from a file of extension ``ext`` by :func:`read_input`, is
    an .mpz whose positions were computed from its skeleton's channels
    (:func:`read_mpz_input`)."""
    from mpz.io.kinematics import Skeleton
    return ext == ".mpz" and isinstance(motion.extras.get("skeleton"), Skeleton)


def read_motion(path: str, asf: str | None = None
                ) -> tuple[Motion, int | None, bytes | None]:
    """Any supported input: a motion file, an .mpz file (decoded), or ``-``; its size in
    bytes (what standard input held; None when a file's size cannot be had); and the MPZ
    bytes when ``path`` is ``-`` and standard input held an MPZ file (None otherwise: a
    file can be read again, standard input cannot), for ``mpz encode``'s look at the
    input's summary chunk.

    ``-`` is read from standard input, its format found from its content.
    """
    motion, ext, data, size = _read_input(path, asf, None, keep=path == STDIO)
    return motion, size, data if ext == ".mpz" else None


def read_input(path: str, asf: str | None = None, *,
               max_samples: int | None = None) -> tuple[Motion, str | None]:
    """:func:`read_motion`, and the extension of the format that was read (``".mpz"``...)."""
    motion, ext, _, _ = _read_input(path, asf, max_samples, keep=False)
    return motion, ext


def read_input_keeping(path: str, asf: str | None = None, *,
                       max_samples: int | None = None, marker_layer: bool = False
                       ) -> tuple[Motion, str | None, bytes | None]:
    """:func:`read_input`, and the bytes of an MPZ input (None for other formats), for a
    caller that reads its chunks too (``mpz compare``: the skeleton chunk's steps; ``mpz
    show``: the declared bound). A file is read again for them; standard input, once.
    ``marker_layer``: as :func:`read_mpz_input`'s, for an MPZ input."""
    motion, ext, data, _ = _read_input(path, asf, max_samples, keep=True,
                                       marker_layer=marker_layer)
    return motion, ext, data


def parts_of(chunk_bytes: dict[str, int], file_bytes: int) -> dict[str, int]:
    """Bytes of an MPZ file by part, each chunk with its 12-byte frame: ``markers`` (the
    signature and the critical chunks, MHDR .. MEND), ``analog`` (cana), ``skeleton``
    (bvhs, asfs: the skeleton and its channels) and ``rest`` (C3D parameters and model
    outputs, metadata, summary, unknown chunks). What ``mpz encode`` and ``mpzinfo``
    report. The parts are the records' ``PART`` (:func:`mpz.chunks.types_of_part`)."""
    from mpz.chunks import types_of_part
    markers = 8 + sum(n for t, n in chunk_bytes.items() if t[:1].isupper())
    analog = sum(chunk_bytes.get(t, 0) for t in types_of_part("analog"))
    skeleton = sum(chunk_bytes.get(t, 0) for t in types_of_part("skeleton"))
    return {"markers": markers, "analog": analog, "skeleton": skeleton,
            "rest": file_bytes - markers - analog - skeleton}


def declared_bound(res: Scan) -> float | None:
    """The error bound MHDR declares (spec §4.1, §7.2) in a :func:`mpz.container.scan` of
    MPZ bytes; None when it declares none or has no readable MHDR."""
    from mpz.chunks import Mhdr
    hdr = res.chunks[0].record if res.chunks else None
    if not isinstance(hdr, Mhdr) or not hdr.error_metric:
        return None
    return float(hdr.error_bound)


def positions_bound(motion: Motion, ext: str | None, data: bytes, res: Scan) -> float | None:
    """The bound declared on the positions of ``motion`` as read from the MPZ bytes
    ``data`` (``res``: their :func:`mpz.container.scan`): for joint positions computed
    from a skeleton's channels (:func:`joint_positions_from_channels`), the skeleton
    chunk's ``position_bound`` (§4.14; None for 0, none); otherwise MHDR's
    (:func:`declared_bound`), which is the marker layer's."""
    if not joint_positions_from_channels(motion, ext):
        return declared_bound(res)
    from mpz.skeleton import report
    rep = report(data)
    pb = float(rep["position_bound"]) if rep is not None else 0.0  # type: ignore[arg-type]
    return pb if pb > 0 else None


def _read_input(path: str, asf: str | None, max_samples: int | None, *, keep: bool,
                marker_layer: bool = False
                ) -> tuple[Motion, str | None, bytes | None, int | None]:
    """The motion, its format's extension, the MPZ bytes if ``keep``, and the input's
    size in bytes."""
    from mpz.io._common import ext_of
    if path == STDIO:
        data, fmt = read_stdin(assume=".amc" if asf is not None else None)
        if fmt == ".mpz":
            return (read_mpz_input_bytes(data, max_samples, marker_layer=marker_layer), fmt,
                    data if keep else None, len(data))
        from mpz.io import read_bytes
        return read_bytes(data, fmt=fmt, name=STDIO, asf=asf), fmt, None, len(data)
    from mpz.io import READERS, read
    ext = ext_of(path)
    if ext not in READERS and ext != ".mpz":      # no known extension: ask the content
        from mpz.api import open_regular
        from mpz.io import DETECT_BYTES, detect_format
        with open_regular(path) as fh:
            ext = detect_format(fh.read(DETECT_BYTES)) or ext
    try:
        size: int | None = os.path.getsize(path)
    except OSError:
        size = None
    if ext == ".mpz":
        motion = read_mpz_input(path, max_samples, marker_layer=marker_layer)
        if not keep:
            return motion, ext, None, size
        from mpz.api import read_source
        return motion, ext, read_source(path)[0], size
    return read(path, asf=asf), ext, None, size


def read_mpz_input_bytes(data: bytes, max_samples: int | None = None, *,
                         marker_layer: bool = False) -> Motion:
    """:func:`read_mpz_input` of MPZ bytes read from standard input."""
    try:
        return _decode(data, max_samples, marker_layer)
    except MPZError as exc:
        exc.path = STDIO
        raise


# -- outputs -----------------------------------------------------------------------------------

def write_stdout(data: bytes, *, binary: bool, force: bool) -> None:
    """Write ``data`` to standard output; refuse binary data on a terminal unless ``force``."""
    out = sys.stdout
    if binary and not force and out.isatty():
        raise EncoderError("refusing to write binary data to a terminal; redirect standard "
                           "output, or use -f", path=STDIO)
    out.flush()
    # the count write returns: on a full disk or past a file-size limit it was short (1024
    # of 7573 bytes) and nothing was raised, so a cut file left with exit 0 (a QA run of
    # stop 49); writing the rest raises the OSError that says why
    view = memoryview(data)
    while view:
        n = out.buffer.write(view)
        view = view[len(view) if n is None else n:]
    out.buffer.flush()


def is_folder_target(output: str | None) -> bool:
    """``-o`` names a folder: it ends in a path separator (``-o out/``).

    An existing folder named without the separator stays an error ("is a
    folder; give a file name"), so a typo never scatters outputs into a folder.
    """
    if output is None or output == STDIO:
        return False
    return output.endswith(("/", os.sep))


# -- batches ---------------------------------------------------------------------------------

@dataclass
class Job:
    """One input of a batch and where its output goes (None: a planning error that names
    no output).

    ``make_folder``: ``-o FOLDER/`` or a folder below it (``--mirror``) that
    :func:`run_batch` creates before the job runs, when it is missing; else None. A job
    with an ``error`` is not run; its ``output`` is the one it would have had when it was
    named (a name clash), else None."""

    input: str
    output: str | None
    error: str | None = None
    make_folder: str | None = None


def expand_inputs(inputs: Sequence[str], recursive: bool, accept: Callable[[str], bool],
                  skip: str | None = None) -> list[tuple[str, str | None, str]]:
    """Inputs with folders expanded (``-r``): (path, planning error or None, base), in order.

    A folder without ``-r`` is an error for that input (as zstd: "is a
    directory -- ignored"); with ``-r`` its files that ``accept`` (by name) are
    taken, sorted, recursively. Hidden files and folders are skipped, and so is the
    folder ``skip`` (the ``-o FOLDER/`` of the batch: outputs written inside an input
    folder, or files decoded there, were taken as inputs by the next run, a QA of stop
    42); links to folders are not followed (:func:`mpz.io._common.walk`: a loop cannot
    hang the walk, and no depth of folders exhausts Python's recursion). ``base`` is the
    folder a path was found in with ``-r`` (as given), else the path's own folder:
    ``--mirror`` keeps the path below it.
    """
    out: list[tuple[str, str | None, str]] = []
    skipped = is_folder(skip)
    for item in inputs:
        if item != STDIO and os.path.isdir(item):
            if not recursive:
                out.append((item, "is a folder; use -r to take the files in it", item))
                continue
            found: list[str] = []
            unlisted: list[OSError] = []      # were skipped without a word (a QA run)
            for root, dirs, files in walk(item, onerror=unlisted.append):
                dirs[:] = sorted(d for d in dirs if not d.startswith(".") and
                                 not skipped(os.path.join(root, d)))
                found += [os.path.join(root, f) for f in sorted(files)
                          if not f.startswith(".") and accept(f)]
            out += [(exc.filename or item, f"cannot list this folder: "
                     f"{exc.strerror or exc}", item) for exc in unlisted]
            if not found and not unlisted:
                out.append((item, "no input files in this folder", item))
            out += [(f, None, item) for f in found]
        else:
            out.append((item, None, os.path.dirname(item)))
    return out


def plan_batch(inputs: Sequence[str], output: str | None, *, recursive: bool,
               accept: Callable[[str], bool], name_for: Callable[[str], str | None],
               what: str, mirror: bool = False,
               same_stem: str = "write it alone with -o, or rename one of the two"
               ) -> list[Job]:
    """Pair every input with its output.

    * ``-o FILE`` (or ``-o -``): exactly one input;
    * ``-o FOLDER/`` (with the trailing separator): every output in that folder, named by
      ``name_for`` from
      the input's base name (flat, as zstd's ``--output-dir-flat``);
    * ``-o FOLDER/`` with ``mirror`` (``--mirror``): a file found with ``-r`` keeps its
      path below the folder given as input (``-r CAPTURES`` with
      ``CAPTURES/s01/walk.c3d`` -> ``FOLDER/s01/walk.mpz``, as zstd's
      ``--output-dir-mirror``, for archives whose file names repeat across folders); a
      file given by name goes to ``FOLDER/`` as without ``mirror``;
    * a missing ``FOLDER/`` and the folders below it are made, with their parents, when
      the first job that writes there runs (nothing is made for a batch that fails
      before);
    * no ``-o``: beside each input; standard input goes to standard output (with
      ``-o FOLDER/`` it fails: it has no name to give its output there).

    Two inputs that would write the same output make the later one fail, unless they
    are the same file (named twice, or by two paths): it is coded once. Where ``-r``
    found them in two folders, the failure names ``--mirror``, which keeps them apart;
    where they lie in one folder, it says ``same_stem``.

    Raises
    ------
    UsageError
        For several inputs with one output file, ``-`` used twice, or ``mirror``
        without ``-o FOLDER/``.
    """
    folder = is_folder_target(output)
    items = expand_inputs(inputs, recursive, accept, skip=output if folder else None)
    if sum(1 for p, _, _ in items if p == STDIO) > 1:
        raise UsageError("standard input (-) can be read only once")
    if mirror and not folder:
        raise UsageError("--mirror keeps the input folders' layout below -o FOLDER/ (ending "
                         "in /); give one")
    if output is not None and not folder and len(items) != 1:
        raise UsageError(f"{len(items)} inputs and one output {printable(output)}: give "
                         "-o FOLDER/ (ending in /) or leave -o out to write beside each input")
    # a missing -o FOLDER/ is made, with its parents, when its first job runs (the
    # trailing separator says it is meant as a folder; zstd's --output-dir-* do the same)
    made = folder and output is not None and not os.path.isdir(output)
    jobs: list[Job] = []
    taken: dict[str, str] = {}
    for path, err, base in items:
        if err is not None:
            jobs.append(Job(path, None, err))
            continue
        if output is not None and not folder:
            jobs.append(Job(path, output))
            continue
        if path == STDIO and output is None:
            jobs.append(Job(path, STDIO))
            continue
        if path == STDIO:           # -o FOLDER/: the output would be named after "-" (QA)
            jobs.append(Job(path, None, "standard input has no file name to name its "
                                        f"output in {printable(output or '')}: give -o FILE, "
                                        "or -o - for standard output"))
            continue
        try:
            name = name_for(path)
        except MPZError as exc:     # naming read the file (decode: its source's format), and
            exc.path = None         # it is corrupt: this file fails, not the batch (QA); the
            jobs.append(Job(path, None, str(exc)))      # line names the file once
            continue
        if name is None:
            jobs.append(Job(path, None, f"cannot name the {what} output: give -o or "
                                        "--format"))
            continue
        make = None
        if folder and output is not None and mirror:
            below = os.path.relpath(name, base or os.curdir)    # name lies beside path
            target = os.path.join(output, below)
            if os.path.dirname(below) or made:      # a file at the top of -r's folder
                make = os.path.join(output, os.path.dirname(below))     # (QA, stop 47)
        elif folder and output is not None:
            target = os.path.join(output, os.path.basename(name))
            make = output if made else None
        else:
            target = name
        key = os.path.normcase(os.path.abspath(target))
        if key in taken and path != STDIO and os.path.realpath(path) == os.path.realpath(
                taken[key]):
            continue            # the same file named again: it is coded once
        if key in taken:
            # found by -r in another folder than the first: --mirror would keep both
            apart = (base is not None and not mirror and os.path.dirname(os.path.abspath(
                path)) != os.path.dirname(os.path.abspath(taken[key])))
            # two formats of one take beside each other (walk.c3d, walk.trc): the remedy
            # is said (a QA run of stop 50); encoding one alone took it out of a corpus
            # (a corpus QA run of stop 76): mpz encode --keep-extension names each
            # after its whole name
            jobs.append(Job(path, target, f"its output {printable(target)} is also the output "
                                        f"of {printable(taken[key])} in this batch"
                                        + ("; --mirror keeps each file's folder below -o"
                                           if apart else f"; {same_stem}")))
            continue
        taken[key] = path
        jobs.append(Job(path, target, make_folder=make))
    return jobs


def plot_format(path: str) -> str:
    """The figure format of a ``--plot`` path: its extension, lower case, without the dot
    (given to ``savefig`` explicitly: it writes to a temporary name)."""
    return os.path.splitext(path)[1].lstrip(".").lower()


def check_plot(path: str, force: bool, sources: Sequence[str]) -> None:
    """Refuse a ``--plot`` path before the work (an EncoderError, exit 2): as any output
    (``mpz.api.check_output``: an existing file only with ``--force``; a QA run found plots
    replacing any file), and with an extension matplotlib cannot write (it raised a
    ValueError traceback after the work). Without matplotlib, an EncoderError that says
    how to install it (``mpz compare --plot`` ended in a traceback, exit 70; ``mpz summary
    --plot --json`` printed no document)."""
    try:
        from matplotlib.backend_bases import FigureCanvasBase
    except ImportError:
        raise EncoderError("--plot needs matplotlib: pip install 'mpz[plot]'") from None

    from mpz.api import check_output
    for src in sources:
        check_output(path, force=force, source=None if src == STDIO else src)
    kinds = FigureCanvasBase.get_supported_filetypes()
    ext = plot_format(path)
    if ext not in kinds:
        raise EncoderError(f"--plot {printable(path)}: matplotlib writes "
                           f"{', '.join('.' + k for k in sorted(kinds))}, not "
                           f"{'.' + ext if ext else 'a file without an extension'}")


def make_folder(folder: str) -> None:
    """Create ``folder`` and its parents if missing (``-o FOLDER/`` and ``--mirror``'s
    folders below it).

    Raises
    ------
    EncoderError
        Naming the folder, when it cannot be made (a file in its place, no permission).
    """
    from mpz.api import folder_problem
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as exc:
        raise EncoderError(f"cannot make the folder {printable(folder)}: "
                           f"{folder_problem(exc)}") from None



def run_batch(command: str, jobs: list[Job], one: Callable[[Job], int], *,
              report: IO[str], quiet: bool,
              failures: list[tuple[Job, BaseException | str, str]] | None = None) -> int:
    """Run ``one`` per job; a failed job is reported on stderr and the others still run.

    Returns the worst exit code (:func:`worst`): 2 when any input failed, 3 when
    one ran out of memory. With more than one job a closing line counts them.
    ``failures``, when given, receives each failed job with its error and status
    ("error" or "memory"), for a ``--json`` document.
    """
    codes: list[int] = []
    failed = 0

    def fail(job: Job, error: BaseException | str, code: int) -> None:
        nonlocal failed
        codes.append(found(code))
        failed += 1
        if failures is not None:
            failures.append((job, error, "memory" if code == EXIT_MEMORY else "error"))

    for job in jobs:
        name = printable(job.input)
        if job.error is not None:
            print(f"mpz {command}: error: {name}: {printable(job.error)}", file=sys.stderr)
            fail(job, job.error, EXIT_ERROR)
            continue
        try:
            if job.make_folder is not None:
                make_folder(job.make_folder)
            codes.append(found(one(job)))
        except MPZError as exc:
            text = printable(str(exc))
            shown = text if exc.path or len(jobs) == 1 else f"{name}: {text}"
            print(f"mpz {command}: error: {shown}", file=sys.stderr)
            fail(job, exc, EXIT_ERROR)
        except MemoryError as exc:
            said = memory_message(exc, command)
            print(f"mpz {command}: {name}: {said}", file=sys.stderr)
            fail(job, said, EXIT_MEMORY)
    if len(jobs) > 1 and not quiet:
        ok = len(jobs) - failed
        print(f"mpz {command}: {len(jobs)} inputs: {ok} done, {failed} failed",
              file=sys.stderr if failed else report)
    return worst(codes)
