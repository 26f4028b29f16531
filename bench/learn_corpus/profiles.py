"""Progress profiles ``s(u)``: how far along a primitive a demonstrator is at normalised time ``u`` in [0, 1].

Each maps [0, 1] onto [0, 1], starts and ends at rest and never moves backwards. A profile is drawn per primitive.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from bench.learn_corpus.rotations import Array

Profile = Callable[[Array], Array]

PROFILE_GRID = 2001
"""Samples of a numerically integrated profile (fine enough that linear interpolation error is below 1e-6)."""


def min_jerk(u: Array) -> Array:
    """Minimum-jerk progress (Flash and Hogan): 10u^3 - 15u^4 + 6u^5."""
    u = np.clip(u, 0.0, 1.0)
    return u**3 * (10.0 - 15.0 * u + 6.0 * u * u)


def sinusoid(u: Array) -> Array:
    """Cosine-eased progress (1 - cos(pi u)) / 2."""
    return 0.5 * (1.0 - np.cos(np.pi * np.clip(u, 0.0, 1.0)))


def _from_speed(speed: Array) -> Profile:
    """The profile whose speed over a uniform grid of [0, 1] is ``speed`` (>= 0), normalised to end at 1."""
    grid = np.linspace(0.0, 1.0, len(speed))
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]))])
    cum /= cum[-1]

    def profile(u: Array) -> Array:
        out: Array = np.interp(np.clip(u, 0.0, 1.0), grid, cum)
        return out

    return profile


def trapezoid(accel_frac: float) -> Profile:
    """Constant acceleration for ``accel_frac`` of the time, cruise, then constant deceleration."""
    u = np.linspace(0.0, 1.0, PROFILE_GRID)
    speed = np.minimum(1.0, np.minimum(u, 1.0 - u) / accel_frac)
    return _from_speed(speed)


def human(rng: np.random.Generator) -> Profile:
    """A bell-shaped speed with one to three hesitations (dips to 10-50 % speed) and a low-pass tremor of up to
    25 % of the speed, as in hand-guided motion."""
    u = np.linspace(0.0, 1.0, PROFILE_GRID)
    speed = 30.0 * u**2 * (1.0 - u) ** 2  # min-jerk speed
    for _ in range(int(rng.integers(1, 4))):
        centre = rng.uniform(0.2, 0.8)
        width = rng.uniform(0.03, 0.08)
        depth = rng.uniform(0.5, 0.9)
        speed *= 1.0 - depth * np.exp(-0.5 * ((u - centre) / width) ** 2)
    tremor = rng.normal(size=PROFILE_GRID)
    kernel = np.hanning(81)
    tremor = np.convolve(tremor, kernel / kernel.sum(), mode="same")
    tremor *= rng.uniform(0.05, 0.25) / max(float(np.std(tremor)), 1e-12)
    speed = np.clip(speed * (1.0 + tremor), 0.0, None)
    return _from_speed(speed)


def draw_profile(rng: np.random.Generator) -> tuple[str, Profile]:
    """A profile drawn from min-jerk, trapezoid, sinusoid and human-like, with its name."""
    kind = str(rng.choice(["min-jerk", "trapezoid", "sinusoid", "human", "human"]))
    if kind == "min-jerk":
        return kind, min_jerk
    if kind == "trapezoid":
        return kind, trapezoid(float(rng.uniform(0.1, 0.4)))
    if kind == "sinusoid":
        return kind, sinusoid
    return kind, human(rng)
