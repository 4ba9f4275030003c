"""A small pure-numpy C3D reader, working on bytes.

Contract: :func:`parse_c3d` takes the whole file as ``bytes`` and returns a
:class:`C3DData` (point data, residual words, parameters) or raises
:class:`mpz.errors.InputFormatError`. It reads only what MPZ needs: the
header, the parameter section and the 3D point data; analog samples are
skipped. It is the fallback for files ``ezc3d`` refuses (SGI/MIPS
big-endian files, parameter sections with unknown types) and a second,
independent reading of the files ezc3d accepts.

The layout follows the C3D.org "C3D file format user guide" (2008):
512-byte blocks; block 1 is the header; byte 0 of the header gives the
first parameter block; byte 3 of the parameter block gives the processor
type (84 Intel, 85 DEC, 86 MIPS).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, NoReturn

import numpy as np
from numpy.typing import NDArray

from mpz.errors import InputFormatError

BLOCK = 512  # C3D files are organised in 512-byte blocks
C3D_KEY = 0x50  # header byte 1: "C3D" key value 80
PROC_INTEL, PROC_DEC, PROC_MIPS = 84, 85, 86  # parameter header byte 3
#: parameter element types: -1 char, 1 byte, 2 int16, 4 float32
_PARAM_TYPES = (-1, 1, 2, 4)
MAX_POINTS = 65535  # POINT:USED is a 16-bit count
MAX_DIMS = 7  # a C3D parameter has at most 7 dimensions

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


def _s8(b: int) -> int:
    """A byte as a signed 8-bit integer."""
    return b - 256 if b > 127 else b


def _fail(msg: str, offset: int | None = None) -> NoReturn:
    raise InputFormatError(f"C3D: {msg}", offset=offset)


def truncated(declared: int, present: int, offset: int | None = None) -> InputFormatError:
    """The error for a file with fewer frames than its header declares."""
    return InputFormatError(f"C3D: truncated point data: {declared} frames declared, "
                            f"{present} present", offset=offset)


def _dec_to_ieee(raw: bytes) -> NDArray[np.float32]:
    """DEC (VAX F_floating) 4-byte values to float32.

    VAX F stores the high 16-bit word first (each word little-endian) and
    uses a 0.1f mantissa with exponent bias 128: swapping the words gives
    the IEEE bit pattern of 4x the value.
    """
    b = np.frombuffer(raw, dtype=np.uint8).reshape(-1, 4)
    swapped = np.ascontiguousarray(b[:, [2, 3, 0, 1]]).view("<f4").ravel()
    return (swapped / np.float32(4.0)).astype(np.float32)


class _Codec:
    """Integer and float decoding for one processor type."""

    def __init__(self, processor: int) -> None:
        self.processor = processor
        big = processor == PROC_MIPS
        self.i2 = np.dtype(">i2" if big else "<i2")
        self.u2 = np.dtype(">u2" if big else "<u2")
        self.f4 = np.dtype(">f4" if big else "<f4")

    def int16(self, data: bytes, off: int, n: int = 1) -> NDArray[np.int16]:
        return np.frombuffer(data, self.i2, n, off)

    def uint16(self, data: bytes, off: int) -> int:
        return int(np.frombuffer(data, self.u2, 1, off)[0])

    def float32(self, data: bytes, off: int, n: int = 1) -> NDArray[np.float32]:
        raw = data[off:off + 4 * n]
        if len(raw) != 4 * n:
            _fail("float data runs past the end of the file", off)
        if self.processor == PROC_DEC:
            return _dec_to_ieee(raw)
        return np.frombuffer(raw, self.f4).astype(np.float32)


def _parse_parameters(data: bytes, start: int,
                      codec: _Codec) -> dict[str, dict[str, ParamValue | None]]:
    """Parse the parameter section that starts at byte ``start``."""
    groups: dict[int, str] = {}
    pending: dict[int, dict[str, ParamValue | None]] = {}  # parameters seen before their group
    n_blocks = data[start + 2]
    end = min(len(data), start + max(n_blocks, 1) * BLOCK)
    pos = start + 4
    while pos + 2 <= end:
        name_len = abs(_s8(data[pos]))
        gid = _s8(data[pos + 1])
        if name_len == 0 or gid == 0:
            break
        name = data[pos + 2:pos + 2 + name_len].decode("latin-1").upper()
        off_pos = pos + 2 + name_len
        if off_pos + 2 > end:
            break
        # the offset is counted from the offset word itself; 0 ends the section
        nxt = codec.uint16(data, off_pos)
        body = off_pos + 2
        if gid < 0:
            groups[-gid] = name
        else:
            value = _parse_value(data, body, codec, end)
            pending.setdefault(gid, {})[name] = value
        if nxt == 0:
            break
        pos = off_pos + nxt
    params: dict[str, dict[str, ParamValue | None]] = {}
    for gid, values in pending.items():
        if gid in groups:
            params.setdefault(groups[gid], {}).update(values)
    for name in groups.values():
        params.setdefault(name, {})
    return params


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
    return codec.float32(data, pos, count).astype(np.float64)


def _text(raw: bytes) -> str:
    """A C3D char field (UTF-8, else Latin-1), padded with blanks or NULs."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
    return text.strip(" \x00")


