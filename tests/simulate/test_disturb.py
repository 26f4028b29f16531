"""Disturbed axes move and tilt by exactly the requested amounts."""

from __future__ import annotations

import math

import numpy as np
import pytest

from schemas.descriptor import Primitive
from tasks.simulate.disturb import disturb_primitive
from tasks.simulate.matching import axis_angle_rad, point_line_distance_m


def test_rotation_axis_moved_2cm_and_tilted_5deg() -> None:
    rng = np.random.default_rng(1)
    prim = Primitive("rotation", (0.5, 0.1, 1.0), (0.0, 0.6, 0.8), 1.2)
    for _ in range(20):
        out = disturb_primitive(prim, 0.02, 5.0, rng)
        assert math.degrees(axis_angle_rad(np.array(out.dir), np.array(prim.dir))) == pytest.approx(5.0)
        assert np.linalg.norm(out.dir) == pytest.approx(1.0)
        assert out.pos is not None
        dist = point_line_distance_m(np.array(out.pos), np.array(prim.pos), np.array(prim.dir))
        assert dist == pytest.approx(0.02)
        assert out.extent == prim.extent


def test_translation_direction_tilted_only() -> None:
    prim = Primitive("translation", None, (1.0, 0.0, 0.0), 0.3)
    out = disturb_primitive(prim, 0.02, 5.0, np.random.default_rng(2))
    assert out.pos is None
    assert math.degrees(axis_angle_rad(np.array(out.dir), np.array(prim.dir))) == pytest.approx(5.0)
