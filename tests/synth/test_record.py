"""Simulated recordings of small scenes: deterministic bytes, truth that matches the links, round trips through
ingest in every container, the sensors' rates, noise and dropouts, the reach and the wrist tracker."""

from __future__ import annotations

import hashlib
import itertools
import json
from pathlib import Path
from typing import Any

import numpy as np
import pybullet as pb
import pytest
from scipy.spatial.transform import Rotation

from tasks.errors import RecordingError
from tasks.hand.tracker import palm_from_sensor
from tasks.ingest.api import ingest_recording
from tasks.recording.load import RecordingData, load_recording
from tasks.scenes.kinematics import link_frames, load_scene, min_jerk, set_joints
from tasks.scenes.scene import HAND_LINK, Scene
from tasks.store import Store
from tasks.synth.paths import truth_path
from tasks.synth.record import OBJECT_MODEL_POINTS, START_NS, record_scene
from tests.synth.scenes import box_model, door_scene, drawer_scene


def _digest(path: Path) -> str:
    files = sorted(path.iterdir()) if path.is_dir() else [path]
    return hashlib.sha256(b"".join(f.name.encode() + f.read_bytes() for f in files)).hexdigest()


def _name(fmt: str) -> str:
    return {"mcap": "demo.mcap", "bag": "demo.bag", "rosbag2": "demo"}[fmt]


@pytest.fixture(scope="module")
def door(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any], RecordingData]:
    """The door scene recorded as MCAP, its truth, and the ingested recording."""
    folder = tmp_path_factory.mktemp("door")
    path = record_scene(door_scene(), folder / "door.mcap", "mcap", box_model)
    truth = json.loads(truth_path(path).read_text())
    store = Store(folder / "store")
    rec = load_recording(store, ingest_recording(path, store).recording_id)
    return path, truth, rec


@pytest.mark.parametrize("fmt", ["mcap", "bag", "rosbag2"])
def test_same_seed_gives_identical_bytes_and_another_seed_does_not(tmp_path: Path, fmt: str) -> None:
    digests = []
    for sub, seed in (("a", 3), ("b", 3), ("c", 4)):
        path = record_scene(door_scene(seed), tmp_path / sub / _name(fmt), fmt, box_model)
        digests.append((_digest(path), truth_path(path).read_bytes()))
    assert digests[0] == digests[1]
    assert digests[0][0] != digests[2][0]
    assert digests[0][1] != digests[2][1]


@pytest.mark.parametrize("fmt", ["mcap", "bag", "rosbag2"])
def test_every_container_round_trips_through_ingest(tmp_path: Path, fmt: str) -> None:
    path = record_scene(drawer_scene(2), tmp_path / _name(fmt), fmt, box_model)
    truth = json.loads(truth_path(path).read_text())
    store = Store(tmp_path / "store")
    result = ingest_recording(path, store)
    info = json.loads((result.folder / "recording.json").read_text())
    roles = {t["name"]: (t["role"], t["count"]) for t in info["topics"]}
    want = {t: ("markers", truth["counts"][t]) for t in truth["sensors"]["mocap_topics"]}
    want |= {
        "/wrist/pose": ("wrist", truth["counts"]["/wrist/pose"]),
        "/object/model": ("object_model", 1),
        "/demo/meta": ("meta", 1),
    }
    assert roles == want
    rec = load_recording(store, result.recording_id)
    assert rec.start_ns == START_NS
    assert rec.meta == {"action": "open", "object": "drawer", "scene": "test_drawer", "seed": 2}
    assert rec.object_model is not None and rec.object_model.shape == (OBJECT_MODEL_POINTS, 3)
    assert sorted(rec.markers) == sorted(truth["sensors"]["mocap_topics"])
    assert rec.wrist is not None and len(rec.wrist.stamps_ns) == truth["counts"]["/wrist/pose"]


def _joint_values(truth: dict[str, Any], t_s: float) -> dict[str, float]:
    """Joint values at ``t_s`` from the truth file alone (motions in order, min-jerk in each segment)."""
    values = dict(truth["joint_start"])
    motions = iter(truth["motions"])
    for seg in truth["segments"]:
        if "joint" not in seg:
            continue
        m = next(motions)
        s = (t_s - seg["t_start"]) / (seg["t_end"] - seg["t_start"])
        values[m["joint"]] = m["start"] + (m["end"] - m["start"]) * float(min_jerk(np.array([s]))[0])
    return values


