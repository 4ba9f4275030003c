"""The MPZ reference encoder: the paper's pipeline, plus a hard error bound.

Strategy (reads as Fig. 2 of Gu, Peng & Deng), one function per stage:

1. :func:`plan_hierarchy` - the body-part hierarchy (§III-A) and ADDH, the head scale
   every threshold is relative to;
2. :func:`plan_grid` - the quantisation grid (spec §4.4): with ``max_error=E`` the step
   keeps the Euclidean error <= E; without it, a fine grid (ADDH / 1000);
3. :func:`code_root` - the root marker as an absolute track (§III-D, spec §4.6);
4. :func:`code_node` - node by node, parents first, in *closed loop* (each node is coded
   relative to the decoded, not the original, reference marker of its parent, so errors
   do not pile up down the tree): :func:`code_patterns` (segmentation, Alg. 1 ->
   normalisation -> adaptive K-means -> patterns quantised and predicted -> (pattern
   index, frame count) pairs -> the decoder's own de-normalisation and smoothing), then,
   with a bound, the cheapest :class:`ResidualLayer` that restores every sample to within
   E (beyond the paper);
5. :func:`file_records` - header, names, hierarchy, grid, mask, the coded nodes, the
   optional Fisher summary and metadata, as typed chunk records (:mod:`mpz.chunks`),
   framed by :func:`mpz.container.build`, the same table the decoder reads with.

The encoder never writes files; see :func:`mpz.write_mpz` for atomic output.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
import math
import time
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mpz import container, keyframe
from mpz.chunks import (
    Hier,
    HierNode,
    Mask,
    Mend,
    Meta,
    MetaEntry,
    Mhdr,
    Mnam,
    Patt,
    Qunt,
    Record,
    Resi,
    Root,
    Segs,
    Smry,
    SummaryLevel,
)
from mpz.cluster import adaptive_kmeans
from mpz.entropy import MAX_EXP, BlockEncoder
from mpz.errors import EncoderError
from mpz.extensions import EXTENSIONS
from mpz.format import (
    FLAG_RESIDUAL,
    MAX_BITS,
    MAX_FRAMES,
    MAX_MARKERS,
    MAX_PATTERN_LENGTH,
    MAX_SAMPLES,
    MAX_SMOOTHING,
    MAX_SUMMARY_LEVELS,
    ROOT_PARENT,
    VERSION_MAJOR,
    VERSION_MINOR,
    ErrorMetric,
    ResidualBase,
    SummarySpace,
    unit_code,
)
from mpz.hierarchy import Hierarchy, Node, build_hierarchy, head_scale
from mpz.motion import Motion
from mpz.normalize import denormalize, normalize, segment_starts
from mpz.predict import residuals
from mpz.quantize import choose_lattice
from mpz.segment import segment
from mpz.smooth import smooth_boundaries

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]
Progress = Callable[[float, str], None]

SQRT3 = math.sqrt(3.0)
#: shrink the grid step by 2^-20 so float rounding can never push an error past E
SAFETY = 1.0 - 2.0 ** -20
#: key frames are fitted on a grid this many times finer than the bound's own grid: the
#: interpolated values are rounded to the grid, and on the coarse grid that rounding alone
#: can use up the whole error budget (measured: 5 mm files 36 -> 51:1 on cmu_02_01)
KEY_REFINE = 2


# ----------------------------------------------------------------- options --
@dataclass(frozen=True)
class EncodeOptions:
    """Every control of the encoder; the field defaults are the one definition of the
    defaults (``mpz encode`` reads them from here).

    Options are immutable: :meth:`validate` checks them without changing them, and
    derived settings (:attr:`pattern_mode`) are properties.

    Global distortion controls (paper §IV): ``theta`` (key-frame threshold, fraction of
    ADDH), ``k0`` (initial clusters), ``tau`` (clustering threshold, fraction of ADDH),
    ``metric`` ("max" or "ave"). Local controls: ``weights`` (marker or node name ->
    weight) and ``group_errors`` (node name -> max error, with ``max_error``). Beyond the
    paper: ``max_error`` (hard bound, motion units), ``patterns`` ("auto" keeps the
    pattern layer of a node only where it makes the file smaller; "on"; "off"; None: "off"
    under a bound, "on" without), ``segmentation`` ("adaptive" = Alg. 1, "optimal" =
    Fisher partition).
    """

    max_error: float | None = None
    group_errors: Mapping[str, float] = field(default_factory=dict)
    theta: float = 0.2
    k0: int = 10
    tau: float = 0.05
    metric: str = "max"
    weights: Mapping[str, float] | None = None
    hierarchy: Any = None
    smoothing: int = 2
    patterns: str | None = None
    segmentation: str = "adaptive"
    grid: float | None = None
    max_segment: int = 240
    summary: tuple[int, ...] = ()
    summary_space: str = "positions"
    metadata: Mapping[str, str] = field(default_factory=dict)
    seed: int = 0

    def __post_init__(self) -> None:
        # read-only views, so an options object cannot change after it is made
        object.__setattr__(self, "group_errors", MappingProxyType(dict(self.group_errors)))
        object.__setattr__(self, "metadata", MappingProxyType(dict(self.metadata)))
        if self.weights is not None:
            object.__setattr__(self, "weights", MappingProxyType(dict(self.weights)))
        object.__setattr__(self, "summary", tuple(self.summary))

    @property
    def bounded(self) -> bool:
        """A hard bound is declared: every node gets a residual layer."""
        return self.max_error is not None

    @property
    def pattern_mode(self) -> str:
        """``patterns`` with its default resolved: "off" under a bound, else "on"."""
        if self.patterns is None:
            return "off" if self.bounded else "on"
        return self.patterns

    def validate(self) -> None:
        """Raise EncoderError for options that cannot be honoured (changes nothing)."""
        e = self.max_error
        if e is not None and not (math.isfinite(e) and e > 0):
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
        if self.pattern_mode not in ("auto", "on", "off"):
            raise EncoderError(f"patterns must be auto, on or off, got {self.patterns!r}")
        if self.pattern_mode == "off" and not self.bounded:
            raise EncoderError("patterns='off' needs max_error (the residual layer carries the "
                               "motion)")
        if self.segmentation not in ("adaptive", "optimal"):
            raise EncoderError(f"segmentation must be adaptive or optimal, got "
                               f"{self.segmentation!r}")
        if not 0 <= self.smoothing <= MAX_SMOOTHING:
            raise EncoderError(f"smoothing must be in 0..{MAX_SMOOTHING}")
        if self.grid is not None and not (math.isfinite(self.grid) and self.grid > 0):
            raise EncoderError(f"grid must be finite and > 0, got {self.grid!r}")
        if not 2 <= self.max_segment <= MAX_PATTERN_LENGTH:
            raise EncoderError(f"max_segment must be in 2..{MAX_PATTERN_LENGTH}")


#: the defaults, for tools that show or restate them
DEFAULTS = EncodeOptions()


# ----------------------------------------------------------------- reports --
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
    nodes: list[NodeReport] = field(default_factory=list)
    chunk_bytes: dict[str, int] = field(default_factory=dict)
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


def _best_order(block: IntArray, period: int | None = None,
                orders: tuple[int, ...] = (0, 1, 2)) -> tuple[int, bytes]:
    """Code ``block`` with each predictor order; return (order, payload) of the smallest."""
    best: tuple[int, bytes] | None = None
    for order in orders:
        enc = BlockEncoder(capacity=max(1024, block.size))
        enc.block(residuals(block, order, period), period=period)
        data = enc.finish()
        if best is None or len(data) < len(best[1]):
            best = (order, data)
    assert best is not None
    return best


def _bounded(y: FloatArray, radius: float,
             orders: tuple[int, ...] = (1, 2)) -> tuple[int, IntArray, bytes]:
    """Best (order, values, payload) for targets ``y`` (grid units) within ``radius``."""
    best: tuple[int, IntArray, bytes] | None = None
    for order in orders:
        wv = choose_lattice(y, radius, order)
        enc = BlockEncoder(capacity=max(1024, wv.size))
        enc.block(residuals(wv, order))
        data = enc.finish()
        if best is None or len(data) < len(best[2]):
            best = (order, wv, data)
    assert best is not None
    return best


def _weights_for(node: Node) -> FloatArray:
    w = np.asarray(node.weights, dtype=np.float64)
    return w if w.size else np.ones(len(node.members))


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


def _reroot(root_marker: int, M: int, x: FloatArray | None = None,
            valid: NDArray[np.bool_] | None = None) -> Hierarchy:
    """A flat hierarchy (root + one node) whose root is ``root_marker``."""
    rest = [m for m in range(M) if m != root_marker]
    if x is not None and valid is not None:
        rest = _chain(x, valid, root_marker, rest)
    nodes = [Node("root", -1, root_marker, [root_marker], [1.0])]
    if rest:
        nodes.append(Node("body", 0, rest[0], rest, [1.0] * len(rest)))
    return Hierarchy(nodes, "flat")


# ---------------------------------------------------------- 1-2: the plan --
def plan_hierarchy(motion: Motion, opts: EncodeOptions) -> Hierarchy:
    """Stage 1: the coding hierarchy (paper §III-A)."""
    if opts.pattern_mode == "off" and opts.hierarchy is None and not opts.group_errors:
        # without patterns the residual layers are absolute (base 1/2) and the tree carries
        # nothing; one node for all non-root markers lets the models adapt once (smaller)
        root_marker = build_hierarchy(motion, None, weights=opts.weights).nodes[0].members[0]
        hier = _reroot(root_marker, motion.n_markers, motion.positions, motion.valid)
    else:
        hier = build_hierarchy(motion, opts.hierarchy, weights=opts.weights)
    hier.validate(motion.n_markers)
    return hier


@dataclass(frozen=True)
class Grid:
    """Stage 2: the quantisation grid (spec §4.4) and each node's error budget."""

    step: float
    offset: FloatArray                  # per axis, the middle of the data range
    scale: dict[int, int]               # node -> residual multiplier g (§6.5)
    bounds: dict[int, float]            # node -> max error in motion units (bounded mode)


