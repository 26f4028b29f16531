"""Arrow schemas of the Parquet tables written by ingest (``../shared/RECORDING.md``, "Parquet layout").

Column names are defined here and nowhere else.
"""

from __future__ import annotations

import pyarrow as pa

SCHEMA_VERSION = 1
"""Version of the Parquet layout; loaders refuse a ``recording.json`` with another ``schema_version``."""

INGEST_VERSION = "1"
"""Version of the ingest code's output; part of every downstream cache key."""

MARKERS_FILE = "markers.parquet"
POSES_FILE = "poses.parquet"
OBJECT_MODEL_FILE = "object_model.parquet"
RECORDING_FILE = "recording.json"

MARKERS_SCHEMA = pa.schema(
    [
        pa.field("marker", pa.string(), nullable=False),
        pa.field("stamp_ns", pa.int64(), nullable=False),
        pa.field("x", pa.float64()),
        pa.field("y", pa.float64()),
        pa.field("z", pa.float64()),
    ]
)
"""Marker samples, metres, world frame; sorted by marker, then stamp."""

POSES_SCHEMA = pa.schema(
    [
        pa.field("frame", pa.string(), nullable=False),
        pa.field("role", pa.string(), nullable=False),
        pa.field("stamp_ns", pa.int64(), nullable=False),
        pa.field("x", pa.float64()),
        pa.field("y", pa.float64()),
        pa.field("z", pa.float64()),
        pa.field("qx", pa.float64()),
        pa.field("qy", pa.float64()),
        pa.field("qz", pa.float64()),
        pa.field("qw", pa.float64()),
    ]
)
"""Rigid-body poses (wrist and marker rigid bodies): position metres, quaternion [x, y, z, w], world frame."""

OBJECT_MODEL_SCHEMA = pa.schema(
    [
        pa.field("x", pa.float32()),
        pa.field("y", pa.float32()),
        pa.field("z", pa.float32()),
    ]
)
"""Object model point cloud, metres, world frame at the start of the demonstration."""

ROLES = ("markers", "wrist", "object_model", "meta", "ignored")
"""Topic roles as RECORDING.md names them (``ignored``: no role, kept in ``recording.json`` only)."""
