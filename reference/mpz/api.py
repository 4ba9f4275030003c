"""File-level helpers around the sans-IO core: read, write (atomically), inspect, summary.

Only this module and :mod:`mpz.io` touch the file system.

Reading is bounded (issue 11.2): a path must name a regular file (a device such
as ``/dev/zero``, a FIFO or a socket is refused before it is opened for
reading, so nothing hangs or reads forever), and a stream (a binary file
object, standard input in the tools) is read chunk by chunk: each chunk's
length is checked against MAX_CHUNK_LENGTH (spec §3.2, §8) before its payload
is read, and reading stops at MEND. No input longer than
:data:`MAX_INPUT_BYTES` is read.
"""
from __future__ import annotations

import _thread
from collections.abc import Iterator, Mapping
import contextlib
from dataclasses import dataclass, field
import errno
import io
import os
import re
import secrets
import signal
import stat
import sys
import tempfile
import threading
import time
from types import FrameType
from typing import IO, Any, BinaryIO, TypeAlias, Unpack, cast

import numpy as np
from numpy.typing import NDArray

from mpz._worker import spelled
from mpz.encoder import EncodeKeywords, EncodeReport  # at run time, as Motion: get_type_hints
from mpz.errors import EncoderError, FormatError, LimitExceededError, MPZError
from mpz.format import MAX_CHUNK_LENGTH, MAX_SAMPLES, SIGNATURE, VERSION_MINOR
from mpz.motion import Motion  # raised NameError under TYPE_CHECKING (an API QA of stop 72)

#: what :func:`decode`, :func:`info` and :func:`read_mpz` accept: a path, the bytes (or a
#: uint8 numpy array of them), or a binary file object (read from its current position up
#: to the end of the MPZ file)
Source: TypeAlias = ("str | os.PathLike[str] | bytes | bytearray | memoryview "
                     "| NDArray[np.uint8] | IO[bytes]")

#: The most bytes read from one input (4 GiB, 2^32). The reference holds a whole file in
#: memory while it decodes; a file this long would by itself exceed the decoding budget of
#: spec §8 (1.5 GiB of output plus 1.5 GiB of integer layer), so it is refused as a lower
#: limit of this decoder ("A decoder MAY use lower limits", §8), before it is read.
MAX_INPUT_BYTES = 1 << 32

_READ_BLOCK = 1 << 20


def open_regular(path: str | os.PathLike[str]) -> BinaryIO:
    """Open ``path`` for reading if it is a regular file; refuse anything else first.

    The file is opened with ``O_NONBLOCK`` and checked with ``fstat`` on the
    open descriptor, so a FIFO without a writer cannot hang the open and a
    file swapped in after a check cannot slip through.

    Raises
    ------
    FormatError
        "no such file", "is a folder", or "not a regular file" (a character or
        block device such as ``/dev/zero``, a FIFO, a socket), naming the path.
    """
    p = os.fspath(path)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(p, flags)
    except FileNotFoundError:
        raise FormatError("no such file", path=p) from None
    except IsADirectoryError:
        raise FormatError("is a folder, not a file", path=p) from None
    except OSError as exc:
        raise FormatError(f"cannot read: {exc.strerror or exc}", path=p) from None
    try:
        mode = os.fstat(fd).st_mode
        if stat.S_ISDIR(mode):
            raise FormatError("is a folder, not a file", path=p)
        if not stat.S_ISREG(mode):
            kind = ("a character device" if stat.S_ISCHR(mode) else
                    "a block device" if stat.S_ISBLK(mode) else
                    "a FIFO" if stat.S_ISFIFO(mode) else
                    "a socket" if stat.S_ISSOCK(mode) else "not a regular file")
            raise FormatError(f"{kind}, not a regular file: refusing to read it (to read "
                              "a stream, redirect it to standard input and name the input -)",
                              path=p)
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def _wait_readable(fh: IO[bytes]) -> None:
    """Wait until ``fh`` has data or its end. A pipe that a parent set non-blocking
    (``O_NONBLOCK``, shared by every process that holds it) reads None while its writer is
    still at work: that was taken for the end of the stream, and a slow producer's file
    for an empty one ("cannot tell the format from the content (first bytes b'')", exit 2;
    a QA run of the CLI plumbing)."""
    import select
    try:
        select.select([fh.fileno()], [], [])
    except (AttributeError, OSError, ValueError):      # no descriptor to wait on
        time.sleep(0.01)


def _read_exact(fh: IO[bytes], n: int) -> bytes:
    """Up to ``n`` bytes (fewer only at the end of the stream)."""
    parts: list[bytes] = []
    while n > 0:
        b = fh.read(min(n, _READ_BLOCK))
        if b is None:               # a non-blocking stream with nothing to read yet
            _wait_readable(fh)
            continue
        if not b:
            break
        if not isinstance(b, (bytes, bytearray)):   # a text stream (QA, stop 33)
            raise TypeError(f"the stream's read() gave {type(b).__name__}, not bytes: open "
                            "the MPZ file in binary mode ('rb')")
        parts.append(b)
        n -= len(b)
    return b"".join(parts)


