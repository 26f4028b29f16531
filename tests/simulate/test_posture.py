"""The posture the null space pulls towards: the placement's verified joint path, interpolated by progress."""

from __future__ import annotations

import numpy as np

from tasks.simulate.execute import posture_at


def test_posture_interpolates_every_joint_like_numpy_and_clamps_at_the_ends() -> None:
    rng = np.random.default_rng(3)
    xs = np.array([0.0, 0.1, 0.1, 0.35, 0.8])  # a repeated progress (a zero-length segment) included
    qs = rng.uniform(-2.0, 2.0, size=(5, 7))
    for progress in [-0.2, 0.0, 0.05, 0.1, 0.2, 0.35, 0.5, 0.8, 1.3]:
        expected = np.array([np.interp(progress, xs, qs[:, j]) for j in range(7)])
        np.testing.assert_allclose(posture_at((xs, qs), progress), expected, atol=1e-12)


def test_posture_of_a_single_row_path_is_that_row() -> None:
    qs = np.arange(7.0)[None, :]
    np.testing.assert_array_equal(posture_at((np.zeros(1), qs), 0.4), qs[0])
