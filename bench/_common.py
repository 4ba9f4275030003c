"""Helpers shared by the benchmark scripts (not part of the mpz package)."""
from __future__ import annotations

import argparse
from collections.abc import Callable
import os
from pathlib import Path
import sys

# Nothing of the mpz package is imported here: bench_rd, bench_encode and bench_decode are
# run with an older version installed, to compare versions (README), and an import of a
# helper that version lacks failed for 515 of 593 revisions (a QA run of stop 50).

REPO = Path(__file__).resolve().parents[1]


def shared_data_dir() -> Path | None:
    """``$MPZ_SHARED_DATA`` or ``<repo>/../shared/data``, or None when absent.

    Real recordings are read in place from there and never copied into the repo.
    """
    env = os.environ.get("MPZ_SHARED_DATA")
    cand = Path(env) if env else REPO.parent / "shared" / "data"
    return cand if cand.is_dir() else None


#: the recordings the benches read
RECORDING_EXTS = (".c3d", ".trc", ".bvh", ".amc")


def shared_data_name() -> str:
    """How messages name the data folder: ``MPZ_SHARED_DATA=<value>`` when that is set,
    else ``../shared/data``."""
    env = os.environ.get("MPZ_SHARED_DATA")
    return f"MPZ_SHARED_DATA={env}" if env else "../shared/data"


def recordings(root: Path, folder: str = "") -> list[Path]:
    """Every recording (C3D, TRC, BVH, AMC) under ``root`` (or its ``folder``), sorted."""
    base = root / folder if folder else root
    return sorted(p for p in base.rglob("*") if p.suffix.lower() in RECORDING_EXTS
                  and p.is_file())


def find_recording(root: Path, name: str) -> Path | None:
    """The recording ``name`` names under ``root`` (``folder/stem``, ``stem``, with or
    without its extension), or None: the folder given first (amc/HDM_dg_... is the AMC),
    then a bare name anywhere below the root."""
    p = root / name
    if p.is_file() and p.suffix.lower() in RECORDING_EXTS:
        return p
    for ext in RECORDING_EXTS:
        if (root / (name + ext)).is_file():
            return root / (name + ext)
    base = Path(name).name
    # a bare name with its extension ("cmu_02_01.c3d") was looked for as
    # "cmu_02_01.c3d.c3d" (a maintainer's QA run of stop 55)
    for pattern in ([base] if Path(base).suffix.lower() in RECORDING_EXTS else []) + \
            [base + ext for ext in RECORDING_EXTS]:
        hits = sorted(p for p in root.rglob(pattern) if p.is_file())
        if hits:
            return hits[0]
    return None


#: millimetres per length unit, as mpz.format.MM_PER_UNIT: the fallback of
#: :func:`mm_per_unit` for an mpz without that module
_MM_PER_UNIT = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4}


def has_option(name: str) -> bool:
    """Whether the installed mpz's EncodeOptions has ``name``: the README runs these
    scripts with an old version too, and 0.1.0 has neither ``lossy`` nor ``threads``."""
    import dataclasses

    import mpz.encoder
    return name in {f.name for f in dataclasses.fields(mpz.encoder.EncodeOptions)}


def mm_per_unit(m) -> float | None:
    """Millimetres per unit of the motion ``m``'s positions (None: it has no unit): the
    unit's, else a skeleton's own (a BVH without one). The README runs these scripts with
    the old version installed too, and 0.1.0 has neither mpz.format nor mpz.skeleton (a
    maintainer's QA run of stop 75: every bench failed on its imports): the units table
    alone then, which a test holds equal to mpz.format's."""
    try:
        from mpz.format import MM_PER_UNIT
    except ImportError:
        MM_PER_UNIT = _MM_PER_UNIT
    try:
        from mpz.skeleton import mm_per_unit as of_skeleton
    except ImportError:
        return MM_PER_UNIT.get(m.units)
    return MM_PER_UNIT.get(m.units) or of_skeleton(m)


def whole_number(low: int) -> Callable[[str], int]:
    """argparse type of a whole number of ``low`` or more (as ``mpz.tools._cli``'s)."""
    def parse(text: str) -> int:
        try:
            n = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"wants a whole number, got {text!r}") from None
        if n < low:
            raise argparse.ArgumentTypeError(f"wants {low} or more, got {n}")
        return n
    return parse


#: argparse type of a whole number of 1 or more (``--repeat N``)
positive_int = whole_number(1)


class Unreadable(SystemExit):
    """A results file that cannot be compared (not JSON, another bench's, malformed rows,
    two runs of one side that disagree): exit 2 with the message, as ``mpz bench``; exit 1
    is a regression (a QA run of stop 50: both were 1). ``str()`` is the message."""

    def __init__(self, message: str) -> None:
        super().__init__(2)
        self.message = message

    def __str__(self) -> str:
        return self.message


