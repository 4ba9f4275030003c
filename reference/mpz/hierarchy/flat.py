"""The ``"flat"`` builder: marker 0 as the root, every other marker in one node.

Contract: depends on the marker count only, never fails for ``n_markers >= 1``
and gives the coder no structure to exploit; it is the fallback of
:func:`mpz.hierarchy.auto.auto_hierarchy` for a motion whose markers are gaps
throughout. The result is valid for ``n_markers`` markers.
"""
from __future__ import annotations

from mpz.hierarchy.model import Hierarchy, Node


def flat_hierarchy(n_markers: int) -> Hierarchy:
    """Marker 0 as the root, every other marker in one child node."""
    nodes = [Node("root", -1, 0, [0])]
    if n_markers > 1:
        nodes.append(Node("rest", 0, 1, list(range(1, n_markers))))
    return Hierarchy(nodes, "flat")
