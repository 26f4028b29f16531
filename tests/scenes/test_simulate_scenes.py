"""The built-in scenes in simulation: their truth descriptors execute with the iiwa and the Barrett hand."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tasks.errors import SceneError
from tasks.scenes.catalog import SCENE_NAMES, build_scene
from tasks.scenes.kinematics import link_frames, scene_client, truth_descriptor
from tasks.scenes.scene import HAND_LINK
from tasks.simulate.api import simulate_descriptor
from tasks.simulate.execute import execute
from tasks.simulate.result import SUCCESS_FRACTION
from tasks.simulate.scenes import scene_instances, scene_setup, scene_setup_for


def test_unknown_scene() -> None:
    with pytest.raises(SceneError, match="unknown scene 'garage': the built-in scenes are"):
        scene_setup("garage", None)


def test_setup_from_a_generator_is_the_seeded_instance() -> None:
    setup = scene_setup("door", np.random.default_rng(7))
    assert setup.joints == ("lever_turn", "door_hinge") and setup.grasp_link == "lever"
    import pybullet as pb

    client = pb.connect(pb.DIRECT)
    try:
        body = setup.load(client)
        pos, _ = pb.getBasePositionAndOrientation(body, physicsClientId=client)
    finally:
        pb.disconnect(client)
    assert np.allclose(pos, build_scene("door", 7).base_position, atol=0.05)


@pytest.mark.parametrize("name", SCENE_NAMES)
def test_truth_descriptor_of_the_nominal_scene_succeeds(name: str) -> None:
    scene = build_scene(name, None)
    result = execute(truth_descriptor(scene), scene_setup_for(scene))
    assert result.success, result.to_dict()
    assert [p.joint for p in result.primitives] == list(dict.fromkeys(m.joint for m in scene.motions))
    for prim, motion in zip(result.primitives, scene.motions, strict=True):
        assert prim.achieved >= SUCCESS_FRACTION * abs(motion.end - motion.start)


@pytest.mark.parametrize(("name", "seed"), [("microwave", 11), ("bottle", 12)])
def test_seeded_instance_through_the_api(name: str, seed: int) -> None:
    """``simulate_descriptor`` with the descriptor's object name and the seed's generator finds the instance."""
    desc = truth_descriptor(build_scene(name, seed))
    result = simulate_descriptor(desc, rng=np.random.default_rng(seed))
    assert result.success, result.to_dict()
    assert result.scene == name


def test_benchmark_instances_and_placed_urdf(tmp_path: Path) -> None:
    """``scene_instances`` cycles the scenes; each placed URDF loaded at the origin is the placed instance."""
    import pybullet as pb

    instances, source = scene_instances(4, np.random.default_rng(0), tmp_path)
    assert [i.scene for i in instances] == list(SCENE_NAMES) and "built-in scenes" in source
    for inst in instances:
        scene = build_scene(inst.scene, inst.seed)
        assert inst.descriptor == truth_descriptor(scene)
        with scene_client(scene) as (client, body):
            links = [m.link for m in scene.markers if m.link != HAND_LINK]
            want = link_frames(client, body, links)
            placed = pb.loadURDF(str(inst.urdf), useFixedBase=True, physicsClientId=client)
            got = link_frames(client, placed, links)
        for link in links:
            np.testing.assert_allclose(got[link][0], want[link][0], atol=1e-6)
