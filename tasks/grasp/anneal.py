"""Simulated annealing with GraspIt!'s online schedule (``SimAnn``, ANNEAL_ONLINE parameters).

Temperatures at step k (k starts at ``k0``): neighbour T_n = T0 exp(-0.24 k^(1/2)), acceptance
T_a = T0 exp(-0.54 k^(1/3)). A neighbour moves each variable by ``jump · y`` with y from Ingber's distribution
y = sgn(u - 1/2) T_n ((1 + 1/T_n)^|2u - 1| - 1), u uniform in [0, 1]; a worse state is accepted with probability
exp(-(E_new - E_old) · 0.01 / T_a) (energies in mm, scaled by the error constant 0.01).

A chain's uniforms are drawn before it starts, a fixed block per chain (``annealing_draws``): a chain's course depends
only on its start and its block, so the chains of one search may run in any process, side by side, and give the
same states.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from tasks.arrays import FloatArray

ILLEGAL_ENERGY = 1e9
"""Energy of an illegal (interpenetrating) state: never accepted from a legal one."""


@dataclass(frozen=True)
class Schedule:
    """GraspIt!'s online annealing constants (T0, start step, neighbour and acceptance constants, error scale)."""

    t0: float = 10.0
    k0: int = 100
    neighbour_c: float = 0.24
    neighbour_d: float = 2.0
    accept_c: float = 0.54
    accept_d: float = 3.0
    error_scale: float = 0.01

    def neighbour_temperature(self, k: int) -> float:
        """T_n(k) = T0 exp(-c k^(1/d))."""
        return self.t0 * math.exp(-self.neighbour_c * k ** (1.0 / self.neighbour_d))

    def accept_temperature(self, k: int) -> float:
        """T_a(k) = T0 exp(-c k^(1/d))."""
        return self.t0 * math.exp(-self.accept_c * k ** (1.0 / self.accept_d))


def ingber_draw(temperature: float, size: int, rng: np.random.Generator) -> FloatArray:
    """(size,) draws in (-1, 1) from Ingber's neighbour distribution at ``temperature``."""
    return ingber_from_uniforms(temperature, rng.random(size))


def ingber_from_uniforms(temperature: float, u: FloatArray) -> FloatArray:
    """Ingber's neighbour draws in (-1, 1) at ``temperature`` from uniforms ``u`` in [0, 1) (same shape)."""
    v = np.abs(2.0 * u - 1.0)
    y = temperature * ((1.0 + 1.0 / temperature) ** v - 1.0)
    return np.where(u < 0.5, -y, y)


@dataclass(frozen=True)
class AnnealTrace:
    """Every state evaluated: ``states`` (n, d) and their ``energies`` (n,); ``accepted`` how many moves won."""

    states: FloatArray
    energies: FloatArray
    accepted: int


def annealing_draws(rng: np.random.Generator, steps: int, dims: int) -> FloatArray:
    """(steps, dims + 1) uniforms in [0, 1) for one chain of ``steps`` steps over ``dims`` variables: each row the
    neighbour's draws then the acceptance draw (used only when the neighbour is legal and worse)."""
    return rng.random((steps, dims + 1))


def anneal(  # noqa: PLR0917 -- the annealing inputs, named at call sites
    energy: Callable[[FloatArray], float],
    start: FloatArray,
    lower: FloatArray,
    upper: FloatArray,
    jump: FloatArray,
    draws: FloatArray,
    schedule: Schedule | None = None,
) -> AnnealTrace:
    """Anneal from ``start`` within [lower, upper], one step per row of ``draws`` (``annealing_draws``); returns
    every evaluated state."""
    sched = schedule or Schedule()
    x = np.clip(np.asarray(start, dtype=np.float64), lower, upper)
    dims = len(x)
    e = energy(x)
    states = [x]
    energies = [e]
    accepted = 0
    for k, row in enumerate(np.asarray(draws, dtype=np.float64), start=sched.k0):
        t_n = sched.neighbour_temperature(k)
        t_a = sched.accept_temperature(k)
        candidate = np.clip(x + jump * ingber_from_uniforms(t_n, row[:dims]), lower, upper)
        e_new = energy(candidate)
        states.append(candidate)
        energies.append(e_new)
        delta = (e_new - e) * sched.error_scale
        if e_new < e or (e_new < ILLEGAL_ENERGY and float(row[dims]) < math.exp(-min(delta / t_a, 700.0))):
            x, e = candidate, e_new
            accepted += 1
    return AnnealTrace(np.array(states), np.array(energies), accepted)
