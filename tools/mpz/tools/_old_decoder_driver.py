"""Run an old revision's decoder on MPZ files: the half of
:mod:`mpz.tools.check_old_decoders` that runs in the old code's process.

Run as a script, never imported by today's code::

    python -I _old_decoder_driver.py SITE CASES.json OUT/

SITE holds the old ``mpz`` package (built by ``check_old_decoders`` from the revision's
tree). This file imports nothing of today's ``mpz``: it takes the old one from SITE,
first removing the import hook of an editable install of today's (setuptools puts its
finder at the end of ``sys.meta_path``, where it would answer for any module the old
tree lacks), and at the end lists every ``mpz`` module loaded from anywhere but SITE, so
that a mixed run is reported, not trusted.

For each case of CASES.json (``{"name": ..., "path": ...}``) it writes ``OUT/NAME.npy``
(the decoded positions, float64 [frames, markers, 3], NaN at gaps) and one line of
``OUT/results.jsonl``: the names, rate (as ``float.hex``), units and meta the old
``mpz.decode`` returned, or the exception it raised, and the exit status and messages of
the old ``mpzinfo -v`` on the same file.
"""
from __future__ import annotations

import contextlib
import json
import os
from pathlib import Path
import sys
import tempfile
import time
import traceback


def isolate(site: str) -> None:
    """Make ``import mpz`` find the old package in ``site`` and nothing else."""
    sys.meta_path[:] = [f for f in sys.meta_path
                        if not type(f).__module__.startswith("__editable__")
                        and not getattr(f, "__module__", "").startswith("__editable__")]
    sys.path_hooks[:] = [h for h in sys.path_hooks
                         if "__editable__" not in getattr(h, "__module__", "")
                         and "__editable__" not in getattr(h, "__qualname__", "")]
    sys.path[:] = [site] + [p for p in sys.path if "__editable__" not in p and p != site]
    sys.path_importer_cache.clear()
    for name in [n for n in sys.modules if n == "mpz" or n.startswith("mpz.")]:
        del sys.modules[name]


def foreign_modules(site: str) -> list[str]:
    """The loaded ``mpz`` modules that do not come from ``site``."""
    root = os.path.realpath(site) + os.sep
    out = []
    for name, mod in sorted(sys.modules.items()):
        if name != "mpz" and not name.startswith("mpz."):
            continue
        where = getattr(mod, "__file__", None)
        if where is None:       # a namespace package: it could span today's tree too
            out.append(f"{name} (no __file__: {list(getattr(mod, '__path__', []))})")
        elif not os.path.realpath(where).startswith(root):
            out.append(f"{name} ({where})")
    return out


@contextlib.contextmanager
def captured_fds():
    """Standard output and error at the descriptor level, whatever the code writes through
    (sys.stdout, its buffer, or fd 1 itself); yields a dict filled on exit."""
    got: dict[str, str] = {}
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        os.dup2(out.fileno(), 1)
        os.dup2(err.fileno(), 2)
        try:
            yield got
        finally:
            with contextlib.suppress(Exception):
                sys.stdout.flush()
            with contextlib.suppress(Exception):
                sys.stderr.flush()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])
            for key, fh in (("stdout", out), ("stderr", err)):
                fh.seek(0)
                got[key] = fh.read().decode("utf-8", "replace")


def _error(exc: BaseException) -> dict:
    try:
        from mpz.errors import MPZError
        rejected = isinstance(exc, MPZError)     # a rejection, not a crash
    except ImportError:
        rejected = False
    return {"type": type(exc).__name__, "message": str(exc)[:2000], "mpz_error": rejected,
            "traceback": "".join(traceback.format_exception(exc))[-4000:]}


def decode_case(path: str, out_npy: Path) -> dict:
    import numpy as np

    import mpz
    data = Path(path).read_bytes()
    t0 = time.perf_counter()
    try:
        m = mpz.decode(data)
    except Exception as exc:   # any failure of the old decoder is a finding
        return {"decoded": False, "error": _error(exc), "seconds": time.perf_counter() - t0}
    seconds = time.perf_counter() - t0
    pos = np.array(m.positions, dtype=np.float64, copy=True)
    pos[~np.asarray(m.valid, dtype=bool)] = np.nan
    np.save(out_npy, pos, allow_pickle=False)
    return {"decoded": True, "seconds": seconds, "names": [str(n) for n in m.names],
            "rate": float(m.rate).hex(), "units": str(m.units),
            "metadata": {str(k): str(v) for k, v in dict(m.metadata).items()}}


def mpzinfo_case(path: str) -> dict:
    try:
        from mpz.tools import mpzinfo
    except ImportError as exc:     # a revision older than its mpzinfo (ff060a2)
        return {"status": None, "absent": f"{type(exc).__name__}: {exc}"}
    t0 = time.perf_counter()
    with captured_fds() as got:
        try:
            status = mpzinfo.main(["-v", path])
        except SystemExit as exc:
            status = exc.code if isinstance(exc.code, int) else 1
        except Exception as exc:   # a crash of the old mpzinfo is a finding
            status = None
            print(traceback.format_exc(), file=sys.stderr)
            got["exception"] = type(exc).__name__
    return {"status": status, "seconds": time.perf_counter() - t0,
            "exception": got.get("exception"),
            "stdout_tail": got["stdout"][-1500:], "stderr_tail": got["stderr"][-3000:]}


def main(argv: list[str]) -> int:
    site, cases_file, out_dir = argv
    isolate(site)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cases = json.loads(Path(cases_file).read_text("utf-8"))
    import mpz
    from mpz.spec import grammar
    head = {"version": getattr(mpz, "__version__", None), "file": mpz.__file__,
            "bitstream": [grammar.VERSION_MAJOR, grammar.VERSION_MINOR]}
    with open(out / "results.jsonl", "w", encoding="utf-8") as fh:
        fh.write(json.dumps({"driver": head}) + "\n")
        fh.flush()
        for case in cases:
            row = {"name": case["name"]}
            row.update(decode_case(case["path"], out / f"{case['name']}.npy"))
            row["mpzinfo"] = mpzinfo_case(case["path"])
            fh.write(json.dumps(row) + "\n")
            fh.flush()
        fh.write(json.dumps({"foreign_modules": foreign_modules(site)}) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
