"""Regenerate the MPZ conformance vectors, byte for byte.

Usage: ``python -m mpz.tools.make_vectors [--out conformance/vectors]``

Strategy: every vector comes from seeded synthetic motion (:mod:`mpz.synth`)
or from integers chosen here. Some are written by the reference encoder; most
are *built by hand*, chunk by chunk, with :func:`mpz.container.build_chunk`,
:class:`mpz.entropy.BlockEncoder` and :func:`mpz.predict.residuals`, so that
every field value that changes decoding appears (predictor orders 0/1/2,
smoothing 0..16, residual scale g > 1, base 0 and 1, pattern scale > 1, ...),
including values the encoder would never choose. Invalid vectors start from a
small valid file and change exactly one thing; CRCs are recomputed after the
change unless the CRC is the thing being broken. Expected outputs are the
reference decoder's, frozen as ``.npy``. The manifest records provenance,
hashes and the tolerances of spec §7.1.

Tests never call this; they only read what it wrote.
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
import struct
import sys

import numpy as np

import mpz
from mpz import container
from mpz.conformance import manifest as mf
from mpz.decoder import UNIT_CODES, decode_integers, decode_mask, read_stream, to_positions
from mpz.entropy import BlockEncoder
from mpz.normalize import denormalize, normalize, segment_starts
from mpz.predict import residuals
from mpz.smooth import smooth_boundaries
from mpz.spec.grammar import PAYLOADS, SIGNATURE

ROOT_PARENT = 0xFFFF
UNITS = {"": 0, "mm": 1, "cm": 2, "m": 3, "in": 4}


# ================================================================ building ==
def rc(*blocks) -> bytes:
    """One range-coded payload from blocks given as (values [T, M, A], kwargs)."""
    enc = BlockEncoder()
    for vals, kw in blocks:
        enc.block(vals, **kw)
    return enc.finish()


def payload(ctype: str, fields) -> bytes:
    return PAYLOADS[ctype.encode()].build(fields)


def frame(ctype: str, body: bytes) -> bytes:
    """Type, length, payload, correct CRC."""
    t = ctype.encode("latin-1")
    return (struct.pack("<4sI", t, len(body)) + body
            + struct.pack("<I", container.crc32(t, body)))


def assemble(chunks) -> bytes:
    """Signature + chunks given as [type, payload] pairs, every CRC correct."""
    return SIGNATURE + b"".join(frame(t, p) for t, p in chunks)


class Design:
    """An MPZ file described by its integer content, built chunk by chunk.

    Attributes hold the header fields; ``nodes`` is a list of
    (parent, ref, members, weights); ``layers[i]`` describes node i (see
    :meth:`node`); the root track is ``root = (order, ints [F, 3])``.
    """

    def __init__(self, F, names, *, rate=120.0, units="mm", step=1.0, offset=(0.0, 0.0, 0.0),
                 smoothing=0, residual=True, error_metric=0, error_bound=0.0, bits=None,
                 version=(1, 0), flags=None):
        self.F, self.names, self.rate, self.units = F, list(names), rate, units
        self.step, self.offset, self.smoothing = step, tuple(offset), smoothing
        self.residual, self.error_metric, self.error_bound = residual, error_metric, error_bound
        self.bits, self.version, self.flags = bits, version, flags
        self.nodes = []
        self.layers = {}
        self.root = None
        self.valid = None
        self.ancillary = []            # (type, payload) placed before MEND
        self.ancillary_early = []      # (type, payload) placed right after MHDR
        self.source = None             # the Motion it codes, if any

    def node(self, parent, ref, members, *, patt=None, segs=None, resi=None, weights=None):
        """Add a node. ``patt`` = dict(K, L, scale, order, values [K*L, n, 3]) or None;
        ``segs`` = (index [S], counts [S]); ``resi`` = dict(base, order, scale, values [F, n, 3])."""
        self.nodes.append((parent, ref, list(members), weights or [1.0] * len(members)))
        self.layers[len(self.nodes) - 1] = {"patt": patt, "segs": segs, "resi": resi}

    def chunks(self) -> list:
        F, M = self.F, len(self.names)
        flags = self.flags if self.flags is not None else (1 if self.residual else 0)
        hdr = {"version_major": self.version[0], "version_minor": self.version[1],
               "flags": flags, "frame_count": F, "marker_count": M,
               "node_count": len(self.nodes), "rate": self.rate, "units": UNITS[self.units],
               "error_metric": self.error_metric, "error_bound": self.error_bound,
               "smoothing": self.smoothing}
        out = [["MHDR", payload("MHDR", hdr)]]
        out += [list(c) for c in self.ancillary_early]
        out.append(["MNAM", payload("MNAM", {"count": M, "names": self.names})])
        out.append(["HIER", payload("HIER", {"count": len(self.nodes), "nodes": [
            {"parent": p, "ref": r, "member_count": len(ms), "members": ms,
             "weights": [float(w) for w in ws]} for p, r, ms, ws in self.nodes]})])
        out.append(["QUNT", payload("QUNT", {"step": self.step, "offset": list(self.offset),
                                             "bits": self.bits or 31})])
        if self.valid is not None:
            out.append(["MASK", payload("MASK", {"coded": rc(
                ((~self.valid).astype(np.int64)[:, :, None], {"signed": False}))})])
        order, vals = self.root
        out.append(["ROOT", payload("ROOT", {"order": order, "coded": rc(
            (residuals(vals[:, None, :], order), {}))})])
        for i in range(1, len(self.nodes)):
            lay = self.layers[i]
            p = lay["patt"]
            if p is None or p["K"] == 0:
                out.append(["PATT", payload("PATT", {"node": i, "pattern_count": 0, "length": 1,
                                                     "scale": 1, "order": 0, "coded": rc()})])
            else:
                out.append(["PATT", payload("PATT", {
                    "node": i, "pattern_count": p["K"], "length": p["L"], "scale": p["scale"],
                    "order": p["order"], "coded": rc((residuals(p["values"], p["order"], p["L"]),
                                                      {"period": p["L"]}))})])
                index, counts = lay["segs"]
                v = np.stack([index, np.asarray(counts) - p["L"]], axis=1)[:, None, :]
                out.append(["SEGS", payload("SEGS", {"node": i, "segment_count": len(index),
                                                     "coded": rc((v, {}))})])
            if self.residual:
                r = lay["resi"]
                out.append(["RESI", payload("RESI", {
                    "node": i, "base": r["base"], "order": r["order"], "scale": r["scale"],
                    "coded": rc((residuals(r["values"], r["order"]), {}))})])
        out += [list(c) for c in self.ancillary]
        out.append(["MEND", b""])
        return out

    def build(self) -> bytes:
        """Assemble; with bits=None, set QUNT bits to the smallest value that holds (§4.4)."""
        data = assemble(self.chunks())
        if self.bits is None:
            s = read_stream(data)
            q = decode_integers(s)
            self.bits = max(1, int(np.abs(q).max(initial=0)).bit_length())
            data = assemble(self.chunks())
        if self.source is not None and self.error_metric == 1:
            # a declared bound must hold against the motion the file was made from
            err = mpz.max_error(self.source, mpz.decode(data))
            assert err <= self.error_bound, (err, self.error_bound)
        return data


def quantise(x, step, offset):
    return np.floor((x - np.asarray(offset)) / step + 0.5).astype(np.int64)


def make_patterns(local, L, K, scale, rng, jitter=3):
    """A simple pattern layer for ``local[F, n, 3]`` (grid units): segments of
    L +- jitter frames, the first K segments as patterns, each segment mapped to the
    nearest pattern. Returns (patt dict without order, (index, counts), prediction)."""
    F = local.shape[0]
    counts = []
    left = F
    while left > 0:
        c = int(L + rng.integers(-jitter, jitter + 1)) if jitter else L
        c = max(1, min(c, left))
        if left - c < max(1, L // 2) and left - c > 0:
            c = left
        counts.append(c)
        left -= c
    counts = np.asarray(counts, np.int64)
    starts = segment_starts(counts)
    segs = normalize(local.astype(np.float64), starts, counts, L)       # [S, L, n, 3]
    S = segs.shape[0]
    K = min(K, S)
    centres = segs[:K]
    d = ((segs[:, None] - centres[None]) ** 2).reshape(S, K, -1).sum(-1)
    index = d.argmin(1).astype(np.int64)
    pats = np.stack([segs[index == k].mean(0) if (index == k).any() else centres[k]
                     for k in range(K)])
    v = np.floor(pats / scale + 0.5).astype(np.int64)                    # [K, L, n, 3]
    return ({"K": K, "L": L, "scale": scale, "values": v.reshape(K * L, *v.shape[2:])},
            (index, counts), v * scale)


def design_from_motion(motion, *, step, nodes, smoothing=0, residual=True, root_order=2,
                       patterns=None, resi=None, rate=None, units=None, seed=0, offset=None,
                       error_metric=None):
    """A Design coding ``motion`` with the hierarchy ``nodes`` = [(parent, ref, members)].

    ``patterns[i]`` = dict(L, K, scale, order[, jitter]) gives node i a pattern
    layer; ``resi[i]`` = dict(base, order, scale) its residual layer (default
    base 0, order 2, scale 1). Nodes are coded in closed loop against the
    decoded parent reference, as the reference encoder does.
    """
    rng = np.random.default_rng(seed)
    x = mpz.encoder.fill_gaps(motion.positions, motion.valid)
    F, M = motion.n_frames, motion.n_markers
    if offset is None:
        lo, hi = x.reshape(-1, 3).min(0), x.reshape(-1, 3).max(0)
        offset = tuple(float(v) for v in np.round((lo + hi) / 2.0))
    t = quantise(x, step, offset)
    d = Design(F, motion.names, rate=motion.rate if rate is None else rate,
               units=motion.units if units is None else units, step=step, offset=offset,
               smoothing=smoothing, residual=residual)
    d.source = motion
    qhat = np.zeros((F, M, 3), np.int64)
    p0, r0, m0 = nodes[0]
    d.nodes.append((ROOT_PARENT, r0, list(m0), [1.0]))
    d.layers[0] = {}
    d.root = (root_order, t[:, r0])
    qhat[:, r0] = t[:, r0]
    for i in range(1, len(nodes)):
        parent, ref, members = nodes[i]
        pref = nodes[parent][1]
        local = t[:, members] - qhat[:, pref][:, None, :]
        pred = np.zeros_like(local)
        patt = segs = None
        pspec = (patterns or {}).get(i)
        if pspec:
            patt, segs, pv = make_patterns(local, pspec["L"], pspec["K"], pspec["scale"], rng,
                                           pspec.get("jitter", 3))
            patt["order"] = pspec["order"]
            pred = smooth_boundaries(denormalize(pv, segs[0], segs[1]),
                                     segment_starts(segs[1]), smoothing)
        r = None
        dec_local = pred
        if residual:
            rs = {"base": 0, "order": 2, "scale": 1}
            rs.update((resi or {}).get(i, {}))
            g = rs["scale"]
            if rs["base"] == 1:
                w = np.floor(t[:, members] / g + 0.5).astype(np.int64)
                dec_local = g * w - qhat[:, pref][:, None, :]
            else:
                w = np.floor((local - pred) / g + 0.5).astype(np.int64)
                dec_local = pred + g * w
            r = dict(rs, values=w)
        d.node(parent, ref, members, patt=patt, segs=segs, resi=r)
        qhat[:, members] = dec_local + qhat[:, pref][:, None, :]
    if not motion.valid.all():
        d.valid = motion.valid.copy()
    # declare the bound the file actually achieves (rounded up), or none when lossy
    xd = qhat * step + np.asarray(offset)
    err = np.linalg.norm(xd - x, axis=2)[motion.valid]
    if error_metric is None:
        error_metric = 1 if residual else 0
    if error_metric:
        d.error_metric = 1
        d.error_bound = float(math.ceil(float(err.max(initial=0.0)) * 1000.0 + 1) / 1000.0)
    return d


# ================================================================ the set ==
class VectorSet:
    def __init__(self, out: Path):
        self.out = out
        self.entries = []
        self.encoder_inputs = []

    def _write(self, rel: str, data: bytes) -> str:
        p = self.out / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(data)
        return mf.sha256_file(p)

    def valid(self, group, name, data, description, features, sections, provenance, file=None):
        """A vector that must decode; the expected output is the reference decoder's."""
        assert group in ("valid", "uncommon")
        s = read_stream(data)
        valid = decode_mask(s)
        q = decode_integers(s)
        x = to_positions(s, q, valid)
        # cross-check against the public API
        m = mpz.decode(data)
        assert np.array_equal(np.isnan(m.as_nan()), np.isnan(x))
        assert np.array_equal(m.as_nan()[valid], x[valid])
        if file is None:
            rel = f"{group}/{name}.mpz"
            sha = self._write(rel, data)
            npy_rel = f"{group}/{name}.npy"
        else:                                   # a file written by someone else: never touched
            rel = file
            sha = mf.sha256_file(self.out / rel)
            npy_rel = str(Path(file).with_suffix(".npy"))
        import io
        buf = io.BytesIO()
        np.save(buf, np.ascontiguousarray(x, dtype="<f8"), allow_pickle=False)
        npy_sha = self._write(npy_rel, buf.getvalue())
        h = s.header
        maxabs = float(np.abs(x[valid]).max(initial=0.0))
        types = []
        for c in s.chunks:
            if c.type not in types:
                types.append(c.type)
        feats = {"chunks": types}
        feats.update(features)
        self.entries.append({
            "name": name, "file": rel, "sha256": sha, "size": len(data), "group": group,
            "description": description, "provenance": provenance,
            "spec_sections": sorted(set(mf.exercised_sections(s)) | set(sections),
                                    key=mf.section_key),
            "features": feats, "expected": "decode", "expected_error": None,
            "expected_output": {"file": npy_rel, "sha256": npy_sha, "dtype": "<f8",
                                "shape": list(x.shape)},
            "integer_layer_digest": mf.intlayer_digest(q, valid),
            "tolerances": mf.tolerances(s.quant.step, maxabs),
            "header": {"frames": h.frame_count, "markers": h.marker_count, "rate": h.rate,
                       "names": list(s.names), "units": UNIT_CODES[h.units],
                       "units_code": h.units, "error_metric": h.error_metric,
                       "error_bound": h.error_bound, "step": s.quant.step,
                       "offset": list(s.quant.offset), "bits": s.quant.bits,
                       "smoothing": h.smoothing, "residual": bool(h.flags & 1),
                       "version": [h.version_major, h.version_minor]},
        })

    def invalid(self, name, data, description, corruption, risk, error, sections, features=None):
        """A vector that must be rejected; checks the reference raises ``error``."""
        try:
            mpz.decode(data)
        except mpz.MPZError as exc:
            got = type(exc).__name__
            if got != error:
                raise AssertionError(f"{name}: reference raised {got} ({exc}), expected {error}")
            message = str(exc)
        else:
            raise AssertionError(f"{name}: the reference decoder accepts it")
        rel = f"invalid/{name}.mpz"
        sha = self._write(rel, data)
        self.entries.append({
            "name": name, "file": rel, "sha256": sha, "size": len(data), "group": "invalid",
            "description": description, "provenance": "hand-built from the base file "
            "(make_vectors.invalid_vectors), one change, CRCs recomputed unless noted",
            "corruption": corruption, "risk": risk,
            "spec_sections": sorted(set(sections), key=mf.section_key),
            "features": features or {}, "expected": "reject", "expected_error": error,
            "reference_message": message,
        })

    def encoder_input(self, name, motion, max_errors, description):
        import io
        buf = io.BytesIO()
        np.save(buf, np.ascontiguousarray(motion.as_nan(), dtype="<f8"), allow_pickle=False)
        rel = f"inputs/{name}.npy"
        sha = self._write(rel, buf.getvalue())
        side = {"names": list(motion.names), "rate": motion.rate, "units": motion.units}
        srel = f"inputs/{name}.json"
        ssha = self._write(srel, (json.dumps(side, indent=1) + "\n").encode())
        self.encoder_inputs.append({"name": name, "input": rel, "sha256": sha, "sidecar": srel,
                                    "sidecar_sha256": ssha, "max_errors": list(max_errors),
                                    "description": description,
                                    "frames": motion.n_frames, "markers": motion.n_markers})

    def write_manifest(self):
        man = {"schema_version": mf.SCHEMA_VERSION, "format": "MPZ 1.0",
               "generator": "python -m mpz.tools.make_vectors",
               "tolerance_rule": "spec §7.1: max_abs = step * 2^-20 + max|x| * 2^-50 over valid "
                                 "expected coordinates; rms = max_abs",
               "integer_layer_digest_rule": "sha256 of q as little-endian int64 [F, M, 3] C order, "
                                            "then the validity mask as uint8 [F, M] (1 = valid)",
               "vectors": self.entries, "encoder_inputs": self.encoder_inputs}
        mf.validate(man)
        (self.out / mf.MANIFEST_NAME).write_text(json.dumps(man, indent=1, ensure_ascii=False)
                                                 + "\n", encoding="utf-8")




