"""Write the quick-start example capture: ``python -m mpz.tools.make_example OUT``.

The example is a deterministic synthetic walk (``mpz.synth``, seed 0) with the
CMU 41-marker set, 4 s at 120 Hz, 0.3 mm noise and a few occlusion gaps, in any
format ``mpz.io.write`` supports (.c3d, .trc, .npy, .csv). Real recordings may
not be redistributed, so the quick start uses this one.
"""
from __future__ import annotations

import sys

from mpz.tools._cli import EXIT_ERROR, Parser, printable


def make(frames: int = 480, seed: int = 0):
    from mpz.synth import generate
    return generate("walk", frames=frames, rate=120.0, seed=seed, noise_mm=0.3,
                    gap_fraction=0.01)


def main(argv=None) -> int:
    p = Parser(prog="python -m mpz.tools.make_example", description=__doc__)
    p.add_argument("output", help="e.g. walk.c3d or walk.trc")
    p.add_argument("--frames", type=int, default=480)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("-f", "--force", action="store_true",
                   help="replace an existing file (else it is an error, as for every mpz "
                        "command; a newcomer's QA run found it replaced silently)")
    args = p.parse_args(argv)
    from mpz._worker import command_main
    from mpz.api import check_output
    from mpz.errors import MPZError
    from mpz.io import write
    before = command_main(True)        # a command: its messages say --force, not force=True
    try:
        check_output(args.output, force=args.force)
        m = make(args.frames, args.seed)
        write(m, args.output)
    except MPZError as exc:
        print(f"make_example: error: {printable(str(exc))}", file=sys.stderr)
        return EXIT_ERROR
    finally:
        command_main(before)
    print(f"wrote {printable(args.output)}: {m.n_frames} frames x {m.n_markers} markers, "
          f"{m.rate:g} Hz, gaps {m.gap_fraction:.1%}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
