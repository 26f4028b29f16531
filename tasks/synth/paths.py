"""Where a simulated recording and its truth file go, and the checks made before anything is simulated (no
heavy imports here: ``pbd synth`` reports bad arguments before pybullet loads)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from tasks.errors import RecordingError, SceneError
from tasks.recording.writer import FORMATS, Format

TRUTH_SUFFIX = ".truth.json"
"""The truth file of recording ``PATH`` is ``PATH.truth.json``."""


def truth_path(out: Path) -> Path:
    """``PATH.truth.json`` beside the recording ``PATH`` (file or rosbag2 folder)."""
    return out.with_name(out.name + TRUTH_SUFFIX)


def check_output(out: Path, fmt: str) -> Format:
    """The format, checked against the path's suffix (``.mcap``, ``.bag``, a rosbag2 folder without either);
    ``RecordingError`` for a bad format, a mismatched suffix or an existing output."""
    if fmt not in FORMATS:
        msg = f"unknown format {fmt!r} (expected one of {', '.join(FORMATS)})"
        raise RecordingError(out, msg)
    suffix = out.suffix.lower()
    if fmt in ("mcap", "bag") and suffix != f".{fmt}":
        msg = f"a {fmt} recording must end in .{fmt}, not {suffix or 'no suffix'!r}"
        raise RecordingError(out, msg)
    if fmt == "rosbag2" and suffix in (".mcap", ".bag"):
        msg = f"a rosbag2 recording is a folder; {suffix} suggests --format {suffix[1:]}"
        raise RecordingError(out, msg)
    for path in (out, truth_path(out)):
        if path.exists():
            msg = "output exists; refusing to overwrite"
            raise RecordingError(path, msg)
    return fmt


def check_scene_name(name: str, known: Sequence[str]) -> None:
    """``SceneError`` naming the built-in scenes when ``name`` is not one of them."""
    if name not in known:
        msg = f"unknown scene {name!r} (built-in scenes: {', '.join(known)})"
        raise SceneError(msg)
