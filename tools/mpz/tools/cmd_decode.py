"""``mpz decode IN.mpz... [-o OUT.{c3d,trc,npy,csv} | -o FOLDER/ | -o -]``: restore motions.

The output format is ``--format``, else the output's extension, else the
format of the source the file was encoded from (its ``source`` metadata).
``-`` is standard input or standard output (reports then go to stderr);
several inputs, or folders with ``-r``, go to ``-o FOLDER/`` (flat, or keeping the
folders below each ``-r`` folder with ``--mirror``) or beside each
input, and a failed input does not stop the others (exit 2 if any failed).
A motion a format cannot hold so that it reads back (a rate C3D stores as 0,
a marker name that breaks a TRC line, a TRC without units) is refused, and
what a format drops (NPY: names, rate, units) is said on stderr.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
from typing import TYPE_CHECKING

from mpz.errors import EncoderError, MPZError
from mpz.tools._cli import EXIT_OK, EXIT_WARN, found, printable

if TYPE_CHECKING:
    from mpz.motion import Motion

#: --format choices, as extensions
FORMATS = ("c3d", "trc", "npy", "csv", "bvh", "amc")


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("decode", help="decompress .mpz to C3D, TRC, BVH, AMC, NPY or CSV",
                       description="Decode MPZ files. NPY output is float64 [frames, markers, 3] "
                       "in the input's marker order and units, NaN for gaps; for a file "
                       "with a skeleton (BVH, AMC), the joint positions its channels give "
                       "(spec §6.10), not the marker layer that mpz.decode returns.")
    p.add_argument("inputs", nargs="+", metavar="INPUT",
                   help=".mpz files, folders (with -r), or - for standard input")
    p.add_argument("-o", "--output", help="OUT.c3d, OUT.trc, OUT.bvh, OUT.amc (with its ASF; "
                   "both need the file's skeleton), OUT.npy or OUT.csv, FOLDER/ for "
                   "several inputs (made if missing), - for standard output, or /dev/null to "
                   "write and drop it (written atomically; default: beside each input)")
    p.add_argument("--asf", metavar="PATH", help="AMC output: where to write its ASF skeleton "
                   "(default: beside the AMC, with its name)")
    p.add_argument("-F", "--format", choices=FORMATS,
                   help="output format (default: from the output name, else the format the "
                   "file was encoded from)")
    p.add_argument("-r", "--recursive", action="store_true",
                   help="decode every .mpz file in the folders given as inputs")
    p.add_argument("--mirror", action="store_true",
                   help="with -r and -o FOLDER/: keep each file's path below the folder given "
                   "as input (-r IN with IN/s01/walk.mpz -> FOLDER/s01/walk.c3d), as zstd's "
                   "--output-dir-mirror; default: every output in FOLDER/ itself")
    p.add_argument("-f", "--force", action="store_true", help="replace OUTPUT if it exists, "
                   "write --format under another extension, or write to a terminal")
    p.add_argument("-q", "--quiet", action="store_true",
                   help="print nothing on success; warnings (exit 1) are still printed")
    p.add_argument("-v", "--verbose", action="store_true",
                   help="also print the file's metadata")
    from mpz.tools._cli import max_samples, max_samples_help
    p.add_argument("--max-samples", type=max_samples, default=None, metavar="N",
                   help=max_samples_help("decoding and writing need about 60 bytes per "
                                         "marker-frame, 95 for a C3D"))
    p.set_defaults(func=run)


def _source_ext(meta: dict[str, str] | object) -> str | None:
    """The writable extension of the file the MPZ was encoded from, if recorded: its name's
    (``source``), else the format its reader recorded (``format``: a file encoded from
    standard input has no name, and could not be decoded without -o or --format, a QA run
    of stop 53)."""
    from mpz.io import WRITERS
    from mpz.io._common import ext_of
    if not isinstance(meta, dict):
        return None
    src = meta.get("source")
    for ext in (ext_of(src) if src else "", "." + str(meta.get("format", "")).lower()):
        if ext in WRITERS:
            return ext
    return None


def _name_for(args: argparse.Namespace, path: str) -> str | None:
    import mpz
    from mpz.errors import InputFormatError
    from mpz.io import FORMAT_NAMES, SKELETON_FORMATS
    stem = os.path.splitext(path)[0]
    if args.format:
        return _with_ext(stem, f".{args.format}")
    try:                              # a motion file named: what to do instead, as below
        with open(path, "rb") as fh:
            head = fh.read(4096)
    except OSError:                   # mpz.info says what is wrong
        head = None
    if head is not None:
        _refuse_other_formats(head, path)
    info = mpz.info(path)
    ext = _source_ext(dict(info.metadata))
    if ext in SKELETON_FORMATS and not {"bvhs", "asfs"} & set(info.chunk_bytes):
        # encoded with --no-skeleton: its own format cannot be written (a newcomer's QA
        # run met the writer's refusal, naming an output nobody had asked for)
        raise InputFormatError(f"it was encoded from {FORMAT_NAMES[ext]} without its "
                               f"skeleton (--no-skeleton), which {FORMAT_NAMES[ext]} output "
                               "needs: give --format npy or csv (c3d or trc: with units), "
                               "or -o with one of those extensions", path=path)
    if ext is None:
        return None
    # the source's own spelling of it: walk.C3D came back as walk.c3d, and a mirrored tree
    # with other names (a corpus QA run)
    return _with_ext(stem, ext, os.path.splitext(str(info.metadata.get("source", "")))[1])


def _with_ext(stem: str, ext: str, own: str = "") -> str:
    """``stem`` with the extension ``ext`` (lower case, with its dot), spelled ``own`` when
    that is the same one in other case; ``stem`` itself when it already ends in it:
    walk.c3d.mpz (``mpz encode --keep-extension``) gives walk.c3d, not walk.c3d.c3d."""
    if os.path.splitext(stem)[1].lower() == ext:
        return stem
    return stem + (own if own.lower() == ext else ext)


def run(args: argparse.Namespace) -> int:
    from mpz.io._common import ext_of
    from mpz.tools._cli import EXIT_USAGE
    from mpz.tools._common import STDIO, UsageError, plan_batch, run_batch

    try:
        jobs = plan_batch(args.inputs, args.output, recursive=args.recursive,
                          mirror=args.mirror,
                          accept=lambda name: ext_of(name) == ".mpz",
                          name_for=lambda path: _name_for(args, path), what="decoded")
    except UsageError as exc:
        print(f"mpz decode: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    problem = _asf_usage(args, jobs)
    if problem:
        print(f"mpz decode: error: {problem}", file=sys.stderr)
        return EXIT_USAGE
    report = sys.stderr if any(j.output == STDIO for j in jobs) else sys.stdout
    return run_batch("decode", jobs, lambda job: _decode_one(job, args, report),
                     report=report, quiet=args.quiet)


def _asf_usage(args: argparse.Namespace, jobs: list) -> str | None:
    """Why ``--asf`` cannot be used with these jobs, checked before anything is written (a
    QA run: ``-o a.amc --asf a.amc`` wrote the ASF, then refused or replaced it with the
    AMC; ``--asf -`` made a file named ``-``), or None."""
    from mpz.api import _same_file
    from mpz.tools._common import STDIO
    if args.asf is None:
        return None
    if args.asf == STDIO:
        return ("--asf -: the ASF cannot go to standard output (the AMC is the output); "
                "give the ASF a file name")
    if len(jobs) > 1:
        return "--asf names one file: with it, decode one input at a time"
    for job in jobs:
        if job.output not in (None, STDIO) and _same_file(args.asf, job.output):
            return (f"--asf {printable(args.asf)} and -o {printable(job.output)} name the "
                    "same file: the ASF and the AMC need a file each")
        if job.input != STDIO and _same_file(args.asf, job.input):
            return f"--asf {printable(args.asf)} is the input file"
    return None


def _target_ext(args: argparse.Namespace, output: str, motion: object = None) -> str:
    """The extension to write ``output`` in; refuses a name that does not say that format."""
    from mpz.api import is_null_device
    from mpz.io import WRITERS
    from mpz.io._common import ext_of
    from mpz.tools._common import STDIO
    if output == STDIO or is_null_device(output):     # no name to take a format from
        if args.format:
            return "." + args.format
        ext = _source_ext(getattr(motion, "metadata", None))
        if ext is None:
            where = "standard output" if output == STDIO else output
            raise EncoderError(f"writing to {where} needs --format ({', '.join(FORMATS)})")
        return ext
    name_ext = ext_of(output)
    if args.format:
        ext = "." + args.format
        if name_ext != ext and not args.force:
            raise EncoderError(f"{output}: --format {args.format} under a name ending in "
                               f"{name_ext or '(no extension)'!r}; use --force to write it "
                               "under this name")
        return ext
    if name_ext not in WRITERS:
        raise EncoderError(f"{output}: cannot write {name_ext or '(no extension)'!r} files; "
                           f"can write {', '.join(WRITERS)} (or choose one with --format)")
    return name_ext


def _decode_one(job, args: argparse.Namespace, out) -> int:
    from mpz.api import atomic_output, check_output, is_null_device
    from mpz.io import READ_BACK_NOTE, SKELETON_FORMATS, check_writable, write
    from mpz.tools._common import (
        MPZ_EXPANSION,
        STDIO,
        compile_notice,
        input_size,
        joint_positions_from_channels,
        stage,
        write_stdout,
    )

    source = None if job.input == STDIO else job.input
    size = input_size(job.input) * MPZ_EXPANSION          # what the .mpz decodes to, about
    to_stdout = job.output == STDIO
    # every check on the output comes before the decode
    if not to_stdout:
        check_output(job.output, force=args.force, source=source)
    # standard output and the null device have no name to take a format from: without
    # --format, the format the file was encoded from, known once it is read (None here)
    nameless = to_stdout or is_null_device(job.output)
    ext = None if nameless and not args.format else _target_ext(args, job.output)
    asf = _asf_output(args, job.output, ext, source)
    compile_notice(args.quiet, args.verbose, announce=False)
    # a skeletal file's joint positions come from its channels (read_mpz_input, §6.10)
    stage("decode", args.quiet, size, f"decoding {printable(job.input)}")
    motion, bound, skipped = _read_mpz(job.input, args.max_samples)
    if ext is None:
        ext = _target_ext(args, job.output, motion)
        if ext == ".amc" and not to_stdout:
            asf = _asf_output(args, job.output, ext, source)
    if to_stdout:
        if ext in (".npy", ".c3d") and not args.force and sys.stdout.isatty():
            raise EncoderError("refusing to write binary data to a terminal; redirect "
                               "standard output, or use -f", path=STDIO)
    found(EXIT_OK)                              # before -o - writes to standard output
    notes = check_writable(motion, ext, path=job.output, bound=bound)
    if skipped:
        many = len(skipped) != 1
        notes.append(f"the file's unknown ancillary chunk{'s' * many} "
                     f"{', '.join(repr(t) for t in skipped)} "
                     f"{'were' if many else 'was'} skipped (spec §2.3: a decoder ignores "
                     "what it does not know)")
    said = motion.metadata.get("warning")
    if said:
        # what the reader said of the source when it was encoded, which the file keeps: it
        # often says what readers find in the file written back (Dance1: groups past the
        # declared parameter blocks), and only encode, show and decode -v said it (an
        # interop QA run of stop 64)
        notes.append(f"its source was read with a warning when it was encoded (kept in the "
                     f"file's metadata): {said}")
    if ext not in SKELETON_FORMATS and joint_positions_from_channels(motion, ".mpz"):
        notes.append("its positions are the joint positions computed from the skeleton's "
                     "channels (spec §6.10), not the file's marker layer (what a 1.0 decoder "
                     "reads, within MHDR's bound)")
    if not args.quiet:
        for note in notes:
            print(f"mpz decode: note: {printable(job.output)}: {printable(note)}",
                  file=sys.stderr)
    stage("decode", args.quiet, size, f"writing {printable(job.output)}")
    if to_stdout:
        import signal

        from mpz.api import signals_exit
        # SIGTERM and SIGHUP end the command through the folder's cleanup: they left it,
        # sometimes with a partial copy, in $TMPDIR (a QA run of stop 49)
        with signals_exit(signal.SIGTERM, getattr(signal, "SIGHUP", None)), \
                tempfile.TemporaryDirectory(prefix="mpz-decode-") as d:
            tmp = os.path.join(d, "stdout" + ext)
            if ext == ".amc" and asf is None:     # issue 13: the ASF goes to --asf
                asf = _asf_output(args, STDIO, ext, source)
            if asf is not None:
                with atomic_output(asf, force=args.force, source=source) as tmp_asf:
                    written = write(motion, tmp, file_name="", asf=tmp_asf, atomic=False)
            else:
                written = write(motion, tmp, file_name="", atomic=False)
            with open(tmp, "rb") as fh:
                write_stdout(fh.read(), binary=ext in (".npy", ".c3d"), force=True)
    else:
        with atomic_output(job.output, force=args.force, source=source, suffix=ext) as tmp:
            try:
                if asf is not None:          # issue 13: AMC output writes its ASF too
                    with atomic_output(asf, force=args.force, source=source) as tmp_asf:
                        written = write(motion, tmp, file_name=os.path.basename(job.output),
                                        asf=tmp_asf, atomic=False)
                else:
                    written = write(motion, tmp, file_name=os.path.basename(job.output),
                                    atomic=False)
            except MPZError as exc:  # name the output, not the temporary file
                if exc.path == tmp:
                    exc.path = job.output
                raise
    # what the file written reads back otherwise (a C3D of an archive made by hand, spec
    # §6.9): a warning, -q too, since the file is not what a reader will see (a fuzzing QA
    # run of stop 54 found such files written with exit 0)
    late = [n for n in written if n.startswith(READ_BACK_NOTE)]
    for warning in late:
        print(f"mpz decode: warning: {printable(job.output)}: {printable(warning)}",
              file=sys.stderr)
    if not args.quiet:
        print(f"{printable(job.input)} -> {printable(job.output)}: {motion.n_frames} frames x "
              f"{motion.n_markers} markers, {motion.rate:g} Hz, gaps {motion.gap_fraction:.1%}",
              file=out)
        if args.verbose:
            for k, v in motion.metadata.items():
                print(f"  {printable(k)}: {printable(v)}", file=out)
    return found(EXIT_WARN) if late else EXIT_OK


def _read_mpz(path: str, max_samples: int | None
              ) -> tuple[Motion, float | None, list[str]]:
    """Decode an MPZ input (a file or ``-``) as :func:`mpz.tools._common.read_mpz_input`
    does, with the bound it declares on those positions (None: none declared; a skeletal
    file's position_bound) for the notes on what the output's number format adds to it,
    and the unknown ancillary chunks the decoder skipped. An input that is another motion
    format is named, with what to do instead."""
    from mpz.api import read_source
    from mpz.container import scan
    from mpz.errors import FormatError
    from mpz.tools._common import STDIO, positions_bound, read_mpz_input_bytes, read_stdin
    if path == STDIO:
        data, fmt = read_stdin()
        if fmt != ".mpz":
            raise FormatError(f"standard input is not an MPZ file (first bytes {data[:8]!r})"
                              + _not_mpz_hint(fmt), path=STDIO)
        motion = read_mpz_input_bytes(data, max_samples)
    else:
        data = read_source(path)[0]
        _refuse_other_formats(data[:4096], path)
        try:
            motion = read_mpz_input_bytes(data, max_samples)
        except MPZError as exc:
            exc.path = path
            raise
    # the decode above checked every chunk; the skipped ones are counted, not kept
    res = scan(data, keep_unknown=False)
    # the joints of a skeleton's channels: position_bound is theirs, not MHDR's (a QA of
    # stop 48: a C3D's float32 note quoted MHDR's)
    return motion, positions_bound(motion, ".mpz", data, res), list(res.skipped)


def _refuse_other_formats(head: bytes, path: str) -> None:
    """Raise FormatError, saying what to do instead, for a file whose first bytes ``head``
    are those of another motion format (spec §3.1); anything else is left to the decoder.
    """
    from mpz.errors import FormatError
    from mpz.format import SIGNATURE
    from mpz.io import detect_format
    from mpz.io._common import ext_of
    if head.startswith(SIGNATURE):
        return
    hint = _not_mpz_hint(detect_format(head))
    if not hint and ext_of(path) == ".asf":          # a skeleton alone: no motion format
        hint = (": this is an ASF skeleton; mpz encode compresses the AMC motion that "
                "goes with it (the ASF beside it is found, or give --asf)")
    if hint:
        raise FormatError(f"not an MPZ file (first bytes {head[:8]!r}){hint}", path=path,
                          section="§3.1")


def _not_mpz_hint(fmt: str | None) -> str:
    """``: this is a C3D file; ...`` for input of a motion format, else ``""``."""
    from mpz.io import FORMAT_NAMES
    if fmt is None or fmt == ".mpz" or fmt not in FORMAT_NAMES:
        return ""
    name = FORMAT_NAMES[fmt]
    article = "an" if name[0] in "AEFHILMNORSX" else "a"      # an AMC, an NPY, a C3D
    return (f": this is {article} {name} file; use mpz encode to compress it "
            "(mpz show summarises it)")


# ------------------------------------------------- issue 13: skeletal output --
def _asf_output(args: argparse.Namespace, output: str, ext: str | None,
                source: str | None) -> str | None:
    """Where AMC output writes its ASF (checked like the output itself), else None."""
    from mpz.api import check_output, is_null_device
    from mpz.io.amc import default_asf_path
    from mpz.tools._common import STDIO
    if ext != ".amc":
        if args.asf is not None and ext is not None:
            raise EncoderError(f"--asf is for AMC output; {printable(output)} is {ext}")
        return None
    if args.asf is None and output == STDIO:
        raise EncoderError("AMC on standard output needs --asf PATH for its ASF skeleton")
    if args.asf is None and is_null_device(output):
        return os.devnull                   # discarded with the AMC
    asf = args.asf if args.asf is not None else default_asf_path(output)
    check_output(asf, force=args.force, source=source)
    return asf
