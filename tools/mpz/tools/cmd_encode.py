"""``mpz encode IN... [-o OUT.mpz | -o FOLDER/ | -o -]``: compress motion-capture files.

``-`` is standard input (its format found from its content) or standard
output; reports then go to stderr. Several inputs, or folders with ``-r``,
are encoded into ``-o FOLDER/`` (flat, or keeping the folders below each
``-r`` folder with ``--mirror``), or beside each input without ``-o``; a failed
input is reported and the others still run (exit 2 if any failed). Lengths
need a unit (``--max-error 1mm``).
"""
from __future__ import annotations

import argparse
import math
import os
import signal
import sys
from typing import TYPE_CHECKING

from mpz.errors import EncoderError, MPZError
from mpz.tools._cli import EXIT_OK, EXIT_WARN, bound_text, found, positive, printable, signal_in

if TYPE_CHECKING:
    from mpz.encoder import EncodeOptions


def _pairs(items, what, *, name_first=False):
    """``NAME=VALUE`` items as a dict. The split is at the last ``=`` (a marker or node
    name may hold one), or with ``name_first`` at the first (--meta: a value such as a
    URL with a query holds them more often than a key)."""
    out = {}
    for item in items or []:
        if "=" not in item:
            raise EncoderError(f"{what} must look like NAME=VALUE, got {item!r}")
        k, v = item.split("=", 1) if name_first else item.rsplit("=", 1)
        out[k] = v
    return out


def add_parser(sub):
    from mpz.encoder import DEFAULTS as D  # the one definition of every default
    p = sub.add_parser("encode", help="compress C3D, TRC, BVH, AMC (+ASF), NPY or CSV to .mpz",
                       description="Compress a motion-capture file to MPZ. With --max-error the "
                       "decoded motion is guaranteed within that Euclidean distance of the input "
                       "on every valid sample; without it the paper's thresholds control quality.")
    p.add_argument("inputs", nargs="+", metavar="INPUT",
                   help="motion files, folders (with -r), or - for standard input")
    p.add_argument("-o", "--output", help="output .mpz file, FOLDER/ for several inputs (made "
                   "if missing), - for standard output, or /dev/null to encode and drop it "
                   "(default: IN.mpz beside each input; stdin -> stdout); written atomically; "
                   "another name needs -f, and a motion format's (.c3d, .trc, ...) is refused")
    p.add_argument("-r", "--recursive", action="store_true",
                   help="encode every motion file in the folders given as inputs")
    p.add_argument("--mirror", action="store_true",
                   help="with -r and -o FOLDER/: keep each file's path below the folder given "
                   "as input (-r IN with IN/s01/walk.c3d -> FOLDER/s01/walk.mpz), as zstd's "
                   "--output-dir-mirror; default: every output in FOLDER/ itself")
    p.add_argument("--keep-extension", action="store_true",
                   help="name each output after the whole input name, NAME.EXT.mpz "
                   "(walk.c3d -> walk.c3d.mpz), so that two formats of one take in one "
                   "folder (walk.c3d, walk.trc) each have their own; mpz decode gives "
                   "walk.c3d back; default: NAME.mpz")
    p.add_argument("--asf", help="skeleton file for AMC input (default: found beside it); "
                   "with several inputs, every AMC file takes this one, in place of the one "
                   "beside it")
    # issue 13: skeletal input (BVH, AMC/ASF)
    p.add_argument("--units", choices=("mm", "cm", "m", "in"),
                   help="the length unit of an input that has none (BVH), e.g. --units cm; "
                   "then lengths with units work (--max-error 1mm). In a corpus run, "
                   "adding or changing it encodes again the files it names a unit for, and "
                   "leaves the others up to date (docs/corpus.md)")
    p.add_argument("--rate", metavar="HZ", type=positive,
                   help="the frame rate of an input that stores none (AMC: 120 Hz is assumed, "
                   "NPY: 1 Hz), e.g. --rate 60; an error for an input that has one")
    p.add_argument("--angle-error", metavar="DEG", type=positive,
                   help="BVH, AMC: bound on the rotation channels, in degrees (default 0.01, "
                   "or as --max-error allows: then each rotation's bound follows how far it "
                   "moves a joint, up to 90, and one that moves none keeps 0.01)")
    p.add_argument("--translation-error", metavar="LEN",
                   help="BVH, AMC: bound on the translation channels, e.g. 0.1mm, or a plain "
                   "number in the skeleton's length unit (default 0.01 of it, or as "
                   "--max-error allows)")
    p.add_argument("--position-error", metavar="E",
                   help="BVH, AMC: bound on the joint positions the decoded channels give, "
                   "with a unit, e.g. 1mm (a bare number only for inputs without units): "
                   "the channels get steps that keep it, found by a search, and the marker "
                   "layer keeps its preview bound (1/500 of the skeleton's size). "
                   "--max-error bounds both, so this gives a smaller file when BVH or AMC "
                   "is what you decode back to (cmu_10_01.bvh at 1 mm: 34.7 against "
                   "49.3 KB; spec §4.14)")
    p.add_argument("--no-skeleton", action="store_true",
                   help="BVH, AMC: store joint positions only (an MPZ 1.0 file)")
    p.add_argument("--max-error", metavar="E", help="hard bound with a unit, e.g. 2mm, 0.5cm, "
                   "0.002m, 0.04in (a bare number only for inputs without units)")
    # issue 12: the default is a declared bound; the paper's unbounded mode only by name
    p.add_argument("--lossy", action="store_true",
                   help="the paper's lossy mode: patterns only, no declared bound (default: "
                   f"a bound: exact on an int16 C3D's grid, else {D.default_error_mm:g} mm, or "
                   f"{D.default_error_fraction:g} of the largest extent without units; a BVH "
                   "or AMC's marker layer within 1/500 of the skeleton's size, its channels "
                   "within --angle-error and --translation-error). "
                   "For reproducing the paper: on 24 of 25 real captures it is larger "
                   "than --max-error 1mm, with errors of 12 to 500 mm (README)")
    p.add_argument("--model-error", action="append", metavar="KIND=F",
                   help="C3D model outputs: max error as a fraction of each channel's range, "
                   f"per kind (ANGLES, FORCES, MOMENTS, POWERS, SCALARS, REACTIONS; default "
                   f"{D.model_error:g}), e.g. ANGLES=1e-3 (repeatable)")
    p.add_argument("--group-error", action="append", metavar="NODE=E",
                   help="tighter bound for one node of the body-part hierarchy (the "
                   "--hierarchy given, else cmu41 with 37 or more of CMU's 41 markers, skeleton "
                   "for BVH/AMC, else auto; not the flat one a bounded encode uses without "
                   "it), e.g. l_foot=0.5mm (repeatable; a bound not tighter than "
                   "--max-error bounds its node no more tightly, but giving one still "
                   "selects the body-part hierarchy, often a larger file; BVH/AMC only "
                   "with --no-skeleton: their joints come from the channels, which it "
                   "does not bound)")
    p.add_argument("--theta", type=float, default=D.theta,
                   help=f"key-frame threshold, fraction of the head size ADDH (default {D.theta})")
    p.add_argument("--k0", type=int, default=D.k0,
                   help=f"initial number of clusters (default {D.k0})")
    p.add_argument("--seed", type=int, default=D.seed,
                   help=f"seed of the pattern clustering's K-means (default {D.seed}); the "
                   "output is the same for the same seed, and the seed is not stored")
    p.add_argument("--tau", type=float, default=D.tau,
                   help=f"clustering threshold, fraction of ADDH (default {D.tau})")
    p.add_argument("--metric", choices=("max", "ave"), default=D.metric,
                   help=f"clustering error metric, paper Eq. 2 (max) or Eq. 1 (ave) "
                   f"(default {D.metric})")
    p.add_argument("--weight", action="append", metavar="NAME=W",
                   help="weight of a marker or node (local distortion control; repeatable)")
    p.add_argument("--hierarchy", help="cmu41, skeleton, auto, flat or a JSON hierarchy file "
                   "(default: flat under a bound without --patterns on or --group-error; "
                   "else cmu41 with 37 or more of CMU's 41 markers, skeleton for BVH/AMC, else "
                   "auto)")
    p.add_argument("--smoothing", type=int, default=D.smoothing,
                   help=f"boundary smoothing half-width 0..16 (default {D.smoothing})")
    p.add_argument("--patterns", choices=("auto", "on", "off"), default=None,
                   help="pattern layer per node of the body-part hierarchy: auto keeps it "
                   "where it makes that node smaller (default: on with --lossy, off under a "
                   "bound, --max-error or the default one, which codes one flat node and is "
                   "usually smaller than auto)")
    p.add_argument("--segmentation", choices=("adaptive", "optimal"), default=D.segmentation,
                   help="adaptive = paper's Alg. 1; optimal = Fisher optimal partition "
                   f"(default {D.segmentation})")
    p.add_argument("--grid", help="grid step with a unit, e.g. 0.5mm: an upper limit under a "
                   "bound (default: the step the bound needs, --max-error or the default one; "
                   "ADDH/1000 with --lossy)")
    p.add_argument("--summary", metavar="K,K,...", help="add the optimal-partition summary chunk "
                   "with these segment counts, e.g. 6,12,24,48")
    p.add_argument("--summary-space", choices=("positions", "angles"), default=None,
                   help="what --summary partitions: the marker positions relative to their "
                   "centroid (default) or the joint angles of BVH or AMC input")
    p.add_argument("--summary-format", choices=("smrc", "smry"), default=None,
                   help="smrc: the range-coded summary chunk (MPZ 1.1, the default); smry: the "
                   "raw 1.0 chunk, for readers that know only MPZ 1.0 (several times larger)")
    p.add_argument("--meta", action="append", metavar="KEY=VALUE",
                   help="metadata (repeatable, each key once; split at the first '=': a "
                   "value may hold more); not the keys the readers set (format, source, "
                   "trc.*, csv.* ...), but subject")
    p.add_argument("--threads", type=int, metavar="N", default=D.threads,
                   help="threads within each file, 1..64 (default: the CPU count, at most 2, and 1 "
                   "below 10,000 marker-frames); the output is the same for any N")
    p.add_argument("-f", "--force", action="store_true", help="replace OUTPUT if it exists, "
                   "write it under a name not ending in .mpz, or write to a terminal")
    p.add_argument("--json", action="store_true",
                   help="print the report as one JSON object (schema mpz-encode/1; a batch's "
                   "mpz-encode-batch/1, a corpus run's mpz-corpus/1; docs/json.md)")
    p.add_argument("-q", "--quiet", action="store_true",
                   help="print nothing on success (no notes, no progress) but the report "
                   "--json asks for; warnings (exit 1) are still printed")
    p.add_argument("-v", "--verbose", action="store_true",
                   help="also print the bytes of every chunk type")
    from mpz.tools._corpus_cli import add_corpus_options  # issue 15: --jobs, --scheduler
    add_corpus_options(p)
    p.set_defaults(func=run)


