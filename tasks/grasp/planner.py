"""The online eigengrasp planner's search (Ciocarlie & Allen; GraspIt!'s online planner as used by Dang & Allen).

**State space** (``SearchSpace``): x = (a1, a2, d, θr, θx, θy, u, v): the two Barrett eigengrasp amplitudes
(``barrett.dofs_from_eigengrasps``), and the wrist pose relative to the demonstrated palm: the palm rotated from the
demonstrated one by θx about its x axis, θy about its y axis and θr about the approach (+z), placed ``d`` metres before
the **pivot**, the point where the demonstrated approach meets the object, moved (u, v) across the approach (along the
demonstrated palm's x and y). Bounds (``PlannerParams``): amplitudes ±4, d -30..200 mm, angles ±30°, (u, v) ±50 mm: the
demonstration fixes the approach and roughly the place, not the exact pose.

**Energy** (``contact_energy``): GraspIt!'s contact energy, the mean over the hand's virtual contacts of their distance
to the object plus 50 mm times their normals' misalignment; a state whose hand surface enters the object is illegal.

**Loop** (``anneal``): simulated annealing with GraspIt!'s online schedule (``temperature``; Ingber's neighbour draws),
a chain of ``steps`` per start; every state evaluated is offered to the list of the best unique states (``BestList``).

**Proposals** (``GENERATORS``): the generators of states to execute, registered in one place, each proposing nothing
where its mechanism does not apply (the bar's two need a bar, ``find_bars``); ``tasks.grasp.api.plan_on_model``
executes them all and ranks the grasps together.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from tasks.arrays import FloatArray, Vector3
from tasks.grasp.object_model import ObjectModel
from tasks.grasp.primitive_fit import PrimitiveShape
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


T0 = 10.0
K0 = 100
NEIGHBOUR_C, NEIGHBOUR_D = 0.24, 2.0
ACCEPT_C, ACCEPT_D = 0.54, 3.0
ERROR_SCALE = 0.01
"""GraspIt!'s online annealing schedule from step ``K0``: neighbour temperature T_n(k) = T0 exp(-0.24 k^(1/2)),
acceptance temperature T_a(k) = T0 exp(-0.54 k^(1/3)), a worse state accepted with probability
exp(-(E_new - E_old) 0.01 / T_a)."""


def temperature(k: int, c: float, d: float) -> float:
    """GraspIt!'s cooling at step k: T0 exp(-c k^(1/d))."""
    return T0 * math.exp(-c * k ** (1.0 / d))


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
        """Palm rotation (..., 3, 3) and position (..., 3) in the world for states x (..., 8): the demonstrated palm
        turned about its x, then its new y, then its new z axis (intrinsic XYZ)."""
        rot = self.seed_rot @ Rotation.from_euler("XYZ", x[..., [4, 5, 3]]).as_matrix()
        centre = self.pivot + x[..., 6, None] * self.seed_rot[:, 0] + x[..., 7, None] * self.seed_rot[:, 1]
        return rot, centre - rot[..., :, 2] * x[..., 2, None]

    def state(self, rot: FloatArray, pos: Vector3, spread_rad: float) -> FloatArray:
        """The state of a palm pose (world) with the open hand at ``spread_rad``, a2 = 0 (the inverse of ``pose``)."""
        tx, ty, tr = Rotation.from_matrix(self.seed_rot.T @ rot).as_euler("XYZ")
        columns = np.stack([self.seed_rot[:, 0], self.seed_rot[:, 1], -rot[:, 2]], axis=1)
        u, v, d = np.linalg.solve(columns, np.asarray(pos, dtype=np.float64) - self.pivot)
        return np.array([barrett.spread_amplitude(spread_rad), 0.0, d, tr, tx, ty, u, v])

    def inside(self, x: FloatArray) -> bool:
        """Whether x lies within the bounds (1 µm slack)."""
        return bool(np.all(x >= self.lower - 1e-6) and np.all(x <= self.upper + 1e-6))


@dataclass(frozen=True)
class Proposal:
    """A state to execute: who proposed it (``source``), the state x (8,), how far (m) the palm may approach to
    contact (0 for a fingertip grasp whose palm is to stay where it is)."""

    source: str
    state: FloatArray
    approach_m: float


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


