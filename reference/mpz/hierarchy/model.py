"""The hierarchy data model: :class:`Node`, :class:`Hierarchy` and its invariants.

Contract: a :class:`Hierarchy` is a list of nodes in topological order. Node 0
is the root and holds exactly one marker, coded in absolute coordinates; every
other node's members are coded relative to the reference marker of its parent
node, so a parent always comes before its children. Every marker belongs to
exactly one node. :meth:`Hierarchy.validate` checks all of this and raises
:class:`mpz.errors.EncoderError` with the offending values. This module builds
no hierarchy itself; the builders live beside it and return this type.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
import math
from typing import Any

from mpz.errors import EncoderError
from mpz.format import MAX_MARKERS

#: the most nodes a hierarchy has: spec §4.1's node_count is 1 .. marker_count, and
#: marker_count is at most MAX_MARKERS (§8)
MAX_NODES = MAX_MARKERS
#: the marker weights HIER can hold: w = (c + 1) / 16 for the codes c = 0 .. 255 (spec
#: §4.3); the one range of ``EncodeOptions.weights`` and of a JSON hierarchy's weights
MIN_WEIGHT, MAX_WEIGHT = 1.0 / 16.0, 16.0


@dataclass
class Node:
    """One body part: markers coded relative to the parent node's reference.

    Attributes
    ----------
    name : str
    parent : int
        Index of the parent node; -1 for the root (node 0).
    ref : int
        Marker index of the reference marker; one of ``members``.
    members : list of int
        Marker indices of this node.
    weights : list of float
        One per member (paper §IV local distortion control), default 1.0.
    """

    name: str
    parent: int
    ref: int
    members: list[int]
    weights: list[float] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.members = [int(m) for m in self.members]
        if not self.weights:
            self.weights = [1.0] * len(self.members)
        self.weights = [float(w) for w in self.weights]


@dataclass
class Hierarchy:
    """Nodes in topological order plus the method that built them."""

    nodes: list[Node]
    method: str = "file"

    def validate(self, n_markers: int) -> None:
        """Check every structural invariant against ``n_markers`` markers.

        Raises
        ------
        EncoderError
            Naming the node and the value that breaks the rule.
        """
        _check_shape(self.nodes, n_markers)
        owner: dict[int, int] = {}
        for i, node in enumerate(self.nodes):
            _check_node(i, node, n_markers, owner)
        missing = sorted(set(range(n_markers)) - set(owner))
        if missing:
            raise EncoderError(f"markers {missing[:10]}{'...' if len(missing) > 10 else ''} "
                               f"are in no node")

    @property
    def levels(self) -> list[int]:
        """Depth of each node (root = 0)."""
        depth: list[int] = []
        for n in self.nodes:
            depth.append(0 if n.parent < 0 else depth[n.parent] + 1)
        return depth

    def to_dict(self, names: Sequence[str]) -> dict[str, Any]:
        """The JSON-ready ``mpz-hierarchy`` dict, markers given by name."""
        names = list(names)
        out = []
        for n in self.nodes:
            d: dict[str, Any] = {
                "name": n.name,
                "parent": None if n.parent < 0 else self.nodes[n.parent].name,
                "ref": names[n.ref],
                "members": [names[m] for m in n.members]}
            if any(w != 1.0 for w in n.weights):
                d["weights"] = {names[m]: w for m, w in zip(n.members, n.weights, strict=False)}
            out.append(d)
        return {"format": "mpz-hierarchy", "version": 1, "method": self.method, "nodes": out}

    @classmethod
    def from_dict(cls, d: object, names: Sequence[str], *, method: str = "file") -> Hierarchy:
        """Parse an ``mpz-hierarchy`` dict against the motion's marker names.

        The node-by-node parser is :func:`mpz.hierarchy.jsonfile.parse_nodes`;
        it is imported here, not at the top, because it builds :class:`Node`.

        Raises
        ------
        EncoderError
            For a malformed dict, unknown marker or node names, or markers of
            the motion the dict does not place.
        """
        from mpz.hierarchy.jsonfile import parse_nodes

        h = cls(parse_nodes(d, names), method)
        h.validate(len(names))
        return h


# -- the invariants, in the order they are checked ----------------------------------
def _check_shape(nodes: Sequence[Node], n_markers: int) -> None:
    """Node count, marker count and the root node."""
    if not nodes:
        raise EncoderError("a hierarchy needs at least one node, got 0")
    if len(nodes) > MAX_NODES:
        raise EncoderError(f"{len(nodes)} nodes, at most {MAX_NODES} allowed (spec §4.1: "
                           "node_count <= marker_count <= MAX_MARKERS)")
    if n_markers < 1:
        raise EncoderError(f"a hierarchy needs at least one marker, got {n_markers}")
    root = nodes[0]
    if root.parent != -1:
        raise EncoderError(f"node 0 ({root.name!r}) must be the root with parent -1, "
                           f"got {root.parent}")
    if len(root.members) != 1:
        raise EncoderError(f"the root node {root.name!r} must hold exactly one marker, "
                           f"got {len(root.members)}: {root.members}")


def _check_node(i: int, node: Node, n_markers: int, owner: dict[int, int]) -> None:
    """Parent, members, reference and weights of node ``i``; records its members in ``owner``."""
    if i > 0 and not 0 <= node.parent < i:
        raise EncoderError(f"node {i} ({node.name!r}) has parent {node.parent}; it must be "
                           f"an earlier node, 0 <= parent < {i}")
    if not node.members:
        raise EncoderError(f"node {i} ({node.name!r}) has no members")
    if len(node.weights) != len(node.members):
        raise EncoderError(f"node {i} ({node.name!r}) has {len(node.weights)} weights "
                           f"for {len(node.members)} members")
    _claim_members(i, node, n_markers, owner)
    if node.ref not in node.members:
        raise EncoderError(f"node {i} ({node.name!r}): reference marker {node.ref} "
                           f"is not one of its members {node.members}")
    for m, w in zip(node.members, node.weights, strict=True):
        if not (isinstance(w, (int, float)) and math.isfinite(w) and w > 0):
            raise EncoderError(f"node {i} ({node.name!r}): weight {w!r} of marker {m} "
                               f"must be positive and finite")


def _claim_members(i: int, node: Node, n_markers: int, owner: dict[int, int]) -> None:
    """Each member of node ``i`` is a marker index no earlier node holds; record it."""
    for m in node.members:
        if not 0 <= m < n_markers:
            raise EncoderError(f"node {i} ({node.name!r}) names marker {m}, "
                               f"outside 0..{n_markers - 1}")
        if m in owner:
            raise EncoderError(f"marker {m} is in node {owner[m]} and again in node {i} "
                               f"({node.name!r})")
        owner[m] = i
