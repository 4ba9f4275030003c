"""Regenerate the MPZ conformance vectors, byte for byte.

Usage: ``python -m mpz.tools.make_vectors [--out conformance/vectors]``

Strategy: every vector comes from seeded synthetic motion (:mod:`mpz.synth`)
or from integers chosen here. Some are written by the reference encoder; most
are *built by hand*, chunk by chunk, with :func:`mpz.container.build`,
:class:`mpz.entropy.BlockEncoder` and :func:`mpz.predict.residuals`, so that
every field value that changes decoding appears (predictor orders 0/1/2,
smoothing 0..16, residual scale g > 1, base 0 and 1, pattern scale > 1, ...),
including values the encoder would never choose. Coded values of 2^30 and more
(§5.4: decoders read them, encoders never write them) go through the §5
transcription :class:`mpz.conformance.rangecoder.RefEncoder` (:func:`rc_wide`).
The vectors for the points of spec 1.0.1 (Appendix B) come last in each group, so
the 1.0 vectors keep their names and bytes. Invalid vectors start from a
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
from mpz.chunks import CHUNKS
from mpz.conformance import manifest as mf
from mpz.conformance.rangecoder import RefEncoder
from mpz.decoder import decode_layers
from mpz.entropy import BlockEncoder
from mpz.format import ROOT_PARENT, SIGNATURE, unit_code, unit_name
from mpz.normalize import denormalize, normalize, segment_starts
from mpz.predict import reconstruct, residuals
from mpz.smooth import smooth_boundaries


# ================================================================ building ==
def rc(*blocks) -> bytes:
    """One range-coded payload from blocks given as (values [T, M, A], kwargs)."""
    enc = BlockEncoder()
    for vals, kw in blocks:
        enc.block(vals, **kw)
    return enc.finish()


def rc_wide(*blocks) -> bytes:
    """As :func:`rc`, for values up to |v| = 2^31 - 1 (exponent k = 30, §5.4), which an
    encoder must not write but a decoder must read. The reference BlockEncoder refuses
    |v| >= 2^30, so this goes through the §5 transcription of the conformance package."""
    enc = RefEncoder()
    for vals, kw in blocks:
        v = np.asarray(vals, np.int64)
        assert v.ndim == 3 and int(np.abs(v).max(initial=0)) < 1 << 31
        enc.block(v, period=kw.get("period"), signed=kw.get("signed", True))
    return enc.finish()


def payload(ctype: str, fields) -> bytes:
    """A payload built straight from its layout (the chunk table's grammar), so that vectors
    can hold values the checks reject."""
    return CHUNKS[ctype].GRAMMAR.build(fields)


def assemble(chunks) -> bytes:
    """Signature + chunks given as [type, payload] pairs, every CRC correct."""
    return container.build((t, p) for t, p in chunks)


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
        self.payloads = {}             # (type, n) -> payload replacing the n-th chunk of type

    def node(self, parent, ref, members, *, patt=None, segs=None, resi=None, weights=None):
        """Add a node. ``patt`` = dict(K, L, scale, order, values [K*L, n, 3]) or None;
        ``segs`` = (index [S], counts [S]); ``resi`` = dict(base, order, scale,
        values [F, n, 3])."""
        self.nodes.append((parent, ref, list(members), weights or [1.0] * len(members)))
        self.layers[len(self.nodes) - 1] = {"patt": patt, "segs": segs, "resi": resi}

    def chunks(self) -> list:
        F, M = self.F, len(self.names)
        flags = self.flags if self.flags is not None else (1 if self.residual else 0)
        hdr = {"version_major": self.version[0], "version_minor": self.version[1],
               "flags": flags, "frame_count": F, "marker_count": M,
               "node_count": len(self.nodes), "rate": self.rate,
               "units": int(unit_code(self.units)),
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
        assert self.root is not None, "set Design.root = (order, ints [F, 3])"
        order, vals = self.root
        out.append(["ROOT", self.payloads.get(("ROOT", 0)) or payload("ROOT", {
            "order": order, "coded": rc((residuals(vals[:, None, :], order), {}))})])
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
                out.append(["RESI", self.payloads.get(("RESI", i - 1)) or payload("RESI", {
                    "node": i, "base": r["base"], "order": r["order"], "scale": r["scale"],
                    "coded": rc((residuals(r["values"], r["order"]), {}))})])
        out += [list(c) for c in self.ancillary]
        out.append(["MEND", b""])
        for (ctype, n), body in self.payloads.items():
            out[_find(out, ctype, n)][1] = body
        return out

    def build(self) -> bytes:
        """Assemble; with bits=None, set QUNT bits to the smallest value that holds (§4.4)."""
        data = assemble(self.chunks())
        if self.bits is None:
            q = decode_layers(data).q
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
    cuts: list[int] = []
    left = F
    while left > 0:
        c = int(L + rng.integers(-jitter, jitter + 1)) if jitter else L
        c = max(1, min(c, left))
        if left - c < max(1, L // 2) and left - c > 0:
            c = left
        cuts.append(c)
        left -= c
    counts = np.asarray(cuts, np.int64)
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
        self.entries: list[dict] = []
        self.encoder_inputs: list[dict] = []

    def _write(self, rel: str, data: bytes) -> str:
        p = self.out / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(data)
        return mf.sha256_file(p)

    def valid(self, group, name, data, description, features, sections, provenance, file=None):
        """A vector that must decode; the expected output is the reference decoder's."""
        assert group in ("valid", "uncommon")
        d = decode_layers(data)
        s, valid, q, x = d.stream, d.valid, d.q, d.positions()
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
                       "names": list(s.names), "units": unit_name(h.units),
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
                raise AssertionError(f"{name}: reference raised {got} ({exc}), "
                                     f"expected {error}") from None
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
    from mpz.encoder import summary_record
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
    smry = summary_record(m, (1, 3), "positions", 0.25).dump()
    d.ancillary_early.append(("meta", payload("meta", {"count": 2, "entries": [
        {"key": "subject", "value": "synthetic"}, {"key": "note", "value": "ünïcödé ✓"}]})))
    d.ancillary.append(("smry", smry))
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
    q = decode_layers(data).q
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
    spec_101_uncommon(vs)


# ------------------------------------------- 1.0.1: valid files the text settles --
#: node layout of the small 1.0.1 files: root C7-like marker 0, a node of two, a grandchild
SMALL = [(None, 0, [0]), (0, 1, [1, 2]), (1, 3, [3])]


def _small(seed, **kw):
    """A small residual-layer file (24 frames, 4 markers, 3 nodes) to change one thing in."""
    m = _synth("walk", 24, markers=4, seed=seed)
    kw.setdefault("resi", {1: {"order": 1}, 2: {"order": 2}})
    return design_from_motion(m, step=1.0, nodes=SMALL, seed=seed, **kw)


def _root_only(F, rows, *, bits=31, **kw):
    """A one-marker file (root track only, ROOT order 0) whose values may reach 2^31 - 1."""
    d = Design(F, ["A"], bits=bits, **kw)
    d.nodes.append((ROOT_PARENT, 0, [0], [1.0]))
    d.root = (0, np.asarray(rows, np.int64))
    d.payloads[("ROOT", 0)] = payload("ROOT", {"order": 0, "coded": rc_wide(
        (d.root[1][:, None, :], {}))})
    return d


def keyframe_blocks(refs, key_counts, spans, keys, *, wide=False) -> bytes:
    """The four blocks of a RESI base-2 payload (§6.5): p_m, K_m - 1, d_k - 1, e_k."""
    col = lambda v: np.asarray(v, np.int64).reshape(-1, 1, 1)   # noqa: E731
    blocks = [(col(refs), {"signed": False}),
              (col(np.asarray(key_counts) - 1), {"signed": False}),
              (col(np.asarray(spans, np.int64) - 1), {"signed": False}),
              (np.asarray(keys, np.int64).reshape(-1, 1, 3), {})]
    return (rc_wide if wide else rc)(*blocks)


def smry_payload(space, dims, levels) -> bytes:
    """A smry payload from (k, wssse, step, starts, means) levels, any values (§4.10)."""
    return payload("smry", {"space": space, "dims": dims, "level_count": len(levels), "levels": [
        {"k": k, "wssse": w, "step": st, "starts": struct.pack(f"<{len(starts)}I", *starts),
         "means": struct.pack(f"<{len(means)}i", *means)} for k, w, st, starts, means in levels]})


def spec_101_uncommon(vs: VectorSet):
    """Valid files for the points spec 1.0.1 settles (Appendix B, issues 10 and 18)."""
    # u13, u14 (10.1, 18.8a): the unused coded field of a K = 0 PATT, empty and 3 bytes
    for n, (name, coded, what) in enumerate([
            ("u13-patt-k0-coded-empty", b"", "empty: the PATT payload is 9 bytes"),
            ("u14-patt-k0-coded-3-bytes", b"\xff\x00\x01",
             "3 bytes FF 00 01 (fewer than 5, first byte not 0)")]):
        d = _small(41 + n)
        d.payloads[("PATT", 0)] = payload("PATT", {"node": 1, "pattern_count": 0, "length": 1,
                                                   "scale": 1, "order": 0, "coded": coded})
        vs.valid("uncommon", name, d.build(),
                 f"node 1's PATT has K = 0 and its unused coded field is {what}: the rules on "
                 "coded fields (at least 5 bytes, first byte 0, close()) do not apply to it, and "
                 "a decoder MUST NOT decode it nor reject the file for it",
                 {"pattern_count": [0], "patt_coded_bytes": len(coded)},
                 ["§2.4", "§4.7", "§5.3", "§5.5"],
                 f"hand-built from mpz.synth walk (frames=24, markers=4, seed={41 + n})")
    # u15 (10.3): the largest grid that keeps every output finite, values at |q| = 2^31 - 1
    lim = (1 << 31) - 1
    rows = [[lim, -lim, 0], [-lim, lim, 1], [1 << 30, -(1 << 30), -1], [0, 0, 0]]
    d = _root_only(4, rows, step=2.0 ** 992)
    vs.valid("uncommon", "u15-qunt-step-2pow992-bits-31", d.build(),
             "QUNT step 2^992, offset 0, bits 31: |offset| + step x 2^bits = 2^1023 is finite, "
             "so the grid is valid; ROOT values reach +-(2^31 - 1), so outputs reach about "
             "+-2^1023 and every one is finite",
             {"step": 2.0 ** 992, "bits": 31, "max_abs_q": lim}, ["§4.4", "§6.8", "§7.1"],
             "integers chosen here")
    # u16 (10.3): the exact boundary: B = 2^1024 - 2^971 + 2^969 rounds down to DBL_MAX
    step = float((2 ** 53 - 1) * 2 ** 940)
    d = _root_only(4, rows, step=step, offset=(2.0 ** 969, -(2.0 ** 969), 0.0))
    vs.valid("uncommon", "u16-qunt-range-rounds-to-max-finite", d.build(),
             "QUNT step (2^53 - 1) x 2^940, bits 31, offset x = 2^969, y = -2^969: on x and y, "
             "|offset| + step x 2^31 = 2^1024 - 2^971 + 2^969 exceeds DBL_MAX as a real but is "
             "below 2^1024 - 2^970, so binary64 rounds it to DBL_MAX and the grid is valid; "
             "a decoder that compares the exact sum with DBL_MAX rejects a valid file",
             {"step": step, "bits": 31, "offset": [2.0 ** 969, -(2.0 ** 969), 0.0]},
             ["§4.4", "§6.8", "§7.1"], "integers chosen here")
    # u17 (10.4): key frames with F = 1: the span block has no rows
    d = Design(1, ["root", "m1", "m2"], step=0.5)
    d.nodes.append((ROOT_PARENT, 0, [0], [1.0]))
    d.root = (1, np.array([[10, -4, 7]], np.int64))
    d.node(0, 1, [1, 2], resi={"base": 2, "order": 0, "scale": 3,
                               "values": np.zeros((1, 2, 3), np.int64)})
    d.payloads[("RESI", 0)] = payload("RESI", {
        "node": 1, "base": 2, "order": 0, "scale": 3,
        "coded": keyframe_blocks([0, 1], [1, 1], [], [[5, -6, 7], [2, 0, -1]])})
    vs.valid("uncommon", "u17-keyframes-one-frame", d.build(),
             "F = 1 with a key-frame residual layer (RESI base 2, g = 3): every K_m = 1, so "
             "the span block has 0 rows and consumes no decisions, and the key block follows "
             "at the same coder state; member 1 predicts from member 0 (p = 1)",
             {"frames": 1, "resi_base": [2], "keyframe_refs": [0, 1]},
             ["§4.9", "§5.5", "§6.5"], "integers chosen here")
    # u18 (18.8b): NUL inside a meta key and a meta value
    d = _small(44)
    d.ancillary.append(("meta", payload("meta", {"count": 2, "entries": [
        {"key": "a\x00b", "value": "x\x00y\x00"}, {"key": "empty", "value": ""}]})))
    vs.valid("uncommon", "u18-meta-nul", d.build(),
             "a meta key 'a U+0000 b' and value 'x U+0000 y U+0000' (U+0000 is allowed in meta, "
             "though encoders should not write it), and an empty value",
             {"meta_nul": True}, ["§4.11", "§6.8"],
             "hand-built from mpz.synth walk (frames=24, markers=4, seed=44)")
    # u19 (10.9): names compared as bytes; a shared prefix that splits a character
    m = _synth("walk", 12, markers=5, seed=45)
    names = ["a", "A", "\u00e9", "\u00e8", "e\u0301"]
    m = mpz.Motion(m.positions, names, m.rate, m.units)
    d = design_from_motion(m, step=1.0, nodes=[(None, 0, [0]), (0, 1, [1, 2, 3, 4])])
    data = d.build()
    body, at, shared = container.parse(data)[1].payload, 2, []
    for _ in names:                                          # entries: shared, len, suffix
        shared.append(body[at])
        at += 2 + body[at + 1]
    assert shared == [0, 0, 0, 1, 0]                         # "è" keeps C3 of "é"
    vs.valid("uncommon", "u19-names-compared-as-bytes", data,
             "marker names 'a' and 'A', 'é' as C3 A9 and as 65 CC 81 (e + combining acute), "
             "and 'è' (C3 A8) front-coded with shared = 1, which splits the 2-byte character "
             "C3 A8: all five names are different byte strings, so the file is valid",
             {"names": names, "shared_splits_character": True}, ["§1", "§4.2", "§6.8"],
             "hand-built from mpz.synth walk (frames=12, markers=5, seed=45)")
    # u20 (10.8): error_bound -0.0 with error_metric 0
    d = _small(46, error_metric=0)
    d.error_bound = -0.0
    vs.valid("uncommon", "u20-error-bound-minus-zero", d.build(),
             "MHDR error_bound = -0.0 with error_metric 0: f64 comparisons are IEEE, so -0.0 "
             "passes 'finite and >= 0'; a decoder that tests the sign bit rejects a valid file",
             {"error_bound": "-0.0", "error_metric": 0}, ["§1.3", "§4.1"],
             "hand-built from mpz.synth walk (frames=24, markers=4, seed=46)")
    # u21 (10.6, 10.8): smry space 1 with D = 0, levels in decreasing k with a repeat, -0.0
    d = _small(47)
    d.ancillary.append(("smry", smry_payload(1, 0, [
        (3, 12.5, 1.0, [0, 5, 9], []), (2, -0.0, 0.5, [0, 10], []), (2, 3.0, 2.0, [0, 4], [])])))
    vs.valid("uncommon", "u21-smry-angles-no-dims", d.build(),
             "a smry chunk with space 1 (joint angles) and D = 0 (no means), three levels with "
             "k = 3, 2, 2 (decreasing, k repeated with different starts) and wssse = -0.0 on one "
             "of them: none of this is a reason to reject",
             {"smry_space": 1, "smry_dims": 0, "smry_k": [3, 2, 2], "wssse": "-0.0"},
             ["§1.3", "§4.10"], "hand-built from mpz.synth walk (frames=24, markers=4, seed=47)")
    # u22 (10.11): decoded values with k = 30 (|v| >= 2^30), which encoders must not write
    d = _root_only(3, [[1 << 30, -lim, 0], [-(1 << 30), lim, 1], [lim - 1, 0, 1 << 30]])
    vs.valid("uncommon", "u22-root-values-k30", d.build(),
             "ROOT order 0 values 2^30, -(2^31 - 1), 2^31 - 1 and 2^31 - 2 (exponent k = 30, "
             "whose terminating zero-bit is left out) with QUNT bits 31: |v| < 2^30 binds "
             "encoders only, and a decoder MUST accept these",
             {"root_order": 0, "bits": 31, "max_abs_q": lim}, ["§5.4", "§6.7"],
             "integers chosen here, coded with mpz.conformance.rangecoder (the reference "
             "encoder refuses |v| >= 2^30)")
    # u23 (18.3): a §5.6 context value of exactly 2^32
    d = Design(3, ["root", "m1", "m2"], bits=31)
    d.nodes.append((ROOT_PARENT, 0, [0], [1.0]))
    d.root = (0, np.zeros((3, 3), np.int64))
    w = np.zeros((3, 2, 3), np.int64)
    w[0, 1, 0] = lim              # v[0, 1, x]
    w[1, 0, 0] = 2                # v[1, 0, x]: ctx_v of v[1, 1, x] = 2 (2^31 - 1) + 2 = 2^32
    w[1, 1, 0] = 5
    w[2, :, :] = [[3, -1, 0], [-4, 2, 1]]
    d.node(0, 1, [1, 2], resi={"base": 1, "order": 0, "scale": 1, "values": w})
    d.payloads[("RESI", 0)] = payload("RESI", {"node": 1, "base": 1, "order": 0, "scale": 1,
                                               "coded": rc_wide((w, {}))})
    vs.valid("uncommon", "u23-context-value-2pow32", d.build(),
             "RESI base 1 with v[0, 1, x] = 2^31 - 1 and v[1, 0, x] = 2, so the context value "
             "of v[1, 1, x] is 2 (2^31 - 1) + 2 = 2^32 (context 7); in unsigned 32 bits it "
             "wraps to 0 (context 0) and the rest of the block decodes differently",
             {"resi_base": [1], "context_value": 2 ** 32}, ["§1.2", "§5.6"],
             "integers chosen here, coded with mpz.conformance.rangecoder")


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
    from mpz.encoder import summary_record
    m = _synth("walk", 24, markers=4, seed=99, gap_fraction=0.05)
    d = design_from_motion(m, step=1.0, nodes=[(None, 0, [0]), (0, 1, [1, 2]), (1, 3, [3])],
                           smoothing=2,
                           patterns={1: {"L": 6, "K": 2, "scale": 1, "order": 1, "jitter": 1}},
                           resi={1: {"order": 1}, 2: {"order": 2}}, seed=99)
    d.ancillary.append(("smry", summary_record(m, (2,), "positions", 1.0).dump()))
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
    fields = CHUNKS[ctype].GRAMMAR.parse(out[i][1])
    for k, v in changes.items():
        fields[k] = v
    out[i][1] = CHUNKS[ctype].GRAMMAR.build(fields)
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
    offs: dict[str, int] = {}
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
        add(f"bad-crc-{ctype.lower()}", bytes(b),
            f"CRC-32 of the first {ctype} chunk off by one bit",
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
            f"file cut in the middle of the {ctype} chunk"
            + (" (inside its CRC)" if not ln else ""),
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
    hier = CHUNKS["HIER"].GRAMMAR.parse(ch[_find(ch, "HIER")][1])
    hier.nodes[2].parent = 2
    ch[_find(ch, "HIER")][1] = CHUNKS["HIER"].GRAMMAR.build(hier)
    add("node-parent-not-before-node", assemble(ch), "node 2 names itself as its parent",
        "HIER node 2 parent = 2", "a parent that is not decoded yet (or a cycle): reads "
        "uninitialised values or loops forever", "FormatError", ["§4.3"])
    hier = CHUNKS["HIER"].GRAMMAR.parse(base[_find(base, "HIER")][1])
    hier.nodes[2].members = [2]
    hier.nodes[2].ref = 2
    ch = [list(c) for c in base]
    ch[_find(ch, "HIER")][1] = CHUNKS["HIER"].GRAMMAR.build(hier)
    add("marker-in-two-nodes", assemble(ch), "marker 2 in nodes 1 and 2, marker 3 in none",
        "HIER node 2 members = [2]", "a marker decoded twice and another never", "FormatError",
        ["§4.3"])
    hier = CHUNKS["HIER"].GRAMMAR.parse(base[_find(base, "HIER")][1])
    hier.nodes[1].ref = 3
    ch = [list(c) for c in base]
    ch[_find(ch, "HIER")][1] = CHUNKS["HIER"].GRAMMAR.build(hier)
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
    pf = CHUNKS["PATT"].GRAMMAR.parse(base[_find(base, "PATT")][1])
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
    spec_101_invalid(add, base)


# ------------------------------------------ 1.0.1: invalid files the text settles --
def _meta_raw(key: bytes, value: bytes) -> bytes:
    """A one-entry meta payload from raw bytes (the grammar would encode str)."""
    return struct.pack("<HB", 1, len(key)) + key + struct.pack("<H", len(value)) + value


def _names(M):
    return [f"m{i:04d}" for i in range(M)]


def _patt_limit_file(K, L, n):
    """A flags-0 file whose node 1 (n members) declares K patterns of L frames; the coded
    field holds one all-zero frame (K x L x n is refused before it is read)."""
    d = Design(1, _names(n + 1), residual=False, bits=1)
    d.nodes.append((ROOT_PARENT, 0, [0], [1.0]))
    d.root = (0, np.zeros((1, 3), np.int64))
    d.node(0, 1, list(range(1, n + 1)),
           patt={"K": 1, "L": 1, "scale": 1, "order": 0, "values": np.zeros((1, n, 3), np.int64)},
           segs=(np.array([0]), np.array([1])))
    ch = d.chunks()
    i = _find(ch, "PATT")
    f = CHUNKS["PATT"].GRAMMAR.parse(ch[i][1])
    f.pattern_count, f.length = K, L
    ch[i][1] = CHUNKS["PATT"].GRAMMAR.build(f)
    return assemble(ch)


def spec_101_invalid(add, base):
    """Invalid files for the points spec 1.0.1 settles (Appendix B, issues 10 and 18)."""
    lim = (1 << 31) - 1
    # --- 10.3: QUNT output range
    add("qunt-step-1e300", assemble(_with_field(base, "QUNT", step=1e300, bits=31)),
        "QUNT step 1e300 with bits 31: step x 2^31 is about 2.1e309, beyond binary64",
        "QUNT step = 1e300, bits = 31", "outputs that are +-infinity (q = 2^20 is enough), for "
        "which the tolerance of §7.1 is undefined (inf - inf)", "FormatError", ["§4.4", "§6.8"])
    add("qunt-offset-plus-range-infinite", assemble(_with_field(
        base, "QUNT", step=2.0 ** 992, bits=31, offset=[0.0, -1.7e308, 0.0])),
        "QUNT offset y = -1.7e308, step 2^992, bits 31: each is finite, but |offset| + step x "
        "2^31 = 1.7e308 + 2^1023 is not", "QUNT step = 2^992, bits = 31, offset[1] = -1.7e308",
        "a decoder that checks step x 2^bits alone, or only axis 0, produces infinite outputs",
        "FormatError", ["§4.4", "§6.8"])
    step = float((2 ** 53 - 1) * 2 ** 940)
    add("qunt-range-tie-rounds-to-infinity", assemble(_with_field(
        base, "QUNT", step=step, bits=31, offset=[0.0, 0.0, 2.0 ** 970])),
        "QUNT step (2^53 - 1) x 2^940, bits 31, offset z = 2^970: |offset| + step x 2^31 is "
        "exactly 2^1024 - 2^970, the halfway point above DBL_MAX, which rounds to +inf",
        "QUNT step = (2^53 - 1) x 2^940, bits = 31, offset[2] = 2^970",
        "a decoder that rounds the other way at the boundary (or tests > instead of >= "
        "2^1024 - 2^970 in exact arithmetic) accepts a grid whose outputs can be infinite",
        "FormatError", ["§4.4"])
    # --- 10.5: meta values are strict UTF-8
    for slug, raw, what in [("surrogate", b"\xed\xa0\x80", "ED A0 80 (the surrogate U+D800)"),
                            ("overlong-nul", b"\xc0\x80", "C0 80 (an overlong U+0000)")]:
        ch = [list(c) for c in base]
        ch[_find(ch, "meta")][1] = _meta_raw(b"k", raw)
        add(f"meta-value-{slug}", assemble(ch), f"a meta value of bytes {what}",
            f"meta value 'v' replaced by {raw.hex(' ').upper()}",
            "a decoder that checks only keys (or decodes leniently, as CESU-8 or modified "
            "UTF-8) passes invalid text on", "FormatError", ["§1", "§4.11"])
    # --- 10.6: smry starts
    sm = CHUNKS["smry"].GRAMMAR.parse(base[_find(base, "smry")][1])
    F = 24
    for slug, starts, what in [("starts-not-at-0", [1, 12], "starts[0] = 1"),
                               ("starts-repeated", [0, 0], "starts = 0, 0"),
                               ("last-start-at-f", [0, F], f"starts[k-1] = F = {F}")]:
        sm.levels[0].starts = struct.pack("<2I", *starts)
        ch = [list(c) for c in base]
        ch[_find(ch, "smry")][1] = CHUNKS["smry"].GRAMMAR.build(sm)
        add(f"smry-{slug}", assemble(ch), f"a smry level whose {what}",
            f"smry level 0 starts = {starts}", "segment bounds outside the clip, or empty "
            "segments, in a summary that readers use without decoding", "FormatError",
            ["§4.10"])
    # --- 10.8: rate -0.0
    add("rate-minus-zero", assemble(_with_field(base, "MHDR", rate=-0.0)), "frame rate -0.0",
        "MHDR rate = -0.0", "IEEE -0.0 == 0 fails 'rate > 0'; a decoder that tests the sign "
        "bit, or rate >= 0, accepts a zero rate (division by zero in timestamps)",
        "FormatError", ["§1.3", "§4.1"])
    # --- 10.7, 18.1: §6.7 rule 1 and the §6.2 guard cover patterns no segment uses
    zeros = np.zeros((12, 2, 3), np.int64)
    d = _small(51)
    d.layers[1]["patt"] = {"K": 2, "L": 6, "scale": 1 << 15, "order": 1, "values": zeros}
    d.layers[1]["segs"] = (np.zeros(4, np.int64), np.array([6, 6, 6, 6]))
    d.build()                                           # valid with both patterns all zero
    d.layers[1]["patt"]["values"] = zeros.copy()
    d.layers[1]["patt"]["values"][6 + 2, 0, 0] = 1 << 21
    add("unused-pattern-out-of-range", assemble(d.chunks()),
        "PATT K = 2, scale 2^15; SEGS uses pattern 0 only (all zero); unused pattern 1 holds "
        "V = 2^21, so V x scale = 2^36", "PATT pattern 1, frame 2, member 0, x = 2^21",
        "a lazy decoder that de-normalises only the patterns SEGS refers to never checks "
        "pattern 1 and accepts a file that other decoders reject", "FormatError",
        ["§6.3", "§6.7"])
    e = np.zeros((8, 2, 3), np.int64)
    e[4 + 1:8, 0, 0] = lim                              # pattern 1, rows 1-3
    d.layers[1]["patt"] = {"K": 2, "L": 4, "scale": 1, "order": 2, "values": zeros[:8]}
    d.payloads[("PATT", 0)] = payload("PATT", {"node": 1, "pattern_count": 2, "length": 4,
                                               "scale": 1, "order": 2,
                                               "coded": rc_wide((e, {"period": 4}))})
    ch = d.chunks()
    del d.payloads[("PATT", 0)]
    add("unused-pattern-order2-overflow", assemble(ch),
        "PATT K = 2, L = 4, order 2; SEGS uses pattern 0 only (all zero); unused pattern 1 has "
        "residuals 2^31 - 1 on rows 1-3, so its difference d[3] = 3 (2^31 - 1) >= 2^32",
        "PATT pattern 1 residuals, rows 1-3, member 0, x = 2^31 - 1",
        "a lazy decoder that never reconstructs pattern 1 accepts the file; one that does, "
        "without the guard, forms values beyond the range §6.7 assumes", "FormatError",
        ["§6.2", "§6.3"])
    # --- 18.1: |x| < 2^36 before multiplying by g: x reaches 2^49 and g = 2^15
    F = (1 << 17) + 2
    d = Design(F, ["A", "B"], bits=31)
    d.nodes.append((ROOT_PARENT, 0, [0], [1.0]))
    d.root = (0, np.zeros((F, 3), np.int64))
    e = np.zeros((F, 1, 3), np.int64)
    e[:4, 0, 0] = [-(1 << 31) + (1 << 17) + 2, lim, lim, 1]   # d = 2^31 - 1, 2^32 - 2, 2^32 - 1..
    x = reconstruct(e, 2)                                     # passes the §6.2 guard
    assert int(x[-1, 0, 0]) == 1 << 49 and int(np.abs(x).max()) == 1 << 49
    d.node(0, 1, [1], resi={"base": 0, "order": 2, "scale": 1 << 15, "values": e})
    d.payloads[("RESI", 0)] = payload("RESI", {"node": 1, "base": 0, "order": 2,
                                               "scale": 1 << 15, "coded": rc_wide((e, {}))})
    add("residual-2pow49-times-g-2pow15", assemble(d.chunks()),
        f"RESI base 0, order 2, g = 2^15, F = {F}: the reconstructed residual reaches exactly "
        "2^49 on the last frame (every order-2 difference below 2^32), so x x g = 2^64",
        "RESI residuals chosen so that max |x| = 2^49",
        "a decoder that multiplies before testing |x| < 2^36 forms 2^64, which is 0 in 64-bit "
        "wrap-around (undefined behaviour for int64_t in C), and accepts", "FormatError",
        ["§1.1", "§6.5", "§6.7"])
    # --- 18.2: checks that must pass before the values they bound are used
    d = _small(52)
    d.layers[1]["patt"] = {"K": 1, "L": 13, "scale": 1, "order": 0,
                           "values": np.zeros((13, 2, 3), np.int64)}
    d.layers[1]["segs"] = (np.array([0, 0]), np.array([12, 12]))
    d.build()
    v = np.array([[[0, lim]], [[0, lim]]], np.int64)           # count = v + L = 2^31 + 12
    ch = d.chunks()
    ch[_find(ch, "SEGS")][1] = payload("SEGS", {"node": 1, "segment_count": 2,
                                                "coded": rc_wide((v, {}))})
    add("segs-counts-wrap-32-bits", assemble(ch),
        "SEGS with L = 13 and two segments of 2^31 + 12 frames each (count - L = 2^31 - 1): "
        "they add up to 2^32 + 24, not F = 24", "SEGS counts = 2^31 + 12, 2^31 + 12",
        "in 32-bit arithmetic the counts add up to 24 = F and the check passes; each count "
        "wraps negative in int32", "FormatError", ["§1.1", "§1.2", "§4.8"])
    # key-frame layers on node 2 (one member, no patterns)
    d = _small(53)
    d.build()

    def keyframes(*blocks):
        ch = d.chunks()
        ch[_find(ch, "RESI", 1)][1] = payload("RESI", {"node": 2, "base": 2, "order": 0,
                                                       "scale": 1, "coded": rc_wide(*blocks)})
        return assemble(ch)

    col = lambda *v: np.array(v, np.int64).reshape(-1, 1, 1)   # noqa: E731
    add("keyframe-count-2pow31", keyframes((col(0), {"signed": False}),
                                         (col(lim), {"signed": False})),
        "RESI base 2 with K_0 - 1 = 2^31 - 1, so K_0 = 2^31 > F (the payload ends there)",
        "node 2 RESI base 2, c_0 = 2^31 - 1",
        "K_m = 2^31 is negative in int32; sizing the span and key blocks from it before the "
        "check allocates 2^31 entries or more", "FormatError", ["§1.1", "§1.2", "§6.5"])
    keys = np.zeros((4, 1, 3), np.int64)
    add("keyframe-spans-wrap-32-bits", keyframes(
        (col(0), {"signed": False}), (col(3), {"signed": False}),
        (col(lim, lim, 24 - 2), {"signed": False}), (keys, {})),
        "RESI base 2 with K_0 = 4 and spans 2^31, 2^31 and F - 1 = 23: they add up to "
        "2^32 + 23, not F - 1", "node 2 RESI base 2, spans - 1 = 2^31 - 1, 2^31 - 1, 22",
        "in 32 bits the spans add up to F - 1 and pass; key times then index far outside "
        "the track", "FormatError", ["§1.1", "§1.2", "§6.5"])
    add("keyframe-value-2pow32-minus-2", keyframes(
        (col(0), {"signed": False}), (col(1), {"signed": False}),
        (col(24 - 2), {"signed": False}), (np.array([[[lim, 0, 0]], [[lim, 0, 0]]]), {})),
        "RESI base 2, p_0 = 0, K_0 = 2, key residuals 2^31 - 1 and 2^31 - 1: w_0 = 2^31 - 1, "
        "w_1 = w_0 + e_1 = 2^32 - 2", "node 2 RESI base 2, key residuals 2^31 - 1, 2^31 - 1",
        "a decoder that checks |w_k| < 2^31 only on the finished track, in 32 bits, sees "
        "w_1 wrap to -2 and accepts", "FormatError", ["§1.1", "§6.5"])
    # --- 18.3: products and sums that wrap in 32 bits
    add("patt-samples-2pow32", _patt_limit_file(32768, 4096, 32),
        "PATT K = 32768, L = 4096 on a node of 32 markers: K x L x n_i = 2^32",
        "PATT pattern_count = 32768, length = 4096 (n_i = 32)",
        "in 32 bits K x L x n_i wraps to 0, passes the 2^24 limit, and the block of 2^27 rows "
        "is allocated or decoded", "LimitExceededError", ["§1.2", "§4.7", "§8"])
    add("patt-samples-2pow40", _patt_limit_file(65535, 4096, 4095),
        "PATT K = 65535, L = 4096 on a node of 4095 markers (M = 4096): K x L x n_i is about "
        "2^40, the largest the fields allow", "PATT pattern_count = 65535, length = 4096 "
        "(n_i = 4095)", "a product formed in 32 bits wraps; one formed in a float loses "
        "exactness", "LimitExceededError", ["§1.2", "§4.7", "§8"])
    ch = [list(c) for c in base]
    ch[_find(ch, "smry")][1] = struct.pack("<BIB", 1, 1 << 31, 1) + struct.pack(
        "<Idd2I", 2, 0.0, 1.0, 0, 12)
    add("smry-4kd-wraps-32-bits", assemble(ch),
        "smry space 1 with D = 2^31 and one level of k = 2, and no means bytes: 4kD = 2^34",
        "smry replaced: space 1, dims 2^31, k = 2, starts 0, 12, no means",
        "in 32 bits 4kD = 2^34 wraps to 0 (and the sum k x D = 2^32 to 0), so a decoder reads "
        "no means and accepts", "FormatError", ["§1.2", "§4.10", "§8"])
    e = np.zeros((24, 1, 3), np.int64)
    e[1:4, 0, 1] = [lim, lim, 2]                         # d = 2^31 - 1, 2^32 - 2, 2^32
    ch = [list(c) for c in base]
    ch[_find(ch, "ROOT")][1] = payload("ROOT", {"order": 2, "coded": rc_wide((e, {}))})
    add("root-order2-difference-2pow32", assemble(ch),
        "ROOT order 2 with residuals 2^31 - 1, 2^31 - 1, 2 on y: the difference d[3] is "
        "exactly 2^32", "ROOT residuals replaced",
        "a guard written as |d| > 2^32 passes; a difference held in 32 bits wraps to 0 and "
        "the file decodes", "FormatError", ["§1.2", "§6.2"])
    # --- 18.4: a key prediction far beyond 32 bits before the |w_k| check
    F = (1 << 16) + 2
    d = Design(F, ["A", "B"], bits=31)
    d.nodes.append((ROOT_PARENT, 0, [0], [1.0]))
    d.root = (0, np.zeros((F, 3), np.int64))
    d.node(0, 1, [1], resi={"base": 2, "order": 0, "scale": 1,
                            "values": np.zeros((F, 1, 3), np.int64)})
    keys = np.array([[[lim, 0, 0]], [[-lim, 0, 0]], [[0, 0, 0]]], np.int64)
    d.payloads[("RESI", 0)] = payload("RESI", {"node": 1, "base": 2, "order": 0, "scale": 1,
                                               "coded": keyframe_blocks(
                                                   [0], [3], [1, 1 << 16], keys, wide=True)})
    add("keyframe-prediction-2pow47", assemble(d.chunks()),
        f"RESI base 2, p_0 = 0, F = {F}, spans 1 and 2^16, key residuals 2^31 - 1, "
        "-(2^31 - 1), 0: w_0 = 2^31 - 1, w_1 = 0, and w_2 = rnd(-(2^31 - 1) x 2^16, 1) is "
        "about -2^47", "node 1 RESI base 2, key residuals chosen",
        "in 32 bits (w_1 - w_0) x d_2 wraps to 2^16 and w_2 passes the check", "FormatError",
        ["§1.2", "§6.5", "§6.7"])
    # --- 10.12: a PATT left out
    m = _synth("walk", 24, markers=3, seed=54)
    d = design_from_motion(m, step=1.0, nodes=[(None, 0, [0]), (0, 1, [1, 2])], residual=False,
                           patterns={1: {"L": 6, "K": 2, "scale": 1, "order": 1}}, seed=54)
    d.build()
    ch = [c for c in d.chunks() if c[0] not in ("PATT", "SEGS")]
    add("patt-left-out-without-residual-flag", assemble(ch),
        "flags 0 (no residual layer) and node 1's PATT and SEGS left out: MEND follows ROOT",
        "PATT and SEGS of node 1 removed", "a parser that treats any missing PATT as K = 0 "
        "accepts a node with no motion at all", "FormatError", ["§3.4", "§4.7"])
    ch = [list(c) for c in base]
    del ch[_find(ch, "PATT")]
    add("patt-left-out-then-segs", assemble(ch),
        "flags 1 and node 1's PATT left out, but its SEGS still follows (where RESI must be)",
        "PATT of node 1 removed", "a parser that recognises a left-out PATT by a missing chunk "
        "alone applies segments to a node without patterns", "FormatError", ["§3.4"])


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
