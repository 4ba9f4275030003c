"""A small pure-numpy C3D reader, working on bytes.

Contract: :func:`parse_c3d` takes the whole file as ``bytes`` and returns a
:class:`C3DData` (point data, residual words, parameters, and for the C3D
archive of spec §4.13: the header block, every parameter record as stored,
the fourth word of every point and the analog words) or raises
:class:`mpz.errors.InputFormatError`. It is the fallback for files ``ezc3d``
refuses (SGI/MIPS big-endian files, parameter sections with unknown types), a
second, independent reading of the files ezc3d accepts, and the one reader of
what MPZ archives. :func:`build_c3d` writes a C3D file (Intel, int16 or
float32 storage) from the same parts, byte for byte where the storage allows.

Normalised form (what the archive keeps): integers little-endian, floats IEEE
754 binary32 little-endian (DEC floats converted exactly, MIPS bytes swapped),
char and byte data as stored.

The layout follows the C3D.org "C3D file format user guide" (2008):
512-byte blocks; block 1 is the header; byte 0 of the header gives the
first parameter block; byte 3 of the parameter block gives the processor
type (84 Intel, 85 DEC, 86 MIPS).

Frame counts above 65,535 (the header's first and last frame are 16-bit words)
follow the user guide's appendix "The C3D frame count": the header's last frame
is 65535 and the count is in TRIAL:ACTUAL_START_FIELD / ACTUAL_END_FIELD (each
two int16 words, low then high, of an unsigned 32-bit frame number),
POINT:LONG_FRAMES (float, C-Motion) or POINT:FRAMES stored as a float;
:func:`frame_range` reads them and :func:`plain_parts` writes them. ezc3d reads
such a file when POINT:FRAMES is the int16 0xFFFF (it refuses a float FRAMES), so
that is what :func:`plain_parts` stores there.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
import math
from typing import Any, NamedTuple, NoReturn

import numpy as np
from numpy.typing import NDArray

from mpz.errors import InputFormatError

BLOCK = 512  # C3D files are organised in 512-byte blocks
#: the largest finite float32, the largest coordinate a float C3D can store
F32_MAX = float(np.finfo(np.float32).max)
C3D_KEY = 0x50  # header byte 1: "C3D" key value 80
PROC_INTEL, PROC_DEC, PROC_MIPS = 84, 85, 86  # parameter header byte 3
#: parameter element types: -1 char, 1 byte, 2 int16, 4 float32
_PARAM_TYPES = (-1, 1, 2, 4)
MAX_POINTS = 65535  # POINT:USED is a 16-bit count
MAX_DIMS = 7  # a C3D parameter has at most 7 dimensions
#: the most strings of no character (a char parameter's first dimension 0) ezc3d is given:
#: it makes each, 134 bytes apiece (:func:`ezc3d_hazard`, rule 10); as many as a char
#: parameter holding data can have within its record (at most 65535 bytes)
MAX_EMPTY_STRINGS = 65535
#: the largest frame number header words 4-5 hold; a header whose last frame is this may
#: describe more frames than it can say (see :func:`frame_range`)
HEADER_MAX_FRAME = 65535
#: the largest frame number or count: TRIAL:ACTUAL_END_FIELD is two 16-bit words
MAX_FRAME_NUMBER = 0xFFFFFFFF

#: a parameter value: char rows, or the flat numbers of an int8/int16/float32 parameter
ParamValue = list[str] | NDArray[np.int64] | NDArray[np.float64]


@dataclass
class C3DData:
    """What :func:`parse_c3d` extracts from a C3D file.

    Attributes
    ----------
    points : ndarray, shape (frames, points, 3)
        Positions in the file's units (integer data already multiplied by
        ``|POINT:SCALE|``).
    residual_words : ndarray, shape (frames, points)
        The fourth word of each point as a signed integer; negative marks an
        invalid sample.
    params : dict
        ``{"GROUP": {"NAME": value}}``; char values are lists of stripped
        strings (one per row), numeric values are flat numpy arrays.
    processor : int
        84 Intel, 85 DEC, 86 MIPS.
    float_storage : bool
        True when ``POINT:SCALE`` is negative (points stored as float32).
    header_rate : float
        The 3D frame rate from header words 11-12 (used when the parameter
        section has no POINT:RATE).
    """

    points: NDArray[np.float64]
    residual_words: NDArray[np.int64]
    params: dict[str, dict[str, ParamValue | None]] = field(default_factory=dict)
    processor: int = PROC_INTEL
    float_storage: bool = True
    header_rate: float = 0.0
    #: the 512-byte header block, normalised (module docstring)
    header_block: bytes = b""
    #: every group and parameter record of the parameter section, in file order, normalised
    records: list[ParamRecord] = field(default_factory=list)
    #: the fourth word of every point in every frame, [frames, points], '<i2' or '<f4'
    point_words: NDArray[Any] = field(default_factory=lambda: np.zeros((0, 0), "<i2"))
    #: the analog words, [frames * samples, channels] in file order, '<i2' or '<f4'
    analog: NDArray[Any] = field(default_factory=lambda: np.zeros((0, 0), "<i2"))
    #: analog samples per channel per point frame (header word 10)
    analog_samples: int = 0
    #: the number of the first frame (header word 4, or TRIAL:ACTUAL_START_FIELD for a
    #: file with more frames than the header can describe; :func:`frame_range`)
    first_frame: int = 1
    #: what the file says twice and differently, and what was read (:func:`_layout`)
    warnings: list[str] = field(default_factory=list)
    #: a DEC float below 2^-126 was rounded to a float32 subnormal (:data:`DEC_ROUNDED`)
    dec_rounded: bool = False
    #: the frames the file holds (more than ``points`` has when :func:`parse_c3d` was asked
    #: for fewer); -1: not given
    frames_in_file: int = -1


@dataclass(frozen=True)
class ParamRecord:
    """One record of a C3D parameter section, as stored (normalised, see the module doc).

    ``group`` < 0 is a group (id ``-group``); ``group`` > 0 a parameter of that group,
    with ``type`` (-1 char, 1 byte, 2 int16, 4 float32), ``dims`` and ``data``
    (|type| x prod(dims) bytes; one element when ``dims`` is empty).
    """

    group: int
    locked: bool
    name: bytes
    description: bytes = b""
    type: int = 0
    dims: tuple[int, ...] = ()
    data: bytes = b""

    @property
    def is_group(self) -> bool:
        return self.group < 0


def _s8(b: int) -> int:
    """A byte as a signed 8-bit integer."""
    return b - 256 if b > 127 else b


def _fail(msg: str, offset: int | None = None) -> NoReturn:
    raise InputFormatError(f"C3D: {msg}", offset=offset)


def truncated(declared: int, present: int, offset: int | None = None) -> InputFormatError:
    """The error for a file with fewer frames than its header declares."""
    return InputFormatError(f"C3D: truncated point data: {declared} frames declared, "
                            f"{present} present", offset=offset)


def _dec_to_ieee(raw: bytes) -> tuple[NDArray[np.float32], bool]:
    """DEC (VAX F_floating) 4-byte values to float32, and whether one was rounded.

    VAX F stores the high 16-bit word first (each word little-endian) and uses a 0.1f
    mantissa with exponent bias 128: swapping the words gives the IEEE bit pattern of 4x
    the value, whose exponent field less 2 is the value's own, exactly (spec §4.13: the
    24-bit significands are the same). That holds for VAX exponents 3 to 255: a division
    by 4, here before, turned exponent 255 (2^126 and above) into inf and NaN (a C3D QA
    run of stop 52). Exponents 1 and 2 (below 2^-126) are float32 subnormals, rounded to
    nearest (said: the flag); exponent 0 is a VAX zero, whatever its fraction, kept with
    its sign.
    """
    u = np.ascontiguousarray(np.frombuffer(raw, dtype=np.uint8).reshape(-1, 4)[:, [2, 3, 0, 1]]
                             ).view("<u4").ravel()
    e = (u >> np.uint32(23)) & np.uint32(0xFF)
    out = (u - np.uint32(2 << 23)).view("<f4")          # right wherever e >= 3
    low = e < 3
    rounded = False
    if low.any():
        small = u[low]
        zero = e[low] == 0
        with np.errstate(invalid="ignore"):              # exponents 1-2: rounded to nearest
            vals = (small.view("<f4") / np.float32(4.0)).astype(np.float32)
        vals[zero] = (small[zero] & np.uint32(0x80000000)).view("<f4")      # VAX zero: +-0.0
        out[low] = vals
        rounded = bool((~zero).any())
    return out, rounded


#: the warning for :attr:`C3DData.dec_rounded` (spec §4.13: the one value a DEC float
#: cannot keep exactly)
DEC_ROUNDED = ("DEC float values below 2^-126 (about 1.2e-38) are kept as the nearest float32, "
               "a subnormal that holds fewer bits")


class _Codec:
    """Integer and float decoding for one processor type."""

    def __init__(self, processor: int) -> None:
        self.processor = processor
        big = processor == PROC_MIPS
        self.i2 = np.dtype(">i2" if big else "<i2")
        self.u2 = np.dtype(">u2" if big else "<u2")
        self.f4 = np.dtype(">f4" if big else "<f4")
        #: whether a DEC float below 2^-126 was read, rounded to a float32 subnormal
        self.rounded = False

    def int16(self, data: bytes, off: int, n: int = 1) -> NDArray[np.int16]:
        return np.frombuffer(data, self.i2, n, off)

    def uint16(self, data: bytes, off: int) -> int:
        return int(np.frombuffer(data, self.u2, 1, off)[0])

    def float32(self, data: bytes, off: int, n: int = 1) -> NDArray[np.float32]:
        raw = data[off:off + 4 * n]
        if len(raw) != 4 * n:
            _fail("float data runs past the end of the file", off)
        if self.processor == PROC_DEC:
            out, rounded = _dec_to_ieee(raw)
            self.rounded |= rounded
            return out
        return np.frombuffer(raw, self.f4).astype(np.float32)


def _parse_value(data: bytes, pos: int, codec: _Codec, end: int) -> ParamValue | None:
    """One parameter value: type, dimensions, data. Unknown types give None."""
    if pos + 2 > end:
        return None
    ptype = _s8(data[pos])
    ndim = data[pos + 1]
    if ptype not in _PARAM_TYPES or ndim > MAX_DIMS:
        return None  # tolerated: the next-offset word still lets us skip it
    dims = list(data[pos + 2:pos + 2 + ndim])
    pos += 2 + ndim
    size = abs(ptype)
    count = int(np.prod(dims)) if dims else 1
    if pos + size * count > len(data):
        return None
    if ptype == -1:
        raw = data[pos:pos + count]
        if ndim <= 1:
            return [_text(raw)]
        width = dims[0]
        if width == 0:
            return [""] * (count and int(np.prod(dims[1:])))
        return [_text(raw[i:i + width]) for i in range(0, count, width)]
    if ptype == 1:
        return np.frombuffer(data, np.int8, count, pos).astype(np.int64)
    if ptype == 2:
        return codec.int16(data, pos, count).astype(np.int64)
    with np.errstate(invalid="ignore"):     # a signalling NaN widens quietly, as ezc3d reads it
        return codec.float32(data, pos, count).astype(np.float64)


def record_params(records: list[ParamRecord]) -> dict[str, dict[str, ParamValue | None]]:
    """The parameters of normalised ``records`` (:func:`parse_records`), as
    :func:`_open` gives those of the section they came from: by upper-case
    group and name, a later record of a name replacing an earlier one; each value read by
    :func:`_parse_value` from the record's type, dimensions and (Intel) data."""
    groups = {-r.group: r.name.decode("latin-1").upper() for r in records if r.is_group}
    params: dict[str, dict[str, ParamValue | None]] = {name: {} for name in groups.values()}
    intel = _Codec(PROC_INTEL)
    for r in records:
        if r.is_group or r.group not in groups:
            continue
        body = bytes([r.type & 0xFF, len(r.dims), *r.dims]) + r.data
        params[groups[r.group]][r.name.decode("latin-1").upper()] = \
            _parse_value(body, 0, intel, len(body))
    return params


