"""The transferred axis's uncertainty: the learned axis's own and the registration's, combined.

A transferred primitive's ``fit`` block holds, besides what learning put there, ``learned_pos_std_m`` and
``learned_dir_std_rad`` (the learned axis's own, its position scaled onto the target), ``registration_pos_std_m``
and ``registration_dir_std_rad`` (how loosely the registration places the axis: ``stretch.line_spread``, or for an
axis moved onto the target's symmetry axis that fit's own covariance across it, and the body's fitted axis's
for a direction turned onto it), and
``pos_std_m`` and ``dir_std_rad`` replaced by their root sum of squares (independent errors). One sigma; metres
and radians, target frame.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

from schemas.descriptor import Primitive
from tasks.transfer.axis_fit import AxisFit
from tasks.transfer.carry import carry_primitive
from tasks.transfer.registration_types import Registration
from tasks.transfer.symmetry_axis import SymmetryFit

MAX_AXIS_POS_STD_M = 1e-3
MAX_AXIS_DIR_STD_RAD = math.radians(1.0)
"""A registration placing an axis more loosely than this (one sigma, in its worst-placed direction across the axis)
is refused: three sigmas must stay within the transferred axis's worst-case tolerance of 3 mm and 3 degrees."""


@dataclass(frozen=True)
class AxisUncertainty:
    """One transferred axis's standard deviations (metres across the axis, radians), target frame."""

    learned_pos_std_m: float | None
    learned_dir_std_rad: float | None
    registration_pos_std_m: float
    registration_dir_std_rad: float
    registration_pos_worst_m: float
    """The registration's position sigma in its worst-placed direction across the axis (``FitSpread``), metres."""
    registration_misfit_m: float = 0.0
    """The part of it from the placing fit's faces' systematic misfit (``FitSpread.misfit_std_m``), metres; 0 for
    a translation or an axis point placed by a symmetry fit."""

    @property
    def pos_std_m(self) -> float:
        """Both position sigmas combined (root sum of squares)."""
        return math.hypot(self.learned_pos_std_m or 0.0, self.registration_pos_std_m)

    @property
    def dir_std_rad(self) -> float:
        """Both direction sigmas combined (root sum of squares)."""
        return math.hypot(self.learned_dir_std_rad or 0.0, self.registration_dir_std_rad)


def fit_number(fit: Mapping[str, object], key: str) -> float | None:
    """A primitive's ``fit`` entry ``key`` as a finite number, None when absent or not one."""
    value = fit.get(key)
    return float(value) if isinstance(value, int | float) and math.isfinite(value) else None


def axis_uncertainty(prim: Primitive, fit: AxisFit, scale: float, symmetry: SymmetryFit | None) -> AxisUncertainty:
    """The uncertainty of ``prim`` (source frame, its ``fit`` block from learning) carried at ``scale`` by
    ``fit``, its point placed by ``symmetry`` when not None (and its direction, when that fit carries a
    direction sigma: turned onto the body's axis)."""
    learned_pos = fit_number(prim.fit, "pos_std_m")
    misfit = 0.0
    if prim.kind != "rotation":
        pos_std, worst = 0.0, 0.0
    elif symmetry is not None:
        pos_std, worst = symmetry.pos_std_m, symmetry.worst_pos_std_m
    else:
        pos_std, worst, misfit = fit.spread.pos_std_m, fit.spread.worst_pos_std_m, fit.spread.misfit_std_m
    return AxisUncertainty(
        learned_pos * scale if learned_pos is not None else None,
        fit_number(prim.fit, "dir_std_rad"),
        pos_std,
        symmetry.dir_std_rad if symmetry is not None and symmetry.dir_std_rad is not None else fit.spread.dir_std_rad,
        worst,
        misfit,
    )


def with_uncertainty(prim: Primitive, unc: AxisUncertainty) -> Primitive:
    """``prim`` (carried) with the combined uncertainty in its ``fit`` block (see the module docstring)."""
    fit: dict[str, Any] = dict(prim.fit)
    fit.update(
        learned_pos_std_m=unc.learned_pos_std_m,
        learned_dir_std_rad=unc.learned_dir_std_rad,
        registration_pos_std_m=unc.registration_pos_std_m if math.isfinite(unc.registration_pos_std_m) else None,
        registration_dir_std_rad=unc.registration_dir_std_rad if math.isfinite(unc.registration_dir_std_rad) else None,
        dir_std_rad=unc.dir_std_rad if math.isfinite(unc.dir_std_rad) else None,
    )
    if prim.kind == "rotation":
        fit["pos_std_m"] = unc.pos_std_m if math.isfinite(unc.pos_std_m) else None
    return replace(prim, fit=fit)


def candidate_axes(chain: tuple[Primitive, ...], reg: Registration, count: int) -> list[dict[str, Any]]:
    """The ``count`` best alignments (best first) with the axes each would carry (target frame), JSON-ready."""
    out = []
    for alignment in reg.alignments[:count]:
        axes = []
        for prim in chain:
            moved = carry_primitive(prim, alignment.transform)
            axes.append({"kind": moved.kind, "pos": list(moved.pos) if moved.pos else None, "dir": list(moved.dir)})
        out.append(
            {
                "start": alignment.start,
                "score": alignment.score,
                "model_score": alignment.model_score,
                "fitness": alignment.fitness,
                "scale": alignment.transform.scale,
                "axes": axes,
            }
        )
    return out
