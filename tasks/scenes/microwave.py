"""The ``microwave`` scene: a countertop microwave oven on a microwave cart, its door swinging open on a vertical
hinge.

Base frame (metres): z up, origin on the floor under the oven's centre, the oven's front looks towards -x.
The door is hinged on the oven's left side as seen from the front (+y edge) and opens towards the viewer, a
positive rotation of joint ``door_hinge`` (axis -z). A vertical bar handle stands in front of the door's free edge;
the hand grips it from the front (the conventions of ``tests.simulate.objects``). Three markers on the door.
"""

from __future__ import annotations

import math

import numpy as np

from tasks.hand.grips import BAR_CURL_RAD, HANDLE_RADIUS, HANDLE_STANDOFF, PALM_TO_BAR, curl_eigengrasps
from tasks.scenes.parts import Joint, Link, Shape, bar_handle, draw_placement, palm_quat, uniform, urdf_text
from tasks.scenes.scene import Marker, Motion, Scene

WIDTH_M, DEPTH_M, HEIGHT_M = 0.50, 0.36, 0.30
"""Nominal outer size of the oven (a 25-litre countertop model: 50 x 36 x 30 cm)."""
DOOR_FRACTION = 0.72
"""Share of the front the door covers; the control panel takes the rest (right side)."""
DOOR_THICKNESS_M = 0.04
DOOR_MASS_KG = 1.6
CART_HEIGHT_M = 0.90
"""Top of the cart the oven stands on (kitchen worktop height, EN 1116: 0.85-0.95 m). The cart is only 5 cm
larger than the oven on each side, so the robot can stand beside it for wide openings (a full-width counter
leaves the iiwa no base pose for openings over about 70 degrees)."""
DOOR_LIMIT_RAD = 2.0
"""The door stops at about 115 degrees."""
OPEN_RANGE_RAD = (math.radians(60.0), math.radians(110.0))
"""Demonstrated opening of a randomised instance."""
NOMINAL_OPEN_RAD = math.radians(90.0)
MAX_TILT_DEG = 3.0


def build(rng: np.random.Generator | None, seed: int | None) -> Scene:
    """The nominal microwave (``rng`` None) or a randomised one drawn from ``rng``."""
    scale = uniform(rng, 1.0, 0.85, 1.15)
    w, d, h = WIDTH_M * scale, DEPTH_M * scale, HEIGHT_M * scale
    cart_h = uniform(rng, CART_HEIGHT_M, 0.85, 0.95)
    open_rad = uniform(rng, NOMINAL_OPEN_RAD, *OPEN_RANGE_RAD)
    door_w = DOOR_FRACTION * w
    t = DOOR_THICKNESS_M

    cart = Link(
        "cart",
        (Shape("box", (d + 0.1, w + 0.1, cart_h), (0.02, 0.0, cart_h / 2), colour="counter"),),
    )
    body_shapes = (
        Shape("box", (d, w, h), (0.0, 0.0, h / 2), colour="white"),
        Shape(
            "box",
            (0.004, w - door_w - 0.02, h - 0.04),
            (-d / 2 - 0.002, -w / 2 + (w - door_w) / 2, h / 2),
            colour="dark",
            collision=False,
        ),
    )
    body = Link("body", body_shapes, mass=14.0, com=(0.0, 0.0, h / 2), extent=(d, w, h))

    # door frame: on the hinge axis at the oven's bottom; the door spans -y from the hinge
    bar_len = min(0.20, h - 0.08)
    bar_x = -t / 2 - HANDLE_STANDOFF
    bar_y = -(door_w - 0.045)
    door_shapes = (
        Shape("box", (t, door_w, h), (0.0, -door_w / 2, h / 2), colour="white"),
        Shape(
            "box",
            (0.004, door_w * 0.62, h * 0.62),
            (-t / 2 - 0.002, -door_w * 0.42, h / 2),
            colour="glass",
            collision=False,
        ),
        *bar_handle(-t / 2, bar_y, h / 2, bar_len, standoff=HANDLE_STANDOFF, radius=HANDLE_RADIUS),
    )
    door = Link("door", door_shapes, mass=DOOR_MASS_KG, com=(0.0, -door_w / 2, h / 2), extent=(t, door_w, h))
    joints = (
        Joint("cart_to_body", "fixed", "cart", "body", (0.0, 0.0, cart_h)),
        Joint(
            "door_hinge",
            "revolute",
            "body",
            "door",
            (-d / 2 - t / 2, w / 2, 0.0),
            axis=(0.0, 0.0, -1.0),
            lower=0.0,
            upper=DOOR_LIMIT_RAD,
            effort=20.0,
            velocity=3.0,
            damping=0.05,
            friction=0.05,
        ),
    )
    front = -t / 2 - 0.006  # marker centres 6 mm in front of the door face
    markers = (
        Marker("door_0", "door", (front, -0.22 * door_w, 0.82 * h)),
        Marker("door_1", "door", (front, -0.50 * door_w, 0.18 * h)),
        Marker("door_2", "door", (front, -0.80 * door_w, 0.74 * h)),
    )
    place = draw_placement(rng, MAX_TILT_DEG)
    return Scene(
        name="microwave",
        seed=seed,
        object_name="microwave",
        action="open",
        urdf=urdf_text("microwave", (cart, body, door), joints),
        base_position=place.position,
        base_orientation=place.orientation,
        motions=(Motion("door_hinge", 0.0, open_rad),),
        grasp_link="door",
        palm_position=(bar_x - PALM_TO_BAR, bar_y, h / 2),
        palm_orientation=palm_quat((0.0, 0.0, 1.0), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0)),
        grasp_eigengrasps=curl_eigengrasps(BAR_CURL_RAD),
        markers=markers,
        model_links=("body", "door"),
        joint_start={"door_hinge": 0.0},
    )
