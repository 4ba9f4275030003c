"""The MPZ 1.0 decoder: spec §6, step by step.

Strategy: :func:`read_stream` turns bytes into a validated :class:`Stream`
(framing via :mod:`mpz.container`, then every cross-chunk rule of §3.4 and §4
with limits of §8 checked before allocation). :func:`decode_integers` runs
the integer decoding process of §6.1-§6.7, which every conforming decoder must
reproduce exactly; :func:`decode` adds the one floating-point step (§6.8).
Only :class:`mpz.errors.MPZError` subclasses escape.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math

from construct import Container
import numpy as np

from mpz.container import (
    MAX_FRAMES,
    MAX_MARKERS,
    MAX_PATTERN_LENGTH,
    MAX_PATTERN_SAMPLES,
    MAX_SAMPLES,
    MAX_SMOOTHING,
    MAX_SUMMARY_LEVELS,
    MAX_SUMMARY_VALUES,
    Chunk,
    parse,
)
from mpz.entropy import BlockDecoder
from mpz.errors import FormatError, LimitExceededError, MPZError, UnsupportedVersionError
from mpz.keyframe import decode_payload as decode_keyframes
from mpz.motion import Motion
from mpz.normalize import denormalize, segment_starts
from mpz.predict import reconstruct
from mpz.smooth import smooth_boundaries
from mpz.spec.grammar import VERSION_MAJOR

#: §4.1 unit codes
UNIT_CODES = {0: "", 1: "mm", 2: "cm", 3: "m", 4: "in"}
UNIT_FROM_NAME = {v: k for k, v in UNIT_CODES.items()}
FLAG_RESIDUAL = 0x0001
ROOT_PARENT = 0xFFFF


def _absent_patt(i: int) -> Chunk:
    """The PATT an encoder left out means K = 0 (§3.4)."""
    return Chunk("PATT", Container(node=i, pattern_count=0, length=1, scale=1, order=0, coded=b""),
                 offset=None)


@dataclass
class Stream:
    """A validated MPZ file: the chunks, indexed by role."""

    chunks: list
    header: object
    names: list
    nodes: list                      # HIER nodes (construct Containers)
    quant: object
    mask: Chunk | None
    root: Chunk
    patt: dict                       # node -> Chunk
    segs: dict                       # node -> Chunk
    resi: dict                       # node -> Chunk
    summary: Chunk | None = None
    meta: dict = field(default_factory=dict)
    unknown: list = field(default_factory=list)

    @property
    def residual(self) -> bool:
        return bool(self.header.flags & FLAG_RESIDUAL)


def _fail(msg, chunk: Chunk | None = None, section=None, cls=FormatError):
    raise cls(msg, offset=None if chunk is None else chunk.offset,
              chunk=None if chunk is None else chunk.type, section=section)


def _check_header(c: Chunk, max_samples: int):
    h = c.fields
    if h.version_major != VERSION_MAJOR:
        _fail(f"unsupported major version {h.version_major}, this decoder reads {VERSION_MAJOR}",
              c, "§2.1", UnsupportedVersionError)
    if h.flags & ~FLAG_RESIDUAL:
        _fail(f"reserved header flag bits set: 0x{h.flags:04x}", c, "§4.1")
    if not 1 <= h.frame_count <= MAX_FRAMES:
        _fail(f"frame_count {h.frame_count} not in 1..{MAX_FRAMES}", c, "§8", LimitExceededError)
    if not 1 <= h.marker_count <= MAX_MARKERS:
        _fail(f"marker_count {h.marker_count} not in 1..{MAX_MARKERS}", c, "§8", LimitExceededError)
    if h.frame_count * h.marker_count > max_samples:
        _fail(f"frame_count x marker_count = {h.frame_count * h.marker_count} exceeds the limit "
              f"{max_samples}", c, "§8", LimitExceededError)
    if not 1 <= h.node_count <= h.marker_count:
        _fail(f"node_count {h.node_count} not in 1..marker_count ({h.marker_count})", c, "§4.1")
    if not (math.isfinite(h.rate) and h.rate > 0):
        _fail(f"frame rate {h.rate!r} is not finite and positive", c, "§4.1")
    if h.units not in UNIT_CODES:
        _fail(f"unknown units code {h.units}", c, "§4.1")
    if h.error_metric not in (0, 1):
        _fail(f"unknown error metric {h.error_metric}", c, "§4.1")
    if not (math.isfinite(h.error_bound) and h.error_bound >= 0):
        _fail(f"error bound {h.error_bound!r} is not finite and >= 0", c, "§4.1")
    if h.smoothing > MAX_SMOOTHING:
        _fail(f"smoothing half-width {h.smoothing} exceeds {MAX_SMOOTHING}", c, "§4.1")


def _check_names(c: Chunk, M: int) -> list:
    f = c.fields
    if f.count != M:
        _fail(f"MNAM lists {f.count} names for {M} markers", c, "§4.2")
    names = list(f.names)
    seen = set()
    for n in names:
        if not n or "\x00" in n:
            _fail("marker names must be non-empty and contain no NUL", c, "§4.2")
        if n in seen:
            _fail(f"duplicate marker name {n!r}", c, "§4.2")
        seen.add(n)
    return names


def _check_hier(c: Chunk, M: int, N: int) -> list:
    f = c.fields
    if f.count != N:
        _fail(f"HIER lists {f.count} nodes, header says {N}", c, "§4.3")
    owner = np.full(M, -1, np.int64)
    for i, node in enumerate(f.nodes):
        if i == 0:
            if node.parent != ROOT_PARENT or node.member_count != 1:
                _fail("node 0 must be the root: parent 0xFFFF and exactly one member", c, "§4.3")
        elif not node.parent < i:
            _fail(f"node {i} has parent {node.parent}; parents must precede their children", c, "§4.3")
        if node.member_count == 0:
            _fail(f"node {i} has no members", c, "§4.3")
        for m in node.members:
            if m >= M:
                _fail(f"node {i} names marker {m}, but there are {M}", c, "§4.3")
            if owner[m] >= 0:
                _fail(f"marker {m} belongs to nodes {owner[m]} and {i}", c, "§4.3")
            owner[m] = i
        if node.ref not in node.members:
            _fail(f"node {i}: reference marker {node.ref} is not a member", c, "§4.3")
    if (owner < 0).any():
        _fail(f"marker {int(np.argmin(owner))} belongs to no node", c, "§4.3")
    return list(f.nodes)


def _check_quant(c: Chunk):
    q = c.fields
    if not (math.isfinite(q.step) and q.step > 0):
        _fail(f"grid step {q.step!r} is not finite and positive", c, "§4.4")
    if not all(math.isfinite(o) for o in q.offset):
        _fail("grid offsets must be finite", c, "§4.4")
    if not 1 <= q.bits <= 31:
        _fail(f"bits {q.bits} not in 1..31", c, "§4.4")


def read_stream(data: bytes, *, max_samples: int = MAX_SAMPLES) -> Stream:
    """Parse and validate every structural rule of §3 and §4 (no sample decoding).

    Parameters
    ----------
    data : bytes
        A complete MPZ file.
    max_samples : int
        Refuse files with more than this many marker-frames (§8); lower it to
        bound memory further.

    Raises
    ------
    MPZError
        FormatError, ChecksumError, UnsupportedVersionError or
        LimitExceededError, with offset and chunk.
    """
    chunks = parse(data)
    crit = [c for c in chunks if c.critical]
    anc = [c for c in chunks if not c.critical]
    if not chunks or chunks[0].type != "MHDR":
        _fail("the first chunk must be MHDR", chunks[0] if chunks else None, "§3.4")
    hdr_chunk = chunks[0]
    _check_header(hdr_chunk, max_samples)
    h = hdr_chunk.fields
    M, N, F = h.marker_count, h.node_count, h.frame_count
    residual = bool(h.flags & FLAG_RESIDUAL)

    # §3.4 the critical chunks, in order
    it = iter(crit[1:])

    def expect(ctype, optional=False):
        nonlocal pending
        c = pending if pending is not None else next(it, None)
        pending = None
        if c is None:
            _fail(f"missing {ctype} chunk", None, "§3.4")
        if c.type != ctype:
            if optional:
                pending = c
                return None
            _fail(f"expected a {ctype} chunk here, found {c.type}", c, "§3.4")
        return c

    pending = None
    names = _check_names(expect("MNAM"), M)
    hier_chunk = expect("HIER")
    nodes = _check_hier(hier_chunk, M, N)
    quant_chunk = expect("QUNT")
    _check_quant(quant_chunk)
    mask = expect("MASK", optional=True)
    root = expect("ROOT")
    if root.fields.order > 2:
        _fail(f"predictor order {root.fields.order} not in 0..2", root, "§4.6")
    patt, segs, resi = {}, {}, {}
    for i in range(1, N):
        n_i = nodes[i].member_count
        # §3.4: with a residual layer, PATT may be left out when the node has no patterns
        p = expect("PATT", optional=residual)
        if p is None:
            p = _absent_patt(i)
        pf = p.fields
        if pf.node != i:
            _fail(f"PATT for node {pf.node} where node {i} was expected", p, "§3.4")
        if pf.pattern_count and not 1 <= pf.length <= MAX_PATTERN_LENGTH:
            _fail(f"pattern length {pf.length} not in 1..{MAX_PATTERN_LENGTH}", p, "§8",
                  LimitExceededError)
        if pf.pattern_count * pf.length * n_i > MAX_PATTERN_SAMPLES:
            _fail(f"{pf.pattern_count} patterns x {pf.length} frames x {n_i} markers exceeds "
                  f"{MAX_PATTERN_SAMPLES}", p, "§8", LimitExceededError)
        if pf.scale < 1 or pf.order > 2:
            _fail(f"pattern scale {pf.scale} / order {pf.order} out of range", p, "§4.7")
        patt[i] = p
        if pf.pattern_count:
            s = expect("SEGS")
            if s.fields.node != i:
                _fail(f"SEGS for node {s.fields.node} where node {i} was expected", s, "§3.4")
            if not 1 <= s.fields.segment_count <= F:
                _fail(f"segment_count {s.fields.segment_count} not in 1..{F}", s, "§4.8",
                      LimitExceededError)
            segs[i] = s
        elif not residual:
            _fail(f"node {i} has no patterns and the file has no residual layer", p, "§4.7")
        if residual:
            r = expect("RESI")
            if r.fields.node != i:
                _fail(f"RESI for node {r.fields.node} where node {i} was expected", r, "§3.4")
            if r.fields.order > 2 or r.fields.scale < 1 or r.fields.base > 2:
                _fail(f"residual base {r.fields.base} / order {r.fields.order} / scale "
                      f"{r.fields.scale} out of range", r, "§4.9")
            if r.fields.base >= 1 and pf.pattern_count:
                _fail(f"node {i}: an absolute residual layer (base {r.fields.base}) needs "
                      f"pattern_count 0", r, "§4.9")
            if r.fields.base == 2 and r.fields.order != 0:
                _fail(f"node {i}: a key-frame layer (base 2) has order 0, got {r.fields.order}",
                      r, "§4.9")
            resi[i] = r
    end = expect("MEND")
    extra = pending if pending is not None else next(it, None)
    if extra is not None:
        _fail(f"unexpected {extra.type} chunk", extra, "§3.4")
    del end

    summary, meta, unknown, seen_meta = None, {}, [], False
    for c in anc:
        if c.type == "smry":
            if summary is not None:
                _fail("more than one smry chunk", c, "§4.10")
            _check_summary(c, F, M)
            summary = c
        elif c.type == "meta":
            if seen_meta:
                _fail("more than one meta chunk", c, "§4.11")
            seen_meta = True
            for e in c.fields.entries:
                if not e.key:
                    _fail("empty metadata key", c, "§4.11")
                meta[e.key] = e.value
        else:
            unknown.append(c)
    return Stream(chunks, h, names, nodes, quant_chunk.fields, mask, root, patt, segs, resi,
                  summary, meta, unknown)


def _check_summary(c: Chunk, F: int, M: int):
    f = c.fields
    if f.space not in (0, 1):
        _fail(f"unknown summary space {f.space}", c, "§4.10")
    if f.space == 0 and f.dims != 3 * M:
        _fail(f"position summary has {f.dims} dims, expected {3 * M}", c, "§4.10")
    if not 1 <= f.level_count <= MAX_SUMMARY_LEVELS:
        _fail(f"summary level count {f.level_count} not in 1..{MAX_SUMMARY_LEVELS}", c, "§4.10")
    total = 0
    for lv in f.levels:
        total += lv.k * f.dims
        if not 1 <= lv.k <= F:
            _fail(f"summary level with k = {lv.k} for {F} frames", c, "§4.10")
        if not (math.isfinite(lv.step) and lv.step > 0 and math.isfinite(lv.wssse) and lv.wssse >= 0):
            _fail("summary step must be > 0 and wssse >= 0, both finite", c, "§4.10")
        starts = np.frombuffer(lv.starts, "<u4")
        if starts[0] != 0 or (np.diff(starts.astype(np.int64)) <= 0).any() or starts[-1] >= F:
            _fail("summary starts must begin at 0, increase strictly and stay below F", c, "§4.10")
    if total > MAX_SUMMARY_VALUES:
        _fail(f"summary holds {total} values, limit {MAX_SUMMARY_VALUES}", c, "§8", LimitExceededError)


# ------------------------------------------------------------ §6 decoding --
def _rc(c: Chunk) -> BlockDecoder:
    return BlockDecoder(c.fields.coded, chunk=c.type, offset=c.offset)


def decode_mask(s: Stream) -> np.ndarray:
    """§6.1 the validity mask: True where a sample is valid."""
    F, M = s.header.frame_count, s.header.marker_count
    if s.mask is None:
        return np.ones((F, M), bool)
    dec = _rc(s.mask)
    flags = dec.block(F, M, 1, signed=False)[:, :, 0]
    dec.close()
    if (flags > 1).any():
        _fail("gap flags must be 0 or 1", s.mask, "§4.5")
    return flags == 0


def decode_root(s: Stream) -> np.ndarray:
    """§6.2 the root track: ``[F, 3]`` integers."""
    F = s.header.frame_count
    dec = _rc(s.root)
    e = dec.block(F, 1)
    dec.close()
    return reconstruct(e, s.root.fields.order, chunk="ROOT", offset=s.root.offset)[:, 0]


def decode_patterns(s: Stream, i: int) -> np.ndarray:
    """§6.3 the K patterns of node i, ``[K, L, n_i, 3]`` in grid units."""
    c = s.patt[i]
    f = c.fields
    n_i = s.nodes[i].member_count
    K, L = f.pattern_count, f.length
    dec = _rc(c)
    e = dec.block(K * L, n_i, period=L)
    dec.close()
    v = reconstruct(e, f.order, period=L, chunk="PATT", offset=c.offset)
    _layer_range(v, f.scale, c)
    return (v * f.scale).reshape(K, L, n_i, 3)


def decode_segments(s: Stream, i: int) -> tuple[np.ndarray, np.ndarray]:
    """§6.3 (pattern index, original frame count) of every segment of node i."""
    c = s.segs[i]
    K, L = s.patt[i].fields.pattern_count, s.patt[i].fields.length
    S = c.fields.segment_count
    dec = _rc(c)
    v = dec.block(S, 1, 2)[:, 0]
    dec.close()
    index, counts = v[:, 0], v[:, 1] + L
    if (index < 0).any() or (index >= K).any():
        bad = int(index[(index < 0) | (index >= K)][0])
        # spec §4.8: "A decoder MUST reject a SEGS chunk whose pattern index
        # is not less than the pattern count of its node."
        _fail(f"pattern index {bad} out of range 0..{K - 1}", c, "§4.8")
    if (counts < 1).any():
        _fail(f"segment frame count {int(counts.min())} < 1", c, "§4.8")
    if int(counts.sum()) != s.header.frame_count:
        _fail(f"segment frame counts add up to {int(counts.sum())}, not {s.header.frame_count}",
              c, "§4.8")
    return index, counts


def node_prediction(s: Stream, i: int) -> np.ndarray:
    """§6.3-§6.4 the pattern layer P of node i, ``[F, n_i, 3]``."""
    F, n_i = s.header.frame_count, s.nodes[i].member_count
    if s.patt[i].fields.pattern_count == 0:
        return np.zeros((F, n_i, 3), np.int64)
    patterns = decode_patterns(s, i)
    index, counts = decode_segments(s, i)
    p = denormalize(patterns, index, counts)
    return smooth_boundaries(p, segment_starts(counts), s.header.smoothing)


def decode_residual(s: Stream, i: int) -> np.ndarray:
    """§6.5 the residual layer of node i, ``[F, n_i, 3]``, already multiplied by g."""
    c = s.resi[i]
    F, n_i = s.header.frame_count, s.nodes[i].member_count
    dec = _rc(c)
    if c.fields.base == 2:
        # §6.5: key frames, linearly interpolated
        w = decode_keyframes(dec, F, n_i, chunk="RESI", offset=c.offset)
        dec.close()
    else:
        e = dec.block(F, n_i)
        dec.close()
        w = reconstruct(e, c.fields.order, chunk="RESI", offset=c.offset)
    _layer_range(w, c.fields.scale, c)
    return w * c.fields.scale


LAYER_LIMIT = 1 << 36


def _layer_range(v, scale, c: Chunk):
    """§6.7 rule 1: scaled pattern and residual values stay below 2^36 in magnitude."""
    peak = int(np.abs(v).max(initial=0))
    if peak >= LAYER_LIMIT or peak * scale >= LAYER_LIMIT:
        _fail(f"scaled {c.type} value {peak} x {scale} reaches 2^36", c, "§6.7")


def decode_integers(s: Stream) -> np.ndarray:
    """§6.1-§6.7: the integer layer q, ``[F, M, 3]`` int64 (gaps included)."""
    F, M = s.header.frame_count, s.header.marker_count
    q = np.zeros((F, M, 3), np.int64)
    root_marker = s.nodes[0].members[0]
    q[:, root_marker] = decode_root(s)
    for i in range(1, len(s.nodes)):
        node = s.nodes[i]
        members = list(node.members)
        if s.residual and s.resi[i].fields.base >= 1:
            # §6.6: an absolute residual layer carries the members' grid values directly
            q[:, members] = decode_residual(s, i)
            continue
        local = node_prediction(s, i)
        if s.residual:
            local = local + decode_residual(s, i)
        ref = s.nodes[node.parent].ref
        # §6.6: members are coded relative to the reference marker of the parent node
        q[:, members] = local + q[:, ref][:, None, :]
    limit = 1 << s.quant.bits
    if np.abs(q).max(initial=0) >= limit:
        _fail(f"decoded value exceeds the declared range |q| < 2^{s.quant.bits}", None, "§6.7")
    return q


def to_positions(s: Stream, q: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """§6.8: x = offset[a] + q * step in binary64, NaN at gaps."""
    step = np.float64(s.quant.step)
    offset = np.asarray(s.quant.offset, dtype=np.float64)
    x = q.astype(np.float64) * step
    x = x + offset
    x[~valid] = np.nan
    return x


def decode(data: bytes, *, max_samples: int = MAX_SAMPLES) -> Motion:
    """Decode an MPZ file into a :class:`mpz.Motion`.

    Parameters
    ----------
    data : bytes
        The whole file.
    max_samples : int, optional
        Reject files declaring more than this many marker-frames (§8).

    Returns
    -------
    Motion
        Positions float64 ``[F, M, 3]`` in the file's units, gaps restored.

    Raises
    ------
    MPZError
        Only subclasses of it, for any invalid input.

    Examples
    --------
    >>> import mpz
    >>> from mpz.synth import generate
    >>> m = generate("walk", frames=60)
    >>> out = mpz.decode(mpz.encode(m, max_error=1.0))
    >>> bool(mpz.max_error(m, out) <= 1.0)
    True
    """
    try:
        s = read_stream(data, max_samples=max_samples)
        valid = decode_mask(s)
        q = decode_integers(s)
        x = to_positions(s, q, valid)
    except MPZError:
        raise
    except (ValueError, IndexError, OverflowError, MemoryError) as exc:  # defence in depth
        raise FormatError(f"invalid data: {type(exc).__name__}: {exc}") from None
    meta = dict(s.meta)
    return Motion(x, s.names, float(s.header.rate), UNIT_CODES[s.header.units], valid, meta)
