"""The online eigengrasp planner (Ciocarlie & Allen; GraspIt!'s online planner as used by Dang & Allen).

Search space (GraspIt!'s approach space around the demonstrated palm pose): x = (a1, a2, d, θ1, θ2) with
eigengrasp amplitudes a1, a2 in ±4, approach distance d in -30..200 mm (palm to the pivot point along the approach
axis, negative = past it), roll θ1 about the approach axis and tilt θ2 about the palm x axis, both
within ±60° and both pivoting about the point where the seed's approach ray meets the object. Energy is the
contact energy over the virtual contacts (``contact_energy``), vectorised with a KD-tree over the object points;
states where the hand's surface samples enter the object are illegal. The lowest-energy distinct states (in
three spread ranges) and a few pre-grasps on the seed's approach line are then tried in pybullet: approach up
to 30 mm to contact, close the fingers until contact, epsilon and volume of the grasp wrench space.
Force-closure grasps (epsilon >= 0.05 first) are ranked by closeness to the demonstrated palm pose.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np
import pybullet as pb
from scipy.spatial.transform import Rotation

from tasks.arrays import FloatArray, Vector3
from tasks.grasp import barrett, closing
from tasks.grasp.anneal import ILLEGAL_ENERGY, AnnealTrace, Schedule, anneal
from tasks.grasp.object_model import ObjectModel, load_object
from tasks.grasp.quality import DEFAULT_MU, GraspQuality, grasp_quality

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
LINE_SPREADS = (-1.13, 0.0)
LINE_POSES = (
    *((dist, 0.0, a2) for dist in (0.005, 0.035, 0.065) for a2 in (0.0, -0.68, -1.37)),
    (0.005, math.radians(45.0), 0.0),
    (0.005, math.radians(-45.0), 0.0),
)
"""Besides the annealed states, pre-grasps on the seed's approach line are tried, (distance m, roll rad, a2):
palm 5, 35 or 65 mm before the pivot with the fingers at 0.79, 0.4 or 0 rad (flat), and rolled ±45° at 5 mm, each
with spread 0 and 1.13 rad (then opened or curled until free of the object). The contact energy favours
curled fingers beside thin parts; these cover the demonstrator's own approach."""
PRESHAPE_OPENINGS_RAD = (0.0, 0.8)
"""Each posture is tried as it is and, unless that gives a good force closure, with its fingers opened by 0.8 rad."""
BACK_OFF_M = 0.02
"""A pre-grasp found in collision in pybullet is moved back along its approach axis by up to 20 mm."""


@dataclass(frozen=True)
class PlannerParams:
    """Planner settings: annealing steps and chains, candidates tried in pybullet, ranges, friction, ranking."""

    steps: int = 400
    chains: int = 4
    candidates: int = 12
    schedule: Schedule = field(default_factory=Schedule)
    distance_range_m: tuple[float, float] = (-0.03, 0.20)
    angle_limit_rad: float = math.radians(60.0)
    amplitude_limit: float = barrett.AMPLITUDE_LIMIT
    approach_max_m: float = 0.03
    mu: float = DEFAULT_MU
    position_scale_m: float = 0.05
    angle_scale_rad: float = math.radians(30.0)
    max_pivot_m: float = 0.20


@dataclass(frozen=True)
class GraspCandidate:
    """A grasp tried in pybullet: state x (5,), palm pose (world), closed joints (7,), quality, ranking cost."""

    state: FloatArray
    position: Vector3
    quat_xyzw: FloatArray
    closed: FloatArray
    quality: GraspQuality
    energy: float
    closeness: float


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


def _better(a: GraspCandidate, b: GraspCandidate) -> bool:
    """Whether ``a`` beats ``b`` for the same annealed state: better tier, then larger epsilon."""
    return (rank_tier(a.quality), -a.quality.epsilon) < (rank_tier(b.quality), -b.quality.epsilon)


def rank_tier(quality: GraspQuality) -> int:
    """0: force closure with epsilon >= ``MIN_GOOD_EPSILON``; 1: weaker force closure; 2: no force closure."""
    if not quality.force_closure:
        return 2
    return 0 if quality.epsilon >= MIN_GOOD_EPSILON else 1


def closeness(rot: FloatArray, pos: Vector3, seed_rot: FloatArray, seed_pos: Vector3, params: PlannerParams) -> float:
    """Ranking cost: palm offset from the seed over 50 mm plus rotation angle over 30° (unitless)."""
    angle = float(Rotation.from_matrix(seed_rot.T @ rot).magnitude())
    return float(np.linalg.norm(pos - seed_pos)) / params.position_scale_m + angle / params.angle_scale_rad


def _free_pregrasp(  # noqa: PLR0917 -- private helper
    client_id: int, hand: int, obj: int, rot: FloatArray, pos: Vector3, quat: FloatArray, dofs: FloatArray
) -> tuple[Vector3, FloatArray] | None:
    """The nearest collision-free pre-grasp: back off along the approach axis in 4 mm steps (up to 20 mm) and
    at each step try finger angles within 0.8 rad of the given ones (0.1 rad steps); all back-offs with opening
    fingers first, then with curling ones (the eigengrasp keeps the three fingers equal); None when nothing is free."""
    approach = rot[:, 2]
    start = float(dofs[1])
    steps = np.arange(1, 9) * 0.1
    opening = [a for a in start - steps if a >= 0.0] + ([0.0] if start > 0.0 else [])
    curling = [a for a in start + steps if a <= float(barrett.DOF_UPPER[1])]
    angles = opening + curling
    backs = np.arange(0.0, BACK_OFF_M + 1e-9, 0.004)
    for angles in ([start, *opening], curling):
        for back in backs:
            trial_pos = pos - back * approach
            closing.set_pose(client_id, hand, trial_pos, quat)
            for angle in angles:
                trial = dofs.copy()
                trial[1:] = angle if angle != start else dofs[1:]
                barrett.apply_dofs(client_id, hand, trial)
                if closing.min_distance(client_id, hand, obj) >= 0.0:
                    return trial_pos, trial
    return None


