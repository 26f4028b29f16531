"""Grasps on the built-in scenes: near the demonstrated palm, executable by the simulated robot; the seed time."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tasks.grasp.api import part_near, plan_on_model
from tasks.grasp.execution import grasp_from_candidate
from tasks.grasp.object_model import build_object_model
from tasks.hand import barrett
from tasks.hand.tracker import stillest_time_ns
from tasks.recording.load import PoseTrack
from tasks.scenes.catalog import build_scene
from tasks.scenes.kinematics import truth_descriptor
from tasks.simulate.api import simulate_descriptor
from tasks.synth.record import OBJECT_MODEL_POINTS
from tasks.synth.scan import scan_object_model


@pytest.mark.slow
@pytest.mark.parametrize("name", ["bottle", "sliding-door", "microwave"])
def test_scene_grasp_is_near_the_demonstration_and_executes(name: str) -> None:
    seed = {"bottle": 3, "sliding-door": 1, "microwave": 1}[name]
    scene = build_scene(name, seed)
    truth = truth_descriptor(scene)
    assert truth.grasp is not None
    demo_pos = np.array(truth.grasp.wrist_position)
    demo_quat = np.array(truth.grasp.wrist_orientation)
    points = scan_object_model(scene, OBJECT_MODEL_POINTS, np.random.default_rng(seed))
    model = build_object_model(part_near(points, demo_pos), np.random.default_rng(0), viewpoint=demo_pos)
    grasp = grasp_from_candidate(plan_on_model(model, demo_pos, demo_quat, np.random.default_rng(0)))
    offset_m = float(np.linalg.norm(np.array(grasp.wrist_position) - demo_pos))
    turn = Rotation.from_quat(demo_quat).inv() * Rotation.from_quat(grasp.wrist_orientation)
    assert offset_m <= 0.05  # within the search space's lateral range of the demonstrated palm
    assert turn.magnitude() <= math.radians(30.0) + 1e-9
    assert grasp.eigengrasps[1] == pytest.approx(barrett.CLOSE_AMPLITUDE)  # closes towards the full fist
    if name == "bottle":  # the cap: force closure (the handles' sparse models often have none there: README)
        assert grasp.quality["force_closure"] is True
        assert grasp.quality["epsilon"] > 0.0
    result = simulate_descriptor(dataclasses.replace(truth, grasp=grasp), scene=name, rng=np.random.default_rng(seed))
    assert result.grasped
    assert result.success


def test_seed_is_the_stillest_wrist_pose_before_the_primitive() -> None:
    # the hand rests from 0.5 s to 1.5 s, then turns about z at 1 rad/s; the primitive is detected late at 2.0 s
    stamps = (np.arange(0, 251) * 10_000_000).astype(np.int64)
    t = stamps * 1e-9
    positions = np.column_stack([np.clip(0.5 - t, 0.0, None) * 0.2, np.zeros_like(t), np.full_like(t, 1.0)])
    quats = Rotation.from_euler("z", np.clip(t - 1.5, 0.0, None)[:, None]).as_quat()
    track = PoseTrack("/wrist", "wrist", stamps, positions, quats)
    chosen = stillest_time_ns(track, 2_000_000_000) * 1e-9
    assert 0.95 <= chosen <= 1.45
