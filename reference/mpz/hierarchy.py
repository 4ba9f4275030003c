"""The body-part hierarchy the codec codes markers in (paper §III-A, Fig. 3).

Contract: a :class:`Hierarchy` is a list of nodes in topological order. Node 0
is the root and holds exactly one marker, coded in absolute coordinates; every
other node's members are coded relative to the reference marker of its parent
node, so a parent always comes before its children. Every marker belongs to
exactly one node. :meth:`Hierarchy.validate` checks all of this and raises
:class:`mpz.errors.EncoderError` with the offending values.

Builders (:func:`build_hierarchy`):

``"cmu41"``
    The built-in hierarchy for the CMU/Vicon 41-marker set in
    ``data/cmu41.json`` (each choice is explained there by a ``"why"``).
    Up to 4 of the 41 markers may be missing; extra markers join the non-root
    node whose reference marker is nearest on average over the motion.
``"file"``
    A JSON hierarchy (a path, or an already-parsed dict)::

        {"format": "mpz-hierarchy", "version": 1,
         "nodes": [{"name": "root", "parent": null, "ref": "C7", "members": ["C7"]},
                   {"name": "head", "parent": "root", "ref": "LFHD",
                    "members": ["LFHD", "RFHD", "LBHD", "RBHD"],
                    "weights": {"LFHD": 2.0}}, ...]}

    ``parent`` is a node name (``null`` for the root, which must come first),
    ``weights`` is optional (default 1.0). Marker names match exactly or after
    stripping a ``"Subject:"`` prefix (everything up to the last ``:``). Every
    marker of the motion must be listed, and every listed name must exist.
``"skeleton"``
    For BVH/AMC input (``motion.parents``): one node per point, parented like
    the skeleton, in breadth-first order from the skeleton root.
``"auto"``
    Groups of markers that move rigidly together, linked into a tree (the
    paper's future work; see :func:`auto_hierarchy`).
``"flat"``
    Marker 0 as the root and one child node with every other marker.

Departure from the paper: the paper builds the hierarchy by hand from the
first frame; here it is built from names (cmu41), a file, the skeleton or the
data, so that every input file can be coded.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from importlib import resources
import json
import math
from pathlib import Path

import numpy as np

from mpz.errors import EncoderError

#: spec §8: node indices are 16-bit.
MAX_NODES = 65535  # 2^16 - 1
METHODS = ("cmu41", "file", "skeleton", "auto", "flat")
CMU41_MAX_MISSING = 4
#: auto: the dissimilarity of two markers is the std over time of their
#: distance plus AUTO_SPREAD x its mean (so that, in still data, near markers
#: group first). Pairs below AUTO_RIGID_FRACTION x the body size (median
#: bounding-box diagonal) are "rigid": 2% of a ~1.8 m standing diagonal is
#: ~36 mm, above skin-motion wobble (1..15 mm on the CMU and HDM05 files) plus
#: the spread term for markers on one segment (0.05 x 100..300 mm), below the
#: change of distance across a flexing joint (tens to hundreds of mm).
AUTO_RIGID_FRACTION = 0.02
AUTO_SPREAD = 0.05
AUTO_MAX_GROUP = 6
AUTO_MAX_FRAMES = 400  # frames sampled for the auto analysis
HEAD_FRAMES = 200      # paper §V: ADDH over the first ~200 frames


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
    members: list
    weights: list = field(default_factory=list)

    def __post_init__(self):
        self.members = [int(m) for m in self.members]
        if not self.weights:
            self.weights = [1.0] * len(self.members)
        self.weights = [float(w) for w in self.weights]


@dataclass
class Hierarchy:
    """Nodes in topological order plus the method that built them."""

    nodes: list
    method: str = "file"

    def validate(self, n_markers: int) -> None:
        """Check every structural invariant against ``n_markers`` markers.

        Raises
        ------
        EncoderError
            Naming the node and the value that breaks the rule.
        """
        nodes = self.nodes
        if not nodes:
            raise EncoderError("a hierarchy needs at least one node, got 0")
        if len(nodes) > MAX_NODES:
            raise EncoderError(f"{len(nodes)} nodes, at most {MAX_NODES} allowed")
        if n_markers < 1:
            raise EncoderError(f"a hierarchy needs at least one marker, got {n_markers}")
        root = nodes[0]
        if root.parent != -1:
            raise EncoderError(f"node 0 ({root.name!r}) must be the root with parent -1, got {root.parent}")
        if len(root.members) != 1:
            raise EncoderError(f"the root node {root.name!r} must hold exactly one marker, "
                               f"got {len(root.members)}: {root.members}")
        owner = {}
        for i, node in enumerate(nodes):
            if i > 0 and not 0 <= node.parent < i:
                raise EncoderError(f"node {i} ({node.name!r}) has parent {node.parent}; it must be "
                                   f"an earlier node, 0 <= parent < {i}")
            if not node.members:
                raise EncoderError(f"node {i} ({node.name!r}) has no members")
            if len(node.weights) != len(node.members):
                raise EncoderError(f"node {i} ({node.name!r}) has {len(node.weights)} weights "
                                   f"for {len(node.members)} members")
            for m in node.members:
                if not 0 <= m < n_markers:
                    raise EncoderError(f"node {i} ({node.name!r}) names marker {m}, "
                                       f"outside 0..{n_markers - 1}")
                if m in owner:
                    raise EncoderError(f"marker {m} is in node {owner[m]} and again in node {i} "
                                       f"({node.name!r})")
                owner[m] = i
            if node.ref not in node.members:
                raise EncoderError(f"node {i} ({node.name!r}): reference marker {node.ref} "
                                   f"is not one of its members {node.members}")
            for m, w in zip(node.members, node.weights):
                if not (isinstance(w, (int, float)) and math.isfinite(w) and w > 0):
                    raise EncoderError(f"node {i} ({node.name!r}): weight {w!r} of marker {m} "
                                       f"must be positive and finite")
        missing = sorted(set(range(n_markers)) - set(owner))
        if missing:
            raise EncoderError(f"markers {missing[:10]}{'...' if len(missing) > 10 else ''} "
                               f"are in no node")

    @property
    def levels(self) -> list:
        """Depth of each node (root = 0)."""
        depth = []
        for n in self.nodes:
            depth.append(0 if n.parent < 0 else depth[n.parent] + 1)
        return depth

    def to_dict(self, names) -> dict:
        """The JSON-ready ``mpz-hierarchy`` dict, markers given by name."""
        names = list(names)
        out = []
        for n in self.nodes:
            d = {"name": n.name,
                 "parent": None if n.parent < 0 else self.nodes[n.parent].name,
                 "ref": names[n.ref],
                 "members": [names[m] for m in n.members]}
            if any(w != 1.0 for w in n.weights):
                d["weights"] = {names[m]: w for m, w in zip(n.members, n.weights)}
            out.append(d)
        return {"format": "mpz-hierarchy", "version": 1, "method": self.method, "nodes": out}

    @classmethod
    def from_dict(cls, d, names, *, method: str = "file") -> Hierarchy:
        """Parse an ``mpz-hierarchy`` dict against the motion's marker names.

        Raises
        ------
        EncoderError
            For a malformed dict, unknown marker or node names, or markers of
            the motion the dict does not place.
        """
        if not isinstance(d, dict) or d.get("format") != "mpz-hierarchy":
            raise EncoderError("not a hierarchy: expected a dict with \"format\": \"mpz-hierarchy\"")
        if d.get("version") != 1:
            raise EncoderError(f"unsupported hierarchy version {d.get('version')!r}, expected 1")
        raw = d.get("nodes")
        if not isinstance(raw, list) or not raw:
            raise EncoderError("hierarchy \"nodes\" must be a non-empty list")
        lookup = _name_lookup(names)
        node_index = {}
        nodes, unknown = [], []
        for i, nd in enumerate(raw):
            try:
                name = str(nd["name"])
                members = list(nd["members"])
                ref = nd["ref"]
                parent = nd.get("parent")
            except (KeyError, TypeError) as exc:
                raise EncoderError(f"hierarchy node {i}: missing field {exc}") from None
            if name in node_index:
                raise EncoderError(f"duplicate node name {name!r}")
            node_index[name] = i
            if parent is None:
                p = -1
            elif parent in node_index:
                p = node_index[parent]
            else:
                raise EncoderError(f"node {name!r}: parent {parent!r} is not an earlier node")
            idx = []
            for m in members:
                j = lookup.get(str(m))
                if j is None:
                    unknown.append(str(m))
                idx.append(j)
            r = lookup.get(str(ref))
            if r is None and str(ref) not in members:
                unknown.append(str(ref))
            wmap = nd.get("weights") or {}
            if not isinstance(wmap, dict):
                raise EncoderError(f"node {name!r}: \"weights\" must map marker names to numbers")
            bad = [k for k in wmap if k not in members]
            if bad:
                raise EncoderError(f"node {name!r}: weights given for non-members {bad}")
            weights = []
            for m in members:
                try:
                    weights.append(float(wmap.get(m, 1.0)))
                except (TypeError, ValueError):
                    raise EncoderError(f"node {name!r}: weight of {m!r} is not a number: "
                                       f"{wmap.get(m)!r}") from None
            nodes.append(Node(name, p, -1 if r is None else r,
                              [-1 if j is None else j for j in idx], weights))
        if unknown:
            raise EncoderError(f"hierarchy names markers the motion does not have: {unknown}")
        h = cls(nodes, method)
        placed = {m for n in nodes for m in n.members}
        missing = [names[i] for i in range(len(names)) if i not in placed]
        if missing:
            raise EncoderError(f"hierarchy does not place these markers of the motion: {missing}")
        h.validate(len(names))
        return h


# -- names ---------------------------------------------------------------------
def strip_subject(name: str) -> str:
    """``"Subject:LFHD"`` -> ``"LFHD"`` (everything up to the last ``:`` removed)."""
    return str(name).rsplit(":", 1)[-1]


def _name_lookup(names) -> dict:
    """Exact names, plus stripped names where they are unambiguous."""
    names = [str(n) for n in names]
    lookup = {n: i for i, n in enumerate(names)}
    stripped = {}
    for i, n in enumerate(names):
        stripped.setdefault(strip_subject(n), []).append(i)
    for s, idx in stripped.items():
        if len(idx) == 1 and s not in lookup:
            lookup[s] = idx[0]
    return lookup


# -- file helpers --------------------------------------------------------------
def read_hierarchy(path, names) -> Hierarchy:
    """Read a JSON hierarchy file against the motion's marker names."""
    try:
        d = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise EncoderError(f"cannot read hierarchy file: {exc}", path=str(path)) from None
    return Hierarchy.from_dict(d, names)


