"""Encoder regressions between two versions: the bytes of every real encode, and its time.

    python bench/bench_encode.py [--files all | NAME ...] [--bounds default,1mm,5mm]
                                 [--threads 1,2] --json OUT.json
    python bench/bench_encode.py --compare BEFORE.json ... --against AFTER.json ...

The first form encodes each file (a name under ../shared/data as bench_speed.py takes it,
or ``all``) at each bound ("default": the encoder's own; "1mm": 1 mm in the file's units,
1 unit where it declares none) with each thread count. It records the SHA-256 and size of
the bytes and the best wall time (bench_speed's ``timed``: at least 3 calls and 0.3 s).
The bytes must not depend on the thread count (issue 15): a row whose thread counts give
different bytes is printed as an ERROR, and the command exits 1; a results file it cannot
compare (not JSON, another bench's, malformed rows, two runs of one side that disagree)
exits 2 with the reason.

An encoder change that should not change the output is checked by the second form: run
the first with the old code (the Python of a venv where ``pip install -e`` put a ``git
worktree`` of the old commit: a ``PYTHONPATH`` of its folders mixes in the editable
install's new ``mpz.spec`` and ``mpz.tools``, README "Benchmarks") and with the new, in
turns, several times, because
the host's load moves short timings by more than most changes do. ``--compare`` then
prints each encode whose bytes changed, with its size before and after, and the time of
every encode before and after (each side's best over its runs), their geometric mean, and
the encodes that got more than 10 % slower. It exits 1 when some bytes changed (any
thread count's: each row keeps one digest per thread count, ``sha256_threads``, and every
one of them is compared), and when an encode is in one run set only or the sets share
none (a gate must not pass with nothing compared), so that a refactoring can be gated on
it; a change meant to alter the output says so in CHANGELOG.md with the sizes this prints.

The numba kernels are loaded first on the first file asked for (not timed). An absent or
empty data folder prints "skipped: ..." and exits 0.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import math
from pathlib import Path
import sys

from _common import (
    Unreadable,
    compare_main,
    is_bound_label,
    no_data_reason,
    shared_data_dir,
    two_versions,
    warm_up,
)

SCHEMA = 1


def measure(files: list[str], bounds: list[str], threads: list[int], out: Path) -> int:
    """Encode every file x bound x thread count; write the rows to ``out``. Returns 1 when
    the thread counts of a row gave different bytes, else 0."""
    from bench_speed import HAS_THREADS, bound_kwargs, files_of, timed
    import mpz
    import mpz.io
    root = shared_data_dir()
    assert root is not None
    paths = files_of(root, files)
    warm_up(paths[0])                                           # JIT warm-up, not timed
    rows: dict[str, dict] = {}
    status = 0
    # the ms columns: the best time with each thread count, in the order of --threads
    if not HAS_THREADS:                 # an mpz before issue 15 (0.1.0): said, and recorded
        print(f"note: this mpz ({mpz.__file__}) has no threads option: every thread count's "
              "column is one thread's encode", flush=True)
    print(f"{'encode':<48} {'bytes':>11}  ms " + " ".join(f"{f'{t} thr':>8}" for t in threads),
          flush=True)
    for path in paths:
        m = mpz.io.read(path)
        for bound in bounds:
            kw, _, desc = bound_kwargs(m, bound)
            key = f"{path.relative_to(root)} {bound}"
            row: dict = {"bound": desc, "seconds": {}, "sha256_threads": {},
                         "bytes_threads": {}}
            for t in threads:
                # an mpz before the threads option (0.1.0) encodes with one: the same
                # call for every count (its columns are then one thread's)
                tk = {"threads": t} if HAS_THREADS else {}
                data = mpz.encode(m, **tk, **kw)
                row["sha256_threads"][str(t)] = hashlib.sha256(data).hexdigest()
                row["bytes_threads"][str(t)] = len(data)
                row["seconds"][str(t)], _ = timed(
                    lambda m=m, kw=kw, tk=tk: mpz.encode(m, **tk, **kw), 3)
            outputs = set(row["sha256_threads"].values())
            # sha256, bytes: the first thread count's (every one's is in *_threads)
            first = str(threads[0])
            row.update(sha256=row["sha256_threads"][first], bytes=row["bytes_threads"][first])
            rows[key] = row
            times = " ".join(f"{row['seconds'][str(t)] * 1e3:8.2f}" for t in threads)
            flag = ""
            if len(outputs) > 1:
                status = 1
                flag = f"  ERROR: {len(outputs)} different outputs for threads {threads}"
            print(f"{key:<48} {row['bytes']:>9} B  ms {times}{flag}", flush=True)
    out.write_text(json.dumps({"bench": "encode", "schema": SCHEMA, "mpz": mpz.__file__,
                               "threads": threads, "threads_option": HAS_THREADS,
                               "rows": rows}, indent=1))
    return status


def load(path: Path) -> dict[str, dict]:
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise Unreadable(f"{path}: cannot read it as JSON: {exc}") from None
    if not isinstance(doc, dict) or doc.get("bench") != "encode" or doc.get("schema") != SCHEMA:
        raise Unreadable(f"{path}: not a bench_encode.py result of schema {SCHEMA}")
    rows = doc.get("rows")
    if not isinstance(rows, dict) or not all(
            isinstance(r, dict) and isinstance(r.get("sha256"), str)
            and isinstance(r.get("bytes"), int) and isinstance(r.get("seconds"), dict)
            and r["seconds"] for r in rows.values()):
        raise Unreadable(f"{path}: malformed rows (each wants sha256, bytes and seconds)")
    return rows


def digests(row: dict) -> dict[str, str]:
    """A row's digest per thread count (``sha256_threads``), or its one ``sha256`` under
    ``"*"`` for a row written before the thread counts were kept apart."""
    per = row.get("sha256_threads")
    return dict(per) if isinstance(per, dict) and per else {"*": row["sha256"]}


def sizes(row: dict) -> dict[str, int]:
    per = row.get("bytes_threads")
    return dict(per) if isinstance(per, dict) and per else {"*": row["bytes"]}


def best_times(runs: list[dict[str, dict]]) -> dict[str, float]:
    """Each encode's best time over the runs and its thread counts (the fastest, as
    bench_speed's verdict takes it)."""
    return {k: min(min(r[k]["seconds"].values()) for r in runs if k in r) for k in runs[0]}


