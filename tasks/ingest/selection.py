"""Which topics a container reader keeps the payloads of: decided once per topic, from its name and type.

Readers count every message of every topic, but keep the bytes only of topics some role can use; chunks that
hold none of those are skipped without being read or decompressed wherever the container says what a chunk
holds (MCAP message indexes, ROS 1 bag index records, rosbag2 sqlite rows by topic).
"""

from __future__ import annotations

import enum
from collections.abc import Callable


class Keep(enum.Enum):
    """What a reader keeps of one topic's messages."""

    NONE = "none"
    """Count them only (a camera image, anything no role can use)."""
    ALL = "all"
    """Every payload."""
    SMALL = "small"
    """The first payload, then only those of at most ``SMALL_PAYLOAD_BYTES`` (a point cloud: a marker set is
    small; a dense cloud keeps its first message, the only one an object model uses)."""


SMALL_PAYLOAD_BYTES = 64 * 1024
"""Largest PointCloud2 payload a marker set can have: 256 markers (more than any mocap marker set) of up to 256
bytes per point."""

Want = Callable[[str, str], Keep]
"""``want(topic, msgtype)`` -> what to keep of that topic (``msgtype`` as ``pkg/msg/Type``)."""


def normalize_type(name: str) -> str:
    """``pkg/Type`` or ``pkg/msg/Type`` -> ``pkg/msg/Type`` (ROS 2 style); other names unchanged."""
    parts = [p for p in name.replace("::", "/").split("/") if p]
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    return "/".join(parts) if parts else name


def keep_all(topic: str, msgtype: str) -> Keep:
    """The selection that keeps every payload."""
    del topic, msgtype
    return Keep.ALL
