"""The built-in scenes: they build (nominal and seeded), load in pybullet, move within their joint limits, and the
markers move with their parts."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pybullet as pb
import pytest

from tasks.errors import SceneError
from tasks.scenes.catalog import SCENE_NAMES, build_scene, draw_scene
from tasks.scenes.kinematics import (
    joint_indices,
    joint_values_at_motion,
    link_frames,
    link_indices,
    moving_links,
    rotation_from_quat,
    scene_client,
    set_joints,
)
from tasks.scenes.scene import HAND_LINK, Scene

SEEDS: list[int | None] = [None, *range(10)]


def marker_positions(client: int, body: int, scene: Scene) -> dict[str, np.ndarray]:
    """World positions of the object markers (not the hand's) at the body's current joints."""
    on_object = [m for m in scene.markers if m.link != HAND_LINK]
    frames = link_frames(client, body, {m.link for m in on_object})
    return {m.name: frames[m.link][0] + rotation_from_quat(frames[m.link][1]) @ np.asarray(m.offset) for m in on_object}


def test_unknown_scene_names_the_valid_ones() -> None:
    with pytest.raises(
        SceneError, match=r"unknown scene 'oven': the built-in scenes are microwave, sliding-door, door"
    ):
        build_scene("oven", None)
    with pytest.raises(SceneError, match="unknown scene 'kettle'"):
        draw_scene("kettle", np.random.default_rng(0))


@pytest.mark.parametrize("name", SCENE_NAMES)
def test_same_seed_same_scene_and_draw_matches_build(name: str) -> None:
    assert build_scene(name, 3) == build_scene(name, 3)
    assert draw_scene(name, np.random.default_rng(3), 3) == build_scene(name, 3)
    assert build_scene(name, 3) != build_scene(name, 4)
    nominal = build_scene(name, None)
    assert nominal.seed is None and nominal.name == name == nominal.object_name
    assert nominal.base_position == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("name", SCENE_NAMES)
def test_seeds_vary_placement_and_extent(name: str) -> None:
    scenes = [build_scene(name, s) for s in range(10)]
    yaws = {round(math.degrees(2 * math.atan2(s.base_orientation[2], s.base_orientation[3]))) % 360 for s in scenes}
    assert len(yaws) == 10
    assert len({s.motions[-1].end for s in scenes}) == 10
    assert len({s.urdf for s in scenes}) == 10


@pytest.mark.parametrize(("name", "seed"), list(itertools.product(SCENE_NAMES, SEEDS)))
def test_scene_loads_and_moves_within_limits(name: str, seed: int | None) -> None:
    scene = build_scene(name, seed)
    per_link: dict[str, list[np.ndarray]] = {}
    with scene_client(scene) as (client, body):
        index = joint_indices(client, body)
        for m in scene.markers:
            if m.link != HAND_LINK:
                per_link.setdefault(m.link, []).append(np.asarray(m.offset))
        for k, motion in enumerate(scene.motions):
            info = pb.getJointInfo(body, index[motion.joint], physicsClientId=client)
            lower, upper = info[8], info[9]
            if upper >= lower:  # continuous joints have no limits (pybullet: lower 0, upper -1)
                assert lower <= min(motion.start, motion.end) and max(motion.start, motion.end) <= upper
            assert motion.end != motion.start
            set_joints(client, body, joint_values_at_motion(scene, k, 0.0))
            before = marker_positions(client, body, scene)
            set_joints(client, body, joint_values_at_motion(scene, k, 1.0))
            after = marker_positions(client, body, scene)
            moved = moving_links(client, body, motion.joint)
            state = pb.getLinkState(body, index[motion.joint], computeForwardKinematics=True, physicsClientId=client)
            axis = rotation_from_quat(state[5]) @ np.asarray(info[13])
            delta = motion.end - motion.start
            for marker in scene.markers:
                if marker.link == HAND_LINK:
                    continue
                shift = after[marker.name] - before[marker.name]
                if marker.link not in moved:
                    assert np.linalg.norm(shift) < 1e-6
                elif info[2] == pb.JOINT_PRISMATIC:
                    np.testing.assert_allclose(shift, delta * axis, atol=1e-6)
                else:  # the marker turns by delta about the joint axis through the joint origin
                    origin = np.asarray(state[4])
                    a = before[marker.name] - origin
                    b = after[marker.name] - origin
                    a -= (a @ axis) * axis
                    b -= (b @ axis) * axis
                    angle = math.atan2(float(np.cross(a, b) @ axis), float(a @ b))
                    assert angle == pytest.approx(math.remainder(delta, 2 * math.pi), abs=1e-5)
    assert scene.grasp_link in {link for motion in scene.motions for link in moved} or scene.grasp_link in per_link
    for offsets in per_link.values():
        assert 3 <= len(offsets) <= 5
        centred = np.array(offsets) - np.mean(offsets, axis=0)
        assert np.linalg.svd(centred, compute_uv=False)[1] > 1e-3  # not collinear


def test_sliding_door_has_a_thumb_marker_and_the_door_two_parts() -> None:
    sliding = build_scene("sliding-door", None)
    assert [m.name for m in sliding.markers if m.link == HAND_LINK] == ["thumb"]
    assert len([m for m in sliding.markers if m.link == "panel"]) == 4
    door = build_scene("door", None)
    assert [m.joint for m in door.motions] == ["lever_turn", "door_hinge"]
    assert {m.link for m in door.markers} == {"lever", "leaf"}
    bottle = build_scene("bottle", 5)
    assert 1.5 <= bottle.motions[0].end <= 4.0


@pytest.mark.parametrize("name", SCENE_NAMES)
def test_palm_sits_at_the_grasp_link(name: str) -> None:
    """The demonstrated palm pose is a few centimetres from the grasped part, not inside it."""
    from tasks.scenes.kinematics import palm_pose_world

    scene = build_scene(name, 2)
    palm, _ = palm_pose_world(scene)
    with scene_client(scene) as (client, body):
        index = link_indices(client, body)
        probe = pb.createCollisionShape(pb.GEOM_SPHERE, radius=0.001, physicsClientId=client)
        ball = pb.createMultiBody(0.0, probe, -1, palm.tolist(), physicsClientId=client)
        pts = pb.getClosestPoints(ball, body, 0.5, linkIndexB=index[scene.grasp_link], physicsClientId=client)
        gap = min(p[8] for p in pts)
    assert 0.02 < gap < 0.09
