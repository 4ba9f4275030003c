"""The coded summary chunk of MPZ 1.1 (spec §4.15): ``smrc``.

``smry`` (§4.10) stores each level's segment means as raw ``s32``: 4 bytes a value, which
on a real clip is several times the coded motion (issue 14.12). ``smrc`` holds the same
levels (space, dims, per level k, wssse, step, the segment starts and the means) with the
starts and the means range-coded (§5): each level's segment lengths in an unsigned block,
and its quantised means as prediction residuals in a signed block. The last level is
predicted along its segments (order 1); every other level from the level after it, by the
overlap-weighted mean of that level's means over each segment (§4.15). The encoder writes
the levels by increasing k, so each level is predicted from the finer one.

Like every ancillary chunk it is not used to decode the motion; a 1.0 decoder skips it
(§2.3). The record checks its § rules and decodes its field (a file whose summary cannot be
decoded is rejected where every other chunk is); :meth:`Smrc.levels_decoded` gives
the starts and the integer means, which :func:`mpz.read_summary` dequantises.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mpz.chunks.base import JSON, Context, Record
from mpz.chunks.base import fail as _fail
from mpz.chunks.core import check_summary_head
from mpz.entropy import BlockDecoder, BlockEncoder
from mpz.errors import EncoderError, LimitExceededError
from mpz.format import MAX_SUMMARY_VALUES, SummarySpace
from mpz.predict import add_overlap
from mpz.spec import grammar

__all__ = ["CodedSummaryLevel", "Smrc", "SUMMARY", "SUMMARY_TYPES", "SMRC_MINOR",
           "MEAN_LIMIT", "encode_levels", "decode_levels", "overlap_prediction"]

#: §2.1 the minor version that added smrc
SMRC_MINOR = 1
#: §3.4, §4.15: a file holds at most one of these (one summary, coded or not)
SUMMARY_TYPES = ("smry", "smrc")
#: §4.15 step 5: every decoded mean q satisfies |q| < 2^31 (smry's s32 range without -2^31)
MEAN_LIMIT = 1 << 31

IntArray = NDArray[np.int64]


def block_shape(space: int, k: int, dims: int) -> tuple[int, int, int]:
    """§4.15 the mean block of a level: [k, D/3, 3] for positions, [k, D, 1] for angles."""
    if space == SummarySpace.POSITIONS:
        return (k, dims // 3, 3)
    return (k, dims, 1)


def overlap_prediction(starts: IntArray, source_q: IntArray, source_starts: IntArray,
                       frames: int) -> IntArray:
    """§4.15 the prediction of a level from another: for each segment j (n_j frames) and
    dimension d, (2 x sum_i q'[i, d] x ov(j, i) + n_j) div (2 n_j), where ov(j, i) is the
    number of frames segment j shares with segment i of the source level
    (:func:`mpz.predict.add_overlap`, which the decoder applies in place)."""
    out = np.zeros((starts.shape[0], source_q.shape[1]), np.int64)
    if out.size:
        add_overlap(starts, source_q, source_starts, frames, out, 1)
    return out


def decode_levels(rec: Smrc, frames: int, *, offset: int | None = None
                  ) -> list[tuple[IntArray, IntArray]]:
    """§4.15 decoding steps 1-4: (starts [k], integer means q [k, D]) of every level.

    Call after the header checks of :meth:`Smrc.check` (k and the two sums, §1.1).
    Memory (§8): each level's residual block becomes its means in place, and its starts
    are one int64 array; nothing else of the summary's size is held.
    """
    dec = BlockDecoder(rec.coded, chunk=rec.TYPE, offset=offset)  # R-4.15-4
    D = rec.dims
    starts_of: list[IntArray] = []
    means: list[IntArray] = []
    for lv in rec.levels:
        k = lv.k
        lengths = dec.block(k, 1, 1, period=k, signed=False).reshape(k)
        lengths += 1
        # §4.15 step 2: the lengths add up to F (the sum formed in 64 bits: k < 2^24 values
        # of at most 2^31, c_j + 1) before any start is formed (§1.1)
        total = int(lengths.sum())
        if total != frames:  # R-4.15-5
            _fail(f"summary level k = {k}: segment lengths add up to {total}, "
                  f"not {frames} frames", "§4.15")
        np.cumsum(lengths, out=lengths)                  # the end of each segment
        lengths[1:] = lengths[:-1].copy()
        lengths[0] = 0
        starts_of.append(lengths)
        if D:
            shape = block_shape(rec.space, k, D)
            means.append(dec.block(*shape, period=k, signed=True).reshape(k, D))
        else:
            means.append(np.zeros((k, 0), np.int64))
    dec.close()  # R-4.15-4
    # steps 3-4, in place: the last level along its segments, then each level from the one
    # after it (already means)
    for li in range(len(rec.levels) - 1, -1, -1):
        q = means[li]
        if not q.size:
            continue
        if li == len(rec.levels) - 1:
            np.cumsum(q, axis=0, out=q)              # |partial sums| < 2^55: exact in int64
        else:
            add_overlap(starts_of[li], means[li + 1], starts_of[li + 1], frames, q, 1)
        if int(q.max()) >= MEAN_LIMIT or int(q.min()) <= -MEAN_LIMIT:  # R-4.15-6
            _fail(f"summary level k = {rec.levels[li].k}: a decoded mean is 2^31 steps or "
                  f"more in magnitude", "§4.15")
    return list(zip(starts_of, means, strict=True))


def encode_levels(space: int, frames: int, levels: list[tuple[IntArray, IntArray]]) -> bytes:
    """The ``coded`` field of §4.15 for (starts [k], integer means q [k, D]) levels, in the
    order they are stored (the reference stores them by increasing k)."""
    enc = BlockEncoder()
    n = len(levels)
    for li, (starts, q) in enumerate(levels):
        k = starts.shape[0]
        lengths = np.diff(np.append(starts, frames)) - 1
        enc.block(lengths.reshape(k, 1, 1), period=k, signed=False)
        if q.shape[1]:
            if li == n - 1:
                e = np.diff(q, axis=0, prepend=0)
            else:
                nxt_starts, nxt_q = levels[li + 1]
                e = q - overlap_prediction(starts, nxt_q, nxt_starts, frames)
            if int(np.abs(e).max(initial=0)) >= 1 << 30:
                raise EncoderError("summary mean residuals do not fit the coder's 2^30 range "
                                   "(§5.4): the step is too fine for these means")
            enc.block(e.reshape(block_shape(space, k, q.shape[1])), period=k, signed=True)
    return enc.finish()


@dataclass(frozen=True)
class CodedSummaryLevel(Record):
    """§4.15 the header of one level of the coded summary."""

    GRAMMAR = grammar.CodedSummaryLevel

    k: int
    wssse: float
    step: float


@dataclass(frozen=True)
class Smrc(Record):
    """§4.15 the coded optimal-partition summary (ancillary, 1.1)."""

    TYPE = "smrc"
    SECTION = "§4.15"
    GRAMMAR = grammar.SMRC
    NESTED = {"levels": CodedSummaryLevel}
    MINOR = SMRC_MINOR
    PART = "summary"

    space: int
    dims: int
    level_count: int
    levels: tuple[CodedSummaryLevel, ...]
    coded: bytes

    def check_header(self, ctx: Context) -> None:
        """The rules of §4.15 that come before the coded field is decoded (§1.1). At most
        one summary chunk (R-4.15-1) is the chunk walk's rule, checked in decoder.py."""
        values, segments = check_summary_head(self, ctx, "§4.15")
        # R-4.15-3, R-8-2
        if values > MAX_SUMMARY_VALUES or segments > MAX_SUMMARY_VALUES:
            _fail(f"summary holds {values} means and {segments} segments, limit "
                  f"{MAX_SUMMARY_VALUES} each", "§8", LimitExceededError)

    def check(self, ctx: Context) -> None:
        self.check_header(ctx)
        decode_levels(self, ctx.header.frame_count)          # §4.15: the field must decode

    def levels_decoded(self, frames: int) -> list[tuple[IntArray, IntArray]]:
        """(starts, integer means [k, D]) of every level (after :meth:`check`)."""
        return decode_levels(self, frames)

    def info(self) -> dict[str, JSON]:
        return {"space": self.space, "dims": self.dims, "level_count": self.level_count,
                "levels": [{"k": lv.k, "wssse": lv.wssse, "step": lv.step}
                           for lv in self.levels],
                "coded": {"bytes": len(self.coded), "head": self.coded[:16].hex()}}


#: the MPZ 1.1 summary chunk types, in the order of the spec's catalogue (§4.15)
SUMMARY = (Smrc,)
