"""mpz.hierarchy: invariants, builders and the ADDH scale (paper §III-A, §V)."""
from __future__ import annotations

import json
import math
import warnings

from hypothesis import given, settings
from hypothesis import strategies as st
import numpy as np
from packaging.version import Version
import pytest
import scipy

import mpz
from mpz.errors import EncoderError
from mpz.hierarchy import (
    MAX_NODES,
    Hierarchy,
    Node,
    build_hierarchy,
    head_scale,
    read_hierarchy,
    write_hierarchy,
)
from mpz.synth import generate

CMU41 = ("LFHD RFHD LBHD RBHD C7 T10 CLAV STRN RBAC LSHO LUPA LELB LFRM LWRA LWRB LFIN "
         "RSHO RUPA RELB RFRM RWRA RWRB RFIN LFWT RFWT LBWT RBWT LTHI LKNE LSHN LANK LHEE "
         "LTOE LMT5 RTHI RKNE RSHN RANK RHEE RTOE RMT5").split()


def _good():
    return [Node("root", -1, 0, [0]), Node("a", 0, 1, [1, 2]), Node("b", 1, 3, [3], [2.0])]


def _case(mutate):
    nodes = _good()
    mutate(nodes)
    return nodes


# (what is broken, nodes, n_markers, words the message must contain)
BROKEN = [
    ("no nodes", [], 4, "at least one node"),
    ("root has a parent", _case(lambda n: setattr(n[0], "parent", 1)), 4, "parent -1"),
    ("root with two members", _case(lambda n: (n[0].members.append(3), n[0].weights.append(1.0),
                                               n.pop())), 4, "exactly one marker"),
    ("parent after child", _case(lambda n: setattr(n[1], "parent", 2)), 4, "earlier node"),
    ("parent is itself", _case(lambda n: setattr(n[2], "parent", 2)), 4, "earlier node"),
    ("negative parent", _case(lambda n: setattr(n[1], "parent", -1)), 4, "earlier node"),
    ("marker twice", _case(lambda n: (n[2].members.append(2), n[2].weights.append(1.0))), 4,
     "again"),
    ("marker in no node", _good(), 5, "in no node"),
    ("marker out of range", _case(lambda n: (n[2].members.append(7), n[2].weights.append(1.0))),
     4, "outside"),
    ("ref not a member", _case(lambda n: setattr(n[1], "ref", 3)), 4, "not one of its members"),
    ("empty node", _case(lambda n: n.append(Node("c", 0, 0, []))), 4, "no members"),
    ("zero weight", _case(lambda n: n[1].weights.__setitem__(0, 0.0)), 4, "positive and finite"),
    ("negative weight", _case(lambda n: n[2].weights.__setitem__(0, -1.0)), 4, "positive"),
    ("nan weight", _case(lambda n: n[1].weights.__setitem__(1, math.nan)), 4, "finite"),
    ("inf weight", _case(lambda n: n[1].weights.__setitem__(1, math.inf)), 4, "finite"),
    ("weights count", _case(lambda n: n[1].weights.pop()), 4, "weights"),
]


def test_good_hierarchy_validates():
    Hierarchy(_good(), "file").validate(4)


@pytest.mark.parametrize("what, nodes, n, words", BROKEN, ids=[b[0] for b in BROKEN])
def test_validate_rejects(what, nodes, n, words):
    with pytest.raises(EncoderError, match=words):
        Hierarchy(nodes, "file").validate(n)


def test_validate_rejects_too_many_nodes():
    """Spec §4.1: node_count <= marker_count, which §8 holds to 4096 (the limit said was
    65535, "node indices are 16-bit", which no § says)."""
    assert MAX_NODES == 4096
    n = MAX_NODES + 1
    nodes = [Node("root", -1, 0, [0])] + [Node(f"n{i}", 0, i, [i]) for i in range(1, n)]
    with pytest.raises(EncoderError, match="at most 4096 allowed"):
        Hierarchy(nodes, "file").validate(n)


def test_encoder_error_is_a_value_error():
    assert issubclass(EncoderError, ValueError) and issubclass(EncoderError, mpz.MPZError)


# -- cmu41 ----------------------------------------------------------------------
def test_cmu41_on_synthetic_covers_all_markers_with_root_c7():
    m = generate("walk", frames=120, seed=1)
    h = build_hierarchy(m)
    assert h.method == "cmu41"
    h.validate(m.n_markers)
    root = h.nodes[0]
    assert [m.names[i] for i in root.members] == ["C7"] and root.parent == -1
    placed = sorted(i for n in h.nodes for i in n.members)
    assert placed == list(range(41))
    by = {n.name: n for n in h.nodes}
    ref = {k: m.names[n.ref] for k, n in by.items()}
    # paper Fig. 3: level 2 = head, shoulders, torso; refs at the joints with children
    for name in ("head", "l_shoulder", "torso", "r_shoulder"):
        assert by[name].parent == 0
    assert ref["l_shoulder"] == "LSHO" and ref["l_upper_arm"] == "LELB"
    assert ref["l_thigh"] == "LKNE" and ref["l_shank"] == "LANK"
    assert sorted(m.names[i] for i in by["head"].members) == ["LBHD", "LFHD", "RBHD", "RFHD"]


