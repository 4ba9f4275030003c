"""``python -m mpz.tools.spec_example OUT``: write the example file of spec Appendix A.

Strategy: the example is built chunk by chunk from hand-chosen integers with
:func:`mpz.container.build` and :class:`mpz.entropy.BlockEncoder`, so
every byte has a reason that Appendix A can state; nothing depends on the
encoder's heuristics. The script then decodes its own output with
:func:`mpz.decode` and checks the integer layer and the declared bound
against the hand-made original motion, so a change in the codec that would
make Appendix A wrong makes this script fail.

``--table`` prints the Appendix A rows (Start | Length | Contents |
Description) instead of only writing the file; ``--entropy`` prints the
worked example of spec §5.7 (bits, contexts and bytes) from a pure-Python
transcription of the §5 pseudocode, checked against the reference coder.

Exit codes: 0 ok, 2 the codec disagrees with the example, 64 usage error.
"""
from __future__ import annotations

import sys

import numpy as np

from mpz.tools._cli import EXIT_ERROR, EXIT_OK, EXIT_USAGE, Parser, quiet_broken_pipe

# --------------------------------------------------------------- the motion --
NAMES = ["C7", "HAND"]
RATE = 120.0
STEP = 0.5                       # mm; <= 2E/sqrt(3) = 0.577 for E = 0.5
OFFSET = (100.0, 200.0, 1000.0)
BOUND = 0.5
SMOOTHING = 2                    # no effect here: one segment, no boundary
ROOT_Q = np.array([[0, 0, 0], [2, 1, 0], [4, 2, -1]], np.int64)
ROOT_ORDER = 1
PATTERN = np.array([[10, -4, 6], [13, -4, 0]], np.int64)   # one pattern, L = 2, one member
PATT_ORDER = 1
RESIDUAL = np.array([[0, 0, 0], [-1, 0, 1], [0, 0, 0]], np.int64)
RESI_ORDER = 0
GAPS = np.array([[0, 0], [0, 0], [0, 1]], np.int64)        # HAND is missing in frame 2
#: what the "capture" said; every valid sample is within BOUND of the decoded one
DEVIATION = np.array([[[0.1, -0.2, 0.0], [0.2, 0.0, -0.1]],
                      [[0.0, 0.1, 0.2], [-0.2, 0.2, 0.1]],
                      [[-0.1, 0.0, 0.1], [0.0, 0.0, 0.0]]])

#: entropy example of spec §5.7: a [T=2, M=2, A=1] block
ENTROPY_BLOCK = np.array([[[5], [-3]], [[4], [0]]], np.int64)


def _residuals(x, order):
    from mpz.predict import residuals
    return residuals(x, order)


def expected_q() -> np.ndarray:
    """The integer layer q [3, 2, 3] that Appendix A says the file decodes to."""
    from mpz.normalize import denormalize
    # [[10, -4, 6], [12, -4, 3], [13, -4, 0]]
    pat = denormalize(PATTERN[None, :, None, :], [0], [3])[:, 0]
    q = np.zeros((3, 2, 3), np.int64)
    q[:, 0] = ROOT_Q
    q[:, 1] = pat + RESIDUAL + ROOT_Q
    return q