def _text(raw: bytes) -> str:
    """A C3D char field (UTF-8, else Latin-1), padded with blanks or NULs."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
    return text.strip(" \x00")


#: header words (1-based, as in the C3D guide) holding floats: scale, rate, 18 event times
_HEADER_FLOAT_WORDS = frozenset([7, 11] + list(range(153, 189, 2)))
#: header words holding bytes or chars, kept as stored: parameter block and key, event
#: display flags, event labels
_HEADER_BYTE_WORDS = frozenset([1] + list(range(189, 198)) + list(range(199, 235)))


def _normal_header(block: bytes, codec: _Codec) -> bytes:
    """The 512-byte header with integers little-endian and floats IEEE binary32 (§4.13.1)."""
    if codec.processor == PROC_INTEL:
        return bytes(block)
    out = bytearray(block)
    word = 1
    while word <= 256:
        at = 2 * (word - 1)
        if word in _HEADER_FLOAT_WORDS:
            out[at:at + 4] = codec.float32(block, at).astype("<f4").tobytes()
            word += 2
            continue
        if word not in _HEADER_BYTE_WORDS:
            out[at:at + 2] = codec.int16(block, at).astype("<i2").tobytes()
        word += 1
    return bytes(out)


def _normal_data(ptype: int, raw: bytes, codec: _Codec) -> bytes:
    """Parameter data in normalised form: int16 little-endian, float32 IEEE little-endian."""
    if codec.processor == PROC_INTEL or ptype in (-1, 1):
        return raw
    if ptype == 2:
        return codec.int16(raw, 0, len(raw) // 2).astype("<i2").tobytes()
    return codec.float32(raw, 0, len(raw) // 4).astype("<f4").tobytes()


def _section_end(data: bytes, start: int, data_start: int) -> int:
    """Where the parameter section at ``start`` ends: its declared block count or, when
    the header's data start (word 9, a 1-based block number) lies further, the data
    start; never past the end of the file (:func:`parse_records`)."""
    n_blocks = data[start + 2]
    return min(len(data), max(start + max(n_blocks, 1) * BLOCK, (data_start - 1) * BLOCK))


def parse_records(data: bytes, start: int, codec: _Codec, *,
                  sequential: bool = False, starts: list[int] | None = None,
                  skipped: list[tuple[int, bytes, str]] | None = None
                  ) -> list[ParamRecord]:
    """Every group and parameter record of the parameter section at ``start``, in file order.

    Follows the next-record offsets, ending at a record with a zero name length or group
    id, a zero offset, or the end of the section: its declared block count or, when the
    header's data start lies further (c3d.org Dance1.c3d declares 3 blocks and uses 11),
    the data start.
    The description is read only where the record's own offset leaves room for it (c3d.org
    Facial-Sing.c3d ends a record right after its data).

    ``sequential``: the records ezc3d reads with ``ignore_bad_formatting``
    (:func:`ezc3d_hazard`): each from the end of the one before (its description read
    whole), the offsets only ending the walk where they are zero, up to the end of the
    file. ``starts``, when given, gets the offset at which each record returned begins.

    Without ``sequential``, a parameter record that cannot be read (a type or dimension
    count no C3D has, or data past the section or the file) is left out and the walk goes
    on from its next-record offset; ``skipped``, when given, gets ``(group id, name, why)``
    of each (:func:`_records_not_kept` words the warning). Why: the walk ended there, and
    every record after it was lost without a word (a QA run of stop 72: ANALOG:GEN_SCALE
    given type 5 lost 27 of 48 parameters, EVENT and ANALOG:SCALE among them, and the
    C3D written back crashed ezc3d).
    """
    out: list[ParamRecord] = []
    end = len(data) if sequential else _section_end(data, start, codec.uint16(data, 16))
    pos = start + 4
    while pos + 2 <= end:
        name_len = _s8(data[pos])
        gid = _s8(data[pos + 1])
        if name_len == 0 or gid == 0:
            break
        name = bytes(data[pos + 2:pos + 2 + abs(name_len)])
        off_pos = pos + 2 + abs(name_len)
        if off_pos + 2 > end:
            break
        nxt = codec.uint16(data, off_pos)
        rec_end = off_pos + nxt if nxt and not sequential else end
        body = off_pos + 2
        locked = name_len < 0
        if gid < 0:
            desc = _description(data, body, rec_end, end)
            out.append(ParamRecord(gid, locked, name, desc))
            if starts is not None:
                starts.append(pos)
            after = body
        else:
            why = _unreadable(data, body, end)
            if why is not None:
                if sequential:
                    break
                if skipped is not None:
                    skipped.append((gid, name, why))
                if nxt == 0:
                    break
                pos = off_pos + nxt
                continue
            ptype = _s8(data[body])
            ndim = data[body + 1]
            dims = tuple(data[body + 2:body + 2 + ndim])
            size = abs(ptype) * (int(np.prod(dims)) if dims else 1)
            at = body + 2 + ndim
            raw = _normal_data(ptype, bytes(data[at:at + size]), codec)
            desc = _description(data, at + size, rec_end, end)
            out.append(ParamRecord(gid, locked, name, desc, ptype, dims, raw))
            if starts is not None:
                starts.append(pos)
            after = at + size
        if nxt == 0:
            break
        if not sequential:
            pos = off_pos + nxt
        elif after < len(data):
            pos = after + 1 + data[after]        # past the description's length and bytes
        else:
            break
    return out


def _unreadable(data: bytes, body: int, end: int) -> str | None:
    """Why the parameter record whose type byte is at ``body`` cannot be read, in a section
    that ends at ``end``, or None: its type and dimension count, then its dimensions within
    the section and its data within the file (:func:`parse_records`)."""
    if body + 2 > end:
        return "its type runs past the parameter section"
    ptype, ndim = _s8(data[body]), data[body + 1]
    if ptype not in _PARAM_TYPES:
        return f"type {ptype}; a C3D parameter's is -1, 1, 2 or 4"
    if ndim > MAX_DIMS:
        return f"{ndim} dimensions; a C3D parameter has at most {MAX_DIMS}"
    if body + 2 + ndim > end:
        return "its dimensions run past the parameter section"
    dims = data[body + 2:body + 2 + ndim]
    if body + 2 + ndim + abs(ptype) * math.prod(dims) > len(data):
        return "its data runs past the end of the file"
    return None


def _description(data: bytes, at: int, rec_end: int, end: int) -> bytes:
    """A record's description: a length byte and that many bytes, when the record has room."""
    if at >= min(rec_end, end):
        return b""
    n = data[at]
    return bytes(data[at + 1:min(at + 1 + n, len(data))])


def _first(params: dict[str, dict[str, ParamValue | None]], group: str, name: str,
           default: Any = None) -> Any:
    """First element of parameter ``group:name``, or ``default`` if it is absent or empty."""
    v = params.get(group, {}).get(name)
    if v is None or len(v) == 0:
        return default
    return v[0]


def param_number(params: dict[str, dict[str, ParamValue | None]], group: str, name: str,
            default: float, *, count: bool = False) -> float:
    """:func:`_first` of a numeric parameter: ``default`` if absent or empty. A char value
    (a text where the C3D user guide has a number), or for a ``count`` a value that is
    not finite, is an InputFormatError that names the parameter, not a ValueError from
    ``int('')`` or ``int(nan)``."""
    v = _first(params, group, name, default)
    if isinstance(v, str):
        _fail(f"{group}:{name} holds the text {v[:20]!r}, not a number")
    if count and not math.isfinite(float(v)):
        _fail(f"{group}:{name} is {float(v)!r}, not a count")
    return float(v)


def header_range_holds(first: int, last: int) -> bool:
    """Whether header words 4-5 (first and last frame) describe the file's frames: a
    non-empty range whose last frame is below 65535 (:func:`frame_range`; else the
    frame-count parameters of the C3D user guide do)."""
    return last - first + 1 > 0 and last < HEADER_MAX_FRAME


def _trial_frame(params: dict[str, dict[str, ParamValue | None]], name: str) -> int | None:
    """TRIAL:``name`` as the unsigned 32-bit frame number of its two int16 words (low,
    high), None when absent."""
    v = params.get("TRIAL", {}).get(name)
    if v is None:
        return None
    if isinstance(v, list) or v.dtype.kind != "i" or len(v) != 2:
        _fail(f"TRIAL:{name} is not two int16 words (low, high) of a frame number", 6)
    return int(v[0]) & 0xFFFF | (int(v[1]) & 0xFFFF) << 16


