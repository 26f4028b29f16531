"""The sample recordings of ``pbd demo``: one MCAP per built-in scene, each with a fixed seed, written only when
missing (``<folder>/<scene>.mcap`` with ``<scene>.mcap.truth.json``)."""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

from tasks.scenes.catalog import SCENE_NAMES
from tasks.synth.paths import truth_path
from tasks.synth.record import synthesize

SAMPLE_SEEDS: dict[str, int] = {}
"""Seed of each scene's sample recording; scenes not listed use ``DEFAULT_SAMPLE_SEED``."""
DEFAULT_SAMPLE_SEED = 1
MAX_SAMPLE_BYTES = 1_000_000
"""Each sample recording stays below this (they are committed under data/recordings/)."""


def sample_seed(scene: str) -> int:
    """The fixed seed of ``scene``'s sample recording."""
    return SAMPLE_SEEDS.get(scene, DEFAULT_SAMPLE_SEED)


def ensure_sample_recordings(folder: Path) -> list[Path]:
    """Paths of the sample recordings of every built-in scene under ``folder``, writing those that are missing
    (a recording whose truth file is missing gets it back from an identical re-run)."""

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths: list[Path] = []
    for scene in SCENE_NAMES:
        path = folder / f"{scene}.mcap"
        truth = truth_path(path)
        if not path.exists():
            if truth.exists():  # a truth file without its recording: made again together
                truth.unlink()
            synthesize(scene, sample_seed(scene), path, "mcap")
        elif not truth.exists():
            scratch = Path(tempfile.mkdtemp(dir=folder, prefix=".synth."))
            try:
                made = synthesize(scene, sample_seed(scene), scratch / path.name, "mcap")
                if made.read_bytes() == path.read_bytes():
                    truth_path(made).rename(truth)
            finally:
                shutil.rmtree(scratch, ignore_errors=True)
        paths.append(path)
    return paths
