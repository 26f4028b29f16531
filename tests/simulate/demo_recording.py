"""Synthetic demonstrations of the procedural objects (``objects.py``), so learned descriptors can be executed.

The object's joints follow its truth chain one primitive after another (minimum-jerk profiles with rests in
between); four markers ride on the grasped link and the wrist pose moves rigidly with it. World frame, metres,
nanosecond stamps. ``demo_tracks`` computes the tracks (pybullet forward kinematics only), ``write_demo`` writes
them with the project's ``RecordingWriter``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from schemas.descriptor import Descriptor
from tasks.arrays import FloatArray, Points, Quats, StampsNs
from tasks.rotations import matrix_from_quat, quat_from_matrix
from tasks.simulate.execute import scene_joints
from tasks.simulate.matching import match_chain

START_NS = 1_700_000_000_000_000_000
"""Stamp of the first sample."""
MARKER_HZ = 120.0
WRIST_HZ = 60.0
REST_S = 0.6
"""Still at the start, between primitives and at the end, seconds."""
MOTION_S_PER_RAD = 1.6
MOTION_S_PER_M = 6.0
"""Duration of a primitive per radian or metre of its extent (at least 1 s)."""
MARKER_NOISE_M = 0.0005
"""Gaussian noise of the marker positions (0.5 mm, a good mocap system)."""
MARKER_OFFSETS: FloatArray = np.array([[0.05, 0.0, 0.0], [0.0, 0.05, 0.02], [-0.04, -0.03, 0.03], [0.01, 0.0, -0.05]])
"""Marker positions in the grasped link's inertial frame, metres (a small marker tree, up to 6 cm out)."""


@dataclass(frozen=True)
class DemoTracks:
    """Marker tracks (name -> (stamps_ns (n,), points (n, 3))) and the wrist's pose track, world frame."""

    markers: dict[str, tuple[StampsNs, Points]]
    wrist_stamps_ns: StampsNs
    wrist_positions: Points
    wrist_quats: Quats
    meta: dict[str, str]


def _min_jerk(s: FloatArray) -> FloatArray:
    out: FloatArray = 10 * s**3 - 15 * s**4 + 6 * s**5
    return out


def _joint_schedule(desc: Descriptor, t: FloatArray) -> FloatArray:
    """(n, k) progress of each primitive at times ``t`` (seconds from the start)."""
    progress = np.zeros((t.size, len(desc.chain)))
    start = REST_S
    for i, prim in enumerate(desc.chain):
        rate = MOTION_S_PER_RAD if prim.kind == "rotation" else MOTION_S_PER_M
        duration = max(1.0, rate * prim.extent)
        s = np.clip((t - start) / duration, 0.0, 1.0)
        progress[:, i] = prim.extent * _min_jerk(s)
        start += duration + REST_S
    return progress


def demo_duration_s(desc: Descriptor) -> float:
    """Length of the demonstration of ``desc``, seconds."""
    total = REST_S
    for prim in desc.chain:
        rate = MOTION_S_PER_RAD if prim.kind == "rotation" else MOTION_S_PER_M
        total += max(1.0, rate * prim.extent) + REST_S
    return total


def demo_tracks(urdf: Path, desc: Descriptor, rng: np.random.Generator) -> DemoTracks:
    """Markers and wrist of a demonstration of ``desc`` (a truth descriptor with a grasp) on the object ``urdf``."""
    import pybullet as pb

    assert desc.grasp is not None
    client = int(pb.connect(pb.DIRECT))
    try:
        body = int(pb.loadURDF(str(urdf), useFixedBase=True, physicsClientId=client))
        joints = scene_joints(client, body, None)
        matches = match_chain(desc.chain, [j.axis for j in joints])
        index = {j.axis.name: j.index for j in joints}
        grasped = index[matches[0].joint]

        def link_pose() -> tuple[FloatArray, FloatArray]:
            st = pb.getLinkState(body, grasped, computeForwardKinematics=True, physicsClientId=client)
            return np.array(st[0]), matrix_from_quat(st[1])

        c0, R0 = link_pose()
        palm_p = np.array(desc.grasp.wrist_position)
        palm_R = matrix_from_quat(desc.grasp.wrist_orientation)
        palm_local_p, palm_local_R = R0.T @ (palm_p - c0), R0.T @ palm_R
        t_m = np.arange(0.0, demo_duration_s(desc), 1.0 / MARKER_HZ)
        progress = _joint_schedule(desc, t_m)
        markers = np.empty((len(MARKER_OFFSETS), t_m.size, 3))
        wrist_p = np.empty((t_m.size, 3))
        wrist_q = np.empty((t_m.size, 4))
        q0 = {j.index: pb.getJointState(body, j.index, physicsClientId=client)[0] for j in joints}
        for n in range(t_m.size):
            for i, m in enumerate(matches):
                j = index[m.joint]
                pb.resetJointState(body, j, q0[j] + m.sign * progress[n, i], physicsClientId=client)
            c, R = link_pose()
            markers[:, n] = c + MARKER_OFFSETS @ R.T
            wrist_p[n] = c + R @ palm_local_p
            wrist_q[n] = quat_from_matrix(R @ palm_local_R)
    finally:
        pb.disconnect(physicsClientId=client)
    markers += rng.normal(0.0, MARKER_NOISE_M, markers.shape)
    stamps = START_NS + np.round(t_m * 1e9).astype(np.int64)
    every = max(1, round(MARKER_HZ / WRIST_HZ))
    return DemoTracks(
        markers={f"/mocap/marker_{i}": (stamps, markers[i]) for i in range(len(MARKER_OFFSETS))},
        wrist_stamps_ns=stamps[::every],
        wrist_positions=wrist_p[::every],
        wrist_quats=wrist_q[::every],
        meta={"action": desc.action, "object": desc.object.name},
    )


def write_demo(path: Path, tracks: DemoTracks) -> Path:
    """Write the demonstration as an MCAP recording at ``path`` (refuses to overwrite); returns ``path``."""
    from tasks.recording.writer import RecordingWriter

    with RecordingWriter(path, "mcap") as writer:
        for topic, (stamps, points) in tracks.markers.items():
            writer.add_points(topic, stamps, points)
        writer.add_poses("/demo/wrist", tracks.wrist_stamps_ns, tracks.wrist_positions, tracks.wrist_quats)
        writer.add_string("/demo/meta", int(tracks.wrist_stamps_ns[0]), json.dumps(tracks.meta))
    return path
