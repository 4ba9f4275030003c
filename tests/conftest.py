"""Shared fixtures. Real recordings are read from ../shared/data (never copied
into the repo); tests that need them skip with a reason when it is absent."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def shared_data_dir() -> Path | None:
    """``$MPZ_SHARED_DATA`` or ``../shared/data`` beside the checkout, if present."""
    env = os.environ.get("MPZ_SHARED_DATA")
    cand = Path(env) if env else REPO.parent / "shared" / "data"
    return cand if cand.is_dir() else None


@pytest.fixture(scope="session")
def shared_data() -> Path:
    d = shared_data_dir()
    if d is None:
        pytest.skip("real recordings not available: ../shared/data is absent (set MPZ_SHARED_DATA)")
    return d
