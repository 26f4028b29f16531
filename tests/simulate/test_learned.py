"""A synthetic demonstration of the test door, learned by the real pipeline, opens the door in simulation."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from tasks.ingest.api import ingest_recording
from tasks.learn.api import learn_descriptor
from tasks.learn.params import LearnParams
from tasks.recording.load import load_recording
from tasks.simulate.api import simulate_descriptor
from tasks.simulate.matching import axis_angle_rad, point_line_distance_m
from tasks.store import Store
from tests.simulate.demo_recording import demo_tracks, write_demo
from tests.simulate.objects import DoorSpec, write_urdf


def test_demo_markers_ride_on_the_door(tmp_path: Path) -> None:
    spec = DoorSpec(hinge_x=0.05, hinge_y=-0.1, hinge_z=0.7)
    truth = spec.descriptor(1.0)
    tracks = demo_tracks(write_urdf(spec.urdf(), tmp_path, "door"), truth, np.random.default_rng(0))
    for stamps, points in tracks.markers.values():
        radius = np.hypot(points[:, 0] - 0.05, points[:, 1] + 0.1)
        assert np.ptp(radius) < 0.005  # circles about the hinge, up to the 0.5 mm noise
        assert np.all(np.diff(stamps) > 0)
    # the wrist turns with the door by the extent
    first, last = tracks.wrist_positions[0], tracks.wrist_positions[-1]
    turned = math.atan2(last[1] + 0.1, last[0] - 0.05) - math.atan2(first[1] + 0.1, first[0] - 0.05)
    assert abs(turned - 1.0) < 0.01


def test_learned_descriptor_opens_the_door(tmp_path: Path, store: Store) -> None:
    spec = DoorSpec()
    truth = spec.descriptor(1.1)
    urdf = write_urdf(spec.urdf(), tmp_path, "door")
    recording = write_demo(tmp_path / "demo.mcap", demo_tracks(urdf, truth, np.random.default_rng(1)))
    rec = load_recording(store, ingest_recording(recording, store).recording_id)
    learned = learn_descriptor(rec, LearnParams(), rng=np.random.default_rng(1))
    (prim,) = learned.chain
    assert prim.kind == "rotation" and prim.pos is not None
    assert math.degrees(axis_angle_rad(np.array(prim.dir), np.array(truth.chain[0].dir))) < 2.0
    assert point_line_distance_m(np.array(prim.pos), np.array([0.0, 0.0, 0.5]), np.array([0.0, 0.0, 1.0])) < 0.01
    result = simulate_descriptor(learned.with_grasp(truth.grasp), urdf=urdf)
    assert result.success, result.to_dict()
