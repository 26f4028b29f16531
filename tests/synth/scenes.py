"""Small scenes built from the simulate bench's procedural door and drawer, for the synth tests (they need no
catalog): a door opened about a tilted, yawed hinge and a drawer pulled out, each with markers and a hand marker."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from tasks.arrays import Points
from tasks.hand.grips import HANDLE_STANDOFF, PALM_TO_BAR
from tasks.scenes.scene import HAND_LINK, Marker, Motion, Scene
from tests.simulate.objects import DoorSpec, DrawerSpec

PALM_QUAT = tuple(float(v) for v in Rotation.from_matrix(np.column_stack([[0, 0, 1], [0, -1, 0], [1, 0, 0]])).as_quat())


def door_scene(seed: int | None = 5) -> Scene:
    """A door (hinge ``hinge``, link ``door``) yawed 30 deg and tilted 5 deg, opened by 0.9 rad."""
    spec = DoorSpec()
    base = Rotation.from_euler("zx", [30.0, 5.0], degrees=True).as_quat()
    return Scene(
        name="test_door",
        seed=seed,
        object_name="door",
        action="open",
        urdf=spec.urdf(),
        base_position=(0.8, 0.2, 0.0),
        base_orientation=(float(base[0]), float(base[1]), float(base[2]), float(base[3])),
        motions=(Motion("hinge", 0.0, 0.9),),
        grasp_link="door",
        palm_position=(-0.02 - HANDLE_STANDOFF - PALM_TO_BAR, spec.handle_y, 0.0),
        palm_orientation=PALM_QUAT,  # type: ignore[arg-type]
        grasp_eigengrasps=(0.5, 0.1),
        markers=(
            Marker("door_0", "door", (-0.02, 0.3, 0.2)),
            Marker("door_1", "door", (-0.02, 0.6, -0.2)),
            Marker("door_2", "door", (-0.02, 0.5, 0.3)),
            Marker("frame_0", "frame", (0.1, -0.07, 0.3)),
            Marker("thumb", HAND_LINK, (0.0, 0.05, 0.03)),
        ),
        model_links=("frame", "door"),
    )


def drawer_scene(seed: int | None = 6) -> Scene:
    """A drawer (joint ``slide``) pulled out 0.25 m, in a cabinet yawed 120 deg."""
    spec = DrawerSpec()
    base = Rotation.from_euler("z", 120.0, degrees=True).as_quat()
    return Scene(
        name="test_drawer",
        seed=seed,
        object_name="drawer",
        action="open",
        urdf=spec.urdf(),
        base_position=(0.5, -0.3, 0.0),
        base_orientation=(float(base[0]), float(base[1]), float(base[2]), float(base[3])),
        motions=(Motion("slide", 0.0, 0.25),),
        grasp_link="drawer",
        palm_position=(-HANDLE_STANDOFF - PALM_TO_BAR, 0.0, 0.0),
        palm_orientation=PALM_QUAT,  # type: ignore[arg-type]
        grasp_eigengrasps=(0.5, 0.1),
        markers=(
            Marker("drawer_0", "drawer", (0.0, 0.2, 0.1)),
            Marker("drawer_1", "drawer", (0.0, -0.2, 0.1)),
            Marker("cabinet_0", "cabinet", (0.0, 0.3, 0.25)),
        ),
        model_links=("cabinet", "drawer"),
    )


def box_model(scene: Scene, n_points: int, rng: np.random.Generator) -> Points:
    """Stand-in object model: points spread over a 0.5 m box around the scene's base (world frame)."""
    centre = np.asarray(scene.base_position) + np.array([0.0, 0.0, 0.5])
    out: Points = centre + rng.uniform(-0.25, 0.25, (n_points, 3))
    return out
