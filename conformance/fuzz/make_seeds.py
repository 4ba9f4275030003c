"""Write seeds for the fuzzer: small valid files of each kind.

    python conformance/fuzz/make_seeds.py OUT_DIR [--real ../shared/data] [--bombs]

Synthetic seeds always; with ``--real DIR``, excerpts of the real recordings in DIR (the
first 48 frames and at most 16 markers of each C3D, TRC, BVH and AMC file) encoded at
several settings, so that the fuzzer starts from the chunk layouts real data produce
(issue 10: seeds from real files); with ``--bombs``, the decompression bombs of issue 11.1
scaled down to 2^16 marker-frames (the fuzzer's cap). Write them to a scratch folder.

The real recordings are never copied into the repository, and neither is anything grown
from their excerpts: a run seeded with ``--real`` finds bugs, but what it adds to its
corpus folder carries pieces of real captures, so it is not merged into
conformance/corpus/. To keep the inputs that add coverage, run again from seeds made
without ``--real`` (and conformance/corpus itself), then
``fuzz_decoder.py -merge=1 conformance/corpus NEW``. Only small files belong there.
"""
from __future__ import annotations

import argparse
from collections.abc import Iterator
from pathlib import Path
import sys
from typing import Any
import warnings

import numpy as np

import mpz
from mpz.synth import generate

#: encoder settings of the real-file seeds: (name, options)
SETTINGS: list[tuple[str, dict[str, Any]]] = [
    ("default", {}),
    ("1mm", {"max_error": 1.0}),
    ("5mm-auto", {"max_error": 5.0, "patterns": "auto"}),
    ("2mm-on", {"max_error": 2.0, "patterns": "on", "smoothing": 4}),
    ("lossy", {"lossy": True}),
    ("lossy-optimal-h16", {"lossy": True, "segmentation": "optimal", "smoothing": 16}),
    ("1mm-summary", {"max_error": 1.0, "summary": (2, 5)}),
]


def synthetic() -> dict[str, bytes]:
    return {
        "seed-bounded.mpz": mpz.encode(generate("walk", frames=16, markers=5, seed=1,
                                                gap_fraction=0.1), max_error=1.0),
        "seed-lossy.mpz": mpz.encode(generate("wave", frames=40, markers=6, seed=2),
                                     lossy=True),
        "seed-summary.mpz": mpz.encode(generate("jump", frames=24, markers=4, seed=3),
                                       max_error=2.0, summary=(2, 3)),
        "seed-patterns.mpz": mpz.encode(generate("walk", frames=48, markers=6, seed=4),
                                        max_error=1.0, patterns="on"),
    }


def excerpt(m: mpz.Motion, frames: int = 48, markers: int = 16) -> mpz.Motion:
    """The first ``frames`` frames of the first ``markers`` markers that have data."""
    short = m.select_frames(0, min(frames, m.n_frames))
    keep = [j for j in range(short.n_markers) if short.valid[:, j].any()][:markers]
    keep = keep or [0]
    return mpz.Motion(short.positions[:, keep], [short.names[j] for j in keep], short.rate,
                      short.units, short.valid[:, keep], dict(short.metadata))


def real(root: Path) -> Iterator[tuple[str, bytes]]:
    from mpz.io import read
    files = sorted(p for p in root.rglob("*")
                   if p.suffix.lower() in (".c3d", ".trc", ".bvh", ".amc"))
    for path in files:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                m = excerpt(read(path))
        except mpz.MPZError as exc:
            print(f"skipped {path.name}: {exc}", file=sys.stderr)
            continue
        for name, opts in SETTINGS:
            try:
                yield f"real-{path.stem}-{name}.mpz", mpz.encode(m, **opts)
            except mpz.MPZError as exc:
                print(f"skipped {path.name} {name}: {exc}", file=sys.stderr)


