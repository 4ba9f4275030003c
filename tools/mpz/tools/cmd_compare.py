"""``mpz compare ORIGINAL DECODED``: error statistics, overall and per marker.

Either input may be ``-`` (standard input, format found from its content).
An .mpz of a BVH or AMC is compared as ``mpz decode`` writes it: the joint positions
computed from its skeleton's channels (the report says so), not its marker layer.
``--asf`` names an AMC original's skeleton; an AMC decoded input is read with the .asf
beside it, which ``mpz decode`` writes (``--decoded-asf`` names another; with neither,
``--asf``'s is used, its skeleton reported "unchecked").
Against a decoded .mpz input the marker errors are held to the bound it declares, as spec
§7.2 states the check; for the joint positions of a skeletal one, to its skeleton chunk's
position_bound (§4.14: the joints of the decoded channels against the source's; none when
it is 0); a sample beyond it, or a marker the decoded input adds, exits 2. When both
inputs are .mpz files (two encodes of one source: two bounds, two versions), neither is
the source: they are held to the sum of their bounds, and their sizes and bounds are
shown (byte-identical files are said to be).
Two frame rates that differ are an error (exit 2; an NPY stores none: not checked). A
reader's warning about a motion-file input (a file cut short, a C3D archive it could not
keep) is printed, and exits 1 unless something exits 2.
Lengths in two known units (mm, cm, m, in) are converted to the original's before
comparing; an input without units against one with units is compared as numbers, the
figures in the unit there is. Both are said on stderr.
Besides the markers, each part a source keeps is compared too: its metadata (a TRC's
header fields), a C3D's header, parameters (with the events), the points' residual and
camera words, analog words and model outputs, and a BVH's or AMC's skeleton and joint
channels: the same bit for bit, within the bound the .mpz input declares (model
outputs, one part per kind in its POINT:*_UNITS; joint channels, by the steps of its
skeleton chunk), changed (no bound declared: where it changed most; metadata with other
values between files in other units), differs (exit 2, saying where first) or missing
from the decoded motion (a note: a format that cannot hold the part, as ``mpz decode``
says); between two .mpz files, which hold every part, a part either lacks differs, and
the entries their readers wrote of the source are shown as "reader metadata". An NPY
input (no names) is matched with the other marker by marker in order, with
a note.
``--plot OUT.png`` draws the Euclidean error over time of the worst markers
(or ``--marker``), one panel each, in the motion's units, with the declared
bound (from an .mpz input, or ``--bound``) as a line and one legend for all
panels. Names are printed escaped; ``--json`` is strict JSON (``null`` for
non-finite values).
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import os
from typing import Any

import numpy as np

from mpz.errors import MotionError
from mpz.metrics import (  # one rule for compare and metrics
    RATE_TOLERANCE,
    rate_assumed,
    same_frame_time,
)
from mpz.tools._cli import bound_text, count, print_json, printable
from mpz.tools._common import check_plot, plot_format

#: ``--json``'s schema (docs/json.md)
JSON_SCHEMA = "mpz-compare/1"


def add_parser(sub):
    p = sub.add_parser("compare", help="error statistics between two motions (any format)",
                       description="Compare a decoded motion with its original: max, p99, RMS "
                       "and ARMS (paper Eq. 3), overall and per marker; optional plot of the "
                       "error over time. Then each part the original keeps besides its "
                       "markers (metadata; a C3D's header, parameters, analog and model "
                       "outputs; a skeleton and its channels): the same, within the declared "
                       "bound, changed, missing, or differs (exit 2). A reader's warning "
                       "about an input (a file cut short) exits 1.")
    p.add_argument("original", help="original motion file, or - for standard input")
    p.add_argument("decoded", help="decoded motion or .mpz file, or - for standard input")
    p.add_argument("--asf", help="skeleton of an AMC original")
    p.add_argument("--decoded-asf", metavar="ASF", help="skeleton of an AMC decoded input "
                   "(default: the .asf beside it, as mpz decode writes it; else --asf's, "
                   "with a note that its skeleton is then not checked)")
    p.add_argument("--marker-layer", action="store_true",
                   help="compare the marker layer of an .mpz input (spec §6.8, what a 1.0 "
                   "decoder reads, held to its MHDR bound) in place of the joint positions "
                   "of its skeleton's channels, and the markers alone: no part besides "
                   "them. Two versions' encodes of one BVH or AMC, one with a skeleton "
                   "chunk and one without, are then compared like with like")
    from mpz.tools._cli import max_samples, max_samples_help
    p.add_argument("--max-samples", type=max_samples, default=None, metavar="N",
                   help=max_samples_help("decoding and comparing two .mpz files need about "
                                         "140 bytes per marker-frame") + "; .mpz inputs")
    p.add_argument("--json", action="store_true",
                   help="print the statistics as one JSON document (strict JSON: NaN and "
                   "infinity are null; an error the text shows as inf is a valid sample "
                   "that became a gap, counted in valid_became_gap, or an overflow)")
    p.add_argument("--top", type=count, default=10, help="markers to list, worst first "
                   "(default 10; 0 for all)")
    p.add_argument("--plot", metavar="PNG", help="plot the error over time of the worst "
                   "markers, with the bound as a line (needs matplotlib)")
    p.add_argument("--marker", action="append", help="marker(s) to plot instead of the worst")
    p.add_argument("-f", "--force", action="store_true", help="replace the --plot file if it "
                   "exists")
    p.add_argument("--bound", metavar="E", help="bound to draw on --plot, with a unit (default: "
                   "the one declared in an .mpz input); drawn only: the check is against the "
                   "bound an .mpz declares")
    p.set_defaults(func=run)


def align(a, b, unnamed: list[str] | None = None, notes: list[str] | None = None):
    """Reorder ``b``'s markers to ``a``'s names; when an input stores no names (NPY, named
    in ``unnamed``), take them in order, with a note."""
    if a.names == b.names:
        return b
    if unnamed:
        if a.n_markers != b.n_markers:
            raise MotionError(f"{' and '.join(unnamed)}: NPY stores no marker names, and the "
                              f"marker counts differ ({a.n_markers} vs {b.n_markers}): "
                              "nothing says which marker is which")
        if notes is not None:
            notes.append(f"{' and '.join(unnamed)}: NPY stores no marker names; markers "
                         "compared in order")
        from mpz.motion import Motion
        return Motion(b.positions, list(a.names), b.rate, b.units, b.valid,
                      metadata=b.metadata)     # its format: an NPY's rate is not compared
    index = {n: i for i, n in enumerate(b.names)}
    missing = [n for n in a.names if n not in index]
    if missing:
        # a renamed marker was told as missing alone, the new name unsaid (a report QA run
        # of stop 55)
        known = set(a.names)
        new = [n for n in b.names if n not in known]
        more = len(missing) - 5
        raise MotionError("markers missing from the decoded motion: "
                          f"{', '.join(printable(n) for n in missing[:5])}"
                          + (f" and {more} more" if more > 0 else "")
                          + (f"; it has markers the original has not: "
                             f"{', '.join(printable(n) for n in new[:5])}"
                             + (f" and {len(new) - 5} more" if len(new) > 5 else "")
                             if new else ""))
    order = [index[n] for n in a.names]
    from mpz.motion import Motion
    return Motion(b.positions[:, order], list(a.names), b.rate, b.units, b.valid[:, order],
                  metadata=b.metadata)


def _declared_bound(path: str | bytes, units: str, *, joints: bool = False) -> float | None:
    """The bound an .mpz file (a path, or its bytes) declares, converted to ``units``
    (None if none or unknown): MHDR's on the markers, or with ``joints`` its skeleton
    chunk's position_bound on the joint positions of its channels (§4.14; 0: none)."""
    from mpz.io._common import ext_of
    if isinstance(path, str) and ext_of(path) != ".mpz":
        return None
    import mpz
    from mpz.format import MM_PER_UNIT
    fi = mpz.info(path)
    bound = fi.error_bound
    if joints:
        from mpz.skeleton import report
        data = path if isinstance(path, bytes) else open(path, "rb").read()
        rep = report(data)
        pb = rep["position_bound"] if rep is not None else 0.0
        assert isinstance(pb, float)
        bound = pb if pb > 0 else None
    if bound is None:
        return None
    if fi.units == units or not (fi.units in MM_PER_UNIT and units in MM_PER_UNIT):
        return bound
    return bound * MM_PER_UNIT[fi.units] / MM_PER_UNIT[units]


