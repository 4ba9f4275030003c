"""What every MPZ command shares: exit codes, the parser, escaping, JSON, quiet broken pipes.

One table for ``mpz``, ``mpzinfo``, ``mpz-conformance`` and ``spec_example``
(README.md, "Command exit codes"):

====  ===================================================================
code  meaning
====  ===================================================================
0     ok (``mpz-conformance``: every selected vector passed)
1     warnings only (``mpz-conformance``: at least one vector failed)
2     errors in the input or the data (a file, an output path, the codec);
      in a batch: at least one input failed (each is reported)
3     out of memory: the input may well be valid, this machine could not
      hold what it needs (spec §8, "Allocation failure"); not a verdict
64    usage error: bad options or arguments (argparse's errors included)
70    internal error: a bug in mpz (its traceback is printed), never a verdict on
      the input; it exited 1, which says "warnings only"
130   interrupted with Ctrl-C ("interrupted", no traceback, from the first import)
143   terminated (SIGTERM) while writing an output (129: SIGHUP, as when the
      terminal closes); ``mpz-conformance``: stopped by SIGTERM (129: SIGHUP),
      its decoders killed
====  ===================================================================

Output piped into a command that stops reading (``mpzinfo -vv *.mpz | head``)
ends the tool quietly, with no ``BrokenPipeError`` traceback, and with the worst
code of what it had found by then (:func:`found`): a failed file, or a verdict
decided before its report was printed; 0 when it had found nothing wrong.

Everything a tool prints that comes from a file (names, file names, metadata,
error messages quoting them) goes through :func:`printable`, so a marker
called ``"\\x1b]0;pwned\\x07"`` cannot drive the terminal. Every ``--json``
document is written by :func:`json_text`: strict JSON, ``null`` for NaN and
infinities.
"""
from __future__ import annotations

import argparse
from collections.abc import Callable, Iterable, Iterator, Mapping
import contextlib
import difflib
import errno
import functools
import io
import itertools
import json
import math
import os
import re
import signal
import sys
import threading
from typing import IO, Any, NoReturn, ParamSpec
import weakref

from mpz._worker import command_main, ignore_sigint_when_done, release_sigint

EXIT_OK = 0
EXIT_WARN = 1
EXIT_ERROR = 2
EXIT_MEMORY = 3
EXIT_USAGE = 64
EXIT_BUG = 70                   # sysexits.h's EX_SOFTWARE
EXIT_INTERRUPTED = 130

#: ``mpz-conformance``'s code for "at least one vector failed" (the code of EXIT_WARN)
EXIT_FAILED = EXIT_WARN

#: one line for ``--help`` epilogs
EXIT_CODES_HELP = ("exit codes: 0 ok, 1 warnings only, 2 errors in the input, "
                   "3 out of memory, 64 usage error, 70 a bug in mpz, 130 interrupted, "
                   "143 terminated while writing (SIGHUP: 129)")

_P = ParamSpec("_P")


# -- escaping ----------------------------------------------------------------------------

def _escape_char(ch: str) -> str:
    o = ord(ch)
    if 0xDC80 <= o <= 0xDCFF:          # a byte os.fsdecode could not decode (surrogateescape)
        return f"\\x{o - 0xDC00:02x}"
    if o <= 0xFF:
        return f"\\x{o:02x}"
    if o <= 0xFFFF:
        return f"\\u{o:04x}"
    return f"\\U{o:08x}"


def printable(text: object) -> str:
    """``text`` safe to print on a terminal: every non-printable character escaped.

    Control characters (ESC, BEL, CR, LF, TAB, DEL, C1), Unicode format
    characters (bidirectional overrides, zero-width joiners), line and
    paragraph separators and undecodable file-name bytes become ``\\xNN``,
    ``\\uNNNN`` or ``\\UNNNNNNNN``; everything else (accents, CJK, the space)
    stays as it is.

    >>> printable("LHEE\\x1b[2J")
    'LHEE\\\\x1b[2J'
    >>> printable("Ferse rechts")
    'Ferse rechts'
    """
    s = text if isinstance(text, str) else str(text)
    if s.isprintable():
        return s
    return "".join(ch if ch.isprintable() else _escape_char(ch) for ch in s)


def path_text(path: str | os.PathLike[str]) -> str:
    """A file name as the tools print it (escaped by :func:`printable`)."""
    return printable(os.fspath(path))


# -- JSON --------------------------------------------------------------------------------

def _utf8(s: str) -> str:
    """``s``, with the bytes that a reader kept as lone surrogates (``surrogateescape``:
    a C3D's POINT:UNITS of 0xFF 0xFE) written as ``\\xff``: JSON text is UTF-8, and
    printing a lone surrogate wrote those raw bytes into it (a QA run)."""
    try:
        s.encode("utf-8")
    except UnicodeEncodeError:
        return s.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
    return s


_NONE = object()


class Streamed(list):
    """A JSON array whose items :func:`print_json` writes one by one as ``items()`` makes
    them, so a report of millions of rows is never held whole: ``mpz summary --json`` of a
    valid file of 2^20 segments took 2.1 GB (a security QA run of stop 73).

    Whether it is empty (written ``[]``) is found by making its first item, which the
    writer asks before the others (a flag given beside it could be wrong, and an empty
    array with a false one was written ``[`` and ``]`` on two lines: a review of stop 74).
    Anywhere else (:func:`json_text`) it is made into a list first."""

    def __init__(self, items: Callable[[], Iterable[Any]]) -> None:
        super().__init__()
        self._items = items
        self._rest: Iterator[Any] | None = None
        self._first: Any = _NONE

    def _start(self) -> None:
        if self._rest is None:
            self._rest = iter(self._items())
            self._first = next(self._rest, _NONE)

    def __bool__(self) -> bool:
        self._start()
        return self._first is not _NONE

    def __iter__(self) -> Iterator[Any]:
        self._start()
        first, rest = self._first, self._rest
        self._rest, self._first = None, _NONE          # a second pass starts again
        if first is _NONE or rest is None:
            return iter(())
        return (jsonable(x, streamed=True) for x in itertools.chain((first,), rest))


