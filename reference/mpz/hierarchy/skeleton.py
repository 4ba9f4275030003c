"""The ``"skeleton"`` builder: one node per point of a BVH/AMC skeleton.

Contract: for a motion with ``parents`` (BVH or AMC input), every point is its
own node, with itself as the only member and reference, parented like the
skeleton, in breadth-first order from the skeleton root (children in point
order). The first point with parent -1 is the root; other parentless points
become children of the root node, in point order (so would points in a cycle of
``parents``, which :class:`mpz.Motion` refuses since stop 50: kept as a defence).
A motion without ``parents`` raises :class:`mpz.errors.EncoderError`. The result
is not validated here.
"""
from __future__ import annotations

from collections.abc import Sequence

from mpz.errors import EncoderError
from mpz.hierarchy.model import Hierarchy, Node
from mpz.motion import Motion


def skeleton_hierarchy(motion: Motion) -> Hierarchy:
    """One node per skeleton point, parented like the skeleton, breadth first.

    The first point with parent -1 is the root; other parentless points become
    children of the root node (and points of a cycle, which Motion refuses).
    """
    parents = motion.parents
    if parents is None:
        raise EncoderError("the skeleton hierarchy needs motion.parents (BVH or AMC input)")
    order, parent_node = _breadth_first(parents)
    names = motion.names
    nodes = [Node(names[i], parent_node[i], i, [i]) for i in order]
    return Hierarchy(nodes, "skeleton")


def _breadth_first(parents: Sequence[int]) -> tuple[list[int], dict[int, int]]:
    """Points in node order, and point -> index of its parent node (-1 for the root)."""
    n = len(parents)
    root = next((i for i, p in enumerate(parents) if p < 0), 0)
    children = _children(parents, root)
    order, parent_node, seen = [root], {root: -1}, {root}
    head = 0
    while True:
        head = _visit(order, head, children, seen, parent_node)
        rest = [i for i in range(n) if i not in seen]
        if not rest:
            return order, parent_node
        # a parentless point or a cycle: hang it under the root node and go on from it
        r = next((i for i in rest if parents[i] < 0), rest[0])
        seen.add(r)
        parent_node[r] = 0
        order.append(r)


def _children(parents: Sequence[int], root: int) -> list[list[int]]:
    """Children of each point in point order (the root is no point's child)."""
    children: list[list[int]] = [[] for _ in range(len(parents))]
    for i, p in enumerate(parents):
        if p >= 0 and i != root:
            children[p].append(i)
    return children


def _visit(order: list[int], head: int, children: list[list[int]], seen: set[int],
           parent_node: dict[int, int]) -> int:
    """Breadth-first from ``order[head:]``, appending unseen children; the new head."""
    while head < len(order):
        i = order[head]
        head += 1
        for c in children[i]:
            if c not in seen:
                seen.add(c)
                parent_node[c] = head - 1
                order.append(c)
    return head
