"""Forward kinematics of a scene in pybullet, and the true chain and descriptor of its demonstration.

World frame, metres, radians, quaternions ``[x, y, z, w]``. Link frames are URDF link (joint) frames. The true
chain follows ``../shared/DESCRIPTOR.md``: one primitive per ``Motion``; ``dir`` signed so that the demonstrated
motion is a positive rotation (right-hand rule) or a move along ``dir``; ``extent`` never negative; a rotation's
``pos`` is the point on its axis nearest the centroid of the moving markers over the motion (sampled uniformly in
time along the minimum-jerk profile, as a recording samples it).
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from collections.abc import Iterable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pybullet as pb

from schemas.descriptor import Descriptor, Grasp, ObjectRef, Primitive
from tasks.arrays import FloatArray
from tasks.errors import SceneError
from tasks.scenes.scene import HAND_LINK, Quat, Scene, Vec3

TRUTH_SAMPLES = 101
"""Samples per motion for the marker centroid of a rotation's ``pos``."""


def min_jerk(s: FloatArray) -> FloatArray:
    """Minimum-jerk progress 10 s^3 - 15 s^4 + 6 s^5 of normalised time ``s`` in [0, 1] (clipped)."""
    s = np.clip(np.asarray(s, dtype=np.float64), 0.0, 1.0)
    return s**3 * (10.0 - 15.0 * s + 6.0 * s * s)


def urdf_path(scene: Scene) -> Path:
    """A file holding the scene's URDF text (content-addressed under the temp folder, written atomically)."""
    digest = hashlib.sha256(scene.urdf.encode()).hexdigest()[:16]
    folder = Path(tempfile.gettempdir()) / "pbd-scenes"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{scene.name}-{digest}.urdf"
    if not path.exists():
        fd, tmp = tempfile.mkstemp(dir=folder, suffix=".urdf.tmp")
        with os.fdopen(fd, "w") as f:
            f.write(scene.urdf)
        Path(tmp).replace(path)
    return path


def load_scene(scene: Scene, client: int) -> int:
    """Load ``scene`` into pybullet ``client`` with a fixed base at its placement and its joints at
    ``joint_start``; returns the body id."""
    body: int = pb.loadURDF(
        str(urdf_path(scene)),
        basePosition=scene.base_position,
        baseOrientation=scene.base_orientation,
        useFixedBase=True,
        physicsClientId=client,
    )
    if body < 0:
        msg = f"scene {scene.name!r}: pybullet could not load its URDF"
        raise SceneError(msg)
    set_joints(client, body, scene.joint_start)
    return body


def joint_indices(client: int, body: int) -> dict[str, int]:
    """Joint name -> index of ``body``."""
    return {
        pb.getJointInfo(body, j, physicsClientId=client)[1].decode(): j
        for j in range(pb.getNumJoints(body, physicsClientId=client))
    }


def link_indices(client: int, body: int) -> dict[str, int]:
    """Link name -> index of ``body`` (the base link is -1)."""
    names = {pb.getBodyInfo(body, physicsClientId=client)[0].decode(): -1}
    for j in range(pb.getNumJoints(body, physicsClientId=client)):
        names[pb.getJointInfo(body, j, physicsClientId=client)[12].decode()] = j
    return names


def set_joints(client: int, body: int, values: Mapping[str, float]) -> None:
    """Reset the named joints to ``values`` (rad or m); ``SceneError`` for a name the body does not have."""
    index = joint_indices(client, body)
    for name, value in values.items():
        if name not in index:
            msg = f"joint {name!r} is not in the scene (joints: {', '.join(sorted(index))})"
            raise SceneError(msg)
        pb.resetJointState(body, index[name], float(value), physicsClientId=client)


def link_frames(client: int, body: int, link_names: Iterable[str]) -> dict[str, tuple[FloatArray, FloatArray]]:
    """World pose (position (3,), quaternion (4,) xyzw) of each named URDF link frame at the current joints."""
    index = link_indices(client, body)
    out: dict[str, tuple[FloatArray, FloatArray]] = {}
    for name in link_names:
        if name not in index:
            msg = f"link {name!r} is not in the scene (links: {', '.join(sorted(index))})"
            raise SceneError(msg)
        i = index[name]
        if i == -1:
            com_pos, com_quat = pb.getBasePositionAndOrientation(body, physicsClientId=client)
            dyn = pb.getDynamicsInfo(body, -1, physicsClientId=client)
            inv_pos, inv_quat = pb.invertTransform(dyn[3], dyn[4])
            pos, quat = pb.multiplyTransforms(com_pos, com_quat, inv_pos, inv_quat)
        else:
            state = pb.getLinkState(body, i, computeForwardKinematics=True, physicsClientId=client)
            pos, quat = state[4], state[5]
        out[name] = (np.asarray(pos, dtype=np.float64), np.asarray(quat, dtype=np.float64))
    return out


def rotation_from_quat(quat: FloatArray | Quat) -> FloatArray:
    """3x3 rotation matrix of quaternion ``[x, y, z, w]``."""
    return np.asarray(pb.getMatrixFromQuaternion(tuple(float(v) for v in quat)), dtype=np.float64).reshape(3, 3)


@contextmanager
def scene_client(scene: Scene) -> Iterator[tuple[int, int]]:
    """A DIRECT pybullet client with ``scene`` loaded: yields (client, body); disconnects on exit."""
    client = pb.connect(pb.DIRECT)
    try:
        yield client, load_scene(scene, client)
    finally:
        pb.disconnect(client)


