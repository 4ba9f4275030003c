"""``mpz summary FILE``: optimal-partition summary of a motion (Yang et al. 2016).

Contract: for a motion-capture file (anything :func:`mpz.io.read` reads) the
command computes the least-WSSSE partitions for each requested ``k`` (past 16,384
frames, with cuts on blocks of frames, as the encoder and the index make them:
:func:`mpz.fisher.summary_partitions`; JSON ``method`` says ``blocks:B``) and prints
one segment table per level: index, start frame, start time, length and the
segment's share of the level's WSSSE. For a ``.mpz`` file it prints the levels
stored in the file (through :func:`mpz.read_summary`; JSON ``method`` is
``stored``); each segment's share of the WSSSE is then measured on the decoded
motion (the file stores the level's total only). ``-`` reads standard input.
``--json`` prints the same as JSON (schema ``mpz-summary/1``; unknown and
non-finite values are ``null``). Each level says what its ``wssse`` is of
(``wssse_of``: the source, as stored, for an ``.mpz``) and what its segments'
``wssse`` were measured on (``segments_of``: the decoded motion, for an ``.mpz``),
with their sum (``segments_wssse_total``): an ``.mpz``'s two differ by the coding
error.
``--plot OUT.png`` draws a timeline like the paper's Fig. 2: one bar per level
with its segments in distinct colours, and the mean pose of each segment of
the coarsest level, explained in a caption. A level of more than
:data:`MAX_PLOT_SEGMENTS` segments is one hatched bar, warned of. The report is
written as it is made, a segment at a time: a valid file may hold 2^24 segments
(spec §8), and the command holds the decoded levels, never a row for each segment.

With ``--space angles`` the sums are of the skeleton's channel values: labelled in its
angle unit (deg, or rad for an ASF that says so), its root translations summed with
them as numbers (the description says how many).

Exit codes: 0 ok; 1 warnings only (a requested ``k`` above the frame count was
dropped, or one an .mpz does not store); 2 errors (unreadable input, missing reader
or matplotlib); 3 out of memory; 64 usage.
"""
from __future__ import annotations

import argparse
import colorsys
import math
import os
from pathlib import Path
import sys

import numpy as np

from mpz.errors import MPZError
from mpz.tools._cli import (
    EXIT_ERROR,
    EXIT_OK,
    EXIT_WARN,
    Parser,
    Streamed,
    found,
    positive,
    print_json,
    printable,
)

JSON_SCHEMA = "mpz-summary/1"
DEFAULT_KS = "6,12,24,48"
#: the most segments of one level that ``--plot`` draws one by one: a figure is about a
#: thousand pixels wide, and a level of 2^20 took 23 s and 965 MB to draw (2^24, which
#: a valid file may hold, would take some 15 GB); a level beyond is drawn as one bar
MAX_PLOT_SEGMENTS = 4096


