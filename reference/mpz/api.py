"""File-level helpers around the sans-IO core: read, write (atomically), summary.

Only this module and :mod:`mpz.io` touch the file system.
"""
from __future__ import annotations

from collections.abc import Iterator
import contextlib
import errno
import os
from pathlib import Path
import secrets
import signal
import stat
import threading
from types import FrameType

import numpy as np

from mpz.errors import EncoderError, FormatError, MPZError


def _same_file(a: str, b: str) -> bool:
    """True if ``a`` and ``b`` name one file (hard links, symbolic links, ``..`` and all)."""
    try:
        if os.path.exists(a) and os.path.exists(b) and os.path.samefile(a, b):
            return True
    except OSError:
        pass
    return os.path.realpath(a) == os.path.realpath(b)


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
        and ``force`` is false; or exists but is not a regular file.
    """
    target = os.fspath(path)
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
                               "use --force to replace it")
        return
    if os.path.lexists(target):
        if not force:
            raise EncoderError(f"{target} exists; use --force to replace it")
        if not stat.S_ISREG(os.stat(target).st_mode):
            raise EncoderError(f"{target} is not a regular file; refusing to replace it")


@contextlib.contextmanager
def _sigterm_raises() -> Iterator[None]:
    """While an output is written, SIGTERM raises ``SystemExit(143)`` so cleanup code runs.

    Only where SIGTERM still has its default action and only in the main
    thread (the only one Python lets set handlers); the old handler comes back
    afterwards. SIGINT needs nothing: it already raises KeyboardInterrupt.
    """
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL):
        yield
        return

    def terminate(signum: int, frame: FrameType | None) -> None:
        raise SystemExit(128 + signum)

    old = signal.signal(signal.SIGTERM, terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """Hold SIGINT and SIGTERM back for a few statements (POSIX threads only).

    Between creating the temporary file and recording its name a signal must
    not strike, or nobody would know which file to remove. A held signal is
    delivered, and its Python handler run, when the mask is restored.
    """
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


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
    exists = EncoderError(f"{target} exists; use --force to replace it")
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
    * Without ``force`` the name is created exclusively: of two writers of
      the same new file exactly one succeeds; the other gets
      :class:`~mpz.errors.EncoderError` "exists; use --force".
    * With ``force`` an existing file is replaced and keeps its mode; a new
      file gets mode 0o666 minus the umask.
    * On any exception, and on SIGTERM (see :func:`_sigterm_raises`), the
      temporary file is removed. An ``OSError`` becomes ``EncoderError``
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
    folder = os.path.dirname(os.path.abspath(target))
    name = os.path.basename(target)
    ext = os.path.splitext(name)[1] if suffix is None else suffix
    with _sigterm_raises():
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
    with atomic_output(path, force=force, source=source) as tmp, open(tmp, "wb") as fh:
        fh.write(data)


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
    check_output(path, force=True, source=source)  # a bad path fails before the encode
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
    from mpz.decoder import read_stream
    from mpz.format import SummarySpace, unit_name
    s = read_stream(data)
    if s.summary is None:
        return None
    f = s.summary.record
    levels = []
    for lv in f.levels:
        starts = lv.start_frames().astype(np.int64)
        levels.append(SummaryLevel(lv.k, starts, lv.mean_values(f.dims), lv.wssse, lv.step))
    space = "positions" if f.space == SummarySpace.POSITIONS else "angles"
    return Summary(space, f.dims, levels, s.header.frame_count, s.header.rate, s.names,
                   unit_name(s.header.units))