def chunks() -> list:
    """The file as a list of (type, payload bytes, field rows) in file order.

    A field row is (length, description); the lengths add up to the payload.
    """
    from mpz.chunks import CHUNKS
    from mpz.entropy import BlockEncoder

    def coded(block, *, period=None, signed=True):
        enc = BlockEncoder(capacity=256)
        enc.block(block, period=period, signed=signed)
        return enc.finish()

    def b(ctype, fields):
        return CHUNKS[ctype].GRAMMAR.build(fields)

    out = []
    mhdr = {"version_major": 1, "version_minor": 0, "flags": 1, "frame_count": 3,
            "marker_count": 2, "node_count": 2, "rate": RATE, "units": 1, "error_metric": 1,
            "error_bound": BOUND, "smoothing": SMOOTHING}
    out.append(("MHDR", b("MHDR", mhdr), [
        (1, "version_major = 1"), (1, "version_minor = 0"),
        (2, "flags = 0x0001: residual layer present"), (4, "frame_count F = 3"),
        (2, "marker_count M = 2"), (2, "node_count N = 2"),
        (8, "rate = 120.0 (f64)"), (1, "units = 1 (mm)"),
        (1, "error_metric = 1 (max Euclidean error per valid sample)"),
        (8, "error_bound = 0.5 (f64)"),
        (1, "smoothing h = 2 (no boundary here, so no effect)")]))
    out.append(("MNAM", b("MNAM", {"count": 2, "names": NAMES}), [
        (2, "count = 2"), (1, "name 0: shared = 0"), (1, "name 0: suffix length 2"),
        (2, 'name 0 = "C7"'), (1, "name 1: shared = 0"), (1, "name 1: suffix length 4"),
        (4, 'name 1 = "HAND"')]))
    hier = {"count": 2, "nodes": [
        {"parent": 0xFFFF, "ref": 0, "member_count": 1, "members": [0], "weights": [1.0]},
        {"parent": 0, "ref": 1, "member_count": 1, "members": [1], "weights": [1.0]}]}
    out.append(("HIER", b("HIER", hier), [
        (2, "count = 2 nodes"),
        (2, "node 0: parent = 0xFFFF (root)"), (2, "node 0: ref = marker 0"),
        (2, "node 0: member_count = 1"), (2, "node 0: members = [0]"),
        (1, "node 0: weights = [1.0] (code 15)"),
        (2, "node 1: parent = 0"), (2, "node 1: ref = marker 1"),
        (2, "node 1: member_count = 1"), (2, "node 1: members = [1]"),
        (1, "node 1: weights = [1.0] (code 15)")]))
    out.append(("QUNT", b("QUNT", {"step": STEP, "offset": list(OFFSET), "bits": 6}), [
        (8, "step s = 0.5 (f64)"), (8, "offset[0] = 100.0 (f64)"),
        (8, "offset[1] = 200.0 (f64)"), (8, "offset[2] = 1000.0 (f64)"),
        (1, "bits = 6: every q is within -63..63 (the largest magnitude here is 17)")]))
    mask = coded(GAPS[:, :, None], signed=False)
    out.append(("MASK", b("MASK", {"coded": mask}), [
        (len(mask), "range-coded [3, 2, 1] unsigned gap flags "
                    "[[0,0],[0,0],[0,1]]: HAND missing in frame 2")]))
    root_e = _residuals(ROOT_Q[:, None, :], ROOT_ORDER)
    root = coded(root_e)
    out.append(("ROOT", b("ROOT", {"order": ROOT_ORDER, "coded": root}), [
        (1, "order = 1"),
        (len(root), "range-coded [3, 1, 3] residuals "
                    "[[0,0,0],[2,1,0],[2,1,-1]] of the root track [[0,0,0],[2,1,0],[4,2,-1]]")]))
    patt_e = _residuals(PATTERN[:, None, :], PATT_ORDER)
    patt = coded(patt_e, period=2)
    out.append(("PATT", b("PATT", {"node": 1, "pattern_count": 1, "length": 2, "scale": 1,
                                   "order": PATT_ORDER, "coded": patt}), [
        (2, "node = 1"), (2, "pattern_count K = 1"), (2, "length L = 2"), (2, "scale = 1"),
        (1, "order = 1"),
        (len(patt), "range-coded [2, 1, 3] (period 2) residuals [[10,-4,6],[3,0,-6]] "
                    "of the pattern [[10,-4,6],[13,-4,0]]")]))
    segs = coded(np.array([[[0, 3 - 2]]], np.int64))
    out.append(("SEGS", b("SEGS", {"node": 1, "segment_count": 1, "coded": segs}), [
        (2, "node = 1"), (4, "segment_count S = 1"),
        (len(segs), "range-coded [1, 1, 2]: pattern index 0, frame count - L = 3 - 2 = 1")]))
    resi = coded(_residuals(RESIDUAL[:, None, :], RESI_ORDER))
    out.append(("RESI", b("RESI", {"node": 1, "base": 0, "order": RESI_ORDER, "scale": 1,
                                   "coded": resi}), [
        (2, "node = 1"), (1, "base = 0 (relative to the parent's reference marker)"),
        (1, "order = 0"), (2, "scale g = 1"),
        (len(resi), "range-coded [3, 1, 3] residuals [[0,0,0],[-1,0,1],[0,0,0]]")]))
    meta = {"count": 1, "entries": [{"key": "subject", "value": "demo"}]}
    out.append(("meta", b("meta", meta), [
        (2, "count = 1"), (1, "key length 7"), (7, 'key = "subject"'),
        (2, "value length 4"), (4, 'value = "demo"')]))
    out.append(("MEND", b"", []))
    return out


