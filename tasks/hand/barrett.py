"""A Barrett BH8-280 hand built from simple collision shapes, with GraspIt!'s eigengrasps.

Frames (all metres, radians):

- **Palm frame = hand base frame** (the URDF base link, and ``Grasp.wrist`` in a descriptor): origin at the
  centre of the palm's top face; **+z is the approach direction** (out of the palm, towards the object);
  +y points from finger 3 (the fixed thumb) towards fingers 1 and 2 at spread 0; +x = y × z.
- The palm is a cylinder (radius 45 mm, 80 mm deep, below z = 0). Fingers 1 and 2 turn about spread axes at
  x = +25 mm and x = -25 mm (finger 1 about -z, finger 2 about +z, by the shared spread DOF, 0..π); finger 3
  is fixed. Each finger has a proximal joint 50 mm from its spread axis (link 70 mm) and a distal joint at the
  end of the proximal link (link 56 mm to the tip). At spread 0, fingers 1 and 2 stand at y = +50 mm and close
  towards -y, opposite finger 3 at y = -50 mm which closes towards +y; at spread π/2 fingers 1 and 2 face each
  other across x.
- The palm link's inertial frame is the palm frame, so pybullet's base pose (``resetBasePositionAndOrientation``,
  ``getBasePositionAndOrientation``) is the palm frame's pose.
- Proximal joints 0..2.44 rad: 0 = finger stretched out flat, radially away from the palm centre (the BH8's
  flat open hand); π/2 = proximal link along +z; 2.44 = curled 50° past it. Distal joint = proximal / 3 + 40°,
  bending further towards the palm (the BH8's
  coupling; URDF mimic joints are ignored by pybullet, so ``apply_dofs`` enforces it).

DOFs are ``(spread, finger_1, finger_2, finger_3)`` radians; ``dofs_from_eigengrasps`` maps GraspIt's two
Barrett eigengrasps onto them.
"""

from __future__ import annotations

import hashlib
import itertools
import math
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pybullet as pb

from tasks.arrays import FloatArray, Points

DOF_NAMES: tuple[str, str, str, str] = ("spread", "finger_1", "finger_2", "finger_3")
"""The hand's four DOFs (radians)."""
DOF_LOWER: FloatArray = np.array([0.0, 0.0, 0.0, 0.0])
DOF_UPPER: FloatArray = np.array([math.pi, 2.44, 2.44, 2.44])
"""DOF limits, radians (BH8-280 data sheet: spread 180°, proximal 140°)."""

EIGENGRASP_ORIGIN: FloatArray = np.array([1.13, 0.79, 0.79, 0.79])
"""GraspIt!'s Barrett eigengrasp origin (``barrett_eigen.xml``), radians."""
EIGENGRASPS: FloatArray = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 1.0, 1.0] / np.sqrt(3.0)])
"""(2, 4) EG1 = spread alone, EG2 = the three fingers closing together (unit vectors)."""
AMPLITUDE_LIMIT = 4.0
"""Eigengrasp amplitudes are searched within ±4 (GraspIt!'s range for the Barrett hand)."""

FINGER_STRAIGHT_RAD = math.pi / 2
"""Proximal angle at which a finger's proximal link points along the approach (+z), radians."""
OPEN_FINGER_RAD = FINGER_STRAIGHT_RAD - 0.3
"""The open hand a grasp is executed from: fingers 0.3 rad past straight, outwards (the simulator's pre-grasp)."""
CLOSE_AMPLITUDE = (2.44 - 0.79) * math.sqrt(3.0)
"""EG2 amplitude that puts all three fingers at their 2.44 rad limit: the target a grasp closes towards."""

DISTAL_OFFSET_RAD = math.radians(40.0)
DISTAL_RATIO = 1.0 / 3.0
"""Distal coupling: distal = proximal * DISTAL_RATIO + DISTAL_OFFSET_RAD (BH8 TorqueSwitch gearing)."""
DISTAL_UPPER = DISTAL_OFFSET_RAD + DISTAL_RATIO * 2.44 + 0.9
"""Distal joint upper limit, radians (room for breakaway closing after the proximal link stops)."""

