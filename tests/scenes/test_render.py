"""Scene pictures: PNGs of the requested size from the software renderer."""

from __future__ import annotations

import struct
from pathlib import Path

import pytest

from tasks.errors import SceneError
from tasks.scenes.catalog import build_scene
from tasks.scenes.render import render_rgb, render_scene


def test_render_writes_a_png_of_the_requested_size(tmp_path: Path) -> None:
    path = render_scene(build_scene("microwave", 4), tmp_path / "m.png", 160, 120)
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert struct.unpack(">II", data[16:24]) == (160, 120)
    assert [p.name for p in tmp_path.iterdir()] == ["m.png"]
    with pytest.raises(SceneError, match=r"m\.png: exists"):
        render_scene(build_scene("microwave", 4), path, 160, 120)


def test_picture_shows_the_object_and_its_markers() -> None:
    rgb = render_rgb(build_scene("bottle", None), 120, 90)
    assert rgb.shape == (90, 120, 3)
    red = (rgb[:, :, 0] > 150) & (rgb[:, :, 1] < 80) & (rgb[:, :, 2] < 80)  # the cap
    blue = (rgb[:, :, 2] > 150) & (rgb[:, :, 0] < 80)  # its markers
    assert red.sum() > 20 and blue.sum() > 2


def test_too_small_a_picture() -> None:
    with pytest.raises(SceneError, match="picture size 8x8"):
        render_rgb(build_scene("door", None), 8, 8)
