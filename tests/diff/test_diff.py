"""``pbd diff``: words and JSON, aligned primitives, exit codes 0 same / 1 different / 2 bad input."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from flows.cli import main
from schemas.descriptor import Descriptor, Grasp, ObjectRef, Primitive
from tasks.diff.core import diff_descriptors, format_diff
from tasks.store import Store

ROT = Primitive("rotation", (0.5, 0.0, 1.0), (0.0, 0.0, 1.0), 1.2, 1.0, 2.0)
TRA = Primitive("translation", None, (1.0, 0.0, 0.0), 0.3, 2.5, 3.5)


def _desc(chain: tuple[Primitive, ...], grasp: Grasp | None = None, name: str = "open-door") -> Descriptor:
    return Descriptor(name, "open", ObjectRef("door"), grasp, chain, parameters={"k": "auto"}, code_version="x")


def test_identical_descriptors_are_the_same() -> None:
    d = diff_descriptors(_desc((ROT, TRA)), _desc((ROT, TRA)))
    assert d.same
    assert d.changed == () and d.added == () and d.removed == ()
    assert format_diff(d)[0].endswith(": same")


def test_axis_angle_offset_and_extent_changes() -> None:
    moved = dataclasses.replace(ROT, dir=(0.0, 0.0174524064, 0.9998476952), pos=(0.5, 0.002, 1.3), extent=1.25)
    d = diff_descriptors(_desc((ROT, TRA)), _desc((moved, TRA)))
    assert not d.same
    (c,) = d.changed
    assert (c.index_a, c.index_b, c.kind) == (0, 0, "rotation")
    assert c.axis_angle_deg == pytest.approx(1.0, abs=1e-6)
    assert c.axis_offset_mm == pytest.approx(2.0, abs=1e-6)  # the 0.3 m shift along the axis does not count
    assert c.extent_change == pytest.approx(0.05)
    assert "rotation 0->0: axis angle 1.000 deg, axis offset 2.000 mm, extent +0.05 rad" in format_diff(d)[1]


def test_added_and_removed_primitives_are_aligned_by_kind() -> None:
    d = diff_descriptors(_desc((ROT, TRA)), _desc((ROT, ROT, TRA)))
    assert [a["index"] for a in d.added] == [1]
    assert d.removed == ()
    d2 = diff_descriptors(_desc((ROT, TRA)), _desc((TRA,)))
    assert [r["kind"] for r in d2.removed] == ["rotation"]
    assert "removed primitive 0: rotation extent 1.2" in format_diff(d2)[1]


def test_grasp_change() -> None:
    g1 = Grasp("barrett", (0.4, -0.1), (0.1, 0.2, 0.3), (0.0, 0.0, 0.0, 1.0))
    g2 = dataclasses.replace(g1, wrist_position=(0.1, 0.2, 0.31))
    d = diff_descriptors(_desc((ROT,), g1), _desc((ROT,), g2))
    assert not d.same
    assert d.grasp is not None and d.grasp["wrist_offset_mm"] == pytest.approx(10.0)
    assert diff_descriptors(_desc((ROT,)), _desc((ROT,), g1)).grasp == {"change": "added"}


def test_cli_exit_codes_and_json(store: Store, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    store.put_descriptor(_desc((ROT, TRA)))
    store.put_descriptor(_desc((dataclasses.replace(ROT, extent=1.0), TRA)))
    path = tmp_path / "copy.json"
    path.write_text(_desc((ROT, TRA)).to_json())
    root = str(store.root)
    assert main(["diff", "open-door@v1", str(path), "--store", root]) == 0
    assert capsys.readouterr().out.splitlines()[0].endswith(": same")
    assert main(["diff", "open-door@v1", "open-door@latest", "--json", "--store", root]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert doc["same"] is False
    assert doc["changed"][0]["extent_change"] == pytest.approx(-0.2)
    assert main(["diff", "open-door@v1", "open-door@v9", "--store", root]) == 2
    assert "open-door has versions 1..2, not 9" in capsys.readouterr().err
    v1 = store.versions("open-door")[0].id
    assert main(["diff", v1[:10], "open-door@v1", "--store", root]) == 0
