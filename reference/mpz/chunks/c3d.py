"""The C3D archive chunk types (spec §4.13, MPZ 1.1), one record class each.

A C3D recording keeps, besides the marker trajectories MPZ 1.0 codes, its header, its
parameter section, the fourth word (residual and camera mask) of every point, the points
that are model outputs (angles, forces, moments, powers, scalars, reactions) and its
analog channels. Each travels in an ancillary chunk (§2.3), so that a 1.0 decoder skips
them and still decodes the markers (§2.1): ``chdr``, ``cprm``, ``cpnt`` and ``cana``.

Each class is the whole of its chunk, as in :mod:`mpz.chunks.core`: layout, § checks,
build and what mpzinfo shows. The checks of ``cpnt`` and ``cana`` include decoding their
channels (§6.9), since their value rules need the decoded values; the result is kept for
the extension that turns the records into :attr:`mpz.Motion.extras` (:mod:`mpz.c3darchive`),
so a file is decoded once.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
import math
from typing import Any
import zlib

import numpy as np
from numpy.typing import NDArray

from mpz.c3dcodec import FLOAT32, INT16, MODEL_LIMIT, decode_channels, decode_model_axes
from mpz.chunks import _parse
from mpz.chunks.base import JSON, Context, Record, kept
from mpz.chunks.base import fail as _fail
from mpz.entropy import BlockDecoder
from mpz.errors import FormatError, LimitExceededError
from mpz.format import (
    C3D_MAX_LOW_BITS,
    C3D_MAX_SHIFT,
    C3D_MIN_SHIFT,
    C3D_MINOR,
    MAX_C3D_PARAMETER_BYTES,
    MAX_MARKERS,
    MAX_ORDER,
    ByteCoding,
    C3DProcessor,
    C3DStorage,
    ChannelMode,
    ModelKind,
)
from mpz.spec import grammar

#: §4.13 the chunk types of a C3D archive; the first three come together, cana is optional
C3D_TYPES = ("chdr", "cprm", "cpnt", "cana")
#: §4.13.1 byte 1 of a C3D header, the parameter-section key
C3D_KEY = 0x50


def _set_rules(ctx: Context) -> None:
    """§4.13: one chdr, one cprm and one cpnt, at most one cana (checked wherever the
    chunk list is known, that is for every chunk the decoder reads)."""
    if not ctx.types:
        return
    counts = {t: ctx.types.count(t) for t in C3D_TYPES}
    for t in C3D_TYPES[:3]:
        # R-4.13-1
        if counts[t] != 1:
            _fail(f"a C3D archive has exactly one {t} chunk; this file has {counts[t]}",
                  "§4.13")
    if counts["cana"] > 1:  # R-4.13-1
        _fail(f"a C3D archive has at most one cana chunk; this file has {counts['cana']}",
              "§4.13")


#: the channel modes and model kinds §4.13 and §4.13.3 define (checked per channel: a
#: set built per check cost a microsecond each)
_MODES, _KINDS = frozenset(ChannelMode), frozenset(ModelKind)


# ------------------------------------------------------------ channel entry --
@dataclass(frozen=True)
class Channel(Record):
    """§4.13 one channel entry: how a channel of C3D words is coded (§6.9)."""

    GRAMMAR = grammar.C3dChannel

    mode: int
    shift: int
    order: int
    low_bits: int

    def check_entry(self, storage: int, what: str, section: str) -> None:
        """The §4.13 rules of a channel entry, for words stored as ``storage``."""
        if self.mode not in _MODES:  # R-4.13-2
            _fail(f"{what}: unknown channel mode {self.mode}", section)
        # R-4.13-2
        if self.mode == ChannelMode.INTEGER and not C3D_MIN_SHIFT <= self.shift <= C3D_MAX_SHIFT:
            _fail(f"{what}: shift {self.shift} not in {C3D_MIN_SHIFT}..{C3D_MAX_SHIFT}", section)
        if self.mode == ChannelMode.BITS and self.shift != 0:  # R-4.13-2
            _fail(f"{what}: a float32 bit-pattern channel has shift 0, got {self.shift}",
                  section)
        # R-4.13-2
        if storage == C3DStorage.INT16 and (self.mode != ChannelMode.INTEGER or self.shift):
            _fail(f"{what}: int16 words are coded as integers with shift 0 (mode "
                  f"{self.mode}, shift {self.shift})", section)
        if self.order > MAX_ORDER:  # R-4.13-2
            _fail(f"{what}: predictor order {self.order} not in 0..{MAX_ORDER}", section)
        # R-4.13-2
        if self.low_bits > C3D_MAX_LOW_BITS:
            _fail(f"{what}: low_bits {self.low_bits} not in 0..{C3D_MAX_LOW_BITS}", section)



def _decode_table(dec: BlockDecoder, T: int, table: tuple[Channel, ...], storage: int,
                  out: NDArray[np.int16] | NDArray[np.float32]) -> None:
    """§6.9 the channels of ``table``, in order, each into its column of ``out``."""
    decode_channels(dec, T, [(c.mode, c.shift, c.order, c.low_bits) for c in table],
                    _dtype(storage), "§6.9", out)


def _dtype(storage: int) -> np.dtype[Any]:
    return INT16 if storage == C3DStorage.INT16 else FLOAT32


def _check_storage(storage: int, section: str) -> None:
    if storage not in set(C3DStorage):  # R-4.13.3-1, R-4.13.4-1
        _fail(f"unknown storage code {storage} (0 int16, 1 float32)", section)


# ------------------------------------------------------ §4.13 byte coding --
def deflate(data: bytes) -> bytes:
    """The reference encoder's raw DEFLATE stream (RFC 1951) of ``data`` (§4.13 coding 1):
    zlib level 9, a 2^15-byte window, memLevel 9. Any other valid stream decodes alike."""
    co = zlib.compressobj(9, zlib.DEFLATED, -15, 9)
    return co.compress(data) + co.flush()


def inflate(body: bytes, limit: int, chunk: str, section: str) -> bytes:
    """§4.13 coding 1: the bytes of one raw DEFLATE stream that fills ``body`` exactly.

    Never inflates more than ``limit`` + 1 bytes, so a small stream cannot expand into a
    large allocation (§8).

    Raises
    ------
    FormatError
        For a stream that is not valid DEFLATE, ends before its final block or is followed
        by other bytes (§4.13's byte coding, R-4.13-3), or inflates to more than ``limit``
        bytes (cited as ``section``, the chunk's content limit, as for stored content).
    """
    d = zlib.decompressobj(-15)
    try:
        out = d.decompress(body, limit + 1)
    except zlib.error as exc:  # R-4.13-3
        raise FormatError(f"malformed {chunk} payload: invalid DEFLATE stream ({exc})",
                          chunk=chunk, section="§4.13") from None
    # R-4.13-3, R-4.13.1-2, R-4.13.2-4
    if len(out) > limit:
        raise FormatError(f"malformed {chunk} payload: the DEFLATE stream inflates to more "
                          f"than {limit} bytes", chunk=chunk, section=section)
    # R-4.13-3
    if not d.eof:
        raise FormatError(f"malformed {chunk} payload: the DEFLATE stream ends before its "
                          f"final block", chunk=chunk, section="§4.13")
    if d.unused_data:  # R-4.13-3
        raise FormatError(f"malformed {chunk} payload: {len(d.unused_data)} byte(s) after "
                          f"the end of the DEFLATE stream", chunk=chunk, section="§4.13")
    return out


def _content(cls: type[Record], coding: int, body: bytes, limit: int) -> bytes:
    """The content bytes of a chdr or cprm body, by ``coding`` (§4.13)."""
    if coding == ByteCoding.STORED:
        # R-4.13-3, R-4.13.1-2, R-4.13.2-4
        if len(body) > limit:
            raise FormatError(f"malformed {cls.TYPE} payload: {len(body)} bytes of content, "
                              f"more than {limit}", chunk=cls.TYPE, section=cls.SECTION)
        return body
    if coding == ByteCoding.DEFLATE:
        return inflate(body, limit, cls.TYPE, cls.SECTION)
    # R-4.13-3
    raise FormatError(f"malformed {cls.TYPE} payload: coding {coding}, not 0 (stored) or 1 "
                      f"(DEFLATE)", chunk=cls.TYPE, section="§4.13")


def _body(coding: int, content: bytes) -> bytes:
    return deflate(content) if coding == ByteCoding.DEFLATE else content


# ----------------------------------------------------------------- §4.13.1 --
@dataclass(frozen=True)
class Chdr(Record):
    """§4.13.1 the C3D header block (ancillary, 1.1).

    ``block`` is always the 512 bytes of the header; ``coding`` says how the payload
    stores them (§4.13: stored, or one raw DEFLATE stream).
    """

    TYPE = "chdr"
    SECTION = "§4.13.1"
    GRAMMAR = grammar.CHDR
    MINOR = C3D_MINOR

    #: the layout of the content that ``body`` stores or deflates (§4.13 byte coding)
    CONTENT = grammar.CHDR_BLOCK

    processor: int
    coding: int
    block: bytes

    @classmethod
    def load(cls, payload: bytes) -> Chdr:
        if len(payload) < 2:  # R-4.13.1-2
            raise FormatError(f"malformed chdr payload: {len(payload)} bytes, shorter than "
                              f"its processor and coding bytes", chunk=cls.TYPE,
                              section="§4.13.1")
        outer = _parse.parse(grammar.CHDR, payload)
        content = _content(cls, outer.coding, outer.body, 512)
        block = _ChdrBlock.load(content).block
        return cls(processor=outer.processor, block=block, coding=outer.coding)

    def dump(self) -> bytes:
        return bytes((self.processor, self.coding)) + _body(self.coding, self.block)

    def word(self, n: int) -> int:
        """Header word ``n`` (1-based, as in the C3D guide) as an unsigned 16-bit integer."""
        return int.from_bytes(self.block[2 * n - 2:2 * n], "little")

    def real(self, n: int) -> float:
        """The binary32 at header words ``n`` and ``n + 1``."""
        return float(np.frombuffer(self.block, "<f4", 1, 2 * n - 2)[0])

    def check(self, ctx: Context) -> None:
        _set_rules(ctx)
        if self.processor not in set(C3DProcessor):  # R-4.13.1-1
            _fail(f"unknown C3D processor type {self.processor} (84, 85 or 86)", "§4.13.1")
        if self.block[1] != C3D_KEY:  # R-4.13.1-1
            _fail(f"C3D header byte 1 is 0x{self.block[1]:02x}, not the key 0x50", "§4.13.1")

    def info(self) -> dict[str, JSON]:
        return {"processor": self.processor, "coding": _coding_name(self.coding),
                "block": super().info()["block"],
                "first_frame": self.word(4), "last_frame": self.word(5),
                "analog_words_per_frame": self.word(3), "analog_samples": self.word(10),
                "scale": self.real(7), "rate": self.real(11),
                "events": self.word(151) if self.word(150) == 12345 else 0}


# ----------------------------------------------------------------- §4.13.2 --
@dataclass(frozen=True)
class Param(Record):
    """§4.13.2 one group (``group`` < 0) or parameter (``group`` > 0) record."""

    GRAMMAR = grammar.C3dParam

    group: int
    locked: int
    name: bytes
    description: bytes
    type: int | None = None
    dims: bytes | None = None
    data: bytes | None = None

    @property
    def is_group(self) -> bool:
        return self.group < 0

    def info(self) -> dict[str, JSON]:
        out: dict[str, JSON] = {"group": self.group, "locked": self.locked,
                                "name": self.name.decode("latin-1"),
                                "description": self.description.decode("latin-1")}
        if not self.is_group:
            out.update(type=self.type, dims=list(self.dims or b""),
                       data={"bytes": len(self.data or b""),
                             "head": (self.data or b"")[:16].hex()})
        return out


_PARAM_TYPES = (-1, 1, 2, 4)


def _coding_name(coding: int) -> str:
    names = {int(ByteCoding.STORED): "stored", int(ByteCoding.DEFLATE): "deflate"}
    return names.get(coding, str(coding))


@dataclass(frozen=True)
class _ChdrBlock(Record):
    """§4.13.1 the inflated header block (the content of a chdr)."""

    TYPE = "chdr"
    SECTION = "§4.13.1"
    GRAMMAR = grammar.CHDR_BLOCK

    block: bytes


@dataclass(frozen=True)
class _CprmSection(Record):
    """§4.13.2 the inflated parameter section (the content of a cprm)."""

    TYPE = "cprm"
    SECTION = "§4.13.2"
    GRAMMAR = grammar.CPRM_SECTION
    NESTED = {"records": Param}

    count: int
    records: tuple[Param, ...]


@dataclass(frozen=True)
class Cprm(Record):
    """§4.13.2 the C3D parameter section (ancillary, 1.1).

    ``count`` and ``records`` are the section; ``coding`` says how the payload stores
    it (§4.13: stored, or one raw DEFLATE stream).
    """

    TYPE = "cprm"
    SECTION = "§4.13.2"
    GRAMMAR = grammar.CPRM
    NESTED = {"records": Param}
    MINOR = C3D_MINOR

    #: the layout of the content that ``body`` stores or deflates (§4.13 byte coding)
    CONTENT = grammar.CPRM_SECTION

    coding: int
    count: int
    records: tuple[Param, ...]

    @classmethod
    def load(cls, payload: bytes) -> Cprm:
        if not payload:  # R-4.13.2-4
            raise FormatError("malformed cprm payload: empty, no coding byte",
                              chunk=cls.TYPE, section="§4.13.2")
        outer = _parse.parse(grammar.CPRM, payload)
        content = _content(cls, outer.coding, outer.body, MAX_C3D_PARAMETER_BYTES)
        sec = _CprmSection.load(content)
        return cls(count=sec.count, records=sec.records, coding=outer.coding)

    def content(self) -> bytes:
        """The §4.13.2 section that the payload stores or deflates. It is built once per
        record (the fields of a frozen record never change), since construct takes
        milliseconds for a parameter section and the encoder needs it for both codings."""
        got: bytes | None = self.__dict__.get("_content")
        if got is None:
            got = _CprmSection(count=self.count, records=self.records).dump()
            self.__dict__["_content"] = got
        return got

    def recoded(self, coding: int) -> Cprm:
        """The same section with another byte coding (§4.13), sharing the built section."""
        other = replace(self, coding=coding)
        other.__dict__["_content"] = self.content()
        return other

    def dump(self) -> bytes:
        got: bytes | None = self.__dict__.get("_payload")
        if got is None:
            got = bytes((self.coding,)) + _body(self.coding, self.content())
            self.__dict__["_payload"] = got
        return got

    def info(self) -> dict[str, JSON]:
        out = super().info()
        out["coding"] = _coding_name(self.coding)
        return out

    def check(self, ctx: Context) -> None:
        _set_rules(ctx)
        fault = self.fault()
        if fault is not None:  # R-4.13.2-1
            _fail(fault, "§4.13.2")

    def fault(self) -> str | None:
        """The first §4.13.2 record rule the section breaks, or None: the check of a
        decoder (:meth:`check`), and of the reader and the encoder before a C3D's
        parameter section is kept (a C3D may declare a group twice; MPZ may not)."""
        groups: set[int] = set()
        for i, r in enumerate(self.records):  # R-4.13.2-1
            if r.group == 0:
                return f"record {i}: group id 0"
            if not 1 <= len(r.name) <= 127:
                return f"record {i}: name of {len(r.name)} bytes, not 1..127"
            if r.locked > 1:
                return f"record {i}: locked flag {r.locked}, not 0 or 1"
            if r.is_group:
                if -r.group in groups:
                    return f"record {i}: group id {-r.group} declared twice"
                groups.add(-r.group)
                continue
            if r.type not in _PARAM_TYPES:
                return f"record {i}: parameter type {r.type}, not -1, 1, 2 or 4"
            if len(r.dims or b"") > 7:
                return f"record {i}: {len(r.dims or b'')} dimensions, at most 7"
        return None


# ----------------------------------------------------------------- §4.13.3 --
@dataclass(frozen=True)
class ModelAxis(Record):
    """§4.13.3 one axis of a model output: x = offset + k x step."""

    GRAMMAR = grammar.C3dModelAxis

    offset: float
    step: float
    bound: float
    order: int

    def fault(self) -> str | None:
        """The §4.13.3 rule this axis breaks, or None: the check of a decoder (Cpnt.check)
        and of the encoder before it writes the axis."""
        if not (math.isfinite(self.offset) and math.isfinite(self.step) and self.step > 0):
            return f"offset {self.offset!r} and step {self.step!r} must be finite, step > 0"
        if not math.isfinite(abs(self.offset) + self.step * float(MODEL_LIMIT)):
            return "|offset| + step x 2^31 is not finite in binary64"
        if not (math.isfinite(self.bound) and self.bound >= 0):
            return f"bound {self.bound!r} is not finite and >= 0"
        if self.order > MAX_ORDER:
            return f"predictor order {self.order} not in 0..{MAX_ORDER}"
        return None


@dataclass(frozen=True)
class Model(Record):
    """§4.13.3 one model output."""

    GRAMMAR = grammar.C3dModel
    NESTED = {"axes": ModelAxis}

    kind: int
    axes: tuple[ModelAxis, ...]


@dataclass(frozen=True)
class PointsDecoded:
    """§6.9 what a cpnt chunk decodes to."""

    words: NDArray[Any]                  # [F, P], int16 or float32
    models: NDArray[np.float64]          # [F, J, 3], NaN at gaps
    valid: NDArray[np.bool_]             # [F, J]


@dataclass(frozen=True)
class Cpnt(Record):
    """§4.13.3 the C3D points: slots, fourth words, model outputs (ancillary, 1.1)."""

    TYPE = "cpnt"
    SECTION = "§4.13.3"
    GRAMMAR = grammar.CPNT
    NESTED = {"words": Channel, "models": Model}
    MINOR = C3D_MINOR

    storage: int
    point_count: int
    slots: tuple[int, ...]
    words: tuple[Channel, ...]
    model_count: int
    models: tuple[Model, ...]
    coded: bytes

    def check(self, ctx: Context) -> None:
        s = "§4.13.3"
        _set_rules(ctx)
        _check_storage(self.storage, s)
        F, M = ctx.header.frame_count, ctx.header.marker_count
        J, P = self.model_count, self.point_count
        # R-4.13.3-2, R-8-2
        if J > MAX_MARKERS or F * J > ctx.max_samples:
            _fail(f"{J} model outputs x {F} frames exceed the limits of §8 (at most "
                  f"{MAX_MARKERS} outputs, {ctx.max_samples} samples)", "§8",
                  LimitExceededError)
        if P != M + J:  # R-4.13.3-1
            _fail(f"point_count {P} is not marker_count {M} + model_count {J}", s)
        # R-4.13.3-1
        if sorted(self.slots) != list(range(P)):
            _fail("slots are not a permutation of 0 .. point_count - 1", s)
        for p, ch in enumerate(self.words):
            ch.check_entry(self.storage, f"point {p} word channel", "§4.13")
        for j, m in enumerate(self.models):
            if m.kind not in _KINDS:  # R-4.13.3-1
                _fail(f"model output {j}: unknown kind {m.kind}", s)
            for a, ax in enumerate(m.axes):
                fault = ax.fault()
                if fault is not None:  # R-4.13.3-1
                    _fail(f"model output {j} axis {'xyz'[a]}: {fault}", s)
        self.decode(F, M)

    def decode(self, F: int, M: int) -> PointsDecoded:
        """§6.9 the words of every point and the model outputs (after :meth:`check`)."""
        return kept(self, (F, M), lambda: self._decode(F))

    def _decode(self, F: int) -> PointsDecoded:
        s = "§6.9"                      # every check of the decoded values is §6.9's
        J = self.model_count
        dec = BlockDecoder(self.coded, chunk=self.TYPE)
        words = np.empty((F, self.point_count), _dtype(self.storage))
        _decode_table(dec, F, self.words, self.storage, words)
        valid = np.ones((F, J), bool)
        if J:
            flags = dec.block(F, J, 1, signed=False)[:, :, 0]
            if flags.size and int(flags.max()) > 1:  # R-6.9-1
                raise FormatError(f"model-output gap flag {int(flags.max())}, not 0 or 1",
                                  section=s)
            valid = flags == 0
            del flags                   # before the outputs are allocated (§8 budget)
        models = np.full((F, J, 3), np.nan)
        if J:
            # models[:, j, a] is column 3 j + a of this view
            decode_model_axes(dec, F, [(ax.order, ax.step, ax.offset) for m in self.models
                                       for ax in m.axes], s, models.reshape(F, 3 * J))
            models[~valid] = np.nan
        # R-6.9-1
        dec.close()
        return PointsDecoded(words, models, valid)


# ----------------------------------------------------------------- §4.13.4 --
@dataclass(frozen=True)
class Cana(Record):
    """§4.13.4 the C3D analog channels (ancillary, 1.1)."""

    TYPE = "cana"
    SECTION = "§4.13.4"
    GRAMMAR = grammar.CANA
    NESTED = {"table": Channel}
    MINOR = C3D_MINOR
    PART = "analog"

    storage: int
    channels: int
    samples: int
    table: tuple[Channel, ...]
    coded: bytes

    def check(self, ctx: Context) -> None:
        s = "§4.13.4"
        _set_rules(ctx)
        _check_storage(self.storage, s)
        C, n, F = self.channels, self.samples, ctx.header.frame_count
        if C < 1 or n < 1:  # R-4.13.4-1
            _fail(f"channels {C} and samples {n} must both be >= 1", s)
        if C * n > 0xFFFF:  # R-4.13.4-1
            _fail(f"channels x samples = {C * n} exceeds 65535, the analog words per frame a "
                  f"C3D header holds", s)
        limit, lowered = ctx.limit("MAX_ANALOG_SAMPLES")
        # R-4.13.4-2, R-8-2
        if F * n * C > limit:
            _fail(f"{F} frames x {n} samples x {C} channels exceed MAX_ANALOG_SAMPLES "
                  f"{limit}{lowered}", "§8", LimitExceededError)
        for c, ch in enumerate(self.table):
            ch.check_entry(self.storage, f"analog channel {c}", "§4.13")
        self.decode(F)

    def decode(self, F: int) -> NDArray[Any]:
        """§6.9 the analog words ``[F x samples, channels]`` (after :meth:`check`)."""
        return kept(self, (F,), lambda: self._decode(F))

    def _decode(self, F: int) -> NDArray[Any]:
        T = F * self.samples
        out = np.empty((T, self.channels), _dtype(self.storage))
        dec = BlockDecoder(self.coded, chunk=self.TYPE)  # R-6.9-1
        _decode_table(dec, T, self.table, self.storage, out)     # each into its column (§8)
        dec.close()
        return out


#: the C3D archive chunk types, in the order of the spec's catalogue (§4.13.1-§4.13.4)
C3D = (Chdr, Cprm, Cpnt, Cana)
