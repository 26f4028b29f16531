"""The ``door`` scene: a room door in its frame, opened by pressing its lever handle down and pulling it open.

Base frame (metres): z up, origin on the floor at the hinge line, the door's front (the side it opens to) looks
towards -x, the leaf spans +y from the hinge. Joint ``door_hinge`` turns the leaf about +z (positive = opening
towards the viewer); joint ``lever_turn`` turns the lever about +x, the door's inward normal, so a positive turn
presses the lever (which points back towards the hinge) down. The hand grips the lever bar from the front
(the conventions of ``tests.simulate.objects.LeverDoorSpec``). Markers: three on the lever, three on the leaf.
"""

from __future__ import annotations

import math

import numpy as np

from tasks.hand.grips import BAR_CURL_RAD, HANDLE_RADIUS, HANDLE_STANDOFF, PALM_TO_BAR, curl_eigengrasps
from tasks.scenes.parts import Joint, Link, Shape, draw_placement, palm_quat, uniform, urdf_text
from tasks.scenes.scene import Marker, Motion, Scene

LEAF_WIDTH_M, LEAF_HEIGHT_M = 0.85, 2.00
"""Nominal leaf: 85 x 200 cm (DIN 18101), 40 mm thick, a light hollow-core door."""
LEAF_THICKNESS_M = 0.04
LEAF_MASS_KG = 12.0
HANDLE_HEIGHT_M = 1.05
"""Lever axis above the floor (DIN 18101: 1.05 m)."""
LEVER_INSET_M = 0.07
"""Lever axis from the leaf's free edge (a 55 mm backset plus the rose)."""
LEVER_LENGTH_M = 0.13
LEVER_LIMIT_RAD = 1.1
DOOR_LIMIT_RAD = 1.75
LEVER_RANGE_RAD = (math.radians(30.0), math.radians(60.0))
DOOR_RANGE_RAD = (math.radians(40.0), math.radians(70.0))
NOMINAL_LEVER_RAD = math.radians(45.0)
NOMINAL_DOOR_RAD = math.radians(60.0)
GRIP_FROM_AXIS_M = 0.07
"""The hand grips the lever bar this far from the lever axis."""
PALM_ARC_MAX_M = 0.80
"""The demonstrated swing is capped so that the palm's arc about the hinge stays within 0.8 m: the iiwa's base
placement sweep finds no base pose for most longer arcs (swings of 40-80 degrees of leaves up to 0.95 m wide failed
in 4 of 21 seeds, all with arcs over 0.9 m)."""


def build(rng: np.random.Generator | None, seed: int | None) -> Scene:
    """The nominal door (``rng`` None) or a randomised one drawn from ``rng``."""
    w = uniform(rng, LEAF_WIDTH_M, 0.75, 0.90)
    h = uniform(rng, LEAF_HEIGHT_M, 1.95, 2.10)
    handle_z = uniform(rng, HANDLE_HEIGHT_M, 0.95, 1.10)
    lever_rad = uniform(rng, NOMINAL_LEVER_RAD, *LEVER_RANGE_RAD)
    door_rad = uniform(rng, NOMINAL_DOOR_RAD, *DOOR_RANGE_RAD)
    t = LEAF_THICKNESS_M
    gap = 0.004
    palm_radius = math.hypot(w - LEVER_INSET_M - GRIP_FROM_AXIS_M, t / 2 + HANDLE_STANDOFF + PALM_TO_BAR)
    door_rad = min(door_rad, PALM_ARC_MAX_M / palm_radius)

    frame_shapes = (
        Shape("box", (0.12, 0.06, h + 0.06), (0.02, -0.03 - gap, (h + 0.06) / 2), colour="white"),
        Shape("box", (0.12, 0.06, h + 0.06), (0.02, w + 0.03 + gap, (h + 0.06) / 2), colour="white"),
        Shape("box", (0.12, w + 0.12 + 2 * gap, 0.06), (0.02, w / 2, h + 0.03 + gap), colour="white"),
    )
    frame = Link("frame", frame_shapes)
    leaf = Link(
        "leaf",
        (Shape("box", (t, w, h), (0.0, w / 2, h / 2 + gap), colour="wood"),),
        mass=LEAF_MASS_KG,
        com=(0.0, w / 2, h / 2),
        extent=(t, w, h),
    )
    bar_x = -HANDLE_STANDOFF
    lever_shapes = (
        Shape("cylinder", (0.026, 0.012), (-0.006, 0.0, 0.0), (0.0, math.pi / 2, 0.0), colour="steel"),
        Shape("box", (HANDLE_STANDOFF, 0.02, 0.02), (-HANDLE_STANDOFF / 2, 0.0, 0.0), colour="steel"),
        Shape(
            "cylinder",
            (HANDLE_RADIUS, LEVER_LENGTH_M + 0.01),
            (bar_x, -(LEVER_LENGTH_M - 0.01) / 2, 0.0),
            (math.pi / 2, 0.0, 0.0),
            colour="steel",
        ),
    )
    lever = Link("lever", lever_shapes, mass=0.25, com=(bar_x, -0.05, 0.0), extent=(0.03, LEVER_LENGTH_M, 0.03))
    joints = (
        Joint(
            "door_hinge",
            "revolute",
            "frame",
            "leaf",
            (0.0, 0.0, 0.0),
            axis=(0.0, 0.0, 1.0),
            lower=0.0,
            upper=DOOR_LIMIT_RAD,
            effort=200.0,
            velocity=2.0,
            damping=0.5,
            friction=0.3,
        ),
        Joint(
            "lever_turn",
            "revolute",
            "leaf",
            "lever",
            (-t / 2, w - LEVER_INSET_M, handle_z),
            axis=(1.0, 0.0, 0.0),
            lower=0.0,
            upper=LEVER_LIMIT_RAD,
            effort=20.0,
            velocity=3.0,
            damping=0.02,
            friction=0.1,
        ),
    )
    front = -t / 2 - 0.006
    lever_top = HANDLE_RADIUS + 0.006
    markers = (
        Marker("lever_0", "lever", (bar_x, -LEVER_LENGTH_M + 0.01, lever_top)),
        Marker("lever_1", "lever", (bar_x, -0.02, lever_top)),
        Marker("lever_2", "lever", (bar_x - lever_top, -0.11, -0.004)),
        Marker("leaf_0", "leaf", (front, 0.35 * w, 1.55)),
        Marker("leaf_1", "leaf", (front, 0.62 * w, 1.25)),
        Marker("leaf_2", "leaf", (front, 0.45 * w, 0.60)),
    )
    place = draw_placement(rng, 0.0)
    return Scene(
        name="door",
        seed=seed,
        object_name="door",
        action="open",
        urdf=urdf_text("door", (frame, leaf, lever), joints),
        base_position=place.position,
        base_orientation=place.orientation,
        motions=(Motion("lever_turn", 0.0, lever_rad), Motion("door_hinge", 0.0, door_rad)),
        grasp_link="lever",
        palm_position=(bar_x - PALM_TO_BAR, -GRIP_FROM_AXIS_M, 0.0),
        palm_orientation=palm_quat((0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (1.0, 0.0, 0.0)),
        grasp_eigengrasps=curl_eigengrasps(BAR_CURL_RAD),
        markers=markers,
        model_links=("frame", "leaf", "lever"),
        joint_start={"door_hinge": 0.0, "lever_turn": 0.0},
    )
