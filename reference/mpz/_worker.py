"""Imported first by the ``mpz`` package: a Dask worker process of the ``mpz`` command
ignores SIGINT (Ctrl-C is the command's).

A worker of ``mpz encode -j N`` is spawned by multiprocessing, which runs the ``mpz``
script again as ``__mp_main__`` and so imports this package before anything else. A
Ctrl-C at the terminal reaches every process of the group: each worker still importing
printed a KeyboardInterrupt traceback, while the command itself cancels the tasks and
closes the cluster (docs/corpus.md). :func:`mpz.corpus.dask_setup` does the same for the
workers of other drivers once they run. Only a multiprocessing child of the ``mpz``
script is touched.

In the ``mpz``, ``mpzinfo`` and ``mpz-conformance`` commands themselves, SIGINT is
*blocked* in the main thread from this first import until the command's ``main`` starts
(:func:`release_sigint`, called by ``mpz.tools._cli.reports_ctrl_c``). A Ctrl-C in the
second or so of imports (numpy, numba, Dask) printed a KeyboardInterrupt traceback and
ended the command by the signal; held, it is delivered inside ``main``, which says
"interrupted" and exits 130 as at any other time.
"""
from __future__ import annotations

from collections.abc import Iterator
import contextlib
import contextvars
import os
import re
import signal
import sys
import threading


def ignore_sigint() -> bool:
    """Ignore SIGINT from now on, in the main thread (the one Python lets set handlers);
    True if it did."""
    if threading.current_thread() is not threading.main_thread():
        return False
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    return True


def _script(module: str) -> str | None:
    """The name, without folder or extension, of the script run as ``module``
    (``__main__``, or ``__mp_main__`` in a multiprocessing child); None if there is none."""
    mod = sys.modules.get(module)
    path = getattr(mod, "__file__", None)
    return os.path.splitext(os.path.basename(path))[0] if mod is not None and path else None


def ignore_sigint_in_a_worker() -> bool:
    """:func:`ignore_sigint` if this process is a multiprocessing child of the ``mpz``
    script; True if it did."""
    return _command_script("__mp_main__", MPZ) and ignore_sigint()


#: the command whose ``encode -j N`` starts worker processes
MPZ = frozenset({"mpz"})
#: the console scripts whose ``main`` reports a Ctrl-C as "interrupted", exit 130, and
#: calls :func:`release_sigint` first
COMMANDS = frozenset({"mpz", "mpzinfo", "mpz-conformance"})


def _command_script(module: str = "__main__", names: frozenset[str] | None = None) -> bool:
    """Whether the script run as ``module`` is one of ``names`` (default :data:`COMMANDS`):
    a script of that name (without extension) whose first 4 KB import a command's
    ``main`` (:data:`_ENTRY`), as the console scripts pip writes do. A user's own script
    named ``mpz`` or ``mpzinfo.py`` that imported mpz had SIGINT blocked for good, and so
    did its children (a QA run of the API, stop 54)."""
    mod = sys.modules.get(module)
    path = getattr(mod, "__file__", None)
    if not path or _script(module) not in (COMMANDS if names is None else names):
        return False
    try:
        with open(path, "rb") as fh:
            return _ENTRY.search(fh.read(4096)) is not None
    except OSError:
        return False


#: the line of a console script that pip writes for one of :data:`COMMANDS` (pyproject's
#: ``[project.scripts]``: ``mpz.tools.mpz_cli``, ``mpz.tools.mpzinfo``,
#: ``mpz.conformance.runner``)
_ENTRY = re.compile(rb"^from mpz\.(?:tools|conformance)\.\w+ import main\s*$", re.M)


def hold_sigint_in_a_command() -> bool:
    """Block SIGINT in the main thread when this process runs one of :data:`COMMANDS`
    itself (not a multiprocessing child of it), until its ``main`` releases it; True if it
    did."""
    if not _command_script() or "__mp_main__" in sys.modules \
            or threading.current_thread() is not threading.main_thread() \
            or not hasattr(signal, "pthread_sigmask"):
        return False
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    return True


def ignore_sigint_when_done() -> bool:
    """In one of :data:`COMMANDS`, once its ``main`` is done: ignore SIGINT for the rest,
    the interpreter's shutdown; True if it did. The shutdown gives SIGINT its default
    action back, so a Ctrl-C in it (0.2 s after a one-file encode: numba's, llvmlite's and
    the threads' teardown) ended the process by the signal, exit 130 without a word,
    after the output had been written whole (a QA of stop 42). The work is done and its
    exit status stands."""
    return own_process() and ignore_sigint()