# ------------------------------------------------------------ valid group --
def _synth(kind, frames, markers=None, seed=0, **kw):
    from mpz.synth import generate
    return generate(kind, frames=frames, seed=seed, markers=markers, **kw)


#: a small hand-made hierarchy over the first 12 CMU markers
#: (LFHD RFHD LBHD RBHD C7 T10 CLAV STRN RBAC LSHO LUPA LELB)
H12 = [(None, 4, [4]),                       # root: C7
       (0, 0, [0, 1, 2, 3]),                 # head, ref LFHD
       (0, 6, [5, 6, 7, 8]),                 # torso, ref CLAV
       (2, 9, [9]),                          # left shoulder, child of torso
       (3, 10, [10, 11])]                    # left upper arm, grandchild


def valid_vectors(vs: VectorSet):
    from mpz.encoder import summary_fields
    # v01: the reference encoder, bounded, full 41-marker set
    m = _synth("walk", 90, seed=1)
    data = mpz.encode(m, max_error=1.0)
    vs.valid("valid", "v01-walk-bounded-1mm", data,
             "41-marker walk from the reference encoder with a 1 mm bound: patterns where they "
             "pay, residual layer everywhere (base 0 and base 1), metadata",
             {"encoder": "mpz.encode(max_error=1.0)"}, ["§4.7", "§4.8", "§4.9", "§4.11", "§6.3",
                                                        "§6.4", "§6.5"],
             "mpz.synth.generate('walk', frames=90, seed=1) -> mpz.encode(max_error=1.0)")
    # v02: encoder, lossy (no residual layer, no declared bound), gaps
    m = _synth("jump", 90, markers=20, seed=2, gap_fraction=0.08)
    data = mpz.encode(m, smoothing=3, metadata={"take": "v02"})
    vs.valid("valid", "v02-jump-lossy-gaps", data,
             "20-marker jump from the reference encoder without a bound: pattern layer only "
             "(flags 0, error_metric 0), smoothing 3, 8% gaps in a MASK chunk",
             {"encoder": "mpz.encode(smoothing=3)", "residual": False, "error_metric": 0,
              "smoothing": 3}, ["§4.5", "§4.7", "§4.8", "§4.11", "§6.1", "§6.3", "§6.4"],
             "mpz.synth.generate('jump', frames=90, markers=20, seed=2, gap_fraction=0.08) -> "
             "mpz.encode(smoothing=3)")
    # v03: encoder with the optimal-partition summary
    m = _synth("wave", 60, markers=12, seed=3)
    data = mpz.encode(m, max_error=2.0, summary=(2, 5))
    vs.valid("valid", "v03-wave-bounded-2mm-summary", data,
             "12-marker wave from the reference encoder, 2 mm bound, with the ancillary smry "
             "chunk (2 and 5 segments) that decoders may ignore",
             {"encoder": "mpz.encode(max_error=2.0, summary=(2, 5))"},
             ["§4.9", "§4.10", "§4.11", "§6.5"],
             "mpz.synth.generate('wave', frames=60, markers=12, seed=3) -> "
             "mpz.encode(max_error=2.0, summary=(2, 5))")

    # v04: orders 0 / 1 / 2 in ROOT and RESI, residual only (pattern_count 0)
    m = _synth("walk", 48, markers=12, seed=4)
    d = design_from_motion(m, step=0.5, nodes=H12, root_order=0,
                           resi={1: {"order": 0}, 2: {"order": 1}, 3: {"order": 2},
                                 4: {"order": 1}})
    vs.valid("valid", "v04-orders-residual-only", d.build(),
             "hand-built: ROOT order 0, RESI orders 0/1/2 (base 0, g 1), no patterns "
             "(pattern_count 0 on every node), a grandchild node, units mm",
             {"root_order": 0, "resi_orders": [0, 1, 2], "resi_base": [0], "resi_scale": [1],
              "pattern_count": [0], "units_code": 1, "smoothing": 0},
             ["§4.9", "§6.5"], "hand-built from mpz.synth walk (frames=48, markers=12, seed=4)")
    # v05: patterns only (lossy), pattern scale 3, pattern orders 0/1/2, smoothing 0, cm
    m = _synth("walk", 72, markers=12, seed=5)
    m = mpz.Motion(m.positions / 10.0, m.names, m.rate, "cm")
    d = design_from_motion(m, step=0.05, nodes=H12, root_order=1, residual=False,
                           patterns={i: {"L": 12, "K": 3, "scale": 3, "order": i % 3}
                                     for i in range(1, 5)})
    vs.valid("valid", "v05-patterns-scale3-lossy-cm", d.build(),
             "hand-built, lossy: pattern layer only (flags 0), pattern scale 3, PATT orders "
             "0/1/2, segments of 9..15 frames re-timed to L = 12, smoothing 0, ROOT order 1, "
             "units cm",
             {"root_order": 1, "patt_orders": [0, 1, 2], "patt_scale": [3], "smoothing": 0,
              "residual": False, "units_code": 2},
             ["§4.7", "§4.8", "§6.3"], "hand-built from mpz.synth walk (frames=72, markers=12, "
             "seed=5), positions / 10 as cm")
    # v06: patterns + residual with g = 2, smoothing 4, metres
    m = _synth("jump", 80, markers=12, seed=6)
    m = mpz.Motion(m.positions / 1000.0, m.names, m.rate, "m")
    d = design_from_motion(m, step=0.0004, nodes=H12, root_order=2, smoothing=4,
                           patterns={1: {"L": 10, "K": 2, "scale": 2, "order": 1},
                                     2: {"L": 16, "K": 3, "scale": 1, "order": 2},
                                     4: {"L": 8, "K": 4, "scale": 5, "order": 0}},
                           resi={1: {"scale": 2, "order": 1}, 2: {"scale": 3, "order": 2},
                                 3: {"scale": 1, "order": 0}, 4: {"scale": 2, "order": 2}})
    vs.valid("valid", "v06-patterns-residual-g2-smooth4-m", d.build(),
             "hand-built: pattern layer plus residual layer with g = 2 and 3 (base 0), "
             "boundary smoothing h = 4, pattern scales 1/2/5, units m",
             {"smoothing": 4, "resi_scale": [1, 2, 3], "resi_base": [0], "patt_scale": [1, 2, 5],
              "patt_orders": [0, 1, 2], "resi_orders": [0, 1, 2], "units_code": 3},
             ["§4.7", "§4.8", "§4.9", "§6.3", "§6.4", "§6.5"],
             "hand-built from mpz.synth jump (frames=80, markers=12, seed=6), positions / 1000 "
             "as m")
    # v07: absolute residuals (base 1) with g = 3, inches, gaps
    m = _synth("wave", 50, markers=12, seed=7, gap_fraction=0.1)
    m = mpz.Motion(m.positions / 25.4, m.names, m.rate, "in", m.valid)
    d = design_from_motion(m, step=0.02, nodes=H12, root_order=2,
                           resi={1: {"base": 1, "scale": 3, "order": 2},
                                 2: {"base": 1, "scale": 1, "order": 1},
                                 3: {"base": 0, "scale": 3, "order": 2},
                                 4: {"base": 1, "scale": 2, "order": 0}})
    vs.valid("valid", "v07-absolute-residual-base1-g3-in", d.build(),
             "hand-built: residual layers with base 1 (absolute grid values, no parent added) "
             "next to base 0, g = 1/2/3, 10% gaps, units in",
             {"resi_base": [0, 1], "resi_scale": [1, 2, 3], "resi_orders": [0, 1, 2],
              "units_code": 4, "mask": True},
             ["§4.5", "§4.9", "§6.1", "§6.5", "§6.6"],
             "hand-built from mpz.synth wave (frames=50, markers=12, seed=7, gap_fraction=0.1), "
             "positions / 25.4 as in")
    # v08: units unknown (0), smry + meta placed early and late, non-zero offsets
    m = _synth("static", 40, markers=6, seed=8)
    m = mpz.Motion(m.positions, m.names, m.rate, "")
    d = design_from_motion(m, step=0.25, nodes=[(None, 0, [0]), (0, 1, [1, 2, 3]),
                                                (1, 4, [4, 5])],
                           resi={1: {"order": 1}, 2: {"order": 2}})
    smry = summary_fields(m, (1, 3), "positions", 0.25)
    d.ancillary_early.append(("meta", payload("meta", {"count": 2, "entries": [
        {"key": "subject", "value": "synthetic"}, {"key": "note", "value": "ünïcödé ✓"}]})))
    d.ancillary.append(("smry", payload("smry", smry)))
    vs.valid("valid", "v08-units-unknown-meta-smry", d.build(),
             "hand-built: units code 0 (unknown), a meta chunk right after MHDR (ancillary "
             "chunks may sit anywhere after MHDR) with UTF-8 values, a smry chunk before MEND",
             {"units_code": 0, "ancillary_positions": ["after MHDR", "before MEND"]},
             ["§2.3", "§4.9", "§4.10", "§4.11", "§6.5"],
             "hand-built from mpz.synth static (frames=40, markers=6, seed=8)")


