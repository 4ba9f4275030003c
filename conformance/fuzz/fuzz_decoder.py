#!/usr/bin/env python3
"""Coverage-guided fuzzing of the decoder and mpzinfo with atheris (not run by CI).

    pip install atheris
    python conformance/fuzz/make_seeds.py SEEDS --real ../shared/data   # optional
    python conformance/fuzz/fuzz_decoder.py -max_total_time=2700 -rss_limit_mb=3000 \\
        CORPUS_DIR conformance/corpus SEEDS

The properties, for any bytes, as they are and with every CRC repaired:

- ``mpz.decode`` returns a Motion or raises an ``MPZError``. **Every other exception is a
  crash**: the target catches ``MPZError`` and nothing else, so a ``ValueError``,
  ``IndexError``, ``OverflowError``, ``MemoryError`` (the inputs are capped at 2^16
  marker-frames, far below any memory limit) or anything else reaches atheris, which
  reports it with the input (issue 10: the decoder must not hide its own bugs);
- a decoded Motion is consistent: shape ``[F, M, 3]`` as the header says, finite wherever
  the mask says valid (§4.4, §6.8), NaN at gaps;
- ``mpzinfo.inspect`` reports without raising, and agrees with ``mpz.decode``: it says
  "error" exactly when the decoder rejects the file (issue 11.5);
- every rejection carries an offset (issue 11.7).

To keep only the inputs that add coverage, ``-merge=1`` runs the script again as a command
(its first argument), so it is executable with a ``python3`` shebang: run it from the
activated venv, e.g. ``conformance/fuzz/fuzz_decoder.py -merge=1 conformance/corpus NEW``.

A hang past ``-timeout`` or memory past ``-rss_limit_mb`` is a crash too. Minimised
crashers and the seed corpus live in conformance/corpus/ and are replayed by
conformance/test_corpus.py on every test run.
"""
from __future__ import annotations

import importlib
import inspect as _inspect
import pkgutil
import sys
import types

import numpy as np

try:
    import atheris
except ImportError:   # --help, and fuzz_readers.py's --seeds and --replay, need none
    atheris = None

import mpz
from mpz.conformance.sources import rebuild_sources
from mpz.container import repair_crcs
from mpz.errors import MPZError
from mpz.tools.mpzinfo import inspect

# Numba-compiled kernels cannot run instrumented bytecode, so only the Python
# layers of the decoding path are instrumented (framing, the chunk table and its checks,
# validation, decoding steps, extensions, mpzinfo, construct); the kernels are warmed up
# first.
_MODULES = ["mpz.container", "mpz.decoder", "mpz.predict", "mpz.normalize", "mpz.smooth",
            "mpz.keyframe", "mpz.extensions", "mpz.skeleton", "mpz.channels", "mpz.api",
            "mpz.tools.mpzinfo", "construct.core"]


def _modules() -> list[str]:
    import mpz.chunks
    chunks = [f"mpz.chunks.{m.name}" for m in pkgutil.iter_modules(mpz.chunks.__path__)]
    return _MODULES + ["mpz.chunks"] + chunks


def _instrument() -> None:
    instrument(_modules())


def instrument(names: list[str]) -> None:
    """Instrument every function and method that the modules ``names`` define (also used
    by fuzz_readers.py)."""
    for name in names:
        mod = importlib.import_module(name)
        for obj in list(vars(mod).values()):
            if isinstance(obj, types.FunctionType) and obj.__module__ == name:
                atheris.instrument_func(obj)
            elif _inspect.isclass(obj) and obj.__module__ == name:
                for meth in vars(obj).values():
                    if isinstance(meth, types.FunctionType):
                        atheris.instrument_func(meth)


def _warm_up() -> None:
    from mpz.synth import generate
    for kw in ({"max_error": 1.0}, {"lossy": True}, {"max_error": 1.0, "patterns": "on"},
               {}):
        m = generate("walk", frames=20, markers=4, seed=0, gap_fraction=0.1)
        mpz.decode(mpz.encode(m, **kw))


# keep each input cheap: refuse anything over 2^16 marker-frames
MAX_SAMPLES = 1 << 16


def check(blob: bytes) -> None:
    """The properties above for one input (raises AssertionError or the escaped exception)."""
    try:
        m = mpz.decode(blob, max_samples=MAX_SAMPLES)
        rejected = None
    except MPZError as exc:
        m, rejected = None, exc
    info = inspect(blob, "fuzz", decode=True, max_samples=MAX_SAMPLES)
    assert info["status"] in ("ok", "warning", "error"), info["status"]
    if rejected is not None:
        assert rejected.offset is not None, f"rejection without an offset: {rejected}"
        assert info["status"] == "error", f"mpz.decode rejects ({rejected}), mpzinfo says OK"
        return
    assert m is not None
    assert info["status"] != "error", f"mpz.decode decodes, mpzinfo says {info['errors']}"
    F, M = info["frames"], info["markers"]
    assert m.positions.shape == (F, M, 3) and m.valid.shape == (F, M)
    assert np.isfinite(m.positions[m.valid]).all(), "a valid sample is not finite"
    assert np.isnan(m.positions[~m.valid]).all(), "a gap is not NaN"
    write_sources(m)


def write_sources(m: mpz.Motion) -> None:
    """Write what a decoded file's ancillary chunks rebuild (issue 12: C3D archive §6.9;
    issue 13: skeletons §6.10) into memory, as ``mpz decode -o X.c3d/.bvh/.amc`` would.
    A writer may refuse a valid file with an MPZError; anything else escapes."""
    try:
        rebuild_sources(m)
    except MPZError:
        pass


def TestOneInput(data: bytes) -> None:
    check(data)
    repaired = repair_crcs(data)
    if repaired != data:
        check(repaired)


def require_atheris() -> None:
    """Exit with a message, not an ImportError's traceback, where atheris is missing (a
    newcomer's QA run, stop 73: ``--help`` gave a traceback)."""
    if atheris is None:
        sys.exit(f"{sys.argv[0]}: atheris is not installed: pip install atheris "
                 "(--help says how to run this)")


def main() -> None:
    if {"-h", "--help"} & set(sys.argv[1:]):
        print(__doc__)
        return
    require_atheris()
    _warm_up()
    _instrument()
    atheris.Setup(sys.argv, TestOneInput)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