def build() -> bytes:
    from mpz.container import build
    return build((t, p) for t, p, _ in chunks())


def original_positions() -> np.ndarray:
    """The motion the example stands for (NaN at the gap)."""
    x = np.asarray(OFFSET) + expected_q().astype(np.float64) * STEP + DEVIATION
    x[GAPS.astype(bool)] = np.nan
    return x


def verify(data: bytes) -> None:
    """Decode ``data`` with the reference decoder; raise AssertionError on any surprise."""
    from mpz.decoder import decode, decode_layers
    d = decode_layers(data)
    q, valid = d.q, d.valid
    assert (q == expected_q()).all(), f"integer layer {q.tolist()} != {expected_q().tolist()}"
    assert (valid == (GAPS == 0)).all(), "mask differs"
    m = decode(data)
    orig = original_positions()
    d = np.linalg.norm(m.positions - orig, axis=2)[valid]
    assert d.max() <= BOUND, f"declared bound {BOUND} broken: {d.max()}"
    assert np.isnan(m.positions[~valid]).all()


def table_rows(data: bytes) -> list:
    """(start, length, contents hex, description) for every byte of the file."""
    from mpz.spec.grammar import SIGNATURE
    rows = [(0, 8, SIGNATURE, "signature \\x89 M P Z \\r \\n \\x1a \\n (§3.1)")]
    pos = 8
    for ctype, payload, fields in chunks():
        label = f"chunk type {ctype!r}"[:-1].replace("'", '"') + '"'
        rows.append((pos, 4, data[pos:pos + 4], label))
        rows.append((pos + 4, 4, data[pos + 4:pos + 8], f"payload length = {len(payload)}"))
        p = pos + 8
        assert sum(n for n, _ in fields) == len(payload), ctype
        for n, desc in fields:
            rows.append((p, n, data[p:p + n], f"{ctype} {desc}"))
            p += n
        crc = int.from_bytes(data[p:p + 4], "little")
        rows.append((p, 4, data[p:p + 4], f"CRC-32 of type + payload = 0x{crc:08x}"))
        pos = p + 4
    assert pos == len(data)
    return rows


def markdown_table(data: bytes) -> str:
    lines = ["| Start | Length | Contents | Description |", "|---|---|---|---|"]
    for start, n, raw, desc in table_rows(data):
        lines.append(f"| 0x{start:04x} | {n} | `{raw.hex(' ')}` | {desc} |")
    return "\n".join(lines)