def test_cmu41_with_prefix_extras_and_missing_markers():
    base = generate("walk", frames=200, seed=2)
    keep = [i for i, n in enumerate(base.names) if n not in ("C7", "LUPA", "RFIN")]
    x = base.positions[:, keep]
    # an extra marker riding 20 mm off the left knee, and one never seen
    lk = base.names.index("LKNE")
    extra = base.positions[:, lk:lk + 1] + np.array([0.0, 20.0, 0.0])
    ghost = np.full((base.n_frames, 1, 3), np.nan)
    names = [f"Subj:{base.names[i]}" for i in keep] + ["LKNE-1", "*0"]
    m = mpz.Motion(np.concatenate([x, extra, ghost], axis=1), names, 120.0)
    h = build_hierarchy(m)
    assert h.method == "cmu41"
    h.validate(m.n_markers)
    assert m.names[h.nodes[0].members[0]] == "Subj:T10"     # first root fallback after C7
    node_of = {i: n.name for n in h.nodes for i in n.members}
    assert node_of[names.index("LKNE-1")] == "l_thigh"       # nearest reference: LKNE
    assert node_of[names.index("*0")] == "torso"             # never valid: fallback node


def test_cmu41_missing_markers_reshape_the_tree():
    base = generate("walk", frames=200, seed=6)
    keep = [i for i, n in enumerate(base.names) if n not in ("LSHO", "T10", "LKNE")]
    m = mpz.Motion(base.positions[:, keep], [base.names[i] for i in keep], base.rate)
    h = build_hierarchy(m, "cmu41")
    by = {n.name: n for n in h.nodes}
    # l_shoulder lost its only marker: gone, and its child hangs from its parent, the root
    assert "l_shoulder" not in by and by["l_upper_arm"].parent == 0
    # torso lost its reference T10: the member nearest on average to its children's references
    kids = [n.ref for n in h.nodes if n.parent == h.nodes.index(by["torso"])]
    assert sorted(m.names[r] for r in kids) == ["LFWT", "RFWT"]

    def dist(a, b):
        return np.linalg.norm(m.positions[:, a] - m.positions[:, b], axis=1).mean()

    nearest = min(by["torso"].members, key=lambda a: np.mean([dist(a, c) for c in kids]))
    assert by["torso"].ref == nearest and m.names[nearest] != "T10"
    assert m.names[by["l_thigh"].ref] == "LTHI"             # the one member left


def test_not_cmu_when_too_many_missing():
    base = generate("walk", frames=50, seed=2)
    m = mpz.Motion(base.positions[:, 5:], base.names[5:], 120.0)
    assert build_hierarchy(m).method == "auto"
    with pytest.raises(EncoderError, match="not a CMU"):
        build_hierarchy(m, "cmu41")


# -- file ----------------------------------------------------------------------
def test_json_file_round_trip(tmp_path):
    m = generate("jump", frames=60, seed=3)
    h = build_hierarchy(m, "cmu41", weights={"l_foot": 4.0, "LHEE": 10.0})
    path = tmp_path / "h.json"
    write_hierarchy(h, path, m.names)
    d = json.loads(path.read_text())
    assert d["format"] == "mpz-hierarchy" and d["version"] == 1
    assert d["nodes"][0]["parent"] is None and d["nodes"][0]["members"] == ["C7"]
    back = build_hierarchy(m, str(path))
    assert back.method == "file"
    assert [(n.name, n.parent, n.ref, n.members, n.weights) for n in back.nodes] == \
           [(n.name, n.parent, n.ref, n.members, n.weights) for n in h.nodes]
    foot = next(n for n in back.nodes if n.name == "l_foot")
    assert dict(zip((m.names[i] for i in foot.members), foot.weights, strict=True)) == \
        {"LHEE": 10.0, "LTOE": 4.0, "LMT5": 4.0}
    # names match after stripping a subject prefix
    pm = mpz.Motion(m.positions, [f"Bob:{n}" for n in m.names], m.rate)
    assert [n.members for n in read_hierarchy(path, pm.names).nodes] == [n.members for n in h.nodes]


def test_file_names_unknown_and_missing_markers():
    m = generate("static", frames=5, markers=3)      # LFHD RFHD LBHD
    d = {"format": "mpz-hierarchy", "version": 1, "nodes": [
        {"name": "root", "parent": None, "ref": "LFHD", "members": ["LFHD"]},
        {"name": "rest", "parent": "root", "ref": "RFHD", "members": ["RFHD", "NOPE"]}]}
    with pytest.raises(EncoderError, match="NOPE"):
        build_hierarchy(m, d)
    d["nodes"][1]["members"] = ["RFHD"]
    with pytest.raises(EncoderError, match="LBHD"):
        build_hierarchy(m, d)
    d["nodes"][1]["members"] = ["RFHD", "LBHD"]
    assert build_hierarchy(m, d).nodes[1].members == [1, 2]


def test_unknown_spec_and_bad_weights():
    m = generate("static", frames=5, markers=3)
    with pytest.raises(EncoderError, match="unknown hierarchy"):
        build_hierarchy(m, "tree")
    with pytest.raises(EncoderError, match="unknown"):
        build_hierarchy(m, "flat", weights={"XYZ": 2.0})
    with pytest.raises(EncoderError, match="positive"):
        build_hierarchy(m, "flat", weights={"RFHD": 0.0})


