"""Adaptive (paper Alg. 1) against optimal (Fisher) segmentation in the encoder.

    python bench/bench_segmentation.py [--files cmu_02_01 ...] [--taus 0.02 0.4]

Neither paper made this comparison. For each real C3D clip (short ones: the
optimal partition is O(n^2 (D + k)) per node), on its marker positions only (a
markers-only copy of the motion: the C3D archive of analog samples, point words and
models is dropped, as bench_scaling.py does, so that the ratio is against float32 xyz,
12 bytes per marker-frame, and is not swamped by analog data coded exactly):

- lossy (paper) mode (``lossy=True``: no bound, pattern layer on): ratio, ARMS and max
  error over a sweep of the clustering threshold tau (theta fixed at its default), and
  the ratio of each strategy interpolated at equal ARMS (2 and 4 mm, the paper's
  operating point);
- bounded mode with the pattern layer forced on (2 mm): ratio at equal max error.

Lengths are in mm (the bound is converted to the file's units).
"""
import argparse
import sys
import time

import numpy as np

from _common import shared_data_dir, shared_data_name
import mpz
from mpz.encoder import EncodeOptions, encode_motion
from mpz.format import MM_PER_UNIT
import mpz.io

FILES = ["cmu_02_01", "HDM_dg_06-03_03_120", "c3dorg_Sample_Jump2", "c3dorg_Eb015pi", "ezc3d_Vicon"]
TAUS = [0.02, 0.05, 0.1, 0.2, 0.4]
TARGETS = (2.0, 4.0)


def run(m, scale=1.0, **kw):
    """(ratio, ARMS, max error, encode seconds); lengths times ``scale`` (mm per unit)."""
    t = time.perf_counter()
    data, rep = encode_motion(m, EncodeOptions(**kw))
    dt = time.perf_counter() - t
    out = mpz.decode(data)
    return (m.raw_size() / len(data), mpz.arms(m, out) * scale,
            mpz.max_error(m, out) * scale, dt)


def markers_only(m):
    """The marker positions with their names, rate, units and gaps, and nothing else."""
    return mpz.Motion(m.positions, m.names, m.rate, m.units, m.valid)


def at_arms(points, target):
    """Ratio at ``target`` ARMS by linear interpolation in (ARMS, log ratio)."""
    pts = sorted(points)
    a = np.array([p[0] for p in pts])
    r = np.log([p[1] for p in pts])
    if not a[0] <= target <= a[-1]:
        return None
    return float(np.exp(np.interp(target, a, r)))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--files", nargs="+", metavar="NAME",
                   help=f"C3D stems under <data>/c3d (default: {' '.join(FILES)})")
    p.add_argument("--taus", nargs="+", type=float, default=TAUS, metavar="TAU",
                   help="the lossy sweep's clustering thresholds (default: %(default)s)")
    args = p.parse_args(argv)
    d = shared_data_dir()
    if d is None:
        print(f"skipped: {shared_data_name()} is absent (set MPZ_SHARED_DATA)")
        return 0
    summary = {(seg, t): [] for seg in ("adaptive", "optimal") for t in TARGETS}
    bounded = {"adaptive": [], "optimal": []}
    measured = 0
    names = args.files or FILES
    for name in names:
        path = d / "c3d" / f"{name.removeprefix('c3d/').removesuffix('.c3d')}.c3d"
        if not path.is_file():
            if args.files:              # a name asked for: a typo is an error, not a skip
                print(f"error: no c3d/{path.stem}.c3d under {d}", file=sys.stderr)
                return 2
            print(f"skipped: no c3d/{path.stem} under {d}")
            continue
        src = mpz.io.read(path)
        scale = MM_PER_UNIT.get(src.units) or 1.0
        m = markers_only(src)
        if not measured:                # JIT warm-up of both strategies, not timed
            for seg in ("adaptive", "optimal"):
                mpz.decode(mpz.encode(m.select_frames(0, min(m.n_frames, 40)), lossy=True,
                                      segmentation=seg))
        measured += 1
        print(f"\n{name}: {m.n_frames} frames x {m.n_markers} markers, units "
              f"{src.units or 'none'}; markers only (raw {m.raw_size()} B)")
        print(f"  {'strategy':<9} {'tau':>5} {'ratio':>6} {'ARMS mm':>8} {'max mm':>8} "
              f"{'enc s':>6}")
        curves = {}
        for seg in ("adaptive", "optimal"):
            pts = []
            for tau in args.taus:
                r, a, mx, dt = run(m, scale, segmentation=seg, tau=tau, lossy=True)
                pts.append((a, r))
                print(f"  {seg:<9} {tau:>5g} {r:>6.1f} {a:>8.3f} {mx:>8.3f} {dt:>6.2f}")
            curves[seg] = pts
            rb, ab, mb, dtb = run(m, scale, segmentation=seg, max_error=2.0 / scale,
                                  patterns="on")
            bounded[seg].append(rb)
            print(f"  {seg:<9} bounded 2 mm, patterns on: ratio {rb:.1f}, ARMS {ab:.3f}, "
                  f"max {mb:.4f}{'' if mb <= 2.0 * (1 + 1e-9) else '  BOUND VIOLATED'}, "
                  f"{dtb:.2f} s")
        for t in TARGETS:
            vals = {seg: at_arms(curves[seg], t) for seg in curves}
            print(f"  ratio at ARMS {t:g} mm: " + ", ".join(
                f"{seg} {'n/a' if v is None else f'{v:.1f}'}" for seg, v in vals.items()))
            if all(v is not None for v in vals.values()):   # compare on the same files only
                for seg, v in vals.items():
                    summary[(seg, t)].append(v)
    if not measured:
        print(f"skipped: none of {', '.join(names)} under {d / 'c3d'}")
        return 0
    print("\nGeometric means over files:")
    for seg in ("adaptive", "optimal"):
        parts = []
        for t in TARGETS:
            s = summary[(seg, t)]
            gm = f"{np.exp(np.mean(np.log(s))):.1f}:1" if s else "n/a"
            parts.append(f"lossy at ARMS {t:g} mm {gm} ({len(s)} files)")
        gb = np.exp(np.mean(np.log(bounded[seg])))
        print(f"  {seg:<9} " + "; ".join(parts) + f"; bounded 2 mm with patterns: {gb:.1f}:1")
    return 0


if __name__ == "__main__":
    sys.exit(main())
