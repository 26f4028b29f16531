"""Descriptor limits (``schemas.limits``): each refused with the field, the value and the limit named."""

from __future__ import annotations

import dataclasses
import json
from typing import Any

import pytest

from schemas.descriptor import Descriptor, Primitive
from schemas.errors import DescriptorError as SchemaDescriptorError
from schemas.limits import MAX_DESCRIPTOR_BYTES, clip
from tasks.errors import DescriptorError, PbdError
from tests.foundation.test_descriptor import make_descriptor


def _doc(**changes: Any) -> dict[str, Any]:
    doc: dict[str, Any] = json.loads(make_descriptor().to_json())
    for dotted, value in changes.items():
        keys = [int(k) if k.isdigit() else k for k in dotted.split("__")]
        parent = doc
        for key in keys[:-1]:
            parent = parent[key]
        parent[keys[-1]] = value
    return doc


def test_the_contract_error_is_the_one_the_cli_catches() -> None:
    assert DescriptorError is SchemaDescriptorError
    assert issubclass(DescriptorError, PbdError)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"name": "n" * 201}, r"name of 201 characters \(limit 200\)"),
        ({"chain": [_doc()["chain"][1]] * 257}, r"chain of 257 primitives \(limit 256\)"),
        ({"chain__0__markers": ["/m"] * 300}, r"chain/0/markers: array of 300 items \(limit 256\)"),
        ({"chain__0__fit": {"a": json.loads("[" * 40 + "]" * 40)}}, r"JSON nested deeper than 32 levels \(at chain/0/"),
        ({"chain__1__dir": [0.0, 0.0, 0.0]}, r"chain/1/dir: must be a unit vector, norm is 0 \(tolerance 0.001\)"),
        ({"chain__1__dir": [0.0, 2.0, 0.0]}, r"chain/1/dir: must be a unit vector, norm is 2 "),
        ({"chain__0__pos": [0.0, 1e6, 0.0]}, r"chain/0/pos: coordinate 1e\+06 m beyond 100 m"),
        ({"chain__0__extent": 40.0}, r"chain/0/extent: 40 rad beyond 31.42 rad"),
        ({"chain__1__extent": 1e308}, r"chain/1/extent: 1e\+308 m beyond 5 m"),
        ({"grasp__wrist__position": [0.0, 0.0, -500.0]}, r"grasp/wrist/position: coordinate 500 m beyond 100 m"),
        ({"grasp__wrist__orientation": [0.0, 0.0, 0.0, 0.0]}, r"grasp/wrist/orientation: must be a unit vector"),
    ],
)
def test_values_beyond_the_limits_are_refused(changes: dict[str, Any], message: str) -> None:
    with pytest.raises(DescriptorError, match=message):
        Descriptor.from_dict(_doc(**changes), source="x.json")


def test_limits_hold_for_descriptors_built_in_memory() -> None:
    desc = make_descriptor()
    bad = dataclasses.replace(desc, chain=(Primitive("rotation", (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 1e6),))
    with pytest.raises(DescriptorError, match=r"chain/0/extent: 1e\+06 rad beyond 31.42 rad"):
        bad.to_json()


def test_text_that_cannot_be_a_descriptor() -> None:
    text = make_descriptor().to_json()
    with pytest.raises(DescriptorError, match=r"x.json: 1048577 bytes, larger than a descriptor can be"):
        Descriptor.from_bytes(b" " * (MAX_DESCRIPTOR_BYTES + 1), source="x.json")
    with pytest.raises(DescriptorError, match=r"characters, larger than a descriptor can be \(1048576 bytes\)"):
        Descriptor.from_json(" " * (MAX_DESCRIPTOR_BYTES + 1))
    with pytest.raises(DescriptorError, match=r"not UTF-8 text \(byte 0 is b'\\xff'\)"):
        Descriptor.from_bytes(text.encode("utf-16"))
    with pytest.raises(DescriptorError, match=r"non-finite number NaN \(descriptor values must be finite\)"):
        Descriptor.from_json(text.replace('"extent": 0.3', '"extent": NaN'))
    with pytest.raises(DescriptorError, match="JSON nested too deeply to parse"):
        Descriptor.from_json("[" * 100_000 + "]" * 100_000)
    schema_error = r"schema pbd.task-descriptor/1: at grasp: \{'eigengrasps': \[0.1, 0.1[0-9., ]{0,160}\.\.\.$"
    doc = _doc(grasp__eigengrasps=[0.1] * 200)  # within the array limit, wrong for the schema: the message is cut
    with pytest.raises(DescriptorError, match=schema_error):
        Descriptor.from_dict(doc)


def test_clip_folds_lines_and_cuts() -> None:
    assert clip("a\n  b\tc") == "a b c"
    assert clip("x" * 500, 10) == "xxxxxxx..."