# -- skeleton and flat ---------------------------------------------------------------
def test_skeleton_builder_orders_breadth_first():
    #        0 hips
    #      /   \
    #   2 spine  1 lleg -> 4 lfoot
    #   |
    #   3 head
    names = ["hips", "lleg", "spine", "head", "lfoot"]
    parents = [-1, 0, 0, 2, 1]
    m = mpz.Motion(np.random.default_rng(0).normal(size=(4, 5, 3)), names, 120.0,
                   parents=parents)
    h = build_hierarchy(m)
    assert h.method == "skeleton"
    h.validate(5)
    order = [names[n.members[0]] for n in h.nodes]
    assert order == ["hips", "lleg", "spine", "lfoot", "head"]
    for n in h.nodes:
        assert n.members == [n.ref]
        if n.parent >= 0:   # node parent = node of the skeleton parent
            assert h.nodes[n.parent].members[0] == parents[n.members[0]]


def test_flat():
    m = generate("static", frames=5, markers=4)
    h = build_hierarchy(m, "flat")
    assert [n.members for n in h.nodes] == [[0], [1, 2, 3]]


# -- auto ----------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["walk", "mixed", "wave"])
def test_auto_groups_rigid_parts(kind):
    m = generate(kind, frames=1500, seed=4, gap_fraction=0.05)
    h = build_hierarchy(m, "auto")
    assert h.method == "auto"
    h.validate(m.n_markers)
    node_of = {i: k for k, n in enumerate(h.nodes) for i in n.members}
    head = {node_of[m.names.index(n)] for n in ("LFHD", "RFHD", "LBHD", "RBHD")}
    assert len(head) == 1
    # segments across a moving joint are not grouped together
    assert node_of[m.names.index("LHEE")] != node_of[m.names.index("LFWT")]
    assert node_of[m.names.index("RWRA")] != node_of[m.names.index("RSHO")]
    assert max(len(n.members) for n in h.nodes) <= 6


def test_auto_one_two_and_dead_markers():
    one = generate("walk", frames=30, markers=1)
    h1 = build_hierarchy(one, "auto")
    assert [n.members for n in h1.nodes] == [[0]]
    two = generate("walk", frames=30, markers=2)
    h2 = build_hierarchy(two, "auto")
    assert sorted(i for n in h2.nodes for i in n.members) == [0, 1]
    assert len(h2.nodes[0].members) == 1
    # markers that are gaps throughout still get a node; all-gap motion works too
    m = generate("walk", frames=100, markers=10, seed=1)
    valid = m.valid.copy()
    valid[:, 3] = False
    x = m.positions.copy()
    x[:, 3] = np.nan
    build_hierarchy(mpz.Motion(x, m.names, m.rate, valid=valid), "auto").validate(10)
    nothing = mpz.Motion(np.full((5, 3, 3), np.nan), ["a", "b", "c"], 10.0)
    build_hierarchy(nothing, "auto").validate(3)


def test_auto_silences_all_gap_warnings_inside_only():
    m = generate("walk", frames=60, markers=8, seed=2)
    valid = m.valid.copy()
    valid[:, 5] = False                      # all-gap marker: all-NaN slices for nanmean
    valid[::2, 2] = False
    x = np.where(valid[..., None], m.positions, np.nan)
    gappy = mpz.Motion(x, m.names, m.rate, valid=valid)
    with warnings.catch_warnings():
        warnings.simplefilter("error")       # any warning that escapes fails the test
        before = list(warnings.filters)
        build_hierarchy(gappy, "auto").validate(8)
        assert warnings.filters == before     # the caller's filters are restored


def test_auto_many_markers_with_gaps():
    base = generate("mixed", frames=5000, seed=8, gap_fraction=0.1)
    # 90 markers: the 41 plus copies shifted by 30 mm and a few copies of copies
    x = np.concatenate([base.positions, base.positions + 30.0, base.positions[:, :8] - 30.0],
                       axis=1)
    v = np.concatenate([base.valid, base.valid, base.valid[:, :8]], axis=1)
    names = base.names + [n + "_b" for n in base.names] + [n + "_c" for n in base.names[:8]]
    m = mpz.Motion(x, names, base.rate, valid=v)
    h = build_hierarchy(m)
    assert h.method == "cmu41"    # the CMU names are all there; the copies are extras
    h.validate(90)
    build_hierarchy(m, "auto").validate(90)


# -- head scale ----------------------------------------------------------------
def test_head_scale_matches_the_synthetic_head_band():
    # the synthetic head band: LFHD at (75, 80, 95), LBHD at (-60, 80, 85) mm from the
    # head joint, right markers mirrored in y; both diagonals are (135, 160, 10) mm
    expected = math.sqrt(135.0 ** 2 + 160.0 ** 2 + 10.0 ** 2)
    for kind in ("walk", "jump"):
        s, how = head_scale(generate(kind, frames=400, seed=5))
        assert how == "addh"
        assert s == pytest.approx(expected, abs=0.5)


