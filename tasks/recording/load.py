"""Load an ingested recording from the store's Parquet layout (``../shared/RECORDING.md``) into arrays."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

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

XYZ = ("x", "y", "z")
"""Position columns of the marker, pose and object-model tables (metres, world frame)."""
QUAT = ("qx", "qy", "qz", "qw")
"""Orientation columns of the pose table (unit quaternion, scalar last)."""


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


def _read_sorted(path: Path, columns: tuple[str, ...], by: str) -> pl.DataFrame:
    """The ``columns`` of the Parquet table ``path`` sorted by ``by`` then ``stamp_ns`` (if present);
    ``RecordingError`` naming the file when it cannot be read or lacks a column."""
    try:
        frame = pl.read_parquet(path, columns=list(columns))
    except (OSError, pl.exceptions.PolarsError) as err:
        msg = f"cannot read ingested table ({str(err).splitlines()[0]})"
        raise RecordingError(path, msg) from err
    return frame.sort(by, "stamp_ns") if by else frame


def _groups(frame: pl.DataFrame, by: str) -> dict[str, pl.DataFrame]:
    """``frame``'s rows split by the string column ``by``, in sorted order of its values."""
    return {str(key[0]): part for key, part in frame.partition_by(by, as_dict=True, maintain_order=True).items()}


def _floats(frame: pl.DataFrame, columns: tuple[str, ...]) -> Points:
    """(n, len(columns)) float64 array of ``columns`` (NaN where null)."""
    out: Points = frame.select(pl.col(c).cast(pl.Float64) for c in columns).to_numpy().astype(np.float64)
    return out


def _stamps(frame: pl.DataFrame) -> StampsNs:
    """(n,) int64 ns of the ``stamp_ns`` column."""
    out: StampsNs = frame["stamp_ns"].to_numpy().astype(np.int64)
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
        table = _read_sorted(folder / MARKERS_FILE, ("marker", "stamp_ns", *XYZ), "marker")
        for name, part in _groups(table, "marker").items():
            markers[name] = MarkerTrack(name, _stamps(part), _floats(part, XYZ))

    poses: dict[str, PoseTrack] = {}
    if (folder / POSES_FILE).is_file():
        table = _read_sorted(folder / POSES_FILE, ("frame", "role", "stamp_ns", *XYZ, *QUAT), "frame")
        for name, part in _groups(table, "frame").items():
            poses[name] = PoseTrack(name, str(part["role"][0]), _stamps(part), _floats(part, XYZ), _floats(part, QUAT))

    model: Points | None = None
    if (folder / OBJECT_MODEL_FILE).is_file():
        table = _read_sorted(folder / OBJECT_MODEL_FILE, XYZ, "")
        if table.height:
            model = _floats(table, XYZ)

    meta = info.get("meta") or {}
    return RecordingData(str(info.get("id", folder.name)), folder, info, markers, poses, model, dict(meta))


def load_recording(store: Store, recording_id: str) -> RecordingData:
    """Load the ingested recording ``recording_id`` from ``store``."""
    if not store.has_recording(recording_id):
        msg = f"recording {recording_id} is not in the store {store.root} (run pbd ingest first)"
        raise RecordingError(store.recording_dir(recording_id), msg)
    return load_recording_folder(store.recording_dir(recording_id))
