"""Simulate a task descriptor on a built-in scene or a user's URDF (issue 7): ``simulate_descriptor``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pybullet as pb

from schemas.descriptor import Descriptor
from tasks.errors import SceneError, SimulationError
from tasks.simulate.execute import GraspMode, SceneSetup, execute
from tasks.simulate.result import SimulationResult
from tasks.simulate.scenes import scene_setup


def urdf_setup(urdf: Path, joints: list[str] | None) -> SceneSetup:
    """A scene from a user's URDF, fixed base at the world origin; ``joints`` the chain may drive (None = all)."""
    if not urdf.is_file():
        msg = f"{urdf}: URDF file not found"
        raise SceneError(msg)
    path = urdf.resolve()

    def load(client: int) -> int:
        try:
            return int(pb.loadURDF(str(path), useFixedBase=True, physicsClientId=client))
        except pb.error as err:
            msg = f"{urdf}: pybullet cannot load this URDF ({err})"
            raise SceneError(msg) from err

    return SceneSetup(name=urdf.stem, load=load, joints=tuple(joints) if joints else None)


def builtin_setup(name: str, rng: np.random.Generator | None) -> SceneSetup:
    """A built-in scene (``tasks.scenes``) instance, randomised by ``rng`` (None = the nominal instance)."""

    return scene_setup(name, rng)


def simulate_descriptor(
    desc: Descriptor,
    *,
    scene: str | None = None,
    urdf: Path | None = None,
    joints: list[str] | None = None,
    rng: np.random.Generator | None = None,
    frames_dir: Path | None = None,
    grasp_mode: GraspMode = "constraint",
) -> SimulationResult:
    """Execute ``desc`` on a built-in ``scene`` or on ``urdf`` (with the ``joints`` it may drive) and judge it.

    With neither, the scene is the descriptor's object name when that is a built-in scene. ``rng`` picks the
    randomised instance of a built-in scene (use the seed the demonstration was synthesised with). Key frames
    go to ``frames_dir`` as PNGs. ``DescriptorError`` for a descriptor beyond the limits of a mechanism (an extent
    of more than a few turns or metres, an axis that is not a unit vector), ``SceneError`` for an unknown scene or
    unreadable URDF, ``SimulationError`` when the descriptor does not fit the scene.
    """
    desc.to_dict()  # the schema and its limits (schemas.limits), for a descriptor built in memory too
    if scene is not None and urdf is not None:
        msg = "give a built-in scene or a URDF, not both"
        raise SimulationError(msg)
    if joints and urdf is None:
        msg = "joints can only be named for a URDF scene (--urdf)"
        raise SimulationError(msg)
    if urdf is not None:
        setup = urdf_setup(urdf, joints)
    else:
        setup = builtin_setup(scene if scene is not None else desc.object.name, rng)
    return execute(desc, setup, grasp_mode=grasp_mode, frames_dir=frames_dir)
