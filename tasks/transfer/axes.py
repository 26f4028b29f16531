"""Placing each carried axis after the global registration: symmetry snap and per-axis local check.

The global similarity carries every primitive first. Then, per primitive with an axis point (source frame):

1. A rotation whose source region is a body of revolution about its own axis (a cap: the symmetry fit on the
   source finds its axis within ``SYMMETRIC_OFFSET_FRAC`` of the region radius) is moved across onto the target
   region's symmetry axis (``symmetry_axis``, fitted to the body's sides), when that lies within ``MAX_SNAP_FRAC``
   of the radius; the primitive's transform is then the global one translated by that move, and the symmetry fit's
   covariance is the axis point's sigma. When the whole body about the axis is one of revolution too (its axis,
   tilt fitted, within the same fraction of the region radius of the demonstrated one at both ends of the body,
   beyond what the demonstrated direction's own sigma moves it there: a bottle under its cap), the direction is
   first turned onto the target body's fitted axis (``symmetry_axis.fit_symmetry_line``), within
   ``MAX_SNAP_TURN_DEG``, and that fit's sigma is the direction's.
2. The local check (``local_refine``) looks at the axis under that transform and warns when the target about
   it is not explained or the region's own refinement disagrees; a snapped axis is not judged by it (two
   bottles of other proportions explain only 0.4-0.7 of each other about a correctly placed cap axis).

The grasp is carried by the transform of the first primitive whose axis passes within reach of the grasped part
(the cap's turn carries the hand on the cap), else by the global one. Lengths in metres.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from schemas.descriptor import Primitive
from tasks.arrays import Points
from tasks.transfer.carry import axis_spread
from tasks.transfer.clouds import median_spacing
from tasks.transfer.local_refine import LocalCheck, LocalParams, check_axis, region_size
from tasks.transfer.registration import surface_normals
from tasks.transfer.similarity import Similarity, angle_between_deg, point_line_distance, rotation_onto
from tasks.transfer.symmetry_axis import SymmetryFit, fit_symmetry_axis, fit_symmetry_line
from tasks.transfer.uncertainty import fit_number

SYMMETRIC_OFFSET_FRAC = 0.01
"""The source region is a body of revolution when its fitted symmetry axis lies within 1 % of the region radius
of the demonstrated axis: bottle caps 0.01-0.25 mm of 30-40 mm; jar lids (0.5-2.6 mm of about 18 mm), mugs,
cabinet and microwave hinges and door levers stay out (translations are never moved)."""
MAX_SNAP_FRAC = 0.5
"""The target's symmetry axis is used only within half the region radius of the carried axis."""
SNAP_ROUNDS = 3
"""Symmetry fits on the target, each about the previous one's axis."""
LOSS_SPACINGS = 0.5
"""Soft-L1 scale of the symmetry fit: half the source's median point spacing (at least 0.5 mm)."""
BODY_RADIUS_FRAC = 2.0
"""The body under a symmetric region is sought within twice the region radius of the axis (a bottle's body is
wider than its cap); points of other parts within it lie on no slice's circle and fall to the soft-L1 loss."""
LEARNED_SIGMAS = 3.0
"""The demonstrated direction may be off by three of its own sigmas (``fit.dir_std_rad``): along a body 0.3 m long
a learned direction 0.1 degrees off lies 0.5 mm from the body's axis at its far end."""
MAX_SNAP_TURN_DEG = 3.0
"""The target body's axis turns the carried direction by at most the transferred axis's worst-case tolerance:
a larger turn means the registration or the fit is wrong, and either way the body's axis does not place it."""


@dataclass(frozen=True)
class PlacedAxes:
    """One transform per primitive (source -> target) and what placing the axes found."""

    transforms: tuple[Similarity, ...]
    snapped_m: tuple[float, ...]
    """How far each axis was moved onto the target's symmetry axis, metres (0: not moved)."""
    symmetry: tuple[SymmetryFit | None, ...]
    """Per primitive: the target's symmetry fit that placed its axis (None: not moved onto one)."""
    checks: tuple[LocalCheck, ...]
    grasp_transform: Similarity
    warnings: tuple[str, ...]
    normals: CloudNormals


