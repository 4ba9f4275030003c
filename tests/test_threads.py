"""The Python API called from several threads at once (README "From Python").

A pipeline that encodes or decodes from a thread pool (Dask's threaded scheduler, a web
service) must get the bytes, motions and errors that the same calls give one at a time.
Each test starts its threads together at a barrier, so that they run the same stages at
the same moment, and compares every result with the serial run's.
"""
from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
import hashlib
from pathlib import Path
import threading
from typing import Any

import numpy as np
import pytest

import mpz
from mpz.synth import generate

THREADS = 4


def _digest(motion: mpz.Motion) -> str:
    h = hashlib.sha256(np.ascontiguousarray(motion.positions, np.float64).tobytes())
    h.update("\0".join(motion.names).encode())
    h.update(repr((motion.rate, motion.units)).encode())
    return h.hexdigest()


def _together(work: Callable[[int], Any], n: int = THREADS) -> list[Any]:
    """``work(i)`` on n threads started at one barrier; each result or raised exception."""
    gate = threading.Barrier(n)

    def run(i: int) -> Any:
        gate.wait(timeout=60)
        try:
            return work(i)
        except Exception as exc:        # compared with the serial run's exception
            return (type(exc).__name__, str(exc))
    with ThreadPoolExecutor(n) as pool:
        return list(pool.map(run, range(n)))


def _serial(work: Callable[[int], Any], n: int = THREADS) -> list[Any]:
    out = []
    for i in range(n):
        try:
            out.append(work(i))
        except Exception as exc:
            out.append((type(exc).__name__, str(exc)))
    return out


def test_encode_decode_from_several_threads() -> None:
    """Each thread codes every motion, starting at a different one, with its own options
    (one or two threads of its own, a bound or the default), and also decodes a damaged
    file: all of it as when run one thread at a time."""
    motions = [generate("walk", frames=300, seed=1),
               generate("jump", frames=200, seed=2, gap_fraction=0.05),
               generate("wave", frames=150, seed=3, markers=12)]
    bad = bytearray(mpz.encode(motions[0], max_error=1.0))
    bad[len(bad) // 2] ^= 0xFF                  # a payload byte: its chunk's CRC fails

    def work(i: int) -> list[Any]:
        out: list[Any] = []
        for k in range(len(motions)):
            m = motions[(i + k) % len(motions)]
            data = mpz.encode(m, max_error=None if i % 2 else 1.0, threads=1 + i % 2,
                              summary=(4, 8))
            back = mpz.decode(data)
            summary = mpz.read_summary(data)
            assert summary is not None
            out.append((hashlib.sha256(data).hexdigest(), _digest(back),
                        mpz.info(data).frames, len(summary.levels)))
        try:
            mpz.decode(bytes(bad))
        except mpz.MPZError as exc:
            out.append(str(exc))
        return out
    got = _together(work)
    assert got == _serial(work)
    # the threads coded with different options, so they did not all give the same bytes
    assert len({r[0][0] for r in got}) > 1
    assert all("CRC" in r[-1] for r in got)


@pytest.mark.parametrize("names", [("c3d/c3dorg_Sample_Jump2.c3d", "c3d/c3dorg_Eb015pi.c3d",
                                    "trc/opensim_subject01_walk1.trc",
                                    "amc/HDM_dg_06-03_03_120.amc", "bvh/cmu_11_01.bvh")])
def test_real_files_from_several_threads(shared_data: Path, tmp_path: Path,
                                         names: tuple[str, ...]) -> None:
    """Reading a real file of each format, coding it, decoding it and writing it back in
    its own format, on four threads at once: the same bytes as one at a time."""
    paths = [shared_data / n for n in names]
    missing = [str(p) for p in paths if not p.exists()]
    if missing:
        pytest.skip(f"not in ../shared/data: {missing}")

    def work(i: int) -> list[Any]:
        out: list[Any] = []
        for k in range(len(paths)):
            src = paths[(i + k) % len(paths)]
            m = mpz.io.read(src)
            data = mpz.encode(m, threads=1 + i % 2)
            back = mpz.decode(data)
            dest = tmp_path / f"t{i}-{src.name}"
            mpz.io.write(back, dest)
            out.append((src.name, hashlib.sha256(data).hexdigest(), _digest(back),
                        _digest(mpz.io.read(dest))))
        return sorted(out)
    got = _together(work)
    assert got == _serial(work)
    assert all(len(r) == len(paths) for r in got)


# ---------------------------------------------------- processes: fork, numba's layers --
_FORK_SCRIPT = r"""
import concurrent.futures as cf, multiprocessing as mp, sys, threading
import mpz
from mpz.synth import generate

def encode(i):
    return mpz.encode(generate("walk", frames=300, seed=i), max_error=1.0, summary=(6, 12))

if __name__ == "__main__":
    first = encode(0)                     # the parent starts the summary's parallel kernel
    if sys.argv[1] == "fork":
        with cf.ProcessPoolExecutor(1, mp_context=mp.get_context("fork")) as ex:
            child = ex.submit(encode, 0).result(timeout=120)
        assert child == first, "the forked child's file differs"
    else:                                 # two threads in the parallel kernel at once
        out = [None, None]
        gate = threading.Barrier(2)
        def run(i):
            gate.wait(timeout=60)
            out[i] = encode(i)
        ts = [threading.Thread(target=run, args=(i,)) for i in range(2)]
        [t.start() for t in ts]
        [t.join(timeout=300) for t in ts]
        assert out == [encode(0), encode(1)], "threads changed the bytes"
    print("ok")
"""


@pytest.mark.parametrize("how, layer", [("fork", None), ("threads", "workqueue"),
                                        ("fork", "workqueue")])
def test_summaries_in_forked_children_and_under_the_workqueue_layer(tmp_path, how, layer):
    """An ML pipeline's QA run (stop 51): once a process had made a summary (numba's
    parallel kernel, GNU OpenMP by default), a child it forked that made one too was
    terminated by numba, and a multiprocessing.Pool waited for it for ever; with
    NUMBA_THREADING_LAYER=workqueue (fork-safe), two threads making summaries at once
    aborted the process. Forked children use the serial compile of the kernel, and one
    parallel kernel runs at a time; the bytes are the same."""
    import os
    import subprocess
    import sys
    script = tmp_path / "fork_check.py"
    script.write_text(_FORK_SCRIPT)
    env = dict(os.environ)
    env.pop("NUMBA_THREADING_LAYER", None)
    if layer:
        env["NUMBA_THREADING_LAYER"] = layer
    p = subprocess.run([sys.executable, str(script), how], capture_output=True, text=True,
                       timeout=600, env=env, cwd=tmp_path)
    assert p.returncode == 0 and p.stdout.strip() == "ok", (p.returncode, p.stdout,
                                                              p.stderr[-2000:])
