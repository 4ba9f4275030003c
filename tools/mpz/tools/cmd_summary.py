"""``mpz summary FILE``: optimal-partition summary of a motion (Yang et al. 2016).

Contract: for a motion-capture file (anything :func:`mpz.io.read` reads) the
command computes the least-WSSSE partitions for each requested ``k`` and prints
one segment table per level: index, start frame, start time, length and the
segment's share of the level's WSSSE. For a ``.mpz`` file it prints the levels
stored in the file (through :func:`mpz.read_summary`). ``--json`` prints the
same as JSON (schema ``mpz-summary/1``; unknown values are ``null``).
``--plot OUT.png`` draws a timeline like the paper's Fig. 2: one bar per level
with its segments, and the mean pose of each segment of the coarsest level.

Exit codes: 0 ok; 1 warnings only (a requested ``k`` above the frame count was
dropped); 2 errors (unreadable input, missing reader or matplotlib); 64 usage.
"""
from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path
import sys

import numpy as np

from mpz.tools._cli import EXIT_ERROR, EXIT_OK, EXIT_WARN, Parser

JSON_SCHEMA = "mpz-summary/1"
DEFAULT_KS = "6,12,24,48"


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
    p.add_argument("file", help="motion file (.c3d, .trc, .bvh, .amc, .npy, .csv) or .mpz")
    p.add_argument("--k", type=_ks, default=None, metavar="K1,K2,...",
                   help=f"numbers of segments (default {DEFAULT_KS}; for .mpz: every stored level)")
    p.add_argument("--space", choices=("positions", "angles"), default="positions",
                   help="segment marker positions relative to their centroid (default) or the "
                        "joint angles of AMC/BVH input")
    p.add_argument("--asf", metavar="FILE",
                   help="skeleton for .amc input (default: found beside it)")
    p.add_argument("--plot", metavar="OUT.png", help="save a timeline figure (needs matplotlib)")
    p.add_argument("--json", action="store_true", help="print JSON instead of tables")
    p.set_defaults(func=run)
    return p


# -- gathering the levels ------------------------------------------------------------
def _levels_from_motion(args, ks):
    """Partitions of a motion file; returns (info, levels, pose_series, parents, warnings)."""
    from mpz.fisher import motion_series, optimal_partitions
    try:
        from mpz.io import read
    except ImportError as exc:
        raise _Fail(f"reading motion files needs mpz.io, which is not available: {exc}") from None
    motion = read(args.file, **({"asf": args.asf} if args.asf else {}))
    x, what = motion_series(motion, args.space)
    n = x.shape[0]
    warnings = []
    dropped = [k for k in ks if k > n]
    if dropped:
        warnings.append(f"k={','.join(map(str, dropped))} dropped: the motion has only {n} frames")
    ks = [k for k in ks if k <= n]
    if not ks:
        raise _Fail(f"no requested k fits the {n} frames of the motion")
    parts = optimal_partitions(x, max(ks), ks=ks)
    levels = []
    for k in ks:
        p = parts[k]
        lengths = p.lengths(n)
        r = x - np.repeat(p.means, lengths, axis=0)
        seg_sse = np.add.reduceat(np.einsum("ij,ij->i", r, r), p.starts)
        levels.append({"k": k, "starts": p.starts, "lengths": lengths, "wssse": p.wssse,
                       "segment_wssse": seg_sse})
    poses = x if args.space == "positions" else motion_series(motion, "positions")[0]
    info = {"file": os.fspath(args.file), "kind": "motion", "n_frames": n, "rate": motion.rate,
            "units": motion.units or None, "space": args.space, "description": what,
            "dims": int(x.shape[1]), "markers": motion.n_markers}
    return info, levels, poses, motion.parents, warnings


