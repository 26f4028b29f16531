"""URDF text from simple parts (boxes, cylinders), and the random draws shared by the built-in scenes.

Metres, kilograms, radians; a shape's ``xyz``/``rpy`` is its pose in its link frame. Inertias are those of a
solid box of the link's ``extent`` about its centre of mass ``com`` (a coarse but physical stand-in).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from tasks.rotations import quat_tuple_from_matrix
from tasks.scenes.scene import Quat, Vec3

COLOURS: dict[str, tuple[float, float, float, float]] = {
    "white": (0.92, 0.92, 0.90, 1.0),
    "steel": (0.62, 0.64, 0.68, 1.0),
    "dark": (0.18, 0.18, 0.20, 1.0),
    "glass": (0.25, 0.32, 0.36, 1.0),
    "wood": (0.62, 0.45, 0.28, 1.0),
    "oak": (0.78, 0.62, 0.42, 1.0),
    "cream": (0.90, 0.86, 0.76, 1.0),
    "green": (0.20, 0.55, 0.35, 1.0),
    "red": (0.80, 0.15, 0.12, 1.0),
    "blue": (0.20, 0.40, 0.80, 1.0),
    "counter": (0.45, 0.45, 0.48, 1.0),
}
"""Material colours (RGBA) the scenes' visuals use."""


@dataclass(frozen=True)
class Shape:
    """A box (``size`` = x, y, z edge lengths) or a cylinder along its local z (``size`` = radius, length)."""

    kind: Literal["box", "cylinder"]
    size: tuple[float, ...]
    xyz: Vec3
    rpy: Vec3 = (0.0, 0.0, 0.0)
    colour: str = "white"
    collision: bool = True

    def geometry(self) -> str:
        """The URDF ``<geometry>`` element."""
        if self.kind == "box":
            sx, sy, sz = self.size
            return f'<geometry><box size="{sx:.6f} {sy:.6f} {sz:.6f}"/></geometry>'
        radius, length = self.size
        return f'<geometry><cylinder radius="{radius:.6f}" length="{length:.6f}"/></geometry>'

    def xml(self) -> str:
        """Visual (and collision) elements."""
        o = f'<origin xyz="{_fmt(self.xyz)}" rpy="{_fmt(self.rpy)}"/>'
        visual = f'<visual>{o}{self.geometry()}<material name="{self.colour}"/></visual>'
        return visual + (f"<collision>{o}{self.geometry()}</collision>" if self.collision else "")


@dataclass(frozen=True)
class Link:
    """A URDF link: shapes, ``mass`` kg (0 = part of the fixed base), centre of mass ``com`` and the box
    ``extent`` (m) its inertia is taken from."""

    name: str
    shapes: tuple[Shape, ...]
    mass: float = 0.0
    com: Vec3 = (0.0, 0.0, 0.0)
    extent: Vec3 = (0.1, 0.1, 0.1)

    def xml(self) -> str:
        """The ``<link>`` element."""
        ex, ey, ez = self.extent
        m = self.mass
        ixx, iyy, izz = m * (ey**2 + ez**2) / 12, m * (ex**2 + ez**2) / 12, m * (ex**2 + ey**2) / 12
        inertial = (
            f'<inertial><origin xyz="{_fmt(self.com)}"/><mass value="{m:.6f}"/>'
            f'<inertia ixx="{ixx:.8f}" iyy="{iyy:.8f}" izz="{izz:.8f}" ixy="0" ixz="0" iyz="0"/></inertial>'
        )
        return f'<link name="{self.name}">{inertial}{"".join(s.xml() for s in self.shapes)}</link>'


