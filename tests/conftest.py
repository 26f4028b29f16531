"""Shared fixtures: a fresh store per test, paths of the shared real data."""

from __future__ import annotations

from pathlib import Path

import pytest

from tasks.store import Store

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
LOGS = SHARED / "logs"
REAL = SHARED / "real"


@pytest.fixture
def store(tmp_path: Path) -> Store:
    """An empty artefact store in a temporary folder."""
    return Store(tmp_path / "store")
