"""Cold start (issue 15.2): the first `mpz encode` / `mpz decode` after a fresh install
against a warm one, with the package in a read-only site-packages.

    python bench/bench_coldstart.py                 # build a wheel, install it in a new venv
    python bench/bench_coldstart.py --wheel W.whl   # install that wheel instead
    python bench/bench_coldstart.py --python PY     # an existing install (its cache is
                                                    # pointed at fresh directories)

Each case starts from an empty cache and runs the command --runs times in new
processes; "first" is run 1, "warm" the median of the others. Cases:

* ro site, cache in HOME  - site-packages read-only, an empty writable HOME: numba cannot
  cache beside the sources, so the kernels must go to the user cache directory;
* ro site, no cache dir   - HOME and XDG_CACHE_HOME under a regular file (nothing can be
  created there, not even by root): every run compiles and must still work.

Read-only: as root (who ignores permission bits) each command runs in a private mount
namespace with site-packages bind-mounted read-only (``unshare -m``); otherwise the
installed package is made ``a-w`` for the run and restored after. Encode and decode
are measured in separate cases so that decode does not find the encoder's kernels.
The third op, "summary", is an encode with ``--summary 6,12,24,48`` (the optimal
partition's kernels). Wall-clock and CPU times (user + system) of whole processes: on a
shared machine the wall clock follows the load (printed with the table), the CPU time
much less. Nothing
is asserted (tests/test_jit.py checks the cache policy).
"""
from __future__ import annotations

import argparse
from importlib import metadata
import json
import os
from pathlib import Path
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

from _common import REPO, shared_data_dir, shared_data_name

#: dependencies installed into the fresh venv at the versions of this environment
DEPS = ("numpy", "scipy", "construct", "ezc3d", "numba", "llvmlite")


class Skip(Exception):
    pass


def _run(cmd: list[str], **kw) -> subprocess.CompletedProcess:
    return subprocess.run(cmd, capture_output=True, text=True, **kw)


def build_venv(work: Path, wheel: Path | None) -> Path:
    """A new venv in ``work`` with mpz installed from a wheel (built from the repo if none)."""
    if wheel is None:
        r = _run([sys.executable, "-m", "pip", "wheel", str(REPO), "--no-deps", "-q",
                  "-w", str(work / "whl")])
        wheels = sorted((work / "whl").glob("mpz-*.whl"))
        if r.returncode or not wheels:
            raise Skip(f"cannot build a wheel: {r.stderr.strip().splitlines()[-1:]}")
        wheel = wheels[-1]
    venv = work / "venv"
    r = _run([sys.executable, "-m", "venv", str(venv)])
    if r.returncode:
        raise Skip(f"cannot create a venv: {r.stderr.strip()}")
    py = venv / "bin" / "python"
    pins = []
    for d in DEPS:
        try:
            pins.append(f"{d}=={metadata.version(d)}")
        except metadata.PackageNotFoundError:
            pins.append(d)
    r = _run([str(py), "-m", "pip", "install", "-q", *pins])
    if r.returncode == 0:
        r = _run([str(py), "-m", "pip", "install", "-q", "--no-deps", str(wheel)])
    if r.returncode:
        raise Skip(f"cannot install into the venv: {r.stderr.strip().splitlines()[-1:]}")
    return py


def site_of(py: Path) -> Path:
    r = _run([str(py), "-c", "import os, mpz; print(os.path.dirname(os.path.dirname("
                             "os.path.abspath(mpz.__file__))))"])
    if r.returncode:
        raise Skip(f"{py} cannot import mpz: {r.stderr.strip().splitlines()[-1:]}")
    return Path(r.stdout.strip())


