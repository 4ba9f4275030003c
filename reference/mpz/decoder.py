"""The MPZ 1.x decoder: spec §6, step by step.

Strategy: :func:`read_stream` turns bytes into a validated :class:`Stream`: framing via
:mod:`mpz.container`, then the §3.4 order of the critical chunks, each chunk checked by
its own entry in :mod:`mpz.chunks` (which holds the §4 rules) with the limits of §8
checked before anything is allocated. :func:`decode_layers` runs the integer decoding
process of §6.1-§6.7, which every conforming decoder must reproduce exactly;
:func:`decode` adds the one floating-point step (§6.8). The 1.1 ancillary chunks decode
inside their own checks, at step 3 (§6 lets a decoder reorder the steps): §6.9 in
:mod:`mpz.chunks.c3d` with :func:`mpz.c3dcodec.decode_channels` and
:func:`mpz.c3dcodec.decode_model_axes`, §6.10 in
:mod:`mpz.chunks.skeleton` with :func:`mpz.channels.decode`.

Memory (§8, the budget this decoder promises): besides q, one node's decoded block at a
time; de-normalisation, smoothing, composition and §6.8 go a block of frames at a time
(:data:`BLOCK_SAMPLES`), and :func:`decode` writes the output over q's memory.

Only the checks that the spec names raise :class:`mpz.errors.MPZError`; any other
exception from in here is a bug in this decoder and propagates unchanged (as h11 and
zstd's educational decoder keep "bad input" apart from "cannot happen").
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Generic, TypeVar

import construct
import numpy as np
from numpy.typing import NDArray

from mpz.chunks import (
    CHUNKS,
    Context,
    Hier,
    HierNode,
    Mask,
    Mend,
    Meta,
    Mhdr,
    Mnam,
    Patt,
    Qunt,
    Record,
    Resi,
    Root,
    Segs,
    Smrc,
    Smry,
)
from mpz.container import Chunk, locate, parse
from mpz.entropy import BlockDecoder
from mpz.errors import FormatError, MPZError
from mpz.extensions import EXTENSIONS
from mpz.format import LAYER_LIMIT, MAX_SAMPLES, VERSION_MINOR, ResidualBase, unit_name
from mpz.keyframe import decode_payload_peak as decode_keyframes
from mpz.motion import Motion
from mpz.normalize import denormalize, segment_starts
from mpz.predict import reconstruct
from mpz.smooth import smooth_frames, window

R = TypeVar("R", bound=Record)
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class Located(Generic[R]):
    """A checked chunk record and where its chunk starts (None: a PATT left out, §3.4)."""

    record: R
    offset: int | None


@dataclass
class Stream:
    """A validated MPZ file: the records of its chunks, by role (spec §3.4)."""

    chunks: list[Chunk]
    header: Mhdr
    names: list[str]
    nodes: tuple[HierNode, ...]
    quant: Qunt
    mask: Located[Mask] | None
    root: Located[Root]
    patt: dict[int, Located[Patt]]       # node -> its PATT (K = 0 when left out)
    segs: dict[int, Located[Segs]]       # node -> its SEGS (nodes with patterns)
    resi: dict[int, Located[Resi]]       # node -> its RESI (files with a residual layer)
    #: the summary chunk: smry (§4.10) or smrc (§4.15, 1.1), at most one of the two (§3.4)
    summary: Located[Smry] | Located[Smrc] | None = None
    meta: dict[str, str] = field(default_factory=dict)
    unknown: list[Chunk] = field(default_factory=list)
    #: checked records of the ancillary chunks that extensions own (mpz.extensions), by type
    extras: dict[str, list[Record]] = field(default_factory=dict)

    @property
    def residual(self) -> bool:
        return self.header.residual


class _Order:
    """The critical chunks after MHDR, taken in the §3.4 order one at a time."""

    def __init__(self, chunks: list[Chunk]) -> None:
        self._it = iter(chunks)
        self._pending: Chunk | None = None

    def _next(self) -> Chunk | None:
        c, self._pending = self._pending, None
        return c if c is not None else next(self._it, None)

    def take(self, cls: type[R], ctx: Context, *, optional: bool = False) -> Located[R] | None:
        """The next chunk, which must be of type ``cls`` (or, if optional, is put back)."""
        c = self._next()
        if c is None:  # R-3.4-2
            raise FormatError(f"missing {cls.TYPE} chunk", section="§3.4")
        if c.type != cls.TYPE:  # R-2.4-4, R-3.4-2, R-3.4-3, R-3.4-5, R-3.4-6, R-3.4-8
            if optional:
                self._pending = c
                return None
            # a RESI where the header says there is no residual layer: the writer's
            # likely mistake is the flag, not the order (a clean-room encoder, stop 60)
            hint = ("; RESI chunks belong only to a file whose MHDR flags bit 0 (the "
                    "residual layer, §4.1) is set, and this one's is not"
                    if c.type == "RESI" and not ctx.header.residual else "")
            raise FormatError(f"expected a {cls.TYPE} chunk here, found {c.type}{hint}",
                              offset=c.offset, chunk=c.type, section="§3.4")
        return _checked(c, cls, ctx)

    def need(self, cls: type[R], ctx: Context) -> Located[R]:
        got = self.take(cls, ctx)
        assert got is not None          # take() without optional never returns None
        return got

    def rest(self) -> Chunk | None:
        return self._next()


def _checked(c: Chunk, cls: type[R], ctx: Context) -> Located[R]:
    """Run the chunk's own § checks (mpz.chunks), locating any violation at the chunk."""
    rec = c.record
    assert isinstance(rec, cls)          # scan() parsed every chunk of a known type
    try:
        rec.check(ctx)
    except MPZError as exc:
        raise locate(exc, c) from None
    return Located(rec, c.offset)