# --------------------------------------------------------- uncommon group --
def uncommon_vectors(vs: VectorSet):
    rng = np.random.default_rng(1000)
    # u01: one frame
    m = _synth("walk", 1, markers=6, seed=11)
    d = design_from_motion(m, step=0.5, nodes=[(None, 0, [0]), (0, 1, [1, 2, 3, 4, 5])],
                           root_order=2, resi={1: {"order": 2}})
    vs.valid("uncommon", "u01-one-frame", d.build(),
             "F = 1: every predictor has only its first row; order 2 on one frame",
             {"frames": 1}, ["§4.9", "§6.5"], "hand-built from mpz.synth walk (frames=1)")
    # u02: one marker (no node but the root)
    m = _synth("walk", 30, markers=1, seed=12)
    d = design_from_motion(m, step=0.5, nodes=[(None, 0, [0])], root_order=1)
    vs.valid("uncommon", "u02-one-marker", d.build(),
             "M = 1, N = 1: the file is the root track only (no PATT/SEGS/RESI chunks), flags 1",
             {"markers": 1, "nodes": 1}, [], "hand-built from mpz.synth walk (markers=1)")
    # u03: a marker that is a gap throughout
    m = _synth("walk", 30, markers=6, seed=13)
    valid = m.valid.copy()
    valid[:, 3] = False
    valid[5:9, 1] = False
    m = mpz.Motion(m.positions, m.names, m.rate, m.units, valid)
    d = design_from_motion(m, step=0.5, nodes=[(None, 0, [0]), (0, 1, [1, 2, 3, 4, 5])])
    vs.valid("uncommon", "u03-marker-gap-throughout", d.build(),
             "marker 3 (LBHD... 'RBHD') is a gap in every frame; its integers still decode and "
             "its output is all NaN",
             {"mask": True, "all_gap_marker": 3}, ["§4.5", "§6.1", "§4.9", "§6.5"],
             "hand-built from mpz.synth walk (frames=30, markers=6, seed=13)")
    # u04: a C3D-style float32 rate
    m = _synth("walk", 24, markers=4, seed=14, rate=65.0364227294921875)
    d = design_from_motion(m, step=1.0, nodes=[(None, 0, [0]), (0, 1, [1, 2, 3])])
    vs.valid("uncommon", "u04-rate-65.0364227294921875", d.build(),
             "rate 65.0364227294921875 Hz (a float32 C3D rate), which must be reported exactly",
             {"rate": 65.0364227294921875}, ["§4.9", "§6.5"],
             "hand-built from mpz.synth walk (rate=65.0364227294921875)")
    # u05: long clip, many segments
    m = _synth("walk", 20000, markers=2, seed=15, rate=100.0)
    d = design_from_motion(m, step=2.0, nodes=[(None, 0, [0]), (0, 1, [1])], smoothing=2,
                           patterns={1: {"L": 50, "K": 6, "scale": 1, "order": 1, "jitter": 20}},
                           resi={1: {"order": 1, "scale": 2}}, root_order=2, seed=15)
    vs.valid("uncommon", "u05-long-20000-frames", d.build(),
             "20000 frames x 2 markers at 100 Hz: hundreds of segments of 30..70 frames re-timed "
             "to L = 50, residual g = 2; 23 kB of file for 960 kB of output",
             {"frames": 20000, "segments": "hundreds"}, ["§4.7", "§4.8", "§4.9", "§6.3", "§6.4",
                                                         "§6.5"],
             "hand-built from mpz.synth walk (frames=20000, markers=2, seed=15)")
    # u06: unknown ancillary chunk
    m = _synth("walk", 20, markers=4, seed=16)
    d = design_from_motion(m, step=1.0, nodes=[(None, 0, [0]), (0, 1, [1, 2, 3])])
    d.ancillary.append(("zzzz", bytes(range(40))))
    d.ancillary_early.append(("qqqq", b""))
    vs.valid("uncommon", "u06-unknown-ancillary-zzzz", d.build(),
             "unknown ancillary chunks 'qqqq' (empty, after MHDR) and 'zzzz' (40 bytes, before "
             "MEND): a decoder must skip them (lower-case first letter)",
             {"unknown_ancillary": ["qqqq", "zzzz"]}, ["§2.3", "§4.9", "§6.5"],
             "hand-built from mpz.synth walk (frames=20, markers=4, seed=16)")
    # u07: max smoothing 16, segments shorter than the window
    m = _synth("mixed", 120, markers=4, seed=17)
    d = design_from_motion(m, step=0.5, nodes=[(None, 0, [0]), (0, 1, [1, 2, 3])], smoothing=16,
                           patterns={1: {"L": 12, "K": 3, "scale": 2, "order": 2, "jitter": 6}},
                           resi={1: {"order": 2}}, seed=17)
    vs.valid("uncommon", "u07-max-smoothing-16", d.build(),
             "smoothing h = 16 (the maximum) with segments of 6..18 frames, so smoothing windows "
             "of neighbouring boundaries overlap and clamp at both clip ends",
             {"smoothing": 16}, ["§4.7", "§4.8", "§4.9", "§6.3", "§6.4", "§6.5"],
             "hand-built from mpz.synth mixed (frames=120, markers=4, seed=17)")
    # u08: values at the edge of |q| < 2^bits
    F = 16
    bits = 20
    lim = (1 << bits) - 1
    root = np.zeros((F, 3), np.int64)
    root[:, 0] = lim
    root[:, 1] = -lim
    root[:, 2] = np.linspace(-lim, lim, F).astype(np.int64)
    d = Design(F, ["A", "B"], step=2.0 ** -20, offset=(0.0, -0.5, 0.5), bits=bits)
    d.nodes.append((ROOT_PARENT, 0, [0], [1.0]))
    d.root = (2, root)
    w = np.zeros((F, 1, 3), np.int64)
    w[:, 0, 0] = -2 * lim                      # B.x = -lim: relative to A.x = lim
    w[:, 0, 1] = 2 * lim                       # B.y = +lim
    w[:, 0, 2] = -rng.integers(0, 3, F)
    d.node(0, 1, [1], resi={"base": 0, "order": 0, "scale": 1, "values": w})
    data = d.build()
    q = decode_integers(read_stream(data))
    assert int(np.abs(q).max()) == lim
    vs.valid("uncommon", "u08-values-at-bits-limit", data,
             f"|q| reaches 2^{bits} - 1 exactly (QUNT bits = {bits}) at step 2^-20, with "
             f"relative values of 2 (2^{bits} - 1) in the residual layer",
             {"bits": bits, "max_abs_q": lim}, ["§4.9", "§6.5", "§6.7"], "integers chosen here")
    # u09: segments of one frame, patterns of one frame
    m = _synth("walk", 30, markers=3, seed=19)
    d = design_from_motion(m, step=0.5, nodes=[(None, 0, [0]), (0, 1, [1]), (0, 2, [2])],
                           smoothing=1)
    # node 1: L = 4, segment counts 1, 2, 4, 23 (counts - L is negative: -3, -2)
    loc = d.layers[1]["resi"]["values"]
    v = rng.integers(-5, 6, (2 * 4, 1, 3))
    d.layers[1]["patt"] = {"K": 2, "L": 4, "scale": 7, "order": 1, "values": v}
    d.layers[1]["segs"] = (np.array([1, 0, 1, 0]), np.array([1, 2, 4, 23]))
    d.layers[1]["resi"] = {"base": 0, "order": 1, "scale": 1, "values": loc}
    # node 2: L = 1, counts 1, 5, 24
    v2 = rng.integers(-50, 51, (3, 1, 3))
    d.layers[2]["patt"] = {"K": 3, "L": 1, "scale": 1, "order": 2, "values": v2}
    d.layers[2]["segs"] = (np.array([2, 0, 1]), np.array([1, 5, 24]))
    d.error_metric, d.error_bound = 0, 0.0          # layers replaced: no bound is claimed
    vs.valid("uncommon", "u09-short-segments-and-patterns", d.build(),
             "segments of 1 and 2 frames (SEGS stores count - L < 0), a segment equal to L, "
             "and patterns of a single frame (L = 1); pattern scale 7",
             {"pattern_length": [1, 4], "segment_counts_min": 1, "patt_scale": [1, 7]},
             ["§4.7", "§4.8", "§4.9", "§6.3", "§6.4", "§6.5"],
             "hand-built from mpz.synth walk (frames=30, markers=3, seed=19), patterns chosen here")
    # u10: minor version 7, long UTF-8 names
    m = _synth("walk", 12, markers=3, seed=20)
    names = ["Ä" * 127 + "x", "subject:LFHD", "名前"]
    m = mpz.Motion(m.positions, names, m.rate, m.units)
    d = design_from_motion(m, step=1.0, nodes=[(None, 0, [0]), (0, 1, [1, 2])])
    d.version = (1, 7)
    vs.valid("uncommon", "u10-minor-version-7-utf8-names", d.build(),
             "minor version 7 (any minor version is accepted), a 255-byte UTF-8 marker name and "
             "non-ASCII names",
             {"version_minor": 7, "name_bytes_max": 255}, ["§2.1", "§4.9", "§6.5"],
             "hand-built from mpz.synth walk (frames=12, markers=3, seed=20)")
    # u11: K = 0 PATT whose coded bytes are not the 5 zero bytes, and length 0
    m = _synth("walk", 16, markers=3, seed=21)
    d = design_from_motion(m, step=1.0, nodes=[(None, 0, [0]), (0, 1, [1, 2])])
    ch = d.chunks()
    i = _find(ch, "PATT")
    ch[i][1] = payload("PATT", {"node": 1, "pattern_count": 0, "length": 0, "scale": 1,
                                "order": 0, "coded": b"\x07garbage"})
    vs.valid("uncommon", "u11-patt-k0-ignored-payload", assemble(ch),
             "a PATT with K = 0 whose length is 0 and whose coded field is 8 arbitrary bytes: "
             "a decoder MUST NOT decode it nor reject the file for it",
             {"pattern_count": [0], "patt_length": 0}, ["§4.7"],
             "hand-built from mpz.synth walk (frames=16, markers=3, seed=21)")
    # u12: MASK present with every flag 0
    m = _synth("walk", 16, markers=3, seed=22)
    d = design_from_motion(m, step=1.0, nodes=[(None, 0, [0]), (0, 1, [1, 2])])
    d.valid = np.ones((16, 3), bool)
    vs.valid("uncommon", "u12-mask-all-valid", d.build(),
             "a MASK chunk whose flags are all 0 (an encoder must not write it, a decoder "
             "accepts it)", {"mask": "all valid"}, ["§4.5", "§6.1"],
             "hand-built from mpz.synth walk (frames=16, markers=3, seed=22)")


