"""Helpers shared by the benchmark scripts (not part of the mpz package)."""
from __future__ import annotations

import os
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def shared_data_dir() -> Path | None:
    """``$MPZ_SHARED_DATA`` or ``<repo>/../shared/data``, or None when absent.

    Real recordings are read in place from there and never copied into the repo.
    """
    env = os.environ.get("MPZ_SHARED_DATA")
    cand = Path(env) if env else REPO.parent / "shared" / "data"
    return cand if cand.is_dir() else None


def best_of(fn, n=3):
    """Fastest of ``n`` timed calls of ``fn``, in seconds."""
    import time
    ts = []
    for _ in range(n):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return min(ts)
