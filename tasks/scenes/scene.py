"""What a built-in demonstration scene is: an articulated object placed in the world, the markers on it, where
the hand grasps it and the motion the demonstrator drives.

World frame: z up, metres, radians, quaternions ``[x, y, z, w]``. The object's URDF is written in its own base
frame; ``base_position``/``base_orientation`` place that frame in the world (fixed base). Link frames are the
URDF link frames (the joint frames), not the inertial frames.
"""

from __future__ import annotations

from dataclasses import dataclass, field

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]

HAND_LINK = "@hand"
"""``Marker.link`` of a marker worn by the demonstrator (the sliding door's thumb marker): its offset is in the
palm frame of ``tasks.hand.barrett`` (z = approach)."""


@dataclass(frozen=True)
class Marker:
    """A motion-capture marker: ``name`` (the recording's topic is ``/mocap/<name>``), the ``link`` it is fixed
    to (or ``HAND_LINK``), ``offset`` metres in that link's frame."""

    name: str
    link: str
    offset: Vec3


@dataclass(frozen=True)
class Motion:
    """One demonstrated primitive: URDF ``joint`` driven from ``start`` to ``end`` (rad or m, joint
    coordinates). Motions happen one after another in the order given."""

    joint: str
    start: float
    end: float


@dataclass(frozen=True)
class Scene:
    """A built-in scene instance (nominal when ``seed`` is None, else randomised by it).

    ``palm_position``/``palm_orientation`` is the demonstrated grasp: the Barrett palm frame
    (``tasks.hand.barrett``: +z approach) in the ``grasp_link`` frame, at the joint values of the first motion's
    start. ``grasp_eigengrasps`` are the amplitudes of that grasp. ``model_links`` are the links whose surfaces
    make the object model (what a 3-D digitizer would scan). ``joint_start`` holds every movable joint's value
    when the demonstration begins (joints not listed start at 0).
    """

    name: str
    seed: int | None
    object_name: str
    action: str
    urdf: str
    base_position: Vec3
    base_orientation: Quat
    motions: tuple[Motion, ...]
    grasp_link: str
    palm_position: Vec3
    palm_orientation: Quat
    grasp_eigengrasps: tuple[float, float]
    markers: tuple[Marker, ...]
    model_links: tuple[str, ...]
    joint_start: dict[str, float] = field(default_factory=dict)
    floor_z: float = 0.0
