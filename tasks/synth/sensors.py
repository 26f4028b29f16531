"""Sensor models of the simulated capture (Dang & Allen's set-up): an optical motion-capture system for the
markers and a magnetic 6-DOF tracker for the wrist.

Mocap: synchronous samples at ``mocap_hz`` (100-240 Hz), isotropic Gaussian noise ``mocap_noise_m`` (0.2-1 mm)
per axis, occlusion dropouts in bursts: per marker a two-state Markov chain (visible / occluded) whose
stationary occluded fraction is ``dropout_fraction`` and whose mean burst length is ``dropout_burst_s``.
Tracker: samples at ``wrist_hz`` (30-120 Hz) starting ``wrist_phase_s`` after the mocap's first, Gaussian
position noise ``wrist_noise_m`` per axis (about 2 mm) and a small random rotation of rms angle
``wrist_noise_rad`` (about 1 degree). Times are seconds from the recording start; world frame, metres.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from tasks.arrays import BoolArray, FloatArray, Points, Quats

MOCAP_HZ_RANGE = (100.0, 240.0)
MOCAP_NOISE_RANGE_M = (0.0002, 0.001)
WRIST_HZ_RANGE = (30.0, 120.0)


@dataclass(frozen=True)
class SensorParams:
    """Rates (Hz), noise levels (m, rad) and dropout statistics of one simulated capture."""

    mocap_hz: float = 120.0
    mocap_noise_m: float = 0.0005
    dropout_fraction: float = 0.02
    dropout_burst_s: float = 0.08
    wrist_hz: float = 60.0
    wrist_phase_s: float = 0.004
    wrist_noise_m: float = 0.002
    wrist_noise_rad: float = float(np.radians(1.0))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict of every field."""
        return asdict(self)


NOMINAL_SENSORS = SensorParams()


def draw_sensor_params(rng: np.random.Generator) -> SensorParams:
    """Random sensor parameters within the ranges of the paper's kind of set-up."""
    wrist_hz = float(rng.uniform(*WRIST_HZ_RANGE))
    return SensorParams(
        mocap_hz=float(rng.uniform(*MOCAP_HZ_RANGE)),
        mocap_noise_m=float(rng.uniform(*MOCAP_NOISE_RANGE_M)),
        dropout_fraction=float(rng.uniform(0.005, 0.04)),
        dropout_burst_s=float(rng.uniform(0.03, 0.15)),
        wrist_hz=wrist_hz,
        wrist_phase_s=float(rng.uniform(0.0, 1.0 / wrist_hz)),
        wrist_noise_m=float(rng.uniform(0.0015, 0.0025)),
        wrist_noise_rad=float(np.radians(rng.uniform(0.7, 1.3))),
    )


def sample_times(duration_s: float, hz: float, phase_s: float = 0.0) -> FloatArray:
    """Sample times (s) ``phase_s + k / hz`` up to and including ``duration_s``."""
    count = int(np.floor((duration_s - phase_s) * hz + 1e-9)) + 1
    out: FloatArray = phase_s + np.arange(max(count, 0), dtype=np.float64) / hz
    return out


def dropout_mask(n: int, hz: float, fraction: float, burst_s: float, rng: np.random.Generator) -> BoolArray:
    """(n,) True where an occlusion hides the marker: a two-state Markov chain starting visible, with mean
    occluded run ``burst_s`` seconds and stationary occluded fraction ``fraction``."""
    p_recover = min(1.0, 1.0 / max(burst_s * hz, 1.0))
    p_drop = min(1.0, fraction * p_recover / max(1.0 - fraction, 1e-9))
    u = rng.random(n)
    out = np.zeros(n, dtype=bool)
    hidden = False
    for i in range(n):
        hidden = (u[i] >= p_recover) if hidden else (u[i] < p_drop)
        out[i] = hidden
    return out


def observe_markers(points: Points, params: SensorParams, rng: np.random.Generator) -> Points:
    """Noisy mocap samples (n, 3) of true positions ``points``; occluded samples are NaN."""
    noisy: Points = points + rng.normal(0.0, params.mocap_noise_m, points.shape)
    hidden = dropout_mask(len(points), params.mocap_hz, params.dropout_fraction, params.dropout_burst_s, rng)
    noisy[hidden] = np.nan
    return noisy


def observe_tracker(
    positions: Points, quats: Quats, params: SensorParams, rng: np.random.Generator
) -> tuple[Points, Quats]:
    """Noisy tracker poses: positions (n, 3) m, quaternions (n, 4) [x, y, z, w], signs kept continuous."""
    pos: Points = positions + rng.normal(0.0, params.wrist_noise_m, positions.shape)
    tilt = rng.normal(0.0, params.wrist_noise_rad / np.sqrt(3.0), positions.shape)
    out: Quats = (Rotation.from_rotvec(tilt) * Rotation.from_quat(quats)).as_quat()
    return pos, continuous_quats(out)


def continuous_quats(quats: Quats) -> Quats:
    """Quaternions (n, 4) with signs flipped so neighbours agree (q and -q are the same rotation)."""
    out = np.array(quats, dtype=np.float64)
    if len(out) and out[0, 3] < 0:
        out[0] *= -1.0
    for i in range(1, len(out)):
        if float(np.dot(out[i], out[i - 1])) < 0.0:
            out[i] *= -1.0
    return out