PALM_RADIUS = 0.045
PALM_DEPTH = 0.080
SPREAD_AXIS_X = 0.025
"""Spread axes of fingers 1 and 2 at x = ±25 mm (BH8 Rw)."""
KNUCKLE_LENGTH = 0.050
"""Spread axis to proximal joint, 50 mm (BH8 A1)."""
PROXIMAL_LENGTH = 0.070
"""Proximal joint to distal joint, 70 mm (BH8 A2)."""
DISTAL_LENGTH = 0.056
"""Distal joint to fingertip, 56 mm (BH8 A3 = 50 mm plus the tip pad)."""
PROXIMAL_HALF = (0.0125, 0.010)
DISTAL_HALF = (0.011, 0.008)
"""Half width (x) and half thickness (y) of the finger links, metres."""

JOINT_NAMES: tuple[str, ...] = (
    "spread_1",
    "proximal_1",
    "distal_1",
    "spread_2",
    "proximal_2",
    "distal_2",
    "knuckle_3",
    "proximal_3",
    "distal_3",
)
"""URDF joints in pybullet index order (joint i moves link i)."""
LINK_NAMES: tuple[str, ...] = (
    "knuckle_1",
    "proximal_link_1",
    "distal_link_1",
    "knuckle_2",
    "proximal_link_2",
    "distal_link_2",
    "knuckle_link_3",
    "proximal_link_3",
    "distal_link_3",
)
"""URDF links in pybullet index order; the palm is the base (link index -1)."""
PALM_LINK = -1
SPREAD_JOINTS = (0, 3)
PROXIMAL_JOINTS = (1, 4, 7)
DISTAL_JOINTS = (2, 5, 8)
FINGER_LINKS: tuple[tuple[int, int], ...] = ((1, 2), (4, 5), (7, 8))
"""(proximal, distal) link indices of fingers 1, 2, 3."""


def coupled_distal(proximal_rad: npt.ArrayLike) -> FloatArray:
    """Distal joint angle(s) coupled to proximal angle(s): proximal / 3 + 40°, radians."""
    return np.asarray(proximal_rad, dtype=np.float64) * DISTAL_RATIO + DISTAL_OFFSET_RAD


def clamp_dofs(dofs: npt.ArrayLike) -> FloatArray:
    """Clamp (4,) DOFs ``(spread, f1, f2, f3)`` radians to the joint limits."""
    arr = np.asarray(dofs, dtype=np.float64)
    if arr.shape != (4,):
        msg = f"dofs: expected shape (4,), got {arr.shape}"
        raise ValueError(msg)
    return np.clip(arr, DOF_LOWER, DOF_UPPER)


def dofs_from_eigengrasps(a1: float, a2: float) -> FloatArray:
    """(4,) DOFs ``(spread, f1, f2, f3)`` radians = origin + a1·EG1 + a2·EG2, clamped to the joint limits."""
    if not (math.isfinite(a1) and math.isfinite(a2)):
        msg = f"eigengrasp amplitudes must be finite, got ({a1}, {a2})"
        raise ValueError(msg)
    return clamp_dofs(EIGENGRASP_ORIGIN + a1 * EIGENGRASPS[0] + a2 * EIGENGRASPS[1])


def eigengrasps_from_dofs(dofs: npt.ArrayLike) -> tuple[float, float]:
    """Least-squares amplitudes (a1, a2) of (4,) DOFs in the eigengrasp basis (projection onto EG1, EG2)."""
    delta = clamp_dofs(dofs) - EIGENGRASP_ORIGIN
    return float(delta @ EIGENGRASPS[0]), float(delta @ EIGENGRASPS[1])


