"""Synthetic demonstrations with known chains, for tests and ``bench/learn_accuracy.py``.

Four scenes after the paper's tasks: a microwave door (rotation), a drawer (translation), a bottle cap
(small rotation), a door whose handle turns before it swings (rotation, rotation). Each has object markers
on the moving parts and a thumb marker that reaches, rides along while the object moves, and leaves. Motions
follow minimum-jerk profiles with holds between; noise is white Gaussian per axis (metres).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tasks.recording.load import MarkerTrack, RecordingData

START_NS = 1_700_000_000_000_000_000
SCENES = ("microwave", "drawer", "bottle", "door")


@dataclass(frozen=True)
class TruthPrimitive:
    """A known primitive: kind, axis point (m), unit direction, extent (rad or m), time span (s)."""

    kind: str
    pos: np.ndarray
    dir: np.ndarray
    extent: float
    t_start: float
    t_end: float


@dataclass(frozen=True)
class Demo:
    """Marker samples per name (t_s, points) and the true chain."""

    scene: str
    markers: dict[str, tuple[np.ndarray, np.ndarray]]
    chain: tuple[TruthPrimitive, ...]
    meta: dict[str, str] = field(default_factory=dict)


def _rodrigues(axis: np.ndarray, angle: float) -> np.ndarray:
    k = axis / np.linalg.norm(axis)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx


def _minjerk(s: np.ndarray) -> np.ndarray:
    s = np.clip(s, 0.0, 1.0)
    return 10 * s**3 - 15 * s**4 + 6 * s**5


def _random_frame(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A world placement: rotation about z by a random yaw and a random offset."""
    yaw = rng.uniform(-np.pi, np.pi)
    return _rodrigues(np.array([0.0, 0.0, 1.0]), yaw), rng.uniform(-0.5, 0.5, 3) + np.array([0.0, 0.0, 0.8])