def write_hierarchy(h: Hierarchy, path, names) -> None:
    """Write ``h`` as an ``mpz-hierarchy`` JSON file, markers by name."""
    Path(path).write_text(json.dumps(h.to_dict(names), indent=1) + "\n", encoding="utf-8")


def cmu41_template() -> dict:
    """The built-in CMU 41-marker hierarchy (``data/cmu41.json``) as a dict."""
    return json.loads((resources.files("mpz") / "data" / "cmu41.json").read_text(encoding="utf-8"))


CMU41 = tuple(m for n in cmu41_template()["nodes"] for m in n["members"])


# -- builders ------------------------------------------------------------------
def build_hierarchy(motion, spec=None, *, weights=None) -> Hierarchy:
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
        if _cmu41_match(names) is not None:
            spec = "cmu41"
        elif motion.parents is not None:
            spec = "skeleton"
        else:
            spec = "auto"
    if isinstance(spec, dict):
        h = Hierarchy.from_dict(spec, names)
    elif spec == "cmu41":
        h = cmu41_hierarchy(motion)
    elif spec == "skeleton":
        h = skeleton_hierarchy(motion)
    elif spec == "auto":
        h = auto_hierarchy(motion)
    elif spec == "flat":
        h = flat_hierarchy(motion.n_markers)
    elif isinstance(spec, (str, Path)) and spec != "file" and Path(spec).is_file():
        h = read_hierarchy(spec, names)
    else:
        raise EncoderError(f"unknown hierarchy {spec!r}: expected one of "
                           f"{[m for m in METHODS if m != 'file']}, a dict or a JSON file path")
    if weights:
        apply_weights(h, names, weights)
    h.validate(motion.n_markers)
    return h


