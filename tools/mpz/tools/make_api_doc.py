"""Write docs/api.md, the Python API reference: ``python -m mpz.tools.make_api_doc``.

The reference collects what a library user calls, in this order: everything in
``mpz.__all__``; ``mpz.io``'s readers, writers and their tables; then the functions the
README and docs/*.md point to in other modules (:data:`ENTRIES`). Each entry is the
object's signature (``inspect.signature``; dataclass fields with their types and defaults)
and its docstring, verbatim: numpydoc section titles become bold lines and doctests become
code blocks, so that Markdown does not read ``----------`` as a heading or an indented
description as code; the words are not changed. The text of a constant or a dataclass
field is its ``#:`` comment, as Sphinx reads it.

The page depends on the sources only: defaults are shown by :func:`stable_repr` (no memory
addresses, sets sorted), and nothing of the Python version. tests/test_api_doc.py fails
when the page is stale, or misses a name of ``mpz.__all__`` or of the README's Python
example: run this command after changing a public signature or docstring. ``--check``
compares instead of writing (exit 1 when the page differs). A listed object without a
docstring, or a parameter its docstring never names, is printed as a warning on standard
error (the page is written all the same).
"""
from __future__ import annotations

import argparse
from collections.abc import Callable, Iterable
import dataclasses
import difflib
import enum
import functools
import importlib
import inspect
from pathlib import Path
import re
import sys
import types
import typing
from typing import Any

# tools/mpz/tools/make_api_doc.py -> the repository root is three folders up
DOC = Path(__file__).resolve().parents[3] / "docs" / "api.md"
COMMAND = "python -m mpz.tools.make_api_doc"
#: a dataclass whose fields are the keywords of a function: a field without a ``#:`` comment
#: of its own is described by that function's numpydoc Parameters entry
FIELDS_DESCRIBED_BY = {"mpz.EncodeOptions": "mpz.encode",
                       "mpz.encoder.EncodeKeywords": "mpz.encode"}
#: a signature longer than this is written one parameter a line
WIDTH = 92

#: (module, names or None for the module's ``__all__``), in the order of the page: mpz and
#: mpz.io by their ``__all__`` (every name they export: mpz.io's per-format readers and
#: writers were exported and not on the page, a QA run of the API at stop 54); the other
#: modules give the functions the README ("From Python", "Hierarchies") and docs/corpus.md
#: point library users to, and the type ``mpz.write_mpz``'s options are checked against.
ENTRIES: list[tuple[str, tuple[str, ...] | None]] = [
    ("mpz", None),
    ("mpz.io", None),
    ("mpz.skeleton", ("with_joint_positions",)),
    ("mpz.synth", ("generate",)),
    ("mpz.metrics", ("besides_markers",)),
    ("mpz.hierarchy", ("write_hierarchy",)),
    ("mpz.encoder", ("EncodeKeywords",)),
]

_SECTIONS = ("Parameters", "Other Parameters", "Returns", "Yields", "Receives", "Raises",
             "Warns", "Warnings", "Attributes", "Methods", "See Also", "Notes", "References",
             "Examples")
_ENTRY_SECTIONS = ("Parameters", "Other Parameters", "Returns", "Yields", "Receives",
                   "Raises", "Warns", "Attributes")
#: a line of prose between the entries of a section: words and a full stop, no " : "
_SENTENCE = re.compile(r"^(?!.* : )\S+ .*\.$")
_ROLE = re.compile(r":(?:py:)?(?:func|meth|class|data|attr|mod|exc|obj|const):`~?([^`]+)`")
_SIMPLE_TABLE = re.compile(r"^=+( +=+)+\s*$")


