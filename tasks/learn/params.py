"""Every parameter of ``pbd learn`` (recorded in the descriptor's provenance)."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any, Literal

Segmenter = Literal["changepoint", "spectral"]
Classifier = Literal["bic", "eigen"]

HAND_PATTERN = r"(?<![a-z])(hand|thumb|finger|index|palm|wrist|glove)(?![a-z])"
"""Marker names matching this (case-insensitive) are on the demonstrator's hand, not the object."""


@dataclass(frozen=True)
class LearnParams:
    """Segmentation, fitting and chain-assembly settings (metres, seconds, radians, nats).

    ``sigma_floor_m``: the smallest noise level the model choice assumes; real mechanisms deviate from ideal
    circles and lines by 1 to 6 mm (Sturm's tracks, measured circle residual rms), more than the sensor noise.
    ``use_orientations``: a rigid part's orientation (Kabsch over its >= 3 object markers) enters the model
    choice and the rotation axis (``tasks.fit.rigid``).
    """

    segmenter: Segmenter = "changepoint"
    classifier: Classifier = "bic"
    k: int | Literal["auto"] = "auto"
    t0: float = 0.05
    sigma_floor_m: float = 0.002
    grid_s: float = 0.05
    min_segment_s: float = 0.3
    penalty: float | None = None
    undefined_nats: float = 9.0
    min_rotation_rad: float = 0.25
    delta_p_m: float = 0.05
    delta_t_s: float = 0.5
    merge_rms_m: float = 0.01
    min_motion_m: float = 0.015
    rigid_tol_m: float = 0.005
    hand_pattern: str = HAND_PATTERN
    use_orientations: bool = True
    max_k: int = 12

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict of every parameter."""
        return asdict(self)

    @classmethod
    def paper_baseline(cls, k: int | Literal["auto"] = "auto", t0: float = 0.05) -> LearnParams:
        """The paper's plain method: spectral segmentation with given k, eq. (3) with T0, algebraic circle fit."""
        return cls(segmenter="spectral", classifier="eigen", k=k, t0=t0)
