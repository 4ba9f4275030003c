"""``mpz search QUERY --index INDEX``: indexed files ranked by motion similarity.

Contract: the index (``OUT/index.sqlite``, written by ``mpz encode -r FOLDER -o OUT/``) holds
a Fisher summary and a descriptor per file (:mod:`mpz.similarity`); no motion is decoded.
``QUERY`` is

* a capture file (C3D, TRC, BVH, AMC, NPY, CSV): it is read and summarised as the corpus
  summarised its files (same levels, same rule for long captures);
* an ``.mpz`` file: if its ``meta`` chunk names a source (sha256) that the index holds,
  that row's stored summary is the query; otherwise its ``smry`` chunk (``mpz encode
  --summary``). Its motion is never decoded.

Files are ranked by the Euclidean distance of their standardised descriptors; ties go to
a byte-identical source (marked ``=``), then to the output name. ``--json`` prints schema
``mpz-search/1``.

Exit codes: 0 ok; 2 errors (no index, unreadable query, nothing to compare); 64 usage.
"""
from __future__ import annotations

import argparse
import os
import sys
from typing import TYPE_CHECKING, Any

from mpz.errors import EncoderError
from mpz.tools._cli import EXIT_OK, count

if TYPE_CHECKING:
    from mpz.similarity import MotionSummary

JSON_SCHEMA = "mpz-search/1"


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p = sub.add_parser("search", help="rank the files of a corpus index by motion similarity",
                       description="Rank the files of a corpus index (OUT/index.sqlite from "
                       "mpz encode -r) by motion similarity to QUERY, from their Fisher "
                       "summaries; nothing is decoded.")
    p.add_argument("query", help="a capture file (.c3d, .trc, .bvh, .amc, .npy, .csv) or "
                   ".mpz, or - for standard input (its format found from its content)")
    p.add_argument("--index", required=True, metavar="INDEX",
                   help="the index file, or the folder that holds index.sqlite")
    p.add_argument("-n", "--top", type=count, default=10, metavar="N",
                   help="show the N nearest files (default 10; 0 for all)")
    p.add_argument("--asf", help="skeleton for an .amc query (default: found beside it)")
    p.add_argument("--json", action="store_true", help="print JSON (schema mpz-search/1)")
    p.set_defaults(func=run)
    return p


def query_summary(path: str, rows: list[dict[str, Any]], levels: tuple[int, ...],
                  asf: str | None = None) -> tuple[MotionSummary, str | None, str]:
    """The query's summary, the sha256 of its source (if known) and where the summary came from.

    ``rows`` are the index's rows, each with its summary under ``"_summary"`` when the
    query is an .mpz file.

    Raises
    ------
    MPZError
        For an unreadable or undecodable query.
    """
    from mpz.corpus import sha256_file
    from mpz.similarity import summarize
    from mpz.tools._common import STDIO
    if path == STDIO:                        # its format from its content, as everywhere
        import hashlib

        from mpz.io import read_bytes
        from mpz.tools._common import read_stdin
        data, fmt = read_stdin()
        if fmt == ".mpz":
            return _mpz_query(data, rows, levels)
        s = summarize(read_bytes(data, fmt=fmt, name=STDIO, asf=asf), levels)
        return s, hashlib.sha256(data).hexdigest(), f"the capture ({s.method})"
    if path.lower().endswith(".mpz"):
        from mpz.api import read_source
        data, _ = read_source(path)          # a regular file of at most 4 GiB (QA: FIFOs)
        return _mpz_query(data, rows, levels)
    from mpz.io import read
    try:
        sha = sha256_file(path)
    except OSError as exc:
        raise EncoderError(f"cannot read: {exc.strerror or exc}", path=path) from None
    s = summarize(read(path, asf=asf), levels)
    return s, sha, f"the capture ({s.method})"


