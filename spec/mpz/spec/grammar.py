"""The MPZ 1.x container grammar (spec §3 and §4), written with construct.

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
input; the reference's fast paths, ``mpz.chunks._build`` and ``mpz.chunks._parse``, walk
these same objects and leave every error to construct), and no ``Switch`` (an unknown
key would parse as nothing): the chunk table names each layout, and a type missing from
it is handled by §2.3 in Python.
"""
from typing import Any

from construct import (
    Adapter,
    Array,
    Bytes,
    ExplicitError,
    Float64l,
    GreedyBytes,
    If,
    Int8sl,
    Int8ul,
    Int16ul,
    Int32sl,
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

#: §2.1 the version this grammar describes (1.1: the C3D archive chunks of §4.13, the
#: skeleton chunks of §4.14 and the coded summary of §4.15)
VERSION_MAJOR, VERSION_MINOR = 1, 1

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
    "error_bound" / Float64l * "§4.1 the declared bound in units (SHOULD be 0 when metric is 0)",
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
            shared = e["shared"]
            if shared > len(prev):  # R-4.2-2
                raise ExplicitError(f"name {i} shares {shared} bytes of a {len(prev)}-byte name")
            raw = prev[:shared] + e["suffix"]
            if not 1 <= len(raw) <= 255:  # R-2.4-16, R-4.2-3
                raise ExplicitError(f"name {i} has {len(raw)} bytes, not 1..255")
            try:
                names.append(raw.decode("utf-8"))
            except UnicodeDecodeError:  # R-2.4-16
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
    "nodes" / Array(this.count, HierNode) * "§4.3 in node order 0 .. N-1",
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
    "length" / Int16ul * "§4.7 L, frames per pattern (reference frame number), 1..4096 if K > 0, "
                          "not checked if K = 0",
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
    # kept as bytes, read as one numpy array each (k x D values, up to 2^24): the elements
    # are little-endian u32 and s32, as the doc strings say (a QA audit, stop 49)
    "starts" / Bytes(4 * this.k) * "§4.10 u32 little-endian x k: first frame of each "
    "segment, starts[0] = 0",
    "means" / Bytes(4 * this.k * this._.dims) * "§4.10 s32 little-endian x k x D: mean of "
    "segment j, dimension d at index j D + d, / step",
)
SMRY = Struct(
    "space" / Int8ul * "§4.10 0 positions relative to the per-frame centroid root, "
    "1 joint angles",
    "dims" / Int32ul * "§4.10 D, values per frame",
    "level_count" / Int8ul * "§4.10 1..64",
    "levels" / Array(this.level_count, SummaryLevel) * "§4.10 one per k",
    Terminated,
)

#: §4.15 smrc, the coded optimal-partition summary (ancillary, 1.1): the level headers,
#: then one range-coded field with each level's segment lengths and mean residuals
CodedSummaryLevel = Struct(
    "k" / Int32ul * "§4.15 segments in this level, 1..F",
    "wssse" / Float64l * "§4.15 within-segment sum of squared error, units^2",
    "step" / Float64l * "§4.15 quantisation step of the means, > 0",
)
SMRC = Struct(
    "space" / Int8ul * "§4.15 0 positions relative to the per-frame centroid root "
    "(§4.10), 1 joint angles",
    "dims" / Int32ul * "§4.15 D, values per frame",
    "level_count" / Int8ul * "§4.15 1..64",
    "levels" / Array(this.level_count, CodedSummaryLevel) * "§4.15 one header per level",
    "coded" / GreedyBytes * "§4.15 per level: unsigned [k, 1, 1] lengths - 1, then (D > 0) "
    "signed [k, D/3, 3] (space 0) or [k, D, 1] (space 1) mean residuals",
)

#: §4.11 meta, key/value metadata (ancillary)
MetaEntry = Struct(
    "key" / PascalString(Int8ul, "utf8") * "§4.11 1..255 bytes",  # R-2.4-41
    "value" / PascalString(Int16ul, "utf8") * "§4.11 0..65535 bytes",  # R-2.4-42
)
META = Struct(
    "count" / Int16ul * "§4.11 entries",
    "entries" / Array(this.count, MetaEntry) * "§4.11 count key/value pairs",
    Terminated,
)

#: §4.12 MEND, the end chunk: empty
MEND = Struct(
    Terminated,  # R-4.12-1
)


