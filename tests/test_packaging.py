"""The lowest versions of what mpz needs at run time: pyproject.toml's floors are the pins of
.ci/lowest.txt, the environment the whole suite was run on (README "Install and test").

Before, the floors were never installed: ``ezc3d>=1.5`` let a user keep ezc3d 1.5.16, which
ends the process on a C3D that 1.7.2 reads, with no error to catch.
"""
from __future__ import annotations

from pathlib import Path
import tomllib

from packaging.requirements import Requirement
from packaging.version import Version
import pytest

REPO = Path(__file__).resolve().parents[1]


def _floors() -> dict[str, Version]:
    """Each run-time dependency and the lowest version pyproject.toml allows."""
    deps = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["dependencies"]
    floors = {}
    for line in deps:
        req = Requirement(line)
        lows = [s for s in req.specifier if s.operator in (">=", "==")]
        assert len(lows) == 1, f"{line}: one lower bound (>= or ==) expected"
        floors[req.name.lower()] = Version(lows[0].version)
    return floors


def _pins() -> dict[str, Version]:
    pins = {}
    for line in (REPO / ".ci" / "lowest.txt").read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            name, _, version = line.partition("==")
            assert version, f".ci/lowest.txt: {line!r} is not NAME==VERSION"
            pins[name.strip().lower()] = Version(version.strip())
    return pins


def test_the_lowest_pins_are_the_stated_floors() -> None:
    assert _pins() == _floors()


def test_the_version_is_pyprojects_and_none_released() -> None:
    """The package said 0.1.0, the released version (CHANGELOG.md), for code long after it:
    a build was a second, different mpz-0.1.0 (a release QA run, stop 74). mpz.__version__
    is pyproject.toml's, and while CHANGELOG.md's "Unreleased" holds entries it is above
    every release the CHANGELOG lists, and none of them."""
    import re

    import mpz
    version = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["version"]
    assert mpz.__version__ == version
    # the README's install line names the wheel a build makes
    assert f"dist/mpz-{version}-py3-none-any.whl" in (REPO / "README.md").read_text()
    log = (REPO / "CHANGELOG.md").read_text()
    released = [Version(v) for v in re.findall(r"^## (\d+\.\d+\.\d+) — \d{4}-\d\d-\d\d$",
                                               log, re.M)]
    assert released, "CHANGELOG.md lists no release"
    unreleased = log.split("## Unreleased", 1)[1].split("\n## ", 1)[0]
    if unreleased.strip():
        assert Version(version) > max(released), (version, max(released))
    else:
        assert Version(version) in released


def test_the_c3d_reader_floor_is_the_version_its_hazard_rules_are_for() -> None:
    """mpz.io.c3dbin's rules say which files would crash ezc3d 1.7.2 (docs/io-notes.md);
    an older ezc3d crashes on others (1.5.16) or reads DEC residuals otherwise (1.7.1)."""
    assert _floors()["ezc3d"] == Version("1.7.2")
    assert "ezc3d` 1.7.2" in (REPO / "docs" / "io-notes.md").read_text()


def test_no_tracked_text_file_holds_merge_conflict_markers() -> None:
    """A cherry-pick's conflict markers were committed into CHANGELOG.md (caught by a
    helper's review, not by a test): no tracked text file has a line that starts with one."""
    import shutil
    import subprocess
    root = Path(__file__).resolve().parents[1]
    if shutil.which("git") is None or not (root / ".git").exists():
        pytest.skip("not a git checkout")
    files = subprocess.run(["git", "ls-files", "-z"], cwd=root, capture_output=True,
                           check=True).stdout.decode().split("\0")
    found = []
    for name in filter(None, files):
        try:
            text = (root / name).read_text(encoding="utf-8")
        except (UnicodeDecodeError, OSError):
            continue                                   # binary: vectors, kernels
        found += [f"{name}:{i}" for i, line in enumerate(text.splitlines(), 1)
                  if line.startswith(("<<<<<<< ", ">>>>>>> ")) or line == "======="]
    assert found == []
