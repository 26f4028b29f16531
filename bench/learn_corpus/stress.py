"""The stress corpus: seeded demonstrations of doors, lids, caps, drawers, sliders and two-joint chains, with
their own motion and sensor models (apart from ``tasks/synth``).

Each case is drawn from ``np.random.default_rng([seed, index])``, so a case does not depend on how many are
drawn. Rates 10-240 Hz, jittered or uneven stamps, noise 0.1 mm to 2 cm per axis (isotropic or 5-10x worse
along the camera's depth), outliers, occlusion gaps, sparse and repeated samples, one to six markers on the
moving part, static markers, unnamed hand markers that reach, ride and retreat, a wrist pose stream, rigid-body
poses, open-then-close.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from bench.learn_corpus.case import Case, PoseTrack, Track
from bench.learn_corpus.mechanisms import (
    Mechanism,
    Move,
    apply,
    chain_transform,
    draw_mechanism,
    joint_values,
    path_length,
    truth_of,
)
from bench.learn_corpus.profiles import Profile, draw_profile, min_jerk
from bench.learn_corpus.rotations import (
    Array,
    matrix_from_quat,
    matrix_from_rotvec,
    perpendicular,
    quat_from_matrix,
    random_rotation,
    slerp,
    unit,
)
from bench.learn_corpus.sampling import (
    add_gaps,
    add_outliers,
    hold_repeats,
    marker_names,
    noise,
    rotation_noise,
    stamps,
    thin,
)

DEV_SEEDS = (1, 2, 3)
"""Seeds of the development part: the only cases constants may be tuned on."""
HELDOUT_SEEDS = (1001, 1002, 1003)
"""Seeds of the held-out part."""

MIN_PATH_PER_SIGMA = 25.0
"""A primitive's path is at least this many noise sigmas long: below that its kind is not decidable from the data."""
ANISO_CAP_GAIN = 2.0
"""With depth-heavy noise only one axis is at the largest sigma, so that sigma may be this much higher."""
MARKER_SPACING_M = 0.1
"""Typical spacing of the markers a rigid-body tracker fits its orientation to (sets the orientation noise)."""

RIGID_BODY_NAMES = ("rb{j}", "RigidBody{j}", "Body {j}", "tracker_{j}")


def _loguniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(np.exp(rng.uniform(np.log(lo), np.log(max(hi, lo)))))


def _schedule(rng: np.random.Generator, mech: Mechanism, t0: float, open_close: bool) -> tuple[list[Move], float]:
    """One move per joint, innermost first, and a closing move of the last joint when ``open_close``."""
    moves: list[Move] = []
    t = t0
    last = len(mech.travels) - 1
    for j, travel in enumerate(mech.travels):
        duration = float(np.clip(path_length(mech, j, travel) / rng.uniform(0.1, 0.45), 0.8, 5.0))
        moves.append(Move(j, 0.0, travel, t, t + duration, draw_profile(rng)[1]))
        t += duration + rng.uniform(0.0 if j == last else 0.2, 0.8)
    if open_close:
        travel = mech.travels[last]
        back = travel * rng.uniform(0.5, 1.0)
        duration = float(np.clip(path_length(mech, last, back) / rng.uniform(0.1, 0.45), 0.8, 5.0))
        moves.append(Move(last, travel, travel - back, t, t + duration, draw_profile(rng)[1]))
        t += duration
    return moves, t


def _motion_fraction(moves: list[Move], t: Array) -> Array:
    """Fraction (n,) of the total joint travel done by time ``t`` (drives the hand's slip on the handle)."""
    total = sum(abs(m.q_to - m.q_from) for m in moves)
    done = np.zeros(len(t))
    for m in moves:
        done += abs(m.q_to - m.q_from) * m.profile((t - m.t_start) / (m.t_end - m.t_start))
    return done / total


