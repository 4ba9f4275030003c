"""Decode speed of every real file, and two runs compared: for decoder changes.

    python bench/bench_decode.py [--files all | NAME ...] [--bound 1mm] --json OUT.json
    python bench/bench_decode.py --compare BEFORE.json ... --against AFTER.json ...

The first form encodes each file once at 1 mm (1 unit where the file declares no units)
with one thread and times ``mpz.decode`` of the bytes: the best of at least 5 calls and
0.3 s (bench_speed's ``timed``), in MB/s of bench_speed's yardstick (every sample MPZ
codes, as float32). It prints one row per file and writes them as JSON.

Decoder changes move the figures by less than the machine's noise from one process to the
next, so compare several runs of each version made alternately: run the first form with
the old code (``PYTHONPATH=OLD/reference:OLD/spec`` from a ``git worktree`` of the old
commit) and the new, in turns, then ``--compare`` takes each file's best over the old
runs and over the new, and prints the table: ms and MB/s before and after, the geometric
mean of the rows, the files together, and the rows below 20 MB/s (issue 4's decode line).
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
import sys

from _common import coded_float32, shared_data_dir, two_versions


def measure(files: list[str], bound: str, out: Path) -> None:
    from bench_speed import bound_kwargs, files_of, find, timed
    import mpz
    import mpz.io
    root = shared_data_dir()
    if root is None:
        raise SystemExit("no ../shared/data beside the repository: nothing to measure")
    warm = mpz.io.read(find(root, "c3d/cmu_02_01")).select_frames(0, 50)
    mpz.decode(mpz.encode(warm, max_error=1.0))                 # JIT warm-up
    rows = {}
    for path in files_of(root, files):
        m = mpz.io.read(path)
        kw, _, desc = bound_kwargs(m, bound)
        data = mpz.encode(m, threads=1, **kw)
        mb = len(coded_float32(m)) / 1e6
        sec, _ = timed(lambda data=data: mpz.decode(data), 5)
        rows[path.name] = {"mb": mb, "sec": sec, "bound": desc, "mpz": mpz.__file__}
        print(f"{path.name:<42} {mb:>6.3f} MB {sec * 1e3:>8.2f} ms {mb / sec:>7.1f} MB/s",
              flush=True)
    out.write_text(json.dumps(rows, indent=1))


def compare(before: list[Path], after: list[Path]) -> None:
    def best(paths: list[Path]) -> dict[str, tuple[float, float]]:
        runs = [json.loads(p.read_text()) for p in paths]
        return {k: (runs[0][k]["mb"], min(r[k]["sec"] for r in runs)) for k in runs[0]}
    b, a = best(before), best(after)
    names = sorted(set(b) & set(a), key=lambda k: b[k][0])
    print(f"{'file':<42} {'MB':>6} {'ms before':>10} {'after':>8} {'MB/s before':>12} "
          f"{'after':>7}")
    for k in names:
        mb, tb = b[k]
        ta = a[k][1]
        print(f"{k:<42} {mb:>6.3f} {tb * 1e3:>10.2f} {ta * 1e3:>8.2f} {mb / tb:>12.1f} "
              f"{mb / ta:>7.1f}")
    n = len(names)
    for label, t in (("before", b), ("after", a)):
        geo = math.exp(sum(math.log(t[k][0] / t[k][1]) for k in names) / n)
        tot = sum(t[k][0] for k in names) / sum(t[k][1] for k in names)
        slow = [k for k in names if t[k][0] / t[k][1] < 20]
        print(f"{label}: geometric mean {geo:.1f} MB/s; together {tot:.1f} MB/s; "
              f"{len(slow)} of {n} rows below 20 MB/s" + (f" ({', '.join(slow)})" if slow else ""))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--files", nargs="+", default=["all"])
    ap.add_argument("--bound", default="1mm")
    args = two_versions(ap, argv)
    if args.compare:
        compare(args.compare, args.against)
    else:
        measure(args.files, args.bound, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
