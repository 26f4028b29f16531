"""Convex-hull collision meshes for the iiwa: the same collision geometry as its STL meshes, far fewer vertices.

pybullet collides a URDF's mesh as the convex hull of all its vertices; the iiwa's STL files hold 3500-9000
vertices per link, of which 190-580 are on the hull. Writing just the hull (an OBJ) gives identical closest points
and contacts and halves the robot's loading time (the hull is no longer recomputed from every vertex).
"""

from __future__ import annotations

import hashlib
import re
import struct
import tempfile
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull

from tasks.arrays import FloatArray

_STL_RECORD = np.dtype([("normal", "<f4", 3), ("vertices", "<f4", (3, 3)), ("attribute", "<u2")])


def stl_vertices(data: bytes) -> FloatArray:
    """(3n, 3) triangle corner positions of a binary STL file's bytes (file units)."""
    count = struct.unpack("<I", data[80:84])[0]
    records = np.frombuffer(data[84 : 84 + count * _STL_RECORD.itemsize], dtype=_STL_RECORD)
    return records["vertices"].reshape(-1, 3).astype(np.float64)


def hull_obj_text(points: FloatArray) -> str:
    """Wavefront OBJ text of the convex hull of ``points`` (n, 3): its vertices and triangles."""

    hull = ConvexHull(points)
    index = {int(v): i + 1 for i, v in enumerate(hull.vertices)}
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in points[hull.vertices]]
    lines += [f"f {index[int(a)]} {index[int(b)]} {index[int(c)]}" for a, b, c in hull.simplices]
    return "\n".join(lines) + "\n"


def hull_mesh(stl: Path, folder: Path) -> Path:
    """The convex hull of binary STL file ``stl`` as an OBJ in ``folder`` (content-addressed, written once)."""
    data = stl.read_bytes()
    digest = hashlib.sha256(data).hexdigest()[:12]
    path = folder / f"{stl.stem}-hull-{digest}.obj"
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile("w", dir=path.parent, delete=False, suffix=".tmp") as tmp:
            tmp.write(hull_obj_text(stl_vertices(data)))
        Path(tmp.name).replace(path)
    return path


def with_hull_collisions(urdf_text: str, folder: Path) -> str:
    """``urdf_text`` with every ``<collision>`` STL mesh (absolute path) replaced by its hull OBJ in ``folder``."""

    def collision(match: re.Match[str]) -> str:
        return re.sub(
            r'filename="([^"]+\.stl)"',
            lambda m: f'filename="{hull_mesh(Path(m.group(1)), folder)}"',
            match.group(0),
        )

    return re.sub(r"<collision>.*?</collision>", collision, urdf_text, flags=re.DOTALL)
