"""Whole archives on Dask (issue 15.3-15.5): corpus throughput, memory per worker, search.

    python bench/bench_corpus.py [--quick] [--long] [--workers 0,1,2,4] [--json OUT.json]

1. The developer set (every capture of ../shared/data, 29 files) encoded by
   :func:`mpz.corpus.encode_corpus` at a 1 mm bound (files without units: the encoder's
   default bound, as ``mpz encode`` gives them) with
   0 workers (in this process, no Dask), then LocalClusters of 1, 2 and 4 worker processes
   (4 on this 2-core machine shows what oversubscription does). Wall time includes
   starting the cluster; files/s and MB/s of float32 positions and of source bytes; the
   summed CPU seconds of the workers; then an incremental re-run (all up to date: nothing
   is encoded, so its MB/s f32 is "-" and its MB/s src is the source bytes checked).
2. Throughput against corpus size on 2 workers: 4, 8, 16, 29 and 58 files (58 = the set
   twice, under other names).
3. ``--long``: a 30-minute capture (cmu_135_02 tiled 42 times: 218,484 frames x 41
   markers, 107 MB of float32) on one worker under the default memory limit: wall time
   and the worker's peak resident memory.
4. Search on the index of (1): self-retrieval from each capture, and precision on the
   labels the developer set allows (docs/corpus.md).

The machine is shared: the load average is printed with each table, and CPU seconds are
given beside wall seconds. ``--json OUT`` writes every number measured (with ``--only-ab``
too). An absent or empty data folder prints "skipped: ..." and exits 0.
"""
from __future__ import annotations

import argparse
from dataclasses import dataclass
import json
import os
from pathlib import Path
import shutil
import sys
import tempfile
import time

import numpy as np

from _common import no_data_reason, shared_data_dir
from mpz.corpus import DEFAULT_MEMORY_LIMIT, encode_corpus, open_index
from mpz.encoder import EncodeOptions
from mpz.format import MM_PER_UNIT
from mpz.similarity import rank


@dataclass(frozen=True)
class BoundMM:
    """A bound in millimetres, converted to each file's units; a file without units gets
    the encoder's default bound."""

    mm: float

    def __call__(self, units: str) -> EncodeOptions:
        if units not in MM_PER_UNIT:
            return EncodeOptions()
        return EncodeOptions(max_error=self.mm / MM_PER_UNIT[units])


OPTIONS = BoundMM(1.0)

#: labels the developer set allows (SOURCES.md descriptions): one class per file at most
CLASSES = {
    "walk": ["c3d/cmu_02_01.c3d", "amc/02_01.amc", "amc/35_01.amc",
             "trc/opensim_subject01_walk1.trc", "c3d/c3dorg_Eb015pi.c3d",
             "c3d/c3dorg_Eb015vr.c3d", "c3d/c3dorg_Eb015sr.c3d",
             "c3d/c3dorg_codamotion_gaitwands_20150204.c3d",
             "c3d/auckland_FMC_MH0222_BP06.c3d"],
    "run": ["trc/opensim_hamner_subject02_running.trc", "trc/btk_SprintMotion.trc"],
    "kick": ["bvh/cmu_10_01.bvh", "bvh/cmu_11_01.bvh"],
    "jump": ["c3d/cmu_01_01.c3d", "c3d/c3dorg_Sample_Jump2.c3d"],
}
#: the same take in two or three encodings
SAME_TAKE = [("c3d/cmu_02_01.c3d", "amc/02_01.amc"),
             ("c3d/HDM_dg_06-03_03_120.c3d", "amc/HDM_dg_06-03_03_120.amc"),
             ("c3d/c3dorg_Eb015pi.c3d", "c3d/c3dorg_Eb015vr.c3d"),
             ("c3d/c3dorg_Eb015pi.c3d", "c3d/c3dorg_Eb015sr.c3d")]


def load() -> str:
    try:
        return "load {:.1f} {:.1f} {:.1f}".format(*os.getloadavg())
    except OSError:
        return "load unknown"


