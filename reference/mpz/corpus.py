"""Whole archives: many motion files encoded in parallel on Dask, into a queryable index.

Contract: :func:`encode_corpus` takes ``(source, output)`` pairs (:func:`mirror_jobs` makes
them for a folder tree) and an output folder ``OUT``. Each file is read, encoded, written
atomically, decoded again to measure its error, and summarised (:mod:`mpz.similarity`); one
row per file goes into ``OUT/index.sqlite`` (:data:`SCHEMA`), which ``mpz search`` and any
SQLite tool read. The run returns a :class:`CorpusReport` (its :meth:`~CorpusReport.table`
is the summary table of ``mpz encode -r``).

* **Parallel on Dask.** Files are tasks of a ``dask.distributed`` cluster: a
  ``LocalCluster`` of ``workers`` processes (one thread each, a memory limit each) by
  default, or an existing cluster at ``scheduler``. ``workers=0`` runs the same tasks in
  this process, one after the other, without Dask.
* **Incremental.** An output is skipped, without being opened (only an AMC's ASF is read,
  :func:`_beside`), when its index row says
  it was written with the same options (:func:`fingerprint`) from a source of the same
  size and modification time, and the output is still there, of the recorded size and
  newer than the source. Otherwise a worker looks at the output: one that carries the
  same fingerprint and the sha256 of the same source (its ``meta`` chunk, keys
  :data:`META_FINGERPRINT` and :data:`META_SHA256`) is *kept*: only its row is rebuilt
  (one older than the source takes a later time). Anything else is encoded again,
  and the report says why (:data:`AGAIN`). With ``verify``, an output up to date by the
  index is read whole and checked on a worker first (:func:`output_problem`), and
  encoded again if damaged (one whose source is not among the inputs: in this process,
  :func:`uncovered_problem`, and said, never encoded); every row's levels are read whole
  and checked against its ``levels_sha256`` (:func:`levels_digest`), and a row whose
  levels changed is rebuilt.
* **Resumable.** Outputs are written through :func:`mpz.api.atomic_output`, so an output
  exists complete or not at all, and the index commits each row as its file finishes.
  After a crash, a kill or Ctrl-C, the next run skips what was done; hidden temporary files
  that a killed worker could not remove are deleted when the run stops and before the
  next one starts.
* **Files the index cannot describe** (:class:`~mpz.similarity.NotDescribable`: one
  frame, fewer than three markers seen) are encoded and indexed without a summary
  (:data:`NO_SUMMARY`), with a note; ``mpz search`` leaves them out.
* **Failures** are per file: bad input and :class:`~mpz.errors.MPZError` of any kind,
  ``OSError`` on a source, a worker killed for exceeding its memory limit. Each is reported
  with its reason (and kept in the index's ``failures`` table) while the other files go
  on. Any other exception is a bug: the run stops, saves what finished, and re-raises it.
* **Outputs that are not ours** (an existing file without our metadata) are replaced only
  with ``force``, which also encodes every file again.

This module touches files (the sources, the outputs, the index); the codec under it does
not.
"""
from __future__ import annotations

import asyncio
from collections.abc import Callable, Collection, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import CancelledError
import contextlib
from dataclasses import asdict, dataclass, field, fields, replace
import datetime
import errno
import functools
import hashlib
import json
import logging
import os
from pathlib import Path
import re
import signal
import sqlite3
import stat
import threading
import time
from typing import TYPE_CHECKING, Any, Protocol, TypeVar, cast, runtime_checkable
import urllib.parse

import numpy as np

from mpz._worker import command_task, in_command, spelled
from mpz.api import _use_force, folder_problem
from mpz.encoder import DEFAULTS, EncodeOptions, unasked
from mpz.errors import EncoderError, MPZError
from mpz.hierarchy import BUILDERS
from mpz.io._common import is_folder, is_utf8, utf8_name, walk
from mpz.similarity import (
    DESCRIPTOR_VERSION,
    EXACT_MAX_FRAMES,
    SUMMARY_LEVELS,
    MotionSummary,
    NotDescribable,
    descriptor,
    features_for,
    from_stored,
)

if TYPE_CHECKING:
    from distributed import Client, Future

    from mpz.motion import Motion

__all__ = ["INDEX_NAME", "NO_SUMMARY", "SCHEMA", "META_FINGERPRINT", "META_SHA256",
           "FileOptions", "FileResult", "CorpusReport", "CorpusStopped",
           "Index", "IndexRow", "encode_corpus", "encode_file", "fingerprint", "output_problem",
           "row_digest",
           "mirror_jobs", "open_index", "sha256_file", "sweep_temporaries",
           "run_in_progress", "DEFAULT_MEMORY_LIMIT", "LOCK_WAIT"]

#: the index's file name inside the output folder
INDEX_NAME = "index.sqlite"
#: ``summary_method`` of a file the index cannot describe (:class:`~mpz.similarity.
#: NotDescribable`: one frame, fewer than three markers seen): encoded and indexed, with
#: no summary and an empty descriptor; not a candidate of ``mpz search``
NO_SUMMARY = "none"
#: version of the index's tables (the ``corpus`` table's ``schema`` value)
SCHEMA_VERSION = 1
#: meta keys the corpus adds to every output
META_FINGERPRINT = "mpz.corpus.fingerprint"
META_SHA256 = "source.sha256"
META_SOURCE = "source"
#: memory limit of each worker of the local cluster. Measured (bench/bench_corpus.py
#: --long, docs/corpus.md): a 30-minute, 41-marker capture at 120 Hz (218,484 frames, NPY)
#: peaks at 1.7 GB in one process (read 0.4, encode 1.7, decode and summary within it); a
#: C3D of 65,535 frames peaked at 2.7 GB in a worker (the C3D reader alone takes about
#: 0.9 GB). Dask's nanny restarts a worker at 95 % of its limit.
DEFAULT_MEMORY_LIMIT = "4GiB"

#: the index's tables (SQLite); docs/corpus.md explains every column
SCHEMA = """
CREATE TABLE IF NOT EXISTS corpus (
    key   TEXT PRIMARY KEY,
    value TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS files (
    output          TEXT PRIMARY KEY,  -- the .mpz, relative to the index's folder
    path            TEXT NOT NULL,     -- the source file (absolute)
    source_sha256   TEXT NOT NULL,
    source_bytes    INTEGER NOT NULL,
    source_mtime_ns INTEGER NOT NULL,
    format          TEXT NOT NULL,     -- the source's extension, e.g. .c3d
    frames          INTEGER NOT NULL,
    markers         INTEGER NOT NULL,
    rate            REAL NOT NULL,     -- frames per second
    units           TEXT NOT NULL,     -- mm, cm, m, in or '' (unknown)
    duration_s      REAL NOT NULL,
    gap_fraction    REAL NOT NULL,     -- share of marker samples that are gaps
    declared_bound  REAL,              -- the hard bound (file units); NULL: none declared
    raw_bytes       INTEGER NOT NULL,  -- positions as float32: frames x markers x 12
    marker_bytes    INTEGER NOT NULL,  -- the signature and the critical chunks (MHDR..MEND)
    analog_bytes    INTEGER NOT NULL,  -- analog samples of a C3D source (cana; 0: none)
    summary_bytes   INTEGER NOT NULL,  -- the smrc or smry chunk, if the options asked for one
    other_bytes     INTEGER NOT NULL,  -- meta and every other ancillary chunk
    total_bytes     INTEGER NOT NULL,  -- the .mpz file
    chunk_bytes     TEXT NOT NULL,     -- JSON: chunk type -> bytes (12-byte frames included)
    ratio           REAL NOT NULL,     -- raw_bytes / total_bytes
    max_error       REAL,              -- measured: decoded vs source, file units
    arms            REAL,              -- measured: average per-frame RMS error
    summary_method  TEXT NOT NULL,     -- exact | blocks:B (see mpz.similarity) | none
    summary_dims    INTEGER NOT NULL,  -- 3 x markers
    descriptor      BLOB NOT NULL,     -- float64 LE features (mpz.similarity.descriptor);
                                       -- empty for summary_method none
    fingerprint     TEXT NOT NULL,     -- of the encode options (mpz.corpus.fingerprint)
    mpz_version     TEXT NOT NULL,     -- the writer: mpz.identity(), "0.1.0 (source 1a2b3c4d5e6f)";
                                       -- the version alone in a row of an older mpz
    encoded_at      TEXT NOT NULL,     -- UTC, ISO 8601
    seconds         REAL NOT NULL,     -- read + encode + write + check + summary, wall
    cpu_seconds     REAL NOT NULL,     -- the same, CPU time of the worker process
    -- said of the file when it was encoded, and said again by a run that finds it up to
    -- date; NULL in a row written by an mpz before these columns (_RECORDED)
    warning         TEXT,              -- the reader's warning about the source; '' none
    not_kept        TEXT,              -- JSON list: what the output does not keep of it
    notes           TEXT,              -- JSON list: the options' notes on the file
    -- sha256 of every column above as written (mpz.corpus.row_digest), so that a value
    -- changed in place is found; NULL in a row written by an mpz before it (unchecked)
    row_sha256      TEXT,
    -- sha256 of the row's levels as written (mpz.corpus.levels_digest); NULL likewise
    levels_sha256   TEXT
);
CREATE INDEX IF NOT EXISTS files_sha256 ON files(source_sha256);
CREATE TABLE IF NOT EXISTS levels (
    output TEXT NOT NULL REFERENCES files(output) ON DELETE CASCADE,
    k      INTEGER NOT NULL,           -- segments
    wssse  REAL NOT NULL,              -- within-segment sum of squared error
    starts BLOB NOT NULL,              -- k x uint32 little-endian: first frame of each
    means  BLOB NOT NULL,              -- k x summary_dims float32 little-endian
    PRIMARY KEY (output, k)
);
CREATE TABLE IF NOT EXISTS failures (
    path   TEXT PRIMARY KEY,           -- the source
    output TEXT,
    reason TEXT NOT NULL,
    at     TEXT NOT NULL
);
"""

_FILE_COLUMNS = ("output", "path", "source_sha256", "source_bytes", "source_mtime_ns", "format",
                 "frames", "markers", "rate", "units", "duration_s", "gap_fraction",
                 "declared_bound", "raw_bytes", "marker_bytes", "analog_bytes", "summary_bytes",
                 "other_bytes", "total_bytes", "chunk_bytes", "ratio", "max_error", "arms",
                 "summary_method", "summary_dims", "descriptor", "fingerprint", "mpz_version",
                 "encoded_at", "seconds", "cpu_seconds")
#: columns added after the first indexes were written (stop 51: a rerun that found a file
#: up to date no longer said its reader's warning or its notes): an index without them
#: gets them (ALTER TABLE, NULL in its rows) when a run opens it for writing, and a row
#: whose value is NULL is read again from its source by the next run (status kept)
_RECORDED = ("warning", "not_kept", "notes")
#: the column of a row's checksum (:func:`row_digest`): SQLite keeps no checksums, and a
#: byte changed inside a stored value (a descriptor, a sha256) passed every check and
#: ranked a search from it (a corpus QA run of stop 55). Added to an older index as
#: _RECORDED are; NULL in its rows, which are not checked until a run writes them again
_CHECKSUM = "row_sha256"
#: the column of the checksum of a row's levels (:func:`levels_digest`): their blobs are
#: checked by length and type on each run, so a value changed inside one passed (stop 57's
#: list). Checked where the levels are read anyway: :meth:`Index.rows` and a run with
#: ``verify``. Added to an older index as ``row_sha256`` is
_LEVELS_CHECKSUM = "levels_sha256"
#: the columns added to ``files`` after the first indexes, in order
_ADDED = (*_RECORDED, _CHECKSUM, _LEVELS_CHECKSUM)
#: the ``corpus`` table's key of the checksum of its other values (:func:`info_digest`):
#: none covered them, and a ``levels`` of 2000 written in place made every mpz search take
#: four minutes (a security QA run of stop 73). Absent from an older index until a run
#: writes its values again; not checked before
_INFO_CHECKSUM = "corpus_sha256"

#: what each column of a ``files`` row may hold, checked as rows are read: SQLite keeps any
#: value in any column, and a row changed by another program (a text in ``frames``, a BLOB
#: path, a rate of 0, a negative wssse) crashed mpz search (exit 70), was blamed on the
#: query, or was shown as it was (a QA run of stop 53). ``text``/``blob``: that type;
#: ``int``: an integer; ``count``: an integer >= 0 (and within :data:`_COUNT_LIMITS`);
#: ``real``: a finite number >= 0; ``rate``: a finite number > 0; a column in ``_NULLABLE``
#: may also be NULL
_COLUMN_KINDS = {
    **dict.fromkeys(("output", "path", "source_sha256", "format", "units", "chunk_bytes",
                     "summary_method", "fingerprint", "mpz_version", "encoded_at",
                     *_RECORDED), "text"),
    "source_mtime_ns": "int",            # before 1970: negative
    **dict.fromkeys(("source_bytes", "frames", "markers", "raw_bytes",
                     "marker_bytes", "analog_bytes", "summary_bytes", "other_bytes",
                     "total_bytes", "summary_dims"), "count"),
    **dict.fromkeys(("duration_s", "gap_fraction", "declared_bound", "ratio", "max_error",
                     "arms", "seconds", "cpu_seconds"), "real"),
    "rate": "rate", "descriptor": "blob",
}
_NULLABLE = frozenset(("declared_bound", "max_error", "arms", *_RECORDED))
#: the limits a row's counts keep besides (spec §8: no file holds more)
_COUNT_LIMITS = {"frames": "MAX_FRAMES", "markers": "MAX_MARKERS"}


def _text(raw: bytes) -> str:
    """A TEXT value as read from the index: UTF-8, and any other byte as a lone surrogate
    (which :func:`_field_problem` refuses)."""
    return raw.decode("utf-8", "surrogateescape")


def _field_problem(column: str, value: Any) -> str | None:
    """Why ``value`` cannot be a ``files`` row's ``column`` (:data:`_COLUMN_KINDS`), or
    None."""
    if value is None:
        return None if column in _NULLABLE else "is NULL"
    kind = _COLUMN_KINDS[column]
    number = isinstance(value, (int, float)) and not isinstance(value, bool)
    if kind == "text" and isinstance(value, str) and not is_utf8(value):
        return f"holds {utf8_name(value)[:40]!r}, a text that is not UTF-8"
    if kind == "text" and isinstance(value, str) or kind == "blob" and isinstance(value, bytes):
        return None
    if kind == "int" and isinstance(value, int) and not isinstance(value, bool):
        return None
    if kind == "count" and isinstance(value, int) and not isinstance(value, bool) and value >= 0:
        import mpz.format as fmt
        limit = getattr(fmt, _COUNT_LIMITS[column]) if column in _COUNT_LIMITS else value
        return None if value <= limit else f"holds {value}, more than {limit}"
    if kind in ("real", "rate") and number and np.isfinite(value) and (
            value > 0 if kind == "rate" else value >= 0):
        return None
    what = {"text": "a text", "blob": "a BLOB", "int": "an integer",
            "count": "a count (an integer >= 0)",
            "real": "a finite number >= 0", "rate": "a finite number > 0"}[kind]
    shown = repr(value if not isinstance(value, (str, bytes)) else value[:40])
    return f"holds {shown}, not {what}"


def _row_problem(row: Mapping[str, Any]) -> str | None:
    """The first column of a ``files`` row that holds what it cannot, said; else a
    checksum that does not match its values (:func:`row_digest`); or None."""
    for column in _COLUMN_KINDS:
        problem = _field_problem(column, row[column])
        if problem is not None:
            return f"its {column} {problem}"
    stored = row.get(_CHECKSUM)
    if stored is not None and stored != row_digest(row):
        return (f"its values are not those written: their {_CHECKSUM} does not match "
                "(a value changed in place)")
    return None


def row_digest(row: Mapping[str, Any]) -> str:
    """The ``row_sha256`` of a ``files`` row: the hexadecimal sha256 of its columns of
    :data:`_FILE_COLUMNS` and :data:`_RECORDED`, in that order, each as its name, a tab,
    its value and a line end, where a value is ``repr`` of the number (an integer as
    such, a real as a float, so that 2 and 2.0 agree), the UTF-8 of a text, the hex of a
    BLOB, or ``NULL``. What SQLite gives back of each value written gives the same
    digest."""
    parts = []
    for column in _DIGESTED:
        v = row[column]
        text = (repr(float(v)) if column in _REALS and isinstance(v, (int, float))
                else _value_text(v))
        parts.append(f"{column}\t{text}\n")
    return hashlib.sha256("".join(parts).encode("utf-8", "surrogateescape")).hexdigest()


def _value_text(v: Any) -> str:
    """A stored value as the checksums sum it: ``NULL``, the hex of a BLOB, a text as it
    is, else ``repr`` (:func:`row_digest`, :func:`info_digest`)."""
    if v is None:
        return "NULL"
    if isinstance(v, bytes):
        return v.hex()
    return v if isinstance(v, str) else repr(v)


def info_digest(info: Mapping[str, Any]) -> str:
    """The ``corpus_sha256`` of the ``corpus`` table: the hexadecimal sha256 of the JSON
    text (``json.dumps`` as Python writes it by default: ASCII, ``", "`` between items) of
    the list of ``[key, value]`` pairs of its other keys in sorted order, where a value is
    a text as it is, the hex of a BLOB, ``repr`` of a number, or ``"NULL"``. JSON, so
    that no key or value can pass for another (lines of tab-separated text could: a
    review of stop 74). It catches a value changed by accident or by another program;
    like ``row_sha256``, it is no defence against an edit that writes it again."""
    pairs = []
    for key, v in sorted(((str(k), v) for k, v in info.items() if k != _INFO_CHECKSUM),
                         key=lambda kv: kv[0]):
        pairs.append([key, _value_text(v)])
    return hashlib.sha256(json.dumps(pairs).encode("ascii")).hexdigest()


def levels_digest(levels: Iterable[tuple[Any, Any, Any, Any]]) -> str:
    """The ``levels_sha256`` of a row's levels ``(k, wssse, starts, means)``: the
    hexadecimal sha256 of, for each level by increasing k, its k, a tab, ``repr`` of its
    wssse as a float, a tab, the hex of its starts, a tab, the hex of its means and a line
    end (the empty string's for a row without levels). What SQLite gives back of each
    value written gives the same digest."""
    lines = [f"{int(k)}\t{float(w)!r}\t{bytes(st).hex()}\t{bytes(mn).hex()}\n"
             for k, w, st, mn in sorted(levels, key=lambda lv: int(lv[0]))]
    return hashlib.sha256("".join(lines).encode("ascii")).hexdigest()


