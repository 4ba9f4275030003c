"""The ``"cmu41"`` builder: the built-in hierarchy of the CMU/Vicon 41-marker set.

Contract: the body-part table is data, ``mpz/data/cmu41.json`` (each node's
choice is explained there by a ``"why"``); this module only fits that table to
the markers a motion has. :func:`cmu41_match` recognises the set (names
compared after stripping a ``"Subject:"`` prefix; at most
:data:`CMU41_MAX_MISSING` missing, none twice). :func:`cmu41_hierarchy` fits
the table, in four steps that each do one thing: place the present markers,
drop emptied nodes, replace missing references, place extra markers. The
result is validated; a motion that is not a CMU set raises
:class:`mpz.errors.EncoderError`.
"""
from __future__ import annotations

from collections.abc import Sequence
from importlib import resources
import json
import math
from typing import Any

import numpy as np

from mpz.errors import EncoderError
from mpz.hierarchy.measure import mean_distance, sample_frames
from mpz.hierarchy.model import Hierarchy, Node
from mpz.hierarchy.names import strip_subject
from mpz.motion import Motion

CMU41_MAX_MISSING = 4
#: frames sampled for the distances that place references and extra markers
_FRAMES = 2000


def cmu41_template() -> dict[str, Any]:
    """The built-in CMU 41-marker hierarchy (``data/cmu41.json``) as a dict."""
    text = (resources.files("mpz") / "data" / "cmu41.json").read_text(encoding="utf-8")
    tpl: dict[str, Any] = json.loads(text)
    return tpl


#: The 41 marker names, in the template's node order.
CMU41 = tuple(m for n in cmu41_template()["nodes"] for m in n["members"])
#: The template's root candidates, first present first (its ``root_fallback``).
_ROOTS = tuple(cmu41_template()["root_fallback"])


def cmu41_match(names: Sequence[str]) -> dict[str, int] | None:
    """Stripped name -> index for the CMU markers, or None if not a CMU set."""
    stripped = [strip_subject(n) for n in names]
    idx: dict[str, int] = {}
    for i, s in enumerate(stripped):
        if s in CMU41:
            if s in idx:
                return None  # two subjects or duplicated labels: not one CMU figure
            idx[s] = i
    if len(CMU41) - len(idx) > CMU41_MAX_MISSING:
        return None
    return idx


def cmu41_hierarchy(motion: Motion) -> Hierarchy:
    """The built-in CMU 41-marker hierarchy fitted to ``motion``'s markers.

    Missing markers (at most 4) leave their node; an emptied node is removed
    and its children move to its parent; a missing reference is replaced by
    the member nearest on average to the children's references (or the first
    member of a leaf); a missing root marker is replaced by the first present
    marker of ``root_fallback``. Extra markers join the non-root node whose
    reference marker is nearest on average over the motion (the
    ``extra_fallback`` node when they share no valid frame with any).
    """
    names = list(motion.names)
    idx = _matched(names)
    tpl = cmu41_template()
    frames = sample_frames(motion.n_frames, _FRAMES)
    nodes = _present_nodes(tpl, idx)
    _replace_missing_refs(nodes, motion, frames)
    _place_extras(nodes, len(names), tpl["extra_fallback"], motion, frames)
    for n in nodes:
        n.weights = [1.0] * len(n.members)
    h = Hierarchy(nodes, "cmu41")
    h.validate(len(names))
    return h


def cmu41_root(motion: Motion) -> int:
    """The root marker of :func:`cmu41_hierarchy` (its node 0), with the same errors: the
    first present marker of the template's ``root_fallback``, which is all the node 0 of
    :func:`_present_nodes` holds and which no later step changes. The encoder's default
    mode keeps only the root (issue 15.1: on HDM_mm the rest of the tree, each extra
    marker's mean distance to each node, took 14 ms of measurements made to be dropped)."""
    return _first_present(_ROOTS, _matched(list(motion.names)))


def _matched(names: list[str]) -> dict[str, int]:
    """:func:`cmu41_match` of ``names``, or the EncoderError saying why they are not one
    CMU 41-marker set."""
    idx = cmu41_match(names)
    if idx is not None:
        return idx
    stripped = [strip_subject(n) for n in names]
    twice = sorted({s for s in stripped if s in CMU41 and stripped.count(s) > 1})
    if twice:       # two subjects, or a label repeated: not one CMU figure
        raise EncoderError(f"the motion is not one CMU 41-marker set: "
                           f"{', '.join(twice[:6])}{' ...' if len(twice) > 6 else ''} "
                           "appear more than once (two subjects?); give each its own "
                           "file, or a hierarchy that names every marker")
    raise EncoderError(f"the motion is not a CMU 41-marker set: missing "
                       f"{sorted(set(CMU41) - set(stripped))}")


