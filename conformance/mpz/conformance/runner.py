"""mpz-conformance: run a decoder (or an encoder) against the MPZ conformance vectors.

Contract (conformance/README.md has the full text):

* decoder mode: for every vector the runner executes ``CMD IN.mpz OUT.npy``
  (CMD split with :func:`shlex.split`). A decoder accepts a file by writing
  float64 ``[frames, markers, 3]`` with NaN at gaps, plus ``OUT.npy.json``
  (names, rate, units code, meta: spec §7.3) and exiting 0; it rejects one by a
  clean non-zero exit. Gap positions must match exactly, every value must be
  within max_abs and the RMS within rms (no slack), and the sidecar must be
  equal. If it also writes ``OUT.npy.intlayer`` (the hex integer-layer digest
  of spec §7.1) that digest must match exactly: Opus style, the integer tier is
  exact and the float tier is within tolerance. ``--array-only`` keeps the
  contract of the spec's 1.0 text (no sidecar); ``--implements 1.0`` judges a decoder of
  MPZ 1.0 alone, which skips the 1.1 chunks (:func:`as_read_by`). A decoder killed by a
  signal (or whose shell reports 128 + a fatal signal), past its time limit or out of
  memory fails the vector whatever its group: a crash is not a rejection (§8).
* encoder mode: for every input motion and requested bound E the runner
  executes ``CMD IN.npy OUT.mpz --max-error E`` and checks OUT.mpz with the
  reference decoder: declared bound <= E, every valid sample within it, gaps
  kept as gaps, names/rate/units kept.

Every vector is run (each with a timeout and an address-space limit, in its own
process group, killed when it exits) before anything is reported; Ctrl-C kills
what runs and exits 130. Exit status (the table shared with ``mpz`` and
``mpzinfo``, :mod:`mpz.tools._cli`): 0 all passed, 1 any failure, 64 usage
error (bad arguments, missing or invalid vectors, command not found, a script the
system cannot start (no ``#!`` line, or one naming no program), a ``--results`` path
that cannot be written, an encoder input the contract does not allow: not run, the
others run and are reported).
"""
from __future__ import annotations

import argparse
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
import contextlib
import difflib
import hashlib
import json
import math
import os
from pathlib import Path
import re
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from typing import Any
import unicodedata
import warnings

import numpy as np

try:
    import resource
except ImportError:          # not POSIX: no memory limit
    resource = None  # type: ignore[assignment]

from mpz.conformance import manifest as mf
from mpz.conformance.refdecoder import implemented_minor
from mpz.errors import MPZError
from mpz.format import MM_PER_UNIT
from mpz.spec.grammar import VERSION_MAJOR, VERSION_MINOR
from mpz.tools._cli import EXIT_FAILED as EXIT_FAIL
from mpz.tools._cli import (
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_USAGE,
    Parser,
    add_version,
    found,
    printable,
    quiet_broken_pipe,
    reports_ctrl_c,
)

RESULTS_SCHEMA_VERSION = 5          # 2: sidecar, contract, peak_rss_mb, actual 'memory';
#                                     3: implements; 4: judged_as; 5: notes (encoder
#                                     mode), totals.not_run
STDERR_TAIL = 2000          # characters of the decoder's stderr kept per vector
FAIL_LIST = 10              # differing samples listed per vector


#: the largest --memory (MiB) whose byte count setrlimit takes
MAX_MEMORY_MB = 1 << 40


class UsageError(Exception):
    pass


def _suggestions(unknown: list[str], names: list[str], most: int) -> str:
    """``; U: did you mean A or B?`` for each ``--only`` entry U that named nothing: the
    ``names`` it begins (at most ``most``; an encoder run's ``@E`` and ``encoder/`` or
    ``inputs/`` set aside), else those it nearly spells, as ``mpz`` suggests a subcommand
    ("--only v09" named nothing and said so alone: QA runs of stop 71)."""
    hints = []
    for u in unknown:
        bare = u.removeprefix("encoder/").removeprefix("inputs/")
        close = ([k for k in names if k.startswith(bare.split("@")[0])][:most] or
                 difflib.get_close_matches(bare, names, n=3, cutoff=0.6))
        if close:
            hints.append(f"; {u}: did you mean {' or '.join(close)}?")
    return "".join(hints)


def _selects(only: str, name: str, E: float) -> bool:
    """Whether an encoder ``--only`` entry names this input (``name``) or this run
    (``name@E``, E compared as a number: ``@1``, ``@1.0``, ``@1e0`` alike), also as the
    runner prints it (``encoder/name@E``) or as its file (``inputs/name.npy``), or names
    the whole group (``encoder``): each of those named nothing (an encoder QA run of stop
    71)."""
    if only == "encoder":
        return True
    only = only.removeprefix("encoder/").removeprefix("inputs/").removesuffix(".npy")
    if only == name:
        return True
    base, at, e = only.rpartition("@")
    if not at or base != name:
        return False
    try:
        return float(e) == E
    except ValueError:
        return False


def _rms(diff: np.ndarray) -> float:
    """The root mean square of the differences ``diff`` (0 for none), scaled by their
    largest first: squared, a difference above about 1.3e154 overflowed to inf, and a
    decoder one ulp off on u15 and u16 failed with "rms error inf" (a QA run of stop 50)."""
    top = float(diff.max(initial=0.0))
    if not diff.size or top == 0.0 or not math.isfinite(top):
        return top if diff.size else 0.0
    return top * math.sqrt(float(((diff / top) ** 2).mean()))