def _float_count(params: dict[str, dict[str, ParamValue | None]], name: str,
                 floats_only: bool) -> float | None:
    """POINT:``name`` as a frame count (its first element), None when absent or, with
    ``floats_only``, not stored as a float."""
    v = params.get("POINT", {}).get(name)
    if v is None or isinstance(v, list) or len(v) == 0 or (floats_only and v.dtype.kind != "f"):
        return None
    x = float(v[0])
    # 2^32: the float32 nearest the largest 32-bit count
    if not (math.isfinite(x) and 1 <= x <= 2.0 ** 32 and x == math.floor(x)):
        _fail(f"POINT:{name} is {x!r}, not a frame count (1 .. 2^32)", 6)
    return x


def frame_range(params: dict[str, dict[str, ParamValue | None]], first: int,
                last: int) -> tuple[int, int]:
    """The first frame number and the frame count of a C3D file.

    Parameters
    ----------
    params : dict
        The parameters (:func:`parse_c3d`'s ``params``).
    first, last : int
        Header words 4 and 5 (unsigned).

    The header's range is authoritative (c3d.org Dance1.c3d has POINT:FRAMES one larger
    than its data) unless it cannot describe the file: its last frame is 65535
    (``HEADER_MAX_FRAME``, the most a 16-bit word holds) or it is empty. Then the count
    comes from the parameters the C3D user guide names for frame counts above 65535:
    TRIAL:ACTUAL_START_FIELD and ACTUAL_END_FIELD (first and last frame, also giving the
    first frame number), POINT:LONG_FRAMES, POINT:FRAMES stored as a float. Those
    present must agree (a float agrees with n when it is float32(n)); they override the
    header, which the guide lets say 1..65535 whatever the range. An empty header
    without them falls back to an int16 POINT:FRAMES (unsigned).

    Raises
    ------
    InputFormatError
        For frame parameters that are malformed or disagree, and for no frames at all.
    """
    n = last - first + 1
    if header_range_holds(first, last):
        return first, n
    start = _trial_frame(params, "ACTUAL_START_FIELD")
    end = _trial_frame(params, "ACTUAL_END_FIELD")
    if (start is None) != (end is None):
        _fail("TRIAL:ACTUAL_START_FIELD and ACTUAL_END_FIELD come as a pair; one is "
              "missing", 6)
    counts: list[tuple[str, float, bool]] = []      # (parameter, count, stored as a float)
    if start is not None and end is not None:
        if end < start:
            _fail(f"TRIAL:ACTUAL_END_FIELD {end} is before ACTUAL_START_FIELD {start}", 6)
        counts.append(("TRIAL:ACTUAL_START_FIELD..ACTUAL_END_FIELD", end - start + 1, False))
    for name, floats_only in (("LONG_FRAMES", False), ("FRAMES", True)):
        x = _float_count(params, name, floats_only)
        if x is not None:
            counts.append((f"POINT:{name}", x, True))
    if counts:
        count = int(counts[0][1])
        # the TRIAL count is exact; a float count is the float32 nearest the count
        if any(v != (float(np.float32(count)) if flt else count) for _, v, flt in counts):
            said = ", ".join(f"{k} {v:.0f}" for k, v, _ in counts)
            _fail(f"inconsistent frame counts: {said} (header frames {first}..{last})", 6)
        return (start if start is not None else first), count
    if n > 0:
        return first, n
    fp = int(param_number(params, "POINT", "FRAMES", 0, count=True))
    n = fp + 65536 if fp < 0 else fp
    if n <= 0:
        _fail(f"no frames (header first {first}, last {last})", 6)
    return first, n


def check_key(head: bytes) -> None:
    """Refuse bytes whose header byte 1 is not the C3D key (80), from the first bytes alone:
    a reader can check it before it reads the rest (a 5 GB file of zeros was read whole
    first, a QA run)."""
    if len(head) >= 2 and head[1] != C3D_KEY:
        _fail(f"bad key byte 0x{head[1]:02x} at offset 1, expected 0x50", 1)


class _Section(NamedTuple):
    """The one walk of a parameter section (:func:`parse_records`): its records, the offset
    each begins at, and the records it left out (group id, name, why). The parameters,
    the layout's two record warnings and the ezc3d checks all read it: each walked the
    section again (0.05-1 ms a real file, up to a sixth of its read; review of stop 73)."""

    records: list[ParamRecord]
    starts: list[int]
    skipped: list[tuple[int, bytes, str]]


def _open(data: bytes) -> tuple[_Codec, int, _Section,
                                dict[str, dict[str, ParamValue | None]]]:
    """The codec, parameter-section offset, the section's walk and its parameters, of C3D
    bytes (checked)."""
    if len(data) < 2 * BLOCK:
        _fail(f"file too short ({len(data)} bytes) for a header and a parameter block")
    check_key(data)
    pstart = (data[0] - 1) * BLOCK
    if data[0] < 2 or pstart + 4 > len(data):
        _fail(f"parameter section block {data[0]} is outside the file", 0)
    processor = data[pstart + 3]
    if processor not in (PROC_INTEL, PROC_DEC, PROC_MIPS):
        _fail(f"unknown processor type {processor} (expected 84, 85 or 86)", pstart + 3)
    codec = _Codec(processor)
    # the parameters from the archive's own walk: a walk of their own stopped at the
    # declared block count, and a section declaring 1 block that goes on (as ezc3d reads
    # it) lost its POINT:LABELS while the archive kept them (a QA run of stop 72: markers
    # named _unnamed_0 ...)
    section = _Section([], [], [])
    section.records.extend(parse_records(data, pstart, codec, starts=section.starts,
                                         skipped=section.skipped))
    params = record_params(section.records)
    params.setdefault("POINT", {})
    return codec, pstart, section, params


@dataclass
class _Layout:
    """Where the 3D frames of a C3D file are and how long they are (:func:`_layout`)."""

    used: int
    scale: float
    first: int
    n_frames: int
    frame_bytes: int
    data_start: int
    warnings: list[str]


def _points_used(data: bytes, codec: _Codec,
                 params: dict[str, dict[str, ParamValue | None]]) -> int:
    """POINT:USED, else header word 2: the points of a 3D frame."""
    used = int(param_number(params, "POINT", "USED", int(codec.int16(data, 2)[0]), count=True))
    return used + 65536 if used < 0 else used  # unsigned in files with > 32767 points


def _layout(data: bytes, codec: _Codec, pstart: int, section: _Section,
            params: dict[str, dict[str, ParamValue | None]]) -> _Layout:
    """The points, storage, frame range and data start of C3D bytes (checked; the data is
    not read). The data start is :func:`_data_start`'s."""
    hdr_analog = codec.uint16(data, 4)  # analog measurements per 3D frame
    hdr_scale = float(codec.float32(data, 12)[0])
    used = _points_used(data, codec, params)
    if used > MAX_POINTS:
        _fail(f"POINT:USED {used} exceeds {MAX_POINTS}")
    scale = param_number(params, "POINT", "SCALE", hdr_scale)
    if not (math.isfinite(scale) and scale != 0):
        # its sign chooses the storage and its size scales int16 words: 0, NaN or inf made
        # every point a gap, silently (a hostile-input QA)
        # an Intel file marked DEC reads its scale -1.0 as a VAX zero: the processor byte
        # may be the fault, as for an implausible rate
        _fail(f"POINT:SCALE {scale!r} is not a finite number other than 0 (its sign says "
              f"float32 or int16 storage, its size the int16 step){processor_hint(data)}")
    # the header frame range, or the frame parameters when it cannot say (frame_range)
    first, n_frames = frame_range(params, codec.uint16(data, 6), codec.uint16(data, 8))
    scale, conflict = _storage_scale(data, codec, pstart, params, scale, used, hdr_analog,
                                     n_frames)
    frame_bytes = (4 * used + hdr_analog) * (4 if scale < 0 else 2)
    start, warning = _data_start(data, codec, pstart, params, n_frames * frame_bytes)
    warnings = [w for w in (conflict, warning,
                            _records_past_declared(data, codec, pstart, section.records,
                                                   section.starts),
                            _records_not_kept(section.records, section.skipped)) if w]
    hfirst, hlast = codec.uint16(data, 6), codec.uint16(data, 8)
    more = _more_frames(params, hfirst, hlast, len(data) - (start - 1) * BLOCK, frame_bytes)
    if more is not None:
        warnings.append(f"the header's frame range {hfirst}..{hlast} says {n_frames} frames, "
                        f"POINT:FRAMES {more}, and the data holds {more}: read {more}")
        n_frames = more
    return _Layout(used, scale, first, n_frames, frame_bytes, start, warnings)


def _records_past_declared(data: bytes, codec: _Codec, pstart: int,
                           every: list[ParamRecord], starts: list[int]) -> str | None:
    """A warning when the parameter records ``every`` (:func:`parse_records`, which gave
    their offsets ``starts``) run on past the section's declared block
    count (:func:`parse_records` reads them to the data start, as ezc3d does), naming what
    a reader that stops at the count does not see. Why: a C3D written back declares the
    blocks it fills, so such a reader sees more there than in the source (c3d.org Dance1:
    10 records of 28 begin within the count, so no ANALOG group, whose GEN_SCALE of -1
    then flips every analog value for it, and no POINT:DESCRIPTIONS; a QA run of stop 62
    with py-c3d)."""
    declared = data[pstart + 2]
    n_blocks = max(declared, 1)
    declared_end = pstart + n_blocks * BLOCK
    if _section_end(data, pstart, codec.uint16(data, 16)) <= declared_end:
        return None
    # what such a reader finds: the records that start within the count (py-c3d reads one
    # that goes on past it: Dance1's POINT:LABELS)
    within = every[:sum(s < declared_end for s in starts)]
    if len(within) >= len(every):
        return None
    group_names = {-r.group: r.name.decode("latin-1") for r in every if r.group < 0}
    kept = {(r.group, r.name) for r in within}
    unseen = [group_names[-r.group] for r in every if r.group < 0 and (r.group, r.name)
              not in kept]
    params = [f"{group_names.get(r.group, r.group)}:{r.name.decode('latin-1')}" for r in every
              if r.group > 0 and (r.group, r.name) not in kept
              and group_names.get(r.group) not in unseen]
    what = [f"the {' and '.join(unseen)} group{_s(len(unseen))}"] if unseen else []
    if params:
        shown = ", ".join(params[:4]) + (", ..." if len(params) > 4 else "")
        what.append(f"{len(params)} parameter{_s(len(params))} of the groups it does see "
                    f"({shown})")
    n_groups = len(group_names)
    n_params = len(every) - sum(r.group < 0 for r in every)
    return (f"the parameter section declares {declared} block{_s(declared)} but its records "
            f"go on past {'them' if declared != 1 else 'it'}: all {n_groups} group"
            f"{_s(n_groups)} and {n_params} parameter{_s(n_params)} are kept, as ezc3d reads "
            f"them; a reader that stops at the declared count (the C3D user guide's rule; "
            f"py-c3d) finds {' and '.join(what)} in a C3D written back but not in this file")


