"""Key frames of an execution, rendered with pybullet's software renderer (ER_TINY_RENDERER) into PNG files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt
import pybullet as pb

from tasks.png import png_bytes

FRAME_SIZE = (480, 360)
"""Width, height of a key frame, pixels."""


def render_rgb(client: int, eye: npt.ArrayLike, target: npt.ArrayLike) -> npt.NDArray[np.uint8]:
    """(h, w, 3) RGB image of the scene seen from ``eye`` towards ``target`` (world, metres), z up."""

    width, height = FRAME_SIZE
    view = pb.computeViewMatrix(
        [float(v) for v in np.asarray(eye, dtype=np.float64)],
        [float(v) for v in np.asarray(target, dtype=np.float64)],
        [0.0, 0.0, 1.0],
        physicsClientId=client,
    )
    proj = pb.computeProjectionMatrixFOV(55.0, width / height, 0.05, 10.0, physicsClientId=client)
    _, _, rgba, _, _ = pb.getCameraImage(
        width, height, view, proj, renderer=pb.ER_TINY_RENDERER, physicsClientId=client
    )
    arr = np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)
    return arr[:, :, :3].copy()


def save_frame(client: int, path: Path, eye: npt.ArrayLike, target: npt.ArrayLike) -> Path:
    """Render a key frame and write it as a PNG at ``path`` (parents created); returns the path."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(png_bytes(render_rgb(client, eye, target)))
    return path
