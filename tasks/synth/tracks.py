"""True (noise-free) marker and palm tracks of a scripted demonstration, by pybullet forward kinematics.

World frame, metres, quaternions ``[x, y, z, w]``; times are seconds from the start of the recording.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pybullet as pb
from scipy.spatial.transform import Rotation

from tasks.arrays import FloatArray, Points, Quats
from tasks.scenes.kinematics import joint_indices, link_frames, set_joints
from tasks.scenes.scene import HAND_LINK, Scene
from tasks.synth.demonstrator import Demonstration, joint_values_at, reach_pose, reach_progress


@dataclass(frozen=True)
class TrueTracks:
    """Noise-free tracks at times ``t_s`` (n,): each marker's positions (n, 3) and the palm pose (n, 3), (n, 4)."""

    t_s: FloatArray
    markers: dict[str, Points]
    palm_pos: Points
    palm_quat: Quats


def joint_types(client: int, body: int) -> dict[str, str]:
    """Joint name -> ``revolute``, ``prismatic`` or ``fixed`` (other pybullet types by their code)."""
    names = {pb.JOINT_REVOLUTE: "revolute", pb.JOINT_PRISMATIC: "prismatic", pb.JOINT_FIXED: "fixed"}
    out: dict[str, str] = {}
    for name, j in joint_indices(client, body).items():
        code = pb.getJointInfo(body, j, physicsClientId=client)[2]
        out[name] = names.get(code, str(code))
    return out


def true_tracks(dem: Demonstration, client: int, body: int, t_s: FloatArray) -> TrueTracks:
    """Forward kinematics of the demonstration at times ``t_s`` (s) in the loaded scene ``body``."""
    scene: Scene = dem.scene
    t_s = np.asarray(t_s, dtype=np.float64)
    links = sorted({m.link for m in scene.markers if m.link != HAND_LINK} | {scene.grasp_link})
    n = len(t_s)
    frames_pos = {link: np.empty((n, 3)) for link in links}
    frames_rot = {link: np.empty((n, 3, 3)) for link in links}
    for i, t in enumerate(t_s.tolist()):
        set_joints(client, body, joint_values_at(dem, t))
        for link, (pos, quat) in link_frames(client, body, links).items():
            frames_pos[link][i] = pos
            frames_rot[link][i] = Rotation.from_quat(quat).as_matrix()
    # the palm: on the reach path until the grasp, then rigid with the grasp link
    grasp_rot = frames_rot[scene.grasp_link]
    attached_pos = frames_pos[scene.grasp_link] + grasp_rot @ np.asarray(scene.palm_position)
    attached_rot = grasp_rot @ Rotation.from_quat(scene.palm_orientation).as_matrix()
    reach_pos, reach_quat = reach_pose(dem.reach, reach_progress(dem, t_s))
    on_part = t_s >= dem.grasp_s
    palm_pos = np.where(on_part[:, None], attached_pos, reach_pos)
    palm_rot = np.where(on_part[:, None, None], attached_rot, Rotation.from_quat(reach_quat).as_matrix())
    markers: dict[str, Points] = {}
    for m in scene.markers:
        offset = np.asarray(m.offset, dtype=np.float64)
        if m.link == HAND_LINK:
            markers[m.name] = palm_pos + palm_rot @ offset
        else:
            markers[m.name] = frames_pos[m.link] + frames_rot[m.link] @ offset
    palm_quat: Quats = Rotation.from_matrix(palm_rot).as_quat()
    return TrueTracks(t_s, markers, palm_pos, palm_quat)