def _levels_from_mpz(args, ks):
    try:
        from mpz import read_summary
    except ImportError:
        raise _Fail(".mpz input needs mpz.read_summary, "
                    "which this build does not provide yet") from None
    summ = read_summary(Path(args.file).read_bytes())
    if summ is None:
        raise _Fail(f"{args.file} has no summary chunk "
                    "(encode with: mpz encode --summary 6,12,24,48)")
    n = int(summ.n_frames)
    levels = []
    for lv in summ.levels:
        if ks is not None and int(lv.k) not in ks:
            continue
        starts = np.asarray(lv.starts, dtype=np.int64)
        levels.append({"k": int(lv.k), "starts": starts, "lengths": np.diff(np.append(starts, n)),
                       "wssse": None if getattr(lv, "wssse", None) is None else float(lv.wssse),
                       "segment_wssse": None, "means": np.asarray(lv.means, dtype=np.float64)})
    info = {"file": os.fspath(args.file), "kind": "mpz", "n_frames": n,
            "rate": float(summ.rate) if getattr(summ, "rate", None) else None, "units": None,
            "space": None, "description": "levels stored in the file", "dims": None,
            "markers": None}
    return info, levels, None, None, []


class _Fail(Exception):
    """An error this command reports itself (exit 2)."""


# -- output ----------------------------------------------------------------------------
def _segments(level, rate):
    out = []
    total = level["wssse"]
    for i, (s, ln) in enumerate(zip(level["starts"], level["lengths"], strict=False)):
        sse = None if level["segment_wssse"] is None else float(level["segment_wssse"][i])
        share = None if sse is None or not total else 100.0 * sse / total
        if sse is not None and not total:
            share = 0.0
        out.append({"index": i, "start": int(s), "start_time": None if not rate else int(s) / rate,
                    "length": int(ln), "wssse": sse, "share": share})
    return out


def _print_text(info, levels, out):
    rate = info["rate"]
    head = f"{info['file']}: {info['n_frames']} frames"
    if rate:
        head += f" at {rate:g} Hz ({(info['n_frames'] - 1) / rate:.2f} s)"
    if info["dims"]:
        head += f", {info['dims']} dims: {info['description']}"
    print(head, file=out)
    for lv in levels:
        w = lv["wssse"]
        line = f"\nk={lv['k']}"
        if w is not None:
            line += f"  WSSSE {w:.6g}  sqrt {math.sqrt(w):.6g}"
            line += f"  RMS per frame {math.sqrt(w / info['n_frames']):.4g}"
        print(line, file=out)
        print(f"{'seg':>5} {'start':>7} {'time s':>9} {'frames':>7} {'WSSSE %':>8}", file=out)
        for s in _segments(lv, rate):
            t = "-" if s["start_time"] is None else f"{s['start_time']:.3f}"
            sh = "-" if s["share"] is None else f"{s['share']:.1f}"
            print(f"{s['index']:>5} {s['start']:>7} {t:>9} {s['length']:>7} {sh:>8}", file=out)


def _json(info, levels, warnings):
    return {"schema": JSON_SCHEMA, **info, "warnings": warnings,
            "levels": [{"k": lv["k"], "wssse": lv["wssse"], "segments": _segments(lv, info["rate"])}
                       for lv in levels]}


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