def apply_weights(h: Hierarchy, names, weights: dict) -> None:
    """Set per-marker weights from marker or node names (in place)."""
    lookup = _name_lookup(names)
    by_node = {n.name: i for i, n in enumerate(h.nodes)}
    where = {m: (i, k) for i, n in enumerate(h.nodes) for k, m in enumerate(n.members)}
    unknown = [k for k in weights if k not in lookup and k not in by_node]
    if unknown:
        raise EncoderError(f"weights name unknown markers or nodes: {unknown}")
    for k, w in weights.items():
        w = float(w)
        if not (math.isfinite(w) and w > 0):
            raise EncoderError(f"weight of {k!r} must be positive and finite, got {w!r}")
    # node names first, then marker names override
    for k, w in weights.items():
        if k in by_node and k not in lookup:
            node = h.nodes[by_node[k]]
            node.weights = [float(w)] * len(node.members)
    for k, w in weights.items():
        if k in lookup:
            i, j = where[lookup[k]]
            h.nodes[i].weights[j] = float(w)


def flat_hierarchy(n_markers: int) -> Hierarchy:
    """Marker 0 as the root, every other marker in one child node."""
    nodes = [Node("root", -1, 0, [0])]
    if n_markers > 1:
        nodes.append(Node("rest", 0, 1, list(range(1, n_markers))))
    return Hierarchy(nodes, "flat")


