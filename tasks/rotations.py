"""Rotation matrices and quaternions [x, y, z, w] (scalar last, pybullet's order): thin wrappers over ``scipy``.

A quaternion ``q_a_from_b`` and the matrix ``R_a_from_b`` it gives map a vector's coordinates in frame b to its
coordinates in frame a (``v_a = R_a_from_b @ v_b``); the matrix's columns are b's axes in frame a. Quaternions
are normalised before use, so any non-zero length is accepted. ``q`` and ``-q`` are the same rotation: the
functions returning quaternions give the one with w >= 0 (for w = 0, the first non-zero of x, y, z positive;
``Rotation.as_quat(canonical=True)``), so equal rotations compare equal component-wise.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from scipy.spatial.transform import Rotation

from tasks.arrays import FloatArray

QuatTuple = tuple[float, float, float, float]
"""Quaternion [x, y, z, w] as plain floats (the ``Quat`` of ``schemas.descriptor`` and ``tasks.scenes.scene``)."""

__all__ = ["QuatTuple", "matrix_from_quat", "quat_from_matrix", "quat_tuple_from_matrix"]


def matrix_from_quat(quat_xyzw: npt.ArrayLike) -> FloatArray:
    """(3, 3) float64 rotation matrix R_a_from_b of the (4,) quaternion [x, y, z, w] q_a_from_b (normalised first).

    ``ValueError`` naming ``quat_xyzw`` for another shape or a non-finite value; scipy's for a zero norm.
    """
    q = np.asarray(quat_xyzw, dtype=np.float64)
    if q.shape != (4,):
        msg = f"quat_xyzw: expected shape (4,), got {q.shape}"
        raise ValueError(msg)
    if not np.isfinite(q).all():
        msg = f"quat_xyzw: expected finite values, got {q.tolist()}"
        raise ValueError(msg)
    out: FloatArray = Rotation.from_quat(q).as_matrix()
    return out


def quat_from_matrix(rot: npt.ArrayLike) -> FloatArray:
    """(4,) float64 quaternion [x, y, z, w] q_a_from_b, w >= 0, of the (3, 3) rotation matrix R_a_from_b.

    A matrix that is not quite orthonormal gives the nearest rotation's quaternion; ``ValueError`` naming ``rot``
    for another shape or a non-finite value, scipy's ``ValueError`` for a non-positive determinant.
    """
    m = np.asarray(rot, dtype=np.float64)
    if m.shape != (3, 3):
        msg = f"rot: expected shape (3, 3), got {m.shape}"
        raise ValueError(msg)
    if not np.isfinite(m).all():
        msg = f"rot: expected finite values, got {m.tolist()}"
        raise ValueError(msg)
    # + 0.0 turns scipy's -0.0 components (sign flips of exact zeros) into 0.0, as the hand-written code gave
    out: FloatArray = Rotation.from_matrix(m).as_quat(canonical=True) + 0.0
    return out


def quat_tuple_from_matrix(rot: npt.ArrayLike) -> QuatTuple:
    """``quat_from_matrix`` as a tuple of four plain floats [x, y, z, w], w >= 0 (the descriptor's ``Quat``)."""
    x, y, z, w = quat_from_matrix(rot).tolist()
    return (x, y, z, w)