def read_stream_bytes(fh: IO[bytes], *, limit: int = MAX_INPUT_BYTES,
                      prefix: bytes = b"", trailing: bool = True) -> bytes:
    """The bytes of one MPZ file from a stream, read chunk by chunk (spec §3.2 order of tests).

    Reads the signature, then each chunk frame: a length over MAX_CHUNK_LENGTH
    (2^30) or one that would take the total past ``limit`` stops the reading
    *before* the payload is read. Reading ends after MEND's CRC; with
    ``trailing`` one more byte is read, so that data after the file is seen and
    rejected by the decoder (standard input: a whole stream is one file);
    without it the stream is left just after the file (a file object that holds
    more, as ``numpy.load`` leaves it). Whatever stops
    the walk early (a bad signature, type or length, the end of the stream)
    returns the bytes read so far, which the decoder then rejects with the
    precise error and offset. ``prefix`` holds bytes already taken from the
    stream (format detection).

    Raises
    ------
    LimitExceededError
        If the file would exceed ``limit`` bytes (§8).
    """
    from mpz.container import is_chunk_type
    out = bytearray(prefix)

    def take(n: int) -> bool:
        if len(out) + n > limit:
            raise LimitExceededError(f"input longer than {limit} bytes, the most this "
                                     "decoder reads", offset=len(out), section="§8")
        got = _read_exact(fh, n)
        out.extend(got)
        return len(got) == n

    if len(out) < 8 and not take(8 - len(out)):
        return bytes(out)
    if bytes(out[:8]) != SIGNATURE:
        return bytes(out)
    pos = 8
    while True:
        if len(out) < pos + 8 and not take(pos + 8 - len(out)):
            return bytes(out)
        ctype = bytes(out[pos:pos + 4])
        if not is_chunk_type(ctype):
            # the 4 bytes a frame needs at least, as below: with 8 the decoder said
            # "truncated chunk frame", where the same bytes in a file are "chunk type ...
            # is not four ASCII letters" (a QA run of the CLI plumbing: mpzinfo - < x)
            take(4)
            return bytes(out)
        length = int.from_bytes(out[pos + 4:pos + 8], "little")
        if length > MAX_CHUNK_LENGTH:     # §3.2: rejected before the payload is read; the
            take(4)                       # 4 bytes a frame needs at least (n - pos >= 12)
            return bytes(out)
        need = pos + 12 + length - len(out)
        if need > 0 and not take(need):
            return bytes(out)
        pos += 12 + length
        if ctype == b"MEND":
            if trailing and len(out) == pos:
                take(1)                   # one byte past MEND: "bytes after MEND" if any
            return bytes(out)


def check_max_samples(max_samples: object) -> int:
    """``max_samples`` as an int in 1 .. MAX_SAMPLES, or TypeError / ValueError naming it.
    It is a lower limit only (spec §8: a decoder MUST enforce the table's limits and MAY
    have lower ones); a larger value let files past MAX_SAMPLES through the limit check."""
    if isinstance(max_samples, (bool, np.bool_)) or not isinstance(
            max_samples, (int, np.integer)):
        raise TypeError(f"max_samples must be an integer, got {type(max_samples).__name__} "
                        f"{max_samples!r}")
    if not 1 <= max_samples <= MAX_SAMPLES:
        raise ValueError(f"max_samples must be 1 .. {MAX_SAMPLES} (2^26, spec §8's "
                         f"MAX_SAMPLES: a decoder may lower it, not raise it), got "
                         f"{max_samples}")
    return int(max_samples)


def read_source(source: Source, *, limit: int = MAX_INPUT_BYTES) -> tuple[bytes, str | None]:
    """The bytes of an MPZ ``source`` and its file name (None for bytes and streams).

    A path is read whole if it names a regular file of at most ``limit``
    bytes; a file object is read with :func:`read_stream_bytes`.

    Raises
    ------
    FormatError
        See :func:`open_regular`; ``TypeError`` for anything else.
    LimitExceededError
        A file longer than ``limit``.
    """
    if isinstance(source, bytes):
        return source, None
    if isinstance(source, (bytearray, memoryview)):
        return bytes(source), None
    if isinstance(source, (str, os.PathLike)):
        p = os.fspath(source)
        if not isinstance(p, str):
            raise TypeError("a path must be str or os.PathLike[str]")
        if "\0" in p:         # a file's bytes decoded to str: os.open's "embedded null byte"
            raise TypeError("a str is a path, and this one holds a NUL: pass the MPZ data as "
                            "bytes (open the file in 'rb'), or its path")
        with open_regular(p) as fh:
            size = os.fstat(fh.fileno()).st_size
            if size > limit:
                raise LimitExceededError(f"file of {size} bytes, longer than {limit}, the "
                                         "most this decoder reads", section="§8", path=p)
            try:
                return fh.read(), p
            except OSError as exc:
                raise FormatError(f"cannot read: {exc.strerror or exc}", path=p) from None
    if isinstance(source, io.TextIOBase):      # it failed inside with a join TypeError
        raise TypeError("a text file object: open the MPZ file in binary mode ('rb')")
    if isinstance(source, np.ndarray):          # bytes-like by the buffer protocol
        if source.dtype != np.uint8:
            raise TypeError(f"a numpy array of MPZ bytes must be uint8, got {source.dtype}")
        return source.tobytes(), None
    if hasattr(source, "read"):
        # the caller's mistakes, as a text file object is: they came as io's own
        # ValueError and UnsupportedOperation (an API user's QA run of stop 72)
        if getattr(source, "closed", False) is True:
            raise TypeError("a closed file object: pass it open, in binary mode ('rb')")
        mode = getattr(source, "mode", None)    # a file's: readable() is False in many a
        if isinstance(mode, str) and not any(c in mode for c in "r+"):  # raw stream that reads
            raise TypeError(f"a file object open for writing (mode {mode!r}), not reading: "
                            "open the MPZ file in 'rb'")
        name = getattr(source, "name", None)
        data = read_stream_bytes(source, limit=limit, trailing=False)
        return data, name if isinstance(name, str) else None
    try:                     # any other bytes-like object (array.array('B'), a QA run of
        view = memoryview(cast(Any, source))     # stop 50: "expected a path ..., got array")
    except TypeError:
        view = None
    if view is not None:
        if view.itemsize != 1:
            raise TypeError(f"{type(source).__name__}: the MPZ bytes must be single bytes "
                            f"(itemsize 1), got itemsize {view.itemsize}")
        return view.tobytes(), None
    raise TypeError(f"expected a path, bytes or a binary file object, got "
                    f"{type(source).__name__}")


def _same_file(a: str, b: str) -> bool:
    """True if ``a`` and ``b`` name one file (hard links, symbolic links, ``..`` and all)."""
    try:
        if os.path.exists(a) and os.path.exists(b) and os.path.samefile(a, b):
            return True
    except OSError:
        pass
    return os.path.realpath(a) == os.path.realpath(b)


def _use_force() -> str:
    """How an "exists" message tells its reader to replace the file."""
    return spelled("use --force", "pass force=True")


