"""Built-in scenes (``tasks.scenes``, issue 3) as simulation set-ups."""

from __future__ import annotations

import numpy as np

from tasks.scenes.catalog import draw_scene
from tasks.scenes.scene import Scene
from tasks.simulate.execute import SceneSetup


def scene_setup_for(scene: Scene) -> SceneSetup:
    """The set-up of one scene instance (e.g. the exact seeded instance a recording was synthesised in): its URDF
    at its world placement with its joints at ``joint_start``; the chain may drive the joints of its motions; the
    grasp holds ``grasp_link``."""
    from tasks.scenes.kinematics import load_scene  # noqa: PLC0415 - pybullet at call time

    joints = tuple(dict.fromkeys(m.joint for m in scene.motions))

    def load(client: int) -> int:
        return load_scene(scene, client)

    return SceneSetup(
        name=scene.name, load=load, joints=joints or None, grasp_link=scene.grasp_link, floor_z=scene.floor_z
    )


def scene_setup(name: str, rng: np.random.Generator | None) -> SceneSetup:
    """The set-up of built-in scene ``name`` randomised by ``rng`` (None = nominal; a fresh
    ``np.random.default_rng(seed)`` gives the instance ``build_scene(name, seed)`` does); ``SceneError`` for an
    unknown name."""
    return scene_setup_for(draw_scene(name, rng))