def plan_grid(motion: Motion, opts: EncodeOptions, hier: Hierarchy, addh: float,
              x: FloatArray) -> Grid:
    """Stage 2: grid step, offset and per-node residual multipliers g (spec §4.4, §6.5)."""
    lo, hi = x.reshape(-1, 3).min(0), x.reshape(-1, 3).max(0)
    offset = (lo + hi) / 2.0
    if opts.max_error is None:
        step = opts.grid if opts.grid is not None else addh / 1000.0
        return Grid(step, offset, {}, {})
    names = {node.name: i for i, node in enumerate(hier.nodes)}
    group: dict[int, float] = {}
    for key, e in opts.group_errors.items():
        if key not in names:
            raise EncoderError(f"group error given for unknown node {key!r}; nodes are "
                               f"{', '.join(names)}")
        group[names[key]] = min(e, opts.max_error)
    e_min = min([opts.max_error, *group.values()])
    # rounding each axis to a grid of step s errs by <= s/2 per axis, sqrt(3) s / 2 in 3-D;
    # the stored grid is KEY_REFINE times finer, so that key-frame interpolation rounds
    # finely (base 2); per-sample residuals (base 0, 1) use g = KEY_REFINE, the same lattice
    step = 2.0 * e_min / SQRT3 * SAFETY / KEY_REFINE
    if opts.grid is not None:
        step = min(step, opts.grid)
    g = {}
    for i in range(1, len(hier.nodes)):
        e = group.get(i, opts.max_error)
        g[i] = int(max(1, min(65535, math.floor(2.0 * e / SQRT3 * SAFETY / step))))
    bounds = {i: opts.max_error for i in range(len(hier.nodes))}
    for i, node in enumerate(hier.nodes):
        if node.name in opts.group_errors:
            bounds[i] = min(opts.max_error, opts.group_errors[node.name])
    return Grid(step, offset, g, bounds)


