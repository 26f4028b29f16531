"""The object model of a scene: points on the surfaces of its parts, as a 3-D digitizer scan would give them.

Points are drawn from the collision shapes (boxes, cylinders, spheres) of ``scene.model_links``, area-weighted,
in the world frame at the demonstration's start (the first motion's start joint values). The functional parts
(door and handle, lever, cap) are links of ``model_links``, so they are in the model.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from tasks.arrays import FloatArray, Points
from tasks.errors import SceneError
from tasks.scenes.kinematics import (
    joint_values_at_motion,
    link_frames,
    rotation_from_quat,
    scene_client,
    set_joints,
)
from tasks.scenes.scene import Scene


@dataclass(frozen=True)
class WorldShape:
    """A collision shape placed in the world: ``kind`` box (``size`` = edge lengths) / cylinder (radius, length,
    along its local z) / sphere (radius); ``rotation`` (3, 3) and ``translation`` (3,) world-from-shape, metres;
    ``link`` the URDF link it belongs to."""

    link: str
    kind: str
    size: tuple[float, ...]
    rotation: FloatArray
    translation: FloatArray

    @property
    def area(self) -> float:
        """Surface area, square metres."""
        if self.kind == "box":
            x, y, z = self.size
            return 2.0 * (x * y + y * z + x * z)
        if self.kind == "cylinder":
            r, length = self.size
            return 2.0 * math.pi * r * (r + length)
        return 4.0 * math.pi * self.size[0] ** 2


def _rpy_matrix(rpy: tuple[float, float, float]) -> FloatArray:
    """URDF roll-pitch-yaw (fixed axes x, y, z) as a 3x3 matrix Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    out: FloatArray = rz @ ry @ rx
    return out


def _floats(text: str | None, count: int, default: float = 0.0) -> tuple[float, ...]:
    if text is None:
        return (default,) * count
    values = tuple(float(v) for v in text.split())
    if len(values) != count:
        msg = f"URDF attribute {text!r}: expected {count} numbers"
        raise SceneError(msg)
    return values


def _link_collisions(urdf: str, link: str) -> list[tuple[str, tuple[float, ...], FloatArray, FloatArray]]:
    """(kind, size, rotation, translation) of each collision element of ``link``, in the link frame."""
    root = ET.fromstring(urdf)
    for element in root.iter("link"):
        if element.get("name") != link:
            continue
        out = []
        for collision in element.iter("collision"):
            origin = collision.find("origin")
            xyz = _floats(origin.get("xyz") if origin is not None else None, 3)
            rpy = _floats(origin.get("rpy") if origin is not None else None, 3)
            geometry = collision.find("geometry")
            shape = next(iter(geometry)) if geometry is not None and len(geometry) else None
            if shape is None or shape.tag not in ("box", "cylinder", "sphere"):
                msg = f"link {link!r}: only box, cylinder and sphere collision shapes can be sampled"
                raise SceneError(msg)
            if shape.tag == "box":
                size = _floats(shape.get("size"), 3)
            elif shape.tag == "cylinder":
                size = (float(shape.get("radius", "0")), float(shape.get("length", "0")))
            else:
                size = (float(shape.get("radius", "0")),)
            out.append((shape.tag, size, _rpy_matrix((rpy[0], rpy[1], rpy[2])), np.array(xyz, dtype=np.float64)))
        return out
    msg = f"scene URDF has no link {link!r}"
    raise SceneError(msg)


def model_shapes(scene: Scene) -> list[WorldShape]:
    """The collision shapes of ``scene.model_links`` placed in the world at the demonstration's start."""

    with scene_client(scene) as (client, body):
        if scene.motions:
            set_joints(client, body, joint_values_at_motion(scene, 0, 0.0))
        frames = link_frames(client, body, scene.model_links)
    shapes: list[WorldShape] = []
    for link in scene.model_links:
        pos, quat = frames[link]
        rot = rotation_from_quat(quat)
        for kind, size, r_local, t_local in _link_collisions(scene.urdf, link):
            shapes.append(WorldShape(link, kind, size, rot @ r_local, pos + rot @ t_local))
    return shapes


def _sample_box(size: tuple[float, ...], n: int, rng: np.random.Generator) -> Points:
    half = np.asarray(size, dtype=np.float64) / 2.0
    face_areas = np.array([size[1] * size[2], size[0] * size[2], size[0] * size[1]])
    axis = rng.choice(3, size=n, p=face_areas / face_areas.sum())
    pts = rng.uniform(-half, half, size=(n, 3))
    sign = rng.choice([-1.0, 1.0], size=n)
    pts[np.arange(n), axis] = sign * half[axis]
    return pts


def _sample_cylinder(size: tuple[float, ...], n: int, rng: np.random.Generator) -> Points:
    r, length = size
    side = 2.0 * math.pi * r * length
    caps = 2.0 * math.pi * r * r
    on_side = rng.random(n) < side / (side + caps)
    theta = rng.uniform(0.0, 2.0 * math.pi, n)
    rad = np.where(on_side, r, r * np.sqrt(rng.random(n)))
    z = np.where(on_side, rng.uniform(-length / 2, length / 2, n), rng.choice([-length / 2, length / 2], size=n))
    return np.column_stack([rad * np.cos(theta), rad * np.sin(theta), z])


def _sample_sphere(size: tuple[float, ...], n: int, rng: np.random.Generator) -> Points:
    v = rng.normal(size=(n, 3))
    out: Points = size[0] * v / np.linalg.norm(v, axis=1, keepdims=True)
    return out


def sample_object_model(scene: Scene, n_points: int, rng: np.random.Generator) -> Points:
    """(n_points, 3) float64 points, metres, world frame at the demonstration's start, drawn area-weighted from the
    surfaces of the collision shapes of ``scene.model_links``."""
    if n_points < 1:
        msg = f"n_points: need at least 1 point, got {n_points}"
        raise SceneError(msg)
    shapes = model_shapes(scene)
    if not shapes:
        msg = f"scene {scene.name!r}: its model links {scene.model_links} have no collision shapes"
        raise SceneError(msg)
    return sample_shapes(shapes, n_points, rng)


def sample_shapes(shapes: list[WorldShape], n_points: int, rng: np.random.Generator) -> Points:
    """(n_points, 3) float64 points, metres, world frame, drawn area-weighted from the surfaces of ``shapes``."""
    areas = np.array([s.area for s in shapes])
    counts = rng.multinomial(n_points, areas / areas.sum())
    samplers = {"box": _sample_box, "cylinder": _sample_cylinder, "sphere": _sample_sphere}
    parts = []
    for shape, count in zip(shapes, counts, strict=True):
        if count:
            local = samplers[shape.kind](shape.size, int(count), rng)
            parts.append(local @ shape.rotation.T + shape.translation)
    points: Points = np.concatenate(parts).astype(np.float64)
    return points
