"""The MPZ reference encoder: the paper's pipeline, plus a hard error bound.

Strategy (reads as Fig. 2 of Gu, Peng & Deng):

1. hierarchy (§III-A) and ADDH, the head scale every threshold is relative to;
2. the quantisation grid (spec §4.4): with ``max_error=E`` the step is
   s = 2E/sqrt(3), so rounding each axis to the grid keeps the Euclidean
   error <= E; without it, a fine grid (ADDH / 1000);
3. the root marker as an absolute track (§III-D, spec §4.6);
4. node by node, parents first, in *closed loop* (each node is coded
   relative to the decoded, not the original, reference marker of its
   parent, so errors do not pile up down the tree):
   segmentation (Alg. 1, :mod:`mpz.segment`) -> normalisation
   (:mod:`mpz.normalize`) -> adaptive K-means (:mod:`mpz.cluster`) ->
   patterns quantised and coded as first frame + deltas (:mod:`mpz.entropy`)
   -> (pattern index, frame count) pairs -> the decoder's own
   de-normalisation and smoothing -> with a bound, the residual layer that
   restores every sample to within E (beyond the paper);
5. the validity mask, the optional Fisher summary, metadata, MEND.

The encoder never writes files; see :func:`mpz.write_mpz` for atomic output.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
import time

import numpy as np

from mpz import container, keyframe
from mpz.cluster import adaptive_kmeans
from mpz.decoder import FLAG_RESIDUAL, ROOT_PARENT, UNIT_FROM_NAME
from mpz.entropy import MAX_EXP, BlockEncoder
from mpz.errors import EncoderError
from mpz.motion import Motion
from mpz.normalize import denormalize, normalize, segment_starts
from mpz.predict import residuals
from mpz.quantize import choose_lattice
from mpz.segment import segment
from mpz.smooth import smooth_boundaries
from mpz.spec.grammar import SIGNATURE, VERSION_MAJOR, VERSION_MINOR

SQRT3 = math.sqrt(3.0)
#: shrink the grid step by 2^-20 so float rounding can never push an error past E
SAFETY = 1.0 - 2.0 ** -20
#: key frames are fitted on a grid this many times finer than the bound's own grid: the
#: interpolated values are rounded to the grid, and on the coarse grid that rounding alone
#: can use up the whole error budget (measured: 5 mm files 36 -> 51:1 on cmu_02_01)
KEY_REFINE = 2


@dataclass
class EncodeOptions:
    """Every control of the encoder, with the defaults used by ``mpz encode``.

    Global distortion controls (paper §IV): ``theta`` (key-frame threshold,
    fraction of ADDH), ``k0`` (initial clusters), ``tau`` (clustering
    threshold, fraction of ADDH), ``metric`` ("max" or "ave"). Local controls:
    ``weights`` (marker or node name -> weight) and ``group_errors`` (node
    name -> max error, with ``max_error``). Beyond the paper: ``max_error``
    (hard bound, motion units), ``patterns`` ("auto" keeps the pattern layer of
    a node only where it makes the file smaller; "on"; "off"),
    ``segmentation`` ("adaptive" = Alg. 1, "optimal" = Fisher partition).
    """

    max_error: float | None = None
    group_errors: dict = field(default_factory=dict)
    theta: float = 0.2
    k0: int = 10
    tau: float = 0.05
    metric: str = "max"
    weights: dict | None = None
    hierarchy: object = None
    smoothing: int = 2
    patterns: str | None = None
    segmentation: str = "adaptive"
    grid: float | None = None
    max_segment: int = 240
    summary: tuple = ()
    summary_space: str = "positions"
    metadata: dict = field(default_factory=dict)
    seed: int = 0

    def check(self):
        if self.max_error is not None and not (math.isfinite(self.max_error) and self.max_error > 0):
            raise EncoderError(f"max_error must be finite and > 0, got {self.max_error!r}")
        for name, e in self.group_errors.items():
            if not (math.isfinite(e) and e > 0):
                raise EncoderError(f"group error for {name!r} must be finite and > 0, got {e!r}")
        if self.group_errors and self.max_error is None:
            raise EncoderError("group error bounds need a global max_error as well")
        if not self.theta > 0 or not self.tau > 0:
            raise EncoderError("theta and tau must be > 0 (fractions of the head size ADDH)")
        if not 1 <= self.k0 <= 65535:
            raise EncoderError(f"k0 must be in 1..65535, got {self.k0}")
        if self.metric not in ("max", "ave"):
            raise EncoderError(f"metric must be 'max' or 'ave', got {self.metric!r}")
        if self.patterns is None:
            self.patterns = "off" if self.max_error is not None else "on"
        if self.patterns not in ("auto", "on", "off"):
            raise EncoderError(f"patterns must be auto, on or off, got {self.patterns!r}")
        if self.patterns == "off" and self.max_error is None:
            raise EncoderError("patterns='off' needs max_error (the residual layer carries the motion)")
        if self.segmentation not in ("adaptive", "optimal"):
            raise EncoderError(f"segmentation must be adaptive or optimal, got {self.segmentation!r}")
        if not 0 <= self.smoothing <= container.MAX_SMOOTHING:
            raise EncoderError(f"smoothing must be in 0..{container.MAX_SMOOTHING}")
        if self.grid is not None and not (math.isfinite(self.grid) and self.grid > 0):
            raise EncoderError(f"grid must be finite and > 0, got {self.grid!r}")
        if not 2 <= self.max_segment <= container.MAX_PATTERN_LENGTH:
            raise EncoderError(f"max_segment must be in 2..{container.MAX_PATTERN_LENGTH}")


@dataclass
class NodeReport:
    name: str
    members: int
    segments: int = 0
    patterns: int = 0
    pattern_length: int = 0
    pattern_bytes: int = 0
    segment_bytes: int = 0
    residual_bytes: int = 0
    residual_scale: int = 1
    residual_order: int | None = None
    used_patterns: bool = False


@dataclass
class EncodeReport:
    """What the encoder did: sizes, grid, per-node segments and patterns."""

    frames: int
    markers: int
    raw_bytes: int
    file_bytes: int = 0
    step: float = 0.0
    addh: float = 0.0
    addh_rule: str = ""
    hierarchy: str = ""
    nodes: list = field(default_factory=list)
    chunk_bytes: dict = field(default_factory=dict)
    seconds: float = 0.0

    @property
    def ratio(self) -> float:
        return self.raw_bytes / max(self.file_bytes, 1)


# ----------------------------------------------------------------- helpers --
def fill_gaps(x: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Linear interpolation over time of each marker's gaps (held at the ends).

    A marker that is a gap throughout copies the first marker that has data
    (so it costs almost nothing); if no marker has data, zeros.
    """
    x = x.copy()
    F, M, _ = x.shape
    t = np.arange(F)
    donor = None
    for m in range(M):
        v = valid[:, m]
        if v.all():
            donor = m if donor is None else donor
            continue
        if not v.any():
            continue
        for a in range(3):
            x[~v, m, a] = np.interp(t[~v], t[v], x[v, m, a])
        donor = m if donor is None else donor
    for m in range(M):
        if not valid[:, m].any():
            x[:, m] = x[:, donor] if donor is not None else 0.0
    return x


