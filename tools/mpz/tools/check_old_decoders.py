"""Decode today's files with the decoders of earlier revisions:
``python -m mpz.tools.check_old_decoders``.

Spec §2.1: a 1.0 decoder keeps decoding the markers of every 1.x file, because later
minor versions only add ancillary chunk types that it skips (§2.3). The test suite
checks this by running today's decoder with the 1.1 chunk types removed from its table
(``mpz.decode(markers_only=True)``); this tool runs the *actual* decoders of earlier
revisions, taken from the repository's history, on what today's encoder writes.

1. Each revision (``--rev``, default :data:`REVISIONS`) is taken out of git with ``git
   archive`` into a work folder, and its ``mpz`` package is assembled there from its
   ``pyproject.toml``'s ``package-dir`` (the layout changed between revisions; no pip,
   so a revision whose package list missed a subpackage still runs).
2. Today's encoder (``mpz encode``, in a subprocess, one batch per option set of
   :data:`OPTION_SETS`) encodes every recording of the data folder (``--data``, default
   ``$MPZ_SHARED_DATA``), plus synthetic inputs for what it lacks
   (:func:`synthetic_inputs`). With ``--vectors``, the conformance vectors are checked
   too, each against today's reading of it as the old decoder's minor version reads it.
3. Each old decoder runs in its own process (:mod:`mpz.tools._old_decoder_driver`, with
   the old package alone on the import path; any ``mpz`` module loaded from elsewhere is
   reported) and decodes every file with its ``mpz.decode``, then runs its ``mpzinfo -v``.
4. Its marker layer is compared with today's ``mpz.decode(markers_only=True)`` bit for
   bit (:func:`compare_layers`: positions, gaps, names, rate, units, meta), and today's
   full decode is held to the same marker layer.

A file passes when the old decoder returns the same marker layer and its ``mpzinfo``
neither fails nor warns of anything but the chunk types it does not know. An old decoder
that refuses, crashes on or decodes differently a file that today's 1.0 reading decodes
fails the check (exit 1). Run it before a release (docs/versioning.md); the first run of
each revision compiles its numba kernels (tens of seconds).
"""
from __future__ import annotations

import argparse
from dataclasses import dataclass, field
import io
import json
import math
import os
from pathlib import Path
import re
import shlex
import shutil
import subprocess
import sys
import tarfile
import tempfile
import time
import tomllib
from typing import Any

import numpy as np

from mpz.tools._cli import EXIT_ERROR, EXIT_OK, EXIT_WARN, Parser, printable

#: the revisions checked by default, oldest first: (commit, label, why this one)
REVISIONS: tuple[tuple[str, str, str], ...] = (
    ("8b20bb6", "0.1.0", "the 0.1.0 release of 2026-11-23: the first MPZ 1.0 decoder "
     "(spec 1.0, CHANGELOG.md)"),
    ("1c3163d", "1.0.1", "spec 1.0.1 (Appendix B): the text revision of 2026-12-01, "
     "the chunk table and the located range errors"),
    ("9d2a616", "1.0-last", "the last commit whose bitstream is 1.0 alone: the next, "
     "76a7bb1, adds the first 1.1 chunk types (chdr, cprm, cpnt, cana)"),
    ("7104913", "1.1-2026-12-02", "MPZ 1.1 as Appendix B dates it (the last commit of "
     "2026-12-02), after 1.1's last change of a chunk layout (c4dbff3, chdr and cprm "
     "coding)"),
)

#: the ancillary chunk types of 1.0 (§2.3): every revision knows them, and its mpzinfo may
#: say that it skipped an unknown ancillary chunk of any other type (a 1.1 type, or the
#: made-up type of a conformance vector), never of these
OWN_1_0 = ("smry", "meta")

#: a draft of 1.1 that today's files are not for: from the first 1.1 chunk types (76a7bb1)
#: to the change of chdr's and cprm's layout in place (c4dbff3; Appendix B: "1.1 had not
#: been released"), a decoder refuses today's C3D archive chunks (checked: 61500d2)
DRAFT_1_1 = ("76a7bb1", "c4dbff3")


@dataclass(frozen=True)
class OptionSet:
    """One way of encoding: the ``mpz encode`` options, and which inputs take them."""

    name: str
    args: tuple[str, ...]
    #: "all", or "skeletal" (BVH and AMC only)
    inputs: str = "all"
    why: str = ""


