"""The planner's hold check (``hold_check``): the program of gravity phases and shakes a grasp must hold the
part through on the planner's own object model (``tasks.grasp.shake``) before ``tasks.grasp.api`` chooses it."""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from tasks.arrays import FloatArray
from tasks.grasp.shake import Motion, ShakeParams

CHECK_TILT_RAD = math.radians(30.0)
CHECK_PEAK_MS2 = 6.5
CHECK_FREQUENCY_HZ = 3.0
CHECK_TURN_RAD = math.radians(7.5)
CHECK_TURN_HZ = 2.0
CHECK_CYCLES = 1.0
"""``hold_check``'s program: gravity tilt (rad), translation peak acceleration (m/s²) and frequency (Hz), palm
turn amplitude (rad) and frequency (Hz), cycles of each motion (whole cycles: A (1 - cos ωt) ends where it
began)."""


def check_length_s(cycles: float = CHECK_CYCLES) -> float:
    """Simulated length of ``hold_check`` (s) with ``cycles`` of each motion: three gravity phases, each 0.5 s
    settling then the four motions."""
    return 3 * (0.5 + cycles * (3 / CHECK_FREQUENCY_HZ + 1 / CHECK_TURN_HZ))


CHECK_LENGTH_S = check_length_s()
"""Simulated length of ``hold_check`` (s) at ``CHECK_CYCLES``: 6 s."""
CHECK_SHIFT_M = 0.005
CHECK_TURN_TOL_RAD = math.radians(5.0)
"""``hold_check`` fails a grasp whose part moved 5 mm or turned 5° in the hand: half the slip a longer, harsher
shake allows (10 mm, 10°), since slip that starts in a short check goes on in a longer one."""


def hold_check(palm_quat_xyzw: FloatArray, cycles: float = CHECK_CYCLES) -> ShakeParams:
    """The planner's hold check for a grasp whose palm has orientation ``palm_quat_xyzw`` (world [x, y, z, w]):
    gravity world down, then tilted 30° towards either end of the palm's x axis (the axis of a bar the fingers
    close round: a lever slides along it) laid horizontal, or of its y axis when x is near vertical; in each
    phase translations along world x, y and z with 6.5 m/s² peaks at 3 Hz and a turn of the palm of 7.5° about
    the world diagonal at 2 Hz, ``cycles`` each (one: 6 s in all), within 5 mm and 5°. Run on the planner's own
    object model. The tilts and the palm turn load a fingertip grasp along and about the bar, the directions it
    slips in, which world gravity and translations alone do not."""
    rot = Rotation.from_quat(palm_quat_xyzw).as_matrix()
    down = np.array([0.0, 0.0, -1.0])
    side = rot[:, 0] - float(rot[:, 0] @ down) * down
    if float(np.linalg.norm(side)) < 0.3:
        side = rot[:, 1] - float(rot[:, 1] @ down) * down
    side = side / float(np.linalg.norm(side))
    gravity = [(0.0, 0.0, -9.81)]
    for sign in (1.0, -1.0):
        g = 9.81 * (math.cos(CHECK_TILT_RAD) * down + sign * math.sin(CHECK_TILT_RAD) * side)
        gravity.append((float(g[0]), float(g[1]), float(g[2])))
    amplitude = CHECK_PEAK_MS2 / (2.0 * math.pi * CHECK_FREQUENCY_HZ) ** 2
    axes = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    motions = [Motion(a, amplitude, CHECK_FREQUENCY_HZ, cycles) for a in axes]
    diagonal = 1.0 / math.sqrt(3.0)
    motions.append(Motion((diagonal, diagonal, diagonal), CHECK_TURN_RAD, CHECK_TURN_HZ, cycles, turn=True))
    return ShakeParams(
        max_shift_m=CHECK_SHIFT_M, max_turn_rad=CHECK_TURN_TOL_RAD, gravity=tuple(gravity), motions=tuple(motions)
    )
