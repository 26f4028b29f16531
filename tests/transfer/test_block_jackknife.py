"""A placement is no surer than how far it moves when one region of its pairs is left out."""

from __future__ import annotations

import numpy as np

from tasks.transfer.block_jackknife import block_labels, dominating, jackknife

AXIS = np.array([0.0, 0.0, 1.0])


def test_the_jackknife_of_blocks_that_each_pull_the_fit_is_their_spread() -> None:
    rng = np.random.default_rng(3)
    points = np.concatenate([rng.normal(loc=(x, 0.0, 0.0), scale=0.01, size=(200, 3)) for x in range(4)])
    labels = block_labels(points, blocks=4)
    assert sorted(np.bincount(labels)) == [200, 200, 200, 200]  # four clusters 1 m apart: one block each
    pull = np.array([[2e-3, 0.0, 5.0], [-2e-3, 0.0, 5.0], [0.0, 0.0, 5.0], [0.0, 0.0, 5.0]])  # z lies along the axis

    def refit(keep: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        gone = int(np.unique(labels[~keep])[0])
        return pull[gone], AXIS if gone else -AXIS  # a direction and its reverse are one axis

    cov, dir_std = jackknife(refit, labels, AXIS)
    # left-out estimates 2, -2, 0, 0 mm along x: (k - 1) / k times their sum of squares, nothing along y or z
    assert np.isclose(cov[0, 0], 0.75 * 8e-6)
    assert np.allclose(np.delete(np.delete(cov, 0, 0), 0, 1), 0.0)
    assert dir_std == 0.0


def test_the_dominating_covariance_covers_both_in_every_direction_across_the_axis() -> None:
    pairs = np.diag([4e-6, 1e-4, 0.0])  # the pairs pin x to 2 mm, leave y to 10 mm
    blocks = np.array([[9e-6, 9e-6, 0.0], [9e-6, 9e-6, 0.0], [0.0, 0.0, 0.0]])  # the blocks disagree along x + y
    out = dominating(pairs, blocks, AXIS)
    for other in (pairs, blocks):
        assert np.linalg.eigvalsh((out - other)[:2, :2]).min() > -1e-12
    assert np.allclose(out[2], 0.0)
    assert np.sqrt(out[0, 0]) > 2.5e-3  # x: the blocks' spread, not the pairs' 2 mm
    assert np.isclose(out[1, 1], 1e-4, rtol=0.1)  # y: about the pairs' 10 mm
    assert np.allclose(dominating(pairs, 0.5 * pairs, AXIS), pairs)  # blocks within the pairs' sigma add nothing