@dataclass(frozen=True)
class Joint:
    """A URDF joint from ``parent`` to ``child`` at ``xyz``/``rpy`` (parent link frame) about/along ``axis``;
    limits rad or m, ``effort`` N·m or N, ``velocity`` rad/s or m/s, ``damping`` N·m·s/rad or N·s/m,
    ``friction`` N·m or N."""

    name: str
    kind: Literal["revolute", "prismatic", "continuous", "fixed"]
    parent: str
    child: str
    xyz: Vec3
    axis: Vec3 = (0.0, 0.0, 1.0)
    rpy: Vec3 = (0.0, 0.0, 0.0)
    lower: float = 0.0
    upper: float = 0.0
    effort: float = 100.0
    velocity: float = 2.0
    damping: float = 0.0
    friction: float = 0.0

    def xml(self) -> str:
        """The ``<joint>`` element."""
        head = (
            f'<joint name="{self.name}" type="{self.kind}"><parent link="{self.parent}"/>'
            f'<child link="{self.child}"/><origin xyz="{_fmt(self.xyz)}" rpy="{_fmt(self.rpy)}"/>'
        )
        if self.kind == "fixed":
            return head + "</joint>"
        limit = f'<limit effort="{self.effort}" velocity="{self.velocity}"'
        limit += "/>" if self.kind == "continuous" else f' lower="{self.lower:.6f}" upper="{self.upper:.6f}"/>'
        dynamics = f'<dynamics damping="{self.damping}" friction="{self.friction}"/>'
        return head + f'<axis xyz="{_fmt(self.axis)}"/>{limit}{dynamics}</joint>'


def urdf_text(robot: str, links: tuple[Link, ...], joints: tuple[Joint, ...]) -> str:
    """The URDF document of ``links`` (the first is the base) and ``joints``, with the ``COLOURS`` materials."""
    materials = "".join(
        f'<material name="{name}"><color rgba="{r} {g} {b} {a}"/></material>' for name, (r, g, b, a) in COLOURS.items()
    )
    body = "".join(link.xml() for link in links) + "".join(joint.xml() for joint in joints)
    return f'<?xml version="1.0"?>\n<robot name="{robot}">{materials}{body}</robot>\n'


def _fmt(v: tuple[float, ...]) -> str:
    return " ".join(f"{float(x):.6f}" for x in v)


def palm_quat(x_axis: Vec3, y_axis: Vec3, z_axis: Vec3) -> Quat:
    """Quaternion of the palm frame whose axes (columns) are ``x_axis``, ``y_axis``, ``z_axis`` (z = approach)."""
    return quat_tuple_from_matrix(np.column_stack([x_axis, y_axis, z_axis]))


@dataclass(frozen=True)
class Placement:
    """World placement of a scene's base frame: ``position`` m, ``orientation`` [x, y, z, w]."""

    position: Vec3
    orientation: Quat


def draw_placement(rng: np.random.Generator | None, max_tilt_deg: float, spread_m: float = 0.5) -> Placement:
    """Nominal: the origin, unrotated. Randomised: x, y uniform within ``spread_m``, any yaw about world z, then a
    tilt of up to ``max_tilt_deg`` about a random horizontal axis."""
    if rng is None:
        return Placement((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    x, y = (float(v) for v in rng.uniform(-spread_m, spread_m, 2))
    yaw = float(rng.uniform(-math.pi, math.pi))
    tilt = math.radians(float(rng.uniform(0.0, max_tilt_deg)))
    bearing = float(rng.uniform(-math.pi, math.pi))
    cy, sy = math.cos(yaw), math.sin(yaw)
    r_yaw = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    axis = np.array([math.cos(bearing), math.sin(bearing), 0.0])
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    r_tilt = np.eye(3) + math.sin(tilt) * k + (1.0 - math.cos(tilt)) * (k @ k)
    return Placement((x, y, 0.0), quat_tuple_from_matrix(r_tilt @ r_yaw))


def uniform(rng: np.random.Generator | None, nominal: float, low: float, high: float) -> float:
    """``nominal`` without a generator, else a uniform draw in [low, high]."""
    return nominal if rng is None else float(rng.uniform(low, high))


def bar_handle(
    face_x: float, y: float, z: float, length: float, *, standoff: float, radius: float
) -> tuple[Shape, ...]:
    """A vertical bar handle ``standoff`` in front (-x) of the face at ``face_x``, centred at (y, z): the bar and
    its two square posts (20 mm) 15 mm in from its ends."""
    post_z = length / 2 - 0.015
    post_x = face_x - standoff / 2
    return (
        Shape("cylinder", (radius, length), (face_x - standoff, y, z), colour="steel"),
        Shape("box", (standoff, 0.02, 0.02), (post_x, y, z + post_z), colour="steel"),
        Shape("box", (standoff, 0.02, 0.02), (post_x, y, z - post_z), colour="steel"),
    )
