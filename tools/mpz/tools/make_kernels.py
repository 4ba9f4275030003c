"""Compile the codec's kernels for the generic CPU into ``mpz/_kernels`` (issue 15.2).

    python -m mpz.tools.make_kernels            # rebuild reference/mpz/_kernels
    python -m mpz.tools.make_kernels --python /venv3.12/bin/python --python ...
                                                # and for more CPython versions
    python -m mpz.tools.make_kernels --check    # exit 1 if they are stale

The first ``mpz encode`` after an install used to spend 3-4 s compiling numba kernels
(docs/cold-start.md). The package now ships them, compiled for a baseline CPU of the
build's platform (:data:`BASELINES`: x86-64-v2 on x86-64, else LLVM's generic CPU), and
:mod:`mpz._jit` loads them when its own cache has no entry and the CPU has the
baseline's features. This command makes them: in a child process, with
``MPZ_SHIP_KERNELS=1``, it encodes and decodes a set of motions that calls every
shippable kernel with the argument types real use gives (bounded, default and lossy
coding, gaps, one and two threads, a C3D round trip, every conformance vector), so
each kernel is compiled once and written to ``mpz/_kernels``.

Like the vectors and the golden file, the shipped kernels change only through this
command. ``_kernels/manifest.json`` records the configuration they serve (CPython minor
version, numba version, target triple) and the SHA-256 of each source file that holds a
shipped kernel. numba checks the same hash before loading an entry, so a kernel whose
source file changed since is compiled as before. ``tests/test_jit.py`` fails on such a
file until this command is run again.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile
from typing import Any

MANIFEST = "manifest.json"
#: the CPU the kernels are compiled for, per architecture, and the features a CPU needs to
#: run them (LLVM names, checked by mpz._jit before loading). x86-64-v2 (SSE4.2, POPCNT:
#: every x86-64 CPU since 2009) runs the kernels as fast as host code; plain "generic"
#: x86-64 was 8-13 % slower in the encoder (no SSE4.1 rounding, so floor() is a call)
BASELINES = {"x86_64": ("x86-64-v2", ["cx16", "popcnt", "sahf", "sse3", "sse4.1", "sse4.2",
                                      "ssse3"])}


def _config() -> dict:
    import platform

    import llvmlite.binding as ll
    import numba
    triple = ll.get_process_triple()
    return {"python": f"{sys.version_info[0]}.{sys.version_info[1]}",
            "implementation": platform.python_implementation(),
            "numba": numba.__version__, "triple": triple}


def workload() -> None:
    """Call every shippable kernel the way encoding and decoding real files does."""
    import warnings

    import mpz
    from mpz import fisher
    from mpz.conformance import manifest as mf
    from mpz.errors import MPZError
    from mpz.synth import generate
    warnings.simplefilter("ignore")
    motions = [generate("walk", frames=300, seed=1),
               generate("mixed", frames=500, seed=2, gap_fraction=0.05)]
    options: list[dict[str, Any]] = [
        {"max_error": 1.0}, {"max_error": 5.0, "threads": 2}, {}, {"lossy": True},
        {"patterns": "on", "max_error": 2.0}, {"max_error": 1.0, "summary": (4, 8)},
        {"max_error": 1.0, "hierarchy": "auto"}]       # marker sets without a template
    for m in motions:
        for kw in options:
            mpz.decode(mpz.encode(m, **kw))
    fisher._FORKED = True                            # the summary's kernel in a forked child
    try:
        mpz.encode(motions[0], max_error=1.0, summary=(4, 8))
    finally:
        fisher._FORKED = False
    with tempfile.TemporaryDirectory() as tmp:      # a C3D source: the archive chunks
        path = os.path.join(tmp, "walk.c3d")
        mpz.io.write(motions[0], path)
        c3d = mpz.io.read(path)
        for kw in options[:3]:
            mpz.decode(mpz.encode(c3d, **kw))
    man = mf.load()
    skeletal: set[str] = set()
    for v in man["vectors"]:                         # every chunk type, decoded
        data = (mf.DEFAULT_DIR / v["file"]).read_bytes()
        try:
            m = mpz.decode(data)
        except MPZError:
            continue
        skel = m.extras.get("skeleton")
        if skel is not None and skel.convention not in skeletal:
            skeletal.add(skel.convention)            # a BVH and an AMC encode: kinematics
            mpz.decode(mpz.encode(m))
            mpz.decode(mpz.encode(m, max_error=1.0))     # a position bound: the step search


def _sources(kernels_dir: Path) -> dict[str, str]:
    """sha256 of each source file that has a shipped kernel, by its path below the
    package's parent (``mpz/keyframe.py``): index files are named ``MODULE.KERNEL-….nbi``
    in the module's own folder (mpz._jit)."""
    import mpz
    top = Path(mpz.__file__).resolve().parent.parent
    out = {}
    for index in sorted(kernels_dir.rglob("*.nbi")):
        rel = (index.parent.relative_to(kernels_dir) / (index.name.split(".")[0] + ".py"))
        out[rel.as_posix()] = hashlib.sha256((top / rel).read_bytes()).hexdigest()
    return out