def compare_main(run: Callable[[], int]) -> int:
    """``run()``, a bench's ``--compare``, with :class:`Unreadable` said on standard error
    as ``error: ...`` and exit 2."""
    import sys
    try:
        return run()
    except Unreadable as exc:
        print(f"error: {exc.message}", file=sys.stderr)
        return 2


def is_bound_label(text: str) -> bool:
    """A bound as the benches take it: ``default`` or a finite positive length in mm."""
    import math
    try:
        return text == "default" or (text.endswith("mm") and 0 < float(text[:-2]) < math.inf)
    except ValueError:
        return False


def no_data_reason(folder: str = "", exts: tuple[str, ...] = RECORDING_EXTS) -> str | None:
    """None when the data folder holds a recording (of ``exts``, under ``folder``), else
    why a bench that needs one is skipped (the folder named as :func:`shared_data_name`
    does): it is absent, or holds no such file."""
    root = shared_data_dir()
    where = shared_data_name()
    if root is None:
        return f"{where} is absent (set MPZ_SHARED_DATA to the recordings)"
    if not any(p.suffix.lower() in exts for p in recordings(root, folder)):
        what = "/".join(e.lstrip(".").upper() for e in exts)
        return f"no {what} recording under {where}" + (f"/{folder}" if folder else "")
    return None


def cannot_run(bench: str) -> int | None:
    """The exit status of a bench that needs the recordings and zstandard (the ``bench``
    extra) when it cannot run, having said why: 0 with "skipped: ..." when the data
    folder holds no recording, 1 when zstandard is missing; None when it can run."""
    reason = no_data_reason()
    if reason:
        print(f"skipped: {reason}")
        return 0
    try:
        import zstandard  # noqa: F401
    except ImportError:
        print(f"{bench}: zstandard is not installed; it is in the bench extra: "
              "pip install -e '.[bench]'", file=sys.stderr)
        return 1
    return None


def warm_up(path: Path) -> None:
    """Load the numba kernels (compile or read the cache) on the first 50 frames of the
    recording ``path``, so that no timed call pays for it: the first file a bench is
    given, not a fixed one that the data folder may lack."""
    import mpz
    import mpz.io
    m = mpz.io.read(path)
    mpz.decode(mpz.encode(m.select_frames(0, min(50, m.n_frames)), max_error=1.0))


def best_of(fn, n=3):
    """Fastest of ``n`` timed calls of ``fn``, in seconds."""
    import time
    ts = []
    for _ in range(n):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return min(ts)


def coded_float32(m) -> bytes:
    """Every sample an encode of the motion ``m`` codes, as float32 bytes: the yardstick
    input of bench_speed.py, so that zstd -19 is given the same data MPZ is (issue 15:
    "on the same float32 bytes").

    - marker positions, x y z (12 bytes per marker-frame, ``Motion.raw_size``; gaps as 0);
    - a C3D archive's per-point fourth words, model outputs (x y z) and analog samples
      (spec §4.13: cpnt and cana code them exactly);
    - a skeleton's channel values (spec §4.14: bvhs / asfs code them).

    A motion with none of the three extras gives the positions alone.
    """
    import numpy as np

    parts = [m.positions]
    extras = getattr(m, "extras", {})          # none in an mpz before 0.2 (the 0.1.0 release)
    arc = extras.get("c3d")
    if arc is not None:
        parts += [arc.words, arc.models, arc.analog]
    if extras.get("skeleton") is not None and m.angles is not None:
        parts.append(m.angles)
    return b"".join(np.nan_to_num(np.asarray(a, dtype=np.float32)).tobytes() for a in parts)


def two_versions(ap: argparse.ArgumentParser, argv: list[str] | None) -> argparse.Namespace:
    """Parse ``argv`` for a bench of two forms: ``--json OUT`` measures the version that
    runs, ``--compare BEFORE ... --against AFTER ...`` compares alternating runs of two
    versions (bench_decode.py, bench_encode.py); one of them must be given."""
    ap.add_argument("--json", type=Path, help="where the first form writes its rows")
    ap.add_argument("--compare", nargs="+", type=Path, metavar="BEFORE")
    ap.add_argument("--against", nargs="+", type=Path, metavar="AFTER")
    args = ap.parse_args(argv)
    if args.compare and not args.against:
        ap.error("--compare needs --against")
    if not args.compare and not args.json:
        ap.error("give --json OUT, or --compare ... --against ...")
    return args