def test_head_scale_fallbacks():
    m = generate("static", frames=50, seed=5)
    body = mpz.Motion(m.positions[:, 4:], m.names[4:], m.rate)
    s, how = head_scale(body)
    assert how == "bbox"
    assert 120.0 < s < 250.0      # 0.1 x the ~1.8 m bounding-box diagonal of a standing adult
    single = mpz.Motion(np.zeros((3, 1, 3)), ["x"], 10.0)
    assert head_scale(single) == (1.0, "unit")
    # head markers with other names, found through a hierarchy node called "head"
    renamed = mpz.Motion(m.positions, [f"m{i}" for i in range(41)], m.rate)
    h = build_hierarchy(m, "cmu41")
    s2, how2 = head_scale(renamed, h)
    assert how2 == "addh" and s2 == pytest.approx(head_scale(m)[0])


# -- real recordings -------------------------------------------------------------
C3D_FILES = ["cmu_01_01", "cmu_02_01", "cmu_135_02", "HDM_dg_06-03_03_120",
             "HDM_mm_01-02_03_120", "numediart_03_rolling", "ezc3d_Vicon", "ezc3d_Qualisys",
             "c3dorg_Eb015pi", "c3dorg_Eb015vr", "c3dorg_Eb015sr", "c3dorg_Dance1",
             "c3dorg_AlbertoINT", "c3dorg_Facial-Sing", "c3dorg_arthuman-sample",
             "c3dorg_codamotion_gaitwands_20150204", "c3dorg_Sample_Jump2",
             "auckland_FMC_MH0222_BP06"]


def _load_c3d(path):
    """Motion from a C3D through mpz.io (which also reads the MIPS and malformed files)."""
    from mpz.io import read
    return read(path)


def _real_c3d(shared_data, stem):
    """The motion of ../shared/data/c3d/STEM.c3d; the test is skipped when it is absent."""
    path = shared_data / "c3d" / f"{stem}.c3d"
    if not path.exists():
        pytest.skip(f"{path} is absent")
    return _load_c3d(path)


@pytest.mark.parametrize("stem", C3D_FILES)
def test_real_c3d_gets_a_valid_hierarchy(shared_data, stem):
    m = _real_c3d(shared_data, stem)
    h = build_hierarchy(m)
    h.validate(m.n_markers)
    if stem.startswith(("cmu_", "HDM_")):
        assert h.method == "cmu41"
        assert m.names[h.nodes[0].members[0]].split(":")[-1] == "C7"
        s, how = head_scale(m, h)
        assert how == "addh" and 150.0 < s < 260.0   # a head band in mm
    else:
        assert h.method == "auto"
    build_hierarchy(m, "auto").validate(m.n_markers)
    build_hierarchy(m, "flat").validate(m.n_markers)


# -- the auto builder's pair statistics (issue 15.1: a kernel in place of numpy) -------
def _distance_sums_numpy(x, v):
    """The numpy expression the kernel replaced, with einsum's sums over the axes written
    out in the order it adds them here, (0 + 2) + 1 (einsum's order is its own SIMD
    detail; written out, the oracle does not depend on it). The hierarchy's groups
    compare these sums with thresholds, so a last-bit change could regroup."""
    x0 = np.where(v[..., None], x, 0.0)
    sq = (x0[..., 0] * x0[..., 0] + x0[..., 2] * x0[..., 2]) + x0[..., 1] * x0[..., 1]
    xa, xb = x0[:, :, None, :], x0[:, None, :, :]
    g = (xa[..., 0] * xb[..., 0] + xa[..., 2] * xb[..., 2]) + xa[..., 1] * xb[..., 1]
    d = np.sqrt(np.maximum(sq[:, :, None] + sq[:, None, :] - 2 * g, 0.0))
    vv = (v[:, :, None] & v[:, None, :]).astype(np.float64)
    return (d * vv).sum(axis=0), (d * d * vv).sum(axis=0), vv.sum(axis=0)


def _same_sums(x, v):
    from mpz.hierarchy.auto import _distance_sums
    got = _distance_sums(np.ascontiguousarray(x), np.ascontiguousarray(v))
    for a, b in zip(got, _distance_sums_numpy(x, v), strict=True):
        assert np.array_equal(a, b)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 40), st.integers(1, 25), st.floats(0.0, 4.0), st.floats(0.0, 0.6),
       st.integers(0, 2 ** 32 - 1))
def test_auto_distance_sums_have_the_numpy_bits(S, M, scale, gaps, seed):
    rng = np.random.default_rng(seed)
    x = rng.normal(0, 10 ** scale, (S, M, 3))
    _same_sums(x, rng.random((S, M)) >= gaps)


@pytest.mark.parametrize("stem", C3D_FILES)
def test_auto_distance_sums_on_real_samples(shared_data, stem):
    from mpz.hierarchy.auto import AUTO_MAX_FRAMES
    from mpz.hierarchy.measure import sample_frames, sampled
    m = _real_c3d(shared_data, stem)
    _same_sums(*sampled(m, sample_frames(m.n_frames, AUTO_MAX_FRAMES)))



# -- the auto builder's clustering (issue 15: kernels in place of scipy's calls) -------
#: scipy before 1.15 cuts maxclust otherwise: two points 2 apart into two clusters under
#: maxclust=1, and three with ties into one under maxclust=2 where two are possible (found
#: on the lowest scipy pyproject.toml allows, 1.11.1; 1.15.0 agrees): not an oracle there
_SCIPY_MAXCLUST_RIGHT = Version(scipy.__version__) >= Version("1.15")


