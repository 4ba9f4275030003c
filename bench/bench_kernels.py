"""Where a one-thread encode's time goes: inside the compiled kernels, or around them,
against the time issue 15.1 allows (half of zstd -19's on the same float32 bytes).

    python bench/bench_kernels.py [--files walk1 amc/35_01 ... | --files all]
                                  [--bound 1mm] [--repeat 9] [--decode] [--json F]

For every file (a name under ../shared/data, or ``$MPZ_SHARED_DATA``, as in
bench_speed.py; default: the rows bench_speed.py found below 2x at stop 59) it prints, in
ms: ``zstd/2``, half of zstd -19's time on the same bytes (``_common.coded_float32``), which
is the whole encode's budget at 2x; MPZ's best one-thread and two-thread encode; ``kernels``,
the time a one-thread encode spends inside the numba kernels (cProfile's own time of every
numba dispatcher of the mpz package, found by walking its modules, so a kernel added or
renamed is counted without editing this file; the least over the rounds, each profiled
alone); ``rest``,
the one-thread time minus the kernels (Python, numpy, construct); and the four largest
kernels. The two verdict columns say whether a row is over its budget even split perfectly
over both cores: ``x1/2 over``, the whole one-thread encode (no use of the two threads can
reach 2x there; only less work can), and ``k/2 over``, its kernels alone (no change to the
Python around them can either; only kernels that search less, which changes the bytes).
docs/speed.md, "Where it stands", reads the table.

With ``--decode``, the same for ``mpz.decode`` of the file's one-thread encode against
issue 15.1's decode aim, 0.1x zstd -19's decompression speed on the same bytes: ``10 x zd``
(ten times zstd's decompression time, the decode's budget), ``dec`` (MPZ's best decode),
its ``kernels`` (the range decoder, the predictors' reconstruction ...), ``rest``, and one
verdict, ``k over``: whether the kernels alone pass the budget (then no change to the
Python around them reaches 0.1x on that row; only a faster coder can). Then the decode
run step by step as ``mpz.decoder.decode`` runs it (:class:`Steps`), each step's best:
``chunks`` (framing, CRCs and every payload read into its record), ``walk`` (the rest of
``read_stream``: the §3.4 order and each chunk's checks, which decode the 1.1 chunks'
payloads), ``layers`` (§6.1-§6.7, the marker layer) and ``output`` (§6.8 and the
extensions' records attached); they add up to about ``dec``.

Times are the best of ``--repeat`` rounds or more (bench_speed.py's ``timed_together``:
each round one call of zstd, of each encode and of the profiled encode, in turn, until
each has had 0.3 s), so that the host's drift moves all of them alike. cProfile adds a
little to each kernel call, not to its inside, so ``kernels`` is a fair floor and ``rest`` a
fair upper estimate.

Exit status: 0; 1 when zstandard (the ``bench`` extra) is missing; 2 for a usage error. An
absent or empty data folder prints "skipped: ..." and exits 0.
"""
from __future__ import annotations

import argparse
import cProfile
from functools import partial
import importlib
import json
import os
from pathlib import Path
import pkgutil
import pstats
import sys
import time

from _common import cannot_run, coded_float32, positive_int, shared_data_dir, warm_up
from bench_speed import bound_kwargs, bound_label, files_of, timed_together
import mpz
import mpz.io

#: the rows below 2x in stop 59's `bench_speed.py --files all --bounds 1mm --repeat 3`
DEFAULT_FILES = ["trc/opensim_subject01_walk1", "amc/35_01", "amc/HDM_dg_06-03_03_120",
                 "amc/02_01", "trc/opensim_hamner_subject02_running", "c3d/c3dorg_Dance1",
                 "c3d/cmu_02_01", "trc/btk_SprintMotion", "c3d/c3dorg_Sample_Jump2",
                 "c3d/HDM_dg_06-03_03_120"]


def kernel_sites() -> dict[tuple[str, str], tuple[str, ...]]:
    """Every numba dispatcher defined in the mpz package: (source file, function name) ->
    the dotted names of the dispatchers there. cProfile records a dispatcher's call under
    its Python function's file and name, which is how :func:`kernel_times` finds them;
    dispatchers that share one Python function (mpz.fisher's parallel and serial tables)
    cannot be told apart there, and share a site."""
    from numba.core.registry import CPUDispatcher
    names: dict[tuple[str, str], list[str]] = {}
    for info in pkgutil.walk_packages(mpz.__path__, "mpz."):
        if info.name.startswith(("mpz.tools", "mpz.conformance")):
            continue                                    # no codec kernels there
        module = importlib.import_module(info.name)
        for name, obj in vars(module).items():
            if isinstance(obj, CPUDispatcher) and obj.py_func.__module__ == info.name:
                code = obj.py_func.__code__
                names.setdefault((os.path.realpath(code.co_filename), code.co_name),
                                 []).append(f"{info.name}.{name}")
    return {site: tuple(sorted(n)) for site, n in names.items()}


