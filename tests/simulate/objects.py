"""Two small procedural articulated objects with their truth descriptors: a hinged door and a drawer.

They exercise a rotation and a translation primitive without the built-in scenes (``tasks.scenes``), for tests
and as the benchmark's fallback. World frame, metres, radians. The robot works from -x: the door's front face
looks towards -x, its hinge axis is +z at (``hinge_x``, ``hinge_y``), its panel extends along +y and a vertical
bar handle stands in front of it; the drawer slides out along -x and has a horizontal bar handle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from schemas.descriptor import Descriptor, Grasp, ObjectRef, Primitive
from tasks.arrays import FloatArray
from tasks.hand.grips import BAR_CURL_RAD, CAP_CURL_RAD, HANDLE_RADIUS, HANDLE_STANDOFF, PALM_TO_BAR, curl_eigengrasps
from tasks.rotations import quat_from_matrix
from tasks.simulate.waypoints import matrix_from_axis_angle

_INERTIAL_FIXED = '<inertial><mass value="0"/><inertia ixx="0" iyy="0" izz="0" ixy="0" ixz="0" iyz="0"/></inertial>'


def _box(xyz: tuple[float, float, float], size: tuple[float, float, float], visual: bool = True) -> str:
    o = f'<origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}"/>'
    g = f'<geometry><box size="{size[0]} {size[1]} {size[2]}"/></geometry>'
    return f"<collision>{o}{g}</collision>" + (f"<visual>{o}{g}</visual>" if visual else "")


def _bar(xyz: tuple[float, float, float], length: float, rpy: str) -> str:
    o = f'<origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}" rpy="{rpy}"/>'
    g = f'<geometry><cylinder radius="{HANDLE_RADIUS}" length="{length}"/></geometry>'
    return f"<collision>{o}{g}</collision><visual>{o}{g}</visual>"


@dataclass(frozen=True)
class DoorSpec:
    """A door: hinge at (hinge_x, hinge_y, hinge_z) on +z, panel ``width`` along +y, handle ``handle_y`` from
    the hinge at hinge height."""

    hinge_x: float = 0.0
    hinge_y: float = 0.0
    hinge_z: float = 0.5
    width: float = 0.8
    handle_y: float = 0.7

    def urdf(self) -> str:
        """URDF text."""
        hx = -0.02 - HANDLE_STANDOFF
        door = (
            _box((0.0, self.width / 2 + 0.01, 0.0), (0.04, self.width, 0.9))
            + _bar((hx, self.handle_y, 0.0), 0.2, "0 0 0")
            + _box((-0.055, self.handle_y, 0.09), (0.07, 0.02, 0.02), visual=False)
            + _box((-0.055, self.handle_y, -0.09), (0.07, 0.02, 0.02), visual=False)
        )
        return (
            '<?xml version="1.0"?>\n<robot name="test_door">'
            f'<link name="frame">{_INERTIAL_FIXED}{_box((0.1, -0.05, 0.0), (0.2, 0.04, 1.0))}</link>'
            f'<link name="door"><inertial><origin xyz="0 {self.width / 2} 0"/><mass value="3"/>'
            f'<inertia ixx="0.2" iyy="0.2" izz="0.2" ixy="0" ixz="0" iyz="0"/></inertial>{door}</link>'
            '<joint name="hinge" type="revolute"><parent link="frame"/><child link="door"/>'
            f'<origin xyz="{self.hinge_x} {self.hinge_y} {self.hinge_z}"/><axis xyz="0 0 1"/>'
            '<limit lower="0" upper="2.0" effort="100" velocity="3"/></joint></robot>\n'
        )

    def descriptor(self, extent: float = 1.0, shift_m: float = 0.0, tilt_deg: float = 0.0) -> Descriptor:
        """Open by ``extent`` rad; the axis optionally shifted along x and tilted about x (a disturbed axis)."""
        rot = np.column_stack([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]])  # palm z = +x, fingers wrap z
        palm = (self.hinge_x - 0.02 - HANDLE_STANDOFF - PALM_TO_BAR, self.hinge_y + self.handle_y, self.hinge_z)
        tilt = math.radians(tilt_deg)
        axis = (0.0, -math.sin(tilt), math.cos(tilt))
        prim = Primitive("rotation", (self.hinge_x + shift_m, self.hinge_y, self.hinge_z), axis, extent)
        return Descriptor("open-test-door", "open", ObjectRef("test_door"), _grasp(palm, rot), (prim,))


@dataclass(frozen=True)
class DrawerSpec:
    """A drawer in a fixed cabinet, front face at x = front_x, sliding out along -x; handle at (y, z)."""

    front_x: float = 0.0
    y: float = 0.0
    z: float = 0.6

    def urdf(self) -> str:
        """URDF text."""
        cabinet = _box((0.3, 0.0, -0.2), (0.6, 0.6, 0.04)) + _box((0.3, 0.0, 0.2), (0.6, 0.6, 0.04))
        drawer = (
            _box((0.25, 0.0, 0.0), (0.5, 0.5, 0.3))
            + _bar((-HANDLE_STANDOFF, 0.0, 0.0), 0.2, "1.5707963 0 0")
            + _box((-0.035, 0.09, 0.0), (0.07, 0.02, 0.02), visual=False)
            + _box((-0.035, -0.09, 0.0), (0.07, 0.02, 0.02), visual=False)
        )
        return (
            '<?xml version="1.0"?>\n<robot name="test_drawer">'
            f'<link name="cabinet">{_INERTIAL_FIXED}{cabinet}</link>'
            '<link name="drawer"><inertial><origin xyz="0.25 0 0"/><mass value="2"/>'
            f'<inertia ixx="0.05" iyy="0.05" izz="0.05" ixy="0" ixz="0" iyz="0"/></inertial>{drawer}</link>'
            '<joint name="slide" type="prismatic"><parent link="cabinet"/><child link="drawer"/>'
            f'<origin xyz="{self.front_x} {self.y} {self.z}"/><axis xyz="-1 0 0"/>'
            '<limit lower="0" upper="0.45" effort="100" velocity="1"/></joint></robot>\n'
        )

    def descriptor(self, extent: float = 0.3, tilt_deg: float = 0.0) -> Descriptor:
        """Pull out by ``extent`` metres, the direction optionally tilted about z by ``tilt_deg``."""
        # palm z = +x (approach), palm x = +y (the bar), so the fingers wrap the horizontal bar
        rot = np.column_stack([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
        palm = (self.front_x - HANDLE_STANDOFF - PALM_TO_BAR, self.y, self.z)
        direction = matrix_from_axis_angle([0.0, 0.0, 1.0], math.radians(tilt_deg)) @ np.array([-1.0, 0.0, 0.0])
        prim = Primitive("translation", None, (float(direction[0]), float(direction[1]), float(direction[2])), extent)
        return Descriptor("open-test-drawer", "open", ObjectRef("test_drawer"), _grasp(palm, rot), (prim,))


def _grasp(palm: tuple[float, float, float], rot: FloatArray, curl_rad: float = BAR_CURL_RAD) -> Grasp:
    q = quat_from_matrix(rot)
    return Grasp("barrett", curl_eigengrasps(curl_rad), palm, (float(q[0]), float(q[1]), float(q[2]), float(q[3])))


def write_urdf(text: str, folder: Path, name: str) -> Path:
    """Write URDF ``text`` to ``folder/name.urdf`` and return the path."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.urdf"
    path.write_text(text)
    return path


