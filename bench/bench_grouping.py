"""The skeleton chunk's group search (spec Appendix C item 11) against coding every count.

    python bench/bench_grouping.py [--synthetic N] [--seed S] [--json out.json]

``mpz.channels.group`` searches the counts of ``GROUP_COUNTS`` from ``FIRST_GROUP_COUNT``
and its neighbours (3-4 codings) where the encoder once coded all six and kept the
smallest. The two choices differ only where the coded length does not fall and then rise
with the count. This bench counts where, and what it costs, on:

- **real channels**: every BVH and AMC file of ../shared/data, its channel residuals as
  the encoder forms them (``plan``, ``coded_values``) at channel steps of 0.001-1 degree
  (and skeleton length units) and at those that joint-position bounds of 0.3-10 mm give
  (``steps_for_position``), over the whole take, its first 100 and 30 frames, and every
  2nd and 4th frame (a lower rate);
- **synthetic channels** (``--synthetic N`` cases): residual matrices of 2-2000 frames x
  1-120 channels, each column Laplace-distributed at a scale drawn log-uniformly over
  four decades, some columns constant, some with rare spikes.

Per set it prints the cases, how many choose another count, the bytes of the search over
those of coding every count (all cases, and the worst one), and the codings it made
(those stopped at their limit included) against 6 a case.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path
import time

import numpy as np

from _common import no_data_reason, shared_data_dir
from bench_speed import bound_kwargs
from mpz import channels as ch
from mpz import skeleton as sk
import mpz.io

ANGLE_ERRORS = (0.001, 0.003, 0.01, 0.03, 0.1, 0.3, 1.0)
POSITION_MM = (0.3, 1.0, 3.0, 5.0, 10.0)


def exhaustive(e: np.ndarray) -> tuple[int, int]:
    """(count, bytes) that coding every count of GROUP_COUNTS and keeping the smallest
    (the fewest groups on a tie) gives: the rule before issue 15.1's search."""
    C = e.shape[1]
    rank = np.empty(C, np.int64)
    rank[np.argsort(ch._cost(e), kind="stable")] = np.arange(C)
    best: tuple[int, int] | None = None
    for G in ch.GROUP_COUNTS:
        if G > C:
            break
        data = ch._encode_groups(e, (rank * G) // C)
        assert data is not None
        if best is None or len(data) < best[1]:
            best = (G, len(data))
    assert best is not None
    return best


def searched(e: np.ndarray) -> tuple[int, int, int]:
    """(count, bytes, codings) of ``channels.group``."""
    calls = 0
    real = ch._encode_groups

    def counted(*a, **k):  # type: ignore[no-untyped-def]
        nonlocal calls
        calls += 1
        return real(*a, **k)

    ch._encode_groups = counted
    try:
        groups, data = ch.group(e)
    finally:
        ch._encode_groups = real
    return int(groups.max(initial=-1)) + 1, len(data), calls


def real_cases(root: Path):  # type: ignore[no-untyped-def]
    """(label, e) for every skeletal file, step and frame window."""
    paths = sorted((root / "bvh").glob("*.bvh")) + sorted((root / "amc").glob("*.amc"))
    for p in paths:
        m = mpz.io.read(p)
        skel = m.extras["skeleton"]
        values = sk._values(m, skel)
        degrees = skel.angle_unit == "deg"
        rot = [degrees and sk.is_rotation(k) for k in skel.channel_kinds()]
        windows = {"all": values, "first100": values[:100], "first30": values[:30],
                   "every2": values[::2], "every4": values[::4]}
        settings = [(f"{err:g} deg", sk.plan_steps(skel, err, err)) for err in ANGLE_ERRORS]
        for mm in POSITION_MM:                    # the steps a joint-position bound gives
            target = bound_kwargs(m, f"{mm:g}mm")[0]["max_error"]
            settings.append((f"{mm:g} mm", sk.steps_for_position(skel, values, target,
                                                                 None, None)[0]))
        for label, steps in settings:
            for w, v in windows.items():
                x = ch.quantise(v, steps)
                yield f"{p.name} {label} {w}", ch.coded_values(x, ch.plan(x, steps, rot))


def synthetic_cases(n: int, seed: int):  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(seed)
    for i in range(n):
        F = int(rng.integers(2, 2001))
        C = int(rng.integers(1, 121))
        scale = 10.0 ** rng.uniform(-1, 3, C)
        e = np.rint(rng.laplace(0, 1, (F, C)) * scale).astype(np.int64)
        e[:, rng.random(C) < 0.1] = 0
        spikes = rng.random((F, C)) < 0.002
        e[spikes] = rng.integers(-10 ** 5, 10 ** 5, int(spikes.sum()))
        yield f"synthetic {i} {F}x{C}", e


def run(cases) -> dict:  # type: ignore[no-untyped-def]
    n = differ = calls = 0
    old_bytes = new_bytes = 0
    worst = (0.0, "")
    t_old = t_new = 0.0
    for label, e in cases:
        t = time.perf_counter()
        G0, b0 = exhaustive(e)
        t_old += time.perf_counter() - t
        t = time.perf_counter()
        G1, b1, k = searched(e)
        t_new += time.perf_counter() - t
        n += 1
        calls += k
        old_bytes += b0
        new_bytes += b1
        assert b1 >= b0, label               # the search can only miss the smallest
        if G1 != G0:
            differ += 1
            excess = b1 / b0 - 1
            if excess >= worst[0]:
                worst = (excess, f"{label}: G {G0} -> {G1}, {b0} -> {b1} bytes")
    return {"cases": n, "differ": differ, "bytes_ratio": new_bytes / max(old_bytes, 1),
            "worst": worst[1], "worst_excess": worst[0], "codings": calls / max(n, 1),
            "seconds_all_counts": t_old, "seconds_search": t_new}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--synthetic", type=int, default=500, help="synthetic cases (500)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", help="write the results here")
    args = ap.parse_args(argv)
    out = {}
    reason = no_data_reason(exts=(".bvh", ".amc"))
    if reason:
        print(f"real channels skipped: {reason}")
    else:
        root = shared_data_dir()
        assert root is not None
        out["real"] = run(real_cases(root))
    if args.synthetic > 0:
        out["synthetic"] = run(synthetic_cases(args.synthetic, args.seed))
    else:
        print("synthetic channels skipped: --synthetic 0")
    for name, r in out.items():
        if not r["cases"]:
            print(f"{name:10s} skipped: no case")
            continue
        print(f"{name:10s} {r['cases']:5d} cases, {r['differ']} choose another count; "
              f"bytes {r['bytes_ratio']:.6f} x coding every count "
              f"(worst +{100 * r['worst_excess']:.2f} %: {r['worst'] or '-'}); "
              f"{r['codings']:.2f} codings a case (6 before); "
              f"{r['seconds_search']:.2f} s against {r['seconds_all_counts']:.2f} s")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
