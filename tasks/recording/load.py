"""Load an ingested recording from the store's Parquet layout (``../shared/RECORDING.md``) into arrays."""

from __future__ import annotations

import itertools
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq

from schemas.tables import (
    MARKERS_FILE,
    OBJECT_MODEL_FILE,
    POSES_FILE,
    RECORDING_FILE,
    SCHEMA_VERSION,
)
from tasks.arrays import Points, Quats, StampsNs
from tasks.errors import RecordingError
from tasks.store import Store


@dataclass(frozen=True)
class MarkerTrack:
    """One marker's samples: stamps (n,) int64 ns, points (n, 3) float64 metres, world frame (NaN = dropout)."""

    name: str
    stamps_ns: StampsNs
    points: Points


@dataclass(frozen=True)
class PoseTrack:
    """One rigid body's poses: stamps (n,) int64 ns, positions (n, 3) metres, quats (n, 4) [x, y, z, w], world."""

    frame: str
    role: str
    stamps_ns: StampsNs
    positions: Points
    quats: Quats


@dataclass(frozen=True)
class RecordingData:
    """An ingested recording: its ``recording.json``, marker tracks, poses, object model and meta."""

    id: str
    folder: Path
    info: dict[str, Any]
    markers: dict[str, MarkerTrack] = field(default_factory=dict)
    poses: dict[str, PoseTrack] = field(default_factory=dict)
    object_model: Points | None = None
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def start_ns(self) -> int:
        """First stamp of the recording, ns (``t_start``/``t_end`` in descriptors count from here)."""
        return int(self.info["start_ns"])

    @property
    def wrist(self) -> PoseTrack | None:
        """The wrist pose track, if the recording has one."""
        for track in self.poses.values():
            if track.role == "wrist":
                return track
        return None


def _split(names: Any, *columns: Any) -> dict[str, tuple[Any, ...]]:
    """Split columns sorted by ``names`` into per-name slices."""
    names_arr = np.asarray(names, dtype=object)
    if len(names_arr) == 0:
        return {}
    change = np.flatnonzero(names_arr[1:] != names_arr[:-1]) + 1
    bounds = [0, *change.tolist(), len(names_arr)]
    out: dict[str, tuple[Any, ...]] = {}
    for a, b in itertools.pairwise(bounds):
        out[str(names_arr[a])] = tuple(c[a:b] for c in columns)
    return out


def read_recording_info(folder: Path) -> dict[str, Any]:
    """The ``recording.json`` of a recording folder written by ingest; ``RecordingError`` naming the file when it
    cannot be read or was written for another schema version."""
    info_path = folder / RECORDING_FILE
    try:
        info: dict[str, Any] = json.loads(info_path.read_text())
    except (OSError, json.JSONDecodeError) as err:
        msg = f"cannot read ingested recording ({err})"
        raise RecordingError(info_path, msg) from err
    version = info.get("schema_version", SCHEMA_VERSION)
    if version != SCHEMA_VERSION:
        msg = f"schema_version {version}, this pbd reads {SCHEMA_VERSION}: ingest it again"
        raise RecordingError(info_path, msg)
    return info


def load_recording_folder(folder: Path) -> RecordingData:
    """Load a recording folder written by ingest; raise ``RecordingError`` naming the file on bad content."""

    info = read_recording_info(folder)

    markers: dict[str, MarkerTrack] = {}
    if (folder / MARKERS_FILE).is_file():
        t = pq.read_table(folder / MARKERS_FILE)
        t = t.sort_by([("marker", "ascending"), ("stamp_ns", "ascending")])
        xyz = np.column_stack([t.column(c).to_numpy(zero_copy_only=False) for c in ("x", "y", "z")]).astype(np.float64)
        stamps = t.column("stamp_ns").to_numpy().astype(np.int64)
        for name, (s, p) in _split(t.column("marker").to_pylist(), stamps, xyz).items():
            markers[name] = MarkerTrack(name, s, p)

    poses: dict[str, PoseTrack] = {}
    if (folder / POSES_FILE).is_file():
        t = pq.read_table(folder / POSES_FILE)
        t = t.sort_by([("frame", "ascending"), ("stamp_ns", "ascending")])
        pos = np.column_stack([t.column(c).to_numpy(zero_copy_only=False) for c in ("x", "y", "z")]).astype(np.float64)
        quat = np.column_stack([t.column(c).to_numpy(zero_copy_only=False) for c in ("qx", "qy", "qz", "qw")])
        stamps = t.column("stamp_ns").to_numpy().astype(np.int64)
        roles = t.column("role").to_pylist()
        frames = t.column("frame").to_pylist()
        for name, (s, p, q, r) in _split(frames, stamps, pos, quat.astype(np.float64), np.asarray(roles)).items():
            poses[name] = PoseTrack(name, str(r[0]), s, p, q)

    model: Points | None = None
    if (folder / OBJECT_MODEL_FILE).is_file():
        t = pq.read_table(folder / OBJECT_MODEL_FILE)
        if t.num_rows:
            model = np.column_stack([t.column(c).to_numpy() for c in ("x", "y", "z")]).astype(np.float64)

    meta = info.get("meta") or {}
    return RecordingData(str(info.get("id", folder.name)), folder, info, markers, poses, model, dict(meta))


def load_recording(store: Store, recording_id: str) -> RecordingData:
    """Load the ingested recording ``recording_id`` from ``store``."""
    if not store.has_recording(recording_id):
        msg = f"recording {recording_id} is not in the store {store.root} (run pbd ingest first)"
        raise RecordingError(store.recording_dir(recording_id), msg)
    return load_recording_folder(store.recording_dir(recording_id))
