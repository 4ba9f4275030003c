"""The base of the chunk table: typed records, their context, and the shared helpers.

A :class:`Record` is a frozen dataclass of one payload's fields, in layout order; the
classes that derive from it (one per chunk type, see :mod:`mpz.chunks`) add their
layout, their § checks and, where needed, their own views of the data. Checks call
:func:`fail`, which raises without a location; :func:`mpz.container.locate` adds the
chunk type and offset in one place.
"""
from __future__ import annotations

from collections.abc import Callable, Hashable
from dataclasses import dataclass, fields
import functools
import math
import re
from typing import TYPE_CHECKING, Any, ClassVar, TypeVar, cast

import construct

from mpz.chunks import _build, _parse
from mpz.errors import FormatError, MPZError
from mpz.format import MAX_ANALOG_SAMPLES, MAX_CHANNEL_SAMPLES, MAX_SAMPLES

if TYPE_CHECKING:   # the Context names core records; core imports this module
    from mpz.chunks.core import HierNode, Mhdr, Patt

__all__ = ["Record", "Context", "JSON", "fail", "forget", "kept"]

R = TypeVar("R", bound="Record")
T = TypeVar("T")
#: a JSON value as ``mpzinfo --json`` writes it
JSON = Any


def fail(message: str, section: str, cls: type[MPZError] = FormatError) -> None:
    """Raise a rule violation; the reader adds the chunk type and offset."""
    raise cls(message, section=section)


def kept(rec: object, key: Hashable, compute: Callable[[], T]) -> T:
    """``compute()``, kept on ``rec`` under ``key`` until :func:`forget`.

    A chunk's check() decodes its payload to know that it decodes, and the decoder then
    needs the values: with this the payload is decoded once (issue 15.1). Records are
    frozen, so the value is stored past ``__setattr__``, outside the fields: equality,
    ``repr`` and ``replace()`` do not see it, and it goes when the record goes."""
    store: dict[Hashable, Any] = rec.__dict__.setdefault("_kept", {})
    if key not in store:
        store[key] = compute()
    return cast(T, store[key])


def forget(rec: object) -> None:
    """Drop the values :func:`kept` holds for ``rec`` (once the decoder has taken them)."""
    rec.__dict__.pop("_kept", None)