#: ``--units cm`` names the unit of a BVH (it has none) and leaves the others alone
OPTION_SETS: tuple[OptionSet, ...] = (
    OptionSet("default", (), why="the default bound; a C3D archive, a skeleton"),
    OptionSet("1mm", ("--max-error", "1mm", "--units", "cm"), why="--max-error 1mm"),
    OptionSet("1mm-smrc", ("--max-error", "1mm", "--units", "cm", "--summary", "6,12,24,48",
                           "--meta", "subject=Zoë check_old_decoders"),
              why="1.1's coded summary (smrc) and a meta key (UTF-8)"),
    OptionSet("1mm-smry", ("--max-error", "1mm", "--units", "cm", "--summary", "6,12,24,48",
                           "--summary-format", "smry"), why="1.0's raw summary (smry)"),
    OptionSet("lossy", ("--lossy",), why="the paper's mode: patterns, hierarchy, no residual"),
    OptionSet("1mm-patterns", ("--max-error", "1mm", "--units", "cm", "--patterns", "on"),
              why="patterns under a bound: PATT, SEGS and RESI over a hierarchy"),
    OptionSet("no-skeleton", ("--no-skeleton",), "skeletal", why="a BVH or AMC as 1.0"),
    OptionSet("angles-summary", ("--summary", "6,12", "--summary-space", "angles"),
              "skeletal", why="an smrc of joint angles beside the skeleton"),
)

#: the ``--json`` file's schema (docs/versioning.md "The --json file")
JSON_SCHEMA = "mpz-check-old-decoders/1"

SKELETAL_SUFFIXES = (".bvh", ".amc")
MOTION_SUFFIXES = (".c3d", ".trc", ".bvh", ".amc")


# ------------------------------------------------------------- comparison --
@dataclass
class MarkerLayer:
    """What a 1.0 decoder returns of a file: the marker layer and its header."""

    positions: np.ndarray          # float64 [frames, markers, 3], NaN at gaps
    names: list[str]
    rate: float
    units: str
    metadata: dict[str, str] = field(default_factory=dict)


def layer_of(motion: Any) -> MarkerLayer:
    """The :class:`MarkerLayer` of a decoded :class:`mpz.Motion`."""
    pos = np.array(motion.positions, dtype=np.float64, copy=True)
    pos[~np.asarray(motion.valid, dtype=bool)] = np.nan
    return MarkerLayer(pos, [str(n) for n in motion.names], float(motion.rate),
                       str(motion.units), {str(k): str(v) for k, v in motion.metadata.items()})


def compare_layers(expected: MarkerLayer, got: MarkerLayer, *, meta: bool = True) -> list[str]:
    """How ``got`` differs from ``expected``, one line per difference (empty: identical).

    Positions are compared bit for bit, as their binary64 patterns, wherever either has
    a value; a gap is a NaN of any payload (spec §6.8), and a NaN where the other has a
    value is a difference. The rate is compared as its bits (``float.hex``), so 65.0364
    and its float32 are different rates; names and meta as exact strings."""
    out: list[str] = []
    a = np.asarray(expected.positions, dtype=np.float64)
    b = np.asarray(got.positions, dtype=np.float64)
    if a.shape != b.shape:
        out.append(f"shape {b.shape} instead of {a.shape}")
    else:
        gap_a, gap_b = np.isnan(a), np.isnan(b)
        moved = gap_a != gap_b
        if moved.any():
            f, m, _ = np.argwhere(moved)[0]
            out.append(f"{int(moved.sum())} coordinate(s) are a gap in one and not the other "
                       f"(first: frame {f}, marker {m}: {b[f, m].tolist()} instead of "
                       f"{a[f, m].tolist()})")
        both = ~gap_a & ~gap_b
        bits_differ = both & (a.view(np.uint64) != b.view(np.uint64))
        if bits_differ.any():
            f, m, _ = np.argwhere(bits_differ)[0]
            worst = float(np.max(np.abs(a[bits_differ] - b[bits_differ])))
            out.append(f"{int(bits_differ.sum())} coordinate(s) differ, by up to {worst!r} "
                       f"(first: frame {f}, marker {m}: {b[f, m].tolist()} instead of "
                       f"{a[f, m].tolist()})")
    if list(got.names) != list(expected.names):
        pairs = zip(expected.names, got.names, strict=False)
        diff = [i for i, (x, y) in enumerate(pairs) if x != y]
        where = (f"first at marker {diff[0]}: {got.names[diff[0]]!r} instead of "
                 f"{expected.names[diff[0]]!r}" if diff else
                 f"{len(got.names)} names instead of {len(expected.names)}")
        out.append(f"names differ ({where})")
    if float(got.rate).hex() != float(expected.rate).hex() and not (
            math.isnan(got.rate) and math.isnan(expected.rate)):
        out.append(f"rate {got.rate!r} instead of {expected.rate!r}")
    if got.units != expected.units:
        out.append(f"units {got.units!r} instead of {expected.units!r}")
    if meta and dict(got.metadata) != dict(expected.metadata):
        keys = sorted(set(got.metadata) | set(expected.metadata))
        bad = [k for k in keys if got.metadata.get(k) != expected.metadata.get(k)]
        out.append(f"meta differs at {', '.join(repr(k) for k in bad[:5])}"
                   f"{' ...' if len(bad) > 5 else ''}")
    return out