def _ks(text: str) -> list[int]:
    try:
        ks = sorted({int(v) for v in text.split(",") if v.strip()})
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--k wants comma-separated integers, got {text!r}") from None
    if not ks or ks[0] < 1:
        raise argparse.ArgumentTypeError(f"--k wants integers >= 1, got {text!r}")
    return ks


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "summary", help="segment a motion optimally and print the segments per level",
        description="Least-WSSSE temporal segmentation (Fisher's optimal partition) of a motion, "
                    "at several numbers of segments k.")
    p.add_argument("file", help="motion file (.c3d, .trc, .bvh, .amc, .npy, .csv) or .mpz; "
                   "- reads standard input")
    p.add_argument("--k", type=_ks, default=None, metavar="K1,K2,...",
                   help=f"numbers of segments (default {DEFAULT_KS}, each lowered to the "
                   "motion's frames; a k given beyond them is dropped, with a warning; for "
                   ".mpz: every stored "
                   "level, or the default of a file without a summary chunk, whose decoded "
                   "motion is segmented)")
    p.add_argument("--space", choices=("positions", "angles"), default=None,
                   help="segment marker positions relative to their centroid (default) or the "
                        "joint angles of AMC/BVH input; an .mpz summary chunk is shown in "
                        "its own space (another is warned)")
    p.add_argument("--rate", metavar="HZ", type=positive,
                   help="the frame rate of an input that stores none (AMC: 120 Hz is "
                   "assumed, NPY: 1 Hz), e.g. --rate 120; an error for one that has one")
    p.add_argument("--asf", metavar="FILE",
                   help="skeleton for .amc input (default: found beside it); an error "
                   "for any other input")
    p.add_argument("--plot", metavar="OUT.png", help="save a timeline figure (needs "
                   f"matplotlib); a level of more than {MAX_PLOT_SEGMENTS} segments is "
                   "drawn as one bar, with a warning (exit 1)")
    p.add_argument("-f", "--force", action="store_true", help="replace the --plot file if it "
                   "exists")
    p.add_argument("--json", action="store_true", help="print JSON instead of tables")
    p.add_argument("--no-decode", action="store_true",
                   help=".mpz input: do not decode the motion (the WSSSE %% column stays "
                   "empty); an error for any other input")
    from mpz.tools._cli import max_samples, max_samples_help
    p.add_argument("--max-samples", type=max_samples, default=None, metavar="N",
                   help=max_samples_help("decoding and segmenting need about 130 bytes per "
                                         "marker-frame") + "; .mpz input only, whose "
                   "summary chunk may then hold at most N segments in all (150-170 bytes "
                   "each in the --json report)")
    p.set_defaults(func=run)
    return p


