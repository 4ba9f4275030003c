"""Decode speed of every real file, and two runs compared: for decoder changes.

    python bench/bench_decode.py [--files all | NAME ...] [--bound 1mm] --json OUT.json
        [--save-inputs DIR | --inputs DIR]
    python bench/bench_decode.py --compare BEFORE.json ... --against AFTER.json ...

The first form encodes each file once at 1 mm (1 unit where the file declares no units)
with one thread and times ``mpz.decode`` of the bytes: the best of at least 5 calls and
0.3 s (bench_speed's ``timed``), in MB/s of bench_speed's yardstick (every sample MPZ
codes, as float32). It prints one row per file and writes them as JSON, with the SHA-256
of the encoded bytes (``mpz_sha256``) and of what the decode gave back (``decoded``: the
positions as float64 bytes, and the C3D archive and skeleton outputs when the file has
them; see :func:`decoded_digests`). The numba kernels are loaded first on the first file
asked for (not timed). An absent or empty data folder prints "skipped: ..." (exit 0).

When the encoder changed too, each version decodes its own encoder's bytes, so the times
measure both changes: ``--save-inputs DIR`` on one run writes the encoded files, and
``--inputs DIR`` on the others (either version) decodes those same bytes; the compare
table says for how many files the encoded bytes are the same on both sides.

Decoder changes move the figures by less than the machine's noise from one process to the
next, so compare several runs of each version made alternately: run the first form with
the old code (the Python of a venv where ``pip install -e`` put a ``git worktree`` of the
old commit: a ``PYTHONPATH`` of its folders mixes in the editable install's new
``mpz.spec``) and the new, in turns, then ``--compare`` takes each file's best over the old
runs and over the new, and prints the table: ms and MB/s before and after, the geometric
mean of the rows, the files together, and the rows below 20 MB/s (issue 4's decode line).

The verdict of ``--compare`` (exit 1, each cause named; exit 0 otherwise):

- a file decodes slower by more than :data:`SLOWER` (25 %) of its best-of time before
  (each side's best over its runs: with a few runs a side, identical code stays well
  within it, while single timings under load do not);
- a file's decoded output differs (a digest of ``decoded``), saying whether the encoded
  bytes differ too (then the encoder changed as well) or not (the decoder did);
- a file is in one run set only, or the two share no file.

Two runs of one side that disagree on the decoded output, and a JSON that is not a
bench_decode.py result of this schema, are errors (exit 2 with a message, as ``mpz
bench``).
"""
from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import math
from pathlib import Path
import sys

import numpy as np

from _common import (
    Unreadable,
    coded_float32,
    compare_main,
    is_bound_label,
    no_data_reason,
    shared_data_dir,
    two_versions,
    warm_up,
)

SCHEMA = 1
#: ``--compare`` flags a file whose best decode time after is above (1 + SLOWER) x before
SLOWER = 0.25


def _feed(h, v) -> None:  # type: ignore[no-untyped-def]
    """Hash ``v`` (arrays with their dtype and shape, bytes, dataclasses field by field,
    sequences item by item, other values by repr) into ``h``."""
    if isinstance(v, np.ndarray):
        h.update(f"{v.dtype.str}{v.shape}".encode())
        h.update(np.ascontiguousarray(v).tobytes())
    elif isinstance(v, (bytes, bytearray, memoryview)):
        h.update(bytes(v))
    elif dataclasses.is_dataclass(v) and not isinstance(v, type):
        for f in dataclasses.fields(v):
            h.update(f.name.encode())
            _feed(h, getattr(v, f.name))
    elif isinstance(v, (list, tuple)):
        for x in v:
            _feed(h, x)
    elif isinstance(v, dict):
        for k in sorted(v, key=str):
            h.update(str(k).encode())
            _feed(h, v[k])
    else:
        h.update(repr(v).encode())