def kernel_times(stats: pstats.Stats, sites: dict[tuple[str, str], tuple[str, ...]]
                 ) -> dict[str, float]:
    """Seconds inside each kernel of ``sites`` (cProfile's own time) in a profiled run,
    by dotted name ("a / b" for a site that several dispatchers share)."""
    out: dict[str, float] = {}
    for (path, _line, func), (_cc, _nc, own, _cum, _callers) in stats.stats.items():
        names = sites.get((os.path.realpath(path), func))
        if names is not None:
            name = " / ".join(names)
            out[name] = out.get(name, 0.0) + own
    return out


def profiled(fn, sites: dict[tuple[str, str], tuple[str, ...]]) -> dict[str, float]:
    """Seconds inside each kernel during one call of ``fn``, profiled alone."""
    profile = cProfile.Profile()
    profile.enable()
    fn()
    profile.disable()
    return kernel_times(pstats.Stats(profile), sites)


class LeastProfiled:
    """A round's profiled call of ``fn`` (:func:`profiled`), keeping the kernel times of
    the run whose kernels took least (``times``)."""

    def __init__(self, fn, sites: dict[tuple[str, str], tuple[str, ...]]) -> None:
        self.fn, self.sites = fn, sites
        self.times: dict[str, float] = {}

    def __call__(self) -> None:
        times = profiled(self.fn, self.sites)
        if not self.times or sum(times.values()) < sum(self.times.values()):
            self.times = times


def start(args, profiled_what: str, tail: str = ""):
    """The files asked for, the kernels loaded (on the first, not timed) and their sites,
    after the line that says how the table was taken."""
    root = shared_data_dir()
    assert root is not None
    paths = files_of(root, args.files)
    warm_up(paths[0])
    sites = kernel_sites()
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs; ms, best of "
          f"{args.repeat} rounds (kernels: the least of the profiled {profiled_what}; "
          f"{sum(len(names) for names in sites.values())} kernels found); bound "
          f"{args.bound}{tail}")
    return paths, sites


def largest(ms: dict[str, float], digits: int) -> str:
    """The four largest kernels of a row, by their last name."""
    top = sorted(ms.items(), key=lambda kv: -kv[1])[:4]
    return ", ".join(f"{k.rsplit('.', 1)[1]} {v:.{digits}f}" for k, v in top)


def yes(flag: bool) -> str:
    return "over" if flag else "-"


class Steps:
    """``mpz.decode(data)`` run step by step as :func:`mpz.decoder.decode` runs it, keeping
    each step's least time over the calls (``seconds``; module docstring) and the last
    result (``motion``). ``walk`` is the least ``read_stream`` less the least ``chunks``:
    ``read_stream`` parses the chunks itself before walking them."""

    def __init__(self, data: bytes) -> None:
        self.data = data
        self.motion: mpz.Motion | None = None
        self._least: dict[str, float] = {}

    def __call__(self) -> None:
        from mpz import container, decoder
        t0 = time.perf_counter()
        container.parse(self.data, keep_unknown=False)
        t1 = time.perf_counter()
        s = decoder.read_stream(self.data)
        t2 = time.perf_counter()
        d = decoder.Decoded(s, decoder.decode_mask(s), decoder.decode_integers(s))
        t3 = time.perf_counter()
        self.motion = d.motion(reuse_q=True)
        t4 = time.perf_counter()
        for k, v in (("chunks", t1 - t0), ("read_stream", t2 - t1), ("layers", t3 - t2),
                     ("output", t4 - t3)):
            self._least[k] = min(self._least.get(k, v), v)

    @property
    def seconds(self) -> dict[str, float]:
        got = dict(self._least)
        got["walk"] = got.pop("read_stream") - got["chunks"]
        return {k: got[k] for k in STEPS}


#: the steps of :class:`Steps`, in decoding order
STEPS = ("chunks", "walk", "layers", "output")


