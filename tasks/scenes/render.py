"""A picture of a scene: pybullet's software renderer (ER_TINY_RENDERER, DIRECT mode, no display needed).

The camera looks at the object (the axis-aligned box of ``scene.model_links``) from its front left, above; the
markers are drawn as small coloured spheres (one colour per link, the demonstrator's thumb marker in yellow at
the demonstrated grasp), on a light floor.
"""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

import numpy as np
import pybullet as pb

from tasks.arrays import FloatArray
from tasks.errors import SceneError
from tasks.png import png_bytes
from tasks.scenes.kinematics import link_frames, link_indices, palm_pose_world, rotation_from_quat, scene_client
from tasks.scenes.scene import HAND_LINK, Scene

FOV_DEG = 40.0
VIEW_DIRECTION = (-1.0, -0.75, 0.55)
"""Camera position relative to the object, in the scene's base frame (its front looks towards -x)."""
MARKER_COLOURS: tuple[tuple[float, float, float, float], ...] = (
    (0.10, 0.45, 0.95, 1.0),
    (0.95, 0.25, 0.60, 1.0),
    (0.10, 0.75, 0.75, 1.0),
)
"""Marker colour per link (in order of first appearance); the thumb marker is yellow."""
THUMB_COLOUR = (1.0, 0.85, 0.0, 1.0)


def _model_box(client: int, body: int, scene: Scene) -> tuple[FloatArray, FloatArray]:

    index = link_indices(client, body)
    lows, highs = [], []
    for link in scene.model_links:
        lo, hi = pb.getAABB(body, index[link], physicsClientId=client)
        lows.append(lo)
        highs.append(hi)
    return np.min(lows, axis=0), np.max(highs, axis=0)


def _marker_positions(client: int, body: int, scene: Scene) -> list[tuple[FloatArray, tuple[float, ...]]]:
    links = list(dict.fromkeys(m.link for m in scene.markers if m.link != HAND_LINK))
    frames = link_frames(client, body, links)
    out: list[tuple[FloatArray, tuple[float, ...]]] = []
    for m in scene.markers:
        if m.link == HAND_LINK:
            pos, quat = palm_pose_world(scene)
            colour: tuple[float, ...] = THUMB_COLOUR
        else:
            pos, quat = frames[m.link]
            colour = MARKER_COLOURS[links.index(m.link) % len(MARKER_COLOURS)]
        out.append((pos + rotation_from_quat(quat) @ np.asarray(m.offset), colour))
    return out


def render_rgb(scene: Scene, width: int, height: int) -> np.ndarray:
    """(height, width, 3) uint8 RGB picture of ``scene`` at the demonstration's start."""

    if width < 16 or height < 16:
        msg = f"picture size {width}x{height}: need at least 16x16 pixels"
        raise SceneError(msg)
    with scene_client(scene) as (client, body):
        lo, hi = _model_box(client, body, scene)
        centre, size = (lo + hi) / 2.0, float(np.linalg.norm(hi - lo))
        radius = float(np.clip(0.012 * size, 0.004, 0.015))
        for pos, colour in _marker_positions(client, body, scene):
            shape = pb.createVisualShape(pb.GEOM_SPHERE, radius=radius, rgbaColor=colour, physicsClientId=client)
            pb.createMultiBody(0.0, -1, shape, pos.tolist(), physicsClientId=client)
        floor = pb.createVisualShape(
            pb.GEOM_BOX, halfExtents=[8.0, 8.0, 0.005], rgbaColor=[0.86, 0.86, 0.84, 1.0], physicsClientId=client
        )
        pb.createMultiBody(0.0, -1, floor, [0.0, 0.0, scene.floor_z - 0.006], physicsClientId=client)
        yaw_only = rotation_from_quat(scene.base_orientation)
        view_dir = yaw_only @ np.asarray(VIEW_DIRECTION)
        view_dir /= np.linalg.norm(view_dir)
        aspect = width / height
        half_fov = math.radians(FOV_DEG) / 2.0 * min(1.0, aspect)
        distance = 0.62 * size / math.tan(half_fov)
        eye = centre + distance * view_dir
        view = pb.computeViewMatrix(eye.tolist(), centre.tolist(), [0.0, 0.0, 1.0], physicsClientId=client)
        proj = pb.computeProjectionMatrixFOV(FOV_DEG, aspect, 0.02, 50.0, physicsClientId=client)
        _, _, rgba, _, _ = pb.getCameraImage(
            width,
            height,
            view,
            proj,
            renderer=pb.ER_TINY_RENDERER,
            lightDirection=[-0.4, -0.6, 1.0],
            shadow=0,
            physicsClientId=client,
        )
    return np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[:, :, :3].copy()


def render_scene(scene: Scene, path: Path, width: int = 480, height: int = 360, *, overwrite: bool = False) -> Path:
    """Write a PNG picture of ``scene`` (``width`` x ``height`` pixels) to ``path`` (temp file, then rename);
    ``SceneError`` if ``path`` exists and ``overwrite`` is not given."""
    path = Path(path)
    if path.exists() and not overwrite:
        msg = f"{path}: exists (a picture is not overwritten without overwrite=True)"
        raise SceneError(msg)
    data = png_bytes(render_rgb(scene, width, height))
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".png.tmp")
    with os.fdopen(fd, "wb") as f:
        f.write(data)
    Path(tmp).chmod(0o644)
    Path(tmp).replace(path)
    return path
