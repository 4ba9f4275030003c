"""Payload parsing from the grammar, without construct's per-field cost (issue 15.1).

construct parses a payload field by field through several Python calls each, with a
``BytesIO`` read and a ``Container`` per record: the asfs chunk of a CMU skeleton took
5.5 ms, a third of its file's decode, and MNAM about 1 ms. :func:`parse` walks the same
grammar objects (spec/mpz/spec/grammar.py stays the one description of every layout),
turned once into plain closures by :func:`_compile`, which follow construct 2.10's
``_parse`` of each class step for step: the same bytes reach the same ``struct``
formats, adapters and count expressions, in the same order. This is the parse-side twin
of :mod:`._build`. A Struct becomes the source of one function (:class:`_Source`), its
common fields written out in place: a closure call per field and a loop over the fields
were most of what was left, about 40 % of the parse of the asfs, bvhs and cprm chunks
(issue 15.1, stop 70).

The grammar's rule "no ``.compile()``: compiled parsers lose error paths on untrusted
input" still holds, because the fast path never reports an error. It reads only what it
has checked is there (every read is bounded by the end of its stream before it is made,
so a count read from the payload cannot make it allocate more than the payload holds),
and at the first thing it does not take as it is (too few bytes, trailing bytes before a
``Terminated``, an adapter or a decoding that raises, a construct class or hook it does
not compile) it gives up, and construct parses the payload instead: the result, record
or error, is then construct's. tests/test_grammar.py checks that both give the same
record for every chunk of every conformance vector (the invalid ones included) and of
mutated payloads.

Only the classes the grammar uses are compiled (``Struct``, ``Renamed``, ``FormatField``,
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
    _expression,
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


def _none(data: bytes, pos: int, end: int, ctx: Any) -> tuple[Any, int]:
    return None, pos                    # Pass


def _terminated(data: bytes, pos: int, end: int, ctx: Any) -> tuple[Any, int]:
    if pos != end:                      # construct: TerminatedError
        raise _GiveUp
    return None, pos


def _greedy(data: bytes, pos: int, end: int, ctx: Any) -> tuple[Any, int]:
    return data[pos:end], end


def _compile(c: construct.Construct) -> _Parser:
    if c.parsed is not None:
        raise _Unsupported("a parsed hook")
    t = type(c)
    if t is construct.Renamed:
        return _compile(c.subcon)
    if t is construct.FormatField:
        unpack, size = struct.Struct(c.fmtstr).unpack_from, c.length

        def field(data: bytes, pos: int, end: int, ctx: Any) -> tuple[Any, int]:
            if pos + size > end:
                raise _GiveUp
            return unpack(data, pos)[0], pos + size
        return field
    if t is construct.Struct:
        return _struct(c)
    if t is construct.Array:
        if c.discard:
            raise _Unsupported("Array(discard=True)")
        return _array(c)
    if t is construct.Bytes:
        length = _expression(c.length)

        def fixed(data: bytes, pos: int, end: int, ctx: Any) -> tuple[Any, int]:
            n = length(ctx)
            if not 0 <= n <= end - pos:
                raise _GiveUp
            return data[pos: pos + n], pos + n
        return fixed
    if c is construct.GreedyBytes:
        return _greedy
    if t is construct.Prefixed:
        if c.includelength:
            raise _Unsupported("Prefixed(includelength=True)")
        sub, lengthfield = _compile(c.subcon), _compile(c.lengthfield)
        code = _format(c.lengthfield)
        if sub is _greedy and code is not None:    # a length and its bytes: one step
            unpack, size = struct.Struct("<" + code).unpack_from, struct.calcsize("<" + code)

            def length_and_bytes(data: bytes, pos: int, end: int, ctx: Any) -> tuple[Any, int]:
                if pos + size > end:
                    raise _GiveUp
                n = unpack(data, pos)[0]
                pos += size
                if not 0 <= n <= end - pos:
                    raise _GiveUp
                return data[pos: pos + n], pos + n
            return length_and_bytes

        def prefixed(data: bytes, pos: int, end: int, ctx: Any) -> tuple[Any, int]:
            n, pos = lengthfield(data, pos, end, ctx)
            if not 0 <= n <= end - pos:
                raise _GiveUp
            value, _ = sub(data, pos, pos + n, ctx)    # its own stream: pos .. pos + n
            return value, pos + n
        return prefixed
    if t is construct.IfThenElse:
        cond = _expression(c.condfunc)
        then, other = _compile(c.thensubcon), _compile(c.elsesubcon)

        def choice(data: bytes, pos: int, end: int, ctx: Any) -> tuple[Any, int]:
            taken = then if cond(ctx) else other
            return taken(data, pos, end, ctx)
        return choice
    if c is construct.Pass:
        return _none
    if c is construct.Terminated:
        return _terminated
    if isinstance(c, construct.Adapter):
        decode, sub = c._decode, _compile(c.subcon)

        def adapted(data: bytes, pos: int, end: int, ctx: Any) -> tuple[Any, int]:
            value, pos = sub(data, pos, end, ctx)
            return decode(value, ctx, "(parsing)"), pos
        return adapted
    raise _Unsupported(type(c).__name__)


def _array(c: construct.Array) -> _Parser:
    """An Array: a run of one little-endian FormatField by one ``struct`` call (after
    checking that the stream holds it), any other item one by one."""
    count = _expression(c.count)
    code = _format(c.subcon)
    sub = _compile(c.subcon)            # also refuses a parsed hook on the item
    if code is not None:
        size = struct.calcsize("<" + code)

        def packed(data: bytes, pos: int, end: int, ctx: Any) -> tuple[Any, int]:
            n = count(ctx)
            if not 0 <= n * size <= end - pos:
                raise _GiveUp
            return struct.unpack_from("<" + str(n) + code, data, pos), pos + n * size
        return packed

    def array(data: bytes, pos: int, end: int, ctx: Any) -> tuple[Any, int]:
        n = count(ctx)
        if not 0 <= n <= end - pos:       # n items of a byte or more cannot fit: give up
            raise _GiveUp
        out = []
        for _ in range(n):
            value, pos = sub(data, pos, end, ctx)
            out.append(value)
        return tuple(out), pos
    return array


def _struct(c: construct.Struct) -> _Parser:
    """A Struct: its fields in order, as the source of one function (:func:`_Source`):
    each run of consecutive named FormatFields unpacked by one ``struct`` call (the values
    of unpacking them one by one: no padding with ``<``), and the common fields (a
    length and its bytes, a condition, an adapter) written out in place rather than
    called through a closure each. The record is its context, as in :mod:`._build`:
    construct's expressions read the fields parsed so far from it, and ``_`` is the
    enclosing record."""
    src = _Source()
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
        code = _format(sc)
        if code is not None and sc.name:
            _compile(sc)                # refuses a parsed hook in a Renamed chain
            run.append((sc.name, code))
            continue
        close()
        src.field(sc, f"context[{sc.name!r}]" if sc.name else "_")
    close()
    return src.parser()


class _Source(_Function):
    """The source of one Struct's parser, written field by field: each field sets a target
    (``context[name]``) and advances ``pos``, giving up (``_GiveUp``) exactly where the
    closures of :func:`_compile` do."""

    def __init__(self) -> None:
        super().__init__(["def record(data, pos, end, ctx):", "    context = _Context(_=ctx)"],
                         _unpack_from=struct.unpack_from)

    def field(self, c: construct.Construct, target: str) -> None:
        """Lines that parse ``c`` into ``target``."""
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
        elif t is construct.Prefixed and c.subcon is construct.GreedyBytes \
                and not c.includelength:        # a length and its bytes
            self.field(c.lengthfield, "n")
            self.line("if not 0 <= n <= end - pos: raise _GiveUp")
            self.line(f"{target} = data[pos: pos + n]")
            self.line("pos += n")
        elif t is construct.Array and not c.discard and _format(c.subcon) is not None:
            _compile(c.subcon)              # refuses a parsed hook on the item
            code = str(_format(c.subcon))
            size = struct.calcsize("<" + code)
            if isinstance(c.count, int):            # a fixed count: one struct format
                whole = struct.Struct("<" + str(c.count) + code)
                self.line(f"if not 0 <= {whole.size} <= end - pos: raise _GiveUp")
                self.line(f"{target} = {self.name(whole.unpack_from)}(data, pos)")
                self.line(f"pos += {whole.size}")
            else:
                self.line(f"n = {self.expression(c.count)}")
                self.line(f"if not 0 <= n * {size} <= end - pos: raise _GiveUp")
                self.line(f'{target} = _unpack_from("<" + str(n) + {code!r}, data, pos)')
                self.line(f"pos += n * {size}")
        elif t is construct.Bytes:
            self.line(f"n = {self.expression(c.length)}")
            self.line("if not 0 <= n <= end - pos: raise _GiveUp")
            self.line(f"{target} = data[pos: pos + n]")
            self.line("pos += n")
        elif t is construct.IfThenElse:
            self.branch(c.condfunc, lambda: self.field(c.thensubcon, target),
                        lambda: self.field(c.elsesubcon, target))
        elif c is construct.Pass:
            self.line(f"{target} = None")
        elif c is construct.Terminated:
            self.line("if pos != end: raise _GiveUp")
        elif isinstance(c, construct.Adapter):
            decode = self.name(c._decode)
            self.field(c.subcon, "v")
            self.line(f'{target} = {decode}(v, context, "(parsing)")')
        else:
            sub = self.name(_compile(c))
            self.line(f"{target}, pos = {sub}(data, pos, end, context)")

    def parser(self) -> _Parser:
        self.line("return context, pos")
        return cast(_Parser, self.function("record", "<mpz.chunks._parse>"))


@functools.cache
def _parser(grammar: construct.Construct) -> _Parser | None:
    try:
        return _compile(grammar)
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