#: the columns :func:`row_digest` sums, in order, and those of them that hold reals
_DIGESTED = (*_FILE_COLUMNS, *_RECORDED)
_REALS = frozenset(c for c, kind in _COLUMN_KINDS.items() if kind in ("real", "rate"))


def _some(items: Sequence[str]) -> str:
    """The first five of ``items`` for a message, then ", ..." if there are more."""
    return ", ".join(items[:5]) + (", ..." if len(items) > 5 else "")


def _rows(n: int, kind: str = "index") -> str:
    """``n`` index row(s) (``kind``: "index", "damaged index"), in the singular for one."""
    return f"{n} {kind} row{'' if n == 1 else 's'}"


def _named(output: Any) -> str:
    """A row's output key for a message: as it is, or its repr if it is not a text."""
    return output[:200] if isinstance(output, str) else repr(output)[:200]


def _levels_problem(stored: Any, levels: Sequence[tuple[Any, Any, Any, Any]]) -> str | None:
    """Why the levels ``(k, wssse, starts, means)`` of a ``files`` row are not those
    written with it (``stored``: its ``levels_sha256``, unchecked while NULL), or None.
    The caller has left out levels that :func:`_level_problem` refuses."""
    if stored is None or stored == levels_digest(levels):
        return None
    return (f"its levels are not those written: their {_LEVELS_CHECKSUM} does not match "
            "(a value changed in place, or a level added or removed)")


def _level_problem(k: Any, wssse: Any, starts_type: str, means_type: str) -> str | None:
    """Why a ``levels`` row cannot be a stored summary level, or None. ``*_type`` are
    SQLite's ``typeof`` of its byte strings (a text there cannot even be read: "Could not
    decode to UTF-8"); their lengths are checked against ``k`` by :meth:`Index._cut_short`
    and :func:`mpz.similarity.from_stored`."""
    if not (isinstance(k, int) and not isinstance(k, bool) and 0 < k <= (1 << 24)):
        return f"a level's k holds {k!r:.40}, not a count of segments"
    if not (isinstance(wssse, (int, float)) and np.isfinite(wssse) and wssse >= 0):
        return f"level k={k} has a wssse of {wssse!r:.40}, not a finite number >= 0"
    if starts_type != "blob" or means_type != "blob":
        return f"level k={k} holds its starts or means as a {starts_type}/{means_type}, not a BLOB"
    return None


#: the encode options for a file, from its units (so that lengths given with a unit convert)
OptionsFor = Callable[[str], EncodeOptions]


@runtime_checkable
class FileOptions(Protocol):
    """Encode options that depend on each file as read, for :func:`encode_corpus`: what
    the CLI's ``mpz encode`` does per file (``--units`` for a BVH, the bounds of a BVH's or
    AMC's skeleton: ``mpz.tools.cmd_encode.PerFile``), or any caller's. An object with
    these three methods; it goes to the workers, so it must pickle.

    A file's fingerprint (:func:`fingerprint`) is that of ``options(units)`` and
    ``key(source, own_units)``, computed without opening the file (the up-to-date check,
    with the units of the output the index records, tried both with and without a unit of
    the source's own: :func:`_stale`); ``key`` must therefore name every input of
    ``prepare`` that ``options`` does not show, and ``options`` must depend on the units
    alone (it is called more than once for a file: in the up-to-date check, and on the
    worker).
    """

    def options(self, units: str) -> EncodeOptions:
        """The options for a file whose motion is in ``units``."""

    def prepare(self, source: str, motion: Motion) -> tuple[Motion, EncodeOptions, list[str]]:
        """The motion to encode, its options, and notes for the report (what is not kept
        or what changed), for ``source`` as read."""

    def key(self, source: str, own_units: bool) -> str:
        """What ``prepare`` adds to ``options`` for ``source`` ('' for nothing);
        ``own_units``: whether the source declares its length unit (a C3D in mm), so that
        an option naming the unit of sources without one (``--units``) leaves it out."""


class _Plain:
    """A :class:`FileOptions` whose options depend on the units alone."""

    def options(self, units: str) -> EncodeOptions:
        raise NotImplementedError

    def prepare(self, source: str, motion: Motion) -> tuple[Motion, EncodeOptions, list[str]]:
        return motion, self.options(motion.units), []

    def key(self, source: str, own_units: bool) -> str:
        return ""


@dataclass(frozen=True)
class _Fixed(_Plain):
    """The same options for every file."""

    fixed: EncodeOptions

    def options(self, units: str) -> EncodeOptions:
        return self.fixed


@dataclass(frozen=True)
class _ByUnits(_Plain):
    """Options from each file's units (an :data:`OptionsFor`)."""

    options_for: OptionsFor

    def options(self, units: str) -> EncodeOptions:
        return self.options_for(units)


# ------------------------------------------------------------------ fingerprint --
#: encode options that never change the output's bytes (threads: tested identical for any
#: count), so they do not make an archive look stale
NOT_IN_OUTPUT = frozenset({"threads"})


