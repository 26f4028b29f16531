"""Compare two descriptors: primitives added or removed (aligned by kind in chain order), axis angle change
(degrees), axis offset (mm, point to line), extent change (rad or m), grasp change, and renamed fields."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from schemas.descriptor import Descriptor, Grasp, Primitive
from tasks.arrays import FloatArray


@dataclass(frozen=True)
class Tolerances:
    """Below these a change does not count (degrees, millimetres, extent units, eigengrasp amplitude)."""

    angle_deg: float = 0.01
    offset_mm: float = 0.01
    extent: float = 1e-6
    eigengrasp: float = 1e-6


@dataclass(frozen=True)
class PrimitiveChange:
    """A matched pair of primitives (index in A, index in B) and how they differ."""

    index_a: int
    index_b: int
    kind: str
    axis_angle_deg: float
    axis_offset_mm: float | None
    extent_change: float
    extent_unit: str

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {
            "index_a": self.index_a,
            "index_b": self.index_b,
            "kind": self.kind,
            "axis_angle_deg": self.axis_angle_deg,
            "axis_offset_mm": self.axis_offset_mm,
            "extent_change": self.extent_change,
            "extent_unit": self.extent_unit,
        }


@dataclass(frozen=True)
class DescriptorDiff:
    """The whole comparison; ``same`` when nothing changed beyond the tolerances."""

    a: dict[str, str]
    b: dict[str, str]
    removed: tuple[dict[str, Any], ...]
    added: tuple[dict[str, Any], ...]
    changed: tuple[PrimitiveChange, ...]
    grasp: dict[str, Any] | None
    fields: dict[str, list[str]] = field(default_factory=dict)
    same: bool = True

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {
            "same": self.same,
            "a": self.a,
            "b": self.b,
            "removed": list(self.removed),
            "added": list(self.added),
            "changed": [c.to_dict() for c in self.changed],
            "grasp": self.grasp,
            "fields": self.fields,
        }


def _align(a: tuple[Primitive, ...], b: tuple[Primitive, ...]) -> list[tuple[int, int]]:
    """Longest common subsequence of the chains' kinds: the matched (index_a, index_b) pairs."""
    n, m = len(a), len(b)
    table = np.zeros((n + 1, m + 1), dtype=np.int64)
    for i in range(n - 1, -1, -1):
        for j in range(m - 1, -1, -1):
            if a[i].kind == b[j].kind:
                table[i, j] = table[i + 1, j + 1] + 1
            else:
                table[i, j] = max(table[i + 1, j], table[i, j + 1])
    pairs = []
    i = j = 0
    while i < n and j < m:
        if a[i].kind == b[j].kind:
            pairs.append((i, j))
            i += 1
            j += 1
        elif table[i + 1, j] >= table[i, j + 1]:
            i += 1
        else:
            j += 1
    return pairs


def _summary(p: Primitive, index: int) -> dict[str, Any]:
    return {
        "index": index,
        "kind": p.kind,
        "dir": list(p.dir),
        "pos": list(p.pos) if p.pos else None,
        "extent": p.extent,
    }


def _unit(v: tuple[float, ...]) -> FloatArray | None:
    """``v`` scaled to length 1, or None when it has no direction (zero length, NaN or infinite entries)."""
    arr = np.asarray(v, dtype=np.float64)
    norm = float(np.linalg.norm(arr))
    if not (np.isfinite(arr).all() and np.isfinite(norm) and norm > 0.0):
        return None
    out: FloatArray = arr / norm
    return out


def compare_primitives(pa: Primitive, pb: Primitive, ia: int, ib: int) -> PrimitiveChange:
    """Axis angle (deg), axis offset (mm: B's axis point to A's axis line; rotations only) and extent change.

    An axis without a direction (zero, NaN or infinite) gives NaN figures, which count as a change.
    """
    ua, ub = _unit(pa.dir), _unit(pb.dir)
    angle = math.nan
    if ua is not None and ub is not None:
        angle = float(np.degrees(np.arccos(np.clip(float(np.dot(ua, ub)), -1.0, 1.0))))
    offset = None
    if pa.kind == "rotation" and pa.pos is not None and pb.pos is not None:
        offset = math.nan
        if ua is not None:
            w = np.asarray(pb.pos, dtype=np.float64) - np.asarray(pa.pos, dtype=np.float64)
            offset = float(np.linalg.norm(w - np.dot(w, ua) * ua) * 1000.0)
    unit = "rad" if pa.kind == "rotation" else "m"
    return PrimitiveChange(ia, ib, pa.kind, angle, offset, float(pb.extent - pa.extent), unit)


def _beyond(value: float, tolerance: float) -> bool:
    """True when ``value`` exceeds ``tolerance`` or is NaN (a figure that cannot be computed is a change)."""
    return not value <= tolerance


