"""Skeletal motion (BVH, AMC/ASF) through MPZ 1.1: sizes and errors, and the alternatives.

    python bench/bench_skeleton.py [--quick] [--files cmu_131_03 02_01 ...] [--json out.json]

Part 1, for every BVH and AMC file of ../shared/data and each setting, one row:

- ``text``: the source text (for AMC the AMC plus its ASF, both needed), gzip -9 and
  xz -9 of that text, and ``f32`` the channels as float32 (4 bytes x frames x channels);
- the MPZ file (the reference encoder, as ``mpz encode`` runs it), its ratio against each
  of those (``/gz`` > 1 means smaller than gzip -9 of the text), and its parts: the
  skeleton chunk (skeleton + channels) and the marker layer;
- ``rot err`` and ``tr err``: the largest channel error after decoding (rotations in
  degrees, translations in the skeleton's length unit), ``pos err``: the largest
  joint-position error of the decoded channels (spec §6.10) and ``bound`` the declared one,
  ``mk err``: the marker layer's largest error (what a 1.0 decoder returns).

Settings: ``default`` (no options: ``mpz.encode(m)``, the same bytes as ``mpz encode FILE``
(with ``--units cm`` for the BVH files read as cm); channels within 0.01 (degrees or length
units), marker layer within the preview bound, ``PREVIEW_FRACTION`` of the skeleton's
size), ``1mm`` and ``5mm`` (``--max-error``: joint positions and marker layer).
BVH has no unit: cmu_10/11/14 are read as centimetres (``--units cm``, docs/io-notes.md);
cmu_131_03 has ASF-like units of 1/0.45 inch (about 5.64 cm), so "1mm" there is
0.45/25.4 of a file unit, without declaring a unit.

Part 2, the alternatives measured (channel bytes only, same files):

- the channel codec at the default steps: one block, order 2 everywhere, no wrap, against
  what the encoder does (order per channel, wrap, groups); prediction of a channel's
  residual from its parent joint's;
- per-joint rotations as quaternions or exponential maps instead of the file's Euler
  channels, each quantised so that the joint positions stay within the same bound as the
  Euler channels (1 mm), with the same lever-arm allocation and coder;
- the marker layer at the preview bound (the default encode) against the joint-position
  bound.
"""
from __future__ import annotations

import argparse
import gzip
import json
import lzma
import math
from pathlib import Path
import sys
import time

import numpy as np

from _common import shared_data_dir, shared_data_name
import mpz
from mpz import channels as ch
from mpz import skeleton as sk
from mpz.container import chunk_sizes
from mpz.decoder import read_stream
from mpz.encoder import EncodeOptions, encode_motion
import mpz.io
from mpz.io.amc import find_asf
from mpz.io.kinematics import Skeleton, _axes_matrix, axis_rotation, forward, lever_arms
from mpz.predict import residuals

#: mm per file unit of the BVH files (a guess: BVH has no unit; docs/io-notes.md)
BVH_MM = {"cmu_10_01": 10.0, "cmu_11_01": 10.0, "cmu_14_19": 10.0, "cmu_131_03": 25.4 / 0.45}
BVH_UNITS = {"cmu_10_01": "cm", "cmu_11_01": "cm", "cmu_14_19": "cm", "cmu_131_03": None}
SETTINGS = ("default", "1mm", "5mm")


def files(names: list[str] | None) -> list[Path] | int:
    """The BVH and AMC files to measure (every one, or those whose stems are ``names``), or
    the exit code, said: 0 (skipped) when the data folder holds none, 2 for a name given
    that is not there (a typo is not a skip)."""
    d = shared_data_dir()
    if d is None:
        print(f"skipped: {shared_data_name()} is absent (set MPZ_SHARED_DATA)")
        return 0
    out = sorted((d / "bvh").glob("*.bvh")) + sorted((d / "amc").glob("*.amc"))
    if not out:
        print(f"skipped: no BVH or AMC file under {d}")
        return 0
    missing = [n for n in names or [] if not any(p.stem == n for p in out)]
    if missing:
        print(f"error: no bvh/NAME.bvh or amc/NAME.amc under {d} for "
              f"{', '.join(map(repr, missing))}", file=sys.stderr)
        return 2
    return [p for p in out if not names or p.stem in names]