def _records_not_kept(every: list[ParamRecord],
                      skipped: list[tuple[int, bytes, str]]) -> str | None:
    """A warning naming the parameter records that :func:`parse_records` left out
    (``skipped``) beside those it read (``every``), and why, or None: the archive keeps
    every other record, and a C3D written back lacks these (spec §4.13.2 has no room for a
    type or dimension count that C3D lacks)."""
    if not skipped:
        return None
    groups = {-r.group: r.name.decode("latin-1") for r in every if r.is_group}
    named = [f"{groups.get(g, f'of group id {g}')}:{n.decode('latin-1')} ({why})"
             for g, n, why in skipped]
    shown = "; ".join(named[:4]) + ("; ..." if len(named) > 4 else "")
    kept = sum(not r.is_group for r in every)
    one = len(skipped) == 1
    return (f"{len(skipped)} parameter record{_s(len(skipped))} cannot be read and "
            f"{'is' if one else 'are'} not kept: {shown}; the other {kept} "
            f"parameter{_s(kept)} are kept, and a C3D written back lacks "
            f"{'it' if one else 'them'}")


def _s(n: int) -> str:
    """The plural ending for a count of ``n``."""
    return "" if n == 1 else "s"


def _more_frames(params: dict[str, dict[str, ParamValue | None]], first: int, last: int,
                 room: int, frame_bytes: int) -> int | None:
    """POINT:FRAMES (int16, unsigned) when it says more frames than a header range that
    holds (:func:`header_range_holds`) and the ``room`` bytes from the data start hold that
    many frames; else None. Reason: a header word changed to a smaller last frame would
    otherwise drop frames silently (ezc3d reads them all); when POINT:FRAMES says more
    than the data holds (c3d.org Dance1.c3d: one more), the header stands."""
    v = params.get("POINT", {}).get("FRAMES")
    if not header_range_holds(first, last) or v is None or isinstance(v, list) or \
            len(v) == 0 or v.dtype.kind != "i":
        return None
    frames = int(v[0]) & 0xFFFF
    if frames > last - first + 1 and frame_bytes and frames * frame_bytes <= room:
        return frames
    return None


def _data_start(data: bytes, codec: _Codec, pstart: int,
                params: dict[str, dict[str, ParamValue | None]],
                need: int) -> tuple[int, str | None]:
    """The first block of the 3D data, and a warning when the file states it twice and
    differently: header word 9 and POINT:DATA_START.

    A block *fits* when it lies past the parameter section and the ``need`` bytes of the
    declared frames from it lie inside the file. A POINT:DATA_START equal to word 9 leaves
    word 9 (outside the file is an error; inside a parameter section whose block count is
    wrong is not). One that is absent, or inside the header or parameter section (c3d.org
    sample13 and Dance1.c3d store 1 there, a known writer habit), leaves word 9, silently,
    unless word 9 itself is inside them (an error). Otherwise the two
    disagree: the one that fits is read, with a warning naming both; when both fit, word 9
    (the C3D user guide's pointer to the data, the one ezc3d follows), with the warning;
    when neither fits, an InputFormatError. Reason: a pointer into the header or the
    parameters, or one that leaves too few bytes for the frames, is certainly wrong, and
    the other one is the file's own second statement of the same number.

    Raises
    ------
    InputFormatError
        When the data start the file gives is outside the file or inside its header or
        parameter section, or when the two disagree and neither fits.
    """
    hdr = codec.uint16(data, 16)
    param_end = data[0] + max(data[pstart + 2], 1)    # the first block past the parameters
    raw = param_number(params, "POINT", "DATA_START", hdr, count=True)
    par = int(raw) + 65536 if raw < 0 else int(raw)

    def fits(block: int) -> bool:
        return block >= param_end and (block - 1) * BLOCK + need <= len(data)

    if par == hdr or par < param_end:
        if hdr < 2 or (hdr - 1) * BLOCK > len(data):
            _fail(f"data start block {hdr} is outside the file", 16)
        if par != hdr and hdr < param_end:      # POINT:DATA_START does not confirm it
            _fail(f"data start block {hdr} (header word 9) is inside the header or the "
                  f"parameter section (blocks 1 to {param_end - 1})", 16)
        return hdr, None
    said = f"the header's data start (word 9) is block {hdr}, POINT:DATA_START {par}"
    if not fits(hdr) and not fits(par):
        _fail(f"{said}, and neither leaves room for the {need} bytes of the declared "
              f"frames past the parameter section (blocks 1 to {param_end - 1}) of this "
              f"{len(data)}-byte file", 16)
    use = hdr if fits(hdr) else par
    other = par if use == hdr else hdr
    why = ("both fit; the header's is the C3D user guide's pointer" if fits(other) else
           f"block {other} is inside the header or the parameter section"
           if other < param_end else f"from block {other} the frames would not fit the file")
    return use, f"{said}: read from block {use} ({why})"


def data_start(data: bytes) -> tuple[int, int, str | None]:
    """The first block of the 3D data of C3D bytes, header word 9, and the warnings of
    :func:`_layout` (:func:`_data_start`, :func:`_more_frames`), for choosing a reader:
    ezc3d reads from header word 9.

    Raises
    ------
    InputFormatError
        As :func:`parse_c3d` does for the header, the parameters and the layout.
    """
    codec, pstart, section, params = _open(data)
    lay = _layout(data, codec, pstart, section, params)
    return lay.data_start, codec.uint16(data, 16), "; ".join(lay.warnings) or None


def scale_conflict(data: bytes) -> str | None:
    """Why the header's scale (words 7-8) and POINT:SCALE disagree: the header's is zero,
    not finite, or of the other sign (the other storage), and which one this reader
    follows (:func:`_storage_scale`); None when they agree in that, there is no
    POINT:SCALE, or it is one :func:`parse_c3d` refuses. ezc3d read such files as other
    numbers (a QA run: Sample_Jump2 with a header scale of 0 moved by 2 m; ezc3d 1.7.2
    reads a float file whose POINT:SCALE is positive as int16)."""
    codec, pstart, _, params = _open(data)
    return _scale_conflict(data, codec, pstart, params)


@dataclass(frozen=True)
class ReaderChecks:
    """What the C3D reader must know before it lets ezc3d open a file (:func:`reader_checks`).

    ``hazard`` (:func:`ezc3d_hazard`), ``conflict`` (:func:`scale_conflict`) and, when
    both are None, ``data_start``, ``word9`` and ``note`` (:func:`data_start`), and
    ``case`` (:func:`_case_ezc3d_misses`)."""

    first: int
    declared: int
    hazard: str | None
    conflict: str | None = None
    data_start: int = 0
    word9: int = 0
    note: str | None = None
    case: str | None = None


#: the groups whose parameters the readers look up by name to read the points: ezc3d
#: compares names exactly, in upper case, where C3D compares them without case (spec §6.9)
_LOOKED_UP = (b"POINT", b"ANALOG", b"TRIAL")


def _case_ezc3d_misses(records: list[ParamRecord]) -> str | None:
    """The first group of :data:`_LOOKED_UP`, or parameter of one, whose name is not
    written in upper case (ASCII), said for the reader's note; None when there is none.
    Why: ezc3d takes a group named ``point`` for another group than POINT, finds no
    POINT:RATE and reads a rate of 0 (vector u81 written back, stop 72)."""
    groups = {-r.group: r.name for r in records if r.is_group}
    for r in records:
        group = r.name if r.is_group else groups.get(r.group, b"")
        if group.upper() in _LOOKED_UP and r.name != r.name.upper():
            what = "group" if r.is_group else f"parameter of {group.decode('latin-1')}"
            return f"a {what} named {r.name.decode('latin-1')!r}"
    return None


def reader_checks(data: bytes) -> ReaderChecks:
    """:func:`declared_frames`, then :func:`ezc3d_hazard`, :func:`scale_conflict` and
    :func:`data_start` as far as each is needed, from one parse of the parameter section
    (each of them parses it on its own: four times a read, 0.3-1.7 ms each on the real
    files).

    Raises
    ------
    InputFormatError
        As those functions do, in that order.
    """
    codec, pstart, section, params = _open(data)
    first, declared = frame_range(params, codec.uint16(data, 6), codec.uint16(data, 8))
    hazard = ezc3d_hazard(data)
    if hazard is not None:
        return ReaderChecks(first, declared, hazard)
    conflict = _scale_conflict(data, codec, pstart, params)
    if conflict is not None:
        return ReaderChecks(first, declared, None, conflict)
    lay = _layout(data, codec, pstart, section, params)
    return ReaderChecks(first, declared, None, None, lay.data_start, codec.uint16(data, 16),
                        "; ".join(lay.warnings) or None, _case_ezc3d_misses(section.records))


def _scale_conflict(data: bytes, codec: _Codec, pstart: int,
                    params: dict[str, dict[str, ParamValue | None]]) -> str | None:
    """:func:`scale_conflict` of parsed parameters."""
    par = param_number(params, "POINT", "SCALE", float(codec.float32(data, 12)[0]))
    if not (math.isfinite(par) and par != 0):
        return None                             # _layout refuses it, naming POINT:SCALE
    _, n_frames = frame_range(params, codec.uint16(data, 6), codec.uint16(data, 8))
    return _storage_scale(data, codec, pstart, params, par, _points_used(data, codec, params),
                          codec.uint16(data, 4), n_frames)[1]