# ---- §4.14 skeleton chunks (MPZ 1.1) ----
#: §4.14 how one channel is quantised and predicted (the channel layer of bvhs and asfs)
ChannelCoding = Struct(
    "step_mantissa" / Int16ul * "§4.14 m >= 1",
    "step_digits" / Int8ul * "§4.14 d, 0..9: the step is m x 10^-d",
    "wrap" / Int8ul * "§4.14 0 none, 1 modulo 360 of the channel's own units "
                       "(N = 360 x 10^d / m steps)",
    "low" / Int32sl * "§4.14 wrap 1: the lowest value of the turn, in steps; wrap 0: 0",
    "order" / Int8ul * "§4.14 temporal predictor order 0..2",
    "group" / Int8ul * "§4.14 the block of the coded field that holds this channel",
)

#: §4.14.1 one joint of a BVH hierarchy (a ROOT, a JOINT or an End Site)
BvhJoint = Struct(
    "name" / PascalString(Int8ul, "utf8") * "§4.14.1 the joint's name; empty for an End Site",
    "parent" / Int16ul
    * "§4.14.1 0xFFFF (a ROOT), joint i - 1 or an ancestor of it (depth-first order)",
    "offset" / Array(3, Float64l) * "§4.14.1 OFFSET x, y, z in MHDR units, finite",
    "channel_count" / Int8ul * "§4.14.1 0..6; 0 for an End Site",
    "channels" / Array(this.channel_count, Int8ul)
    * "§4.14.1 channel kinds in file order: 0-2 X/Y/Zposition, 3-5 X/Y/Zrotation",
)
#: §4.14.1 bvhs, a BVH hierarchy and its channels (ancillary, 1.1)
BVHS = Struct(
    "encoding" / Int8ul * "§4.14.1 text encoding of the source: 0 UTF-8, 1 Latin-1",
    "frame_time" / Float64l * "§4.14.1 the BVH Frame Time in seconds, finite and > 0",
    "joint_count" / Int16ul * "§4.14.1 J, equals marker_count",
    "joints" / Array(this.joint_count, BvhJoint) * "§4.14.1 in file (depth-first) order",
    "channel_count" / Int16ul * "§4.14 C of the channel layer, the sum of the joints' counts",
    "position_bound" / Float64l * "§4.14 declared joint position error, MHDR units; 0 none",
    "channels" / Array(this.channel_count, ChannelCoding) * "§4.14.1 the channel layer (§4.14)",
    "coded" / GreedyBytes * "§4.14.1 range-coded: one signed block [F, n_g, 1] per group",
)

#: §4.14.2 one bone of an ASF skeleton
AsfBone = Struct(
    "bone_id" / Int32ul * "§4.14.2 the ASF id (0: none written)",
    "name" / PascalString(Int8ul, "utf8")
    * "§4.14.2 1..255 bytes, unique, not the bytes 'root' (case-sensitive)",
    "parent" / Int16ul * "§4.14.2 parent joint: 0 the root, bone b is joint b + 1",
    "direction" / Array(3, Float64l) * "§4.14.2 direction x, y, z, finite",
    "length" / Float64l * "§4.14.2 length in ASF units, finite",
    "axis" / Array(3, Float64l) * "§4.14.2 axis angles x, y, z, finite",
    "axis_order" / Int8ul * "§4.14.2 0 XYZ, 1 XZY, 2 YXZ, 3 YZX, 4 ZXY, 5 ZYX",
    "dof_count" / Int8ul * "§4.14.2 0..7",
    "dofs" / Array(this.dof_count, Int8ul) * "§4.14.2 channel kinds 0..6 (tx..rz, l)",
    "limit_count" / Int8ul * "§4.14.2 0 or dof_count",
    "limits" / Array(this.limit_count, Array(2, Float64l))
    * "§4.14.2 (low, high) per dof, not NaN",
)
#: §4.14.2 asfs, an ASF skeleton, the layout of its AMC motion and its channels
#: (ancillary, 1.1)
ASFS = Struct(
    "encoding" / Int8ul * "§4.14.2 text encoding of the source: 0 UTF-8, 1 Latin-1",
    "angle_unit" / Int8ul * "§4.14.2 0 degrees, 1 radians",
    "length_unit" / Float64l * "§4.14.2 ':units length', finite and > 0",
    "mass" / PascalString(Int8ul, "utf8") * "§4.14.2 ':units mass' as written (informative)",
    "version" / PascalString(Int8ul, "utf8") * "§4.14.2 ':version' (informative)",
    "name" / PascalString(Int8ul, "utf8") * "§4.14.2 ':name' (informative)",
    "documentation" / PascalString(Int16ul, "utf8") * "§4.14.2 ':documentation' lines",
    "comments" / PascalString(Int16ul, "utf8")
    * "§4.14.2 comment lines before the first keyword, without their '#'",
    "root_order_count" / Int8ul * "§4.14.2 0..6",
    "root_order" / Array(this.root_order_count, Int8ul) * "§4.14.2 root channel kinds 0..5",
    "root_axis_order" / Int8ul * "§4.14.2 0..5, as axis_order",
    "root_position" / Array(3, Float64l) * "§4.14.2 finite",
    "root_orientation" / Array(3, Float64l) * "§4.14.2 finite",
    "bone_count" / Int16ul * "§4.14.2 B, marker_count - 1",
    "bones" / Array(this.bone_count, AsfBone) * "§4.14.2 every parent before its children",
    "amc_header" / PascalString(Int16ul, "utf8") * "§4.14.2 AMC lines before the first frame",
    "first_frame" / Int32ul * "§4.14.2 number of the first AMC frame",
    "amc_count" / Int16ul * "§4.14.2 1..B + 1",
    "amc_order" / Array(this.amc_count, Int16ul) * "§4.14.2 joints in AMC line order",
    "channel_count" / Int16ul * "§4.14.2 C, root order count plus the bones' dof counts",
    "position_bound" / Float64l * "§4.14 declared joint position error, MHDR units; 0 none",
    "channels" / Array(this.channel_count, ChannelCoding) * "§4.14.2 the channel layer (§4.14)",
    "coded" / GreedyBytes * "§4.14.2 range-coded: one signed block [F, n_g, 1] per group",
)