def _options(args: argparse.Namespace, units: str, source: str | None) -> EncodeOptions:
    """The EncodeOptions of the command line, lengths converted to the input's units."""
    from mpz.encoder import EncodeOptions
    from mpz.io._common import utf8_name
    from mpz.tools._common import parse_length
    metadata = _pairs(args.meta, "--meta", name_first=True)
    if source is not None:          # a name that is not UTF-8 as \xNN (mpz.io.read's note)
        metadata.setdefault("source", utf8_name(os.path.basename(source)))
    return EncodeOptions(
        max_error=None if args.max_error is None else parse_length(args.max_error, units),
        group_errors={k: parse_length(v, units, "--group-error")
                      for k, v in _pairs(args.group_error, "--group-error").items()},
        theta=args.theta, k0=args.k0, tau=args.tau, metric=args.metric, seed=args.seed,
        weights=_weights(args.weight), hierarchy=args.hierarchy, smoothing=args.smoothing,
        patterns=args.patterns, segmentation=args.segmentation,
        grid=None if args.grid is None else parse_length(args.grid, units, "--grid"),
        summary=_summary_ks(args.summary), metadata=metadata, lossy=args.lossy,
        # None: not given (the encoder's default; a note says when they change nothing)
        **{k: v for k, v in (("summary_space", args.summary_space),
                             ("summary_format", args.summary_format)) if v is not None},
        model_errors=_model_errors(args.model_error), threads=args.threads)


