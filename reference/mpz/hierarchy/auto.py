"""The ``"auto"`` builder: groups of markers that move rigidly together, linked into a tree.

Contract: :func:`auto_hierarchy` needs nothing but positions and gaps (no
names, no skeleton), so it codes any input; it is the paper's future work.
It is deterministic (evenly spaced frame samples, ties broken by marker or
group index) and returns a validated hierarchy whose method is ``"auto"``:
node 0 is one root marker, node 1 (``"root_group"``) holds the root group's
other markers plus the markers that are gaps throughout, and every other node
is one rigid group (``"group<k>"``). Numeric warnings of all-gap slices are
silenced; the gaps are handled explicitly.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from mpz._jit import njit
from mpz.hierarchy.flat import flat_hierarchy
from mpz.hierarchy.measure import body_size, pair_frames, sample_frames, sampled
from mpz.hierarchy.model import Hierarchy, Node
from mpz.motion import Motion

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


def auto_hierarchy(motion: Motion, *, rigid_fraction: float = AUTO_RIGID_FRACTION,
                   max_group: int = AUTO_MAX_GROUP) -> Hierarchy:
    """Build a hierarchy from the data: rigid groups linked into a tree.

    Notes
    -----
    On at most :data:`AUTO_MAX_FRAMES` evenly spaced frames (fewer beyond 256 markers,
    :func:`~mpz.hierarchy.measure.pair_frames`):

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
    a = _analyse(motion, rigid_fraction, max_group)
    if a is None:                       # one marker, or every marker a gap throughout
        M = motion.n_markers
        return Hierarchy([Node("root", -1, 0, [0])] if M == 1 else flat_hierarchy(M).nodes,
                         "auto")
    # steps 4-6
    fin = _finite(a.std)
    tree = _group_tree(fin, a.groups, a.root_group)
    h = Hierarchy(_nodes(tree, a.groups, a.root_marker, a.dead, fin, a.n_valid_all), "auto")
    h.validate(motion.n_markers)
    return h


def auto_root(motion: Motion, *, rigid_fraction: float = AUTO_RIGID_FRACTION,
              max_group: int = AUTO_MAX_GROUP) -> int:
    """The root marker of :func:`auto_hierarchy` (its node 0), from steps 1-3 alone: the
    encoder's default mode keeps only the root of the built hierarchy (issue 15: the
    group tree was a tenth of a short clip's encode, made to be dropped)."""
    a = _analyse(motion, rigid_fraction, max_group)
    return 0 if a is None else a.root_marker


class _Analysis(NamedTuple):
    """Steps 1-3 of :func:`auto_hierarchy`."""

    std: np.ndarray                  # dissimilarity [M, M]
    groups: list[list[int]]          # the rigid groups of the live markers
    root_group: int
    root_marker: int
    dead: list[int]                  # markers that are gaps throughout
    n_valid_all: np.ndarray          # valid frames per marker, over every frame


def _analyse(motion: Motion, rigid_fraction: float, max_group: int) -> _Analysis | None:
    """Steps 1-3 of :func:`auto_hierarchy`; None for one marker, or when every marker is a
    gap throughout (the builder's fallbacks)."""
    M = motion.n_markers
    if M == 1:
        return None
    frames = sample_frames(motion.n_frames, pair_frames(M, AUTO_MAX_FRAMES))
    x, v = sampled(motion, frames)
    n_valid_all = sampled(motion)[1].sum(axis=0)  # over every frame, not the sample
    live = [m for m in range(M) if v[:, m].any()]
    alive = set(live)
    dead = [m for m in range(M) if m not in alive]
    if not live:
        return None
    # steps 1-2
    std, mean, _ = _distance_std(x, v)
    std += AUTO_SPREAD * mean
    size = body_size(motion, frames)
    threshold = rigid_fraction * size if size > 0 else 1e-9
    groups = _groups(std, live, threshold, max_group)
    # step 3
    xn = np.where(v[..., None], x, np.nan)
    root_g = _root_group(xn, live, groups)
    root_m = _root_marker(xn, groups[root_g], n_valid_all)
    return _Analysis(std, groups, root_g, root_m, dead, n_valid_all)


class _Tree(NamedTuple):
    """Groups linked into a tree: breadth-first ``order`` and group -> ``parent`` group."""

    root: int
    order: list[int]
    parent: dict[int, int]


