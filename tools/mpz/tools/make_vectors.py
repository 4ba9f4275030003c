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
import functools
import json
import math
from pathlib import Path
import struct
import sys
from typing import NamedTuple

import numpy as np

import mpz
from mpz import container
from mpz.chunks import CHUNKS
from mpz.conformance import manifest as mf
from mpz.conformance.rangecoder import RefEncoder
from mpz.decoder import decode_layers
from mpz.entropy import BlockEncoder
from mpz.format import (
    ROOT_PARENT,
    SIGNATURE,
    VERSION_MAJOR,
    VERSION_MINOR,
    unit_code,
    unit_name,
)
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
        feats.update(_summary_features(s))
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
                       "units_code": h.units, "meta": dict(s.meta),
                       "error_metric": h.error_metric,
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

    def encoder_input(self, name, motion, max_errors, description, positions=None):
        """An encoder input: ``motion`` as IN.npy (its gaps all NaN, or ``positions`` as
        given, where a gap may have a finite coordinate) and IN.json."""
        import io
        buf = io.BytesIO()
        x = motion.as_nan() if positions is None else positions
        np.save(buf, np.ascontiguousarray(x, dtype="<f8"), allow_pickle=False)
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
        # issue 17: each vector lists the rules of the spec §7.4 index it probes (by slug, so
        # numbering is free), the encoder-made vectors their recipe, and the rules no small
        # file can probe their reason
        for e in self.entries + self.encoder_inputs:
            e["rules"] = sorted(VECTOR_RULES.get(_slug(e["name"]), ()), key=_rule_key)
            if e["name"] in ENCODER_RECIPES:
                e["recipe"] = ENCODER_RECIPES[e["name"]]
        man = {"schema_version": mf.SCHEMA_VERSION,
               "format": f"MPZ {VERSION_MAJOR}.{VERSION_MINOR}",   # the newest the set uses
               "generator": "python -m mpz.tools.make_vectors",
               "tolerance_rule": "spec §7.1: max_abs = step * 2^-20 + max|x| * 2^-50 over valid "
                                 "expected coordinates; rms = max_abs",
               "integer_layer_digest_rule": "sha256 of q as little-endian int64 [F, M, 3] C order, "
                                            "then the validity mask as uint8 [F, M] (1 = valid)",
               "vectors": self.entries, "encoder_inputs": self.encoder_inputs,
               "rule_exceptions": dict(sorted(RULE_EXCEPTIONS.items(),
                                              key=lambda kv: _rule_key(kv[0]))),
               "limit_boundaries": LIMIT_BOUNDARIES}
        mf.validate(man)
        (self.out / mf.MANIFEST_NAME).write_text(json.dumps(man, indent=1, ensure_ascii=False)
                                                 + "\n", encoding="utf-8")




# ------------------------------------------------------------ valid group --
class BoundBroken(RuntimeError):
    """The reference encoder broke the bound it was given: a vector made now would freeze
    the bug (and test_encoder_pinned.py's advice, "regenerate", would pass it on)."""


def encode_within(m, *, max_error, **kw) -> bytes:
    """``mpz.encode(m, max_error=..., **kw)``, checked: every encoder-made vector with a
    bound holds it against the motion it was made from, as the hand-built ones do
    (``Design.build``). A QA run: an encoder whose node bounds were 2 % too loose wrote all
    380 vectors without a word, and test_manifest.py and test_golden.py then passed."""
    data = mpz.encode(m, max_error=max_error, **kw)
    err = mpz.max_error(m, mpz.decode(data))
    if not err <= max_error:
        raise BoundBroken(f"the reference encoder breaks its bound: max error {err!r} > "
                          f"{max_error!r} ({m!r}); fix the encoder, do not regenerate")
    return data


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
    data = encode_within(m, max_error=1.0)
    vs.valid("valid", "v01-walk-bounded-1mm", data,
             "41-marker walk from the reference encoder with a 1 mm bound: patterns where they "
             "pay, residual layer everywhere (base 0 and base 1), metadata",
             {"encoder": "mpz.encode(max_error=1.0)"}, ["§4.7", "§4.8", "§4.9", "§4.11", "§6.3",
                                                        "§6.4", "§6.5"],
             "mpz.synth.generate('walk', frames=90, seed=1) -> mpz.encode(max_error=1.0)")
    # v02: encoder, lossy (no residual layer, no declared bound), gaps
    m = _synth("jump", 90, markers=20, seed=2, gap_fraction=0.08)
    data = mpz.encode(m, smoothing=3, metadata={"take": "v02"}, lossy=True)  # by name (issue 12)
    vs.valid("valid", "v02-jump-lossy-gaps", data,
             "20-marker jump from the reference encoder without a bound: pattern layer only "
             "(flags 0, error_metric 0), smoothing 3, 8% gaps in a MASK chunk",
             {"encoder": "mpz.encode(smoothing=3, lossy=True)", "residual": False,
              "error_metric": 0,
              "smoothing": 3}, ["§4.5", "§4.7", "§4.8", "§4.11", "§6.1", "§6.3", "§6.4"],
             "mpz.synth.generate('jump', frames=90, markers=20, seed=2, gap_fraction=0.08) -> "
             "mpz.encode(smoothing=3, lossy=True)")
    # v03: encoder with the optimal-partition summary
    m = _synth("wave", 60, markers=12, seed=3)
    data = encode_within(m, max_error=2.0, summary=(2, 5), summary_format="smry")
    vs.valid("valid", "v03-wave-bounded-2mm-summary", data,
             "12-marker wave from the reference encoder, 2 mm bound, with the ancillary smry "
             "chunk (2 and 5 segments) that decoders may ignore",
             {"encoder": "mpz.encode(max_error=2.0, summary=(2, 5), summary_format='smry')"},
             ["§4.9", "§4.10", "§4.11", "§6.5"],
             "mpz.synth.generate('wave', frames=60, markers=12, seed=3) -> "
             "mpz.encode(max_error=2.0, summary=(2, 5), summary_format='smry')")

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
    spec_17_uncommon(vs)


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
             "python -m mpz.tools.spec_example conformance/vectors/spec-example.mpz "
             "(not written by make_vectors)",
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
        "a 632-byte file declaring 2^24 frames x 4096 markers",
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
    spec_17_invalid(add, base)


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


# ------------------------------------------- issue 17: a vector for every rule --
def _repaired(data: bytes) -> bytes:
    return container.repair_crcs(data)


def _retyped(chunks, index: int, ctype: bytes) -> bytes:
    """The file of ``chunks`` with the type of chunk ``index`` replaced by ``ctype`` (any bytes),
    CRCs recomputed."""
    data = bytearray(assemble(chunks))
    pos = len(SIGNATURE) + sum(12 + len(c[1]) for c in chunks[:index])
    data[pos: pos + 4] = ctype
    return _repaired(bytes(data))


def _mnam_raw(entries) -> bytes:
    """An MNAM payload from raw (shared, suffix bytes) entries."""
    out = struct.pack("<H", len(entries))
    for shared, suffix in entries:
        out += struct.pack("<BB", shared, len(suffix)) + suffix
    return out


def _hier_with(base, edit) -> list:
    """``base`` with its HIER parsed, changed by ``edit(hier)`` and rebuilt."""
    ch = [list(c) for c in base]
    i = _find(ch, "HIER")
    hier = CHUNKS["HIER"].GRAMMAR.parse(ch[i][1])
    edit(hier)
    ch[i][1] = CHUNKS["HIER"].GRAMMAR.build(hier)
    return ch


def _node(parent, ref, members):
    return {"parent": parent, "ref": ref, "member_count": len(members), "members": members,
            "weights": [1.0] * len(members)}


def _replace(chunks, ctype, body, n=0) -> list:
    ch = [list(c) for c in chunks]
    ch[_find(ch, ctype, n)][1] = body
    return ch


def spec_17_invalid(add, base):
    """Invalid files for the rules of the spec §7.4 index that no earlier vector probes
    (issue 17): every forbidden value of §2.4 and every MUST-reject sentence of §3-§8."""
    lim = (1 << 31) - 1
    ch0 = [list(c) for c in base]
    # --- §2.4 / §3.2 chunk type bytes: each bad byte in an otherwise unknown *ancillary*
    # chunk, so a decoder that skips the letter test would skip the chunk and accept
    for btype, what in [(b"`zzz", "0x60 (backtick) in position 0"),
                        (b"z[zz", "0x5B ('[') in position 1"),
                        (b"zz@z", "0x40 ('@') in position 2"),
                        (b"zzz{", "0x7B ('{') in position 3")]:
        ch = [list(c) for c in base]
        at = _find(ch, "MEND")
        ch.insert(at, ["zzzz", b"\x00\x01"])
        add(f"chunk-type-byte-0x{btype[[b in b'z' for b in btype].index(False)]:02x}",
            _retyped(ch, at, btype), f"an ancillary-looking chunk {btype!r} before MEND: byte "
            f"{what} is not a letter", f"chunk {btype!r} (2 bytes) inserted",
            "a decoder that tests only the first byte, or the range 0x41-0x7A, or bit 5 (as "
            "PNG readers do), takes it for an unknown ancillary chunk and skips it",
            "FormatError", ["§2.4", "§3.2"])
    # --- §3.2 chunk length just over the limit
    b = bytearray(assemble(base))
    struct.pack_into("<I", b, len(SIGNATURE) + 12 + len(base[0][1]) + 4, (1 << 30) + 1)
    add("length-2pow30-plus-1", bytes(b), "MNAM length field 2^30 + 1, one over the limit",
        "MNAM length = 2^30 + 1", "a limit tested as > 2^30 + 1, or not at all (then only the "
        "end of the file stops the read)", "LimitExceededError", ["§2.4", "§3.2", "§8"])
    # --- §2.3, §3.3 CRCs of ancillary and unknown chunks
    ch = [list(c) for c in base]
    ch.insert(_find(ch, "MEND"), ["zzzz", b"\x00\x01"])
    data = bytearray(assemble(ch))
    data[-12 - 4] ^= 0x01                                 # last CRC byte before MEND
    add("unknown-ancillary-bad-crc", bytes(data), "an unknown ancillary chunk 'zzzz' with a "
        "wrong CRC", "CRC of 'zzzz' XOR 0x01 in its last byte", "a decoder that skips unknown "
        "chunks without reading their CRC accepts damaged files", "ChecksumError",
        ["§2.3", "§3.3"])
    data = bytearray(assemble(base))
    pos = len(SIGNATURE) + sum(12 + len(c[1]) for c in base[:_find(base, "meta")])
    data[pos + 8 + len(base[_find(base, "meta")][1])] ^= 0x80
    add("bad-crc-meta", bytes(data), "the CRC of the meta chunk off by one bit",
        "stored CRC of meta XOR 0x80", "a decoder that checks CRCs of critical chunks only",
        "ChecksumError", ["§3.3"])
    # --- §2.3 chunk types are exact byte strings
    add("mend-spelled-mEND", _retyped(ch0, _find(ch0, "MEND"), b"mEND"),
        "the last chunk is 'mEND' (an unknown ancillary chunk), so the file has no MEND",
        "MEND type bytes changed to 'mEND', CRC recomputed", "a case-insensitive type "
        "comparison takes it for MEND", "FormatError", ["§2.3", "§3.4"])
    # --- §3.2 payload layouts, §4.12
    add("mhdr-payload-short", assemble(_replace(base, "MHDR", base[0][1][:-1])),
        "an MHDR payload of 30 bytes (31 required)", "last MHDR byte (smoothing) removed",
        "a decoder that reads fixed fields without checking the length reads the next chunk's "
        "bytes as smoothing", "FormatError", ["§3.2", "§4.1"])
    add("mend-payload-1-byte", assemble(_replace(base, "MEND", b"\x00")),
        "an MEND chunk with a 1-byte payload", "MEND payload = 00",
        "a decoder that stops at the MEND type without checking its frame", "FormatError",
        ["§3.2", "§4.12"])
    # --- §3.4 order
    ch = [list(c) for c in base]
    meta = ch.pop(_find(ch, "meta"))
    ch.insert(0, meta)
    add("meta-before-mhdr", assemble(ch), "the meta chunk placed before MHDR",
        "meta moved to the front", "a decoder that skips ancillary chunks before looking for "
        "MHDR accepts a file that does not start with its header", "FormatError", ["§3.4"])
    ch = [list(c) for c in base]
    ch.insert(_find(ch, "QUNT") + 1, list(ch[_find(ch, "QUNT")]))
    add("second-qunt", assemble(ch), "QUNT twice in a row", "QUNT repeated",
        "a decoder that takes the last QUNT (or the first) silently", "FormatError", ["§3.4"])
    add("patt-wrong-node", assemble(_with_field(base, "PATT", node=2)),
        "the PATT of node 1 says node 2", "PATT node = 2", "layers applied to the wrong node",
        "FormatError", ["§3.4"])
    add("resi-wrong-node", assemble(_with_field(base, "RESI", node=2)),
        "the RESI of node 1 says node 2", "RESI (node 1) node = 2",
        "layers applied to the wrong node", "FormatError", ["§3.4"])
    ch = [list(c) for c in base]
    segs = payload("SEGS", {"node": 2, "segment_count": 1, "coded": rc((np.array([[[0, 0]]]),
                                                                        {}))})
    ch.insert(_find(ch, "PATT", 1) + 1, ["SEGS", segs])
    add("segs-after-k0-patt", assemble(ch), "a SEGS chunk after node 2's PATT, which has K = 0",
        "SEGS (node 2) inserted", "segments applied to a node without patterns", "FormatError",
        ["§3.4"])
    ch = [list(c) for c in base]
    del ch[_find(ch, "RESI", 1)]
    add("resi-missing-with-flag", assemble(ch), "flags bit 0 set but node 2 has no RESI",
        "RESI of node 2 removed", "a node silently decoded without its residual layer",
        "FormatError", ["§3.4"])
    add("resi-present-without-flag", assemble(_with_field(base, "MHDR", flags=0)),
        "flags 0 but every node still has its RESI chunk", "MHDR flags = 0",
        "residual layers applied (or skipped) against the header's word", "FormatError",
        ["§3.4", "§4.1"])
    for ctype in ("smry", "meta"):
        ch = [list(c) for c in base]
        ch.insert(_find(ch, "MEND"), list(ch[_find(ch, ctype)]))
        add(f"second-{ctype}", assemble(ch), f"two {ctype} chunks", f"{ctype} repeated",
            "which one counts is undefined: readers disagree", "FormatError",
            ["§3.4", CHUNKS[ctype].SECTION])
    # --- §2.4 header values
    header_cases: list[tuple[str, dict, str, str, str]] = [
            ("flags-bit-1", {"flags": 0x0003}, "reserved flag bit 1 set (flags 0x0003)",
             "a decoder that tests only the top bit, or flags > 1 in a signed byte",
             "FormatError"),
            ("marker-count-zero", {"marker_count": 0}, "marker_count 0",
             "empty arrays; names and nodes that index nothing", "LimitExceededError"),
            ("node-count-zero", {"node_count": 0}, "node_count 0", "no root node to decode",
             "FormatError"),
            ("node-count-over-markers", {"node_count": 5}, "node_count 5 for 4 markers",
             "more nodes than markers: some node has no member", "FormatError"),
            ("rate-zero", {"rate": 0.0}, "frame rate +0.0", "division by zero in timestamps",
             "FormatError"),
            ("rate-infinite", {"rate": math.inf}, "frame rate +inf",
             "a test of > 0 alone accepts it; timestamps collapse to 0", "FormatError"),
            ("rate-negative", {"rate": -120.0}, "frame rate -120",
             "time running backwards", "FormatError"),
            ("error-metric-2", {"error_metric": 2}, "error_metric 2 (reserved)",
             "a promise whose meaning the decoder does not know, reported as a bound",
             "FormatError"),
            ("error-bound-nan", {"error_metric": 1, "error_bound": math.nan}, "error_bound NaN",
             "NaN passes no comparison, so a bound check written as bound < 0 accepts it",
             "FormatError"),
            ("error-bound-infinite", {"error_bound": math.inf}, "error_bound +inf",
             "a test of >= 0 alone accepts it", "FormatError"),
            ("error-bound-negative", {"error_bound": -0.5}, "error_bound -0.5",
             "a bound no file can meet", "FormatError")]
    for slug, changes, what, risk, error in header_cases:
        add(slug, assemble(_with_field(base, "MHDR", **changes)), what,
            "MHDR " + ", ".join(f"{k} = {v!r}" for k, v in changes.items()), risk, error,
            ["§2.4", "§4.1"] + (["§8"] if error == "LimitExceededError" else []))
    d1 = _root_only(1, [[0, 0, 0]])
    one = d1.chunks()
    add("frame-count-2pow24-plus-1", assemble(_with_field(one, "MHDR", frame_count=(1 << 24) + 1)),
        "a one-marker file declaring 2^24 + 1 frames (F x M = 2^24 + 1 is under MAX_SAMPLES)",
        "MHDR frame_count = 2^24 + 1", "a decoder that checks F x M alone accepts it",
        "LimitExceededError", ["§2.4", "§4.1", "§8"])
    add("marker-count-4097", assemble(_with_field(one, "MHDR", marker_count=4097)),
        "marker_count 4097 with F = 1 (F x M is small)", "MHDR marker_count = 4097",
        "a decoder that checks F x M alone accepts it", "LimitExceededError",
        ["§2.4", "§4.1", "§8"])
    add("frames-x-markers-2pow26-plus-1", assemble(_with_field(
        base, "MHDR", frame_count=13421773, marker_count=5)),
        "F = 13421773 and M = 5: F x M = 2^26 + 1, each count within its own limit",
        "MHDR frame_count = 13421773, marker_count = 5", "a limit tested as > 2^26 + 1 or "
        "F x M >= 2^27 allocates 1.5 GiB", "LimitExceededError", ["§2.4", "§4.1", "§8"])
    # --- §2.4 / §4.2 names
    for slug, entries, what in [
            ("name-empty", [(0, b"A"), (0, b""), (0, b"C"), (0, b"D")], "name 1 is empty"),
            ("name-nul", [(0, b"A"), (0, b"B\x00"), (0, b"C"), (0, b"D")],
             "name 1 is 'B' U+0000"),
            ("name-invalid-utf8", [(0, b"A"), (0, b"\xff"), (0, b"C"), (0, b"D")],
             "name 1 is the byte FF (not UTF-8)"),
            ("mnam-shared-too-long", [(0, b"A"), (2, b"B"), (0, b"C"), (0, b"D")],
             "name 1 shares 2 bytes of the 1-byte name 'A'"),
            ("name-256-bytes", [(0, b"A" * 255), (255, b"B"), (0, b"C"), (0, b"D")],
             "name 1 is 255 shared bytes plus 'B': 256 bytes")]:
        add(slug, assemble(_replace(base, "MNAM", _mnam_raw(entries))), f"MNAM: {what}",
            f"MNAM entries {[(s, e[:8]) for s, e in entries]}", "names that cannot be "
            "displayed, looked up or written back (and, for shared, a copy past the previous "
            "name)", "FormatError", ["§2.4", "§4.2"])
    # --- §2.4 / §4.3 hierarchy
    def nodes(*ns):
        def edit(h):
            h.nodes = [_node(*n) for n in ns]
            h.count = len(ns)
        return edit
    for slug, ns, what in [
            ("hier-count-mismatch", [(0xFFFF, 0, [0]), (0, 1, [1, 2, 3])],
             "HIER lists 2 nodes, MHDR node_count is 3"),
            ("parent-0xffff-for-node-1", [(0xFFFF, 0, [0]), (0xFFFF, 1, [1, 2]), (1, 3, [3])],
             "node 1's parent is 0xFFFF"),
            ("root-parent-not-0xffff", [(0, 0, [0]), (0, 1, [1, 2]), (1, 3, [3])],
             "node 0's parent is 0"),
            ("node-member-count-zero", [(0xFFFF, 0, [0]), (0, 1, [1, 2, 3]), (1, 3, [])],
             "node 2 has no members (its marker moved to node 1)"),
            ("root-node-two-members", [(0xFFFF, 0, [0, 3]), (0, 1, [1, 2]), (1, 1, [1])],
             "node 0 has two members"),
            ("member-index-m", [(0xFFFF, 0, [0]), (0, 1, [1, 2]), (1, 3, [3, 4])],
             "node 2 lists marker 4 of 4 (indices are 0..3); every marker is owned once"),
            ("marker-repeated", [(0xFFFF, 0, [0]), (0, 1, [1, 2]), (1, 3, [3, 1])],
             "marker 1 is in nodes 1 and 2 (every marker is owned)"),
            ("marker-unowned", [(0xFFFF, 0, [0]), (0, 1, [1]), (1, 3, [3])],
             "marker 2 is in no node (no marker repeats)")]:
        ch = _hier_with(base, nodes(*ns))
        add(slug, assemble(ch), f"HIER: {what}", f"HIER nodes = {ns}",
            "a marker decoded twice, never, or relative to a node not yet decoded",
            "FormatError", ["§2.4", "§4.3"])
    # --- §2.4 / §4.4 grid
    grid_cases: list[tuple[str, dict, str]] = [
            ("step-nan", {"step": math.nan}, "QUNT step NaN"),
            ("step-negative", {"step": -1.0}, "QUNT step -1"),
            ("offset-nan", {"offset": [0.0, math.nan, 0.0]}, "QUNT offset y NaN"),
            ("offset-infinite", {"offset": [0.0, 0.0, -math.inf]}, "QUNT offset z -inf"),
            ("bits-0", {"bits": 0}, "QUNT bits 0"),
            ("bits-32", {"bits": 32}, "QUNT bits 32 (|q| < 2^32 overflows int32 outputs)")]
    for slug, changes, what in grid_cases:
        add(slug, assemble(_with_field(base, "QUNT", **changes)), what,
            "QUNT " + ", ".join(f"{k} = {v!r}" for k, v in changes.items()),
            "positions that are NaN, infinite or mirrored, or integers beyond 32 bits",
            "FormatError", ["§2.4", "§4.4"])
    # --- §2.4 / §4.7-§4.9 layer fields
    layer_cases: list[tuple[str, str, int, dict, str, str]] = [
            ("patt-order-3", "PATT", 0, {"order": 3}, "PATT (node 1) order 3", "FormatError"),
            ("resi-order-3", "RESI", 0, {"order": 3}, "RESI (node 1) order 3", "FormatError"),
            ("patt-k0-order-3", "PATT", 1, {"order": 3}, "PATT (node 2, K = 0) order 3",
             "FormatError"),
            ("patt-length-zero", "PATT", 0, {"length": 0}, "PATT (node 1, K = 2) length 0",
             "LimitExceededError"),
            ("patt-length-4097", "PATT", 0, {"length": 4097},
             "PATT (node 1, K = 2) length 4097", "LimitExceededError"),
            ("segs-count-zero", "SEGS", 0, {"segment_count": 0}, "SEGS segment_count 0",
             "LimitExceededError"),
            ("segs-count-over-f", "SEGS", 0, {"segment_count": 25},
             "SEGS segment_count 25 > F = 24", "LimitExceededError"),
            ("resi-base-3", "RESI", 1, {"base": 3}, "RESI (node 2) base 3", "FormatError"),
            ("resi-base2-with-patterns", "RESI", 0, {"base": 2, "order": 0},
             "RESI (node 1, which has K = 2 patterns) base 2", "FormatError"),
            ("resi-base2-order-1", "RESI", 1, {"base": 2, "order": 1},
             "RESI (node 2, K = 0) base 2 with order 1", "FormatError")]
    for slug, ctype, n, changes, what, error in layer_cases:
        ch = [list(c) for c in base]
        i = _find(ch, ctype, n)
        f = CHUNKS[ctype].GRAMMAR.parse(ch[i][1])
        for k, v in changes.items():
            f[k] = v
        ch[i][1] = CHUNKS[ctype].GRAMMAR.build(f)
        add(slug, assemble(ch), what, f"{ctype} " + ", ".join(f"{k} = {v}" for k, v in
                                                               changes.items()),
            "a field value with no meaning in 1.0 silently treated as another, or sizes "
            "beyond the §8 limits", error, ["§2.4", CHUNKS[ctype].SECTION]
            + (["§8"] if error == "LimitExceededError" else []))
    add("patt-samples-2pow24-plus-1", _patt_limit_file(24929, 673, 1),
        "PATT K = 24929, L = 673 on a node of 1 marker: K x L x n_i = 2^24 + 1",
        "PATT pattern_count = 24929, length = 673", "a limit tested as > 2^24 + 1",
        "LimitExceededError", ["§4.7", "§8"])
    m = _synth("walk", 24, markers=3, seed=54)
    d = design_from_motion(m, step=1.0, nodes=[(None, 0, [0]), (0, 1, [1, 2])], residual=False,
                           patterns={1: {"L": 6, "K": 2, "scale": 1, "order": 1}}, seed=54)
    d.build()
    ch = [list(c) for c in d.chunks() if c[0] != "SEGS"]
    ch[_find(ch, "PATT")][1] = payload("PATT", {"node": 1, "pattern_count": 0, "length": 1,
                                                "scale": 1, "order": 0, "coded": rc()})
    add("patt-k0-without-residual-flag", assemble(ch),
        "flags 0 (no residual layer) and node 1's PATT has K = 0", "PATT K = 0, SEGS removed",
        "a node with no motion at all decoded as zeros", "FormatError", ["§4.7"])
    # --- §2.4 / §4.10 summary
    sm = CHUNKS["smry"].GRAMMAR.parse(base[_find(base, "smry")][1])
    lv = sm.levels[0]
    starts = list(struct.unpack(f"<{lv.k}I", lv.starts))
    means = list(struct.unpack(f"<{len(lv.means) // 4}i", lv.means))
    smry_cases: list[tuple[str, bytes, str]] = [
            ("smry-space-2", smry_payload(2, sm.dims, [(lv.k, lv.wssse, lv.step, starts,
                                                        means)]), "smry space 2"),
            ("smry-dims-wrong", smry_payload(0, sm.dims + 3, [(lv.k, lv.wssse, lv.step, starts,
                                                               means + [0] * lv.k * 3)]),
             "smry space 0 with dims 3M + 3"),
            ("smry-levels-0", struct.pack("<BIB", 1, 0, 0), "smry with level_count 0"),
            ("smry-levels-65", smry_payload(1, 0, [(1, 0.0, 1.0, [0], [])] * 65),
             "smry with 65 levels (space 1, D = 0)"),
            ("smry-k-zero", smry_payload(1, 0, [(0, 0.0, 1.0, [], [])]), "a smry level k = 0"),
            ("smry-k-over-f", smry_payload(1, 0, [(25, 0.0, 1.0, list(range(25)), [])]),
             "a smry level k = 25 > F = 24"),
            ("smry-wssse-negative", smry_payload(1, 0, [(2, -1.0, 1.0, [0, 12], [])]),
             "a smry level wssse -1"),
            ("smry-wssse-nan", smry_payload(1, 0, [(2, math.nan, 1.0, [0, 12], [])]),
             "a smry level wssse NaN"),
            ("smry-step-zero", smry_payload(1, 0, [(2, 1.0, 0.0, [0, 12], [])]),
             "a smry level step 0")]
    for slug, body, what in smry_cases:
        add(slug, assemble(_replace(base, "smry", body)), what, "smry replaced: " + what,
            "a summary that readers use without decoding holds meaningless values",
            "FormatError", ["§2.4", "§4.10"])
    # --- §2.4 / §4.11 meta keys
    for slug, raw_key, what in [("meta-key-empty", b"", "an empty meta key"),
                            ("meta-key-invalid-utf8", b"\xc3", "a meta key of the byte C3 "
                             "(a truncated 2-byte sequence)")]:
        add(slug, assemble(_replace(base, "meta", _meta_raw(raw_key, b"v"))), what,
            "meta key replaced", "keys that cannot be looked up or written back", "FormatError",
            ["§2.4", "§4.11"])
    # --- §2.4 / §5.3 range-coded payloads
    ch = _with_field(base, "RESI")
    i = _find(ch, "RESI", 1)
    f = CHUNKS["RESI"].GRAMMAR.parse(ch[i][1])
    f.coded = b"\x00\x00\x00\x00"
    ch[i][1] = CHUNKS["RESI"].GRAMMAR.build(f)
    add("rc-payload-4-bytes", assemble(ch), "node 2's RESI coded field is 4 zero bytes",
        "RESI (node 2) coded = 00 00 00 00", "reading the 5-byte preamble past the payload",
        "FormatError", ["§2.4", "§5.3"])
    for ctype, n in [("MASK", 0), ("PATT", 0), ("SEGS", 0), ("RESI", 1)]:
        ch = [list(c) for c in base]
        ch[_find(ch, ctype, n)][1] += b"\x00"
        add(f"rc-leftover-byte-{ctype.lower()}", assemble(ch),
            f"one byte after the last range-coded symbol of {ctype}"
            + (" (node 2)" if n else ""), f"{ctype} payload + 1 zero byte",
            "a decoder that calls close() for some chunk types only accepts padding there",
            "FormatError", ["§5.3", "§5.5"])
    # --- §6.5 key frames, on node 2 (one member, no patterns)
    d = _small(53)
    d.build()

    def keyframes(*blocks, extra=b"", wide=False):
        ch = d.chunks()
        ch[_find(ch, "RESI", 1)][1] = payload("RESI", {"node": 2, "base": 2, "order": 0,
                                                       "scale": 1, "coded": (rc_wide if wide
                                                                             else rc)(*blocks)
                                                       + extra})
        return assemble(ch)

    col = lambda *v: np.array(v, np.int64).reshape(-1, 1, 1)   # noqa: E731
    keys2 = np.array([[[5, -3, 2]], [[7, 0, -1]]], np.int64)
    good_kf: tuple = ((col(0), {"signed": False}), (col(1), {"signed": False}),
               (col(22), {"signed": False}), (keys2, {}))
    assert mpz.decode(keyframes(*good_kf)).n_frames == 24
    add("rc-leftover-byte-resi-keyframes", keyframes(*good_kf, extra=b"\x00"),
        "one byte after the four key-frame blocks of node 2's RESI (base 2)",
        "RESI base 2 payload + 1 zero byte", "a decoder that forgets close() after the "
        "key-frame blocks accepts padding", "FormatError", ["§5.3", "§5.5", "§6.5"])
    for slug, blocks, what in [
            ("keyframe-source-self", ((col(1), {"signed": False}),) + good_kf[1:],
             "p_0 = 1: member 0 predicts from member (1 - 1) div 2 = 0, itself"),
            ("keyframe-one-key", ((col(0), {"signed": False}), (col(0), {"signed": False}),
                                  (np.zeros((0, 1, 1), np.int64), {"signed": False}),
                                  (keys2[:1], {})), "K_0 = 1 with F = 24"),
            ("keyframe-spans-short", good_kf[:2] + ((col(21), {"signed": False}),
                                                    good_kf[3]),
             "K_0 = 2 with one span of 22 frames: the spans add up to 22, not F - 1 = 23")]:
        add(slug, keyframes(*blocks), f"RESI base 2 on node 2: {what}", "node 2 RESI base 2",
            "reading a track that is not decoded yet, or key times outside the clip",
            "FormatError", ["§6.5"])
    add("keyframe-value-2pow31", keyframes(
        *good_kf[:3], (np.array([[[lim, 0, 0]], [[1, 0, 0]]]), {}), wide=True),
        "RESI base 2 on node 2: p_0 = 0, K_0 = 2, key residuals 2^31 - 1 and 1, so w_1 = "
        "w_0 + 1 = 2^31 exactly", "node 2 RESI base 2, key residuals 2^31 - 1, 1",
        "a check written as |w_k| > 2^31 lets w_k = 2^31 through (it wraps to -2^31 in "
        "int32)", "FormatError", ["§6.5"])
    d = Design(1, ["root", "m1", "m2"], step=0.5)
    d.nodes.append((ROOT_PARENT, 0, [0], [1.0]))
    d.root = (1, np.array([[10, -4, 7]], np.int64))
    d.node(0, 1, [1, 2], resi={"base": 2, "order": 0, "scale": 3,
                               "values": np.zeros((1, 2, 3), np.int64)})
    d.payloads[("RESI", 0)] = payload("RESI", {
        "node": 1, "base": 2, "order": 0, "scale": 3,
        "coded": keyframe_blocks([0, 1], [1, 2], [1], [[5, -6, 7], [2, 0, -1], [1, 1, 1]])})
    d.bits = 31
    add("keyframe-two-keys-one-frame", assemble(d.chunks()),
        "F = 1 with a key-frame layer whose member 1 has K_1 = 2 keys (and a span of 1)",
        "RESI base 2, c_1 = 1", "a key time beyond the last frame", "FormatError", ["§6.5"])
    # --- §6.7 rule 2 on a gap sample
    d = base_design()
    d.build()
    gaps = np.argwhere(~d.valid)
    t, mk = (int(v) for v in gaps[gaps[:, 1] > 0][0])
    node = next(i for i, n in enumerate(d.nodes) if mk in n[2])
    at = d.nodes[node][2].index(mk)
    d.layers[node]["resi"]["values"][t, at, 0] += 1 << d.bits
    add("gap-sample-beyond-bits", assemble(d.chunks()),
        f"the gap sample at frame {t}, marker {mk} decodes to |q| >= 2^bits; every valid "
        "sample stays in range", f"RESI (node {node}) value at frame {t} + 2^bits",
        "a decoder that range-checks only the samples it outputs accepts it", "FormatError",
        ["§6.1", "§6.7"])
    # --- §5.3 an overrun by exactly one byte (x45 lacks 3)
    ch = [list(c) for c in base]
    ch[_find(ch, "RESI")][1] = ch[_find(ch, "RESI")][1][:-1]
    add("rc-payload-one-byte-short", assemble(ch), "the RESI range-coded payload lacks its "
        "last byte (chunk length and CRC consistent)", "RESI payload shortened by 1 byte, "
        "CRC recomputed", "a decoder that tests pos > n instead of pos == n before reading "
        "reads one byte past the payload and decodes on", "FormatError", ["§5.3"])