@dataclass(frozen=True)
class Snap:
    """A carried axis moved onto the target's symmetry axis: the moved transform and the fit that placed it."""

    transform: Similarity
    fit: SymmetryFit


@dataclass(frozen=True)
class CloudNormals:
    """Unit surface normals (any sign) of the source and of the target cloud, one per point."""

    source: Points
    target: Points

    @classmethod
    def of(cls, source: Points, target: Points, target_spacing_m: float) -> CloudNormals:
        """Normals estimated at each cloud's point spacing (the target's given, metres)."""
        return cls(surface_normals(source, median_spacing(source)), surface_normals(target, target_spacing_m))


def _snap(
    prim: Primitive, source: Points, target: Points, *, normals: CloudNormals, best: Similarity, radius: float
) -> Snap | None:
    """``best`` translated so the carried axis lies on the target's symmetry axis, or None."""
    if prim.kind != "rotation" or prim.pos is None:
        return None
    pos = np.asarray(prim.pos, dtype=np.float64)
    direction = np.asarray(prim.dir, dtype=np.float64)
    direction = direction / np.linalg.norm(direction)
    loss = max(5e-4, LOSS_SPACINGS * median_spacing(source))
    own = fit_symmetry_axis(source, normals.source, pos, direction, radius, loss_scale_m=loss)
    if own is None or own.offset_m > SYMMETRIC_OFFSET_FRAC * radius:
        return None
    carried, carried_dir = best.apply_point(pos), best.apply_direction(direction)
    slack = LEARNED_SIGMAS * (fit_number(prim.fit, "dir_std_rad") or 0.0)
    body = _body_axis(
        source, target, normals=normals, best=best, line=(pos, direction), radius=radius, loss=loss, slack_rad=slack
    )
    axis_dir = carried_dir if body is None else body.direction
    centre = carried
    fitted: SymmetryFit | None = None
    for _ in range(SNAP_ROUNDS):  # the region about a misplaced axis cuts the part unevenly: fit again about the fit
        fitted = fit_symmetry_axis(
            target, normals.target, centre, axis_dir, radius * best.scale, loss_scale_m=loss * best.scale
        )
        if fitted is None:
            return None
        centre = fitted.pos
    if fitted is None or float(np.linalg.norm(centre - carried)) > MAX_SNAP_FRAC * radius * best.scale:
        return None
    turned = best
    if body is not None:
        fitted = replace(fitted, dir_std_rad=body.dir_std_rad)
        turn = rotation_onto(carried_dir, axis_dir)
        turned = Similarity(best.scale, turn @ best.rotation, carried - turn @ (carried - best.translation))
    return Snap(Similarity(turned.scale, turned.rotation, turned.translation + (centre - carried)), fitted)


def _body_axis(
    source: Points,
    target: Points,
    *,
    normals: CloudNormals,
    best: Similarity,
    line: tuple[np.ndarray, np.ndarray],
    radius: float,
    loss: float,
    slack_rad: float,
) -> SymmetryFit | None:
    """The target body's symmetry axis (direction fitted, target frame) about the carried ``line`` (source frame),
    when the source's body about it is one of revolution (``BODY_RADIUS_FRAC``; ``slack_rad``: how far the
    demonstrated direction may be off, radians) and the target's turns it by at most ``MAX_SNAP_TURN_DEG``; else
    None."""
    pos, direction = line
    wide = BODY_RADIUS_FRAC * radius
    own = fit_symmetry_line(source, normals.source, pos, direction, wide, loss_scale_m=loss)
    if own is None or own.offset_m > SYMMETRIC_OFFSET_FRAC * radius + slack_rad * own.reach_m:
        return None
    carried_dir = best.apply_direction(direction)
    centre, axis_dir = best.apply_point(pos), carried_dir
    fitted: SymmetryFit | None = None
    for _ in range(SNAP_ROUNDS):
        fitted = fit_symmetry_line(
            target, normals.target, centre, axis_dir, wide * best.scale, loss_scale_m=loss * best.scale
        )
        if fitted is None:
            return None
        centre, axis_dir = fitted.pos, fitted.direction
    if fitted is None or angle_between_deg(axis_dir, carried_dir) > MAX_SNAP_TURN_DEG:
        return None
    return fitted