def check_output(path: str | os.PathLike[str], *, force: bool = False,
                 source: str | os.PathLike[str] | None = None) -> None:
    """Refuse an output path that must not or cannot be written, before any work is done.

    :func:`atomic_output` runs this check too; tools call it first so that a
    bad ``-o`` is reported before a long encode or decode, not after.

    Raises
    ------
    EncoderError
        One line naming the path, when the path is the ``source`` file (even
        with ``force``); is a folder or ends in a separator; lies in a folder
        that does not exist; exists, or is a symbolic link to a missing file,
        and ``force`` is false; exists but is not a regular file (the null
        device, :data:`os.devnull`, excepted: :func:`atomic_output`), or is marked
        immutable or append-only (Linux's ``chattr +i``, ``+a``); names an open file
        descriptor (``/dev/stdout``, ``/dev/fd/3``; even with ``force``); or lies in a
        folder that is not writable.
    TypeError
        For a ``path`` that is not a str or an os.PathLike of str (bytes raised "Can't mix
        strings and bytes in path components", a QA run of stop 50).
    """
    target = os.fspath(path)
    if not isinstance(target, str):
        raise TypeError(f"the output path must be a str or an os.PathLike of str, got "
                        f"{type(path).__name__}")
    if source is not None and _same_file(target, os.fspath(source)):
        raise EncoderError(f"refusing to overwrite the input file {os.fspath(source)}")
    if not os.path.basename(target):
        raise EncoderError(f"{target} names a folder; give a file name")
    if os.path.isdir(target):
        raise EncoderError(f"{target} is a folder; give a file name")
    folder = os.path.dirname(target)
    if not os.path.isdir(folder or "."):
        what = "is not a folder" if os.path.lexists(folder) else "does not exist"
        raise EncoderError(f"cannot write {target}: {folder} {what}")
    if os.path.islink(target) and not os.path.exists(target):
        if not force:
            raise EncoderError(f"{target} is a symbolic link to a missing file; "
                               f"{_use_force()} to replace it")
        return
    if is_null_device(target):
        return                          # written and discarded (atomic_output)
    if _names_a_descriptor(target):
        # a rename would replace the link (/dev/stdout itself, for root) and not write
        # through it: `-f -o /dev/stdout > out.mpz` left out.mpz empty and exited 0
        raise EncoderError(f"{target} names an open file descriptor, which an atomic write "
                           "(a new file renamed over the name) cannot write through; "
                           + spelled("write to standard output with -o -",
                                     "write the bytes to the open file yourself"))
    if os.path.lexists(target):
        # a FIFO, device or socket first: --force would not help, so it is not offered
        if not stat.S_ISREG(os.stat(target).st_mode):
            raise EncoderError(f"{target} is not a regular file; refusing to replace it")
        if not force:
            raise EncoderError(f"{target} exists; {_use_force()} to replace it")
        if _immutable(target):
            raise EncoderError(f"cannot write {target}: it is marked immutable or append-"
                               "only (chattr +i or +a); the rename that replaces it would fail")
        if _sticky_refuses(folder or ".", target):
            raise EncoderError(f"cannot write {target}: it belongs to another user in a "
                               f"folder with the sticky bit ({folder or '.'}), where only its "
                               "owner may replace it; the rename would fail after the work")
    if not os.access(folder or ".", os.W_OK | os.X_OK):
        # read-only, or (for root, whom permissions do not stop) marked immutable: the
        # temporary file beside the output could not be made, after all the work; a folder
        # that is writable but cannot be entered (no x) is said as such (QA, stop 47)
        why = ("cannot be entered (no execute permission)"
               if os.access(folder or ".", os.W_OK) else "is not writable")
        raise EncoderError(f"cannot write {target}: {folder or '.'} {why}")


#: the folders whose entries are a process's open descriptors (/dev/fd, /dev/stdout lead there)
_DESCRIPTOR_FOLDER = re.compile(r"/proc/(self|thread-self|\d+)(/task/\d+)?/fd")


def _names_a_descriptor(target: str) -> bool:
    """Whether ``target``, or a symbolic link on its way, is an entry of a process's
    descriptor folder (``/dev/stdout``, ``/dev/fd/3``, ``/proc/self/fd/1``): a name an
    atomic write cannot replace without replacing the link itself (a QA run of the CLI
    plumbing)."""
    p = os.path.abspath(target)
    for _ in range(40):
        if _DESCRIPTOR_FOLDER.fullmatch(os.path.realpath(os.path.dirname(p))):
            return True
        if not os.path.islink(p):
            return False
        p = os.path.join(os.path.dirname(p), os.readlink(p))
    return False


def _sticky_refuses(folder: str, target: str) -> bool:
    """Whether the rename that replaces ``target`` would be refused by the sticky bit of
    ``folder`` (/tmp and shared folders): there only the file's owner, the folder's owner
    and root may replace a file (a QA run of stop 47: found after an 11 s encode)."""
    euid = os.geteuid() if hasattr(os, "geteuid") else 0
    if euid == 0:
        return False
    fst = os.stat(folder)
    return bool(fst.st_mode & stat.S_ISVTX) and euid not in (fst.st_uid,
                                                           os.stat(target).st_uid)


def _immutable(path: str) -> bool:
    """True if ``path`` is a regular file with Linux's immutable or append-only flag (no
    rename may replace it, not even root's); False where that cannot be asked."""
    if not os.path.isfile(path):        # a device is never opened: opening may act on it
        return False
    try:
        import fcntl
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except (ImportError, OSError):
        return False
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return False
        buf = fcntl.ioctl(fd, 0x80086601, b"\0" * 8)          # FS_IOC_GETFLAGS
        flags = int.from_bytes(buf[:4], sys.byteorder)
        return bool(flags & (0x10 | 0x20))                    # FS_IMMUTABLE_FL, FS_APPEND_FL
    except OSError:                 # a file system without these flags, or not Linux
        return False
    finally:
        os.close(fd)


#: the packages whose Python code a signal's exception must not interrupt
#: (:func:`in_compiler`)
COMPILER_PACKAGES = ("numba", "llvmlite")


def _compiler_dirs() -> tuple[str, ...]:
    return tuple(os.path.dirname(m.__file__) + os.sep for name in COMPILER_PACKAGES
                 if (m := sys.modules.get(name)) is not None and m.__file__)


