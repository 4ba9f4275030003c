"""``mpz decode IN.mpz -o OUT.{c3d,trc,npy,csv}``: restore a motion."""
from __future__ import annotations

import argparse
import os

from mpz.errors import EncoderError, MPZError


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("decode", help="decompress .mpz to C3D, TRC, NPY or CSV",
                       description="Decode an MPZ file. NPY output is float64 [frames, markers, 3] "
                       "in the input's marker order and units, NaN for gaps.")
    p.add_argument("input")
    p.add_argument("-o", "--output", required=True, help="OUT.c3d, OUT.trc, OUT.npy or OUT.csv "
                   "(written atomically)")
    p.add_argument("--force", action="store_true", help="replace OUTPUT if it exists")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from mpz.api import atomic_output, check_output, read_mpz
    from mpz.io import WRITERS, write
    from mpz.io._common import ext_of

    # every check on the output comes before the decode
    check_output(args.output, force=args.force, source=args.input)
    ext = ext_of(args.output)
    if ext not in WRITERS:
        raise EncoderError(f"{args.output}: cannot write {ext or '(no extension)'!r} files; "
                           f"can write {', '.join(WRITERS)}")
    motion = read_mpz(args.input)
    with atomic_output(args.output, force=args.force, source=args.input) as tmp:
        try:
            write(motion, tmp, file_name=os.path.basename(args.output))
        except MPZError as exc:  # name the output, not the temporary file
            if exc.path == tmp:
                exc.path = args.output
            raise
    if not args.quiet:
        print(f"{args.input} -> {args.output}: {motion.n_frames} frames x {motion.n_markers} "
              f"markers, {motion.rate:g} Hz, gaps {motion.gap_fraction:.1%}")
    return 0
