"""Payload building from the grammar, without construct's per-field cost (issue 15.1).

construct builds a payload field by field through several Python calls each: about 1 us a
field, so 2.3 ms for the asfs chunk of a CMU skeleton and 0.3 ms for 41 marker names,
a fifth of a short clip's fixed encoding cost. :func:`build` reads the same grammar
objects (spec/mpz/spec/grammar.py stays the one description of every layout), written
once per grammar as the Python source of a function (:class:`_Source`) that follows
construct 2.10's ``_build`` of each class step for step: the same values reach the same
``struct`` formats, adapters and count expressions, in the same order. Each Struct is one
function, its fields written out in place: a closure call per field and the loop over the
fields were about a third of what was left of building the asfs, bvhs and cprm chunks
(issue 15.1, stop 70). :mod:`._parse` does the same on the parse side.

Only the classes the grammar uses are written (``Struct``, ``Renamed``, ``FormatField``,
``Array``, ``Bytes``, ``GreedyBytes``, ``Prefixed``, ``IfThenElse``, ``Pass``,
``Terminated`` and any ``Adapter``); a grammar holding another class is built by
construct. Whatever the fast path does not take as it is (a count that does not match,
a value ``struct`` refuses, an adapter that raises, bytes of the wrong length or type)
makes it give up, and construct builds the payload instead and raises its own error for
it: the result, error or bytes, is construct's. tests/test_grammar.py checks that both
give the same bytes for every chunk of every conformance vector and of real encodes.
"""
from __future__ import annotations

from collections.abc import Callable
import functools
import operator
import struct
from typing import Any, cast

import construct

__all__ = ["build", "fast_path"]

#: a compiled builder: appends the bytes of ``obj`` to ``out`` and returns what construct's
#: ``_build`` returns (the value a Struct keeps in its context for later fields)
_Builder = Callable[[Any, list[bytes], Any], Any]


class _Context(dict[str, Any]):
    """A Struct's context as construct's expressions read it (``this.count`` by item,
    ``ctx.type`` by attribute), without ``Container``'s Python-level ``update``."""

    def __getattr__(self, name: str) -> Any:
        try:
            return self[name]
        except KeyError:
            raise AttributeError(name) from None


class _Unsupported(Exception):
    """A construct class this module does not compile."""


class _GiveUp(Exception):
    """A value (here) or bytes (:mod:`._parse`) the fast path does not take as they are:
    construct builds or parses the payload instead."""


def _expression(e: Any) -> Callable[[Any], Any]:
    """construct's count, length or condition ``e`` as a plain function of the context,
    computed as construct computes it: a ``this`` path by the same item reads, a binary
    or unary expression by its operator on its compiled operands, any other callable (the
    grammar's own functions) called, and a constant returned. construct evaluates an
    expression through a Python call per node and per operand; a CMU C3D's parameter
    section evaluates ``this.group > 0`` three times for each of its ~200 records."""
    if isinstance(e, construct.expr.Path):
        parent, field = e._Path__parent, e._Path__field
        if parent is None:
            return _itself
        if parent._Path__parent is None:     # this.field: one item read
            return lambda ctx: ctx[field]
        up = _expression(parent)
        return lambda ctx: up(ctx)[field]
    if isinstance(e, construct.expr.BinExpr):
        op, lhs, rhs = e.op, _expression(e.lhs), _expression(e.rhs)
        return lambda ctx: op(lhs(ctx), rhs(ctx))
    if isinstance(e, construct.expr.UniExpr):
        uop, operand = e.op, _expression(e.operand)
        return lambda ctx: uop(operand(ctx))
    if callable(e):
        return cast(Callable[[Any], Any], e)
    return lambda ctx: e


#: the operators of construct's expressions that :func:`_source` writes as Python
_OPERATORS = {operator.add: "+", operator.sub: "-", operator.mul: "*",
              operator.floordiv: "//", operator.mod: "%", operator.gt: ">",
              operator.ge: ">=", operator.lt: "<", operator.le: "<=", operator.eq: "==",
              operator.ne: "!="}


def _source(e: Any) -> str | None:
    """construct's count, length or condition ``e`` as a Python expression of
    ``context`` (a generated function's record), computed as :func:`_expression` computes
    it: ``this.field`` as ``context['field']``, ``this._.field`` as
    ``context['_']['field']``, an operator on its operands, an int constant as itself;
    None for anything else (a function of the grammar, another operator), which
    :func:`_expression` then calls."""
    if isinstance(e, construct.expr.Path):
        parent, field = e._Path__parent, e._Path__field
        if parent is None:
            return "context"
        up = _source(parent)
        return None if up is None else f"{up}[{field!r}]"
    if isinstance(e, construct.expr.BinExpr) and e.op in _OPERATORS:
        lhs, rhs = _source(e.lhs), _source(e.rhs)
        if lhs is None or rhs is None:
            return None
        return f"({lhs} {_OPERATORS[e.op]} {rhs})"
    if type(e) is int:
        return repr(e)
    return None