def fingerprint(options: EncodeOptions, levels: Sequence[int] = SUMMARY_LEVELS,
                key: str = "") -> str:
    """sha256 of the options that decide an output's bytes and its index row.

    The fields of ``options`` that differ from their defaults (metadata without the keys
    the corpus sets per file: :data:`META_SOURCE`, :data:`META_SHA256`,
    :data:`META_FINGERPRINT`), the summary levels of the index,
    :data:`~mpz.similarity.EXACT_MAX_FRAMES` and a :meth:`FileOptions.key` if not empty,
    as canonical JSON; a hierarchy given as a JSON file counts by its content (sha256), not
    its path. Only values that differ
    from the defaults count, so a new option added to :class:`~mpz.encoder.EncodeOptions`
    later (with a default) does not make an archive look stale; nor does upgrading mpz
    (its version is recorded in each row; ``force`` re-encodes).

    Examples
    --------
    >>> fingerprint(EncodeOptions(max_error=1.0)) == fingerprint(EncodeOptions(max_error=1.0))
    True
    >>> fingerprint(EncodeOptions(max_error=1.0)) == fingerprint(EncodeOptions(max_error=2.0))
    False
    >>> fingerprint(EncodeOptions(threads=1)) == fingerprint(EncodeOptions(threads=2))
    True
    """
    own = {META_SOURCE, META_SHA256, META_FINGERPRINT}

    def plain(name: str, v: Any) -> Any:
        if name == "metadata":
            v = {k: x for k, x in v.items() if k not in own}
        if name == "hierarchy" and isinstance(v, (str, os.PathLike)) \
                and os.fspath(v) not in BUILDERS and os.path.isfile(v):
            return {"file sha256": sha256_file(v)}     # a JSON file: by its content
        return dict(sorted(v.items())) if isinstance(v, Mapping) else v

    doc: dict[str, Any] = {}
    for f in fields(options):
        if f.name in NOT_IN_OUTPUT:
            continue
        v = plain(f.name, getattr(options, f.name))
        if v != plain(f.name, getattr(DEFAULTS, f.name)):
            doc[f.name] = v
    doc["index.levels"] = sorted({int(k) for k in levels})
    doc["index.exact_max_frames"] = EXACT_MAX_FRAMES
    if key:
        doc["file_options"] = key
    text = json.dumps(doc, sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


# ---------------------------------------------------------------------- worker --
@dataclass(frozen=True)
class Task:
    """What a worker gets for one file."""

    source: str
    output: str
    output_key: str                    # the index key: output relative to the index folder
    options: FileOptions
    levels: tuple[int, ...]
    force: bool = False
    asf: str | None = None             # skeleton for AMC sources (default: found beside)
    #: the index has a row for ``output``: a corpus run wrote it, so an output there that
    #: no longer reads as MPZ (damaged) is encoded again without ``force``
    indexed: bool = False
    #: the source the index row of ``output`` names (absolute), None without a row: an
    #: output that holds another source's bytes is not replaced without ``force``
    indexed_path: str | None = None
    #: ``(fingerprint, source sha256)`` of an index row that says the output is up to date,
    #: with ``verify``: the output is read whole and checked first (:func:`output_problem`);
    #: a sound one is ``skipped``, a damaged one encoded again
    verify: tuple[str, str] | None = None
    #: sent by a command (``mpz encode``): its messages spell options as the command line
    #: does, on a worker of any cluster (:func:`mpz._worker.spelled`)
    command: bool = False


@dataclass
class FileResult:
    """What became of one file.

    ``status`` is ``encoded``, ``kept`` (the output was up to date; its row was rebuilt),
    ``skipped`` (up to date by the index; not opened) or ``failed`` (see ``reason``).
    """

    source: str
    output: str
    status: str
    reason: str = ""
    source_bytes: int = 0
    output_bytes: int = 0
    raw_bytes: int = 0
    seconds: float = 0.0
    cpu_seconds: float = 0.0
    row: dict[str, Any] | None = None
    levels: list[tuple[int, float, bytes, bytes]] = field(default_factory=list)
    #: the worker process's peak resident memory so far, in bytes (None where unknown)
    worker_peak_rss: int | None = None
    #: said of the file: what :meth:`FileOptions.prepare` said (what is not kept, what
    #: changed)
    notes: list[str] = field(default_factory=list)
    #: what of the source the output does not keep (:func:`mpz.encoder.not_kept`); such a
    #: file is left out of the report's ratio against the source
    not_kept: list[str] = field(default_factory=list)
    #: the reader's warning about the source (a file cut short, a header that disagrees
    #: with the rows: ``metadata["warning"]``), "" when none; the CLI exits 1 for it
    warning: str = ""


def sha256_file(path: str | os.PathLike[str]) -> str:
    """The sha256 of a file's bytes, read in blocks of 1 MiB (hex). A device, FIFO or
    socket is refused first (:func:`mpz.api.open_regular` raises FormatError): hashed
    before the reader's own check, a FIFO in a folder hung ``mpz encode -r`` (QA)."""
    from mpz.api import open_regular
    h = hashlib.sha256()
    with open_regular(path) as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _peak_rss() -> int | None:
    try:
        import resource
    except ImportError:             # not POSIX
        return None
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024   # Linux: KiB


def _ours(output: str, fp: str, sha: str, source_mtime_ns: int, indexed: bool = False,
          source: str | None = None, indexed_path: str | None = None) -> bytes | None:
    """The bytes of an existing output that is up to date, or None if it must be encoded.
    One of the same options and source bytes that is older than the source (touched, or
    restored without its times) is given the later of now and ``source_mtime_ns``.

    ``indexed``: the index lists ``output`` (a corpus run wrote it), so one that no longer
    reads as MPZ is damaged and is encoded again. ``source``: the file to encode into it;
    an output that is the archive of another source (its meta names another file, or the
    index row ``indexed_path`` another path) and holds other bytes is refused.

    Raises
    ------
    EncoderError
        When the output exists but is not an MPZ file written by a corpus run, or does not
        read as MPZ and the index does not list it (replacing it needs ``force``), or is
        not a regular file or a symbolic link to one (:func:`mpz.api.check_output`).
    """
    from mpz.api import check_output
    from mpz.decoder import read_stream
    if not os.path.lexists(output):
        return None
    if not os.path.isfile(output):
        # a symbolic link to a missing file was replaced without a word (a QA run), and a
        # FIFO would have been read from; check_output says why each is refused
        check_output(output)
    try:
        data = Path(output).read_bytes()
        st = os.stat(output)
    except OSError:
        return None
    try:
        meta = read_stream(data).meta
    except MPZError as exc:
        if indexed:
            return None
        raise EncoderError(f"{output} exists and does not read as MPZ ({exc}); if it is a "
                           f"damaged output of an earlier run, {_use_force()} to replace "
                           "it") from None
    if META_FINGERPRINT not in meta:
        raise EncoderError(f"{output} exists and was not written by an mpz corpus run; "
                           f"{_use_force()} to replace it")
    if source is not None and meta.get(META_SHA256) != sha:
        # a run from another input folder into the same output folder replaced the archive
        # of a file of the same name (b/take.trc over a/take.c3d's take.mpz), exit 0: lost
        # when a/take.c3d was deleted after archiving (an archive team's QA run of stop 53)
        named = meta.get(META_SOURCE)
        other = (indexed_path if indexed_path is not None
                 and indexed_path != os.path.abspath(source)
                 else named if named is not None and named != os.path.basename(source)
                 else None)
        if other is not None:
            # the index names a path; the meta a file name alone, which says nothing of
            # where that file is (a review of stop 56: "which this run does not hold" of
            # an input of the same run, whose output had been swapped with this one)
            there = ("named by the output's meta chunk" if not os.path.isabs(other) else
                     "still there" if os.path.exists(other) else "no longer there")
            raise EncoderError(f"{output} is the archive of another source, {other} "
                               f"({there}), not of {os.path.basename(source)}: a run from "
                               "another input folder into this output folder, or outputs "
                               "moved or copied over each other? Give another "
                               f"{spelled('-o FOLDER', 'output folder')}, or "
                               f"{_use_force()} to replace it")
        if not indexed and meta.get(META_SHA256) is not None:
            # no row to name the file it was made from, and the meta names a file of the
            # same name: another take of that name (a flat output folder) replaced the
            # archive, exit 0, once the index had been removed as docs/corpus.md advises
            # for a damaged one (a corpus QA run of stop 76)
            raise EncoderError(f"{output} is the archive of other bytes than "
                               f"{os.path.basename(source)}'s, and no index row says which "
                               "file they were: an earlier version of this source, or "
                               "another file of the same name (a flat output folder, the "
                               f"index removed)? Remove {output} if it is an old version "
                               f"of this source, or {_use_force()} to replace it")
    if meta[META_FINGERPRINT] == fp and meta.get(META_SHA256) == sha:
        if st.st_mtime_ns < source_mtime_ns:
            # the same options and source bytes, the source touched or restored without its
            # times: encoded again, byte for byte the same (a corpus QA run of stop 76: a
            # restore re-encoded the whole archive). The output takes the later of now and
            # the source's time, so that the next run's size-and-time check finds it up to
            # date; not through a link (the file it names lies outside the folder), and
            # checked again: a file system of coarser times (FAT's 2 s) may round it below
            # the source's, and the file was then "kept" on every run (a review of stop 76)
            if os.path.islink(output):
                return None
            now = time.time_ns()
            try:
                os.utime(output, ns=(now, max(now, source_mtime_ns)))
                if os.stat(output).st_mtime_ns < source_mtime_ns:
                    return None
            except OSError:
                return None
        return data
    return None


def _row(task: Task, data: bytes, motion: Any, sha: str, st: os.stat_result, fp: str,
         summary: MotionSummary | None, features: bytes, seconds: float) -> dict[str, Any]:
    """The index row of one file, from its output bytes and its source motion; ``features``
    is the summary's descriptor as stored (float64 LE). A file without a ``summary``
    (:class:`~mpz.similarity.NotDescribable`) has the method :data:`NO_SUMMARY` and an
    empty descriptor."""
    import mpz
    from mpz.chunks import types_of_part
    from mpz.container import chunk_sizes
    from mpz.decoder import decode, read_stream
    from mpz.format import unit_name
    from mpz.io.c3d import round_trip_warnings
    from mpz.metrics import arms, besides_markers, max_error
    from mpz.skeleton import channel_bounds

    h = read_stream(data).header
    sizes = chunk_sizes(data)
    marker = 8 + sum(n for t, n in sizes.items() if t[:1].isupper())   # with the signature
    # the analog samples of a C3D source (§4.13.4; the archive's other chunks count as
    # other bytes), and the summary, smry or smrc (at most one of the two, §4.15)
    analog = sum(sizes.get(t, 0) for t in types_of_part("analog"))
    smry = sum(sizes.get(t, 0) for t in types_of_part("summary"))
    decoded = decode(data)
    err, avg = max_error(motion, decoded), arms(motion, decoded)
    trip = round_trip_warnings(motion, decoded)         # what its C3D will not give back
    # what the source keeps besides its markers must come back too (mpz compare's check)
    wrong = [p for p in besides_markers(motion, decoded, channel_bounds=channel_bounds(data))
             if p.status == "differs"]
    del decoded
    if wrong:
        raise EncoderError(f"the output does not give back the source's "
                           f"{', '.join(p.name for p in wrong)} ({wrong[0].detail}): a defect "
                           f"of mpz {mpz.identity()}, please report it; the output is left "
                           "for the report")
    raw = motion.raw_size()
    return {
        "output": task.output_key, "path": os.path.abspath(task.source), "source_sha256": sha,
        "source_bytes": st.st_size, "source_mtime_ns": st.st_mtime_ns,
        "format": os.path.splitext(task.source)[1].lower(), "frames": h.frame_count,
        "markers": h.marker_count, "rate": h.rate, "units": unit_name(h.units),
        "duration_s": h.frame_count / h.rate, "gap_fraction": float(motion.gap_fraction),
        "declared_bound": h.error_bound if h.error_metric else None, "raw_bytes": raw,
        "marker_bytes": marker, "analog_bytes": analog, "summary_bytes": smry,
        "other_bytes": len(data) - marker - analog - smry, "total_bytes": len(data),
        "chunk_bytes": json.dumps(sizes), "ratio": raw / len(data), "max_error": err,
        "arms": avg,
        "summary_method": NO_SUMMARY if summary is None else summary.method,
        "summary_dims": 3 * motion.n_markers if summary is None else summary.dims,
        "descriptor": features,
        "fingerprint": fp, "mpz_version": mpz.identity(), "warning": "; ".join(trip),
        "encoded_at": datetime.datetime.now(datetime.UTC).isoformat(
            timespec="seconds"),
        "seconds": seconds, "cpu_seconds": 0.0}


def _one_numba_thread() -> None:
    """In a Dask worker: numba's parallel kernels (the summary's) on one thread, since each
    worker has one core. Set here and not as NUMBA_NUM_THREADS in the workers' environment:
    a worker whose numba had started before it saw that variable refused to compile any
    kernel after it ("Cannot set NUMBA_NUM_THREADS to a different value once the threads
    have been launched", seen once, compiling the Fisher kernel). Outside a worker (``jobs
    0``, this process) nothing changes."""
    try:
        from distributed import get_worker
        get_worker()
    except (ImportError, ValueError):
        return
    import numba
    numba.set_num_threads(1)


def encode_file(task: Task) -> FileResult:
    """Encode one file of a corpus (the task a worker runs): :func:`_encode_file`, its
    messages spelled for the command line when a command sent it."""
    with command_task(task.command):
        return _encode_file(task)


def _encode_file(task: Task) -> FileResult:
    """Encode one file of a corpus (the task a worker runs).

    Returns
    -------
    FileResult
        ``encoded``, ``kept`` or ``failed`` with the reason. Bad input
        (:class:`~mpz.errors.MPZError`), an ``OSError`` and ``MemoryError`` are failures
        of this file; any other exception is a bug and propagates.
    """
    from mpz.api import write_atomic
    from mpz.encoder import encode_motion, not_kept, outcome_notes
    from mpz.io import read
    from mpz.similarity import summarize

    _one_numba_thread()
    t0, c0 = time.perf_counter(), time.process_time()
    src_bytes = 0
    damage = ""
    if task.verify is not None:
        damage = output_problem(task.output, *task.verify)
        if not damage:               # sound: the driver reports it from its index row
            return FileResult(task.source, task.output, "skipped",
                              seconds=time.perf_counter() - t0, worker_peak_rss=_peak_rss())
        damage = f"its output failed the check of --verify ({damage})"
    try:
        st = os.stat(task.source)
        src_bytes = st.st_size
        sha = sha256_file(task.source)
        motion = read(task.source, asf=task.asf)
        own_units = bool(motion.units)        # before --units names a unit for it
        motion, opts, notes = task.options.prepare(task.source, motion)
        warning = str(motion.metadata.get("warning", ""))   # the reader's (kept in the meta)
        # a file the index cannot describe (one frame, no valid sample, fewer than three
        # markers: one frame stopped the whole run with a traceback, a QA run) is encoded
        # and indexed as any other, without a summary: mpz search leaves it out, said
        summary: MotionSummary | None
        features: bytes = b""                 # the descriptor, worked out once, for _row
        try:
            summary = summarize(motion, task.levels)
            features = descriptor(summary, task.levels).astype("<f8").tobytes()
        except NotDescribable as exc:
            summary = None
            notes = [*notes, f"not searchable ({exc}): indexed without a summary, and "
                             "mpz search leaves it out"]
        fp = _fingerprint(task, motion.units, own_units)
        data = None if task.force else _ours(task.output, fp, sha, st.st_mtime_ns,
                                             task.indexed, task.source, task.indexed_path)
        status = "kept"
        if data is None:
            meta = dict(opts.metadata)
            meta.update({META_SOURCE: os.path.basename(task.source), META_SHA256: sha,
                         META_FINGERPRINT: fp})
            # one thread per file: the Dask workers already use the cores
            data, _ = encode_motion(motion, replace(opts, metadata=meta, threads=1))
            # replace only a file we wrote (checked by _ours) or, with force, any file
            write_atomic(task.output, data, source=task.source,
                         force=task.force or os.path.lexists(task.output))
            status = "encoded"
            # a source dated in the future (clock skew, an archive extracted as made
            # elsewhere) would leave the output older than it for ever: up to date means
            # "not older than the source", so the output takes the source's time
            if os.stat(task.output).st_mtime_ns < st.st_mtime_ns:
                os.utime(task.output, ns=(time.time_ns(), st.st_mtime_ns))
        try:
            row = _row(task, data, motion, sha, st, fp, summary, features, 0.0)
        except MPZError as exc:
            # an output of an earlier run fails this file; so does an EncoderError of _row's
            # own (what it does not give back: the output is left for the report)
            if status != "encoded" or isinstance(exc, EncoderError):
                raise
            # a file its own decoder refuses is the encoder's bug; it is not left behind
            # for the next run to refuse as "not an MPZ file" (a QA run of stop 51)
            with contextlib.suppress(OSError):
                os.remove(task.output)
            raise AssertionError(f"the encoder wrote a file that its decoder refuses: "
                                 f"{exc} ({task.source}); the output was removed") from None
        # what the output shows of the options (a --grid overruled, --weight without a
        # pattern layer): said of a file kept as well as of one encoded now; within the
        # file's try, as the rest of its work (a review of stop 74)
        notes = [*notes, *outcome_notes(motion, opts, data)]
    except (MPZError, OSError, MemoryError) as exc:
        reason = ("out of memory" if isinstance(exc, MemoryError) else
                  _reason(exc, task.source))
        if damage:
            reason += f"; {damage}, and is left as it is"
        return FileResult(task.source, task.output, "failed", reason, src_bytes,
                          seconds=time.perf_counter() - t0, worker_peak_rss=_peak_rss())
    row["seconds"] = seconds = time.perf_counter() - t0
    row["cpu_seconds"] = cpu = time.process_time() - c0
    levels = [(lv.k, lv.wssse, lv.starts.astype("<u4").tobytes(),
               np.ascontiguousarray(lv.means, "<f4").tobytes())
              for lv in (summary.levels if summary is not None else ())]
    dropped = not_kept(motion, opts)
    # the reader's warning, and what the output's C3D will not give back (_row's)
    warning = "; ".join(w for w in (warning, row["warning"]) if w)
    row.update(warning=warning, not_kept=json.dumps(dropped), notes=json.dumps(notes))
    return FileResult(task.source, task.output, status, "", src_bytes, len(data),
                      row["raw_bytes"], seconds, cpu, row, levels, _peak_rss(),
                      # said of this run alone, not kept in the row's notes
                      [*notes, f"{damage}: "
                       f"{'encoded again' if status == 'encoded' else 'its row rebuilt'}"]
                      if damage else notes, dropped, warning)


def output_problem(output: str, fingerprint: str, sha256: str) -> str:
    """What is wrong with a corpus output that its index row says is up to date, "" when
    nothing: it is read whole and must have the signature, every chunk's frame and CRC-32
    and the MEND chunk of spec §3 (:func:`mpz.container.scan`, which loads the ``meta``
    chunk alone: the samples and the other payloads were checked when the file was
    written, by decoding it), and its meta must name the row's ``fingerprint`` and source
    ``sha256``. Bit rot, a bad copy or another file of the same size and time passes the
    index's size-and-time check; not this one."""
    from mpz.chunks.core import Meta
    from mpz.container import scan
    try:
        data = Path(output).read_bytes()
    except OSError as exc:
        return f"cannot be read: {exc.strerror or exc}"
    found = scan(data, keep_unknown=False, load=("meta",))
    if found.errors:
        return str(found.errors[0])
    meta = [c.record for c in found.chunks if c.type == "meta"]
    items = meta[0].as_dict() if len(meta) == 1 and isinstance(meta[0], Meta) else {}
    if items.get(META_FINGERPRINT) != fingerprint or items.get(META_SHA256) != sha256:
        return "its meta chunk names other options or another source than its index row"
    return ""


def uncovered_problem(output: str, total_bytes: Any, fingerprint: Any, sha256: Any,
                      verify: bool) -> str:
    """What is wrong with the output of an index row that this run's inputs do not cover,
    "" when nothing: its size against the row's ``total_bytes`` (a stat), and with
    ``verify`` the whole of :func:`output_problem`. Such an output is checked in the
    driver, one after the other (no source to encode, so no task for a worker)."""
    try:
        size = os.stat(output).st_size
    except OSError as exc:
        return f"cannot be read: {exc.strerror or exc}"
    if size != total_bytes:
        return f"it is {size} bytes, its index row says {total_bytes}"
    if not verify:
        return ""
    return output_problem(output, str(fingerprint), str(sha256))


def _no_source(path: Any) -> str:
    """Why a damaged output of :attr:`CorpusReport.damaged` is not encoded again."""
    there = isinstance(path, str) and os.path.exists(path)
    return (f"its source {path} is still there, but no input of this run writes this "
            "output: run over that source with the options that wrote it, to encode it "
            "again" if there else
            f"its source {path} is no longer there, so it cannot be encoded again: restore "
            "the output from a copy")


def _fingerprint(task: Task, units: str, own_units: bool) -> str:
    """The fingerprint of ``task``'s output in ``units`` of a source that declares its unit
    or not (``own_units``): its options, and what the output depends on besides the source
    file (:func:`_beside`)."""
    key = ";".join(k for k in (_beside(task), task.options.key(task.source, own_units)) if k)
    return fingerprint(task.options.options(units), task.levels, key)


def _beside(task: Task) -> str:
    """The other files an output depends on, by content: an AMC's ASF skeleton (its
    sha256), so that an edited ASF encodes its AMC files again although they did not
    change.

    Raises
    ------
    InputFormatError
        When an AMC has no ASF (the up-to-date check then encodes it, and reading fails
        with that error).
    """
    from mpz.io._common import ext_of
    if ext_of(task.source) != ".amc":
        return ""
    from mpz.io.amc import find_asf
    asf = task.asf if task.asf is not None else find_asf(task.source)
    st = os.stat(asf)
    return f"asf={_sha256_of(os.path.abspath(asf), st.st_size, st.st_mtime_ns)}"


@functools.lru_cache(maxsize=256)
def _sha256_of(path: str, size: int, mtime_ns: int) -> str:
    """:func:`sha256_file` of a file as it is at ``size`` and ``mtime_ns``: an ASF shared
    by many AMC files (one per CMU subject) is read once per process, and again only when
    it changed."""
    return sha256_file(path)


def _reason(exc: BaseException, source: str) -> str:
    """One line for the summary table (which names the source itself)."""
    if isinstance(exc, OSError):
        return f"{exc.strerror or exc}" + (f": {exc.filename}" if exc.filename else "")
    text = str(exc)
    if isinstance(exc, MPZError) and exc.path == source and text.startswith(f"{source}: "):
        text = text[len(source) + 2:]
    return text


# ----------------------------------------------------------------------- index --
@dataclass(frozen=True)
class IndexRow:
    """One indexed file: its ``files`` row (a dict) and its summary (None for a file the
    index could not describe, :data:`NO_SUMMARY`)."""

    values: dict[str, Any]
    summary: MotionSummary | None

    def __getitem__(self, key: str) -> Any:
        return self.values[key]


#: how to recover from a damaged index: encoding again keeps failing on it, and --force
#: too (a QA of stop 42); a run without one rebuilds each output's row from its meta chunk
_REBUILD = ("restore a copy of it, or remove it: the next mpz encode -r into its folder "
            "rebuilds the rows of the .mpz files of its inputs, without encoding them "
            "again (not those of sources no longer there: docs/corpus.md)")


def _size(path: str | os.PathLike[str]) -> int:
    """A source's size for the report's totals; 0 if it cannot be stat'ed (a file that
    failed before it was read still counts its bytes: a QA of stop 42 found 0.00 MB)."""
    try:
        return os.stat(path).st_size
    except (OSError, ValueError):
        return 0


#: an Index method: a TypeVar, so that :func:`_sql` keeps each method's signature (an
#: alias made every method ``(*Any, **Any) -> Any`` to a type checker: an API QA run of
#: stop 74)
_F = TypeVar("_F", bound=Callable[..., Any])


def _listable(path: str) -> bool:
    """Whether ``path`` is a folder that can be listed now: the failure of a folder that
    could not be (:func:`mirror_jobs`) is over. It stayed in the failures table for ever
    once the folder was readable again (a corpus QA run of stop 76); a run that still
    cannot list it records it again."""
    try:
        with os.scandir(path):
            return True
    except OSError:                 # not a folder, or still not listable
        return False


def _source_there(path: str) -> bool:
    """Whether the source a failures row names exists: ``path`` itself, or the bytes its
    ``\\xNN`` escapes stand for (:func:`utf8_name` of a name that is not UTF-8)."""
    if os.path.lexists(path):
        return True
    if "\\x" not in path:
        return False
    raw = re.sub(rb"\\x([0-9a-f]{2})", lambda m: bytes([int(m[1], 16)]), path.encode())
    return os.path.lexists(raw)


def _sql(method: _F) -> _F:
    """An :class:`Index` method whose ``sqlite3.DatabaseError`` becomes an EncoderError that
    names the index and says what to do: a page damaged inside the file (its header intact)
    passes the checks of the opening and raised "database disk image is malformed" from a
    later query, a traceback with exit 1 (a QA run)."""
    @functools.wraps(method)
    def wrapper(self: Index, *args: Any, **kwargs: Any) -> Any:
        try:
            return method(self, *args, **kwargs)
        except sqlite3.ProgrammingError:
            # the caller's misuse (an Index used from another thread than the one that
            # opened it, or after close()), not the file's: it was called "a damaged
            # index, remove it" (an API QA run of stop 74)
            raise
        except sqlite3.OperationalError as exc:    # locked, read-only, disk full, I/O
            raise EncoderError(f"{self.path}: cannot {'write' if self.create else 'read'} "
                               f"the index: {exc}") from None
        except sqlite3.DatabaseError as exc:       # malformed, not a database, ...
            raise EncoderError(f"{self.path}: a damaged MPZ corpus index ({exc}); "
                               f"{_REBUILD}") from None
        except UnicodeDecodeError as exc:          # SQLite's message quoted damaged bytes
            said = _sqlite_said(exc)
            if said is None:
                raise                              # not SQLite's: a bug, said as one
            raise EncoderError(f"{self.path}: a damaged MPZ corpus index "
                               f"({said}); {_REBUILD}") from None
    return cast(_F, wrapper)


#: the words of SQLite's messages about a damaged schema (sqlite3.c: "malformed database
#: schema (%s)", "near \"%s\": syntax error", "no such ..."), where it quotes the text
_SCHEMA_DAMAGE = ("malformed database schema", "syntax error", "no such ")


def _sqlite_said(exc: UnicodeDecodeError) -> str | None:
    """What SQLite said in an error message that Python could not decode, its damaged
    bytes escaped; None when the bytes are no such message (then the error is not
    SQLite's but a bug). A byte damaged in the schema's own text ("malformed database
    schema (le\\x89els)", "near "CREA\\xabE": syntax error") came as this
    UnicodeDecodeError instead of a sqlite3.DatabaseError, a traceback with exit 70 from
    mpz search and mpz encode -r (a corpus QA run: 33 of 624 bytes flipped in the
    schema's pages)."""
    raw = exc.object if isinstance(exc.object, bytes) else bytes(exc.object)
    said = raw.decode("utf-8", "backslashreplace")
    return said if any(w in said for w in _SCHEMA_DAMAGE) else None


def _tables(db: sqlite3.Connection) -> set[str]:
    return {r[0] for r in db.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}


class Index:
    """The SQLite index of a corpus (:data:`SCHEMA`); one writer, the process that runs
    the corpus.

    Raises
    ------
    EncoderError
        If the file is not an MPZ corpus index (for writing: a database that holds other
        tables is refused, not written into), is damaged, or has an unknown schema
        version.
    """

    def __init__(self, path: str | os.PathLike[str], *, create: bool = False) -> None:
        self.path = os.fspath(path)
        if not create and not os.path.isfile(self.path):
            if os.path.exists(self.path):   # a device, a pipe: "no such index" (QA, stop 61)
                raise EncoderError(f"{self.path}: not a regular file (an index is the file "
                                   "OUT/index.sqlite that mpz encode -r FOLDER -o OUT/ writes)")
            raise EncoderError(f"{self.path}: no such index (encode a folder with "
                               "mpz encode -r FOLDER -o OUT/ to make OUT/index.sqlite)")
        self.create = create
        try:
            self.db = sqlite3.connect(self.path) if create else _read_only(self.path)
            # a text that is not UTF-8 (another program's bytes cast to text) raised
            # "Could not decode to UTF-8" from whatever query read it, reported as a locked
            # or full disk (a review of stop 53): read as lone surrogates, _field_problem
            # names it and a run rebuilds the row
            self.db.text_factory = _text
            self.db.execute("PRAGMA foreign_keys = ON")
            # a page damaged inside the file passed every check below: search ranked from
            # it and a run wrote its rows into it (a corpus QA run of stop 55). SQLite's
            # own walk of the b-trees finds it (a flipped byte inside a value it cannot:
            # SQLite keeps no checksums). The small tables only: the levels' blobs, 64 KB
            # a file, took a cold search of 100,000 files from 8 s to 31 s (a review of
            # stop 55); a damaged levels page is met by the query that reads it (_sql)
            bad = self._quick_check()
            if bad is not None:
                said = " ".join(bad.replace("*** in database main ***", "").split())
                raise EncoderError(f"{self.path}: a damaged MPZ corpus index (SQLite's "
                                   f"quick_check: {said}); {_REBUILD}")
            # another program's database at OUT/index.sqlite was written into, our tables
            # beside its own (a QA run); an empty one (0 bytes, no table) is made ours
            tables = _tables(self.db)
            got = None
            if "corpus" in tables:
                try:
                    got = self.db.execute(
                        "SELECT value FROM corpus WHERE key = 'schema'").fetchone()
                except sqlite3.OperationalError:   # a 'corpus' table of other columns
                    got = None
            if got is None and {"files", "levels"} <= tables:
                raise EncoderError(f"{self.path}: a damaged MPZ corpus index (its corpus "
                                   f"table holds no schema); {_REBUILD}")
            if got is None and (tables or not create):
                what = (f"it holds the table{'' if len(tables) == 1 else 's'} "
                        f"{_some(sorted(tables))}"
                        if tables else "an empty database")
                raise EncoderError(
                    f"{self.path}: not an MPZ corpus index ({what}, and no MPZ schema); "
                    + ("mpz encode -r keeps its index in OUT/index.sqlite: move this file "
                       "away or write to another folder" if create and tables else
                       "make one with mpz encode -r FOLDER -o OUT/"))
            if create:
                # a commit per file without an fsync each (a row lost to a power cut is
                # rebuilt by the next run from the output's meta chunk)
                self.db.execute("PRAGMA journal_mode = WAL")
                self.db.execute("PRAGMA synchronous = NORMAL")
                self.db.executescript(SCHEMA)
                self.db.execute("INSERT OR IGNORE INTO corpus VALUES ('schema', ?)",
                                (str(SCHEMA_VERSION),))
                self.db.commit()
                got = self.db.execute(
                    "SELECT value FROM corpus WHERE key = 'schema'").fetchone()
            if got is None or got[0] != str(SCHEMA_VERSION):
                raise EncoderError(f"{self.path}: index schema {got and got[0]!r}, this mpz "
                                   f"reads schema {SCHEMA_VERSION}")
            missing = sorted({"corpus", "files", "levels", "failures"} - _tables(self.db))
            if missing:
                raise EncoderError(f"{self.path}: not an MPZ corpus index (no table "
                                   f"{', '.join(missing)}); {_REBUILD}")
            columns = {r[1] for r in self.db.execute("PRAGMA table_info(files)")}
            lost = [c for c in _FILE_COLUMNS if c not in columns]
            if lost:               # a query naming it raised sqlite3's error (QA, stop 33)
                raise EncoderError(f"{self.path}: a damaged MPZ corpus index (the files "
                                   f"table has no column {', '.join(lost)}); {_REBUILD}")
            if create:             # (after the checks: a damaged index is left as it was)
                for c in _ADDED:
                    if c not in columns:
                        self.db.execute(f"ALTER TABLE files ADD COLUMN {c} TEXT")
                        columns.add(c)
                self.db.commit()
        except sqlite3.OperationalError as exc:
            self._close_quietly()
            raise EncoderError(f"{self.path}: cannot {'write' if create else 'read'} the "
                               f"index: {exc}") from None
        except sqlite3.DatabaseError as exc:
            self._close_quietly()
            raise EncoderError(f"{self.path}: not an MPZ corpus index, or a damaged one "
                               f"({exc}); if it is the index of its folder, {_REBUILD}"
                               ) from None
        except UnicodeDecodeError as exc:
            # a byte damaged in the schema's text: SQLite's "malformed database schema"
            # quoted it, and Python could not decode the message (_sqlite_said)
            self._close_quietly()
            damage = _sqlite_said(exc)
            if damage is None:
                raise
            raise EncoderError(f"{self.path}: a damaged MPZ corpus index ({damage}); if it "
                               f"is the index of its folder, {_REBUILD}") from None
        except EncoderError:
            self._close_quietly()
            raise
        # read-only, an index written before the _RECORDED columns reads them as NULL
        self._select = ", ".join([*_FILE_COLUMNS, *(c if c in columns else f"NULL AS {c}"
                                                    for c in _ADDED)])

    def _quick_check(self) -> str | None:
        """SQLite's quick_check of the tables a run and a search read first (corpus, files,
        failures, each with its indexes; SQLite 3.33 and later take a table's name, an
        older one checks the whole file): its first complaint, None when they are whole."""
        for table in ("corpus", "files", "failures"):
            if table not in _tables(self.db):
                continue                   # a new index, or another program's file
            try:
                row = self.db.execute(f"PRAGMA quick_check({table})").fetchone()
            except sqlite3.OperationalError:
                raise                      # locked, unreadable: not a damage
            except sqlite3.DatabaseError as exc:        # "malformed": the check stopped
                return str(exc)
            if row is None or row[0] != "ok":
                return str(row and row[0])
        return None

    def _close_quietly(self) -> None:
        db = getattr(self, "db", None)
        if db is not None:
            with contextlib.suppress(sqlite3.Error):
                db.close()

    def close(self) -> None:
        if self.create:
            # back to a rollback journal: a WAL file needs its -shm beside it to be read,
            # which a reader without write access to the folder cannot make (a QA run:
            # mpz search of another user's index failed)
            with contextlib.suppress(sqlite3.Error):
                self.db.execute("PRAGMA journal_mode = DELETE")
        self.db.close()

    def __enter__(self) -> Index:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- writing
    @_sql
    def set_info(self, items: Mapping[str, str]) -> None:
        """Write ``items`` into the ``corpus`` table, and the checksum of all its values
        (:func:`info_digest`). A table whose values do not match their checksum is refused
        first (:meth:`info`), so a damaged value is never given a checksum."""
        written = {k: str(v) for k, v in items.items()}     # as the TEXT column keeps them
        values = {**self.info(), **written}
        with self.db:
            self.db.executemany("INSERT OR REPLACE INTO corpus VALUES (?, ?)",
                                [*written.items(), (_INFO_CHECKSUM, info_digest(values))])

    @_sql
    def put(self, result: FileResult, output_key: str) -> None:
        """Record a result: a row and its levels, or a failure (committed at once)."""
        now = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
        with self.db:
            if result.status == "failed":     # a name that is not UTF-8 as \xNN
                self.db.execute("INSERT OR REPLACE INTO failures VALUES (?, ?, ?, ?)",
                                (utf8_name(os.path.abspath(result.source)),
                                 utf8_name(output_key), result.reason, now))
                return
            if result.row is None:      # skipped: the row is already there
                self.db.execute("DELETE FROM failures WHERE path = ?",
                                (os.path.abspath(result.source),))
                return
            self.db.execute("DELETE FROM files WHERE output = ?", (output_key,))
            # levels go with their file (ON DELETE CASCADE), but a tool without foreign
            # keys enabled may have left some behind
            self.db.execute("DELETE FROM levels WHERE output = ?", (output_key,))
            names = (*_FILE_COLUMNS, *_ADDED)
            values = {**result.row, _CHECKSUM: row_digest(result.row),
                      _LEVELS_CHECKSUM: levels_digest(result.levels)}
            self.db.execute(f"INSERT INTO files ({', '.join(names)}) VALUES "
                            f"({', '.join('?' * len(names))})", [values[c] for c in names])
            self.db.executemany("INSERT INTO levels VALUES (?, ?, ?, ?, ?)",
                                [(output_key, k, w, s, m) for k, w, s, m in result.levels])
            self.db.execute("DELETE FROM failures WHERE path = ?", (result.row["path"],))

    @_sql
    def add_checksums(self) -> tuple[int, int]:
        """Give each row without a ``row_sha256`` (written by an mpz before it) the checksum
        of its values as they are now, and each without a ``levels_sha256`` that of its
        levels; return how many rows got each: such rows were unchecked for good, since a
        run writes a row again only when its file changes (a review of stop 56). A value
        changed before this is not found; one changed after is."""
        done = [(row_digest(r), r["output"])
                for r in self._files(f"WHERE {_CHECKSUM} IS NULL", check=False)
                if _row_problem(r) is None]
        problems = self._level_problems()
        unsummed = [k for (k,) in self.db.execute(
            f"SELECT output FROM files WHERE {_LEVELS_CHECKSUM} IS NULL ORDER BY output")
            if isinstance(k, str) and k not in problems]
        levels = [(self._levels_of(k), k) for k in unsummed]
        with self.db:
            self.db.executemany(f"UPDATE files SET {_CHECKSUM} = ? WHERE output = ?", done)
            self.db.executemany(f"UPDATE files SET {_LEVELS_CHECKSUM} = ? WHERE output = ?",
                                [(levels_digest(lv), k) for lv, k in levels])
        return len(done), len(levels)

    def _levels_of(self, output_key: str) -> list[tuple[Any, Any, Any, Any]]:
        """The levels ``(k, wssse, starts, means)`` of ``output_key``, by increasing k."""
        return self.db.execute("SELECT k, wssse, starts, means FROM levels WHERE output = ? "
                               "ORDER BY k", (output_key,)).fetchall()

    def levels_changed(self) -> set[str]:
        """Output keys of rows whose levels are not those written (:func:`_levels_problem`:
        their ``levels_sha256``), reading every level whole: a run with ``verify`` only
        (6 GB of reads for 100,000 files). Rows with a level that cannot be one are
        :meth:`damaged`'s."""
        problems = self._level_problems()
        stored = self.db.execute(f"SELECT output, {_LEVELS_CHECKSUM} FROM files WHERE "
                                 f"{_LEVELS_CHECKSUM} IS NOT NULL").fetchall()
        return {out for out, digest in stored if isinstance(out, str) and out not in problems
                and _levels_problem(digest, self._levels_of(out)) is not None}

    @_sql
    def forget_missing(self, index_dir: str, keep: Collection[str] = ()) -> list[str]:
        """Remove the rows whose output is no longer in ``index_dir`` (deleted or moved
        away since it was indexed: a search would rank a file that is not there), except
        those of ``keep`` (this run's outputs, which it writes again), and return their
        output keys. The failures table is left as it is."""
        keys = [k for (k,) in self.db.execute("SELECT output FROM files ORDER BY output")
                if isinstance(k, str) and k not in keep and not os.path.isfile(
                    os.path.join(index_dir, *k.split("/")))]
        with self.db:
            self._delete(keys)
            # levels of no file (a tool without foreign keys left them, put() says): one
            # that held what it cannot made search refuse the index for good, and the run
            # said it rebuilt it (a review of stop 53)
            self.db.execute("DELETE FROM levels WHERE output NOT IN (SELECT output FROM files)")
        return keys

    @_sql
    def uncovered(self, keys: Collection[str]) -> list[tuple[str, Any, Any, Any, Any]]:
        """``(output key, source path, total bytes, fingerprint, source sha256)`` of every
        row whose output is not among ``keys`` (this run's outputs): the archives of
        sources this run was not given, often the only copy of a take whose source was
        deleted. Unchecked (a damaged row is said by :meth:`damaged`)."""
        return [r for r in self.db.execute(
            "SELECT output, path, total_bytes, fingerprint, source_sha256 FROM files "
            "ORDER BY output") if r[0] not in keys]

    @_sql
    def paths(self) -> dict[str, str]:
        """Output key -> source path of every row whose two are texts (unchecked): what a
        run keeps of the rows :meth:`refresh_descriptors` removes, so that a source edited
        since is encoded again, not refused as another file's (a review of stop 76)."""
        return {k: p for k, p in self.db.execute("SELECT output, path FROM files")
                if isinstance(k, str) and isinstance(p, str)}

    @_sql
    def keys(self) -> set[Any]:
        """The output key of every row."""
        return {k for (k,) in self.db.execute("SELECT output FROM files")}

    @_sql
    def forget_gone_failures(self, inputs: Collection[str] = ()) -> list[str]:
        """Remove the failures whose source cannot be found now (deleted, moved, or on a
        drive not mounted: the run that meets it again records it again) and return their
        paths: they stayed for ever, and a count of the failures never went down (a corpus
        QA run of stop 55). ``inputs`` are this run's sources, as the table names them
        (absolute, :func:`utf8_name`): their rows are this run's to write. A name that is
        not UTF-8 is found by the bytes its ``\\xNN`` text stands for."""
        gone = [p for (p,) in self.db.execute("SELECT path FROM failures ORDER BY path")
                if isinstance(p, str) and p not in inputs
                and (not _source_there(p) or _listable(p))]
        with self.db:
            for p in gone:
                self.db.execute("DELETE FROM failures WHERE path = ?", (p,))
        return gone

    @_sql
    def drop_unnamed(self) -> list[str]:
        """Remove the rows whose output key is not a text (another program's BLOB: it names
        no file, and crashed the run, a QA run of stop 53) and return their keys' reprs;
        the run then rebuilds the row of each output that is there."""
        keys = [k for (k,) in self.db.execute(
            "SELECT output FROM files WHERE typeof(output) != 'text' ORDER BY output")]
        with self.db:
            self._delete(keys)
        return [repr(k) for k in keys]

    def _delete(self, keys: Collection[Any]) -> None:
        """Delete the rows of ``keys`` and their levels (in the caller's transaction)."""
        for k in keys:
            self.db.execute("DELETE FROM files WHERE output = ?", (k,))
            self.db.execute("DELETE FROM levels WHERE output = ?", (k,))

    @_sql
    def same_sources(self) -> list[list[str]]:
        """Outputs that hold the same source bytes (sha256), each group in output order: a
        source moved or copied within the input folder is encoded again under its new
        name, and the output of its old name stays until it is removed."""
        groups: dict[str, list[str]] = {}
        for out, sha in self.db.execute(
                "SELECT output, source_sha256 FROM files ORDER BY output"):
            groups.setdefault(sha, []).append(out)
        return [g for g in groups.values() if len(g) > 1]

    # -- reading
    def _files(self, where: str, args: Sequence[Any] = (), *, check: bool = True
               ) -> list[dict[str, Any]]:
        """``files`` rows as dicts of every column (those of :data:`_RECORDED` None in an
        index written before them).

        Raises
        ------
        EncoderError
            With ``check``, for a row whose column holds what it cannot
            (:data:`_COLUMN_KINDS`), named.
        """
        cur = self.db.execute(f"SELECT {self._select} FROM files {where}", args)
        rows = [dict(zip((*_FILE_COLUMNS, *_ADDED), r, strict=True))
                for r in cur.fetchall()]
        if check:
            for r in rows:
                problem = _row_problem(r)
                if problem is not None:
                    raise EncoderError(f"{self.path}: the row of {_named(r['output'])} is damaged "
                                       f"({problem}); {_REBUILD}")
        return rows

    @_sql
    def row(self, output_key: str) -> dict[str, Any] | None:
        """The row of ``output_key``, unchecked (a run rebuilds a damaged row:
        :meth:`damaged` names it)."""
        got = self._files("WHERE output = ?", (output_key,), check=False)
        return got[0] if got else None

    @_sql
    def rows(self) -> list[IndexRow]:
        """Every indexed file with its summary, in output order."""
        values = self._files("ORDER BY output")
        self._check_levels()                 # (a text among them cannot even be read)
        levels: dict[str, list[tuple[int, bytes, bytes, float]]] = {}
        for out, k, w, s, m in self.db.execute(
                "SELECT output, k, wssse, starts, means FROM levels ORDER BY output, k"):
            levels.setdefault(out, []).append((k, s, m, w))
        return [IndexRow(v, self._stored(v, levels.get(v["output"], []))) for v in values]

    @_sql
    def summary_of(self, output_key: str) -> Any:
        """The stored summary of one row (None for a row archived without one, or none of
        that key), checked as :meth:`rows` checks every row: its columns, its levels' types
        and their checksum. An ``.mpz`` query of ``mpz search`` needs its source's row
        alone; it read every row's levels (18 s and 2.2 GB a query at 20,000 rows, a search
        QA run)."""
        got = self._files("WHERE output = ?", (output_key,))
        if not got:
            return None
        for k, w, st, mt in self.db.execute(
                "SELECT k, wssse, typeof(starts), typeof(means) FROM levels WHERE output = ? "
                "ORDER BY k", (output_key,)):
            problem = _level_problem(k, w, st, mt)
            if problem is not None:
                raise EncoderError(f"{self.path}: the row of {_named(output_key)} is damaged "
                                   f"({problem}); {_REBUILD}")
        levels = [(k, s, m, w) for k, w, s, m in self.db.execute(
            "SELECT k, wssse, starts, means FROM levels WHERE output = ? ORDER BY k",
            (output_key,))]
        return self._stored(got[0], levels)

    def _stored(self, v: dict[str, Any], levels: list[tuple[int, bytes, bytes, float]]
                ) -> Any:
        """Row ``v``'s stored summary from its ``levels`` ``(k, starts, means, wssse)``, their
        checksum checked; None for a row archived without one."""
        problem = _levels_problem(v[_LEVELS_CHECKSUM], [(k, w, s, m) for k, s, m, w in levels])
        if problem is not None:
            raise EncoderError(f"{self.path}: the row of {_named(v['output'])} is damaged "
                               f"({problem}); {_REBUILD}")
        return None if v["summary_method"] == NO_SUMMARY else self._summary(v, levels)

    def _summary(self, v: dict[str, Any], levels: list[tuple[int, bytes, bytes, float]]
                 ) -> Any:
        """A row's stored summary; a row the index cannot give one for is named."""
        try:
            return from_stored(v["frames"], v["rate"], v["summary_dims"], v["summary_method"],
                               levels)
        except (MPZError, ValueError) as exc:
            raise EncoderError(f"{self.path}: the row of {v['output']} is damaged ({exc}); "
                               f"{_REBUILD}") from None

    @_sql
    def info(self) -> dict[str, str]:
        """The ``corpus`` table's values (its checksum left out).

        Raises
        ------
        EncoderError
            When they do not match the checksum the last run wrote (:func:`info_digest`):
            a value changed in place."""
        info, matches = self._info()
        if not matches:
            raise EncoderError(f"{self.path}: a damaged MPZ corpus index (the values of its "
                               f"corpus table are not those written: their {_INFO_CHECKSUM} "
                               "does not match; a value changed in place, or written by an "
                               "mpz before 0.2.0); run mpz encode -r into its folder again, "
                               "which writes them again and rebuilds its rows from the .mpz "
                               "files there, without encoding them again")
        return info

    def _info(self) -> tuple[dict[str, str], bool]:
        """The ``corpus`` table's values (its checksum left out), and whether they match
        the checksum (True where there is none: an index from before it)."""
        info = dict(self.db.execute("SELECT key, value FROM corpus").fetchall())
        stored = info.pop(_INFO_CHECKSUM, None)
        return info, stored is None or stored == info_digest(info)

    @_sql
    def refresh_descriptors(self) -> tuple[list[str], bool]:
        """Make the index this :data:`~mpz.similarity.DESCRIPTOR_VERSION`'s; returns the
        output keys of the rows it removed, and whether the ``corpus`` table's values
        were written again because they did not match their checksum.

        The rows of an index of another version (its summaries leave out other markers:
        version 1 kept the markers valid in a few frames) are removed, so that the run
        rebuilds each from its output (status ``kept``, nothing encoded again), as for a
        removed index; then this version is recorded. Recomputing the descriptors from the
        stored summaries would keep those summaries. A ``corpus`` table that does not
        match its checksum (changed in place, or written by an mpz before it: a review of
        stop 74 saw such an index refused by every run until it was removed) says nothing
        that can be trusted: its values are removed, and the rows rebuilt likewise."""
        info, matches = self._info()
        if not matches:
            with self.db:
                self.db.execute("DELETE FROM corpus WHERE key != 'schema'")
            info = {}
        version = info.get("descriptor_version")
        dropped: list[str] = []
        if version != DESCRIPTOR_VERSION:
            dropped = [k for (k,) in self.db.execute("SELECT output FROM files ORDER BY output")]
            with self.db:
                self.db.execute("DELETE FROM levels")
                self.db.execute("DELETE FROM files")
        self.set_info({"descriptor_version": DESCRIPTOR_VERSION})
        return dropped, not matches

    @_sql
    def damaged(self) -> set[str]:
        """Output keys of rows that cannot be searched: a descriptor that is not finite or
        not of the index's width, no level, or a level whose byte strings are not of its
        ``k`` and ``summary_dims`` (cut short), or a column or level that holds what it
        cannot (:func:`_row_problem`, :func:`_level_problem`; a key that is not a text
        as its repr). Read from the lengths, the types and the 80-byte descriptors
        alone; a run rebuilds such rows (they passed it as up to date, and a NaN
        descriptor made every distance of a search unscaled: a QA run)."""
        width = 8 * len(features_for(self.levels()))
        bad = set()
        for out, d in self.db.execute("SELECT output, descriptor FROM files WHERE "
                                      "summary_method != ?", (NO_SUMMARY,)):
            if not isinstance(d, bytes) or len(d) != width or not np.all(
                    np.isfinite(np.frombuffer(d, "<f8"))):
                bad.add(out)
        mistyped = self._mistyped()          # first: the checks below need numbers
        found = bad | mistyped | self._cut_short() | self._levels_missing(mistyped)
        return {o if isinstance(o, str) else repr(o) for o in found}

    def _mistyped(self) -> set[str]:
        """Output keys of rows that hold in a column what it cannot (:func:`_row_problem`),
        or a level that cannot be one (:func:`_level_problem`)."""
        bad = {r["output"] for r in self._files("", check=False) if _row_problem(r)}
        return bad | set(self._level_problems())

    def _level_problems(self) -> dict[str, str]:
        """The first :func:`_level_problem` of each output's levels that has one."""
        found: dict[str, str] = {}
        for out, k, w, st, mt in self.db.execute(
                "SELECT l.output, l.k, l.wssse, typeof(l.starts), typeof(l.means) FROM levels l "
                "JOIN files f ON f.output = l.output ORDER BY l.output, l.k"):
            problem = _level_problem(k, w, st, mt)
            if problem is not None:
                found.setdefault(out, problem)
        return found

    def _check_levels(self) -> None:
        """Raise for the first output whose levels hold what they cannot."""
        for out, problem in self._level_problems().items():
            raise EncoderError(f"{self.path}: the row of {_named(out)} is damaged "
                               f"({problem}); {_REBUILD}")

    def _levels_missing(self, mistyped: Collection[str] = ()) -> set[str]:
        """Output keys of rows of the index's levels (a descriptor of its width) whose
        stored levels are not the summary's, min(k, frames) for each k of them: a level
        row deleted (a QA run of stop 48: the row passed the run as up to date, and a
        query by its own file ranked it at 0.635, not 0). Rows of other levels (a run
        with other levels into the index) are left to :meth:`descriptors`, those of
        ``mistyped`` (:meth:`_mistyped`) left out."""
        levels = self.levels()
        width = 8 * len(features_for(levels))
        have: dict[str, set[int]] = {}
        for out, k in self.db.execute("SELECT output, k FROM levels"):
            have.setdefault(out, set()).add(k)
        return {out for out, frames, d in self.db.execute(
                    "SELECT output, frames, length(descriptor) FROM files WHERE "
                    "summary_method != ?", (NO_SUMMARY,))
                if out not in mistyped and d == width
                and have.get(out, set()) != {min(k, frames) for k in levels}}

    def _cut_short(self) -> set[str]:
        """Output keys of rows without a level, or with a level whose byte strings are not
        of its ``k`` and ``summary_dims`` (lengths only: no blob is read)."""
        return {out for (out,) in self.db.execute(
            "SELECT f.output FROM files f WHERE f.summary_method != ? AND (NOT EXISTS "
            "(SELECT 1 FROM levels l WHERE l.output = f.output) OR EXISTS "
            "(SELECT 1 FROM levels l WHERE l.output = f.output AND (length(l.starts) != 4 * l.k "
            "OR length(l.means) != 4 * l.k * f.summary_dims)))", (NO_SUMMARY,))}

    @_sql
    def levels(self) -> tuple[int, ...]:
        """The summary levels the index was built with (its ``corpus`` table)."""
        text = self.info().get("levels", "")
        ks = [k.strip() for k in text.split(",") if k.strip()]
        from mpz.format import MAX_FRAMES, MAX_SUMMARY_LEVELS
        if len(ks) > MAX_SUMMARY_LEVELS or not all(
                k.isascii() and k.isdigit() and 0 < int(k) <= MAX_FRAMES for k in ks):
            raise EncoderError(f"{self.path}: a damaged MPZ corpus index (its levels read "
                               f"{text[:40]!r}); {_REBUILD}")
        return tuple(int(k) for k in ks) or SUMMARY_LEVELS

    @_sql
    def descriptors(self) -> tuple[list[dict[str, Any]], np.ndarray]:
        """Every searchable row (without its levels) and the matrix of their descriptors:
        the rows of files the index could not describe (:data:`NO_SUMMARY`) are left out.

        The stored descriptors are used; rows of other levels (a run with other levels
        into the same index) are recomputed from their stored summaries (nothing is
        decoded either way).

        Raises
        ------
        EncoderError
            For an index of another :data:`~mpz.similarity.DESCRIPTOR_VERSION` (its
            summaries are not this version's: a corpus run into its folder rebuilds
            them), and for a damaged row (a descriptor that is not finite, a summary that
            is cut short), named.
        """
        version = self.info().get("descriptor_version")
        levels = self.levels()
        width = len(features_for(levels))
        values = self._files("WHERE summary_method != ? ORDER BY output", (NO_SUMMARY,))
        if values and version != DESCRIPTOR_VERSION:
            raise EncoderError(
                f"{self.path}: an index of descriptor version {version or '(none)'}, this mpz "
                f"searches version {DESCRIPTOR_VERSION} (its summaries are made another "
                "way): run mpz encode -r into its folder again, which rebuilds its rows "
                "from the .mpz files there without encoding them again (or remove it: "
                "the next run does the same)")
        if all(isinstance(v["descriptor"], bytes) and len(v["descriptor"]) == 8 * width
               for v in values):
            table = np.array([np.frombuffer(v["descriptor"], "<f8") for v in values]
                             ).reshape(len(values), width)
        else:
            rows = [r for r in self.rows() if r.summary is not None]   # other levels:
            values = [r.values for r in rows]                          # recompute all
            table = np.array([self._descriptor(r, levels) for r in rows]
                             ).reshape(len(rows), width)
        for v, d in zip(values, table, strict=True):
            if not np.all(np.isfinite(d)):
                raise EncoderError(f"{self.path}: the row of {v['output']} is damaged (its "
                                   f"descriptor is not finite); {_REBUILD}")
        self._check_levels()
        bad = sorted(self._cut_short() | self._levels_missing())
        if bad:
            raise EncoderError(f"{self.path}: the row of {bad[0]} is damaged (its stored "
                               f"summary is cut short or missing); {_REBUILD}")
        return values, table

    def _descriptor(self, r: IndexRow, levels: tuple[int, ...]) -> np.ndarray:
        assert r.summary is not None, "rows without a summary are not searched"
        try:
            return descriptor(r.summary, levels)
        except EncoderError as exc:
            raise EncoderError(f"{self.path}: the row of {r['output']} is damaged ({exc}); "
                               f"{_REBUILD}") from None

    @_sql
    def unsearchable(self) -> int:
        """How many rows have no summary (:data:`NO_SUMMARY`): archived, not searched."""
        return int(self.db.execute("SELECT COUNT(*) FROM files WHERE summary_method = ?",
                                   (NO_SUMMARY,)).fetchone()[0])

    @_sql
    def failures(self) -> list[tuple[str, str]]:
        return self.db.execute("SELECT path, reason FROM failures ORDER BY path").fetchall()


#: seconds a run starting waits for its lock while it is held in shared mode: a search's
#: probe (:func:`run_in_progress`) holds it for microseconds
PROBE_WAIT = 1.0
#: seconds a reader of the index waits for another process's write transaction to end
#: (sqlite3's busy timeout; a corpus run's commit of one file takes milliseconds)
LOCK_WAIT = 5.0


def _locked(exc: sqlite3.OperationalError) -> bool:
    """Whether SQLite said the database is locked (another connection's transaction)."""
    return (getattr(exc, "sqlite_errorname", "") in ("SQLITE_BUSY", "SQLITE_LOCKED")
            or "database is locked" in str(exc))


def _read_only(path: str, *, rolled_back: bool = False) -> sqlite3.Connection:
    """``path`` opened for reading only: no write access is needed, to the file or its
    folder. An index left in WAL mode by a killed run needs a -shm file that such a reader
    cannot make; it is then read as immutable (a run would have changed the journal mode
    back). An index that another process holds locked for writing for :data:`LOCK_WAIT`
    seconds is refused as such: read as immutable, its half-written pages were reported
    as damage, with the advice to remove it (a QA run of stop 61: a program that holds a
    write transaction open, as SQLite browsers do until their changes are saved)."""
    uri = "file:" + urllib.parse.quote(os.fsencode(os.path.abspath(path))) + "?mode=ro"
    db = sqlite3.connect(uri, uri=True, timeout=LOCK_WAIT)
    try:
        db.execute("SELECT count(*) FROM sqlite_master").fetchone()
    except (sqlite3.DatabaseError, UnicodeDecodeError) as exc:
        if not isinstance(exc, sqlite3.OperationalError):
            db.close()                    # damage: Index says so
            raise
        db.close()
        if (getattr(exc, "sqlite_errorname", "") == "SQLITE_READONLY_ROLLBACK"
                and not rolled_back):
            _roll_back(path)
            return _read_only(path, rolled_back=True)
        if _locked(exc):
            raise EncoderError(f"{path}: the index is locked by another process writing it "
                               f"(a corpus run into its folder, or a program holding a write "
                               f"transaction open) and stayed locked for {LOCK_WAIT:g} s; "
                               f"try again once it has finished or saved its changes") from None
        db = sqlite3.connect(uri + "&immutable=1", uri=True)
    return db


def _roll_back(path: str) -> None:
    """Roll back the journal that a writer killed mid-transaction left beside the index at
    ``path`` (a "hot" journal, ``index.sqlite-journal``).
    A read-only connection cannot roll it back: read as immutable, the half-written pages
    were reported as damage, with the advice to remove the index (a review of stop 61).
    One read-write connection does what any SQLite reader with write access does on
    opening; without write access, the error says what to do."""
    folder = os.path.dirname(os.path.abspath(path))
    if not (os.access(path, os.W_OK) and os.access(folder, os.W_OK)):
        raise EncoderError(f"{path}: a program writing the index was stopped in the middle "
                           f"of a change and left its journal ({os.path.basename(path)}"
                           f"-journal), which a reader without write access to the folder "
                           f"cannot roll back; open it once with write access (any mpz "
                           f"encode -r into the folder, or sqlite3) and search again")
    rw = sqlite3.connect(path, timeout=LOCK_WAIT)
    try:
        rw.execute("SELECT count(*) FROM sqlite_master").fetchone()     # rolls it back
    finally:
        rw.close()


def open_index(path: str | os.PathLike[str]) -> Index:
    """Open an existing index; ``path`` may be the file or the folder holding it.

    An :class:`Index` is one SQLite connection: use it from the thread that opened it
    (open one per thread of a data loader; they may read the file at once), and not after
    :meth:`Index.close`. Either misuse raises ``sqlite3.ProgrammingError`` as it is, not
    an :class:`~mpz.errors.EncoderError`: the file is not at fault (it was said to be
    damaged: an API QA run of stop 74)."""
    p = os.fspath(path)
    if os.path.isdir(p):
        p = os.path.join(p, INDEX_NAME)
    return Index(p)


# ---------------------------------------------------------------------- report --
@dataclass
class CorpusReport:
    """The outcome of a corpus run: one :class:`FileResult` per file, in input order."""

    results: list[FileResult]
    seconds: float
    workers: int
    cluster: str
    #: the index file; "" when the run made none (no input there to read)
    index: str
    #: output keys whose rows were removed: the outputs were gone (Index.forget_missing)
    forgotten: list[str] = field(default_factory=list)
    #: groups of outputs of the same source bytes (Index.same_sources)
    same_source: list[list[str]] = field(default_factory=list)
    #: what the run did to the index itself: rows rebuilt for a new descriptor version or
    #: because they were damaged
    index_notes: list[str] = field(default_factory=list)
    #: files that had an index row and were encoded again, by the reason (a key of
    #: :data:`AGAIN`): a changed ``--max-error`` encoded a whole folder again with no word
    #: (a corpus QA run of stop 55)
    encoded_again: dict[str, list[str]] = field(default_factory=dict)
    #: outputs read whole and found sound by ``verify``: those among the ``skipped``, and
    #: those of :attr:`uncovered` rows
    verified: int = 0
    #: ``(output key, source path, problem)`` of each indexed output whose source is not
    #: among this run's inputs, found damaged (:func:`uncovered_problem`): it is not
    #: encoded again, having no source here, and the run fails (a corpus QA run of stop 76:
    #: ``--verify`` said "verified" of an archive one of whose only copies was cut short)
    damaged: list[tuple[str, str, str]] = field(default_factory=list)
    #: why the run stopped before every file was done ("" when it did not stop):
    #: :class:`CorpusStopped` carries such a report
    stopped: str = ""
    #: ``(source, source bytes)`` of the files the stopped run did not get to
    not_run: list[tuple[str, int]] = field(default_factory=list)

    def count(self, status: str) -> int:
        return sum(r.status == status for r in self.results)

    @property
    def failed(self) -> list[FileResult]:
        return [r for r in self.results if r.status == "failed"]

    def as_dict(self) -> dict[str, Any]:
        return {"schema": "mpz-corpus/1", "seconds": self.seconds, "workers": self.workers,
                "cluster": self.cluster, "index": self.index or None,
                "counts": {s: self.count(s) for s in ("encoded", "kept", "skipped", "failed")},
                "files": [{k: v for k, v in asdict(r).items() if k not in ("row", "levels")}
                          for r in self.results],
                "forgotten": self.forgotten, "same_source": self.same_source,
                "index_notes": self.index_notes, "encoded_again": self.encoded_again,
                "verified": self.verified,
                "damaged": [{"output": o, "source": p, "reason": why}
                            for o, p, why in self.damaged],
                "stopped": self.stopped or None,
                "not_run": [source for source, _ in self.not_run]}

    def table(self, name: Callable[[str], str] = str) -> str:
        """The summary table: files, bytes in and out per status, and each failure.

        ``name`` shows a file name or a reason (the CLI's escapes control characters, so
        that a file name cannot drive the terminal)."""
        n = len(self.results)
        lines = [f"{n} file{'' if n == 1 else 's'} in {self.seconds:.1f} s, {self.workers} "
                 f"worker{'s' if self.workers != 1 else ''} ({self.cluster})",
                 f"  {'':<11}{'files':>7}{'source MB':>12}{'MPZ MB':>10}{'ratio':>8}"]
        for status, label in (("encoded", "encoded"), ("kept", "kept"),
                              ("skipped", "up to date"), ("failed", "failed")):
            rs = [r for r in self.results if r.status == status]
            if not rs and status != "encoded":
                continue
            src = sum(r.source_bytes for r in rs)
            out = sum(r.output_bytes for r in rs)
            # the ratio counts what was kept: files that drop part of their source are out
            whole = [r for r in rs if not r.not_kept]
            w_out = sum(r.output_bytes for r in whole)
            ratio = (f"{sum(r.source_bytes for r in whole) / w_out:8.1f}" if w_out
                     else f"{'-':>8}")
            outs = f"{out / 1e6:10.2f}" if status != "failed" else f"{'-':>10}"
            partial = len(rs) - len(whole)
            lines.append(f"  {label:<11}{len(rs):>7}{src / 1e6:12.2f}{outs}{ratio}"
                         + (f"  (ratio without the {partial} that drop part of their "
                            "source)" if partial and status != "failed" else ""))
        if self.not_run:
            src = sum(b for _, b in self.not_run)
            lines.append(f"  {'not run':<11}{len(self.not_run):>7}{src / 1e6:12.2f}"
                         f"{'-':>10}{'-':>8}")
        if self.verified:
            lines.append(f"  verified {self.verified} output{'s' * (self.verified != 1)} up "
                         "to date, read whole: every chunk's frame and CRC hold, and the "
                         "meta names the indexed source (--verify)")
        done = [r for r in self.results if r.status == "encoded"]
        if done and self.seconds > 0:
            mb = sum(r.raw_bytes for r in done) / 1e6
            lines.append(f"  throughput {len(done) / self.seconds:.2f} files/s, "
                         f"{mb / self.seconds:.2f} MB/s of float32 positions")
        for r in self.failed:
            lines.append(f"  FAILED {name(r.source)}: {name(r.reason)}")
        for key, source, why in self.damaged:
            lines.append(f"  DAMAGED {name(key)}: {name(why)}; {name(_no_source(source))}")
        for r in self.results:
            if r.warning:
                lines.append(f"  WARNING {name(r.source)}: {name(r.warning)}")
        for r in self.results:
            lines += [f"  NOTE {name(r.source)}: {name(note)}" for note in r.notes]
            # what no option asked to drop is a warning (mpz.encoder.unasked), the rest a
            # note (--no-skeleton's)
            lost = unasked(r.not_kept)
            asked = [d for d in r.not_kept if d not in lost]
            if lost:
                lines.append(f"  WARNING {name(r.source)}: not kept: {name('; '.join(lost))}")
            if asked:
                lines.append(f"  NOTE {name(r.source)}: not kept: "
                             f"{name('; '.join(asked))}")
        if self.forgotten:
            n = len(self.forgotten)
            lines.append(f"  NOTE {n} index row{'' if n == 1 else 's'} removed, the output "
                         f"{'was' if n == 1 else 'were'} gone: "
                         f"{name(', '.join(self.forgotten[:5]))}{', ...' if n > 5 else ''}")
        for group in self.same_source:
            # said as a fact: copies kept on purpose are said on every run, and "remove the
            # outputs not wanted" invited deleting archives (a corpus QA run of stop 76)
            lines.append(f"  NOTE the same source bytes in {name(', '.join(group))} (copies "
                         "of one source, or a source moved or renamed since: a run forgets "
                         "the row of an output removed)")
        for why, sources in self.encoded_again.items():
            n = len(sources)
            lines.append(f"  NOTE {n} file{'' if n == 1 else 's'} encoded again, "
                         f"{AGAIN[why]}: {name(_some(sources))}")
        lines += [f"  NOTE {name(note)}" for note in self.index_notes]
        if self.stopped:
            n = len(self.not_run)
            lines.append(f"  STOPPED with {n} file{'' if n == 1 else 's'} not run: "
                         f"{name(self.stopped)}")
        lines.append(f"  index {name(self.index) if self.index else '(not made)'}")
        return "\n".join(lines)


class CorpusStopped(EncoderError):
    """A corpus run that stopped before every file was done: its cluster was lost, stopped
    answering or had no worker. The files that finished are written and indexed;
    ``report`` says which (its :attr:`~CorpusReport.stopped` is the reason, its
    :attr:`~CorpusReport.not_run` the files left), so that the summary table is printed
    as at the end of any run (a corpus QA run of stop 55: a scheduler killed mid-run left
    one error line and no account of what finished)."""

    def __init__(self, message: str, report: CorpusReport) -> None:
        super().__init__(message)
        self.report = report

    def __reduce__(self) -> tuple[Any, ...]:
        # as the other MPZErrors, it pickles (a run inside a Dask task or a subprocess)
        return (type(self), (self.message, self.report))


# ---------------------------------------------------------------------- driver --
def mirror_jobs(folder: str | os.PathLike[str], outdir: str | os.PathLike[str],
                extensions: Sequence[str] | None = None, *, keep_extension: bool = False
                ) -> list[tuple[str, str]]:
    """``(source, output)`` for every motion file under ``folder``, mirrored under ``outdir``.

    ``a/b/walk.c3d`` becomes ``OUT/a/b/walk.mpz``, or with ``keep_extension``
    ``OUT/a/b/walk.c3d.mpz`` (``mpz encode --keep-extension``: two formats of one take in
    one folder each have their own). Hidden files and folders are left out, and so is
    ``outdir`` when it lies inside ``folder``; links to folders are not followed; files
    are in sorted order.

    Raises
    ------
    EncoderError
        Naming a folder under ``folder`` (or ``folder`` itself) that cannot be listed: it
        was skipped without a word.
    """
    from mpz.io import READERS
    exts = tuple(extensions) if extensions is not None else tuple(READERS)
    root = os.fspath(folder)
    out: list[tuple[str, str]] = []

    def unlisted(exc: OSError) -> None:
        raise EncoderError(f"cannot list the folder {exc.filename or root}: "
                           f"{exc.strerror or exc}")
    skipped = is_folder(outdir)
    for here, dirs, files in walk(root, onerror=unlisted):  # no recursion: any depth
        dirs[:] = sorted(d for d in dirs if not d.startswith(".")
                         and not skipped(os.path.join(here, d)))
        for name in sorted(files):
            if name.startswith(".") or os.path.splitext(name)[1].lower() not in exts:
                continue
            rel = os.path.relpath(os.path.join(here, name), root)
            stem = rel if keep_extension else os.path.splitext(rel)[0]
            out.append((os.path.join(here, name),
                        os.path.join(os.fspath(outdir), stem + ".mpz")))
    return out


def _key(output: str, index_dir: str) -> str:
    """An output's index key: its path relative to the index's folder, with / separators."""
    rel = os.path.relpath(os.path.abspath(output), index_dir)
    return Path(rel).as_posix()


#: why a file with an index row is encoded again (:func:`_stale`), as the report says it
AGAIN = {"options": "as the options differ from their last encode's (--max-error, "
                    "--summary, --units, a hierarchy, an ASF that changed ...)",
         "source": "as the source changed (size or time) since the last encode",
         "output": "as the output was changed or replaced since the index recorded it",
         "gone": "as the output was no longer there",
         "damaged": "as the output failed the check of --verify (its NOTE says how)"}


def _stale(row: dict[str, Any] | None, task: Task) -> str | None:
    """Why the index cannot say that ``task``'s output is current: ``None`` when it can (the
    fast path that opens nothing); otherwise "new" (no row of this source), "force", or
    a key of :data:`AGAIN`, the first that applies."""
    # the row must be this source's: another file of the same size and time at another
    # path (a second folder into the same output, a moved input folder) was "up to date"
    # and never archived (an archive team's QA run of stop 50)
    if row is None or row["path"] != os.path.abspath(task.source):
        return "new"
    if task.force:
        return "force"
    try:
        st = os.stat(task.source)
    except OSError:
        return "source"               # gone since it was listed: its read fails, and says so
    if row["source_bytes"] != st.st_size or row["source_mtime_ns"] != st.st_mtime_ns:
        return "source"
    try:
        # the index does not say whether the source declares its unit: an output with a
        # unit is up to date under either reading (a source without one got it from the
        # options, which the key then names); one without a unit had none of its own
        fps = {_fingerprint(task, row["units"], own) for own in
               ((False, True) if row["units"] else (False,))}
    except (OSError, MPZError):
        return "options"             # an AMC's ASF gone: its read fails, and says so
    if row["fingerprint"] not in fps:
        return "options"
    try:
        out = os.stat(task.output)
    except OSError:
        return "gone"
    if out.st_size != row["total_bytes"] or out.st_mtime_ns < st.st_mtime_ns:
        return "output"
    return None


def _said_of_row(row: dict[str, Any]) -> dict[str, Any] | None:
    """What a run said of a file when it encoded it, from its index row: the reader's
    warning, what the output does not keep, and the notes (a rerun that found the file up
    to date skipped the warning and the notes, and counted a file that drops part of its
    source in its ratio: archive teams' QA runs of stops 50 and 51). None for a row that
    cannot say: written by an mpz before these columns (NULL), or changed by another
    program into something else."""
    try:
        said = {"warning": row["warning"], "not_kept": json.loads(row["not_kept"]),
                "notes": json.loads(row["notes"])}
    except (TypeError, ValueError, RecursionError):   # RecursionError: '[' x 10^5 (review)
        return None
    lists = [said["not_kept"], said["notes"]]
    if not (isinstance(said["warning"], str) and all(
            isinstance(v, list) and all(isinstance(x, str) for x in v) for v in lists)):
        return None
    return said


def _temp_pattern(output: str) -> re.Pattern[str]:
    """Names of the temporary files :func:`mpz.api.atomic_output` makes for ``output``."""
    name = os.path.basename(output)
    suffix = os.path.splitext(name)[1]
    return re.compile(r"\." + re.escape(name[:120]) + r"\.[0-9a-f]{8}\.part" + re.escape(suffix)
                      + r"\Z")


#: the file a corpus run locks in its output folder, so that a second run into the same
#: folder stops at once instead of encoding the same files, sweeping the other's
#: temporaries and racing it for each row
LOCK_NAME = ".mpz-corpus.lock"


@contextlib.contextmanager
def _one_run(index_dir: str) -> Iterator[None]:
    """Hold an exclusive lock on ``index_dir``'s :data:`LOCK_NAME` for one corpus run.

    ``flock``: the system drops it when the process ends, however it ends, so a crash
    leaves no stale lock, only an empty file that the next run takes. The file is removed
    at the end of the run, while still locked; a run that locked the file just before
    that finds it gone and locks the one at the path (the usual check of the inode).
    Where there is no ``fcntl`` (Windows), runs are not locked.

    Raises
    ------
    EncoderError
        When another process holds the lock, or the lock file cannot be made (a folder
        that is not writable).
    """
    try:
        import fcntl
    except ImportError:                                  # pragma: no cover - Windows
        yield
        return
    path = os.path.join(index_dir, LOCK_NAME)
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:       # a folder that cannot be written: nothing can be
            raise EncoderError(f"cannot write in {index_dir}: {exc.strerror} "
                               f"({LOCK_NAME}, the run's lock, is the first file a run "
                               "makes there)") from None
        # a search's probe (run_in_progress) holds a shared lock for an instant: a run
        # starting then was refused as if another run held it (a review of stop 61)
        deadline = time.monotonic() + PROBE_WAIT
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() < deadline:
                    time.sleep(0.01)
                    continue
                os.close(fd)
                raise EncoderError(
                    f"another corpus run is writing {index_dir} (it holds {path}); wait "
                    "for it to finish, or write to another folder") from None
        here = os.fstat(fd)
        try:
            there = os.stat(path)
        except FileNotFoundError:
            there = None
        if there is not None and (there.st_dev, there.st_ino) == (here.st_dev, here.st_ino):
            break
        os.close(fd)                                     # removed by the run before: again
    try:
        yield
    finally:
        # a lock file that cannot be removed (the folder made read-only during the run) is
        # harmless: the lock goes with the descriptor, and the next run takes the file.
        # Its PermissionError replaced the run's report with a traceback (a QA run).
        with contextlib.suppress(OSError):
            os.unlink(path)
        os.close(fd)                                     # and with it the lock


def run_in_progress(index_dir: str | os.PathLike[str]) -> bool | None:
    """Whether a corpus run holds ``index_dir``'s lock (:func:`_one_run`) now: its index is
    being written, so a reader sees the files indexed so far. None when it cannot be told:
    a lock file this process may not open (another user's run), one that is not a regular
    file, a file system without locks, or no ``fcntl`` (Windows).

    Asked without writing: a shared lock tried and given back at once (a run starting in
    that instant waits :data:`PROBE_WAIT` for it); the file is opened without blocking and
    without following a link (a FIFO there hung the search: a review of stop 61)."""
    try:
        import fcntl
    except ImportError:                                  # pragma: no cover - Windows
        return None
    path = os.path.join(os.path.realpath(index_dir), LOCK_NAME)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOFOLLOW", 0))
    except FileNotFoundError:             # no lock file: no run since the last one ended
        return False
    except OSError:                       # not ours to open, a link: cannot be told
        return None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return None
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    except OSError:                       # a file system without locks
        return None
    finally:
        os.close(fd)                      # and with it a shared lock taken
    return False


def sweep_temporaries(outputs: Sequence[str], *, before: float | None = None) -> list[str]:
    """Remove the temporary files a killed writer left beside ``outputs``; returns them.

    Only files named as :func:`mpz.api.atomic_output` names its temporaries for these
    outputs, and (with ``before``) last modified before that time, are removed.
    """
    by_folder: dict[str, list[re.Pattern[str]]] = {}
    for o in outputs:
        by_folder.setdefault(os.path.dirname(os.path.abspath(o)), []).append(_temp_pattern(o))
    removed = []
    for folder, pats in by_folder.items():
        try:
            entries = list(os.scandir(folder))
        except OSError:
            continue
        for e in entries:
            if not e.name.startswith(".") or not any(p.match(e.name) for p in pats):
                continue
            with contextlib.suppress(OSError):
                if before is None or e.stat(follow_symlinks=False).st_mtime < before:
                    os.unlink(e.path)
                    removed.append(e.path)
    return removed


Progress = Callable[[int, int, FileResult], None]


class _QuietLostGather(logging.Filter):
    """Drops asyncio's "Task exception was never retrieved" for Dask's AllExit: the gather
    of a result lost with its worker, left when :func:`_run_on` stops waiting for it (a QA
    run of stop 47 printed its traceback above the run's own error)."""

    def filter(self, record: logging.LogRecord) -> bool:
        exc = record.exc_info[1] if record.exc_info else None
        return type(exc).__name__ != "AllExit"


class _QuietCancelledReconnect(logging.Filter):
    """Drops Dask's words on a cancelled reconnect: a client that lost its scheduler tries
    to reconnect, and closing it cancels that, which Dask logs at ERROR with a traceback of
    ConnectionRefusedError and CancelledError (a corpus QA run of stop 55: 30 lines above
    the run's own error, which says what happened)."""

    def filter(self, record: logging.LogRecord) -> bool:
        exc = record.exc_info[1] if record.exc_info else None
        # and its "Failed to reconnect to scheduler after 30.00 seconds, closing client",
        # logged as the run closes the client (its own error names the lost scheduler)
        return not (isinstance(exc, asyncio.CancelledError)
                    or str(record.msg).startswith("Failed to reconnect to scheduler"))


def _quiet_dask_logs() -> None:
    """Install :class:`_QuietLostGather` and :class:`_QuietCancelledReconnect` (once)."""
    for name, quiet in (("asyncio", _QuietLostGather),
                        ("distributed.client", _QuietCancelledReconnect)):
        log = logging.getLogger(name)
        if not any(isinstance(f, quiet) for f in log.filters):
            log.addFilter(quiet())


@contextlib.contextmanager
def _dask_client(workers: int, scheduler: str | None, memory_limit: str | int | None
                 ) -> Iterator[tuple[Client, str]]:
    """A client of an existing cluster, or of a new LocalCluster closed afterwards."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise EncoderError("running on Dask needs dask.distributed: pip install "
                           "'mpz[corpus]' (or use workers=0 / --jobs 0 to encode "
                           "without it)") from None
    if scheduler is not None:
        client = _connect(Client, scheduler)
        try:
            _same_mpz(client, scheduler)
            yield client, f"scheduler {scheduler}"
        finally:
            # bounded: a scheduler that stopped answering held the close too; the run's
            # own error says what happened
            with contextlib.suppress(TimeoutError):
                client.close(timeout=CONNECT_SECONDS)
        return
    # one thread per worker process: the codec is CPU-bound (numba's parallel kernels are
    # held to one thread in each task, _one_numba_thread)
    # the scheduler's HTTP endpoints (no dashboard) on a free local port, not 8787 on
    # every interface
    # Ctrl-C is the driver's: the workers are born with SIGINT blocked (_sigint_deferred)
    # and ignore it from their preload (dask_setup; the mpz command's own workers from
    # their first import, mpz._worker), and a Ctrl-C while the cluster starts waits for it
    # to be up (stopped half-way, it failed an assertion in Dask's exit hook). Worker logs
    # are silenced below CRITICAL: a worker's error is this run's failure of a file,
    # reported with its reason, and shutting down after a Ctrl-C made them log lost
    # heartbeats.
    # a worker that dies again and again (a file over the memory limit, run again alone
    # after its KilledWorker) is restarted by its nanny; LocalCluster closed that nanny
    # for good when the worker had been gone from the scheduler at one moment 15 s
    # after a death (distributed.deploy.lost-worker-timeout), and the run had no worker
    # left (a QA run of external clusters, --jobs 1 --memory-limit 380MB). A worker that
    # cannot come back is the no-worker watch's (NO_WORKER_SECONDS).
    import dask
    with dask.config.set({"distributed.deploy.lost-worker-timeout": "1000d"}):
        pending: list[int] = []
        try:
            with _sigint_deferred(pending):
                cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                       host="127.0.0.1", memory_limit=memory_limit,
                                       dashboard_address=None, preload=[__name__],
                                       scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                                       silence_logs=logging.CRITICAL)
                try:
                    client = Client(cluster)
                except BaseException:
                    cluster.close()
                    raise
        except Exception as exc:
            if pending:         # a worker stopped by the same Ctrl-C before it could ignore it
                raise KeyboardInterrupt from None
            if isinstance(exc, (RuntimeError, OSError, TimeoutError)):
                # Dask's own words for workers that cannot start ("Nanny failed to start": a
                # Python the worker processes cannot run, no free port ...): a failure of this
                # run, said, not a traceback with exit 1 (a QA run of stop 47)
                raise EncoderError(f"the local Dask cluster of {workers} worker process"
                                   f"{'es' if workers != 1 else ''} did not start "
                                   f"({type(exc).__name__}: {exc}); --jobs 0 encodes in this "
                                   "process") from None
            raise
        try:
            if pending:
                raise KeyboardInterrupt
            yield client, f"LocalCluster, {memory_limit} per worker"
        finally:
            # a Ctrl-C as the cluster closed (the run's last second) cut the close short, and
            # Dask then waited 10 s for what it had not closed (a QA run of stop 57): the close
            # runs whole, and that Ctrl-C is dropped (the work is done, or stopping already);
            # a second one stops the close
            with _sigint_noted([]):
                client.close()
                cluster.close()


#: how long a connection to ``--scheduler`` may take: Client's own 30 s timeout, and a
#: margin (the deadline of :func:`_connect`)
CONNECT_SECONDS = 40.0


def _refused(scheduler: str) -> None:
    """Raise EncoderError at once when nothing listens at a ``tcp://`` scheduler address
    (the connection refused) or its host name does not resolve: Dask retried each for its
    full 30 s (a corpus QA run of stop 55; a newcomer's of stop 58). Anything else (a
    timeout, another scheme) is left to the Client."""
    import socket
    parts = urllib.parse.urlsplit(scheduler if "://" in scheduler else f"tcp://{scheduler}")
    if parts.scheme != "tcp" or not parts.hostname or parts.port is None:
        return
    try:
        with socket.create_connection((parts.hostname, parts.port), timeout=5.0):
            return
    except socket.gaierror as exc:
        # a name that does not resolve: Dask retried it for its full 30 s too (a newcomer's
        # QA run, --scheduler head:8786)
        raise EncoderError(f"cannot reach the Dask scheduler at {scheduler}: the host name "
                           f"{parts.hostname!r} does not resolve ({exc.strerror or exc}): "
                           "is it the scheduler's host?") from None
    except ConnectionRefusedError:
        raise EncoderError(f"cannot reach the Dask scheduler at {scheduler}: nothing listens "
                           f"at {parts.hostname}:{parts.port} (connection refused): is the "
                           "scheduler running, on that port?") from None
    except (OSError, ValueError):
        return                              # unreachable, slow, unresolved: the Client says


def _connect(client_class: type[Client], scheduler: str) -> Client:
    """A Client of the scheduler at ``scheduler``, or EncoderError within
    :data:`CONNECT_SECONDS`. Client's timeout alone did not end the wait when the address
    answered but was not a Dask scheduler (an HTTP server: a QA run waited for ever), so
    the Client is made in a daemon thread that is left behind at the deadline."""
    _refused(scheduler)
    box: dict[str, Any] = {}

    def make() -> None:
        try:
            box["client"] = client_class(scheduler, timeout="30s")
        except BaseException as exc:       # handed to the caller's thread, as it is
            box["error"] = exc

    thread = threading.Thread(target=make, name="mpz-dask-connect", daemon=True)
    thread.start()
    thread.join(CONNECT_SECONDS)
    if thread.is_alive():
        raise EncoderError(f"no Dask scheduler answered at {scheduler} within "
                           f"{CONNECT_SECONDS:.0f} s: is it the address of a "
                           "dask.distributed scheduler (tcp://HOST:8786)?")
    exc = box.get("error")
    # unreachable; a malformed address; a peer whose answer Dask read as a frame length
    # (it asked numpy for exabytes)
    if isinstance(exc, (OSError, ValueError, MemoryError)):
        raise EncoderError(f"cannot reach the Dask scheduler at {scheduler}: "
                           f"{type(exc).__name__}: {exc}")
    if exc is not None:
        raise exc
    return box["client"]


def _mpz_identity_probe() -> Callable[[], str]:
    """A function that says which mpz the process it runs in imports: its
    :func:`mpz.identity`, the ``mpz.__version__`` alone of an mpz older than that function
    (which never equals an identity: another mpz), or ``none: why`` where mpz cannot be
    imported. It is nested, so Dask (cloudpickle) sends it by value: it must run on a
    worker of any mpz or none, so it uses nothing of this module (a function of
    ``mpz.corpus`` would go by name, and one an older worker lacks kills the task as it is
    loaded)."""
    def probe() -> str:
        try:
            import mpz as worker_mpz
        except Exception as exc:
            return f"none: it cannot import mpz ({type(exc).__name__}: {exc})"
        try:
            return str(worker_mpz.identity())
        except Exception:           # an mpz before identity(), or one that fails it
            return str(getattr(worker_mpz, "__version__", "(no version)"))
    return probe


def _version_of(identity: str) -> str:
    """The bare version of an mpz :func:`mpz.identity` (``0.1.0`` of ``0.1.0 (source
    1a2b3c4d5e6f)``; an older mpz's version is already bare)."""
    return identity.partition(" (source ")[0]


def _mpz_versions(client: Client) -> dict[str, str] | None:
    """The mpz each worker of ``client``'s cluster imports, by worker address
    (:func:`_mpz_identity_probe`: its :func:`mpz.identity`, or why it cannot import mpz);
    None when they do not all answer within :data:`SCHEDULER_SECONDS` (the run's own watch
    then says what is wrong)."""
    try:                        # bounded as _nthreads is
        got = client.run(_mpz_identity_probe(), on_error="return",
                         callback_timeout=SCHEDULER_SECONDS)
    except Exception:           # silent or gone: the run's own watch says what is wrong
        return None
    return {a: v if isinstance(v, str) else f"none: {type(v).__name__}: {v}"
            for a, v in got.items()}


def _same_mpz(client: Client, scheduler: str) -> None:
    """Refuse a ``--scheduler`` cluster whose workers run another mpz than this process, or
    none. The workers encode with their own mpz: one of another version wrote the archive
    with no word (its rows' ``mpz_version`` alone said it), and a worker without mpz died
    on its first task, after which the run waited 60 s and blamed the memory limit (a QA
    run of external clusters). "Another mpz" is another :func:`mpz.identity`: every
    development checkout had the version 0.1.0, so one of other code (an edited file, an
    older commit) passed a check of the version alone. A worker that joins later is
    stopped by the task's own check (:func:`_version_checked`)."""
    import mpz
    mine = mpz.identity()
    other = {a: v for a, v in (_mpz_versions(client) or {}).items() if v != mine}
    if other:
        raise _other_mpz(f"the Dask workers at {scheduler}", mine, other)


def _other_mpz(who: str, mine: str, other: Mapping[str, str]) -> EncoderError:
    """The error of a run whose workers ``other`` (address -> their :func:`mpz.identity`,
    an older mpz's version, or ``none: why``) do not run this process's mpz ``mine`` (its
    identity). The pip command names the bare version; when every such worker has that
    version, their source differs, and the error says so."""
    said = "; ".join(f"{a} {'has ' + v if v.startswith('none') else 'runs mpz ' + v}"
                     for a, v in sorted(other.items()))
    version = _version_of(mine)
    if all(_version_of(v) == version for v in other.values()):
        return EncoderError(
            f"{who} must run the mpz of this command, {mine}, with the corpus extra: "
            f"{said}. Theirs is mpz {version} of other source files (another checkout, "
            "files edited since, or an mpz older than its source fingerprint): run them "
            "from the same checkout as this command, or install the same release on both "
            f"sides (pip install 'mpz[corpus]=={version}'), and start them again")
    return EncoderError(f"{who} must run the mpz of this command, {mine}, with the corpus "
                        f"extra: {said}. Install mpz {version} where they run (pip install "
                        f"'mpz[corpus]=={version}', or the same checkout) and start them "
                        "again")


#: the first words of the error a task raises on a worker whose mpz is not the driver's
#: (:func:`_version_checked`); the rest is ``address|identity`` (an older mpz's version, or
#: ``none: why``)
OTHER_MPZ = "mpz corpus task on another mpz|"


def _version_checked(version: str) -> Callable[[bytes], FileResult]:
    """A task that runs :func:`encode_file` on a (cloud)pickled :class:`Task` where the
    worker's mpz is ``version`` (this process's :func:`mpz.identity`), and raises
    RuntimeError(:data:`OTHER_MPZ` ...) before reading anything where it is not or cannot
    be imported.

    ``_same_mpz`` asks the workers there as the run connects; a worker that joined a
    ``--scheduler`` cluster later ran its own mpz's ``encode_file``, which is sent by name:
    one of another version wrote its share without a word. This function is nested, so
    Dask (cloudpickle) sends it by value, with the probe of :func:`_mpz_identity_probe`,
    and its argument is bytes, so that a worker of any mpz, or none, can load the task and
    run the check."""
    probe = _mpz_identity_probe()

    def task(payload: bytes) -> FileResult:
        have = probe()
        if have != version:
            try:
                from distributed import get_worker
                where = str(get_worker().address)
            except Exception:
                where = "a worker"
            raise RuntimeError(f"{OTHER_MPZ}{where}|{have}")
        import pickle

        from mpz.corpus import encode_file as run
        return run(pickle.loads(payload))
    return task


@contextlib.contextmanager
def _sigint_noted(pending: list[int], *, second_stops: bool = True) -> Iterator[None]:
    """While the block runs in the main thread, a first SIGINT only appends its number to
    ``pending``, and a second raises KeyboardInterrupt (``second_stops``) or is appended
    too (the handler before comes back afterwards); elsewhere nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def note(signum: int, frame: object) -> None:
        if pending and second_stops:
            raise KeyboardInterrupt
        pending.append(signum)

    old = signal.signal(signal.SIGINT, note)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


@contextlib.contextmanager
def _sigint_deferred(pending: list[int]) -> Iterator[None]:
    """Hold a SIGINT back for the while, in the main thread (the one Python lets set
    handlers): ``pending`` gets its number, for the caller to raise KeyboardInterrupt once
    it can clean up (:func:`_sigint_noted`, every SIGINT noted).

    The main thread also *blocks* SIGINT for the while. The threads it starts meanwhile
    inherit the block, and so do the processes they start: Dask's workers are born with
    SIGINT blocked, so that a Ctrl-C in their start-up stays pending until mpz._worker or
    the preload ignores it, which discards it. Before, a Ctrl-C in a worker's first
    moments, before either had run, ended that worker with its own traceback (on a slow
    machine that window is longer than 0.3 s; CI of stop 30). The driver still hears the
    Ctrl-C: a thread that does not block SIGINT (numpy's OpenBLAS pool) takes it and
    Python notes it in the main thread; if every thread blocks it, it stays pending
    and is delivered when the block ends.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    masks = hasattr(signal, "pthread_sigmask")           # not on Windows: the handler only
    if masks:
        # multiprocessing's resource tracker *unblocks* SIGINT in the thread that starts it
        # (CPython's resource_tracker.ensure_running), Dask's event loop once the cluster
        # makes its first queue: started here, before the block, it is not started there
        from multiprocessing import resource_tracker
        # the tracker ignores SIGINT and SIGTERM (CPython's resource_tracker.main) but not
        # SIGHUP: a hangup of the process group ended it, and the driver relaunched it with
        # a warning and six KeyError tracebacks (a QA run of stop 50). An ignored signal
        # stays ignored across the tracker's exec.
        hup = getattr(signal, "SIGHUP", None)
        old_hup = signal.signal(hup, signal.SIG_IGN) if hup is not None else None
        try:
            resource_tracker.ensure_running()
        finally:
            if hup is not None:
                signal.signal(hup, signal.SIG_DFL if old_hup is None else old_hup)
    with _sigint_noted(pending, second_stops=False):
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT}) if masks else None
        try:
            yield
        finally:
            # the mask restored delivers a pending SIGINT to the noting handler, which
            # signal.signal runs (it checks signals first) before putting the old one back
            if mask is not None:
                signal.pthread_sigmask(signal.SIG_SETMASK, mask)


def dask_setup(worker: object) -> None:
    """Dask's preload hook, run in each worker process of the local cluster as it starts:
    the worker ignores SIGINT. A Ctrl-C at the terminal reaches every process of the
    group; the driver cancels the tasks and closes the cluster, and each worker printed a
    KeyboardInterrupt traceback of its event loop besides (a QA note of stop 28)."""
    from mpz._worker import ignore_sigint
    ignore_sigint()


def _killed(exc: BaseException) -> bool:
    try:
        from distributed import KilledWorker
    except ImportError:
        return False
    return isinstance(exc, KilledWorker)


#: the reason a file whose path is not UTF-8 fails a corpus run (mpz encode of the file
#: alone encodes it, its metadata 'source' holding the name's bytes as \\xNN)
NOT_UTF8 = ("its path is not UTF-8, and the index stores paths as UTF-8 text: rename it, "
            "or encode it alone (mpz encode FILE -o OUT.mpz)")


def _check_corpus_arguments(jobs: Sequence[Any], outdir: str | os.PathLike[str],
                            options: Any, workers: int | None) -> None:
    """Refuse :func:`encode_corpus` arguments of the wrong kind at once, naming them (a QA
    of stop 42: workers=-1 waited 60 s and blamed the memory limit; options as a dict
    gave "'dict' object is not callable"; jobs as a folder's name "not enough values to
    unpack"; an outdir that is a file os.makedirs' FileExistsError)."""
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                or workers < 0):
        raise ValueError(f"workers must be an int >= 0 (0: in this process), got {workers!r}")
    if isinstance(jobs, (str, bytes, os.PathLike)) or not all(
            isinstance(j, (tuple, list)) and len(j) == 2 for j in jobs):
        raise TypeError("jobs must be a sequence of (source, output) pairs, such as "
                        "mirror_jobs(folder, outdir) gives")
    if not isinstance(options, (EncodeOptions, FileOptions)) and not callable(options):
        raise TypeError(f"options must be EncodeOptions, a FileOptions or a function of the "
                        f"units giving EncodeOptions, got {type(options).__name__}")
    folder = os.fspath(outdir)
    if os.path.exists(folder) and not os.path.isdir(folder):
        raise EncoderError(f"{folder}: not a folder; outdir holds the outputs and "
                           "index.sqlite")