@settings(max_examples=300, deadline=None)
@given(st.integers(2, 30), st.sampled_from(["ties", "tenths", "any"]), st.integers(1, 32),
       st.floats(0.0, 3.5), st.integers(0, 2 ** 32 - 1))
def test_auto_clustering_is_scipys(n, kind, mc, t, seed):
    """Complete linkage and both flat cuts give scipy's matrix and cluster numbers bit for
    bit. Ties decide complete linkage's tree (a-b 1, b-c 1, a-c 5 cut at 1 is {a, b} {c}
    or {a} {b, c} by the order of merges), so most cases are made of a few distinct
    values; the oracle is scipy itself, which the encoder called before."""
    from scipy.cluster.hierarchy import fcluster, linkage

    from mpz.hierarchy.auto import _complete_linkage, _fcluster_distance, _fcluster_maxclust
    rng = np.random.default_rng(seed)
    a = {"ties": lambda: rng.integers(0, 4, (n, n)).astype(float),
         "tenths": lambda: np.round(rng.random((n, n)) * 10) / 10,
         "any": lambda: rng.random((n, n)) * 3}[kind]()
    a = 0.5 * (a + a.T)
    np.fill_diagonal(a, 0.0)
    z = linkage(a[np.triu_indices(n, 1)], method="complete")
    got = _complete_linkage(a)
    assert np.array_equal(got, z)
    cut = float(rng.choice(a[np.triu_indices(n, 1)])) if kind != "any" else t
    assert np.array_equal(_fcluster_distance(got, cut),
                          fcluster(z, t=cut, criterion="distance"))
    if _SCIPY_MAXCLUST_RIGHT:
        assert np.array_equal(_fcluster_maxclust(got, mc),
                              fcluster(z, t=mc, criterion="maxclust"))
    assert len(set(_fcluster_maxclust(got, mc))) <= mc    # what maxclust promises, any scipy


def test_auto_clustering_ties_by_hand():
    """a-b 1, b-c 1, a-c 5: the chain from a meets b first (the lower index on a tie), so
    a and b merge at 1 and c joins at 5; cut at 1: {a, b}, {c}, numbered in that order."""
    from mpz.hierarchy.auto import _complete_linkage, _fcluster_distance
    a = np.array([[0.0, 1.0, 5.0], [1.0, 0.0, 1.0], [5.0, 1.0, 0.0]])
    z = _complete_linkage(a)
    assert z.tolist() == [[0.0, 1.0, 1.0, 2.0], [2.0, 3.0, 5.0, 3.0]]
    assert _fcluster_distance(z, 1.0).tolist() == [1, 1, 2]


def _group_distances_numpy(xn, live, groups):
    """The numpy expression :func:`mpz.hierarchy.auto._group_distances` replaced."""
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        overall = np.nanmean(xn[:, live], axis=1)
        cent = np.stack([np.nanmean(xn[:, g], axis=1) for g in groups], axis=1)
        return np.nanmean(np.linalg.norm(cent - overall[:, None], axis=2), axis=0)


@settings(max_examples=150, deadline=None)
@given(st.integers(1, 420), st.integers(2, 70), st.floats(0.0, 4.0), st.floats(0.0, 0.8),
       st.integers(0, 2 ** 32 - 1))
def test_auto_root_group_distances_have_the_numpy_bits(S, M, scale, gaps, seed):
    """The root group is an argmin of these means, so a last-bit change could move the
    root: the kernel must give numpy's bits, gaps, all-gap frames and markers included."""
    from mpz.hierarchy.auto import _group_distances
    rng = np.random.default_rng(seed)
    x = rng.normal(0, 10 ** scale, (S, M, 3)) + rng.normal(0, 1000, (1, M, 3))
    v = rng.random((S, M)) >= gaps
    xn = np.where(v[..., None], x, np.nan)
    live = [m for m in range(M) if v[:, m].any()]
    if len(live) < 2:
        return
    perm = rng.permutation(live)
    k = int(rng.integers(2, len(live) + 1))
    groups = [list(map(int, g)) for g in np.split(perm, np.sort(rng.choice(
        np.arange(1, len(live)), size=k - 1, replace=False)))]
    got = _group_distances(xn, np.array(live), np.array([m for g in groups for m in g]),
                           np.cumsum([0] + [len(g) for g in groups]))
    assert np.array_equal(got, _group_distances_numpy(xn, live, groups), equal_nan=True)


def _body_size_numpy(x, v):
    """The numpy expression :func:`mpz.hierarchy.measure.body_size` computed before its
    kernel (issue 15): the rigid threshold and the bbox scale are fractions of it."""
    ok = v.sum(axis=1) >= 2
    if not ok.any():
        return 0.0
    xt = np.ascontiguousarray(x[ok].transpose(0, 2, 1))
    vt = v[ok][:, None, :]
    hi = np.where(vt, xt, -np.inf).max(axis=2)
    lo = np.where(vt, xt, np.inf).min(axis=2)
    return float(np.median(np.linalg.norm(hi - lo, axis=1)))


