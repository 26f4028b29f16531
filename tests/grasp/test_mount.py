"""A part's mount (the face it stands on): kept apart in the model, an obstacle but not the free body when shaken."""

from __future__ import annotations

import numpy as np

from schemas.descriptor import Grasp
from tasks.arrays import Points
from tasks.grasp.object_model import ObjectModel, build_object_model, labelled_model, sample_box_surface
from tasks.grasp.shake import shake_test

from .conftest import PALM_DOWN

CENTRE = np.array([0.5, 0.0, 0.3])
HALF = np.array([0.025, 0.025, 0.04])
WALL_GAP_M = 0.010
"""The walls stand 10 mm out from the box's sides, their tops 10 mm below its top."""


def _box(rng: np.random.Generator) -> Points:
    pts, _ = sample_box_surface(HALF, 3000, rng)
    out: Points = pts + CENTRE
    return out


def _walls(rng: np.random.Generator) -> Points:
    """Four 4 mm walls round the box, 10 mm out from its sides: where the closing fingers come down."""
    walls = []
    for axis in (0, 1):
        for sign in (-1.0, 1.0):
            half = np.array([0.06, 0.06, 0.035])
            half[axis] = 0.002
            offset = np.zeros(3)
            offset[axis] = sign * (HALF[axis] + WALL_GAP_M + 0.002)
            offset[2] = -0.015
            pts, _ = sample_box_surface(half, 1500, rng)
            walls.append(pts + CENTRE + offset)
    return np.concatenate(walls)


def _palm_on_top() -> Grasp:
    pos = CENTRE + np.array([0.0, 0.0, HALF[2] + 0.0015])
    quat = (float(PALM_DOWN[0]), float(PALM_DOWN[1]), float(PALM_DOWN[2]), float(PALM_DOWN[3]))
    return Grasp("barrett", (-1.13, -1.37), (float(pos[0]), float(pos[1]), float(pos[2])), quat)


def test_labelled_model_keeps_the_mount_apart() -> None:
    rng = np.random.default_rng(0)
    model = labelled_model(_box(rng), _walls(rng), rng, viewpoint=CENTRE + np.array([0.0, 0.0, 0.2]))
    assert model.mount is not None
    assert 0 < model.mount_parts < len(model.parts)
    np.testing.assert_allclose(model.center, CENTRE, atol=0.003)  # the part's centre, not the walls'
    part = model.without_mount()
    assert part.mount is None
    assert len(part.parts) == len(model.parts) - model.mount_parts
    assert len(part.points) == int((~model.mount).sum())
    assert np.all(np.abs(part.points - CENTRE) <= HALF + 0.003)  # the box alone
    pieces = np.arange(len(model.parts))
    np.testing.assert_array_equal(model.is_mount_piece(pieces), pieces >= len(part.parts))
    plain: ObjectModel = build_object_model(_box(rng), rng)
    assert plain.without_mount() is plain
    assert not plain.is_mount_piece(np.arange(len(plain.parts))).any()


def test_fingers_stopped_by_the_mount_do_not_hold_the_part() -> None:
    grasp = _palm_on_top()
    rng = np.random.default_rng(1)
    box, walls = _box(rng), _walls(rng)
    view = CENTRE + np.array([0.0, 0.0, 0.2])
    away = walls + np.array([0.3, 0.0, 0.0])
    alone = shake_test(labelled_model(box, away, rng, viewpoint=view), grasp)
    assert alone.holds  # the mount out of the fingers' way: the wrap holds the box
    mounted = shake_test(labelled_model(box, walls, rng, viewpoint=view), grasp)
    assert not mounted.holds  # the fingers close on the walls: the box, a free body, falls
    as_one = shake_test(build_object_model(np.concatenate([box, walls]), rng, viewpoint=view), grasp)
    assert as_one.holds  # box and walls one body: pinching the walls carries the box
