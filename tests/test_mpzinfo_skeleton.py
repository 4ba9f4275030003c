"""mpzinfo and the skeleton chunks (a QA run of stop 53): spec §7.3 says the figures of
``features.skeleton`` are what mpzinfo reports, and it reported none of them; an asfs
joint limit of ±∞ (which §4.14.2 allows) showed as null in ``--json`` and ``-vv``, as if
unknown. Expected figures are the frozen manifest's and, for one vector, worked out from
the spec's formula."""
from __future__ import annotations

import json
import math
from pathlib import Path
import subprocess
import sys

import pytest

from mpz.tools.mpzinfo import inspect, summary_line

REPO = Path(__file__).resolve().parents[1]
VECTORS = REPO / "conformance" / "vectors"
U37 = VECTORS / "uncommon" / "u37-asfs-radians-inf-limits-stretch.mpz"


def _skeleton_vectors() -> list[tuple[str, dict]]:
    manifest = json.loads((VECTORS / "manifest.json").read_text())
    return [(v["file"], v["features"]["skeleton"]) for v in manifest["vectors"]
            if v.get("expected") == "decode" and "skeleton" in v.get("features", {})]


def test_some_vectors_hold_a_skeleton():
    chunks = {sk["chunk"] for _, sk in _skeleton_vectors()}
    assert chunks == {"bvhs", "asfs"}


@pytest.mark.parametrize(("name", "features"), _skeleton_vectors())
def test_mpzinfo_reports_the_manifests_skeleton_figures(name, features):
    info = inspect((VECTORS / name).read_bytes(), name)
    want = {k: v for k, v in features.items() if k != "channels_sha256"}
    assert info["skeleton"] == want
    assert f"{want['chunk']} skeleton of {want['joints']} joints" in summary_line(info)


def test_the_angle_bound_of_a_radian_asfs_follows_the_spec_formula():
    """§7.3: h = (m / 10^d) / 2 per channel, the largest h of the rotations times the
    binary64 180/π; translations in their own units."""
    info = inspect(U37.read_bytes(), U37.name)
    asfs = next(c["fields"] for c in info["chunks"] if c["type"] == "asfs")
    assert asfs["angle_unit"] == 1                         # radians
    kinds = list(asfs["root_order"])
    for bone in asfs["bones"]:
        kinds += bone["dofs"]
    h = [c["step_mantissa"] / 10.0 ** c["step_digits"] / 2 for c in asfs["channels"]]
    rot = [x for x, k in zip(h, kinds, strict=True) if k in (3, 4, 5)]
    lin = [x for x, k in zip(h, kinds, strict=True) if k not in (3, 4, 5)]
    assert rot and lin
    assert info["skeleton"]["angle_bound"] == max(rot) * 57.29577951308232
    assert info["skeleton"]["translation_bound"] == max(lin)
    assert info["skeleton"]["angle_bound"] == math.degrees(max(rot) * 2) / 2


def test_infinite_limits_are_said_as_infinite_not_as_unknown():
    info = inspect(U37.read_bytes(), U37.name)
    bones = next(c["fields"] for c in info["chunks"] if c["type"] == "asfs")["bones"]
    limits = [lim for b in bones for lim in b["limits"]]
    assert ["-inf", 20.0] in limits and ["-inf", "inf"] in limits
    p = subprocess.run([sys.executable, "-m", "mpz.tools.mpzinfo", "-vv", str(U37)],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert '"limits": [["-inf", 20.0], [-1.0, 1.0], ["-inf", "inf"]]' in p.stdout
    assert "null" not in p.stdout


def test_a_file_without_a_skeleton_has_none():
    name = "valid/v01-walk-default.mpz"
    path = VECTORS / name
    if not path.exists():
        path = sorted((VECTORS / "valid").glob("v01-*.mpz"))[0]
    info = inspect(path.read_bytes(), path.name)
    assert info["status"] == "ok" and info["skeleton"] is None
    assert "skeleton of" not in summary_line(info)
