"""Payload parsing from the grammar, without construct's per-field cost (issue 15.1).

construct parses a payload field by field through several Python calls each, with a
``BytesIO`` read and a ``Container`` per record: the asfs chunk of a CMU skeleton took
5.5 ms, a third of its file's decode, and MNAM about 1 ms. :func:`parse` reads the same
grammar objects (spec/mpz/spec/grammar.py stays the one description of every layout),
written once per grammar as the Python source of a function (:class:`_Source`) that
follows construct 2.10's ``_parse`` of each class step for step: the same bytes reach the
same ``struct`` formats, adapters and count expressions, in the same order. Each Struct
is one function, its fields written out in place: a closure call per field and a loop
over the fields were about 40 % of the parse of the asfs, bvhs and cprm chunks (issue
15.1, stop 70). This is the parse-side twin of :mod:`._build`.

The grammar's rule "no ``.compile()``: compiled parsers lose error paths on untrusted
input" still holds, because the fast path never reports an error. It reads only what it
has checked is there (every read is bounded by the end of its stream before it is made,
so a count read from the payload cannot make it allocate more than the payload holds),
and at the first thing it does not take as it is (too few bytes, trailing bytes before a
``Terminated``, an adapter or a decoding that raises, a construct class or hook it does
not write) it gives up, and construct parses the payload instead: the result, record
or error, is then construct's. tests/test_grammar.py checks that both give the same
record for every chunk of every conformance vector (the invalid ones included) and of
mutated payloads.

Only the classes the grammar uses are written (``Struct``, ``Renamed``, ``FormatField``,
``Array``, ``Bytes``, ``GreedyBytes``, ``Prefixed``, ``IfThenElse``, ``Pass``,
``Terminated`` and any ``Adapter``, ``StringEncoded`` included); a grammar holding
another class, or a field with a ``parsed`` hook, is parsed by construct.
"""
from __future__ import annotations

from collections.abc import Callable
import functools
import struct
from typing import Any, cast

import construct

from mpz.chunks._build import (
    _Context,
    _format,
    _Function,
    _GiveUp,
    _Unsupported,
)

__all__ = ["parse", "fast_path"]

#: a compiled parser: ``(data, pos, end, ctx) -> (value, new pos)``, reading ``data``
#: from ``pos`` up to at most ``end`` (the end of the stream construct would read from)
_Parser = Callable[[bytes, int, int, Any], tuple[Any, int]]


#: what the adapters and decodings of the grammar raise on bytes they refuse (construct's
#: own errors, a codec's): the fast path gives up on them and construct raises its own
_REFUSED = (_GiveUp, construct.ConstructError, struct.error, UnicodeError, ValueError,
            OverflowError)


def _format_unhooked(c: construct.Construct) -> str | None:
    """:func:`._build._format` of ``c``, refusing a ``parsed`` hook on it or on any
    Renamed around it (construct would call the hook; the fast path does not)."""
    code = _format(c)
    while code is not None:
        if c.parsed is not None:
            raise _Unsupported("a parsed hook")
        if type(c) is not construct.Renamed:
            break
        c = c.subcon
    return code


def _struct(c: construct.Struct) -> _Parser:
    """A Struct: its fields in order, as the source of one function (:class:`_Source`),
    each run of consecutive named FormatFields unpacked by one ``struct`` call (the values
    of unpacking them one by one: no padding with ``<``). The record is its context, as in
    :mod:`._build`: construct's expressions read the fields parsed so far from it, and
    ``_`` is the enclosing record."""
    src = _Source(["def record(data, pos, end, ctx):", "    context = _Context(_=ctx)"])
    run: list[tuple[str, str]] = []

    def close() -> None:
        if run:
            s = struct.Struct("<" + "".join(f for _, f in run))
            unpack = src.name(s.unpack_from)
            src.line(f"if pos + {s.size} > end: raise _GiveUp")
            targets = ", ".join(f"context[{n!r}]" for n, _ in run)
            src.line(f"{targets}{',' if len(run) == 1 else ''} = {unpack}(data, pos)")
            src.line(f"pos += {s.size}")
            run.clear()
    for sc in c.subcons:
        code = _format_unhooked(sc)
        if code is not None and sc.name:
            run.append((sc.name, code))
            continue
        close()
        src.field(sc, f"context[{sc.name!r}]" if sc.name else "_")
    close()
    src.line("return context, pos")
    return src.parser("record")


