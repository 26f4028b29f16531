"""The digitised object model of a simulated demonstration: what a person with a 3-D digitizer would scan.

A scan covers the whole object evenly and the part the hand grasps in detail (a hand-held digitizer is passed
over the handle or cap more closely than over a door leaf); an even sample alone leaves a few points on a lever
handle of a 2 m door, too few to plan a grasp on. World frame at the demonstration's start, metres.
"""

from __future__ import annotations

import numpy as np

from tasks.arrays import Points
from tasks.scenes.kinematics import palm_pose_world
from tasks.scenes.scene import Scene
from tasks.scenes.surface import sample_object_model

SCAN_POINTS = 8192
"""Points of a scan (98 kB as float32 xyz in the recording)."""
DETAIL_RADIUS_M = 0.15
"""Surfaces within this distance of the demonstrated palm are the grasped part's neighbourhood, metres."""
DETAIL_SHARE = 0.5
"""Share of the scan's points spent on that neighbourhood (at most what is there: a small object is all detail)."""
OVERSAMPLE = 32
"""Even surface samples drawn per scan point before the detail and the even parts are chosen from them."""


def scan_object_model(scene: Scene, n_points: int, rng: np.random.Generator) -> Points:
    """(n_points, 3) float64 surface points of ``scene``'s model links, world frame at the start: an even sample
    of the whole object plus ``DETAIL_SHARE`` of the points on the surfaces within ``DETAIL_RADIUS_M`` of the
    demonstrated palm."""
    dense = sample_object_model(scene, n_points * OVERSAMPLE, rng)
    palm, _ = palm_pose_world(scene)
    near = np.flatnonzero(np.linalg.norm(dense - palm, axis=1) < DETAIL_RADIUS_M)
    n_detail = min(int(n_points * DETAIL_SHARE), len(near))
    detail = dense[rng.choice(near, size=n_detail, replace=False)]
    even = dense[rng.choice(len(dense), size=n_points - n_detail, replace=False)]
    return np.concatenate([even, detail])
