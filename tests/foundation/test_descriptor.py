"""The descriptor dataclasses, canonical JSON, content id and JSON Schema validation."""

from __future__ import annotations

import json

import pytest

from schemas.descriptor import Descriptor, Grasp, ObjectRef, Primitive, canonical_json
from tasks.errors import DescriptorError


def make_descriptor(extent: float = 0.76, name: str = "open-microwave") -> Descriptor:
    """A small valid descriptor with one rotation and one translation."""
    return Descriptor(
        name=name,
        action="open",
        object=ObjectRef("microwave", "a" * 64, 4096, None),
        grasp=Grasp("barrett", (0.41, -0.12), (0.1, 0.2, 0.3), (0.0, 0.0, 0.0, 1.0), {"epsilon": 0.08}),
        chain=(
            Primitive("rotation", (0.52, 0.02, 1.33), (-0.97, -0.03, 0.24), extent, 1.02, 2.2, ("/m0",)),
            Primitive("translation", None, (0.0, 1.0, 0.0), 0.30),
        ),
        recording_id="0123456789abcdef",
        parameters={"k": "auto", "t0": 0.05},
        code_version="abc",
    )


def test_round_trip_keeps_content_and_id() -> None:
    desc = make_descriptor()
    back = Descriptor.from_json(desc.to_json())
    assert back == desc
    assert back.id == desc.id


def test_id_ignores_provenance_but_not_chain() -> None:
    a = make_descriptor()
    b = Descriptor(**{**a.__dict__, "parameters": {"k": 3}})
    c = make_descriptor(extent=0.77)
    assert a.id == b.id
    assert a.id != c.id


def test_canonical_json_rounds_last_bits() -> None:
    assert canonical_json({"b": 0.1 + 0.2, "a": -0.0}) == canonical_json({"a": 0.0, "b": 0.3})


def test_tampered_id_is_rejected() -> None:
    doc = make_descriptor().to_dict()
    doc["id"] = "0" * 64
    with pytest.raises(DescriptorError, match="does not match its content"):
        Descriptor.from_dict(doc, source="x.json")


def test_negative_extent_fails_schema() -> None:
    doc = make_descriptor().to_dict()
    doc["chain"][0]["extent"] = -1.0
    with pytest.raises(DescriptorError, match=r"at chain/0/extent"):
        Descriptor.from_dict(doc, source="x.json")


def test_rotation_without_pos_fails_schema() -> None:
    doc = make_descriptor().to_dict()
    doc["chain"][0]["pos"] = None
    with pytest.raises(DescriptorError, match="chain/0/pos"):
        Descriptor.from_dict(doc)


def test_not_json_names_source() -> None:
    with pytest.raises(DescriptorError, match=r"bad\.json: not JSON"):
        Descriptor.from_json("{", source="bad.json")
    with pytest.raises(DescriptorError, match="not a JSON object"):
        Descriptor.from_json(json.dumps([1]), source="bad.json")


def test_nan_is_rejected() -> None:
    with pytest.raises(DescriptorError, match="non-finite"):
        make_descriptor(extent=float("nan")).to_json()