def _cmu41_match(names):
    """Stripped name -> index for the CMU markers, or None if not a CMU set."""
    stripped = [strip_subject(n) for n in names]
    idx = {}
    for i, s in enumerate(stripped):
        if s in CMU41:
            if s in idx:
                return None  # two subjects or duplicated labels: not one CMU figure
            idx[s] = i
    if len(CMU41) - len(idx) > CMU41_MAX_MISSING:
        return None
    return idx


def _mean_distance(motion, a: int, b: int, frames=None) -> float:
    """Mean distance between markers a and b over frames where both are valid."""
    x, v = motion.positions, motion.valid
    if frames is not None:
        x, v = x[frames], v[frames]
    both = v[:, a] & v[:, b]
    if not both.any():
        return math.inf
    return float(np.linalg.norm(x[both, a] - x[both, b], axis=1).mean())


def _sample_frames(n: int, k: int) -> np.ndarray:
    return np.unique(np.linspace(0, n - 1, min(n, k)).round().astype(np.int64))


def cmu41_hierarchy(motion) -> Hierarchy:
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
    idx = _cmu41_match(names)
    if idx is None:
        have = {strip_subject(n) for n in names}
        raise EncoderError(f"the motion is not a CMU 41-marker set: missing "
                           f"{sorted(set(CMU41) - have)}")
    tpl = cmu41_template()
    frames = _sample_frames(motion.n_frames, 2000)
    # template nodes with present markers only
    tnodes = [dict(n) for n in tpl["nodes"]]
    tindex = {n["name"]: i for i, n in enumerate(tnodes)}
    root_name = next((m for m in tpl["root_fallback"] if m in idx), None)
    if root_name is None:
        raise EncoderError("no CMU root marker (C7, T10, CLAV, STRN, RBAC) is present")
    parent = [None if n["parent"] is None else tindex[n["parent"]] for n in tnodes]
    members = [[idx[m] for m in n["members"] if m in idx and m != root_name] for n in tnodes]
    members[0] = [idx[root_name]]
    refs = [idx.get(n["ref"]) if n["ref"] != root_name else None for n in tnodes]
    refs[0] = idx[root_name]
    # drop emptied nodes, re-parenting their children
    keep = [i for i in range(len(tnodes)) if members[i]]

    def alive_parent(i):
        p = parent[i]
        while p is not None and not members[p]:
            p = parent[p]
        return p

    newpos = {old: new for new, old in enumerate(keep)}
    nodes = []
    for i in keep:
        p = alive_parent(i)
        nodes.append(Node(tnodes[i]["name"], -1 if p is None else newpos[p],
                          refs[i] if refs[i] in members[i] else -1, list(members[i])))
    # replace missing references
    for k, n in enumerate(nodes):
        if n.ref in n.members:
            continue
        kids = [c.ref for c in nodes if c.parent == k and c.ref in c.members]
        if kids:
            n.ref = min(n.members, key=lambda m: np.mean(
                [_mean_distance(motion, m, c, frames) for c in kids]))
        else:
            n.ref = n.members[0]
    # extra markers -> nearest non-root node by reference distance
    placed = {m for n in nodes for m in n.members}
    extras = [i for i in range(len(names)) if i not in placed]
    fallback = next((k for k, n in enumerate(nodes) if n.name == tpl["extra_fallback"]),
                    1 if len(nodes) > 1 else None)
    if extras and fallback is None:  # only the root survived; cannot happen with <= 4 missing
        nodes.append(Node("extra", 0, extras[0], []))
        fallback = len(nodes) - 1
    for e in extras:
        best, best_d = fallback, math.inf
        for k, n in enumerate(nodes):
            if k == 0:
                continue
            d = _mean_distance(motion, e, n.ref, frames)
            if d < best_d:
                best, best_d = k, d
        nodes[best].members.append(e)
    for n in nodes:
        n.weights = [1.0] * len(n.members)
    h = Hierarchy(nodes, "cmu41")
    h.validate(len(names))
    return h


