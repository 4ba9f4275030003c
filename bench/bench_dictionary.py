"""What would a trained dictionary buy? A held-out study for issue 16 (not the feature).

Issue 16 asks for ``mpz train`` dictionaries "whichever pays on held-out files". Before a
new major version is spent on them (§2.1: a file that needs a dictionary must not decode
in a 1.x decoder, so dictionary use is a critical change), this bench measures on the real
recordings what each candidate content saves, always on files held out from training:

1. **Initial model states** (§5.2 starts every model at p = 1024). For every critical
   block the encoder codes (MASK, ROOT, PATT, SEGS, RESI and the four key-frame blocks),
   the binary decisions each model of §5.4 sees are counted per file. A held-out file is
   then coded with every block starting from p = 2048 (n0 + 1) / (n0 + n1 + 2), clamped to
   31 .. 2017, where n0, n1 are summed over the files of *other subjects* (leave one
   subject out: the CMU subject number, HDM05 actor, or the file itself when it has no
   relative). The counts add, so one pass over the corpus serves every fold.
2. **Archive byte payloads.** The C3D header (chdr) and parameter section (cprm) are
   stored as bytes (§4.13.1, §4.13.2). Measured: raw, DEFLATE (RFC 1951, zlib level 9),
   and DEFLATE with a 32 KiB preset dictionary made of the other subjects' payloads.

The pattern database of Gu et al. across files (lossy mode) is not measured here: it needs
matching body-part hierarchies between files, which the corpus has only for a few takes
(docs/dictionaries.md).

Run ``python bench/bench_dictionary.py [--bounds 1,5] [--lossy] [--files GLOB]``. Needs
``../shared/data`` (or ``MPZ_SHARED_DATA``); prints tables, writes nothing.
"""
from __future__ import annotations

import argparse
from collections.abc import Callable
import glob
import inspect
import math
from pathlib import Path
import sys
from typing import Any
import warnings
import zlib

from numba import njit
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import no_data_reason, shared_data_dir
from bench_entropy import _context8
import mpz
from mpz import container, entropy

# The §5.4 model-set shapes, with a last axis of 2: how often each model saw a 0 and a 1.
_SHAPES = ((3, 8), (3, 8), (3, 8, 30), (3, 31, 30))
Counts = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def new_counts() -> Counts:
    z, s, e, x = (np.zeros(shape + (2,), np.int64) for shape in _SHAPES)
    return z, s, e, x


@njit(cache=True)
def _count_block(vals, period, signed, cz, cs, ce, cx):  # pragma: no cover - numba
    """Count the decisions of §5.4/§5.6 for one block, model by model (no coding)."""
    T, M, A = vals.shape
    for t in range(T):
        first = (t % period) == 0
        for m in range(M):
            for a in range(A):
                c = _context8(vals, t, m, a, first)          # §5.6
                v = vals[t, m, a]
                if v == 0:
                    cz[a, c, 0] += 1
                    continue
                cz[a, c, 1] += 1
                u = v
                if signed:
                    if v < 0:
                        cs[a, c, 1] += 1
                        u = -v
                    else:
                        cs[a, c, 0] += 1
                k = 0
                while (u >> (k + 1)) != 0:
                    k += 1
                for i in range(k):
                    ce[a, c, i, 1] += 1
                if k < 30:
                    ce[a, c, k, 0] += 1
                for j in range(k):
                    cx[a, k, j, (u >> (k - 1 - j)) & 1] += 1


def to_models(c: Counts) -> entropy.Models:
    """Initial probabilities from decision counts (add-one smoothing, §5.2's range)."""
    out = []
    for arr in c:
        n0, n1 = arr[..., 0].astype(np.float64), arr[..., 1].astype(np.float64)
        out.append(np.clip(np.rint(2048 * (n0 + 1) / (n0 + n1 + 2)), 31, 2017).astype(np.int32))
    return out[0], out[1], out[2], out[3]


class Probe:
    """Counts or replaces the initial models of the critical blocks the encoder codes.

    A block is identified by where the encoder codes it (module and line), so the ROOT
    block, each RESI candidate and each of the four key-frame blocks get their own model
    set. Ancillary coders (C3D channels, skeleton channels) are left alone.
    """

    CRITICAL = ("encoder.py", "keyframe.py")

    def __init__(self) -> None:
        self.counts: dict[tuple[str, int], Counts] | None = None
        self.models: dict[tuple[str, int], entropy.Models] | None = None
        self._orig: Callable[..., Any] = entropy.BlockEncoder.block

    def __enter__(self) -> Probe:
        probe, orig = self, self._orig

        def block(enc: Any, values: Any, *, period: int | None = None, signed: bool = True,
                  models: Any = None) -> None:
            caller = inspect.stack(0)[1]
            key = (Path(caller.filename).name, caller.lineno)
            v = np.ascontiguousarray(values, dtype=np.int64)
            if key[0] in probe.CRITICAL:
                if probe.counts is not None:
                    c = probe.counts.setdefault(key, new_counts())
                    _count_block(v, max(1, v.shape[0] if period is None else int(period)),
                                 signed, *c)
                if probe.models is not None and key in probe.models:
                    models = probe.models[key]
            orig(enc, v, period=period, signed=signed, models=models)

        entropy.BlockEncoder.block = block  # type: ignore[method-assign]
        return self

    def __exit__(self, *exc: object) -> None:
        entropy.BlockEncoder.block = self._orig  # type: ignore[method-assign]


