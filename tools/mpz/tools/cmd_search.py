"""``mpz search QUERY --index INDEX``: indexed files ranked by motion similarity.

Contract: the index (``OUT/index.sqlite``, written by ``mpz encode -r FOLDER -o OUT/``) holds
a Fisher summary and a descriptor per file (:mod:`mpz.similarity`); no indexed file is
decoded.
``QUERY`` is

* a capture file (C3D, TRC, BVH, AMC, NPY, CSV): it is read and summarised as the corpus
  summarised its files (same levels, same rule for long captures);
* an ``.mpz`` file: if its ``meta`` chunk names a source (sha256) that the index holds,
  that row's stored summary is the query; otherwise its summary chunk (``mpz encode
  --summary``), when it has the index's levels and summarises what the index's summaries
  do (no marker valid in fewer than :data:`mpz.similarity.MIN_VALID_SHARE` of the frames,
  which they leave out); otherwise its decoded motion, summarised as a capture's, and
  the result says which.

Files are ranked by the Euclidean distance of their standardised descriptors; ties go to
a byte-identical source (marked ``=``), then to the output name. Each result names its
``.mpz`` (relative to the index's folder) and its source, and says when either is no
longer there. ``--json`` prints schema ``mpz-search/1`` (docs/corpus.md lists its fields).

A query the descriptor cannot describe (one frame, no valid sample, fewer than three
markers) is refused. ``--rate HZ`` gives the rate of an AMC or NPY query, which stores
none (a note says when it is assumed); ``--asf`` the skeleton of an AMC query.

Exit codes: 0 ok; 1 a result's ``.mpz`` is gone (warnings only); 2 errors (no index, a
damaged or foreign index, an unreadable or undescribable query, nothing to compare, an
option that does not apply to the query); 64 usage.
"""
from __future__ import annotations

import argparse
from collections.abc import Callable
import os
import stat
import sys
from typing import TYPE_CHECKING, Any

from mpz.errors import EncoderError, MPZError
from mpz.tools._cli import EXIT_OK, EXIT_WARN, count, found, positive

if TYPE_CHECKING:
    from mpz.motion import Motion
    from mpz.similarity import MotionSummary

JSON_SCHEMA = "mpz-search/1"
#: the index's stored summary of the row whose source has a sha256, or None
SourceSummary = Callable[[str], "MotionSummary | None"]


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p = sub.add_parser("search", help="rank the files of a corpus index by motion similarity",
                       description="Rank the files of a corpus index (OUT/index.sqlite from "
                       "mpz encode -r) by motion similarity to QUERY, from their stored "
                       "Fisher summaries; no indexed file is decoded.")
    p.add_argument("query", help="a capture file (.c3d, .trc, .bvh, .amc, .npy, .csv) or "
                   ".mpz, or - for standard input (its format found from its content)")
    p.add_argument("--index", required=True, metavar="INDEX",
                   help="the index file, or the folder that holds index.sqlite")
    p.add_argument("-n", "--top", type=count, default=10, metavar="N",
                   help="show the N nearest files (default 10; 0 for all)")
    p.add_argument("--asf", metavar="FILE.asf",
                   help="skeleton for an .amc query (default: found beside it; needed for "
                   "an AMC on standard input); an error for any other query")
    p.add_argument("--rate", metavar="HZ", type=positive,
                   help="the frame rate of a query that stores none (AMC: 120 Hz is "
                   "assumed, NPY: 1 Hz), e.g. --rate 120; an error for a query that has one")
    from mpz.tools._cli import max_samples, max_samples_help
    p.add_argument("--max-samples", type=max_samples, default=None, metavar="N",
                   help=max_samples_help("an .mpz query whose summary chunk cannot serve "
                                         "(other levels, a marker the index leaves out) is "
                                         "decoded and segmented, about 130 bytes per "
                                         "marker-frame") + "; .mpz query only, an error "
                   "for any other")
    p.add_argument("--json", action="store_true", help="print JSON (schema mpz-search/1)")
    p.set_defaults(func=run)
    return p