def jsonable(v: Any, *, streamed: bool = False) -> Any:
    """``v`` with NaN and infinities as None, numpy scalars and arrays as Python values;
    a :class:`Streamed` array kept as it is with ``streamed``, else made a list."""
    if isinstance(v, Streamed):
        return v if streamed else [jsonable(x) for x in v._items()]
    if isinstance(v, float):
        return v if math.isfinite(v) else None
    if isinstance(v, dict):
        return {_utf8(str(k)): jsonable(x, streamed=streamed) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [jsonable(x, streamed=streamed) for x in v]
    if isinstance(v, str):
        return _utf8(v)
    if isinstance(v, (int, bool)) or v is None:
        return v
    tolist = getattr(v, "tolist", None)     # numpy scalars and arrays
    if callable(tolist):
        return jsonable(tolist())
    return v


def json_text(doc: Any, *, indent: int | None = 2, ascii_only: bool = False) -> str:
    """The one JSON writer of every ``--json`` output: strict JSON, ``null`` for non-finite.

    ``allow_nan=False`` makes a non-finite value that slipped through an error,
    not an ``Infinity`` token that strict parsers reject. ``ascii_only`` writes every
    other character as a ``\\uXXXX`` escape (for a stream that is not UTF-8).

    >>> json_text({"rate": float("inf"), "k": [1.5, float("nan")]}, indent=None)
    '{"rate": null, "k": [1.5, null]}'
    """
    return json.dumps(jsonable(doc), indent=indent, allow_nan=False,
                      ensure_ascii=ascii_only)


def _is_utf8(stream: object) -> bool:
    """Whether ``stream`` encodes text as UTF-8 (a stream with no encoding counts as one)."""
    import codecs
    encoding = getattr(stream, "encoding", None)
    if not isinstance(encoding, str):
        return True
    try:
        return codecs.lookup(encoding).name == "utf-8"
    except LookupError:
        return False


def print_json(doc: Any, *, file: IO[str] | None = None, indent: int | None = 2) -> None:
    """Print ``doc`` (:func:`json_text`); on a stream that is not UTF-8 (a Latin-1 or C
    locale with ``PYTHONUTF8=0``, ``PYTHONIOENCODING=ascii``) with ``\\uXXXX`` escapes,
    which every ASCII-compatible encoding holds: a marker named "Ferse_rechts_\u00fc"
    failed to encode there, a traceback and exit 70 (a QA run of the CLI plumbing)."""
    out = sys.stdout if file is None else file
    ascii_only = not _is_utf8(out)
    if not _holds_streamed(doc):
        print(json_text(doc, indent=indent, ascii_only=ascii_only), file=out)
        return
    # the same text as json_text's (json.dumps with an indent runs this same pure-Python
    # encoder), written in blocks of about 64 KB as it is made
    encoder = json.JSONEncoder(indent=indent, allow_nan=False, ensure_ascii=ascii_only)
    block: list[str] = []
    size = 0
    for part in encoder.iterencode(jsonable(doc, streamed=True)):
        block.append(part)
        size += len(part)
        if size >= 1 << 16:
            _started(out, False)
            out.write("".join(block))
            block.clear()
            size = 0
    block.append("\n")
    _started(out, False)
    out.write("".join(block))
    _started(out, True)


#: the streams that :func:`print_json` began a streamed document on, in this command,
#: and whether it is complete
_STARTED: weakref.WeakKeyDictionary[Any, bool] = weakref.WeakKeyDictionary()


def _started(out: IO[str], complete: bool) -> None:
    with contextlib.suppress(TypeError):         # a stream that takes no weak reference
        _STARTED[out] = complete


def document_started(file: IO[str] | None = None) -> bool | None:
    """Whether a streamed document was begun on ``file`` (standard output) since
    :func:`forget_documents`: None if not, else whether it is complete. A command that
    fails after that cannot print its ``mpz-error/1`` document there, behind the text
    (a review of stop 74: the two together did not parse); its error goes to standard
    error alone."""
    return _STARTED.get(sys.stdout if file is None else file)


def forget_documents() -> None:
    """Start a command: no document begun (a command run in the same process before)."""
    _STARTED.clear()


def _holds_streamed(v: Any) -> bool:
    """Whether a :class:`Streamed` array is in ``v`` (dicts and lists, not inside one)."""
    if isinstance(v, Streamed):
        return True
    if isinstance(v, dict):
        return any(_holds_streamed(x) for x in v.values())
    if isinstance(v, (list, tuple)):
        return any(_holds_streamed(x) for x in v)
    return False


#: the schema of the document a failing command prints with ``--json`` (docs/json.md)
ERROR_SCHEMA = "mpz-error/1"


def json_error(exc: BaseException | str, path: str | None = None) -> dict[str, Any]:
    """What went wrong, as every ``--json`` document says it (docs/json.md, "error"): the
    exception's class (None for a message of the command's own) and message, and an
    :class:`~mpz.errors.MPZError`'s path (else ``path``), offset, chunk and spec section;
    None where unknown."""
    from mpz.errors import MPZError
    mpz_error = exc if isinstance(exc, MPZError) else None
    message = (mpz_error.message if mpz_error is not None else
               exc if isinstance(exc, str) else str(exc))
    # the first public class: a private subclass (encoder._NodeNameError) is the
    # EncoderError a caller catches
    public = None if isinstance(exc, str) else next(
        c.__name__ for c in type(exc).__mro__ if not c.__name__.startswith("_"))
    return {"class": public,
            "message": message,
            "path": mpz_error.path if mpz_error is not None and mpz_error.path else path,
            "offset": None if mpz_error is None else mpz_error.offset,
            "chunk": None if mpz_error is None else mpz_error.chunk,
            "section": None if mpz_error is None else mpz_error.section}


def json_failure(command: str, exc: BaseException | str, status: str = "error", *,
                 path: str | None = None) -> dict[str, Any]:
    """The document (schema ``mpz-error/1``) a command run with ``--json`` prints on stdout
    when it fails (exit 2, or 3 with ``status`` "memory"): a failing ``mpz compare``,
    ``summary``, ``search`` or ``bench --json`` printed nothing (a CLI audit), and ``mpz
    show`` and ``mpz encode`` printed documents of other shapes."""
    return {"schema": ERROR_SCHEMA, "command": f"mpz {command}", "status": status,
            "error": json_error(exc, path)}


# -- argument parsing ----------------------------------------------------------------------

#: what a word that is no option or command of mpz most likely meant, said where the
#: parser has the word beside it (``--lossy``: mpz encode's; ``show``: mpz's commands):
#: difflib's nearest word was wrong for these ("--lossless: did you mean --lossy?", the
#: opposite; "mpz info" had no hint: an animation studio's QA run of stop 75)
MEANT = {
    "--lossless": ("--lossy", "MPZ has no lossless flag: an int16 C3D is kept exactly by "
                   "default, and any other input within a bound, so give a fine one: "
                   "--max-error (e.g. 0.01mm), or for BVH and AMC channels --angle-error "
                   "and --translation-error (e.g. 1e-5); --lossy is the other way, no bound"),
    "info": ("show", "mpz show gives what a file holds (mpzinfo: its chunks)"),
}


def _suggest(words: Iterable[str], choices: Iterable[str]) -> str:
    """`` (did you mean --max-error?)`` for the first word close to one of ``choices``, or
    what :data:`MEANT` says of it."""
    pool = list(choices)
    for w in words:
        key = w.split("=", 1)[0]
        beside, meant = MEANT.get(key, (None, ""))
        if beside in pool and key not in pool:
            return f"; {meant}"
        close = difflib.get_close_matches(key, pool, n=1, cutoff=0.6)
        if close:
            return f"; did you mean {close[0]}?"
    return ""


#: a negative number, which argparse takes for a value, not an option
_NUMBER = re.compile(r"-\d+|-\d*\.\d+")

#: the options that take a length with its unit (the unit hint is for their commands)
LENGTH_OPTIONS = frozenset({"--max-error", "--bound", "--grid", "--group-error",
                            "--translation-error"})


class Parser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose usage errors exit with :data:`EXIT_USAGE` (64), not 2.

    Unknown options are reported by the parser that was parsing them: ``mpz
    encode --max-eror 1mm`` prints ``mpz encode``'s usage and "did you mean
    --max-error?" (difflib), not the top-level usage. A mistyped subcommand
    gets the same hint.
    """

    #: the parsers of the command's other subcommands (set by the command's parser)
    family: Mapping[str, argparse.ArgumentParser] = {}

    #: the words this parser was given (:meth:`parse_known_args`)
    _words: list[str] = []

    def error(self, message: str) -> NoReturn:
        if message.startswith(("the following arguments are required: ",
                               "one of the arguments ")):
            # and "mpz-conformance --decodr x" said only "one of the arguments --decoder
            # --encoder is required" (a newcomer's QA run, stop 73)
            # argparse says what is missing before what it did not know: "mpz --bogus",
            # "mpz encode -x.trc" said "the following arguments are required" and no more
            # (a QA run of the CLI plumbing)
            unknown = self._unknown_options(self._words)
            if unknown:
                self.error(f"unrecognized arguments: {' '.join(unknown)}")
        if message.startswith("unrecognized arguments: "):
            words = message[len("unrecognized arguments: "):].split()
            options = [w for w in words if w.startswith("-")]
            elsewhere = self._elsewhere(options)
            message += "".join(elsewhere.values()) + _suggest(
                [w for w in options if w not in elsewhere], self._option_strings())
            # "--max-error 1 mm" (a newcomer's QA run: no hint); not the value of an option
            # this command lacks ("mpz decode --units cm", a QA run of stop 62), but after
            # "--max-eror=1" (the review of stop 62)
            if any(w in ("mm", "cm", "m", "in") and not (
                    i and words[i - 1].startswith("-") and "=" not in words[i - 1])
                   for i, w in enumerate(words)) and LENGTH_OPTIONS & set(self._option_strings()):
                message += "; a length takes its unit without a space, e.g. --max-error 1mm"
            named = [w for w in options if os.path.lexists(w)]
            if named:
                message += (f"; {named[0]} is a file: put -- before a file name that begins "
                            f"with -, or write ./{named[0]}")
        elif message.startswith("argument ") and message.endswith(": expected one argument"):
            # "--max-error -1mm": argparse takes -1mm for an option and says only that the
            # value is missing (a newcomer's QA run, stop 73)
            flags = set(message[len("argument "):-len(": expected one argument")].split("/"))
            words = self._words
            value = next((words[i + 1] for i, w in enumerate(words[:-1])
                          if w in flags and re.match(r"-[0-9.]", words[i + 1])), None)
            if value is not None:
                flag = next(iter(sorted(flags, key=len, reverse=True)))
                message += (f"; a length must be above 0, and {value} reads as an option"
                            if flags & LENGTH_OPTIONS else
                            f"; {value} reads as an option: write {flag}={value}")
        elif "invalid choice: " in message:
            bad = message.split("invalid choice: ", 1)[1].split(" ", 1)[0].strip("'\"")
            message += _suggest([bad], self._subcommands())
        self.print_usage(sys.stderr)
        print(f"{self.prog}: error: {printable(message)}", file=sys.stderr)
        raise SystemExit(EXIT_USAGE)

    def _print_message(self, message: str, file: Any = None) -> None:
        """argparse's, but a failed write of ``--help`` or ``--version`` to standard output
        is raised (argparse drops it: ``mpz encode -h > /dev/full`` exited 0), to be
        reported by :func:`reports_ctrl_c`; one to standard error is still dropped."""
        if message and file is not None and file is sys.stdout:
            file.write(message)
            return
        super()._print_message(message, file)

    def _option_strings(self) -> list[str]:
        return [s for a in self._actions for s in a.option_strings if s.startswith("--")] + \
            [s for a in self._actions for s in a.option_strings if not s.startswith("--")]

    def _unknown_options(self, words: Iterable[str]) -> list[str]:
        """The words before ``--`` that look like options this parser does not know (not a
        known option, a prefix of one of its long options, a cluster of its short ones or
        a negative number; the value after an option that takes one is skipped)."""
        known = {s: a for a in self._actions for s in a.option_strings}
        out: list[str] = []
        takes_value = False
        for w in words:
            if takes_value:
                takes_value = False
                continue
            if w == "--":
                break
            if not w.startswith("-") or w == "-" or _NUMBER.fullmatch(w):
                continue
            key = w.split("=", 1)[0] if w.startswith("--") else w[:2]
            action = known.get(key)
            if action is None and key.startswith("--"):
                close = [a for s, a in known.items() if s.startswith(key)]
                action = close[0] if len(close) == 1 else None
            if action is None:
                out.append(w)
            elif action.nargs != 0 and w == key:        # its value is the next word
                takes_value = True
        return out

    def _elsewhere(self, words: Iterable[str]) -> dict[str, str]:
        """``; --units is an option of mpz encode`` for each of ``words`` that is an option
        of another subcommand of the same command, by word ("mpz decode --units cm" was
        offered --quiet)."""
        out = {}
        for w in words:
            key = w.split("=", 1)[0]
            owners = sorted({p.prog for p in self.family.values() if p is not self and
                             isinstance(p, Parser) and key in p._option_strings()})
            if owners:
                out[w] = f"; {key} is an option of {' and '.join(owners)}"
        return out

    def _subcommands(self) -> list[str]:
        out: list[str] = []
        for a in self._actions:
            if isinstance(a, argparse._SubParsersAction):
                out += list(a.choices)
        return out

    def add_subparsers(self, **kwargs: Any) -> Any:
        kwargs.setdefault("parser_class", SubcommandParser)
        return super().add_subparsers(**kwargs)

    def parse_known_args(self, args: Any = None, namespace: Any = None) -> Any:
        self._words = [str(w) for w in (sys.argv[1:] if args is None else args)]
        for action in self._actions:            # each subcommand knows its siblings
            if isinstance(action, argparse._SubParsersAction):
                for parser in action.choices.values():
                    if isinstance(parser, Parser):
                        parser.family = action.choices
        return super().parse_known_args(args, namespace)


class SubcommandParser(Parser):
    """The parser of one subcommand: it rejects what it does not know itself."""

    def parse_known_args(self, args: Any = None,
                         namespace: Any = None) -> Any:
        ns, extras = super().parse_known_args(args, namespace)
        if extras:
            self.error(f"unrecognized arguments: {' '.join(extras)}")
        return ns, extras


class _Version(argparse.Action):
    """``--version``: ``PROG VERSION (source FINGERPRINT)``, :func:`mpz.identity`, read as the
    option is given (a few ms: the package's source is hashed), not as the parser is built.
    The version alone was 0.1.0 for every development checkout, so a bug report or two
    hosts compared by it could not tell which code ran."""

    def __init__(self, option_strings: list[str], dest: str = argparse.SUPPRESS,
                 default: str = argparse.SUPPRESS,
                 help: str = "show the version and the source fingerprint, and exit"
                 ) -> None:
        super().__init__(option_strings, dest, nargs=0, default=default, help=help)

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: Any, option_string: str | None = None) -> NoReturn:
        import mpz
        print(f"{parser.prog} {mpz.identity()}")        # on stdout, as argparse's own
        parser.exit()


def add_version(parser: argparse.ArgumentParser) -> None:
    """Give ``parser`` the ``--version`` of every MPZ command (:class:`_Version`)."""
    parser.add_argument("--version", action=_Version)


# -- memory --------------------------------------------------------------------------------

#: the commands that take ``--max-samples`` (a lower limit on what a decode holds)
MAX_SAMPLES_COMMANDS = ("decode", "show", "mpzinfo")


def memory_message(exc: MemoryError, command: str) -> str:
    """The one report of an allocation failure (spec §8: a resource error, not a verdict).
    ``--max-samples`` is offered only by the commands that have it (encode advised it)."""
    what = str(exc).strip()
    detail = f" ({printable(what)})" if what else ""
    # (it bounds the decode of an .mpz alone: `mpz show walk.trc` was offered it, QA stop 51)
    cure = (", or lower --max-samples for an .mpz input" if command in MAX_SAMPLES_COMMANDS
            else "")
    return (f"out of memory{detail}; the input may be valid: this machine could not hold "
            f"what it needs (free memory or raise the limit{cure})")


def bound_text(x: float, digits: int = 6) -> str:
    """A bound ``x`` to ``digits`` significant digits, rounded up: a bound printed shorter
    than it is must not be below it (``joints within 1.16 mm`` was printed for 1.16141 mm,
    which a user's own check then passed: an archive team's QA run of stop 72). ``%g``
    where that is not below ``x``, and for 0 or a value that is not finite.

    >>> bound_text(1.16141, 3), bound_text(1.16141, 4), bound_text(0.01), bound_text(2.0, 3)
    ('1.17', '1.162', '0.01', '2')
    """
    text = f"{x:.{digits}g}"
    if not math.isfinite(x) or x == 0 or float(text) >= x:
        return text
    step = 10.0 ** (math.floor(math.log10(abs(x))) - digits + 1)
    up = (math.floor(x / step) + 1) * step
    text = f"{up:.{digits}g}"
    while float(text) < x:                 # the product rounded below: one step more
        up += step
        text = f"{up:.{digits}g}"
    return text


# -- exit codes of a batch, and of a report cut short --------------------------------------

#: how bad each exit code is, for the code of a batch and of a report cut short
_SEVERITY = {EXIT_OK: 0, EXIT_WARN: 1, EXIT_ERROR: 2, EXIT_MEMORY: 3, EXIT_USAGE: 4}


def worst(codes: Iterable[int]) -> int:
    """The exit code of a batch: its worst job's (usage > memory > error > warning > ok)."""
    out = EXIT_OK
    for c in codes:
        if _SEVERITY.get(c, 2) > _SEVERITY.get(out, 2):
            out = c
    return out


#: the worst exit code the running command has found so far (:func:`found`)
_found = [EXIT_OK]
#: the running command's name for its messages ("mpz encode"), once its arguments are
#: parsed (:func:`running`); before, the program's
_running: list[str | None] = [None]


def running(name: str) -> None:
    """Name the running command (``mpz encode``) for the messages of
    :func:`reports_ctrl_c`, which wraps the whole program before it knows the command."""
    _running[0] = name


def found(code: int) -> int:
    """Note ``code`` as found by the running command (a job's result; a verdict decided
    before its report is printed) and return it. A reader that closes the pipe in the
    middle of the output ends the command with the worst code found
    (:func:`quiet_broken_pipe`): it exited 0 after an error line had been printed (a docs
    QA run, stop 52: ``mpzinfo -vv BAD.mpz | head -1``)."""
    _found[0] = worst((_found[0], code))
    return code


# -- broken pipes --------------------------------------------------------------------------

def _silence_stdout() -> None:
    """Point stdout at /dev/null so that Python's final flush cannot fail again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):  # stdout is not a real file (e.g. captured in tests)
        pass


def _reserve(fd: int, flags: int) -> bool:
    """Open the null device on ``fd`` if it is closed (``>&-``); True if it was closed."""
    try:
        os.fstat(fd)
        return False
    except OSError:
        pass
    try:
        null = os.open(os.devnull, flags)
        if null != fd:
            os.dup2(null, fd)
            os.close(null)
    except OSError:
        return False
    return True


def standard_streams() -> None:
    """Make the three standard streams safe to use, once at a command's start.

    A standard stream closed by the caller (``mpz show x >&-``, ``2>&-``, ``<&-``) is
    None in Python, and its descriptor is free: ``print(..., file=sys.stderr)`` then
    wrote the notes, even a traceback, into standard output (into ``-o -``'s CSV or
    MPZ data), ``sys.stdout.flush()`` raised AttributeError (exit 70, a traceback),
    and the next file opened took the descriptor. Here the null device takes each
    closed descriptor: standard error's notes are dropped, standard input stays None
    (the commands say "there is no standard input"), and standard output is opened
    read-only, so that what a command prints there fails as ``ls >&-`` does: "cannot
    write standard output: Bad file descriptor", exit 2 (:func:`reports_ctrl_c`).

    Standard output that is not UTF-8 (a Latin-1 locale, ``LC_ALL=C`` with
    ``PYTHONUTF8=0``, ``PYTHONIOENCODING=ascii``) escapes what it cannot encode (a
    marker called "tête", mpzinfo's "→") as ``\\xNN``, as standard error does; it
    raised UnicodeEncodeError: a traceback and exit 70 (a QA run of the CLI plumbing).
    """
    _reserve(0, os.O_RDONLY)
    if sys.stdout is None and _reserve(1, os.O_RDONLY):
        sys.stdout = io.TextIOWrapper(io.FileIO(1, "w", closefd=False),
                                      encoding="utf-8", errors="backslashreplace")
    if sys.stderr is None and _reserve(2, os.O_WRONLY):
        sys.stderr = io.TextIOWrapper(io.FileIO(2, "w", closefd=False), encoding="utf-8",
                                      errors="backslashreplace", line_buffering=True)
    for name, fd in (("stdout", 1), ("stderr", 2)):
        _patient(name, fd)
    out = sys.stdout
    if (isinstance(out, io.TextIOWrapper) and not _is_utf8(out)
            and out.errors in ("strict", "surrogateescape")):
        with contextlib.suppress(Exception):
            out.reconfigure(errors="backslashreplace")


class _PatientWriter(io.RawIOBase):
    """The raw file of a standard stream that a parent set non-blocking (``O_NONBLOCK``,
    shared by every process that holds the pipe): a write that would block waits until
    the reader has made room (:func:`_patient`)."""

    def __init__(self, fd: int) -> None:
        super().__init__()
        self._fd = fd

    def writable(self) -> bool:
        return True

    def fileno(self) -> int:
        return self._fd

    def isatty(self) -> bool:
        return os.isatty(self._fd)

    def write(self, data: Any) -> int:
        import select
        while True:
            try:
                return os.write(self._fd, data)
            except BlockingIOError:
                select.select([], [self._fd], [])


def _patient(name: str, fd: int) -> None:
    """Give ``sys.<name>`` a raw file that waits (:class:`_PatientWriter`) when ``fd`` is a
    non-blocking pipe: with a reader slower than mpz writes, a write raised
    BlockingIOError, and ``mpz encode x -o - | slow`` ended with 64 KiB of its data, a
    traceback and exit 120 (a QA run of the CLI plumbing)."""
    stream = getattr(sys, name)
    if not isinstance(stream, io.TextIOWrapper):
        return
    try:
        if stream.fileno() != fd or os.get_blocking(fd):
            return
    except (OSError, ValueError):           # no descriptor (a test's capture)
        return
    stream.flush()
    setattr(sys, name, io.TextIOWrapper(
        io.BufferedWriter(_PatientWriter(fd)), encoding=stream.encoding,
        errors=stream.errors, line_buffering=stream.line_buffering,
        write_through=stream.write_through))


def quiet_broken_pipe(main: Callable[_P, int]) -> Callable[_P, int]:
    """Decorate a command's ``main``: a reader closing the pipe ends the command quietly.

    The decorated function flushes stdout before returning, so that a broken
    pipe shows up here and not in the interpreter's exit handler. It then returns the
    worst code the command had noted with :func:`found`, else 0. It first makes the
    standard streams safe (:func:`standard_streams`).
    """

    @functools.wraps(main)
    def wrapper(*args: _P.args, **kwargs: _P.kwargs) -> int:
        _found[0] = EXIT_OK
        standard_streams()
        try:
            code = main(*args, **kwargs)
            sys.stdout.flush()
        except BrokenPipeError:
            _silence_stdout()
            code = _found[0]       # the worst it had found (found()), else 0
        return code

    return wrapper


# -- Ctrl-C --------------------------------------------------------------------------------

#: errors of a write that the machine's state causes: no space, a file-size limit, a quota,
#: an I/O error (what :func:`reports_ctrl_c` reports as an error, not a bug)
OUTPUT_FULL = frozenset({errno.ENOSPC, errno.EFBIG, errno.EDQUOT, errno.EIO})


def _failed_output(exc: OSError) -> str:
    """Which output a write error ``exc`` that reached :func:`reports_ctrl_c` came from:
    the file it names, else standard output. Every file a command writes goes through
    :func:`mpz.api.atomic_output`, whose errors name their file (an
    :class:`~mpz.errors.EncoderError`, reported as such); what is left unnamed is a write
    to standard output (a print, a flush, ``-o -``)."""
    return repr(exc.filename) if exc.filename else "standard output"


def reports_ctrl_c(message: str) -> Callable[[Callable[_P, int]], Callable[_P, int]]:
    """Decorate a command's ``main``: SIGINT, held since the command's first import of mpz
    (:mod:`mpz._worker`), is released first, and a Ctrl-C anywhere in ``main`` (a held one
    included, and one a finalizer dropped) prints ``message`` and exits
    :data:`EXIT_INTERRUPTED`, without a traceback; one that lands in numba's or llvmlite's
    code is put off until the main thread has left it (:func:`ctrl_c_outside_compiler`).

    An exception that no command handles is a bug: its traceback is printed, then a line
    that says so, and the code is :data:`EXIT_BUG`. It exited 1, which means "warnings
    only" (``mpz-conformance``: "a vector failed"), so a script took a crash of
    ``mpzinfo -vv`` on a valid file for a warning (a QA of stop 48). A MemoryError is left
    to the command (each reports its own, exit 3), and a BrokenPipeError to the quiet
    handling of a closed pipe (:func:`quiet_broken_pipe`)."""
    prog = message.split(":")[0] if ":" in message else "mpz"

    def decorate(main: Callable[_P, int]) -> Callable[_P, int]:
        @functools.wraps(main)
        def wrapper(*args: _P.args, **kwargs: _P.kwargs) -> int:
            _running[0] = None
            before = command_main(True)          # messages spell options as the CLI does
            try:
                with ctrl_c_outside_compiler():
                    release_sigint()
                    code = main(*args, **kwargs)
                    # here, not in the interpreter's exit: a buffered report that cannot
                    # be written (> /dev/full) is then this command's error, not a
                    # traceback and exit 120 (PYTHONUNBUFFERED, set where the QA runs
                    # ran, had hidden it)
                    sys.stdout.flush()
                    return code
            except KeyboardInterrupt:
                print(message, file=sys.stderr)
                return leave_stuck_threads(EXIT_INTERRUPTED)
            except SystemExit as exc:
                leave_stuck_threads(exc.code)
                if exc.code in (0, None):       # --help, --version: argparse's own print
                    failed = _stdout_failure(prog)
                    if failed is not None:
                        return failed
                raise
            except SystemError as exc:
                end = signal_in(exc)
                if isinstance(end, SystemExit):
                    # SIGTERM (signals_exit) heard inside a kernel: the exit it asked for,
                    # not a bug (a review of stop 56: exit 70 and a traceback)
                    leave_stuck_threads(end.code)
                    raise end from None
                if end is None:
                    return _bug(prog)
                print(message, file=sys.stderr)
                return leave_stuck_threads(EXIT_INTERRUPTED)
            except (MemoryError, BrokenPipeError):
                raise            # each command's own report; a pipe closed by `head`
            except OSError as exc:
                if isinstance(exc, FileNotFoundError) and _working_folder_gone():
                    # os.path.abspath of a relative path raised deep in a command (a QA run
                    # of stop 54: exit 70); absolute paths still work there
                    print(f"{prog}: error: the current folder no longer exists (deleted?): "
                          "cd to one that does, or give absolute paths", file=sys.stderr)
                    return EXIT_ERROR
                if exc.errno not in OUTPUT_FULL and not _closed_stdout(exc):
                    return _bug(prog)
                # a full disk or a file-size limit where a command writes (standard output
                # above all: mpzinfo > /dev/full): the machine's state, not a bug (a QA run).
                # Which output failed: "mpz: error: cannot write" did not say, and left
                # an encode's user to wonder whether the .mpz beside it was whole
                print(f"{_running[0] or prog}: error: cannot write {_failed_output(exc)}: "
                      f"{exc.strerror or exc}", file=sys.stderr)
                if not exc.filename:    # what stays in its buffer would fail again at exit
                    _silence_stdout()
                return EXIT_ERROR
            except Exception:
                return _bug(prog)
            finally:
                command_main(before)
                ignore_sigint_when_done()

        return wrapper

    return decorate




@contextlib.contextmanager
def ctrl_c_outside_compiler() -> Iterator[None]:
    """While the block runs in the main thread with Python's own SIGINT handler: a Ctrl-C
    raises KeyboardInterrupt as that handler does, but not while the main thread runs
    numba's or llvmlite's Python code (:func:`mpz.api.in_compiler`): there it is put off
    until it has left it (:class:`mpz.api.SignalsPutOff`; a second Ctrl-C is not put
    off). A KeyboardInterrupt raised in a kernel's callbacks or its loading left a tuple
    with a missing item or a kernel half loaded: ``mpz search`` ended in a segmentation
    fault in 3 of 65 interrupted runs, ``mpz encode`` in 1 of 150 (a QA run of stop 57).

    A Ctrl-C (or a SIGTERM or SIGHUP that :func:`mpz.api.signals_exit` turns into
    SystemExit) whose exception Python drops is handed back the same way. Python runs a
    signal's handler at the main thread's next instruction, wherever that is; inside a
    finalizer (``__del__``, a weakref callback) the exception cannot leave it, and Python
    prints "Exception ignored in ..." and goes on: the encode then finished and exited 0
    (about 1 in 60 interrupted runs of ``mpz encode``, stops 55-56). Python hands such
    exceptions to :data:`sys.unraisablehook`; this one puts the signal off (the poller
    hands it back once the finalizer has returned) and hands every other exception on,
    and Python's own message when no thread can be started."""
    from mpz.api import SignalsPutOff, in_compiler
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    put_off = SignalsPutOff()
    old_hook = sys.unraisablehook

    def hook(unraisable: Any) -> None:
        signum = _dropped_signal(unraisable.exc_value)
        if signum is None:
            old_hook(unraisable)
            return
        try:
            put_off.later(signum)
        except RuntimeError:           # no thread to be had: Python's word, as before
            old_hook(unraisable)

    def interrupt(signum: int, frame: Any) -> None:
        if in_compiler(frame) and put_off.later(signum):
            return
        raise KeyboardInterrupt

    ours = signal.getsignal(signal.SIGINT) is signal.default_int_handler
    old = signal.signal(signal.SIGINT, interrupt) if ours else None
    sys.unraisablehook = hook
    try:
        yield
    finally:
        try:
            put_off.close()                 # a signal still put off is dropped
        finally:
            if sys.unraisablehook is hook:
                sys.unraisablehook = old_hook
            if ours and signal.getsignal(signal.SIGINT) is interrupt:
                signal.signal(signal.SIGINT, old)


def _dropped_signal(exc: BaseException | None) -> signal.Signals | None:
    """The signal whose handler raised ``exc`` (the end of its chain of SystemErrors, as a
    kernel reports one: :func:`signal_in`): SIGINT for KeyboardInterrupt, the signal of
    ``SystemExit(128 + signum)`` when that signal has a Python handler; None otherwise."""
    end = None if exc is None else signal_in(exc)
    if isinstance(end, KeyboardInterrupt):
        return signal.SIGINT
    if isinstance(end, SystemExit) and isinstance(end.code, int) and end.code > 128:
        with contextlib.suppress(ValueError):
            signum = signal.Signals(end.code - 128)
            if callable(signal.getsignal(signum)):
                return signum
    return None


def leave_stuck_threads(code: Any) -> int:
    """``code``; or, when one of the encoder's threads (:data:`mpz.encoder.CODEC_THREADS`)
    is still running, the process ends here with it (``os._exit``, after flushing its
    output). An interrupted encode has waited :data:`mpz.encoder.INTERRUPT_WAIT_SECONDS`
    for its threads already, so such a thread is stuck: a signal can land while a lock is
    held that it then waits on for ever (numba's compiler lock as a kernel loads), and the
    interpreter's exit joins every thread: a Ctrl-C hung the command, and a second one did
    nothing (a review of stop 56, about 1 in 50 tries)."""
    exit_code = 0 if code is None else code if isinstance(code, int) else EXIT_ERROR
    encoder = sys.modules.get("mpz.encoder")    # not imported: none of its threads runs
    if encoder is not None and any(t.name.startswith(encoder.CODEC_THREADS) and t.is_alive()
                                   for t in threading.enumerate()):
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                stream.flush()
        os._exit(exit_code)
    return exit_code


def _closed_stdout(exc: OSError) -> bool:
    """Whether ``exc`` is a write to a standard output that cannot take one: closed
    (``>&-``, see :func:`standard_streams`) or open for reading (``1</dev/null``)."""
    if exc.errno != errno.EBADF or exc.filename:
        return False
    try:
        import fcntl
        return fcntl.fcntl(1, fcntl.F_GETFL) & os.O_ACCMODE == os.O_RDONLY
    except (ImportError, OSError):
        return True


def _stdout_failure(prog: str) -> int | None:
    """Flush standard output after argparse printed ``--help`` or ``--version`` (it
    swallows its own write errors): :data:`EXIT_ERROR` with a message when that fails
    (``mpz -h > /dev/full`` exited 0), else None. A closed pipe stays quiet."""
    try:
        if sys.stdout is not None:
            sys.stdout.flush()
    except BrokenPipeError:
        raise
    except OSError as exc:
        print(f"{prog}: error: cannot write standard output: {exc.strerror or exc}",
              file=sys.stderr)
        _silence_stdout()
        return EXIT_ERROR
    return None


def _working_folder_gone() -> bool:
    """Whether the process's working folder has been deleted (os.getcwd fails)."""
    try:
        os.getcwd()
    except FileNotFoundError:
        return True
    return False


def _bug(prog: str) -> int:
    """Print the exception being handled as the bug it is (see :func:`reports_ctrl_c`)."""
    import traceback

    from mpz import identity
    traceback.print_exc()
    print(f"{prog}: internal error: this is a bug in mpz {identity()}, not a verdict on "
          "the input; please report it with the traceback above", file=sys.stderr)
    return EXIT_BUG


def interrupted(exc: BaseException) -> bool:
    """Whether ``exc`` is a Ctrl-C as a compiled kernel reports it: a numba kernel that
    hears the KeyboardInterrupt in one of its Python callbacks (``_numba_unpickle``) raises
    ``SystemError: ... returned a result with an exception set``, with the
    KeyboardInterrupt at the end of a chain of such SystemErrors (each the direct cause of
    the next). Any other SystemError is a bug and is not taken for one (a QA of stop 42:
    a Ctrl-C during the Fisher tables or the key-frame fit gave a traceback and exit 1)."""
    return isinstance(signal_in(exc), KeyboardInterrupt)


def signal_in(exc: BaseException) -> KeyboardInterrupt | SystemExit | None:
    """The KeyboardInterrupt (Ctrl-C) or SystemExit (SIGTERM or SIGHUP, as
    :func:`mpz.api.signals_exit` raises it) at the end of ``exc``'s chain of SystemErrors,
    as a compiled kernel reports a signal heard in it (:func:`interrupted`); None for any
    other exception."""
    seen: set[int] = set()
    e: BaseException | None = exc
    while isinstance(e, SystemError) and id(e) not in seen:
        seen.add(id(e))
        e = e.__cause__
    return e if isinstance(e, (KeyboardInterrupt, SystemExit)) else None


def whole_number(low: int) -> Callable[[str], int]:
    """argparse type of a whole number of ``low`` or more."""
    def parse(text: str) -> int:
        try:
            n = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"wants a whole number, got {text!r}") from None
        if n < low:
            raise argparse.ArgumentTypeError(f"wants {low} or more, got {n}")
        return n
    return parse


#: argparse type of a count that may be 0 (``--jobs N``, ``compare --top N``)
count = whole_number(0)


def positive(text: str) -> float:
    """argparse type of a finite number above 0 (``--rate HZ``, ``--angle-error DEG``): nan,
    inf and 0 were judged only after the input was read, as input errors (exit 2)."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"wants a number, got {text!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"wants a finite number above 0, got {text!r}")
    return v


def max_samples(text: str) -> int:
    """argparse type of ``--max-samples N`` (issue 11.1): a lower F x M limit, 1 .. 2^26.

    Spec §8 lets a decoder use lower limits to bound its memory; a file above the
    limit is then rejected with a limit error (exit 2), before anything is decoded.
    """
    from mpz.format import MAX_SAMPLES
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if not 1 <= n <= MAX_SAMPLES:
        raise argparse.ArgumentTypeError(f"{n} is not in 1..{MAX_SAMPLES} (2^26, the limit of "
                                         "spec §8; a decoder may only lower it)")
    return n


#: the help of ``--max-samples`` (mpzinfo, mpz decode, mpz show)
def max_samples_help(needs: str = "decoding needs about 50 bytes per marker-frame") -> str:
    """``--max-samples``'s help, with what the command ``needs`` per marker-frame
    (measured on a file of 2^24 marker-frames, peak RSS; docs/cli.md's figures)."""
    return ("refuse files of more than N marker-frames (F x M, at most 2^26), and below 2^26 "
            f"also of more than 4N analog words or N skeleton channel values: {needs} "
            "(spec §8)")


MAX_SAMPLES_HELP = max_samples_help()
