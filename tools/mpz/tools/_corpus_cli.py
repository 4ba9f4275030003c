"""``mpz encode`` over many files on Dask: the command-line side of :mod:`mpz.corpus`.

Contract: ``mpz encode`` hands its planned batch here (:func:`run_corpus`) when
:func:`wants_corpus` says so: ``--jobs`` or ``--scheduler`` was given, or several inputs
(or ``-r``) go to ``-o FOLDER/``. The files are encoded by :func:`mpz.corpus.encode_corpus` (a local
Dask cluster of ``--jobs`` worker processes, or the cluster at ``--scheduler``; ``--jobs 0``
or a missing Dask: in this process), incrementally, into ``FOLDER/index.sqlite``. One
progress bar on stderr (a terminal only; none with ``-q``), then the summary table (files,
bytes in and out, failures with their reasons) on stdout, or ``--json`` (schema
``mpz-corpus/1``).

Exit codes: 0 every file encoded or up to date; 2 some failed, or an indexed output whose
source is not among the inputs was found damaged; 64 usage; 130 interrupted,
143 terminated (SIGTERM; 129 SIGHUP): the files that finished are kept and indexed, and
the next run resumes.
"""
from __future__ import annotations

import argparse
from collections.abc import Sequence
import importlib.util
import os
import signal
import sys
from typing import TYPE_CHECKING, Any

from mpz.tools._cli import EXIT_ERROR, EXIT_OK, count, found

if TYPE_CHECKING:
    from mpz.corpus import FileOptions, FileResult


def add_corpus_options(p: argparse.ArgumentParser) -> None:
    """``--jobs``, ``--scheduler``, ``--memory-limit`` and ``--verify`` on ``mpz encode``."""
    from mpz.corpus import DEFAULT_MEMORY_LIMIT
    p.add_argument("-j", "--jobs", type=count, metavar="N",
                   help="encode several files in parallel on N Dask worker processes "
                   "(default with several inputs and -o FOLDER/: one per CPU; 0: in this "
                   "process); writes FOLDER/index.sqlite and skips files already encoded")
    p.add_argument("--scheduler", metavar="ADDRESS", type=_scheduler,
                   help="run on an existing dask.distributed cluster, e.g. tcp://host:8786 "
                   "(its workers must see the inputs and FOLDER at the same paths, and run "
                   "this mpz version: checked as the run starts; docs/corpus.md)")
    p.add_argument("--memory-limit", metavar="SIZE", type=_memory_limit,
                   help=f"memory limit of each local Dask worker, e.g. 2GiB or 500MB "
                   f"(default {DEFAULT_MEMORY_LIMIT}); a worker needs about 200 MB to start. "
                   "Unused (with a note) by --scheduler, whose workers have their own, by "
                   "--jobs 0 and by an encode that is not a corpus run")
    p.add_argument("--verify", action="store_true",
                   help="corpus runs: read whole every output that the index says is up to "
                   "date and check it (every chunk's frame and CRC, its meta against the "
                   "index), on the workers; encode a damaged one again. Also check "
                   "every row's stored summary levels against their checksum, and "
                   "rebuild a row whose levels changed. Without it, up to date is the "
                   "index's word (sizes and times)")


def _scheduler(text: str) -> str:
    """A ``--scheduler`` address as dask.distributed reads it (``tcp://host:port``)."""
    try:
        from distributed.comm.addressing import parse_address, parse_host_port
    except ImportError:
        return text              # run_corpus says that Dask is missing
    from distributed.comm.registry import backends
    try:
        proto, loc = parse_address(text)
        if proto not in backends:       # http:// failed only once the run had started (QA)
            raise ValueError(f"unknown address scheme {proto!r} (Dask knows "
                             f"{', '.join(sorted(backends))})")
        if proto in ("tcp", "tls"):
            _, port = parse_host_port(loc)
            if not 0 < int(port) < 65536:  # :99999 waited 30 s for a connection (QA)
                raise ValueError(f"port {port} is not in 1..65535")
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"--scheduler wants an address such as "
                                         f"tcp://host:8786, got {text!r}: {exc}") from None
    return text


def _memory_limit(text: str) -> str:
    """A ``--memory-limit`` size (``4GiB``, ``500MB``, a number of bytes)."""
    try:
        from dask.utils import parse_bytes
    except ImportError:
        return text
    try:
        n = parse_bytes(text)
    except (ValueError, TypeError):
        raise argparse.ArgumentTypeError(f"--memory-limit wants a size such as 2GiB or "
                                         f"500MB, got {text!r}") from None
    if n <= 0:
        raise argparse.ArgumentTypeError(f"--memory-limit wants a positive size, got {text!r}")
    return text