def decoded_digests(out) -> dict[str, str]:  # type: ignore[no-untyped-def]
    """SHA-256 of a decoded Motion's outputs: ``positions`` (float64 bytes, NaN at the
    gaps), and when present ``c3d`` (the archive: header, parameters, point words,
    models, analog samples) and ``skeleton`` (the skeleton and its channel values)."""
    d = {"positions": hashlib.sha256(
        np.ascontiguousarray(out.positions, dtype=np.float64).tobytes()).hexdigest()}
    extras = getattr(out, "extras", None) or {}
    if extras.get("c3d") is not None:
        h = hashlib.sha256()
        _feed(h, extras["c3d"])
        d["c3d"] = h.hexdigest()
    if extras.get("skeleton") is not None:
        h = hashlib.sha256()
        _feed(h, extras["skeleton"])
        if getattr(out, "angles", None) is not None:
            _feed(h, np.asarray(out.angles, dtype=np.float64))
        d["skeleton"] = h.hexdigest()
    return d


def measure(files: list[str], bound: str, out: Path, inputs: Path | None = None,
            save: Path | None = None) -> None:
    from bench_speed import HAS_THREADS, bound_kwargs, files_of, timed
    import mpz
    import mpz.io
    root = shared_data_dir()
    assert root is not None
    paths = files_of(root, files)
    warm_up(paths[0])                                           # JIT warm-up, not timed
    rows = {}
    saved = _saved_inputs(inputs, bound) if inputs is not None else None
    if save is not None:
        try:
            save.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise SystemExit(f"bench_decode.py: --save-inputs {save}: cannot make the "
                             f"folder ({exc.strerror or exc})") from None
    listed: dict[str, str] = {}
    if save is not None:                 # files saved before at this bound stay listed
        try:
            saved_at, before = _inputs_list(save)
            listed = before if saved_at == bound else {}
        except (OSError, ValueError):
            pass
    for path in paths:
        m = mpz.io.read(path)
        kw, _, desc = bound_kwargs(m, bound)
        if inputs is not None:             # another version's bytes: the decoders alone
            assert saved is not None
            given = inputs / f"{path.name}.mpz"
            try:
                data = given.read_bytes()
            except OSError as exc:
                raise SystemExit(f"bench_decode.py: --inputs: cannot read {given} "
                                 f"({exc.strerror or exc}); write it with --save-inputs "
                                 f"{inputs} and the same --files and --bound") from None
            # the bytes saved for this file, as saved (a review of stop 56: a file copied
            # under another name was timed as that file)
            if saved.get(path.name) != hashlib.sha256(data).hexdigest():
                said = "does not list it" if path.name not in saved else "says otherwise"
                raise SystemExit(f"bench_decode.py: --inputs: {given} is not what "
                                 f"--save-inputs wrote for {path.name} ({INPUTS_LIST} "
                                 f"{said})")
        else:
            data = mpz.encode(m, **({"threads": 1} if HAS_THREADS else {}), **kw)
        if save is not None:
            (save / f"{path.name}.mpz").write_bytes(data)
            listed[path.name] = hashlib.sha256(data).hexdigest()
            (save / INPUTS_LIST).write_text(json.dumps({"bound": bound, "files": listed},
                                                       indent=1))
        mb = len(coded_float32(m)) / 1e6
        sec, _ = timed(lambda data=data: mpz.decode(data), 5)
        rows[path.name] = {"mb": mb, "sec": sec, "bound": desc,
                           "mpz_sha256": hashlib.sha256(data).hexdigest(),
                           "decoded": decoded_digests(mpz.decode(data))}
        print(f"{path.name:<42} {mb:>6.3f} MB {sec * 1e3:>8.2f} ms {mb / sec:>7.1f} MB/s",
              flush=True)
    out.write_text(json.dumps({"bench": "decode", "schema": SCHEMA, "mpz": mpz.__file__,
                               "bound": bound, "rows": rows,
                               "inputs": None if inputs is None else str(inputs)}, indent=1))


#: what --save-inputs writes beside the files: the bound they were encoded at, and each
#: file's SHA-256
INPUTS_LIST = "inputs.json"