def _storage_scale(data: bytes, codec: _Codec, pstart: int,
                   params: dict[str, dict[str, ParamValue | None]], par: float, used: int,
                   analog: int, n_frames: int) -> tuple[float, str | None]:
    """The signed scale that reads C3D ``data``, and :func:`scale_conflict`'s warning (None
    when the header's scale, words 7-8, agrees with POINT:SCALE ``par``, a finite number
    other than 0): ``par``, or its size with the sign of the header's scale when the two
    disagree in sign and only the header's storage fits the file.

    A storage *fits* when the ``n_frames`` frames of ``used`` points and ``analog`` words
    (int16: 2 bytes a word, float32: 4), from the data start :func:`_data_start` finds for
    them, end within the file and leave less than a block and a frame after them (the
    padding :func:`frames_unread` allows). Reason: float32 frames are twice the size of
    int16 ones, so the wrong storage either runs past the end of the file (an int16 file
    whose POINT:SCALE is negative was refused as truncated) or leaves half of it unread (a
    float file whose POINT:SCALE is positive was read as int16 garbage, with a warning
    about frames past the header's range; a QA run of stop 63). When both or neither fit
    (a file of a frame or two), POINT:SCALE decides, as in the C3D user guide, and its
    size is the int16 step either way (the archive's and the writer's, spec §6.9
    *Scale*)."""
    hdr = float(codec.float32(data, 12)[0])
    said = f"the header's scale {hdr!r} disagrees with POINT:SCALE {par!r}"
    if par == hdr or (math.isfinite(hdr) and hdr != 0 and (hdr < 0) == (par < 0)):
        return par, None
    if not (math.isfinite(hdr) and hdr != 0):
        return par, f"{said} (the storage and step were taken from POINT:SCALE)"

    def fits(float32: bool) -> bool:
        frame_bytes = (4 * used + analog) * (4 if float32 else 2)
        need = n_frames * frame_bytes
        try:
            start, _ = _data_start(data, codec, pstart, params, need)
        except InputFormatError:           # no data start leaves room for these frames
            return False
        extra = len(data) - (start - 1) * BLOCK - need
        return 0 <= extra < BLOCK + frame_bytes

    if fits(hdr < 0) and not fits(par < 0):
        storage, other = ("float32", "int16") if hdr < 0 else ("int16", "float32")
        step = ", with the size of POINT:SCALE as the step" if hdr > 0 else ""
        return math.copysign(par, hdr), (
            f"{said}: the file's size fits {n_frames} frames of {storage} points, as the "
            f"header says, and not of {other}, so they were read as {storage}{step}; a C3D "
            "written back gives POINT:SCALE the sign of its storage")
    return par, f"{said} (the storage and step were taken from POINT:SCALE)"


#: the processor types' names, as messages say them
PROCESSOR_NAMES = {PROC_INTEL: "Intel", PROC_DEC: "DEC", PROC_MIPS: "MIPS"}


def processor_hint(data: bytes) -> str:
    """For the message about an implausible frame rate or point scale: what the processor
    byte says, and the frame rate (POINT:RATE, else header words 11-12) each other
    processor type reads,
    where that is a plausible rate (a finite float32 of 1e-6 Hz or more); "" when none
    is, or the bytes are no C3D file."""
    try:
        _, pstart, _, _ = _open(data)
    except InputFormatError:
        return ""
    proc = data[pstart + 3]
    others = []
    for other in (PROC_INTEL, PROC_DEC, PROC_MIPS):
        if other == proc:
            continue
        c = _Codec(other)
        try:
            rate = param_number(record_params(parse_records(data, pstart, c)), "POINT", "RATE",
                                float(c.float32(data, 20)[0]))
        except InputFormatError:
            continue
        if math.isfinite(rate) and 1e-6 <= rate <= F32_MAX:
            others.append(f"as {PROCESSOR_NAMES[other]} ({other}) it reads {rate:g} Hz")
    if not others:
        return ""
    return (f"; is the processor byte (byte 4 of the parameter section: "
            f"{PROCESSOR_NAMES[proc]}, {proc}) wrong? " + "; ".join(others))


def frames_missing(data: bytes, declared: int, present: int,
                   offset: int | None = None) -> InputFormatError:
    """The error for C3D bytes of which a reader found ``present`` frames where ``declared``
    are declared: :func:`truncated`, unless the header's own range (words 4-5) says
    ``declared`` and POINT:FRAMES disagrees with it while the file is whole: the data holds
    exactly POINT:FRAMES frames (a frame word of the header is wrong: a first frame 0,
    say), or all ``declared`` (ezc3d stops at POINT:FRAMES); the message then says so."""
    try:
        codec, pstart, section, params = _open(data)
        frames = param_number(params, "POINT", "FRAMES", -1)
        lay = _layout(data, codec, pstart, section, params)
        repeated = _repeated_layout(section.records)
    except InputFormatError:
        return truncated(declared, present, offset)
    if repeated:
        # the last of a repeated POINT:USED is the one read (ezc3d's too): a file whose
        # POINT:RATE was renamed USED was called "truncated" (a fuzzing QA run of stop 54)
        return InputFormatError(f"C3D: {declared} frames declared, {present} present, with "
                                f"{repeated}, the last of which sets the frame size here: "
                                "is the file whole and one of them wrong?", offset=offset)
    first, last = codec.uint16(data, 6), codec.uint16(data, 8)
    holds = _data_bytes(data, lay) // lay.frame_bytes if lay.frame_bytes else declared
    fp = int(frames) & 0xFFFF if math.isfinite(frames) and frames >= 0 else -1
    if header_range_holds(first, last) and last - first + 1 == declared and fp != declared \
            and holds in (fp, declared):
        wrong = "a first or last frame word of the header (words 4-5)" if holds == fp else \
            "POINT:FRAMES"
        return InputFormatError(
            f"C3D: the header's frame range {first}..{last} ({declared} frames) disagrees "
            f"with POINT:FRAMES {fp}, and the data holds {holds} frames: {wrong} is wrong",
            offset=6)
    return truncated(declared, present, offset)


def _analog_samples(params: dict[str, dict[str, ParamValue | None]], words: int) -> int:
    """The analog samples a channel has in a frame of ``words`` analog words when header
    word 10, which says it, is 0 or does not divide ``words``: ``words`` / ANALOG:USED when
    that is a whole number, else 1 (one word per "channel"; the words are kept in their
    order either way). Reason: a word 10 of 0 made 2 channels of 2 samples read as 4
    channels of 1, which ``mpz show`` printed (a QA run of stop 63)."""
    used = _first(params, "ANALOG", "USED", 0)     # a text or NaN there: no help
    channels = int(used) & 0xFFFF if not isinstance(used, str) and math.isfinite(used) else 0
    if words and channels and words % channels == 0:
        return words // channels
    return 1 if words else 0


def _data_bytes(data: bytes, lay: _Layout) -> int:
    """The bytes of C3D ``data`` from the start of its 3D data (:class:`_Layout`) on."""
    return len(data) - (lay.data_start - 1) * BLOCK


def frames_unread(data: bytes, read: int) -> str | None:
    """A warning when the data holds whole frames past the ``read`` frames of the header's
    range (the header is authoritative, :func:`frame_range`, as for ezc3d), beyond what
    padding explains (up to a whole block), or None. Such a stale header (spec §4.13.1 keeps one:
    vector u42's C3D written back) read as 2 of its 24 frames, with no word (a CLI
    fuzzing QA run of stop 54)."""
    try:
        codec, pstart, section, params = _open(data)
        lay = _layout(data, codec, pstart, section, params)
    except InputFormatError:
        return None
    if not lay.frame_bytes:
        return None
    extra = _data_bytes(data, lay) - read * lay.frame_bytes
    if extra < BLOCK + lay.frame_bytes:
        # padding: up to a whole block of it, which some writers add after the last
        # block's remainder (mpz.tools.make_example's walk.c3d: 512 bytes)
        return None
    frames = param_number(params, "POINT", "FRAMES", -1)
    said = (f", and POINT:FRAMES says {int(frames) & 0xFFFF}"
            if math.isfinite(frames) and frames >= 0 else "")
    return (f"the data holds {extra} bytes past the {read} frames of the header's frame "
            f"range (words 4-5), room for up to {extra // lay.frame_bytes} more frames "
            f"(padding included){said}: they are not read (the C3D user guide and ezc3d "
            "go by the header); is the header stale?")


def first_number(r: ParamRecord) -> float | None:
    """The first element of a numeric parameter record (normalised data: int8, int16 or
    float32, little-endian), or None for a char one or one without an element."""
    fmt = {1: "<i1", 2: "<i2", 4: "<f4"}.get(r.type)
    if fmt is None or len(r.data) < abs(r.type):
        return None
    return float(np.frombuffer(r.data, fmt, 1)[0])


def _repeated_layout(records: list[ParamRecord]) -> str:
    """The parameters that set the data's layout (POINT:USED, ANALOG:USED, ANALOG:RATE,
    POINT:RATE) given more than once with other values, as text ("" when none is)."""
    said = []
    for group, name in ((b"POINT", b"USED"), (b"ANALOG", b"USED"), (b"ANALOG", b"RATE"),
                        (b"POINT", b"RATE")):
        values = [v for v in (first_number(records[i]) for i in named(records, group, name))
                  if v is not None]
        if len(set(values)) > 1:
            said.append(f"{group.decode()}:{name.decode()} given {len(values)} times "
                        f"({', '.join(f'{v:g}' for v in values)})")
    return "; ".join(said)


def declared_frames(data: bytes) -> tuple[int, int]:
    """The first frame number and frame count that C3D bytes declare (:func:`frame_range`),
    without reading the data; for checking another reader's frame count.

    Raises
    ------
    InputFormatError
        As :func:`parse_c3d` does for the header, the parameters and the frame range.
    """
    codec, _, _, params = _open(data)
    return frame_range(params, codec.uint16(data, 6), codec.uint16(data, 8))


def is_mips(data: bytes) -> bool:
    """Whether C3D bytes say MIPS (big-endian) in their parameter section's processor byte:
    valid C3D that ezc3d refuses before reading its parameters."""
    start = (data[0] - 1) * BLOCK if data else -1
    return 0 <= start < len(data) - 3 and data[start + 3] == PROC_MIPS


