"""A poor registration judged again as the stretched fit places the source model.

A similar object is the demonstrated one under a similarity and a stretch along its box axes (``stretch``, at
most ``MAX_STRETCH`` either way): one of other proportions (taller, or wider at its functional part's scale) fits
no similarity well, and its scores under the best similarity can fall below the poor limits
(``RegistrationParams``) where the stretched fit of the same alignment explains the scan. The registration is
poor only when both fall below them: the limits stay the same, applied to the model the transfer itself fits.
Lengths in metres (source frame in, target frame out).
"""

from __future__ import annotations

import numpy as np

from tasks.arrays import Points
from tasks.transfer.clouds import downsample, even_indices, functional_mask, median_spacing, outward_sample
from tasks.transfer.registration import (
    OUTWARD_POINTS,
    PLANE_ICP_POINTS,
    Registration,
    RegistrationParams,
    ScoredPart,
    prepare_target,
    score_fit,
    surface_normals,
)
from tasks.transfer.registration_types import Alignment
from tasks.transfer.scoring import scan_explained_score, two_way_score
from tasks.transfer.stretch import Stretched


def stretched_alignment(
    source: Points,
    target: Points,
    reg: Registration,
    stretched: Stretched,
    *,
    focus: Points | None,
    grip: Points | None,
    params: RegistrationParams,
) -> Alignment:
    """The scores of ``register_models`` for the source stretched as ``stretched`` places it (its similarity
    the alignment's transform): the same functional region, grip points, thresholds and sampling."""
    fine = prepare_target(target, params)
    stretched_src = stretched.stretch_points(source)
    crop = reg.crop_radius_m
    mask, stretched_focus = np.ones(len(source), bool), None
    if focus is not None and crop is not None:
        mask, stretched_focus = functional_mask(source, focus, crop), stretched.stretch_points(focus)
    used = stretched_src[mask]
    pick = even_indices(used.shape[0], PLANE_ICP_POINTS)
    outward, outward_normals = outward_sample(source, OUTWARD_POINTS)
    normals = stretched.stretch_normals(surface_normals(source, median_spacing(source)))[mask]
    part = ScoredPart(
        stretched_src,
        used,
        stretched_focus,
        crop,
        stretched.stretch_points(grip) if grip is not None and len(grip) else None,
        used[pick],
        normals[pick],
        (stretched.stretch_points(outward), stretched.stretch_normals(outward_normals)),
    )
    fitted = stretched.similarity
    mid = downsample(stretched_src, fine.mid_voxel / fitted.scale)
    model_score = two_way_score(mid, fine.mid, fitted, 1.5 * fine.mid_voxel)
    explained = scan_explained_score(mid, fine.mid, fitted, 1.5 * fine.mid_voxel)
    return score_fit(
        part,
        fitted,
        model_score,
        f"{reg.best.start}, stretched",
        explained_score=explained,
        fine=fine,
        params=params,
        sample_scale=fitted.scale,
        region_scale=fitted.scale,
    )