def moving_links(client: int, body: int, joint: str) -> set[str]:
    """Names of the links that ``joint`` moves (its child link and every descendant)."""
    index = joint_indices(client, body)
    if joint not in index:
        msg = f"joint {joint!r} is not in the scene (joints: {', '.join(sorted(index))})"
        raise SceneError(msg)
    count = pb.getNumJoints(body, physicsClientId=client)
    infos = [pb.getJointInfo(body, j, physicsClientId=client) for j in range(count)]
    moved = {index[joint]}
    changed = True
    while changed:
        changed = False
        for j, info in enumerate(infos):
            if j not in moved and info[16] in moved:
                moved.add(j)
                changed = True
    return {infos[j][12].decode() for j in moved}


def joint_values_at_motion(scene: Scene, k: int, progress: float) -> dict[str, float]:
    """Joint values when motion ``k`` has made ``progress`` (0..1, of its joint travel); earlier motions done."""
    values = dict(scene.joint_start)
    for m in scene.motions[:k]:
        values[m.joint] = m.end
    m = scene.motions[k]
    values[m.joint] = m.start + (m.end - m.start) * progress
    return values


def truth_chain(scene: Scene) -> tuple[Primitive, ...]:
    """The demonstration's true manipulation chain, world frame, at each motion's start (DESCRIPTOR.md signs)."""
    chain: list[Primitive] = []
    with scene_client(scene) as (client, body):
        index = joint_indices(client, body)
        for k, motion in enumerate(scene.motions):
            if motion.joint not in index:
                msg = f"scene {scene.name!r}: motion joint {motion.joint!r} is not in its URDF"
                raise SceneError(msg)
            info = pb.getJointInfo(body, index[motion.joint], physicsClientId=client)
            kind_code, child = info[2], info[12].decode()
            if kind_code not in (pb.JOINT_REVOLUTE, pb.JOINT_PRISMATIC):
                msg = f"scene {scene.name!r}: motion joint {motion.joint!r} is neither revolute nor prismatic"
                raise SceneError(msg)
            set_joints(client, body, joint_values_at_motion(scene, k, 0.0))
            pos, quat = link_frames(client, body, [child])[child]
            axis = rotation_from_quat(quat) @ np.asarray(info[13], dtype=np.float64)
            axis /= np.linalg.norm(axis)
            delta = motion.end - motion.start
            direction = axis if delta >= 0 else -axis
            moved = moving_links(client, body, motion.joint)
            hand_moves = scene.grasp_link in moved
            names = tuple(
                f"/mocap/{m.name}" for m in scene.markers if m.link in moved or (m.link == HAND_LINK and hand_moves)
            )
            if kind_code == pb.JOINT_PRISMATIC:
                chain.append(Primitive("translation", None, _vec(direction), abs(delta), markers=names))
                continue
            centroid = _moving_marker_centroid(scene, client, body, k, moved)
            foot = pos + axis * float(np.dot(centroid - pos, axis))
            chain.append(Primitive("rotation", _vec(foot), _vec(direction), abs(delta), markers=names))
    return tuple(chain)


def _moving_marker_centroid(scene: Scene, client: int, body: int, k: int, moved: set[str]) -> FloatArray:
    """Mean world position of the object markers on the ``moved`` links over motion ``k`` (uniform in time)."""
    markers = [m for m in scene.markers if m.link in moved]
    if not markers:  # no marker on the part: the grasp site stands for it
        markers_links = [scene.grasp_link]
        offsets = [np.asarray(scene.palm_position)]
    else:
        markers_links = [m.link for m in markers]
        offsets = [np.asarray(m.offset) for m in markers]
    total = np.zeros(3)
    count = 0
    for p in min_jerk(np.linspace(0.0, 1.0, TRUTH_SAMPLES)):
        set_joints(client, body, joint_values_at_motion(scene, k, float(p)))
        frames = link_frames(client, body, set(markers_links))
        for link, offset in zip(markers_links, offsets, strict=True):
            pos, quat = frames[link]
            total += pos + rotation_from_quat(quat) @ offset
            count += 1
    return total / count


def palm_pose_world(scene: Scene) -> tuple[FloatArray, FloatArray]:
    """The demonstrated grasp's palm pose in the world (position (3,), quaternion xyzw) at the first motion's
    start."""
    with scene_client(scene) as (client, body):
        if scene.motions:
            set_joints(client, body, joint_values_at_motion(scene, 0, 0.0))
        link_pos, link_quat = link_frames(client, body, [scene.grasp_link])[scene.grasp_link]
        pos, quat = pb.multiplyTransforms(
            link_pos.tolist(), link_quat.tolist(), scene.palm_position, scene.palm_orientation
        )
    return np.asarray(pos, dtype=np.float64), np.asarray(quat, dtype=np.float64)


def truth_descriptor(scene: Scene) -> Descriptor:
    """The true task descriptor of the scene's demonstration: its chain and the demonstrated grasp (palm frame)."""
    palm_pos, palm_quat = palm_pose_world(scene)
    grasp = Grasp("barrett", scene.grasp_eigengrasps, _vec(palm_pos), _quat(palm_quat))
    return Descriptor(
        f"{scene.action}-{scene.object_name}",
        scene.action,
        ObjectRef(scene.object_name),
        grasp,
        truth_chain(scene),
        extra_provenance={"scene": scene.name, "seed": scene.seed, "truth": True},
    )


def _vec(v: FloatArray) -> Vec3:
    return (float(v[0]), float(v[1]), float(v[2]))


def _quat(q: FloatArray) -> Quat:
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))
