"""Find the recordings under an archive folder: ``*.mcap``, ``*.bag`` files and rosbag2 folders."""

from __future__ import annotations

from pathlib import Path

from tasks.errors import RecordingError

ROSBAG2_MARKER = "metadata.yaml"
"""A folder holding this file is one rosbag2 recording (its storage files are not listed on their own)."""


def find_recordings(archive: Path) -> list[Path]:
    """Every recording under ``archive`` in path order: MCAP and ROS 1 bag files, and rosbag2 folders."""
    if not archive.is_dir():
        msg = "not a folder of recordings"
        raise RecordingError(archive, msg)
    bags2 = sorted(p.parent for p in archive.rglob(ROSBAG2_MARKER))
    found = list(bags2)
    for path in sorted(archive.rglob("*")):
        if not path.is_file() or path.suffix not in {".mcap", ".bag"}:
            continue
        if any(folder in path.parents for folder in bags2):
            continue
        found.append(path)
    return sorted(found)