# ------------------------------------------------------------------ values --
def stable_repr(value: object) -> str:
    """``repr(value)`` without what changes between runs: functions, classes and modules
    by their qualified names, numpy scalars as Python numbers, sets sorted, and any other
    object whose repr holds a memory address as ``<TypeName>``."""
    if isinstance(value, enum.Enum):
        return f"{type(value).__qualname__}.{value.name}"
    if isinstance(value, (bool, int, float, complex, str, bytes, type(None))):
        return repr(value)
    if isinstance(value, types.ModuleType):
        return value.__name__
    if isinstance(value, (types.FunctionType, types.BuiltinFunctionType, type)):
        return f"{value.__module__}.{value.__qualname__}"
    if isinstance(value, functools.partial):
        return f"functools.partial({stable_repr(value.func)}, ...)"
    if hasattr(value, "dtype") and hasattr(value, "item") and getattr(value, "ndim", 1) == 0:
        return stable_repr(value.item())           # np.float64(1.0) (numpy 2) -> 1.0
    if isinstance(value, (set, frozenset)):
        items = sorted(stable_repr(v) for v in value)
        if not items:
            return f"{type(value).__name__}()"
        inner = "{" + ", ".join(items) + "}"
        return inner if type(value) is set else f"{type(value).__name__}({inner})"
    if isinstance(value, tuple):
        inner = ", ".join(stable_repr(v) for v in value)
        return f"({inner},)" if len(value) == 1 else f"({inner})"
    if isinstance(value, list):
        return "[" + ", ".join(stable_repr(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{stable_repr(k)}: {stable_repr(v)}"
                               for k, v in value.items()) + "}"
    text = repr(value)
    if " at 0x" in text or re.search(r"0x[0-9a-fA-F]{6,}", text):
        return f"<{type(value).__qualname__}>"
    return text


class _Shown:
    """A value whose repr is the given text (what inspect prints for a default or an
    annotation)."""

    def __init__(self, text: str) -> None:
        self.text = text

    def __repr__(self) -> str:
        return self.text


def _annotation(ann: object) -> str:
    if isinstance(ann, str):                 # ``from __future__ import annotations``
        return ann
    return inspect.formatannotation(ann)


def signature(name: str, obj: Callable[..., Any], *, skip_self: bool = False) -> str:
    """``name(params) -> return``, from ``inspect.signature``, annotations as written in
    the source and defaults by :func:`stable_repr`; one parameter a line when long. A
    class is shown as its constructor call, without ``-> None``."""
    try:
        sig = inspect.signature(obj)
    except (TypeError, ValueError):
        return f"{name}(...)"
    params: list[str] = []
    seen_kw_marker = False
    plist = list(sig.parameters.values())
    if skip_self and plist and plist[0].name in ("self", "cls"):
        plist = plist[1:]
    for i, p in enumerate(plist):
        if p.kind is p.KEYWORD_ONLY and not seen_kw_marker:
            params.append("*")
            seen_kw_marker = True
        if p.kind is p.VAR_POSITIONAL:
            seen_kw_marker = True
        stars = "*" if p.kind is p.VAR_POSITIONAL else "**" if p.kind is p.VAR_KEYWORD else ""
        text = stars + p.name
        if p.annotation is not p.empty:
            text += f": {_annotation(p.annotation)}"
        if p.default is not p.empty:
            d = stable_repr(p.default)
            text += f" = {d}" if p.annotation is not p.empty else f"={d}"
        params.append(text)
        if p.kind is p.POSITIONAL_ONLY and (i + 1 == len(plist)
                                            or plist[i + 1].kind is not p.POSITIONAL_ONLY):
            params.append("/")
    ret = ""
    if sig.return_annotation is not sig.empty and not inspect.isclass(obj):
        ret = f" -> {_annotation(sig.return_annotation)}"
    one = f"{name}({', '.join(params)}){ret}"
    if len(one) <= WIDTH:
        return one
    return f"{name}(\n" + "".join(f"    {p},\n" for p in params) + f"){ret}"


# -------------------------------------------------------------- docstrings --
def _own_doc(obj: object) -> str | None:
    """The docstring written for ``obj`` itself: not a dataclass's generated
    ``Name(fields)``, not one inherited from a base class or from ``object``."""
    doc = obj.__doc__ if not isinstance(obj, property) else (obj.fget.__doc__
                                                              if obj.fget else None)
    if not doc or not doc.strip():
        return None
    if inspect.isclass(obj):
        if dataclasses.is_dataclass(obj) and doc.startswith(obj.__name__ + "("):
            return None
        if any(doc == getattr(b, "__doc__", None) for b in obj.__mro__[1:]):
            return None
    return inspect.cleandoc(doc)


def _roles(text: str) -> str:
    """reStructuredText roles as code: :func:`~mpz.io.read` -> `mpz.io.read`."""
    return _ROLE.sub(r"`\1`", text)


def markdown(doc: str) -> str:
    """A numpydoc docstring as Markdown, its words unchanged: a section title with its
    dashes -> a bold line; a ``name : type`` entry of Parameters, Returns, Raises,
    Attributes... -> a list item with its description under it; ``>>>`` doctests and
    reStructuredText simple tables -> code blocks; roles such as :func:`x` -> `x`."""
    lines = doc.splitlines()
    out: list[str] = []
    section = ""
    i = 0
    while i < len(lines):
        line = lines[i]
        nxt = lines[i + 1] if i + 1 < len(lines) else ""
        stripped = line.strip()
        if (stripped in _SECTIONS and re.fullmatch(r"\s*-{3,}\s*", nxt)
                and len(nxt.strip()) >= len(stripped) - 1):
            section = stripped
            out += ["", f"**{stripped}**", ""]
            i += 2
            continue
        if _SIMPLE_TABLE.match(line):           # an rST simple table: three rules
            block, rules = [], 0
            while i < len(lines):
                block.append(lines[i])
                rules += bool(_SIMPLE_TABLE.match(lines[i]))
                i += 1
                if rules == 3:
                    break
            out += ["```", *block, "```"]
            continue
        if stripped.startswith(">>>"):
            block = []
            while i < len(lines) and lines[i].strip():
                block.append(lines[i])
                i += 1
            out += ["```pycon", *block, "```"]
            continue
        if (section in _ENTRY_SECTIONS and stripped and not line[:1].isspace()
                and not _SENTENCE.match(line)):
            name, sep, kind = line.partition(" : ")
            if sep:
                item = f"- `{name.strip()}` : {_roles(kind.strip())}"
            else:
                item = f"- `{stripped}`"
            out.append(item)
            i += 1
            while i < len(lines) and (lines[i][:1].isspace() or not lines[i].strip()):
                # the description: an indented continuation of the item; a blank line
                # followed by another entry (not indented) ends it
                if not lines[i].strip():
                    j = i
                    while j < len(lines) and not lines[j].strip():
                        j += 1
                    if j >= len(lines) or not lines[j][:1].isspace():
                        break
                    out.append("")
                else:
                    out.append("  " + _roles(lines[i].strip()))
                i += 1
            continue
        out.append(_roles(line))
        i += 1
    text = "\n".join(out).strip("\n")
    return re.sub(r"\n{3,}", "\n\n", text)


def numpydoc_parameters(doc: str) -> dict[str, str]:
    """{name: "type: description"} of the Parameters section of ``doc``, one line each
    (an entry ``a, b : float`` gives both names)."""
    out: dict[str, str] = {}
    lines = doc.splitlines()
    try:
        start = next(i for i, line in enumerate(lines[:-1])
                     if line.strip() == "Parameters" and set(lines[i + 1].strip()) == {"-"})
    except StopIteration:
        return out
    kinds: dict[str, str] = {}
    text: dict[str, list[str]] = {}
    names: list[str] = []
    for i in range(start + 2, len(lines)):
        line = lines[i]
        if i + 1 < len(lines) and re.fullmatch(r"\s*-{3,}\s*", lines[i + 1]):
            break                                   # the next section
        if line.strip() and not line[:1].isspace():
            head, _, kind = line.partition(" : ")
            names = [n.strip() for n in head.split(",")]
            for n in names:
                kinds[n], text[n] = kind.strip(), []
        elif line.strip():
            for n in names:
                text[n].append(line.strip())
    for n, kind in kinds.items():
        out[n] = f"{kind}: {' '.join(text[n])}" if text[n] else kind
    return out


def _doc_or_note(obj: object, what: str, warn: list[str]) -> str:
    doc = _own_doc(obj)
    if doc is None:
        warn.append(f"{what}: no docstring")
        return "*(no docstring)*"
    return markdown(doc)


def _words(doc: str | None) -> set[str]:
    return set(re.findall(r"[A-Za-z_]\w*", doc or ""))


def _check_params(name: str, obj: Callable[..., Any], doc: str | None,
                  warn: list[str], *, skip_self: bool = False,
                  notes: dict[str, str] | None = None) -> None:
    """Warn of each parameter of ``obj`` whose name its docstring never uses (nor, for a
    dataclass field, its ``#:`` comment: ``notes``). A ``**kwargs: Never`` takes no
    argument (it only makes a misspelt keyword an error of the function's own): it is not
    one to document."""
    if doc is None:
        return
    notes = notes or {}
    try:
        sig = inspect.signature(obj)
    except (TypeError, ValueError):
        return
    words = _words(doc)
    for i, p in enumerate(sig.parameters.values()):
        if skip_self and i == 0 and p.name in ("self", "cls"):
            continue
        if _annotation(p.annotation) in ("Never", "NoReturn", "typing.Never"):
            continue
        if p.name not in words and p.name not in notes:
            what = ("field {!r} is mentioned neither in the docstring nor in a #: comment"
                    if inspect.isclass(obj) else "parameter {!r} is not mentioned in the "
                    "docstring")
            warn.append(f"{name}: {what.format(p.name)}")


# ------------------------------------------------------------ #: comments --
@functools.cache
def _comments(module_name: str, class_name: str | None = None) -> dict[str, str]:
    """{name: its ``#:`` comment} for the assignments of a module (or the fields of one of
    its classes) that have one on the lines just above them."""
    module = importlib.import_module(module_name)
    try:
        source = inspect.getsource(getattr(module, class_name) if class_name else module)
    except (OSError, TypeError):
        return {}
    lines = source.splitlines()
    indent = None
    out: dict[str, str] = {}
    pending: list[str] = []
    for line in lines:
        s = line.strip()
        lead = len(line) - len(line.lstrip())
        if class_name and indent is None and s and not s.startswith(("class ", "@")):
            indent = lead
        level = indent if class_name else 0
        if s.startswith("#:") and lead == level:
            pending.append(s[2:].strip())
            continue
        m = re.match(r"(\w+)\s*(?::[^=]*)?=|(\w+)\s*:", s)
        if m and lead == level and pending:
            out[m.group(1) or m.group(2)] = " ".join(pending)
        if s or not pending:
            pending = []
    return out


# ----------------------------------------------------------------- entries --
def _is_exception(obj: object) -> bool:
    return inspect.isclass(obj) and issubclass(obj, BaseException)


def _bases(cls: type) -> str:
    names = []
    for b in cls.__bases__:
        names.append(b.__qualname__ if b.__module__ == "builtins"
                     else f"{_public_module(b)}.{b.__qualname__}")
    return ", ".join(f"`{n}`" for n in names)


def _public_module(obj: Any) -> str:
    """``mpz`` for what ``mpz`` re-exports under the same name, else the defining module."""
    import mpz
    if getattr(mpz, obj.__name__, None) is obj:
        return "mpz"
    return str(obj.__module__)


def _members(cls: type) -> list[tuple[str, Any]]:
    """The public methods and properties ``cls`` defines (or inherits from a class of
    this package), in the order of the source; not dataclass fields."""
    fields = {f.name for f in dataclasses.fields(cls)} if dataclasses.is_dataclass(cls) else set()
    seen: dict[str, Any] = {}
    for klass in reversed(cls.__mro__):
        if klass.__module__ == "builtins":
            continue
        for k, v in vars(klass).items():
            if k.startswith("_") or k in fields:
                continue
            if isinstance(v, (property, staticmethod, classmethod)) or inspect.isfunction(v):
                seen.pop(k, None)
                seen[k] = v
    return list(seen.items())


def _entry_typeddict(qual: str, cls: type, warn: list[str]) -> list[str]:
    """A TypedDict: its keys, each with its type and the default of the function it types
    (:data:`FIELDS_DESCRIBED_BY`), which describes them."""
    described = FIELDS_DESCRIBED_BY.get(qual)
    head = "*TypedDict*" + ("" if getattr(cls, "__total__", True) else "; every key optional")
    out = [f"### `{qual}`", "", head, "", _doc_or_note(cls, qual, warn), ""]
    params = inspect.signature(_resolve(described)).parameters if described else {}
    if described:
        out += [f"Each key is described under `{described}`.", ""]
    out += ["| key | type | default |", "|---|---|---|"]
    for key, ann in cls.__annotations__.items():
        p = params.get(key)
        default = ("" if p is None or p.default is inspect.Parameter.empty
                   else f"`{stable_repr(p.default)}`".replace("|", "\\|"))
        text = ann.__forward_arg__ if isinstance(ann, typing.ForwardRef) else _annotation(ann)
        cell = text.replace("|", "\\|")
        out.append(f"| `{key}` | `{cell}` | {default} |")
    out.append("")
    return out


def _entry_class(qual: str, cls: type, warn: list[str]) -> list[str]:
    if typing.is_typeddict(cls):
        return _entry_typeddict(qual, cls, warn)
    kind = "exception" if _is_exception(cls) else "class"
    out = [f"### `{qual}`", ""]
    bases = [b for b in cls.__bases__ if b is not object]
    head = f"*{kind}*"
    if bases:
        head += f"; bases: {_bases(cls)}"
    if _is_exception(cls):
        chain = [c for c in cls.__mro__[1:] if c not in (BaseException, object)]
        head += "; hierarchy: " + " → ".join(
            f"`{c.__qualname__}`" for c in [cls, *chain])
    out += [head, ""]
    if "__init__" in vars(cls) or dataclasses.is_dataclass(cls) or not _is_exception(cls):
        out += ["```python", signature(qual, cls), "```", ""]
    out += [_doc_or_note(cls, qual, warn), ""]
    init = vars(cls).get("__init__")
    doc = _own_doc(cls)
    if dataclasses.is_dataclass(cls):
        notes = _comments(cls.__module__, cls.__qualname__)
        _check_params(qual, cls, doc, warn, notes=notes)
        described = FIELDS_DESCRIBED_BY.get(qual)
        if described:
            fn = _resolve(described)
            from_fn = numpydoc_parameters(inspect.getdoc(fn) or "")
            notes = {**{k: f"{v} (`{described}`)" for k, v in from_fn.items()}, **notes}
        out += ["| field | type | default | note |", "|---|---|---|---|"]
        for f in dataclasses.fields(cls):
            if f.default is not dataclasses.MISSING:
                default = f"`{stable_repr(f.default)}`"
            elif f.default_factory is not dataclasses.MISSING:
                default = f"`{stable_repr(f.default_factory())}`"
            else:
                default = "required"
            cell = _annotation(f.type).replace("|", "\\|")
            note = _roles(notes.get(f.name, "")).replace("|", "\\|")
            default = default.replace("|", "\\|")
            out.append(f"| `{f.name}` | `{cell}` | {default} | {note} |")
        out.append("")
    elif init is not None and inspect.isfunction(init):
        _check_params(qual, init, doc, warn, skip_self=True)
    for name, member in _members(cls):
        mqual = f"{qual}.{name}"
        if isinstance(member, property):
            ret = ""
            if member.fget is not None:
                ann = inspect.signature(member.fget).return_annotation
                if ann is not inspect.Signature.empty:
                    ret = f": {_annotation(ann)}"
            out += [f"#### `{mqual}`", "", f"*property*{ret and f' `{ret[2:]}`'}", ""]
            out += [_doc_or_note(member, mqual, warn), ""]
            continue
        func = member.__func__ if isinstance(member, (staticmethod, classmethod)) else member
        label = {staticmethod: "*staticmethod*", classmethod: "*classmethod*"}.get(
            type(member), "*method*")
        out += [f"#### `{mqual}`", "", label, "",
                "```python", signature(mqual, func,
                                       skip_self=not isinstance(member, staticmethod)),
                "```", ""]
        out += [_doc_or_note(func, mqual, warn), ""]
        _check_params(mqual, func, _own_doc(func), warn,
                      skip_self=not isinstance(member, staticmethod))
    return out


def _entry_function(qual: str, fn: Callable[..., Any], warn: list[str]) -> list[str]:
    out = [f"### `{qual}`", "", "```python", signature(qual, fn), "```", ""]
    out += [_doc_or_note(fn, qual, warn), ""]
    _check_params(qual, fn, _own_doc(fn), warn)
    return out


def _entry_data(qual: str, module: str, name: str, value: object,
                warn: list[str]) -> list[str]:
    note = _comments(module).get(name)
    out = [f"### `{qual}`", "", f"*{type(value).__name__}*", ""]
    shown = stable_repr(value)
    if isinstance(value, dict) and len(shown) > WIDTH:
        shown = "{\n" + "".join(f"    {stable_repr(k)}: {stable_repr(v)},\n"
                                for k, v in value.items()) + "}"
    out += ["```python", f"{qual} = {shown}", "```", ""]
    if note is None:
        warn.append(f"{qual}: no docstring (no #: comment above its assignment)")
        out += ["*(no docstring)*", ""]
    else:
        out += [_roles(note), ""]
    return out


def _exception_tree(module: str, classes: Iterable[type]) -> list[str]:
    """The package's exceptions as an indented list, each under its first base of the
    package (the other bases named after it)."""
    classes = [c for c in classes if _is_exception(c)]
    inside = set(classes)

    def parent(c: type) -> type | None:
        return next((b for b in c.__bases__ if b in inside), None)

    out: list[str] = []

    def walk(node: type | None, depth: int) -> None:
        for c in classes:
            if parent(c) is node:
                others = [b.__qualname__ for b in c.__bases__ if b is not parent(c)]
                also = f" (also `{'`, `'.join(others)}`)" if others else ""
                out.append(f"{'  ' * depth}- [`{module}.{c.__qualname__}`]"
                           f"(#{_anchor(f'{module}.{c.__qualname__}')}){also}")
                walk(c, depth + 1)

    walk(None, 0)
    return out


def _anchor(qual: str) -> str:
    """The anchor GitHub gives the heading ``### `qual` ``."""
    return re.sub(r"[^\w\- ]", "", qual.lower()).replace(" ", "-")


def _resolve(qual: str) -> Any:
    module, _, name = qual.rpartition(".")
    return getattr(importlib.import_module(module), name)


def entries() -> list[tuple[str, str, Any]]:
    """(module, name, object) of every entry of the page, in order."""
    out: list[tuple[str, str, Any]] = []
    for module_name, names in ENTRIES:
        module = importlib.import_module(module_name)
        for name in names if names is not None else module.__all__:
            out.append((module_name, name, getattr(module, name)))
    return out


def render_with_warnings() -> tuple[str, list[str]]:
    """The page, and the warnings (missing docstrings, parameters never mentioned)."""
    warn: list[str] = []
    parts = ["# Python API reference", "",
             "What a library user calls, with its signature and its docstring. Written by "
             f"`{COMMAND}` from the docstrings and signatures; do not edit by hand. "
             "The README's [From Python](../README.md#quick-start) section is the tour; "
             "the command-line tools are in [cli.md](cli.md).", ""]
    listing = entries()
    toc: list[str] = []
    for module_name, _ in ENTRIES:
        links = [f"[`{n}`](#{_anchor(f'{m}.{n}')})" for m, n, o in listing
                 if m == module_name and not isinstance(o, types.ModuleType)]
        toc.append(f"- [`{module_name}`](#{_anchor(module_name)}): {', '.join(links)}")
    parts += ["Contents:", "", *toc, ""]
    for module_name, names in ENTRIES:
        module = importlib.import_module(module_name)
        parts += [f"## `{module_name}`", ""]
        if names is None:                  # the package itself: its docstring and __all__
            parts += [_doc_or_note(module, module_name, warn), ""]
            tree = _exception_tree(module_name, [getattr(module, n) for n in module.__all__
                                                 if inspect.isclass(getattr(module, n))])
            if tree:
                parts += ["The exceptions, each under its base class:",
                          "", *tree, ""]
        elif module_name == "mpz.io":      # the section mpz.__all__ points to
            parts += [_doc_or_note(module, module_name, warn), ""]
        for m, name, obj in listing:
            if m != module_name:
                continue
            qual = f"{module_name}.{name}"
            if isinstance(obj, types.ModuleType):
                parts += [f"### `{qual}`", "",
                          f"*module*: see [`{obj.__name__}`](#{_anchor(obj.__name__)}) below.",
                          ""]
            elif inspect.isclass(obj):
                parts += _entry_class(qual, obj, warn)
            elif callable(obj):
                parts += _entry_function(qual, obj, warn)
            else:
                parts += _entry_data(qual, module_name, name, obj, warn)
    text = "\n".join(parts).rstrip("\n") + "\n"
    return re.sub(r"\n{3,}", "\n\n", text), warn


def render() -> str:
    """The text of docs/api.md."""
    return render_with_warnings()[0]


def _diff_summary(old: str, new: str, name: str, limit: int = 40) -> str:
    diff = list(difflib.unified_diff(old.splitlines(), new.splitlines(),
                                     f"{name} (on disk)", f"{name} (generated)", lineterm="",
                                     n=1))
    plus = sum(1 for d in diff if d.startswith("+") and not d.startswith("+++"))
    minus = sum(1 for d in diff if d.startswith("-") and not d.startswith("---"))
    shown = diff[:limit]
    more = f"\n... {len(diff) - limit} more diff lines" if len(diff) > limit else ""
    return (f"{name} is stale: {minus} lines would go, {plus} would come; run {COMMAND}\n"
            + "\n".join(shown) + more)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog=COMMAND, description=(__doc__ or "").splitlines()[0])
    p.add_argument("--out", type=Path, default=DOC, help=f"default: {DOC}")
    p.add_argument("--check", action="store_true",
                   help="write nothing; exit 1 with a diff summary when --out differs from "
                        "what would be written")
    args = p.parse_args(argv)
    if not args.out.parent.is_dir():      # installed from a wheel: a traceback (a QA run)
        p.error(f"{args.out.parent}: no such folder: run this in a clone of the repository "
                "(its docs/), or give --out")
    from mpz.tools._cli import printable
    text, warnings = render_with_warnings()
    for w in warnings:
        print(f"warning: {printable(w)}", file=sys.stderr)
    if warnings:
        print(f"{len(warnings)} warnings: a listed object without a docstring, or a "
              "parameter its docstring does not name", file=sys.stderr)
    shown = printable(str(args.out))
    if args.check:
        try:
            old = args.out.read_text(encoding="utf-8")
        except OSError as e:
            print(f"{shown}: cannot read ({e.strerror}); run {COMMAND}", file=sys.stderr)
            return 1
        if old != text:
            print(_diff_summary(old, text, shown))
            return 1
        print(f"{shown} is up to date")
        return 0
    args.out.write_text(text, encoding="utf-8")
    print(f"wrote {shown}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