def query_summary(path: str, source_summary: SourceSummary, levels: tuple[int, ...],
                  asf: str | None = None, *, rate: float | None = None,
                  notes: list[str] | None = None, warnings: list[str] | None = None,
                  max_samples: int | None = None) -> tuple[MotionSummary, str | None, str]:
    """The query's summary, the sha256 of its source (if known) and where the summary came from.

    ``source_summary(sha)`` is the index's stored summary of the row whose source has that
    sha256 (None: no such row), asked for an .mpz query's source alone (every row's summary
    was read for it: a search QA run). ``rate`` is that of an AMC or NPY query (they store none);
    ``notes`` gets what the user should know (an assumed rate), ``warnings`` the reader's
    warning about a motion file (cut short, a header that disagrees with its rows: it was
    dropped, exit 0, a QA run of stop 53); ``max_samples`` is a lower F x M limit for an
    .mpz query (spec §8).

    Raises
    ------
    MPZError
        For an unreadable, undecodable or undescribable query, and for ``asf`` or
        ``rate`` given for a query they do not apply to; each names the query (or the
        ASF).
    """
    try:
        return _query_summary(path, source_summary, levels, asf, rate,
                              notes if notes is not None else [],
                              warnings if warnings is not None else [], max_samples)
    except MPZError as exc:          # a damaged .mpz query's error named no file (QA)
        if exc.path is None:
            exc.path = path
        raise


def _query_summary(path: str, source_summary: SourceSummary, levels: tuple[int, ...],
                   asf: str | None, rate: float | None, notes: list[str], warnings: list[str],
                   max_samples: int | None) -> tuple[MotionSummary, str | None, str]:
    from mpz.corpus import sha256_file
    from mpz.similarity import summarize
    from mpz.tools._common import STDIO
    if asf is not None:
        _check_asf(asf)
    if path == STDIO:                        # its format from its content, as everywhere
        import hashlib

        from mpz.io import read_bytes
        from mpz.tools._common import read_stdin
        data, fmt = read_stdin()
        if fmt == ".mpz":
            _no_options_for(".mpz", asf, rate)
            return _mpz_query(data, source_summary, levels, max_samples)
        _no_max_samples(max_samples)
        if fmt == ".amc" and asf is None:
            raise EncoderError("an AMC query on standard input needs its skeleton: give "
                               "the .asf file with --asf FILE.asf", path=STDIO)
        motion = _as_query(read_bytes(data, fmt=fmt, name=STDIO, asf=asf), asf, rate, notes,
                           warnings)
        s = summarize(motion, levels)
        return s, hashlib.sha256(data).hexdigest(), f"the capture ({s.method})"
    if path.lower().endswith(".mpz"):
        from mpz.api import read_source
        _no_options_for(".mpz", asf, rate)
        data, _ = read_source(path)          # a regular file of at most 4 GiB (QA: FIFOs)
        return _mpz_query(data, source_summary, levels, max_samples)
    _no_max_samples(max_samples)
    from mpz.io import read
    try:
        sha = sha256_file(path)
    except OSError as exc:
        raise EncoderError(f"cannot read: {exc.strerror or exc}", path=path) from None
    s = summarize(_as_query(read(path, asf=asf), asf, rate, notes, warnings), levels)
    return s, sha, f"the capture ({s.method})"


def _as_query(motion: Motion, asf: str | None, rate: float | None, notes: list[str],
              warnings: list[str]) -> Motion:
    """The query's motion with ``--rate`` applied, as mpz encode applies it: to an AMC or
    NPY (which store no rate), an error for any other; ``--asf`` for anything but an AMC
    is an error too (it was ignored without a word, a QA run). The reader's warning goes
    to ``warnings``, the rate assumed without ``--rate`` to ``notes``."""
    from mpz.tools._common import RATELESS_FORMATS, assumed_rate, with_rate
    if motion.metadata.get("warning"):
        warnings.append(motion.metadata["warning"])
    fmt = f".{motion.metadata.get('format', '')}"
    _no_options_for(fmt, None if fmt == ".amc" else asf,
                    None if fmt in RATELESS_FORMATS else rate)
    assumed = assumed_rate(motion, rate)    # an NPY was taken at 1 Hz without a word (QA)
    if assumed:
        notes.append(assumed)
    return with_rate(motion, rate)