def contact_energy(model: ObjectModel, rot: FloatArray, pos: Vector3, joints: FloatArray) -> FloatArray:
    """(c,) mean over the virtual contacts of |distance| + 50 (1 - n·p) in mm (n into the object, p the contact's
    approach direction, both world), or ``ILLEGAL_ENERGY`` where the hand enters the object, of c hand poses:
    palm rotations (c, 3, 3) and positions (c, 3) (world, m), URDF joint angles (c, 9) rad."""
    tfs = barrett.link_transforms(joints)
    vc_pos, vc_dir = barrett.VIRTUAL_CONTACTS.in_palm(tfs)
    surf_pos, _ = barrett.SURFACE_SAMPLES.in_palm(tfs)
    turn = np.swapaxes(rot, 1, 2)  # row vectors times rot^T: each hand's palm frame into the world
    surf_world = surf_pos @ turn + pos[:, None, :]
    inside_box = np.all((surf_world > model.lower) & (surf_world < model.upper), axis=2)
    probe = surf_world[inside_box]
    illegal = np.zeros(len(rot), dtype=bool)
    if len(probe):
        _, idx = model.tree.query(probe)
        signed = np.einsum("ij,ij->i", probe - model.points[idx], model.normals[idx])
        illegal[np.nonzero(inside_box)[0][signed < -PENETRATION_TOL_M]] = True
    dist, idx = model.tree.query(vc_pos @ turn + pos[:, None, :])
    align = 1.0 + np.einsum("cmi,cmi->cm", model.normals[idx], vc_dir @ turn)  # 1 - n_in · p
    return np.where(illegal, ILLEGAL_ENERGY, np.mean(1000.0 * dist + NORMAL_WEIGHT_MM * align, axis=1))


def state_energy(model: ObjectModel, space: SearchSpace, x: FloatArray) -> FloatArray:
    """(c,) ``contact_energy`` (mm) of states x (c, 8) in ``space``."""
    rot, pos = space.pose(x)
    return contact_energy(model, rot, pos, barrett.joints_from_eigengrasps(x[:, :2]))


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
    energy: Callable[[FloatArray], FloatArray],
    starts: FloatArray,
    space: SearchSpace,
    rng: np.random.Generator,
    steps: int,
    best: BestList,
) -> None:
    """One annealing chain of ``steps`` from each of ``starts`` (c, 8) within the space's bounds, the chains side by
    side (one call of the batched ``energy`` per step), each drawing its own numbers in turn; then every state of
    chain 0, of chain 1, ... offered to ``best``. A neighbour moves each variable by half the range times an Ingber
    draw at the neighbour temperature."""
    jump = (space.upper - space.lower) / 2.0
    x = np.clip(np.asarray(starts, dtype=np.float64), space.lower, space.upper)
    draws = np.stack([rng.random((steps, x.shape[1] + 1)) for _ in x])
    e = energy(x)
    seen, seen_e = [x], [e]
    for k in range(steps):
        move = ingber_from_uniforms(temperature(k + K0, NEIGHBOUR_C, NEIGHBOUR_D), draws[:, k, :-1])
        y = np.clip(x + jump * move, space.lower, space.upper)
        e_new = energy(y)
        seen.append(y)
        seen_e.append(e_new)
        worse = (e_new - e) * ERROR_SCALE / temperature(k + K0, ACCEPT_C, ACCEPT_D)
        take = (e_new < e) | ((e_new < ILLEGAL_ENERGY) & (draws[:, k, -1] < np.exp(-np.clip(worse, 0.0, 700.0))))
        x, e = np.where(take[:, None], y, x), np.where(take, e_new, e)
    for chain_x, chain_e in zip(np.stack(seen, axis=1), np.stack(seen_e, axis=1), strict=True):
        for state, energy_mm in zip(chain_x, chain_e, strict=True):
            best.offer(state, float(energy_mm))


SPREADS_RAD = (0.0, 1.13, math.pi / 2)
"""Spreads of the demonstrated palm's proposals: the thumb opposite fingers 1 and 2, GraspIt!'s origin posture, and
fingers 1 and 2 face to face."""
TIP_SPREADS_RAD = (0.0, math.pi / 2)
"""Spreads of the fingertip proposals: three fingertips two against one, then two face to face."""
ROLLS_RAD = (0.0, math.radians(15.0), math.radians(-15.0))
"""Rolls about the demonstrated approach: a hand closes round a bar or a box at any roll within a few tens of
degrees of the demonstrated one."""
HOLD_BACK_M = 0.02
"""The demonstrated palm held back by about a finger's width, so the fingers close round the part, not on top."""
SLIDES_M = (0.025, 0.05)
"""Distances slid along a bar: a finger's width and two."""
TIP_DISTANCES_M = (0.06, 0.07, 0.08, 0.09, 0.10)
"""Palm distances from the part's surface at which the open fingertips (126 mm fingers on 50 mm knuckles) close on
a part 10-50 mm across."""
CHAIN_SPREADS = (-1.13, 0.0, 0.44, 2.0)
"""Start amplitude a1 of the annealing chains: spread 0, 1.13 (the origin), π/2 and π."""

Generator = Callable[[ObjectModel, SearchSpace, PlannerParams, np.random.Generator], list[Proposal]]


