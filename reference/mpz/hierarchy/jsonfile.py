"""The ``"file"`` builder: hierarchies written as ``mpz-hierarchy`` JSON.

Contract: :func:`parse_nodes` turns a parsed dict into nodes, checking the
format, the version, every node's fields, and that the names match the
motion's markers (exactly or after stripping a ``"Subject:"`` prefix); every
marker must be placed. It raises :class:`mpz.errors.EncoderError` naming the
node or marker at fault, for the first broken rule in node order, except that
unknown marker names are collected over all nodes and reported together.
:meth:`mpz.hierarchy.Hierarchy.from_dict` wraps it and validates the result;
:func:`read_hierarchy` and :func:`write_hierarchy` move it through files.
"""
from __future__ import annotations

from collections.abc import Sequence
import json
from pathlib import Path
from typing import Any

from mpz.errors import EncoderError
from mpz.hierarchy.model import MAX_WEIGHT, MIN_WEIGHT, Hierarchy, Node
from mpz.hierarchy.names import name_lookup

#: A path to a JSON file, as accepted by :func:`read_hierarchy`.
PathLike = str | Path


def parse_nodes(d: object, names: Sequence[str]) -> list[Node]:
    """The nodes of an ``mpz-hierarchy`` dict, marker names resolved to indices.

    Raises
    ------
    EncoderError
        For a malformed dict, unknown marker or node names, or markers of the
        motion the dict does not place.
    """
    raw = _node_list(d)
    lookup = name_lookup(names)
    node_index: dict[str, int] = {}
    nodes: list[Node] = []
    unknown: list[str] = []
    held: dict[str, str] = {}             # marker name -> the node that holds it
    for i, nd in enumerate(raw):
        name, members, ref, parent = _fields(i, nd)
        if name in node_index:
            raise EncoderError(f"duplicate node name {name!r}")
        node_index[name] = i
        # by name, where the checks of the built hierarchy can only give indices
        if i > 0 and parent is None:
            raise EncoderError(f"node {name!r} has no parent (null or missing): only the "
                               f"first node, {raw[0].get('name')!r}, is the root")
        for m in members:
            if m in held:
                raise EncoderError(f"marker {m!r} is listed twice in node {name!r}"
                                   if held[m] == name else
                                   f"marker {m!r} is in node {held[m]!r} and again in node "
                                   f"{name!r}")
            held[m] = name
        if ref not in members:
            raise EncoderError(f"node {name!r}: its ref {ref!r} is not one of its members")
        p = _parent_index(name, parent, node_index)
        idx, r = _marker_indices(members, ref, lookup, unknown)
        weights = _weights(name, members, nd.get("weights") or {})
        nodes.append(Node(name, p, r, idx, weights))
    if unknown:
        raise EncoderError(f"hierarchy names markers the motion does not have: {unknown}")
    placed = {m for n in nodes for m in n.members}
    missing = [names[i] for i in range(len(names)) if i not in placed]
    if missing:
        raise EncoderError(f"hierarchy does not place these markers of the motion: {missing}")
    return nodes


def _node_list(d: object) -> list[Any]:
    """The ``nodes`` list of a dict whose format and version are checked."""
    if not isinstance(d, dict) or d.get("format") != "mpz-hierarchy":
        raise EncoderError("not a hierarchy: expected a dict with "
                           "\"format\": \"mpz-hierarchy\"")
    version = d.get("version")
    if type(version) is not int or version != 1:      # not true, not 1.0
        raise EncoderError(f"unsupported hierarchy version {version!r}, expected 1")
    raw = d.get("nodes")
    if not isinstance(raw, list) or not raw:
        raise EncoderError("hierarchy \"nodes\" must be a non-empty list")
    return raw


#: the fields of a node: "why" and "description" are free text for people (cmu41.json's)
NODE_FIELDS = ("name", "parent", "ref", "members", "weights", "why", "description")