def skeleton_hierarchy(motion) -> Hierarchy:
    """One node per skeleton point, parented like the skeleton, breadth first.

    The first point with parent -1 is the root; other parentless points and
    points unreachable from the root (a cycle in ``parents``) become children
    of the root node.
    """
    parents = motion.parents
    if parents is None:
        raise EncoderError("the skeleton hierarchy needs motion.parents (BVH or AMC input)")
    n = len(parents)
    children = [[] for _ in range(n)]
    roots = [i for i, p in enumerate(parents) if p < 0]
    root = roots[0] if roots else 0
    for i, p in enumerate(parents):
        if p >= 0 and i != root:
            children[p].append(i)
    order, parent_node, seen = [root], {root: -1}, {root}
    head = 0
    while True:
        while head < len(order):
            i = order[head]
            head += 1
            for c in children[i]:
                if c not in seen:
                    seen.add(c)
                    parent_node[c] = head - 1
                    order.append(c)
        rest = [i for i in range(n) if i not in seen]
        if not rest:
            break
        r = next((i for i in rest if parents[i] < 0), rest[0])
        seen.add(r)
        parent_node[r] = 0
        order.append(r)
    names = motion.names
    nodes = [Node(names[i], parent_node[i], i, [i]) for i in order]
    return Hierarchy(nodes, "skeleton")


# -- auto ----------------------------------------------------------------------
def _distance_std(x, v):
    """Per-pair std over frames of the distance, on frames where both are valid.

    Returns (std [M, M], mean distance [M, M], co-valid frame count [M, M]).
    """
    x0 = np.where(v[..., None], x, 0.0)
    sq = np.einsum("fmk,fmk->fm", x0, x0)
    g = np.einsum("fak,fbk->fab", x0, x0)
    d = np.sqrt(np.maximum(sq[:, :, None] + sq[:, None, :] - 2 * g, 0.0))
    vv = (v[:, :, None] & v[:, None, :]).astype(np.float64)
    cnt = vv.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = (d * vv).sum(axis=0) / cnt
        var = (d * d * vv).sum(axis=0) / cnt - mean ** 2
    std = np.sqrt(np.maximum(var, 0.0))
    std[cnt < 2] = np.inf
    mean[cnt < 1] = np.inf
    return std, mean, cnt


def body_size(motion, frames=None) -> float:
    """Median over frames of the bounding-box diagonal of the valid markers."""
    x, v = motion.positions, motion.valid
    if frames is not None:
        x, v = x[frames], v[frames]
    ok = v.sum(axis=1) >= 2
    if not ok.any():
        return 0.0
    xn = np.where(v[..., None], x, np.nan)[ok]
    diag = np.linalg.norm(np.nanmax(xn, axis=1) - np.nanmin(xn, axis=1), axis=1)
    return float(np.median(diag))


