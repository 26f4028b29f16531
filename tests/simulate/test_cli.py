"""``pbd simulate``: text and --json output, exit codes."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import pytest

from flows.cli import main
from tasks.errors import DescriptorError
from tasks.simulate.api import simulate_descriptor
from tests.simulate.fixtures import door_descriptor, write_door
from tests.simulate.objects import DrawerSpec


def test_json_output_shape(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    urdf = write_door(tmp_path)
    desc_path = tmp_path / "door.json"
    desc_path.write_text(door_descriptor(0.8).to_json())
    code = main(
        [
            "simulate",
            str(desc_path),
            "--urdf",
            str(urdf),
            "--joints",
            "hinge",
            "--json",
            "--store",
            str(tmp_path / "store"),
        ]
    )
    out = capsys.readouterr().out
    assert code == 0
    doc = json.loads(out)
    assert set(doc) == {
        "descriptor",
        "scene",
        "success",
        "grasped",
        "contact_kept",
        "contact_fraction",
        "grasp_mode",
        "sim_time_s",
        "wall_time_s",
        "loop_wall_time_s",
        "loop_cpu_time_s",
        "physics_cpu_time_s",
        "cpu_time_s",
        "real_time_factor",
        "base",
        "primitives",
        "frames",
        "notes",
    }
    assert doc["success"] is True and doc["scene"] == "test_door" and doc["descriptor"] == door_descriptor(0.8).id
    (prim,) = doc["primitives"]
    assert prim["joint"] == "hinge" and prim["unit"] == "rad" and prim["target"] == pytest.approx(0.8)
    assert prim["fraction"] >= 0.9 and prim["success"] is True
    assert len(doc["base"]["position"]) == 3 and len(doc["base"]["orientation"]) == 4


def test_text_output(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    urdf = write_door(tmp_path)
    desc_path = tmp_path / "door.json"
    desc_path.write_text(door_descriptor(0.5).to_json())
    assert main(["simulate", str(desc_path), "--urdf", str(urdf), "--grasp", "friction"]) == 0
    out = capsys.readouterr().out
    assert re.search(r" 0 rotation +hinge +28\.6° +2[6-9]\.\d°", out), out
    assert "grasp held by friction" in out
    assert out.rstrip().endswith("success: yes")


def test_bad_input_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    urdf = write_door(tmp_path)
    desc_path = tmp_path / "door.json"
    desc_path.write_text(door_descriptor(1.0, axis_shift_m=0.5).to_json())
    assert main(["simulate", str(desc_path), "--urdf", str(urdf)]) == 2
    assert "primitive 0 (rotation): axis is 0.500 m" in capsys.readouterr().err
    assert main(["simulate", str(desc_path), "--joints", "hinge"]) == 2
    assert "--joints needs --urdf" in capsys.readouterr().err
    assert main(["simulate", str(tmp_path / "nope.json"), "--urdf", str(urdf)]) == 2
    assert "nope.json" in capsys.readouterr().err


def test_a_descriptor_beyond_the_limits_is_refused_before_simulating() -> None:
    desc = DrawerSpec().descriptor(0.3)
    far = dataclasses.replace(desc, chain=(dataclasses.replace(desc.chain[0], extent=1e6),))
    with pytest.raises(DescriptorError, match=r"chain/0/extent: 1e\+06 m beyond 5 m"):
        simulate_descriptor(far, scene="sliding-door")