def in_compiler(frame: FrameType | None) -> bool:
    """Whether ``frame``, or a frame that called it, runs the Python code of numba or
    llvmlite (:data:`COMPILER_PACKAGES`): a compiled kernel's callbacks as it makes the
    objects it returns (``_numba_unpickle``), its loading from the cache, llvmlite's
    finalizers. An exception a signal handler raises there does not unwind cleanly: a
    kernel returned a tuple with a missing item, and unpacking it ended the process
    (SIGSEGV: ``mpz search``, 3 of 65 interrupted runs; ``mpz encode``, 1 of 150), a
    kernel half loaded crashed the interpreter's exit, and llvmlite's ``__del__`` dropped
    the exception (a QA run of stop 57)."""
    dirs = _compiler_dirs()
    while dirs and frame is not None:
        if frame.f_code.co_filename.startswith(dirs):
            return True
        frame = frame.f_back
    return False


#: how often a thread looks whether the main thread has left numba's and llvmlite's code,
#: while a signal waits (:class:`SignalsPutOff`)
SIGNAL_POLL_SECONDS = 0.002


class SignalsPutOff:
    """Signals that a handler in the main thread puts off (:meth:`later`) while that
    thread runs numba's or llvmlite's code (:func:`in_compiler`). A thread of
    :mod:`_thread` (a handler may run where :mod:`threading`'s locks are held) looks every
    :data:`SIGNAL_POLL_SECONDS` at the main thread's frames, and once it has left that
    code hands each signal back to its handler (``_thread.interrupt_main``), which then
    decides again. A second signal of a kind already waiting is not put off: a second
    Ctrl-C stops a command even in a long compile (a review of stop 57: a cold start's
    compile made the first wait 2-20 s).

    :meth:`close` (in the main thread, as the block that installed the handler ends)
    stops the handing back and returns the signals still waiting but SIGINT (dropped:
    the work it would have stopped is done), for the caller to send again once it has put
    the handlers back."""

    def __init__(self) -> None:
        self._lock = _thread.allocate_lock()
        self._open = True
        self._waiting: set[signal.Signals] = set()
        self._polling = False
        self._main = threading.main_thread().ident or 0

    def later(self, signum: int) -> bool:
        """Put ``signum`` off (True), or, when one of its kind waits already, do not
        (False: the handler acts now). Called by a handler, in the main thread; no lock,
        as a handler may run while this thread holds one."""
        sig = signal.Signals(signum)
        if sig in self._waiting:
            self._waiting.discard(sig)
            return False
        self._waiting.add(sig)
        if not self._polling:
            self._polling = True
            try:
                _thread.start_new_thread(self._poll, ())
            except RuntimeError:          # no thread to be had: the caller says so
                self._polling = False
                self._waiting.discard(sig)
                raise
        return True

    def _poll(self) -> None:
        while True:
            time.sleep(SIGNAL_POLL_SECONDS)
            with self._lock:
                if not self._open:
                    return
                if in_compiler(sys._current_frames().get(self._main)):
                    continue
                self._polling = False
                waiting, self._waiting = self._waiting, set()
                for sig in waiting:
                    _thread.interrupt_main(sig)
                return

    def close(self) -> set[signal.Signals]:
        """Stop handing signals back; the signals still waiting, SIGINT left out."""
        self._open = False            # first: no signal is handed back from now on
        with self._lock:              # and one being handed back has been
            pass
        waiting, self._waiting = self._waiting, set()
        return waiting - {signal.SIGINT}


#: SIGHUP, where the platform has it (a terminal closed): a temporary output is removed on
#: it as on SIGTERM (a QA run of stop 57 left a hidden .part file after one)
_SIGHUP = getattr(signal, "SIGHUP", None)


@contextlib.contextmanager
def signals_exit(*signums: int | None) -> Iterator[None]:
    """While the block runs, each of ``signums`` (SIGTERM, SIGHUP; None is skipped, for a
    signal the platform lacks) raises ``SystemExit(128 + signum)``, so that cleanup code
    runs: a temporary output is removed, the commands a runner started are killed.
    Not while the main thread runs numba's or llvmlite's code (:func:`in_compiler`): the
    signal is then put off until it does not (:class:`SignalsPutOff`).

    Only for a signal that still has its default action, and only in the main thread
    (the only one Python lets set handlers); the old handlers come back afterwards.
    SIGINT needs nothing: it already raises KeyboardInterrupt.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    put_off = SignalsPutOff()

    def terminate(signum: int, frame: FrameType | None) -> None:
        if in_compiler(frame) and put_off.later(signum):
            return
        raise SystemExit(128 + signum)

    old = {n: signal.signal(n, terminate) for n in signums
           if n is not None and signal.getsignal(n) is signal.SIG_DFL}
    try:
        yield
    finally:
        # the handlers back first, then a signal still put off to the action it has now
        # (sent with this block's handler in place, it raised SystemExit here and the
        # handler stayed for good: a review of stop 57)
        late = put_off.close()
        try:
            for n, handler in old.items():
                signal.signal(n, handler)
        finally:
            for sig in late:
                os.kill(os.getpid(), sig)


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """Hold SIGINT, SIGTERM and SIGHUP back for a few statements.

    Between creating the temporary file and recording its name a signal must
    not strike, or nobody would know which file to remove. Blocking the signals
    in this thread's mask is not enough: the kernel then delivers them to another
    thread (a decoder's pool), and Python still runs the handler in the main
    thread at its next instruction. So in the main thread the Python handlers
    are also replaced for the while by ones that only note the signal; when the
    region ends, the old handlers are back and each noted signal is raised again
    for them. (A .part file was left behind once in a loaded CI run of
    test_sigterm_while_decoding_leaves_no_temporary_file; and once more with SIGHUP,
    which :func:`atomic_output` turns into an exit as it does SIGTERM, but which was not
    held here: a CI run of stop 66.)
    """
    held = tuple(s for s in (signal.SIGINT, signal.SIGTERM, _SIGHUP) if s is not None)
    noted: list[int] = []
    old_handlers: dict[int, Any] = {}
    if threading.current_thread() is threading.main_thread():
        for sig in held:
            if signal.getsignal(sig) is not None:        # None: a handler set outside Python
                old_handlers[sig] = signal.signal(sig, lambda n, _frame: noted.append(n))
    old_mask = (signal.pthread_sigmask(signal.SIG_BLOCK, set(held))
                if hasattr(signal, "pthread_sigmask") else None)
    try:
        yield
    finally:
        # the handlers first, then the mask (a signal pending in this thread then goes to
        # its own handler); ExitStack runs every step even if a handler raises in between
        with contextlib.ExitStack() as restore:
            if old_mask is not None:
                restore.callback(signal.pthread_sigmask, signal.SIG_SETMASK, old_mask)
            for held_sig, handler in old_handlers.items():
                restore.callback(signal.signal, held_sig, handler)
        for signum in dict.fromkeys(noted):
            signal.raise_signal(signum)                # to the handler it was meant for


def folder_problem(exc: OSError) -> str:
    """Why ``os.makedirs`` could not make a folder, in words: its "File exists" and "Not a
    directory" name neither the file in the way nor that it is a file."""
    if isinstance(exc, FileExistsError):
        return "a file (not a folder) is in its place"
    if isinstance(exc, NotADirectoryError):
        return "a file (not a folder) is in its path"
    return exc.strerror or str(exc)


def is_null_device(path: str) -> bool:
    """``path`` is the null device (:data:`os.devnull`, by any name that leads to it): an
    output written in full and then discarded, to time or check a writer (``-o
    /dev/null``), never replaced by a rename."""
    try:
        return os.path.samefile(path, os.devnull)
    except (OSError, ValueError):
        return False


def _create_temp(folder: str, name: str, suffix: str) -> str:
    """A new hidden file beside the output, created with mode 0o666 minus the umask.

    ``os.open`` applies the process umask (and a folder's default ACL) itself,
    so the umask is never read or changed (``os.umask`` would race with threads).
    """
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0)
    for _ in range(100):
        tmp = os.path.join(folder, f".{name[:120]}.{secrets.token_hex(4)}.part{suffix}")
        try:
            fd = os.open(tmp, flags, 0o666)
        except FileExistsError:
            continue
        os.close(fd)
        return tmp
    raise FileExistsError(errno.EEXIST, "no free temporary file name", folder)


