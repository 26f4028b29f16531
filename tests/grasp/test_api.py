"""The grasp API: seeds from a wrist track through the tracker's offset from the palm, part cropping, and its errors."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tasks.arrays import Points
from tasks.errors import GraspError
from tasks.grasp.api import part_near, plan_grasp, plan_grasp_for_recording
from tasks.hand.tracker import (
    GRASPIT_TRACKER_OFFSET,
    PalmOffset,
    palm_from_sensor,
    sensor_from_palm,
    wrist_pose_at,
)
from tasks.recording.load import PoseTrack
from tasks.store import Store
from tests.grasp.surface_sampling import sample_cylinder_surface

from .conftest import HANDLE_CENTER, PALM_DOWN


def _track(palm_pos: np.ndarray, palm_quat: np.ndarray) -> PoseTrack:
    """A 1 s wrist tracker track (60 Hz) that ends at the sensor pose whose palm is the given pose."""
    off = GRASPIT_TRACKER_OFFSET
    sensor_rot = Rotation.from_quat(palm_quat) * off.rotation().inv()
    sensor_pos = palm_pos - sensor_rot.apply(off.translation_m)
    n = 61
    stamps = (10**9 + np.arange(n) * (10**9 // 60)).astype(np.int64)
    positions = sensor_pos + np.linspace(0.0, 1.0, n)[::-1, None] * np.array([0.0, 0.0, 0.1])
    quats = np.tile(sensor_rot.as_quat(), (n, 1))
    return PoseTrack("/wrist", "wrist", stamps, positions, quats)


def test_graspit_offset_moves_and_turns_the_palm() -> None:
    pos, quat = palm_from_sensor(np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
    np.testing.assert_allclose(pos, [0.0, -0.060, -0.035])
    expected = Rotation.from_euler("z", 90, degrees=True) * Rotation.from_euler("y", 30, degrees=True)
    assert (Rotation.from_quat(quat) * expected.inv()).magnitude() < 1e-9
    pos, _ = palm_from_sensor(np.ones(3), np.array([0.0, 0.0, 0.0, 1.0]), PalmOffset((0.0, 0.0, 0.0), 0.0, 0.0))
    np.testing.assert_allclose(pos, np.ones(3))


def test_sensor_from_palm_inverts_palm_from_sensor() -> None:
    pos, quat = np.array([0.3, -0.2, 1.1]), Rotation.from_euler("xyz", [0.3, -1.0, 2.0]).as_quat()
    back_pos, back_quat = palm_from_sensor(*sensor_from_palm(pos, quat))
    np.testing.assert_allclose(back_pos, pos, atol=1e-12)
    assert (Rotation.from_quat(back_quat) * Rotation.from_quat(quat).inv()).magnitude() < 1e-9


def test_wrist_pose_is_interpolated_at_the_seed_time() -> None:
    track = _track(np.zeros(3), PALM_DOWN)
    first, _ = wrist_pose_at(track, int(track.stamps_ns[0]))
    mid, _ = wrist_pose_at(track, int(track.stamps_ns[0] + 5 * 10**8))
    assert mid[2] == pytest.approx((first[2] + track.positions[-1][2]) / 2, abs=1e-3)


def test_no_object_model_gives_no_grasp() -> None:
    track = _track(np.zeros(3), PALM_DOWN)
    assert plan_grasp_for_recording(None, track, 0.5, 10**9, np.random.default_rng(0)) is None


@pytest.mark.slow
def test_plans_for_a_recording_from_the_wrist_track(handle_points: tuple[Points, Points]) -> None:
    palm = HANDLE_CENTER + np.array([0.0, 0.0, 0.05])
    track = _track(palm, PALM_DOWN)
    grasp = plan_grasp_for_recording(handle_points[0], track, 1.0, 10**9, np.random.default_rng(1))
    assert grasp is not None
    assert grasp.quality["force_closure"] is True
    assert np.linalg.norm(np.array(grasp.wrist_position) - palm) < 0.1


def test_part_near_the_seed_is_cropped() -> None:
    far = np.random.default_rng(0).uniform(1.0, 2.0, (500, 3))
    near = np.random.default_rng(1).uniform(-0.02, 0.02, (200, 3))
    part = part_near(np.concatenate([near, far]), np.array([0.0, 0.0, 0.05]))
    assert len(part) == 200


def test_errors_name_what_is_wrong(handle_points: tuple[Points, Points]) -> None:
    rng = np.random.default_rng(0)
    with pytest.raises(GraspError, match=r"0 finite object points, need at least 30"):
        plan_grasp(np.zeros((0, 3)), np.zeros(3), PALM_DOWN, rng)
    with pytest.raises(GraspError, match=r"expected shape \(n, 3\)"):
        plan_grasp(np.zeros((10, 2)), np.zeros(3), PALM_DOWN, rng)
    with pytest.raises(GraspError, match="seed pose is not finite"):
        plan_grasp(handle_points[0], np.array([math.nan, 0.0, 0.0]), PALM_DOWN, rng)
    with pytest.raises(GraspError, match="seed quaternion has zero length"):
        plan_grasp(handle_points[0], np.zeros(3), np.zeros(4), rng)
    with pytest.raises(GraspError, match=r"expected position \(3,\) and quaternion \(4,\)"):
        plan_grasp(handle_points[0], np.zeros(2), PALM_DOWN, rng)
    with pytest.raises(GraspError, match="seed time is not finite"):
        plan_grasp_for_recording(handle_points[0], _track(np.zeros(3), PALM_DOWN), math.nan, 0, rng)
    empty = PoseTrack("/wrist", "wrist", np.zeros(0, dtype=np.int64), np.zeros((0, 3)), np.zeros((0, 4)))
    with pytest.raises(GraspError, match="wrist track /wrist: no finite samples"):
        plan_grasp_for_recording(handle_points[0], empty, 0.0, 0, rng)


@pytest.mark.slow
def test_plans_for_a_recording_written_ingested_and_loaded(tmp_path: Path, store: Store) -> None:
    """A demonstration MCAP (real writer) with a handle cloud, a wrist track and one marker, through ingest."""
    from tasks.ingest.api import ingest_recording
    from tasks.recording.load import load_recording
    from tasks.recording.writer import RecordingWriter

    rng = np.random.default_rng(4)
    pts, _ = sample_cylinder_surface(0.02, 0.08, 3000, rng)
    handle = Rotation.from_euler("y", 90, degrees=True).apply(pts) + HANDLE_CENTER
    track = _track(HANDLE_CENTER + np.array([0.0, 0.0, 0.05]), PALM_DOWN)
    path = tmp_path / "demo.mcap"
    with RecordingWriter(path, "mcap") as writer:
        writer.add_cloud("/object/model", int(track.stamps_ns[0]), handle)
        writer.add_poses("/hand/wrist", track.stamps_ns, track.positions, track.quats)
        marker = HANDLE_CENTER + np.zeros((len(track.stamps_ns), 3))
        writer.add_points("/mocap/marker_0", track.stamps_ns, marker)
    result = ingest_recording(path, store)
    rec = load_recording(store, result.recording_id)
    assert rec.object_model is not None
    assert rec.wrist is not None
    t_seed = (int(track.stamps_ns[-1]) - rec.start_ns) * 1e-9
    grasp = plan_grasp_for_recording(rec.object_model, rec.wrist, t_seed, rec.start_ns, np.random.default_rng(1))
    assert grasp is not None
    assert grasp.quality["force_closure"] is True
    assert np.linalg.norm(np.array(grasp.wrist_position) - (HANDLE_CENTER + np.array([0.0, 0.0, 0.05]))) < 0.1