def _marker_fk(scene: Scene, values: dict[str, float]) -> dict[str, np.ndarray]:
    client = pb.connect(pb.DIRECT)
    try:
        body = load_scene(scene, client)
        set_joints(client, body, values)
        links = {m.link for m in scene.markers if m.link != HAND_LINK}
        frames = link_frames(client, body, links)
        return {
            f"/mocap/{m.name}": frames[m.link][0] + Rotation.from_quat(frames[m.link][1]).apply(m.offset)
            for m in scene.markers
            if m.link != HAND_LINK
        }
    finally:
        pb.disconnect(client)


def test_markers_follow_the_links_at_the_truth_joint_values(door: tuple[Path, dict[str, Any], RecordingData]) -> None:
    _, truth, rec = door
    sigma = truth["sensors"]["mocap_noise_m"]
    prim = truth["chain"][0]
    track0 = rec.markers["/mocap/door_0"]
    times = (track0.stamps_ns - rec.start_ns) / 1e9
    mid = prim["t_start"] + 0.37 * (prim["t_end"] - prim["t_start"])
    for t_s in (0.2, mid, truth["recording"]["duration_s"]):
        stamp = track0.stamps_ns[int(np.argmin(np.abs(times - t_s)))]  # a sample time: the FK is exact there
        want = _marker_fk(door_scene(), _joint_values(truth, (stamp - rec.start_ns) / 1e9))
        for name, pos in want.items():
            track = rec.markers[name]
            if stamp in track.stamps_ns:  # not hidden at that moment
                got = track.points[int(np.searchsorted(track.stamps_ns, stamp))]
                assert np.linalg.norm(got - pos) < 5 * sigma * np.sqrt(3), (name, t_s)


def test_truth_axes_agree_with_the_urdf_joint_axes_in_the_world(tmp_path: Path) -> None:
    for scene, local_axis, local_origin in (
        (door_scene(), [0.0, 0.0, 1.0], [0.0, 0.0, 0.5]),
        (drawer_scene(), [-1.0, 0.0, 0.0], [0.0, 0.0, 0.6]),
    ):
        path = record_scene(scene, tmp_path / f"{scene.name}.mcap", "mcap", box_model)
        prim = json.loads(truth_path(path).read_text())["chain"][0]
        base = Rotation.from_quat(scene.base_orientation)
        axis = base.apply(local_axis)
        np.testing.assert_allclose(prim["dir"], axis, atol=1e-6)  # both motions go the joint's positive way
        assert prim["extent"] == pytest.approx(abs(scene.motions[0].end - scene.motions[0].start))
        if prim["kind"] == "rotation":
            origin = np.asarray(scene.base_position) + base.apply(local_origin)
            off = np.asarray(prim["pos"]) - origin
            assert np.linalg.norm(off - np.dot(off, axis) * axis) < 1e-6
        else:
            assert prim["pos"] is None


def test_truth_segments_cover_the_recording_in_order(door: tuple[Path, dict[str, Any], RecordingData]) -> None:
    _, truth, rec = door
    kinds = [s["kind"] for s in truth["segments"]]
    assert kinds == ["rest", "reach", "hold", "rotation", "hold"]
    ends = [(s["t_start"], s["t_end"]) for s in truth["segments"]]
    assert ends[0][0] == 0.0
    assert all(a[1] == b[0] for a, b in itertools.pairwise(ends))
    assert ends[-1][1] == pytest.approx(truth["recording"]["duration_s"])
    prim = truth["chain"][0]
    assert (prim["t_start"], prim["t_end"]) == ends[3]
    assert prim["markers"] == ["/mocap/door_0", "/mocap/door_1", "/mocap/door_2", "/mocap/thumb"]
    for s in truth["segments"]:
        if s["kind"] in ("rest", "hold"):
            assert s["t_end"] - s["t_start"] >= 0.4
    last = max(int(tr.stamps_ns[-1]) for tr in rec.markers.values())
    assert (last - rec.start_ns) / 1e9 == pytest.approx(truth["recording"]["duration_s"], abs=0.02)