@dataclass(frozen=True)
class CapSpec:
    """A bottle (fixed) whose cap turns about +z through (x, y); cap top at ``top_z``; grasped from above."""

    x: float = 0.0
    y: float = 0.0
    top_z: float = 0.3
    cap_radius: float = 0.028

    def urdf(self) -> str:
        """URDF text."""
        body_h = self.top_z - 0.03
        bottle = (
            f'<collision><origin xyz="0 0 {body_h / 2}"/><geometry><cylinder radius="0.045" length="{body_h}"/>'
            f'</geometry></collision><visual><origin xyz="0 0 {body_h / 2}"/><geometry><cylinder radius="0.045" '
            f'length="{body_h}"/></geometry></visual>'
        )
        cap = (
            f'<collision><origin xyz="0 0 0.015"/><geometry><cylinder radius="{self.cap_radius}" length="0.03"/>'
            f'</geometry></collision><visual><origin xyz="0 0 0.015"/><geometry><cylinder radius="{self.cap_radius}"'
            ' length="0.03"/></geometry></visual>'
        )
        return (
            '<?xml version="1.0"?>\n<robot name="test_bottle">'
            f'<link name="bottle">{_INERTIAL_FIXED}{bottle}</link>'
            '<link name="cap"><inertial><origin xyz="0 0 0.015"/><mass value="0.2"/>'
            f'<inertia ixx="1e-4" iyy="1e-4" izz="1e-4" ixy="0" ixz="0" iyz="0"/></inertial>{cap}</link>'
            '<joint name="cap_turn" type="revolute"><parent link="bottle"/><child link="cap"/>'
            f'<origin xyz="{self.x} {self.y} {body_h}"/><axis xyz="0 0 1"/>'
            '<limit lower="-10" upper="10" effort="10" velocity="5"/></joint></robot>\n'
        )

    def descriptor(self, extent: float = 3.5) -> Descriptor:
        """Unscrew by ``extent`` radians (counter-clockwise seen from above)."""
        rot = np.column_stack([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])  # palm z = -z (from above)
        palm = (self.x, self.y, self.top_z + 0.055)
        prim = Primitive("rotation", (self.x, self.y, self.top_z), (0.0, 0.0, 1.0), extent)
        return Descriptor(
            "open-test-bottle", "open", ObjectRef("test_bottle"), _grasp(palm, rot, CAP_CURL_RAD), (prim,)
        )