def captures(data: Path) -> list[Path]:
    from mpz.io import READERS
    return sorted(p for p in data.rglob("*") if p.suffix.lower() in READERS)


def jobs_for(files: list[Path], out: Path, tag: str = "") -> list[tuple[str, str]]:
    return [(str(p), str(out / f"{p.parent.name}{tag}" / f"{p.stem}.mpz")) for p in files]


def run(files_jobs: list[tuple[str, str]], out: Path, workers: int, *, force: bool = True,
        memory_limit: str = DEFAULT_MEMORY_LIMIT) -> dict:
    t = time.perf_counter()
    rep = encode_corpus(files_jobs, out, OPTIONS, workers=workers, force=force,
                        memory_limit=memory_limit)
    wall = time.perf_counter() - t
    done = [r for r in rep.results if r.status in ("encoded", "kept")]
    raw = sum(r.raw_bytes for r in done)
    src = sum(r.source_bytes for r in rep.results)
    return {"workers": workers, "files": len(rep.results), "failed": len(rep.failed),
            "skipped": rep.count("skipped"), "wall_s": wall, "files_per_s": len(rep.results) / wall,
            "raw_mb": raw / 1e6, "source_mb": src / 1e6, "raw_mb_per_s": raw / 1e6 / wall,
            "source_mb_per_s": src / 1e6 / wall, "mpz_mb": sum(r.output_bytes for r in done) / 1e6,
            "cpu_s": sum(r.cpu_seconds for r in done), "task_wall_s": sum(r.seconds for r in done),
            "peak_rss_mb": max((r.worker_peak_rss or 0 for r in rep.results), default=0) / 2**20,
            "cluster": rep.cluster, "load": load(),
            "failures": [(r.source, r.reason) for r in rep.failed]}


def show(rows: list[dict], first: str) -> None:
    # busy: tasks running at once on average (sum of task wall times / wall time)
    print(f"{first:>8} {'files':>6} {'wall s':>8} {'files/s':>8} {'MB/s f32':>9} "
          f"{'MB/s src':>9} {'CPU s':>7} {'busy':>5} {'peak MB':>8}  {'load'}")
    for r in rows:
        key = r.get("label", r["workers"])
        busy = r["task_wall_s"] / r["wall_s"] if r["wall_s"] else 0.0
        # nothing encoded (an up-to-date re-run): no float32 rate to give
        f32 = "-" if r["raw_mb"] == 0 and r["skipped"] else f"{r['raw_mb_per_s']:.2f}"
        print(f"{key!s:>8} {r['files']:>6} {r['wall_s']:>8.1f} {r['files_per_s']:>8.2f} "
              f"{f32:>9} {r['source_mb_per_s']:>9.2f} {r['cpu_s']:>7.1f} "
              f"{busy:>5.2f} {r['peak_rss_mb']:>8.0f}  {r['load']}")
        for src, why in r["failures"]:
            print(f"         FAILED {src}: {why}")


def _class_scores(rel: list[str], ranked: dict[str, list[str]], n: int) -> dict | None:
    """R-precision and mean average precision of the class ``rel`` (its members' ranked
    lists of the other ``n - 1`` files in ``ranked``), and the chance level; None when the
    class has fewer than two members."""
    r = len(rel) - 1
    if r < 1:
        return None
    precisions, aps = [], []
    for q in rel:
        hits = [o in rel for o in ranked[q]]
        precisions.append(sum(hits[:r]) / r)
        found, ap = 0, 0.0
        for k, h in enumerate(hits, 1):
            if h:
                found += 1
                ap += found / k
        aps.append(ap / r)
    return {"files": len(rel), "r_precision": float(np.mean(precisions)),
            "map": float(np.mean(aps)), "chance": r / (n - 1)}


