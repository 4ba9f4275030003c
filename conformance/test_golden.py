"""Regression across codec versions: mpzinfo --json and the decoded digests of
every vector are frozen in conformance/golden/golden.json (regenerated only by
``python -m mpz.tools.make_golden``, with a CHANGELOG.md entry naming the new
golden id)."""
import json
from pathlib import Path

import pytest

from mpz.tools.make_golden import GOLDEN_DIR, GOLDEN_FILE, compute

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def frozen():
    return json.loads((GOLDEN_DIR / GOLDEN_FILE).read_text())


@pytest.fixture(scope="module")
def current():
    return compute()


def test_golden_matches_current_codec(frozen, current):
    changed = sorted(name for name in set(frozen["vectors"]) | set(current["vectors"])
                     if frozen["vectors"].get(name) != current["vectors"].get(name))
    assert not changed, (
        f"golden output changed for {len(changed)} vector(s), e.g. {changed[:5]}; if intended, run "
        f"python -m mpz.tools.make_golden and say why in CHANGELOG.md")
    assert frozen["golden_id"] == current["golden_id"]


def test_changelog_explains_the_golden_id(frozen):
    text = (REPO / "CHANGELOG.md").read_text()
    assert frozen["golden_id"] in text, "CHANGELOG.md must name the current golden id and say why"


def test_vector_set_and_spec_version_history_in_step():
    """Every format version the vectors use is in spec Appendix B, and the newest spec
    version has vectors: a 1.x decoder must decode every vector of every earlier 1.y."""
    import re
    man = json.loads((REPO / "conformance" / "vectors" / "manifest.json").read_text())
    spec = (REPO / "spec" / "mpz-1.md").read_text()
    history = spec[spec.index("## Appendix B"):spec.index("## Appendix C")]
    versions = re.findall(r"^\| (\d+\.\d+) \|", history, flags=re.M)
    assert versions, "Appendix B lists no version"
    fmt = man["format"].split()[-1]
    assert fmt in versions
    assert max(versions, key=lambda v: tuple(map(int, v.split(".")))) == fmt, \
        "the newest spec version has no vector set: run python -m mpz.tools.make_vectors"
