"""``mpz show FILE``: summarise a motion-capture input file.

Prints frames, markers, rate, units, duration, share of gaps and the
source format; ``--json`` gives the same as one JSON object (schema
version 1, numbers as numbers, ``null`` for unknown units and non-finite
numbers). A ``.mpz`` file is decoded and shown the same way (``mpzinfo``
dumps its chunks). ``-`` reads standard input, its format found from its
content. Names and metadata are printed escaped. Exit codes: 0 ok, 1 the
file was read with a warning (the ``warning`` line, or ``metadata.warning``
in JSON; the ``note`` line, ``metadata.reader_note``, says which reader read it and
why, and is no warning), 2 unreadable input (the dispatcher turns
:class:`mpz.errors.MPZError` into 2), 3 out of memory.
"""
from __future__ import annotations

import os
import sys

from mpz.errors import MPZError
from mpz.tools._cli import (
    EXIT_ERROR,
    EXIT_OK,
    EXIT_WARN,
    bound_text,
    found,
    json_failure,
    print_json,
    printable,
)

#: ``--json``'s schema (docs/json.md); 2: a name as every command's, and a failure's
#: document is ``mpz-error/1``
JSON_SCHEMA = "mpz-show/2"

#: the --help text (plain text: argparse shows it as it is)
DESCRIPTION = ("Summarise a motion-capture file (C3D, TRC, BVH, AMC, NPY, CSV) or a decoded "
               ".mpz: frames, markers, rate, units, duration, gaps and format. Exit 1 when "
               "the reader warned.")


def add_parser(subparsers):
    p = subparsers.add_parser("show", help="summarise a C3D/TRC/BVH/AMC/NPY/CSV or .mpz file",
                              description=DESCRIPTION)
    p.add_argument("file", help="input file (.c3d .trc .bvh .amc .npy .csv .mpz), or - for "
                   "standard input")
    p.add_argument("--asf", default=None,
                   help="ASF skeleton for an .amc file (default: found beside it)")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    from mpz.tools._cli import MAX_SAMPLES_HELP, max_samples
    p.add_argument("--max-samples", type=max_samples, default=None, metavar="N",
                   help=MAX_SAMPLES_HELP + "; .mpz input only")
    p.set_defaults(func=run)
    return p


def summary(motion, path: str) -> dict:
    """The facts ``mpz show`` reports, as a JSON-ready dict."""
    from mpz.io import FORMAT_NAMES
    from mpz.io._common import ext_of
    from mpz.metrics import rate_assumed

    return {
        "schema": JSON_SCHEMA,
        "file": path,
        "format": FORMAT_NAMES.get(ext_of(path)),
        "frames": motion.n_frames,
        "markers": motion.n_markers,
        "rate": motion.rate,
        # an AMC's or NPY's rate is the reader's assumption: show printed "120.0 Hz" as if
        # measured (an animation studio's QA run of stop 75)
        "rate_assumed": rate_assumed(motion),
        "units": motion.units or None,
        "duration": motion.duration,
        "gap_fraction": motion.gap_fraction,
        "skeletal": motion.parents is not None,
        "channels": None if motion.angles is None else int(motion.angles.shape[1]),
        "c3d": _archive(motion),
        "metadata": dict(motion.metadata),
    }


def _archive(motion) -> dict | None:
    """What a C3D holds beside its markers (the archive of spec §4.13,
    :meth:`mpz.c3darchive.C3DArchive.contents`), or None: before, show gave auckland's 54
    markers with 0 % gaps and said nothing of its 36 model outputs (12 % gaps), 24 analog
    channels or 12 events."""
    a = motion.extras.get("c3d")
    return None if a is None else a.contents()


def _metadata_lines(meta: dict[str, str]) -> list[str]:
    """The subject, and the free metadata's keys (not those a reader sets to describe the
    file it read: :data:`mpz.io.READER_KEYS`); ``--json`` gives every value."""
    from mpz.io import READER_KEYS
    lines = [f"subject:   {printable(meta['subject'])}"] if meta.get("subject") else []
    free = [k for k in meta if k not in READER_KEYS]
    if free:
        more = len(free) - 6
        lines.append(f"metadata:  {len(free)} entr{'ies' if len(free) != 1 else 'y'}: "
                     + ", ".join(printable(k) for k in free[:6])
                     + (f" and {more} more" if more > 0 else "") + " (--json: the values)")
    return lines


def _seconds(d: float) -> str:
    """A duration to the millisecond; one from a rate far from any capture's (spec §4.1
    allows any finite rate > 0) in exponent form, not hundreds of digits or "0.000"."""
    return f"{d:.3f}" if d == 0 or 1e-3 <= d < 1e9 else f"{d:.6g}"


