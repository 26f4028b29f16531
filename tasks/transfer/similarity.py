"""Similarity transforms x' = s R x + t (scale, rotation, translation) between object frames.

``Similarity`` maps points of the source object's frame (metres) into the target object's frame (metres).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from tasks.arrays import FloatArray, Points, Vector3, check_points, check_vector3


@dataclass(frozen=True)
class Similarity:
    """x_target = scale * rotation @ x_source + translation (metres; ``rotation`` is a proper 3x3 rotation)."""

    scale: float
    rotation: FloatArray
    translation: Vector3

    @classmethod
    def identity(cls) -> Similarity:
        """The identity transform."""
        return cls(1.0, np.eye(3), np.zeros(3))

    @classmethod
    def from_matrix(cls, matrix: FloatArray) -> Similarity:
        """From a 4x4 homogeneous matrix whose upper-left block is s R (s > 0); R is re-orthonormalised."""
        m = np.asarray(matrix, dtype=np.float64)
        if m.shape != (4, 4):
            msg = f"matrix: expected shape (4, 4), got {m.shape}"
            raise ValueError(msg)
        if not np.isfinite(m).all():
            msg = "matrix: non-finite entries"
            raise ValueError(msg)
        block = m[:3, :3]
        det = float(np.linalg.det(block))
        if not det > 0.0:
            msg = f"matrix: upper-left block has determinant {det:.3g}, not a similarity"
            raise ValueError(msg)
        scale = det ** (1.0 / 3.0)
        return cls(scale, nearest_rotation(block / scale), m[:3, 3].copy())

    def matrix(self) -> FloatArray:
        """The 4x4 homogeneous matrix [[s R, t], [0, 1]]."""
        m = np.eye(4)
        m[:3, :3] = self.scale * self.rotation
        m[:3, 3] = self.translation
        return m

    def apply_points(self, points: Points) -> Points:
        """Map (n, 3) points (metres, source frame) into the target frame."""
        pts = check_points(points, "points")
        out: Points = self.scale * pts @ self.rotation.T + self.translation
        return out

    def apply_point(self, point: Vector3) -> Vector3:
        """Map one (3,) point (metres, source frame) into the target frame."""
        p = check_vector3(point, "point")
        out: Vector3 = self.scale * self.rotation @ p + self.translation
        return out

    def apply_direction(self, direction: Vector3) -> Vector3:
        """Rotate a (3,) direction into the target frame and renormalise it to unit length."""
        d = check_vector3(direction, "direction")
        out: Vector3 = self.rotation @ d
        norm = float(np.linalg.norm(out))
        if norm == 0.0:
            msg = "direction: zero vector"
            raise ValueError(msg)
        return out / norm

    def compose(self, first: Similarity) -> Similarity:
        """``self ∘ first``: apply ``first``, then ``self``."""
        return Similarity(
            self.scale * first.scale,
            self.rotation @ first.rotation,
            self.scale * self.rotation @ first.translation + self.translation,
        )

    def inverse(self) -> Similarity:
        """The inverse transform (target frame to source frame)."""
        rot_t = self.rotation.T
        return Similarity(1.0 / self.scale, rot_t, -(rot_t @ self.translation) / self.scale)


def rotation_onto(a: Vector3, b: Vector3) -> FloatArray:
    """The smallest rotation (3, 3) taking direction ``a`` onto direction ``b`` (the identity when they are
    parallel)."""
    axis = np.cross(a, b)
    norm = float(np.linalg.norm(axis))
    if norm <= 1e-12:
        return np.eye(3)
    angle = math.atan2(norm, float(np.dot(a, b)))
    out: FloatArray = Rotation.from_rotvec(axis / norm * angle).as_matrix()
    return out


def nearest_rotation(matrix: FloatArray) -> FloatArray:
    """The proper rotation nearest (Frobenius) to a 3x3 matrix, by SVD."""
    u, _, vt = np.linalg.svd(np.asarray(matrix, dtype=np.float64))
    d = np.sign(np.linalg.det(u @ vt)) or 1.0
    out: FloatArray = u @ np.diag([1.0, 1.0, d]) @ vt
    return out


def umeyama(source: Points, target: Points, *, with_scale: bool = True) -> Similarity:
    """Least-squares similarity mapping ``source`` onto ``target`` (corresponding rows; Umeyama 1991)."""
    src = check_points(source, "source")
    dst = check_points(target, "target")
    if src.shape != dst.shape or src.shape[0] < 3:
        msg = f"source/target: need equal shapes with at least 3 rows, got {src.shape} and {dst.shape}"
        raise ValueError(msg)
    mu_s, mu_d = src.mean(axis=0), dst.mean(axis=0)
    xs, xd = src - mu_s, dst - mu_d
    cov = xd.T @ xs / src.shape[0]
    u, sig, vt = np.linalg.svd(cov)
    signs = np.array([1.0, 1.0, np.sign(np.linalg.det(u @ vt)) or 1.0])
    rot = u @ np.diag(signs) @ vt
    var_s = float((xs**2).sum() / src.shape[0])
    scale = float((sig * signs).sum() / var_s) if with_scale else 1.0
    return Similarity(scale, rot, mu_d - scale * rot @ mu_s)


def angle_between_deg(a: Vector3, b: Vector3, *, undirected: bool = False) -> float:
    """Angle between two directions in degrees (``undirected``: the line angle, 0..90)."""
    ua = check_vector3(a, "a") / np.linalg.norm(a)
    ub = check_vector3(b, "b") / np.linalg.norm(b)
    c = float(np.dot(ua, ub))
    if undirected:
        c = abs(c)
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def point_line_distance(point: Vector3, line_point: Vector3, line_dir: Vector3) -> float:
    """Distance (metres) from ``point`` to the line through ``line_point`` along ``line_dir``."""
    d = check_vector3(line_dir, "line_dir") / np.linalg.norm(line_dir)
    v = check_vector3(point, "point") - check_vector3(line_point, "line_point")
    return float(np.linalg.norm(v - np.dot(v, d) * d))
