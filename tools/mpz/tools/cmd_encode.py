"""``mpz encode IN -o OUT.mpz``: compress a motion-capture file."""
from __future__ import annotations

import json
import os

from mpz.errors import EncoderError


def _pairs(items, what):
    out = {}
    for item in items or []:
        if "=" not in item:
            raise EncoderError(f"{what} must look like NAME=VALUE, got {item!r}")
        k, v = item.rsplit("=", 1)
        out[k] = v
    return out


def add_parser(sub):
    from mpz.encoder import DEFAULTS as D   # the one definition of every default
    p = sub.add_parser("encode", help="compress C3D, TRC, BVH, AMC (+ASF), NPY or CSV to .mpz",
                       description="Compress a motion-capture file to MPZ. With --max-error the "
                       "decoded motion is guaranteed within that Euclidean distance of the input "
                       "on every valid sample; without it the paper's thresholds control quality.")
    p.add_argument("input")
    p.add_argument("-o", "--output", required=True, help="output .mpz file (written atomically)")
    p.add_argument("--asf", help="skeleton file for AMC input (default: found beside it)")
    p.add_argument("--max-error", metavar="E", help="hard bound, e.g. 2mm, 0.5cm, or a number "
                   "in the input's units")
    p.add_argument("--group-error", action="append", metavar="NODE=E",
                   help="tighter bound for one hierarchy node, e.g. lfoot=0.5mm (repeatable)")
    p.add_argument("--theta", type=float, default=D.theta,
                   help=f"key-frame threshold, fraction of the head size ADDH (default {D.theta})")
    p.add_argument("--k0", type=int, default=D.k0,
                   help=f"initial number of clusters (default {D.k0})")
    p.add_argument("--tau", type=float, default=D.tau,
                   help=f"clustering threshold, fraction of ADDH (default {D.tau})")
    p.add_argument("--metric", choices=("max", "ave"), default=D.metric,
                   help="clustering error metric, paper Eq. 2 (max) or Eq. 1 (ave)")
    p.add_argument("--weight", action="append", metavar="NAME=W",
                   help="weight of a marker or node (local distortion control; repeatable)")
    p.add_argument("--hierarchy", help="cmu41, skeleton, auto, flat or a JSON hierarchy file")
    p.add_argument("--smoothing", type=int, default=D.smoothing,
                   help=f"boundary smoothing half-width 0..16 (default {D.smoothing})")
    p.add_argument("--patterns", choices=("auto", "on", "off"), default=None,
                   help="pattern layer per node: auto keeps it where it makes the file smaller "
                   "(default: on without --max-error, off with it)")
    p.add_argument("--segmentation", choices=("adaptive", "optimal"), default=D.segmentation,
                   help="adaptive = paper's Alg. 1; optimal = Fisher optimal partition")
    p.add_argument("--grid", help="grid step (default: from --max-error, else ADDH/1000)")
    p.add_argument("--summary", metavar="K,K,...", help="add the optimal-partition summary chunk "
                   "with these segment counts, e.g. 6,12,24,48")
    p.add_argument("--summary-space", choices=("positions", "angles"), default=D.summary_space)
    p.add_argument("--meta", action="append", metavar="KEY=VALUE", help="metadata (repeatable)")
    p.add_argument("--force", action="store_true", help="replace OUTPUT if it exists, "
                   "or write it under a name not ending in .mpz")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.add_argument("--quiet", action="store_true", help="print nothing on success")
    p.set_defaults(func=run)


def run(args) -> int:
    import mpz
    from mpz.api import check_output
    from mpz.encoder import EncodeOptions, encode_motion
    from mpz.io._common import ext_of
    from mpz.metrics import summary as error_summary
    from mpz.tools._common import Progress, human_size, parse_length, read_motion

    # every check on the output comes before the encode
    check_output(args.output, force=args.force, source=args.input)
    if ext_of(args.output) != ".mpz" and not args.force:
        raise EncoderError(f"{args.output}: an MPZ file should end in .mpz; "
                           "use --force to write it under this name")
    motion = read_motion(args.input, args.asf)
    units = motion.units
    metadata = _pairs(args.meta, "--meta")
    metadata.setdefault("source", os.path.basename(args.input))
    opts = EncodeOptions(
        max_error=None if args.max_error is None else parse_length(args.max_error, units),
        group_errors={k: parse_length(v, units)
                      for k, v in _pairs(args.group_error, "--group-error").items()},
        theta=args.theta, k0=args.k0, tau=args.tau, metric=args.metric,
        weights={k: float(v) for k, v in _pairs(args.weight, "--weight").items()} or None,
        hierarchy=args.hierarchy, smoothing=args.smoothing, patterns=args.patterns,
        segmentation=args.segmentation,
        grid=None if args.grid is None else parse_length(args.grid, units),
        summary=tuple(int(k) for k in args.summary.split(",")) if args.summary else (),
        summary_space=args.summary_space, metadata=metadata)
    bar = Progress("encoding", enabled=None if not args.quiet else False)
    try:
        data, rep = encode_motion(motion, opts, progress=bar)
    finally:
        bar.close()
    mpz.write_atomic(args.output, data, source=args.input, force=args.force)
    decoded = mpz.decode(data)
    err = error_summary(motion, decoded)
    in_size = os.path.getsize(args.input)
    result = {
        "input": args.input, "output": args.output, "frames": rep.frames, "markers": rep.markers,
        "units": units, "raw_float32_bytes": rep.raw_bytes, "input_bytes": in_size,
        "file_bytes": rep.file_bytes, "ratio_float32": rep.raw_bytes / rep.file_bytes,
        "ratio_input": in_size / rep.file_bytes, "max_error": err["max"], "arms": err["arms"],
        "p99": err["p99"], "rms": err["rms"], "declared_bound": opts.max_error,
        "grid_step": rep.step, "addh": rep.addh, "addh_rule": rep.addh_rule,
        "hierarchy": rep.hierarchy, "seconds": rep.seconds, "chunk_bytes": rep.chunk_bytes,
        "nodes": [vars(n) for n in rep.nodes]}
    if args.json:
        print(json.dumps(result, indent=2))
    elif not args.quiet:
        u = f" {units}" if units else ""
        print(f"{args.input} -> {args.output}: {rep.frames} frames x {rep.markers} markers, "
              f"{rep.seconds:.2f} s")
        print(f"  size     raw float32 {human_size(rep.raw_bytes)}, input {human_size(in_size)}, "
              f"MPZ {human_size(rep.file_bytes)}")
        print(f"  ratio    {result['ratio_float32']:.1f}:1 vs float32, "
              f"{result['ratio_input']:.1f}:1 vs input file")
        bound = f" (bound {opts.max_error:g}{u})" if opts.max_error else " (no bound declared)"
        print(f"  error    max {err['max']:.4g}{u}{bound}, p99 {err['p99']:.4g}{u}, "
              f"ARMS {err['arms']:.4g}{u}")
        print(f"  grid     step {rep.step:.4g}{u}; ADDH {rep.addh:.4g}{u} ({rep.addh_rule}); "
              f"hierarchy {rep.hierarchy}")
        print("  node             markers segments patterns  L  pattern B  resid B  g")
        for n in rep.nodes:
            print(f"  {n.name[:16]:<16} {n.members:>7} {n.segments:>8} {n.patterns:>8} "
                  f"{n.pattern_length:>3} {n.pattern_bytes + n.segment_bytes:>10} "
                  f"{n.residual_bytes:>8} {n.residual_scale:>2}")
    return 0