def infinite_as_text(v: Any) -> Any:
    """``v`` (a float, or lists, tuples and dicts of them) with each float that is not
    finite as the text ``"inf"``, ``"-inf"`` or ``"nan"``: how mpzinfo shows a field
    that JSON cannot hold (docs/mpzinfo.md)."""
    if isinstance(v, float) and not math.isfinite(v):
        return "nan" if math.isnan(v) else "inf" if v > 0 else "-inf"
    if isinstance(v, dict):
        return {k: infinite_as_text(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [infinite_as_text(x) for x in v]
    return v


def _jsonable(v: object) -> JSON:
    """A field value as mpzinfo shows it: bulk bytes as their size and first 16 bytes;
    a binary64 that is not finite as the text ``"inf"``, ``"-inf"`` or ``"nan"`` (JSON
    has none: an asfs limit of ±∞, which §4.14.2 allows, showed as null, as if unknown)."""
    if isinstance(v, float):
        return infinite_as_text(v)
    if isinstance(v, (bytes, bytearray)):
        return {"bytes": len(v), "head": bytes(v[:16]).hex()}
    if isinstance(v, Record):
        return v.info()
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    return v


def _plain(v: object) -> object:
    """construct's parse result -> plain Python (ListContainer -> tuple), and the lists the
    grammar's adapters make (names, weights) -> tuples: a list's items are looked into
    only when they are lists themselves."""
    if isinstance(v, list):
        return tuple([_plain(x) if isinstance(x, list) else x for x in v])
    return v


@dataclass(frozen=True)
class Context:
    """What the §3.4 order has established when a chunk is checked."""

    header: Mhdr
    max_samples: int
    nodes: tuple[HierNode, ...] = ()
    node: int = 0                      # the node a PATT/SEGS/RESI belongs to
    patt: Patt | None = None           # that node's PATT (for SEGS and RESI)
    #: the type of every chunk of the file, in order (for the presence and count rules of
    #: ancillary chunks that come in sets, §4.13); empty where no rule needs it
    types: tuple[str, ...] = ()

    @property
    def members(self) -> int:
        """n_i, the member count of the node being checked."""
        return self.nodes[self.node].member_count

    def limit(self, name: str) -> tuple[int, str]:
        """MAX_ANALOG_SAMPLES or MAX_CHANNEL_SAMPLES (``name``) as this decode applies it,
        and what to add to an error naming it: "" for the table's value, else why it is
        lower. ``max_samples`` below MAX_SAMPLES (a decoder's lower MAX_SAMPLES, §8) lowers
        them to 4 x max_samples and max_samples (the table's ratios), so that one option
        bounds the memory of every chunk (§8, memory budget)."""
        spec, per = {"MAX_ANALOG_SAMPLES": (MAX_ANALOG_SAMPLES, 4),
                     "MAX_CHANNEL_SAMPLES": (MAX_CHANNEL_SAMPLES, 1)}[name]
        if self.max_samples >= MAX_SAMPLES:
            return spec, ""
        low = min(spec, per * self.max_samples)
        times = "" if per == 1 else f"{per} x "
        return low, f" (this decoder's {name}: {times}its max_samples {self.max_samples})"


@dataclass(frozen=True)
class Record:
    """Base of every chunk record (and of the records nested in them)."""

    TYPE: ClassVar[str] = ""
    SECTION: ClassVar[str] = "§4"
    #: the minor version that introduced this chunk type (§2.1): a file holding it is
    #: written as 1.MINOR at least
    MINOR: ClassVar[int] = 0
    #: the part of a file it counts in when sizes are reported by part (``mpz encode``,
    #: ``mpzinfo``, the corpus index): "analog", "skeleton" or "summary", else "other"
    #: (the critical chunks are the "markers" part by their upper-case type, §3.2)
    PART: ClassVar[str] = "other"
    GRAMMAR: ClassVar[construct.Construct]
    #: nested record class of a field holding a list of records
    NESTED: ClassVar[dict[str, type[Record]]] = {}

    @classmethod
    def from_parsed(cls: type[R], c: Any) -> R:
        """The record of a parse result (construct's, or :mod:`._parse`'s dicts and tuples)."""
        make = _MAKERS.get(cls)
        if make is None:
            make = _maker(cls)
        return cast(R, make(c))

    def to_build(self) -> dict[str, object]:
        """The dict construct builds the payload from: tuples as lists, nested records as
        their own dicts (a generated function per class, :func:`_to_build`)."""
        cls = type(self)
        make = _TO_BUILD.get(cls)
        if make is None:
            make = _to_build(cls)
        return make(self)

    @classmethod
    def load(cls: type[R], payload: bytes) -> R:
        """Parse a payload. Raises FormatError, under the chunk's own § (its layout), for
        bytes that do not fit the layout."""
        try:
            parsed = _parse.parse(cls.GRAMMAR, payload)
        except _LAYOUT_ERRORS as exc:  # R-3.2-3
            # construct reports layout problems with these; translated here, at the one
            # boundary between the grammar and the rest of the decoder
            raise FormatError(f"malformed {cls.TYPE} payload: {_layout_problem(exc)}",
                              chunk=cls.TYPE, section=cls.SECTION) from None
        return cls.from_parsed(parsed)

    def dump(self) -> bytes:
        """The payload bytes of this record (``GRAMMAR.build``, by :mod:`._build`)."""
        return _build.build(self.GRAMMAR, self.to_build())

    def check(self, ctx: Context) -> None:
        """The rules of this chunk's § (nothing to check by default)."""

    def info(self) -> dict[str, JSON]:
        """The fields as mpzinfo shows them, in layout order."""
        return {f.name: _jsonable(getattr(self, f.name)) for f in fields(self)}

    @classmethod
    def field_offsets(cls, payload: bytes) -> list[tuple[str, int]]:
        """(name, offset in the payload) of each top-level field: one parse with the
        position taken before each field; for a malformed payload, the fields that parse,
        by parsing ever longer prefixes (that was every payload's way, quadratic in the
        field count: 0.6 s of ``mpzinfo -vv`` on a CMU skeleton, issue 15)."""
        subcons = [s for s in cls.GRAMMAR.subcons if s.name]
        marked: list[construct.Construct] = []
        for i, sc in enumerate(subcons):
            marked += [f"_pos{i}" / construct.Tell, sc]
        try:
            parsed = construct.Struct(*marked).parse(payload)
        except _LAYOUT_ERRORS:
            pass
        else:
            return [(sc.name, int(parsed[f"_pos{i}"])) for i, sc in enumerate(subcons)]
        out = []
        for i, sc in enumerate(subcons):
            probe = construct.Struct(*subcons[:i], "_pos" / construct.Tell)
            try:
                start = probe.parse(payload)._pos
            except _LAYOUT_ERRORS:
                break          # a malformed payload: show the fields that parsed
            out.append((sc.name, int(start)))
        return out

    @classmethod
    def stored_fields(cls, payload: bytes) -> dict[str, Any]:
        """The top-level fields that the grammar adapts (§4.2's front-coded names, §4.3's
        weight codes) as they are stored, for ``mpzinfo -vv``: lists and dicts, each
        struct of them with ``at``, its offset in the payload. Empty when no field is
        adapted or the payload does not parse (the record's own checks say why)."""
        named, grammar = _stored_grammar(cls.GRAMMAR)
        if not named:
            return {}
        try:
            parsed = grammar.parse(payload)
        except _LAYOUT_ERRORS:
            return {}
        out = {}
        for name in named:
            v = _as_stored(parsed[name])
            if isinstance(v, dict) and "at" not in v:   # a string: asfs's name, version ...
                v = {"at": int(parsed[f"_at_{name}"]), **v}
            out[name] = v
        return out


@functools.cache
def _stored_grammar(grammar: construct.Construct) -> tuple[tuple[str, ...],
                                                           construct.Construct]:
    """The names of ``grammar``'s adapted top-level fields, and the grammar without its
    adapters (:func:`_stored`), each top-level field after ``_at_NAME``, its offset:
    built once per chunk type, not per chunk shown."""
    named = tuple(sc.name for sc in grammar.subcons if sc.name and _adapts(sc))
    # each top-level field preceded by its offset, for the fields that are no Struct
    marked = [x for sc in grammar.subcons
              for x in ((f"_at_{sc.name}" / construct.Tell, _stored(sc)) if sc.name
                        else (_stored(sc),))]
    return named, construct.Struct(*marked)


def _adapts(c: construct.Construct) -> bool:
    """Whether an Adapter lies anywhere in ``c``."""
    if isinstance(c, construct.Adapter):
        return True
    inner = [*getattr(c, "subcons", ()), *([c.subcon] if hasattr(c, "subcon") else [])]
    return any(_adapts(s) for s in inner)


def _stored(c: construct.Construct) -> construct.Construct:
    """``c`` without its adapters, each Struct beginning with ``at`` (its offset)."""
    if isinstance(c, construct.Adapter):
        return _stored(c.subcon)
    if isinstance(c, construct.Renamed):
        return construct.Renamed(_stored(c.subcon), newname=c.name, newdocs=c.docs)
    if isinstance(c, construct.Struct):
        return construct.Struct("at" / construct.Tell, *[_stored(s) for s in c.subcons])
    if isinstance(c, construct.Array):
        return construct.Array(c.count, _stored(c.subcon))
    return c


def _as_stored(v: Any) -> Any:
    """A construct parse result as plain lists and dicts (no ``_io``), bytes as their
    length and hex digits."""
    if isinstance(v, dict):
        return {k: _as_stored(x) for k, x in v.items() if not k.startswith("_")}
    if isinstance(v, list):
        return [_as_stored(x) for x in v]
    if isinstance(v, bytes):
        return {"bytes": len(v), "hex": v.hex()}
    return v


#: the exceptions construct reports a payload that does not fit its layout with
_LAYOUT_ERRORS = (construct.ConstructError, UnicodeDecodeError)


_NAMES: dict[type, tuple[str, ...]] = {}
#: each record class's from_parsed, made once by :func:`_maker`
_MAKERS: dict[type, Callable[[Any], Record]] = {}


#: each record class's to_build, made once by :func:`_to_build`
_TO_BUILD: dict[type, Callable[[Any], dict[str, object]]] = {}


def _to_build(cls: type[Record]) -> Callable[[Any], dict[str, object]]:
    """``cls.to_build`` as the source of one function: each field read by name, a tuple
    made a list, a field of nested records (``NESTED``) made by their own ``to_build``. A
    loop over the fields with a getattr and two tests each was most of it, and the
    encoder makes 130 such dicts for a C3D's parameter section (issue 15.1, stop 70)."""
    env: dict[str, Any] = {}
    lines = ["def to_build(r):"]
    names = _field_names(cls)
    for i, name in enumerate(names):
        if name in cls.NESTED:
            lines.append(f"    v{i} = [x.to_build() for x in r.{name}]")
        else:
            lines.append(f"    v{i} = r.{name}")
            lines.append(f"    if isinstance(v{i}, tuple): v{i} = list(v{i})")
    lines.append("    return {" + ", ".join(f"{n!r}: v{i}" for i, n in enumerate(names)) + "}")
    exec(compile("\n".join(lines), f"<{cls.__name__}.to_build>", "exec"), env)
    make = _TO_BUILD[cls] = env["to_build"]
    return cast(Callable[[Any], dict[str, object]], make)


def _maker(cls: type[Record]) -> Callable[[Any], Record]:
    """``cls.from_parsed`` as the source of one function: each field read from the parse
    result by name, construct's lists made tuples (:func:`_plain`; the fast path's arrays
    are tuples already), a field of nested records (``NESTED``) made by their own maker.
    A class with a ``__post_init__`` is made by its ``__init__``; any other as its frozen
    dataclass ``__init__`` makes it (every field set, in layout order) without its
    ``object.__setattr__`` per field: 1.1 us a record against 0.2, and a CMU C3D's
    parameter section alone holds ~200 records (issue 15.1, decoding). A loop over the
    fields per record was half of what was left (stop 70)."""
    env: dict[str, Any] = {"_cls": cls, "_new": object.__new__, "_plain": _plain}
    lines = ["def make(c):"]
    names = _field_names(cls)
    for i, name in enumerate(names):
        nested = cls.NESTED.get(name)
        if nested is not None:
            env[f"_m{i}"] = _MAKERS.get(nested) or _maker(nested)
            lines.append(f"    v{i} = tuple([_m{i}(x) for x in c[{name!r}]])")
        else:
            lines.append(f"    v{i} = c[{name!r}]")
            lines.append(f"    if isinstance(v{i}, list): v{i} = _plain(v{i})")
    values = ", ".join(f"{name!r}: v{i}" for i, name in enumerate(names))
    if hasattr(cls, "__post_init__"):
        lines.append(f"    return _cls(**{{{values}}})")
    else:
        lines += ["    rec = _new(_cls)", f"    rec.__dict__.update({{{values}}})",
                  "    return rec"]
    exec(compile("\n".join(lines), f"<{cls.__name__}.from_parsed>", "exec"), env)
    make = _MAKERS[cls] = env["make"]
    return cast(Callable[[Any], Record], make)


def _field_names(cls: type[Record]) -> tuple[str, ...]:
    """The field names of a record class, in layout order (``fields`` builds its tuple on
    every call: a tenth of the asfs chunk's build time, issue 15.1)."""
    names = _NAMES.get(cls)
    if names is None:
        names = _NAMES[cls] = tuple(f.name for f in fields(cls))
    return names


#: a bytes literal in a message, and a number of many digits (construct quotes both)
_BYTES_LITERAL = re.compile(r"b'(?:[^'\\]|\\.)*'" + r'|b"(?:[^"\\]|\\.)*"')
_LONG_NUMBER = re.compile(r"\d{25,}")


#: construct's path to the field it was reading ("Error in path (parsing) -> a -> a -> b")
_PATH = re.compile(r"Error in path \(parsing\)((?: -> [^\n]*)?)")
_SHORT_READ = re.compile(r"stream read less than specified amount, expected (\d+), found (\d+)")


def _layout_problem(exc: BaseException) -> str:
    """What construct's error says about the payload, in the spec's terms: the field where
    the payload ends (construct's path, each name once: it names a field and then its
    subconstruct), bytes left after the last field, or a string that is not UTF-8; its
    other messages (the grammar's own checks among them) as they are, shortened."""
    text = str(exc)
    path = _PATH.search(text)
    names = [] if path is None else [n for n in path.group(1).split(" -> ") if n]
    field = ".".join(n for i, n in enumerate(names) if i == 0 or n != names[i - 1])
    short = _SHORT_READ.search(text)
    if short is not None:
        need, left = int(short.group(1)), int(short.group(2))
        need_text = (f"{need} byte{'s' if need != 1 else ''}" if need < 10 ** 25 else
                     f"<a {len(short.group(1))}-digit number of> bytes")
        where = f"field '{field}'" if field else "a field"
        return f"the payload ends inside {where}: {need_text} needed, {left} left"
    if isinstance(exc, construct.TerminatedError):
        return "bytes are left after the last field of the layout"
    if isinstance(exc, construct.StringError) and "decode" in text:
        stored = _BYTES_LITERAL.search(_short(exc))
        return (f"a string{f' ({field})' if field else ''} is not valid UTF-8"
                + (f": {stored.group(0)}" if stored else ""))
    return _short(exc)


def _short(exc: BaseException) -> str:
    """The last line of construct's message, with a quoted run of bytes cut to its first
    32 characters and a number of 25 digits or more named by its length: a misread
    count could otherwise put hundreds of payload bytes into the error (a QA run, stop
    40: 507 characters for an asfs string read from the wrong place)."""
    text = str(exc).strip().splitlines()
    line = text[-1] if text else type(exc).__name__
    line = _BYTES_LITERAL.sub(
        lambda m: m.group(0) if len(m.group(0)) <= 40 else
        f"{m.group(0)[:32]}... ({len(m.group(0))} characters)", line)
    return _LONG_NUMBER.sub(lambda m: f"<a {len(m.group(0))}-digit number>", line)


