"""``mpz bench --compare OLD.json NEW.json``: flag regressions between two benchmark runs.

The JSON files are written by ``python bench/bench_rd.py --json FILE`` (schema 1: one row
per file and bound with ratio, max error, ARMS and times); ``-`` reads one of them from
standard input. A row is flagged when its ratio drops by more than ``--ratio-tolerance``
(default 1 %); when a bounded row of the new run (a numeric E, the "op" operating point,
or any row with a "bound") has a max error above its bound; when an unbounded (lossy)
row's ARMS or max error grows by more than ``--distortion-tolerance`` (default 1 %: the
encoder is deterministic, so the same code gives the same figures); or when its encode or
decode time grows by more than ``--speed-tolerance`` (default 25 %) and by more than
``--time-floor`` seconds (default 0.001 s: below that, timing noise; the best-of CPU times
of two runs of the same code moved by 15 % at most here, and the floors before, 0.05 s
until stop 48 and 0.005 s until stop 53, hid a decoder three times slower on the real
files, whose times are about a millisecond). The times compared are the process CPU
seconds (enc_cpu_s, dec_cpu_s: bench_rd's best of several runs, which other processes
hardly move) when both runs have them, else the wall-clock ones (enc_s, dec_s). A file
with two rows of the same file and E is refused, and so are two runs that measured
different inputs (bench_rd.py's "input": a run that does not say it came from a
bench_rd.py before 2026-12-04, whose MPZ ratios may count a C3D's archive as well; run
today's bench_rd.py with the old version instead), or a row whose raw size differs (other data
under the same name). A row whose bound or unit scale (``bound``, ``mm_per_unit``) differs
between the runs is flagged: its ratio and errors are not of the same question (a reader
that took another unit moved the bound tenfold without a word). A comparison of no row at
all (an empty or foreign run) exits 1. Besides the regressions, every row whose file size,
max error or ARMS is not the same in both runs is listed as CHANGED, improvements too: the
encoder is deterministic, so a change means the code or the data changed, which a
maintainer wants to see even below the tolerances. Times of two runs that bench_rd.py
recorded on different machines ("host", "machine") are not compared, and a note says so.
Exit 0: no regression (changes or not);
1: regressions flagged, or no row compared; 2: unreadable input.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys

from mpz.errors import FormatError
from mpz.tools._cli import found, print_json, printable

#: ``--json``'s schema (docs/json.md); a bare list before it had one
JSON_SCHEMA = "mpz-bench-compare/1"

#: the bound, in mm, of bench_rd.py's "op" row (the paper's operating point) in results
#: written before the rows carried their "bound"
OPERATING_BOUND = 6.5


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


def _open_fraction(text: str) -> float:
    """argparse type of a ratio tolerance: a fraction strictly between 0 and 1 (1 or more
    turned the ratio check off: a ratio cannot drop by 100 %)."""
    v = _fraction(text)
    if not 0 < v < 1:
        raise argparse.ArgumentTypeError(f"wants a fraction between 0 and 1 (exclusive), "
                                         f"got {text!r}")
    return v


def add_parser(sub):
    p = sub.add_parser("bench", help="compare two benchmark result files",
                       description=__doc__.split("\n\n")[1])
    p.add_argument("--compare", nargs=2, metavar=("OLD", "NEW"), required=True,
                   help="two bench_rd.py --json results; '-' for standard input (one of them)")
    p.add_argument("--ratio-tolerance", type=_open_fraction, default=0.01,
                   help="flag a ratio that drops by more than this fraction, in (0, 1) "
                        "(default 0.01)")
    p.add_argument("--distortion-tolerance", type=_fraction, default=0.01,
                   help="flag an unbounded row whose ARMS or max error grows by more than "
                        "this fraction (default 0.01)")
    p.add_argument("--speed-tolerance", type=_fraction, default=0.25,
                   help="flag a time that grows by more than this fraction (default 0.25) "
                        "and by more than --time-floor")
    p.add_argument("--time-floor", type=_fraction, default=0.001, metavar="SECONDS",
                   help="a time must also grow by more than this many seconds to be flagged "
                        "(default 0.001: smaller differences are timing noise)")
    p.add_argument("--json", action="store_true",
                   help="print one JSON object (schema mpz-bench-compare/1, docs/json.md): "
                        "regressions and changes, one object each with file, E (null for a "
                        "lossy row) and problem or change; the notes also go to standard "
                        "error")
    p.set_defaults(func=run, bench_parser=p)


def _refuse(token: str) -> float:
    raise ValueError(f"{token} is not a number a result can hold")


#: a row's figures: (name, required); each a finite number (times and errors 0 or more,
#: the ratio above 0)
_FIGURES = (("mpz_ratio", True), ("max", False), ("arms", False), ("enc_s", False),
            ("dec_s", False), ("enc_cpu_s", False), ("dec_cpu_s", False), ("bound", False),
            ("bytes", False), ("raw", False), ("mm_per_unit", False))


def bound_of(key: tuple, row: dict) -> float | None:
    """The bound a row declares: its "bound", else a numeric E, else 6.5 for the "op" row
    (:data:`OPERATING_BOUND`); None for an unbounded (lossy) row."""
    if "bound" in row:
        return row["bound"]
    if _number(key[1]):
        return key[1]
    if key[1] == "op":
        return OPERATING_BOUND
    return None


def _read(path):
    """The bytes of a result file, or of standard input for ``-``."""
    if path == "-":
        return sys.stdin.buffer.read()
    from mpz.api import read_source
    return read_source(path)[0]


def _load(path):
    """The rows of a bench_rd.py result by (file, E: a bound, None for lossy, or a label such
    as "op"), and the input it declares it measured (None: before bench_rd said; its MPZ
    ratios counted a C3D's archive too). Anything else, a figure that is not a finite
    number (NaN passed every check: a QA run), two rows with the same key, or a bounded
    row without its max error is a FormatError (exit 2)."""
    from mpz.errors import MPZError
    where = "standard input" if path == "-" else path
    try:
        doc = json.loads(_read(path), parse_constant=_refuse)
    except MPZError as exc:
        hint = ("" if path == "-" or os.path.lexists(path) else
                " (bench_rd.py writes no JSON when it skips for want of data: see its output)")
        raise FormatError(f"cannot read benchmark results: {exc.message}{hint}",
                          path=where) from None
    except ValueError as exc:          # JSON, UTF-8, or a NaN / Infinity token
        raise FormatError(f"cannot read benchmark results: {exc}", path=where) from None
    except RecursionError:             # 100,000 nested brackets: exit 70 (a QA run)
        raise FormatError("cannot read benchmark results: JSON nested too deeply",
                          path=where) from None
    if (not isinstance(doc, dict) or doc.get("schema") != 1
            or not isinstance(doc.get("rows"), list)):
        raise FormatError("not a bench_rd.py result (schema 1 with rows)", path=where)
    rows: dict = {}
    first: dict = {}
    for i, r in enumerate(doc["rows"]):
        if not _row_ok(r):
            raise FormatError(f"row {i} is not a result row (file, E: a bound, a label or "
                              f"null for lossy, mpz_ratio above 0, and where present the "
                              f"finite figures 0 or more "
                              f"{', '.join(n for n, req in _FIGURES if not req)})",
                              path=where)
        key = (r["file"], r.get("E"))
        if key in rows:
            raise FormatError(f"rows {first[key]} and {i} are both file {r['file']!r} at "
                              f"E={_e(key[1])}: which one to compare is ambiguous", path=where)
        if bound_of(key, r) is not None and "max" not in r:
            raise FormatError(f"row {i} ({r['file']!r}, E={_e(key[1])}) is bounded but has no "
                              f"max error: its bound cannot be checked", path=where)
        rows[key] = r
        first[key] = i
    return rows, doc.get("input"), {k: doc[k] for k in ("host", "machine")
                                    if isinstance(doc.get(k), str)}


def _row_ok(r: object) -> bool:
    # E is required, null for a lossy row: a row without it was taken as the lossy one
    if not (isinstance(r, dict) and isinstance(r.get("file"), str) and "E" in r
            and (r["E"] is None or isinstance(r["E"], str) or _number(r["E"]))):
        return False
    for name, required in _FIGURES:
        if (name in r or required) and not (_number(r.get(name)) and r[name] >= 0):
            return False
    return bool(r["mpz_ratio"] > 0)


def _number(v: object) -> bool:
    if not isinstance(v, (int, float)) or isinstance(v, bool):
        return False
    try:
        return math.isfinite(v)
    except OverflowError:           # an int past float's range (10**400): exit 70 (QA)
        return False


def compare(old: dict, new: dict, ratio_tol=0.01, speed_tol=0.25, distortion_tol=0.01,
            time_floor=0.001) -> list:
    """List of (key, problem) for every regression of ``new`` against ``old``."""
    flags = []
    for key, n in new.items():
        bound = bound_of(key, n)
        if bound is not None and n.get("max", 0) > bound:
            # repr: the shortest text that reads back as the same float (2.0001, not "2")
            flags.append((key, f"bound violated: max error {float(n['max'])!r} > "
                               f"{float(bound)!r}"))
        o = old.get(key)
        if o is None:
            continue
        for what in ("bound", "mm_per_unit"):
            if what in o and what in n and o[what] != n[what]:
                flags.append((key, f"{what} changed {float(o[what])!r} -> {float(n[what])!r}: "
                                   "the rows measure another question (a reader that "
                                   "takes other units?)"))
        if n["mpz_ratio"] < o["mpz_ratio"] * (1 - ratio_tol):
            flags.append((key, f"ratio dropped {o['mpz_ratio']:.2f} -> {n['mpz_ratio']:.2f} "
                               f"({100 * (n['mpz_ratio'] / o['mpz_ratio'] - 1):+.1f} %)"))
        if bound is None:
            for d in ("arms", "max"):
                if d not in o:
                    continue
                if d not in n:
                    flags.append((key, f"{d} missing from the new run's unbounded row"))
                elif n[d] > o[d] * (1 + distortion_tol):
                    flags.append((key, f"{'ARMS' if d == 'arms' else 'max error'} grew "
                                       f"{o[d]:.4f} -> {n[d]:.4f}"))
        for what in ("enc", "dec"):
            # the process CPU time when both runs have it: other processes hardly move it
            t = f"{what}_cpu_s" if f"{what}_cpu_s" in n and f"{what}_cpu_s" in o else f"{what}_s"
            if (t in n and t in o and n[t] > o[t] * (1 + speed_tol)
                    and n[t] - o[t] > time_floor):
                flags.append((key, f"{what}oding slower{' (CPU)' if 'cpu' in t else ''} "
                                   f"{o[t]:.3f} s -> {n[t]:.3f} s"))
    missing = sorted(set(old) - set(new), key=str)
    flags.extend((k, "missing from the new run") for k in missing)
    return flags


def changes(old: dict, new: dict) -> list:
    """List of (key, what changed) for every row of both runs whose file size, max error
    or ARMS differs at all, better or worse (a QA run of stop 48: an encoder change that
    moved 15 of 18 file sizes by -0.5 .. +0.7 % printed what two runs of the same code
    print). The times are left out: they differ between any two runs."""
    out = []
    for key, n in new.items():
        o = old.get(key)
        if o is None:
            continue
        said = []
        if "bytes" in o and "bytes" in n and o["bytes"] != n["bytes"]:
            said.append(f"{o['bytes']} -> {n['bytes']} B "
                        f"({100 * (n['bytes'] / o['bytes'] - 1):+.2f} %)")
        elif "bytes" not in o or "bytes" not in n:
            if o["mpz_ratio"] != n["mpz_ratio"]:
                said.append(f"ratio {o['mpz_ratio']:.4g} -> {n['mpz_ratio']:.4g}")
        for d, name in (("max", "max error"), ("arms", "ARMS")):
            if d in o and d in n and o[d] != n[d]:
                said.append(f"{name} {o[d]:.6g} -> {n[d]:.6g} "
                            f"({100 * (n[d] / o[d] - 1) if o[d] else math.inf:+.2f} %)")
        if said:
            out.append((key, "; ".join(said)))
    return out


def _other_data(old: dict, new: dict) -> list:
    """The keys of rows of both runs whose raw float32 size differs: the same file name,
    other data (another copy of the corpus), whose ratios do not compare."""
    return [k for k, n in new.items() if k in old and "raw" in n and "raw" in old[k]
            and n["raw"] != old[k]["raw"]]


def run(args) -> int:
    if args.compare == ["-", "-"]:
        args.bench_parser.error("only one of OLD and NEW can be '-' (standard input)")
    (old, old_input, old_at), (new, new_input, new_at) = (_load(args.compare[0]),
                                                          _load(args.compare[1]))
    if old_input != new_input:
        # a run that does not say came from a bench_rd.py before it did: its ratios may
        # count a C3D archive (an mpz of issue 12 and after) or not (0.1.0 had none), so
        # "plus the C3D archive" was a false claim of a 0.1.0 run, and "rerun the old
        # version's bench" what made it (a maintainer's QA run of stop 75)
        before = "not said: a bench_rd.py before 2026-12-04, whose ratios may count a C3D archive"
        raise FormatError(f"the two runs measured different inputs ({old_input or before} "
                          f"against {new_input or before}): their ratios cannot be "
                          f"compared; run this bench_rd.py with the other version installed "
                          f"(README, For maintainers), which says what it measures")
    other = _other_data(old, new)
    if other:
        (f, e) = other[0]
        raise FormatError(f"the two runs measured other data under the same names ({len(other)} "
                          f"row(s), the first {f!r} at E={e}: {old[other[0]]['raw']} against "
                          f"{new[other[0]]['raw']} raw bytes): their ratios cannot be compared")
    # times from two machines do not compare (bench_rd.py records where it ran since stop
    # 48): they are left out, and said to be, instead of flagging every row (a QA run)
    elsewhere = [k for k in ("host", "machine") if k in old_at and k in new_at
                 and old_at[k] != new_at[k]]
    speed_tol = math.inf if elsewhere else args.speed_tolerance
    flags = compare(old, new, args.ratio_tolerance, speed_tol,
                    args.distortion_tolerance, args.time_floor)
    notes = []            # on standard error with --json, which keeps standard output JSON
    if elsewhere:
        k = elsewhere[0]
        notes.append(f"the runs were made on different machines ({k} {old_at[k]!r} and "
                     f"{new_at[k]!r}): their times are not compared")
    unsized = [k for k in new if k in old and ("raw" not in new[k] or "raw" not in old[k])]
    if unsized:             # _other_data cannot check these (a run from an older bench_rd)
        notes.append(f"{len(unsized)} row(s) have no raw size in one of the runs (the first "
                     f"{_label(unsized[0])}): that both measured the same data is not checked")
    changed = changes(old, new)
    unmatched = [k for k in new if k not in old]
    if unmatched:
        names = ", ".join(_label(k) for k in unmatched[:5])
        notes.append(f"{len(unmatched)} row(s) of the new run have no row in the old run: "
                     f"{names}{', ...' if len(unmatched) > 5 else ''}")
    compared = len(new) - len(unmatched)
    if not compared:      # an empty or foreign run passed as clean, exit 0 (a QA run of stop 53)
        notes.append("no row was compared: the runs share no (file, E) row")
    code = 1 if flags or not compared else 0
    found(code)                   # what a pipe closed in the report exits with
    for note in notes:
        print(f"note: {printable(note)}", file=sys.stderr if args.json else sys.stdout)
    if args.json:
        print_json({"schema": JSON_SCHEMA, "compared": compared,
                    "unmatched": [{"file": k[0], "E": k[1]} for k in unmatched],
                    "regressions": [{"file": k[0], "E": k[1], "problem": p}
                                    for k, p in flags],
                    "changes": [{"file": k[0], "E": k[1], "change": c} for k, c in changed],
                    "notes": notes})
    else:
        for key, problem in flags:
            print(f"REGRESSION {printable(_label(key))}: {printable(problem)}")
        for key, change in changed:
            print(f"CHANGED {printable(_label(key))}: {printable(change)}")
        print(f"{compared} rows compared"
              f"{f', {len(unmatched)} without a row in the old run' if unmatched else ''}; "
              f"{len(flags)} regression(s), {len(changed)} changed (size, max error or ARMS)")
    return code


def _label(key: tuple) -> str:
    """A row as messages name it: ``c3d/cmu_02_01 E=1.0``, ``... E=lossy`` (E null)."""
    return f"{key[0]} E={_e(key[1])}"


def _e(e: object) -> object:
    """A row's E as messages say it: ``lossy`` for null (it printed ``None``)."""
    return "lossy" if e is None else e
