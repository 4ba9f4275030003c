"""``mpz bench --compare OLD.json NEW.json``: flag regressions between two benchmark runs.

The JSON files are written by ``python bench/bench_rd.py --json FILE`` (schema 1:
one row per file and bound with ratio, max error, ARMS and times). A row is
flagged when its ratio drops by more than ``--ratio-tolerance`` (default 1 %),
when the new run breaks its declared bound, or when encode or decode time
grows by more than ``--speed-tolerance`` (default 25 %, to stay above timing
noise). Exit 0: no regression; 1: regressions flagged; 2: unreadable input.
"""
from __future__ import annotations

import argparse
import json
import math

from mpz.errors import FormatError
from mpz.tools._cli import print_json, printable


def _fraction(text: str) -> float:
    """argparse type of a tolerance: a finite fraction, 0 or more (a QA run: NaN and inf
    turned every check off and printed '0 regression(s)')."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"wants a number, got {text!r}") from None
    if not (math.isfinite(v) and v >= 0):
        raise argparse.ArgumentTypeError(f"wants a finite number, 0 or more, got {text!r}")
    return v


def add_parser(sub):
    p = sub.add_parser("bench", help="compare two benchmark result files",
                       description=__doc__.split("\n\n")[1])
    p.add_argument("--compare", nargs=2, metavar=("OLD", "NEW"), required=True)
    p.add_argument("--ratio-tolerance", type=_fraction, default=0.01,
                   help="flag a ratio that drops by more than this fraction (default 0.01)")
    p.add_argument("--speed-tolerance", type=_fraction, default=0.25,
                   help="flag a time that grows by more than this fraction (default 0.25)")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def _refuse(token: str) -> float:
    raise ValueError(f"{token} is not a number a result can hold")


#: a row's figures: (name, required); each a finite number (times and errors 0 or more,
#: the ratio above 0)
_FIGURES = (("mpz_ratio", True), ("max", False), ("enc_s", False), ("dec_s", False))


def _load(path):
    """The rows of a bench_rd.py result by (file, E: a bound, None for lossy, or a label such
    as "op"). Anything else, or a figure that is
    not a finite number (NaN passed every check: a QA run), is a FormatError (exit 2)."""
    from mpz.api import read_source
    from mpz.errors import MPZError
    try:
        data, _ = read_source(path)
        doc = json.loads(data, parse_constant=_refuse)
    except MPZError as exc:
        raise FormatError(f"cannot read benchmark results: {exc.message}", path=path) from None
    except ValueError as exc:          # JSON, UTF-8, or a NaN / Infinity token
        raise FormatError(f"cannot read benchmark results: {exc}", path=path) from None
    if (not isinstance(doc, dict) or doc.get("schema") != 1
            or not isinstance(doc.get("rows"), list)):
        raise FormatError("not a bench_rd.py result (schema 1 with rows)", path=path)
    rows = {}
    for i, r in enumerate(doc["rows"]):
        if not _row_ok(r):
            raise FormatError(f"row {i} is not a result row (file, E, and finite figures "
                              f"{', '.join(n for n, _ in _FIGURES)})", path=path)
        rows[(r["file"], r.get("E"))] = r
    return rows


def _row_ok(r: object) -> bool:
    if not (isinstance(r, dict) and isinstance(r.get("file"), str)
            and (r.get("E") is None or isinstance(r["E"], str) or _number(r["E"]))):
        return False
    for name, required in _FIGURES:
        if (name in r or required) and not (_number(r.get(name)) and r[name] >= 0):
            return False
    return bool(r["mpz_ratio"] > 0)


def _number(v: object) -> bool:
    return (isinstance(v, (int, float)) and not isinstance(v, bool)
            and math.isfinite(v))


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