def text_of(path: Path) -> bytes:
    data = path.read_bytes()
    return data + Path(find_asf(path)).read_bytes() if path.suffix == ".amc" else data


def load(path: Path) -> tuple[mpz.Motion, float]:
    """The motion (units set as the CLI would) and mm per marker unit."""
    m = mpz.io.read(path)
    if path.suffix == ".bvh":
        units = BVH_UNITS[path.stem]
        if units is not None:
            m = sk.with_units(m, units)
        return m, BVH_MM[path.stem]
    return m, 1.0


def options(m: mpz.Motion, setting: str, mm: float) -> EncodeOptions:
    """What ``mpz encode`` passes for a setting (cmd_encode._skeleton_options). The default
    is no option at all: ``max_error=preview_bound`` would set ``position_error`` too
    (``resolve_bound``) and code the channels about 1 degree coarse (QA 45, item 3)."""
    if setting == "default":
        return EncodeOptions()
    e = float(setting.removesuffix("mm")) / mm            # marker units
    return EncodeOptions(max_error=e, position_error=e)


def row(path: Path, setting: str) -> dict:
    m, mm = load(path)
    text = text_of(path)
    skel = m.extras["skeleton"]
    F, C = m.angles.shape
    t0 = time.perf_counter()
    data, rep = encode_motion(m, options(m, setting, mm))
    secs = time.perf_counter() - t0
    d = mpz.decode(data)
    kinds = skel.channel_kinds()
    rot = np.array([sk.is_rotation(k) for k in kinds], bool)
    diff = np.abs(d.angles - m.angles)
    info = sk.report(data)
    assert info is not None
    sizes = chunk_sizes(data)
    skel_bytes = sizes.get("bvhs", 0) + sizes.get("asfs", 0)
    marker = np.linalg.norm(d.positions - m.positions, axis=2).max()
    pos = sk.position_error(skel, m.angles, d.angles)
    gz = len(gzip.compress(text, 9))
    xz = len(lzma.compress(text, preset=9 | lzma.PRESET_EXTREME))
    n = len(data)
    return {"file": path.name, "setting": setting, "frames": F, "channels": C,
            "text": len(text), "gzip9": gz, "xz9": xz, "f32": 4 * F * C, "mpz": n,
            "skeleton_chunk": skel_bytes, "marker_layer": n - skel_bytes,
            "ratio_text": len(text) / n, "ratio_gzip": gz / n, "ratio_xz": xz / n,
            "ratio_f32": 4 * F * C / n,
            "max_rot_err_deg": float(diff[:, rot].max(initial=0.0)) * (
                180 / math.pi if skel.angle_unit == "rad" else 1.0),
            "max_trans_err": float(diff[:, ~rot].max(initial=0.0)),
            "pos_err_mm": pos * mm, "pos_bound_mm": info["position_bound"] * mm,
            "marker_err_mm": float(marker) * mm,
            "marker_bound_mm": read_stream(data).header.error_bound * mm, "seconds": secs}


def print_rows(rows: list[dict]) -> None:
    print(f"{'file':26s} {'setting':8s} {'text':>8s} {'gzip9':>7s} {'xz9':>7s} {'f32':>7s} "
          f"{'mpz':>7s} {'/text':>6s} {'/gz':>5s} {'/xz':>5s} {'/f32':>5s} {'skel':>7s} "
          f"{'mark':>6s} {'rot err':>8s} {'tr err':>7s} {'pos err':>8s} {'bound':>7s} "
          f"{'mk err':>7s}")
    for r in rows:
        print(f"{r['file']:26s} {r['setting']:8s} {r['text']:8d} {r['gzip9']:7d} {r['xz9']:7d} "
              f"{r['f32']:7d} {r['mpz']:7d} {r['ratio_text']:6.1f} {r['ratio_gzip']:5.2f} "
              f"{r['ratio_xz']:5.2f} {r['ratio_f32']:5.2f} {r['skeleton_chunk']:7d} "
              f"{r['marker_layer']:6d} {r['max_rot_err_deg']:8.4f} {r['max_trans_err']:7.4f} "
              f"{r['pos_err_mm']:6.3f}mm {r['pos_bound_mm']:5.3f}mm "
              f"{r['marker_err_mm']:5.2f}mm")


