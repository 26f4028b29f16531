"""Built-in scenes (``tasks.scenes``, issue 3) as simulation set-ups."""

from __future__ import annotations

import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pybullet as pb

from schemas.descriptor import Descriptor
from tasks.scenes.catalog import SCENE_NAMES, build_scene, draw_scene
from tasks.scenes.kinematics import load_scene, truth_descriptor
from tasks.scenes.scene import Scene
from tasks.simulate.execute import SceneSetup


def scene_setup_for(scene: Scene) -> SceneSetup:
    """The set-up of one scene instance (e.g. the exact seeded instance a recording was synthesised in): its URDF
    at its world placement with its joints at ``joint_start``; the chain may drive the joints of its motions; the
    grasp holds ``grasp_link``."""

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


@dataclass(frozen=True)
class SceneInstance:
    """A seeded built-in scene instance for the simulation benchmark (``bench/simulate.py``): its ``scene`` name,
    simulation ``setup``, truth ``descriptor``, and ``urdf``: a file whose fixed base loaded at the world origin
    *is* the placed instance (a root link ``world`` holds the scene's base at its placement)."""

    scene: str
    setup: SceneSetup
    descriptor: Descriptor
    urdf: Path
    seed: int


def placed_urdf_text(scene: Scene) -> str:
    """The scene's URDF with a root link ``world`` fixed to its base at ``base_position``/``base_orientation``, so
    that loading it at the origin (fixed base) places it."""

    root = ET.fromstring(scene.urdf)
    children = {child.get("link") for child in root.iter("child")}
    base = next(link.get("name") for link in root.iter("link") if link.get("name") not in children)
    roll, pitch, yaw = pb.getEulerFromQuaternion(scene.base_orientation)
    x, y, z = scene.base_position
    world = ET.Element("link", name="world")
    joint = ET.Element("joint", name="world_to_base", type="fixed")
    ET.SubElement(joint, "parent", link="world")
    ET.SubElement(joint, "child", link=str(base))
    ET.SubElement(joint, "origin", xyz=f"{x} {y} {z}", rpy=f"{roll} {pitch} {yaw}")
    root.insert(0, world)
    root.append(joint)
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def scene_instances(n: int, rng: np.random.Generator, folder: Path | None = None) -> tuple[list[SceneInstance], str]:
    """``n`` randomised instances cycling through the four scenes (seeds drawn from ``rng``) with their truth
    descriptors; placed URDFs go to ``folder`` (default: a temporary folder). Returns them and a description."""

    out_dir = folder if folder is not None else Path(tempfile.mkdtemp(prefix="pbd-scenes-"))
    out_dir.mkdir(parents=True, exist_ok=True)
    instances = []
    for i in range(n):
        name = SCENE_NAMES[i % len(SCENE_NAMES)]
        seed = int(rng.integers(0, 2**31 - 1))
        scene = build_scene(name, seed)
        path = out_dir / f"{i:03d}-{name}-{seed}.urdf"
        path.write_text(placed_urdf_text(scene))
        instances.append(SceneInstance(name, scene_setup_for(scene), truth_descriptor(scene), path, seed))
    source = "the built-in scenes (tasks.scenes: microwave, sliding-door, door, bottle), seeded instances"
    return instances, source
