"""Range coder speed (spec §5), and the MPZ 2.0 entropy-coder question on real residuals.

    python bench/bench_entropy.py              # both parts
    python bench/bench_entropy.py --synthetic  # part 1 only
    python bench/bench_entropy.py --real [--files cmu_135_02 ...] [--bound 1.0]

Part 1 (synthetic): symbols per second, encode and decode, on Laplacian residuals of
three scales, like the RESI blocks of real captures; a symbol is one coded integer. The
baseline in the same process is the pure-Python transcription of §5 used by
tests/test_entropy.py. Target (issue 3): >= 5 M symbols/s decoding.

Part 2 (real, issue 15, docs/mpz2-entropy.md): the integer blocks the encoder actually
writes (ROOT and RESI payloads of real files at ``--bound`` mm, taken from the encoder while
it runs: only the blocks of payloads that end up in the file, not losing candidates),
coded by

(a) the current coder, §5: adaptive binary range coder, binarised values, 8 contexts;
(b) static-table rANS (a prototype here, not a format): direct symbols (zigzag value,
    escape above 254 with the rest in a varint side stream), one 12-bit frequency table
    per block and axis (``rans``) or per block, axis and §5.6 context (``rans-ctx``), every
    table's cost counted, 4 interleaved 32-bit states with byte renormalisation;
(c) zstd -19 on the residuals as int16/int32 little-endian bytes, axis-major.

It prints bytes (and the cost against (a)) and decode speed in M values/s, best of 3.
"""
from __future__ import annotations

import argparse
import sys

from numba import njit
import numpy as np

from _common import best_of, no_data_reason, shared_data_dir
from mpz.conformance.rangecoder import RefEncoder
from mpz.entropy import BlockDecoder, BlockEncoder


# ----------------------------------------------------------- part 1: synthetic --
def synthetic() -> None:
    rng = np.random.default_rng(0)
    BlockDecoder(_enc(np.zeros((2, 1, 3), np.int64))).block(2, 1)   # JIT warm-up
    print(f"{'scale':>6} {'symbols':>9} {'bits/sym':>9} {'enc Msym/s':>11} {'dec Msym/s':>11} "
          f"{'py-ref Msym/s':>14} {'dec speed-up':>12}")
    ok = True
    for scale in (0.5, 3.0, 50.0):
        v = np.round(rng.laplace(0, scale, (5202, 41, 3))).astype(np.int64)
        data = _enc(v)
        small = v[:200]
        te = best_of(lambda v=v: _enc(v), 5)
        td = best_of(lambda data=data: BlockDecoder(data).block(5202, 41), 5)
        tr = best_of(lambda small=small: _ref(small), n=1) * (v.shape[0] / small.shape[0])
        n = v.size
        dec = n / td / 1e6
        ok &= dec >= 5
        print(f"{scale:>6g} {n:>9} {8 * len(data) / n:>9.3f} {n / te / 1e6:>11.1f} {dec:>11.1f} "
              f"{n / tr / 1e6:>14.3f} {tr / td:>11.0f}x")
    print(f"decode >= 5 M symbols/s: {'MET' if ok else 'MISSED'}")


def _enc(v):
    e = BlockEncoder()
    e.block(v)
    return e.finish()


def _ref(v):
    r = RefEncoder()
    r.block(v)
    return r.finish()


