"""The MPZ 1.0 chunk types (spec §4.1-§4.12), one record class each.

Each class is the whole of its chunk: layout (``GRAMMAR``), § checks (``check``),
build (``dump``) and what mpzinfo shows (``info``). See :mod:`mpz.chunks.base`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import TYPE_CHECKING

import numpy as np

from mpz.chunks.base import Context, Record
from mpz.chunks.base import fail as _fail
from mpz.errors import LimitExceededError, UnsupportedVersionError
from mpz.format import (
    FLAG_RESIDUAL,
    MAX_BITS,
    MAX_FRAMES,
    MAX_MARKERS,
    MAX_ORDER,
    MAX_PATTERN_LENGTH,
    MAX_PATTERN_SAMPLES,
    MAX_SMOOTHING,
    MAX_SUMMARY_LEVELS,
    MAX_SUMMARY_VALUES,
    ROOT_PARENT,
    VERSION_MAJOR,
    ErrorMetric,
    ResidualBase,
    SummarySpace,
    Units,
)
from mpz.spec import grammar

if TYPE_CHECKING:
    from mpz.chunks.summary import Smrc


# ------------------------------------------------------------------- §4.1 MHDR --
@dataclass(frozen=True)
class Mhdr(Record):
    """§4.1 the header: always the first chunk."""

    TYPE = "MHDR"
    SECTION = "§4.1"
    GRAMMAR = grammar.MHDR

    version_major: int
    version_minor: int
    flags: int
    frame_count: int
    marker_count: int
    node_count: int
    rate: float
    units: int
    error_metric: int
    error_bound: float
    smoothing: int

    @property
    def residual(self) -> bool:
        """§4.1 flags bit 0: one RESI chunk per non-root node."""
        return bool(self.flags & FLAG_RESIDUAL)

    def check(self, ctx: Context) -> None:
        if self.version_major != VERSION_MAJOR:  # R-2.1-1, R-2.4-5
            _fail(f"unsupported major version {self.version_major}, this decoder reads "
                  f"{VERSION_MAJOR}", "§2.1", UnsupportedVersionError)
        # R-2.4-6
        if self.flags & ~FLAG_RESIDUAL:
            _fail(f"reserved header flag bits set: 0x{self.flags:04x}", "§4.1")
        F, M = self.frame_count, self.marker_count
        # R-2.4-7, R-8-2
        if not 1 <= F <= MAX_FRAMES:
            _fail(f"frame_count {F} not in 1..{MAX_FRAMES}", "§8", LimitExceededError)
        # R-2.4-8, R-8-2
        if not 1 <= M <= MAX_MARKERS:
            _fail(f"marker_count {M} not in 1..{MAX_MARKERS}", "§8", LimitExceededError)
        # R-2.4-9, R-4.1-1, R-8-2
        if F * M > ctx.max_samples:
            _fail(f"frame_count x marker_count = {F * M} exceeds the limit {ctx.max_samples}",
                  "§8", LimitExceededError)
        # R-2.4-10
        if not 1 <= self.node_count <= M:
            _fail(f"node_count {self.node_count} not in 1..marker_count ({M})", "§4.1")
        # R-2.4-11
        if not (math.isfinite(self.rate) and self.rate > 0):
            _fail(f"frame rate {self.rate!r} is not finite and positive", "§4.1")
        if self.units not in set(Units):  # R-2.4-12
            _fail(f"unknown units code {self.units}", "§4.1")
        # R-2.4-13
        if self.error_metric not in set(ErrorMetric):
            _fail(f"unknown error metric {self.error_metric}", "§4.1")
        # R-2.4-14
        if not (math.isfinite(self.error_bound) and self.error_bound >= 0):
            _fail(f"error bound {self.error_bound!r} is not finite and >= 0", "§4.1")
        # R-2.4-15
        if self.smoothing > MAX_SMOOTHING:
            _fail(f"smoothing half-width {self.smoothing} exceeds {MAX_SMOOTHING}", "§4.1")


# ------------------------------------------------------------------- §4.2 MNAM --
@dataclass(frozen=True)
class Mnam(Record):
    """§4.2 the marker names, front-coded UTF-8."""

    TYPE = "MNAM"
    SECTION = "§4.2"
    GRAMMAR = grammar.MNAM

    count: int
    names: tuple[str, ...]

    def check(self, ctx: Context) -> None:
        M = ctx.header.marker_count
        # R-4.2-1
        if self.count != M:
            _fail(f"MNAM lists {self.count} names for {M} markers", "§4.2")
        # §4.2: names are equal only if their bytes are: strict UTF-8 decoding is one-to-one,
        # so comparing the decoded str (no normalisation, no case folding) is the same
        seen: set[str] = set()
        for n in self.names:
            # R-2.4-16
            if not n or "\x00" in n:
                _fail("marker names must be non-empty and contain no NUL", "§4.2")
            # R-2.4-16
            if n in seen:
                _fail(f"duplicate marker name {n!r}", "§4.2")
            seen.add(n)


# ------------------------------------------------------------------- §4.3 HIER --
@dataclass(frozen=True)
class HierNode(Record):
    """§4.3 one node of the body-part hierarchy."""

    GRAMMAR = grammar.HierNode

    parent: int
    ref: int
    member_count: int
    members: tuple[int, ...]
    weights: tuple[float, ...]


@dataclass(frozen=True)
class Hier(Record):
    """§4.3 the body-part hierarchy: node 0 is the root marker, parents come first."""

    TYPE = "HIER"
    SECTION = "§4.3"
    GRAMMAR = grammar.HIER
    NESTED = {"nodes": HierNode}

    count: int
    nodes: tuple[HierNode, ...]

    def check(self, ctx: Context) -> None:
        M, N = ctx.header.marker_count, ctx.header.node_count
        # R-4.3-1
        if self.count != N:
            _fail(f"HIER lists {self.count} nodes, header says {N}", "§4.3")
        owner = np.full(M, -1, np.int64)
        for i, node in enumerate(self.nodes):
            if i == 0:
                # R-2.4-17, R-2.4-18
                if node.parent != ROOT_PARENT or node.member_count != 1:
                    _fail("node 0 must be the root: parent 0xFFFF and exactly one member",
                          "§4.3")
            # R-2.4-17
            elif not node.parent < i:
                _fail(f"node {i} has parent {node.parent}; parents must precede their children",
                      "§4.3")
            # R-2.4-18
            if node.member_count == 0:
                _fail(f"node {i} has no members", "§4.3")
            for m in node.members:
                # R-2.4-19
                if m >= M:
                    _fail(f"node {i} names marker {m}, but there are {M}", "§4.3")
                # R-2.4-19
                if owner[m] >= 0:
                    _fail(f"marker {m} belongs to nodes {owner[m]} and {i}", "§4.3")
                owner[m] = i
            # R-2.4-20
            if node.ref not in node.members:
                _fail(f"node {i}: reference marker {node.ref} is not a member", "§4.3")
        # R-2.4-19
        if (owner < 0).any():
            _fail(f"marker {int(np.argmin(owner))} belongs to no node", "§4.3")


# ------------------------------------------------------------------- §4.4 QUNT --
@dataclass(frozen=True)
class Qunt(Record):
    """§4.4 the quantisation grid: x = offset[a] + q * step."""

    TYPE = "QUNT"
    SECTION = "§4.4"
    GRAMMAR = grammar.QUNT

    step: float
    offset: tuple[float, float, float]
    bits: int

    def check(self, ctx: Context) -> None:
        # R-2.4-21
        if not (math.isfinite(self.step) and self.step > 0):
            _fail(f"grid step {self.step!r} is not finite and positive", "§4.4")
        # R-2.4-22
        if not all(math.isfinite(o) for o in self.offset):
            _fail("grid offsets must be finite", "§4.4")
        # R-2.4-23
        if not 1 <= self.bits <= MAX_BITS:
            _fail(f"bits {self.bits} not in 1..{MAX_BITS}", "§4.4")
        # §4.4 output range (1.0.1): B_a = |o_a| + s * 2^bits, evaluated in binary64 (the
        # product is exact unless it overflows, the sum rounds once), must not be +inf, so
        # every output of §6.8 is finite. Not math.ldexp: it raises where C returns +inf.
        for a, o in enumerate(self.offset):
            # R-2.4-24
            if not math.isfinite(abs(o) + self.step * 2.0 ** self.bits):
                _fail(f"axis {a}: |offset| + step x 2^{self.bits} = |{o!r}| + {self.step!r} x "
                      f"2^{self.bits} is not finite in binary64, so outputs could be infinite",
                      "§4.4")


# ------------------------------------------------------------------- §4.5 MASK --
@dataclass(frozen=True)
class Mask(Record):
    """§4.5 the validity mask, range-coded [F, M, 1] gap flags (present only with gaps)."""

    TYPE = "MASK"
    SECTION = "§4.5"
    GRAMMAR = grammar.MASK

    coded: bytes


# ------------------------------------------------------------------- §4.6 ROOT --
@dataclass(frozen=True)
class Root(Record):
    """§4.6 the root-marker track, range-coded [F, 1, 3] prediction residuals."""

    TYPE = "ROOT"
    SECTION = "§4.6"
    GRAMMAR = grammar.ROOT

    order: int
    coded: bytes

    def check(self, ctx: Context) -> None:
        # R-2.4-26
        if self.order > MAX_ORDER:
            _fail(f"predictor order {self.order} not in 0..{MAX_ORDER}", "§4.6")


# ------------------------------------------------------------------- §4.7 PATT --
@dataclass(frozen=True)
class Patt(Record):
    """§4.7 the K motion patterns of one node, each L frames long."""

    TYPE = "PATT"
    SECTION = "§4.7"
    GRAMMAR = grammar.PATT

    node: int
    pattern_count: int
    length: int
    scale: int
    order: int
    coded: bytes

    @classmethod
    def absent(cls, node: int) -> Patt:
        """§3.4: a PATT an encoder left out (residual files only) means K = 0."""
        return cls(node=node, pattern_count=0, length=1, scale=1, order=0, coded=b"")

    def check(self, ctx: Context) -> None:
        i = ctx.node
        if self.node != i:  # R-3.4-4
            _fail(f"PATT for node {self.node} where node {i} was expected", "§3.4")
        # R-2.4-27, R-8-2
        if self.pattern_count and not 1 <= self.length <= MAX_PATTERN_LENGTH:
            _fail(f"pattern length {self.length} not in 1..{MAX_PATTERN_LENGTH}", "§8",
                  LimitExceededError)
        # R-4.7-2, R-8-2
        if self.pattern_count * self.length * ctx.members > MAX_PATTERN_SAMPLES:
            _fail(f"{self.pattern_count} patterns x {self.length} frames x {ctx.members} markers "
                  f"exceeds {MAX_PATTERN_SAMPLES}", "§8", LimitExceededError)
        # R-2.4-26, R-2.4-28, R-4.7-1
        if self.scale < 1 or self.order > MAX_ORDER:
            _fail(f"pattern scale {self.scale} / order {self.order} out of range", "§4.7")
        # R-4.7-3
        if not self.pattern_count and not ctx.header.residual:
            _fail(f"node {i} has no patterns and the file has no residual layer", "§4.7")


# ------------------------------------------------------------------- §4.8 SEGS --
@dataclass(frozen=True)
class Segs(Record):
    """§4.8 the (pattern index, original frame count) pair of each segment of one node."""

    TYPE = "SEGS"
    SECTION = "§4.8"
    GRAMMAR = grammar.SEGS

    node: int
    segment_count: int
    coded: bytes

    def check(self, ctx: Context) -> None:
        i, F = ctx.node, ctx.header.frame_count
        if self.node != i:  # R-3.4-4
            _fail(f"SEGS for node {self.node} where node {i} was expected", "§3.4")
        # R-2.4-29, R-8-2
        if not 1 <= self.segment_count <= F:
            _fail(f"segment_count {self.segment_count} not in 1..{F}", "§4.8", LimitExceededError)


# ------------------------------------------------------------------- §4.9 RESI --
@dataclass(frozen=True)
class Resi(Record):
    """§4.9 the residual layer of one node."""

    TYPE = "RESI"
    SECTION = "§4.9"
    GRAMMAR = grammar.RESI

    node: int
    base: int
    order: int
    scale: int
    coded: bytes

    def check(self, ctx: Context) -> None:
        i = ctx.node
        if self.node != i:  # R-3.4-4
            _fail(f"RESI for node {self.node} where node {i} was expected", "§3.4")
        # R-2.4-26, R-2.4-32, R-2.4-33
        if self.order > MAX_ORDER or self.scale < 1 or self.base not in set(ResidualBase):
            _fail(f"residual base {self.base} / order {self.order} / scale {self.scale} out of "
                  f"range", "§4.9")
        # R-2.4-32
        if self.base != ResidualBase.PARENT and ctx.patt is not None and ctx.patt.pattern_count:
            _fail(f"node {i}: an absolute residual layer (base {self.base}) needs "
                  f"pattern_count 0", "§4.9")
        # R-2.4-32
        if self.base == ResidualBase.KEYFRAMES and self.order != 0:
            _fail(f"node {i}: a key-frame layer (base 2) has order 0, got {self.order}", "§4.9")


# ------------------------------------------------------------------ §4.10 smry --
@dataclass(frozen=True)
class SummaryLevel(Record):
    """§4.10 one level of the optimal-partition summary."""

    GRAMMAR = grammar.SummaryLevel

    k: int
    wssse: float
    step: float
    starts: bytes
    means: bytes

    def start_frames(self) -> np.ndarray:
        """The u32 first frame of each segment."""
        return np.frombuffer(self.starts, "<u4")

    def mean_values(self, dims: int) -> np.ndarray:
        """The segment means in units, float64 [k, dims]: ±inf where the product
        overflows (§4.10)."""
        q = np.frombuffer(self.means, "<i4").astype(np.float64)
        with np.errstate(over="ignore"):
            return q.reshape(self.k, dims) * self.step


@dataclass(frozen=True)
class Smry(Record):
    """§4.10 the optimal-partition summary (ancillary)."""

    TYPE = "smry"
    SECTION = "§4.10"
    GRAMMAR = grammar.SMRY
    NESTED = {"levels": SummaryLevel}
    PART = "summary"

    space: int
    dims: int
    level_count: int
    levels: tuple[SummaryLevel, ...]

    def check(self, ctx: Context) -> None:
        F = ctx.header.frame_count
        values, _ = check_summary_head(self, ctx, "§4.10")
        for lv in self.levels:
            starts = lv.start_frames()
            if (starts[0] != 0 or (np.diff(starts.astype(np.int64)) <= 0).any()  # R-2.4-40
                    or starts[-1] >= F):
                _fail("summary starts must begin at 0, increase strictly and stay below F",
                      "§4.10")
        if values > MAX_SUMMARY_VALUES:  # R-4.10-1, R-8-2
            _fail(f"summary holds {values} values, limit {MAX_SUMMARY_VALUES}", "§8",
                  LimitExceededError)


def check_summary_head(rec: Smry | Smrc, ctx: Context, section: str) -> tuple[int, int]:
    """The rules that smry (§4.10) and smrc (§4.15, "as for smry") share: the space, D =
    3M for positions, 1 .. MAX_SUMMARY_LEVELS levels, 1 <= k <= F and a finite step > 0
    and wssse >= 0 at each level. Returns the sums of k x D and of k, formed after each k
    is checked (§1.1), for the caller's §8 limit."""
    F, M = ctx.header.frame_count, ctx.header.marker_count
    if rec.space not in set(SummarySpace):  # R-2.4-34, R-4.15-2
        _fail(f"unknown summary space {rec.space}", section)
    if rec.space == SummarySpace.POSITIONS and rec.dims != 3 * M:  # R-2.4-35, R-4.15-2
        _fail(f"position summary has {rec.dims} dims, expected {3 * M}", section)
    if not 1 <= rec.level_count <= MAX_SUMMARY_LEVELS:  # R-2.4-36, R-4.15-2
        _fail(f"summary level count {rec.level_count} not in 1..{MAX_SUMMARY_LEVELS}",
              section)
    values = segments = 0
    for lv in rec.levels:
        # levels may come in any order and repeat k, and D = 0 is allowed for space 1
        # R-2.4-37, R-4.15-2
        if not 1 <= lv.k <= F:
            _fail(f"summary level with k = {lv.k} for {F} frames", section)
        segments += lv.k
        values += lv.k * rec.dims
        # R-2.4-38, R-2.4-39, R-4.15-2
        if not (math.isfinite(lv.step) and lv.step > 0 and math.isfinite(lv.wssse)
                and lv.wssse >= 0):
            _fail("summary step must be > 0 and wssse >= 0, both finite", section)
    return values, segments