def _at(spread: float, d: float, roll: float = 0.0, u: float = 0.0, v: float = 0.0) -> np.ndarray:
    """The state of the open hand at ``spread`` (rad), ``d`` before the pivot, rolled, moved (u, v) across."""
    return np.array([barrett.spread_amplitude(spread), 0.0, d, roll, 0.0, 0.0, u, v])


def annealed(model: ObjectModel, space: SearchSpace, params: PlannerParams, rng: np.random.Generator) -> list[Proposal]:
    """GraspIt!'s online eigengrasp planner: the best unique states of ``params.chains`` annealing chains from the
    demonstrated palm under the contact energy (``planner.anneal``)."""
    best = BestList(params.candidates, space.upper - space.lower)
    d0 = float(np.clip(space.pivot_m, *params.distance_range_m))
    starts = np.array([[a1, -1.0, d0, 0.0, 0.0, 0.0, 0.0, 0.0] for a1 in CHAIN_SPREADS[: params.chains]])
    anneal(lambda x: state_energy(model, space, x), starts, space, rng, params.steps, best)
    return [Proposal("annealed", x, params.approach_max_m) for _, x in best.states]


def demonstrated(
    _model: ObjectModel, space: SearchSpace, params: PlannerParams, _rng: np.random.Generator
) -> list[Proposal]:
    """The demonstrated palm, held back ``HOLD_BACK_M`` and rolled ``ROLLS_RAD``, at ``SPREADS_RAD``: what the
    demonstrator did, which the energy does not always rank first."""
    return [
        Proposal("demonstrated", _at(spread, space.pivot_m + back, roll), params.approach_max_m)
        for back in (0.0, HOLD_BACK_M)
        for roll in ROLLS_RAD
        for spread in SPREADS_RAD
    ]


def _palm(approach: FloatArray, x_hint: FloatArray) -> FloatArray:
    """The palm rotation (3, 3) looking along ``approach`` with +x the part of ``x_hint`` across it (world)."""
    z = approach / float(np.linalg.norm(approach))
    x = x_hint - float(x_hint @ z) * z
    x /= float(np.linalg.norm(x))
    return np.stack([x, np.cross(z, x), z], axis=1)


BAR_ELONGATION = 3.0
"""A mounted part at least three times as long as it is wide (its posts included) is a bar the fingers close across,
whatever its profile: round, square or D-shaped."""


@dataclass(frozen=True)
class Bar:
    """A bar: unit ``axis``, ``centre`` (3,) of its axis, ``half_length`` and ``half_width`` (m, world)."""

    axis: FloatArray
    centre: Vector3
    half_length: float
    half_width: float


def _shape_bars(shape: PrimitiveShape, approach: FloatArray) -> list[Bar]:
    """A cylinder as the bar along its axis; a box as a bar along each of its two edges most square to
    ``approach``, as wide as the box across it: the fingertips close on two parallel faces either way."""
    rot = Rotation.from_quat(shape.quat_xyzw).as_matrix()
    centre = np.asarray(shape.position, dtype=np.float64)
    if shape.kind == "cylinder":
        return [Bar(rot[:, 2], centre, float(shape.size[1]), float(shape.size[0]))]
    along = int(np.argmax(np.abs(approach @ rot)))
    edges = [k for k in range(3) if k != along]
    return [Bar(rot[:, k], centre, float(shape.size[k]), float(shape.size[3 - along - k])) for k in edges]


def find_bars(model: ObjectModel, space: SearchSpace) -> list[Bar]:
    """The model's bars within 60° of square to the demonstrated approach (a bar along the approach, a cap, is no
    bar to slide along or pinch across): its exact cylinder or fitted primitive (``_shape_bars``), or else a mounted
    part's points spread ``BAR_ELONGATION`` times as long (principal axis) as they are wide across it and the
    approach (the 2nd to 98th percentile), its axis that half width behind the part's front."""
    approach = space.seed_rot[:, 2]
    shape = model.cylinder or model.primitive
    if shape is not None:
        bars = _shape_bars(shape, approach)
    elif model.mount is not None and np.count_nonzero(~model.mount) >= 3:
        part = model.points[~model.mount]
        axis = np.linalg.svd(part - part.mean(axis=0), full_matrices=False)[2][0]
        frame = _palm(approach - float(approach @ axis) * axis, axis).T  # rows: along, across, depth
        low, high = np.percentile(part @ frame.T, (2, 98), axis=0)
        half, width = 0.5 * (high - low)[:2]
        mid = np.array([0.5 * (low[0] + high[0]), 0.5 * (low[1] + high[1]), low[2] + width]) @ frame
        bars = [Bar(axis, mid, half, width)] if half >= BAR_ELONGATION * width else []
    else:
        bars = []
    return [bar for bar in bars if math.hypot(*(bar.axis @ space.seed_rot[:, :2])) >= 0.5]