class HandPath:
    """The demonstrator's hand frame: rests, reaches the handle along a curved path while the object rests,
    rides with the moving part (slipping a few millimetres), then retreats along another curve and rests."""

    def __init__(
        self,
        rng: np.random.Generator,
        mech: Mechanism,
        moves: list[Move],
        reach: tuple[float, float],
        retreat: tuple[float, float],
    ) -> None:
        self.mech, self.moves, self.reach, self.retreat = mech, moves, reach, retreat
        self.grasp_pos = mech.handle + unit(rng.normal(size=3)) * rng.uniform(0.02, 0.05)
        self.grasp_rot = random_rotation(rng)
        self.slip = unit(rng.normal(size=3)) * rng.uniform(0.001, 0.005)
        self.start_pos = self.grasp_pos + unit(rng.normal(size=3)) * rng.uniform(0.25, 0.6)
        self.start_rot = (
            matrix_from_rotvec((unit(rng.normal(size=3)) * rng.uniform(0.3, 1.0))[None])[0] @ self.grasp_rot
        )
        self.reach_bulge = perpendicular(unit(self.grasp_pos - self.start_pos), rng) * rng.uniform(0.05, 0.2)
        self.retreat_dir = unit(rng.normal(size=3)) * rng.uniform(0.25, 0.6)
        self.retreat_bulge = perpendicular(unit(self.retreat_dir), rng) * rng.uniform(0.05, 0.2)
        self.turn = matrix_from_rotvec((unit(rng.normal(size=3)) * rng.uniform(0.3, 1.0))[None])[0]
        self.reach_profile: Profile = draw_profile(rng)[1]
        self.retreat_profile: Profile = min_jerk if rng.uniform() < 0.5 else draw_profile(rng)[1]

    def _ride(self, t: Array) -> tuple[Array, Array]:
        q = joint_values(self.moves, len(self.mech.joints), t)
        rot, trans = chain_transform(self.mech.joints, q)
        local = self.grasp_pos + self.slip * _motion_fraction(self.moves, t)[:, None]
        return rot @ self.grasp_rot, np.einsum("nij,nj->ni", rot, local) + trans

    def pose(self, t: Array) -> tuple[Array, Array]:
        """Hand frame rotations (n, 3, 3) and positions (n, 3) m at times ``t`` s."""
        rot, pos = self._ride(t)
        u = self.reach_profile((t - self.reach[0]) / (self.reach[1] - self.reach[0]))
        mid = 0.5 * (self.start_pos + self.grasp_pos) + self.reach_bulge
        bez = (
            ((1 - u) ** 2)[:, None] * self.start_pos
            + (2 * u * (1 - u))[:, None] * mid
            + (u**2)[:, None] * self.grasp_pos
        )
        q_start = np.broadcast_to(quat_from_matrix(self.start_rot), (len(t), 4))
        q_grasp = np.broadcast_to(quat_from_matrix(self.grasp_rot), (len(t), 4))
        before = t < self.reach[1]
        pos = np.where(before[:, None], bez, pos)
        rot = np.where(before[:, None, None], matrix_from_quat(slerp(q_start, q_grasp, u)), rot)
        rot_rel, pos_rel = self._ride(np.array([self.retreat[0]]))
        v = self.retreat_profile((t - self.retreat[0]) / (self.retreat[1] - self.retreat[0]))
        end = pos_rel[0] + self.retreat_dir
        mid = 0.5 * (pos_rel[0] + end) + self.retreat_bulge
        bez = ((1 - v) ** 2)[:, None] * pos_rel[0] + (2 * v * (1 - v))[:, None] * mid + (v**2)[:, None] * end
        q_rel = np.broadcast_to(quat_from_matrix(rot_rel[0]), (len(t), 4))
        q_end = np.broadcast_to(quat_from_matrix(self.turn @ rot_rel[0]), (len(t), 4))
        after = t > self.retreat[0]
        pos = np.where(after[:, None], bez, pos)
        rot = np.where(after[:, None, None], matrix_from_quat(slerp(q_rel, q_end, v)), rot)
        return rot, pos


def _object_points(rng: np.random.Generator, mech: Mechanism) -> list[Array]:
    """One to six marker positions (m, world, q = 0) on the innermost link; the first is the handle."""
    n = int(rng.choice([1, 2, 3, 4, 5, 6], p=[0.3, 0.2, 0.2, 0.12, 0.1, 0.08]))
    reach = max(0.03, 0.6 * mech.part_size_m)
    return [mech.handle] + [mech.handle + unit(rng.normal(size=3)) * rng.uniform(0.02, reach) for _ in range(n - 1)]