def bombs() -> dict[str, bytes]:
    """Issue 11.1 at 2^16 marker-frames: one 1-frame pattern stretched over every frame by
    one segment, and by one segment per frame with smoothing 16."""
    from mpz import container
    from mpz.chunks import Hier, HierNode, Mend, Mhdr, Mnam, Patt, Qunt, Root, Segs
    from mpz.entropy import BlockEncoder

    def coded(values: np.ndarray, **kw: Any) -> bytes:
        enc = BlockEncoder()
        enc.block(values, **kw)
        return enc.finish()

    M, F = 256, 256
    n = M - 1
    out = {}
    for name, per_frame, h in (("bomb-one-segment-2pow16.mpz", False, 0),
                               ("bomb-segment-per-frame-h16-2pow16.mpz", True, 16)):
        segs = (Segs(node=1, segment_count=F, coded=coded(np.zeros((F, 1, 2), np.int64)))
                if per_frame else
                Segs(node=1, segment_count=1, coded=coded(np.array([[[0, F - 1]]]))))
        out[name] = container.build([
            Mhdr(version_major=1, version_minor=0, flags=0, frame_count=F, marker_count=M,
                 node_count=2, rate=120.0, units=1, error_metric=0, error_bound=0.0,
                 smoothing=h),
            Mnam(count=M, names=tuple(f"m{i}" for i in range(M))),
            Hier(count=2, nodes=(
                HierNode(parent=0xFFFF, ref=0, member_count=1, members=(0,), weights=(1.0,)),
                HierNode(parent=0, ref=1, member_count=n, members=tuple(range(1, M)),
                         weights=(1.0,) * n))),
            Qunt(step=1.0, offset=(0.0, 0.0, 0.0), bits=8),
            Root(order=0, coded=coded(np.zeros((F, 1, 3), np.int64))),
            Patt(node=1, pattern_count=1, length=1, scale=1, order=0,
                 coded=coded(np.ones((1, n, 3), np.int64), period=1)),
            segs, Mend()])
    return out


def skeletal() -> dict[str, bytes]:
    """Issue 13: a BVH and an AMC/ASF file with their skeleton chunk (spec §4.14), both
    synthetic (the texts of make_vectors), at the default and at a joint-position bound."""
    from mpz.io.amc import parse_amc, parse_asf
    from mpz.io.bvh import parse_bvh
    from mpz.tools.make_vectors import _SKELETON_ASF, _skeleton_amc_text, _skeleton_bvh_text
    bvh = parse_bvh(_skeleton_bvh_text(F=12))
    amc = parse_amc(_skeleton_amc_text(F=10), parse_asf(_SKELETON_ASF))
    return {"seed-skeleton-bvh.mpz": mpz.encode(bvh),
            "seed-skeleton-bvh-5mm.mpz": mpz.encode(bvh, max_error=0.5, position_error=0.5),
            "seed-skeleton-amc.mpz": mpz.encode(amc)}


def c3d_archives() -> dict[str, bytes]:
    """Issue 12: C3D archives (spec §4.13) from the synthetic C3D sources of make_vectors:
    float32 with analog and model outputs, int16 exact on the grid, no analog."""
    from mpz.tools.make_vectors import c3d_motion
    return {"seed-c3d-float32.mpz": mpz.encode(c3d_motion(71, storage=1), max_error=1.0),
            "seed-c3d-int16-exact.mpz": mpz.encode(c3d_motion(72, storage=0, J=1, C=2, n=2)),
            "seed-c3d-bare.mpz": mpz.encode(c3d_motion(73, storage=1, J=0, C=0),
                                            max_error=2.0)}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out", nargs="?", default="conformance/corpus")
    p.add_argument("--real", type=Path, help="folder of real recordings (read in place)")
    p.add_argument("--bombs", action="store_true", help="the issue 11.1 bombs, 2^16 samples")
    args = p.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    seeds = synthetic()
    seeds.update(skeletal())
    seeds.update(c3d_archives())
    if args.bombs:
        seeds.update(bombs())
    if args.real is not None:
        seeds.update(real(args.real))
    for name, data in seeds.items():
        (out / name).write_bytes(data)
    print(f"wrote {len(seeds)} seeds to {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