def _shown(path: str) -> str:
    """A path as the results print it: relative to the current folder when it lies
    below it, else absolute (not ../../../tmp/...)."""
    rel = os.path.relpath(path)
    return path if rel == ".." or rel.startswith(".." + os.sep) else rel


def _no_options_for(fmt: str, asf: str | None, rate: float | None) -> None:
    """Refuse ``--asf`` or ``--rate`` for a query of format ``fmt`` they do not apply to."""
    what = fmt[1:].upper() or "query"
    if asf is not None:
        raise EncoderError(f"--asf is the skeleton of an AMC query; this query is {what}")
    if rate is not None:
        raise EncoderError(f"--rate {rate:g}: this {what} stores its rate; --rate is for "
                           "queries without one (AMC, NPY)")


def _no_max_samples(max_samples: int | None) -> None:
    """Refuse ``--max-samples`` for a capture query: it limits the decoding of an .mpz
    query (it was ignored there, where mpz summary now refuses it: a review of stop 61)."""
    if max_samples is not None:
        raise EncoderError(f"--max-samples {max_samples}: a limit on decoding an .mpz query "
                           "(spec §8); a capture query's readers have their own limits")


def _check_asf(asf: str) -> None:
    """``--asf`` must read as an ASF skeleton (a C3D given there gave "cannot read:
    IndexError: list index out of range", a QA run)."""
    from mpz.io.amc import read_asf
    try:
        read_asf(asf)
    except MPZError as exc:
        text = getattr(exc, "message", str(exc))
        why = "" if text.startswith("cannot read:") else f": {text}"
        raise EncoderError(f"--asf: not a readable ASF skeleton file{why}", path=asf) from None


def _mpz_query(data: bytes, source_summary: SourceSummary, levels: tuple[int, ...],
               max_samples: int | None = None) -> tuple[MotionSummary, str | None, str]:
    """:func:`query_summary` of an MPZ file's bytes."""
    from mpz.api import read_summary
    from mpz.corpus import META_SHA256
    from mpz.decoder import read_stream
    from mpz.similarity import from_smry, summarize
    stream = read_stream(data, **({} if max_samples is None else {"max_samples": max_samples}))
    sha = stream.meta.get(META_SHA256)
    found = None if sha is None else source_summary(sha)
    if found is not None:
        return found, sha, "the index's row of its source"
    smry = read_summary(data)
    frames = stream.header.frame_count
    need = {k for k in levels if k <= frames}
    have = set() if smry is None else {int(lv.k) for lv in smry.levels}
    sparse = 0
    if smry is not None and smry.space == "positions" and need <= have:
        # the chunk summarises every marker; the index's summaries leave out those valid in
        # fewer than MIN_VALID_SHARE of the frames: with one, the chunk is another motion's
        # summary (a CMU take's own .mpz ranked it 13th, a QA run of stop 61)
        sparse = _sparse_markers(stream)
        if not sparse:
            return from_smry(smry), sha, "its summary chunk"
    # its own levels are not the index's (ev_k would come from other k: its source ranked
    # second, a QA run), or it has none: the summary of its decoded motion, as a capture's
    from mpz.similarity import MIN_VALID_SHARE
    from mpz.tools._common import read_mpz_input_bytes
    why = ("no summary chunk" if smry is None else
           "a summary of joint angles" if smry.space != "positions" else
           f"a summary chunk that includes {sparse} marker{'' if sparse == 1 else 's'} "
           f"valid in fewer than {MIN_VALID_SHARE:.0%} of its frames, which the index's "
           f"summaries leave out" if sparse else
           f"summary levels k = {', '.join(map(str, sorted(have)))}, not the index's "
           f"{', '.join(map(str, sorted(need)))}")
    s = summarize(read_mpz_input_bytes(data, max_samples), levels)
    return s, sha, f"its decoded motion ({s.method}; the file holds {why})"