@dataclass(frozen=True)
class SlidingDoorSpec:
    """A panel sliding along +y in a fixed frame; vertical bar handle on its front face (x = front_x) at ``z``."""

    front_x: float = 0.0
    y: float = 0.0
    z: float = 0.8

    def urdf(self) -> str:
        """URDF text."""
        frame = _box((0.1, -0.45, 0.0), (0.2, 0.04, 1.0)) + _box((0.1, 0.9, 0.5), (0.2, 1.8, 0.04))
        panel = (
            _box((0.02, 0.0, 0.0), (0.04, 0.6, 0.9))
            + _bar((-HANDLE_STANDOFF, 0.2, 0.0), 0.2, "0 0 0")
            + _box((-0.035, 0.2, 0.09), (0.07, 0.02, 0.02), visual=False)
            + _box((-0.035, 0.2, -0.09), (0.07, 0.02, 0.02), visual=False)
        )
        return (
            '<?xml version="1.0"?>\n<robot name="test_sliding_door">'
            f'<link name="frame">{_INERTIAL_FIXED}{frame}</link>'
            '<link name="panel"><inertial><mass value="4"/>'
            f'<inertia ixx="0.3" iyy="0.3" izz="0.3" ixy="0" ixz="0" iyz="0"/></inertial>{panel}</link>'
            '<joint name="slide" type="prismatic"><parent link="frame"/><child link="panel"/>'
            f'<origin xyz="{self.front_x} {self.y} {self.z}"/><axis xyz="0 1 0"/>'
            '<limit lower="0" upper="0.8" effort="100" velocity="1"/></joint></robot>\n'
        )

    def descriptor(self, extent: float = 0.4) -> Descriptor:
        """Slide open by ``extent`` metres along +y."""
        rot = np.column_stack([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]])
        palm = (self.front_x - HANDLE_STANDOFF - PALM_TO_BAR, self.y + 0.2, self.z)
        prim = Primitive("translation", None, (0.0, 1.0, 0.0), extent)
        return Descriptor("open-test-sliding-door", "open", ObjectRef("test_sliding_door"), _grasp(palm, rot), (prim,))


@dataclass(frozen=True)
class LeverDoorSpec:
    """A hinged door (hinge +z at (hinge_x, hinge_y), panel along +y) with a lever handle: the lever turns about
    +x (the door's normal) at ``pivot_y`` from the hinge and points back towards the hinge; press it down, then
    swing the door open (two rotations)."""

    hinge_x: float = 0.0
    hinge_y: float = 0.0
    hinge_z: float = 0.5
    pivot_y: float = 0.75

    def urdf(self) -> str:
        """URDF text."""
        door = _box((0.0, 0.41, 0.0), (0.04, 0.8, 0.9))
        lever = _box((-0.035, 0.0, 0.0), (0.07, 0.02, 0.02), visual=False) + _bar(
            (-HANDLE_STANDOFF, -0.06, 0.0), 0.14, "1.5707963 0 0"
        )
        return (
            '<?xml version="1.0"?>\n<robot name="test_lever_door">'
            f'<link name="frame">{_INERTIAL_FIXED}{_box((0.1, -0.05, 0.0), (0.2, 0.04, 1.0))}</link>'
            '<link name="door"><inertial><origin xyz="0 0.4 0"/><mass value="3"/>'
            f'<inertia ixx="0.2" iyy="0.2" izz="0.2" ixy="0" ixz="0" iyz="0"/></inertial>{door}</link>'
            '<link name="lever"><inertial><origin xyz="-0.06 -0.05 0"/><mass value="0.2"/>'
            f'<inertia ixx="1e-3" iyy="1e-3" izz="1e-3" ixy="0" ixz="0" iyz="0"/></inertial>{lever}</link>'
            '<joint name="hinge" type="revolute"><parent link="frame"/><child link="door"/>'
            f'<origin xyz="{self.hinge_x} {self.hinge_y} {self.hinge_z}"/><axis xyz="0 0 1"/>'
            '<limit lower="0" upper="2.0" effort="100" velocity="3"/></joint>'
            '<joint name="lever_turn" type="revolute"><parent link="door"/><child link="lever"/>'
            f'<origin xyz="-0.02 {self.pivot_y} 0"/><axis xyz="1 0 0"/>'
            '<limit lower="0" upper="1.0" effort="20" velocity="3"/></joint></robot>\n'
        )

    def descriptor(self, lever_rad: float = 0.6, door_rad: float = 1.0) -> Descriptor:
        """Press the lever by ``lever_rad`` about +x, then open the door by ``door_rad`` about +z."""
        rot = np.column_stack([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])  # fingers wrap the y bar
        bar_y = self.hinge_y + self.pivot_y - 0.07
        palm = (self.hinge_x - 0.02 - HANDLE_STANDOFF - PALM_TO_BAR, bar_y, self.hinge_z)
        pivot = (self.hinge_x - 0.02, self.hinge_y + self.pivot_y, self.hinge_z)
        chain = (
            Primitive("rotation", pivot, (1.0, 0.0, 0.0), lever_rad),
            Primitive("rotation", (self.hinge_x, self.hinge_y, self.hinge_z), (0.0, 0.0, 1.0), door_rad),
        )
        return Descriptor("open-test-lever-door", "open", ObjectRef("test_lever_door"), _grasp(palm, rot), chain)