@settings(max_examples=150, deadline=None)
@given(st.integers(1, 1000), st.integers(1, 70), st.floats(-2.0, 5.0), st.floats(0.0, 1.0),
       st.integers(0, 2 ** 32 - 1))
def test_body_size_has_the_numpy_bits(S, M, scale, gaps, seed):
    from mpz.hierarchy.measure import body_size
    rng = np.random.default_rng(seed)
    x = rng.normal(0, 10 ** scale, (S, M, 3)) + rng.normal(0, 10 ** scale, (1, M, 3))
    v = rng.random((S, M)) >= gaps
    x[~v] = np.nan
    got = body_size(mpz.Motion(x, [f"m{i}" for i in range(M)], 100.0, valid=v))
    assert got == _body_size_numpy(x, v)


@settings(max_examples=150, deadline=None)
@given(st.integers(1, 420), st.integers(2, 70), st.floats(0.0, 4.0), st.floats(0.0, 0.9),
       st.integers(0, 2 ** 32 - 1))
def test_root_marker_motion_has_the_numpy_bits(S, M, scale, gaps, seed):
    """The root marker is chosen by these means on a tie of gaps: numpy's bits over all
    markers (the expression the kernel replaced), read at any two or more members."""
    from mpz.hierarchy.auto import _motion_amounts
    rng = np.random.default_rng(seed)
    xn = np.cumsum(rng.normal(0, 10 ** scale, (S, M, 3)), axis=0)
    xn[rng.random((S, M)) < gaps] = np.nan
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        want = np.nanmean(np.linalg.norm(np.diff(xn, axis=0), axis=2), axis=0)
    members = np.sort(rng.choice(M, size=int(rng.integers(2, M + 1)), replace=False))
    assert np.array_equal(_motion_amounts(xn, members), want[members], equal_nan=True)

# -- the root alone (issue 15.1: the encoder's default mode keeps only the root) -------
def _same_root(m, spec=None, weights=None):
    from mpz.hierarchy import root_marker
    assert root_marker(m, spec, weights=weights) == \
        build_hierarchy(m, spec, weights=weights).nodes[0].members[0]


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 12), st.integers(2, 60), st.floats(0.0, 0.7), st.booleans(),
       st.integers(0, 2 ** 32 - 1))
def test_root_marker_is_the_built_hierarchys(M, F, gaps, dead, seed):
    """root_marker skips the auto builder's group tree; the root must be the one
    build_hierarchy gives, also with gaps, markers that are gaps throughout, one marker,
    and a motion with no valid sample at all."""
    rng = np.random.default_rng(seed)
    x = np.cumsum(rng.normal(0, 5, (F, M, 3)), axis=0) + rng.normal(0, 300, (1, M, 3))
    valid = rng.random((F, M)) >= gaps
    if dead:
        valid[:, rng.integers(M)] = False
    x[~valid] = np.nan
    m = mpz.Motion(x, [f"m{i}" for i in range(M)], 100.0, valid=valid)
    _same_root(m)
    _same_root(m, "flat")


def test_root_marker_keeps_build_hierarchys_errors_and_specs():
    m = generate("walk", frames=60, seed=3)
    _same_root(m)                                      # cmu41
    _same_root(m, "auto")
    _same_root(m, "auto", weights={"root_group": 2.0})  # weights: the tree is built
    from mpz.hierarchy import root_marker
    with pytest.raises(EncoderError, match="unknown"):
        root_marker(m, weights={"nonesuch": 1.0})
    with pytest.raises(EncoderError, match="unknown hierarchy"):
        root_marker(m, "nonesuch")


def _root_or_error(fn):
    try:
        return fn()
    except EncoderError as exc:
        return f"EncoderError: {exc}"


@settings(max_examples=80, deadline=None)
@given(st.integers(0, 2 ** 32 - 1), st.integers(0, 7), st.integers(0, 4), st.booleans(),
       st.booleans(), st.floats(0.0, 0.6))
def test_cmu41_root_is_the_built_hierarchys(seed, missing, extras, prefix, repeat, gaps):
    """The CMU set's root without its tree (issue 15.1) is the built tree's node 0, or the
    same error, for any of the set's markers missing (the root's candidates among them,
    past the 4 the builder allows), extra markers, a subject prefix, a label given twice
    (two subjects), and gaps; with the builder named and chosen by default."""
    rng = np.random.default_rng(seed)
    names = [n for n in CMU41 if n not in set(rng.choice(CMU41, missing, replace=False))]
    names += [f"extra{i}" for i in range(extras)]
    if repeat:                                  # a second subject's label of one of them
        names.append("Other:" + names[int(rng.integers(len(names)))])
    names = [names[i] for i in rng.permutation(len(names))]
    if prefix:
        names = [f"Sub:{n}" for n in names]
    F, M = 30, len(names)
    x = np.cumsum(rng.normal(0, 5, (F, M, 3)), axis=0) + rng.normal(0, 300, (1, M, 3))
    valid = rng.random((F, M)) >= gaps
    x[~valid] = np.nan
    m = mpz.Motion(x, names, 100.0, valid=valid)
    from mpz.hierarchy import root_marker
    for spec in ("cmu41", None):
        want = _root_or_error(lambda spec=spec: build_hierarchy(m, spec).nodes[0].members[0])
        assert _root_or_error(lambda spec=spec: root_marker(m, spec)) == want


