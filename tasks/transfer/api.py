"""Public API of the transfer stage: ``register_models`` and ``transfer_descriptor``.

``transfer_descriptor`` registers the descriptor's object model (source, metres, the source recording's world
frame) onto a target model (metres, the target's frame), carries the chain and the grasp across and returns a
new ``Descriptor`` whose ``provenance.parent`` is the source id and whose ``provenance.transfer`` holds the
registration figures. No file IO: the caller loads both clouds and stores the result.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from schemas.descriptor import Descriptor, Grasp, ObjectRef
from tasks.arrays import Points
from tasks.code_version import code_version
from tasks.errors import GraspError, TransferError
from tasks.grasp import api as grasp_api
from tasks.transfer.axes import place_axes, placed_spread
from tasks.transfer.axis_fit import fit_axes
from tasks.transfer.carry import axis_spread, carry_grasp, carry_primitive, focus_points, grip_points, keep_standoff
from tasks.transfer.clouds import check_model
from tasks.transfer.registration import Registration, RegistrationParams, register_models
from tasks.transfer.scoring import poor_fit_warning
from tasks.transfer.similarity import Similarity
from tasks.transfer.stretched_judgement import stretched_alignment
from tasks.transfer.uncertainty import (
    MAX_AXIS_DIR_STD_RAD,
    MAX_AXIS_POS_STD_M,
    AxisUncertainty,
    axis_uncertainty,
    candidate_axes,
    with_uncertainty,
)

__all__ = ["RegistrationParams", "TransferResult", "register_models", "transfer_descriptor"]

SPREAD_SCORE_GAP = 0.02
"""Alignments scoring within this of the best count as equally plausible for the axis spread: a box's mirror
image whose knob the scan hardly shows scores within 0.01 of it, an upside-down mug 0.035-0.04 below."""
SPREAD_COUNT = 5
"""At most this many best alignments (the best included) enter the axis spread."""
STANDOFF_RAY_SPACINGS = 3.0
"""The palm's approach ray meets the surface at points within 3 median point spacings of it."""
MAX_SPREAD_DEG = 3.0
MAX_SPREAD_MM = 3.0
"""Alignments as good as the best that carry an axis further apart than the transferred axis's worst-case
tolerance (3 degrees, 3 mm) make the transfer ambiguous: the data do not single out one of them."""


@dataclass(frozen=True)
class TransferResult:
    """A transferred descriptor with the registration behind it and the axis uncertainty."""

    descriptor: Descriptor
    registration: Registration
    axis_spread_deg: float
    """Largest angle between the best alignment's carried axes and those of the equally good alternatives."""
    axis_spread_mm: float
    """Largest point-to-line distance between them, millimetres (target frame)."""
    poor: bool
    """The transfer is refused unless the user accepts it: the fit is poor, alignments as good as the best
    disagree on an axis, or the registration places an axis too loosely (``reasons``)."""
    warnings: tuple[str, ...]
    reasons: tuple[str, ...] = ()
    """Why ``poor``: one line each."""


def plausible_alternatives(reg: Registration) -> list[Similarity]:
    """The runner-up alignments scoring within ``SPREAD_SCORE_GAP`` of the best (at most ``SPREAD_COUNT`` - 1)."""
    return [a.transform for a in reg.alignments[1:SPREAD_COUNT] if a.score >= reg.best.score - SPREAD_SCORE_GAP]


def _uncertain_reason(i: int, unc: AxisUncertainty) -> str:
    """The refusal line of axis ``i`` placed too loosely; naming its faces' misfit where that is most of the
    position's variance."""
    misfit_m = unc.registration_misfit_m
    out = (
        f"uncertain registration: axis {i} is placed within {unc.registration_pos_worst_m * 1e3:.1f} mm and "
        f"{math.degrees(unc.registration_dir_std_rad):.2f} deg (one sigma; want <= "
        f"{MAX_AXIS_POS_STD_M * 1e3:g} mm and {math.degrees(MAX_AXIS_DIR_STD_RAD):g} deg)"
    )
    if misfit_m**2 >= 0.5 * unc.registration_pos_worst_m**2:
        out += f", its faces {misfit_m * 1e3:.1f} mm off the scan on average (the model's shape differs there)"
    return out


def _finite(value: float) -> float | None:
    """``value``, or None when it is not finite (JSON has no NaN)."""
    return value if math.isfinite(value) else None


