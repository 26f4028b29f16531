"""Where each axis lands: the stretched fit of the whole model, then a rigid fit of the axis's neighbourhood.

The whole model's stretched fit (``stretch``) carries the proportions; the points about a rotation's axis (its
hinge edge, the lever and rose) pin the axis itself, once the model's faces that meet there are matched by a
rigid point-to-plane fit of that neighbourhood alone, started from the stretched fit. The neighbourhood is used
only when its normals pin the axis across itself (their scatter across the axis has both eigenvalues at least
``MIN_LATERAL``: two faces meeting at a hinge, a lever's sides), and when its fit pairs enough points; else the
whole model's fit places the axis. Each placement comes with its spread (``stretch.line_spread``, from the
model's plane normals: ``face_normals``; a neighbourhood's with the uncertainty of the whole model's proportions,
which its rigid fit holds, and at least how far it moves with each region of its pairs left out,
``block_jackknife``), widened to cover how far the neighbourhood moved the axis from the whole model's placement
when the two fits contradict each other (``AGREEMENT_SIGMAS``), and by the misfit of faces whose pairs lie off to
one side on average, which the pairs' scatter does not show (``face_misfit``). The
neighbourhood's fit starts from the whole model's, so before its own pairs it knows the axis as well as the whole
model placed it (its translation prior is the whole model's sigma there). Last, the edges of the model's flat
faces that a rotation's axis runs along (a door's front face at its hinge) are located in the scan and update the
placement and its covariance (``with_edges``, ``face_edge``). Lengths in metres.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from schemas.descriptor import Primitive
from tasks.arrays import FloatArray, Points, Vector3
from tasks.transfer.block_jackknife import block_labels, dominating, jackknife
from tasks.transfer.clouds import median_spacing
from tasks.transfer.face_edge import EdgeUpdate, ModelEdge, edge_update, model_edges
from tasks.transfer.face_normals import ModelNormals, model_normals
from tasks.transfer.local_refine import LocalParams, axis_region, region_size
from tasks.transfer.neighbourhood_search import search_start
from tasks.transfer.registration import surface_normals
from tasks.transfer.similarity import Similarity, angle_between_deg, point_line_distance
from tasks.transfer.stretch import (
    POINT_WEIGHT,
    STRETCH_POINTS,
    FitSpread,
    Stretched,
    across_std,
    box_axes,
    fit_stretch,
    line_spread,
    local_similarity,
    smoothed_normals,
    stretch_icp,
)

MIN_LATERAL = 0.05
"""The neighbourhood pins the axis when its normals' scatter across the axis has both eigenvalues at least this
(one flat face: 0, free to slide; two perpendicular faces in equal parts: 0.5)."""
AGREEMENT_SIGMAS = 3.0
"""The neighbourhood's and the whole model's placements of an axis are two estimates from the same scan: when
they lie more than three of their combined sigmas apart they contradict each other (one fit's model leaves out
something, a face the scan lacks, a wrong pairing), the scan does not say which, and the kept one's sigma is
widened so that three of it cover the disagreement; within that, the kept fit's own sigma stands."""
MIN_REGION_PAIRS = 60
"""Fewer matched neighbourhood points than this: the neighbourhood does not place the axis."""
LOCAL_SPACINGS = 3.0
"""A neighbourhood found by its own features (``neighbourhood_search``) is sought and fitted at the registration's
threshold halved down to three of the scan's median point spacings (its pairs still find their surface at that
sampling) or a quarter of the threshold. The threshold grows with the whole object (about a door's diagonal / 100:
22 mm), the features that pin an axis do not (a lever 20 mm tall): within 22 mm a lever 19 mm off pairs with
itself."""