# -- gathering the levels ------------------------------------------------------------
def _levels_from_motion(args, ks, motion=None):
    """Partitions of a motion file (or of ``motion``, an .mpz file's decoded motion);
    returns (info, levels, pose_series, parents, warnings)."""
    from mpz.fisher import block_length, motion_series, summary_partitions
    try:
        from mpz.io import read
    except ImportError as exc:
        raise _Fail(f"reading motion files needs mpz.io, which is not available: {exc}") from None
    # the reader's warning (a file cut short, a header that disagrees with its rows) was
    # dropped, exit 0 (a QA run of stop 53); an .mpz file's source was warned of by encode
    read_here = motion is None
    if motion is None and args.file == "-":
        from mpz.io import read_bytes
        motion = read_bytes(args.stdin_data, fmt=args.stdin_format, asf=args.asf)
    elif motion is None:
        motion = read(args.file, **({"asf": args.asf} if args.asf else {}))
    if read_here:
        # --asf for what did not read as an AMC (by its content, whatever its name) was
        # ignored (a QA run of stop 61), as mpz search refuses it
        fmt = motion.metadata.get("format", "")
        if args.asf is not None and fmt != "amc":
            raise _Fail(f"--asf: the skeleton of .amc input; this input is "
                        f"{fmt.upper() or 'not an AMC'}")
        # an NPY was segmented at 1 Hz without a word, its times in frames (a QA run of
        # stop 53); --rate names the rate, as for mpz encode and search
        from mpz.errors import EncoderError
        from mpz.tools._common import assumed_rate, with_rate
        assumed = assumed_rate(motion, args.rate)
        if assumed:
            print(f"mpz summary: note: {printable(args.file)}: {assumed}", file=sys.stderr)
        try:
            motion = with_rate(motion, args.rate)
        except EncoderError as exc:
            raise _Fail(f"{printable(args.file)}: {exc}") from None
    x, what = motion_series(motion, args.space)
    n = x.shape[0]
    said = motion.metadata.get("warning") if read_here else None
    warnings = [f"{args.file}: {said}"] if said else []
    if not motion.valid.any():      # a table of cuts at 0 WSSSE, exit 0 (a QA run of stop 53)
        warnings.append(f"{args.file}: every marker is a gap throughout: there is no motion "
                        "to segment, and the cuts below are arbitrary")
    b = block_length(n)                 # past 16,384 frames the cuts fall on blocks of b
    rows = -(-n // b)
    units_of = f"{n} frames" if b == 1 else f"{rows} blocks of {b} frames"
    if args.k is None:
        # the default levels are lowered to what the motion has, as the encoder lowers a
        # summary's (spec Appendix C): a 5-frame file failed (exit 2, "no requested k
        # fits") and a 10-frame one warned (exit 1) of k nobody had asked for (a CLI audit)
        ks = sorted({min(k, rows) for k in ks})
    dropped = [k for k in ks if k > rows]
    if dropped:
        warnings.append(f"k={','.join(map(str, dropped))} dropped: the motion has only "
                        f"{units_of}")
    ks = [k for k in ks if k <= rows]
    if not ks:
        raise _Fail(f"{printable(args.file)}: no requested k fits the {units_of} of the motion")
    _, parts = summary_partitions(x, ks)
    levels = []
    for k in ks:
        p = parts[k]
        lengths = p.lengths(n)
        r = x - np.repeat(p.means, lengths, axis=0)
        seg_sse = np.add.reduceat(np.einsum("ij,ij->i", r, r), p.starts)
        levels.append({"k": k, "starts": p.starts, "lengths": lengths, "wssse": p.wssse,
                       "segment_wssse": seg_sse})
    poses = x if args.space == "positions" else motion_series(motion, "positions")[0]
    units = motion.units or None
    if args.space == "angles":
        units, channels = _channel_units(motion.extras.get("skeleton"))
        what += channels
    info = {"file": os.fspath(args.file), "kind": "motion", "n_frames": n, "rate": motion.rate,
            "units": units, "space": args.space, "description": what,
            "dims": int(x.shape[1]), "markers": motion.n_markers,
            "method": "exact" if b == 1 else f"blocks:{b}"}
    return info, levels, poses, motion.parents, warnings


def _levels_from_mpz(args, ks):
    try:
        from mpz import read_summary
    except ImportError:
        raise _Fail(".mpz input needs mpz.read_summary, "
                    "which this build does not provide yet") from None
    from mpz.api import read_source
    data = args.stdin_data if args.file == "-" else read_source(args.file)[0]
    if args.max_samples is not None:
        # the limit before the summary chunk is read: --no-decode decodes nothing, and
        # took a file of any size (a review of stop 53)
        from mpz.decoder import read_stream
        from mpz.errors import MPZError
        try:
            read_stream(data, max_samples=args.max_samples)
        except MPZError as exc:
            exc.path = args.file
            raise
    summ = read_summary(data)
    if summ is not None and args.max_samples is not None:
        # a 12 KB file of 2^20 segments took 2.1 GB and printed 156 MB of JSON, whatever
        # --max-samples said (a security QA run, stop 73): the segments count against it
        segments = sum(int(lv.k) for lv in summ.levels)
        if segments > args.max_samples:
            raise _Fail(f"{printable(args.file)}: its summary chunk holds {segments} "
                        f"segments in all, more than --max-samples {args.max_samples} "
                        "allows (their --json report takes 150-170 bytes each); give a "
                        "larger --max-samples to show them")
    if summ is None and args.no_decode:
        raise _Fail(f"{printable(args.file)} has no summary chunk, and --no-decode leaves "
                    "nothing to segment (encode with: mpz encode --summary 6,12,24,48)")
    if summ is None:     # segment the decoded motion, as any motion file (a QA run, stop 47)
        from mpz.errors import MPZError
        from mpz.tools._common import read_mpz_input_bytes
        try:
            motion = read_mpz_input_bytes(data, args.max_samples)
        except MPZError as exc:
            exc.path = args.file
            raise
        print(f"mpz summary: note: {printable(args.file)} has no summary chunk: the levels "
              "are computed from its decoded motion (mpz encode --summary stores them)",
              file=sys.stderr)
        return _levels_from_motion(args, ks if ks is not None else _ks(DEFAULT_KS), motion)
    n = int(summ.n_frames)
    series = None
    if not args.no_decode:       # the per-segment shares, measured on the decoded motion
        from mpz.errors import MPZError
        from mpz.fisher import motion_series
        from mpz.tools._common import read_mpz_input_bytes
        # a file whose motion does not decode is an error (exit 2), as in mpz decode; a
        # skeletal file gives the joint positions from its channels, as mpz decode does
        try:
            motion = read_mpz_input_bytes(data, args.max_samples)
        except MPZError as exc:
            exc.path = args.file             # the file named, not standard input
            raise
        try:
            series = motion_series(motion, summ.space)[0]
        except MPZError:
            series = None        # e.g. an angle summary of a motion decoded without angles
    stored = [int(lv.k) for lv in summ.levels]
    missing = [] if ks is None else [k for k in ks if k not in stored]
    warnings = []
    if args.space_asked not in (None, summ.space):    # was ignored without a word (QA)
        warnings.append(f"--space {args.space_asked}: the file's summary chunk is of "
                        f"{summ.space}, shown as stored")
    if missing and len(missing) == len(ks or ()):
        # a table of no row, exit 1 (a QA run of stop 53); a motion file whose k all
        # exceed its frames is an error too
        raise _Fail(f"{printable(args.file)}: no requested k is stored in the file (stored: "
                    f"{', '.join(map(str, stored))}); its summary chunk holds those alone")
    if missing:
        warnings.append(f"k={','.join(map(str, missing))} not stored in the file (stored: "
                        f"{', '.join(map(str, stored))})")
    levels = []
    for lv in summ.levels:
        if ks is not None and int(lv.k) not in ks:
            continue
        starts = np.asarray(lv.starts, dtype=np.int64)
        lengths = np.diff(np.append(starts, n))
        seg_sse = None
        if series is not None:
            r = series - np.repeat(_means(series, starts), lengths, axis=0)
            seg_sse = np.add.reduceat(np.einsum("ij,ij->i", r, r), starts)
        levels.append({"k": int(lv.k), "starts": starts, "lengths": lengths,
                       "wssse": None if getattr(lv, "wssse", None) is None else float(lv.wssse),
                       "segment_wssse": seg_sse,
                       "segment_total": None if seg_sse is None else float(seg_sse.sum()),
                       "means": np.asarray(lv.means, dtype=np.float64)})
    unit, channels = (summ.units or None), ""
    if summ.space == "angles":
        unit, channels = _channel_units(_skeleton_of(data), default="deg")
    what = ("levels stored in the file" + channels
            + ("; WSSSE % measured on the decoded motion" if series is not None else ""))
    info = {"file": os.fspath(args.file), "kind": "mpz", "n_frames": n,
            "rate": float(summ.rate) if getattr(summ, "rate", None) else None,
            "units": unit, "space": summ.space, "description": what, "dims": summ.dims,
            "markers": len(summ.names), "method": "stored"}
    return info, levels, None, None, warnings


def _skeleton_of(data: bytes):
    """The skeleton an MPZ file's skeleton chunk holds (spec §4.14), else None."""
    from mpz.chunks.skeleton import SKELETON_TYPES, Asfs, Bvhs
    from mpz.container import scan
    from mpz.skeleton import skeleton_of_record
    # the skeleton chunks alone, and nothing kept per unknown chunk (as skeleton.report)
    res = scan(data, keep_unknown=False, load=SKELETON_TYPES)
    if res.errors:
        raise res.errors[0]
    for c in res.chunks:
        if isinstance(c.record, (Bvhs, Asfs)):
            return skeleton_of_record(c.record)
    return None


def _channel_units(skel, default: str | None = None) -> tuple[str | None, str]:
    """The unit of an angle summary's sums and what its channels are.

    The series is the skeleton's channel values as stored (spec §4.10, space 1): the
    rotations in the skeleton's angle unit (deg, or rad for an ASF that says so), and the
    root's translations in its length units, summed with them as numbers. Returns (the
    angle unit, or ``default`` without a skeleton; a clause for the description)."""
    from mpz.io.kinematics import Skeleton
    from mpz.skeleton import is_rotation
    if not isinstance(skel, Skeleton):
        return default, ""
    kinds = skel.channel_kinds()
    rot = sum(1 for k in kinds if is_rotation(k))
    text = f" ({rot} rotations in {skel.angle_unit}"
    if rot < len(kinds):
        text += (f"; {len(kinds) - rot} translations in the skeleton's length units, summed "
                 "with them as numbers")
    return skel.angle_unit, text + ")"


def _means(x: np.ndarray, starts: np.ndarray) -> np.ndarray:
    from mpz.fisher import segment_means
    return segment_means(x, starts)


class _Fail(Exception):
    """An error this command reports itself (exit 2)."""


# -- output ----------------------------------------------------------------------------
def _segments(level, rate):
    """The segments of a level, one dict each, made as they are asked for: a valid file
    may hold 2^24 of them (spec §8), and a list of them all took gigabytes (a security QA
    run of stop 73)."""
    total = level.get("segment_total", level["wssse"])
    for i, (s, ln) in enumerate(zip(level["starts"], level["lengths"], strict=True)):
        sse = None if level["segment_wssse"] is None else float(level["segment_wssse"][i])
        share = None if sse is None or not total else 100.0 * sse / total
        if sse is not None and not total:
            share = 0.0
        yield {"index": i, "start": int(s), "start_time": None if not rate else int(s) / rate,
               "length": int(ln), "wssse": sse, "share": share}


def _print_text(info, levels, out):
    rate = info["rate"]
    n = info["n_frames"]
    head = f"{printable(info['file'])}: {n} frame{'' if n == 1 else 's'}"
    if rate:
        head += f" at {rate:g} Hz ({info['n_frames'] / rate:.2f} s)"
    if info["dims"]:
        head += f", {info['dims']} dims: {info['description']}"
    method = info.get("method", "exact")
    if method.startswith("blocks:"):           # not "exact", nor "stored" (an .mpz's levels)
        head += (f"; cuts on blocks of {method.removeprefix('blocks:')} frames (the exact "
                 "partition is quadratic in the frames: spec Appendix C item 8)")
    print(head, file=out)
    for lv in levels:
        w = None if lv["wssse"] is None else lv["wssse"] + 0.0      # -0.0 (§1.3) as 0
        line = f"\nk={lv['k']}"
        if w is not None:
            unit = f" {info['units']}" if info.get("units") else ""
            sq = f"{unit}\u00b2" if unit else ""
            line += f"  WSSSE {w:.6g}{sq}  sqrt {math.sqrt(w):.6g}{unit}"
            line += f"  RMS per frame {math.sqrt(w / info['n_frames']):.4g}{unit}"
            # that is every coordinate of a pose together: a QA run read it as one
            # marker's (454.5 mm on a 41-marker take whose markers' RMS is 71 mm)
            each = ("marker", info["dims"] // 3) if info.get("space") == "positions" \
                else ("channel", info["dims"])
            if each[1] > 1:
                line += (f" (all {each[1]} {each[0]}s; per {each[0]} "
                         f"{math.sqrt(w / (info['n_frames'] * each[1])):.4g}{unit})")
        print(line, file=out)
        print(f"{'seg':>5} {'start':>7} {'time s':>9} {'frames':>7} {'WSSSE %':>8}", file=out)
        for s in _segments(lv, rate):
            t = "-" if s["start_time"] is None else f"{s['start_time']:.3f}"
            sh = "-" if s["share"] is None else f"{s['share']:.1f}"
            print(f"{s['index']:>5} {s['start']:>7} {t:>9} {s['length']:>7} {sh:>8}", file=out)


def _json(info, levels, warnings):
    # a stored level's wssse is the source's, its segments' are measured on the decoded
    # motion, and they did not add up with nothing saying why (a report QA run of stop
    # 55): each level says what its segments were measured on, and their sum
    stored = info.get("method") == "stored"
    return {"schema": JSON_SCHEMA, **info, "warnings": warnings,
            "wssse_units": (f"{info['units']}^2" if info.get("units") else None),
            "levels": [{"k": lv["k"], "wssse": lv["wssse"],
                        "wssse_of": "the source, as stored" if stored else "the motion read",
                        "segments_wssse_total": None if lv["segment_wssse"] is None
                        else float(np.sum(lv["segment_wssse"])),
                        "segments_of": ("the decoded motion" if stored else "the motion read")
                        if lv["segment_wssse"] is not None else None,
                        "segments": _streamed_segments(lv, info["rate"])}
                       for lv in levels]}


def _streamed_segments(level, rate) -> Streamed:
    """A level's segments, written to the JSON report as they are made (:func:`_segments`)."""
    return Streamed(lambda: _segments(level, rate))


# -- plot ------------------------------------------------------------------------------
def _pose_axes(poses: np.ndarray):
    """(horizontal, vertical) axes for thumbnails of ``poses[segments, markers, 3]``.

    Vertical: the axis along which the average pose is tallest (a body is taller
    than it is wide). Horizontal: of the other two, the one along which the
    segment poses differ most, so the motion shows (the sagittal plane for gait).
    """
    avg = poses.mean(axis=0)
    v = int(np.argmax(avg.max(axis=0) - avg.min(axis=0)))
    rest = [a for a in range(3) if a != v]
    change = [float(poses[:, :, a].var(axis=0).sum()) for a in rest]
    return rest[int(np.argmax(change))], v


def _rgb(c: tuple[float, ...]) -> tuple[float, float, float]:
    return (float(c[0]), float(c[1]), float(c[2]))


def segment_colours(k: int) -> list[tuple[float, float, float]]:
    """``k`` distinct RGB colours, neighbours far apart (segment i gets colour i).

    Up to 10: matplotlib's tab10; up to 20: tab20 (dark and light pairs, the
    lights after the darks so neighbours differ in hue); beyond: hues stepped
    by the golden ratio, with lightness and saturation cycling over three
    values, so no colour repeats however large ``k`` is (the old tab10 cycle
    repeated from segment 11 on).
    """
    if k <= 10:
        from matplotlib import colormaps
        return [_rgb(colormaps["tab10"](i)) for i in range(k)]
    if k <= 20:
        from matplotlib import colormaps
        order = list(range(0, 20, 2)) + list(range(1, 20, 2))
        return [_rgb(colormaps["tab20"](order[i])) for i in range(k)]
    out = []
    for i in range(k):
        hue = (i * 0.618033988749895) % 1.0
        light = (0.42, 0.60, 0.30)[i % 3]
        sat = (0.75, 0.95, 0.60)[(i // 3) % 3]
        out.append(colorsys.hls_to_rgb(hue, light, sat))
    return out


def thumbnail_level(levels: list[dict]) -> dict:
    """The level that gets mean-pose thumbnails: the coarsest, the first of the least k
    (spec §4.10 lets levels come in any order: the first stored one was taken)."""
    return min(levels, key=lambda lv: lv["k"])


def thumbnail_means(info: dict, level: dict) -> np.ndarray | None:
    """A stored level's means as poses [k, 3M], or None: only a position summary's (space
    0) are poses. An angle summary's D = 0 means crashed the plot, and a BVH's channel
    values (D = 6 + 3 J, a multiple of 3 too) were drawn as points (a QA run, stop 49).
    None too when a mean is not finite: a stored mean may overflow to ±inf in a valid
    file (§4.10), and the plot's limits were then infinite, an internal error (a review
    of stop 67); the segments are drawn without the poses."""
    means = level.get("means")
    if info.get("space") != "positions" or means is None or not means.shape[1] \
            or means.shape[1] % 3 or not np.isfinite(means).all():
        return None
    return np.asarray(means)


def _plot(path, info, levels, poses, parents, force: bool = False) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n, rate = info["n_frames"], info["rate"] or 1.0
    unit = "s" if info["rate"] else "frames"
    thumb = thumbnail_level(levels)
    kt = thumb["k"]
    means = None
    if poses is not None:
        from mpz.fisher import segment_means
        means = segment_means(poses, thumb["starts"])
    else:
        means = thumbnail_means(info, thumb)
    show_thumbs = means is not None and kt <= 24
    fig = plt.figure(figsize=(max(8.0, 0.9 * kt if show_thumbs else 8.0), 1.2 + 0.45 * len(levels)
                              + (2.0 if show_thumbs else 0.0)))
    gs = fig.add_gridspec(2 if show_thumbs else 1, kt if show_thumbs else 1,
                          height_ratios=[2.0, 0.45 * len(levels) + 0.6] if show_thumbs else None,
                          hspace=0.35, wspace=0.05)
    if show_thumbs and means is not None:
        pts_all = means.reshape(kt, -1, 3)
        thumb_colours = segment_colours(kt)
        h, v = _pose_axes(pts_all)
        lo = pts_all.reshape(-1, 3).min(axis=0)
        hi = pts_all.reshape(-1, 3).max(axis=0)
        # a span of 0 (one pose: every marker a gap throughout, or a still capture) made
        # matplotlib warn of singular limits (a QA run of stop 53): pad by 1 unit then
        pad = 0.05 * float((hi - lo).max()) or 1.0
        for i in range(kt):
            ax = fig.add_subplot(gs[0, i])
            p = pts_all[i]
            if parents is not None and len(parents) == p.shape[0]:
                for c, par in enumerate(parents):
                    if par >= 0:
                        ax.plot(p[[c, par], h], p[[c, par], v], color="0.3", lw=0.8)
            ax.scatter(p[:, h], p[:, v], s=4, color=thumb_colours[i])
            ax.set_xlim(lo[h] - pad, hi[h] + pad)
            ax.set_ylim(lo[v] - pad, hi[v] + pad)
            ax.set_aspect("equal", adjustable="box")
            ax.set_xticks([])
            ax.set_yticks([])
            for sp in ax.spines.values():
                sp.set_color(thumb_colours[i])
                sp.set_linewidth(2)
            t0 = thumb["starts"][i] / rate
            ax.set_title(f"#{i}\n{t0:.2f} {unit}" if info["rate"] else f"#{i}\n{t0:.0f}",
                         fontsize=7)
        ax_t = fig.add_subplot(gs[1, :])
    else:
        ax_t = fig.add_subplot(gs[0, 0])
    for row, lv in enumerate(levels):
        if len(lv["starts"]) > MAX_PLOT_SEGMENTS:        # warned of by plot_warnings
            ax_t.broken_barh([(0.0, n / rate)], (row - 0.4, 0.8), facecolors="0.85",
                             edgecolor="0.5", hatch="///", linewidth=0.5)
            ax_t.text(n / rate / 2, row, f"{len(lv['starts'])} segments: too many to draw",
                      ha="center", va="center", fontsize=7,
                      bbox={"facecolor": "white", "edgecolor": "none", "pad": 1.5})
            continue
        spans = [(s / rate, ln / rate)
                 for s, ln in zip(lv["starts"], lv["lengths"], strict=False)]
        colours = segment_colours(len(spans))
        ax_t.broken_barh(spans, (row - 0.4, 0.8), facecolors=colours, edgecolor="white",
                         linewidth=0.5)
        if lv is thumb and show_thumbs:
            for i, (s, w) in enumerate(spans):
                ax_t.text(s + w / 2, row, str(i), ha="center", va="center", fontsize=7,
                          color="white")
    ax_t.set_yticks(range(len(levels)), [f"k={lv['k']}" for lv in levels])
    ax_t.set_ylim(len(levels) - 0.5, -0.5)
    ax_t.set_xlim(0, n / rate)
    ax_t.set_xlabel(f"time ({unit})")
    ax_t.set_ylabel("level (k segments)")
    title = f"{printable(Path(info['file']).name).replace('$', chr(92) + '$')}: " \
            "optimal partitions"
    if info.get("space"):
        title += f" ({info['space']})"
    fig.suptitle(title, fontsize=10)
    if show_thumbs:
        axis = "xyz"
        fig.text(0.5, -0.02, f"Top: the mean pose of each of the k={kt} segments of the "
                 "coarsest level, relative to the per-frame centroid of the markers, seen "
                 f"along the {'xyz'[3 - h - v]} axis (horizontal {axis[h]}, vertical "
                 f"{axis[v]}); number, colour and start time match its bar in the k={kt} row "
                 "below. Bottom: every level's segments over time, each in its own colour.",
                 ha="center", va="top", fontsize=7, wrap=True)
    from mpz.api import atomic_output
    with atomic_output(path, force=force) as tmp:
        from mpz.tools._common import plot_format
        fig.savefig(tmp, dpi=130, bbox_inches="tight", format=plot_format(path))
    plt.close(fig)


def plot_warnings(levels: list[dict]) -> list[str]:
    """What ``--plot`` cannot draw: a level of more than :data:`MAX_PLOT_SEGMENTS`
    segments is drawn as one hatched bar that says so, and warned of here."""
    return [f"--plot: the level k={lv['k']} has {len(lv['starts'])} segments, more than "
            f"the {MAX_PLOT_SEGMENTS} a plot draws; it is drawn as one hatched bar (the "
            "report lists them all)"
            for lv in levels if len(lv["starts"]) > MAX_PLOT_SEGMENTS]


# -- entry points --------------------------------------------------------------------------
def _check_applies(args, fmt: str | None) -> None:
    """Refuse an option that does nothing for this input (format ``fmt``, an extension):
    --asf, --no-decode and --max-samples were ignored where --rate was refused (a QA run
    of stop 61); mpz search refuses them too. --asf for a motion file is checked against
    the format it reads as (:func:`_levels_from_motion`)."""
    if fmt == ".mpz":
        if args.rate is not None:
            raise _Fail(f"--rate {args.rate:g}: an .mpz file stores its rate; --rate is "
                        "for inputs without one (AMC, NPY)")
        if args.asf is not None:
            raise _Fail("--asf: an .mpz file holds its own skeleton; --asf is for .amc "
                        "input")
        return
    if args.no_decode:
        raise _Fail("--no-decode is for .mpz input, whose stored summary it shows; a "
                    "motion file is segmented as it is read")
    if args.max_samples is not None:
        raise _Fail(f"--max-samples {args.max_samples}: a limit on decoding .mpz input "
                    "(spec §8); a motion file's readers have their own limits")


def run(args) -> int:
    if args.plot:  # a bad plot path, or no matplotlib, fails before the work
        from mpz.tools._common import check_plot
        check_plot(args.plot, args.force, (args.file,))
    path = Path(args.file)
    args.space_asked, args.space = args.space, args.space or "positions"
    args.stdin_data, args.stdin_format = None, None
    if args.file == "-":
        from mpz.tools._common import read_stdin
        args.stdin_data, args.stdin_format = read_stdin()
    try:
        if args.file != "-" and not path.is_file():
            # a folder said as every other command says it (a QA run of the CLI plumbing)
            what = ("no such file" if not path.exists() else "is a folder, not a file"
                    if path.is_dir() else "not a regular file")
            raise _Fail(f"{printable(args.file)}: {what}")
        fmt = args.stdin_format if args.file == "-" else path.suffix.lower()
        _check_applies(args, fmt)
        if fmt == ".mpz":
            info, levels, poses, parents, warnings = _levels_from_mpz(args, args.k)
        else:
            ks = args.k if args.k is not None else _ks(DEFAULT_KS)
            info, levels, poses, parents, warnings = _levels_from_motion(args, ks)
    except _Fail as exc:
        print(f"mpz summary: error: {exc}", file=sys.stderr)
        if args.json:                       # as the dispatcher does for an MPZError
            from mpz.tools._cli import json_failure
            print_json(json_failure("summary", str(exc)))
        return EXIT_ERROR
    except MPZError as exc:
        # a damaged .mpz file's error named no file, where every other command's does (a
        # QA run of stop 53)
        if exc.path is None:
            exc.path = args.file
        raise
    if args.plot:
        warnings += plot_warnings(levels)
    for w in warnings:
        # escaped here, kept as they are for --json: a file name or a reader's warning
        # with control characters drove the terminal (a review of stop 53)
        print(f"mpz summary: warning: {printable(w)}", file=sys.stderr)
    code = found(EXIT_WARN if warnings else EXIT_OK)
    if args.plot:     # the file first: a reader that closes the pipe early cannot stop it
        _plot(args.plot, info, levels, poses, parents, args.force)
    if args.json:
        print_json(_json(info, levels, warnings), indent=1)
    else:
        _print_text(info, levels, sys.stdout)
        if args.plot:
            print(f"\nplot written to {printable(args.plot)}")
    return code


def main(argv=None) -> int:
    """Run ``mpz summary`` on its own (same options and exit codes)."""
    from mpz.errors import MPZError
    parser = Parser(prog="mpz")
    sub = parser.add_subparsers(dest="command", parser_class=Parser)
    add_parser(sub)
    args = parser.parse_args(["summary", *(sys.argv[1:] if argv is None else argv)])
    try:
        return int(args.func(args))
    except MPZError as exc:
        print(f"mpz summary: error: {printable(str(exc))}", file=sys.stderr)
        return EXIT_ERROR


if __name__ == "__main__":
    sys.exit(main())