_UNKNOWN_WARNING = re.compile(r"warning: unknown ancillary chunk '([a-z][A-Za-z]{3})' skipped")


def mpzinfo_problem(status: int | None, stdout: str, stderr: str) -> str | None:
    """What is wrong with an old ``mpzinfo -v`` run on a valid file (None: nothing).

    Exit 0 passes. Exit 1 (warnings) passes when its only warnings are that it skipped
    unknown ancillary chunks (§2.3: 1.1's types, to a 1.0 decoder), none of a type of
    :data:`OWN_1_0`; any other status or warning is a problem."""
    if status == 0:
        return None
    if status == 1:
        text = stdout + "\n" + stderr
        warnings = [line.strip() for line in text.splitlines() if "warning" in line.lower()
                    and not line.lstrip().startswith("WARN:")]
        others = [w for w in warnings
                  if not ((m := _UNKNOWN_WARNING.search(w)) and m.group(1) not in OWN_1_0)]
        if warnings and not others:
            return None
        return f"exit 1: {others[0] if others else 'no warning named'}"
    tail = (stderr.strip() or stdout.strip()).splitlines()[-1:] or ["(no message)"]
    return f"exit {status}: {tail[0][:300]}"


# --------------------------------------------------------------- revisions --
def build_site(repo: Path, rev: str, dest: Path) -> Path:
    """The old revision's ``mpz`` package, assembled in ``dest/site`` from ``git archive``
    and its own ``pyproject.toml``'s ``package-dir``; returns the site folder."""
    tree, site = dest / "tree", dest / "site"
    if (site / "mpz" / "__init__.py").is_file():
        return site
    shutil.rmtree(dest, ignore_errors=True)
    tree.mkdir(parents=True)
    raw = subprocess.run(["git", "-C", str(repo), "archive", "--format=tar", rev],
                         check=True, capture_output=True).stdout
    with tarfile.open(fileobj=io.BytesIO(raw)) as tar:
        tar.extractall(tree, filter="data")
    mapping = package_dirs(tree)
    for package, folder in sorted(mapping.items(), key=lambda kv: kv[0].count(".")):
        shutil.copytree(tree / folder, site / package.replace(".", "/"), dirs_exist_ok=True)
    if not (site / "mpz" / "__init__.py").is_file():
        raise RuntimeError(f"{rev}: no mpz package in its tree (package-dir {mapping})")
    return site


def package_dirs(tree: Path) -> dict[str, str]:
    """The ``[tool.setuptools] package-dir`` of the tree's pyproject.toml, or the mpz/
    folder at its top when it has none."""
    project = tomllib.loads((tree / "pyproject.toml").read_text("utf-8"))
    mapping = project.get("tool", {}).get("setuptools", {}).get("package-dir", {})
    if mapping:
        return {str(k): str(v) for k, v in mapping.items() if str(k).split(".")[0] == "mpz"}
    return {"mpz": "mpz"}


def is_ancestor(repo: Path, older: str, newer: str) -> bool:
    """True when ``older`` is ``newer`` or one of its ancestors."""
    return subprocess.run(["git", "-C", str(repo), "merge-base", "--is-ancestor", older, newer],
                          capture_output=True).returncode == 0


