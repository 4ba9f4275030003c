"""Imported first by the ``mpz`` package: a Dask worker process of the ``mpz`` command
ignores SIGINT (Ctrl-C is the command's).

A worker of ``mpz encode -j N`` is spawned by multiprocessing, which runs the ``mpz``
script again as ``__mp_main__`` and so imports this package before anything else. A
Ctrl-C at the terminal reaches every process of the group: each worker still importing
printed a KeyboardInterrupt traceback, while the command itself cancels the tasks and
closes the cluster (docs/corpus.md). :func:`mpz.corpus.dask_setup` does the same for the
workers of other drivers once they run. Only a multiprocessing child of the ``mpz``
script is touched.

In the ``mpz`` command itself, SIGINT is *blocked* in the main thread from this first
import until the command's ``main`` starts (:func:`release_sigint`): the helper threads
that the imports start (numpy's OpenBLAS pool) are born with it blocked, so a Ctrl-C is
always the main thread's, and :func:`mpz.corpus._sigint_deferred` can ignore it while the
workers start without another thread dropping it.
"""
from __future__ import annotations

import os
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


def ignore_sigint_in_a_worker() -> bool:
    """:func:`ignore_sigint` if this process is a multiprocessing child of the ``mpz``
    script; True if it did."""
    mp_main = sys.modules.get("__mp_main__")
    script = os.path.basename(getattr(mp_main, "__file__", None) or "")
    if mp_main is None or os.path.splitext(script)[0] != "mpz":
        return False
    return ignore_sigint()


def _is_the_command() -> bool:
    """Whether this process runs the ``mpz`` script itself (not one of its workers)."""
    main = sys.modules.get("__main__")
    script = os.path.basename(getattr(main, "__file__", None) or "")
    return ("__mp_main__" not in sys.modules and os.path.splitext(script)[0] == "mpz"
            and threading.current_thread() is threading.main_thread())


def hold_sigint_in_the_command() -> bool:
    """Block SIGINT in the ``mpz`` command's main thread until :func:`release_sigint`;
    True if it did."""
    if not hasattr(signal, "pthread_sigmask") or not _is_the_command():
        return False
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    return True


def release_sigint() -> None:
    """Unblock SIGINT in the calling thread: a Ctrl-C held since the first import is
    delivered now, as KeyboardInterrupt where the command reports it."""
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


if not ignore_sigint_in_a_worker():
    hold_sigint_in_the_command()
