"""Forward kinematics and the true chain of a scene, on the simulate stage's procedural lever door."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tasks.errors import SceneError
from tasks.scenes.kinematics import (
    joint_values_at_motion,
    link_frames,
    min_jerk,
    moving_links,
    scene_client,
    set_joints,
    truth_chain,
    truth_descriptor,
)
from tasks.scenes.scene import Marker, Motion, Scene
from tests.simulate.objects import LeverDoorSpec


def lever_door(yaw_rad: float = 0.0, lever_end: float = 0.5, door_end: float = 1.0) -> Scene:
    """The lever door rotated by ``yaw_rad`` about world z, lever pressed to ``lever_end``, door to ``door_end``."""
    spec = LeverDoorSpec(hinge_x=0.0, hinge_y=0.0, hinge_z=0.0)
    quat = (0.0, 0.0, math.sin(yaw_rad / 2), math.cos(yaw_rad / 2))
    return Scene(
        name="lever-door-test",
        seed=None,
        object_name="door",
        action="open",
        urdf=spec.urdf(),
        base_position=(1.0, 2.0, 0.5),
        base_orientation=quat,
        motions=(Motion("lever_turn", 0.0, lever_end), Motion("hinge", 0.0, door_end)),
        grasp_link="lever",
        palm_position=(-0.11, -0.07, 0.0),
        palm_orientation=(0.5, 0.5, 0.5, 0.5),
        grasp_eigengrasps=(0.0, 1.0),
        markers=(
            Marker("lever_a", "lever", (-0.07, -0.1, 0.0)),
            Marker("lever_b", "lever", (-0.07, -0.02, 0.01)),
            Marker("leaf_a", "door", (-0.02, 0.3, 0.3)),
            Marker("leaf_b", "door", (-0.02, 0.5, -0.2)),
        ),
        model_links=("door", "lever"),
    )


def test_min_jerk_ends_and_midpoint() -> None:
    s = min_jerk(np.array([-1.0, 0.0, 0.5, 1.0, 2.0]))
    np.testing.assert_allclose(s, [0.0, 0.0, 0.5, 1.0, 1.0])


@pytest.mark.parametrize("yaw_deg", [0.0, 73.0, -150.0])
def test_truth_chain_axes_follow_the_placement(yaw_deg: float) -> None:
    yaw = math.radians(yaw_deg)
    chain = truth_chain(lever_door(yaw))
    assert [p.kind for p in chain] == ["rotation", "rotation"]
    lever, door = chain
    np.testing.assert_allclose(lever.dir, [math.cos(yaw), math.sin(yaw), 0.0], atol=1e-6)
    np.testing.assert_allclose(door.dir, [0.0, 0.0, 1.0], atol=1e-6)
    assert lever.extent == pytest.approx(0.5)
    assert door.extent == pytest.approx(1.0)
    assert door.pos is not None
    np.testing.assert_allclose(door.pos[:2], [1.0, 2.0], atol=1e-6)  # the hinge line through the base
    assert door.markers == ("/mocap/lever_a", "/mocap/lever_b", "/mocap/leaf_a", "/mocap/leaf_b")
    assert lever.markers == ("/mocap/lever_a", "/mocap/lever_b")


def test_negative_motion_flips_the_direction() -> None:
    chain = truth_chain(lever_door(door_end=-0.0))
    assert chain[1].extent == pytest.approx(0.0)
    scene = lever_door()
    flipped = Scene(**{**scene.__dict__, "motions": (Motion("hinge", 1.2, 0.2),)})
    (door,) = truth_chain(flipped)
    np.testing.assert_allclose(door.dir, [0.0, 0.0, -1.0], atol=1e-6)
    assert door.extent == pytest.approx(1.0)


def test_rotation_pos_is_the_foot_of_the_marker_centroid() -> None:
    scene = lever_door()
    _, door = truth_chain(scene)
    assert door.pos is not None
    # leaf markers at z = +0.3 and -0.2 in the door frame; the lever markers' z after the lever turned 0.5 rad
    lever_z = [-0.1 * math.sin(0.5), -0.02 * math.sin(0.5) + 0.01 * math.cos(0.5)]
    assert door.pos[2] == pytest.approx(0.5 + (0.3 - 0.2 + sum(lever_z)) / 4, abs=1e-6)


def test_link_frames_move_with_the_joints() -> None:
    scene = lever_door()
    with scene_client(scene) as (client, body):
        before = link_frames(client, body, ["door", "frame"])
        set_joints(client, body, joint_values_at_motion(scene, 1, 1.0))
        after = link_frames(client, body, ["door", "frame"])
        assert moving_links(client, body, "hinge") == {"door", "lever"}
        with pytest.raises(SceneError, match="link 'nope' is not in the scene"):
            link_frames(client, body, ["nope"])
        with pytest.raises(SceneError, match="joint 'nope' is not in the scene"):
            set_joints(client, body, {"nope": 0.0})
    np.testing.assert_allclose(before["frame"][0], after["frame"][0])
    np.testing.assert_allclose(before["door"][0], after["door"][0], atol=1e-6)  # the door frame sits on the hinge
    assert not np.allclose(before["door"][1], after["door"][1])


def test_truth_descriptor_grasp_is_the_palm_in_the_world() -> None:
    desc = truth_descriptor(lever_door())
    assert desc.grasp is not None
    assert desc.name == "open-door"
    # lever frame at base + (-0.02, 0.75, 0); the palm 0.11 m further along -x and 0.07 m along -y
    np.testing.assert_allclose(desc.grasp.wrist_position, [1.0 - 0.13, 2.0 + 0.68, 0.5], atol=1e-6)


def test_unknown_motion_joint() -> None:
    scene = lever_door()
    bad = Scene(**{**scene.__dict__, "motions": (Motion("nope", 0.0, 1.0),)})
    with pytest.raises(SceneError, match="motion joint 'nope' is not in its URDF"):
        truth_chain(bad)
