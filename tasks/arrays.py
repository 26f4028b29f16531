"""Array type aliases used across the stages (defined once, see STYLE.md)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
"""Any float64 array."""
Points = npt.NDArray[np.float64]
"""(n, 3) float64 positions, metres."""
Vector3 = npt.NDArray[np.float64]
"""(3,) float64 vector (a direction is unit length)."""
Quats = npt.NDArray[np.float64]
"""(n, 4) float64 quaternions [x, y, z, w]."""
StampsNs = npt.NDArray[np.int64]
"""(n,) int64 time stamps, nanoseconds."""
Labels = npt.NDArray[np.int64]
"""(n,) int64 segment labels."""
BoolArray = npt.NDArray[np.bool_]
"""Boolean mask."""
IntArray = npt.NDArray[np.int64]
"""(n,) int64 indices."""


def check_points(values: object, name: str) -> Points:
    """Convert ``values`` to an (n, 3) float64 array or raise ``ValueError`` naming ``name`` and the shape."""
    arr = np.asarray(values, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        msg = f"{name}: expected shape (n, 3), got {arr.shape}"
        raise ValueError(msg)
    return arr


def check_vector3(values: object, name: str) -> Vector3:
    """Convert ``values`` to a (3,) float64 array or raise ``ValueError`` naming ``name`` and the shape."""
    arr = np.asarray(values, dtype=np.float64)
    if arr.shape != (3,):
        msg = f"{name}: expected shape (3,), got {arr.shape}"
        raise ValueError(msg)
    return arr
