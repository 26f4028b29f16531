"""Executing descriptors in real pybullet: the test door opens; misfits are clear errors."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from schemas.descriptor import Primitive
from tasks.errors import SceneError, SimulationError
from tasks.simulate.api import simulate_descriptor
from tasks.simulate.result import SUCCESS_FRACTION
from tests.simulate.fixtures import door_descriptor, write_door
from tests.simulate.objects import CapSpec, DrawerSpec, write_urdf


@pytest.mark.parametrize("mode", ["constraint", "friction"])
def test_truth_descriptor_opens_the_door(tmp_path: Path, mode: str) -> None:
    urdf = write_door(tmp_path)
    result = simulate_descriptor(door_descriptor(1.0), urdf=urdf, grasp_mode=mode)  # type: ignore[arg-type]
    assert result.success, result.to_dict()
    assert result.grasped and result.contact_kept and result.grasp_mode == mode
    (prim,) = result.primitives
    assert prim.joint == "hinge"
    assert prim.achieved >= SUCCESS_FRACTION * 1.0
    assert prim.achieved <= 1.05
    assert prim.end_speed < 1.0
    assert result.sim_time_s > 1.0
    assert result.trace.joints == ("hinge",)
    assert len(result.trace.t_s) == len(result.trace.q) > 10
    assert result.trace.q[0][0] < 0.1 * prim.achieved < result.trace.q[-1][0]  # the hinge angle climbs


def test_disturbed_axis_still_opens_the_door(tmp_path: Path) -> None:
    urdf = write_door(tmp_path)
    result = simulate_descriptor(door_descriptor(1.0, axis_shift_m=0.02, axis_tilt_deg=5.0), urdf=urdf)
    assert result.success, result.to_dict()


def test_key_frames_are_png_images(tmp_path: Path) -> None:
    urdf = write_door(tmp_path)
    result = simulate_descriptor(door_descriptor(0.3), urdf=urdf, frames_dir=tmp_path / "frames")
    assert [Path(f).name for f in result.frames] == [
        "00-pregrasp.png",
        "01-grasped.png",
        "02-primitive-0.png",
        "03-end.png",
    ]
    data = Path(result.frames[-1]).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert int.from_bytes(data[16:20], "big") == 480 and int.from_bytes(data[20:24], "big") == 360


def test_primitive_far_from_any_joint_is_an_error(tmp_path: Path) -> None:
    urdf = write_door(tmp_path)
    with pytest.raises(SimulationError, match=r"primitive 0 \(rotation\): axis is 0\.400 m and 0\.0° from .* hinge"):
        simulate_descriptor(door_descriptor(1.0, axis_shift_m=0.4), urdf=urdf)


def test_translation_with_no_prismatic_joint_is_an_error(tmp_path: Path) -> None:
    urdf = write_door(tmp_path)
    desc = door_descriptor()
    desc = replace(desc, chain=(*desc.chain, Primitive("translation", None, (1.0, 0.0, 0.0), 0.1)))
    with pytest.raises(SimulationError, match=r"primitive 1 \(translation\): no prismatic joint"):
        simulate_descriptor(desc, urdf=urdf)


def test_descriptor_without_grasp_is_an_error(tmp_path: Path) -> None:
    urdf = write_door(tmp_path)
    with pytest.raises(SimulationError, match="has no grasp"):
        simulate_descriptor(door_descriptor().with_grasp(None), urdf=urdf)


def test_bad_scene_arguments(tmp_path: Path) -> None:
    urdf = write_door(tmp_path)
    desc = door_descriptor()
    with pytest.raises(SimulationError, match="scene test_door: no revolute/prismatic joint named latch"):
        simulate_descriptor(desc, urdf=urdf, joints=["latch"])
    with pytest.raises(SceneError, match="URDF file not found"):
        simulate_descriptor(desc, urdf=tmp_path / "missing.urdf")
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'/><joint")
    with pytest.raises(SceneError, match="pybullet cannot load this URDF"):
        simulate_descriptor(desc, urdf=bad)
    with pytest.raises(SimulationError, match="not both"):
        simulate_descriptor(desc, urdf=urdf, scene="microwave")
    with pytest.raises(SimulationError, match="joints can only be named for a URDF"):
        simulate_descriptor(desc, scene="microwave", joints=["hinge"])


def test_unknown_builtin_scene_is_an_error() -> None:
    with pytest.raises(SceneError, match="unknown scene 'test_door'"):
        simulate_descriptor(door_descriptor())


def test_truth_descriptor_pulls_the_drawer(tmp_path: Path) -> None:
    spec = DrawerSpec(front_x=0.1, y=0.2, z=0.7)
    urdf = write_urdf(spec.urdf(), tmp_path, "drawer")
    result = simulate_descriptor(spec.descriptor(0.25), urdf=urdf)
    assert result.success, result.to_dict()
    (prim,) = result.primitives
    assert prim.kind == "translation" and prim.joint == "slide"
    assert 0.9 * 0.25 <= prim.achieved <= 0.27


def test_truth_descriptor_unscrews_the_cap_past_half_a_turn(tmp_path: Path) -> None:
    spec = CapSpec(x=0.1, y=-0.1, top_z=0.45)
    urdf = write_urdf(spec.urdf(), tmp_path, "bottle")
    result = simulate_descriptor(spec.descriptor(3.5), urdf=urdf)
    assert result.success, result.to_dict()
    (prim,) = result.primitives
    assert prim.joint == "cap_turn" and prim.achieved >= 0.9 * 3.5
