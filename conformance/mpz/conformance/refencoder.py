"""The reference encoder as a conformance-runner command.

Usage: ``python -m mpz.conformance.refencoder IN.npy OUT.mpz --max-error E``

IN.npy is float64 [frames, markers, 3] with NaN at gaps; its sidecar IN.json
(same path, suffix .json) gives ``names``, ``rate`` and ``units``. Exit
status: 0 written, 2 the input or options are refused (message on stderr).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path
import sys

import numpy as np


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m mpz.conformance.refencoder")
    p.add_argument("input", help="float64 [frames, markers, 3] .npy, NaN at gaps")
    p.add_argument("output", help="MPZ file to write")
    p.add_argument("--max-error", type=float, required=True, metavar="E",
                   help="max Euclidean error per valid sample, in the input's units")
    args = p.parse_args(argv)
    import mpz
    try:
        x = np.load(args.input, allow_pickle=False)
        side = json.loads(Path(args.input).with_suffix(".json").read_text(encoding="utf-8"))
        motion = mpz.Motion(x, side["names"], side["rate"], side.get("units", ""))
        mpz.write_mpz(motion, args.output, max_error=args.max_error)
    except (OSError, ValueError, KeyError) as exc:   # MPZError is a ValueError
        print(f"{type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