def is_draft_1_1(repo: Path, commit: str) -> bool:
    """True for a revision of :data:`DRAFT_1_1`, whose decoder is expected to refuse
    today's C3D archive chunks."""
    first, settled = DRAFT_1_1
    return is_ancestor(repo, first, commit) and not is_ancestor(repo, settled, commit)


class UnknownRevision(Exception):
    """A --rev that names no commit of the repository (git's own message alone, "fatal:
    Needed a single revision", did not say which: a maintainer's QA run, stop 73)."""


def resolve(repo: Path, rev: str) -> str:
    p = subprocess.run(["git", "-C", str(repo), "rev-parse", "--verify", "--quiet",
                        f"{rev}^{{commit}}"], capture_output=True, text=True)
    if p.returncode != 0:
        raise UnknownRevision(f"--rev {rev}: no commit of {repo} has that name"
                              + (f" (git: {p.stderr.strip()})" if p.stderr.strip() else ""))
    return p.stdout.strip()


# ------------------------------------------------------------------- cases --
@dataclass
class Case:
    name: str
    path: Path
    source: str
    options: str


def inputs_of(data: Path) -> list[Path]:
    return sorted(p for p in data.rglob("*") if p.suffix.lower() in MOTION_SUFFIXES
                  and p.is_file())


def encode_cases(data_dirs: list[Path], work: Path, sets: tuple[OptionSet, ...],
                 python: str) -> tuple[list[Case], list[str]]:
    """Today's ``mpz encode`` of every input of ``data_dirs`` with every option set (one
    batch per set and folder of inputs, in a subprocess); returns the cases and what
    failed to encode."""
    cases: list[Case] = []
    failures: list[str] = []
    for s in sets:
        for k, data in enumerate(data_dirs):
            inputs = [p for p in inputs_of(data)
                      if s.inputs == "all" or p.suffix.lower() in SKELETAL_SUFFIXES]
            for folder in sorted({p.parent for p in inputs}):
                batch = [p for p in inputs if p.parent == folder]
                out = work / "encoded" / s.name / str(k) / folder.relative_to(data)
                shutil.rmtree(out, ignore_errors=True)   # no output of an earlier checkout
                run = subprocess.run(
                    [python, "-m", "mpz.tools.mpz_cli", "encode", "-q", "-j", "0", "-o",
                     f"{out}{os.sep}", *map(str, batch), *s.args],
                    capture_output=True, text=True)
                if run.returncode not in (EXIT_OK, EXIT_WARN):
                    failures.append(f"{s.name}: mpz encode {folder} exit {run.returncode}: "
                                    f"{run.stderr.strip()[-500:]}")
                for p in batch:
                    rel = p.relative_to(data)
                    label = f"{data.name}/{rel}"
                    got = out / f"{p.stem}.mpz"
                    if not got.is_file():
                        failures.append(f"{s.name}: {label}: no output")
                        continue
                    safe = re.sub(r"[^A-Za-z0-9_.-]", "_",
                                  f"{s.name}__{k}__{rel.with_suffix('')}")
                    cases.append(Case(safe, got, label, s.name))
    return cases, failures


def synthetic_inputs(work: Path) -> Path:
    """Synthetic inputs for what the recordings lack: the quick start's walk as C3D and
    TRC (mpz.tools.make_example), a walk in metres (units code 3), and one of 20,000
    frames, longer than the decoder's blocks of frames (``mpz.decoder.BLOCK_SAMPLES``)
    and than one block of the summary's partition (16,384 frames)."""
    import mpz
    from mpz.io import write
    from mpz.tools.make_example import make
    folder = work / "synthetic"
    walk = make()
    metres = mpz.Motion(walk.positions / 1000.0, list(walk.names), walk.rate, "m",
                        valid=walk.valid)
    # one folder each: an output name per folder
    for name, motion in (("c3d/walk.c3d", walk), ("trc/walk.trc", walk),
                         ("metres/walk-m.trc", metres), ("long/walk-long.c3d", None)):
        if not (folder / name).exists():
            (folder / name).parent.mkdir(parents=True, exist_ok=True)
            write(motion if motion is not None else make(frames=20_000, seed=1),
                  folder / name)
    return folder


def vector_cases(vectors: Path) -> list[Case]:
    """The conformance vectors (every group), as cases."""
    man = json.loads((vectors / "manifest.json").read_text("utf-8"))
    return [Case(re.sub(r"[^A-Za-z0-9_.-]", "_", f"vector__{v['name']}"), vectors / v["file"],
                 f"vector {v['name']} ({v['group']}, {v['expected']})", "vector")
            for v in man["vectors"]]


