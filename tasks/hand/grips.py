"""How the hand holds the scenes' handles and caps: bar and cap geometry and the finger curl of each grip.

World-independent: metres and radians in the palm frame of ``tasks.hand.barrett`` (+z the approach).
"""

from __future__ import annotations

from functools import cache

import numpy as np

from tasks.hand import barrett

HANDLE_RADIUS = 0.012
"""Bar handles are 24 mm thick."""
HANDLE_STANDOFF = 0.07
"""Bar axis in front of the face it is mounted on, metres."""
PALM_TO_BAR = 0.04
"""Palm face to bar axis along the approach, metres (the Barrett fingers wrap a bar there)."""
BAR_CURL_RAD = 1.31
"""A power grasp of a bar: spread 0 (fingers 1, 2 opposite finger 3), proximal links 1.31 rad past pointing along
the approach (clamped to the hand's range)."""
CAP_CURL_RAD = 0.9
"""A cap grasped from above: the fingers 0.9 rad past pointing along the approach."""


def curl_eigengrasps(curl_rad: float) -> tuple[float, float]:
    """Eigengrasp amplitudes of spread 0 and all three fingers ``curl_rad`` past pointing along the approach."""
    finger = min(float(barrett.DOF_UPPER[1]), finger_straight_rad() + curl_rad)
    return barrett.eigengrasps_from_dofs([0.0, finger, finger, finger])


@cache
def finger_straight_rad() -> float:
    """Proximal angle (radians) at which finger 1's proximal link points along the palm's +z (the approach).

    Read off the hand's own kinematics (``barrett.link_transforms``), so the hand module may define its zero
    anywhere (flat open hand or straight fingers)."""
    grid = np.linspace(float(barrett.DOF_LOWER[1]), float(barrett.DOF_UPPER[1]), 245)
    spread = barrett.dofs_from_eigengrasps(0.0, 0.0)[0]
    best, best_cos = float(grid[0]), -2.0
    for angle in grid:
        tf = barrett.link_transforms(barrett.joint_positions([spread, angle, angle, angle]))
        cos = float(tf[2][2, 2])  # z of the proximal link of finger 1 (link 1 -> index 2), palm frame
        if cos > best_cos:
            best, best_cos = float(angle), cos
    return best