# ---- §4.13 C3D archive chunks (MPZ 1.1) ----
#: §4.13 one channel entry: how one channel of C3D words is coded (§6.9)
C3dChannel = Struct(
    "mode" / Int8ul * "§4.13 0 integer (word = k x 2^shift), 1 float32 bit pattern",
    "shift" / Int8sl * "§4.13 mode 0: -128..104 (int16 storage: 0); mode 1: 0",
    "order" / Int8ul * "§4.13 temporal predictor order 0..2 (§6.2)",
    "low_bits" / Int8ul * "§4.13 b, 0..3: each residual is h x 2^b + l, l coded apart",
)

#: §4.13.1 chdr, the C3D header block (ancillary, 1.1); ``body`` is the block as stored
#: (coding 0) or its raw DEFLATE stream (coding 1, §4.13, inflated before it is checked)
CHDR = Struct(
    "processor" / Int8ul * "§4.13.1 the source's processor type: 84 Intel, 85 DEC, 86 MIPS",
    "coding" / Int8ul * "§4.13 0: stored, 1: raw DEFLATE (RFC 1951)",
    "body" / GreedyBytes * "§4.13.1 coding 0: the 512-byte block; 1: a stream inflating to it",
)
#: §4.13.1 the inflated header block
CHDR_BLOCK = Struct(
    # R-4.13.1-2
    "block" / Bytes(512) * "§4.13.1 the 512-byte C3D header: integers LE, floats binary32 LE",
    Terminated,
)


#: §4.13.2, §8 the largest inflated cprm section: a C3D parameter section has at most 255
#: blocks of 512 bytes (its block count is one byte), and the normalised records are no
#: larger than the C3D ones plus the 2-byte count (mpz.format.LIMITS holds it); no
#: record's data is longer
MAX_C3D_PARAMETER_BYTES = 1 << 17


def _data_size(ctx: Any) -> int:
    """§4.13.2 |type| x the product of the dimensions (1 element without dimensions).

    A record of more than the 7 dimensions §4.13.2 allows is refused here when its
    product passes the 2^17 bytes a section holds, since no such data can follow: its up
    to 255 dimension bytes would ask for a read of a 600-digit length, which the error
    quoted (a QA run, stop 40). Up to 7 the product is below 4 x 255^7 < 2^58, and the
    read fails as any data longer than the bytes left does."""
    n = abs(int(ctx["type"]))
    for d in ctx["dims"]:
        n *= int(d)
        if n > MAX_C3D_PARAMETER_BYTES and len(ctx.dims) > 7:  # R-4.13.2-1, R-4.13.2-2
            raise ExplicitError(f"a parameter of {len(ctx.dims)} dimensions "
                                f"{list(ctx.dims)[:8]}... holds more than the "
                                f"{MAX_C3D_PARAMETER_BYTES} bytes of a parameter section "
                                f"(§4.13.2, §8)")
    return n