@dataclass(frozen=True)
class AxisFit:
    """The fit that carries one primitive and how well it pins the axis."""

    fit: Stretched
    spread: FitSpread
    local: bool
    """True when the axis's neighbourhood placed it (else the whole model's stretched fit)."""
    direction_from: Stretched | None = None
    """The fit that turns the axis when it is not ``fit`` (the whole model's, when it pins the direction better)."""
    whole_shift_m: float = 0.0
    """How far the neighbourhood's fit moved the axis point from the whole model's placement, metres (target)."""
    whole_turn_rad: float = 0.0
    """How far it turned the axis from the whole model's placement, radians."""
    fit_pos_std_m: float = float("nan")
    """The neighbourhood fit's own position sigma (``stretch.line_spread``, before any widening), metres."""
    edges: tuple[EdgeUpdate, ...] = ()
    """The faces' edges the axis runs along, as measured in the scan (``face_edge``), in the order applied."""

    @property
    def edge_shift(self) -> Vector3:
        """(3,) metres: how far the faces' edges moved the axis point from the fit's placement (target frame)."""
        out: Vector3 = sum((e.shift for e in self.edges), np.zeros(3))
        return out

    def start(self, pos: Vector3, direction: Vector3) -> Similarity:
        """The similarity carrying the line through ``pos`` along unit ``direction`` (source frame) as this fit
        places it."""
        out = local_similarity(self.fit, pos, direction)
        if self.direction_from is not None:
            turned = local_similarity(self.direction_from, pos, direction)
            out = Similarity(out.scale, turned.rotation, out.apply_point(pos) - out.scale * turned.rotation @ pos)
        return Similarity(out.scale, out.rotation, out.translation + self.edge_shift)


def lateral_pinning(normals: Points, direction: np.ndarray) -> float:
    """Smaller eigenvalue of the normals' scatter across unit ``direction`` (0: they leave the axis free)."""
    across = normals @ (np.eye(3) - np.outer(direction, direction))
    return float(np.linalg.eigvalsh(across.T @ across / max(len(normals), 1))[1])


def fit_axis(
    prim: Primitive,
    source: Points,
    model: ModelNormals,
    target: Points,
    target_normals: Points,
    *,
    whole: Stretched,
    whole_points: tuple[Points, Points, FloatArray],
    grip: Points,
    radius_m: float,
    threshold_m: float,
    spacing_m: float,
    edges: Sequence[ModelEdge],
) -> AxisFit:
    """The fit carrying ``prim`` (source frame) onto ``target`` by point-to-plane pairs: its neighbourhood's
    rigid fit from ``whole`` when that pins it, else ``whole``. ``model``: the source's normals and plane weights
    (``face_normals``);
    ``whole_points``: the points, normals and plane weights ``whole`` was fitted with;
    ``grip``: (g, 3) grasped-part points, whose ball joins the neighbourhood of an axis within ``radius_m``;
    ``spacing_m``: the target's median point spacing, which bounds the distance a searched neighbourhood is fitted
    at (``LOCAL_SPACINGS``); ``edges``: the model's face edges along the axis (``axis_edges``)."""
    direction = np.asarray(prim.dir, dtype=np.float64)
    direction = direction / np.linalg.norm(direction)
    pos = np.asarray(prim.pos, dtype=np.float64) if prim.pos is not None else whole.centre
    line = (pos, direction)
    global_spread = line_spread(
        whole,
        whole_points[0],
        whole_points[1],
        target=target,
        target_normals=target_normals,
        dist_m=threshold_m,
        line=line,
        plane_weight=whole_points[2],
        model=(source, model.normals),
    )
    if prim.kind != "rotation" or prim.pos is None:
        return AxisFit(whole, global_spread, local=False)
    mask = axis_region(source, pos, direction, radius_m)
    for g in grip:
        if point_line_distance(g, pos, direction) <= radius_m:
            mask |= ((source - g) ** 2).sum(axis=1) <= radius_m**2
    informs = mask & (model.plane_weight > 0.0)
    if int(mask.sum()) < MIN_REGION_PAIRS or lateral_pinning(model.normals[informs], direction) < MIN_LATERAL:
        return AxisFit(whole, global_spread, local=False)
    region, normals, weight = source[mask], model.normals[mask], model.plane_weight[mask]
    distances = [2.0 * threshold_m, threshold_m]
    fine = threshold_m
    while fine / 2.0 >= max(LOCAL_SPACINGS * spacing_m, threshold_m / 4.0):
        fine /= 2.0
    search = search_start(
        whole,
        region,
        normals,
        target,
        target_normals,
        line=line,
        sigma_m=global_spread.worst_pos_std_m,
        radius_m=radius_m,
        dist_m=fine,
        reach_m=distances[0],
    )
    # The point-to-point terms see a face's edge, where the planes do not. About an axis no face's edge runs along
    # (a lever's spindle, a cap's axis) they add only the pull of parts the scan shows from one side, where a model
    # point's nearest scan point is not centred on it: they moved a lever's spindle 2-4 mm across with a sigma
    # under 0.5 mm. A hinge keeps them: its door's edge is what they see.
    point_weight = POINT_WEIGHT if edges else 0.0
    fitted = whole
    if search is not None:  # found at the features' own scale: the fit goes on there, wider stages would leave them
        fitted, distances = search.start, [2.0 * fine, fine]
    for dist in distances:
        fitted = stretch_icp(
            region,
            target,
            target_normals,
            fitted,
            dist,
            source_normals=normals,
            free_stretch=False,
            final_m=distances[-1],
            point_weight=point_weight,
        )
    spread = line_spread(
        fitted,
        region,
        normals,
        target=target,
        target_normals=target_normals,
        dist_m=distances[-1],
        line=line,
        free_stretch=False,
        plane_weight=weight,
        model=(source, model.normals),
        start_pos_std_m=max(threshold_m, global_spread.pos_std_m) if math.isfinite(global_spread.pos_std_m) else None,
        held_factor_cov=global_spread.factor_cov,
    )
    if spread.pairs < MIN_REGION_PAIRS:
        return AxisFit(whole, global_spread, local=False)
    spread = with_jackknife(
        spread,
        fitted,
        (region, normals),
        (target, target_normals),
        line=line,
        dist_m=distances[-1],
        point_weight=point_weight,
    )
    whole_pos, whole_dir = whole.carry_line(pos, direction)
    local_pos, local_dir = fitted.carry_line(pos, direction)
    shift = point_line_distance(local_pos, whole_pos, whole_dir)
    turn = math.radians(angle_between_deg(local_dir, whole_dir))
    own = spread.pos_std_m
    if search is not None and search.spread_m > AGREEMENT_SIGMAS * spread.pos_std_m:  # the scan tells them not apart
        spread = replace(spread, pos_std_m=search.spread_m / AGREEMENT_SIGMAS)
    if shift > AGREEMENT_SIGMAS * math.hypot(spread.pos_std_m, global_spread.pos_std_m):
        spread = replace(spread, pos_std_m=max(spread.pos_std_m, shift / AGREEMENT_SIGMAS))
    if global_spread.dir_std_rad < spread.dir_std_rad:  # the whole model turns the axis more surely (a door's leaf)
        spread = replace(spread, dir_std_rad=global_spread.dir_std_rad)
        return AxisFit(
            fitted, spread, local=True, direction_from=whole, whole_shift_m=shift, whole_turn_rad=turn,
            fit_pos_std_m=own,
        )  # fmt: skip
    if turn > AGREEMENT_SIGMAS * math.hypot(spread.dir_std_rad, global_spread.dir_std_rad):
        spread = replace(spread, dir_std_rad=max(spread.dir_std_rad, turn / AGREEMENT_SIGMAS))
    return AxisFit(fitted, spread, local=True, whole_shift_m=shift, whole_turn_rad=turn, fit_pos_std_m=own)