def _inputs_list(folder: Path) -> tuple[str, dict[str, str]]:
    """The bound and the files (name -> SHA-256) that --save-inputs listed in ``folder``;
    ValueError (or OSError) when there is no such list."""
    doc = json.loads((folder / INPUTS_LIST).read_text())
    if not (isinstance(doc, dict) and isinstance(doc.get("bound"), str)
            and isinstance(doc.get("files"), dict)):
        raise ValueError("not a list of saved inputs")
    return doc["bound"], dict(doc["files"])


def _saved_inputs(folder: Path, bound: str) -> dict[str, str]:
    """The files a --save-inputs run wrote into ``folder``, name -> SHA-256; SystemExit
    when there is no such list or it was saved at another bound (a review of stop 56: a
    --bound 5mm run decoded the 1 mm bytes, and its compare with a 5 mm run made up a
    decoder regression)."""
    try:
        saved_at, files = _inputs_list(folder)
    except (OSError, ValueError) as exc:
        raise SystemExit(f"bench_decode.py: --inputs {folder}: no list of saved inputs "
                         f"({folder / INPUTS_LIST}: {exc}); make it with --save-inputs "
                         f"{folder}") from None
    if saved_at != bound:
        raise SystemExit(f"bench_decode.py: --inputs {folder}: saved at --bound {saved_at}, "
                         f"not {bound}: give --bound {saved_at}")
    return files


def load(path: Path) -> dict[str, dict]:
    """The rows of a bench_decode.py result; SystemExit with the reason for anything
    else (another bench's JSON, an older format, malformed rows)."""
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise Unreadable(f"{path}: cannot read it as JSON: {exc}") from None
    if not isinstance(doc, dict) or doc.get("bench") != "decode" or doc.get("schema") != SCHEMA:
        what = doc.get("bench") if isinstance(doc, dict) else None
        raise Unreadable(f"{path}: not a bench_decode.py result of schema {SCHEMA}"
                         + (f" (it is bench {what!r})" if isinstance(what, str) else ""))
    rows = doc.get("rows")
    ok = isinstance(rows, dict) and all(
        isinstance(r, dict) and isinstance(r.get("mb"), (int, float))
        and isinstance(r.get("sec"), (int, float)) and r["sec"] > 0
        and isinstance(r.get("decoded"), dict) for r in rows.values())
    if not ok:
        raise Unreadable(f"{path}: malformed rows (each wants mb, sec > 0 and decoded)")
    return rows


def _side(paths: list[Path]) -> dict[str, dict]:
    """Each file of a side's runs: mb, its best time over the runs, the digests; the runs
    must agree on what the decode gave back."""
    runs = [load(p) for p in paths]
    side: dict[str, dict] = {}
    for run, p in zip(runs, paths, strict=True):
        for k, r in run.items():
            if k not in side:
                side[k] = {"mb": r["mb"], "sec": r["sec"], "decoded": r["decoded"],
                           "mpz_sha256": r.get("mpz_sha256")}
                continue
            if r["decoded"] != side[k]["decoded"]:
                raise Unreadable(f"{k}: two runs of the same side decoded differently ({p})")
            side[k]["sec"] = min(side[k]["sec"], r["sec"])
    return side


