"""The body-part hierarchy the codec codes markers in (paper §III-A, Fig. 3).

Contract: :func:`build_hierarchy` returns a :class:`Hierarchy` validated
against the motion: a list of nodes in topological order; node 0 is the root
and holds exactly one marker, coded in absolute coordinates; every other
node's members are coded relative to the reference marker of its parent node;
every marker belongs to exactly one node. It raises
:class:`mpz.errors.EncoderError` for an unknown spec, a file that does not fit
the motion, or bad weights. :func:`head_scale` gives the ADDH every threshold
is relative to. Equal inputs give equal hierarchies, so encoded files do not
depend on the machine.

Builders, one module each (:func:`build_hierarchy` dispatches by name):

``"cmu41"`` (:mod:`.cmu41`)
    The built-in hierarchy for the CMU/Vicon 41-marker set in
    ``data/cmu41.json`` (each choice is explained there by a ``"why"``).
    Up to 4 of the 41 markers may be missing; extra markers join the non-root
    node whose reference marker is nearest on average over the motion.
``"file"`` (:mod:`.jsonfile`)
    A JSON hierarchy (a path, or an already-parsed dict)::

        {"format": "mpz-hierarchy", "version": 1,
         "nodes": [{"name": "root", "parent": null, "ref": "C7", "members": ["C7"]},
                   {"name": "head", "parent": "root", "ref": "LFHD",
                    "members": ["LFHD", "RFHD", "LBHD", "RBHD"],
                    "weights": {"LFHD": 2.0}}, ...]}

    ``parent`` is a node name (``null`` for the root, which must come first),
    ``weights`` is optional (default 1.0). A motion's marker names match the file's
    exactly or after stripping their ``"Subject:"`` prefix (everything up to the last
    ``:``); the file's names are taken as written. Every marker of the motion must be
    listed once, every listed name must exist, and each ``ref`` is one of its node's
    members. The file is UTF-8 (a byte-order mark is allowed).
``"skeleton"`` (:mod:`.skeleton`)
    For BVH/AMC input (``motion.parents``): one node per point, parented like
    the skeleton, in breadth-first order from the skeleton root.
``"auto"`` (:mod:`.auto`)
    Groups of markers that move rigidly together, linked into a tree (the
    paper's future work; see :func:`auto_hierarchy`).
``"flat"`` (:mod:`.flat`)
    Marker 0 as the root and one child node with every other marker.

The data model and its invariants are in :mod:`.model`, name matching in
:mod:`.names`, distances and sizes in :mod:`.measure`; every public name of
those modules is importable from here.

Departure from the paper: the paper builds the hierarchy by hand from the
first frame; here it is built from names (cmu41), a file, the skeleton or the
data, so that every input file can be coded.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from mpz.errors import EncoderError
from mpz.hierarchy.auto import (
    AUTO_MAX_FRAMES,
    AUTO_MAX_GROUP,
    AUTO_RIGID_FRACTION,
    AUTO_SPREAD,
    auto_hierarchy,
    auto_root,
)
from mpz.hierarchy.cmu41 import (
    CMU41,
    CMU41_MAX_MISSING,
    cmu41_hierarchy,
    cmu41_match,
    cmu41_root,
    cmu41_template,
)
from mpz.hierarchy.flat import flat_hierarchy
from mpz.hierarchy.jsonfile import read_hierarchy, write_hierarchy
from mpz.hierarchy.measure import body_size, sample_frames, sampled
from mpz.hierarchy.model import MAX_NODES, Hierarchy, Node
from mpz.hierarchy.names import name_lookup, strip_subject
from mpz.hierarchy.skeleton import skeleton_hierarchy
from mpz.motion import Motion

__all__ = [
    "AUTO_MAX_FRAMES", "AUTO_MAX_GROUP", "AUTO_RIGID_FRACTION", "AUTO_SPREAD", "CMU41",
    "CMU41_MAX_MISSING", "HEAD_FRAMES", "MAX_NODES", "METHODS", "Hierarchy", "Node",
    "apply_weights", "auto_hierarchy", "body_size", "build_hierarchy", "cmu41_hierarchy",
    "cmu41_template", "flat_hierarchy", "head_scale", "read_hierarchy", "root_marker",
    "skeleton_hierarchy", "strip_subject", "write_hierarchy",
]

METHODS = ("cmu41", "file", "skeleton", "auto", "flat")
HEAD_FRAMES = 200      # paper §V: ADDH over the first ~200 frames
#: the CMU head markers whose diagonals give the ADDH, in the order LF, RF, LB, RB
HEAD_MARKERS = ("LFHD", "RFHD", "LBHD", "RBHD")

#: The builders chosen by name (``"file"`` is a path or a dict instead).
BUILDERS: dict[str, Callable[[Motion], Hierarchy]] = {
    "cmu41": cmu41_hierarchy,
    "skeleton": skeleton_hierarchy,
    "auto": auto_hierarchy,
    "flat": lambda motion: flat_hierarchy(motion.n_markers),
}

#: What :func:`build_hierarchy` accepts as ``spec``.
Spec = str | Path | dict[str, Any] | None


# -- builders ------------------------------------------------------------------
def build_hierarchy(motion: Motion, spec: Spec = None, *,
                    weights: Mapping[str, float] | None = None) -> Hierarchy:
    """Build and validate the coding hierarchy of ``motion``.

    Parameters
    ----------
    motion : Motion
    spec : None, str, path or dict
        ``"cmu41"``, ``"skeleton"``, ``"auto"``, ``"flat"``, a path to a JSON
        hierarchy file or its parsed dict. None chooses: ``"cmu41"`` when the
        names (prefix stripped) hold at least 37 of the CMU 41 markers, else
        ``"skeleton"`` when ``motion.parents`` is set, else ``"auto"``.
    weights : dict, optional
        Marker name (or node name, for all its members) -> weight, applied
        after the structure is built; marker names win over node names.

    Returns
    -------
    Hierarchy
        Validated against ``motion.n_markers``.

    Raises
    ------
    EncoderError
        For an unknown spec, a file that does not fit the motion, or bad
        weights.

    Examples
    --------
    >>> from mpz.synth import generate
    >>> h = build_hierarchy(generate("walk", frames=30))
    >>> h.method, len(h.nodes), h.nodes[0].name
    ('cmu41', 17, 'root')
    """
    names = list(motion.names)
    if spec is None:
        spec = _default_spec(motion, names)
    h = _build(motion, names, spec)
    if weights:
        apply_weights(h, names, weights)
    h.validate(motion.n_markers)
    return h


def root_marker(motion: Motion, spec: Spec = None, *,
                weights: Mapping[str, float] | None = None) -> int:
    """The root marker of ``build_hierarchy(motion, spec, weights=weights)`` (its node 0),
    with the same errors; the ``"auto"`` and ``"cmu41"`` builders' trees, which the root
    does not depend on, are not built (:func:`~mpz.hierarchy.auto.auto_root`,
    :func:`~mpz.hierarchy.cmu41.cmu41_root`; issue 15)."""
    names = list(motion.names)
    if spec is None:
        spec = _default_spec(motion, names)
    if not weights:                        # weights may name the tree's nodes: build it
        if spec == "auto":
            return auto_root(motion)
        if spec == "cmu41":
            return cmu41_root(motion)
    return build_hierarchy(motion, spec, weights=weights).nodes[0].members[0]


def _default_spec(motion: Motion, names: Sequence[str]) -> str:
    """``"cmu41"`` for a CMU marker set, else ``"skeleton"`` when there is one, else ``"auto"``."""
    if cmu41_match(names) is not None:
        return "cmu41"
    if motion.parents is not None:
        return "skeleton"
    return "auto"


def _build(motion: Motion, names: Sequence[str], spec: str | Path | dict[str, Any]) -> Hierarchy:
    """The hierarchy ``spec`` names: a dict, a builder's name or a JSON file path."""
    if isinstance(spec, dict):
        return Hierarchy.from_dict(spec, names)
    if isinstance(spec, str) and spec in BUILDERS:
        return BUILDERS[spec](motion)
    if isinstance(spec, (str, Path)) and spec != "file" and Path(spec).is_file():
        return read_hierarchy(spec, names)
    if isinstance(spec, (str, Path)) and Path(spec).is_dir():
        raise EncoderError(f"hierarchy {str(spec)!r} is a folder, not a JSON file")
    if isinstance(spec, (str, Path)) and spec != "file" and Path(spec).exists():
        # a FIFO or a device was "does not exist" (a QA run of stop 50)
        raise EncoderError(f"hierarchy {str(spec)!r} is not a regular file (a FIFO, a "
                           "device or a socket), not a JSON file")
    if isinstance(spec, Path) or (isinstance(spec, str) and (
            spec.lower().endswith(".json") or os.sep in spec or "/" in spec)):
        # a path that is not there was "unknown hierarchy ...: expected one of [...]"
        raise EncoderError(f"hierarchy file {str(spec)!r} does not exist")
    raise EncoderError(f"unknown hierarchy {spec!r}: expected one of "
                       f"{[m for m in METHODS if m != 'file']}, a dict or a JSON file path")


