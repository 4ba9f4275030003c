"""The benchmarks' error-bounded peers (``bench/peers.py``) give back every valid sample
within their bound, and the gaps where the source has them: a peer that broke its bound
would make MPZ look worse than it is, one that dropped the gaps better than it is.

``bench/peers.py`` is loaded from its path (as tests/test_fisher.py loads baselines.py);
the peers need the ``bench`` extra (zstandard, pysz) and are skipped without it.
"""
from __future__ import annotations

import importlib.util
from pathlib import Path
import sys

import numpy as np
import pytest

from mpz.synth import generate

pytest.importorskip("zstandard", reason="the bench extra is not installed")


def _load_peers():
    bench = Path(__file__).resolve().parents[1] / "bench"
    spec = importlib.util.spec_from_file_location("mpz_bench_peers", bench / "peers.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


peers = _load_peers()


def _motion_with_gaps():
    m = generate("walk", frames=150, markers=12, seed=7)
    m.valid[40:55, 3] = False          # a gap inside, one at the start, one marker at the end
    m.valid[:10, 5] = False
    m.valid[140:, 11] = False
    m.positions[~m.valid] = np.nan
    return m


def _check(m, back, E):
    assert back.shape == m.positions.shape
    assert np.array_equal(np.isnan(back).any(-1), ~m.valid)      # the gaps, and only them
    d = np.linalg.norm(back[m.valid] - m.positions[m.valid], axis=-1)
    assert d.max() <= E
    assert d.max() > E / 10            # a lossy peer at this bound does use it


@pytest.mark.parametrize("E", [0.5, 2.0, 1e-4])       # 1e-4: residuals past 16 bits
@pytest.mark.parametrize("planes", [True, False])
def test_qpz_keeps_its_bound_and_the_gaps(E, planes):
    m = _motion_with_gaps()
    enc, dec = peers.qpz_codec(m, E, planes=planes)
    _check(m, dec(enc()), E)


@pytest.mark.parametrize("layout", peers.SZ3_LAYOUTS)
def test_each_sz3_layout_keeps_its_bound_and_the_gaps(layout):
    pytest.importorskip("pysz", reason="pysz (SZ3) is not installed")
    m = _motion_with_gaps()
    enc, dec = peers.sz3_one(m, 1.0, layout, "LORENZO_REG")
    _check(m, dec(enc()), 1.0)


@pytest.mark.parametrize("predictor", peers.SZ3_ALGORITHMS)
def test_each_sz3_predictor_keeps_its_bound_and_its_settings_take_effect(predictor):
    pytest.importorskip("pysz", reason="pysz (SZ3) is not installed")
    m = _motion_with_gaps()
    enc, dec = peers.sz3_one(m, 1.0, "1-D by channel", predictor)
    _check(m, dec(enc()), 1.0)


def test_sz3_config_settings_change_the_coding():
    """The [AlgoSettings] reach SZ3 (a config file that failed to load would leave every
    LORENZO_REG mix at its defaults, and the search would try one predictor four times)."""
    pytest.importorskip("pysz", reason="pysz (SZ3) is not installed")
    m = _motion_with_gaps()
    sizes = {p: len(peers.sz3_one(m, 1.0, "1-D by channel", p)[0]())
             for p in ("LORENZO_REG", "Lorenzo 2", "Lorenzo 1")}
    assert len(set(sizes.values())) == 3, sizes


def test_sz3_best_is_the_smallest_configuration():
    pytest.importorskip("pysz", reason="pysz (SZ3) is not installed")
    m = _motion_with_gaps()
    (enc, dec), name, size = peers.sz3_codec(m, 1.0)
    assert len(enc()) == size
    sizes = [len(peers.sz3_one(m, 1.0, lay, alg)[0]())
             for lay in peers.SZ3_LAYOUTS for alg in peers.SZ3_ALGORITHMS]
    assert size == min(sizes), name
    _check(m, dec(enc()), 1.0)


def test_a_missing_peer_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "pysz", None)           # import pysz raises ImportError
    with pytest.raises(peers.PeerMissing, match=r"\[bench\]"):
        peers.sz3_one(_motion_with_gaps(), 1.0, "F,M,3", "INTERP cubic")



def test_the_benches_run_with_the_old_release_s_package(monkeypatch):
    """The README runs today's bench_rd.py (and bench_encode, bench_decode) with the old
    version installed; 0.1.0 has no mpz.format or mpz.skeleton, no ``lossy`` option (its
    default mode had no bound) and no ``Motion.extras``, and every script failed on its
    imports (a maintainer's QA run of stop 75). Without those modules their units come
    from a table of their own, which must be mpz.format's."""
    from mpz.format import MM_PER_UNIT
    from mpz.io.bvh import parse_bvh
    bench = Path(__file__).resolve().parents[1] / "bench"
    monkeypatch.syspath_prepend(str(bench))
    monkeypatch.setitem(sys.modules, "peers", peers)

    def load(name, file):
        spec = importlib.util.spec_from_file_location(name, bench / file)
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module
    common = load("mpz_bench_common", "_common.py")
    assert common._MM_PER_UNIT == MM_PER_UNIT
    assert load("mpz_bench_rd", "bench_rd.py").LOSSY == {"lossy": True}
    bvh = parse_bvh("HIERARCHY\nROOT A\n{\nOFFSET 0 0 0\nCHANNELS 3 Xposition Yposition "
                    "Zposition\nEnd Site\n{\nOFFSET 0 1 0\n}\n}\nMOTION\nFrames: 1\n"
                    "Frame Time: 0.1\n0 0 0\n")
    from mpz.skeleton import with_units
    walk, cm = generate("walk", frames=5), with_units(bvh, "cm")
    assert common.mm_per_unit(walk) == 1.0 and common.mm_per_unit(cm) == 10.0
    assert common.mm_per_unit(bvh) is None
    monkeypatch.setitem(sys.modules, "mpz.format", None)     # import mpz.format fails
    monkeypatch.setitem(sys.modules, "mpz.skeleton", None)
    assert common.mm_per_unit(walk) == 1.0 and common.mm_per_unit(bvh) is None
    # no lossy and no threads option (0.1.0's EncodeOptions), and a Motion without extras
    import dataclasses
    from types import SimpleNamespace

    import mpz.encoder

    @dataclasses.dataclass
    class OldOptions:
        max_error: float | None = None
    monkeypatch.setattr(mpz.encoder, "EncodeOptions", OldOptions)
    assert load("mpz_bench_rd_old", "bench_rd.py").LOSSY == {}
    assert load("mpz_bench_speed_old", "bench_speed.py").HAS_THREADS is False
    old = SimpleNamespace(positions=walk.positions, angles=None)
    assert common.coded_float32(old) == common.coded_float32(walk)