def search_quality(out: Path, data: Path) -> dict:
    """Self-retrieval and precision from the index's stored descriptors (no decoding)."""
    with open_index(out) as ix:
        values, table = ix.descriptors()
    names = [str(Path(v["path"]).relative_to(data.resolve())) for v in values]
    label = {f: c for c, fs in CLASSES.items() for f in fs}
    result: dict = {"files": len(names), "self_first": 0, "classes": {}, "same_take": []}
    ranked = {}
    for i, n in enumerate(names):
        same = [v["source_sha256"] == values[i]["source_sha256"] for v in values]
        order, dist = rank(table[i], table, identical=same, names=[v["output"] for v in values])
        result["self_first"] += int(order[0] == i)
        ranked[n] = [names[j] for j in order if j != i]
    for c, members in CLASSES.items():
        scores = _class_scores([m for m in members if m in names], ranked, len(names))
        if scores is not None:     # None: fewer than two of the class in this data folder
            result["classes"][c] = scores
    # the walk class with the Eb015 triplet counted once (vr, sr left out of the candidates)
    drop = {"c3d/c3dorg_Eb015vr.c3d", "c3d/c3dorg_Eb015sr.c3d"}
    rel = [m for m in CLASSES["walk"] if m not in drop and m in names]
    if len(rel) > 1 and drop <= set(names) and len(names) > 3:
        once = {q: [o for o in ranked[q] if o not in drop] for q in rel}
        scores = _class_scores(rel, once, len(names) - 2)
        assert scores is not None
        result["classes"]["walk (Eb015 once)"] = {**scores, "map": None}   # as first shown
    # every class counted in distinct takes: the second encoding of each take of SAME_TAKE
    # (CMU 02_01's AMC, HDM's AMC, Eb015 vr and sr) is neither a query nor a candidate, so
    # that a take does not find its own other encoding as a hit (a QA run of stop 61)
    again = {b for _, b in SAME_TAKE}
    distinct = {n: [o for o in ranked[n] if o not in again] for n in names if n not in again}
    for c, members in CLASSES.items():
        scores = _class_scores([m for m in members if m in distinct], distinct, len(distinct))
        if scores is not None:
            result["classes"][f"{c} (distinct takes)"] = scores
    for a, b in SAME_TAKE:
        if a not in ranked or b not in ranked:
            continue
        result["same_take"].append({"query": a, "other": b, "rank": ranked[a].index(b) + 1,
                                    "rank_back": ranked[b].index(a) + 1})
    label_of = {n: label.get(n, "-") for n in names}
    result["nearest"] = {n: ranked[n][:3] for n in names}
    result["labels"] = label_of
    return result


