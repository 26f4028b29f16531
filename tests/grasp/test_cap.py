"""The cap a palm looks down on (``mount.find_cap``): the solid the palm meets first as far as its side keeps one
radius, its neck and body the mount (a knob's stem and plate too); a box, a can and a lone cylinder have none. On the
bottle scene a cap planned as the part holds the cap, not the neck below it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tasks.arrays import Points
from tasks.grasp.mount import find_cap, find_mount
from tasks.grasp.object_model import build_object_model
from tasks.grasp.primitive_fit import within
from tests.grasp.bench_object import plan_bench_scene
from tests.grasp.surface_sampling import sample_box_surface, sample_cylinder_surface

CAP_RADIUS_M = 0.020
CAP_HEIGHT_M = 0.022
NECK_RADIUS_M = 0.018
"""A cap 40 mm across and 22 mm tall on a neck 2 mm narrower (the bottle scene's), on a shoulder and a body."""
TOP = np.array([0.3, -0.1, 1.0])
"""Centre of the cap's top face, world m; the bottle stands along world z."""


def bottle_points(rng: np.random.Generator) -> Points:
    """Surface points of a bottle's top as a sampled model has them, each closed cylinder whole (the cap's, the
    neck's, the shoulder's and the body's hidden faces too): cap, 12 mm of neck below it, shoulder, body."""
    shapes = (  # (radius, height, depth of the top below the cap's top)
        (CAP_RADIUS_M, CAP_HEIGHT_M, 0.0),
        (NECK_RADIUS_M, 0.025, CAP_HEIGHT_M - 0.013),
        (0.030, 0.030, CAP_HEIGHT_M + 0.012),
        (0.042, 0.08, CAP_HEIGHT_M + 0.042),
    )
    clouds = []
    for radius, height, below in shapes:
        pts, _ = sample_cylinder_surface(radius, height / 2, 2500, rng)
        clouds.append(pts + TOP - np.array([0.0, 0.0, below + height / 2]))
    return np.concatenate(clouds)


@pytest.mark.parametrize("tilt_deg", [0.0, 10.0])
def test_cap_on_a_bottle_is_found_with_its_size_and_axis(tilt_deg: float) -> None:
    """Seen from 80 mm above, the approach straight down or tilted 10°: the cap's radius within 0.5 mm, its height
    (top to where the neck begins) within 2 mm, its axis within 1° of world -z and its top face's centre within
    1 mm."""
    points = bottle_points(np.random.default_rng(3))
    approach = Rotation.from_euler("x", tilt_deg, degrees=True).apply([0.0, 0.0, -1.0])
    cap = find_cap(points, TOP - 0.08 * approach, approach)
    assert cap is not None
    assert cap.kind == "cylinder"
    assert cap.size[0] == pytest.approx(CAP_RADIUS_M, abs=0.0005)
    assert 2.0 * cap.size[1] == pytest.approx(CAP_HEIGHT_M, abs=0.002)
    axis = Rotation.from_quat(cap.quat_xyzw).apply([0.0, 0.0, 1.0])
    assert math.degrees(math.acos(float(axis @ [0.0, 0.0, -1.0]))) < 1.0
    assert np.linalg.norm(np.asarray(cap.position) - cap.size[1] * axis - TOP) < 0.001
    inside = within(cap, points, 0.0)
    assert not inside[points[:, 2] < TOP[2] - CAP_HEIGHT_M - 0.004].any()  # nothing of the neck or below


def test_a_cap_side_with_a_sector_left_unsampled_keeps_its_height() -> None:
    """A sampled side leaves, by chance, one of the eight sectors of a 2 mm slab without a point: here the side has
    none over 80 degrees round the axis (one whole sector and parts of its neighbours), 6 to 8 mm below the top. The
    cap still reaches down to the neck (its height within 2 mm), not to where the gap is."""
    points = bottle_points(np.random.default_rng(3))
    rel = points - TOP
    azimuth = np.degrees(np.arctan2(rel[:, 1], rel[:, 0]))
    radial = np.linalg.norm(rel[:, :2], axis=1)
    gap = (azimuth > 20.0) & (azimuth < 100.0) & (rel[:, 2] < -0.006) & (rel[:, 2] > -0.008) & (radial > 0.019)
    down = np.array([0.0, 0.0, -1.0])
    cap = find_cap(points[~gap], TOP - 0.08 * down, down)
    assert gap.sum() > 0
    assert cap is not None
    assert 2.0 * cap.size[1] == pytest.approx(CAP_HEIGHT_M, abs=0.002)


def test_box_can_and_lone_cylinder_have_no_cap() -> None:
    """A box's top is no disk; a can's side goes on past 60 mm; a cylinder with nothing beyond it is the whole
    object."""
    rng = np.random.default_rng(4)
    down = np.array([0.0, 0.0, -1.0])
    box, _ = sample_box_surface(np.array([0.03, 0.02, 0.05]), 6000, rng)
    assert find_cap(box, np.array([0.0, 0.0, 0.13]), down) is None
    can, _ = sample_cylinder_surface(0.03, 0.06, 6000, rng)
    assert find_cap(can, np.array([0.0, 0.0, 0.14]), down) is None
    lone, _ = sample_cylinder_surface(CAP_RADIUS_M, CAP_HEIGHT_M / 2, 3000, rng)
    assert find_cap(lone, np.array([0.0, 0.0, 0.09]), down) is None


def test_bottle_model_is_its_cap_on_a_mount() -> None:
    """Modelled from above, the bottle's free body is its cap: one piece, the cap's cylinder; the neck, shoulder
    and body are the mount."""
    points = bottle_points(np.random.default_rng(5))
    down = np.array([0.0, 0.0, -1.0])
    model = build_object_model(
        points, np.random.default_rng(0), viewpoint=TOP + np.array([0.0, 0.0, 0.08]), approach=down
    )
    assert model.cylinder is not None and model.cylinder.size[0] == pytest.approx(CAP_RADIUS_M, abs=0.0005)
    assert model.mount is not None
    assert len(model.parts) - model.mount_parts == 1
    part = model.points[~model.mount]
    assert float(part[:, 2].min()) > TOP[2] - CAP_HEIGHT_M - 0.004
    assert float(model.points[model.mount][:, 2].max()) < TOP[2] - CAP_HEIGHT_M + 0.004


@pytest.mark.parametrize(
    ("radius", "height", "tilt_deg", "noise_m"), [(0.022, 0.018, 0.0, 0.0), (0.016, 0.026, 10.0, 0.0003)]
)
def test_knob_on_a_plate_is_a_cap_on_its_stem(radius: float, height: float, tilt_deg: float, noise_m: float) -> None:
    """A knob (44 mm across and 18 mm tall; 32 mm and 26 mm, seen 10° off its axis through 0.3 mm of noise) on a
    stem 12 mm across and 20 mm long, in front of a plate 120 mm square, seen from 80 mm: the plate is a mount, and
    the knob a cap on its stem as a bottle's cap is on its neck. The model's free body is the knob's cylinder; its
    stem and the plate are the mount."""
    rng = np.random.default_rng(6)
    stem = 0.020
    clouds = [
        sample_cylinder_surface(radius, height / 2, 2500, rng)[0] + TOP - [0.0, 0.0, height / 2],
        sample_cylinder_surface(0.006, stem / 2, 600, rng)[0] + TOP - [0.0, 0.0, height + stem / 2],
        sample_box_surface(np.array([0.06, 0.06, 0.005]), 6000, rng)[0] + TOP - [0.0, 0.0, height + stem + 0.005],
    ]
    points = np.concatenate(clouds)
    points += rng.normal(scale=noise_m, size=points.shape) if noise_m else 0.0
    approach = Rotation.from_euler("x", tilt_deg, degrees=True).apply([0.0, 0.0, -1.0])
    palm = TOP - 0.08 * approach
    assert find_mount(points, palm, approach).any()
    model = build_object_model(points, np.random.default_rng(0), viewpoint=palm, approach=approach)
    assert model.cylinder is not None and model.cylinder.size[0] == pytest.approx(radius, abs=0.0005)
    assert 2.0 * model.cylinder.size[1] == pytest.approx(height, abs=0.002)
    assert model.mount is not None
    assert len(model.parts) - model.mount_parts == 1
    assert float(model.points[~model.mount][:, 2].min()) > TOP[2] - height - 0.004
    assert float(model.points[model.mount][:, 2].min()) < TOP[2] - height - stem  # the plate is the mount


@pytest.mark.slow
def test_benchmark_bottle_cap_is_held_not_the_neck() -> None:
    """The benchmark's bottle seed 1 (seed 11): planned on the whole scan as one free body, the grasp the planner's
    check held closed on the cap and the neck and dropped the exact cap. Planned on the cap, the grasp holds the
    exact cap under the benchmark's hold test, at the demonstrated palm."""
    planned = plan_bench_scene(11, "bottle seed 1")
    assert planned.grasp.quality["force_closure"] is True
    assert planned.grasp.quality["demo_offset_m"] < 0.005
    assert planned.holds