#: the starts of :func:`ezc3d_hazard`'s reasons that are faults of the file itself (a
#: section that loops or runs past the file, a record's data past its record, a type or a
#: dimension count no C3D has), not ezc3d's fragility on a file C3D allows: the reader
#: warns of these, and only notes the others (which reader read the file, and why)
FILE_FAULTS = ("a parameter section whose records loop", "a parameter record past the end",
               "a parameter with ", "a parameter of type ", "the record of parameter ")


def hazard_is_fault(why: str) -> bool:
    """Whether an :func:`ezc3d_hazard` reason is a fault of the file (:data:`FILE_FAULTS`)."""
    return why.startswith(FILE_FAULTS)


def ezc3d_hazard(data: bytes, *, ignore_bad_formatting: bool = False) -> str | None:
    """Why ezc3d must not open these C3D bytes, or None; with ``ignore_bad_formatting``,
    why it must not open them so (``ezc3d.c3d(path, ignore_bad_formatting=True)``).

    ezc3d 1.7.2 ends the process (a segmentation fault or an abort, not an exception), or
    does not return, on the parameter sections below. They were found by mutating real and
    synthetic files and opening each in a forked process (about 19,000 files, issue 15 stop
    27); the rule flags every crash found, none of the 18 real files of ``../shared/data``,
    and 345 of 345 crashes of a later run it was not built from. The reader then uses
    :func:`parse_c3d` alone, so that no input brings the process down. In ezc3d's terms
    (it compares names exactly, upper case):

    1. a char parameter with no dimensions;
    2. POINT:USED, SCALE, RATE or FRAMES, ANALOG:USED, RATE or GEN_SCALE (and with a
       ROTATION group its USED, DATA_START and RATIO) present with no element;
    3. ANALOG:USED > 0 with ANALOG:SCALE or ANALOG:OFFSET missing or empty, unless there
       is a SHADOW group;
    4. a ROTATION group with RATIO < 0, or without RATIO and a negative ROTATION:RATE or
       POINT:RATE;
    5. ROTATION:USED > 0 with a rotation block not inside the file (an abort);
    6. a description length of 128 or more (ezc3d reads the byte signed: 255 crashed it,
       and 185, one byte changed in a real file's SUBJECT group, took 17 s and 12.6 GB
       before an exception, a QA run of stop 50), a dimension count above 7, an unknown
       type or a record past the end of the file, walked as ezc3d walks the section
       (signed bytes, past records :func:`parse_records` would stop at);
    7. ANALOG:RATE more than 10,000 times POINT:RATE (ezc3d allocates for it, or hangs);
    8. a parameter whose data (its type times its dimensions) runs past its record's
       next-record offset, or, for the last record, past the parameter section
       (:func:`_section_end`): a dimension byte changed in a file that is otherwise whole
       (ANALOG:SCALE of 255 elements in a file of 32 channels; with
       ``ignore_bad_formatting`` ezc3d then crashes, found by a later QA run). The file
       contradicts itself, so it is not one ezc3d is needed for;
    9. two group records of one name (compared in upper case): ezc3d looks a parameter up
       in the first, and rules 2-5 and 7 would judge another (a QA run of stop 54: two
       ANALOG groups, the first with USED 5 and no OFFSET, crashed ezc3d);
    10. a char parameter whose strings have no character (a first dimension of 0) and
        that counts more than :data:`MAX_EMPTY_STRINGS` of them (the product of its other
        dimensions): it holds no data byte, so rule 8 does not bound it, and ezc3d makes
        each string (a fuzzing QA run of the readers: a real file's LABEL_PREFIXES of
        dimensions (0, 1) given 7 dimensions by one byte, the description's first bytes
        read as the others, was 2 x 10^9 strings: 157 s and 16.9 GB, or a
        ``std::bad_alloc``; 0 x 255 x 255 x 255 took 6 s and 2.2 GB).

    With ``ignore_bad_formatting`` the section is walked as ezc3d walks it then: a record
    that does not end where the one before it says the next begins is not refused, and
    ezc3d reads on from the end of its description, not from that offset, until a record
    whose offset is zero. Every rule is applied to the records so reached (a fuzzing run
    of the readers, stop 57: a 7.7 KB file whose POINT:LABELS description ran past its
    record had ezc3d read its point data as parameters, 12 GB in 3 s; an ANALOG group
    whose offset pointed past the file hid an ANALOG:RATE without element, a segmentation
    fault; the walk by offsets found neither).
    """
    start = (data[0] - 1) * BLOCK if len(data) > BLOCK else -1
    if start < BLOCK or start + 4 > len(data):
        return None                       # parse_c3d gives the precise error
    if is_mips(data):
        return None                       # ezc3d refuses these before their parameters
    why = _ezc3d_walk(data, start, ignore_bad_formatting)
    if why is None:
        why = _ezc3d_values(data, start, ignore_bad_formatting)
    return None if why is None else f"{why} (files like it crash ezc3d 1.7)"


def _ezc3d_walk(data: bytes, start: int, sequential: bool = False) -> str | None:
    """Rules 6 and 8 of :func:`ezc3d_hazard`: the section walked record by record as ezc3d
    does: from each record's next-record offset, or, ``sequential``, from the end of its
    description (ezc3d with ``ignore_bad_formatting``)."""
    pos, seen = start + 4, set()
    groups: dict[int, str] = {}
    section_end = _section_end(data, start, int.from_bytes(data[16:18], "little"))
    while pos + 2 <= len(data):
        if pos in seen:
            return "a parameter section whose records loop"
        seen.add(pos)
        name_len, gid = _s8(data[pos]), _s8(data[pos + 1])
        if name_len == 0 or gid == 0:
            return None
        off = pos + 2 + abs(name_len)
        if off + 2 > len(data):
            return "a parameter record past the end of the file"
        nxt = int.from_bytes(data[off:off + 2], "little")
        body = off + 2
        if gid < 0:
            desc_at = body
            groups[-gid] = bytes(data[pos + 2:off]).decode("latin-1")
        else:
            if body + 2 > len(data):
                return "a parameter record past the end of the file"
            ptype, ndim = _s8(data[body]), data[body + 1]
            if ndim > MAX_DIMS:
                return f"a parameter with {ndim} dimensions"
            if ptype not in _PARAM_TYPES:
                return f"a parameter of type {ptype}"
            dims = data[body + 2:body + 2 + ndim]
            if ptype == -1 and ndim > 1 and dims[0] == 0 \
                    and math.prod(dims[1:]) > MAX_EMPTY_STRINGS:          # rule 10
                return (f"a char parameter of {math.prod(dims[1:])} strings of no character "
                        f"(dimensions {tuple(dims)}), more than {MAX_EMPTY_STRINGS}")
            desc_at = body + 2 + ndim + abs(ptype) * (math.prod(dims) if ndim else 1)
            if desc_at >= len(data):
                return "a parameter record past the end of the file"
            # rule 8: the data must end where the record does (its next-record offset),
            # the last record's inside the parameter section
            rec_end = off + nxt if nxt else section_end
            if desc_at > rec_end:
                where = "into the next record" if nxt else "past the parameter section"
                name = bytes(data[pos + 2:off]).decode("latin-1")
                group = groups.get(gid)
                name = f"{group}:{name}" if group is not None else name
                return (f"the record of parameter {name} (dimensions {tuple(dims)}, "
                        f"{desc_at - body - 2 - ndim} data bytes) runs {where}")
        if desc_at < len(data) and data[desc_at] >= 128:
            return f"a description length of {data[desc_at]} (128 or more)"
        if nxt == 0:
            return None
        if not sequential:
            pos = off + nxt
        elif desc_at < len(data):
            pos = desc_at + 1 + data[desc_at]
        else:
            return "a parameter record past the end of the file"
    return None


def _ezc3d_values(data: bytes, start: int, sequential: bool = False) -> str | None:
    """Rules 1-5, 7 and 9 of :func:`ezc3d_hazard`, on the records :func:`parse_records`
    reads (``sequential``: those ezc3d reads with ``ignore_bad_formatting``)."""
    try:
        codec = _Codec(data[start + 3])
        records = parse_records(data, start, codec, sequential=sequential)
    except InputFormatError:
        return None                       # parse_c3d gives the precise error
    groups = {-r.group: r.name for r in records if r.is_group}
    params = {(groups.get(r.group, b""), r.name): r for r in records if not r.is_group}

    def count(r: ParamRecord) -> int:
        return math.prod(r.dims) if r.dims else 1

    def first(key: tuple[bytes, bytes]) -> float | None:
        r = params.get(key)
        return None if r is None or count(r) == 0 else first_number(r)

    for r in records:
        if not r.is_group and r.type == -1 and not r.dims:
            return f"a char parameter without dimensions ({r.name.decode('latin-1')})"
    names = [r.name.upper() for r in records if r.is_group]
    twice = next((n for i, n in enumerate(names) if n in names[:i]), None)
    if twice is not None:
        # rule 9: the dict above keeps the last group of a name and ezc3d the first, so
        # rule 3 looked at another ANALOG:USED than ezc3d's (a QA run of stop 54: a
        # segmentation fault in mpz show, encode, compare and summary)
        return f"a group name declared twice ({twice.decode('latin-1')})"
    needed = [(b"POINT", b"USED"), (b"POINT", b"SCALE"), (b"POINT", b"RATE"),
              (b"POINT", b"FRAMES"), (b"ANALOG", b"USED"), (b"ANALOG", b"RATE"),
              (b"ANALOG", b"GEN_SCALE")]
    rotation = b"ROTATION" in groups.values()
    if rotation:
        needed += [(b"ROTATION", b"USED"), (b"ROTATION", b"DATA_START"), (b"ROTATION", b"RATIO")]
    for key in needed:
        if key in params and count(params[key]) == 0:
            return f"{b':'.join(key).decode()} with no element"
    used = first((b"ANALOG", b"USED"))
    if used and b"SHADOW" not in groups.values():
        for name in (b"SCALE", b"OFFSET"):
            got = params.get((b"ANALOG", name))
            if got is None or count(got) == 0:
                return f"analog channels without ANALOG:{name.decode()}"
    if rotation:
        ratio = first((b"ROTATION", b"RATIO"))
        if (b"ROTATION", b"RATIO") not in params:
            rates = (first((b"ROTATION", b"RATE")), first((b"POINT", b"RATE")))
            if any(r is not None and r < 0 for r in rates):
                return "a ROTATION group without RATIO and a negative rate"
        elif ratio is not None and ratio < 0:
            return "ROTATION:RATIO < 0"
        rot_used = first((b"ROTATION", b"USED")) or 0
        rot_start = first((b"ROTATION", b"DATA_START")) or 0
        if rot_used > 0 and ratio is not None and ratio > 0:
            frames = first((b"POINT", b"FRAMES")) or 0
            if frames <= 0 or rot_start <= 0 or \
                    (rot_start - 1) * BLOCK + frames * ratio * rot_used * 64 > len(data):
                return "a ROTATION block not inside the file"
    analog_rate, point_rate = first((b"ANALOG", b"RATE")), first((b"POINT", b"RATE"))
    if analog_rate and point_rate and point_rate > 0 and analog_rate / point_rate > 10000:
        return "ANALOG:RATE more than 10,000 times POINT:RATE"
    return None