def make_long(path: Path, data: Path) -> None:
    import mpz
    from mpz.io import read, write
    m = read(data / "c3d" / "cmu_135_02.c3d")
    reps = 42
    long = mpz.Motion(np.concatenate([m.positions] * reps), m.names, m.rate, m.units,
                      valid=np.concatenate([m.valid] * reps))
    write(long, path)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true", help="fewer runs: 0 and 2 workers, sizes "
                   "4, 8, 16")
    p.add_argument("--long", action="store_true", help="also the 30-minute capture")
    p.add_argument("--ab", action="store_true", help="also 1 against 2 workers, alternated")
    p.add_argument("--only-ab", action="store_true", help="only the 1 against 2 comparison")
    p.add_argument("--workers", default=None, help="comma-separated worker counts "
                   "(default 0,1,2,4)")
    p.add_argument("--json", metavar="OUT", help="write every number as JSON")
    args = p.parse_args(argv)
    reason = no_data_reason()
    if reason:
        print(f"skipped: {reason}")
        return 0
    data = shared_data_dir()
    assert data is not None
    files = captures(data)
    counts = [int(w) for w in (args.workers or ("0,2" if args.quick else "0,1,2,4")).split(",")]
    report: dict = {"workers": [], "sizes": [], "long": None, "search": None}
    tmp = Path(tempfile.mkdtemp(prefix="mpz-bench-corpus-"))
    try:
        # warm the numba caches in this process (workers load them from disk)
        run(jobs_for(files[:1], tmp / "warm"), tmp / "warm", 0)
        if args.only_ab:
            args.ab, args.long, counts, sizes = True, False, [], []
        else:
            sizes = [4, 8, 16] if args.quick else [4, 8, 16, 29, 58]
        if counts:
            print(f"1. the developer set: {len(files)} captures, "
                  f"{sum(f.stat().st_size for f in files) / 1e6:.1f} MB of source files, "
                  "1 mm bound")
        for w in counts:
            out = tmp / f"w{w}"
            report["workers"].append(run(jobs_for(files, out), out, w))
        if counts:
            again = run(jobs_for(files, tmp / f"w{counts[-1]}"), tmp / f"w{counts[-1]}",
                        counts[-1], force=False)
            again["label"] = "re-run"
            report["workers"].append(again)
            show(report["workers"], "workers")

        if sizes:
            print("\n2. throughput against corpus size, 2 workers")
        order = [files[i] for i in np.random.default_rng(0).permutation(len(files))]
        for n in sizes:
            out = tmp / f"n{n}"
            jobs = jobs_for(order[:min(n, len(order))], out)
            if n > len(order):   # the set again, under other output names
                jobs += jobs_for(order[:n - len(order)], out, tag="-copy")
            row = run(jobs, out, 2)
            row["label"] = n
            report["sizes"].append(row)
        if sizes:
            show(report["sizes"], "files")

        if args.long:
            print("\n3. a 30-minute capture on 1 worker "
                  f"(memory limit {DEFAULT_MEMORY_LIMIT})")
            src = tmp / "long" / "long30.c3d"
            src.parent.mkdir()
            make_long(src, data)
            row = run([(str(src), str(tmp / "long-out" / "long30.mpz"))], tmp / "long-out", 1)
            row["label"] = "30 min"
            report["long"] = row
            show([row], "capture")

        if args.ab:
            print("\n5. 1 against 2 workers, alternated 3 times on 8 equal synthetic files "
                  "(walk, 2,400 frames x 41 markers, TRC); the ratio of each pair")
            from mpz.io import write
            from mpz.synth import generate
            syn = tmp / "syn"
            syn.mkdir()
            for i in range(8):
                write(generate("walk", frames=2400, seed=i), syn / f"walk{i}.trc")
            pairs = []
            syn_files = sorted(syn.glob("*.trc"))
            for k in range(3):
                one = run(jobs_for(syn_files, tmp / f"a{k}"), tmp / f"a{k}", 1)
                two = run(jobs_for(syn_files, tmp / f"b{k}"), tmp / f"b{k}", 2)
                one["label"], two["label"] = f"1 #{k + 1}", f"2 #{k + 1}"
                pairs += [one, two]
            report["ab"] = pairs
            show(pairs, "workers")
            ratios = [pairs[i]["wall_s"] / pairs[i + 1]["wall_s"] for i in range(0, 6, 2)]
            print("speed-up of 2 workers over 1, per pair: "
                  + ", ".join(f"{r:.2f}" for r in ratios))

        if counts:
            search(report, tmp / f"w{counts[0]}", data)
        if args.json:
            Path(args.json).write_text(json.dumps(report, indent=1))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


def search(report: dict, index: Path, data: Path) -> None:
    """(4): search quality on the index of (1), printed and put in ``report``."""
    print("\n4. search from the index of (1): no motion decoded")
    q = search_quality(index, data)
    report["search"] = q
    print(f"self-retrieval: {q['self_first']}/{q['files']} captures rank their own file "
          "first")
    print(f"{'class':<24} {'files':>5} {'R-prec':>7} {'MAP':>6} {'chance':>7}")
    for c, v in q["classes"].items():
        mp = "-" if v["map"] is None else f"{v['map']:.2f}"
        print(f"{c:<24} {v['files']:>5} {v['r_precision']:>7.2f} {mp:>6} "
              f"{v['chance']:>7.2f}")
    print("same take, rank of the other encoding among the other files (1 = nearest):")
    for s in q["same_take"]:
        print(f"  {s['query']} -> {s['other']}: {s['rank']}; back: {s['rank_back']}")


if __name__ == "__main__":
    sys.exit(main())