def test_cmu41_root_measures_no_distance(monkeypatch):
    """The encoder's default mode keeps only the root: on a CMU set with extra markers the
    tree's mean distances (14 ms of HDM_mm's encode) are not measured for it."""
    from mpz.hierarchy import root_marker
    import mpz.hierarchy.cmu41 as cmu41
    m = generate("walk", frames=60, seed=3)
    x = np.concatenate([m.positions, m.positions[:, :2] + 40.0], axis=1)
    m = mpz.Motion(x, list(m.names) + ["extraA", "extraB"], m.rate, units=m.units)
    want = build_hierarchy(m).nodes[0].members[0]

    def measured(*args, **kwargs):
        raise AssertionError("a distance was measured for the root alone")
    monkeypatch.setattr(cmu41, "mean_distance", measured)
    assert root_marker(m) == want


@pytest.mark.parametrize("stem", C3D_FILES)
def test_root_marker_on_real_captures(shared_data, stem):
    m = _real_c3d(shared_data, stem)
    _same_root(m)
    _same_root(m, "auto")


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 30), st.integers(1, 20), st.floats(0.0, 1.0), st.integers(0, 2 ** 32 - 1))
def test_body_size_is_the_median_box_diagonal(F, M, gaps, seed):
    """body_size reduces a transposed copy (issue 15.1); the oracle is the definition:
    per frame with two valid markers or more, the diagonal of the box of its valid markers
    (numpy's nanmax / nanmin with the gaps as NaN), then the median over those frames."""
    from mpz.hierarchy import body_size
    rng = np.random.default_rng(seed)
    x = rng.normal(0, 500, (F, M, 3))
    valid = rng.random((F, M)) >= gaps
    x[~valid] = np.nan
    m = mpz.Motion(x, [f"m{i}" for i in range(M)], 100.0, valid=valid)
    ok = valid.sum(axis=1) >= 2
    want = 0.0
    if ok.any():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            box = np.nanmax(x[ok], axis=1) - np.nanmin(x[ok], axis=1)
        want = float(np.median(np.linalg.norm(box, axis=1)))
    assert body_size(m) == want


# -- package layout ----------------------------------------------------------------
def test_every_public_name_of_the_former_module_is_still_importable():
    """mpz.hierarchy became a package (one module per builder); its public names stay."""
    import mpz.hierarchy as h
    former = ("AUTO_MAX_FRAMES AUTO_MAX_GROUP AUTO_RIGID_FRACTION AUTO_SPREAD CMU41 "
              "CMU41_MAX_MISSING HEAD_FRAMES MAX_NODES METHODS Hierarchy Node apply_weights "
              "auto_hierarchy body_size build_hierarchy cmu41_hierarchy cmu41_template "
              "flat_hierarchy head_scale read_hierarchy skeleton_hierarchy strip_subject "
              "write_hierarchy").split()
    added = ["root_marker"]                    # issue 15.1: the root without the whole tree
    assert sorted(h.__all__) == sorted(former + added)
    for name in former:
        assert getattr(h, name) is not None
    assert sorted(h.CMU41) == sorted(CMU41)


@pytest.mark.parametrize("n", [8, 16, 51])
def test_markers_that_all_stand_at_one_point_are_grouped(n):
    """Markers with no distance between them (unused markers parked at one point): the
    auto builder's complete-linkage tree ties everywhere and cannot be cut, and cutting
    again at half the threshold recursed until RecursionError (a QA run, 8 or more such
    markers). Now they are cut in order into groups of at most max_size, and the file
    encodes and decodes exactly."""
    from mpz.hierarchy.auto import _groups
    groups = _groups(np.zeros((n, n)), list(range(n)), 1.0, 6)
    assert sorted(m for g in groups for m in g) == list(range(n))
    assert all(1 <= len(g) <= 6 for g in groups)
    m = mpz.Motion(np.full((20, n, 3), 1.0), [f"M{i}" for i in range(n)], 100.0, "mm")
    back = mpz.decode(mpz.encode(m, max_error=0.5))
    assert np.abs(back.positions - 1.0).max() <= 0.5


def _hierarchy_doc() -> tuple[dict, list[str]]:
    """A valid mpz-hierarchy dict of three nodes over four markers, and the names."""
    names = ["A", "B", "C", "D"]
    return {"format": "mpz-hierarchy", "version": 1, "nodes": [
        {"name": "root", "members": ["A"], "ref": "A", "parent": None},
        {"name": "arm", "members": ["B", "C"], "ref": "B", "parent": "root"},
        {"name": "hand", "members": ["D"], "ref": "D", "parent": "arm"}]}, names