# --------------------------------------------------------- 3: the root track --
def code_root(u_root: FloatArray, opts: EncodeOptions, grid: Grid) -> tuple[Root, IntArray]:
    """Stage 3: the root marker's track (spec §4.6); returns the record and the decoded
    integer track ``[F, 3]``."""
    if opts.bounded:
        order, w, data = _bounded(u_root[:, None, :], grid.bounds[0] / grid.step)
        return Root(order=order, coded=data), w[:, 0]
    q = _round(u_root)
    order, data = _best_order(q[:, None, :])
    return Root(order=order, coded=data), q


# ------------------------------------------------------------ 4: one node --
@dataclass(frozen=True)
class PatternLayer:
    """The paper's layer for one node: K patterns of L frames and the segments using them."""

    K: int
    L: int
    scale: int                          # pattern grid multiplier (§4.7)
    order: int                          # predictor order within each pattern
    coded: bytes                        # PATT payload data
    segments: int                       # S
    segments_coded: bytes               # SEGS payload data
    prediction: IntArray                # P, what the decoder rebuilds, [F, n, 3]

    @property
    def cost(self) -> int:
        return len(self.coded) + len(self.segments_coded)

    def records(self, node: int) -> list[Record]:
        return [Patt(node=node, pattern_count=self.K, length=self.L, scale=self.scale,
                     order=self.order, coded=self.coded),
                Segs(node=node, segment_count=self.segments, coded=self.segments_coded)]