def _next_name(vs: VectorSet, letter: str, slug: str) -> str:
    """``<letter><n>-slug`` with n one above the highest number of that group so far (the
    vectors of other helpers may come first)."""
    nums = [int(e["name"][1:3]) for e in vs.entries
            if e["name"][:1] == letter and e["name"][1:3].isdigit()]
    return f"{letter}{max(nums, default=0) + 1:02d}-{slug}"


def spec_17_uncommon(vs: VectorSet):
    """Valid files at the limits and boundaries of the spec §7.4 rules (issue 17)."""
    lim = (1 << 31) - 1
    # §4.11: a repeated meta key, the last value counts
    d = _small(61)
    d.ancillary.append(("meta", payload("meta", {"count": 3, "entries": [
        {"key": "take", "value": "first"}, {"key": "note", "value": "x"},
        {"key": "take", "value": "last"}]})))
    vs.valid("uncommon", _next_name(vs, "u", "meta-repeated-key"), d.build(),
             "a meta chunk in which the key 'take' repeats: the decoded metadata maps it to "
             "its last value, 'last' (§4.11), and the sidecar of §7.3 must say so",
             {"meta_repeated_key": "take"}, ["§4.11", "§6.8"],
             "hand-built from mpz.synth walk (frames=24, markers=4, seed=61)")
    # §5.3: code >= range after init is not checked
    for n in range(5, 64):
        coded = b"\x00" + b"\xff" * (n - 1)
        try:
            dec = mpz.entropy.BlockDecoder(coded)
            v = dec.block(1, 1, 3)
            dec.close()
        except mpz.MPZError:
            continue
        break
    assert int(np.abs(v).max()) == lim
    d = _root_only(1, v[:, 0, :])
    d.payloads[("ROOT", 0)] = payload("ROOT", {"order": 0, "coded": coded})
    vs.valid("uncommon", _next_name(vs, "u", "rc-code-above-range"), d.build(),
             f"a ROOT payload of 00 then {n - 1} bytes FF: after init code = 0xFFFFFFFF is "
             "not below range = 0xFFFFFFFF; a decoder MUST NOT check that and decodes every "
             "decision as 1, so every value is -(2^31 - 1)",
             {"root_coded": coded.hex()}, ["§5.3", "§5.4"], "bytes chosen here")
    # §6.2 and §6.7: an unused pattern with an order-2 difference of 2^32 - 1, and one whose
    # scaled value is 2^36 - 1 (only patterns no segment uses can hold such values)
    zeros = np.zeros((8, 2, 3), np.int64)
    d = _small(62)
    d.layers[1]["patt"] = {"K": 2, "L": 4, "scale": 1, "order": 2, "values": zeros}
    d.layers[1]["segs"] = (np.zeros(4, np.int64), np.array([6, 6, 6, 6]))
    d.build()
    e = np.zeros((8, 2, 3), np.int64)
    e[5:8, 0, 0] = [lim, lim, 1]                  # d = 2^31 - 1, 2^32 - 2, 2^32 - 1
    d.payloads[("PATT", 0)] = payload("PATT", {"node": 1, "pattern_count": 2, "length": 4,
                                               "scale": 1, "order": 2,
                                               "coded": rc_wide((e, {"period": 4}))})
    vs.valid("uncommon", _next_name(vs, "u", "unused-pattern-difference-2pow32-minus-1"),
             d.build(),
             "PATT K = 2, L = 4, order 2; SEGS uses pattern 0 only; pattern 1 has residuals "
             "2^31 - 1, 2^31 - 1, 1, so its differences reach 2^32 - 1, one below the guard of "
             "§6.2, and its values 5 x 2^31 - 4 stay below 2^36",
             {"order2_difference_max": 2 ** 32 - 1}, ["§6.2", "§6.3", "§6.7"],
             "hand-built from mpz.synth walk (frames=24, markers=4, seed=62), patterns chosen "
             "here")
    d = _small(63)
    v = np.zeros((12, 2, 3), np.int64)
    d.layers[1]["patt"] = {"K": 2, "L": 6, "scale": 4095, "order": 1, "values": v}
    d.layers[1]["segs"] = (np.zeros(4, np.int64), np.array([6, 6, 6, 6]))
    d.build()
    d.layers[1]["patt"]["values"] = v.copy()
    d.layers[1]["patt"]["values"][6 + 3, 1, 2] = -16781313     # x 4095 = -(2^36 - 1)
    vs.valid("uncommon", _next_name(vs, "u", "unused-pattern-scaled-2pow36-minus-1"),
             d.build(),
             "PATT K = 2, scale 4095; SEGS uses pattern 0 only; pattern 1 holds V = -16781313, "
             "so V x scale = -(2^36 - 1), one below the limit of §6.7 rule 1",
             {"patt_scale": [4095], "scaled_value": -(2 ** 36 - 1)}, ["§6.3", "§6.7"],
             "hand-built from mpz.synth walk (frames=24, markers=4, seed=63), patterns chosen "
             "here")
    # §6.5: key values of magnitude 2^31 - 1
    d = Design(3, ["root", "m1"], bits=31)
    d.nodes.append((ROOT_PARENT, 0, [0], [1.0]))
    d.root = (0, np.zeros((3, 3), np.int64))
    d.node(0, 1, [1], resi={"base": 2, "order": 0, "scale": 1,
                            "values": np.zeros((3, 1, 3), np.int64)})
    keys = [[lim, -lim, 0], [-lim, lim, 1]]                  # w_0 = +-(2^31 - 1), w_1 = 0 / 1
    d.payloads[("RESI", 0)] = payload("RESI", {"node": 1, "base": 2, "order": 0, "scale": 1,
                                               "coded": keyframe_blocks([0], [2], [2], keys,
                                                                        wide=True)})
    data = d.build()
    assert int(np.abs(decode_layers(data).q).max()) == lim
    vs.valid("uncommon", _next_name(vs, "u", "keyframe-values-2pow31-minus-1"), data,
             "RESI base 2, F = 3, one member with K = 2 keys at frames 0 and 2: w_0 = "
             "(2^31 - 1, -(2^31 - 1), 0), w_1 = (0, 0, 1); |w_k| = 2^31 - 1 is one below the "
             "limit of §6.5, and frame 1 interpolates to 2^30",
             {"resi_base": [2], "max_abs_key": lim}, ["§6.5", "§6.7"],
             "integers chosen here, coded with mpz.conformance.rangecoder")
    # §8 limits that fit in a small file: L = 4096, 64 smry levels, M = 4096
    d = _small(64)
    v = np.zeros((4096, 2, 3), np.int64)
    v[:, 0, 0] = np.arange(4096) % 7 - 3
    d.layers[1]["patt"] = {"K": 1, "L": 4096, "scale": 1, "order": 1, "values": v}
    d.layers[1]["segs"] = (np.zeros(2, np.int64), np.array([12, 12]))
    d.error_metric, d.error_bound = 0, 0.0
    vs.valid("uncommon", _next_name(vs, "u", "pattern-length-4096"), d.build(),
             "PATT with L = 4096 (MAX_PATTERN_LENGTH) stretched over segments of 12 frames",
             {"pattern_length": [4096]}, ["§4.7", "§6.3", "§8"],
             "hand-built from mpz.synth walk (frames=24, markers=4, seed=64), pattern chosen "
             "here")
    d = _small(65)
    d.ancillary.append(("smry", smry_payload(1, 0, [(1 + k % 24, float(k), 1.0,
                                                      list(range(1 + k % 24)), [])
                                                     for k in range(64)])))
    vs.valid("uncommon", _next_name(vs, "u", "smry-64-levels"), d.build(),
             "a smry chunk with 64 levels (MAX_SUMMARY_LEVELS), space 1, D = 0",
             {"smry_levels": 64}, ["§4.10", "§8"],
             "hand-built from mpz.synth walk (frames=24, markers=4, seed=65)")
    M = 4096
    d = Design(1, _names(M), bits=12)
    d.nodes.append((ROOT_PARENT, 0, [0], [1.0]))
    d.root = (0, np.zeros((1, 3), np.int64))
    w = (np.arange(3 * (M - 1), dtype=np.int64).reshape(1, M - 1, 3) % 13) - 6
    d.node(0, 1, list(range(1, M)), resi={"base": 1, "order": 0, "scale": 1, "values": w})
    vs.valid("uncommon", _next_name(vs, "u", "markers-4096"), d.build(),
             "M = 4096 markers (MAX_MARKERS) in one frame: a root and one node of 4095 "
             "members (RESI base 1)", {"markers": M}, ["§4.1", "§4.3", "§8"],
             "integers chosen here")


def _slug(name: str) -> str:
    """A vector's name without its number (``x05-bad-crc-root`` -> ``bad-crc-root``)."""
    return name.split("-", 1)[1] if name[:1] in "vuxe" and name[1:3].isdigit() else name


def _rule_key(rule: str) -> tuple:
    return tuple(int(p) for p in rule[2:].replace("-", ".").split("."))


def _rules(*pairs) -> dict:
    """{slug: rules} from (rules, slugs) pairs: each rule probed by each slug."""
    out: dict[str, set] = {}
    for rules, slugs in pairs:
        for slug in slugs.split():
            out.setdefault(slug, set()).update(rules.split())
    return {k: tuple(sorted(v, key=_rule_key)) for k, v in out.items()}


_DECODABLE_BASICS = ("walk-bounded-1mm jump-lossy-gaps wave-bounded-2mm-summary "
                     "orders-residual-only patterns-scale3-lossy-cm "
                     "patterns-residual-g2-smooth4-m absolute-residual-base1-g3-in "
                     "units-unknown-meta-smry all-chunk-types spec-example smrc-positions")

#: rule (spec §7.4) -> the vectors that probe it, by slug; make_vectors writes each vector's
#: ``rules`` from this table, and conformance/test_rules.py checks it against the spec
VECTOR_RULES = _rules(
    ("R-2.1-1 R-2.4-5", "major-version-2"),
    ("R-2.1-2", "minor-version-7-utf8-names"),
    ("R-2.3-1", "unknown-critical-ABCD"),
    ("R-2.3-2 R-3.4-9", "unknown-ancillary-zzzz"),
    ("R-2.3-3 R-3.3-2", "unknown-ancillary-bad-crc"),
    ("R-3.3-2", "bad-crc-meta"),
    ("R-2.3-4", "smry-starts-not-at-0 meta-value-surrogate smry-space-2 meta-key-empty"),
    ("R-2.3-5 R-3.4-12", "mend-spelled-mEND"),
    ("R-2.4-1 R-3.1-1", "bad-signature"),
    ("R-2.4-2", "chunk-type-byte-0x60 chunk-type-byte-0x5b chunk-type-byte-0x40 "
                "chunk-type-byte-0x7b"),
    ("R-2.4-3", "length-max-0xffffffff length-2pow30-plus-1"),
    ("R-2.4-4", "duplicate-mhdr"),
    ("R-2.4-6", "reserved-flag-bits flags-bit-1"),
    ("R-2.4-7", "frame-count-zero frame-count-2pow24-plus-1"),
    ("R-2.4-8", "marker-count-zero marker-count-4097"),
    ("R-2.4-9 R-8-2", "frames-x-markers-over-limit frames-x-markers-2pow26-plus-1"),
    ("R-2.4-10", "node-count-zero node-count-over-markers"),
    ("R-2.4-11", "rate-nan rate-minus-zero rate-zero rate-infinite rate-negative"),
    ("R-2.4-12", "units-code-5"),
    ("R-2.4-13", "error-metric-2"),
    ("R-2.4-14", "error-bound-nan error-bound-infinite error-bound-negative"),
    ("R-2.4-15", "smoothing-17"),
    ("R-2.4-16", "duplicate-marker-names name-empty name-nul name-invalid-utf8"),
    ("R-2.4-17", "node-parent-not-before-node parent-0xffff-for-node-1 root-parent-not-0xffff"),
    ("R-2.4-18", "node-member-count-zero root-node-two-members"),
    ("R-2.4-19", "marker-in-two-nodes member-index-m marker-repeated marker-unowned"),
    ("R-2.4-20", "reference-not-a-member"),
    ("R-2.4-21", "grid-step-zero step-nan step-negative"),
    ("R-2.4-22", "offset-nan offset-infinite"),
    ("R-2.4-23", "bits-0 bits-32"),
    ("R-2.4-24", "qunt-step-1e300 qunt-offset-plus-range-infinite "
                 "qunt-range-tie-rounds-to-infinity"),
    ("R-2.4-25", "mask-flag-2"),
    ("R-2.4-26", "root-order-3 patt-order-3 resi-order-3"),
    ("R-2.4-27", "patt-length-zero patt-length-4097"),
    ("R-2.4-28", "patt-scale-zero"),
    ("R-2.4-29 R-8-2", "segs-count-zero segs-count-over-f"),
    ("R-2.4-30", "segs-index-out-of-range segs-index-negative"),
    ("R-2.4-31", "segs-counts-exceed-f segs-counts-short-of-f segs-count-zero "
                 "segs-counts-wrap-32-bits"),
    ("R-2.4-32", "resi-base-3 resi-base1-with-patterns resi-base2-with-patterns "
                 "resi-base2-order-1"),
    ("R-2.4-33", "resi-scale-zero"),
    ("R-2.4-34", "smry-space-2"),
    ("R-2.4-35", "smry-dims-wrong"),
    ("R-2.4-36", "smry-levels-0 smry-levels-65"),
    ("R-2.4-37", "smry-k-zero smry-k-over-f"),
    ("R-2.4-38", "smry-wssse-negative smry-wssse-nan"),
    ("R-2.4-39", "smry-step-zero"),
    ("R-2.4-40", "smry-starts-not-at-0 smry-starts-repeated smry-last-start-at-f"),
    ("R-2.4-41", "meta-key-empty meta-key-invalid-utf8"),
    ("R-2.4-42", "meta-value-surrogate meta-value-overlong-nul"),
    ("R-2.4-43", "rc-payload-4-bytes"),
    ("R-2.4-44", "rc-first-byte-nonzero"),
    ("R-3.2-1", "truncated-in-mend truncated-in-meta"),
    ("R-3.2-2 R-8-1", "length-beyond-file truncated-in-mhdr truncated-in-mnam "
                      "truncated-in-hier truncated-in-qunt truncated-in-mask truncated-in-root "
                      "truncated-in-patt truncated-in-segs truncated-in-resi truncated-in-smry"),
    ("R-3.2-3", "qunt-trailing-byte mhdr-payload-short mend-payload-1-byte"),
    ("R-3.3-1", "bad-crc-mhdr bad-crc-hier bad-crc-root bad-crc-resi bad-crc-mend "
                "bad-crc-patt-payload"),
    ("R-3.4-1", "meta-before-mhdr"),
    ("R-3.4-2", "chunks-out-of-order missing-root missing-segs"),
    ("R-3.4-3", "second-qunt unknown-critical-ABCD"),
    ("R-3.4-4", "segs-wrong-node patt-wrong-node resi-wrong-node"),
    ("R-3.4-5", "missing-segs segs-after-k0-patt"),
    ("R-3.4-6", "resi-missing-with-flag resi-present-without-flag"),
    ("R-3.4-7", "walk-bounded-1mm wave-bounded-2mm-summary"),
    ("R-3.4-8", "patt-left-out-without-residual-flag patt-left-out-then-segs"),
    ("R-3.4-9", "units-unknown-meta-smry"),
    ("R-3.4-10", "second-smry second-meta"),
    ("R-3.4-11", "bytes-after-mend"),
    ("R-3.4-12", "missing-mend signature-only"),
    ("R-4.1-2", "error-bound-minus-zero jump-lossy-gaps"),
    ("R-4.2-1", "names-count-mismatch names-count-over-markers"),
    ("R-4.2-2", "mnam-shared-too-long"),
    ("R-4.2-3", "name-256-bytes"),
    ("R-4.2-4", "names-compared-as-bytes"),
    ("R-4.3-1", "hier-count-mismatch"),
    ("R-4.4-1", "qunt-step-2pow992-bits-31 qunt-range-rounds-to-max-finite"),
    ("R-4.5-1", "mask-all-valid"),
    ("R-4.7-1", "patt-k0-order-3 patt-scale-zero"),
    ("R-4.7-2 R-8-2", "patt-samples-2pow32 patt-samples-2pow40 patt-samples-2pow24-plus-1"),
    ("R-4.7-3", "patt-k0-without-residual-flag"),
    ("R-4.7-4", "patt-k0-ignored-payload patt-k0-coded-empty patt-k0-coded-3-bytes"),
    ("R-4.10-1 R-8-2", "smry-4kd-wraps-32-bits"),
    ("R-4.10-2", "smry-angles-no-dims smry-64-levels"),
    ("R-4.11-1", "meta-nul"),
    ("R-4.11-2 R-6.8-2", "meta-repeated-key"),
    ("R-4.12-1", "mend-payload-1-byte"),
    ("R-5.2-1 R-5.5-2 R-6.2-3 R-6.8-1", _DECODABLE_BASICS),
    ("R-6.2-3", "one-frame one-marker"),
    ("R-5.3-1", "rc-payload-short rc-payload-one-byte-short"),
    ("R-5.3-2", "rc-leftover-bytes rc-leftover-byte-mask rc-leftover-byte-patt "
                "rc-leftover-byte-segs rc-leftover-byte-resi rc-leftover-byte-resi-keyframes"),
    ("R-5.3-3", "rc-code-above-range"),
    ("R-5.4-1", "root-values-k30 rc-code-above-range"),
    ("R-5.5-1", "keyframes-one-frame"),
    ("R-5.6-1", "context-value-2pow32"),
    ("R-6.1-1", "marker-gap-throughout gap-sample-beyond-bits"),
    ("R-6.2-1", "order2-overflow root-order2-difference-2pow32 "
                "unused-pattern-order2-overflow"),
    ("R-6.2-2", "unused-pattern-difference-2pow32-minus-1"),
    ("R-6.3-1", "patterns-scale3-lossy-cm short-segments-and-patterns long-20000-frames "
                "pattern-length-4096"),
    ("R-6.4-1", "max-smoothing-16 patterns-residual-g2-smooth4-m"),
    ("R-6.5-1", "keyframe-source-self"),
    ("R-6.5-2", "keyframe-count-2pow31 keyframe-one-key keyframe-two-keys-one-frame"),
    ("R-6.5-3", "keyframe-spans-wrap-32-bits keyframe-spans-short"),
    ("R-6.5-4", "keyframe-value-2pow32-minus-2 keyframe-prediction-2pow47 "
                "keyframe-value-2pow31"),
    ("R-6.5-5", "keyframe-values-2pow31-minus-1"),
    ("R-6.5-6", "walk-bounded-1mm wave-bounded-2mm-summary keyframes-one-frame"),
    ("R-6.6-1", "orders-residual-only absolute-residual-base1-g3-in markers-4096"),
    ("R-6.7-1", "unused-pattern-out-of-range residual-2pow49-times-g-2pow15"),
    ("R-6.7-2", "unused-pattern-scaled-2pow36-minus-1"),
    ("R-6.7-3", "value-beyond-bits gap-sample-beyond-bits"),
    ("R-6.7-4", "values-at-bits-limit root-values-k30"),
    ("R-6.8-2", "rate-65.0364227294921875 meta-nul names-compared-as-bytes "
                "units-unknown-meta-smry rate-59.94 names-meta-white-space-non-bmp"),
    ("R-7.2-1 R-7.2-2 R-7.3-1", "walk-41-gaps mixed-10-metres names-cm-59.94-gap-throughout "
                        "inches-23.976 no-units"),
)

#: rules no small file can probe: the reason, and the unit test that covers the boundary
RULE_EXCEPTIONS = {
    "R-4.1-1": "a decoder's own lower limit is not a property of any file; the reference's "
               "max_samples is tested in conformance/test_rules.py::test_lower_sample_limit",
    "R-8-3": "an allocation failure depends on the decoder's memory, not on the file; the "
             "reference lets MemoryError through unwrapped, tested in conformance/"
             "test_rules.py::test_allocation_failure_is_not_invalid_data",
}

#: boundaries at a limit whose valid file would be impractical (documented here, tested in
#: unit tests; the invalid side of each has a vector)
LIMIT_BOUNDARIES = {
    "F x M = 2^26 (MAX_SAMPLES)": "a valid file is small, but its expected output is 1.5 GiB "
        "of float64; tested in conformance/test_rules.py::test_limit_boundaries "
        "(frames-x-markers-2pow26-plus-1 is the invalid side)",
    "chunk length = 2^30 (MAX_CHUNK_LENGTH)": "the payload must be present, so the file is "
        "1 GiB; tested in conformance/test_rules.py::test_chunk_length_boundary "
        "(length-2pow30-plus-1 is the invalid side)",
    "K x L x n_i = 2^24 (MAX_PATTERN_SAMPLES)": "3 x 2^24 coded values, 400 MB of int64 while "
        "decoding; tested in conformance/test_rules.py::test_limit_boundaries "
        "(patt-samples-2pow24-plus-1 is the invalid side)",
    "F = 2^24 (MAX_FRAMES)": "its expected output is 384 MiB; tested in "
        "conformance/test_rules.py::test_limit_boundaries",
    "sum of k x D = 2^24 (MAX_SUMMARY_VALUES)": "the means alone are 64 MiB; tested in "
        "conformance/test_rules.py::test_limit_boundaries. Its invalid side is isolated for "
        "smrc (smrc-values-over-limit) but not for smry: a smry past the limit must hold "
        "64 MiB of means, and smry-4kd-wraps-32-bits (R-4.10-1) is rejected for its length "
        "first, so it probes 4kD formed in 64 bits, not the limit (a review of stop 71)",
}

#: how the encoder-made vectors were made, so that a test can re-encode them byte for byte
#: (mpz.synth.generate arguments, mpz.encode keyword arguments)
ENCODER_RECIPES = {
    "v01-walk-bounded-1mm": {"synth": {"kind": "walk", "frames": 90, "seed": 1},
                             "encode": {"max_error": 1.0}},
    "v02-jump-lossy-gaps": {"synth": {"kind": "jump", "frames": 90, "markers": 20, "seed": 2,
                                      "gap_fraction": 0.08},
                            "encode": {"smoothing": 3, "metadata": {"take": "v02"},
                                       "lossy": True}},
    "v03-wave-bounded-2mm-summary": {"synth": {"kind": "wave", "frames": 60, "markers": 12,
                                               "seed": 3},
                                     "encode": {"max_error": 2.0, "summary": [2, 5],
                                                "summary_format": "smry"}},
}


# ------------------------------------------------- §4.13 C3D archive (MPZ 1.1) --
def _c3d_header(P, C, n, F, first, scale, rate, events=()):
    """A normalised 512-byte C3D header (C3D.org layout), built with struct."""
    h = bytearray(512)
    h[0], h[1] = 2, 0x50
    struct.pack_into("<hhHHh", h, 2, P, C * n, first, first + F - 1, 10)
    struct.pack_into("<f", h, 12, scale)
    struct.pack_into("<hh", h, 16, 11, n)
    struct.pack_into("<f", h, 20, rate)
    if events:
        struct.pack_into("<hh", h, 298, 12345, len(events))
        for i, (t, label) in enumerate(events):
            struct.pack_into("<f", h, 304 + 4 * i, t)
            h[376 + i] = 1
            h[396 + 4 * i:400 + 4 * i] = label.encode("ascii").ljust(4)[:4]
    return bytes(h)


def _c3d_records(labels, models, C, scale, rate, n):
    """A parameter section: POINT (with ANGLES/POWERS listing the model outputs), ANALOG,
    EVENT, a byte parameter, a locked one and a parameter of an undeclared group."""
    from mpz.io.c3dbin import ParamRecord as R

    def chars(rows):
        w = max([1] + [len(r) for r in rows])
        return (w, len(rows)), b"".join(r.encode("latin-1").ljust(w) for r in rows)

    dims, lab = chars(labels)
    out = [R(-1, False, b"POINT", b"3-D point data"),
           R(1, True, b"USED", b"points", 2, (), struct.pack("<h", len(labels))),
           R(1, False, b"SCALE", b"", 4, (), struct.pack("<f", scale)),
           R(1, False, b"RATE", b"", 4, (), struct.pack("<f", rate)),
           R(1, False, b"DATA_START", b"", 2, (), struct.pack("<h", 11)),
           R(1, False, b"LABELS", b"labels", -1, dims, lab)]
    for kind, names in models.items():
        d, v = chars(names)
        out.append(R(1, False, kind.encode(), b"model outputs", -1, d, v))
    out += [R(-2, False, b"ANALOG", b""),
            R(2, False, b"USED", b"", 2, (), struct.pack("<h", C)),
            R(2, False, b"RATE", b"", 4, (), struct.pack("<f", rate * n)),
            R(2, False, b"GAIN", b"bytes", 1, (C,), bytes(range(1, C + 1))),
            R(-3, True, b"EVENT", b"events"),
            R(3, False, b"TIMES", b"", 4, (2, 2), struct.pack("<4f", 0, 0.1, 0, 0.3)),
            R(3, False, b"Mixed Case Name", b"", -1, (0,), b""),
            R(9, False, b"ORPHAN", b"group 9 is never declared", 2, (), b"\x07\x00")]
    return out


def c3d_motion(seed, *, storage, F=24, M=5, J=2, C=3, n=4, scale=0.5):
    """A synthetic motion with a C3D archive (mpz.synth, integers chosen here): float32 or
    int16 storage, J model outputs, C analog channels of n samples per frame, whose words
    need both channel modes (ADC counts as floats, -0.0, NaN, infinities, 1e38); int16
    points on the grid of POINT:SCALE ``scale``."""
    from mpz.c3darchive import C3DArchive
    rng = np.random.default_rng(seed)
    m = _synth("walk", F, markers=M, seed=seed, gap_fraction=0.05)
    pos = m.positions
    if storage == 0:                                  # on the int16 grid of POINT:SCALE
        pos = np.rint(np.nan_to_num(pos) / scale) * scale
        pos[~m.valid] = np.nan
    P = M + J
    slots = list(rng.permutation(P))
    models = np.cumsum(rng.normal(0, 0.3, (F, J, 3)), axis=0) + 5.0
    if storage == 0:
        models = np.rint(models / scale) * scale
    mvalid = np.ones((F, J), bool)
    if J:
        mvalid[:3, 0] = False                         # a model output starting late
    models[~mvalid] = np.nan
    words = rng.integers(0, 4000, (F, P)).astype(np.int64)
    words[:, :] += (rng.integers(0, 2, (F, P)) * 256)           # a camera bit
    dt = "<i2" if storage == 0 else "<f4"
    marker_slot = {s: p for p, s in enumerate(slots) if s < M}
    for mk in range(M):
        words[~m.valid[:, mk], marker_slot[mk]] = -1
    for j in range(J):
        words[~mvalid[:, j], slots.index(M + j)] = -1
    T = F * n
    if storage == 0:
        analog = rng.integers(-2048, 2048, (T, C)).astype("<i2")
    else:
        analog = np.zeros((T, C), "<f4")
        if C >= 2:
            analog[:, 0] = rng.integers(-3000, 3000, T) * 2.0 ** -15       # mode 0, shift -15
            special = np.array([-0.0, np.nan, np.inf, -np.inf, 1e38, -1e-40], "<f4")
            analog[:, 1] = np.where(np.arange(T) % 7 == 0, special[np.arange(T) % 6],
                                    np.cumsum(rng.normal(0, 1, T)).astype("<f4"))
        for c in range(2, C):
            analog[:, c] = rng.integers(0, 4096, T)
    labels = [""] * P
    names = list(m.names)
    for p, s in enumerate(slots):
        labels[p] = names[s] if s < M else f"OUT{s - M}"
    labels[slots.index(0)] = names[0]
    kinds = {"ANGLES": [f"OUT{j}" for j in range(J) if j % 2 == 0],
             "POWERS": [f"OUT{j}" for j in range(J) if j % 2 == 1]}
    a = C3DArchive(84, _c3d_header(P, C, n, F, 10, -scale if storage else scale, m.rate,
                                   events=((0.1, "FS"), (0.3, "FO"))),
                   _c3d_records(labels, kinds, C, scale, m.rate, n), slots,
                   words.astype(dt), storage, models, mvalid,
                   [0 if j % 2 == 0 else 3 for j in range(J)], analog, n, storage)
    return mpz.Motion(pos, m.names, m.rate, m.units, m.valid, {"format": "c3d"},
                      extras={"c3d": a})