def parse_c3d(data: bytes, *, frames: int | None = None) -> C3DData:
    """Parse a complete C3D file held in memory.

    Parameters
    ----------
    data : bytes
        The file contents.
    frames : int, optional
        Read the points and analog words of the first ``frames`` frames only (the
        header, the parameters and the whole file's length are still checked); default:
        every frame. For checking a file just written (:func:`mpz.io.c3d.read_back`).

    Returns
    -------
    C3DData

    Raises
    ------
    InputFormatError
        If the bytes are not a C3D file or are truncated.
    """
    codec, pstart, section, params = _open(data)
    processor = codec.processor
    header_block = _normal_header(data[:BLOCK], codec)
    records = parse_records(data, pstart, codec)

    hdr_analog = codec.uint16(data, 4)  # analog measurements per 3D frame
    hdr_rate = float(codec.float32(data, 20)[0])
    lay = _layout(data, codec, pstart, section, params)
    used, scale, first, n_frames = lay.used, lay.scale, lay.first, lay.n_frames
    float_storage = scale < 0
    frame_words = 4 * used + hdr_analog
    frame_bytes = lay.frame_bytes
    data_start = lay.data_start
    off = (data_start - 1) * BLOCK
    avail = (len(data) - off) // frame_bytes if frame_bytes else n_frames
    if avail < n_frames:
        raise frames_missing(data, n_frames, avail, off)
    in_file = n_frames
    if frames is not None:
        n_frames = min(n_frames, max(frames, 0))
    samples = codec.uint16(data, 18)  # header word 10: analog samples per channel per frame
    if used == 0:
        return C3DData(np.zeros((n_frames, 0, 3)), np.zeros((n_frames, 0), np.int64),
                       params, processor, float_storage, hdr_rate, header_block, records,
                       first_frame=first, warnings=lay.warnings, frames_in_file=in_file)

    # read the frames, then keep the 4*used point words of each
    raw = data[off:off + n_frames * frame_bytes]
    words: NDArray[np.float32] | NDArray[np.int16]
    if float_storage:
        words = codec.float32(raw, 0, n_frames * frame_words).reshape(n_frames, frame_words)
    else:
        words = codec.int16(raw, 0, n_frames * frame_words).reshape(n_frames, frame_words)
    with np.errstate(invalid="ignore"):     # signalling NaNs (a gap's bits) widen quietly
        pts = words[:, :4 * used].reshape(n_frames, used, 4).astype(np.float64)
    # the archive keeps the fourth words and the analog words as stored (normalised)
    store = "<f4" if float_storage else "<i2"
    point_words = np.ascontiguousarray(words[:, 3:4 * used:4]).astype(store)
    if samples < 1 or hdr_analog % samples:
        samples = _analog_samples(params, hdr_analog)
    channels = hdr_analog // samples if hdr_analog else 0
    analog = np.ascontiguousarray(words[:, 4 * used:]).astype(store).reshape(
        n_frames * samples if channels else 0, channels)
    if float_storage:
        # the residual word is stored as a float holding an integer; a NaN one holds none:
        # residual 0, as ezc3d reads it (read_c3d), so both readers keep the sample
        r = pts[:, :, 3]
        res = np.where(np.isnan(r), 0.0, np.clip(r, -32768, 32767)).astype(np.int64)
        xyz = pts[:, :, :3]
    else:
        res = pts[:, :, 3].astype(np.int64)
        xyz = pts[:, :, :3] * abs(scale)
    return C3DData(xyz, res, params, processor, float_storage, hdr_rate, header_block, records,
                   point_words, analog, samples, first, lay.warnings, codec.rounded, in_file)


# ------------------------------------------------------------------ writing --
#: the largest parameter section a C3D header can point past: byte 2 of the section is a u8
MAX_PARAM_BLOCKS = 255


def _record_body(r: ParamRecord) -> bytes:
    """A record's bytes after its next-record offset field."""
    if r.is_group:
        return bytes([len(r.description)]) + r.description
    return (bytes([r.type & 0xFF, len(r.dims)]) + bytes(r.dims) + r.data
            + bytes([len(r.description)]) + r.description)


#: the largest next-record offset a reader that takes it as signed (the C3D user guide,
#: ezc3d) follows; spec §6.9 writes it unsigned, up to 65535
SIGNED_OFFSET_LIMIT = 0x7FFF


def long_offsets(records: list[ParamRecord]) -> list[bytes]:
    """The names of the records (all but the last) whose next-record offset exceeds
    :data:`SIGNED_OFFSET_LIMIT` and fits 16 bits: spec §6.9 writes them, and readers that
    take the offset as signed cannot follow them. One beyond 65535 is refused, not written
    (a note said such a record was "written unsigned" before the writer refused it: vector
    u94, a maintainer's QA run of stop 73)."""
    return [r.name for r in records[:-1]
            if SIGNED_OFFSET_LIMIT < 2 + len(_record_body(r)) <= 0xFFFF]


def _record_bytes(r: ParamRecord, last: bool) -> bytes:
    """One parameter-section record (Intel), its next-record offset 0 when ``last``
    (spec §6.9: unsigned 16-bit)."""
    if not 1 <= len(r.name) <= 127 or len(r.description) > 255:
        raise InputFormatError(f"C3D: parameter name {r.name!r} or its description does not "
                               f"fit a C3D record (1..127 and 0..255 bytes)")
    head = bytes([(-len(r.name) if r.locked else len(r.name)) & 0xFF, r.group & 0xFF]) + r.name
    body = _record_body(r)
    nxt = 0 if last else 2 + len(body)
    if nxt > 0xFFFF:
        raise InputFormatError(f"C3D: record {r.name!r} needs a next-record offset of {nxt} "
                               f"(its {len(body)} bytes after the offset field, "
                               f"{len(r.data)} of them data), beyond the 16-bit field's 65535")
    return head + nxt.to_bytes(2, "little") + body


def named(records: list[ParamRecord], group: bytes, name: bytes) -> list[int]:
    """The indexes, in file order, of the parameter records ``group:name``: the name is
    ``name`` and the group is any group record named ``group`` (names compared as ASCII
    without case, as spec §6.9 compares them)."""
    gids = {-r.group for r in records if r.is_group and r.name.upper() == group.upper()}
    return [i for i, r in enumerate(records)
            if not r.is_group and r.group in gids and r.name.upper() == name.upper()]


def analog_unsigned(records: list[ParamRecord]) -> bool:
    """Spec §6.9: whether the first parameter record named FORMAT in a group named ANALOG
    (names as ASCII without case) is a char value that reads UNSIGNED (without case, blanks
    and NULs around it): the source's int16 analog words are then unsigned."""
    first = named(records, b"ANALOG", b"FORMAT")[:1]
    return any(records[i].type == -1 and records[i].data.strip(b" \0").upper() == b"UNSIGNED"
               for i in first)


def _patched(records: list[ParamRecord], name: bytes, ptype: int, data: bytes) -> None:
    """Replace the first element of every POINT:``name`` record of type ``ptype`` with at
    least one element by ``data`` (one element), in place; the other elements are kept
    (spec §6.9)."""
    for i in named(records, b"POINT", name):
        r = records[i]
        if r.type == ptype and len(r.data) >= len(data):
            records[i] = ParamRecord(r.group, r.locked, r.name, r.description, r.type, r.dims,
                                     data + r.data[len(data):])


def _scale_signed(records: list[ParamRecord], signed_scale: float) -> None:
    """Spec §6.9: in every float32 POINT:SCALE record with at least one element, the first
    element becomes ``signed_scale`` (header words 7-8) and every other one takes its sign.
    ezc3d (1.7) scales point p by element p and reads a point whose element is positive as
    int16: a POINT:SCALE of two elements was written positive in a float file, and its
    second point read back 17,000 units off (a clean-room review of stop 54)."""
    for i in named(records, b"POINT", b"SCALE"):
        records[i] = scale_as_written(records[i], signed_scale)