# ------------------------------------------------- part 2: the blocks of real files --
def real_blocks(files: list[str], bound: float) -> list[tuple[str, list[tuple]]]:
    """[(file, [(values [T, M, A] int64, period, signed), ...] per kept payload)] from the
    encoder: every BlockEncoder it makes is recorded, and the payloads found in the file's
    ROOT and RESI chunks select the blocks that were written."""
    import mpz.container
    import mpz.encoder
    import mpz.io
    made: list[tuple[BlockEncoder, list[tuple]]] = []

    class Recording(BlockEncoder):
        def __init__(self, *a, **k):
            super().__init__(*a, **k)
            self.blocks: list[tuple] = []
            made.append((self, self.blocks))

        def block(self, values, *, period=None, signed=True, **k):
            v = np.array(values, dtype=np.int64)
            self.blocks.append((v, v.shape[0] if period is None else int(period), signed))
            super().block(values, period=period, signed=signed, **k)

        def finish(self):
            self.payload = super().finish()
            return self.payload

    root = shared_data_dir()
    out = []
    saved = mpz.encoder.BlockEncoder
    mpz.encoder.BlockEncoder = Recording           # type: ignore[misc]
    try:
        for name in files:
            path = next(root.rglob(name + ".c3d"))
            m = mpz.io.read(path)
            made.clear()
            data = mpz.encoder.encode(m, max_error=bound, threads=1)
            written = {c.record.coded for c in mpz.container.parse(data)
                       if c.type in ("ROOT", "RESI") and c.record is not None}
            kept = [blocks for enc, blocks in made
                    if getattr(enc, "payload", None) in written]
            out.append((path.stem, kept))
    finally:
        mpz.encoder.BlockEncoder = saved           # type: ignore[misc]
    return out


def current_coder(payload: list[tuple]) -> tuple[bytes, float]:
    """(a) the §5 payload and its decode time (best of 3)."""
    enc = BlockEncoder()
    for v, period, signed in payload:
        enc.block(v, period=period, signed=signed)
    data = enc.finish()

    def dec():
        d = BlockDecoder(data)
        for v, period, signed in payload:
            d.block(v.shape[0], v.shape[1], v.shape[2], period=period, signed=signed)
        d.close()
    return data, best_of(dec)


# -- (b) static-table rANS prototype --------------------------------------------------
SCALE_BITS = 12
M_TOTAL = 1 << SCALE_BITS
RANS_L = 1 << 23
ESC = 255              # symbols 0..254: zigzag value; 255: escape, the rest in the side stream


@njit(cache=True)
def _context8(v, t, m, a, first):
    cv = 0
    if not first:
        cv += 2 * abs(v[t - 1, m, a])
    if m > 0:
        cv += abs(v[t, m - 1, a])
    c = 0
    while cv > 0 and c < 7:
        cv >>= 1
        c += 1
    return c


@njit(cache=True)
def _symbols(v, period, use_ctx):
    """Flat symbols, their table ids (axis, or axis x 8 + context) and the escapes."""
    T, M, A = v.shape
    n = T * M * A
    sym = np.empty(n, np.int64)
    tab = np.empty(n, np.int64)
    side = np.empty(n * 5 + 8, np.uint8)
    ns = 0
    i = 0
    for t in range(T):
        first = t % period == 0
        for m in range(M):
            for a in range(A):
                x = v[t, m, a]
                z = 2 * x if x >= 0 else -2 * x - 1
                tab[i] = a * 8 + _context8(v, t, m, a, first) if use_ctx else a
                if z < ESC:
                    sym[i] = z
                else:
                    sym[i] = ESC
                    r = z - ESC
                    while r >= 128:
                        side[ns] = (r & 127) | 128
                        ns += 1
                        r >>= 7
                    side[ns] = r
                    ns += 1
                i += 1
    return sym, tab, side[:ns]