def _option_notes(args: argparse.Namespace, motion, opts: EncodeOptions) -> list[str]:
    """The notes on options that do less than they seem to: the encoder's
    (:func:`mpz.encoder.option_notes`: a --group-error not tighter than the bound, channel
    bounds without a skeleton chunk), a --meta key that readers set (:func:`_reader_keys`),
    and --summary-space or --summary-format without --summary (a QA run: they changed
    nothing, unsaid)."""
    from mpz.encoder import option_notes
    unused = [o for o, v in (("--summary-space", args.summary_space),
                             ("--summary-format", args.summary_format)) if v is not None]
    idle = ([f"{' and '.join(unused)} change{'s' * (len(unused) == 1)} nothing without "
             "--summary (no summary chunk is written)"] if unused and not opts.summary else [])
    return option_notes(motion, opts) + _reader_keys(args) + idle


def _check_meta_keys(items: list[str] | None) -> None:
    """Refuse a --meta key that a reader sets and the tools read back (a QA run: --meta
    format=bvh made every later mpz decode of the file try to write BVH, and fail), and a
    key given twice (the last value was kept without a word)."""
    from mpz.encoder import own_key, reader_key
    seen: set[str] = set()
    for item in items or []:
        key = item.split("=", 1)[0] if "=" in item else item
        if reader_key(key) or key == "source":        # the CLI names it from the input
            raise EncoderError(f"--meta {key}: a key the readers set to describe the file "
                               f"they read, which the tools go by (mpz decode, mpz show); "
                               f"give your own name, e.g. --meta {own_key(key)}=...")
        if key in seen:
            raise EncoderError(f"--meta {key} is given twice: give each key once")
        seen.add(key)


def _reader_keys(args: argparse.Namespace) -> list[str]:
    """A note for each --meta key that is one a reader sets to describe the file it read
    (:data:`mpz.io.READER_KEYS`, e.g. subject from a C3D's SUBJECTS): kept in the .mpz,
    but no writer writes it back, so it is lost again without a word on decoding."""
    from mpz.io import READER_KEYS
    keys = [k for k in _pairs(args.meta, "--meta", name_first=True) if k in READER_KEYS]
    return [f"--meta {k}: a key the readers set to describe the file they read: kept in the "
            ".mpz (mpz show --json), but no format writes it back and mpz compare does not "
            f"check it; a name of your own (e.g. {k}_name) is free metadata, which compare "
            "checks" for k in keys]


def _model_errors(items: list[str] | None) -> dict[str, float]:
    """--model-error KIND=F (issue 12): a fraction of each channel's range, per kind."""
    out: dict[str, float] = {}
    for k, v in _pairs(items, "--model-error").items():
        try:
            out[k.upper()] = float(v)
        except ValueError:
            raise EncoderError(f"--model-error {k}={v}: give a fraction of the range, e.g. "
                               "ANGLES=1e-3") from None
    return out


def _weights(items: list[str] | None) -> dict[str, float] | None:
    out: dict[str, float] = {}
    for k, v in _pairs(items, "--weight").items():
        try:
            out[k] = float(v)
        except ValueError:
            raise EncoderError(f"--weight {k}={v}: the weight must be a number") from None
    return out or None


def _summary_ks(text: str | None) -> tuple[int, ...]:
    if not text:
        return ()
    try:
        return tuple(int(k) for k in text.split(","))
    except ValueError:
        raise EncoderError(f"--summary {text}: give segment counts as integers, e.g. "
                           "6,12,24,48") from None


def _check_options(args: argparse.Namespace) -> None:
    """Everything about the options that can be judged before an input is read: lengths
    whatever the input's units can be (:func:`~mpz.tools._common.check_length`), and every
    other value as the encoder checks it (EncodeOptions' ``validate``, with the lengths
    left out: they need the input's units). An error here is a usage error (exit 64):
    --threads 0, --smoothing 17 or --max-error 0mm exited 2, as an input error."""
    import copy

    from mpz.tools._common import check_length
    check_length(args.max_error, "--max-error")
    check_length(args.grid, "--grid")
    _check_meta_keys(args.meta)
    groups = _pairs(args.group_error, "--group-error")
    for v in groups.values():
        check_length(v, "--group-error")
    _translation_error(args.translation_error, None)
    check_length(args.position_error, "--position-error")
    unitless = copy.copy(args)       # _options parses --meta, --weight and --summary too
    unitless.max_error = None if args.max_error is None else "1"    # a bound is asked for
    unitless.grid = None
    # group bounds asked for (their lengths need the units): --lossy with them exited 2
    unitless.group_error = [f"{name}=1" for name in groups] or None
    _options(unitless, "", None).validate()