def own_process() -> bool:
    """True in a process that runs mpz's code alone: one of :data:`COMMANDS` itself, or a
    multiprocessing child of the ``mpz`` script (a worker of ``mpz encode -j N``). Not in
    a program that imports mpz as a library, nor in a Dask worker of someone else's
    cluster."""
    return ((_command_script() and "__mp_main__" not in sys.modules)
            or _command_script("__mp_main__", MPZ))


#: set while a command's ``main`` runs (``mpz.tools._cli.reports_ctrl_c``), however it was
#: started: the console script, ``python -m mpz.tools.mpz_cli``, ``main([...])`` in a program
_MAIN = [False]
#: set while a worker of any cluster runs a corpus task that a command sent
#: (``mpz.corpus.Task.command``)
_TASK: contextvars.ContextVar[bool] = contextvars.ContextVar("mpz_command_task", default=False)


def command_main(running: bool) -> bool:
    """Say whether a command's ``main`` runs now; returns what was said before."""
    before, _MAIN[0] = _MAIN[0], running
    return before


@contextlib.contextmanager
def command_task(sent: bool) -> Iterator[None]:
    """Within it, this thread runs a task a command sent (``sent``) or a program did."""
    token = _TASK.set(sent)
    try:
        yield
    finally:
        _TASK.reset(token)


def in_command() -> bool:
    """Whether what runs now answers to a command line: a command's ``main``, a task it
    sent to a worker, or a process of :func:`own_process`."""
    return _MAIN[0] or _TASK.get() or own_process()


def spelled(cli: str, api: str) -> str:
    """How a message names an option: ``cli`` (``--force``) where :func:`in_command`, else
    ``api`` (``force=True``). Messages said both ("use --force (force=True)"), for whichever
    reader (a newcomer's QA run, stop 62); the review of stop 62 found the console script's
    test alone wrong for ``python -m mpz.tools.mpz_cli`` and ``--scheduler`` workers."""
    return cli if in_command() else api


def release_sigint() -> None:
    """Unblock SIGINT in the calling thread: a Ctrl-C held since the first import is
    delivered now, as KeyboardInterrupt where the command reports it."""
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


#: the exit status of a command that ran out of memory (mpz.tools._cli.EXIT_MEMORY)
EXIT_MEMORY = 3


def out_of_memory(exc: BaseException | None) -> BaseException | None:
    """``exc``, or the exception it was raised from or while handling, that is a failure
    to get memory: a MemoryError, or an OSError of ENOMEM or of a shared library the loader
    could not map (llvmlite's ``failed to map segment`` under ``ulimit -v``); else None."""
    seen: set[int] = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if isinstance(exc, MemoryError) or (isinstance(exc, OSError) and (
                exc.errno == 12 or "failed to map segment" in str(exc)
                or "Cannot allocate memory" in str(exc))):
            return exc
        exc = exc.__cause__ or exc.__context__
    return None


def _start_up_hook(kind: type[BaseException], exc: BaseException, tb: object) -> None:
    """In one of :data:`COMMANDS`, an exception that escapes before ``main`` handles it:
    one line and exit 3 when it is a failure to get memory, as ``main`` reports one. Under
    ``ulimit -v`` 160-300 MB every command failed in its imports with two tracebacks of
    llvmlite's (``mpz --version`` too; stop 61's list of what was not done)."""
    cause = out_of_memory(exc)
    if cause is not None:
        name = os.path.basename(sys.argv[0] or "mpz")
        what = (str(cause).splitlines() or [""])[0][:200] or type(cause).__name__
        print(f"{name}: error: out of memory while starting ({what}): the libraries it "
              "loads (numpy, numba's compiler) need about 400 MB of address space, more "
              "than this process may have (ulimit -v, a job's memory limit)",
              file=sys.stderr, flush=True)
        os._exit(EXIT_MEMORY)
    sys.__excepthook__(kind, exc, tb)    # type: ignore[arg-type]


if not ignore_sigint_in_a_worker():
    if hold_sigint_in_a_command():
        sys.excepthook = _start_up_hook
