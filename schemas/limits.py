"""Limits a task descriptor must stay within, checked before any work starts (``../shared/DESCRIPTOR.md``).

``check_shape`` runs on the parsed JSON before the JSON Schema, so a crafted file cannot make validation or
anything after it slow; ``check_values`` runs after the schema on the numbers a mechanism could have. Every
error names the field, the value found and the limit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from schemas.errors import DescriptorError

MAX_DESCRIPTOR_BYTES = 1 << 20
"""Largest descriptor file read: a chain of ``MAX_PRIMITIVES`` primitives with their fit summaries is tens of KB."""
MAX_PRIMITIVES = 256
"""Primitives in a chain: a door swung open and shut every two seconds for ten minutes of recording (the longest
demonstration archives hold) gives about 260 at most; a descriptor of that many is a few hundred KB."""
MAX_ARRAY_ITEMS = 256
"""Items in any JSON array: the longest of the layout is a primitive's marker names, and a motion-capture rig on
one object tracks at most a few hundred markers."""
MAX_DEPTH = 32
"""Nesting of JSON containers: the layout nests five levels; free-form ``fit`` and ``parameters`` a few more."""
MAX_NAME_CHARS = 200
"""Descriptor name length: it is a folder name, and file systems allow 255 bytes with room for suffixes."""
MAX_ROTATION_RAD = 10.0 * math.pi
"""Rotation extent: a hand-turned mechanism (a jar lid, a valve, a knob) takes at most a few turns; five here."""
MAX_TRANSLATION_M = 5.0
"""Translation extent: a person standing at an object moves a part (a drawer, a sliding door) at most a few metres."""
MAX_POSITION_M = 100.0
"""Axis points and wrist positions: a capture volume or robot cell is at most tens of metres across."""
UNIT_TOLERANCE = 1e-3
"""Allowed departure of an axis or quaternion norm from 1: covers hand-written files with three or four decimals."""
MAX_MESSAGE_CHARS = 160
"""Longest piece of a value quoted in an error, so an error stays one short line whatever the input."""


def clip(text: str, limit: int = MAX_MESSAGE_CHARS) -> str:
    """``text`` cut to ``limit`` characters (an ellipsis marks the cut), newlines folded into spaces."""
    flat = " ".join(text.split())
    return flat if len(flat) <= limit else flat[: limit - 3] + "..."


def _walk(doc: Any, source: str) -> None:
    """Nesting within ``MAX_DEPTH`` and arrays within ``MAX_ARRAY_ITEMS``, checked without recursion (a crafted
    file may nest thousands deep)."""
    stack: list[tuple[Any, tuple[str, ...]]] = [(doc, ())]
    while stack:
        value, where = stack.pop()
        if not isinstance(value, dict | list):
            continue
        if len(where) >= MAX_DEPTH:
            msg = f"JSON nested deeper than {MAX_DEPTH} levels (at {clip('/'.join(where[:4]))}/...)"
            raise DescriptorError(source, msg)
        if isinstance(value, list) and len(value) > MAX_ARRAY_ITEMS:
            msg = f"{clip('/'.join(where))}: array of {len(value)} items (limit {MAX_ARRAY_ITEMS})"
            raise DescriptorError(source, msg)
        items = value.items() if isinstance(value, dict) else enumerate(value)
        stack.extend((child, (*where, str(key))) for key, child in items)


def check_shape(doc: dict[str, Any], source: str) -> None:
    """Counts and nesting of a parsed descriptor within the limits (before the JSON Schema)."""
    name = doc.get("name")
    if isinstance(name, str) and len(name) > MAX_NAME_CHARS:
        msg = f"name of {len(name)} characters (limit {MAX_NAME_CHARS})"
        raise DescriptorError(source, msg)
    chain = doc.get("chain")
    if isinstance(chain, list) and len(chain) > MAX_PRIMITIVES:
        msg = f"chain of {len(chain)} primitives (limit {MAX_PRIMITIVES})"
        raise DescriptorError(source, msg)
    _walk(doc, source)


def _unit(values: Sequence[float], where: str, source: str) -> None:
    norm = math.sqrt(math.fsum(float(v) * float(v) for v in values))
    if not abs(norm - 1.0) <= UNIT_TOLERANCE:
        msg = f"{where}: must be a unit vector, norm is {norm:.6g} (tolerance {UNIT_TOLERANCE})"
        raise DescriptorError(source, msg)


def _position(values: Sequence[float], where: str, source: str) -> None:
    big = max(abs(float(v)) for v in values)
    if not big <= MAX_POSITION_M:
        msg = f"{where}: coordinate {big:.6g} m beyond {MAX_POSITION_M:g} m"
        raise DescriptorError(source, msg)


def check_values(doc: dict[str, Any], source: str) -> None:
    """Axes, extents, positions and quaternions of a schema-valid descriptor within what a mechanism could have."""
    for i, prim in enumerate(doc["chain"]):
        where = f"chain/{i}"
        _unit(prim["dir"], f"{where}/dir", source)
        if prim["pos"] is not None:
            _position(prim["pos"], f"{where}/pos", source)
        extent = float(prim["extent"])
        rotation = prim["kind"] == "rotation"
        limit, unit = (MAX_ROTATION_RAD, "rad") if rotation else (MAX_TRANSLATION_M, "m")
        if not extent <= limit:
            msg = f"{where}/extent: {extent:.6g} {unit} beyond {limit:.4g} {unit}"
            raise DescriptorError(source, msg)
    grasp = doc["grasp"]
    if grasp is not None:
        _position(grasp["wrist"]["position"], "grasp/wrist/position", source)
        _unit(grasp["wrist"]["orientation"], "grasp/wrist/orientation", source)
