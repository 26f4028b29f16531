"""Settling a wrap: the squeezing fingers pull a lying cylinder into the palm, a force closure the static
closing misses."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tasks.grasp.object_model import ObjectModel
from tasks.grasp.settle import MAX_SHIFT_M, settle, settled_wraps
from tests.grasp.lying_cylinder import CENTRE, PALM_DOWN, RADIUS, closed_above, lying_cylinder


@pytest.fixture(scope="module")
def cylinder() -> ObjectModel:
    """A cylinder of 30 mm radius, 160 mm long, lying along world x (``lying_cylinder``)."""
    return lying_cylinder()


def test_the_squeeze_pulls_the_part_into_the_palm(cylinder: ObjectModel) -> None:
    cand = closed_above(cylinder, 0.01)
    assert not cand.quality.force_closure  # statically the fingertips only push the cylinder away
    done = settle(cylinder, cand.position, cand.quat_xyzw, 0.0, 0.5)
    assert done.quality.force_closure
    assert done.quality.epsilon > 0.05
    assert done.palm_contact
    assert 0.003 < done.shift_m < MAX_SHIFT_M
    # the settled palm, with the cylinder back in place, lies on it: 10 mm lower, same orientation
    assert done.position[2] == pytest.approx(CENTRE[2] + RADIUS, abs=0.004)
    turn = (PALM_DOWN.inv() * Rotation.from_quat(done.quat_xyzw)).magnitude()
    assert np.degrees(turn) < 5.0


def test_wraps_come_back_near_and_far_pulls_do_not(cylinder: ObjectModel) -> None:
    seed_rot = PALM_DOWN.as_matrix()
    near, far = closed_above(cylinder, 0.01), closed_above(cylinder, 0.03)
    wraps = settled_wraps([near], cylinder, near.position, seed_rot, 0.02, np.radians(15.0))
    assert len(wraps) == 1
    assert wraps[0].quality.force_closure and wraps[0].near
    assert wraps[0].offset_m < 0.005  # on the demonstrated approach
    assert settled_wraps([far], cylinder, far.position, seed_rot, 0.02, np.radians(15.0)) == []  # pulled 60 mm


def test_later_wraps_are_the_next_closest_settled(cylinder: ObjectModel) -> None:
    """``skip`` settles the grasps after the closest ones: the first settles and the later ones together are the
    wraps of settling all of them (the planner's late wraps, when no grasp of its first round holds)."""
    seed_rot = PALM_DOWN.as_matrix()
    cands = [closed_above(cylinder, gap) for gap in (0.012, 0.004, 0.008)]
    limits = (cands[1].position, seed_rot, 0.02, np.radians(15.0))
    every = settled_wraps(cands, cylinder, *limits, count=3)
    first = settled_wraps(cands, cylinder, *limits, count=1)
    later = settled_wraps(cands, cylinder, *limits, count=2, skip=1)
    assert len(every) >= 2
    assert [w.closeness for w in first] == [0.004]  # the closest, whatever the order given
    assert [w.closeness for w in first + later] == [w.closeness for w in every]
    for a, b in zip(first + later, every, strict=True):
        assert np.allclose(a.position, b.position)