def along_the_bar(
    model: ObjectModel, space: SearchSpace, _params: PlannerParams, _rng: np.random.Generator
) -> list[Proposal]:
    """The demonstrated palm slid ``SLIDES_M`` either way along the bar (its axis taken across the approach), at
    the pivot and held back, at ``TIP_SPREADS_RAD``, closed where it is. A bar is held anywhere along it, and the
    demonstrated place may be where a post or the fingers' sweep into the plate behind it gets in the way."""
    proposals = []
    for bar in find_bars(model, space):
        u, v = bar.axis @ space.seed_rot[:, :2] / math.hypot(*(bar.axis @ space.seed_rot[:, :2]))
        proposals += [
            Proposal("along the bar", _at(spread, space.pivot_m + back, 0.0, s * u, s * v), 0.0)
            for slide in SLIDES_M
            for s in (slide, -slide)
            for back in (0.0, HOLD_BACK_M)
            for spread in TIP_SPREADS_RAD
        ]
    return proposals


def pinch(model: ObjectModel, space: SearchSpace, params: PlannerParams, _rng: np.random.Generator) -> list[Proposal]:
    """On a mounted part: the demonstrated palm held back ``TIP_DISTANCES_M`` from the pivot, rolled ``ROLLS_RAD``,
    at ``TIP_SPREADS_RAD``, closed where it is: fingers curled round a bar reach 45 mm or more in front of the palm,
    so on a bar 20-50 mm before its plate they meet the plate; the open fingertips close 80-100 mm in front of it.
    On a part whose exact cylinder lies along the approach within the wrist's range (a cap), also the palm on its
    axis looking along it, that far before its top: from the axis the fingertips press the round side evenly, from
    the demonstrated palm, tilted and off the axis, they meet it at different heights and turn it."""
    if model.mount is None:
        return []
    states = [_at(spread, d, roll) for roll in ROLLS_RAD for d in TIP_DISTANCES_M for spread in TIP_SPREADS_RAD]
    if model.cylinder is not None:
        (cap,) = _shape_bars(model.cylinder, space.seed_rot[:, 2])
        along = float(cap.axis @ space.seed_rot[:, 2])
        if abs(along) >= math.cos(params.angle_limit_rad):
            rot = _palm(cap.axis if along > 0.0 else -cap.axis, space.seed_rot[:, 0])
            top = cap.centre - rot[:, 2] * cap.half_length
            states += [space.state(rot, top - rot[:, 2] * d, a) for d in TIP_DISTANCES_M for a in TIP_SPREADS_RAD]
    return [Proposal("pinch", s, 0.0) for s in states if space.inside(s)]


def square_pinch(
    model: ObjectModel, space: SearchSpace, _params: PlannerParams, _rng: np.random.Generator
) -> list[Proposal]:
    """On a part with a bar: palms square to the bar, +x along it, through its axis where it passes nearest the
    demonstrated palm, closed where they are (those outside the search space left out: tilted fingertips meet a round
    bar at different heights and a squeeze rolls it out of them). Thumb against fingers 1 and 2 (spread 0) with the
    fingertips closing on the bar's widest (``barrett.tip_depth``): tips meeting it short of or past its widest push
    it out or drag it rolling towards the palm as they squeeze. Fingers 1 and 2 face to face (spread π/2) with the
    palm ``TIP_DISTANCES_M`` from the bar."""
    proposals = []
    for bar in find_bars(model, space):
        x = bar.axis if float(bar.axis @ space.seed_rot[:, 0]) >= 0.0 else -bar.axis
        rot = _palm(space.seed_rot[:, 2] - float(space.seed_rot[:, 2] @ x) * x, x)
        z = rot[:, 2]
        half, radius = bar.half_length, bar.half_width
        through = bar.centre + float(np.clip((space.seed_pos - bar.centre) @ x, -half, half)) * x
        states = [space.state(rot, through - z * barrett.tip_depth(radius), TIP_SPREADS_RAD[0])]
        states += [space.state(rot, through - z * (radius + d), TIP_SPREADS_RAD[1]) for d in TIP_DISTANCES_M]
        proposals += [Proposal("square pinch", s, 0.0) for s in states if space.inside(s)]
    return proposals


GENERATORS: dict[str, Generator] = {
    "demonstrated": demonstrated,
    "annealed": annealed,
    "along the bar": along_the_bar,
    "pinch": pinch,
    "square pinch": square_pinch,
}
"""Every generator, by name: ``tasks.grasp.api.plan_on_model`` executes the proposals of all of them."""