def _plot(path, info, levels, poses, parents) -> None:
    import matplotlib
    matplotlib.use("Agg")
    from matplotlib import colormaps
    import matplotlib.pyplot as plt

    n, rate = info["n_frames"], info["rate"] or 1.0
    unit = "s" if info["rate"] else "frames"
    cmap = colormaps["tab10"]
    thumb = levels[0]  # the coarsest level gets mean-pose thumbnails
    kt = thumb["k"]
    means = None
    if poses is not None:
        from mpz.fisher import segment_means
        means = segment_means(poses, thumb["starts"])
    elif thumb.get("means") is not None and thumb["means"].shape[1] % 3 == 0:
        means = thumb["means"]
    show_thumbs = means is not None and kt <= 24
    fig = plt.figure(figsize=(max(8.0, 0.9 * kt if show_thumbs else 8.0), 1.2 + 0.45 * len(levels)
                              + (2.0 if show_thumbs else 0.0)))
    gs = fig.add_gridspec(2 if show_thumbs else 1, kt if show_thumbs else 1,
                          height_ratios=[2.0, 0.45 * len(levels) + 0.6] if show_thumbs else None,
                          hspace=0.35, wspace=0.05)
    if show_thumbs:
        pts_all = means.reshape(kt, -1, 3)
        h, v = _pose_axes(pts_all)
        lo = pts_all.reshape(-1, 3).min(axis=0)
        hi = pts_all.reshape(-1, 3).max(axis=0)
        pad = 0.05 * (hi - lo).max()
        for i in range(kt):
            ax = fig.add_subplot(gs[0, i])
            p = pts_all[i]
            if parents is not None and len(parents) == p.shape[0]:
                for c, par in enumerate(parents):
                    if par >= 0:
                        ax.plot(p[[c, par], h], p[[c, par], v], color="0.3", lw=0.8)
            ax.scatter(p[:, h], p[:, v], s=4, color=cmap(i % 10))
            ax.set_xlim(lo[h] - pad, hi[h] + pad)
            ax.set_ylim(lo[v] - pad, hi[v] + pad)
            ax.set_aspect("equal", adjustable="box")
            ax.set_xticks([])
            ax.set_yticks([])
            for sp in ax.spines.values():
                sp.set_color(cmap(i % 10))
                sp.set_linewidth(2)
            t0 = thumb["starts"][i] / rate
            ax.set_title(f"#{i}\n{t0:.2f} {unit}" if info["rate"] else f"#{i}\n{t0:.0f}",
                         fontsize=7)
        ax_t = fig.add_subplot(gs[1, :])
    else:
        ax_t = fig.add_subplot(gs[0, 0])
    for row, lv in enumerate(levels):
        spans = [(s / rate, ln / rate)
                 for s, ln in zip(lv["starts"], lv["lengths"], strict=False)]
        colours = [cmap(i % 10) for i in range(len(spans))]
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
    title = f"{Path(info['file']).name}: optimal partitions"
    if info.get("space"):
        title += f" ({info['space']})"
    fig.suptitle(title, fontsize=10)
    from mpz.api import atomic_output
    with atomic_output(path, force=True) as tmp:
        fig.savefig(tmp, dpi=130, bbox_inches="tight")
    plt.close(fig)


# -- entry points --------------------------------------------------------------------------
def run(args) -> int:
    if args.plot:
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            print("mpz summary: --plot needs matplotlib (pip install 'mpz[plot]')", file=sys.stderr)
            return EXIT_ERROR
    if args.plot:  # a bad plot path fails before the work
        from mpz.api import check_output
        check_output(args.plot, force=True, source=args.file)
    path = Path(args.file)
    if not path.is_file():
        print(f"mpz summary: error: {args.file}: no such file", file=sys.stderr)
        return EXIT_ERROR
    try:
        if path.suffix.lower() == ".mpz":
            info, levels, poses, parents, warnings = _levels_from_mpz(args, args.k)
        else:
            ks = args.k if args.k is not None else _ks(DEFAULT_KS)
            info, levels, poses, parents, warnings = _levels_from_motion(args, ks)
    except _Fail as exc:
        print(f"mpz summary: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    for w in warnings:
        print(f"mpz summary: warning: {w}", file=sys.stderr)
    if args.json:
        json.dump(_json(info, levels, warnings), sys.stdout, indent=1)
        print()
    else:
        _print_text(info, levels, sys.stdout)
    if args.plot:
        _plot(args.plot, info, levels, poses, parents)
        if not args.json:
            print(f"\nplot written to {args.plot}")
    return EXIT_WARN if warnings else EXIT_OK


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
        print(f"mpz summary: error: {exc}", file=sys.stderr)
        return EXIT_ERROR


if __name__ == "__main__":
    sys.exit(main())