def _summary_features(s) -> dict:
    """What a file's summary chunk decodes to, for implementers (a review of stop 49 found
    no way to check decoded summary values without the reference): sha256 of its integer
    levels; {} without a summary."""
    import hashlib
    if s.summary is None:
        return {}
    rec = s.summary.record
    if rec.TYPE == "smry":
        levels = [(np.frombuffer(lv.starts, "<u4"), np.frombuffer(lv.means, "<i4"))
                  for lv in rec.levels]
    else:
        levels = rec.levels_decoded(s.header.frame_count)
    h = hashlib.sha256()
    for starts, q in levels:
        h.update(np.ascontiguousarray(starts, "<i8").tobytes())
        h.update(np.ascontiguousarray(q, "<i8").tobytes())
    return {"summary_sha256": h.hexdigest(),
            "summary_digest_rule": "sha256, level after level in stored order, of the starts "
                                   "[k] then the integer means q [k, D] (smry: as stored; "
                                   "smrc: §4.15 steps 1-5), both int64 little-endian, C order"}


def _c3d_archive_features(m) -> dict:
    """The archive digest and counts of :func:`_c3d_features` for a decoded motion ``m``."""
    import hashlib
    a = m.extras["c3d"]
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(a.words).tobytes())
    h.update(np.ascontiguousarray(a.analog).tobytes())
    h.update(np.ascontiguousarray(a.models, "<f8").tobytes())
    return {"c3d_points": len(a.slots), "c3d_model_outputs": int(a.models.shape[1]),
            "c3d_analog_channels": a.channels, "c3d_parameters": len(a.records),
            "c3d_archive_sha256": h.hexdigest(),
            "c3d_archive_digest_rule": "sha256 of the words [F, P] (int16 or float32 LE), the "
                                       "analog words [F n, C] and the model values [F, J, 3] "
                                       "(float64 LE, NaN at gaps)"}


def _c3d_features(data):
    """What the archive decodes to, for implementers: sha256 of the words and model values,
    and of the C3D file that spec §6.9's writer makes of it."""
    import hashlib

    from mpz.io.c3d import archive_bytes
    m = mpz.decode(data)
    return {**_c3d_archive_features(m),
            "c3d_file_sha256": hashlib.sha256(archive_bytes(m)).hexdigest()}


def _add_invalid(vs: VectorSet, slug: str, data: bytes, description: str, corruption: str,
                 risk: str, error: str, sections: list[str]) -> None:
    """An invalid vector named by the next free x number and ``slug`` (the builders' add)."""
    vs.invalid(_numbered(vs, "x", slug), data, description, corruption, risk, error,
               sections)


def _axis_changed(models, **changes) -> tuple:
    """cpnt models with axis 1 (y) of model output 0 changed."""
    import dataclasses
    md = list(models)
    axes = list(md[0].axes)
    axes[1] = dataclasses.replace(axes[1], **changes)
    md[0] = dataclasses.replace(md[0], axes=tuple(axes))
    return tuple(md)


@functools.cache
def _smrc_base() -> bytes:
    """v-smrc-positions: a 4-marker walk with levels k = 2 and 5 in smrc, which the smrc
    builders edit (encoded once)."""
    return encode_within(_synth("walk", 24, markers=4, seed=141), max_error=1.0, summary=(2, 5))


@functools.cache
def _c3d_float_base() -> bytes:
    """v-c3d-archive-float32, which the C3D archive builders edit (encoded once)."""
    return encode_within(c3d_motion(71, storage=1), max_error=1.0)


@functools.cache
def _bvhs_base() -> bytes:
    """v-bvhs-synthetic-default, which the skeleton builders edit (encoded once)."""
    from mpz.io.bvh import parse_bvh
    return mpz.encode(parse_bvh(_skeleton_bvh_text(), source="synthetic.bvh"))


@functools.cache
def _asfs_base() -> bytes:
    """v-asfs-synthetic-default, which the skeleton builders edit (encoded once)."""
    from mpz.io.amc import parse_amc, parse_asf
    return mpz.encode(parse_amc(_skeleton_amc_text(), parse_asf(_SKELETON_ASF),
                                source="synthetic_01.amc"))


def _numbered(vs: VectorSet, letter: str, slug: str) -> str:
    import re
    found = [re.match(r"[a-z](\d+)-", e["name"]) for e in vs.entries
             if e["name"][:1] == letter]
    nums = [int(x.group(1)) for x in found if x is not None]
    return f"{letter}{max(nums, default=0) + 1:02d}-{slug}"


def _c3d_rebuild(data, ctype, **changes):
    """``data`` with the first ``ctype`` chunk's record fields changed (payload rebuilt)."""
    import dataclasses
    from typing import Any

    from mpz.container import scan
    out = []
    done = False
    for c in scan(data).chunks:
        rec: Any = c.record
        if c.type == ctype and not done:
            out.append((c.type, dataclasses.replace(rec, **changes).dump()))
            done = True
        else:
            out.append((c.type, c.payload))
    return assemble(out)


def _c3d_chunks(data):
    from mpz.container import scan
    return [[c.type, c.payload] for c in scan(data).chunks]


def c3d_archive_vectors(vs: VectorSet):
    """Valid, uncommon and invalid files for the C3D archive chunks (spec §4.13, §6.9,
    MPZ 1.1), from synthetic motions with synthetic archives (never real files)."""
    import dataclasses

    from mpz.chunks import Cana, Chdr, Cpnt, Cprm
    secs = ["§2.1", "§2.3", "§4.13", "§4.13.1", "§4.13.2", "§4.13.3", "§4.13.4", "§6.9"]
    m = c3d_motion(71, storage=1)
    good = encode_within(m, max_error=1.0)
    vs.valid("valid", _numbered(vs, "v", "c3d-archive-float32"), good,
             "a C3D archive (1.1): header with events, parameters (byte, locked, undeclared "
             "group, mixed-case name), 7 points of which 2 model outputs (ANGLES, POWERS) in "
             "shuffled slots, float32 words, 3 analog channels of 4 samples per frame: "
             "fixed-point (mode 0, shift -15), specials -0.0, NaN, +-inf, 1e38, a subnormal "
             "(mode 1), integers", _c3d_features(good), secs,
             "make_vectors.c3d_motion(71, storage=1) -> mpz.encode(max_error=1.0)")
    mi = c3d_motion(72, storage=0, J=1, C=2, n=2)
    exact = mpz.encode(mi)
    vs.valid("uncommon", _numbered(vs, "u", "c3d-int16-exact-on-grid"), exact,
             "an int16 C3D archive coded by default: exact on the source grid (QUNT step = "
             "POINT:SCALE 0.5, offset 0, error_bound 0), int16 words and analog",
             _c3d_features(exact), secs, "make_vectors.c3d_motion(72, storage=0) -> "
             "mpz.encode() (the default)")
    # no analog, no model outputs: cpnt with J = 0 and no cana
    mn = c3d_motion(73, storage=1, J=0, C=0)
    bare = encode_within(mn, max_error=2.0)
    assert "cana" not in [c[0] for c in _c3d_chunks(bare)]
    vs.valid("uncommon", _numbered(vs, "u", "c3d-no-analog-no-models"), bare,
             "a C3D archive without analog channels (no cana) and without model outputs "
             "(J = 0)", _c3d_features(bare), secs,
             "make_vectors.c3d_motion(73, storage=1, J=0, C=0) -> mpz.encode(max_error=2.0)")

    add = functools.partial(_add_invalid, vs)

    ch = _c3d_chunks(good)
    i_hdr = next(i for i, c in enumerate(ch) if c[0] == "chdr")
    two = ch[:i_hdr + 1] + [ch[i_hdr]] + ch[i_hdr + 1:]
    add("c3d-two-chdr", assemble(two), "two chdr chunks", "chdr repeated",
        "a decoder that keeps the last header writes a C3D from the wrong one",
        "FormatError", ["§4.13"])
    add("c3d-no-cprm", assemble([c for c in ch if c[0] != "cprm"]),
        "a C3D archive without its parameter section", "cprm removed",
        "a writer with no parameters writes a C3D no reader understands", "FormatError",
        ["§4.13"])
    ana = next(c for c in ch if c[0] == "cana")
    add("c3d-two-cana", assemble(ch[:-1] + [ana] + ch[-1:]), "two cana chunks",
        "cana repeated before MEND", "which analog channels?", "FormatError", ["§4.13"])
    add("chdr-processor-87", _c3d_rebuild(good, "chdr", processor=87), "chdr processor 87",
        "processor = 87", "an unknown processor type", "FormatError", ["§4.13.1"])
    hdr = next(c for c in ch if c[0] == "chdr")
    blk = bytearray(Chdr.load(hdr[1]).block)
    blk[1] = 0x51
    add("chdr-key-0x51", _c3d_rebuild(good, "chdr", block=bytes(blk)),
        "chdr block byte 1 = 0x51", "C3D key byte changed",
        "a C3D written from it is not a C3D", "FormatError", ["§4.13.1"])
    prm = Cprm.load(next(c for c in ch if c[0] == "cprm")[1])

    def with_record(i, **kw):
        recs = list(prm.records)
        recs[i] = dataclasses.replace(recs[i], **kw)
        return _c3d_rebuild(good, "cprm", records=tuple(recs))

    add("cprm-group-0", with_record(1, group=0), "a parameter record with group id 0",
        "record 1 group = 0", "C3D ends the section at group 0: the rest is lost",
        "FormatError", ["§4.13.2"])
    add("cprm-name-empty", with_record(0, name=b""), "a group record with an empty name",
        "record 0 name = b''", "C3D ends the section at a zero name length", "FormatError",
        ["§4.13.2"])
    add("cprm-name-128-bytes", with_record(0, name=b"N" * 128), "a name of 128 bytes",
        "record 0 name 128 bytes", "a C3D name length is a signed byte: 128 is -128 (locked, "
        "128 bytes?)", "FormatError", ["§4.13.2"])
    add("cprm-type-3", with_record(1, type=3, data=b"\x00" * 3),
        "a parameter of type 3", "record 1 type = 3", "an unknown type has no element size",
        "FormatError", ["§4.13.2"])
    add("cprm-eight-dims", with_record(11, dims=b"\x01" * 8, data=b"\x01"),
        "a parameter with 8 dimensions", "record 11 dims 8 x 1", "C3D allows at most 7",
        "FormatError", ["§4.13.2"])
    add("cprm-group-declared-twice", with_record(9, group=-1),
        "group id 1 declared twice (POINT and EVENT)", "record 9 group = -1",
        "parameters of group 1 would belong to two groups", "FormatError", ["§4.13.2"])
    # the byte-level corruptions below work on the stored form (§4.13 coding 0): the
    # coding byte, then the count at payload offset 1
    raw = bytearray(dataclasses.replace(prm, coding=0).dump())
    raw[1:3] = struct.pack("<H", prm.count + 1)
    add("cprm-count-past-payload", assemble([[t, bytes(raw) if t == "cprm" else p]
                                             for t, p in ch]),
        "cprm count one more than the records present", "count + 1",
        "a reader that trusts the count reads past the payload", "FormatError",
        ["§3.2", "§4", "§4.13.2"])
    big = bytearray(dataclasses.replace(prm, coding=0).dump())
    # the first parameter (USED): 7 dims of 255, data 2 x 255^7 bytes declared
    at = 1 + 2 + 2 + 1 + len(prm.records[0].name) + 1 + len(prm.records[0].description)
    at += 2 + 1 + len(prm.records[1].name) + 1 + len(prm.records[1].description) + 1
    assert big[at] == 0                       # USED has no dimensions
    big[at:at + 1] = bytes([7]) + b"\xff" * 7
    add("cprm-data-2x255pow7", assemble([[t, bytes(big) if t == "cprm" else p]
                                         for t, p in ch]),
        "a parameter whose 7 dimensions of 255 declare 2 x 255^7 (about 2^57) data bytes",
        "record 1 dims = 7 x 255", "a decoder that allocates the declared size, or forms "
        "it in 32 bits (it wraps), crashes or misreads", "FormatError", ["§3.2", "§4",
                                                                          "§4.13.2", "§8"])
    pnt = Cpnt.load(next(c for c in ch if c[0] == "cpnt")[1])
    add("cpnt-storage-2", _c3d_rebuild(good, "cpnt", storage=2), "cpnt storage 2",
        "storage = 2", "no word type", "FormatError", ["§4.13.3"])
    add("cpnt-point-count-mismatch", _c3d_rebuild(
        good, "cpnt", point_count=pnt.point_count - 1, slots=pnt.slots[:-1],
        words=pnt.words[:-1]), "cpnt with one point fewer than markers + model outputs",
        "last point removed", "a marker without a slot is written nowhere", "FormatError",
        ["§4.13.3"])
    sl = list(pnt.slots)
    sl[0] = sl[1]
    add("cpnt-slots-repeated", _c3d_rebuild(good, "cpnt", slots=tuple(sl)),
        "two points in the same slot", "slots[0] = slots[1]",
        "one marker written twice, another never", "FormatError", ["§4.13.3"])
    w = list(pnt.words)
    for slug, kw, what in (("cpnt-mode-2", {"mode": 2}, "mode 2"),
                           ("cpnt-shift-105", {"shift": 105}, "shift 105"),
                           ("cpnt-bits-shift-1", {"mode": 1, "shift": 1},
                            "mode 1 with shift 1"),
                           ("cpnt-order-3", {"order": 3}, "order 3"),
                           ("cpnt-low-bits-4", {"low_bits": 4}, "low_bits 4")):
        w2 = list(w)
        w2[0] = dataclasses.replace(w[0], **kw)
        add(slug, _c3d_rebuild(good, "cpnt", words=tuple(w2)),
            f"a word channel entry with {what}", f"words[0] {what}",
            "an entry outside §4.13 has no defined decoding", "FormatError", ["§4.13"])
    md = list(pnt.models)
    md[0] = dataclasses.replace(md[0], kind=6)
    add("cpnt-model-kind-6", _c3d_rebuild(good, "cpnt", models=tuple(md)),
        "a model output of kind 6", "models[0].kind = 6", "no POINT parameter lists it",
        "FormatError", ["§4.13.3"])
    for slug, akw, what in (("cpnt-model-step-0", {"step": 0.0}, "step 0"),
                           ("cpnt-model-step-2pow994", {"step": 2.0 ** 994},
                            "step 2^994: |offset| + step x 2^31 overflows"),
                           ("cpnt-model-bound-negative", {"bound": -1.0}, "bound -1"),
                           ("cpnt-model-order-3", {"order": 3}, "order 3")):
        add(slug, _c3d_rebuild(good, "cpnt", models=_axis_changed(pnt.models, **akw)),
            f"a model-output axis with {what}", f"models[0].axes[1] {what}",
            "values that are not finite, or no declared accuracy", "FormatError",
            ["§4.13.3"])
    # model_count 4097 (the entries are not there: the limit comes first)
    add("cpnt-model-count-4097", _c3d_rebuild(
        good, "cpnt", model_count=4097, models=(pnt.models * 4097)[:4097],
        point_count=pnt.point_count + 4095,
        slots=tuple(range(pnt.point_count + 4095)),
        words=pnt.words + (pnt.words[0],) * 4095),
        "4097 model outputs (more than 4096 markers could be)", "model_count = 4097",
        "F x J unbounded: the model arrays are allocated from it", "LimitExceededError",
        ["§4.13.3", "§8"])
    # decoded values: rebuild cpnt's coded field
    F, P, J = 24, pnt.point_count, pnt.model_count

    def cpnt_coded(word_blocks, flags, values, wide=False):
        blocks = [b if isinstance(b, tuple) else (b, {}) for b in word_blocks]
        if J:
            blocks.append((flags, {"signed": False}))
            blocks += [(v, {}) for v in values]
        return (rc_wide if wide else rc)(*blocks)

    zeros = np.zeros((F, 1, 1), np.int64)
    okw = [zeros] * P
    okf = np.zeros((F, J, 1), np.int64)
    okv = [zeros] * (3 * J)
    w0 = tuple(dataclasses.replace(x, mode=0, shift=0, order=0, low_bits=0) for x in w)
    md0 = tuple(dataclasses.replace(mm, axes=tuple(dataclasses.replace(ax, order=0)
                                                   for ax in mm.axes)) for mm in pnt.models)
    flags2 = okf.copy()
    flags2[5, 1, 0] = 2
    add("cpnt-gap-flag-2", _c3d_rebuild(good, "cpnt", words=w0, models=md0,
                                        coded=cpnt_coded(okw, flags2, okv)),
        "a model-output gap flag of 2", "flag at frame 5, output 1 = 2",
        "a decoder that tests flag != 0 takes it for a gap", "FormatError",
        ["§4.13.3", "§6.9"])
    big_k = [zeros] * (3 * J)
    kv = np.zeros((F, 1, 1), np.int64)
    kv[3, 0, 0] = (1 << 31) - 1
    kv[4, 0, 0] = 1
    md1 = tuple(dataclasses.replace(mm, axes=tuple(dataclasses.replace(ax, order=1)
                                                   for ax in mm.axes)) for mm in pnt.models)
    big_k = [kv] + big_k[1:]
    add("cpnt-model-value-2pow31", _c3d_rebuild(good, "cpnt", words=w0, models=md1,
                                                coded=cpnt_coded(okw, okf, big_k, wide=True)),
        "a model-output value k = 2^31 (order 1: 2^31 - 1, then + 1)",
        "model 0 axis x residuals chosen", "k held in 32 bits wraps to -2^31",
        "FormatError", ["§4.13.3", "§6.9"])
    over = np.zeros((F, 1, 1), np.int64)
    over[2, 0, 0] = 1 << 24
    add("cpnt-word-2pow24", _c3d_rebuild(good, "cpnt", words=w0, models=md0,
                                         coded=cpnt_coded([over] + okw[1:], okf, okv)),
        "an integer word channel value of 2^24", "point 0 word at frame 2 = 2^24",
        "2^24 x 2^shift is not a binary32 for every shift", "FormatError",
        ["§4.13.3", "§6.9"])
    wl = list(w0)
    wl[0] = dataclasses.replace(w0[0], low_bits=2)
    lo = np.zeros((F, 1, 1), np.int64)
    lo[1, 0, 0] = 4
    add("cpnt-low-part-4-of-2-bits", _c3d_rebuild(
        good, "cpnt", words=tuple(wl), models=md0,
        coded=cpnt_coded([zeros, (lo, {"signed": False})] + okw[1:], okf, okv)),
        "low_bits 2 and a low part l = 4", "point 0 l at frame 1 = 4",
        "l >= 2^b overlaps the next value of h", "FormatError", ["§4.13.3", "§6.9"])
    add("cpnt-coded-leftover-byte", _c3d_rebuild(good, "cpnt", coded=pnt.coded + b"\x00"),
        "one byte after the last symbol of cpnt", "coded + 00",
        "a decoder that does not close() the payload", "FormatError",
        ["§4.13.3", "§5.3", "§6.9"])
    cana = Cana.load(ana[1])
    add("cana-storage-2", _c3d_rebuild(good, "cana", storage=2), "cana storage 2",
        "storage = 2", "no word type", "FormatError", ["§4.13.4"])
    add("cana-samples-0", _c3d_rebuild(good, "cana", samples=0), "cana samples 0",
        "samples = 0", "no analog words at all, yet channels", "FormatError", ["§4.13.4"])
    add("cana-words-per-frame-65536", _c3d_rebuild(good, "cana", samples=16384,
                                                  channels=4, table=cana.table + cana.table[:1]),
        "C x n = 4 x 16384 = 65536 analog words per frame", "channels 4, samples 16384",
        "the C3D header word 3 is 16 bits", "FormatError", ["§4.13.4"])
    # F x n x C over MAX_ANALOG_SAMPLES: F = 2^24 frames of one marker, n = 17 (the marker
    # data is never decoded: the cana check comes first, before anything is allocated)
    Fb = 1 << 24
    mhdr: dict[str, object] = {"version_major": 1, "version_minor": 1, "flags": 0,
                               "frame_count": Fb,
           "marker_count": 1, "node_count": 1, "rate": 100.0, "units": 1, "error_metric": 0,
           "error_bound": 0.0, "smoothing": 0}
    huge = [["MHDR", payload("MHDR", mhdr)],
            ["MNAM", payload("MNAM", {"count": 1, "names": ["A"]})],
            ["HIER", payload("HIER", {"count": 1, "nodes": [
                {"parent": ROOT_PARENT, "ref": 0, "member_count": 1, "members": [0],
                 "weights": [1.0]}]})],
            ["QUNT", payload("QUNT", {"step": 1.0, "offset": [0.0, 0.0, 0.0], "bits": 31})],
            ["ROOT", payload("ROOT", {"order": 0, "coded": b"\x00" * 5})],
            next([t, p] for t, p in ch if t == "chdr"),
            next([t, p] for t, p in ch if t == "cprm"),
            ["cana", Cana(storage=1, channels=1, samples=17, table=cana.table[:1],
                               coded=b"\x00" * 5).dump()],
            ["cpnt", Cpnt(storage=1, point_count=1, slots=(0,), words=pnt.words[:1],
                               model_count=0, models=(), coded=b"\x00" * 5).dump()],
            ["MEND", b""]]
    add("cana-samples-over-limit", assemble(huge),
        f"F x n x C = 2^24 x 17 x 1 = {Fb * 17} analog words, over MAX_ANALOG_SAMPLES 2^28",
        "MHDR frame_count 2^24 with one marker; cana channels 1, samples 17",
        "a decoder that allocates F x n x C words before the check asks for 2 GiB from a "
        "file of 1 KB", "LimitExceededError", ["§4.13.4", "§8"])
    ci = Cana.load(next(c for c in _c3d_chunks(exact) if c[0] == "cana")[1])
    ti = list(ci.table)
    ti[0] = dataclasses.replace(ti[0], mode=1)
    add("cana-int16-with-bits-mode", _c3d_rebuild(exact, "cana", table=tuple(ti)),
        "an int16 analog channel coded as float32 bits", "table[0].mode = 1",
        "a float bit pattern has no int16 word", "FormatError", ["§4.13"])
    Ti = 24 * ci.samples
    big16 = np.zeros((Ti, 1, 1), np.int64)
    big16[0, 0, 0] = 40000
    t0 = tuple(dataclasses.replace(x, order=0, low_bits=0) for x in ci.table)
    add("cana-int16-value-40000", _c3d_rebuild(
        exact, "cana", table=t0, coded=rc(*([(big16, {})] + [(np.zeros((Ti, 1, 1), np.int64),
                                                               {})] * (ci.channels - 1)))),
        "an int16 analog word of 40000", "channel 0 word 0 = 40000",
        "an int16 writer wraps it to -25536", "FormatError", ["§4.13.4", "§6.9"])


#: the §7.4 rules the C3D archive vectors probe (merged into VECTOR_RULES)
C3D_VECTOR_RULES = _rules(
    ("R-4.13-1", "c3d-two-chdr c3d-no-cprm c3d-two-cana"),
    ("R-4.13-2", "cpnt-mode-2 cpnt-shift-105 cpnt-bits-shift-1 cpnt-order-3 "
                 "cpnt-low-bits-4 cana-int16-with-bits-mode"),
    ("R-4.13-3", "chdr-coding-2 cprm-coding-2 cprm-deflate-truncated "
     "cprm-deflate-trailing-byte chdr-deflate-invalid cprm-inflates-past-2pow17 "
     "chdr-inflates-to-513-bytes"),
    ("R-4.13-4", "c3d-stored-header-and-parameters c3d-archive-float32"),
    ("R-4.13.1-1", "chdr-processor-87 chdr-key-0x51"),
    # an inflated content over the limit breaks the byte coding (R-4.13-3) and the chunk's
    # content limit, which its message cites (a clean-room review of stop 54)
    ("R-4.13.1-2", "chdr-stored-511-bytes chdr-payload-1-byte chdr-inflates-to-513-bytes"),
    ("R-4.13.1-3", "c3d-header-counts-stale"),
    ("R-4.13.2-4", "cprm-empty-payload cprm-stored-over-2pow17 cprm-records-short-of-content "
                   "cprm-inflates-past-2pow17"),
    ("R-4.13.2-1", "cprm-group-0 cprm-name-empty cprm-name-128-bytes cprm-type-3 "
                   "cprm-eight-dims cprm-group-declared-twice"),
    ("R-4.13.2-2", "cprm-count-past-payload cprm-data-2x255pow7"),
    ("R-4.13.2-3", "c3d-archive-float32"),
    ("R-4.13.3-1", "cpnt-storage-2 cpnt-point-count-mismatch cpnt-slots-repeated "
                   "cpnt-model-kind-6 cpnt-model-step-0 cpnt-model-step-2pow994 "
                   "cpnt-model-bound-negative cpnt-model-order-3"),
    ("R-4.13.3-2", "cpnt-model-count-4097"),
    ("R-4.13.4-1", "cana-storage-2 cana-samples-0 cana-words-per-frame-65536"),
    ("R-4.13.4-2", "cana-samples-over-limit"),
    ("R-6.9-1", "cpnt-gap-flag-2 cpnt-model-value-2pow31 cpnt-word-2pow24 "
                "cpnt-low-part-4-of-2-bits cpnt-coded-leftover-byte cana-int16-value-40000"),
    ("R-6.9-2", "c3d-archive-float32 c3d-int16-exact-on-grid c3d-no-analog-no-models"),
)
VECTOR_RULES.update(C3D_VECTOR_RULES)


# ------------------------------------------------------- issue 13: skeleton chunks --
def _skeleton_bvh_text(F=60, seed=131):
    """A synthetic BVH (never a real file): 8 joints and 3 End Sites, the root spinning
    through +-180 degrees about z, values printed with 4 decimals."""
    rng = np.random.default_rng(seed)
    t = np.arange(F) / 30.0
    hier = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Spine
  {
    OFFSET 0 10.5 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT Head
    {
      OFFSET 0 12 1
      CHANNELS 3 Zrotation Xrotation Yrotation
      End Site
      {
        OFFSET 0 6 0
      }
    }
  }
  JOINT LeftLeg
  {
    OFFSET 4 -2 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT LeftFoot
    {
      OFFSET 0 -40 0
      CHANNELS 2 Xrotation Zrotation
      End Site
      {
        OFFSET 0 -3 8
      }
    }
  }
  JOINT RightLeg
  {
    OFFSET -4 -2 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT RightFoot
    {
      OFFSET 0 -40 0
      CHANNELS 1 Xrotation
      End Site
      {
        OFFSET 0 -3 8
      }
    }
  }
}
"""
    C = 6 + 3 + 3 + 3 + 2 + 3 + 1
    v = 20 * np.sin(2 * np.pi * (0.5 + rng.random(C)) * t[:, None] + rng.random(C) * 6)
    v += rng.normal(0, 0.05, (F, C))
    v[:, 0] = 10 * t
    v[:, 1] = 90 + 2 * np.sin(4 * t)
    v[:, 2] = 3 * t
    v[:, 3] = (150 + 120 * t + 180) % 360 - 180          # the root's Zrotation wraps
    lines = [" ".join(f"{x:.4f}" for x in row) for row in v]
    return hier + f"MOTION\nFrames: {F}\nFrame Time: 0.0333333\n" + "\n".join(lines) + "\n"


_SKELETON_ASF = """# a synthetic skeleton (make_vectors)
:version 1.10
:name SYNTH
:units
  mass 1.0
  length 0.45
  angle deg
:documentation
   made by python -m mpz.tools.make_vectors
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name lhip
     direction 0.6 -0.7 0.2
     length 2.5
     axis 0 0 0 XYZ
  end
  begin
     id 2
     name lfemur
     direction 0.34 -0.94 0
     length 7.5
     axis 0 0 20 XYZ
    dof rx ry rz
    limits (-160.0 20.0)
           (-70.0 70.0)
           (-60.0 70.0)
  end
  begin
     id 3
     name ltibia
     direction 0.34 -0.94 0
     length 7.2
     axis 0 0 20 XYZ
    dof rx
    limits (-10.0 170.0)
  end
  begin
     id 4
     name back
     direction 0 1 0
     length 2
     axis 0 0 0 ZYX
    dof rx rz
    limits (-20.0 45.0)
           (-30.0 30.0)
  end
:hierarchy
  begin
    root lhip back
    lhip lfemur
    lfemur ltibia
  end
"""


def _skeleton_amc_text(F=40, seed=35):
    rng = np.random.default_rng(seed)
    t = np.arange(F) / 120.0
    out = [":FULLY-SPECIFIED", ":DEGREES"]
    for f in range(F):
        a = 30 * np.sin(2 * np.pi * 1.3 * t[f] + np.arange(9)) + rng.normal(0, 0.02, 9)
        out.append(str(f + 1))
        out.append(f"root {10 + 5 * t[f]:.4f} 16.7 {-30 + t[f]:.4f} {a[0]:.4f} {a[1]:.4f} "
                   f"{a[2]:.4f}")
        out.append(f"back {a[3]:.4f} {a[4]:.4f}")
        out.append(f"lfemur {a[5]:.4f} {a[6]:.4f} {a[7]:.4f}")
        out.append(f"ltibia {abs(a[8]):.4f}")
    return "\n".join(out) + "\n"


def _skeleton_rebuild(data, **changes):
    """``data`` with its skeleton chunk's record fields changed (payload rebuilt)."""
    import dataclasses

    from mpz.chunks import Asfs, Bvhs
    from mpz.container import scan
    out = []
    for c in scan(data).chunks:
        if isinstance(c.record, (Bvhs, Asfs)):
            out.append((c.type, dataclasses.replace(c.record, **changes).dump()))
        else:
            out.append((c.type, c.payload))
    return assemble(out)


def _skeleton_record(data):
    from mpz.chunks import Asfs, Bvhs
    from mpz.container import scan
    return next(c.record for c in scan(data).chunks if isinstance(c.record, (Bvhs, Asfs)))


def _skeleton_features(data):
    """What mpzinfo reports of the skeleton chunk, and the digest of its channel integers
    (§7.3): what an implementer checks §6.10 against."""
    import hashlib

    from mpz import skeleton as sk
    from mpz.channels import decode as decode_channels
    rep = sk.report(data)
    assert rep is not None
    rec = _skeleton_record(data)
    x = decode_channels(rec.channels, rec.coded, mpz.info(data).frames)
    rep["channels_sha256"] = hashlib.sha256(np.ascontiguousarray(x, "<i8").tobytes()).hexdigest()
    return {"skeleton": rep}


