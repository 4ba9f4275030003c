"""Adaptive (paper Alg. 1) against optimal (Fisher) segmentation in the encoder.

    python bench/bench_segmentation.py

Neither paper made this comparison. For each real C3D clip (short ones: the
optimal partition is O(n^2 (D + k)) per node):

- lossy (paper) mode: ratio and ARMS over a sweep of the clustering threshold
  tau (theta fixed at its default), and the ratio of each strategy
  interpolated at equal ARMS (2 and 4 mm, the paper's operating point);
- bounded mode with the pattern layer forced on (2 mm): ratio at equal max error.
"""
import sys
import time

import numpy as np

from _common import shared_data_dir
import mpz
from mpz.encoder import EncodeOptions, encode_motion
import mpz.io

FILES = ["cmu_02_01", "HDM_dg_06-03_03_120", "c3dorg_Sample_Jump2", "c3dorg_Eb015pi", "ezc3d_Vicon"]
TAUS = [0.02, 0.05, 0.1, 0.2, 0.4]
TARGETS = (2.0, 4.0)


def run(m, **kw):
    t = time.perf_counter()
    data, rep = encode_motion(m, EncodeOptions(**kw))
    dt = time.perf_counter() - t
    out = mpz.decode(data)
    return m.raw_size() / len(data), mpz.arms(m, out), mpz.max_error(m, out), dt


def at_arms(points, target):
    """Ratio at ``target`` ARMS by linear interpolation in (ARMS, log ratio)."""
    pts = sorted(points)
    a = np.array([p[0] for p in pts])
    r = np.log([p[1] for p in pts])
    if not a[0] <= target <= a[-1]:
        return None
    return float(np.exp(np.interp(target, a, r)))


def main():
    d = shared_data_dir()
    if d is None:
        print("skipped: ../shared/data is absent")
        return 0
    summary = {(seg, t): [] for seg in ("adaptive", "optimal") for t in TARGETS}
    bounded = {"adaptive": [], "optimal": []}
    for name in FILES:
        m = mpz.io.read(d / "c3d" / f"{name}.c3d")
        print(f"\n{name}: {m.n_frames} frames x {m.n_markers} markers")
        print(f"  {'strategy':<9} {'tau':>5} {'ratio':>6} {'ARMS':>6} {'max':>7} {'enc s':>6}")
        curves = {}
        for seg in ("adaptive", "optimal"):
            pts = []
            for tau in TAUS:
                r, a, mx, dt = run(m, segmentation=seg, tau=tau)
                pts.append((a, r))
                print(f"  {seg:<9} {tau:>5} {r:>6.1f} {a:>6.2f} {mx:>7.1f} {dt:>6.2f}")
            curves[seg] = pts
            rb, ab, mb, dtb = run(m, segmentation=seg, max_error=2.0, patterns="on")
            bounded[seg].append(rb)
            print(f"  {seg:<9} bounded 2 mm, patterns on: ratio {rb:.1f}, max {mb:.3f}, "
                  f"{dtb:.2f} s")
        for t in TARGETS:
            vals = {seg: at_arms(curves[seg], t) for seg in curves}
            print(f"  ratio at ARMS {t:g} mm: " + ", ".join(
                f"{seg} {'n/a' if v is None else f'{v:.1f}'}" for seg, v in vals.items()))
            if all(v is not None for v in vals.values()):   # compare on the same files only
                for seg, v in vals.items():
                    summary[(seg, t)].append(v)
    print("\nGeometric means over files:")
    for seg in ("adaptive", "optimal"):
        parts = []
        for t in TARGETS:
            s = summary[(seg, t)]
            gm = np.exp(np.mean(np.log(s))) if s else float("nan")
            parts.append(f"lossy at ARMS {t:g} mm {gm:.1f}:1 ({len(s)} files)")
        gb = np.exp(np.mean(np.log(bounded[seg])))
        print(f"  {seg:<9} " + "; ".join(parts) + f"; bounded 2 mm with patterns: {gb:.1f}:1")
    return 0


if __name__ == "__main__":
    sys.exit(main())