def encode_corpus(jobs: Sequence[tuple[str | os.PathLike[str], str | os.PathLike[str]]],
                  outdir: str | os.PathLike[str],
                  options: EncodeOptions | OptionsFor | FileOptions = DEFAULTS, *,
                  levels: Sequence[int] = SUMMARY_LEVELS, workers: int | None = None,
                  scheduler: str | None = None, client: Client | None = None,
                  memory_limit: str | int | None = DEFAULT_MEMORY_LIMIT, force: bool = False,
                  progress: Progress | None = None,
                  asf: str | os.PathLike[str] | None = None,
                  failed: Sequence[tuple[str, str | None, str]] = (),
                  verify: bool = False) -> CorpusReport:
    """Encode ``(source, output)`` pairs in parallel and index them in ``outdir``.

    Parameters
    ----------
    jobs : sequence of (source, output)
        Outputs are usually under ``outdir`` (:func:`mirror_jobs`); their folders are
        created.
    outdir : path
        Holds ``index.sqlite`` (created or updated).
    options : EncodeOptions, callable(units) -> EncodeOptions, or FileOptions
        The same options for every file, options from each file's units (lengths given
        with a unit, ``--max-error 1mm``), or a :class:`FileOptions` that also prepares
        each motion as read (the CLI's: ``--units``, a skeleton's bounds). Must be
        picklable (cloudpickle) for Dask.
    levels : sequence of int
        Segment counts of the summaries stored in the index.
    workers : int, optional
        Worker processes of the local cluster (default: the CPU count); ``0`` encodes in
        this process without Dask. Ignored with ``scheduler`` or ``client``.
    scheduler : str, optional
        Address of a running ``dask.distributed`` scheduler (``tcp://host:8786``); its
        workers must see the sources and ``outdir`` at the same paths.
    client : distributed.Client, optional
        A client to use as it is (not closed).
    memory_limit : str or int, optional
        Per worker of the local cluster; Dask restarts a worker that exceeds it, and a
        file that kills its workers three times is reported as failed.
    force : bool
        Encode every file again and replace existing outputs, ours or not.
    progress : callable(done, total, FileResult), optional
        Called in this process as each file finishes (skipped ones included).
    asf : path, optional
        Skeleton for every AMC source (default: found beside each).
    failed : sequence of (source, output or None, reason)
        Inputs that failed before they could be planned (a repeated output, an input that
        cannot be read): reported and recorded in the index's ``failures`` table as the
        other failures are, so that every count agrees.
    verify : bool
        Read whole every output that the index says is up to date, on the workers, and
        check it (:func:`output_problem`: every chunk's frame and CRC, and its meta
        against its row); a damaged one is encoded again, and said. Every row's levels
        are also read whole and checked against their ``levels_sha256``; such a row is
        rebuilt from its output. Without it, up to date is the index's word (size and
        times), no output is opened and the levels are checked by length and type only.

    Returns
    -------
    CorpusReport

    Raises
    ------
    KeyboardInterrupt
        After cancelling the tasks in flight, removing their temporary files and
        committing the rows of the files that finished.
    EncoderError
        When ``outdir`` cannot be made, the index cannot be opened, another run is
        writing ``outdir`` (:data:`LOCK_NAME`), or Dask is missing or unreachable.
    """
    t0 = time.perf_counter()
    if not isinstance(jobs, (str, bytes, os.PathLike)):
        jobs = list(jobs)                   # a generator: checked, then used, once
    _check_corpus_arguments(jobs, outdir, options, workers)
    wall0 = time.time()
    index_dir = os.path.abspath(os.fspath(outdir))
    per_file = (options if isinstance(options, FileOptions) else
                _Fixed(options) if isinstance(options, EncodeOptions) else _ByUnits(options))
    levels = tuple(sorted({int(k) for k in levels}))
    skeleton = None if asf is None else os.path.abspath(os.fspath(asf))
    command = in_command()
    tasks = [Task(os.fspath(s), os.fspath(o), _key(os.fspath(o), index_dir), per_file,
                  levels, force, skeleton, command=command) for s, o in jobs]
    # the index holds paths as UTF-8 text: such a name stopped the run with a traceback
    named = [is_utf8(os.path.abspath(t.source)) and is_utf8(t.output_key) for t in tasks]
    failed = [*failed, *((t.source, t.output, NOT_UTF8)
                         for t, ok in zip(tasks, named, strict=True) if not ok)]
    tasks = [t for t, ok in zip(tasks, named, strict=True) if ok]
    results: list[FileResult | None] = [None] * len(tasks)
    n_workers = workers if workers is not None else (os.cpu_count() or 1)
    early = [FileResult(os.fspath(src), "" if out is None else os.fspath(out), "failed",
                        reason, _size(src)) for src, out, reason in failed]
    if not os.path.isdir(index_dir) and not any(os.path.lexists(s) for s, _ in jobs):
        # no input there to read (mistyped paths): the output folder and an empty index
        # were made all the same (an archive team's QA run of stop 53)
        absent = [FileResult(t.source, t.output, "failed",
                             f"{os.strerror(errno.ENOENT)}: {t.source}") for t in tasks]
        return CorpusReport(absent + early, time.perf_counter() - t0, 0, "nothing to do", "",
                            index_notes=[f"no input to encode: the output folder "
                                         f"{os.fspath(outdir)} was not made"])
    with contextlib.ExitStack() as stack:
        remote = None
        if scheduler is not None and client is None:
            # reached before the index and its folder are made: an unreachable address
            # left an empty index behind (stop 48's list), then an empty folder (a QA run
            # of external clusters: a refused, unresolved or non-Dask address, and
            # workers of another mpz)
            remote = stack.enter_context(_dask_client(n_workers, scheduler, memory_limit))
        try:
            os.makedirs(index_dir, exist_ok=True)
        except OSError as exc:
            raise EncoderError(f"cannot make the folder {os.fspath(outdir)}: "
                               f"{folder_problem(exc)}") from None
        stack.enter_context(_one_run(index_dir))
        index = stack.enter_context(Index(os.path.join(index_dir, INDEX_NAME), create=True))
        known = index.paths()
        dropped, rewritten = index.refresh_descriptors()
        # the source path of each row dropped for a new descriptor version or a corpus
        # table that fails its checksum: without it, a source edited since was refused as
        # another file of the same name (_ours)
        remembered = {k: known[k] for k in dropped if k in known}
        del known
        unnamed = index.drop_unnamed()
        summed, levels_summed = index.add_checksums()
        keys = {t.output_key for t in tasks}
        forgotten = index.forget_missing(index_dir, keys)
        gone = index.forget_gone_failures({utf8_name(os.path.abspath(s)) for s in
                                           [*(s for s, _ in jobs), *(s for s, _, _ in failed)]})
        damaged = index.damaged() | (index.levels_changed() if verify else set())
        # a damaged row this run's inputs do not cover is not rebuilt (a run over a part of
        # the inputs said it was, a review of stop 53)
        rebuilt = sorted(damaged & keys)
        left = sorted(damaged - keys)
        notes = []
        if rewritten:
            notes.append(f"the values of the index's corpus table did not match their "
                         f"{_INFO_CHECKSUM} (changed in place, or written by an mpz before "
                         f"0.2.0): they are written again, and its {len(dropped)} "
                         f"row{'' if len(dropped) == 1 else 's'} rebuilt from the outputs "
                         "(status kept, nothing encoded again)")
        elif dropped:
            notes.append(f"the index was of another descriptor version: its {len(dropped)} "
                         f"row{'' if len(dropped) == 1 else 's'} are rebuilt from the outputs "
                         "(status kept, nothing encoded again)")
        if unnamed:
            notes.append(f"{_rows(len(unnamed))} whose output is not a text removed: "
                         f"{_some(unnamed)}")
        if summed:
            notes.append(f"{_rows(summed)} written before row_sha256 got the checksum of "
                         "their values as they are: a value changed from now on is found")
        if levels_summed:
            notes.append(f"{_rows(levels_summed)} written before levels_sha256 got the "
                         "checksum of their levels as they are: a level changed from now "
                         "on is found where the levels are read (Index.rows, an .mpz "
                         "query of mpz search, a run with --verify)")
        if gone:
            notes.append(f"{len(gone)} failure{'s' * (len(gone) != 1)} of sources no longer "
                         f"there, or of folders that can be listed now, forgotten: "
                         f"{_some(gone)}")
        what = ("(a descriptor that is not finite, a summary cut short, a column holding what "
                "it cannot, values changed in place)")
        if rebuilt:
            notes.append(f"{_rows(len(rebuilt), 'damaged index')} {what} rebuilt: "
                         f"{_some(rebuilt)}")
        if left:
            notes.append(f"{_rows(len(left), 'damaged index')} {what} of outputs this run's "
                         f"inputs do not cover, left as "
                         f"{'it is' if len(left) == 1 else 'they are'} (mpz search refuses "
                         f"the index): {_some(left)}; run over their sources too, or "
                         "restore a copy of the index")
        index.set_info({"levels": ",".join(map(str, levels)),
                        "exact_max_frames": str(EXACT_MAX_FRAMES)})
        done = verified = 0
        # the outputs of rows this run's inputs do not cover (a source deleted once its
        # take was archived): a cut or changed one was never looked at, and --verify said
        # "verified" of the archive (a corpus QA run of stop 76)
        damaged_outputs: list[tuple[str, str, str]] = []
        for key, src, total, fp, sha in index.uncovered(keys):
            if key in damaged or not isinstance(key, str):
                continue                        # said above, as a damaged row
            # read whole only where the source is gone: the only copy. One whose source
            # is there (a run over a part of the inputs) is the next full run's to verify,
            # and a run of one folder read the whole archive first (a review of stop 76)
            whole = verify and not (isinstance(src, str) and os.path.exists(src))
            problem = uncovered_problem(os.path.join(index_dir, *key.split("/")), total, fp,
                                        sha, whole)
            if problem:
                damaged_outputs.append((key, src if isinstance(src, str) else "", problem))
            elif whole:
                verified += 1
        sound: dict[int, FileResult] = {}    # with verify: the report of each, if sound

        def report(workers: int, same: list[list[str]], **stop: Any) -> CorpusReport:
            """The run's report, of the files finished so far."""
            return CorpusReport([r for r in results if r is not None] + early,
                                time.perf_counter() - t0, workers, cluster,
                                os.path.join(index_dir, INDEX_NAME), forgotten, same, notes,
                                _again(again, results), verified, damaged_outputs, **stop)

        unindexed: list[str] = []            # written, but their row could not be

        def finish(i: int, r: FileResult) -> None:
            nonlocal done, verified
            if r.status == "skipped" and i in sound:
                r = sound.pop(i)             # checked by its worker, and sound
                verified += 1
            results[i] = r
            try:
                index.put(r, tasks[i].output_key)
            except EncoderError:
                if r.status == "encoded":
                    unindexed.append(r.output)
                raise
            done += 1
            if progress is not None:
                progress(done, len(tasks) + len(early), r)

        # the files refused before planning (name clashes, names not UTF-8) count in the
        # progress as in the table: the bar ended at 3 of 3 where the table said 5 files
        # (a corpus QA run of stop 63)
        for r in early:
            index.put(r, "" if not r.output else _key(r.output, index_dir))
            done += 1
            if progress is not None:
                progress(done, len(tasks) + len(early), r)
        todo: list[int] = []
        again: dict[int, str] = {}          # why a file with a row is encoded again
        for i, t in enumerate(tasks):
            row = index.row(t.output_key)
            # a row of an mpz before the _RECORDED columns cannot say its file's warning and
            # notes: such a file is read again
            said = None if row is None or t.output_key in damaged else _said_of_row(row)
            why = _stale(row, t) if said is not None else None
            if why in AGAIN:
                again[i] = why
            if said is not None and why is None:
                assert row is not None
                skipped = FileResult(t.source, t.output, "skipped", "", row["source_bytes"],
                                     row["total_bytes"], row["raw_bytes"], **said)
                if not verify:
                    finish(i, skipped)
                    continue
                sound[i] = skipped
                again[i] = "damaged"
                tasks[i] = replace(t, indexed=True, indexed_path=row["path"],
                                   verify=(row["fingerprint"], row["source_sha256"]))
                todo.append(i)
            else:
                path = remembered.get(t.output_key) if row is None else row["path"]
                tasks[i] = replace(t, indexed=row is not None or path is not None,
                                   indexed_path=path if isinstance(path, str) else None)
                todo.append(i)
        # each output folder made once; one that cannot be made (a file in its place, no
        # permission: a QA run) fails its files alone
        unmade: dict[str, str | None] = {}
        made: list[str] = []            # the folders this run made, removed if left empty
        for i in todo:
            folder = os.path.dirname(os.path.abspath(tasks[i].output))
            if folder not in unmade:
                try:
                    made += _missing_folders(folder)
                    os.makedirs(folder, exist_ok=True)
                    unmade[folder] = None
                except OSError as exc:
                    unmade[folder] = f"cannot make the folder {folder}: {folder_problem(exc)}"
            reason = unmade[folder]
            if reason is not None:
                finish(i, FileResult(tasks[i].source, tasks[i].output, "failed", reason,
                                     _size(tasks[i].source)))
        todo = [i for i in todo if unmade[os.path.dirname(os.path.abspath(tasks[i].output))]
                is None]
        # every output's folder, not only those with work: a leftover stays no longer
        sweep_temporaries([t.output for t in tasks], before=wall0)
        inflight: dict[Future[FileResult], int] = {}
        # no more local workers than files to encode (each costs a process and its memory)
        n_workers = min(n_workers, len(todo))
        seen: list[int] = []            # the cluster's worker counts, as it said them
        # what a report of a run stopped before _dispatch returns names as its cluster
        cluster = ("given client" if client is not None else remote[1] if remote is not None
                   else IN_PROCESS if n_workers == 0 and scheduler is None
                   else f"LocalCluster, {memory_limit} per worker")
        try:
            n_workers, cluster = _dispatch(tasks, todo, finish, inflight, n_workers, client,
                                           remote, scheduler, memory_limit, seen)
        except EncoderError as exc:
            # the run stopped (the cluster lost, silent or without a worker): what finished
            # is indexed, and the report says so with the files left
            not_run = [(tasks[i].source, _size(tasks[i].source))
                       for i, r in enumerate(results) if r is None]
            # the cluster's own count (a review of stop 56: the local CPU count was said of
            # a --scheduler cluster of one worker, and of one with none)
            _remove_empty(made)
            if unindexed:
                # counted as encoded, its output written: the report said "0 files not run"
                # and nothing of the row a full disk kept out (a corpus QA run of stop 63)
                n = len(unindexed)
                notes.append(f"{n} file{'' if n == 1 else 's'} written but not indexed: "
                             f"{_some([_key(o, index_dir) for o in unindexed])}; the next "
                             f"run indexes {'it' if n == 1 else 'them'} from "
                             f"{'its output' if n == 1 else 'their outputs'}, without "
                             "encoding again")
            raise CorpusStopped(exc.message, report(seen[-1] if seen else n_workers, [],
                                                    stopped=exc.message, not_run=not_run)
                                ) from None
        _remove_empty(made)
        same = index.same_sources()
        # an output of this run's inputs without a row is this run's failure, said as such
        # (the note told the run just made to run over its sources: a review of stop 76)
        loose = unindexed_outputs(index_dir, index.keys() | keys)
        if loose:
            # a removed index, or rows dropped, is rebuilt from the outputs of this run's
            # inputs alone: the archive of a deleted source lost its row without a word
            # (a corpus QA run of stop 76)
            notes.append(f"{len(loose)} output{'s' * (len(loose) != 1)} in this folder "
                         f"{'have' if len(loose) != 1 else 'has'} no index row, and mpz "
                         f"search does not see {'them' if len(loose) != 1 else 'it'}: "
                         f"{_some(loose)}; a run indexes an output only from its source "
                         "(run over the sources, if they are still there)")
    return report(n_workers, same)