def read_stream(data: bytes, *, max_samples: int = MAX_SAMPLES,
                minor: int = VERSION_MINOR) -> Stream:
    """Parse and validate every structural rule of §3 and §4 (no sample decoding).

    Parameters
    ----------
    data : bytes
        A complete MPZ file.
    max_samples : int
        Refuse files with more than this many marker-frames (§8); lower it to
        bound memory further (below MAX_SAMPLES it also lowers MAX_ANALOG_SAMPLES to 4x
        and MAX_CHANNEL_SAMPLES to 1x it: :meth:`mpz.chunks.Context.limit`).
    minor : int
        Validate and read as a decoder of 1.0 .. 1.``minor`` (§2.1): the chunk types of
        later minor versions are unknown ancillary chunks, skipped after their frame and CRC
        are checked (§2.3). ``minor=0`` is a 1.0 decoder (the conformance runner's
        ``--implements 1.0``).

    Raises
    ------
    MPZError
        FormatError, ChecksumError, UnsupportedVersionError or
        LimitExceededError, with offset and chunk.
    """
    # the unknown ancillary chunks are checked and counted, not kept (§8: nothing per
    # skipped chunk)
    chunks = parse(data, minor=minor, keep_unknown=False)
    # R-3.4-1
    if not chunks or chunks[0].type != "MHDR":
        first = chunks[0] if chunks else None
        raise FormatError("the first chunk must be MHDR", section="§3.4",
                          offset=None if first is None else first.offset,
                          chunk=None if first is None else first.type)
    assert isinstance(chunks[0].record, Mhdr)
    ctx = Context(chunks[0].record, max_samples)
    h = _checked(chunks[0], Mhdr, ctx).record

    # §3.4 the critical chunks, in order
    order = _Order([c for c in chunks[1:] if c.critical])
    names = list(order.need(Mnam, ctx).record.names)
    nodes = order.need(Hier, ctx).record.nodes
    ctx = Context(h, max_samples, nodes)
    quant = order.need(Qunt, ctx).record
    mask = order.take(Mask, ctx, optional=True)
    root = order.need(Root, ctx)
    patt: dict[int, Located[Patt]] = {}
    segs: dict[int, Located[Segs]] = {}
    resi: dict[int, Located[Resi]] = {}
    for i in range(1, h.node_count):
        node_ctx = Context(h, max_samples, nodes, i)
        # §3.4: with a residual layer, PATT may be left out when the node has no patterns
        # R-3.4-8
        p = order.take(Patt, node_ctx, optional=h.residual)
        patt[i] = p if p is not None else Located(Patt.absent(i), None)
        node_ctx = Context(h, max_samples, nodes, i, patt[i].record)
        if patt[i].record.pattern_count:  # R-3.4-5
            segs[i] = order.need(Segs, node_ctx)
        if h.residual:  # R-3.4-6
            resi[i] = order.need(Resi, node_ctx)
    order.need(Mend, ctx)
    extra = order.rest()
    # R-3.4-3
    if extra is not None:
        raise FormatError(f"unexpected {extra.type} chunk", offset=extra.offset,
                          chunk=extra.type, section="§3.4")

    # ancillary chunks: one summary (smry or smrc, §3.4) and one meta at most (§4.10, §4.11,
    # §4.15); the chunks extensions own are checked and kept for them; unknown types, and
    # those of a minor version after ``minor``, are kept, unread (§2.3)
    summary: Located[Smry] | Located[Smrc] | None = None
    meta: dict[str, str] = {}
    unknown: list[Chunk] = []
    extras: dict[str, list[Record]] = {}
    seen: set[str] = set()
    for c in chunks:
        if c.critical:
            continue
        if c.type not in CHUNKS or CHUNKS[c.type].MINOR > minor:
            unknown.append(c)
            continue
        if c.type in ("smry", "smrc", "meta"):  # R-2.3-4
            role = "meta" if c.type == "meta" else "summary"
            # R-3.4-10, R-4.15-1
            if c.type in seen:
                raise FormatError(f"more than one {c.type} chunk", offset=c.offset,
                                  chunk=c.type, section="§3.4")
            # R-4.15-1
            if role in seen:
                raise FormatError("a file holds at most one summary chunk: smry or smrc, not "
                                  "both", offset=c.offset, chunk=c.type, section="§4.15")
            seen |= {c.type, role}
            if c.type == "smry":
                summary = _checked(c, Smry, ctx)
            elif c.type == "smrc":
                summary = _checked(c, Smrc, ctx)
            else:
                meta = _checked(c, Meta, ctx).record.as_dict()
        else:
            # the records extensions own may need the whole chunk list (sets of chunks, §4.13)
            actx = Context(h, max_samples, nodes, types=tuple(x.type for x in chunks))
            extras.setdefault(c.type, []).append(_checked(c, CHUNKS[c.type], actx).record)
    return Stream(chunks, h, names, nodes, quant, mask, root, patt, segs, resi, summary, meta,
                  unknown, extras)