def run_decode(args) -> list[dict]:
    """The ``--decode`` table (module docstring)."""
    import zstandard
    paths, sites = start(args, "decodes", ", encoded with one thread")
    print(f"{'file':<34} {'10 x zd':>7} {'dec':>7} {'kernels':>7} {'rest':>7} {'k over':>6}"
          + "".join(f" {k:>7}" for k in STEPS) + "  largest kernels")
    rows = []
    zc, zd = zstandard.ZstdCompressor(level=19), zstandard.ZstdDecompressor()
    for path in paths:
        m = mpz.io.read(path)
        kw, _, _ = bound_kwargs(m, args.bound)
        raw = coded_float32(m)
        z = zc.compress(raw)
        data = mpz.encode(m, threads=1, **kw)
        one = partial(mpz.decode, data)
        one()
        least, steps = LeastProfiled(one, sites), Steps(data)
        best = {k: w for k, (w, _) in timed_together(
            {"zstd": partial(zd.decompress, z), "dec": one, "profiled": least,
             "steps": steps}, args.repeat).items()}
        ms = {k: v * 1e3 for k, v in least.times.items()}
        step_ms = {k: v * 1e3 for k, v in steps.seconds.items()}
        row = {"file": path.name, "frames": m.n_frames, "markers": m.n_markers,
               "bytes": len(raw), "mpz_bytes": len(data), "budget_ms": best["zstd"] * 10e3,
               "dec_ms": best["dec"] * 1e3, "kernels_ms": sum(ms.values()),
               "rest_ms": best["dec"] * 1e3 - sum(ms.values()), "kernels_ms_by_name": ms,
               "steps_ms": step_ms}
        rows.append(row)
        print(f"{path.name[:34]:<34} " + " ".join(
              f"{row[k]:>7.2f}" for k in ("budget_ms", "dec_ms", "kernels_ms", "rest_ms"))
              + f" {yes(row['kernels_ms'] > row['budget_ms']):>6}"
              + "".join(f" {step_ms[k]:>7.2f}" for k in STEPS) + f"  {largest(ms, 2)}",
              flush=True)
    for what, key in (("the whole decode", "dec_ms"), ("its kernels alone", "kernels_ms")):
        over = [r["file"] for r in rows if r[key] > r["budget_ms"]]
        print(f"{what} over the 0.1x budget: {len(over)} of {len(rows)}"
              + (f" ({', '.join(over)})" if over else ""))
    return rows


def run(args) -> list[dict]:
    import zstandard
    paths, sites = start(args, "one-thread encodes")
    print(f"{'file':<34} {'zstd/2':>7} {'x1':>7} {'x2':>7} {'kernels':>7} {'rest':>7}  "
          f"{'x1/2 over':>9} {'k/2 over':>8}  largest kernels")
    rows = []
    zc = zstandard.ZstdCompressor(level=19)
    for path in paths:
        m = mpz.io.read(path)
        kw, _, _ = bound_kwargs(m, args.bound)
        data = coded_float32(m)
        one = partial(mpz.encode, m, threads=1, **kw)
        one()
        least = LeastProfiled(one, sites)
        # bench_speed's rounds: the profiled encode in turn with zstd and the timed ones
        best = {k: w for k, (w, _) in timed_together(
            {"zstd": partial(zc.compress, data), "x1": one,
             "x2": partial(mpz.encode, m, threads=2, **kw), "profiled": least},
            args.repeat).items()}
        ms = {k: v * 1e3 for k, v in least.times.items()}
        row = {"file": path.name, "frames": m.n_frames, "markers": m.n_markers,
               "bytes": len(data), "budget_ms": best["zstd"] / 2 * 1e3,
               "x1_ms": best["x1"] * 1e3, "x2_ms": best["x2"] * 1e3,
               "kernels_ms": sum(ms.values()), "rest_ms": best["x1"] * 1e3 - sum(ms.values()),
               "kernels_ms_by_name": ms}
        rows.append(row)
        print(f"{path.name[:34]:<34} " + " ".join(
              f"{row[k]:>7.1f}" for k in ("budget_ms", "x1_ms", "x2_ms", "kernels_ms",
                                           "rest_ms"))
              + f"  {yes(row['x1_ms'] / 2 > row['budget_ms']):>9} "
              f"{yes(row['kernels_ms'] / 2 > row['budget_ms']):>8}  {largest(ms, 1)}",
              flush=True)
    for what, key in (("the whole one-thread encode", "x1_ms"), ("its kernels alone",
                                                                   "kernels_ms")):
        over = [r["file"] for r in rows if r[key] / 2 > r["budget_ms"]]
        print(f"{what}, split perfectly over two cores, over the 2x budget: {len(over)} of "
              f"{len(rows)}" + (f" ({', '.join(over)})" if over else ""))
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--files", nargs="+", default=DEFAULT_FILES,
                    help="names under the data folder, or all (default: stop 59's rows "
                         "below 2x)")
    ap.add_argument("--bound", type=bound_label, default="1mm",
                    help="default, or a length in mm such as 1mm (default 1mm)")
    ap.add_argument("--repeat", type=positive_int, default=9,
                    help="at least this many rounds of zstd, the two encodes and a profiled "
                         "one-thread encode (default 9)")
    ap.add_argument("--decode", action="store_true",
                    help="time mpz.decode against 0.1x zstd -19's decompression instead")
    ap.add_argument("--json", help="write the rows here")
    args = ap.parse_args(argv)
    status = cannot_run("bench_kernels")
    if status is not None:
        return status
    rows = run_decode(args) if args.decode else run(args)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