#: §4.13.2 one group or parameter record of the C3D parameter section
C3dParam = Struct(
    "group" / Int8sl * "§4.13.2 < 0: the group -group; > 0: a parameter of group `group`",
    "locked" / Int8ul * "§4.13.2 0 or 1 (the C3D name length was negative)",
    "name" / Prefixed(Int8ul, GreedyBytes) * "§4.13.2 1..127 bytes, as stored",
    "description" / Prefixed(Int8ul, GreedyBytes) * "§4.13.2 0..255 bytes, as stored",
    "type" / If(this.group > 0, Int8sl) * "§4.13.2 parameters: -1 char, 1 byte, 2 int16, 4 float32",
    "dims" / If(this.group > 0, Prefixed(Int8ul, GreedyBytes))
    * "§4.13.2 parameters: 0..7 dimensions, one byte each",
    "data" / If(this.group > 0, Bytes(_data_size))  # R-4.13.2-2
    * "§4.13.2 parameters: |type| x prod(dims) bytes, int16 LE, float32 binary32 LE",
)
#: §4.13.2 cprm, the C3D parameter section (ancillary, 1.1); ``body`` is the section as
#: stored (coding 0) or its raw DEFLATE stream (coding 1, §4.13, inflated before parsing)
CPRM = Struct(
    "coding" / Int8ul * "§4.13 0: stored, 1: raw DEFLATE (RFC 1951)",
    "body" / GreedyBytes * "§4.13.2 the section, as stored or deflated",
)
#: §4.13.2 the (inflated) parameter section
CPRM_SECTION = Struct(
    "count" / Int16ul * "§4.13.2 R, records",
    "records" / Array(this.count, C3dParam) * "§4.13.2 groups and parameters in file order",
    Terminated,  # R-4.13.2-4
)

#: §4.13.3 one model-output axis: x = offset + k x step
C3dModelAxis = Struct(
    "offset" / Float64l * "§4.13.3 finite",
    "step" / Float64l * "§4.13.3 finite, > 0, |offset| + step x 2^31 finite",
    "bound" / Float64l * "§4.13.3 declared max |error| of valid samples, finite, >= 0",
    "order" / Int8ul * "§4.13.3 temporal predictor order 0..2 (§6.2)",
)
#: §4.13.3 one model output (a point listed in POINT:ANGLES, FORCES, ...)
C3dModel = Struct(
    "kind" / Int8ul * "§4.13.3 0 ANGLES, 1 FORCES, 2 MOMENTS, 3 POWERS, 4 SCALARS, 5 REACTIONS",
    "axes" / Array(3, C3dModelAxis) * "§4.13.3 x, y, z",
)
#: §4.13.3 cpnt, the C3D points: slots, fourth words, model outputs (ancillary, 1.1)
CPNT = Struct(
    "storage" / Int8ul * "§4.13.3 how the source stored the words: 0 int16, 1 float32",
    "point_count" / Int16ul * "§4.13.3 P = M + J, the points of the source",
    "slots" / Array(this.point_count, Int16ul)
    * "§4.13.3 per point: s < M marker s, s >= M model output s - M",
    "words" / Array(this.point_count, C3dChannel) * "§4.13.3 how each point's 4th word is coded",
    "model_count" / Int16ul * "§4.13.3 J, model outputs",
    "models" / Array(this.model_count, C3dModel) * "§4.13.3 in model-output order",
    "coded" / GreedyBytes * "§4.13.3 P word channels, J gap flags [F, J, 1], 3J value blocks",
)

#: §4.13.4 cana, the C3D analog channels (ancillary, 1.1)
CANA = Struct(
    "storage" / Int8ul * "§4.13.4 how the source stored the words: 0 int16, 1 float32",
    "channels" / Int16ul * "§4.13.4 C >= 1",
    "samples" / Int16ul * "§4.13.4 n >= 1, samples per channel per frame; C x n <= 65535",
    "table" / Array(this.channels, C3dChannel) * "§4.13.4 how each channel is coded",
    "coded" / GreedyBytes * "§4.13.4 C channels of F x n words, one after the other",
)