# ---------------------------------------------------------------- checking --
@dataclass
class Reading:
    """Today's decode of a file, read as one minor version reads it."""

    layer: MarkerLayer | None          # None: rejected
    error: str | None = None


@dataclass
class Expected:
    """What today's decoder makes of a file: as a 1.0 decoder (``markers_only``) and as
    a 1.1 one, and where the two disagree on a file that should decode alike."""

    as_1_0: Reading
    as_1_1: Reading
    problems: list[str] = field(default_factory=list)

    def for_minor(self, minor: int) -> Reading:
        return self.as_1_0 if minor == 0 else self.as_1_1


def _reading(data: bytes, markers_only: bool) -> Reading:
    import mpz
    from mpz.errors import MPZError
    try:
        return Reading(layer_of(mpz.decode(data, markers_only=markers_only)))
    except MPZError as exc:
        return Reading(None, f"{type(exc).__name__}: {exc}")


def expected_of(path: Path, *, valid: bool = True) -> Expected:
    """Today's two readings of the file; for a ``valid`` one (every file today's encoder
    writes) both must decode it, to the same marker layer (spec §2.1)."""
    data = path.read_bytes()
    exp = Expected(_reading(data, True), _reading(data, False))
    if valid:
        for r, how in ((exp.as_1_0, "as 1.0"), (exp.as_1_1, "as 1.1")):
            if r.layer is None:
                exp.problems.append(f"today's decoder rejects it {how}: {r.error}")
        if exp.as_1_0.layer is not None and exp.as_1_1.layer is not None:
            exp.problems += [f"today's full decode: {d}"
                             for d in compare_layers(exp.as_1_0.layer, exp.as_1_1.layer)]
    return exp


def run_driver(site: Path, cases: list[Case], out: Path, python: str, cache: Path,
               timeout: float) -> tuple[list[dict[str, Any]], dict[str, Any], list[str]]:
    """Run the old decoder of ``site`` on ``cases`` (one process); returns its rows, its
    header and the mpz modules it loaded from elsewhere."""
    out.mkdir(parents=True, exist_ok=True)
    listing = out / "cases.json"
    listing.write_text(json.dumps([{"name": c.name, "path": str(c.path)} for c in cases]),
                       "utf-8")
    driver = Path(__file__).with_name("_old_decoder_driver.py")
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    env.update(NUMBA_CACHE_DIR=str(cache), MPZ_CACHE_DIR=str(cache))
    try:
        run = subprocess.run([python, "-I", str(driver), str(site), str(listing), str(out)],
                             env=env, capture_output=True, text=True, timeout=timeout)
        status, said = run.returncode, run.stderr
    except subprocess.TimeoutExpired:
        status, said = None, f"still running after {timeout:g} s (--timeout), stopped"
    rows: list[dict[str, Any]] = []
    head: dict[str, Any] = {}
    foreign: list[str] = []
    results = out / "results.jsonl"
    if results.exists():
        for line in results.read_text("utf-8").splitlines():
            doc = json.loads(line)
            if "driver" in doc:
                head = doc["driver"]
            elif "foreign_modules" in doc:
                foreign = doc["foreign_modules"]
            else:
                rows.append(doc)
    if status != 0:
        head["failed"] = f"driver exit {status}: {said.strip()[-2000:]}"
    return rows, head, foreign


def verdict(exp: Reading, row: dict[str, Any] | None, out: Path) -> tuple[str, str]:
    """("pass" | "fail" | "note", why) for one old decoder's ``row`` on one file, against
    today's reading of it as the old decoder's minor version reads it (``exp``)."""
    if row is None:
        return "fail", "the old decoder's process ended before this file"
    info = row.get("mpzinfo", {})
    if not row.get("decoded"):
        err = row.get("error", {})
        said = f"{err.get('type')}: {err.get('message')}"
        if not err.get("mpz_error"):
            return "fail", f"crashed: {said}"
        if exp.layer is None:
            return "pass", f"rejected, as today's decoder does ({said})"
        return "fail", f"refused: {said}"
    if exp.layer is None:
        return "note", f"decoded a file today's decoder rejects ({exp.error})"
    got = MarkerLayer(np.load(out / f"{row['name']}.npy", allow_pickle=False), row["names"],
                      float.fromhex(row["rate"]), row["units"], row["metadata"])
    diffs = compare_layers(exp.layer, got)
    if diffs:
        return "fail", "decoded differently: " + "; ".join(diffs)
    if "absent" in info:
        return "pass", f"same marker layer (no mpzinfo at this revision: {info['absent']})"
    problem = mpzinfo_problem(info.get("status"), info.get("stdout_tail", ""),
                              info.get("stderr_tail", ""))
    if problem:
        return "fail", f"mpzinfo -v: {problem}"
    return "pass", "same marker layer"