# ------------------------------------------------------------ §6 decoding --
def coded_field_offset(cls: type[Record]) -> int:
    """Where the ``coded`` field starts in a payload of ``cls``: after the fixed-size fields
    that precede it in the grammar (MASK 0, ROOT 1, PATT 9, SEGS 6, RESI 6; §4.5-§4.9).
    Worked out once per class: construct's sizeof took 20 us a coded field, a tenth of a
    short TRC's decode outside the range decoder (issue 15.1)."""
    at = _CODED_AT.get(cls)
    if at is None:
        subcons = list(cls.GRAMMAR.subcons)
        end = [sc.name for sc in subcons].index("coded")
        at = _CODED_AT[cls] = int(construct.Struct(*subcons[:end]).sizeof())
    return at


#: coded_field_offset of each record class asked for
_CODED_AT: dict[type, int] = {}


def _coded(c: Located[Mask] | Located[Root] | Located[Patt] | Located[Segs] | Located[Resi]
           ) -> BlockDecoder:
    """The range decoder of a chunk's coded field; its errors carry the offset of the failing
    byte in the file (chunk start + 8-byte frame header + the field's place in the payload)."""
    at = None if c.offset is None else c.offset + 8 + coded_field_offset(type(c.record))
    return BlockDecoder(c.record.coded, chunk=c.record.TYPE, offset=at)


def decode_mask(s: Stream) -> NDArray[np.bool_]:
    """§6.1 the validity mask: True where a sample is valid."""
    F, M = s.header.frame_count, s.header.marker_count
    if s.mask is None:
        return np.ones((F, M), bool)
    dec = _coded(s.mask)
    flags = dec.block(F, M, 1, signed=False)[:, :, 0]
    dec.close()
    # R-2.4-25
    if (flags > 1).any():
        raise FormatError("gap flags must be 0 or 1", offset=s.mask.offset, chunk="MASK",
                          section="§4.5")
    return np.asarray(flags == 0)