def _fsync(path: str) -> None:
    """Flush a file's data, or a folder's entries, to the disk."""
    flags = os.O_RDONLY
    if os.path.isdir(path):
        flags |= getattr(os, "O_DIRECTORY", 0)
    fd = os.open(path, flags)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


#: errors of os.link on file systems without hard links (FAT, some network mounts)
_NO_HARD_LINKS = {errno.EPERM, errno.EOPNOTSUPP, errno.ENOTSUP, errno.ENOSYS, errno.EMLINK}


def _commit(tmp: str, target: str, *, force: bool) -> None:
    """Give ``tmp`` the name ``target``: replacing it if ``force``, else exclusively."""
    if force:
        if os.path.isfile(target):  # a replaced file keeps its mode
            os.chmod(tmp, stat.S_IMODE(os.stat(target).st_mode))
        os.replace(tmp, target)
        return
    exists = EncoderError(f"{target} exists; {_use_force()} to replace it")
    try:
        os.link(tmp, target)  # fails if the name exists, atomically: one writer wins
    except FileExistsError:
        raise exists from None
    except OSError as exc:
        if exc.errno not in _NO_HARD_LINKS:
            raise
        try:  # claim the name exclusively, then move the finished file onto it
            os.close(os.open(target, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
        except FileExistsError:
            raise exists from None
        os.replace(tmp, target)
        return
    os.unlink(tmp)


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike[str], *, force: bool = False,
                  source: str | os.PathLike[str] | None = None,
                  suffix: str | None = None) -> Iterator[str]:
    """Write an output file atomically: yields a temporary path to write, then names it ``path``.

    The one way every MPZ writer creates a file (:func:`write_atomic` is the
    bytes form). The temporary file is hidden, beside ``path`` (same file
    system), and ends in ``suffix`` (default: the suffix of ``path``) for
    writers that choose the format or append an extension from the name.
    Nobody ever sees a partial file at ``path``. On success the data and then
    the folder are flushed to disk (fsync).

    * ``path`` is checked first with :func:`check_output`.
    * The null device (``os.devnull``) takes a whole file that is then dropped: the
      temporary path is in the system's temporary folder and is removed afterwards.
    * Without ``force`` the name is created exclusively: of two writers of
      the same new file exactly one succeeds; the other gets
      :class:`~mpz.errors.EncoderError` "exists; pass force=True" ("use --force" in the
      commands).
    * With ``force`` an existing file is replaced and keeps its mode; a new
      file gets mode 0o666 minus the umask.
    * On any exception, and on SIGTERM or SIGHUP (a terminal closed; see
      :func:`signals_exit`), the temporary file is removed. An ``OSError`` becomes ``EncoderError``
      naming ``path`` (never the temporary name).

    Examples
    --------
    >>> import os, tempfile
    >>> d = tempfile.mkdtemp()
    >>> with atomic_output(os.path.join(d, "a.txt")) as tmp:
    ...     with open(tmp, "w") as fh:
    ...         _ = fh.write("hello")
    >>> os.listdir(d)
    ['a.txt']
    """
    target = os.fspath(path)
    check_output(target, force=force, source=source)
    name = os.path.basename(target)
    ext = os.path.splitext(name)[1] if suffix is None else suffix
    if is_null_device(target):
        # the writer writes a whole file, in the temporary folder; then it is dropped
        with signals_exit(signal.SIGTERM, _SIGHUP), \
                tempfile.TemporaryDirectory(prefix="mpz-null-") as scratch:
            try:
                yield os.path.join(scratch, f"null{ext}")
            except OSError as exc:
                raise EncoderError(f"cannot write {target}: {exc.strerror or exc}") from exc
        return
    folder = os.path.dirname(os.path.abspath(target))
    with signals_exit(signal.SIGTERM, _SIGHUP):
        tmp: str | None = None
        try:
            with _signals_held():
                tmp = _create_temp(folder, name, ext)
            yield tmp
            _fsync(tmp)
            _commit(tmp, target, force=force)
            tmp = None
            with contextlib.suppress(OSError):  # not every platform can fsync a folder
                _fsync(folder)
        except OSError as exc:
            raise EncoderError(f"cannot write {target}: {exc.strerror or exc}") from exc
        finally:
            if tmp is not None:
                with _signals_held(), contextlib.suppress(OSError):
                    os.unlink(tmp)


def write_atomic(path: str | os.PathLike[str], data: bytes, *,
                 source: str | os.PathLike[str] | None = None, force: bool = True) -> None:
    """Write ``data`` to ``path`` through :func:`atomic_output`.

    No partial file is ever left at ``path``; ``path`` must not be the
    ``source`` file (the encoder never overwrites its input). ``force=True``
    (the default, as in earlier versions) replaces an existing file;
    ``force=False`` creates ``path`` exclusively.

    Raises
    ------
    EncoderError
        See :func:`atomic_output`.
    """
    if not isinstance(force, bool):      # "no" replaced the file (a QA run of stop 50)
        raise TypeError(f"force must be True or False, got {force!r}")
    with atomic_output(path, force=force, source=source) as tmp, open(tmp, "wb") as fh:
        fh.write(data)


def decode(source: Source, *, max_samples: int = MAX_SAMPLES,
           markers_only: bool = False) -> Motion:
    """Decode an MPZ file into a :class:`~mpz.Motion`, as numpy and soundfile read theirs.

    Parameters
    ----------
    source : str, os.PathLike, bytes-like or binary file object
        A path to a regular file; the file's bytes; or a binary file object,
        read from its current position to the end of the MPZ file (not
        beyond: other data may follow in the stream).
    max_samples : int, optional
        A lower F × M limit for a memory budget (spec §8), 1 .. MAX_SAMPLES; files
        above it are rejected with :class:`~mpz.errors.LimitExceededError`. Below MAX_SAMPLES it
        also lowers MAX_ANALOG_SAMPLES to 4 × max_samples and MAX_CHANNEL_SAMPLES to
        max_samples.
    markers_only : bool, default False
        Decode as an MPZ 1.0 decoder does (spec §2.1): the marker layer alone, with the
        names, rate, units and ``meta``; the 1.1 chunks (a C3D archive, a skeleton and
        its channels, the coded summary) are skipped after their frame and CRC are
        checked, not decoded or checked further (§2.3). The markers are the same. On a
        C3D file with analog data it is 12-17 times faster (ezc3d_Vicon: 2.0-2.9 ms
        against 35 ms, the machine idle or loaded, docs/partial-decode.md; a data loader
        that trains on markers: an ML pipeline's QA run of stop 51); ``extras`` and
        ``angles`` are then empty.

    Returns
    -------
    Motion
        Positions in the file's units (``motion.units``), gaps restored: the marker
        layer (spec §6), within the file's declared bound. A file with a skeleton chunk
        (from BVH or AMC, spec §4.14) also gives ``motion.angles`` and
        ``extras["skeleton"]``; its marker layer is a preview of the joints, coarser than
        the channels when no bound was given (Appendix C), and
        :func:`mpz.skeleton.with_joint_positions` gives the joint positions that the
        channels give, as ``mpz decode`` and ``mpz.io.write`` to BVH or AMC do.

    Raises
    ------
    MPZError
        If the file is invalid (with offset, chunk and §), missing, not a
        regular file, or beyond a limit. ``MemoryError`` is not caught: running
        out of memory says nothing about the file (spec §8).
    TypeError
        If ``source`` is none of the above (a closed file object, or one open for
        writing, included), or ``max_samples`` is not an integer.
    ValueError
        If ``max_samples`` is outside 1 .. MAX_SAMPLES.

    Examples
    --------
    >>> import io, mpz
    >>> from mpz.synth import generate
    >>> data = mpz.encode(generate("walk", frames=24), max_error=1.0)
    >>> mpz.decode(data).n_frames, mpz.decode(io.BytesIO(data)).n_frames
    (24, 24)
    """
    from mpz.decoder import decode as decode_bytes
    max_samples = check_max_samples(max_samples)
    if not isinstance(markers_only, (bool, np.bool_)):
        raise TypeError(f"markers_only must be True or False, got {markers_only!r}")
    data, name = read_source(source)
    try:
        return decode_bytes(data, max_samples=max_samples, minor=0 if markers_only
                            else VERSION_MINOR)
    except MPZError as exc:
        if name is not None:
            exc.path = name
        raise


def read_mpz(path: Source, *, max_samples: int = MAX_SAMPLES) -> Motion:
    """Decode the MPZ file at ``path`` into a Motion (the same as :func:`decode`, whose
    ``max_samples`` it takes)."""
    return decode(path, max_samples=max_samples)


@dataclass(frozen=True)
class FileInfo:
    """What an MPZ file says about itself, read without decoding the motion (:func:`info`).

    ``rate`` is in Hz, ``error_bound`` (None: no bound declared) in ``units``: MHDR's,
    the bound on the marker layer (a skeletal file's joint positions computed from its
    channels have the skeleton chunk's own, its ``position_bound``, §4.14, which
    ``mpz show`` and ``mpzinfo`` print);
    ``chunk_bytes`` maps each chunk type to its bytes in the file (frame
    included); ``summary_levels`` lists the k of the smry or smrc levels, in stored order (empty: no
    summary; read them with :func:`read_summary`). ``skeleton`` (None without a bvhs or
    asfs chunk) gives how accurate a skeletal file's channels and joints are, as
    ``mpzinfo --json``'s ``skeleton``: ``chunk``, ``bytes``, ``joints`` (BVH End Sites
    included), ``end_sites``, ``channels``, ``angle_bound`` (degrees) and
    ``translation_bound`` (skeleton units), the largest error the channel steps allow,
    and ``position_bound``, the declared bound on the joint positions computed from them
    (marker units; 0: none declared).
    """

    #: the bitstream version MHDR declares, "major.minor" (spec §2.1), e.g. "1.1"
    version: str
    #: F, the frame count (MHDR)
    frames: int
    #: M, the marker count (MHDR; for a skeletal file, its joint positions)
    markers: int
    rate: float
    units: str
    #: the marker names in marker order (MNAM, §4.2)
    names: tuple[str, ...]
    #: the body-part hierarchy's node count (HIER, §4.3)
    nodes: int
    error_bound: float | None
    #: the file's length in bytes
    size: int
    summary_levels: tuple[int, ...] = ()
    #: the file's metadata entries (the meta chunk, §4.11), as stored
    metadata: Mapping[str, str] = field(default_factory=dict)
    chunk_bytes: Mapping[str, int] = field(default_factory=dict)
    #: the skeleton chunk's figures (see above); None without one
    skeleton: Mapping[str, Any] | None = None

    def __post_init__(self) -> None:
        # read-only and hashable, as a frozen dataclass promises (API review F10)
        from mpz.encoder import FrozenMapping
        object.__setattr__(self, "names", tuple(self.names))
        object.__setattr__(self, "summary_levels", tuple(self.summary_levels))
        object.__setattr__(self, "metadata", FrozenMapping(self.metadata))
        object.__setattr__(self, "chunk_bytes", FrozenMapping(self.chunk_bytes))
        if self.skeleton is not None:
            object.__setattr__(self, "skeleton", FrozenMapping(self.skeleton))

    @property
    def duration(self) -> float:
        """Seconds from the first frame to the end of the last one (frames / rate)."""
        return self.frames / self.rate if self.rate else float("nan")


def _stream(source: Source) -> tuple[Any, bytes]:
    """:func:`mpz.decoder.read_stream` of an MPZ ``source`` (every chunk's frame, CRC and §
    checks; no payload decoded) and its bytes; an error names the file of a path."""
    from mpz.decoder import read_stream
    data, name = read_source(source)
    try:
        return read_stream(data), data
    except MPZError as exc:
        if name is not None:
            exc.path = name
        raise


def info(source: Source) -> FileInfo:
    """Names, rate, frame count, bound and summary levels of an MPZ file, without decoding.

    Every chunk's frame, CRC and § checks are run (spec §3, §4). The marker
    layer's range-coded payloads are not decoded, so for a 1.0 file this is
    fast and its memory is that of the file. The 1.1 chunks' rules need their
    payloads decoded (a C3D archive's channels, a skeleton's, an smrc
    summary: §4.13-§4.15), so a file with them costs what decoding those
    costs (spec §8's terms for them: a QA run of stop 48 measured 1.2 GiB and
    7 s for a valid file of 20,000 frames with 2.56 x 10^8 analog words). A
    file ``info`` accepts may still fail to decode; ``mpzinfo`` runs both.

    Parameters
    ----------
    source : str, os.PathLike, bytes-like or binary file object
        As for :func:`decode`.

    Raises
    ------
    MPZError
        If the structure is invalid.
    TypeError
        If ``source`` is none of those :func:`decode` takes.

    Examples
    --------
    >>> import mpz
    >>> from mpz.synth import generate
    >>> fi = mpz.info(mpz.encode(generate("walk", frames=24), max_error=1.0))
    >>> fi.frames, fi.markers, fi.rate, fi.units, fi.error_bound
    (24, 41, 120.0, 'mm', 1.0)
    """
    from mpz.container import chunk_sizes
    from mpz.format import ErrorMetric, Units, unit_name
    s, data = _stream(source)
    h = s.header
    units = unit_name(h.units) if h.units in set(Units) else ""
    meta = s.meta
    levels: tuple[int, ...] = ()
    if s.summary is not None:
        levels = tuple(int(lv.k) for lv in s.summary.record.levels)
    from mpz.skeleton import SKELETON_TYPES, record_report
    sizes = chunk_sizes(data)
    # how accurate a skeletal file's channels and joints are: mpz show and mpzinfo gave
    # it, the API did not (a QA run of an animation pipeline, stop 61); from the record
    # read_stream has checked (§4.13: one skeleton chunk at most)
    skeleton = next((record_report(s.extras[t][0], sizes[t] - 12, end_sites=True)
                     for t in SKELETON_TYPES if t in s.extras), None)
    return FileInfo(version=f"{h.version_major}.{h.version_minor}", frames=h.frame_count,
                    markers=h.marker_count, rate=h.rate, units=units, names=tuple(s.names),
                    nodes=h.node_count,
                    error_bound=(h.error_bound if h.error_metric != ErrorMetric.NONE else None),
                    size=len(data), summary_levels=levels, metadata=dict(meta),
                    chunk_bytes=sizes, skeleton=skeleton)


def check_mpz_name(path: str | os.PathLike[str]) -> None:
    """Refuse to name an MPZ file as a motion format that :mod:`mpz.io` reads, or as an
    ASF: every tool, mpz's own included, would take it for one. ``mpz encode x.trc -o
    x.c3d`` wrote MPZ bytes into x.c3d without a word, for a user who meant to convert
    (``mpz decode``). Any other name is the caller's choice.

    Raises
    ------
    EncoderError
        ``path`` ends in .c3d, .trc, .bvh, .amc, .asf, .npy or .csv (any case).
    """
    from mpz.io import READERS
    from mpz.io._common import ext_of
    ext = ext_of(path)
    if ext in READERS or ext == ".asf":
        kind = ext[1:].upper()
        # an ASF is written beside its AMC: the hint named a write that refuses .asf (an
        # API user's QA run of stop 72)
        target = os.fspath(path)[:-len(ext)] + ".amc" if ext == ".asf" else os.fspath(path)
        how = spelled(f"mpz decode FILE.mpz -o {target}",
                      f"mpz.io.write(mpz.decode(data), {target!r})") + (
            ", which writes the ASF beside the AMC" if ext == ".asf" else "")
        raise EncoderError(f"{os.fspath(path)}: an MPZ file named {ext} would be read as "
                           f"{kind}; name it .mpz (to write {kind}, decode an .mpz: {how})")


def write_mpz(motion: Motion, path: str | os.PathLike[str], *,
              source: str | os.PathLike[str] | None = None,
              **options: Unpack[EncodeKeywords]) -> EncodeReport:
    """Encode ``motion`` with ``options`` (the keywords of :func:`mpz.encode`, typed as
    :class:`mpz.encoder.EncodeKeywords`) and write it to ``path`` atomically, replacing a
    file there; returns the EncodeReport. ``source``: the input file, which ``path`` must
    not be; ``path`` must not end in a motion format's extension (:func:`check_mpz_name`)."""
    from mpz.encoder import encode_motion, keyword_options
    opts = keyword_options(options)
    check_mpz_name(path)
    check_output(path, force=True, source=source)  # a bad path fails before the encode
    data, report = encode_motion(motion, opts)
    write_atomic(path, data, source=source)
    return report


def _read_only(a: np.ndarray) -> np.ndarray:
    """A view of ``a`` that cannot be written through (``a`` itself is left as it is)."""
    view = np.asarray(a).view()
    view.flags.writeable = False
    return view


class SummaryLevel:
    """One level of the summary chunk, dequantised: ``k`` segments starting at frames
    ``starts`` [k], their means ``means`` [k, dims], the level's ``wssse`` and the
    quantisation ``step`` of the means. The arrays are read-only views: what the file
    holds (written into, they changed every later :meth:`Summary.level` and
    :meth:`Summary.preview`: an API QA run of stop 74); copy them to edit."""

    def __init__(self, k: int, starts: np.ndarray, means: np.ndarray, wssse: float,
                 step: float) -> None:
        self.k, self.wssse, self.step = k, wssse, step
        self.starts, self.means = _read_only(starts), _read_only(means)

    def __repr__(self) -> str:
        return f"SummaryLevel(k={self.k}, wssse={self.wssse:.6g})"


class Summary:
    """The optimal-partition summary of a file (its smry or smrc chunk, spec §4.10, §4.15),
    read without decoding motion (:func:`read_summary`): its ``space`` ("positions" or
    "angles"), ``dims`` per frame (0 for an angle summary without means), ``levels`` (one
    :class:`SummaryLevel` per stored level, in stored order: the spec lets them come in any
    order and repeat a k; the reference encoder writes each k once, increasing), and the
    file's ``n_frames``, ``rate``, marker ``names`` and ``units``."""

    def __init__(self, space: str, dims: int, levels: list[SummaryLevel], n_frames: int,
                 rate: float, names: list[str], units: str) -> None:
        self.space, self.dims, self.levels = space, dims, levels
        self.n_frames, self.rate, self.names, self.units = n_frames, rate, names, units

    def level(self, k: int) -> SummaryLevel:
        """The level of ``k`` segments, the first stored when two have that k (spec §4.10
        allows it; :attr:`levels` holds every one, in stored order); KeyError naming the
        levels there are, TypeError for a ``k`` that is not an int (``6.0``, ``'6'``)."""
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)):   # '2' (QA, stop 50)
            raise TypeError(f"k must be an int (a number of segments), got {k!r}")
        for lv in self.levels:
            if lv.k == k:
                return lv
        raise KeyError(f"no summary level of {k} segments; the file has "
                       f"{', '.join(str(lv.k) for lv in self.levels)}")

    def preview(self, k: int | None = None, mode: str = "constant") -> Motion:
        """A preview Motion rebuilt from the summary alone (positions relative to the
        per-frame centroid, the root :func:`mpz.fisher.motion_series` takes by default),
        from the level of ``k`` segments (default: the finest); ``mode`` "constant" (each
        frame its segment's mean) or "linear". KeyError (as :meth:`level`) for a ``k`` the
        file does not hold, ValueError for another mode, FormatError for a summary of
        joint angles (space 1). Every sample of the preview is valid: a summary holds no
        gap mask (:func:`mpz.fisher.motion_series` filled the gaps, and a marker that was
        a gap throughout is at the centroid, 0, in every frame)."""
        from mpz.fisher import preview_series
        from mpz.motion import Motion
        if mode not in ("constant", "linear"):
            raise ValueError(f"mode must be 'constant' or 'linear', got {mode!r}")
        if self.space != "positions":
            raise FormatError("a preview Motion needs a position summary (space 0)")
        # the finest by k, not by place: levels may come in any order (§4.10; a QA run)
        lv = max(self.levels, key=lambda lv: lv.k) if k is None else self.level(k)
        series = preview_series(lv.starts, lv.means, self.n_frames, mode=mode)
        pos = series.reshape(self.n_frames, -1, 3)
        return Motion(pos, list(self.names), self.rate, self.units,
                      metadata={"preview": f"summary k={lv.k} ({mode})"})