def _first(params: dict[str, dict[str, ParamValue | None]], group: str, name: str,
           default: Any = None) -> Any:
    """First element of parameter ``group:name``, or ``default`` if it is absent or empty."""
    v = params.get(group, {}).get(name)
    if v is None or len(v) == 0:
        return default
    return v[0]


def parse_c3d(data: bytes) -> C3DData:
    """Parse a complete C3D file held in memory.

    Parameters
    ----------
    data : bytes
        The file contents.

    Returns
    -------
    C3DData

    Raises
    ------
    InputFormatError
        If the bytes are not a C3D file or are truncated.
    """
    if len(data) < 2 * BLOCK:
        _fail(f"file too short ({len(data)} bytes) for a header and a parameter block")
    if data[1] != C3D_KEY:
        _fail(f"bad key byte 0x{data[1]:02x} at offset 1, expected 0x50", 1)
    pstart = (data[0] - 1) * BLOCK
    if data[0] < 2 or pstart + 4 > len(data):
        _fail(f"parameter section block {data[0]} is outside the file", 0)
    processor = data[pstart + 3]
    if processor not in (PROC_INTEL, PROC_DEC, PROC_MIPS):
        _fail(f"unknown processor type {processor} (expected 84, 85 or 86)", pstart + 3)
    codec = _Codec(processor)
    params = _parse_parameters(data, pstart, codec)
    params.setdefault("POINT", {})

    # header words (1-based word numbers as in the C3D guide)
    hdr_points = int(codec.int16(data, 2)[0])
    hdr_analog = codec.uint16(data, 4)  # analog measurements per 3D frame
    first = codec.uint16(data, 6)
    last = codec.uint16(data, 8)
    hdr_scale = float(codec.float32(data, 12)[0])
    hdr_data_start = codec.uint16(data, 16)
    hdr_rate = float(codec.float32(data, 20)[0])

    used = int(_first(params, "POINT", "USED", hdr_points))
    if used < 0:
        used += 65536  # POINT:USED is unsigned in files with > 32767 points
    if used > MAX_POINTS:
        _fail(f"POINT:USED {used} exceeds {MAX_POINTS}")
    scale = float(_first(params, "POINT", "SCALE", hdr_scale))
    # POINT:DATA_START must point past the parameter section; some writers
    # (c3d.org sample13, Dance1.c3d) store 1 there: fall back to the header
    param_end_block = data[0] + max(data[pstart + 2], 1)
    data_start = int(_first(params, "POINT", "DATA_START", hdr_data_start))
    if data_start < 0:
        data_start += 65536
    if data_start < param_end_block:
        data_start = hdr_data_start
    # the header frame range is authoritative (Dance1.c3d has POINT:FRAMES
    # one larger than the data); POINT:FRAMES only when the header is empty
    n_frames = last - first + 1
    if n_frames <= 0:
        fp = int(_first(params, "POINT", "FRAMES", 0))
        n_frames = fp + 65536 if fp < 0 else fp
    if n_frames <= 0:
        _fail(f"no frames (header first {first}, last {last})", 6)
    float_storage = scale < 0
    word = 4 if float_storage else 2
    frame_words = 4 * used + hdr_analog
    frame_bytes = frame_words * word
    off = (data_start - 1) * BLOCK
    if data_start < 2 or off > len(data):
        _fail(f"data start block {data_start} is outside the file")
    avail = (len(data) - off) // frame_bytes if frame_bytes else n_frames
    if avail < n_frames:
        raise truncated(n_frames, avail, off)
    if used == 0:
        return C3DData(np.zeros((n_frames, 0, 3)), np.zeros((n_frames, 0), np.int64),
                       params, processor, float_storage, hdr_rate)

    # read the frames, then keep the 4*used point words of each
    raw = data[off:off + n_frames * frame_bytes]
    words: NDArray[np.float32] | NDArray[np.int16]
    if float_storage:
        words = codec.float32(raw, 0, n_frames * frame_words).reshape(n_frames, frame_words)
    else:
        words = codec.int16(raw, 0, n_frames * frame_words).reshape(n_frames, frame_words)
    pts = words[:, :4 * used].reshape(n_frames, used, 4).astype(np.float64)
    if float_storage:
        # the residual word is stored as a float holding an integer
        r = pts[:, :, 3]
        res = np.where(np.isfinite(r), np.clip(r, -32768, 32767), -1.0).astype(np.int64)
        xyz = pts[:, :, :3]
    else:
        res = pts[:, :, 3].astype(np.int64)
        xyz = pts[:, :, :3] * abs(scale)
    return C3DData(xyz, res, params, processor, float_storage, hdr_rate)
