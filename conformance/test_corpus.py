"""Replay the fuzzing corpus (conformance/corpus/): the seeds plus the inputs
atheris kept for new coverage, minimised with -merge=1. For each input, with
and without repaired CRCs, the decoder returns a Motion or raises MPZError,
and mpzinfo reports without raising. CI replays; it does not fuzz."""
from pathlib import Path

import pytest

import mpz
from mpz.conformance.sources import rebuild_sources
from mpz.container import repair_crcs
from mpz.errors import MPZError
from mpz.tools.mpzinfo import inspect

CORPUS = sorted((Path(__file__).parent / "corpus").iterdir())


def test_corpus_is_not_empty():
    assert len(CORPUS) >= 50


@pytest.mark.parametrize("path", CORPUS, ids=[p.name[:16] for p in CORPUS])
def test_replay(path):
    data = path.read_bytes()
    for blob in (data, repair_crcs(data)):
        try:
            out = mpz.decode(blob, max_samples=1 << 16)
            assert out.n_frames >= 1
            rebuild_sources(out)        # what mpz decode -o X.c3d/.bvh/.amc writes
        except MPZError:
            pass
        # the fuzz target's own sample limit: the corpus probes the decoder's paths, not the
        # machine's memory (test_bombs.py decodes the 2^26-sample files under a cap)
        info = inspect(blob, path.name, max_samples=1 << 16)
        assert info["status"] in ("ok", "warning", "error")
