"""``mpz decode IN.mpz -o OUT.{c3d,trc,npy,csv}``: restore a motion."""
from __future__ import annotations

import os
import tempfile

from mpz.errors import EncoderError


def add_parser(sub):
    p = sub.add_parser("decode", help="decompress .mpz to C3D, TRC, NPY or CSV",
                       description="Decode an MPZ file. NPY output is float64 [frames, markers, 3] "
                       "in the input's marker order and units, NaN for gaps.")
    p.add_argument("input")
    p.add_argument("-o", "--output", required=True, help="OUT.c3d, OUT.trc, OUT.npy or OUT.csv")
    p.add_argument("--force", action="store_true", help="replace OUTPUT if it exists")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=run)


def run(args) -> int:
    from mpz.api import read_mpz
    from mpz.io import write
    from mpz.tools._common import same_file
    if same_file(args.input, args.output):
        raise EncoderError(f"refusing to overwrite the input file {args.input}")
    if os.path.exists(args.output) and not args.force:
        raise EncoderError(f"{args.output} exists; use --force to replace it")
    motion = read_mpz(args.input)
    directory = os.path.dirname(os.path.abspath(args.output))
    ext = os.path.splitext(args.output)[1]
    fd, tmp = tempfile.mkstemp(prefix=".mpz-decode-", suffix=ext, dir=directory)
    os.close(fd)
    try:
        write(motion, tmp)
        os.replace(tmp, args.output)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    if not args.quiet:
        print(f"{args.input} -> {args.output}: {motion.n_frames} frames x {motion.n_markers} "
              f"markers, {motion.rate:g} Hz, gaps {motion.gap_fraction:.1%}")
    return 0
