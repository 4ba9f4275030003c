"""Replay the fuzzing corpus (conformance/corpus/): the seeds plus the inputs
atheris kept for new coverage, minimised with -merge=1. For each input, with
and without repaired CRCs, the decoder returns a Motion or raises MPZError,
and mpzinfo reports without raising. CI replays; it does not fuzz."""
from pathlib import Path

import pytest

import mpz
from mpz.container import repair_crcs
from mpz.errors import MPZError
from mpz.tools.mpzinfo import inspect

CORPUS = sorted((Path(__file__).parent / "corpus").iterdir())


def _write_sources(m: mpz.Motion) -> None:
    """What the fuzz target's ``write_sources`` does: the C3D, BVH or AMC/ASF text that the
    file's ancillary chunks rebuild, in memory (an MPZError is a refusal, anything else a
    bug that escapes)."""
    from mpz.io import amc, bvh, c3d
    from mpz.io.kinematics import Skeleton
    if m.extras.get("c3d") is not None:
        c3d.archive_bytes(m)
    skel = m.extras.get("skeleton")
    if isinstance(skel, Skeleton):
        if skel.convention == "bvh":
            bvh.format_bvh(m)
        else:
            amc.format_asf(skel)
            amc.format_amc(m)


def test_corpus_is_not_empty():
    assert len(CORPUS) >= 50


@pytest.mark.parametrize("path", CORPUS, ids=[p.name[:16] for p in CORPUS])
def test_replay(path):
    data = path.read_bytes()
    for blob in (data, repair_crcs(data)):
        try:
            out = mpz.decode(blob, max_samples=1 << 16)
            assert out.n_frames >= 1
            _write_sources(out)
        except MPZError:
            pass
        # the fuzz target's own sample limit: the corpus probes the decoder's paths, not the
        # machine's memory (test_bombs.py decodes the 2^26-sample files under a cap)
        info = inspect(blob, path.name, max_samples=1 << 16)
        assert info["status"] in ("ok", "warning", "error")