def unindexed_outputs(index_dir: str, keys: Collection[Any]) -> list[str]:
    """The keys of the ``.mpz`` files under ``index_dir`` (hidden ones and hidden folders
    left out, as :func:`mirror_jobs` leaves them out) that are not in ``keys``."""
    loose = []
    for here, dirs, files in walk(index_dir):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        for name in sorted(files):
            if name.startswith(".") or not name.lower().endswith(".mpz"):
                continue
            key = _key(os.path.join(here, name), index_dir)
            if key not in keys:
                loose.append(key)
    return loose


def _missing_folders(folder: str) -> list[str]:
    """``folder`` and its ancestors that do not exist yet, deepest first: what
    ``os.makedirs(folder)`` makes."""
    out = []
    while folder and not os.path.isdir(folder):
        out.append(folder)
        parent = os.path.dirname(folder)
        if parent == folder:
            break
        folder = parent
    return out


def _remove_empty(made: Sequence[str]) -> None:
    """Remove the folders a run made (:func:`_missing_folders`) that hold nothing after it:
    with ``--mirror``, the folder of a file that failed was left empty (a corpus QA run).
    One that holds anything, or cannot be removed, stays."""
    for folder in sorted(set(made), key=len, reverse=True):      # the deepest first
        with contextlib.suppress(OSError):
            os.rmdir(folder)