def subject(path: str) -> str:
    """The group a file is held out with: CMU subject, HDM05 actor, a c3d.org series."""
    p = Path(path)
    b = p.stem
    for tag in ("HDM_dg", "HDM_mm"):
        if b.startswith(tag):
            return tag
    if b.startswith("cmu_"):
        return "cmu" + b.split("_")[1]
    if p.suffix == ".amc":
        return "cmu" + b.split("_")[0]
    if b.startswith("c3dorg_Eb015"):
        return "Eb015"
    return b


def geomean(xs: list[float]) -> float:
    return math.exp(sum(math.log(x) for x in xs) / len(xs)) if xs else float("nan")


def study_models(files: list[str], opts: dict[str, Any], label: str) -> None:
    motions = {f: mpz.io.read(f) for f in files}
    probe = Probe()
    counts: dict[str, dict[tuple[str, int], Counts]] = {}
    plain: dict[str, int] = {}
    with probe:
        for f in files:
            probe.counts = {}
            plain[f] = len(mpz.encode(motions[f], **opts))
            counts[f] = probe.counts
        probe.counts = None
        print(f"\n[{label}] initial model states, leave one subject out")
        print(f"  {'file':44s} {'frames':>6s} {'without':>8s} {'with':>8s} {'change':>7s}")
        short, long_ = [], []
        agg: dict[tuple[str, int], Counts] = {}
        for f in files:
            agg = {}
            for g in files:
                if subject(g) == subject(f):
                    continue
                for key, c in counts[g].items():
                    a = agg.setdefault(key, new_counts())
                    for x, y in zip(a, c, strict=True):
                        x += y
            probe.models = {k: to_models(c) for k, c in agg.items()}
            with_dict = len(mpz.encode(motions[f], **opts))
            probe.models = None
            frames = motions[f].positions.shape[0]
            (short if frames <= 1000 else long_).append(with_dict / plain[f])
            print(f"  {Path(f).parent.name + '/' + Path(f).name:44s} {frames:6d} {plain[f]:8d} "
                  f"{with_dict:8d} {100 * (with_dict / plain[f] - 1):6.1f}%")
        print(f"  geometric mean size ratio (with/without): <= 1000 frames "
              f"{geomean(short):.4f} ({len(short)} files), longer {geomean(long_):.4f} "
              f"({len(long_)} files)")
        slots = len(next(iter(agg.values()))) if agg else 0
        print(f"  dictionary content: {len(agg)} block slots x 3558 models x 2 bytes = "
              f"{len(agg) * 3558 * 2} bytes raw ({slots} arrays each)")


def study_archive(files: list[str]) -> None:
    c3d = [f for f in files if f.endswith(".c3d")]
    if not c3d:
        return
    payloads: dict[str, dict[str, bytes]] = {}
    total: dict[str, int] = {}
    for f in c3d:
        data = mpz.encode(mpz.io.read(f), max_error=1.0)
        total[f] = len(data)
        payloads[f] = {c.type: c.payload for c in container.scan(data).chunks
                       if c.type in ("chdr", "cprm")}
    print("\n[C3D archive payloads at 1 mm] bytes: raw / DEFLATE / DEFLATE + preset "
          "dictionary (other subjects)")
    print(f"  {'file':44s} {'file':>7s} {'cprm':>17s} {'chdr':>15s} {'saved':>13s}")
    for f in c3d:
        cells, saved = [], [0, 0]
        for t in ("cprm", "chdr"):
            raw = payloads[f][t]
            z = zlib.compress(raw, 9)
            zd = b"".join(payloads[g][t] for g in c3d if subject(g) != subject(f))[-32768:]
            co = zlib.compressobj(9, zlib.DEFLATED, 15, 9, zlib.Z_DEFAULT_STRATEGY, zd)
            zz = co.compress(raw) + co.flush()
            cells.append(f"{len(raw):5d}/{len(z):5d}/{len(zz):5d}")
            saved[0] += len(raw) - len(z)
            saved[1] += len(raw) - len(zz)
        print(f"  {Path(f).name:44s} {total[f]:7d} {cells[0]:>17s} {cells[1]:>15s} "
              f"{100 * saved[0] / total[f]:5.1f}%/{100 * saved[1] / total[f]:5.1f}%")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bounds", default="1,5", help="max-error bounds in mm (default 1,5)")
    ap.add_argument("--lossy", action="store_true", help="also the paper's lossy mode")
    ap.add_argument("--files", default="*/*", help="glob under the data folder")
    args = ap.parse_args(argv)
    reason = no_data_reason()
    if reason:
        print(f"skipped: {reason}")
        return 0
    data = shared_data_dir()
    assert data is not None
    warnings.simplefilter("ignore")
    files = sorted(f for f in glob.glob(str(data / args.files))
                   if f.endswith((".c3d", ".trc", ".bvh", ".amc")))
    if not files:
        print(f"skipped: no recording matches --files {args.files!r} under {data}")
        return 0
    for b in (float(x) for x in args.bounds.split(",") if x):
        study_models(files, {"max_error": b}, f"bound {b:g} mm")
    if args.lossy:
        study_models(files, {"lossy": True}, "lossy (paper mode)")
    study_archive(files)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