def spread_amplitude(spread_rad: float) -> float:
    """EG1 amplitude a1 of a spread angle (radians): spread - 1.13."""
    return float(spread_rad - EIGENGRASP_ORIGIN[0])


def open_dofs(spread_rad: float, finger_rad: float = OPEN_FINGER_RAD) -> FloatArray:
    """(4,) DOFs of the open hand at a spread (radians): all three fingers at ``finger_rad``."""
    return clamp_dofs(np.array([spread_rad, finger_rad, finger_rad, finger_rad]))


def joint_positions(dofs: npt.ArrayLike, distal: npt.ArrayLike | None = None) -> FloatArray:
    """(9,) URDF joint angles for (4,) DOFs; distal joints coupled unless ``distal`` (3,) is given."""
    d = clamp_dofs(dofs)
    dist = coupled_distal(d[1:]) if distal is None else np.asarray(distal, dtype=np.float64)
    return np.array([d[0], d[1], dist[0], d[0], d[2], dist[1], 0.0, d[3], dist[2]])


def apply_dofs(client_id: int, body_id: int, dofs: npt.ArrayLike, distal: npt.ArrayLike | None = None) -> None:
    """Set the hand's joints (kinematic reset) to (4,) DOFs, with distal = proximal/3 + 40° unless given."""
    q = joint_positions(dofs, distal)
    for joint, angle in enumerate(q):
        if joint == 6:
            continue
        pb.resetJointState(body_id, joint, float(angle), 0.0, physicsClientId=client_id)


def drive_dofs(
    client_id: int,
    body_id: int,
    dofs: npt.ArrayLike,
    *,
    max_torque_nm: float = 3.0,
    distal: npt.ArrayLike | None = None,
) -> None:
    """Position-control the joints towards (4,) DOFs (distal coupled unless given), each with ``max_torque_nm``."""
    q = joint_positions(dofs, distal)
    joints = [j for j in range(9) if j != 6]
    pb.setJointMotorControlArray(
        body_id,
        joints,
        pb.POSITION_CONTROL,
        targetPositions=[float(q[j]) for j in joints],
        forces=[max_torque_nm] * len(joints),
        physicsClientId=client_id,
    )


# --- URDF -----------------------------------------------------------------------------------------------------


def _inertial(mass: float, xyz: tuple[float, float, float]) -> str:
    i = mass * 1e-4
    return (
        f'<inertial><origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}"/><mass value="{mass}"/>'
        f'<inertia ixx="{i}" iyy="{i}" izz="{i}" ixy="0" ixz="0" iyz="0"/></inertial>'
    )


def _box_link(name: str, mass: float, half: tuple[float, float], length: float) -> str:
    size = f"{2 * half[0]} {2 * half[1]} {length}"
    origin = f'<origin xyz="0 0 {length / 2}"/>'
    geom = f'<geometry><box size="{size}"/></geometry>'
    return (
        f'<link name="{name}">{_inertial(mass, (0.0, 0.0, length / 2))}'
        f"<visual>{origin}{geom}</visual><collision>{origin}{geom}</collision></link>"
    )