def _grasp_change(ga: Grasp | None, gb: Grasp | None, tol: Tolerances) -> tuple[dict[str, Any] | None, bool]:
    """(description, changed) of the grasp."""
    if ga is None and gb is None:
        return None, False
    if ga is None or gb is None:
        return {"change": "added" if ga is None else "removed"}, True
    d_eig = [float(y - x) for x, y in zip(ga.eigengrasps, gb.eigengrasps, strict=True)]
    d_pos = float(np.linalg.norm(np.subtract(gb.wrist_position, ga.wrist_position)) * 1000.0)
    qa, qb = _unit(ga.wrist_orientation), _unit(gb.wrist_orientation)
    d_rot = math.nan
    if qa is not None and qb is not None:
        d_rot = float(np.degrees(2.0 * np.arccos(np.clip(abs(float(np.dot(qa, qb))), 0.0, 1.0))))
    changed = (
        any(_beyond(abs(x), tol.eigengrasp) for x in d_eig)
        or _beyond(d_pos, tol.offset_mm)
        or _beyond(d_rot, tol.angle_deg)
        or ga.hand != gb.hand
    )
    desc = {"change": "changed" if changed else "same", "eigengrasps": d_eig, "wrist_offset_mm": d_pos}
    desc["wrist_angle_deg"] = d_rot
    return desc, changed


def diff_descriptors(a: Descriptor, b: Descriptor, tol: Tolerances | None = None) -> DescriptorDiff:
    """Compare descriptor ``a`` (old) with ``b`` (new)."""
    tol = tol or Tolerances()
    pairs = _align(a.chain, b.chain)
    matched_a = {i for i, _ in pairs}
    matched_b = {j for _, j in pairs}
    removed = tuple(_summary(p, i) for i, p in enumerate(a.chain) if i not in matched_a)
    added = tuple(_summary(p, j) for j, p in enumerate(b.chain) if j not in matched_b)
    changes = [compare_primitives(a.chain[i], b.chain[j], i, j) for i, j in pairs]
    significant = tuple(
        c
        for c in changes
        if _beyond(c.axis_angle_deg, tol.angle_deg)
        or (c.axis_offset_mm is not None and _beyond(c.axis_offset_mm, tol.offset_mm))
        or _beyond(abs(c.extent_change), tol.extent)
    )
    grasp, grasp_changed = _grasp_change(a.grasp, b.grasp, tol)
    fields = {}
    for key, va, vb in (
        ("name", a.name, b.name),
        ("action", a.action, b.action),
        ("object", a.object.name, b.object.name),
    ):
        if va != vb:
            fields[key] = [va, vb]
    if a.object.model_sha256 != b.object.model_sha256:
        fields["object_model"] = [str(a.object.model_sha256), str(b.object.model_sha256)]
    same = not (removed or added or significant or grasp_changed or any(k != "name" for k in fields))
    return DescriptorDiff(
        a={"name": a.name, "id": a.id},
        b={"name": b.name, "id": b.id},
        removed=removed,
        added=added,
        changed=significant,
        grasp=grasp,
        fields=fields,
        same=same,
    )


def format_diff(d: DescriptorDiff) -> list[str]:
    """The diff in words, one line per change."""
    head = f"{d.a['name']} {d.a['id'][:12]} -> {d.b['name']} {d.b['id'][:12]}: " + ("same" if d.same else "different")
    lines = [head]
    for key, (va, vb) in d.fields.items():
        lines.append(f"  {key}: {va} -> {vb}")
    for r in d.removed:
        lines.append(f"  removed primitive {r['index']}: {r['kind']} extent {r['extent']:.4g}")
    for r in d.added:
        lines.append(f"  added primitive {r['index']}: {r['kind']} extent {r['extent']:.4g}")
    for c in d.changed:
        off = f", axis offset {c.axis_offset_mm:.3f} mm" if c.axis_offset_mm is not None else ""
        lines.append(
            f"  {c.kind} {c.index_a}->{c.index_b}: axis angle {c.axis_angle_deg:.3f} deg{off}, "
            f"extent {c.extent_change:+.4g} {c.extent_unit}"
        )
    if d.grasp is not None and d.grasp.get("change") != "same":
        g = d.grasp
        if "wrist_offset_mm" in g:
            eig = ", ".join(f"{x:+.3g}" for x in g["eigengrasps"])
            wrist = f"wrist {g['wrist_offset_mm']:.2f} mm, {g['wrist_angle_deg']:.2f} deg"
            lines.append(f"  grasp changed: eigengrasps {eig}, {wrist}")
        else:
            lines.append(f"  grasp {g['change']}")
    return lines
