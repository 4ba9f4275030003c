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