def scale_as_written(r: ParamRecord, signed_scale: float) -> ParamRecord:
    """A POINT:SCALE record ``r`` as spec §6.9's writer writes it beside header words 7-8 of
    ``signed_scale``: a float32 of at least one element gets ``signed_scale`` as its first
    element and that sign on every other one (a NaN keeps its payload); any other record
    is as stored. ``mpz compare`` allows this difference and no other (u69, u71, u72)."""
    if r.type != 4 or len(r.data) < 4:
        return r
    v = np.abs(np.frombuffer(r.data, "<f4", len(r.data) // 4))
    v = -v if signed_scale < 0 else v
    v[0] = signed_scale
    return ParamRecord(r.group, r.locked, r.name, r.description, r.type, r.dims,
                       v.astype("<f4").tobytes() + r.data[len(v) * 4:])


def frame_words(first: int, frames: int) -> tuple[int, int, bool]:
    """Header words 4-5 for ``frames`` frames numbered from ``first``, and whether the
    header cannot describe them (the last frame is above 65535): then the last frame word
    is 65535, the first frame word is kept when it fits (1 otherwise), and the count
    belongs in the frame parameters (:func:`plain_parts`, :func:`frame_range`)."""
    last = first + frames - 1
    if last <= HEADER_MAX_FRAME:
        return first, last, False
    return (first if first <= HEADER_MAX_FRAME else 1), HEADER_MAX_FRAME, True


def _param(group: int, name: str, ptype: int, dims: tuple[int, ...], data: bytes,
           description: str = "") -> ParamRecord:
    return ParamRecord(group, False, name.encode("ascii"), description.encode("ascii"),
                       ptype, dims, data)


def param_blocks(records: Sequence[ParamRecord]) -> int:
    """The 512-byte blocks a parameter section of ``records`` takes, its 4-byte header
    included (a C3D header can count at most :data:`MAX_PARAM_BLOCKS`)."""
    recs = list(records)
    size = 4 + sum(len(_record_bytes(r, i == len(recs) - 1)) for i, r in enumerate(recs))
    return max(1, -(-size // BLOCK))


def plain_parts(names: list[str], rate: float, units: str, frames: int,
                first: int = 1) -> tuple[bytes, list[ParamRecord]]:
    """The header block and parameter section of a float C3D of bare points (no analog,
    no source to restore), for :func:`build_c3d`.

    POINT holds USED, SCALE, RATE, DATA_START, FRAMES, UNITS (when given) and LABELS
    (LABELS2, LABELS3 ... past 255 points); ANALOG says no channels. With more frames
    than the header can describe (:func:`frame_words`) the file follows the C3D user
    guide's frame-count appendix: header last frame 65535, POINT:FRAMES the int16
    0xFFFF (ezc3d refuses a float FRAMES and reads 0xFFFF as "see the data"),
    POINT:LONG_FRAMES the float32 count and a TRIAL group with ACTUAL_START_FIELD and
    ACTUAL_END_FIELD (low, high int16 words of the first and last frame).

    Raises
    ------
    InputFormatError
        More than 65535 points, a name longer than 255 bytes, or a last frame number
        beyond 32 bits.
    """
    P = len(names)
    if P > MAX_POINTS:
        raise InputFormatError(f"C3D: {P} points; a C3D file holds at most {MAX_POINTS}")
    if frames < 1 or first < 0 or first + frames - 1 > MAX_FRAME_NUMBER:
        raise InputFormatError(f"C3D: frames {first}..{first + frames - 1} do not fit the "
                               "32-bit frame numbers of TRIAL:ACTUAL_END_FIELD")
    raw = [n.encode("utf-8") for n in names]
    width = max((len(b) for b in raw), default=0) or 1
    if width > 255:
        raise InputFormatError(f"C3D: a point name of {width} bytes; C3D labels hold 255")
    hfirst, hlast, long = frame_words(first, frames)

    def i16(*v: int) -> bytes:
        return np.array([x & 0xFFFF for x in v], "<u2").tobytes()

    def f32(v: float) -> bytes:
        return np.array([v], "<f4").tobytes()

    recs = [ParamRecord(-1, False, b"POINT", b"3-D point parameters"),
            _param(1, "USED", 2, (), i16(P), "number of points"),
            _param(1, "SCALE", 4, (), f32(-1.0), "float storage"),
            _param(1, "RATE", 4, (), f32(rate), "frames per second"),
            _param(1, "DATA_START", 2, (), i16(0), "first block of the data"),
            _param(1, "FRAMES", 2, (), i16(frames if not long else 0xFFFF),
                   "number of frames" + (" (see LONG_FRAMES)" if long else ""))]
    if long:
        recs.append(_param(1, "LONG_FRAMES", 4, (), f32(frames), "number of frames"))
    if units:
        u = units.encode("utf-8")
        recs.append(_param(1, "UNITS", -1, (len(u),), u, "units"))
    for k in range(0, max(P, 1), 255):
        part = raw[k:k + 255]
        name = "LABELS" if k == 0 else f"LABELS{k // 255 + 1}"
        recs.append(_param(1, name, -1, (width, len(part)),
                           b"".join(b.ljust(width) for b in part), "point labels"))
    recs += [ParamRecord(-2, False, b"ANALOG", b"analog parameters"),
             _param(2, "USED", 2, (), i16(0), "no analog channels"),
             _param(2, "RATE", 4, (), f32(0.0), "no analog channels")]
    if long:
        last = first + frames - 1
        recs += [ParamRecord(-3, False, b"TRIAL", b"frame range"),
                 _param(3, "ACTUAL_START_FIELD", 2, (2,), i16(first, first >> 16),
                        "first frame (low, high word)"),
                 _param(3, "ACTUAL_END_FIELD", 2, (2,), i16(last, last >> 16),
                        "last frame (low, high word)")]
    head = bytearray(BLOCK)
    head[2:4] = i16(P)
    head[6:10] = i16(hfirst, hlast)
    head[20:24] = f32(rate)
    return bytes(head), recs


#: values :func:`_largest_magnitude` takes at a time (2 MiB of float64)
_PEAK_VALUES = 1 << 18


def _largest_magnitude(x: NDArray[np.float64]) -> float:
    """max |x| (0.0 for none; NaN if x holds one), a block of frames at a time: |x| of the
    whole array was a copy of the points' float64 size, the peak of `mpz decode` of a
    30-minute capture to C3D (docs/corpus.md, "Memory per worker")."""
    rows = max(1, _PEAK_VALUES // max(1, math.prod(x.shape[1:])))
    peaks = [np.abs(x[f: f + rows]).max(initial=0.0) for f in range(0, x.shape[0], rows)]
    return float(np.max(peaks, initial=0.0))


def build_c3d(header: bytes, records: list[ParamRecord], xyz: NDArray[np.float64],
              point_words: NDArray[Any], analog: NDArray[Any], *, float_storage: bool,
              scale: float) -> bytes:
    """A C3D file (Intel) from the parts :func:`parse_c3d` returns.

    Parameters
    ----------
    header : bytes
        The normalised 512-byte header block; its parameter-block pointer (byte 0), key
        (byte 1), scale (words 7-8) and data start (word 9) are set here. When its last
        frame (word 5) is 65535 the data is not padded to a whole block (see the code).
    records : list of ParamRecord
        The parameter section, written in this order; POINT:DATA_START and the sign of
        POINT:SCALE are set here, every other record is written as given.
    xyz : ndarray, float64, shape (frames, points, 3)
        Coordinates to store (finite; for int16 storage, exact multiples of ``scale``).
    point_words : ndarray, shape (frames, points)
        The fourth word of each point, int16 or float32 values.
    analog : ndarray, shape (frames * samples, channels)
        Analog words, int16 or float32 values.
    float_storage : bool
        float32 storage (POINT:SCALE negative) or int16.
    scale : float
        |POINT:SCALE|: the int16 grid step.

    Raises
    ------
    InputFormatError
        For a parameter section a C3D file cannot hold (more than 255 blocks, a record
        longer than its 16-bit offset allows).
    """
    recs = list(records)
    signed_scale = -abs(scale) if float_storage else abs(scale)
    _scale_signed(recs, signed_scale)
    n_blocks = param_blocks(recs)
    if n_blocks > MAX_PARAM_BLOCKS:
        raise InputFormatError(f"C3D: the parameter section needs {n_blocks} blocks; a C3D "
                               f"header can point past at most {MAX_PARAM_BLOCKS}")
    data_start = 2 + n_blocks
    _patched(recs, b"DATA_START", 2, np.array([data_start], "<i2").tobytes())
    section = b"".join(_record_bytes(r, i == len(recs) - 1) for i, r in enumerate(recs))
    params = (bytes([1, C3D_KEY, n_blocks, PROC_INTEL]) + section).ljust(n_blocks * BLOCK,
                                                                         b"\x00")
    head = bytearray(header[:BLOCK].ljust(BLOCK, b"\x00"))
    head[0], head[1] = 2, C3D_KEY
    head[12:16] = np.array([signed_scale], "<f4").tobytes()
    head[16:18] = int(data_start).to_bytes(2, "little")
    # frames: every point's x, y, z and fourth word, then the analog words, each frame's
    # bytes written in place in the one buffer of the file (the frames, their bytes, the
    # padded body and the file were each a copy: 1.5 GB for 2^24 marker-frames)
    F, P = point_words.shape
    per = analog.shape[0] // F if F and analog.size else 0
    row = 16 * P if float_storage else 8 * P
    arow = per * analog.shape[1] * (4 if float_storage else 2)
    n_body = F * (row + arow)
    if int.from_bytes(head[8:10], "little") != HEADER_MAX_FRAME:
        # the last block padded with zeros; not when the header's last frame is 65535:
        # readers then count frames to the end of the file (ezc3d does), and padding
        # would read as frames
        n_body = -(-n_body // BLOCK) * BLOCK
    out = np.zeros(len(head) + len(params) + n_body, np.uint8)
    out[:BLOCK] = np.frombuffer(bytes(head), np.uint8)
    out[BLOCK:BLOCK + len(params)] = np.frombuffer(params, np.uint8)
    frames = out[BLOCK + len(params):][:F * (row + arow)].reshape(F, row + arow)
    if float_storage:
        big = _largest_magnitude(xyz)
        if big > F32_MAX:
            # an MPZ file may hold coordinates up to 2^1024 (§4.4); a C3D cannot
            # repr: at 6 digits one just above the largest binary32 printed as that value
            raise InputFormatError(f"C3D: a coordinate of magnitude {big!r} does not fit a "
                                   f"float32 C3D (at most {F32_MAX!r}); write another format")
        pts = frames[:, :row].view("<f4").reshape(F, P, 4)
        pts[:, :, :3] = xyz                          # rounded to float32 as astype does
        pts[:, :, 3] = point_words                   # int16 words convert exactly
        words = analog
        if analog.dtype.kind == "i" and analog_unsigned(recs):
            # spec §6.9: an UNSIGNED source's words as their unsigned values, which a float
            # file's readers take as they are (65535 was written -1.0: a QA run of stop 52)
            words = analog.astype(np.int64) & 0xFFFF
        if arow:
            frames[:, row:].view("<f4")[:] = words.reshape(F, per * analog.shape[1])
    else:
        ipts = frames[:, :row].view("<i2").reshape(F, P, 4)
        ipts[:, :, :3] = np.rint(xyz / abs(scale)).astype("<i2")
        ipts[:, :, 3] = point_words.astype("<i2")
        if arow:
            frames[:, row:].view("<i2")[:] = analog.astype("<i2").reshape(
                F, per * analog.shape[1])
    return out.tobytes()