def _replan(grasp: Grasp, target: Points, rng: np.random.Generator, *, strict: bool, warnings: list[str]) -> Grasp:
    """Re-plan the carried grasp on the target model, seeded by the carried wrist pose; the carried grasp is kept
    (with a warning, or ``TransferError`` when ``strict``) when planning fails or finds no force closure."""

    seed = np.asarray(grasp.wrist_position)
    try:
        part = grasp_api.part_near(target, seed)  # the planner grasps the part the hand reaches for
        planned = grasp_api.plan_grasp(part, seed, np.asarray(grasp.wrist_orientation, dtype=np.float64), rng)
    except GraspError as err:
        if strict:
            msg = f"grasp re-planning on the target model failed: {err}"
            raise TransferError(msg) from err
        warnings.append(f"grasp re-planning failed ({err}); kept the carried grasp")
        return grasp
    if planned.quality.get("force_closure") is True:
        return planned
    why = f"the re-planned grasp has no force closure ({planned.quality.get('contacts', 0)} contacts)"
    if strict:
        msg = f"grasp re-planning on the target model: {why} (--strict)"
        raise TransferError(msg)
    warnings.append(f"{why}; kept the carried grasp")
    return grasp


def transfer_descriptor(
    desc: Descriptor,
    source_model: Points,
    target_model: Points,
    target_object: ObjectRef,
    *,
    name: str | None = None,
    params: RegistrationParams | None = None,
    strict: bool = False,
    replan_grasp: bool = False,
    target_label: str | None = None,
    init: Similarity | None = None,
    rng: np.random.Generator,
) -> TransferResult:
    """Carry ``desc`` from its object model ``source_model`` onto ``target_model`` (both (n, 3) metres).

    ``target_object`` is the new object reference (the caller stores the model); ``name`` the new descriptor
    name (default ``<source name>-to-<target object name>``); ``target_label`` the model's path or recording
    id for the provenance. A poor registration is a warning, or ``TransferError`` when ``strict``.
    """
    params = params or RegistrationParams()
    source = check_model(source_model, "source model")
    target = check_model(target_model, "target model")
    focus = focus_points(desc, source)
    grip = grip_points(desc, source)
    reg = register_models(
        source, target, focus=focus if len(focus) else None, grip=grip, params=params, init=init, rng=rng
    )
    warnings = list(reg.warnings)
    best = reg.best.transform
    fits = fit_axes(
        desc.chain, source, target, best=best, grip=grip, threshold_m=reg.threshold_m, spacing_m=reg.spacing_m, rng=rng
    )
    placed = place_axes(
        desc.chain,
        source,
        target,
        best=best,
        grip=grip,
        threshold_m=reg.threshold_m,
        spacing_m=reg.spacing_m,
        starts=fits.starts,
    )
    alternatives: list[tuple[Similarity, ...]] = []
    for alt in plausible_alternatives(reg):
        deg, metres = axis_spread(desc.chain, best, [alt])
        if deg > MAX_SPREAD_DEG or metres * 1e3 > MAX_SPREAD_MM:  # placed as the best was, they may yet agree
            alt_fit = fit_axes(
                desc.chain, source, target, best=alt, grip=grip, threshold_m=reg.threshold_m,
                spacing_m=reg.spacing_m, rng=rng,
            )  # fmt: skip
            alternatives.append(alt_fit.starts)
    spread_deg, spread_m = placed_spread(desc.chain, source, target, placed, alternatives)
    reasons: list[str] = []
    if spread_deg > MAX_SPREAD_DEG or spread_m * 1e3 > MAX_SPREAD_MM:
        reasons.append(
            f"ambiguous registration: alignments as good as the best disagree on the axes by {spread_deg:.1f} deg "
            f"and {spread_m * 1e3:.1f} mm (want <= {MAX_SPREAD_DEG:g} deg and {MAX_SPREAD_MM:g} mm)"
        )
    uncertainty = tuple(
        axis_uncertainty(prim, fit, t.scale, symmetry)
        for prim, fit, t, symmetry in zip(desc.chain, fits.axes, placed.transforms, placed.symmetry, strict=True)
    )
    for i, unc in enumerate(uncertainty):
        if unc.registration_pos_worst_m > MAX_AXIS_POS_STD_M or unc.registration_dir_std_rad > MAX_AXIS_DIR_STD_RAD:
            reasons.append(_uncertain_reason(i, unc))
    stretched_scores: dict[str, float | None] | None = None
    if reg.poor:
        judged = stretched_alignment(
            source, target, reg, fits.whole, focus=focus if len(focus) else None, grip=grip, params=params
        )
        stretched_scores = {
            "fitness": judged.fitness,
            "plane_rmse_m": _finite(judged.plane_rmse_m),
            "two_way_score": judged.model_score,
            "scanned_two_way_score": judged.explained_score,
            "functional_score": judged.score,
        }
        poor_sim = [w for w in reg.warnings if w.startswith("poor")]
        if poor_fit_warning(judged, params, reg.threshold_m) is None:
            warnings = [w for w in warnings if w not in poor_sim]
        else:
            reasons.extend(poor_sim)
    reasons.extend(placed.warnings)
    warnings.extend(r for r in reasons if r not in warnings)
    poor = bool(reasons)
    if poor and strict:
        msg = "; ".join(reasons) + " (--strict)"
        raise TransferError(msg)

    grasp = None
    if desc.grasp is not None:
        grasp = carry_grasp(desc.grasp, placed.grasp_transform, grip[0] if len(grip) else None)
        grasp = keep_standoff(grasp, desc.grasp, source, target, STANDOFF_RAY_SPACINGS * reg.spacing_m)
    if replan_grasp:
        if grasp is None:
            warnings.append("no grasp to re-plan: the source descriptor has none")
        else:
            grasp = _replan(grasp, target, rng, strict=strict, warnings=warnings)

    info: dict[str, Any] = {
        "fitness": reg.best.fitness,
        "inlier_rmse_m": reg.best.inlier_rmse_m,
        "threshold_m": reg.threshold_m,
        "scale": best.scale,
        "transform": best.matrix().tolist(),
        "axis_spread_deg": spread_deg,
        "axis_spread_mm": spread_m * 1e3,
        "plane_rmse_m": _finite(reg.best.plane_rmse_m),
        "scanned_two_way_score": reg.best.explained_score,
        "stretched_scores": stretched_scores,
        "scale_range": list(params.scale_range),
        "stretch": {"axes": fits.whole.axes.T.tolist(), "factors": fits.whole.factors.tolist()},
        "refused": poor,
        "reasons": reasons,
        "candidates": candidate_axes(desc.chain, reg, SPREAD_COUNT),
        "axes": [
            {
                "placed_by": "symmetry" if snapped > 0.0 else ("neighbourhood" if fit.local else "whole model"),
                "direction_by": (
                    "symmetry"
                    if sym is not None and sym.dir_std_rad is not None
                    else ("neighbourhood" if fit.local and fit.direction_from is None else "whole model")
                ),
                "residual_rms_m": _finite(fit.spread.rms_m),
                "neighbourhood_shift_mm": fit.whole_shift_m * 1e3,
                "neighbourhood_turn_deg": math.degrees(fit.whole_turn_rad),
                "neighbourhood_pos_std_m": _finite(fit.fit_pos_std_m),
                "face_misfit_m": _finite(unc.registration_misfit_m),
                "registration_pos_std_m": _finite(unc.registration_pos_std_m),
                "registration_pos_worst_m": _finite(unc.registration_pos_worst_m),
                "edges": [
                    {"measured_mm": e.measured_m * 1e3, "std_mm": e.std_m * 1e3, "agrees": e.agrees} for e in fit.edges
                ],
                "edge_shift_mm": float(np.linalg.norm(fit.edge_shift)) * 1e3,
                "registration_dir_std_rad": _finite(unc.registration_dir_std_rad),
                "snapped_mm": snapped * 1e3,
                "region_points": check.region_points,
                "back_fitness": _finite(check.back_fitness),
                "local_turn_deg": check.turn_deg,
                "local_shift_mm": check.shift_m * 1e3,
            }
            for snapped, sym, check, fit, unc in zip(
                placed.snapped_m, placed.symmetry, placed.checks, fits.axes, uncertainty, strict=True
            )
        ],
        "start": reg.best.start,
        "region": "whole" if reg.crop_radius_m is None else "functional",
        "crop_radius_m": reg.crop_radius_m,
        "source_points_used": reg.source_points_used,
        "poor": poor,
        "warnings": warnings,
        "source": {"id": desc.id, "name": desc.name, "object": desc.object.name},
        "target_model": target_label,
    }
    out = Descriptor(
        name=name or f"{desc.name}-to-{target_object.name}",
        action=desc.action,
        object=target_object,
        grasp=grasp,
        chain=tuple(
            with_uncertainty(carry_primitive(p, t), u)
            for p, t, u in zip(desc.chain, placed.transforms, uncertainty, strict=True)
        ),
        recording_id=desc.recording_id,
        recording_path=desc.recording_path,
        parameters=desc.parameters,
        code_version=code_version("tasks.transfer"),
        parent=desc.id,
        extra_provenance={**desc.extra_provenance, "transfer": info},
    )
    return TransferResult(out, reg, spread_deg, spread_m * 1e3, poor, tuple(warnings), tuple(reasons))