def compare(before: list[Path], after: list[Path]) -> int:
    """Print the table and the verdict; 1 when a file got slower beyond :data:`SLOWER`,
    decoded differently or is on one side only, or the sides share no file; else 0."""
    b, a = _side(before), _side(after)
    names = sorted(set(b) & set(a), key=lambda k: b[k]["mb"])
    problems: list[str] = []
    for k in sorted(set(b) - set(a)):
        problems.append(f"{k}: only in the before runs")
    for k in sorted(set(a) - set(b)):
        problems.append(f"{k}: only in the after runs")
    if not names:
        print("no file in both run sets: nothing to compare")
        for p in problems:
            print(f"FAIL {p}")
        return 1
    print(f"{'file':<42} {'MB':>6} {'ms before':>10} {'after':>8} {'MB/s before':>12} "
          f"{'after':>7} {'change':>7}")
    for k in names:
        mb, tb, ta = b[k]["mb"], b[k]["sec"], a[k]["sec"]
        print(f"{k:<42} {mb:>6.3f} {tb * 1e3:>10.2f} {ta * 1e3:>8.2f} {mb / tb:>12.1f} "
              f"{mb / ta:>7.1f} {100 * (ta / tb - 1):>+6.1f}%")
        if ta > (1 + SLOWER) * tb:
            problems.append(f"{k}: decodes slower, {tb * 1e3:.2f} -> {ta * 1e3:.2f} ms "
                            f"({100 * (ta / tb - 1):+.0f} %, tolerance {100 * SLOWER:.0f} %)")
        if b[k]["decoded"] != a[k]["decoded"]:
            parts = sorted(p for p in set(b[k]["decoded"]) | set(a[k]["decoded"])
                           if b[k]["decoded"].get(p) != a[k]["decoded"].get(p))
            same_input = (b[k]["mpz_sha256"] is not None
                          and b[k]["mpz_sha256"] == a[k]["mpz_sha256"])
            problems.append(f"{k}: decoded output differs ({', '.join(parts)}); "
                            + ("the encoded bytes are the same: the decoder changed"
                               if same_input else "the encoded bytes differ too"))
    n = len(names)
    same = sum(b[k]["mpz_sha256"] is not None and b[k]["mpz_sha256"] == a[k]["mpz_sha256"]
               for k in names)
    # whether the table measures the decoders alone: with other encoded bytes, a change of
    # the encoder moves the times too (--save-inputs / --inputs give both the same bytes)
    print(f"encoded bytes the same on both sides for {same} of {n} files"
          + ("" if same == n else ": those rows time each version's own encoder output "
             "too (--save-inputs DIR on one side, --inputs DIR on the other decode the "
             "same bytes)"))
    for label, t in (("before", b), ("after", a)):
        geo = math.exp(sum(math.log(t[k]["mb"] / t[k]["sec"]) for k in names) / n)
        tot = sum(t[k]["mb"] for k in names) / sum(t[k]["sec"] for k in names)
        slow = [k for k in names if t[k]["mb"] / t[k]["sec"] < 20]
        print(f"{label}: geometric mean {geo:.1f} MB/s; together {tot:.1f} MB/s; "
              f"{len(slow)} of {n} rows below 20 MB/s" + (f" ({', '.join(slow)})" if slow else ""))
    if not problems:
        print(f"verdict: PASS: {n} files, none slower by more than {100 * SLOWER:.0f} %, "
              "every decoded output identical")
        return 0
    for p in problems:
        print(f"FAIL {p}")
    print(f"verdict: FAIL ({len(problems)})")
    return 1


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--files", nargs="+", default=["all"])
    ap.add_argument("--bound", default="1mm",
                    help="default, or a length in mm such as 1mm (default 1mm)")
    ap.add_argument("--save-inputs", type=Path, metavar="DIR",
                    help="also write each encoded file to DIR/NAME.mpz")
    ap.add_argument("--inputs", type=Path, metavar="DIR",
                    help="decode DIR/NAME.mpz (from --save-inputs) instead of encoding each "
                    "file with this version: both versions then decode the same bytes, and "
                    "a change of the encoder does not move the figures")
    args = two_versions(ap, argv)
    if args.compare:
        return compare_main(lambda: compare(args.compare, args.against))
    if not is_bound_label(args.bound):
        ap.error(f"--bound wants default or a length in mm such as 1mm, got {args.bound!r}")
    reason = no_data_reason()
    if reason:
        print(f"skipped: {reason}")
        return 0
    if args.inputs is not None and args.save_inputs is not None:
        ap.error("--inputs and --save-inputs: give one (the first run saves, the others "
                 "decode what it saved)")
    measure(args.files, args.bound, args.json, args.inputs, args.save_inputs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