def barrett_urdf_text() -> str:
    """The hand's URDF as text (deterministic; see the module docstring for frames and dimensions)."""
    palm_origin = f'<origin xyz="0 0 {-PALM_DEPTH / 2}"/>'
    palm_geom = f'<geometry><cylinder radius="{PALM_RADIUS}" length="{PALM_DEPTH}"/></geometry>'
    parts = [
        '<?xml version="1.0"?>',
        '<robot name="barrett_bh8_280">',
        f'<link name="palm">{_inertial(1.2, (0.0, 0.0, 0.0))}'
        f"<visual>{palm_origin}{palm_geom}</visual><collision>{palm_origin}{palm_geom}</collision></link>",
    ]
    fingers = (
        (1, (SPREAD_AXIS_X, 0.0), 0.0, "0 0 -1"),
        (2, (-SPREAD_AXIS_X, 0.0), 0.0, "0 0 1"),
        (3, (0.0, 0.0), math.pi, None),
    )
    for k, (x, y), yaw, spread_axis in fingers:
        knuckle = f"knuckle_{k}" if k != 3 else "knuckle_link_3"
        parts.append(f'<link name="{knuckle}">{_inertial(0.05, (0.0, KNUCKLE_LENGTH / 2, 0.0))}</link>')
        if spread_axis is not None:
            parts.append(
                f'<joint name="spread_{k}" type="revolute"><parent link="palm"/><child link="{knuckle}"/>'
                f'<origin xyz="{x} {y} 0" rpy="0 0 {yaw}"/><axis xyz="{spread_axis}"/>'
                f'<limit lower="0" upper="{math.pi}" effort="5" velocity="2"/></joint>'
            )
        else:
            parts.append(
                f'<joint name="knuckle_3" type="fixed"><parent link="palm"/><child link="{knuckle}"/>'
                f'<origin xyz="{x} {y} 0" rpy="0 0 {yaw}"/></joint>'
            )
        parts.append(_box_link(f"proximal_link_{k}", 0.1, PROXIMAL_HALF, PROXIMAL_LENGTH))
        parts.append(
            f'<joint name="proximal_{k}" type="revolute"><parent link="{knuckle}"/>'
            f'<child link="proximal_link_{k}"/><origin xyz="0 {KNUCKLE_LENGTH} 0" rpy="{-math.pi / 2:.9f} 0 0"/>'
            f'<axis xyz="1 0 0"/>'
            f'<limit lower="0" upper="2.44" effort="5" velocity="2"/></joint>'
        )
        parts.append(_box_link(f"distal_link_{k}", 0.05, DISTAL_HALF, DISTAL_LENGTH))
        parts.append(
            f'<joint name="distal_{k}" type="revolute"><parent link="proximal_link_{k}"/>'
            f'<child link="distal_link_{k}"/><origin xyz="0 0 {PROXIMAL_LENGTH}"/><axis xyz="1 0 0"/>'
            f'<limit lower="0" upper="{DISTAL_UPPER:.6f}" effort="5" velocity="2"/>'
            f'<mimic joint="proximal_{k}" multiplier="{DISTAL_RATIO:.6f}" offset="{DISTAL_OFFSET_RAD:.6f}"/></joint>'
        )
    parts.append("</robot>")
    return "\n".join(parts) + "\n"


def barrett_urdf(cache_dir: Path | None = None) -> Path:
    """Write the hand's URDF once to a content-addressed cache path and return it (``$PBD_CACHE`` or tmp)."""
    text = barrett_urdf_text()
    digest = hashlib.sha256(text.encode()).hexdigest()[:12]
    root = cache_dir or Path(os.environ.get("PBD_CACHE", Path(tempfile.gettempdir()) / "pbd-cache"))
    path = root / "grasp" / f"barrett_bh8_280-{digest}.urdf"
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile("w", dir=path.parent, delete=False, suffix=".tmp") as tmp:
            tmp.write(text)
        Path(tmp.name).replace(path)
    return path


def load_hand(
    client_id: int, position: npt.ArrayLike = (0.0, 0.0, 0.0), quat_xyzw: npt.ArrayLike = (0, 0, 0, 1)
) -> int:
    """Load the hand into a pybullet client with its palm frame at the given world pose; returns the body id."""
    pos = [float(v) for v in np.asarray(position, dtype=np.float64)]
    quat = [float(v) for v in np.asarray(quat_xyzw, dtype=np.float64)]
    body = int(pb.loadURDF(str(barrett_urdf()), pos, quat, physicsClientId=client_id))
    for joint in range(9):
        pb.setJointMotorControl2(body, joint, pb.VELOCITY_CONTROL, force=0.0, physicsClientId=client_id)
    return body


# --- numpy kinematics (mirrors the URDF; used by the planner's vectorised energy) ----------------------------