def default_data() -> Path | None:
    env = os.environ.get("MPZ_SHARED_DATA")
    if env:
        return Path(env)
    beside = Path(__file__).resolve().parents[3].parent / "shared" / "data"
    return beside if beside.is_dir() else None


def main(argv: list[str] | None = None) -> int:
    p = Parser(prog="python -m mpz.tools.check_old_decoders",
               description=__doc__.split("\n\n")[0] if __doc__ else None,
               formatter_class=argparse.RawDescriptionHelpFormatter,
               epilog="exit codes: 0 every file passed (notes allowed), 1 a file failed or "
                      "an input did not encode, 2 no recordings or an unknown revision, "
                      "64 usage error; docs/versioning.md")
    p.add_argument("--rev", action="append", metavar="REV",
                   help="a revision to check (repeatable; default: "
                        + ", ".join(f"{r} ({label})" for r, label, _ in REVISIONS) + ")")
    p.add_argument("--repo", default=str(Path(__file__).resolve().parents[3]),
                   help="the git repository the revisions come from (default: this checkout)")
    p.add_argument("--data", action="append", metavar="DIR",
                   help="a folder of recordings (repeatable; default $MPZ_SHARED_DATA, else "
                        "../shared/data beside the checkout)")
    p.add_argument("--options", action="append", metavar="NAME",
                   choices=[s.name for s in OPTION_SETS],
                   help="an option set (repeatable; default all: "
                        + ", ".join(s.name for s in OPTION_SETS) + ")")
    p.add_argument("--encode-options", action="append", metavar="ARGS",
                   help="one more option set, as mpz encode options in one word, e.g. "
                        "--encode-options='--lossy --smoothing 16' (repeatable; with it or "
                        "--options, only the sets named are run)")
    p.add_argument("--no-synthetic", action="store_true",
                   help="leave out the synthetic inputs (the quick start's walk as C3D and "
                        "TRC, a walk in metres, a walk of 20,000 frames)")
    p.add_argument("--vectors", action="store_true",
                   help="also decode every conformance vector with each old decoder")
    p.add_argument("--work", help="work folder (kept; default: a temporary one, removed)")
    p.add_argument("--python", default=sys.executable,
                   help="the interpreter for the encoder and the old decoders (default: this "
                        "one; numpy, scipy, numba, construct and ezc3d must import)")
    p.add_argument("--timeout", type=float, default=3600.0,
                   help="seconds one old decoder may take for all files (default 3600)")
    p.add_argument("--json", metavar="FILE", help="write every verdict to FILE as JSON")
    args = p.parse_args(argv)

    repo = Path(args.repo)
    known = {r: (label, why) for r, label, why in REVISIONS}
    revs = [(r, *known.get(r, (r, "given"))) for r in args.rev] if args.rev else list(REVISIONS)
    chosen = args.options or ([] if args.encode_options else [s.name for s in OPTION_SETS])
    sets = tuple(s for s in OPTION_SETS if s.name in chosen) + tuple(
        OptionSet(f"extra{i}", tuple(shlex.split(text)), why=text)
        for i, text in enumerate(args.encode_options or [], 1))
    data_dirs = [Path(d) for d in args.data] if args.data else (
        [d] if (d := default_data()) is not None else [])
    for d in data_dirs:
        if not d.is_dir():
            print(f"check_old_decoders: error: {printable(str(d))} is not a folder",
                  file=sys.stderr)
            return EXIT_ERROR
    temp = None if args.work else tempfile.TemporaryDirectory(prefix="mpz-old-decoders-")
    work = Path(args.work) if args.work else Path(temp.name)     # type: ignore[union-attr]
    work.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    try:
        return _check(repo, revs, sets, data_dirs, work, args, t0)
    finally:
        if temp is not None:
            temp.cleanup()


