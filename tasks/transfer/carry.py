"""Carry a descriptor's chain and grasp across a similarity transform (source object frame -> target frame).

Axis points move as points (x' = s R x + t), directions as directions (R d, renormalised), translation
extents scale by s, rotation extents (radians) are kept; the wrist pose turns by R and its position moves as
a point. Nothing here reads files or prints.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from schemas.descriptor import Descriptor, Grasp, Primitive, Vec3
from tasks.arrays import Points, Vector3
from tasks.rotations import matrix_from_quat, quat_tuple_from_matrix
from tasks.transfer.similarity import Similarity, angle_between_deg, point_line_distance


def _vec3(v: Vector3) -> Vec3:
    return (float(v[0]), float(v[1]), float(v[2]))


def carry_primitive(prim: Primitive, transform: Similarity) -> Primitive:
    """One primitive in the target frame: pos as a point, dir as a direction, translation extent scaled."""
    pos = _vec3(transform.apply_point(np.asarray(prim.pos))) if prim.pos is not None else None
    direction = _vec3(transform.apply_direction(np.asarray(prim.dir)))
    extent = prim.extent * transform.scale if prim.kind == "translation" else prim.extent
    return replace(prim, pos=pos, dir=direction, extent=extent)


def carry_grasp(grasp: Grasp, transform: Similarity, anchor: Vector3 | None = None) -> Grasp:
    """The grasp in the target frame: orientation turned by the rotation part; the wrist position as a point,
    or, given the grasped part's ``anchor`` point (source frame, metres), at the carried anchor plus the turned
    but unscaled wrist offset: the hand does not grow with the object (a palm 80 mm above a cap stays 80 mm
    above the carried cap, where scaling the offset would push the fingers past a small cap onto the neck)."""
    wrist = np.asarray(grasp.wrist_position, dtype=np.float64)
    if anchor is None:
        position = transform.apply_point(wrist)
    else:
        position = transform.apply_point(anchor) + transform.rotation @ (wrist - anchor)
    rotation = transform.rotation @ matrix_from_quat(grasp.wrist_orientation)
    return replace(grasp, wrist_position=_vec3(position), wrist_orientation=quat_tuple_from_matrix(rotation))


def carry_chain(chain: tuple[Primitive, ...], transform: Similarity) -> tuple[Primitive, ...]:
    """Every primitive of a chain carried by ``transform``."""
    return tuple(carry_primitive(p, transform) for p in chain)


def focus_points(desc: Descriptor, model: Points) -> Points:
    """The functional part's centres on the source model: the model points nearest to the wrist position and
    to each rotation axis point (metres, source frame); (0, 3) when the descriptor has neither."""
    seeds: list[Vector3] = [np.asarray(p.pos) for p in desc.chain if p.pos is not None]
    if desc.grasp is not None:
        seeds.append(np.asarray(desc.grasp.wrist_position))
    if not seeds:
        return np.zeros((0, 3))
    out = []
    for seed in seeds:
        d2 = ((model - seed) ** 2).sum(axis=1)
        out.append(model[int(np.argmin(d2))])
    return np.array(out, dtype=np.float64)


def standoff_m(wrist: Vector3, approach: Vector3, model: Points, radius_m: float) -> float | None:
    """Distance (metres) from the palm at ``wrist`` along its unit ``approach`` to the first model surface point
    within ``radius_m`` of that ray; None when the ray meets no surface."""
    rel = model - wrist
    along = rel @ approach
    lateral = np.linalg.norm(rel - along[:, None] * approach, axis=1)
    hit = (along > 0.0) & (lateral <= radius_m)
    return float(along[hit].min()) if hit.any() else None


def keep_standoff(grasp: Grasp, source_grasp: Grasp, source: Points, target: Points, radius_m: float) -> Grasp:
    """The carried ``grasp`` moved along its approach so the palm stands off the target's surface it faces as
    far as the source palm stood off the source's (metres): the hand keeps its size when the object does not
    scale uniformly (a taller cap, a thicker handle). Unchanged when either ray meets no surface."""

    def approach(g: Grasp) -> Vector3:
        out: Vector3 = matrix_from_quat(g.wrist_orientation)[:, 2]  # Barrett palm frame: +z is the approach
        return out

    before = standoff_m(np.asarray(source_grasp.wrist_position), approach(source_grasp), source, radius_m)
    wrist, towards = np.asarray(grasp.wrist_position), approach(grasp)
    after = standoff_m(wrist, towards, target, radius_m)
    if before is None or after is None:
        return grasp
    return replace(grasp, wrist_position=_vec3(wrist + (after - before) * towards))


def grip_points(desc: Descriptor, model: Points) -> Points:
    """The grasped part's centre on the source model: the model point nearest the wrist position (metres,
    source frame), (1, 3); (0, 3) when the descriptor has no grasp."""
    if desc.grasp is None:
        return np.zeros((0, 3))
    d2 = ((model - np.asarray(desc.grasp.wrist_position)) ** 2).sum(axis=1)
    return np.array([model[int(np.argmin(d2))]], dtype=np.float64)


def axis_spread(
    chain: tuple[Primitive, ...],
    best: Similarity | tuple[Similarity, ...],
    others: list[Similarity] | list[tuple[Similarity, ...]],
) -> tuple[float, float]:
    """Largest change of any carried axis between ``best`` and ``others`` (each one transform, or one per
    primitive): (degrees, metres point to line)."""

    def per_primitive(t: Similarity | tuple[Similarity, ...]) -> tuple[Similarity, ...]:
        return t if isinstance(t, tuple) else (t,) * len(chain)

    worst_deg, worst_m = 0.0, 0.0
    ref_transforms = per_primitive(best)
    for other in others:
        for prim, ref_t, alt_t in zip(chain, ref_transforms, per_primitive(other), strict=True):
            ref, alt = carry_primitive(prim, ref_t), carry_primitive(prim, alt_t)
            worst_deg = max(worst_deg, angle_between_deg(np.asarray(ref.dir), np.asarray(alt.dir)))
            if ref.pos is not None and alt.pos is not None:
                dist = point_line_distance(np.asarray(alt.pos), np.asarray(ref.pos), np.asarray(ref.dir))
                worst_m = max(worst_m, dist)
    return worst_deg, worst_m
