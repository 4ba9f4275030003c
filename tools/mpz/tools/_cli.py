"""What every MPZ command shares: the exit codes, the argument parser, quiet broken pipes.

One table for ``mpz``, ``mpzinfo``, ``mpz-conformance`` and ``spec_example``
(README.md, "Command exit codes"):

====  ===================================================================
code  meaning
====  ===================================================================
0     ok (``mpz-conformance``: every selected vector passed)
1     warnings only (``mpz-conformance``: at least one vector failed)
2     errors in the input or the data (a file, an output path, the codec)
64    usage error: bad options or arguments (argparse's errors included)
130   ``mpz`` only: interrupted with Ctrl-C
====  ===================================================================

Output piped into a command that stops reading (``mpzinfo -vv *.mpz | head``)
ends the tool quietly with the code it would have had otherwise, or 0 when the
pipe broke before it knew; no ``BrokenPipeError`` traceback.
"""
from __future__ import annotations

import argparse
from collections.abc import Callable
import functools
import os
import sys
from typing import NoReturn, ParamSpec

EXIT_OK = 0
EXIT_WARN = 1
EXIT_ERROR = 2
EXIT_USAGE = 64
EXIT_INTERRUPTED = 130

#: ``mpz-conformance``'s code for "at least one vector failed" (the code of EXIT_WARN)
EXIT_FAILED = EXIT_WARN

#: one line for ``--help`` epilogs
EXIT_CODES_HELP = ("exit codes: 0 ok, 1 warnings only, 2 errors in the input, "
                   "64 usage error")

_P = ParamSpec("_P")


class Parser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose usage errors exit with :data:`EXIT_USAGE` (64), not 2."""

    def error(self, message: str) -> NoReturn:
        self.print_usage(sys.stderr)
        print(f"{self.prog}: error: {message}", file=sys.stderr)
        raise SystemExit(EXIT_USAGE)


def _silence_stdout() -> None:
    """Point stdout at /dev/null so that Python's final flush cannot fail again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):  # stdout is not a real file (e.g. captured in tests)
        pass


def quiet_broken_pipe(main: Callable[_P, int]) -> Callable[_P, int]:
    """Decorate a command's ``main``: a reader closing the pipe ends the command quietly.

    The decorated function flushes stdout before returning, so that a broken
    pipe shows up here and not in the interpreter's exit handler.
    """

    @functools.wraps(main)
    def wrapper(*args: _P.args, **kwargs: _P.kwargs) -> int:
        code = EXIT_OK
        try:
            code = main(*args, **kwargs)
            sys.stdout.flush()
        except BrokenPipeError:
            _silence_stdout()
        return code

    return wrapper
