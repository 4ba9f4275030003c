"""Peak memory of the commands that read an .mpz file, per marker-frame (stop 53).

    python bench/bench_commands_memory.py [--frames 409200] [--markers 41] [--quick]

Encodes a synthetic walk of F frames (``mpz.synth.generate("walk")``, max error 1 mm) once
into a temporary folder, then runs each command on it as a child process and reports the
child's peak resident memory (``ru_maxrss`` of ``os.wait4``: the interpreter and its
libraries, about 100 MB, included) and its wall time. ``B/mf`` is that peak over F x M,
the figure the commands' ``--max-samples`` help and docs/io-notes.md give. The default,
409,200 frames of 41 markers, is 2^24 marker-frames (about 60 s in all here); ``--quick``
runs 40,000 frames (the interpreter's baseline then dominates B/mf). Linux and macOS
(``os.wait4``).
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
import subprocess
import sys
import tempfile
import time

#: (label, arguments after the program; {f} is the .mpz file, {d} the folder)
COMMANDS = [
    ("mpzinfo", ["mpzinfo", "{f}"]),
    ("mpz show", ["mpz", "show", "{f}"]),
    ("mpz decode -> .npy", ["mpz", "decode", "{f}", "-o", "{d}/out.npy", "-f"]),
    ("mpz decode -> .trc", ["mpz", "decode", "{f}", "-o", "{d}/out.trc", "-f"]),
    ("mpz decode -> .csv", ["mpz", "decode", "{f}", "-o", "{d}/out.csv", "-f"]),
    ("mpz decode -> .c3d", ["mpz", "decode", "{f}", "-o", "{d}/out.c3d", "-f"]),
    ("mpz summary", ["mpz", "summary", "{f}", "--k", "6,12"]),
    ("mpz compare .mpz .mpz", ["mpz", "compare", "{f}", "{f}"]),
]


MAKE = """
import sys
from pathlib import Path
import mpz
from mpz.synth import generate
m = generate("walk", frames=int(sys.argv[2]), markers=int(sys.argv[3]), seed=0)
Path(sys.argv[1]).write_bytes(mpz.encode(m, max_error=1.0))
"""


def peak(argv: list[str]) -> tuple[int, float, int]:
    """(peak RSS in bytes, seconds, exit status) of one command."""
    bindir = Path(sys.executable).parent
    exe = [str(bindir / argv[0])] + argv[1:]
    t = time.perf_counter()
    proc = subprocess.Popen(exe, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    seconds = time.perf_counter() - t
    proc.returncode = os.waitstatus_to_exitcode(status)
    scale = 1 if sys.platform == "darwin" else 1024          # Linux reports KiB
    return usage.ru_maxrss * scale, seconds, proc.returncode


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, default=409_200)
    p.add_argument("--markers", type=int, default=41)
    p.add_argument("--quick", action="store_true", help="40 000 frames, in place of --frames")
    p.add_argument("--json", action="store_true", help="one JSON object per command")
    args = p.parse_args(argv)
    frames = 40_000 if args.quick else args.frames
    with tempfile.TemporaryDirectory(prefix="mpz-bench-mem-") as d:
        f = os.path.join(d, "walk.mpz")
        # in a child: Linux gives a child the peak RSS of its parent at the fork, so this
        # process must stay small (it imports neither numpy nor mpz)
        subprocess.run([sys.executable, "-c", MAKE, f, str(frames), str(args.markers)],
                       check=True)
        samples = frames * args.markers
        if not args.json:
            print(f"{frames} frames x {args.markers} markers = {samples} marker-frames; "
                  f"peak RSS of each command (interpreter included)")
            print(f"{'command':<24} {'peak MB':>9} {'B/mf':>7} {'s':>7}  exit")
        for label, cmd in COMMANDS:
            rss, seconds, code = peak([a.format(f=f, d=d) for a in cmd])
            if args.json:
                print(json.dumps({"command": label, "frames": frames, "markers": args.markers,
                                  "peak_bytes": rss, "bytes_per_marker_frame": rss / samples,
                                  "seconds": seconds, "exit": code}), flush=True)
            else:
                print(f"{label:<24} {rss / 1e6:>9.0f} {rss / samples:>7.1f} {seconds:>7.1f}  "
                      f"{code}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
