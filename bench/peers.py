"""The error-bounded peers MPZ is measured against, in the same process (bench_rd.py,
bench_speed.py): one definition of each, so that every bench gives the same peer the same
input and the same bound.

Every peer codes the marker positions of a motion (``[F, M, 3]``, gaps as in
``Motion.valid``) under a guaranteed Euclidean bound ``E`` per valid sample, the bound MPZ
declares (spec §7.2), and pays for what it needs to give the gaps back: gaps are filled
by linear interpolation (``mpz.encoder.fill_gaps``, as MPZ's own encoder does) and the
validity mask, when a motion has gaps, is packed one bit per marker-frame and compressed
with zstd -19. Each codec is a pair of closures, ``enc() -> bytes`` and ``dec(bytes) ->
positions`` (float64 ``[F, M, 3]``, NaN at gaps), so that a bench can time them and check
the bound on what comes back.

- :func:`qpz_codec`: quantise with step 2E/sqrt(3) (each axis within E/sqrt(3), so the
  Euclidean error within E), second-order temporal prediction, zstd -19 on the residuals,
  marker-major, zigzag-mapped in byte planes: the baseline of issues 4 and 15.
- :func:`sz3_codec`: SZ3 (``pysz``, the ``bench`` extra) with an absolute bound per value,
  the best of :data:`SZ3_LAYOUTS` x :data:`SZ3_PREDICTORS` (5 x 7) for this motion and bound
  (smallest output whose decoded positions keep the bound): the "SZ3 best" of
  ``../shared/ANCHORS.md``.
- :func:`zstd19`, :func:`xz9`: lossless, on bytes.

A peer whose package is missing raises :class:`PeerMissing`, with the extra to install.
"""
from __future__ import annotations

from collections.abc import Callable
import lzma
import math

import numpy as np

from mpz.encoder import fill_gaps
from mpz.predict import reconstruct, residuals

Codec = tuple[Callable[[], bytes], Callable[[bytes], np.ndarray]]


class PeerMissing(RuntimeError):
    """A peer's package is not installed."""


def _zstandard():
    try:
        import zstandard
    except ImportError:
        raise PeerMissing("zstandard is not installed: pip install -e '.[bench]'") from None
    return zstandard


def zstd19(b: bytes) -> bytes:
    """zstd -19 of ``b`` (lossless)."""
    return _zstandard().ZstdCompressor(level=19).compress(b)


def unzstd(b: bytes) -> bytes:
    return _zstandard().ZstdDecompressor().decompress(b)


def xz9(b: bytes) -> bytes:
    """xz -9 of ``b`` (lossless)."""
    return lzma.compress(b, preset=9)


def _mask_bytes(valid: np.ndarray) -> bytes:
    """The validity mask as a peer pays for it: empty without gaps, else zstd -19 of one
    bit per marker-frame."""
    return b"" if valid.all() else zstd19(np.packbits(valid).tobytes())


def _with_gaps(x: np.ndarray, valid: np.ndarray) -> np.ndarray:
    out = np.array(x, dtype=np.float64)
    out[~valid] = np.nan
    return out


def _framed(mask: bytes, body: bytes) -> bytes:
    """mask length (4 bytes, little-endian), mask, body: one byte string per peer output,
    so that its length is everything the peer needs to give the motion back."""
    return len(mask).to_bytes(4, "little") + mask + body


def _unframed(data: bytes) -> tuple[bytes, bytes]:
    n = int.from_bytes(data[:4], "little")
    return data[4:4 + n], data[4 + n:]


def _mask_back(mask: bytes, shape: tuple[int, int]) -> np.ndarray:
    if not mask:
        return np.ones(shape, bool)
    bits = np.unpackbits(np.frombuffer(unzstd(mask), np.uint8), count=shape[0] * shape[1])
    return bits.reshape(shape).astype(bool)


