"""The ``sliding-door`` scene: a sideboard with two bypass sliding doors; the left one slides to the right.

Base frame (metres): z up, origin on the floor under the cabinet's centre, the front looks towards -x. The
right door is fixed on the inner track; the left door runs on the outer track, joint ``door_slide`` (prismatic,
axis -y: positive = sliding to the right as seen from the front). A vertical bar handle near its outer edge is
gripped from the front. Four markers on the moving door, one on the demonstrator's thumb (``HAND_LINK``).
"""

from __future__ import annotations

import numpy as np

from tasks.hand.grips import BAR_CURL_RAD, HANDLE_RADIUS, HANDLE_STANDOFF, PALM_TO_BAR, curl_eigengrasps
from tasks.scenes.parts import Joint, Link, Shape, bar_handle, draw_placement, palm_quat, uniform, urdf_text
from tasks.scenes.scene import HAND_LINK, Marker, Motion, Scene

WIDTH_M, DEPTH_M, HEIGHT_M = 1.20, 0.45, 0.80
"""Nominal sideboard: 120 cm wide, 45 cm deep, 80 cm tall (plinth included)."""
PLINTH_M = 0.08
PANEL_THICKNESS_M = 0.018
"""18 mm board doors."""
PANEL_MASS_KG = 4.5
SLIDE_RANGE_M = (0.20, 0.40)
NOMINAL_SLIDE_M = 0.30
THUMB_OFFSET_M = (0.0, -0.045, 0.035)
"""The demonstrator's thumb marker in the palm frame: beside finger 3 (the thumb, -y), 35 mm ahead of the palm."""


def build(rng: np.random.Generator | None, seed: int | None) -> Scene:
    """The nominal sideboard (``rng`` None) or a randomised one drawn from ``rng``."""
    scale = uniform(rng, 1.0, 0.85, 1.15)
    w, d, h = WIDTH_M * scale, DEPTH_M, HEIGHT_M * uniform(rng, 1.0, 0.9, 1.15)
    slide = uniform(rng, NOMINAL_SLIDE_M, *SLIDE_RANGE_M)
    t = PANEL_THICKNESS_M
    panel_w, panel_h = w / 2 + 0.02, h - PLINTH_M - 0.04
    inner_x = -d / 2 - t / 2 - 0.002
    outer_x = inner_x - t - 0.006
    panel_z = PLINTH_M + 0.02 + panel_h / 2

    carcass_shapes = (
        Shape("box", (d, w, h - PLINTH_M), (0.0, 0.0, PLINTH_M + (h - PLINTH_M) / 2), colour="oak"),
        Shape("box", (d - 0.05, w - 0.04, PLINTH_M), (0.025, 0.0, PLINTH_M / 2), colour="dark"),
        Shape("box", (t, panel_w, panel_h), (inner_x, -w / 4, panel_z), colour="cream"),
    )
    carcass = Link("carcass", carcass_shapes)

    bar_len = 0.20
    bar_x = -t / 2 - HANDLE_STANDOFF
    bar_y = panel_w / 2 - 0.07
    bar_z = min(0.15, panel_h / 2 - bar_len / 2 - 0.05)
    panel_shapes = (
        Shape("box", (t, panel_w, panel_h), (0.0, 0.0, 0.0), colour="cream"),
        *bar_handle(-t / 2, bar_y, bar_z, bar_len, standoff=HANDLE_STANDOFF, radius=HANDLE_RADIUS),
    )
    panel = Link("panel", panel_shapes, mass=PANEL_MASS_KG, extent=(t, panel_w, panel_h))
    joints = (
        Joint(
            "door_slide",
            "prismatic",
            "carcass",
            "panel",
            (outer_x, w / 4, panel_z),
            axis=(0.0, -1.0, 0.0),
            lower=0.0,
            upper=w / 2 - 0.06,
            effort=100.0,
            velocity=1.0,
            damping=2.0,
            friction=1.0,
        ),
    )
    front = -t / 2 - 0.006
    markers = (
        Marker("panel_0", "panel", (front, -0.30 * panel_w, 0.35 * panel_h)),
        Marker("panel_1", "panel", (front, 0.25 * panel_w, 0.40 * panel_h)),
        Marker("panel_2", "panel", (front, -0.20 * panel_w, -0.30 * panel_h)),
        Marker("panel_3", "panel", (front, 0.32 * panel_w, -0.22 * panel_h)),
        Marker("thumb", HAND_LINK, THUMB_OFFSET_M),
    )
    place = draw_placement(rng, 0.0)
    return Scene(
        name="sliding-door",
        seed=seed,
        object_name="sliding-door",
        action="slide",
        urdf=urdf_text("sliding_door", (carcass, panel), joints),
        base_position=place.position,
        base_orientation=place.orientation,
        motions=(Motion("door_slide", 0.0, slide),),
        grasp_link="panel",
        palm_position=(bar_x - PALM_TO_BAR, bar_y, bar_z),
        palm_orientation=palm_quat((0.0, 0.0, 1.0), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0)),
        grasp_eigengrasps=curl_eigengrasps(BAR_CURL_RAD),
        markers=markers,
        model_links=("carcass", "panel"),
        joint_start={"door_slide": 0.0},
    )