def evaluate_pose(  # noqa: PLR0917 -- pybullet ids, model, pose, posture, params
    client_id: int,
    hand: int,
    obj: int,
    model: ObjectModel,
    rot: FloatArray,
    pos: Vector3,
    dofs: FloatArray,
    params: PlannerParams,
) -> tuple[Vector3, FloatArray, FloatArray, GraspQuality] | None:
    """Approach, close and score one pre-grasp in pybullet; a pre-grasp in collision first opens its fingers,
    then backs off up to 20 mm along the approach axis; None when it is still in collision. Returns the palm
    position after the approach, the pre-grasp DOFs used (4,), the closed joints (7,) and the quality."""
    quat = Rotation.from_matrix(rot).as_quat()
    closing.set_pose(client_id, hand, pos, quat)
    barrett.apply_dofs(client_id, hand, dofs)
    free = _free_pregrasp(client_id, hand, obj, rot, pos, quat, dofs)
    if free is None:
        return None
    pos, dofs = free
    final_pos = closing.approach_to_contact(client_id, hand, obj, pos, quat, params.approach_max_m)
    closed = closing.close_fingers(client_id, hand, obj, dofs)
    contacts = closing.contacts_of(client_id, hand, obj)
    quality = grasp_quality(contacts.positions, contacts.normals_in, model.center, model.radius, params.mu)
    return final_pos, dofs, closed, quality


def search(
    model: ObjectModel,
    seed_rot: FloatArray,
    seed_pos: Vector3,
    rng: np.random.Generator,
    params: PlannerParams | None = None,
) -> list[GraspCandidate]:
    """Anneal from the seed, try the best distinct states in pybullet; all candidates, force closure first
    and then by closeness to the seed."""
    prm = params or PlannerParams()
    space = ApproachSpace(seed_rot, seed_pos, pivot_distance(model, seed_rot, seed_pos, prm.max_pivot_m))
    lim = prm.amplitude_limit
    ang = prm.angle_limit_rad
    lower = np.array([-lim, -lim, prm.distance_range_m[0], -ang, -ang])
    upper = np.array([lim, lim, prm.distance_range_m[1], ang, ang])
    jump = (upper - lower) / 2.0

    def energy(x: FloatArray) -> float:
        rot, pos = space.pose(x)
        return contact_energy(model, rot, pos, barrett.dofs_from_eigengrasps(float(x[0]), float(x[1])))

    d0 = float(np.clip(space.pivot_m, *prm.distance_range_m))
    starts = [np.array([a1, -1.0, d0, 0.0, 0.0]) for a1 in CHAIN_SPREADS[: prm.chains]]
    traces = [anneal(energy, s, lower, upper, jump, prm.steps, rng, prm.schedule) for s in starts]
    pooled = AnnealTrace(np.concatenate([t.states for t in traces]), np.concatenate([t.energies for t in traces]), 0)
    spreads = np.array([barrett.dofs_from_eigengrasps(float(a), 0.0)[0] for a in pooled.states[:, 0]])
    per_bin = max(1, prm.candidates // (len(SPREAD_BINS) - 1))
    picks: list[tuple[FloatArray, float]] = []
    for lo, hi in itertools.pairwise(SPREAD_BINS):
        sel = np.flatnonzero((spreads >= lo) & (spreads < hi))
        sub = AnnealTrace(pooled.states[sel], pooled.energies[sel], 0)
        picks += [(sub.states[i], float(sub.energies[i])) for i in _select(sub, per_bin, upper - lower)]

    for a1, (dist, roll, a2) in itertools.product(LINE_SPREADS, LINE_POSES):
        x = np.array([a1, a2, dist, roll, 0.0])
        picks.append((x, energy(x)))
    client = pb.connect(pb.DIRECT)
    try:
        obj = load_object(client, model)
        hand = barrett.load_hand(client)
        out: list[GraspCandidate] = []
        for x, e in picks:
            rot, pos = space.pose(x)
            quat = Rotation.from_matrix(rot).as_quat()
            best: GraspCandidate | None = None
            for opening in PRESHAPE_OPENINGS_RAD:
                dofs = barrett.dofs_from_eigengrasps(float(x[0]), float(x[1]))
                dofs[1:] = np.maximum(dofs[1:] - opening, 0.0)
                result = evaluate_pose(client, hand, obj, model, rot, pos, dofs, prm)
                if result is None:
                    continue
                final_pos, pre_dofs, closed, quality = result
                state = x.copy()
                state[1] = barrett.eigengrasps_from_dofs(pre_dofs)[1]
                cost = closeness(rot, final_pos, seed_rot, seed_pos, prm)
                cand = GraspCandidate(state, final_pos, quat, closed, quality, e, cost)
                if best is None or _better(cand, best):
                    best = cand
                if rank_tier(best.quality) == 0:
                    break
            if best is not None:
                out.append(best)
    finally:
        pb.disconnect(client)
    out.sort(key=lambda c: (rank_tier(c.quality), c.closeness))
    return _distinct(out)


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