#: the report's cluster of a run without Dask (``workers=0``: this process encodes)
IN_PROCESS = "this process, no Dask"


def _again(again: Mapping[int, str], results: Sequence[FileResult | None]
           ) -> dict[str, list[str]]:
    """The sources that were encoded again, by the reason (:data:`AGAIN`)."""
    out: dict[str, list[str]] = {}
    for i, why in again.items():
        r = results[i]
        if r is not None and r.status == "encoded":     # kept: the same source bytes
            out.setdefault(why, []).append(r.source)
    return {k: out[k] for k in AGAIN if k in out}


def _dispatch(tasks: list[Task], todo: list[int], finish: Callable[[int, FileResult], None],
              inflight: dict[Future[FileResult], int], n_workers: int,
              client: Client | None, remote: tuple[Client, str] | None,
              scheduler: str | None, memory_limit: str | int | None,
              seen: list[int]) -> tuple[int, str]:
    """Encode ``todo`` where :func:`encode_corpus` was told to; returns the worker count
    and the cluster's description for the report. ``seen`` gets the worker count each
    time the cluster says it (for the report of a run that stops)."""
    if not todo:
        cluster = "nothing to do"          # no cluster is started for a no-op run
    elif n_workers == 0 and scheduler is None and client is None:
        cluster = IN_PROCESS
        for i in todo:       # an interrupted write removes its own temporary file
            finish(i, encode_file(tasks[i]))
    elif client is not None or remote is not None:
        if client is not None:
            c, cluster = client, "given client"
        else:
            assert remote is not None
            c, cluster = remote
        try:
            n_workers = _run_on(c, tasks, todo, finish, inflight, seen=seen)
        finally:
            # a worker killed mid-write (SIGKILL, its nanny over the memory limit) left the
            # hidden temporary of that attempt, which Dask then ran elsewhere: it stayed
            # until the next run (a QA run of external clusters). A file whose result came,
            # or that was not started, has no writer left; one still in flight (a Ctrl-C:
            # a remote task runs on) is left to its task.
            running = set(inflight.values())
            sweep_temporaries([tasks[i].output for i in todo if i not in running])
    else:
        try:
            with _dask_client(n_workers, scheduler, memory_limit) as (c, cluster):
                # a local worker's death is most often its memory limit: say which
                # (a scale QA run of stop 51: "over the memory limit?" named none)
                limit = memory_limit if memory_limit is not None else DEFAULT_MEMORY_LIMIT
                n_workers = _run_on(c, tasks, todo, finish, inflight,
                                    f"over the workers' memory limit, {limit}? "
                                    "--memory-limit raises it", seen=seen)
        finally:
            # the local workers are gone now: a task killed mid-write left a hidden
            # temporary file
            if scheduler is None and inflight:
                sweep_temporaries([tasks[i].output for i in inflight.values()])
    return n_workers, cluster