def _fields(i: int, nd: Any) -> tuple[str, list[str], str, str | None]:
    """``(name, members, ref, parent)`` of raw node ``i``, each of its JSON type: name and
    ref text, members a non-empty list of text, parent text or null (issue 11.6: a wrong
    type is an EncoderError naming the node and the field, never a TypeError)."""
    if not isinstance(nd, dict):
        raise EncoderError(f"hierarchy node {i} must be an object with name, members, ref and "
                           f"parent, got {type(nd).__name__}")
    missing = [k for k in ("name", "members", "ref") if k not in nd]
    if missing:
        raise EncoderError(f"hierarchy node {i}: missing field {', '.join(missing)}")
    # a field no reader reads: a misspelt "weigths" was ignored, and the weights with it
    # (an ML pipeline's QA run of the API)
    unknown = [k for k in nd if k not in NODE_FIELDS]
    if unknown:
        raise EncoderError(f"hierarchy node {i} ({nd['name']!r}): unknown field "
                           f"{', '.join(map(repr, unknown))}; a node has "
                           f"{', '.join(NODE_FIELDS)}")
    name, members, ref, parent = nd["name"], nd["members"], nd["ref"], nd.get("parent")
    if not isinstance(name, str) or not name:
        raise EncoderError(f"hierarchy node {i}: \"name\" must be non-empty text, got "
                           f"{name!r}")
    if (not isinstance(members, list) or not members
            or not all(isinstance(m, str) for m in members)):
        raise EncoderError(f"hierarchy node {i} ({name!r}): \"members\" must be a non-empty "
                           f"list of marker names, got {members!r}")
    if not isinstance(ref, str):
        raise EncoderError(f"hierarchy node {i} ({name!r}): \"ref\" must be a marker name, "
                           f"got {ref!r}")
    if parent is not None and not isinstance(parent, str):
        raise EncoderError(f"hierarchy node {i} ({name!r}): \"parent\" must be a node name "
                           f"or null, got {parent!r}")
    return name, list(members), ref, parent


def _parent_index(name: str, parent: str | None, node_index: dict[str, int]) -> int:
    """Index of the parent node (-1 for ``null``); it must come earlier."""
    if parent is None:
        return -1
    if parent in node_index:
        return node_index[parent]
    raise EncoderError(f"node {name!r}: parent {parent!r} is not an earlier node")


def _marker_indices(members: list[str], ref: str, lookup: dict[str, int],
                    unknown: list[str]) -> tuple[list[int], int]:
    """Member and reference indices (-1 where unknown); unknown names go to ``unknown``."""
    idx = []
    for m in members:
        j = lookup.get(str(m))
        if j is None:
            unknown.append(str(m))
        idx.append(-1 if j is None else j)
    r = lookup.get(str(ref))
    if r is None and str(ref) not in members:
        unknown.append(str(ref))
    return idx, -1 if r is None else r


def _weights(name: str, members: list[str], wmap: Any) -> list[float]:
    """One weight per member from the node's ``weights`` map (default 1.0): JSON numbers
    (not text, not true/false) from 1/16 to 16, the range HIER stores."""
    if not isinstance(wmap, dict):
        raise EncoderError(f"node {name!r}: \"weights\" must map marker names to numbers")
    bad = [k for k in wmap if k not in members]
    if bad:
        raise EncoderError(f"node {name!r}: weights given for non-members {bad}")
    weights = []
    for m in members:
        w = wmap.get(m, 1.0)
        if isinstance(w, bool) or not isinstance(w, (int, float)):
            raise EncoderError(f"node {name!r}: weight of {m!r} is not a number: {w!r}")
        if not MIN_WEIGHT <= w <= MAX_WEIGHT:          # NaN fails too
            raise EncoderError(f"node {name!r}: weight of {m!r} must be from 1/16 to 16 (what "
                               f"HIER holds, spec §4.3), got {w!r}")
        weights.append(float(w))
    return weights


def read_hierarchy(path: PathLike, names: Sequence[str]) -> Hierarchy:
    """Read a JSON hierarchy file against the motion's marker names."""
    try:                                  # utf-8-sig: a byte-order mark is still UTF-8
        d = json.loads(Path(path).read_text(encoding="utf-8-sig"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise EncoderError(f"cannot read hierarchy file: {exc}", path=str(path)) from None
    except RecursionError:                # 100,000 nested brackets: a traceback (exit 1)
        raise EncoderError("cannot read hierarchy file: JSON nested too deeply",
                           path=str(path)) from None
    return Hierarchy.from_dict(d, names)


def write_hierarchy(h: Hierarchy, path: PathLike, names: Sequence[str]) -> None:
    """Write ``h`` to the file ``path`` as an ``mpz-hierarchy`` JSON file, each marker by
    its name in ``names`` (the motion's marker names, which the hierarchy indexes)."""
    if not isinstance(h, Hierarchy):         # AttributeError of None (a QA run, stop 50)
        raise TypeError(f"expected an mpz Hierarchy, got {type(h).__name__}")
    Path(path).write_text(json.dumps(h.to_dict(names), indent=1) + "\n", encoding="utf-8")
