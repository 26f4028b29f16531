"""The rigid part's orientation: a known turn and screw axis come back; a translation does not turn; collinear
markers fix no orientation; the excess residuals tell rotation from translation."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from tasks.arrays import FloatArray, Points
from tasks.fit.geometry import angle_between_axes, point_line_distance
from tasks.fit.rigid import net_turn, part_motion, rss_about_axis, screw_axis

AXIS_DIR = np.array([0.13, 0.99, 0.0]) / np.linalg.norm([0.13, 0.99, 0.0])
AXIS_POS = np.array([-0.37, 0.11, 0.96])
LEVER = np.array([[0.12, 0.0, 0.02], [0.02, 0.0, 0.02], [0.11, 0.02, -0.004]])
"""Marker offsets (m) from the axis point of a door lever, 2.8 to 12.2 cm out (as on the door scene's lever)."""


def _part(
    turn_rad: float, slide_m: float, noise_m: float, seed: int, n: int = 120
) -> tuple[list[FloatArray], list[Points]]:
    """Marker tracks of the lever turned about AXIS by up to ``turn_rad`` and slid along x by ``slide_m``."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0.0, 1.0, n)
    s = 10 * s**3 - 15 * s**4 + 6 * s**5
    rot = Rotation.from_rotvec(np.outer(s * turn_rad, AXIS_DIR))
    times = []
    tracks = []
    for m, offset in enumerate(LEVER):
        pts = AXIS_POS + rot.apply(offset) + np.outer(s * slide_m, [1.0, 0.0, 0.0])
        keep = np.ones(n, dtype=bool)
        keep[20 + 7 * m : 24 + 7 * m] = False  # a short occlusion per marker
        t = np.arange(n) / 120.0
        times.append(t[keep])
        tracks.append(pts[keep] + rng.normal(0.0, noise_m, (int(keep.sum()), 3)))
    return times, tracks


def test_a_turn_of_half_a_radian_and_its_screw_axis_come_back() -> None:
    times, tracks = _part(0.53, 0.0, 0.0005, seed=0)
    motion = part_motion(times, tracks)
    assert motion is not None
    assert abs(float(np.dot(net_turn(motion), AXIS_DIR)) - 0.53) < 0.01
    screw = screw_axis(motion)
    assert screw is not None
    assert angle_between_axes(screw.dir, AXIS_DIR) < np.radians(1.0)
    assert point_line_distance(screw.pos, AXIS_POS, AXIS_DIR) < 0.005  # a start for the circle fit
    assert abs(screw.turn_rad - 0.53) < 0.01
    assert 0.0 < screw.dir_std_rad < np.radians(2.0)


def test_a_translation_does_not_turn_and_has_no_screw_axis() -> None:
    times, tracks = _part(0.0, 0.04, 0.0005, seed=1)
    motion = part_motion(times, tracks)
    assert motion is not None
    assert float(np.linalg.norm(net_turn(motion))) < 0.03
    assert screw_axis(motion) is None
    # no turn explains the markers as well as the best turn, up to the noise (3 markers x 3 axes)
    assert float(np.mean(motion.rss_no_turn - motion.rss_best)) < 9 * 0.0005**2


def test_the_excess_residual_of_no_turn_is_large_in_a_rotation_and_small_about_the_axis() -> None:
    times, tracks = _part(0.53, 0.0, 0.0005, seed=2)
    motion = part_motion(times, tracks)
    assert motion is not None
    no_turn = float((motion.rss_no_turn - motion.rss_best).sum())
    about = float((rss_about_axis(motion, AXIS_DIR) - motion.rss_best).sum())
    assert no_turn > 100 * about
    assert about < len(motion.t_s) * 9 * 0.0005**2


def test_collinear_or_too_few_markers_fix_no_orientation() -> None:
    times, tracks = _part(0.53, 0.0, 0.0, seed=3)
    assert part_motion(times[:2], tracks[:2]) is None
    line = [
        np.column_stack([t, 2 * t, np.zeros_like(t)]) * 0.1 + k * np.array([0.02, 0.04, 0.0])
        for k, t in enumerate(times)
    ]
    assert part_motion(times, line) is None


def test_a_pose_streams_orientation_noise_widens_its_screw_axis_sigma() -> None:
    """A tracked body's three orientation points (as ``tasks.learn.prepare`` makes them) turning 0.25 rad under
    2 degrees of orientation noise per sample: the noise turns all points together and leaves no Kabsch residual,
    and the reference configuration's own error tilts every later turn alike. The stated sigma covers the error."""
    ratios = []
    for seed in range(6):
        rng = np.random.default_rng(seed)
        n = 400
        s = np.clip(np.linspace(-0.5, 1.5, n), 0.0, 1.0)
        true = Rotation.from_rotvec(np.outer(0.25 * (10 * s**3 - 15 * s**4 + 6 * s**5), AXIS_DIR))
        noisy = Rotation.from_rotvec(rng.normal(0.0, np.radians(2.0), (n, 3))) * true
        origin = AXIS_POS + true.apply([0.3, 0.0, 0.0]) + rng.normal(0.0, 0.0005, (n, 3))
        t = np.arange(n) / 200.0
        tracks = [origin] + [origin + 0.1 * noisy.as_matrix()[:, :, k] for k in range(3)]
        screw = screw_axis(part_motion([t] * 4, tracks))
        assert screw is not None
        ratios.append(angle_between_axes(screw.dir, AXIS_DIR, signed=False) / screw.dir_std_rad)
    assert float(np.median(ratios)) < 2.0


def test_a_dropout_is_bridged_as_in_every_fit_and_an_occlusion_is_not() -> None:
    """The same rule as ``interpolate.bracketed``: each marker's 42 ms dropout at 120 Hz is interpolated across (a
    part's speed barely changes in it); a 0.3 s occlusion is not."""
    times, tracks = _part(0.53, 0.0, 0.0005, seed=4)
    motion = part_motion(times, tracks)
    assert motion is not None
    assert len(motion.t_s) == len(times[0])  # the grid: the first marker's 116 samples
    hidden = (times[0] > 0.4) & (times[0] < 0.7)
    times[0], tracks[0] = times[0][~hidden], tracks[0][~hidden]
    motion = part_motion(times, tracks)
    assert motion is not None
    assert not np.any((motion.t_s > 0.41) & (motion.t_s < 0.69))
    assert len(motion.t_s) > 80