def _decoded_asf(args: argparse.Namespace) -> tuple[str | None, bool, list[str]]:
    """The skeleton to read an AMC decoded input with, whether it is ``--asf``'s in place
    of its own, and a note naming the one found: ``--decoded-asf``; else its own, the .asf
    beside it that ``mpz decode`` writes (so that a skeleton that came back different is
    seen); else ``--asf``'s (standard input: no .asf beside it).

    Raises
    ------
    InputFormatError
        An AMC decoded input with neither an .asf beside it nor an option naming one.
    """
    from mpz.io._common import ext_of
    if args.decoded_asf is not None:
        return args.decoded_asf, False, []
    if args.decoded == "-":
        return args.asf, args.asf is not None, []
    if ext_of(args.decoded) != ".amc":
        return args.asf, False, []                 # not an AMC by its name: not used
    from mpz.errors import InputFormatError
    from mpz.io.amc import find_asf
    try:
        found = find_asf(args.decoded)
    except InputFormatError as exc:
        if args.asf is not None:
            return args.asf, True, []
        raise InputFormatError(f"no .asf skeleton found beside the decoded "
                               f"{os.path.basename(args.decoded)}; name it: --decoded-asf "
                               "PATH", path=args.decoded) from exc
    stem = os.path.splitext(os.path.basename(args.decoded))[0]
    own = os.path.splitext(os.path.basename(found))[0] == stem
    return found, False, [] if own else [f"{_label(args.decoded)} is read with "
                                         f"{printable(found)} (the .asf beside it whose name "
                                         "begins its name); --decoded-asf names another"]




