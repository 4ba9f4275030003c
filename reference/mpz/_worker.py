"""Imported first by the ``mpz`` package: a Dask worker process of the ``mpz`` command
ignores SIGINT (Ctrl-C is the command's).

A worker of ``mpz encode -j N`` is spawned by multiprocessing, which runs the ``mpz``
script again as ``__mp_main__`` and so imports this package before anything else. A
Ctrl-C at the terminal reaches every process of the group: each worker still importing
printed a KeyboardInterrupt traceback, while the command itself cancels the tasks and
closes the cluster (docs/corpus.md). :func:`mpz.corpus.dask_setup` does the same for the
workers of other drivers once they run. Only a multiprocessing child of the ``mpz``
script is touched.
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


ignore_sigint_in_a_worker()