def apply_weights(h: Hierarchy, names: Sequence[str], weights: Mapping[str, float]) -> None:
    """Set per-marker weights from marker or node names (in place)."""
    lookup = name_lookup(names)
    by_node = {n.name: i for i, n in enumerate(h.nodes)}
    _check_weights(weights, lookup, by_node)
    # node names first, then marker names override
    for k, w in weights.items():
        if k in by_node and k not in lookup:
            node = h.nodes[by_node[k]]
            node.weights = [float(w)] * len(node.members)
    where = {m: (i, j) for i, n in enumerate(h.nodes) for j, m in enumerate(n.members)}
    for k, w in weights.items():
        if k in lookup:
            i, j = where[lookup[k]]
            h.nodes[i].weights[j] = float(w)


def _check_weights(weights: Mapping[str, float], lookup: Mapping[str, int],
                   by_node: Mapping[str, int]) -> None:
    """Every key names a marker or a node; every weight is positive and finite."""
    unknown = [k for k in weights if k not in lookup and k not in by_node]
    if unknown:
        raise EncoderError(f"weights name unknown markers or nodes: {unknown}")
    for k, w in weights.items():
        w = float(w)
        if not (math.isfinite(w) and w > 0):
            raise EncoderError(f"weight of {k!r} must be positive and finite, got {w!r}")