def _label(path: str) -> str:
    return "standard input" if path == "-" else printable(path)


def _positions(motion, ext: str | None) -> str:
    """What an input's positions are, for the report."""
    from mpz.tools._common import joint_positions_from_channels
    if joint_positions_from_channels(motion, ext):
        return ("joint positions from the skeleton's channels (as mpz decode writes them, "
                "not the file's marker layer)")
    return "decoded markers" if ext == ".mpz" else "as read"


def check_rates(a, b, ext_a: str | None, ext_b: str | None, names: tuple[str, str]) -> list[str]:
    """Refuse two motions at different frame rates (the same frame is not the same time);
    return the notes (an NPY input stores no rate, an AMC's is assumed: not checked).

    Raises
    ------
    MotionError
        Saying both rates.
    """
    unknown = [n for n, e in zip(names, (ext_a, ext_b), strict=True) if e == ".npy"]
    if unknown:
        return [f"{' and '.join(unknown)}: NPY stores no frame rate; rates not compared"]
    close = math.isclose(a.rate, b.rate, rel_tol=RATE_TOLERANCE)
    # an AMC's rate is its reader's assumption (120 Hz): one encoded with --rate 60, as
    # the README says, could never be compared with its source (a QA run of stop 53)
    pairs = [(n, m) for n, m in zip(names, (a, b), strict=True) if rate_assumed(m)]
    if pairs and not close:
        said = ("an AMC stores no frame rate" if all(m.metadata.get("format") == "amc"
                                                     for _, m in pairs)
                else "its reader assumed the frame rate")       # a one-row CSV's
        return [f"{' and '.join(f'{n} ({m.rate:g} Hz assumed)' for n, m in pairs)}: {said}; "
                f"rates not compared ({a.rate:g} vs {b.rate:g} Hz), the frames taken in order"]
    if not close and same_frame_time(a, b):
        return [f"rates {a.rate:.10g} and {b.rate:.10g} Hz are one BVH Frame Time "
                f"({a.metadata['frame_time']} s) rounded two ways (mpz read a Frame Time of "
                "0.008333 as 120.0048 Hz before it snapped it to 120): the frames compared "
                "in order"]
    if not close:
        raise MotionError(f"frame rates differ: {a.rate:.10g} Hz ({names[0]}) vs "
                          f"{b.rate:.10g} Hz "
                          f"({names[1]}); the same frame is not the same moment, so the "
                          "positions are not compared")
    return []