def _distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The Euclidean distance of each xyz of ``a`` and ``b`` (``[..., 3]``), scaled by the
    largest component as :func:`_rms` is (np.linalg.norm squares them unscaled)."""
    with np.errstate(over="ignore", invalid="ignore"):
        d = np.abs(a - b)
        top = d.max(axis=-1)
        safe = np.where(top > 0, top, 1.0)
        return np.where(top > 0, top * np.sqrt(((d / safe[..., None]) ** 2).sum(axis=-1)),
                        top)


# ------------------------------------------------------------ subprocesses --
def _limits(memory_mb):
    def apply():
        # runs in the child between fork and exec: no imports, no locks
        try:
            if memory_mb:
                lim = int(memory_mb) * 1024 * 1024
                resource.setrlimit(resource.RLIMIT_AS, (lim, lim))
            resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
            # no file a command writes past MAX_FILE_BYTES: a runaway one filled the
            # temporary folder's disk within its timeout (a QA run of stop 50)
            resource.setrlimit(resource.RLIMIT_FSIZE, (MAX_FILE_BYTES, MAX_FILE_BYTES))
        except (ValueError, OSError):
            pass
    return apply


#: the largest file a decoder or encoder under test may write (RLIMIT_FSIZE): past it the
#: command gets SIGXFSZ, a crash. The largest expected output of the vectors is 6.3 MB
#: (x265-smrc-segments-over-limit as a 1.0 decoder reads it).
MAX_FILE_BYTES = 4 << 30

#: set when the runner is interrupted (Ctrl-C): every command running is killed, and none
#: is started after it
STOP = threading.Event()

#: the most the runner reads of what a decoder or encoder under test wrote beside the array
#: (the JSON sidecar, the integer-layer digest) and of an encoder's MPZ output: the
#: vectors are small, and a 1.5 GB sidecar took the runner to 3.2 GB (QA, stop 33)
MAX_SIDECAR_BYTES = 16 << 20
MAX_DIGEST_BYTES = 4096
MAX_ENCODED_BYTES = 256 << 20


def _read_capped(path: Path, limit: int) -> bytes | None:
    """The bytes of ``path`` (:func:`mpz.api.read_source`), or None when it holds more
    than ``limit`` (then nothing is read)."""
    from mpz.api import read_source
    from mpz.errors import LimitExceededError
    try:
        return read_source(path, limit=limit)[0]
    except LimitExceededError:
        return None

#: bytes of a command's output kept (its tail): the rest is read and dropped, so that a
#: decoder that prints gigabytes costs the runner no memory
OUTPUT_KEEP = 4 * STDERR_TAIL


def _tail(pipe: Any, keep: int, buf: bytearray) -> None:
    """Read ``pipe`` to its end into ``buf``, keeping at least its last ``keep`` bytes (the
    caller takes them, also while this still reads: a pipe that a process of another
    session holds open never ends)."""
    while True:
        chunk = pipe.read1(1 << 16)
        if not chunk:
            break
        buf += chunk
        if len(buf) > 2 * keep:
            del buf[:-keep]


def run_command(argv: list[str], timeout: float, memory_mb: int | None,
                cwd: str | None = None) -> dict[str, Any]:
    """Run ``argv`` with limits.

    Returns the exit code (negative: killed by that signal), seconds, the tail of what it
    printed (stderr and stdout, one stream), ``timed_out``, ``signal`` (its name when
    killed by one), ``interrupted`` (:data:`STOP`) and ``peak_rss_mb`` (the child's peak
    resident memory, from ``wait4``; None where unavailable). The command runs in a new
    process group, which is killed when the command ends: a child it left behind is not
    left running (one that starts its own session is beyond reach).
    """
    t0 = time.perf_counter()
    if STOP.is_set():
        return {"exit_code": None, "seconds": 0.0, "stderr": "not run: interrupted",
                "timed_out": False, "signal": None, "peak_rss_mb": None, "interrupted": True}
    try:
        proc = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, cwd=cwd, start_new_session=True,
                                preexec_fn=_limits(memory_mb) if resource else None)
    except OSError as exc:
        return {"exit_code": None, "seconds": 0.0, "stderr": f"cannot start: {exc}",
                "timed_out": False, "signal": None, "peak_rss_mb": None,
                "interrupted": False}
    timed_out = interrupted = False
    peak = None
    note = ""
    if hasattr(os, "wait4"):
        # read the output in a thread and reap the child with wait4, which also gives its
        # rusage
        buf = bytearray()
        reader = threading.Thread(target=_tail, args=(proc.stdout, OUTPUT_KEEP, buf),
                                  daemon=True)
        reader.start()
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if STOP.is_set() or time.perf_counter() - t0 >= timeout:
                interrupted = STOP.is_set()
                timed_out = not interrupted
                _kill_group(proc)
                pid, status, usage = os.wait4(proc.pid, 0)
                break
            time.sleep(0.005)
        proc.returncode = os.waitstatus_to_exitcode(status)
        _kill_group(proc)              # what it left running in its group (it holds the pipe)
        # ru_maxrss is in KiB on Linux, in bytes on macOS
        peak = round(usage.ru_maxrss / (1 << 20 if sys.platform == "darwin" else 1 << 10), 1)
        reader.join(timeout=5.0)
        err = bytes(buf[-OUTPUT_KEEP:])
        if reader.is_alive():
            # a process it started in a session of its own holds the output open: its
            # output was lost and 5 s waited, with no word (a QA run of stop 55). Said
            # apart from the output, which failure_kind reads by its last line
            note = ("[mpz-conformance: the output stayed open 5 s after the command "
                    "exited: a process it started in a session of its own holds it; what "
                    "it printed after this is not read]")
    else:                               # no wait4 (Windows): no memory figure
        try:
            err, _ = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            timed_out = True
            _kill_group(proc)
            err, _ = proc.communicate()
        err = err[-OUTPUT_KEEP:]
    secs = time.perf_counter() - t0
    code = proc.returncode
    sig = None
    if code is not None and code < 0:
        try:
            sig = signal.Signals(-code).name
        except ValueError:
            sig = f"signal {-code}"
    text = err.decode("utf-8", "replace")
    return {"exit_code": code, "seconds": round(secs, 3),
            "stderr": text[-STDERR_TAIL:], "timed_out": timed_out, "signal": sig,
            "peak_rss_mb": peak, "interrupted": interrupted, "note": note}


def _kill_group(proc: subprocess.Popen[bytes]) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except OSError:
        proc.kill()


#: below this --memory (MiB), a crash is said to have perhaps come from the limit: a shell
#: or a language runtime may need more address space than that to start at all
SMALL_MEMORY_MB = 64

#: exit statuses a shell reports for a child killed by a fatal signal (128 + N): a decoder
#: run through a wrapper script that crashes exits with these, and they count as a crash
SHELL_CRASH_CODES = {128 + int(getattr(signal, n)): n for n in (
    "SIGQUIT", "SIGILL", "SIGTRAP", "SIGABRT", "SIGBUS", "SIGFPE", "SIGKILL", "SIGSEGV",
    "SIGXCPU", "SIGXFSZ", "SIGSYS") if hasattr(signal, n)}
#: every other 128 + N: a shell's report of a child killed by signal N (SIGTERM 143, SIGINT
#: 130, SIGPIPE 141 ...), which spec §7.3 does not count as a rejection either; they passed
#: as "rejected (exit 143)" (a QA run of stop 53)
SHELL_SIGNAL_CODES = {128 + int(s): s.name for s in signal.Signals
                      if 128 + int(s) not in SHELL_CRASH_CODES and 128 + int(s) <= 255}
#: the exit statuses spec §7.3 takes as a rejection
REJECTION_CODES = range(1, 126)
#: a line, anywhere in the output, that only a runtime out of memory prints before its
#: stack trace: C++'s std::bad_alloc, Rust's allocation failure, Go's fatal error, Java's
#: OutOfMemoryError
OUT_OF_MEMORY = re.compile(r"^(.*\bstd::bad_alloc\b|memory allocation of \d+ bytes failed|"
                           r"fatal error: (runtime: )?out of memory|.*\bjava\.lang\."
                           r"OutOfMemoryError\b)")
#: ... and the last line of one whose exception ends its output (Python's MemoryError,
#: numpy's _ArrayMemoryError) or that reports it itself: "out of memory" as the message
#: (after an optional "prog: " prefix), or the C library's ENOMEM text. A sentence that
#: only mentions memory ("it would run out of memory"), or a MemoryError on an earlier
#: line followed by another error, is an orderly rejection.
OUT_OF_MEMORY_LAST = re.compile(r"^([\w.]*MemoryError\b|([\w./ -]+:\s*)?(out of memory|"
                                r"cannot allocate memory)\b)", re.I)
#: a line that a runtime prints when it aborts, not when a program chooses to exit: Python's
#: "Fatal Python error" (a MemoryError while the interpreter starts ends in one, under a
#: small --memory, and exits 1), OpenBLAS's failed thread buffers, and the dynamic
#: loader's failed mapping of a shared library. Such a run passed an invalid vector as
#: "rejected (exit 1)" (a conformance QA run of stop 55)
RUNTIME_ABORT = re.compile(r"^Fatal Python error: ")
#: ... and those that count as its last line only: a decoder that met them, said so and
#: went on to its own rejection is no abort (a review of stop 55: a loader note of an
#: optional library failed every invalid vector)
RUNTIME_ABORT_LAST = re.compile(r"^(.*Memory allocation still failed\b|"
                                r".*failed to map segment from shared object\b)")
#: exit statuses a shell (or exec wrapper) gives when the command cannot be run: 126 not
#: executable, 127 not found; never a decoder's own rejection
CANNOT_RUN_CODES = {126: "found but could not be executed", 127: "not found"}


#: a line of stderr that reports EFBIG (strerror "File too large"): a write that
#: RLIMIT_FSIZE cut off, in a command that removed the partial file (mpz decode does)
TOO_LARGE = re.compile(r"File too large|\bEFBIG\b")


def _cut_off_by_the_file_limit(run: dict[str, Any], folder: Path) -> tuple[str, str] | None:
    """("error", why) when a command that exited non-zero said EFBIG (:data:`TOO_LARGE`)
    or left a file of :data:`MAX_FILE_BYTES` in its working ``folder``: a write cut off by
    RLIMIT_FSIZE. A
    process that ignores SIGXFSZ (Python does) gets EFBIG, and its clean exit passed an
    invalid vector as rejected after it had decoded it (a QA run of stop 53)."""
    if not run["exit_code"]:
        return None
    said = next((ln.strip() for ln in run["stderr"].splitlines() if TOO_LARGE.search(ln)), None)
    if said is not None:          # a command that removed what it had written says so
        return "error", (f"exited {run['exit_code']} after a write past the runner's file "
                         f"size limit ({MAX_FILE_BYTES >> 30} GiB, RLIMIT_FSIZE): "
                         f"{said[:200]}: a write the limit cut off is not a rejection")
    for f in folder.iterdir():
        try:
            size = f.lstat().st_size
        except OSError:
            continue
        if f.is_file() and size >= MAX_FILE_BYTES:
            return "error", (f"wrote {size} bytes to {f.name}, the runner's file size limit "
                             f"({MAX_FILE_BYTES >> 30} GiB, RLIMIT_FSIZE), and exited "
                             f"{run['exit_code']}: a write the limit cut off is not a "
                             "rejection")
    return None


def failure_kind(run: dict[str, Any]) -> tuple[str, str] | None:
    """("timeout" | "crash" | "memory" | "error", why) when a run did not end by a clean exit.

    A clean exit, 0 or a chosen non-zero status, is None: only that counts as a decode or
    a rejection. Killed by a signal (negative exit code), a shell's 128 + N for a fatal
    signal N, running past the time limit or out of memory are failures whatever the
    vector's group: a crash is not a rejection (spec §8).
    """
    code = run["exit_code"]
    if run.get("interrupted"):
        return "error", "interrupted (Ctrl-C)"
    if code is None:
        return "error", run["stderr"]
    if run["timed_out"]:
        return "timeout", "did not finish within the time limit (killed)"
    lines = [ln.strip() for ln in run["stderr"].splitlines() if ln.strip()]
    if run["signal"] or code in SHELL_CRASH_CODES:
        how = (f"killed by {run['signal']}" if run["signal"] else
               f"exit {code} = 128 + {SHELL_CRASH_CODES[code]}, a shell's report of a process "
               "killed by that signal")
        # an uncaught std::bad_alloc and Rust's failed allocation end in abort(): they were
        # told as a crash, the cause dropped (an implementer's QA run of stop 71)
        hit = next((ln for ln in lines if OUT_OF_MEMORY.match(ln)), None)
        if hit is not None:
            return "memory", f"ran out of memory ({how}, after: {hit[:200]})"
        return "crash", how
    if code != 0 and lines:
        hit = next((ln for ln in lines if OUT_OF_MEMORY.match(ln)), None)
        if hit is None and OUT_OF_MEMORY_LAST.match(lines[-1]):
            hit = lines[-1]
        if hit is not None:
            return "memory", f"ran out of memory (exit {code}: {hit[:200]})"
        abort = next((i for i, ln in enumerate(lines) if RUNTIME_ABORT.match(ln)),
                     len(lines) - 1 if RUNTIME_ABORT_LAST.match(lines[-1]) else None)
        if abort is not None:
            if any(OUT_OF_MEMORY_LAST.match(ln) for ln in lines[:abort + 1]):
                return "memory", (f"ran out of memory (exit {code}: "
                                  f"{lines[abort][:200]})")
            return "crash", (f"exit {code} after its runtime aborted ({lines[abort][:200]}), "
                             "not a rejection")
    if code in CANNOT_RUN_CODES:
        return "error", (f"exit {code}: a shell's code for a command {CANNOT_RUN_CODES[code]}, "
                         "not a rejection" + (f" ({lines[-1][:200]})" if lines else ""))
    if code in SHELL_SIGNAL_CODES:
        return "crash", (f"exit {code} = 128 + {SHELL_SIGNAL_CODES[code]}, a shell's report of "
                         "a process killed by that signal, not a rejection (spec §7.3)")
    if code != 0 and code not in REJECTION_CODES:
        return "error", (f"exit {code}: not a rejection, which is an exit status from 1 to 125 "
                         "(spec §7.3)" + (f" ({lines[-1][:200]})" if lines else ""))
    return None


#: a line of an exit that no check of the decoder chose: Python's uncaught exception, a
#: Rust panic, an uncaught Java exception
UNPLANNED_EXIT = re.compile(r"^(Traceback \(most recent call last\):|thread '.*' panicked at |"
                            r"Exception in thread )")


def _tail_of(run: dict[str, Any]) -> str:
    """What a result keeps of a run's output: its tail, and the runner's note on it."""
    return run["stderr"] + (f"\n{run['note']}\n" if run.get("note") else "")


def _uncaught(run: dict[str, Any]) -> str | None:
    """The first line of a run's output that shows an uncaught exception or a panic
    (:data:`UNPLANNED_EXIT`), or None."""
    return next((ln.strip() for ln in run["stderr"].splitlines()
                 if UNPLANNED_EXIT.match(ln.strip())), None)


def _unplanned(run: dict[str, Any]) -> str:
    """A note for a rejection whose output shows an uncaught exception or a panic: spec
    §7.3 counts its exit as a rejection, but it may be a bug that happens to stop on this
    file rather than a check of the spec (a panic and a traceback passed invalid vectors
    with no word: a conformance QA run of stop 55)."""
    hit = _uncaught(run)
    if hit is None:
        return ""
    return (f"; note: its output shows an uncaught exception or a panic ({hit[:120]}), "
            "which may be a bug rather than a check of the spec")


# ----------------------------------------------------------- comparisons --
#: the rule of each check of a decoded output, which its failure leads with: the rules
#: its vector probes (the manifest's) follow, and were alone the pointer before, though 69
#: of the 75 decodable vectors do not probe R-6.8-2 (an implementer's QA run of stop 71)
RULE_ARRAY = "§7.3"                         # OUT.npy itself: float64 [F, M, 3], little-endian
RULE_VALUES = "R-6.8-1 (§7.1 item 3)"       # the values and the NaN pattern
RULE_DIGEST = "§7.1 item 2"                 # the integer-layer digest
RULE_SIDECAR = "R-6.8-2 (§6.8, §7.3)"       # names, rate, units and meta


def _led(tagged: list[tuple[str, str]]) -> str:
    """Problems joined, each run of them led by its rule: ``R-6.8-1 (§7.1 item 3): ...``."""
    out = []
    last = None
    for rule, text in tagged:
        out.append(text if rule == last else f"{rule}: {text}")
        last = rule
    return "; ".join(out)


def _fmt(v: float) -> str:
    """Six decimals, or six significant digits for a value they would not show: a large
    one, or a tiny one ("got 0.000000" for 5.55e-307: a maintainer's QA run of stop 75)."""
    if isinstance(v, float) and math.isnan(v):
        return "NaN"
    return f"{v:.6f}" if v == 0 or 1e-3 <= abs(v) < 1e7 else f"{v:.6g}"


@contextlib.contextmanager
def _numpy_quiet() -> Iterator[None]:
    """numpy's warnings off for the while: reading a decoder's OUT.npy whose header
    declares a huge shape printed its overflow warnings on the runner's stderr."""
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        yield


def _npy_problem(path: Path, exc: Exception) -> str:
    """What is wrong with a decoder's ``OUT.npy`` that numpy could not load, in the terms
    of the format: numpy's own messages misled (a text file "contains pickled (object)
    data", a short one gave "mmap length is greater than file size"; a QA of stop 42)."""
    fmt = np.lib.format
    try:
        size = path.stat().st_size
        with path.open("rb") as fh:
            if fh.read(6) != b"\x93NUMPY":
                return "it does not begin with the NPY magic \\x93NUMPY"
            fh.seek(0)
            version = fmt.read_magic(fh)
            with _numpy_quiet():
                shape, _, dtype = (fmt.read_array_header_1_0(fh) if version == (1, 0)
                                   else fmt.read_array_header_2_0(fh))
            start = fh.tell()
    except Exception as why:            # the header itself is unreadable: the decoder's
        return f"its header cannot be read ({type(why).__name__}: {why})"[:500]
    if dtype.hasobject:
        return f"it holds Python objects ({dtype}), which are not read (no pickles)"
    need = math.prod(int(n) for n in shape) * dtype.itemsize
    if need > size - start:
        return (f"its header declares shape {tuple(shape)} of {dtype.str}, {need} bytes of "
                f"data, and the file holds {size - start}")
    return f"{type(exc).__name__}: {exc}"[:500]


def _pair(got: float, expected: float) -> tuple[str, str]:
    """Two values as :func:`_fmt` writes them, or to 17 significant digits where that
    would show them the same (an FMA or a float32 intermediate is off by less than the 6
    decimals: "got 1673.000000, expected 1673.000000" showed nothing wrong, a QA of stop
    42)."""
    a, b = _fmt(got), _fmt(expected)
    return (a, b) if a != b or got == expected else (f"{got:.17g}", f"{expected:.17g}")


def _where(idx, names):
    f, m, a = (int(i) for i in idx)
    name = names[m] if names and m < len(names) else "?"
    return f"frame {f}, marker {name!r} (index {m}), axis {'xyz'[a]}", f, m, a


def _other_byte_order(got: np.ndarray, exp: np.ndarray, max_abs: float) -> bool:
    """Whether ``got``, read in the other byte order, has ``exp``'s gaps and values within
    ``max_abs``, where as read it has not: a decoder that wrote big-endian float64 under a
    little-endian header."""
    if got.size == 0:
        return False
    ok = ~np.isnan(exp)

    def fits(x: np.ndarray) -> bool:
        return np.array_equal(np.isnan(x), ~ok) and bool((np.abs(x[ok] - exp[ok])
                                                          <= max_abs).all())
    with np.errstate(over="ignore", invalid="ignore"):
        # as read first: a passing output is not swapped (every vector is compared)
        return not fits(got) and fits(got.byteswap())


def compare_output(got: np.ndarray, exp: np.ndarray, vec: dict) -> dict:
    """Float-tier comparison of a decoded array with the expected one."""
    tol = vec["tolerances"]
    res = {"max_abs": None, "rms": None, "allowed_max_abs": tol["max_abs"],
           "allowed_rms": tol["rms"], "first_failure": None, "problems": [], "rules": []}
    # each problem's rule (:data:`RULE_ARRAY`, :data:`RULE_VALUES`), in "rules", one a problem
    _judge_array(got, exp, vec, res)
    res["rules"] += [RULE_VALUES] * (len(res["problems"]) - len(res["rules"]))
    return res


def _judge_array(got: np.ndarray, exp: np.ndarray, vec: dict, res: dict) -> None:
    """:func:`compare_output`'s checks, into ``res``: the problems of the array's form
    (dtype, shape, byte order) with their rule in ``res["rules"]``, then those of its
    values, whose rule the caller adds."""
    hdr = vec["header"]
    tol = vec["tolerances"]
    names = hdr.get("names") or []
    step = float(hdr["step"])
    if got.dtype != np.float64:
        res["problems"].append(f"output dtype {got.dtype} != float64 (the contract requires "
                               f"float64 little-endian .npy)")
        res["rules"].append(RULE_ARRAY)
        return
    if got.shape != exp.shape:
        res["problems"].append(f"shape {tuple(got.shape)} != expected {tuple(exp.shape)} "
                               f"(frames, markers, 3)")
        res["rules"].append(RULE_ARRAY)
        return
    gnan, enan = np.isnan(got), np.isnan(exp)
    if _other_byte_order(got, exp, tol["max_abs"]):
        # the values written big-endian under a '<f8' header were told as a NaN pattern
        # or values that differ (a conformance QA run of stop 55)
        res["problems"].append("the values are in the other byte order: the array read "
                               "big-endian is the expected one, but the .npy header says "
                               "little-endian ('<f8'); write the values little-endian (or "
                               "a header that says '>f8', which the contract refuses too)")
        res["rules"].append(RULE_ARRAY)
        return
    if (gnan != enan).any():
        idx = np.argwhere(gnan != enan)
        where, f, m, a = _where(idx[0], names)
        what = ("NaN (gap) where a value was expected" if gnan[tuple(idx[0])]
                else f"{_fmt(float(got[tuple(idx[0])]))} where a gap (NaN) was expected")
        res["problems"].append(f"NaN pattern differs at {len(idx)} coordinate(s); first at "
                               f"{where}: got {what}")
        res["first_failure"] = {"frame": f, "marker": m, "marker_name": names[m] if m < len(names)
                                else None, "axis": "xyz"[a], "got": None if gnan[tuple(idx[0])]
                                else float(got[tuple(idx[0])]), "expected": None if
                                enan[tuple(idx[0])] else float(exp[tuple(idx[0])]), "off_by": None,
                                "grid_steps": None}
        return
    ok = ~enan
    if np.isinf(got[ok]).any():
        idx = np.argwhere(np.isinf(got) & ok)[0]
        where, *_ = _where(idx, names)
        res["problems"].append(f"infinite value at {where}")
        return
    diff = np.zeros_like(exp)
    with np.errstate(over="ignore"):     # a huge wrong value: inf, reported as such
        diff[ok] = np.abs(got[ok] - exp[ok])
        res["max_abs"] = float(diff.max(initial=0.0))
        res["rms"] = _rms(diff[ok])
    bad = diff > tol["max_abs"]
    if bad.any():
        idx = np.argwhere(bad)
        lines = []
        for k, i in enumerate(idx[:FAIL_LIST]):
            where, f, m, a = _where(i, names)
            g, e = float(got[tuple(i)]), float(exp[tuple(i)])
            off = g - e
            steps = off / step
            gs, es = _pair(g, e)
            lines.append(f"{where}: got {gs}, expected {es} (off by {off:.6g} = "
                         + (f"{steps:.3f}" if 1e-3 <= abs(steps) < 1e7 else f"{steps:.3g}")
                         + " grid steps)")
            if k == 0:
                res["first_failure"] = {"frame": f, "marker": m,
                                        "marker_name": names[m] if m < len(names) else None,
                                        "axis": "xyz"[a], "got": g, "expected": e,
                                        "off_by": off, "grid_steps": off / step}
        more = f" (and {len(idx) - FAIL_LIST} more)" if len(idx) > FAIL_LIST else ""
        # most of them a fraction of a step off: values not on the file's grid, such as the
        # joint positions `mpz decode` writes for a BVH or AMC file (QA, stop 71)
        with np.errstate(all="ignore"):
            steps_off = (got[bad] - exp[bad]) / step
            part = np.abs(steps_off - np.round(steps_off))
        grid = (" (most are a fraction of a grid step off, off the file's grid: not the "
                "§6.8 marker layer, offset + q × step?)"
                if len(idx) >= 2 and float(np.mean(part > 0.01)) > 0.5 else "")
        res["problems"].append(f"{len(idx)} coordinate(s) beyond max_abs {tol['max_abs']:.3g}"
                               f"{grid}: " + "; ".join(lines) + more)
    if res["rms"] > tol["rms"]:
        res["problems"].append(f"rms error {res['rms']:.6g} > allowed {tol['rms']:.3g}")


# ---------------------------------------------------------------- sidecar --
def _json_constant(name: str) -> float:
    raise ValueError(f"{name} is not JSON (RFC 8259)")


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _json(v: Any, n: int = 100) -> str:
    """``v`` as JSON writes it (``null``, ``true``, ``"x"``: a sidecar's value said as
    Python's ``None`` puzzled an implementer of another language, QA of stop 71), cut to
    ``n`` characters."""
    try:
        t = json.dumps(v, ensure_ascii=False)
    except (TypeError, ValueError):
        t = repr(v)
    return t if len(t) <= n else t[:n] + "..."


def _fold(text: str) -> str:
    """``text`` as it prints, near enough: NFKC, without format and control characters."""
    return "".join(c for c in unicodedata.normalize("NFKC", text)
                   if unicodedata.category(c) not in ("Cf", "Cc", "Zl", "Zp"))


def _said(got: str, want: str) -> tuple[str, str]:
    """Two strings that differ, as a message quotes them: with their code points when they
    print alike (Unicode normalisation, an invisible character): "names[4] = 'é' != expected
    'é'" showed nothing (an implementer's QA run of stop 71)."""
    a, b = repr(got)[:100], repr(want)[:100]
    if got == want or _fold(got) != _fold(want):
        return a, b

    def points(t: str) -> str:
        return " ".join(f"U+{ord(c):04X}" for c in t[:24]) + (" ..." if len(t) > 24 else "")
    return f"{a} ({points(got)})", f"{b} ({points(want)})"


#: the members of the decoder's sidecar (spec §7.3)
SIDECAR_MEMBERS = ("names", "rate", "units", "meta")


def _missing_member(key: str, doc: dict[str, Any]) -> str:
    """A member of the sidecar that ``doc`` lacks, said in JSON terms, with the member it
    holds that may be it misnamed (``units_code``, the manifest's name)."""
    others = [k for k in doc if k not in SIDECAR_MEMBERS]
    close = ([k for k in others if key in k.lower()] or
             difflib.get_close_matches(key, others, n=1, cutoff=0.6))
    return (f"sidecar member {_json(key)} missing"
            + (f" (found {_json(close[0])})" if close else "")
            + (": write {} when the file has no meta chunk" if key == "meta" else ""))


def compare_sidecar(path: Path, vec: dict[str, Any]) -> tuple[str, list[str]]:
    """Spec §7.3: compare ``OUT.npy.json`` with the manifest's expected result.

    Returns (status, problems), status ``match``, ``mismatch``, ``missing`` or
    ``unreadable``. Names, units and meta must be equal exactly (strings as code points),
    and the rate, read as binary64, must be the same binary64 as MHDR.rate. Problems are
    said in JSON's terms: a member missing (or misnamed), ``null``, a member twice.
    """
    hdr = vec["header"]
    if not path.is_file():
        # OUT.json for OUT.npy: the encoder contract's IN.json replaces .npy (QA, stop 71)
        other = path.with_name(Path(path.stem).stem + ".json")
        return "missing", [f"no {path.name}"
                           + (f" ({other.name} exists: the decoder's sidecar name is OUT.npy "
                              "with .json appended, where the encoder contract's IN.json "
                              "replaces .npy)" if other.is_file() else "")
                           + ": the decoded result's names, rate, units and meta "
                           "are part of the contract (spec §7.3; --array-only checks the array "
                           "alone)"]
    raw = _read_capped(path, MAX_SIDECAR_BYTES)
    if raw is None:
        return "unreadable", [f"{path.name} is larger than {MAX_SIDECAR_BYTES} bytes: not read"]
    if raw.startswith(b"\xef\xbb\xbf"):        # Python's advice was "decode using utf-8-sig"
        return "unreadable", [f"{path.name} starts with a UTF-8 byte order mark (EF BB BF), "
                              "which RFC 8259 §8.1 forbids: write none"]
    twice: list[str] = []

    def members(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
        # a member twice: RFC 8259 leaves its meaning open, and C parsers often keep the
        # first where Python keeps the last ("lists 0 names, expected 4": QA, stop 71)
        seen: dict[str, Any] = {}
        for k, v in pairs:
            if k in seen and k not in twice:
                twice.append(k)
            seen[k] = v
        return seen
    try:
        doc = json.loads(raw.decode("utf-8"), parse_constant=_json_constant,
                         object_pairs_hook=members)
    except (ValueError, UnicodeDecodeError, RecursionError) as exc:
        return "unreadable", [f"{path.name} is not UTF-8 JSON: {exc}"]
    if not isinstance(doc, dict):
        return "unreadable", [f"{path.name} is not a JSON object"]
    problems = [f"sidecar has the member {_json(k)} twice (RFC 8259 leaves its meaning open: "
                "write each member once)" for k in twice]
    problems += [_missing_member(k, doc) for k in SIDECAR_MEMBERS if k not in doc]
    names, want = doc.get("names"), list(hdr["names"])
    if "names" not in doc:
        pass
    elif not (isinstance(names, list) and all(isinstance(n, str) for n in names)):
        problems.append(f"sidecar names is not an array of strings: {_json(names, 200)}")
    elif names != want:
        if len(names) != len(want):
            problems.append(f"sidecar lists {len(names)} names, expected {len(want)}")
        else:
            k = next(k for k, (a, b) in enumerate(zip(names, want, strict=True)) if a != b)
            shown, exp = _said(names[k], want[k])
            problems.append(f"sidecar names[{k}] = {shown} != expected {exp} "
                            f"(names compare as exact code points, §4.2)")
    rate: Any = doc.get("rate")
    if "rate" not in doc:
        pass
    elif not _is_number(rate):
        problems.append(f"sidecar rate is not a number: {_json(rate)}")
    else:
        try:
            got = float(rate)
        except OverflowError:
            got = math.inf
        if got != float(hdr["rate"]):
            problems.append(f"sidecar rate {got!r} != expected {float(hdr['rate'])!r} (the exact "
                            f"binary64 of MHDR.rate; write 17 significant digits)")
    units: Any = doc.get("units")
    if "units" not in doc:
        pass
    elif not (_is_number(units) and (isinstance(units, int) or units.is_integer())):
        problems.append(f"sidecar units is not an integer code: {_json(units)} (MHDR's "
                        f"code, {hdr['units_code']} for this file: spec §4.1's table, not "
                        "the unit's name, which the encoder's IN.json uses)")
    elif int(units) != int(hdr["units_code"]):
        problems.append(f"sidecar units {int(units)} != expected code {hdr['units_code']}")
    meta, want_meta = doc.get("meta"), dict(hdr["meta"])
    if "meta" not in doc:
        pass
    elif not (isinstance(meta, dict) and all(isinstance(v, str) for v in meta.values())):
        problems.append(f"sidecar meta is not an object of strings: {_json(meta, 200)}")
    elif meta != want_meta:
        extra, lost = sorted(set(meta) - set(want_meta)), sorted(set(want_meta) - set(meta))
        alike = next(((e, m) for m in lost for e in extra if _fold(e) == _fold(m)), None)
        if alike:
            shown, exp = _said(*alike)
            problems.append(f"sidecar meta has key {shown} where the file holds {exp} (keys "
                            "compare as exact code points)")
        elif lost:
            problems.append(f"sidecar meta lacks key {lost[0]!r} (expected "
                            f"{want_meta[lost[0]]!r:.100})")
        elif extra:
            problems.append(f"sidecar meta has key {extra[0]!r}, which the file does not hold")
        else:
            k = next(k for k in want_meta if meta[k] != want_meta[k])
            shown, exp = _said(meta[k], want_meta[k])
            problems.append(f"sidecar meta[{k!r}] = {shown}, expected {exp} (for a repeated "
                            "key, the last value: §4.11)")
    return ("mismatch" if problems else "match"), problems


def _digest_problem(path: Path, want: str, array_matched: bool) -> str | None:
    """What is wrong with the integer-layer digest file ``path`` (spec §7.1 item 2, §7.3:
    64 hex characters, whitespace around them ignored), None when it holds ``want``. Its
    form is checked first: 32 raw bytes were printed as mojibake, and an empty file as
    '' (an implementer's QA run of stop 71); its bytes are never printed as they are."""
    raw = _read_capped(path, MAX_DIGEST_BYTES)
    if raw is None:
        return f"{path.name} is larger than {MAX_DIGEST_BYTES} bytes: not read"
    text = raw.strip()
    if not text:
        return (f"{path.name} is empty{' but for whitespace' if raw else ''}: write the "
                "digest as 64 hex characters, or no file")
    if not re.fullmatch(rb"[0-9a-fA-F]{64}", text):
        if all(0x20 <= c < 0x7f for c in text):
            what = (f"{len(text)} hex characters" if re.fullmatch(rb"[0-9a-fA-F]+", text) else
                    f"the text {text[:40].decode('ascii')!r}"
                    + (f" ({len(text)} characters)" if len(text) > 40 else ""))
        else:
            what = (f"{len(raw)} bytes that are not ASCII text"
                    + (" (the SHA-256 itself?)" if len(raw) == 32 else ""))
        return f"{path.name} holds {what}, not 64 hex characters: write the digest in hex"
    got = text.decode("ascii").lower()
    if got == want:
        return None
    return (f"integer-layer digest {got} != expected {want} (the integers q and the mask "
            "must be exact" + ("; the array matched: check the digest's layout, q as "
                               "little-endian int64 [F, M, 3] with the gap samples, then the "
                               "mask as one byte per sample [F, M]" if array_matched else "")
            + ")")


# ------------------------------------------------------------ decoder mode --
#: what a failure ends with when a decoder of 1.0 alone would have had to decode the invalid
#: vector it decoded (:func:`as_read_by`), and the summary's note counts
IMPLEMENTS_HINT = "a decoder of 1.0 alone runs with --implements 1.0 (spec §2.1)"


def as_read_by(vec: dict[str, Any], vdir: Path, minor: int
               ) -> tuple[dict[str, Any], np.ndarray | None]:
    """What a decoder of 1.0 .. 1.``minor`` must do with vector ``vec``: (the vector's entry,
    None) when that is what the manifest says, else (an entry with the expectation of such a
    decoder, and its expected array when it must decode).

    The manifest holds the expectations of a decoder of the suite's version (1.1). A decoder
    of an earlier minor version does not know the chunk types added after it: it checks
    their frame and CRC and skips them (spec §2.1, §2.3), so a file that breaks only a rule
    of those chunks is valid for it. Its expectation is the reference decoder's, reading as
    such a decoder (:func:`mpz.decoder.decode_layers` with ``minor``)."""
    from mpz.chunks import CHUNKS
    from mpz.conformance.refdecoder import outputs
    from mpz.container import scan
    from mpz.decoder import decode_layers
    data = (vdir / vec["file"]).read_bytes()
    later = sorted({c.type for c in scan(data).chunks
                    if c.type in CHUNKS and CHUNKS[c.type].MINOR > minor})
    if not later:
        return vec, None
    why = (f"as a 1.{minor} decoder reads it, with {', '.join(later)} unknown "
           f"(spec §2.1, §2.3)")
    try:
        d = decode_layers(data, minor=minor)
    except MPZError as exc:          # the reason such a decoder has (the class informative)
        return dict(vec, expected="reject", expected_error=type(exc).__name__,
                    corruption=f"{why}: {exc}", note=why), None
    x, digest, side = outputs(d)
    if vec["expected"] == "decode" and vec["integer_layer_digest"] == digest:
        return vec, None
    step = float(d.stream.quant.step)
    header = {"names": side["names"], "rate": side["rate"], "units_code": side["units"],
              "meta": side["meta"], "step": step}
    return dict(vec, expected="decode", expected_error=None, corruption=None,
                expected_output=None, integer_layer_digest=digest, header=header,
                tolerances=mf.tolerances(step, float(np.abs(x[d.valid]).max(initial=0.0))),
                note=why), x


def run_decoder_vector(cmd: list[str], vdir: Path, vec: dict[str, Any], timeout: float,
                       memory_mb: int | None, array_only: bool = False,
                       expected_array: np.ndarray | None = None,
                       minor: int = VERSION_MINOR) -> dict[str, Any]:
    """Run the decoder on one vector and judge what it did against ``vec``'s expectation
    (and ``expected_array`` in place of the vector's .npy file, from :func:`as_read_by`,
    whose reason a failure's message ends with), as a decoder of 1.``minor``."""
    entry = _run_decoder_vector(cmd, vdir, vec, timeout, memory_mb, array_only,
                                expected_array)
    # a vector re-judged for an earlier minor version says so whether it passed or not: a
    # pass was told from a pass of the vector as written by nothing (an implementer's QA
    # run of stop 50)
    entry["judged_as"] = vec.get("note")
    rules = ", ".join(vec.get("rules") or [])
    if not entry["passed"] and rules and "(spec §7.4)" not in entry["message"]:
        # every failure names the rules its vector tests, as a wrong acceptance did: a
        # wrong rejection or a wrong output sent an implementer to the manifest to learn
        # which rule of the spec to read (a QA run of stop 53)
        later = vec["expected"] == "decode" and vec.get("group") == "invalid"
        # an output judged and found wrong leads with the rule of the check that failed
        # (:func:`_led`); the vector's own rules follow, as what it probes
        judged = vec["expected"] == "decode" and entry["actual"] == "decode"
        entry["message"] += (f"; vector probes: {rules} (spec §7.4)" if judged else
                             f"; rules {rules} (spec §7.4)") + (
            ", rules of a later minor version than --implements names (spec §2.1)"
            if later else "")
    if not entry["passed"] and minor == VERSION_MINOR and vec["expected"] == "reject" and \
            entry["actual"] == "decode" and as_read_by(vec, vdir, 0)[0]["expected"] == "decode":
        # a 1.0 decoder run as the Quick start shows failed 153 vectors, and nothing
        # named --implements (an implementer's QA run of stop 71); as_read_by, not the
        # rules' (1.1) marks, since x206 and x236 break only 1.1 rules and a 1.0
        # decoder must still reject them
        n = len(vec["rules"])
        entry["message"] += (f"; {'it is a 1.1 rule' if n == 1 else 'they are 1.1 rules'}: "
                             + IMPLEMENTS_HINT)
    if vec.get("note"):
        entry["message"] += f" [judged {vec['note']}]"
    return entry


def _run_decoder_vector(cmd: list[str], vdir: Path, vec: dict[str, Any], timeout: float,
                        memory_mb: int | None, array_only: bool,
                        expected_array: np.ndarray | None) -> dict[str, Any]:
    entry: dict[str, Any] = {
        "name": vec["name"], "group": vec["group"], "file": vec["file"],
        "expected": vec["expected"], "expected_error": vec.get("expected_error"),
        "actual": None, "passed": False, "message": "", "max_abs": None, "rms": None,
        "allowed_max_abs": None, "allowed_rms": None, "intlayer": "absent",
        "sidecar": "not checked", "first_failure": None, "exit_code": None, "signal": None,
        "timed_out": False, "seconds": None, "peak_rss_mb": None, "stderr_tail": ""}
    with tempfile.TemporaryDirectory(prefix="mpz-conf-") as tmp:
        src = Path(tmp) / "in.mpz"
        shutil.copyfile(vdir / vec["file"], src)
        out = Path(tmp) / "out.npy"
        run = run_command(cmd + [str(src), str(out)], timeout, memory_mb, cwd=tmp)
        entry.update(exit_code=run["exit_code"], signal=run["signal"],
                     timed_out=run["timed_out"], seconds=run["seconds"],
                     peak_rss_mb=run["peak_rss_mb"], stderr_tail=_tail_of(run))
        bad = failure_kind(run) or _cut_off_by_the_file_limit(run, Path(tmp))
        if bad is not None:
            # a crash, a hang or running out of memory is never a rejection (§8)
            kind, why = bad
            entry["actual"] = kind
            if kind == "error":
                entry["message"] = why
            else:
                limit = (f"{timeout:g} s" if kind == "timeout" else
                         f"{memory_mb} MB" if kind == "memory" else
                         # a shell or runtime cannot start in a few MiB of address space:
                         # it dies by a signal, which said nothing of the limit (QA, stop 42)
                         f"--memory {memory_mb} MiB, perhaps too little for the command to "
                         f"start" if kind == "crash" and memory_mb and memory_mb < SMALL_MEMORY_MB
                         else "")
                entry["message"] = (f"decoder {why}" + (f" (limit {limit})" if limit else "")
                                    + f"; expected it to {vec['expected']} this file"
                                    + (" with a clean non-zero exit: a crash, a hang or running "
                                       "out of memory is not a rejection (spec §8)"
                                       if vec["expected"] == "reject" else ""))
            return entry
        if vec["expected"] == "reject":
            if run["exit_code"] != 0:
                entry["actual"] = "reject"
                entry["passed"] = True
                entry["message"] = f"rejected (exit {run['exit_code']})" + _unplanned(run)
            else:
                entry["actual"] = "decode"
                # the rules it breaks, by their spec §7.4 IDs: "byte 1 XOR 0x20" alone sent
                # an implementer to the manifest (a QA run of stop 50)
                rules = ", ".join(vec.get("rules") or [])
                # what it wrote and said, and the reference's message with its §: they were
                # in --results alone, and a decoder that printed its rejection and exited 0
                # was told nothing of it (an implementer's QA run of stop 71)
                wrote = out.is_file()
                lines = [ln.strip() for ln in run["stderr"].splitlines() if ln.strip()]
                said = (f"it wrote {'' if wrote else 'no '}{out.name}; "
                        + (f"its output ends: {lines[-1][:160]!r}" if lines else
                           "it printed nothing"))
                ref = None if vec.get("note") else vec.get("reference_message")
                entry["message"] = (f"expected rejection ({vec['corruption']}), but decoder "
                                    f"exited 0 ({said})"
                                    + ("" if wrote else ": a rejection is a non-zero exit "
                                       "status (spec §7.3)")
                                    + f"; the reference raises {vec['expected_error']}"
                                    + (f": {ref[:300]}" if ref else "")
                                    + (f"; rules {rules} (spec §7.4)" if rules else ""))
            return entry
        # expected: decode
        if run["exit_code"] != 0:
            entry["actual"] = "reject"
            tail = run["stderr"].strip().splitlines()
            entry["message"] = (f"expected a decode, but decoder exited {run['exit_code']}"
                                + (f": {tail[-1][:300]}" if tail else ""))
            return entry
        entry["actual"] = "decode"
        if not out.is_file():
            entry["message"] = (f"{RULE_ARRAY}: decoder exited 0 but wrote no output file "
                                f"{out.name}")
            return entry
        try:
            # mapped, not read: a huge output costs the runner no memory before its shape
            # is compared; numpy's overflow warnings on a huge declared shape are its own
            with _numpy_quiet():
                got = np.load(out, mmap_mode="r", allow_pickle=False)
        except Exception as exc:  # any unreadable output is the decoder's failure
            entry["message"] = (f"{RULE_ARRAY}: output is not a readable .npy file: "
                                f"{_npy_problem(out, exc)}")
            return entry
        if not isinstance(got, np.ndarray):     # np.load gives an NpzFile for a zip
            entry["message"] = f"{RULE_ARRAY}: output is not a .npy file (a .npz archive?)"
            return entry
        exp = (expected_array if expected_array is not None else
               np.load(vdir / vec["expected_output"]["file"], allow_pickle=False))
        cmp = compare_output(got, exp, vec)
        del got                                  # the map, before the directory goes
        entry.update(max_abs=cmp["max_abs"], rms=cmp["rms"],
                     allowed_max_abs=cmp["allowed_max_abs"], allowed_rms=cmp["allowed_rms"],
                     first_failure=cmp["first_failure"])
        problems = list(zip(cmp["rules"], cmp["problems"], strict=True))
        dig = out.with_name(out.name + ".intlayer")
        if os.path.lexists(dig) and not dig.is_file():
            # a link to /dev/urandom or a folder passed as "absent" (a QA run of stop 50)
            entry["intlayer"] = "mismatch"
            problems.insert(0, (RULE_DIGEST, f"{dig.name} is not a regular file (a folder, a "
                                             "device, a FIFO): the integer-layer digest, if "
                                             "written, must be a file"))
        elif dig.is_file():
            wrong = _digest_problem(dig, vec["integer_layer_digest"], not cmp["problems"])
            entry["intlayer"] = "mismatch" if wrong else "match"
            if wrong:
                problems.insert(0, (RULE_DIGEST, wrong))
        if not array_only:
            entry["sidecar"], side_problems = compare_sidecar(
                out.with_name(out.name + ".json"), vec)
            problems += [(RULE_SIDECAR, p) for p in side_problems]
        if problems:
            entry["message"] = _led(problems)
        else:
            entry["passed"] = True
            entry["message"] = (f"max_abs {cmp['max_abs']:.3g} <= {cmp['allowed_max_abs']:.3g}, "
                                f"rms {cmp['rms']:.3g} <= {cmp['allowed_rms']:.3g}, integer "
                                f"layer {entry['intlayer']}, "
                                + ("names/rate/units/meta not checked (--array-only)"
                                   if array_only else "names/rate/units/meta match"))
    return entry


# ------------------------------------------------------------ encoder mode --
def _load_input(vdir: Path, item: dict):
    x = np.load(vdir / item["input"], allow_pickle=False)
    side = json.loads((vdir / item["sidecar"]).read_text(encoding="utf-8"))
    return x, side


def check_encoded(data: bytes, x: np.ndarray, side: dict, E: float) -> tuple[list, dict]:
    """Validate an encoder's output with the reference decoder; returns (problems, facts)."""
    import mpz
    from mpz.chunks import CHUNKS
    from mpz.decoder import decode_layers
    # the digest: two encoders' (or versions') results show whether they wrote the same
    # bytes, not only as many (a maintainer's QA run of stop 75)
    facts: dict[str, Any] = {"declared_bound": None, "measured_max_error": None,
                             "bytes": len(data), "sha256": hashlib.sha256(data).hexdigest(),
                             "notes": []}
    try:
        decoded = decode_layers(data)
    except mpz.MPZError as exc:
        # R-7.3-1 is the output itself too: the failure ended without its rule, where every
        # other encoder failure names one (a maintainer's QA run of stop 75)
        return [f"the reference decoder rejects the output: {type(exc).__name__}: {exc} "
                f"(§7.2: a conforming encoder writes only valid files) (R-7.3-1)"], facts
    out, s = decoded.motion(), decoded.stream
    h = s.header
    facts["declared_bound"] = float(h.error_bound)
    problems = []
    if h.error_metric != 1:
        problems.append(f"header error_metric {h.error_metric}, expected 1 (a declared max "
                        f"Euclidean error, §4.1, §7.3; R-7.3-1)")
    if not h.error_bound <= E:
        problems.append(f"declared error_bound {h.error_bound!r} > requested --max-error {E!r} "
                        "(§7.3: error_bound <= E) (R-7.3-1)")
    if out.positions.shape != x.shape:
        said = f"shape {out.positions.shape} != input {x.shape}"
        got, want = list(out.names), list(side["names"])
        lost = [n for n in want if n not in got]
        extra = [n for n in got if n not in want]
        if lost or extra:      # which markers, not only how many (a QA run of stop 48)
            said += "; " + "; ".join(
                f"{what} {', '.join(repr(printable(n)) for n in names[:5])}"
                + (f" and {len(names) - 5} more" if len(names) > 5 else "")
                for what, names in (("markers missing:", lost), ("markers added:", extra))
                if names)
        elif out.positions.shape[0] != x.shape[0]:
            said += f"; {out.positions.shape[0]} frames decoded of the {x.shape[0]} given"
        problems.append(f"{said} (R-7.2-2)")
        return problems, facts
    positions, mask = out.positions, decoded.valid
    if list(out.names) != list(side["names"]):
        # the first that differs, by index (the first four of each said nothing when the
        # last was renamed, a QA run of stop 47); the shapes are equal here
        k = next(i for i, (got, want) in enumerate(zip(out.names, side["names"],
                                                        strict=True)) if got != want)
        got_k, want_k = _said(printable(out.names[k]), printable(side["names"][k]))
        said = f"marker names[{k}] = {got_k} != input {want_k}"
        if sorted(out.names) == sorted(side["names"]) and \
                len(set(side["names"])) == len(side["names"]):
            # the same markers in another order: the gaps and the bound are checked marker
            # by marker, by name (by index, a review of stop 56 was told of a broken bound
            # and of gaps, where only the order was wrong)
            at = {n: i for i, n in enumerate(out.names)}
            order = [at[n] for n in side["names"]]
            positions, mask = positions[:, order], mask[:, order]
            said += ": the same markers in another order (gaps and bound checked by name)"
        problems.append(f"{said} (R-7.2-2)")
    if float(out.rate) != float(side["rate"]):
        problems.append(f"rate {out.rate!r} != input {side['rate']!r} (rates are kept "
                        "exactly, R-7.2-2)")
    valid_in = ~np.isnan(x).any(axis=2)
    if (mask != valid_in).any():
        f, m = (int(i) for i in np.argwhere(mask != valid_in)[0])
        what = "a gap" if valid_in[f, m] else "valid"
        problems.append(f"gaps not preserved: frame {f}, marker {side['names'][m]!r} decodes as "
                        f"{what} ({int((mask != valid_in).sum())} marker-frames differ; "
                        "R-7.2-2)")
    both = valid_in & mask
    d = _distances(positions, x)
    d[~both] = 0.0
    facts["measured_max_error"] = float(d.max(initial=0.0))
    bound = float(h.error_bound)
    # §7.2: the float slack max|x| * 2^-50 (the float tier of §7.1) on top of the bound,
    # max|x| over the input's valid samples: the finite coordinates of a gap sample
    # (NaN, 1e30, 0) made it 8.9e14 and let a file 6 units off a 1-unit bound pass (a
    # clean-room encoder's review, stop 64)
    slack = mf.tolerances(0.0, float(np.abs(x[valid_in]).max(initial=0.0)))["max_abs"]
    if h.error_metric == 1 and (d > bound + slack).any():
        f, m = (int(i) for i in np.argwhere(d > bound + slack)[0])
        problems.append(f"declared bound {bound!r} broken at {int((d > bound + slack).sum())} "
                        f"sample(s); first at frame {f}, marker {side['names'][m]!r}: error "
                        f"{float(d[f, m])!r}, beyond the bound by {float(d[f, m]) - bound:.3g} "
                        f"where §7.2's float slack allows {slack:.3g} (R-7.2-1)")
    # what a pass does not show (an outside encoder implementer's QA, stop 72): a bound
    # held only by the float slack, which §7.2 says an encoder SHOULD NOT rely on, and a
    # version above (or below) the lowest that describes the file, a SHOULD of §2.1
    if h.error_metric == 1 and facts["measured_max_error"] > bound:
        facts["notes"].append(
            f"within the declared bound only by the float slack of §7.2: error "
            f"{facts['measured_max_error']!r} beyond it by "
            f"{facts['measured_max_error'] - bound:.3g} (slack {slack:.3g}; an encoder SHOULD "
            "NOT rely on it)")
    lowest = max(CHUNKS[c.type].MINOR for c in s.chunks if c.type in CHUNKS)
    if h.version_minor != lowest:
        facts["notes"].append(
            f"the file is marked version {h.version_major}.{h.version_minor}, where the lowest "
            f"minor version that describes it (by its newest chunk type) is "
            f"{h.version_major}.{lowest}: an encoder SHOULD write that (§2.1); not a failure")
    units = side.get("units", "")
    if out.units != units:
        # the cause before its consequences: an encoder that wrote metres for millimetres
        # was told of its declared bound above E and of the broken bound first, the units
        # between them (an outside encoder implementer's QA, stop 72)
        said = f"units {out.units!r} != input {units!r}"
        if out.units in MM_PER_UNIT and units in MM_PER_UNIT and h.error_metric == 1:
            factor = MM_PER_UNIT[units] / MM_PER_UNIT[out.units]
            if (_distances(positions, x * factor)[both] <= bound + factor * slack).all():
                said += (f", and the values were converted with them (the input's × {factor:g}, "
                         "within the declared bound)")
        problems.insert(0, f"{said}: keep the input's units" + (
            f"; the figures that follow come from it ({out.units} against {units})"
            if problems else "") + " (R-7.2-2)")
    return problems, facts


#: what an encoder's refusal or missing output ends with: the bound it did not hold
ENCODER_RULES = "; rules R-7.3-1 (spec §7.4)"


def run_encoder_item(cmd, vdir: Path, item: dict, E: float, timeout, memory_mb) -> dict:
    name = f"{item['name']}@{E:g}"
    entry = {"name": name, "group": "encoder", "file": item["input"], "expected": "encode",
             "max_error": E, "actual": None, "passed": False, "message": "",
             "declared_bound": None, "measured_max_error": None, "bytes": None, "sha256": None,
             "notes": [],
             "exit_code": None, "signal": None, "timed_out": False, "seconds": None,
             "peak_rss_mb": None, "stderr_tail": ""}
    x, side = _load_input(vdir, item)
    infinite = np.isinf(x) & ~np.isnan(x).any(axis=-1, keepdims=True)
    if infinite.any():
        # §7.3: a sample is a gap when a coordinate is NaN, so one with an infinity is
        # valid and no bound holds there (the reference encoder writes it as a gap, which
        # R-7.2-2 then fails): the input, not the encoder, is at fault
        f, m, _ = (int(i) for i in np.argwhere(infinite)[0])
        entry.update(actual="input", message=(
            f"input {item['input']} holds an infinite coordinate in a valid sample (frame "
            f"{f}, marker {m}): the encoder contract's inputs are finite or NaN (§7.3), so "
            "the input is at fault, not the encoder: not run"))
        return entry
    with tempfile.TemporaryDirectory(prefix="mpz-conf-") as tmp:
        src = Path(tmp) / "in.npy"
        shutil.copyfile(vdir / item["input"], src)
        shutil.copyfile(vdir / item["sidecar"], Path(tmp) / "in.json")
        out = Path(tmp) / "out.mpz"
        run = run_command(cmd + [str(src), str(out), "--max-error", repr(float(E))], timeout,
                          memory_mb, cwd=tmp)
        entry.update(exit_code=run["exit_code"], signal=run["signal"],
                     timed_out=run["timed_out"], seconds=run["seconds"],
                     peak_rss_mb=run["peak_rss_mb"], stderr_tail=_tail_of(run))
        bad = failure_kind(run) or _cut_off_by_the_file_limit(run, Path(tmp))
        if bad is not None:
            entry["actual"] = bad[0]
            limit = (f" (limit {timeout:g} s)" if bad[0] == "timeout" else
                     f" (limit {memory_mb} MB)" if bad[0] == "memory" else "")
            # the rule and the §, as a refusal says them (an encoder QA run of stop 71: a
            # crash, a hang and exit 200 named neither)
            entry["message"] = (bad[1] if bad[0] == "error" else f"encoder {bad[1]}{limit}") \
                + ": the encoder must write the file and exit 0 (spec §7.3)" + ENCODER_RULES
            return entry
        if run["exit_code"] != 0:
            tail = run["stderr"].strip().splitlines()
            entry["actual"] = "reject"
            # an uncaught exception or a panic, as decoder mode tells them (_uncaught), is a
            # crash, not a refusal: a traceback was worded as the encoder's refusal (an
            # encoder implementer's QA, stop 72)
            hit = _uncaught(run)
            # the rule and the §, as decoder mode says them (an implementer's QA run of
            # stop 71: a refusal and a missing output named neither)
            entry["message"] = (
                (f"encoder crashed: exited {run['exit_code']} after an uncaught exception or "
                 f"a panic, not a refusal (its output shows {hit[:120]!r}"
                 + (f" and ends {tail[-1][:300]!r})" if tail[-1].strip() != hit else ")")
                 + ": the encoder must write the file and exit 0 (spec §7.3)") if hit else
                (f"encoder exited {run['exit_code']}" + (f": {tail[-1][:300]}" if tail else "")
                 + ": every input and bound the suite ships can be held, so a refusal fails "
                 "here (spec §7.3)")) + ENCODER_RULES
            return entry
        if not out.is_file():
            # what it wrote instead, if anything (out.MPZ, a name of its own): "wrote no
            # file" alone did not say (an encoder QA run of stop 71)
            others = sorted(p.name for p in Path(tmp).iterdir()
                            if p.name not in (src.name, "in.json"))
            entry["actual"] = "encode"
            entry["message"] = (f"encoder exited 0 but wrote no file {out.name}"
                                + (f" (it wrote {', '.join(others[:5])} in its working "
                                   "folder)" if others else
                                   " (nor any other file in its working folder)")
                                + ": OUT.mpz is the second argument, as given (spec §7.3)"
                                + ENCODER_RULES)
            return entry
        got = _read_capped(out, MAX_ENCODED_BYTES)
        if got is None:
            entry["actual"] = "encode"
            entry["message"] = (f"the encoder wrote more than {MAX_ENCODED_BYTES} bytes: not "
                                "read")
            return entry
        data = got
    entry["actual"] = "encode"
    problems, facts = check_encoded(data, x, side, E)
    entry.update(facts)
    if problems:
        # the rules at the end, "rules ... (spec §7.4)" as in decoder mode, not after each
        # problem (QA, stop 71)
        rules = sorted({r for p in problems for r in re.findall(r"R-7\.[23]-\d+", p)})
        entry["message"] = "; ".join(re.sub(r" \(R-7\.[23]-\d\)$", "", p)
                                     for p in problems) + (
            f"; rules {', '.join(rules)} (spec §7.4)" if rules else "")
    else:
        entry["passed"] = True
        entry["message"] = (f"{len(data)} bytes, declared bound {facts['declared_bound']:g} <= "
                            f"{E:g}, measured max error {facts['measured_max_error']:.6g}"
                            + "".join(f"; note: {n}" for n in facts["notes"]))
    return entry


# --------------------------------------------------------------------- CLI --
def _finite(obj: Any) -> Any:
    """``obj`` with every non-finite float as None (JSON has no inf or NaN; a decoder that
    writes 1e300 makes the RMS infinite, and the message says so)."""
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    return obj


def _parser() -> argparse.ArgumentParser:
    p = Parser(
        prog="mpz-conformance",
        description="Run an MPZ decoder or encoder against the conformance vectors "
                    "(see conformance/README.md for the contract).",
        epilog="exit codes: 0 every selected vector passed, 1 at least one failed (or, "
               "with only invalid vectors selected, the command did not decode a valid one), "
               "2 the report could not be written to standard output (a full disk), "
               "64 usage error (bad options, missing or invalid vectors, command not found or "
               "a script it cannot start, a --results file that cannot be written, said "
               "after the report, an encoder input with an infinity in a valid sample, "
               "not run), "
               "130 interrupted, 143 terminated (SIGTERM; 129 for SIGHUP): the commands "
               "running are killed and no --results is written")
    add_version(p)
    who = p.add_mutually_exclusive_group(required=True)
    who.add_argument("--decoder", metavar="CMD",
                     help="decoder command; run as CMD IN.mpz OUT.npy")
    who.add_argument("--encoder", metavar="CMD",
                     help="encoder command; run as CMD IN.npy OUT.mpz --max-error E")
    p.add_argument("--vectors", metavar="DIR", default=str(mf.DEFAULT_DIR),
                   help="vector directory holding manifest.json (default: the shipped set)")
    p.add_argument("--results", metavar="FILE", help="write JSON results here (a file name; "
                   "not -: the report itself goes to standard output)")
    p.add_argument("--timeout", type=float, default=60.0, metavar="S",
                   help="seconds allowed per vector (default 60)")
    p.add_argument("--memory", type=int, default=2048, metavar="MB",
                   help="address-space limit per run in MiB, 0 for none (default 2048)")
    p.add_argument("--only", nargs="+", metavar="NAME",
                   help="run only these vectors (name, file name or group)")
    p.add_argument("--jobs", "-j", type=int, default=1, metavar="N",
                   help="run N vectors at once (default 1)")
    p.add_argument("--quiet", "-q", action="store_true", help="print failures and the summary only")
    p.add_argument("--implements", metavar="1.N", default=None,
                   help="the MPZ version the decoder implements, 1.0 up to the suite's "
                        "(default); a decoder of 1.0 skips the chunk types of 1.1 as unknown "
                        "(spec §2.1), so the vectors that break only their rules must decode")
    p.add_argument("--as-given", action="store_true",
                   help="pass the command's arguments as written; by default each one that "
                        "names a file or folder where you run the runner is made absolute, "
                        "as the command runs in a temporary directory (a note lists them)")
    p.add_argument("--array-only", action="store_true",
                   help="the contract of the spec's 1.0 text: check OUT.npy (and the "
                        "digest) alone, without OUT.npy.json; names, rate, units and meta go "
                        "unchecked")
    return p


def _command(text: str, as_given: bool = False) -> list:
    """``text`` split as a shell would, to run in a temporary directory: the program's path
    made absolute, and (unless ``as_given``) each argument that names a file or folder
    here. Raises UsageError for a command that cannot start."""
    try:
        argv = shlex.split(text)
    except ValueError as exc:
        raise UsageError(f"cannot split the command {text!r}: {exc}") from None
    if not argv:
        raise UsageError("empty command")
    exe = argv[0]
    if os.sep in exe:
        if not (os.path.isfile(exe) and os.access(exe, os.X_OK)):
            raise UsageError(f"{exe}: not an executable file")
        _check_script(exe)
        argv[0] = os.path.abspath(exe)             # the decoder runs in a temporary directory
    elif shutil.which(exe) is None:
        raise UsageError(f"{exe}: command not found on PATH")
    # ... and so does every argument that names a file or folder here: "python3 dec.py",
    # "java -jar dec.jar" would otherwise look for it there and fail every vector
    return [argv[0]] + [os.path.abspath(a) if not as_given and not a.startswith("-")
                        and os.path.exists(a) and not os.path.isabs(a) else a
                        for a in argv[1:]]


def _rewritten(text: str, cmd: list) -> list[tuple[str, str]]:
    """The arguments of ``text`` that :func:`_command` made absolute, as (given, run)."""
    return [(a, b) for a, b in zip(shlex.split(text)[1:], cmd[1:], strict=True) if a != b]


def _check_script(exe: str) -> None:
    """Refuse an executable text file that the system cannot start: no ``#!`` line ("Exec
    format error"), or one naming an interpreter that does not exist, often ``python3\\r``
    of a script with CRLF line ends. Each vector failed with "cannot start", naming the
    script itself as missing (a conformance QA run of stop 55); a binary is left to run.

    Raises
    ------
    UsageError
        For such a script.
    """
    try:
        with open(exe, "rb") as fh:
            head = fh.read(256)
    except OSError:
        return                                       # run_command says why it cannot start
    if head.startswith(b"#!"):
        line = head[2:].split(b"\n", 1)[0]
        words = line.split()
        interp = words[0].decode("utf-8", "replace") if words else ""
        if line.endswith(b"\r"):
            raise UsageError(f"{exe}: its #! line ends in a carriage return (CRLF line ends), "
                             "so the system looks for an interpreter whose name ends in one; "
                             "convert the script to LF line ends")
        if not interp:
            raise UsageError(f"{exe}: its #! line names no program")
        if not os.path.exists(interp):
            raise UsageError(f"{exe}: its #! line names {interp}, which does not exist")
        return
    if b"\0" not in head and head.strip() and all(b >= 0x20 or b in b"\t\r\n" for b in head):
        raise UsageError(f"{exe}: a text file without a #! line, which the system cannot start "
                         "(Exec format error); add one, or name its interpreter: "
                         f"--decoder \"python3 {exe}\"")


class SuiteUnreadable(Exception):
    """The runner could not read or copy a file of the suite itself (or make its temporary
    folder) while the run went on: not the command's failure."""


@contextlib.contextmanager
def _suite_files() -> Iterator[None]:
    """Turn an OSError or ValueError that escapes a vector's run (the decoder's own outputs
    are judged inside it) into :class:`SuiteUnreadable`: vectors regenerated or removed
    during a run, or a full temporary folder, ended it with a traceback, exit 70 (a QA run
    of stop 53)."""
    try:
        yield
    except (OSError, ValueError) as exc:
        raise SuiteUnreadable(f"cannot read the suite's files or make a temporary folder "
                              f"({type(exc).__name__}: {exc}): were the vectors regenerated "
                              "or removed while the run went on? The hashes were checked at "
                              "its start; run it again") from exc


#: words of a command's output that a --memory limit may explain (:func:`_warn_if_nothing_decoded`)
MEMORY_WORDS = re.compile(r"memory|MemoryError|shared object|map segment|allocat", re.I)


def _warn_if_nothing_decoded(results: list[dict[str, Any]],
                             probed: dict[str, Any] | None = None,
                             memory_mb: int | None = None, as_given: bool = False) -> None:
    """Say so when a command meant to decode decoded none of the valid vectors: it may not
    run at all (``python -m NAME`` finds no module from the temporary working directory),
    and then its exits of 1 pass every invalid vector as a rejection (a QA of stop 42:
    "277/277 invalid passed" for a command that never started). ``probed``: the result of
    the valid vector run to check that the command decodes at all, when none was
    selected. ``memory_mb``: the --memory limit, which may be too small for the command
    to start (the reference decoder's numba cannot load its library under 256 MiB:
    a conformance QA run of stop 55 was sent after a path problem). ``as_given``: the
    command's arguments were passed as written (--as-given), which a relative path then
    cannot be (a review of stop 56)."""
    valid = [r for r in results if r.get("expected") == "decode"]
    if valid and not any(r["passed"] for r in valid):
        said = printable(valid[0]["message"])[:300]
        # the limit is named when the outputs speak of memory or of a library that did not
        # load, not after "No module named" (a review of stop 55)
        starved = any(MEMORY_WORDS.search(r.get("stderr_tail") or "") or
                      r.get("actual") in ("memory", "crash") for r in valid)
        limit = (f"; or --memory {memory_mb} MiB is too little for it to start: try one "
                 "vector with --memory 0 (no limit)") if memory_mb and starved else ""
        if all(r["group"] == "invalid" and r["actual"] == "reject" for r in valid) and \
                probed is not None and probed["passed"]:
            # --implements 1.0 with vectors of 1.1 rules alone: a decoder that applies them
            # was sent after a start-up problem, "none of the 2 valid vector(s)" of the
            # invalid group (a QA run of stop 53)
            print(f"mpz-conformance: warning: the command rejected each of the {len(valid)} "
                  f"invalid vector(s) that break only rules of a later minor version, which "
                  f"a decoder of the version given to --implements must decode (spec §2.1) "
                  f"(the first: {said}): if it implements the later version, leave out "
                  "--implements", file=sys.stderr)
            return
        if any(r.get("exit_code") == 0 for r in valid):
            # it runs and answers: its outputs fail the checks (a wrong dtype, no sidecar);
            # the hint below sent such a decoder after a path problem (QA, stop 47)
            print(f"mpz-conformance: warning: the command passed none of the {len(valid)} "
                  f"valid vector(s), though it ran and exited 0 (the first: {said}): until "
                  "its outputs pass, its rejections of invalid vectors prove little",
                  file=sys.stderr)
            return
        kinds = sorted({str(r.get("actual")) for r in valid})
        if set(kinds) <= {"crash", "timeout", "memory"}:
            # it started: the start-up hint below sent a decoder that crashes or hangs after
            # a path problem (an implementer's QA run of stop 50)
            what = " or ".join({"crash": "crashed", "timeout": "timed out",
                                "memory": "ran out of memory"}[k] for k in kinds)
            print(f"mpz-conformance: warning: the command {what} on each of the "
                  f"{len(valid)} valid vector(s) (the first: {said}): until it decodes "
                  f"them, its rejections of invalid vectors prove nothing{limit}",
                  file=sys.stderr)
            return
        print(f"mpz-conformance: warning: the command decoded none of the {len(valid)} valid "
              f"vector(s) (the first: {said}); check that it runs at all from a temporary "
              "working directory (python -m NAME does not find a module beside you: give "
              "its path"
              + ("; with --as-given, a relative path among its arguments is looked for "
                 "there too" if as_given else "")
              + f"){limit}: until it does, its rejections of invalid vectors prove "
              "nothing", file=sys.stderr)


@quiet_broken_pipe
@reports_ctrl_c("mpz-conformance: interrupted")
def main(argv: list[str] | None = None) -> int:
    parser = _parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:          # 0 for --help and --version, 64 for usage errors
        return int(exc.code or 0)
    from mpz.api import check_output, signals_exit, write_atomic
    try:
        if not (math.isfinite(args.timeout) and args.timeout > 0):
            raise UsageError(f"--timeout must be a finite number > 0, got {args.timeout}")
        if args.jobs < 1:
            raise UsageError(f"--jobs must be at least 1, got {args.jobs}")
        if not 0 <= args.memory <= MAX_MEMORY_MB:
            raise UsageError(f"--memory must be 0 (no limit) .. {MAX_MEMORY_MB} MiB, got "
                             f"{args.memory}")
        minor = VERSION_MINOR
        if args.array_only and args.decoder is None:     # it was taken silently (QA, stop 50)
            raise UsageError("--array-only is for --decoder")
        if args.implements is not None:
            if args.decoder is None:
                raise UsageError("--implements is for --decoder")
            try:
                minor = implemented_minor(args.implements)
            except ValueError as exc:
                raise UsageError(str(exc)) from None
        given = args.decoder if args.decoder is not None else args.encoder
        cmd = _command(given, args.as_given)
        moved = _rewritten(given, cmd)
        if moved and not args.quiet:
            # a word that happens to name a folder here ("fast", "data") was changed without
            # a word (a conformance QA run of stop 55)
            print("note: arguments that name a file or folder here are given as absolute "
                  "paths (the command runs in a temporary directory): "
                  + ", ".join(f"{printable(shlex.quote(a))} -> {printable(shlex.quote(b))}"
                              for a, b in moved)
                  + "; --as-given leaves them as written", file=sys.stderr)
        vdir = Path(args.vectors)
        try:
            man = mf.load(vdir)
        except mf.ManifestError as exc:
            raise UsageError(str(exc)) from None
        if args.only:        # "uncommon/", as a shell completes a folder, named nothing
            args.only = [o.rstrip("/") or o for o in args.only]
        if args.decoder is not None:
            if not man["vectors"]:           # never a pass of nothing
                raise UsageError(f"{vdir / mf.MANIFEST_NAME} lists encoder inputs only: "
                                 "run it with --encoder")
            todo = mf.vectors(man, args.only)
            if args.only:
                unknown = set(args.only) - {k for v in todo for k in mf.selectors(v)}
                if unknown:
                    # the names that begin so, or are close, as mpz suggests a subcommand
                    # ("--only v09" named nothing: QA, stop 71)
                    every = sorted({k for v in man["vectors"] for k in mf.selectors(v)
                                    if "/" not in k and "." not in k})
                    raise UsageError(f"no vector named {', '.join(sorted(unknown))} (names "
                                     "as the runner prints them, v04-orders-residual-only, "
                                     "valid/v04-orders-residual-only, a file name, or a "
                                     "group)" + _suggestions(sorted(unknown), every, 3))
        else:
            todo = [(item, float(E)) for item in man.get("encoder_inputs", [])
                    for E in item["max_errors"]
                    if not args.only or any(_selects(o, item["name"], float(E))
                                            for o in args.only)]
            if args.only:     # every --only that names nothing, before "none selected"
                unmatched = [o for o in args.only if not any(
                    _selects(o, item["name"], float(E)) for item in man.get("encoder_inputs", [])
                    for E in item["max_errors"])]
                if unmatched:
                    # the runs there are, or those an entry begins or nearly spells, as in
                    # decoder mode (an encoder QA run of stop 71)
                    runs = [f"{item['name']}@{float(E):g}"
                            for item in man.get("encoder_inputs", [])
                            for E in item["max_errors"]]
                    raise UsageError(f"no encoder input named {', '.join(unmatched)} (an "
                                     "input, input@E, encoder/input@E as the runner prints "
                                     "it, inputs/input.npy, or encoder)"
                                     + _suggestions(unmatched, runs, 4))
            if not todo:
                raise UsageError("no encoder inputs selected")
        missing = mf.check_hashes({"vectors": [v for v in todo if isinstance(v, dict)],
                                   "encoder_inputs": list({id(ie[0]): ie[0] for ie in todo
                                                           if isinstance(ie, tuple)}.values())},
                                  vdir)
        if missing:
            raise UsageError(f"{len(missing)} vector file(s) do not match the manifest (a "
                             f"damaged or partial copy?): {'; '.join(missing[:3])}")
        if args.results == "-":      # wrote a file named "-" (a QA run of stop 55)
            raise UsageError("--results -: the report goes to standard output; give the "
                             "JSON a file name (or /dev/stdout to mix the two)")
        if args.results and os.path.isdir(args.results):
            raise UsageError(f"--results {args.results}: a folder, not a file")
        stream = args.results and os.path.exists(args.results) and not os.path.isfile(args.results)
        if args.results and not stream:   # found out now, not after every vector has run
            try:
                check_output(args.results, force=True)
            except MPZError as exc:
                raise UsageError(f"--results: {exc}") from None
    except UsageError as exc:
        print(f"mpz-conformance: error: {exc}", file=sys.stderr)
        return EXIT_USAGE

    mode = "decoder" if args.decoder is not None else "encoder"
    t0 = time.perf_counter()
    if mode == "decoder":
        # the expectations of a decoder of an earlier minor version, where they differ
        plans = [as_read_by(v, vdir, minor) if minor < VERSION_MINOR else (v, None)
                 for v in todo]
        changed = sum(v["expected"] != w["expected"]
                      for (v, _), w in zip(plans, todo, strict=True))

        def job(plan):
            with _suite_files():
                return run_decoder_vector(cmd, vdir, plan[0], args.timeout, args.memory,
                                          args.array_only, plan[1], minor)
        todo = plans
    else:
        def job(ie):
            with _suite_files():
                return run_encoder_item(cmd, vdir, ie[0], ie[1], args.timeout, args.memory)
    # only vectors to reject: a command that never starts "rejects" every one, and nothing
    # said so ("319/319 passed", exit 0: a QA run of stop 53). One valid vector more, not
    # counted, shows whether it decodes at all.
    # So with --implements 1.0 and invalid vectors alone, some of which it must decode:
    # a command that never started was told to leave out --implements (a review of stop 53).
    probe = None
    if mode == "decoder" and not any(plan[0]["expected"] == "decode" and
                                     plan[0]["group"] != "invalid" for plan in todo):
        probe = _probe_plan(man, vdir, minor)
    pool = ThreadPoolExecutor(max_workers=args.jobs)
    try:
        # SIGTERM (a CI job's timeout) and SIGHUP raise SystemExit here, as Ctrl-C raises
        # KeyboardInterrupt: the decoders run in their own process groups, which no signal
        # to the runner reaches, and were left running (a QA of stop 42)
        with signals_exit(signal.SIGTERM, getattr(signal, "SIGHUP", None)):
            results = list(pool.map(job, todo + ([probe] if probe else [])))
            probed = results.pop() if probe else None  # every vector runs before reporting
    except SuiteUnreadable as exc:
        STOP.set()
        pool.shutdown(wait=True, cancel_futures=True)
        print(f"mpz-conformance: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except (KeyboardInterrupt, SystemExit) as exc:
        STOP.set()                  # the running commands are killed, no other one starts
        pool.shutdown(wait=True, cancel_futures=True)
        if isinstance(exc, SystemExit):
            code = int(exc.code or 0)
            print(f"mpz-conformance: stopped by {signal.Signals(code - 128).name}",
                  file=sys.stderr)
            return code
        print("mpz-conformance: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    pool.shutdown()

    # an encoder input the contract does not allow (an infinity in a valid sample) is not
    # run: the input is at fault, not the command. It was counted as a failure, exit 1 (an
    # outside encoder implementer's QA, stop 72); it is counted apart, and the run exits
    # 64, as for the suite's other faults (a file that does not match the manifest)
    not_run = [r["name"] for r in results if r["actual"] == "input"]
    ran = [r for r in results if r["actual"] != "input"]
    n_fail = sum(not r["passed"] for r in ran)
    unproven = probed is not None and not probed["passed"]
    status = EXIT_USAGE if not_run else EXIT_FAIL if n_fail or unproven else EXIT_OK
    found(status)                                         # what a closed pipe exits with
    by_group: dict[str, dict[str, int]] = {}
    for r in results:
        g = by_group.setdefault(r["group"], {"passed": 0, "failed": 0})
        if r["actual"] != "input":
            g["passed" if r["passed"] else "failed"] += 1
    # the results file before the report: a reader that closes the pipe (`| head`) stopped
    # the command before it wrote the file (a docs QA run, stop 52)
    results_error = None
    if args.results:
        doc = {"schema_version": RESULTS_SCHEMA_VERSION, "tool": "mpz-conformance",
               "mode": mode, "command": cmd, "vectors": str(vdir),
               "contract": ("array-only" if args.array_only else "full") if mode == "decoder"
               else "encoder",
               "implements": f"{VERSION_MAJOR}.{minor}" if mode == "decoder" else None,
               "manifest_schema_version": man["schema_version"],
               "timeout": args.timeout, "memory_mb": args.memory,
               "seconds": round(time.perf_counter() - t0, 3),
               "totals": {"total": len(results), "passed": len(ran) - n_fail,
                          "failed": n_fail, "not_run": len(not_run), "groups": by_group},
               "failed": [r["name"] for r in ran if not r["passed"]],
               "results": results,
               **({"probe": probed} if probed is not None else {})}
        text = json.dumps(_finite(doc), indent=1, allow_nan=False) + "\n"
        try:
            if stream:                    # /dev/stdout, a FIFO: not a file to replace
                Path(args.results).write_text(text, encoding="utf-8")
            else:
                write_atomic(args.results, text.encode("utf-8"), force=True)
        except MPZError as exc:
            found(EXIT_USAGE)
            results_error = str(exc)
        except OSError as exc:
            # a device or FIFO that fails the write (/dev/full): the report below was lost
            # with it, exit 2 and one line (a QA run of stop 53)
            found(EXIT_USAGE)
            results_error = f"{args.results}: cannot write: {exc.strerror or exc}"
    for r in results:
        if r["passed"] and args.quiet:
            continue
        # the message may quote the decoder's output: its control characters are escaped,
        # so that a decoder cannot drive the terminal
        verdict = ("PASS" if r["passed"] else "NOT RUN" if r["actual"] == "input" else
                   "FAIL")
        print(f"{verdict} {r['group']}/{r['name']}: "
              f"{printable(r['message'])}")
    summary = ", ".join(f"{g} {c['passed']}/{c['passed'] + c['failed']}"
                        for g, c in by_group.items())
    if mode == "decoder" and args.array_only:
        print("note: --array-only: names, rate, units and meta were not checked (spec §7.3)")
    later = sum(IMPLEMENTS_HINT in r["message"] for r in results if not r["passed"])
    if later:
        print(f"note: {later} failure(s) are decodes of invalid vectors that break only "
              "rules marked (1.1) in spec §7.4, which a decoder of MPZ 1.0 alone must "
              "decode: if it implements 1.0 alone, run it with --implements 1.0 (spec §2.1)")
    # rejections by a traceback or a panic: their PASS lines say so, which -q hid, and a
    # decoder that panics on every bad file read as conformant (QA, stop 71)
    unplanned = sum(r["passed"] and r.get("actual") == "reject" and
                    bool(_unplanned({"stderr": r.get("stderr_tail") or ""})) for r in results)
    # an unproven run's line said "1/1 passed" above exit 1, the reason on stderr alone
    # (a CLI audit): it says so on the summary line too
    # the count of re-judged vectors on the summary line, where the README says it is (it
    # was a note of its own above it: QA, stop 71)
    print(f"{len(ran) - n_fail}/{len(ran)} passed ({summary})"
          + (f"; --implements 1.{minor}: {changed} vector(s) judged as a 1.{minor} decoder "
             "must read them, from reject to decode, their later chunk types unknown to it "
             "(spec §2.1, §2.3)" if mode == "decoder" and minor < VERSION_MINOR else "")
          + (f"; {unplanned} of the rejections by an uncaught exception or a panic ("
             + ("see --results" if args.quiet and args.results else
                "run without -q to see which" if args.quiet else "see their PASS lines")
             + ")" if unplanned else "")
          + (f"; failing: {', '.join(r['name'] for r in ran if not r['passed'])}"
             if n_fail else "")
          + (f"; not run, the input at fault, not the encoder (§7.3): {', '.join(not_run)}"
             if not_run else "")
          + (f"; not proven: the command did not decode {probed['group']}/{probed['name']}"
             if unproven and probed is not None else ""))
    _warn_if_nothing_decoded(results, probed, args.memory, bool(getattr(args, "as_given",
                                                                        False)))
    if probed is not None:
        said = f"{probed['group']}/{probed['name']}"
        if unproven:
            print(f"mpz-conformance: error: only invalid vectors were selected, and the "
                  f"command did not decode {said}, run as a check that it decodes at all "
                  f"({printable(probed['message'])[:300]}): its rejections prove nothing",
                  file=sys.stderr)
        else:
            print(f"note: only invalid vectors were selected; the command decoded {said}, "
                  "run as a check that it decodes at all (not counted)")
    if not_run:
        print(f"mpz-conformance: error: {len(not_run)} encoder input(s) of the manifest not "
              "run: the encoder contract's inputs are finite or NaN (§7.3); fix the input or "
              "the manifest", file=sys.stderr)
    if results_error is not None:
        print(f"mpz-conformance: error: --results: {results_error}", file=sys.stderr)
        return EXIT_USAGE
    return status


def _probe_plan(man: dict, vdir: Path, minor: int) -> tuple[dict, Any] | None:
    """The first vector of the manifest that a decoder of 1.``minor`` must decode and whose
    file matches the manifest, as :func:`run_decoder_vector` takes it; None if none."""
    for v in mf.vectors(man, None):
        plan = as_read_by(v, vdir, minor) if minor < VERSION_MINOR else (v, None)
        if plan[0]["expected"] == "decode" and not mf.check_hashes(
                {"vectors": [v], "encoder_inputs": []}, vdir):
            return plan
    return None


if __name__ == "__main__":
    sys.exit(main())
