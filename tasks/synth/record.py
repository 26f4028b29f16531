"""``synthesize``: a simulated demonstration of a built-in scene written as a recording (RECORDING.md) with
``PATH.truth.json`` beside it.

Topics: ``/mocap/<marker>`` ``geometry_msgs/PointStamped`` (occluded samples absent), ``/wrist/pose``
``geometry_msgs/PoseStamped`` (the tracker, not the palm: ``tasks.hand.tracker.sensor_from_palm``),
``/object/model`` ``sensor_msgs/PointCloud2`` (world frame, at the start) and ``/demo/meta`` ``std_msgs/String``
JSON ``{"action", "object", "scene", "seed"}``. The first mocap sample, the object model and the meta are at
``START_NS``. The same scene and seed give byte-identical output; nothing is ever overwritten.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pybullet as pb

from tasks.arrays import Points
from tasks.errors import RecordingError, SceneError
from tasks.hand.tracker import sensor_from_palm
from tasks.recording.writer import RecordingWriter
from tasks.scenes.catalog import SCENE_NAMES, build_scene
from tasks.scenes.kinematics import load_scene, palm_pose_world, truth_chain
from tasks.scenes.scene import Scene
from tasks.synth.demonstrator import plan_demonstration
from tasks.synth.paths import check_output, check_scene_name, truth_path
from tasks.synth.scan import SCAN_POINTS, scan_object_model
from tasks.synth.sensors import (
    NOMINAL_SENSORS,
    draw_sensor_params,
    observe_markers,
    observe_tracker,
    sample_times,
)
from tasks.synth.tracks import joint_types, true_tracks
from tasks.synth.truth import META_TOPIC, MOCAP_PREFIX, OBJECT_TOPIC, WRIST_TOPIC, truth_document, truth_text

START_NS = 1_700_000_000_000_000_000
"""Stamp of the recording's first sample (2023-11-14 22:13:20 UTC), nanoseconds."""
OBJECT_MODEL_POINTS = SCAN_POINTS
"""Points of the digitised object model (the paper used a 3-D digitizer; ``tasks.synth.scan``)."""

ObjectModelFn = Callable[[Scene, int, np.random.Generator], Points]
"""``(scene, n_points, rng) -> (n, 3)`` world-frame surface samples of the scene's model links at the start."""


def _stamps(t_s: Any) -> Any:
    return START_NS + np.round(np.asarray(t_s, dtype=np.float64) * 1e9).astype(np.int64)


def record_scene(scene: Scene, out: str | Path, fmt: str, object_model: ObjectModelFn) -> Path:
    """Simulate and write the demonstration of ``scene`` to ``out`` with its truth file; returns ``out``.

    ``scene.seed`` None gives the nominal demonstrator and sensors (noise still drawn, from seed 0)."""
    out = Path(out)
    checked = check_output(out, fmt)
    plan_rng, noise_rng, model_rng = (
        np.random.default_rng(s) for s in np.random.SeedSequence(scene.seed or 0).spawn(3)
    )
    randomised = scene.seed is not None
    sensors = draw_sensor_params(plan_rng) if randomised else NOMINAL_SENSORS
    palm_pos, palm_quat = palm_pose_world(scene)
    client = pb.connect(pb.DIRECT)
    try:
        body = load_scene(scene, client)
        dem = plan_demonstration(
            scene, joint_types(client, body), palm_pos, palm_quat, plan_rng if randomised else None
        )
        mocap = true_tracks(dem, client, body, sample_times(dem.duration_s, sensors.mocap_hz))
        wrist = true_tracks(dem, client, body, sample_times(dem.duration_s, sensors.wrist_hz, sensors.wrist_phase_s))
    finally:
        pb.disconnect(physicsClientId=client)
    chain = truth_chain(scene)
    model = np.asarray(object_model(scene, OBJECT_MODEL_POINTS, model_rng), dtype=np.float64)
    if model.ndim != 2 or model.shape[1] != 3 or not np.isfinite(model).all():
        msg = f"scene {scene.name!r}: object model must be finite (n, 3) points, got shape {model.shape}"
        raise SceneError(msg)
    observed = {m.name: observe_markers(mocap.markers[m.name], sensors, noise_rng) for m in scene.markers}
    tracker_pos, tracker_quat = sensor_from_palm(wrist.palm_pos, wrist.palm_quat)
    tracker_pos, tracker_quat = observe_tracker(tracker_pos, tracker_quat, sensors, noise_rng)
    meta = {"action": scene.action, "object": scene.object_name, "scene": scene.name, "seed": scene.seed}
    counts: dict[str, int] = {}
    with RecordingWriter(out, checked) as writer:
        stamps = _stamps(mocap.t_s)
        for name, points in observed.items():
            writer.add_points(MOCAP_PREFIX + name, stamps, points)
            counts[MOCAP_PREFIX + name] = int(np.isfinite(points).all(axis=1).sum())
        writer.add_poses(WRIST_TOPIC, _stamps(wrist.t_s), tracker_pos, tracker_quat)
        counts[WRIST_TOPIC] = len(wrist.t_s)
        writer.add_cloud(OBJECT_TOPIC, START_NS, model)
        counts[OBJECT_TOPIC] = 1
        writer.add_string(META_TOPIC, START_NS, json.dumps(meta, sort_keys=True))
        counts[META_TOPIC] = 1
    grasp_tracker = sensor_from_palm(palm_pos, palm_quat)
    doc = truth_document(
        dem,
        chain,
        sensors,
        palm=(palm_pos, palm_quat),
        tracker=grasp_tracker,
        counts=counts,
        fmt=checked,
        start_ns=START_NS,
    )
    _write_text(truth_path(out), truth_text(doc), out)
    return out


def _write_text(path: Path, text: str, recording: Path) -> None:
    """Write ``text`` atomically (temporary file, then rename); on failure the just-written ``recording`` goes."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(text)
        if path.exists():
            msg = "output exists; refusing to overwrite"
            raise RecordingError(path, msg)
        tmp.rename(path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        _remove(recording)
        raise


def _remove(path: Path) -> None:
    if path.is_dir():
        for child in sorted(path.iterdir()):
            child.unlink()
        path.rmdir()
    else:
        path.unlink(missing_ok=True)


def synthesize(scene_name: str, seed: int | None, out_path: str | Path, fmt: str = "mcap") -> Path:
    """Record built-in scene ``scene_name`` (randomised by ``seed``; None is the nominal instance) to
    ``out_path`` in ``fmt`` (mcap, bag, rosbag2) with ``PATH.truth.json``; ``SceneError`` for an unknown scene."""

    check_scene_name(scene_name, SCENE_NAMES)
    check_output(Path(out_path), fmt)
    return record_scene(build_scene(scene_name, seed), out_path, fmt, scan_object_model)
