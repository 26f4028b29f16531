"""Rotation helpers over numpy arrays: matrices, quaternions ``[x, y, z, w]``, axis-angle, slerp.

Written here so the corpus shares no code with the learner it measures.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]


def unit(v: Array) -> Array:
    """``v`` scaled to unit length along its last axis."""
    v = np.asarray(v, dtype=np.float64)
    out: Array = v / np.linalg.norm(v, axis=-1, keepdims=True)
    return out


def matrix_from_axis_angle(axis: Array, angle_rad: Array | float) -> Array:
    """Rotation matrices (n, 3, 3), or (3, 3) for a scalar angle, about the unit ``axis`` by ``angle_rad``."""
    k = unit(np.asarray(axis, dtype=np.float64))
    theta = np.asarray(angle_rad, dtype=np.float64)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    s = np.sin(theta)[..., None, None]
    c = np.cos(theta)[..., None, None]
    out: Array = np.eye(3) + s * kx + (1.0 - c) * (kx @ kx)
    return out


def matrix_from_rotvec(rotvec: Array) -> Array:
    """Rotation matrices (n, 3, 3) from rotation vectors (n, 3) (axis times angle, rad)."""
    rv = np.asarray(rotvec, dtype=np.float64)
    theta = np.linalg.norm(rv, axis=-1)
    k = rv / np.where(theta > 0, theta, 1.0)[:, None]
    kx = np.zeros((len(rv), 3, 3))
    kx[:, 0, 1], kx[:, 0, 2], kx[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    kx[:, 1, 0], kx[:, 2, 0], kx[:, 2, 1] = k[:, 2], -k[:, 1], k[:, 0]
    s = np.sin(theta)[:, None, None]
    c = np.cos(theta)[:, None, None]
    out: Array = np.eye(3) + s * kx + (1.0 - c) * (kx @ kx)
    return out


def matrix_from_quat(quat_xyzw: Array) -> Array:
    """Rotation matrices (..., 3, 3) from unit quaternions (..., 4) ``[x, y, z, w]``."""
    x, y, z, w = np.moveaxis(unit(quat_xyzw), -1, 0)
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def quat_from_matrix(matrix: Array) -> Array:
    """Unit quaternions (..., 4) ``[x, y, z, w]`` with ``w >= 0`` from rotation matrices (..., 3, 3)."""
    m = np.asarray(matrix, dtype=np.float64)
    t = np.trace(m, axis1=-2, axis2=-1)
    cands = np.stack(
        [
            np.stack(
                [m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1], 1 + t], -1
            ),
            np.stack(
                [
                    1 + 2 * m[..., 0, 0] - t,
                    m[..., 0, 1] + m[..., 1, 0],
                    m[..., 0, 2] + m[..., 2, 0],
                    m[..., 2, 1] - m[..., 1, 2],
                ],
                -1,
            ),
            np.stack(
                [
                    m[..., 0, 1] + m[..., 1, 0],
                    1 + 2 * m[..., 1, 1] - t,
                    m[..., 1, 2] + m[..., 2, 1],
                    m[..., 0, 2] - m[..., 2, 0],
                ],
                -1,
            ),
            np.stack(
                [
                    m[..., 0, 2] + m[..., 2, 0],
                    m[..., 1, 2] + m[..., 2, 1],
                    1 + 2 * m[..., 2, 2] - t,
                    m[..., 1, 0] - m[..., 0, 1],
                ],
                -1,
            ),
        ],
        axis=-2,
    )
    norms = np.linalg.norm(cands, axis=-1)
    best = np.take_along_axis(cands, np.argmax(norms, axis=-1)[..., None, None], axis=-2)[..., 0, :]
    q = unit(best)
    return np.where(q[..., 3:4] < 0, -q, q)


def axis_angle_from_matrix(matrix: Array) -> tuple[Array, Array]:
    """Unit axes (..., 3) and angles (...,) in [0, pi] of rotation matrices (..., 3, 3)."""
    q = quat_from_matrix(matrix)
    s = np.linalg.norm(q[..., :3], axis=-1)
    angle = 2.0 * np.arctan2(s, q[..., 3])
    axis = np.where(s[..., None] > 1e-12, q[..., :3] / np.maximum(s, 1e-300)[..., None], np.array([0.0, 0.0, 1.0]))
    return axis, angle


def slerp(q0: Array, q1: Array, frac: Array) -> Array:
    """Spherical interpolation between unit quaternions (n, 4) ``q0`` and ``q1`` at fractions (n,) in [0, 1]."""
    q0 = unit(q0)
    q1 = unit(q1)
    dot = np.sum(q0 * q1, axis=-1)
    q1 = np.where(dot[:, None] < 0, -q1, q1)
    dot = np.abs(dot)
    omega = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_omega = np.sin(omega)
    small = sin_omega < 1e-9
    f = np.asarray(frac, dtype=np.float64)
    safe = np.where(small, 1.0, sin_omega)
    w0 = np.where(small, 1.0 - f, np.sin((1.0 - f) * omega) / safe)
    w1 = np.where(small, f, np.sin(f * omega) / safe)
    return unit(w0[:, None] * q0 + w1[:, None] * q1)


def random_rotation(rng: np.random.Generator) -> Array:
    """A rotation matrix drawn uniformly from SO(3)."""
    q = unit(rng.normal(size=4))
    return matrix_from_quat(q)


def perpendicular(v: Array, rng: np.random.Generator) -> Array:
    """A random unit vector perpendicular to the unit vector ``v``."""
    r = rng.normal(size=3)
    r -= np.dot(r, v) * v
    return unit(r)
