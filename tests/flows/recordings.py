"""Small demonstration recordings for the flow and report tests, written by the real ``RecordingWriter``.

A door (three markers) turns ``angle_rad`` about a vertical hinge through (0.5, 0, 1) m between 0.5 s and
2.5 s of a 3 s recording at 100 Hz, with the wrist following the handle and an object model cloud of the
door leaf at the start.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from tasks.recording.writer import RecordingWriter

HINGE = np.array([0.5, 0.0, 1.0])
START_NS = 1_700_000_000_000_000_000


def door_positions(angle_rad: float, rate_hz: float = 100.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stamps (n,) ns, marker positions (3, n, 3) m and the door angle (n,) rad over the recording."""
    t = np.arange(0.0, 3.0, 1.0 / rate_hz)
    phase = np.clip((t - 0.5) / 2.0, 0.0, 1.0)
    angle = angle_rad * (0.5 - 0.5 * np.cos(np.pi * phase))
    offsets = np.array([[0.3, 0.0, 0.2], [0.5, 0.0, -0.1], [0.2, 0.0, -0.3]])  # on the leaf, in the hinge frame
    c, s = np.cos(angle), np.sin(angle)
    pts = np.empty((3, len(t), 3))
    for i, (x, y, z) in enumerate(offsets):
        pts[i] = HINGE + np.column_stack([c * x - s * y, s * x + c * y, np.full_like(t, z)])
    stamps = START_NS + np.round(t * 1e9).astype(np.int64)
    return stamps, pts, angle


def write_door_recording(
    path: Path, fmt: str = "mcap", angle_rad: float = 1.2, seed: int = 0, *, with_model: bool = True
) -> Path:
    """Write a door-opening demonstration to ``path`` (file, or folder for rosbag2); returns ``path``.

    Without the object model cloud, learning plans no grasp (seconds faster).
    """
    rng = np.random.default_rng(seed)
    stamps, pts, angle = door_positions(angle_rad)
    noisy = pts + rng.normal(0.0, 3e-4, pts.shape)
    leaf = np.column_stack([rng.uniform(0.0, 0.6, 2000), rng.uniform(-0.01, 0.01, 2000), rng.uniform(-0.4, 0.4, 2000)])
    with RecordingWriter(path, fmt) as writer:  # type: ignore[arg-type]
        for i in range(3):
            writer.add_points(f"/mocap/door_{i}", stamps, noisy[i])
        quat = np.column_stack([np.zeros_like(angle), np.zeros_like(angle), np.sin(angle / 2), np.cos(angle / 2)])
        writer.add_poses("/wrist/pose", stamps, pts[0] + np.array([0.0, -0.08, 0.0]), quat)
        if with_model:
            writer.add_cloud("/object/cloud", int(stamps[0]), HINGE + leaf)
        writer.add_string("/demo/meta", int(stamps[0]), json.dumps({"action": "open", "object": "door"}))
    return path
