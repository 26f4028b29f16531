"""Pooled pybullet clients and the visual-less robot change nothing an execution does (real pybullet)."""

from __future__ import annotations

from pathlib import Path

from tasks.scenes.catalog import build_scene
from tasks.scenes.kinematics import truth_descriptor
from tasks.simulate import clients
from tasks.simulate import robot as rb
from tasks.simulate.execute import execute
from tasks.simulate.scenes import scene_setup_for


def test_a_pooled_client_is_handed_out_empty_and_reused() -> None:
    import pybullet as pb

    first = clients.acquire()
    pb.loadURDF(str(rb.robot_urdf(visuals=False)), useFixedBase=True, physicsClientId=first)
    clients.release(first)
    again = clients.acquire()
    try:
        assert again == first
        assert pb.getNumBodies(physicsClientId=again) == 0
    finally:
        clients.release(again)


def test_reused_clients_give_the_same_execution_bit_for_bit() -> None:
    scene = build_scene("sliding-door", 4)
    desc, setup = truth_descriptor(scene), scene_setup_for(scene)
    first = execute(desc, setup)
    second = execute(desc, setup)  # the pool hands the first run's clients out again, reset
    assert first.success
    assert second.trace == first.trace
    assert second.primitives == first.primitives
    assert second.base_position == first.base_position


def test_the_robot_without_visuals_is_the_same_robot(tmp_path: Path) -> None:
    import pybullet as pb

    with_visuals = rb.robot_urdf(tmp_path, visuals=True)
    bare = rb.robot_urdf(tmp_path, visuals=False)
    assert "<visual" in with_visuals.read_text() and "<visual" not in bare.read_text()
    client = pb.connect(pb.DIRECT)
    try:
        a = pb.loadURDF(str(with_visuals), useFixedBase=True, physicsClientId=client)
        b = pb.loadURDF(str(bare), useFixedBase=True, physicsClientId=client)
        n = pb.getNumJoints(a, physicsClientId=client)
        assert n == pb.getNumJoints(b, physicsClientId=client)
        for link in range(-1, n):
            da = pb.getDynamicsInfo(a, link, physicsClientId=client)
            db = pb.getDynamicsInfo(b, link, physicsClientId=client)
            assert da[:3] == db[:3]  # mass, friction, inertia
            ca = pb.getCollisionShapeData(a, link, physicsClientId=client)
            cb = pb.getCollisionShapeData(b, link, physicsClientId=client)
            assert [s[2:] for s in ca] == [s[2:] for s in cb]
    finally:
        pb.disconnect(client)