def _itself(ctx: Any) -> Any:
    return ctx                          # construct's ``this``: the context itself


def _format(c: construct.Construct) -> str | None:
    """The little-endian ``struct`` code of a FormatField (through Renamed), else None."""
    while type(c) is construct.Renamed:
        c = c.subcon
    if type(c) is construct.FormatField and c.fmtstr[:1] == "<" and len(c.fmtstr) == 2:
        return str(c.fmtstr[1])
    return None


def _struct(c: construct.Struct) -> _Builder:
    """A Struct: its fields in order, as the source of one function (:class:`_Source`),
    each run of consecutive named FormatFields packed by one ``struct`` call (the bytes
    of packing them one by one: no padding with ``<``)."""
    src = _Source(["def record(obj, out, ctx):", "    if obj is None:", "        obj = {}",
                   "    context = _Context(obj)", '    context["_"] = ctx'])
    run: list[tuple[str, str]] = []

    def close() -> None:
        if run:
            pack = src.name(struct.Struct("<" + "".join(f for _, f in run)).pack)
            # (the context, a copy of obj, holds these values already)
            src.line(f"out.append({pack}({', '.join(f'obj[{n!r}]' for n, _ in run)}))")
            run.clear()
    for sc in c.subcons:
        code = _format(sc)
        if code is not None and sc.name and not sc.flagbuildnone:
            run.append((sc.name, code))
            continue
        close()
        name = sc.name
        v = src.temp()
        src.line(f"{v} = " + (f"obj.get({name!r}, None)" if sc.flagbuildnone
                               else f"obj[{name!r}]"))
        if name:
            src.line(f"context[{name!r}] = {v}")
        src.field(sc, v, f"context[{name!r}]" if name else "_")
    close()
    src.line("return context")
    return src.builder("record")


class _Function:
    """The Python source of one generated function, written line by line (at ``depth``
    levels of indentation), and the namespace it runs in: :meth:`name` puts an object
    there (a struct format, a compiled expression, an adapter's method, a nested Struct's
    function) and gives the name it has in the source. The builders here and the parsers
    of :mod:`._parse` are written with it."""

    def __init__(self, head: list[str], **names: Any) -> None:
        self.lines = list(head)
        self.depth = 1
        self.temps = 0
        self.env: dict[str, Any] = {"_Context": _Context, "_GiveUp": _GiveUp, **names}

    def name(self, obj: Any) -> str:
        key = f"_o{len(self.env)}"
        self.env[key] = obj
        return key

    def temp(self) -> str:
        """A new local name."""
        self.temps += 1
        return f"t{self.temps}"

    def line(self, text: str) -> None:
        self.lines.append("    " * self.depth + text)

    def expression(self, e: Any) -> str:
        """construct's expression ``e`` as source of ``context``: written out
        (:func:`_source`), or a call of its compiled function (:func:`_expression`)."""
        return _source(e) or f"{self.name(_expression(e))}(context)"

    def branch(self, cond: Any, then: Callable[[], None], other: Callable[[], None]) -> None:
        """``if cond: then else: other``, each side's lines written by its callable."""
        self.line(f"if {self.expression(cond)}:")
        for side, head in ((then, None), (other, "else:")):
            if head:
                self.line(head)
            self.depth += 1
            side()
            self.depth -= 1

    def function(self, name: str, where: str) -> Any:
        """The function ``name`` the lines define (``where`` names its source in tracebacks)."""
        exec(compile("\n".join(self.lines), where, "exec"), self.env)
        return self.env[name]


