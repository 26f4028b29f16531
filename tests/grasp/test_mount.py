"""A part's mount (the face it stands on): kept apart in the model, an obstacle but not the free body when shaken."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from schemas.descriptor import Grasp
from tasks.arrays import Points
from tasks.grasp.mount import find_mount
from tasks.grasp.object_model import ObjectModel, build_object_model
from tasks.grasp.shake import hold_check, shake_test
from tests.grasp.cases.exact import labelled_model
from tests.grasp.surface_sampling import sample_box_surface, sample_cylinder_surface

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


@pytest.mark.slow
def test_fingers_stopped_by_the_mount_do_not_hold_the_part() -> None:
    grasp = _palm_on_top()
    rng = np.random.default_rng(1)
    box, walls = _box(rng), _walls(rng)
    view = CENTRE + np.array([0.0, 0.0, 0.2])
    away = walls + np.array([0.3, 0.0, 0.0])
    program = hold_check(PALM_DOWN)
    alone = shake_test(labelled_model(box, away, rng, viewpoint=view), grasp, program)
    assert alone.holds  # the mount out of the fingers' way: the wrap holds the box
    mounted = shake_test(labelled_model(box, walls, rng, viewpoint=view), grasp, program)
    assert not mounted.holds  # the fingers close on the walls: the box, a free body, falls
    as_one = shake_test(build_object_model(np.concatenate([box, walls]), rng, viewpoint=view), grasp, program)
    assert as_one.holds  # box and walls one body: pinching the walls carries the box


def _handle_on_plate(rng: np.random.Generator) -> tuple[Points, Points]:
    """A vertical bar (12 mm radius, 140 mm) 40 mm in front (-y) of a 10 mm plate 60 x 200 mm: bar, plate."""
    bar, _ = sample_cylinder_surface(0.012, 0.07, 1500, rng)
    plate, _ = sample_box_surface(np.array([0.03, 0.005, 0.10]), 1500, rng)
    return bar + CENTRE, plate + CENTRE + np.array([0.0, 0.045, 0.0])


def test_the_plate_behind_a_handle_is_its_mount() -> None:
    rng = np.random.default_rng(2)
    bar, plate = _handle_on_plate(rng)
    points = np.concatenate([bar, plate])
    palm = CENTRE - np.array([0.0, 0.05, 0.0])
    mount = find_mount(points, palm, np.array([0.0, 1.0, 0.0]))
    assert not mount[: len(bar)].any()
    assert mount[len(bar) :].mean() > 0.3  # the plate's face towards the hand (and its back, 10 mm on, apart)
    model = build_object_model(points, rng, viewpoint=palm, approach=np.array([0.0, 1.0, 0.0]))
    assert model.mount is not None and model.mount_parts > 0
    assert np.all(np.abs(model.without_mount().points[:, 1] - CENTRE[1]) < 0.02)  # the bar alone


def test_a_box_face_or_a_cylinder_the_palm_meets_first_is_no_mount() -> None:
    rng = np.random.default_rng(3)
    box = _box(rng)
    above = CENTRE + np.array([0.0, 0.0, 0.1])
    assert not find_mount(box, above, np.array([0.0, 0.0, -1.0])).any()  # its top faces the palm: the part
    lying, _ = sample_cylinder_surface(0.03, 0.08, 3000, rng)
    cylinder = Rotation.from_euler("y", 90, degrees=True).apply(lying) + CENTRE
    assert not find_mount(cylinder, above, np.array([0.0, 0.0, -1.0])).any()  # its far side is a strip
    side = CENTRE - np.array([0.0, 0.1, 0.0])
    assert not find_mount(box, side, np.array([0.0, 1.0, 0.0])).any()  # the far face is smaller than the hand


def test_degenerate_clouds_have_no_mount() -> None:
    rng = np.random.default_rng(4)
    above, down = np.array([0.0, 0.0, 0.2]), np.array([0.0, 0.0, -1.0])
    flat = np.c_[rng.uniform(-0.1, 0.1, (200, 2)), np.zeros(200)]  # all one plane: nothing stands in front of it
    for cloud in (rng.uniform(-0.05, 0.05, (30, 3)), flat, np.zeros((40, 3))):
        assert not find_mount(cloud, above, down).any()