def _present_nodes(tpl: dict[str, Any], idx: dict[str, int]) -> list[Node]:
    """The template's nodes holding present markers, emptied ones dropped.

    The root holds the first present marker of ``root_fallback`` (and no
    other node does). A node whose markers are all missing is dropped and its
    children move to its nearest kept ancestor. A node whose reference is
    missing gets ref -1, for :func:`_replace_missing_refs`.
    """
    root = _first_present(tpl["root_fallback"], idx)
    tnodes = tpl["nodes"]
    parent = _template_parents(tnodes)
    members = [[root]] + [_present(n["members"], idx, root) for n in tnodes[1:]]
    keep = [i for i in range(len(tnodes)) if members[i]]
    newpos = {old: new for new, old in enumerate(keep)}
    nodes = []
    for i in keep:
        p = _kept_ancestor(parent, members, i)
        ref = root if i == 0 else idx.get(tnodes[i]["ref"], -1)
        nodes.append(Node(tnodes[i]["name"], -1 if p is None else newpos[p],
                          ref if ref in members[i] else -1, list(members[i])))
    return nodes


def _first_present(fallback: Sequence[str], idx: dict[str, int]) -> int:
    """Index of the first present marker of the template's ``root_fallback`` list."""
    for name in fallback:
        if name in idx:
            return idx[name]
    raise EncoderError("no CMU root marker (C7, T10, CLAV, STRN, RBAC) is present")


def _template_parents(tnodes: list[dict[str, Any]]) -> list[int | None]:
    """Index of each template node's parent node (None for the root)."""
    tindex = {n["name"]: i for i, n in enumerate(tnodes)}
    return [None if n["parent"] is None else tindex[n["parent"]] for n in tnodes]


def _present(names: list[str], idx: dict[str, int], root: int) -> list[int]:
    """Indices of the present markers among ``names``, the root marker left out."""
    return [idx[m] for m in names if m in idx and idx[m] != root]


def _kept_ancestor(parent: list[int | None], members: list[list[int]], i: int) -> int | None:
    """Nearest ancestor of template node ``i`` that kept a marker (None for the root)."""
    p = parent[i]
    while p is not None and not members[p]:
        p = parent[p]
    return p


def _replace_missing_refs(nodes: list[Node], motion: Motion, frames: np.ndarray) -> None:
    """Give every node without a reference one, in node order (in place).

    The member nearest on average to the references of the children that
    have one; a leaf's first member.
    """
    for k, n in enumerate(nodes):
        if n.ref in n.members:
            continue
        kids = [c.ref for c in nodes if c.parent == k and c.ref in c.members]
        if kids:
            n.ref = min(n.members, key=lambda m: np.mean(
                [mean_distance(motion, m, c, frames) for c in kids]))
        else:
            n.ref = n.members[0]


def _place_extras(nodes: list[Node], n_markers: int, fallback_name: str, motion: Motion,
                  frames: np.ndarray) -> None:
    """Add every marker no node holds to the nearest non-root node (in place).

    Nearest: least mean distance to the node's reference marker; the
    ``fallback_name`` node (else node 1) when no distance is finite.
    """
    placed = {m for n in nodes for m in n.members}
    extras = [i for i in range(n_markers) if i not in placed]
    if not extras:
        return
    fallback = _fallback_node(nodes, fallback_name, extras[0])
    for e in extras:
        best, best_d = fallback, math.inf
        for k, n in enumerate(nodes[1:], start=1):
            d = mean_distance(motion, e, n.ref, frames)
            if d < best_d:
                best, best_d = k, d
        nodes[best].members.append(e)


def _fallback_node(nodes: list[Node], name: str, first_extra: int) -> int:
    """The node named ``name``, else node 1, else a new ``"extra"`` node under the root."""
    k = next((k for k, n in enumerate(nodes) if n.name == name), None)
    if k is not None:
        return k
    if len(nodes) > 1:
        return 1
    # only the root survived; cannot happen with <= 4 missing
    nodes.append(Node("extra", 0, first_extra, []))
    return len(nodes) - 1
