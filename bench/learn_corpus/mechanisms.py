"""Articulated mechanisms of the stress corpus: joints in a chain, a schedule of joint motions, and their truth.

Joints are listed innermost first: a point ``x`` on the innermost link is at ``T_{m-1}(q_{m-1}) ... T_0(q_0) x``
in the world (metres), where ``T_j`` rotates about the line ``(pos, dir)`` by ``q_j`` radians or translates along
``dir`` by ``q_j`` metres. Joint axes are given at the configuration ``q = 0``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.learn_corpus.case import TruthPrimitive
from bench.learn_corpus.profiles import Profile
from bench.learn_corpus.rotations import Array, matrix_from_axis_angle, perpendicular, random_rotation, unit


@dataclass(frozen=True)
class Joint:
    """One joint at ``q = 0``: ``kind`` "rotation" (``pos`` a point on the axis, m) or "translation"; unit ``dir``."""

    kind: str
    pos: Array
    dir: Array


@dataclass(frozen=True)
class Move:
    """Joint ``joint`` goes from ``q_from`` to ``q_to`` (rad or m) between ``t_start`` and ``t_end`` (s)."""

    joint: int
    q_from: float
    q_to: float
    t_start: float
    t_end: float
    profile: Profile


@dataclass(frozen=True)
class Mechanism:
    """A kinematic chain with its handle point (m, world, at ``q = 0``) and the joint travels to demonstrate."""

    name: str
    joints: tuple[Joint, ...]
    handle: Array
    travels: tuple[float, ...]
    part_size_m: float


Transform = tuple[Array, Array]


def joint_values(moves: list[Move], n_joints: int, t: Array) -> Array:
    """Joint values (n_joints, n) at times ``t`` (s): each move's profile, holding between moves."""
    q = np.zeros((n_joints, len(t)))
    for m in sorted(moves, key=lambda m: m.t_start):
        u = (t - m.t_start) / (m.t_end - m.t_start)
        value = m.q_from + (m.q_to - m.q_from) * m.profile(u)
        q[m.joint] = np.where(t >= m.t_start, value, q[m.joint])
    return q


def _joint_transform(joint: Joint, q: Array) -> Transform:
    if joint.kind == "rotation":
        rot = matrix_from_axis_angle(joint.dir, q)
        return rot, joint.pos - rot @ joint.pos
    return np.broadcast_to(np.eye(3), (len(q), 3, 3)).copy(), q[:, None] * joint.dir


def chain_transform(joints: tuple[Joint, ...], q: Array, first: int = 0) -> Transform:
    """World-from-link transforms (R (n, 3, 3), t (n, 3)) of link ``first`` for joint values ``q`` (m, n)."""
    n = q.shape[1]
    rot = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    trans = np.zeros((n, 3))
    for j in range(first, len(joints)):
        r_j, t_j = _joint_transform(joints[j], q[j])
        rot = r_j @ rot
        trans = np.einsum("nij,nj->ni", r_j, trans) + t_j
    return rot, trans


def apply(transform: Transform, x: Array) -> Array:
    """Positions (n, 3) of the link point ``x`` (3,) under transforms (n)."""
    rot, trans = transform
    out: Array = np.einsum("nij,j->ni", rot, x) + trans
    return out


def truth_of(mech: Mechanism, moves: list[Move], handle_name: str) -> tuple[TruthPrimitive, ...]:
    """The true primitive of each move, the axis carried by the outer joints at the move's midpoint."""
    out = []
    for m in sorted(moves, key=lambda m: m.t_start):
        t_mid = np.array([0.5 * (m.t_start + m.t_end)])
        q = joint_values(moves, len(mech.joints), t_mid)
        rot, trans = chain_transform(mech.joints, q, first=m.joint + 1)
        joint = mech.joints[m.joint]
        sign = 1.0 if m.q_to >= m.q_from else -1.0
        direction = unit(rot[0] @ joint.dir) * sign
        handle_mid = apply(chain_transform(mech.joints, q), mech.handle)[0]
        if joint.kind == "rotation":
            pos_axis = rot[0] @ joint.pos + trans[0]
            foot = pos_axis + np.dot(handle_mid - pos_axis, direction) * direction
            radius: float | None = float(np.linalg.norm(handle_mid - foot))
            pos: Array | None = foot
        else:
            radius, pos = None, None
        out.append(
            TruthPrimitive(
                kind=joint.kind,
                pos=pos,
                dir=direction,
                extent=abs(m.q_to - m.q_from),
                t_start=m.t_start,
                t_end=m.t_end,
                radius_m=radius,
                radius_marker=handle_name if radius is not None else None,
            )
        )
    return tuple(out)


def _tilt(rng: np.random.Generator, max_deg: float) -> Array:
    return matrix_from_axis_angle(unit(rng.normal(size=3)), np.radians(rng.uniform(0.0, max_deg)))