def _normalise(counts: np.ndarray) -> np.ndarray:
    """Frequencies summing to M_TOTAL, >= 1 for every symbol that occurs."""
    n = counts.sum()
    f = np.where(counts > 0, np.maximum(1, counts * M_TOTAL // max(n, 1)), 0)
    f[np.argmax(f)] += M_TOTAL - f.sum()
    assert f.min() >= 0 and f.sum() == M_TOTAL
    return f


def _table_cost(f: np.ndarray) -> int:
    """Bytes to store one table: the number of symbols used, then (symbol, varint freq)."""
    used = np.flatnonzero(f)
    return 1 + sum(1 + (1 if f[s] < 128 else 2) for s in used)


@njit(cache=True)
def _rans_encode(sym, tab, freq, cum):
    n = sym.shape[0]
    out = np.empty(n * 2 + 64, np.uint8)
    p = out.shape[0]
    st = np.full(4, RANS_L, np.int64)
    for i in range(n - 1, -1, -1):
        j = i & 3
        s = sym[i]
        f = freq[tab[i], s]
        x = st[j]
        x_max = ((RANS_L >> SCALE_BITS) << 8) * f
        while x >= x_max:
            p -= 1
            out[p] = x & 0xFF
            x >>= 8
        st[j] = ((x // f) << SCALE_BITS) + (x % f) + cum[tab[i], s]
    for j in range(3, -1, -1):
        x = st[j]
        for k in range(3, -1, -1):
            p -= 1
            out[p] = (x >> (8 * k)) & 0xFF
    return out[p:].copy()


@njit(cache=True)
def _rans_decode(buf, n, tab, freq, cum, slot):
    sym = np.empty(n, np.int64)
    st = np.empty(4, np.int64)
    p = 0
    for j in range(4):
        st[j] = buf[p] | (buf[p + 1] << 8) | (buf[p + 2] << 16) | (np.int64(buf[p + 3]) << 24)
        p += 4
    for i in range(n):
        j = i & 3
        x = st[j]
        tb = tab[i]
        s = slot[tb, x & (M_TOTAL - 1)]
        x = freq[tb, s] * (x >> SCALE_BITS) + (x & (M_TOTAL - 1)) - cum[tb, s]
        while x < RANS_L:
            x = (x << 8) | buf[p]
            p += 1
        st[j] = x
        sym[i] = s
    return sym


@njit(cache=True)
def _rans_decode_ctx(buf, T, M, A, period, freq, cum, slot, side):
    """Decode with the tables chosen by the §5.6 context of already decoded values (the
    context needs the values, so this is the decoder that a context format would run)."""
    v = np.empty((T, M, A), np.int64)
    st = np.empty(4, np.int64)
    p = 0
    q = 0
    for j in range(4):
        st[j] = buf[p] | (buf[p + 1] << 8) | (buf[p + 2] << 16) | (np.int64(buf[p + 3]) << 24)
        p += 4
    i = 0
    for t in range(T):
        first = t % period == 0
        for m in range(M):
            for a in range(A):
                tb = a * 8 + _context8(v, t, m, a, first)
                j = i & 3
                x = st[j]
                s = slot[tb, x & (M_TOTAL - 1)]
                x = freq[tb, s] * (x >> SCALE_BITS) + (x & (M_TOTAL - 1)) - cum[tb, s]
                while x < RANS_L:
                    x = (x << 8) | buf[p]
                    p += 1
                st[j] = x
                z = s
                if s == ESC:
                    r = 0
                    sh = 0
                    while True:
                        b = side[q]
                        q += 1
                        r |= (b & 127) << sh
                        sh += 7
                        if b < 128:
                            break
                    z = ESC + r
                v[t, m, a] = (z >> 1) if (z & 1) == 0 else -((z + 1) >> 1)
                i += 1
    return v


@njit(cache=True)
def _unsymbol(sym, side, shape):
    v = np.empty(sym.shape[0], np.int64)
    q = 0
    for i in range(sym.shape[0]):
        z = sym[i]
        if z == ESC:
            r = 0
            sh = 0
            while True:
                b = side[q]
                q += 1
                r |= (b & 127) << sh
                sh += 7
                if b < 128:
                    break
            z = ESC + r
        v[i] = (z >> 1) if (z & 1) == 0 else -((z + 1) >> 1)
    return v.reshape(shape)


def rans_block(v: np.ndarray, period: int, use_ctx: bool):
    """(bytes, decode closure) of one block under the static-table rANS prototype."""
    sym, tab, side = _symbols(v, period, use_ctx)
    n_tab = 3 * 8 if use_ctx else 3
    counts = np.zeros((n_tab, 256), np.int64)
    np.add.at(counts, (tab, sym), 1)
    freq = np.zeros((n_tab, 256), np.int64)
    cost = 0
    for k in range(n_tab):
        if counts[k].any():
            freq[k] = _normalise(counts[k])
            cost += _table_cost(freq[k])
    cum = np.zeros_like(freq)
    cum[:, 1:] = np.cumsum(freq, axis=1)[:, :-1]
    slot = np.zeros((n_tab, M_TOTAL), np.int64)
    for k in range(n_tab):
        if freq[k].any():
            slot[k] = np.repeat(np.arange(256), freq[k])
    data = _rans_encode(sym, tab, freq, cum)
    n = sym.shape[0]
    if use_ctx:
        T, M, A = v.shape

        def dec():
            return _rans_decode_ctx(data, T, M, A, period, freq, cum, slot, side)
    else:
        def dec():
            return _unsymbol(_rans_decode(data, n, tab, freq, cum, slot), side, v.shape)
    return len(data) + len(side) + cost, dec


def zstd_block(v: np.ndarray) -> tuple[int, object]:
    import zstandard
    dt = np.int16 if v.size == 0 or np.abs(v).max() < 32767 else np.int32
    raw = np.ascontiguousarray(v.transpose(2, 1, 0)).astype(dt).tobytes()
    z = zstandard.ZstdCompressor(level=19).compress(raw)

    def dec():
        return np.frombuffer(zstandard.ZstdDecompressor().decompress(z), dt)
    return len(z) + 1, dec


def real(files: list[str], bound: float) -> None:
    print(f"\nreal residual blocks (ROOT and RESI payloads as written at {bound:g} mm)")
    print(f"{'file':<22} {'values':>9} {'coder':<10} {'bytes':>9} {'vs §5':>7} "
          f"{'dec Mval/s':>11}")
    tot: dict[str, list[float]] = {}
    for name, payloads in real_blocks(files, bound):
        n = sum(v.size for p in payloads for v, _, _ in p)
        rows: dict[str, tuple[int, float]] = {}
        b_a, t_a = 0, 0.0
        for p in payloads:
            data, t = current_coder(p)
            b_a, t_a = b_a + len(data), t_a + t
        rows["§5 range"] = (b_a, t_a)
        for label, ctx in (("rans", False), ("rans-ctx", True)):
            b, t = 0, 0.0
            for p in payloads:
                for v, period, _ in p:
                    size, dec = rans_block(v, period, ctx)
                    got = dec()
                    assert np.array_equal(np.asarray(got).reshape(v.shape), v)
                    b, t = b + size, t + best_of(dec)
            rows[label] = (b, t)
        b, t = 0, 0.0
        for p in payloads:
            for v, _, _ in p:
                size, dec = zstd_block(v)
                b, t = b + size, t + best_of(dec)
        rows["zstd -19"] = (b, t)
        for label, (b, t) in rows.items():
            print(f"{name:<22} {n:>9} {label:<10} {b:>9} {b / b_a:>7.3f} {n / t / 1e6:>11.1f}")
            acc = tot.setdefault(label, [0, 0, 0.0])
            acc[0] += b
            acc[1] += n
            acc[2] += t
    base = tot["§5 range"][0]
    for label, (b, n, t) in tot.items():
        print(f"{'all':<22} {int(n):>9} {label:<10} {int(b):>9} {b / base:>7.3f} "
              f"{n / t / 1e6:>11.1f}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--synthetic", action="store_true")
    ap.add_argument("--real", action="store_true")
    ap.add_argument("--files", nargs="+",
                    default=["cmu_135_02", "cmu_02_01", "HDM_dg_06-03_03_120",
                             "auckland_FMC_MH0222_BP06", "numediart_03_rolling"])
    ap.add_argument("--bound", type=float, default=1.0, help="max error in mm (default 1)")
    args = ap.parse_args(argv)
    both = not (args.synthetic or args.real)
    if args.synthetic or both:
        synthetic()
    if args.real or both:
        root = shared_data_dir()
        reason = no_data_reason(exts=(".c3d",))
        missing = [n for n in args.files
                   if root is not None and next(root.rglob(n + ".c3d"), None) is None]
        if reason:
            print(f"real blocks skipped: {reason}")
        elif missing:
            print(f"real blocks skipped: no C3D named {', '.join(missing)} under {root}")
        else:
            real(args.files, args.bound)
    return 0


if __name__ == "__main__":
    sys.exit(main())