def qpz_codec(m, E: float, *, planes: bool = True) -> Codec:
    """(encode, decode) of the quantise + predict + zstd -19 baseline at bound ``E``.

    The second-order residuals go marker after marker and axis after axis. With
    ``planes`` (the default) they are zigzag-mapped to unsigned integers and split into
    byte planes (the low bytes of every residual, then the next bytes) before zstd -19:
    8-10 % smaller than the residuals as they are (cmu_02_01, cmu_135_02, HDM_mm at 1 mm:
    ratio 15.9 / 20.0 / 26.5 against 14.6 / 18.1 / 24.4), the baseline at its best, as
    issue 15's table measured it. ``planes=False`` is issue 4's recipe as written: the
    residuals as little-endian int16 (int32 when one does not fit), then zstd -19."""
    step = 2 * E / math.sqrt(3)
    F, M = m.n_frames, m.n_markers

    def enc() -> bytes:
        x = fill_gaps(m.positions, m.valid)
        q = np.floor(x / step + 0.5).astype(np.int64)
        e = np.ascontiguousarray(residuals(q, 2).transpose(1, 2, 0)).ravel()
        if planes:
            z = (e << 1) ^ (e >> 63)                        # zigzag: 0, -1, 1, -2 -> 0, 1, 2, 3
            top = int(z.max(initial=0))
            width = 2 if top < 1 << 16 else 4 if top < 1 << 32 else 8
            body = z.astype(f"<u{width}").view(np.uint8).reshape(-1, width).T.tobytes()
        else:
            width = 2 if int(np.abs(e).max(initial=0)) < 1 << 15 else 4
            body = e.astype(f"<i{width}").tobytes()
        return _framed(_mask_bytes(m.valid), bytes([width]) + zstd19(body))

    def dec(data: bytes) -> np.ndarray:
        mask, body = _unframed(data)
        width, raw = body[0], unzstd(body[1:])
        if planes:
            stacked = np.frombuffer(raw, np.uint8).reshape(width, -1)
            z = np.ascontiguousarray(stacked.T).view(f"<u{width}").ravel().astype(np.uint64)
            e = (z >> np.uint64(1)).astype(np.int64) ^ -(z & np.uint64(1)).astype(np.int64)
        else:
            e = np.frombuffer(raw, f"<i{width}").astype(np.int64)
        return _with_gaps(reconstruct(e.reshape(M, 3, F).transpose(2, 0, 1), 2) * step,
                          _mask_back(mask, (F, M)))
    return enc, dec


#: the array shapes SZ3 is given (from the ``[F, M, 3]`` positions): the 3-D array as it is
#: or marker-major, frames by channels, channels by frames, and channel after channel
SZ3_LAYOUTS = ("F,M,3", "M,3,F", "F,3M", "3M,F", "1-D by channel")
#: SZ3's predictors tried for each layout: name -> (``szAlgorithm``, the ``[AlgoSettings]``
#: of an SZ3 config file, loaded with ``szConfig.loadcfg``). LORENZO_REG's default
#: (first-order Lorenzo and regression) is one of four mixes: on marker channels the
#: second-order Lorenzo alone codes 13 % smaller than the best default (cmu_02_01 at 1 mm,
#: one channel after another: 10,498 bytes against 12,100 for INTERP_LORENZO), and a peer
#: tried with its defaults only would flatter MPZ
SZ3_PREDICTORS: dict[str, tuple[str, str]] = {
    "INTERP_LORENZO": ("INTERP_LORENZO", ""),
    "INTERP cubic": ("INTERP", "InterpolationAlgo = CUBIC\n"),
    "INTERP linear": ("INTERP", "InterpolationAlgo = LINEAR\n"),
    "LORENZO_REG": ("LORENZO_REG", ""),
    "Lorenzo 1+2, regression": ("LORENZO_REG", "Lorenzo = YES\nLorenzo2ndOrder = YES\n"
                                               "Regression = YES\n"),
    "Lorenzo 2": ("LORENZO_REG", "Lorenzo = NO\nLorenzo2ndOrder = YES\nRegression = NO\n"),
    "Lorenzo 1": ("LORENZO_REG", "Lorenzo = YES\nLorenzo2ndOrder = NO\nRegression = NO\n"),
}
SZ3_ALGORITHMS = tuple(SZ3_PREDICTORS)


def _layout(x: np.ndarray, name: str) -> np.ndarray:
    F, M, _ = x.shape
    if name == "F,M,3":
        return np.ascontiguousarray(x)
    if name == "M,3,F":
        return np.ascontiguousarray(x.transpose(1, 2, 0))
    if name == "F,3M":
        return np.ascontiguousarray(x.reshape(F, 3 * M))
    if name == "3M,F":
        return np.ascontiguousarray(x.reshape(F, 3 * M).T)
    return np.ascontiguousarray(x.transpose(1, 2, 0)).reshape(-1)     # 1-D by channel