def _nodes(tree: _Tree, groups: list[list[int]], root_m: int, dead: list[int], fin: np.ndarray,
           n_valid_all: np.ndarray) -> list[Node]:
    """The root marker; the rest of the root group and the dead markers; one node per group."""
    nodes = [Node("root", -1, root_m, [root_m])]
    rest = [m for m in groups[tree.root] if m != root_m] + dead
    if rest:
        nodes.append(Node("root_group", 0, min(rest, key=lambda m: (-n_valid_all[m], m)), rest))
    node_of_group = {tree.root: 0}
    for g in tree.order:
        if g == tree.root:
            continue
        kids = [c for c in tree.order if tree.parent[c] == g]
        p = node_of_group[tree.parent[g]]
        node_of_group[g] = len(nodes)
        nodes.append(Node(f"group{len(nodes)}", p, _reference(g, kids, groups, fin, n_valid_all),
                          list(groups[g])))
    return nodes


# -- step 1: dissimilarity ----------------------------------------------------------
def _distance_std(x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-pair std over frames of the distance, on frames where both are valid.

    Returns (std [M, M], mean distance [M, M], co-valid frame count [M, M]).
    """
    s1, s2, cnt = _distance_sums(np.ascontiguousarray(x, dtype=np.float64),
                                 np.ascontiguousarray(v, dtype=np.bool_))
    # in place, the same operations in the same order: each [M, M] table is 128 MiB at
    # 4096 markers, and a one-frame CSV of them took 1 GiB here (a scale QA run of stop 51)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.divide(s1, cnt, out=s1)
        var = np.divide(s2, cnt, out=s2)
        var -= mean ** 2
    std = np.sqrt(np.maximum(var, 0.0, out=var), out=var)
    std[cnt < 2] = np.inf
    mean[cnt < 1] = np.inf
    return std, mean, cnt


@njit(cache=True, nogil=True)
def _distance_sums(x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For every pair (a, b) of markers, over the frames f where both are valid: the sums
    of the distance d and of d^2, and the number of frames. ``x[S, M, 3]``, ``v[S, M]``.

    d = sqrt(max(|x_a|^2 + |x_b|^2 - 2 x_a . x_b, 0)), with invalid positions taken as 0,
    the three axes added as (0 + 2) + 1, and each sum taken frame after frame from 0: the
    bits of the numpy expression this replaced (einsum adds the axes in that order on this
    machine; the 29 real files keep their groups and bytes), and now the same on every
    machine. tests/test_hierarchy.py keeps that expression as the oracle.

    Speed (issue 15.1): no [S, M, M] temporaries, and each pair once (d is symmetric in a
    and b, bit for bit): 28 -> 2 ms on a 400-frame, 68-marker sample, where the numpy
    version was up to a third of a C3D encode. Then each pair's frames in one run over
    marker-major copies, its distances first (a loop without a branch, which the compiler
    vectorises) and its three sums after, in frame order as before: 2.0 -> 0.65 ms on
    c3dorg_Dance1's 400 x 40 sample, the same bits."""
    S, M = v.shape
    xz = np.zeros((M, 3, S))                     # marker-major, 0 where invalid
    sq = np.zeros((M, S))
    vf = np.zeros((M, S))                        # 1.0 where valid
    for f in range(S):
        for m in range(M):
            if v[f, m]:
                x0, x1, x2 = x[f, m, 0], x[f, m, 1], x[f, m, 2]
                xz[m, 0, f] = x0
                xz[m, 1, f] = x1
                xz[m, 2, f] = x2
                sq[m, f] = (x0 * x0 + x2 * x2) + x1 * x1
                vf[m, f] = 1.0
    s1 = np.zeros((M, M))
    s2 = np.zeros((M, M))
    cnt = np.zeros((M, M))
    dist = np.empty(S)
    for a in range(M):
        a0, a1, a2, sa, va = xz[a, 0], xz[a, 1], xz[a, 2], sq[a], vf[a]
        for b in range(a, M):
            b0, b1, b2, sb, vb = xz[b, 0], xz[b, 1], xz[b, 2], sq[b], vf[b]
            for f in range(S):
                g = (a0[f] * b0[f] + a2[f] * b2[f]) + a1[f] * b1[f]
                dist[f] = math.sqrt(max(sa[f] + sb[f] - 2 * g, 0.0))
            # 0.0 + the first term is that term: d w >= 0 (or NaN), never -0.0
            t1 = 0.0
            t2 = 0.0
            tc = 0.0
            for f in range(S):
                d = dist[f]
                w = va[f] * vb[f]
                t1 += d * w
                t2 += d * d * w
                tc += w
            s1[a, b] = s1[b, a] = t1
            s2[a, b] = s2[b, a] = t2
            cnt[a, b] = cnt[b, a] = tc
    return s1, s2, cnt


def _finite(std: np.ndarray) -> np.ndarray:
    """``std`` with non-finite entries replaced by 10 x its largest finite entry + 1."""
    fin = np.where(np.isfinite(std), std, np.nan)
    big = (np.nanmax(fin) if np.isfinite(fin).any() else 1.0) * 10 + 1.0
    return np.where(np.isnan(fin), big, fin)


# -- step 2: rigid groups -----------------------------------------------------------
def _groups(std: np.ndarray, idx: list[int], threshold: float,
            max_size: int) -> list[list[int]]:
    """Complete-linkage clusters of ``idx`` under ``threshold``, at most ``max_size`` each
    (scipy's ``linkage`` and ``fcluster``, by :func:`_complete_linkage` and the kernels
    after it, which give the same clusters in the same order: issue 15)."""
    if len(idx) == 1:
        return [list(idx)]
    sub = std[np.ix_(idx, idx)]
    finite = np.isfinite(sub)
    big = (np.max(sub[finite]) if finite.any() else 1.0) * 10 + threshold * 10 + 1.0
    sub = np.where(finite, sub, big)
    sub = 0.5 * (sub + sub.T)
    np.fill_diagonal(sub, 0.0)
    z = _complete_linkage(sub)
    labels = _fcluster_distance(z, float(threshold))
    out = []
    for lab in np.unique(labels):
        members = [idx[k] for k in np.flatnonzero(labels == lab)]
        if len(members) <= max_size:
            out.append(members)
            continue
        # too big: cut this cluster's own tree into ceil(n / max) parts, recursively
        sel = np.flatnonzero(labels == lab)
        zz = _complete_linkage(np.ascontiguousarray(sub[np.ix_(sel, sel)]))
        parts = _fcluster_maxclust(zz, -(-len(members) // max_size))
        if len(np.unique(parts)) == 1:
            # the tree cannot be cut (every distance ties: markers that move as one, such
            # as unused ones parked at one point): consecutive parts of max_size, in order,
            # where cutting again at half the threshold would recurse for ever
            out.extend(members[k: k + max_size] for k in range(0, len(members), max_size))
            continue
        for q in np.unique(parts):
            part = [members[k] for k in np.flatnonzero(parts == q)]
            out.extend(_groups(std, part, threshold * 0.5, max_size) if len(part) > max_size
                       else [part])
    return out


# -- step 2's clustering: complete linkage and flat clusters, as scipy.cluster.hierarchy --
@njit(cache=True, nogil=True)
def _complete_linkage(sub: np.ndarray) -> np.ndarray:
    """``scipy.cluster.hierarchy.linkage(condensed(sub), method="complete")`` of a symmetric
    ``sub[n, n]`` of finite dissimilarities, n >= 2: the linkage matrix ``Z[n - 1, 4]``.

    The same algorithm as scipy's (version 1.11 to 1.17 at least), so the same tree when
    distances tie, where complete linkage's tree depends on the order of merges: the
    nearest-neighbour chain from the first live cluster, each step to the nearest other
    cluster (the lowest index on a tie, but the previous cluster of the chain first), a
    merge of two mutual nearest neighbours into the higher slot, with the larger of the two
    distances to every other cluster; then the merges stably sorted by distance, and cluster
    ids n, n + 1, ... given in that order (each row: the two ids, lower first, and the
    size). Complete linkage only takes maxima, so the distances are the input's bits.
    tests/test_hierarchy.py checks it against scipy, ties included. Speed (issue 15): scipy
    validates its input and output on every call; this was most of a short clip's root."""
    n = sub.shape[0]
    D = sub.copy()
    size = np.ones(n, np.int64)
    chain = np.empty(n, np.int64)
    Z = np.empty((n - 1, 4))
    length = 0
    y = 0
    for k in range(n - 1):
        if length == 0:
            length = 1
            for i in range(n):
                if size[i] > 0:
                    chain[0] = i
                    break
        while True:
            x = chain[length - 1]
            if length > 1:
                y = chain[length - 2]
                best = D[x, y]
            else:
                best = math.inf
            for i in range(n):
                if size[i] == 0 or i == x:
                    continue
                if D[x, i] < best:
                    best = D[x, i]
                    y = i
            if length > 1 and y == chain[length - 2]:
                break
            chain[length] = y
            length += 1
        length -= 2
        if x > y:
            x, y = y, x
        nx, ny = size[x], size[y]
        Z[k, 0] = x
        Z[k, 1] = y
        Z[k, 2] = best
        Z[k, 3] = nx + ny
        size[x] = 0
        size[y] = nx + ny
        for i in range(n):
            if size[i] == 0 or i == y:
                continue
            d = D[i, x] if D[i, x] > D[i, y] else D[i, y]
            D[i, y] = d
            D[y, i] = d
    Z = Z[np.argsort(Z[:, 2], kind="mergesort")]
    parent = np.arange(2 * n - 1)                   # union-find of the cluster ids
    count = np.ones(2 * n - 1, np.int64)
    for i in range(n - 1):
        a = int(Z[i, 0])
        while parent[a] != a:
            a = parent[a]
        b = int(Z[i, 1])
        while parent[b] != b:
            b = parent[b]
        Z[i, 0], Z[i, 1] = (a, b) if a < b else (b, a)
        parent[a] = parent[b] = n + i
        count[n + i] = count[a] + count[b]
        Z[i, 3] = count[n + i]
    return Z


@njit(cache=True, nogil=True)
def _cut(Z: np.ndarray, crit: np.ndarray, cutoff: float) -> np.ndarray:
    """Flat cluster numbers 1, 2, ... of the n leaves of ``Z`` whose merges' ``crit`` (for
    complete linkage: the merge's distance) is at most ``cutoff``: the leaves are visited
    depth first from the root, left before right, and each cluster (a subtree whose crit
    is within the cutoff, or a single leaf) takes the next number when first reached, as
    scipy's ``fcluster`` numbers them."""
    n = Z.shape[0] + 1
    T = np.zeros(n, np.int32)
    stack = np.empty(n, np.int64)
    visited = np.zeros(2 * n - 1, np.bool_)
    nc = 0
    leader = -1
    k = 0
    stack[0] = 2 * n - 2
    while k >= 0:
        root = stack[k] - n
        lc, rc = int(Z[root, 0]), int(Z[root, 1])
        if leader == -1 and crit[root] <= cutoff:
            leader = root
            nc += 1
        if lc >= n and not visited[lc]:
            visited[lc] = True
            k += 1
            stack[k] = lc
            continue
        if rc >= n and not visited[rc]:
            visited[rc] = True
            k += 1
            stack[k] = rc
            continue
        if lc < n:
            if leader == -1:
                nc += 1
            T[lc] = nc
        if rc < n:
            if leader == -1:
                nc += 1
            T[rc] = nc
        if leader == root:
            leader = -1
        k -= 1
    return T


@njit(cache=True, nogil=True)
def _max_dists(Z: np.ndarray) -> np.ndarray:
    """The largest merge distance in each merge's subtree (children have lower ids)."""
    m = Z.shape[0]
    n = m + 1
    md = np.empty(m)
    for i in range(m):
        d = Z[i, 2]
        for c in (int(Z[i, 0]), int(Z[i, 1])):
            if c >= n and md[c - n] > d:
                d = md[c - n]
        md[i] = d
    return md


@njit(cache=True, nogil=True)
def _fcluster_distance(Z: np.ndarray, t: float) -> np.ndarray:
    """``fcluster(Z, t, criterion="distance")``."""
    return _cut(Z, _max_dists(Z), t)


@njit(cache=True, nogil=True)
def _fcluster_maxclust(Z: np.ndarray, mc: int) -> np.ndarray:
    """``fcluster(Z, mc, criterion="maxclust")``: the lowest merge distance, found by
    bisection over the merges in order, that leaves at most ``mc`` clusters, as scipy
    counts them (stopping a count once it passes ``mc``)."""
    n = Z.shape[0] + 1
    if mc >= n:
        return np.arange(1, n + 1).astype(np.int32)
    md = _max_dists(Z)
    stack = np.empty(n, np.int64)
    lower, upper = -1, n - 1
    while upper - lower > 1:
        i = (lower + upper) >> 1
        thresh = md[i]
        visited = np.zeros(2 * n - 1, np.bool_)
        nc = 0
        k = 0
        stack[0] = 2 * n - 2
        while k >= 0:
            root = stack[k] - n
            lc, rc = int(Z[root, 0]), int(Z[root, 1])
            if md[root] <= thresh:
                nc += 1
                if nc > mc:
                    break
                k -= 1
                visited[lc] = True
                visited[rc] = True
                continue
            if not visited[lc]:
                visited[lc] = True
                if lc >= n:
                    k += 1
                    stack[k] = lc
                    continue
                nc += 1
                if nc > mc:
                    break
            if not visited[rc]:
                visited[rc] = True
                if rc >= n:
                    k += 1
                    stack[k] = rc
                    continue
                nc += 1
                if nc > mc:
                    break
            k -= 1
        if nc > mc:
            lower = i
        else:
            upper = i
    return _cut(Z, md, md[upper])


# -- step 3: the root ---------------------------------------------------------------
def _root_group(xn: np.ndarray, live: list[int], groups: list[list[int]]) -> int:
    """The group whose centroid is nearest the centroid of all live markers, on average:
    the least of :func:`_group_distances` (the first on a tie; a group whose distance is
    not finite is never chosen unless all are so)."""
    if len(groups) == 1:
        return 0
    members = np.array([m for g in groups for m in g], np.int64)
    starts = np.cumsum([0] + [len(g) for g in groups]).astype(np.int64)
    gd = _group_distances(np.ascontiguousarray(xn, dtype=np.float64),
                          np.array(live, np.int64), members, starts)
    gd = np.where(np.isfinite(gd), gd, np.inf)
    return int(np.argmin(gd))


@njit(cache=True, nogil=True)
def _mean_over(xn: np.ndarray, idx: np.ndarray, out: np.ndarray) -> None:
    """``out[S, 3]``: the mean over the markers ``idx`` of ``xn[S, M, 3]`` at each frame and
    axis, NaN (a gap) left out: the total taken from 0.0 in ``idx`` order, a gap adding
    0.0, over the count; NaN where every one is a gap (numpy's ``nanmean(axis=1)``)."""
    for f in range(xn.shape[0]):
        for c in range(3):
            tot = 0.0
            cnt = 0
            for m in idx:
                v = xn[f, m, c]
                if v == v:
                    tot += v
                    cnt += 1
                else:
                    tot += 0.0
            out[f, c] = tot / cnt if cnt > 0 else math.nan


@njit(cache=True, nogil=True)
def _group_distances(xn: np.ndarray, live: np.ndarray, members: np.ndarray,
                     starts: np.ndarray) -> np.ndarray:
    """For each of G >= 2 groups (group g: ``members[starts[g]:starts[g + 1]]``), the mean
    over the frames ``xn[S, M, 3]`` (NaN at gaps) of the distance between its centroid and
    the centroid of the ``live`` markers, frames where either is undefined left out (NaN
    where all are).

    The bits of the numpy expression this replaced (tests/test_hierarchy.py keeps it as
    the oracle): the centroids as :func:`_mean_over`; the distance as ``np.linalg.norm``
    over the axes, sqrt(((0 + d0^2) + d1^2) + d2^2); its mean over frames summed from 0.0
    in frame order, as ``nanmean(axis=0)`` of a [S, G] array does for G >= 2 (for G = 1
    numpy sums pairwise, and no choice is left to make). Speed (issue 15): 0.65 ->
    0.05 ms on a short clip."""
    S = xn.shape[0]
    G = starts.shape[0] - 1
    overall = np.empty((S, 3))
    _mean_over(xn, live, overall)
    cent = np.empty((S, 3))
    tot = np.zeros(G)
    cnt = np.zeros(G, np.int64)
    for g in range(G):
        _mean_over(xn, members[starts[g]:starts[g + 1]], cent)
        for f in range(S):
            d0 = cent[f, 0] - overall[f, 0]
            d1 = cent[f, 1] - overall[f, 1]
            d2 = cent[f, 2] - overall[f, 2]
            d = math.sqrt(((0.0 + d0 * d0) + d1 * d1) + d2 * d2)
            if d == d:
                tot[g] += d
                cnt[g] += 1
    gd = np.empty(G)
    for g in range(G):
        gd[g] = tot[g] / cnt[g] if cnt[g] > 0 else math.nan
    return gd


def _root_marker(xn: np.ndarray, members: list[int], n_valid_all: np.ndarray) -> int:
    """The member with the fewest gaps, then the least motion (:func:`_motion_amounts`),
    then the lowest index."""
    if len(members) == 1:
        return members[0]
    amount = _motion_amounts(np.ascontiguousarray(xn, dtype=np.float64),
                             np.array(members, np.int64))
    amount = np.where(np.isfinite(amount), amount, np.inf)
    return min(members, key=lambda m: (-n_valid_all[m], amount[members.index(m)], m))


@njit(cache=True, nogil=True)
def _motion_amounts(xn: np.ndarray, members: np.ndarray) -> np.ndarray:
    """The mean over frames of how far each member of ``xn[S, M, 3]`` (NaN at gaps) moves
    from one frame to the next, steps that touch a gap left out (NaN when all do): each
    step sqrt(((0 + dx^2) + dy^2) + dz^2) and their total summed from 0.0 in frame order,
    the bits of the numpy expression this replaced (``nanmean(norm(diff(xn, axis=0),
    axis=2), axis=0)`` over two or more markers; tests/test_hierarchy.py keeps it).
    Speed (issue 15): only the root group's members, without [S, M, 3] temporaries."""
    S = xn.shape[0]
    out = np.empty(members.shape[0])
    for i in range(members.shape[0]):
        m = members[i]
        tot = 0.0
        cnt = 0
        for f in range(S - 1):
            d0 = xn[f + 1, m, 0] - xn[f, m, 0]
            d1 = xn[f + 1, m, 1] - xn[f, m, 1]
            d2 = xn[f + 1, m, 2] - xn[f, m, 2]
            d = math.sqrt(((0.0 + d0 * d0) + d1 * d1) + d2 * d2)
            if d == d:
                tot += d
                cnt += 1
        out[i] = tot / cnt if cnt > 0 else math.nan
    return out


# -- steps 4-5: the tree and the references ---------------------------------------------
def _group_tree(fin: np.ndarray, groups: list[list[int]], root_g: int) -> _Tree:
    """Minimum spanning tree over the groups, breadth first from ``root_g`` (parent -1)."""
    from scipy.sparse.csgraph import breadth_first_order, minimum_spanning_tree

    G = len(groups)
    if G == 1:
        return _Tree(root_g, [root_g], {root_g: -1})
    W = np.zeros((G, G))
    for a in range(G):
        for b in range(a + 1, G):
            blk = fin[np.ix_(groups[a], groups[b])]
            W[a, b] = W[b, a] = min(blk.mean(axis=1).min(), blk.mean(axis=0).min())
    mst = minimum_spanning_tree(W + 1e-9 * (W == 0) * (1 - np.eye(G)))
    order_arr, pred = breadth_first_order(mst + mst.T, root_g, directed=False)
    order = list(order_arr)
    # a disconnected graph cannot happen (all edges finite), but stay total
    order += [g for g in range(G) if g not in set(order)]
    parent = {g: -1 if g == root_g else int(pred[g]) if pred[g] >= 0 else root_g for g in order}
    return _Tree(root_g, order, parent)


def _reference(g: int, kids: list[int], groups: list[list[int]], fin: np.ndarray,
               n_valid_all: np.ndarray) -> int:
    """The member of group ``g`` least dissimilar on average to its children's members.

    A leaf's (no children): the member with the fewest gaps. Ties: fewest
    gaps, then lowest index.
    """
    ch = [m for c in kids for m in groups[c]]
    cand = groups[g]
    if ch:
        return min(cand, key=lambda m: (fin[m, ch].mean(), -n_valid_all[m], m))
    return min(cand, key=lambda m: (-n_valid_all[m], m))
