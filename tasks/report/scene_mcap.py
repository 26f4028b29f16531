"""The learned axes as an MCAP of ``foxglove.SceneUpdate`` messages (JSON encoding), for Foxglove / Lichtblick.

Open the original recording and this file together: the entities are stamped at the recording's start and
never expire, in the recording's world frame, so the fitted rotation axes and translation directions are
drawn over the markers. One entity per chain primitive: an arrow along ``dir`` (at ``pos`` for a rotation,
at the segment's first marker sample for a translation), a line through a rotation axis, and a text label.
"""

from __future__ import annotations

import io
import json
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from mcap.writer import Writer

from schemas.descriptor import Descriptor

SCENE_TOPIC = "/pbd/axes"
SCENE_SCHEMA_NAME = "foxglove.SceneUpdate"
AXIS_LINE_HALF_LENGTH_M = 0.25
"""Half length of the line drawn through a rotation axis, metres."""

_RGBA = ((0.89, 0.1, 0.11), (0.22, 0.49, 0.72), (0.3, 0.69, 0.29), (0.6, 0.31, 0.64), (1.0, 0.5, 0.0))

# A compact JSON Schema of foxglove.SceneUpdate (the viewers dispatch on the schema name).
_VEC3 = {"type": "object", "properties": {k: {"type": "number"} for k in "xyz"}}
_QUAT = {"type": "object", "properties": {k: {"type": "number"} for k in "xyzw"}}
_POSE = {"type": "object", "properties": {"position": _VEC3, "orientation": _QUAT}}
_COLOR = {"type": "object", "properties": {k: {"type": "number"} for k in "rgba"}}
_TIME = {"type": "object", "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}}}
SCENE_UPDATE_SCHEMA: dict[str, Any] = {
    "title": SCENE_SCHEMA_NAME,
    "type": "object",
    "properties": {
        "deletions": {"type": "array"},
        "entities": {
            "type": "array",
            "items": {
                "type": "object",
                "properties": {
                    "timestamp": _TIME,
                    "frame_id": {"type": "string"},
                    "id": {"type": "string"},
                    "lifetime": _TIME,
                    "frame_locked": {"type": "boolean"},
                    "metadata": {"type": "array"},
                    "arrows": {"type": "array", "items": {"type": "object", "properties": {"pose": _POSE}}},
                    "lines": {"type": "array"},
                    "texts": {"type": "array"},
                    "cubes": {"type": "array"},
                    "spheres": {"type": "array"},
                    "cylinders": {"type": "array"},
                    "triangles": {"type": "array"},
                    "models": {"type": "array"},
                },
            },
        },
    },
}


def quat_x_to(direction: Sequence[float]) -> tuple[float, float, float, float]:
    """Unit quaternion [x, y, z, w] rotating +x onto ``direction`` (foxglove arrows point along +x)."""
    d = np.asarray(direction, dtype=np.float64)
    d = d / (np.linalg.norm(d) or 1.0)
    x = np.array([1.0, 0.0, 0.0])
    dot = float(np.dot(x, d))
    if dot < -1 + 1e-12:  # opposite: half a turn about z
        return (0.0, 0.0, 1.0, 0.0)
    q = np.append(np.cross(x, d), 1.0 + dot)  # half-way quaternion, exact for unit vectors
    q /= np.linalg.norm(q)
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))


def _vec(p: Sequence[float] | np.ndarray) -> dict[str, float]:
    return {"x": float(p[0]), "y": float(p[1]), "z": float(p[2])}


def _color(i: int, alpha: float = 1.0) -> dict[str, float]:
    r, g, b = _RGBA[i % len(_RGBA)]
    return {"r": r, "g": g, "b": b, "a": alpha}


def scene_update(
    desc: Descriptor, stamp_ns: int, frame_id: str, segment_starts: Mapping[int, Sequence[float]]
) -> dict[str, Any]:
    """One ``foxglove.SceneUpdate`` (as a dict) with an entity per chain primitive of ``desc``.

    ``segment_starts`` maps a primitive's index to a world point (metres) where a translation arrow starts.
    """
    stamp = {"sec": stamp_ns // 1_000_000_000, "nsec": stamp_ns % 1_000_000_000}
    entities = []
    for i, prim in enumerate(desc.chain):
        origin = prim.pos if prim.pos is not None else tuple(segment_starts.get(i, (0.0, 0.0, 0.0)))
        q = quat_x_to(prim.dir)
        length = AXIS_LINE_HALF_LENGTH_M if prim.kind == "rotation" else max(prim.extent, 0.05)
        pose = {"position": _vec(origin), "orientation": {"x": q[0], "y": q[1], "z": q[2], "w": q[3]}}
        arrows = [
            {"pose": pose, "shaft_length": 0.8 * length, "shaft_diameter": 0.01, "head_length": 0.2 * length,
             "head_diameter": 0.03, "color": _color(i)}
        ]  # fmt: skip
        lines = []
        if prim.kind == "rotation":
            d = np.asarray(prim.dir)
            p = np.asarray(origin)
            ends = [p - AXIS_LINE_HALF_LENGTH_M * d, p + AXIS_LINE_HALF_LENGTH_M * d]
            identity = {"position": _vec((0, 0, 0)), "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}
            lines.append(
                {"type": 0, "pose": identity, "thickness": 0.004, "scale_invariant": False,
                 "points": [_vec(e) for e in ends], "color": _color(i, 0.6), "colors": [], "indices": []}
            )  # fmt: skip
        unit = "rad" if prim.kind == "rotation" else "m"
        text = {
            "pose": {
                "position": _vec(np.asarray(origin) + np.array([0.0, 0.0, 0.05])),
                "orientation": pose["orientation"],
            },
            "billboard": True,
            "font_size": 14.0,
            "scale_invariant": True,
            "color": _color(i),
            "text": f"{i}: {prim.kind} {prim.extent:.3f} {unit}",
        }
        entities.append(
            {
                "timestamp": stamp,
                "frame_id": frame_id,
                "id": f"{desc.name}/{i}",
                "lifetime": {"sec": 0, "nsec": 0},
                "frame_locked": False,
                "metadata": [{"key": "descriptor", "value": desc.id}, {"key": "kind", "value": prim.kind}],
                "arrows": arrows,
                "lines": lines,
                "texts": [text],
                "cubes": [],
                "spheres": [],
                "cylinders": [],
                "triangles": [],
                "models": [],
            }
        )
    return {"deletions": [], "entities": entities}


def axes_mcap_bytes(updates: Sequence[tuple[int, dict[str, Any]]]) -> bytes:
    """MCAP bytes holding ``(stamp_ns, SceneUpdate dict)`` messages on ``/pbd/axes`` (JSON encoding)."""

    buf = io.BytesIO()
    writer = Writer(buf)
    writer.start(profile="", library="pbd")
    schema_id = writer.register_schema(
        name=SCENE_SCHEMA_NAME, encoding="jsonschema", data=json.dumps(SCENE_UPDATE_SCHEMA).encode()
    )
    channel_id = writer.register_channel(topic=SCENE_TOPIC, message_encoding="json", schema_id=schema_id)
    for stamp_ns, update in sorted(updates, key=lambda u: u[0]):
        data = json.dumps(update, sort_keys=True).encode()
        writer.add_message(channel_id=channel_id, log_time=stamp_ns, data=data, publish_time=stamp_ns)
    writer.finish()  # type: ignore[no-untyped-call]
    return buf.getvalue()