#: marker-frames per block of the §6.3-§6.8 work: temporaries of 2^18 x 3 int64 (6 MiB) each,
#: so that the peak memory is set by q and the output, never by the de-normalised or smoothed
#: layers of a node (spec §8: a SEGS chunk of a few bytes can stretch one pattern over 2^26
#: marker-frames)
BLOCK_SAMPLES = 1 << 18


def frame_blocks(F: int, n: int) -> Iterator[tuple[int, int]]:
    """Consecutive frame ranges ``(t0, t1)`` covering ``0 .. F - 1``, each about
    :data:`BLOCK_SAMPLES` marker-frames for ``n`` markers (at least one frame)."""
    step = max(1, BLOCK_SAMPLES // max(1, n))
    for t0 in range(0, F, step):
        yield t0, min(F, t0 + step)


def decode_root(s: Stream) -> IntArray:
    """§6.2 the root track: ``[F, 3]`` integers."""
    F = s.header.frame_count
    dec = _coded(s.root)
    e = dec.block(F, 1)
    dec.close()
    return reconstruct(e, s.root.record.order, chunk="ROOT", offset=s.root.offset,
                       inplace=True)[:, 0]


def decode_patterns(s: Stream, i: int) -> IntArray:
    """§6.3 the K patterns of node i, ``[K, L, n_i, 3]`` in grid units."""
    c = s.patt[i]
    f = c.record
    n_i = s.nodes[i].member_count
    K, L = f.pattern_count, f.length
    dec = _coded(c)
    e = dec.block(K * L, n_i, period=L)
    dec.close()
    v = reconstruct(e, f.order, period=L, chunk="PATT", offset=c.offset, inplace=True)
    _layer_range(v, f.scale, c)
    v *= f.scale                        # below 2^36 in magnitude after the check
    return v.reshape(K, L, n_i, 3)


def decode_segments(s: Stream, i: int) -> tuple[IntArray, IntArray]:
    """§6.3 (pattern index, original frame count) of every segment of node i."""
    c = s.segs[i]
    K, L = s.patt[i].record.pattern_count, s.patt[i].record.length
    S = c.record.segment_count
    dec = _coded(c)
    v = dec.block(S, 1, 2)[:, 0]
    dec.close()
    index, counts = v[:, 0], v[:, 1] + L

    def fail(message: str) -> FormatError:
        return FormatError(message, offset=c.offset, chunk="SEGS", section="§4.8")

    # R-2.4-30
    if (index < 0).any() or (index >= K).any():
        bad = int(index[(index < 0) | (index >= K)][0])
        # spec §4.8: "A decoder MUST reject a SEGS chunk whose pattern index
        # is not less than the pattern count of its node."
        raise fail(f"pattern index {bad} out of range 0..{K - 1}")
    # R-2.4-31
    if (counts < 1).any():
        raise fail(f"segment frame count {int(counts.min())} < 1")
    # R-2.4-31
    if int(counts.sum()) != s.header.frame_count:
        raise fail(f"segment frame counts add up to {int(counts.sum())}, not "
                   f"{s.header.frame_count}")
    return index, counts


@dataclass(frozen=True)
class PatternLayer:
    """§6.3-§6.4 the pattern layer P' of one node, produced a block of frames at a time.

    Holds only the patterns and the segment table; :meth:`frames` de-normalises and smooths
    the frames asked for, so no array of the node's F x n_i samples is ever built.
    """

    patterns: IntArray                  # Pat [K, L, n_i, 3], scaled
    index: IntArray                     # pattern of each segment [S]
    counts: IntArray                    # frames of each segment [S]
    starts: IntArray                    # first frame of each segment [S]
    frame_count: int                    # F
    smoothing: int                      # h

    def frames(self, t0: int, t1: int) -> IntArray:
        """P' for frames ``t0 .. t1 - 1``: ``[t1 - t0, n_i, 3]``."""
        lo, hi = window(self.frame_count, self.smoothing, (t0, t1))
        p = denormalize(self.patterns, self.index, self.counts, frames=(lo, hi),
                        starts=self.starts)
        return smooth_frames(p, lo, self.starts, self.smoothing, self.frame_count, (t0, t1))


def pattern_layer(s: Stream, i: int) -> PatternLayer | None:
    """§6.3-§6.4 node i's pattern layer (None for K = 0, where P = 0): decodes and checks
    PATT and SEGS; the samples come from :meth:`PatternLayer.frames`."""
    if s.patt[i].record.pattern_count == 0:
        return None
    patterns = decode_patterns(s, i)
    index, counts = decode_segments(s, i)
    return PatternLayer(patterns, index, counts, segment_starts(counts), s.header.frame_count,
                        s.header.smoothing)


def node_prediction(s: Stream, i: int) -> IntArray:
    """§6.3-§6.4 the pattern layer P' of node i, ``[F, n_i, 3]``, as one array (tests and
    tools; the decoder itself composes it a block at a time, :func:`decode_integers`)."""
    F, n_i = s.header.frame_count, s.nodes[i].member_count
    layer = pattern_layer(s, i)
    out = np.zeros((F, n_i, 3), np.int64)
    if layer is not None:
        for t0, t1 in frame_blocks(F, n_i):
            out[t0:t1] = layer.frames(t0, t1)
    return out


def decode_residual(s: Stream, i: int, *, out: IntArray | None = None) -> IntArray:
    """§6.5 the residual layer of node i, ``[F, n_i, 3]``, already multiplied by g.

    A key-frame layer (base 2) can instead be rebuilt straight into q: with ``out`` (q,
    ``[F, M, 3]``) its members' columns receive R and ``out`` is returned.
    """
    c = s.resi[i]
    F, n_i = s.header.frame_count, s.nodes[i].member_count
    dec = _coded(c)
    g = c.record.scale
    if c.record.base == ResidualBase.KEYFRAMES:
        # §6.5: key frames, linearly interpolated
        members = np.asarray(s.nodes[i].members, np.intp)
        w, peak = decode_keyframes(dec, F, n_i, chunk="RESI", offset=c.offset, out=out,
                                   columns=None if out is None else members)
        dec.close()
        # §6.7 rule 1 on every value of the layer: its peak is its largest key's
        _check_peak(peak, g, c)
        if out is None:
            w *= g
            return w
        # R = x g, a block of frames at a time
        if g != 1:
            for t0, t1 in frame_blocks(F, n_i):
                out[t0:t1, members] *= g
        return out
    e = dec.block(F, n_i)
    dec.close()
    w = reconstruct(e, c.record.order, chunk="RESI", offset=c.offset, inplace=True)
    _layer_range(w, g, c)
    if g != 1:                          # (x 1 would be a pass over the layer that changes nothing)
        w *= g                          # below 2^36 in magnitude after the check
    return w


def _peak(v: IntArray) -> int:
    """max |v|, a block of rows at a time."""
    per_row = max(1, v[0].size // 3 if v.shape[0] else 1)
    peak = 0
    for t0, t1 in frame_blocks(v.shape[0], per_row):
        blk = v[t0:t1]
        if blk.size:                    # max |v| as max(max v, -min v): no |v| array
            peak = max(peak, int(blk.max()), -int(blk.min()))
    return peak


def _layer_range(v: IntArray, scale: int, c: Located[Patt] | Located[Resi]) -> None:
    """§6.7 rule 1: scaled pattern and residual values stay below 2^36 in magnitude.

    Every value of the layer is checked (all K patterns, used or not; gap samples too),
    and the unscaled peak first: the product is formed only once |v| < 2^36 (§1.1), as a
    fixed-width decoder must (here Python integers could not overflow anyway).
    """
    _check_peak(_peak(v), scale, c)


def _check_peak(peak: int, scale: int, c: Located[Patt] | Located[Resi]) -> None:
    """§6.7 rule 1 for a layer whose largest magnitude is ``peak``."""
    what = f"node {c.record.node} {c.record.TYPE}"
    # R-6.7-1
    if peak >= LAYER_LIMIT:
        raise FormatError(f"{what}: reconstructed value {peak} reaches 2^36 before scaling",
                          offset=c.offset, chunk=c.record.TYPE, section="§6.7")
    # R-6.7-1
    if peak * scale >= LAYER_LIMIT:
        raise FormatError(f"{what}: scaled value {peak} x {scale} = {peak * scale} reaches 2^36",
                          offset=c.offset, chunk=c.record.TYPE, section="§6.7")


def decode_integers(s: Stream) -> IntArray:
    """§6.1-§6.7: the integer layer q, ``[F, M, 3]`` int64 (gaps included).

    Memory (spec §8): besides q, at most one node's decoded residual block (or its
    patterns and segment table) is held at a time; the pattern layer is de-normalised,
    smoothed and composed into q a block of frames at a time (:data:`BLOCK_SAMPLES`).
    """
    F, M = s.header.frame_count, s.header.marker_count
    q = np.zeros((F, M, 3), np.int64)
    root_marker = s.nodes[0].members[0]
    q[:, root_marker] = decode_root(s)
    for i in range(1, len(s.nodes)):
        node = s.nodes[i]
        members = np.asarray(node.members, np.intp)
        n_i = len(members)
        base = s.resi[i].record.base if s.residual else ResidualBase.PARENT
        if base == ResidualBase.KEYFRAMES:
            # §6.6: an absolute residual layer carries the members' grid values directly
            decode_residual(s, i, out=q)
            continue
        if base == ResidualBase.ABSOLUTE:
            r = decode_residual(s, i)
            for t0, t1 in frame_blocks(F, n_i):
                q[t0:t1, members] = r[t0:t1]
            continue
        layer = pattern_layer(s, i)
        ref = s.nodes[node.parent].ref
        # §6.6: members are coded relative to the reference marker of the parent node;
        # q = P' + R + q[ref], summed as P' + q[ref] first and R after (exact integers)
        for t0, t1 in frame_blocks(F, n_i):
            at_ref = q[t0:t1, ref][:, None, :]
            q[t0:t1, members] = at_ref if layer is None else layer.frames(t0, t1) + at_ref
        del layer
        if s.residual:
            r = decode_residual(s, i)
            for t0, t1 in frame_blocks(F, n_i):
                q[t0:t1, members] += r[t0:t1]
            del r
    _declared_range(s, q)
    return q


def _declared_range(s: Stream, q: IntArray) -> None:
    """§6.7 rule 2: every |q| < 2^bits, gap samples included.

    Reported at the first node, in node order, that holds a value out of range (its first
    such value by frame, member and axis), located at the chunk that produced that node's
    values: ROOT for the root marker, otherwise the node's RESI (its last layer) or, in a
    file without a residual layer, its PATT.
    """
    limit = 1 << s.quant.bits
    if q.size == 0 or (int(q.max()) < limit and int(q.min()) > -limit):  # R-6.7-3
        return                          # every value in range: no node to report
    for i, node in enumerate(s.nodes):
        members = np.asarray(node.members, np.intp)
        for t0, t1 in frame_blocks(q.shape[0], len(members)):
            blk = q[t0:t1, members]
            if not blk.size or (blk.max() < limit and blk.min() > -limit):  # R-6.7-3
                continue
            mag = np.abs(blk)
            t, m, a = (int(k) for k in np.unravel_index(int(np.argmax(mag >= limit)),
                                                         mag.shape))
            t += t0
            marker = int(members[m])
            c: Located[Root] | Located[Patt] | Located[Resi] = (
                s.root if i == 0 else s.resi[i] if s.residual else s.patt[i])
            raise FormatError(f"node {i}: decoded value {int(q[t, marker, a])} (frame {t}, "
                              f"marker {marker} {s.names[marker]!r}, axis {'xyz'[a]}) is "
                              f"outside the range |q| < 2^{s.quant.bits} that QUNT's "
                              f"bits field ({s.quant.bits}) declares",
                              offset=c.offset, chunk=c.record.TYPE, section="§6.7")


def to_positions(s: Stream, q: IntArray, valid: NDArray[np.bool_], *,
                 out: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """§6.8: x = offset[a] + q * step in binary64, NaN at gaps.

    Computed a block of frames at a time into ``out`` (a new array by default). ``out``
    may be q's own memory (``q.view(np.float64)``): each block is read before it is
    written, so q is turned into the output with no second array of its size (§8).
    """
    step = np.float64(s.quant.step)
    offset = np.asarray(s.quant.offset, dtype=np.float64)
    F, M = q.shape[0], q.shape[1]
    x = np.empty((F, M, 3), np.float64) if out is None else out
    for t0, t1 in frame_blocks(F, M):
        blk = q[t0:t1].astype(np.float64)
        blk *= step                     # the product, rounded to binary64
        blk += offset                   # then the sum, rounded again (no FMA)
        blk[~valid[t0:t1]] = np.nan
        x[t0:t1] = blk
    return x


@dataclass
class Decoded:
    """The exact result of §6.1-§6.7 for one file: the stream, the mask and the integer layer.

    Everything that decodes (``mpz.decode``, ``mpzinfo``, the conformance reference
    decoder, the vector and golden makers) goes through :func:`decode_layers`.
    """

    stream: Stream
    valid: NDArray[np.bool_]
    q: IntArray

    def positions(self) -> NDArray[np.float64]:
        """§6.8 the float output, NaN at gaps."""
        return to_positions(self.stream, self.q, self.valid)

    def motion(self, *, reuse_q: bool = False) -> Motion:
        """The decoded result of §6.8: positions plus names, rate, units and metadata, and
        whatever the extensions' chunks hold (mpz.extensions).

        With ``reuse_q`` the positions are written over q's memory (spec §8: the output
        then costs no memory beyond q's), and ``self.q`` is set to None: the integer layer
        is gone, so this Decoded can give no more positions or motions.
        """
        s = self.stream
        if reuse_q:
            q, self.q = self.q, None    # type: ignore[assignment]  # spent, see above
            x = to_positions(s, q, self.valid, out=q.view(np.float64))
            del q
        else:
            x = self.positions()
        m = Motion(x, s.names, float(s.header.rate), unit_name(s.header.units), self.valid,
                   dict(s.meta))
        for ext in EXTENSIONS:
            mine = {t: s.extras[t] for t in ext.chunk_types if t in s.extras}
            if mine:
                ext.attach(mine, m)
        return m


def decode_layers(data: bytes, *, max_samples: int = MAX_SAMPLES,
                  minor: int = VERSION_MINOR) -> Decoded:
    """Validate ``data`` and run the integer decoding process (§3-§6.7); ``minor`` as in
    :func:`read_stream`.

    Raises
    ------
    MPZError
        For any file the spec says to reject, with offset, chunk and §.
    """
    # R-8-1 (no one check: every check of a rule raises MPZError, nothing else is caught)
    s = read_stream(data, max_samples=max_samples, minor=minor)
    valid = decode_mask(s)
    return Decoded(s, valid, decode_integers(s))


def decode(data: bytes, *, max_samples: int = MAX_SAMPLES,
           minor: int = VERSION_MINOR) -> Motion:
    """Decode an MPZ file into a :class:`mpz.Motion`.

    Parameters
    ----------
    data : bytes
        The whole file.
    max_samples : int, optional
        Reject files declaring more than this many marker-frames (§8), and below
        MAX_SAMPLES more than 4x as many analog words or as many skeleton channel
        values.
    minor : int, optional
        As in :func:`read_stream`: ``0`` decodes as an MPZ 1.0 decoder would.

    Returns
    -------
    Motion
        Positions float64 ``[F, M, 3]`` in the file's units, gaps restored.

    Raises
    ------
    MPZError
        For every file the spec says to reject. Any other exception is a bug in
        this decoder and is not disguised as bad input.

    Examples
    --------
    >>> import mpz
    >>> from mpz.synth import generate
    >>> m = generate("walk", frames=60)
    >>> out = mpz.decode(mpz.encode(m, max_error=1.0))
    >>> bool(mpz.max_error(m, out) <= 1.0)
    True
    """
    return decode_layers(data, max_samples=max_samples, minor=minor).motion(reuse_q=True)