class ReadOnly:
    """Runs commands with ``site`` read-only (see the module docstring)."""

    def __init__(self, site: Path, pkg: Path):
        self.site, self.pkg, self.prefix = site, pkg, []
        self.chmodded = False
        if os.geteuid() == 0 and shutil.which("unshare"):
            s = str(site)
            self.prefix = ["unshare", "-m", "sh", "-c",
                           f'mount --bind "{s}" "{s}" && mount -o remount,ro,bind "{s}" "{s}"'
                           ' && exec "$0" "$@"']
        elif os.geteuid() != 0:
            _run(["chmod", "-R", "a-w", str(pkg)])
            self.chmodded = True
        probe = ("import sys, tempfile\ntry:\n    tempfile.TemporaryFile(dir=sys.argv[1])\n"
                 "except OSError:\n    print('ro')\nelse:\n    print('rw')")
        r = _run([*self.prefix, sys.executable, "-c", probe, str(pkg)])
        self.label = "ro site" if r.stdout.strip() == "ro" else "WRITABLE site"

    def run(self, cmd: list[str], env: dict[str, str]) -> tuple[float, float] | str:
        """(wall, CPU) seconds, or the last line of stderr if the command failed."""
        c = resource.getrusage(resource.RUSAGE_CHILDREN)
        t = time.perf_counter()
        r = subprocess.run([*self.prefix, *cmd], env=env, capture_output=True, text=True)
        dt = time.perf_counter() - t
        c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        if r.returncode:
            return (r.stderr.strip().splitlines() or [f"exit {r.returncode}"])[-1]
        return dt, (c1.ru_utime - c.ru_utime) + (c1.ru_stime - c.ru_stime)

    def restore(self) -> None:
        if self.chmodded:
            _run(["chmod", "-R", "u+w", str(self.pkg)])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--python", type=Path, help="an interpreter with mpz installed")
    ap.add_argument("--wheel", type=Path, help="install this wheel instead of building one")
    ap.add_argument("--input", type=Path, help="motion file (default: cmu_02_01.c3d)")
    ap.add_argument("--runs", type=int, default=3, help="runs per case (first + warm ones)")
    ap.add_argument("--json", type=Path, help="also write the rows here")
    ap.add_argument("--keep", action="store_true", help="keep the temporary directory")
    args = ap.parse_args()
    src = args.input
    if src is None:
        d = shared_data_dir()
        if d is None:
            print(f"skipped: {shared_data_name()} is absent (or give --input)")
            return 0
        src = d / "c3d" / "cmu_02_01.c3d"
    work = Path(tempfile.mkdtemp(prefix="mpz-coldstart-"))
    ro = None
    try:
        try:
            py = args.python or build_venv(work, args.wheel)
            site = site_of(py)
        except Skip as e:
            print(f"skipped: {e}")
            return 0
        ro = ReadOnly(site, site / "mpz")
        mpz_cli = [str(py), "-m", "mpz.tools.mpz_cli"]
        base = {k: v for k, v in os.environ.items()
                if k not in ("MPZ_CACHE_DIR", "NUMBA_CACHE_DIR", "XDG_CACHE_HOME",
                             "PYTHONPATH", "VIRTUAL_ENV")}
        (work / "out").mkdir()
        (work / "file").write_bytes(b"")
        packed = work / "out" / "input.mpz"
        # the decode input, made outside the measured cases with a cache of its own
        made = ro.run([*mpz_cli, "encode", "-q", "-f", str(src), "-o", str(packed)],
                      {**base, "HOME": str(work / "prep")})
        if isinstance(made, str):
            print(f"skipped: cannot encode {src}: {made}")
            return 0
        ops = {"encode": ["encode", "-q", "-f", str(src), "-o", str(work / "out" / "a.mpz")],
               "decode": ["decode", "-q", "-f", str(packed), "-o", str(work / "out" / "a.c3d")],
               # the summary's kernels, shipped since stop 62 (a first --summary compiled
               # them for 2.5-4 s)
               "summary": ["encode", "-q", "-f", str(src), "-o", str(work / "out" / "s.mpz"),
                           "--summary", "6,12,24,48"]}
        rows = []
        load0 = os.getloadavg()
        for case in ("cache in HOME", "no cache dir"):
            for op, cmd in ops.items():
                if case == "cache in HOME":
                    home = work / f"home-{op}"
                    home.mkdir()
                else:
                    home = work / "file" / "home"
                env = {**base, "HOME": str(home)}
                if case == "no cache dir":
                    env["XDG_CACHE_HOME"] = str(home)
                if args.python is not None and case == "cache in HOME":
                    # an existing install may be writable: numba's own setting sends both
                    # old and new code to an empty directory
                    env["NUMBA_CACHE_DIR"] = str(home / "numba")
                times = [ro.run([*mpz_cli, *cmd], env) for _ in range(max(2, args.runs))]
                failed = [t for t in times if isinstance(t, str)]
                row: dict = {"case": f"{ro.label}, {case}", "op": op, "runs": times}
                if failed:
                    row["error"] = failed[0]
                else:
                    wall = [t[0] for t in times if not isinstance(t, str)]
                    cpu = [t[1] for t in times if not isinstance(t, str)]
                    warm, warm_cpu = statistics.median(wall[1:]), statistics.median(cpu[1:])
                    row.update(first=wall[0], warm=warm, extra=wall[0] - warm,
                               first_cpu=cpu[0], warm_cpu=warm_cpu,
                               extra_cpu=cpu[0] - warm_cpu)
                rows.append(row)
        load1 = os.getloadavg()
        # mpz.identity()'s digest of the installed sources: once per process, on a corpus
        # run's first check and in each Dask worker (tests/test_identity.py checks only
        # that it is cached; its time is measured here, not asserted)
        fp = _run([str(py), "-c", "import time\nfrom mpz._identity import source_digest, "
                   "source_roots\nts = []\nfor _ in range(5):\n    t = time.perf_counter()"
                   "\n    source_digest(source_roots())\n    ts.append(time.perf_counter() "
                   "- t)\nprint(min(ts))"], env={**base, "HOME": str(work / "prep")})
        fingerprint = float(fp.stdout) if fp.returncode == 0 else None
    finally:
        if ro is not None:
            ro.restore()
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
        else:
            print(f"kept {work}")
    print(f"cold start, {src.name}, {os.cpu_count()} CPUs, load average "
          f"{load0[0]:.1f} before, {load1[0]:.1f} after")
    print(f"{'':<40} {'wall clock, s':^26} {'CPU time, s':^26}")
    print(f"{'case':<32} {'op':<7} " + f"{'first':>8} {'warm':>8} {'extra':>8} " * 2)
    for r in rows:
        if "error" in r:
            print(f"{r['case']:<32} {r['op']:<7} fails: {r['error'][:60]}")
        else:
            print(f"{r['case']:<32} {r['op']:<7} {r['first']:>8.2f} {r['warm']:>8.2f} "
                  f"{r['extra']:>8.2f} {r['first_cpu']:>8.2f} {r['warm_cpu']:>8.2f} "
                  f"{r['extra_cpu']:>8.2f}")
    print("source fingerprint (mpz.identity, once per process and Dask worker): "
          + (f"{fingerprint * 1e3:.1f} ms, best of 5" if fingerprint is not None
             else f"fails: {fp.stderr[-200:]}"))
    if args.json:
        args.json.write_text(json.dumps({"input": str(src), "load": [load0, load1],
                                         "rows": rows, "fingerprint_seconds": fingerprint},
                                        indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
