"""Forward kinematics (spec §6.10) against a plain numpy oracle.

:func:`mpz.io.kinematics.forward` is one numba kernel (issue 15.1: 10x faster than the
numpy version it replaced, which cost a third of a BVH encode). The oracle below is that
numpy version, written from the conventions of the module docstring with whole-array
3 x 3 products; the two differ only in the order of floating-point operations, so they
agree to a few ulps of the skeleton's size. The hand-derived cases are in tests/test_io.py.
"""
from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st
import numpy as np
import pytest

from mpz.format import ChannelKind
from mpz.io.kinematics import Joint, Skeleton, _axes_matrix, axis_rotation, forward


def oracle(skel: Skeleton, v: np.ndarray) -> np.ndarray:
    """Joint positions [F, J, 3] by the module docstring's formulas, in numpy."""
    F = v.shape[0]
    starts = skel.channel_starts()
    pos = np.empty((len(skel.joints), F, 3))
    world: list[np.ndarray] = []
    eye = np.broadcast_to(np.eye(3), (F, 3, 3))
    for i, j in enumerate(skel.joints):
        cols = {c: v[:, starts[i] + k] for k, c in reversed(list(enumerate(j.channels)))}
        rots = [axis_rotation("XYZ"[c - ChannelKind.RX], skel.degrees(v[:, starts[i] + k]))
                for k, c in enumerate(j.channels) if ChannelKind.RX <= c <= ChannelKind.RZ]
        p = j.parent
        if skel.convention == "bvh":
            t = np.tile(np.asarray(j.offset, float), (F, 1))
            for k, c in enumerate(j.channels):
                if c <= ChannelKind.TZ:
                    t[:, c] += v[:, starts[i] + k]
            R = eye.copy()
            for A in rots:
                R = R @ A
            if p < 0:
                pos[i] = t
                world.append(R)
            else:
                pos[i] = pos[p] + np.einsum("fij,fj->fi", world[p], t)
                world.append(world[p] @ R)
            continue
        C = _axes_matrix(j.axis_order, [float(a) for a in skel.degrees(np.asarray(j.axis))])
        M = eye.copy()
        for A in rots:
            M = A @ M
        W_local = C @ M @ C.T
        t = np.stack([cols.get(c, np.zeros(F)) for c in
                      (ChannelKind.TX, ChannelKind.TY, ChannelKind.TZ)], 1)
        if p < 0:
            pos[i] = np.asarray(j.offset, float) + t
            world.append(W_local)
            continue
        W = world[p] @ W_local
        world.append(W)
        length = j.length + cols.get(ChannelKind.L, np.zeros(F))
        bone = np.asarray(j.direction, float)[None, :] * length[:, None]
        pos[i] = pos[p] + np.einsum("fij,fj->fi", W, bone) \
            + np.einsum("fij,fj->fi", world[p] @ C, t)
    return pos.transpose(1, 0, 2)


def _close(a: np.ndarray, b: np.ndarray, skel_size: float) -> None:
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * max(skel_size, 1.0))


@st.composite
def skeletons(draw):
    conv = draw(st.sampled_from(["bvh", "asf"]))
    n = draw(st.integers(1, 7))
    kinds = st.lists(st.sampled_from(range(7 if conv == "asf" else 6)), max_size=5)
    coord = st.floats(-50, 50, allow_nan=False)
    vec = st.tuples(coord, coord, coord)
    joints = []
    for i in range(n):
        joints.append(Joint(
            f"j{i}", -1 if i == 0 else draw(st.integers(0, i - 1)),
            tuple(draw(kinds)), offset=draw(vec), direction=draw(vec),
            length=draw(st.floats(0, 20)), axis=draw(vec),
            axis_order=draw(st.sampled_from(["XYZ", "ZYX", "YXZ", "XZY"]))))
    unit = draw(st.sampled_from(["deg", "rad"]))
    return Skeleton(conv, tuple(joints), angle_unit=unit)


@settings(max_examples=150, deadline=None)
@given(skeletons(), st.integers(1, 5), st.integers(0, 2 ** 32 - 1))
def test_forward_is_the_numpy_oracle(skel, F, seed):
    rng = np.random.default_rng(seed)
    scale = np.pi if skel.angle_unit == "rad" else 180.0
    v = rng.uniform(-1, 1, (F, skel.channel_count)) * scale
    _close(forward(skel, v), oracle(skel, v), 500.0)


def test_forward_checks_its_input_shape():
    skel = Skeleton("bvh", (Joint("A", -1, (0, 1, 2)),))
    with pytest.raises(ValueError, match="values must be"):
        forward(skel, np.zeros((4, 2)))


def test_forward_on_real_skeletons(shared_data):
    import mpz.io
    files = [*sorted((shared_data / "bvh").glob("*.bvh")),
             *sorted((shared_data / "amc").glob("*.amc"))]
    assert files
    for path in files:
        m = mpz.io.read(path)
        skel = m.extras["skeleton"]
        got, want = forward(skel, m.angles), oracle(skel, m.angles)
        _close(got, want, float(np.abs(want).max()))
