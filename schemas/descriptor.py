"""The task descriptor T = <O, A, G, M, C> (``../shared/DESCRIPTOR.md``): dataclasses, canonical JSON, id.

Coordinates are metres in the world frame of the recording (or of the object transferred to); angles are
radians; quaternions are [x, y, z, w]. ``Descriptor.to_json()`` validates against the JSON Schema beside
this file; ``Descriptor.from_json()`` validates before it builds.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field, replace
from functools import cache
from importlib import resources
from typing import Any, Literal

from schemas.errors import DescriptorError
from schemas.limits import MAX_DESCRIPTOR_BYTES, check_shape, check_values, clip

DESCRIPTOR_SCHEMA = "pbd.task-descriptor/1"
FLOAT_DIGITS = 10
"""Significant digits kept in canonical JSON, so the content id is stable across platforms' last bits."""

Json = dict[str, Any]
Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]


def _round(value: Any) -> Any:
    """Round floats recursively to ``FLOAT_DIGITS`` significant digits (canonical form)."""
    if isinstance(value, float):
        if not math.isfinite(value):
            msg = f"non-finite number {value!r} in descriptor"
            raise DescriptorError("descriptor", msg)
        return float(f"{value:.{FLOAT_DIGITS}g}") + 0.0  # + 0.0 turns -0.0 into 0.0
    if isinstance(value, dict):
        return {k: _round(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_round(v) for v in value]
    return value


def canonical_json(value: Any) -> str:
    """Canonical JSON: sorted keys, no spaces, floats rounded to ``FLOAT_DIGITS`` significant digits."""
    return json.dumps(_round(value), sort_keys=True, separators=(",", ":"), ensure_ascii=True)


@dataclass(frozen=True)
class Primitive:
    """One manipulation primitive P = <pos, dir> with its extent (metres or radians), world frame."""

    kind: Literal["rotation", "translation"]
    pos: Vec3 | None
    dir: Vec3
    extent: float
    t_start: float | None = None
    t_end: float | None = None
    markers: tuple[str, ...] = ()
    fit: Json = field(default_factory=dict)

    def to_dict(self) -> Json:
        """JSON-ready dict in the layout of DESCRIPTOR.md."""
        out: Json = {
            "kind": self.kind,
            "pos": list(self.pos) if self.pos is not None else None,
            "dir": list(self.dir),
            "extent": self.extent,
        }
        if self.t_start is not None:
            out["t_start"] = self.t_start
        if self.t_end is not None:
            out["t_end"] = self.t_end
        if self.markers:
            out["markers"] = list(self.markers)
        if self.fit:
            out["fit"] = self.fit
        return out

    @classmethod
    def from_dict(cls, data: Json) -> Primitive:
        """Build from the JSON layout (already schema-validated)."""
        pos = data.get("pos")
        return cls(
            kind=data["kind"],
            pos=(float(pos[0]), float(pos[1]), float(pos[2])) if pos is not None else None,
            dir=(float(data["dir"][0]), float(data["dir"][1]), float(data["dir"][2])),
            extent=float(data["extent"]),
            t_start=data.get("t_start"),
            t_end=data.get("t_end"),
            markers=tuple(data.get("markers", ())),
            fit=dict(data.get("fit", {})),
        )


@dataclass(frozen=True)
class Grasp:
    """G: Barrett hand eigengrasp amplitudes (a1, a2) and wrist pose (world frame) with grasp qualities."""

    hand: str
    eigengrasps: tuple[float, float]
    wrist_position: Vec3
    wrist_orientation: Quat
    quality: Json = field(default_factory=dict)

    def to_dict(self) -> Json:
        """JSON-ready dict in the layout of DESCRIPTOR.md."""
        return {
            "hand": self.hand,
            "eigengrasps": list(self.eigengrasps),
            "wrist": {"position": list(self.wrist_position), "orientation": list(self.wrist_orientation)},
            "quality": self.quality,
        }

    @classmethod
    def from_dict(cls, data: Json) -> Grasp:
        """Build from the JSON layout (already schema-validated)."""
        p = data["wrist"]["position"]
        q = data["wrist"]["orientation"]
        return cls(
            hand=data["hand"],
            eigengrasps=(float(data["eigengrasps"][0]), float(data["eigengrasps"][1])),
            wrist_position=(float(p[0]), float(p[1]), float(p[2])),
            wrist_orientation=(float(q[0]), float(q[1]), float(q[2]), float(q[3])),
            quality=dict(data.get("quality", {})),
        )


@dataclass(frozen=True)
class ObjectRef:
    """O: the object's name and a reference to its model point cloud (sha256 of its Parquet/PLY bytes)."""

    name: str
    model_sha256: str | None = None
    model_points: int = 0
    model_uri: str | None = None

    def to_dict(self) -> Json:
        """JSON-ready dict in the layout of DESCRIPTOR.md."""
        model = None
        if self.model_sha256 is not None:
            model = {"sha256": self.model_sha256, "points": self.model_points, "uri": self.model_uri}
        return {"name": self.name, "model": model}

    @classmethod
    def from_dict(cls, data: Json) -> ObjectRef:
        """Build from the JSON layout (already schema-validated)."""
        model = data.get("model")
        if model is None:
            return cls(name=data["name"])
        return cls(data["name"], model["sha256"], int(model["points"]), model.get("uri"))


@dataclass(frozen=True)
class Descriptor:
    """T = <O, A, G, M, C>; ``id`` is derived from action, object, grasp and chain (see ``content_id``)."""

    name: str
    action: str
    object: ObjectRef
    grasp: Grasp | None
    chain: tuple[Primitive, ...]
    recording_id: str | None = None
    recording_path: str | None = None
    parameters: Json = field(default_factory=dict)
    code_version: str = ""
    parent: str | None = None
    extra_provenance: Json = field(default_factory=dict)

    @property
    def id(self) -> str:
        """Content id: SHA-256 of the canonical JSON of action, object, grasp and chain."""
        return content_id(self)

    def with_grasp(self, grasp: Grasp | None) -> Descriptor:
        """A copy with another grasp."""
        return replace(self, grasp=grasp)

    def to_dict(self) -> Json:
        """The full JSON document, schema-validated."""
        recording = None
        if self.recording_id is not None:
            recording = {"id": self.recording_id, "path": self.recording_path}
        provenance: Json = {
            **self.extra_provenance,
            "recording": recording,
            "parameters": self.parameters,
            "code_version": self.code_version,
            "parent": self.parent,
        }
        doc: Json = {
            "schema": DESCRIPTOR_SCHEMA,
            "name": self.name,
            "id": self.id,
            "action": self.action,
            "object": self.object.to_dict(),
            "grasp": self.grasp.to_dict() if self.grasp is not None else None,
            "chain": [p.to_dict() for p in self.chain],
            "provenance": provenance,
        }
        doc = _round(doc)
        validate(doc, source=self.name)
        return doc

    def to_json(self) -> str:
        """Pretty, key-sorted JSON text (stable bytes for the same content)."""
        return json.dumps(self.to_dict(), indent=2, sort_keys=True) + "\n"

    @classmethod
    def from_dict(cls, doc: Json, source: str = "descriptor") -> Descriptor:
        """Validate ``doc`` against the schema and build; a wrong ``id`` is an error."""
        validate(doc, source=source)
        prov = doc["provenance"]
        rec = prov.get("recording")
        extra = {k: v for k, v in prov.items() if k not in {"recording", "parameters", "code_version", "parent"}}
        out = cls(
            name=doc["name"],
            action=doc["action"],
            object=ObjectRef.from_dict(doc["object"]),
            grasp=Grasp.from_dict(doc["grasp"]) if doc["grasp"] is not None else None,
            chain=tuple(Primitive.from_dict(p) for p in doc["chain"]),
            recording_id=rec["id"] if rec else None,
            recording_path=rec.get("path") if rec else None,
            parameters=dict(prov["parameters"]),
            code_version=prov["code_version"],
            parent=prov["parent"],
            extra_provenance=extra,
        )
        if out.id != doc["id"]:
            msg = f"id {doc['id'][:12]}... does not match its content (expected {out.id[:12]}...)"
            raise DescriptorError(source, msg)
        return out

    @classmethod
    def from_json(cls, text: str, source: str = "descriptor") -> Descriptor:
        """Parse JSON text (at most ``MAX_DESCRIPTOR_BYTES``; no NaN or Infinity), validate and build."""
        if len(text) > MAX_DESCRIPTOR_BYTES:
            msg = f"{len(text)} characters, larger than a descriptor can be ({MAX_DESCRIPTOR_BYTES} bytes)"
            raise DescriptorError(source, msg)
        try:
            doc = json.loads(text, parse_constant=_reject_constant)
        except json.JSONDecodeError as err:
            msg = f"not JSON ({err.msg} at line {err.lineno} column {err.colno})"
            raise DescriptorError(source, msg) from err
        except ValueError as err:  # a NaN or Infinity literal (``_reject_constant``)
            raise DescriptorError(source, str(err)) from err
        except RecursionError as err:
            msg = "JSON nested too deeply to parse"
            raise DescriptorError(source, msg) from err
        if not isinstance(doc, dict):
            raise DescriptorError(source, "not a JSON object")
        return cls.from_dict(doc, source=source)

    @classmethod
    def from_bytes(cls, data: bytes, source: str = "descriptor") -> Descriptor:
        """Decode UTF-8 JSON bytes (at most ``MAX_DESCRIPTOR_BYTES``), validate and build."""
        if len(data) > MAX_DESCRIPTOR_BYTES:
            msg = f"{len(data)} bytes, larger than a descriptor can be ({MAX_DESCRIPTOR_BYTES} bytes)"
            raise DescriptorError(source, msg)
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError as err:
            msg = f"not UTF-8 text (byte {err.start} is {data[err.start : err.start + 1]!r})"
            raise DescriptorError(source, msg) from err
        return cls.from_json(text, source=source)


def _reject_constant(name: str) -> float:
    """``json.loads`` hook for the non-standard literals NaN, Infinity and -Infinity: refuse them."""
    msg = f"non-finite number {name} (descriptor values must be finite)"
    raise ValueError(msg)


def content_id(desc: Descriptor) -> str:
    """SHA-256 hex of the canonical JSON of action, object, grasp and chain."""
    body = {
        "action": desc.action,
        "object": desc.object.to_dict(),
        "grasp": desc.grasp.to_dict() if desc.grasp is not None else None,
        "chain": [p.to_dict() for p in desc.chain],
    }
    return hashlib.sha256(canonical_json(body).encode()).hexdigest()


@cache
def json_schema() -> Json:
    """The descriptor's JSON Schema (``schemas/task-descriptor.schema.json``)."""
    text = resources.files("schemas").joinpath("task-descriptor.schema.json").read_text()
    schema: Json = json.loads(text)
    return schema


def validate(doc: Json, source: str = "descriptor") -> None:
    """Validate a descriptor document against the limits (``schemas.limits``) and the JSON Schema; raise
    ``DescriptorError`` naming the field, what is wrong and the limit."""
    import jsonschema  # noqa: PLC0415 - kept out of CLI start-up

    check_shape(doc, source)
    validator = jsonschema.Draft202012Validator(json_schema())
    errors = sorted(validator.iter_errors(doc), key=lambda e: [str(p) for p in e.path])
    if errors:
        err = errors[0]
        where = clip("/".join(str(p) for p in err.path) or "(top)")
        msg = f"schema {DESCRIPTOR_SCHEMA}: at {where}: {clip(err.message)}"
        raise DescriptorError(source, msg)
    check_values(doc, source)