def wants_corpus(args: argparse.Namespace, jobs: Sequence[Any]) -> bool:
    """Whether ``mpz encode`` should run this batch as a corpus (see the module docstring).

    Always with ``--jobs`` or ``--scheduler`` (:func:`run_corpus` refuses what cannot
    work); otherwise for several inputs, or ``-r``, going to ``-o FOLDER/``.
    """
    from mpz.tools._common import STDIO, is_folder_target
    if getattr(args, "jobs", None) is not None or getattr(args, "scheduler", None):
        return True
    several = len(jobs) > 1 or bool(getattr(args, "recursive", False))
    return several and is_folder_target(args.output) and not any(
        j.output == STDIO for j in jobs)


def _dask_installed() -> bool:
    return importlib.util.find_spec("distributed") is not None


class _Bar:
    """The corpus's one progress bar (stderr, a terminal only)."""

    def __init__(self, enabled: bool) -> None:
        from mpz.tools._common import Progress
        self.bar = Progress("encoding", enabled=None if enabled else False)
        self.failed = 0
        self.written = 0
        self.done = 0
        self.total = 0

    def __call__(self, done: int, total: int, r: FileResult) -> None:
        self.failed += r.status == "failed"
        self.written += r.status == "encoded"
        self.done, self.total = done, total
        bad = f", {self.failed} failed" if self.failed else ""
        self.bar(done / max(total, 1), f"{done}/{total}{bad} {os.path.basename(r.source)}")

    @property
    def all_done(self) -> bool:
        """Whether every file of the run finished: a Ctrl-C as the cluster closed, the work
        done, said "3 of 3 files finished ... run the same command again to encode the
        rest" (a QA run of stop 57)."""
        return bool(self.total) and self.done == self.total

    def finished(self, planned: int) -> str:
        """How many files finished, of the run's (``planned`` until one finished), for the
        line of an interrupted run."""
        bad = f", {self.failed} of them failed" if self.failed else ""
        if self.all_done:
            return f"all {_plural(self.total, 'file')} finished{bad}"
        return f"{self.done} of {_plural(self.total or planned, 'file')} finished{bad}"

    def kinds(self) -> str:
        """What the finished files were, for the line of an interrupted run: those written,
        those already up to date (kept or skipped), each in the index. Why: a run of 5 up
        to date files and 3 new ones, stopped before any was written, said "5 of 8 files
        finished ...: written and indexed" (an archive team's QA run of stop 72)."""
        current = self.done - self.written - self.failed
        said = [f"{n} {what}" for n, what in ((self.written, "written"),
                                              (current, "already up to date")) if n]
        # "none written, each in the index" read as nonsense (a corpus QA run of stop 76)
        return f"{', '.join(said)}, each in the index" if said else "none written"

    def rest(self) -> str:
        """What to do about the files an interrupted run did not finish: nothing when it
        finished them all. A worker may have written a file whose result the run did not
        hear of (an output on disk beyond the count, QA of stop 72): that run keeps it."""
        return "" if self.all_done else ("; run the same command again to encode the rest "
                                         "(it keeps a file a worker finished as the run "
                                         "stopped)")

    def close(self) -> None:
        self.bar.close()