def _sparse_markers(stream: Any) -> int:
    """How many markers of an MPZ stream are valid in some frames but not described by a
    summary (:func:`mpz.similarity.described_markers`), from its validity mask alone: a
    file without a MASK chunk has none, and its mask is not made."""
    import numpy as np

    from mpz.decoder import decode_mask
    from mpz.similarity import described_markers
    if stream.mask is None:                         # every sample valid (§4.5)
        return 0
    valid = decode_mask(stream)
    return int(np.count_nonzero(valid.any(axis=0) & ~described_markers(valid)))


def run(args: argparse.Namespace) -> int:
    from mpz.corpus import INDEX_NAME, open_index, run_in_progress
    from mpz.similarity import descriptor, features_for, rank
    from mpz.tools._cli import print_json, printable

    # a run writing the folder: the ranking is of the files indexed so far (a QA run of
    # stop 61 ranked 5, 9, 11 ... 24 candidates in turn, with no word). Asked before and
    # after the reading, so that a run ending in between is still said (a review)
    # the index's own folder, a link to it followed: its lock and its outputs are there
    folder = os.path.dirname(os.path.realpath(os.path.join(args.index, INDEX_NAME)
                                              if os.path.isdir(args.index) else args.index))
    before = run_in_progress(folder)
    with open_index(args.index) as index:
        levels = index.levels()
        values, table = index.descriptors()
        left_out = index.unsearchable()     # archived without a summary: not candidates
        index_path = index.path
        notes: list[str] = []
        warned: list[str] = []
        if values:
            # an .mpz query (standard input may be one) may be found by its source's row:
            # that row's summary alone is read, while the index is open (every row's was:
            # 18 s and 2.2 GB a query at 20,000 rows, a search QA run)
            def source_summary(sha: str) -> MotionSummary | None:
                first = next((v for v in values if v["source_sha256"] == sha), None)
                return None if first is None else index.summary_of(first["output"])
            summary, sha, origin = query_summary(args.query, source_summary, levels, args.asf,
                                                 rate=args.rate, notes=notes,
                                                 warnings=warned,
                                                 max_samples=args.max_samples)
    after = run_in_progress(folder)
    writing = True if True in (before, after) else None if None in (before, after) else False
    if not values:
        raise EncoderError("the index holds no files" + (
            " yet: a corpus run is writing it now" if writing else ""), path=index_path)
    try:
        q = descriptor(summary, levels)
    except MPZError as exc:                # a summary chunk of no pose: the query's
        exc.path = exc.path or args.query
        raise
    if writing:
        notes.append(f"a corpus run is writing this index now: the ranking is of the "
                     f"{len(values)} file{'s' * (len(values) != 1)} indexed so far")
    for note in notes:
        print(f"mpz search: note: {printable(note)}", file=sys.stderr)
    for warning in warned:          # -q too: it is no success (exit 1)
        print(f"mpz search: warning: {printable(args.query)}: {printable(warning)}",
              file=sys.stderr)
    same = [v["source_sha256"] == sha for v in values]
    order, dist = rank(q, table, identical=same, names=[v["output"] for v in values])
    shown = order if args.top == 0 else order[:args.top]
    results = [{"rank": n + 1, "distance": float(dist[i]), "identical": bool(same[i]),
                "output": values[i]["output"], "path": values[i]["path"],
                **_output_state(os.path.join(folder, *values[i]["output"].split("/")),
                                values[i]["total_bytes"]),
                "source_exists": os.path.isfile(values[i]["path"]),
                "frames": values[i]["frames"], "rate": values[i]["rate"],
                "duration_s": values[i]["duration_s"], "markers": values[i]["markers"],
                "units": values[i]["units"] or None, "format": values[i]["format"]}
               for n, i in enumerate(shown)]
    query = {"file": args.query, "frames": summary.n_frames, "rate": summary.rate,
             "rate_assumed": any("Hz is assumed" in n for n in notes),
             "dims": summary.dims, "summary": origin, "levels": list(summary.level_ks()),
             "sha256": sha, "warnings": warned}
    gone = sum(not r["output_exists"] for r in results)
    changed = sum(r["output_changed"] for r in results)
    code = found(EXIT_WARN if gone or changed or warned else EXIT_OK)
    if args.json:
        print_json({"schema": JSON_SCHEMA, "index": index_path, "query": query,
                    "features": list(features_for(levels)),
                    "descriptor": [float(v) for v in q], "candidates": len(values),
                    "not_searchable": left_out, "run_in_progress": writing,
                    "results": results})
        _say_missing(results, gone, changed)    # exit 1 said nothing on stderr (a JSON audit)
        return code
    secs = summary.n_frames / summary.rate
    print(f"query {printable(args.query)}: {summary.n_frames} frames, {secs:.2f} s, "
          f"{summary.dims // 3} markers; summary from {origin}")
    also = (f" (and {left_out} not searchable: fewer than 2 frames or 3 markers)"
            if left_out else "")
    n = len(values)
    print(f"{n} file{'s' * (n != 1)} in {printable(index_path)}{also}; nearest first (= marks a "
          f"byte-identical source; outputs relative to {printable(_shown(folder))})")
    print(f"{'rank':>4} {'distance':>9} {'frames':>7} {'secs':>7} {'markers':>7}  "
          "output  <- source")
    for r in results:
        mark = "=" if r["identical"] else " "
        out_gone = (" [missing]" if not r["output_exists"] else
                    " [changed]" if r["output_changed"] else "")
        src_gone = "" if r["source_exists"] else " [missing]"
        print(f"{r['rank']:>4} {r['distance']:>9.3f} {r['frames']:>7} {r['duration_s']:>7.2f} "
              f"{r['markers']:>7} {mark}{printable(r['output'])}{out_gone}  <- "
              f"{printable(_shown(r['path']))}{src_gone}")
    _say_missing(results, gone, changed)
    return code