def _absolute(task: Task) -> Task:
    """``task`` with absolute paths: a worker may run in another folder (a cluster's
    worker is started wherever its machine starts it), and must see the files at the
    paths the driver sees them (``scheduler``)."""
    return replace(task, source=os.path.abspath(task.source),
                   output=os.path.abspath(task.output),
                   asf=None if task.asf is None else os.path.abspath(task.asf))


#: while no task finishes, how often the driver checks that the cluster has workers
WATCH_SECONDS = 5.0
#: a cluster without a worker this long fails the run (a worker that cannot start, for
#: example under a memory limit below what it needs, is restarted for ever)
NO_WORKER_SECONDS = 60.0


def _lost(exc: CancelledError) -> EncoderError:
    """The error of a run whose cluster cancelled its tasks (the scheduler died or the
    connection to it was lost)."""
    reason = " ".join(str(exc).split())
    # Dask's text names every future cancelled ("3 Futures cancelled: Reasons: ...
    # Futures: ['mpz-encode-21-...', ...]"): its reason is what the user can act on
    lost = "scheduler-connection-lost" in reason
    reason = ("the connection to the scheduler was lost: is it still running?" if lost
              else reason[:300])
    return EncoderError(f"the Dask cluster cancelled the run's tasks ({reason}); the files "
                        "that finished are written and indexed: run the same command again "
                        "to encode the rest")


