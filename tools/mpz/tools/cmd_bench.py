"""``mpz bench --compare OLD.json NEW.json``: flag regressions between two benchmark runs.

The JSON files are written by ``python bench/bench_rd.py --json FILE`` (schema 1:
one row per file and bound with ratio, max error, ARMS and times). A row is
flagged when its ratio drops by more than ``--ratio-tolerance`` (default 1 %),
when the new run breaks its declared bound, or when encode or decode time
grows by more than ``--speed-tolerance`` (default 25 %, to stay above timing
noise). Exit 0: no regression; 1: regressions flagged; 2: unreadable input.
"""
from __future__ import annotations

import json

from mpz.errors import FormatError
from mpz.tools._cli import print_json, printable


def add_parser(sub):
    p = sub.add_parser("bench", help="compare two benchmark result files",
                       description=__doc__.split("\n\n")[1])
    p.add_argument("--compare", nargs=2, metavar=("OLD", "NEW"), required=True)
    p.add_argument("--ratio-tolerance", type=float, default=0.01)
    p.add_argument("--speed-tolerance", type=float, default=0.25)
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def _load(path):
    try:
        with open(path) as fh:
            doc = json.load(fh)
    except (OSError, ValueError) as exc:
        raise FormatError(f"cannot read benchmark results: {exc}", path=path) from None
    if doc.get("schema") != 1 or "rows" not in doc:
        raise FormatError("not a bench_rd.py result (schema 1 with rows)", path=path)
    return {(r["file"], r.get("E")): r for r in doc["rows"]}


def compare(old: dict, new: dict, ratio_tol=0.01, speed_tol=0.25) -> list:
    """List of (key, problem) for every regression of ``new`` against ``old``."""
    flags = []
    for key, n in new.items():
        if isinstance(key[1], (int, float)) and n.get("max", 0) > key[1]:
            flags.append((key, f"bound violated: max error {n['max']:.4g} > {key[1]}"))
        o = old.get(key)
        if o is None:
            continue
        if n["mpz_ratio"] < o["mpz_ratio"] * (1 - ratio_tol):
            flags.append((key, f"ratio dropped {o['mpz_ratio']:.2f} -> {n['mpz_ratio']:.2f} "
                               f"({100 * (n['mpz_ratio'] / o['mpz_ratio'] - 1):+.1f} %)"))
        for t in ("enc_s", "dec_s"):
            if t in n and t in o and o[t] > 0.05 and n[t] > o[t] * (1 + speed_tol):
                flags.append((key, f"{t[:3]}oding slower {o[t]:.3f} s -> {n[t]:.3f} s"))
    missing = sorted(set(old) - set(new), key=str)
    flags.extend((k, "missing from the new run") for k in missing)
    return flags


def run(args) -> int:
    old, new = _load(args.compare[0]), _load(args.compare[1])
    flags = compare(old, new, args.ratio_tolerance, args.speed_tolerance)
    if args.json:
        print_json([{"file": k[0], "E": k[1], "problem": p} for k, p in flags])
    else:
        for (f, e), problem in flags:
            print(f"REGRESSION {printable(f)} E={e}: {printable(problem)}")
        print(f"{len(new)} rows compared, {len(flags)} regression(s)")
    return 1 if flags else 0