def _round(a):
    return np.floor(np.asarray(a) + 0.5).astype(np.int64)


def _best_order(block, period=None, orders=(0, 1, 2)):
    """Code ``block`` with each predictor order; return (order, payload) of the smallest."""
    best = None
    for order in orders:
        enc = BlockEncoder(capacity=max(1024, block.size))
        enc.block(residuals(block, order, period), period=period)
        data = enc.finish()
        if best is None or len(data) < len(best[1]):
            best = (order, data)
    return best


def _bounded(y, radius, orders=(1, 2)):
    """Best (order, values, payload) for targets ``y`` (grid units) within ``radius``."""
    best = None
    for order in orders:
        wv = choose_lattice(y, radius, order)
        enc = BlockEncoder(capacity=max(1024, wv.size))
        enc.block(residuals(wv, order))
        data = enc.finish()
        if best is None or len(data) < len(best[2]):
            best = (order, wv, data)
    return best


def _node_bounds(opts, hier):
    """Max error of each node (motion units): group bound or the global one."""
    if opts.max_error is None:
        return {}
    b = {i: opts.max_error for i in range(len(hier.nodes))}
    for i, node in enumerate(hier.nodes):
        if node.name in opts.group_errors:
            b[i] = min(opts.max_error, opts.group_errors[node.name])
    return b


