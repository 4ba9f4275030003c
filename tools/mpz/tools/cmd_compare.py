"""``mpz compare ORIGINAL DECODED``: error statistics, overall and per marker."""
from __future__ import annotations

import json

import numpy as np

from mpz.errors import MotionError


def add_parser(sub):
    p = sub.add_parser("compare", help="error statistics between two motions (any format)",
                       description="Compare a decoded motion with its original: max, p99, RMS "
                       "and ARMS (paper Eq. 3), overall and per marker; optional plot.")
    p.add_argument("original")
    p.add_argument("decoded")
    p.add_argument("--asf", help="skeleton for AMC input")
    p.add_argument("--json", action="store_true")
    p.add_argument("--top", type=int, default=10, help="markers to list, worst first")
    p.add_argument("--plot", metavar="PNG", help="plot trajectories of the worst markers "
                   "(needs matplotlib)")
    p.add_argument("--marker", action="append", help="marker(s) to plot instead of the worst")
    p.set_defaults(func=run)


def align(a, b):
    """Reorder ``b``'s markers to ``a``'s names."""
    if a.names == b.names:
        return b
    index = {n: i for i, n in enumerate(b.names)}
    missing = [n for n in a.names if n not in index]
    if missing:
        raise MotionError(f"markers missing from the decoded motion: {', '.join(missing[:5])}")
    order = [index[n] for n in a.names]
    from mpz.motion import Motion
    return Motion(b.positions[:, order], list(a.names), b.rate, b.units, b.valid[:, order])


def run(args) -> int:
    from mpz.metrics import summary
    from mpz.tools._common import read_motion
    if args.plot:  # a bad plot path fails before the work
        from mpz.api import check_output
        check_output(args.plot, force=True, source=args.original)
        check_output(args.plot, force=True, source=args.decoded)
    a = read_motion(args.original, args.asf)
    b = align(a, read_motion(args.decoded, args.asf))
    if a.n_frames != b.n_frames:
        raise MotionError(f"frame counts differ: {a.n_frames} vs {b.n_frames}")
    s = summary(a, b)
    gaps_lost = int((a.valid & ~b.valid).sum())
    gaps_added = int((~a.valid & b.valid).sum())
    s.update(frames=a.n_frames, markers=a.n_markers, units=a.units,
             valid_became_gap=gaps_lost, gap_became_valid=gaps_added)
    worst = sorted(((v, n) for n, v in s["per_marker_max"].items() if v is not None),
                   reverse=True)
    if args.json:
        print(json.dumps(s, indent=2))
    else:
        u = f" {a.units}" if a.units else ""
        print(f"{a.n_frames} frames x {a.n_markers} markers")
        print(f"  max {s['max']:.4g}{u}  p99 {s['p99']:.4g}{u}  RMS {s['rms']:.4g}{u}  "
              f"ARMS {s['arms']:.4g}{u}  mean {s['mean']:.4g}{u}")
        print(f"  gaps: {gaps_lost} valid samples became gaps, {gaps_added} gaps became valid")
        print("  marker            max        RMS")
        for v, n in worst[: args.top]:
            print(f"  {n[:16]:<16} {v:>8.4g} {s['per_marker_rms'][n]:>10.4g}")
    if args.plot:
        names = args.marker or [n for _, n in worst[:3]]
        plot(a, b, names, args.plot)
    return 2 if gaps_lost or gaps_added else 0


def plot(a, b, names, path):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise MotionError("--plot needs matplotlib: pip install 'mpz[plot]'") from None
    idx = {n: i for i, n in enumerate(a.names)}
    t = np.arange(a.n_frames) / a.rate
    fig, axes = plt.subplots(len(names), 3, figsize=(12, 2.6 * len(names)), squeeze=False)
    for r, n in enumerate(names):
        if n not in idx:
            raise MotionError(f"no marker named {n!r}")
        m = idx[n]
        for c, axis in enumerate("xyz"):
            ax = axes[r, c]
            ax.plot(t, a.as_nan()[:, m, c], lw=1.2, label="original")
            ax.plot(t, b.as_nan()[:, m, c], lw=0.9, ls="--", label="decoded")
            ax.set_title(f"{n} {axis}", fontsize=9)
            ax.tick_params(labelsize=7)
    axes[0, 0].legend(fontsize=7)
    fig.supxlabel("time (s)")
    fig.tight_layout()
    from mpz.api import atomic_output
    with atomic_output(path, force=True) as tmp:
        fig.savefig(tmp, dpi=110)