def run_corpus(args: argparse.Namespace, jobs: Sequence[Any], options: FileOptions) -> int:
    """Encode the planned ``jobs`` (``.input``, ``.output``, ``.error``) as a corpus.

    ``options`` makes each file's options (``mpz.tools.cmd_encode.PerFile``); it is sent
    to the workers, so it must pickle.
    """
    from mpz.api import signals_exit
    from mpz.corpus import DEFAULT_MEMORY_LIMIT, CorpusStopped, encode_corpus
    from mpz.tools._cli import EXIT_USAGE, EXIT_WARN, print_json, printable, signal_in
    from mpz.tools._common import STDIO, is_folder_target
    if not is_folder_target(args.output) or any(j.output == STDIO for j in jobs):
        print("mpz encode: error: --jobs and --scheduler encode files into -o FOLDER/ "
              "(ending in /), not to one file or standard output", file=sys.stderr)
        return EXIT_USAGE
    quiet = bool(getattr(args, "quiet", False))
    planned = [j for j in jobs if j.error is None]
    workers = getattr(args, "jobs", None)
    scheduler = getattr(args, "scheduler", None)
    if workers is None and scheduler is None and not _dask_installed():
        workers = 0
        if not quiet:
            print("mpz encode: dask.distributed is not installed: encoding in this process "
                  "(pip install 'mpz[corpus]' to use every core)", file=sys.stderr)
    elif workers is None:
        workers = min(os.cpu_count() or 1, max(len(planned), 1))
    memory_limit = getattr(args, "memory_limit", None)
    if memory_limit is not None and (scheduler or workers == 0) and not quiet:
        # QA (stop 47): --memory-limit with --scheduler was dropped without a word
        why = ("the workers of --scheduler's cluster have the limit they were started with"
               if scheduler else "--jobs 0 encodes in this process")
        print(f"mpz encode: note: --memory-limit {memory_limit} changes nothing: {why}",
              file=sys.stderr)
    verify = bool(getattr(args, "verify", False))
    if verify and getattr(args, "force", False) and not quiet:
        print("mpz encode: note: --verify changes nothing with --force, which encodes "
              "every file again", file=sys.stderr)
    bar = _Bar(enabled=not quiet and not args.json)
    stopped: CorpusStopped | None = None
    try:
        try:
            # SIGTERM (a batch system's kill, `timeout`, Docker) and SIGHUP end the run as
            # Ctrl-C does: the index goes back to its rollback journal, the lock is removed,
            # the local cluster is closed (a QA run of stop 48: a SIGTERM left the committed
            # rows in index.sqlite-wal alone, so a copy of index.sqlite was empty)
            with signals_exit(signal.SIGTERM, getattr(signal, "SIGHUP", None)):
                report = encode_corpus([(j.input, j.output) for j in planned], args.output,
                                       options, workers=workers, scheduler=scheduler,
                                       memory_limit=memory_limit or DEFAULT_MEMORY_LIMIT,
                                       force=bool(getattr(args, "force", False)),
                                       progress=bar, asf=getattr(args, "asf", None),
                                       failed=[(j.input, j.output, j.error) for j in jobs
                                               if j.error is not None], verify=verify)
        except SystemError as exc:
            # a signal heard inside a kernel of this process (--jobs 0) comes as a chain of
            # SystemErrors: its Ctrl-C or SIGTERM, handled below (a review of stop 56)
            end = signal_in(exc)
            if end is None:
                raise
            raise end from None
    except CorpusStopped as exc:
        # the cluster was lost or stopped answering: the table of what finished, then
        # the error (the run's last line)
        stopped, report = exc, exc.report
    except KeyboardInterrupt:
        print(f"mpz encode: {bar.finished(len(planned))} before the interrupt: "
              f"{bar.kinds()}{bar.rest()}", file=sys.stderr)
        raise
    except SystemExit as exc:
        if exc.code not in (128 + signal.SIGTERM, 128 + getattr(signal, "SIGHUP", 1)):
            raise
        print(f"mpz encode: terminated (signal {int(exc.code) - 128}): "
              f"{bar.finished(len(planned))}: {bar.kinds()}{bar.rest()}",
              file=sys.stderr)
        return int(exc.code)
    finally:
        bar.close()
    failed = len(report.failed)
    # a source read with a warning (cut short, a header that disagrees), or part of one
    # that its output does not keep and no option asked to drop, is "warnings only"
    from mpz.encoder import unasked
    warned = any(r.warning or unasked(r.not_kept) for r in report.results)
    # an indexed output found damaged that this run cannot encode again (no source among
    # its inputs) fails the run as a failed file does
    code = found(EXIT_ERROR if failed or stopped or report.damaged
                 else EXIT_WARN if warned else EXIT_OK)
    if args.json:
        doc = report.as_dict()
        doc["planning_errors"] = [{"input": j.input, "reason": j.error}
                                  for j in jobs if j.error is not None]
        print_json(doc)
    elif not quiet:
        print(report.table(printable))
    if args.json or quiet:
        # the table says them; without it, standard error does (--json said them only
        # inside its document, exit 1 with an empty stderr: a JSON audit of stop 59)
        for r in report.failed:
            print(f"mpz encode: error: {printable(r.source)}: {printable(r.reason)}",
                  file=sys.stderr)
        for out, _, why in report.damaged:
            print(f"mpz encode: error: {printable(out)}: damaged: {printable(why)}",
                  file=sys.stderr)
        for r in report.results:        # -q prints nothing on success: a warning is none
            if r.warning:
                print(f"mpz encode: warning: {printable(r.source)}: {printable(r.warning)}",
                      file=sys.stderr)
            for item in unasked(r.not_kept):
                print(f"mpz encode: warning: {printable(r.source)}: not kept: "
                      f"{printable(item)}", file=sys.stderr)
    if stopped is not None:
        print(f"mpz encode: error: {printable(str(stopped))}", file=sys.stderr)
        wal = f"{report.index}-wal" if report.index else ""
        if wal and os.path.exists(wal):
            # a full disk left no room to fold the log back into the index, so a copy of
            # index.sqlite alone was an empty index (a corpus QA run of stop 76)
            print(f"mpz encode: note: the index's rows are partly in {printable(wal)} (it "
                  "could not be folded into the index: a full disk, or another program "
                  "holding the index open): copy it with the index, or run again",
                  file=sys.stderr)
        left = len(report.not_run)
        print(f"mpz encode: {_plural(len(jobs), 'input')}: {len(jobs) - failed - left} "
              f"done, {failed} failed, {left} not run", file=sys.stderr)
    elif failed:        # the closing line of a sequential batch, on stderr even with -q
        print(f"mpz encode: {_plural(len(jobs), 'input')}: {len(jobs) - failed} done, "
              f"{failed} failed", file=sys.stderr)
    return code


def _plural(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"