def with_jackknife(
    spread: FitSpread,
    fitted: Stretched,
    model: tuple[Points, Points],
    scan: tuple[Points, Points],
    *,
    line: tuple[Vector3, Vector3],
    dist_m: float,
    point_weight: float,
) -> FitSpread:
    """``spread`` of the neighbourhood's rigid fit ``fitted`` of ``model`` (its points and normals, source frame)
    onto ``scan`` (points and normals, target frame), made at least the spread of that fit refitted with each block
    of the model's points left out (``block_jackknife``), in every direction across the carried line (``line``:
    point and unit direction, source frame); ``dist_m`` and ``point_weight`` as the fit's last stage ran."""
    if spread.pos_cov is None:
        return spread
    pos, direction = line
    region, normals = model
    target, target_normals = scan

    def refit(keep: np.ndarray) -> tuple[Vector3, Vector3]:
        out = stretch_icp(
            region[keep],
            target,
            target_normals,
            fitted,
            dist_m,
            source_normals=normals[keep],
            free_stretch=False,
            final_m=dist_m,
            point_weight=point_weight,
        )
        return out.carry_line(pos, direction)

    moved_dir = fitted.carry_line(pos, direction)[1]
    jack_cov, jack_dir = jackknife(refit, block_labels(region), moved_dir)
    cov = dominating(spread.pos_cov, jack_cov, moved_dir)
    return replace(spread, pos_std_m=across_std(cov), pos_cov=cov, dir_std_rad=max(spread.dir_std_rad, jack_dir))


def with_bias(axis: AxisFit) -> AxisFit:
    """``axis`` with its placing fit's faces' systematic misfit (``FitSpread.bias_cov``) added to its position
    covariance (once, before the faces' edges update it)."""
    spread = axis.spread
    cov = spread.scaled_cov()
    if cov is None or spread.bias_cov is None or not spread.bias_cov.any():
        return axis
    cov = cov + spread.bias_cov
    return replace(axis, spread=replace(spread, pos_std_m=across_std(cov), pos_cov=cov))


