"""Coverage-guided fuzzing of the decoder and mpzinfo with atheris (not run by CI).

    pip install atheris
    python conformance/fuzz/fuzz_decoder.py -max_total_time=600 -rss_limit_mb=2048 \
        CORPUS_DIR conformance/corpus

The property: for any bytes, ``mpz.decode`` returns a Motion or raises an
``MPZError``, and ``mpzinfo.inspect`` returns a report; anything else
(another exception, a hang past -timeout, memory past -rss_limit_mb) is a
crash. Minimised crashers and the seed corpus live in conformance/corpus/ and
are replayed by conformance/test_corpus.py on every test run.
"""
import inspect as _inspect
import sys
import types

import atheris

import mpz
from mpz.container import repair_crcs
from mpz.errors import MPZError
from mpz.tools.mpzinfo import inspect

# Numba-compiled kernels cannot run instrumented bytecode, so only the Python
# layers of the decoding path are instrumented (framing, validation, decoding
# steps, mpzinfo, construct); the kernels are warmed up first.
_MODULES = ["mpz.container", "mpz.decoder", "mpz.predict", "mpz.normalize", "mpz.smooth",
            "mpz.api", "mpz.tools.mpzinfo", "construct.core"]


def _instrument():
    for name in _MODULES:
        mod = sys.modules[name]
        for obj in list(vars(mod).values()):
            if isinstance(obj, types.FunctionType) and obj.__module__ == name:
                atheris.instrument_func(obj)
            elif _inspect.isclass(obj) and obj.__module__ == name:
                for meth in vars(obj).values():
                    if isinstance(meth, types.FunctionType):
                        atheris.instrument_func(meth)


def _warm_up():
    from mpz.synth import generate
    for kw in ({"max_error": 1.0}, {}, {"max_error": 1.0, "patterns": "on"}):
        m = generate("walk", frames=20, markers=4, seed=0, gap_fraction=0.1)
        mpz.decode(mpz.encode(m, **kw))

# keep each input cheap: refuse anything over 2^16 marker-frames
MAX_SAMPLES = 1 << 16


def TestOneInput(data: bytes):
    for blob in (data, repair_crcs(data)):
        try:
            mpz.decode(blob, max_samples=MAX_SAMPLES)
        except MPZError:
            pass
    info = inspect(repair_crcs(data), "fuzz", decode=True)
    assert info["status"] in ("ok", "warning", "error")


def main():
    _warm_up()
    _instrument()
    atheris.Setup(sys.argv, TestOneInput)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