@dataclass(frozen=True)
class ResidualLayer:
    """One candidate residual layer of a node (spec §4.9): what it adds and what it costs."""

    base: ResidualBase
    order: int
    scale: int                          # g
    values: IntArray                    # w, before multiplying by g
    coded: bytes

    def record(self, node: int) -> Resi:
        return Resi(node=node, base=int(self.base), order=self.order, scale=self.scale,
                    coded=self.coded)


def _segments(x: FloatArray, w: FloatArray, threshold: float, n: int,
              opts: EncodeOptions) -> tuple[IntArray, IntArray]:
    """Segment starts and frame counts: Alg. 1, or the Fisher optimal partition."""
    if opts.segmentation == "optimal":
        from mpz.fisher import choose_k_for_threshold, optimal_partitions
        F = x.shape[0]
        flat = x.reshape(F, -1)
        # the Fisher deviation is the norm over all n members; Alg. 1's is a mean
        # marker distance, so scale by sqrt(n) to make theta mean the same thing
        thr = threshold * math.sqrt(n)
        k_max = max(1, min(F, F // 4 + 1, 512))
        try:
            part = choose_k_for_threshold(flat, thr, k_max)
        except EncoderError:       # no k <= k_max fits: take the finest partition
            part = optimal_partitions(flat, k_max, ks=[k_max])[k_max]
        starts = np.asarray(part.starts, dtype=np.int64)
        counts = np.diff(np.append(starts, F))
        return starts, counts
    return segment(x, w, threshold, max_len=opts.max_segment)


def code_patterns(x: FloatArray, w: FloatArray, opts: EncodeOptions, addh_q: float,
                  seed: int) -> PatternLayer:
    """The pattern layer of ``x[F, n, 3]`` (grid units, relative to the parent's reference).

    The node's mean weight divides its thresholds (paper §IV: a heavier marker group is
    segmented and clustered more finely); the relative weights of its members shape the
    distances.
    """
    F, n, _ = x.shape
    boost = max(float(np.mean(w)), 1e-6)
    starts, counts = _segments(x, w, opts.theta * addh_q / boost, n, opts)
    L = int(max(1, min(MAX_PATTERN_LENGTH, round(float(counts.mean())))))
    segs = normalize(x, starts, counts, L)                       # [S, L, n, 3]
    S = segs.shape[0]
    sw = np.sqrt(w / w.mean())[None, None, :, None]
    vec = (segs * sw).reshape(S, -1)
    labels, _ = adaptive_kmeans(vec, opts.k0, opts.tau * addh_q / boost,
                                metric=opts.metric, per_sample=L * n, seed=seed)
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
    scale = int(max(1, min(65535, math.floor(opts.tau * addh_q / boost / 3))))
    v = _round(centers / scale)
    porder, pdata = _best_order(v.reshape(K * L, n, 3), period=L, orders=(1, 2))
    enc = BlockEncoder()
    enc.block(np.stack([labels, counts - L], axis=1)[:, None, :])
    sdata = enc.finish()
    p = denormalize(v * scale, labels, counts)
    p = smooth_boundaries(p, segment_starts(counts), opts.smoothing)
    return PatternLayer(K, L, scale, porder, pdata, S, sdata, p)


def residual_candidates(i: int, xl: FloatArray, u_members: FloatArray,
                        pat: PatternLayer | None, opts: EncodeOptions,
                        grid: Grid) -> list[tuple[int, ResidualLayer]]:
    """(cost, layer) of every residual layer that keeps node i within its bound (beyond
    the paper): on the pattern layer (base 0), absolute per sample (base 1), key frames
    (base 2)."""
    g = grid.scale.get(i, 1)
    radius = grid.bounds[i] / (g * grid.step)
    out = []
    if pat is not None:
        order, wv, data = _bounded((xl - pat.prediction) / g, radius)
        out.append((pat.cost + len(data),
                    ResidualLayer(ResidualBase.PARENT, order, g, wv, data)))
    if opts.pattern_mode != "on":
        order, wv, data = _bounded(u_members / g, radius)
        out.append((len(data), ResidualLayer(ResidualBase.ABSOLUTE, order, g, wv, data)))
        gk = max(1, g // KEY_REFINE)
        enc = BlockEncoder()
        wk = keyframe.encode_blocks(enc, u_members / gk, grid.bounds[i] / (gk * grid.step))
        data = enc.finish()
        out.append((len(data), ResidualLayer(ResidualBase.KEYFRAMES, 0, gk, wk, data)))
    return out


@dataclass(frozen=True)
class NodeCode:
    """Stage 4's result for one node: its records and its decoded grid values."""

    records: list[Record]
    decoded: IntArray                   # q of the members, [F, n, 3]
    report: NodeReport


def code_node(i: int, node: Node, ref: int, u: FloatArray, qhat: IntArray,
              opts: EncodeOptions, grid: Grid, addh_q: float) -> NodeCode:
    """Stage 4: node i, coded against the *decoded* track of ``ref``, the reference marker of
    its parent (closed loop)."""
    members = list(node.members)
    ref_q = qhat[:, ref][:, None, :]
    xl = u[:, members] - ref_q
    rep = NodeReport(node.name, len(members))
    pat = None
    if opts.pattern_mode != "off":
        pat = code_patterns(xl, _weights_for(node), opts, addh_q, opts.seed + i)
    records: list[Record] = []
    if opts.bounded:
        # the cheapest candidate; on a tie the first (min keeps the first minimum)
        _, layer = min(residual_candidates(i, xl, u[:, members], pat, opts, grid),
                       key=lambda c: c[0])
        if layer.base == ResidualBase.PARENT:
            assert pat is not None
            local = pat.prediction + layer.scale * layer.values
        else:
            pat = None
            local = layer.scale * layer.values - ref_q
        rep.residual_bytes, rep.residual_scale = len(layer.coded), layer.scale
        rep.residual_order = layer.order
    else:
        assert pat is not None              # validate(): lossy mode always has patterns
        local = pat.prediction
    if pat is not None:
        records += pat.records(i)
        rep.segments, rep.patterns, rep.pattern_length = pat.segments, pat.K, pat.L
        rep.pattern_bytes, rep.segment_bytes = len(pat.coded), len(pat.segments_coded)
        rep.used_patterns = True
    # with a residual layer and no patterns, PATT is left out (spec §3.4)
    if opts.bounded:
        records.append(layer.record(i))
    return NodeCode(records, local + ref_q, rep)


# ------------------------------------------------------ 5: the file records --
def summary_record(motion: Motion, ks: tuple[int, ...] | list[int], space: str,
                   step: float) -> Smry:
    """The ancillary smry chunk (spec §4.10) from the optimal partition."""
    from mpz.fisher import motion_series, optimal_partitions
    series, _ = motion_series(motion, space=space)
    levels_k = sorted({int(k) for k in ks})
    if not levels_k or levels_k[0] < 1:
        raise EncoderError(f"summary levels must be positive integers, got {levels_k}")
    if len(levels_k) > MAX_SUMMARY_LEVELS:
        raise EncoderError(f"at most {MAX_SUMMARY_LEVELS} summary levels")
    F = series.shape[0]
    levels_k = sorted({min(k, F) for k in levels_k})
    parts = optimal_partitions(series, max(levels_k), ks=levels_k)
    levels = []
    for k in levels_k:
        p = parts[k]
        means_q = _round(np.asarray(p.means) / step)
        if np.abs(means_q).max(initial=0) >= 2 ** 31:
            raise EncoderError("summary means do not fit 32 bits at this step")
        levels.append(SummaryLevel(k=int(p.k), wssse=float(p.wssse), step=float(step),
                                   starts=np.asarray(p.starts, "<u4").tobytes(),
                                   means=means_q.astype("<i4").tobytes()))
    space_code = SummarySpace.POSITIONS if space == "positions" else SummarySpace.ANGLES
    return Smry(space=int(space_code), dims=int(series.shape[1]), level_count=len(levels),
                levels=tuple(levels))


def _meta_record(motion: Motion, opts: EncodeOptions) -> Meta | None:
    """§4.11 metadata: the motion's, then the options' (limits are in UTF-8 bytes)."""
    meta = dict(motion.metadata)
    meta.update(opts.metadata)
    if not meta:
        return None

    def clip(text: str, limit: int) -> str:
        return text.encode("utf-8")[:limit].decode("utf-8", "ignore")

    entries = [MetaEntry(key=clip(str(k), 255) or "_", value=clip(str(v), 65535))
               for k, v in meta.items()]
    return Meta(count=len(entries), entries=tuple(entries))


def file_records(motion: Motion, opts: EncodeOptions, hier: Hierarchy, grid: Grid,
                 root: Root, nodes: list[NodeCode], bits: int) -> list[Record]:
    """Stage 5: every chunk of the file, in the §3.4 order."""
    F, M = motion.n_frames, motion.n_markers
    if any(not 1 <= len(n.encode("utf-8")) <= 255 for n in motion.names):
        raise EncoderError("marker names must be 1..255 bytes of UTF-8 (spec §4.2)")
    records: list[Record] = [
        Mhdr(version_major=VERSION_MAJOR, version_minor=VERSION_MINOR,
             flags=FLAG_RESIDUAL if opts.bounded else 0, frame_count=F, marker_count=M,
             node_count=len(hier.nodes), rate=motion.rate, units=int(unit_code(motion.units)),
             error_metric=int(ErrorMetric.MAX_EUCLIDEAN if opts.bounded else ErrorMetric.NONE),
             error_bound=float(opts.max_error) if opts.max_error is not None else 0.0,
             smoothing=opts.smoothing),
        Mnam(count=M, names=tuple(motion.names)),
        Hier(count=len(hier.nodes), nodes=tuple(
            HierNode(parent=ROOT_PARENT if nd.parent < 0 else nd.parent, ref=nd.ref,
                     member_count=len(nd.members), members=tuple(nd.members),
                     weights=tuple(float(v) for v in nd.weights)) for nd in hier.nodes)),
        Qunt(step=grid.step, offset=(float(grid.offset[0]), float(grid.offset[1]),
                                     float(grid.offset[2])), bits=bits),
    ]
    if not motion.valid.all():
        enc = BlockEncoder()
        enc.block((~motion.valid).astype(np.int64)[:, :, None], signed=False)
        records.append(Mask(coded=enc.finish()))
    records.append(root)
    for n in nodes:
        records += n.records
    if opts.summary:
        sstep = grid.step if opts.summary_space == "positions" else 1e-3   # angles: 0.001 deg
        records.append(summary_record(motion, opts.summary, opts.summary_space, sstep))
    meta = _meta_record(motion, opts)
    if meta is not None:
        records.append(meta)
    for ext in EXTENSIONS:           # what the source holds besides markers (ancillary)
        records += ext.records(motion, opts)
    records.append(Mend())
    return records


# ------------------------------------------------------------------ encode --
def encode_motion(motion: Motion, opts: EncodeOptions | None = None, *,
                  progress: Progress | None = None) -> tuple[bytes, EncodeReport]:
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
    opts = opts if opts is not None else DEFAULTS
    opts.validate()
    if not isinstance(motion, Motion):
        raise EncoderError(f"expected an mpz.Motion, got {type(motion).__name__}")
    F, M = motion.n_frames, motion.n_markers
    if F > MAX_FRAMES or M > MAX_MARKERS or F * M > MAX_SAMPLES:
        raise EncoderError(f"{F} frames x {M} markers exceeds the limits of spec §8")
    hier = plan_hierarchy(motion, opts)
    addh, addh_rule = head_scale(motion, hier)
    x = fill_gaps(motion.positions, motion.valid)
    grid = plan_grid(motion, opts, hier, addh, x)
    report = EncodeReport(F, M, motion.raw_size(), step=grid.step, addh=addh,
                          addh_rule=addh_rule, hierarchy=hier.method)
    u = (x - grid.offset) / grid.step                          # grid coordinates (float)
    if np.abs(u).max() * 2 + 2 >= 2.0 ** MAX_EXP:
        span = float((x.reshape(-1, 3).max(0) - x.reshape(-1, 3).min(0)).max())
        raise EncoderError(f"grid step {grid.step:g} is too fine for a data range of "
                           f"{span:g} {motion.units}: values exceed 2^29")

    qhat = np.zeros((F, M, 3), np.int64)                       # what the decoder will rebuild
    root_marker = hier.nodes[0].members[0]
    root, root_q = code_root(u[:, root_marker], opts, grid)
    qhat[:, root_marker] = root_q
    coded: list[NodeCode] = []
    n_nodes = len(hier.nodes)
    for i in range(1, n_nodes):
        node = hier.nodes[i]
        nc = code_node(i, node, hier.nodes[node.parent].ref, u, qhat, opts, grid,
                       addh / grid.step)
        qhat[:, list(node.members)] = nc.decoded
        coded.append(nc)
        report.nodes.append(nc.report)
        if progress is not None:
            progress(i / (n_nodes - 1) if n_nodes > 1 else 1.0, node.name)

    bits = int(np.abs(qhat).max(initial=0)).bit_length() + 1
    if bits > MAX_BITS:
        raise EncoderError("decoded values exceed the 31-bit range of spec §4.4; use a coarser "
                           "grid")
    data = container.build(file_records(motion, opts, hier, grid, root, coded, bits))
    report.chunk_bytes = container.chunk_sizes(data)
    report.file_bytes = len(data)
    report.seconds = time.perf_counter() - t0
    return data, report


def encode(motion: Motion, **options: Any) -> bytes:
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