def _check(repo: Path, revs: list[tuple[str, str, str]], sets: tuple[OptionSet, ...],
           data_dirs: list[Path], work: Path, args: argparse.Namespace, t0: float) -> int:
    try:
        commits = [(resolve(repo, r), label, why) for r, label, why in revs]
    except UnknownRevision as exc:
        print(f"check_old_decoders: error: {printable(str(exc))}", file=sys.stderr)
        return EXIT_ERROR
    if not args.no_synthetic:
        data_dirs = [*data_dirs, synthetic_inputs(work)]
    if not data_dirs and not args.vectors:
        print("check_old_decoders: error: no recordings (set MPZ_SHARED_DATA or give --data)",
              file=sys.stderr)
        return EXIT_ERROR
    print(f"encoding {sum(len(inputs_of(d)) for d in data_dirs)} inputs with "
          f"{len(sets)} option sets (today's mpz encode) ...", flush=True)
    cases, failures = encode_cases(data_dirs, work, sets, args.python)
    if args.vectors:
        from mpz.conformance.manifest import DEFAULT_DIR
        cases += vector_cases(Path(DEFAULT_DIR))
    expected = {c.name: expected_of(c.path, valid=c.options != "vector") for c in cases}
    for c in cases:
        failures += [f"{c.options}: {c.source}: {p}" for p in expected[c.name].problems]
    print(f"{len(cases)} files, encoded and decoded by today's mpz in "
          f"{time.perf_counter() - t0:.0f} s", flush=True)
    # a schema, as every other file the tools write (a maintainer's QA run of stop 75:
    # none, and no document of its fields; docs/versioning.md "The --json file")
    report: dict[str, Any] = {"schema": JSON_SCHEMA, "revisions": [], "cases": len(cases),
                              "encode_failures": failures}
    worst = EXIT_OK if not failures else EXIT_WARN
    for commit, label, why in commits:
        t1 = time.perf_counter()
        site = build_site(repo, commit, work / "revs" / commit[:12])
        rows, head, foreign = run_driver(site, cases, work / "out" / commit[:12], args.python,
                                         work / "cache" / commit[:12], args.timeout)
        by_name = {r["name"]: r for r in rows}
        minor = int(head.get("bitstream", [1, 0])[1])
        verdicts = [(c, *verdict(expected[c.name].for_minor(minor), by_name.get(c.name),
                                 work / "out" / commit[:12])) for c in cases]
        counts = {k: sum(1 for _, v, _ in verdicts if v == k) for k in ("pass", "fail", "note")}
        problems = ([f"the old process: {head['failed']}"] if "failed" in head else []) + \
            [f"loaded from outside the revision: {m}" for m in foreign]
        seconds = time.perf_counter() - t1
        print(f"\n{commit[:12]} {label} (a 1.{minor} decoder): {counts['pass']} pass, "
              f"{counts['fail']} fail, {counts['note']} notes ({seconds:.0f} s; {why})")
        if is_draft_1_1(repo, commit):
            print(f"  (a draft of 1.1, between {DRAFT_1_1[0]} and {DRAFT_1_1[1]}: its chdr and "
                  "cprm are not today's, which changed in place before 1.1 was released "
                  "(spec Appendix B), so it refuses today's C3D archive chunks)")
        for text in problems:
            print(f"  ERROR {printable(text)}")
        for c, v, text in verdicts:
            if v != "pass":
                print(f"  {v.upper()} {c.options:14} {printable(c.source)}: {printable(text)}")
        if counts["fail"] or problems:
            worst = EXIT_WARN
        report["revisions"].append({
            "commit": commit, "label": label, "why": why, "seconds": round(seconds, 1),
            "counts": counts, "problems": problems, "driver": head,
            "verdicts": [{"case": c.name, "source": c.source, "options": c.options,
                          "verdict": v, "why": text} for c, v, text in verdicts]})
    for text in failures:
        print(f"ENCODE {printable(text)}")
    total = time.perf_counter() - t0
    report["seconds"] = round(total, 1)
    print(f"\n{'all passed' if worst == EXIT_OK else 'FAILURES'}: {len(cases)} files x "
          f"{len(commits)} revisions in {total:.0f} s")
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=1), "utf-8")
    return worst


if __name__ == "__main__":
    sys.exit(main())
