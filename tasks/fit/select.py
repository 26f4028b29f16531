"""Model choice per segment: still, translation, rotation or undefined.

Default (BIC, as in Sturm's articulation models): each model's negative log-likelihood with an explicit noise
level sigma (metres, per axis) plus a complexity penalty: 1/2 log n per global parameter and
``LATENT_NATS`` per sample for the position along a moving model (so slow drift stays "still"); "undefined"
costs ``undefined_nats`` per sample whatever the residual (a robust, truncated likelihood). A rotation that
sweeps less than ``min_rotation_rad`` is a line in disguise (a 4 m radius on a drawer track) and counts as a
translation. Baseline: the paper's eq. (3), a threshold T0 on the eigenvalue ratio lambda_2 / lambda_1.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from tasks.arrays import FloatArray

Kind = Literal["still", "translation", "rotation", "undefined"]
KINDS: tuple[Kind, ...] = ("still", "translation", "rotation", "undefined")

LATENT_NATS = 1.0
"""Penalty per sample for the latent coordinate (position along the line, angle on the circle), nats."""
PARAMS: dict[Kind, int] = {"still": 3, "translation": 4, "rotation": 6, "undefined": 3}
"""Global parameters per model (centre; line point + direction; circle centre, normal, radius)."""
SIGMA_MIN_M = 1e-5
"""Smallest sensor noise assumed (m): noise-free synthetic tracks would otherwise make every motion infinitely
unlikely under "still"."""


@dataclass(frozen=True)
class SelectParams:
    """Noise and penalties of the model choice (metres, nats, radians)."""

    undefined_nats: float = 9.0
    min_rotation_rad: float = 0.25


def model_costs(
    n: FloatArray,
    rss_still: FloatArray,
    rss_line: FloatArray,
    rss_circle: FloatArray,
    *,
    sigma_still: float | FloatArray,
    sigma_model: float | FloatArray,
    undefined: float,
    still_noise: tuple[FloatArray, FloatArray, FloatArray] | None = None,
) -> FloatArray:
    """(b, 4) negative log-likelihood + penalty of still, translation, rotation, undefined (nats).

    ``n`` samples and residual sums of squares (m^2) per span. Two explicit noise levels (per axis, m): an
    object at rest scatters by the sensor noise ``sigma_still``; a moving one also departs from the ideal line
    or circle (mechanism play, marker wobble), ``sigma_model`` >= ``sigma_still``. The Gaussian normaliser
    3 log(sigma_model / sigma_still) per sample keeps the two comparable (costs are relative to "still").
    ``still_noise`` = (scatter (b, 3, 3) m^2, noise precision (b, 3, 3) 1/m^2, log-normaliser excess (b,) nats
    per sample; ``tasks.segment.tracks.anisotropy``) scores "still" under the marker's anisotropic noise, so that
    a camera's depth noise does not pass for motion along a line; ``sigma_still`` is then its rms per axis.
    """
    s_still = np.maximum(sigma_still, SIGMA_MIN_M)
    s_model = np.maximum(sigma_model, s_still)
    lognorm = 3.0 * np.log(s_model / s_still) * n
    still = rss_still / (2.0 * s_still**2)
    if still_noise is not None:
        scatter, precision, excess = still_noise
        still = 0.5 * np.einsum("bij,bji->b", precision, scatter)
        lognorm = lognorm + excess * n
    logn = np.log(np.maximum(n, 2.0))
    circle = np.minimum(rss_circle, rss_line)
    moving = LATENT_NATS * n + lognorm
    return np.stack(
        [
            still + 0.5 * PARAMS["still"] * logn,
            rss_line / (2.0 * s_model**2) + moving + 0.5 * PARAMS["translation"] * logn,
            circle / (2.0 * s_model**2) + moving + 0.5 * PARAMS["rotation"] * logn,
            undefined * n + lognorm + 0.5 * PARAMS["undefined"] * logn,
        ],
        axis=1,
    )


def choose_bic(costs: FloatArray, angle_rad: float, params: SelectParams, force: Kind | None = None) -> Kind:
    """The model of least cost from a (4,) cost row (or ``force``); a rotation sweeping too little counts as a
    translation, forced or not: an arc too short to tell from a line is a line."""
    kind = force or KINDS[int(np.argmin(costs))]
    if kind == "rotation" and angle_rad < params.min_rotation_rad:
        return "translation"
    return kind


def eigenvalue_ratio(eigenvalues: tuple[float, float, float]) -> float:
    """lambda_2 / lambda_1 of the scatter eigenvalues (largest first), the quantity eq. (3) thresholds."""
    return eigenvalues[1] / eigenvalues[0] if eigenvalues[0] > 0 else 0.0


def choose_eigen(eigenvalues: tuple[float, float, float], t0: float, still_m: float) -> Kind:
    """The paper's eq. (3): still below ``still_m`` rms spread, else rotation when lambda_2 / lambda_1 >= T0."""
    if np.sqrt(max(eigenvalues[0], 0.0)) < still_m:
        return "still"
    return "rotation" if eigenvalue_ratio(eigenvalues) >= t0 else "translation"