# ------------------------------------------------------------- alternatives --
def codec_variants(m: mpz.Motion) -> dict:
    """Channel bytes at the default steps for each codec choice."""
    skel = m.extras["skeleton"]
    steps = sk.plan_steps(skel, sk.DEFAULT_CHANNEL_ERROR, sk.DEFAULT_CHANNEL_ERROR)
    x = ch.quantise(m.angles, steps)
    rots = [skel.angle_unit == "deg" and sk.is_rotation(k) for k in skel.channel_kinds()]
    plans = ch.plan(x, steps, rots)
    e = ch.coded_values(x, plans)
    out = {}

    def one_block(v: np.ndarray) -> int:
        data = ch._encode_groups(v, np.zeros(v.shape[1], np.int64))
        assert data is not None                       # no limit: always coded
        return len(data)

    out["one block, order 2, no wrap"] = one_block(residuals(x, 2))
    out["one block, order per channel, wrap"] = one_block(e)
    out["groups, order per channel, wrap (kept)"] = len(ch.group(e)[1])
    # the parent joint's residual as a prediction, where it helps
    joint = skel.channel_joints()
    kinds = skel.channel_kinds()
    where = {(joint[c], kinds[c]): c for c in range(len(kinds))}
    ep = e.copy()
    for c in range(len(kinds)):
        p = skel.joints[joint[c]].parent
        k = where.get((p, kinds[c]))
        if k is not None and np.abs(e[:, c] - e[:, k]).sum() < np.abs(e[:, c]).sum():
            ep[:, c] = e[:, c] - e[:, k]
    out["groups + parent prediction"] = len(ch.group(ep)[1])
    return out


def _local_rotations(skel: Skeleton, values: np.ndarray) -> list[np.ndarray | None]:
    """Per joint, its rotation channels as matrices [F, 3, 3] (None without any)."""
    starts = skel.channel_starts()
    out: list[np.ndarray | None] = []
    for i, j in enumerate(skel.joints):
        rk = [(k, c) for k, c in enumerate(j.channels) if sk.is_rotation(c)]
        if not rk:
            out.append(None)
            continue
        R = np.broadcast_to(np.eye(3), (values.shape[0], 3, 3)).copy()
        for k, c in rk:
            a = skel.degrees(values[:, starts[i] + k])
            Rk = axis_rotation("XYZ"[c - 3], a)
            # BVH: listed order, left to right; ASF: the first listed is applied first
            R = R @ Rk if skel.convention == "bvh" else Rk @ R
        out.append(R)
    return out