def read_summary(source: Source) -> Summary | None:
    """Read the summary chunk (smry, §4.10, or smrc, §4.15) of an MPZ file without decoding
    the motion.

    Parameters
    ----------
    source : str, os.PathLike, bytes-like or binary file object
        As for :func:`decode`.

    Returns None when the file has no summary chunk.

    Raises
    ------
    MPZError
        If the file is invalid.
    TypeError
        If ``source`` is none of the above (a closed file object, or one open for
        writing, included).
    """
    from mpz.format import SummarySpace, unit_name
    s, _ = _stream(source)
    if s.summary is None:
        return None
    from mpz.chunks import Smrc
    f = s.summary.record
    levels = []
    if isinstance(f, Smrc):        # §4.15 (1.1): the same levels, starts and means range-coded
        decoded = f.levels_decoded(s.header.frame_count)
        for head, (starts, q) in zip(f.levels, decoded, strict=True):
            with np.errstate(over="ignore"):            # ±inf where it overflows, §4.15
                means = q.astype(np.float64) * head.step
            levels.append(SummaryLevel(head.k, starts, means, head.wssse, head.step))
    else:
        for lv in f.levels:
            starts = lv.start_frames().astype(np.int64)
            levels.append(SummaryLevel(lv.k, starts, lv.mean_values(f.dims), lv.wssse,
                                       lv.step))
    space = "positions" if f.space == SummarySpace.POSITIONS else "angles"
    return Summary(space, f.dims, levels, s.header.frame_count, s.header.rate, s.names,
                   unit_name(s.header.units))
