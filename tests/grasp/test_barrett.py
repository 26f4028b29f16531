"""The Barrett hand model: eigengrasp mapping and clamping, URDF, and the distal coupling in pybullet."""

from __future__ import annotations

import math

import numpy as np
import pybullet as pb
import pytest

from tasks.hand import barrett


def test_eigengrasp_origin_and_directions() -> None:
    np.testing.assert_allclose(barrett.dofs_from_eigengrasps(0.0, 0.0), [1.13, 0.79, 0.79, 0.79])
    np.testing.assert_allclose(barrett.dofs_from_eigengrasps(1.0, 0.0), [2.13, 0.79, 0.79, 0.79])
    step = 0.5 / math.sqrt(3.0)
    np.testing.assert_allclose(barrett.dofs_from_eigengrasps(0.0, 0.5), [1.13, 0.79 + step, 0.79 + step, 0.79 + step])
    assert barrett.eigengrasps_from_dofs(barrett.dofs_from_eigengrasps(0.3, -0.7)) == pytest.approx((0.3, -0.7))


def test_eigengrasps_are_clamped_to_joint_limits() -> None:
    np.testing.assert_allclose(barrett.dofs_from_eigengrasps(4.0, 4.0), [math.pi, 2.44, 2.44, 2.44])
    np.testing.assert_allclose(barrett.dofs_from_eigengrasps(-4.0, -4.0), [0.0, 0.0, 0.0, 0.0])


def test_non_finite_amplitudes_are_refused() -> None:
    with pytest.raises(ValueError, match="must be finite"):
        barrett.dofs_from_eigengrasps(float("nan"), 0.0)
    with pytest.raises(ValueError, match=r"expected shape \(4,\)"):
        barrett.clamp_dofs([0.0, 1.0])


def test_urdf_is_deterministic(tmp_path: object) -> None:
    assert barrett.barrett_urdf_text() == barrett.barrett_urdf_text()
    path = barrett.barrett_urdf()
    assert path.read_text() == barrett.barrett_urdf_text()
    assert barrett.barrett_urdf() == path


def test_coupling_is_enforced_in_pybullet_and_kinematics_match() -> None:
    client = pb.connect(pb.DIRECT)
    try:
        hand = barrett.load_hand(client)
        dofs = np.array([0.7, 0.3, 1.2, 2.0])
        barrett.apply_dofs(client, hand, dofs)
        prox = [pb.getJointState(hand, j, physicsClientId=client)[0] for j in barrett.PROXIMAL_JOINTS]
        dist = [pb.getJointState(hand, j, physicsClientId=client)[0] for j in barrett.DISTAL_JOINTS]
        np.testing.assert_allclose(prox, dofs[1:])
        np.testing.assert_allclose(dist, dofs[1:] / 3.0 + math.radians(40.0))
        spread = [pb.getJointState(hand, j, physicsClientId=client)[0] for j in barrett.SPREAD_JOINTS]
        np.testing.assert_allclose(spread, [0.7, 0.7])
        # the numpy kinematics used by the planner agree with pybullet's link frames
        tfs = barrett.link_transforms(barrett.joint_positions(dofs))
        for link in range(9):
            state = pb.getLinkState(hand, link, computeForwardKinematics=1, physicsClientId=client)
            np.testing.assert_allclose(state[4], tfs[link + 1][:3, 3], atol=1e-6)
        # driven (dynamic) joints follow the coupling too
        barrett.drive_dofs(client, hand, [0.0, 0.9, 0.9, 0.9])
        pb.createConstraint(hand, -1, -1, -1, pb.JOINT_FIXED, [0, 0, 0], [0, 0, 0], [0, 0, 0], physicsClientId=client)
        for _ in range(240):
            pb.stepSimulation(physicsClientId=client)
        d1 = pb.getJointState(hand, barrett.DISTAL_JOINTS[0], physicsClientId=client)[0]
        assert d1 == pytest.approx(0.9 / 3.0 + math.radians(40.0), abs=0.02)
    finally:
        pb.disconnect(client)


def test_open_hand_is_flat_and_closing_brings_the_fingers_along_the_approach_axis() -> None:
    def tips(a2: float) -> list[np.ndarray]:
        tfs = barrett.link_transforms(barrett.joint_positions(barrett.dofs_from_eigengrasps(-1.13, a2)))
        return [tfs[d + 1] @ np.array([0.0, 0.0, barrett.DISTAL_LENGTH, 1.0]) for _, d in barrett.FINGER_LINKS]

    flat = tips(-4.0)  # proximal joints at 0: fingers stretched out radially, the BH8's flat hand
    assert all(abs(t[1]) > 0.1 for t in flat)
    assert all(0.0 < t[2] < 0.05 for t in flat)  # distal links bent 40° towards the approach side
    half = math.pi / 2 - 0.79  # proximal links along +z (the approach axis)
    upright = tips(half * math.sqrt(3.0))
    assert all(t[2] > 0.08 for t in upright)  # proximal 70 mm up, distal bent 70° inwards
    assert upright[0][1] < 0.05  # finger 1 (at y = +50 mm) bends towards the thumb
    assert upright[2][1] > -0.05  # the thumb (at y = -50 mm) bends towards fingers 1 and 2


def test_batched_kinematics_match_one_hand_at_a_time() -> None:
    amplitudes = np.array([[-1.13, -1.37], [0.0, 0.0], [2.0, 3.0], [-4.0, 4.0]])
    joints = barrett.joints_from_eigengrasps(amplitudes)
    batch = barrett.link_transforms(joints)
    contacts, _ = barrett.VIRTUAL_CONTACTS.in_palm(batch)
    for a, q, tfs, points in zip(amplitudes, joints, batch, contacts, strict=True):
        np.testing.assert_allclose(q, barrett.joint_positions(barrett.dofs_from_eigengrasps(float(a[0]), float(a[1]))))
        np.testing.assert_allclose(tfs, barrett.link_transforms(q), atol=1e-12)
        np.testing.assert_allclose(points, barrett.VIRTUAL_CONTACTS.in_palm(barrett.link_transforms(q))[0], atol=1e-12)
