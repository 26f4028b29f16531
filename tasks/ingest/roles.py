"""Topic roles (``../shared/RECORDING.md``, "Roles"): detection by type and name, and the topic map override."""

from __future__ import annotations

import json
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from tasks.errors import TopicMapError
from tasks.ingest.selection import Keep, Want

POINT = "geometry_msgs/msg/PointStamped"
POSE = "geometry_msgs/msg/PoseStamped"
TRANSFORM = "geometry_msgs/msg/TransformStamped"
TF = "tf2_msgs/msg/TFMessage"
TF_LEGACY = "tf/msg/tfMessage"
MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"
CLOUD = "sensor_msgs/msg/PointCloud2"
STRING = "std_msgs/msg/String"
META_TOPIC = "/demo/meta"

MARKERS, WRIST, OBJECT_MODEL, META, IGNORED = "markers", "wrist", "object_model", "meta", "ignored"


def is_mocap_markers(msgtype: str) -> bool:
    """Mocap driver marker arrays such as ``mocap4r2_msgs/msg/Markers``."""
    pkg, _, name = msgtype.rpartition("/")
    return name == "Markers" and "mocap" in pkg.lower()


def marker_capable(msgtype: str) -> bool:
    """Types whose messages can be markers."""
    return msgtype in (POINT, POSE, TRANSFORM, MARKER_ARRAY, CLOUD) or is_mocap_markers(msgtype)


def wrist_capable(msgtype: str) -> bool:
    """Types whose messages can be the wrist pose."""
    return msgtype in (POSE, TRANSFORM, TF, TF_LEGACY)


def is_service_event(name: str, msgtype: str) -> bool:
    """rosbag2 service-event topics (``.../_service_event``, types ``pkg/srv/X_Event``)."""
    return name.endswith("/_service_event") or ("/srv/" in msgtype and msgtype.endswith("_Event"))


def _same_topic(a: str, b: str) -> bool:
    return a.lstrip("/") == b.lstrip("/")


def detect_role(name: str, msgtype: str, child_frames: Iterable[str] = ()) -> str:
    """The role of a topic without a topic map (``child_frames``: child frame ids seen, for TF types)."""
    lname = name.lower()
    if _same_topic(name, META_TOPIC):
        return META
    if msgtype == CLOUD and "object" in lname:
        return OBJECT_MODEL
    if wrist_capable(msgtype) and ("wrist" in lname or any("wrist" in c.lower() for c in child_frames)):
        return WRIST
    if marker_capable(msgtype):
        return MARKERS
    return IGNORED


MARKER_SET_MAX_POINTS = 256
"""Most points a PointCloud2 marker set has: mocap marker sets carry tens to a few hundred markers; a cloud with
more is a scan (lidar, depth camera)."""


def could_have_role(name: str, msgtype: str) -> bool:
    """Whether detection can give this topic a role (TF child frames and cloud sizes are seen only later)."""
    return _same_topic(name, META_TOPIC) or marker_capable(msgtype) or wrist_capable(msgtype) or msgtype == CLOUD


@dataclass(frozen=True)
class TopicMap:
    """A parsed ``--topics`` YAML: patterns per role (exact topic names or regular expressions)."""

    source: str
    roles: dict[str, list[str]] = field(default_factory=dict)

    def canonical(self) -> str:
        """The map as canonical JSON (roles sorted, each role's patterns sorted): equal maps, equal text."""
        return json.dumps({r: sorted(p) for r, p in self.roles.items()}, sort_keys=True, separators=(",", ":"))

    def role_of(self, name: str) -> str | None:
        """The role this map gives topic ``name`` (``ignored`` wins, as in ``apply_topic_map``); None: unnamed."""
        found = None
        for role in (MARKERS, WRIST, OBJECT_MODEL, META, IGNORED):
            if any(_matches(p, name) for p in self.roles.get(role, [])):
                found = role
        return found


def wanted(tmap: TopicMap | None) -> Want:
    """What a reader keeps of each topic: nothing of those no role can use (cameras, anything the map ignores),
    the first and the small messages of a point cloud, everything else."""

    def want(name: str, msgtype: str) -> Keep:
        role = tmap.role_of(name) if tmap is not None else None
        if role == IGNORED or (role is None and not could_have_role(name, msgtype)):
            return Keep.NONE
        return Keep.SMALL if msgtype == CLOUD else Keep.ALL

    return want


def parse_topic_map(path: Path) -> TopicMap:
    """Read a topic map YAML: ``markers: [..]``, ``wrist: t``, ``object_model: t``, ``meta: t``, ``ignore: [..]``."""
    import yaml  # noqa: PLC0415 (imported on first use: only with a topic map)

    try:
        doc = yaml.safe_load(path.read_text())
    except OSError as err:
        msg = f"cannot read topic map ({err.strerror})"
        raise TopicMapError(path, msg) from err
    except yaml.YAMLError as err:
        msg = f"not valid YAML ({str(err).splitlines()[0]})"
        raise TopicMapError(path, msg) from err
    if not isinstance(doc, dict):
        raise TopicMapError(path, "a topic map is a YAML mapping of role: topic(s)")
    keys = {"markers": MARKERS, "wrist": WRIST, "object_model": OBJECT_MODEL, "meta": META, "ignore": IGNORED}
    roles: dict[str, list[str]] = {}
    for key, value in doc.items():
        if key not in keys:
            msg = f"unknown key {key!r} (expected {', '.join(keys)})"
            raise TopicMapError(path, msg)
        items = value if isinstance(value, list) else [value]
        if not all(isinstance(v, str) and v for v in items):
            msg = f"{key}: expected a topic name or a list of topic names / regular expressions"
            raise TopicMapError(path, msg)
        for v in items:
            try:
                re.compile(v)
            except re.error as err:
                msg = f"{key}: {v!r} is not a valid regular expression ({err})"
                raise TopicMapError(path, msg) from err
        roles[keys[key]] = [str(v) for v in items]
    return TopicMap(str(path), roles)


def _matches(pattern: str, name: str) -> bool:
    if _same_topic(pattern, name):
        return True
    try:
        return re.fullmatch(pattern, name) is not None
    except re.error:
        return False


def apply_topic_map(tmap: TopicMap, detected: Mapping[str, str], types: Mapping[str, str]) -> dict[str, str]:
    """Roles after the topic map: a role the map names is given exactly to the topics it lists.

    Topics the map does not mention keep their detected role unless that role is one the map assigns
    (then they become ``ignored``). Raises ``TopicMapError`` for patterns matching no topic and for topics
    whose type cannot play the role.
    """
    roles = {name: (IGNORED if role in tmap.roles else role) for name, role in detected.items()}
    for role in (MARKERS, WRIST, OBJECT_MODEL, META, IGNORED):
        for pattern in tmap.roles.get(role, []):
            hits = [n for n in detected if _matches(pattern, n)]
            if not hits:
                msg = f"{role if role != IGNORED else 'ignore'}: {pattern!r} matches no topic of the recording"
                raise TopicMapError(tmap.source, msg)
            for name in hits:
                typ = types[name]
                ok = {
                    MARKERS: marker_capable(typ),
                    WRIST: wrist_capable(typ),
                    OBJECT_MODEL: typ == CLOUD,
                    META: typ in (STRING, "") or not typ.count("/"),
                    IGNORED: True,
                }[role]
                if not ok:
                    msg = f"topic {name} has type {typ}, which cannot be {role}"
                    raise TopicMapError(tmap.source, msg)
                roles[name] = role
    return roles
