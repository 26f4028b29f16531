"""Object model from a file (``--object-model model.ply|.pcd|.obj|.stl``), metres, world frame.

open3d is imported here, lazily, and only on this path: ``pbd ingest`` without ``--object-model`` never
loads it. Point clouds (.ply/.pcd) give their points; meshes (.obj/.stl, or a .ply without points) give
their distinct vertices.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import numpy.typing as npt

from tasks.errors import RecordingError

SUFFIXES = (".ply", ".pcd", ".obj", ".stl")


def load_object_model(path: Path) -> tuple[npt.NDArray[np.float32], str]:
    """(n, 3) float32 points of the model file and the file's SHA-256; raises ``RecordingError``."""
    path = Path(path)
    if not path.is_file():
        raise RecordingError(path, "object model file not found")
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        msg = f"unknown object model format {suffix or '(none)'} (expected {', '.join(SUFFIXES)})"
        raise RecordingError(path, msg)
    sha = hashlib.sha256(path.read_bytes()).hexdigest()
    import open3d as o3d  # noqa: PLC0415

    pts = np.zeros((0, 3))
    if suffix in (".ply", ".pcd"):
        pts = np.asarray(o3d.io.read_point_cloud(path).points, dtype=np.float64)
    if len(pts) == 0 and suffix != ".pcd":
        mesh = o3d.io.read_triangle_mesh(path)
        pts = np.unique(np.asarray(mesh.vertices, dtype=np.float64), axis=0)
    pts = pts[np.isfinite(pts).all(axis=1)] if len(pts) else pts
    if len(pts) == 0:
        raise RecordingError(path, "object model file holds no points")
    return pts.astype(np.float32), sha