def _fk_local(skel: Skeleton, values: np.ndarray, local: list[np.ndarray | None]) -> np.ndarray:
    """Forward kinematics with the joints' rotation channels replaced by ``local``."""
    F = values.shape[0]
    if skel.convention == "bvh":
        pos = np.empty((len(skel.joints), F, 3))
        rot = np.empty((len(skel.joints), F, 3, 3))
        starts = skel.channel_starts()
        for i, j in enumerate(skel.joints):
            t = np.broadcast_to(np.asarray(j.offset), (F, 3)).copy()
            for k, c in enumerate(j.channels):
                if c <= 2:
                    t[:, c] += values[:, starts[i] + k]
            R = local[i] if local[i] is not None else np.broadcast_to(np.eye(3), (F, 3, 3))
            if j.parent < 0:
                pos[i], rot[i] = t, R
            else:
                pos[i] = pos[j.parent] + np.einsum("fij,fj->fi", rot[j.parent], t)
                rot[i] = rot[j.parent] @ R
        return pos.transpose(1, 0, 2)
    starts = skel.channel_starts()
    pos = np.empty((len(skel.joints), F, 3))
    world: list[np.ndarray] = []
    for i, j in enumerate(skel.joints):
        C = _axes_matrix(j.axis_order, [float(a) for a in skel.degrees(np.asarray(j.axis))])
        M = local[i] if local[i] is not None else np.broadcast_to(np.eye(3), (F, 3, 3))
        t = np.zeros((F, 3))
        for k, c in enumerate(j.channels):
            if c <= 2:
                t[:, c] = values[:, starts[i] + k]
        if j.parent < 0:
            pos[i] = np.asarray(j.offset) + t
            world.append(C @ M @ C.T)
            continue
        W = world[j.parent] @ C @ M @ C.T
        world.append(W)
        pos[i] = pos[j.parent] + np.einsum("fij,j->fi", W, np.asarray(j.direction) * j.length)
    return pos.transpose(1, 0, 2)


def _quat(R: np.ndarray) -> np.ndarray:
    """Unit quaternions (w, x, y, z) of rotation matrices, sign-continuous over time."""
    from scipy.spatial.transform import Rotation
    q = Rotation.from_matrix(R).as_quat()[:, [3, 0, 1, 2]]
    for t in range(1, len(q)):
        if np.dot(q[t], q[t - 1]) < 0:
            q[t] = -q[t]
    return q


def _expmap(R: np.ndarray) -> np.ndarray:
    """Rotation vectors, continuous over time (a jump of 2 pi along the axis is undone)."""
    from scipy.spatial.transform import Rotation
    v = Rotation.from_matrix(R).as_rotvec()
    for t in range(1, len(v)):
        best = v[t]
        n = np.linalg.norm(v[t])
        if n > 1e-9:
            for k in (-1, 1):
                alt = v[t] * (1 + k * 2 * math.pi / n)
                if np.linalg.norm(alt - v[t - 1]) < np.linalg.norm(best - v[t - 1]):
                    best = alt
        v[t] = best
    return v


def representation_bytes(m: mpz.Motion, target: float) -> dict:
    """Channel bytes of Euler, quaternion and exponential-map rotations, each at the
    coarsest lever-arm-weighted steps that keep the joint positions within ``target``
    (marker units); the translation channels at the Euler steps in all three."""
    from scipy.spatial.transform import Rotation
    skel = m.extras["skeleton"]
    values = m.angles
    scale = sk.marker_scale(skel)
    euler_steps, _ = sk.steps_for_position(skel, values, target, None, None)
    _, coded = sk.code_channels(values, skel, euler_steps)
    out = {"euler (kept)": len(coded)}
    kinds = skel.channel_kinds()
    lin = [c for c, k in enumerate(kinds) if not sk.is_rotation(k)]
    lin_steps = [euler_steps[c] for c in lin]
    lin_x = ch.quantise(values[:, lin], lin_steps) if lin else np.zeros((len(values), 0), int)
    lin_back = ch.dequantise(lin_x, [_coding(s) for s in lin_steps])
    v_lin = values.copy()
    v_lin[:, lin] = lin_back
    local = _local_rotations(skel, values)
    arms = lever_arms(skel, forward(skel, values)) * scale
    joints = [i for i, r in enumerate(local) if r is not None]
    ref = forward(skel, values) * scale
    for name, to, back, per in (
            ("quaternion", _quat, lambda q: Rotation.from_quat(
                (q / np.linalg.norm(q, axis=1, keepdims=True))[:, [1, 2, 3, 0]]).as_matrix(), 4),
            ("expmap", _expmap, lambda v: Rotation.from_rotvec(v).as_matrix(), 3)):
        comps = {i: to(local[i]) for i in joints}

        def attempt(kappa: float, comps=comps, back=back):
            rec = list(local)
            ints = []
            for i in joints:
                s = kappa / max(arms[i], 1e-9)            # radians-ish per component
                q = np.floor(comps[i] / s + 0.5).astype(np.int64)
                ints.append(q)
                rec[i] = back(q * s)
            err = np.linalg.norm(_fk_local(skel, v_lin, rec) * scale - ref, axis=2).max()
            return err, ints

        lo, hi = 0.0, target
        while attempt(hi)[0] <= target:
            lo, hi = hi, hi * 2
        for _ in range(25):
            mid = (lo + hi) / 2 if lo else hi / 2
            if attempt(mid)[0] <= target:
                lo = mid
            else:
                hi = mid
        _, ints = attempt(lo)
        x = np.concatenate([*ints, lin_x], axis=1) if ints else lin_x
        e = residuals(x, 2)
        out[name] = len(ch.group(e)[1])
        assert per in (3, 4)
    return out


