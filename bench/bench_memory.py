"""Encoder peak memory on long captures (issue 11.11): peak RSS against the input size.

    python bench/bench_memory.py [--frames 100000 300000 1000000] [--modes default 1mm lossy]
                                 [--quick] [--joints J]

Each run is a child process that builds a synthetic walk (``mpz.synth.generate("walk",
frames=N, markers=41)``), resets its peak-RSS mark (``/proc/self/clear_refs``), encodes,
and reports the peak resident memory of the encode (``VmHWM``) with the input's own size
(positions float64, F x M x 24 bytes, plus the mask). Columns: ``peak MB`` is the child's
whole peak RSS, the interpreter, numpy, numba and the input included; ``over MB`` is that
peak less the RSS just before the encode (``rss0``: what the encode itself added); ``x
input`` is ``over MB`` / ``input MB``, the ratio that must stay a small constant as
captures grow (the interpreter's baseline, about 100 MB, would swamp it on short inputs).
The SHA-256 of the output is printed too, so that a memory change can be shown to leave
the bytes alone. Linux only (``/proc``). ``--quick`` runs 20 000 and 50 000 frames in
place of ``--frames`` (giving both is an error).

Modes: ``default`` (the default bound), ``1mm`` (``max_error=1.0``), ``lossy`` (the
paper's mode, pattern layers).

``--joints J`` encodes a joint-heavy BVH instead of the walk (a QA run's bomb: 183 KB of
text for 4096 joints and 10,000 frames, 983 MB of joint positions, took about 11 GB to
encode before the encoder worked in blocks): a ROOT with 6 channels and a chain of J - 1
JOINTs without channels, an End Site at its end, and a line of 6 random digits a frame
(every frame is then a key frame of every joint), read by ``parse_bvh`` in the child; the
input is its joint positions (J + 1 points). ``1mm`` is 1 unit of the BVH (it has none),
which the position-bound search for its channels takes too. E.g. ``--joints 4096
--frames 1000 2000 --modes default 1mm`` (the figures of docs/io-notes.md, "Size and
memory"); 4096 x 10,000 needs about 4 GB.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from typing import Any

CHILD = r"""
import gc, hashlib, json, re, sys, time
import numpy as np
from mpz.encoder import EncodeOptions, encode_motion
from mpz.synth import generate

def status(key):
    text = open("/proc/self/status").read()
    return int(re.search(key + r":\s+(\d+) kB", text).group(1)) * 1024

frames, mode, joints = int(sys.argv[1]), sys.argv[2], int(sys.argv[3])
opts = {"default": {}, "1mm": {"max_error": 1.0}, "lossy": {"lossy": True}}[mode]
if joints:
    from mpz.io.bvh import parse_bvh
    rng = np.random.default_rng(0)
    head = ["HIERARCHY", "ROOT j0", "{", "OFFSET 0 0 0",
            "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"]
    for k in range(1, joints):
        head += [f"JOINT j{k}", "{", "OFFSET 0 1 0"]
    head += ["End Site", "{", "OFFSET 0 1 0", "}"] + ["}"] * joints
    rows = [" ".join(map(str, r)) for r in rng.integers(0, 10, (frames, 6))]
    text = "\n".join(head + ["MOTION", f"Frames: {frames}", "Frame Time: 0.01", *rows])
    m = parse_bvh(text + "\n")
    del text, rows
else:
    m = generate("walk", frames=frames, markers=41, seed=0)
gc.collect()
input_bytes = m.positions.nbytes + m.valid.nbytes
with open("/proc/self/clear_refs", "w") as fh:       # reset VmHWM to the current RSS
    fh.write("5")
before = status("VmRSS")
t = time.perf_counter()
try:
    options = EncodeOptions(**opts)
except TypeError:                   # an encoder from before "lossy" (its default was lossy)
    options = EncodeOptions()
data, rep = encode_motion(m, options)
seconds = time.perf_counter() - t
print(json.dumps({"frames": frames, "mode": mode, "input": input_bytes, "rss0": before,
                  "peak": status("VmHWM"), "seconds": seconds, "bytes": len(data),
                  "sha256": hashlib.sha256(data).hexdigest()}))
"""


def run(frames: int, mode: str, joints: int = 0) -> dict[str, Any]:
    out = subprocess.run([sys.executable, "-c", CHILD, str(frames), mode, str(joints)],
                         capture_output=True, text=True)
    if out.returncode != 0:
        return {"frames": frames, "mode": mode, "error": out.stderr.strip().splitlines()[-1]}
    result: dict[str, Any] = json.loads(out.stdout.strip().splitlines()[-1])
    return result


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, nargs="+", default=[100_000, 300_000, 1_000_000])
    p.add_argument("--modes", nargs="+", default=["default", "1mm", "lossy"],
                   choices=["default", "1mm", "lossy"])
    p.add_argument("--quick", action="store_true",
                   help="20 000 and 50 000 frames, in place of --frames")
    p.add_argument("--json", action="store_true", help="one JSON object per run")
    p.add_argument("--joints", type=int, default=0, metavar="J",
                   help="a BVH chain of J joints whose root alone has channels, instead "
                        "of the 41-marker walk")
    args = p.parse_args(argv)
    if args.quick and args.frames != p.get_default("frames"):
        p.error("--quick runs 20 000 and 50 000 frames: give --quick or --frames, not both")
    sizes = [20_000, 50_000] if args.quick else args.frames
    if not args.json:
        print("peak MB: the child's whole peak RSS (interpreter included); over MB: peak less "
              "the RSS before the encode;\nx input: over MB / input MB (the encode's own "
              "memory per byte of input)")
        print(f"{'frames':>9} {'mode':>8} {'input MB':>9} {'peak MB':>9} {'over MB':>9} "
              f"{'x input':>8} {'s':>7} {'MPZ KB':>8}  sha256")
    for frames in sizes:
        for mode in args.modes:
            r = run(frames, mode, args.joints)
            if args.json:
                print(json.dumps(r), flush=True)
                continue
            if "error" in r:
                print(f"{frames:>9} {mode:>8}  failed: {r['error']}", flush=True)
                continue
            over = r["peak"] - r["rss0"]
            print(f"{frames:>9} {mode:>8} {r['input'] / 1e6:>9.1f} {r['peak'] / 1e6:>9.1f} "
                  f"{over / 1e6:>9.1f} {over / r['input']:>8.2f} {r['seconds']:>7.1f} "
                  f"{r['bytes'] / 1e3:>8.1f}  {r['sha256'][:16]}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