def _place(rng: np.random.Generator, joints: list[Joint], handle: Array) -> tuple[tuple[Joint, ...], Array]:
    """Move a mechanism built about the origin to a random pose in the tracker's workspace (sometimes tilted
    arbitrarily, as when the tracker is on a robot)."""
    if rng.uniform() < 0.3:
        rot = random_rotation(rng)
    else:
        rot = matrix_from_axis_angle(np.array([0.0, 0.0, 1.0]), rng.uniform(0.0, 2.0 * np.pi)) @ _tilt(rng, 3.0)
    offset = rng.uniform([0.3, -0.6, 0.2], [1.5, 0.6, 1.4])
    placed = tuple(Joint(j.kind, rot @ j.pos + offset, unit(rot @ j.dir)) for j in joints)
    return placed, rot @ handle + offset


def _hinged(rng: np.random.Generator, radius: float, vertical: bool) -> tuple[Joint, Array, Array]:
    """A hinge on the z (door) or x (lid) axis through the origin, its handle at ``radius``, and the panel normal."""
    axis = np.array([0.0, 0.0, 1.0]) if vertical else np.array([1.0, 0.0, 0.0])
    radial = np.array([0.0, 1.0, 0.0]) if not vertical else np.array([1.0, 0.0, 0.0])
    along = rng.uniform(-0.3, 0.3) * radius
    handle = radial * radius + axis * along
    normal = unit(np.cross(axis, radial))
    return Joint("rotation", np.zeros(3), axis), handle, normal


def draw_mechanism(rng: np.random.Generator) -> Mechanism:
    """A random mechanism: a revolute door, lid or cap, a prismatic drawer or slider, or a two-joint chain (a
    lever, knob or bolt on a door, a knob on a drawer)."""
    kind = str(
        rng.choice(
            ["door", "lid", "cap", "drawer", "slider", "lever-door", "knob-door", "bolt-door", "knob-drawer"],
            p=[0.2, 0.12, 0.1, 0.17, 0.1, 0.1, 0.07, 0.07, 0.07],
        )
    )
    if kind in {"door", "lid"}:
        radius = rng.uniform(0.3, 0.9) if kind == "door" else rng.uniform(0.15, 0.5)
        joint, handle, _ = _hinged(rng, radius, vertical=kind == "door")
        joints, travels, size = [joint], [rng.uniform(0.3, 2.0)], radius
    elif kind == "cap":
        radius = rng.uniform(0.02, 0.05)
        joints = [Joint("rotation", np.zeros(3), np.array([0.0, 0.0, 1.0]))]
        handle, travels, size = np.array([radius, 0.0, 0.0]), [rng.uniform(1.5, 3.0)], radius
    elif kind in {"drawer", "slider"}:
        direction = np.array([1.0, 0.0, 0.0]) if kind == "drawer" else unit(rng.normal(size=3))
        joints = [Joint("translation", np.zeros(3), direction)]
        handle, travels, size = np.array([0.0, 0.0, 0.0]), [rng.uniform(0.05, 0.6)], 0.2
    elif kind == "knob-drawer":
        r_knob = rng.uniform(0.02, 0.04)
        direction = np.array([1.0, 0.0, 0.0])
        joints = [Joint("rotation", np.zeros(3), direction), Joint("translation", np.zeros(3), direction)]
        handle = np.array([0.0, r_knob, 0.0])
        travels, size = [rng.uniform(1.5, 3.0), rng.uniform(0.1, 0.6)], r_knob
    else:
        r_door = rng.uniform(0.3, 0.9)
        hinge, at, normal = _hinged(rng, r_door, vertical=True)
        in_plane = perpendicular(normal, rng)
        if kind == "lever-door":
            length = rng.uniform(0.06, 0.15)
            inner = Joint("rotation", at, normal)
            handle, travel, size = at + length * in_plane, rng.uniform(0.4, 1.2), length
        elif kind == "knob-door":
            r_knob = rng.uniform(0.02, 0.04)
            inner = Joint("rotation", at, normal)
            handle, travel, size = at + r_knob * in_plane, rng.uniform(1.5, 3.0), r_knob
        else:
            inner = Joint("translation", at, unit(at - hinge.pos - np.dot(at, hinge.dir) * hinge.dir))
            handle, travel, size = at.copy(), rng.uniform(0.05, 0.12), 0.1
        joints, travels = [inner, hinge], [travel, rng.uniform(0.3, 1.8)]
    placed, handle_world = _place(rng, joints, handle)
    signs = rng.choice([-1.0, 1.0], size=len(travels))
    return Mechanism(kind, placed, handle_world, tuple(float(s * t) for s, t in zip(signs, travels, strict=True)), size)


def path_length(mech: Mechanism, joint: int, travel: float) -> float:
    """Distance (m) the handle moves when joint ``joint`` travels ``travel`` from ``q = 0``."""
    j = mech.joints[joint]
    if j.kind == "translation":
        return abs(travel)
    rel = mech.handle - j.pos
    radius = float(np.linalg.norm(rel - np.dot(rel, j.dir) * j.dir))
    return abs(travel) * radius