def common_units(a, b, names: tuple[str, str]):
    """``b`` in ``a``'s length unit when both have one (mm, cm, m, in), the unit the
    figures are in (``""``: none known) and the notes.

    An input without units (BVH, NPY) against one with units is compared as numbers,
    and the figures take the unit of the one that has them."""
    from mpz.format import MM_PER_UNIT
    from mpz.motion import Motion
    if a.units == b.units:
        return b, a.units, []
    if a.units in MM_PER_UNIT and b.units in MM_PER_UNIT:
        scale = MM_PER_UNIT[b.units] / MM_PER_UNIT[a.units]
        note = (f"{names[1]} is in {b.units}, {names[0]} in {a.units}: lengths converted "
                f"to {a.units} (x {scale:g}) before comparing")
        return (Motion(b.positions * scale, b.names, b.rate, a.units, b.valid,
                       metadata=b.metadata), a.units, [note])
    has, lacks = (a, names[1]) if a.units else (b, names[0])
    return b, has.units, [f"{lacks} has no length unit, "
                          f"{names[0] if a.units else names[1]} is in {has.units}: compared "
                          f"as numbers (figures in {has.units})"]


def run(args: argparse.Namespace) -> int:
    import sys

    from mpz.errors import EncoderError
    from mpz.metrics import besides_markers, summary
    from mpz.motion import READER_NOT_KEPT
    from mpz.skeleton import channel_bounds
    from mpz.tools._cli import EXIT_USAGE, found
    from mpz.tools._common import (
        check_length,
        joint_positions_from_channels,
        parse_length,
        read_input_keeping,
    )
    if args.original == "-" and args.decoded == "-":
        # a usage error (64), as mpz bench --compare - - says it (a CLI audit: exit 2)
        print("mpz compare: error: only one of the two inputs can be standard input (-)",
              file=sys.stderr)
        return EXIT_USAGE
    try:                        # a usage error (64), as encode's lengths: not an input error
        check_length(args.bound, "--bound")
    except EncoderError as exc:
        print(f"mpz compare: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    if args.plot:  # a bad plot path fails before the work
        check_plot(args.plot, args.force, (args.original, args.decoded))
        _matplotlib()
    names = (_label(args.original), _label(args.decoded))
    layer = args.marker_layer
    a, ext_a, data_a = read_input_keeping(args.original, args.asf, max_samples=args.max_samples,
                                          marker_layer=layer)
    asf_b, borrowed, asf_found = _decoded_asf(args)
    b, ext_b, data_b = read_input_keeping(args.decoded, asf_b, max_samples=args.max_samples,
                                          marker_layer=layer)
    # the readers' warnings (a file cut short; a C3D archive dropped, whose analog data
    # then went unnoticed on both sides) were dropped, exit 0 (a QA run of stop 53); an
    # .mpz file's is its source's, which encoding said
    warned = [f"{printable(path)}: {printable(m.metadata['warning'])}"
              for path, m, ext in ((args.original, a, ext_a), (args.decoded, b, ext_b))
              if ext != ".mpz" and m.metadata.get("warning")]
    for w in warned:                # -q has no meaning here; printed as encode prints it
        print(f"mpz compare: warning: {w}", file=sys.stderr)
    notes = check_rates(a, b, ext_a, ext_b, names) + asf_found
    # what a source's reader does not keep (an ASF's LENGTH respelled, an AMC's ':' line
    # after the first frame) is on neither side: the compare said "same" without a word,
    # where `mpz encode` notes it as not kept (a round-trip QA run); a note here too
    notes += [f"{printable(path)}: its reader does not keep "
              f"{printable('; '.join(map(str, m.extras[READER_NOT_KEPT])))} (on neither "
              "side, so not compared)"
              for path, m, ext in ((args.original, a, ext_a), (args.decoded, b, ext_b))
              if ext != ".mpz" and m.extras.get(READER_NOT_KEPT)]
    notes += _asf_notes(args, ext_a, ext_b, names, borrowed and ext_b == ".amc")
    data = data_b or data_a                 # the bounds an .mpz input declares
    # two .mpz files: each within its own steps of the source, so the sum (one file's
    # failed two good encodes, a QA run of stop 53), as the markers below
    steps = [] if layer else [c for c in (channel_bounds(d) for d in (data_a, data_b)
                                          if d is not None) if c is not None]
    parts = [] if layer else besides_markers(a, b, channel_bounds=None if not steps else (
        sum(r for r, _ in steps), sum(t for _, t in steps)))
    if ext_a == ext_b == ".mpz" and not layer:
        parts = _both_mpz(a, b, names, parts)
    if layer:
        # an input that is no .mpz is read as it is (the review of stop 75: the note
        # spoke of a marker layer where neither input had one)
        notes.append("--marker-layer: the markers alone are compared, "
                     + ("an .mpz input's marker layer" if ".mpz" in (ext_a, ext_b) else
                        "as read (neither input is an .mpz file, which alone has a marker "
                        "layer to choose)")
                     + "; no part besides them (metadata, a C3D archive, a skeleton) is")
    if borrowed and ext_b == ".amc":         # its own skeleton was not read: not checked
        parts = [dataclasses.replace(p, status="unchecked", detail=f"{p.detail}; read with "
                                     "--asf's (the decoded AMC has no .asf of its own)")
                 if p.name == "skeleton" else p for p in parts]
    # the marker bound an .mpz decoded input declares against its source (spec §7.2); for
    # joint positions computed from a skeleton's channels, its position_bound (§4.14: it
    # was not checked at all, a QA run of stop 47)
    declared = data_b if ext_b == ".mpz" else None
    joints = declared is not None and joint_positions_from_channels(b, ext_b)
    # two .mpz files (two encodes of one source: two versions, two bounds): neither is the
    # source, each is within its own bound of it, so they are held to the sum (a QA run of
    # stop 48: B's bound alone against A gave BEYOND, exit 2, for two good files)
    first_mpz = data_a if ext_a == ".mpz" and declared is not None else None
    first_joints = first_mpz is not None and joint_positions_from_channels(a, ext_a)
    # two .mpz files, one giving joint positions and the other its marker layer
    mixed = first_mpz is not None and first_joints != joints
    del data_a, data_b, data
    notes += [f"{names[1]} does not hold the original's {p.name}: {p.detail}"
              for p in parts if p.status == "missing"]
    pos = {"original": _positions(a, ext_a), "decoded": _positions(b, ext_b)}
    if mixed:
        # an encode of a BVH or AMC with a skeleton chunk against one without (two
        # versions, or --no-skeleton): joint positions from channels against a marker
        # layer, 1.66 mm apart where the two marker layers agreed to 2e-13 mm (a
        # maintainer's QA run of stop 75)
        withj, without = (names[0], names[1]) if first_joints else (names[1], names[0])
        notes.append(f"{withj} gives the joint positions of its skeleton's channels and "
                     f"{without} its marker layer (it holds no skeleton): --marker-layer "
                     "compares the marker layers of both")
    npy = ext_a == ".npy" or ext_b == ".npy"           # no names: taken in order
    known = set(a.names)
    added = [n for n in b.names if n not in known] if not npy else []
    b = align(a, b, unnamed=[n for n, e in zip(names, (ext_a, ext_b), strict=True)
                             if e == ".npy"], notes=notes)
    if added:
        notes.append(f"{names[1]} has {len(added)} marker{'s' * (len(added) != 1)} the "
                     f"original has not: {', '.join(printable(n) for n in added[:5])}"
                     + (f" and {len(added) - 5} more" if len(added) > 5 else "")
                     + " (not compared; a difference: exit 2)")
    if a.n_frames != b.n_frames:
        raise MotionError(f"frame counts differ: {a.n_frames} vs {b.n_frames}")
    if args.plot:             # a --marker that is not there fails before the report
        unknown = [n for n in args.marker or () if n not in a.names]
        if unknown:
            raise MotionError(f"--marker: no marker named {printable(unknown[0])!r}")
    units_b = b.units
    b, units, more = common_units(a, b, names)
    notes += more
    # --bound is read now, against the inputs' units: a bare number is refused when they
    # have units, as for every length option (README); before, it was read only for a plot
    bound_given = None
    if args.bound is not None:
        bound_given = parse_length(args.bound, units, "--bound")   # in range: check_length
        if not args.plot:
            notes.append("--bound is drawn on --plot, which was not asked for")
    if args.marker and not args.plot:     # it was ignored without a word (QA, stop 50)
        notes.append("--marker chooses the markers of --plot, which was not asked for")
    for note in notes:
        print(f"mpz compare: note: {note}", file=sys.stderr)
    s = summary(a, b)
    gaps_lost = int((a.valid & ~b.valid).sum())
    gaps_added = int((~a.valid & b.valid).sum())
    # a valid sample that became a gap is an infinite error (mpz.metrics), which hides the
    # errors of every other sample: those too, over the samples valid in both (a QA run of
    # stop 47 saw "max inf  p99 0")
    both = None
    if gaps_lost:
        from mpz.motion import Motion
        kept = Motion(a.positions, list(a.names), a.rate, a.units, a.valid & b.valid,
                      metadata=a.metadata)
        both = {k: v for k, v in summary(kept, b).items() if not k.startswith("per_marker")}
    bound_b = None if declared is None else _declared_bound(declared, units, joints=joints)
    pair: dict[str, Any] | None = None
    if first_mpz is not None and declared is not None:
        bound_a = _declared_bound(first_mpz, units, joints=first_joints)
        pair = {"sizes": [len(first_mpz), len(declared)], "bounds": [bound_a, bound_b],
                "identical": first_mpz == declared}
        if bound_a is None and bound_b is not None:
            print(f"mpz compare: note: {names[0]} declares no bound: the two .mpz files "
                  "are not held to one against each other", file=sys.stderr)
        bound_b = None if bound_a is None or bound_b is None else bound_a + bound_b
    check = marker_bound(a, b, bound_b)
    if check is not None:
        # two .mpz files of two kinds: the bound is the sum of a marker bound and a
        # position bound (the review of stop 75: "of" named the decoded side's alone)
        check["of"] = ("markers and joint positions" if mixed
                       else "joint positions" if joints else "markers")
        if pair is not None:
            check["declared_by"] = "both"
    s.update(frames=a.n_frames, markers=a.n_markers, units=units or None,
             original_units=a.units or None, decoded_units=units_b or None, positions=pos,
             notes=notes, valid_became_gap=gaps_lost, gap_became_valid=gaps_added,
             added_markers=added, bound_check=check, valid_in_both=both,
             besides_markers=[dataclasses.asdict(p) for p in parts], mpz_files=pair,
             warnings=warned)
    worst = sorted(((v, n) for n, v in s["per_marker_max"].items() if v is not None),
                   reverse=True)
    differs = any(p.status == "differs" for p in parts) or added or (
        check is not None and check["beyond"])
    code = found(2 if gaps_lost or gaps_added or differs else 1 if warned else 0)
    if args.plot:     # the file first: a reader that closes the pipe early cannot stop it
        # the three worst; the first three when no marker has an error (an original of
        # gaps alone made a figure of no panel: exit 70, a QA run of stop 53)
        plot_names = args.marker or [n for _, n in worst[:3]] or list(a.names[:3])
        bound = (bound_given if bound_given is not None
                 else _declared_bound(args.decoded, units)
                 or _declared_bound(args.original, units))
        plot(a, b, plot_names, args.plot, bound=bound, units=units, force=args.force)
    if args.json:
        print_json({"schema": JSON_SCHEMA, **s})
    else:
        u = f" {units}" if units else ""
        print(f"{a.n_frames} frames x {a.n_markers} markers, "
              + (f"errors in {units}" if units else "neither input has a length unit"))
        for which, path in (("original", args.original), ("decoded", args.decoded)):
            if pos[which] != "as read":
                print(f"  {which} {_label(path)}: {pos[which]}")
        if s["max"] is None:
            print("  no sample of the original is valid: no error to measure")
        else:
            print(f"  max {s['max']:.4g}{u}  p99 {s['p99']:.4g}{u}  RMS {s['rms']:.4g}{u}  "
                  f"ARMS {s['arms']:.4g}{u}  mean {s['mean']:.4g}{u}")
        print(f"  gaps: {gaps_lost} valid samples became gaps, {gaps_added} gaps became valid")
        if both is not None and both["max"] is None:
            print("  valid in both: no sample")
        elif both is not None:
            print(f"  valid in both: max {both['max']:.4g}{u}  p99 {both['p99']:.4g}{u}  "
                  f"RMS {both['rms']:.4g}{u}  ARMS {both['arms']:.4g}{u}  "
                  f"mean {both['mean']:.4g}{u}")
        if pair is not None:
            (sa, sb), (ba, bb) = pair["sizes"], pair["bounds"]
            print(f"  .mpz files: {sa} and {sb} bytes"
                  # same-size files that differ showed "+0.00 %" alone (a QA run, stop 75)
                  + (" (byte-identical)" if pair["identical"] else
                     " (the same size, other bytes)" if sa == sb else
                     f" ({100 * (sb / sa - 1):+.2f} %)")
                  + f", bounds {'none' if ba is None else f'{bound_text(ba, 4)}{u}'} and "
                  f"{'none' if bb is None else f'{bound_text(bb, 4)}{u}'}")
        if check is not None:
            what = ("one's marker layer bound (spec §7.2), the other's position_bound of "
                    "its joint positions (§4.14)" if mixed
                    else "position_bound of the joint positions (spec §4.14)" if joints
                    else "spec §7.2")
            by = (f"the sum of the bounds of {names[0]} and {names[1]}" if pair is not None
                  else f"declared by {names[1]}")
            print(f"  bound {bound_text(check['bound'], 4)}{u} {by} ({what}): "
                  + ("no valid sample to hold to it" if s["max"] is None else
                     "every sample within" if not check["beyond"] else
                     f"BEYOND at {check['beyond']} sample{'s' * (check['beyond'] != 1)}, "
                     f"the first {printable(check['first']['marker'])!r} at frame index "
                     f"{check['first']['frame']} ({check['first']['error']:.4g}{u})"))
        print("  marker            max        RMS")
        for v, n in worst[: args.top or None]:                  # --top 0: every marker
            rms = s["per_marker_rms"][n]
            print(f"  {printable(n)[:16]:<16} {v:>8.4g} "
                  f"{(float('nan') if rms is None else rms):>10.4g}")
        if parts:
            print("  besides the markers:")
        for p in parts:
            print(f"  {p.name:<19} {_status(p)}")
        if args.plot:
            print(f"plot written to {printable(args.plot)}")
    return code


def marker_bound(a, b, bound: float | None) -> dict | None:
    """The marker errors held to the ``bound`` an .mpz declares (None: no check), as spec
    §7.2 states it: error <= E + max|x| x 2^-50, x the original's valid coordinates. The
    samples beyond it, and the first (frame index, marker, error); samples that became
    gaps are counted apart (``valid_became_gap``)."""
    if bound is None:
        return None
    from mpz.metrics import errors
    err = errors(a, b)                                    # [F, M], NaN at original gaps
    x = np.abs(a.positions[a.valid])
    tol = bound + (float(x.max()) if x.size else 0.0) * 2.0 ** -50
    beyond = np.isfinite(err) & (err > tol)
    out: dict = {"bound": bound, "beyond": int(beyond.sum()), "first": None}
    if out["beyond"]:
        f, m = (int(v[0]) for v in np.nonzero(beyond))
        out["first"] = {"frame": f, "marker": a.names[m], "error": float(err[f, m])}
    return out


def _asf_notes(args: argparse.Namespace, ext_a: str | None, ext_b: str | None,
               names: tuple[str, str], borrowed: bool) -> list[str]:
    """What the skeleton options did: an AMC decoded input read with --asf's (its own
    skeleton unchecked), and --asf or --decoded-asf given for an input that is no AMC."""
    notes = []
    if borrowed:
        notes.append(f"{names[1]} has no .asf beside it (name one with --decoded-asf): read "
                     "with --asf's, so its skeleton is the original's and is not checked")
    if args.asf is not None and ext_a != ".amc":
        notes.append(f"--asf names an AMC original's skeleton; {names[0]} is no AMC: unused")
    if args.decoded_asf is not None and ext_b != ".amc":
        notes.append(f"--decoded-asf names an AMC decoded input's skeleton; {names[1]} is no "
                     "AMC: unused")
    return notes


def _status(p) -> str:
    """A :class:`mpz.metrics.Part` as a line of the report, its figures in its own unit."""
    u = f" {p.unit}" if p.unit else ""
    if p.status == "within":
        return f"within {bound_text(p.bound, 4)}{u}: largest {p.error:.4g}{u}; {p.detail}"
    if p.status == "changed" and p.error is not None:    # metadata has no figure
        return f"changed: largest {p.error:.4g}{u}; {p.detail}"
    return f"{p.status}: {p.detail}"


def _matplotlib():
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise MotionError("--plot needs matplotlib: pip install 'mpz[plot]'") from None
    return plt


def plot_label(name: str) -> str:
    """A name as matplotlib text: escaped, and ``$`` not taken for mathtext."""
    return printable(name).replace("$", r"\$")


def plot(a, b, names, path, *, bound: float | None = None, units: str | None = None,
         force: bool = False) -> None:
    """Error over time per marker: one panel each, the bound as a line, one shared legend."""
    from mpz.metrics import errors
    plt = _matplotlib()
    idx = {n: i for i, n in enumerate(a.names)}
    for n in names:
        if n not in idx:
            raise MotionError(f"no marker named {printable(n)!r}")
    err = errors(a, b)                                    # [F, M], NaN at original gaps
    t = np.arange(a.n_frames) / a.rate
    unit = (a.units if units is None else units) or "input units"
    fig, axes = plt.subplots(len(names), 1, figsize=(10, 1.2 + 2.0 * len(names)),
                             sharex=True, squeeze=False)
    handles = {}
    for r, n in enumerate(names):
        ax = axes[r, 0]
        e = err[:, idx[n]]
        lost = np.isinf(e)                                # valid in the original, gap decoded
        (h,) = ax.plot(t, np.where(lost, np.nan, e), lw=0.9, color="C0")
        handles["Euclidean error"] = h
        if lost.any():
            top = np.nanmax(np.where(lost, np.nan, e)) if np.isfinite(e).any() else 1.0
            hl = ax.scatter(t[lost], np.full(int(lost.sum()), top), marker="x", color="C3",
                            s=12, zorder=3)
            handles["sample lost (became a gap)"] = hl
        if bound is not None:
            hb = ax.axhline(bound, color="C1", ls="--", lw=1.2)
            handles[f"bound {bound:g} {unit}"] = hb
        ax.set_ylim(bottom=0)
        ax.set_ylabel(f"error ({unit})", fontsize=8)
        ax.set_title(plot_label(n), fontsize=9, loc="left")
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time (s)")
    fig.legend(list(handles.values()), list(handles), loc="upper center",
               ncol=len(handles), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.35 / (1.2 + 2.0 * len(names))))
    from mpz.api import atomic_output
    with atomic_output(path, force=force) as tmp:
        fig.savefig(tmp, dpi=110, format=plot_format(path))
    plt.close(fig)


