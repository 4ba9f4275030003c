"""What mpz compare and mpz summary report: the motion compared, its units and rate.

Each expected figure is computed here with numpy from the arrays written (or from what
``mpz decode`` writes, to NPY), not by the command under test. The tests on the real
recordings skip without them (conftest.shared_data)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mpz.tools import mpz_cli


def cli(capsys, *argv: object) -> tuple[int, str, str]:
    code = mpz_cli.main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def max_error(a: np.ndarray, b: np.ndarray) -> float:
    """The largest Euclidean distance between two [frames, markers, 3] arrays."""
    return float(np.linalg.norm(a - b, axis=2).max())


def bvh_text(frames: int = 60) -> str:
    """A three-joint BVH whose angles sweep smoothly (no length unit, as every BVH)."""
    t = np.arange(frames) / frames
    rows = []
    for v in t:
        ch = [10 * v, 2.0, 3 * v, 30 * np.sin(6 * v), 20 * v, 5.0,
              40 * np.sin(4 * v), 10.0, 25 * np.cos(5 * v), 60 * v]
        rows.append(" ".join(f"{c:.4f}" for c in ch))
    return ("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n"
            "  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
            "  JOINT Spine\n  {\n    OFFSET 0 10 0\n"
            "    CHANNELS 3 Zrotation Xrotation Yrotation\n"
            "    End Site\n    {\n      OFFSET 0 12 0\n    }\n  }\n"
            "  JOINT Leg\n  {\n    OFFSET 2 -1 0\n    CHANNELS 1 Xrotation\n"
            "    End Site\n    {\n      OFFSET 0 -15 0\n    }\n  }\n}\n"
            f"MOTION\nFrames: {frames}\nFrame Time: 0.0333333\n" + "\n".join(rows) + "\n")


def decoded_npy(capsys, tmp_path: Path, packed: Path) -> np.ndarray:
    """What ``mpz decode`` writes (NPY: float64 positions, NaN gaps)."""
    out = tmp_path / (packed.stem + "_decoded.npy")
    code, _, err = cli(capsys, "decode", packed, "-o", out, "-f")
    assert code == 0, err
    return np.load(out)


# -- 1. a skeletal .mpz is read as mpz decode writes it ---------------------------------------

def test_summary_of_a_skeletal_mpz_measures_shares_on_the_joint_positions(tmp_path, capsys):
    src = tmp_path / "sweep.bvh"
    src.write_text(bvh_text())
    packed = tmp_path / "sweep.mpz"
    code, _, err = cli(capsys, "encode", src, "-o", packed, "--summary", "3", "-q")
    assert code == 0, err
    pos = decoded_npy(capsys, tmp_path, packed)                 # no gaps in a BVH
    x = (pos - pos.mean(axis=1, keepdims=True)).reshape(len(pos), -1)
    code, out, _ = cli(capsys, "summary", packed, "--json")
    (level,) = json.loads(out)["levels"]
    starts = [s["start"] for s in level["segments"]]
    sse = [float(((x[s:e] - x[s:e].mean(axis=0)) ** 2).sum())
           for s, e in zip(starts, [*starts[1:], len(x)], strict=True)]
    got = [s["share"] for s in level["segments"]]
    assert got == pytest.approx([100 * v / sum(sse) for v in sse], rel=1e-9)
