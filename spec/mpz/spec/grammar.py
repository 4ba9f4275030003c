"""The MPZ 1.0 container grammar (spec §3 and §4), written with construct.

Strategy: construct describes structure only: the signature, the chunk frame
and each chunk's fixed fields. Range-coded payloads are opaque ``GreedyBytes``
decoded by :mod:`mpz.entropy`; bulk arrays are ``Bytes`` read with numpy.
Checksums, limits, chunk order and every cross-field rule live in Python
(framing in :mod:`mpz.container`, each chunk's § rules in its entry of the chunk
table :data:`mpz.chunks.CHUNKS`, the §3.4 order in :func:`mpz.decoder.read_stream`),
which raises :mod:`mpz.errors` exceptions carrying the byte offset and chunk type.

construct pitfalls avoided on purpose: no ``GreedyRange`` for the chunk list (it
silently drops a corrupt last chunk), ``Terminated`` ends every payload (trailing
bytes are an error), no ``.compile()`` (compiled parsers lose error paths on untrusted
input), and no ``Switch`` (an unknown key would parse as nothing): the chunk table
names each layout, and a type missing from it is handled by §2.3 in Python.
"""
from typing import Any

from construct import (
    Adapter,
    Array,
    Bytes,
    ExplicitError,
    Float64l,
    GreedyBytes,
    Int8ul,
    Int16ul,
    Int32ul,
    PascalString,
    Prefixed,
    Struct,
    Terminated,
    this,
)

#: §3.1 "\x89" catches 7-bit transfers, "\r\n" and "\x1a\n" catch newline
#: conversion and DOS type, as in PNG.
SIGNATURE = b"\x89MPZ\r\n\x1a\n"

#: §2.1 the version this grammar describes
VERSION_MAJOR, VERSION_MINOR = 1, 0

#: §3.2 chunk frame: type, length, payload, CRC-32 over type + payload
ChunkHeader = Struct(
    "type" / Bytes(4) * "§3.2 four ASCII letters; lower-case first letter = ancillary",
    "length" / Int32ul * "§3.2 payload length in bytes, at most MAX_CHUNK_LENGTH",
)
ChunkCRC = Int32ul * "§3.3 CRC-32 (ISO-HDLC, as zlib.crc32) of type and payload"

# ----------------------------------------------------------------- chunks --
#: §4.1 MHDR, the header: always the first chunk
MHDR = Struct(
    "version_major" / Int8ul * "§4.1 major version; decoders reject one they do not know",
    "version_minor" / Int8ul * "§4.1 minor version; any value is accepted",
    "flags" / Int16ul * "§4.1 bit 0: residual layer present; other bits reserved, 0",
    "frame_count" / Int32ul * "§4.1 F, frames in the clip, 1..2^24",
    "marker_count" / Int16ul * "§4.1 M, markers, 1..4096",
    "node_count" / Int16ul * "§4.1 N, hierarchy nodes, 1..M",
    "rate" / Float64l * "§4.1 frames per second, finite and > 0, exact as captured",
    "units" / Int8ul * "§4.1 0 unknown, 1 mm, 2 cm, 3 m, 4 in",
    "error_metric" / Int8ul * "§4.1 0 none declared, 1 max Euclidean error per valid sample",
    "error_bound" / Float64l * "§4.1 the declared bound in units (0 when metric is 0)",
    "smoothing" / Int8ul * "§4.1 h, half-width of the boundary smoothing filter, 0..16",
    Terminated,
)

class FrontCodedNames(Adapter):
    """§4.2 names front-coded: each entry keeps ``shared`` leading bytes of the
    previous name and appends ``suffix``; the result is a name of 1..255 bytes
    of UTF-8. Capture software prefixes every label with the subject
    ("TakeoMonday:LFHD"), so this halves MNAM on real files."""

    def _decode(self, obj: Any, context: Any, path: str) -> list[str]:
        names: list[str] = []
        prev = b""
        for i, e in enumerate(obj):
            if e.shared > len(prev):
                raise ExplicitError(f"name {i} shares {e.shared} bytes of a {len(prev)}-byte name")
            raw = prev[: e.shared] + e.suffix
            if not 1 <= len(raw) <= 255:
                raise ExplicitError(f"name {i} has {len(raw)} bytes, not 1..255")
            try:
                names.append(raw.decode("utf-8"))
            except UnicodeDecodeError:
                raise ExplicitError(f"name {i} is not valid UTF-8") from None
            prev = raw
        return names

    def _encode(self, obj: Any, context: Any, path: str) -> list[dict[str, Any]]:
        out: list[dict[str, Any]] = []
        prev = b""
        for name in obj:
            raw = name.encode("utf-8")
            shared = 0
            while shared < min(len(prev), len(raw), 255) and prev[shared] == raw[shared]:
                shared += 1
            out.append({"shared": shared, "suffix": raw[shared:]})
            prev = raw
        return out


NameEntry = Struct(
    "shared" / Int8ul * "§4.2 leading bytes taken from the previous name",
    "suffix" / Prefixed(Int8ul, GreedyBytes) * "§4.2 u8 length + the remaining bytes",
)