def run(args) -> int:
    from mpz.container import scan
    from mpz.io import FORMAT_NAMES
    from mpz.tools._common import (
        declared_bound,
        joint_positions_from_channels,
        positions_bound,
        read_input_keeping,
    )

    path = args.file
    try:
        motion, ext, data = read_input_keeping(path, args.asf,
                                               max_samples=args.max_samples)
    except MPZError as exc:        # exit 2 as the dispatcher gives it, and with --json a
        if not args.json:          # document that says so, as mpzinfo --json gives one
            raise
        print(f"mpz show: error: {printable(str(exc))}", file=sys.stderr)
        print_json(json_failure("show", exc, path=path))
        return EXIT_ERROR
    info = summary(motion, path)
    info["format"] = "MPZ" if ext == ".mpz" else FORMAT_NAMES.get(ext or "")
    # an .mpz file's declared bound (None: none declared, or not an .mpz), as mpzinfo says;
    # and the one on the positions shown: for a skeletal file, the joints computed from
    # its channels, which MHDR's does not bound (a newcomer's QA run read it as theirs)
    info["error_bound"] = info["position_bound"] = None
    if data is not None:
        # MHDR alone, and nothing kept per unknown chunk (1.07 GB for 10^6 of them in a
        # valid 12 MB file: a security QA run, stop 73; spec §8)
        res = scan(data, keep_unknown=False, load=("MHDR",))
        info["error_bound"] = declared_bound(res)
        info["position_bound"] = positions_bound(motion, ext, data, res)
    code = found(EXIT_WARN if "warning" in motion.metadata else EXIT_OK)
    if args.json:
        # the reader's warning, as every command gives one with --json: on standard error
        # and in "warnings" (it was only inside "metadata", and stderr said nothing)
        info["warnings"] = [motion.metadata["warning"]] if "warning" in motion.metadata else []
        for w in info["warnings"]:
            print(f"mpz show: warning: {printable(path)}: {printable(w)}", file=sys.stderr)
        print_json(info)
        return code
    lines = [
        f"file:      {printable(os.path.basename(path))}",
        f"format:    {info['format']}",
        f"frames:    {info['frames']}",
        f"markers:   {info['markers']}" + (" (skeleton points)" if info["skeletal"] else ""),
        f"rate:      {info['rate']!r} Hz"
        + (" (assumed: the source stores none; mpz encode --rate gives the true one)"
           if info["rate_assumed"] else ""),
        f"units:     {info['units'] or 'unknown'}",
        f"duration:  {_seconds(info['duration'])} s",
        f"gaps:      {info['gap_fraction']:.2%}",
    ]
    if ext == ".mpz":
        bound = info["error_bound"]
        u = f" {info['units']}" if info["units"] else ""
        said = ("none declared" if bound is None else
                f"max error \u2264 {bound_text(bound)}{u} (declared)")
        if joint_positions_from_channels(motion, ext):
            joints = info["position_bound"]
            said = ("joints " + ("none declared" if joints is None else
                                 f"within {bound_text(joints)}{u} (declared)")
                    + f", computed from the channels; the marker layer: {said}")
        lines.append("bound:     " + said)
    if info["channels"] is not None:
        lines.append(f"channels:  {info['channels']}")
    c = info["c3d"]
    if c is not None:
        parts = [f"{c['storage']} points, first frame {c['first_frame']}"]
        if c["model_outputs"]:
            parts.append(f"{c['model_outputs']} model outputs (not markers; "
                         f"{c['model_gap_fraction']:.2%} gaps)")
        if c["analog_channels"]:
            parts.append(f"{c['analog_channels']} analog channels x "
                         f"{c['analog_samples_per_frame']} sample"
                         f"{'s' * (c['analog_samples_per_frame'] != 1)} a frame")
        if c["events"]:
            parts.append(f"{c['events']} events")
        if c.get("header_events"):
            parts.append(f"{c['header_events']} event{'s' * (c['header_events'] != 1)} "
                         "(header)")
        parts.append(f"{c['parameter_records']} parameter records")
        lines.append("c3d:       " + ", ".join(parts))
    lines += _metadata_lines(motion.metadata)
    from mpz.tools._common import renamed_list
    renamed = renamed_list(motion.metadata)
    if renamed:             # in --json's metadata alone (a QA run of exporters: a TRC name)
        lines.append("renamed:   marker names that repeat or are empty, made unique: "
                     + printable(renamed))
    if "reader_note" in motion.metadata:      # which reader, and why: not about the data
        lines.append(f"note:      {printable(motion.metadata['reader_note'])}")
    if "warning" in motion.metadata:
        lines.append(f"warning:   {printable(motion.metadata['warning'])}")
    print("\n".join(lines))
    return code
