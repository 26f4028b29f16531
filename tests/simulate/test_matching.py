"""Primitives are matched to scene joints by axis; a misfit is a SimulationError naming primitive and distance."""

from __future__ import annotations

import math

import numpy as np
import pytest

from schemas.descriptor import Primitive
from tasks.errors import SimulationError
from tasks.simulate.matching import JointAxis, match_chain

HINGE = JointAxis("hinge", "revolute", np.array([0.5, 0.0, 1.0]), np.array([0.0, 0.0, 1.0]))
HANDLE = JointAxis("handle", "revolute", np.array([0.5, 0.7, 1.0]), np.array([1.0, 0.0, 0.0]))
DRAWER = JointAxis("drawer", "prismatic", np.array([0.0, 0.0, 0.5]), np.array([-1.0, 0.0, 0.0]))


def test_each_primitive_finds_its_joint_with_sign() -> None:
    chain = (
        Primitive("rotation", (0.52, 0.7, 1.01), (-1.0, 0.02, 0.0), 0.6),  # handle turned the other way
        Primitive("rotation", (0.5, 0.03, 1.2), (0.0, 0.0, 1.0), 1.2),
        Primitive("translation", None, (0.99, 0.0, 0.05), 0.3),
    )
    matches = match_chain(chain, [HINGE, HANDLE, DRAWER])
    assert [m.joint for m in matches] == ["handle", "hinge", "drawer"]
    assert [m.sign for m in matches] == [-1.0, 1.0, -1.0]
    assert matches[1].distance_m == pytest.approx(0.03)
    assert math.degrees(matches[2].angle_rad) == pytest.approx(math.degrees(math.atan2(0.05, 0.99)), abs=1e-6)


def test_disturbed_axis_still_matches() -> None:
    tilt = math.radians(5.0)
    prim = Primitive("rotation", (0.52, 0.0, 1.0), (0.0, math.sin(tilt), math.cos(tilt)), 1.0)
    (m,) = match_chain((prim,), [HINGE, HANDLE])
    assert m.joint == "hinge"
    assert math.degrees(m.angle_rad) == pytest.approx(5.0)


def test_axis_far_from_every_joint_is_an_error() -> None:
    prim = Primitive("rotation", (0.8, 0.0, 1.0), (0.0, 0.0, 1.0), 1.0)
    with pytest.raises(SimulationError, match=r"primitive 0 \(rotation\): axis is 0\.300 m and 0\.0° from .* hinge"):
        match_chain((prim,), [HINGE, HANDLE])


def test_axis_at_wrong_angle_is_an_error() -> None:
    prim = Primitive("rotation", (0.5, 0.0, 1.0), (0.0, 1.0, 1.0), 1.0)
    with pytest.raises(SimulationError, match=r"axis is 0\.000 m and 45\.0° from"):
        match_chain((prim,), [HINGE])


def test_primitive_with_no_joint_to_drive_is_an_error() -> None:
    prim = Primitive("translation", None, (1.0, 0.0, 0.0), 0.2)
    with pytest.raises(SimulationError, match=r"primitive 0 \(translation\): no prismatic joint in the scene to drive"):
        match_chain((prim,), [HINGE])


def test_empty_chain_is_an_error() -> None:
    with pytest.raises(SimulationError, match="empty manipulation chain"):
        match_chain((), [HINGE])