def _groups(std, idx, threshold, max_size):
    """Complete-linkage clusters of ``idx`` under ``threshold``, at most ``max_size`` each."""
    from scipy.cluster.hierarchy import fcluster, linkage

    if len(idx) == 1:
        return [list(idx)]
    sub = std[np.ix_(idx, idx)]
    finite = np.isfinite(sub)
    big = (np.max(sub[finite]) if finite.any() else 1.0) * 10 + threshold * 10 + 1.0
    sub = np.where(finite, sub, big)
    sub = 0.5 * (sub + sub.T)
    np.fill_diagonal(sub, 0.0)
    cond = sub[np.triu_indices(len(idx), 1)]
    z = linkage(cond, method="complete")
    labels = fcluster(z, t=threshold, criterion="distance")
    out = []
    for lab in np.unique(labels):
        members = [idx[k] for k in np.flatnonzero(labels == lab)]
        if len(members) <= max_size:
            out.append(members)
            continue
        # too big: cut this cluster's own tree into ceil(n / max) parts, recursively
        zz = linkage(sub[np.ix_(np.flatnonzero(labels == lab), np.flatnonzero(labels == lab))]
                     [np.triu_indices(len(members), 1)], method="complete")
        parts = fcluster(zz, t=-(-len(members) // max_size), criterion="maxclust")
        for q in np.unique(parts):
            part = [members[k] for k in np.flatnonzero(parts == q)]
            out.extend(_groups(std, part, threshold * 0.5, max_size) if len(part) > max_size
                       else [part])
    return out


def auto_hierarchy(motion, *, rigid_fraction: float = AUTO_RIGID_FRACTION,
                   max_group: int = AUTO_MAX_GROUP) -> Hierarchy:
    """Build a hierarchy from the data: rigid groups linked into a tree.

    Notes
    -----
    On at most :data:`AUTO_MAX_FRAMES` evenly spaced frames:

    1. dissimilarity of every pair: std over time of its distance plus
       :data:`AUTO_SPREAD` x its mean (frames where both markers are valid;
       pairs never co-valid count as non-rigid);
    2. complete-linkage clustering of it, cut at ``rigid_fraction`` x
       the body size (:func:`body_size`), groups of at most ``max_group``;
    3. root group: centroid nearest the overall centroid on average; root
       marker: its member with the fewest gaps, then the least motion;
    4. tree: minimum spanning tree over groups, edge weight = the best (over
       the members of either group) mean dissimilarity to the other group,
       rooted at the root group;
    5. reference marker of a group: the member least dissimilar on average
       to the children's members (most valid member for a leaf);
    6. the root group's other members, and markers that are gaps throughout,
       form one child node of the root.
    """
    from scipy.sparse.csgraph import breadth_first_order, minimum_spanning_tree

    M = motion.n_markers
    if M == 1:
        return Hierarchy([Node("root", -1, 0, [0])], "auto")
    frames = _sample_frames(motion.n_frames, AUTO_MAX_FRAMES)
    x, v = motion.positions[frames], motion.valid[frames]
    n_valid_all = motion.valid.sum(axis=0)
    live = [m for m in range(M) if v[:, m].any()]
    dead = [m for m in range(M) if m not in set(live)]
    if not live:
        return Hierarchy(flat_hierarchy(M).nodes, "auto")
    std, mean, _ = _distance_std(x, v)
    std = std + AUTO_SPREAD * mean
    size = body_size(motion, frames)
    threshold = rigid_fraction * size if size > 0 else 1e-9
    groups = _groups(std, live, threshold, max_group)
    G = len(groups)
    xn = np.where(v[..., None], x, np.nan)
    with np.errstate(invalid="ignore"), _quiet():
        overall = np.nanmean(xn[:, live], axis=1)                    # [S, 3]
        cent = np.stack([np.nanmean(xn[:, g], axis=1) for g in groups], axis=1)  # [S, G, 3]
        gd = np.nanmean(np.linalg.norm(cent - overall[:, None], axis=2), axis=0)
    gd = np.where(np.isfinite(gd), gd, np.inf)
    root_g = int(np.argmin(gd))
    # root marker: fewest gaps, then least motion
    step = np.linalg.norm(np.diff(xn, axis=0), axis=2)
    with _quiet():
        motion_amount = np.nanmean(step, axis=0)
    motion_amount = np.where(np.isfinite(motion_amount), motion_amount, np.inf)
    root_m = min(groups[root_g], key=lambda m: (-n_valid_all[m], motion_amount[m], m))
    # group graph
    fin = np.where(np.isfinite(std), std, np.nan)
    big = (np.nanmax(fin) if np.isfinite(fin).any() else 1.0) * 10 + 1.0
    fin = np.where(np.isnan(fin), big, fin)
    W = np.zeros((G, G))
    for a in range(G):
        for b in range(a + 1, G):
            blk = fin[np.ix_(groups[a], groups[b])]
            W[a, b] = W[b, a] = min(blk.mean(axis=1).min(), blk.mean(axis=0).min())
    tree = minimum_spanning_tree(W + 1e-9 * (W == 0) * (1 - np.eye(G))) if G > 1 else None
    if G > 1:
        sym = tree + tree.T
        order, pred = breadth_first_order(sym, root_g, directed=False)
        order = list(order)
        # a disconnected graph cannot happen (all edges finite), but stay total
        order += [g for g in range(G) if g not in set(order)]
    else:
        order, pred = [root_g], np.array([-9999])
    gparent = {g: (int(pred[g]) if g != root_g and pred[g] >= 0 else (root_g if g != root_g else -1))
               for g in order}
    kids = {g: [c for c in order if gparent[c] == g] for g in order}

    def ref_of(g):
        ch = [m for c in kids[g] for m in groups[c]]
        cand = groups[g]
        if ch:
            return min(cand, key=lambda m: (fin[m, ch].mean(), -n_valid_all[m], m))
        return min(cand, key=lambda m: (-n_valid_all[m], m))

    nodes = [Node("root", -1, root_m, [root_m])]
    node_of_group = {root_g: 0}
    rest = [m for m in groups[root_g] if m != root_m] + dead
    if rest:
        nodes.append(Node("root_group", 0, min(rest, key=lambda m: (-n_valid_all[m], m)), rest))
    for g in order:
        if g == root_g:
            continue
        p = node_of_group[gparent[g]]
        node_of_group[g] = len(nodes)
        nodes.append(Node(f"group{len(nodes)}", p, ref_of(g), list(groups[g])))
    h = Hierarchy(nodes, "auto")
    h.validate(M)
    return h


class _quiet:
    """Silence numpy's all-NaN slice warnings inside a block."""

    def __enter__(self):
        import warnings
        self._w = warnings.catch_warnings()
        self._w.__enter__()
        warnings.simplefilter("ignore", RuntimeWarning)

    def __exit__(self, *exc):
        return self._w.__exit__(*exc)


# -- scale ---------------------------------------------------------------------
def head_scale(motion, hierarchy: Hierarchy | None = None) -> tuple:
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
    lookup = _name_lookup(motion.names)
    head = [lookup.get(n) for n in ("LFHD", "RFHD", "LBHD", "RBHD")]
    if any(h is None for h in head) and hierarchy is not None:
        node = next((n for n in hierarchy.nodes if n.name == "head" and len(n.members) == 4), None)
        if node is not None:
            head = list(node.members)
    diags = []
    if all(h is not None for h in head):
        lf, rf, lb, rb = head
        for a, b in ((lf, rb), (rf, lb)):
            both = np.flatnonzero(motion.valid[:, a] & motion.valid[:, b])[:HEAD_FRAMES]
            if both.size:
                d = np.linalg.norm(motion.positions[both, a] - motion.positions[both, b], axis=1)
                diags.append(float(d.mean()))
    if diags and np.mean(diags) > 0:
        return float(np.mean(diags)), "addh"
    size = body_size(motion, _sample_frames(motion.n_frames, 1000))
    if math.isfinite(size) and size > 0:
        return 0.1 * size, "bbox"
    return 1.0, "unit"