def spec_example(vs: VectorSet):
    """The file of spec Appendix A, if present (written by mpz.tools.spec_example)."""
    p = vs.out / mf.SPEC_EXAMPLE
    if not p.is_file():
        print(f"warning: {p} absent; not in the manifest", file=sys.stderr)
        return
    vs.valid("valid", "spec-example", p.read_bytes(),
             "the worked example of spec Appendix A: 3 frames, 2 markers, one gap, one pattern "
             "stretched from 2 to 3 frames, residual layer", {}, ["§5.7"],
             "python -m mpz.tools.spec_example (not written by make_vectors)",
             file=mf.SPEC_EXAMPLE)


# ---------------------------------------------------------- invalid group --
def base_design():
    """The small file every invalid vector starts from: every chunk type present."""
    from mpz.encoder import summary_fields
    m = _synth("walk", 24, markers=4, seed=99, gap_fraction=0.05)
    d = design_from_motion(m, step=1.0, nodes=[(None, 0, [0]), (0, 1, [1, 2]), (1, 3, [3])],
                           smoothing=2,
                           patterns={1: {"L": 6, "K": 2, "scale": 1, "order": 1, "jitter": 1}},
                           resi={1: {"order": 1}, 2: {"order": 2}}, seed=99)
    d.ancillary.append(("smry", payload("smry", summary_fields(m, (2,), "positions", 1.0))))
    d.ancillary.append(("meta", payload("meta", {"count": 1, "entries": [
        {"key": "k", "value": "v"}]})))
    return d