def _static_points(rng: np.random.Generator, mech: Mechanism) -> list[Array]:
    """One or two markers on the fixed frame: beside the outer hinge, or behind the drawer's front."""
    outer = mech.joints[-1]
    pts = []
    for _ in range(int(rng.integers(1, 3))):
        side = perpendicular(outer.dir, rng) * rng.uniform(0.03, 0.1)
        if outer.kind == "rotation":
            pts.append(outer.pos + outer.dir * rng.uniform(-0.3, 0.3) + side)
        else:
            pts.append(mech.handle - outer.dir * rng.uniform(0.05, 0.2) + side)
    return pts


def stress_case(seed: int, index: int, *, clean: bool = False) -> Case:
    """Case ``index`` of the stress corpus drawn with ``seed``; ``clean`` leaves out position noise, outliers and
    repeated samples (the same motion, stamps, gaps and names)."""
    rng = np.random.default_rng([seed, index])
    mech = draw_mechanism(rng)
    tags: list[str] = [mech.name]
    hand_markers = rng.uniform() < 0.45
    wrist = rng.uniform() < 0.25
    t = rng.uniform(0.3, 1.0)
    reach = (t, t + rng.uniform(0.8, 2.0))
    if hand_markers or wrist:
        t = reach[1] + rng.uniform(0.1, 0.5)
    open_close = rng.uniform() < (0.35 if len(mech.joints) == 1 else 0.2)
    moves, t = _schedule(rng, mech, t, open_close)
    retreat_start = t + rng.uniform(0.1, 0.5)
    retreat = (retreat_start, retreat_start + rng.uniform(0.6, 1.5))
    duration = (retreat[1] if hand_markers or wrist else t) + rng.uniform(0.3, 1.0)
    hand = HandPath(rng, mech, moves, reach, retreat)

    named = rng.uniform() < 0.08
    obj = _object_points(rng, mech)
    static = _static_points(rng, mech) if rng.uniform() < 0.25 else []
    hand_offsets = [unit(rng.normal(size=3)) * rng.uniform(0.01, 0.06) for _ in range(int(rng.integers(1, 3)))]
    if not hand_markers:
        hand_offsets = []
    if named:
        names = [f"{mech.name}/m{k}" for k in range(len(obj))] + [f"frame/m{k}" for k in range(len(static))]
        names += ["hand", "right_thumb"][: len(hand_offsets)]
    else:
        names = marker_names(rng, len(obj) + len(static) + len(hand_offsets))
    roles = ["object"] * len(obj) + ["static"] * len(static) + ["hand"] * len(hand_offsets)
    local = obj + static + hand_offsets
    role_of = dict(zip(names, roles, strict=True))
    pose = rng.uniform() < 0.25
    pose_only = pose and rng.uniform() < 0.35
    body = str(rng.choice(RIGID_BODY_NAMES)).format(j=int(rng.integers(1, 5)))
    body_origin = np.mean(obj, axis=0)
    body_rot0 = random_rotation(rng)

    hz = _loguniform(rng, 10.0, 240.0)
    timing = str(rng.choice(["uniform", "jitter", "uneven"], p=[0.4, 0.35, 0.25]))
    asynchronous = rng.uniform() < 0.3
    carrier, carrier_name = (replace(mech, handle=body_origin), body) if pose_only else (mech, names[0])
    truth = truth_of(carrier, moves, carrier_name)
    min_path = min(p.extent * (p.radius_m if p.radius_m is not None else 1.0) for p in truth)
    aniso = rng.uniform() < 0.3
    cap = min(0.02, min_path / MIN_PATH_PER_SIGMA * (ANISO_CAP_GAIN if aniso else 1.0))
    noise_m = rng.uniform(0.5 * cap, cap) if rng.uniform() < 0.15 else _loguniform(rng, 1e-4, cap)
    sigma_lat = noise_m / rng.uniform(5.0, 10.0) if aniso else noise_m
    depth_dir = unit(mech.handle)
    corr_s = rng.uniform(0.02, 0.1) if rng.uniform() < 0.15 else 0.0
    outliers = rng.uniform() < 0.1
    gaps = rng.uniform() < 0.3
    repeats = rng.uniform() < 0.1
    sparse = hz >= 40.0 and rng.uniform() < 0.25
    shared_t = stamps(rng, hz, duration, timing)
    gain = 0.0 if clean else 1.0

    markers: dict[str, Track] = {}
    for k, (name, role, x) in enumerate(zip(names, roles, local, strict=True)):
        tm = shared_t
        if asynchronous and k > 0:
            tm = stamps(rng, hz, duration, timing) + rng.uniform(0.0, 1.0 / hz)
            tm = tm[tm <= duration]
        if role == "object":
            xyz = apply(chain_transform(mech.joints, joint_values(moves, len(mech.joints), tm)), x)
        elif role == "static":
            xyz = np.broadcast_to(x, (len(tm), 3)).copy()
        else:
            rot, pos = hand.pose(tm)
            xyz = pos + rot @ x
        xyz = xyz + gain * noise(rng, tm, sigma_lat, noise_m, depth_dir=depth_dir, corr_s=corr_s)
        if outliers:
            spoiled = add_outliers(rng, xyz, noise_m)
            xyz = xyz if clean else spoiled
        if repeats:
            spoiled = hold_repeats(rng, xyz)
            xyz = xyz if clean else spoiled
        if gaps:
            xyz = add_gaps(rng, tm, xyz, keep_before_s=0.3)
        if sparse:
            tm, xyz = thin(rng, tm, xyz, rng.uniform(max(0.2, 12.0 / hz), 0.5))
        if not (pose_only and role == "object"):
            markers[name] = (tm, xyz)
    order = rng.permutation(len(markers))
    keys = list(markers)
    markers = {keys[i]: markers[keys[i]] for i in order}

    poses: dict[str, PoseTrack] = {}
    if pose:
        rot, trans = chain_transform(mech.joints, joint_values(moves, len(mech.joints), shared_t))
        pos_noise = noise(rng, shared_t, sigma_lat, noise_m, depth_dir=depth_dir, corr_s=corr_s)
        pos = np.einsum("nij,j->ni", rot, body_origin) + trans + gain * pos_noise
        rot_noise = rotation_noise(rng, len(shared_t), gain * min(0.05, noise_m / MARKER_SPACING_M))
        poses[body] = (shared_t, pos, quat_from_matrix(rot_noise @ rot @ body_rot0))
        tags += ["pose", "pose-only"] if pose_only else ["pose"]
    wrist_track: PoseTrack | None = None
    if wrist:
        tw = stamps(rng, rng.uniform(30.0, 120.0), duration, "jitter")
        rot, pos = hand.pose(tw)
        offset = np.array([-0.08, 0.0, 0.0])
        wpos = pos + rot @ offset + gain * rng.normal(0.0, 0.001, size=(len(tw), 3))
        wrot = rotation_noise(rng, len(tw), gain * np.radians(0.5)) @ rot
        wrist_track = (tw, wpos, quat_from_matrix(wrot))

    flags = {
        "chain": len(mech.joints) > 1,
        "open-close": open_close,
        "hand": bool(hand_offsets),
        "wrist": wrist,
        "static": bool(static),
        "named": named,
        timing: timing != "uniform",
        "async": asynchronous,
        "aniso": aniso,
        "colored": corr_s > 0,
        "outliers": outliers,
        "gaps": gaps,
        "repeats": repeats,
        "sparse": sparse,
    }
    tags += [tag for tag, on in flags.items() if on]
    return Case(
        name=f"stress-{seed}-{index:03d}-{mech.name}",
        markers=markers,
        poses=poses,
        wrist=wrist_track,
        truth=truth,
        noise_m=noise_m,
        hz=hz,
        tags=tuple(tags),
        check_axis=True,
        radius_tol_m=None,
        roles={**{n: role_of[n] for n in markers}, **dict.fromkeys(poses, "body")},
    )


def stress_cases(seed: int, n: int) -> list[Case]:
    """The first ``n`` cases of the stress corpus drawn with ``seed``."""
    return [stress_case(seed, i) for i in range(n)]


def dev_cases(n_per_seed: int) -> list[Case]:
    """The development part: ``n_per_seed`` cases of each of ``DEV_SEEDS``."""
    return [case for seed in DEV_SEEDS for case in stress_cases(seed, n_per_seed)]


def heldout_cases(n_per_seed: int) -> list[Case]:
    """The held-out part: ``n_per_seed`` cases of each of ``HELDOUT_SEEDS``."""
    return [case for seed in HELDOUT_SEEDS for case in stress_cases(seed, n_per_seed)]
