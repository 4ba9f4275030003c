"""bench/bench_corpus.py's search figures (docs/corpus.md quotes them): R-precision, mean
average precision and chance, per class, and per class counted in distinct takes."""
from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture
def bench(bench_script):
    return bench_script("bench_corpus")


def test_class_scores_by_hand(bench):
    """Six files, a class of three; each member's ranked list of the five others.
    a: b d c e f -> R-prec 1/2, AP (1/1 + 2/3) / 2; b: d e a f c -> 0, (1/3 + 2/5) / 2;
    c: a b ... -> 1, 1. Chance: 2 of the 5 others."""
    ranked = {"a": list("bdcef"), "b": list("deafc"), "c": list("abdef")}
    got = bench._class_scores(["a", "b", "c"], ranked, 6)
    assert got["files"] == 3
    assert got["r_precision"] == pytest.approx((0.5 + 0.0 + 1.0) / 3)
    assert got["map"] == pytest.approx(((1 + 2 / 3) / 2 + (1 / 3 + 2 / 5) / 2 + 1.0) / 3)
    assert got["chance"] == pytest.approx(2 / 5)
    assert bench._class_scores(["a"], ranked, 6) is None     # one member: no figure


def test_distinct_takes_leave_out_the_second_encoding(bench, monkeypatch):
    """In distinct takes, a take's other encoding is neither a query nor a candidate: a
    walk class whose only 'hit' is the same take in another encoding scores 0 there."""
    class Index:
        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def descriptors(self):
            import numpy as np
            rows = [("w1.c3d", [0.0]), ("w1.amc", [0.01]), ("x.c3d", [0.5]), ("w2.c3d", [1.0])]
            return ([{"path": f"/d/{n}", "source_sha256": n, "output": n} for n, _ in rows],
                    np.array([v for _, v in rows]))
    monkeypatch.setattr(bench, "open_index", lambda out: Index())
    monkeypatch.setattr(bench, "CLASSES", {"walk": ["w1.c3d", "w1.amc", "w2.c3d"]})
    monkeypatch.setattr(bench, "SAME_TAKE", [("w1.c3d", "w1.amc")])
    q = bench.search_quality(Path("/out"), Path("/d"))
    # all encodings: w1.c3d finds w1.amc first (a hit), w2.c3d after x.c3d
    assert q["classes"]["walk"]["r_precision"] == pytest.approx((1 / 2 + 1 / 2 + 1 / 2) / 3)
    # distinct takes: w1.c3d and w2.c3d, x.c3d between them both ways
    assert q["classes"]["walk (distinct takes)"] == pytest.approx(
        {"files": 2, "r_precision": 0.0, "map": 0.5, "chance": 1 / 2})