def stale(kernels_dir: Path | None = None) -> list[str]:
    """What keeps the shipped kernels from serving this checkout: changed source files,
    or a missing manifest. Empty when they are fresh."""
    import mpz
    from mpz import _jit
    kernels_dir = Path(_jit.SHIPPED_DIR) if kernels_dir is None else kernels_dir
    mpath = kernels_dir / MANIFEST
    if not mpath.is_file():
        return [f"{mpath} is missing"]
    recorded = json.loads(mpath.read_text())["sources"]
    top = Path(mpz.__file__).resolve().parent.parent
    out = []
    for rel, digest in recorded.items():
        src = top / rel
        if not src.is_file():
            out.append(f"{rel}: gone")
        elif hashlib.sha256(src.read_bytes()).hexdigest() != digest:
            out.append(f"{rel}: changed since the kernels were compiled")
    return out


def build(out: Path, pythons: list[str]) -> dict:
    """Compile the kernels into ``out``, the package's ``_kernels`` (emptied first), with
    each interpreter of ``pythons`` (each with this checkout installed, and all with the
    same numba), and write the manifest."""
    configs = []
    for py in pythons:
        r = subprocess.run([py, "-m", "mpz.tools.make_kernels", "--config"], check=True,
                           capture_output=True, text=True)
        configs.append(json.loads(r.stdout))
    if len({(c["numba"], c["triple"], c["implementation"]) for c in configs}) != 1:
        raise SystemExit(f"make_kernels: the interpreters differ in numba, platform or "
                         f"implementation: {configs}")
    config = configs[0]
    cpu, need = BASELINES.get(config["triple"].split("-")[0], ("generic", []))
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    env = {k: v for k, v in os.environ.items()
           if k not in ("MPZ_CACHE_DIR", "NUMBA_CACHE_DIR", "NUMBA_CPU_FEATURES")}
    env.update(NUMBA_CPU_NAME=cpu, NUMBA_CPU_FEATURES="", MPZ_SHIP_KERNELS="1",
               MPZ_SHIPPED_KERNELS="0")
    for py in pythons:
        subprocess.run([py, "-m", "mpz.tools.make_kernels", "--workload"], env=env, check=True)
    files = sorted(p for p in out.rglob("*") if p.is_file())
    info = {**config, "python": sorted({c["python"] for c in configs}), "cpu": cpu,
            "requires_features": need, "sources": _sources(out),
            "files": len(files), "bytes": sum(p.stat().st_size for p in files)}
    (out / MANIFEST).write_text(json.dumps(info, indent=1, sort_keys=True) + "\n")
    return info


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true",
                    help="exit 1 if the shipped kernels do not match the sources")
    ap.add_argument("--python", action="append", metavar="PY",
                    help="also compile with this interpreter (this checkout installed in it "
                         "with the same numba); repeatable. Default: this interpreter only")
    ap.add_argument("--workload", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--config", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.workload:
        workload()
        return 0
    if args.config:
        print(json.dumps(_config()))
        return 0
    from mpz import _jit
    from mpz.tools._cli import printable  # paths may hold terminal controls
    if args.check:
        problems = stale()
        for p in problems:
            print(f"make_kernels: {printable(p)}", file=sys.stderr)
        if problems:
            print("make_kernels: run `python -m mpz.tools.make_kernels`", file=sys.stderr)
        return 1 if problems else 0
    info = build(Path(_jit.SHIPPED_DIR), [sys.executable, *(args.python or [])])
    print(f"{info['files']} files, {info['bytes']} bytes in {printable(_jit.SHIPPED_DIR)} "
          f"(CPython {', '.join(info['python'])}, numba {info['numba']}, {info['triple']}, "
          f"CPU {info['cpu']}); sources: {', '.join(info['sources'])}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