def _find(chunks, ctype, n=0):
    idx = [i for i, c in enumerate(chunks) if c[0] == ctype]
    return idx[n]


def _with_field(chunks, ctype, **changes):
    """Copy of ``chunks`` with fields of the first ``ctype`` chunk changed (payload rebuilt)."""
    out = [list(c) for c in chunks]
    i = _find(out, ctype)
    fields = PAYLOADS[ctype.encode()].parse(out[i][1])
    for k, v in changes.items():
        fields[k] = v
    out[i][1] = PAYLOADS[ctype.encode()].build(fields)
    return out


def invalid_vectors(vs: VectorSet):
    d = base_design()
    d.build()                                                 # fixes QUNT bits
    base = d.chunks()
    good = assemble(base)
    assert mpz.decode(good).n_frames == 24
    vs.valid("valid", "v09-all-chunk-types", good,
             "the small base file every invalid vector is derived from: every chunk type "
             "(MHDR MNAM HIER QUNT MASK ROOT PATT SEGS RESI smry meta MEND), 3-level hierarchy",
             {}, ["§4.5", "§4.7", "§4.8", "§4.9", "§4.10", "§4.11", "§6.1", "§6.3", "§6.4",
                  "§6.5"], "hand-built from mpz.synth walk (frames=24, markers=4, seed=99, "
             "gap_fraction=0.05)")
    offs = {}
    pos = len(SIGNATURE)
    for t, p in base:
        offs.setdefault(t, pos)
        pos += 12 + len(p)
    n = [0]

    def add(slug, data, description, corruption, risk, error, sections, **kw):
        n[0] += 1
        vs.invalid(f"x{n[0]:02d}-{slug}", data, description, corruption, risk, error, sections,
                   **kw)

    # --- framing
    b = bytearray(good)
    b[1] ^= 0x20                                              # 'M' -> 'm'
    add("bad-signature", bytes(b), "signature byte 1 changed from 'M' to 'm'",
        "byte 1 XOR 0x20", "a decoder that skips the signature check reads foreign files as MPZ",
        "FormatError", ["§3.1"])
    add("signature-only", SIGNATURE, "the 8-byte signature and nothing else",
        "file truncated after the signature", "a chunk loop that treats end of file as the end "
        "of the chunk list accepts an empty file", "FormatError", ["§3.4"])
    for ctype in ("MHDR", "HIER", "ROOT", "RESI", "MEND"):
        b = bytearray(good)
        o = offs[ctype] + 8 + len(base[_find(base, ctype)][1])
        b[o] ^= 0x01
        add(f"bad-crc-{ctype.lower()}", bytes(b), f"CRC-32 of the first {ctype} chunk off by one bit",
            f"stored CRC of {ctype} at offset {o} XOR 0x01 (payload intact)",
            f"a decoder that ignores CRCs decodes corrupted {ctype} data silently",
            "ChecksumError", ["§3.3"], features={"chunk": ctype})
    b = bytearray(good)
    o = offs["PATT"] + 8 + 3
    b[o] ^= 0x40
    add("bad-crc-patt-payload", bytes(b), "one bit flipped inside the PATT payload, CRC left as "
        "it was", f"byte at offset {o} XOR 0x40", "a flipped payload bit changes pattern fields "
        "(here: pattern_count) without any other sign", "ChecksumError", ["§3.3"],
        features={"chunk": "PATT"})
    for ctype in ("MHDR", "MNAM", "HIER", "QUNT", "MASK", "ROOT", "PATT", "SEGS", "RESI", "smry",
                  "meta", "MEND"):
        i = _find(base, ctype)
        o = offs[ctype]
        ln = len(base[i][1])
        cut = o + 8 + ln // 2 if ln else o + 8 + 2              # MEND: mid-CRC
        add(f"truncated-in-{ctype.lower()}", good[:cut],
            f"file cut in the middle of the {ctype} chunk" + (" (inside its CRC)" if not ln else ""),
            f"file truncated to {cut} bytes; the {ctype} chunk at offset {o} declares {ln} "
            "payload bytes",
            "a decoder that trusts the length field reads past the end of its buffer",
            "LimitExceededError" if cut - o >= 12 else "FormatError", ["§3.2", "§8"],
            features={"chunk": ctype})
    b = bytearray(good)
    struct.pack_into("<I", b, offs["QUNT"] + 4, len(good))
    add("length-beyond-file", bytes(b), "QUNT length field larger than the whole file",
        f"QUNT length set to {len(good)}", "allocating or reading by the declared length "
        "overruns the buffer", "LimitExceededError", ["§3.2", "§8"])
    b = bytearray(good)
    struct.pack_into("<I", b, offs["MNAM"] + 4, 0xFFFFFFFF)
    add("length-max-0xffffffff", bytes(b), "MNAM length field 0xFFFFFFFF",
        "MNAM length set to 0xFFFFFFFF", "length + 12 overflows 32-bit arithmetic and wraps to "
        "a small number; or a 4 GiB allocation", "LimitExceededError", ["§3.2", "§8"])
    add("missing-mend", assemble(base[:-1]), "the MEND chunk is absent (file otherwise whole)",
        "last chunk (MEND) removed", "a decoder that stops at end of file accepts truncation at "
        "a chunk boundary", "FormatError", ["§3.4", "§4.12"])
    add("bytes-after-mend", good + b"\x00" * 4, "four zero bytes after MEND",
        "4 bytes appended", "data after the end is silently ignored (concatenated or smuggled "
        "content)", "FormatError", ["§3.4"])
    ch = [list(c) for c in base]
    ch.insert(_find(ch, "MEND"), ["ABCD", b"\x00\x01"])
    add("unknown-critical-ABCD", assemble(ch), "an unknown critical chunk 'ABCD' before MEND",
        "chunk ABCD (2 bytes) inserted", "a decoder that skips unknown critical chunks decodes "
        "data whose meaning it does not know", "FormatError", ["§2.3"])
    ch = [list(c) for c in base]
    i, j = _find(ch, "HIER"), _find(ch, "QUNT")
    ch[i], ch[j] = ch[j], ch[i]
    add("chunks-out-of-order", assemble(ch), "QUNT before HIER", "HIER and QUNT swapped",
        "an order-agnostic decoder builds state from chunks in the wrong order", "FormatError",
        ["§3.4"])
    ch = [list(c) for c in base]
    del ch[_find(ch, "ROOT")]
    add("missing-root", assemble(ch), "the ROOT chunk is absent", "ROOT chunk removed",
        "a decoder that defaults the root track to zeros accepts a damaged file",
        "FormatError", ["§3.4", "§4.6"])
    ch = [list(c) for c in base]
    ch.insert(_find(ch, "MHDR") + 1, list(base[_find(base, "MHDR")]))
    add("duplicate-mhdr", assemble(ch), "two MHDR chunks", "MHDR repeated",
        "a later header silently overriding the first", "FormatError", ["§3.4"])
    # --- header
    add("major-version-2", assemble(_with_field(base, "MHDR", version_major=2)),
        "major version 2", "MHDR version_major = 2", "a 1.x decoder decoding a future, "
        "incompatible format", "UnsupportedVersionError", ["§2.1", "§4.1"])
    add("reserved-flag-bits", assemble(_with_field(base, "MHDR", flags=0x8001)),
        "reserved header flag bit 15 set", "MHDR flags = 0x8001",
        "ignoring reserved bits hides a future feature the decoder cannot honour",
        "FormatError", ["§4.1"])
    add("frames-x-markers-over-limit", assemble(_with_field(base, "MHDR", frame_count=1 << 24,
                                                            marker_count=4096, node_count=3)),
        "a 400-byte file declaring 2^24 frames x 4096 markers",
        "MHDR frame_count = 2^24, marker_count = 4096",
        "allocating [F, M, 3] float64 up front (1.6 TB) before reading any data",
        "LimitExceededError", ["§4.1", "§8"])
    add("frame-count-zero", assemble(_with_field(base, "MHDR", frame_count=0)),
        "frame_count 0", "MHDR frame_count = 0", "empty arrays and division by F - 1",
        "LimitExceededError", ["§4.1", "§8"])
    add("rate-nan", assemble(_with_field(base, "MHDR", rate=float("nan"))), "frame rate NaN",
        "MHDR rate = NaN", "NaN propagating into timestamps", "FormatError", ["§4.1"])
    add("smoothing-17", assemble(_with_field(base, "MHDR", smoothing=17)),
        "smoothing half-width 17 (max 16)", "MHDR smoothing = 17",
        "out-of-range filter widths", "FormatError", ["§4.1", "§6.4"])
    add("units-code-5", assemble(_with_field(base, "MHDR", units=5)), "units code 5",
        "MHDR units = 5", "guessing units scales data by 10-1000x", "FormatError", ["§4.1"])
    # --- names / hierarchy / grid
    add("duplicate-marker-names", assemble(_with_field(base, "MNAM", names=["A", "B", "A", "C"])),
        "two markers named 'A'", "MNAM names = A, B, A, C",
        "name-keyed lookups silently drop a marker", "FormatError", ["§4.2"])
    add("names-count-mismatch", assemble(_with_field(base, "MNAM", count=3,
                                                     names=["A", "B", "C"])),
        "3 names for 4 markers", "MNAM count = 3", "indexing names by marker overruns",
        "FormatError", ["§4.2"])
    ch = _with_field(base, "HIER")
    hier = PAYLOADS[b"HIER"].parse(ch[_find(ch, "HIER")][1])
    hier.nodes[2].parent = 2
    ch[_find(ch, "HIER")][1] = PAYLOADS[b"HIER"].build(hier)
    add("node-parent-not-before-node", assemble(ch), "node 2 names itself as its parent",
        "HIER node 2 parent = 2", "a parent that is not decoded yet (or a cycle): reads "
        "uninitialised values or loops forever", "FormatError", ["§4.3"])
    hier = PAYLOADS[b"HIER"].parse(base[_find(base, "HIER")][1])
    hier.nodes[2].members = [2]
    hier.nodes[2].ref = 2
    ch = [list(c) for c in base]
    ch[_find(ch, "HIER")][1] = PAYLOADS[b"HIER"].build(hier)
    add("marker-in-two-nodes", assemble(ch), "marker 2 in nodes 1 and 2, marker 3 in none",
        "HIER node 2 members = [2]", "a marker decoded twice and another never", "FormatError",
        ["§4.3"])
    hier = PAYLOADS[b"HIER"].parse(base[_find(base, "HIER")][1])
    hier.nodes[1].ref = 3
    ch = [list(c) for c in base]
    ch[_find(ch, "HIER")][1] = PAYLOADS[b"HIER"].build(hier)
    add("reference-not-a-member", assemble(ch), "node 1's reference marker is not one of its "
        "members", "HIER node 1 ref = 3", "children coded relative to a marker not yet decoded",
        "FormatError", ["§4.3"])
    add("grid-step-zero", assemble(_with_field(base, "QUNT", step=0.0)), "grid step 0",
        "QUNT step = 0", "all positions collapse to the offset", "FormatError", ["§4.4"])
    ch = [list(c) for c in base]
    ch[_find(ch, "QUNT")][1] += b"\x00"
    add("qunt-trailing-byte", assemble(ch), "one extra byte at the end of the QUNT payload",
        "QUNT payload + 1 zero byte", "fixed-size payloads parsed without checking their "
        "length hide misframed data", "FormatError", ["§4.4"])
    # --- range coder
    ch = [list(c) for c in base]
    ch[_find(ch, "ROOT")][1] += b"\x00\x00"
    add("rc-leftover-bytes", assemble(ch), "two bytes after the last range-coded symbol of ROOT",
        "ROOT payload + 2 zero bytes", "a range decoder that never checks it consumed its input "
        "accepts padding or smuggled data", "FormatError", ["§5.3"])
    ch = [list(c) for c in base]
    i = _find(ch, "RESI")
    body = bytearray(ch[i][1])
    body[6] = 0x01                                     # RESI header is 6 bytes, then rc byte 0
    ch[i][1] = bytes(body)
    add("rc-first-byte-nonzero", assemble(ch), "the first range-coder byte of a RESI payload is "
        "1", "RESI coded[0] = 0x01", "a decoder that skips the first byte without checking "
        "decodes a different stream", "FormatError", ["§5.1", "§5.3"])
    ch = [list(c) for c in base]
    i = _find(ch, "RESI")
    ch[i][1] = ch[i][1][:-3]
    add("rc-payload-short", assemble(ch), "the RESI range-coded payload lacks its last 3 bytes "
        "(chunk length and CRC consistent)", "RESI payload shortened by 3 bytes, CRC recomputed",
        "reading past the payload for the last symbols", "FormatError", ["§5.3"])
    # mask flag 2
    ch = [list(c) for c in base]
    valid = d.valid
    flags = (~valid).astype(np.int64)[:, :, None]
    flags[3, 1, 0] = 2
    ch[_find(ch, "MASK")][1] = payload("MASK", {"coded": rc((flags, {"signed": False}))})
    add("mask-flag-2", assemble(ch), "a gap flag of 2", "MASK value at frame 3, marker 1 = 2",
        "treating any non-zero flag as a gap (or any non-one as valid) diverges between decoders",
        "FormatError", ["§4.5", "§6.1"])
    add("root-order-3", assemble(_with_field(base, "ROOT", order=3)), "ROOT predictor order 3",
        "ROOT order = 3", "an unknown predictor silently treated as another order",
        "FormatError", ["§4.6", "§6.2"])
    # order-2 overflow: constant large second differences
    ch = [list(c) for c in base]
    e = np.zeros((24, 1, 3), np.int64)
    e[1:, 0, 0] = (1 << 30) - 1
    ch[_find(ch, "ROOT")][1] = payload("ROOT", {"order": 2, "coded": rc((e, {}))})
    add("order2-overflow", assemble(ch), "ROOT order-2 residuals of 2^30 - 1 in every frame: "
        "the first differences pass 2^32 and positions would pass 2^63",
        "ROOT residuals replaced", "signed 64-bit overflow (undefined behaviour in C) during "
        "prediction", "FormatError", ["§6.2"])
    # --- patterns and segments
    pf = PAYLOADS[b"PATT"].parse(base[_find(base, "PATT")][1])
    K, L = pf.pattern_count, pf.length
    index, counts = d.layers[1]["segs"]

    def segs_with(idx, cnt, S=None):
        ch = [list(c) for c in base]
        v = np.stack([idx, np.asarray(cnt) - L], axis=1)[:, None, :]
        ch[_find(ch, "SEGS")][1] = payload("SEGS", {"node": 1, "segment_count":
                                                    len(idx) if S is None else S,
                                                    "coded": rc((v, {}))})
        return assemble(ch)

    bad = index.copy()
    bad[-1] = K
    add("segs-index-out-of-range", segs_with(bad, counts), f"a segment uses pattern {K} of "
        f"{K} (indices are 0..{K - 1})", f"SEGS last pattern index = {K}",
        "indexing the pattern table out of bounds", "FormatError", ["§4.8", "§6.3"])
    bad = index.copy()
    bad[0] = -1
    add("segs-index-negative", segs_with(bad, counts), "a segment uses pattern -1",
        "SEGS first pattern index = -1", "negative indices wrap to the end of the table in "
        "many languages", "FormatError", ["§4.8", "§6.3"])
    bad = counts.copy()
    bad[0] += 1
    add("segs-counts-exceed-f", segs_with(index, bad), "segment frame counts add up to F + 1",
        "SEGS first frame count + 1", "writing one frame past the end of the output",
        "FormatError", ["§4.8", "§6.3"])
    bad = counts.copy()
    bad[0] -= 1
    add("segs-counts-short-of-f", segs_with(index, bad), "segment frame counts add up to F - 1",
        "SEGS first frame count - 1", "an uninitialised last frame", "FormatError",
        ["§4.8", "§6.3"])
    bad = counts.copy()
    bad[0], bad[1] = 0, bad[1] + bad[0]
    add("segs-count-zero", segs_with(index, bad), "a segment of 0 frames (total still F)",
        "SEGS first frame count = 0, second + original", "division by n - 1 = -1 in the "
        "re-timing of §6.3", "FormatError", ["§4.8", "§6.3"])
    ch = [list(c) for c in base]
    del ch[_find(ch, "SEGS")]
    add("missing-segs", assemble(ch), "a PATT with patterns but no SEGS chunk after it",
        "SEGS removed", "patterns applied without segment data", "FormatError", ["§3.4", "§4.8"])
    add("segs-wrong-node", assemble(_with_field(base, "SEGS", node=2)),
        "SEGS says node 2 where node 1 is expected", "SEGS node = 2",
        "layers applied to the wrong node", "FormatError", ["§3.4", "§4.8"])
    add("patt-scale-zero", assemble(_with_field(base, "PATT", scale=0)), "pattern scale 0",
        "PATT scale = 0", "every pattern collapses to zero", "FormatError", ["§4.7"])
    add("resi-scale-zero", assemble(_with_field(base, "RESI", scale=0)), "residual scale g = 0",
        "RESI scale = 0", "the residual layer silently vanishes", "FormatError", ["§4.9"])
    add("resi-base1-with-patterns", assemble(_with_field(base, "RESI", base=1)),
        "an absolute residual layer (base 1) on a node that has patterns",
        "RESI (node 1) base = 1", "patterns and absolute values both applied, or one ignored",
        "FormatError", ["§4.9"])
    # value beyond bits
    add("value-beyond-bits", assemble(_with_field(base, "QUNT", bits=d.bits - 1)),
        f"QUNT bits {d.bits - 1}, one less than the decoded values need",
        f"QUNT bits = {d.bits - 1}", "decoders using narrow integer types overflow",
        "FormatError", ["§4.4", "§6.7"])


