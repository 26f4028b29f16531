"""Shared fixtures: a fresh store per test, paths of the shared real data."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

from tasks.store import Store

REPO = Path(__file__).resolve().parents[1]


def _shared_folder() -> Path:
    """The shared real data (logs, real trajectories, contracts): ``$PBD_SHARED`` when set, else ``../shared``
    beside this repository, else ``../shared`` beside the local repository this one was cloned from (a clone made
    in a temporary folder: ``git clone . "$(mktemp -d)"``), else ``../shared`` beside this one, which then fails
    the tests that need it, naming the path."""
    env = os.environ.get("PBD_SHARED")
    if env:
        return Path(env)
    beside = REPO.parent / "shared"
    if beside.is_dir():
        return beside
    try:
        found = subprocess.run(
            ["git", "-C", str(REPO), "config", "--get", "remote.origin.url"],
            capture_output=True,
            text=True,
            check=False,
        )
    except OSError:
        return beside
    url = found.stdout.strip().removeprefix("file://")
    if url and "://" not in url and ":" not in url.split("/")[0]:
        origin_shared = Path(url).resolve().parent / "shared"
        if origin_shared.is_dir():
            return origin_shared
    return beside


SHARED = _shared_folder()
LOGS = SHARED / "logs"
REAL = SHARED / "real"


@pytest.fixture
def store(tmp_path: Path) -> Store:
    """An empty artefact store in a temporary folder."""
    return Store(tmp_path / "store")
