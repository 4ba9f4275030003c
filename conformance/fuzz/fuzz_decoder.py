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
import sys

import atheris

with atheris.instrument_imports():
    import mpz
    from mpz.errors import MPZError
    from mpz.tools.mpzinfo import inspect

# keep each input cheap: refuse anything over 2^16 marker-frames
MAX_SAMPLES = 1 << 16


def TestOneInput(data: bytes):
    try:
        mpz.decode(data, max_samples=MAX_SAMPLES)
    except MPZError:
        pass
    info = inspect(data, "fuzz", decode=False)
    assert info["status"] in ("ok", "warning", "error")


def main():
    atheris.Setup(sys.argv, TestOneInput)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