def _joint_tf(axis: int, angle: npt.ArrayLike, trans: tuple[float, float, float]) -> FloatArray:
    """(..., 4, 4) transforms: a rotation by ``angle`` (...,) rad about the x (0) or z (2) axis, then ``trans`` (m)."""
    theta = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(theta), np.sin(theta)
    i, j = (1, 2) if axis == 0 else (0, 1)
    out = np.zeros((*theta.shape, 4, 4))
    out[..., axis, axis] = out[..., 3, 3] = 1.0
    out[..., i, i], out[..., i, j], out[..., j, i], out[..., j, j] = c, -s, s, c
    out[..., :3, 3] = trans
    return out


def link_transforms(joints: npt.ArrayLike) -> FloatArray:
    """(..., 10, 4, 4) transforms palm-from-link for the palm (index 0) and the 9 URDF links (index i + 1), for
    joint angles (..., 9) rad."""
    q = np.asarray(joints, dtype=np.float64)
    out = np.zeros((*q.shape[:-1], 10, 4, 4))
    out[..., 0, :, :] = np.eye(4)
    bases = (
        _joint_tf(2, -q[..., 0], (SPREAD_AXIS_X, 0.0, 0.0)),
        _joint_tf(2, q[..., 3], (-SPREAD_AXIS_X, 0.0, 0.0)),
        _joint_tf(2, np.full(q.shape[:-1], math.pi), (0.0, 0.0, 0.0)),
    )
    for k, knuckle in enumerate(bases):
        prox = knuckle @ _joint_tf(0, q[..., 3 * k + 1] - math.pi / 2, (0.0, KNUCKLE_LENGTH, 0.0))
        dist = prox @ _joint_tf(0, q[..., 3 * k + 2], (0.0, 0.0, PROXIMAL_LENGTH))
        out[..., 3 * k + 1, :, :], out[..., 3 * k + 2, :, :], out[..., 3 * k + 3, :, :] = knuckle, prox, dist
    return out


def joints_from_eigengrasps(amplitudes: npt.ArrayLike) -> FloatArray:
    """(..., 9) URDF joint angles (rad, distal joints coupled) of eigengrasp amplitudes (..., 2) (a1, a2), the DOFs
    clamped to the joint limits as ``dofs_from_eigengrasps`` clamps them."""
    a = np.asarray(amplitudes, dtype=np.float64)
    d = np.clip(EIGENGRASP_ORIGIN + a[..., :1] * EIGENGRASPS[0] + a[..., 1:] * EIGENGRASPS[1], DOF_LOWER, DOF_UPPER)
    dist = coupled_distal(d[..., 1:])
    zero = np.zeros(d.shape[:-1])
    columns = (d[..., 0], d[..., 1], dist[..., 0], d[..., 0], d[..., 2], dist[..., 1], zero, d[..., 3], dist[..., 2])
    return np.stack(columns, axis=-1)


def tip_depth(half_width_m: float) -> float:
    """Depth (m, along +z) at which the inner edges of the closing fingertips (distal joints coupled) come within
    ``half_width_m`` of the mid plane y = 0 between the thumb and fingers 1 and 2 at spread 0."""
    proximal = np.linspace(1.0, 2.0, 101)  # the edge from 56 mm out to 32 mm across the mid plane, monotonic
    joints = np.zeros((len(proximal), 9))
    joints[:, 7], joints[:, 8] = proximal, coupled_distal(proximal)
    edge = link_transforms(joints)[:, 9] @ np.array([0.0, -DISTAL_HALF[1], DISTAL_LENGTH, 1.0])
    return float(np.interp(-half_width_m, edge[:, 1], edge[:, 2]))