def _weights_for(node):
    w = np.asarray(node.weights, dtype=np.float64)
    return w if w.size else np.ones(len(node.members))


# ------------------------------------------------------------------ encode --
class _NodeCoder:
    """Codes one node: pattern layer, segments and (with a bound) residuals."""

    def __init__(self, opts: EncodeOptions, addh_q: float, smoothing: int):
        self.o = opts
        self.addh_q = addh_q
        self.h = smoothing

    def segments(self, x, w, boost=1.0):
        if self.o.segmentation == "optimal":
            from mpz.fisher import choose_k_for_threshold, optimal_partitions
            F, n = x.shape[0], x.shape[1]
            flat = x.reshape(F, -1)
            # the Fisher deviation is the norm over all n members; Alg. 1's is a mean
            # marker distance, so scale by sqrt(n) to make theta mean the same thing
            thr = self.o.theta * self.addh_q / boost * math.sqrt(n)
            k_max = max(1, min(F, F // 4 + 1, 512))
            try:
                part = choose_k_for_threshold(flat, thr, k_max)
            except EncoderError:       # no k <= k_max fits: take the finest partition
                part = optimal_partitions(flat, k_max, ks=[k_max])[k_max]
            starts = np.asarray(part.starts, dtype=np.int64)
            counts = np.diff(np.append(starts, F))
            return starts, counts
        return segment(x, w, self.o.theta * self.addh_q / boost, max_len=self.o.max_segment)

    def patterns(self, x, w, seed):
        """Pattern layer of ``x[F, n, 3]`` (grid units): returns dict or None.

        The node's mean weight divides its thresholds (paper §IV: a heavier
        marker group is segmented and clustered more finely); the relative
        weights of its members shape the distances.
        """
        F, n, _ = x.shape
        boost = max(float(np.mean(w)), 1e-6)
        starts, counts = self.segments(x, w, boost)
        L = int(max(1, min(container.MAX_PATTERN_LENGTH, round(float(counts.mean())))))
        segs = normalize(x, starts, counts, L)                       # [S, L, n, 3]
        S = segs.shape[0]
        sw = np.sqrt(w / w.mean())[None, None, :, None]
        vec = (segs * sw).reshape(S, -1)
        labels, _ = adaptive_kmeans(vec, self.o.k0, self.o.tau * self.addh_q / boost,
                                    metric=self.o.metric, per_sample=L * n, seed=seed)
        K = int(labels.max()) + 1
        # relabel by frequency so the most used pattern gets index 0
        order = np.argsort(-np.bincount(labels, minlength=K), kind="stable")
        remap = np.empty(K, np.int64)
        remap[order] = np.arange(K)
        labels = remap[labels]
        centers = np.zeros((K, L, n, 3))
        np.add.at(centers, labels, segs)
        centers /= np.bincount(labels, minlength=K)[:, None, None, None]
        # pattern grid: a fraction of the clustering threshold (paper: 8-bit deltas)
        scale = int(max(1, min(65535, math.floor(self.o.tau * self.addh_q / boost / 3))))
        v = _round(centers / scale)
        porder, pdata = _best_order(v.reshape(K * L, n, 3), period=L, orders=(1, 2))
        enc = BlockEncoder()
        enc.block(np.stack([labels, counts - L], axis=1)[:, None, :])
        sdata = enc.finish()
        p = denormalize(v * scale, labels, counts)
        p = smooth_boundaries(p, segment_starts(counts), self.h)
        return {"K": K, "L": L, "scale": scale, "order": porder, "pdata": pdata, "sdata": sdata,
                "pred": p, "segments": S}


def _chain(x, valid, root_marker, members):
    """Order ``members`` so that each follows the already ordered marker it moves most
    rigidly with (std over time of their distance), starting next to the root: every
    marker then has a good key-frame reference before it (spec §6.5, base 2)."""
    if len(members) < 3:
        return list(members)
    idx = [root_marker] + list(members)
    sub = np.nan_to_num(x[:: max(1, x.shape[0] // 400), idx])
    ok = valid[:: max(1, x.shape[0] // 400)][:, idx]
    d = np.linalg.norm(sub[:, :, None] - sub[:, None], axis=3)
    both = ok[:, :, None] & ok[:, None, :]
    n = both.sum(0).clip(min=1)
    mean = (d * both).sum(0) / n
    std = np.sqrt(np.maximum((d ** 2 * both).sum(0) / n - mean ** 2, 0))
    score = std + 0.05 * mean
    score[both.sum(0) < 2] = np.inf
    order, left = [0], set(range(1, len(idx)))
    best = score[0].copy()
    while left:
        nxt = min(left, key=lambda j: (best[j], j))
        order.append(nxt)
        left.remove(nxt)
        best = np.minimum(best, score[nxt])
    return [idx[j] for j in order[1:]]


def _reroot(root_marker, M, x=None, valid=None):
    """A flat hierarchy (root + one node) whose root is ``root_marker``."""
    from mpz.hierarchy import Hierarchy, Node
    rest = [m for m in range(M) if m != root_marker]
    if x is not None:
        rest = _chain(x, valid, root_marker, rest)
    nodes = [Node("root", -1, root_marker, [root_marker], [1.0])]
    if rest:
        nodes.append(Node("body", 0, rest[0], rest, [1.0] * len(rest)))
    return Hierarchy(nodes, "flat")


def _grid(motion, opts, addh, hier):
    """Grid step and per-node residual multipliers g (spec §4.4, §6.5)."""
    if opts.max_error is None:
        step = opts.grid if opts.grid is not None else addh / 1000.0
        return step, {}
    bounds = {}
    names = {node.name: i for i, node in enumerate(hier.nodes)}
    for key, e in opts.group_errors.items():
        if key not in names:
            raise EncoderError(f"group error given for unknown node {key!r}; nodes are "
                               f"{', '.join(names)}")
        bounds[names[key]] = min(e, opts.max_error)
    e_min = min([opts.max_error] + list(bounds.values()))
    # rounding each axis to a grid of step s errs by <= s/2 per axis, sqrt(3) s / 2 in 3-D;
    # the stored grid is KEY_REFINE times finer, so that key-frame interpolation rounds
    # finely (base 2); per-sample residuals (base 0, 1) use g = KEY_REFINE, the same lattice
    step = 2.0 * e_min / SQRT3 * SAFETY / KEY_REFINE
    if opts.grid is not None:
        step = min(step, opts.grid)
    g = {}
    for i in range(1, len(hier.nodes)):
        e = bounds.get(i, opts.max_error)
        g[i] = int(max(1, min(65535, math.floor(2.0 * e / SQRT3 * SAFETY / step))))
    return step, g


def encode_motion(motion: Motion, opts: EncodeOptions | None = None, *, progress=None):
    """Encode ``motion``; returns ``(bytes, EncodeReport)``.

    Parameters
    ----------
    motion : Motion
    opts : EncodeOptions
    progress : callable(fraction, message), optional
        Called as each node is coded.

    Raises
    ------
    EncoderError
        For options that cannot be honoured.
    """
    t0 = time.perf_counter()
    opts = opts or EncodeOptions()
    opts.check()
    if not isinstance(motion, Motion):
        raise EncoderError(f"expected an mpz.Motion, got {type(motion).__name__}")
    from mpz.hierarchy import build_hierarchy, head_scale
    F, M = motion.n_frames, motion.n_markers
    if F > container.MAX_FRAMES or M > container.MAX_MARKERS or F * M > container.MAX_SAMPLES:
        raise EncoderError(f"{F} frames x {M} markers exceeds the limits of spec §8")
    if opts.patterns == "off" and opts.hierarchy is None and not opts.group_errors:
        # without patterns the residual layers are absolute (base 1/2) and the tree carries
        # nothing; one node for all non-root markers lets the models adapt once (smaller)
        root_marker = build_hierarchy(motion, None, weights=opts.weights).nodes[0].members[0]
        hier = _reroot(root_marker, motion.n_markers, motion.positions, motion.valid)
    else:
        hier = build_hierarchy(motion, opts.hierarchy, weights=opts.weights)
    hier.validate(M)
    addh, addh_rule = head_scale(motion, hier)
    step, gmap = _grid(motion, opts, addh, hier)
    report = EncodeReport(F, M, motion.raw_size(), step=step, addh=addh, addh_rule=addh_rule,
                          hierarchy=hier.method)

    x = fill_gaps(motion.positions, motion.valid)
    lo, hi = x.reshape(-1, 3).min(0), x.reshape(-1, 3).max(0)
    offset = (lo + hi) / 2.0
    u = (x - offset) / step                                   # grid coordinates (float)
    if np.abs(u).max() * 2 + 2 >= 2.0 ** MAX_EXP:
        raise EncoderError(f"grid step {step:g} is too fine for a data range of "
                           f"{float((hi - lo).max()):g} {motion.units}: values exceed 2^29")
    residual = opts.max_error is not None
    h = opts.smoothing
    coder = _NodeCoder(opts, addh / step, h)

    chunks = []
    qhat = np.zeros((F, M, 3), np.int64)
    root_marker = hier.nodes[0].members[0]
    qhat[:, root_marker] = _round(u[:, root_marker])
    bounds = _node_bounds(opts, hier)
    if residual:
        rorder, w_root, rdata = _bounded(u[:, root_marker][:, None, :], bounds[0] / step)
        qhat[:, root_marker] = w_root[:, 0]
    else:
        rorder, rdata = _best_order(qhat[:, root_marker][:, None, :])
    body = [("ROOT", {"order": rorder, "coded": rdata})]
    n_nodes = len(hier.nodes)
    for i in range(1, n_nodes):
        node = hier.nodes[i]
        members = list(node.members)
        ref = hier.nodes[node.parent].ref
        xl = u[:, members] - qhat[:, ref][:, None, :]          # closed loop: decoded parent
        w = _weights_for(node)
        nrep = NodeReport(node.name, len(members))
        g = gmap.get(i, 1)
        pat = None
        if opts.patterns != "off":
            pat = coder.patterns(xl, w, opts.seed + i)
        base = 0
        if residual:
            radius = bounds[i] / (g * step)
            cand = []
            if pat is not None:
                order, wv, data = _bounded((xl - pat["pred"]) / g, radius)
                cost = len(pat["pdata"]) + len(pat["sdata"]) + len(data)
                cand.append((cost, 0, pat, order, wv, data, g))
            if opts.patterns != "on":
                order, wv, data = _bounded(u[:, members] / g, radius)
                cand.append((len(data), 1, None, order, wv, data, g))
                gk = max(1, g // KEY_REFINE)
                enc = BlockEncoder()
                wk = keyframe.encode_blocks(enc, u[:, members] / gk, bounds[i] / (gk * step))
                data = enc.finish()
                cand.append((len(data), 2, None, 0, wk, data, gk))
            cost, base, pat, order, wv, data, g = min(cand, key=lambda c: c[0])
            if base >= 1:
                local = g * wv - qhat[:, ref][:, None, :]
            else:
                local = pat["pred"] + g * wv
            nrep.residual_bytes, nrep.residual_scale, nrep.residual_order = len(data), g, order
        else:
            local = pat["pred"]
        if pat is not None:
            body.append(("PATT", {"node": i, "pattern_count": pat["K"], "length": pat["L"],
                                  "scale": pat["scale"], "order": pat["order"],
                                  "coded": pat["pdata"]}))
            body.append(("SEGS", {"node": i, "segment_count": pat["segments"],
                                  "coded": pat["sdata"]}))
            nrep.segments, nrep.patterns, nrep.pattern_length = pat["segments"], pat["K"], pat["L"]
            nrep.pattern_bytes, nrep.segment_bytes = len(pat["pdata"]), len(pat["sdata"])
            nrep.used_patterns = True
        elif not residual:  # pragma: no cover - lossy mode always has patterns
            raise EncoderError(f"node {node.name} has neither patterns nor a residual layer")
        # with a residual layer and no patterns, PATT is left out (spec §3.4)
        if residual:
            body.append(("RESI", {"node": i, "base": base, "order": nrep.residual_order,
                                  "scale": g, "coded": data}))
        qhat[:, members] = local + qhat[:, ref][:, None, :]
        report.nodes.append(nrep)
        if progress is not None:
            progress(i / (n_nodes - 1) if n_nodes > 1 else 1.0, node.name)

    bits = int(np.abs(qhat).max(initial=0)).bit_length() + 1
    if bits > 31:
        raise EncoderError("decoded values exceed the 31-bit range of spec §4.4; use a coarser grid")
    units = UNIT_FROM_NAME.get(motion.units, 0)
    header = {"version_major": VERSION_MAJOR, "version_minor": VERSION_MINOR,
              "flags": FLAG_RESIDUAL if residual else 0, "frame_count": F, "marker_count": M,
              "node_count": n_nodes, "rate": motion.rate, "units": units,
              "error_metric": 1 if residual else 0,
              "error_bound": float(opts.max_error) if residual else 0.0, "smoothing": h}
    chunks.append(("MHDR", header))
    names = [n.encode("utf-8") for n in motion.names]
    if any(not 1 <= len(n) <= 255 for n in names):
        raise EncoderError("marker names must be 1..255 bytes of UTF-8 (spec §4.2)")
    chunks.append(("MNAM", {"count": M, "names": list(motion.names)}))
    chunks.append(("HIER", {"count": n_nodes, "nodes": [
        {"parent": ROOT_PARENT if nd.parent < 0 else nd.parent, "ref": nd.ref,
         "member_count": len(nd.members), "members": list(nd.members),
         "weights": [float(v) for v in nd.weights]} for nd in hier.nodes]}))
    chunks.append(("QUNT", {"step": step, "offset": [float(o) for o in offset], "bits": bits}))
    if not motion.valid.all():
        enc = BlockEncoder()
        enc.block((~motion.valid).astype(np.int64)[:, :, None], signed=False)
        chunks.append(("MASK", {"coded": enc.finish()}))
    chunks.extend(body)
    if opts.summary:
        sstep = step if opts.summary_space == "positions" else 1e-3   # angles: 0.001 degree
        chunks.append(("smry", summary_fields(motion, opts.summary, opts.summary_space, sstep)))
    meta = dict(motion.metadata)
    meta.update(opts.metadata)
    if meta:
        def clip(text, limit):   # spec §4.11 limits are in UTF-8 bytes
            return text.encode("utf-8")[:limit].decode("utf-8", "ignore")
        entries = [{"key": clip(str(k), 255) or "_", "value": clip(str(v), 65535)}
                   for k, v in meta.items()]
        chunks.append(("meta", {"count": len(entries), "entries": entries}))
    chunks.append(("MEND", {}))
    parts = [SIGNATURE]
    for ctype, fields in chunks:
        b = container.build_chunk(ctype, fields)
        report.chunk_bytes[ctype] = report.chunk_bytes.get(ctype, 0) + len(b)
        parts.append(b)
    data = b"".join(parts)
    report.file_bytes = len(data)
    report.seconds = time.perf_counter() - t0
    return data, report


def summary_fields(motion: Motion, ks, space: str, step: float) -> dict:
    """Fields of the ancillary smry chunk (spec §4.10) from the optimal partition."""
    from mpz.fisher import motion_series, optimal_partitions
    series, _ = motion_series(motion, space=space)
    ks = sorted({int(k) for k in ks})
    if not ks or ks[0] < 1:
        raise EncoderError(f"summary levels must be positive integers, got {ks}")
    if len(ks) > container.MAX_SUMMARY_LEVELS:
        raise EncoderError(f"at most {container.MAX_SUMMARY_LEVELS} summary levels")
    F = series.shape[0]
    ks = [min(k, F) for k in ks]
    ks = sorted(set(ks))
    parts = optimal_partitions(series, max(ks), ks=ks)
    levels = []
    for k in ks:
        p = parts[k]
        means_q = _round(np.asarray(p.means) / step)
        if np.abs(means_q).max(initial=0) >= 2 ** 31:
            raise EncoderError("summary means do not fit 32 bits at this step")
        levels.append({"k": int(p.k), "wssse": float(p.wssse), "step": float(step),
                       "starts": np.asarray(p.starts, "<u4").tobytes(),
                       "means": means_q.astype("<i4").tobytes()})
    return {"space": 0 if space == "positions" else 1, "dims": int(series.shape[1]),
            "level_count": len(levels), "levels": levels}


def encode(motion: Motion, **options) -> bytes:
    """Encode a motion to MPZ bytes.

    Parameters
    ----------
    motion : Motion
    **options
        Any field of :class:`EncodeOptions`, e.g. ``max_error=1.0``.

    Returns
    -------
    bytes
        A complete MPZ 1.0 file.

    Examples
    --------
    >>> from mpz.synth import generate
    >>> data = encode(generate("walk", frames=30), max_error=2.0)
    >>> data[:4]
    b'\\x89MPZ'
    """
    try:
        opts = EncodeOptions(**options)
    except TypeError as exc:
        raise EncoderError(str(exc)) from None
    return encode_motion(motion, opts)[0]
