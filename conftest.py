"""Session set-up shared by ``conformance/`` and ``tests/``.

Many tests start ``mpz``, ``mpzinfo``, ``mpz-conformance`` or the reference decoder as
processes. Where ``PYTHONDONTWRITEBYTECODE`` is set (this project's CI machine sets it), no
process writes the bytecode of mpz's own modules, so each one compiled them from source
again: 0.74 s to import the command instead of 0.52-0.58 s, measured over 8 starts each,
on some 450 processes a run. The controlling pytest process therefore writes that
bytecode once, where Python looks for it (``__pycache__`` beside each module, which
``.gitignore`` keeps out of the repository), when the package folders can be written.
"""
from __future__ import annotations

import compileall
import importlib.util
import os

import pytest


def _package_dirs() -> list[str]:
    """The folders of mpz's packages as this interpreter imports them (an editable
    install spreads them over reference/, tools/ and conformance/)."""
    found = []
    for name in ("mpz", "mpz.tools", "mpz.conformance"):
        spec = importlib.util.find_spec(name)
        for d in (spec.submodule_search_locations or []) if spec is not None else []:
            if d not in found:
                found.append(d)
    return found


def pytest_sessionstart(session: pytest.Session) -> None:
    if hasattr(session.config, "workerinput"):      # an xdist worker: the controller did it
        return
    for d in _package_dirs():
        if os.access(d, os.W_OK):
            # quiet: a file that cannot be compiled is the tests' to report, not this hook's
            compileall.compile_dir(d, quiet=2, workers=1)