# -- scale ---------------------------------------------------------------------
def head_scale(motion: Motion, hierarchy: Hierarchy | None = None) -> tuple[float, str]:
    """The paper's ADDH (§V): mean diagonal of the four head markers.

    Parameters
    ----------
    motion : Motion
    hierarchy : Hierarchy, optional
        Used when the names are not the CMU head markers: a node named
        ``"head"`` with four members is read as LFHD, RFHD, LBHD, RBHD.

    Returns
    -------
    (float, str)
        The scale in the motion's units and the rule used:

        ``"addh"``: mean of the LFHD-RBHD and RFHD-LBHD distances, each over
        the first 200 frames where its pair is valid, averaged;
        ``"bbox"``: no head markers (or never valid): 0.1 x the median over
        frames of the bounding-box diagonal of the valid markers, which is
        ~180 mm for a standing adult, near the ~200 mm ADDH of the CMU set;
        ``"unit"``: 1.0 when that is zero or undefined.

    Examples
    --------
    >>> from mpz.synth import generate
    >>> s, how = head_scale(generate("static", frames=10))
    >>> how, 200 < s < 220
    ('addh', True)
    """
    head = _head_markers(motion, hierarchy)
    diags = [] if head is None else _head_diagonals(motion, head)
    if diags and np.mean(diags) > 0:
        return float(np.mean(diags)), "addh"
    size = body_size(motion, sample_frames(motion.n_frames, 1000))
    if math.isfinite(size) and size > 0:
        return 0.1 * size, "bbox"
    return 1.0, "unit"


def _head_markers(motion: Motion, hierarchy: Hierarchy | None) -> list[int] | None:
    """LFHD, RFHD, LBHD, RBHD by name, else the members of a 4-marker ``"head"`` node."""
    lookup = name_lookup(motion.names)
    head = [i for i in (lookup.get(n) for n in HEAD_MARKERS) if i is not None]
    if len(head) == len(HEAD_MARKERS):
        return head
    if hierarchy is not None:
        node = next((n for n in hierarchy.nodes if n.name == "head" and len(n.members) == 4), None)
        if node is not None:
            return list(node.members)
    return None


def _head_diagonals(motion: Motion, head: list[int]) -> list[float]:
    """Mean LFHD-RBHD and RFHD-LBHD distances over the first frames each pair is valid."""
    x, v = sampled(motion)
    lf, rf, lb, rb = head
    diags = []
    for a, b in ((lf, rb), (rf, lb)):
        both = np.flatnonzero(v[:, a] & v[:, b])[:HEAD_FRAMES]
        if both.size:
            d = np.linalg.norm(x[both, a] - x[both, b], axis=1)
            diags.append(float(d.mean()))
    return diags