#: §4.2 MNAM, marker names
MNAM = Struct(
    "count" / Int16ul * "§4.2 equals marker_count",
    "names" / FrontCodedNames(Array(this.count, NameEntry)) * "§4.2 front-coded UTF-8 names",
    Terminated,
)

class WeightCodes(Adapter):
    """§4.3 encoder weights as u8 codes: weight = (code + 1) / 16, i.e. 1/16 .. 16 in
    steps of 1/16. Informative only (the decoder never uses them), so a byte is enough."""

    def _decode(self, obj: Any, context: Any, path: str) -> list[float]:
        return [(c + 1) / 16.0 for c in obj]

    def _encode(self, obj: Any, context: Any, path: str) -> list[int]:
        return [min(255, max(0, int(round(float(w) * 16.0)) - 1)) for w in obj]


#: §4.3 HIER, the body-part hierarchy
HierNode = Struct(
    "parent" / Int16ul * "§4.3 parent node index, < own index; 0xFFFF for node 0",
    "ref" / Int16ul * "§4.3 reference marker of this node (one of its members)",
    "member_count" / Int16ul * "§4.3 1..M",
    "members" / Array(this.member_count, Int16ul) * "§4.3 marker indices",
    "weights" / WeightCodes(Array(this.member_count, Int8ul))
    * "§4.3 encoder weights, u8 code c: w = (c + 1) / 16 (informative)",
)
HIER = Struct(
    "count" / Int16ul * "§4.3 equals node_count",
    "nodes" / Array(this.count, HierNode),
    Terminated,
)

#: §4.4 QUNT, the quantisation grid
QUNT = Struct(
    "step" / Float64l * "§4.4 grid step s in units, finite and > 0",
    "offset" / Array(3, Float64l) * "§4.4 per-axis offset o_a, finite",
    "bits" / Int8ul * "§4.4 every decoded q satisfies |q| < 2^bits; 1..31",
    Terminated,
)

#: §4.5 MASK, the validity mask (present only when there are gaps)
MASK = Struct(
    "coded" / GreedyBytes * "§4.5 range-coded [F, M, 1] gap flags",
)

#: §4.6 ROOT, the root-marker track
ROOT = Struct(
    "order" / Int8ul * "§4.6 temporal predictor order 0..2",
    "coded" / GreedyBytes * "§4.6 range-coded [F, 1, 3] prediction residuals",
)

#: §4.7 PATT, the encoded motion patterns (EMP) of one node
PATT = Struct(
    "node" / Int16ul * "§4.7 node index, 1..N-1",
    "pattern_count" / Int16ul * "§4.7 K, 0..65535",
    "length" / Int16ul * "§4.7 L, frames per pattern (reference frame number), 1..4096",
    "scale" / Int16ul * "§4.7 pattern grid multiplier, >= 1",
    "order" / Int8ul * "§4.7 temporal predictor order 0..2 within each pattern (1 = deltas)",
    "coded" / GreedyBytes * "§4.7 range-coded [K*L, n_i, 3], contexts restart every L rows",
)

#: §4.8 SEGS, the (pattern index, original frame count) pairs of one node
SEGS = Struct(
    "node" / Int16ul * "§4.8 node index",
    "segment_count" / Int32ul * "§4.8 S, 1..F",
    "coded" / GreedyBytes * "§4.8 range-coded [S, 1, 2]: index, frame count - L",
)

#: §4.9 RESI, the residual layer of one node
RESI = Struct(
    "node" / Int16ul * "§4.9 node index",
    "base" / Int8ul * "§4.9 0 relative to the parent's reference marker, 1 absolute, 2 key frames",
    "order" / Int8ul * "§4.9 temporal predictor order 0..2",
    "scale" / Int16ul * "§4.9 residual multiplier g >= 1",
    "coded" / GreedyBytes * "§4.9 range-coded [F, n_i, 3] residuals, or (base 2) key frames",
)

#: §4.10 smry, the optimal-partition summary (ancillary)
SummaryLevel = Struct(
    "k" / Int32ul * "§4.10 segments in this level, 1..F",
    "wssse" / Float64l * "§4.10 within-segment sum of squared error, units^2",
    "step" / Float64l * "§4.10 quantisation step of the means, > 0",
    "starts" / Bytes(4 * this.k) * "§4.10 u32 first frame of each segment, starts[0] = 0",
    "means" / Bytes(4 * this.k * this._.dims) * "§4.10 s32 mean of each segment / step",
)
SMRY = Struct(
    "space" / Int8ul * "§4.10 0 positions relative to the root marker, 1 joint angles",
    "dims" / Int32ul * "§4.10 D, values per frame",
    "level_count" / Int8ul * "§4.10 1..64",
    "levels" / Array(this.level_count, SummaryLevel),
    Terminated,
)

#: §4.11 meta, key/value metadata (ancillary)
MetaEntry = Struct(
    "key" / PascalString(Int8ul, "utf8") * "§4.11 1..255 bytes",
    "value" / PascalString(Int16ul, "utf8") * "§4.11 0..65535 bytes",
)
META = Struct(
    "count" / Int16ul,
    "entries" / Array(this.count, MetaEntry),
    Terminated,
)

#: §4.12 MEND, the end chunk: empty
MEND = Struct(Terminated)