@pytest.mark.parametrize("change,match", [
    (lambda d: d["nodes"][2]["members"].append("B"), "marker 'B' is in node 'arm' and "
                                                      "again in node 'hand'"),
    (lambda d: d["nodes"][1]["members"].append("B"), "marker 'B' is listed twice in node 'arm'"),
    (lambda d: d["nodes"][1].update(ref="D"), "node 'arm': its ref 'D' is not one of its"),
    (lambda d: d["nodes"][2].pop("parent"), "node 'hand' has no parent"),
    (lambda d: d["nodes"][1].update(parent=None), "node 'arm' has no parent"),
    (lambda d: d.update(version=True), "unsupported hierarchy version True"),
    (lambda d: d.update(version=1.0), "unsupported hierarchy version 1.0"),
])
def test_hierarchy_file_errors_name_markers_and_nodes(tmp_path, change, match):
    """They named markers and nodes by index ('marker 15 is in node 3 and again in node 5'),
    called a missing parent 'parent -1', and took version true (a QA run)."""
    d, names = _hierarchy_doc()
    change(d)
    p = tmp_path / "h.json"
    p.write_text(json.dumps(d))
    with pytest.raises(EncoderError, match=match):
        read_hierarchy(p, names)


def test_hierarchy_file_deeply_nested_bom_and_folder(tmp_path):
    """100,000 nested brackets gave a RecursionError traceback; a byte-order mark was
    refused; a folder was 'an unknown hierarchy'."""
    from mpz.hierarchy import build_hierarchy
    p = tmp_path / "deep.json"
    p.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(EncoderError, match="nested too deeply"):
        read_hierarchy(p, ["A"])
    d, names = _hierarchy_doc()
    p.write_bytes(b"\xef\xbb\xbf" + json.dumps(d).encode())
    assert [n.name for n in read_hierarchy(p, names).nodes] == ["root", "arm", "hand"]
    m = mpz.Motion(np.zeros((3, 4, 3)), names, 100.0)
    with pytest.raises(EncoderError, match="is a folder"):
        build_hierarchy(m, tmp_path)
    # a path that is not there: said so (it was "unknown hierarchy ...: expected one of")
    for missing in (tmp_path / "none.json", str(tmp_path / "none.json"), "none.json",
                    "sub/none"):
        with pytest.raises(EncoderError, match="does not exist"):
            build_hierarchy(m, missing)
    with pytest.raises(EncoderError, match="unknown hierarchy 'tree'"):
        build_hierarchy(m, "tree")                     # a name: the known names listed


def test_two_subjects_are_not_called_a_missing_marker() -> None:
    """Two CMU subjects in one capture (S1:LFHD ... S2:LFHD ...): hierarchy="cmu41" said
    "missing []" (API review F11); it names the labels that appear twice."""
    import numpy as np

    import mpz
    from mpz.errors import EncoderError
    from mpz.synth import generate
    one = generate("walk", frames=30, seed=1)
    two = mpz.Motion(np.concatenate([one.positions, one.positions + 1000.0], axis=1),
                     [f"S1:{n}" for n in one.names] + [f"S2:{n}" for n in one.names],
                     one.rate, one.units)
    with pytest.raises(EncoderError, match="appear more than once") as err:
        mpz.encode(two, max_error=1.0, hierarchy="cmu41")
    assert "missing" not in str(err.value)


# -- pair analyses on many markers (stop 67) --------------------------------------------
@pytest.mark.parametrize(("markers", "frames"), [(1, 400), (68, 400), (256, 400), (257, 396),
                                                 (300, 291), (1024, 32), (4096, 32)])
def test_pair_frames_keep_400_up_to_256_markers_then_a_budget(markers, frames):
    """Appendix C: 400 frames while markers^2 x 400 <= 400 x 256^2, then
    floor(400 x 256^2 / markers^2), at least 32 (worked by hand: 26,214,400 // 66,049 = 396,
    // 90,000 = 291, // 1,048,576 = 25 -> 32)."""
    from mpz.hierarchy.measure import pair_frames
    assert pair_frames(markers, 400) == frames


def test_pair_analyses_of_many_markers_sample_fewer_frames(monkeypatch):
    """The auto hierarchy's distance table and the encoder's rigidity-chain scores read
    every pair on every sampled frame: 27 s of a 69 s encode of 4096 markers. Beyond 256
    markers they sample fewer frames (300 markers: 291), and up to 256 as before."""
    from mpz import encoder, keyframe
    from mpz.hierarchy import auto
    seen: dict[str, list[int]] = {"table": [], "chain": []}
    table, chain = auto._distance_sums, keyframe.chain_scores

    def table_of(x, v):
        seen["table"].append(x.shape[0])
        return table(x, v)

    def chain_of(c, ok):
        seen["chain"].append(c.shape[2])
        return chain(c, ok)

    monkeypatch.setattr(auto, "_distance_sums", table_of)
    monkeypatch.setattr(keyframe, "chain_scores", chain_of)
    rng = np.random.default_rng(3)
    for M, table_frames, chain_frames in ((300, 291, 300), (100, 400, 600)):
        x = rng.normal(0, 100, (1, M, 3)) + np.cumsum(rng.normal(0, 1, (600, 1, 3)), axis=0)
        m = mpz.Motion(x, [f"m{i}" for i in range(M)], 100.0, "mm")
        auto.auto_hierarchy(m)
        encoder.chain_scores_of(m.positions, m.valid)
        # 300 markers: 291 frames of 600 evenly spaced; every 600 // 291 = 2nd frame
        # 100 markers: 400 of 600; every 600 // 400 = 1st frame
        assert seen["table"][-1] == table_frames and seen["chain"][-1] == chain_frames