def place_axes(
    chain: tuple[Primitive, ...],
    source: Points,
    target: Points,
    *,
    best: Similarity,
    grip: Points,
    threshold_m: float,
    spacing_m: float,
    params: LocalParams | None = None,
    starts: tuple[Similarity, ...] | None = None,
) -> PlacedAxes:
    """Place every primitive of ``chain`` (source frame) on ``target`` from the global transform ``best``.

    ``grip``: (g, 3) grasped-part points (source frame); ``threshold_m`` and ``spacing_m``: the registration's
    final correspondence threshold and the target's median point spacing; ``starts``: one transform per
    primitive to start from instead of ``best`` (the stretched fit's, ``stretch.local_similarity``)."""
    params = params or LocalParams()
    span, radius = region_size(source, params)
    clouds = CloudNormals.of(source, target, spacing_m)
    transforms: list[Similarity] = []
    snapped: list[float] = []
    fits: list[SymmetryFit | None] = []
    checks: list[LocalCheck] = []
    grasp_transform: Similarity | None = None
    for i, prim in enumerate(chain):
        start = starts[i] if starts is not None else best
        moved = _snap(prim, source, target, normals=clouds, best=start, radius=radius)
        transform = moved.transform if moved is not None else start
        transforms.append(transform)
        fits.append(moved.fit if moved is not None else None)
        anchor = np.asarray(prim.pos, dtype=np.float64) if prim.pos is not None else np.zeros(3)
        shift = float(np.linalg.norm(transform.apply_point(anchor) - start.apply_point(anchor)))
        snapped.append(shift)
        check = check_axis(
            prim,
            i,
            source,
            target,
            clouds.target,
            source_normals=clouds.source,
            best=transform,
            grip=grip,
            threshold=threshold_m,
            params=params,
        )
        if moved is not None:  # a body of revolution placed on the target's own symmetry axis: the fit is the check
            check = replace(check, warning=None)
        checks.append(check)
        near_grip = prim.pos is not None and any(
            point_line_distance(g, np.asarray(prim.pos), np.asarray(prim.dir)) <= params.reach_frac * span for g in grip
        )
        if grasp_transform is None and near_grip:
            grasp_transform = transform
    warnings = tuple(c.warning for c in checks if c.warning is not None)
    return PlacedAxes(
        tuple(transforms), tuple(snapped), tuple(fits), tuple(checks), grasp_transform or best, warnings, clouds
    )


def snapped_transforms(
    chain: tuple[Primitive, ...],
    source: Points,
    target: Points,
    transform: Similarity | tuple[Similarity, ...],
    *,
    normals: CloudNormals,
    params: LocalParams | None = None,
) -> tuple[Similarity, ...]:
    """One transform per primitive: ``transform`` (or the primitive's own start), moved onto the target's
    symmetry axis where ``place_axes`` would move it (no local check): how an alternative would place the axes."""
    params = params or LocalParams()
    _, radius = region_size(source, params)
    starts = transform if isinstance(transform, tuple) else (transform,) * len(chain)
    out = []
    for prim, start in zip(chain, starts, strict=True):
        moved = _snap(prim, source, target, normals=normals, best=start, radius=radius)
        out.append(moved.transform if moved is not None else start)
    return tuple(out)


def placed_spread(
    chain: tuple[Primitive, ...],
    source: Points,
    target: Points,
    placed: PlacedAxes,
    alternatives: list[Similarity] | list[tuple[Similarity, ...]],
) -> tuple[float, float]:
    """Largest change of any placed axis between ``placed`` and each alternative alignment (or per-primitive
    starts) placed the same way: (degrees, metres point to line)."""
    others = [snapped_transforms(chain, source, target, alt, normals=placed.normals) for alt in alternatives]
    return axis_spread(chain, placed.transforms, others)