def _coding(s: ch.Step):
    from mpz.chunks.skeleton import ChannelCoding
    return ChannelCoding(s.mantissa, s.digits, 0, 0, 0, 0)


def marker_layer_bytes(m: mpz.Motion, mm: float) -> dict:
    """Marker layer bytes at the preview bound and at the default joint-position bound."""
    def skeleton_bytes(data: bytes) -> int:
        sizes = chunk_sizes(data)
        return sizes.get("bvhs", 0) + sizes.get("asfs", 0)

    out = {}
    data, _ = encode_motion(m, EncodeOptions())          # the default: the preview bound
    info = sk.report(data)
    assert info is not None
    out["preview (kept)"] = (len(data) - skeleton_bytes(data), sk.preview_bound(m) * mm)
    pos = float(info["position_bound"])
    data2, _ = encode_motion(m, EncodeOptions(max_error=pos, keep_skeleton=True))
    out["at the position bound"] = (len(data2) - skeleton_bytes(data2), pos * mm)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--files", nargs="*", help="file stems (default: every BVH and AMC)")
    ap.add_argument("--quick", action="store_true", help="default setting only, no part 2")
    ap.add_argument("--json", help="write the rows here")
    args = ap.parse_args(argv)
    paths = files(args.files)
    if isinstance(paths, int):
        return paths
    rows = [row(p, s) for p in paths for s in (("default",) if args.quick else SETTINGS)]
    print_rows(rows)
    worst = min(r["ratio_gzip"] for r in rows if r["setting"] == "default")
    print(f"\nbar (smaller than gzip -9 of the text at the default, every file): "
          f"{'met' if worst > 1 else 'NOT met'}, smallest text-gzip/mpz ratio {worst:.2f}")
    alt: dict = {}
    if not args.quick:
        print("\nchannel codec at the default steps (channel bytes):")
        for p in paths:
            m, mm = load(p)
            v = codec_variants(m)
            alt.setdefault(p.name, {})["codec"] = v
            print(f"  {p.name:26s} " + ", ".join(f"{k}: {n}" for k, n in v.items()))
        print("\nrotations as Euler channels, quaternions or exponential maps, joint positions "
              "within 1 mm (channel bytes):")
        for p in paths:
            m, mm = load(p)
            v = representation_bytes(m, 1.0 / mm)
            alt[p.name]["representation"] = v
            print(f"  {p.name:26s} " + ", ".join(f"{k}: {n}" for k, n in v.items()))
        print("\nmarker layer (bytes, bound):")
        for p in paths:
            m, mm = load(p)
            v = marker_layer_bytes(m, mm)
            alt[p.name]["marker_layer"] = v
            print(f"  {p.name:26s} " + ", ".join(f"{k}: {n} B within {b:.3f} mm"
                                                  for k, (n, b) in v.items()))
    if args.json:
        Path(args.json).write_text(json.dumps({"rows": rows, "alternatives": alt}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
