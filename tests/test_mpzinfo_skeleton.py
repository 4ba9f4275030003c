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
    e = info["skeleton"]["end_sites"]               # not a §7.3 feature (stop 55)
    assert {k: v for k, v in info["skeleton"].items() if k != "end_sites"} == want
    assert 0 <= e < want["joints"] and (e == 0 or want["chunk"] == "bvhs")
    assert f"{want['chunk']} skeleton of {want['joints'] - e} joint" in summary_line(info)


def _bvh_counts(text: str) -> tuple[int, int, int, int]:
    """ROOT and JOINT lines, End Site lines, the channels the CHANNELS lines declare, and
    the Frames: count of BVH text, read here from the text itself."""
    words = [ln.split() for ln in text.splitlines() if ln.split()]
    joints = sum(w[0] in ("ROOT", "JOINT") for w in words)
    ends = sum(w[:2] == ["End", "Site"] for w in words)
    channels = sum(int(w[1]) for w in words if w[0] == "CHANNELS")
    frames = next(int(w[1]) for w in words if w[0] == "Frames:")
    return joints, ends, channels, frames


def test_mpzinfo_counts_bvh_end_sites_apart_and_leads_with_the_channels_ratio(shared_data):
    """cmu_131_03 has 31 joints and 7 End Sites: mpzinfo, mpz encode and mpz compare said
    "38 joints", the chunk's count. And mpzinfo's ratio was the joint positions' as float32,
    1.3-1.5x the ratio against the channels, which are what a BVH holds (a report QA run of
    stop 55). Counts and sizes are read from the BVH text and the file's length."""
    import mpz
    for src in sorted((shared_data / "bvh").glob("*.bvh")):
        joints, ends, channels, frames = _bvh_counts(src.read_text())
        data = mpz.encode(mpz.io.read(src))
        info = inspect(data, src.name)
        assert info["skeleton"]["joints"] == joints + ends
        assert info["skeleton"]["end_sites"] == ends and info["skeleton"]["channels"] == channels
        assert math.isclose(info["ratio_channels"], 4 * frames * channels / len(data),
                            rel_tol=1e-12)
        line = summary_line(info)
        assert f"skeleton of {joints} joints and {ends} End Sites" in line, line
        assert f"{info['ratio_channels']:.1f}:1 (the joint positions" in line
    amc = shared_data / "amc" / "02_01.amc"
    info = inspect(mpz.encode(mpz.io.read(amc)), amc.name)
    asf = (shared_data / "amc" / "02.asf").read_text()
    bonedata = asf.split(":bonedata")[1].split(":hierarchy")[0]
    bones = sum(ln.strip() == "begin" for ln in bonedata.splitlines())
    assert info["skeleton"]["end_sites"] == 0 and info["skeleton"]["joints"] == bones + 1
    assert f"skeleton of {bones + 1} joints," in summary_line(info)


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


@pytest.mark.parametrize(("name", "features"), _skeleton_vectors())
def test_the_bounds_mpzinfo_prints_are_not_below_the_files(name, features):
    """mpzinfo printed `joints within 1.16 mm` for a position_bound of 1.16141 mm, and
    `mpz encode` 1.161: a bound printed shorter than it is was below it, and an archive
    team's own check passed the printed figure (a QA run of stop 72). Each bound of the
    line, read back from it, is now at least the manifest's (the file's) figure."""
    import re
    line = summary_line(inspect((VECTORS / name).read_bytes(), name))
    got = re.search(r"channels within (\S+) deg and (\S+), (?:joints within (\S+?)(?: \w+)?\)|"
                    r"no joint bound)", line)
    assert got is not None, line
    for printed, key in zip(got.groups(), ("angle_bound", "translation_bound",
                                           "position_bound"), strict=True):
        if printed is not None:
            assert float(printed) >= features[key], (key, printed, features[key], line)