# ------------------------------------------------------------------ §4.11 meta --
@dataclass(frozen=True)
class MetaEntry(Record):
    """§4.11 one key/value pair."""

    GRAMMAR = grammar.MetaEntry

    key: str
    value: str


@dataclass(frozen=True)
class Meta(Record):
    """§4.11 key/value metadata (ancillary)."""

    TYPE = "meta"
    SECTION = "§4.11"
    GRAMMAR = grammar.META
    NESTED = {"entries": MetaEntry}

    count: int
    entries: tuple[MetaEntry, ...] = field(default=())

    @classmethod
    def of(cls, items: dict[str, str]) -> Meta:
        return cls(count=len(items),
                   entries=tuple(MetaEntry(key=k, value=v) for k, v in items.items()))

    def as_dict(self) -> dict[str, str]:
        return {e.key: e.value for e in self.entries}

    def check(self, ctx: Context) -> None:
        # keys and values are strict UTF-8 (the layout decodes them, §1, §4.11); U+0000 is
        # allowed in both; repeated keys are allowed (the last value counts)
        for e in self.entries:
            # R-2.4-41
            if not e.key:
                _fail("empty metadata key", "§4.11")


# ------------------------------------------------------------------ §4.12 MEND --
@dataclass(frozen=True)
class Mend(Record):
    """§4.12 the end chunk: empty."""

    TYPE = "MEND"
    SECTION = "§4.12"
    GRAMMAR = grammar.MEND


#: the MPZ 1.0 chunk types, in the order of the spec's catalogue (§4.1-§4.12)
CORE = (Mhdr, Mnam, Hier, Qunt, Mask, Root, Patt, Segs, Resi, Smry, Meta, Mend)