def test_the_hand_reaches_along_a_curve_while_the_object_stays_still(
    door: tuple[Path, dict[str, Any], RecordingData],
) -> None:
    _, truth, rec = door
    reach = truth["segments"][1]
    thumb = rec.markers["/mocap/thumb"]
    t = (thumb.stamps_ns - rec.start_ns) / 1e9
    during = thumb.points[(t >= reach["t_start"]) & (t <= reach["t_end"])]
    start, end = during[0], during[-1]
    assert 0.25 < np.linalg.norm(end - start) < 0.6
    chord = (end - start) / np.linalg.norm(end - start)
    off = during - start
    assert np.linalg.norm(off - np.outer(off @ chord, chord), axis=1).max() > 0.02  # curved, not straight
    before_motion = truth["chain"][0]["t_start"]
    for name in ("/mocap/door_0", "/mocap/frame_0"):
        tr = rec.markers[name]
        tt = (tr.stamps_ns - rec.start_ns) / 1e9
        assert np.ptp(tr.points[tt < before_motion], axis=0).max() < 10 * truth["sensors"]["mocap_noise_m"]
    # the thumb rides on the palm: still during the grasp hold
    hold = truth["segments"][2]
    assert np.ptp(thumb.points[(t > hold["t_start"]) & (t < hold["t_end"])], axis=0).max() < 0.01


def test_the_wrist_tracker_gives_back_the_demonstrated_palm(door: tuple[Path, dict[str, Any], RecordingData]) -> None:
    _, truth, rec = door
    wrist = rec.wrist
    assert wrist is not None
    t = (wrist.stamps_ns - rec.start_ns) / 1e9
    hold = truth["segments"][2]
    pick = (t > hold["t_start"]) & (t < hold["t_end"])
    palms = [palm_from_sensor(p, q) for p, q in zip(wrist.positions[pick], wrist.quats[pick], strict=True)]
    pos = np.mean([p for p, _ in palms], axis=0)
    rot = Rotation.from_quat([q for _, q in palms]).mean()
    want = truth["grasp"]["wrist"]
    assert np.linalg.norm(pos - want["position"]) < 0.004
    assert (rot * Rotation.from_quat(want["orientation"]).inv()).magnitude() < np.radians(1.5)
    # the tracker noise is about 2 mm and 1 degree
    steps = np.linalg.norm(np.diff(wrist.positions[pick], axis=0), axis=1)
    assert 0.001 < float(np.median(steps)) < 0.006


def test_refuses_to_overwrite_and_checks_the_suffix(tmp_path: Path) -> None:
    path = record_scene(drawer_scene(), tmp_path / "d.mcap", "mcap", box_model)
    before = path.read_bytes()
    with pytest.raises(RecordingError, match="refusing to overwrite"):
        record_scene(drawer_scene(), path, "mcap", box_model)
    assert path.read_bytes() == before
    truth_only = tmp_path / "t.mcap"
    truth_path(truth_only).write_text("{}")
    with pytest.raises(RecordingError, match=r"t\.mcap\.truth\.json: output exists"):
        record_scene(drawer_scene(), truth_only, "mcap", box_model)
    assert not truth_only.exists()
    with pytest.raises(RecordingError, match=r"must end in \.bag"):
        record_scene(drawer_scene(), tmp_path / "d2.mcap", "bag", box_model)
    with pytest.raises(RecordingError, match="rosbag2 recording is a folder"):
        record_scene(drawer_scene(), tmp_path / "d3.bag", "rosbag2", box_model)
    with pytest.raises(RecordingError, match="unknown format 'ros3'"):
        record_scene(drawer_scene(), tmp_path / "d4", "ros3", box_model)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.mcap", "d.mcap.truth.json", "t.mcap.truth.json"]


def test_a_failing_object_model_leaves_nothing(tmp_path: Path) -> None:
    from tasks.errors import SceneError

    def flat(scene: Scene, n: int, rng: np.random.Generator) -> np.ndarray:
        return np.zeros((n, 2))

    with pytest.raises(SceneError, match=r"object model must be finite \(n, 3\) points, got shape \(8192, 2\)"):
        record_scene(drawer_scene(), tmp_path / "d.mcap", "mcap", flat)
    assert list(tmp_path.iterdir()) == []


def test_nominal_scene_has_nominal_sensors_and_null_seed(tmp_path: Path) -> None:
    path = record_scene(door_scene(None), tmp_path / "n.mcap", "mcap", box_model)
    truth = json.loads(truth_path(path).read_text())
    assert truth["seed"] is None
    assert truth["sensors"]["mocap_hz"] == 120.0
    assert truth["sensors"]["wrist_hz"] == 60.0
    assert [s["kind"] for s in truth["segments"]][:3] == ["rest", "reach", "hold"]