def axis_edges(prim: Primitive, source: Points, model: ModelNormals, radius_m: float) -> list[ModelEdge]:
    """The edges of the model's flat faces that ``prim``'s axis runs along (``face_edge.model_edges``; none for
    a translation or a rotation without an axis point)."""
    if prim.kind != "rotation" or prim.pos is None:
        return []
    direction = np.asarray(prim.dir, dtype=np.float64)
    line = (np.asarray(prim.pos, dtype=np.float64), direction / np.linalg.norm(direction))
    return model_edges(source, model, line=line, radius_m=radius_m)


def with_edges(axis: AxisFit, prim: Primitive, *, found: Sequence[ModelEdge], target: Points) -> AxisFit:
    """``axis`` updated by ``found``, the edges of the model's flat faces that ``prim``'s axis runs along
    (``axis_edges``): its placement moved and its position sigma narrowed, or widened where an edge contradicts
    it."""
    cov = axis.spread.scaled_cov()
    if not found or prim.pos is None or cov is None:
        return axis
    pos = np.asarray(prim.pos, dtype=np.float64)
    direction = np.asarray(prim.dir, dtype=np.float64)
    direction = direction / np.linalg.norm(direction)
    carried = axis.start(pos, direction)
    updates: list[EdgeUpdate] = []
    shift = np.zeros(3)
    for edge in found:
        moved = Similarity(carried.scale, carried.rotation, carried.translation + shift)
        line_fit = replace(axis.fit, similarity=moved, axes=np.eye(3), factors=np.ones(3), centre=np.zeros(3))
        step = edge_update(edge, line_fit, (pos, direction), target, cov)
        if step is None:
            continue
        updates.append(step)
        cov, shift = step.cov, shift + step.shift
    if not updates:
        return axis
    return replace(axis, spread=replace(axis.spread, pos_std_m=across_std(cov), pos_cov=cov), edges=tuple(updates))


@dataclass(frozen=True)
class AxisFits:
    """The whole model's stretched fit and, per primitive, its fit and the similarity that carries it."""

    whole: Stretched
    axes: tuple[AxisFit, ...]
    starts: tuple[Similarity, ...]
    """Per primitive: the similarity carrying its axis as its fit does (``stretch.local_similarity``)."""


def fit_axes(
    chain: tuple[Primitive, ...],
    source: Points,
    target: Points,
    *,
    best: Similarity,
    grip: Points,
    threshold_m: float,
    spacing_m: float,
    rng: np.random.Generator,
) -> AxisFits:
    """The stretched fit of ``source`` onto ``target`` from the registration's ``best``, then every primitive's
    own fit (``fit_axis``, then ``with_bias`` and ``with_edges``); ``threshold_m`` and ``spacing_m``: the
    registration's final correspondence threshold and the target's median point spacing."""
    model = model_normals(smoothed_normals(source, surface_normals(source, median_spacing(source))))
    target_normals = surface_normals(target, spacing_m)
    pick = rng.permutation(source.shape[0])[:STRETCH_POINTS]
    sample = (source[pick], model.normals[pick], model.plane_weight[pick])
    whole = fit_stretch(
        sample[:2],
        target,
        target_normals,
        best,
        threshold_m,
        axes=box_axes(source, model.normals),
        centre=source.mean(axis=0),
    )
    _, radius = region_size(source, LocalParams())
    edges = [axis_edges(prim, source, model, radius) for prim in chain]
    fits = tuple(
        with_edges(
            with_bias(
                fit_axis(
                    prim,
                    source,
                    model,
                    target,
                    target_normals,
                    whole=whole,
                    whole_points=sample,
                    grip=grip,
                    radius_m=radius,
                    threshold_m=threshold_m,
                    spacing_m=spacing_m,
                    edges=found,
                )
            ),
            prim,
            found=found,
            target=target,
        )
        for prim, found in zip(chain, edges, strict=True)
    )
    starts = []
    for prim, fit in zip(chain, fits, strict=True):
        pos = np.asarray(prim.pos, dtype=np.float64) if prim.pos is not None else whole.centre
        direction = np.asarray(prim.dir, dtype=np.float64)
        starts.append(fit.start(pos, direction / np.linalg.norm(direction)))
    return AxisFits(whole, fits, tuple(starts))
