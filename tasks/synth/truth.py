"""``PATH.truth.json``: what really happened in a simulated demonstration, to score the learning stage against.

Schema ``pbd.synth-truth/1``. ``chain`` is the true manipulation chain in the form of ``../shared/DESCRIPTOR.md``
(kind, pos, dir, extent with its sign conventions; ``t_start``/``t_end`` seconds from the recording start;
``markers`` the topics of the markers on the moving part). ``segments`` lists every scripted phase (rest,
reach, hold, rotation, translation) in time order. ``grasp`` is the demonstrated palm pose (Barrett palm frame,
+z approach, world) with its eigengrasp amplitudes and the tracker pose it was recorded as. World frame,
metres, radians, quaternions ``[x, y, z, w]``.
"""

from __future__ import annotations

import json
from dataclasses import replace
from typing import Any

from schemas.descriptor import Primitive
from tasks.arrays import FloatArray
from tasks.scenes.scene import Scene
from tasks.synth.demonstrator import Demonstration
from tasks.synth.sensors import SensorParams

TRUTH_SCHEMA = "pbd.synth-truth/1"
MOCAP_PREFIX = "/mocap/"
WRIST_TOPIC = "/wrist/pose"
OBJECT_TOPIC = "/object/model"
META_TOPIC = "/demo/meta"


def timed_chain(chain: tuple[Primitive, ...], dem: Demonstration) -> tuple[Primitive, ...]:
    """The true chain with each primitive's ``t_start``/``t_end`` (s) from the demonstration's phases."""
    spans = {p.motion: (p.t_start, p.t_end) for p in dem.phases if p.motion is not None}
    return tuple(replace(prim, t_start=spans[k][0], t_end=spans[k][1]) for k, prim in enumerate(chain))


def _floats(values: FloatArray | tuple[float, ...]) -> list[float]:
    return [float(v) for v in values]


def truth_document(
    dem: Demonstration,
    chain: tuple[Primitive, ...],
    sensors: SensorParams,
    *,
    palm: tuple[FloatArray, FloatArray],
    tracker: tuple[FloatArray, FloatArray],
    counts: dict[str, int],
    fmt: str,
    start_ns: int,
) -> dict[str, Any]:
    """The truth document of a recording (``counts``: messages written per topic)."""
    scene: Scene = dem.scene
    by_link: dict[str, list[str]] = {}
    for m in scene.markers:
        by_link.setdefault(m.link, []).append(MOCAP_PREFIX + m.name)
    mocap_topics = [MOCAP_PREFIX + m.name for m in scene.markers]
    return {
        "schema": TRUTH_SCHEMA,
        "scene": scene.name,
        "seed": scene.seed,
        "action": scene.action,
        "object": scene.object_name,
        "name": f"{scene.action}-{scene.object_name}",
        "recording": {"format": fmt, "start_ns": start_ns, "duration_s": dem.duration_s},
        "chain": [p.to_dict() for p in timed_chain(chain, dem)],
        "segments": [
            {
                "kind": p.kind,
                "t_start": p.t_start,
                "t_end": p.t_end,
                **({"joint": scene.motions[p.motion].joint} if p.motion is not None else {}),
            }
            for p in dem.phases
        ],
        "motions": [{"joint": m.joint, "start": m.start, "end": m.end} for m in scene.motions],
        "joint_start": dict(sorted(scene.joint_start.items())),
        "grasp": {
            "hand": "barrett",
            "link": scene.grasp_link,
            "t_s": dem.grasp_s,
            "eigengrasps": list(scene.grasp_eigengrasps),
            "wrist": {"position": _floats(palm[0]), "orientation": _floats(palm[1])},
            "tracker": {"position": _floats(tracker[0]), "orientation": _floats(tracker[1])},
        },
        "markers": dict(sorted(by_link.items())),
        "sensors": {
            **sensors.to_dict(),
            "mocap_topics": mocap_topics,
            "wrist_topic": WRIST_TOPIC,
            "object_model_topic": OBJECT_TOPIC,
            "meta_topic": META_TOPIC,
        },
        "counts": dict(sorted(counts.items())),
    }


def truth_text(doc: dict[str, Any]) -> str:
    """The truth document as JSON text (sorted keys, two-space indent, trailing newline): deterministic."""
    return json.dumps(doc, indent=2, sort_keys=True) + "\n"
