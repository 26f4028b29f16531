"""The ``bottle`` scene: a bottle held upright on a side table whose screw cap is unscrewed.

Base frame (metres): z up, origin on the floor under the bottle's axis. The bottle is fixed (held in a stand);
the cap turns on joint ``cap_turn`` (continuous, axis +z): unscrewing a right-hand thread is counter-clockwise
seen from above, a positive rotation about +z. The hand grips the cap from above (the conventions of
``tests.simulate.objects.CapSpec``). Four markers on the cap, around its rim and on its top.
"""

from __future__ import annotations

import math

import numpy as np

from tasks.hand.grips import CAP_CURL_RAD, curl_eigengrasps
from tasks.scenes.parts import Joint, Link, Shape, draw_placement, palm_quat, uniform, urdf_text
from tasks.scenes.scene import Marker, Motion, Scene

CAP_RADIUS_M = 0.02
"""Nominal cap: 40 mm across (a wide-mouth bottle); randomised 12-30 mm radius."""
CAP_RADIUS_RANGE_M = (0.012, 0.030)
CAP_HEIGHT_M = 0.022
BODY_HEIGHT_M = 0.22
TABLE_HEIGHT_M = 0.75
TABLE_TOP_M = (0.40, 0.40)
NECK_M = 0.025
"""Neck between the shoulder and the cap."""
TURN_RANGE_RAD = (1.5, 4.0)
NOMINAL_TURN_RAD = 3.0
PALM_ABOVE_CAP_M = 0.08
"""Palm face above the cap's top: from there the distal links close on the cap's rim (at 55 mm, as ``CapSpec``, they
reach past a small cap to the neck)."""
MAX_TILT_DEG = 0.0
"""The bottle stays upright (yaw only): tilted by up to 2.5 degrees its truth descriptor failed in 1 of 20
seeds in simulation (two fingers did not close on the cap), upright in none."""
CAP_MASS_KG = 0.2
"""Simulated cap mass: a real cap weighs 2-10 g, but so light a link held by the palm constraint jitters in
pybullet (50 g kept spinning at 1.7 rad/s after the turn); 200 g, as ``CapSpec``, holds still."""


def build(rng: np.random.Generator | None, seed: int | None) -> Scene:
    """The nominal bottle (``rng`` None) or a randomised one drawn from ``rng``."""
    cap_r = uniform(rng, CAP_RADIUS_M, *CAP_RADIUS_RANGE_M)
    cap_h = uniform(rng, CAP_HEIGHT_M, 0.016, 0.026)
    body_r = max(cap_r + 0.015, uniform(rng, 0.04, 0.032, 0.048))
    body_h = uniform(rng, BODY_HEIGHT_M, 0.16, 0.28)
    table_h = uniform(rng, TABLE_HEIGHT_M, 0.70, 0.80)
    turn = uniform(rng, NOMINAL_TURN_RAD, *TURN_RANGE_RAD)
    neck_r = cap_r - 0.002
    shoulder_h = 0.03

    table = Link(
        "table",
        (
            Shape("box", (*TABLE_TOP_M, 0.03), (0.0, 0.0, table_h - 0.015), colour="wood"),
            Shape("box", (0.06, 0.06, table_h - 0.03), (0.0, 0.0, (table_h - 0.03) / 2), colour="dark"),
        ),
    )
    bottle_shapes = (
        Shape("cylinder", (body_r, body_h), (0.0, 0.0, body_h / 2), colour="green"),
        Shape("cylinder", ((body_r + neck_r) / 2, shoulder_h), (0.0, 0.0, body_h + shoulder_h / 2), colour="green"),
        Shape("cylinder", (neck_r, NECK_M), (0.0, 0.0, body_h + shoulder_h + NECK_M / 2), colour="green"),
    )
    bottle = Link(
        "bottle", bottle_shapes, mass=0.6, com=(0.0, 0.0, body_h / 2), extent=(2 * body_r, 2 * body_r, body_h)
    )
    cap = Link(
        "cap",
        (Shape("cylinder", (cap_r, cap_h), (0.0, 0.0, cap_h / 2), colour="red"),),
        mass=CAP_MASS_KG,
        com=(0.0, 0.0, cap_h / 2),
        extent=(2 * cap_r, 2 * cap_r, cap_h),
    )
    cap_base = body_h + shoulder_h + NECK_M - cap_h * 0.6  # the cap skirt covers the top of the neck
    joints = (
        Joint("table_to_bottle", "fixed", "table", "bottle", (0.0, 0.0, table_h)),
        Joint(
            "cap_turn",
            "continuous",
            "bottle",
            "cap",
            (0.0, 0.0, cap_base),
            axis=(0.0, 0.0, 1.0),
            effort=2.0,
            velocity=6.0,
            damping=0.002,
            friction=0.02,
        ),
    )
    rim = cap_r + 0.004  # 4 mm marker balls on the rim
    markers = (
        Marker("cap_0", "cap", (rim * math.cos(0.3), rim * math.sin(0.3), 0.35 * cap_h)),
        Marker("cap_1", "cap", (rim * math.cos(2.4), rim * math.sin(2.4), 0.70 * cap_h)),
        Marker("cap_2", "cap", (rim * math.cos(4.3), rim * math.sin(4.3), 0.50 * cap_h)),
        Marker("cap_3", "cap", (0.55 * cap_r, -0.2 * cap_r, cap_h + 0.004)),
    )
    place = draw_placement(rng, MAX_TILT_DEG)
    return Scene(
        name="bottle",
        seed=seed,
        object_name="bottle",
        action="unscrew",
        urdf=urdf_text("bottle", (table, bottle, cap), joints),
        base_position=place.position,
        base_orientation=place.orientation,
        motions=(Motion("cap_turn", 0.0, turn),),
        grasp_link="cap",
        palm_position=(0.0, 0.0, cap_h + PALM_ABOVE_CAP_M),
        palm_orientation=palm_quat((1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, -1.0)),
        grasp_eigengrasps=curl_eigengrasps(CAP_CURL_RAD),
        markers=markers,
        model_links=("bottle", "cap"),
        joint_start={"cap_turn": 0.0},
    )