class _Source(_Function):
    """The source of one builder (a Struct's, or a grammar's that is not a Struct),
    written construct by construct: each appends its bytes to ``out`` and sets a target to
    what construct's ``_build`` returns for it (the value a Struct keeps in its context),
    giving up (``_GiveUp``) where construct would refuse the value or build it otherwise.
    A nested Struct is a call of its own generated function."""

    def __init__(self, head: list[str]) -> None:
        super().__init__(head, _pack=struct.pack)

    def data(self, value: str) -> str:
        """Lines that take ``value`` as bytes (a bytearray as its bytes), or give up."""
        d = self.temp()
        self.line(f"{d} = bytes({value}) if type({value}) is bytearray else {value}")
        self.line(f"if type({d}) is not bytes: raise _GiveUp")
        return d

    def field(self, c: construct.Construct, value: str, target: str) -> None:
        """Lines that build ``c`` from the expression ``value`` and set ``target``, as
        construct 2.10's ``_build`` of its class does, or :class:`_Unsupported`."""
        t = type(c)
        if t is construct.Renamed:
            self.field(c.subcon, value, target)
        elif t is construct.FormatField:
            self.line(f"out.append({self.name(struct.Struct(c.fmtstr).pack)}({value}))")
            self.line(f"{target} = {value}")
        elif t is construct.Struct:
            self.line(f"{target} = {self.name(_struct(c))}({value}, out, context)")
        elif t is construct.Array:
            self.array(c, value, target)
        elif t is construct.Bytes:
            n = self.temp()
            self.line(f"{n} = {self.expression(c.length)}")
            d = self.data(value)
            self.line(f"if len({d}) != {n}: raise _GiveUp")
            self.line(f"out.append({d})")
            self.line(f"{target} = {d}")
        elif c is construct.GreedyBytes:
            d = self.data(value)
            self.line(f"out.append({d})")
            self.line(f"{target} = {d}")
        elif t is construct.Prefixed:
            if c.includelength:
                raise _Unsupported("Prefixed(includelength=True)")
            if c.subcon is construct.GreedyBytes and _format(c.lengthfield) is not None:
                d = self.data(value)                        # a length and its bytes
                pack = self.name(struct.Struct("<" + str(_format(c.lengthfield))).pack)
                self.line(f"out.append({pack}(len({d})))")
                self.line(f"out.append({d})")
                self.line(f"{target} = {d}")
                return
            outer, d = self.temp(), self.temp()     # the subcon's bytes first, then both
            self.line(f"{outer}, out = out, []")
            self.field(c.subcon, value, target)
            self.line(f"{d}, out = b''.join(out), {outer}")
            self.field(c.lengthfield, f"len({d})", "_")
            self.line(f"out.append({d})")
        elif t is construct.IfThenElse:
            self.branch(c.condfunc, lambda: self.field(c.thensubcon, value, target),
                        lambda: self.field(c.elsesubcon, value, target))
        elif c is construct.Pass or c is construct.Terminated:
            self.line(f"{target} = {value}")                # nothing written
        elif isinstance(c, construct.Adapter):
            v = self.temp()
            self.line(f'{v} = {self.name(c._encode)}({value}, context, "(building)")')
            self.field(c.subcon, v, "_")
            self.line(f"{target} = {value}")
        else:
            raise _Unsupported(t.__name__)

    def array(self, c: construct.Array, value: str, target: str) -> None:
        """Lines that build an Array: a run of one little-endian FormatField by one
        ``struct`` call, any other item one by one in a loop; construct returns a list."""
        item = _format(c.subcon)
        if item is not None and not callable(c.count) and c.count >= 0:
            run = self.name(struct.Struct("<" + str(c.count) + item).pack)
            self.line(f"if len({value}) != {c.count}: raise _GiveUp")
            self.line(f"out.append({run}(*{value}))")
            self.line(f"{target} = list({value})")
            return
        n = self.temp()
        self.line(f"{n} = {self.expression(c.count)}")
        self.line(f"if not 0 <= {n} or len({value}) != {n}: raise _GiveUp")
        if item is not None:
            self.line(f'out.append(_pack("<" + str({n}) + {item!r}, *{value}))')
            self.line(f"{target} = list({value})")
            return
        items, e, r = self.temp(), self.temp(), self.temp()
        self.line(f"{items} = []")
        self.line(f"for {e} in {value}:")
        self.depth += 1
        self.field(c.subcon, e, r)
        self.line(f"{items}.append({r})")
        self.depth -= 1
        self.line(f"{target} = {items}")

    def builder(self, name: str) -> _Builder:
        return cast(_Builder, self.function(name, "<mpz.chunks._build>"))


@functools.cache
def _builder(grammar: construct.Construct) -> _Builder | None:
    """The generated builder of ``grammar`` (a Struct's own function; any other construct
    in a function of the caller's context), or None where it holds what is not written."""
    try:
        if type(grammar) is construct.Struct:
            return _struct(grammar)
        src = _Source(["def top(obj, out, ctx):", "    context = ctx"])
        src.field(grammar, "obj", "value")
        src.line("return value")
        return src.builder("top")
    except _Unsupported:
        return None


def fast_path(grammar: construct.Construct, obj: Any) -> bytes | None:
    """The payload of ``obj`` built by the compiled grammar, or None where the fast path
    gives up (an unsupported class, or a value it does not take as it is)."""
    b = _builder(grammar)
    if b is None:
        return None
    out: list[bytes] = []
    try:
        b(obj, out, _Context())
    except _GiveUp:
        return None
    except (construct.ConstructError, struct.error, TypeError, ValueError, KeyError,
            AttributeError, IndexError, OverflowError, UnicodeError):
        return None                     # construct raises its own error for these
    return b"".join(out)


def build(grammar: construct.Construct, obj: Any) -> bytes:
    """``grammar.build(obj)``: the same bytes, or construct's own error."""
    data = fast_path(grammar, obj)
    return data if data is not None else bytes(grammar.build(obj))