# --------------------------------------------------- §5 pseudocode, in Python --
class SpecEncoder:
    """A literal transcription of the range encoder of spec §5.1-§5.6, recording each decision."""

    def __init__(self):
        self.low, self.range, self.cache, self.cache_size = 0, 0xFFFFFFFF, 0, 1
        self.out = bytearray()
        self.trace = []

    def shift_low(self):
        if self.low < 0xFF000000 or self.low >= 0x100000000:
            carry = self.low >> 32
            temp = self.cache
            while True:
                self.out.append((temp + carry) & 0xFF)
                temp = 0xFF
                self.cache_size -= 1
                if self.cache_size == 0:
                    break
            self.cache = (self.low >> 24) & 0xFF
        self.cache_size += 1
        self.low = (self.low & 0x00FFFFFF) << 8

    def encode_bit(self, probs, idx, bit, label):
        p = probs[idx]
        self.trace.append((label, p, bit))
        bound = (self.range >> 11) * p
        if bit == 0:
            self.range = bound
            probs[idx] = p + ((2048 - p) >> 5)
        else:
            self.low += bound
            self.range -= bound
            probs[idx] = p - (p >> 5)
        while self.range < (1 << 24):
            self.range = (self.range << 8) & 0xFFFFFFFF
            self.shift_low()

    def encode_int(self, models, a, c, v, signed):
        Z, S, E, X = models
        if v == 0:
            self.encode_bit(Z[a], c, 0, f"Z[{a}][{c}]")
            return
        self.encode_bit(Z[a], c, 1, f"Z[{a}][{c}]")
        u = abs(v)
        if signed:
            self.encode_bit(S[a], c, 1 if v < 0 else 0, f"S[{a}][{c}]")
        k = u.bit_length() - 1
        for i in range(k):
            self.encode_bit(E[a][c], i, 1, f"E[{a}][{c}][{i}]")
        if k < 30:
            self.encode_bit(E[a][c], k, 0, f"E[{a}][{c}][{k}]")
        for j in range(k):
            self.encode_bit(X[a][k], j, (u >> (k - 1 - j)) & 1, f"X[{a}][{k}][{j}]")

    def encode_block(self, v, period=None, signed=True):
        T, M, A = v.shape
        period = T if period is None else period
        models = ([[1024] * 8 for _ in range(3)], [[1024] * 8 for _ in range(3)],
                  [[[1024] * 30 for _ in range(8)] for _ in range(3)],
                  [[[1024] * 30 for _ in range(31)] for _ in range(3)])
        for t in range(T):
            for m in range(M):
                for a in range(A):
                    cv = 0
                    if t % period != 0:
                        cv += 2 * abs(int(v[t - 1, m, a]))
                    if m > 0:
                        cv += abs(int(v[t, m - 1, a]))
                    c = min(7, cv.bit_length())
                    self.trace.append(((t, m, a), int(v[t, m, a]), cv, c))
                    self.encode_int(models, a, c, int(v[t, m, a]), signed)

    def finish(self) -> bytes:
        for _ in range(5):
            self.shift_low()
        return bytes(self.out)


def entropy_example() -> tuple[bytes, list]:
    """Bytes and decision trace of the §5.7 example; checked against mpz.entropy."""
    from mpz.entropy import BlockEncoder
    enc = SpecEncoder()
    enc.encode_block(ENTROPY_BLOCK)
    data = enc.finish()
    ref = BlockEncoder()
    ref.block(ENTROPY_BLOCK)
    assert ref.finish() == data, "spec pseudocode and mpz.entropy disagree"
    return data, enc.trace


def entropy_text() -> str:
    data, trace = entropy_example()
    lines = []
    for item in trace:
        if len(item) == 4:
            (t, m, a), v, cv, c = item
            lines.append(f"v[{t},{m},{a}] = {v}: ctx_v = {cv}, ctx = {c}")
        else:
            label, p, bit = item
            lines.append(f"    {label:<12} p = {p:4d}  bit {bit}")
    lines.append("bytes: " + data.hex(" "))
    return "\n".join(lines)


@quiet_broken_pipe
def main(argv: list[str] | None = None) -> int:
    ap = Parser(prog="python -m mpz.tools.spec_example",
                description="Write the example file of spec Appendix A.")
    ap.add_argument("out", nargs="?", help="where to write the file (e.g. "
                    "conformance/vectors/spec-example.mpz)")
    ap.add_argument("--table", action="store_true", help="print the Appendix A table")
    ap.add_argument("--entropy", action="store_true", help="print the §5.7 worked example")
    try:
        args = ap.parse_args(argv)
    except SystemExit as exc:
        return EXIT_OK if exc.code == 0 else EXIT_USAGE
    if not (args.out or args.table or args.entropy):
        ap.print_usage(sys.stderr)
        return EXIT_USAGE
    data = build()
    try:
        verify(data)
        entropy_example()
    except AssertionError as exc:
        print(f"spec_example: {exc}", file=sys.stderr)
        return EXIT_ERROR
    if args.out:
        with open(args.out, "wb") as fh:
            fh.write(data)
    if args.table:
        print(markdown_table(data))
    if args.entropy:
        print(entropy_text())
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
