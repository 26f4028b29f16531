"""The old and new values behind a descriptor diff: each matched primitive's extent, axis direction and point,
the grasp (wrist, eigengrasps, quality) and the parameters of provenance that differ (metres, radians)."""

from __future__ import annotations

from typing import Any

from schemas.descriptor import Descriptor, Grasp
from tasks.diff.core import DescriptorDiff

PROVENANCE_KEYS = ("seed", "scene")
"""Provenance entries besides ``parameters`` whose change changes the result."""


def _vec(v: Any) -> str:
    return "-" if v is None else "[" + ", ".join(f"{float(x):.4f}" for x in v) + "]"


def _pos(pos: tuple[float, float, float] | None) -> list[float] | None:
    return None if pos is None else list(pos)


def _grasp_values(g: Grasp | None) -> dict[str, Any] | None:
    if g is None:
        return None
    return {
        "eigengrasps": list(g.eigengrasps),
        "wrist_position": list(g.wrist_position),
        "wrist_orientation": list(g.wrist_orientation),
        "quality": dict(g.quality),
    }


def changed_values(a: Descriptor, b: Descriptor, d: DescriptorDiff) -> dict[str, Any]:
    """JSON-ready old and new values of what ``d`` (``diff_descriptors(a, b)``) found changed, the grasps'
    qualities and every learning parameter or result-changing provenance entry that differs."""
    primitives = [
        {
            "index_a": c.index_a,
            "index_b": c.index_b,
            "kind": c.kind,
            "extent": [a.chain[c.index_a].extent, b.chain[c.index_b].extent],
            "dir": [list(a.chain[c.index_a].dir), list(b.chain[c.index_b].dir)],
            "pos": [_pos(a.chain[c.index_a].pos), _pos(b.chain[c.index_b].pos)],
        }
        for c in d.changed
    ]
    keys = sorted(set(a.parameters) | set(b.parameters))
    params = {k: [a.parameters.get(k), b.parameters.get(k)] for k in keys if a.parameters.get(k) != b.parameters.get(k)}
    for k in PROVENANCE_KEYS:
        va, vb = a.extra_provenance.get(k), b.extra_provenance.get(k)
        if va != vb:
            params[k] = [va, vb]
    return {"primitives": primitives, "grasp": [_grasp_values(a.grasp), _grasp_values(b.grasp)], "parameters": params}


def format_values(values: dict[str, Any]) -> list[str]:
    """The old -> new values in words, one line each (after ``tasks.diff.core.format_diff``'s lines)."""
    lines = []
    for p in values["primitives"]:
        unit = "rad" if p["kind"] == "rotation" else "m"
        (ea, eb), (da, db), (pa, pb) = p["extent"], p["dir"], p["pos"]
        lines.append(f"  {p['kind']} {p['index_a']}->{p['index_b']}: extent {ea:.4f} -> {eb:.4f} {unit}")
        lines.append(f"    dir {_vec(da)} -> {_vec(db)}")
        if pa is not None or pb is not None:
            lines.append(f"    pos {_vec(pa)} -> {_vec(pb)} m")
    ga, gb = values["grasp"]
    if ga != gb:
        if ga is None or gb is None:
            lines.append(f"  grasp: {'none' if ga is None else 'planned'} -> {'none' if gb is None else 'planned'}")
        else:
            lines.append(f"  grasp wrist {_vec(ga['wrist_position'])} -> {_vec(gb['wrist_position'])} m")
            lines.append(f"  grasp eigengrasps {_vec(ga['eigengrasps'])} -> {_vec(gb['eigengrasps'])}")
            for key in sorted(set(ga["quality"]) | set(gb["quality"])):
                qa, qb = ga["quality"].get(key), gb["quality"].get(key)
                lines.append(f"  grasp quality {key}: {qa} -> {qb}")
    for key, (va, vb) in values["parameters"].items():
        lines.append(f"  parameter {key}: {va} -> {vb}")
    return lines
