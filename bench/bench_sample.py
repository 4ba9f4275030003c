"""The base-1 sample (spec Appendix C item 6) against trying base 1 on every node, on
varied synthetic motions; prints figures, asserts nothing.

    python bench/bench_sample.py [--cases 2000] [--seed 2] [--json OUT]

Each case is a motion of the project's generator (``mpz.synth.generate``: kind, frames,
markers, noise and gaps drawn at random), then one of: unchanged, every 2nd-4th marker
held still, every 2nd-4th marker plus white noise, some markers jittered, or the first
half of the clip frozen. It is encoded at a random bound (0.05-10 mm, one thread) twice:
with the encoder's rule, and with ``ABSOLUTE_LOSES`` so high that base 1 is always
tried. In a node the rule can only make the residual layer larger (base 1 left untried
where it would have won); across a file of several nodes, later nodes are coded against
decoded tracks, so they may move either way (the default plan has one node). The table
lists every case whose bytes differ.
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np

import mpz.encoder as E
from mpz.motion import Motion
from mpz.synth import KINDS, generate

MIXES = ("none", "still_every", "noisy_every", "jitter_some", "frozen_half")


def case(rng: np.random.Generator) -> tuple[Motion, dict]:
    """One random motion and what it is made of."""
    kind = str(rng.choice(list(KINDS)))
    F = int(rng.choice([8, 30, 120, 343, 800, 1500, 3000]))
    M = int(rng.choice([5, 12, 41]))
    noise = float(rng.choice([0.0, 0.3, 1.0, 3.0, 10.0]))
    m = generate(kind, frames=F, seed=int(rng.integers(1 << 30)), noise_mm=noise,
                 gap_fraction=float(rng.choice([0.0, 0.0, 0.05, 0.3])), markers=M)
    x = m.positions.copy()
    mix = str(rng.choice(MIXES))
    if mix == "still_every":
        s = int(rng.choice([2, 3, 4]))
        x[:, ::s] = x[:1, ::s]
    elif mix == "noisy_every":
        s = int(rng.choice([2, 3, 4]))
        x[:, ::s] += rng.normal(0, float(rng.choice([1, 5, 30])), x[:, ::s].shape)
    elif mix == "jitter_some":
        cols = rng.random(x.shape[1]) < 0.3
        x[:, cols] += rng.normal(0, 3.0, x[:, cols].shape)
    elif mix == "frozen_half":
        x[: F // 2] = x[:1]
    motion = Motion(x, m.names, m.rate, m.units, np.isfinite(x).all(axis=2))
    return motion, {"kind": kind, "frames": F, "markers": M, "noise_mm": noise, "mix": mix}


def main() -> None:
    ap = argparse.ArgumentParser(
        description="The base-1 sample (spec Appendix C item 6) against trying base 1 on "
        "every node, on varied synthetic motions: each case is encoded with the encoder's "
        "rule and with base 1 always tried, and the cases whose bytes differ are listed. "
        "Prints figures, asserts nothing.")
    ap.add_argument("--cases", type=int, default=2000, help="random motions (default 2000)")
    ap.add_argument("--seed", type=int, default=2, help="of the random cases (default 2)")
    ap.add_argument("--json", help="write every case's row here")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    rows = []
    t0 = time.perf_counter()
    rule = E.ABSOLUTE_LOSES
    for k in range(args.cases):
        motion, row = case(rng)
        bound = float(rng.choice([0.05, 0.2, 1.0, 3.0, 10.0]))
        opts = E.EncodeOptions(max_error=bound, threads=1)
        E.ABSOLUTE_LOSES = rule
        sampled = len(E.encode_motion(motion, opts)[0])
        E.ABSOLUTE_LOSES = 1e9
        try:
            tried = len(E.encode_motion(motion, opts)[0])
        finally:
            E.ABSOLUTE_LOSES = rule
        rows.append({**row, "case": k, "bound_mm": bound, "rule": sampled, "tried": tried})
    differ = [r for r in rows if r["rule"] != r["tried"]]
    total = sum(r["rule"] for r in rows) / sum(r["tried"] for r in rows) - 1
    print(f"{len(rows)} cases (seed {args.seed}) in {time.perf_counter() - t0:.0f} s: "
          f"{len(differ)} differ, {sum(r['rule'] > r['tried'] for r in differ)} larger; "
          f"all bytes {total:+.4%}")
    for r in sorted(differ, key=lambda r: r["rule"] / r["tried"]):
        print(f"  {r['rule'] / r['tried'] - 1:+7.2%}  {r['kind']:6s} {r['frames']:5d} frames "
              f"{r['markers']:2d} markers noise {r['noise_mm']:4.1f} mm {r['mix']:12s} "
              f"bound {r['bound_mm']:g} mm  {r['rule']} B vs {r['tried']} B")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