def _both_mpz(a, b, names: tuple[str, str], parts: list) -> list:
    """The parts of two .mpz files compared both ways: an .mpz holds every part, so one
    that either file lacks is a difference, not a format's limit (``missing`` and a note
    said so, exit 0: an encoder that dropped a --meta entry or a skeleton passed a
    maintainer's compare of two versions, and a part the second file alone held was not
    named at all; a QA run of stop 73). The reader's own entries (its warning, format,
    name...), which a source compare leaves out, are shown as "reader metadata": two
    encodes whose bytes differed only there were all "same", the difference unsaid."""
    from mpz.io import READER_KEYS
    from mpz.metrics import Part, parts_missing_from
    out = [dataclasses.replace(p, status="differs", detail=f"{p.detail} (not in "
                               f"{names[1]}, and an .mpz file holds it)")
           if p.status == "missing" else p for p in parts]
    out += [Part(p.name, "differs", f"{p.detail} (only in {names[1]}, and an .mpz file "
                 "holds it)") for p in parts_missing_from(b, a)]
    keys = sorted(k for k in {*a.metadata, *b.metadata} if k in READER_KEYS)
    other = [k for k in keys if a.metadata.get(k) != b.metadata.get(k)]
    if other:
        out.append(Part("reader metadata", "changed", f"{len(other)} of {len(keys)} "
                        "entries with other values or on one side only (what each file's "
                        f"reader said of its source): {', '.join(other)}"))
    elif keys:
        out.append(Part("reader metadata", "same",
                        f"{len(keys)} entr{'ies' if len(keys) != 1 else 'y'}"))
    return out