def differences(before: list[dict[str, dict]], after: list[dict[str, dict]]
                ) -> tuple[list[tuple[str, int, int]], list[str]]:
    """(encodes whose bytes differ: key, bytes before, bytes after; encodes on one side
    only, each with the side it is on). An encode differs when its digests over both
    sides and every thread count are not all one: changed bytes, or a thread count that
    gives other bytes than the rest (issue 15) on either side. A side's runs must agree
    on the bytes: a run of a side that disagrees with its first run is an error."""
    for side in (before, after):
        for run in side[1:]:
            for k, row in run.items():
                if k in side[0] and digests(row) != digests(side[0][k]):
                    raise Unreadable(f"{k}: two runs of the same side gave different bytes")
    b, a = before[0], after[0]
    changed = []
    for k in b:
        if k in a and len(set(digests(b[k]).values()) | set(digests(a[k]).values())) > 1:
            changed.append((k, b[k]["bytes"], a[k]["bytes"]))
    alone = [f"{k} (before only)" for k in sorted(set(b) - set(a))]
    alone += [f"{k} (after only)" for k in sorted(set(a) - set(b))]
    return changed, alone


def compare(before_paths: list[Path], after_paths: list[Path]) -> int:
    before = [load(p) for p in before_paths]
    after = [load(p) for p in after_paths]
    changed, alone = differences(before, after)
    tb, ta = best_times(before), best_times(after)
    keys = [k for k in before[0] if k in after[0]]
    print(f"{'encode':<48} {'ms before':>10} {'after':>8} {'change':>7}")
    for k in keys:
        print(f"{k:<48} {tb[k] * 1e3:>10.2f} {ta[k] * 1e3:>8.2f} "
              f"{100 * (ta[k] / tb[k] - 1):>+6.1f}%")
    geo = math.exp(sum(math.log(ta[k] / tb[k]) for k in keys) / len(keys)) if keys else 1.0
    slower = [k for k in keys if ta[k] > 1.10 * tb[k]]
    print(f"time after / before, geometric mean of {len(keys)} encodes: {geo:.3f}; "
          f"more than 10 % slower: {', '.join(slower) if slower else 'none'}")
    for k in alone:
        print(f"only on one side: {k}")
    status = 0
    if not keys:
        print("bytes: no encode in both run sets: nothing compared")
        status = 1
    elif not changed:
        print(f"bytes: all {len(keys)} encodes identical")
    else:
        status = 1
        print(f"bytes: {len(changed)} of {len(keys)} encodes changed:")
        for k, nb, na in changed:
            print(f"  {k:<46} {nb:>9} -> {na:>9} B ({100 * (na / nb - 1):+.2f} %)")
            for side, row in (("before", before[0][k]), ("after", after[0][k])):
                d, n = digests(row), sizes(row)
                if len(set(d.values())) > 1:
                    print(f"    {side}: the thread counts disagree: " + ", ".join(
                        f"{t} thread(s) {n.get(t, '?')} B {h[:12]}" for t, h in d.items()))
    if alone:
        status = 1
        print(f"FAIL: {len(alone)} encode(s) on one side only: {', '.join(alone)}")
    return status


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--files", nargs="+", default=["all"])
    ap.add_argument("--bounds", default="default,1mm,5mm",
                    help="comma-separated: default, or a length in mm such as 1mm")
    ap.add_argument("--threads", default="1,2", help="comma-separated thread counts")
    args = two_versions(ap, argv)
    if args.compare:
        return compare_main(lambda: compare(args.compare, args.against))
    try:
        threads = [int(t) for t in args.threads.split(",")]
    except ValueError:
        ap.error(f"--threads wants whole numbers such as 1,2, got {args.threads!r}")
    if any(t < 1 for t in threads):
        ap.error("--threads wants counts of 1 or more")
    bounds = args.bounds.split(",")
    for b in bounds:
        if not is_bound_label(b):
            ap.error(f"--bounds wants default or lengths in mm such as 1mm, got {b!r}")
    reason = no_data_reason()
    if reason:
        print(f"skipped: {reason}")
        return 0
    return measure(args.files, bounds, threads, args.json)


if __name__ == "__main__":
    sys.exit(main())