# ------------------------------------------------------------ encoder set --
def encoder_inputs(vs: VectorSet):
    m = _synth("walk", 60, markers=41, seed=31, gap_fraction=0.05)
    vs.encoder_input("e01-walk-41-gaps", m, [1.0, 5.0],
                     "41-marker walk, 60 frames, 5% gaps, mm")
    m = _synth("mixed", 80, markers=10, seed=32)
    m = mpz.Motion(m.positions / 1000.0, m.names, m.rate, "m")
    vs.encoder_input("e02-mixed-10-metres", m, [0.0005],
                     "10-marker mixed motion in metres, 80 frames")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m mpz.tools.make_vectors",
                                description=__doc__.splitlines()[0])
    p.add_argument("--out", default=str(mf.DEFAULT_DIR),
                   help="output directory (default: the package's conformance/vectors)")
    args = p.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for g in ("valid", "uncommon", "invalid", "inputs"):
        d = out / g
        if d.is_dir():
            for f in d.iterdir():
                if f.is_file() and f.name != "spec-example.mpz":
                    f.unlink()
    vs = VectorSet(out)
    valid_vectors(vs)
    spec_example(vs)
    invalid_vectors(vs)
    uncommon_vectors(vs)
    encoder_inputs(vs)
    vs.entries.sort(key=lambda e: (mf.GROUPS.index(e["group"]), e["name"]))
    vs.write_manifest()
    total = sum(f.stat().st_size for f in out.rglob("*") if f.is_file())
    print(f"wrote {len(vs.entries)} vectors and {len(vs.encoder_inputs)} encoder inputs to "
          f"{out} ({total} bytes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