def _unlayout(y: np.ndarray, name: str, F: int, M: int) -> np.ndarray:
    if name == "F,M,3":
        return y.reshape(F, M, 3)
    if name == "F,3M":
        return y.reshape(F, M, 3)
    if name == "3M,F":
        return y.reshape(3 * M, F).T.reshape(F, M, 3)
    return y.reshape(M, 3, F).transpose(2, 0, 1)                        # M,3,F and 1-D


def _pysz():
    try:
        import pysz
    except ImportError:
        raise PeerMissing("pysz (SZ3) is not installed: pip install -e '.[bench]'") from None
    return pysz


def _sz3_config(pysz, shape: tuple[int, ...], algorithm: str, per_value: float):
    """An ``szConfig`` of predictor ``algorithm`` (:data:`SZ3_PREDICTORS`), absolute bound
    ``per_value``; its ``[AlgoSettings]`` go through a config file, as SZ3 reads them."""
    import os
    import tempfile
    algo, settings = SZ3_PREDICTORS[algorithm]
    cfg = pysz.szConfig(shape)
    if settings:
        fd, path = tempfile.mkstemp(suffix=".ini")
        try:
            with os.fdopen(fd, "w") as fh:
                fh.write(f"[GlobalSettings]\nCmprAlgo = ALGO_{algo}\nErrorBoundMode = ABS\n"
                         f"AbsErrorBound = {per_value!r}\n[AlgoSettings]\n{settings}")
            cfg.loadcfg(path)
        finally:
            os.remove(path)
    cfg.errorBoundMode = pysz.szErrorBoundMode.ABS
    cfg.absErrorBound = per_value
    cfg.cmprAlgo = getattr(pysz.szAlgorithm, algo)
    return cfg


def sz3_one(m, E: float, layout: str, algorithm: str) -> Codec:
    """SZ3 with one layout and predictor (:data:`SZ3_PREDICTORS`), at bound ``E``. The
    input is the float32 positions (the yardstick's bytes) with the gaps filled; the
    per-value bound is E/sqrt(3) less float32's rounding of the largest coordinate, so
    that the decoded float32 values are within E (Euclidean) of the float64 source."""
    pysz = _pysz()
    F, M = m.n_frames, m.n_markers
    x32 = fill_gaps(m.positions, m.valid).astype(np.float32)
    top = float(np.abs(x32).max()) if x32.size else 0.0
    per_value = E / math.sqrt(3) - 2.0 * top * 2.0 ** -24
    if per_value <= 0:
        raise ValueError(f"E = {E} is below float32's resolution of these positions")
    data = _layout(x32, layout)
    cfg = _sz3_config(pysz, data.shape, algorithm, per_value)

    def enc() -> bytes:
        body, _ = pysz.sz.compress(data, cfg)
        return _framed(_mask_bytes(m.valid), body.tobytes())

    def dec(blob: bytes) -> np.ndarray:
        mask, body = _unframed(blob)
        y, _ = pysz.sz.decompress(np.frombuffer(body, np.uint8), np.float32, data.shape)
        return _with_gaps(_unlayout(np.asarray(y), layout, F, M), _mask_back(mask, (F, M)))
    return enc, dec


def max_error(m, back: np.ndarray) -> float:
    """Largest Euclidean error over the valid samples (0 for a motion without any)."""
    d = np.linalg.norm(back[m.valid] - m.positions[m.valid], axis=-1)
    return float(d.max()) if d.size else 0.0


def sz3_codec(m, E: float) -> tuple[Codec, str, int]:
    """The best SZ3 configuration for ``m`` at bound ``E``: ((enc, dec), its name, its
    byte count). Every configuration of :data:`SZ3_LAYOUTS` x :data:`SZ3_ALGORITHMS` is
    run once and decoded; those beyond the bound are not chosen (none was, on the real
    files); ValueError when none keeps it."""
    best: tuple[int, str, Codec] | None = None
    for layout in SZ3_LAYOUTS:
        for algorithm in SZ3_ALGORITHMS:
            codec = sz3_one(m, E, layout, algorithm)
            data = codec[0]()
            if max_error(m, codec[1](data)) > E:
                continue
            if best is None or len(data) < best[0]:
                best = (len(data), f"{layout} {algorithm}", codec)
    if best is None:
        raise ValueError(f"no SZ3 configuration keeps the bound {E}")
    return best[2], best[1], best[0]