def _mpz_query(data: bytes, rows: list[dict[str, Any]], levels: tuple[int, ...]
               ) -> tuple[MotionSummary, str | None, str]:
    """:func:`query_summary` of an MPZ file's bytes."""
    from mpz.api import read_summary
    from mpz.corpus import META_SHA256
    from mpz.decoder import read_stream
    from mpz.similarity import from_smry, summarize
    stream = read_stream(data)
    sha = stream.meta.get(META_SHA256)
    for r in rows:
        if sha is not None and r["source_sha256"] == sha:
            return r["_summary"], sha, "the index's row of its source"
    smry = read_summary(data)
    frames = stream.header.frame_count
    need = {k for k in levels if k <= frames}
    have = set() if smry is None else {int(lv.k) for lv in smry.levels}
    if smry is not None and smry.space == "positions" and need <= have:
        return from_smry(smry), sha, "its summary chunk"
    # its own levels are not the index's (ev_k would come from other k: its source ranked
    # second, a QA run), or it has none: the summary of its decoded motion, as a capture's
    from mpz.tools._common import read_mpz_input_bytes
    why = ("no summary chunk" if smry is None else
           "a summary of joint angles" if smry.space != "positions" else
           f"summary levels k = {', '.join(map(str, sorted(have)))}, not the index's "
           f"{', '.join(map(str, sorted(need)))}")
    s = summarize(read_mpz_input_bytes(data), levels)
    return s, sha, f"its decoded motion ({s.method}; the file holds {why})"


def run(args: argparse.Namespace) -> int:
    from mpz.corpus import open_index
    from mpz.similarity import descriptor, features_for, rank
    from mpz.tools._cli import print_json, printable

    with open_index(args.index) as index:
        levels = index.levels()
        values, table = index.descriptors()
        # an .mpz query may be found by its source's row; standard input may be one
        need_summaries = args.query == "-" or args.query.lower().endswith(".mpz")
        if need_summaries:
            by_out = {r["output"]: r.summary for r in index.rows()}
            for v in values:
                v["_summary"] = by_out[v["output"]]
        index_path = index.path
    if not values:
        raise EncoderError("the index holds no files", path=index_path)
    summary, sha, origin = query_summary(args.query, values, levels, args.asf)
    q = descriptor(summary, levels)
    same = [v["source_sha256"] == sha for v in values]
    order, dist = rank(q, table, identical=same, names=[v["output"] for v in values])
    shown = order if args.top == 0 else order[:args.top]
    results = [{"rank": n + 1, "distance": float(dist[i]), "identical": bool(same[i]),
                "output": values[i]["output"], "path": values[i]["path"],
                "frames": values[i]["frames"], "rate": values[i]["rate"],
                "duration_s": values[i]["duration_s"], "markers": values[i]["markers"],
                "units": values[i]["units"] or None, "format": values[i]["format"]}
               for n, i in enumerate(shown)]
    query = {"file": args.query, "frames": summary.n_frames, "rate": summary.rate,
             "dims": summary.dims, "summary": origin, "levels": list(summary.level_ks()),
             "sha256": sha}
    if args.json:
        print_json({"schema": JSON_SCHEMA, "index": index_path, "query": query,
                    "features": list(features_for(levels)),
                    "descriptor": [float(v) for v in q], "candidates": len(values),
                    "results": results})
        return EXIT_OK
    secs = summary.n_frames / summary.rate
    print(f"query {printable(args.query)}: {summary.n_frames} frames, {secs:.2f} s, "
          f"{summary.dims // 3} markers; summary from {origin}")
    print(f"{len(values)} files in {printable(index_path)}; nearest first "
          "(= marks a byte-identical source)")
    print(f"{'rank':>4} {'distance':>9} {'frames':>7} {'secs':>7} {'markers':>7}  file")
    for r in results:
        mark = "=" if r["identical"] else " "
        print(f"{r['rank']:>4} {r['distance']:>9.3f} {r['frames']:>7} {r['duration_s']:>7.2f} "
              f"{r['markers']:>7} {mark}{printable(os.path.relpath(r['path']))}")
    return EXIT_OK


def main(argv: list[str] | None = None) -> int:
    """Run ``mpz search`` on its own (same options and exit codes)."""
    from mpz.tools.mpz_cli import main as mpz_main
    return mpz_main(["search", *(sys.argv[1:] if argv is None else argv)])
