"""The online eigengrasp planner (Ciocarlie & Allen; GraspIt!'s online planner as used by Dang & Allen).

Search space (GraspIt!'s approach space around the demonstrated palm pose): x = (a1, a2, d, θ1, θ2) with
eigengrasp amplitudes a1, a2 in ±4, approach distance d in -30..200 mm (palm to the pivot point along the approach
axis, negative = past it), roll θ1 about the approach axis and tilt θ2 about the palm x axis, both
within ±25° (GraspIt!'s ±60° let distant grasps win) and both pivoting about the point where the seed's approach
ray meets the object. Energy is the contact energy over the virtual contacts (``contact_energy``), vectorised with
a KD-tree over the object points; states where the hand's surface samples enter the object are illegal. The
demonstrated pose itself, a few poses on its approach, and the lowest-energy distinct states (in three spread
ranges) are then executed in pybullet as the robot executes a grasp: the hand open at the state's spread (fingers
``barrett.OPEN_FINGER_RAD``), approach up to 30 mm to contact, close the fingers until contact; epsilon and
volume of the grasp wrench space. Grasps off the demonstrated approach by more than 20 mm or 25° are set aside;
the rest, force closure first, are ranked by closeness to the demonstration (``closeness``).
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import math
from dataclasses import dataclass, field

import numpy as np
import pybullet as pb
from scipy.spatial.transform import Rotation

from tasks.arrays import FloatArray, Vector3
from tasks.grasp import closing, worker_pool
from tasks.grasp.anneal import ILLEGAL_ENERGY, AnnealTrace, Schedule, anneal, annealing_draws
from tasks.grasp.object_model import ObjectModel, load_object
from tasks.grasp.quality import DEFAULT_MU, GraspQuality, grasp_quality
from tasks.grasp.worker_pool import Beside
from tasks.hand import barrett

NORMAL_WEIGHT_MM = 50.0
"""Contact energy: weight of the misalignment term 1 - n·p, in mm (GraspIt!'s contactEnergy)."""
PENETRATION_TOL_M = 0.0015
"""A surface sample of the hand deeper than 1.5 mm inside the object makes a state illegal."""
MIN_GOOD_EPSILON = 0.05
"""Force-closure grasps below this epsilon rank after the others (they rarely survive the shake test)."""
SPREAD_BINS = (0.0, 0.7, 2.0, 4.0)
"""Candidates are taken from each spread range (rad): fingers opposing the thumb, tripod, hook."""
CHAIN_SPREADS = (-1.13, 0.0, 0.44, 2.0, -0.5, 1.2)
"""Start amplitude a1 of each annealing chain: spread 0, 1.13 (origin), π/2 and π, then in between."""
LINE_SPREADS = (-1.13, 0.0, math.pi / 2 - 1.13)
LINE_POSES = tuple((back, math.radians(roll)) for back in (0.0, 0.02) for roll in (0.0, 15.0, -15.0))
"""Besides the annealed states, the demonstrated pose itself and its neighbours on the demonstrated approach are
tried: (palm m behind the demonstrated palm, roll rad about the approach), each with spread 0, 1.13 and π/2 rad
(fingers 1 and 2 face to face: on the scenes' bar handles often the only force closure at the demonstrated palm)."""
OPEN_MIN_RAD = barrett.OPEN_FINGER_RAD - 0.75
"""How far the planner may open the fingers when the open hand touches the object model at a pose: 0.75 rad
wider, as the simulated robot does (``tasks.simulate.hand.WIDER_OPENINGS_RAD``). Round 1 let them open down to
flat for the sparse models of the time; from flat a closing finger sweeps into the face behind a handle."""
PREGRASP_TOL_M = 0.004
"""An open pre-grasp may touch the object model by up to 4 mm (the fingertips grazing the face behind a handle at
the demonstrated palm; 2 mm lost it on the sample recordings, seeded 2 mm off): the fingers close away from it
(``closing.close_fingers`` stops a finger only when blocked)."""
BACK_OFF_M = 0.02
"""A pre-grasp found in collision in pybullet is moved back along its approach axis by up to 20 mm."""
LIMIT_TOL_M = 1e-6
"""Offsets within 1 µm of a neighbourhood limit count as inside it: the demonstrated approach's poses 20 mm behind
the demonstrated palm (``LINE_POSES``) lie on the 20 mm limit, and rounding put some outside it (a door lever's
only grasp that held)."""


@dataclass(frozen=True)
class PlannerParams:
    """Planner settings: annealing steps and chains, candidates tried in pybullet, ranges (the wrist angles
    within ±25°: a grasp must stay near the demonstration), friction; ranking scales (lateral offset from the
    demonstrated approach 20 mm, angle 20°, advance along it 50 mm, behind the demonstrated palm 10 mm) and the
    neighbourhood a grasp must lie in (20 mm off the demonstrated approach, 25°, at most 12 mm past the
    demonstrated palm along it: a palm moved 14-29 mm onto the bottle's cap left fewer than two fingers on it in
    execution). ``focus_radius_m``: when set,
    only contacts that close to where the demonstrated approach meets the object count for the quality (off by
    default: a wrap's contacts spread over the whole part, and leaving the far ones out denies most grasps a force
    closure they have)."""

    steps: int = 400
    chains: int = 4
    candidates: int = 12
    schedule: Schedule = field(default_factory=Schedule)
    distance_range_m: tuple[float, float] = (-0.03, 0.20)
    angle_limit_rad: float = math.radians(25.0)
    amplitude_limit: float = barrett.AMPLITUDE_LIMIT
    approach_max_m: float = 0.03
    mu: float = DEFAULT_MU
    position_scale_m: float = 0.02
    angle_scale_rad: float = math.radians(20.0)
    advance_scale_m: float = 0.05
    behind_scale_m: float = 0.01
    near_position_m: float = 0.02
    near_angle_rad: float = math.radians(25.0)
    near_advance_m: float = 0.012
    max_pivot_m: float = 0.20
    focus_radius_m: float | None = None


@dataclass(frozen=True)
class GraspCandidate:
    """A grasp tried in pybullet: state x (5,), palm pose (world), closed joints (7,), quality, ranking cost,
    its offset (m) from the demonstrated approach and angle (rad) from the demonstrated palm, whether it lies
    within the planner's neighbourhood (``near``), and whether it does but for having advanced further along the
    demonstrated approach (``reach``: the palm moved on towards an object the demonstrated palm stops short of)."""

    state: FloatArray
    position: Vector3
    quat_xyzw: FloatArray
    closed: FloatArray
    quality: GraspQuality
    energy: float
    closeness: float
    offset_m: float
    angle_rad: float
    near: bool
    reach: bool = False


@dataclass(frozen=True)
class ApproachSpace:
    """The seed palm pose (rotation (3, 3), position (3,) m, world) and the pivot distance along its approach."""

    seed_rot: FloatArray
    seed_pos: Vector3
    pivot_m: float

    def pose(self, state: FloatArray) -> tuple[FloatArray, Vector3]:
        """Palm rotation (3, 3) and position (3,) in the world for state (a1, a2, d, θ1, θ2)."""
        rot = self.seed_rot @ _rot_x(float(state[4])) @ _rot_z(float(state[3]))
        pivot = self.seed_pos + self.seed_rot[:, 2] * self.pivot_m
        return rot, pivot - rot[:, 2] * float(state[2])


def _rot_x(a: float) -> FloatArray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rot_z(a: float) -> FloatArray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def pivot_distance(model: ObjectModel, seed_rot: FloatArray, seed_pos: Vector3, limit_m: float) -> float:
    """Distance (m) along the seed's approach axis to the object (nearest point within 15 mm of the ray)."""
    approach = seed_rot[:, 2]
    rel = model.points - seed_pos
    along = rel @ approach
    off = np.linalg.norm(rel - along[:, None] * approach, axis=1)
    hit = (along > 0) & (off < 0.015)
    if np.any(hit):
        return float(min(along[hit].min(), limit_m))
    _, i = model.tree.query(seed_pos)
    return float(np.clip(along[i], 0.0, limit_m))


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
    approach = vc_dir @ rot.T
    align = 1.0 + np.einsum("ij,ij->i", model.normals[idx], approach)  # 1 - n_in · p
    return float(np.mean(1000.0 * dist + NORMAL_WEIGHT_MM * align))


def _select(trace: AnnealTrace, count: int, scale: FloatArray) -> list[int]:
    """Indices of up to ``count`` lowest-energy legal states, each distinct from those chosen before."""
    order = np.argsort(trace.energies, kind="stable")
    chosen: list[int] = []
    for i in order:
        if trace.energies[i] >= ILLEGAL_ENERGY or len(chosen) >= count:
            break
        if all(np.max(np.abs(trace.states[i] - trace.states[j]) / scale) > 0.1 for j in chosen):
            chosen.append(int(i))
    return chosen


def rank_tier(quality: GraspQuality) -> int:
    """0: force closure; 2: no force closure (1 is kept for weak closures, unused)."""
    return 0 if quality.force_closure else 2


@dataclass(frozen=True)
class DemoOffset:
    """Where a palm pose lies from the demonstration: offset (m) from the demonstrated approach segment (the
    demonstrated palm moved up to ``approach_max_m`` along its approach, no further than the object), advance
    (m) along the approach from the demonstrated palm (negative = behind it), angle (rad) between the palms."""

    lateral_m: float
    advance_m: float
    angle_rad: float


def demo_offset(rot: FloatArray, pos: Vector3, space: ApproachSpace, params: PlannerParams) -> DemoOffset:
    """Offset of a palm pose (rotation (3, 3), position (3,) m, world) from the demonstrated one."""
    approach = space.seed_rot[:, 2]
    rel = pos - space.seed_pos
    advance = float(rel @ approach)
    on_segment = float(np.clip(advance, 0.0, min(max(space.pivot_m, 0.0), params.approach_max_m)))
    lateral = float(np.linalg.norm(rel - on_segment * approach))
    angle = float(Rotation.from_matrix(space.seed_rot.T @ rot).magnitude())
    return DemoOffset(lateral, advance, angle)


def closeness(offset: DemoOffset, params: PlannerParams) -> float:
    """Ranking cost (unitless): offset over 20 mm + angle over 20° + advance over 50 mm, or distance behind the
    demonstrated palm over 10 mm (a palm held back reaches the part with the fingertips only)."""
    return (
        offset.lateral_m / params.position_scale_m
        + offset.angle_rad / params.angle_scale_rad
        + max(offset.advance_m, 0.0) / params.advance_scale_m
        + max(-offset.advance_m, 0.0) / params.behind_scale_m
    )


def is_near(offset: DemoOffset, params: PlannerParams) -> bool:
    """Whether a grasp lies in the demonstration's neighbourhood (lateral offset, angle and advance along the
    demonstrated approach within the limits)."""
    return (
        offset.lateral_m <= params.near_position_m + LIMIT_TOL_M
        and offset.angle_rad <= params.near_angle_rad
        and offset.advance_m <= params.near_advance_m
    )


def is_reach(offset: DemoOffset, params: PlannerParams) -> bool:
    """Whether a grasp lies off the demonstrated approach by at most the neighbourhood's offset and angle, however
    far along it (the approach to contact bounds the advance: the palm stops at the object)."""
    return offset.lateral_m <= params.near_position_m + LIMIT_TOL_M and offset.angle_rad <= params.near_angle_rad


def _free_pregrasp(  # noqa: PLR0917 -- private helper
    client_id: int, hand: int, obj: int, rot: FloatArray, pos: Vector3, quat: FloatArray, spread: float
) -> tuple[Vector3, FloatArray] | None:
    """The nearest open pre-grasp free of the object (within ``PREGRASP_TOL_M``): the open hand
    (``closing.open_free``, no wider than ``OPEN_MIN_RAD``) at the pose, else moved back along the approach axis
    in 4 mm steps (up to 20 mm); None when nothing is free."""
    approach = rot[:, 2]
    for back in np.arange(0.0, BACK_OFF_M + 1e-9, 0.004):
        trial_pos = pos - back * approach
        closing.set_pose(client_id, hand, trial_pos, quat)
        dofs = closing.open_free(client_id, hand, obj, spread, OPEN_MIN_RAD, PREGRASP_TOL_M)
        if closing.min_distance(client_id, hand, obj) >= -PREGRASP_TOL_M:
            return trial_pos, dofs
    return None


def evaluate_pose(  # noqa: PLR0917 -- pybullet ids, model, pose, spread, params
    client_id: int,
    hand: int,
    obj: int,
    model: ObjectModel,
    rot: FloatArray,
    pos: Vector3,
    spread: float,
    params: PlannerParams,
    focus: Vector3 | None = None,
) -> tuple[Vector3, FloatArray, FloatArray, GraspQuality] | None:
    """Execute one grasp as the robot does, in pybullet: the hand open at ``spread`` (rad) at the pose (backed
    off up to 20 mm when in collision; None when still in collision), approach up to 30 mm to contact along +z,
    close the fingers until contact. With ``focus`` (world, m) and ``params.focus_radius_m`` set, only contacts
    that close to it count for the quality (the grasped part). Returns the palm position after the approach, the
    open DOFs used (4,), the closed joints (7,) and the quality."""
    quat = Rotation.from_matrix(rot).as_quat()
    free = _free_pregrasp(client_id, hand, obj, rot, pos, quat, spread)
    if free is None:
        return None
    pos, dofs = free
    final_pos = closing.approach_to_contact(client_id, hand, obj, pos, quat, params.approach_max_m)
    closed = closing.close_fingers(client_id, hand, obj, dofs)
    contacts = closing.contacts_of(client_id, hand, obj)
    positions, normals = contacts.positions, contacts.normals_in
    if focus is not None and params.focus_radius_m is not None and len(positions):
        keep = np.linalg.norm(positions - focus, axis=1) <= params.focus_radius_m
        positions, normals = positions[keep], normals[keep]
    quality = grasp_quality(positions, normals, model.center, model.radius, params.mu)
    return final_pos, dofs, closed, quality


def state_energy(model: ObjectModel, space: ApproachSpace, x: FloatArray) -> float:
    """``contact_energy`` (mm) of state x = (a1, a2, d, θ1, θ2) in ``space``."""
    rot, pos = space.pose(x)
    return contact_energy(model, rot, pos, barrett.dofs_from_eigengrasps(float(x[0]), float(x[1])))


@dataclass(frozen=True)
class SearchBox:
    """The annealing's bounds on x = (a1, a2, d, θ1, θ2): ``lower``, ``upper`` (5,)."""

    lower: FloatArray
    upper: FloatArray

    @property
    def jump(self) -> FloatArray:
        """(5,) neighbour scale: half the box's width in each variable."""
        return (self.upper - self.lower) / 2.0


def anneal_chains(
    model: ObjectModel,
    space: ApproachSpace,
    box: SearchBox,
    chains: list[tuple[FloatArray, FloatArray]],
    schedule: Schedule,
) -> list[AnnealTrace]:
    """Anneal each (start (5,), uniforms ``annealing_draws``) of ``chains`` over ``state_energy``, in order."""
    energy = functools.partial(state_energy, model, space)
    return [anneal(energy, x0, box.lower, box.upper, box.jump, draws, schedule) for x0, draws in chains]


def search(
    model: ObjectModel,
    seed_rot: FloatArray,
    seed_pos: Vector3,
    rng: np.random.Generator,
    params: PlannerParams | None = None,
) -> list[GraspCandidate]:
    """Anneal from the seed (``params.chains`` chains, each with its own block of ``rng``'s uniforms, the later half
    in a worker process beside this one when there are any; none: only the poses on the demonstrated approach), try
    the best distinct states and the demonstrated pose in pybullet; all candidates: near the demonstration first,
    force closure first, then by closeness to the demonstration."""
    prm = params or PlannerParams()
    space = ApproachSpace(seed_rot, seed_pos, pivot_distance(model, seed_rot, seed_pos, prm.max_pivot_m))
    lim = prm.amplitude_limit
    ang = prm.angle_limit_rad
    lower = np.array([-lim, -lim, prm.distance_range_m[0], -ang, -ang])
    upper = np.array([lim, lim, prm.distance_range_m[1], ang, ang])
    box = SearchBox(lower, upper)

    line: list[tuple[FloatArray, float]] = []
    for a1, (back, roll) in itertools.product(LINE_SPREADS, LINE_POSES):
        x = np.array([a1, 0.0, space.pivot_m + back, roll, 0.0])
        line.insert(0, (x, state_energy(model, space, x)))
    on_line = executing(model, space, line, prm, parts=1 if prm.chains else None)  # one worker while this anneals
    d0 = float(np.clip(space.pivot_m, *prm.distance_range_m))
    chains = [
        (np.array([a1, -1.0, d0, 0.0, 0.0]), annealing_draws(rng, prm.steps, len(lower)))
        for a1 in CHAIN_SPREADS[: prm.chains]
    ]
    here = len(chains) - len(chains) // 2 if worker_pool.workers() else len(chains)
    beside = Beside(anneal_chains, model, space, box, chains[here:], prm.schedule) if chains[here:] else None
    traces = anneal_chains(model, space, box, chains[:here], prm.schedule)
    traces += beside.result() if beside is not None else []
    picks: list[tuple[FloatArray, float]] = []
    spread_bins = SPREAD_BINS if traces else ()  # chains=0: the demonstrated approach's poses only
    if traces:
        pooled = AnnealTrace(
            np.concatenate([t.states for t in traces]), np.concatenate([t.energies for t in traces]), 0
        )
        spreads = np.array([barrett.dofs_from_eigengrasps(float(a), 0.0)[0] for a in pooled.states[:, 0]])
    per_bin = max(1, prm.candidates // (len(SPREAD_BINS) - 1))
    for lo, hi in itertools.pairwise(spread_bins):
        sel = np.flatnonzero((spreads >= lo) & (spreads < hi))
        sub = AnnealTrace(pooled.states[sel], pooled.energies[sel], 0)
        picks += [(sub.states[i], float(sub.energies[i])) for i in _select(sub, per_bin, box.upper - box.lower)]

    out = [cand for part in on_line + executing(model, space, picks, prm) for cand in part.result()]
    out.sort(key=lambda c: (not c.near, rank_tier(c.quality), c.closeness))
    return _distinct(out)


def execute_states(
    model: ObjectModel,
    space: ApproachSpace,
    picks: list[tuple[FloatArray, float]],
    params: PlannerParams,
    approach_max_m: float | None = None,
    *,
    demo: ApproachSpace | None = None,
) -> list[GraspCandidate]:
    """Execute each (state, energy) of ``picks`` in pybullet (``evaluate_pose``; the approach to contact up to
    ``approach_max_m`` m, ``params.approach_max_m`` when None) and return the candidates in the same order (those
    still in collision left out), with their offsets from the demonstration: ``demo``'s palm, ``space``'s when
    None."""
    run_prm = params if approach_max_m is None else dataclasses.replace(params, approach_max_m=approach_max_m)
    focus = space.seed_pos + space.seed_rot[:, 2] * space.pivot_m
    client = pb.connect(pb.DIRECT)
    try:
        obj = load_object(client, model)
        hand = barrett.load_hand(client)
        out: list[GraspCandidate] = []
        for x, e in picks:
            rot, pos = space.pose(x)
            spread = float(barrett.dofs_from_eigengrasps(float(x[0]), 0.0)[0])
            result = evaluate_pose(client, hand, obj, model, rot, pos, spread, run_prm, focus)
            if result is None:
                continue
            final_pos, _, closed, quality = result
            offset = demo_offset(rot, final_pos, demo or space, params)
            out.append(
                GraspCandidate(
                    x.copy(),
                    final_pos,
                    Rotation.from_matrix(rot).as_quat(),
                    closed,
                    quality,
                    e,
                    closeness(offset, params),
                    offset.lateral_m,
                    offset.angle_rad,
                    is_near(offset, params),
                    is_reach(offset, params),
                )
            )
    finally:
        pb.disconnect(client)
    return out


def executing(
    model: ObjectModel,
    space: ApproachSpace,
    picks: list[tuple[FloatArray, float]],
    params: PlannerParams,
    parts: int | None = None,
) -> list[Beside[list[GraspCandidate]]]:
    """``execute_states`` of ``picks`` in up to ``parts`` consecutive parts (by default one for each worker process,
    ``worker_pool``), now running there: their results, in order, are those of executing all of ``picks`` in one."""
    size = max(1, math.ceil(len(picks) / max(1, parts or worker_pool.workers())))
    return [Beside(execute_states, model, space, picks[i : i + size], params) for i in range(0, len(picks), size)]


def _distinct(candidates: list[GraspCandidate]) -> list[GraspCandidate]:
    """Drop candidates that closed into the same grasp as an earlier one (palm within 2 mm and 2°, joints
    within 0.02 rad): different pre-grasps often end in one grasp."""
    kept: list[GraspCandidate] = []
    for cand in candidates:
        same = any(
            np.linalg.norm(cand.position - k.position) < 0.002
            and abs(float(np.dot(cand.quat_xyzw, k.quat_xyzw))) > math.cos(math.radians(1.0))
            and np.max(np.abs(cand.closed - k.closed)) < 0.02
            for k in kept
        )
        if not same:
            kept.append(cand)
    return kept