def _output_state(output: str, total_bytes: object) -> dict[str, bool]:
    """``output_exists``: ``output`` is a file; ``output_changed``: one of another size
    than its index row's ``total_bytes`` (cut short, or replaced since it was indexed).
    One stat."""
    try:
        st = os.stat(output)
    except OSError:
        return {"output_exists": False, "output_changed": False}
    exists = stat.S_ISREG(st.st_mode)
    return {"output_exists": exists, "output_changed": exists and st.st_size != total_bytes}


def _say_missing(results: list[dict], gone: int, changed: int = 0) -> None:
    """On stderr: the outputs listed that are gone or changed (exit 1), the sources that
    moved."""
    moved = sum(not r["source_exists"] for r in results)
    if gone:
        print(f"mpz search: warning: {gone} of the files listed {'is' if gone == 1 else 'are'}"
              " no longer in the index's folder ([missing] after the output, output_exists "
              "false in --json); the next mpz encode -r into it forgets such rows",
              file=sys.stderr)
    if changed:
        # an output cut short whose source was deleted was listed as if sound, with "the
        # .mpz holds the motion" (a corpus QA run of stop 76)
        print(f"mpz search: warning: {changed} of the outputs listed "
              f"{'has' if changed == 1 else 'have'} another size than the index recorded "
              "([changed] after the output, output_changed in --json): damaged or replaced "
              "since; mpz encode -r over the sources into the index's folder says which "
              "(--verify reads each whole)", file=sys.stderr)
    if moved:
        what = ("1 of the sources listed is" if moved == 1 else
                f"{moved} of the sources listed are")
        print(f"mpz search: note: {what} no longer at the path the index holds ([missing] "
              "after the source); the .mpz holds the motion"
              + (", if it is sound" if changed else ""), file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    """Run ``mpz search`` on its own (same options and exit codes)."""
    from mpz.tools.mpz_cli import main as mpz_main
    return mpz_main(["search", *(sys.argv[1:] if argv is None else argv)])