def make_demo(scene: str, rng: np.random.Generator, noise_m: float = 0.0005, hz: float = 120.0) -> Demo:
    """One demonstration of ``scene`` in a random world placement with the given noise and rate."""
    rot_w, off_w = _random_frame(rng)
    # scene in a local frame: list of primitives (kind, pos, dir, extent, duration) and parts
    if scene == "microwave":
        prims = [("rotation", [0, 0, 0], [0, 0, 1], rng.uniform(1.2, 1.7), 2.0)]
        parts = {"/mocap/door_0": ([0.3, 0.02, 0.1], (0,)), "/mocap/door_1": ([0.42, 0.02, -0.12], (0,))}
        grasp = [0.45, 0.04, 0.0]
        meta = {"action": "open", "object": "microwave"}
    elif scene == "drawer":
        prims = [("translation", [0, 0, 0], [1, 0, 0], rng.uniform(0.2, 0.35), 1.6)]
        parts = {"/mocap/drawer_0": ([0.0, 0.1, 0.0], (0,)), "/mocap/drawer_1": ([0.0, -0.12, 0.05], (0,))}
        grasp = [0.03, 0.0, 0.02]
        meta = {"action": "open", "object": "drawer"}
    elif scene == "bottle":
        prims = [("rotation", [0, 0, 0], [0, 0, 1], rng.uniform(2.0, 3.5), 2.0)]
        parts = {"/mocap/cap_0": ([0.01, 0.0, 0.01], (0,)), "/mocap/cap_1": ([-0.005, 0.0087, 0.01], (0,))}
        grasp = [0.0, -0.011, 0.012]
        meta = {"action": "open", "object": "bottle"}
    elif scene == "door":
        prims = [
            ("rotation", [0.7, 0.0, 0.0], [1, 0, 0], rng.uniform(0.6, 0.9), 1.2),
            ("rotation", [0, 0, 0], [0, 0, 1], rng.uniform(0.8, 1.3), 2.2),
        ]
        parts = {"/mocap/handle_0": ([0.7, 0.06, -0.1], (0, 1)), "/mocap/door_0": ([0.4, 0.0, 0.3], (1,))}
        grasp = [0.7, 0.08, -0.08]
        meta = {"action": "open", "object": "door"}
    else:
        msg = f"unknown scene {scene}"
        raise ValueError(msg)

    t_reach, t_hold = 1.0, 0.4
    t_first = 0.8 + t_reach + 0.3
    starts = []
    t = t_first
    for p in prims:
        starts.append(t)
        t += p[4] + t_hold
    t_release = t
    t_end = t_release + 1.0 + 0.5
    times = np.arange(0.0, t_end, 1.0 / hz)

    def pose_at(tt: float, moved_by: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
        """Rotation and translation (local frame) of a part moved by the primitives ``moved_by`` (in order)."""
        r_tot, t_tot = np.eye(3), np.zeros(3)
        for i in moved_by:
            kind, pos, d, ext, dur = prims[i]
            s = float(_minjerk(np.array([(tt - starts[i]) / dur]))[0])
            if kind == "rotation":
                r = _rodrigues(np.asarray(d, float), ext * s)
                tr = np.asarray(pos, float) - r @ np.asarray(pos, float)
            else:
                r, tr = np.eye(3), np.asarray(d, float) * ext * s
            r_tot, t_tot = r @ r_tot, r @ t_tot + tr
        return r_tot, t_tot

    markers: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for name, (p0, moved_by) in parts.items():
        poses = [pose_at(tt, moved_by) for tt in times]
        pts = np.array([r @ np.asarray(p0, float) + tr for r, tr in poses])
        markers[name] = (times, pts)
    g0 = np.asarray(grasp, float)
    far = g0 + np.array([0.25, -0.3, 0.15])
    thumb = []
    for tt in times:
        if tt < 0.8:
            thumb.append(far)
        elif tt < 0.8 + t_reach:
            s = float(_minjerk(np.array([(tt - 0.8) / t_reach]))[0])
            thumb.append(far + (g0 - far) * s + np.array([0, 0, 0.06]) * np.sin(np.pi * s))
        elif tt < t_release:
            r, tr = pose_at(tt, tuple(range(len(prims))))
            thumb.append(r @ g0 + tr)
        else:
            r, tr = pose_at(t_release, tuple(range(len(prims))))
            end = r @ g0 + tr
            s = float(_minjerk(np.array([(tt - t_release) / 1.0]))[0])
            thumb.append(end + (far - g0) * s)
    markers["/mocap/thumb"] = (times, np.array(thumb))

    out_markers = {}
    for name, (tt, pts) in markers.items():
        world = pts @ rot_w.T + off_w + rng.normal(0.0, noise_m, pts.shape)
        out_markers[name] = (tt, world)
    chain = []
    for i, (kind, pos, d, ext, dur) in enumerate(prims):
        # each primitive's axis is fixed in the frame of the parts moved by the later primitives, which are
        # still at rest when it acts: the initial axis is the world axis
        wdir = rot_w @ np.asarray(d, float)
        wpos = rot_w @ np.asarray(pos, float) + off_w
        chain.append(TruthPrimitive(kind, wpos, wdir / np.linalg.norm(wdir), float(ext), starts[i], starts[i] + dur))
    return Demo(scene, out_markers, tuple(chain), meta)


def to_recording(demo: Demo, rec_id: str = "synthetic") -> RecordingData:
    """The demo as an in-memory ``RecordingData`` (as the loader would give it after ingest)."""
    markers = {}
    for name, (t, pts) in demo.markers.items():
        stamps = START_NS + np.round(t * 1e9).astype(np.int64)
        markers[name] = MarkerTrack(name, stamps, pts)
    info: dict[str, Any] = {"id": rec_id, "start_ns": START_NS, "source": f"{demo.scene}.mcap", "meta": demo.meta}
    return RecordingData(rec_id, Path(rec_id), info, markers, {}, None, dict(demo.meta))


def write_recording(demo: Demo, path: Path, fmt: str = "mcap") -> None:
    """Write the demo with the real ``RecordingWriter`` (PointStamped per marker, meta string)."""
    from tasks.recording.writer import RecordingWriter

    with RecordingWriter(path, fmt) as w:  # type: ignore[arg-type]
        for name, (t, pts) in demo.markers.items():
            w.add_points(name, START_NS + np.round(t * 1e9).astype(np.int64), pts)
        w.add_string("/demo/meta", START_NS, json.dumps(demo.meta))