#: how long one call to the scheduler may take before the run fails: one that stopped
#: answering (a frozen head node, a network cut) held ``--scheduler`` runs for ever, with
#: no word (a corpus QA run of stop 55: a SIGSTOPped scheduler)
SCHEDULER_SECONDS = 60.0


class _SchedulerSilent(EncoderError):
    """The scheduler did not answer within :data:`SCHEDULER_SECONDS`: nothing more is
    asked of it (cancelling the tasks would wait for it too)."""


def _nthreads(client: Client) -> dict[str, int]:
    """``client.nthreads()``, within :data:`SCHEDULER_SECONDS`.

    Raises
    ------
    EncoderError
        When the scheduler does not answer in that time.
    """
    try:
        return dict(client.nthreads(callback_timeout=SCHEDULER_SECONDS))
    except TimeoutError:
        raise _SchedulerSilent(
            f"the Dask scheduler has not answered for {SCHEDULER_SECONDS:.0f} s (is it "
            "frozen, overloaded or cut off?); the files that finished are written and "
            "indexed: run the same command again when it answers") from None


def _run_on(client: Client, tasks: list[Task], todo: list[int],
            finish: Callable[[int, FileResult], None],
            inflight: dict[Future[FileResult], int],
            died: str = "over the memory limit?", seen: list[int] | None = None) -> int:
    """Run ``todo`` on the cluster, a bounded window of tasks at a time; returns the
    worker count. ``inflight`` holds the tasks not finished yet; on any exception,
    KeyboardInterrupt included, they are cancelled before it propagates.

    Workers get the tasks with absolute paths (:func:`_absolute`); the results name the
    files as they were given. A cluster that has had no worker for
    :data:`NO_WORKER_SECONDS` while tasks wait fails the run (EncoderError) rather than
    waiting for ever. ``died`` is the likely cause said of a file whose worker died each
    time it ran it. ``seen`` gets the worker count each time the scheduler says it.

    Dask blames a worker's death on every task the worker held, running or queued
    (``KilledWorker`` after ``distributed.scheduler.allowed-failures`` deaths), so a small
    file queued beside one that exceeds the memory limit failed with it, for the same
    reason, and again on each run (a QA run of external clusters). A file that gets
    ``KilledWorker`` is therefore run once more *alone* (nothing else in flight) once the
    other files are done, and fails only if its worker dies then too."""
    from distributed import wait
    _quiet_dask_logs()                  # a given client's too
    pending = iter(todo)
    said = seen if seen is not None else []

    def workers() -> dict[str, int]:
        nthreads = _nthreads(client)
        said.append(len(nthreads))
        return nthreads

    threads = max(sum(workers().values()), 1)
    window = 2 * threads + 1     # queued work stays small: a stop loses little

    suspects: list[int] = []    # got KilledWorker beside other tasks: to run alone
    alone: set[int] = set()     # run alone after a KilledWorker

    import cloudpickle  # Dask's: a task's FileOptions may be a lambda

    import mpz
    version = mpz.identity()        # the workers' mpz must be this one (_same_mpz)
    encode = _version_checked(version)

    def submit() -> None:
        while len(inflight) < window:
            i = next(pending, None)
            if i is None:
                break
            fut = client.submit(encode, cloudpickle.dumps(_absolute(tasks[i])), pure=False,
                                key=f"mpz-encode-{i}-{os.urandom(4).hex()}")
            inflight[fut] = i
        if not inflight and suspects:        # the rest done: one suspect at a time, alone
            i = suspects.pop(0)
            alone.add(i)
            fut = client.submit(encode, cloudpickle.dumps(_absolute(tasks[i])), pure=False,
                                key=f"mpz-encode-{i}-alone-{os.urandom(4).hex()}")
            inflight[fut] = i

    idle_since: float | None = None

    def watch() -> None:
        """Fail the run when the cluster has had no worker for NO_WORKER_SECONDS."""
        nonlocal idle_since
        if workers():
            idle_since = None
        elif idle_since is None:
            idle_since = time.monotonic()
        elif time.monotonic() - idle_since > NO_WORKER_SECONDS:
            raise EncoderError(
                f"the Dask cluster has had no worker for {NO_WORKER_SECONDS:.0f} s "
                "while files wait: its workers were stopped or died, cannot start (is "
                "the memory limit below what a worker needs, about 200 MB?), cannot load "
                "mpz's tasks (is this mpz installed where they run? their logs say) or "
                "none is connected; the files that finished are written and indexed: run "
                "the same command again when it has workers"
            ) from None

    try:
        submit()
        while inflight:
            try:
                done, _ = wait(list(inflight), timeout=WATCH_SECONDS,
                               return_when="FIRST_COMPLETED")
            except CancelledError as exc:    # the scheduler is gone: it was a traceback
                raise _lost(exc) from None
            except TimeoutError:
                watch()
                continue
            for fut in sorted(done, key=lambda f: inflight[f]):
                i = inflight.pop(fut)
                try:
                    # a result held by a worker that died is computed again, and result()
                    # waited for it for ever once the last worker was gone (a QA run of
                    # stop 47, --scheduler): it waits a while, and the watch runs
                    r = fut.result(timeout=WATCH_SECONDS)
                    # taken: the future is let go at once, or a worker that died holding
                    # the result while this loop still held the future (during the next
                    # wait) ran the file again (a QA run of stop 64)
                    fut.release()
                except TimeoutError:
                    inflight[fut] = i
                    watch()
                    continue
                except CancelledError as exc:
                    raise _lost(exc) from None
                except Exception as exc:
                    fut.release()
                    if str(exc).startswith(OTHER_MPZ):    # a worker that joined later
                        where, _, have = str(exc)[len(OTHER_MPZ):].partition("|")
                        raise _other_mpz("the Dask workers that join the run", version,
                                         {where: have}) from None
                    if not _killed(exc):
                        raise        # a bug in the task: stop the run, keep what finished
                    if i not in alone:
                        suspects.append(i)  # perhaps another file's death: alone, later
                        idle_since = None
                        continue
                    r = FileResult(tasks[i].source, tasks[i].output, "failed",
                                   f"its worker died each time it ran, alone too ({died}): "
                                   f"{exc}", _size(tasks[i].source))
                idle_since = None                   # a result came: workers were there
                finish(i, replace(r, source=tasks[i].source, output=tasks[i].output))
            submit()
    except BaseException as exc:
        if inflight and not isinstance(exc, _SchedulerSilent):
            with contextlib.suppress(Exception):
                client.cancel(list(inflight))
        raise
    # the worker count is for the report alone: a scheduler silent now, every file done,
    # failed a finished run (a review of stop 55)
    try:
        return len(workers()) or threads
    except _SchedulerSilent:
        return threads
