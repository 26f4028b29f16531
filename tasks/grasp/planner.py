"""The online eigengrasp planner's search (Ciocarlie & Allen; GraspIt!'s online planner as used by Dang & Allen).

**State space** (``SearchSpace``): x = (a1, a2, d, θr, θx, θy, u, v): the two Barrett eigengrasp amplitudes
(``barrett.dofs_from_eigengrasps``), and the wrist pose relative to the demonstrated palm: the palm rotated from
the demonstrated one by θx about its x axis, θy about its y axis and θr about the approach (+z), placed ``d``
metres before the **pivot**, the point where the demonstrated approach meets the object, moved (u, v) across the
approach (along the demonstrated palm's x and y). Bounds (``PlannerParams``): amplitudes ±4, d -30..200 mm, angles
±30°, (u, v) ±50 mm: the demonstration fixes the approach and roughly the place, not the exact pose.

**Energy** (``contact_energy``): GraspIt!'s contact energy, the mean over the hand's virtual contacts of their
distance to the object plus the misalignment of their normals with the surface's, in mm; a state whose hand
surface enters the object is illegal.

**Loop** (``anneal``): simulated annealing with GraspIt!'s online schedule (``Schedule``; Ingber's neighbour
draws), a chain of ``steps`` per start; every state evaluated is offered to a **list of the best unique states**
(``BestList``: the lowest energies, each differing from the others by a tenth of the search range in some variable).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from tasks.arrays import FloatArray, Vector3
from tasks.grasp.object_model import ObjectModel
from tasks.grasp.quality import DEFAULT_MU
from tasks.hand import barrett

ILLEGAL_ENERGY = 1e9
"""Energy of an illegal (interpenetrating) state: never accepted from a legal one."""
NORMAL_WEIGHT_MM = 50.0
"""Contact energy: weight of the misalignment term 1 - n·p, in mm (GraspIt!'s contactEnergy)."""
PENETRATION_TOL_M = 0.0015
"""A surface sample of the hand deeper than 1.5 mm inside the object makes a state illegal (the scan's noise)."""
PIVOT_RAY_M = 0.015
"""The pivot is the nearest object point within 15 mm of the demonstrated approach ray (a bar's radius)."""
UNIQUE_FRACTION = 0.1
"""Two states are the same grasp when every variable differs by less than this fraction of its range."""


@dataclass(frozen=True)
class Schedule:
    """GraspIt!'s online annealing constants (T0, start step, neighbour and acceptance constants, error scale):
    T_n(k) = T0 exp(-0.24 k^(1/2)), T_a(k) = T0 exp(-0.54 k^(1/3)), a worse state accepted with probability
    exp(-(E_new - E_old) 0.01 / T_a)."""

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


@dataclass(frozen=True)
class PlannerParams:
    """Planner settings. Search: ``steps`` per annealing chain, ``chains`` (one per start spread), ``candidates``
    (size of the best list), the state bounds (amplitudes, approach distance d (m), wrist angles (rad), lateral
    offset (m)). Execution: ``approach_max_m`` the move to contact, ``mu`` the friction of the quality.
    Ranking (``closeness``): lateral offset from the demonstrated approach over 20 mm, angle over 20°, advance
    past the demonstrated palm over 50 mm, distance behind it over 10 mm (a palm held back reaches the part with
    its fingertips only). ``hold_checks``: the plan's time budget, the simulated time of this many whole hold
    checks (a check stops when the part slips, so more grasps than that are usually checked)."""

    steps: int = 400
    chains: int = 4
    candidates: int = 12
    schedule: Schedule = field(default_factory=Schedule)
    amplitude_limit: float = barrett.AMPLITUDE_LIMIT
    distance_range_m: tuple[float, float] = (-0.03, 0.20)
    angle_limit_rad: float = math.radians(30.0)
    lateral_limit_m: float = 0.05
    approach_max_m: float = 0.03
    mu: float = DEFAULT_MU
    position_scale_m: float = 0.02
    angle_scale_rad: float = math.radians(20.0)
    advance_scale_m: float = 0.05
    behind_scale_m: float = 0.01
    hold_checks: float = 3.0


def _rot(axis: int, a: float) -> FloatArray:
    c, s = math.cos(a), math.sin(a)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    out = np.eye(3)
    out[i, i], out[i, j], out[j, i], out[j, j] = c, -s, s, c
    return out


@dataclass(frozen=True)
class SearchSpace:
    """The demonstrated palm (rotation (3, 3), position (3,) m, world), the pivot distance along its approach (m),
    and the state bounds ``lower``, ``upper`` (8,)."""

    seed_rot: FloatArray
    seed_pos: Vector3
    pivot_m: float
    lower: FloatArray
    upper: FloatArray

    @property
    def pivot(self) -> Vector3:
        """Where the demonstrated approach meets the object (world, m)."""
        out: Vector3 = self.seed_pos + self.seed_rot[:, 2] * self.pivot_m
        return out

    def pose(self, x: FloatArray) -> tuple[FloatArray, Vector3]:
        """Palm rotation (3, 3) and position (3,) in the world for state x."""
        rot = self.seed_rot @ _rot(0, float(x[4])) @ _rot(1, float(x[5])) @ _rot(2, float(x[3]))
        centre = self.pivot + self.seed_rot[:, 0] * float(x[6]) + self.seed_rot[:, 1] * float(x[7])
        return rot, centre - rot[:, 2] * float(x[2])

    def state(self, rot: FloatArray, pos: Vector3, spread_rad: float) -> FloatArray:
        """The state of a palm pose (world) with the open hand at ``spread_rad``, a2 = 0 (the inverse of ``pose``)."""
        tx, ty, tr = Rotation.from_matrix(self.seed_rot.T @ rot).as_euler("XYZ")
        columns = np.stack([self.seed_rot[:, 0], self.seed_rot[:, 1], -rot[:, 2]], axis=1)
        u, v, d = np.linalg.solve(columns, np.asarray(pos, dtype=np.float64) - self.pivot)
        return np.array([barrett.spread_amplitude(spread_rad), 0.0, d, tr, tx, ty, u, v])

    def inside(self, x: FloatArray) -> bool:
        """Whether x lies within the bounds (1 µm slack)."""
        return bool(np.all(x >= self.lower - 1e-6) and np.all(x <= self.upper + 1e-6))


def search_space(model: ObjectModel, seed_rot: FloatArray, seed_pos: Vector3, params: PlannerParams) -> SearchSpace:
    """The search space around the demonstrated palm: the pivot is the nearest object point within ``PIVOT_RAY_M``
    of the demonstrated approach ray, else the point nearest the palm taken onto the ray (clipped to the d range)."""
    approach = seed_rot[:, 2]
    rel = model.points - seed_pos
    along = rel @ approach
    off = np.linalg.norm(rel - along[:, None] * approach, axis=1)
    hit = (along > 0) & (off < PIVOT_RAY_M)
    far = params.distance_range_m[1]
    if np.any(hit):
        pivot = float(min(along[hit].min(), far))
    else:
        pivot = float(np.clip(along[int(model.tree.query(seed_pos)[1])], 0.0, far))
    lim, ang, lat = params.amplitude_limit, params.angle_limit_rad, params.lateral_limit_m
    lower = np.array([-lim, -lim, params.distance_range_m[0], -ang, -ang, -ang, -lat, -lat])
    upper = np.array([lim, lim, params.distance_range_m[1], ang, ang, ang, lat, lat])
    return SearchSpace(seed_rot, np.asarray(seed_pos, dtype=np.float64), pivot, lower, upper)


def contact_energy(model: ObjectModel, rot: FloatArray, pos: Vector3, dofs: FloatArray) -> float:
    """Mean over the virtual contacts of |distance| + 50 (1 - n·p) in mm (n into the object, p the contact's
    approach direction, both world), or ``ILLEGAL_ENERGY`` when the hand enters the object."""
    tfs = barrett.link_transforms(barrett.joint_positions(dofs))
    vc_pos, vc_dir = barrett.VIRTUAL_CONTACTS.in_palm(tfs)
    surf_pos, _ = barrett.SURFACE_SAMPLES.in_palm(tfs)
    surf_world = surf_pos @ rot.T + pos
    inside_box = np.all((surf_world > model.lower) & (surf_world < model.upper), axis=1)
    probe = surf_world[inside_box]
    if len(probe):
        _, idx = model.tree.query(probe)
        signed = np.einsum("ij,ij->i", probe - model.points[idx], model.normals[idx])
        if np.any(signed < -PENETRATION_TOL_M):
            return ILLEGAL_ENERGY
    vc_world = vc_pos @ rot.T + pos
    dist, idx = model.tree.query(vc_world)
    align = 1.0 + np.einsum("ij,ij->i", model.normals[idx], vc_dir @ rot.T)  # 1 - n_in · p
    return float(np.mean(1000.0 * dist + NORMAL_WEIGHT_MM * align))


def state_energy(model: ObjectModel, space: SearchSpace, x: FloatArray) -> float:
    """``contact_energy`` (mm) of state x in ``space``."""
    rot, pos = space.pose(x)
    return contact_energy(model, rot, pos, barrett.dofs_from_eigengrasps(float(x[0]), float(x[1])))


def ingber_from_uniforms(temperature: float, u: FloatArray) -> FloatArray:
    """Ingber's neighbour draws in (-1, 1) at ``temperature`` from uniforms ``u`` in [0, 1) (same shape):
    y = sgn(u - 1/2) T ((1 + 1/T)^|2u - 1| - 1)."""
    v = np.abs(2.0 * u - 1.0)
    y = temperature * ((1.0 + 1.0 / temperature) ** v - 1.0)
    return np.where(u < 0.5, -y, y)


class BestList:
    """The lowest-energy unique legal states seen (at most ``size``), lowest first."""

    def __init__(self, size: int, scale: FloatArray) -> None:
        """Keep ``size`` states; two are the same when no variable differs by ``UNIQUE_FRACTION`` of ``scale``."""
        self.size = size
        self.tolerance = UNIQUE_FRACTION * np.asarray(scale, dtype=np.float64)
        self.energies = np.zeros(0)
        self.xs = np.zeros((0, len(self.tolerance)))

    @property
    def states(self) -> list[tuple[float, FloatArray]]:
        """(energy, state) pairs, lowest energy first."""
        return [(float(e), x) for e, x in zip(self.energies, self.xs, strict=True)]

    def offer(self, x: FloatArray, energy: float) -> None:
        """Keep x if it is among the best and unlike the others (a better twin replaces its worse one)."""
        if energy >= ILLEGAL_ENERGY or (len(self.energies) >= self.size and energy >= self.energies[-1]):
            return
        twins = np.flatnonzero(np.all(np.abs(self.xs - x) < self.tolerance, axis=1))
        if len(twins):
            if energy >= self.energies[twins[0]]:
                return
            self.energies = np.delete(self.energies, twins[0])
            self.xs = np.delete(self.xs, twins[0], axis=0)
        at = int(np.searchsorted(self.energies, energy, side="right"))
        self.energies = np.insert(self.energies, at, energy)[: self.size]
        self.xs = np.insert(self.xs, at, x, axis=0)[: self.size]


def anneal(  # noqa: PLR0917 -- the annealing inputs, named at call sites
    energy: Callable[[FloatArray], float],
    start: FloatArray,
    space: SearchSpace,
    rng: np.random.Generator,
    steps: int,
    best: BestList,
    schedule: Schedule | None = None,
) -> None:
    """One annealing chain of ``steps`` from ``start`` within the space's bounds, every state offered to ``best``.
    A neighbour moves each variable by half the range times an Ingber draw at the neighbour temperature."""
    sched = schedule or Schedule()
    jump = (space.upper - space.lower) / 2.0
    x = np.clip(np.asarray(start, dtype=np.float64), space.lower, space.upper)
    e = energy(x)
    best.offer(x, e)
    draws = rng.random((steps, len(x) + 1))
    for k, row in enumerate(draws, start=sched.k0):
        y = np.clip(x + jump * ingber_from_uniforms(sched.neighbour_temperature(k), row[:-1]), space.lower, space.upper)
        e_new = energy(y)
        best.offer(y, e_new)
        worse = (e_new - e) * sched.error_scale / sched.accept_temperature(k)
        if e_new < e or (e_new < ILLEGAL_ENERGY and float(row[-1]) < math.exp(-min(worse, 700.0))):
            x, e = y, e_new