@dataclass(frozen=True)
class LinkPoints:
    """Points fixed on the hand's links: ``link`` (m,) index into ``link_transforms`` (0 = palm, i + 1 = link i),
    ``local`` (m, 3) metres in the link frame, ``normal`` (m, 3) unit outward direction in the link frame."""

    link: npt.NDArray[np.int64]
    local: Points
    normal: Points

    def in_palm(self, transforms: FloatArray) -> tuple[Points, Points]:
        """Positions and directions (..., m, 3) in the palm frame for ``link_transforms`` output (..., 10, 4, 4),
        one link's run of points at a time."""
        starts = np.concatenate([[0], np.flatnonzero(np.diff(self.link)) + 1, [len(self.link)]])
        pos, nrm = [], []
        for a, b in itertools.pairwise(starts):
            tf = transforms[..., self.link[a], :, :]
            turn = np.swapaxes(tf[..., :3, :3], -1, -2)
            pos.append(self.local[a:b] @ turn + tf[..., None, :3, 3])
            nrm.append(self.normal[a:b] @ turn)
        return np.concatenate(pos, axis=-2), np.concatenate(nrm, axis=-2)


def _virtual_contacts() -> LinkPoints:
    """GraspIt!-style virtual contacts: points on the inner (gripping) faces, approach = face normal."""
    links: list[int] = []
    local: list[tuple[float, float, float]] = []
    normal: list[tuple[float, float, float]] = []
    for x, y in ((0.0, 0.0), (0.02, 0.0), (-0.02, 0.0), (0.0, 0.02), (0.0, -0.02)):
        links.append(0)
        local.append((x, y, 0.0))
        normal.append((0.0, 0.0, 1.0))
    for prox, dist in FINGER_LINKS:
        for z in (0.020, 0.040, 0.060):
            links.append(prox + 1)
            local.append((0.0, -PROXIMAL_HALF[1], z))
            normal.append((0.0, -1.0, 0.0))
        for z in (0.015, 0.030, 0.045):
            links.append(dist + 1)
            local.append((0.0, -DISTAL_HALF[1], z))
            normal.append((0.0, -1.0, 0.0))
    return LinkPoints(np.array(links, dtype=np.int64), np.array(local), np.array(normal))


def _surface_samples(step: float = 0.007) -> LinkPoints:
    """Points on the collision surfaces (palm top disc, finger boxes) for cheap penetration tests."""
    links: list[int] = []
    local: list[npt.NDArray[np.float64]] = []
    normal: list[npt.NDArray[np.float64]] = []
    g = np.arange(-PALM_RADIUS, PALM_RADIUS + 1e-9, step)
    xx, yy = np.meshgrid(g, g)
    disc = np.stack([xx.ravel(), yy.ravel(), np.zeros(xx.size)], axis=1)
    disc = disc[np.hypot(disc[:, 0], disc[:, 1]) <= PALM_RADIUS]
    links += [0] * len(disc)
    local.append(disc)
    normal.append(np.tile([0.0, 0.0, 1.0], (len(disc), 1)))
    for prox, dist in FINGER_LINKS:
        for link, half, length in ((prox, PROXIMAL_HALF, PROXIMAL_LENGTH), (dist, DISTAL_HALF, DISTAL_LENGTH)):
            zs = np.linspace(0.004, length, max(2, int(length / step) + 1))
            for across in (-0.9, 0.9):
                for sx, sy, nx, ny in ((across, -1, 0, -1), (across, 1, 0, 1), (-1, across, -1, 0), (1, across, 1, 0)):
                    face = np.stack([np.full_like(zs, sx * half[0]), np.full_like(zs, sy * half[1]), zs], axis=1)
                    links += [link + 1] * len(zs)
                    local.append(face)
                    normal.append(np.tile([float(nx), float(ny), 0.0], (len(zs), 1)))
    return LinkPoints(np.array(links, dtype=np.int64), np.concatenate(local), np.concatenate(normal))


VIRTUAL_CONTACTS: LinkPoints = _virtual_contacts()
"""Virtual contacts (palm 5, each finger link 3), approach direction = inward face normal (link frame)."""
SURFACE_SAMPLES: LinkPoints = _surface_samples()
"""Points on the hand's collision surfaces, link frames."""