class _Source(_Function):
    """The source of one parser (a Struct's, or a grammar's that is not a Struct), written
    construct by construct: each sets a target and advances ``pos`` over ``data`` up to
    ``end``, the end of the stream construct would read from, and gives up (``_GiveUp``)
    before reading past it. A nested Struct is a call of its own generated function."""

    def __init__(self, head: list[str]) -> None:
        super().__init__(head, _unpack_from=struct.unpack_from)

    def field(self, c: construct.Construct, target: str) -> None:
        """Lines that parse ``c`` into ``target``, as construct 2.10's ``_parse`` of its
        class does, or :class:`_Unsupported` for a class or hook it does not write."""
        if c.parsed is not None:
            raise _Unsupported("a parsed hook")
        t = type(c)
        if t is construct.Renamed:
            self.field(c.subcon, target)
        elif t is construct.FormatField:
            unpack = self.name(struct.Struct(c.fmtstr).unpack_from)
            self.line(f"if pos + {c.length} > end: raise _GiveUp")
            self.line(f"{target} = {unpack}(data, pos)[0]")
            self.line(f"pos += {c.length}")
        elif t is construct.Struct:
            self.line(f"{target}, pos = {self.name(_struct(c))}(data, pos, end, context)")
        elif t is construct.Array:
            self.array(c, target)
        elif t is construct.Bytes:
            n = self.temp()
            self.line(f"{n} = {self.expression(c.length)}")
            self.take(n, target)
        elif c is construct.GreedyBytes:
            self.line(f"{target} = data[pos:end]")
            self.line("pos = end")
        elif t is construct.Prefixed:
            if c.includelength:
                raise _Unsupported("Prefixed(includelength=True)")
            n = self.temp()
            self.field(c.lengthfield, n)
            if c.subcon is construct.GreedyBytes:   # a length and its bytes
                self.take(n, target)
                return
            stop, outer = self.temp(), self.temp()  # its own stream: pos .. pos + n
            self.line(f"if not 0 <= {n} <= end - pos: raise _GiveUp")
            self.line(f"{stop}, {outer}, end = pos + {n}, end, pos + {n}")
            self.field(c.subcon, target)
            self.line(f"pos, end = {stop}, {outer}")
        elif t is construct.IfThenElse:
            self.branch(c.condfunc, lambda: self.field(c.thensubcon, target),
                        lambda: self.field(c.elsesubcon, target))
        elif c is construct.Pass:
            self.line(f"{target} = None")
        elif c is construct.Terminated:
            self.line("if pos != end: raise _GiveUp")    # construct: TerminatedError
        elif isinstance(c, construct.Adapter):
            v = self.temp()
            self.field(c.subcon, v)
            self.line(f'{target} = {self.name(c._decode)}({v}, context, "(parsing)")')
        else:
            raise _Unsupported(t.__name__)

    def take(self, n: str, target: str) -> None:
        """Lines that take the next ``n`` bytes as ``target``."""
        self.line(f"if not 0 <= {n} <= end - pos: raise _GiveUp")
        self.line(f"{target} = data[pos: pos + {n}]")
        self.line(f"pos += {n}")

    def array(self, c: construct.Array, target: str) -> None:
        """Lines that parse an Array into a tuple: a run of one little-endian FormatField
        by one ``struct`` call (after checking that the stream holds it), any other item
        one by one in a loop."""
        if c.discard:
            raise _Unsupported("Array(discard=True)")
        code = _format_unhooked(c.subcon)
        if code is not None and isinstance(c.count, int):   # a fixed count: one format
            whole = struct.Struct("<" + str(c.count) + code)
            self.line(f"if not 0 <= {whole.size} <= end - pos: raise _GiveUp")
            self.line(f"{target} = {self.name(whole.unpack_from)}(data, pos)")
            self.line(f"pos += {whole.size}")
            return
        n = self.temp()
        self.line(f"{n} = {self.expression(c.count)}")
        if code is not None:
            size = struct.calcsize("<" + code)
            self.line(f"if not 0 <= {n} * {size} <= end - pos: raise _GiveUp")
            self.line(f'{target} = _unpack_from("<" + str({n}) + {code!r}, data, pos)')
            self.line(f"pos += {n} * {size}")
            return
        # n items of a byte or more cannot fit in fewer bytes: give up before the loop
        items, item = self.temp(), self.temp()
        self.line(f"if not 0 <= {n} <= end - pos: raise _GiveUp")
        self.line(f"{items} = []")
        self.line(f"for _ in range({n}):")
        self.depth += 1
        self.field(c.subcon, item)
        self.line(f"{items}.append({item})")
        self.depth -= 1
        self.line(f"{target} = tuple({items})")

    def parser(self, name: str) -> _Parser:
        return cast(_Parser, self.function(name, "<mpz.chunks._parse>"))


@functools.cache
def _parser(grammar: construct.Construct) -> _Parser | None:
    """The generated parser of ``grammar`` (a Struct's own function; any other construct
    in a function of the caller's context), or None where it holds what is not written."""
    try:
        if type(grammar) is construct.Struct and grammar.parsed is None:
            return _struct(grammar)
        src = _Source(["def top(data, pos, end, ctx):", "    context = ctx"])
        src.field(grammar, "value")
        src.line("return value, pos")
        return src.parser("top")
    except _Unsupported:
        return None


def fast_path(grammar: construct.Construct, payload: bytes) -> Any | None:
    """The parse of ``payload`` by the compiled grammar, or None where the fast path gives
    up (an unsupported class, or bytes it does not take as they are). Records come as
    dicts and arrays as tuples, which is what :meth:`Record.from_parsed` makes of
    construct's containers and lists."""
    p = _parser(grammar)
    if p is None or (isinstance(payload, memoryview) and not payload.c_contiguous):
        return None                     # construct's BytesIO refuses a strided view
    data = bytes(payload)
    try:
        value, _ = p(data, 0, len(data), _Context())
    except _REFUSED:
        return None
    return value


def parse(grammar: construct.Construct, payload: bytes) -> Any:
    """``grammar.parse(payload)``: the same fields, or construct's own error."""
    value = fast_path(grammar, payload)
    return value if value is not None else grammar.parse(payload)
