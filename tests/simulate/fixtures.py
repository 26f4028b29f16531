"""The procedural test door, written into a test's folder."""

from __future__ import annotations

from pathlib import Path

from schemas.descriptor import Descriptor
from tests.simulate.objects import DoorSpec, write_urdf


def write_door(folder: Path) -> Path:
    """Write the default test door URDF into ``folder`` and return its path."""
    return write_urdf(DoorSpec().urdf(), folder, "test_door")


def door_descriptor(extent: float = 1.0, axis_shift_m: float = 0.0, axis_tilt_deg: float = 0.0) -> Descriptor:
    """Open the default test door by ``extent`` radians (axis optionally shifted along x and tilted about x)."""
    return DoorSpec().descriptor(extent, axis_shift_m, axis_tilt_deg)