def _skeleton_layer(rec, values):
    """Channel entries and coded field for integer channel values ``[F, C]`` (one entry per
    channel of ``rec``), with each entry's order, wrap and group as ``rec`` has them."""
    from mpz.conformance.rangecoder import RefEncoder
    from mpz.predict import residuals
    x = np.asarray(values, np.int64)
    e = np.empty_like(x)
    for c, cc in enumerate(rec.channels):
        r = residuals(x[:, c], cc.order)
        if cc.wrap:
            n = 360 * 10 ** cc.step_digits // cc.step_mantissa
            r = (r + n // 2) % n - n // 2
        e[:, c] = r
    enc = RefEncoder()
    groups = np.array([cc.group for cc in rec.channels])
    for g in range(int(groups.max(initial=-1)) + 1):
        enc.block(e[:, groups == g, None], period=None, signed=True)
    return enc.finish()


def skeleton_vectors(vs: VectorSet):
    """Valid, uncommon and invalid files for the skeleton chunks (spec §4.14, §6.10, MPZ
    1.1), from synthetic BVH and AMC/ASF motions (never real files)."""
    import dataclasses

    from mpz.chunks.skeleton import ChannelCoding
    from mpz.io.amc import parse_amc, parse_asf
    from mpz.io.bvh import parse_bvh
    secs = ["§2.1", "§2.3", "§4.14", "§6.10"]
    bvh_src = _skeleton_bvh_text()
    good = mpz.encode(parse_bvh(bvh_src, source="synthetic.bvh"))
    vs.valid("valid", _numbered(vs, "v", "bvhs-synthetic-default"), good,
             "a BVH (1.1): 8 joints and 3 End Sites, 60 frames, the root's Zrotation wrapping "
             "through +-180 degrees, coded by the reference encoder's defaults (channels "
             "within 0.01, step 0.02; marker layer within 1/500 of the skeleton's size)",
             _skeleton_features(good), [*secs, "§4.14.1"],
             "make_vectors._skeleton_bvh_text() -> parse_bvh -> mpz.encode()")
    asf = parse_asf(_SKELETON_ASF)
    amc = mpz.encode(parse_amc(_skeleton_amc_text(), asf, source="synthetic_01.amc"))
    vs.valid("valid", _numbered(vs, "v", "asfs-synthetic-default"), amc,
             "an AMC with its ASF (1.1): root and 4 bones, one without dofs (not in the AMC "
             "frames), limits, axis order ZYX, 40 frames, reference encoder defaults",
             _skeleton_features(amc), [*secs, "§4.14.2"],
             "make_vectors._SKELETON_ASF, _skeleton_amc_text() -> parse_amc -> mpz.encode()")

    # -- uncommon: hand-made channel layers on the same skeletons
    rec = _skeleton_record(good)
    F = 60
    rng = np.random.default_rng(13)
    C = rec.channel_count
    x = rng.integers(-50, 50, (F, C)).cumsum(axis=0)
    ent = []
    for c in range(C):
        order, wrap, low, m, d = c % 3, 0, 0, 1 + (c % 7) * 9, c % 10
        if c == 3:                       # a turn that ends exactly at 2^31
            m, d, wrap = 2, 2, 1
            low = (1 << 31) - 18000
            x[:, c] = low + np.mod(x[:, c] * 37, 18000)
        elif c == 4:                     # a turn that starts at -2^31 + 1
            m, d, wrap = 1, 0, 1
            low = -(1 << 31) + 1
            x[:, c] = low + np.mod(x[:, c], 360)
        elif c == 5:                     # the largest mantissa, no wrap
            m, d = 0xFFFF, 9
        ent.append(ChannelCoding(step_mantissa=m, step_digits=d, wrap=wrap, low=low,
                                 order=order, group=(c * 5) % 3))
    hand = dataclasses.replace(rec, channels=tuple(ent), position_bound=0.0)
    hand = dataclasses.replace(hand, coded=_skeleton_layer(hand, x))
    data = _skeleton_rebuild(good, channels=hand.channels, coded=hand.coded, position_bound=0.0)
    assert np.array_equal(_skeleton_record(data).integers(F), x)
    vs.valid("uncommon", _numbered(vs, "u", "bvhs-layer-every-field"), data,
             "a bvhs whose channel layer exercises every field: orders 0, 1, 2, wrapped "
             "channels whose turn ends at 2^31 - 1 and starts at -2^31 + 1, steps m x 10^-d "
             "with d = 0 .. 9 and m up to 65535, three groups interleaved, position_bound 0 "
             "(none declared)", _skeleton_features(data), [*secs, "§4.14.1"],
             "make_vectors.skeleton_vectors: the v-bvhs file, channel layer rebuilt by hand")
    # no channels at all: C = 0, G = 0, the coded field holds no block
    bare = _skeleton_rebuild(good, joints=tuple(dataclasses.replace(j, channel_count=0,
                                                                    channels=())
                                                for j in rec.joints),
                             channel_count=0, channels=(), coded=BlockEncoder().finish())
    vs.valid("uncommon", _numbered(vs, "u", "bvhs-no-channels"), bare,
             "a bvhs with no channel at all (C = 0, G = 0): its coded field holds no block "
             "and is still closed (5 bytes)", _skeleton_features(bare), [*secs, "§4.14.1"],
             "make_vectors.skeleton_vectors: v-bvhs with every CHANNELS line emptied")
    # several ROOTs, a repeated name, an End Site right under a root
    rj = list(rec.joints)
    two_roots = [*rj[:7], dataclasses.replace(rj[7], name="Spine", parent=ROOT_PARENT),
                 *rj[8:]]
    roots = _skeleton_rebuild(good, joints=tuple(two_roots))
    vs.valid("uncommon", _numbered(vs, "u", "bvhs-two-roots-repeated-name"), roots,
             "a bvhs with two ROOTs (the second starts a new hierarchy) and two joints named "
             "Spine", _skeleton_features(roots), [*secs, "§4.14.1"],
             "make_vectors.skeleton_vectors: v-bvhs with joint 7 (RightLeg) made a second "
             "ROOT named Spine")
    # ASF in radians, infinite limits, a bone without dofs listed in the AMC, latin-1, t/l
    arec = _skeleton_record(amc)
    bones = list(arec.bones)
    bones[1] = dataclasses.replace(bones[1], limits=((float("-inf"), 20.0), (-1.0, 1.0),
                                                     (float("-inf"), float("inf"))))
    bones[3] = dataclasses.replace(bones[3], dof_count=4, dofs=(6, 0, 3, 5), limit_count=0,
                                   limits=())
    Fa = 40
    xa = np.zeros((Fa, arec.channel_count + 2), np.int64)
    xa[:, :] = rng.integers(-20, 20, xa.shape).cumsum(axis=0)
    ent = [ChannelCoding(step_mantissa=1, step_digits=4, wrap=0, low=0, order=2, group=0)
           for _ in range(arec.channel_count + 2)]
    rad = dataclasses.replace(arec, encoding=1, angle_unit=1, first_frame=0,
                              bones=tuple(bones), amc_count=5, amc_order=(0, 4, 1, 2, 3),
                              channel_count=len(ent), channels=tuple(ent),
                              comments=" \u00e9 latin-1")
    rad = dataclasses.replace(rad, coded=_skeleton_layer(rad, xa))
    data = _skeleton_rebuild(amc, **{f.name: getattr(rad, f.name)
                                     for f in dataclasses.fields(rad)})
    vs.valid("uncommon", _numbered(vs, "u", "asfs-radians-inf-limits-stretch"), data,
             "an asfs in radians, Latin-1, first frame 0, with infinite limits, a bone without "
             "dofs listed in the AMC order, and a bone with the l (stretch), tx and rz dofs",
             _skeleton_features(data), [*secs, "§4.14.2"],
             "make_vectors.skeleton_vectors: the v-asfs file, fields changed by hand")

    # -- invalid: one change each
    add = functools.partial(_add_invalid, vs)

    def bad(slug, changes, what, risk, section, src=good, error="FormatError"):
        add(slug, _skeleton_rebuild(src, **changes), what, what, risk, error,
            [section] if isinstance(section, str) else list(section))

    chunks = [[c.type, c.payload] for c in container.parse(good)]
    k = next(i for i, c in enumerate(chunks) if c[0] == "bvhs")
    add("skeleton-two-bvhs", assemble(chunks[:k + 1] + [chunks[k]] + chunks[k + 1:]),
        "two bvhs chunks", "bvhs repeated", "which skeleton does a writer use?",
        "FormatError", ["§4.14"])
    asfs_payload = next(c.payload for c in container.parse(amc) if c.type == "asfs")
    add("skeleton-bvhs-and-asfs", assemble(chunks[:k + 1] + [["asfs", asfs_payload]]
                                           + chunks[k + 1:]),
        "a bvhs and an asfs in one file", "the asfs of the v-asfs file added",
        "two skeletons for one set of markers", "FormatError", ["§4.14"])
    j = list(rec.joints)

    def joints(i, **kw):
        jj = list(j)
        jj[i] = dataclasses.replace(jj[i], **kw)
        return {"joints": tuple(jj)}

    bad("bvhs-joint-count", {"joint_count": rec.joint_count - 1, "joints": rec.joints[:-1]},
        "bvhs with one joint fewer than the markers", "joint j is not marker j",
        "§4.14.1")
    bad("bvhs-frame-time-zero", {"frame_time": 0.0}, "bvhs frame_time 0",
        "a writer divides by it", "§4.14.1")
    bad("bvhs-encoding-2", {"encoding": 2}, "bvhs encoding 2", "an unknown text encoding",
        "§4.14.1")
    bad("bvhs-not-depth-first", joints(5, parent=2),
        "joint 5's parent is joint 2, neither joint 4 nor one of its ancestors",
        "a writer cannot nest it without reordering the MOTION columns", "§4.14.1")
    bad("bvhs-end-site-channels", {**joints(3, channel_count=1, channels=(3,)),
                                   "channel_count": rec.channel_count + 1,
                                   "channels": (*rec.channels, rec.channels[0])},
        "an End Site with a channel", "End Sites hold no CHANNELS line", "§4.14.1")
    bad("bvhs-end-site-as-root", joints(4, name="", parent=ROOT_PARENT, channel_count=0,
                                        channels=()),
        "an End Site (empty name) without a parent", "an End Site is not a ROOT",
        "§4.14.1")
    bad("bvhs-child-of-end-site", joints(4, parent=3), "a joint whose parent is an End Site",
        "End Sites have no children", "§4.14.1")
    bad("bvhs-name-space", joints(1, name="Sp ine"), "a joint named 'Sp ine'",
        "a BVH name is one word", "§4.14.1")
    bad("bvhs-offset-nan", joints(1, offset=(0.0, float("nan"), 0.0)),
        "an OFFSET with a NaN", "forward kinematics gives NaN", "§4.14.1")
    bad("bvhs-kind-6", joints(2, channels=(5, 3, 6)), "a BVH channel of kind 6",
        "BVH has no stretch channel", "§4.14.1")
    bad("bvhs-kind-twice", joints(2, channels=(5, 3, 5)), "a joint listing Zrotation twice",
        "each kind once per joint", "§4.14.1")
    bad("bvhs-channel-count", {"channel_count": rec.channel_count - 1,
                               "channels": rec.channels[:-1]},
        "a channel layer with one channel fewer than the joints declare",
        "the MOTION columns do not line up", "§4.14.1")

    def entry(c, **kw):
        ee = list(rec.channels)
        ee[c] = dataclasses.replace(ee[c], **kw)
        return {"channels": tuple(ee)}

    wrapped = next(c for c, e in enumerate(rec.channels) if e.wrap)
    plain = next(c for c, e in enumerate(rec.channels) if not e.wrap)
    bad("skeleton-position-bound-nan", {"position_bound": float("nan")},
        "position_bound NaN", "a promise that means nothing", "§4.14")
    bad("skeleton-position-bound-negative", {"position_bound": -1.0},
        "position_bound -1", "a promise that means nothing", "§4.14")
    bad("skeleton-step-mantissa-0", entry(plain, step_mantissa=0), "a step of 0",
        "every value decodes to 0", "§4.14")
    bad("skeleton-step-digits-10", entry(plain, step_digits=10), "step_digits 10",
        "beyond the decimals the format allows", "§4.14")
    bad("skeleton-order-3", entry(plain, order=3), "predictor order 3",
        "no such predictor", "§4.14")
    bad("skeleton-wrap-2", entry(wrapped, wrap=2), "wrap 2", "a reserved value", "§4.14")
    bad("skeleton-wrap-step-7", entry(wrapped, step_mantissa=7, step_digits=2),
        "a wrapped channel with step 0.07, which does not divide 360",
        "N = 360 / step is not an integer", "§4.14")
    bad("skeleton-wrap-past-2pow31", entry(wrapped, low=(1 << 31) - 17999),
        "a turn low .. low + 17999 that reaches 2^31", "a 32-bit value wraps", "§4.14")
    bad("skeleton-low-without-wrap", entry(plain, low=5), "low 5 on a channel without wrap",
        "a field that must be 0", "§4.14")
    last = max(e.group for e in rec.channels)
    bad("skeleton-group-gap", entry(plain, group=last + 2), "a channel in a group two past "
        "the last", "an empty group has no block", "§4.14")
    # §6.10 and §5.3 on the coded field
    # §6.10 states the rule (R-6.10-1), §5.3 the check (a clean-room review of stop 54)
    bad("skeleton-coded-short", {"coded": rec.coded[:-1]}, "the coded field lacks its last "
        "byte", "a decoder that does not check the end reads past it", ("§5.3", "§6.10"))
    bad("skeleton-coded-leftover", {"coded": rec.coded + b"\x00"}, "a byte after the last "
        "block", "trailing data unnoticed", ("§5.3", "§6.10"))
    # order 1, values 0, 2^31 - 1, 2^31, 2^31 - 1, 0, ...: every residual fits the coder
    ov = dataclasses.replace(rec, channels=tuple(dataclasses.replace(e, order=1, wrap=0, low=0)
                                                 if i == plain else e
                                                 for i, e in enumerate(rec.channels)))
    xo = rec.integers(F).copy()          # read-only: the record keeps it (chunks.base.kept)
    xo[:, plain] = 0
    xo[1:4, plain] = [(1 << 31) - 1, 1 << 31, (1 << 31) - 1]
    bad("skeleton-value-2pow31", {"channels": ov.channels, "coded": _skeleton_layer(ov, xo)},
        "a channel (no wrap, order 1) whose value reaches 2^31 at frame 2 (residuals 2^31 - "
        "1, 1, -1, -(2^31 - 1))", "a 32-bit decoder wraps it to -2^31", "§6.10")
    # -- the F x C limit: one joint, 6 channels, F = 2^24 (F x M = 2^24 is fine)
    one = _root_only(1, [[0, 0, 0]]).chunks()
    one = _with_field(one, "MHDR", frame_count=1 << 24)
    root = rec.joints[0]
    big = dataclasses.replace(rec, joint_count=1, joints=(root,), channel_count=6,
                              channels=tuple(dataclasses.replace(e, group=0)
                                             for e in rec.channels[:6]), coded=b"\x00" * 5)
    add("skeleton-channel-samples-over-limit", assemble(one[:-1] + [["bvhs", big.dump()]]
                                                        + one[-1:]),
        "a bvhs of 6 channels in a file of F = 2^24 frames: F x C = 6 x 2^24 > 2^26",
        "MHDR frame_count 2^24, bvhs with one joint of 6 channels",
        "a decoder that sizes the channel blocks first allocates 800 MB",
        "LimitExceededError", ["§4.14", "§8"])
    # -- asfs
    ab = list(arec.bones)

    def bone(b, **kw):
        bb = list(ab)
        bb[b] = dataclasses.replace(bb[b], **kw)
        return {"bones": tuple(bb)}

    cm = [[t, p] for t, p in container_pairs(amc)]
    cm = _with_field(cm, "MHDR", units=2)
    add("asfs-markers-in-cm", assemble(cm), "an asfs in a file whose markers are in cm",
        "MHDR units 2", "the joint positions of an ASF are millimetres", "FormatError",
        ["§4.14.2"])
    bad("asfs-bone-count", {"bone_count": arec.bone_count - 1, "bones": arec.bones[:-1]},
        "an asfs with one bone fewer than the markers", "bone b is not marker b + 1",
        "§4.14.2", src=amc)
    bad("asfs-length-unit-0", {"length_unit": 0.0}, "length_unit 0",
        "millimetres per unit are infinite", "§4.14.2", src=amc)
    bad("asfs-angle-unit-2", {"angle_unit": 2}, "angle_unit 2", "an unknown unit",
        "§4.14.2", src=amc)
    bad("asfs-name-line-break", {"name": "SYN\nTH"}, "an ASF name with a line break",
        "the :name line breaks", "§4.14.2", src=amc)
    bad("asfs-root-order-stretch", {"root_order": (0, 1, 2, 3, 4, 6)},
        "the root's order lists the stretch dof l", "the root has no bone to stretch",
        "§4.14.2", src=amc)
    bad("asfs-axis-order-6", bone(1, axis_order=6), "a bone axis order 6",
        "there are six orders", "§4.14.2", src=amc)
    bad("asfs-parent-after-bone", bone(1, parent=3), "bone 1's parent is bone 2 (joint 3)",
        "positions are computed parents first", "§4.14.2", src=amc)
    bad("asfs-bone-named-root", bone(2, name="root"), "a bone named root",
        "the AMC line 'root' is ambiguous", "§4.14.2", src=amc)
    bad("asfs-bone-names-repeat", bone(2, name=ab[1].name), "two bones with one name",
        "AMC lines name bones", "§4.14.2", src=amc)
    bad("asfs-dof-twice", bone(1, dofs=(3, 4, 3)), "a bone listing rx twice",
        "each kind once", "§4.14.2", src=amc)
    bad("asfs-limit-count", bone(1, limit_count=2, limits=ab[1].limits[:2]),
        "a bone with 2 limits for 3 dofs", "limits per dof", "§4.14.2", src=amc)
    bad("asfs-limit-nan", bone(2, limits=((float("nan"), 1.0),)), "a NaN limit",
        "a range that means nothing", "§4.14.2", src=amc)
    bad("asfs-amc-order-out-of-range", {"amc_order": (0, 2, 3, 9)},
        "AMC order names joint 9 of 5", "a writer indexes past the joints", "§4.14.2",
        src=amc)
    bad("asfs-amc-order-repeats", {"amc_order": (0, 2, 2, 4)}, "AMC order lists joint 2 twice",
        "a bone written twice per frame", "§4.14.2", src=amc)
    bad("asfs-amc-order-misses-a-bone", {"amc_count": 3, "amc_order": (0, 2, 3)},
        "AMC order leaves out the bone with dofs 'back'", "its values are never written",
        "§4.14.2", src=amc)
    LIMIT_BOUNDARIES["F x C = 2^26 (MAX_CHANNEL_SAMPLES)"] = (
        "a valid file holds 2^26 coded channel values (its expected output is 512 MiB of "
        "int64 while decoding); tested in tests/test_skeleton.py::test_channel_samples_limit "
        "(skeleton-channel-samples-over-limit is the invalid side)")


def container_pairs(data):
    return [(c.type, c.payload) for c in container.parse(data)]


#: the §7.4 rules the skeleton vectors probe (merged into VECTOR_RULES)
SKELETON_VECTOR_RULES = _rules(
    ("R-4.14-1", "skeleton-two-bvhs skeleton-bvhs-and-asfs"),
    ("R-4.14-2", "skeleton-position-bound-nan skeleton-position-bound-negative "
                 "skeleton-step-mantissa-0 skeleton-step-digits-10 skeleton-order-3 "
                 "skeleton-wrap-2 skeleton-wrap-step-7 skeleton-wrap-past-2pow31 "
                 "skeleton-low-without-wrap skeleton-group-gap bvhs-channel-count"),
    ("R-4.14-3", "skeleton-channel-samples-over-limit"),
    ("R-4.14-4", "bvhs-layer-every-field bvhs-no-channels"),
    ("R-4.14.1-1", "bvhs-joint-count bvhs-frame-time-zero bvhs-encoding-2 "
                   "bvhs-not-depth-first bvhs-end-site-channels bvhs-end-site-as-root "
                   "bvhs-child-of-end-site bvhs-name-space bvhs-offset-nan bvhs-kind-6 "
                   "bvhs-kind-twice"),
    ("R-4.14.1-2", "bvhs-two-roots-repeated-name bvhs-no-channels"),
    ("R-4.14.2-1", "asfs-markers-in-cm asfs-bone-count asfs-length-unit-0 asfs-angle-unit-2 "
                   "asfs-name-line-break asfs-root-order-stretch asfs-axis-order-6 "
                   "asfs-parent-after-bone asfs-bone-named-root asfs-bone-names-repeat "
                   "asfs-dof-twice asfs-limit-count asfs-limit-nan "
                   "asfs-amc-order-out-of-range asfs-amc-order-repeats "
                   "asfs-amc-order-misses-a-bone"),
    ("R-4.14.2-2", "asfs-radians-inf-limits-stretch asfs-names-Root-ROOT-line-separators"),
    ("R-6.10-1", "skeleton-coded-short skeleton-coded-leftover skeleton-value-2pow31"),
    ("R-6.10-2", "bvhs-synthetic-default asfs-synthetic-default bvhs-layer-every-field "
                 "asfs-radians-inf-limits-stretch asfs-names-Root-ROOT-line-separators"),
)
VECTOR_RULES.update(SKELETON_VECTOR_RULES)


# --------------------------------------------------- §4.15 coded summary (MPZ 1.1) --
def _smrc_payload(space, dims, levels, coded=None, frames=None):
    """An smrc payload from (k, wssse, step, starts, q [k, D]) levels; ``coded`` given as
    bytes, or None to code the levels as §4.15 says (reference encoder, ``frames`` = F)."""
    from mpz.chunks.summary import encode_levels
    if coded is None:
        coded = encode_levels(space, frames, [(np.asarray(st, np.int64),
                                               np.asarray(q, np.int64).reshape(len(st), dims))
                                              for _, _, _, st, q in levels])
    return payload("smrc", {"space": space, "dims": dims, "level_count": len(levels),
                            "levels": [{"k": k, "wssse": w, "step": s}
                                       for k, w, s, _, _ in levels], "coded": coded})


def _with_smrc(data, body, *, extra=()):
    """``data`` with its smrc payload replaced by ``body`` (and ``extra`` chunks after it)."""
    out = []
    for c in container.parse(data):
        out.append([c.type, body if c.type == "smrc" else c.payload])
        if c.type == "smrc":
            out += [list(e) for e in extra]
    return assemble(out)


def smrc_vectors(vs: VectorSet):
    """Valid, uncommon and invalid files for the coded summary chunk smrc (spec §4.15, MPZ
    1.1, issue 14.12), from a small synthetic walk (never real files)."""
    import dataclasses

    from mpz.chunks.summary import Smrc, overlap_prediction
    secs = ["§2.1", "§2.3", "§3.4", "§4.15", "§5.5"]
    good = _smrc_base()
    vs.valid("valid", _numbered(vs, "v", "smrc-positions"), good,
             "a 4-marker walk with the coded summary smrc (1.1): levels k = 2 and 5 of a "
             "position summary (D = 12), step = the 1 mm bound, the k = 2 level predicted from "
             "the k = 5 level", {"summary": "smrc", "levels": [2, 5]}, secs,
             "mpz.synth.generate('walk', frames=24, markers=4, seed=141) -> "
             "mpz.encode(max_error=1.0, summary=(2, 5))")
    F, M = 24, 4
    rng = np.random.default_rng(141)
    # uncommon: an angle summary without means (D = 0): the A blocks alone
    body = _smrc_payload(1, 0, [(3, 0.0, 0.5, [0, 1, 23], np.zeros((3, 0))),
                                (1, -0.0, 1.0, [0], np.zeros((1, 0)))], frames=F)
    vs.valid("uncommon", _numbered(vs, "u", "smrc-angles-no-dims"), _with_smrc(good, body),
             "smrc with space 1 and D = 0: two levels (k = 3 with a last segment of one frame, "
             "then k = 1, wssse -0.0), the coded field holds the two length blocks alone",
             {"summary": "smrc", "dims": 0}, secs, "make_vectors.smrc_vectors: hand-made smrc "
             "in the v-smrc-positions file")
    # uncommon: one level, k = 1
    q1 = rng.integers(-40, 40, (1, 3 * M))
    body = _smrc_payload(0, 3 * M, [(1, 12.5, 0.25, [0], q1)], frames=F)
    vs.valid("uncommon", _numbered(vs, "u", "smrc-one-level-k1"), _with_smrc(good, body),
             "smrc with one level of one segment (k = 1): a length block of one value (F - 1) "
             "and one row of means, predicted from 0", {"summary": "smrc", "levels": [1]},
             secs, "make_vectors.smrc_vectors: hand-made smrc in the v-smrc-positions file")
    # uncommon: levels out of order, a repeated k, k = F, means at the s32 limit
    lv_f = rng.integers(-(1 << 20), 1 << 20, (F, 3 * M))
    # the s32 limit, its neighbours at 2^30 so that every residual stays below 2^31
    lv_f[4:7, 0] = (1 << 30, (1 << 31) - 1, 1 << 30)
    lv_f[5:8, 1] = (-(1 << 30), -(1 << 31) + 1, -(1 << 30))
    lv_3 = rng.integers(-(1 << 20), 1 << 20, (3, 3 * M))
    lv_3[:, 0], lv_3[:, 1] = np.abs(lv_3[:, 0]), -np.abs(lv_3[:, 1])
    levels = [(3, 1.0, 0.5, [0, 10, 11], lv_3), (F, 0.0, 0.5, list(range(F)), lv_f),
              (3, 2.0, 0.5, [0, 4, 20], lv_3), (F, 0.0, 0.5, list(range(F)), lv_f)]
    qs = [(np.asarray(st, np.int64), np.asarray(q, np.int64)) for *_, st, q in levels]
    # residuals reach 2^30 and more: code them with the wide §5 transcription
    blocks = []
    for li, (st, q) in enumerate(qs):
        k = st.shape[0]
        blocks.append(((np.diff(np.append(st, F)) - 1).reshape(k, 1, 1),
                       {"period": k, "signed": False}))
        e = (np.diff(q, axis=0, prepend=0) if li == len(qs) - 1
             else q - overlap_prediction(st, qs[li + 1][1], qs[li + 1][0], F))
        blocks.append((e.reshape(k, M, 3), {"period": k}))
    coded = rc_wide(*blocks)
    body = _smrc_payload(0, 3 * M, levels, coded=coded)
    data = _with_smrc(good, body)
    got = Smrc.load(body).levels_decoded(F)
    assert all(np.array_equal(a[1], q) for a, (_, q) in zip(got, qs, strict=True))
    vs.valid("uncommon", _numbered(vs, "u", "smrc-levels-any-order"), data,
             "smrc with levels k = 3, 24, 3, 24 (= F): out of order, repeated, two different "
             "k = 3 partitions, a level of one-frame segments, and means of 2^31 - 1 and "
             "-(2^31 - 1); each level predicted from the next", {"summary": "smrc",
                                                                  "levels": [3, 24, 3, 24]},
             secs, "make_vectors.smrc_vectors: hand-made smrc (wide residuals) in the "
             "v-smrc-positions file")

    add = functools.partial(_add_invalid, vs)

    ch = [[c.type, c.payload] for c in container.parse(good)]
    k = next(i for i, c in enumerate(ch) if c[0] == "smrc")
    smrc = ch[k][1]
    assert isinstance(smrc, bytes)
    rec = Smrc.load(smrc)
    add("smrc-twice", assemble(ch[:k + 1] + [ch[k]] + ch[k + 1:]), "two smrc chunks",
        "smrc repeated", "which summary does a reader use?", "FormatError", ["§3.4", "§4.15"])
    smry = payload("smry", {"space": 0, "dims": 3 * M, "level_count": 1, "levels": [
        {"k": 1, "wssse": 0.0, "step": 1.0, "starts": struct.pack("<I", 0),
         "means": struct.pack(f"<{3 * M}i", *range(3 * M))}]})
    add("smrc-and-smry", assemble(ch[:k] + [["smry", smry]] + ch[k:]),
        "a smry and a smrc in one file", "a one-level smry put before the smrc",
        "two summaries for one motion; a reader that takes the first differs from one that "
        "takes the last", "FormatError", ["§3.4", "§4.15"])

    def lv(i, **kw):
        levels = list(rec.levels)
        levels[i] = dataclasses.replace(levels[i], **kw)
        return dataclasses.replace(rec, levels=tuple(levels)).dump()

    add("smrc-k-over-frames", _with_smrc(good, lv(1, k=F + 1)), "a level with k = F + 1",
        "level 1 k 5 -> 25", "a decoder sizes the blocks by k and reads 25 segments of 24 "
        "frames", "FormatError", ["§4.15"])
    add("smrc-step-zero", _with_smrc(good, lv(0, step=0.0)), "a level with step 0",
        "level 0 step -> 0", "every mean reads as 0", "FormatError", ["§4.15", "§1.3"])
    add("smrc-space-2", _with_smrc(good, dataclasses.replace(rec, space=2).dump()),
        "smrc space 2", "space 0 -> 2", "a reserved space", "FormatError", ["§4.15"])
    add("smrc-dims-not-3m", _with_smrc(good, dataclasses.replace(rec, dims=9).dump()),
        "a position smrc with D = 9 for 4 markers", "dims 12 -> 9",
        "the means do not line up with the markers", "FormatError", ["§4.15"])
    body = _smrc_payload(1, 1 << 23, [(3, 0.0, 1.0, [0, 1, 2], np.zeros((3, 0)))],
                         coded=b"\x00" * 5)
    add("smrc-values-over-limit", _with_smrc(good, body),
        "an angle smrc with D = 2^23 and k = 3: 3 x 2^23 means, above MAX_SUMMARY_VALUES",
        "hand-made smrc, coded field of 5 zero bytes", "a decoder allocates 3 x 2^23 means "
        "for a 5-byte field", "LimitExceededError", ["§4.15", "§8"])
    coded = rec.coded
    add("smrc-coded-overrun", _with_smrc(good, dataclasses.replace(
        rec, coded=coded[:-2]).dump()), "the smrc coded field cut by 2 bytes",
        "last 2 bytes of the coded field dropped", "a decoder reads past the payload",
        "FormatError", ["§4.15", "§5.3"])
    add("smrc-coded-leftover", _with_smrc(good, dataclasses.replace(
        rec, coded=coded + b"\x00").dump()), "a byte left after the last block of smrc",
        "one 0 byte appended to the coded field", "a decoder that does not close the "
        "payload", "FormatError", ["§4.15", "§5.3"])
    st5 = [0, 5, 9, 14, 20]
    q = rng.integers(-9, 9, (5, 3 * M))
    body = _smrc_payload(0, 3 * M, [(5, 1.0, 1.0, st5, q)], frames=F + 1)
    add("smrc-lengths-over-frames", _with_smrc(good, body),
        "a level whose segment lengths add up to F + 1",
        "last segment 4 -> 5 frames (starts stay increasing, the end passes F)",
        "the last segment reaches past the clip", "FormatError", ["§4.15"])
    body = _smrc_payload(0, 3 * M, [(5, 1.0, 1.0, st5, q)], frames=F - 1)
    add("smrc-lengths-under-frames", _with_smrc(good, body),
        "a level whose segment lengths add up to F - 1", "last segment 4 -> 3 frames",
        "the last frame belongs to no segment", "FormatError", ["§4.15"])
    e = np.zeros((2, M, 3), np.int64)
    e[0, 0, 0], e[1, 0, 0] = (1 << 31) - 1, 1
    coded = rc_wide((np.array([11, 11]).reshape(2, 1, 1), {"period": 2, "signed": False}),
                    (e, {"period": 2}))
    body = _smrc_payload(0, 3 * M, [(2, 1.0, 1.0, [0, 12], None)], coded=coded)
    add("smrc-mean-2pow31", _with_smrc(good, body),
        "a mean of 2^31: residuals 2^31 - 1, then 1 along the segments",
        "hand-made smrc, wide residuals", "a decoder that keeps the means in int32 wraps",
        "FormatError", ["§4.15", "§1.2"])
    # sum of k over the levels above 2^24 with D = 0: F = 2^18 + 1 frames, 64 levels of k = F
    Fb = (1 << 18) + 1
    d = Design(Fb, ["A"], bits=1, version=(1, 1))
    d.nodes.append((ROOT_PARENT, 0, [0], [1.0]))
    d.root = (0, np.zeros((Fb, 3), np.int64))
    d.payloads[("ROOT", 0)] = payload("ROOT", {"order": 0, "coded": rc(
        (np.zeros((Fb, 1, 3), np.int64), {}))})
    d.ancillary.append(("smrc", payload("smrc", {
        "space": 1, "dims": 0, "level_count": 64,
        "levels": [{"k": Fb, "wssse": 0.0, "step": 1.0}] * 64, "coded": b"\x00" * 5})))
    add("smrc-segments-over-limit", assemble(d.chunks()),
        "64 levels of k = F = 2^18 + 1 with D = 0: 2^24 + 64 segments, above "
        "MAX_SUMMARY_VALUES", "one-marker file of 2^18 + 1 frames, hand-made smrc with a "
        "5-byte coded field", "a decoder allocates 2^24 segment lengths for a 5-byte field "
        "(smry's starts are bounded by its payload, smrc's are not)", "LimitExceededError",
        ["§4.15", "§8"])


#: the §7.4 rules the smrc vectors probe (merged into VECTOR_RULES)
SMRC_VECTOR_RULES = _rules(
    ("R-4.15-1", "smrc-twice smrc-and-smry"),
    ("R-4.15-2", "smrc-k-over-frames smrc-step-zero smrc-space-2 smrc-dims-not-3m"),
    ("R-4.15-3", "smrc-values-over-limit smrc-segments-over-limit"),
    ("R-4.15-4", "smrc-coded-overrun smrc-coded-leftover"),
    ("R-4.15-5", "smrc-lengths-over-frames smrc-lengths-under-frames "
                 "smrc-lengths-wrap-32-bits"),
    ("R-4.15-6", "smrc-mean-2pow31"),
    ("R-4.15-7", "smrc-angles-no-dims smrc-one-level-k1 smrc-levels-any-order"),
)
VECTOR_RULES.update(SMRC_VECTOR_RULES)


def c3d_coding_vectors(vs: VectorSet):
    """§4.13 byte coding of chdr and cprm (stored, or one raw DEFLATE stream): an archive
    with both stored, and one invalid file per rejection rule. The streams are made here
    with zlib (raw DEFLATE, wbits -15), not by the records."""
    import dataclasses
    import zlib

    from mpz.chunks import Chdr, Cprm
    secs = ["§4.13", "§4.13.1", "§4.13.2", "§8"]

    def deflate(data: bytes, level: int = 9) -> bytes:
        co = zlib.compressobj(level, zlib.DEFLATED, -15)
        return co.compress(data) + co.flush()

    good = encode_within(c3d_motion(74, storage=1, F=8, M=3, J=1, C=1, n=2), max_error=1.0)
    ch = _c3d_chunks(good)
    hdr = Chdr.load(bytes(next(p for t, p in ch if t == "chdr")))
    prm = Cprm.load(bytes(next(p for t, p in ch if t == "cprm")))
    block = hdr.block
    section = dataclasses.replace(prm, coding=0).dump()[1:]
    assert hdr.coding == 1 and prm.coding == 1

    def with_payloads(chdr: bytes | None = None, cprm: bytes | None = None) -> bytes:
        new = {"chdr": chdr, "cprm": cprm}
        return assemble([[t, new[t] if new.get(t) is not None else p] for t, p in ch])

    head = bytes([hdr.processor])
    stored = with_payloads(head + b"\0" + block, b"\0" + section)
    vs.valid("uncommon", _numbered(vs, "u", "c3d-stored-header-and-parameters"), stored,
             "a C3D archive whose chdr and cprm are stored (coding 0): the same content as "
             "the reference encoder's DEFLATE streams", _c3d_features(stored), secs,
             "make_vectors.c3d_motion(74) -> mpz.encode(max_error=1.0), chdr and cprm "
             "rewritten with coding 0")

    def add(slug, data, description, corruption, risk):
        vs.invalid(_numbered(vs, "x", slug), data, description, corruption, risk,
                   "FormatError", secs)

    stream = deflate(section)
    add("chdr-coding-2", with_payloads(head + b"\2" + block), "chdr coding 2",
        "coding = 2", "no defined way to read the header")
    add("cprm-coding-2", with_payloads(cprm=b"\2" + section), "cprm coding 2",
        "coding = 2", "no defined way to read the parameters")
    add("cprm-deflate-truncated", with_payloads(cprm=b"\1" + stream[:-2]),
        "a cprm DEFLATE stream cut 2 bytes before its end", "last 2 bytes removed",
        "a decoder that accepts a partial inflation loses the last parameters")
    add("cprm-deflate-trailing-byte", with_payloads(cprm=b"\1" + stream + b"\0"),
        "one byte after the end of the cprm DEFLATE stream", "byte 0 appended",
        "bytes no rule reads: two decoders could disagree about the payload")
    add("chdr-deflate-invalid", with_payloads(head + b"\1" + b"\xff" * 8),
        "a chdr body that is not DEFLATE (block type 3)", "body = 8 x 0xff",
        "a decoder without the inflate error check reads garbage")
    bomb = deflate(section + bytes((1 << 20) - len(section)))
    add("cprm-inflates-past-2pow17", with_payloads(cprm=b"\1" + bomb),
        f"a {len(bomb)}-byte cprm stream that inflates to 1 MiB, past MAX_C3D_PARAMETER_BYTES",
        "section padded with zeros to 2^20 bytes, deflated",
        "a decoder that inflates without a limit can be made to allocate without bound")
    add("cprm-stored-over-2pow17",
        with_payloads(cprm=b"\0" + section + bytes((1 << 17) + 1 - len(section))),
        "a stored cprm content of 2^17 + 1 bytes", "zeros appended",
        "content no C3D parameter section can have")
    add("cprm-empty-payload", with_payloads(cprm=b""), "an empty cprm payload",
        "payload removed", "no coding byte")
    add("cprm-records-short-of-content", with_payloads(cprm=b"\1" + deflate(section + b"\0")),
        "cprm content one byte longer than its records", "byte 0 appended, deflated",
        "bytes no rule reads")
    add("chdr-stored-511-bytes", with_payloads(head + b"\0" + block[:511]),
        "a stored chdr block of 511 bytes", "last byte removed",
        "a header block of the wrong size: its words would shift")
    add("chdr-inflates-to-513-bytes", with_payloads(head + b"\1" + deflate(block + b"\0")),
        "a chdr stream that inflates to 513 bytes", "byte appended, deflated",
        "one byte past the 512-byte header block")
    add("chdr-payload-1-byte", with_payloads(head), "a chdr payload of 1 byte",
        "coding and body removed", "no coding byte")


def clarified_accept_vectors(vs: VectorSet):
    """Files the third clean-room review's settled text accepts, which no vector showed
    (spec §4.13.1 and §4.14.2, stop 27): a C3D header whose counts disagree with the
    chunks, and ASF bone names and text fields that a looser reading would refuse. Made
    last, so that the numbers of the vectors before them do not move."""
    import dataclasses
    import struct

    from mpz.chunks import Chdr
    good = _c3d_float_base()
    block = bytearray(Chdr.load(bytes(next(p for t, p in _c3d_chunks(good)
                                           if t == "chdr"))).block)
    # words 2 (points), 3 (analog words a frame), 4-5 (first, last frame), 10 (analog
    # samples a frame): bytes 2-9 and 18-19, C3D words numbered from 1 (§4.13.1)
    struct.pack_into("<HHHH", block, 2, 3, 7, 40, 41)
    struct.pack_into("<H", block, 18, 9)
    stale = _c3d_rebuild(good, "chdr", block=bytes(block))
    vs.valid("uncommon", _numbered(vs, "u", "c3d-header-counts-stale"), stale,
             "a C3D archive whose header words disagree with its chunks: 3 points (cpnt "
             "holds 7), 7 analog words a frame (cana: 12), frames 40..41 (F = 24), 9 analog "
             "samples a frame (cana: 4); none is checked, and a writer writes them back",
             _c3d_features(stale), ["§4.13", "§4.13.1", "§6.9"],
             "make_vectors.c3d_motion(71, storage=1) -> mpz.encode(max_error=1.0), chdr "
             "words 2-5 and 10 changed")
    amc = _asfs_base()
    rec = _skeleton_record(amc)
    bones = list(rec.bones)
    bones[0] = dataclasses.replace(bones[0], name="Root")
    bones[1] = dataclasses.replace(bones[1], name="ROOT")
    names = _skeleton_rebuild(amc, bones=tuple(bones), name="take\u000bone\u2028two",
                              version="1.10\u0085", mass="1.0\u000c\u001e")
    vs.valid("uncommon", _numbered(vs, "u", "asfs-names-Root-ROOT-line-separators"), names,
             "an asfs with bones named Root and ROOT (only the four bytes root are refused) "
             "and U+000B, U+000C, U+001E, U+0085 and U+2028 in its name, version and mass "
             "(only U+000A and U+000D are refused)", _skeleton_features(names),
             ["§2.1", "§2.3", "§4.14", "§4.14.2", "§6.10"],
             "make_vectors.skeleton_vectors' v-asfs file, bones 1-2 renamed and the text "
             "fields changed by hand")


def smrc_wrap_vectors(vs: VectorSet):
    """An smrc level whose segment lengths add up to F only modulo 2^32 (spec §4.15 step 2,
    §1.2), in the v-smrc-positions file; a builder of its own, after the others, so that
    the vectors before it keep their numbers."""
    good = _smrc_base()
    F, M = 24, 4
    # c_j = n_j - 1 = (2^31 - 1, 2^31 - 1, 23): the lengths (2^31, 2^31, 24) add up to
    # 2^32 + 24, which a decoder summing in 32 bits reads as 24 = F
    lengths = np.array([(1 << 31) - 1, (1 << 31) - 1, F - 1]).reshape(3, 1, 1)
    e = np.arange(3 * M * 3, dtype=np.int64).reshape(3, M, 3) % 7 - 3
    coded = rc_wide((lengths, {"period": 3, "signed": False}), (e, {"period": 3}))
    body = _smrc_payload(0, 3 * M, [(3, 1.0, 1.0, [0, 1, 2], None)], coded=coded)
    vs.invalid(_numbered(vs, "x", "smrc-lengths-wrap-32-bits"), _with_smrc(good, body),
               "an smrc level of k = 3 whose segment lengths 2^31, 2^31 and 24 add up to "
               "2^32 + 24, which is 24 = F in 32 bits",
               "hand-made smrc, wide length block: c = (2^31 - 1, 2^31 - 1, 23)",
               "a decoder that sums the lengths in 32 bits accepts the level and forms "
               "starts 0, 2^31, 2^32 (0 in 32 bits)", "FormatError",
               ["§1.2", "§4.15", "§5.4"])


def summary_edge_vectors(vs: VectorSet):
    """Summary rules that no earlier vector isolated (a review of stop 49, spec §4.10,
    §4.15): limits and header fields of smrc, its coded field when D = 0, a mean out of
    range in a predicted level, and space 1 with D > 0 in both summary chunks; in the
    v-smrc-positions file."""
    import dataclasses

    from mpz.chunks.summary import Smrc
    good = _smrc_base()
    F, M = 24, 4
    rng = np.random.default_rng(149)
    secs = ["§2.1", "§2.3", "§3.4", "§4.15", "§5.5"]
    rec = next(Smrc.load(c.payload) for c in container.parse(good) if c.type == "smrc")

    def add(slug, body, description, corruption, risk, error, sections):
        vs.invalid(_numbered(vs, "x", slug), _with_smrc(good, body), description,
                   corruption, risk, error, sections)

    # space 1 with D > 0: the B blocks of shape [k, D, 1] (smrc) and raw s32 means (smry)
    qa = rng.integers(-500, 500, (3, 5))
    qb = rng.integers(-500, 500, (2, 5))
    body = _smrc_payload(1, 5, [(2, 3.5, 0.001, [0, 11], qb), (3, 1.25, 0.001, [0, 7, 16], qa)],
                         frames=F)
    vs.valid("uncommon", _numbered(vs, "u", "smrc-angles-d5"), _with_smrc(good, body),
             "an angle smrc (space 1) with D = 5: levels k = 2 and 3, mean blocks of shape "
             "[k, 5, 1], the k = 2 level predicted from the k = 3 level",
             {"summary": "smrc", "dims": 5, "levels": [2, 3]}, secs,
             "make_vectors.summary_edge_vectors: hand-made smrc in the v-smrc-positions file")
    smry = payload("smry", {"space": 1, "dims": 5, "level_count": 2, "levels": [
        {"k": k, "wssse": w, "step": 0.001, "starts": np.asarray(st, "<u4").tobytes(),
         "means": np.asarray(q, "<i4").tobytes()}
        for k, w, st, q in ((2, 3.5, [0, 11], qb), (3, 1.25, [0, 7, 16], qa))]})
    ch = [["smry", smry] if c.type == "smrc" else [c.type, c.payload]
          for c in container.parse(good)]
    vs.valid("uncommon", _numbered(vs, "u", "smry-angles-d5"), assemble(ch),
             "an angle smry (space 1) with D = 5 in a 1.1 file: levels k = 2 and 3, five "
             "s32 means per segment", {"summary": "smry", "dims": 5, "levels": [2, 3]},
             ["§2.3", "§3.4", "§4.10"],
             "make_vectors.summary_edge_vectors: the smrc of v-smrc-positions replaced by a "
             "hand-made smry")
    # Σ k x D = 2^24 + 1 with a coded field that decodes: only the limit rejects it
    big = (1 << 24) + 1
    body = _smrc_payload(1, big, [(1, 0.0, 1.0, [0], np.zeros((1, big), np.int64))],
                         frames=F)
    add("smrc-values-over-limit-coded", body,
        "an angle smrc of one level, k = 1 and D = 2^24 + 1, whose coded field holds every "
        "block: 2^24 + 1 means, one above MAX_SUMMARY_VALUES",
        "hand-made smrc, the 2^24 + 1 zero residuals coded in about 46 KB",
        "a decoder without the limit decodes it (the other limit vectors also fail for "
        "their short coded fields)", "LimitExceededError", ["§4.15", "§8"])
    # the coded field when D = 0: still decoded and closed
    body0 = _smrc_payload(1, 0, [(3, 0.0, 0.5, [0, 1, 23], np.zeros((3, 0)))], frames=F)
    rec0 = Smrc.load(body0)
    add("smrc-no-dims-leftover", dataclasses.replace(rec0, coded=rec0.coded + b"\x00").dump(),
        "an angle smrc with D = 0 and a byte left after its length block",
        "one 0 byte appended to the coded field", "a decoder that skips the coded field "
        "when there are no means", "FormatError", ["§4.15", "§5.3"])
    add("smrc-no-dims-overrun", dataclasses.replace(rec0, coded=rec0.coded[:-1]).dump(),
        "an angle smrc with D = 0 whose coded field is cut by one byte",
        "last byte of the coded field dropped", "a decoder that skips the coded field when "
        "there are no means", "FormatError", ["§4.15", "§5.3"])
    # §5.3 on smrc: a payload of 4 bytes, a first byte other than 0
    add("smrc-coded-4-bytes", dataclasses.replace(rec0, coded=b"\x00" * 4).dump(),
        "an angle smrc with D = 0 whose coded field is 4 bytes", "coded field -> 00 00 00 00",
        "a decoder that reads the 4-byte code value and stops", "FormatError",
        ["§2.4", "§4.15", "§5.3"])
    add("smrc-coded-first-byte", dataclasses.replace(
        rec0, coded=b"\x01" + rec0.coded[1:]).dump(),
        "an smrc coded field whose first byte is 1", "first byte 00 -> 01",
        "a decoder that skips the first byte without checking it", "FormatError",
        ["§2.4", "§4.15", "§5.3"])
    # header fields
    add("smrc-level-count-0", dataclasses.replace(rec0, level_count=0, levels=(),
                                                  coded=b"\x00" * 5).dump(),
        "an smrc with level_count 0", "no levels, a 5-byte coded field",
        "a summary with nothing in it", "FormatError", ["§2.4", "§4.15"])
    body = _smrc_payload(1, 0, [(1, 0.0, 1.0, [0], np.zeros((1, 0)))] * 65, frames=F)
    add("smrc-level-count-65", body, "an angle smrc of 65 levels of k = 1 (D = 0)",
        "level_count 65, one length block each", "a decoder that sizes a 64-entry table",
        "FormatError", ["§4.15", "§8"])
    add("smrc-k-zero", dataclasses.replace(rec0, levels=(dataclasses.replace(
        rec0.levels[0], k=0),)).dump(), "an smrc level with k = 0",
        "level 0 k 3 -> 0", "a decoder that codes an empty length block", "FormatError",
        ["§4.15"])
    add("smrc-wssse-nan", dataclasses.replace(rec, levels=(dataclasses.replace(
        rec.levels[0], wssse=math.nan), rec.levels[1])).dump(), "an smrc level with wssse "
        "NaN", "level 0 wssse -> NaN", "a ranking by WSSSE that compares NaN", "FormatError",
        ["§4.15", "§1.3"])
    add("smrc-wssse-negative", dataclasses.replace(rec, levels=(dataclasses.replace(
        rec.levels[0], wssse=-1.0), rec.levels[1])).dump(), "an smrc level with wssse -1",
        "level 0 wssse -> -1.0", "a negative error read as a better partition",
        "FormatError", ["§4.15"])
    # a predicted level out of range: level 1 (k = 2) is at 2^31 - 1, level 0 (k = 1) is
    # predicted from it as 2^31 - 1 and adds 1
    e1 = np.zeros((2, M, 3), np.int64)
    e1[0, 0, 0] = (1 << 31) - 1
    e0 = np.zeros((1, M, 3), np.int64)
    e0[0, 0, 0] = 1
    coded = rc_wide((np.array([F - 1]).reshape(1, 1, 1), {"period": 1, "signed": False}),
                    (e0, {"period": 1}),
                    (np.array([11, 11]).reshape(2, 1, 1), {"period": 2, "signed": False}),
                    (e1, {"period": 2}))
    body = _smrc_payload(0, 3 * M, [(1, 1.0, 1.0, [0], None), (2, 1.0, 1.0, [0, 12], None)],
                         coded=coded)
    add("smrc-predicted-mean-2pow31", body,
        "an smrc whose last level (k = 2) holds means of 2^31 - 1 and whose level k = 1, "
        "predicted from it as 2^31 - 1, adds 1: a mean of 2^31 in a predicted level",
        "hand-made smrc, wide residuals", "a decoder that range-checks the last level only",
        "FormatError", ["§4.15", "§1.2"])


#: the §7.4 rules the summary edge vectors probe (merged into VECTOR_RULES)
SUMMARY_EDGE_VECTOR_RULES = _rules(
    ("R-4.15-2", "smrc-level-count-0 smrc-level-count-65 smrc-k-zero smrc-wssse-nan "
                 "smrc-wssse-negative"),
    ("R-4.15-3", "smrc-values-over-limit-coded"),
    ("R-4.15-4", "smrc-no-dims-leftover smrc-no-dims-overrun smrc-coded-4-bytes "
                 "smrc-coded-first-byte"),
    ("R-4.15-6", "smrc-predicted-mean-2pow31"),
    ("R-4.10-3", "smry-angles-d5"),
    ("R-4.15-8", "smrc-angles-d5"),
)
VECTOR_RULES.update(SUMMARY_EDGE_VECTOR_RULES)


def mutation_gap_vectors(vs: VectorSet):
    """Checks that a mutation-testing run could remove without any vector failing (spec
    §4.13, §4.14, §4.15, §6.9): each file changes one thing in a good file of the builders
    above (the C3D archives of c3d_archive_vectors, the skeletons of skeleton_vectors, the
    v-smrc-positions file), so that a decoder without that one check accepts it; and an
    archive whose analog channel is coded with the least shift, -128. A builder of its own,
    last, so that the vectors before it keep their numbers."""
    import dataclasses
    from typing import Any

    from mpz.chunks import Cana, Cpnt

    add = functools.partial(_add_invalid, vs)

    # -- C3D archives: the float32 file of v-c3d-archive-float32, the int16 one of
    # u-c3d-int16-exact-on-grid
    good = _c3d_float_base()
    exact = mpz.encode(c3d_motion(72, storage=0, J=1, C=2, n=2))
    ch = _c3d_chunks(good)
    pnt = Cpnt.load(next(p for t, p in ch if t == "cpnt"))
    cana = Cana.load(next(p for t, p in ch if t == "cana"))
    ch16 = _c3d_chunks(exact)
    pnt16 = Cpnt.load(next(p for t, p in ch16 if t == "cpnt"))
    cana16 = Cana.load(next(p for t, p in ch16 if t == "cana"))
    assert pnt16.storage == 0 and pnt16.words[0].mode == 0 and pnt16.words[0].shift == 0
    w16 = list(pnt16.words)
    w16[0] = dataclasses.replace(w16[0], shift=1)
    add("cpnt-int16-shift-1", _c3d_rebuild(exact, "cpnt", words=tuple(w16)),
        "an int16 cpnt (storage 0) whose point 0 word channel has mode 0 with shift 1",
        "words[0].shift 0 -> 1", "a decoder that checks only the mode of int16 channels "
        "doubles every word, or writes words that int16 cannot hold", "FormatError",
        ["§4.13", "§4.13.3"])
    P = pnt.point_count
    sl = list(pnt.slots)
    sl[0] = P
    add("cpnt-slot-equals-point-count", _c3d_rebuild(good, "cpnt", slots=tuple(sl)),
        f"cpnt slots all distinct but not a permutation: point 0 in slot P = {P}",
        f"slots[0] = {P}", "a decoder that checks only that slots are distinct indexes "
        "past the markers and model outputs", "FormatError", ["§4.13.3"])
    akw: Any                    # offset and step, or bound: floats of a ModelAxis
    for slug, akw, what, risk in (
            ("cpnt-model-sum-rounds-to-inf",
             {"offset": 1.7976931348623157e308, "step": 2.0 ** 939},
             "offset 1.7976931348623157e308 (the largest binary64) and step 2^939: step x "
             "2^31 = 2^970 is finite, |offset| + step x 2^31 = 2^1024 - 2^970 rounds (ties "
             "to even) to +inf",
             "a decoder that checks offset and step x 2^31 apart, or the exact sum against "
             "the largest binary64, accepts values that overflow"),
            ("cpnt-model-bound-inf", {"bound": math.inf}, "bound +inf",
             "a decoder that checks bound >= 0 only declares an infinite error")):
        add(slug, _c3d_rebuild(good, "cpnt", models=_axis_changed(pnt.models, **akw)),
            f"a model-output axis with {what}", f"models[0].axes[1] {what.split(':')[0]}",
            risk, "FormatError", ["§4.13.3"])
    add("cana-coded-leftover-byte", _c3d_rebuild(good, "cana", coded=cana.coded + b"\x00"),
        "one byte after the last symbol of cana", "coded + 00",
        "a decoder that does not close() the cana payload", "FormatError",
        ["§4.13.4", "§5.3", "§6.9"])
    T16 = 24 * cana16.samples
    t0 = tuple(dataclasses.replace(x, order=0, low_bits=0) for x in cana16.table)
    for slug, value in (("cana-int16-value-32768", 32768),
                        ("cana-int16-value-minus-32769", -32769)):
        col = np.zeros((T16, 1, 1), np.int64)
        col[5, 0, 0] = value
        zero = np.zeros((T16, 1, 1), np.int64)
        add(slug, _c3d_rebuild(exact, "cana", table=t0, coded=rc(
            *([(col, {})] + [(zero, {})] * (cana16.channels - 1)))),
            f"an int16 analog word of {value}, one past the int16 range",
            f"channel 0 (order 0) word 5 = {value}, every other word 0",
            "a decoder whose range check is off by one writes a word int16 cannot hold "
            f"({value} wraps to {(value + 32768) % 65536 - 32768})", "FormatError",
            ["§4.13.4", "§6.9"])
    # a float32 bit-pattern word channel (mode 1, order 1) reaching v = 2^31
    F, J = 24, pnt.model_count
    zeros = np.zeros((F, 1, 1), np.int64)
    w0 = [dataclasses.replace(x, mode=0, shift=0, order=0, low_bits=0) for x in pnt.words]
    w0[0] = dataclasses.replace(w0[0], mode=1, order=1)
    md0 = tuple(dataclasses.replace(mm, axes=tuple(dataclasses.replace(ax, order=0)
                                                   for ax in mm.axes)) for mm in pnt.models)
    big = np.zeros((F, 1, 1), np.int64)
    big[3, 0, 0] = (1 << 31) - 1
    big[4, 0, 0] = 1
    coded = rc_wide(*([(big, {})] + [(zeros, {})] * (P - 1)
                      + [(np.zeros((F, J, 1), np.int64), {"signed": False})]
                      + [(zeros, {})] * (3 * J)))
    add("cpnt-bits-value-2pow31", _c3d_rebuild(good, "cpnt", words=tuple(w0), models=md0,
                                               coded=coded),
        "a float32 bit-pattern word channel (mode 1, order 1) whose value reaches v = 2^31 "
        "at frame 4 (residuals 2^31 - 1, then 1)", "point 0 word channel: mode 1, order 1, "
        "residuals chosen (wide); other channels and model axes order 0, all zero",
        "a decoder that checks only the mode 0 ranges writes the word 0x80000000 (-0.0); "
        "one that keeps v in 32 bits wraps it to -2^31, the word 0xFFFFFFFF (a NaN)",
        "FormatError", ["§4.13.3", "§6.9"])

    # -- skeletons: the files of v-bvhs-synthetic-default and v-asfs-synthetic-default
    bvh = _bvhs_base()
    amc = _asfs_base()
    arec = _skeleton_record(amc)

    def bad(slug, src, changes, what, risk, section):
        add(slug, _skeleton_rebuild(src, **changes), what, what, risk, "FormatError",
            [section])

    bad("bvhs-frame-time-inf", bvh, {"frame_time": math.inf}, "bvhs frame_time +inf",
        "a decoder that checks frame_time > 0 only: a writer prints Frame Time: inf",
        "§4.14.1")
    bad("skeleton-position-bound-inf", bvh, {"position_bound": math.inf},
        "position_bound +inf", "a decoder that checks position_bound >= 0 only: a promise "
        "that means nothing", "§4.14")
    bad("asfs-root-orientation-nan", amc, {"root_orientation": (0.0, math.nan, 0.0)},
        "an asfs root_orientation with a NaN (y)", "forward kinematics gives NaN for every "
        "joint", "§4.14.2")
    bones = list(arec.bones)
    b = 1
    assert bones[b].parent <= b
    bones[b] = dataclasses.replace(bones[b], parent=b + 1)
    bad("asfs-parent-itself", amc, {"bones": tuple(bones)},
        f"bone {b}'s parent is joint {b + 1}, which is bone {b} itself (bone b is joint b + 1)",
        "a decoder that compares the parent with b + 1, mixing bone and joint numbers, "
        "loops on a bone that is its own parent", "§4.14.2")
    assert arec.amc_order[0] == 0 and 0 not in arec.amc_order[1:]
    bad("asfs-amc-order-misses-root", amc, {"amc_count": arec.amc_count - 1,
                                            "amc_order": arec.amc_order[1:]},
        f"AMC order {list(arec.amc_order[1:])} leaves out joint 0, the root",
        "an AMC frame always has a root line: a writer drops the root's values", "§4.14.2")
    joints = arec.bone_count + 1
    bad("asfs-amc-order-one-past-end", amc, {"amc_count": arec.amc_count + 1,
                                             "amc_order": (*arec.amc_order, joints)},
        f"AMC order names joint {joints} = bone_count + 1, one past the last joint",
        "a decoder whose range check is off by one indexes past the joints", "§4.14.2")

    # -- smrc: the mirror of smrc-mean-2pow31 in the v-smrc-positions file
    srcf = _smrc_base()
    M = 4
    e = np.zeros((2, M, 3), np.int64)
    e[0, 0, 0], e[1, 0, 0] = -((1 << 31) - 1), -1
    coded = rc_wide((np.array([11, 11]).reshape(2, 1, 1), {"period": 2, "signed": False}),
                    (e, {"period": 2}))
    body = _smrc_payload(0, 3 * M, [(2, 1.0, 1.0, [0, 12], None)], coded=coded)
    add("smrc-mean-minus-2pow31", _with_smrc(srcf, body),
        "a mean of -2^31: residuals -(2^31 - 1), then -1 along the segments",
        "hand-made smrc, wide residuals", "a decoder that checks q > -2^31 - 1, or q < 2^31 "
        "only, accepts a mean smry cannot hold (-2^31 is not a mean, §4.15)", "FormatError",
        ["§4.15", "§1.2"])

    # -- uncommon: an analog channel whose words are k x 2^-128 (mode 0, shift -128)
    mc = c3d_motion(75, storage=1)
    a = mc.extras["c3d"]
    T = a.analog.shape[0]
    bits = np.where(np.arange(T) % 3 == 0, 0x00600000, 0x00200000).astype("<u4")
    bits[np.arange(T) % 5 == 4] = 0
    a.analog[:, 2] = bits.view("<f4")
    low = encode_within(mc, max_error=1.0)
    table = Cana.load(next(p for t, p in _c3d_chunks(low) if t == "cana")).table
    assert (table[2].mode, table[2].shift) == (0, -128), table[2]
    back = mpz.decode(low).extras["c3d"].analog[:, 2]
    assert np.array_equal(np.ascontiguousarray(back).view("<u4"), bits)
    vs.valid("uncommon", _numbered(vs, "u", "c3d-analog-shift-minus-128"), low,
             "a float32 C3D archive whose analog channel 2 holds the subnormal words "
             "0x00200000 and 0x00600000 (2^-128 and 3 x 2^-128) and 0: coded in mode 0 with "
             "shift -128, the least shift, k = 1 and 3", _c3d_features(low),
             ["§2.1", "§2.3", "§4.13", "§4.13.4", "§6.9"],
             "make_vectors.c3d_motion(75, storage=1), analog channel 2 set to the bit "
             "patterns by hand -> mpz.encode(max_error=1.0)")


#: the §7.4 rules the mutation gap vectors probe (merged into VECTOR_RULES)
MUTATION_GAP_VECTOR_RULES = _rules(
    ("R-4.13-2", "cpnt-int16-shift-1 c3d-analog-shift-minus-128"),
    ("R-4.13.3-1", "cpnt-slot-equals-point-count cpnt-model-sum-rounds-to-inf "
                   "cpnt-model-bound-inf"),
    ("R-6.9-1", "cana-coded-leftover-byte cana-int16-value-32768 "
                "cana-int16-value-minus-32769 cpnt-bits-value-2pow31"),
    ("R-6.9-2", "c3d-analog-shift-minus-128"),
    ("R-4.14.1-1", "bvhs-frame-time-inf"),
    ("R-4.14-2", "skeleton-position-bound-inf"),
    ("R-4.14.2-1", "asfs-root-orientation-nan asfs-parent-itself asfs-amc-order-misses-root "
                   "asfs-amc-order-one-past-end"),
    ("R-4.15-6", "smrc-mean-minus-2pow31"),
)
VECTOR_RULES.update(MUTATION_GAP_VECTOR_RULES)


def range_gap_vectors(vs: VectorSet):
    """Range rules of the §4.13 and §4.14 layout tables that no invalid vector isolated (an
    audit: only R-4.13.2-1, R-4.13.4-1, R-4.14.1-1 and R-4.14.2-1 paraphrased them): each
    file changes one field of a good file of the builders above (the asfs file and the bvhs
    file of mutation_gap_vectors, the float32 C3D archive) to a value its Range column
    forbids, with the channel layer kept consistent where a count changes. Every one breaks
    only (1.1) rules, so a 1.0 decoder skips the chunk and decodes the file. A builder of its
    own, last, so that the vectors before it keep their numbers.

    A count one past its Range (bvhs channel_count 7, asfs dof_count 8) cannot come alone:
    more kinds than there are repeat one, which the reference checks after the count. Not
    here: an amc_count other than the length of amc_order (the u16 count is that length, so
    no file holds it); a root_order_count of 7 (it too repeats a kind: asfs-root-order-repeats
    has the repeat alone, with the count in range); a dof_count of 7, which the Range
    allows."""
    import dataclasses

    from mpz.chunks import Cprm

    add = functools.partial(_add_invalid, vs)

    bvh = _bvhs_base()
    amc = _asfs_base()
    arec = _skeleton_record(amc)
    brec = _skeleton_record(bvh)

    def bad(slug, src, changes, what, risk, section):
        add(slug, _skeleton_rebuild(src, **changes), what, what, risk, "FormatError",
            [section])

    def bone(b, **kw):
        bb = list(arec.bones)
        bb[b] = dataclasses.replace(bb[b], **kw)
        return {"bones": tuple(bb)}

    def widened(rec, F, at, extra):
        """The channel layer of ``rec`` with ``extra`` channels inserted at channel ``at``
        (entries copied from channel at - 1 without wrap, values 0): what a skeleton that
        declares ``extra`` more channels there needs, so that only its Range is broken."""
        e = dataclasses.replace(rec.channels[at - 1], wrap=0, low=0)
        ch = (*rec.channels[:at], *(e,) * extra, *rec.channels[at:])
        x = rec.integers(F)
        x = np.concatenate([x[:, :at], np.zeros((F, extra), np.int64), x[:, at:]], axis=1)
        wide = dataclasses.replace(rec, channel_count=len(ch), channels=ch)
        return {"channel_count": len(ch), "channels": ch,
                "coded": _skeleton_layer(wide, x)}

    # -- asfs: the file of v-asfs-synthetic-default
    bad("asfs-encoding-2", amc, {"encoding": 2}, "asfs encoding 2",
        "an unknown text encoding: a writer cannot choose the bytes of the ASF", "§4.14.2")
    bad("asfs-mass-line-feed", amc, {"mass": "1.0\n0"}, "an ASF mass text with a line feed "
        "(U+000A)", "the ':units mass' line of an ASF written from it breaks: a reader reads "
        "mass 1.0 and then a stray line '0'",
        "§4.14.2")
    bad("asfs-version-carriage-return", amc, {"version": "1.10\r2"},
        "an ASF version text with a carriage return (U+000D)",
        "the ':version' line breaks for a reader that splits lines on CR (Python's "
        "splitlines does)", "§4.14.2")
    ro = arec.root_order
    assert ro == (0, 1, 2, 3, 4, 5), ro
    bad("asfs-root-order-repeats", amc, {"root_order": (0, 1, 2, 3, 4, 3)},
        "the root's order lists RX twice (TX TY TZ RX RY RX), its count 6 in range",
        "a decoder that checks only the kinds' range gives the root two x rotations and no "
        "y rotation", "§4.14.2")
    bad("asfs-root-position-inf", amc,
        {"root_position": (math.inf, *arec.root_position[1:])},
        "an asfs root_position with +inf (x)", "forward kinematics gives inf and NaN for "
        "every joint", "§4.14.2")
    b = 1                                     # lfemur: 3 dofs, 3 limits
    bn = arec.bones[b]
    assert bn.dof_count == 3 and bn.limit_count == 3, bn
    bad("asfs-bone-direction-nan", amc, bone(b, direction=(bn.direction[0], math.nan,
                                                           bn.direction[2])),
        f"bone {b}'s direction with a NaN (y)", "the bone's joint position is NaN, and that "
        "of every joint below it", "§4.14.2")
    bad("asfs-bone-length-inf", amc, bone(b, length=math.inf), f"bone {b}'s length +inf",
        "a decoder that checks only the lengths it can print writes 'length inf'; the joint "
        "positions below it are not finite (a length <= 0 is allowed, +inf is not)",
        "§4.14.2")
    bad("asfs-bone-axis-nan", amc, bone(b, axis=(bn.axis[0], bn.axis[1], math.nan)),
        f"bone {b}'s axis with a NaN (z)", "the bone's rotation is NaN: every joint below "
        "it is NaN", "§4.14.2")
    # dof_count 8: eight kinds of 0..6 repeat one, so the count's Range cannot be broken
    # alone; the limits drop to 0 (allowed) and the channel layer gets the 5 new channels
    at = len(arec.root_order) + sum(x.dof_count for x in arec.bones[:b + 1])
    bad("asfs-dof-count-8", amc, {**bone(b, dof_count=8, dofs=(*bn.dofs, 0, 1, 2, 6, 3),
                                         limit_count=0, limits=()),
                                  **widened(arec, 40, at, 5)},
        f"bone {b} with 8 dofs (rx ry rz tx ty tz l rx), one past the Range 0..7; no "
        "limits; the channel layer holds the 5 added channels",
        "a decoder that reads the dofs into a 7-entry array before it checks them writes "
        "past it (the repeated rx is then also refused)", "§4.14.2")
    for slug, name, what in (
            ("asfs-bone-name-empty", "", "an empty name (the Range is 1..255 bytes)"),
            ("asfs-bone-name-no-break-space", "l\u00a0femur",
             "the name 'l\\u00a0femur', with U+00A0 (NO-BREAK SPACE, a Latin-1 byte A0)"),
            ("asfs-bone-name-nul", "l\u0000femur", "the name 'l\\u0000femur', with U+0000")):
        bad(slug, amc, bone(b, name=name), f"bone {b} with {what}",
            "the AMC frame line of the bone does not start with its name as one word (or "
            "a C reader ends the name at NUL)", "§4.14.2")

    # -- bvhs: the file of v-bvhs-synthetic-default
    j = 0
    jt = brec.joints[j]
    assert jt.channel_count == 6 and jt.parent == ROOT_PARENT, jt
    ch7 = (*jt.channels, jt.channels[3])
    joints = list(brec.joints)
    joints[j] = dataclasses.replace(jt, channel_count=7, channels=ch7)
    bad("bvhs-channel-count-7", bvh, {"joints": tuple(joints), **widened(brec, 60, 6, 1)},
        f"joint {j} (the ROOT) with 7 channels, one past the Range 0..6 (its Zrotation "
        "twice); the channel layer holds the added channel",
        "a decoder that reads a joint's channels into a 6-entry array before it checks them "
        "writes past it", "§4.14.1")

    # -- C3D: the float32 archive of v-c3d-archive-float32
    good = _c3d_float_base()
    ch = _c3d_chunks(good)
    add("cana-channels-0", _c3d_rebuild(good, "cana", channels=0, table=(),
                                        coded=BlockEncoder().finish()),
        "a cana with no analog channel (C = 0): an empty table and a coded field of no "
        "block, closed", "channels = 0, table and coded emptied to match",
        "a decoder that checks only C x n <= 65535 accepts an analog chunk with nothing in "
        "it; a C3D writer writes 0 analog words a frame with an analog rate",
        "FormatError", ["§4.13.4"])
    prm = Cprm.load(next(p for t, p in ch if t == "cprm"))
    r = 2                                     # POINT:SCALE, not locked
    assert prm.records[r].group > 0 and prm.records[r].locked == 0, prm.records[r]
    recs = list(prm.records)
    recs[r] = dataclasses.replace(recs[r], locked=2)
    add("cprm-locked-2", _c3d_rebuild(good, "cprm", records=tuple(recs)),
        f"a parameter record ({recs[r].name.decode()}) whose locked flag is 2",
        f"record {r} locked 0 -> 2",
        "a decoder that tests locked != 0 writes it as locked (a negative name length): "
        "what the source held is not what comes back", "FormatError", ["§4.13.2"])
    # §3.4: the first chunk is MHDR whatever follows; x93 probes it with a known chunk
    ch = [list(c) for c in _c3d_chunks(good)]
    ch.insert(0, ["zzzz", b"an ancillary chunk no decoder knows"])
    add("unknown-chunk-before-mhdr", assemble(ch),
        "an ancillary chunk of a type no decoder knows (zzzz) placed before MHDR",
        "a zzzz chunk of 35 bytes inserted at offset 8",
        "a decoder that skips unknown ancillary chunks while it walks them, before it checks "
        "that the first chunk is MHDR, accepts a file that does not start with its header "
        "(the reference did until stop 66: a fuzzing QA run)", "FormatError", ["§3.4"])


def contract_gap_vectors(vs: VectorSet):
    """What the decoder and encoder contracts keep (spec §6.8, §7.1 item 4, §7.2) and no file
    could catch (a QA run of the runner, stop 53): every decodable vector's rate (120, 30,
    100, 65.0364227294921875) is exact in binary32, so a decoder that reported the rate as
    a float32 passed; the encoder inputs were at 120 Hz in mm and m, with ASCII names of at
    most 4 bytes and no marker that is a gap throughout, so an encoder that stored the rate
    as a float32, mixed up units, wrote no unit as mm, cut or upper-cased names or dropped
    an empty marker passed. A builder of its own, last, so that the vectors before it keep
    their numbers."""
    m = _synth("walk", 24, markers=4, seed=51, rate=59.94)
    d = design_from_motion(m, step=1.0, nodes=[(None, 0, [0]), (0, 1, [1, 2, 3])])
    vs.valid("uncommon", _numbered(vs, "u", "rate-59.94"), d.build(),
             "rate 59.94 Hz, which binary32 cannot hold (59.939998626708984): a decoder must "
             "report the binary64 value exactly", {"rate": 59.94}, ["§4.1", "§6.8"],
             "hand-built from mpz.synth walk (rate=59.94)")
    names = ["Hüfte_links_vorn", "Ω-Marker", "x" * 40 + "_lange_Bezeichnung_äöü",
             "名前", "LeftShoulderMarkerWithAVeryLongDescriptiveName_001", "ASIS r"]
    m = _synth("walk", 50, markers=6, seed=52, rate=59.94, gap_fraction=0.04)
    valid = m.valid.copy()
    valid[:, 3] = False
    m = mpz.Motion(m.positions / 10.0, names, m.rate, "cm", valid)
    vs.encoder_input("e03-names-cm-59.94-gap-throughout", m, [0.1],
                     "6 markers in cm at 59.94 Hz (not a binary32), names of up to 65 bytes "
                     "with non-ASCII letters and a space, marker 3 a gap throughout, 4% gaps")
    m = _synth("wave", 40, markers=5, seed=53, rate=23.976)
    vs.encoder_input("e04-inches-23.976", mpz.Motion(m.positions / 25.4, m.names, m.rate,
                                                      "in", m.valid), [0.05],
                     "5 markers in inches at 23.976 Hz")
    m = _synth("jump", 40, markers=5, seed=54, rate=250.0)
    vs.encoder_input("e05-no-units", mpz.Motion(m.positions, m.names, m.rate, "", m.valid),
                     [2.0], "5 markers without a length unit (MHDR units 0), 250 Hz")


#: the §7.4 rules the range gap vectors probe (merged into VECTOR_RULES)
RANGE_GAP_VECTOR_RULES = _rules(
    ("R-3.4-1", "unknown-chunk-before-mhdr"),
    ("R-4.13.2-1", "cprm-locked-2"),
    ("R-4.13.4-1", "cana-channels-0"),
    ("R-4.14.1-1", "bvhs-channel-count-7"),
    ("R-4.14.2-1", "asfs-encoding-2 asfs-mass-line-feed asfs-version-carriage-return "
                   "asfs-root-order-repeats asfs-root-position-inf asfs-bone-direction-nan "
                   "asfs-bone-length-inf asfs-bone-axis-nan asfs-dof-count-8 "
                   "asfs-bone-name-empty asfs-bone-name-no-break-space asfs-bone-name-nul"),
)
VECTOR_RULES.update(RANGE_GAP_VECTOR_RULES)


# ------------------------------------ §4.13 DEFLATE as zlib reads it (spec of stop 70) --
class DeflateCase(NamedTuple):
    """One crafted chdr or cprm stream of :func:`deflate_streams`: the chunk it stands in
    (``chunk``), the stream, and zlib's message for it (``zlib_error``, None for a valid
    stream). For an invalid stream, ``twin`` is the same stream with the one fault undone,
    which zlib inflates to the content: what shows that nothing else is wrong with it."""

    chunk: str
    stream: bytes
    zlib_error: str | None
    twin: bytes | None
    description: str
    corruption: str
    risk: str


def deflate_streams(section: bytes, block: bytes) -> dict[str, DeflateCase]:
    """Raw DEFLATE streams written bit by bit (:mod:`mpz.tools.deflate_bits`) for spec
    §4.13's list of what is not valid DEFLATE (R-4.13-3) and of what is (R-4.13-5), by
    vector slug: ``section`` is a cprm content, ``block`` a chdr content (512 bytes).
    conformance/test_deflate_streams.py checks each against zlib and against the frozen
    vectors."""
    from mpz.tools import deflate_bits as db

    def dynamic(tokens, litlen=db.FULL_LITLEN, dist=db.FULL_DIST, **kw) -> bytes:
        bw = db.BitWriter()
        db.dynamic_block(bw, tokens, litlen, dist, final=True, **kw)
        return bw.finish()

    def fixed(tokens) -> bytes:
        bw = db.BitWriter()
        db.fixed_block(bw, tokens, final=True)
        return bw.finish()

    ts, tb = db.lz77(section), db.lz77(block)
    assert db.inflated(ts) == section and db.inflated(tb) == block
    out = {}
    # HDIST = 30: a 31st distance code length (0), the 30 before it a complete code
    out["cprm-deflate-hdist-30"] = DeflateCase(
        "cprm", dynamic(ts, dist=db.FULL_DIST + (0,)), "too many length or distance symbols",
        dynamic(ts), "a cprm stream of one dynamic block with HDIST = 30 (31 distance code "
        "lengths, the last 0); the rest is a valid stream of the content",
        "dynamic block, HDIST 30: the 30 codes of a complete distance code and a length 0",
        "RFC 1951's field counts up to 32 distance codes: a decoder that takes the RFC's "
        "word accepts a stream zlib, and so the reference, refuses (§4.13)")
    # an incomplete literal/length code: one 9-bit code the data never uses left out
    lit, _ = db.symbols_used(tb)
    gone = max(s for s in range(286) if db.FULL_LITLEN[s] == 9 and s not in lit)
    short = list(db.FULL_LITLEN)
    short[gone] = 0
    out["chdr-deflate-litlen-incomplete"] = DeflateCase(
        "chdr", dynamic(tb, litlen=short), "invalid literal/lengths set", dynamic(tb),
        f"a chdr stream of one dynamic block whose literal/length code is incomplete: 285 "
        f"codes of 8 and 9 bits, symbol {gone}'s 9-bit code left out (sum 2^-length = "
        f"1 - 2^-9); the data uses only symbols that have a code",
        f"dynamic block, literal/length length of symbol {gone} 9 -> 0",
        "a decoder that builds its tables without the completeness check decodes the file; "
        "the reference (zlib) refuses it, so two decoders disagree on its validity")
    # a fixed block whose first back-reference has distance symbol 30
    i, m = next((k, t) for k, t in enumerate(ts) if isinstance(t, db.Match))
    lsym, lext, lbits = db.length_code(m.length)
    dsym, dext, dbits = db.distance_code(m.distance)
    bad = [*ts[:i], db.Raw("litlen", lsym, lext, lbits), db.Raw("dist", 30, dext, dbits),
           *ts[i + 1:]]
    out["cprm-deflate-fixed-distance-30"] = DeflateCase(
        "cprm", fixed(bad), "invalid distance code", fixed(ts),
        f"a cprm stream of one fixed-code block whose first back-reference (length "
        f"{m.length}, distance {m.distance}: symbol {dsym}) is written with distance symbol "
        f"30, its extra bits kept", f"fixed block, distance symbol {dsym} -> 30 (5 bits "
        f"11110) at the first match",
        "the fixed code has 5-bit codes for distance symbols 30 and 31, which mean nothing: "
        "a decoder that indexes a 30-entry table with them reads past it")
    # code lengths that start with 16 (repeat the previous length: there is none); the
    # block's code gives symbols 0-2 no code, so a decoder that takes 'previous' as 0 reads
    # the complete code it describes
    ll = (0, 0, 0) + (8,) * 229 + (9,) * 54
    seq = db.code_length_symbols(ll + db.FULL_DIST)
    assert seq[0] == (17, 0)

    def two_blocks(first) -> bytes:
        bw = db.BitWriter()
        db.fixed_block(bw, ts, final=False)
        db.dynamic_block(bw, [], ll, db.FULL_DIST, final=True, cl_sequence=first + seq[1:])
        return bw.finish()

    out["cprm-deflate-lengths-start-with-16"] = DeflateCase(
        "cprm", two_blocks([(16, 0)]), "invalid bit length repeat", two_blocks([(17, 0)]),
        "a cprm stream of a fixed-code block holding the content, then a final dynamic block "
        "holding no data whose code lengths start with 16 (copy the previous length 3 "
        "times), where no length precedes", "second block's first code length symbol 17 "
        "(3 zeros) -> 16 (3 copies of the previous length)",
        "a decoder that takes the missing previous length as 0 (or reads lens[-1]) reads "
        "a valid empty block")
    # valid: nonzero bits after the final block, one distance code of one bit, none at all
    pad = db.BitWriter()
    db.dynamic_block(pad, ts, db.FULL_LITLEN, db.FULL_DIST, final=True)
    unused = -pad.bit_length % 8
    assert unused
    out["cprm-deflate-padding-ones"] = DeflateCase(
        "cprm", pad.finish(fill=True), None, None,
        f"a cprm stream of one dynamic block whose last byte ends with {unused} bits after "
        f"the end of block, all 1 (zlib writes 0): §4.13 does not check them", "", "")
    td = db.lz77(block, distances=(1,))
    assert db.symbols_used(td)[1] == {0}
    runs = sum(isinstance(t, db.Match) for t in td)
    out["chdr-deflate-one-distance-code"] = DeflateCase(
        "chdr", dynamic(td, dist=(1,)), None, None,
        f"a chdr stream of one dynamic block whose distance code is one code of 1 bit "
        f"(HDIST 0, distance symbol 0: distance 1), which {runs} "
        f"back-references use (runs of a byte): an incomplete code that RFC 1951 "
        f"section 3.2.7 allows", "", "")
    out["cprm-deflate-no-distance-codes"] = DeflateCase(
        "cprm", dynamic(list(section), dist=(0,)), None, None,
        "a cprm stream of one dynamic block without distance codes (HDIST 0, its one length "
        "0): every byte a literal, as RFC 1951 section 3.2.7 allows", "", "")
    return out


@functools.cache
def _c3d_coding_base() -> bytes:
    """The archive of c3d_coding_vectors (c3d_motion(74)), encoded once."""
    return encode_within(c3d_motion(74, storage=1, F=8, M=3, J=1, C=1, n=2), max_error=1.0)


def deflate_vectors(vs: VectorSet):
    """§4.13's list of what valid DEFLATE is (the spec text of stop 70): one invalid file
    per kind of stream zlib refuses that RFC 1951 leaves open or that zlib never writes,
    and one uncommon file per kind of stream it accepts that the reference encoder never
    writes, each in the archive of c3d_coding_vectors with one chdr or cprm body replaced.
    A builder of its own, last, so that the vectors before it keep their numbers."""
    import dataclasses

    from mpz.chunks import Chdr, Cprm
    good = _c3d_coding_base()
    ch = _c3d_chunks(good)
    hdr = Chdr.load(bytes(next(p for t, p in ch if t == "chdr")))
    prm = Cprm.load(bytes(next(p for t, p in ch if t == "cprm")))
    section = dataclasses.replace(prm, coding=0).dump()[1:]
    head = {"chdr": bytes([hdr.processor, 1]), "cprm": b"\1"}
    cases = deflate_streams(section, hdr.block)
    for slug, c in cases.items():
        data = assemble([[t, head[t] + c.stream if t == c.chunk else p] for t, p in ch])
        sec = "§4.13.1" if c.chunk == "chdr" else "§4.13.2"
        if c.zlib_error is not None:
            vs.invalid(_numbered(vs, "x", slug), data, c.description, c.corruption, c.risk,
                       "FormatError", ["§4.13", sec])
    for slug, c in cases.items():
        if c.zlib_error is None:
            data = assemble([[t, head[t] + c.stream if t == c.chunk else p] for t, p in ch])
            vs.valid("uncommon", _numbered(vs, "u", slug), data, c.description,
                     _c3d_features(data), ["§2.1", "§2.3", "§4.13", "§6.9"],
                     f"make_vectors.c3d_motion(74) -> mpz.encode(max_error=1.0), the {c.chunk} "
                     f"body written by make_vectors.deflate_streams (mpz.tools.deflate_bits)")


#: the §7.4 rules the DEFLATE vectors probe (merged into VECTOR_RULES)
DEFLATE_VECTOR_RULES = _rules(
    ("R-4.13-3", "cprm-deflate-hdist-30 chdr-deflate-litlen-incomplete "
                 "cprm-deflate-fixed-distance-30 cprm-deflate-lengths-start-with-16"),
    ("R-4.13-5", "cprm-deflate-padding-ones chdr-deflate-one-distance-code "
                 "cprm-deflate-no-distance-codes"),
)
VECTOR_RULES.update(DEFLATE_VECTOR_RULES)


def _bytes_swapped(data: bytes, ctype: str, fake: bytes, real: bytes) -> bytes:
    """``data`` with the bytes ``fake`` (once in the ``ctype`` payload) replaced by ``real``
    of the same length, CRCs recomputed: a string the record classes cannot hold (bytes
    that are not UTF-8), written over a placeholder they built."""
    from mpz.container import scan
    assert len(fake) == len(real)
    out = []
    for c in scan(data).chunks:
        p = bytes(c.payload)
        if c.type == ctype:
            assert p.count(fake) == 1, (ctype, fake)
            p = p.replace(fake, real)
        out.append((c.type, p))
    return assemble(out)


def settled_text_vectors(vs: VectorSet):
    """What the spec text of stop 70 settled and no vector showed: strings that are not
    UTF-8 in a skeleton chunk (§1), a cprm record of dims 255, 255, 0 and one of group id
    128 with bytes outside ASCII (§4.13.2), a cana whose storage is not cpnt's (§4.13.4), a
    skeleton whose joint names and parents are not MNAM's and HIER's (§4.14), ASF bones
    with a reversed limit, a length <= 0 and a zero direction (§4.14.2). Each edits one
    good file of the builders above. A builder of its own, last, so that the vectors
    before it keep their numbers."""
    import dataclasses

    from mpz.chunks import Cprm
    from mpz.chunks.c3d import Param
    from mpz.io.amc import parse_amc, parse_asf

    # -- invalid: strings that are not UTF-8, the CRC recomputed
    bvh = _bvhs_base()
    brec = _skeleton_record(bvh)
    assert brec.encoding == 0 and brec.joints[0].name == "Hips"
    joints = list(brec.joints)
    joints[0] = dataclasses.replace(joints[0], name="HQfte")
    latin = _bytes_swapped(_skeleton_rebuild(bvh, joints=tuple(joints), encoding=1), "bvhs",
                           b"\x05HQfte", b"\x05H\xfcfte")
    vs.invalid(_numbered(vs, "x", "bvhs-name-latin-1"), latin,
               "a bvhs whose encoding is 1 (Latin-1) and whose joint 0 is named with the "
               "Latin-1 bytes 48 FC 66 74 65 (Hüfte), not UTF-8",
               "encoding 0 -> 1; joint 0 name 'Hips' -> bytes 48 FC 66 74 65",
               "a decoder that reads the names as `encoding` says (or does not check them) "
               "accepts a string the format stores only as UTF-8 (§1)", "FormatError",
               ["§1", "§4.14.1"])
    amc = _asfs_base()
    arec = _skeleton_record(amc)
    assert arec.encoding == 0
    fake = " ein synthetisches Skelett (fQr make_vectors)"
    comments = _bytes_swapped(_skeleton_rebuild(amc, comments=fake), "asfs", fake.encode(),
                              fake.encode().replace(b"fQr", b"f\xfcr"))
    vs.invalid(_numbered(vs, "x", "asfs-comments-latin-1"), comments,
               "an asfs (encoding 0, UTF-8) whose informative comments str16 holds the "
               "Latin-1 byte FC (f\\xfcr), not UTF-8",
               "comments -> ' ein synthetisches Skelett (f\\xfcr make_vectors)' as Latin-1",
               "a decoder that skips the checks of informative fields accepts a string the "
               "format stores only as UTF-8 (§1: the file is rejected, the chunk is not "
               "skipped)", "FormatError", ["§1", "§4.14.2"])

    # -- uncommon: cprm records (the float32 archive of v-c3d-archive-float32)
    good = _c3d_float_base()
    prm = Cprm.load(next(p for t, p in _c3d_chunks(good) if t == "cprm"))
    c3d_secs = ["§2.1", "§2.3", "§4.13", "§4.13.2", "§6.9"]
    recs = (*prm.records, Param(group=1, locked=0, name=b"EMPTY",
                                description=b"no values: 255 x 255 x 0", type=4,
                                dims=bytes([255, 255, 0]), data=b""))
    empty = _c3d_rebuild(good, "cprm", count=len(recs), records=recs)
    vs.valid("uncommon", _numbered(vs, "u", "cprm-dims-255-255-0"), empty,
             "a cprm whose last record is a float32 parameter (POINT:EMPTY) of dims 255, 255, "
             "0 and no data: n = 4 x 255 x 255 x 0 = 0, though the product formed one dim at a "
             "time passes the bytes left (none) at the first factor and 2^17 at the second",
             _c3d_features(empty), c3d_secs,
             "make_vectors.c3d_motion(71, storage=1) -> mpz.encode(max_error=1.0), a cprm "
             "record appended")
    recs = (*prm.records,
            Param(group=-128, locked=0, name=b"ZUS\xc4TZE",
                  description="Zusätze, gemessen am 3. März".encode()),
            Param(group=3, locked=0, name=b"DUR\xc9E", description="durée (s)".encode(),
                  type=4, dims=b"", data=struct.pack("<f", 1.5)))
    g128 = _c3d_rebuild(good, "cprm", count=len(recs), records=recs)
    vs.valid("uncommon", _numbered(vs, "u", "cprm-group-128-non-ascii"), g128,
             "a cprm with a group record of id 128 (group = -128) named with the Latin-1 "
             "bytes ZUS C4 TZE and a UTF-8 description, and an EVENT parameter named DUR C9 E "
             "(Latin-1) with a UTF-8 description: bytes outside ASCII are kept as stored",
             _c3d_features(g128), c3d_secs,
             "make_vectors.c3d_motion(71, storage=1) -> mpz.encode(max_error=1.0), two cprm "
             "records appended")
    # -- uncommon: cpnt int16, cana float32
    mc = c3d_motion(76, storage=0, J=1, C=2, n=2)
    a = mc.extras["c3d"]
    T = a.analog.shape[0]
    rng = np.random.default_rng(76)
    an = np.zeros((T, 2), "<f4")
    an[:, 0] = rng.integers(-3000, 3000, T) * 2.0 ** -15
    an[:, 1] = np.where(np.arange(T) % 5 == 0, -0.0,
                        np.cumsum(rng.normal(0, 1, T))).astype("<f4")
    mc.extras["c3d"] = dataclasses.replace(a, analog=an, analog_storage=1)
    mixed = mpz.encode(mc)
    got = {c[0]: c[1] for c in _c3d_chunks(mixed)}
    assert (got["cpnt"][0], got["cana"][0]) == (0, 1)
    vs.valid("uncommon", _numbered(vs, "u", "c3d-cana-float32-cpnt-int16"), mixed,
             "a C3D archive whose points are int16 (cpnt storage 0) and whose analog words "
             "are float32 (cana storage 1), which no C3D file holds: each chunk's words "
             "decode by its own storage, and a writer writes float32 (cana is not int16)",
             _c3d_features(mixed), ["§2.1", "§2.3", "§4.13", "§4.13.3", "§4.13.4", "§6.9"],
             "make_vectors.c3d_motion(76, storage=0, J=1, C=2, n=2), analog replaced by "
             "float32 words (analog_storage 1) -> mpz.encode()")

    # -- uncommon: a skeleton that MNAM and HIER do not describe (the ASF of
    # v-asfs-synthetic-default, encoded with HIER = its bone tree)
    sk_secs = ["§2.1", "§2.3", "§4.14", "§4.14.2", "§6.10"]
    tree = mpz.encode(parse_amc(_skeleton_amc_text(), parse_asf(_SKELETON_ASF),
                                source="synthetic_01.amc"), hierarchy="skeleton")
    tb = list(_skeleton_record(tree).bones)
    assert [x.name for x in tb] == ["lhip", "lfemur", "ltibia", "back"]
    renamed = list(tb)
    renamed[1] = dataclasses.replace(tb[1], name="lthigh")
    names = _skeleton_rebuild(tree, bones=tuple(renamed))
    vs.valid("uncommon", _numbered(vs, "u", "asfs-names-other-than-mnam"), names,
             "an asfs whose bone 1 (joint 2) is named lthigh where MNAM names marker 2 "
             "lfemur: nothing ties the names together", _skeleton_features(names), sk_secs,
             "make_vectors._SKELETON_ASF, _skeleton_amc_text() -> parse_amc -> "
             "mpz.encode(hierarchy='skeleton'), bone 1 renamed")
    assert tb[2].parent == 2
    moved = list(tb)
    moved[2] = dataclasses.replace(tb[2], parent=0)
    parents = _skeleton_rebuild(tree, bones=tuple(moved))
    vs.valid("uncommon", _numbered(vs, "u", "asfs-parents-other-than-hier"), parents,
             "a file whose HIER is the ASF's bone tree (one node a marker, the reference "
             "encoder's hierarchy='skeleton'), with bone ltibia (joint 3) under the root in "
             "the asfs where HIER puts marker 3's node under marker 2's (lfemur): nothing "
             "ties the trees together", _skeleton_features(parents), sk_secs,
             "make_vectors._SKELETON_ASF, _skeleton_amc_text() -> parse_amc -> "
             "mpz.encode(hierarchy='skeleton'), bone 2's parent joint 2 -> 0")

    # -- uncommon: ASF values that §4.14.2 does not check
    bones = list(arec.bones)
    assert bones[1].limits[0] == (-160.0, 20.0)
    bones[0] = dataclasses.replace(bones[0], length=0.0)
    bones[1] = dataclasses.replace(bones[1], limits=((20.0, -160.0), *bones[1].limits[1:]))
    bones[2] = dataclasses.replace(bones[2], length=-7.2)
    bones[3] = dataclasses.replace(bones[3], direction=(0.0, 0.0, 0.0))
    odd = _skeleton_rebuild(amc, bones=tuple(bones))
    vs.valid("uncommon", _numbered(vs, "u", "asfs-limit-reversed-lengths-0-and-negative-"
                                        "direction-0"), odd,
             "an asfs whose bone lfemur has the limit (20, -160) (low above high), lhip the "
             "length 0, ltibia the length -7.2 and back the direction (0, 0, 0): none is "
             "checked", _skeleton_features(odd), ["§2.1", "§2.3", "§4.14", "§4.14.2", "§6.10"],
             "make_vectors.skeleton_vectors' v-asfs file, four bone fields changed by hand")


#: the §7.4 rules the vectors of stop 70 probe (merged into VECTOR_RULES)
SETTLED_VECTOR_RULES = _rules(
    ("R-4.14.1-1", "bvhs-name-latin-1"),
    ("R-4.14.2-1", "asfs-comments-latin-1"),
    ("R-4.13.2-3", "cprm-dims-255-255-0 cprm-group-128-non-ascii"),
    ("R-4.13.4-3", "c3d-cana-float32-cpnt-int16"),
    ("R-4.14-5", "asfs-names-other-than-mnam asfs-parents-other-than-hier"),
    ("R-4.14.2-2", "asfs-limit-reversed-lengths-0-and-negative-direction-0"),
    # every C3D vector whose features record c3d_file_sha256 (§7.3) but those of
    # deflate_vectors, whose archive is u41's: the writer's output is the same
    ("R-6.9-3", "c3d-archive-float32 c3d-int16-exact-on-grid c3d-no-analog-no-models "
                "c3d-stored-header-and-parameters c3d-header-counts-stale "
                "c3d-analog-shift-minus-128 cprm-dims-255-255-0 cprm-group-128-non-ascii "
                "c3d-cana-float32-cpnt-int16"),
    ("R-6.9-2", "c3d-cana-float32-cpnt-int16"),
)


def _merge_rules(table: dict) -> None:
    """Add ``table``'s rules to :data:`VECTOR_RULES`, keeping the rules a slug already has
    (``update`` would replace them: R-6.9-3 names vectors that probe other rules too)."""
    for slug, rules in table.items():
        VECTOR_RULES[slug] = tuple(sorted(set(VECTOR_RULES.get(slug, ())) | set(rules),
                                          key=_rule_key))


_merge_rules(SETTLED_VECTOR_RULES)

@functools.cache
def _asfs_small() -> bytes:
    """The ASF of v-asfs-synthetic-default with an AMC of 4 frames (reference encoder
    defaults): the smallest skeleton file the builders make, for the vectors of
    :func:`unprobed_accept_vectors` (conformance/vectors is held under 3 MiB)."""
    from mpz.io.amc import parse_amc, parse_asf
    return mpz.encode(parse_amc(_skeleton_amc_text(F=4), parse_asf(_SKELETON_ASF),
                                source="synthetic_01.amc"))


def _marked_1_0(data: bytes) -> bytes:
    """``data``, a file of version 1.1, with its MHDR saying 1.0 (version_minor 0)."""
    import dataclasses

    from mpz.chunks import Mhdr
    from mpz.container import scan
    chunks = []
    for c in scan(data).chunks:
        if isinstance(c.record, Mhdr):
            assert c.record.version_minor == 1
            chunks.append((c.type, dataclasses.replace(c.record, version_minor=0).dump()))
        else:
            chunks.append((c.type, c.payload))
    return assemble(chunks)


def unprobed_accept_vectors(vs: VectorSet):
    """Skeleton files that §1.3, §4.14, §4.14.1 and §4.14.2 call valid and that no vector
    showed, so that a decoder rejecting them passed the suite: position_bound -0.0, a bvhs
    frame_time other than 1 / MHDR.rate, U+0000 and other control characters in the asfs
    text fields that allow them, and a skeleton chunk in a file marked 1.0. Each edits one
    field of a 4-frame file (the vectors are held under 3 MiB). A builder of its own,
    last, so that the vectors before it keep their numbers."""
    import struct

    from mpz.chunks import Mhdr
    from mpz.container import scan
    from mpz.io.bvh import parse_bvh

    small = _asfs_small()
    rec = _skeleton_record(small)
    prov = ("make_vectors._SKELETON_ASF, _skeleton_amc_text(F=4) -> parse_amc -> "
            "mpz.encode()")
    asf_secs = ["§2.1", "§2.3", "§4.14", "§4.14.2", "§6.10"]

    # -- §1.3: "≥ 0" is a comparison, and -0.0 passes it
    neg = _skeleton_rebuild(small, position_bound=-0.0)
    assert struct.pack("<d", _skeleton_record(neg).position_bound) == b"\0" * 7 + b"\x80"
    vs.valid("uncommon", _numbered(vs, "u", "asfs-position-bound-negative-zero"), neg,
             "an asfs whose channel layer declares position_bound -0.0 (bytes 00 .. 00 80): "
             "finite and >= 0 by comparison, as §1.3 says (the sign bit is not tested), a "
             "bound of zero (none declared)", _skeleton_features(neg), ["§1.3", *asf_secs],
             prov + ", position_bound -> -0.0")

    # -- §4.14.1: frame_time is not checked against MHDR.rate
    bvh = mpz.encode(parse_bvh(_skeleton_bvh_text(F=4), source="synthetic.bvh"))
    assert mpz.info(bvh).rate == 30.0
    ft = _skeleton_rebuild(bvh, frame_time=0.5)
    vs.valid("uncommon", _numbered(vs, "u", "bvhs-frame-time-not-rate"), ft,
             "a bvhs whose frame_time is 0.5 s (2 Hz) in a file whose MHDR.rate is 30 Hz: "
             "frame_time is not checked against MHDR.rate (§4.14.1); the marker layer "
             "decodes at MHDR.rate", _skeleton_features(ft),
             ["§2.1", "§2.3", "§4.14", "§4.14.1", "§6.10"],
             "make_vectors._skeleton_bvh_text(F=4) -> parse_bvh -> mpz.encode(), frame_time "
             "0.0333333 -> 0.5")

    # -- §1, §4.14.2: U+0000 and the control characters are valid code points
    ctl = "\x00\x01\x1b\x7f\x9f"
    texts = dict(mass=rec.mass + ctl, version=rec.version + ctl, name=rec.name + ctl,
                 documentation=rec.documentation + ctl + "\r\n\x00",
                 comments=rec.comments + ctl + "\r",
                 amc_header=rec.amc_header + "\n" + ctl + "\r")
    ctrl = _skeleton_rebuild(small, **texts)
    got = _skeleton_record(ctrl)
    assert all(getattr(got, k) == v for k, v in texts.items())
    vs.valid("uncommon", _numbered(vs, "u", "asfs-texts-nul-and-controls"), ctrl,
             "an asfs whose mass, version and name end with U+0000, U+0001, U+001B, U+007F "
             "and U+009F, and whose documentation, comments and amc_header hold those and "
             "U+000D (documentation also U+0000 after a line feed): only mass, version and "
             "name refuse U+000A and U+000D, every other code point passes (§1, §4.14.2)",
             _skeleton_features(ctrl), ["§1", *asf_secs],
             prov + ", control characters appended to the six text fields")

    # -- §2.1, §4.14: a skeleton chunk in a file marked 1.0
    old = _marked_1_0(small)
    head = scan(old).chunks[0].record
    assert isinstance(head, Mhdr) and head.version_minor == 0
    vs.valid("uncommon", _numbered(vs, "u", "asfs-in-file-marked-1.0"), old,
             "an asfs in a file whose MHDR says version 1.0 (version_minor 0): an encoder "
             "should write 1.1, but a decoder accepts any minor version (§2.1), decodes the "
             "skeleton chunk as a 1.1 decoder (validity is judged by the decoder's minor "
             "version, not the file's) and a 1.0 decoder skips it", _skeleton_features(old),
             asf_secs, prov + ", MHDR version_minor 1 -> 0")

    # -- §1: encoding 1 (Latin-1) tells a writer how to write; the chunk holds UTF-8 text
    wide = rec.name + " \u0141\u00f3d\u017a \u2713"
    beyond = _skeleton_rebuild(small, encoding=1, name=wide)
    got = _skeleton_record(beyond)
    assert got.encoding == 1 and got.name == wide
    vs.valid("uncommon", _numbered(vs, "u", "asfs-latin-1-encoding-text-beyond-latin-1"),
             beyond,
             "an asfs whose encoding is 1 (Latin-1) and whose :name holds U+0141, U+017A and "
             "U+2713, which Latin-1 cannot encode: the strings are UTF-8 whatever encoding "
             "says, and the file is valid; a writer then writes the ASF in UTF-8 (§1)",
             _skeleton_features(beyond), ["§1", *asf_secs],
             prov + ", encoding 0 -> 1, characters beyond U+00FF appended to :name")


#: the §7.4 accept rules the vectors of :func:`unprobed_accept_vectors` probe
UNPROBED_ACCEPT_VECTOR_RULES = _rules(
    ("R-4.14-4", "asfs-position-bound-negative-zero"),
    ("R-4.14.1-2", "bvhs-frame-time-not-rate"),
    ("R-4.14.2-2", "asfs-texts-nul-and-controls asfs-latin-1-encoding-text-beyond-latin-1"),
    ("R-2.1-2 R-4.14-6", "asfs-in-file-marked-1.0"),
)
_merge_rules(UNPROBED_ACCEPT_VECTOR_RULES)

#: every builder, in the order that numbers the vectors: a new one goes last, so that the
#: vectors before it keep their numbers (conformance/test_manifest.py runs these too)
def core_review_vectors(vs: VectorSet):
    """What the two reviews of stop 71 found no vector for: an MNAM whose count exceeds
    marker_count (§4.2, now a row of §1.1: a decoder that stores names by marker index in
    an array of M overruns it; x37 has fewer names, not more), from the base file of
    :func:`invalid_vectors`; and names and meta strings with leading or trailing white
    space, a name of one tab and characters outside the BMP, which §4.2 and §4.11 allow
    and §6.8 returns exactly (a decoder that trims C3D-style padded labels, or writes
    UTF-16 surrogates wrongly into its JSON, passed every other vector). A builder of its
    own, last, so that the vectors before it keep their numbers."""
    d = base_design()
    d.build()
    base = d.chunks()
    names = CHUNKS["MNAM"].GRAMMAR.parse(base[_find(base, "MNAM")][1]).names
    assert len(names) == 4
    vs.invalid(_numbered(vs, "x", "names-count-over-markers"),
               assemble(_with_field(base, "MNAM", count=5, names=[*names, "E"])),
               "5 names for 4 markers", "MNAM count = 5, a fifth name 'E' appended",
               "a decoder that stores the names by marker index in an array of "
               "marker_count entries writes past its end", "FormatError", ["§4.2", "§1.1"])

    m = _synth("walk", 2, markers=5, seed=71)
    names = [" LFHD", "RFHD ", "\t", "\U0001F600", "T10\U00010348"]
    m = mpz.Motion(m.positions, names, m.rate, m.units)
    d = design_from_motion(m, step=1.0, nodes=[(None, 0, [0]), (0, 1, [1, 2, 3, 4])])
    d.ancillary.append(("meta", payload("meta", {"count": 3, "entries": [
        {"key": " subject ", "value": "Takeo \n"},
        {"key": "note", "value": "\U0001F3C3 run\t"},
        {"key": "\U00010348", "value": "  "}]})))
    data = d.build()
    from mpz.decoder import read_stream
    assert mpz.decode(data).names == names
    assert read_stream(data).meta[" subject "] == "Takeo \n"
    vs.valid("uncommon", _numbered(vs, "u", "names-meta-white-space-non-bmp"), data,
             "marker names ' LFHD' and 'RFHD ' (a space before, after), a tab, U+1F600 and "
             "'T10' + U+10348 (4-byte UTF-8, a surrogate pair in UTF-16); meta keys and "
             "values with spaces around them, a trailing newline and tab, U+1F3C3: all are "
             "returned exactly, nothing trimmed",
             {"names": names, "meta_white_space": True}, ["§4.2", "§4.11", "§6.8"],
             "hand-built from mpz.synth walk (frames=2, markers=5, seed=71)")


def summary_review_vectors(vs: VectorSet):
    """What the stop 71 review of §2, §4.10, §4.15 and §8 found no vector for: summary
    means that overflow to ±∞ at a finite step, which §4.10 and §4.15 step 6 call valid
    (R-4.10-2, R-4.15-7); an smrc and a C3D archive in a file marked 1.0, which §2.1
    accepts (R-4.15-7, R-4.13-6; u60 showed it for a skeleton only); and an smrc of D = 0
    whose step is 0, still checked though the level holds no means (R-4.15-2; x155 showed
    it for smry only). A builder of its own, last, so that the vectors before it keep
    their numbers."""


    def overflows(data: bytes, up: tuple[int, int], down: tuple[int, int]) -> bytes:
        """``data``, checked: its first level's means at ``up`` and ``down`` are ±∞."""
        summary = mpz.read_summary(data)
        assert summary is not None
        means = summary.levels[0].means
        assert np.isposinf(means[up]) and np.isneginf(means[down])
        return data

    big = (1 << 31) - 1
    # -- uncommon: smry means that overflow to ±∞ (a 1.0 file)
    d = _small(171)
    means = [0] * 24
    means[0], means[13] = big, -big                          # level k = 2, D = 12
    d.ancillary.append(("smry", smry_payload(0, 12, [(2, 1.0, 1e300, [0, 12], means)])))
    data = overflows(d.build(), (0, 0), (1, 1))
    vs.valid("uncommon", _numbered(vs, "u", "smry-means-overflow-to-infinity"), data,
             "a smry level (k = 2, D = 12) whose step is 1e300 and two of whose quantised "
             "means are 2^31 - 1 and -(2^31 - 1): mean x step overflows to +inf and -inf in "
             "binary64, and the file is valid (the step is finite and > 0)",
             {"summary": "smry", "levels": [2]}, ["§1.3", "§4.10"],
             "hand-built from mpz.synth walk (frames=24, markers=4, seed=171)")
    # -- uncommon: smrc means that overflow to ±∞
    secs = ["§2.1", "§2.3", "§3.4", "§4.15", "§5.5"]
    good = _smrc_base()
    q = np.zeros((1, 12), np.int64)
    q[0, 0], q[0, 1] = 1 << 29, -(1 << 29)          # residuals below 2^30 (§5.4)
    body = _smrc_payload(0, 12, [(1, 1.0, 1e300, [0], q)], frames=24)
    data = overflows(_with_smrc(good, body), (0, 0), (0, 1))
    vs.valid("uncommon", _numbered(vs, "u", "smrc-means-overflow-to-infinity"), data,
             "an smrc level (k = 1, D = 12) whose step is 1e300 and two of whose quantised "
             "means are 2^29 and -2^29: mean x step overflows to +inf and -inf, and the file "
             "is valid (§4.15 step 6)", {"summary": "smrc", "levels": [1]}, secs,
             "make_vectors.summary_review_vectors: hand-made smrc in the v-smrc-positions "
             "file")

    # -- uncommon: an smrc, then a C3D archive, in a file marked 1.0
    old = _marked_1_0(good)
    vs.valid("uncommon", _numbered(vs, "u", "smrc-in-file-marked-1.0"), old,
             "an smrc in a file whose MHDR says version 1.0 (version_minor 0): an encoder "
             "should write 1.1, but a decoder accepts any minor version (§2.1) and checks the "
             "smrc as a 1.1 decoder all the same; a 1.0 decoder skips it",
             {"summary": "smrc", "levels": [2, 5]}, secs,
             "v-smrc-positions, MHDR version_minor 1 -> 0")
    c3d = _c3d_float_base()
    old = _marked_1_0(c3d)
    vs.valid("uncommon", _numbered(vs, "u", "c3d-archive-in-file-marked-1.0"), old,
             "the C3D archive of v-c3d-archive-float32 (chdr, cprm, cpnt, cana) in a file "
             "whose MHDR says version 1.0: a decoder accepts any minor version (§2.1) and a "
             "1.1 decoder checks and decodes the archive all the same; a 1.0 decoder skips it",
             {"c3d_archive": True}, ["§2.1", "§2.3", "§4.13", "§6.9"],
             "v-c3d-archive-float32, MHDR version_minor 1 -> 0")
    # -- invalid: an smrc of D = 0 whose step is 0
    body = _smrc_payload(1, 0, [(1, 0.0, 0.0, [0], np.zeros((1, 0)))], frames=24)
    vs.invalid(_numbered(vs, "x", "smrc-angles-no-dims-step-zero"), _with_smrc(good, body),
               "an smrc with space 1 and D = 0 (no means) whose one level has step 0",
               "smrc space 1, D = 0, one level k = 1, step 0.0",
               "a decoder that skips the step of a level without means accepts a step §4.15 "
               "rejects (finite and > 0, as for smry: x155)", "FormatError", ["§4.10", "§4.15"])


def encoder_review_inputs(vs: VectorSet):
    """What an outside encoder implementer's QA of stop 71 found no input for: samples with
    only some coordinates NaN, which §7.2 and §7.3 call gaps (an encoder that took only
    all-NaN samples for gaps passed every input), and a name in NFD beside its NFC twin's
    letters, which an encoder must keep as it is (one that normalised names passed). A
    builder of its own, last, so that the inputs before it keep their names."""
    m = _synth("walk", 30, markers=5, seed=711, gap_fraction=0.0)
    x = np.array(m.positions, dtype=np.float64)
    rng = np.random.default_rng(711)
    for t, j, a in zip(rng.integers(0, 30, 12), rng.integers(0, 5, 12), rng.integers(0, 3, 12),
                       strict=True):
        x[t, j, a] = np.nan                    # one coordinate: the sample is a gap
    x[5:9, 2, :] = np.nan                      # whole samples too
    valid = np.asarray(~np.isnan(x).any(axis=2), dtype=bool)
    assert (np.isnan(x).sum(axis=2) == 1).any() and not valid.all()
    names = ["Kn\u00e9e", "Kne\u0301e", "C7", "Ellbogen links", "\u00c5ngstr\u00f6m"]
    assert names[0] != names[1]                # NFC and NFD of one word: two names
    motion = mpz.Motion(np.where(valid[..., None], x, 0.0), names, m.rate, "mm", valid)
    vs.encoder_input("e06-partial-gaps-nfd-names", motion, [1.0],
                     "5 markers, 30 frames, mm: 12 samples with one coordinate NaN (gaps, as "
                     "any NaN makes one), a marker 4 frames a gap, and names in NFC (Kn\u00e9e) "
                     "and NFD (Kne + U+0301 + e) that must be kept as they are", positions=x)


#: the §7.4 rules the vectors of :func:`summary_review_vectors` probe
SUMMARY_REVIEW_VECTOR_RULES = _rules(
    ("R-4.10-2", "smry-means-overflow-to-infinity"),
    ("R-4.15-7", "smrc-means-overflow-to-infinity smrc-in-file-marked-1.0"),
    ("R-4.13-6", "c3d-archive-in-file-marked-1.0"),
    ("R-4.15-2", "smrc-angles-no-dims-step-zero"),
    ("R-7.2-1 R-7.2-2 R-7.3-1", "partial-gaps-nfd-names"),
)
VECTOR_RULES.update(SUMMARY_REVIEW_VECTOR_RULES)


# ---------------------------------------- §6.9 "Writing a C3D": the writer's branches --
def _c3d_refused_features(data, refusal: str) -> dict:
    """The features of a valid archive that spec §6.9's writer refuses (§7.3): the archive's
    digest and counts, ``c3d_file_sha256`` null, and ``c3d_file_refused``, which of §6.9's
    three refusals it is (the reference's message checked to be that one)."""
    from mpz.errors import InputFormatError
    from mpz.io.c3d import archive_bytes
    m = mpz.decode(data)
    try:
        archive_bytes(m)
    except InputFormatError as exc:
        said = str(exc)
    else:
        raise AssertionError(f"the C3D writer wrote an archive it must refuse ({refusal})")
    words = {"coordinate": "does not fit a float32 C3D", "section": "the parameter section needs",
             "offset": "needs a next-record offset of"}
    assert words[refusal] in said, said
    out = _c3d_archive_features(m)
    out["c3d_file_sha256"] = None
    out["c3d_file_refused"] = {
        "coordinate": "a coordinate beyond binary32 (§6.9 Storage)",
        "section": "a parameter section of more than 255 blocks (§6.9 Parameter section)",
        "offset": "a next-record offset beyond 65535 (§6.9 Parameter section)"}[refusal]
    return out


@functools.cache
def _c3d_writer_base(storage: int, scale: float = 0.5) -> bytes:
    """A small C3D archive (6 frames, 3 markers, 1 model output, 2 analog channels of 2
    samples) that :func:`c3d_writer_vectors` edits: float32 (encoded within 1.0) or int16
    (exact on the grid of POINT:SCALE ``scale``)."""
    import dataclasses

    from mpz.io.c3dbin import ParamRecord as R
    m = c3d_motion(77 + storage, storage=storage, F=6, M=3, J=1, C=2, n=2, scale=scale)
    a = m.extras["c3d"]
    recs = list(a.records)
    at = next(i for i, r in enumerate(recs) if r.group == 2 and r.name == b"GAIN") + 1
    # the ANALOG parameters ezc3d 1.7 needs to read the file back without crashing
    recs[at:at] = [R(2, False, b"LABELS", b"", -1, (3, 2), b"A1 A2 "),
                   R(2, False, b"SCALE", b"", 4, (2,), struct.pack("<2f", 1.0, 1.0)),
                   R(2, False, b"OFFSET", b"", 2, (2,), struct.pack("<2h", 0, 0)),
                   R(2, False, b"GEN_SCALE", b"", 4, (), struct.pack("<f", 1.0)),
                   R(2, False, b"UNITS", b"", -1, (1, 2), b"VV")]
    m.extras["c3d"] = dataclasses.replace(a, records=recs)
    if storage == 1:
        return encode_within(m, max_error=1.0)
    return mpz.encode(m)


def _cprm_edited(data, edit):
    """``data`` with its cprm records replaced by ``edit(records)`` (a list of Param), its
    coding kept (DEFLATE is rebuilt by the reference's deflate)."""
    from mpz.chunks import Cprm
    prm = Cprm.load(next(p for t, p in _c3d_chunks(data) if t == "cprm"))
    recs = tuple(edit(list(prm.records)))
    return _c3d_rebuild(data, "cprm", count=len(recs), records=recs)


def _chdr_edited(data, **fields):
    """``data`` with header fields changed: ``scale`` (words 7-8, binary32), ``last``
    (word 5, u16)."""
    from mpz.chunks import Chdr
    blk = bytearray(Chdr.load(next(p for t, p in _c3d_chunks(data) if t == "chdr")).block)
    if "scale" in fields:
        struct.pack_into("<f", blk, 12, fields["scale"])
    if "last" in fields:
        struct.pack_into("<H", blk, 8, fields["last"])
    return _c3d_rebuild(data, "chdr", block=bytes(blk))


def _param_at(recs, group_name: bytes, name: bytes) -> int:
    """The index of the parameter ``name`` (exact bytes) of the group named ``group_name``."""
    gid = next(-r.group for r in recs if r.group < 0 and r.name == group_name)
    return next(i for i, r in enumerate(recs) if r.group == gid and r.name == name)


def _dec_floats(raw: bytes) -> bytes:
    """Little-endian binary32 values as DEC (VAX F) floats: the binary32 bits of 4 x the
    value (VAX exponent = binary32 exponent + 2), their two 16-bit words swapped. Only
    values a DEC float holds the same (+0.0, and 2^-126 <= |v| < 2^126) are taken."""
    v = np.frombuffer(raw, "<f4")
    a = np.abs(v.astype(np.float64))
    held = ((v == 0) & ~np.signbit(v)) | ((a >= 2.0 ** -126) & (a < 2.0 ** 126))
    assert held.all(), f"no DEC float holds {v[~held]}"
    return (v * np.float32(4.0)).astype("<f4").view(np.uint8).reshape(-1, 4)[
        :, [2, 3, 0, 1]].tobytes()


def _c3d_in_processor(blob: bytes, processor: int) -> bytes:
    """The Intel C3D ``blob`` (as spec §6.9 writes it) in the form of a DEC (85) or MIPS
    (86) source, as the C3D user guide lays it out: the processor byte of the parameter
    section, every int16 (header words, int16 parameters, int16 data) and the next-record
    offsets big-endian for MIPS, every float (header words 7-8, 11-12 and 153-188, float32
    parameters, float data) a DEC float or big-endian; chars, bytes and header bytes 0-1,
    words 189-197 and 199-234 as they are (the words spec §4.13.1 keeps as stored)."""
    big = processor == 86

    def f32(raw: bytes) -> bytes:
        return _dec_floats(raw) if processor == 85 else \
            np.frombuffer(raw, "<f4").astype(">f4").tobytes()

    def i16(raw: bytes) -> bytes:
        return np.frombuffer(raw, "<i2").astype(">i2").tobytes() if big else raw

    out = bytearray(blob)
    floats, kept = {7, 11, *range(153, 189, 2)}, {1, *range(189, 198), *range(199, 235)}
    word = 1
    while word <= 256:
        at = 2 * (word - 1)
        if word in floats:
            out[at:at + 4] = f32(blob[at:at + 4])
            word += 2
            continue
        if word not in kept:
            out[at:at + 2] = i16(blob[at:at + 2])
        word += 1
    pos = 512 * (blob[0] - 1)
    out[pos + 3] = processor
    pos += 4
    while True:                                    # the records, by their offsets
        n, gid = abs(struct.unpack_from("<b", blob, pos)[0]), struct.unpack_from("<b", blob,
                                                                                pos + 1)[0]
        at = pos + 2 + n
        nxt = struct.unpack_from("<H", blob, at)[0]
        struct.pack_into(">H" if big else "<H", out, at, nxt)
        if gid > 0:
            t, D = struct.unpack_from("<bB", blob, at + 2)
            d0 = at + 4 + D
            size = abs(t) * math.prod(blob[at + 4:d0])
            if t in (2, 4):
                out[d0:d0 + size] = (i16 if t == 2 else f32)(blob[d0:d0 + size])
        if nxt == 0:
            break
        pos = at + nxt
    start = 512 * (struct.unpack_from("<H", blob, 16)[0] - 1)
    words = f32 if struct.unpack_from("<f", blob, 12)[0] < 0 else i16
    out[start:] = words(blob[start:])
    return bytes(out)


@functools.cache
def _c3d_source_vector(storage: int, processor: int) -> bytes:
    """The MPZ file the reference encoder makes of the C3D of :func:`_c3d_writer_base`
    (``storage``) written in the form of ``processor`` (:func:`_c3d_in_processor`) and
    read by mpz's C3D reader (:mod:`mpz.io.c3dbin`, not ezc3d: the same on every machine),
    encoded as the base is. Checked to be the file made of the Intel C3D read the same way
    but for chdr.processor and the metadata's ``processor``: the chunks hold normalised
    values (§4.13), whatever the source's processor."""
    from mpz.container import scan
    from mpz.io import c3dbin
    from mpz.io.c3d import archive_bytes, motion_from_c3d_bytes, split_archive

    def encoded(blob: bytes) -> bytes:
        m = split_archive(motion_from_c3d_bytes(blob, source="synthetic.c3d"),
                          c3dbin.parse_c3d(blob))
        return mpz.encode(m) if storage == 0 else encode_within(m, max_error=1.0)

    intel = archive_bytes(mpz.decode(_c3d_writer_base(storage)))
    data, same = encoded(_c3d_in_processor(intel, processor)), encoded(intel)
    a, b = scan(data).chunks, scan(same).chunks
    assert [c.type for c in a] == [c.type for c in b]
    differ = [c.type for c, d in zip(a, b, strict=True) if c.payload != d.payload]
    assert differ == ["meta", "chdr"], differ
    chdr = next(c.payload for c in a if c.type == "chdr")
    assert chdr[0] == processor and chdr[1:] == next(c.payload for c in b
                                                      if c.type == "chdr")[1:]
    got, want = mpz.decode(data).metadata, mpz.decode(same).metadata
    assert got.pop("processor") == {85: "dec", 86: "mips"}[processor]
    assert want.pop("processor") == "intel" and got == want
    return data


def c3d_writer_vectors(vs: VectorSet):
    """Uncommon vectors for the branches of spec §6.9's C3D writer ("Writing a C3D") that
    no vector reached (the writer run under coverage on every C3D vector of stop 71): the
    scale read from the header, a POINT:SCALE of 0, -inf, NaN or several elements, int16
    points written float32, ANALOG:FORMAT UNSIGNED, a parameter section of several blocks,
    next-record offsets past 32767 and in a last record past 65535, a last frame of 65535,
    group names compared as ASCII without case, and the writer's three refusals (an archive
    it refuses is valid: ``c3d_file_sha256`` null, ``c3d_file_refused`` says which). Stop
    73 added a DEC and a MIPS source, a POINT group record after its parameters and an
    archive that meets the three refusals at once (the first in §6.9's order is reported).
    Each edits a small archive of :func:`_c3d_writer_base`. A builder of its own, last, so
    that the vectors before it keep their numbers."""
    import dataclasses

    from mpz.chunks import Cpnt, Cprm
    from mpz.chunks.c3d import Param
    secs = ["§2.1", "§2.3", "§4.13", "§4.13.1", "§4.13.2", "§6.9"]
    f32 = _c3d_writer_base(1)
    i16 = _c3d_writer_base(0)
    # the markers off the grid: QUNT's x offset 0 -> 0.125 (the reference encoder codes an
    # int16 source on its grid whatever the bound, Appendix C item 9)
    off = _c3d_rebuild(i16, "QUNT", offset=(0.125, 0.0, 0.0))
    i16_1 = _c3d_writer_base(0, 1.0)
    src = "make_vectors._c3d_writer_base"

    def add(slug, data, description, provenance, refused=None):
        feats = (_c3d_features(data) if refused is None
                 else _c3d_refused_features(data, refused))
        vs.valid("uncommon", _numbered(vs, "u", slug), data, description, feats, secs,
                 f"{src}{provenance}")

    def par(group, name, ptype, dims, value, description=b""):
        return Param(group=group, locked=0, name=name, description=description, type=ptype,
                     dims=bytes(dims), data=value)

    def scale_set(recs, *values, group=b"POINT"):
        i = _param_at(recs, group, b"SCALE")
        dims = (len(values),) if len(values) != 1 else ()
        recs[i] = dataclasses.replace(recs[i], dims=bytes(dims),
                                      data=struct.pack(f"<{len(values)}f", *values))
        return recs

    # -- the parameter section: 2 blocks, POINT:DATA_START of two elements
    def two_blocks(recs):
        i = _param_at(recs, b"POINT", b"DATA_START")
        recs[i] = dataclasses.replace(recs[i], dims=b"\x02", data=struct.pack("<2h", 11, 7))
        note = b"".join(f"note {k:02d}: walking trial, synthetic ".ljust(60).encode()
                        for k in range(8))
        recs.insert(i + 1, par(1, b"NOTES", -1, (60, 8), note, b"480 bytes of text"))
        return recs
    add("c3d-parameter-section-of-2-blocks", _cprm_edited(f32, two_blocks),
        "a C3D archive whose parameter section takes 2 blocks (B = 2: a 480-byte POINT:NOTES) "
        "and whose POINT:DATA_START has two elements, 11 and 7: the writer puts the data at "
        "block 4 (word 9 and the first element 4, the second kept 7)",
        "(1): POINT:DATA_START -> [11, 7], POINT:NOTES (char 60 x 8) inserted")

    # -- the scale: from header words 7-8
    def no_scale(recs):
        del recs[_param_at(recs, b"POINT", b"SCALE")]
        return recs
    add("c3d-no-point-scale", _chdr_edited(_cprm_edited(i16, no_scale), scale=-0.5),
        "an int16 C3D archive without POINT:SCALE and header words 7-8 -0.5: s = 0.5 comes "
        "from the header, the points are on its grid, so the file is int16 with words 7-8 "
        "+0.5",
        "(0): POINT:SCALE removed, chdr words 7-8 -> -0.5")

    def scale_int16_first(recs):
        i = _param_at(recs, b"POINT", b"SCALE")
        recs[i] = dataclasses.replace(recs[i], type=2, data=struct.pack("<h", 3))
        recs.insert(i + 1, par(1, b"SCALE", 4, (2,), struct.pack("<2f", 0.25, -0.125),
                               b"a second SCALE"))
        return recs
    add("c3d-point-scale-int16-then-float32", _cprm_edited(i16, scale_int16_first),
        "an int16 C3D archive whose first POINT:SCALE is an int16 (3) and a second one a "
        "float32 [0.25, -0.125]: s = 0.5 from header words 7-8 (a later SCALE is not looked "
        "at, so its elements of two magnitudes do not make the file float32); the int16 "
        "SCALE is written as stored, the float32 one as [0.5, 0.125]",
        "(0): POINT:SCALE -> int16 3, a float32 POINT:SCALE [0.25, -0.125] after it")

    def scale_empty(recs):
        i = _param_at(recs, b"POINT", b"SCALE")
        recs[i] = dataclasses.replace(recs[i], dims=b"\x00", data=b"")
        return recs
    add("c3d-point-scale-no-element", _chdr_edited(_cprm_edited(f32, scale_empty), scale=-0.75),
        "a float32 C3D archive whose POINT:SCALE is a float32 of dims (0) (no element) and "
        "header words 7-8 -0.75: s = 0.75 from the header, words 7-8 written -0.75, "
        "POINT:SCALE written as stored",
        "(1): POINT:SCALE dims (0), no data; chdr words 7-8 -> -0.75")

    # -- the scale: s = 1
    add("c3d-point-scale-zero", _cprm_edited(i16_1, lambda r: scale_set(r, 0.0)),
        "an int16 C3D archive on the grid 1 whose POINT:SCALE is 0.0: s = 1, the file is "
        "int16 with words 7-8 +1.0 and POINT:SCALE written 1.0",
        "(0, 1.0): POINT:SCALE -> 0.0")
    add("c3d-point-scale-minus-infinity",
        _cprm_edited(i16_1, lambda r: scale_set(r, -math.inf)),
        "an int16 C3D archive on the grid 1 whose POINT:SCALE is -inf: s = 1, the file is "
        "int16 with words 7-8 +1.0 and POINT:SCALE written 1.0",
        "(0, 1.0): POINT:SCALE -> -inf")

    # -- the scale: several elements
    nan = struct.unpack("<f", struct.pack("<I", 0xFFC01234))[0]

    def scale_nan(recs):
        i = _param_at(recs, b"POINT", b"SCALE")
        recs[i] = dataclasses.replace(recs[i], dims=b"\x04", data=struct.pack(
            "<fIff", 0.5, 0x7FC01234, -0.5, 0.5))
        return recs
    assert nan != nan
    add("c3d-point-scale-nan-element", _cprm_edited(i16, scale_nan),
        "an int16 C3D archive on the grid 0.5 whose POINT:SCALE is [0.5, NaN (0x7FC01234), "
        "-0.5, 0.5]: a NaN equals nothing, so the file is float32 (words 7-8 -0.5, the int16 "
        "point and analog words as binary32 of the same value, negative analog words "
        "negative) and POINT:SCALE is written [-0.5, NaN 0xFFC01234 (payload kept, sign "
        "set), -0.5, -0.5]",
        "(0): POINT:SCALE -> 4 elements, one a NaN")
    add("c3d-point-scale-magnitudes-differ",
        _cprm_edited(i16, lambda r: scale_set(r, 0.5, 0.25, -0.5, 0.5)),
        "an int16 C3D archive on the grid 0.5 whose POINT:SCALE is [0.5, 0.25, -0.5, 0.5]: "
        "elements of two magnitudes make the file float32, POINT:SCALE written [-0.5, -0.25, "
        "-0.5, -0.5]", "(0): POINT:SCALE -> [0.5, 0.25, -0.5, 0.5]")
    add("c3d-point-scale-signs-differ-int16",
        _cprm_edited(i16, lambda r: scale_set(r, -0.5, 0.5, -0.5, -0.5)),
        "an int16 C3D archive on the grid 0.5 whose POINT:SCALE is [-0.5, 0.5, -0.5, -0.5]: "
        "one magnitude, so int16; words 7-8 +0.5, POINT:SCALE written [0.5, 0.5, 0.5, 0.5]",
        "(0): POINT:SCALE -> [-0.5, 0.5, -0.5, -0.5]")

    # -- int16 source written float32: off the grid, beyond 32767
    m = mpz.decode(off)
    assert not np.array_equal(np.rint(m.positions[m.valid] / 0.5) * 0.5, m.positions[m.valid])
    add("c3d-int16-off-grid-written-float32", off,
        "an int16 C3D archive (POINT:SCALE 0.5) whose QUNT x offset is 0.125, so its decoded "
        "markers are off the grid: the file is float32 (words 7-8 -0.5, POINT:SCALE -0.5), "
        "the int16 point and analog words written as binary32 of the same value",
        "(0): QUNT offset x 0 -> 0.125")
    pnt = Cpnt.load(next(p for t, p in _c3d_chunks(i16) if t == "cpnt"))
    ax = pnt.models[0].axes[1]
    far = _c3d_rebuild(i16, "cpnt", models=_axis_changed(pnt.models, offset=ax.offset + 16384))
    a = mpz.decode(far).extras["c3d"]
    y = a.models[:, 0, 1][a.model_valid[:, 0]]
    assert np.array_equal(np.rint(y / 0.5) * 0.5, y) and (y / 0.5 > 32767).any()
    add("c3d-int16-on-grid-beyond-32767", far,
        "an int16 C3D archive on the grid 0.5 whose model output 0 has y values 16384 higher "
        "(cpnt offset + 16384): on the grid, but q = x / s passes 32767, so the file is "
        "float32", "(0): cpnt model 0 axis y offset + 16384")

    # -- ANALOG:FORMAT UNSIGNED
    def unsigned(recs):
        i = next(k for k, r in enumerate(recs) if r.group == -2)
        recs[i] = dataclasses.replace(recs[i], name=b"analog")
        j = _param_at(recs, b"analog", b"GAIN")
        recs.insert(j + 1, par(2, b"Format", -1, (12,), b" unsigned\x00\x00 "))
        recs.insert(j + 2, par(2, b"FORMAT", -1, (6,), b"SIGNED", b"not looked at"))
        return recs
    add("c3d-analog-format-unsigned", _cprm_edited(off, unsigned),
        "the float32-written int16 archive of c3d-int16-off-grid-written-float32 with the "
        "group ANALOG named analog, whose first FORMAT (named Format) is ' unsigned' with "
        "U+0000 and U+0020 around it, and a later FORMAT SIGNED (not looked at): every "
        "negative int16 analog word v is written as the binary32 of v + 65536",
        "(0), QUNT offset x 0.125: ANALOG -> analog, Format ' unsigned\\0\\0 ', FORMAT 'SIGNED'")

    def signed_first(recs):
        j = _param_at(recs, b"ANALOG", b"GAIN")
        recs.insert(j + 1, par(2, b"FORMAT", 1, (8,), b"UNSIGNED", b"a byte array"))
        recs.insert(j + 2, par(2, b"FORMAT", -1, (8,), b"UNSIGNED", b"not looked at"))
        return recs
    add("c3d-analog-format-unsigned-not-first", _cprm_edited(off, signed_first),
        "the archive of c3d-int16-off-grid-written-float32 whose first ANALOG:FORMAT is a "
        "byte array (type 1) spelling UNSIGNED and a later one the char UNSIGNED: only the "
        "first is looked at, and it is not char, so the analog words are written signed",
        "(0), QUNT offset x 0.125: ANALOG:FORMAT byte 'UNSIGNED', then char 'UNSIGNED'")

    # -- a last frame of 65535: no padding
    add("c3d-last-frame-65535", _chdr_edited(f32, last=65535),
        "a float32 C3D archive whose header word 5 (last frame) is 65535 (bytes FF FF): the "
        "writer ends the file at the last frame, without padding its last block",
        "(1): chdr word 5 -> 65535")

    # -- names compared as ASCII without case
    def lower(recs):
        i = next(k for k, r in enumerate(recs) if r.name == b"POINT" and r.group < 0)
        recs[i] = dataclasses.replace(recs[i], name=b"point")
        for nm, new in ((b"SCALE", b"Scale"), (b"DATA_START", b"data_start")):
            j = _param_at(recs, b"point", nm)
            recs[j] = dataclasses.replace(recs[j], name=new)
        return recs
    add("c3d-group-point-lowercase", _cprm_edited(f32, lower),
        "a float32 C3D archive whose group POINT is named point and its SCALE and DATA_START "
        "Scale and data_start: names compared as ASCII without case, so both are set as for "
        "POINT (-0.5, 3)", "(1): POINT -> point, SCALE -> Scale, DATA_START -> data_start")

    def spaced(recs):
        i = next(k for k, r in enumerate(recs) if r.name == b"POINT" and r.group < 0)
        recs[i] = dataclasses.replace(recs[i], name=b"POINT ")
        return scale_set(recs, 0.25, 1.0, group=b"POINT ")
    add("c3d-group-point-trailing-space", _cprm_edited(i16, spaced),
        "an int16 C3D archive whose group POINT is named 'POINT ' (a trailing U+0020), which "
        "is not POINT: its SCALE [0.25, 1.0] is not read (s = 0.5 from header words 7-8, the "
        "file int16) and, with its DATA_START (11), written as stored",
        "(0): POINT -> 'POINT ', its SCALE -> [0.25, 1.0]")

    # -- next-record offsets past 32767, and a last record past 65535
    def long_record(recs):
        j = _param_at(recs, b"POINT", b"LABELS")
        recs.insert(j + 1, par(1, b"LONG", -1, (250, 132), b"." * 33000, b"33000 bytes"))
        return recs
    add("c3d-next-record-offset-above-32767", _cprm_edited(f32, long_record),
        "a float32 C3D archive with a POINT:LONG of 33000 bytes (not the last record): its "
        "next-record offset, 33018, is written unsigned (above 32767, where readers that take "
        "it signed fail); B = 66", "(1): POINT:LONG (char 250 x 132) inserted")

    def last_record(recs):
        return [*recs, par(9, b"LAST", -1, (255, 2, 129), b"-" * 65790, b"the last record")]
    add("c3d-last-record-above-65535", _cprm_edited(f32, last_record),
        "a float32 C3D archive whose last parameter record holds 65790 bytes of data: in the "
        "last record the next-record offset is 0, whatever its size, so it is written (B = "
        "129)", "(1): a last record of 65790 bytes appended")

    # -- the writer's refusals: the MPZ files are valid
    big = _c3d_rebuild(f32, "cpnt", models=_axis_changed(
        Cpnt.load(next(p for t, p in _c3d_chunks(f32) if t == "cpnt")).models, offset=1e39))
    add("c3d-writer-refuses-coordinate-beyond-float32", big,
        "a float32 C3D archive whose model output 0 has y values about 1e39 (cpnt offset "
        "1e39, valid by §4.13.3): the writer refuses it (a coordinate beyond binary32); "
        "c3d_file_sha256 is null", "(1): cpnt model 0 axis y offset -> 1e39",
        refused="coordinate")

    def section_256(recs):
        # C3D records are 1 byte longer than cprm's (a 2-byte offset for the locked byte),
        # the section's head 2 bytes longer than cprm's count: a content of 130,646 to
        # 130,900 bytes (at most 2^17, §8) gives a section of 130,648 + R bytes at least,
        # more than 255 x 512
        have = len(Cprm(coding=0, count=len(recs), records=tuple(recs)).content())
        extra = [par(9, f"FILL{k}".encode(), -1, (255, 171), b"\x00" * 43605) for k in range(2)]
        rest = 130900 - have - 2 * 43617 - 12           # 12: a FILL record's other bytes
        extra.append(par(9, b"FILL2", -1, (rest // 255, 255), b"\x00" * (rest // 255 * 255)))
        out = [*recs, *extra]
        n = len(Cprm(coding=0, count=len(out), records=tuple(out)).content())
        assert n <= 1 << 17 and n + 2 + len(out) > 255 * 512, n
        return out
    add("c3d-writer-refuses-section-of-256-blocks", _cprm_edited(f32, section_256),
        "a float32 C3D archive with three more parameters of 43605 bytes: the cprm content "
        "(under 2^17 bytes) is valid, but its C3D section needs 256 blocks, which the writer "
        "refuses; c3d_file_sha256 is null", "(1): three char records 255 x 171 appended",
        refused="section")

    def offset_65536(recs):
        j = _param_at(recs, b"POINT", b"LABELS")
        recs.insert(j + 1, par(1, b"HUGE", -1, (255, 2, 129), b"\x00" * 65790))
        return recs
    add("c3d-writer-refuses-next-record-offset-65536", _cprm_edited(f32, offset_65536),
        "a float32 C3D archive with a POINT:HUGE of 65790 bytes that is not the last record: "
        "its next-record offset would be 65798, beyond 65535, which the writer refuses; "
        "c3d_file_sha256 is null", "(1): POINT:HUGE (char 255 x 2 x 129) inserted",
        refused="offset")

    # -- a review from the text alone (stop 72): Storage compares the magnitudes also when
    # the first element is 0 (s = 1), which no vector told apart from skipping the test
    add("c3d-point-scale-zero-then-other-magnitude",
        _cprm_edited(i16_1, lambda r: scale_set(r, 0.0, 0.5)),
        "an int16 C3D archive on the grid 1 whose POINT:SCALE is [0.0, 0.5]: s = 1, and the "
        "elements' magnitudes differ (the comparison is made also when the first is 0), so "
        "the file is float32, words 7-8 -1.0 and POINT:SCALE written [-1.0, -0.5]",
        "(0, 1.0): POINT:SCALE -> [0.0, 0.5]")
    # ... and two more points of its list that the text states and no vector probed: s = 1
    # for header words 7-8 of 0 without POINT:SCALE, and the refusal of |x| above binary32's
    # largest value even where x rounds to that value (not only where rounding overflows)
    add("c3d-no-point-scale-header-scale-zero",
        _chdr_edited(_cprm_edited(i16_1, no_scale), scale=0.0),
        "an int16 C3D archive on the grid 1 without POINT:SCALE and header words 7-8 0.0: "
        "s = 1 (v = 0 from the header), the file is int16 with words 7-8 +1.0",
        "(0, 1.0): POINT:SCALE removed, chdr words 7-8 -> 0.0")
    just_over = 3.4028234663852886e38 + 2.0 ** 80      # binary64; binary32 rounds it down
    add("c3d-writer-refuses-coordinate-just-beyond-float32",
        _c3d_rebuild(f32, "cpnt", models=_axis_changed(
            Cpnt.load(next(p for t, p in _c3d_chunks(f32) if t == "cpnt")).models,
            offset=just_over)),
        "a float32 C3D archive whose model output 0 has y values just above the largest "
        "binary32 (cpnt offset 3.4028234663852886e38 + 2^80): their nearest binary32 is that "
        "largest value, yet |x| > 3.4028234663852886e38, so the writer refuses it; "
        "c3d_file_sha256 is null", "(1): cpnt model 0 axis y offset -> 2^128 - 2^104 + 2^80",
        refused="coordinate")

    # -- stop 73: a DEC and a MIPS source (chdr.processor 85, 86; every C3D vector had 84),
    # each the C3D of a base written in that processor's form and read by mpz's C3D reader
    from mpz.io.c3d import archive_bytes
    dec = _c3d_source_vector(0, 85)
    assert archive_bytes(mpz.decode(dec)) == archive_bytes(mpz.decode(i16))
    add("c3d-dec-source-processor-85", dec,
        "the int16 C3D of c3d_writer_base(0) written as a DEC source (processor 85: header "
        "words 7-8, 11-12 and 153-188 and the float32 parameters as DEC floats), read by "
        "mpz's C3D reader and encoded: chdr.processor is 85 and the chunks hold the "
        "normalised little-endian values, the same as for the Intel source but for "
        "chdr.processor and meta's processor. A decoder accepts processor 85; the writer "
        "writes processor 84 and Intel byte order whatever chdr says: the Intel C3D the DEC "
        "one was made from, byte for byte",
        "(0) written by spec §6.9 then as DEC (processor 85), read by mpz.io.c3dbin, encoded "
        "(make_vectors._c3d_source_vector)")
    add("c3d-mips-source-processor-86", _c3d_source_vector(1, 86),
        "the float32 C3D of c3d_writer_base(1) written as a MIPS source (processor 86: every "
        "int16, float and next-record offset big-endian), read by mpz's C3D reader and "
        "encoded within 1.0: chdr.processor is 86 and the chunks hold the normalised "
        "little-endian values (NaN, infinities and -0.0 among the analog words bit for bit), "
        "the same as for the Intel source but for chdr.processor and meta's processor. A "
        "decoder accepts processor 86; the writer writes processor 84 and Intel byte order "
        "whatever chdr says",
        "(1) written by spec §6.9 then as MIPS (processor 86), read by mpz.io.c3dbin, "
        "encoded within 1.0 (make_vectors._c3d_source_vector)")

    # -- a POINT group record after its parameters (the C3D user guide allows any order):
    # Scale's and DATA_START's "any group record named POINT" is not the record before
    def point_group_after(recs):
        g = recs.pop(next(k for k, r in enumerate(recs) if r.group < 0 and r.name == b"POINT"))
        recs.insert(max(k for k, r in enumerate(recs) if r.group == -g.group) + 1, g)
        return recs
    after = _chdr_edited(_cprm_edited(i16, point_group_after), scale=1.0)
    m = mpz.decode(after)
    assert (np.rint(m.positions[m.valid]) != m.positions[m.valid]).any()   # off the grid 1
    add("c3d-point-group-record-after-its-parameters", after,
        "an int16 C3D archive on the grid 0.5 whose POINT group record comes after its "
        "parameters (the last of them, POINT:POWERS, before it; the C3D user guide allows "
        "records in any order) and whose header words 7-8 are 1.0: POINT:SCALE (0.5) is "
        "read all the same, so the file is int16 with words 7-8 +0.5, POINT:SCALE written "
        "0.5 and POINT:DATA_START 3 (a writer that knew only the groups before a record "
        "would take s = 1 from the header, and the points off that grid would make the file "
        "float32 with POINT:DATA_START 11)",
        "(0): the POINT group record moved after POINT:POWERS, chdr words 7-8 -> 1.0")

    # -- the three refusals at once: the writer reports the first in §6.9's order
    def three_refusals(recs):
        recs = offset_65536(recs)
        have = len(Cprm(coding=0, count=len(recs), records=tuple(recs)).content())
        k = (130900 - have - 13) // 255                 # 13: the FILL record's other bytes
        assert k == 253, k                              # as the description says
        out = [*recs, par(9, b"FILL0", -1, (255, k), b"\x00" * (255 * k))]
        n = len(Cprm(coding=0, count=len(out), records=tuple(out)).content())
        assert n <= 1 << 17 and -(-(n + 2 + len(out)) // 512) == 256, n
        return out
    add("c3d-writer-refuses-next-record-offset-first-of-three",
        _c3d_rebuild(_cprm_edited(f32, three_refusals), "cpnt", models=_axis_changed(
            Cpnt.load(next(p for t, p in _c3d_chunks(f32) if t == "cpnt")).models,
            offset=1e39)),
        "a float32 C3D archive that meets all three of the writer's refusals: a POINT:HUGE "
        "of 65790 bytes that is not the last record (a next-record offset of 65798), a "
        "parameter section of 256 blocks (a last record of 64515 bytes) and model output "
        "0's y values about 1e39 (cpnt offset 1e39). The writer reports the first in §6.9's "
        "order, the next-record offset (then the section's blocks, then a coordinate); "
        "c3d_file_sha256 is null",
        "(1): POINT:HUGE (char 255 x 2 x 129) inserted, FILL0 (char 255 x 253) appended, "
        "cpnt model 0 axis y offset -> 1e39", refused="offset")


_WRITER_SLUGS = (
    "c3d-parameter-section-of-2-blocks c3d-no-point-scale c3d-point-scale-int16-then-float32 "
    "c3d-point-scale-no-element c3d-point-scale-zero c3d-point-scale-minus-infinity "
    "c3d-point-scale-nan-element c3d-point-scale-magnitudes-differ "
    "c3d-point-scale-signs-differ-int16 c3d-int16-off-grid-written-float32 "
    "c3d-int16-on-grid-beyond-32767 c3d-analog-format-unsigned "
    "c3d-analog-format-unsigned-not-first c3d-last-frame-65535 c3d-group-point-lowercase "
    "c3d-group-point-trailing-space c3d-next-record-offset-above-32767 "
    "c3d-last-record-above-65535 c3d-point-scale-zero-then-other-magnitude "
    "c3d-no-point-scale-header-scale-zero c3d-dec-source-processor-85 "
    "c3d-mips-source-processor-86 c3d-point-group-record-after-its-parameters")
_REFUSED_SLUGS = ("c3d-writer-refuses-coordinate-beyond-float32 "
                  "c3d-writer-refuses-coordinate-just-beyond-float32 "
                  "c3d-writer-refuses-section-of-256-blocks "
                  "c3d-writer-refuses-next-record-offset-65536 "
                  "c3d-writer-refuses-next-record-offset-first-of-three")
#: the §7.4 rules the vectors of :func:`c3d_writer_vectors` probe: each one's written C3D
#: (R-6.9-3), or the writer's refusal of a valid file, which still decodes (R-6.9-2); a DEC
#: and a MIPS source, whose processor byte a decoder accepts (R-4.13.1-1)
C3D_WRITER_VECTOR_RULES = _rules(
    ("R-6.9-3", f"{_WRITER_SLUGS} {_REFUSED_SLUGS}"),
    ("R-6.9-2", _REFUSED_SLUGS),
    ("R-4.13.1-1", "c3d-dec-source-processor-85 c3d-mips-source-processor-86"),
)
_merge_rules(C3D_WRITER_VECTOR_RULES)


def order_review_vectors(vs: VectorSet):
    """What stop 74's decoder written in C from the spec alone found no vector for: a
    second MASK chunk (§3.4 allows MASK at most once; x94 tests a second QUNT, a chunk
    the order requires, but a decoder that loops over the optional MASK passed every
    vector), from the base file of :func:`invalid_vectors`. A builder of its own, last,
    so that the vectors before it keep their numbers."""
    d = base_design()
    d.build()
    ch = [list(c) for c in d.chunks()]
    i = _find(ch, "MASK")
    ch.insert(i + 1, list(ch[i]))
    vs.invalid(_numbered(vs, "x", "second-mask"), assemble(ch),
               "MASK twice in a row (§3.4: at most once)", "MASK repeated",
               "a decoder that reads MASK in a loop takes the last one silently",
               "FormatError", ["§3.4"])


#: the §7.4 rules the vectors of :func:`order_review_vectors` probe
_merge_rules(_rules(("R-3.4-3", "second-mask")))


BUILDERS = (
    valid_vectors,
    spec_example,
    invalid_vectors,
    uncommon_vectors,
    encoder_inputs,
    c3d_archive_vectors,                      # issue 12 (MPZ 1.1)
    skeleton_vectors,                         # issue 13 (MPZ 1.1)
    smrc_vectors,                             # issue 14.12 (MPZ 1.1)
    c3d_coding_vectors,                       # §4.13 byte coding (MPZ 1.1)
    clarified_accept_vectors,                 # §4.13.1, §4.14.2 text of stop 27
    smrc_wrap_vectors,                        # §4.15 lengths that wrap in 32 bits
    summary_edge_vectors,                     # §4.10, §4.15 rules isolated (stop 49)
    mutation_gap_vectors,                     # checks no vector isolated (mutation run)
    range_gap_vectors,                        # §4.13, §4.14 Range columns (audit)
    contract_gap_vectors,                     # rate, units, names kept (runner QA, stop 53)
    deflate_vectors,                          # §4.13 valid DEFLATE as zlib reads it (stop 70)
    settled_text_vectors,                     # §1, §4.13.2, §4.13.4, §4.14 text of stop 70
    unprobed_accept_vectors,                  # §1.3, §4.14 accept text no vector showed
    core_review_vectors,                      # §4.2, §6.8 (the reviews of stop 71)
    summary_review_vectors,                   # §2.1, §4.10, §4.15 (review of stop 71)
    encoder_review_inputs,                    # §7.2, §7.3 (encoder QA of stop 71)
    c3d_writer_vectors,                       # §6.9 the C3D writer's branches (stop 72)
    order_review_vectors,                     # §3.4 a second MASK (C decoder of stop 74)
)

#: the markers around the vector table of conformance/README.md (written by :func:`main`)
TABLE_BEGIN, TABLE_END = "<!-- mpz:vector-table -->", "<!-- /mpz:vector-table -->"


def vector_table(entries: list[dict]) -> str:
    """The README's table of the vectors, one row per manifest entry, in manifest order."""
    rows = ["| Vector | Bytes | Must | What it tests | Rules |", "|---|---|---|---|---|"]
    for e in entries:
        text = e["description"].replace("|", "\\|").replace("\n", " ")
        rows.append(f"| `{e['file']}` | {e['size']} | {e['expected']} | {text} | "
                    f"{' '.join(e.get('rules', []))} |")
    return "\n".join(rows)


def update_readme(readme: Path, entries: list[dict]) -> bool:
    """Rewrite the table between :data:`TABLE_BEGIN` and :data:`TABLE_END`; True if changed."""
    text = readme.read_text(encoding="utf-8")
    a, b = text.index(TABLE_BEGIN) + len(TABLE_BEGIN), text.index(TABLE_END)
    new = text[:a] + "\n" + vector_table(entries) + "\n" + text[b:]
    if new != text:
        readme.write_text(new, encoding="utf-8")
    return new != text


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m mpz.tools.make_vectors",
                                description=__doc__.splitlines()[0])
    p.add_argument("--out", default=str(mf.DEFAULT_DIR),
                   help="output directory (default: the package's conformance/vectors)")
    args = p.parse_args(argv)
    out = Path(args.out)
    from mpz.tools._common import is_clone
    default = Path(mf.DEFAULT_DIR)
    if out.resolve() == default.resolve() and not is_clone(default.resolve().parents[1]):
        p.error(f"{default} are the installed package's vectors, which mpz-conformance "
                "checks against: run this in a clone of the repository, or give --out")
    out.mkdir(parents=True, exist_ok=True)
    for g in ("valid", "uncommon", "invalid", "inputs"):
        d = out / g
        if d.is_dir():
            for f in d.iterdir():
                if f.is_file() and f.name != "spec-example.mpz":
                    f.unlink()
    vs = VectorSet(out)
    for build in BUILDERS:
        build(vs)
    vs.entries.sort(key=lambda e: (mf.GROUPS.index(e["group"]), e["name"]))
    vs.write_manifest()
    readme = out.parent / "README.md"
    if out.resolve() == Path(mf.DEFAULT_DIR).resolve() and readme.is_file():
        entries = json.loads((out / mf.MANIFEST_NAME).read_text())["vectors"]
        if update_readme(readme, entries):
            print(f"updated the vector table of {readme}")
    total = sum(f.stat().st_size for f in out.rglob("*") if f.is_file())
    print(f"wrote {len(vs.entries)} vectors and {len(vs.encoder_inputs)} encoder inputs to "
          f"{out} ({total} bytes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
