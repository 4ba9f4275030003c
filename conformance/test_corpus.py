"""Replay the fuzzing corpus (conformance/corpus/): the seeds plus the inputs
atheris kept for new coverage, minimised with -merge=1. For each input, with
and without repaired CRCs, the decoder returns a Motion or raises MPZError,
and mpzinfo reports without raising. CI replays; it does not fuzz."""
from pathlib import Path
import zlib

import pytest

import mpz
from mpz.errors import MPZError
from mpz.tools.mpzinfo import inspect

CORPUS = sorted((Path(__file__).parent / "corpus").iterdir())


def fix_crcs(data: bytes) -> bytes:
    out = bytearray(data)
    pos = 8
    while pos + 12 <= len(out):
        length = int.from_bytes(out[pos + 4: pos + 8], "little")
        end = pos + 8 + length
        if end + 4 > len(out):
            break
        crc = zlib.crc32(bytes(out[pos + 8: end]), zlib.crc32(bytes(out[pos: pos + 4])))
        out[end: end + 4] = crc.to_bytes(4, "little")
        pos = end + 4
    return bytes(out)


def test_corpus_is_not_empty():
    assert len(CORPUS) >= 50


@pytest.mark.parametrize("path", CORPUS, ids=[p.name[:16] for p in CORPUS])
def test_replay(path):
    data = path.read_bytes()
    for blob in (data, fix_crcs(data)):
        try:
            out = mpz.decode(blob, max_samples=1 << 16)
            assert out.n_frames >= 1
        except MPZError:
            pass
        info = inspect(blob, path.name)
        assert info["status"] in ("ok", "warning", "error")
