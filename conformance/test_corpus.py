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


@pytest.mark.parametrize("script", ["fuzz_decoder.py", "fuzz_readers.py"])
def test_the_fuzz_scripts_say_how_to_run_them_without_atheris(script, tmp_path):
    """``--help`` printed an ImportError's traceback where atheris is not installed (a
    newcomer's QA run, stop 73): it prints the script's docstring, and a fuzzing run
    without atheris says to install it."""
    import importlib.util
    import subprocess
    import sys
    path = Path(__file__).parent / "fuzz" / script
    p = subprocess.run([sys.executable, str(path), "--help"], capture_output=True, text=True,
                       timeout=300, cwd=tmp_path)
    assert p.returncode == 0 and "atheris" in p.stdout and "Traceback" not in p.stderr, \
        p.stderr
    if importlib.util.find_spec("atheris") is None:
        p = subprocess.run([sys.executable, str(path), str(tmp_path)], capture_output=True,
                           text=True, timeout=300, cwd=tmp_path)
        assert p.returncode == 1 and "atheris is not installed: pip install atheris" in \
            p.stderr and "Traceback" not in p.stderr, p.stderr