def run(args: argparse.Namespace) -> int:
    from mpz.io import READERS
    from mpz.io._common import ext_of
    from mpz.tools._cli import EXIT_USAGE, print_json
    from mpz.tools._common import (
        RATELESS_FORMATS,
        STDIO,
        UsageError,
        is_folder_target,
        plan_batch,
        run_batch,
    )

    try:
        _check_options(args)
    except EncoderError as exc:
        print(f"mpz encode: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    try:
        jobs = plan_batch(args.inputs, args.output, recursive=args.recursive,
                          mirror=args.mirror,
                          accept=lambda name: ext_of(name) in READERS,
                          name_for=lambda path: (path if args.keep_extension else
                                                 os.path.splitext(path)[0]) + ".mpz",
                          what="MPZ",
                          same_stem="--keep-extension names each output after its whole "
                                    "input name (walk.c3d.mpz, walk.trc.mpz), or rename one "
                                    "of the two")
    except UsageError as exc:
        print(f"mpz encode: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    # a batch (several inputs, -r or -o FOLDER/, however many files that makes): --units
    # and --rate name the unit and rate of its inputs without one, and leave the others
    batch = len(jobs) > 1 or args.recursive or is_folder_target(args.output)
    if batch and args.rate is not None and not args.quiet \
            and not any(ext_of(j.input) in RATELESS_FORMATS for j in jobs):
        print(f"mpz encode: note: --rate {args.rate:g} changes nothing: every input of this "
              "batch stores its rate (--rate is for AMC and NPY)", file=sys.stderr)
    from mpz.tools._corpus_cli import run_corpus, wants_corpus  # issue 15: Dask + index
    if wants_corpus(args, jobs):
        return run_corpus(args, jobs, PerFile(args))
    if args.memory_limit is not None and not args.quiet:
        print(f"mpz encode: note: --memory-limit {args.memory_limit} changes nothing: it "
              "limits the Dask workers of a corpus run (several inputs or -r into "
              "-o FOLDER/, or --jobs N)", file=sys.stderr)
    if args.verify and not args.quiet:
        print("mpz encode: note: --verify changes nothing: it checks the outputs of a "
              "corpus run (several inputs or -r into -o FOLDER/, or --jobs N), which an "
              "index says are up to date", file=sys.stderr)
    data_on_stdout = any(j.output == STDIO for j in jobs)
    report = sys.stderr if data_on_stdout else sys.stdout
    results: list[dict] = []
    # the batch's closing line: with --json, stdout holds the JSON alone (a CI audit found
    # "mpz encode: 2 inputs: 2 done, 0 failed" before it)
    failures: list = []
    try:
        code = run_batch("encode", jobs,
                         lambda job: _encode_one(job, args, report, results, batch=batch),
                         report=sys.stderr if args.json else report, quiet=args.quiet,
                         failures=failures)
    except (KeyboardInterrupt, SystemExit) as exc:
        signal_name = (_signal_name(exc.code - 128) if isinstance(exc, SystemExit)
                       and isinstance(exc.code, int) else None)
        if batch and (isinstance(exc, KeyboardInterrupt) or signal_name is not None):
            _say_interrupted(signal_name or "the interrupt", jobs, results)
        raise
    if args.json:
        print_json(_json_document(results, failures, batch), file=report)
    return code


#: ``--json``'s schemas (docs/json.md): one input's report, and a batch's (several inputs,
#: -r or -o FOLDER/ without a corpus run, which prints ``mpz-corpus/1``)
JSON_SCHEMA = "mpz-encode/1"
JSON_BATCH_SCHEMA = "mpz-encode-batch/1"


def _json_document(results: list[dict], failures: list, batch: bool) -> dict:
    """What ``--json`` prints: one input's report (``mpz-encode/1``), or the error document
    when it failed; a batch's reports and failures (``mpz-encode-batch/1``), however many
    files it found. Before, one input gave an object, a failed one ``[]`` and a batch a bare
    list (a CLI audit of stop 58)."""
    from mpz.tools._cli import json_error, json_failure
    if not batch:
        if failures:
            _, error, status = failures[0]
            return json_failure("encode", error, status, path=failures[0][0].input)
        return {"schema": JSON_SCHEMA, **results[0]}
    return {"schema": JSON_BATCH_SCHEMA, "inputs": len(results) + len(failures),
            "encoded": len(results), "failed": len(failures),
            "files": [{"schema": JSON_SCHEMA, **r} for r in results],
            "failures": [{"input": job.input, "status": status,
                          "error": json_error(error, job.input)}
                         for job, error, status in failures]}


def _say_interrupted(what: str, jobs: list, results: list[dict]) -> None:
    """The line of a batch stopped by Ctrl-C or a signal (``what``): which outputs it
    wrote, whole (with --json, nothing said which: no document is printed, a JSON audit of
    stop 59)."""
    from mpz.tools._cli import printable
    names = [printable(r["output"]) for r in results]
    shown = ", ".join(names[:10]) + (f" and {len(names) - 10} more" if len(names) > 10 else "")
    print(f"mpz encode: {len(results)} of {len(jobs)} inputs written before {what}"
          + (f": {shown}" if names else "") + "; the others are not (no partial file is left)",
          file=sys.stderr)


def _signal_name(signum: int) -> str | None:
    """"SIGTERM" or "SIGHUP" for the signal whose ``signals_exit`` code is ``128 + signum``;
    None for any other code."""
    import signal
    names = {int(signal.SIGTERM): "SIGTERM"}
    if hasattr(signal, "SIGHUP"):
        names[int(signal.SIGHUP)] = "SIGHUP"
    return names.get(signum)


def _holds(path: str, data: bytes) -> bool:
    """Whether the file ``path`` holds ``data`` (a write that an interrupt may have cut
    short either put it there whole or left the old file)."""
    try:
        with open(path, "rb") as fh:
            return os.fstat(fh.fileno()).st_size == len(data) and fh.read() == data
    except OSError:
        return False


def _remove_output(output: str, to_stdout: bool) -> str:
    """Remove a bad output that this command wrote, and say what became of it. Standard
    output is gone already, and the null device is never removed: as root, `-o
    /dev/null` would have unlinked it (a review of stop 51)."""
    from mpz.api import is_null_device
    if to_stdout:
        return "it was written to standard output"
    if is_null_device(output) or not os.path.isfile(output):
        return "it was written to a file that is not kept"
    os.remove(output)
    return "the output was removed"


def _encode_one(job, args: argparse.Namespace, out, results: list[dict], *,
                batch: bool = False) -> int:
    import mpz
    from mpz.api import check_mpz_name, check_output, is_null_device
    from mpz.encoder import encode_motion, reader_not_kept, unasked
    from mpz.io._common import ext_of
    from mpz.metrics import summary as error_summary
    from mpz.tools._common import (
        STDIO,
        Progress,
        compile_notice,
        human_size,
        input_size,
        ratio_text,
        read_motion,
        stage,
        write_stdout,
    )

    source = None if job.input == STDIO else job.input
    size = input_size(job.input)
    to_stdout = job.output == STDIO
    # every check on the output comes before the encode
    if not to_stdout:
        check_output(job.output, force=args.force, source=source)
        if not is_null_device(job.output):
            check_mpz_name(job.output)        # -o x.c3d, even with -f: mpz decode was meant
            if ext_of(job.output) != ".mpz" and not args.force:
                raise EncoderError(f"{job.output}: an MPZ file should end in .mpz; "
                                   "use --force to write it under this name")
    elif not args.force and sys.stdout.isatty():
        raise EncoderError("refusing to write MPZ data to a terminal; redirect standard "
                           "output, or use -f", path=STDIO)
    stage("encode", args.quiet, size, f"reading {printable(job.input)} ({human_size(size)})")
    motion, in_size, stdin_mpz = read_motion(job.input, args.asf)
    # the reader's (a file cut short, a header that disagrees with the rows); kept in the
    # file's meta, and the exit code is 1, "warnings only" (a QA run of stop 47: a note,
    # exit 0, and nothing at all with -q)
    warning = motion.metadata.get("warning")
    if warning:     # -q too: it is no success, and it exits 1 (a QA run of stop 52)
        print(f"mpz encode: warning: {printable(job.input)}: {printable(warning)}",
              file=sys.stderr)
    # what the reader could not carry into the file (an AMC's comments among its frames,
    # an ASF's unknown sections, a BVH's keyword spelling): the output will not give it
    # back, so a warning, as the reader's (a note that -q hid, or words in the ratio line
    # alone, exit 0: an animation studio's QA run of stop 75)
    for item in unasked(reader_not_kept(motion)):
        warning = f"{warning}; not kept: {item}" if warning else f"not kept: {item}"
        print(f"mpz encode: warning: {printable(job.input)}: not kept: {printable(item)}",
              file=sys.stderr)
    found(EXIT_WARN if warning else EXIT_OK)    # before -o - writes to standard output
    reader_note = motion.metadata.get("reader_note")              # which reader read it
    if reader_note and not args.quiet:
        print(f"mpz encode: note: {printable(job.input)}: {printable(reader_note)}",
              file=sys.stderr)
    motion = _rate(args, _units(args, motion, batch=batch), batch=batch)
    units = motion.units
    opts, notes = _skeleton_options(args, motion, _options(args, units, source))
    opts, kept = _summary_of_mpz_input(args, opts, job.input, stdin_mpz)
    notes += kept + _option_notes(args, motion, opts)
    notes = _input_notes(args, motion, job.input) + notes
    if not args.quiet:
        for note in notes:
            print(f"mpz encode: note: {printable(note)}", file=sys.stderr)
    compile_notice(args.quiet, args.verbose)
    bar = Progress("encoding", enabled=None if not args.quiet else False)
    try:
        bar(0.0, "planning")    # then the nodes, and the stages within each (encode_motion)
        try:
            data, rep = encode_motion(motion, opts, progress=bar)
        except EncoderError as exc:
            # what this input's data cannot be coded with (a channel value too large for
            # its step) named no file, where every reader's error does (a QA run, stop 75)
            if exc.path is None and source is not None:
                exc.path = source
            raise
    finally:
        bar.close()
    # the notes that the encoded file gives (mpz.encoder.outcome_notes: a --grid, --weight
    # or --model-error that did less than it seems): the report's that were not printed
    later = [n for n in rep.notes if n not in notes]
    if not args.quiet:
        for note in later:
            print(f"mpz encode: note: {printable(note)}", file=sys.stderr)
    notes = [*([reader_note] if reader_note else []), *notes, *later]
    from mpz.api import signals_exit
    if to_stdout:
        write_stdout(data, binary=True, force=args.force)
    # the write and the report's figures: a Ctrl-C or SIGTERM that comes once the output
    # is in place (in the write's last steps, or between the two: a review of stop 56 saw
    # exit 130 and "interrupted" alone with the file there) says it was written
    try:
        if not to_stdout:
            mpz.write_atomic(job.output, data, source=source, force=args.force)
        stage("encode", args.quiet, size, "decoding what was written, to measure its error")
        with signals_exit(signal.SIGTERM, getattr(signal, "SIGHUP", None)):
            try:
                decoded = mpz.decode(data)
            except MPZError as exc:
                # a file its own decoder refuses is the encoder's bug, not bad input: it was
                # left behind, exit 2 with a decoder's message (a 2-hour BVH, QA of stop 51)
                raise AssertionError(
                    f"the encoder wrote a file that its decoder refuses: {exc} "
                    f"({job.input}); {_remove_output(job.output, to_stdout)}") from None
            stored_levels = list(mpz.info(data).summary_levels)      # the k the file holds
            err = error_summary(motion, decoded)
    except (KeyboardInterrupt, SystemExit, SystemError) as exc:
        # a signal heard inside a kernel comes as a chain of SystemErrors (signal_in)
        sig = signal_in(exc) if isinstance(exc, SystemError) else exc
        if sig is None:
            raise
        # 130 or 143 read as "nothing changed" lost a --force target (QA, stops 47, 48)
        terminated = (None if isinstance(sig, KeyboardInterrupt) or not isinstance(sig.code, int)
                      else _signal_name(sig.code - 128))
        if not to_stdout and (isinstance(sig, KeyboardInterrupt) or terminated) \
                and _holds(job.output, data):
            print(f"mpz encode: {printable(job.output)} was written (the "
                  f"{terminated or 'interrupt'} came while its report was measured)",
                  file=sys.stderr)
        if sig is exc:
            raise
        raise sig from None
    if rep.bound is not None and err["max"] is not None and not err["max"] <= rep.bound:
        # the encoder's own guarantee, checked on what it wrote (a QA run of stop 50: an
        # encoder broken on purpose reported "max 1.6 mm (bound 1 mm)", exit 0): a file
        # that breaks its declared bound is not left behind; the bug is reported (exit 70)
        raise AssertionError(
            f"the encoded file breaks its declared bound: max error {err['max']!r} > "
            f"{rep.bound!r} ({job.input}); {_remove_output(job.output, to_stdout)}")
    # what the C3D it decodes to will not give back (exit 1, as the reader's warnings)
    from mpz.io.c3d import round_trip_warnings
    for note in round_trip_warnings(motion, decoded):
        found(EXIT_WARN)
        warning = f"{warning}; {note}" if warning else note
        print(f"mpz encode: warning: {printable(job.input)}: {printable(note)}",
              file=sys.stderr)
    del decoded
    channel_bytes = (4 * motion.angles.size if motion.angles is not None
                     and opts.keep_skeleton else None)
    result = {
        "input": job.input, "output": job.output, "frames": rep.frames,
        "markers": rep.markers, "units": units or None, "raw_float32_bytes": rep.raw_bytes,
        "input_bytes": in_size, "file_bytes": rep.file_bytes,
        "ratio_float32": rep.raw_bytes / rep.file_bytes,
        # a skeletal source's data are its channels: the joint positions (raw_float32_bytes)
        # are computed from them, so the ratio against the channels is the one that counts
        "channel_float32_bytes": channel_bytes,
        "ratio_channels_float32": None if channel_bytes is None
        else channel_bytes / rep.file_bytes,
        "ratio_input": None if in_size is None else in_size / rep.file_bytes,
        "max_error": err["max"], "arms": err["arms"],
        "p99": err["p99"], "rms": err["rms"], "declared_bound": rep.bound,
        "bound_rule": rep.bound_rule, **_kept(motion, rep, in_size),
        "grid_step": rep.step, "addh": rep.addh, "addh_rule": rep.addh_rule,
        "hierarchy": rep.hierarchy, "seconds": rep.seconds, "chunk_bytes": rep.chunk_bytes,
        "summary_bytes": rep.chunk_bytes.get("smrc", rep.chunk_bytes.get("smry")),
        "summary_levels": stored_levels,
        "summary_blocks": rep.summary_blocks,
        "summary_chunk": next((t for t in ("smrc", "smry") if t in rep.chunk_bytes), None),
        "skeleton": _skeleton_report(data),
        "nodes": [vars(n) for n in rep.nodes], "notes": notes, "warning": warning or None}
    results.append(result)
    code = found(EXIT_WARN if warning else EXIT_OK)
    if args.json or args.quiet:
        return code
    u = f" {units}" if units else " (input units)"
    print(f"{printable(job.input)} -> {printable(job.output)}: {rep.frames} frames x "
          f"{rep.markers} markers, {rep.seconds:.2f} s", file=out)
    insize = "?" if in_size is None else human_size(in_size)
    print(f"  size     raw float32 {human_size(rep.raw_bytes)}, input {insize}, "
          f"MPZ {human_size(rep.file_bytes)}", file=out)
    vs_input = ("" if result["ratio_input"] is None
                else f", {ratio_text(result['ratio_input'])}:1 vs input file")
    if result["ratio_input"] is None and result["dropped"]:
        vs_input = f", vs input file n/a ({'; '.join(result['dropped'])} not kept)"
    if channel_bytes is not None:
        print(f"  ratio    {ratio_text(result['ratio_channels_float32'])}:1 vs the "
              f"{motion.angles.shape[1]} channels as float32 ({human_size(channel_bytes)}), "
              f"{ratio_text(result['ratio_float32'])}:1 vs the joint positions{vs_input}", file=out)
    else:
        print(f"  ratio    {ratio_text(result['ratio_float32'])}:1 vs float32{vs_input}", file=out)
    _print_parts(result, out)
    bound = (" (no bound declared: --lossy)" if rep.bound is None
             else f" (bound {bound_text(rep.bound)}{u}: {rep.bound_rule})")
    layer = ("marker layer (what a 1.0 decoder reads; mpz decode computes the joints from "
             "the channels: skeleton below) " if result["bytes_skeleton"] else "")
    # max with the bound's digits: 0.3054 next to a bound of 0.305372 looked over it
    if err["max"] is None:
        print(f"  error    {layer}none measured: no sample of the input is valid{bound}",
              file=out)
    else:
        print(f"  error    {layer}max {err['max']:.6g}{u}{bound}, p99 {err['p99']:.4g}{u}, "
              f"ARMS {err['arms']:.4g}{u}", file=out)
    print(f"  grid     step {rep.step:.4g}{u}; ADDH {rep.addh:.4g}{u} ({rep.addh_rule}); "
          f"hierarchy {rep.hierarchy}", file=out)
    kind = result["summary_chunk"]
    if kind is not None:
        smry = rep.chunk_bytes[kind]
        stored = stored_levels
        asked = sorted(set(opts.summary))
        per = ("frame" if rep.summary_blocks <= 1 else
               f"block of {rep.summary_blocks} frames")
        clipped = ("" if stored == asked else
                   f" (asked {', '.join(map(str, asked))}: at most one segment a {per}, "
                   f"{rep.frames} frames)")
        pct = 100 * smry / rep.file_bytes
        share = f"{pct:.0f}" if pct >= 1 else f"{pct:.2g}"      # 0.46 %, not "0 %"
        blocks = ("" if rep.summary_blocks <= 1 else
                  f"; cuts on blocks of {rep.summary_blocks} frames (the exact partition is "
                  f"quadratic in the frames: spec Appendix C item 8)")
        print(f"  summary  {kind} chunk {human_size(smry)} ({share} % of the file), "
              f"k = {', '.join(str(k) for k in stored)}{clipped}{blocks}", file=out)
        if smry > rep.file_bytes - smry:
            # smry stores k x D means as raw 32-bit integers (spec §4.10); smrc (§4.15)
            # range-codes them (docs/summary-size.md)
            hint = ("; without --summary-format smry the coded smrc chunk is several times "
                    "smaller" if kind == "smry" else "")
            print(f"mpz encode: note: {printable(job.output)}: the summary is larger than the "
                  f"motion itself; fewer or smaller k shrink it{hint}", file=sys.stderr)
    _print_skeleton(result["skeleton"], units, out)
    if args.verbose:
        print("  chunks   " + ", ".join(f"{printable(t)} {human_size(n)}"
                                        for t, n in rep.chunk_bytes.items()), file=out)
    print("  node             markers segments patterns  L  pattern B  resid B  g", file=out)
    for n in rep.nodes:
        print(f"  {printable(n.name)[:16]:<16} {n.members:>7} {n.segments:>8} "
              f"{n.patterns:>8} {n.pattern_length:>3} {n.pattern_bytes + n.segment_bytes:>10} "
              f"{n.residual_bytes:>8} {n.residual_scale:>2}", file=out)
    return code


# ---------------------------------------------------- issue 13: skeletal input --
def _units(args: argparse.Namespace, motion, *, batch: bool = False):
    """--units: name the length unit of an input that has none (BVH). In a batch it names
    that of every such input, and leaves the others as they are (an error for one file)."""
    from mpz.skeleton import with_units
    if batch and args.units is not None and motion.units:
        return motion
    if args.units is None:
        lengths = [(o, v) for o, v in (("--max-error", args.max_error), ("--grid", args.grid),
                                        ("--translation-error", args.translation_error),
                                        ("--position-error", args.position_error))
                   if v is not None and v.strip()[-1:].isalpha()]
        if lengths and motion.units == "":
            option, text = lengths[0]
            fmt = motion.metadata.get("format", "").upper() or "this input"
            said = motion.metadata.get("units_in_file")
            # a TRC's Units field may hold a word that is no length unit: "TRC stores none"
            # was wrong of it (a QA run of stop 52)
            why = (f"its units {said!r} are not mm, cm, m or in" if said else
                   f"{fmt} stores none")
            raise EncoderError(f"{option} {text}: the input has no length unit ({why}); "
                               "name it with --units (mm, cm, m or in), e.g. "
                               "--units cm, or give a plain number in the file's own units")
        return motion
    return with_units(motion, args.units)


def _rate(args: argparse.Namespace, motion, *, batch: bool = False):
    """--rate: the frame rate of an input whose format stores none (:func:`with_rate`)."""
    from mpz.tools._common import with_rate
    return with_rate(motion, args.rate, batch=batch)


def _input_notes(args: argparse.Namespace, motion, source: str, *,
                 batch: bool = False) -> list[str]:
    """What the input itself makes the user want to know, said once per file (QA of issue
    15): an assumed rate, renamed markers, an MPZ input whose own error adds to the new
    one, and (one file) an --asf that a non-AMC input does not use."""
    from mpz.io._common import ext_of
    notes = []
    fmt = motion.metadata.get("format", "")
    if args.asf is not None and fmt != "amc" and not batch:
        notes.append(f"--asf changes nothing: the input is {fmt.upper() or 'not AMC'}, "
                     "not AMC")
    from mpz.tools._common import assumed_rate
    assumed = assumed_rate(motion, args.rate)
    if assumed:
        notes.append(assumed)
    from mpz.tools._common import renamed_list
    renamed = renamed_list(motion.metadata)
    if renamed:
        # a BVH or AMC written back keeps its joints' own names, as a C3D its labels: the
        # note said a BVH got the new ones (an animation studio's QA run of stop 75)
        # and a C3D its labels only from its archive (a BVH with --no-skeleton decoded to
        # C3D has the new names: the review of stop 75)
        keeps = ("a BVH or AMC written back keeps the joints' own names; other formats get "
                 "these names" if motion.extras.get("skeleton") is not None
                 and not args.no_skeleton else
                 "a C3D written back keeps the source's labels; other formats get these "
                 "names" if motion.extras.get("c3d") is not None else
                 "every format written back gets these names")
        notes.append(f"marker names that repeat or are empty were made unique: {renamed} "
                     f"({keeps})")
    if source != "-" and ext_of(source) == ".mpz":
        import mpz
        bound = mpz.info(source).error_bound
        if bound:
            unit = f" {motion.units}" if motion.units else ""
            notes.append(f"the input is an MPZ file, within {bound:g}{unit} of its own source: "
                         "the new bound is against its decoded motion, so against that "
                         "source the errors can add up")
    return notes


def _summary_of_mpz_input(args: argparse.Namespace, opts: EncodeOptions, source: str,
                          stdin_mpz: bytes | None) -> tuple[EncodeOptions, list[str]]:
    """An .mpz input's summary chunk (a file, or ``stdin_mpz``: the MPZ bytes standard
    input held), made again from its decoded motion with the same levels, space and chunk
    type unless --summary is given: a re-encode dropped it without a word (stop 49's
    list; from standard input too, a review of stop 50)."""
    from dataclasses import replace

    from mpz.io._common import ext_of
    mpz_input = stdin_mpz if source == "-" else source
    if args.summary is not None or mpz_input is None or (
            source != "-" and ext_of(source) != ".mpz"):
        return opts, []
    import mpz
    info = mpz.info(mpz_input)
    summary = mpz.read_summary(mpz_input) if info.summary_levels else None
    if summary is None:
        return opts, []
    chunk = "smrc" if "smrc" in info.chunk_bytes else "smry"
    ks = ",".join(str(k) for k in info.summary_levels)
    space, chunk = args.summary_space or summary.space, args.summary_format or chunk
    return (replace(opts, summary=tuple(info.summary_levels), summary_space=space,
                    summary_format=chunk),
            [f"the input's summary (k = {ks}) is made again from its decoded motion, as "
             f"{chunk} of the {space} (--summary K,... chooses other levels)"])


def _skeleton_options(args: argparse.Namespace, motion, opts: EncodeOptions, *,
                      batch: bool = False) -> tuple[EncodeOptions, list[str]]:
    """The skeleton options (spec §4.14) for a BVH or AMC/ASF input, and notes on what is
    not kept: --max-error bounds the joint positions computed from the channels too;
    without it the channels keep their default bound and the marker layer gets the
    reference encoder's preview bound (Appendix C).

    For one file, --angle-error and --translation-error on an input without a skeleton are
    an error. In a ``batch`` (:class:`PerFile`) they leave such inputs as they are, and a
    skeleton left out by --no-skeleton, or a part of the ASF, is not a note but the file's
    ``not_kept``."""
    from dataclasses import replace

    from mpz.tools._common import parse_length
    if motion.extras.get("skeleton") is None:
        if not batch and (args.angle_error is not None or args.translation_error is not None
                          or args.position_error is not None):
            raise EncoderError("--angle-error, --translation-error and --position-error apply "
                               "to skeletal input (BVH, AMC/ASF) only")
        if not batch and args.no_skeleton:
            return opts, ["--no-skeleton changes nothing: the input has no skeleton"]
        return opts, []
    # nothing is lost without a word: what the ASF held that the file does not keep is
    # among the reader's not_kept, a warning (run); a note here said it twice
    notes: list[str] = []
    if args.no_skeleton:
        if not batch:
            notes.append("--no-skeleton: the skeleton and its channels are not kept, only the "
                         "joint positions")
            # said here: a --translation-error in mm on a file without a unit has no
            # value to give the encoder's own note (mpz.encoder.option_notes); naming the
            # flags given alone, as that note does (a docs QA run of stop 74)
            given = [f for f, v in (("--angle-error", args.angle_error),
                                    ("--translation-error", args.translation_error),
                                    ("--position-error", args.position_error))
                     if v is not None]
            if given:
                notes.append(f"{' and '.join(given)} change{'s' * (len(given) == 1)} "
                             "nothing with --no-skeleton (no channels are coded)")
        return replace(opts, keep_skeleton=False), notes
    lin = _translation_error(args.translation_error, motion)
    # the marker layer's default is the preview bound (mpz.encoder.default_error); a given
    # --max-error bounds the joint positions too (mpz.encoder.resolve_bound), and
    # --position-error them alone: the smaller file for a BVH or AMC decoded back to one
    # (--max-error 1mm made cmu_10_01 49.3 KB, --position-error 1mm 34.7 KB: a QA run of
    # stop 75, which found no flag for it)
    pos = (None if args.position_error is None
           else parse_length(args.position_error, motion.units, "--position-error"))
    return replace(opts, angle_error=args.angle_error, translation_error=lin,
                   position_error=pos), notes


def _translation_error(text: str | None, motion) -> float | None:
    """--translation-error: a plain number in the skeleton's own length unit, or a length
    with a unit converted to it. With ``motion`` None only what needs no input is judged
    (the number's range, a length's syntax), as a usage error."""
    from mpz.skeleton import mm_per_unit
    from mpz.tools._common import check_length, parse_length
    if text is None:
        return None
    try:
        lin = float(text)                          # the skeleton's own length unit
    except ValueError:
        check_length(text, "--translation-error")
        if motion is None:
            return None
        per = mm_per_unit(motion)
        if per is None:
            raise EncoderError(f"--translation-error {text}: the input has no length "
                               "unit; name it with --units, or give a plain number in "
                               "the file's own units") from None
        return parse_length(text, "mm", "--translation-error") / per
    if not (math.isfinite(lin) and lin > 0):
        raise EncoderError(f"--translation-error {text}: give a finite length above 0")
    return lin


class PerFile:
    """The options of a ``mpz encode`` batch run as a corpus
    (:func:`~mpz.corpus.encode_corpus`; a :class:`~mpz.corpus.FileOptions`), made per
    file as the one-file path makes them: lengths converted to the file's units,
    ``--units`` naming those of a BVH, and a BVH's or AMC's skeleton bounds
    (:func:`_skeleton_options`: ``--max-error`` bounds its joint positions too). Its
    :meth:`key` names what the fingerprint of the options alone does not show, so that
    changing ``--units``, ``--angle-error``, ``--translation-error``, ``--position-error``
    or ``--no-skeleton`` encodes a file again. Sent to the workers (it pickles with the
    parsed arguments)."""

    #: the version of the skeleton rule in :meth:`key`: 1 since ``mpz encode -r`` applies
    #: it (before, a corpus gave a skeleton the default bounds, whatever --max-error said)
    SKELETON_RULE = 1

    def __init__(self, args: argparse.Namespace) -> None:
        self.args = args

    def options(self, units: str) -> EncodeOptions:
        return _options(self.args, units, None)

    def prepare(self, source: str, motion):
        motion = _rate(self.args, _units(self.args, motion, batch=True), batch=True)
        opts, notes = _skeleton_options(self.args, motion, self.options(motion.units),
                                        batch=True)
        return motion, opts, (_input_notes(self.args, motion, source, batch=True) + notes
                              + _option_notes(self.args, motion, opts))

    def key(self, source: str, own_units: bool) -> str:
        from mpz.io import SKELETON_FORMATS
        from mpz.io._common import ext_of
        from mpz.tools._common import RATELESS_FORMATS
        a = self.args
        # --units names the unit of a file without one, and leaves the others: it joins the
        # key of a source without a unit only, so that adding or changing --units for the
        # BVH files of an archive leaves its C3D files up to date (a QA run of stop 47 saw
        # every file encoded again; one of stop 48, those already in the unit named)
        parts = [f"units={a.units}"] if a.units is not None and not own_units else []
        if a.rate is not None and ext_of(source) in RATELESS_FORMATS:
            parts.append(f"rate={a.rate!r}")
        if ext_of(source) in SKELETON_FORMATS:
            parts += [f"skeleton={self.SKELETON_RULE}", f"angle={a.angle_error}",
                      f"translation={a.translation_error}", f"no_skeleton={a.no_skeleton}"]
            if a.position_error is not None:       # a key without it is as before
                parts.append(f"position={a.position_error}")
        return ",".join(parts)


def _skeleton_report(data: bytes) -> dict | None:
    from mpz.skeleton import report
    return report(data, end_sites=True)


def _print_skeleton(rep: dict | None, units: str, out) -> None:
    if rep is None:
        return
    u = f" {units}" if units else " (input units)"
    from mpz.skeleton import joints_text
    print(f"  skeleton {rep['chunk']} {rep['bytes']} B: "
          f"{joints_text(rep['joints'], rep.get('end_sites', 0))}, "
          f"{rep['channels']} channels; rotations within {bound_text(rep['angle_bound'])} deg, "
          f"translations within {bound_text(rep['translation_bound'])} (skeleton units); joint "
          f"positions within {bound_text(rep['position_bound'], 4)}{u}", file=out)


# --------------------------------------------------- issue 12: truthful sizes --
#: chunk types by part of the file: markers (the MPZ 1.0 critical chunks), analog, the rest


def _kept(motion, rep, in_size: int | None) -> dict:
    """Sizes by part, and the ratio against the input counting only what was kept: the whole
    input when nothing was dropped, else None and what was dropped."""
    from mpz.tools._common import parts_of
    cb = rep.chunk_bytes
    parts = parts_of(cb, rep.file_bytes)
    markers, analog, skeleton, rest = (parts[k] for k in ("markers", "analog", "skeleton",
                                                          "rest"))
    dropped = list(rep.not_kept)                  # mpz.encoder.not_kept: the one rule
    a = motion.extras.get("c3d")
    model = None
    if a is not None and a.models.shape[1]:
        model = {"outputs": int(a.models.shape[1]), "cpnt_bytes": cb.get("cpnt", 0)}
    ratio = None if in_size is None or dropped else in_size / rep.file_bytes
    return {"ratio_input": ratio, "dropped": dropped,
            "bytes_markers": markers, "bytes_analog": analog, "bytes_skeleton": skeleton,
            "bytes_rest": rest,
            "ratio_markers_float32": rep.raw_bytes / markers, "model_outputs": model,
            "analog_channels": None if a is None else a.channels}


def _print_parts(result: dict, out) -> None:
    from mpz.tools._common import human_size, ratio_text
    if result["bytes_skeleton"]:
        print(f"  parts    joint positions {human_size(result['bytes_markers'])} "
              f"({ratio_text(result['ratio_markers_float32'])}:1 vs float32), skeleton and "
              f"channels {human_size(result['bytes_skeleton'])}, the rest "
              f"{human_size(result['bytes_rest'])}", file=out)
    elif result["bytes_analog"] or result["bytes_rest"] > 200:
        ch = result["analog_channels"]
        exact = f" ({ch} channel{'s' * (ch != 1)}, exact)" if ch else ""
        print(f"  parts    markers {human_size(result['bytes_markers'])} "
              f"({ratio_text(result['ratio_markers_float32'])}:1 vs float32), analog "
              f"{human_size(result['bytes_analog'])}{exact}, parameters and the rest "
              f"{human_size(result['bytes_rest'])}", file=out)
    if result["model_outputs"]:
        mo = result["model_outputs"]
        n = mo["outputs"]
        print(f"  models   {n} model output{'s' * (n != 1)} (not markers) in their own units, "
              f"each axis within its declared bound (mpzinfo -vv: cpnt)", file=out)
